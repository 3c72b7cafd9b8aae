// Solving a whole batch of pairs by either path, timed, with the results in
// plain arrays: what `contact` writes out and what `demo` compares.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cli/command_line.hpp"
#include "fixtures/families.hpp"
#include "pwcontact/batch.hpp"

namespace pwcontact::cli {

// What is answered per pair: mu^2 and what goes with it, or only whether
// the pair overlaps.
enum class Mode { full, overlap };
const char* mode_name(Mode mode) noexcept;  // "full", "overlap"

// What a solve computes. Full mode: mu2 always, the rest when asked for
// (the batch path then computes nothing else). Overlap mode: overlap and
// status, the other fields being ignored.
struct Request {
  Mode mode = Mode::full;
  double cutoff = 1;  // overlap mode: a pair overlaps when mu < cutoff
  bool lambda = true;
  bool status = true;
  bool contact_point = false;
  bool normal = false;
  bool gradient = false;
};

template <class T>
struct Solution {
  Request request;
  // One element per pair for what the request asks for, empty otherwise.
  std::vector<T> mu2, lambda;
  std::vector<Status> status;
  std::vector<T> contact_point[3], normal[3], gradient[3];
  std::vector<std::uint8_t> overlap;  // 1: mu < cutoff
  // For the reference path: fallbacks 0, isa automatic (it is scalar code),
  // iterations 0 (it iterates to convergence), mean_evaluations its own,
  // overlapping counted here, prefilter and certificate counts 0.
  BatchReport report;
  Accuracy accuracy = Accuracy::standard;  // the batch path's; BatchReport lacks it
  bool reference_path = false;
  double seconds = 0;  // of the solve alone

  // A few lines for a summary: the path and its settings as resolved, the
  // time and rate of the solve, evaluations per pair, fallbacks, invalid
  // pairs, the statuses that occurred and, in overlap mode, how the pairs
  // were decided.
  std::string describe() const;
};

// The batch path, contact_function_batch or overlap_batch, with `options`
// (whose instruction set should be resolved already).
template <class T>
Solution<T> solve_batch(const PairBatch<T>& pairs, const Request& request,
                        const BatchOptions& options);

// The scalar reference path, contact_function<T> (and contact_geometry<T>
// for the geometric outputs), pair by pair in parallel. In overlap mode a
// pair overlaps when its status is valid and mu^2 < cutoff^2.
template <class T>
Solution<T> solve_reference(const PairBatch<T>& pairs, const Request& request, int threads);

// Adds what `block` counted and timed to `total` (the settings are the
// block's): the summary of an input solved a block at a time.
template <class T>
void add_block(Solution<T>& total, const Solution<T>& block);

// The same pairs in another floating type: pwcontact::convert_pairs
// (fixtures/families.hpp), whose double -> float rounding sends values beyond
// float range to +-inf, which the solvers answer with status non_finite_input.
using pwcontact::convert_pairs;

}  // namespace pwcontact::cli
