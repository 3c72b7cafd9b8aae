// screen_pairs: cell lists, prefilters, compaction, the batch path, and the
// pairs found in a deterministic order (see screen.hpp).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "pwcontact/screen.hpp"
#include "screen/cell_lists.hpp"

namespace pwcontact {
namespace {

// A pair the prefilters left: its indices and r12 = c_j - c_i (minimum image).
struct Undecided {
  std::uint32_t i, j;
  double r[3];
};

// What one thread's share of the particles produced.
struct ThreadPairs {
  std::vector<Undecided> undecided;
  std::vector<std::uint64_t> found;  // decided in by the inscribed spheres: i << 32 | j
  std::size_t candidates = 0, out = 0;
};

std::uint64_t pair_key(std::uint32_t i, std::uint32_t j) {
  return (std::uint64_t(i) << 32) | j;
}

void check(const ParticleStore& particles, const Box& box, const ScreenOptions& options) {
  if (!(options.cutoff > 0) || !std::isfinite(options.cutoff))
    throw std::invalid_argument("screen_pairs: the cutoff must be positive and finite, got " +
                                std::to_string(options.cutoff));
  if (options.threads < 0)
    throw std::invalid_argument("screen_pairs: threads must be >= 0 (0 = all)");
  // Cell indices are 32-bit and grids have up to two cells per particle.
  if (particles.size() >= (std::size_t(1) << 31))
    throw std::invalid_argument("screen_pairs: at most 2^31 - 1 particles");
  if (!box.periodic || particles.size() == 0) return;
  const std::vector<double>& bounding = particles.bounding_radius();
  const double largest = *std::max_element(bounding.begin(), bounding.end());
  const double reach = options.cutoff * 2 * largest;
  for (int k = 0; k < 3; ++k)
    if (!(2 * reach <= box.length[k]))
      throw std::invalid_argument(
          "screen_pairs: the periodic box is too small for the cutoff: length " +
          std::to_string(box.length[k]) + " along axis " + std::to_string(k) +
          " is less than twice the largest reach cutoff * 2 R_max = " + std::to_string(reach) +
          " (the minimum image convention would miss pairs)");
}

}  // namespace

ScreenReport screen_pairs(const ParticleStore& particles, const Box& box,
                          const ScreenOptions& options, ScreenedPairs& out) {
  check(particles, box, options);
  ScreenReport report;
  report.particles = particles.size();
  out = {};
  const int threads = options.threads > 0 ? options.threads : omp_get_max_threads();
  report.threads = threads;
  const double cutoff = options.cutoff;

  double t0 = omp_get_wtime();
  const screen::CellLists lists = screen::build_cell_lists(particles, box, cutoff, threads);
  report.size_classes = lists.grids.size();
  double t1 = omp_get_wtime();
  report.seconds_cells = t1 - t0;

  // Candidates and prefilters: each class's members in cell order (the
  // neighbour cells of consecutive members are the same, and in cache),
  // shared among the threads.
  const std::size_t n = particles.size();
  std::vector<std::size_t> done_before(lists.grids.size() + 1, 0);  // members of earlier classes
  for (std::size_t g = 0; g < lists.grids.size(); ++g)
    done_before[g + 1] = done_before[g] + lists.grids[g].members.size();
  std::vector<ThreadPairs> per_thread(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    ThreadPairs& mine = per_thread[std::size_t(omp_get_thread_num())];
    for (std::size_t own = 0; own < lists.grids.size(); ++own) {
      const screen::ClassGrid& home = lists.grids[own];
#pragma omp for schedule(dynamic, 1024)
      for (std::size_t at = 0; at < home.members.size(); ++at) {
        if (options.progress && omp_get_thread_num() == 0 && at % 16384 == 0)
          options.progress((double(done_before[own]) + double(at)) / double(n));
        const std::uint32_t i = home.members[at];
        // The cell search takes the wrapped position; r12 the given centres.
        const std::array<double, 3> c = {home.position[0][at], home.position[1][at],
                                         home.position[2][at]};
        const std::array<double, 3> p = {lists.wrapped(0, c[0]), lists.wrapped(1, c[1]),
                                         lists.wrapped(2, c[2])};
        const std::int32_t image_i[3] = {home.image[0][at], home.image[1][at], home.image[2][at]};
        const double bounding_i = home.bounding[at], inscribed_i = home.inscribed[at];
        // Classes of radii at least as large as i's (indices 0 .. own).
        for (std::size_t g = 0; g <= own; ++g) {
          const screen::ClassGrid& grid = lists.grids[g];
          screen::for_each_neighbour_cell(
              lists, grid, p,
              [&](std::uint32_t begin, std::uint32_t end, const int (&shift)[3],
                  bool nearest_image) {
                for (std::uint32_t m = begin; m < end; ++m) {
                  const std::uint32_t j = grid.members[m];
                  if (g == own && j <= i) continue;  // within a class, from the lower index
                  ++mine.candidates;
                  double r[3];
                  for (int k = 0; k < 3; ++k) {
                    r[k] = grid.position[k][m] - c[k];
                    const int lengths = shift[k] - (grid.image[k][m] - image_i[k]);
                    if (lengths != 0) r[k] += double(lengths) * box.length[k];
                  }
                  if (nearest_image)
                    for (int k = 0; k < 3; ++k)
                      r[k] -= box.length[k] * std::nearbyint(r[k] / box.length[k]);
                  const double rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                  const double reach = cutoff * (bounding_i + grid.bounding[m]);
                  if (rr >= reach * reach) {
                    ++mine.out;
                    continue;
                  }
                  const std::uint32_t a = std::min(i, j), b = std::max(i, j);
                  const double inner = cutoff * (inscribed_i + grid.inscribed[m]);
                  if (!options.with_mu2 && rr < inner * inner) {
                    mine.found.push_back(pair_key(a, b));
                    continue;
                  }
                  // r12 from the lower index to the higher: the pair as (a, b).
                  const double sign = a == i ? 1 : -1;
                  mine.undecided.push_back({a, b, {sign * r[0], sign * r[1], sign * r[2]}});
                }
              });
        }
      }
    }
  }
  if (options.progress) options.progress(1);
  std::size_t undecided = 0, found_in = 0;
  for (const ThreadPairs& t : per_thread) {
    report.candidate_pairs += t.candidates;
    report.decided_out += t.out;
    undecided += t.undecided.size();
    found_in += t.found.size();
  }
  report.decided_in = found_in;
  report.solved = undecided;
  double t2 = omp_get_wtime();
  report.seconds_candidates = t2 - t1;

  // Compaction: the undecided pairs as a SoA batch, in thread order.
  PairBatch<double> batch(undecided);
  std::vector<std::uint64_t> keys(undecided);
  {
    std::vector<std::size_t> first(per_thread.size() + 1, 0);
    for (std::size_t t = 0; t < per_thread.size(); ++t)
      first[t + 1] = first[t] + per_thread[t].undecided.size();
#pragma omp parallel for num_threads(threads) schedule(static, 1)
    for (std::size_t t = 0; t < per_thread.size(); ++t) {
      std::size_t at = first[t];
      for (const Undecided& u : per_thread[t].undecided) {
        keys[at] = pair_key(u.i, u.j);
        for (int k = 0; k < 3; ++k) batch.r12(k)[at] = u.r[k];
        for (int k = 0; k < 6; ++k) {
          batch.q1(k)[at] = particles.q(k)[u.i];
          batch.q2(k)[at] = particles.q(k)[u.j];
        }
        ++at;
      }
      std::vector<Undecided>().swap(per_thread[t].undecided);
    }
  }
  double t3 = omp_get_wtime();
  report.seconds_compaction = t3 - t2;

  // The solve.
  BatchOptions batch_options = options.batch;
  batch_options.threads = threads;
  std::vector<Status> status(undecided);
  std::vector<std::uint8_t> overlap;
  std::vector<double> mu2;
  if (undecided == 0) {
    report.batch.pairs = 0;
  } else if (options.with_mu2) {
    mu2.resize(undecided);
    report.batch = contact_function_batch(batch.view(), {mu2.data(), nullptr, status.data()},
                                          batch_options);
  } else {
    overlap.resize(undecided);
    report.batch = overlap_batch(batch.view(), {overlap.data(), status.data()}, batch_options,
                                 cutoff);
  }
  report.invalid = report.batch.invalid;
  double t4 = omp_get_wtime();
  report.seconds_solve = t4 - t3;

  // The pairs found, sorted by (i, j).
  const double cutoff2 = cutoff * cutoff;
  if (options.with_mu2) {
    std::vector<std::pair<std::uint64_t, double>> found;
    for (std::size_t k = 0; k < undecided; ++k)
      if (is_valid(status[k]) && mu2[k] < cutoff2) found.push_back({keys[k], mu2[k]});
    std::sort(found.begin(), found.end());
    out.i.resize(found.size());
    out.j.resize(found.size());
    out.mu2.resize(found.size());
    for (std::size_t k = 0; k < found.size(); ++k) {
      out.i[k] = std::uint32_t(found[k].first >> 32);
      out.j[k] = std::uint32_t(found[k].first);
      out.mu2[k] = found[k].second;
    }
  } else {
    std::vector<std::uint64_t> found;
    found.reserve(found_in + undecided / 2);
    for (const ThreadPairs& t : per_thread) found.insert(found.end(), t.found.begin(), t.found.end());
    for (std::size_t k = 0; k < undecided; ++k)
      if (overlap[k]) found.push_back(keys[k]);
    std::sort(found.begin(), found.end());
    out.i.resize(found.size());
    out.j.resize(found.size());
    for (std::size_t k = 0; k < found.size(); ++k) {
      out.i[k] = std::uint32_t(found[k] >> 32);
      out.j[k] = std::uint32_t(found[k]);
    }
  }
  report.found = out.size();
  report.seconds_output = omp_get_wtime() - t4;
  return report;
}

}  // namespace pwcontact
