// Defines the KernelTable of one instruction set from the kernel bodies of
// its target namespace (target.hpp); used once in each per-target
// translation unit (contact_sse2.cpp, ...), after it defines PWCONTACT_TARGET.
#pragma once

#include "kernels/bounding_kernel.hpp"
#include "kernels/contact_kernel.hpp"
#include "kernels/overlap_kernel.hpp"

#define PWCONTACT_DEFINE_KERNEL_TABLE(table, arch, label)          \
  namespace pwcontact::kernels {                                   \
  const KernelTable kernel_table_##table = {                       \
      label,                                                       \
      int(xsimd::batch<double, arch>::size),                       \
      int(xsimd::batch<float, arch>::size),                        \
      &PWCONTACT_TARGET::solve_full<arch, double, double, double>, \
      &PWCONTACT_TARGET::solve_full_mixed<arch>,                   \
      &PWCONTACT_TARGET::solve_full<arch, float, double, double>,  \
      &PWCONTACT_TARGET::solve_full<arch, float, float, float>,    \
      &PWCONTACT_TARGET::solve_overlap<arch, double, double>,      \
      &PWCONTACT_TARGET::solve_overlap_float_first<arch, double>,  \
      &PWCONTACT_TARGET::solve_overlap_float_first<arch, double>,  \
      &PWCONTACT_TARGET::solve_overlap_float_first<arch, float>,   \
      &PWCONTACT_TARGET::bounding_spheres_meet<arch>,              \
  };                                                               \
  }
