// Hard-particle Monte Carlo on a MovingScene: NVT translation and rotation
// moves (Metropolis for hard particles: a move is accepted when the moved
// particle overlaps nothing, exactly), in checkerboard sweeps, and
// compression of the box to a packing fraction by the exact mu of the
// closest pair. The example the moving scene was built for, and the
// command `pwcontact mc`.
//
// A sweep: the scene's cells grouped into domains of 2 x 2 x 2 cells, the
// grouping shifted by a random number of cells along each axis every sweep,
// uniform over the axis (so that no face between domains stays in place,
// with an odd number of cells too); the domains coloured so that two of
// one colour are a domain apart (2 colours along an axis, a third for the
// last domain of an odd count). Colour by colour, the domains of the colour
// run in parallel (OpenMP threads), each its own trials one after another:
// a random particle of the domain, a move of it (a translation uniform in
// [-d, d]^3 and a turn by an angle uniform in [0, a] about a random axis),
// rejected if it leaves the domain, else a trial query and, when the moved
// particle overlaps nothing, the move (MovingScene::move_in_own_cells; one
// that needs a rebuild is applied after the colour, in one thread, and ends
// its domain's trials for the colour). Domains of one colour are at least a
// cell (the largest reach) apart, so their moves are independent and no
// query reaches a cell another domain writes: the result is the same for
// every thread count. Each domain proposes as many moves as it holds
// particles: one per particle per
// sweep on average. Every (seed, sweep, colour, domain) has its own random
// stream. A scene of fewer than 64 domains is swept one trial at a time
// instead (n trials of random particles, one random stream per sweep).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "pwcontact/moving_scene.hpp"

namespace pwcontact {

struct HardParticleMCOptions {
  double packing = 0.5;      // the packing fraction compress_to_packing reaches
  double translation = 0.1;  // the largest displacement along each axis, d
  double rotation = 0.1;     // the largest turn, a (radians)
  bool adapt_steps = true;   // d and a scaled after each sweep towards 30 % acceptance
  std::uint64_t seed = 1;
  int threads = 0;     // 0 .. 1024; 0: omp_get_max_threads()
  BatchOptions batch;  // precision and instruction set of the overlap kernels
};

struct SweepReport {
  std::size_t proposed = 0;
  std::size_t accepted = 0;
  std::size_t left_domain = 0;  // rejected for leaving their domain
  // Accepted moves into a full cell (its slots rebuilt): applied after their
  // colour of the checkerboard, each ending its domain's trials for it.
  std::size_t deferred = 0;
  double seconds = 0;
};

class HardParticleMC {
 public:
  // Particles by centre, semi-axes and quaternion (w, x, y, z; normalised,
  // those unit to rounding kept as given), in a periodic box. Throws
  // std::invalid_argument for sizes that differ, bad particles (naming
  // them), an open box, or options out of range. Does not require the state
  // to be free of overlaps (overlapping_pairs() tells).
  HardParticleMC(const Box& box, std::vector<std::array<double, 3>> centre,
                 std::vector<std::array<double, 3>> semi_axes,
                 std::vector<std::array<double, 4>> orientation,
                 const HardParticleMCOptions& options = {});
  // n spheroids (a^2 c = 0.5^3, aspect ratios c / a log-uniform in
  // [1 / max_aspect, max_aspect], or with `shapes` > 0 drawn from that many
  // log-spaced over the range; random orientations) on a simple cubic
  // lattice of spacing 1.02 times the largest diameter: a dilute state with
  // no overlap, packing fraction ~0.055 for max_aspect 3.
  static HardParticleMC dilute_spheroids(std::size_t n, std::uint64_t seed, double max_aspect,
                                         const HardParticleMCOptions& options = {},
                                         std::size_t shapes = 0);
  ~HardParticleMC();
  HardParticleMC(HardParticleMC&&) noexcept;
  HardParticleMC& operator=(HardParticleMC&&) noexcept;

  SweepReport sweep();
  // Checks the state by a full screen_pairs (std::logic_error on any
  // overlap), then, short of the target packing fraction, scales
  // the box (and every centre) by s = max(s_target, mu_min^(-1/2)),
  // where s_target reaches the options' packing fraction and mu_min is the
  // smallest mu of any pair (by screen_pairs with mu^2, cutoff 1.1; 1.1 when
  // none is below; no compression closer than 1e-6 to contact): every
  // pair's mu becomes mu s >= sqrt(mu_min) > 1, so no overlap arises.
  // Returns the packing fraction. Its screens reuse the memory of the one
  // before (a ScreenWorkspace the state keeps).
  double compress();
  // Sweeps and compressions in turn until the packing fraction is reached,
  // at most max_sweeps sweeps (std::runtime_error beyond, saying how far it
  // got); progress(sweeps done, packing, acceptance of the last sweep) after
  // each, may be empty. Every sweep is followed by compress(), whose full
  // screen_pairs must find no overlap (std::logic_error otherwise). Throws
  // std::invalid_argument before any sweep when the box at the packing
  // fraction would be narrower than twice compress()'s reach, 1.1 times the
  // largest diameter, across some axis (too few particles for it).
  void compress_to_packing(std::size_t max_sweeps = 100000,
                           const std::function<void(std::size_t, double, double)>& progress = {});

  // The pairs (i < j) that overlap now, by a full screen_pairs.
  std::size_t overlapping_pairs() const;

  const ParticleStore& particles() const;
  const Box& box() const;
  const std::vector<std::array<double, 3>>& semi_axes() const;
  const std::vector<std::array<double, 4>>& orientation() const;
  double packing() const;  // total volume of the particles over the box's
  double translation() const;
  double rotation() const;
  std::size_t sweeps() const;

 private:
  void finish_sweep(SweepReport& report, double start);
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pwcontact
