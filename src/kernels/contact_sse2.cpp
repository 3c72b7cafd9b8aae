// The batch kernel for SSE2 (2 doubles or 4 floats per lane group); runs on every x86-64 CPU.
#define PWCONTACT_TARGET sse2
#include "kernels/kernel_table.hpp"

PWCONTACT_DEFINE_KERNEL_TABLE(sse2, xsimd::sse2, "sse2")
