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
  const char* name;              // as isa_name gives it and PWCONTACT_ISA and parse_isa take it
  bool (*supported)() noexcept;  // by this CPU and its operating system
  const kernels::KernelTable* kernels;  // null where this build has none (not x86-64)
};

bool always() noexcept { return true; }

// GCC's __builtin_cpu_supports also checks that the operating system saves
// the AVX and AVX-512 register state (XCR0), which a bare CPUID test misses.
// (x86 only: a build without the x86 kernels asks nothing.)
bool cpu_has_avx2() noexcept {
#if PWCONTACT_X86_KERNELS
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}
bool cpu_has_avx512() noexcept {
#if PWCONTACT_X86_KERNELS
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512cd") &&
         __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma");
#else
  return false;
#endif
}

#if PWCONTACT_X86_KERNELS
constexpr const kernels::KernelTable* avx512_kernels = &kernels::kernel_table_avx512;
constexpr const kernels::KernelTable* avx2_kernels = &kernels::kernel_table_avx2;
constexpr const kernels::KernelTable* sse2_kernels = &kernels::kernel_table_sse2;
#else
constexpr const kernels::KernelTable* avx512_kernels = nullptr;
constexpr const kernels::KernelTable* avx2_kernels = nullptr;
constexpr const kernels::KernelTable* sse2_kernels = nullptr;
#endif

// Every target, best first, the portable one last (supported everywhere):
// the one place that names them. A target this build has no kernels for
// keeps its name (for isa_name, parse_isa and the error that it is not
// supported) and is never supported.
constexpr Target targets[] = {
    {Isa::avx512, "avx512", cpu_has_avx512, avx512_kernels},
    {Isa::avx2, "avx2", cpu_has_avx2, avx2_kernels},
    {Isa::sse2, "sse2", always, sse2_kernels},  // part of x86-64
    {Isa::fallback, "fallback", always, &kernels::kernel_table_fallback},
};
constexpr std::size_t target_count = sizeof targets / sizeof targets[0];
constexpr const char* automatic_name = "auto";

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
    for (std::size_t k = 0; k < target_count; ++k)
      s[k] = targets[k].kernels != nullptr && targets[k].supported();
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

// "auto, avx512, avx2, sse2, fallback": what PWCONTACT_ISA may say.
std::string every_name() {
  std::string names = automatic_name;
  for (const Target& t : targets) names += std::string(", ") + t.name;
  return names;
}

}  // namespace

const char* isa_name(Isa isa) noexcept {
  if (isa == Isa::automatic) return automatic_name;
  const Target* t = find_target(isa);
  return t ? t->name : "unknown";
}

std::optional<Isa> parse_isa(std::string_view name) noexcept {
  if (name == automatic_name) return Isa::automatic;
  for (const Target& t : targets)
    if (name == t.name) return t.isa;
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
  // (A value cast from outside the enumeration is a malformed call, not an
  // instruction set this CPU lacks.)
  if (!(int(requested) >= int(Isa::automatic) && int(requested) <= int(Isa::fallback)))
    throw std::invalid_argument("BatchOptions::isa: " + std::to_string(int(requested)) +
                                " is not an Isa");
  if (requested == Isa::automatic) {
    const EnvironmentChoice& env = environment_choice();
    if (!env.invalid_value.empty())
      throw std::invalid_argument("PWCONTACT_ISA=" + env.invalid_value + " is not one of " +
                                  every_name());
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
  return t && t->kernels ? *t->kernels : kernel_table_fallback;
}

}  // namespace pwcontact
