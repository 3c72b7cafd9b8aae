// pwcontact_bench: pairs per second and accuracy of every way pwcontact
// computes the contact function mu^2, timed in one run against the existing
// library's method (brent_baseline). The summary of the ratios and of the
// project's targets is made from the JSON output by bench/report.py summary
// (scripts/run.sh bench runs both).
//
// Benchmark names: <path>/<family>/isa:<isa>/iterations:<n>[/accuracy:high]/threads:<t>
// for the batch paths and <path>/<family>/threads:1 for the scalar ones
// (Google Benchmark appends /real_time); see configuration.hpp for the paths
// and families. iterations:0 is the library's automatic count.
// Every benchmark reports items_per_second = pairs per second, in real time:
// the batch path runs its own OpenMP threads, so CPU time would not compare
// like with like. Accuracy counters are computed once per configuration,
// outside the timed region, on the whole family (see counters.hpp).
//
// The default sweep measures every fixed iteration count on the default
// instruction set (isa:auto resolved: the best one, or PWCONTACT_ISA) with 1
// thread, and the default settings on every instruction set and with every
// thread count, for the full answers in double, mixed and float on the random
// and pw85 families; the accurate mode (accuracy:high) with default settings;
// and the overlap answers on the scene-like mix with default settings;
// --pwcontact_sweep=full crosses everything. The speed/accuracy trade over
// every setting is pwcontact_trade's.
// For the summary's medians, run with --benchmark_repetitions=5 (and
// --benchmark_enable_random_interleaving=true on a noisy machine, so that a
// burst of foreign load does not hit one configuration's repetitions only),
// and --benchmark_out=FILE --benchmark_out_format=json for the summary.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "command_line.hpp"
#include "configuration.hpp"
#include "families.hpp"
#include "registration.hpp"

namespace pwcontact::bench {
namespace {

// ---------------------------------------------------------------------------
// Settings

struct Settings {
  bool full_sweep = false;
  std::vector<int> iterations = {2, 3, 4, 5, 6, 7, 8};  // fixed counts swept besides 0
  std::vector<int> threads = {1, 2};
  // Pairs of the random family and of the scene-like mix; the scalar paths
  // time a sample of them.
  FamilySizes sizes;
};

const char* const pwcontact_flags_help =
    "\npwcontact_bench flags:\n"
    "  [--pwcontact_sweep=default|full]  full: every path x instruction set x iteration count\n"
    "                                    x thread count (default: iteration counts on the\n"
    "                                    default instruction set only, 1 thread)\n"
    "  [--pwcontact_iterations=LIST]     fixed Newton iteration counts to sweep, e.g. 2,3,4\n"
    "                                    (0, the library's automatic count, is always measured)\n"
    "  [--pwcontact_threads=LIST]        thread counts of the batch paths (default 1,2)\n"
    "  [--pwcontact_random_pairs=N]      size of the random family and of the scene-like mix\n"
    "                                    (default 1048576)\n"
    "Names: <path>/<family>/isa:<isa>/iterations:<n>[/accuracy:high]/threads:<t>; select with\n"
    "filters, e.g.\n"
    "  --benchmark_filter='(brent_baseline|batch_double)/random'\n"
    "  --benchmark_filter=pw85 --pwcontact_iterations=4,8,12,16,20,24  (pw85 needs more)\n"
    "  --benchmark_filter=scene  (overlap answers against brent_baseline)\n"
    "The summary (ratios to brent_baseline, thread scaling, targets) is bench/report.py's:\n"
    "  pwcontact_bench --benchmark_out=bench.json --benchmark_out_format=json\n"
    "  /usr/bin/python3 bench/report.py summary bench.json\n";

void print_help() {
  benchmark::PrintDefaultHelp();
  std::fputs(pwcontact_flags_help, stdout);
}

// Reads and removes pwcontact's own flags; Google Benchmark has already
// removed its own, so whatever is left is unknown.
Settings parse_settings(int& argc, char** argv) {
  Settings settings;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (auto v = flag_value(argv[i], "pwcontact_sweep")) {
      if (*v != "default" && *v != "full")
        throw std::invalid_argument("--pwcontact_sweep: '" + *v + "' is not default or full");
      settings.full_sweep = *v == "full";
    } else if (auto v = flag_value(argv[i], "pwcontact_iterations")) {
      settings.iterations = parse_counts(*v, "pwcontact_iterations", 1);
    } else if (auto v = flag_value(argv[i], "pwcontact_threads")) {
      settings.threads = parse_counts(*v, "pwcontact_threads", 1);
    } else if (auto v = flag_value(argv[i], "pwcontact_random_pairs")) {
      settings.sizes.generated = std::size_t(parse_count(*v, "pwcontact_random_pairs", 1));
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  return settings;
}

// ---------------------------------------------------------------------------
// What is measured

// The default sweep: the default settings with 1 thread on every instruction
// set, every swept iteration count on the default one, and the default
// settings with every thread count. The accurate mode and the overlap answers
// are measured with the default settings only.
bool in_default_sweep(const Configuration& c, Isa default_isa) {
  const bool defaults = c.iterations == 0 && c.threads == 1;
  if (c.accuracy == Accuracy::high) return defaults && c.isa == default_isa;
  if (c.iterations != 0 && (c.family == Family::scene || is_overlap(c.path))) return false;
  return defaults || (c.isa == default_isa && (c.threads == 1 || c.iterations == 0));
}

// The families measured (their sizes: FamilySizes).
const std::vector<Family> families_measured = {Family::random, Family::pw85, Family::scene};

// The batch paths measured on each family: full answers on the random and pw85
// families; overlap answers on the scene-like mix, with the full double answer
// beside them, and on the pw85 family (elongated shapes, where float lanes
// need double most).
std::vector<Path> batch_paths(Family family) {
  if (family == Family::scene)
    return {Path::batch_double, Path::overlap_double, Path::overlap_mixed, Path::overlap_float};
  if (family == Family::pw85)
    return {Path::batch_double, Path::batch_mixed, Path::batch_float, Path::overlap_double,
            Path::overlap_float};
  return {Path::batch_double, Path::batch_mixed, Path::batch_float};
}

std::vector<Configuration> sweep(const Settings& settings, Isa default_isa) {
  std::vector<int> iterations = {0};
  iterations.insert(iterations.end(), settings.iterations.begin(), settings.iterations.end());
  std::vector<Configuration> out;
  for (Family family : families_measured) {
    out.push_back({Path::brent_baseline, family});
    out.push_back({Path::scalar_reference, family});
    for (Path path : batch_paths(family))
      for (Accuracy accuracy : {Accuracy::standard, Accuracy::high}) {
        if (accuracy == Accuracy::high && (family == Family::scene || !allows_high_accuracy(path)))
          continue;
        for (Isa isa : supported_isas())
          for (int n : iterations)
            for (int threads : settings.threads) {
              Configuration c{path, family, isa, n, threads};
              c.accuracy = accuracy;
              if (settings.full_sweep || in_default_sweep(c, default_isa)) out.push_back(c);
            }
      }
  }
  return out;
}

int run(int argc, char** argv) {
  BenchmarkArguments arguments(argc, argv);
  const std::string min_time =
      arguments.last_value("benchmark_min_time").value_or(default_min_time);
  benchmark::Initialize(&arguments.argc(), arguments.argv(), print_help);
  const Settings settings = parse_settings(arguments.argc(), arguments.argv());
  if (benchmark::ReportUnrecognizedArguments(arguments.argc(), arguments.argv())) return 1;

  const Isa default_isa = resolve_isa(Isa::automatic);
  add_run_context({default_isa, settings.sizes, settings.threads, families_measured, min_time, {}});
  Families families(settings.sizes);
  Accuracies accuracies(families);
  register_configurations(sweep(settings, default_isa), families, accuracies);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

}  // namespace
}  // namespace pwcontact::bench

int main(int argc, char** argv) {
  try {
    return pwcontact::bench::run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "pwcontact_bench: " << e.what() << '\n';
    return 2;
  }
}
