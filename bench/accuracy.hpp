// How far a path's mu^2 is from the truth: a high-precision oracle (the
// reference path instantiated in long double) and relative error statistics
// against it.
#pragma once

#include <cstddef>
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
  double p999 = 0;    // 99.9th percentile (nearest rank)
  double median = 0;
  std::size_t compared = 0;  // pairs with a valid oracle value
};

// Relative error |mu2 - oracle| / oracle over the pairs the oracle solved.
// A NaN mu2 where the oracle has a value counts as an infinite error, so a
// path that silently fails cannot look accurate.
template <class T>
ErrorStatistics relative_errors(const std::vector<T>& mu2, const std::vector<long double>& oracle);

extern template std::vector<long double> oracle_mu2(const PairBatch<double>&);
extern template std::vector<long double> oracle_mu2(const PairBatch<float>&);
extern template ErrorStatistics relative_errors(const std::vector<double>&,
                                                const std::vector<long double>&);
extern template ErrorStatistics relative_errors(const std::vector<float>&,
                                                const std::vector<long double>&);

}  // namespace pwcontact::bench
