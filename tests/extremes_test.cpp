// The batch path at the extremes, on every instruction set and in every
// precision. Each test states the expected behaviour in its name:
// - shapes: needles and discs with aspect ratios to 1e4, size ratios to 1e4,
//   lambda near 0 or 1: mu^2 within the conditioned floor of the oracle;
// - scales from 1e-150 to 1e150: the unscaled answer;
// - near-tangent pairs with a known mu^2 = 1 +- eps: classified correctly
//   whenever eps exceeds the error bound;
// - coincident centres, identical ellipsoids, one inside the other: the
//   closed forms;
// - nearly singular Q: an answer within the conditioned floor, or a status;
// - all of these interleaved with ordinary pairs: every ordinary lane as if
//   it were alone.
//
// The oracle is the reference path in 50 digits (or a closed form). The
// accuracy the library documents is the floor of the arithmetic: ~eps times
// the condition of Q (batch.hpp). Here that is measured as
//   |mu2 - mu2*| / mu2*  <=  floor_factor * eps * cond(Q(lambda*))
// with cond(Q(lambda*)) the condition number of Q at the exact maximiser,
// which is what the solves see at convergence.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::Precision;

class Extremes : public ::testing::TestWithParam<Isa> {};
INSTANTIATE_TEST_SUITE_P(EverySupportedIsa, Extremes, ::testing::ValuesIn(isas()), isa_param_name);

// The precisions a batch of double pairs can be solved in.
const Precision precisions[] = {Precision::double_precision, Precision::mixed,
                                Precision::single_precision};

BatchOptions options_for(Isa isa, Precision precision) {
  return with_precision(with_isa(isa), precision);
}

std::string what(const std::string& set, Isa isa, Precision precision) {
  return set + ", " + pwcontact::isa_name(isa) + ", " + pwcontact::precision_name(precision);
}

// ---------------------------------------------------------------------------
// Building extreme pairs

// Two shapes along a random direction, at a distance where mu is uniform in
// [0.5, 2] (scaled from the long double oracle of a first placement at
// distance 1).
Pair<double> around_contact(const pwcontact::QuadraticForm& q1, const pwcontact::QuadraticForm& q2,
                            Engine& engine) {
  const Eigen::Vector3d n = random_rotation(engine).col(0);
  const Pair<double> first = make_pair({n[0], n[1], n[2]}, q1, q2);
  const long double mu = 0.5L + 1.5L * uniform01(engine);
  const ContactResult<long double> placed = long_double_oracle(first);
  // A form that is not positive definite once stored has no contact: kept as placed.
  if (placed.status != Status::ok) return first;
  return scaled_to_mu2(first, placed.mu2, mu * mu);
}

// Spheroids (1, 1, rho) with rho from 1e-4 (discs) to 1e4 (needles), and
// spheres, all against all in random orientations: aspect ratios to 1e4,
// cond(Q) to 1e8.
const Solved& needles_and_discs() {
  static const Solved set = [] {
    Engine engine(101);
    const double shapes[] = {1e-4, 1e-3, 1e-2, 1, 1e2, 1e3, 1e4};
    std::vector<Pair<double>> pairs;
    for (double rho1 : shapes)
      for (double rho2 : shapes)
        for (int k = 0; k < 6; ++k)
          pairs.push_back(around_contact(oriented({1, 1, rho1}, engine),
                                         oriented({1, 1, rho2}, engine), engine));
    return solved(std::move(pairs));
  }();
  return set;
}

// Random shapes (semi-axes in [0.5, 2]) scaled by factors 1e-4 .. 1e4 against
// unscaled ones, both ways round: size ratios to 1e4, lambda* near 0 or 1.
const Solved& size_ratios() {
  static const Solved set = [] {
    Engine engine(102);
    std::vector<Pair<double>> pairs;
    for (double size : {1e-4, 1e-3, 1e-2, 1e2, 1e3, 1e4})
      for (int k = 0; k < 20; ++k) {
        const auto resized = ordinary_shape(engine, size);
        const auto other = ordinary_shape(engine);
        pairs.push_back(around_contact(resized, other, engine));
        pairs.push_back(around_contact(other, resized, engine));
      }
    return solved(std::move(pairs));
  }();
  return set;
}

// Ellipsoids (1, 0.7, t) with t = 1e-6 .. 1e-9 (cond(Q) = 1e12 .. 1e18)
// against random shapes and against each other. For t <= 1e-8 the rounding
// of the rotated Q (~1e-16) is as large as its smallest eigenvalue, so some
// of the stored forms are not positive definite at all.
const Solved& nearly_singular() {
  static const Solved set = [] {
    Engine engine(103);
    std::vector<Pair<double>> pairs;
    for (double t : {1e-6, 1e-7, 1e-8, 1e-9})
      for (int k = 0; k < 20; ++k) {
        const auto thin = oriented({1, 0.7, t}, engine);
        const auto other = ordinary_shape(engine);
        pairs.push_back(around_contact(thin, other, engine));
        pairs.push_back(around_contact(other, thin, engine));
        pairs.push_back(around_contact(thin, oriented({0.3, 1, t}, engine), engine));
      }
    return solved(std::move(pairs));
  }();
  return set;
}

// ---------------------------------------------------------------------------
// The conditioned floor

// |mu2 - mu2*| / mu2* <= floor_factor * eps * cond(Q(lambda*)), with eps that
// of the arithmetic. Measured over the needles and discs, size ratios,
// nearly singular forms, identical ellipsoids and one inside the other, on
// every instruction set: at most 1.15 in double and mixed precision
// (eps 1.1e-16) and 1.35 in single precision (eps 6e-8; float lanes whose
// factorisation shows growth go to the double reference path). 16 leaves a
// factor ~12 and still catches an answer that loses a digit to a worse
// evaluation than the floor allows.
constexpr double floor_factor = 16;

double floor_eps(Precision precision) {
  return precision == Precision::single_precision ? std::numeric_limits<float>::epsilon()
                                                  : std::numeric_limits<double>::epsilon();
}

struct FloorErrors {
  MaxError ratio;           // error / (eps cond)
  std::size_t flagged = 0;  // lanes given a non-ok status
};

// Every lane: valid and within the floor, or (where allowed) an invalid status.
FloorErrors expect_within_conditioned_floor(const Solved& set, const BatchRun<double>& run,
                                            Precision precision, bool status_allowed,
                                            const std::string& what) {
  FloorErrors out;
  for (std::size_t i = 0; i < set.pairs.size(); ++i) {
    if (!pwcontact::is_valid(run.status[i])) {
      ++out.flagged;
      EXPECT_TRUE(status_allowed) << what << ", pair " << i << ": "
                                  << pwcontact::status_name(run.status[i]);
      EXPECT_TRUE(std::isnan(run.mu2[i])) << what << ", pair " << i;
      continue;
    }
    // A valid answer where the stored form is not positive definite would
    // be a silent wrong answer.
    if (set.exact[i].status != Status::ok) {
      ADD_FAILURE() << what << ", pair " << i << ": an answer (mu2 " << run.mu2[i] << ", "
                    << pwcontact::status_name(run.status[i]) << ") for a pair the oracle rejects ("
                    << pwcontact::status_name(set.exact[i].status) << ")";
      continue;
    }
    const double allowed = floor_factor * floor_eps(precision) * set.condition[i];
    const double error = relative_error(run.mu2[i], set.exact[i].mu2);
    out.ratio.add(i, error / (floor_eps(precision) * set.condition[i]));
    EXPECT_LE(error, allowed) << what << ", pair " << i << ": mu2 " << run.mu2[i] << ", exact "
                              << double(set.exact[i].mu2) << ", cond(Q(lambda*)) "
                              << set.condition[i];
  }
  return out;
}

void expect_set_within_conditioned_floor(const Solved& set, Isa isa, bool status_allowed,
                                         const std::string& name) {
  for (Precision precision : precisions) {
    const std::string label = what(name, isa, precision);
    const BatchRun<double> run = run_batch(make_batch(set.pairs), options_for(isa, precision));
    const FloorErrors errors =
        expect_within_conditioned_floor(set, run, precision, status_allowed, label);
    print_measured(label + ", error / (eps cond(Q(lambda*)))", errors.ratio);
    std::printf("[ measured ] %s: %zu of %zu lanes flagged with a status\n", label.c_str(),
                errors.flagged, set.pairs.size());
  }
}

TEST_P(Extremes, NeedlesAndDiscsWithAspectRatiosTo1e4AreWithinTheConditionedFloor) {
  expect_set_within_conditioned_floor(needles_and_discs(), GetParam(), false, "needles and discs");
}

TEST_P(Extremes, SizeRatiosTo1e4AreWithinTheConditionedFloor) {
  expect_set_within_conditioned_floor(size_ratios(), GetParam(), false, "size ratios");
}

TEST_P(Extremes, NearlySingularQGivesAnAnswerWithinTheConditionedFloorOrAStatus) {
  expect_set_within_conditioned_floor(nearly_singular(), GetParam(), true, "nearly singular");
}

// ---------------------------------------------------------------------------
// lambda* near 0 or 1: two spheres of radii 1e-4 .. 1e4, where
// mu = |r| / (a1 + a2) and lambda* = a1 / (a1 + a2) exactly (a_i = sqrt(q_i),
// from the stored q_i).

// Two spheres of radii a1, a2 (each pair of `radii`, both ways round) at a
// random distance between 0.5 and 2 times contact, in a random direction.
std::vector<Pair<double>> sphere_pairs(const std::vector<std::pair<double, double>>& radii,
                                       std::uint64_t seed) {
  Engine engine(seed);
  std::vector<Pair<double>> pairs;
  for (const auto& [a1, a2] : radii) {
    const Eigen::Vector3d n = random_rotation(engine).col(0);
    const double d = (a1 + a2) * (0.5 + 1.5 * uniform01(engine));
    pairs.push_back(
        make_pair({d * n[0], d * n[1], d * n[2]}, pwcontact::sphere(a1), pwcontact::sphere(a2)));
  }
  return pairs;
}

// mu^2: a handful of roundings (reference_test measures <= 2.2 eps for the
// scalar path); 8 eps of the arithmetic. Single precision rounds the
// inputs to float first, a few float eps more. lambda: within 1e-12
// (batch.hpp) in double and mixed precision; in single precision, the
// float floor of lambda, 4e-6 (LaneTolerance<float>).
void expect_spheres_closed_form(const std::vector<Pair<double>>& pairs, Isa isa,
                                const std::string& name) {
  for (Precision precision : precisions) {
    const std::string label = what(name, isa, precision);
    const BatchRun<double> run = run_batch(make_batch(pairs), options_for(isa, precision));
    MaxError mu2_error, lambda_error;
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const Pair<double>& p = pairs[i];
      const long double a1 = std::sqrt((long double)p.q1[0]), a2 = std::sqrt((long double)p.q2[0]);
      const long double r2 = (long double)p.r12[0] * p.r12[0] + (long double)p.r12[1] * p.r12[1] +
                             (long double)p.r12[2] * p.r12[2];
      ASSERT_TRUE(pwcontact::is_valid(run.status[i])) << label << ", pair " << i;
      mu2_error.add(
          i, relative_error(run.mu2[i], r2 / ((a1 + a2) * (a1 + a2))) / floor_eps(precision));
      lambda_error.add(i, absolute_error(run.lambda[i], a1 / (a1 + a2)));
    }
    print_measured(label + ", mu2 relative error in eps", mu2_error);
    print_measured(label + ", lambda absolute error", lambda_error);
    EXPECT_LE(mu2_error.value, 8) << label << ", pair " << mu2_error.index;
    EXPECT_LE(lambda_error.value, precision == Precision::single_precision
                                      ? LaneTolerance<float>::lambda
                                      : LaneTolerance<double>::lambda)
        << label << ", pair " << lambda_error.index;
  }
}

TEST_P(Extremes, SpheresWithLambdaNearZeroOrOneGiveTheClosedForm) {
  // Radii 1e-4 .. 1e4 against each other. Measured: 1.4 eps (double,
  // mixed), 4.0 float eps (single); lambda 1.1e-13 (mixed), 4.7e-7 (single).
  const double radii[] = {1e-4, 1e-2, 1, 1e2, 1e4};
  std::vector<std::pair<double, double>> sizes;
  for (double a1 : radii)
    for (double a2 : radii) sizes.push_back({a1, a2});
  expect_spheres_closed_form(sphere_pairs(sizes, 104), GetParam(), "spheres");
}

TEST_P(Extremes, SizeRatiosBeyondWhatLambdaResolvesGiveTheClosedForm) {
  // Radius ratios 1e-6 .. 1e-140: beyond ~1e-16 (~1e-7 in float) lambda* =
  // a1 / (a1 + a2) rounds to 1, where f(1) = 0. The answer must still be
  // mu^2 to 8 eps: at the largest lambda below 1, f is within one eps of
  // mu^2 (concavity). Both ways round (lambda* near 0 too).
  std::vector<std::pair<double, double>> sizes;
  for (double ratio : {1e-6, 1e-12, 1e-15, 1e-16, 1e-17, 1e-20, 1e-50, 1e-100, 1e-140}) {
    sizes.push_back({1, ratio});
    sizes.push_back({ratio, 1});
  }
  expect_spheres_closed_form(sphere_pairs(sizes, 107), GetParam(),
                             "size ratios beyond lambda's resolution");
}

// ---------------------------------------------------------------------------
// Scales: mu^2 is invariant under r -> k r, Q -> k^2 Q, and lambda with it;
// the contact point scales with k, the gradient with 1 / k.

// Ordinary pairs and needles and discs, scaled by k.
std::vector<Pair<double>> scaled_all(const std::vector<Pair<double>>& pairs, double k) {
  std::vector<Pair<double>> out;
  for (const auto& p : pairs) out.push_back(scaled(p, k));
  return out;
}

std::vector<Pair<double>> pairs_to_scale() {
  auto pairs = make_random_pairs(300, 105);
  const auto& extreme = needles_and_discs().pairs;
  pairs.insert(pairs.end(), extreme.begin(), extreme.begin() + 100);
  return pairs;
}

// Scaling by a power of two is exact, and so is every operation on the
// scaled numbers (no overflow or underflow on the way, if the kernels
// nondimensionalise): the answers must agree bit for bit, the contact point
// and gradient after scaling back.
template <class T>
void expect_power_of_two_scale_changes_no_bit(const std::vector<Pair<double>>& pairs, int exponent,
                                              Isa isa, Precision precision) {
  const double k = std::ldexp(1.0, exponent);
  const auto unscaled = convert_all<T>(pairs), scaled_pairs = convert_all<T>(scaled_all(pairs, k));
  const BatchOptions options = options_for(isa, precision);
  const BatchRun<T> a = run_batch(make_batch(unscaled), options, Requested::everything());
  BatchRun<T> b = run_batch(make_batch(scaled_pairs), options, Requested::everything());
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      b.contact_point[c][i] = std::ldexp(b.contact_point[c][i], -exponent);
      b.gradient[c][i] = std::ldexp(b.gradient[c][i], exponent);
    }
  const std::string what = label<T>(
      "scaled by 2^" + std::to_string(exponent) + ", " + pwcontact::precision_name(precision), isa);
  // Single precision on double pairs whose scale factor float cannot hold
  // (the pairs of 2^+-480 here; the switch lies between 2^149 and 2^151 and
  // between 2^-126 and 2^-128 for these pairs): the float lanes leave every pair, and the double
  // kernels finish them (the reference path what they leave) with the
  // answers of a double-precision call on the unscaled pairs, bit for bit.
  if (std::is_same<T, double>::value && precision == Precision::single_precision &&
      std::abs(exponent) >= 126) {
    const BatchRun<T> in_double =
        run_batch(make_batch(unscaled), options_for(isa, Precision::double_precision),
                  Requested::everything());
    expect_bitwise_equal(in_double, b, what + ", against double precision unscaled");
    EXPECT_EQ(b.report.finished_in_double + b.report.fallbacks, pairs.size())
        << what << ": every lane left by the float kernels";
    EXPECT_EQ(b.report.finished_in_double, in_double.report.status_counts[int(Status::ok)])
        << what << ": the double kernels finish what they finish unscaled";
    return;
  }
  expect_bitwise_equal(a, b, what);
}

TEST_P(Extremes, ScalingByPowersOfTwoTo1e144ChangesNoBitInAnyPrecision) {
  // 2^+-480 ~ 1e+-144: Q's entries ~1e+-289, where an unscaled solve
  // overflows or underflows; 2^+-100: within the range every type solves
  // as given, except float lanes (1e+-38), which need the nondimensionalisation.
  // Mixed precision's float lanes only guess lambda and carry no scale
  // factor: its double lanes give the same answers at every scale.
  const auto pairs = pairs_to_scale();
  for (int exponent : {-480, -100, 100, 480})
    for (Precision precision : precisions)
      expect_power_of_two_scale_changes_no_bit<double>(pairs, exponent, GetParam(), precision);
  for (int exponent : {-50, -20, 20, 50})  // float pairs: 2^+-50 ~ 1e+-15, Q ~ 1e+-30
    expect_power_of_two_scale_changes_no_bit<float>(pairs, exponent, GetParam(),
                                                    Precision::single_precision);
}

TEST_P(Extremes, ScalingWithinTheBandSolvedAsGivenChangesNoBitOfFarOrNearPairs) {
  // Forms with diagonals up to 2^+-100 are solved as given (unless another
  // lane of the register is outside), so a pair there must give the bits it
  // gives at scale 1. The products of a cold start's polynomial steps reach
  // degree 18 in the length scale: the pairs 2^+-60 farther or nearer than
  // the family's (slopes ~2^+-120) scaled by 2^+-49 (diagonals to 2^+-100)
  // took them beyond double's range (was: overflow and underflow, the steps
  // bisected, 1-3 ulp apart in mu^2 and lambda from the unscaled answers).
  for (double apart : {0x1p60, 0x1p-60}) {
    auto pairs = pairs_to_scale();
    for (auto& p : pairs)
      for (double& x : p.r12) x *= apart;
    for (int exponent : {-49, 49})
      expect_power_of_two_scale_changes_no_bit<double>(pairs, exponent, GetParam(),
                                                       Precision::double_precision);
  }
}

// The answers for k r12, k^2 Q against the reference path on the unscaled
// pairs: mu2 and lambda as they are, the contact point divided by k, the
// gradient multiplied by k.
void expect_scaled_answers_match_unscaled_reference(const std::vector<Pair<double>>& pairs,
                                                    double k, Isa isa, Precision precision) {
  const std::string label = what("scaled by " + testing::PrintToString(k), isa, precision);
  const auto references = double_references(pairs);
  BatchRun<double> run = run_batch(make_batch(scaled_all(pairs, k)), options_for(isa, precision),
                                   Requested::everything());
  for (int c = 0; c < 3; ++c)
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      run.contact_point[c][i] /= k;
      run.gradient[c][i] *= k;
    }
  const Tolerances tolerances = tolerances_for(precision);
  const LaneErrors errors = expect_lanes_match_reference(references, run, label, tolerances);
  print_measured(label + ", mu2 relative error", errors.mu2);
  expect_geometry_matches(run, reference_geometries(pairs, references), tolerances.geometry, label);
}

TEST_P(Extremes, ScalesFrom1eMinus150To1e150GiveTheUnscaledAnswerAndGeometry) {
  // Decimal factors round the scaled inputs (~1e-16 relative each), which
  // moves the answers by a few eps on these well-conditioned pairs: they
  // must stay within the tolerances of the unscaled random family.
  // Measured in double and mixed precision: mu2 9.2e-16, geometry 1.5e-13;
  // in single precision mu2 3.3e-7.
  const auto pairs = make_random_pairs(300, 106);
  for (double k : {1e-150, 1e-100, 1e-30, 1e30, 1e100, 1e150})
    for (Precision precision : precisions)
      expect_scaled_answers_match_unscaled_reference(pairs, k, GetParam(), precision);
}

// ---------------------------------------------------------------------------
// Near tangency: pairs built at mu^2 = 1 + offset, |offset| = 1e-3 .. 1e-14
// (test_support: closed forms and the 50-digit oracle), classified by the
// full answer (mu2 < 1, mu2 alone: the cheapest call, with the loosest
// convergence check) and by overlap_batch.

// The smallest |offset| from which the classification must be right: the
// error bound of the answer. The full answer in double and mixed precision
// is at the double floor, a few eps times cond(Q) (measured: 7.0e-16
// relative on the well-conditioned kinds, 3.0e-14 on the elongated ones,
// whose cond(Q) <= 1e4 allows up to ~1e-12), so every offset down to 1e-14
// must be classified right on well-conditioned pairs, and from 1e-11 on
// elongated ones (measured: right from 1e-13). In single precision the
// answer is a float one (measured 1.5e-6 relative): from 1e-5 (measured:
// right from 1e-6, elongated from 1e-5). overlap_batch promises agreement beyond 1e-9 in every
// precision (batch.hpp); in double and mixed precision it is held to the
// full answer's bounds. It leaves what its certificates cannot decide to the
// double reference path and reaches the double floor in single precision
// too (measured: right from 1e-14, elongated from 1e-13).
double required_offset(TangentKind kind, Precision precision, bool overlap_only) {
  if (overlap_only && precision == Precision::single_precision) return 1e-9;
  if (precision == Precision::single_precision) return 1e-5;
  return well_conditioned(kind) ? 1e-14 : 1e-11;
}

// For each kind: the smallest |offset| at which every pair with that offset
// or more was classified right, and how many pairs beyond the required
// offset were not.
struct TangentTally {
  double correct_from[4] = {0, 0, 0, 0};
  std::size_t wrong_beyond_bound = 0;
  std::size_t first_wrong = 0;
};

TangentTally tally(const std::vector<NearTangent>& set, const std::vector<bool>& says_overlap,
                   Precision precision, bool overlap_only) {
  TangentTally t;
  for (std::size_t i = 0; i < set.size(); ++i) {
    const bool right = says_overlap[i] == (set[i].mu2 < 1);
    const int kind = int(set[i].kind);
    const double offset = std::fabs(set[i].offset);
    if (!right && offset >= required_offset(set[i].kind, precision, overlap_only) &&
        t.wrong_beyond_bound++ == 0)
      t.first_wrong = i;
    if (!right) t.correct_from[kind] = std::max(t.correct_from[kind], offset * 10);
  }
  return t;
}

void expect_classified(const std::vector<NearTangent>& set, const std::vector<bool>& says_overlap,
                       Precision precision, bool overlap_only, const std::string& label) {
  const TangentTally t = tally(set, says_overlap, precision, overlap_only);
  for (TangentKind kind : {TangentKind::spheres, TangentKind::coaxial_spheroids,
                           TangentKind::general, TangentKind::elongated})
    std::printf("[ measured ] %s, %s: right for every |offset| >= %.0e\n", label.c_str(),
                tangent_kind_name(kind), std::max(t.correct_from[int(kind)], 1e-14));
  EXPECT_EQ(t.wrong_beyond_bound, 0u) << label << ": first pair " << t.first_wrong << " ("
                                      << tangent_kind_name(set[t.first_wrong].kind) << ", offset "
                                      << set[t.first_wrong].offset << ")";
}

TEST_P(Extremes, NearTangentPairsAreClassifiedRightWheneverTheOffsetExceedsTheErrorBound) {
  const std::vector<NearTangent> set = near_tangent_pairs();
  std::vector<Pair<double>> pairs;
  for (const NearTangent& t : set) pairs.push_back(t.pair);
  const PairBatch<double> batch = make_batch(pairs);
  for (Precision precision : precisions) {
    const std::string label = what("near tangent", GetParam(), precision);
    const BatchRun<double> full = run_batch(batch, options_for(GetParam(), precision),
                                            Requested{false, true});  // mu2, status
    const OverlapRun overlap = run_overlap(batch, options_for(GetParam(), precision));
    std::vector<bool> full_says(set.size()), overlap_says(set.size());
    MaxError well_conditioned_error, elongated_error;
    for (std::size_t i = 0; i < set.size(); ++i) {
      ASSERT_TRUE(pwcontact::is_valid(full.status[i])) << label << ", pair " << i;
      ASSERT_TRUE(pwcontact::is_valid(overlap.status[i])) << label << ", pair " << i;
      full_says[i] = full.mu2[i] < 1;
      overlap_says[i] = overlap.overlap[i] == 1;
      (well_conditioned(set[i].kind) ? well_conditioned_error : elongated_error)
          .add(i, relative_error(full.mu2[i], set[i].mu2));
    }
    print_measured(label + ", well conditioned, mu2 relative error", well_conditioned_error);
    print_measured(label + ", elongated, mu2 relative error", elongated_error);
    expect_classified(set, full_says, precision, false, label + ", mu2 < 1");
    expect_classified(set, overlap_says, precision, true, label + ", overlap_batch");
  }
}

// ---------------------------------------------------------------------------
// Degenerate configurations with closed forms.

// Ordinary pairs and the needles and discs.
std::vector<Pair<double>> shapes_to_degenerate() {
  auto pairs = make_random_pairs(100, 107);
  const auto& extreme = needles_and_discs().pairs;
  pairs.insert(pairs.end(), extreme.begin(), extreme.end());
  return pairs;
}

TEST_P(Extremes, CoincidentCentresGiveMu2ZeroZeroGeometryAndOverlap) {
  // f vanishes identically: mu^2 = 0 exactly, any lambda in [0, 1] is a
  // maximiser, s = Q^-1 r = 0 so the contact point and the gradient are 0,
  // and the normal is documented as 0 (reference.hpp). mu = 0 < cutoff.
  auto pairs = shapes_to_degenerate();
  for (auto& p : pairs) p.r12 = {0, 0, 0};
  const PairBatch<double> batch = make_batch(pairs);
  for (Precision precision : precisions) {
    const std::string label = what("coincident centres", GetParam(), precision);
    const BatchRun<double> run =
        run_batch(batch, options_for(GetParam(), precision), Requested::everything());
    const OverlapRun overlap = run_overlap(batch, options_for(GetParam(), precision));
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const std::string lane = label + ", pair " + std::to_string(i);
      EXPECT_TRUE(pwcontact::is_valid(run.status[i])) << lane;
      EXPECT_EQ(run.mu2[i], 0.0) << lane;
      EXPECT_TRUE(run.lambda[i] >= 0 && run.lambda[i] <= 1) << lane << ": lambda " << run.lambda[i];
      const Vector3L zero = Vector3L::Zero();
      EXPECT_EQ(lane_vector(run.contact_point, i), zero) << lane;
      EXPECT_EQ(lane_vector(run.normal, i), zero) << lane;
      EXPECT_EQ(lane_vector(run.gradient, i), zero) << lane;
      EXPECT_EQ(overlap.overlap[i], 1) << lane;
    }
  }
}

TEST_P(Extremes, IdenticalEllipsoidsGiveLambdaOneHalfAndAQuarterOfTheRadialForm) {
  // Q1 = Q2 = Q: f = lambda (1 - lambda) r^T Q^-1 r, so lambda* = 1/2 and
  // mu^2 = r^T Q^-1 r / 4, computed here in long double (Eigen). mu^2 is
  // held to the conditioned floor (cond(Q) up to 1e8 for the needles and
  // discs); lambda to the accuracy documented for it. Measured: at most
  // 1.2 eps cond(Q); lambda exactly 1/2 in every lane.
  auto pairs = shapes_to_degenerate();
  for (auto& p : pairs) p.q2 = p.q1;
  for (Precision precision : precisions) {
    const std::string label = what("identical ellipsoids", GetParam(), precision);
    const BatchRun<double> run = run_batch(make_batch(pairs), options_for(GetParam(), precision));
    MaxError ratio, lambda_error;
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const Pair<double>& p = pairs[i];
      const Eigen::Matrix<long double, 3, 3> q = unpack(p.q1).cast<long double>();
      const Vector3L r(p.r12[0], p.r12[1], p.r12[2]);
      const long double exact = r.dot(q.ldlt().solve(r)) / 4;
      const double condition = condition_at(p, 0.5L);
      ASSERT_TRUE(pwcontact::is_valid(run.status[i])) << label << ", pair " << i;
      const double error = relative_error(run.mu2[i], exact);
      ratio.add(i, error / (floor_eps(precision) * condition));
      lambda_error.add(i, absolute_error(run.lambda[i], 0.5L));
      EXPECT_LE(error, floor_factor * floor_eps(precision) * condition) << label << ", pair " << i;
    }
    print_measured(label + ", error / (eps cond(Q))", ratio);
    print_measured(label + ", lambda absolute error", lambda_error);
    EXPECT_LE(lambda_error.value, tolerances_for(precision).lambda)
        << label << ", pair " << lambda_error.index;
  }
}

TEST_P(Extremes, OneEllipsoidInsideTheOtherOverlapsAndMatchesTheOracle) {
  // A small ellipsoid (semi-axes <= 1) whose centre is within 2 of the
  // centre of a large one (semi-axes >= 5): it lies wholly inside, mu^2 < 1
  // (measured: 0.10 at most), both ways round. Within the conditioned floor of
  // the 50-digit oracle; overlap_batch says 1.
  Engine engine(108);
  std::vector<Pair<double>> pairs;
  for (int k = 0; k < 100; ++k) {
    const auto large = oriented({5 + 5 * uniform01(engine), 5 + 5 * uniform01(engine), 5}, engine);
    const auto small =
        oriented({0.1 + 0.9 * uniform01(engine), 0.1 + 0.9 * uniform01(engine), 1}, engine);
    const Eigen::Vector3d r = 2 * uniform01(engine) * random_rotation(engine).col(0);
    pairs.push_back(make_pair({r[0], r[1], r[2]}, large, small));
    pairs.push_back(make_pair({-r[0], -r[1], -r[2]}, small, large));
  }
  const Solved set = solved(pairs);
  MaxError largest;
  for (std::size_t i = 0; i < pairs.size(); ++i) largest.add(i, double(set.exact[i].mu2));
  print_measured("one inside the other, largest exact mu2", largest);
  const PairBatch<double> batch = make_batch(pairs);
  for (Precision precision : precisions) {
    const std::string label = what("one inside the other", GetParam(), precision);
    const BatchRun<double> run = run_batch(batch, options_for(GetParam(), precision));
    const OverlapRun overlap = run_overlap(batch, options_for(GetParam(), precision));
    const FloorErrors errors = expect_within_conditioned_floor(set, run, precision, false, label);
    print_measured(label + ", error / (eps cond(Q(lambda*)))", errors.ratio);
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      EXPECT_LT(set.exact[i].mu2, 1) << label << ", pair " << i << " is not inside";
      EXPECT_EQ(overlap.overlap[i], 1) << label << ", pair " << i;
    }
  }
}

// ---------------------------------------------------------------------------
// Neighbours: every extreme above, and invalid pairs, interleaved with
// ordinary pairs in one batch. Lanes are independent (batch.hpp: results do
// not depend on a pair's position), so every ordinary lane must get exactly
// the bits it gets alone, in a batch of one, with the same options.

std::vector<Pair<double>> every_extreme() {
  std::vector<Pair<double>> out;
  for (const Solved* set : {&needles_and_discs(), &size_ratios(), &nearly_singular()})
    out.insert(out.end(), set->pairs.begin(), set->pairs.end());
  for (const NearTangent& t : near_tangent_pairs()) out.push_back(t.pair);
  for (const auto& p : make_random_pairs(40, 109)) {
    out.push_back(scaled(p, 1e150));
    out.push_back(scaled(p, 1e-150));
    Pair<double> coincident = p, identical = p, invalid = p;
    coincident.r12 = {0, 0, 0};
    identical.q2 = identical.q1;
    invalid.q1[0] = std::numeric_limits<double>::quiet_NaN();
    out.insert(out.end(), {coincident, identical, invalid});
  }
  return out;
}

TEST_P(Extremes, OrdinaryLanesAmongExtremesGetTheirAnswersAlone) {
  const std::vector<Pair<double>> extremes = every_extreme();
  const std::vector<Pair<double>> ordinary = make_random_pairs(150, 110);
  // 1 to 3 extremes between ordinary pairs, so that both share registers in
  // every arrangement.
  std::vector<Pair<double>> mixed;
  std::vector<std::size_t> ordinary_lanes;
  std::size_t next = 0;
  for (std::size_t i = 0; i < ordinary.size(); ++i) {
    ordinary_lanes.push_back(mixed.size());
    mixed.push_back(ordinary[i]);
    for (std::size_t k = 0; k <= i % 3 && next < extremes.size(); ++k)
      mixed.push_back(extremes[next++]);
  }
  mixed.insert(mixed.end(), extremes.begin() + std::ptrdiff_t(next), extremes.end());
  const PairBatch<double> batch = make_batch(mixed);
  for (Precision precision : precisions)
    for (int iterations : {0, 2}) {
      const BatchOptions options = with_precision(with_isa(GetParam(), iterations), precision);
      const BatchRun<double> run = run_batch(batch, options, Requested::everything());
      BatchRun<double> alone;
      for (const Pair<double>& p : ordinary) {
        const BatchRun<double> one =
            run_batch(make_batch(std::vector<Pair<double>>{p}), options, Requested::everything());
        append_lanes(alone, one);
      }
      expect_bitwise_equal(
          select_lanes(run, ordinary_lanes), alone,
          what("ordinary lanes among extremes vs alone, iterations " + std::to_string(iterations),
               GetParam(), precision));
    }
}

}  // namespace
}  // namespace pwtest
