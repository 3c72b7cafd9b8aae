#include "targets.hpp"

#include <cmath>

#include "accuracy.hpp"

namespace pwcontact::bench {
namespace {

Configuration defaults(Path path, Family family, Accuracy accuracy = Accuracy::standard) {
  Configuration c{path, family};
  c.accuracy = accuracy;
  return c;
}

const char* verdict(bool met) { return met ? "met" : "NOT MET"; }

std::string speedup_text(double speedup) {
  return std::isnan(speedup) ? std::string("brent_baseline not measured")
                             : format("%.1fx brent_baseline", speedup);
}

bool speed_target(const Target& t) { return t.min_speedup > 0; }

// "0 (2 within) of 65536" for the near-tangent set's counts, "-" unmeasured.
std::string misclassification_text(const Measurement& m, const char* beyond, const char* within) {
  const double b = m.counter(beyond), w = m.counter(within);
  return std::isnan(b) ? std::string("-") : format("%.0f beyond (%.0f within)", b, w);
}

std::string accuracy_text(const Target& t, const Measurement& m) {
  if (is_overlap(t.configuration.path))
    return format(
        "misclassified %s 1e-9 of tangency on the family, %s on %.0f near-tangent "
        "pairs (target: none beyond)",
        misclassification_text(m, counter::misclassified_beyond, counter::misclassified_within)
            .c_str(),
        misclassification_text(m, counter::near_tangent_misclassified_beyond,
                               counter::near_tangent_misclassified_within)
            .c_str(),
        m.counter(counter::near_tangent_pairs));
  std::string text =
      format("max rel err %.2e (target <= %g)", m.counter(counter::max_rel_err), t.max_rel_err);
  const double error_double_input = m.counter(counter::max_rel_err_double_input);
  if (!std::isnan(error_double_input))
    text += format("; %.2e against the double inputs", error_double_input);
  return text;
}

// "  met      <name>: <speed>, <accuracy>[; noise]" for one measurement.
std::string target_line(const Target& t, const Table& table, const Measurement& m) {
  const double speedup = table.speedup(m);
  const bool accurate = within_accuracy(t, m);
  const bool met = accurate && (!speed_target(t) || speedup >= t.min_speedup);
  const bool decided = !speed_target(t) || !std::isnan(speedup);
  std::string line =
      format("  %-8s %s: ", decided ? verdict(met) : "-", m.configuration.name().c_str());
  if (speed_target(t))
    line += format("%s (target >= %gx), ", speedup_text(speedup).c_str(), t.min_speedup);
  else
    line += format("%.3g pairs/s = %s, ", m.pairs_per_second, speedup_text(speedup).c_str());
  line += accuracy_text(t, m);
  if (!speed_target(t))
    line += format("; %.3g fallbacks per pair", m.counter(counter::fallbacks_per_pair));
  return line + Table::noise_note({&m, table.brent_baseline(t.configuration.family)});
}

}  // namespace

const std::vector<Target>& targets() {
  static const std::vector<Target> list = {
      {defaults(Path::batch_double, Family::pw85), 2e-11, 20},
      {defaults(Path::batch_float, Family::random), 1e-5, 80},
      {defaults(Path::batch_mixed, Family::random), 1e-13, 40},
      {defaults(Path::overlap_double, Family::scene), 0, 100},
      // The accurate mode must beat the double floor (~1.1e-11 on pw85).
      {defaults(Path::batch_double, Family::pw85, Accuracy::high), 1e-13, 0},
      // Kept from before the mixed and overlap paths existed.
      {defaults(Path::batch_double, Family::random), 1e-13, 30},
      {defaults(Path::batch_float, Family::random), 1e-5, 60},
  };
  return list;
}

const std::vector<ThreadScalingTarget>& thread_scaling_targets() {
  static const std::vector<ThreadScalingTarget> list = {
      {Path::batch_double, Family::random, 2, 1.8},
      {Path::batch_float, Family::random, 2, 1.8},
  };
  return list;
}

Configuration target_configuration(const Target& t, Isa default_isa) {
  Configuration c = t.configuration;
  if (c.isa == Isa::automatic) c.isa = default_isa;
  return c;
}

bool within_accuracy(const Target& t, const Measurement& m) {
  if (!is_overlap(t.configuration.path)) return m.counter(counter::max_rel_err) <= t.max_rel_err;
  // NaN (not measured) compares false: only a measured zero is within.
  const double near_tangent = m.counter(counter::near_tangent_misclassified_beyond);
  return m.counter(counter::misclassified_beyond) == 0 &&
         (std::isnan(near_tangent) || near_tangent == 0);
}

const Measurement* fastest_within(const Table& table, const Target& t, Isa default_isa,
                                  bool fixed_iterations_only, std::size_t* candidates) {
  const Configuration wanted = target_configuration(t, default_isa);
  const Measurement* best = nullptr;
  std::size_t considered = 0;
  for (const Measurement& m : table.rows()) {
    const Configuration& c = m.configuration;
    if (c.path != wanted.path || c.family != wanted.family || c.accuracy != wanted.accuracy ||
        c.isa != wanted.isa || c.threads != 1 || (fixed_iterations_only && c.iterations == 0))
      continue;
    ++considered;
    if (!within_accuracy(t, m)) continue;
    if (!best || m.pairs_per_second > best->pairs_per_second) best = &m;
  }
  if (candidates) *candidates = considered;
  return best;
}

void print_targets(std::ostream& out, const Table& table, Isa default_isa) {
  for (const Target& t : targets()) {
    const Configuration c = target_configuration(t, default_isa);
    if (const Measurement* m = table.find(c))
      out << target_line(t, table, *m) << '\n';
    else
      out << format("  %-8s %s: not measured\n", "-", c.name().c_str());
  }
  for (const ThreadScalingTarget& t : thread_scaling_targets()) {
    const Configuration c = target_configuration({defaults(t.path, t.family), 0, 0}, default_isa);
    const double scaling = table.thread_scaling(c, t.threads);
    out << format("  %-8s %s: threads:%d / threads:1 = %s (target >= %g)",
                  std::isnan(scaling) ? "-" : verdict(scaling >= t.min_scaling), c.name().c_str(),
                  t.threads, cell(scaling, "%.2f").c_str(), t.min_scaling)
        << table.best_scaling_note(c, t.threads)
        << Table::noise_note({table.find(c), table.find(c.with_threads(t.threads))}) << '\n';
  }
}

void print_targets_best_in_sweep(std::ostream& out, const Table& table, Isa default_isa) {
  for (const Target& t : targets()) {
    std::size_t candidates = 0;
    if (const Measurement* m = fastest_within(table, t, default_isa, false, &candidates)) {
      out << target_line(t, table, *m) << '\n';
      continue;
    }
    out << format("  %-8s %s: %s\n", candidates ? "NOT MET" : "-",
                  target_configuration(t, default_isa).name().c_str(),
                  candidates ? "no measured setting is within the accuracy" : "not measured");
  }
}

}  // namespace pwcontact::bench
