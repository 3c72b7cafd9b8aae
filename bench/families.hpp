// The families of pairs the benchmarks solve, what is derived from each (its
// float rounding, its oracles, the scalar paths' sample), and the near-tangent
// sets built from them. Everything is built on first use and kept: the
// oracles take seconds, and none of it may be charged to a timed region.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "configuration.hpp"
#include "fixtures/families.hpp"
#include "pwcontact/batch.hpp"
#include "pwcontact/status.hpp"

namespace pwcontact::bench {

// One pair in the layout the scalar paths take, as the existing library's
// callers hold it: gathered before timing, so the scalar paths are not
// charged for reading the structure of arrays.
struct ScalarPair {
  double r12[3], q1[6], q2[6];
};

ScalarPair scalar_pair(const PairBatch<double>& pairs, std::size_t i);

// Where the batch paths write their answers. One set of buffers per pair set,
// shared by every configuration that solves it (they run one after the
// other), allocated and zero-filled once so that no timed call pays for page
// faults.
template <class T>
struct FullAnswers {
  explicit FullAnswers(std::size_t n) : mu2(n), lambda(n) {}
  std::vector<T> mu2, lambda;
};

struct AnswerBuffers {
  explicit AnswerBuffers(std::size_t n) : in_double(n), in_float(n), status(n), overlap(n) {}

  // The full answers of a batch path of arithmetic T.
  template <class T>
  FullAnswers<T>& full() {
    if constexpr (std::is_same_v<T, float>)
      return in_float;
    else
      return in_double;
  }

  FullAnswers<double> in_double;
  FullAnswers<float> in_float;
  std::vector<Status> status;
  std::vector<std::uint8_t> overlap;
};

// A set of pairs and what is derived from it.
class PairSet {
 public:
  explicit PairSet(PairBatch<double> pairs) : pairs_(std::move(pairs)) {}

  std::size_t size() const { return pairs_.size(); }
  const PairBatch<double>& pairs() const { return pairs_; }
  const PairBatch<float>& float_pairs();
  // mu^2 by the long double reference path on the double inputs: the truth
  // every path is measured against. NaN where even the oracle has no answer.
  const std::vector<long double>& oracle();
  // The same on the float-rounded inputs: a float path's own error.
  const std::vector<long double>& float_input_oracle();
  // Every k-th pair (see scalar_stride), for the scalar paths' timing.
  const std::vector<ScalarPair>& scalar_sample();
  AnswerBuffers& answers();

  // The inputs a batch path of arithmetic T takes, and their oracle.
  template <class T>
  const PairBatch<T>& inputs();
  template <class T>
  const std::vector<long double>& inputs_oracle();

 private:
  PairBatch<double> pairs_;
  std::optional<PairBatch<float>> float_pairs_;
  std::optional<std::vector<long double>> oracle_, float_input_oracle_;
  std::optional<std::vector<ScalarPair>> scalar_sample_;
  std::optional<AnswerBuffers> answers_;
};

template <>
inline const PairBatch<double>& PairSet::inputs<double>() {
  return pairs_;
}
template <>
inline const PairBatch<float>& PairSet::inputs<float>() {
  return float_pairs();
}
template <>
inline const std::vector<long double>& PairSet::inputs_oracle<double>() {
  return oracle();
}
template <>
inline const std::vector<long double>& PairSet::inputs_oracle<float>() {
  return float_input_oracle();
}

struct FamilySizes {
  // Pairs of each generated family (random, extreme, scene); pw85 is fixed.
  // A million pairs stream from memory rather than cache, and a batch call
  // (~25 ms in double on one thread) dwarfs the cost of starting threads.
  std::size_t generated = std::size_t(1) << 20;
  // Pairs of each near-tangent set.
  std::size_t near_tangent = std::size_t(1) << 16;
};

// The extreme family's parameters, for pwcontact::random_pairs: semi-axes
// log-uniform over three decades, so that aspect ratios and size ratios up
// to 1e3 (needles, discs, a small body beside a large one) are as frequent as
// moderate ones; centre distances up to twice the largest semi-axis, so that
// pairs range from deeply overlapping to well apart.
RandomFamily extreme_family();

// The scene-like mix: random shapes (the random family's), each pair's centre
// distance scaled so that mu is uniform in [0.5, 1.5], as in a packing or a
// collision check where most pairs are near contact. Built with the double
// reference path; the oracle of the result is computed afresh.
PairBatch<double> scene_pairs(std::size_t n, std::uint64_t seed);

// The families, and one near-tangent set per family (near_tangent_pairs of
// fixtures/families.hpp, from the family's long double oracle).
class Families {
 public:
  explicit Families(FamilySizes sizes) : sizes_(sizes) {}

  PairSet& family(Family f);
  PairSet& near_tangent(Family f);
  const FamilySizes& sizes() const { return sizes_; }

 private:
  FamilySizes sizes_;
  std::map<Family, PairSet> families_, near_tangent_;
};

}  // namespace pwcontact::bench
