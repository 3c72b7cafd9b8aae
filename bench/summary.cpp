#include "summary.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>

#include "targets.hpp"

namespace pwcontact::bench {
namespace {

constexpr double not_measured = std::numeric_limits<double>::quiet_NaN();

void print_table(std::ostream& out, const Table& table) {
  std::size_t width = 13;
  for (const Measurement& m : table.rows()) width = std::max(width, m.configuration.name().size());
  const int w = int(width);
  constexpr const char* row = "%-*s %10s %6s %8s %10s %10s %10s %13s %10s %10s %8s %10s %10s\n";
  out << format(row, w, "configuration", "pairs/s", "cv", "x brent", "max err", "p99.9 err",
                "median err", "max err (dbl)", "fallb/pair", "evals/pair", "invalid", "misclass.",
                "near-tang.");
  for (const Measurement& m : table.rows())
    out << format(
        row, w, m.configuration.name().c_str(), cell(m.pairs_per_second, "%.3g").c_str(),
        cell(100 * m.pairs_per_second_cv, "%.0f%%").c_str(), cell(table.speedup(m), "%.2f").c_str(),
        cell(m.counter(counter::max_rel_err)).c_str(),
        cell(m.counter(counter::p999_rel_err)).c_str(),
        cell(m.counter(counter::median_rel_err)).c_str(),
        cell(m.counter(counter::max_rel_err_double_input)).c_str(),
        cell(m.counter(counter::fallbacks_per_pair), "%.3g").c_str(),
        cell(m.counter(counter::mean_evaluations), "%.2f").c_str(),
        cell(m.counter(counter::invalid), "%.0f").c_str(), misclassification_cell(m, false).c_str(),
        misclassification_cell(m, true).c_str());
}

void print_thread_scaling(std::ostream& out, const Table& table) {
  int printed = 0;
  for (const Measurement& m : table.rows()) {
    const Configuration& c = m.configuration;
    if (!is_batch(c.path) || c.threads == 1 || !table.find(c.with_threads(1))) continue;
    const Configuration one_thread = c.with_threads(1);
    out << format("  %-60s threads:%d / threads:1 = %.2f%s\n", one_thread.name().c_str(), c.threads,
                  table.thread_scaling(one_thread, c.threads),
                  table.best_scaling_note(one_thread, c.threads).c_str());
    ++printed;
  }
  if (printed == 0) out << "  not measured\n";
}

// Which fixed iteration count gives the most pairs per second while staying
// within each target's accuracy, on the default instruction set, 1 thread.
void print_iteration_choice(std::ostream& out, const Table& table, Isa default_isa) {
  for (const Target& t : targets()) {
    const Configuration defaults = target_configuration(t, default_isa);
    std::string line = format("  %s: ", defaults.name().c_str());
    std::size_t candidates = 0;
    const Measurement* best = fastest_within(table, t, default_isa, true, &candidates);
    if (!best) {
      out << line
          << (candidates ? "no measured fixed iteration count is within the accuracy\n"
                         : "no fixed iteration count measured\n");
      continue;
    }
    line += format(
        "fastest iterations:%d, %.3g pairs/s = %sx brent_baseline, "
        "%.3g fallbacks per pair",
        best->configuration.iterations, best->pairs_per_second,
        cell(table.speedup(*best), "%.1f").c_str(), best->counter(counter::fallbacks_per_pair));
    if (const Measurement* d = table.find(defaults))
      line += format("; default (automatic) %.3g pairs/s, fastest / default = %.2f",
                     d->pairs_per_second, best->pairs_per_second / d->pairs_per_second);
    out << line << '\n';
  }
}

}  // namespace

SummaryReporter::SummaryReporter(benchmark::BenchmarkReporter* display,
                                 const std::vector<Configuration>& configurations, Isa default_isa)
    : display_(display), default_isa_(default_isa) {
  for (const Configuration& c : configurations) {
    order_.push_back(c.name());
    records_.emplace(c.name(), Record{c, {}, not_measured, not_measured, {}});
  }
}

bool SummaryReporter::ReportContext(const Context& context) {
  // Google Benchmark hands its streams to the reporter it was given: pass them on.
  display_->SetOutputStream(&GetOutputStream());
  display_->SetErrorStream(&GetErrorStream());
  return display_->ReportContext(context);
}

void SummaryReporter::ReportRuns(const std::vector<Run>& runs) {
  display_->ReportRuns(runs);
  for (const Run& run : runs) {
    const auto found = records_.find(run.run_name.function_name);
    if (run.error_occurred || found == records_.end()) continue;
    Record& record = found->second;
    const auto rate = run.counters.find(counter::items_per_second);
    const double pairs_per_second = rate == run.counters.end() ? not_measured : rate->second.value;
    // Of the aggregates, the median gives the throughput (robust on a noisy
    // machine) and the coefficient of variation says how noisy it was. The
    // iteration runs may be absent (--benchmark_report_aggregates_only).
    if (run.run_type == Run::RT_Aggregate) {
      if (run.aggregate_name == "cv") record.rate_cv = pairs_per_second;
      if (run.aggregate_name != "median") continue;
      record.median_rate = pairs_per_second;
    } else {
      record.rates.push_back(pairs_per_second);
    }
    repetitions_ = std::max<long>(repetitions_, long(run.repetitions));
    for (const auto& [name, value] : run.counters) record.counters[name] = value.value;
  }
}

std::vector<Measurement> SummaryReporter::measurements() const {
  std::vector<Measurement> out;
  for (const std::string& name : order_) {
    const Record& r = records_.at(name);
    const double rate = std::isnan(r.median_rate) ? median(r.rates) : r.median_rate;
    if (std::isnan(rate)) continue;  // filtered out, or failed
    const double best =
        r.rates.empty() ? not_measured : *std::max_element(r.rates.begin(), r.rates.end());
    Measurement m{r.configuration, rate, r.rate_cv, best, r.counters};
    m.counters[counter::items_per_second] = rate;
    out.push_back(std::move(m));
  }
  return out;
}

void SummaryReporter::Finalize() {
  display_->Finalize();
  std::ostream& out =
      dynamic_cast<benchmark::ConsoleReporter*>(display_) ? GetOutputStream() : GetErrorStream();
  print_summary(out, measurements(), default_isa_, repetitions_);
}

void print_summary(std::ostream& out, const std::vector<Measurement>& measurements, Isa default_isa,
                   long repetitions) {
  const Table table(measurements);
  out << format(
      "\nSummary (%s; real time; errors: relative error of mu^2 against the long double "
      "oracle on the inputs each path solved, \"dbl\" against the double inputs)\n",
      repetitions > 1 ? format("medians of %ld repetitions", repetitions).c_str()
                      : "single runs, no repetitions");
  out << "(misclass.: overlap answers on the family that disagree with the oracle's mu^2 < 1, "
         "farther from tangency than |mu^2 - 1| = 1e-9 / closer; near-tang.: the same for "
         "overlap answers or mu^2 < 1 of full answers on the family's near-tangent set.)\n"
         "(Google Benchmark prints small counters with SI prefixes: m 1e-3, u 1e-6, n 1e-9, "
         "p 1e-12, f 1e-15, a 1e-18, z 1e-21.)\n\n";
  print_table(out, table);
  out << "\nThread scaling (same configuration, more threads / 1 thread)\n";
  print_thread_scaling(out, table);
  out << format(
      "\nTargets (1 thread; default settings are isa:auto = isa:%s and iterations:0 = "
      "automatic)\n",
      isa_name(default_isa));
  print_targets(out, table, default_isa);
  out << format("\nFixed iteration counts swept on isa:%s, 1 thread\n", isa_name(default_isa));
  print_iteration_choice(out, table, default_isa);
  out.flush();
}

}  // namespace pwcontact::bench
