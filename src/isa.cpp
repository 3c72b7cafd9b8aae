// Which instruction set the batch path runs on: detected from the CPU once,
// overridable per call (BatchOptions::isa) or per process (PWCONTACT_ISA).
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "kernels/kernel_api.hpp"
#include "pwcontact/batch.hpp"

namespace pwcontact {

const char* isa_name(Isa isa) noexcept {
  switch (isa) {
    case Isa::automatic: return "auto";
    case Isa::sse2: return "sse2";
    case Isa::avx2: return "avx2";
    case Isa::avx512: return "avx512";
  }
  return "unknown";
}

std::optional<Isa> parse_isa(std::string_view name) noexcept {
  for (Isa isa : {Isa::automatic, Isa::sse2, Isa::avx2, Isa::avx512})
    if (name == isa_name(isa)) return isa;
  return std::nullopt;
}

// GCC's __builtin_cpu_supports also checks that the operating system saves
// the AVX and AVX-512 register state (XCR0), which a bare CPUID test misses.
bool isa_supported(Isa isa) noexcept {
  switch (isa) {
    case Isa::automatic:
    case Isa::sse2:
      return true;  // part of x86-64
    case Isa::avx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case Isa::avx512:
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma");
  }
  return false;
}

std::vector<Isa> supported_isas() {
  std::vector<Isa> out;
  for (Isa isa : {Isa::avx512, Isa::avx2, Isa::sse2})
    if (isa_supported(isa)) out.push_back(isa);
  return out;
}

Isa resolve_isa(Isa requested) {
  if (requested == Isa::automatic) {
    if (const char* env = std::getenv("PWCONTACT_ISA"); env && *env) {
      const std::optional<Isa> parsed = parse_isa(env);
      if (!parsed)
        throw std::invalid_argument(std::string("PWCONTACT_ISA=") + env +
                                    " is not one of auto, sse2, avx2, avx512");
      requested = *parsed;
    }
  }
  if (requested == Isa::automatic) return supported_isas().front();
  if (!isa_supported(requested))
    throw std::runtime_error(std::string("instruction set ") + isa_name(requested) +
                             " was requested but this CPU (or OS) does not support it");
  return requested;
}

int simd_lanes(Isa isa, bool single_precision) {
  const kernels::KernelTable* table = nullptr;
  switch (resolve_isa(isa)) {
    case Isa::avx512: table = &kernels::kernel_table_avx512; break;
    case Isa::avx2: table = &kernels::kernel_table_avx2; break;
    default: table = &kernels::kernel_table_sse2; break;
  }
  return single_precision ? table->lanes_float : table->lanes_double;
}

}  // namespace pwcontact
