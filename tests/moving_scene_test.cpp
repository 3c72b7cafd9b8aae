// The moving scene (scene.hpp) against a brute force over every periodic
// image with the scalar reference path, and against a fresh screen_pairs,
// after every step of random sequences of inserts, removes, moves and
// queries; bad input refused with the scene unchanged.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "kernels/kernel_api.hpp"
#include "pwcontact/moving_scene.hpp"
#include "pwcontact/pwcontact.hpp"

namespace {

using pwcontact::Box;
using pwcontact::MovingScene;
using pwcontact::ParticleStore;
using Particle = ParticleStore::Particle;

// Near-tangent pairs are not compared: the overlap answers are exact beyond
// 1e-9 relative to the cutoff's square (batch.hpp), the reference path's
// mu^2 to ~1e-14.
constexpr double tangency_band = 1e-8;

// mu^2 of a trial and a stored particle by the reference path, the smallest
// over every image n1 a1 + n2 a2 + n3 a3, |n_k| <= 2, of the stored one
// (the box's lattice vectors from its lengths and tilts, independent of the
// scene's minimum image and cells).
double brute_mu2(const Box& box, const Particle& t, const ParticleStore& s, std::size_t i) {
  const double lx = box.length[0], ly = box.length[1], lz = box.length[2];
  const double a[3][3] = {
      {lx, 0, 0}, {box.tilt[0] * ly, ly, 0}, {box.tilt[1] * lz, box.tilt[2] * lz, lz}};
  const int reach = box.periodic ? 2 : 0;
  std::array<double, 6> q;
  for (int k = 0; k < 6; ++k) q[k] = s.q(k)[i];
  // Both centres moved into the box first, by whole lattice vectors (the
  // fractional coordinates by Eigen's LU, rounded down).
  Eigen::Vector3d ci(s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]);
  Eigen::Vector3d ct(t.centre()[0], t.centre()[1], t.centre()[2]);
  if (box.periodic) {
    Eigen::Matrix3d h;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) h(r, c) = a[c][r];
    const Eigen::Matrix3d inverse = h.inverse();
    for (Eigen::Vector3d* x : {&ci, &ct}) {
      Eigen::Vector3d f = inverse * *x;
      for (int k = 0; k < 3; ++k) f[k] = std::floor(f[k]);
      *x -= h * f;
    }
  }
  double best = INFINITY;
  for (int n1 = -reach; n1 <= reach; ++n1)
    for (int n2 = -reach; n2 <= reach; ++n2)
      for (int n3 = -reach; n3 <= reach; ++n3) {
        double r[3];
        for (int k = 0; k < 3; ++k)
          r[k] = ci[k] - ct[k] + n1 * a[0][k] + n2 * a[1][k] + n3 * a[2][k];
        const double limit = 3 * (t.bounding_radius() + s.bounding_radius()[i]);
        if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] >= limit * limit) continue;
        const auto result = pwcontact::contact_function<double>(r, t.q().data(), q.data());
        EXPECT_EQ(result.status, pwcontact::Status::ok);
        best = std::min(best, result.mu2);
      }
  return best;
}

// Centres of a periodic box: anywhere in [-2 L, 3 L) (given outside the box
// as often as inside); open: in [0, L).
std::array<double, 3> random_centre(std::mt19937_64& engine, const Box& box, double l) {
  std::uniform_real_distribution<double> unit(0, 1);
  std::array<double, 3> c;
  for (double& x : c) x = box.periodic ? l * (5 * unit(engine) - 2) : l * unit(engine);
  return c;
}

std::array<double, 4> random_quaternion(std::mt19937_64& engine) {
  std::normal_distribution<double> normal(0, 1);
  return {normal(engine), normal(engine), normal(engine), normal(engine)};
}

// Spheroids and ellipsoids of semi-axes 0.15 .. 0.6, some spheres, some of a
// shape type.
Particle random_particle(std::mt19937_64& engine, const ParticleStore& s, const Box& box,
                         double l) {
  std::uniform_real_distribution<double> unit(0, 1);
  const auto c = random_centre(engine, box, l);
  const double kind = unit(engine);
  if (kind < 0.2) {
    const double a = 0.15 + 0.3 * unit(engine);
    return ParticleStore::particle_axes(c, {a, a, a}, {1, 0, 0, 0});
  }
  if (kind < 0.5 && s.types() > 0) return s.particle_typed(c, 0, random_quaternion(engine));
  return ParticleStore::particle_axes(
      c, {0.15 + 0.45 * unit(engine), 0.15 + 0.45 * unit(engine), 0.15 + 0.45 * unit(engine)},
      random_quaternion(engine));
}

// The trial query's answers against the brute force.
void expect_query_matches(const MovingScene& scene, const Particle& t, std::int64_t exclude,
                          const std::string& where) {
  const ParticleStore& s = scene.particles();
  std::set<std::uint32_t> overlapping, near, within_cutoff;
  std::vector<double> mu2(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (std::int64_t(i) == exclude) continue;
    mu2[i] = brute_mu2(scene.box(), t, s, i);
    if (std::abs(mu2[i] - 1) <= tangency_band || std::abs(mu2[i] - 1.96) <= tangency_band * 1.96) {
      near.insert(std::uint32_t(i));
      continue;
    }
    if (mu2[i] < 1) overlapping.insert(std::uint32_t(i));
    if (mu2[i] < 1.96) within_cutoff.insert(std::uint32_t(i));
  }
  // A trial far outside a triclinic box is wrapped into it through its
  // fractional coordinates, each to a few eps of their size (as is the brute
  // force's): r12 then errs by ~eps |x|, mu^2 by twice that over |r12|
  // (>= 0.1 here), relatively. (The same for a stored particle far out.)
  double largest = 0;
  for (double x : t.centre()) largest = std::max(largest, std::abs(x));
  const std::int64_t first = scene.overlaps(t, exclude);
  if (first == MovingScene::none) {
    EXPECT_TRUE(overlapping.empty())
        << where << ": none found, " << overlapping.size() << " overlap";
  } else {
    EXPECT_TRUE(overlapping.count(std::uint32_t(first)) || near.count(std::uint32_t(first)))
        << where << ": particle " << first << " reported overlapping, mu2 " << mu2[first];
  }
  const std::size_t count = scene.overlap_count(t, exclude);
  EXPECT_GE(count, overlapping.size()) << where;
  EXPECT_LE(count, overlapping.size() + near.size()) << where;
  for (bool with_mu2 : {false, true}) {
    const auto found = scene.neighbors(t, 1.4, with_mu2, exclude);
    std::set<std::uint32_t> got;
    for (const auto& n : found) {
      got.insert(n.index);
      if (near.count(n.index)) continue;
      EXPECT_TRUE(within_cutoff.count(n.index)) << where << ": neighbour " << n.index;
      if (with_mu2) {
        double far = largest;
        for (int k = 0; k < 3; ++k) far = std::max(far, std::abs(s.centre(k)[n.index]));
        EXPECT_NEAR(n.mu2, mu2[n.index], (1e-10 + 1e-13 * far) * mu2[n.index])
            << where << ": neighbour " << n.index;
      }
    }
    for (std::uint32_t i : within_cutoff)
      EXPECT_TRUE(got.count(i)) << where << ": missed neighbour " << i;
  }
}

// Every stored particle's overlaps (excluding itself) against a fresh
// screen_pairs of the same particles.
void expect_same_as_screen(const MovingScene& scene, const std::string& where) {
  pwcontact::ScreenedPairs pairs;
  pwcontact::ScreenOptions options;
  options.threads = 1;
  pwcontact::screen_pairs(scene.particles(), scene.box(), options, pairs);
  std::vector<std::size_t> count(scene.size(), 0);
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    ++count[pairs.i[k]];
    ++count[pairs.j[k]];
  }
  for (std::size_t i = 0; i < scene.size(); ++i) {
    const Particle p = scene.particles().particle_at(i);
    const bool any = scene.overlaps(p, std::int64_t(i)) != MovingScene::none;
    EXPECT_EQ(any, count[i] > 0) << where << ": particle " << i;
    EXPECT_EQ(scene.overlap_count(p, std::int64_t(i)), count[i]) << where << ": particle " << i;
  }
}

struct Sequence {
  Box box;
  double length;  // of the region particles are drawn in
  std::size_t particles;
  std::size_t steps;
  std::uint64_t seed;
};

void run_sequence(const Sequence& q) {
  std::mt19937_64 engine(q.seed);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  for (std::size_t n = 0; n < q.particles; ++n)
    s.add_particle(random_particle(engine, s, q.box, q.length));
  MovingScene scene(s, q.box);
  expect_same_as_screen(scene, "start");
  for (std::size_t step = 0; step < q.steps; ++step) {
    const std::string where = "seed " + std::to_string(q.seed) + ", step " + std::to_string(step);
    const double op = unit(engine);
    const ParticleStore& now = scene.particles();
    if (op < 0.45 && scene.size() > 0) {
      // A move: small (a Monte Carlo step), across the boundary, or far away.
      const std::size_t i = std::size_t(unit(engine) * double(scene.size()));
      Particle p = now.particle_at(i);
      std::array<double, 3> c = p.centre();
      const double kind = unit(engine);
      const double jump = kind < 0.8 ? 0.2 : (kind < 0.95 ? q.length : 1e6);
      for (double& x : c) x += jump * (2 * unit(engine) - 1);
      Particle moved = unit(engine) < 0.5
                           ? p.moved_to(c)
                           : random_particle(engine, now, q.box, q.length).moved_to(c);
      expect_query_matches(scene, moved, std::int64_t(i), where + " (trial move)");
      scene.move(i, moved);
    } else if (op < 0.6) {
      const Particle p = random_particle(engine, now, q.box, q.length);
      expect_query_matches(scene, p, MovingScene::none, where + " (trial insert)");
      const std::uint32_t i = scene.insert(p);
      EXPECT_EQ(i, scene.size() - 1);
    } else if (op < 0.75 && scene.size() > 0) {
      const std::size_t i = std::size_t(unit(engine) * double(scene.size()));
      const std::size_t last = scene.size() - 1;
      const Particle moving = now.particle_at(last);
      EXPECT_EQ(scene.remove(i), last);
      if (i != last) {
        EXPECT_EQ(scene.particles().particle_at(i).centre(), moving.centre()) << where;
      }
    } else {
      expect_query_matches(scene, random_particle(engine, now, q.box, q.length), MovingScene::none,
                           where + " (query)");
    }
    if (step % 40 == 39) expect_same_as_screen(scene, where);
  }
  // Emptied and refilled.
  while (scene.size() > 0) scene.remove(scene.size() - 1);
  EXPECT_EQ(scene.overlaps(random_particle(engine, scene.particles(), q.box, q.length)),
            MovingScene::none);
  for (std::size_t n = 0; n < q.particles; ++n)
    scene.insert(random_particle(engine, scene.particles(), q.box, q.length));
  expect_same_as_screen(scene, "refilled");
  for (int n = 0; n < 20; ++n)
    expect_query_matches(scene, random_particle(engine, scene.particles(), q.box, q.length),
                         MovingScene::none, "refilled, query " + std::to_string(n));
}

TEST(MovingScene, RandomSequencesInAPeriodicBoxMatchTheBruteForceAndTheScreen) {
  for (std::uint64_t seed : {1, 2})
    run_sequence({Box::periodic_box(5, 6, 5.5), 5.5, 150, 1500, seed});
}

TEST(MovingScene, RandomSequencesInATriclinicBoxMatchTheBruteForceAndTheScreen) {
  for (std::uint64_t seed : {3, 4})
    run_sequence({Box::triclinic(5, 6, 5.5, 0.4, -0.3, 0.25), 5.5, 150, 1500, seed});
}

TEST(MovingScene, RandomSequencesInOpenBoundariesMatchTheBruteForceAndTheScreen) {
  for (std::uint64_t seed : {5, 6}) run_sequence({Box::open(), 5, 150, 1500, seed});
}

// The coarse test of every instruction set keeps every member that the
// scene's exact test (below, in the baseline arithmetic the scene makes it
// in) keeps, sets no bit at or beyond n, and lets through nothing farther
// than 1e-9 beyond the limit. Members are planted a few ulps either side of
// the limit, where FMA lanes and the baseline round differently, at scales
// from 1e-160 (squares in the subnormal range) to 1e150.
TEST(MovingScene, TheCoarseKernelOfEveryIsaKeepsWhatTheExactTestKeeps) {
  std::mt19937_64 engine(17);
  std::uniform_real_distribution<double> unit(0, 1);
  for (pwcontact::Isa isa : pwcontact::supported_isas()) {
    const pwcontact::kernels::BoundingKernel meet =
        pwcontact::kernels::kernels_for(isa).bounding_spheres_meet;
    std::size_t kept = 0, near_limit = 0;
    for (int round = 0; round < 3000; ++round) {
      const double scale = std::pow(10.0, -160 + 310 * unit(engine));
      const std::uint32_t n = std::uint32_t(engine() % 33);
      // Members beyond n (whole registers are read) are junk.
      std::vector<double> x(40), y(40), z(40), bounding(40);
      const double origin[3] = {scale * (unit(engine) - 0.5), scale * (unit(engine) - 0.5),
                                scale * (unit(engine) - 0.5)};
      const double reach = scale * unit(engine), cut = 0.5 + unit(engine);
      for (std::size_t k = 0; k < 40; ++k) {
        bounding[k] = scale * unit(engine);
        double d[3] = {unit(engine) - 0.5, unit(engine) - 0.5, unit(engine) - 0.5};
        const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        // Half of them on the limit, moved by a few ulps; the rest anywhere.
        const double limit = reach + cut * bounding[k];
        const double at = k % 2 == 0 ? limit * (1 + double(int(engine() % 9) - 4) * 0x1p-52)
                                     : 3 * limit * unit(engine);
        x[k] = origin[0] + at * d[0] / norm;
        y[k] = origin[1] + at * d[1] / norm;
        z[k] = origin[2] + at * d[2] / norm;
      }
      // In the scene's tiles (kernels::CoarseMembers): rows of coarse_tile.
      std::vector<double> tiles(4 * 40);
      for (std::size_t k = 0; k < 40; ++k) {
        double* row = tiles.data() + pwcontact::kernels::coarse_place(k);
        row[0] = x[k];
        row[pwcontact::kernels::coarse_tile] = y[k];
        row[2 * pwcontact::kernels::coarse_tile] = z[k];
        row[3 * pwcontact::kernels::coarse_tile] = bounding[k];
      }
      const std::uint32_t bits = meet({tiles.data()}, n, origin, reach, cut);
      for (std::uint32_t k = 0; k < 32; ++k) {
        const bool set = (bits >> k) & 1u;
        if (k >= n) {
          EXPECT_FALSE(set) << pwcontact::isa_name(isa) << ": bit " << k << " of " << n;
          continue;
        }
        const double rx = x[k] - origin[0], ry = y[k] - origin[1], rz = z[k] - origin[2];
        const double rr = rx * rx + ry * ry + rz * rz;
        const double limit = reach + cut * bounding[k];
        const bool exact = rr < limit * limit;
        kept += exact;
        near_limit += std::abs(rr - limit * limit) <= 1e-14 * limit * limit;
        if (exact) {
          EXPECT_TRUE(set) << pwcontact::isa_name(isa) << ": member " << k << " of " << n
                           << " dropped, scale " << scale;
        }
        if (rr > limit * limit * (1 + 1e-9) + 1e-299) {
          EXPECT_FALSE(set) << pwcontact::isa_name(isa) << ": member " << k << " far beyond";
        }
      }
    }
    // The test is not vacuous: members kept, and many within 1e-14 of the limit.
    EXPECT_GT(kept, 10000u) << pwcontact::isa_name(isa);
    EXPECT_GT(near_limit, 10000u) << pwcontact::isa_name(isa);
  }
}

// Spheres planted 1e-12 inside and outside contact with a trial, in every
// direction, queried on every instruction set: the coarse kernels drop no
// pair that overlaps.
TEST(MovingScene, SpheresPlantedJustInsideContactAreFoundOnEveryIsa) {
  std::mt19937_64 engine(19);
  std::uniform_real_distribution<double> unit(0, 1);
  for (pwcontact::Isa isa : pwcontact::supported_isas()) {
    for (const Box& box :
         {Box::periodic_box(20, 20, 20), Box::triclinic(20, 21, 19, 0.3, -0.2, 0.1), Box::open()}) {
      ParticleStore s;
      std::vector<double> radius;
      for (int k = 0; k < 400; ++k) {
        const double a = 0.2 + 0.8 * unit(engine);
        s.add_particle(
            ParticleStore::particle({20 * unit(engine), 20 * unit(engine), 20 * unit(engine)},
                                    {a * a, 0, 0, a * a, 0, a * a}));
        radius.push_back(a);
      }
      pwcontact::MovingSceneOptions options;
      options.batch.isa = isa;
      const MovingScene scene(s, box, options);
      for (int k = 0; k < 400; ++k) {
        const std::size_t j = std::size_t(engine() % s.size());
        const double a = 0.2 + 0.8 * unit(engine);
        double d[3] = {unit(engine) - 0.5, unit(engine) - 0.5, unit(engine) - 0.5};
        const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        const bool inside = k % 2 == 0;
        const double at = (a + radius[j]) * (inside ? 1 - 1e-12 : 1 + 1e-12);
        const Particle t = ParticleStore::particle(
            {s.centre(0)[j] + at * d[0] / norm, s.centre(1)[j] + at * d[1] / norm,
             s.centre(2)[j] + at * d[2] / norm},
            {a * a, 0, 0, a * a, 0, a * a});
        const std::vector<pwcontact::Neighbor> found = scene.neighbors(t, 1.0);
        bool has_j = false;
        for (const pwcontact::Neighbor& f : found) has_j = has_j || f.index == j;
        EXPECT_EQ(has_j, inside) << pwcontact::isa_name(isa) << ", sphere " << k;
        if (inside) {
          EXPECT_NE(scene.overlaps(t), MovingScene::none) << pwcontact::isa_name(isa);
        }
      }
    }
  }
}

// Ellipsoids at scales 2^-400 (about 1e-120) .. 2^400, every length a power
// of two times the unit scene's: overlaps, overlap_count and neighbors
// against the brute force. Was: below about 1e-80 the prefilters' projection
// test (r^T Q r, of the fourth power of the lengths) underflowed and
// declared every ellipsoid pair apart.
TEST(MovingScene, EllipsoidsScaledByPowersOfTwoMatchTheBruteForce) {
  std::mt19937_64 engine(23);
  std::uniform_real_distribution<double> unit(0, 1);
  // (At 2^-400 in an open box: brute_mu2's inverse of the box matrix goes
  // through its determinant, of the cube of the lengths, which underflows.)
  for (int e : {0, -300, -400, 400}) {
    const double scale = std::ldexp(1.0, e);
    const Box box = e == -400 ? Box::open() : Box::periodic_box(8 * scale, 8 * scale, 8 * scale);
    auto draw = [&]() {
      const double a = 0.2 + 0.4 * unit(engine);
      return ParticleStore::particle_axes(
          {8 * scale * unit(engine), 8 * scale * unit(engine), 8 * scale * unit(engine)},
          {a * scale, a * (0.3 + unit(engine)) * scale, a * (0.3 + 2 * unit(engine)) * scale},
          random_quaternion(engine));
    };
    ParticleStore s;
    for (int k = 0; k < 300; ++k) s.add_particle(draw());
    const MovingScene scene(s, box);
    std::size_t overlapping = 0;
    for (int k = 0; k < 300; ++k) {
      const Particle t = draw();
      std::size_t expected = 0;
      bool near_tangent = false;
      for (std::size_t i = 0; i < s.size(); ++i) {
        const double mu2 = brute_mu2(box, t, s, i);
        expected += mu2 < 1;
        near_tangent = near_tangent || std::abs(mu2 - 1) < tangency_band;
      }
      if (near_tangent) continue;
      overlapping += expected > 0;
      EXPECT_EQ(scene.overlap_count(t), expected) << "scale 2^" << e << ", trial " << k;
      EXPECT_EQ(scene.overlaps(t) != MovingScene::none, expected > 0)
          << "scale 2^" << e << ", trial " << k;
      EXPECT_EQ(scene.neighbors(t, 1.0, true).size(), expected) << "scale 2^" << e;
    }
    EXPECT_GT(overlapping, 50u) << "scale 2^" << e;
  }
}

TEST(MovingScene, BatchedQueriesAreTheSingleQueriesWhateverTheThreadCount) {
  std::mt19937_64 engine(11);
  const Box box = Box::periodic_box(12, 12, 12);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  for (int n = 0; n < 1500; ++n) s.add_particle(random_particle(engine, s, box, 12));
  const MovingScene scene(s, box);
  std::vector<Particle> trials;
  std::vector<std::int64_t> exclude;
  std::uniform_real_distribution<double> unit(0, 1);
  for (int n = 0; n < 3000; ++n) {
    const std::size_t i = std::size_t(unit(engine) * double(s.size()));
    auto c = s.particle_at(i).centre();
    for (double& x : c) x += 0.3 * (2 * unit(engine) - 1);
    trials.push_back(random_particle(engine, s, box, 12).moved_to(c));
    exclude.push_back(n % 3 ? std::int64_t(i) : MovingScene::none);
  }
  std::vector<std::int64_t> single(trials.size());
  std::size_t overlapping = 0;
  for (std::size_t k = 0; k < trials.size(); ++k) {
    single[k] = scene.overlaps(trials[k], exclude[k]);
    overlapping += single[k] != MovingScene::none;
  }
  EXPECT_GT(overlapping, trials.size() / 10) << "a test of both answers";
  EXPECT_LT(overlapping, trials.size() * 9 / 10) << "a test of both answers";
  for (int threads : {1, 2, 3}) {
    std::vector<std::int64_t> batched(trials.size(), -7);
    scene.overlaps(trials.data(), exclude.data(), trials.size(), batched.data(), threads);
    EXPECT_EQ(batched, single) << threads << " threads";
  }
}

TEST(MovingScene, ParallelMovesAreTheMovesOneAfterAnother) {
  std::mt19937_64 engine(12);
  const Box box = Box::triclinic(30, 30, 30, 0.2, 0.1, -0.1);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  for (int n = 0; n < 12000; ++n) s.add_particle(random_particle(engine, s, box, 30));
  MovingScene parallel(s, box), serial(s, box);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int round = 0; round < 20; ++round) {
    // One move in every fourth cell along each axis (cells apart, so the
    // moves are independent), the cells shifted every round.
    std::vector<std::uint32_t> index;
    std::vector<Particle> moved;
    std::set<std::array<int, 3>> taken;
    for (std::uint32_t i = 0; i < s.size(); ++i) {
      const auto cell = parallel.cell_of_particle(i);
      if ((cell[0] + round) % 4 || (cell[1] + round) % 4 || (cell[2] + round) % 4 ||
          !taken.insert(cell).second)
        continue;
      auto c = parallel.particles().particle_at(i).centre();
      for (double& x : c) x += 0.3 * (2 * unit(engine) - 1);
      index.push_back(i);
      moved.push_back(parallel.particles().particle_at(i).moved_to(c));
    }
    ASSERT_GT(index.size(), 50u) << "round " << round;
    parallel.move_many(index.data(), moved.data(), index.size(), 2);
    for (std::size_t k = 0; k < index.size(); ++k) serial.move(index[k], moved[k]);
    for (std::uint32_t i = 0; i < s.size(); ++i)
      ASSERT_EQ(parallel.cell_of_particle(i),
                parallel.cell_of(parallel.particles().particle_at(i).centre()))
          << "round " << round << ", particle " << i;
  }
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(parallel.particles().centre(k), serial.particles().centre(k));
  EXPECT_EQ(parallel.counters().moves, serial.counters().moves);
  EXPECT_EQ(parallel.counters().cell_changes, serial.counters().cell_changes);
  EXPECT_GT(serial.counters().cell_changes, 0u);
  EXPECT_EQ(serial.counters().rebuilds, 1u) << "small moves need no rebuild";
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Particle p = serial.particles().particle_at(i);
    EXPECT_EQ(parallel.overlaps(p, std::int64_t(i)), serial.overlaps(p, std::int64_t(i))) << i;
  }
  expect_same_as_screen(parallel, "after parallel moves");
}

TEST(MovingScene, ParallelMovesOutOfAnOpenBoxRebuildAsTheMovesOneAfterAnother) {
  // 100 spheres in an open box, 89 of them (the limit, n / 4 + 64) moved
  // out of the grid's region one at a time; then two independent moves, the
  // first taking one more out (one after another: a rebuild before the
  // second move), the second far along x. The parallel path rebuilt once,
  // after both: another grid, and queries after it found another particle
  // first (for 194 of 512 trials that overlap two or more).
  std::mt19937_64 engine(7);
  std::uniform_real_distribution<double> unit(0, 1);
  const std::size_t n = 100;
  ParticleStore s;
  for (std::size_t i = 0; i < n; ++i)
    s.add_axes({10 * unit(engine), 10 * unit(engine), 10 * unit(engine)}, {0.1, 0.1, 0.1},
               {1, 0, 0, 0});
  MovingScene parallel(s, Box::open()), serial(s, Box::open());
  for (std::size_t i = 0; i < 89; ++i) {
    auto c = parallel.particles().particle_at(i).centre();
    c[0] = -50 - unit(engine);
    const Particle p = parallel.particles().particle_at(i).moved_to(c);
    parallel.move(i, p);
    serial.move(i, p);
  }
  ASSERT_EQ(parallel.counters().rebuilds, serial.counters().rebuilds);
  const std::uint32_t index[2] = {95, 97};
  auto c0 = parallel.particles().particle_at(95).centre();
  auto c1 = parallel.particles().particle_at(97).centre();
  c0[0] = -50.5;
  c1[0] = 60;
  const Particle moved[2] = {parallel.particles().particle_at(95).moved_to(c0),
                             parallel.particles().particle_at(97).moved_to(c1)};
  parallel.move_many(index, moved, 2, 2);
  serial.move_many(index, moved, 2, 1);
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(parallel.particles().centre(k), serial.particles().centre(k));
  EXPECT_EQ(parallel.cells(), serial.cells());
  EXPECT_EQ(parallel.counters().rebuilds, serial.counters().rebuilds);
  std::size_t several = 0;
  for (int t = 0; t < 2000; ++t) {
    const Particle trial = parallel.trial_axes(
        {10 * unit(engine), 10 * unit(engine), 10 * unit(engine)}, {3, 3, 3}, {1, 0, 0, 0});
    if (serial.overlap_count(trial) < 2) continue;
    ++several;
    EXPECT_EQ(parallel.overlaps(trial), serial.overlaps(trial)) << "trial " << t;
  }
  EXPECT_GT(several, 100u);
  expect_same_as_screen(parallel, "after parallel moves out of an open box");
}

TEST(MovingScene, AFarParticleInAnOpenBoxLeavesTheCellsOfTheRest) {
  // 20,000 spheroids in a cube of side 60 and one at x = 1e9: the cells grew
  // alike along every axis until one spanned the cube across y and z
  // (39,720 x 1 x 1, every query comparing thousands of particles). The
  // region now leaves the outlier to the outer cells.
  std::mt19937_64 engine(21);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  const Box box = Box::open();
  for (int n = 0; n < 20000; ++n) s.add_particle(random_particle(engine, s, box, 60));
  s.add_axes({1e9, 3, 3}, {0.5, 0.2, 0.2}, {1, 0, 0, 0});
  // And one so far that eps of its coordinate is 2: the coarse test's slack
  // (and so the cells' side) was taken from the coordinates, 4 x 200 wide.
  s.add_axes({-1e16, 3, 3}, {0.5, 0.2, 0.2}, {1, 0, 0, 0});
  MovingScene scene(s, box);
  const auto cells = scene.cells();
  for (int k = 1; k < 3; ++k) EXPECT_GE(cells[std::size_t(k)], 20) << "axis " << k;
  expect_same_as_screen(scene, "one particle at x = 1e9");
  // A trial beside the far particle finds it; moved back among the others,
  // the far one is found there too.
  const Particle beside = scene.trial_axes({1e9 + 0.3, 3, 3}, {0.5, 0.2, 0.2}, {1, 0, 0, 0});
  EXPECT_EQ(scene.overlaps(beside), 20000);
  scene.move(20000, scene.particles().particle_at(20000).moved_to({30, 30, 30}));
  expect_same_as_screen(scene, "the far particle moved back");
}

TEST(MovingScene, ClustersFarApartInAnOpenBoxKeepFineCellsAndLoseNoPairAcrossTheFold) {
  // Two clusters of 3,000 1e6 apart along x: the cells grew over the whole
  // span (27,000 x 1 x 1). The empty stretch between them is now folded out
  // of cell space (screen::fold_empty_stretches). Particles then moved into
  // the folded stretch, about its ends and into its middle, where the fold
  // maps a whole stretch to one point, must still find every partner.
  std::mt19937_64 engine(29);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  const Box box = Box::open();
  for (int n = 0; n < 6000; ++n) {
    Particle p = random_particle(engine, s, box, 25);
    if (n % 2) p = p.moved_to({p.centre()[0] + 1e6, p.centre()[1], p.centre()[2]});
    s.add_particle(p);
  }
  MovingScene scene(s, box);
  const auto cells = scene.cells();
  for (int k = 1; k < 3; ++k) EXPECT_GE(cells[std::size_t(k)], 10) << "axis " << k;
  expect_same_as_screen(scene, "two clusters 1e6 apart");
  // Pairs placed across the stretch's ends (the clusters reach x = 25 and
  // start at 1e6) and in its middle, each checked against the brute force.
  const double spots[] = {25.3, 26.5, 28, 31, 4e5, 5e5 + 0.25, 1e6 - 3, 1e6 - 1.2};
  std::uint32_t moved = 0;
  for (double x : spots)
    for (double dx : {0.0, 0.45}) {
      const std::array<double, 3> c = {x + dx, 12 + dx, 12};
      scene.move(moved, scene.particles().particle_at(moved).moved_to(c));
      ++moved;
    }
  for (double x : spots)
    for (double dx : {-0.3, 0.2, 0.6}) {
      const Particle t = scene.trial_axes({x + dx, 12.1, 12}, {0.5, 0.2, 0.2}, {1, 0, 0, 0});
      expect_query_matches(scene, t, MovingScene::none, "trial at x = " + std::to_string(x + dx));
    }
  expect_same_as_screen(scene, "particles moved into the folded stretch");
}

TEST(MovingScene, ParticlesParkedFarAwayAndBroughtBackLeaveTheCellsFine) {
  // 40 % of the particles moved one by one to x = 1e9 and back: the rebuilds
  // they caused sized the cells over the whole span (39,718 x 1 x 1 for
  // 20,000 particles, queries 9 times slower, and so they stayed after the
  // particles came back). The rebuilds now fold the empty stretch.
  std::mt19937_64 engine(31);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  const Box box = Box::open();
  for (int n = 0; n < 5000; ++n) s.add_particle(random_particle(engine, s, box, 22));
  MovingScene scene(s, box);
  for (bool parked : {true, false}) {
    for (std::uint32_t i = 0; i < 2000; ++i) {
      const std::array<double, 3> c = {(parked ? 1e9 : 0) + 22 * unit(engine), 22 * unit(engine),
                                       22 * unit(engine)};
      scene.move(i, scene.particles().particle_at(i).moved_to(c));
    }
    const auto cells = scene.cells();
    for (int k = 1; k < 3; ++k)
      EXPECT_GE(cells[std::size_t(k)], 10) << (parked ? "parked" : "back") << ", axis " << k;
    EXPECT_GE(scene.counters().rebuilds, 2u);
    expect_same_as_screen(scene, parked ? "2,000 parked at 1e9" : "brought back");
  }
}

TEST(MovingScene, BadInputIsRefusedNamingItWithTheSceneUnchanged) {
  std::mt19937_64 engine(13);
  const Box box = Box::periodic_box(6, 6, 6);
  ParticleStore s;
  s.add_type({0.5, 0.2, 0.2});
  for (int n = 0; n < 100; ++n) s.add_particle(random_particle(engine, s, box, 6));
  MovingScene scene(s, box);
  const Particle good = scene.particles().particle_at(0);
  auto expect_message = [](auto&& call, const std::string& text) {
    try {
      call();
      ADD_FAILURE() << "no exception, expected one naming " << text;
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what() << " / " << text;
    }
  };
  expect_message([&] { scene.move(100, good); }, "particle 100 does not exist");
  expect_message([&] { scene.remove(250); }, "particle 250 does not exist");
  expect_message([&] { scene.trial({0, 0, 0}, {1, 2, 0, 1, 0, 1}); }, "not positive definite");
  expect_message([&] { scene.trial({NAN, 0, 0}, {1, 0, 0, 1, 0, 1}); }, "centre is not finite");
  expect_message([&] { good.moved_to({0, INFINITY, 0}); }, "centre is not finite");
  expect_message([&] { scene.trial_typed({0, 0, 0}, 3, {1, 0, 0, 0}); }, "type 3 does not exist");
  expect_message([&] { scene.trial_axes({0, 0, 0}, {1, -1, 1}, {1, 0, 0, 0}); }, "semi-axes");
  // A particle too large for the box (its reach would wrap around).
  expect_message(
      [&] {
        scene.move(3, scene.trial_axes({0, 0, 0}, {2, 1, 1}, {1, 0, 0, 0}));
      },
      "periodic box is too small");
  const std::uint32_t index[2] = {1, 7};
  const Particle moves[2] = {good, scene.trial_axes({0, 0, 0}, {2, 1, 1}, {1, 0, 0, 0})};
  // (A batch names the move at fault.)
  expect_message([&] { scene.move_many(index, moves, 2); }, "move_many, move 1");
  expect_message([&] { scene.move_many(index, moves, 2); }, "periodic box is too small");
  ParticleStore other;
  other.add_type({0.1, 0.1, 0.1});
  other.add_type({0.1, 0.2, 0.1});
  expect_message(
      [&] {
        scene.insert(other.particle_typed({0, 0, 0}, 1, {1, 0, 0, 0}));
      },
      "type 1 does not exist");
  // Another store's type 0 is another shape: it went in as this scene's
  // type 0 (a sphere of 0.1 stored as the 0.5 x 0.2 x 0.2 type).
  for (const std::uint32_t at : {0u, 1u}) {
    const Particle foreign = other.particle_typed({1, 1, 1}, 0, {1, 0, 0, 0});
    expect_message([&] { scene.insert(foreign); }, "whose shape is not that type's here");
    expect_message([&] { scene.move(at, foreign); }, "whose shape is not that type's here");
    const std::uint32_t one[1] = {at};
    expect_message([&] { scene.move_many(one, &foreign, 1); }, "move_many, move 0");
    EXPECT_FALSE(scene.move_in_own_cells(at, foreign));
  }
  // An exclude that is neither none nor a particle (it was taken as none).
  expect_message([&] { scene.overlaps(good, 100); }, "exclude 100 is neither none");
  expect_message([&] { scene.overlaps(good, -5); }, "exclude -5 is neither none");
  expect_message([&] { scene.neighbors(good, 1.2, false, 100); }, "exclude 100");
  {
    const Particle trials[3] = {good, good, good};
    const std::int64_t excluded[3] = {0, MovingScene::none, 1000};
    std::int64_t first[3];
    expect_message([&] { scene.overlaps(trials, excluded, 3, first); }, "trial 2: exclude 1000");
  }
  // A cutoff whose square underflows is refused saying so (it said "got
  // 0.000000" of a positive, finite 1e-200).
  expect_message([&] { scene.neighbors(good, 1e-200); },
                 "its square a normal number (mu^2 is compared with it), got 1e-200");
  expect_message([&] { scene.cell_of({NAN, 0, 0}); }, "not finite");
  // Unchanged: the same particles, and the same answers as a fresh scene's.
  EXPECT_EQ(scene.size(), 100u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(scene.particles().centre(k), s.centre(k));
  for (int k = 0; k < 6; ++k) EXPECT_EQ(scene.particles().q(k), s.q(k));
  const MovingScene fresh(s, box);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const Particle p = s.particle_at(i);
    EXPECT_EQ(scene.overlap_count(p, std::int64_t(i)), fresh.overlap_count(p, std::int64_t(i)));
  }
  EXPECT_THROW(MovingScene(s, box, {0.5, {}}), std::invalid_argument);
  EXPECT_THROW(scene.neighbors(good, -1), std::invalid_argument);
}

// A trial whose reach to the scene's largest particle wraps around a
// periodic box has no minimum image to answer by: every query refuses it,
// single or batched, rather than answer for the wrong image. (overlaps()
// answered "none" for a needle through a sphere's centre, mu^2 = 0.85 by
// the reference path, where overlap_count refused it.)
TEST(MovingScene, ATrialTooLargeForThePeriodicBoxIsRefusedByEveryQuery) {
  const Box box = Box::periodic_box(4, 4, 4);
  ParticleStore s;
  s.add_axes({2.8, 1.4, 0}, {0.1, 0.1, 0.1}, {1, 0, 0, 0});
  const MovingScene scene(s, box);
  // A needle through the origin along (2, 1, 0), half-length 3.3, through the
  // sphere's centre at this image.
  const double angle = std::atan2(1.0, 2.0);
  const Particle needle = scene.trial_axes({0, 0, 0}, {3.3, 0.05, 0.05},
                                           {std::cos(angle / 2), 0, 0, std::sin(angle / 2)});
  const double r[3] = {2.8, 1.4, 0};
  const auto at_that_image =
      pwcontact::contact_function<double>(r, needle.q().data(), s.particle_at(0).q().data());
  ASSERT_LT(at_that_image.mu2, 1);  // (so "none" would be wrong)
  EXPECT_THROW(scene.overlaps(needle), std::invalid_argument);
  EXPECT_THROW(scene.overlap_count(needle), std::invalid_argument);
  EXPECT_THROW(scene.neighbors(needle, 1.0), std::invalid_argument);
  std::int64_t first = 7;
  EXPECT_THROW(scene.overlaps(&needle, nullptr, 1, &first, 1), std::invalid_argument);
  // A trial that fits is answered: the reach is the trial's and the largest
  // stored particle's, R_t + R_max <= L / 2.
  const Particle fits = scene.trial_axes({2.2, 1.4, 0}, {1.8, 0.05, 0.05}, {1, 0, 0, 0});
  EXPECT_EQ(scene.overlaps(fits), 0);
  EXPECT_EQ(scene.overlap_count(fits), 1u);
}

// A clustered scene (a dense droplet of small spheres in a large box whose
// cells one large sphere sizes) holds memory in proportion to its particles:
// the droplet's cells get rooms of their own. (Every cell had the room of
// the fullest: 496 kB a particle at 1,729 particles, growing as N.)
TEST(MovingScene, AClusteredSceneHoldsMemoryInProportionToItsParticles) {
  for (int side : {8, 16}) {
    ParticleStore s;
    s.add_axes({30, 30, 30}, {1, 1, 1}, {1, 0, 0, 0});
    for (int a = 0; a < side; ++a)
      for (int b = 0; b < side; ++b)
        for (int c = 0; c < side; ++c)  // radius 0.05, 0.11 apart: none overlap
          s.add_axes({5 + 0.11 * a, 5 + 0.11 * b, 5 + 0.11 * c}, {0.05, 0.05, 0.05}, {1, 0, 0, 0});
    MovingScene scene(s, Box::periodic_box(60, 60, 60));
    const double per_particle = double(scene.bytes()) / double(scene.size());
    std::printf("[ measured ] %zu particles, %d^3 cells: %.1f kB a particle\n", scene.size(),
                scene.cells()[0], per_particle / 1024);
    // ~5 kB: 16 + 24 slots of ~100 bytes per cell, at two cells a particle.
    EXPECT_LT(per_particle, 16 * 1024.0);
    // The droplet doubles by inserts (a copy moved by half a spacing): its
    // cells overflow and the grid is rebuilt; still in proportion, and the
    // answers those of a fresh scene.
    const std::size_t rebuilds = scene.counters().rebuilds;
    for (std::size_t i = 1; i < s.size(); ++i) {
      const auto c = s.particle_at(i).centre();
      scene.insert(scene.trial_axes({c[0] + 0.055, c[1] + 0.055, c[2] + 0.055}, {0.05, 0.05, 0.05},
                                    {1, 0, 0, 0}));
    }
    EXPECT_GT(scene.counters().rebuilds, rebuilds);
    EXPECT_LT(double(scene.bytes()) / double(scene.size()), 16 * 1024.0);
    const MovingScene fresh(scene.particles(), Box::periodic_box(60, 60, 60));
    const Particle probe = scene.trial_axes({5 + 0.11 * side / 2, 5 + 0.11 * side / 2, 5.3},
                                            {0.3, 0.3, 0.3}, {1, 0, 0, 0});
    EXPECT_EQ(scene.overlap_count(probe), fresh.overlap_count(probe));
    EXPECT_GT(scene.overlap_count(probe), 10u);
    // Every particle's overlaps (cells of rooms of their own) are those a
    // screen finds.
    pwcontact::ScreenedPairs pairs;
    pwcontact::screen_pairs(scene.particles(), Box::periodic_box(60, 60, 60), {}, pairs);
    const auto counts = pwcontact::pair_counts(pairs, scene.size());
    ASSERT_GT(pairs.size(), scene.size());
    for (std::size_t i = 0; i < scene.size(); ++i) {
      const Particle p = scene.particles().particle_at(i);
      ASSERT_EQ(scene.overlap_count(p, std::int64_t(i)), counts[i]) << "particle " << i;
      EXPECT_EQ(scene.overlaps(p, std::int64_t(i)) != MovingScene::none, counts[i] > 0);
    }
  }
}

// A scene built empty (or emptied) takes its cells' size from the particles
// that come: the same answers as the scene built from them. (An empty scene
// sized its cells for a radius of 1, and then refused every query in a box
// narrower than 4, naming that radius.)
TEST(MovingScene, AnEmptySceneFilledByInsertsAnswersAsTheSceneBuiltFromItsParticles) {
  const Box box = Box::periodic_box(3, 3, 3);
  std::mt19937_64 engine(5);
  ParticleStore s;
  s.add_type({0.1, 0.07, 0.05});
  for (int n = 0; n < 200; ++n) s.add_particle(random_particle(engine, s, box, 3));
  ParticleStore types_only;  // (the typed particles need their type)
  types_only.add_type({0.1, 0.07, 0.05});
  MovingScene filled(types_only, box);
  for (int round = 0; round < 2; ++round) {
    // After every insert, the particles so far answer as in a scene built
    // from them.
    ParticleStore so_far = types_only;
    for (std::size_t i = 0; i < s.size(); ++i) {
      filled.insert(s.particle_at(i));
      so_far.add_particle(s.particle_at(i));
      if (i % 10 != 0 && i > 10) continue;
      const MovingScene built(so_far, box);
      for (std::size_t j = 0; j <= i; ++j) {
        const Particle p = s.particle_at(j);
        const auto expected = built.neighbors(p, 1.0, false, std::int64_t(j));
        const auto found = filled.neighbors(p, 1.0, false, std::int64_t(j));
        ASSERT_EQ(found.size(), expected.size()) << "particle " << j << " of " << i + 1;
        for (std::size_t k = 0; k < found.size(); ++k) EXPECT_EQ(found[k].index, expected[k].index);
        EXPECT_EQ(filled.overlaps(p, std::int64_t(j)), built.overlaps(p, std::int64_t(j)));
      }
    }
    // Emptied, then filled again.
    while (filled.size() > 0) filled.remove(filled.size() - 1);
  }
}

}  // namespace

namespace {

TEST(HardParticleMC, CompressesWithoutEverOverlappingAndTheLastStateHasNone) {
  pwcontact::HardParticleMCOptions options;
  options.packing = 0.35;
  options.seed = 3;
  auto mc = pwcontact::HardParticleMC::dilute_spheroids(125, 3, 3, options);
  std::size_t sweeps = 0;
  mc.compress_to_packing(20000, [&](std::size_t done, double, double) { sweeps = done; });
  EXPECT_NEAR(mc.packing(), 0.35, 1e-9);
  EXPECT_GT(sweeps, 10u);
  // The final state against the brute force over every image.
  const ParticleStore& s = mc.particles();
  std::size_t overlapping = 0;
  for (std::size_t i = 0; i < s.size(); ++i)
    for (std::size_t j = i + 1; j < s.size(); ++j)
      overlapping += brute_mu2(mc.box(), s.particle_at(i), s, j) < 1;
  EXPECT_EQ(overlapping, 0u);
  EXPECT_EQ(mc.overlapping_pairs(), 0u);
}

TEST(HardParticleMC, EveryFaceBetweenCellsIsCrossedWithAnOddNumberOfCells) {
  // 256 hard spheres (diameter 1) on an fcc lattice at packing 0.3: 7 cells
  // along each axis, 64 domains, checkerboard sweeps. With the grouping
  // shifted by 0 or 1 cell only, the face between cells 5 and 6 was between
  // domains in every sweep and no centre ever crossed it.
  const int k = 4;
  const std::size_t n = 4 * k * k * k;
  const double length = std::cbrt(double(n) * M_PI / 6 / 0.3), a = length / k;
  const double base[4][3] = {{0, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
  std::vector<std::array<double, 3>> centre;
  for (int x = 0; x < k; ++x)
    for (int y = 0; y < k; ++y)
      for (int z = 0; z < k; ++z)
        for (const auto& b : base)
          centre.push_back({(x + b[0] + 0.25) * a, (y + b[1] + 0.25) * a, (z + b[2] + 0.25) * a});
  const Box box = Box::periodic_box(length, length, length);
  const std::array<int, 3> cells = [&] {
    ParticleStore s;
    for (const auto& c : centre) s.add_axes(c, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
    return MovingScene(s, box).cells();  // (the grid the Monte Carlo scene makes)
  }();
  ASSERT_EQ(cells[0] % 2, 1) << cells[0] << " cells: the case needs an odd count";
  ASSERT_TRUE(cells[1] == cells[0] && cells[2] == cells[0]);
  pwcontact::HardParticleMCOptions options;
  options.translation = 0.12;
  options.rotation = 0;
  options.adapt_steps = false;
  options.seed = 7;
  options.threads = 1;
  pwcontact::HardParticleMC mc(box, centre, std::vector<std::array<double, 3>>(n, {0.5, 0.5, 0.5}),
                               std::vector<std::array<double, 4>>(n, {1, 0, 0, 0}), options);
  // Crossings of each face (x = c L / cells along each axis), counted from
  // the centres before and after each sweep (they are kept unwrapped).
  std::vector<std::array<std::size_t, 3>> crossings(std::size_t(cells[0]), {0, 0, 0});
  std::size_t left_domain = 0;
  auto wrapped_count = [&](double x, int c) {
    return std::floor((x - c * length / cells[0]) / length);
  };
  for (int sweep = 0; sweep < 400; ++sweep) {
    std::vector<std::array<double, 3>> before(n);
    for (std::size_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) before[i][std::size_t(d)] = mc.particles().centre(d)[i];
    left_domain += mc.sweep().left_domain;
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < cells[0]; ++c)
        for (int d = 0; d < 3; ++d)
          crossings[std::size_t(c)][std::size_t(d)] +=
              wrapped_count(mc.particles().centre(d)[i], c) !=
              wrapped_count(before[i][std::size_t(d)], c);
  }
  EXPECT_GT(left_domain, 0u) << "the checkerboard path (the one-at-a-time path has no domains)";
  for (int c = 0; c < cells[0]; ++c)
    for (int d = 0; d < 3; ++d)
      EXPECT_GT(crossings[std::size_t(c)][std::size_t(d)], 0u)
          << "the face between cells " << (c + cells[0] - 1) % cells[0] << " and " << c
          << " along axis " << d;
  EXPECT_EQ(mc.overlapping_pairs(), 0u);
}

TEST(HardParticleMC, MovesIntoFullCellsAreDeferredAndGiveTheSameStateForEveryThreadCount) {
  // 1728 small spheres (radius 0.2) packed in a cube of about one cell of a
  // grid sized for one large sphere (radius 2): the cluster spreads into
  // cells of few slots, which fill up, so that accepted moves into a full
  // cell are deferred past their colour of the checkerboard (and the cells
  // rebuilt), again and again. Spheres are decided in closed form, in the
  // baseline arithmetic: the trajectory is the same on every instruction
  // set (11 deferred moves in 30 sweeps).
  const double length = 36;
  std::vector<std::array<double, 3>> centre = {{27, 27, 27}}, axes = {{2, 2, 2}};
  for (int x = 0; x < 12; ++x)
    for (int y = 0; y < 12; ++y)
      for (int z = 0; z < 12; ++z) {
        centre.push_back({4.3 + 0.41 * x, 4.3 + 0.41 * y, 4.3 + 0.41 * z});
        axes.push_back({0.2, 0.2, 0.2});
      }
  const std::size_t n = centre.size();
  const Box box = Box::periodic_box(length, length, length);
  std::vector<std::vector<double>> states;
  for (int threads : {1, 2, 3}) {
    pwcontact::HardParticleMCOptions options;
    options.translation = 1.5;
    options.rotation = 0;
    options.adapt_steps = false;
    options.seed = 5;
    options.threads = threads;
    pwcontact::HardParticleMC mc(box, centre, axes,
                                 std::vector<std::array<double, 4>>(n, {1, 0, 0, 0}), options);
    std::size_t deferred = 0, accepted = 0, left_domain = 0;
    for (int sweep = 0; sweep < 30; ++sweep) {
      const pwcontact::SweepReport r = mc.sweep();
      EXPECT_LE(r.deferred, r.accepted);
      deferred += r.deferred;
      accepted += r.accepted;
      left_domain += r.left_domain;
      ASSERT_EQ(mc.overlapping_pairs(), 0u) << "sweep " << sweep << ", " << threads << " threads";
    }
    EXPECT_GT(left_domain, 0u) << "the checkerboard path (the one-at-a-time path has no domains)";
    EXPECT_GE(deferred, 8u) << "moves into full cells, of " << accepted << " accepted";
    // Spheres overlap when their centres, by the nearest image, are closer
    // than the sum of their radii: every pair, once at the end.
    const ParticleStore& s = mc.particles();
    std::size_t overlapping = 0;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) {
        double rr = 0;
        for (int k = 0; k < 3; ++k) {
          double d = s.centre(k)[j] - s.centre(k)[i];
          d -= length * std::nearbyint(d / length);
          rr += d * d;
        }
        const double sum = axes[i][0] + axes[j][0];
        overlapping += rr < sum * sum;
      }
    EXPECT_EQ(overlapping, 0u);
    std::vector<double> all;
    for (int k = 0; k < 3; ++k) all.insert(all.end(), s.centre(k).begin(), s.centre(k).end());
    states.push_back(all);
  }
  EXPECT_EQ(states[0], states[1]);
  EXPECT_EQ(states[0], states[2]);
}

TEST(HardParticleMC, OrientationsAreUnitQuaternions) {
  // (A quaternion of norm 2 was kept as given, and written so to GSD.)
  const pwcontact::HardParticleMC mc(
      Box::periodic_box(10, 10, 10), {{1, 1, 1}, {5, 5, 5}}, {{0.5, 0.3, 0.3}, {0.5, 0.3, 0.3}},
      {{2, 0, 0, 0}, {0.6, 0.8, 0, 0}}, pwcontact::HardParticleMCOptions{});
  EXPECT_EQ(mc.orientation()[0], (std::array<double, 4>{1, 0, 0, 0}));
  EXPECT_EQ(mc.orientation()[1], (std::array<double, 4>{0.6, 0.8, 0, 0}))
      << "a quaternion unit to rounding is kept as given";
}

TEST(HardParticleMC, CheckerboardSweepsGiveTheSameStateForEveryThreadCount) {
  // 2000 spheroids at packing ~0.06: 9 x 9 x 9 domains, checkerboard sweeps.
  std::vector<std::vector<double>> centres;
  for (int threads : {1, 2, 3}) {
    pwcontact::HardParticleMCOptions options;
    options.threads = threads;
    options.translation = 0.5;
    auto mc = pwcontact::HardParticleMC::dilute_spheroids(2000, 4, 3, options);
    std::size_t accepted = 0, proposed = 0;
    for (int sweep = 0; sweep < 4; ++sweep) {
      const auto r = mc.sweep();
      accepted += r.accepted;
      proposed += r.proposed;
    }
    EXPECT_GT(accepted, proposed / 10);
    EXPECT_EQ(mc.overlapping_pairs(), 0u);
    std::vector<double> all;
    for (int k = 0; k < 3; ++k)
      all.insert(all.end(), mc.particles().centre(k).begin(), mc.particles().centre(k).end());
    centres.push_back(all);
  }
  EXPECT_EQ(centres[0], centres[1]);
  EXPECT_EQ(centres[0], centres[2]);
}

}  // namespace
