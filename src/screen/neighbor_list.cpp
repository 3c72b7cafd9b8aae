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
  const screen::BoxGeometry geometry(box);
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
    box_ = box;
    for (int k = 0; k < 3; ++k) centre_[k] = particles.centre(k);
    for (int k = 0; k < 6; ++k) q_[k] = particles.q(k);
    inscribed_ = particles.inscribed_radius();
    in_plane_ = box.two_dimensional;
    for (std::size_t i = 0; i < n && in_plane_; ++i) in_plane_ = in_plane(particles, i);
    if (in_plane_)
      for (std::size_t i = 0; i < n; ++i) {
        const double q[6] = {q_[0][i], q_[1][i], q_[2][i], q_[3][i], q_[4][i], q_[5][i]};
        inscribed_[i] = in_plane_inscribed(q, inscribed_[i]);
      }
    ++rebuilds_;
    out = ScreenedPairs();
    for (std::size_t k = 0; k < listed_.size(); ++k)
      if (listed_.mu2[k] < cutoff * cutoff) {
        out.i.push_back(listed_.i[k]);
        out.j.push_back(listed_.j[k]);
        out.mu2.push_back(listed_.mu2[k]);
      }
    report.rebuilt = true;
    report.listed = listed_.size();
    // The list taken over (its old arrays left to the next rebuild's screen).
    first_.swap(listed_.i);
    second_.swap(listed_.j);
    lambda_.assign(first_.size(), std::numeric_limits<double>::quiet_NaN());
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
  // them in ten arrays): a pair's second particle is anywhere in memory, and
  // its gather then touches two cache lines, not ten. The centres wrapped
  // into the box first, as the screen's are: the difference of centres
  // given many box lengths away (unwrapped trajectories) lost eps |x|, and
  // the kept pairs' mu^2 with it (2e-9 relatively at 1e6 box lengths).
  struct Packed {
    double centre[3], q[6], bounding;
  };
  std::vector<Packed> packed(n);
  {
    const std::vector<double>& bounding = particles.bounding_radius();
#pragma omp parallel for num_threads(threads) schedule(static)
    for (std::size_t i = 0; i < n; ++i) {
      Packed& p = packed[i];
      const double given[3] = {particles.centre(0)[i], particles.centre(1)[i],
                               particles.centre(2)[i]};
      geometry.wrap(given, p.centre);
      for (int d = 0; d < 6; ++d) p.q[d] = particles.q(d)[i];
      p.bounding = bounding[i];
    }
  }
  std::vector<double> mu2(listed, std::numeric_limits<double>::quiet_NaN());
  std::vector<Status> status(listed, Status::ok);
  std::vector<std::uint8_t> solved(listed, 0);
  const std::size_t chunk = 2048;
  const std::size_t chunks = (listed + chunk - 1) / chunk;
  std::size_t solved_count = 0;
  double evaluations = 0, seconds_solve = 0;
  detail::ParallelErrors errors;
#pragma omp parallel num_threads(threads) reduction(+ : solved_count, evaluations, seconds_solve)
  {
    PairBatch<double> batch;
    batch.reserve(chunk);
    std::vector<std::uint32_t> which;
    std::vector<double> guess, chunk_mu2, chunk_lambda;
    std::vector<Status> chunk_status;
    BatchOptions batch_options = options_.batch;
    batch_options.threads = 1;
#pragma omp for schedule(dynamic, 4)
    for (std::size_t c = 0; c < chunks; ++c) {
      errors.run([&] {
        batch.resize(0);  // (capacity kept)
        which.clear();
        guess.clear();
        for (std::size_t k = c * chunk; k < std::min(listed, (c + 1) * chunk); ++k) {
          const Packed& a = packed[first_[k]];
          const Packed& b = packed[second_[k]];
          double r[3];
          for (int d = 0; d < 3; ++d) r[d] = b.centre[d] - a.centre[d];
          geometry.minimum_image(r);
          const double reach = cutoff * (a.bounding + b.bounding);
          if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] >= reach * reach) continue;
          batch.push_back(r, a.q, b.q);
          which.push_back(std::uint32_t(k));
          guess.push_back(lambda_[k]);
        }
        const std::size_t m = which.size();
        chunk_mu2.resize(m);
        chunk_lambda.resize(m);
        chunk_status.resize(m);
        PairBatchView<double> view = batch.view();
        if (options_.warm_start) view.lambda_start = guess.data();
        const double solve_start = now();
        const BatchReport r = contact_function_batch(
            view, {chunk_mu2.data(), chunk_lambda.data(), chunk_status.data()}, batch_options);
        seconds_solve += now() - solve_start;
        evaluations += r.mean_evaluations * double(m);
        solved_count += m;
        for (std::size_t s = 0; s < m; ++s) {
          const std::size_t k = which[s];
          mu2[k] = chunk_mu2[s];
          status[k] = chunk_status[s];
          solved[k] = 1;
          lambda_[k] = chunk_lambda[s];
        }
      });
    }
  }
  errors.rethrow_if_failed();
  // (seconds_solve summed over threads: the solve's share of the wall time.)
  report.seconds_solve = seconds_solve / threads;
  out = ScreenedPairs();
  for (std::size_t k = 0; k < listed; ++k) {
    if (!solved[k]) continue;
    if (!is_valid(status[k]) && status[k] != Status::out_of_range)
      throw std::runtime_error("SkinNeighborList: the pair (" + std::to_string(first_[k]) + ", " +
                               std::to_string(second_[k]) + ") has no answer (" +
                               status_name(status[k]) + ")");
    if (mu2[k] < cutoff * cutoff) {
      out.i.push_back(first_[k]);
      out.j.push_back(second_[k]);
      out.mu2.push_back(mu2[k]);
    }
  }
  report.listed = listed;
  report.solved = solved_count;
  report.found = out.size();
  report.mean_evaluations = solved_count ? evaluations / double(solved_count) : 0;
  report.seconds_total = now() - start;
  return report;
}

}  // namespace pwcontact
