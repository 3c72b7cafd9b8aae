// Every pair gets a status: the answer is either valid (and says how it was
// obtained) or it is NaN and says why. Nothing is ever reported as "apart"
// because a solve failed.
#pragma once

#include <cstdint>

namespace pwcontact {

enum class Status : std::uint8_t {
  // Valid answers.
  ok = 0,           // answered by the batch kernels (or by the reference path
                    // when that was the path asked for)
  ok_fallback = 1,  // the batch kernels left the pair (convergence check missed,
                    // or an overlap left undecided) and the scalar reference
                    // path answered it
  // Invalid answers: mu2 and lambda are NaN (but for out_of_range).
  non_finite_input = 2,          // NaN or infinity in r12, q1 or q2
  q1_not_positive_definite = 3,  // Q1 zero, negative, indefinite or singular
  q2_not_positive_definite = 4,  // same for Q2
  not_converged = 5,             // even the reference path failed to converge
  // mu^2 is outside the normal range of the result's type: mu2 is +infinity
  // when it overflows (the pair is certainly apart) and 0 or subnormal when it
  // underflows (certainly overlapping); lambda is valid. An overlap answer is
  // exact for such a pair and gets a valid status instead.
  out_of_range = 6,
};

// Number of distinct status codes; codes are 0 .. status_count - 1.
inline constexpr int status_count = 7;

constexpr bool is_valid(Status s) noexcept { return s == Status::ok || s == Status::ok_fallback; }

// Short stable name ("ok", "non_finite_input", ...), as printed by the CLI.
const char* status_name(Status s) noexcept;

// One-line human description, as listed by `pwcontact --help`.
const char* status_description(Status s) noexcept;

}  // namespace pwcontact
