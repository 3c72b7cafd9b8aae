// The neighbour list with a skin (neighbor_list.hpp).
#include "pwcontact/neighbor_list.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "number_text.hpp"
#include "parallel_errors.hpp"
#include "screen/cell_lists.hpp"
#include "thread_count.hpp"

namespace pwcontact {

using detail::number_text;
namespace {

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

bool same_box(const Box& a, const Box& b) {
  return a.periodic == b.periodic && a.two_dimensional == b.two_dimensional &&
         a.length == b.length && a.tilt == b.tilt;
}

// In a 2D box: a lower bound on the in-plane inscribed radius of the form q
// (the square root of the smaller eigenvalue of its x-y block), at least
// `inscribed`, the 3D one. Eq. 34's support bound needs sqrt(n^T Q n) >= rho
// only for the directions n in the plane, where the contact of two ellipses
// lives; the third semi-axis, which the plane never sees, may be far
// smaller (a flat ellipsoid), and made every small move a rebuild. The
// smaller eigenvalue, det / lambda_max, is taken less its rounding: the
// determinant's cancellation errs by at most ~4 eps (q_xx q_yy + q_xy^2) <=
// 8 eps lambda_max^2, i.e. 8 eps lambda_max / lambda_min relatively; 16 eps
// times that ratio is taken off.
double in_plane_inscribed(const double q[6], double inscribed) {
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const double half_sum = 0.5 * (q[0] + q[3]), half_difference = 0.5 * (q[0] - q[3]);
  const double largest = half_sum + std::hypot(half_difference, q[1]);
  const double smallest = (q[0] * q[3] - q[1] * q[1]) / largest;
  const double safe = smallest * (1 - 16 * eps * largest / smallest);
  return safe > inscribed * inscribed ? std::sqrt(safe) : inscribed;
}

// Particle i lies in the z = 0 plane: its centre there and its form with no
// x-z or y-z term (exactly: the in-plane bound holds for these only).
bool in_plane(const ParticleStore& particles, std::size_t i) {
  return particles.centre(2)[i] == 0 && particles.q(2)[i] == 0 && particles.q(4)[i] == 0;
}

// Each item's place when the items are ordered by key (a stable counting
// sort; keys below `keys_end`).
std::vector<std::uint32_t> places_by_key(const std::vector<std::uint32_t>& key,
                                         std::size_t keys_end) {
  std::vector<std::uint32_t> start(keys_end + 1, 0);
  for (std::uint32_t k : key) ++start[k + 1];
  for (std::size_t c = 0; c < keys_end; ++c) start[c + 1] += start[c];
  std::vector<std::uint32_t> place(key.size());
  for (std::size_t i = 0; i < key.size(); ++i) place[i] = start[key[i]]++;
  return place;
}

// Each particle's place in an order along a grid of cells over the wrapped
// centres (about two particles a cell, cells in the order of x, then y,
// then z), by a counting sort. The listed pairs, taken in the order of
// their first particle's place, then find the numbers of both particles
// near those of the pairs before them, where in the order of the indices
// a pair's second particle is anywhere in memory (with the prefetches of
// the kept step, measured 20-25 % of a kept step: 1M spheroids at 0.3,
// 3.7M listed pairs, one thread). Only the order depends on the grid,
// never the answers.
std::vector<std::uint32_t> spatial_ranks(const ParticleStore& particles,
                                         const screen::BoxGeometry& geometry, int threads) {
  const std::size_t n = particles.size();
  std::vector<double> wrapped(3 * n);
  double low[3], high[3];
  for (int k = 0; k < 3; ++k) {
    low[k] = std::numeric_limits<double>::infinity();
    high[k] = -std::numeric_limits<double>::infinity();
  }
  for (std::size_t i = 0; i < n; ++i) {
    const double given[3] = {particles.centre(0)[i], particles.centre(1)[i],
                             particles.centre(2)[i]};
    double* w = &wrapped[3 * i];
    geometry.wrap(given, w);
    for (int k = 0; k < 3; ++k) low[k] = std::min(low[k], w[k]), high[k] = std::max(high[k], w[k]);
  }
  // The grid covers the centres without the farthest: along each axis from
  // the 1/64 to the 63/64 quantile of a sample of at most 4,096 centres (a
  // particle far away would otherwise stretch the cells over the whole
  // scene, with every other particle in one of them); those beyond fall in
  // the outer cells. (Clusters far apart still share a few cells.)
  {
    const std::size_t stride = std::max<std::size_t>(1, n / 4096);
    std::vector<double> sample;
    for (int k = 0; k < 3; ++k) {
      sample.clear();
      for (std::size_t i = 0; i < n; i += stride) sample.push_back(wrapped[3 * i + std::size_t(k)]);
      if (sample.size() < 64) continue;
      std::sort(sample.begin(), sample.end());
      const double from = sample[sample.size() / 64],
                   to = sample[sample.size() - 1 - sample.size() / 64];
      if (to > from) low[k] = from, high[k] = to;
    }
  }
  // Cells of one side, as many as about half the particles, shaped as that
  // region (an axis without extent, or whose extent overflows, gets one
  // cell), and fewer than 2^32.
  double extent[3], volume = 1;
  int dimensions = 0;
  for (int k = 0; k < 3; ++k) {
    extent[k] = high[k] - low[k];
    if (!(extent[k] > 0) || !std::isfinite(extent[k])) extent[k] = 0;
    if (extent[k] > 0) volume *= extent[k], ++dimensions;
  }
  const double wanted = std::max(1.0, double(n) / 2);
  double side = dimensions ? std::pow(volume / wanted, 1.0 / dimensions) : 1;
  if (!(side > 0) || !std::isfinite(side)) side = 1;
  std::size_t cells[3];
  for (;;) {
    double total = 1;
    for (int k = 0; k < 3; ++k) {
      const double along = extent[k] > 0 ? std::ceil(extent[k] / side) : 1;
      cells[k] = std::size_t(std::min(along, double(1 << 20)));
      total *= double(cells[k]);
    }
    if (total <= 4 * wanted + 64 && total < 4294967295.0) break;
    side *= 2;
  }
  const double inverse_side = 1 / side;
  std::vector<std::uint32_t> cell(n);
#pragma omp parallel for num_threads(threads) schedule(static)
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t c[3];
    for (int k = 0; k < 3; ++k) {
      const double u = (wrapped[3 * i + std::size_t(k)] - low[k]) * inverse_side;
      // (NaN and beyond the last cell: the last cell.)
      c[k] = u >= 0 && u < double(cells[k]) ? std::size_t(u) : (u < 0 ? 0 : cells[k] - 1);
    }
    cell[i] = std::uint32_t((c[0] * cells[1] + c[1]) * cells[2] + c[2]);
  }
  return places_by_key(cell, cells[0] * cells[1] * cells[2]);
}

// The pairs of a new list that the list before it held too (the same
// particle count: the same indices) start their first kept step from the
// lambda of their last solve, not from the radial guess: the scene has
// moved a little since (the skin's worth at most), and one Newton step and
// the convergence check then answer most of them, as at any kept step.
// Both lists are sorted by (i, j): a merge. A lambda is only a start (any
// start gives the reference answer), so a pair whose particles have changed
// shape since is no risk.
void carry_lambda(const std::vector<std::uint32_t>& old_first,
                  const std::vector<std::uint32_t>& old_second,
                  const std::vector<std::uint32_t>& old_place_of,
                  const std::vector<double>& old_lambda, const ScreenedPairs& listed,
                  const std::vector<std::uint32_t>& place_of, std::vector<double>& lambda) {
  const std::size_t old = old_first.size();
  std::size_t o = 0;
  for (std::size_t k = 0; k < listed.size() && o < old; ++k) {
    const std::uint32_t i = listed.i[k], j = listed.j[k];
    while (o < old && (old_first[o] < i || (old_first[o] == i && old_second[o] < j))) ++o;
    if (o < old && old_first[o] == i && old_second[o] == j)
      lambda[place_of[k]] = old_lambda[old_place_of[o]];
  }
}

}  // namespace

SkinNeighborList::SkinNeighborList(const SkinOptions& options) : options_(options) {
  if (!(options.cutoff >= 1) || !std::isfinite(options.cutoff))
    throw std::invalid_argument("SkinNeighborList: the cutoff must be >= 1 and finite, got " +
                                number_text(options.cutoff));
  if (!(options.skin > 0) || !std::isfinite(options.skin))
    throw std::invalid_argument("SkinNeighborList: the skin must be positive and finite, got " +
                                number_text(options.skin));
  if (!std::isfinite(options.cutoff + options.skin))
    throw std::invalid_argument("SkinNeighborList: cutoff + skin must be finite, got " +
                                number_text(options.cutoff) + " + " + number_text(options.skin));
}

SkinReport SkinNeighborList::update(const ParticleStore& particles, const Box& box,
                                    ScreenedPairs& out) {
  const double start = now();
  SkinReport report;
  const std::size_t n = particles.size();
  const int threads = detail::thread_count(options_.threads, "SkinNeighborList");
  const double cutoff = options_.cutoff;
  const screen::BoxGeometry geometry(box);  // (checks a Box filled in by hand)
  // (A kept list is checked as a rebuild's screen checks the store: an unset
  // particle, Q = 0, would otherwise pass as one that never moved.)
  particles.require_set("SkinNeighborList::update");
  // The largest m_i since the last rebuild (infinite when there is none to
  // compare with).
  double largest = std::numeric_limits<double>::infinity();
  if (rebuilds_ > 0 && inscribed_.size() == n && same_box(box, box_)) {
    largest = 0;
#pragma omp parallel for num_threads(threads) reduction(max : largest) schedule(static)
    for (std::size_t i = 0; i < n; ++i) {
      double d[3];
      for (int k = 0; k < 3; ++k) d[k] = particles.centre(k)[i] - centre_[k][i];
      geometry.minimum_image(d);
      const double dq[6] = {particles.q(0)[i] - q_[0][i], particles.q(1)[i] - q_[1][i],
                            particles.q(2)[i] - q_[2][i], particles.q(3)[i] - q_[3][i],
                            particles.q(4)[i] - q_[4][i], particles.q(5)[i] - q_[5][i]};
      const double frobenius = std::sqrt(dq[0] * dq[0] + dq[3] * dq[3] + dq[5] * dq[5] +
                                         2 * (dq[1] * dq[1] + dq[2] * dq[2] + dq[4] * dq[4]));
      const double moved = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const double m = (moved + cutoff * frobenius / (2 * inscribed_[i])) / inscribed_[i];
      const bool bound_holds = !in_plane_ || in_plane(particles, i);
      largest = std::max(
          largest, std::isnan(m) || !bound_holds ? std::numeric_limits<double>::infinity() : m);
    }
  }
  report.largest_move = largest;
  // (A margin of 1e-9 for the rounding of m_i and of the listed pairs' mu.)
  if (!(largest <= options_.skin * (1 - 1e-9))) {
    ScreenOptions screen_options;
    screen_options.cutoff = cutoff + options_.skin;
    screen_options.with_mu2 = true;
    screen_options.threads = threads;
    screen_options.batch = options_.batch;
    const ScreenReport screened = screen_pairs(particles, box, screen_options, listed_, workspace_);
    // Pairs are indexed by 32-bit numbers below (as particles are).
    const std::size_t pairs = listed_.size();
    if (pairs > std::numeric_limits<std::uint32_t>::max())
      throw std::length_error("SkinNeighborList: " + std::to_string(pairs) +
                              " pairs within cutoff + skin, more than 2^32 - 1");
    // Everything of the new list is made first and then swapped in: a
    // failure on the way (out of memory) leaves the old list whole.
    // The particles' places along the cells, and the pairs by their first
    // particle's place (a counting sort).
    std::vector<std::uint32_t> rank = spatial_ranks(particles, geometry, threads);
    std::vector<std::uint32_t> place_of;
    {
      std::vector<std::uint32_t> first_rank(pairs);
      for (std::size_t k = 0; k < pairs; ++k) first_rank[k] = rank[listed_.i[k]];
      place_of = places_by_key(first_rank, n);
    }
    std::vector<std::uint32_t> near_first(pairs), near_second(pairs);
    for (std::size_t k = 0; k < pairs; ++k) {
      near_first[place_of[k]] = rank[listed_.i[k]];
      near_second[place_of[k]] = rank[listed_.j[k]];
    }
    std::vector<double> lambda(pairs, std::numeric_limits<double>::quiet_NaN());
    if (options_.warm_start && rebuilds_ > 0 && inscribed_.size() == n)
      carry_lambda(first_, second_, place_of_, lambda_, listed_, place_of, lambda);
    std::vector<Answer> answers(pairs, Answer{0, 0, Status::ok});
    std::vector<double> centre[3], q[6];
    for (int k = 0; k < 3; ++k) centre[k] = particles.centre(k);
    for (int k = 0; k < 6; ++k) q[k] = particles.q(k);
    std::vector<double> inscribed = particles.inscribed_radius();
    bool planar = box.two_dimensional;
    for (std::size_t i = 0; i < n && planar; ++i) planar = in_plane(particles, i);
    if (planar)
      for (std::size_t i = 0; i < n; ++i) {
        const double form[6] = {q[0][i], q[1][i], q[2][i], q[3][i], q[4][i], q[5][i]};
        inscribed[i] = in_plane_inscribed(form, inscribed[i]);
      }
    ScreenedPairs found;
    for (std::size_t k = 0; k < pairs; ++k)
      if (listed_.mu2[k] < cutoff * cutoff) {
        found.i.push_back(listed_.i[k]);
        found.j.push_back(listed_.j[k]);
        found.mu2.push_back(listed_.mu2[k]);
      }
    // (From here on nothing throws.)
    box_ = box;
    for (int k = 0; k < 3; ++k) centre_[k].swap(centre[k]);
    for (int k = 0; k < 6; ++k) q_[k].swap(q[k]);
    inscribed_.swap(inscribed);
    in_plane_ = planar;
    ++rebuilds_;
    out = std::move(found);
    report.rebuilt = true;
    report.listed = pairs;
    // The list taken over (its old arrays left to the next rebuild's screen).
    first_.swap(listed_.i);
    second_.swap(listed_.j);
    rank_.swap(rank);
    place_of_.swap(place_of);
    near_first_.swap(near_first);
    near_second_.swap(near_second);
    lambda_.swap(lambda);
    answers_.swap(answers);
    step_ = 0;
    report.found = out.size();
    report.solved = screened.solved;
    report.mean_evaluations = screened.batch.mean_evaluations;
    report.seconds_solve = screened.seconds_solve;
    report.seconds_total = now() - start;
    return report;
  }
  // The listed pairs whose bounding spheres (scaled by the cutoff) meet now,
  // solved from their last lambda: gathered and solved a chunk at a time, so
  // that the pairs the kernels read (15 numbers each) are still in cache (a
  // batch of the whole list would be written to memory and read back).
  const std::size_t listed = first_.size();
  // Each particle's numbers side by side (80 bytes, where the store keeps
  // them in ten arrays), at its place along the cells (rank_): a pair's
  // gather then touches two cache lines, not ten, and near the pairs
  // before it. The centres wrapped into the box first, as the screen's
  // are: the difference of centres given many box lengths away
  // (unwrapped trajectories) lost eps |x|, and the kept pairs' mu^2 with
  // it (2e-9 relatively at 1e6 box lengths).
  // (Random accesses, each asked for this many iterations ahead.)
  constexpr std::size_t prefetch_distance = 24;
  packed_.resize(n);
  {
    const std::vector<double>& bounding = particles.bounding_radius();
#pragma omp parallel for num_threads(threads) schedule(static)
    for (std::size_t i = 0; i < n; ++i) {
      if (i + prefetch_distance < n) __builtin_prefetch(&packed_[rank_[i + prefetch_distance]], 1);
      Packed& p = packed_[rank_[i]];
      const double given[3] = {particles.centre(0)[i], particles.centre(1)[i],
                               particles.centre(2)[i]};
      geometry.wrap(given, p.centre);
      for (int d = 0; d < 6; ++d) p.q[d] = particles.q(d)[i];
      p.bounding = bounding[i];
    }
  }
  // The answers of this step are those stamped with it (no pass to clear
  // the last step's; every 2^32 steps the stamps start again).
  if (++step_ == 0) {
    for (Answer& a : answers_) a.step = 0;
    step_ = 1;
  }
  const std::uint32_t step = step_;
  const std::size_t chunk = 2048;
  constexpr int pair_columns = 15;
  const std::size_t chunks = (listed + chunk - 1) / chunk;
  std::size_t solved_count = 0;
  double evaluations = 0, seconds_solve = 0;
  detail::ParallelErrors errors;
#pragma omp parallel num_threads(threads) reduction(+ : solved_count, evaluations, seconds_solve)
  {
    // A chunk's pairs, written in place (15 columns of `chunk` numbers).
    // (Allocated through errors.run, as everything in the region that may
    // throw: a thread whose allocation failed runs no chunk, since run()
    // skips every body once an error is kept.)
    PairBatch<double> batch;
    double* column[pair_columns] = {};
    std::vector<std::uint32_t> which;
    std::vector<double> guess, chunk_mu2, chunk_lambda;
    std::vector<Status> chunk_status;
    errors.run([&] {
      batch.resize(chunk);
      for (int k = 0; k < 3; ++k) column[k] = batch.r12(k).data();
      for (int k = 0; k < 6; ++k)
        column[3 + k] = batch.q1(k).data(), column[9 + k] = batch.q2(k).data();
      which.resize(chunk);
      guess.resize(chunk);
      chunk_mu2.resize(chunk);
      chunk_lambda.resize(chunk);
      chunk_status.resize(chunk);
    });
    BatchOptions batch_options = options_.batch;
    batch_options.threads = 1;
#pragma omp for schedule(dynamic, 4)
    for (std::size_t c = 0; c < chunks; ++c) {
      errors.run([&] {
        std::size_t m = 0;
        const std::size_t end = std::min(listed, (c + 1) * chunk);
        for (std::size_t p = c * chunk; p < end; ++p) {
          // The second particles are near the first ones, but a third of
          // them in the next layer of cells, not yet read: asked for a few
          // pairs ahead (two cache lines each).
          if (p + prefetch_distance < listed) {
            const char* ahead =
                reinterpret_cast<const char*>(&packed_[near_second_[p + prefetch_distance]]);
            __builtin_prefetch(ahead);
            __builtin_prefetch(ahead + sizeof(Packed) - 1);
          }
          const Packed& a = packed_[near_first_[p]];
          const Packed& b = packed_[near_second_[p]];
          double r[3];
          for (int d = 0; d < 3; ++d) r[d] = b.centre[d] - a.centre[d];
          geometry.minimum_image(r);
          const double reach = cutoff * (a.bounding + b.bounding);
          if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] >= reach * reach + screen::square_slack)
            continue;
          for (int k = 0; k < 3; ++k) column[k][m] = r[k];
          for (int k = 0; k < 6; ++k) column[3 + k][m] = a.q[k], column[9 + k][m] = b.q[k];
          which[m] = std::uint32_t(p);
          guess[m] = lambda_[p];
          ++m;
        }
        PairBatchView<double> view = batch.view();
        view.size = m;
        if (options_.warm_start) view.lambda_start = guess.data();
        const double solve_start = now();
        const BatchReport r = contact_function_batch(
            view, {chunk_mu2.data(), chunk_lambda.data(), chunk_status.data()}, batch_options);
        seconds_solve += now() - solve_start;
        evaluations += r.mean_evaluations * double(m);
        solved_count += m;
        for (std::size_t s = 0; s < m; ++s) {
          const std::size_t p = which[s];
          answers_[p] = Answer{chunk_mu2[s], step, chunk_status[s]};
          lambda_[p] = chunk_lambda[s];
        }
      });
    }
  }
  errors.rethrow_if_failed();
  // (seconds_solve summed over threads: the solve's share of the wall time.)
  report.seconds_solve = seconds_solve / threads;
  // The pairs found, in the order of the list, a block of it per thread:
  // every answer is checked before `out` is touched (a pair without one
  // throws, and the smallest such pair is named whatever the thread count).
  const double cutoff2 = cutoff * cutoff;
  const std::size_t blocks = std::size_t(threads);
  std::vector<std::vector<std::uint32_t>> found_pairs(blocks);
  std::vector<std::vector<double>> found_mu2(blocks);
  std::vector<std::size_t> unanswered(blocks, listed);
  detail::ParallelErrors output_errors;
#pragma omp parallel for num_threads(threads) schedule(static, 1)
  for (std::size_t b = 0; b < blocks; ++b) {
    output_errors.run([&] {
      const std::size_t from = listed * b / blocks, to = listed * (b + 1) / blocks;
      for (std::size_t k = from; k < to; ++k) {
        // (Read in the order of the list from the order they were solved in:
        // asked for a few pairs ahead.)
        if (k + prefetch_distance < to)
          __builtin_prefetch(&answers_[place_of_[k + prefetch_distance]]);
        const Answer& a = answers_[place_of_[k]];
        if (a.step != step) continue;
        if (!is_valid(a.status) && a.status != Status::out_of_range) {
          unanswered[b] = k;
          break;
        }
        if (a.mu2 < cutoff2) {
          found_pairs[b].push_back(std::uint32_t(k));
          found_mu2[b].push_back(a.mu2);
        }
      }
    });
  }
  output_errors.rethrow_if_failed();
  const std::size_t missing = *std::min_element(unanswered.begin(), unanswered.end());
  if (missing < listed)
    throw std::runtime_error("SkinNeighborList: the pair (" + std::to_string(first_[missing]) +
                             ", " + std::to_string(second_[missing]) + ") has no answer (" +
                             status_name(answers_[place_of_[missing]].status) + ")");
  std::vector<std::size_t> offset(blocks + 1, 0);
  for (std::size_t b = 0; b < blocks; ++b) offset[b + 1] = offset[b] + found_pairs[b].size();
  ScreenedPairs found = std::move(out);  // (its memory reused)
  found.i.resize(offset[blocks]);
  found.j.resize(offset[blocks]);
  found.mu2.resize(offset[blocks]);
#pragma omp parallel for num_threads(threads) schedule(static, 1)
  for (std::size_t b = 0; b < blocks; ++b)
    for (std::size_t f = 0; f < found_pairs[b].size(); ++f) {
      const std::uint32_t k = found_pairs[b][f];
      found.i[offset[b] + f] = first_[k];
      found.j[offset[b] + f] = second_[k];
      found.mu2[offset[b] + f] = found_mu2[b][f];
    }
  out = std::move(found);
  report.listed = listed;
  report.solved = solved_count;
  report.found = out.size();
  report.mean_evaluations = solved_count ? evaluations / double(solved_count) : 0;
  report.seconds_total = now() - start;
  return report;
}

}  // namespace pwcontact
