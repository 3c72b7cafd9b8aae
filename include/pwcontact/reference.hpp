// The scalar reference path: one pair in, mu^2 and lambda out, converged to
// the full precision of the floating type T.
//
// It is a template so that the tests can instantiate it in higher precision
// (long double, Boost.Multiprecision) as an oracle, and it is written to be
// read against the theory (shared/seed/theory.txt); equation numbers below
// refer to it.
//
// Method: the contact function is mu^2 = max over lambda in [0, 1] of
//   f(lambda) = lambda (1 - lambda) r12^T Q^-1 r12,   Q = (1 - lambda) Q1 + lambda Q2
// (eqs. 6, 10, 11). f is concave, so its maximiser is the unique root of the
// increasing residual g = -f' = mu2^2 - mu1^2 (eq. 13), bracketed by [0, 1].
// We run a safeguarded Newton iteration on g: a Newton step is accepted when
// it stays inside the current bracket (inclusive test: at convergence the
// Newton iterate coincides with a bracket end) and is replaced by bisection
// otherwise, so convergence is global.
#pragma once

#include <cmath>
#include <limits>

#include "pwcontact/status.hpp"

namespace pwcontact {

template <class T>
struct ContactResult {
  T mu2;           // the contact function, eq. (6); NaN when status is invalid
  T lambda;        // its maximiser lambda_0 in [0, 1]; NaN when invalid
  Status status;
  int iterations;  // evaluations of (f, g, g') that were needed
};

struct ReferenceOptions {
  // Safety net only: the safeguarded iteration converges in far fewer
  // evaluations (quadratically once Newton takes over; bisection halves the
  // bracket otherwise).
  int max_iterations = 200;
};

namespace detail {

// Q = L D L^T for a symmetric 3x3 matrix given as 6 numbers (upper triangle,
// row-major, eq. 3), L unit lower triangular. No square roots, and
// r^T Q^-1 r = sum y_i^2 / d_i with y = L^-1 r is a sum of positive terms.
// For a symmetric matrix, Q is positive definite iff all d_i > 0.
template <class T>
struct Ldlt3 {
  T d0, d1, d2;
  T l10, l20, l21;

  explicit Ldlt3(const T a[6]) {
    d0 = a[0];
    l10 = a[1] / d0;
    l20 = a[2] / d0;
    d1 = a[3] - l10 * a[1];
    const T t = a[4] - l20 * a[1];
    l21 = t / d1;
    d2 = a[5] - l20 * a[2] - l21 * t;
  }

  // Positive definite beyond doubt: every pivot above the rounding error of
  // the terms that cancel in it (16 eps times their magnitudes; the error is
  // a few eps). A Q whose smallest eigenvalue is below ~1e-15 of its largest
  // (double) is then "not positive definite" rather than answered as if it
  // were an ellipsoid its rounded entries cannot define. Written so that NaN
  // pivots count as "not positive definite".
  bool positive_definite(const T a[6]) const {
    using std::abs;
    const T margin = T(16) * std::numeric_limits<T>::epsilon();
    const T cancelled1 = a[3] + abs(l10 * a[1]);
    const T cancelled2 = a[5] + abs(l20 * a[2]) + l21 * l21 * d1;
    return d0 > 0 && d1 > margin * cancelled1 && d2 > margin * cancelled2;
  }

  // y = L^-1 b
  void forward(const T b[3], T y[3]) const {
    y[0] = b[0];
    y[1] = b[1] - l10 * y[0];
    y[2] = b[2] - l20 * y[0] - l21 * y[1];
  }

  // x = L^-T z
  void backward(const T z[3], T x[3]) const {
    x[2] = z[2];
    x[1] = z[1] - l21 * x[2];
    x[0] = z[0] - l10 * x[1] - l20 * x[2];
  }
};

// y = A x for a symmetric A given as 6 numbers.
template <class T>
void symmetric_times(const T a[6], const T x[3], T y[3]) {
  y[0] = a[0] * x[0] + a[1] * x[1] + a[2] * x[2];
  y[1] = a[1] * x[0] + a[3] * x[1] + a[4] * x[2];
  y[2] = a[2] * x[0] + a[4] * x[1] + a[5] * x[2];
}

template <class T>
T dot3(const T a[3], const T b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// f, g = -f' and g' at one lambda.
template <class T>
struct Residual {
  T f;   // f(lambda), eq. (11)
  T g;   // mu2^2 - mu1^2 = -f'(lambda); increasing in lambda
  T dg;  // g'(lambda) = -f''(lambda) >= 0
};

// With s = Q^-1 r12 (eq. 9: x0 - c1 = (1 - lambda) Q1 s, x0 - c2 = -lambda Q2 s):
//   f      = lambda (1 - lambda) r12^T s                            (11)
//   mu1^2  = (1 - lambda)^2 s^T Q1 s,  mu2^2 = lambda^2 s^T Q2 s    (13)
//   g'     = 2 (Q1 s)^T Q^-1 (Q2 s) = 2 s^T [(1 - lambda) Q2^-1 + lambda Q1^-1]^-1 s
// Q is formed as the convex combination (eq. 10), never as Q1 + lambda (Q2 - Q1),
// which would lose the smaller matrix when the sizes differ by orders of magnitude.
template <class T>
Residual<T> evaluate(const T r[3], const T q1[6], const T q2[6], T lambda) {
  const T mu = T(1) - lambda;  // exact for lambda >= 1/2 (Sterbenz)
  T q[6];
  for (int k = 0; k < 6; ++k) q[k] = mu * q1[k] + lambda * q2[k];
  const Ldlt3<T> ldlt(q);

  T y[3], z[3], s[3];
  ldlt.forward(r, y);
  z[0] = y[0] / ldlt.d0;
  z[1] = y[1] / ldlt.d1;
  z[2] = y[2] / ldlt.d2;
  ldlt.backward(z, s);
  const T rs = dot3(y, z);  // r^T Q^-1 r as a sum of positive terms

  T a[3], b[3];
  symmetric_times(q1, s, a);
  symmetric_times(q2, s, b);
  T ya[3], yb[3];
  ldlt.forward(a, ya);
  ldlt.forward(b, yb);

  Residual<T> out;
  out.f = lambda * mu * rs;
  out.g = lambda * lambda * dot3(s, b) - mu * mu * dot3(s, a);
  out.dg = T(2) * (ya[0] * yb[0] / ldlt.d0 + ya[1] * yb[1] / ldlt.d1 +
                   ya[2] * yb[2] / ldlt.d2);
  return out;
}

// Initial guess exact for two spheres: lambda = rho1 / (rho1 + rho2), with
// rho_i the distance from centre i to its surface along the centre line,
// rho_i = |r| (r^T Qi^-1 r)^-1/2. It only needs r^T Qi^-1 r = f'(0) and -f'(1).
template <class T>
T radial_initial_guess(T r_q1inv_r, T r_q2inv_r) {
  using std::sqrt;
  const T w1 = sqrt(r_q2inv_r);  // proportional to rho1
  const T w2 = sqrt(r_q1inv_r);  // proportional to rho2
  return w1 / (w1 + w2);
}

template <class T>
T inverse_quadratic_form(const Ldlt3<T>& ldlt, const T r[3]) {
  T y[3];
  ldlt.forward(r, y);
  return y[0] * y[0] / ldlt.d0 + y[1] * y[1] / ldlt.d1 + y[2] * y[2] / ldlt.d2;
}

template <class T>
bool all_finite(const T* x, int n) {
  using std::isfinite;
  for (int k = 0; k < n; ++k)
    if (!isfinite(x[k])) return false;
  return true;
}

template <class T>
T max_diagonal(const T q[6]) {
  T m = q[0];
  if (q[3] > m) m = q[3];
  if (q[5] > m) m = q[5];
  return m;
}

// mu^2 is invariant under Q -> k^2 Q, r -> k r. The pair scaled by a power of
// two (exact) so that the largest diagonal entry is O(1): no overflow or
// underflow at extreme scales, and the factorisations see O(1) numbers.
// r = 2^-exponent r12, Q = 2^-2 exponent Q.
template <class T>
struct ScaledPair {
  T r[3], q1[6], q2[6];
  int exponent = 0;

  ScaledPair(const T r12[3], const T q1_in[6], const T q2_in[6]) {
    using std::frexp;
    using std::ldexp;
    using std::sqrt;
    const T largest = max_diagonal(q1_in) > max_diagonal(q2_in) ? max_diagonal(q1_in)
                                                                 : max_diagonal(q2_in);
    if (largest > 0) frexp(sqrt(largest), &exponent);
    for (int k = 0; k < 3; ++k) r[k] = ldexp(r12[k], -exponent);
    for (int k = 0; k < 6; ++k) {
      q1[k] = ldexp(q1_in[k], -2 * exponent);
      q2[k] = ldexp(q2_in[k], -2 * exponent);
    }
  }
};

}  // namespace detail

// The contact function of two ellipsoids (c1, Q1) and (c2, Q2), with
// r12 = c2 - c1 and each Q as 6 numbers (upper triangle, row-major, eq. 3).
template <class T>
ContactResult<T> contact_function(const T r12[3], const T q1[6], const T q2[6],
                                  const ReferenceOptions& options = {}) {
  using std::abs;
  using std::sqrt;
  const T nan = std::numeric_limits<T>::quiet_NaN();
  const T eps = std::numeric_limits<T>::epsilon();

  if (!detail::all_finite(r12, 3) || !detail::all_finite(q1, 6) ||
      !detail::all_finite(q2, 6))
    return {nan, nan, Status::non_finite_input, 0};

  const detail::ScaledPair<T> scaled(r12, q1, q2);
  const T* const r = scaled.r;
  const T* const p1 = scaled.q1;
  const T* const p2 = scaled.q2;

  const detail::Ldlt3<T> ldlt1(p1), ldlt2(p2);
  if (!ldlt1.positive_definite(p1))
    return {nan, nan, Status::q1_not_positive_definite, 0};
  if (!ldlt2.positive_definite(p2))
    return {nan, nan, Status::q2_not_positive_definite, 0};

  const T slope0 = detail::inverse_quadratic_form(ldlt1, r);  // f'(0)
  const T slope1 = detail::inverse_quadratic_form(ldlt2, r);  // -f'(1)
  if (!(slope0 > 0) || !(slope1 > 0)) {
    // Coincident centres: f vanishes identically, mu^2 = 0. Any lambda is a
    // maximiser; report the one that is exact for spheres in the limit of
    // small r along any direction, from the traces.
    const T t1 = sqrt(p1[0] + p1[3] + p1[5]);
    const T t2 = sqrt(p2[0] + p2[3] + p2[5]);
    return {T(0), t1 / (t1 + t2), Status::ok, 0};
  }

  // lambda stays at or below the largest number under 1: f(1) = 0, while a
  // maximiser closer to 1 than that (size ratios beyond ~1e16, where the
  // radial guess and the steps round to 1) is represented by it to a
  // relative 2^-digits in f (concavity: f(l) >= l mu^2 / lambda* on
  // [0, lambda*]). The side of 0 needs nothing: lambda* ~ a1 / a2 there, and
  // the nondimensionalised forms keep that far above the smallest number.
  const T below_one = T(1) - eps / 2;
  T lambda = detail::radial_initial_guess(slope0, slope1);
  if (lambda > below_one) lambda = below_one;
  T lo = 0, hi = 1;
  T previous_step = 1;
  for (int it = 1; it <= options.max_iterations; ++it) {
    const detail::Residual<T> res = detail::evaluate(r, p1, p2, lambda);
    if (!(res.dg > 0) || !(res.f >= 0)) break;  // lost to round-off: give up honestly
    if (res.g > 0) hi = lambda;
    if (res.g < 0) lo = lambda;
    const T step = res.g / res.dg;
    T next = lambda - step;
    const bool newton = lo <= next && next <= hi;  // inclusive, see header
    if (!newton) next = (lo + hi) / 2;
    if (next > below_one) next = below_one;

    // Done when lambda no longer moves at its own precision, or when Newton
    // has stalled on round-off noise in g while the predicted gain in mu^2,
    // g^2 / (2 g'), is already below one ulp of f.
    const T scale = lambda < T(1) - lambda ? lambda : T(1) - lambda;
    const bool settled = abs(next - lambda) <= T(2) * eps * scale ||
                         hi - lo <= T(2) * eps * scale;
    const bool stalled = newton && it > 2 && abs(step) >= abs(previous_step) / 2 &&
                         res.g * step <= T(2) * eps * res.f;
    if (settled || stalled) {
      lambda = next;
      const detail::Residual<T> final_res = detail::evaluate(r, p1, p2, lambda);
      if (!(final_res.f >= 0)) break;
      return {final_res.f, lambda, Status::ok, it + 1};
    }
    if (newton) previous_step = step;
    lambda = next;
  }
  return {nan, nan, Status::not_converged, options.max_iterations};
}

// What else the maximiser lambda gives (shared/notes/numerics.md), with
// s = Q(lambda)^-1 r12:
template <class T>
struct ContactGeometry {
  T contact_point[3];  // x0 - c1 = (1 - lambda) Q1 s (eq. 9a), where the two
                       // ellipsoids scaled by mu touch, relative to centre 1
  T normal[3];         // s / |s|: the unit normal at x0, outward of ellipsoid 1
                       // (eq. 8); 0 for coincident centres, where it is undefined
  T gradient[3];       // d mu^2 / d r12 = 2 lambda (1 - lambda) s (envelope theorem)
};

// The geometry at a given lambda (normally contact_function's), computed
// with the same nondimensionalisation. The inputs must be valid (see
// contact_function's statuses).
template <class T>
ContactGeometry<T> contact_geometry(const T r12[3], const T q1[6], const T q2[6], T lambda) {
  using std::sqrt;
  const detail::ScaledPair<T> p(r12, q1, q2);
  const T mu = T(1) - lambda;
  T q[6];
  for (int k = 0; k < 6; ++k) q[k] = mu * p.q1[k] + lambda * p.q2[k];
  const detail::Ldlt3<T> ldlt(q);
  T y[3], z[3], s[3];
  ldlt.forward(p.r, y);
  z[0] = y[0] / ldlt.d0;
  z[1] = y[1] / ldlt.d1;
  z[2] = y[2] / ldlt.d2;
  ldlt.backward(z, s);  // s = t Q^-1 r12 with t = 2^-exponent
  T a[3];
  detail::symmetric_times(p.q1, s, a);
  const T norm = sqrt(detail::dot3(s, s));
  ContactGeometry<T> out;
  for (int k = 0; k < 3; ++k) {
    using std::ldexp;
    out.contact_point[k] = ldexp(mu * a[k], p.exponent);
    out.normal[k] = norm > 0 ? s[k] / norm : T(0);
    out.gradient[k] = ldexp(T(2) * lambda * mu * s[k], -p.exponent);
  }
  return out;
}

}  // namespace pwcontact

namespace pwcontact {
// Compiled once in the library for the two types the batch path uses.
extern template ContactResult<double> contact_function<double>(const double*, const double*,
                                                               const double*,
                                                               const ReferenceOptions&);
extern template ContactResult<float> contact_function<float>(const float*, const float*,
                                                             const float*,
                                                             const ReferenceOptions&);
extern template ContactGeometry<double> contact_geometry<double>(const double*, const double*,
                                                                 const double*, double);
extern template ContactGeometry<float> contact_geometry<float>(const float*, const float*,
                                                               const float*, float);
}  // namespace pwcontact
