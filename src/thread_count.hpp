// The OpenMP threads a call asks for: 0 (all that OpenMP offers) to
// max_threads, the bound the command line and Python take too. Beyond it,
// std::invalid_argument naming the caller: 10^5 threads crashed the batched
// moving-scene query and the screen (each OpenMP thread takes a stack, and
// the runtime does not report that it could not make them).
#pragma once

#include <omp.h>

#include <stdexcept>
#include <string>

namespace pwcontact::detail {

inline constexpr int max_threads = 1024;

inline int thread_count(int requested, const char* who) {
  if (requested < 0 || requested > max_threads)
    throw std::invalid_argument(std::string(who) + ": threads must be in 0 .. " +
                                std::to_string(max_threads) + " (0: all), got " +
                                std::to_string(requested));
  return requested > 0 ? requested : omp_get_max_threads();
}

}  // namespace pwcontact::detail
