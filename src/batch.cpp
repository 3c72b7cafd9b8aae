// The batch driver: resolves the options, splits the pairs into chunks, runs
// the chosen kernel on each chunk in OpenMP threads, and answers with the
// reference path the lanes the kernels left (status needs_fallback): lanes
// that did not converge or stayed undecided, and lanes whose input failed the
// kernels' cheap checks, which the reference path validates exactly. In
// single precision the lanes the float kernels leave go to the double
// kernels first (finish_in_double), and only what those leave to the
// reference path. (The single-precision overlap kernels do that themselves:
// their accurate solve runs in double lanes.)
#include <omp.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "kernels/kernel_api.hpp"
#include "number_text.hpp"
#include "pair_overlap_solver.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/batch.hpp"
#include "pwcontact/reference.hpp"
#include "thread_count.hpp"

namespace pwcontact {
namespace {

// Pairs per chunk: a multiple of every kernel's block (lanes times
// interleaved groups: 4 to 48), so that only a batch's last chunk has a
// padded tail; small enough to balance threads and to keep a chunk's kept
// lanes in cache, large enough that the scheduling cost (~1 us) is noise
// next to the work (~60 us).
constexpr std::size_t chunk_pairs = 48 * 48;

template <class T>
constexpr bool single_input = std::is_same<T, float>::value;

// The options with nothing left automatic, checked against the input type.
template <class T>
BatchReport resolve(const BatchOptions& options, std::size_t pairs) {
  if (options.iterations < 0 || options.iterations > max_fixed_iterations)
    throw std::invalid_argument("BatchOptions::iterations must be 0 (automatic) or a count 1 .. " +
                                std::to_string(max_fixed_iterations) + ", got " +
                                std::to_string(options.iterations));
  detail::thread_count(options.threads, "BatchOptions::threads");
  // Values cast from outside their enumerations: refused, not taken for a
  // default.
  auto check_enum = [](const char* name, int value, int last) {
    if (value < 0 || value > last)
      throw std::invalid_argument(std::string("BatchOptions::") + name + ": " +
                                  std::to_string(value) + " is not one of its values");
  };
  check_enum("precision", int(options.precision), int(Precision::mixed));
  check_enum("accuracy", int(options.accuracy), int(Accuracy::high));
  check_enum("formulation", int(options.formulation), int(Formulation::log_odds));
  BatchReport report;
  report.pairs = pairs;
  report.isa = resolve_isa(options.isa);
  report.iterations = options.iterations;
  report.precision = options.precision;
  report.accuracy = options.accuracy;
  if (report.precision == Precision::automatic)
    report.precision = single_input<T> ? Precision::single_precision : Precision::double_precision;
  if (single_input<T> && report.precision != Precision::single_precision)
    throw std::invalid_argument(std::string("float pairs are solved in single precision, not ") +
                                precision_name(report.precision));
  if (options.accuracy == Accuracy::high && report.precision == Precision::single_precision)
    throw std::invalid_argument(
        "Accuracy::high refines the answer in double: it needs double or mixed precision");
  // Newton on g: measured at least as fast as log_odds wherever the targets
  // are set (README, "The trade"); log_odds needs fewer iterations on the
  // most elongated shapes but costs more per iteration.
  report.formulation =
      options.formulation == Formulation::automatic ? Formulation::newton : options.formulation;
  const std::size_t chunks = (pairs + chunk_pairs - 1) / chunk_pairs;
  const int wanted = detail::thread_count(options.threads, "BatchOptions::threads");
  report.threads =
      int(std::min<std::size_t>(std::size_t(wanted), std::max<std::size_t>(chunks, 1)));
  return report;
}

template <class T>
void check_pairs(const PairBatchView<T>& pairs) {
  for (const T* p : pairs.r12)
    if (!p) throw std::invalid_argument("PairBatchView::r12 has a null component");
  for (int k = 0; k < 6; ++k)
    if (!pairs.q1[k] || !pairs.q2[k])
      throw std::invalid_argument("PairBatchView::q1 or q2 has a null component");
  // The gathers of a block offset by up to 15 strides in the kernels' index
  // type (32 bits for float).
  constexpr std::ptrdiff_t largest = std::ptrdiff_t(1) << 26;
  for (std::ptrdiff_t stride : {pairs.r12_stride, pairs.q1_stride, pairs.q2_stride})
    if (stride > largest || stride < -largest)
      throw std::invalid_argument("PairBatchView: a stride of " + std::to_string(stride) +
                                  " numbers is beyond +-2^26");
  // A count whose pairs the strides cannot address (a negative count
  // converted to std::size_t, most likely): size -1 computed nothing and
  // returned, -3000 read and wrote far beyond the arrays.
  constexpr std::size_t most = std::size_t(1) << 36;  // x 2^26 numbers: within std::ptrdiff_t
  if (pairs.size > most)
    throw std::invalid_argument("PairBatchView: " + std::to_string(pairs.size) +
                                " pairs, more than 2^36 (a negative count converted to "
                                "std::size_t?)");
}

// Which optional outputs are asked for; a three-component output is all
// three arrays or none.
template <class T>
unsigned output_bits(const ContactOutputs<T>& out) {
  unsigned bits = out.lambda ? unsigned(kernels::with_lambda) : 0u;
  auto triple = [&](T* const(&v)[3], unsigned bit, const char* name) {
    const int given = (v[0] != nullptr) + (v[1] != nullptr) + (v[2] != nullptr);
    if (given != 0 && given != 3)
      throw std::invalid_argument(std::string("ContactOutputs::") + name +
                                  " needs all three components or none");
    if (given == 3) bits |= bit;
  };
  triple(out.contact_point, kernels::with_contact_point, "contact_point");
  triple(out.normal, kernels::with_normal, "normal");
  triple(out.gradient, kernels::with_gradient, "gradient");
  return bits;
}

// One pair in the scalar layout, in double: the reference path always runs
// in double, also for float batches (a lane that failed in float gets the
// better answer, rounded once to float).
struct ScalarPair {
  double r[3], q1[6], q2[6];
};

template <class T>
ScalarPair scalar_pair(const PairBatchView<T>& pairs, std::size_t i) {
  ScalarPair p;
  const std::ptrdiff_t at = std::ptrdiff_t(i);
  for (int k = 0; k < 3; ++k) p.r[k] = pairs.r12[k][at * pairs.r12_stride];
  for (int k = 0; k < 6; ++k) {
    p.q1[k] = pairs.q1[k][at * pairs.q1_stride];
    p.q2[k] = pairs.q2[k][at * pairs.q2_stride];
  }
  return p;
}

// Accuracy::high for the pairs the kernels leave: the reference path in long
// double (64-bit significand), whose floor is ~2000 times below double's.
ContactResult<double> reference_in_long_double(const ScalarPair& p) {
  long double r[3], q1[6], q2[6];
  for (int k = 0; k < 3; ++k) r[k] = p.r[k];
  for (int k = 0; k < 6; ++k) {
    q1[k] = p.q1[k];
    q2[k] = p.q2[k];
  }
  const ContactResult<long double> ref = contact_function<long double>(r, q1, q2);
  return {double(ref.mu2), double(ref.lambda), ref.status, ref.iterations};
}

template <class T>
kernels::PairSpan<T> span_at(const PairBatchView<T>& pairs, std::size_t begin) {
  kernels::PairSpan<T> in;
  in.lambda_start = pairs.lambda_start ? pairs.lambda_start + begin : nullptr;
  const std::ptrdiff_t at = std::ptrdiff_t(begin);
  for (int k = 0; k < 3; ++k) in.r12[k] = pairs.r12[k] + at * pairs.r12_stride;
  for (int k = 0; k < 6; ++k) {
    in.q1[k] = pairs.q1[k] + at * pairs.q1_stride;
    in.q2[k] = pairs.q2[k] + at * pairs.q2_stride;
  }
  in.stride[0] = pairs.r12_stride;
  in.stride[1] = pairs.q1_stride;
  in.stride[2] = pairs.q2_stride;
  return in;
}

// The kernels' memory for one chunk, one block per thread that runs them
// (the caller's and OpenMP's pool threads), 64-byte aligned, allocated on a
// thread's first call and kept: a fresh block per call (550 KB, from mmap)
// cost more than the solve of a small batch (measured: 1.5 us a call for 16
// pairs, most of it the allocation, its page faults and the thread team).
kernels::Scratch thread_scratch() {
  struct Block {
    std::unique_ptr<unsigned char[]> storage;
    kernels::Scratch scratch{};
  };
  thread_local Block block;
  if (!block.storage) {
    const std::size_t bytes = kernels::scratch_bytes(chunk_pairs);
    block.storage.reset(new unsigned char[bytes + 64]);
    unsigned char* base = block.storage.get();
    base += (64 - reinterpret_cast<std::uintptr_t>(base) % 64) % 64;
    block.scratch = {base, chunk_pairs};
  }
  return block.scratch;
}

// What the driver counts per chunk, while the chunk's results are in cache
// (a pass over the whole batch afterwards would cost several % of a call).
struct ChunkTally {
  std::size_t fallbacks = 0;
  std::size_t finished_in_double = 0;
  std::size_t status_counts[status_count] = {};
  std::size_t overlapping = 0;

  void add(const ChunkTally& other) {
    fallbacks += other.fallbacks;
    finished_in_double += other.finished_in_double;
    for (int s = 0; s < status_count; ++s) status_counts[s] += other.status_counts[s];
    overlapping += other.overlapping;
  }
};

// Runs `solve_chunk(begin, n, scratch, counters, tally)` over the chunks in
// parallel and sums what the chunks counted into the report.
template <class SolveChunk>
void run_chunks(std::size_t pairs, BatchReport& report, SolveChunk&& solve_chunk) {
  const std::size_t chunks = (pairs + chunk_pairs - 1) / chunk_pairs;
  std::uint64_t evaluations = 0, prefilter = 0, certificate = 0;
  ChunkTally total;
  auto solve = [&](std::size_t c, const kernels::Scratch& scratch, ChunkTally& tally,
                   std::uint64_t& evaluated, std::uint64_t& by_prefilter,
                   std::uint64_t& by_certificate) {
    const std::size_t begin = c * chunk_pairs;
    kernels::ChunkCounters counters;
    solve_chunk(begin, std::min(chunk_pairs, pairs - begin), scratch, counters, tally);
    evaluated += counters.lane_evaluations;
    by_prefilter += counters.decided_by_prefilter;
    by_certificate += counters.decided_by_certificate;
  };
  if (report.threads == 1 || chunks <= 1) {
    // In the calling thread, without a thread team.
    const kernels::Scratch scratch = thread_scratch();
    for (std::size_t c = 0; c < chunks; ++c)
      solve(c, scratch, total, evaluations, prefilter, certificate);
  } else {
    detail::ParallelErrors errors;  // (nothing in a chunk is expected to throw)
#pragma omp parallel num_threads(report.threads) reduction(+ : evaluations, prefilter, certificate)
    {
      const kernels::Scratch scratch = thread_scratch();
      ChunkTally tally;
#pragma omp for schedule(dynamic, 1)
      for (std::size_t c = 0; c < chunks; ++c)
        errors.run([&] { solve(c, scratch, tally, evaluations, prefilter, certificate); });
#pragma omp critical(pwcontact_tally)
      total.add(tally);
    }
    errors.rethrow_if_failed();
  }
  report.fallbacks = total.fallbacks;
  report.finished_in_double = total.finished_in_double;
  for (int s = 0; s < status_count; ++s) {
    report.status_counts[s] = total.status_counts[s];
    if (!is_valid(static_cast<Status>(s))) report.invalid += total.status_counts[s];
  }
  report.overlapping = total.overlapping;
  report.decided_by_prefilter = prefilter;
  report.decided_by_certificate = certificate;
  report.mean_evaluations = pairs ? double(evaluations) / double(pairs) : 0;
}

// Calls `visit(i)` for every lane i of [begin, begin + n) that the kernels
// left (status needs_fallback), in order; returns how many. Found with
// memchr: on compact shapes a chunk leaves few lanes if any, and a byte scan
// measured 3 % of a float solve.
template <class Visit>
std::size_t for_each_left_lane(const Status* status, std::size_t begin, std::size_t n,
                               Visit&& visit) {
  static_assert(sizeof(Status) == 1, "statuses are searched for as bytes");
  const unsigned char* const first = reinterpret_cast<const unsigned char*>(status);
  const unsigned char* at = first + begin;
  const unsigned char* const end = at + n;
  std::size_t left = 0;
  while (const void* found =
             std::memchr(at, int(std::uint8_t(kernels::needs_fallback)), std::size_t(end - at))) {
    at = static_cast<const unsigned char*>(found) + 1;
    visit(std::size_t(static_cast<const unsigned char*>(found) - first));
    ++left;
  }
  return left;
}

// Calls `answer(i)` for every lane of [begin, begin + n) the kernels left
// (they wrote ok or needs_fallback for every lane), which gives it its final
// status, and tallies the chunk's statuses (but for `counted` lanes whose
// status finish_in_double counted).
template <class Answer>
void answer_left_lanes(Status* status, std::size_t begin, std::size_t n, ChunkTally& tally,
                       Answer&& answer, std::size_t counted = 0) {
  const std::size_t left = for_each_left_lane(status, begin, n, [&](std::size_t i) {
    answer(i);
    ++tally.status_counts[static_cast<int>(status[i])];
  });
  tally.status_counts[static_cast<int>(Status::ok)] += n - left - counted;
}

// The lanes of a chunk that a single-precision kernel left, gathered and
// widened (exactly) into double lanes, with room for the double kernels'
// answers: one per thread, sized for a chunk, allocated on first use.
struct WideLanes {
  std::vector<double> values[15];       // r12 (3), q1 (6), q2 (6)
  std::vector<std::uint32_t> position;  // in the chunk
  std::vector<Status> status;
  std::vector<double> mu2, lambda, geometry[9];
  std::size_t count = 0;

  WideLanes() {
    for (auto& v : values) v.resize(chunk_pairs);
    position.resize(chunk_pairs);
    status.resize(chunk_pairs);
  }
  kernels::PairSpan<double> span() const {
    kernels::PairSpan<double> in;
    for (int k = 0; k < 3; ++k) in.r12[k] = values[k].data();
    for (int k = 0; k < 6; ++k) {
      in.q1[k] = values[3 + k].data();
      in.q2[k] = values[9 + k].data();
    }
    return in;
  }
};

WideLanes& thread_wide_lanes() {
  thread_local WideLanes lanes;
  return lanes;
}

// Gathers the lanes of [begin, begin + n) left with status needs_fallback.
template <class T>
WideLanes& gather_left_lanes(const PairBatchView<T>& pairs, const Status* status, std::size_t begin,
                             std::size_t n) {
  WideLanes& wide = thread_wide_lanes();
  wide.count = 0;
  for_each_left_lane(status, begin, n, [&](std::size_t i) {
    const ScalarPair p = scalar_pair(pairs, i);
    const std::size_t c = wide.count++;
    for (int k = 0; k < 3; ++k) wide.values[k][c] = p.r[k];
    for (int k = 0; k < 6; ++k) {
      wide.values[3 + k][c] = p.q1[k];
      wide.values[9 + k][c] = p.q2[k];
    }
    wide.position[c] = std::uint32_t(i - begin);
  });
  return wide;
}

// The number of ones among n bytes that are each 0 or 1: eight at a time,
// summed into the top byte by one multiplication (at most 8, no carry; a
// popcount instruction is not in the baseline instruction set this file is
// compiled for, and its library replacement measured slower).
std::size_t count_ones(const std::uint8_t* bytes, std::size_t n) {
  std::size_t ones = 0, i = 0;
  for (; i + 8 <= n; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, bytes + i, 8);
    ones += std::size_t((word * 0x0101010101010101ull) >> 56);
  }
  for (; i < n; ++i) ones += bytes[i];
  return ones;
}

kernels::ChunkSettings chunk_settings(const BatchReport& report, const BatchOptions& options) {
  kernels::ChunkSettings settings{};
  settings.iterations = report.iterations;
  settings.max_iterations = max_automatic_iterations;
  settings.formulation = report.formulation;
  settings.accuracy = options.accuracy;
  return settings;
}

template <class T>
kernels::FullKernel<T, T> full_kernel(const kernels::KernelTable& table, Precision precision) {
  if constexpr (single_input<T>) {
    return table.full_float;
  } else {
    switch (precision) {
      case Precision::mixed: return table.full_mixed;
      case Precision::single_precision: return table.full_single;
      default: return table.full_double;
    }
  }
}

template <class T>
kernels::OverlapKernel<T> overlap_kernel(const kernels::KernelTable& table, Precision precision) {
  if constexpr (single_input<T>) {
    return table.overlap_float;
  } else {
    switch (precision) {
      case Precision::mixed: return table.overlap_mixed;
      case Precision::single_precision: return table.overlap_single;
      default: return table.overlap_double;
    }
  }
}

// The reference path's answer for a pair the kernels left, with the outputs
// asked for; returns whether it counts as a fallback (a valid pair the kernels
// did not finish, as opposed to an invalid one). The answer is checked
// against the range of the output type (T, or double for a long double
// answer): a mu^2 beyond it is out_of_range, never a valid infinity or zero.
template <class T>
bool answer_with_reference(const PairBatchView<T>& pairs, const ContactOutputs<T>& out,
                           Status* status, std::size_t i, unsigned bits, Accuracy accuracy) {
  const ScalarPair p = scalar_pair(pairs, i);
  const ContactResult<double> ref = accuracy == Accuracy::high
                                        ? reference_in_long_double(p)
                                        : contact_function<double>(p.r, p.q1, p.q2);
  const bool solved = ref.status == Status::ok || ref.status == Status::out_of_range;
  out.mu2[i] = T(ref.mu2);
  if (bits & kernels::with_lambda) out.lambda[i] = T(ref.lambda);
  if (bits & ~unsigned(kernels::with_lambda)) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    ContactGeometry<double> g{{nan, nan, nan}, {nan, nan, nan}, {nan, nan, nan}};
    if (solved) g = contact_geometry<double>(p.r, p.q1, p.q2, ref.lambda);
    for (int k = 0; k < 3; ++k) {
      if (bits & kernels::with_contact_point) out.contact_point[k][i] = T(g.contact_point[k]);
      if (bits & kernels::with_normal) out.normal[k][i] = T(g.normal[k]);
      if (bits & kernels::with_gradient) out.gradient[k][i] = T(g.gradient[k]);
    }
  }
  // (mu^2 = 0 is the exact answer for coincident centres.)
  const bool coincident = p.r[0] == 0 && p.r[1] == 0 && p.r[2] == 0;
  if (solved)
    status[i] = coincident || detail::range_status(out.mu2[i]) == Status::ok ? Status::ok_fallback
                                                                             : Status::out_of_range;
  else
    status[i] = ref.status;
  return solved || ref.status == Status::not_converged;
}

// Single precision: the lanes the float kernel left in [begin, begin + n),
// finished by the double kernel (exactly widened: the same pairs) before any
// goes to the reference path. The float kernels leave the lanes whose
// factorisation shows element growth beyond what float resolves (elongated
// shapes: 41 % of the pw85 family's lanes) besides those that did not
// converge; a double lane costs a few evaluations where the reference path
// costs a scalar solve. Answers are rounded once to T, and a mu^2 beyond T's
// range is out_of_range, as the reference path's. Returns how many lanes it
// finished with out_of_range (their statuses counted here).
template <class T>
std::size_t finish_in_double(const PairBatchView<T>& pairs, const ContactOutputs<T>& out,
                             Status* status, std::size_t begin, std::size_t n, unsigned bits,
                             kernels::FullKernel<double, double> kernel,
                             const kernels::ChunkSettings& settings,
                             const kernels::Scratch& scratch, kernels::ChunkCounters& counters,
                             ChunkTally& tally) {
  WideLanes& wide = gather_left_lanes(pairs, status, begin, n);
  if (wide.count == 0) return 0;
  auto room = [](std::vector<double>& v) {
    if (v.empty()) v.resize(chunk_pairs);
    return v.data();
  };
  kernels::ResultSpan<double> result{room(wide.mu2),
                                     bits & kernels::with_lambda ? room(wide.lambda) : nullptr,
                                     wide.status.data(),
                                     {},
                                     {},
                                     {}};
  for (int k = 0; k < 3; ++k) {
    if (bits & kernels::with_contact_point) result.contact_point[k] = room(wide.geometry[k]);
    if (bits & kernels::with_normal) result.normal[k] = room(wide.geometry[3 + k]);
    if (bits & kernels::with_gradient) result.gradient[k] = room(wide.geometry[6 + k]);
  }
  kernel(wide.span(), result, wide.count, settings, scratch, counters);
  std::size_t out_of_range = 0;
  for (std::size_t c = 0; c < wide.count; ++c) {
    if (wide.status[c] != Status::ok) continue;  // (needs_fallback: the reference path's)
    const std::size_t i = begin + wide.position[c];
    out.mu2[i] = T(wide.mu2[c]);
    if (bits & kernels::with_lambda) out.lambda[i] = T(wide.lambda[c]);
    for (int k = 0; k < 3; ++k) {
      if (bits & kernels::with_contact_point) out.contact_point[k][i] = T(wide.geometry[k][c]);
      if (bits & kernels::with_normal) out.normal[k][i] = T(wide.geometry[3 + k][c]);
      if (bits & kernels::with_gradient) out.gradient[k][i] = T(wide.geometry[6 + k][c]);
    }
    // (A valid kernel answer is 0 only for coincident centres, exactly.)
    const bool in_range = wide.mu2[c] == 0 || detail::range_status(out.mu2[i]) == Status::ok;
    status[i] = in_range ? Status::ok : Status::out_of_range;
    if (!in_range) {
      ++out_of_range;
      ++tally.status_counts[static_cast<int>(Status::out_of_range)];
    }
    ++tally.finished_in_double;
  }
  return out_of_range;
}

template <class T>
BatchReport full_batch(const PairBatchView<T>& pairs, const ContactOutputs<T>& out,
                       const BatchOptions& options) {
  BatchReport report = resolve<T>(options, pairs.size);
  if (pairs.size == 0) return report;
  check_pairs(pairs);
  if (!out.mu2) throw std::invalid_argument("ContactOutputs::mu2 must not be null");
  const unsigned bits = output_bits(out);
  kernels::ChunkSettings settings = chunk_settings(report, options);
  settings.outputs = bits;
  const auto kernel = full_kernel<T>(kernels::kernels_for(report.isa), report.precision);
  const bool single = report.precision == Precision::single_precision;
  const auto double_kernel = kernels::kernels_for(report.isa).full_double;

  // Statuses are needed to find the lanes left to the reference path.
  std::vector<Status> scratch_status(out.status ? 0 : pairs.size);
  Status* const status = out.status ? out.status : scratch_status.data();
  run_chunks(
      pairs.size, report,
      [&](std::size_t begin, std::size_t n, const kernels::Scratch& scratch,
          kernels::ChunkCounters& counters, ChunkTally& tally) {
        kernels::ResultSpan<T> result{
            out.mu2 + begin, out.lambda ? out.lambda + begin : nullptr, status + begin, {}, {}, {}};
        for (int k = 0; k < 3; ++k) {
          if (bits & kernels::with_contact_point)
            result.contact_point[k] = out.contact_point[k] + begin;
          if (bits & kernels::with_normal) result.normal[k] = out.normal[k] + begin;
          if (bits & kernels::with_gradient) result.gradient[k] = out.gradient[k] + begin;
        }
        kernel(span_at(pairs, begin), result, n, settings, scratch, counters);
        const std::size_t counted =
            single ? finish_in_double(pairs, out, status, begin, n, bits, double_kernel, settings,
                                      scratch, counters, tally)
                   : 0;
        answer_left_lanes(
            status, begin, n, tally,
            [&](std::size_t i) {
              tally.fallbacks +=
                  answer_with_reference(pairs, out, status, i, bits, options.accuracy);
            },
            counted);
      });
  return report;
}

// Overlap answers: the options and cutoff checked, the settings resolved.
template <class T>
kernels::ChunkSettings overlap_settings(const BatchReport& report, const BatchOptions& options,
                                        double cutoff) {
  if (!(cutoff > 0) || !std::isfinite(cutoff))
    throw std::invalid_argument("overlap_batch: cutoff must be positive and finite, got " +
                                detail::number_text(cutoff));
  // mu^2 is compared with cutoff^2: it must be a normal number.
  if (!(cutoff * cutoff >= std::numeric_limits<double>::min()) || !std::isfinite(cutoff * cutoff))
    throw std::invalid_argument(
        "overlap_batch: the cutoff's square is outside the range of normal doubles, cutoff " +
        detail::number_text(cutoff));
  if (options.accuracy == Accuracy::high)
    throw std::invalid_argument(
        "overlap_batch: Accuracy::high applies to mu^2, not to overlap answers");
  kernels::ChunkSettings settings = chunk_settings(report, options);
  settings.cutoff_mu2 = cutoff * cutoff;
  return settings;
}

// Pair i that the overlap kernels left, answered by the reference path;
// whether it counts as a fallback.
template <class T>
bool answer_overlap_with_reference(const PairBatchView<T>& pairs, const OverlapOutputs& out,
                                   std::size_t i, double cutoff_mu2) {
  const ScalarPair p = scalar_pair(pairs, i);
  ContactResult<double> ref = contact_function<double>(p.r, p.q1, p.q2);
  // The double reference path errs by up to ~16 eps cond(Q(lambda*)): 4e-7
  // at cond 1e8, where the overlap answers promise the side of the cutoff
  // beyond 1e-9 of it (a pair 6e-9 beyond tangency at cond 7e7 was answered
  // overlapping). Within 1e-6 of the cutoff (cond to ~3e8) the long-double
  // path decides, whose error there is below 16 eps_ld cond ~ 2e-10.
  if (ref.status == Status::ok && std::abs(ref.mu2 - cutoff_mu2) <= 1e-6 * cutoff_mu2) {
    const ContactResult<double> refined = reference_in_long_double(p);
    if (refined.status == Status::ok) ref = refined;
  }
  // A mu^2 out of range (infinite, or below the smallest normal number)
  // still decides the overlap exactly.
  const bool solved = ref.status == Status::ok || ref.status == Status::out_of_range;
  out.overlap[i] = solved && ref.mu2 < cutoff_mu2;
  out.status[i] = solved ? Status::ok_fallback : ref.status;
  return solved || ref.status == Status::not_converged;
}

template <class T>
BatchReport overlap_only(const PairBatchView<T>& pairs, const OverlapOutputs& out,
                         const BatchOptions& options, double cutoff) {
  BatchReport report = resolve<T>(options, pairs.size);
  const kernels::ChunkSettings settings = overlap_settings<T>(report, options, cutoff);
  if (pairs.size == 0) return report;
  check_pairs(pairs);
  if (!out.overlap) throw std::invalid_argument("OverlapOutputs::overlap must not be null");
  const auto kernel = overlap_kernel<T>(kernels::kernels_for(report.isa), report.precision);

  std::vector<Status> scratch_status(out.status ? 0 : pairs.size);
  const OverlapOutputs all{out.overlap, out.status ? out.status : scratch_status.data()};
  run_chunks(pairs.size, report,
             [&](std::size_t begin, std::size_t n, const kernels::Scratch& scratch,
                 kernels::ChunkCounters& counters, ChunkTally& tally) {
               kernel(span_at(pairs, begin), {all.overlap + begin, all.status + begin}, n, settings,
                      scratch, counters);
               answer_left_lanes(all.status, begin, n, tally, [&](std::size_t i) {
                 tally.fallbacks +=
                     answer_overlap_with_reference(pairs, all, i, settings.cutoff_mu2);
               });
               tally.overlapping += count_ones(all.overlap + begin, n);
             });
  return report;
}

}  // namespace

namespace detail {

// Calls of at most this many pairs (a trial move's few undecided
// candidates) run on 256-bit lanes where the resolved instruction set is
// AVX-512: its blocks of 3 x 8 lanes would evaluate mostly padding for them,
// an AVX2 block (2 x 4 lanes) less. Measured on the trial moves of a packing
// at 0.5 (3.5 pairs a call): 1,600 cycles a call on AVX-512, 790 on AVX2,
// 1,020 on SSE2.
constexpr std::size_t narrow_call_pairs = 8;

struct PairOverlapSolver::State {
  kernels::ChunkSettings settings;
  kernels::OverlapKernel<double> kernel;
  kernels::OverlapKernel<double> narrow_kernel;  // for calls of narrow_call_pairs or fewer
  std::size_t capacity;
  std::unique_ptr<unsigned char[]> storage;
  kernels::Scratch scratch;
};

PairOverlapSolver::PairOverlapSolver(const BatchOptions& options, double cutoff,
                                     std::size_t capacity)
    : state_(new State) {
  const BatchReport report = resolve<double>(options, capacity);
  state_->settings = overlap_settings<double>(report, options, cutoff);
  state_->kernel = overlap_kernel<double>(kernels::kernels_for(report.isa), report.precision);
  state_->narrow_kernel =
      report.isa == Isa::avx512 && isa_supported(Isa::avx2)
          ? overlap_kernel<double>(kernels::kernels_for(Isa::avx2), report.precision)
          : state_->kernel;
  state_->capacity = capacity;
  const std::size_t bytes = kernels::scratch_bytes(capacity);
  state_->storage.reset(new unsigned char[bytes + 64]);
  unsigned char* base = state_->storage.get();
  base += (64 - reinterpret_cast<std::uintptr_t>(base) % 64) % 64;
  state_->scratch = {base, capacity};
}

PairOverlapSolver::~PairOverlapSolver() = default;
PairOverlapSolver::PairOverlapSolver(PairOverlapSolver&&) noexcept = default;
PairOverlapSolver& PairOverlapSolver::operator=(PairOverlapSolver&&) noexcept = default;

std::size_t PairOverlapSolver::capacity() const noexcept { return state_->capacity; }

void PairOverlapSolver::solve(const PairBatchView<double>& pairs, std::uint8_t* overlap,
                              Status* status) {
  if (pairs.size > state_->capacity)
    throw std::invalid_argument("PairOverlapSolver: " + std::to_string(pairs.size) +
                                " pairs for a capacity of " + std::to_string(state_->capacity));
  if (pairs.size == 0) return;
  kernels::ChunkCounters counters;
  const auto kernel = pairs.size <= narrow_call_pairs ? state_->narrow_kernel : state_->kernel;
  kernel(span_at(pairs, 0), {overlap, status}, pairs.size, state_->settings, state_->scratch,
         counters);
  const OverlapOutputs out{overlap, status};
  for (std::size_t i = 0; i < pairs.size; ++i)
    if (status[i] == kernels::needs_fallback)
      answer_overlap_with_reference(pairs, out, i, state_->settings.cutoff_mu2);
}

}  // namespace detail

BatchReport contact_function_batch(const PairBatchView<double>& pairs,
                                   const ContactOutputs<double>& out, const BatchOptions& options) {
  return full_batch(pairs, out, options);
}

BatchReport contact_function_batch(const PairBatchView<float>& pairs,
                                   const ContactOutputs<float>& out, const BatchOptions& options) {
  return full_batch(pairs, out, options);
}

BatchReport overlap_batch(const PairBatchView<double>& pairs, const OverlapOutputs& out,
                          const BatchOptions& options, double cutoff) {
  return overlap_only(pairs, out, options, cutoff);
}

BatchReport overlap_batch(const PairBatchView<float>& pairs, const OverlapOutputs& out,
                          const BatchOptions& options, double cutoff) {
  return overlap_only(pairs, out, options, cutoff);
}

void add_report(BatchReport& total, const BatchReport& call) {
  const double evaluations =
      total.mean_evaluations * double(total.pairs) + call.mean_evaluations * double(call.pairs);
  total.pairs += call.pairs;
  total.fallbacks += call.fallbacks;
  total.finished_in_double += call.finished_in_double;
  total.invalid += call.invalid;
  for (int s = 0; s < status_count; ++s) total.status_counts[s] += call.status_counts[s];
  total.decided_by_prefilter += call.decided_by_prefilter;
  total.decided_by_certificate += call.decided_by_certificate;
  total.overlapping += call.overlapping;
  total.mean_evaluations = total.pairs ? evaluations / double(total.pairs) : 0;
  total.isa = call.isa;
  total.iterations = call.iterations;
  total.precision = call.precision;
  total.formulation = call.formulation;
  total.accuracy = call.accuracy;
  total.threads = call.threads;
}

}  // namespace pwcontact
