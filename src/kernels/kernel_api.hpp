// The boundary between the baseline code and the per-ISA kernel translation
// units: plain types only, so that nothing compiled with AVX flags leaks into
// code that runs on every CPU (and the other way round).
#pragma once

#include <cstddef>
#include <cstdint>

#include "pwcontact/status.hpp"

namespace pwcontact::kernels {

// SoA input, pointers already offset to the first pair of the span.
template <class T>
struct PairSpan {
  const T* r12[3];
  const T* q1[6];
  const T* q2[6];
};

// SoA output; lambda may be null (not wanted). mu2 and status are required.
template <class T>
struct ResultSpan {
  T* mu2;
  T* lambda;
  Status* status;
};

// Written by the kernels for every lane they do not accept: lanes that missed
// their convergence check, and lanes whose input failed the kernel's cheap
// validity tests. The driver recomputes those pairs with the reference path,
// which validates the input and assigns the exact status.
inline constexpr Status needs_fallback = static_cast<Status>(0xFF);

// What one instruction set offers. `solve_*` handle any n (tails included,
// without reading or writing past n) with a fixed number of Newton iterations,
// and write status ok or needs_fallback.
struct KernelTable {
  const char* name;
  int lanes_double;
  int lanes_float;
  void (*solve_double)(const PairSpan<double>& in, const ResultSpan<double>& out,
                       std::size_t n, int iterations);
  void (*solve_float)(const PairSpan<float>& in, const ResultSpan<float>& out,
                      std::size_t n, int iterations);
};

extern const KernelTable kernel_table_sse2;
extern const KernelTable kernel_table_avx2;
extern const KernelTable kernel_table_avx512;

}  // namespace pwcontact::kernels
