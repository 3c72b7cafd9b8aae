#include "pwcontact/status.hpp"

namespace pwcontact {

const char* status_name(Status s) noexcept {
  switch (s) {
    case Status::ok: return "ok";
    case Status::ok_fallback: return "ok_fallback";
    case Status::non_finite_input: return "non_finite_input";
    case Status::q1_not_positive_definite: return "q1_not_positive_definite";
    case Status::q2_not_positive_definite: return "q2_not_positive_definite";
    case Status::not_converged: return "not_converged";
    case Status::out_of_range: return "out_of_range";
  }
  return "unknown";
}

const char* status_description(Status s) noexcept {
  switch (s) {
    case Status::ok:
      return "valid: answered by the batch kernels (converged, or decided by a certificate), "
             "or by the reference path when it was asked for";
    case Status::ok_fallback:
      return "valid: answered by the scalar reference path after the batch kernels left the "
             "pair (convergence check missed, or undecided)";
    case Status::non_finite_input:
      return "invalid: NaN or infinity in r12, q1 or q2 (mu2 and lambda are NaN)";
    case Status::q1_not_positive_definite:
      return "invalid: Q1 is not positive definite, e.g. zero, negative or singular "
             "(mu2 and lambda are NaN)";
    case Status::q2_not_positive_definite:
      return "invalid: Q2 is not positive definite (mu2 and lambda are NaN)";
    case Status::not_converged:
      return "invalid: the reference path did not converge either (mu2 and lambda "
             "are NaN)";
    case Status::out_of_range:
      return "invalid: mu2 overflows the result's type (mu2 = inf: certainly apart) or "
             "underflows below its smallest normal number (mu2 = 0 or subnormal: certainly "
             "overlapping); lambda is valid";
  }
  return "unknown status";
}

}  // namespace pwcontact
