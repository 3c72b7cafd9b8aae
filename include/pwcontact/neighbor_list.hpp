// A neighbour list with a skin, for anisotropic molecular dynamics
// (Gay-Berne, RE-squared): the pairs with mu < mu_cut, step after step,
// from a list of the pairs with mu < mu_cut + skin that is kept while no
// particle has moved or turned beyond what the skin allows, and rebuilt
// (screen_pairs) otherwise.
//
// The criterion (safe, whatever the shapes): since the list was built,
// particle i has moved by d_i (its centre, by the minimum image) and its form
// changed from Q_i to Q_i' (a turn, or any change of shape). The support of
// its shape moved outwards by at most t_i = |Q_i' - Q_i|_F / (2 rho_i) in any
// direction (sqrt(n^T Q' n) - sqrt(n^T Q n) <= n^T (Q' - Q) n / (2 sqrt(n^T Q n))
// by the concavity of the square root, for a unit n, and sqrt(n^T Q n) >=
// rho_i, its inscribed radius then, sqrt(lambda_min(Q_i)); only this outward
// bound is needed; doc/theory.md eq. 34). So
// the ellipsoid scaled by mu_cut now lies inside the old one scaled by
// mu_cut + m_i, m_i = (d_i + mu_cut t_i) / rho_i (a ball of radius x lies in
// x / rho_i times the ellipsoid), and two particles with mu < mu_cut now had
// mu < mu_cut + max(m_i, m_j) then. The list is kept while every m_i <= skin.
// In a 2D box whose particles all lie in the plane (centres at z = 0, forms
// with no x-z or y-z term, exactly), only the directions in the plane
// matter, and rho_i is the in-plane inscribed radius (of the x-y block of
// Q_i), which a third semi-axis smaller than the other two does not shrink;
// a particle that then leaves the plane (a centre off z = 0, a form tilted
// out of it) rebuilds the list. Otherwise, in a 2D box too, rho_i is the 3D
// inscribed radius: the screen measures such pairs in 3D.
// (For a turn by theta of semi-axes a >= c, |Q' - Q|_F is at most about
// sqrt(2) (a^2 - c^2) theta.)
//
// Warm start: the pairs of a kept list are solved again from the lambda
// each had at the last step (PairBatchView::lambda_start), which the
// double-precision kernels start their Newton iteration from: one step and
// the convergence check, where a cold start takes three and the check. The
// first kept step after a rebuild starts the pairs that the list before it
// held too from the lambda of their last solve (when the particle count is
// unchanged: the same indices), the others from the radial guess (the
// screen keeps no lambda). The
// pairs are gathered and solved a chunk at a time over the threads (a chunk
// stays in cache between the gather and the solve), in an order along the
// cells of space made at each rebuild (a pair's second particle is then
// near the particles gathered before it in memory).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact {

struct SkinOptions {
  double cutoff = 1.5;  // mu_cut: the pairs with mu < cutoff are reported
  double skin = 0.2;    // the list holds the pairs with mu < cutoff + skin (> 0)
  bool warm_start = true;
  int threads = 0;     // 0 .. 1024; 0: omp_get_max_threads()
  BatchOptions batch;  // of the solves (threads ignored)
};

struct SkinReport {
  bool rebuilt = false;
  double largest_move = 0;      // max m_i (in units of mu) since the last rebuild
  std::size_t listed = 0;       // pairs in the list
  std::size_t solved = 0;       // pairs solved this step
  std::size_t found = 0;        // pairs with mu < cutoff
  double mean_evaluations = 0;  // per solved pair
  // seconds_solve: the time in the solver (summed over the chunks and
  // threads, divided by the threads); seconds_total: the whole update.
  double seconds_solve = 0, seconds_total = 0;
};

class SkinNeighborList {
 public:
  // Throws std::invalid_argument for a cutoff below 1 or not finite, or a
  // skin that is not positive, or whose sum with the cutoff is not finite.
  explicit SkinNeighborList(const SkinOptions& options = {});

  // The pairs (i < j, sorted) with mu < cutoff of the particles as they are
  // now, with mu^2: from the list when every particle's m_i is within the
  // skin (and the count and box are unchanged), after a rebuild otherwise.
  // Throws as screen_pairs does. Rebuilds screen in the list's own
  // ScreenWorkspace: the memory of the last rebuild's screen (about 150
  // bytes a particle) is kept for the next.
  SkinReport update(const ParticleStore& particles, const Box& box, ScreenedPairs& out);

  std::size_t rebuilds() const noexcept { return rebuilds_; }
  const SkinOptions& options() const noexcept { return options_; }

 private:
  SkinOptions options_;
  std::size_t rebuilds_ = 0;
  Box box_;
  // At the last rebuild: centres, forms and inscribed radii (in_plane_:
  // the in-plane ones of a 2D box's particles, all in its plane).
  std::vector<double> centre_[3], q_[6], inscribed_;
  bool in_plane_ = false;
  // The listed pairs (i < j), in the order of first then second.
  std::vector<std::uint32_t> first_, second_;
  // Kept steps take the particles in an order along the cells of space
  // (rank_: each particle's place in it, from the last rebuild) and the
  // pairs in the order of their first particle's place: listed pair k is at
  // place place_of_[k], and the pair at place p has its particles at places
  // near_first_[p] and near_second_[p], and lambda_[p] the lambda it had at
  // its last solve.
  std::vector<std::uint32_t> rank_, near_first_, near_second_, place_of_;
  std::vector<double> lambda_;
  // The numbers of a kept step, kept for the next one: the particles side by
  // side in the order of rank_, and each pair's answer by its place
  // (stamped with the step that solved it).
  struct Packed {
    double centre[3], q[6], bounding;
  };
  struct Answer {
    double mu2;
    std::uint32_t step;
    Status status;
  };
  std::vector<Packed> packed_;
  std::vector<Answer> answers_;
  std::uint32_t step_ = 0;
  ScreenWorkspace workspace_;  // of the rebuilds' screens
  ScreenedPairs listed_;       // what the last rebuild's screen listed
};

}  // namespace pwcontact
