// The scalar reference path against closed-form answers, against its own
// symmetries, and against itself instantiated in higher precision.
#include <algorithm>
#include <boost/multiprecision/cpp_bin_float.hpp>
#include <cmath>
#include <limits>

#include "test_support.hpp"

namespace pwtest {
namespace {

// ---------------------------------------------------------------------------
// Closed forms, in float, double and long double alike.
//
// When r12 is along a principal direction shared by both ellipsoids, with
// semi-axes rho1 and rho2 in that direction, f(lambda) reduces to the sphere
// case: mu = |r| / (rho1 + rho2) and lambda = rho1 / (rho1 + rho2).

// Q as given to the solver: the diagonal a_k^2 rounded to T. The expected
// values are computed from these rounded inputs, so that only the solver's
// own rounding is measured.
template <class T>
Pair<T> diagonal_pair(const std::array<long double, 3>& r, const std::array<long double, 3>& a1,
                      const std::array<long double, 3>& a2) {
  Pair<T> p;
  for (int k = 0; k < 3; ++k) p.r12[k] = T(r[k]);
  p.q1 = {T(a1[0] * a1[0]), 0, 0, T(a1[1] * a1[1]), 0, T(a1[2] * a1[2])};
  p.q2 = {T(a2[0] * a2[0]), 0, 0, T(a2[1] * a2[1]), 0, T(a2[2] * a2[2])};
  return p;
}

// The semi-axis of a diagonal Q along diagonal entry k, as the solver sees it.
template <class T>
long double semi_axis(const std::array<T, 6>& q, int k) {
  const int diagonal[3] = {0, 3, 5};
  return std::sqrt((long double)q[diagonal[k]]);
}

template <class T>
long double length(const std::array<T, 3>& r) {
  return std::sqrt((long double)r[0] * r[0] + (long double)r[1] * r[1] + (long double)r[2] * r[2]);
}

// Collects the largest error of the closed-form cases of one test, in units
// of the type's eps, and prints it.
template <class T>
class ClosedForm : public ::testing::Test {
 protected:
  void expect_radial_contact(const Pair<T>& p, long double rho1, long double rho2) {
    // The solve is a handful of LDL^T solves of an exactly diagonal
    // Q(lambda) (each entry one rounding) and a Newton iteration that
    // converges to full precision: a few roundings, measured at most 2.2 eps
    // in float, double and long double alike. 8 eps leaves a factor 4.
    const long double eps = std::numeric_limits<T>::epsilon();
    const long double mu = length(p.r12) / (rho1 + rho2);
    const ContactResult<T> result = reference(p);
    ASSERT_EQ(result.status, Status::ok);
    const double mu2_error = relative_error(result.mu2, mu * mu) / eps;
    const double lambda_error = relative_error(result.lambda, rho1 / (rho1 + rho2)) / eps;
    EXPECT_LE(mu2_error, 8) << "mu2 " << result.mu2 << ", expected " << mu * mu;
    EXPECT_LE(lambda_error, 8) << "lambda " << result.lambda << ", expected "
                               << rho1 / (rho1 + rho2);
    worst_.add(worst_.count, std::max(mu2_error, lambda_error));
  }

  void TearDown() override {
    print_measured(std::string("closed form, relative error in eps of ") +
                       ::testing::internal::GetTypeName<T>(),
                   worst_);
  }

 private:
  MaxError worst_;
};
using Precisions = ::testing::Types<float, double, long double>;
TYPED_TEST_SUITE(ClosedForm, Precisions);

const long double radii[] = {0.01L, 0.7L, 1, 3, 250};
const long double distances[] = {1e-3L, 0.9L, 2.5L, 40};

TYPED_TEST(ClosedForm, SpheresGiveDistanceOverSumOfRadii) {
  const std::array<long double, 3> directions[] = {
      {1, 0, 0}, {0, 0, -1}, {1.0L / 3, 2.0L / 3, -2.0L / 3}};
  for (long double a1 : radii)
    for (long double a2 : radii)
      for (long double d : distances)
        for (const auto& n : directions) {
          const auto p =
              diagonal_pair<TypeParam>({d * n[0], d * n[1], d * n[2]}, {a1, a1, a1}, {a2, a2, a2});
          SCOPED_TRACE(testing::Message() << "a1 " << a1 << " a2 " << a2 << " d " << d);
          this->expect_radial_contact(p, semi_axis(p.q1, 0), semi_axis(p.q2, 0));
        }
}

// Spheroids: equatorial radius a, polar radius c, axis along coordinate `axis`.
std::array<long double, 3> spheroid_axes(long double a, long double c, int axis) {
  std::array<long double, 3> out = {a, a, a};
  out[axis] = c;
  return out;
}

const std::array<long double, 2> spheroid_shapes[] = {
    {1, 1}, {0.5L, 2}, {2, 0.3L}, {0.02L, 9}, {7, 0.05L}};

TYPED_TEST(ClosedForm, CoaxialSpheroidsAlongTheAxisGiveDistanceOverSumOfPolarRadii) {
  for (int axis = 0; axis < 3; ++axis)
    for (const auto& s1 : spheroid_shapes)
      for (const auto& s2 : spheroid_shapes)
        for (long double d : distances) {
          std::array<long double, 3> r = {0, 0, 0};
          r[axis] = d;
          const auto p = diagonal_pair<TypeParam>(r, spheroid_axes(s1[0], s1[1], axis),
                                                  spheroid_axes(s2[0], s2[1], axis));
          SCOPED_TRACE(testing::Message()
                       << "axis " << axis << " c1 " << s1[1] << " c2 " << s2[1] << " d " << d);
          this->expect_radial_contact(p, semi_axis(p.q1, axis), semi_axis(p.q2, axis));
        }
}

TYPED_TEST(ClosedForm, CoaxialSpheroidsAcrossTheAxisGiveDistanceOverSumOfEquatorialRadii) {
  // Any direction in the equatorial plane is a common principal direction.
  const long double angles[] = {0, 0.4L, 1.3L};
  for (int axis = 0; axis < 3; ++axis)
    for (const auto& s1 : spheroid_shapes)
      for (const auto& s2 : spheroid_shapes)
        for (long double angle : angles) {
          std::array<long double, 3> r = {0, 0, 0};
          r[(axis + 1) % 3] = 1.7L * std::cos(angle);
          r[(axis + 2) % 3] = 1.7L * std::sin(angle);
          const auto p = diagonal_pair<TypeParam>(r, spheroid_axes(s1[0], s1[1], axis),
                                                  spheroid_axes(s2[0], s2[1], axis));
          SCOPED_TRACE(testing::Message() << "axis " << axis << " a1 " << s1[0] << " a2 " << s2[0]
                                          << " angle " << angle);
          // a^2 rounded to T is the same on both equatorial diagonal entries.
          this->expect_radial_contact(p, semi_axis(p.q1, (axis + 1) % 3),
                                      semi_axis(p.q2, (axis + 1) % 3));
        }
}

TYPED_TEST(ClosedForm, EllipsoidsWithCommonPrincipalAxesAlongAnAxis) {
  const std::array<long double, 3> shapes[] = {{0.5L, 1.2L, 3}, {2, 0.3L, 0.9L}, {0.05L, 4, 1}};
  for (int axis = 0; axis < 3; ++axis)
    for (const auto& a1 : shapes)
      for (const auto& a2 : shapes)
        for (long double d : distances) {
          std::array<long double, 3> r = {0, 0, 0};
          r[axis] = -d;
          const auto p = diagonal_pair<TypeParam>(r, a1, a2);
          SCOPED_TRACE(testing::Message() << "axis " << axis << " d " << d);
          this->expect_radial_contact(p, semi_axis(p.q1, axis), semi_axis(p.q2, axis));
        }
}

// ---------------------------------------------------------------------------
// Symmetries, on random pairs in double.

// The two solves see different (mirrored or rounded) inputs and each carries
// its own rounding, measured at most 5e-16 against the quad-precision data on
// this family: 4e-15 (18 eps) bounds the difference of two such answers
// plus the effect of one rounding of the inputs on a well-conditioned Q
// (measured differences: 1.2e-15 at most).
constexpr double symmetry_tolerance = 4e-15;
// lambda is pinned down less sharply than mu2 (mu2 is stationary in lambda,
// so a stopping test on mu2 alone could accept a lambda off by ~sqrt(eps));
// measured differences stay below 3e-16 on this family, and 1e-12 still
// catches a lambda that is not converged.
constexpr double lambda_symmetry_tolerance = 1e-12;

// Solves every pair as given and transformed: mu2 must agree, and lambda of
// the transformed pair, mapped back by `lambda_back`, must agree too.
template <class Transform, class LambdaBack>
void expect_invariant(const std::string& what, const std::vector<Pair<double>>& pairs,
                      Transform transform, LambdaBack lambda_back) {
  MaxError mu2_error, lambda_error;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const ContactResult<double> a = reference(pairs[i]), b = reference(transform(pairs[i]));
    ASSERT_EQ(b.status, Status::ok) << what << ", pair " << i;
    mu2_error.add(i, relative_error(b.mu2, a.mu2));
    lambda_error.add(i, absolute_error(lambda_back(b.lambda), a.lambda));
  }
  print_measured(what + ", mu2 relative difference", mu2_error);
  print_measured(what + ", lambda absolute difference", lambda_error);
  EXPECT_LE(mu2_error.value, symmetry_tolerance) << what << ", pair " << mu2_error.index;
  EXPECT_LE(lambda_error.value, lambda_symmetry_tolerance)
      << what << ", pair " << lambda_error.index;
}

double same(double lambda) { return lambda; }

TEST(Symmetry, SwappingTheEllipsoidsKeepsMu2AndMirrorsLambda) {
  expect_invariant("swap", make_random_pairs(2000, 11), swapped,
                   [](double lambda) { return 1 - lambda; });
}

TEST(Symmetry, RotatingThePairKeepsMu2AndLambda) {
  std::mt19937_64 engine(12);
  const auto rotate = [&engine](const Pair<double>& p) {
    return rotated(p, random_rotation(engine));
  };
  expect_invariant("rotation", make_random_pairs(2000, 13), rotate, same);
}

TEST(Symmetry, ScalingByAPowerOfTwoChangesNothing) {
  // Q -> k^2 Q, r -> k r is exact for k = 2^m, and the solver nondimensionalises
  // by a power of two: it sees the same numbers, so the answers agree bit for bit,
  // out to scales where an unscaled solve would overflow or underflow.
  const auto pairs = make_random_pairs(200, 14);
  for (int m : {-300, -60, -1, 1, 45, 300}) {
    const double k = std::ldexp(1.0, m);
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const ContactResult<double> a = reference(pairs[i]), b = reference(scaled(pairs[i], k));
      ASSERT_EQ(b.status, Status::ok) << "k = 2^" << m << ", pair " << i;
      EXPECT_EQ(b.mu2, a.mu2) << "k = 2^" << m << ", pair " << i;
      EXPECT_EQ(b.lambda, a.lambda) << "k = 2^" << m << ", pair " << i;
    }
  }
}

TEST(Symmetry, ScalingByAnyFactorKeepsMu2AndLambda) {
  // Out to scales where Q's entries (~k^2) would overflow or underflow in
  // intermediate products of an unscaled solve.
  const auto pairs = make_random_pairs(200, 15);
  for (double k : {1e-150, 1e-100, 3e-7, 3.3, 1e13, 1e100, 1e150}) {
    const auto scale = [k](const Pair<double>& p) { return scaled(p, k); };
    expect_invariant("scaling by " + testing::PrintToString(k), pairs, scale, same);
  }
}

TEST(CoincidentCentres, Mu2IsZeroAndStatusOk) {
  auto pairs = make_random_pairs(50, 16);
  pairs.push_back(make_pair({0, 0, 0}, pwcontact::sphere(1), pwcontact::sphere(3)));
  for (auto& p : pairs) {
    p.r12 = {0, 0, 0};
    const ContactResult<double> result = reference(p);
    EXPECT_EQ(result.status, Status::ok);
    EXPECT_EQ(result.mu2, 0.0);
    EXPECT_GE(result.lambda, 0.0);
    EXPECT_LE(result.lambda, 1.0);
  }
}

// ---------------------------------------------------------------------------
// Against the same template in higher precision.

TEST(HigherPrecision, DoubleAgreesWithLongDoubleOnRandomPairs) {
  // Random pairs are well conditioned (axes within a factor 4, so cond(Q) <= 16):
  // a full-precision double solve is within a few eps; the oracle carries
  // 11 more bits. 2e-15 (9 eps) bounds the double rounding with margin.
  const double tolerance = 2e-15;
  const auto pairs = make_random_pairs(5000, 17);
  const auto oracle = long_double_oracles(pairs);
  MaxError mu2_error, lambda_error;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const ContactResult<double> result = reference(pairs[i]);
    ASSERT_EQ(oracle[i].status, Status::ok) << "pair " << i;
    ASSERT_EQ(result.status, Status::ok) << "pair " << i;
    mu2_error.add(i, relative_error(result.mu2, oracle[i].mu2));
    lambda_error.add(i, absolute_error(result.lambda, oracle[i].lambda));
  }
  print_measured("random, double vs long double, mu2 relative error", mu2_error);
  print_measured("random, double vs long double, lambda absolute error", lambda_error);
  EXPECT_LE(mu2_error.value, tolerance) << "pair " << mu2_error.index;
  EXPECT_LE(lambda_error.value, lambda_symmetry_tolerance) << "pair " << lambda_error.index;
}

// 50 decimal digits with expression templates: the reference template has to
// compile and converge for a type that is neither built in nor hardware.
using Float50 = boost::multiprecision::cpp_bin_float_50;

ContactResult<Float50> multiprecision_oracle(const Pair<double>& p) {
  return reference(convert<Float50>(p));
}

template <class T>
void expect_agrees_with_multiprecision(double tolerance) {
  const auto pairs = make_random_pairs(20, 18);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const ContactResult<Float50> exact = multiprecision_oracle(pairs[i]);
    const ContactResult<T> result = reference(convert<T>(pairs[i]));
    ASSERT_EQ(exact.status, Status::ok) << "pair " << i;
    ASSERT_EQ(result.status, Status::ok) << "pair " << i;
    const Float50 error = abs(Float50(result.mu2) - exact.mu2) / exact.mu2;
    EXPECT_LE(error.convert_to<double>(), tolerance) << "pair " << i;
  }
}

TEST(HigherPrecision, LongDoubleAgreesWithFiftyDigits) {
  // This is what makes long double a trustworthy oracle for double: its own
  // error is a few of its eps (1.1e-19); 2e-18 allows ~18 of them.
  expect_agrees_with_multiprecision<long double>(2e-18);
}

TEST(HigherPrecision, DoubleAgreesWithFiftyDigits) {
  // Same reasoning as against long double: 9 eps of double.
  expect_agrees_with_multiprecision<double>(2e-15);
}

// ---------------------------------------------------------------------------

TEST(Iterations, CountIsPositiveAndFarBelowTheSafetyNet) {
  // Newton converges quadratically from the radial guess on random pairs;
  // even pure bisection would resolve [0, 1] to double precision in ~53
  // steps. More than that means the safeguard keeps rejecting Newton steps.
  const auto pairs = make_random_pairs(2000, 19);
  int largest = 0;
  long total = 0;
  for (const auto& p : pairs) {
    const ContactResult<double> result = reference(p);
    EXPECT_GT(result.iterations, 0);
    largest = std::max(largest, result.iterations);
    total += result.iterations;
  }
  std::printf("[ measured ] iterations on random pairs: mean %.2f, max %d\n",
              double(total) / double(pairs.size()), largest);
  EXPECT_LE(largest, 53);
}

}  // namespace
}  // namespace pwtest
