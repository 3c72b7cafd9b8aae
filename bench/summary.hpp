// The figures every run of pwcontact_bench ends with: each configuration's
// throughput as a multiple of brent_baseline on the same family, the thread
// scaling of the batch paths, and the project's speed and accuracy targets
// (targets.hpp), each said to be met or not.
#pragma once

#include <benchmark/benchmark.h>

#include <map>
#include <string>
#include <vector>

#include "configuration.hpp"
#include "measurement.hpp"

namespace pwcontact::bench {

// Passes every run on, unchanged, to the display reporter Google Benchmark
// would have used (so --benchmark_format still works) and collects the
// measurements; once all runs are done it prints the summary: after the
// console output on standard output, or on standard error when the display
// format is JSON or CSV so that standard output stays machine-readable.
class SummaryReporter : public benchmark::BenchmarkReporter {
 public:
  // `display` is not owned. `default_isa` is what the default settings
  // (Isa::automatic) resolve to on this machine.
  SummaryReporter(benchmark::BenchmarkReporter* display,
                  const std::vector<Configuration>& configurations, Isa default_isa);

  bool ReportContext(const Context& context) override;
  void ReportRuns(const std::vector<Run>& runs) override;
  void Finalize() override;

 private:
  // Everything a configuration's runs reported, before the median is taken.
  struct Record {
    Configuration configuration;
    std::vector<double> rates;  // items_per_second of each repetition
    double median_rate;         // from the "_median" aggregate, NaN without one
    double rate_cv;             // from the "_cv" aggregate, NaN without one
    std::map<std::string, double> counters;
  };

  std::vector<Measurement> measurements() const;  // in registration order, measured ones only

  benchmark::BenchmarkReporter* display_;
  std::vector<std::string> order_;
  std::map<std::string, Record> records_;
  Isa default_isa_;
  long repetitions_ = 1;
};

// The summary itself, for any list of measurements.
void print_summary(std::ostream& out, const std::vector<Measurement>& measurements, Isa default_isa,
                   long repetitions);

}  // namespace pwcontact::bench
