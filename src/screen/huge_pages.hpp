// Large arrays in transparent huge pages where the kernel offers them (Linux,
// with transparent huge pages in `madvise` mode, Debian's default): a hint
// given before the first touch, so that a million-particle array is faulted
// in 2 MiB pages instead of 4 KiB ones. Measured for a million particles:
// a ParticleStore's zero-filled arrays (108 MB) ready in 23-31 ms instead
// of 67-89 ms, most of which was the kernel's page faults. Elsewhere, or
// when the kernel declines, nothing changes but the speed.
#pragma once

#include <cstddef>
#include <cstdint>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace pwcontact::screen {

// Advises the whole 2 MiB pages inside [p, p + bytes) (below two of them:
// nothing; a failure is ignored: the advice is only a hint).
inline void advise_huge_pages(const void* p, std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t huge = std::uintptr_t(1) << 21;
  if (bytes < 2 * huge) return;
  const std::uintptr_t at = reinterpret_cast<std::uintptr_t>(p);
  const std::uintptr_t begin = (at + huge - 1) & ~(huge - 1), end = (at + bytes) & ~(huge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#else
  (void)p;
  (void)bytes;
#endif
}

// v.reserve(n), the new storage advised before anything but v's old
// elements touches it.
template <class Vector>
void reserve_in_huge_pages(Vector& v, std::size_t n) {
  if (n <= v.capacity()) return;
  v.reserve(n);
  advise_huge_pages(v.data(), v.capacity() * sizeof(typename Vector::value_type));
}

// v.assign(n, value) in new storage advised as above when v's own is too
// small: v is emptied first, so that growing it copies none of the old
// elements the assignment overwrites (a moving scene's rebuild: up to
// ~0.6 GB).
template <class Vector>
void assign_in_huge_pages(Vector& v, std::size_t n, const typename Vector::value_type& value) {
  v.clear();
  reserve_in_huge_pages(v, n);
  v.assign(n, value);
}

}  // namespace pwcontact::screen
