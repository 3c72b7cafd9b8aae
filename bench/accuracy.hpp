// How far a path's mu^2 is from the truth: a high-precision oracle (the
// reference path instantiated in long double) and relative error statistics
// against it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "pwcontact/batch.hpp"

namespace pwcontact::bench {

// mu^2 of every pair by pwcontact::contact_function<long double> on the very
// same inputs (a float batch's oracle sees the float values, widened exactly).
// NaN where the oracle itself reports an invalid status. OpenMP-parallel:
// several seconds for the pw85 family.
template <class T>
std::vector<long double> oracle_mu2(const PairBatch<T>& pairs);

struct ErrorStatistics {
  double max = 0;
  double p999 = 0;  // 99.9th percentile (nearest rank)
  double median = 0;
  std::size_t compared = 0;  // pairs with a valid oracle value
};

// Relative error |mu2 - oracle| / oracle over the pairs the oracle solved.
// A NaN mu2 where the oracle has a value counts as an infinite error, so a
// path that silently fails cannot look accurate.
template <class T>
ErrorStatistics relative_errors(const std::vector<T>& mu2, const std::vector<long double>& oracle);

// Within this distance of tangency, |mu^2 - 1| <= 1e-9, double precision
// cannot be relied on to say which side a pair is on: overlap_batch promises
// the right answer only beyond it. Misclassifications are counted on both
// sides of it.
inline constexpr double tangency_tolerance = 1e-9;

struct Misclassification {
  std::size_t beyond = 0;    // wrong answers with |mu^2 - 1| > tangency_tolerance: errors
  std::size_t within = 0;    // wrong answers closer to tangency than that
  std::size_t compared = 0;  // pairs with a valid oracle value
};

// How many of the answers "overlapping" (mu < 1, nonzero) or "apart" (0)
// disagree with the oracle's mu^2 < 1, over the pairs the oracle solved.
Misclassification misclassified(const std::vector<std::uint8_t>& overlapping,
                                const std::vector<long double>& oracle);

extern template std::vector<long double> oracle_mu2(const PairBatch<double>&);
extern template std::vector<long double> oracle_mu2(const PairBatch<float>&);
extern template ErrorStatistics relative_errors(const std::vector<double>&,
                                                const std::vector<long double>&);
extern template ErrorStatistics relative_errors(const std::vector<float>&,
                                                const std::vector<long double>&);

}  // namespace pwcontact::bench
