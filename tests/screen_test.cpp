// Screening a scene against a brute-force O(N^2) scan with the scalar
// reference path: the same pair sets on random scenes (monodisperse and
// polydisperse, aspect ratios up to 50, periodic and open, dense and sparse,
// pairs across the periodic boundary). Pairs within 1e-9 of the cutoff
// (|mu^2 - cutoff^2| <= 1e-9 cutoff^2, the overlap answers' documented
// band) may differ; they are counted and printed.
#include <gtest/gtest.h>
#include <omp.h>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "pwcontact/pwcontact.hpp"
#include "screen/cell_lists.hpp"
#include "screen/radix_sort.hpp"
#include "test_support.hpp"

namespace {

using pwcontact::Box;
using pwcontact::ParticleStore;
using pwcontact::ScreenedPairs;
using pwcontact::ScreenOptions;
using pwcontact::ScreenReport;

struct SceneSpec {
  std::size_t particles;
  double min_aspect, max_aspect;  // spheroids: polar / equatorial radius
  double min_size, max_size;      // equatorial radius, log-uniform
  double box;                     // edge of the cube the centres are drawn in
  bool periodic;
  std::uint64_t seed;
};

// Random spheroids of the spec, uniformly placed, random orientations.
ParticleStore make_scene(const SceneSpec& spec) {
  std::mt19937_64 engine(spec.seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore store;
  for (std::size_t n = 0; n < spec.particles; ++n) {
    const double size = spec.min_size * std::pow(spec.max_size / spec.min_size, unit(engine));
    const double aspect =
        spec.min_aspect * std::pow(spec.max_aspect / spec.min_aspect, unit(engine));
    std::array<double, 4> q;
    for (double& c : q) c = normal(engine);
    store.add_axes({spec.box * unit(engine), spec.box * unit(engine), spec.box * unit(engine)},
                   {size, size, size * aspect}, q);
  }
  return store;
}

Box box_of(const SceneSpec& spec) {
  return spec.periodic ? Box::periodic_box(spec.box, spec.box, spec.box) : Box::open();
}

// r12 = c_j - c_i, by the minimum image in a periodic box.
std::array<double, 3> separation(const ParticleStore& s, const Box& box, std::size_t i,
                                 std::size_t j) {
  std::array<double, 3> r;
  for (int k = 0; k < 3; ++k) {
    r[k] = s.centre(k)[j] - s.centre(k)[i];
    if (box.periodic) r[k] -= box.length[k] * std::nearbyint(r[k] / box.length[k]);
  }
  return r;
}

std::array<double, 6> form(const ParticleStore& s, std::size_t i) {
  std::array<double, 6> q;
  for (int k = 0; k < 6; ++k) q[k] = s.q(k)[i];
  return q;
}

double reference_mu2(const ParticleStore& s, const Box& box, std::size_t i, std::size_t j) {
  const auto r = separation(s, box, i, j);
  const auto q1 = form(s, i), q2 = form(s, j);
  const auto result = pwcontact::contact_function<double>(r.data(), q1.data(), q2.data());
  EXPECT_EQ(result.status, pwcontact::Status::ok) << "pair " << i << " " << j;
  return result.mu2;
}

// Every pair (i < j) with mu^2 < cutoff^2 by the scalar reference path.
std::set<std::pair<std::uint32_t, std::uint32_t>> brute_force(const ParticleStore& s,
                                                              const Box& box, double cutoff) {
  const std::size_t n = s.size();
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> rows(n);
#pragma omp parallel for schedule(dynamic, 8)
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      if (reference_mu2(s, box, i, j) < cutoff * cutoff)
        rows[i].push_back({std::uint32_t(i), std::uint32_t(j)});
  std::set<std::pair<std::uint32_t, std::uint32_t>> all;
  for (const auto& row : rows) all.insert(row.begin(), row.end());
  return all;
}

// The largest relative error of the pairs' mu^2 against the reference path.
double largest_mu2_error(const ParticleStore& s, const Box& box, const ScreenedPairs& pairs) {
  double worst = 0;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const double exact = reference_mu2(s, box, pairs.i[k], pairs.j[k]);
    worst = std::max(worst, std::abs(pairs.mu2[k] - exact) / exact);
  }
  return worst;
}

struct Comparison {
  std::size_t found = 0, expected = 0, differing_within_band = 0, across_boundary = 0;
  ScreenReport report;  // expect_same_pairs: the screen's
};

// The screen's pairs against the brute force: sorted, i < j, and the same
// set except for pairs within the band.
Comparison compare(const ParticleStore& s, const Box& box, double cutoff, const ScreenedPairs& got,
                   const std::string& what) {
  Comparison c;
  c.found = got.size();
  std::set<std::pair<std::uint32_t, std::uint32_t>> screened;
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_LT(got.i[k], got.j[k]) << what << ", entry " << k;
    if (k > 0) {
      EXPECT_LT(std::make_pair(got.i[k - 1], got.j[k - 1]), std::make_pair(got.i[k], got.j[k]))
          << what << ": not sorted by i then j at entry " << k;
    }
    screened.insert({got.i[k], got.j[k]});
    // Across the boundary: the minimum image differs from the plain difference.
    bool across = false;
    for (int a = 0; a < 3; ++a)
      across = across || (box.periodic && std::abs(s.centre(a)[got.j[k]] - s.centre(a)[got.i[k]]) >
                                              box.length[a] / 2);
    c.across_boundary += across;
  }
  const auto expected = brute_force(s, box, cutoff);
  c.expected = expected.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> differ;
  std::set_symmetric_difference(screened.begin(), screened.end(), expected.begin(), expected.end(),
                                std::back_inserter(differ));
  for (const auto& [i, j] : differ) {
    const double mu2 = reference_mu2(s, box, i, j);
    const double band = 1e-9 * cutoff * cutoff;
    if (std::abs(mu2 - cutoff * cutoff) <= band) {
      ++c.differing_within_band;
      continue;
    }
    ADD_FAILURE() << what << ": pair " << i << " " << j << " (mu^2 " << mu2 << ", cutoff^2 "
                  << cutoff * cutoff << ") " << (screened.count({i, j}) ? "found" : "missed")
                  << " by the screen, the opposite by the brute force";
  }
  std::printf(
      "[ measured ] %s: %zu pairs found, %zu expected, %zu differing within 1e-9 of the "
      "cutoff, %zu across the periodic boundary\n",
      what.c_str(), c.found, c.expected, c.differing_within_band, c.across_boundary);
  return c;
}

ScreenReport screen(const ParticleStore& s, const Box& box, double cutoff, ScreenedPairs& out,
                    bool with_mu2 = false, int threads = 0) {
  ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = with_mu2;
  options.threads = threads;
  return pwcontact::screen_pairs(s, box, options, out);
}

// A scene of the spec, screened and compared; the stages must add up.
Comparison expect_same_pairs(const SceneSpec& spec, double cutoff, const std::string& what) {
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  ScreenedPairs got;
  const ScreenReport report = screen(s, box, cutoff, got);
  EXPECT_EQ(report.particles, spec.particles);
  EXPECT_EQ(report.candidate_pairs, report.decided_out + report.decided_out_by_projection +
                                        report.decided_in + report.decided_spheres +
                                        report.decided_same_form + report.solved)
      << what;
  EXPECT_EQ(report.found, got.size()) << what;
  EXPECT_EQ(report.invalid, 0u) << what;
  std::printf(
      "[ measured ] %s: %zu size classes, %zu candidates, %zu out by the bounding "
      "spheres and %zu by projections, %zu in by the inscribed spheres, %zu solved\n",
      what.c_str(), report.size_classes, report.candidate_pairs, report.decided_out,
      report.decided_out_by_projection, report.decided_in, report.solved);
  Comparison c = compare(s, box, cutoff, got, what);
  c.report = report;
  return c;
}

TEST(Screen, MonodisperseSpheroidsInAPeriodicBoxMatchTheBruteForce) {
  // Aspect ratios 1/3 .. 3, packing fraction ~0.3 (random placement: dense,
  // many overlaps), pairs across the boundary.
  const Comparison c =
      expect_same_pairs({1000, 1.0 / 3, 3, 0.5, 0.5, 9.0, true, 1}, 1, "monodisperse, periodic");
  EXPECT_GT(c.expected, 200u) << "the scene should be dense";
  EXPECT_GT(c.across_boundary, 10u) << "pairs across the periodic boundary should be exercised";
}

TEST(Screen, PolydisperseEllipsoidsInOpenBoundariesMatchTheBruteForce) {
  // Sizes over a factor 20 (several size classes), aspect ratios 1/5 .. 5.
  expect_same_pairs({1200, 0.2, 5, 0.05, 1.0, 12.0, false, 2}, 1, "polydisperse, open");
}

TEST(Screen, NeedlesAndDiscsWithAspectRatiosTo50MatchTheBruteForce) {
  // Equatorial radii 0.03 .. 0.05: needles up to 2.5 long, discs 6e-4 thin;
  // enough of them that many touch.
  const Comparison periodic = expect_same_pairs({3000, 1.0 / 50, 50, 0.03, 0.05, 10.5, true, 3}, 1,
                                                "aspect to 50, periodic");
  const Comparison open =
      expect_same_pairs({3000, 1.0 / 50, 50, 0.03, 0.05, 10.5, false, 4}, 1, "aspect to 50, open");
  EXPECT_GT(periodic.expected, 50u);
  EXPECT_GT(open.expected, 50u);
  // Elongated shapes: the projections on r12 decide many pairs the bounding
  // spheres cannot (and the brute force agrees with every one of them).
  EXPECT_GT(periodic.report.decided_out_by_projection, 1000u);
}

TEST(Screen, SparseScenesMatchTheBruteForce) {
  expect_same_pairs({600, 0.5, 2, 0.2, 0.5, 40.0, true, 5}, 1, "sparse, periodic");
  expect_same_pairs({600, 0.5, 2, 0.2, 0.5, 40.0, false, 6}, 1, "sparse, open");
}

TEST(Screen, NeighbourListsWithASkinMatchTheBruteForceAndReportMu2) {
  // cutoff 1.3 with mu^2: every pair found, with the batch path's mu^2 within
  // its double accuracy of the reference's (1e-13 relative, the batch
  // path's documented bound on compact shapes).
  const SceneSpec spec{900, 0.25, 4, 0.1, 0.5, 11.0, true, 7};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  ScreenedPairs got;
  const ScreenReport report = screen(s, box, 1.3, got, true);
  EXPECT_EQ(report.decided_in, 0u) << "with mu^2 every pair within reach is solved";
  ASSERT_EQ(got.mu2.size(), got.size());
  const double worst = largest_mu2_error(s, box, got);
  std::printf("[ measured ] neighbour list: max relative error of mu^2 %.3g\n", worst);
  EXPECT_LE(worst, 1e-13);
  compare(s, box, 1.3, got, "neighbour list, cutoff 1.3");
}

TEST(Screen, PerParticleCountsAndNeighbourListsHoldEveryPairOfTheBruteForce) {
  const SceneSpec spec{900, 0.25, 4, 0.1, 0.5, 11.0, true, 17};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  ScreenedPairs got;
  screen(s, box, 1.3, got, true);
  const auto expected = brute_force(s, box, 1.3);
  const Comparison c = compare(s, box, 1.3, got, "per-particle outputs");
  ASSERT_EQ(c.differing_within_band, 0u) << "the expectations below assume the same pairs";
  const std::size_t n = s.size();
  // Counts and rows straight from the brute force's pairs.
  std::vector<std::uint32_t> counts(n, 0);
  std::vector<std::vector<std::uint32_t>> rows(n), upper_rows(n);
  for (const auto& [i, j] : expected) {
    ++counts[i];
    ++counts[j];
    rows[i].push_back(j);
    rows[j].push_back(i);
    upper_rows[i].push_back(j);
  }
  EXPECT_EQ(pwcontact::pair_counts(got, n), counts);
  for (bool both : {true, false}) {
    const auto list = pwcontact::neighbor_list(got, n, both);
    ASSERT_EQ(list.offsets.size(), n + 1);
    ASSERT_EQ(list.mu2.size(), list.neighbors.size());
    for (std::size_t p = 0; p < n; ++p) {
      auto row = both ? rows[p] : upper_rows[p];
      std::sort(row.begin(), row.end());
      const std::vector<std::uint32_t> listed(list.neighbors.begin() + list.offsets[p],
                                              list.neighbors.begin() + list.offsets[p + 1]);
      ASSERT_EQ(listed, row) << "particle " << p << (both ? "" : ", upper rows");
      // mu^2 belongs to its neighbour (the screen's double accuracy, as above).
      for (std::size_t k = list.offsets[p]; k < list.offsets[p + 1]; ++k) {
        const double exact = reference_mu2(s, box, p, list.neighbors[k]);
        EXPECT_LE(std::abs(list.mu2[k] - exact), 1e-13 * exact) << p << " " << list.neighbors[k];
      }
    }
  }
  EXPECT_GT(expected.size(), 300u) << "the scene should have many pairs";
  // Pairs not as the screen gives them are refused, not miscounted.
  ScreenedPairs unsorted = got;
  std::swap(unsorted.i[0], unsorted.i[1]);
  std::swap(unsorted.j[0], unsorted.j[1]);
  EXPECT_THROW(pwcontact::neighbor_list(unsorted, n), std::invalid_argument);
  EXPECT_THROW(pwcontact::pair_counts(got, got.j.back()), std::invalid_argument);
  ScreenedPairs reversed{{3}, {2}, {}};
  EXPECT_THROW(pwcontact::pair_counts(reversed, n), std::invalid_argument);
}

TEST(Screen, PairsOfSpheresAreDecidedInClosedFormWithoutASolve) {
  // Polydisperse spheres (aspect 1; radii 0.2 .. 1), dense, periodic: every
  // pair the bounding spheres leave is decided by mu = |r| / (a_i + a_j).
  const SceneSpec spec{1000, 1, 1, 0.2, 1.0, 10.0, true, 9};
  const ParticleStore s = make_scene(spec);
  for (std::size_t i = 0; i < s.size(); ++i) ASSERT_GT(s.sphere_radius()[i], 0) << i;
  const Box box = box_of(spec);
  ScreenedPairs got;
  const ScreenReport report = screen(s, box, 1, got);
  EXPECT_EQ(report.solved, 0u);
  EXPECT_GT(report.decided_spheres, 500u);
  const Comparison c = compare(s, box, 1, got, "spheres");
  EXPECT_GT(c.expected, 500u);
  // With mu^2: the closed form to a few roundings of the reference's.
  ScreenedPairs with_mu2;
  screen(s, box, 1.2, with_mu2, true);
  const double worst = largest_mu2_error(s, box, with_mu2);
  EXPECT_LE(worst, 1e-14) << "a few roundings of |r|^2 / (a_i + a_j)^2";
  compare(s, box, 1.2, with_mu2, "spheres, cutoff 1.2");
}

TEST(Screen, IdenticalShapesAreDetectedAndMatchTheBruteForce) {
  // One shape (semi-axes 0.3, 0.3, 0.9), random orientations: one size class
  // and one reach for every pair; a scene of varied shapes is not taken for one.
  const SceneSpec spec{1500, 3, 3, 0.3, 0.3, 10.0, true, 21};
  const Comparison c = expect_same_pairs(spec, 1, "identical shapes, periodic");
  EXPECT_TRUE(c.report.identical_shapes);
  EXPECT_EQ(c.report.size_classes, 1u);
  EXPECT_GT(c.expected, 200u);
  expect_same_pairs({1500, 3, 3, 0.3, 0.3, 12.0, false, 22}, 1.2, "identical shapes, open, 1.2");
  ScreenedPairs varied;
  EXPECT_FALSE(screen(make_scene({500, 0.5, 2, 0.3, 0.3, 10.0, true, 23}), box_of(spec), 1, varied)
                   .identical_shapes);
}

// A scene of the spec whose last `planted` particles (other shapes) sit
// exactly on the centres of earlier ones: coincident centres, the most
// overlapping pairs there are.
ParticleStore scene_with_coincident_centres(const SceneSpec& spec, std::size_t planted) {
  const ParticleStore base = make_scene(spec);
  std::mt19937_64 engine(spec.seed + 100);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore store;
  for (std::size_t i = 0; i < base.size(); ++i) {
    std::array<double, 6> q;
    for (int k = 0; k < 6; ++k) q[k] = base.q(k)[i];
    const std::size_t from = i >= base.size() - planted ? i - (base.size() - planted) : i;
    store.add({base.centre(0)[from], base.centre(1)[from], base.centre(2)[from]}, q);
  }
  return store;
}

TEST(Screen, CoincidentCentresAreFoundWithAndWithoutMu2) {
  // Was: with mu^2 the projection prefilter's test read 0 >= 0 at r12 = 0
  // and dropped every such pair of non-spherical particles.
  const SceneSpec spec{2000, 0.3, 3, 0.2, 0.6, 14.0, true, 41};
  const ParticleStore s = scene_with_coincident_centres(spec, 50);
  const Box box = box_of(spec);
  for (bool with_mu2 : {false, true}) {
    ScreenedPairs got;
    screen(s, box, 1, got, with_mu2);
    std::set<std::pair<std::uint32_t, std::uint32_t>> found;
    for (std::size_t k = 0; k < got.size(); ++k) found.insert({got.i[k], got.j[k]});
    for (std::uint32_t k = 0; k < 50; ++k)
      EXPECT_TRUE(found.count({k, std::uint32_t(spec.particles - 50 + k)}))
          << "coincident pair " << k << (with_mu2 ? ", with mu2" : "");
    compare(s, box, 1, got, with_mu2 ? "coincident centres, with mu2" : "coincident centres");
  }
}

// One scene at scales 2^-480 (about 1e-144) .. 2^400: every length times a
// power of two, so the forms scale exactly and mu^2 does not change. Was:
// below about 1e-80 the projections' r^T Q r (of the fourth power of the
// lengths) underflowed to 0 and every ellipsoid pair was "apart".
TEST(Screen, ASceneScaledByPowersOfTwoGivesTheBruteForcesPairs) {
  std::mt19937_64 engine(61);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  struct Drawn {
    std::array<double, 3> centre, axes;
    std::array<double, 4> q;
  };
  std::vector<Drawn> drawn;
  for (int n = 0; n < 400; ++n) {
    Drawn d;
    for (double& c : d.centre) c = 9 * unit(engine);
    const double a = 0.2 + 0.4 * unit(engine);
    d.axes = {a, a * (0.3 + unit(engine)), a * (0.3 + 2 * unit(engine))};
    if (n % 10 == 0) d.axes = {a, a, a};  // some spheres
    for (double& c : d.q) c = normal(engine);
    drawn.push_back(d);
  }
  std::set<std::pair<std::uint32_t, std::uint32_t>> at_one;
  for (int e : {0, -240, -300, -400, -480, 300, 400}) {
    const double scale = std::ldexp(1.0, e);
    ParticleStore s;
    for (const Drawn& d : drawn)
      s.add_axes({d.centre[0] * scale, d.centre[1] * scale, d.centre[2] * scale},
                 {d.axes[0] * scale, d.axes[1] * scale, d.axes[2] * scale}, d.q);
    for (const Box& box : {Box::periodic_box(9 * scale, 9 * scale, 9 * scale), Box::open()}) {
      const std::string what =
          "scale 2^" + std::to_string(e) + (box.periodic ? ", periodic" : ", open");
      ScreenedPairs got;
      screen(s, box, 1, got);
      const Comparison c = compare(s, box, 1, got, what);
      EXPECT_GT(c.expected, 100u) << what;
      std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;
      for (std::size_t k = 0; k < got.size(); ++k) pairs.insert({got.i[k], got.j[k]});
      if (e == 0 && box.periodic) at_one = pairs;
      if (box.periodic) {
        EXPECT_EQ(pairs, at_one) << what;
      }
    }
  }
}

// The demo's scene generators refuse what would make no scene with an
// exception the caller can catch. Was: a largest aspect ratio of 0, NaN or
// 1e300 made forms the store refuses, thrown inside the OpenMP region, and
// the program (a Python interpreter) ended in std::terminate.
TEST(Screen, SceneGeneratorsRefuseBadArgumentsWithAnExceptionFromEveryThread) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (double aspect : {0.0, 0.5, -1.0, nan, inf}) {
    EXPECT_THROW(pwcontact::spheroid_scene(10000, 1, 0.3, aspect, false, 2), std::invalid_argument)
        << aspect;
    EXPECT_THROW(pwcontact::ellipse_scene(10000, 1, 0.3, aspect, 2), std::invalid_argument)
        << aspect;
  }
  for (double packing : {0.0, -0.3, 1.0, 5.0, nan, inf}) {
    EXPECT_THROW(pwcontact::spheroid_scene(10000, 1, packing, 3, false, 2), std::invalid_argument)
        << packing;
    EXPECT_THROW(pwcontact::ellipse_scene(10000, 1, packing, 3, 2), std::invalid_argument)
        << packing;
  }
  // Finite but too elongated for a definite form: refused by the store,
  // inside the region, on both threads' blocks.
  try {
    pwcontact::spheroid_scene(20000, 1, 0.3, 1e300, false, 2);
    ADD_FAILURE() << "an aspect ratio of 1e300 was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("particle"), std::string::npos) << e.what();
  }
  // A progress callback that throws (one thread: the callback is called by
  // thread 0 only, which with two might take no block; a team of one is an
  // OpenMP region all the same).
  EXPECT_THROW(pwcontact::spheroid_scene(20000, 1, 0.3, 3, false, 1,
                                         [](double) { throw std::runtime_error("stop"); }),
               std::runtime_error);
  EXPECT_EQ(pwcontact::spheroid_scene(20000, 1, 0.3, 3, false, 2).particles.size(), 20000u);
}

TEST(Screen, NearlyCoincidentCentresWhoseMu2UnderflowsAreFound) {
  // mu^2 below the smallest normal number (|r12| ~ 1e-170): out of the batch
  // path's range, but an overlap all the same.
  ParticleStore s;
  s.add_axes({1, 1, 1}, {0.3, 0.5, 1}, {1, 0.2, 0.3, 0.4});
  s.add_axes({1 + 1e-170, 1, 1}, {0.2, 0.7, 0.4}, {0.3, 1, 0.2, 0.1});
  s.add_axes({5, 5, 5}, {0.3, 0.5, 1}, {1, 0, 0, 0});
  for (bool with_mu2 : {false, true}) {
    ScreenedPairs got;
    const ScreenReport report = screen(s, Box::periodic_box(10, 10, 10), 1, got, with_mu2);
    ASSERT_EQ(got.size(), 1u) << (with_mu2 ? "with mu2" : "");
    EXPECT_EQ(got.i[0], 0u);
    EXPECT_EQ(got.j[0], 1u);
    EXPECT_EQ(report.invalid, 0u);
    if (with_mu2) {
      EXPECT_LT(got.mu2[0], 1e-300);
    }
  }
}

TEST(Screen, PeriodicCoordinatesBillionsOfBoxLengthsAwayGiveTheSamePairs) {
  // Was: image counts in 32 bits, pairs missed beyond 2^31 box lengths.
  // Centres on a grid of 2^-8 in a box of 8, moved by n box lengths with |n|
  // from 0 to 2^40 per axis: every coordinate exact, and its residue in the box
  // the unmoved one, so the pairs and their mu^2 must be the same bits.
  std::mt19937_64 engine(51);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore near, far;
  for (int n = 0; n < 1500; ++n) {
    std::array<double, 3> centre, moved;
    for (int k = 0; k < 3; ++k) {
      centre[k] = std::floor(unit(engine) * 2048) / 256;  // [0, 8) on a grid of 2^-8
      // 0 .. 2^40 box lengths, about half of them beyond 2^31.
      const double lengths = std::floor(std::ldexp(unit(engine), int(unit(engine) * 41)));
      moved[k] = centre[k] + (unit(engine) < 0.5 ? -8 : 8) * lengths;
    }
    const std::array<double, 3> axes = {0.2 + 0.3 * unit(engine), 0.3, 0.2 + 0.4 * unit(engine)};
    const std::array<double, 4> q = {normal(engine), normal(engine), normal(engine),
                                     normal(engine)};
    near.add_axes(centre, axes, q);
    far.add_axes(moved, axes, q);
  }
  const Box box = Box::periodic_box(8, 8, 8);
  for (bool with_mu2 : {false, true}) {
    ScreenedPairs a, b;
    screen(near, box, 1, a, with_mu2);
    screen(far, box, 1, b, with_mu2);
    ASSERT_EQ(a.size(), b.size()) << (with_mu2 ? "with mu2" : "");
    for (std::size_t k = 0; k < a.size(); ++k) {
      EXPECT_EQ(a.i[k], b.i[k]);
      EXPECT_EQ(a.j[k], b.j[k]);
      if (with_mu2) {
        EXPECT_EQ(a.mu2[k], b.mu2[k]);
      }
    }
    EXPECT_GT(a.size(), 100u);
  }
  ScreenedPairs a;
  screen(near, box, 1, a);
  compare(near, box, 1, a, "grid scene in a box of 8");
  // Two spheres of radius 0.3 whose residues are 0.5 apart: one at 0, 3e9
  // or 1e12 box lengths, the other at -5e9 (the coordinates are exact).
  for (double lengths : {0.0, 3e9, 1e12}) {
    ParticleStore pair;
    pair.add_axes({1 + 8 * lengths, 1, 1}, {0.3, 0.3, 0.3}, {1, 0, 0, 0});
    pair.add_axes({1.5 - 8 * 5e9, 1, 1}, {0.3, 0.3, 0.3}, {1, 0, 0, 0});
    ScreenedPairs got;
    screen(pair, box, 1, got, true);
    ASSERT_EQ(got.size(), 1u) << lengths << " box lengths";
    EXPECT_EQ(got.mu2[0], 0.25 / 0.36) << lengths << " box lengths";
  }
}

TEST(Screen, OpenBoxesSpanningBillionsOfCellsMissNoPair) {
  // Was: a cell coordinate converted to int beyond its range (undefined
  // behaviour), and pairs missed near cell 2^31. Spheres of radius 0.5
  // along a line, 2 apart (no pair), then 100 pairs 0.8 apart (each an
  // overlap) 10 apart from each other, beyond 1e13 and below -1e12 (cells
  // of side ~1: trillions of cells, clamped to the grid's last).
  ParticleStore s;
  for (int k = 0; k < 5000; ++k) s.add_axes({2.0 * k, 0, 0}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
  std::set<std::pair<std::uint32_t, std::uint32_t>> planted;
  for (double base : {1e13, -1e12}) {
    for (int k = 0; k < 50; ++k) {
      const std::uint32_t first = std::uint32_t(s.size());
      s.add_axes({base + 10.0 * k, 1, 0}, {0.5, 0.4, 0.5}, {1, 0, 0, 0});
      s.add_axes({base + 10.0 * k + 0.8, 1, 0}, {0.5, 0.4, 0.5}, {1, 0, 0, 0});
      planted.insert({first, first + 1});
    }
  }
  for (bool with_mu2 : {false, true}) {
    ScreenedPairs got;
    screen(s, Box::open(), 1, got, with_mu2);
    std::set<std::pair<std::uint32_t, std::uint32_t>> found;
    for (std::size_t k = 0; k < got.size(); ++k) found.insert({got.i[k], got.j[k]});
    EXPECT_EQ(found, planted) << (with_mu2 ? "with mu2" : "");
  }
}

TEST(Screen, AFewFarParticlesInAnOpenBoxLeaveTheCellsOfTheRestFine) {
  // The cells grew alike along every axis until they were at most twice the
  // particles: one particle at x = 1e9 left one cell across y and z, and
  // every pair was compared (200,000 spheroids: 89 s instead of 0.05 s).
  // The grid now covers the region without the farthest 1/64 of the centres
  // at each end of an open axis, those in its outer cells.
  const SceneSpec spec{1500, 1.0 / 3, 3, 0.5, 0.5, 10.3, false, 23};
  ParticleStore s = make_scene(spec);
  ScreenedPairs near;
  const std::size_t compared_without = screen(s, Box::open(), 1, near).candidate_pairs;
  // One far along x, an overlapping pair far the other way, one far along z
  // (and one farther, below).
  s.add_axes({1e9, 5, 5}, {0.5, 0.5, 1}, {1, 0, 0, 0});
  s.add_axes({-1e9, 5, 5}, {0.5, 0.5, 1}, {1, 0, 0, 0});
  s.add_axes({-1e9 + 0.6, 5, 5}, {0.5, 0.5, 1}, {1, 0, 0, 0});
  s.add_axes({5, 5, -3e8}, {0.5, 0.5, 1}, {1, 0, 0, 0});
  // One so far that eps of its coordinate is 7 (the coarse test's slack was
  // taken from the coordinates, and every window then spanned the grid).
  s.add_axes({3e16, 5, 5}, {0.5, 0.5, 1}, {1, 0, 0, 0});
  ScreenedPairs got;
  const ScreenReport report = screen(s, Box::open(), 1, got);
  // The far ones add a few compares each, not the scene's every pair (1.1M
  // compared before, 0.10M without them). Twice leaves room for the cells'
  // other cut of the region.
  EXPECT_LT(report.candidate_pairs, 2 * compared_without)
      << "compared " << report.candidate_pairs << " pairs, " << compared_without
      << " without the far particles";
  const Comparison c = compare(s, Box::open(), 1, got, "far particles, open");
  EXPECT_EQ(c.found, near.size() + 1) << "the far pair is found, the near pairs stay";
}

TEST(Screen, ClustersFarApartInAnOpenBoxAreScreenedAsFinelyAsEachAlone) {
  // The cells were sized over the whole span of the centres: two clusters
  // of 50,000 spheroids 1e6 apart compared 100 times the pairs of the two
  // side by side. The long empty stretches of an open axis are now folded
  // out of cell space (cell_lists.hpp, OpenFold). Four clusters: 1e6 apart
  // along x, one off along every axis, one beyond 1e15.
  const std::array<std::array<double, 3>, 4> offsets = {
      {{0, 0, 0}, {1e6, 0, 0}, {1.7e6, 3e5, -2e5}, {-3.5e15, 2e4, 1e9}}};
  ParticleStore all;
  std::size_t compared_alone = 0;
  for (std::size_t c = 0; c < offsets.size(); ++c) {
    ParticleStore one = make_scene({600, 1.0 / 3, 3, 0.5, 0.5, 8.0, false, 90 + c});
    // A pair of spheres at the cluster's face along x, 1e-6 inside contact,
    // and one 1e-6 outside (the fold's stretch begins just beyond them).
    // (Beyond 1e15 a coordinate's ulp is 0.5: there, one overlapping pair.)
    const double face = 9, inside = c < 3 ? 1e-6 : 0.5;
    one.add_axes({face, 4, 4}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
    one.add_axes({face + 1 - inside, 4, 4}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
    one.add_axes({face, 6, 6}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
    one.add_axes({face + 1 + 1e-6, 6, 6}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
    ScreenedPairs pairs;
    compared_alone += screen(one, Box::open(), 1, pairs).candidate_pairs;
    for (std::size_t i = 0; i < one.size(); ++i) {
      const ParticleStore::Particle p = one.particle_at(i);
      all.add_particle(p.moved_to({p.centre()[0] + offsets[c][0], p.centre()[1] + offsets[c][1],
                                   p.centre()[2] + offsets[c][2]}));
    }
  }
  for (double cutoff : {1.0, 1.5}) {
    ScreenedPairs got;
    const ScreenReport report = screen(all, Box::open(), cutoff, got);
    // (Before the fold: every pair compared, 1.8M against 0.13M. Each axis
    // is folded on its own: clusters off along every axis leave the empty
    // blocks between them in cell space, and the cells grow by the cube
    // root of that volume over the clusters', here 3 x 3 x 3 blocks for 4.)
    if (cutoff == 1) {
      EXPECT_LT(report.candidate_pairs, 3 * compared_alone)
          << "compared " << report.candidate_pairs << " pairs, " << compared_alone
          << " with each cluster alone";
    }
    const Comparison c = compare(all, Box::open(), cutoff, got, "clusters far apart, open");
    EXPECT_GT(c.found, 1000u);
  }
}

TEST(Screen, OutliersSpreadFarAwayAreLeftToTheOuterCellsWhenTheFoldWouldBeCoarser) {
  // 200 particles spread over three widths of a cube of 20,000, 1e6 away:
  // their own gaps are too short to fold, and the folded grid spent its
  // cells on them (1.6 times the pairs compared); the trim alone leaves them
  // to the outer cells, and is taken where its cells are finer.
  const SceneSpec spec{20000, 1.0 / 3, 3, 0.3, 0.3, 36.0, false, 95};
  ParticleStore s = make_scene(spec);
  ScreenedPairs near;
  const std::size_t compared_without = screen(s, Box::open(), 1, near).candidate_pairs;
  std::mt19937_64 engine(96);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < 200; ++i)
    s.add_axes({1e6 + 3 * 36 * unit(engine), 36 * unit(engine), 36 * unit(engine)}, {0.3, 0.3, 0.3},
               {1, 0, 0, 0});
  ScreenedPairs got;
  const ScreenReport report = screen(s, Box::open(), 1, got);
  EXPECT_LT(report.candidate_pairs, 1.2 * double(compared_without))
      << "compared " << report.candidate_pairs << ", " << compared_without << " without them";
  EXPECT_GE(got.size(), near.size());
}

TEST(Screen, ALineLongerThanAMillionCellsComparesEachParticleWithItsNeighbours) {
  // An axis holds at most 1e6 cells: beyond, the cells kept their side and
  // the far part of the region fell into the last cell (550,000 spheres
  // spaced 4 along x compared 1.25e9 pairs). The cells are now wider along
  // that axis, over the whole region. Two overlapping spheres at the far
  // end are found.
  ParticleStore s;
  const std::size_t n = 600000;
  for (std::size_t i = 0; i < n; ++i)
    s.add_axes({4.0 * double(i), 0, 0}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
  s.add_axes({4.0 * double(n - 1) + 0.9, 0.1, 0}, {0.5, 0.5, 0.5}, {1, 0, 0, 0});
  ScreenedPairs got;
  const ScreenReport report = screen(s, Box::open(), 1, got);
  EXPECT_LT(report.candidate_pairs, 4 * n) << "compared " << report.candidate_pairs;
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got.i[0], n - 1);
  EXPECT_EQ(got.j[0], n);
}

// The cell search misses no partner under a fold of cell space that is
// non-decreasing and moves no two points apart, to within the roundings of
// the cell-space coordinates (eps of themselves) that the coarse test's
// slack allows for (cell_lists.hpp, OpenFold). Checked on the folds of
// clusters at gaps from 7.5 to 1e12, about the origin of coordinates and
// as far as 2^50 and 3e15 (where an ulp of a coordinate is 0.5), at points
// a few ulps about every pivot and end of a folded stretch and anywhere.
TEST(Screen, TheFoldOfEmptyStretchesIsNonDecreasingAndMovesNoTwoPointsApart) {
  std::mt19937_64 engine(97);
  std::uniform_real_distribution<double> unit(0, 1);
  constexpr double eps = std::numeric_limits<double>::epsilon();
  std::size_t folds = 0, checked = 0;
  for (double base : {0.0, 1e6, -7e9, 0x1p50, 3e15}) {
    ParticleStore s;
    const double gaps[] = {50, 3e3, 7.5, 1e5, 1e9, 30, 1e12};
    double at = base, end = base;  // (end: of the last cluster)
    for (double gap : gaps) {
      for (int i = 0; i < 60; ++i)
        s.add_axes({at + 10 * unit(engine), 10 * unit(engine), 10 * unit(engine)}, {0.5, 0.5, 0.5},
                   {1, 0, 0, 0});
      end = at + 10;
      at += 10 + gap;
    }
    const pwcontact::screen::CellLists lists =
        pwcontact::screen::build_cell_lists(s, Box::open(), 1, 1);
    const pwcontact::screen::OpenFold& fold = lists.fold[0];
    ASSERT_GE(fold.pivot.size(), 3u) << "base " << base;
    folds += fold.pivot.size();
    EXPECT_TRUE(lists.fold[1].pivot.empty() && lists.fold[2].pivot.empty());
    std::vector<double> x;
    for (std::size_t j = 0; j < fold.pivot.size(); ++j)
      for (double end : {fold.pivot[j], fold.pivot[j] + fold.removed[j]}) {
        double v = end;
        for (int k = 0; k < 4; ++k) v = std::nextafter(v, -INFINITY);
        for (int k = 0; k < 9; ++k, v = std::nextafter(v, INFINITY)) x.push_back(v);
        for (int k = 0; k < 20; ++k) x.push_back(end + 3 * (unit(engine) - 0.5));
      }
    const double low = *std::min_element(s.centre(0).begin(), s.centre(0).end());
    for (int k = 0; k < 400; ++k) x.push_back(low + (end - base) * unit(engine) * unit(engine));
    std::sort(x.begin(), x.end());
    std::vector<double> u(x.size());
    for (std::size_t k = 0; k < x.size(); ++k) u[k] = lists.open_coordinate(0, x[k]);
    for (std::size_t a = 0; a + 1 < x.size(); ++a)
      for (std::size_t b = a + 1; b < std::min(x.size(), a + 40); ++b) {
        ++checked;
        const double allowed = (x[b] - x[a]) + 4 * eps * (std::abs(u[a]) + std::abs(u[b]));
        ASSERT_LE(u[a], u[b]) << "base " << base << ": u(" << x[a] << ") > u(" << x[b] << ")";
        ASSERT_LE(u[b] - u[a], allowed)
            << "base " << base << ": u(" << x[b] << ") - u(" << x[a] << ") = " << u[b] - u[a];
      }
    // The clusters' 7 x 10 of extent and what is kept of each stretch,
    // 4 cutoff R_max = 2 (or all of it, 7.5): not the 1e12 between them.
    EXPECT_LT(lists.open_coordinate(0, end), 100) << "base " << base;
  }
  EXPECT_GE(folds, 15u);
  EXPECT_GT(checked, 50000u);
}

TEST(Screen, ErrorsInsideTheSearchReachTheCallerAsExceptions) {
  // Was: an exception thrown in the search's threads (a bad PWCONTACT_ISA,
  // memory exhausted, a visitor's) ended the program in std::terminate.
  const ParticleStore s = make_scene({500, 0.5, 2, 0.3, 0.5, 8.0, true, 61});
  const Box box = Box::periodic_box(8, 8, 8);
  {
    const pwtest::ScopedEnvironment bad("PWCONTACT_ISA", "avx9");
    ScreenedPairs got;
    EXPECT_THROW(screen(s, box, 1, got), std::invalid_argument);
  }
  EXPECT_THROW(
      pwcontact::for_each_candidate_pair(s, box, 1, 2,
                                         [](int, std::uint32_t i, std::uint32_t, const double*) {
                                           if (i == 100) throw std::runtime_error("visitor");
                                         }),
      std::runtime_error);
}

TEST(Screen, ACutoffWhoseSquareIsNotANormalDoubleIsRefusedWithItsValue) {
  const ParticleStore s = make_scene({10, 0.5, 2, 0.3, 0.5, 8.0, false, 62});
  for (double cutoff : {1e-200, 1e160}) {
    ScreenedPairs got;
    try {
      screen(s, Box::open(), cutoff, got);
      ADD_FAILURE() << "cutoff " << cutoff << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(cutoff < 1 ? "1e-200" : "1e+160"), std::string::npos)
          << e.what();
    }
  }
}

TEST(Screen, CentresSpanningMoreThanTheDoubleRangeAreRefused) {
  ParticleStore s;
  s.add_axes({-1e308, 0, 0}, {1, 1, 1}, {1, 0, 0, 0});
  s.add_axes({1e308, 0, 0}, {1, 1, 1}, {1, 0, 0, 0});
  ScreenedPairs got;
  EXPECT_THROW(screen(s, Box::open(), 1, got), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Triclinic boxes

// The pairs (i < j) with mu^2 < cutoff^2 at some periodic image: every image
// n1 a1 + n2 a2 + n3 a3 with |n_k| <= 2 whose bounding spheres meet,
// solved by the reference path. Independent of the screen's minimum image
// and cell lists.
std::set<std::pair<std::uint32_t, std::uint32_t>> brute_force_images(const ParticleStore& s,
                                                                     const Box& box,
                                                                     double cutoff) {
  const double lx = box.length[0], ly = box.length[1], lz = box.length[2];
  const double a[3][3] = {
      {lx, 0, 0}, {box.tilt[0] * ly, ly, 0}, {box.tilt[1] * lz, box.tilt[2] * lz, lz}};
  const int nz = box.two_dimensional ? 0 : 2;
  const std::size_t n = s.size();
  // Every centre moved into the box first, by whole lattice vectors: the
  // fractional coordinates by Eigen's LU, rounded down.
  Eigen::Matrix3d h;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) h(r, c) = a[c][r];
  if (box.two_dimensional) h(2, 2) = 1;
  const Eigen::Matrix3d inverse = h.inverse();
  std::vector<Eigen::Vector3d> centres(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x(s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]);
    Eigen::Vector3d f = inverse * x;
    for (int k = 0; k < (box.two_dimensional ? 2 : 3); ++k) f[k] = std::floor(f[k]);
    if (box.two_dimensional) f[2] = 0;
    centres[i] = x - h * f;
  }
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> rows(n);
#pragma omp parallel for schedule(dynamic, 8)
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const double reach = cutoff * (s.bounding_radius()[i] + s.bounding_radius()[j]);
      const auto qi = form(s, i), qj = form(s, j);
      bool found = false;
      for (int n1 = -2; n1 <= 2 && !found; ++n1)
        for (int n2 = -2; n2 <= 2 && !found; ++n2)
          for (int n3 = -nz; n3 <= nz && !found; ++n3) {
            double r[3];
            for (int k = 0; k < 3; ++k)
              r[k] = centres[j][k] - centres[i][k] + n1 * a[0][k] + n2 * a[1][k] + n3 * a[2][k];
            if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] >= reach * reach) continue;
            const auto result = pwcontact::contact_function<double>(r, qi.data(), qj.data());
            found = result.status == pwcontact::Status::ok && result.mu2 < cutoff * cutoff;
          }
      if (found) rows[i].push_back({std::uint32_t(i), std::uint32_t(j)});
    }
  std::set<std::pair<std::uint32_t, std::uint32_t>> all;
  for (const auto& row : rows) all.insert(row.begin(), row.end());
  return all;
}

// Random spheroids with centres anywhere in [-3 L, 3 L) (so that many are
// given outside the box) in a box of the given tilts.
ParticleStore triclinic_scene(std::size_t count, const Box& box, std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore s;
  for (std::size_t k = 0; k < count; ++k) {
    const double size = 0.2 + 0.2 * unit(engine), aspect = 0.4 + 1.6 * unit(engine);
    s.add_axes({box.length[0] * (6 * unit(engine) - 3), box.length[1] * (6 * unit(engine) - 3),
                box.length[2] * (6 * unit(engine) - 3)},
               {size, size, size * aspect},
               {normal(engine), normal(engine), normal(engine), normal(engine)});
  }
  return s;
}

void expect_same_pairs_as_every_image(const ParticleStore& s, const Box& box, double cutoff,
                                      const std::string& what) {
  const auto expected = brute_force_images(s, box, cutoff);
  for (bool with_mu2 : {false, true}) {
    ScreenedPairs got;
    screen(s, box, cutoff, got, with_mu2);
    std::set<std::pair<std::uint32_t, std::uint32_t>> found;
    for (std::size_t k = 0; k < got.size(); ++k) found.insert({got.i[k], got.j[k]});
    std::size_t differing = 0;
    for (const auto& p : expected) differing += !found.count(p);
    for (const auto& p : found) differing += !expected.count(p);
    EXPECT_EQ(differing, 0u) << what << (with_mu2 ? ", with mu2" : "") << ": " << found.size()
                             << " found, " << expected.size() << " expected";
    std::printf("[ measured ] %s%s: %zu pairs found, %zu by every image\n", what.c_str(),
                with_mu2 ? " (with mu2)" : "", found.size(), expected.size());
  }
}

TEST(Screen, TriclinicBoxesMatchABruteForceOverEveryImage) {
  // Tilts from none to beyond 0.5 (skewed cells), centres given up to three
  // box lengths outside the box: pairs across every face and edge.
  const double tilts[][3] = {{0, 0, 0}, {0.3, 0.2, 0.1}, {0.5, -0.5, 0.5}, {-0.9, 0.7, -0.8}};
  std::uint64_t seed = 71;
  for (const auto& t : tilts) {
    const Box box = Box::triclinic(7, 6.5, 6, t[0], t[1], t[2]);
    const ParticleStore s = triclinic_scene(900, box, seed++);
    expect_same_pairs_as_every_image(
        s, box, 1,
        "tilts " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]));
  }
  // A neighbour list (cutoff 1.4) in the most skewed box.
  const Box skewed = Box::triclinic(8, 7.5, 7, -0.9, 0.7, -0.8);
  expect_same_pairs_as_every_image(triclinic_scene(700, skewed, 79), skewed, 1.4,
                                   "skewed, cutoff 1.4");
}

// Each member searches only the cells within its own reach and its grid's
// largest (thinner cells along z), so the cells a search visits are cut
// close to the pairs' reach. Spheres of radii over a factor 8 (four size
// classes), half of them planted beside another at cutoff (a_i + a_j) (1 -+
// 1e-12) in random directions and along the axes (the cells' cuts): every
// pair in by 1e-12 found, every pair out by 1e-12 not, and the whole set
// that of an oracle in long double over every image |n_k| <= 2 (no band:
// pairs it finds within 1e-13 of the cutoff, none here, would be left out).
// Periodic, triclinic and open boxes, two of them barely twice the largest
// reach along z; cutoffs 1 and 1.3. (A window of twice
// the member's own reach, without the grid's largest, misses 73 to 90 of
// the 350 planted inside.)
TEST(Screen, SpheresJustInsideTheirReachAreFoundWhereverTheCellsAreCut) {
  struct Case {
    const char* name;
    Box box;
    double cutoff;
  };
  const Case cases[] = {
      {"periodic", Box::periodic_box(11, 10, 9.5), 1},
      {"periodic, cutoff 1.3", Box::periodic_box(11, 10, 9.5), 1.3},
      {"triclinic", Box::triclinic(11, 10, 9.5, 0.4, -0.3, 0.2), 1},
      // Barely twice the largest reach along z: the windows of the largest
      // class span the whole axis there (the minimum image).
      {"periodic, thin along z", Box::periodic_box(11, 10, 3.4), 1},
      {"triclinic, thin along z", Box::triclinic(11, 10, 3.4, 0.4, -0.3, 0.2), 1},
      {"open", Box::open(), 1.3},
  };
  std::uint64_t seed = 301;
  for (const Case& c : cases) {
    std::mt19937_64 engine(seed++);
    std::uniform_real_distribution<double> unit(0, 1);
    std::normal_distribution<double> normal(0, 1);
    const double radii[] = {0.1, 0.17, 0.25, 0.4, 0.55, 0.8};
    ParticleStore s;
    std::vector<double> a;  // the spheres' radii
    std::vector<std::array<long double, 3>> x;
    auto add = [&](const std::array<double, 3>& centre, double radius) {
      s.add_axes(centre, {radius, radius, radius}, {1, 0, 0, 0});
      a.push_back(radius);
      x.push_back({centre[0], centre[1], centre[2]});
    };
    // Planted pairs: (first, second, inside).
    std::vector<std::tuple<std::uint32_t, std::uint32_t, bool>> planted;
    for (int k = 0; k < 700; ++k) {
      const double ai = radii[engine() % 6], aj = radii[engine() % 6];
      std::array<double, 3> ci;
      for (int d = 0; d < 3; ++d) ci[d] = 10 * unit(engine);
      std::array<double, 3> dir;
      if (k % 4 == 0) {  // along an axis, either way
        dir = {0, 0, 0};
        dir[engine() % 3] = engine() % 2 ? 1 : -1;
      } else {
        for (double& v : dir) v = normal(engine);
        const double norm = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        for (double& v : dir) v /= norm;
      }
      const bool inside = k % 2 == 0;
      const double d = c.cutoff * (ai + aj) * (inside ? 1 - 1e-12 : 1 + 1e-12);
      add(ci, ai);
      add({ci[0] + d * dir[0], ci[1] + d * dir[1], ci[2] + d * dir[2]}, aj);
      planted.emplace_back(std::uint32_t(s.size() - 2), std::uint32_t(s.size() - 1), inside);
    }
    // Lattice vectors (periodic) for the oracle's images.
    const Box& box = c.box;
    long double lattice[3][3] = {};
    if (box.periodic) {
      const long double lx = box.length[0], ly = box.length[1], lz = box.length[2];
      const long double v[3][3] = {
          {lx, 0, 0}, {box.tilt[0] * ly, ly, 0}, {box.tilt[1] * lz, box.tilt[2] * lz, lz}};
      std::copy(&v[0][0], &v[0][0] + 9, &lattice[0][0]);
    }
    const int images = box.periodic ? 2 : 0;
    const long double cut2 = static_cast<long double>(c.cutoff) * c.cutoff;
    // mu^2 of two spheres: the least |r|^2 over the images over (a_i + a_j)^2.
    auto mu2 = [&](std::size_t i, std::size_t j) {
      long double best = std::numeric_limits<long double>::infinity();
      for (int n1 = -images; n1 <= images; ++n1)
        for (int n2 = -images; n2 <= images; ++n2)
          for (int n3 = -images; n3 <= images; ++n3) {
            long double rr = 0;
            for (int d = 0; d < 3; ++d) {
              const long double r =
                  x[j][d] - x[i][d] + n1 * lattice[0][d] + n2 * lattice[1][d] + n3 * lattice[2][d];
              rr += r * r;
            }
            best = std::min(best, rr);
          }
      const long double sum = static_cast<long double>(a[i]) + a[j];
      return best / (sum * sum);
    };
    // Periodic: every centre taken into the box first (its fractional
    // coordinates less their floor), so that the images |n_k| <= 2 hold the
    // nearest of every pair.
    if (box.periodic)
      for (auto& c : x) {
        long double f[3];
        f[2] = c[2] / lattice[2][2];
        f[1] = (c[1] - f[2] * lattice[2][1]) / lattice[1][1];
        f[0] = (c[0] - f[1] * lattice[1][0] - f[2] * lattice[2][0]) / lattice[0][0];
        for (long double& v : f) v -= std::floor(v);
        for (int d = 0; d < 3; ++d)
          c[d] = f[0] * lattice[0][d] + f[1] * lattice[1][d] + f[2] * lattice[2][d];
      }
    std::set<std::pair<std::uint32_t, std::uint32_t>> expected, unclear;
    const std::size_t n = s.size();
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) {
        const long double m = mu2(i, j);
        if (std::abs(m - cut2) <= 1e-13L * cut2)
          unclear.insert({std::uint32_t(i), std::uint32_t(j)});
        else if (m < cut2)
          expected.insert({std::uint32_t(i), std::uint32_t(j)});
      }
    for (bool with_mu2 : {false, true}) {
      const std::string what = std::string(c.name) + (with_mu2 ? ", with mu2" : "");
      ScreenedPairs got;
      const ScreenReport report = screen(s, box, c.cutoff, got, with_mu2);
      EXPECT_GE(report.size_classes, 4u) << what;
      std::set<std::pair<std::uint32_t, std::uint32_t>> found;
      for (std::size_t k = 0; k < got.size(); ++k)
        if (!unclear.count({got.i[k], got.j[k]})) found.insert({got.i[k], got.j[k]});
      std::size_t missed = 0, extra = 0;
      for (const auto& p : expected) missed += !found.count(p);
      for (const auto& p : found) extra += !expected.count(p);
      EXPECT_EQ(missed, 0u) << what;
      EXPECT_EQ(extra, 0u) << what;
      std::size_t planted_in = 0, planted_in_found = 0, planted_out_found = 0;
      for (const auto& [i, j, inside] : planted) {
        const bool is_found = found.count({i, j}) > 0;
        planted_in += inside;
        planted_in_found += inside && is_found;
        planted_out_found += !inside && is_found;
      }
      EXPECT_EQ(planted_in_found, planted_in) << what;
      EXPECT_EQ(planted_out_found, 0u) << what;
      std::printf(
          "[ measured ] %s: %zu pairs found, %zu expected, %zu unclear; %zu of %zu "
          "planted inside found\n",
          what.c_str(), found.size(), expected.size(), unclear.size(), planted_in_found,
          planted_in);
    }
  }
}

TEST(Screen, ATiltedBoxThinnerThanTwiceTheReachAcrossAFaceIsAnError) {
  // Lengths 6 but tilted by 2: the width across x is 6 / sqrt(1 + 4) = 2.7.
  const Box box = Box::triclinic(6, 6, 6, 2, 0, 0);
  ParticleStore s;
  s.add_axes({0, 0, 0}, {0.8, 0.8, 0.8}, {1, 0, 0, 0});
  ScreenedPairs got;
  try {
    screen(s, box, 1, got);
    ADD_FAILURE() << "a box 2.7 wide accepted for a reach of 3.2";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tilted"), std::string::npos) << e.what();
  }
}

TEST(Screen, LammpsBoxesConvertToTheHoomdConventionAndBack) {
  // LAMMPS tilts are lengths: xy = 1.5 with Ly = 6 is HOOMD's 0.25.
  const Box box = Box::from_lammps(8, 6, 5, 1.5, -1, 0.5);
  EXPECT_EQ(box.tilt[0], 0.25);
  EXPECT_EQ(box.tilt[1], -0.2);
  EXPECT_EQ(box.tilt[2], 0.1);
  const auto lammps = box.lammps_tilts();
  EXPECT_DOUBLE_EQ(lammps[0], 1.5);
  EXPECT_DOUBLE_EQ(lammps[1], -1);
  EXPECT_DOUBLE_EQ(lammps[2], 0.5);
  std::mt19937_64 engine(81);
  std::uniform_real_distribution<double> unit(-1, 1);
  for (int k = 0; k < 100; ++k) {
    const Box b = Box::triclinic(1 + unit(engine) + 2, 3 + unit(engine), 2 + unit(engine),
                                 unit(engine), unit(engine), unit(engine));
    const auto t = b.lammps_tilts();
    const Box back = Box::from_lammps(b.length[0], b.length[1], b.length[2], t[0], t[1], t[2]);
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(back.tilt[a], b.tilt[a], 4e-16) << k;
  }
}

// ---------------------------------------------------------------------------
// Two dimensions

// The 2D contact function of two ellipses (2x2 forms a, b: xx, xy, yy) at
// separation r, by ternary search of the concave f(lambda) = lambda (1 -
// lambda) r^T M^-1 r, M = (1 - lambda) A + lambda B, in long double: an
// oracle that shares nothing with the library (no 3D form, no Newton step).
long double ellipse_mu2(const long double r[2], const long double a[3], const long double b[3]) {
  auto f = [&](long double lambda) {
    const long double m00 = (1 - lambda) * a[0] + lambda * b[0];
    const long double m01 = (1 - lambda) * a[1] + lambda * b[1];
    const long double m11 = (1 - lambda) * a[2] + lambda * b[2];
    const long double det = m00 * m11 - m01 * m01;
    const long double form = (m11 * r[0] * r[0] - 2 * m01 * r[0] * r[1] + m00 * r[1] * r[1]) / det;
    return lambda * (1 - lambda) * form;
  };
  long double lo = 0, hi = 1;
  for (int k = 0; k < 200; ++k) {
    const long double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
    if (f(m1) < f(m2))
      lo = m1;
    else
      hi = m2;
  }
  return f((lo + hi) / 2);
}

TEST(Screen, EllipsesInTwoDimensionsMatchABruteForceWithThe2DContactFunction) {
  // Ellipses (aspect 1/3 .. 3, packing fraction 0.5) in square and tilted
  // 2D boxes; every pair of every image against the 2D oracle; with mu^2,
  // the screen's mu^2 is the 2D one.
  for (double xy : {0.0, 0.3, -0.6}) {
    const pwcontact::SpheroidScene scene = pwcontact::ellipse_scene(1500, 91, 0.5, 3);
    const Box box = Box::two_dimensional_box(scene.box.length[0], scene.box.length[1], xy);
    const ParticleStore& s = scene.particles;
    const double lx = box.length[0], ly = box.length[1];
    std::set<std::pair<std::uint32_t, std::uint32_t>> expected;
    std::map<std::pair<std::uint32_t, std::uint32_t>, long double> mu2_of;
    std::map<std::pair<std::uint32_t, std::uint32_t>, double> tolerance_of;
    const double cutoff = 1.1;
    for (std::uint32_t i = 0; i < s.size(); ++i)
      for (std::uint32_t j = i + 1; j < s.size(); ++j) {
        const long double a[3] = {s.q(0)[i], s.q(1)[i], s.q(3)[i]};
        const long double b[3] = {s.q(0)[j], s.q(1)[j], s.q(3)[j]};
        const double reach = cutoff * (s.bounding_radius()[i] + s.bounding_radius()[j]);
        long double best = std::numeric_limits<long double>::infinity(), distance = 0;
        for (int n1 = -2; n1 <= 2; ++n1)
          for (int n2 = -2; n2 <= 2; ++n2) {
            const long double r[2] = {
                (long double)s.centre(0)[j] - s.centre(0)[i] + n1 * lx + n2 * xy * ly,
                (long double)s.centre(1)[j] - s.centre(1)[i] + n2 * ly};
            if (r[0] * r[0] + r[1] * r[1] >= reach * reach) continue;
            const long double mu2 = ellipse_mu2(r, a, b);
            if (mu2 < best) {
              best = mu2;
              distance = std::sqrt(r[0] * r[0] + r[1] * r[1]);
            }
          }
        if (best < cutoff * cutoff) {
          expected.insert({i, j});
          mu2_of[{i, j}] = best;
          // In a tilted box the centres are wrapped through fractional
          // coordinates, to a few eps L: mu^2 (quadratic in r) moves by
          // up to ~8 eps L / |r| relatively.
          tolerance_of[{i, j}] = 1e-13 + 16 * std::numeric_limits<double>::epsilon() * lx *
                                             (1 + std::abs(xy)) / double(distance);
        }
      }
    for (bool with_mu2 : {false, true}) {
      ScreenedPairs got;
      screen(s, box, cutoff, got, with_mu2);
      std::set<std::pair<std::uint32_t, std::uint32_t>> found;
      double worst = 0;
      for (std::size_t k = 0; k < got.size(); ++k) {
        found.insert({got.i[k], got.j[k]});
        if (with_mu2 && mu2_of.count({got.i[k], got.j[k]}))
          worst = std::max(worst, double(std::abs(got.mu2[k] - mu2_of[{got.i[k], got.j[k]}]) /
                                         mu2_of[{got.i[k], got.j[k]}]) /
                                      tolerance_of[{got.i[k], got.j[k]}]);
      }
      EXPECT_EQ(found, expected) << "tilt " << xy << (with_mu2 ? ", with mu2" : "");
      std::printf(
          "[ measured ] 2D, tilt %.1f%s: %zu pairs (%zu by the 2D oracle), mu2 within %.3g "
          "of its tolerance from the 2D oracle's\n",
          xy, with_mu2 ? ", with mu2" : "", found.size(), expected.size(), worst);
      if (with_mu2) {
        EXPECT_LE(worst, 1);
      }
    }
  }
}

// Identical, aligned ellipsoids (one Q for all) of the given semi-axes,
// random centres in a periodic box.
ParticleStore aligned_scene(const std::array<double, 3>& semi_axes, std::size_t n, double box,
                            std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore s;
  for (std::size_t k = 0; k < n; ++k)
    s.add_axes({box * unit(engine), box * unit(engine), box * unit(engine)}, semi_axes,
               {0.8, 0.1, -0.5, 0.3});
  return s;
}

TEST(Screen, PairsOfOneFormAreDecidedInClosedFormWithoutASolve) {
  // One shape, one orientation: mu^2 = r^T Q^-1 r / 4 (theory eqs. 10, 11),
  // no solve; the same pairs as the brute force, and with mu^2 within 1e-14
  // of the reference's (Cholesky on cond(Q) = 36: a few roundings times 36).
  const Box box = Box::periodic_box(9, 9, 9);
  const ParticleStore s = aligned_scene({0.2, 0.5, 1.2}, 1200, 9, 31);
  ScreenedPairs got;
  const ScreenReport report = screen(s, box, 1, got);
  EXPECT_EQ(report.solved, 0u);
  EXPECT_GT(report.decided_same_form, 300u);
  const Comparison c = compare(s, box, 1, got, "one form");
  EXPECT_GT(c.expected, 200u);
  ScreenedPairs with_mu2;
  screen(s, box, 1.3, with_mu2, true);
  const double worst = largest_mu2_error(s, box, with_mu2);
  std::printf("[ measured ] one form: max relative error of mu^2 %.3g\n", worst);
  EXPECT_LE(worst, 1e-14);
  compare(s, box, 1.3, with_mu2, "one form, cutoff 1.3");
}

TEST(Screen, PairsOfOneIllConditionedFormAreSolvedNotTakenInClosedForm) {
  // Needles of aspect 150 (cond(Q) = 2.25e4 > 1e4): the closed form's
  // rounding would grow with cond(Q), so they go to the batch path.
  const Box box = Box::periodic_box(6.5, 6.5, 6.5);
  const ParticleStore s = aligned_scene({0.01, 0.01, 1.5}, 1000, 6.5, 32);
  ScreenedPairs got;
  const ScreenReport report = screen(s, box, 1, got);
  EXPECT_EQ(report.decided_same_form, 0u);
  EXPECT_GT(report.solved, 100u);
  compare(s, box, 1, got, "one ill-conditioned form");
}

TEST(Screen, ACandidateListOfOnesOwnGivesTheSamePairsAsTheCellLists) {
  // Every pair (i < j) within 3 of each other, listed both ways round and
  // some twice: the pairs found must be the cell lists' (each once), for a
  // polydisperse periodic scene with mu^2 and without.
  const SceneSpec spec{800, 0.3, 3, 0.1, 0.5, 10.0, true, 10};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  std::vector<std::uint32_t> first, second;
  for (std::uint32_t i = 0; i < s.size(); ++i)
    for (std::uint32_t j = i + 1; j < s.size(); ++j) {
      const auto r = separation(s, box, i, j);
      if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] >= 9) continue;
      first.push_back(j % 2 ? i : j);  // either order
      second.push_back(j % 2 ? j : i);
      if (j % 7 == 0) first.push_back(i), second.push_back(j);  // and some twice
    }
  for (bool with_mu2 : {false, true}) {
    ScreenOptions options;
    options.with_mu2 = with_mu2;
    ScreenedPairs from_cells, one_thread;
    pwcontact::screen_pairs(s, box, options, from_cells);
    // (7 threads: seven lists of pairs with repeats, merged in rounds.)
    for (int threads : {1, 2, 7}) {
      options.threads = threads;
      ScreenedPairs from_list;
      const ScreenReport report = pwcontact::screen_candidates(s, box, first.data(), second.data(),
                                                               first.size(), options, from_list);
      const std::string what =
          "with_mu2 " + std::to_string(with_mu2) + ", " + std::to_string(threads) + " threads";
      EXPECT_EQ(report.candidate_pairs, first.size()) << what;
      EXPECT_EQ(from_list.i, from_cells.i) << what;
      EXPECT_EQ(from_list.j, from_cells.j) << what;
      ASSERT_EQ(from_list.mu2.size(), from_cells.mu2.size()) << what;
      for (std::size_t k = 0; k < from_list.mu2.size(); ++k)
        EXPECT_NEAR(from_list.mu2[k], from_cells.mu2[k], 1e-13 * from_cells.mu2[k]) << k;
      if (threads == 1)
        one_thread = from_list;
      else
        EXPECT_EQ(from_list.mu2, one_thread.mu2) << what;
    }
    EXPECT_GT(from_cells.size(), 100u);
  }
  const std::uint32_t bad_first[] = {0, 5}, bad_second[] = {1, 5};
  ScreenedPairs out;
  EXPECT_THROW(pwcontact::screen_candidates(s, box, bad_first, bad_second, 2, {}, out),
               std::invalid_argument);
  const std::uint32_t beyond[] = {800};
  EXPECT_THROW(pwcontact::screen_candidates(s, box, beyond, bad_second, 1, {}, out),
               std::invalid_argument);
}

TEST(Screen, ThePairsAndTheirOrderDoNotDependOnTheThreadCount) {
  const SceneSpec spec{1500, 0.3, 3, 0.05, 0.6, 12.0, true, 8};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  ScreenedPairs one, two;
  screen(s, box, 1.1, one, true, 1);
  screen(s, box, 1.1, two, true, 2);
  EXPECT_GT(one.size(), 100u);
  EXPECT_EQ(one.i, two.i);
  EXPECT_EQ(one.j, two.j);
  EXPECT_EQ(one.mu2, two.mu2);
}

// Large enough that the cell lists are built by several chunks in parallel
// (one per thread, from 16,384 particles a chunk), with several size
// classes: the pairs found and their mu^2 must be those of one thread
// (with and without mu^2).
TEST(Screen, CellListsBuiltInParallelGiveTheOneThreadAnswer) {
  const SceneSpec spec{50000, 0.3, 3, 0.05, 0.6, 26.0, true, 9};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  ScreenedPairs one;
  const pwcontact::ScreenReport report = screen(s, box, 1.1, one, true, 1);
  EXPECT_GT(report.size_classes, 2u);
  EXPECT_GT(one.size(), 10000u);
  // (7 threads: more lists of pairs than the last merge takes at once.)
  for (int threads : {2, 3, 7}) {
    ScreenedPairs many;
    screen(s, box, 1.1, many, true, threads);
    EXPECT_EQ(one.i, many.i) << threads << " threads";
    EXPECT_EQ(one.j, many.j) << threads << " threads";
    EXPECT_EQ(one.mu2, many.mu2) << threads << " threads";
    ScreenedPairs one_alone, many_alone;  // without mu^2 (the overlap answers)
    screen(s, box, 1.1, one_alone, false, 1);
    screen(s, box, 1.1, many_alone, false, threads);
    EXPECT_GT(one_alone.size(), 10000u);
    EXPECT_EQ(one_alone.i, many_alone.i) << threads << " threads, without mu2";
    EXPECT_EQ(one_alone.j, many_alone.j) << threads << " threads, without mu2";
  }
}

// One workspace through a sequence of screens that grow and shrink its
// arrays (scenes of other sizes, boxes and size classes, other thread counts
// and cutoffs, with and without mu^2, an empty scene, after release()):
// every screen's pairs are the brute force's, and its pairs, mu^2 and
// counts exactly those of a screen without a workspace (the same arithmetic
// in other memory).
TEST(Screen, AWorkspaceReusedAcrossScenesGivesTheBruteForcesPairsEachTime) {
  struct Step {
    SceneSpec spec;
    double cutoff;
    bool with_mu2;
    int threads;
  };
  const std::vector<Step> steps = {
      {{900, 0.3, 3, 0.05, 0.6, 9.0, true, 31}, 1.0, false, 2},  // several size classes
      {{400, 0.2, 5, 0.3, 0.3, 6.0, false, 32}, 1.3, true, 1},   // one size, open box
      {{1200, 0.5, 2, 0.2, 0.4, 10.0, true, 33}, 1.1, true, 7},  // larger: arrays grow
      {{500, 0.3, 3, 0.05, 0.6, 7.5, true, 34}, 1.0, false, 2},  // smaller
      {{0, 1, 1, 1, 1, 1.0, false, 35}, 1.0, true, 2},           // empty
      {{900, 0.3, 3, 0.05, 0.6, 9.0, true, 31}, 1.0, true, 3},
  };
  pwcontact::ScreenWorkspace workspace;
  EXPECT_EQ(workspace.bytes(), 0u);
  ScreenedPairs reused;  // (the output's storage is reused too)
  for (std::size_t k = 0; k <= steps.size(); ++k) {
    if (k == steps.size()) {  // the first step again, after release()
      workspace.release();
      EXPECT_EQ(workspace.bytes(), 0u);
    }
    const Step& step = steps[k % steps.size()];
    const std::string what = "workspace, step " + std::to_string(k);
    const ParticleStore s = make_scene(step.spec);
    const Box box = box_of(step.spec);
    ScreenOptions options;
    options.cutoff = step.cutoff;
    options.with_mu2 = step.with_mu2;
    options.threads = step.threads;
    const ScreenReport got = pwcontact::screen_pairs(s, box, options, reused, workspace);
    ScreenedPairs alone;
    const ScreenReport expected = pwcontact::screen_pairs(s, box, options, alone);
    EXPECT_EQ(reused.i, alone.i) << what;
    EXPECT_EQ(reused.j, alone.j) << what;
    EXPECT_EQ(reused.mu2, alone.mu2) << what;
    EXPECT_EQ(reused.mu2.size(), step.with_mu2 ? reused.size() : 0u) << what;
    EXPECT_EQ(got.candidate_pairs, expected.candidate_pairs) << what;
    EXPECT_EQ(got.solved, expected.solved) << what;
    EXPECT_EQ(got.found, reused.size()) << what;
    EXPECT_EQ(got.size_classes, expected.size_classes) << what;
    if (step.spec.particles > 0) {
      EXPECT_GT(reused.size(), 50u) << what;
      EXPECT_GT(workspace.bytes(), step.spec.particles * sizeof(double)) << what;
    }
    compare(s, box, step.cutoff, reused, what);
  }
}

// A workspace serves one screen at a time: a second call meanwhile, or a
// release() (here from the first's progress callback), is refused, the
// first finishes, and the workspace serves the next; a moved-from workspace
// is refused.
TEST(Screen, AWorkspaceInUseOrMovedFromIsRefused) {
  const SceneSpec spec{300, 0.3, 3, 0.05, 0.6, 7.5, true, 36};
  const ParticleStore s = make_scene(spec);
  const Box box = box_of(spec);
  pwcontact::ScreenWorkspace workspace;
  ScreenOptions options;
  options.threads = 1;
  std::size_t refused = 0, release_refused = 0;
  // bytes() during the screen: the figure as of the last screen's end (here
  // none: 0), never the arrays the running screen resizes (a race, and under
  // ThreadSanitizer from another thread).
  std::vector<std::size_t> held_during;
  options.progress = [&](double) {
    held_during.push_back(workspace.bytes());
    ScreenedPairs inner;
    try {
      pwcontact::screen_pairs(s, box, ScreenOptions(), inner, workspace);
    } catch (const std::logic_error& e) {
      EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
      ++refused;
    }
    try {
      workspace.release();
    } catch (const std::logic_error& e) {
      EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
      ++release_refused;
    }
  };
  ScreenedPairs first, alone;
  pwcontact::screen_pairs(s, box, options, first, workspace);
  EXPECT_GT(refused, 0u);
  EXPECT_EQ(release_refused, refused);
  EXPECT_GT(workspace.bytes(), 0u);  // (released only after)
  ASSERT_FALSE(held_during.empty());
  for (std::size_t b : held_during) EXPECT_EQ(b, 0u);
  // A second screen's callback sees the first one's figure.
  const std::size_t after_first = workspace.bytes();
  held_during.clear();
  ScreenedPairs second;
  pwcontact::screen_pairs(s, box, options, second, workspace);
  ASSERT_FALSE(held_during.empty());
  for (std::size_t b : held_during) EXPECT_EQ(b, after_first);
  EXPECT_EQ(second.j, first.j);
  workspace.release();
  EXPECT_EQ(workspace.bytes(), 0u);
  options.progress = nullptr;
  pwcontact::screen_pairs(s, box, options, alone);
  EXPECT_EQ(first.i, alone.i);
  EXPECT_EQ(first.j, alone.j);
  ScreenedPairs again;
  pwcontact::screen_pairs(s, box, options, again, workspace);  // free again
  EXPECT_EQ(again.i, alone.i);
  pwcontact::ScreenWorkspace taken = std::move(workspace);
  EXPECT_THROW(pwcontact::screen_pairs(s, box, options, again, workspace), std::invalid_argument);
  EXPECT_EQ(workspace.bytes(), 0u);
  pwcontact::screen_pairs(s, box, options, again, taken);
  EXPECT_EQ(again.j, alone.j);
}

TEST(Screen, APeriodicBoxTooSmallForTheCutoffIsAnError) {
  ParticleStore s;
  s.add({0, 0, 0}, pwcontact::sphere(1.0));
  s.add({1, 1, 1}, pwcontact::sphere(1.0));
  ScreenedPairs out;
  // Reach cutoff * 2 R_max = 2 (R_max rounded up by a few eps): the box must
  // be at least 4 along every axis.
  EXPECT_NO_THROW(screen(s, Box::periodic_box(4.01, 4.01, 4.01), 1, out));
  try {
    screen(s, Box::periodic_box(4.01, 3.9, 4.01), 1, out);
    ADD_FAILURE() << "a box of 3.9 along y was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("too small"), std::string::npos) << e.what();
  }
  EXPECT_THROW(screen(s, Box::periodic_box(8, 8, 8), 0, out), std::invalid_argument);
  EXPECT_THROW(screen(s, Box::periodic_box(8, 8, 8), std::nan(""), out), std::invalid_argument);
}

// Boxes that the factories refuse are refused by the screens and scenes
// too when filled in by hand, and the factories refuse a box whose lengths
// and tilts are finite but whose lattice vectors are not: such a box was
// taken, and every pair lost (9 of 9 here).
TEST(Screen, BoxesWithInfiniteOrFlatLatticesAreRefusedEverywhere) {
  ParticleStore s;
  for (int k = 0; k < 10; ++k) s.add({0.9 * k, 0, 0}, pwcontact::sphere(0.5));
  auto expect_refused = [](const std::function<void()>& call, const std::string& what,
                           const std::string& words) {
    try {
      call();
      ADD_FAILURE() << what << ": accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << what << ": " << e.what();
    }
  };
  const double inf = std::numeric_limits<double>::infinity();
  expect_refused([] { Box::triclinic(1e300, 1e300, 1e300, 1e10, 0, 0); }, "xy Ly = 1e310",
                 "a lattice vector is not finite (xy Ly = inf)");
  expect_refused([] { Box::two_dimensional_box(1e300, 1e300, 1e300); }, "2D, xy Ly = 1e600",
                 "a lattice vector is not finite");
  Box by_hand;
  by_hand.periodic = true;
  by_hand.length = {inf, 20, 20};
  Box tilted = Box::periodic_box(20, 20, 20);
  tilted.tilt = {0, inf, 0};
  Box flat = Box::periodic_box(1e300, 1e300, 20);
  flat.tilt = {1e300, 0, 0};  // xy Ly = inf
  for (const auto& [box, words] : {std::pair{by_hand, std::string("finite lengths, got inf")},
                                   std::pair{tilted, std::string("tilt factors must be finite")},
                                   std::pair{flat, std::string("lattice vector is not finite")}}) {
    ScreenedPairs out;
    expect_refused([&, b = box] { screen(s, b, 1, out); }, "screen_pairs", words);
    expect_refused([&, b = box] { pwcontact::MovingScene scene(s, b); }, "MovingScene", words);
    pwcontact::SkinNeighborList list;
    expect_refused([&, b = box] { list.update(s, b, out); }, "SkinNeighborList", words);
  }
  ScreenedPairs open;
  screen(s, Box::open(), 1, open);
  EXPECT_EQ(open.size(), 9u);
}

// Spheres and pairs of one form are decided in closed form; where the
// squares of the pair's numbers would be subnormal (tiny sizes, or centres
// far closer than the sizes) the pair is scaled first, and the tests that
// call a pair apart from squared distances decide nothing there: every
// answer is the reference path's (which scales each pair) on the stored
// numbers. Before, spheres of radius 1e-150 at |r| = 3e-160 had mu^2 off
// by 1e-5, and of radius 1e-160 (subnormal Q) pairs within 2e-5 of contact
// were missed.
TEST(Screen, TinySpheresAndFormsAreDecidedAsTheReferencePathDecidesThem) {
  struct Case {
    double size, distance;  // |r| from distance (1 - 3e-5) to (1 + 3e-5)
    bool same_form;
  };
  for (const Case& c : {Case{1e-150, 3e-160, false}, Case{1e-160, 2e-160, false},
                        Case{1e-150, 3e-160, true}, Case{1e-155, 1.6e-155, true}}) {
    for (int step = -6; step <= 6; ++step) {
      const double d = c.distance * (1 + 5e-6 * step);
      ParticleStore s;
      if (c.same_form) {
        const std::array<double, 4> turn = {0.9, 0.1, 0.3, 0.2};
        s.add_axes({0, 0, 0}, {c.size, 0.6 * c.size, 0.5 * c.size}, turn);
        s.add_axes({d, 0.3 * d, 0}, {c.size, 0.6 * c.size, 0.5 * c.size}, turn);
      } else {
        s.add({0, 0, 0}, pwcontact::sphere(c.size));
        s.add({d, 0, 0}, pwcontact::sphere(c.size));
      }
      const double r[3] = {s.centre(0)[1], s.centre(1)[1], s.centre(2)[1]};
      double q0[6], q1[6];
      for (int k = 0; k < 6; ++k) q0[k] = s.q(k)[0], q1[k] = s.q(k)[1];
      const auto exact = pwcontact::contact_function<double>(r, q0, q1);
      ASSERT_TRUE(pwcontact::is_valid(exact.status));
      const std::string what = std::string(c.same_form ? "one form" : "spheres") + " of size " +
                               std::to_string(c.size) + " at |r| " + std::to_string(d);
      ScreenOptions options;
      options.with_mu2 = true;
      ScreenedPairs with_mu2, overlap;
      pwcontact::screen_pairs(s, Box::open(), options, with_mu2);
      options.with_mu2 = false;
      pwcontact::screen_pairs(s, Box::open(), options, overlap);
      const bool overlapping = exact.mu2 < 1;
      EXPECT_EQ(with_mu2.size(), overlapping ? 1u : 0u) << what << ", mu2 " << exact.mu2;
      EXPECT_EQ(overlap.size(), overlapping ? 1u : 0u) << what << ", mu2 " << exact.mu2;
      // (The closed forms to 8 eps, as for pairs of ordinary sizes.)
      if (with_mu2.size() == 1) {
        EXPECT_NEAR(with_mu2.mu2[0], exact.mu2, 8e-16 * exact.mu2) << what;
      }
      pwcontact::MovingScene scene(s, Box::open());
      const auto trial = scene.particles().particle_at(1);
      EXPECT_EQ(scene.overlap_count(trial, 1), overlapping ? 1u : 0u) << what;
      EXPECT_EQ(scene.overlaps(trial, 1), overlapping ? 0 : pwcontact::MovingScene::none) << what;
      const auto near = scene.neighbors(trial, 1.0, true, 1);
      ASSERT_EQ(near.size(), overlapping ? 1u : 0u) << what;
      if (overlapping) {
        EXPECT_NEAR(near[0].mu2, exact.mu2, 8e-16 * exact.mu2) << what;
      }
    }
  }
}

TEST(Screen, AParticleWhoseQIsNotPositiveDefiniteIsRejectedByTheStore) {
  ParticleStore s;
  s.add({0, 0, 0}, pwcontact::sphere(1.0));
  try {
    s.add({0, 0, 0}, {1, 0, 0, 1, 0, -1});
    ADD_FAILURE() << "an indefinite Q was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("particle 1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(s.add({0, 0, std::nan("")}, pwcontact::sphere(1.0)), std::invalid_argument);
  EXPECT_EQ(s.size(), 1u);
}

TEST(Screen, RadiiBoundTheEllipsoid) {
  // Semi-axes 0.5, 1, 3: bounding radius 3 and inscribed 0.5, rounded outwards
  // and inwards by 64 eps of the largest eigenvalue (ParticleStore::add):
  // relative 64 eps cond(Q) / 2 = 2.6e-13 for the inscribed one here.
  ParticleStore s;
  s.add_axes({0, 0, 0}, {0.5, 1, 3}, {0.3, -0.2, 0.9, 0.1});
  EXPECT_GE(s.bounding_radius()[0], 3.0);
  EXPECT_LE(s.bounding_radius()[0], 3.0 * (1 + 1e-13));
  EXPECT_LE(s.inscribed_radius()[0], 0.5);
  EXPECT_GE(s.inscribed_radius()[0], 0.5 * (1 - 1e-12));
}

TEST(Screen, RadiiFromSemiAxesBoundTheStoredFormsEigenvalues) {
  // add_axes takes the radii from the semi-axes (no eigensolver): they must
  // bound the form actually stored, whose eigenvalues (long double Eigen, an
  // independent computation) differ from a^2 by its rounding. Aspect ratios
  // to 1e4, random rotations.
  std::mt19937_64 engine(41);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore s;
  for (int k = 0; k < 2000; ++k) {
    const std::array<double, 3> axes = {std::pow(10.0, 4 * unit(engine) - 2),
                                        std::pow(10.0, 4 * unit(engine) - 2),
                                        std::pow(10.0, 4 * unit(engine) - 2)};
    s.add_axes({0, 0, 0}, axes, {normal(engine), normal(engine), normal(engine), normal(engine)});
    const std::array<double, 6> q = form(s, s.size() - 1);
    Eigen::Matrix<long double, 3, 3> m;
    m << q[0], q[1], q[2], q[1], q[3], q[4], q[2], q[4], q[5];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<long double, 3, 3>> solver(
        m, Eigen::EigenvaluesOnly);
    const long double smallest = solver.eigenvalues()[0], largest = solver.eigenvalues()[2];
    ASSERT_GE((long double)s.bounding_radius().back(), std::sqrt(largest)) << k;
    ASSERT_LE((long double)s.inscribed_radius().back(), std::sqrt(smallest)) << k;
  }
}

// ---------------------------------------------------------------------------
// Shape types

// n particles of random types among `types` (and, every fourth, an untyped
// particle of the same semi-axes by add_axes when `mixed`), random centres
// in [0, box)^3 and random quaternions (of any norm).
ParticleStore typed_scene(const std::vector<std::array<double, 3>>& types, std::size_t n,
                          double box, bool mixed, std::uint64_t seed) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore s;
  for (const auto& axes : types) s.add_type(axes);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t t = std::uint32_t(engine() % types.size());
    const std::array<double, 3> c = {box * unit(engine), box * unit(engine), box * unit(engine)};
    const std::array<double, 4> q = {normal(engine), normal(engine), normal(engine),
                                     normal(engine)};
    if (mixed && k % 4 == 3)
      s.add_axes(c, types[t], q);
    else
      s.add_typed(c, t, q);
  }
  return s;
}

// set_axes writes its common case straight into the arrays, by the
// operations particle_axes() uses: the stored numbers must be that
// Particle's, bit for bit, and what it refuses must still be refused with
// the particle's name. Random semi-axes over 1e-150 .. 1e150 (and equal
// ones: spheres), quaternions of any scale (1e-300 .. 1e300: the scaled
// path), aspect ratios to 1e8 (beyond ~8e6 the form is not definite).
TEST(Screen, SetAxesStoresWhatParticleAxesGives) {
  std::mt19937_64 engine(401);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  ParticleStore store;
  std::vector<ParticleStore::Particle> expected;
  std::size_t spheres = 0, refused = 0;
  for (int k = 0; k < 20000; ++k) {
    const double scale = std::pow(10.0, -150 + 300 * unit(engine));
    std::array<double, 3> axes;
    for (double& a : axes) a = scale * std::pow(10.0, 8 * unit(engine) - 4);
    if (k % 10 == 0) axes = {scale, scale, scale};  // a sphere
    std::array<double, 4> q;
    const double q_scale = k % 7 == 0 ? std::pow(10.0, -300 + 600 * unit(engine)) : 1;
    for (double& c : q) c = q_scale * normal(engine);
    const std::array<double, 3> centre = {1e3 * normal(engine), normal(engine), -normal(engine)};
    bool general_refuses = false;
    std::optional<ParticleStore::Particle> general;
    try {
      general.emplace(ParticleStore::particle_axes(centre, axes, q));
    } catch (const std::invalid_argument&) {
      general_refuses = true;
    }
    const std::size_t i = store.size();
    store.resize(i + 1);
    bool refuses = false;
    try {
      store.set_axes(i, centre, axes, q);
    } catch (const std::invalid_argument& e) {
      refuses = true;
      EXPECT_NE(std::string(e.what()).find("particle " + std::to_string(i)), std::string::npos)
          << e.what();
    }
    ASSERT_EQ(refuses, general_refuses) << k;
    if (refuses) {
      ++refused;
      store.resize(i);
      continue;
    }
    spheres += general->sphere_radius() > 0;
    expected.push_back(*general);
  }
  ASSERT_EQ(store.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const ParticleStore::Particle& p = expected[i];
    for (int k = 0; k < 3; ++k) EXPECT_EQ(store.centre(k)[i], p.centre()[k]) << i;
    for (int k = 0; k < 6; ++k) EXPECT_EQ(store.q(k)[i], p.q()[k]) << i << " " << k;
    EXPECT_EQ(store.bounding_radius()[i], p.bounding_radius()) << i;
    EXPECT_EQ(store.inscribed_radius()[i], p.inscribed_radius()) << i;
    EXPECT_EQ(store.sphere_radius()[i], p.sphere_radius()) << i;
    EXPECT_EQ(store.type_id()[i], ParticleStore::untyped) << i;
  }
  EXPECT_GT(spheres, 1000u);
  EXPECT_GT(refused, 100u);  // the forms too elongated to be definite
  std::printf(
      "[ measured ] %zu particles stored as particle_axes gives them (%zu spheres), %zu "
      "refused by both\n",
      expected.size(), spheres, refused);
  // A zero or non-finite quaternion: refused naming the particle, for a
  // sphere too (its rotation does not matter, but a NaN there is malformed
  // input: it was taken silently), by every way of storing one.
  ParticleStore s;
  s.resize(2);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const std::array<double, 3>& axes :
       {std::array<double, 3>{1, 2, 3}, std::array<double, 3>{2, 2, 2}})
    for (const std::array<double, 4>& q :
         {std::array<double, 4>{0, 0, 0, 0}, std::array<double, 4>{nan, 0, 0, 0},
          std::array<double, 4>{1, inf, 0, 0}}) {
      try {
        s.set_axes(1, {0, 0, 0}, axes, q);
        ADD_FAILURE() << "a quaternion " << q[0] << " " << q[1] << " taken for axes " << axes[0]
                      << " " << axes[1] << " " << axes[2];
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("particle 1"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("quaternion"), std::string::npos) << e.what();
      }
      EXPECT_THROW(ParticleStore::particle_axes({0, 0, 0}, axes, q), std::invalid_argument);
      EXPECT_THROW(ParticleStore().add_axes({0, 0, 0}, axes, q), std::invalid_argument);
    }
  ParticleStore typed;
  const std::uint32_t ball = typed.add_type({2, 2, 2});
  EXPECT_THROW(typed.add_typed({0, 0, 0}, ball, {nan, 0, 0, 0}), std::invalid_argument);
  s.set_axes(1, {0, 0, 0}, {2, 2, 2}, {1e-300, 0, 0, 0});  // any non-zero finite one
  EXPECT_EQ(s.sphere_radius()[1], 2.0);
  EXPECT_THROW(s.set_axes(2, {0, 0, 0}, {1, 1, 1}, {1, 0, 0, 0}), std::out_of_range);
}

TEST(Screen, TypedParticlesAreStoredAsTheirSemiAxesWouldBe) {
  // A typed particle has the form add_axes makes of the same numbers and its
  // type's radii, bit for bit (the radii computed once per type).
  const std::vector<std::array<double, 3>> types = {
      {0.2, 0.5, 1.2}, {0.7, 0.7, 0.7}, {1e-3, 2, 5e2}};
  const ParticleStore typed = typed_scene(types, 300, 10, false, 51);
  std::mt19937_64 engine(51);
  ParticleStore by_axes;
  for (std::size_t i = 0; i < typed.size(); ++i) {
    const std::uint32_t t = typed.type_id()[i];
    ASSERT_LT(t, types.size());
    EXPECT_EQ(typed.type_semi_axes(t), types[t]);
  }
  // The same particles by add_axes (the same draws).
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  for (std::size_t k = 0; k < typed.size(); ++k) {
    const std::uint32_t t = std::uint32_t(engine() % types.size());
    const std::array<double, 3> c = {10 * unit(engine), 10 * unit(engine), 10 * unit(engine)};
    by_axes.add_axes(c, types[t], {normal(engine), normal(engine), normal(engine), normal(engine)});
  }
  for (std::size_t i = 0; i < typed.size(); ++i) {
    for (int k = 0; k < 6; ++k) ASSERT_EQ(typed.q(k)[i], by_axes.q(k)[i]) << "particle " << i;
    EXPECT_EQ(typed.bounding_radius()[i], by_axes.bounding_radius()[i]) << "particle " << i;
    EXPECT_EQ(typed.inscribed_radius()[i], by_axes.inscribed_radius()[i]) << "particle " << i;
    EXPECT_EQ(typed.sphere_radius()[i], by_axes.sphere_radius()[i]) << "particle " << i;
    EXPECT_EQ(by_axes.type_id()[i], ParticleStore::untyped);
  }
}

TEST(Screen, ScenesOfShapeTypesMatchTheBruteForce) {
  // Three types (an ellipsoid, a sphere, a needle) with untyped particles
  // among them, periodic and open, overlaps and a neighbour list.
  const std::vector<std::array<double, 3>> types = {
      {0.2, 0.5, 1.2}, {0.6, 0.6, 0.6}, {0.05, 0.05, 1.5}};
  const ParticleStore s = typed_scene(types, 1500, 11, true, 52);
  for (const Box& box : {Box::periodic_box(11, 11, 11), Box::open()})
    for (double cutoff : {1.0, 1.3}) {
      ScreenedPairs got;
      const ScreenReport report = screen(s, box, cutoff, got);
      EXPECT_FALSE(report.one_type);
      EXPECT_FALSE(report.identical_shapes);
      const std::string what = std::string("three types and untyped, ") +
                               (box.periodic ? "periodic" : "open") + ", cutoff " +
                               std::to_string(cutoff);
      const Comparison c = compare(s, box, cutoff, got, what);
      EXPECT_GT(c.expected, 300u) << what;
    }
}

TEST(Screen, OneShapeTypeDeclaresIdenticalShapesAndAlignedPairsAreTakenInClosedForm) {
  // One type, random orientations: identical shapes by declaration (one
  // size class), the brute force's pairs. One type, one orientation (the
  // same quaternion): every near pair of one form, mu^2 in closed form.
  const ParticleStore random = typed_scene({{0.3, 0.3, 0.9}}, 1500, 10, false, 53);
  const Box box = Box::periodic_box(10, 10, 10);
  ScreenedPairs got;
  const ScreenReport report = screen(random, box, 1, got);
  EXPECT_TRUE(report.one_type);
  EXPECT_TRUE(report.identical_shapes);
  EXPECT_EQ(report.size_classes, 1u);
  EXPECT_GT(compare(random, box, 1, got, "one type, random orientations").expected, 200u);

  ParticleStore aligned;
  aligned.add_type({0.2, 0.5, 1.2});
  std::mt19937_64 engine(54);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int k = 0; k < 1200; ++k)
    aligned.add_typed({9 * unit(engine), 9 * unit(engine), 9 * unit(engine)}, 0,
                      {0.9, 0.1, -0.3, 0.2});
  const Box aligned_box = Box::periodic_box(9, 9, 9);
  ScreenedPairs aligned_pairs;
  const ScreenReport aligned_report = screen(aligned, aligned_box, 1, aligned_pairs);
  EXPECT_TRUE(aligned_report.one_type);
  EXPECT_EQ(aligned_report.solved, 0u);
  EXPECT_GT(aligned_report.decided_same_form, 300u);
  EXPECT_GT(compare(aligned, aligned_box, 1, aligned_pairs, "one type, one orientation").expected,
            200u);
  // A second type, even of the same semi-axes, is no longer one type (the
  // radii still show identical shapes).
  ParticleStore two = random;
  two.add_type({0.3, 0.3, 0.9});
  two.add_typed({5, 5, 5}, 1, {1, 0, 0, 0});
  const ScreenReport two_report = screen(two, box, 1, got);
  EXPECT_FALSE(two_report.one_type);
  EXPECT_TRUE(two_report.identical_shapes);
}

TEST(Screen, BadTypesAndTypedParticlesAreRefusedNamingThem) {
  ParticleStore s;
  auto message = [](auto&& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message([&] {
              s.add_type({1, 0, 2});
            }),
            "type 0: semi-axes must be positive and finite, got (1, 0, 2)");
  EXPECT_EQ(message([&] {
              s.add_type({1e200, 1, 1});
            }),
            "type 0: Q is not finite (its largest eigenvalue, a semi-axis squared, overflows)");
  EXPECT_EQ(s.types(), 0u);
  s.add_type({1, 2, 3});
  EXPECT_EQ(message([&] {
              s.add_typed({0, 0, 0}, 1, {1, 0, 0, 0});
            }),
            "particle 0: type 1 does not exist (1 types)");
  EXPECT_EQ(s.size(), 0u);
  EXPECT_NE(message([&] {
              s.add_typed({0, 0, 0}, 0, {0, 0, 0, 0});
            }).find("particle 0: "),
            std::string::npos);
  EXPECT_EQ(s.size(), 0u);
  EXPECT_EQ(message([&] {
              s.add_typed({NAN, 0, 0}, 0, {1, 0, 0, 0});
            }),
            "particle 0: centre is not finite");
  s.add_typed({0, 0, 0}, 0, {1, 0, 0, 0});
  EXPECT_EQ(s.size(), 1u);
  EXPECT_EQ(s.type_id()[0], 0u);
}

TEST(Screen, AnEmptySceneAndASingleParticleFindNothing) {
  ParticleStore s;
  ScreenedPairs out;
  EXPECT_EQ(screen(s, Box::open(), 1, out).found, 0u);
  s.add({0, 0, 0}, pwcontact::sphere(1.0));
  EXPECT_EQ(screen(s, Box::periodic_box(5, 5, 5), 1, out).found, 0u);
  EXPECT_EQ(out.size(), 0u);
}

}  // namespace

// The radix sort of the pairs found, against std::stable_sort on keys as
// the screen makes them (i << 32 | j, both below the particle count), with
// repeated keys and a payload that must travel with its key.
TEST(ScreenRadixSort, SortsPairKeysStablyAsAComparisonSortDoes) {
  std::mt19937_64 engine(11);
  for (std::size_t particles :
       {std::size_t(1), std::size_t(2), std::size_t(3), std::size_t(2047), std::size_t(2049),
        std::size_t(1) << 22, (std::size_t(1) << 31) - 1}) {
    for (std::size_t n : {std::size_t(0), std::size_t(1), std::size_t(2), std::size_t(5000)}) {
      std::uniform_int_distribution<std::uint64_t> index(0, particles - 1);
      std::vector<std::pair<std::uint64_t, std::size_t>> v;
      for (std::size_t k = 0; k < n; ++k) {
        // A tenth repeat an earlier key (the same pair found twice).
        const std::uint64_t key =
            k > 0 && k % 10 == 0 ? v[k / 2].first : (index(engine) << 32) | index(engine);
        v.push_back({key, k});
      }
      std::vector<std::pair<std::uint64_t, std::size_t>> expected = v;
      std::stable_sort(expected.begin(), expected.end(),
                       [](const auto& x, const auto& y) { return x.first < y.first; });
      pwcontact::screen::radix_sort_pair_keys(v, pwcontact::screen::index_bits(particles),
                                              [](const auto& x) { return x.first; });
      EXPECT_EQ(v, expected) << particles << " particles, " << n << " keys";
    }
  }
  EXPECT_EQ(pwcontact::screen::index_bits(1), 0);
  EXPECT_EQ(pwcontact::screen::index_bits(2), 1);
  EXPECT_EQ(pwcontact::screen::index_bits(1000000), 20);
  EXPECT_EQ(pwcontact::screen::index_bits(std::size_t(1) << 20), 20);
}

namespace {

// A triclinic box's centres far from it are wrapped by whole lattice vectors
// in double-double arithmetic: the pairs and mu^2 are those of the scene at
// the box. (Through the rounded fractional coordinates, a centre K box
// lengths away lost eps K box lengths, and beyond 2^52 its whole residue:
// it was placed at the box's origin.)
TEST(Screen, TriclinicCentresFarFromTheBoxGiveThePairsAndMu2OfTheSceneAtTheBox) {
  // Lattice vectors of small integers (h = [[8, 3, -2], [0, 8, 1], [0, 0, 8]]),
  // centres on a grid of 2^-20: every shifted centre below is exact.
  const Box box = Box::triclinic(8, 8, 8, 0.375, -0.25, 0.125);
  const double h[3][3] = {{8, 3, -2}, {0, 8, 1}, {0, 0, 8}};
  std::mt19937_64 engine(11);
  std::uniform_real_distribution<double> unit(0, 1);
  ParticleStore at_box, shifted;
  for (int n = 0; n < 600; ++n) {
    std::array<double, 3> c, axes;
    for (double& x : c) x = std::ldexp(std::floor(std::ldexp(8 * unit(engine), 20)), -20);
    for (double& a : axes) a = 0.15 + 0.35 * unit(engine);
    std::normal_distribution<double> normal(0, 1);
    const std::array<double, 4> q = {normal(engine), normal(engine), normal(engine),
                                     normal(engine)};
    at_box.add_axes(c, axes, q);
    // Whole lattice vectors, up to 2^28 of each: |x| < 2^33, exact with
    // the centre's 20 bits of fraction.
    std::array<double, 3> far = c;
    for (int k = 0; k < 3; ++k) {
      const double m = std::floor((2 * unit(engine) - 1) * std::ldexp(1, 28));
      for (int r = 0; r < 3; ++r) far[r] += m * h[r][k];
    }
    shifted.add_axes(far, axes, q);
  }
  ScreenOptions options;
  options.cutoff = 1.2;
  options.with_mu2 = true;
  ScreenedPairs near, far;
  pwcontact::screen_pairs(at_box, box, options, near);
  pwcontact::screen_pairs(shifted, box, options, far);
  ASSERT_GT(near.size(), 100u);
  ASSERT_EQ(far.size(), near.size());
  double worst = 0;
  for (std::size_t k = 0; k < near.size(); ++k) {
    ASSERT_EQ(far.i[k], near.i[k]);
    ASSERT_EQ(far.j[k], near.j[k]);
    worst = std::max(worst, std::abs(far.mu2[k] - near.mu2[k]) / near.mu2[k]);
  }
  // Both wraps within a few eps of the box's lengths: mu^2 to ~1e-14 (it
  // was ~1e-6 at these distances).
  EXPECT_LT(worst, 1e-12);
  std::printf("[ measured ] %zu pairs, centres up to 2^28 box lengths away: mu^2 within %.2g\n",
              near.size(), worst);

  // Beyond 2^52 box lengths: B lies 10 * 2^53 + 10 from A along the first
  // lattice vector, which a tilt of the third leaves along x; B coincides
  // with A's image, C is 5.5 from both.
  const Box tilted = Box::triclinic(10, 10, 10, 0, 0, 1e-3);
  ParticleStore three;
  three.add_axes({6, 5, 5}, {0.5, 0.4, 0.3}, {1, 0, 0, 0});
  three.add_axes({10 * std::ldexp(1, 53) + 16, 5, 5}, {0.5, 0.4, 0.3}, {1, 0, 0, 0});
  three.add_axes({0.5, 5, 5}, {0.5, 0.4, 0.3}, {1, 0, 0, 0});
  ScreenedPairs pairs;
  pwcontact::screen_pairs(three, tilted, {}, pairs);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs.i[0], 0u);
  EXPECT_EQ(pairs.j[0], 1u);
}

}  // namespace

namespace {

// A slot resize() left unset has no shape: every screen and scene refuses
// the store, naming it. (Its reach of 0 sized no grid: screen_pairs and
// for_each_candidate_pair never returned, and screen_candidates reported
// the pair found.)
TEST(Screen, AParticleThatResizeLeftUnsetIsRefusedNamingIt) {
  ParticleStore s;
  s.resize(3);
  s.set_axes(0, {1, 1, 1}, {1, 0.5, 0.5}, {1, 0, 0, 0});
  s.set_axes(2, {2, 1, 1}, {1, 0.5, 0.5}, {1, 0, 0, 0});
  EXPECT_EQ(s.first_unset(), 1u);
  auto expect_refused = [](auto&& call) {
    try {
      call();
      ADD_FAILURE() << "no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("particle 1 was never set"), std::string::npos)
          << e.what();
    }
  };
  for (const Box& box : {Box::open(), Box::periodic_box(10, 10, 10)}) {
    ScreenedPairs out;
    expect_refused([&] { pwcontact::screen_pairs(s, box, {}, out); });
    const std::uint32_t first[1] = {0}, second[1] = {1};
    expect_refused([&] { pwcontact::screen_candidates(s, box, first, second, 1, {}, out); });
    expect_refused([&] {
      pwcontact::for_each_candidate_pair(s, box, 1.0, 1,
                                         [](int, std::uint32_t, std::uint32_t, const double*) {});
    });
    expect_refused([&] { pwcontact::MovingScene scene(s, box); });
  }
  s.set_axes(1, {5, 5, 5}, {1, 0.5, 0.5}, {1, 0, 0, 0});
  EXPECT_EQ(s.first_unset(), 3u);
  ScreenedPairs out;
  pwcontact::screen_pairs(s, Box::open(), {}, out);
  EXPECT_EQ(out.size(), 1u);
}

}  // namespace
