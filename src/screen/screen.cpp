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

// A pair the prefilters left: its indices i < j, r12 = c_j - c_i (minimum
// image), and where the two forms are in the cell-ordered copies.
struct Undecided {
  std::uint32_t i, j;
  double r[3];
  const double* const* q1;  // the grid's q arrays, and the member's place in them
  const double* const* q2;
  std::uint32_t at1, at2;
};

// What one thread's share of the particles produced, and its buffers: the
// pairs the prefilters leave are solved a chunk at a time, while they are in
// cache, rather than gathered for the whole scene first (which would build a
// batch of 120 bytes per pair in memory).
struct ThreadPairs {
  std::vector<Undecided> undecided;  // waiting for the next chunk's solve
  std::vector<std::uint64_t> found;  // i << 32 | j
  std::vector<double> found_mu2;     // with_mu2
  std::size_t candidates = 0, out = 0, in = 0, solved = 0, invalid = 0, fallbacks = 0;
  double evaluations = 0;  // summed over the solved pairs
  double seconds_compaction = 0, seconds_solve = 0;
  BatchReport last;  // of the last chunk solved (settings as resolved)
  PairBatch<double> batch;
  std::vector<Status> status;
  std::vector<std::uint8_t> overlap;
  std::vector<double> mu2;
};

// Pairs solved per call of the batch path: enough to amortise a call, few
// enough that the chunk stays in cache between compaction and solve.
constexpr std::size_t solve_chunk = 8192;

std::uint64_t pair_key(std::uint32_t i, std::uint32_t j) {
  return (std::uint64_t(i) << 32) | j;
}

// Compacts the waiting pairs into the thread's batch and solves them (one
// thread: the screen's threads are already busy), keeping those found.
void solve_waiting(ThreadPairs& t, const ScreenOptions& options) {
  const std::size_t n = t.undecided.size();
  if (n == 0) return;
  const double start = omp_get_wtime();
  t.batch.resize(n);
  for (std::size_t at = 0; at < n; ++at) {
    const Undecided& u = t.undecided[at];
    for (int k = 0; k < 3; ++k) t.batch.r12(k)[at] = u.r[k];
    for (int k = 0; k < 6; ++k) {
      t.batch.q1(k)[at] = u.q1[k][u.at1];
      t.batch.q2(k)[at] = u.q2[k][u.at2];
    }
  }
  t.status.resize(n);
  const double compacted = omp_get_wtime();
  BatchOptions batch_options = options.batch;
  batch_options.threads = 1;
  const double cutoff2 = options.cutoff * options.cutoff;
  if (options.with_mu2) {
    t.mu2.resize(n);
    t.last = contact_function_batch(t.batch.view(), {t.mu2.data(), nullptr, t.status.data()},
                                    batch_options);
    for (std::size_t at = 0; at < n; ++at)
      if (is_valid(t.status[at]) && t.mu2[at] < cutoff2) {
        t.found.push_back(pair_key(t.undecided[at].i, t.undecided[at].j));
        t.found_mu2.push_back(t.mu2[at]);
      }
  } else {
    t.overlap.resize(n);
    t.last = overlap_batch(t.batch.view(), {t.overlap.data(), t.status.data()}, batch_options,
                           options.cutoff);
    for (std::size_t at = 0; at < n; ++at)
      if (t.overlap[at]) t.found.push_back(pair_key(t.undecided[at].i, t.undecided[at].j));
  }
  t.solved += n;
  t.invalid += t.last.invalid;
  t.fallbacks += t.last.fallbacks;
  t.evaluations += t.last.mean_evaluations * double(n);
  t.undecided.clear();
  t.seconds_compaction += compacted - start;
  t.seconds_solve += omp_get_wtime() - compacted;
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
  // Each grid's six q arrays, as pointers the undecided pairs refer to.
  std::vector<std::array<const double*, 6>> grid_q_storage(lists.grids.size());
  std::vector<const double* const*> grid_q(lists.grids.size());
  for (std::size_t g = 0; g < lists.grids.size(); ++g) {
    for (int k = 0; k < 6; ++k) grid_q_storage[g][std::size_t(k)] = lists.grids[g].q[k].data();
    grid_q[g] = grid_q_storage[g].data();
  }
#pragma omp parallel num_threads(threads)
  {
    ThreadPairs& mine = per_thread[std::size_t(omp_get_thread_num())];
    for (std::size_t own = 0; own < lists.grids.size(); ++own) {
      const screen::ClassGrid& home = lists.grids[own];
      const double* const* home_q = grid_q[own];
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
                    ++mine.in;
                    continue;
                  }
                  // r12 from the lower index to the higher: the pair as (a, b).
                  const bool i_first = a == i;
                  const double sign = i_first ? 1 : -1;
                  const double* const* q_i = home_q;
                  const double* const* q_j = grid_q[g];
                  mine.undecided.push_back({a, b, {sign * r[0], sign * r[1], sign * r[2]},
                                            i_first ? q_i : q_j, i_first ? q_j : q_i,
                                            std::uint32_t(i_first ? at : m),
                                            std::uint32_t(i_first ? m : at)});
                  if (mine.undecided.size() == solve_chunk) solve_waiting(mine, options);
                }
              });
        }
      }
    }
    solve_waiting(mine, options);
  }
  if (options.progress) options.progress(1);
  // Compaction and solve ran inside the search, chunk by chunk: their times
  // are the threads' summed times shared out over the threads, and the
  // search's time what remains of the stage.
  double compaction = 0, solve = 0, evaluations = 0;
  for (const ThreadPairs& t : per_thread) {
    report.candidate_pairs += t.candidates;
    report.decided_out += t.out;
    report.decided_in += t.in;
    report.solved += t.solved;
    report.invalid += t.invalid;
    report.batch.fallbacks += t.fallbacks;
    evaluations += t.evaluations;
    compaction += t.seconds_compaction;
    solve += t.seconds_solve;
    if (t.solved) {
      report.batch.isa = t.last.isa;
      report.batch.precision = t.last.precision;
      report.batch.formulation = t.last.formulation;
      report.batch.iterations = t.last.iterations;
    }
  }
  report.batch.pairs = report.solved;
  report.batch.invalid = report.invalid;
  report.batch.threads = threads;
  report.batch.mean_evaluations = report.solved ? evaluations / double(report.solved) : 0;
  double t2 = omp_get_wtime();
  report.seconds_compaction = compaction / threads;
  report.seconds_solve = solve / threads;
  report.seconds_candidates =
      std::max(0.0, (t2 - t1) - report.seconds_compaction - report.seconds_solve);
  const double t4 = t2;

  // The pairs found, sorted by (i, j).
  if (options.with_mu2) {
    std::vector<std::pair<std::uint64_t, double>> found;
    for (const ThreadPairs& t : per_thread)
      for (std::size_t k = 0; k < t.found.size(); ++k) found.push_back({t.found[k], t.found_mu2[k]});
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
    std::size_t total = 0;
    for (const ThreadPairs& t : per_thread) total += t.found.size();
    std::vector<std::uint64_t> found;
    found.reserve(total);
    for (ThreadPairs& t : per_thread) {
      found.insert(found.end(), t.found.begin(), t.found.end());
      std::vector<std::uint64_t>().swap(t.found);
    }
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
