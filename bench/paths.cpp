#include "paths.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include "brent_baseline.hpp"
#include "counters.hpp"
#include "pwcontact/reference.hpp"

namespace pwcontact::bench {
namespace {

// Calls visit(solve) with solve(const ScalarPair&) -> mu^2 (NaN when the path
// has no valid answer) for one of the scalar paths.
template <class Visit>
auto with_scalar_path(Path path, Visit&& visit) {
  if (path == Path::brent_baseline)
    return visit([](const ScalarPair& p) { return brent_contact_function(p.r12, p.q1, p.q2).mu2; });
  return visit([](const ScalarPair& p) { return contact_function<double>(p.r12, p.q1, p.q2).mu2; });
}

template <class T>
std::function<BatchReport()> batch_call(const Configuration& c, PairSet& set) {
  const PairBatchView<T> view = set.inputs<T>().view();
  AnswerBuffers& a = set.answers();
  const BatchOptions options = c.options();
  if (is_overlap(c.path)) {
    const OverlapOutputs out{a.overlap.data(), a.status.data()};
    return [view, out, options] { return overlap_batch(view, out, options); };
  }
  const ContactOutputs<T> out{a.full<T>().mu2.data(), a.full<T>().lambda.data(), a.status.data()};
  return [view, out, options] { return contact_function_batch(view, out, options); };
}

// Runs the configuration on `set` and says which pairs it found overlapping:
// its overlap answers, or mu^2 < 1 of its full answers.
template <class T>
std::vector<std::uint8_t> overlapping(const Configuration& c, PairSet& set) {
  PreparedRun{c, set}();
  AnswerBuffers& a = set.answers();
  if (is_overlap(c.path)) return a.overlap;
  const std::vector<T>& mu2 = a.full<T>().mu2;
  std::vector<std::uint8_t> out(mu2.size());
  std::transform(mu2.begin(), mu2.end(), out.begin(), [](T x) { return x < 1; });
  return out;
}

AccuracyReport scalar_accuracy(Path path, PairSet& set) {
  const PairBatch<double>& pairs = set.pairs();
  const std::vector<double> mu2 = with_scalar_path(path, [&](auto solve) {
    std::vector<double> out(pairs.size());
#pragma omp parallel for schedule(dynamic, 1024)
    for (std::size_t i = 0; i < pairs.size(); ++i) out[i] = solve(scalar_pair(pairs, i));
    return out;
  });
  AccuracyReport a;
  a.pairs = pairs.size();
  a.error = relative_errors(mu2, set.oracle());
  a.invalid = std::size_t(
      std::count_if(mu2.begin(), mu2.end(), [](double x) { return !std::isfinite(x); }));
  return a;
}

template <class T>
AccuracyReport batch_accuracy(const Configuration& c, Families& families, bool near_tangent) {
  // All threads: the answers do not depend on the thread count.
  const Configuration all_threads = c.with_threads(0);
  PairSet& set = families.family(c.family);
  const BatchReport report = PreparedRun{all_threads, set}();
  AccuracyReport a;
  a.pairs = set.size();
  a.invalid = report.invalid;
  a.fallbacks = report.fallbacks;
  a.mean_evaluations = report.mean_evaluations;
  if (is_overlap(c.path)) {
    a.decided_early = report.decided_by_prefilter + report.decided_by_certificate;
    a.overlapping = report.overlapping;
    a.misclassified = misclassified(set.answers().overlap, set.inputs_oracle<T>());
  } else {
    const std::vector<T>& mu2 = set.answers().full<T>().mu2;
    a.error = relative_errors(mu2, set.inputs_oracle<T>());
    if constexpr (std::is_same_v<T, float>)
      a.error_double_input = relative_errors(mu2, set.oracle());
  }
  if (near_tangent) {
    PairSet& tangent = families.near_tangent(c.family);
    a.near_tangent =
        misclassified(overlapping<T>(all_threads, tangent), tangent.inputs_oracle<T>());
  }
  return a;
}

}  // namespace

PreparedRun::PreparedRun(const Configuration& c, PairSet& set) {
  if (is_batch(c.path)) {
    pairs_per_call_ = set.size();
    solve_ = has_float_input(c.path) ? batch_call<float>(c, set) : batch_call<double>(c, set);
    return;
  }
  const std::vector<ScalarPair>& sample = set.scalar_sample();
  pairs_per_call_ = sample.size();
  // The answers are stored, as a caller would: the solves cannot be optimised away.
  auto mu2 = std::make_shared<std::vector<double>>(sample.size());
  solve_ = with_scalar_path(c.path, [&](auto solve) -> std::function<BatchReport()> {
    return [&sample, mu2, solve] {
      for (std::size_t i = 0; i < sample.size(); ++i) (*mu2)[i] = solve(sample[i]);
      return BatchReport{};
    };
  });
}

AccuracyReport measure_accuracy(const Configuration& c, Families& families, bool near_tangent) {
  if (is_scalar(c.path)) return scalar_accuracy(c.path, families.family(c.family));
  return has_float_input(c.path) ? batch_accuracy<float>(c, families, near_tangent)
                                 : batch_accuracy<double>(c, families, near_tangent);
}

std::map<std::string, double> accuracy_counters(const AccuracyReport& a) {
  std::map<std::string, double> out;
  const double pairs = double(a.pairs);
  out[counter::invalid] = double(a.invalid);
  if (a.error) {
    out[counter::max_rel_err] = a.error->max;
    out[counter::p999_rel_err] = a.error->p999;
    out[counter::median_rel_err] = a.error->median;
  }
  if (a.error_double_input) out[counter::max_rel_err_double_input] = a.error_double_input->max;
  if (a.fallbacks) {
    out[counter::fallbacks] = double(*a.fallbacks);
    out[counter::fallbacks_per_pair] = double(*a.fallbacks) / pairs;
  }
  if (a.mean_evaluations) out[counter::mean_evaluations] = *a.mean_evaluations;
  if (a.decided_early) out[counter::decided_early_per_pair] = double(*a.decided_early) / pairs;
  if (a.overlapping) out[counter::overlapping_per_pair] = double(*a.overlapping) / pairs;
  if (a.misclassified) {
    out[counter::misclassified_beyond] = double(a.misclassified->beyond);
    out[counter::misclassified_within] = double(a.misclassified->within);
  }
  if (a.near_tangent) {
    out[counter::near_tangent_pairs] = double(a.near_tangent->compared);
    out[counter::near_tangent_misclassified_beyond] = double(a.near_tangent->beyond);
    out[counter::near_tangent_misclassified_within] = double(a.near_tangent->within);
  }
  return out;
}

}  // namespace pwcontact::bench
