// The decisions about a near pair that need no solve, shared by the
// screening (screen.cpp) and the moving scene (scene.cpp): pairs of spheres
// and pairs of one form in closed form, overlapping by the inscribed
// spheres, apart by the projections on the line of centres.
#pragma once

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

}  // namespace pwcontact::screen
