// A scene that moves: particles in a box, kept in cell lists between calls,
// for the questions hard-particle Monte Carlo, packing and neighbour-list
// molecular dynamics ask millions of times: does this particle, at a trial
// position and orientation, overlap anything? Which particles are within
// mu < cutoff of it?
//
// The cells are one uniform grid over the box, in the cell space of the
// screening (screen.hpp): at least as wide as the reach
// max_cutoff * 2 R_max of the largest bounding radius, so that every partner
// of a particle lies in the 3 x 3 x 3 cells about its own. Each cell keeps
// its members in fixed slots, so that insert, remove and move are O(1): a
// member's entry is rewritten in place, or moved to another cell's free
// slot. A cell has room for half as many again as it held at the last
// rebuild, and at least a common room (that of the fullest cell, up to a
// few times the mean occupancy), so that memory is O(N + cells) however
// the particles cluster. The grid is rebuilt (O(N)) only when a cell overflows its slots,
// when a particle larger than the cells' reach arrives, or, in an open box,
// when many particles have left the region the grid covers (the grid's
// outer cells take them meanwhile: nothing is lost, only slower).
//
// Answers are exact as screen_pairs' are: the same prefilters (bounding and
// inscribed spheres, projections on r12, spheres and pairs of one form in
// closed form); for overlap answers, the overlap kernels' certificates taken
// in scalar arithmetic for up to two evaluations; then the overlap kernels
// on the candidates left.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact {

struct MovingSceneOptions {
  // The largest cutoff neighbors() will be asked for (>= 1; overlaps use
  // mu_cut = 1): the cells are sized for its reach. A larger cutoff is
  // answered all the same, over more cells.
  double max_cutoff = 1;
  // Precision and instruction set of the overlap kernels (threads and
  // accuracy are not used: queries run in the caller's thread, and overlap
  // answers are exact in every accuracy).
  BatchOptions batch;
};

// A particle near a trial one: its index and, when asked for, mu^2.
struct Neighbor {
  std::uint32_t index;
  double mu2;  // NaN unless asked for
};

// What the scene did since it was made.
struct MovingSceneCounters {
  std::size_t rebuilds = 0;      // of the whole grid (overflow, size, open-box drift)
  std::size_t cell_changes = 0;  // moves that took a particle to another cell
  std::size_t moves = 0, inserts = 0, removes = 0;  // (queries are const: not counted)
};

class MovingScene {
 public:
  using Particle = ParticleStore::Particle;
  static constexpr std::int64_t none = -1;

  // A scene over the particles (copied) in the box. Throws
  // std::invalid_argument for a bad max_cutoff, 2^31 particles or more, or
  // a periodic box narrower than twice the largest reach in some direction
  // (the minimum image would miss pairs).
  MovingScene(ParticleStore particles, const Box& box, const MovingSceneOptions& options = {});
  ~MovingScene();
  MovingScene(MovingScene&&) noexcept;
  MovingScene& operator=(MovingScene&&) noexcept;

  std::size_t size() const noexcept;
  const ParticleStore& particles() const noexcept;
  const Box& box() const noexcept;
  const MovingSceneCounters& counters() const noexcept;
  // Memory held by the cells (their slots and per-particle places; the
  // particles' own store not counted), in bytes.
  std::size_t bytes() const noexcept;

  // Trial particles (not stored), checked as the store checks particles
  // (std::invalid_argument naming "trial particle"): a new form (radii from
  // its eigenvalues), semi-axes and a quaternion, or one of the store's
  // types. Particle i translated and turned: particles().particle_at(i).
  Particle trial(const std::array<double, 3>& centre, const std::array<double, 6>& q) const;
  Particle trial_axes(const std::array<double, 3>& centre, const std::array<double, 3>& semi_axes,
                      const std::array<double, 4>& quaternion) const;
  Particle trial_typed(const std::array<double, 3>& centre, std::uint32_t type,
                       const std::array<double, 4>& quaternion) const;

  // Changes. Each checks its input first and throws (std::out_of_range for
  // an index that does not exist, std::invalid_argument for a particle the
  // store would refuse, naming it) with the scene unchanged.
  std::uint32_t insert(const Particle& p);  // the new particle's index: size() - 1
  // Removes particle i; the last particle takes its index (as in a swap
  // with the last and a pop). Returns the index that moved to i (the old
  // size() - 1), or i when i was the last.
  std::uint32_t remove(std::size_t i);
  void move(std::size_t i, const Particle& p);  // new centre and form (and radii, type)

  // Queries, for a trial particle against every stored particle but
  // `exclude` (none, or the index of the particle the trial would replace).
  // In a periodic box a trial whose reach cutoff * (R_trial + R_max) to the
  // largest particle the cells are sized for is more than half the box's
  // width across some axis is refused (std::invalid_argument): the minimum
  // image would answer for the wrong image. (R_max: the largest bounding
  // radius held since the grid was last rebuilt; a scene emptied by
  // remove() forgets it.)
  // overlaps: an overlapping particle (mu < 1), the first in the scene's
  // search order (which depends only on the scene's state), or none.
  std::int64_t overlaps(const Particle& trial, std::int64_t exclude = none) const;
  std::size_t overlap_count(const Particle& trial, std::int64_t exclude = none) const;
  // Every particle with mu < cutoff (positive, finite), by index; with mu^2
  // when with_mu2 (from the full solve, to the batch path's accuracy).
  std::vector<Neighbor> neighbors(const Particle& trial, double cutoff, bool with_mu2 = false,
                                  std::int64_t exclude = none) const;

  // Many independent trials at once (e.g. one move per domain of a
  // checkerboard sweep): first_overlap[k] = overlaps(trials[k], exclude[k])
  // for k < count (exclude may be null: none), identical to the single
  // queries whatever the thread count; the undecided pairs of all trials
  // share the SIMD lanes, the trials are spread over `threads` OpenMP threads
  // (0 .. 1024; 0: all; std::invalid_argument beyond).
  void overlaps(const Particle* trials, const std::int64_t* exclude, std::size_t count,
                std::int64_t* first_overlap, int threads = 0) const;

  // Moves of particles that no other call touches meanwhile, in parallel:
  // move(index[k], particles[k]) for every k, as if one after another.
  // Moves whose old and new cells are all distinct from those of every
  // other move of the call (a checkerboard sweep's domains) are applied by
  // `threads` threads (0 .. 1024; 0: all); otherwise, or when a move needs a
  // rebuild, in order in one thread. Checks the thread count and every move
  // first (and throws, naming it, with the scene unchanged).
  void move_many(const std::uint32_t* index, const Particle* particles, std::size_t count,
                 int threads = 0);

  // A move for callers that own cells, e.g. the domains of a checkerboard
  // sweep run by several threads at once: thread-safe provided that no other
  // call reads or writes particle i, its old cell or its new cell meanwhile
  // (nor queries reach them). Applies the move and returns true when it
  // needs no more than its two cells; returns false, changing nothing, when
  // it would need more (a rebuild: a full cell, a particle beyond the cells'
  // reach, an open box's region left or entered) or the input is not valid
  // for move():
  // then call move() from one thread. (Not counted in counters().)
  bool move_in_own_cells(std::size_t i, const Particle& p);

  // The grid: cells per axis and the cell of particle i (for domain
  // decompositions such as a checkerboard sweep's); the cell of a centre.
  std::array<int, 3> cells() const noexcept;
  std::array<int, 3> cell_of(const std::array<double, 3>& centre) const;
  std::array<int, 3> cell_of_particle(std::size_t i) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pwcontact
