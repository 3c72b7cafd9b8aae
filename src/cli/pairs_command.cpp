// `pwcontact pairs`: the batch path on random pairs. Random pairs go
// through the batch path; the scalar reference path then solves the same
// pairs, which gives both the speed-up and the accuracy of the batch path.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "cli/solve.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"
#include "fixtures/families.hpp"

namespace pwcontact::cli {
namespace {

constexpr std::size_t default_pairs = 2'000'000;
constexpr std::uint64_t default_seed = 1;

struct PairsOptions {
  SolverOptions solver;
  std::size_t pairs = default_pairs;
  std::uint64_t seed = default_seed;
};

OptionParser pairs_parser(PairsOptions& options) {
  const RandomFamily family;
  char description[1024];
  std::snprintf(description, sizeof description,
                "Generates random pairs of ellipsoids (semi-axes uniform in [%g, %g], random "
                "orientations, centre distance uniform in [0, %g]), solves them with the "
                "batch path and prints its throughput; then solves them with the scalar "
                "reference path and prints its throughput, the speed-up, and the accuracy of "
                "the batch path against it (relative error of mu^2: max, 99.9th percentile, "
                "median). With --precision float both paths see the same float-rounded pairs "
                "(the batch path then reads them as float).",
                family.min_semi_axis, family.max_semi_axis, family.max_distance);
  OptionParser parser("pairs", description);
  parser.add_value({"--pairs"}, "N", std::to_string(default_pairs), "number of random pairs",
                   [&options](std::string_view value) {
                     options.pairs = std::size_t(parse_integer(value, 1, std::int64_t(1) << 40));
                   });
  parser.add_value({"--seed"}, "S", std::to_string(default_seed),
                   "seed of the random pairs (the same pairs on every platform)",
                   [&options](std::string_view value) { options.seed = parse_unsigned(value); });
  add_solver_options(parser, options.solver);
  return parser;
}

std::string pairs_options_help() {
  PairsOptions options;
  return pairs_parser(options).help();
}

// Relative error of mu^2 over the pairs both paths answer as valid.
struct ErrorStatistics {
  std::size_t compared = 0;
  std::size_t validity_differs = 0;  // valid by one path, invalid by the other
  double max = 0, p999 = 0, median = 0;
};

template <class T>
ErrorStatistics accuracy_against(const Solution<T>& batch, const Solution<double>& reference) {
  ErrorStatistics accuracy;
  std::vector<double> errors;
  errors.reserve(batch.mu2.size());
  for (std::size_t i = 0; i < batch.mu2.size(); ++i) {
    const bool valid = is_valid(batch.status[i]);
    if (valid != is_valid(reference.status[i])) ++accuracy.validity_differs;
    if (!valid || !is_valid(reference.status[i])) continue;
    const double exact = reference.mu2[i], value = batch.mu2[i];
    errors.push_back(exact != 0   ? std::abs(value - exact) / exact
                     : value == 0 ? 0
                                  : std::numeric_limits<double>::infinity());
  }
  accuracy.compared = errors.size();
  if (errors.empty()) return accuracy;
  // Nearest-rank quantiles.
  auto quantile = [&errors](double q) {
    const std::size_t rank = std::size_t(std::ceil(q * double(errors.size())));
    const auto nth = errors.begin() + std::ptrdiff_t(std::max<std::size_t>(rank, 1) - 1);
    std::nth_element(errors.begin(), nth, errors.end());
    return *nth;
  };
  accuracy.max = *std::max_element(errors.begin(), errors.end());
  accuracy.p999 = quantile(0.999);
  accuracy.median = quantile(0.5);
  return accuracy;
}

template <class T>
void print_report(const PairsOptions& options, const PairBatch<T>& batch_pairs,
                  const PairBatch<double>& reference_pairs, double generate_seconds) {
  const Solution<T> batch = solve_batch(batch_pairs, Request{}, options.solver);
  const Solution<double> reference =
      solve_reference(reference_pairs, Request{}, options.solver.threads);
  const ErrorStatistics accuracy = accuracy_against(batch, reference);
  std::printf("pwcontact pairs: %zu random pairs, seed %llu (generated in %s)\n\n",
              batch.report.pairs, static_cast<unsigned long long>(options.seed),
              describe_seconds(generate_seconds).c_str());
  std::printf("%s\n%s\n", batch.describe().c_str(), reference.describe().c_str());
  if (batch.seconds > 0)
    std::printf("speed-up of the batch path over the reference path: %.1fx\n\n",
                reference.seconds / batch.seconds);
  std::printf(
      "accuracy of the batch path: relative error of mu^2 against the reference path\n"
      "  max %.3g, p99.9 %.3g, median %.3g (%zu pairs compared)\n",
      accuracy.max, accuracy.p999, accuracy.median, accuracy.compared);
  if (accuracy.validity_differs != 0)
    std::printf("  %zu pairs valid by one path and invalid by the other\n",
                accuracy.validity_differs);
}

// The arguments into `options`, checked; false when help was asked for.
bool parse_pairs(const Arguments& arguments, PairsOptions& options) {
  OptionParser parser = pairs_parser(options);
  if (!parser.parse(arguments)) return false;
  check_solver_options(parser, options.solver);
  return true;
}

bool parse_pairs_only(const Arguments& arguments) {
  PairsOptions options;
  return parse_pairs(arguments, options);
}

ExitStatus run_pairs(const Arguments& arguments) {
  PairsOptions options;
  if (!parse_pairs(arguments, options)) {
    std::fputs(full_help(pairs_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  options.solver.isa = resolve_instruction_set(options.solver.isa);

  const Stopwatch generating;
  PairBatch<double> pairs = random_pairs(options.pairs, options.seed);
  const double generate_seconds = generating.seconds();
  if (options.solver.precision == Precision::single_precision) {
    // The reference solves the float-rounded pairs too, so that the
    // comparison measures the solve, not the rounding of its input.
    const PairBatch<float> single = convert_pairs<float>(pairs);
    pairs = convert_pairs<double>(single);
    print_report(options, single, pairs, generate_seconds);
  } else {
    print_report(options, pairs, pairs, generate_seconds);
  }
  return ExitStatus::success;
}

}  // namespace

const Subcommand pairs_subcommand = {"pairs",
                                     "random pairs through the batch path: throughput and accuracy",
                                     pairs_options_help, run_pairs, parse_pairs_only};

}  // namespace pwcontact::cli
