#include "measurement.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace pwcontact::bench {
namespace {

constexpr double not_measured = std::numeric_limits<double>::quiet_NaN();

// Above this coefficient of variation over repetitions a ratio is flagged:
// on a shared machine a foreign process can take a core for whole seconds.
constexpr double noisy_cv = 0.10;

}  // namespace

double Measurement::counter(const char* name) const {
  const auto it = counters.find(name);
  return it == counters.end() ? not_measured : it->second;
}

double median(std::vector<double> values) {
  if (values.empty()) return not_measured;
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  if (values.size() % 2 == 1) return values[mid];
  const double upper = values[mid];
  return (*std::max_element(values.begin(), values.begin() + mid) + upper) / 2;
}

double coefficient_of_variation(const std::vector<double>& values) {
  if (values.size() < 2) return not_measured;
  const double n = double(values.size());
  const double mean = std::accumulate(values.begin(), values.end(), 0.0) / n;
  double squares = 0;
  for (double v : values) squares += (v - mean) * (v - mean);
  return std::sqrt(squares / (n - 1)) / mean;  // sample deviation, as Google Benchmark's "_cv"
}

std::string format(const char* fmt, ...) {
  char buffer[1024];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buffer, sizeof buffer, fmt, args);
  va_end(args);
  return buffer;
}

std::string cell(double value, const char* fmt) {
  return std::isnan(value) ? std::string("-") : format(fmt, value);
}

std::string misclassification_cell(const Measurement& m, bool near_tangent) {
  const double beyond = m.counter(near_tangent ? counter::near_tangent_misclassified_beyond
                                               : counter::misclassified_beyond);
  const double within = m.counter(near_tangent ? counter::near_tangent_misclassified_within
                                               : counter::misclassified_within);
  return std::isnan(beyond) ? std::string("-") : format("%.0f/%.0f", beyond, within);
}

Table::Table(const std::vector<Measurement>& rows) : rows_(rows) {
  for (const Measurement& m : rows_) by_name_.emplace(m.configuration.name(), &m);
}

const Measurement* Table::find(const Configuration& c) const {
  const auto found = by_name_.find(c.name());
  return found == by_name_.end() ? nullptr : found->second;
}

const Measurement* Table::brent_baseline(Family family) const {
  return find(Configuration{Path::brent_baseline, family});
}

double Table::speedup(const Measurement& m) const {
  const Measurement* brent = brent_baseline(m.configuration.family);
  return brent ? m.pairs_per_second / brent->pairs_per_second : not_measured;
}

double Table::thread_scaling(const Configuration& one_thread, int threads,
                             double Measurement::*rate) const {
  const Measurement* one = find(one_thread);
  const Measurement* more = find(one_thread.with_threads(threads));
  return one && more ? (*more).*rate / (*one).*rate : not_measured;
}

std::string Table::best_scaling_note(const Configuration& one_thread, int threads) const {
  const double best = thread_scaling(one_thread, threads, &Measurement::best_pairs_per_second);
  return std::isnan(best) ? "" : format("; best repetitions %.2f", best);
}

std::string Table::noise_note(std::initializer_list<const Measurement*> behind_ratio) {
  double worst = 0;
  for (const Measurement* m : behind_ratio)
    if (m && m->pairs_per_second_cv > worst) worst = m->pairs_per_second_cv;
  return worst > noisy_cv ? format("; noisy: cv up to %.0f%%, rerun", 100 * worst) : "";
}

}  // namespace pwcontact::bench
