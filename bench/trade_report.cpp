#include "trade_report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <stdexcept>

#include "accuracy.hpp"
#include "targets.hpp"

namespace pwcontact::bench {
namespace {

constexpr double not_measured = std::numeric_limits<double>::quiet_NaN();

// best_in_group: settings whose max error is within this factor of the lowest
// a precision reached count as equally accurate (one decade: the same level
// on the plot, e.g. 3e-6 and 7e-7 in float, 1e-11 and 9e-12 on pw85 in double).
constexpr double best_accuracy_factor = 10;

std::ofstream open_output(const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  return out;
}

// The rows the outputs list: one per configuration, with 1 thread (the
// other thread counts are looked up beside them), in measurement order.
std::vector<const Measurement*> one_thread_rows(const Table& table) {
  std::vector<const Measurement*> rows;
  for (const Measurement& m : table.rows())
    if (m.configuration.threads == 1) rows.push_back(&m);
  return rows;
}

// Pairs per second with `threads` threads, NaN when not timed.
double rate_with(const Table& table, const Measurement& one_thread, int threads) {
  const Measurement* m = table.find(one_thread.configuration.with_threads(threads));
  return m ? m->pairs_per_second : not_measured;
}

double brent_rate(const Table& table, Family family) {
  const Measurement* brent = table.brent_baseline(family);
  return brent ? brent->pairs_per_second : not_measured;
}

const char* answer_name(Path path) {
  if (is_scalar(path)) return "scalar";
  return is_overlap(path) ? "overlap" : "full";
}

bool in_group(const Configuration& c, Family family, const PrecisionGroup& group) {
  return c.family == family && c.path == group.path && c.accuracy == group.accuracy &&
         c.threads == 1;
}

std::vector<const Measurement*> group_rows(const Table& table, Family family,
                                           const PrecisionGroup& group) {
  std::vector<const Measurement*> rows;
  for (const Measurement& m : table.rows())
    if (in_group(m.configuration, family, group) && !std::isnan(m.counter(counter::max_rel_err)))
      rows.push_back(&m);
  return rows;
}

// The CSV's and the Markdown's description of a family.
const char* family_description(Family family) {
  switch (family) {
    case Family::random: return "semi-axes uniform in [0.5, 2], centre distance uniform in [0, 6]";
    case Family::pw85: return "the peer library's 419,904 cases, aspect ratios up to 500";
    case Family::extreme:
      return "semi-axes log-uniform in [0.03, 30] (aspect and size ratios up to 1e3), centre "
             "distance uniform in [0, 60]";
    case Family::scene:
      return "random family's shapes, centre distance scaled so that mu is uniform in [0.5, 1.5]";
  }
  return "";
}

std::string run_description(const TradeRun& run) {
  std::string threads;
  for (int t : run.threads) threads += (threads.empty() ? "" : ", ") + std::to_string(t);
  return format(
      "isa %s; medians of %d repetitions of at least %.3g s of calls each, %s "
      "thread(s); %zu pairs per generated family, %zu per near-tangent set",
      isa_name(run.isa), run.repetitions, run.min_time, threads.c_str(), run.sizes.generated,
      run.sizes.near_tangent);
}

// ---------------------------------------------------------------------------
// CSV

// A CSV field: numbers as they are, NaN as an empty field.
std::string csv_number(double value, const char* fmt = "%.6g") {
  return std::isnan(value) ? std::string() : format(fmt, value);
}

// A CSV text field, quoted when it holds a comma or a quote (RFC 4180).
std::string csv_text(const std::string& text) {
  if (text.find_first_of(",\"") == std::string::npos) return text;
  std::string out = "\"";
  for (char ch : text) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

const char* const csv_counters[] = {
    counter::max_rel_err,
    counter::p999_rel_err,
    counter::median_rel_err,
    counter::max_rel_err_double_input,
    counter::fallbacks_per_pair,
    counter::mean_evaluations,
    counter::decided_early_per_pair,
    counter::overlapping_per_pair,
    counter::misclassified_beyond,
    counter::misclassified_within,
    counter::near_tangent_pairs,
    counter::near_tangent_misclassified_beyond,
    counter::near_tangent_misclassified_within,
    counter::invalid,
};

// ---------------------------------------------------------------------------
// Markdown

std::string md_rate(double rate) { return cell(rate, "%.3g"); }
std::string md_ratio(double ratio) { return cell(ratio, "%.1f"); }

void markdown_family_table(std::ostream& out, const Table& table, const TradeRun& run,
                           Family family) {
  out << "\n### " << family_name(family) << " family\n\n" << family_description(family) << ".\n\n";
  out << "| configuration |";
  for (int t : run.threads) out << " pairs/s, " << t << " thr | × brent |";
  out << " max err | p99.9 err | median err | max err, dbl inputs | fallbacks/pair | evals/pair "
         "| decided early | misclassified >1e-9/≤1e-9 | near-tangent >1e-9/≤1e-9 |\n|---|";
  for (std::size_t k = 0; k < run.threads.size(); ++k) out << "---:|---:|";
  out << "---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  const double brent = brent_rate(table, family);
  for (const Measurement* m : one_thread_rows(table)) {
    if (m->configuration.family != family) continue;
    out << "| `" << m->configuration.settings_name() << "` |";
    for (int t : run.threads) {
      const double rate = rate_with(table, *m, t);
      out << ' ' << md_rate(rate) << " | " << md_ratio(rate / brent) << " |";
    }
    out << ' ' << cell(m->counter(counter::max_rel_err)) << " | "
        << cell(m->counter(counter::p999_rel_err)) << " | "
        << cell(m->counter(counter::median_rel_err)) << " | "
        << cell(m->counter(counter::max_rel_err_double_input)) << " | "
        << cell(m->counter(counter::fallbacks_per_pair), "%.3g") << " | "
        << cell(m->counter(counter::mean_evaluations), "%.2f") << " | "
        << cell(m->counter(counter::decided_early_per_pair), "%.3f") << " | "
        << misclassification_cell(*m, false) << " | " << misclassification_cell(*m, true) << " |\n";
  }
}

// "pairs/s | × brent" cells of a measurement; dashes without one.
std::string speed_cells(const Measurement* m, double brent) {
  if (!m) return "- | -";
  return md_rate(m->pairs_per_second) + " | " + md_ratio(m->pairs_per_second / brent);
}

// A counter's cell; a dash without a measurement.
std::string counter_cell(const Measurement* m, const char* name, const char* fmt = "%.2e") {
  return cell(m ? m->counter(name) : not_measured, fmt);
}

void markdown_best_settings(std::ostream& out, const Table& table, const TradeRun& run) {
  out << "| family | precision | best setting | pairs/s | × brent | max err | p99.9 err | "
         "near-tangent >1e-9/≤1e-9 | defaults: pairs/s | × brent | max err |\n"
         "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
  for (Family family : run.families)
    for (const PrecisionGroup& group : precision_groups()) {
      const Measurement* best = best_in_group(table, family, group);
      if (!best) continue;
      const Measurement* defaults = automatic_in_group(table, family, group);
      const double brent = brent_rate(table, family);
      out << format(
          "| %s | %s | `%s` | %s | %s | %s | %s | %s | %s |\n", family_name(family),
          group.label().c_str(), best->configuration.settings_name().c_str(),
          speed_cells(best, brent).c_str(), counter_cell(best, counter::max_rel_err).c_str(),
          counter_cell(best, counter::p999_rel_err).c_str(),
          misclassification_cell(*best, true).c_str(), speed_cells(defaults, brent).c_str(),
          counter_cell(defaults, counter::max_rel_err).c_str());
    }
}

// The fastest overlap configuration per family and precision that makes no
// misclassification beyond tangency_tolerance, on the family nor on its
// near-tangent set.
void markdown_overlap_screening(std::ostream& out, const Table& table, const TradeRun& run) {
  out << "| family | path | fastest without misclassification beyond 1e-9 | pairs/s | × brent | "
         "decided early | evals/pair | near-tangent >1e-9/≤1e-9 | defaults: pairs/s | × brent |\n"
         "|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n";
  for (Family family : run.families)
    for (Path path :
         {Path::overlap_double, Path::overlap_mixed, Path::overlap_single, Path::overlap_float}) {
      const Target screening{Configuration{path, family, run.isa}, 0, 0};
      const Measurement* best = fastest_within(table, screening, run.isa, false);
      const Measurement* defaults = table.find(screening.configuration);
      if (!best && !defaults) continue;
      const double brent = brent_rate(table, family);
      out << format("| %s | %s | %s | %s | %s | %s | %s | %s |\n", family_name(family),
                    path_name(path),
                    best ? ("`" + best->configuration.settings_name() + "`").c_str() : "none",
                    speed_cells(best, brent).c_str(),
                    counter_cell(best, counter::decided_early_per_pair, "%.3f").c_str(),
                    counter_cell(best, counter::mean_evaluations, "%.2f").c_str(),
                    best ? misclassification_cell(*best, true).c_str() : "-",
                    speed_cells(defaults, brent).c_str());
    }
}

// ---------------------------------------------------------------------------
// Plot

// Errors are plotted on a log scale: exact answers (0) are drawn at this
// floor and answers without a value (infinite error) at the top.
constexpr double plot_error_floor = 1e-17;
constexpr double plot_error_ceiling = 1e-2;

double plotted_error(double error) {
  return std::clamp(error, plot_error_floor, plot_error_ceiling);
}

const char* const group_colours[] = {"#1f77b4", "#6baed6", "#2ca02c",
                                     "#98df8a", "#ff7f0e", "#d62728"};

// Point types: filled for automatic iterations, open for fixed; circles for
// Newton (and the automatic formulation), triangles for log_odds.
int point_type(const Configuration& c) {
  const bool automatic = c.iterations == 0;
  if (c.formulation == Formulation::log_odds) return automatic ? 9 : 8;
  return automatic ? 7 : 6;
}

// The group's points that no other point beats in both speed and error, by
// increasing throughput: the curve through the trade.
std::vector<const Measurement*> pareto_front(std::vector<const Measurement*> rows) {
  std::sort(rows.begin(), rows.end(), [](const Measurement* a, const Measurement* b) {
    return a->pairs_per_second > b->pairs_per_second;
  });
  std::vector<const Measurement*> front;
  double lowest = std::numeric_limits<double>::infinity();
  for (const Measurement* m : rows) {
    const double error = plotted_error(m->counter(counter::max_rel_err));
    if (error < lowest) {
      front.push_back(m);
      lowest = error;
    }
  }
  std::reverse(front.begin(), front.end());
  return front;
}

// One "x y" (and point type) line per measurement, as a gnuplot data block.
void write_block(std::ostream& out, const std::vector<const Measurement*>& rows) {
  for (const Measurement* m : rows)
    out << format("%.6g %.6g %d  # %s\n", m->pairs_per_second,
                  plotted_error(m->counter(counter::max_rel_err)), point_type(m->configuration),
                  m->configuration.settings_name().c_str());
  out << "\n\n";  // gnuplot: the next index
}

std::string panel_title(Family family) {
  switch (family) {
    case Family::random: return "random family: semi-axes in [0.5, 2]";
    case Family::pw85: return "pw85 family: 419,904 cases, aspect ratios up to 500";
    case Family::extreme: return "extreme family: semi-axes log-uniform in [0.03, 30]";
    case Family::scene: return "scene-like mix: mu uniform in [0.5, 1.5]";
  }
  return "";
}

// The targets on `family` drawn as corners: a configuration meets a target
// when its point lies below and right of the corner. Their labels sit at the
// right end of the horizontal lines, stacked where error bounds coincide.
void write_target_corners(std::ostream& gp, const Table& table, Family family) {
  const double brent = brent_rate(table, family);
  std::map<double, int> labels_at;  // labels already placed at each error bound
  for (const Target& t : targets()) {
    const Configuration& c = t.configuration;
    if (c.family != family || is_overlap(c.path)) continue;
    const PrecisionGroup group{c.path, c.accuracy};
    const double y = t.max_rel_err;
    const bool speed = t.min_speedup > 0 && !std::isnan(brent);
    const double x = speed ? t.min_speedup * brent : 0;
    const std::string style = format("nohead dt %d lw 1.5 lc rgb '#555555'", speed ? 2 : 3);
    const std::string start =
        speed ? format("first %g, first %g", x, y) : format("graph 0, first %g", y);
    gp << "set arrow from " << start << format(" to graph 1, first %g ", y) << style << '\n';
    if (speed)
      gp << format("set arrow from first %g, graph 0 to first %g, first %g ", x, x, y) << style
         << '\n'
         << format(
                "set label '%gx' at first %g, graph 0.02 rotate by 90 offset -0.3,0 "
                "font ',8'\n",
                t.min_speedup, x);
    const std::string text =
        speed ? format("target: %s >= %gx brent, <= %g", group.label().c_str(), t.min_speedup, y)
              : format("target: %s <= %g (speed reported)", group.label().c_str(), y);
    gp << format(
        "set label \"%s\" at graph 0.99, first %g right offset 0,%.1f font ',8' "
        "noenhanced\n",
        text.c_str(), y, 0.6 + 1.1 * labels_at[y]++);
  }
}

// gnuplot strings are single-quoted here: a quote inside is doubled.
std::string gp_quoted(const std::string& text) {
  std::string out = "'";
  for (char ch : text) out += ch == '\'' ? std::string("''") : std::string(1, ch);
  return out + "'";
}

// A double-quoted gnuplot string, where "\n" starts a new line.
std::string gp_text(const std::string& text) {
  std::string out = "\"";
  for (char ch : text) {
    if (ch == '\n')
      out += "\\n";
    else if (ch == '"' || ch == '\\')
      out += std::string("\\") + ch;
    else
      out += ch;
  }
  return out + "\"";
}

// The same for the shell.
std::string shell_quoted(const std::string& text) {
  std::string out = "'";
  for (char ch : text) out += ch == '\'' ? std::string("'\\''") : std::string(1, ch);
  return out + "'";
}

}  // namespace

std::string without_extension(const std::string& path, const std::string& extension) {
  if (path.size() > extension.size() &&
      path.compare(path.size() - extension.size(), extension.size(), extension) == 0)
    return path.substr(0, path.size() - extension.size());
  return path;
}

std::string PrecisionGroup::label() const {
  std::string label = precision_label(path);
  if (accuracy == Accuracy::high) label += ", accuracy high";
  return label;
}

const std::vector<PrecisionGroup>& precision_groups() {
  static const std::vector<PrecisionGroup> groups = {
      {Path::batch_double, Accuracy::standard}, {Path::batch_double, Accuracy::high},
      {Path::batch_mixed, Accuracy::standard},  {Path::batch_mixed, Accuracy::high},
      {Path::batch_single, Accuracy::standard}, {Path::batch_float, Accuracy::standard},
  };
  return groups;
}

const Measurement* best_in_group(const Table& table, Family family, const PrecisionGroup& group) {
  const std::vector<const Measurement*> rows = group_rows(table, family, group);
  double lowest = std::numeric_limits<double>::infinity();
  for (const Measurement* m : rows) lowest = std::min(lowest, m->counter(counter::max_rel_err));
  const Measurement* best = nullptr;
  for (const Measurement* m : rows)
    if (m->counter(counter::max_rel_err) <= best_accuracy_factor * lowest &&
        (!best || m->pairs_per_second > best->pairs_per_second))
      best = m;
  return best;
}

const Measurement* automatic_in_group(const Table& table, Family family,
                                      const PrecisionGroup& group) {
  for (const Measurement* m : group_rows(table, family, group))
    if (m->configuration.iterations == 0 && m->configuration.formulation == Formulation::automatic)
      return m;
  return nullptr;
}

void print_best_settings(std::ostream& out, const Table& table, const TradeRun& run) {
  for (Family family : run.families)
    for (const PrecisionGroup& group : precision_groups()) {
      const Measurement* best = best_in_group(table, family, group);
      if (!best) continue;
      out << format("  %-8s %-26s %-72s %9.3g pairs/s %6.1fx brent  max err %.2e\n",
                    family_name(family), group.label().c_str(),
                    best->configuration.settings_name().c_str(), best->pairs_per_second,
                    table.speedup(*best), best->counter(counter::max_rel_err));
    }
}

void write_csv(const std::string& path, const Table& table, const TradeRun& run) {
  std::ofstream out = open_output(path);
  out << "configuration,path,family,answer,precision,formulation,accuracy,iterations";
  for (int t : run.threads)
    out << ",pairs_per_second_" << t << "_threads,cv_" << t << "_threads,x_brent_" << t
        << "_threads";
  for (const char* name : csv_counters) out << ',' << name;
  out << '\n';
  for (const Measurement* m : one_thread_rows(table)) {
    const Configuration& c = m->configuration;
    const bool batch = is_batch(c.path);
    out << c.settings_name() << ',' << path_name(c.path) << ',' << family_name(c.family) << ','
        << answer_name(c.path) << ',' << csv_text(batch ? precision_label(c.path) : "double") << ','
        << (batch ? formulation_name(c.formulation) : "") << ','
        << (batch ? accuracy_name(c.accuracy) : "") << ','
        << (batch ? std::to_string(c.iterations) : "");
    const double brent = brent_rate(table, c.family);
    for (int t : run.threads) {
      const Measurement* timed = table.find(c.with_threads(t));
      const double rate = timed ? timed->pairs_per_second : not_measured;
      out << ',' << csv_number(rate) << ','
          << csv_number(timed ? timed->pairs_per_second_cv : not_measured, "%.3f") << ','
          << csv_number(rate / brent, "%.3f");
    }
    for (const char* name : csv_counters) out << ',' << csv_number(m->counter(name));
    out << '\n';
  }
}

void write_markdown(const std::string& path, const Table& table, const TradeRun& run) {
  std::ofstream out = open_output(path);
  out << "# pwcontact: the speed/accuracy trade\n\n";
  if (!run.label.empty()) out << "Measured: " << run.label << ".\n\n";
  out << run_description(run) << ".\n\n"
      << "Throughput in pairs per second (real time); × brent: over brent_baseline's on the same "
         "family with 1 thread, measured in the same run. Errors: relative error of μ² against "
         "the long double oracle on the inputs each path solved (float pairs: the float-rounded "
         "ones; \"dbl inputs\": against the double pairs). Misclassified: answers to \"μ < 1?\" "
         "(overlap answers, or μ² < 1 of full answers) that disagree with the oracle, farther "
         "from tangency than |μ² − 1| = 1e-9 (errors) / closer (tolerated), on the family "
         "(overlap answers) and on the family's near-tangent set (μ² = 1 ± ε, ε log-uniform in "
         "[1e-12, 1e-2]). Full answers ask for μ², λ and the status; overlap answers for the "
         "answer and the status.\n";
  out << "\n## Targets: the fastest measured setting within each target's accuracy\n\n```text\n";
  print_targets_best_in_sweep(out, table, run.isa);
  out << "```\n\n## Targets: the library's default settings\n\n```text\n";
  print_targets(out, table, run.isa);
  out << "```\n\n## Best setting per family and precision (full answer, 1 thread)\n\n"
      << format(
             "The fastest setting whose max error is within a factor %g of the lowest that "
             "precision reached on the family; defaults: automatic iterations and "
             "formulation.\n\n",
             best_accuracy_factor);
  markdown_best_settings(out, table, run);
  out << "\n## Overlap screening (1 thread)\n\n";
  markdown_overlap_screening(out, table, run);
  out << "\n## Every configuration\n";
  for (Family family : run.families) markdown_family_table(out, table, run, family);
}

bool gnuplot_available() { return std::system("command -v gnuplot > /dev/null 2>&1") == 0; }

void draw_plot(const std::string& png, const std::string& work_files, const Table& table,
               const TradeRun& run) {
  const std::string& base = work_files;
  const std::string points_path = base + "_points.dat", fronts_path = base + "_fronts.dat",
                    brent_path = base + "_brent.dat", script_path = base + ".gp";
  std::ofstream points = open_output(points_path), fronts = open_output(fronts_path),
                brent = open_output(brent_path), gp = open_output(script_path);

  std::vector<Family> panels;
  for (Family f : run.families)
    if (f != Family::scene) panels.push_back(f);  // the scene is for overlap answers
  if (panels.empty()) throw std::runtime_error("no family to plot (the scene has no full sweep)");

  gp << "# Drawn by pwcontact_trade: max relative error of mu^2 against throughput.\n"
     << format("set terminal pngcairo size %d,780 font 'sans,10'\n", 660 * int(panels.size()))
     << "set output " << gp_quoted(png) << '\n'
     << format("set multiplot layout 1,%d title %s noenhanced\n", int(panels.size()),
               gp_text("pwcontact: max relative error of mu^2 against throughput (1 thread, "
                       "full answer)" +
                       (run.label.empty() ? "" : " - " + run.label) +
                       "\npoints: every configuration; lines: the fastest at each accuracy")
                   .c_str())
     << "set logscale xy\nset format x '10^{%L}'\nset format y '10^{%L}'\n"
     << format("set yrange [%g:%g]\n", plot_error_floor, plot_error_ceiling)
     << "set xlabel 'pairs per second, 1 thread'\nset ylabel 'max relative error of mu^2'\n"
     << "set grid\nset key below maxrows 5 font ',9' noenhanced\n"
     // Room on both sides: brent_baseline and the fastest points are at the ends.
     << "set offsets graph 0.05, graph 0.05, 0, 0\n";

  int block = 0, brent_block = 0;
  for (Family family : panels) {
    gp << "unset arrow\nunset label\n"
       << "set title " << gp_quoted(panel_title(family)) << " noenhanced font ',9'\n";
    write_target_corners(gp, table, family);
    std::string plot;
    const auto add = [&](const std::string& clause) {
      plot += (plot.empty() ? "plot " : ", \\\n     ") + clause;
    };
    for (std::size_t g = 0; g < precision_groups().size(); ++g) {
      const PrecisionGroup& group = precision_groups()[g];
      const std::vector<const Measurement*> rows = group_rows(table, family, group);
      if (rows.empty()) continue;
      write_block(points, rows);
      write_block(fronts, pareto_front(rows));
      const char* colour = group_colours[g];
      add(format("%s index %d using 1:2 with lines lw 2 lc rgb '%s' title %s",
                 gp_quoted(fronts_path).c_str(), block, colour, gp_quoted(group.label()).c_str()));
      add(format("%s index %d using 1:2:3 with points pt variable ps 1.1 lc rgb '%s' notitle",
                 gp_quoted(points_path).c_str(), block, colour));
      ++block;
    }
    if (const Measurement* b = table.brent_baseline(family)) {
      brent << format("%.6g %.6g\n\n\n", b->pairs_per_second,
                      plotted_error(b->counter(counter::max_rel_err)));
      add(
          format("%s index %d using 1:2 with points pt 3 ps 2.2 lw 2 lc rgb 'black' "
                 "title 'brent_baseline'",
                 gp_quoted(brent_path).c_str(), brent_block++));
    }
    add("keyentry with points pt 7 lc rgb 'gray40' title 'newton, automatic iterations'");
    add("keyentry with points pt 6 lc rgb 'gray40' title 'newton, fixed iterations'");
    add("keyentry with points pt 9 lc rgb 'gray40' title 'log_odds, automatic iterations'");
    add("keyentry with points pt 8 lc rgb 'gray40' title 'log_odds, fixed iterations'");
    gp << plot << '\n';
  }
  gp << "unset multiplot\n";
  for (std::ofstream* f : {&points, &fronts, &brent, &gp}) f->close();

  const std::string command = "gnuplot " + shell_quoted(script_path);
  if (std::system(command.c_str()) != 0)
    throw std::runtime_error("gnuplot failed on " + script_path);
}

}  // namespace pwcontact::bench
