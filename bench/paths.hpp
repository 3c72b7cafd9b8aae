// The paths at work: one configuration bound to a pair set, ready to be
// timed, and what its answers are worth against the oracle.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <string>

#include "accuracy.hpp"
#include "configuration.hpp"
#include "families.hpp"

namespace pwcontact::bench {

// One configuration bound to a pair set with its inputs built and its answer
// buffers allocated: a call solves the whole set (batch paths) or the set's
// scalar sample (scalar paths) and does nothing else, so that it can be
// timed. The full batch paths ask for what a caller typically wants, mu^2,
// lambda and each pair's status, as the scalar paths deliver mu^2 and lambda
// too; the overlap paths for the answer and the status.
class PreparedRun {
 public:
  PreparedRun(const Configuration& c, PairSet& set);

  // Solves; the report of the batch call (empty for the scalar paths).
  BatchReport operator()() const { return solve_(); }
  std::size_t pairs_per_call() const { return pairs_per_call_; }

 private:
  std::function<BatchReport()> solve_;
  std::size_t pairs_per_call_ = 0;
};

// What a configuration's answers are worth, measured once, on the whole
// family, with all threads (batch results do not depend on the thread count).
struct AccuracyReport {
  std::size_t pairs = 0;
  std::size_t invalid = 0;  // pairs without a valid answer
  // Full answers: relative error of mu^2 against the oracle on the inputs the
  // path solved; for float pairs, also against the double inputs.
  std::optional<ErrorStatistics> error, error_double_input;
  // Batch paths.
  std::optional<std::size_t> fallbacks;
  std::optional<double> mean_evaluations;
  // Overlap answers: how they were decided, and how many disagree with the
  // oracle's mu^2 < 1 on the family.
  std::optional<std::size_t> decided_early;  // by the prefilter or a certificate
  std::optional<std::size_t> overlapping;
  std::optional<Misclassification> misclassified;
  // Batch paths, on the family's near-tangent set: overlap answers, or mu^2 < 1
  // of full answers, against the oracle's (on the inputs the path solved).
  std::optional<Misclassification> near_tangent;
};

// Measures a configuration's accuracy. `near_tangent` also classifies the
// family's near-tangent set (batch paths).
AccuracyReport measure_accuracy(const Configuration& c, Families& families, bool near_tangent);

// The report as named counters (see counters.hpp), absent figures left out.
std::map<std::string, double> accuracy_counters(const AccuracyReport& a);

}  // namespace pwcontact::bench
