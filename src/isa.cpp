// The one dispatch point: which kernels a batch call runs on. One table of
// targets, best first; what the CPU supports is examined once, and
// PWCONTACT_ISA read once, at the first call that needs them (a call of a
// few pairs costs about 0.5 us: a CPUID walk and an environment scan per
// call were a visible part of it).
#include <array>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "kernels/kernel_api.hpp"
#include "pwcontact/batch.hpp"

namespace pwcontact {
namespace {

struct Target {
  Isa isa;
  const char* name;
  bool (*supported)() noexcept;  // by this CPU and its operating system
  const kernels::KernelTable* kernels;
};

bool always() noexcept { return true; }

#if PWCONTACT_X86_KERNELS
// GCC's __builtin_cpu_supports also checks that the operating system saves
// the AVX and AVX-512 register state (XCR0), which a bare CPUID test misses.
bool cpu_has_avx2() noexcept {
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}
bool cpu_has_avx512() noexcept {
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
         __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma");
}
#endif

// Best first; the portable target last, supported everywhere.
constexpr Target targets[] = {
#if PWCONTACT_X86_KERNELS
    {Isa::avx512, "avx512", cpu_has_avx512, &kernels::kernel_table_avx512},
    {Isa::avx2, "avx2", cpu_has_avx2, &kernels::kernel_table_avx2},
    {Isa::sse2, "sse2", always, &kernels::kernel_table_sse2},  // part of x86-64
#endif
    {Isa::fallback, "fallback", always, &kernels::kernel_table_fallback},
};
constexpr std::size_t target_count = sizeof targets / sizeof targets[0];

const Target* find_target(Isa isa) noexcept {
  for (const Target& t : targets)
    if (t.isa == isa) return &t;
  return nullptr;
}

// targets[k].supported(), asked once.
const std::array<bool, target_count>& support() noexcept {
  static const std::array<bool, target_count> supported = [] {
    std::array<bool, target_count> s{};
#if PWCONTACT_X86_KERNELS
    __builtin_cpu_init();  // (asked once: possibly before libgcc's own initialiser has run)
#endif
    for (std::size_t k = 0; k < target_count; ++k) s[k] = targets[k].supported();
    return s;
  }();
  return supported;
}

// What PWCONTACT_ISA asks for: nothing (unset, empty or "auto"), an
// instruction set, or a value that is none (kept to be named in the error).
struct EnvironmentChoice {
  std::optional<Isa> isa;
  std::string invalid_value;
};

EnvironmentChoice read_environment() {
  EnvironmentChoice choice;
  const char* env = std::getenv("PWCONTACT_ISA");
  if (!env || !*env) return choice;
  const std::optional<Isa> parsed = parse_isa(env);
  if (!parsed)
    choice.invalid_value = env;
  else if (*parsed != Isa::automatic)
    choice.isa = parsed;
  return choice;
}

EnvironmentChoice& environment_choice() {
  static EnvironmentChoice choice = read_environment();
  return choice;
}

}  // namespace

const char* isa_name(Isa isa) noexcept {
  if (isa == Isa::automatic) return "auto";
  if (const Target* t = find_target(isa)) return t->name;
  switch (isa) {  // targets this build has no kernels for
    case Isa::sse2: return "sse2";
    case Isa::avx2: return "avx2";
    case Isa::avx512: return "avx512";
    default: return "unknown";
  }
}

std::optional<Isa> parse_isa(std::string_view name) noexcept {
  for (Isa isa : {Isa::automatic, Isa::sse2, Isa::avx2, Isa::avx512, Isa::fallback})
    if (name == isa_name(isa)) return isa;
  return std::nullopt;
}

bool isa_supported(Isa isa) noexcept {
  if (isa == Isa::automatic) return true;
  for (std::size_t k = 0; k < target_count; ++k)
    if (targets[k].isa == isa) return support()[k];
  return false;
}

std::vector<Isa> supported_isas() {
  std::vector<Isa> out;
  for (std::size_t k = 0; k < target_count; ++k)
    if (support()[k]) out.push_back(targets[k].isa);
  return out;
}

Isa resolve_isa(Isa requested) {
  if (requested == Isa::automatic) {
    const EnvironmentChoice& env = environment_choice();
    if (!env.invalid_value.empty())
      throw std::invalid_argument("PWCONTACT_ISA=" + env.invalid_value +
                                  " is not one of auto, sse2, avx2, avx512, fallback");
    requested = env.isa.value_or(Isa::automatic);
  }
  if (requested == Isa::automatic) {
    for (std::size_t k = 0; k < target_count; ++k)
      if (support()[k]) return targets[k].isa;
  }
  if (!isa_supported(requested))
    throw std::runtime_error(std::string("instruction set ") + isa_name(requested) +
                             " was requested but this CPU (or OS, or build) does not support it");
  return requested;
}

void reread_isa_environment() { environment_choice() = read_environment(); }

int simd_lanes(Isa isa, bool single_precision) {
  const kernels::KernelTable& table = kernels::kernels_for(resolve_isa(isa));
  return single_precision ? table.lanes_float : table.lanes_double;
}

const kernels::KernelTable& kernels::kernels_for(Isa isa) noexcept {
  const Target* t = find_target(isa);
  return t ? *t->kernels : kernel_table_fallback;
}

}  // namespace pwcontact
