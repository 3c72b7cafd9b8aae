// Building the quadratic form Q of an ellipsoid (theory eq. 2:
// Q = sum_i a_i^2 v_i v_i^T) from its semi-axes and orientation, as the
// 6 numbers the solvers take (upper triangle, row-major, eq. 3).
//
// Semi-axes are used as given: a zero one yields a singular Q and a negative
// one a negative eigenvalue (a |a| instead of a^2), both of which the solvers
// report as not positive definite, rather than an exception here.
#pragma once

#include <array>

namespace pwcontact {

using QuadraticForm = std::array<double, 6>;

// Semi-axes a[0..2] along the columns of the rotation matrix R (row-major,
// R[3*i + j]); R must be orthogonal to 1e-9 (std::invalid_argument otherwise).
QuadraticForm quadratic_form(const std::array<double, 3>& semi_axes,
                             const std::array<double, 9>& rotation);

// Semi-axes a[0..2] along the body axes x, y, z rotated by the unit
// quaternion (w, x, y, z). A quaternion whose norm is not 1 is normalised;
// a zero or non-finite one throws std::invalid_argument.
QuadraticForm quadratic_form_from_quaternion(const std::array<double, 3>& semi_axes,
                                             const std::array<double, 4>& quaternion);

// Spheroid with equatorial radius a, polar radius c and unit axis n:
// Q = a^2 I + (c^2 - a^2) n n^T. n is normalised; a zero n throws.
QuadraticForm spheroid(double a, double c, const std::array<double, 3>& axis);

// Sphere of radius a: Q = a^2 I.
QuadraticForm sphere(double a);

}  // namespace pwcontact
