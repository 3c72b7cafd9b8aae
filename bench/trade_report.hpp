// The trade table's outputs: CSV and Markdown (one row per configuration,
// every thread count in its columns), the best setting per family and
// precision, and a plot of max relative error against throughput drawn by
// gnuplot.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "families.hpp"
#include "measurement.hpp"

namespace pwcontact::bench {

// How the measurements were taken, for the headers of the outputs.
struct TradeRun {
  std::string label;  // e.g. the commit measured; may be empty
  Isa isa = Isa::automatic;
  int repetitions = 0;
  double min_time = 0;       // seconds of calls per timing
  std::vector<int> threads;  // the thread counts timed
  FamilySizes sizes;
  std::vector<Family> families;
};

// One precision of the full answer, as the plot and the best-setting table
// group configurations: a full batch path with an accuracy.
struct PrecisionGroup {
  Path path;
  Accuracy accuracy;
  std::string label() const;  // "double", "double, accuracy high", ...
};

// The full-answer groups in a fixed order (the plot's colours follow it).
const std::vector<PrecisionGroup>& precision_groups();

// The fastest 1-thread configuration of `group` on `family` whose max relative
// error is within a factor 10 of the lowest the group reached there: the
// setting to choose for that precision. Null when none was measured.
const Measurement* best_in_group(const Table& table, Family family, const PrecisionGroup& group);
// The group's configuration with automatic iterations and formulation: the
// library's defaults. Null when not measured.
const Measurement* automatic_in_group(const Table& table, Family family,
                                      const PrecisionGroup& group);

// A plain-text table of best_in_group for every family and group.
void print_best_settings(std::ostream& out, const Table& table, const TradeRun& run);

void write_csv(const std::string& path, const Table& table, const TradeRun& run);
void write_markdown(const std::string& path, const Table& table, const TradeRun& run);

// Whether `gnuplot` can be run (it is looked up on PATH).
bool gnuplot_available();

// Writes the gnuplot script and its data as <work_files>.gp and
// <work_files>_*.dat, then runs gnuplot on them to draw `png`. Throws
// std::runtime_error when gnuplot fails.
void draw_plot(const std::string& png, const std::string& work_files, const Table& table,
               const TradeRun& run);

// `path` without `extension` at its end, if it ends so.
std::string without_extension(const std::string& path, const std::string& extension);

}  // namespace pwcontact::bench
