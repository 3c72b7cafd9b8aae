#include "registration.hpp"

#include <benchmark/benchmark.h>

#include <cstdint>
#include <exception>

#include "command_line.hpp"
#include "paths.hpp"

namespace pwcontact::bench {
namespace {

void run_configuration(benchmark::State& state, const Configuration& c, Families& families,
                       Accuracies& accuracies) {
  const std::map<std::string, double>* counters = nullptr;
  try {
    counters = &accuracies.of(c);  // also builds the family, outside the timed region
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const PreparedRun run(c, families.family(c.family));
  for (auto _ : state) {
    benchmark::DoNotOptimize(run());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * std::int64_t(run.pairs_per_call()));
  for (const auto& [name, value] : *counters) state.counters[name] = value;
}

template <class T, class Name>
std::string joined(const std::vector<T>& items, Name name) {
  std::string out;
  for (const T& item : items) out += (out.empty() ? "" : ",") + std::string(name(item));
  return out;
}

}  // namespace

const std::map<std::string, double>& Accuracies::of(const Configuration& c) {
  const std::string key = c.with_threads(1).name();
  auto found = cache_.find(key);
  if (found == cache_.end())
    found = cache_.emplace(key, accuracy_counters(measure_accuracy(c, families_, true))).first;
  return found->second;
}

void register_configurations(const std::vector<Configuration>& configurations, Families& families,
                             Accuracies& accuracies) {
  for (const Configuration& c : configurations)
    benchmark::RegisterBenchmark(c.name().c_str(),
                                 [c, &families, &accuracies](benchmark::State& state) {
                                   run_configuration(state, c, families, accuracies);
                                 })
        ->UseRealTime()
        ->Unit(benchmark::kMillisecond);
}

void add_run_context(const RunContext& context) {
  benchmark::AddCustomContext("pwcontact_default_isa", isa_name(context.default_isa));
  benchmark::AddCustomContext("pwcontact_generated_pairs", std::to_string(context.sizes.generated));
  benchmark::AddCustomContext("pwcontact_pw85_pairs", std::to_string(pw85_family_size));
  benchmark::AddCustomContext("pwcontact_near_tangent_pairs",
                              std::to_string(context.sizes.near_tangent));
  benchmark::AddCustomContext("pwcontact_threads",
                              joined(context.threads, [](int t) { return std::to_string(t); }));
  benchmark::AddCustomContext("pwcontact_families", joined(context.families, family_name));
  benchmark::AddCustomContext("pwcontact_min_time", context.min_time);
  if (!context.label.empty()) benchmark::AddCustomContext("pwcontact_label", context.label);
}

BenchmarkArguments::BenchmarkArguments(int argc, char** argv,
                                       const std::vector<std::string>& defaults) {
  if (argc > 0) arguments_.push_back(argv[0]);
  arguments_.insert(arguments_.end(), defaults.begin(), defaults.end());
  for (int i = 1; i < argc; ++i) arguments_.push_back(argv[i]);
  for (std::string& argument : arguments_) pointers_.push_back(argument.data());
  argc_ = int(pointers_.size());
  pointers_.push_back(nullptr);  // argv[argc], as main's
}

std::optional<std::string> BenchmarkArguments::last_value(const std::string& flag) const {
  std::optional<std::string> value;
  for (const std::string& argument : arguments_)
    if (auto v = flag_value(argument.c_str(), flag)) value = v;
  return value;
}

}  // namespace pwcontact::bench
