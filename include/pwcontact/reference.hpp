// The scalar reference path: one pair in, mu^2 and lambda out, converged to
// the full precision of the floating type T.
//
// It is a template so that the tests can instantiate it in higher precision
// (long double, Boost.Multiprecision) as an oracle, and it is written to be
// read against the theory (doc/theory.md in the source tree); equation
// numbers below refer to it.
//
// Method: the contact function is mu^2 = max over lambda in [0, 1] of
//   f(lambda) = lambda (1 - lambda) r12^T Q^-1 r12,   Q = (1 - lambda) Q1 + lambda Q2
// (eqs. 6, 10, 11). f is concave (eq. 15), so its maximiser is the unique root
// of the increasing residual g = -f' = mu2^2 - mu1^2 (eqs. 13, 17), bracketed
// by [0, 1] (eq. 16).
// We run a safeguarded Newton iteration on g: a Newton step is accepted when
// it stays inside the current bracket (inclusive test: at convergence the
// Newton iterate coincides with a bracket end) and is replaced by bisection
// otherwise, so convergence is global; an iterate that lands exactly on the
// far end of the bracket (a point already evaluated: a cycle on noise in g)
// is bisected too, or ends the iteration when no number lies inside the
// bracket.
#pragma once

#include <cmath>
#include <limits>
#include <utility>

#include "pwcontact/status.hpp"

namespace pwcontact {

template <class T>
struct ContactResult {
  T mu2;     // the contact function, eq. (6); NaN when status is invalid
  T lambda;  // its maximiser lambda_0 in [0, 1]; NaN when invalid
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
// For a symmetric matrix, Q is positive definite iff all d_i > 0 (eq. 38).
//
// The kernels' copy is Ldlt, factor, forward, backward,
// inverse_quadratic_form and evaluate in src/kernels/simd_math.hpp: the same
// operations in the same order, except that the kernels keep 1/d_i and
// multiply by it where this divides by d_i (fewer divisions per lane; here
// each quotient is rounded once). tests/shared_math_test.cpp holds the two
// copies together bit for bit.
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

// Whether a stored form is positive definite, decided so that a form that is
// not is never accepted.
//
// First a filter: Sylvester's criterion through the pivots of Q = L D L^T,
// d0 = a0, d1 = a3 - l10 a1, d2 = a5 - l20 a2 - l21 t (t = a4 - l20 a1),
// each compared with a rigorous bound on its rounding error. A pivot carries
// its own rounding and what it inherits from the earlier ones: to first
// order (u = eps / 2, the unit roundoff; doc/theory.md eq. 39, which counts
// each term),
//   |d1~ - d1| <= 3u C1,  C1 = a3 + |l10 a1|                (cancelled1)
//   |d2~ - d2| <= 6u C2,  C2 = a5 + |l20 a2| + l21 t
//                              + |l21| (|a4| + |l20 a1|) + l21^2 C1   (cancelled2)
// (the last terms are t^2 / d1 inheriting the errors of t and d1). The
// filter's bounds, 4 eps C_i = 8u C_i, lie above both, plus an absolute
// floor for the rounding of numbers that underflow. A pivot below minus its bound proves the
// form indefinite or negative (the leading minors are a0 d1 and a0 d1 d2);
// one above 64 times the rounding of its terms (where the first-order bound
// holds with room) proves the minor positive. Between, the filter cannot
// tell, and the minors' signs are computed exactly (positive_definite_exactly).
enum class Definiteness { positive, not_positive, undecided };

template <class T>
Definiteness definiteness(const T a[6]) {
  using std::abs;
  const T eps = std::numeric_limits<T>::epsilon();
  const T underflow = T(16) * std::numeric_limits<T>::min();
  if (!(a[0] > 0) || !(a[3] > 0) || !(a[5] > 0)) return Definiteness::not_positive;
  const T l10 = a[1] / a[0], l20 = a[2] / a[0];
  const T c1 = l10 * a[1];
  const T d1 = a[3] - c1;
  const T cancelled1 = a[3] + abs(c1);
  if (d1 < -(T(4) * eps * cancelled1 + underflow)) return Definiteness::not_positive;
  if (!(d1 > T(64) * eps * cancelled1 + underflow)) return Definiteness::undecided;
  const T t = a[4] - l20 * a[1];
  const T l21 = t / d1;
  const T c2 = l20 * a[2], c3 = l21 * t;
  const T d2 = a[5] - c2 - c3;
  const T cancelled2 =
      a[5] + abs(c2) + c3 + abs(l21) * (abs(a[4]) + abs(l20 * a[1])) + l21 * l21 * cancelled1;
  if (d2 < -(T(4) * eps * cancelled2 + underflow)) return Definiteness::not_positive;
  if (!(d2 > T(64) * eps * cancelled2 + underflow)) return Definiteness::undecided;
  return Definiteness::positive;
}

// Sylvester's criterion on the stored numbers, exactly: the leading minors
// a0 a3 - a1^2 and det Q of D Q D with D the diagonal of powers of two that
// brings Q's diagonal into [1, 4) (congruent: the same signs), each summed
// from error-free products as a floating-point expansion, whose sign is that
// of its leading component. Off-diagonals that underflow in D Q D change a
// minor by less than 2^-1000; a minor below 2^-900 (a form whose smallest
// eigenvalue is below ~2^-900 of its diagonal) is therefore not positive
// beyond doubt, and the form is rejected. Defined in reference.cpp.
bool positive_definite_exactly(const double a[6]);

// The decision the whole library uses: the filter, then the exact test on the
// stored numbers. Every float and double is a double; a wider type's entries
// that are not (never the case for the library's inputs) cannot be decided
// exactly and are rejected.
template <class T>
bool positive_definite(const T a[6]) {
  switch (definiteness(a)) {
    case Definiteness::positive: return true;
    case Definiteness::not_positive: return false;
    case Definiteness::undecided: break;
  }
  double d[6];
  for (int k = 0; k < 6; ++k) {
    d[k] = static_cast<double>(a[k]);
    if (!(T(d[k]) == a[k])) return false;
  }
  return positive_definite_exactly(d);
}

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
  out.dg = T(2) * (ya[0] * yb[0] / ldlt.d0 + ya[1] * yb[1] / ldlt.d1 + ya[2] * yb[2] / ldlt.d2);
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

// mu^2 is invariant under Q -> k^2 Q, r -> k r, and homogeneous of degree 2
// in r alone. The pair is solved as two exact power-of-two scalings: Q by the
// one that brings the largest diagonal entry to O(1), r by the one that
// brings its largest component to [1/2, 1). Then no scale of the inputs
// overflows or underflows on the way, nor does r^T Q^-1 r for a distance
// far beyond the sizes (or far below them), and mu^2 is rescaled once at
// the end, where its own overflow or underflow is reported (out_of_range).
//   Q = 2^(2 q_exponent) q,  r12 = 2^r_exponent r,
//   mu^2(r12, Q1, Q2) = 2^(2 (r_exponent - q_exponent)) mu^2(r, q1, q2).
// Coincident centres (r12 = 0) keep r = 0 and r_exponent = 0 (eq. 36).
// The kernels' copies, nondimensionalise (src/kernels/lane_blocks.hpp) and
// pack_unfinished (contact_kernel.hpp), scale r and Q by one power t, Q's
// largest diagonal entry into [1, 4): their Q is this one's times 4,
// exactly (tests/shared_math_test.cpp).
template <class T>
struct ScaledPair {
  T r[3], q1[6], q2[6];
  int q_exponent = 0;
  int r_exponent = 0;

  ScaledPair(const T r12[3], const T q1_in[6], const T q2_in[6]) {
    using std::abs;
    using std::frexp;
    using std::ldexp;
    using std::sqrt;
    const T largest =
        max_diagonal(q1_in) > max_diagonal(q2_in) ? max_diagonal(q1_in) : max_diagonal(q2_in);
    if (largest > 0) frexp(sqrt(largest), &q_exponent);
    T r_largest = abs(r12[0]);
    for (int k = 1; k < 3; ++k)
      if (abs(r12[k]) > r_largest) r_largest = abs(r12[k]);
    if (r_largest > 0) frexp(r_largest, &r_exponent);
    for (int k = 0; k < 3; ++k) r[k] = ldexp(r12[k], -r_exponent);
    for (int k = 0; k < 6; ++k) {
      q1[k] = ldexp(q1_in[k], -2 * q_exponent);
      q2[k] = ldexp(q2_in[k], -2 * q_exponent);
    }
  }

  // mu^2 (or f) of the given pair from that of the scaled one.
  T unscaled_mu2(T mu2) const {
    using std::ldexp;
    return ldexp(mu2, 2 * (r_exponent - q_exponent));
  }
};

// r^T Q^-1 r through the factorisation, or infinity where it is not usable:
// a pivot that is not positive (a form so much smaller than the other that
// the common scaling left it without significant digits) or an overflow.
template <class T>
T slope_or_infinity(const Ldlt3<T>& ldlt, const T r[3]) {
  using std::isfinite;
  const T slope = inverse_quadratic_form(ldlt, r);
  const bool usable = ldlt.d0 > 0 && ldlt.d1 > 0 && ldlt.d2 > 0 && slope > 0 && isfinite(slope);
  return usable ? slope : std::numeric_limits<T>::infinity();
}

// The status of a mu^2 as the type holds it: out_of_range beyond the normal
// range (mu2 > 0 here: coincident centres are answered before).
template <class T>
Status range_status(T mu2) {
  return mu2 >= std::numeric_limits<T>::min() && mu2 <= std::numeric_limits<T>::max()
             ? Status::ok
             : Status::out_of_range;
}

// The largest number under 1: lambda stays in [1 - below_one, below_one] =
// [eps/2, 1 - eps/2]. A maximiser closer to 0 or 1 than that (size ratios
// beyond ~1e16) is represented by the bound to a relative eps/2 in f, by
// concavity: f(l) >= l mu^2 / lambda* on [0, lambda*] and
// f(l) >= (1 - l) mu^2 / (1 - lambda*) on [lambda*, 1]. Below eps/2 the
// terms of Q(lambda) would span more than the type's range (Q(lambda) ~
// lambda Q1 beside a form lost to the scaling: its products overflow).
template <class T>
T below_one() {
  return T(1) - std::numeric_limits<T>::epsilon() / 2;
}

template <class T>
struct Maximum {
  T f = 0;  // f(lambda) of the scaled pair
  T lambda = 0;
  bool converged = false;
};

// The safeguarded Newton iteration on g (see the header) from a start in
// [0, 1]; iterations counts the evaluations of (f, g, g'), added to the
// count given.
template <class T>
Maximum<T> maximise(const T r[3], const T* p1, const T* p2, T lambda,
                    const ReferenceOptions& options, int& iterations) {
  using std::abs;
  using std::isfinite;
  const T eps = std::numeric_limits<T>::epsilon();
  const T ceiling = below_one<T>();
  const T floor = T(1) - ceiling;  // eps / 2, exactly
  if (lambda > ceiling) lambda = ceiling;
  if (lambda < floor) lambda = floor;
  T lo = 0, hi = 1;
  T previous_step = 1;
  for (int it = 1; it <= options.max_iterations; ++it) {
    const Residual<T> res = evaluate(r, p1, p2, lambda);
    // At a clamp with g pointing beyond it, lambda* lies closer to 0 or 1
    // than eps/2 and f here is mu^2 to eps/2 (below_one): the end, as a
    // Newton step clamped back onto lambda would make it, whatever g' says.
    // (Was: a disc 1.1e-29 thick beside a shape of size 1, lambda* ~1e-29 on
    // the mirrored pair: at the floor g' came out -1, all cancellation, and
    // the pair was not_converged.)
    if (((lambda == floor && res.g > 0) || (lambda == ceiling && res.g < 0)) && res.f > 0 &&
        isfinite(res.f)) {
      iterations += it;
      return {res.f, lambda, true};
    }
    // Lost to round-off: give up honestly. (g' = 0 is allowed: a form that
    // the scaling left without digits has none; the step is then a bisection.)
    if (!(res.dg >= 0) || !(res.f >= 0)) {
      iterations += it;
      return {};
    }
    if (res.g > 0) hi = lambda;
    if (res.g < 0) lo = lambda;
    const T step = res.g / res.dg;
    T next = lambda - step;
    const bool newton = lo <= next && next <= hi;  // inclusive, see header
    if (!newton) next = (lo + hi) / 2;
    if (next > ceiling) next = ceiling;
    if (next < floor) next = floor;

    // Done when lambda no longer moves at its own precision, or when Newton
    // has stalled on round-off noise in g while the predicted gain in mu^2,
    // g^2 / (2 g'), is already below one ulp of f. The prediction is the
    // quadratic model's, good only for a step small beside the distance to
    // the nearest singularity of f (det Q(lambda) = 0 lies outside [0, 1],
    // so at least min(lambda, 1 - lambda) away): a step beyond 1/16 of it is
    // progress, not a stall. (Was: Q1 = diag(1, 1e-50, 1), Q2 = I, r = (1, 2,
    // 3): from the radial guess ~sqrt(1e-50) Newton's steps grew fourfold
    // and more each time, the curvature ~1e-50 / lambda^3 made every predicted
    // gain negligible, and mu^2 = 4 was returned for 4.9.)
    //
    // A Newton iterate on the far end of the bracket is a point already
    // evaluated (each evaluated lambda became lo or hi; after the clamp,
    // next > 0 is never an unevaluated lo, nor next < 1 an unevaluated hi):
    // no progress. When that end was itself left by a Newton step, the same
    // g and g' lead back, a 2-cycle that the stall test ends only while the
    // predicted gain is below one ulp of f, which noise in g of ~eps cond(Q)
    // mu^2 defeats at large cond. Such an iterate is replaced by bisection
    // below, or, when no number lies strictly inside the bracket (one ulp
    // wide above 3/4, where 2 eps scale is less than an ulp of lambda), the
    // iteration has settled. (Was: parallel flat ellipsoids, cond(Q(lambda*))
    // 7.8e10, in long double: lambda alternating between 0.46806260966 and
    // 0.46806260984, g = -/+17.41 (exact: -27.6, -10.2), g' = 9.8e10, a
    // predicted gain of 1.16 ulps of f; not_converged after 200 evaluations.)
    const T scale = lambda < T(1) - lambda ? lambda : T(1) - lambda;
    const bool revisit = newton && next != lambda && (next == lo || next == hi);
    const T middle = (lo + hi) / 2;
    const bool settled = abs(next - lambda) <= T(2) * eps * scale ||
                         hi - lo <= T(2) * eps * scale ||
                         (revisit && !(lo < middle && middle < hi));
    const bool stalled = newton && it > 2 && abs(step) >= abs(previous_step) / 2 &&
                         abs(step) <= scale / 16 && res.g * step <= T(2) * eps * res.f;
    if (settled || stalled) {
      iterations += it + 1;
      const Residual<T> final_res = evaluate(r, p1, p2, next);
      if (!(final_res.f > 0) || !isfinite(final_res.f)) return {};
      return {final_res.f, next, true};
    }
    if (revisit)
      next = middle;
    else if (newton)
      previous_step = step;
    lambda = next;
  }
  iterations += options.max_iterations;
  return {};
}

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

  if (!detail::all_finite(r12, 3) || !detail::all_finite(q1, 6) || !detail::all_finite(q2, 6))
    return {nan, nan, Status::non_finite_input, 0};
  // Decided on the stored numbers, before any scaling could round them.
  if (!detail::positive_definite(q1)) return {nan, nan, Status::q1_not_positive_definite, 0};
  if (!detail::positive_definite(q2)) return {nan, nan, Status::q2_not_positive_definite, 0};

  const detail::ScaledPair<T> scaled(r12, q1, q2);
  if (r12[0] == 0 && r12[1] == 0 && r12[2] == 0) {
    // Coincident centres: f vanishes identically, mu^2 = 0. Any lambda is a
    // maximiser; report the one that is exact for spheres in the limit of
    // small r along any direction, from the traces.
    const T t1 = sqrt(scaled.q1[0] + scaled.q1[3] + scaled.q1[5]);
    const T t2 = sqrt(scaled.q2[0] + scaled.q2[3] + scaled.q2[5]);
    return {T(0), t1 / (t1 + t2), Status::ok, 0};
  }
  T r[3] = {scaled.r[0], scaled.r[1], scaled.r[2]};
  const T* p1 = scaled.q1;
  const T* p2 = scaled.q2;
  T slope0 = detail::slope_or_infinity(detail::Ldlt3<T>(p1), r);  // f'(0)
  T slope1 = detail::slope_or_infinity(detail::Ldlt3<T>(p2), r);  // -f'(1)
  const T infinity = std::numeric_limits<T>::infinity();
  // A form negligible beside the other (largest diagonal entry below eps^2
  // of the other's: sizes beyond 1 / eps apart) puts the maximiser within
  // ~eps of 0 or 1. Its slope may overflow, or its factorisation be lost to
  // the common scaling; the other slope is then all the guess needs.
  auto negligible = [eps](const T* q, const T* other) {
    return detail::max_diagonal(q) < eps * eps * detail::max_diagonal(other);
  };
  // Ellipsoid 1 negligible: solved as ellipsoid 2, since mu^2(r, Q1, Q2) =
  // mu^2(-r, Q2, Q1) with lambda -> 1 - lambda, so that the maximiser is near
  // 1, where lambda's clamp below handles it.
  bool swapped = slope0 == infinity && negligible(p1, p2);
  if (swapped) {
    std::swap(p1, p2);
    std::swap(slope0, slope1);
    for (T& x : r) x = -x;
  }

  // lambda stays in [eps/2, 1 - eps/2] (detail::below_one). A slope that is
  // not usable for another reason (a form positive definite but too
  // ill-conditioned for its factorisation in T) leaves the guess at 1/2: the
  // safeguarded iteration needs none.
  //
  // Near 1, though, lambda is resolved only to eps, not eps (1 - lambda): a
  // Newton step below half an ulp of 1 rounds to no step at all, and the
  // iteration "settles" wherever that happens. (Was: Q2 ~1e-25 beside Q1 ~1,
  // lambda* = 1 - 2.35e-13: the radial guess rounded to 1, the first step to
  // none, and mu^2 came back 5e-10 low, status ok.) So a maximiser above 1/2
  // is sought on the mirrored pair, mu^2(r, Q1, Q2) = mu^2(-r, Q2, Q1) at
  // 1 - lambda, where 1 - lambda is a small number held to full precision:
  // from the start when the radial guess is above 1/2, and again from the
  // answer when the iteration ends above 1/2 all the same. Not so for a
  // negligible form, whose maximiser within ~eps of 1 is meant to be
  // represented by the clamp.
  T lambda = T(0.5);
  if (slope0 < infinity && slope1 < infinity)
    lambda = detail::radial_initial_guess(slope0, slope1);
  else if (slope1 == infinity && negligible(p2, p1))
    lambda = detail::below_one<T>();
  const bool mirror = !negligible(p2, p1);
  auto mirror_pair = [&] {
    std::swap(p1, p2);
    for (T& x : r) x = -x;
    swapped = !swapped;
  };
  if (mirror && lambda > T(0.5)) {
    mirror_pair();
    lambda = detail::radial_initial_guess(slope1, slope0);
  }
  int iterations = 0;
  detail::Maximum<T> found = detail::maximise(r, p1, p2, lambda, options, iterations);
  if (mirror && found.converged && found.lambda > T(0.5)) {
    mirror_pair();
    const detail::Maximum<T> again =
        detail::maximise(r, p1, p2, T(1) - found.lambda, options, iterations);
    if (again.converged)
      found = again;
    else
      mirror_pair();  // keep the first answer, in its own frame
  }
  if (!found.converged) return {nan, nan, Status::not_converged, iterations};
  const T mu2 = scaled.unscaled_mu2(found.f);
  return {mu2, swapped ? T(1) - found.lambda : found.lambda, detail::range_status(mu2), iterations};
}

// What else the maximiser lambda gives (doc/theory.md eq. 43), with
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
  using std::ldexp;
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
  ldlt.backward(z, s);  // Q^-1 r12 = 2^(r_exponent - 2 q_exponent) s
  T a[3];
  detail::symmetric_times(p.q1, s, a);
  const T norm = sqrt(detail::dot3(s, s));
  ContactGeometry<T> out;
  for (int k = 0; k < 3; ++k) {
    out.contact_point[k] = ldexp(mu * a[k], p.r_exponent);
    out.normal[k] = norm > 0 ? s[k] / norm : T(0);
    out.gradient[k] = ldexp(T(2) * lambda * mu * s[k], p.r_exponent - 2 * p.q_exponent);
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
                                                             const float*, const ReferenceOptions&);
extern template ContactGeometry<double> contact_geometry<double>(const double*, const double*,
                                                                 const double*, double);
extern template ContactGeometry<float> contact_geometry<float>(const float*, const float*,
                                                               const float*, float);
}  // namespace pwcontact
