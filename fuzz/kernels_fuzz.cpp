// The batch kernels on arbitrary bit patterns: up to 48 pairs of 15 raw
// doubles (or floats), every option combination chosen by the first bytes.
// No crash, no sanitizer report, and every answer checked against the
// reference path (fuzz_checks.hpp); in overlap mode also the moving scene's
// scalar certificates (screen::certify_overlap) on the same pairs.
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_checks.hpp"
#include "screen/pair_prefilters.hpp"

using namespace pwcontact;

namespace {

template <class T>
void run(const std::uint8_t* data, std::size_t size, std::uint8_t knobs, std::uint8_t more) {
  constexpr std::size_t pair_bytes = 15 * sizeof(T);
  const std::size_t n = std::min<std::size_t>(size / pair_bytes, 48);
  if (n == 0) return;
  PairBatch<T> pairs(n);
  for (std::size_t i = 0; i < n; ++i) {
    T v[15];
    std::memcpy(v, data + i * pair_bytes, pair_bytes);
    pairs.set(i, v, v + 3, v + 9);
  }
  const std::vector<Isa> isas = supported_isas();
  BatchOptions options;
  options.threads = 1;
  options.isa = isas[knobs % isas.size()];
  const bool single = std::is_same<T, float>::value;
  const int precision = (knobs >> 2) % 3;
  if (!single)
    options.precision = precision == 0   ? Precision::double_precision
                        : precision == 1 ? Precision::mixed
                                         : Precision::single_precision;
  const int iterations[] = {0, 0, 1, 3};
  options.iterations = iterations[(knobs >> 4) % 4];
  options.formulation = (knobs >> 6) & 1 ? Formulation::log_odds : Formulation::newton;
  const bool overlap_mode = more & 1;
  const bool lambda_asked = more & 2;
  const bool high =
      (more & 4) && !single && options.precision != Precision::single_precision && !overlap_mode;
  if (high) options.accuracy = Accuracy::high;
  const double eps = single || options.precision == Precision::single_precision
                         ? std::numeric_limits<float>::epsilon()
                         : std::numeric_limits<double>::epsilon();
  std::vector<Status> status(n);
  auto widened = [&](std::size_t i, double r[3], double q1[6], double q2[6]) {
    T rt[3], q1t[6], q2t[6];
    pairs.get(i, rt, q1t, q2t);
    for (int k = 0; k < 3; ++k) r[k] = rt[k];
    for (int k = 0; k < 6; ++k) q1[k] = q1t[k], q2[k] = q2t[k];
  };
  if (overlap_mode) {
    const double cutoffs[] = {1, 0.5, 2, 1e-3};
    const double cutoff = cutoffs[(more >> 3) % 4];
    std::vector<std::uint8_t> overlap(n);
    overlap_batch(pairs.view(), {overlap.data(), status.data()}, options, cutoff);
    for (std::size_t i = 0; i < n; ++i) {
      double r[3], q1[6], q2[6];
      widened(i, r, q1, q2);
      fuzz::check_overlap_answer(r, q1, q2, overlap[i], status[i], cutoff * cutoff, eps);
      // The moving scene's scalar certificates on the same pair: what they
      // decide is held to the same classification.
      const screen::Certified certified =
          screen::certify_overlap(r, q1, q2, cutoff * cutoff, 1 + (more >> 5) % 8);
      if (certified != screen::Certified::undecided)
        fuzz::check_overlap_answer(r, q1, q2, certified == screen::Certified::overlapping,
                                   Status::ok, cutoff * cutoff,
                                   std::numeric_limits<double>::epsilon());
    }
    return;
  }
  std::vector<T> mu2(n), lambda(n);
  contact_function_batch(
      pairs.view(), {mu2.data(), lambda_asked ? lambda.data() : nullptr, status.data()}, options);
  for (std::size_t i = 0; i < n; ++i) {
    double r[3], q1[6], q2[6];
    widened(i, r, q1, q2);
    fuzz::check_full_answer(r, q1, q2, double(mu2[i]), double(lambda[i]), status[i], eps,
                            lambda_asked, std::numeric_limits<T>::min());
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 3) return 0;
  if (data[0] & 0x80)
    run<float>(data + 3, size - 3, data[1], data[2]);
  else
    run<double>(data + 3, size - 3, data[1], data[2]);
  return 0;
}
