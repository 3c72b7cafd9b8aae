// The kernel bodies (simd_math.hpp, lane_blocks.hpp, contact_kernel.hpp,
// overlap_kernel.hpp) are compiled once per target, each time with that
// target's instruction-set flags, in kernels/contact_<target>.cpp, which
// defines PWCONTACT_TARGET (sse2, avx2, avx512) before including them. They
// open namespace pwcontact::kernels::PWCONTACT_TARGET, so that nothing they
// define has the same name in two targets: an inline function or variable
// defined alike in two objects compiled with different flags is one symbol
// to the linker, which keeps one copy (possibly the AVX-512 one, called
// from the SSE2 path). tests/target_symbols.cmake checks the objects for
// such shared definitions. Only kernel_api.hpp, plain types, is shared.
#pragma once

#ifndef PWCONTACT_TARGET
#error \
    "kernel bodies are compiled once per target: include them from kernels/contact_<target>.cpp, which defines PWCONTACT_TARGET"
#endif
