// The batch kernel for AVX2 with FMA (4 doubles or 8 floats per lane group).
// Compiled with -mavx2 -mfma; only called after a CPU check.
#define PWCONTACT_TARGET avx2
#include "kernels/kernel_table.hpp"

PWCONTACT_DEFINE_KERNEL_TABLE(avx2, xsimd::fma3<xsimd::avx2>, "avx2")
