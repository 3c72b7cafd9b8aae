// `pwcontact contact`: mu^2, lambda and status of every pair of a text file.
#include <charconv>
#include <cstdio>

#include "cli/number_table.hpp"
#include "cli/solve.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"

namespace pwcontact::cli {
namespace {

// One pair per line: r12 (3 numbers), then Q1 and Q2 (6 numbers each).
constexpr std::size_t numbers_per_pair = 15;

struct ContactOptions {
  SolverOptions solver;
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
      "other line that does not hold exactly 15 numbers stops the run (exit status 2, "
      "nothing written).\n\n"
      "Output: one line per pair, in input order: mu2 lambda status, numbers with 17 "
      "significant digits (nan when the status is invalid). A summary goes to "
      "standard error.",
      "[FILE]", 1, [&options](std::string_view file) { options.input = file; });
  add_solver_options(parser, options.solver);
  parser.add_flag({"--scalar"},
                  "solve every pair with the scalar reference path, contact_function<double> "
                  "(<float> with --precision float), in parallel, instead of the batch path",
                  [&options] { options.scalar = true; });
  parser.add_value({"-o", "--output"}, "OUT", "- = standard output",
                   "write the results to OUT; it appears only when the run succeeds "
                   "(written beside it, then renamed into place)",
                   [&options](std::string_view path) { options.output = path; });
  return parser;
}

std::string contact_options_help() {
  ContactOptions options;
  return contact_parser(options).help();
}

PairBatch<double> read_pairs(const std::string& path, int threads, std::string& source) {
  TextInput input(path);
  source = input.name();
  NumberColumns table = read_number_columns(input, numbers_per_pair, threads);
  // The parsed columns become the batch's columns, without a copy.
  PairBatch<double> pairs;
  std::vector<std::vector<double>>& columns = table.columns;
  for (int k = 0; k < 3; ++k) pairs.r12(k).swap(columns[std::size_t(k)]);
  for (int k = 0; k < 6; ++k) {
    pairs.q1(k).swap(columns[std::size_t(3 + k)]);
    pairs.q2(k).swap(columns[std::size_t(9 + k)]);
  }
  return pairs;
}

template <class T>
void append_result_line(std::string& text, const Solution<T>& solution, std::size_t i) {
  char line[2 * max_number_chars + 8];
  char* end = write_number(line, solution.mu2[i]);
  *end++ = ' ';
  end = write_number(end, solution.lambda[i]);
  *end++ = ' ';
  end = std::to_chars(end, line + sizeof line, int(solution.status[i])).ptr;
  *end++ = '\n';
  text.append(line, end);
}

template <class T>
void solve_and_write(const PairBatch<T>& pairs, const ContactOptions& options, OutputFile& output,
                     const std::string& source, double read_seconds) {
  const Solution<T> solution = options.scalar ? solve_reference(pairs, options.solver.threads)
                                              : solve_batch(pairs, options.solver);
  const Stopwatch writing;
  write_lines_in_order(
      output, pairs.size(), resolve_thread_count(options.solver.threads),
      [&solution](std::string& text, std::size_t i) { append_result_line(text, solution, i); });
  output.commit();

  std::fprintf(
      stderr, "pwcontact contact: %zu pairs from %s (read in %s) to %s (written in %s)\n%s",
      pairs.size(), source.c_str(), describe_seconds(read_seconds).c_str(), output.name().c_str(),
      describe_seconds(writing.seconds()).c_str(), solution.describe().c_str());
}

ExitStatus run_contact(const Arguments& arguments) {
  ContactOptions options;
  OptionParser parser = contact_parser(options);
  if (!parser.parse(arguments)) {
    std::fputs(full_help(contact_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  if (options.scalar && (parser.given("--iterations") || parser.given("--isa")))
    parser.fail(
        "--iterations and --isa apply to the batch path, not to --scalar (the "
        "reference path iterates to convergence, in scalar code)");
  // Settle everything that can fail before reading a possibly large input.
  if (!options.scalar) options.solver.isa = resolve_instruction_set(options.solver.isa);
  const int threads = resolve_thread_count(options.solver.threads);
  OutputFile output(options.output);

  const Stopwatch reading;
  std::string source;
  PairBatch<double> pairs = read_pairs(options.input, threads, source);
  if (options.solver.precision == Precision::single_precision) {
    const PairBatch<float> single = convert_pairs<float>(pairs);
    pairs = PairBatch<double>();  // release the double copy before solving
    solve_and_write(single, options, output, source, reading.seconds());
  } else {
    solve_and_write(pairs, options, output, source, reading.seconds());
  }
  return ExitStatus::success;
}

}  // namespace

const Subcommand contact_subcommand = {
    "contact", "mu^2, lambda and status of every pair in a file or standard input",
    contact_options_help, run_contact};

}  // namespace pwcontact::cli
