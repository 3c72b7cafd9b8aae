// Overlap answers for a few pairs at a time, many times over (a scene's
// trial-move queries): overlap_batch without its per-call cost. The kernel
// and its settings are resolved once, the scratch memory is kept, and no
// thread team is started: one solver per thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "pwcontact/batch.hpp"

namespace pwcontact::detail {

class PairOverlapSolver {
 public:
  // The options and cutoff are checked as overlap_batch checks them
  // (std::invalid_argument); capacity: the most pairs of one call.
  PairOverlapSolver(const BatchOptions& options, double cutoff, std::size_t capacity);
  ~PairOverlapSolver();
  PairOverlapSolver(PairOverlapSolver&&) noexcept;
  PairOverlapSolver& operator=(PairOverlapSolver&&) noexcept;

  std::size_t capacity() const noexcept;
  // overlap[k] (and status[k]) for the pairs of the view, size at most the
  // capacity: the answers overlap_batch gives for them (exact); under
  // AVX-512, calls of 8 pairs or fewer run the AVX2 kernel (see batch.cpp),
  // whose lanes may certify a pair that AVX-512's leave to the reference
  // path, or the other way round (status ok or ok_fallback).
  void solve(const PairBatchView<double>& pairs, std::uint8_t* overlap, Status* status);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pwcontact::detail
