// Arrays whose elements are left uninitialised on resize, for the large
// per-member copies the screen fills in parallel right after: a zeroing
// resize would touch every page from one thread first (measured: a tenth of
// the demo's screen in the kernel clearing pages), and the parallel fill
// after it then writes them a second time.
#pragma once

#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

namespace pwcontact::screen {

// std::allocator, except that value-initialisation (resize(n), vector(n))
// default-initialises: nothing for arithmetic types.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}

  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

template <class T>
using UninitializedVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace pwcontact::screen
