// Exceptions and OpenMP: an exception that leaves an OpenMP region ends the
// program in std::terminate (an abort, not an error message). Work inside a
// region that may throw (allocation, a user's callback, a malformed input)
// runs through ParallelErrors::run, which keeps the first exception; the
// other threads skip what is left, and the caller rethrows it after the
// region, where it reaches the caller's handlers as if thrown there.
#pragma once

#include <atomic>
#include <exception>

namespace pwcontact::detail {

class ParallelErrors {
 public:
  // Calls body() unless an exception is already kept; keeps the one it throws.
  template <class Body>
  void run(Body&& body) noexcept {
    if (failed()) return;
    try {
      body();
    } catch (...) {
      keep(std::current_exception());
    }
  }

  bool failed() const noexcept { return failed_.load(std::memory_order_relaxed); }

  // After the region: throws the kept exception, if any.
  void rethrow_if_failed() const {
    if (error_) std::rethrow_exception(error_);
  }

 private:
  void keep(std::exception_ptr error) noexcept {
#pragma omp critical(pwcontact_parallel_errors)
    {
      if (!error_) error_ = error;
    }
    failed_.store(true, std::memory_order_relaxed);
  }

  std::exception_ptr error_;
  std::atomic<bool> failed_{false};
};

}  // namespace pwcontact::detail
