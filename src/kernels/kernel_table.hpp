// Defines the KernelTable of one instruction set from the kernel bodies; used
// once in each per-ISA translation unit (contact_sse2.cpp, ...).
#pragma once

#include "kernels/contact_kernel.hpp"
#include "kernels/overlap_kernel.hpp"

#define PWCONTACT_DEFINE_KERNEL_TABLE(table, arch, label)                                   \
  namespace pwcontact::kernels {                                                           \
  const KernelTable kernel_table_##table = {                                              \
      label,                                                                               \
      int(xsimd::batch<double, arch>::size),                                               \
      int(xsimd::batch<float, arch>::size),                                                \
      &solve_full<arch, double, double, double>,                                           \
      &solve_full_mixed<arch>,                                                             \
      &solve_full<arch, float, double, double>,                                            \
      &solve_full<arch, float, float, float>,                                              \
      &solve_overlap<arch, double, double>,                                                \
      &solve_overlap_mixed<arch>,                                                          \
      &solve_overlap<arch, float, double>,                                                 \
      &solve_overlap<arch, float, float>,                                                  \
  };                                                                                       \
  }
