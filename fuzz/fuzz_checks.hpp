// What every fuzz target checks of the library's answers: a valid status is
// a promise (finite, positive mu^2 within the documented bound), checked
// against the reference path on the same pair; an invalid one has the
// reference path's reason. A broken promise aborts, which libFuzzer reports
// with the input that did it.
#pragma once

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "pwcontact/pwcontact.hpp"

namespace pwcontact::fuzz {

[[noreturn]] inline void broken(const char* what, double got, double expected) {
  std::fprintf(stderr, "broken promise: %s (got %.17g, expected %.17g)\n", what, got, expected);
  std::abort();
}

inline void expect(bool condition, const char* what, double got = 0, double expected = 0) {
  if (!condition) broken(what, got, expected);
}

// cond(Q(lambda)) in double (infinite where not positive definite or not
// finite): what bounds the accuracy of any solve.
inline double condition_at(const double q1[6], const double q2[6], double lambda) {
  Eigen::Matrix3d q;
  const double mu = 1 - lambda;
  const int index[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) q(i, j) = mu * q1[index[i][j]] + lambda * q2[index[i][j]];
  if (!q.allFinite()) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d e = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(q).eigenvalues();
  if (!(e[0] > 0) || !std::isfinite(e[2] / e[0])) return std::numeric_limits<double>::infinity();
  return e[2] / e[0];
}

// Whether the reference path answers the pair; where it rejects it (input
// not finite, a form not positive definite) the answer's status must be
// its reason.
inline bool has_answer(const ContactResult<double>& ref, Status status) {
  if (ref.status == Status::non_finite_input || ref.status == Status::q1_not_positive_definite ||
      ref.status == Status::q2_not_positive_definite) {
    expect(status == ref.status, "the reference path's reason for an invalid pair", double(status),
           double(ref.status));
    return false;
  }
  return true;
}

// One pair's full answer (mu2, lambda, status) against the reference path's
// in double on the same numbers (float pairs widened exactly); eps is that
// of the arithmetic the answer was computed in, normal_min the smallest
// normal number of the answer's type (a valid mu2 is in its normal range,
// or exactly 0 for coincident centres).
inline void check_full_answer(const double r[3], const double q1[6], const double q2[6], double mu2,
                              double lambda, Status status, double eps, bool lambda_asked,
                              double normal_min = std::numeric_limits<double>::min()) {
  const ContactResult<double> ref = contact_function<double>(r, q1, q2);
  if (!has_answer(ref, status)) return;
  if (!is_valid(status)) return;  // not_converged or out_of_range: no promise made
  expect(std::isfinite(mu2) && mu2 >= 0, "a valid mu2 is finite and not negative", mu2, ref.mu2);
  const bool coincident = r[0] == 0 && r[1] == 0 && r[2] == 0;
  expect(coincident ? mu2 == 0 : mu2 >= normal_min,
         "a valid mu2 is in the normal range of its type (0 only for coincident centres)", mu2,
         ref.mu2);
  // (The reference path in double may not converge where the answer came
  // from the long double one, with accuracy high: nothing to compare then.)
  if (lambda_asked) expect(lambda >= 0 && lambda <= 1, "lambda in [0, 1]", lambda, ref.lambda);
  if (ref.status != Status::ok) return;
  // Both within 16 eps cond(Q(lambda*)) of the exact mu^2 (the documented
  // bound), cond taken at the reference's lambda.
  const double cond = condition_at(q1, q2, ref.lambda);
  if (!std::isfinite(cond) || 32 * eps * cond >= 1) return;  // no bound worth checking
  const double error = std::abs(mu2 - ref.mu2);
  expect(error <= 32 * eps * cond * ref.mu2 + std::numeric_limits<double>::min(),
         "mu2 within the documented bound of the reference path's", mu2, ref.mu2);
}

// An overlap answer against the reference path's mu^2: the same
// classification wherever mu^2 is clear of the cutoff by the bound.
inline void check_overlap_answer(const double r[3], const double q1[6], const double q2[6],
                                 bool overlap, Status status, double cutoff2, double eps) {
  const ContactResult<double> ref = contact_function<double>(r, q1, q2);
  if (!has_answer(ref, status)) return;
  if (!is_valid(status)) return;
  if (ref.status == Status::out_of_range) {
    expect(overlap == (ref.mu2 < cutoff2), "an out-of-range mu2 decides the overlap", overlap,
           ref.mu2);
    return;
  }
  if (ref.status != Status::ok) return;
  const double cond = condition_at(q1, q2, ref.lambda);
  const double band = std::max(1e-9, 32 * eps * cond) * cutoff2;
  if (std::abs(ref.mu2 - cutoff2) > band)
    expect(overlap == (ref.mu2 < cutoff2), "the overlap answer's classification", overlap, ref.mu2);
}

}  // namespace pwcontact::fuzz
