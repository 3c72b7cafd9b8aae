// The names of the figures every benchmark reports besides its time: Google
// Benchmark counters, as they appear in its JSON output, which bench/report.py
// reads (it lists the same names).
#pragma once

namespace pwcontact::bench {

// The figures every configuration reports besides its throughput. Errors are
// relative errors of mu^2 against the long double oracle on the inputs the
// path actually solved: for the float pairs that is the float-rounded pairs,
// so the error is the solver's own; max_rel_err_double_input adds the effect
// of rounding the inputs to float.
namespace counter {
inline constexpr const char* items_per_second = "items_per_second";  // pairs per second
inline constexpr const char* max_rel_err = "max_rel_err";
inline constexpr const char* p999_rel_err = "p999_rel_err";
inline constexpr const char* median_rel_err = "median_rel_err";
inline constexpr const char* max_rel_err_double_input = "max_rel_err_double_input";
inline constexpr const char* fallbacks = "fallbacks";  // per batch call (the whole family)
inline constexpr const char* fallbacks_per_pair = "fallbacks_per_pair";
inline constexpr const char* invalid = "invalid";                    // pairs without a valid answer
inline constexpr const char* mean_evaluations = "mean_evaluations";  // per pair, in the kernels
// Overlap answers: the share decided by the prefilter or a certificate, the
// share found overlapping, and the answers that disagree with the oracle's
// mu^2 < 1 farther from tangency than tangency_tolerance (errors) or closer.
inline constexpr const char* decided_early_per_pair = "decided_early_per_pair";
inline constexpr const char* overlapping_per_pair = "overlapping_per_pair";
inline constexpr const char* misclassified_beyond = "misclassified_beyond";
inline constexpr const char* misclassified_within = "misclassified_within";
// The same classification (overlap answers, or mu^2 < 1 of full answers) on
// the family's near-tangent set.
inline constexpr const char* near_tangent_pairs = "near_tangent_pairs";
inline constexpr const char* near_tangent_misclassified_beyond =
    "near_tangent_misclassified_beyond";
inline constexpr const char* near_tangent_misclassified_within =
    "near_tangent_misclassified_within";
}  // namespace counter

}  // namespace pwcontact::bench
