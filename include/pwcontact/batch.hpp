// The batch path: many pairs at once, laid out as structure of arrays,
// processed in SIMD lanes with a fixed number of Newton iterations and
// OpenMP threads. Every lane's convergence is checked afterwards; lanes that
// missed it are recomputed by the scalar reference path (status ok_fallback),
// so the default answer is always as accurate as the reference.
//
// Plain types only: no SIMD headers or compiler flags are needed to use it.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>
#include <optional>
#include <string_view>
#include <vector>

#include "pwcontact/status.hpp"

namespace pwcontact {

// ---------------------------------------------------------------------------
// Instruction sets

enum class Isa {
  automatic,  // the best this CPU runs, unless PWCONTACT_ISA says otherwise
  sse2,
  avx2,      // AVX2 with FMA
  avx512,    // AVX-512 F, CD, DQ, BW, VL
  fallback,  // portable: each pair on the reference path, one lane; on every
             // CPU, and the only one where pwcontact is built without its x86
             // kernels. Answers at the reference path's accuracy whatever the
             // iteration setting; Accuracy::high as on the other targets.
};

const char* isa_name(Isa isa) noexcept;                        // "auto", "sse2", ..., "fallback"
std::optional<Isa> parse_isa(std::string_view name) noexcept;  // inverse of isa_name
bool isa_supported(Isa isa) noexcept;  // by this CPU and OS (and build); automatic is always
std::vector<Isa> supported_isas();     // best first, never includes automatic; ends with fallback

// The instruction set a batch call with `requested` will use: `requested`
// itself, or for Isa::automatic the environment variable PWCONTACT_ISA
// (auto|sse2|avx2|avx512|fallback) if set, else the best supported one.
// The CPU is examined and PWCONTACT_ISA read once per process, at the first
// call that needs them. Throws std::invalid_argument for an unknown
// PWCONTACT_ISA value and std::runtime_error for an instruction set this
// CPU does not support.
Isa resolve_isa(Isa requested);

// Reads PWCONTACT_ISA again, for a program that changes its own environment
// after its first batch call (resolve_isa reads it once). Not thread-safe:
// call it only while no other thread is in a batch, screen or resolve_isa
// call (as setenv itself requires).
void reread_isa_environment();

// SIMD lanes per register for this instruction set and floating type.
int simd_lanes(Isa isa, bool single_precision);

// ---------------------------------------------------------------------------
// Pairs and results

// Non-owning SoA view of `size` pairs: r12 = c2 - c1 (x, y, z) and the two
// quadratic forms as 6 numbers each (upper triangle, row-major). Every
// pointer must address `size` elements; no alignment is required.
template <class T>
struct PairBatchView {
  std::size_t size = 0;
  const T* r12[3] = {};
  const T* q1[6] = {};
  const T* q2[6] = {};
  // Optional, for contact_function_batch: a lambda to start each pair's
  // Newton iteration from (a warm start, e.g. the pair's lambda at the
  // previous step); NaN or a value outside (0, 1) takes the radial guess.
  // Used by the double-precision kernels (and float ones on float pairs);
  // the answer's accuracy does not depend on it, only the evaluations.
  const T* lambda_start = nullptr;
  // Numbers from one pair to the next in each array of r12, of q1 and of q2
  // (lambda_start is always contiguous): 1 for columns of their own (the
  // structure-of-arrays layout, read fastest), 3 and 6 for the rows of
  // C-ordered (N, 3) and (N, 6) arrays (component k of pair i at
  // r12[k][3 i]: r12[k] = data + k), 0 for one vector or form shared by
  // every pair, negative for arrays read backwards. Strides other than 1
  // are read by gathers, in place: the answers are the same, bit for bit.
  std::ptrdiff_t r12_stride = 1, q1_stride = 1, q2_stride = 1;
};

// Where the results go, `size` elements each. mu2 is required; everything
// else may be null when not wanted, and what is not wanted is not computed
// (the kernels are specialised at compile time for the requested outputs).
// The three-component outputs are all given (three arrays) or all null.
template <class T>
struct ContactOutputs {
  T* mu2 = nullptr;
  T* lambda = nullptr;  // the maximiser lambda_0 of f (theory eq. 6)
  Status* status = nullptr;
  // x0 - c1: where the two ellipsoids, both scaled by mu about their centres,
  // touch (eq. 9a: x0 - c1 = (1 - lambda) Q1 Q^-1 r12), relative to centre 1.
  T* contact_point[3] = {};
  // Unit normal at x0, outward of ellipsoid 1 (towards ellipsoid 2): along
  // Q^-1 r12 (eq. 8).
  T* normal[3] = {};
  // d mu^2 / d r12 = 2 lambda (1 - lambda) Q^-1 r12 (envelope theorem).
  T* gradient[3] = {};
};

// Where an overlap-only answer goes, `size` elements each: overlap[i] is 1
// when mu < cutoff (mu^2 < cutoff^2), else 0; for invalid pairs it is 0 and
// the status says why. overlap is required, status may be null.
struct OverlapOutputs {
  std::uint8_t* overlap = nullptr;
  Status* status = nullptr;
};

namespace detail {
// The large columns' offsets in cache lines, taken in turn (CacheLineAllocator).
inline constexpr unsigned column_staggers = 16;
inline unsigned next_column_stagger() noexcept {
  static std::atomic<unsigned> next{0};
  return next.fetch_add(1, std::memory_order_relaxed) % column_staggers;
}
}  // namespace detail

// An allocator for columns that are read side by side, a register of each at
// the same index (PairBatch's 15).
// - Its storage starts on a 64-byte boundary (a cache line, and one AVX-512
//   register): a column read a register at a time never splits a register
//   between two cache lines.
// - Large columns (from 64 KiB) start 1 to 16 lines past that boundary, in
//   turn, so that a batch's columns are not all at the same address modulo
//   4 KiB, as separately allocated large arrays are (each on pages of its
//   own): the same lines of all 15 would then fall into one set of the
//   32 KiB 8-way L1 cache, more than it has ways.
// Measured on Zen 4, 1M random pairs streamed from memory, one thread, the
// double and mixed-precision full answers (mu^2 only): columns 16 bytes off
// a line and at one offset modulo 4 KiB, as std::vector leaves them,
// 28.3-28.9 and 31.5-32.8 ms; on lines, 25.2-25.5 and 24.2-24.5 ms; on lines
// and a line apart, 23.7-26.4 and 23.3-23.6 ms (README, "Columns on cache
// lines").
template <class T>
struct CacheLineAllocator {
  using value_type = T;
  static constexpr std::size_t line = 64;
  static constexpr std::size_t staggered_from = std::size_t(64) << 10;  // bytes
  static constexpr std::align_val_t alignment{line};

  CacheLineAllocator() noexcept = default;
  template <class U>
  CacheLineAllocator(const CacheLineAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    if (n > (std::size_t(-1) - detail::column_staggers * line) / sizeof(T))
      throw std::bad_array_new_length();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < staggered_from) return static_cast<T*>(::operator new(bytes, alignment));
    // The lines skipped, kept in the last bytes before the column.
    const std::size_t skipped = 1 + detail::next_column_stagger();
    char* const base = static_cast<char*>(::operator new(bytes + skipped * line, alignment));
    char* const column = base + skipped * line;
    std::memcpy(column - sizeof(skipped), &skipped, sizeof(skipped));
    return reinterpret_cast<T*>(column);
  }

  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < staggered_from) return ::operator delete(p, alignment);
    char* const column = reinterpret_cast<char*>(p);
    std::size_t skipped;
    std::memcpy(&skipped, column - sizeof(skipped), sizeof(skipped));
    ::operator delete(column - skipped * line, alignment);
  }

  template <class U>
  bool operator==(const CacheLineAllocator<U>&) const noexcept {
    return true;
  }
  template <class U>
  bool operator!=(const CacheLineAllocator<U>&) const noexcept {
    return false;
  }
};

// Owning SoA storage for pairs, with a view for the batch calls. Its
// columns start on cache lines, large ones staggered (CacheLineAllocator).
template <class T>
class PairBatch {
 public:
  using Column = std::vector<T, CacheLineAllocator<T>>;

  PairBatch() = default;
  explicit PairBatch(std::size_t n) { resize(n); }

  std::size_t size() const noexcept { return r12_[0].size(); }
  void resize(std::size_t n);
  void reserve(std::size_t n);
  void push_back(const T r12[3], const T q1[6], const T q2[6]);
  void set(std::size_t i, const T r12[3], const T q1[6], const T q2[6]);
  // Copies pair i out in the scalar layout (r12[3], q1[6], q2[6]).
  void get(std::size_t i, T r12[3], T q1[6], T q2[6]) const;

  Column& r12(int k) { return r12_[k]; }
  Column& q1(int k) { return q1_[k]; }
  Column& q2(int k) { return q2_[k]; }
  const Column& r12(int k) const { return r12_[k]; }
  const Column& q1(int k) const { return q1_[k]; }
  const Column& q2(int k) const { return q2_[k]; }

  PairBatchView<T> view() const noexcept;

 private:
  Column r12_[3], q1_[6], q2_[6];
};

extern template class PairBatch<double>;
extern template class PairBatch<float>;

// ---------------------------------------------------------------------------
// Solving

// The floating-point arithmetic of the iterations.
enum class Precision {
  automatic,         // that of the inputs: double for double pairs, single for float pairs
  double_precision,  // double pairs only
  single_precision,  // iterate and answer in float (double pairs are rounded to float)
  mixed,             // double pairs only: iterate in float lanes (twice as many per
                     // register), then finish with a double Newton step and a double
                     // convergence check: double accuracy. Measured no faster than
                     // double on Zen 4 (README, "The trade"): loading the pair twice
                     // and the double finish cost what the float steps save.
};

// How accurately the final mu^2 is evaluated.
enum class Accuracy {
  standard,  // plain double (or float): the floor is ~eps times the condition of Q
  high,      // the last evaluation is refined once with an error-free residual
             // (double-double), which squares the conditioning floor: measured
             // within 16 (eps + (eps cond)^2) for status ok, and 16 (eps +
             // eps_long_double cond) for the lanes answered by the reference path
             // in long double (ok_fallback); double or mixed precision only
};

// The Newton iteration the lanes run (both safeguarded by the same bracket).
enum class Formulation {
  automatic,  // the measured best for the precision (see README, "The trade")
  newton,     // Newton on g(lambda) = mu2^2 - mu1^2 (= -f'), in lambda
  log_odds,   // Newton on ln(mu2^2 / mu1^2) in t = ln(lambda / (1 - lambda)):
              // cubic for spheres (doc/theory.md eq. 22), fewer iterations on
              // elongated shapes, but not faster in double since cold solves
              // step on the polynomial form (eq. 46; README)
};

// BatchOptions::iterations: 0 means automatic, 1 .. max_fixed_iterations a
// fixed count (beyond it a call would take minutes per pair batch to no end:
// Newton has long stalled, and the reference path answers what it leaves).
inline constexpr int automatic_iterations = 0;
inline constexpr int max_fixed_iterations = 1000;

struct BatchOptions {
  // Automatic: every lane iterates until its convergence check passes, the
  // lanes still running being regrouped into full SIMD registers between
  // passes, up to max_automatic_iterations; what is left goes to the
  // reference path. Fixed N: every lane runs exactly N evaluations, then the
  // check, then the reference path for those that fail it.
  int iterations = automatic_iterations;
  int threads = 0;           // OpenMP threads, 0 .. 1024; 0: omp_get_max_threads()
  Isa isa = Isa::automatic;  // see resolve_isa
  Precision precision = Precision::automatic;
  Accuracy accuracy = Accuracy::standard;
  Formulation formulation = Formulation::automatic;
};

// The automatic mode's cap on evaluations per lane.
inline constexpr int max_automatic_iterations = 40;

// What a batch call did.
struct BatchReport {
  std::size_t pairs = 0;
  std::size_t fallbacks = 0;  // valid pairs the kernels left (not finished, or in overlap
                              // mode undecided), answered by the reference path
                              // (status ok_fallback, or not_converged if it failed too)
  // Full answers in single precision: pairs the float kernels left that the
  // double kernels finished (status ok, or out_of_range where mu^2 is beyond
  // float's range), before the reference path took what remained. (Overlap
  // answers in single precision decide in float what the cheap bounds decide
  // and solve the rest in double lanes.)
  std::size_t finished_in_double = 0;
  std::size_t invalid = 0;  // pairs whose status is not valid (mu2 is NaN, or
                            // out of the type's range: out_of_range)
  std::size_t status_counts[status_count] = {};
  // Overlap-only calls: pairs decided before any Newton evaluation (by the
  // bounds from the radial and support extents), decided by a certificate
  // after some evaluations, and found overlapping.
  std::size_t decided_by_prefilter = 0;
  std::size_t decided_by_certificate = 0;
  std::size_t overlapping = 0;
  double mean_evaluations = 0;                 // (f, g, g') evaluations per pair in the kernels,
                                               // SIMD lanes included, reference path excluded
  Isa isa = Isa::automatic;                    // the instruction set actually used
  int iterations = 0;                          // the iteration setting used (0: automatic)
  Precision precision = Precision::automatic;  // as resolved
  Formulation formulation = Formulation::automatic;  // as resolved
  Accuracy accuracy = Accuracy::standard;
  int threads = 0;  // the thread count actually used
};

const char* precision_name(Precision p) noexcept;      // "auto", "double", "float", "mixed"
const char* accuracy_name(Accuracy a) noexcept;        // "standard", "high"
const char* formulation_name(Formulation f) noexcept;  // "auto", "newton", "log_odds"
std::optional<Precision> parse_precision(std::string_view name) noexcept;
std::optional<Accuracy> parse_accuracy(std::string_view name) noexcept;
std::optional<Formulation> parse_formulation(std::string_view name) noexcept;

// mu^2 (and whatever else `out` asks for) of every pair of the view.
//
// Accuracy: mu^2 to the floor of the arithmetic (double: ~eps times the
// condition of Q; Accuracy::high removes the conditioning). A lane is
// finished when one more Newton step would change f by less than 1e-11 f and
// mu^2 is then f plus that predicted gain (a third-order error). When lambda
// or a geometric output is asked for, the threshold is 1e-13 f, which puts
// lambda within ~1e-12 of the maximiser on compact shapes (on elongated ones
// the floor of evaluating f sets it: measured 1.4e-12 on pw85's sample and
// 9.1e-11 on aspect ratios to 1e4; mu1^2 = mu2^2 = mu^2 at the returned
// lambda to ~3e-11 on the peer library's family); mu^2 alone is
// therefore computed faster, and may differ in the last bits from the mu^2
// of a call that asks for lambda.
//
// Results do not depend on the thread count or on a pair's position in the
// batch (bit for bit) and are within the reference path's precision of it
// for every instruction set (but lambda, and the geometry built on it, of
// pairs beyond aspect ratios ~1e4, where f is flat: there the convergence
// test above stops short of the reference path's lambda; see README, "Known
// limits"). Throws std::invalid_argument for a malformed call (null
// pointers, negative counts, which as std::size_t are beyond the 2^36 pairs
// a call takes, an option the input type does not support).
BatchReport contact_function_batch(const PairBatchView<double>& pairs,
                                   const ContactOutputs<double>& out,
                                   const BatchOptions& options = {});
BatchReport contact_function_batch(const PairBatchView<float>& pairs,
                                   const ContactOutputs<float>& out,
                                   const BatchOptions& options = {});

// Adds the report of one call to `total`, for callers that split a batch
// into several calls: counts summed, mean_evaluations weighted by pairs, the
// settings (isa, precision, ...) as the call's.
void add_report(BatchReport& total, const BatchReport& call);

// Overlap only: whether mu < cutoff for every pair, decided with certificates
// so that most pairs need few or no Newton evaluations: before any, the
// radial extents along r12 bound mu^2 from above (they lie inside both
// ellipsoids) and the support extents along r12 bound it from below (a
// separating plane); after each, f(lambda) bounds mu^2 from below and the
// tangents of the concave f at the bracket ends bound it from above. A pair
// is decided when a bound clears cutoff^2 by more than its rounding error;
// pairs still undecided when the automatic iterations end are decided by the
// reference path. The answer agrees with mu^2 < cutoff^2 whenever
// |mu^2 - cutoff^2| > 1e-9 cutoff^2 in double precision, for Q conditioned
// up to ~1e8 (see README). cutoff must be positive and finite.
BatchReport overlap_batch(const PairBatchView<double>& pairs, const OverlapOutputs& out,
                          const BatchOptions& options = {}, double cutoff = 1);
BatchReport overlap_batch(const PairBatchView<float>& pairs, const OverlapOutputs& out,
                          const BatchOptions& options = {}, double cutoff = 1);

}  // namespace pwcontact
