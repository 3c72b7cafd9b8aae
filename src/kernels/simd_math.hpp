// The arithmetic of the batch kernels on SIMD registers: one pair per lane.
//
// The mathematics is the reference path's (include/pwcontact/reference.hpp);
// equation numbers refer to doc/theory.md. Compiled once per target,
// in that target's namespace (target.hpp).
#pragma once

#include "kernels/target.hpp"

#include <immintrin.h>
#include <xsimd/xsimd.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

// The kernels are long chains of small functions on registers; GCC's inliner
// gives up on some of them in the larger kernels, and a call that passes a
// dozen registers through memory costs more than the arithmetic (measured:
// 20 % of the whole kernel). Everything on the hot path is forced inline.
#define PWCONTACT_INLINE inline __attribute__((always_inline))
#define PWCONTACT_INLINE_LAMBDA __attribute__((always_inline))
// Rarely taken paths (Accuracy::high) stay out of the hot code.
#define PWCONTACT_COLD inline __attribute__((noinline, cold))

namespace pwcontact::kernels::PWCONTACT_TARGET {

template <class Arch>
inline constexpr bool is_avx512 = std::is_base_of<xsimd::avx512f, Arch>::value;
// (In xsimd 8.1 the AVX-512 architectures do not derive from avx2.)
template <class Arch>
inline constexpr bool is_avx2 = std::is_base_of<xsimd::avx2, Arch>::value;

// The lanes of a comparison as the low bits of an integer, lane 0 lowest.
template <class Arch, class T>
PWCONTACT_INLINE std::uint32_t lane_bits(const xsimd::batch_bool<T, Arch>& b) {
  constexpr std::size_t bytes = xsimd::batch<T, Arch>::size * sizeof(T);
  constexpr bool single = std::is_same<T, float>::value;
  if constexpr (is_avx512<Arch>) {
    return std::uint32_t(b.data);  // (a mask register)
  } else if constexpr (bytes == 32 && single) {
    return std::uint32_t(_mm256_movemask_ps(b.data));
  } else if constexpr (bytes == 32) {
    return std::uint32_t(_mm256_movemask_pd(b.data));
  } else if constexpr (single) {
    return std::uint32_t(_mm_movemask_ps(b.data));
  } else {
    static_assert(bytes == 16, "registers of 16, 32 or 64 bytes");
    return std::uint32_t(_mm_movemask_pd(b.data));
  }
}

// ---------------------------------------------------------------------------
// Symmetric 3x3 matrices: 6 numbers, upper triangle row-major (eq. 3).

// Q = L D L^T with L unit lower triangular, the reciprocal pivots kept since
// every solve divides by them. rᵀQ⁻¹r = Σ yᵢ²/dᵢ (y = L⁻¹r) is then a sum of
// positive terms, and Q is positive definite iff every dᵢ > 0 (eq. 38).
//
// The reference path's copy is detail::Ldlt3 (include/pwcontact/reference.hpp,
// with its forward, backward, inverse_quadratic_form and evaluate): the same
// operations in the same order, except that it divides by dᵢ where these
// multiply by 1/dᵢ (one division per pivot here, a division per use there;
// a / d and a (1/d) differ by a rounding unless d is a power of two).
// tests/shared_math_test.cpp holds the two copies together bit for bit.
template <class B>
struct Ldlt {
  B d0, d1, d2;
  B inv_d0, inv_d1, inv_d2;
  B l10, l20, l21;
};

template <class B>
PWCONTACT_INLINE Ldlt<B> factor(const B a[6]) {
  Ldlt<B> f;
  f.d0 = a[0];
  f.inv_d0 = B(1) / f.d0;
  f.l10 = a[1] * f.inv_d0;
  f.l20 = a[2] * f.inv_d0;
  f.d1 = a[3] - f.l10 * a[1];
  f.inv_d1 = B(1) / f.d1;
  const B t = a[4] - f.l20 * a[1];
  f.l21 = t * f.inv_d1;
  f.d2 = a[5] - f.l20 * a[2] - f.l21 * t;
  f.inv_d2 = B(1) / f.d2;
  return f;
}

// The magnitudes whose rounding a pivot of Q = L D L^T carries: its own
// terms and what it inherits from the earlier pivots (the bound derived at
// detail::definiteness in reference.hpp): for d1 = a3 - l10 a1,
// C1 = a3 + |l10 a1|, and for d2 = a5 - l20 a2 - l21 t (t = l21 d1),
// C2 = a5 + |l20 a2| + l21^2 (d1 + C1) + |l21| (|a4| + |l20 a1|).
// The rounding error of d_i is at most ~2 eps C_i.
template <class B>
PWCONTACT_INLINE void pivot_terms(const Ldlt<B>& f, const B a[6], B& cancelled1, B& cancelled2) {
  cancelled1 = a[3] + xsimd::abs(f.l10 * a[1]);
  cancelled2 = a[5] + xsimd::abs(f.l20 * a[2]) + f.l21 * f.l21 * (f.d1 + cancelled1) +
               xsimd::abs(f.l21) * (xsimd::abs(a[4]) + xsimd::abs(f.l20 * a[1]));
}

// The kernels answer only for Q positive definite beyond doubt: every pivot
// above 1024 eps times the terms it carries (512 times its rounding bound).
// A Q near the boundary goes to the reference path, which decides exactly,
// so that the kernels never call valid a pair the reference path would
// reject. (Underflow, which the bound does not cover, cannot happen in the
// lanes the kernels keep: their numbers are in range, see slopes_in_range.)
template <class T>
inline constexpr T definiteness_margin = 1024 * std::numeric_limits<T>::epsilon();

template <class B>
PWCONTACT_INLINE auto positive_definite(const Ldlt<B>& f, const B a[6]) {
  using T = typename B::value_type;
  const B margin(definiteness_margin<T>);
  B cancelled1, cancelled2;
  pivot_terms(f, a, cancelled1, cancelled2);
  return (f.d0 > B(0)) & (f.d1 > margin * cancelled1) & (f.d2 > margin * cancelled2);
}

// The largest ratio of the magnitudes that cancel in a pivot to the pivot:
// the factor by which rounding errors in Q are amplified in rᵀQ⁻¹r
// (measured: relative error of f below ~100 growth eps, p99 ~3 growth eps).
// An empirical measure of the error of f, calibrated with the margins that
// use it; the definiteness test above uses the rigorous pivot_terms. (The
// scalar certificates of the moving scene take the same ratio from the
// factors alone: certificate::Factors in src/screen/pair_prefilters.hpp.)
template <class B>
PWCONTACT_INLINE B growth(const Ldlt<B>& f, const B a[6]) {
  // d1 = a3 - l10 a1 and d2 = a5 - l20 a2 - l21 t with t = l21 d1.
  const B g1 = (a[3] + xsimd::abs(f.l10 * a[1])) * f.inv_d1;
  const B g2 = (a[5] + xsimd::abs(f.l20 * a[2]) + f.l21 * f.l21 * f.d1) * f.inv_d2;
  return xsimd::max(g1, g2);
}

// y = L⁻¹ b
template <class B>
PWCONTACT_INLINE void forward(const Ldlt<B>& f, const B b[3], B y[3]) {
  y[0] = b[0];
  y[1] = b[1] - f.l10 * y[0];
  y[2] = b[2] - f.l20 * y[0] - f.l21 * y[1];
}

// x = L⁻ᵀ D⁻¹ y, i.e. x = Q⁻¹ b when y = L⁻¹ b
template <class B>
PWCONTACT_INLINE void backward(const Ldlt<B>& f, const B y[3], B x[3]) {
  x[2] = y[2] * f.inv_d2;
  x[1] = y[1] * f.inv_d1 - f.l21 * x[2];
  x[0] = y[0] * f.inv_d0 - f.l10 * x[1] - f.l20 * x[2];
}

// bᵀQ⁻¹b
template <class B>
PWCONTACT_INLINE B inverse_quadratic_form(const Ldlt<B>& f, const B b[3]) {
  B y[3];
  forward(f, b, y);
  return y[0] * y[0] * f.inv_d0 + y[1] * y[1] * f.inv_d1 + y[2] * y[2] * f.inv_d2;
}

template <class B>
PWCONTACT_INLINE void symmetric_times(const B a[6], const B x[3], B y[3]) {
  y[0] = a[0] * x[0] + a[1] * x[1] + a[2] * x[2];
  y[1] = a[1] * x[0] + a[3] * x[1] + a[4] * x[2];
  y[2] = a[2] * x[0] + a[4] * x[1] + a[5] * x[2];
}

// The adjugate (cofactor matrix) and determinant of a symmetric Q: rᵀQ⁻¹r =
// rᵀ adj(Q) r / det Q without a division per pivot. Cancellation makes it
// unreliable for ill-conditioned Q (doc/theory.md, eq. 39): only for
// initial guesses and positive-definiteness tests, never for answers.
template <class B>
struct Adjugate {
  B c00, c01, c02, c11, c12, c22;
  B det;
  explicit Adjugate(const B a[6]) {
    c00 = a[3] * a[5] - a[4] * a[4];
    c01 = a[2] * a[4] - a[1] * a[5];
    c02 = a[1] * a[4] - a[2] * a[3];
    c11 = a[0] * a[5] - a[2] * a[2];
    c12 = a[1] * a[2] - a[0] * a[4];
    c22 = a[0] * a[3] - a[1] * a[1];
    det = a[0] * c00 + a[1] * c01 + a[2] * c02;
  }
  // rᵀ adj(Q) r
  B form(const B r[3]) const {
    return c00 * r[0] * r[0] + c11 * r[1] * r[1] + c22 * r[2] * r[2] +
           B(2) * (c01 * r[0] * r[1] + c02 * r[0] * r[2] + c12 * r[1] * r[2]);
  }
  // The magnitudes of what cancels in det: sum |a_i| C_i over the first row,
  // C_i the sum of the magnitudes of cofactor i's two products (absolute
  // values throughout: a negative a5 must not shrink it). Every cofactor
  // errs by at most gamma_2 C_i (gamma_k = k u / (1 - k u), u = eps / 2),
  // and det by at most gamma_6 this.
  static B det_magnitude(const B a[6]) {
    return a[0] * (xsimd::abs(a[3] * a[5]) + a[4] * a[4]) +
           xsimd::abs(a[1]) * (xsimd::abs(a[2] * a[4]) + xsimd::abs(a[1] * a[5])) +
           xsimd::abs(a[2]) * (xsimd::abs(a[1] * a[4]) + xsimd::abs(a[2] * a[3]));
  }
  // The same for form(r): sum C_ij |r_i| |r_j| (off-diagonal terms twice);
  // form(r) errs by at most gamma_9 this (gamma_7 by a count of its
  // roundings; doc/theory.md eq. 47 keeps the rounder bound).
  static B form_magnitude(const B a[6], const B abs_r[3]) {
    const B m00 = xsimd::abs(a[3] * a[5]) + a[4] * a[4];
    const B m11 = xsimd::abs(a[0] * a[5]) + a[2] * a[2];
    const B m22 = xsimd::abs(a[0] * a[3]) + a[1] * a[1];
    const B m01 = xsimd::abs(a[2] * a[4]) + xsimd::abs(a[1] * a[5]);
    const B m02 = xsimd::abs(a[1] * a[4]) + xsimd::abs(a[2] * a[3]);
    const B m12 = xsimd::abs(a[1] * a[2]) + xsimd::abs(a[0] * a[4]);
    return m00 * abs_r[0] * abs_r[0] + m11 * abs_r[1] * abs_r[1] + m22 * abs_r[2] * abs_r[2] +
           B(2) *
               (m01 * abs_r[0] * abs_r[1] + m02 * abs_r[0] * abs_r[2] + m12 * abs_r[1] * abs_r[2]);
  }
  // Sylvester's criterion, beyond doubt: the leading principal minors a0,
  // a0 a3 - a1^2 and det above the rounding error of what cancels in them
  // (see definiteness_margin).
  auto positive_definite(const B a[6]) const {
    using T = typename B::value_type;
    const B margin(definiteness_margin<T>);
    // Every cofactor errs by at most ~2 eps the magnitudes of its two
    // products, and det by ~5 eps det_magnitude.
    const B minor_terms = a[0] * a[3] + a[1] * a[1];
    return (a[0] > B(0)) & (c22 > margin * minor_terms) & (det > margin * det_magnitude(a));
  }
};

// The contact function as a rational function of lambda (doc/theory.md,
// eq. 46): with x = lambda and y = 1 - lambda,
//   f = x y N / D,  D = det Q(lambda) = d0 y^3 + d1 x y^2 + d2 x^2 y + d3 x^3,
//                   N = r^T adj Q(lambda) r = n0 y^2 + n1 x y + n2 x^2,
// where d0 = det Q1, d3 = det Q2, d1 = tr(adj(Q1) Q2), d2 = tr(adj(Q2) Q1),
// n0 = r^T adj(Q1) r, n2 = r^T adj(Q2) r and n1 = r^T M r, M the mixed
// adjugate of Q1 and Q2 (adj(Q1 + Q2) = adj Q1 + M + adj Q2). Every
// coefficient is positive for positive definite forms, so D and N carry no
// cancellation inside [0, 1]; the coefficients do (the cofactors'), which
// makes this form cheap and good for locating lambda* but not for answers:
// the answer is always the factorised evaluation's (eq. 38). A step costs
// ~40 operations and one division, against ~100 and four for evaluate().
template <class B>
struct ContactPolynomials {
  B d[4];
  B n[3];
  // The coefficients of D', D'', P' and P'' in the same basis (see step),
  // formed once per pair rather than at every step.
  B e[3], d2[2];  // D' = e0 y^2 + e1 x y + e2 x^2, D'' = d2_0 y + d2_1 x
  B p1, p2;       // P' = n0 y^3 + p1 x y^2 + p2 x^2 y - n2 x^3
  B q2[3];        // P'' = q2_0 y^2 + q2_1 x y + q2_2 x^2

  ContactPolynomials() = default;
  ContactPolynomials(const B r[3], const B a[6], const B b[6], const Adjugate<B>& adj_a,
                     const Adjugate<B>& adj_b) {
    d[0] = adj_a.det;
    d[3] = adj_b.det;
    d[1] = trace_of_product(adj_a, b);
    d[2] = trace_of_product(adj_b, a);
    n[0] = adj_a.form(r);
    n[2] = adj_b.form(r);
    // The mixed adjugate, entry by entry from the cofactors' formulas.
    const B m00 = a[3] * b[5] + b[3] * a[5] - B(2) * (a[4] * b[4]);
    const B m11 = a[0] * b[5] + b[0] * a[5] - B(2) * (a[2] * b[2]);
    const B m22 = a[0] * b[3] + b[0] * a[3] - B(2) * (a[1] * b[1]);
    const B m01 = a[2] * b[4] + b[2] * a[4] - a[1] * b[5] - b[1] * a[5];
    const B m02 = a[1] * b[4] + b[1] * a[4] - a[2] * b[3] - b[2] * a[3];
    const B m12 = a[1] * b[2] + b[1] * a[2] - a[0] * b[4] - b[0] * a[4];
    n[1] = m00 * r[0] * r[0] + m11 * r[1] * r[1] + m22 * r[2] * r[2] +
           B(2) * (m01 * r[0] * r[1] + m02 * r[0] * r[2] + m12 * r[1] * r[2]);
    // A step's products are of degree 18 in the length scale (h D), beyond
    // the range the unscaled lanes keep clear (degree 12, see
    // KernelTolerance<double>::safe_scale_low): D and N are brought near 1 by
    // powers of two (exact), on which the step, of degree 0 in each, does
    // not depend. The same bits whether or not the pair was nondimensionalised.
    const B d_scale = reciprocal_power_of_two(d[0] + d[3]);
    const B n_scale = reciprocal_power_of_two(n[0] + n[2]);
    for (B& c : d) c *= d_scale;
    for (B& c : n) c *= n_scale;
    // The derivatives' coefficients follow from dx/dlambda = 1 and
    // dy/dlambda = -1.
    e[0] = d[1] - B(3) * d[0];
    e[1] = B(2) * (d[2] - d[1]);
    e[2] = B(3) * d[3] - d[2];
    d2[0] = e[1] - B(2) * e[0];
    d2[1] = B(2) * e[2] - e[1];
    p1 = B(2) * n[1] - B(3) * n[0];
    p2 = B(3) * n[2] - B(2) * n[1];
    q2[0] = p1 - B(3) * n[0];
    q2[1] = B(2) * (p2 - p1);
    q2[2] = -(B(3) * n[2] + p2);
  }

  // The radial guess (eq. 30) from s1 / s2 = n0 d3 / (n2 d0) (eq. 16:
  // s_i = r^T Qi^-1 r).
  PWCONTACT_INLINE B radial_guess() const {
    return B(1) / (B(1) + xsimd::sqrt((n[0] * d[3]) / (n[2] * d[0])));
  }

  // Whichever of `lambda` and the fixed `starts` (inside (0, 1)) has the
  // largest f = x y N / D, compared without a division (D > 0):
  // f(a) > f(b) iff P(a) D(b) > P(b) D(a). For a fixed start the weights of
  // the coefficients are constants. A lane whose coefficients are not
  // finite keeps `lambda` (every comparison false).
  template <std::size_t K>
  PWCONTACT_INLINE B largest_of(const B& lambda, const double (&starts)[K]) const {
    auto values = [&](const B& x, const B& y, B& P, B& D) {
      D = denominator(x, y, x * x, y * y);
      P = numerator(x * y, x * x, y * y);
    };
    B best = lambda, best_P, best_D;
    values(lambda, B(1) - lambda, best_P, best_D);
    for (double start : starts) {
      B P, D;
      values(B(start), B(1 - start), P, D);
      const auto larger = P * best_D > best_P * D;
      best = xsimd::select(larger, B(start), best);
      best_P = xsimd::select(larger, P, best_P);
      best_D = xsimd::select(larger, D, best_D);
    }
    return best;
  }

  // One safeguarded Newton step on f' (the step of eq. 20: g = -f'), from
  // f' = h / D^2 and f'' = (k D - 2 D' h) / D^3 with P = x y N, h = P' D -
  // P D' and k = P'' D - P D'', the derivatives' coefficients formed once
  // (the constructor). Narrows [lo, hi] by the sign of h; returns how far
  // lambda moved.
  PWCONTACT_INLINE B step(B& lambda, B& lo, B& hi) const {
    const B x = lambda, y = B(1) - lambda;
    const B xx = x * x, xy = x * y, yy = y * y;
    const B D = denominator(x, y, xx, yy);
    const B D1 = e[0] * yy + e[1] * xy + e[2] * xx;
    const B D2 = d2[0] * y + d2[1] * x;
    const B P = numerator(xy, xx, yy);
    const B P1 = yy * (n[0] * y + p1 * x) + xx * (p2 * y - n[2] * x);
    const B P2 = q2[0] * yy + q2[1] * xy + q2[2] * xx;
    const B h = P1 * D - P * D1;
    const B k = P2 * D - P * D2;
    lo = xsimd::select(h > B(0), lambda, lo);
    hi = xsimd::select(h < B(0), lambda, hi);
    const B next = lambda - h * D / (k * D - B(2) * D1 * h);
    const auto newton = (lo <= next) & (next <= hi);
    const B previous = lambda;
    lambda = xsimd::select(newton, next, (lo + hi) * B(0.5));
    return xsimd::abs(lambda - previous);
  }

 private:
  // D and P = x y N of eq. 46 at x = lambda, y = 1 - lambda (xx = x^2 ...).
  PWCONTACT_INLINE B denominator(const B& x, const B& y, const B& xx, const B& yy) const {
    return yy * (d[0] * y + d[1] * x) + xx * (d[2] * y + d[3] * x);
  }
  PWCONTACT_INLINE B numerator(const B& xy, const B& xx, const B& yy) const {
    return xy * (n[0] * yy + n[1] * xy + n[2] * xx);
  }

  // 2^-e for x = m 2^e (m in [1, 2)) normal and positive, from the exponent
  // bits; 1 elsewhere (0, subnormal, infinite or NaN sums: such a lane's
  // steps are noise or NaN, and its factorised check decides).
  static B reciprocal_power_of_two(const B& x) {
    using T = typename B::value_type;
    using I = xsimd::batch<xsimd::as_integer_t<T>, typename B::arch_type>;
    constexpr int mantissa_bits = std::numeric_limits<T>::digits - 1;
    constexpr int bias = std::numeric_limits<T>::max_exponent - 1;
    const I biased = xsimd::bitwise_cast<I>(x) >> mantissa_bits;
    const B power = xsimd::bitwise_cast<B>((I(2 * bias) - biased) << mantissa_bits);
    const auto normal =
        (x >= B(std::numeric_limits<T>::min())) & (x <= B(std::numeric_limits<T>::max()));
    return xsimd::select(normal, power, B(1));
  }

  // tr(adj(Q) S) for symmetric S.
  static B trace_of_product(const Adjugate<B>& c, const B s[6]) {
    return c.c00 * s[0] + c.c11 * s[3] + c.c22 * s[5] +
           B(2) * (c.c01 * s[1] + c.c02 * s[2] + c.c12 * s[4]);
  }
};

// bᵀQ b
template <class B>
PWCONTACT_INLINE B quadratic_form(const B a[6], const B b[3]) {
  B y[3];
  symmetric_times(a, b, y);
  return b[0] * y[0] + b[1] * y[1] + b[2] * y[2];
}

template <class B>
PWCONTACT_INLINE B dot3(const B a[3], const B b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// ---------------------------------------------------------------------------
// One pair per lane, already nondimensionalised.

template <class B>
struct PairLanes {
  B r[3];
  B q1[6];
  B q2[6];
};

// Everything one evaluation at lambda computes (the reference path's copy:
// detail::evaluate, see Ldlt above). Callers use what they need;
// the rest is dead code the compiler removes after inlining.
template <class B>
struct Evaluation {
  B lambda, mu;  // lambda and 1 - lambda
  B q[6];        // Q(lambda) = mu Q1 + lambda Q2, eq. (10)
  Ldlt<B> ldlt;
  B s[3];          // Q⁻¹ r
  B a[3], b[3];    // Q1 s and Q2 s: x0 - c1 = mu a, x0 - c2 = -lambda b (eq. 9)
  B ya[3], yb[3];  // L⁻¹ a, L⁻¹ b
  B rs;            // rᵀ Q⁻¹ r
  B sa, sb;        // sᵀQ1 s, sᵀQ2 s
  B f;             // f(lambda) = lambda mu rᵀQ⁻¹r, eq. (11)
  B g;             // mu2² - mu1² = lambda² sb - mu² sa = -f'(lambda), eq. (13); increasing
  B dg;            // g'(lambda) = 2 aᵀQ⁻¹b = 2 sᵀ[mu Q2⁻¹ + lambda Q1⁻¹]⁻¹ s >= 0
};

template <class B>
PWCONTACT_INLINE Evaluation<B> evaluate(const PairLanes<B>& p, const B& lambda) {
  Evaluation<B> e;
  e.lambda = lambda;
  e.mu = B(1) - lambda;  // exact for lambda >= 1/2
  // The convex combination, never Q1 + lambda (Q2 - Q1): that would lose the
  // smaller matrix when the sizes differ by orders of magnitude.
  for (int k = 0; k < 6; ++k) e.q[k] = e.mu * p.q1[k] + lambda * p.q2[k];
  e.ldlt = factor(e.q);
  B y[3];
  forward(e.ldlt, p.r, y);
  backward(e.ldlt, y, e.s);
  e.rs = y[0] * y[0] * e.ldlt.inv_d0 + y[1] * y[1] * e.ldlt.inv_d1 + y[2] * y[2] * e.ldlt.inv_d2;
  symmetric_times(p.q1, e.s, e.a);
  symmetric_times(p.q2, e.s, e.b);
  forward(e.ldlt, e.a, e.ya);
  forward(e.ldlt, e.b, e.yb);
  e.sa = dot3(e.s, e.a);
  e.sb = dot3(e.s, e.b);
  e.f = lambda * e.mu * e.rs;
  e.g = lambda * lambda * e.sb - e.mu * e.mu * e.sa;
  e.dg = B(2) * (e.ya[0] * e.yb[0] * e.ldlt.inv_d0 + e.ya[1] * e.yb[1] * e.ldlt.inv_d1 +
                 e.ya[2] * e.yb[2] * e.ldlt.inv_d2);
  return e;
}

// The next lambda of Newton's method on g in lambda.
template <class B>
PWCONTACT_INLINE B newton_step(const Evaluation<B>& e) {
  return e.lambda - e.g / e.dg;
}

// The next lambda of Newton's method on psi = ln(mu2² / mu1²) in the log-odds
// t = ln(lambda / mu). For two spheres psi is linear in t (sa/sb is constant),
// so one step is exact from anywhere; for elongated shapes psi stays closer to
// linear than g does near the ends of [0, 1], where g has near poles.
//   dpsi/dt = 2 + 2 lambda mu [(aQ⁻¹b - aQ⁻¹a)/sa - (bQ⁻¹b - aQ⁻¹b)/sb]
// using d(sa)/dlambda = -2 aᵀQ⁻¹(b - a) and d(sb)/dlambda = -2 bᵀQ⁻¹(b - a).
// Two Padé approximants keep it free of transcendental functions and exact to
// third order at the root: ln x ~ 2 (x - 1)/(x + 1), so psi ~ 2 g / (mu1² +
// mu2²); e^dt ~ (2 + dt)/(2 - dt), which maps the log-odds step to
// lambda' = lambda (2 + dt) / (2 + dt (2 lambda - 1)). Steps are clamped to
// |dt| <= 3/2 (a factor of at most 7 on the odds); where dpsi/dt is not
// positive the plain Newton step is taken instead.
template <class B>
PWCONTACT_INLINE B log_odds_step(const Evaluation<B>& e) {
  const Ldlt<B>& l = e.ldlt;
  const B aqa =
      e.ya[0] * e.ya[0] * l.inv_d0 + e.ya[1] * e.ya[1] * l.inv_d1 + e.ya[2] * e.ya[2] * l.inv_d2;
  const B bqb =
      e.yb[0] * e.yb[0] * l.inv_d0 + e.yb[1] * e.yb[1] * l.inv_d1 + e.yb[2] * e.yb[2] * l.inv_d2;
  const B aqb = B(0.5) * e.dg;
  const B mu1 = e.mu * e.mu * e.sa, mu2 = e.lambda * e.lambda * e.sb;
  // dt = numerator / denominator with both multiplied by sa sb (mu1² + mu2²)
  const B sasb = e.sa * e.sb;
  const B slope = B(2) * sasb + B(2) * e.lambda * e.mu * ((aqb - aqa) * e.sb - (bqb - aqb) * e.sa);
  const B denominator = slope * (mu1 + mu2);
  B numerator = B(-2) * e.g * sasb;
  const B limit = B(1.5) * denominator;
  numerator = xsimd::min(xsimd::max(numerator, -limit), limit);
  const B two_d = B(2) * denominator;
  const B next = e.lambda * (two_d + numerator) / (two_d + numerator * (B(2) * e.lambda - B(1)));
  return xsimd::select(denominator > B(0), next, newton_step(e));
}

// ---------------------------------------------------------------------------
// Error-free transformations, for the refined evaluation (Accuracy::high).

// a + b = s + e exactly (Knuth's TwoSum)
template <class B>
PWCONTACT_INLINE void two_sum(const B& a, const B& b, B& s, B& e) {
  s = a + b;
  const B z = s - a;
  e = (a - (s - z)) + (b - z);
}

// a b = p + e exactly. With a fused multiply-add, written as an intrinsic
// (xsimd 8.1's fms on AVX-512 is a plain a*b - c that only the compiler's
// contraction would fuse); without one (SSE2), Dekker's product of Veltkamp
// halves, each with at most half the significand's bits, so that every
// partial product is exact (this file is compiled without FMA contraction
// there: no -mfma).
template <class B>
PWCONTACT_INLINE void two_product(const B& a, const B& b, B& p, B& e) {
  using Arch = typename B::arch_type;
  using T = typename B::value_type;
  p = a * b;
  if constexpr (is_avx512<Arch> && std::is_same<T, double>::value) {
    e = _mm512_fmsub_pd(a, b, p);
  } else if constexpr (is_avx512<Arch>) {
    e = _mm512_fmsub_ps(a, b, p);
  } else if constexpr (std::is_base_of<xsimd::fma3<xsimd::avx2>, Arch>::value) {
    e = xsimd::fms(a, b, p);  // a real vfmsub on fma3
  } else {
    const B splitter(std::is_same<T, double>::value ? T(134217729.0)
                                                    : T(4097.0));  // 2^27+1, 2^12+1
    const B ca = splitter * a, cb = splitter * b;
    const B a_hi = ca - (ca - a), b_hi = cb - (cb - b);
    const B a_lo = a - a_hi, b_lo = b - b_hi;
    e = ((a_hi * b_hi - p) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo;
  }
}

// A double-double accumulator: hi + lo
template <class B>
struct Compensated {
  B hi, lo;
  void add_product(const B& a, const B& b) {
    B p, pe, s, se;
    two_product(a, b, p, pe);
    two_sum(hi, p, s, se);
    hi = s;
    lo += pe + se;
  }
  B value() const { return hi + lo; }
};

// f at lambda to nearly full precision whatever the conditioning of Q: one
// step of iterative refinement of s = Q⁻¹r with the residual
// r - (mu Q1 s + lambda Q2 s) accumulated error-free from the exact inputs
// (not from the rounded Q(lambda)), then rᵀs accumulated error-free. Takes
// copies (a cold call must not make the caller's registers escape to memory)
// and returns f and the refined s.
// With the refined s also g = lambda^2 s^T Q2 s - mu^2 s^T Q1 s (eq. 13)
// again, its forms accumulated error-free as well: from the rounded s, or
// in plain double from the refined one, its noise is ~eps cond f / w,
// which the convergence test's gain and bound would otherwise take at face
// value.
template <class B>
struct Refined {
  B f;
  B s[3];
  B g;
};

template <class B>
PWCONTACT_COLD Refined<B> refined_f(const PairLanes<B> p, const Ldlt<B> ldlt, const B lambda,
                                    const B mu, Refined<B> current) {
  B residual[3];
  const B minus_mu = -mu, minus_lambda = -lambda;
  static constexpr int row[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  for (int i = 0; i < 3; ++i) {
    Compensated<B> acc{p.r[i], B(0)};
    for (int j = 0; j < 3; ++j) {
      // -mu Q1 and -lambda Q2 entries split exactly into a rounded part and
      // its error; the errors' products with s are second order.
      B m1, m1e, m2, m2e;
      two_product(minus_mu, p.q1[row[i][j]], m1, m1e);
      two_product(minus_lambda, p.q2[row[i][j]], m2, m2e);
      acc.add_product(m1, current.s[j]);
      acc.add_product(m2, current.s[j]);
      acc.lo += (m1e + m2e) * current.s[j];
    }
    residual[i] = acc.value();
  }
  B y[3], correction[3];
  forward(ldlt, residual, y);
  backward(ldlt, y, correction);
  // r^T s as r^T s + r^T correction, both accumulated, before s + correction
  // is rounded: where r is nearly orthogonal to s (r^T s << |r| |s|, ill-
  // conditioned Q), that rounding alone cost f ~eps |r| |s| / r^T s.
  Compensated<B> rs{B(0), B(0)};
  for (int i = 0; i < 3; ++i) rs.add_product(p.r[i], current.s[i]);
  for (int i = 0; i < 3; ++i) rs.add_product(p.r[i], correction[i]);
  for (int i = 0; i < 3; ++i) current.s[i] += correction[i];
  current.f = lambda * mu * rs.value();
  // g from the refined s in the same arithmetic: its two terms are each
  // ~f / w (w = min(lambda, mu)) and cancel at lambda*, and s^T Q s taken in
  // double errs by ~eps cond(Q) of itself, so that g computed plainly from
  // even an exact s is off by ~eps cond f / w (1e-5 f at cond 2e8 and
  // lambda* 1.5e-3 from 0): lanes 8e-9 from lambda* passed the convergence
  // test with mu^2 3.5 times beyond Accuracy::high's bound, status ok.
  // (Six terms: the off-diagonal ones doubled, exactly.)
  auto form = [&current](const B* q) {
    Compensated<B> acc{B(0), B(0)};
    for (int i = 0; i < 3; ++i)
      for (int j = i; j < 3; ++j) {
        B product, error;
        two_product(q[row[i][j]], current.s[j], product, error);
        if (j != i) product = product + product, error = error + error;
        acc.add_product(current.s[i], product);
        acc.lo += current.s[i] * error;
      }
    return acc;
  };
  const Compensated<B> form1 = form(p.q1), form2 = form(p.q2);
  B lambda2, lambda2e, mu2, mu2e;
  two_product(lambda, lambda, lambda2, lambda2e);
  two_product(mu, mu, mu2, mu2e);
  Compensated<B> g{B(0), B(0)};  // lambda^2 s^T Q2 s - mu^2 s^T Q1 s (eq. 13)
  g.add_product(lambda2, form2.hi);
  g.lo += lambda2 * form2.lo + lambda2e * form2.hi;
  g.add_product(-mu2, form1.hi);
  g.lo -= mu2 * form1.lo + mu2e * form1.hi;
  current.g = g.value();
  return current;
}

// ---------------------------------------------------------------------------
// Moving lanes between double and float registers of the same instruction
// set: a float register holds the lanes of two double registers.

template <class Arch>
PWCONTACT_INLINE xsimd::batch<float, Arch> narrow(const xsimd::batch<double, Arch>& lo,
                                                  const xsimd::batch<double, Arch>& hi) {
  if constexpr (is_avx512<Arch>) {
    const __m512 low = _mm512_castps256_ps512(_mm512_cvtpd_ps(lo));
    return _mm512_insertf32x8(low, _mm512_cvtpd_ps(hi), 1);
  } else if constexpr (std::is_base_of<xsimd::avx, Arch>::value) {
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm256_cvtpd_ps(lo)), _mm256_cvtpd_ps(hi),
                                1);
  } else {
    return _mm_movelh_ps(_mm_cvtpd_ps(lo), _mm_cvtpd_ps(hi));
  }
}

template <class Arch>
PWCONTACT_INLINE void widen(const xsimd::batch<float, Arch>& x, xsimd::batch<double, Arch>& lo,
                            xsimd::batch<double, Arch>& hi) {
  if constexpr (is_avx512<Arch>) {
    lo = _mm512_cvtps_pd(_mm512_castps512_ps256(x));
    hi = _mm512_cvtps_pd(_mm512_extractf32x8_ps(x, 1));
  } else if constexpr (std::is_base_of<xsimd::avx, Arch>::value) {
    lo = _mm256_cvtps_pd(_mm256_castps256_ps128(x));
    hi = _mm256_cvtps_pd(_mm256_extractf128_ps(x, 1));
  } else {
    lo = _mm_cvtps_pd(x);
    hi = _mm_cvtps_pd(_mm_movehl_ps(x, x));
  }
}

}  // namespace pwcontact::kernels::PWCONTACT_TARGET
