// The batch driver: splits the pairs into chunks, runs the chosen kernel on
// each chunk in OpenMP threads, and recomputes with the reference path the
// lanes that missed their convergence check.
#include <omp.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "kernels/kernel_api.hpp"
#include "pwcontact/batch.hpp"
#include "pwcontact/reference.hpp"

namespace pwcontact {
namespace {

// Pairs per chunk: a multiple of every kernel's block (lanes times
// interleaved groups: 4 to 48), so that only a batch's last chunk has a
// padded tail; small enough to balance threads, large enough that the
// scheduling cost (~1 us) is noise next to the work (~60 us).
constexpr std::size_t chunk_pairs = 48 * 48;

const kernels::KernelTable& kernel_table(Isa isa) {
  switch (isa) {
    case Isa::avx512: return kernels::kernel_table_avx512;
    case Isa::avx2: return kernels::kernel_table_avx2;
    default: return kernels::kernel_table_sse2;
  }
}

void solve_span(const kernels::KernelTable& table, const kernels::PairSpan<double>& in,
                const kernels::ResultSpan<double>& out, std::size_t n, int iterations) {
  table.solve_double(in, out, n, iterations);
}
void solve_span(const kernels::KernelTable& table, const kernels::PairSpan<float>& in,
                const kernels::ResultSpan<float>& out, std::size_t n, int iterations) {
  table.solve_float(in, out, n, iterations);
}

// The fallback always runs in double, also for float batches: a lane that
// failed in float gets the better answer, rounded once to float.
template <class T>
ContactResult<double> reference_for_pair(const PairBatchView<T>& pairs, std::size_t i) {
  double r[3], q1[6], q2[6];
  for (int k = 0; k < 3; ++k) r[k] = pairs.r12[k][i];
  for (int k = 0; k < 6; ++k) {
    q1[k] = pairs.q1[k][i];
    q2[k] = pairs.q2[k][i];
  }
  return contact_function<double>(r, q1, q2);
}

template <class T>
void check_call(const PairBatchView<T>& pairs, const ContactOutputs<T>& out,
                const BatchOptions& options) {
  if (options.iterations < 0)
    throw std::invalid_argument("BatchOptions::iterations must be >= 0 (0 = default), got " +
                                std::to_string(options.iterations));
  if (options.threads < 0)
    throw std::invalid_argument("BatchOptions::threads must be >= 0 (0 = all), got " +
                                std::to_string(options.threads));
  if (pairs.size == 0) return;
  if (!out.mu2) throw std::invalid_argument("ContactOutputs::mu2 must not be null");
  for (const T* p : pairs.r12)
    if (!p) throw std::invalid_argument("PairBatchView::r12 has a null component");
  for (int k = 0; k < 6; ++k)
    if (!pairs.q1[k] || !pairs.q2[k])
      throw std::invalid_argument("PairBatchView::q1 or q2 has a null component");
}

template <class T>
BatchReport run_batch(const PairBatchView<T>& pairs, const ContactOutputs<T>& out,
                      const BatchOptions& options) {
  check_call(pairs, out, options);
  BatchReport report;
  report.pairs = pairs.size;
  report.isa = resolve_isa(options.isa);
  report.iterations = options.iterations > 0 ? options.iterations
                      : sizeof(T) == sizeof(float) ? default_iterations_float
                                                   : default_iterations_double;
  const std::size_t chunks = (pairs.size + chunk_pairs - 1) / chunk_pairs;
  const int wanted = options.threads > 0 ? options.threads : omp_get_max_threads();
  report.threads = int(std::min<std::size_t>(std::size_t(wanted), std::max<std::size_t>(chunks, 1)));
  if (pairs.size == 0) return report;

  const kernels::KernelTable& table = kernel_table(report.isa);
  // Status scratch for callers who did not ask for statuses.
  std::vector<Status> scratch(out.status ? 0 : pairs.size);
  Status* const status = out.status ? out.status : scratch.data();
  std::size_t fallbacks = 0;
  std::size_t counts[status_count] = {};

#pragma omp parallel num_threads(report.threads) reduction(+ : fallbacks, counts[:status_count])
  {
#pragma omp for schedule(dynamic, 1)
    for (std::size_t c = 0; c < chunks; ++c) {
      const std::size_t begin = c * chunk_pairs;
      const std::size_t n = std::min(chunk_pairs, pairs.size - begin);
      kernels::PairSpan<T> in;
      for (int k = 0; k < 3; ++k) in.r12[k] = pairs.r12[k] + begin;
      for (int k = 0; k < 6; ++k) {
        in.q1[k] = pairs.q1[k] + begin;
        in.q2[k] = pairs.q2[k] + begin;
      }
      const kernels::ResultSpan<T> result{out.mu2 + begin, out.lambda ? out.lambda + begin : nullptr,
                                          status + begin};
      solve_span(table, in, result, n, report.iterations);

      for (std::size_t i = begin; i < begin + n; ++i) {
        if (status[i] == kernels::needs_fallback) {
          // The reference path validates the input too: invalid pairs get
          // their exact status here and are not counted as fallbacks.
          const ContactResult<double> ref = reference_for_pair(pairs, i);
          const bool solved = ref.status == Status::ok || ref.status == Status::not_converged;
          fallbacks += solved;
          out.mu2[i] = T(ref.mu2);
          if (out.lambda) out.lambda[i] = T(ref.lambda);
          status[i] = ref.status == Status::ok ? Status::ok_fallback : ref.status;
        }
        ++counts[static_cast<int>(status[i])];
      }
    }
  }

  report.fallbacks = fallbacks;
  for (int s = 0; s < status_count; ++s) {
    report.status_counts[s] = counts[s];
    if (!is_valid(static_cast<Status>(s))) report.invalid += counts[s];
  }
  return report;
}

}  // namespace

BatchReport contact_function_batch(const PairBatchView<double>& pairs,
                                   const ContactOutputs<double>& out, const BatchOptions& options) {
  return run_batch(pairs, out, options);
}

BatchReport contact_function_batch(const PairBatchView<float>& pairs,
                                   const ContactOutputs<float>& out, const BatchOptions& options) {
  return run_batch(pairs, out, options);
}

}  // namespace pwcontact
