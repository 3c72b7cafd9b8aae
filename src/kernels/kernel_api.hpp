// The boundary between the baseline code and the per-ISA kernel translation
// units: plain types only, so that nothing compiled with AVX flags leaks into
// code that runs on every CPU (and the other way round).
#pragma once

#include <cstddef>
#include <cstdint>

#include "pwcontact/batch.hpp"
#include "pwcontact/status.hpp"

namespace pwcontact::kernels {

// Input, pointers already offset to the first pair of the span; component
// k of pair i at r12[k][i * stride[0]], q1[k][i * stride[1]],
// q2[k][i * stride[2]] (PairBatchView's strides).
template <class T>
struct PairSpan {
  const T* r12[3];
  const T* q1[6];
  const T* q2[6];
  const T* lambda_start = nullptr;  // optional: where the full kernels start (contiguous)
  std::ptrdiff_t stride[3] = {1, 1, 1};
};

// Which optional outputs a full-answer kernel computes: the kernels are
// specialised for each combination, so that what is not asked for costs nothing.
enum OutputBits : unsigned {
  with_lambda = 1,
  with_contact_point = 2,
  with_normal = 4,
  with_gradient = 8,
};
inline constexpr unsigned output_combinations = 16;
inline constexpr unsigned geometry_outputs = with_contact_point | with_normal | with_gradient;

// SoA output of a full answer; mu2 and status are required, the rest
// follows the output bits of the call.
template <class T>
struct ResultSpan {
  T* mu2;
  T* lambda;
  Status* status;
  T* contact_point[3];
  T* normal[3];
  T* gradient[3];
};

// SoA output of an overlap-only answer.
struct OverlapSpan {
  std::uint8_t* overlap;
  Status* status;
};

// Written by the kernels for every lane they do not finish: lanes that missed
// their convergence check (or stayed undecided), and lanes whose input failed
// the kernels' cheap validity tests. The driver recomputes those pairs with
// the reference path, which validates the input and assigns the exact status.
inline constexpr Status needs_fallback = static_cast<Status>(0xFF);

// How a chunk is solved; everything resolved by the driver (no "automatic").
struct ChunkSettings {
  int iterations;           // fixed count, or 0 for automatic
  int max_iterations;       // automatic: cap on evaluations per lane
  Formulation formulation;  // newton or log_odds
  Accuracy accuracy;
  unsigned outputs;   // OutputBits (full answer)
  double cutoff_mu2;  // overlap: the threshold on mu^2
};

// What a chunk's kernels did, summed by the driver.
struct ChunkCounters {
  std::uint64_t lane_evaluations = 0;  // SIMD lanes times evaluations, padding excluded
  std::uint64_t decided_by_prefilter = 0;
  std::uint64_t decided_by_certificate = 0;
};

// Per-thread memory the kernels keep lanes in between passes: at least
// scratch_bytes(chunk) bytes, 64-byte aligned.
inline constexpr std::size_t scratch_values_per_pair = 48;  // of the widest type, double
inline constexpr std::size_t scratch_padding_pairs = 64;    // a padded block beyond the chunk
inline constexpr std::size_t scratch_bytes(std::size_t chunk) {
  return (chunk + scratch_padding_pairs) * scratch_values_per_pair * sizeof(double);
}
struct Scratch {
  void* memory;
  std::size_t capacity;  // pairs it was sized for
};

template <class In, class Out>
using FullKernel = void (*)(const PairSpan<In>& in, const ResultSpan<Out>& out, std::size_t n,
                            const ChunkSettings& settings, const Scratch& scratch,
                            ChunkCounters& counters);
template <class In>
using OverlapKernel = void (*)(const PairSpan<In>& in, const OverlapSpan& out, std::size_t n,
                               const ChunkSettings& settings, const Scratch& scratch,
                               ChunkCounters& counters);

// A cell's members as the coarse test of a moving scene reads them, in
// tiles of coarse_tile members: a tile is four rows of coarse_tile numbers,
// the members' centres along x, y and z and their bounding radii, and a
// cell's room is a whole number of tiles (the kernels read whole registers
// of a row). A cell of up to eight members is then four adjacent cache
// lines, not four lines a room apart (as with the rows of the whole room
// one after the other): single queries in sweep order at packing 0.3
// measured 2-7 % faster with the tiles (the benchmark and a harness, each
// alternating with the rows).
inline constexpr std::uint32_t coarse_tile = 8;
struct CoarseMembers {
  const double* tiles;
};
// Where member k's centre along x is in its cell's tiles; along y, along z
// and its bounding radius follow, coarse_tile numbers apart each.
constexpr std::size_t coarse_place(std::size_t k) {
  return k / coarse_tile * 4 * coarse_tile + k % coarse_tile;
}

// Bit k set for every member k < n (n <= 32) whose bounding sphere may meet
// the trial's: |c_k - origin|^2 < (reach + scale R_k)^2, on the safe side
// (a superset: bounding_kernel.hpp says by how much).
using BoundingKernel = std::uint32_t (*)(const CoarseMembers& members, std::uint32_t n,
                                         const double origin[3], double reach, double scale);

// What one instruction set offers. Every kernel handles any n up to the
// scratch capacity (tails included, without reading or writing past n) and
// writes status ok or needs_fallback.
struct KernelTable {
  const char* name;
  int lanes_double;
  int lanes_float;
  FullKernel<double, double> full_double;  // double arithmetic
  FullKernel<double, double> full_mixed;   // float iterations, double finish
  FullKernel<double, double> full_single;  // float arithmetic on double pairs
  FullKernel<float, float> full_float;     // float arithmetic on float pairs
  OverlapKernel<double> overlap_double;
  OverlapKernel<double> overlap_mixed;  // float certificates, double for the rest
  OverlapKernel<double> overlap_single;
  OverlapKernel<float> overlap_float;
  BoundingKernel bounding_spheres_meet;
};

// The tables, one per target (kernels/contact_<target>.cpp); chosen only
// through kernels_for (isa.cpp, the one dispatch point).
#ifndef PWCONTACT_X86_KERNELS
#error "PWCONTACT_X86_KERNELS (0 or 1) is set by src/CMakeLists.txt for the library's sources"
#endif
#if PWCONTACT_X86_KERNELS
extern const KernelTable kernel_table_sse2;
extern const KernelTable kernel_table_avx2;
extern const KernelTable kernel_table_avx512;
#endif
extern const KernelTable kernel_table_fallback;

// The kernels of a resolved, supported instruction set (not automatic).
const KernelTable& kernels_for(Isa isa) noexcept;

}  // namespace pwcontact::kernels
