// Solving a whole batch of pairs by either path, timed, with the results in
// plain arrays: what `contact` writes out and what `demo` compares.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "cli/command_line.hpp"
#include "pwcontact/batch.hpp"

namespace pwcontact::cli {

template <class T>
struct Solution {
  std::vector<T> mu2, lambda;
  std::vector<Status> status;
  // For the reference path: fallbacks 0, isa automatic (it is scalar code),
  // iterations 0 (it iterates to convergence).
  BatchReport report;
  bool reference_path = false;
  double seconds = 0;  // of the solve alone

  // A few lines for a summary: the path and its settings, the time and
  // rate of the solve, fallbacks, invalid pairs and the statuses that occurred.
  std::string describe() const;
};

// The batch path, contact_function_batch, with the options' iterations,
// threads and instruction set (which should be resolved already).
template <class T>
Solution<T> solve_batch(const PairBatch<T>& pairs, const SolverOptions& options);

// The scalar reference path, contact_function<T>, pair by pair in parallel.
template <class T>
Solution<T> solve_reference(const PairBatch<T>& pairs, int threads);

// The same pairs in another floating type. From double to float, values
// beyond float range become +-inf (IEEE 754 rounding), which the solvers
// answer with status non_finite_input.
template <class To, class From>
PairBatch<To> convert_pairs(const PairBatch<From>& pairs);

static_assert(std::numeric_limits<float>::is_iec559 && std::numeric_limits<double>::is_iec559,
              "convert_pairs relies on IEEE 754 overflow to infinity");

}  // namespace pwcontact::cli
