// What the benchmark measures: one path solving one family of pairs with given
// settings, and the names under which it is reported.
#pragma once

#include <string>

#include "pwcontact/batch.hpp"

namespace pwcontact::bench {

// The ways of computing mu^2 that are timed against each other.
enum class Path {
  scalar_reference,  // pwcontact::contact_function<double>, one pair at a time
  brent_baseline,    // the existing library's method (brent_baseline.hpp), one pair at a time
  batch_double,      // contact_function_batch on double pairs
  batch_float,       // contact_function_batch on the same pairs rounded to float
};

enum class Family {
  random,  // pwcontact::random_pairs: semi-axes in [0.5, 2], centre distance in [0, 6]
  pw85,    // pwcontact::pw85_family: the peer library's 419,904 cases
};

const char* path_name(Path path) noexcept;
const char* family_name(Family family) noexcept;

constexpr bool is_batch(Path path) noexcept {
  return path == Path::batch_double || path == Path::batch_float;
}

struct Configuration {
  Path path = Path::batch_double;
  Family family = Family::random;
  Isa isa = Isa::automatic;  // batch paths only
  int iterations = 0;        // batch paths only; 0 is the library's default count
  int threads = 1;           // OpenMP threads of the batch call; the scalar paths use one

  // "<path>/<family>/isa:<isa>/iterations:<n>/threads:<t>" for the batch paths,
  // "<path>/<family>/threads:1" for the scalar ones.
  std::string name() const;

  Configuration with_threads(int t) const {
    Configuration c = *this;
    c.threads = t;
    return c;
  }
};

// Counters every configuration reports besides items_per_second (pairs per
// second). Errors are relative errors of mu^2 against the long double oracle
// on the inputs the path actually solved: for batch_float that is the
// float-rounded pairs, so the error is the solver's own;
// max_rel_err_double_input adds the effect of rounding the inputs to float.
namespace counter {
inline constexpr const char* items_per_second = "items_per_second";
inline constexpr const char* max_rel_err = "max_rel_err";
inline constexpr const char* p999_rel_err = "p999_rel_err";
inline constexpr const char* median_rel_err = "median_rel_err";
inline constexpr const char* max_rel_err_double_input = "max_rel_err_double_input";
inline constexpr const char* fallbacks = "fallbacks";  // per batch call (the whole family)
inline constexpr const char* fallbacks_per_pair = "fallbacks_per_pair";
inline constexpr const char* invalid = "invalid";  // pairs without a valid mu^2
}  // namespace counter

}  // namespace pwcontact::bench
