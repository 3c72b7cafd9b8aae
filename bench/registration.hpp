// What both benchmark programs do with Google Benchmark: register each
// configuration as a benchmark that times its prepared run (paths.hpp) and
// reports, besides items_per_second (pairs per second, real time), its
// accuracy as counters (counters.hpp); and describe the run in the JSON
// output's context. Every report is made afterwards from that JSON by
// bench/report.py.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "configuration.hpp"
#include "families.hpp"

namespace pwcontact::bench {

// Each configuration's accuracy counters, measured once (on the whole family,
// with all threads) the first time it runs, outside the timed region; the
// thread counts of one configuration share them, as batch results are bit
// for bit the same for every thread count.
class Accuracies {
 public:
  explicit Accuracies(Families& families) : families_(families) {}

  const std::map<std::string, double>& of(const Configuration& c);

 private:
  Families& families_;
  std::map<std::string, std::map<std::string, double>> cache_;
};

// Registers every configuration, in order, under its name() (Google Benchmark
// appends /real_time). `families` and `accuracies` must outlive the runs.
void register_configurations(const std::vector<Configuration>& configurations, Families& families,
                             Accuracies& accuracies);

// How the run was made, for the reports: added to the JSON output's context
// as pwcontact_default_isa, pwcontact_generated_pairs, pwcontact_pw85_pairs,
// pwcontact_near_tangent_pairs, pwcontact_threads, pwcontact_families,
// pwcontact_min_time and, when not empty, pwcontact_label.
struct RunContext {
  Isa default_isa = Isa::automatic;
  FamilySizes sizes;
  std::vector<int> threads;
  std::vector<Family> families;
  std::string min_time;  // seconds, as --benchmark_min_time says
  std::string label;     // e.g. the commit measured
};

void add_run_context(const RunContext& context);

// Google Benchmark's own command line with `defaults` put first, so that the
// caller's flags (later) override them; and the value the last of them gives
// to --<flag>, Google Benchmark's rule too. Read before benchmark::Initialize,
// which removes its flags.
class BenchmarkArguments {
 public:
  BenchmarkArguments(int argc, char** argv, const std::vector<std::string>& defaults = {});

  int& argc() { return argc_; }
  char** argv() { return pointers_.data(); }
  std::optional<std::string> last_value(const std::string& flag) const;

 private:
  std::vector<std::string> arguments_;
  std::vector<char*> pointers_;
  int argc_ = 0;
};

// Google Benchmark's default --benchmark_min_time (version 1.7), in seconds.
inline constexpr const char* default_min_time = "0.5";

}  // namespace pwcontact::bench
