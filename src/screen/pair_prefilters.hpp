// The decisions about a near pair that need no solve, shared by the
// screening (screen.cpp) and the moving scene (moving_scene.cpp): pairs of spheres
// and pairs of one form in closed form, overlapping by the inscribed
// spheres, apart by the projections on the line of centres; and the overlap
// certificates in scalar arithmetic, for the moving scene's few pairs.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
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
inline bool apart_by_projections(const Side& p, const Side& o, const double r[3], double rr,
                                 double cutoff) {
  constexpr double eps = std::numeric_limits<double>::epsilon();
  const double sp = form_value(p.q, r) + 64 * eps * p.bounding * p.bounding * rr;
  const double so = form_value(o.q, r) + 64 * eps * o.bounding * o.bounding * rr;
  // Coincident centres (rr = 0, both sides 0) are the most overlapping pair.
  return rr > 0 && rr >= cutoff * (std::sqrt(sp) + std::sqrt(so)) * (1 + 4 * eps);
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
    const double sum = p.sphere + o.sphere;
    mu2 = rr / (sum * sum);
    return NearPair::spheres;
  }
  if (same_moderate_form(p, o)) {
    // Q1 = Q2 = Q: Q(lambda) = Q in eq. (10), so f(lambda) = lambda (1 -
    // lambda) r^T Q^-1 r by eq. (11), largest at lambda = 1/2 (eq. 6). A scene
    // of identical, aligned ellipsoids is an affine image of one of spheres.
    mu2 = detail::inverse_quadratic_form(detail::Ldlt3<double>(p.q), r) / 4;
    return NearPair::same_form;
  }
  const double inner = cutoff * (p.inscribed + o.inscribed);
  if (!with_mu2 && rr < inner * inner) return NearPair::in;
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

// The factors of Q = L D L^T when they are usable by the certificates: every
// pivot at least certificate_floor and the growth at most the cap (0
// otherwise, else the growth).
inline double usable_growth(const detail::Ldlt3<double>& f) {
  if (!(f.d0 >= certificate_floor && f.d1 >= certificate_floor && f.d2 >= certificate_floor))
    return 0;
  const double growth = detail::element_growth(f);
  return growth <= certificate_growth_cap ? growth : 0;
}

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
  // sqrt(largest) = m 2^e with m in [1/2, 1): t = 2^(1 - e), t^2 largest in [1, 4).
  int e = 0;
  std::frexp(std::sqrt(largest), &e);
  // (The forms times t twice: t^2 itself overflows for forms below ~2^-1024.)
  const double t = std::ldexp(1.0, 1 - e);
  double r[3], q1[6], q2[6];
  for (int k = 0; k < 3; ++k) r[k] = r12[k] * t;
  for (int k = 0; k < 6; ++k) q1[k] = q1_given[k] * t * t, q2[k] = q2_given[k] * t * t;
  const detail::Ldlt3<double> f1(q1), f2(q2);
  const double growth1 = usable_growth(f1), growth2 = usable_growth(f2);
  if (!(growth1 > 0 && growth2 > 0)) return Certified::undecided;
  // sigma_i = r^T Qi^-1 r = f'(0) and -f'(1) (eq. 16).
  const double sigma1 = detail::inverse_quadratic_form(f1, r);
  const double sigma2 = detail::inverse_quadratic_form(f2, r);
  auto in_range = [](double x) { return x >= certificate_floor && x <= 1 / certificate_floor; };
  if (!in_range(sigma1) || !in_range(sigma2)) return Certified::undecided;
  double margin = margin_per_growth * std::max(growth1, growth2);
  // Eq. 31: mu^2 <= sigma1 sigma2 / (sqrt(sigma1) + sqrt(sigma2))^2.
  const double root1 = std::sqrt(sigma1), root2 = std::sqrt(sigma2);
  const double extents = root1 + root2;
  double upper = sigma1 / extents * (sigma2 / extents) * (1 + margin);
  if (upper < cutoff2) return Certified::overlapping;
  double lower = 0;
  // The bracket [lo, hi] of the maximiser, with f and g = -f' at its ends
  // (f = 0 at both, g(0) = -sigma1, g(1) = sigma2), and the guess (eq. 31).
  double lo = 0, hi = 1, f_lo = 0, g_lo = -sigma1, f_hi = 0, g_hi = sigma2;
  double lambda = root2 / extents;
  for (int n = 0; n < evaluations; ++n) {
    detail::Ldlt3<double> factors;
    const detail::Residual<double> at = detail::evaluate(r, q1, q2, lambda, &factors);
    const double growth = usable_growth(factors);
    if (!(growth > 0) || !in_range(at.f) || !std::isfinite(at.g) || !(at.dg > 0) ||
        !std::isfinite(at.dg))
      return Certified::undecided;
    margin = std::max(margin, margin_per_growth * growth);
    lower = std::max(lower, at.f * (1 - margin));  // eq. 27
    if (lower >= cutoff2) return Certified::apart;
    if (at.g > 0) {
      hi = lambda, f_hi = at.f, g_hi = at.g;
    } else if (at.g < 0) {
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
