#include "pwcontact/ellipsoid.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "number_text.hpp"

namespace pwcontact {
namespace {

QuadraticForm pack(const Eigen::Matrix3d& q) {
  return {q(0, 0), q(0, 1), q(0, 2), q(1, 1), q(1, 2), q(2, 2)};
}

// Q = R diag(a^2) R^T (eq. 2: the columns of R are the principal directions).
// A negative semi-axis enters with its sign (a |a|), so that it yields a
// negative eigenvalue, which the solvers report, instead of passing for its
// absolute value.
// Written out for the six entries the form keeps (a third of a
// million-particle store's build went to the full 3 x 3 product), in the
// order of the sums that Eigen's product r * diag(a2) * r^T used before,
// so that every form keeps its bits: left to right, except the last
// diagonal entry, summed from the right (checked equal on 10^6 random
// rotations and semi-axes).
QuadraticForm from_rotation(const std::array<double, 3>& semi_axes, const Eigen::Matrix3d& r) {
  const double a2[3] = {semi_axes[0] * std::abs(semi_axes[0]),
                        semi_axes[1] * std::abs(semi_axes[1]),
                        semi_axes[2] * std::abs(semi_axes[2])};
  auto term = [&](int i, int j, int k) { return (r(i, k) * a2[k]) * r(j, k); };
  auto left = [&](int i, int j) { return (term(i, j, 0) + term(i, j, 1)) + term(i, j, 2); };
  return {left(0, 0), left(0, 1), left(0, 2),
          left(1, 1), left(1, 2), term(2, 2, 0) + (term(2, 2, 1) + term(2, 2, 2))};
}

}  // namespace

QuadraticForm quadratic_form(const std::array<double, 3>& semi_axes,
                             const std::array<double, 9>& rotation) {
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> r(rotation.data());
  // (maxCoeff skips NaN, hence the explicit finiteness check.)
  const double defect = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!r.allFinite() || !(defect <= 1e-9))
    throw std::invalid_argument(
        "quadratic_form: rotation matrix is not orthogonal (|R^T R - I| = " +
        detail::number_text(defect) + ")");
  return from_rotation(semi_axes, r);
}

QuadraticForm quadratic_form_from_quaternion(const std::array<double, 3>& semi_axes,
                                             const std::array<double, 4>& quaternion) {
  // Outside 2^+-400 brought to a largest component in [1/2, 1) by a power of
  // two (exact) first, so that its norm neither underflows nor overflows:
  // any finite, non-zero quaternion gives its rotation.
  double largest = 0;
  bool finite = true;
  for (double c : quaternion) {
    largest = std::max(largest, std::abs(c));
    finite = finite && std::isfinite(c);
  }
  if (!(largest > 0) || !finite) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "quadratic_form_from_quaternion: the quaternion (%.17g, %.17g, %.17g, %.17g) "
                  "is %s",
                  quaternion[0], quaternion[1], quaternion[2], quaternion[3],
                  finite ? "zero" : "not finite");
    throw std::invalid_argument(text);
  }
  Eigen::Quaterniond q(quaternion[0], quaternion[1], quaternion[2], quaternion[3]);
  // Where the largest component is within 2^+-400 the sum of squares can
  // neither overflow nor lose a significant term without the scaling, and
  // the scaling (exact, and cancelling in each quotient) would change no bit
  // of the unit quaternion, unless it took a component below 2^-1022, where
  // it would round it: skipped there, which is almost always (it was a
  // tenth of a million-particle store's build).
  if (!(largest >= 0x1p-400 && largest <= 0x1p400)) {
    int exponent = 0;
    std::frexp(largest, &exponent);
    for (int k = 0; k < 4; ++k) q.coeffs()[k] = std::ldexp(q.coeffs()[k], -exponent);
  }
  q.coeffs() /= q.norm();
  return from_rotation(semi_axes, q.toRotationMatrix());
}

QuadraticForm spheroid(double a, double c, const std::array<double, 3>& axis) {
  Eigen::Vector3d n(axis[0], axis[1], axis[2]);
  double norm = n.norm();
  if (!(norm > 0) || !std::isfinite(norm)) {
    // A finite, non-zero axis whose sum of squares under- or overflows
    // (components below ~1e-154 or above ~1e154) is brought to a largest
    // component in [1, 2) by a power of two first (exact); only a zero or
    // non-finite one is refused.
    const double largest = n.cwiseAbs().maxCoeff();
    if (!n.allFinite() || !(largest > 0))
      throw std::invalid_argument("spheroid: zero or non-finite axis");
    n *= std::ldexp(1.0, -std::ilogb(largest));
    norm = n.norm();
  }
  n /= norm;
  const double a2 = a * std::abs(a), c2 = c * std::abs(c);  // signed, as in from_rotation
  const Eigen::Matrix3d q = a2 * Eigen::Matrix3d::Identity() + (c2 - a2) * n * n.transpose();
  return pack(q);
}

QuadraticForm sphere(double a) {
  const double a2 = a * std::abs(a);  // signed, as in from_rotation
  return {a2, 0, 0, a2, 0, a2};
}

}  // namespace pwcontact
