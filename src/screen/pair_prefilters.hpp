// The decisions about a near pair that need no solve, shared by the
// screening (screen.cpp) and the moving scene (moving_scene.cpp): pairs of spheres
// and pairs of one form in closed form, overlapping by the inscribed
// spheres, apart by the projections on the line of centres; and the overlap
// certificates in scalar arithmetic, for the moving scene's few pairs.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "pwcontact/reference.hpp"

namespace pwcontact::screen {

// One side of a candidate pair: its particle index, radii and form (six
// contiguous numbers).
struct Side {
  std::uint32_t index;
  double bounding, inscribed, sphere;
  const double* q;
};

// Whether two particles have the same form Q (the same shape and
// orientation) that is well enough conditioned for the closed form below:
// bounding over inscribed radius at most 100, so cond(Q) <= 1e4 and
// r^T Q^-1 r by L D L^T within 1e4 * a few eps (1e-11) relatively.
inline bool same_moderate_form(const Side& p, const Side& o) {
  for (int k = 0; k < 6; ++k)
    if (p.q[k] != o.q[k]) return false;
  return p.bounding <= 100 * p.inscribed;
}

// r^T Q r for the form q (eq. 3's six numbers).
inline double form_value(const double q[6], const double r[3]) {
  double qr[3];
  detail::symmetric_times(q, r, qr);
  return detail::dot3(r, qr);
}

// Apart when the projections of the two ellipsoids scaled by the cutoff on
// the line of centres do not overlap (a separating plane normal to r): the
// support of ellipsoid Q in the direction r / |r| is sqrt(r^T Q r) / |r|, so
// |r| >= cutoff (h_p + h_o) reads rr >= cutoff (sqrt(r^T Q_p r) +
// sqrt(r^T Q_o r)). Tighter than the bounding spheres for elongated shapes.
// r^T Q r, a sum of nine products, errs by at most about 6 eps times the sum
// of their magnitudes, and |q_ij| <= max q_ii <= R^2 makes that sum at most
// 3 R^2 rr: 18 eps R^2 rr in the worst case. 64 eps R^2 rr is added before
// the square roots, so the test stays on the safe side.
// That bound is relative, and r^T Q r is of the fourth power of the lengths:
// for particles of about 1e-77 and less its products fall below the normal
// range, each then off by up to 2^-1075 absolutely, and at 1e-81 they are 0,
// which made every such pair "apart". So the test decides nothing when the
// margin is below 2^-1000 (lengths below about 1e-72): its 46 eps R^2 rr of
// slack then exceeds the nine products' underflow (for |r| below 2^70 R)
// and such pairs are left to the solve, which scales each pair by a power
// of two.
inline bool apart_by_projections(const Side& p, const Side& o, const double r[3], double rr,
                                 double cutoff) {
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const double margin_p = 64 * eps * p.bounding * p.bounding * rr;
  const double margin_o = 64 * eps * o.bounding * o.bounding * rr;
  constexpr double smallest_margin = 0x1p-1000;
  if (!(margin_p >= smallest_margin && margin_o >= smallest_margin)) return false;
  const double sp = form_value(p.q, r) + margin_p;
  const double so = form_value(o.q, r) + margin_o;
  // Coincident centres (rr = 0, both sides 0) are the most overlapping pair.
  return rr > 0 && rr >= cutoff * (std::sqrt(sp) + std::sqrt(so)) * (1 + 4 * eps);
}

// Squares of lengths near the subnormal numbers keep only a few digits
// (each product errs by up to 2^-1075 absolutely). The tests that call a
// pair apart from squared distances (the bounding spheres in the screen,
// the moving scene and the neighbour list's kept steps; the coarse kernels
// let as much through) compare with an absolute slack, |r|^2 >= limit^2 +
// square_slack, which changes nothing where the squares are normal and
// decides nothing where they are not; the cell search's coarse test is
// left out for a particle whose reach squared is below closed_form_low.
// The closed forms below take |r|^2 and r^T Q^-1 r as they are only within
// [closed_form_low, closed_form_high]: beyond (sizes below ~1e-145 or above
// ~1e145) they take the pair scaled by a power of two first, exactly, as
// the solve's paths scale it.
inline constexpr double square_slack = 0x1p-1000;
inline constexpr double closed_form_low = 0x1p-960, closed_form_high = 0x1p960;

inline bool closed_form_in_range(double x) { return x >= closed_form_low && x <= closed_form_high; }

// Two spheres of radii summing to `sum` (mu = |r| / sum): rr / sum^2, or
// the same of r and sum scaled by 2^-e, sum = m 2^e (m in [1/2, 1)).
inline double spheres_mu2(const double r[3], double rr, double sum) {
  if (closed_form_in_range(rr) && closed_form_in_range(sum * sum)) return rr / (sum * sum);
  int e = 0;
  const double m = std::frexp(sum, &e);
  double x[3];
  for (int k = 0; k < 3; ++k) x[k] = std::ldexp(r[k], -e);
  return detail::dot3(x, x) / (m * m);
}

// One form Q for both (eq. 11 at lambda = 1/2): r^T Q^-1 r / 4, or the same
// of r and Q scaled by 2^-e and 2^-2e, Q's largest diagonal entry m 2^2e.
inline double same_form_mu2(const double q[6], const double r[3], double rr) {
  const double largest = std::max({q[0], q[3], q[5]});
  if (closed_form_in_range(rr) && closed_form_in_range(largest))
    return detail::inverse_quadratic_form(detail::Ldlt3<double>(q), r) / 4;
  int e = 0;
  std::frexp(std::sqrt(largest), &e);
  double x[3], scaled[6];
  for (int k = 0; k < 3; ++k) x[k] = std::ldexp(r[k], -e);
  for (int k = 0; k < 6; ++k) scaled[k] = std::ldexp(q[k], -2 * e);
  return detail::inverse_quadratic_form(detail::Ldlt3<double>(scaled), x) / 4;
}

// What the prefilters say of a pair the bounding spheres left.
enum class NearPair : std::uint8_t {
  spheres,            // two spheres: mu2 in closed form
  same_form,          // one form Q: mu2 in closed form
  in,                 // mu < cutoff by the inscribed spheres (no mu2)
  out_by_projection,  // apart by a separating plane normal to r
  undecided,          // to be solved
};

// The pair (p, o) with r = c_o - c_p and rr = |r|^2; mu2 is set for
// spheres and same_form. The inscribed spheres are not used when with_mu2
// (they give no mu^2).
inline NearPair decide_near_pair(const Side& p, const Side& o, const double r[3], double rr,
                                 double cutoff, bool with_mu2, double& mu2) {
  if (p.sphere > 0 && o.sphere > 0) {
    // Two spheres: mu = |r| / (a_i + a_j) (Q(lambda) is then a multiple of
    // I), to a few roundings.
    mu2 = spheres_mu2(r, rr, p.sphere + o.sphere);
    return NearPair::spheres;
  }
  if (same_moderate_form(p, o)) {
    // Q1 = Q2 = Q: Q(lambda) = Q in eq. (10), so f(lambda) = lambda (1 -
    // lambda) r^T Q^-1 r by eq. (11), largest at lambda = 1/2 (eq. 6). A scene
    // of identical, aligned ellipsoids is an affine image of one of spheres.
    mu2 = same_form_mu2(p.q, r, rr);
    return NearPair::same_form;
  }
  // (Where inner^2 or rr is subnormal, their few digits could decide a
  // pair wrongly near the inscribed spheres' touch: left to the solve.)
  const double inner = cutoff * (p.inscribed + o.inscribed);
  if (!with_mu2 && rr < inner * inner && inner * inner >= closed_form_low) return NearPair::in;
  if (apart_by_projections(p, o, r, rr, cutoff)) return NearPair::out_by_projection;
  return NearPair::undecided;
}

// What the certificates of an overlap answer decide of one pair in a few
// scalar evaluations, before any kernel (doc/theory.md, "The overlap
// decision"): a trial move's few undecided candidates cost a kernel call
// each time, several hundred nanoseconds of fixed cost for one or two
// pairs, where most pairs are decided by the first bounds.
enum class Certified : std::uint8_t { overlapping, apart, undecided };

// Evaluations certify_overlap takes before it leaves a pair to the kernels,
// by measurement on the trials of pwcontact_moves' single queries (1M
// spheroids at packing 0.5, a harness repeating them): the radial extents
// alone +13 %, with 1 evaluation +43 %, 2 +58 %, 3 no more than 2.
inline constexpr int certificate_evaluations = 2;

// The range the certificates' arithmetic keeps to: pivots (and so every
// quantity of degree -2 in the length scale) at least this, and the
// numbers of degree 0 (sigma, f, g) within [floor, 1 / floor]. Far from
// underflow and overflow, so that the rounding errors are the relative ones
// eq. 40's margins count.
inline constexpr double certificate_floor = 0x1p-500;

// The growth beyond which the margin (256 eps growth, 2^-4 here) leaves the
// bounds too wide to decide anything worth the evaluations.
inline constexpr double certificate_growth_cap = 0x1p40;

namespace certificate {

// Q = L D L^T with the reciprocal pivots kept, and one evaluation at lambda:
// the kernels' arithmetic (simd_math.hpp's factor, backward and evaluate,
// which multiply by 1/d_i where the reference path divides by d_i) in
// scalars (tests/shared_math_test.cpp holds the copies together bit for
// bit), three divisions per factorisation and none in the solves: the
// certificates' share of a query is mostly divisions.
struct Factors {
  double d0, d1, d2, inv_d0, inv_d1, inv_d2, l10, l20, l21;
  explicit Factors(const double a[6]) {
    d0 = a[0];
    inv_d0 = 1 / d0;
    l10 = a[1] * inv_d0;
    l20 = a[2] * inv_d0;
    d1 = a[3] - l10 * a[1];
    inv_d1 = 1 / d1;
    const double t = a[4] - l20 * a[1];
    l21 = t * inv_d1;
    d2 = a[5] - l20 * a[2] - l21 * t;
    inv_d2 = 1 / d2;
  }
  // y = L^-1 b
  void forward(const double b[3], double y[3]) const {
    y[0] = b[0];
    y[1] = b[1] - l10 * y[0];
    y[2] = b[2] - l20 * y[0] - l21 * y[1];
  }
  // x = L^-T D^-1 y, i.e. x = Q^-1 b for y = L^-1 b
  void backward(const double y[3], double x[3]) const {
    x[2] = y[2] * inv_d2;
    x[1] = y[1] * inv_d1 - l21 * x[2];
    x[0] = y[0] * inv_d0 - l10 * x[1] - l20 * x[2];
  }
  // sum y_i^2 / d_i = b^T Q^-1 b for y = L^-1 b
  double inverse_form_of(const double y[3]) const {
    return y[0] * y[0] * inv_d0 + y[1] * y[1] * inv_d1 + y[2] * y[2] * inv_d2;
  }
  // The element growth of Q (eq. 40) when the factors are usable by the
  // certificates: every pivot at least certificate_floor and the growth at
  // most the cap; 0 otherwise. The growth is the largest ratio of the
  // magnitudes that cancel in a pivot to the pivot, taken from the factors
  // alone (q3 + |l10 q1| = d1 + 2 l10^2 d0, and q5 + |l20 q2| + l21^2 d1 =
  // d2 + 2 l20^2 d0 + 2 l21^2 d1, for a positive definite Q; the kernels'
  // growth() in simd_math.hpp takes it from the form's entries). The
  // relative rounding errors of the pivots, and with them of r^T Q^-1 r and
  // f, are O(eps growth).
  double usable_growth() const {
    if (!(d0 >= certificate_floor && d1 >= certificate_floor && d2 >= certificate_floor)) return 0;
    const double g1 = 1 + 2 * l10 * l10 * d0 * inv_d1;
    const double g2 = 1 + 2 * (l20 * l20 * d0 + l21 * l21 * d1) * inv_d2;
    const double growth = g1 > g2 ? g1 : g2;
    return growth <= certificate_growth_cap ? growth : 0;
  }
};

// f, g = -f' and g' at lambda (eqs. 11, 13 and 16), with Q(lambda)'s growth
// (0: not usable).
struct Evaluation {
  double f, g, dg, growth;
};

inline Evaluation evaluate(const double r[3], const double q1[6], const double q2[6],
                           double lambda) {
  const double mu = 1 - lambda;
  double q[6];
  for (int k = 0; k < 6; ++k) q[k] = mu * q1[k] + lambda * q2[k];  // eq. 10
  const Factors l(q);
  Evaluation e;
  e.growth = l.usable_growth();
  double y[3], s[3];
  l.forward(r, y);
  l.backward(y, s);
  double a[3], b[3], ya[3], yb[3];
  detail::symmetric_times(q1, s, a);
  detail::symmetric_times(q2, s, b);
  l.forward(a, ya);
  l.forward(b, yb);
  e.f = lambda * mu * l.inverse_form_of(y);
  e.g = lambda * lambda * detail::dot3(s, b) - mu * mu * detail::dot3(s, a);
  e.dg = 2 * (ya[0] * yb[0] * l.inv_d0 + ya[1] * yb[1] * l.inv_d1 + ya[2] * yb[2] * l.inv_d2);
  return e;
}

// The power of two t with t^2 m in [1, 4), for a positive normal m, from m's
// exponent bits (m = 1.f 2^E: t = 2^-floor(E/2)); 0 for a subnormal m.
inline double scale_to_unit(double m) {
  std::uint64_t bits;
  std::memcpy(&bits, &m, sizeof bits);
  const int biased = int(bits >> 52) & 0x7ff;
  if (biased == 0) return 0;
  const int e = biased - 1023;
  const int k = -(e >= 0 ? e / 2 : -((1 - e) / 2));  // -floor(e / 2)
  const std::uint64_t t_bits = std::uint64_t(k + 1023) << 52;
  double t;
  std::memcpy(&t, &t_bits, sizeof t);
  return t;
}

}  // namespace certificate

// Whether mu^2 < cutoff2 for the pair (r = c2 - c1, forms q1, q2), decided
// by the bounds the overlap kernels keep, each with the margin of eq. 40:
// m = 256 eps times the largest element growth of Q1, Q2 and every Q(lambda)
// evaluated (the kernels' margin, measured against errors of at most
// ~100 growth eps). From above, the radial extents (eq. 31) and then the
// tangents at the bracket ends (eq. 29); from below, f(lambda) (eq. 27);
// decided as eq. 45 decides. Between the bounds, safeguarded Newton steps
// from the guess that is exact for spheres. The pair is first scaled by a
// power of two (exactly; mu^2 does not change) so that the largest diagonal
// entry of the forms is in [1, 4), as the kernels nondimensionalise.
// Undecided: bounds that have not cleared the cutoff after `evaluations`
// evaluations, or a pair whose arithmetic would leave the range above
// (certificate_floor, the growth cap); the kernels and the reference path
// decide those.
inline Certified certify_overlap(const double r12[3], const double q1_given[6],
                                 const double q2_given[6], double cutoff2,
                                 int evaluations = certificate_evaluations) {
  constexpr double margin_per_growth = 256 * std::numeric_limits<double>::epsilon();
  const double largest =
      std::max({q1_given[0], q1_given[3], q1_given[5], q2_given[0], q2_given[3], q2_given[5]});
  if (!(largest > 0) || !(largest < std::numeric_limits<double>::infinity()))
    return Certified::undecided;
  double t = certificate::scale_to_unit(largest);
  if (t == 0) {
    // A subnormal largest entry: sqrt(largest) = m 2^e with m in [1/2, 1),
    // t = 2^(1 - e) (beyond 2^511: t^2 itself would overflow, so the forms
    // are multiplied by t twice below).
    int e = 0;
    std::frexp(std::sqrt(largest), &e);
    t = std::ldexp(1.0, 1 - e);
  }
  double r[3], q1[6], q2[6];
  for (int k = 0; k < 3; ++k) r[k] = r12[k] * t;
  for (int k = 0; k < 6; ++k) q1[k] = q1_given[k] * t * t, q2[k] = q2_given[k] * t * t;
  const certificate::Factors f1(q1), f2(q2);
  const double growth1 = f1.usable_growth(), growth2 = f2.usable_growth();
  if (!(growth1 > 0 && growth2 > 0)) return Certified::undecided;
  // sigma_i = r^T Qi^-1 r = f'(0) and -f'(1) (eq. 16).
  double y[3];
  f1.forward(r, y);
  const double sigma1 = f1.inverse_form_of(y);
  f2.forward(r, y);
  const double sigma2 = f2.inverse_form_of(y);
  auto in_range = [](double x) { return x >= certificate_floor && x <= 1 / certificate_floor; };
  if (!in_range(sigma1) || !in_range(sigma2)) return Certified::undecided;
  double margin = margin_per_growth * std::max(growth1, growth2);
  // Eq. 31: mu^2 <= sigma1 sigma2 / (sqrt(sigma1) + sqrt(sigma2))^2.
  const double root1 = std::sqrt(sigma1), root2 = std::sqrt(sigma2);
  const double inv_extents = 1 / (root1 + root2);
  double upper = sigma1 * inv_extents * (sigma2 * inv_extents) * (1 + margin);
  if (upper < cutoff2) return Certified::overlapping;
  double lower = 0;
  // The bracket [lo, hi] of the maximiser, with f and g = -f' at its ends
  // (f = 0 at both, g(0) = -sigma1, g(1) = sigma2), and the guess (eq. 31).
  double lo = 0, hi = 1, f_lo = 0, g_lo = -sigma1, f_hi = 0, g_hi = sigma2;
  double lambda = root2 * inv_extents;
  for (int n = 0; n < evaluations; ++n) {
    const certificate::Evaluation at = certificate::evaluate(r, q1, q2, lambda);
    if (!(at.growth > 0) || !in_range(at.f) || !std::isfinite(at.g) || !(at.dg > 0) ||
        !std::isfinite(at.dg))
      return Certified::undecided;
    margin = std::max(margin, margin_per_growth * at.growth);
    lower = std::max(lower, at.f * (1 - margin));  // eq. 27
    if (lower >= cutoff2) return Certified::apart;
    // g = 0 makes lambda the upper end, with a horizontal tangent: the
    // crossing is then f itself (kernels::ends_after).
    if (at.g >= 0) {
      hi = lambda, f_hi = at.f, g_hi = at.g;
    } else {
      lo = lambda, f_lo = at.f, g_lo = at.g;
    }
    // Eq. 29: where the tangents at the bracket's ends cross.
    const double x = (f_hi - f_lo + g_hi * hi - g_lo * lo) / (g_hi - g_lo);
    upper = std::min(upper, (f_lo - g_lo * (x - lo)) * (1 + margin));
    if (upper < cutoff2) return Certified::overlapping;
    // Bounds that have met within their margins straddle the cutoff: only
    // an exact solve can tell (eq. 45's settled lanes).
    if (upper <= lower * (1 + 8 * margin)) return Certified::undecided;
    const double newton = lambda - at.g / at.dg;
    lambda = newton > lo && newton < hi ? newton : 0.5 * (lo + hi);
  }
  return Certified::undecided;
}

}  // namespace pwcontact::screen
