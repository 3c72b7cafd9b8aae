// `pwcontact contact`'s input: text parsed as pairs (15 numbers a line) as
// the command line does, then solved in the mode and precision the first
// byte chooses, every answer checked against the reference path.
#include <cstdint>
#include <string_view>
#include <vector>

#include "cli/command_line.hpp"
#include "cli/number_table.hpp"
#include "fuzz_checks.hpp"

using namespace pwcontact;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t knobs = data[0];
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
  cli::NumberColumns table;
  try {
    table = cli::parse_number_columns(text, 15, 1, false, "fuzz");
  } catch (const cli::CommandError&) {
    return 0;  // a malformed line (the parser's own target checks those)
  }
  const std::size_t n = std::min<std::size_t>(table.records(), 64);
  PairBatch<double> pairs(n);
  for (std::size_t i = 0; i < n; ++i) {
    double v[15];
    for (int k = 0; k < 15; ++k) v[k] = table.columns[std::size_t(k)][i];
    pairs.set(i, v, v + 3, v + 9);
  }
  BatchOptions options;
  options.threads = 1;
  const int precision = knobs % 3;
  options.precision = precision == 0   ? Precision::double_precision
                      : precision == 1 ? Precision::mixed
                                       : Precision::single_precision;
  const double eps = precision == 2 ? std::numeric_limits<float>::epsilon()
                                    : std::numeric_limits<double>::epsilon();
  std::vector<Status> status(n);
  if (knobs & 4) {
    std::vector<std::uint8_t> overlap(n);
    overlap_batch(pairs.view(), {overlap.data(), status.data()}, options, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
      double r[3], q1[6], q2[6];
      pairs.get(i, r, q1, q2);
      fuzz::check_overlap_answer(r, q1, q2, overlap[i], status[i], 1.0, eps);
    }
    return 0;
  }
  std::vector<double> mu2(n), lambda(n);
  contact_function_batch(pairs.view(), {mu2.data(), lambda.data(), status.data()}, options);
  for (std::size_t i = 0; i < n; ++i) {
    double r[3], q1[6], q2[6];
    pairs.get(i, r, q1, q2);
    fuzz::check_full_answer(r, q1, q2, mu2[i], lambda[i], status[i], eps, true);
  }
  return 0;
}
