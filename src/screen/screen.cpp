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
  const std::size_t n = particles.size();
  const double cutoff = options.cutoff;

  double t0 = omp_get_wtime();
  const screen::CellLists lists = screen::build_cell_lists(particles, box, cutoff, threads);
  report.size_classes = lists.grids.size();
  double t1 = omp_get_wtime();
  report.seconds_cells = t1 - t0;

  // Candidates and prefilters, each thread over a share of the particles.
  const std::vector<double>* centre[3] = {&particles.centre(0), &particles.centre(1),
                                          &particles.centre(2)};
  const std::vector<double>& bounding = particles.bounding_radius();
  const std::vector<double>& inscribed = particles.inscribed_radius();
  std::vector<ThreadPairs> per_thread(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    ThreadPairs& mine = per_thread[std::size_t(omp_get_thread_num())];
#pragma omp for schedule(dynamic, 1024)
    for (std::size_t i = 0; i < n; ++i) {
      const std::array<double, 3> p = {(*centre[0])[i], (*centre[1])[i], (*centre[2])[i]};
      const int own = lists.size_class[i];
      // Classes of radii at least as large as i's (indices 0 .. own).
      for (int g = 0; g <= own; ++g) {
        screen::for_each_neighbour(lists, lists.grids[std::size_t(g)], p, [&](std::uint32_t j) {
          if (g == own && j <= i) return;  // within a class, from the lower index
          ++mine.candidates;
          double r[3], rr = 0;
          for (int k = 0; k < 3; ++k) {
            r[k] = (*centre[k])[j] - p[k];
            if (box.periodic) r[k] -= box.length[k] * std::nearbyint(r[k] / box.length[k]);
            rr += r[k] * r[k];
          }
          const double reach = cutoff * (bounding[i] + bounding[j]);
          if (rr >= reach * reach) {
            ++mine.out;
            return;
          }
          const std::uint32_t a = std::min<std::uint32_t>(std::uint32_t(i), j);
          const std::uint32_t b = std::max<std::uint32_t>(std::uint32_t(i), j);
          const double inner = cutoff * (inscribed[i] + inscribed[j]);
          if (!options.with_mu2 && rr < inner * inner) {
            mine.found.push_back(pair_key(a, b));
            return;
          }
          // r12 from the lower index to the higher: the pair as (a, b).
          const double sign = a == i ? 1 : -1;
          mine.undecided.push_back({a, b, {sign * r[0], sign * r[1], sign * r[2]}});
        });
      }
    }
  }
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
