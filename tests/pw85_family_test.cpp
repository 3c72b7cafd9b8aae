// The peer library's published reference family (419,904 spheroid pairs,
// aspect ratios up to 500) through the batch path at default settings:
// accuracy against the long double oracle, and the peer's own checks.
#include <cmath>

#include "test_support.hpp"

namespace pwtest {
namespace {

struct SolvedFamily {
  std::vector<Pair<double>> pairs;
  BatchRun<double> run;
};

// Built once per process; the tests below only read it.
const SolvedFamily& solved_family() {
  static const SolvedFamily family = [] {
    const PairBatch<double> batch = pwcontact::pw85_family();
    SolvedFamily out{pairs_of(batch), run_batch(batch)};
    std::printf("[ measured ] pw85 family at default settings: %zu pairs, %zu fallbacks, isa %s\n",
                out.run.report.pairs, out.run.report.fallbacks,
                pwcontact::isa_name(out.run.report.isa));
    return out;
  }();
  return family;
}

TEST(Pw85Family, HasTheDocumentedSize) {
  EXPECT_EQ(solved_family().pairs.size(), pwcontact::pw85_family_size);
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

TEST(Pw85Family, Mu2WithinTwoTimesTenToTheMinusElevenOfTheLongDoubleOracle) {
  // Evaluating f in double at the exact maximiser already costs up to 1.1e-11
  // on this family (cond(Q) up to 2.5e5); 2e-11 is the promised accuracy.
  // The oracle's own error here is ~4e-15, far below.
  const double tolerance = 2e-11;
  const SolvedFamily& family = solved_family();
  const auto oracle = long_double_oracles(family.pairs);
  MaxError error;
  for (std::size_t i = 0; i < family.pairs.size(); ++i) {
    ASSERT_EQ(oracle[i].status, Status::ok) << "pair " << i;
    error.add(i, relative_error(family.run.mu2[i], oracle[i].mu2));
  }
  print_measured("pw85 batch default vs long double, mu2 relative error", error);
  EXPECT_LE(error.value, tolerance) << "pair " << error.index;
}

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

}  // namespace
}  // namespace pwtest
