// The batch kernel: the contact function of many pairs at once, one pair per
// SIMD lane, with a fixed number of safeguarded Newton iterations.
//
// This body is written once and compiled once per instruction set, each time
// in its own translation unit with its own flags (contact_sse2.cpp, ...).
// Every function here is a template on the xsimd architecture tag, so the
// copies compiled with different flags are distinct symbols and none can
// replace another at link time. Nothing here calls into non-template inline
// code of the library or the standard library for the same reason.
//
// The mathematics is the reference path's (include/pwcontact/reference.hpp),
// written branch-free: lanes step together and diverge only through select.
// Equation numbers refer to shared/seed/theory.txt.
#pragma once

#include <xsimd/xsimd.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "kernels/kernel_api.hpp"

// The loops over the U interleaved groups must be unrolled: only then do the
// groups' instructions mix and their state live in registers.
#define PWCONTACT_UNROLL _Pragma("GCC unroll 4")

namespace pwcontact::kernels {

template <class T>
struct KernelTolerance;
// A lane is accepted when the gain in mu^2 that one more Newton step would
// bring, g^2 / (2 g'), is below a few units in the last place of f.
// Inputs whose largest diagonal entry lies in [safe_scale_low, safe_scale_high]
// are solved as they are; others are first rescaled (see solve_groups).
template <>
struct KernelTolerance<double> {
  static constexpr double predicted_gain = 4 * std::numeric_limits<double>::epsilon();
  static constexpr double safe_scale_low = 0x1p-300, safe_scale_high = 0x1p300;
  // A double lane that is ill-conditioned would gain nothing from the
  // fallback, which runs in double too.
  static constexpr bool checks_growth = false;
};
template <>
struct KernelTolerance<float> {
  static constexpr float predicted_gain = 4 * std::numeric_limits<float>::epsilon();
  static constexpr float safe_scale_low = 0x1p-36f, safe_scale_high = 0x1p36f;
  // A float lane whose factorisation shows element growth above this is
  // recomputed in double: beyond it float can lose more than ~1e-5 (measured
  // on the pw85 and log-uniform families; random pairs with semi-axes in
  // [0.5, 2] stay below 6).
  static constexpr bool checks_growth = true;
  static constexpr float max_growth = 16;
};

// Q = L D L^T of a symmetric 3x3 matrix (6 numbers, eq. 3), with the
// reciprocal pivots kept since every solve divides by them.
template <class B>
struct BatchLdlt {
  B inv_d0, inv_d1, inv_d2;
  B l10, l20, l21;
  B d0, d1, d2;
};

template <class B>
inline BatchLdlt<B> factor(const B a[6]) {
  BatchLdlt<B> f;
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

// y = L^-1 b
template <class B>
inline void forward(const BatchLdlt<B>& f, const B b[3], B y[3]) {
  y[0] = b[0];
  y[1] = b[1] - f.l10 * y[0];
  y[2] = b[2] - f.l20 * y[0] - f.l21 * y[1];
}

// b^T Q^-1 b = sum y_i^2 / d_i, a sum of positive terms
template <class B>
inline B inverse_quadratic_form(const BatchLdlt<B>& f, const B b[3]) {
  B y[3];
  forward(f, b, y);
  return y[0] * y[0] * f.inv_d0 + y[1] * y[1] * f.inv_d1 + y[2] * y[2] * f.inv_d2;
}

template <class B>
inline void symmetric_times(const B a[6], const B x[3], B y[3]) {
  y[0] = a[0] * x[0] + a[1] * x[1] + a[2] * x[2];
  y[1] = a[1] * x[0] + a[3] * x[1] + a[4] * x[2];
  y[2] = a[2] * x[0] + a[4] * x[1] + a[5] * x[2];
}

template <class B>
inline B dot3(const B a[3], const B b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

template <class B>
struct BatchResidual {
  B f;   // f(lambda), eq. (11)
  B g;   // mu2^2 - mu1^2 = -f'(lambda), eq. (13)
  B dg;  // g'(lambda) >= 0
  B growth;  // element growth of the factorisation, only when asked for
};

// Same formulas as detail::evaluate in the reference path; see there.
// With `growth`, also the largest ratio of the magnitudes that cancel in a
// pivot to the pivot itself: the factor by which rounding errors in Q(lambda)
// are amplified in r^T Q^-1 r (measured: relative error of f below
// ~100 growth eps, p99 ~3 growth eps).
template <bool growth, class B>
inline BatchResidual<B> evaluate(const B r[3], const B q1[6], const B q2[6], const B& lambda) {
  const B mu = B(1) - lambda;
  B q[6];
  for (int k = 0; k < 6; ++k) q[k] = mu * q1[k] + lambda * q2[k];  // eq. (10)
  const BatchLdlt<B> ldlt = factor(q);

  B y[3], s[3];
  forward(ldlt, r, y);
  const B z0 = y[0] * ldlt.inv_d0, z1 = y[1] * ldlt.inv_d1, z2 = y[2] * ldlt.inv_d2;
  s[2] = z2;  // s = L^-T z = Q^-1 r
  s[1] = z1 - ldlt.l21 * s[2];
  s[0] = z0 - ldlt.l10 * s[1] - ldlt.l20 * s[2];
  const B rs = y[0] * z0 + y[1] * z1 + y[2] * z2;

  B a[3], b[3], ya[3], yb[3];
  symmetric_times(q1, s, a);
  symmetric_times(q2, s, b);
  forward(ldlt, a, ya);
  forward(ldlt, b, yb);

  BatchResidual<B> out;
  out.f = lambda * mu * rs;
  out.g = lambda * lambda * dot3(s, b) - mu * mu * dot3(s, a);
  out.dg = B(2) * (ya[0] * yb[0] * ldlt.inv_d0 + ya[1] * yb[1] * ldlt.inv_d1 +
                   ya[2] * yb[2] * ldlt.inv_d2);
  if constexpr (growth) {
    // d1 = q3 - l10 q1 and d2 = q5 - l20 q2 - l21 t with t = l21 d1.
    const B g1 = (q[3] + xsimd::abs(ldlt.l10 * q[1])) * ldlt.inv_d1;
    const B g2 = (q[5] + xsimd::abs(ldlt.l20 * q[2]) + ldlt.l21 * ldlt.l21 * ldlt.d1) * ldlt.inv_d2;
    out.growth = xsimd::max(g1, g2);
  }
  return out;
}

// U independent SIMD groups solved side by side: one group's Newton step is a
// long chain of dependent divisions and multiply-adds, so interleaving groups
// keeps the floating-point units busy while each chain waits.
template <class Arch, class T, int U>
inline void solve_groups(const PairSpan<T>& in, const ResultSpan<T>& out, std::size_t first,
                         int iterations) {
  using B = xsimd::batch<T, Arch>;
  using M = xsimd::batch_bool<T, Arch>;
  constexpr std::size_t W = B::size;
  const B zero(T(0)), one(T(1)), half(T(0.5));
  const B nan(std::numeric_limits<T>::quiet_NaN());
  const B tol(KernelTolerance<T>::predicted_gain);

  B r[U][3], q1[U][6], q2[U][6];
  B lambda[U], lo[U], hi[U];
  M finite[U], pd1[U], pd2[U], coincident[U];
  B lambda_coincident[U];

  PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
    const std::size_t i = first + std::size_t(u) * W;
    for (int k = 0; k < 3; ++k) r[u][k] = B::load_unaligned(in.r12[k] + i);
    for (int k = 0; k < 6; ++k) {
      q1[u][k] = B::load_unaligned(in.q1[k] + i);
      q2[u][k] = B::load_unaligned(in.q2[k] + i);
    }

    // The sum of the inputs is finite when they all are (a NaN or an infinity
    // makes it NaN or infinite), and only rarely otherwise (overflow): a lane
    // that fails this cheap test goes to the reference path, which decides.
    B sum = r[u][0] + r[u][1] + r[u][2];
    for (int k = 0; k < 6; ++k) sum += q1[u][k] + q2[u][k];
    finite[u] = (sum - sum) == zero;

    // Nondimensionalise by a power of two (exact): r -> r t, Q -> Q t^2, with
    // t = 1 / 2^floor(log2 sqrt(max diagonal)); mu^2 is invariant. Only needed
    // when some lane's scale is far from 1, where products of entries could
    // overflow or underflow; the scaling is exact, so skipping it elsewhere
    // changes no result.
    const B largest = xsimd::max(xsimd::max(xsimd::max(q1[u][0], q1[u][3]), q1[u][5]),
                                 xsimd::max(xsimd::max(q2[u][0], q2[u][3]), q2[u][5]));
    const B safe_low(KernelTolerance<T>::safe_scale_low), safe_high(KernelTolerance<T>::safe_scale_high);
    if (!xsimd::all((largest >= safe_low) & (largest <= safe_high))) {
      const B infinity(std::numeric_limits<T>::infinity());
      const B power = xsimd::bitwise_and(xsimd::sqrt(largest), infinity);  // exponent bits only
      const B t = xsimd::select((power > zero) & (power < infinity), one / power, one);
      const B t2 = t * t;
      for (int k = 0; k < 3; ++k) r[u][k] *= t;
      for (int k = 0; k < 6; ++k) {
        q1[u][k] *= t2;
        q2[u][k] *= t2;
      }
    }

    const BatchLdlt<B> f1 = factor(q1[u]), f2 = factor(q2[u]);
    pd1[u] = (f1.d0 > zero) & (f1.d1 > zero) & (f1.d2 > zero);
    pd2[u] = (f2.d0 > zero) & (f2.d1 > zero) & (f2.d2 > zero);

    // Initial guess exact for spheres: lambda = rho1 / (rho1 + rho2), rho_i the
    // distance from centre i to its surface along r12 (see the reference path).
    const B slope0 = inverse_quadratic_form(f1, r[u]);  // f'(0)
    const B slope1 = inverse_quadratic_form(f2, r[u]);  // -f'(1)
    const B w1 = xsimd::sqrt(slope1), w2 = xsimd::sqrt(slope0);
    lambda[u] = w1 / (w1 + w2);
    lo[u] = zero;
    hi[u] = one;

    // Coincident centres: mu^2 = 0, lambda from the traces (as the reference).
    coincident[u] = !((slope0 > zero) & (slope1 > zero));
    lambda_coincident[u] = nan;
    if (xsimd::any(coincident[u])) {
      const B tr1 = xsimd::sqrt(q1[u][0] + q1[u][3] + q1[u][5]);
      const B tr2 = xsimd::sqrt(q2[u][0] + q2[u][3] + q2[u][5]);
      lambda_coincident[u] = tr1 / (tr1 + tr2);
    }
  }

  // iterations >= 1 (checked by the driver); initialised for the compiler's sake.
  BatchResidual<B> last[U];
  M newton[U];
  PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
    last[u] = {nan, nan, nan, nan};
    newton[u] = zero != zero;
  }
  for (int it = 0; it < iterations; ++it) {
    const bool final = it + 1 == iterations;
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      last[u] = final && KernelTolerance<T>::checks_growth
                    ? evaluate<true>(r[u], q1[u], q2[u], lambda[u])
                    : evaluate<false>(r[u], q1[u], q2[u], lambda[u]);
      hi[u] = xsimd::select(last[u].g > zero, lambda[u], hi[u]);
      lo[u] = xsimd::select(last[u].g < zero, lambda[u], lo[u]);
      const B next = lambda[u] - last[u].g / last[u].dg;
      newton[u] = (lo[u] <= next) & (next <= hi[u]);  // inclusive safeguard
      lambda[u] = xsimd::select(newton[u], next, (lo[u] + hi[u]) * half);
    }
  }

  PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
    const std::size_t i = first + std::size_t(u) * W;
    const BatchResidual<B>& res = last[u];
    // Convergence check: the predicted gain of one more Newton step,
    // g^2 / (2 g'), is below tolerance, and either the last Newton step stayed
    // in the bracket (the quadratic model holds) or the rigorous concavity
    // bound mu^2 - f <= |g| (hi - lo) is below tolerance too.
    const B bound = tol * res.f;
    M converged = (res.dg > zero) & (half * res.g * res.g <= bound * res.dg) &
                  (newton[u] | (xsimd::abs(res.g) * (hi[u] - lo[u]) <= bound));
    if constexpr (KernelTolerance<T>::checks_growth)
      converged = converged & (res.growth <= B(KernelTolerance<T>::max_growth));
    // Everything else, invalid input included, is the reference path's to
    // answer: it validates the input and assigns the exact status.
    const M accepted = finite[u] & pd1[u] & pd2[u] & (converged | coincident[u]);
    xsimd::select(coincident[u], zero, res.f).store_unaligned(out.mu2 + i);
    if (out.lambda)
      xsimd::select(coincident[u], lambda_coincident[u], lambda[u]).store_unaligned(out.lambda + i);
    bool lanes[W];
    accepted.store_unaligned(lanes);
    for (std::size_t l = 0; l < W; ++l) out.status[i + l] = lanes[l] ? Status::ok : needs_fallback;
  }
}

// Groups interleaved per instruction set, by measurement (1M random pairs,
// one thread): AVX-512's 32 registers hold three groups' state (U = 3 is
// 3-4 % faster than 2, U = 1 is 12 % slower); with 16 registers, two.
template <class Arch>
inline constexpr int interleaved_groups = std::is_base_of<xsimd::avx512f, Arch>::value ? 3 : 2;

// The whole span in blocks of U groups, the last block padded into a local
// buffer so that nothing is read or written past n. Every pair goes through
// the same instantiation: the compiler may fuse multiply-adds differently in
// differently shaped code, and a pair's result must not depend on where it
// sits in the batch.
template <class Arch, class T>
void solve_span(const PairSpan<T>& in, const ResultSpan<T>& out, std::size_t n, int iterations) {
  constexpr int U = interleaved_groups<Arch>;
  constexpr std::size_t block = U * xsimd::batch<T, Arch>::size;
  std::size_t i = 0;
  for (; i + block <= n; i += block) solve_groups<Arch, T, U>(in, out, i, iterations);
  if (i == n) return;

  // The missing lanes repeat the first pair of the tail, so they hold a valid
  // problem and cost nothing special.
  const std::size_t rest = n - i;
  alignas(64) T buffer[15][block];
  alignas(64) T mu2[block], lambda[block];
  Status status[block];
  PairSpan<T> padded;
  for (int k = 0; k < 15; ++k) {
    const T* source = k < 3 ? in.r12[k] : k < 9 ? in.q1[k - 3] : in.q2[k - 9];
    for (std::size_t l = 0; l < block; ++l) buffer[k][l] = source[i + (l < rest ? l : 0)];
    if (k < 3) padded.r12[k] = buffer[k];
    else if (k < 9) padded.q1[k - 3] = buffer[k];
    else padded.q2[k - 9] = buffer[k];
  }
  const ResultSpan<T> local{mu2, out.lambda ? lambda : nullptr, status};
  solve_groups<Arch, T, U>(padded, local, 0, iterations);
  for (std::size_t l = 0; l < rest; ++l) {
    out.mu2[i + l] = mu2[l];
    if (out.lambda) out.lambda[i + l] = lambda[l];
    out.status[i + l] = status[l];
  }
}

}  // namespace pwcontact::kernels

// Defines the KernelTable of one instruction set; used once in each per-ISA file.
#define PWCONTACT_DEFINE_KERNEL_TABLE(table, arch, label)                                  \
  namespace pwcontact::kernels {                                                          \
  namespace {                                                                             \
  void solve_double_##table(const PairSpan<double>& in, const ResultSpan<double>& out,   \
                            std::size_t n, int iterations) {                              \
    solve_span<arch, double>(in, out, n, iterations);                                     \
  }                                                                                       \
  void solve_float_##table(const PairSpan<float>& in, const ResultSpan<float>& out,      \
                           std::size_t n, int iterations) {                               \
    solve_span<arch, float>(in, out, n, iterations);                                      \
  }                                                                                       \
  }                                                                                       \
  const KernelTable kernel_table_##table = {                                             \
      label, int(xsimd::batch<double, arch>::size), int(xsimd::batch<float, arch>::size), \
      &solve_double_##table, &solve_float_##table};                                       \
  }
