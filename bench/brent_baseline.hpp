// The classic scalar approach of the existing library (pw85 2.0), rewritten
// here as the benchmark's baseline: Brent's method from Boost.Math finds the
// maximum of f on [0, 1] to half the bits of a double, then up to three
// Newton steps on g = -f' refine it, and the better of the two answers (by
// |g|) is kept. Each evaluation factorises Q(lambda) by Cholesky.
//
// It is here to be timed against, pair by pair: every speed-up quoted by the
// benchmark is a ratio to this, measured in the same run.
#pragma once

#include <boost/math/tools/minima.hpp>
#include <cmath>
#include <limits>

namespace pwcontact::bench {

struct BrentResult {
  double mu2;
  double lambda;
};

namespace brent_detail {

// Q = L L^T, L lower triangular stored as l0; l1 l3; l2 l4 l5.
inline void cholesky(const double a[6], double l[6]) {
  l[0] = std::sqrt(a[0]);
  l[1] = a[1] / l[0];
  l[2] = a[2] / l[0];
  l[3] = std::sqrt(a[3] - l[1] * l[1]);
  l[4] = (a[4] - l[1] * l[2]) / l[3];
  l[5] = std::sqrt(a[5] - l[2] * l[2] - l[4] * l[4]);
}

inline void cholesky_solve(const double l[6], const double b[3], double x[3]) {
  const double y0 = b[0] / l[0];
  const double y1 = (b[1] - l[1] * y0) / l[3];
  const double y2 = (b[2] - l[2] * y0 - l[4] * y1) / l[5];
  x[2] = y2 / l[5];
  x[1] = (y1 - l[4] * x[2]) / l[3];
  x[0] = (y0 - l[1] * x[1] - l[2] * x[2]) / l[0];
}

inline void combine(const double q1[6], const double q2[6], double lambda, double q[6]) {
  for (int k = 0; k < 6; ++k) q[k] = (1 - lambda) * q1[k] + lambda * q2[k];
}

// f(lambda) = lambda (1 - lambda) r^T Q^-1 r
inline double f(const double r[3], const double q1[6], const double q2[6], double lambda) {
  double q[6], l[6], s[3];
  combine(q1, q2, lambda, q);
  cholesky(q, l);
  cholesky_solve(l, r, s);
  return lambda * (1 - lambda) * (r[0] * s[0] + r[1] * s[1] + r[2] * s[2]);
}

// f, g = -f' and g' at lambda
inline void residual(const double r[3], const double q1[6], const double q2[6], double lambda,
                     double out[3]) {
  double q[6], l[6], s[3], v[3];
  combine(q1, q2, lambda, q);
  cholesky(q, l);
  cholesky_solve(l, r, s);
  double dq[6];
  for (int k = 0; k < 6; ++k) dq[k] = q2[k] - q1[k];
  const double u[3] = {dq[0] * s[0] + dq[1] * s[1] + dq[2] * s[2],
                       dq[1] * s[0] + dq[3] * s[1] + dq[4] * s[2],
                       dq[2] * s[0] + dq[4] * s[1] + dq[5] * s[2]};
  cholesky_solve(l, u, v);
  const double rs = r[0] * s[0] + r[1] * s[1] + r[2] * s[2];
  const double su = s[0] * u[0] + s[1] * u[1] + s[2] * u[2];
  const double uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  out[0] = lambda * (1 - lambda) * rs;
  out[1] = (2 * lambda - 1) * rs + lambda * (1 - lambda) * su;
  out[2] = 2 * rs + 2 * (1 - 2 * lambda) * su - 2 * lambda * (1 - lambda) * uv;
}

}  // namespace brent_detail

inline BrentResult brent_contact_function(const double r[3], const double q1[6],
                                          const double q2[6]) {
  using namespace brent_detail;
  auto minus_f = [&](double lambda) { return -f(r, q1, q2, lambda); };
  const auto [lambda_brent, minus_mu2] = boost::math::tools::brent_find_minima(
      minus_f, 0.0, 1.0, std::numeric_limits<double>::digits / 2);

  double res[3];
  residual(r, q1, q2, lambda_brent, res);
  const double g_brent = std::fabs(res[1]);
  double lambda = lambda_brent, mu2 = -minus_mu2, g = g_brent;
  for (int i = 0; i < 3; ++i) {
    const double trial = lambda - res[1] / res[2];
    if (trial < 0 || trial > 1) break;
    residual(r, q1, q2, trial, res);
    lambda = trial;
    mu2 = res[0];
    g = std::fabs(res[1]);
  }
  if (g < g_brent) return {mu2, lambda};
  return {-minus_mu2, lambda_brent};
}

}  // namespace pwcontact::bench
