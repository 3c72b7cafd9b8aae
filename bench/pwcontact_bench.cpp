// pwcontact_bench: pairs per second and accuracy of every way pwcontact
// computes the contact function mu^2, timed in one run against the existing
// library's method (brent_baseline), and a closing summary of the ratios and
// of the project's targets.
//
// Benchmark names: <path>/<family>/isa:<isa>/iterations:<n>/threads:<t> for the
// batch paths and <path>/<family>/threads:1 for the scalar ones (Google
// Benchmark appends /real_time). iterations:0 is the library's default count.
// Every benchmark reports items_per_second = pairs per second, in real time:
// the batch path runs its own OpenMP threads, so CPU time would not compare
// like with like. Accuracy counters are computed once per configuration,
// outside the timed region, on the whole family (see configuration.hpp).
//
// The default sweep measures every fixed iteration count on the default
// instruction set (isa:auto resolved: the best one, or PWCONTACT_ISA) with 1
// thread, and the default settings on every instruction set and with every
// thread count; --pwcontact_sweep=full crosses everything.
// For the summary's medians, run with --benchmark_repetitions=5 (and
// --benchmark_enable_random_interleaving=true on a noisy machine, so that a
// burst of foreign load does not hit one configuration's repetitions only).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "accuracy.hpp"
#include "brent_baseline.hpp"
#include "configuration.hpp"
#include "pwcontact/pwcontact.hpp"
#include "summary.hpp"

namespace pwcontact::bench {
namespace {

// ---------------------------------------------------------------------------
// Settings

struct Settings {
  bool full_sweep = false;
  std::vector<int> iterations;  // fixed counts swept besides 0 (the default)
  std::vector<int> threads = {1, 2};
  // Large enough that a batch call (~25 ms in double on one thread) dwarfs the
  // cost of starting and joining threads, so that thread scaling is measured
  // on the work; the scalar paths time a sample of it (below).
  std::size_t random_pairs = std::size_t(1) << 20;
};

// Fixed so that every run solves the same pairs.
constexpr std::uint64_t random_seed = 85;

// The scalar paths solve about a million pairs per second: a sample of this
// many pairs keeps one benchmark iteration near 0.1 s.
constexpr std::size_t scalar_sample_limit = std::size_t(1) << 16;

const char* const pwcontact_flags_help =
    "\npwcontact_bench flags:\n"
    "  [--pwcontact_sweep=default|full]  full: every instruction set x iteration count x\n"
    "                                    thread count (default: iteration counts on the\n"
    "                                    default instruction set only, 1 thread)\n"
    "  [--pwcontact_iterations=LIST]     fixed Newton iteration counts to sweep, e.g. 2,3,4\n"
    "                                    (0, the library's default, is always measured)\n"
    "  [--pwcontact_threads=LIST]        thread counts of the batch paths (default 1,2)\n"
    "  [--pwcontact_random_pairs=N]      size of the random family (default 1048576)\n"
    "Names: <path>/<family>/isa:<isa>/iterations:<n>/threads:<t>; select with filters, e.g.\n"
    "  --benchmark_filter='(brent_baseline|batch_double)/random'\n"
    "  --benchmark_filter=pw85 --pwcontact_iterations=4,8,12,16,20,24  (pw85 needs more)\n";

void print_help() {
  benchmark::PrintDefaultHelp();
  std::fputs(pwcontact_flags_help, stdout);
}

std::vector<int> sorted_unique(std::vector<int> counts) {
  std::sort(counts.begin(), counts.end());
  counts.erase(std::unique(counts.begin(), counts.end()), counts.end());
  return counts;
}

std::vector<int> default_swept_iterations() {
  return sorted_unique({2, 3, 4, 5, 6, 7, 8});
}

// "--name=value" -> value
std::optional<std::string> flag_value(const char* arg, const std::string& name) {
  const std::string prefix = "--" + name + "=";
  if (std::strncmp(arg, prefix.c_str(), prefix.size()) != 0) return std::nullopt;
  return std::string(arg + prefix.size());
}

long parse_count(const std::string& text, const std::string& flag, long minimum) {
  std::size_t used = 0;
  long value = 0;
  try {
    value = std::stol(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || value < minimum)
    throw std::invalid_argument("--" + flag + ": '" + text + "' is not an integer >= " +
                                std::to_string(minimum));
  return value;
}

// "2,3,4" -> {2, 3, 4}, sorted, without repeats.
std::vector<int> parse_counts(const std::string& list, const std::string& flag, int minimum) {
  std::vector<int> counts;
  std::stringstream items(list);
  for (std::string item; std::getline(items, item, ',');)
    counts.push_back(int(parse_count(item, flag, minimum)));
  if (counts.empty()) throw std::invalid_argument("--" + flag + ": empty list");
  return sorted_unique(std::move(counts));
}

// Reads and removes pwcontact's own flags; Google Benchmark has already
// removed its own, so whatever is left is unknown.
Settings parse_settings(int& argc, char** argv) {
  Settings settings;
  settings.iterations = default_swept_iterations();
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
      settings.random_pairs = std::size_t(parse_count(*v, "pwcontact_random_pairs", 1));
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  return settings;
}

// ---------------------------------------------------------------------------
// Families of pairs, their oracles, and the scalar paths' samples

// One pair in the layout the scalar paths take, as the existing library's
// callers hold it: gathered before timing, so the scalar paths are not
// charged for reading the structure of arrays.
struct ScalarPair {
  double r12[3], q1[6], q2[6];
};

ScalarPair scalar_pair(const PairBatch<double>& pairs, std::size_t i) {
  ScalarPair p;
  pairs.get(i, p.r12, p.q1, p.q2);
  return p;
}

// The scalar paths time every k-th pair, k the smallest stride that keeps the
// sample within scalar_sample_limit and is prime to 2 and 3: the pw85 family
// is built from 3 distances, 12 directions and 108 spheroids, so such a
// stride visits all of them in their proportions.
std::size_t scalar_stride(std::size_t n) {
  std::size_t stride = 1;
  const auto prime_to_6 = [](std::size_t k) { return k % 2 != 0 && k % 3 != 0; };
  while ((n + stride - 1) / stride > scalar_sample_limit || !prime_to_6(stride)) ++stride;
  return stride;
}

template <class V, class Make>
const V& cached(std::optional<V>& slot, Make make) {
  if (!slot) slot = make();
  return *slot;
}

template <class T>
std::vector<long double> family_oracle(const PairBatch<T>& pairs, Family family,
                                       const char* inputs) {
  std::vector<long double> oracle = oracle_mu2(pairs);
  const auto failed = std::count_if(oracle.begin(), oracle.end(),
                                    [](long double x) { return std::isnan(x); });
  if (failed > 0)
    std::cerr << "pwcontact_bench: the long double oracle has no valid mu^2 for " << failed
              << " pairs of the " << family_name(family) << " family (" << inputs
              << " inputs); they are left out of the error statistics\n";
  return oracle;
}

// Everything derived from a family is built on first use and kept: the pw85
// oracle alone takes seconds.
class Families {
 public:
  explicit Families(std::size_t random_pairs) : random_pairs_(random_pairs) {}

  const PairBatch<double>& pairs(Family f) {
    return cached(data_[f].pairs, [&] {
      return f == Family::random ? random_pairs(random_pairs_, random_seed) : pw85_family();
    });
  }
  const PairBatch<float>& float_pairs(Family f) {
    return cached(data_[f].float_pairs, [&] { return to_float(pairs(f)); });
  }
  // On the double inputs: the truth every path is measured against.
  const std::vector<long double>& oracle(Family f) {
    return cached(data_[f].oracle, [&] { return family_oracle(pairs(f), f, "double"); });
  }
  // On the float-rounded inputs: the float batch path's own error.
  const std::vector<long double>& float_input_oracle(Family f) {
    return cached(data_[f].float_input_oracle,
                  [&] { return family_oracle(float_pairs(f), f, "float-rounded"); });
  }
  const std::vector<ScalarPair>& scalar_sample(Family f) {
    return cached(data_[f].scalar_sample, [&] {
      const PairBatch<double>& all = pairs(f);
      std::vector<ScalarPair> sample;
      for (std::size_t i = 0, stride = scalar_stride(all.size()); i < all.size(); i += stride)
        sample.push_back(scalar_pair(all, i));
      return sample;
    });
  }

 private:
  struct Derived {
    std::optional<PairBatch<double>> pairs;
    std::optional<PairBatch<float>> float_pairs;
    std::optional<std::vector<long double>> oracle, float_input_oracle;
    std::optional<std::vector<ScalarPair>> scalar_sample;
  };
  std::size_t random_pairs_;
  std::map<Family, Derived> data_;
};

// ---------------------------------------------------------------------------
// The paths

// Calls visit(solve) with solve(const ScalarPair&) -> mu^2 (NaN when the path
// has no valid answer) for one of the scalar paths.
template <class Visit>
auto with_scalar_path(Path path, Visit&& visit) {
  if (path == Path::brent_baseline)
    return visit(
        [](const ScalarPair& p) { return brent_contact_function(p.r12, p.q1, p.q2).mu2; });
  return visit(
      [](const ScalarPair& p) { return contact_function<double>(p.r12, p.q1, p.q2).mu2; });
}

BatchOptions batch_options(const Configuration& c) {
  BatchOptions options;
  options.iterations = c.iterations;
  options.threads = c.threads;
  options.isa = c.isa;
  return options;
}

// ---------------------------------------------------------------------------
// Accuracy, once per configuration

struct Accuracy {
  ErrorStatistics error;  // against the oracle on the inputs the path solved
  std::optional<ErrorStatistics> error_double_input;  // batch_float only
  std::optional<std::size_t> fallbacks;               // batch paths only
  std::size_t invalid = 0;
  std::size_t pairs = 0;
};

class Accuracies {
 public:
  explicit Accuracies(Families& families) : families_(families) {}

  const Accuracy& of(const Configuration& c) {
    // Batch results are bit for bit the same for every thread count: one
    // entry per configuration serves all of them, computed with all threads.
    const std::string key = c.with_threads(1).name();
    auto found = cache_.find(key);
    if (found == cache_.end()) found = cache_.emplace(key, measure(c)).first;
    return found->second;
  }

 private:
  Accuracy measure(const Configuration& c) {
    const Family f = c.family;
    switch (c.path) {
      case Path::scalar_reference:
      case Path::brent_baseline:
        return scalar_accuracy(c.path, f);
      case Path::batch_double:
        return batch_accuracy(families_.pairs(f), c, families_.oracle(f));
      case Path::batch_float: {
        std::vector<float> mu2;
        Accuracy a =
            batch_accuracy(families_.float_pairs(f), c, families_.float_input_oracle(f), &mu2);
        a.error_double_input = relative_errors(mu2, families_.oracle(f));
        return a;
      }
    }
    throw std::logic_error("unknown path");
  }

  Accuracy scalar_accuracy(Path path, Family f) {
    const PairBatch<double>& pairs = families_.pairs(f);
    const std::vector<double> mu2 = with_scalar_path(path, [&](auto solve) {
      std::vector<double> out(pairs.size());
#pragma omp parallel for schedule(dynamic, 1024)
      for (std::size_t i = 0; i < pairs.size(); ++i) out[i] = solve(scalar_pair(pairs, i));
      return out;
    });
    Accuracy a;
    a.pairs = pairs.size();
    a.error = relative_errors(mu2, families_.oracle(f));
    a.invalid = std::size_t(
        std::count_if(mu2.begin(), mu2.end(), [](double x) { return !std::isfinite(x); }));
    return a;
  }

  // `mu2_out`, when given, receives the batch's mu^2 for further comparisons.
  template <class T>
  Accuracy batch_accuracy(const PairBatch<T>& pairs, const Configuration& c,
                          const std::vector<long double>& oracle,
                          std::vector<T>* mu2_out = nullptr) {
    std::vector<T> mu2(pairs.size());
    BatchOptions options = batch_options(c);
    options.threads = 0;  // all: the results do not depend on it
    const BatchReport report = contact_function_batch(pairs.view(), {mu2.data()}, options);
    Accuracy a;
    a.pairs = pairs.size();
    a.error = relative_errors(mu2, oracle);
    a.fallbacks = report.fallbacks;
    a.invalid = report.invalid;
    if (mu2_out) *mu2_out = std::move(mu2);
    return a;
  }

  Families& families_;
  std::map<std::string, Accuracy> cache_;
};

void report_accuracy(benchmark::State& state, const Accuracy& a) {
  state.counters[counter::max_rel_err] = a.error.max;
  state.counters[counter::p999_rel_err] = a.error.p999;
  state.counters[counter::median_rel_err] = a.error.median;
  if (a.error_double_input)
    state.counters[counter::max_rel_err_double_input] = a.error_double_input->max;
  if (a.fallbacks) {
    state.counters[counter::fallbacks] = double(*a.fallbacks);
    state.counters[counter::fallbacks_per_pair] = double(*a.fallbacks) / double(a.pairs);
  }
  state.counters[counter::invalid] = double(a.invalid);
}

// ---------------------------------------------------------------------------
// Timing

template <class Solve>
void time_scalar(benchmark::State& state, const std::vector<ScalarPair>& sample, Solve solve) {
  for (auto _ : state)
    for (const ScalarPair& p : sample) benchmark::DoNotOptimize(solve(p));
  state.SetItemsProcessed(state.iterations() * std::int64_t(sample.size()));
}

// Asks for what a caller typically wants, mu^2, lambda and each pair's status,
// as the scalar paths deliver mu^2 and lambda too.
template <class T>
void time_batch(benchmark::State& state, const PairBatch<T>& pairs, const BatchOptions& options) {
  const std::size_t n = pairs.size();
  std::vector<T> mu2(n), lambda(n);  // zero-filled: no page faults in the timed region
  std::vector<Status> status(n);
  const PairBatchView<T> view = pairs.view();
  const ContactOutputs<T> out{mu2.data(), lambda.data(), status.data()};
  for (auto _ : state) {
    contact_function_batch(view, out, options);
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(n));
}

void run_configuration(benchmark::State& state, const Configuration& c, Families& families,
                       Accuracies& accuracies) {
  const Accuracy* accuracy = nullptr;
  try {
    accuracy = &accuracies.of(c);  // also builds the family, outside the timed region
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  switch (c.path) {
    case Path::scalar_reference:
    case Path::brent_baseline:
      with_scalar_path(c.path, [&](auto solve) {
        time_scalar(state, families.scalar_sample(c.family), solve);
      });
      break;
    case Path::batch_double:
      time_batch(state, families.pairs(c.family), batch_options(c));
      break;
    case Path::batch_float:
      time_batch(state, families.float_pairs(c.family), batch_options(c));
      break;
  }
  report_accuracy(state, *accuracy);
}

// ---------------------------------------------------------------------------
// What is measured

// The default sweep: the default iteration count with 1 thread on every
// instruction set, every swept iteration count on the default one, and the
// default settings with every thread count.
bool in_default_sweep(const Configuration& c, Isa default_isa) {
  if (c.iterations == 0 && c.threads == 1) return true;
  return c.isa == default_isa && (c.threads == 1 || c.iterations == 0);
}

std::vector<Configuration> sweep(const Settings& settings, Isa default_isa) {
  std::vector<int> iterations = {0};
  iterations.insert(iterations.end(), settings.iterations.begin(), settings.iterations.end());
  std::vector<Configuration> out;
  for (Family family : {Family::random, Family::pw85}) {
    out.push_back({Path::brent_baseline, family});
    out.push_back({Path::scalar_reference, family});
    for (Path path : {Path::batch_double, Path::batch_float})
      for (Isa isa : supported_isas())
        for (int n : iterations)
          for (int threads : settings.threads) {
            const Configuration c{path, family, isa, n, threads};
            if (settings.full_sweep || in_default_sweep(c, default_isa)) out.push_back(c);
          }
  }
  return out;
}

int run(int argc, char** argv) {
  benchmark::Initialize(&argc, argv, print_help);
  const Settings settings = parse_settings(argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;

  const Isa default_isa = resolve_isa(Isa::automatic);
  benchmark::AddCustomContext("pwcontact_default_isa", isa_name(default_isa));
  benchmark::AddCustomContext("pwcontact_random_pairs", std::to_string(settings.random_pairs));
  benchmark::AddCustomContext("pwcontact_pw85_pairs", std::to_string(pw85_family_size));

  Families families(settings.random_pairs);
  Accuracies accuracies(families);
  const std::vector<Configuration> configurations = sweep(settings, default_isa);
  for (const Configuration& c : configurations)
    benchmark::RegisterBenchmark(c.name().c_str(),
                                 [c, &families, &accuracies](benchmark::State& state) {
                                   run_configuration(state, c, families, accuracies);
                                 })
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);

  SummaryReporter reporter(benchmark::CreateDefaultDisplayReporter(), configurations, default_isa);
  benchmark::RunSpecifiedBenchmarks(&reporter);
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
