#include "cli/screen_summary.hpp"

#include <cstdio>

#include "cli/text_output.hpp"

namespace pwcontact::cli {
namespace {

// "1.23 M/s": a count per second, or "n/a" when the time was too short.
std::string per_second(std::size_t count, double seconds) {
  char text[64];
  if (!(seconds > 0)) return "n/a";
  const double rate = double(count) / seconds;
  if (rate >= 1e6)
    std::snprintf(text, sizeof text, "%.3g M/s", rate / 1e6);
  else if (rate >= 1e3)
    std::snprintf(text, sizeof text, "%.3g k/s", rate / 1e3);
  else
    std::snprintf(text, sizeof text, "%.3g /s", rate);
  return text;
}

}  // namespace

std::string describe_screen(const ScreenReport& r, const Box& box, double cutoff) {
  char text[2048];
  char where[192];
  if (box.periodic && box.two_dimensional)
    std::snprintf(where, sizeof where, "two-dimensional periodic box %g x %g, tilt xy %g",
                  box.length[0], box.length[1], box.tilt[0]);
  else if (box.periodic && !box.orthorhombic())
    std::snprintf(where, sizeof where, "periodic box %g x %g x %g, tilts xy %g xz %g yz %g",
                  box.length[0], box.length[1], box.length[2], box.tilt[0], box.tilt[1],
                  box.tilt[2]);
  else if (box.periodic)
    std::snprintf(where, sizeof where, "periodic box %g x %g x %g", box.length[0], box.length[1],
                  box.length[2]);
  else
    std::snprintf(where, sizeof where, "open boundaries");
  std::snprintf(
      text, sizeof text,
      "screen: %zu ellipsoids, %s, cutoff %g, threads %d\n"
      "  cell lists: %zu size class%s%s\n"
      "  candidate pairs %zu: %zu apart by the bounding spheres, %zu apart by their projections "
      "on r12, %zu overlapping by the "
      "inscribed spheres, %zu pairs of spheres and %zu of one form (same shape and orientation) "
      "in closed form, %zu solved by the batch path "
      "(%s, %s, mean evaluations %.2f, fallbacks %zu, invalid %zu)\n"
      "  found %zu pairs with mu < %g\n"
      "  time: cells %s, candidates and prefilters %s, compaction %s, solve %s, sorting %s; "
      "total %s\n"
      "  rates: %s ellipsoids, %s candidate pairs\n",
      r.particles, where, cutoff, r.threads, r.size_classes, r.size_classes == 1 ? "" : "es",
      r.one_type           ? " (identical shapes, one type: one reach for every pair)"
      : r.identical_shapes ? " (identical shapes: one reach for every pair)"
                           : "",
      r.candidate_pairs, r.decided_out, r.decided_out_by_projection, r.decided_in,
      r.decided_spheres, r.decided_same_form, r.solved,
      r.solved ? precision_name(r.batch.precision) : "-", r.solved ? isa_name(r.batch.isa) : "-",
      r.batch.mean_evaluations, r.batch.fallbacks, r.invalid, r.found, cutoff,
      describe_seconds(r.seconds_cells).c_str(), describe_seconds(r.seconds_candidates).c_str(),
      describe_seconds(r.seconds_compaction).c_str(), describe_seconds(r.seconds_solve).c_str(),
      describe_seconds(r.seconds_output).c_str(), describe_seconds(r.seconds_total()).c_str(),
      per_second(r.particles, r.seconds_total()).c_str(),
      per_second(r.candidate_pairs, r.seconds_total()).c_str());
  return text;
}

}  // namespace pwcontact::cli
