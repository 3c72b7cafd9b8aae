#include "summary.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <ostream>

namespace pwcontact::bench {
namespace {

constexpr double not_measured = std::numeric_limits<double>::quiet_NaN();

// The project's targets on this machine: 1 thread, default settings, ratios
// to brent_baseline measured in the same run.
struct Target {
  Path path;
  Family family;
  double max_rel_err;
  double min_speedup;  // over brent_baseline on the same family; 0: throughput reported only
};
constexpr Target targets[] = {
    {Path::batch_double, Family::random, 1e-13, 30},
    {Path::batch_float, Family::random, 1e-5, 60},
    {Path::batch_double, Family::pw85, 2e-11, 0},
};
// 2 threads against 1, both batch paths, default settings on this family.
constexpr Path thread_scaling_paths[] = {Path::batch_double, Path::batch_float};
constexpr Family thread_scaling_family = Family::random;
constexpr int thread_scaling_threads = 2;
constexpr double min_thread_scaling = 1.8;

// Above this coefficient of variation over repetitions a ratio is flagged:
// on a shared machine a foreign process can take a core for whole seconds.
constexpr double noisy_cv = 0.10;

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  char buffer[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buffer, sizeof buffer, fmt, args);
  va_end(args);
  return buffer;
}

// A table cell: "-" for a figure that was not measured.
std::string cell(double value, const char* fmt = "%.2e") {
  return std::isnan(value) ? std::string("-") : format(fmt, value);
}

const char* verdict(bool met) { return met ? "met" : "NOT MET"; }

std::string speedup_text(double speedup) {
  return std::isnan(speedup) ? std::string("brent_baseline not measured")
                             : format("%.1fx brent_baseline", speedup);
}

// As Google Benchmark computes its "_median" aggregate.
double median(std::vector<double> values) {
  if (values.empty()) return not_measured;
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  if (values.size() % 2 == 1) return values[mid];
  const double upper = values[mid];
  return (*std::max_element(values.begin(), values.begin() + mid) + upper) / 2;
}


Configuration default_settings(Path path, Family family, Isa default_isa) {
  return Configuration{path, family, default_isa, 0, 1};
}

// The measurements, looked up by configuration.
class Table {
 public:
  explicit Table(const std::vector<Measurement>& rows) : rows_(rows) {}

  const std::vector<Measurement>& rows() const { return rows_; }

  const Measurement* find(const Configuration& c) const {
    const std::string name = c.name();
    for (const Measurement& m : rows_)
      if (m.configuration.name() == name) return &m;
    return nullptr;
  }

  // Throughput as a multiple of brent_baseline's on the same family.
  double speedup(const Measurement& m) const {
    const Measurement* brent = brent_baseline(m.configuration.family);
    return brent ? m.pairs_per_second / brent->pairs_per_second : not_measured;
  }

  // "; noisy: cv N%" when a throughput behind a ratio varied a lot between repetitions.
  static std::string noise_note(std::initializer_list<const Measurement*> behind_ratio) {
    double worst = 0;
    for (const Measurement* m : behind_ratio)
      if (m && m->pairs_per_second_cv > worst) worst = m->pairs_per_second_cv;
    return worst > noisy_cv ? format("; noisy: cv up to %.0f%%, rerun", 100 * worst) : "";
  }

  const Measurement* brent_baseline(Family family) const {
    return find(Configuration{Path::brent_baseline, family});
  }

  // Throughput with `threads` threads over the same configuration with 1.
  // `rate` picks the median (default) or the best repetition.
  double thread_scaling(const Configuration& one_thread, int threads,
                        double Measurement::*rate = &Measurement::pairs_per_second) const {
    const Measurement* one = find(one_thread);
    const Measurement* more = find(one_thread.with_threads(threads));
    return one && more ? (*more).*rate / (*one).*rate : not_measured;
  }

  // "; best repetitions d.ef": the ratio of the fastest repetitions, which
  // tells foreign load on the machine apart from poor scaling.
  std::string best_scaling_note(const Configuration& one_thread, int threads) const {
    const double best = thread_scaling(one_thread, threads, &Measurement::best_pairs_per_second);
    return std::isnan(best) ? "" : format("; best repetitions %.2f", best);
  }

 private:
  const std::vector<Measurement>& rows_;
};

void print_table(std::ostream& out, const Table& table) {
  std::size_t width = 13;
  for (const Measurement& m : table.rows())
    width = std::max(width, m.configuration.name().size());
  const int w = int(width);
  constexpr const char* row = "%-*s %10s %6s %8s %10s %10s %10s %13s %10s %8s\n";
  out << format(row, w, "configuration", "pairs/s", "cv", "x brent", "max err", "p99.9 err",
                "median err", "max err (dbl)", "fallb/pair", "invalid");
  for (const Measurement& m : table.rows())
    out << format(row, w, m.configuration.name().c_str(), cell(m.pairs_per_second, "%.3g").c_str(),
                  cell(100 * m.pairs_per_second_cv, "%.0f%%").c_str(),
                  cell(table.speedup(m), "%.2f").c_str(),
                  cell(m.counter(counter::max_rel_err)).c_str(),
                  cell(m.counter(counter::p999_rel_err)).c_str(),
                  cell(m.counter(counter::median_rel_err)).c_str(),
                  cell(m.counter(counter::max_rel_err_double_input)).c_str(),
                  cell(m.counter(counter::fallbacks_per_pair), "%.3g").c_str(),
                  cell(m.counter(counter::invalid), "%.0f").c_str());
}

void print_thread_scaling(std::ostream& out, const Table& table) {
  int printed = 0;
  for (const Measurement& m : table.rows()) {
    if (!is_batch(m.configuration.path) || m.configuration.threads != 1) continue;
    for (const Measurement& other : table.rows()) {
      const int t = other.configuration.threads;
      if (t == 1 || other.configuration.name() != m.configuration.with_threads(t).name()) continue;
      out << format("  %-60s threads:%d / threads:1 = %.2f%s\n", m.configuration.name().c_str(),
                    t, table.thread_scaling(m.configuration, t),
                    table.best_scaling_note(m.configuration, t).c_str());
      ++printed;
    }
  }
  if (printed == 0) out << "  not measured\n";
}

void print_targets(std::ostream& out, const Table& table, Isa default_isa) {
  for (const Target& t : targets) {
    const Configuration c = default_settings(t.path, t.family, default_isa);
    const Measurement* m = table.find(c);
    if (!m) {
      out << format("  %-8s %s: not measured\n", "-", c.name().c_str());
      continue;
    }
    const double error = m->counter(counter::max_rel_err);
    const bool accurate = error <= t.max_rel_err;
    const double speedup = table.speedup(*m);
    const bool speed_target = t.min_speedup > 0;
    const bool met = accurate && (!speed_target || speedup >= t.min_speedup);
    const bool decided = !speed_target || !std::isnan(speedup);
    std::string line = format("  %-8s %s: ", decided ? verdict(met) : "-", c.name().c_str());
    if (speed_target)
      line += format("%s (target >= %gx), max rel err %.2e (target <= %g)",
                     speedup_text(speedup).c_str(), t.min_speedup, error, t.max_rel_err);
    else
      line += format("max rel err %.2e (target <= %g); %.3g pairs/s = %s, "
                     "%.0f fallbacks (%.3g per pair)",
                     error, t.max_rel_err, m->pairs_per_second, speedup_text(speedup).c_str(),
                     m->counter(counter::fallbacks), m->counter(counter::fallbacks_per_pair));
    const double error_double_input = m->counter(counter::max_rel_err_double_input);
    if (!std::isnan(error_double_input))
      line += format("; %.2e against the double inputs", error_double_input);
    out << line << Table::noise_note({m, table.brent_baseline(t.family)}) << '\n';
  }
  for (Path path : thread_scaling_paths) {
    const Configuration c = default_settings(path, thread_scaling_family, default_isa);
    const double scaling = table.thread_scaling(c, thread_scaling_threads);
    out << format("  %-8s %s: threads:%d / threads:1 = %s (target >= %g)",
                  std::isnan(scaling) ? "-" : verdict(scaling >= min_thread_scaling),
                  c.name().c_str(), thread_scaling_threads, cell(scaling, "%.2f").c_str(),
                  min_thread_scaling)
        << table.best_scaling_note(c, thread_scaling_threads)
        << Table::noise_note({table.find(c), table.find(c.with_threads(thread_scaling_threads))})
        << '\n';
  }
}

// Which fixed iteration count gives the most pairs per second while staying
// within each target's accuracy, on the default instruction set, 1 thread.
void print_iteration_choice(std::ostream& out, const Table& table, Isa default_isa) {
  for (const Target& t : targets) {
    const Configuration defaults = default_settings(t.path, t.family, default_isa);
    const Measurement* best = nullptr;
    int swept = 0;
    for (const Measurement& m : table.rows()) {
      const Configuration& c = m.configuration;
      if (c.path != t.path || c.family != t.family || c.isa != default_isa || c.threads != 1 ||
          c.iterations == 0)
        continue;
      ++swept;
      if (!(m.counter(counter::max_rel_err) <= t.max_rel_err)) continue;
      if (!best || m.pairs_per_second > best->pairs_per_second) best = &m;
    }
    std::string line = format("  %s/%s (max rel err <= %g): ", path_name(t.path),
                              family_name(t.family), t.max_rel_err);
    if (!best) {
      out << line << (swept ? "no swept iteration count is within the bound\n" : "not measured\n");
      continue;
    }
    line += format("fastest iterations:%d, %.3g pairs/s = %s, max rel err %.2e, "
                   "%.3g fallbacks per pair",
                   best->configuration.iterations, best->pairs_per_second,
                   speedup_text(table.speedup(*best)).c_str(), best->counter(counter::max_rel_err),
                   best->counter(counter::fallbacks_per_pair));
    if (const Measurement* d = table.find(defaults))
      line += format("; default (automatic) %.3g pairs/s, fastest / default = %.2f",
                     d->pairs_per_second, best->pairs_per_second / d->pairs_per_second);
    out << line << '\n';
  }
}

}  // namespace

double Measurement::counter(const char* name) const {
  const auto it = counters.find(name);
  return it == counters.end() ? not_measured : it->second;
}

SummaryReporter::SummaryReporter(benchmark::BenchmarkReporter* display,
                                 const std::vector<Configuration>& configurations,
                                 Isa default_isa)
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
  std::ostream& out = dynamic_cast<benchmark::ConsoleReporter*>(display_) ? GetOutputStream()
                                                                          : GetErrorStream();
  print_summary(out, measurements(), default_isa_, repetitions_);
}

void print_summary(std::ostream& out, const std::vector<Measurement>& measurements,
                   Isa default_isa, long repetitions) {
  const Table table(measurements);
  out << format("\nSummary (%s; real time; errors: relative error of mu^2 against the long double "
                "oracle on the inputs each path solved, \"dbl\" against the double inputs)\n",
                repetitions > 1 ? format("medians of %ld repetitions", repetitions).c_str()
                                : "single runs, no repetitions");
  out << "(Google Benchmark prints small counters with SI prefixes: m 1e-3, u 1e-6, n 1e-9, "
         "p 1e-12, f 1e-15, a 1e-18, z 1e-21.)\n\n";
  print_table(out, table);
  out << "\nThread scaling (same configuration, more threads / 1 thread)\n";
  print_thread_scaling(out, table);
  out << format("\nTargets (1 thread; default settings are isa:auto = isa:%s and iterations:0 = "
                "automatic)\n",
                isa_name(default_isa));
  print_targets(out, table, default_isa);
  out << format("\nFixed iteration counts swept on isa:%s, 1 thread\n", isa_name(default_isa));
  print_iteration_choice(out, table, default_isa);
  out.flush();
}

}  // namespace pwcontact::bench
