#include "families.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <stdexcept>

#include "accuracy.hpp"
#include "fixtures/families.hpp"
#include "pwcontact/reference.hpp"

namespace pwcontact::bench {
namespace {

// Fixed so that every run solves the same pairs.
constexpr std::uint64_t random_seed = 85;
constexpr std::uint64_t extreme_seed = 86;
constexpr std::uint64_t scene_seed = 87;
constexpr std::uint64_t near_tangent_seed = 88;

// The scalar paths solve about a million pairs per second: a sample of this
// many pairs keeps one timed call near 0.1 s.
constexpr std::size_t scalar_sample_limit = std::size_t(1) << 16;

// The smallest stride that visits at most `limit` of `n` pairs and is prime
// to 2 and 3: the pw85 family is built from 3 distances, 12 directions and
// 108 spheroids, so such a stride visits all of them in their proportions.
std::size_t stride_prime_to_6(std::size_t n, std::size_t limit) {
  std::size_t stride = 1;
  const auto prime_to_6 = [](std::size_t k) { return k % 2 != 0 && k % 3 != 0; };
  while ((n + stride - 1) / stride > limit || !prime_to_6(stride)) ++stride;
  return stride;
}

template <class V, class Make>
const V& cached(std::optional<V>& slot, Make make) {
  if (!slot) slot = make();
  return *slot;
}

std::vector<long double> checked_oracle_mu2(const std::vector<long double>& oracle,
                                            const char* inputs) {
  const auto failed =
      std::count_if(oracle.begin(), oracle.end(), [](long double x) { return std::isnan(x); });
  if (failed > 0)
    std::cerr << "pwcontact bench: the long double oracle has no valid mu^2 for " << failed
              << " pairs (" << inputs << " inputs); they are left out of the statistics\n";
  return oracle;
}

}  // namespace

ScalarPair scalar_pair(const PairBatch<double>& pairs, std::size_t i) {
  ScalarPair p;
  pairs.get(i, p.r12, p.q1, p.q2);
  return p;
}

const PairBatch<float>& PairSet::float_pairs() {
  return cached(float_pairs_, [&] { return to_float(pairs_); });
}

const std::vector<long double>& PairSet::oracle() {
  return cached(oracle_, [&] { return checked_oracle_mu2(oracle_mu2(pairs_), "double"); });
}

const std::vector<long double>& PairSet::float_input_oracle() {
  return cached(float_input_oracle_,
                [&] { return checked_oracle_mu2(oracle_mu2(float_pairs()), "float-rounded"); });
}

const std::vector<ScalarPair>& PairSet::scalar_sample() {
  return cached(scalar_sample_, [&] {
    std::vector<ScalarPair> sample;
    const std::size_t stride = stride_prime_to_6(size(), scalar_sample_limit);
    for (std::size_t i = 0; i < size(); i += stride) sample.push_back(scalar_pair(pairs_, i));
    return sample;
  });
}

AnswerBuffers& PairSet::answers() {
  if (!answers_) answers_.emplace(size());
  return *answers_;
}

RandomFamily extreme_family() {
  RandomFamily family;
  family.min_semi_axis = 0.03;
  family.max_semi_axis = 30;
  family.max_distance = 60;
  family.log_uniform_axes = true;
  return family;
}

PairBatch<double> scene_pairs(std::size_t n, std::uint64_t seed) {
  const PairBatch<double> shapes = random_pairs(n, seed);
  std::vector<double> target_mu(n);
  // A stream of its own, so that the shapes are drawn exactly as the random
  // family draws them.
  std::mt19937_64 engine(seed + 1);
  for (double& mu : target_mu) mu = 0.5 + uniform01(engine);

  PairBatch<double> scene(n);
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::size_t i = 0; i < n; ++i) {
    ScalarPair p = scalar_pair(shapes, i);
    const double mu2 = contact_function<double>(p.r12, p.q1, p.q2).mu2;
    // mu scales with |r12|; coincident centres (probability ~2^-53) stay as they are.
    const long double scale = mu2 > 0 ? target_mu[i] / std::sqrt((long double)mu2) : 1;
    scale_r12(p.r12, scale);
    scene.set(i, p.r12, p.q1, p.q2);
  }
  return scene;
}

PairSet& Families::family(Family f) {
  auto found = families_.find(f);
  if (found != families_.end()) return found->second;
  const std::size_t n = sizes_.generated;
  switch (f) {
    case Family::random: return families_.emplace(f, random_pairs(n, random_seed)).first->second;
    case Family::pw85: return families_.emplace(f, pw85_family()).first->second;
    case Family::extreme:
      return families_.emplace(f, random_pairs(n, extreme_seed, extreme_family())).first->second;
    case Family::scene: return families_.emplace(f, scene_pairs(n, scene_seed)).first->second;
  }
  throw std::logic_error("unknown family");
}

PairSet& Families::near_tangent(Family f) {
  auto found = near_tangent_.find(f);
  if (found != near_tangent_.end()) return found->second;
  PairSet& base = family(f);
  return near_tangent_
      .emplace(f, near_tangent_pairs(base.pairs(), base.oracle(), sizes_.near_tangent,
                                     near_tangent_seed + std::uint64_t(f)))
      .first->second;
}

}  // namespace pwcontact::bench
