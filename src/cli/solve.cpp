#include "cli/solve.hpp"

#include <omp.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <type_traits>

#include "cli/text_output.hpp"
#include "pwcontact/reference.hpp"

namespace pwcontact::cli {
namespace {

template <class T>
Solution<T> sized_solution(std::size_t pairs, const Request& request) {
  Solution<T> solution;
  solution.request = request;
  auto size_if = [pairs](bool wanted, auto& column) { column.resize(wanted ? pairs : 0); };
  const bool full = request.mode == Mode::full;
  size_if(full, solution.mu2);
  size_if(full && request.lambda, solution.lambda);
  size_if(!full || request.status, solution.status);
  size_if(!full, solution.overlap);
  for (int k = 0; k < 3; ++k) {
    size_if(full && request.contact_point, solution.contact_point[k]);
    size_if(full && request.normal, solution.normal[k]);
    size_if(full && request.gradient, solution.gradient[k]);
  }
  return solution;
}

// A column's storage as the library takes it: null when not asked for.
template <class T>
T* data_or_null(std::vector<T>& column) {
  return column.empty() ? nullptr : column.data();
}

template <class T>
ContactOutputs<T> contact_outputs(Solution<T>& solution) {
  ContactOutputs<T> out;
  out.mu2 = data_or_null(solution.mu2);
  out.lambda = data_or_null(solution.lambda);
  out.status = data_or_null(solution.status);
  for (int k = 0; k < 3; ++k) {
    out.contact_point[k] = data_or_null(solution.contact_point[k]);
    out.normal[k] = data_or_null(solution.normal[k]);
    out.gradient[k] = data_or_null(solution.gradient[k]);
  }
  return out;
}

template <class T>
void store_geometry(const ContactOutputs<T>& out, std::size_t i,
                    const ContactGeometry<T>& geometry) {
  for (int k = 0; k < 3; ++k) {
    if (out.contact_point[k]) out.contact_point[k][i] = geometry.contact_point[k];
    if (out.normal[k]) out.normal[k][i] = geometry.normal[k];
    if (out.gradient[k]) out.gradient[k][i] = geometry.gradient[k];
  }
}

// The geometry of a pair without a valid answer, as the batch path gives it.
template <class T>
ContactGeometry<T> undefined_geometry() {
  const T nan = std::numeric_limits<T>::quiet_NaN();
  return {{nan, nan, nan}, {nan, nan, nan}, {nan, nan, nan}};
}

// "1", "0.5": the shortest text that reads back as `value`.
std::string shortest_text(double value) {
  char text[max_number_chars];
  return std::string(text, std::to_chars(text, text + sizeof text, value).ptr);
}

std::string percent_of(std::size_t part, std::size_t whole) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g %%", whole ? 100.0 * double(part) / double(whole) : 0.0);
  return text;
}

}  // namespace

const char* mode_name(Mode mode) noexcept { return mode == Mode::overlap ? "overlap" : "full"; }

template <class T>
std::string Solution<T>::describe() const {
  const bool overlap_mode = request.mode == Mode::overlap;
  std::string mode = std::string("mode ") + mode_name(request.mode);
  if (overlap_mode) mode += " (cutoff " + shortest_text(request.cutoff) + ")";

  std::string text;
  if (reference_path) {
    text = std::string("reference path contact_function<") +
           (std::is_same_v<T, float> ? "float" : "double") + ">: " + mode + ", threads " +
           std::to_string(report.threads) + "\n";
  } else {
    text = "batch path: " + mode + ", precision " + precision_name(report.precision) +
           (overlap_mode ? "" : std::string(", accuracy ") + accuracy_name(accuracy)) +
           ", formulation " + formulation_name(report.formulation) + "\n  isa " +
           isa_name(report.isa) + ", iterations " +
           (report.iterations == automatic_iterations ? std::string("auto")
                                                      : std::to_string(report.iterations)) +
           ", threads " + std::to_string(report.threads) + "\n";
  }
  char evaluations[64];
  std::snprintf(evaluations, sizeof evaluations, ", mean evaluations per pair %.3g",
                report.mean_evaluations);
  text += "  time " + describe_seconds(seconds) + ", " + describe_rate(report.pairs, seconds) +
          evaluations + "\n  ";
  if (!reference_path && !overlap_mode && report.precision == Precision::single_precision)
    text += "finished in double lanes " + std::to_string(report.finished_in_double) + " (" +
            percent_of(report.finished_in_double, report.pairs) + "), ";
  if (!reference_path)
    text += "fallbacks " + std::to_string(report.fallbacks) + " (" +
            percent_of(report.fallbacks, report.pairs) + "), ";
  text += "invalid " + std::to_string(report.invalid) +
          "\n  statuses: " + describe_status_counts(report) + "\n";
  if (overlap_mode) {
    // Whatever the kernels leave undecided, the reference path decides; its
    // answers are exactly the pairs with its own status (ok for the
    // reference path itself, ok_fallback for the batch path).
    const Status by_reference = reference_path ? Status::ok : Status::ok_fallback;
    text += "  overlapping " + std::to_string(report.overlapping) + " (" +
            percent_of(report.overlapping, report.pairs) + "); decided by prefilter " +
            std::to_string(report.decided_by_prefilter) + ", by certificate " +
            std::to_string(report.decided_by_certificate) + ", by the reference path " +
            std::to_string(report.status_counts[int(by_reference)]) + "\n";
  }
  return text;
}

template <class T>
Solution<T> solve_batch(const PairBatch<T>& pairs, const Request& request,
                        const BatchOptions& options) {
  Solution<T> solution = sized_solution<T>(pairs.size(), request);
  solution.accuracy = options.accuracy;
  const Stopwatch stopwatch;
  if (request.mode == Mode::overlap)
    solution.report = overlap_batch(pairs.view(), {solution.overlap.data(), solution.status.data()},
                                    options, request.cutoff);
  else
    solution.report = contact_function_batch(pairs.view(), contact_outputs(solution), options);
  solution.seconds = stopwatch.seconds();
  return solution;
}

template <class T>
Solution<T> solve_reference(const PairBatch<T>& pairs, const Request& request, int threads) {
  const std::ptrdiff_t count = std::ptrdiff_t(pairs.size());
  Solution<T> solution = sized_solution<T>(pairs.size(), request);
  solution.reference_path = true;
  solution.report.pairs = pairs.size();
  solution.report.threads = resolve_thread_count(threads);
  const ContactOutputs<T> out = contact_outputs(solution);
  std::uint8_t* const overlap = data_or_null(solution.overlap);
  const bool geometry = out.contact_point[0] || out.normal[0] || out.gradient[0];
  const double cutoff_mu2 = request.cutoff * request.cutoff;
  std::size_t counts[status_count] = {};
  std::size_t evaluations = 0, overlapping = 0;

  const Stopwatch stopwatch;
  // Pairs differ in cost (bisection steps, invalid input), hence dynamic.
#pragma omp parallel for schedule(dynamic, 1024) num_threads(solution.report.threads) \
    reduction(+ : counts[:status_count], evaluations, overlapping)
  for (std::ptrdiff_t signed_i = 0; signed_i < count; ++signed_i) {
    const std::size_t i = std::size_t(signed_i);
    T r12[3], q1[6], q2[6];
    pairs.get(i, r12, q1, q2);
    ContactResult<T> result = contact_function<T>(r12, q1, q2);
    // A mu^2 out of range has a valid lambda, and decides an overlap exactly.
    const bool solved = is_valid(result.status) || result.status == Status::out_of_range;
    if (overlap && solved) result.status = Status::ok;
    ++counts[int(result.status)];
    evaluations += std::size_t(result.iterations);
    if (out.mu2) out.mu2[i] = result.mu2;
    if (out.lambda) out.lambda[i] = result.lambda;
    if (out.status) out.status[i] = result.status;
    if (geometry)
      store_geometry(
          out, i,
          solved ? contact_geometry<T>(r12, q1, q2, result.lambda) : undefined_geometry<T>());
    if (overlap) {
      bool overlaps = solved && double(result.mu2) < cutoff_mu2;
      // Float cannot decide where mu^2 or cutoff^2 lies outside its normal
      // range (mu^2 = inf beyond 3.4e38, subnormal below 1.2e-38, with a
      // few digits): there the pair, widened exactly, is decided in double,
      // as the batch path's float lanes hand such pairs to double ones.
      // (Was: mu^2 = 9e39 against a cutoff^2 of 1e40 answered "apart".)
      if (std::is_same_v<T, float> && solved &&
          !(std::abs(double(result.mu2)) >= double(std::numeric_limits<float>::min()) &&
            double(result.mu2) <= double(std::numeric_limits<float>::max()) &&
            cutoff_mu2 >= double(std::numeric_limits<float>::min()) &&
            cutoff_mu2 <= double(std::numeric_limits<float>::max()))) {
        double wide_r12[3], wide_q1[6], wide_q2[6];
        for (int k = 0; k < 3; ++k) wide_r12[k] = double(r12[k]);
        for (int k = 0; k < 6; ++k) {
          wide_q1[k] = double(q1[k]);
          wide_q2[k] = double(q2[k]);
        }
        const ContactResult<double> wide = contact_function<double>(wide_r12, wide_q1, wide_q2);
        overlaps =
            (is_valid(wide.status) || wide.status == Status::out_of_range) && wide.mu2 < cutoff_mu2;
      }
      overlap[i] = overlaps;
      overlapping += overlap[i];
    }
  }
  solution.seconds = stopwatch.seconds();

  for (int s = 0; s < status_count; ++s) {
    solution.report.status_counts[s] = counts[s];
    if (!is_valid(Status(s))) solution.report.invalid += counts[s];
  }
  solution.report.overlapping = overlapping;
  solution.report.mean_evaluations = count ? double(evaluations) / double(count) : 0;
  return solution;
}

template <class T>
void add_block(Solution<T>& total, const Solution<T>& block) {
  add_report(total.report, block.report);
  total.request = block.request;
  total.accuracy = block.accuracy;
  total.reference_path = block.reference_path;
  total.seconds += block.seconds;
}

template struct Solution<double>;
template struct Solution<float>;
template Solution<double> solve_batch(const PairBatch<double>&, const Request&,
                                      const BatchOptions&);
template Solution<float> solve_batch(const PairBatch<float>&, const Request&, const BatchOptions&);
template Solution<double> solve_reference(const PairBatch<double>&, const Request&, int);
template Solution<float> solve_reference(const PairBatch<float>&, const Request&, int);
template void add_block(Solution<double>&, const Solution<double>&);
template void add_block(Solution<float>&, const Solution<float>&);

}  // namespace pwcontact::cli
