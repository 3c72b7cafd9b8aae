// The pairs a screen finds, sorted by their keys i << 32 | j (i, j below the
// particle count): a least-significant-digit radix sort over only the bits
// the particle count leaves in each half of the key, 11 bits a pass. For a
// million particles that is four passes over the keys, each a scatter into
// 2048 runs, after one read that counts every pass's digits; std::sort's
// comparisons took 0.10 s of the 1M demo scene's screen with one thread
// (1.34M pairs).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace pwcontact::screen {

// Sorts v by key(element) (a std::uint64_t whose halves are each below
// 2^bits_per_half), stably. Passes in which every key has the same digit
// are skipped. The passes scatter into a second array: `scratch`'s storage
// when given (kept there or in v for the next sort), else one of its own.
template <class T, class Key>
void radix_sort_pair_keys(std::vector<T>& v, int bits_per_half, Key key,
                          std::vector<T>* scratch_memory = nullptr) {
  constexpr int digit_bits = 11;
  constexpr std::size_t buckets = std::size_t(1) << digit_bits;
  const std::size_t n = v.size();
  if (n < 2) return;
  if (bits_per_half < 0 || bits_per_half > 32)
    throw std::invalid_argument("radix_sort_pair_keys: at most 32 bits a half");
  // The digits' shifts: low half then high half, each from its lowest bit.
  int shifts[8], passes = 0;
  for (int half = 0; half < 64; half += 32)
    for (int shift = half; shift < half + bits_per_half; shift += digit_bits)
      shifts[passes++] = shift;
  // Every pass's counts in one read of the keys.
  std::vector<std::size_t> start(std::size_t(passes) * buckets, 0);
  for (const T& x : v) {
    const std::uint64_t k = key(x);
    for (int p = 0; p < passes; ++p)
      ++start[std::size_t(p) * buckets + ((k >> shifts[p]) & (buckets - 1))];
  }
  std::vector<T> own;
  std::vector<T>& scratch = scratch_memory ? *scratch_memory : own;
  bool scattering = false;  // scratch sized for v
  for (int p = 0; p < passes; ++p) {
    const int shift = shifts[p];
    std::size_t* count = start.data() + std::size_t(p) * buckets;
    auto digit = [&](const T& x) { return std::size_t(key(x) >> shift) & (buckets - 1); };
    if (count[digit(v[0])] == n) continue;  // one digit throughout: already in order
    std::size_t at = 0;
    for (std::size_t b = 0; b < buckets; ++b) {
      const std::size_t here = count[b];
      count[b] = at;
      at += here;
    }
    if (!scattering) {
      scratch.resize(n);  // (its old elements, if any, are all overwritten)
      scattering = true;
    }
    for (const T& x : v) scratch[count[digit(x)]++] = x;
    v.swap(scratch);
  }
}

// The bits a particle index below `particles` needs (0 for one particle).
inline int index_bits(std::size_t particles) {
  int bits = 0;
  while (bits < 64 && (std::uint64_t(1) << bits) < particles) ++bits;
  return bits;
}

}  // namespace pwcontact::screen
