// What a configuration measured, the names of its figures, and the table of
// all measurements of one run with the ratios the reports quote.
#pragma once

#include <cstdarg>
#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include "configuration.hpp"

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

// What one configuration measured: its throughput (the median over
// repetitions when there are several) and its other counters.
struct Measurement {
  Configuration configuration;
  double pairs_per_second = 0;
  double pairs_per_second_cv = 0;  // coefficient of variation over repetitions; NaN without
  // The fastest repetition: what the machine can do when no foreign load
  // interferes. NaN when only aggregates were reported.
  double best_pairs_per_second = 0;
  std::map<std::string, double> counters;

  double counter(const char* name) const;  // NaN when not reported
};

// The median as Google Benchmark computes its "_median" aggregate; NaN for none.
double median(std::vector<double> values);
// Standard deviation over mean; NaN for fewer than two values.
double coefficient_of_variation(const std::vector<double>& values);

// printf into a std::string.
std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
// A table cell: "-" for a figure that was not measured.
std::string cell(double value, const char* fmt = "%.2e");

// "beyond/within" misclassification counts (see counter::misclassified_beyond)
// on the family or on its near-tangent set; "-" when not measured.
std::string misclassification_cell(const Measurement& m, bool near_tangent);

// The measurements of one run, looked up by configuration.
class Table {
 public:
  // `rows` must outlive the table.
  explicit Table(const std::vector<Measurement>& rows);

  const std::vector<Measurement>& rows() const { return rows_; }
  const Measurement* find(const Configuration& c) const;
  const Measurement* brent_baseline(Family family) const;

  // Throughput as a multiple of brent_baseline's on the same family (NaN
  // when it was not measured).
  double speedup(const Measurement& m) const;

  // Throughput with `threads` threads over the same configuration with 1.
  // `rate` picks the median (default) or the best repetition.
  double thread_scaling(const Configuration& one_thread, int threads,
                        double Measurement::*rate = &Measurement::pairs_per_second) const;

  // "; best repetitions d.ef": the ratio of the fastest repetitions, which
  // tells foreign load on the machine apart from poor scaling.
  std::string best_scaling_note(const Configuration& one_thread, int threads) const;

  // "; noisy: cv N%" when a throughput behind a ratio varied a lot between repetitions.
  static std::string noise_note(std::initializer_list<const Measurement*> behind_ratio);

 private:
  const std::vector<Measurement>& rows_;
  std::map<std::string, const Measurement*> by_name_;
};

}  // namespace pwcontact::bench
