// `pwcontact contact`: mu^2 and what goes with it, or the overlap answer, for
// every pair of a text file.
#include <algorithm>
#include <charconv>
#include <cstdio>
#include <initializer_list>

#include "cli/number_table.hpp"
#include "cli/solve.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"

namespace pwcontact::cli {
namespace {

// One pair per line: r12 (3 numbers), then Q1 and Q2 (6 numbers each).
constexpr std::size_t numbers_per_pair = 15;

// The columns of an output line. contact_point, normal and gradient are
// three numbers each (x y z).
enum class Column { mu2, lambda, status, contact_point, normal, gradient, overlap };

const char* column_name(Column column) noexcept {
  constexpr const char* names[] = {"mu2",    "lambda",   "status", "contact_point",
                                   "normal", "gradient", "overlap"};
  return names[int(column)];
}

// What --outputs may list (overlap mode has its own fixed columns).
const Choices<Column> full_columns{{Column::mu2, Column::lambda, Column::status,
                                    Column::contact_point, Column::normal, Column::gradient},
                                   column_name};
const std::vector<Column> default_columns{Column::mu2, Column::lambda, Column::status};
const std::vector<Column> overlap_columns{Column::overlap, Column::status};

std::vector<Column> parse_columns(std::string_view list) {
  std::vector<Column> columns;
  for (std::size_t start = 0; start <= list.size();) {
    const std::size_t comma = std::min(list.find(',', start), list.size());
    const Column column = full_columns.parse(list.substr(start, comma - start));
    if (std::find(columns.begin(), columns.end(), column) != columns.end())
      throw std::invalid_argument(std::string(column_name(column)) + " is listed twice");
    columns.push_back(column);
    start = comma + 1;
  }
  return columns;
}

std::string column_list(const std::vector<Column>& columns) {
  std::string text;
  for (Column column : columns)
    text += (text.empty() ? "" : ",") + std::string(column_name(column));
  return text;
}

struct ContactOptions {
  SolverOptions solver;
  Mode mode = Mode::full;
  double cutoff = 1;
  std::vector<Column> columns = default_columns;
  bool scalar = false;
  std::string input = "-";
  std::string output = "-";
};

OptionParser contact_parser(ContactOptions& options) {
  OptionParser parser(
      "contact",
      "Computes the contact function mu^2 of every pair of ellipsoids in FILE "
      "(standard input if FILE is absent or -): they overlap if mu^2 < 1, touch if "
      "mu^2 = 1, and are apart if mu^2 > 1.\n\n"
      "Input: one pair per line, 15 numbers separated by blanks: r12 x y z "
      "(centre 2 minus centre 1), q1[0..5], q2[0..5] (Q = sum a_i^2 v_i v_i^T as its upper "
      "triangle, row-major: Q00 Q01 Q02 Q11 Q12 Q22). Blank lines and lines starting "
      "with '#' are skipped. nan and inf are numbers, answered with a status; any "
      "other line that does not hold exactly 15 numbers stops the run (exit status 2; "
      "with -o nothing is written, while on standard output the lines before it "
      "have already been).\n\n"
      "Output, --mode full: one line per pair, in input order, with the columns "
      "listed by --outputs, separated by a space: mu2 (the contact function mu^2), "
      "lambda (its maximiser in [0, 1]), status (a code below), contact_point (x0 - c1: "
      "where the two ellipsoids, both scaled by mu about their centres, touch), normal "
      "(the unit normal there, outward of ellipsoid 1; 0 0 0 for coincident centres) "
      "and gradient (d mu^2 / d r12); the last three are x y z, three columns each. "
      "Numbers have 17 significant digits, nan when the status is invalid; with "
      "--precision float only the first ~7 are meaningful.\n\n"
      "Output, --mode overlap: one line per pair, in input order: overlap status, "
      "overlap being 1 when mu < cutoff (mu^2 < cutoff^2) and 0 otherwise (also 0 "
      "for an invalid pair, whose status says why). Pairs are decided by cheap bounds "
      "and certificates, most after few or no Newton evaluations, the rest by the "
      "reference path (status 1); in double and mixed precision the answer agrees "
      "with mu^2 < cutoff^2 whenever |mu^2 - cutoff^2| > 1e-9 cutoff^2 (for Q "
      "conditioned up to ~1e8).\n\n"
      "A summary goes to standard error: the mode and the settings as resolved, time "
      "and rate, mean Newton evaluations per pair, fallbacks, statuses and, in "
      "overlap mode, the overlapping pairs and how they were decided. An option that "
      "does not apply to the chosen mode or path is a usage error, whatever its value.",
      "[FILE]", 1, [&options](std::string_view file) { options.input = file; });
  add_choice(parser, "--mode", Choices<Mode>{{Mode::full, Mode::overlap}, mode_name}, options.mode,
             "full: mu^2 and the columns of --outputs; overlap: whether each pair overlaps "
             "(see Output)");
  parser.add_value({"--cutoff"}, "MU", "1",
                   "--mode overlap only: a pair overlaps when mu < MU; positive and finite",
                   [&options](std::string_view value) { options.cutoff = parse_cutoff(value); });
  parser.add_value({"--outputs"}, "LIST", column_list(default_columns),
                   "--mode full only: the columns of each line, comma-separated, each at most "
                   "once, in the order given: " +
                       full_columns.names(", ", " and ") +
                       " (see Output). Only what is listed is computed; mu2 alone is the "
                       "fastest (it converges to a looser tolerance than with lambda or "
                       "geometry, and may differ in the last digits)",
                   [&options](std::string_view value) { options.columns = parse_columns(value); });
  add_solver_options(parser, options.solver);
  parser.add_flag({"--scalar"},
                  "solve every pair with the scalar reference path, contact_function<double> "
                  "(<float> with --precision float, on the numbers rounded to float: beyond "
                  "float range +-inf, status non_finite_input) and contact_geometry for the "
                  "geometric columns, in parallel, instead of the batch path; same columns. "
                  "--iterations, --accuracy, --formulation, --isa and --precision mixed "
                  "apply to the batch path only",
                  [&options] { options.scalar = true; });
  add_output_option(parser, options.output, "the results");
  return parser;
}

std::string contact_options_help() {
  ContactOptions options;
  return contact_parser(options).help();
}

// A block's parsed columns as a batch: swapped in, without a copy (and
// swapped back by give_back, so that the reader reuses their storage).
void take_pairs(NumberColumns& block, PairBatch<double>& pairs) {
  std::vector<NumberColumns::Column>& columns = block.columns;
  for (int k = 0; k < 3; ++k) pairs.r12(k).swap(columns[std::size_t(k)]);
  for (int k = 0; k < 6; ++k) {
    pairs.q1(k).swap(columns[std::size_t(3 + k)]);
    pairs.q2(k).swap(columns[std::size_t(9 + k)]);
  }
}

template <class T>
char* write_triple(char* out, const std::vector<T> (&column)[3], std::size_t i) {
  for (int k = 0; k < 3; ++k) {
    if (k != 0) *out++ = ' ';
    out = write_number(out, column[k][i]);
  }
  return out;
}

template <class T>
char* write_column(char* out, Column column, const Solution<T>& solution, std::size_t i) {
  switch (column) {
    case Column::mu2: return write_number(out, solution.mu2[i]);
    case Column::lambda: return write_number(out, solution.lambda[i]);
    case Column::status: return std::to_chars(out, out + 3, int(solution.status[i])).ptr;
    case Column::contact_point: return write_triple(out, solution.contact_point, i);
    case Column::normal: return write_triple(out, solution.normal, i);
    case Column::gradient: return write_triple(out, solution.gradient, i);
    case Column::overlap: *out = solution.overlap[i] ? '1' : '0'; return out + 1;
  }
  return out;
}

// Room for a line with every column of full mode: 12 numbers, each followed
// by a separator or the line end.
constexpr std::size_t max_line_chars = 12 * (max_number_chars + 1);

template <class T>
void append_result_line(std::string& text, const std::vector<Column>& columns,
                        const Solution<T>& solution, std::size_t i) {
  char line[max_line_chars];
  char* end = line;
  for (Column column : columns) {
    end = write_column(end, column, solution, i);
    *end++ = ' ';
  }
  end[-1] = '\n';  // in place of the last separator
  text.append(line, end);
}

// Full mode computes what the columns need, overlap mode its own two.
Request request_for(const ContactOptions& options) {
  Request request;
  request.mode = options.mode;
  request.cutoff = options.cutoff;
  auto listed = [&options](Column column) {
    return std::find(options.columns.begin(), options.columns.end(), column) !=
           options.columns.end();
  };
  request.lambda = listed(Column::lambda);
  request.status = listed(Column::status);
  request.contact_point = listed(Column::contact_point);
  request.normal = listed(Column::normal);
  request.gradient = listed(Column::gradient);
  return request;
}

template <class T>
void write_solution(const Solution<T>& solution, const ContactOptions& options,
                    OutputFile& output) {
  const std::vector<Column>& columns =
      options.mode == Mode::overlap ? overlap_columns : options.columns;
  write_lines_in_order(
      output, solution.report.pairs, resolve_thread_count(options.solver.threads),
      [&](std::string& text, std::size_t i) { append_result_line(text, columns, solution, i); });
}

// One block of pairs, solved as asked and written.
template <class T>
Solution<T> solve(const PairBatch<T>& pairs, const ContactOptions& options, const Request& request,
                  int threads) {
  return options.scalar ? solve_reference(pairs, request, threads)
                        : solve_batch(pairs, request, options.solver);
}

// Options that do not apply to the chosen mode or path are refused rather
// than ignored, so that nobody believes they had an effect.
void reject_given(const OptionParser& parser, std::initializer_list<const char*> names,
                  const std::string& reason) {
  for (const char* name : names)
    if (parser.given(name)) parser.fail(std::string(name) + " " + reason);
}

void check_contact_options(const OptionParser& parser, const ContactOptions& options) {
  check_solver_options(parser, options.solver);
  if (options.mode == Mode::overlap) {
    reject_given(parser, {"--outputs"},
                 "applies to --mode full; --mode overlap writes the columns overlap status");
    reject_given(parser, {"--accuracy"}, "applies to mu^2 (--mode full), not to overlap answers");
  } else {
    reject_given(parser, {"--cutoff"},
                 "applies to --mode overlap (in full mode, compare mu2 with the cutoff squared)");
  }
  if (options.scalar) {
    reject_given(parser, {"--iterations", "--accuracy", "--formulation", "--isa"},
                 "applies to the batch path, not to --scalar (the reference path iterates "
                 "to convergence, in scalar code)");
    if (options.solver.precision == Precision::mixed)
      parser.fail("--precision mixed applies to the batch path; --scalar runs in double or float");
  }
}

// The arguments into `options`, checked; false when help was asked for.
bool parse_contact(const Arguments& arguments, ContactOptions& options) {
  OptionParser parser = contact_parser(options);
  if (!parser.parse(arguments)) return false;
  check_contact_options(parser, options);
  return true;
}

bool parse_contact_only(const Arguments& arguments) {
  ContactOptions options;
  return parse_contact(arguments, options);
}

ExitStatus run_contact(const Arguments& arguments) {
  ContactOptions options;
  if (!parse_contact(arguments, options)) {
    std::fputs(full_help(contact_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  // Settle everything that can fail before reading a possibly large input.
  if (!options.scalar) options.solver.isa = resolve_instruction_set(options.solver.isa);
  const int threads = resolve_thread_count(options.solver.threads);
  const Request request = request_for(options);
  OutputFile output(options.output);
  TextInput input(options.input);

  // The input is read, solved and written a block at a time (the pairs of
  // at most TextInput::block_bytes of text), in order: memory stays that of
  // a block, whatever the size of the input. A malformed line stops the run
  // with its number; with -o nothing is written then (the output appears
  // only on success), on standard output the lines of the blocks before it
  // have been written.
  const bool single_scalar =
      options.scalar && options.solver.precision == Precision::single_precision;
  // The totals start as the solve of no pairs: the settings as resolved,
  // for the summary even of an empty input.
  Solution<double> total;
  Solution<float> total_float;
  if (single_scalar)
    total_float = solve(PairBatch<float>(), options, request, threads);
  else
    total = solve(PairBatch<double>(), options, request, threads);
  double read_seconds = 0, write_seconds = 0;
  Stopwatch reading;
  PairBatch<double> pairs;
  for_each_number_block(input, numbers_per_pair, threads, false, [&](NumberColumns& block) {
    read_seconds += reading.seconds();
    take_pairs(block, pairs);
    if (single_scalar) {
      // The float reference path is contact_function<float>: it takes float
      // pairs. (The batch path rounds double pairs to float itself.)
      const Solution<float> solution =
          solve(convert_pairs<float>(pairs), options, request, threads);
      const Stopwatch writing;
      write_solution(solution, options, output);
      write_seconds += writing.seconds();
      add_block(total_float, solution);
    } else {
      const Solution<double> solution = solve(pairs, options, request, threads);
      const Stopwatch writing;
      write_solution(solution, options, output);
      write_seconds += writing.seconds();
      add_block(total, solution);
    }
    take_pairs(block, pairs);  // the columns back to the reader, for the next block
    reading = Stopwatch();
  });
  read_seconds += reading.seconds();
  const Stopwatch committing;
  output.commit();
  write_seconds += committing.seconds();

  const std::size_t count = single_scalar ? total_float.report.pairs : total.report.pairs;
  std::fprintf(stderr,
               "pwcontact contact: %zu pairs from %s (read in %s) to %s (written in %s)\n%s", count,
               input.name().c_str(), describe_seconds(read_seconds).c_str(), output.name().c_str(),
               describe_seconds(write_seconds).c_str(),
               single_scalar ? total_float.describe().c_str() : total.describe().c_str());
  return ExitStatus::success;
}

}  // namespace

const Subcommand contact_subcommand = {
    "contact", "mu^2 and more, or overlap only, of every pair in a file or stdin",
    contact_options_help, run_contact, parse_contact_only};

}  // namespace pwcontact::cli
