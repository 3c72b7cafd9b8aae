// The batch kernel for AVX-512 (8 doubles or 16 floats per lane group).
// Compiled with -mavx512f/cd/dq/bw/vl -mfma; only called after a CPU check.
#define PWCONTACT_TARGET avx512
#include "kernels/kernel_table.hpp"

PWCONTACT_DEFINE_KERNEL_TABLE(avx512, xsimd::avx512bw, "avx512")
