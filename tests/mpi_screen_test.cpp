// screen_pairs over MPI ranks against the single-process screen_pairs on the
// same scene: the pairs gathered on rank 0, and their mu^2, must be the same
// numbers exactly (the same radii, r12 and solve per pair: see
// src/mpi/screen_mpi.cpp). Run by ctest under mpirun with 1, 2, 3 and 4
// ranks; every rank builds the whole scene from one seed, passes its share
// (round robin, or all on one rank) and rank 0 compares. Returns nonzero
// when any scene differs.
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "pwcontact/mpi.hpp"
#include "pwcontact/screen.hpp"

namespace {

using pwcontact::Box;
using pwcontact::ParticleStore;
using pwcontact::ScreenOptions;

int rank = 0, ranks = 1;
int failures = 0;

// splitmix64: the same numbers on every rank and every platform.
struct Random {
  std::uint64_t state;
  double uniform() {  // [0, 1)
    std::uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return double(z >> 11) * 0x1.0p-53;
  }
  double between(double a, double b) { return a + (b - a) * uniform(); }
  std::array<double, 4> quaternion() {
    std::array<double, 4> q{};
    double n = 0;
    do {
      for (double& c : q) c = between(-1, 1);
      n = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    } while (n > 1 || n < 1e-3);
    for (double& c : q) c /= std::sqrt(n);
    return q;
  }
};

// A scene: how particle k is added to a store (the same call for the whole
// scene and for a rank's share).
struct Scene {
  std::string name;
  Box box;
  std::size_t size = 0;
  std::function<void(ParticleStore&, std::size_t)> add;
  std::function<void(ParticleStore&)> prepare = [](ParticleStore&) {};  // types, before any add
};

// Where the particles start: round robin, all on the last rank, or each on
// the rank next to its owner (+1 slab along every axis: as after a move) in
// a periodic orthorhombic box whose particles lie in [0, L) and whose grid
// of ranks is next_dims (row-major ranks, as MPI_Cart_create numbers them
// without reordering).
enum class Start { round_robin, last_rank, next_to_owner };
std::array<int, 3> next_dims = {1, 1, 1};
std::array<double, 3> next_lengths = {1, 1, 1};

int next_to_owner(const ParticleStore& one) {
  int c[3];
  for (int k = 0; k < 3; ++k) {
    const int d = next_dims[std::size_t(k)];
    const int slab = std::min(d - 1, int(one.centre(k)[0] / next_lengths[std::size_t(k)] * d));
    c[k] = (slab + 1) % d;
  }
  return (c[0] * next_dims[1] + c[1]) * next_dims[2] + c[2];
}

// One workspace per rank, used by every other check: its memory grows and
// shrinks over scenes of other sizes, boxes and size classes, and the pairs
// must not change.
pwcontact::ScreenWorkspace* workspace = nullptr;
int checks = 0;

// Screens the scene on all ranks and compares on rank 0.
// With wide_tags, particle k is tagged k 2^32 plus a scramble of k below
// 2^32, instead of k: tags in the same order, whose lower half is in
// another (the ranks order their particles by the tags' digits, all 64
// bits of them).
pwcontact::mpi::DistributedReport check(const Scene& scene, double cutoff, bool with_mu2,
                                        Start start = Start::round_robin, bool tags32 = false,
                                        bool wide_tags = false) {
  auto tag_of = [wide_tags](std::size_t k) -> std::uint64_t {
    return wide_tags ? (std::uint64_t(k) << 32 | std::uint32_t(k * 2654435761u)) : std::uint64_t(k);
  };
  ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = with_mu2;
  options.threads = 1;
  ParticleStore mine;
  scene.prepare(mine);
  std::vector<std::uint64_t> tags;
  std::vector<std::uint32_t> tags_32;
  for (std::size_t k = 0; k < scene.size; ++k) {
    int at = start == Start::round_robin ? int(k % std::size_t(ranks)) : ranks - 1;
    if (start == Start::next_to_owner) {
      ParticleStore one;
      scene.prepare(one);
      scene.add(one, k);
      at = next_to_owner(one);
    }
    if (at != rank) continue;
    scene.add(mine, k);
    tags.push_back(tag_of(k));
    tags_32.push_back(std::uint32_t(k));
  }
  pwcontact::mpi::TaggedPairs local;
  const bool reused = workspace && checks++ % 2 == 1;
  const pwcontact::mpi::DistributedReport report =
      reused ? (tags32 ? pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, mine, tags_32, scene.box,
                                                      options, local, *workspace)
                       : pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, mine, tags, scene.box,
                                                      options, local, *workspace))
      : tags32
          ? pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, mine, tags_32, scene.box, options, local)
          : pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, mine, tags, scene.box, options, local);
  // Local pairs: sorted, i < j.
  bool ok = true;
  for (std::size_t k = 0; k < local.size(); ++k)
    if (local.i[k] >= local.j[k] ||
        (k > 0 && (local.i[k] < local.i[k - 1] ||
                   (local.i[k] == local.i[k - 1] && local.j[k] <= local.j[k - 1]))))
      ok = false;
  const pwcontact::mpi::TaggedPairs all = pwcontact::mpi::gather_pairs(MPI_COMM_WORLD, local);
  unsigned long long owned = report.owned, total_owned = 0, ghosts = report.ghosts,
                     total_ghosts = 0;
  MPI_Reduce(&owned, &total_owned, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
  MPI_Reduce(&ghosts, &total_ghosts, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
  int local_ok = ok, all_ok = 0;
  MPI_Reduce(&local_ok, &all_ok, 1, MPI_INT, MPI_MIN, 0, MPI_COMM_WORLD);
  if (rank != 0) return report;
  ParticleStore whole;
  scene.prepare(whole);
  for (std::size_t k = 0; k < scene.size; ++k) scene.add(whole, k);
  pwcontact::ScreenedPairs expected;
  pwcontact::screen_pairs(whole, scene.box, options, expected);
  std::string why;
  if (!all_ok) why = "local pairs not sorted or not i < j";
  if (total_owned != scene.size)
    why = "owned " + std::to_string(total_owned) + " of " + std::to_string(scene.size);
  if (all.size() != expected.size())
    why = std::to_string(all.size()) + " pairs, expected " + std::to_string(expected.size());
  if (with_mu2 != !all.mu2.empty() && expected.size() > 0) why = "mu2 missing or unasked";
  for (std::size_t k = 0; why.empty() && k < expected.size(); ++k) {
    if (all.i[k] != tag_of(expected.i[k]) || all.j[k] != tag_of(expected.j[k]))
      why = "pair " + std::to_string(k) + " is (" + std::to_string(all.i[k]) + ", " +
            std::to_string(all.j[k]) + "), expected (" + std::to_string(tag_of(expected.i[k])) +
            ", " + std::to_string(tag_of(expected.j[k])) + ")";
    else if (with_mu2 && !(all.mu2[k] == expected.mu2[k]))
      why = "pair " + std::to_string(k) + ": mu2 " + std::to_string(all.mu2[k]) + " vs " +
            std::to_string(expected.mu2[k]);
  }
  if (start == Start::next_to_owner && !report.migration_by_neighbours)
    why = "migrated by MPI_Alltoallv, though every particle went to a neighbour";
  std::printf("%-40s cutoff %.2f%s %d ranks (%d x %d x %d): %zu pairs, %llu ghosts%s%s: %s\n",
              scene.name.c_str(), cutoff, with_mu2 ? " mu2" : "", ranks, report.dims[0],
              report.dims[1], report.dims[2], expected.size(), total_ghosts,
              report.migration_by_neighbours ? "" : " (migrated by alltoallv)",
              reused ? " (workspace reused)" : "",
              why.empty() ? "same" : ("DIFFERENT: " + why).c_str());
  if (!why.empty()) ++failures;
  return report;
}

// Random spheroids (semi-axes (a, a/2, a/2) times a factor in [1, spread])
// in a region, randomly oriented.
Scene random_scene(const std::string& name, const Box& box, std::size_t n,
                   std::array<double, 3> region, double a, double spread, std::uint64_t seed) {
  struct Particle {
    std::array<double, 3> centre, axes;
    std::array<double, 4> q;
  };
  std::vector<Particle> ps(n);
  Random random{seed};
  for (Particle& p : ps) {
    for (int k = 0; k < 3; ++k)
      p.centre[std::size_t(k)] = random.between(0, region[std::size_t(k)]);
    const double f = std::exp(random.between(0, std::log(spread)));
    p.axes = {a * f, a * f / 2, a * f / 2};
    p.q = random.quaternion();
  }
  Scene scene;
  scene.name = name;
  scene.box = box;
  scene.size = n;
  scene.add = [ps](ParticleStore& s, std::size_t k) {
    s.add_axes(ps[k].centre, ps[k].axes, ps[k].q);
  };
  return scene;
}

// Particles on the integer points 0 .. n - 1 of a lattice (typed, random
// orientations): with n = 12 in a box of 12 (or 13 points in open
// boundaries, extent 12) they lie exactly on the faces between subdomains of
// 2, 3 and 4 ranks along an axis, and each is paired across faces, edges and
// corners.
Scene lattice_scene(const std::string& name, const Box& box, int n, std::uint64_t seed) {
  std::vector<std::array<double, 4>> orientation(std::size_t(n * n * n));
  Random random{seed};
  for (auto& q : orientation) q = random.quaternion();
  Scene scene;
  scene.name = name;
  scene.box = box;
  scene.size = orientation.size();
  scene.prepare = [](ParticleStore& s) { s.add_type({0.8, 0.6, 0.55}); };
  scene.add = [orientation, n](ParticleStore& s, std::size_t k) {
    const int x = int(k) / (n * n), y = (int(k) / n) % n, z = int(k) % n;
    s.add_typed({double(x), double(y), double(z)}, 0, orientation[k]);
  };
  return scene;
}

void expect_error(const std::string& name, const std::function<void()>& call,
                  const std::string& part) {
  std::string message;
  try {
    call();
  } catch (const std::invalid_argument& e) {
    message = e.what();
  }
  int ok = message.find(part) != std::string::npos, all_ok = 0;
  MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (rank == 0) {
    std::printf("%-40s %d ranks: %s\n", name.c_str(), ranks,
                all_ok ? "invalid_argument on every rank" : ("WRONG: '" + message + "'").c_str());
    if (!all_ok) ++failures;
  }
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  pwcontact::ScreenWorkspace rank_workspace;
  workspace = &rank_workspace;
  try {
    const Box cube = Box::periodic_box(24, 20, 22);
    const Scene periodic =
        random_scene("periodic orthorhombic", cube, 3000, {24, 20, 22}, 1.0, 1, 11);
    next_dims = check(periodic, 1.0, false).dims;
    next_lengths = {24, 20, 22};
    MPI_Bcast(next_dims.data(), 3, MPI_INT, 0, MPI_COMM_WORLD);
    Scene moved = periodic;
    moved.name = "periodic, each next to its owner";
    check(moved, 1.0, true, Start::next_to_owner);
    check(periodic, 1.3, true, Start::last_rank, true);
    check(random_scene("open", Box::open(), 3000, {26, 22, 24}, 1.0, 1, 12), 1.2, true);
    const Box tilted = Box::triclinic(24, 22, 20, 0.3, -0.2, 0.25);
    check(random_scene("triclinic", tilted, 2500, {30, 24, 20}, 1.0, 1, 13), 1.1, true);
    check(random_scene("triclinic, tags over 64 bits", tilted, 2500, {30, 24, 20}, 1.0, 1, 25), 1.1,
          true, Start::round_robin, false, true);
    check(random_scene("triclinic, 2 cells per axis", Box::triclinic(6, 6.5, 6, 0.3, -0.2, 0.25),
                       150, {6, 6.5, 6}, 0.8, 1.2, 22),
          1.1, true);
    check(random_scene("polydisperse (radii x8), periodic", Box::periodic_box(30, 30, 30), 2000,
                       {30, 30, 30}, 0.4, 8, 14),
          1.0, true);
    check(random_scene("polydisperse (radii x8), triclinic",
                       Box::triclinic(30, 28, 32, -0.25, 0.1, 0.2), 2000, {30, 28, 32}, 0.4, 8, 15),
          1.2, true);
    check(lattice_scene("lattice on the faces, periodic", Box::periodic_box(12, 12, 12), 12, 16),
          1.5, true);
    check(lattice_scene("lattice on the faces, open", Box::open(), 13, 17), 1.5, true,
          Start::last_rank);
    check(lattice_scene("lattice on the faces, triclinic", Box::triclinic(12, 12, 12, 0.25, 0, 0.5),
                        12, 18),
          1.5, true);
    // Particles only in x < 5 of 24: with two ranks or more along x, some
    // rank has none (and all start on the last rank).
    check(random_scene("empty subdomains", cube, 600, {5, 20, 22}, 1.0, 1, 19), 1.2, true,
          Start::last_rank);
    // No particles at all, and all on one point (no extent to split).
    check(random_scene("no particles", Box::open(), 0, {1, 1, 1}, 1.0, 1, 23), 1.0, true);
    {
      Scene point = random_scene("all on one point, open", Box::open(), 5, {1, 1, 1}, 1.0, 1, 24);
      const auto add = point.add;
      point.add = [add](ParticleStore& s, std::size_t k) {
        add(s, k);
        s.set_particle(s.size() - 1, s.particle_at(s.size() - 1).moved_to({3, 3, 3}));
      };
      check(point, 1.0, true);
    }
    // Ellipses in the plane of a two-dimensional box (not split along z).
    {
      const Box plane = Box::two_dimensional_box(40, 36, 0.2);
      Random random{20};
      std::vector<std::array<double, 4>> ellipses(1500);
      for (auto& e : ellipses)
        e = {random.between(0, 40), random.between(0, 36), random.between(0.4, 1.2),
             random.between(0, 3.14159)};
      Scene scene;
      scene.name = "two-dimensional (ellipses)";
      scene.box = plane;
      scene.size = ellipses.size();
      scene.add = [ellipses](ParticleStore& s, std::size_t k) {
        const auto& e = ellipses[k];
        s.add_ellipse(e[0], e[1], e[2], e[2] / 2, e[3]);
      };
      check(scene, 1.0, true);
    }
    // One particle whose reach is wider than a subdomain: handled (its
    // ghosts go to every rank within its reach).
    for (const bool open : {true, false}) {
      // Open: 1,500 small ones over 20^3, the large one's reach 24 wider
      // than any subdomain of 2 ranks or more along an axis; periodic: 3,000
      // over a box of 40 and a reach of 19, wider than a third of the box,
      // the large particle on the faces between the halves.
      Scene scene =
          open ? random_scene("", Box::open(), 1500, {20, 20, 20}, 0.5, 1, 21)
               : random_scene("", Box::periodic_box(40, 40, 40), 3000, {40, 40, 40}, 0.8, 1, 21);
      scene.name = open ? "one particle wider than a subdomain, open"
                        : "one particle wider than a subdomain, periodic";
      const auto small = scene.add;
      const std::size_t n = scene.size;
      scene.size = n + 1;
      const double big = open ? 12 : 9.5, at = open ? 10 : 20;
      scene.add = [small, n, big, at](ParticleStore& s, std::size_t k) {
        if (k < n)
          small(s, k);
        else
          s.add_axes({at, at, at}, {big, 3, 3}, {0.9, 0.1, 0.3, 0.2});
      };
      check(scene, 1.0, true);
    }
    // A few particles far from the rest in open boundaries: the slabs split
    // the region without them (one at x = 1e9 beside 200,000 left every
    // other particle to one rank of two), and the pairs stay the single
    // screen's, the far ones' included.
    for (const Start start : {Start::round_robin, Start::last_rank}) {
      Scene scene = random_scene("", Box::open(), 3000, {26, 22, 24}, 1.0, 1, 26);
      scene.name = start == Start::round_robin ? "far particles, open"
                                               : "far particles, open, all on the last rank";
      const auto near = scene.add;
      const std::size_t n = scene.size;
      scene.size = n + 5;
      scene.add = [near, n](ParticleStore& s, std::size_t k) {
        // (The last so far that eps of its coordinate is 22: the ghosts'
        // slack was taken from the coordinates, and every particle went to
        // every rank.)
        const std::array<std::array<double, 3>, 5> far = {
            {{1e9, 5, 5}, {-1e9, 5, 5}, {-1e9 + 0.6, 5, 5}, {5, 5, -3e8}, {1e17, 5, 5}}};
        if (k < n)
          near(s, k);
        else
          s.add_axes(far[k - n], {0.5, 0.5, 1}, {1, 0, 0, 0});
      };
      const pwcontact::mpi::DistributedReport report = check(scene, 1.0, true, start);
      // Every rank owns a share of the near ones (a quarter of an even share).
      // And the ghosts stay a layer (1,758 of the 3,005 particles with 8
      // ranks), not every particle on every rank.
      unsigned long long owned = report.owned, fewest = 0, ghosts = report.ghosts, all = 0;
      MPI_Allreduce(&owned, &fewest, 1, MPI_UNSIGNED_LONG_LONG, MPI_MIN, MPI_COMM_WORLD);
      MPI_Allreduce(&ghosts, &all, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
      const bool balanced = fewest >= n / std::size_t(4 * ranks), thin = all < n;
      if (rank == 0) {
        std::printf("%-40s %d ranks: %s %llu particles, %llu ghosts%s\n", "far particles, slabs",
                    ranks, balanced ? "the fewest a rank owns is" : "WRONG: a rank owns only",
                    fewest, all, thin ? "" : " (WRONG: as many as the particles)");
        if (!balanced || !thin) ++failures;
      }
    }
    // Clusters far apart in open boundaries: the slabs split the folded
    // axis (four clusters at x = 0, 1e4, 2e4 and 1e6 left the middle rank
    // of three without particles, and three quarters to one rank of two),
    // and the pairs stay the single screen's.
    for (const Start start : {Start::round_robin, Start::last_rank}) {
      const Scene cube = random_scene("", Box::open(), 2800, {14, 14, 14}, 1.0, 1, 27);
      Scene scene = cube;
      scene.name = start == Start::round_robin ? "clusters far apart, open"
                                               : "clusters far apart, open, all on the last rank";
      const auto add = cube.add;
      scene.add = [add](ParticleStore& s, std::size_t k) {
        add(s, k);
        const double offset[4] = {0, 1e4, 2e4, 1e6};
        const auto p = s.particle_at(s.size() - 1);
        s.set_particle(s.size() - 1,
                       p.moved_to({p.centre()[0] + offset[k % 4], p.centre()[1], p.centre()[2]}));
      };
      const pwcontact::mpi::DistributedReport report = check(scene, 1.0, true, start);
      // Every rank owns at least 0.6 of an even share.
      unsigned long long owned = report.owned, fewest = 0;
      MPI_Allreduce(&owned, &fewest, 1, MPI_UNSIGNED_LONG_LONG, MPI_MIN, MPI_COMM_WORLD);
      const bool balanced = double(fewest) >= 0.6 * double(scene.size) / double(ranks);
      if (rank == 0) {
        std::printf("%-40s %d ranks: %s %llu of %zu particles\n", "clusters far apart, slabs",
                    ranks, balanced ? "the fewest a rank owns is" : "WRONG: a rank owns only",
                    fewest, scene.size);
        if (!balanced) ++failures;
      }
    }
    // Ghost layers per size: one large particle added to a scene of small
    // ones changes what every rank receives by at most itself, the rank that
    // owns it included (small particles go as far as twice their own reach,
    // the large one comes to them: src/mpi/screen_mpi.cpp).
    {
      const Scene small =
          random_scene("small ones", Box::periodic_box(40, 40, 40), 3000, {40, 40, 40}, 0.6, 1, 25);
      Scene with_large = small;
      with_large.name = "small ones and a large one";
      with_large.size = small.size + 1;
      const auto add_small = small.add;
      const std::size_t n = small.size;
      with_large.add = [add_small, n](ParticleStore& s, std::size_t k) {
        if (k < n)
          add_small(s, k);
        else
          s.add_axes({5, 5, 5}, {7, 2, 2}, {1, 0, 0, 0});
      };
      const pwcontact::mpi::DistributedReport before = check(small, 1.0, false);
      const pwcontact::mpi::DistributedReport after = check(with_large, 1.0, false);
      int ok = after.ghosts <= before.ghosts + 1, all_ok = 0;
      int owns_large = after.largest_radius >= 7, owners = 0;
      MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
      MPI_Allreduce(&owns_large, &owners, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
      if (rank == 0) {
        std::printf("%-40s %d ranks: %s\n", "ghost layers per size", ranks,
                    all_ok && owners == 1 ? "every rank receives at most the large one in addition"
                                          : "WRONG: a rank receives more");
        if (!all_ok || owners != 1) ++failures;
      }
    }
    // Errors: on every rank, whatever rank found them.
    expect_error(
        "tags and particles differ in count",
        [&] {
          ParticleStore s;
          if (rank == ranks - 1) s.add_axes({1, 1, 1}, {1, 1, 1}, {1, 0, 0, 0});
          pwcontact::mpi::TaggedPairs out;
          pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, std::vector<std::uint64_t>{}, cube,
                                       ScreenOptions{}, out);
        },
        "1 particles");
    expect_error(
        "a tag given twice",
        [&] {
          ParticleStore s;
          std::vector<std::uint64_t> tags;
          if (rank == 0) {
            s.add_axes({1, 1, 1}, {1, 1, 1}, {1, 0, 0, 0});
            s.add_axes({1.5, 1, 1}, {1, 1, 1}, {1, 0, 0, 0});
            tags = {7, 7};
          }
          pwcontact::mpi::TaggedPairs out;
          pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, tags, cube, ScreenOptions{}, out);
        },
        "tag 7 is given to two particles");
    expect_error(
        "a periodic box too small for the reach",
        [&] {
          ParticleStore s;
          std::vector<std::uint64_t> tags;
          if (rank == 0) {
            s.add_axes({1, 1, 1}, {6, 1, 1}, {1, 0, 0, 0});
            tags = {0};
          }
          pwcontact::mpi::TaggedPairs out;
          pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, tags, cube, ScreenOptions{}, out);
        },
        "too small for the cutoff");
    // Centres whose differences overflow (two of 600, at -1e308 and 1e308):
    // refused on every rank as the single-process screen refuses them,
    // where 2 ranks, each screening one of them with the scene between,
    // answered.
    expect_error(
        "centres spanning beyond the largest double",
        [&] {
          ParticleStore s;
          std::vector<std::uint64_t> tags;
          Random random{27};
          for (std::uint64_t k = 0; k < 600; ++k) {
            const std::array<double, 3> centre = {
                16 * random.uniform() - 8, 16 * random.uniform() - 8, 16 * random.uniform() - 8};
            const std::array<double, 3> axes = {0.3 + 0.5 * random.uniform(),
                                                0.3 + 0.5 * random.uniform(),
                                                0.3 + 0.5 * random.uniform()};
            const auto q = random.quaternion();
            if (int(k % std::uint64_t(ranks)) != rank) continue;
            s.add_axes(k == 0   ? std::array<double, 3>{1e308, 0, 0}
                       : k == 1 ? std::array<double, 3>{-1e308, 0, 0}
                                : centre,
                       axes, q);
            tags.push_back(k);
          }
          pwcontact::mpi::TaggedPairs out;
          pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, tags, Box::open(), ScreenOptions{}, out);
        },
        "span more than the largest double along axis 0");
    expect_error(
        "a particle resize() left unset",
        [&] {
          ParticleStore s;
          std::vector<std::uint64_t> tags;
          if (rank == ranks - 1) {
            s.resize(1);
            tags = {0};
          }
          pwcontact::mpi::TaggedPairs out;
          pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, tags, cube, ScreenOptions{}, out);
        },
        "particle 0 was never set");
    // A box or cutoff that differs between ranks (with one rank, nothing
    // differs: a screen of no pairs).
    for (const bool box_differs : {true, false}) {
      auto call = [&] {
        ParticleStore s;
        ScreenOptions options;
        if (!box_differs && rank == ranks - 1) options.cutoff = 1.5;
        const Box box = box_differs && rank == ranks - 1 ? Box::periodic_box(24, 20, 23) : cube;
        pwcontact::mpi::TaggedPairs out;
        pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, std::vector<std::uint64_t>{}, box, options,
                                     out);
      };
      if (ranks > 1)
        expect_error(box_differs ? "a box that differs between ranks"
                                 : "a cutoff that differs between ranks",
                     call, box_differs ? "different box lengths" : "different cutoffs");
      else
        call();
    }
    // The solve's options decide mu^2's last bits: one rank in single
    // precision gave other mu^2 than the single-process screen, silently.
    if (ranks > 1)
      expect_error(
          "a precision that differs between ranks",
          [&] {
            ParticleStore s;
            ScreenOptions options;
            if (rank == 1) options.batch.precision = pwcontact::Precision::single_precision;
            pwcontact::mpi::TaggedPairs out;
            pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, std::vector<std::uint64_t>{}, cube,
                                         options, out);
          },
          "different batch precisions");
    // So does the instruction set each rank runs (FMA or not): one rank
    // naming the portable path beside the others' automatic choice (where
    // that is not the portable path itself) is refused. (Left automatic on
    // every rank, the ranks take the one all run: ctest's
    // mpi.screen_mixed_instruction_sets runs this program so.)
    if (ranks > 1 && pwcontact::resolve_isa(pwcontact::Isa::automatic) != pwcontact::Isa::fallback)
      expect_error(
          "an instruction set that differs between ranks",
          [&] {
            ParticleStore s;
            ScreenOptions options;
            if (rank == 1) options.batch.isa = pwcontact::Isa::fallback;
            pwcontact::mpi::TaggedPairs out;
            pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, std::vector<std::uint64_t>{}, cube,
                                         options, out);
          },
          "different instruction sets (from ");
    // A box made field by field with a NaN, on the last rank only: a NaN
    // drops out of the ranks' min and max, and that rank alone threw (the
    // others waited for it for ever).
    for (const bool in_tilt : {false, true})
      expect_error(
          in_tilt ? "a NaN tilt on one rank" : "a NaN box length on one rank",
          [&] {
            ParticleStore s;
            std::vector<std::uint64_t> tags;
            if (rank == 0) {
              s.add_axes({1, 1, 1}, {1, 1, 1}, {1, 0, 0, 0});
              tags = {0};
            }
            Box box = cube;
            if (rank == ranks - 1) (in_tilt ? box.tilt[0] : box.length[0]) = std::nan("");
            pwcontact::mpi::TaggedPairs out;
            pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, s, tags, box, ScreenOptions{}, out);
          },
          "positive, finite lengths and finite tilts");
    // A two-dimensional box is not split along z, whatever z its centres
    // have (ellipsoids off the plane were split into 2 x 2 x 2 on 8 ranks).
    {
      Scene scene = random_scene("two-dimensional box, centres off the plane",
                                 Box::two_dimensional_box(30, 30), 800, {30, 30, 6}, 0.8, 1, 26);
      const pwcontact::mpi::DistributedReport r = check(scene, 1.0, true);
      if (rank == 0) {
        std::printf("%-40s %d ranks: %s\n", "two-dimensional box: z not split", ranks,
                    r.dims[2] == 1 ? "one rank along z" : "WRONG: split along z");
        if (r.dims[2] != 1) ++failures;
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rank %d: %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 2);
  }
  MPI_Bcast(&failures, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Finalize();
  return failures == 0 ? 0 : 1;
}
