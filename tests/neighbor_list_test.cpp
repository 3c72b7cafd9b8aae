// The neighbour list with a skin against a fresh screen_pairs at every step
// of slowly moving and turning scenes; warm starts against cold ones and
// against the reference path.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pwcontact/pwcontact.hpp"
#include "test_support.hpp"

namespace {

using pwcontact::Box;
using pwcontact::ParticleStore;

// q1 q2 (Hamilton product, (w, x, y, z)).
std::array<double, 4> multiply(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

struct Moving {
  Box box;
  std::vector<std::array<double, 3>> centre, axes;
  std::vector<std::array<double, 4>> orientation;
  ParticleStore store() const {
    ParticleStore s;
    for (std::size_t i = 0; i < centre.size(); ++i) s.add_axes(centre[i], axes[i], orientation[i]);
    return s;
  }
  // Every particle moved by up to `step` along each axis and turned by up to
  // `turn` radians.
  void move(std::mt19937_64& engine, double step, double turn) {
    std::uniform_real_distribution<double> unit(-1, 1);
    for (std::size_t i = 0; i < centre.size(); ++i) {
      for (double& x : centre[i]) x += step * unit(engine);
      const double angle = turn * unit(engine) / 2;
      double axis[3] = {unit(engine), unit(engine), unit(engine)};
      const double norm = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
      orientation[i] =
          multiply({std::cos(angle), std::sin(angle) * axis[0] / norm,
                    std::sin(angle) * axis[1] / norm, std::sin(angle) * axis[2] / norm},
                   orientation[i]);
    }
  }
};

Moving random_scene(std::size_t n, double length, std::uint64_t seed, bool triclinic) {
  std::mt19937_64 engine(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  Moving m;
  m.box = triclinic ? Box::triclinic(length, length, length, 0.3, -0.2, 0.1)
                    : Box::periodic_box(length, length, length);
  for (std::size_t i = 0; i < n; ++i) {
    m.centre.push_back({length * unit(engine), length * unit(engine), length * unit(engine)});
    const double a = 0.2 + 0.3 * unit(engine);
    m.axes.push_back({a, a * (0.5 + unit(engine)), a * (0.4 + 2 * unit(engine))});
    m.orientation.push_back({normal(engine), normal(engine), normal(engine), normal(engine)});
  }
  return m;
}

// The pairs of `got` and of a fresh screen_pairs, compared: the same pairs
// (but those within 1e-9 of the cutoff), mu^2 within 1e-10 (both are the
// batch path's mu^2, from different starts).
void expect_same(const pwcontact::ScreenedPairs& got, const ParticleStore& s, const Box& box,
                 double cutoff, const std::string& where) {
  pwcontact::ScreenedPairs fresh;
  pwcontact::ScreenOptions options;
  options.cutoff = cutoff;
  options.with_mu2 = true;
  pwcontact::screen_pairs(s, box, options, fresh);
  // (The pairs come as the screen gives them: i < j, sorted by i then j.)
  for (std::size_t k = 0; k < got.size(); ++k) {
    ASSERT_LT(got.i[k], got.j[k]) << where << ", pair " << k;
    if (k > 0) {
      ASSERT_TRUE(got.i[k - 1] < got.i[k] || (got.i[k - 1] == got.i[k] && got.j[k - 1] < got.j[k]))
          << where << ": pairs " << k - 1 << " and " << k << " out of order";
    }
  }
  std::map<std::pair<std::uint32_t, std::uint32_t>, double> expected, found;
  for (std::size_t k = 0; k < fresh.size(); ++k) expected[{fresh.i[k], fresh.j[k]}] = fresh.mu2[k];
  for (std::size_t k = 0; k < got.size(); ++k) found[{got.i[k], got.j[k]}] = got.mu2[k];
  const double band = 1e-9 * cutoff * cutoff;
  for (const auto& [pair, mu2] : expected) {
    auto f = found.find(pair);
    if (f == found.end()) {
      EXPECT_GE(mu2, cutoff * cutoff - band)
          << where << ": missed (" << pair.first << ", " << pair.second << ")";
      continue;
    }
    EXPECT_NEAR(f->second, mu2, 1e-10 * mu2) << where;
  }
  for (const auto& [pair, mu2] : found)
    if (!expected.count(pair)) {
      EXPECT_GE(mu2, cutoff * cutoff - band)
          << where << ": extra (" << pair.first << ", " << pair.second << ")";
    }
}

TEST(SkinNeighborList, EveryStepIsTheFreshScreenAndTheListIsKeptWhileTheSkinAllows) {
  for (bool triclinic : {false, true}) {
    std::mt19937_64 engine(triclinic ? 21 : 20);
    Moving m = random_scene(1500, 12, triclinic ? 3 : 2, triclinic);
    pwcontact::SkinOptions options;
    options.cutoff = 1.4;
    options.skin = 0.15;
    pwcontact::SkinNeighborList list(options);
    std::size_t kept = 0;
    for (int step = 0; step < 60; ++step) {
      const ParticleStore s = m.store();
      pwcontact::ScreenedPairs pairs;
      const pwcontact::SkinReport r = list.update(s, m.box, pairs);
      kept += !r.rebuilt;
      if (!r.rebuilt) {
        EXPECT_LE(r.largest_move, options.skin);
      }
      expect_same(
          pairs, s, m.box, options.cutoff,
          std::string(triclinic ? "triclinic" : "cubic") + ", step " + std::to_string(step));
      // Slow, with now and then a jump beyond the skin.
      m.move(engine, step % 17 == 16 ? 0.3 : 0.004, 0.004);
    }
    EXPECT_GT(kept, 30u) << "the list is kept while the moves are small";
    EXPECT_GE(list.rebuilds(), 4u) << "and rebuilt after the jumps (and as the moves add up)";
  }
}

// Centres given many box lengths away (an unwrapped trajectory): a kept
// list's mu^2 are the fresh screen's to 1e-12, as at the box. Was: the kept
// pairs' separations were differences of the centres as given, which lost
// eps |x| (2e-9 of mu^2 at 10^6 box lengths).
TEST(SkinNeighborList, CentresManyBoxLengthsAwayKeepTheListAndItsAccuracy) {
  Moving m = random_scene(600, 8, 5, false);
  pwcontact::SkinOptions options;
  options.cutoff = 1.3;
  options.skin = 0.2;
  std::mt19937_64 engine(6);
  for (double lengths : {1e3, 1e6}) {
    pwcontact::SkinNeighborList list(options);
    pwcontact::ScreenedPairs pairs;
    list.update(m.store(), m.box, pairs);
    Moving far = m;
    for (auto& c : far.centre)
      for (double& x : c) x += 8 * lengths * double(int(engine() % 3) - 1);
    const ParticleStore s = far.store();
    const pwcontact::SkinReport r = list.update(s, far.box, pairs);
    ASSERT_FALSE(r.rebuilt) << lengths;
    pwcontact::ScreenedPairs fresh;
    pwcontact::ScreenOptions screen_options;
    screen_options.cutoff = options.cutoff;
    screen_options.with_mu2 = true;
    pwcontact::screen_pairs(s, far.box, screen_options, fresh);
    ASSERT_EQ(pairs.size(), fresh.size()) << lengths;
    ASSERT_GT(pairs.size(), 100u);
    double worst = 0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      ASSERT_EQ(pairs.i[k], fresh.i[k]);
      ASSERT_EQ(pairs.j[k], fresh.j[k]);
      worst = std::max(worst, std::abs(pairs.mu2[k] - fresh.mu2[k]) / fresh.mu2[k]);
    }
    // (Both the batch path's answers, from different starts.)
    EXPECT_LT(worst, 1e-12) << lengths << " box lengths";
  }
}

// Ellipses in a 2D box whose third semi-axis (which the plane never sees)
// is far smaller than the other two: the skin is measured against the
// in-plane inscribed radius, so small moves keep the list, and every step
// is still the fresh screen's. Was: rho was the third semi-axis, 1e-3, and
// every step rebuilt.
TEST(SkinNeighborList, FlatEllipsesInAPlaneKeepTheListWhileTheirMovesAreSmall) {
  std::mt19937_64 engine(31);
  std::uniform_real_distribution<double> unit(0, 1);
  const double length = 20;
  const Box box = Box::two_dimensional_box(length, length);
  std::vector<std::array<double, 3>> centre, axes;
  std::vector<double> angle;
  for (int i = 0; i < 400; ++i) {
    centre.push_back({length * unit(engine), length * unit(engine), 0});
    const double a = 0.4 + 0.4 * unit(engine);
    axes.push_back({a, a * (0.3 + 0.6 * unit(engine)), 1e-3});
    angle.push_back(6.283185307179586 * unit(engine));
  }
  pwcontact::SkinOptions options;
  options.cutoff = 1.2;
  options.skin = 0.2;
  pwcontact::SkinNeighborList list(options);
  std::size_t kept = 0;
  for (int step = 0; step < 30; ++step) {
    ParticleStore s;
    for (std::size_t i = 0; i < centre.size(); ++i)
      s.add_axes(centre[i], axes[i], {std::cos(angle[i] / 2), 0, 0, std::sin(angle[i] / 2)});
    pwcontact::ScreenedPairs pairs;
    const pwcontact::SkinReport r = list.update(s, box, pairs);
    kept += !r.rebuilt;
    expect_same(pairs, s, box, options.cutoff, "2D, step " + std::to_string(step));
    for (std::size_t i = 0; i < centre.size(); ++i) {
      centre[i][0] += 0.004 * (2 * unit(engine) - 1);
      centre[i][1] += 0.004 * (2 * unit(engine) - 1);
      angle[i] += 0.004 * (2 * unit(engine) - 1);
    }
  }
  EXPECT_GT(kept, 15u) << "the list is kept while the moves are small";
}

// A 2D box whose particles are not all in its plane: the screen measures
// their pairs in 3D, and so must the skin (the in-plane inscribed radius
// bounds only moves and turns within the plane). Was: discs tilted out of
// the plane, or a centre moved back onto it, kept the list while a pair
// fell below the cutoff, and the pair was missing. The oracle: the
// reference path in long double.
TEST(SkinNeighborList, ParticlesOutOfATwoDimensionalBoxsPlaneMeasureTheSkinIn3D) {
  using pwtest::long_double_oracle;
  using pwtest::make_pair;
  const Box box = Box::two_dimensional_box(20, 20);
  pwcontact::SkinOptions options;
  options.cutoff = 1.5;
  options.skin = 0.2;
  auto check = [&](const std::array<double, 3>& c0, const std::array<double, 3>& c1,
                   const pwcontact::QuadraticForm& q, const std::string& where) {
    // (Both steps are called on one list: the first builds it.)
    return [=](pwcontact::SkinNeighborList& list) {
      ParticleStore s;
      s.add(c0, q);
      s.add(c1, q);
      pwcontact::ScreenedPairs pairs;
      list.update(s, box, pairs);
      const double mu2 = double(
          long_double_oracle(make_pair({c1[0] - c0[0], c1[1] - c0[1], c1[2] - c0[2]}, q, q)).mu2);
      EXPECT_EQ(pairs.size(), mu2 < options.cutoff * options.cutoff ? 1u : 0u)
          << where << ": the oracle's mu^2 " << mu2;
    };
  };
  {
    // Discs (1, 1, 0.01) turned by 45 degrees about x, 0.05 then 0.04 apart
    // along y: mu 1.77 then 1.41 (tilted, a move along y meets the thin side).
    const double half = 0.39269908169872414;  // pi / 8
    const pwcontact::QuadraticForm q = pwcontact::quadratic_form_from_quaternion(
        {1, 1, 0.01}, {std::cos(half), std::sin(half), 0, 0});
    pwcontact::SkinNeighborList list(options);
    check({5, 5, 0}, {5, 5.05, 0}, q, "tilted discs, built")(list);
    check({5, 5, 0}, {5, 5.04, 0}, q, "tilted discs, moved by 0.01")(list);
  }
  {
    // Flat particles in the plane's orientation, one centre off the plane
    // by 0.025, then moved onto it: mu 1.30 at z = 0.
    const pwcontact::QuadraticForm q =
        pwcontact::quadratic_form({1, 1, 0.01}, {1, 0, 0, 0, 1, 0, 0, 0, 1});
    pwcontact::SkinNeighborList list(options);
    check({5, 5, 0}, {7.6, 5, 0.025}, q, "a centre off the plane, built")(list);
    check({5, 5, 0}, {7.6, 5, 0}, q, "moved onto the plane")(list);
  }
}

// A kept list checks the store as a rebuild's screen does: a particle that
// resize() left unset (Q = 0) is refused, not taken for one that never
// moved.
TEST(SkinNeighborList, AnUnsetParticleIsRefusedWhenTheListIsKept) {
  pwcontact::SkinOptions options;
  options.cutoff = 1.5;
  options.skin = 5;
  pwcontact::SkinNeighborList list(options);
  ParticleStore a;
  a.add({0, 0, 0}, pwcontact::sphere(1));
  a.add({2.5, 0, 0}, pwcontact::sphere(1));
  pwcontact::ScreenedPairs pairs;
  list.update(a, Box::open(), pairs);
  ParticleStore b;
  b.resize(2);
  b.set(1, {2.5, 0, 0}, pwcontact::sphere(1));
  try {
    list.update(b, Box::open(), pairs);
    ADD_FAILURE() << "an unset particle was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("particle 0 was never set"), std::string::npos)
        << e.what();
  }
}

TEST(SkinNeighborList, ACutoffAndSkinWhoseSumOverflowsIsRefusedForThat) {
  pwcontact::SkinOptions options;
  options.cutoff = 1e308;
  options.skin = 1e308;
  try {
    pwcontact::SkinNeighborList list(options);
    ADD_FAILURE() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cutoff + skin must be finite"), std::string::npos)
        << e.what();
  }
}

TEST(SkinNeighborList, ATurnAloneBeyondTheSkinRebuildsTheList) {
  Moving m = random_scene(400, 8, 5, false);
  pwcontact::SkinOptions options;
  options.cutoff = 1.2;
  options.skin = 0.1;
  pwcontact::SkinNeighborList list(options);
  pwcontact::ScreenedPairs pairs;
  list.update(m.store(), m.box, pairs);
  // One needle turned by 0.3 rad about its centre, nothing else moved.
  m.axes[7] = {0.1, 0.1, 0.6};
  pwcontact::ScreenedPairs before;
  list.update(m.store(), m.box, before);  // (a new shape: rebuilt)
  const std::size_t rebuilds = list.rebuilds();
  m.orientation[7] = multiply({std::cos(0.15), std::sin(0.15), 0, 0}, m.orientation[7]);
  const pwcontact::SkinReport r = list.update(m.store(), m.box, pairs);
  EXPECT_TRUE(r.rebuilt);
  EXPECT_EQ(list.rebuilds(), rebuilds + 1);
  expect_same(pairs, m.store(), m.box, options.cutoff, "after the turn");
}

TEST(SkinNeighborList, WarmStartsSaveEvaluationsAndGiveTheColdAnswers) {
  std::mt19937_64 engine(30);
  Moving m = random_scene(3000, 15, 6, false);
  pwcontact::SkinOptions warm_options, cold_options;
  cold_options.warm_start = false;
  pwcontact::SkinNeighborList warm(warm_options), cold(cold_options);
  double warm_evaluations = 0, cold_evaluations = 0;
  for (int step = 0; step < 12; ++step) {
    const ParticleStore s = m.store();
    pwcontact::ScreenedPairs a, b;
    const auto rw = warm.update(s, m.box, a);
    const auto rc = cold.update(s, m.box, b);
    ASSERT_EQ(rw.rebuilt, rc.rebuilt);
    ASSERT_EQ(a.i, b.i);
    ASSERT_EQ(a.j, b.j);
    for (std::size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a.mu2[k], b.mu2[k], 1e-10 * b.mu2[k]);
    if (step > 1 && !rw.rebuilt) {
      warm_evaluations += rw.mean_evaluations;
      cold_evaluations += rc.mean_evaluations;
    }
    m.move(engine, 0.002, 0.002);
  }
  std::printf("[ measured ] mean evaluations per pair, warm %.3f, cold %.3f\n",
              warm_evaluations / 10, cold_evaluations / 10);
  // (The portable target makes no kernel evaluations to save.)
  if (!pwtest::on_portable_target()) {
    EXPECT_LT(warm_evaluations, 0.8 * cold_evaluations);
  }
}

// A kept step takes the pairs in an order along the cells of space, not in
// the order of the particles' indices (whose positions here are random):
// each pair still starts from its own lambda of the step before (tiny moves:
// one Newton step and the check, 2 evaluations; measured 2.0-2.1, where
// the radial guess takes 4), and the pairs come out as the fresh screen's,
// sorted, the same with 1 and 2 threads. In a periodic triclinic box, and
// in an open one with a particle far away (which the order's grid leaves
// to its outer cells: stretched over it, the grid put every other particle
// in one cell).
TEST(SkinNeighborList, PairsTakenInTheOrderOfSpaceKeepTheirOwnLambdaAndComeOutSorted) {
  for (int kind = 0; kind < 2; ++kind) {
    const bool open = kind == 1;
    std::mt19937_64 engine(40 + kind);
    Moving m = random_scene(4000, 16, 8 + std::uint64_t(kind), !open);
    if (open) {
      m.box = Box::open();
      m.centre[1234] = {1e7, -3e6, 5e5};
    }
    pwcontact::SkinOptions options;
    options.cutoff = 1.3;
    options.skin = 0.2;
    pwcontact::SkinOptions two = options;
    options.threads = 1;
    two.threads = 2;
    pwcontact::SkinNeighborList list(options), list_two(two);
    const std::string where = open ? "open, far particle" : "triclinic";
    for (int step = 0; step < 4; ++step) {
      const ParticleStore s = m.store();
      pwcontact::ScreenedPairs pairs, pairs_two;
      const pwcontact::SkinReport r = list.update(s, m.box, pairs);
      list_two.update(s, m.box, pairs_two);
      EXPECT_EQ(r.rebuilt, step == 0) << where;
      ASSERT_GT(pairs.size(), 1000u) << where;
      expect_same(pairs, s, m.box, options.cutoff, where + ", step " + std::to_string(step));
      EXPECT_EQ(pairs.i, pairs_two.i) << where;
      EXPECT_EQ(pairs.j, pairs_two.j) << where;
      EXPECT_EQ(pairs.mu2, pairs_two.mu2) << where;
      if (step > 1 && !pwtest::on_portable_target()) {
        EXPECT_LT(r.mean_evaluations, 2.3) << where << ", step " << step;
      }
      m.move(engine, 1e-4, 1e-4);
    }
  }
}

// After a rebuild the pairs that were listed before too start from the
// lambda of their last solve, not from the radial guess: the first kept step
// after a rebuild takes about the warm steps' evaluations (2.0 here, one
// Newton step and the check) where the radial guess takes 3.05, and its
// answers are the fresh screen's. A particle moved far forces the rebuild;
// its pairs are new and start cold. A rebuild with a particle more (other
// indices) takes no lambda over and is still the fresh screen.
TEST(SkinNeighborList, TheFirstKeptStepAfterARebuildStartsFromTheLambdasBefore) {
  std::mt19937_64 engine(50);
  Moving m = random_scene(4000, 16, 12, true);
  pwcontact::SkinOptions options;
  options.cutoff = 1.3;
  options.skin = 0.2;
  pwcontact::SkinNeighborList list(options);
  pwcontact::ScreenedPairs pairs;
  std::vector<double> evaluations;  // of each kept step
  auto step = [&](bool rebuilt, const std::string& where) {
    const ParticleStore s = m.store();
    const pwcontact::SkinReport r = list.update(s, m.box, pairs);
    EXPECT_EQ(r.rebuilt, rebuilt) << where;
    expect_same(pairs, s, m.box, options.cutoff, where);
    if (!r.rebuilt) {
      EXPECT_GT(r.solved, 1000u) << where;
      evaluations.push_back(r.mean_evaluations);
    }
    m.move(engine, 1e-4, 1e-4);
  };
  step(true, "the first rebuild");
  step(false, "the first kept step (cold)");
  step(false, "a warm step");
  m.centre[17][0] += 5;  // beyond any skin
  step(true, "the rebuild forced by a particle moved far");
  step(false, "the first kept step after it");
  m.centre.push_back({1, 2, 3});
  m.axes.push_back({0.3, 0.2, 0.25});
  m.orientation.push_back({1, 0, 0, 0});
  step(true, "the rebuild for a particle more");
  step(false, "the first kept step after it (cold: other indices)");
  std::printf(
      "[ measured ] evaluations per pair: first kept step %.3f, warm step %.3f, first "
      "after a rebuild %.3f, after a rebuild with a particle more %.3f\n",
      evaluations[0], evaluations[1], evaluations[2], evaluations[3]);
  if (!pwtest::on_portable_target()) {
    EXPECT_GT(evaluations[0], 2.7);  // (the radial guess: the test tells the two apart)
    EXPECT_LT(evaluations[1], 2.3);
    EXPECT_LT(evaluations[2], 2.3);
    EXPECT_GT(evaluations[3], 2.7);
  }
}

TEST(WarmStart, AnyStartingLambdaGivesTheReferenceAnswer) {
  // Starts at the exact lambda, near it, at the ends, outside (0, 1) and NaN:
  // the answer is the reference path's whichever.
  std::mt19937_64 engine(31);
  std::uniform_real_distribution<double> unit(0, 1);
  const Moving m = random_scene(200, 5, 7, false);
  const ParticleStore s = m.store();
  pwcontact::PairBatch<double> batch;
  std::vector<double> exact_mu2, exact_lambda;
  for (std::uint32_t i = 0; i + 1 < s.size(); i += 2) {
    double r[3], q1[6], q2[6];
    for (int k = 0; k < 3; ++k) r[k] = 0.3 + unit(engine);
    for (int k = 0; k < 6; ++k) {
      q1[k] = s.q(k)[i];
      q2[k] = s.q(k)[i + 1];
    }
    batch.push_back(r, q1, q2);
    const auto ref = pwcontact::contact_function<double>(r, q1, q2);
    exact_mu2.push_back(ref.mu2);
    exact_lambda.push_back(ref.lambda);
  }
  const std::size_t n = batch.size();
  for (int kind = 0; kind < 6; ++kind) {
    std::vector<double> start(n);
    for (std::size_t k = 0; k < n; ++k) {
      const double l = exact_lambda[k];
      const double choices[6] = {l, l * (1 + 1e-3), 1e-300, 1 - 1e-16, 2, NAN};
      start[k] = choices[kind];
    }
    for (pwcontact::Isa isa : pwcontact::supported_isas()) {
      pwcontact::PairBatchView<double> view = batch.view();
      view.lambda_start = start.data();
      std::vector<double> mu2(n);
      std::vector<pwcontact::Status> status(n);
      pwcontact::BatchOptions options;
      options.isa = isa;
      options.precision = pwcontact::Precision::double_precision;
      const auto report =
          pwcontact::contact_function_batch(view, {mu2.data(), nullptr, status.data()}, options);
      for (std::size_t k = 0; k < n; ++k) {
        ASSERT_TRUE(pwcontact::is_valid(status[k]));
        EXPECT_NEAR(mu2[k], exact_mu2[k], 1e-11 * exact_mu2[k])
            << "start kind " << kind << ", pair " << k;
      }
      if (kind == 0)
        std::printf("[ measured ] %s: %.3f evaluations per pair from the exact lambda\n",
                    pwcontact::isa_name(isa), report.mean_evaluations);
    }
  }
}

}  // namespace
