// Every status code the library can produce, on both paths: bad pairs get
// their own code and NaN results, never a valid-looking answer, and they do
// not disturb good pairs around them.
#include <cmath>
#include <functional>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "fixtures/families.hpp"
#include "pwcontact/pwcontact.hpp"
#include "test_support.hpp"

namespace pwtest {
namespace {

struct BadCase {
  std::string name;
  Pair<double> pair;
  Status expected;
};

// Input component c of 15 in the CLI order: r12 x y z, q1[0..5], q2[0..5].
double& component(Pair<double>& p, int c) {
  return c < 3 ? p.r12[c] : c < 9 ? p.q1[c - 3] : p.q2[c - 9];
}

const Pair<double> good_pair =
    make_pair({1.5, -0.5, 0.25}, pwcontact::spheroid(0.5, 2, {1, 2, 3}),
              pwcontact::quadratic_form_from_quaternion({1, 0.7, 1.3}, {0.9, 0.1, -0.3, 0.2}));

// Quadratic forms that are not positive definite. All entries are small
// integers, exact in float too, and the singular ones are exactly singular.
const std::pair<const char*, pwcontact::QuadraticForm> not_positive_definite[] = {
    {"zero", {0, 0, 0, 0, 0, 0}},
    {"negative_definite", {-1, 0, 0, -2, 0, -3}},
    {"indefinite_diagonal", {1, 0, 0, -1, 0, 1}},
    // Positive diagonal, eigenvalues 3, -1, 1: a diagonal test would miss it.
    {"indefinite_positive_diagonal", {1, 2, 0, 1, 0, 1}},
    // A flat disc: one semi-axis zero.
    {"flat_disc", {1, 0, 0, 1, 0, 0}},
    // Rank 2 off the axes: (1,1,0)(1,1,0)^T + (0,1,1)(0,1,1)^T.
    {"singular_rotated", {1, 1, 0, 2, 1, 1}},
    // A needle: rank 1.
    {"needle", {0, 0, 0, 0, 0, 4}},
};

std::vector<BadCase> bad_cases() {
  std::vector<BadCase> out;
  const std::pair<const char*, double> non_finite[] = {
      {"nan", std::numeric_limits<double>::quiet_NaN()},
      {"+inf", std::numeric_limits<double>::infinity()},
      {"-inf", -std::numeric_limits<double>::infinity()}};
  for (int c = 0; c < 15; ++c)
    for (const auto& [name, value] : non_finite) {
      BadCase bad{std::string(name) + " in component " + std::to_string(c), good_pair,
                  Status::non_finite_input};
      component(bad.pair, c) = value;
      out.push_back(bad);
    }
  for (const auto& [name, q] : not_positive_definite) {
    out.push_back({std::string("q1 ") + name, good_pair, Status::q1_not_positive_definite});
    out.back().pair.q1 = q;
    out.push_back({std::string("q2 ") + name, good_pair, Status::q2_not_positive_definite});
    out.back().pair.q2 = q;
  }
  return out;
}

template <class T>
void expect_rejected(const BadCase& bad, T mu2, T lambda, Status status, const std::string& where) {
  EXPECT_EQ(status, bad.expected) << where << ": " << bad.name << " gave "
                                  << pwcontact::status_name(status);
  EXPECT_FALSE(pwcontact::is_valid(status)) << where << ": " << bad.name;
  // NaN compares false both ways: it can never be read as "apart" or "overlapping".
  EXPECT_TRUE(std::isnan(mu2)) << where << ": " << bad.name << " gave mu2 " << mu2;
  EXPECT_TRUE(std::isnan(lambda)) << where << ": " << bad.name << " gave lambda " << lambda;
}

template <class T>
void expect_scalar_path_rejects_every_bad_case() {
  for (const BadCase& bad : bad_cases()) {
    const ContactResult<T> result = reference(convert<T>(bad.pair));
    expect_rejected(bad, result.mu2, result.lambda, result.status,
                    single_precision<T> ? "scalar float" : "scalar double");
  }
}

TEST(ScalarPath, EveryBadInputGetsItsStatusAndNaNInDouble) {
  expect_scalar_path_rejects_every_bad_case<double>();
}

TEST(ScalarPath, EveryBadInputGetsItsStatusAndNaNInFloat) {
  expect_scalar_path_rejects_every_bad_case<float>();
}

TEST(ScalarPath, IterationLimitGivesNotConvergedAndNaN) {
  // A single evaluation cannot settle an ordinary pair: the radial guess is
  // exact only for spheres.
  pwcontact::ReferenceOptions options;
  options.max_iterations = 1;
  const ContactResult<double> result = reference(good_pair, options);
  EXPECT_EQ(result.status, Status::not_converged);
  EXPECT_TRUE(std::isnan(result.mu2));
  EXPECT_TRUE(std::isnan(result.lambda));
}

// ---------------------------------------------------------------------------

class BadInputBatch : public ::testing::TestWithParam<Isa> {};
INSTANTIATE_TEST_SUITE_P(EverySupportedIsa, BadInputBatch, ::testing::ValuesIn(isas()),
                         isa_param_name);

// Good pairs with the bad cases slipped in between at irregular gaps (1, 2, 3
// good pairs), so that bad pairs land in every lane position and in the tail.
struct Interleaved {
  std::vector<Pair<double>> pairs, good;
  std::vector<std::size_t> good_index, bad_index;  // positions in `pairs`
};

Interleaved interleave(const std::vector<BadCase>& bad) {
  Interleaved out;
  const auto good = make_random_pairs(3 * bad.size() + 5, 41);
  std::size_t next_good = 0;
  for (std::size_t b = 0; b <= bad.size(); ++b) {
    for (std::size_t k = 0; k < 1 + b % 3; ++k) {
      out.good_index.push_back(out.pairs.size());
      out.pairs.push_back(good[next_good]);
      out.good.push_back(good[next_good++]);
    }
    if (b == bad.size()) break;
    out.bad_index.push_back(out.pairs.size());
    out.pairs.push_back(bad[b].pair);
  }
  return out;
}

template <class T>
void expect_bad_lanes_rejected_and_good_lanes_unaffected(Isa isa) {
  const std::vector<BadCase> bad = bad_cases();
  const Interleaved mix = interleave(bad);
  const BatchRun<T> run = run_batch(make_batch(convert_all<T>(mix.pairs)), with_isa(isa));
  EXPECT_EQ(run.report.invalid, bad.size());

  for (std::size_t b = 0; b < bad.size(); ++b) {
    const std::size_t i = mix.bad_index[b];
    expect_rejected(bad[b], run.mu2[i], run.lambda[i], run.status[i],
                    label<T>("lane " + std::to_string(i), isa));
  }

  // Good lanes: as accurate as anywhere, and bit for bit what a batch of the
  // good pairs alone gives (lanes are independent).
  const auto good = convert_all<T>(mix.good);
  const BatchRun<T> good_lanes = select_lanes(run, mix.good_index);
  expect_lanes_match_reference(double_references(good), good_lanes, label<T>("good lanes", isa));
  const BatchRun<T> alone = run_batch(make_batch(good), with_isa(isa));
  expect_bitwise_equal(good_lanes, alone,
                       label<T>("good lanes among bad ones vs the good pairs alone", isa));
}

TEST_P(BadInputBatch, BadLanesAreRejectedAndGoodLanesUnaffectedInDouble) {
  expect_bad_lanes_rejected_and_good_lanes_unaffected<double>(GetParam());
}

TEST_P(BadInputBatch, BadLanesAreRejectedAndGoodLanesUnaffectedInFloat) {
  expect_bad_lanes_rejected_and_good_lanes_unaffected<float>(GetParam());
}

// A batch of nothing but bad pairs: whole SIMD groups of them, nothing to lean on.
template <class T>
void expect_all_bad_batch_rejected(Isa isa) {
  const std::vector<BadCase> bad = bad_cases();
  std::vector<Pair<double>> pairs;
  for (const BadCase& b : bad) pairs.push_back(b.pair);
  const BatchRun<T> run = run_batch(make_batch(convert_all<T>(pairs)), with_isa(isa));
  EXPECT_EQ(run.report.invalid, bad.size());
  for (std::size_t i = 0; i < bad.size(); ++i)
    expect_rejected(bad[i], run.mu2[i], run.lambda[i], run.status[i],
                    label<T>("lane " + std::to_string(i), isa));
}

TEST_P(BadInputBatch, BatchOfOnlyBadPairsIsRejectedInDouble) {
  expect_all_bad_batch_rejected<double>(GetParam());
}

TEST_P(BadInputBatch, BatchOfOnlyBadPairsIsRejectedInFloat) {
  expect_all_bad_batch_rejected<float>(GetParam());
}

template <class T>
void expect_coincident_centres_give_zero(Isa isa) {
  auto pairs = make_random_pairs(2 * pwcontact::simd_lanes(isa, single_precision<T>) + 3, 42);
  for (std::size_t i = 0; i < pairs.size(); i += 2) pairs[i].r12 = {0, 0, 0};
  const BatchRun<T> run = run_batch(make_batch(convert_all<T>(pairs)), with_isa(isa));
  for (std::size_t i = 0; i < pairs.size(); i += 2) {
    const std::string where = label<T>("lane " + std::to_string(i), isa);
    // (The portable target answers every pair on the reference path.)
    EXPECT_EQ(run.status[i], isa == Isa::fallback ? Status::ok_fallback : Status::ok) << where;
    EXPECT_EQ(run.mu2[i], T(0)) << where;
    EXPECT_GE(run.lambda[i], T(0)) << where;
    EXPECT_LE(run.lambda[i], T(1)) << where;
  }
}

TEST_P(BadInputBatch, CoincidentCentresGiveMu2ZeroAndStatusOk) {
  expect_coincident_centres_give_zero<double>(GetParam());
  expect_coincident_centres_give_zero<float>(GetParam());
}

// ---------------------------------------------------------------------------

TEST(StatusText, NamesAndDescriptionsAreNonEmptyAndDistinct) {
  std::set<std::string> names, descriptions;
  for (int s = 0; s < pwcontact::status_count; ++s) {
    const std::string name = pwcontact::status_name(Status(s));
    const std::string description = pwcontact::status_description(Status(s));
    EXPECT_FALSE(name.empty()) << "code " << s;
    EXPECT_FALSE(description.empty()) << "code " << s;
    EXPECT_TRUE(names.insert(name).second) << "code " << s << " repeats the name " << name;
    EXPECT_TRUE(descriptions.insert(description).second)
        << "code " << s << " repeats its description";
  }
}

TEST(StatusText, OnlyOkAndOkFallbackAreValid) {
  for (int s = 0; s < pwcontact::status_count; ++s)
    EXPECT_EQ(pwcontact::is_valid(Status(s)),
              Status(s) == Status::ok || Status(s) == Status::ok_fallback)
        << pwcontact::status_name(Status(s));
}

// Thread counts: 0 (all) to 1024, as the command line and Python take them,
// in every call that takes one; beyond, std::invalid_argument naming the
// call (10^5 threads crashed the batched moving-scene query and the screen;
// the moving scene's batched calls took a negative count for "all").
TEST(ThreadCounts, BeyondZeroTo1024AreRefusedByEveryCallNamingIt) {
  using pwcontact::Box;
  using pwcontact::ParticleStore;
  ParticleStore store;
  store.add({0, 0, 0}, pwcontact::sphere(1));
  store.add({1.5, 0, 0}, pwcontact::sphere(1));
  const Box box = Box::periodic_box(10, 10, 10);
  auto refused = [](const std::function<void()>& call, const char* who) {
    try {
      call();
      ADD_FAILURE() << who << ": accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(who) + ": threads must be in 0 .. 1024"),
                std::string::npos)
          << e.what();
    }
  };
  for (int threads : {-1, 1025, 100000}) {
    pwcontact::ScreenOptions screen_options;
    screen_options.threads = threads;
    pwcontact::ScreenedPairs pairs;
    refused([&] { pwcontact::screen_pairs(store, box, screen_options, pairs); }, "screen_pairs");
    pwcontact::PairBatch<double> batch;
    const double r[3] = {1.5, 0, 0};
    const auto q = pwcontact::sphere(1);
    batch.push_back(r, q.data(), q.data());
    std::vector<double> mu2(1);
    std::vector<Status> status(1);
    BatchOptions batch_options;
    batch_options.threads = threads;
    refused(
        [&] {
          pwcontact::contact_function_batch(batch.view(), {mu2.data(), nullptr, status.data()},
                                            batch_options);
        },
        "BatchOptions::threads");
    pwcontact::MovingScene scene(store, box);
    const pwcontact::MovingScene::Particle trial = scene.trial({5, 5, 5}, q);
    const std::int64_t exclude = pwcontact::MovingScene::none;
    std::int64_t hit = 0;
    refused([&] { scene.overlaps(&trial, &exclude, 1, &hit, threads); }, "MovingScene::overlaps");
    const std::uint32_t index = 0;
    refused([&] { scene.move_many(&index, &trial, 1, threads); }, "MovingScene::move_many");
    EXPECT_EQ(scene.particles().centre(0)[0], 0) << "the scene unchanged";
    pwcontact::SkinOptions skin_options;
    skin_options.threads = threads;
    pwcontact::SkinNeighborList list(skin_options);
    refused([&] { list.update(store, box, pairs); }, "SkinNeighborList");
    pwcontact::HardParticleMCOptions mc_options;
    mc_options.threads = threads;
    refused([&] { pwcontact::HardParticleMC::dilute_spheroids(8, 1, 2, mc_options); },
            "HardParticleMC");
  }
}

// Iteration counts: 0 (automatic) or a fixed count 1 .. max_fixed_iterations,
// as the command line and Python take them, in both batch calls and for
// both input types; beyond, std::invalid_argument naming the range (a count
// of 2^31 - 1 was taken, and every lane of the call then ran that many).
TEST(IterationCounts, BeyondTheFixedRangeAreRefusedAndItsEndsTaken) {
  pwcontact::PairBatch<double> batch;
  const double r[3] = {1.5, 0, 0};
  const auto q = pwcontact::sphere(1);
  batch.push_back(r, q.data(), q.data());
  const pwcontact::PairBatch<float> single = pwcontact::to_float(batch);
  std::vector<double> mu2(1);
  std::vector<float> mu2_single(1);
  std::vector<std::uint8_t> overlap(1);
  std::vector<Status> status(1);
  auto calls = [&](int iterations) {
    BatchOptions options;
    options.iterations = iterations;
    return std::vector<std::function<void()>>{
        [&, options] {
          pwcontact::contact_function_batch(batch.view(), {mu2.data(), nullptr, status.data()},
                                            options);
        },
        [&, options] {
          pwcontact::contact_function_batch(single.view(),
                                            {mu2_single.data(), nullptr, status.data()}, options);
        },
        [&, options] {
          pwcontact::overlap_batch(batch.view(), {overlap.data(), status.data()}, options);
        },
        [&, options] {
          pwcontact::overlap_batch(single.view(), {overlap.data(), status.data()}, options);
        }};
  };
  for (int iterations : {-1, pwcontact::max_fixed_iterations + 1, 2147483647})
    for (const auto& call : calls(iterations)) {
      try {
        call();
        ADD_FAILURE() << iterations << ": accepted";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("BatchOptions::iterations must be 0 (automatic) or a "
                                             "count 1 .. 1000, got " +
                                             std::to_string(iterations)),
                  std::string::npos)
            << e.what();
      }
    }
  // Both ends answer: two spheres 1.5 apart, mu^2 = 1.5^2 / 2^2.
  for (int iterations : {0, 1, pwcontact::max_fixed_iterations}) {
    mu2[0] = mu2_single[0] = 0;
    overlap[0] = 0;
    for (const auto& call : calls(iterations)) {
      status[0] = Status::not_converged;
      EXPECT_NO_THROW(call()) << iterations;
      EXPECT_TRUE(pwcontact::is_valid(status[0])) << iterations;
    }
    EXPECT_NEAR(mu2[0], 0.5625, 1e-15) << iterations;
    EXPECT_NEAR(mu2_single[0], 0.5625f, 1e-6f) << iterations;
    EXPECT_EQ(overlap[0], 1) << iterations;
  }
}

}  // namespace
}  // namespace pwtest
