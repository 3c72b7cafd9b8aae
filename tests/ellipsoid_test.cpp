// Building Q (theory eq. 2, packed as eq. 3) from semi-axes and an
// orientation: Q must have the squared semi-axes as eigenvalues, with the
// rotated body axes as eigenvectors.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::QuadraticForm;

const std::array<double, 3> semi_axes = {0.3, 1.7, 4.0};

// Q is R diag(a^2) R^T evaluated with a few roundings per entry, |Q| <= 16:
// 1e-14 relative to the largest eigenvalue (~45 eps) bounds it.
constexpr double form_tolerance = 1e-14;

// Q v = a^2 v for the given unit vector, to form_tolerance of the largest a^2.
void expect_eigenpair(const QuadraticForm& q, const Eigen::Vector3d& v, double a,
                      double largest_a) {
  const Eigen::Vector3d residual = unpack(q) * v - a * a * v;
  EXPECT_LE(residual.norm(), form_tolerance * largest_a * largest_a)
      << "semi-axis " << a << " along (" << v.transpose() << ")";
}

// The eigenvalues of Q, found by Eigen independently of how Q was built.
void expect_eigenvalues_are_squared_semi_axes(const QuadraticForm& q, std::array<double, 3> axes) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(unpack(q));
  std::sort(axes.begin(), axes.end());
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(solver.eigenvalues()[i], axes[i] * axes[i], form_tolerance * axes[2] * axes[2]);
}

std::array<double, 9> row_major(const Eigen::Matrix3d& r) {
  std::array<double, 9> out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) out[3 * i + j] = r(i, j);
  return out;
}

TEST(QuadraticForm, SemiAxesLieAlongTheColumnsOfTheRotation) {
  std::mt19937_64 engine(51);
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::Matrix3d r = random_rotation(engine);
    const QuadraticForm q = pwcontact::quadratic_form(semi_axes, row_major(r));
    for (int i = 0; i < 3; ++i) expect_eigenpair(q, r.col(i), semi_axes[i], semi_axes[2]);
    expect_eigenvalues_are_squared_semi_axes(q, semi_axes);
  }
}

TEST(QuadraticForm, NonOrthogonalMatrixThrows) {
  std::mt19937_64 engine(52);
  const Eigen::Matrix3d r = random_rotation(engine);
  Eigen::Matrix3d sheared = r;
  sheared(0, 1) += 1e-6;  // far beyond the documented 1e-9
  EXPECT_THROW(pwcontact::quadratic_form(semi_axes, row_major(sheared)), std::invalid_argument);
  EXPECT_THROW(pwcontact::quadratic_form(semi_axes, row_major(1.01 * r)), std::invalid_argument);
}

TEST(QuadraticForm, MatrixWithNaNEntryThrows) {
  // A NaN entry makes R^T R - I NaN: it is not orthogonal to any tolerance.
  std::mt19937_64 engine(52);
  Eigen::Matrix3d nan_entry = random_rotation(engine);
  nan_entry(2, 2) = std::nan("");
  EXPECT_THROW(pwcontact::quadratic_form(semi_axes, row_major(nan_entry)), std::invalid_argument);
}

TEST(QuadraticForm, RotationRoundedToDoubleIsAccepted) {
  // A rotation computed in floating point is orthogonal only to a few eps.
  std::mt19937_64 engine(53);
  Eigen::Matrix3d r = random_rotation(engine);
  r(1, 2) += 1e-13;
  EXPECT_NO_THROW(pwcontact::quadratic_form(semi_axes, row_major(r)));
}

// ---------------------------------------------------------------------------

// v rotated by the unit quaternion (w, x, y, z), from the Hamilton product
// q v q*, written out (independent of any matrix conversion).
Eigen::Vector3d rotate(const std::array<double, 4>& q, const Eigen::Vector3d& v) {
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double w = q[0] / norm;
  const Eigen::Vector3d u(q[1] / norm, q[2] / norm, q[3] / norm);
  return v + 2 * w * u.cross(v) + 2 * u.cross(u.cross(v));
}

TEST(QuadraticFormFromQuaternion, SemiAxesLieAlongTheRotatedBodyAxes) {
  const std::array<double, 4> quaternions[] = {
      {1, 0, 0, 0}, {0.5, 0.5, 0.5, 0.5}, {0.9, 0.1, -0.3, 0.2}, {-0.2, 0.7, 0.1, -0.6}};
  for (const auto& quaternion : quaternions) {
    const QuadraticForm q = pwcontact::quadratic_form_from_quaternion(semi_axes, quaternion);
    for (int i = 0; i < 3; ++i)
      expect_eigenpair(q, rotate(quaternion, Eigen::Vector3d::Unit(i)), semi_axes[i], semi_axes[2]);
    expect_eigenvalues_are_squared_semi_axes(q, semi_axes);
  }
}

TEST(QuadraticFormFromQuaternion, ScalarPartComesFirst) {
  // (cos 45deg, 0, 0, sin 45deg) turns x into y: the long axis ends up along y.
  const double h = std::sqrt(0.5);
  const QuadraticForm q = pwcontact::quadratic_form_from_quaternion({3, 1, 1}, {h, 0, 0, h});
  EXPECT_NEAR(q[0], 1, form_tolerance * 9);
  EXPECT_NEAR(q[3], 9, form_tolerance * 9);
  EXPECT_NEAR(q[5], 1, form_tolerance * 9);
}

TEST(QuadraticFormFromQuaternion, NonUnitQuaternionIsNormalised) {
  const std::array<double, 4> unit = {0.9, 0.1, -0.3, 0.2};
  const QuadraticForm reference_form = pwcontact::quadratic_form_from_quaternion(semi_axes, unit);
  for (double k : {1e-3, 3.7, 1e5}) {
    const QuadraticForm q = pwcontact::quadratic_form_from_quaternion(
        semi_axes, {k * unit[0], k * unit[1], k * unit[2], k * unit[3]});
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(q[i], reference_form[i], form_tolerance * 16) << "scale " << k << ", entry " << i;
  }
}

TEST(QuadraticFormFromQuaternion, AnyFiniteNonZeroNormGivesTheRotationOfTheUnitQuaternion) {
  // Was: norms whose squares underflow or overflow (1e-161, 1e154) refused
  // or wrong. Scaled by a power of two the unit quaternion gives the same
  // numbers; scaled by a decimal factor, the same to a few eps (the factor's
  // rounding of the components).
  const std::array<double, 4> unit = {0.5, -0.5, 0.5, 0.5};
  const auto expected = pwcontact::quadratic_form_from_quaternion(semi_axes, unit);
  for (double k : {0x1p-1000, 0x1p1000, 1e-161, 1e154, 5e-324 * 1e10, 1e300}) {
    const std::array<double, 4> q = {unit[0] * k, unit[1] * k, unit[2] * k, unit[3] * k};
    const auto got = pwcontact::quadratic_form_from_quaternion(semi_axes, q);
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(got[i], expected[i], 1e-14 * 4) << "scale " << k;
    if (k == 0x1p-1000 || k == 0x1p1000) {
      EXPECT_EQ(got, expected) << "scale " << k;
    }
  }
}

TEST(QuadraticFormFromQuaternion, ZeroOrNonFiniteQuaternionThrows) {
  EXPECT_THROW(pwcontact::quadratic_form_from_quaternion(semi_axes, {0, 0, 0, 0}),
               std::invalid_argument);
  EXPECT_THROW(pwcontact::quadratic_form_from_quaternion(semi_axes, {std::nan(""), 0, 0, 1}),
               std::invalid_argument);
  EXPECT_THROW(pwcontact::quadratic_form_from_quaternion(semi_axes, {HUGE_VAL, 0, 0, 1}),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------

// Two unit vectors completing n to an orthonormal basis.
std::pair<Eigen::Vector3d, Eigen::Vector3d> perpendiculars(const Eigen::Vector3d& n) {
  const Eigen::Vector3d t1 = n.unitOrthogonal();
  return {t1, n.cross(t1)};
}

TEST(Spheroid, PolarRadiusAlongTheAxisEquatorialRadiusAcross) {
  const std::array<double, 3> axes[] = {{0, 0, 1}, {1, 2, 3}, {-0.3, 0.1, 0.05}};
  const double shapes[][2] = {{0.5, 2}, {3, 0.2}, {1, 1}};
  for (const auto& axis : axes)
    for (const auto& shape : shapes) {
      const double a = shape[0], c = shape[1];
      const QuadraticForm q = pwcontact::spheroid(a, c, axis);
      const Eigen::Vector3d n = Eigen::Vector3d(axis[0], axis[1], axis[2]).normalized();
      const auto [t1, t2] = perpendiculars(n);
      const double largest = std::max(a, c);
      expect_eigenpair(q, n, c, largest);
      expect_eigenpair(q, t1, a, largest);
      expect_eigenpair(q, t2, a, largest);
    }
}

TEST(Spheroid, ZeroAxisThrows) {
  EXPECT_THROW(pwcontact::spheroid(1, 2, {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(pwcontact::spheroid(1, 2, {NAN, 0, 1}), std::invalid_argument);
  EXPECT_THROW(pwcontact::spheroid(1, 2, {INFINITY, 0, 1}), std::invalid_argument);
}

// An axis of any finite, non-zero length gives the spheroid of the unit
// axis, bit for bit where its sum of squares under- or overflows too (was:
// "zero or non-finite axis" for 1e-300 or 1e200).
TEST(Spheroid, AnAxisOfAnyFiniteLengthIsTheUnitAxis) {
  const std::array<double, 3> unit = {0.6, 0, 0.8};
  const QuadraticForm expected = pwcontact::spheroid(0.5, 2, unit);
  for (double scale : {0x1p-1000, 0x1p-600, 0x1p-30, 1.0, 0x1p30, 0x1p600, 0x1p1000}) {
    const QuadraticForm q =
        pwcontact::spheroid(0.5, 2, {unit[0] * scale, unit[1] * scale, unit[2] * scale});
    for (int k = 0; k < 6; ++k)
      EXPECT_EQ(q[k], expected[k]) << "scale " << scale << ", entry " << k;
  }
  const QuadraticForm along_x = pwcontact::spheroid(0.5, 2, {1e-300, 0, 0});
  EXPECT_EQ(along_x[0], 4.0);
  EXPECT_EQ(along_x[3], 0.25);
}

TEST(Sphere, IsSquaredRadiusTimesIdentity) {
  for (double a : {1e-3, 0.5, 7.0}) {
    const QuadraticForm q = pwcontact::sphere(a);
    const QuadraticForm expected = {a * a, 0, 0, a * a, 0, a * a};
    EXPECT_EQ(q, expected) << "radius " << a;
  }
}

// ---------------------------------------------------------------------------
// Degenerate semi-axes are documented to pass through here and be rejected by
// the solvers, so that bad data is reported per pair rather than thrown.

void expect_solver_rejects_as_q1(const QuadraticForm& q) {
  const ContactResult<double> result = reference(make_pair({1, 0, 0}, q, pwcontact::sphere(1)));
  EXPECT_EQ(result.status, Status::q1_not_positive_definite)
      << "got " << pwcontact::status_name(result.status) << ", mu2 " << result.mu2;
}

const std::array<double, 9> identity = {1, 0, 0, 0, 1, 0, 0, 0, 1};

TEST(DegenerateSemiAxes, ZeroSemiAxisGivesAFormTheSolversReject) {
  QuadraticForm q;
  ASSERT_NO_THROW(q = pwcontact::quadratic_form({1, 2, 0}, identity));
  expect_solver_rejects_as_q1(q);
}

TEST(DegenerateSemiAxes, NegativeSemiAxisGivesAFormTheSolversReject) {
  QuadraticForm q;
  ASSERT_NO_THROW(q = pwcontact::quadratic_form({1, -2, 1}, identity));
  expect_solver_rejects_as_q1(q);
}

}  // namespace
}  // namespace pwtest
