// The peer library's published reference family (419,904 spheroid pairs,
// aspect ratios up to 500) through the batch path at default settings:
// accuracy against the long double oracle, and the peer's own checks; and
// Accuracy::high, which beats the double floor there.
#include <cmath>

#include "test_support.hpp"

namespace pwtest {
namespace {

// The family as a batch and pair by pair, built once per process.
struct Family {
  PairBatch<double> batch;
  std::vector<Pair<double>> pairs;
};

const Family& the_family() {
  static const Family built = [] {
    PairBatch<double> batch = pwcontact::pw85_family();
    std::vector<Pair<double>> pairs = pairs_of(batch);
    return Family{std::move(batch), std::move(pairs)};
  }();
  return built;
}

struct SolvedFamily {
  const std::vector<Pair<double>>& pairs;
  BatchRun<double> run;
};

// Solved at default settings once per process; the tests below only read it.
const SolvedFamily& solved_family() {
  static const SolvedFamily solved = [] {
    SolvedFamily out{the_family().pairs, run_batch(the_family().batch)};
    std::printf("[ measured ] pw85 family at default settings: %zu pairs, %zu fallbacks, isa %s\n",
                out.run.report.pairs, out.run.report.fallbacks,
                pwcontact::isa_name(out.run.report.isa));
    return out;
  }();
  return solved;
}

TEST(Pw85Family, HasTheDocumentedSize) {
  EXPECT_EQ(the_family().pairs.size(), pwcontact::pw85_family_size);
  EXPECT_EQ(pwcontact::pw85_family_size, 419904u);
}

TEST(Pw85Family, EveryAnswerIsValidWithLambdaInTheUnitInterval) {
  const SolvedFamily& family = solved_family();
  EXPECT_EQ(family.run.report.invalid, 0u);
  for (std::size_t i = 0; i < family.pairs.size(); ++i) {
    ASSERT_TRUE(pwcontact::is_valid(family.run.status[i]))
        << "pair " << i << ": " << pwcontact::status_name(family.run.status[i]);
    ASSERT_FALSE(std::isnan(family.run.mu2[i])) << "pair " << i;
    ASSERT_GE(family.run.lambda[i], 0.0) << "pair " << i;
    ASSERT_LE(family.run.lambda[i], 1.0) << "pair " << i;
  }
}

// The long double oracle of every pair, computed once per process. Its own
// error on this family is ~4e-15 (against 50 digits).
const std::vector<ContactResult<long double>>& family_oracle() {
  static const auto oracle = long_double_oracles(the_family().pairs);
  return oracle;
}

// The relative error of every mu2 against the oracle.
MaxError error_against_oracle(const std::vector<double>& mu2) {
  const auto& oracle = family_oracle();
  MaxError error;
  std::size_t oracle_failures = 0;
  for (std::size_t i = 0; i < oracle.size(); ++i) {
    oracle_failures += oracle[i].status != Status::ok;
    error.add(i, relative_error(mu2[i], oracle[i].mu2));
  }
  EXPECT_EQ(oracle_failures, 0u) << "the oracle failed on some pairs";
  return error;
}

// Evaluating f in plain double at the exact maximiser already costs up to
// 1.1e-11 on this family (cond(Q) up to 2.5e5): the double floor.
constexpr double double_floor = 2e-11;

TEST(Pw85Family, Mu2WithinTwoTimesTenToTheMinusElevenOfTheLongDoubleOracle) {
  // 2e-11 is the promised accuracy at default settings. The error stays at
  // the floor, well above 1e-13 (measured 1.0e-11): that is what
  // Accuracy::high is there to beat.
  const MaxError error = error_against_oracle(solved_family().run.mu2);
  print_measured("pw85 batch default vs long double, mu2 relative error", error);
  EXPECT_LE(error.value, double_floor) << "pair " << error.index;
  EXPECT_GE(error.value, 1e-12) << "the plain double floor";
}

class Pw85HighAccuracy : public ::testing::TestWithParam<Isa> {};

// Accuracy::high refines the last evaluation with an error-free residual,
// which removes the conditioning floor: measured 5.3e-15 on avx2 and avx512
// in double and mixed precision, which is the oracle's own floor (~4e-15).
// 1e-13 is the promised accuracy (batch.hpp).
TEST_P(Pw85HighAccuracy, Mu2WithinTenToTheMinusThirteenOfTheLongDoubleOracleInDoubleAndMixed) {
  for (pwcontact::Precision precision :
       {pwcontact::Precision::double_precision, pwcontact::Precision::mixed}) {
    const std::string what = std::string("pw85, Accuracy::high, ") +
                             pwcontact::isa_name(GetParam()) + ", " +
                             pwcontact::precision_name(precision);
    const BatchOptions options =
        with_precision(with_isa(GetParam()), precision, pwcontact::Formulation::automatic,
                       pwcontact::Accuracy::high);
    const BatchRun<double> run = run_batch(the_family().batch, options, Requested::mu2_only());
    EXPECT_EQ(run.report.invalid, 0u) << what;
    const MaxError error = error_against_oracle(run.mu2);
    print_measured(what + ", mu2 relative error", error);
    EXPECT_LE(error.value, 1e-13) << what << ", pair " << error.index;
  }
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, Pw85HighAccuracy, ::testing::ValuesIn(isas()), isa_param_name);

// The peer's checks, in long double at the returned lambda, with
// s = Q(lambda)^-1 r (eq. 9, 10):
//   mu1^2 = (1 - lambda)^2 s^T Q1 s,  mu2^2 = lambda^2 s^T Q2 s   (eq. 13)
//   f'(lambda) = mu1^2 - mu2^2,  f''(lambda) = -2 (Q1 s)^T Q^-1 (Q2 s).
// Computed independently of the library (Eigen's LDL^T).
struct PeerQuantities {
  long double mu1_squared, mu2_squared, f_prime, f_second;
};

PeerQuantities peer_quantities(const Pair<double>& p, double lambda) {
  using Matrix = Eigen::Matrix<long double, 3, 3>;
  using Vector = Eigen::Matrix<long double, 3, 1>;
  const Matrix q1 = unpack(p.q1).cast<long double>(), q2 = unpack(p.q2).cast<long double>();
  const Vector r(p.r12[0], p.r12[1], p.r12[2]);
  const long double l = lambda;
  const Eigen::LDLT<Matrix> q(((1 - l) * q1 + l * q2).eval());
  const Vector s = q.solve(r);
  const Vector a = q1 * s, b = q2 * s;
  PeerQuantities out;
  out.mu1_squared = (1 - l) * (1 - l) * s.dot(a);
  out.mu2_squared = l * l * s.dot(b);
  out.f_prime = out.mu1_squared - out.mu2_squared;
  out.f_second = -2 * a.dot(q.solve(b));
  return out;
}

std::vector<PeerQuantities> peer_quantities_of_family() {
  const SolvedFamily& family = solved_family();
  std::vector<PeerQuantities> out(family.pairs.size());
  const std::ptrdiff_t n = std::ptrdiff_t(out.size());
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::ptrdiff_t i = 0; i < n; ++i)
    out[i] = peer_quantities(family.pairs[i], family.run.lambda[i]);
  return out;
}

TEST(Pw85Family, Mu2EqualsMu1SquaredAndMu2SquaredAtTheReturnedLambda) {
  // The peer's tolerance. Both squares equal mu^2 only at the maximiser, so
  // this checks lambda (to first order) as well as mu2.
  const double tolerance = 1e-10;
  const SolvedFamily& family = solved_family();
  const auto peer = peer_quantities_of_family();
  MaxError error1, error2;
  for (std::size_t i = 0; i < peer.size(); ++i) {
    error1.add(i, relative_error(peer[i].mu1_squared, family.run.mu2[i]));
    error2.add(i, relative_error(peer[i].mu2_squared, family.run.mu2[i]));
  }
  print_measured("pw85 batch default, |mu1^2 - mu^2| / mu^2", error1);
  print_measured("pw85 batch default, |mu2^2 - mu^2| / mu^2", error2);
  EXPECT_LE(error1.value, tolerance) << "pair " << error1.index;
  EXPECT_LE(error2.value, tolerance) << "pair " << error2.index;
}

TEST(Pw85Family, ReturnedLambdaIsStationary) {
  // The peer's third check: |f'(lambda)| <= 1e-6 |f''(lambda)|, i.e. one
  // Newton step would move lambda by at most 1e-6.
  const double tolerance = 1e-6;
  const auto peer = peer_quantities_of_family();
  MaxError error;
  for (std::size_t i = 0; i < peer.size(); ++i)
    error.add(i, double(std::fabs(peer[i].f_prime) / std::fabs(peer[i].f_second)));
  print_measured("pw85 batch default, |f'| / |f''|", error);
  EXPECT_LE(error.value, tolerance) << "pair " << error.index;
}

// The family rounded to float and solved as float pairs (float lanes, and
// double lanes for what they cannot finish), against the long double oracle
// on the float pairs widened exactly (rounding the inputs alone moves mu2 by
// up to 3e-3: the float answer is judged on the pairs it was given). Measured
// 2.2e-6 with avx512 and up to 3.6e-6 over instruction sets and
// formulations (sse2, log_odds); 1e-5 is README's bound for this row.
TEST(Pw85Family, FloatPairsWithinTenToTheMinusFiveOfTheOracleOnTheRoundedInputs) {
  const std::vector<Pair<double>>& pairs = the_family().pairs;
  std::vector<Pair<float>> rounded;
  std::vector<Pair<double>> widened;
  rounded.reserve(pairs.size());
  widened.reserve(pairs.size());
  for (const Pair<double>& p : pairs) {
    rounded.push_back(pwtest::convert<float>(p));
    widened.push_back(pwtest::convert<double>(rounded.back()));
  }
  const BatchRun<float> run = run_batch(make_batch(rounded));
  const auto oracle = long_double_oracles(widened);
  MaxError error;
  std::size_t oracle_failures = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    ASSERT_TRUE(pwcontact::is_valid(run.status[i])) << "pair " << i;
    if (oracle[i].status != Status::ok) {
      ++oracle_failures;  // (a rounded form the oracle finds not positive definite)
      continue;
    }
    error.add(i, relative_error(run.mu2[i], oracle[i].mu2));
  }
  print_measured("pw85 family as float pairs vs long double on them, mu2 relative error", error);
  EXPECT_LE(error.value, 1e-5) << "pair " << error.index;
  EXPECT_EQ(oracle_failures, 0u);
}

TEST(Pw85Family, SinglePrecisionFinishesInDoubleLanesWhatFloatLanesCannot) {
  // Float lanes leave the lanes whose factorisation shows element growth
  // beyond float's bound (measured: 41 % of this family); the double kernels
  // finish those (not the scalar reference path), with the double kernels'
  // answer on the same pair (double pairs here: the same bits as a double
  // call). Overlap answers likewise, and classified as the double ones.
  const SolvedFamily& family = solved_family();
  const BatchOptions single =
      with_precision(BatchOptions{}, pwcontact::Precision::single_precision);
  const BatchRun<double> run = run_batch(the_family().batch, single);
  const std::size_t n = family.pairs.size();
  std::printf(
      "[ measured ] pw85 family in single precision: %zu finished in double lanes, %zu "
      "fallbacks\n",
      run.report.finished_in_double, run.report.fallbacks);
  // (The portable target's lanes are the reference path's: no counts there.)
  const bool simd = run.report.isa != Isa::fallback;
  if (simd) {
    EXPECT_GE(run.report.finished_in_double, n / 4);
    EXPECT_LE(run.report.fallbacks, n / 100);
  }
  EXPECT_EQ(run.report.invalid, 0u);
  std::size_t as_double = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_TRUE(pwcontact::is_valid(run.status[i])) << "pair " << i;
    as_double += run.mu2[i] == family.run.mu2[i];
  }
  EXPECT_GE(as_double, run.report.finished_in_double) << "lanes with the double call's mu2";

  const OverlapRun overlap = run_overlap(the_family().batch, single);
  const OverlapRun overlap_double = run_overlap(the_family().batch);
  std::printf(
      "[ measured ] pw85 family, overlap in single precision: %zu finished in double "
      "lanes, %zu fallbacks\n",
      overlap.report.finished_in_double, overlap.report.fallbacks);
  if (simd) {
    EXPECT_LE(overlap.report.fallbacks, n / 100);
  }
  std::size_t differing = 0;
  for (std::size_t i = 0; i < n; ++i) {
    // (The float lanes decide on the pairs rounded to float: answers may
    // differ only where that rounding moves mu^2 across 1, within ~3e-3.)
    if (std::abs(family.run.mu2[i] - 1) <= 3e-3) continue;
    differing += overlap.overlap[i] != overlap_double.overlap[i];
  }
  EXPECT_EQ(differing, 0u) << "overlap answers away from tangency";
}

}  // namespace
}  // namespace pwtest
