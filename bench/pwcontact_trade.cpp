// pwcontact_trade: the speed/accuracy trade, measured. Sweeps the answer
// (full mu^2 and lambda, or overlap only) x the precision (double, mixed,
// float on double pairs, float pairs) x the iterations (automatic and fixed
// counts) x the formulation (newton, log_odds, and the library's automatic
// choice with automatic iterations) x the accuracy (standard, and high where
// the library allows it) over the random, pw85, extreme and scene-like
// families, and records for each configuration its throughput with each
// thread count, the error of mu^2 against the long double oracle, its
// fallbacks and evaluations, and its misclassifications of the family's
// near-tangent pairs. brent_baseline is timed on every family in the same
// run, so that every speed is also a ratio to it.
//
// Timing: each timing calls the prepared configuration (paths.hpp: inputs
// built, answers allocated, oracles computed beforehand) until at least
// --min-time seconds have passed, on a steady clock, and counts pairs per
// second. Every configuration is timed once per round, in an order shuffled
// afresh each round, so that a burst of foreign load on this shared machine
// hits different configurations in different rounds; the figure is the
// median over the rounds.
//
// Outputs: a CSV and a Markdown table, one row per configuration, and a PNG
// plot of max relative error against throughput drawn by gnuplot (see
// --help); a summary on standard output.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

#include "command_line.hpp"
#include "configuration.hpp"
#include "families.hpp"
#include "measurement.hpp"
#include "paths.hpp"
#include "targets.hpp"
#include "trade_report.hpp"

namespace pwcontact::bench {
namespace {

// ---------------------------------------------------------------------------
// Settings

struct Settings {
  std::vector<int> iterations;  // fixed counts swept besides 0 (automatic)
  std::vector<int> threads = {1, 2};
  int repetitions = 3;
  double min_time = 0.03;
  FamilySizes sizes;
  std::vector<Family> families = {Family::random, Family::pw85, Family::extreme, Family::scene};
  std::optional<std::regex> filter;  // on settings_name(); brent_baseline is always timed
  std::string csv, markdown, plot;
  bool draw_plot = true;
  std::string label;
};

// The sweeps offered: how many fixed iteration counts, repetitions and
// pairs. The default keeps a run to a few minutes on this machine.
Settings preset(const std::string& sweep) {
  Settings s;
  if (sweep == "quick") {
    s.iterations = {4, 12};
    s.repetitions = 3;
    s.min_time = 0.01;
    s.sizes = {std::size_t(1) << 16, std::size_t(1) << 13};
  } else if (sweep == "default") {
    s.iterations = {2, 3, 4, 6, 8, 12, 16, 24};
    s.repetitions = 3;
    s.min_time = 0.03;
    s.sizes = {std::size_t(1) << 18, std::size_t(1) << 16};
  } else if (sweep == "full") {
    s.iterations = {1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 32};
    s.repetitions = 5;
    s.min_time = 0.1;
    s.sizes = {std::size_t(1) << 20, std::size_t(1) << 17};
  } else {
    throw std::invalid_argument("--sweep: '" + sweep + "' is not quick, default or full");
  }
  return s;
}

const char* const help_text =
    "usage: pwcontact_trade [flags]\n"
    "Measures pwcontact's speed/accuracy trade and writes it as CSV, Markdown and a PNG plot.\n"
    "  --sweep=quick|default|full  size of the sweep (default: default, a few minutes;\n"
    "                              quick: seconds, small families; full: every count, 2^20 pairs)\n"
    "  --iterations=LIST           fixed iteration counts swept besides automatic, e.g. 2,4,8\n"
    "  --threads=LIST              thread counts timed (default 1,2)\n"
    "  --repetitions=N             timing rounds; figures are medians over them\n"
    "  --min-time=SECONDS          calls per timing last at least this long\n"
    "  --pairs=N                   pairs of each generated family (random, extreme, scene)\n"
    "  --near-tangent=N            pairs of each near-tangent set\n"
    "  --families=LIST             of random,pw85,extreme,scene (default all)\n"
    "  --filter=REGEX              only configurations whose name matches (brent_baseline is\n"
    "                              always timed), e.g. 'batch_(double|mixed)/pw85'\n"
    "  --csv=PATH --markdown=PATH --plot=PATH   output files (default: trade.csv, trade.md,\n"
    "                              trade.png in " PWCONTACT_TRADE_OUTPUT_DIR
    ");\n"
    "                              the plot's gnuplot script and data go beside the CSV\n"
    "  --no-plot                   write no plot (gnuplot is then not needed)\n"
    "  --label=TEXT                printed in the headers, e.g. the commit measured\n"
    "Names: <path>/<family>/isa:<isa>/iterations:<n>[/formulation:<f>][/accuracy:high]\n"
    "(the same scheme as pwcontact_bench's).\n";

Family parse_family(const std::string& name) {
  for (Family f : {Family::random, Family::pw85, Family::extreme, Family::scene})
    if (name == family_name(f)) return f;
  throw std::invalid_argument("--families: unknown family '" + name + "'");
}

std::optional<Settings> parse_settings(int argc, char** argv) {
  std::string sweep = "default";
  for (int i = 1; i < argc; ++i)
    if (auto v = flag_value(argv[i], "sweep")) sweep = *v;
  Settings s = preset(sweep);
  const std::string output_dir = PWCONTACT_TRADE_OUTPUT_DIR;
  s.csv = output_dir + "/trade.csv";
  s.markdown = output_dir + "/trade.md";
  s.plot = output_dir + "/trade.png";
  for (int i = 1; i < argc; ++i) {
    const char* arg = argv[i];
    if (std::string(arg) == "--help" || std::string(arg) == "-h") {
      std::fputs(help_text, stdout);
      return std::nullopt;
    }
    if (std::string(arg) == "--no-plot") {
      s.draw_plot = false;
    } else if (flag_value(arg, "sweep")) {
      // read above: the other flags override the preset whatever their order
    } else if (auto v = flag_value(arg, "iterations")) {
      s.iterations = parse_counts(*v, "iterations", 1);
    } else if (auto v = flag_value(arg, "threads")) {
      s.threads = parse_counts(*v, "threads", 1);
    } else if (auto v = flag_value(arg, "repetitions")) {
      s.repetitions = int(parse_count(*v, "repetitions", 1));
    } else if (auto v = flag_value(arg, "min-time")) {
      s.min_time = parse_positive(*v, "min-time");
    } else if (auto v = flag_value(arg, "pairs")) {
      s.sizes.generated = std::size_t(parse_count(*v, "pairs", 1));
    } else if (auto v = flag_value(arg, "near-tangent")) {
      s.sizes.near_tangent = std::size_t(parse_count(*v, "near-tangent", 1));
    } else if (auto v = flag_value(arg, "families")) {
      s.families.clear();
      for (const std::string& name : parse_names(*v, "families"))
        s.families.push_back(parse_family(name));
    } else if (auto v = flag_value(arg, "filter")) {
      s.filter.emplace(*v);
    } else if (auto v = flag_value(arg, "csv")) {
      s.csv = *v;
    } else if (auto v = flag_value(arg, "markdown")) {
      s.markdown = *v;
    } else if (auto v = flag_value(arg, "plot")) {
      s.plot = *v;
    } else if (auto v = flag_value(arg, "label")) {
      s.label = *v;
    } else {
      throw std::invalid_argument(std::string("unknown flag '") + arg + "' (see --help)");
    }
  }
  if (s.threads.front() != 1)
    throw std::invalid_argument("--threads must include 1: every ratio is quoted for 1 thread");
  return s;
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

// With 1 thread; the timing adds the other thread counts.
std::vector<Configuration> sweep(const Settings& settings, Isa isa) {
  std::vector<int> iterations = {0};
  iterations.insert(iterations.end(), settings.iterations.begin(), settings.iterations.end());
  const auto wanted = [&](const Configuration& c) {
    return !settings.filter || std::regex_search(c.settings_name(), *settings.filter);
  };
  std::vector<Configuration> swept;
  for (Family family : settings.families) {
    swept.push_back({Path::brent_baseline, family});  // always: every ratio needs it
    std::vector<Configuration> family_sweep = {{Path::scalar_reference, family}};
    // The scene-like mix is there for the overlap answers; its full answers
    // are measured with automatic iterations only, for comparison.
    const std::vector<int> full_iterations =
        family == Family::scene ? std::vector<int>{0} : iterations;
    for (Path path : full_paths) add_settings(family_sweep, path, family, isa, full_iterations);
    for (Path path : overlap_paths) add_settings(family_sweep, path, family, isa, iterations);
    for (const Configuration& c : family_sweep)
      if (wanted(c)) swept.push_back(c);
  }
  return swept;
}

// ---------------------------------------------------------------------------
// Timing

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Pairs per second of one configuration: calls until min_time has passed.
double time_configuration(const PreparedRun& run, double min_time) {
  long calls = 0;
  const Clock::time_point start = Clock::now();
  double elapsed = 0;
  do {
    run();
    ++calls;
    elapsed = seconds_since(start);
  } while (elapsed < min_time);
  return double(calls) * double(run.pairs_per_call()) / elapsed;
}

// Progress on standard error: updated in place about once a second on a
// terminal, one line per finished stage otherwise (a log stays readable).
class Progress {
 public:
  void report(const std::string& stage, std::size_t done, std::size_t total) {
    const bool finished = done == total;
    if (!finished && (!terminal_ || seconds_since(last_) < 1)) return;
    last_ = Clock::now();
    std::cerr << format("%s%s: %zu/%zu (%.0f s)%s", terminal_ ? "\r" : "", stage.c_str(), done,
                        total, seconds_since(start_), finished ? "\n" : "   ")
              << std::flush;
  }

 private:
  bool terminal_ = isatty(STDERR_FILENO) != 0;
  Clock::time_point start_ = Clock::now(), last_ = Clock::now();
};

std::vector<Measurement> measure(const std::vector<Configuration>& swept, const Settings& settings,
                                 Families& families) {
  Progress progress;
  // Accuracy first, once per configuration: this also builds every family,
  // oracle and near-tangent set, so that none of it is timed.
  std::map<std::string, std::map<std::string, double>> counters;
  for (std::size_t k = 0; k < swept.size(); ++k) {
    const Configuration& c = swept[k];
    counters[c.settings_name()] = accuracy_counters(measure_accuracy(c, families, true));
    progress.report("accuracy", k + 1, swept.size());
  }

  std::vector<Configuration> timed;
  for (const Configuration& c : swept)
    for (int t : settings.threads)
      if (t == 1 || is_batch(c.path)) timed.push_back(c.with_threads(t));
  for (const Configuration& c : timed) families.family(c.family).scalar_sample();

  std::map<std::string, std::vector<double>> rates;
  std::mt19937_64 shuffle(85);
  for (int round = 1; round <= settings.repetitions; ++round) {
    std::vector<std::size_t> order(timed.size());
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), shuffle);
    for (std::size_t k = 0; k < order.size(); ++k) {
      const Configuration& c = timed[order[k]];
      const PreparedRun run(c, families.family(c.family));
      rates[c.name()].push_back(time_configuration(run, settings.min_time));
      progress.report(format("timing, round %d of %d", round, settings.repetitions), k + 1,
                      order.size());
    }
  }

  std::vector<Measurement> out;
  for (const Configuration& c : timed) {
    const std::vector<double>& r = rates[c.name()];
    Measurement m{c, median(r), coefficient_of_variation(r), *std::max_element(r.begin(), r.end()),
                  counters[c.settings_name()]};
    m.counters[counter::items_per_second] = m.pairs_per_second;
    out.push_back(std::move(m));
  }
  return out;
}

void create_parent_directory(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent);
}

int run(int argc, char** argv) {
  const std::optional<Settings> parsed = parse_settings(argc, argv);
  if (!parsed) return 0;
  const Settings& settings = *parsed;
  // Before minutes of measuring, not after.
  if (settings.draw_plot && !gnuplot_available()) {
    std::cerr << "pwcontact_trade: gnuplot is not installed, and the plot needs it. Install "
                 "Debian's gnuplot-nox (apt-get install gnuplot-nox), or pass --no-plot to "
                 "write only the CSV and Markdown tables.\n";
    return 3;
  }
  for (const std::string& path : {settings.csv, settings.markdown, settings.plot})
    create_parent_directory(path);

  const Isa isa = resolve_isa(Isa::automatic);
  const std::vector<Configuration> swept = sweep(settings, isa);
  std::cerr << "pwcontact_trade: " << swept.size() << " configurations, " << settings.repetitions
            << " timing rounds, isa " << isa_name(isa) << '\n';
  Families families(settings.sizes);
  const std::vector<Measurement> measurements = measure(swept, settings, families);
  const Table table(measurements);

  const TradeRun run{settings.label,       isa,
                     settings.repetitions, settings.min_time,
                     settings.threads,     settings.sizes,
                     settings.families};
  write_csv(settings.csv, table, run);
  write_markdown(settings.markdown, table, run);
  std::cout << "Targets, fastest measured setting within each target's accuracy (1 thread)\n";
  print_targets_best_in_sweep(std::cout, table, isa);
  std::cout << "\nTargets, default settings\n";
  print_targets(std::cout, table, isa);
  std::cout << "\nBest setting per family and precision (full answer, 1 thread; fastest within "
               "10x of the lowest max error)\n";
  print_best_settings(std::cout, table, run);
  std::cout << "\nCSV: " << settings.csv << "\nMarkdown: " << settings.markdown << '\n';
  if (settings.draw_plot) {
    // The script and its data stay beside the CSV: the plot may be published alone.
    draw_plot(settings.plot, without_extension(settings.csv, ".csv"), table, run);
    std::cout << "Plot: " << settings.plot << '\n';
  }
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
