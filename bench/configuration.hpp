// What the benchmarks measure: one path solving one family of pairs with given
// settings, and the names under which it is reported.
#pragma once

#include <string>

#include "pwcontact/batch.hpp"

namespace pwcontact::bench {

// The ways of computing mu^2 (or of answering "mu < 1?") that are timed
// against each other. The batch paths are named <answer>_<arithmetic>.
enum class Path {
  scalar_reference,  // pwcontact::contact_function<double>, one pair at a time
  brent_baseline,    // the existing library's method (brent_baseline.hpp), one pair at a time
  batch_double,      // contact_function_batch on double pairs, double precision
  batch_mixed,       // the same, mixed precision (float iterations, double finish)
  batch_single,      // the same, single precision (the pairs are rounded to float inside)
  batch_float,       // contact_function_batch on the pairs rounded to float beforehand
  overlap_double,    // overlap_batch (cutoff 1) on double pairs, double precision
  overlap_mixed,     // the same, mixed precision
  overlap_single,    // the same, single precision
  overlap_float,     // overlap_batch on the pairs rounded to float beforehand
};

enum class Family {
  random,   // pwcontact::random_pairs: semi-axes in [0.5, 2], centre distance in [0, 6]
  pw85,     // pwcontact::pw85_family: the peer library's 419,904 cases
  extreme,  // semi-axes log-uniform in [0.03, 30]: aspect and size ratios up to 1e3
  scene,    // random shapes, centre distances scaled so that mu is uniform in [0.5, 1.5]
};

const char* path_name(Path path) noexcept;
const char* family_name(Family family) noexcept;

constexpr bool is_scalar(Path path) noexcept {
  return path == Path::scalar_reference || path == Path::brent_baseline;
}
constexpr bool is_batch(Path path) noexcept { return !is_scalar(path); }
constexpr bool is_overlap(Path path) noexcept {
  return path == Path::overlap_double || path == Path::overlap_mixed ||
         path == Path::overlap_single || path == Path::overlap_float;
}
// The batch paths whose pairs are rounded to float before the call.
constexpr bool has_float_input(Path path) noexcept {
  return path == Path::batch_float || path == Path::overlap_float;
}
// The arithmetic of a batch path (Precision::automatic for float input, where
// it can only be single).
Precision path_precision(Path path) noexcept;
// "double", "mixed", "float, double pairs" or "float, float pairs": the
// arithmetic and, in float, whether the pairs were rounded before the call.
const char* precision_label(Path path) noexcept;
// Accuracy::high refines mu^2 in double: full answers in double or mixed only.
constexpr bool allows_high_accuracy(Path path) noexcept {
  return path == Path::batch_double || path == Path::batch_mixed;
}

struct Configuration {
  Path path = Path::batch_double;
  Family family = Family::random;
  Isa isa = Isa::automatic;  // batch paths only
  int iterations = 0;        // batch paths only; 0 is the library's automatic count
  int threads = 1;           // OpenMP threads of the batch call; the scalar paths use one
  Formulation formulation = Formulation::automatic;  // batch paths only
  Accuracy accuracy = Accuracy::standard;            // batch paths only

  // "<path>/<family>/isa:<isa>/iterations:<n>[/formulation:<f>][/accuracy:high]/threads:<t>"
  // for the batch paths (the bracketed parts only when not the default),
  // "<path>/<family>/threads:1" for the scalar ones.
  std::string name() const;
  // The same without "/threads:<t>": what the answers depend on.
  std::string settings_name() const;

  Configuration with_threads(int t) const {
    Configuration c = *this;
    c.threads = t;
    return c;
  }

  // The options of the batch call this configuration makes.
  BatchOptions options() const;
};

}  // namespace pwcontact::bench
