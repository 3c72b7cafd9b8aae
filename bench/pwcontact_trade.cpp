// pwcontact_trade: the speed/accuracy trade, measured with Google Benchmark.
// Sweeps the answer (full mu^2 and lambda, or overlap only) x the precision
// (double, mixed, float on double pairs, float pairs) x the iterations
// (automatic and fixed counts) x the formulation (newton, log_odds, and the
// library's automatic choice with automatic iterations) x the accuracy
// (standard, and high where the library allows it) over the random, pw85,
// extreme and scene-like families, and registers each configuration with
// each thread count as a benchmark that reports its throughput and, as
// counters, the error of mu^2 against the long double oracle, its fallbacks
// and evaluations, and its misclassifications of the family's near-tangent
// pairs (registration.hpp). brent_baseline is registered on every family, so
// that every speed is also a ratio to it.
//
// Names: <path>/<family>/isa:<isa>/iterations:<n>[/formulation:<f>][/accuracy:high]/threads:<t>
// (the same scheme as pwcontact_bench's; Google Benchmark appends /real_time).
//
// Timing: each sweep presets Google Benchmark's flags (the caller's own come
// after and override them): repetitions with random interleaving, so that
// every configuration is timed once per round in an order shuffled afresh
// each round and a burst of foreign load on a shared machine hits different
// configurations in different rounds; a minimum time per repetition; only
// the aggregates on the console. The figures are the medians over the rounds.
//
// Outputs: Google Benchmark's, with --benchmark_out=FILE
// --benchmark_out_format=json for bench/report.py trade, which writes the
// trade table (CSV, Markdown) and the plot (gnuplot); scripts/run.sh trade
// runs both.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <iostream>
#include <optional>
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
  std::vector<int> iterations;  // fixed counts swept besides 0 (automatic)
  std::vector<int> threads = {1, 2};
  FamilySizes sizes;
  std::vector<Family> families = {Family::random, Family::pw85, Family::extreme, Family::scene};
  std::vector<std::string> benchmark_defaults;  // Google Benchmark's flags, before the caller's
  std::string label;
};

// Google Benchmark's flags for a sweep: `repetitions` shuffled rounds of at
// least `min_time` seconds each.
std::vector<std::string> timing_flags(int repetitions, const char* min_time) {
  return {"--benchmark_repetitions=" + std::to_string(repetitions),
          std::string("--benchmark_min_time=") + min_time,
          "--benchmark_enable_random_interleaving=true",
          "--benchmark_display_aggregates_only=true"};
}

// The sweeps offered: how many fixed iteration counts, repetitions and
// pairs. The default keeps a run to several minutes on this machine.
Settings preset(const std::string& sweep) {
  Settings s;
  if (sweep == "quick") {
    s.iterations = {4, 12};
    s.sizes = {std::size_t(1) << 16, std::size_t(1) << 13};
    s.benchmark_defaults = timing_flags(3, "0.01");
  } else if (sweep == "default") {
    s.iterations = {2, 3, 4, 6, 8, 12, 16, 24};
    s.sizes = {std::size_t(1) << 18, std::size_t(1) << 16};
    s.benchmark_defaults = timing_flags(3, "0.03");
  } else if (sweep == "full") {
    s.iterations = {1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 32};
    s.sizes = {std::size_t(1) << 20, std::size_t(1) << 17};
    s.benchmark_defaults = timing_flags(5, "0.1");
  } else {
    throw std::invalid_argument("--pwcontact_sweep: '" + sweep + "' is not quick, default or full");
  }
  return s;
}

const char* const pwcontact_flags_help =
    "\npwcontact_trade flags:\n"
    "  [--pwcontact_sweep=quick|default|full]  size of the sweep (default: default, several\n"
    "                                minutes; quick: small families, 2 fixed counts; full: every\n"
    "                                count, 2^20 pairs). Each presets Google Benchmark's\n"
    "                                --benchmark_repetitions (3, 3, 5), --benchmark_min_time\n"
    "                                (0.01, 0.03, 0.1), random interleaving and aggregates only\n"
    "                                on the console; flags given override them\n"
    "  [--pwcontact_iterations=LIST] fixed iteration counts swept besides automatic, e.g. 2,4,8\n"
    "  [--pwcontact_threads=LIST]    thread counts of the batch paths (default 1,2; with 1)\n"
    "  [--pwcontact_pairs=N]         pairs of each generated family (random, extreme, scene)\n"
    "  [--pwcontact_near_tangent=N]  pairs of each near-tangent set\n"
    "  [--pwcontact_families=LIST]   of random,pw85,extreme,scene (default all)\n"
    "  [--pwcontact_label=TEXT]      the commit measured, for the reports' headers\n"
    "Names: <path>/<family>/isa:<isa>/iterations:<n>[/formulation:<f>][/accuracy:high]/"
    "threads:<t>;\nselect with --benchmark_filter, keeping brent_baseline (every ratio needs "
    "it), e.g.\n"
    "  --benchmark_filter='brent_baseline|batch_(double|mixed)/pw85'\n"
    "The trade table and plot are bench/report.py's:\n"
    "  pwcontact_trade --benchmark_out=trade.json --benchmark_out_format=json\n"
    "  /usr/bin/python3 bench/report.py trade trade.json  (CSV, Markdown, gnuplot plot)\n";

void print_help() {
  benchmark::PrintDefaultHelp();
  std::fputs(pwcontact_flags_help, stdout);
}

Family parse_family(const std::string& name) {
  for (Family f : {Family::random, Family::pw85, Family::extreme, Family::scene})
    if (name == family_name(f)) return f;
  throw std::invalid_argument("--pwcontact_families: unknown family '" + name + "'");
}

// The sweep's preset, then the other pwcontact flags, which override it
// whatever their order.
Settings parse_settings(int argc, char** argv) {
  std::string sweep = "default";
  for (int i = 1; i < argc; ++i)
    if (auto v = flag_value(argv[i], "pwcontact_sweep")) sweep = *v;
  Settings s = preset(sweep);
  for (int i = 1; i < argc; ++i) {
    const char* arg = argv[i];
    if (flag_value(arg, "pwcontact_sweep")) {
      // read above
    } else if (auto v = flag_value(arg, "pwcontact_iterations")) {
      s.iterations = parse_counts(*v, "pwcontact_iterations", 1);
    } else if (auto v = flag_value(arg, "pwcontact_threads")) {
      s.threads = parse_counts(*v, "pwcontact_threads", 1);
    } else if (auto v = flag_value(arg, "pwcontact_pairs")) {
      s.sizes.generated = std::size_t(parse_count(*v, "pwcontact_pairs", 1));
    } else if (auto v = flag_value(arg, "pwcontact_near_tangent")) {
      s.sizes.near_tangent = std::size_t(parse_count(*v, "pwcontact_near_tangent", 1));
    } else if (auto v = flag_value(arg, "pwcontact_families")) {
      s.families.clear();
      for (const std::string& name : parse_names(*v, "pwcontact_families"))
        s.families.push_back(parse_family(name));
    } else if (auto v = flag_value(arg, "pwcontact_label")) {
      s.label = *v;
    } else if (std::string(arg).rfind("--pwcontact_", 0) == 0) {
      throw std::invalid_argument(std::string("unknown flag '") + arg + "' (see --help)");
    }
  }
  if (s.threads.front() != 1)
    throw std::invalid_argument(
        "--pwcontact_threads must include 1: every ratio is quoted for 1 thread");
  return s;
}

// Removes pwcontact's own flags; Google Benchmark has already removed its
// own, so whatever is left is unknown.
void remove_pwcontact_flags(int& argc, char** argv) {
  int kept = 1;
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]).rfind("--pwcontact_", 0) != 0) argv[kept++] = argv[i];
  argc = kept;
}

// ---------------------------------------------------------------------------
// What is measured

constexpr Path full_paths[] = {Path::batch_double, Path::batch_mixed, Path::batch_single,
                               Path::batch_float};
constexpr Path overlap_paths[] = {Path::overlap_double, Path::overlap_mixed, Path::overlap_single,
                                  Path::overlap_float};

// Every setting of one batch path on one family: the library's defaults
// (automatic iterations and formulation), then each formulation with
// automatic and each fixed iteration count, in each allowed accuracy.
void add_settings(std::vector<Configuration>& out, Path path, Family family, Isa isa,
                  const std::vector<int>& iterations) {
  for (Accuracy accuracy : {Accuracy::standard, Accuracy::high}) {
    if (accuracy == Accuracy::high && !allows_high_accuracy(path)) continue;
    Configuration c{path, family, isa};
    c.accuracy = accuracy;
    out.push_back(c);
    for (Formulation formulation : {Formulation::newton, Formulation::log_odds})
      for (int n : iterations) {
        c.formulation = formulation;
        c.iterations = n;
        out.push_back(c);
      }
  }
}

// Each setting with 1 thread, then (batch paths) with each other thread count.
std::vector<Configuration> sweep(const Settings& settings, Isa isa) {
  std::vector<int> iterations = {0};
  iterations.insert(iterations.end(), settings.iterations.begin(), settings.iterations.end());
  std::vector<Configuration> swept;
  for (Family family : settings.families) {
    swept.push_back({Path::brent_baseline, family});
    swept.push_back({Path::scalar_reference, family});
    // The scene-like mix is there for the overlap answers; its full answers
    // are measured with automatic iterations only, for comparison.
    const std::vector<int> full_iterations =
        family == Family::scene ? std::vector<int>{0} : iterations;
    for (Path path : full_paths) add_settings(swept, path, family, isa, full_iterations);
    for (Path path : overlap_paths) add_settings(swept, path, family, isa, iterations);
  }
  std::vector<Configuration> timed;
  for (const Configuration& c : swept)
    for (int t : settings.threads)
      if (t == 1 || is_batch(c.path)) timed.push_back(c.with_threads(t));
  return timed;
}

int run(int argc, char** argv) {
  const Settings settings = parse_settings(argc, argv);
  BenchmarkArguments arguments(argc, argv, settings.benchmark_defaults);
  const std::string min_time =
      arguments.last_value("benchmark_min_time").value_or(default_min_time);
  benchmark::Initialize(&arguments.argc(), arguments.argv(), print_help);
  remove_pwcontact_flags(arguments.argc(), arguments.argv());
  if (benchmark::ReportUnrecognizedArguments(arguments.argc(), arguments.argv())) return 1;

  const Isa isa = resolve_isa(Isa::automatic);
  add_run_context(
      {isa, settings.sizes, settings.threads, settings.families, min_time, settings.label});
  Families families(settings.sizes);
  Accuracies accuracies(families);
  register_configurations(sweep(settings, isa), families, accuracies);
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
    std::cerr << "pwcontact_trade: " << e.what() << '\n';
    return 2;
  }
}
