// The batch path: many pairs at once, laid out as structure of arrays,
// processed in SIMD lanes with a fixed number of Newton iterations and
// OpenMP threads. Every lane's convergence is checked afterwards; lanes that
// missed it are recomputed by the scalar reference path (status ok_fallback),
// so the default answer is always as accurate as the reference.
//
// Plain types only: no SIMD headers or compiler flags are needed to use it.
#pragma once

#include <cstddef>
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
  avx2,    // AVX2 with FMA
  avx512,  // AVX-512 F, CD, DQ, BW, VL
};

const char* isa_name(Isa isa) noexcept;                        // "auto", "sse2", ...
std::optional<Isa> parse_isa(std::string_view name) noexcept;  // inverse of isa_name
bool isa_supported(Isa isa) noexcept;  // by this CPU and OS; automatic is always
std::vector<Isa> supported_isas();     // best first, never includes automatic

// The instruction set a batch call with `requested` will use: `requested`
// itself, or for Isa::automatic the environment variable PWCONTACT_ISA
// (auto|sse2|avx2|avx512) if set, else the best supported one.
// Throws std::invalid_argument for an unknown PWCONTACT_ISA value and
// std::runtime_error for an instruction set this CPU does not support.
Isa resolve_isa(Isa requested);

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
};

// Where the results go, `size` elements each. mu2 is required; lambda and
// status may be null when not wanted (the report still counts statuses).
template <class T>
struct ContactOutputs {
  T* mu2 = nullptr;
  T* lambda = nullptr;
  Status* status = nullptr;
};

// Owning SoA storage for pairs, with a view for the batch calls.
template <class T>
class PairBatch {
 public:
  PairBatch() = default;
  explicit PairBatch(std::size_t n) { resize(n); }

  std::size_t size() const noexcept { return r12_[0].size(); }
  void resize(std::size_t n);
  void reserve(std::size_t n);
  void push_back(const T r12[3], const T q1[6], const T q2[6]);
  void set(std::size_t i, const T r12[3], const T q1[6], const T q2[6]);
  // Copies pair i out in the scalar layout (r12[3], q1[6], q2[6]).
  void get(std::size_t i, T r12[3], T q1[6], T q2[6]) const;

  std::vector<T>& r12(int k) { return r12_[k]; }
  std::vector<T>& q1(int k) { return q1_[k]; }
  std::vector<T>& q2(int k) { return q2_[k]; }
  const std::vector<T>& r12(int k) const { return r12_[k]; }
  const std::vector<T>& q1(int k) const { return q1_[k]; }
  const std::vector<T>& q2(int k) const { return q2_[k]; }

  PairBatchView<T> view() const noexcept;

 private:
  std::vector<T> r12_[3], q1_[6], q2_[6];
};

extern template class PairBatch<double>;
extern template class PairBatch<float>;

// ---------------------------------------------------------------------------
// Solving

// Fixed Newton iterations per lane when BatchOptions::iterations is 0,
// chosen by measurement on random pairs (semi-axes in [0.5, 2]): the
// smallest count that, with the convergence check and fallback, gives the
// highest throughput (see README, "Choosing the iteration count").
inline constexpr int default_iterations_double = 4;
inline constexpr int default_iterations_float = 3;

struct BatchOptions {
  int iterations = 0;        // fixed Newton iterations per lane; 0: the default above
  int threads = 0;           // OpenMP threads; 0: omp_get_max_threads()
  Isa isa = Isa::automatic;  // see resolve_isa
};

// What a batch call did.
struct BatchReport {
  std::size_t pairs = 0;
  std::size_t fallbacks = 0;  // valid lanes that missed the convergence check and were
                              // recomputed by the reference path (status ok_fallback or
                              // not_converged)
  std::size_t invalid = 0;    // pairs whose status is not valid (mu2 is NaN)
  std::size_t status_counts[status_count] = {};
  Isa isa = Isa::automatic;   // the instruction set actually used
  int iterations = 0;         // the fixed iteration count actually used
  int threads = 0;            // the thread count actually used
};

// mu^2 (and lambda, status) of every pair of the view. Results do not depend
// on the thread count (bit for bit) and are within the reference path's
// precision of it for every instruction set. Throws std::invalid_argument
// for a malformed call (null pointers, negative counts).
BatchReport contact_function_batch(const PairBatchView<double>& pairs,
                                   const ContactOutputs<double>& out,
                                   const BatchOptions& options = {});
BatchReport contact_function_batch(const PairBatchView<float>& pairs,
                                   const ContactOutputs<float>& out,
                                   const BatchOptions& options = {});

}  // namespace pwcontact
