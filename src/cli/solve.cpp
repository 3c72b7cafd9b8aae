#include "cli/solve.hpp"

#include <omp.h>

#include <algorithm>
#include <cstdio>
#include <type_traits>

#include "cli/text_output.hpp"
#include "pwcontact/reference.hpp"

namespace pwcontact::cli {
namespace {

template <class T>
constexpr Precision precision_of() {
  return std::is_same_v<T, float> ? Precision::single_precision : Precision::double_precision;
}

template <class T>
Solution<T> sized_solution(std::size_t pairs) {
  Solution<T> solution;
  solution.mu2.resize(pairs);
  solution.lambda.resize(pairs);
  solution.status.resize(pairs);
  return solution;
}

}  // namespace

template <class T>
std::string Solution<T>::describe() const {
  const std::string precision = precision_name(precision_of<T>());
  const std::string threads =
      std::to_string(report.threads) + " thread" + (report.threads == 1 ? "" : "s");
  std::string text = reference_path
                         ? "reference path contact_function<" + precision + ">, " + threads + "\n"
                         : "batch path, " + precision + ", " + isa_name(report.isa) + ", " +
                               std::to_string(report.iterations) + " iterations, " + threads + "\n";
  text +=
      "  time " + describe_seconds(seconds) + ", " + describe_rate(report.pairs, seconds) + "\n";
  if (!reference_path) {
    char share[32];
    std::snprintf(share, sizeof share, " (%.3g %%)",
                  report.pairs ? 100.0 * double(report.fallbacks) / double(report.pairs) : 0.0);
    text += "  fallbacks " + std::to_string(report.fallbacks) + share + ", ";
  } else {
    text += "  ";
  }
  return text + "invalid " + std::to_string(report.invalid) +
         "\n  statuses: " + describe_status_counts(report) + "\n";
}

template <class T>
Solution<T> solve_batch(const PairBatch<T>& pairs, const SolverOptions& options) {
  Solution<T> solution = sized_solution<T>(pairs.size());
  BatchOptions batch_options;
  batch_options.iterations = options.iterations;
  batch_options.threads = options.threads;
  batch_options.isa = options.isa;
  const Stopwatch stopwatch;
  solution.report = contact_function_batch(
      pairs.view(), {solution.mu2.data(), solution.lambda.data(), solution.status.data()},
      batch_options);
  solution.seconds = stopwatch.seconds();
  return solution;
}

template <class T>
Solution<T> solve_reference(const PairBatch<T>& pairs, int threads) {
  const std::ptrdiff_t count = std::ptrdiff_t(pairs.size());
  Solution<T> solution = sized_solution<T>(pairs.size());
  solution.reference_path = true;
  solution.report.pairs = pairs.size();
  solution.report.threads = resolve_thread_count(threads);
  std::size_t counts[status_count] = {};

  const Stopwatch stopwatch;
  // Pairs differ in cost (bisection steps, invalid input), hence dynamic.
#pragma omp parallel for schedule(dynamic, 1024) num_threads(solution.report.threads) \
    reduction(+ : counts[:status_count])
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    T r12[3], q1[6], q2[6];
    pairs.get(std::size_t(i), r12, q1, q2);
    const ContactResult<T> result = contact_function<T>(r12, q1, q2);
    solution.mu2[std::size_t(i)] = result.mu2;
    solution.lambda[std::size_t(i)] = result.lambda;
    solution.status[std::size_t(i)] = result.status;
    ++counts[int(result.status)];
  }
  solution.seconds = stopwatch.seconds();

  for (int s = 0; s < status_count; ++s) {
    solution.report.status_counts[s] = counts[s];
    if (!is_valid(Status(s))) solution.report.invalid += counts[s];
  }
  return solution;
}

template <class To, class From>
PairBatch<To> convert_pairs(const PairBatch<From>& pairs) {
  PairBatch<To> out(pairs.size());
  auto convert = [](const std::vector<From>& from, std::vector<To>& to) {
    std::transform(from.begin(), from.end(), to.begin(), [](From x) { return To(x); });
  };
  for (int k = 0; k < 3; ++k) convert(pairs.r12(k), out.r12(k));
  for (int k = 0; k < 6; ++k) {
    convert(pairs.q1(k), out.q1(k));
    convert(pairs.q2(k), out.q2(k));
  }
  return out;
}

template struct Solution<double>;
template struct Solution<float>;
template Solution<double> solve_batch(const PairBatch<double>&, const SolverOptions&);
template Solution<float> solve_batch(const PairBatch<float>&, const SolverOptions&);
template Solution<double> solve_reference(const PairBatch<double>&, int);
template Solution<float> solve_reference(const PairBatch<float>&, int);
template PairBatch<float> convert_pairs(const PairBatch<double>&);
template PairBatch<double> convert_pairs(const PairBatch<float>&);

}  // namespace pwcontact::cli
