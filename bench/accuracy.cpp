#include "accuracy.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pwcontact/reference.hpp"

namespace pwcontact::bench {

template <class T>
std::vector<long double> oracle_mu2(const PairBatch<T>& pairs) {
  const std::size_t n = pairs.size();
  std::vector<long double> mu2(n);
  // Pairs differ a lot in cost (aspect ratios up to 500 in pw85): dynamic.
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::size_t i = 0; i < n; ++i) {
    T r[3], q1[6], q2[6];
    pairs.get(i, r, q1, q2);
    long double wide_r[3], wide_q1[6], wide_q2[6];
    std::copy(r, r + 3, wide_r);
    std::copy(q1, q1 + 6, wide_q1);
    std::copy(q2, q2 + 6, wide_q2);
    mu2[i] = contact_function<long double>(wide_r, wide_q1, wide_q2).mu2;  // NaN when invalid
  }
  return mu2;
}

template <class T>
ErrorStatistics relative_errors(const std::vector<T>& mu2, const std::vector<long double>& oracle) {
  constexpr double infinity = std::numeric_limits<double>::infinity();
  std::vector<double> errors;
  errors.reserve(oracle.size());
  for (std::size_t i = 0; i < oracle.size(); ++i) {
    const long double exact = oracle[i];
    if (std::isnan(exact)) continue;
    const long double diff = std::fabs(static_cast<long double>(mu2[i]) - exact);
    if (std::isnan(diff))
      errors.push_back(infinity);
    else if (exact == 0)  // coincident centres: relative error undefined, exact 0 expected
      errors.push_back(diff == 0 ? 0 : infinity);
    else
      errors.push_back(static_cast<double>(diff / std::fabs(exact)));
  }

  ErrorStatistics stats;
  stats.compared = errors.size();
  if (errors.empty()) return stats;
  std::sort(errors.begin(), errors.end());
  const auto nearest_rank = [&](double q) {
    const auto rank = static_cast<std::size_t>(std::ceil(q * double(errors.size())));
    return errors[std::clamp<std::size_t>(rank, 1, errors.size()) - 1];
  };
  stats.max = errors.back();
  stats.p999 = nearest_rank(0.999);
  stats.median = nearest_rank(0.5);
  return stats;
}

Misclassification misclassified(const std::vector<std::uint8_t>& overlapping,
                                const std::vector<long double>& oracle) {
  Misclassification m;
  for (std::size_t i = 0; i < oracle.size(); ++i) {
    if (std::isnan(oracle[i])) continue;
    ++m.compared;
    if ((overlapping[i] != 0) == (oracle[i] < 1)) continue;
    if (std::fabs(oracle[i] - 1) > tangency_tolerance)
      ++m.beyond;
    else
      ++m.within;
  }
  return m;
}

template std::vector<long double> oracle_mu2(const PairBatch<double>&);
template std::vector<long double> oracle_mu2(const PairBatch<float>&);
template ErrorStatistics relative_errors(const std::vector<double>&,
                                         const std::vector<long double>&);
template ErrorStatistics relative_errors(const std::vector<float>&,
                                         const std::vector<long double>&);

}  // namespace pwcontact::bench
