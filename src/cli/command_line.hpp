// Parsing the command line: a declarative option table per subcommand, from
// which both the parser and the help text are made, so that the help can
// never drift from what is accepted. Also the options every solving
// subcommand shares (precision, iterations, accuracy, formulation, threads,
// instruction set).
#pragma once

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "pwcontact/batch.hpp"

namespace pwcontact::cli {

// The exit statuses of every subcommand, as documented in the help.
enum class ExitStatus : int {
  success = 0,
  io_error = 1,     // an input cannot be opened or read, an output cannot be written
  usage_error = 2,  // bad command line, malformed input, an instruction set this CPU lacks
  failed = 3,       // mc: the packing fraction not reached, or an overlap found
};

// A failure reported to the user: a message (and, for command-line mistakes,
// the short usage) on standard error, and an exit status.
class CommandError : public std::runtime_error {
 public:
  CommandError(ExitStatus status, const std::string& message, std::string usage = {})
      : std::runtime_error(message), status_(status), usage_(std::move(usage)) {}
  ExitStatus exit_status() const noexcept { return status_; }
  const std::string& usage() const noexcept { return usage_; }

 private:
  ExitStatus status_;
  std::string usage_;
};

// The arguments after the subcommand name.
using Arguments = std::vector<std::string_view>;

// Option values. Each throws std::invalid_argument with a message that
// completes "option --name: ..." when the text is not acceptable.
std::int64_t parse_integer(std::string_view text, std::int64_t min, std::int64_t max);
std::uint64_t parse_unsigned(std::string_view text);
double parse_positive_number(std::string_view text);  // finite and > 0
double parse_cutoff(std::string_view text);  // positive, its square a normal, finite double

// One subcommand's syntax: its options and its operands (positional
// arguments). Options may come before or after operands; "--" ends the
// options; "--name=value" and "--name value" are both accepted; "-" is an
// operand (standard input by convention), not an option.
class OptionParser {
 public:
  using ValueHandler = std::function<void(std::string_view value)>;
  using FlagHandler = std::function<void()>;
  using OperandHandler = std::function<void(std::string_view operand)>;

  // `operands` as shown in the synopsis, e.g. "[FILE]"; `max_operands`
  // operands are accepted, each passed to `on_operand`.
  OptionParser(std::string command, std::string summary, std::string operands = {},
               std::size_t max_operands = 0, OperandHandler on_operand = {});

  // `names` are the spellings ("-o", "--output"); `value_name` is shown in
  // the help ("N", "double|float"); `default_text` is the default as shown.
  void add_value(std::initializer_list<std::string_view> names, std::string value_name,
                 std::string default_text, std::string description, ValueHandler on_value);
  void add_flag(std::initializer_list<std::string_view> names, std::string description,
                FlagHandler on_flag);

  // Applies the arguments through the handlers. Returns false when help was
  // asked for (-h, --help); the caller then prints help() and stops.
  // Throws CommandError (usage_error, with usage()) for anything not accepted.
  bool parse(const Arguments& arguments);

  // Whether an option was given on the command line, by any of its names.
  bool given(std::string_view name) const;

  std::string synopsis() const;  // "Usage: pwcontact <command> [--option VALUE]... OPERANDS"
  std::string usage() const;     // the synopsis and where to find more
  std::string help() const;      // the synopsis, the summary and the option table

  // Throws CommandError(usage_error) with this command's usage attached.
  [[noreturn]] void fail(const std::string& message) const;

 private:
  struct Option {
    std::vector<std::string> names;
    std::string value_name;  // empty for a flag
    std::string default_text;
    std::string description;
    ValueHandler on_value;
    FlagHandler on_flag;
    bool given = false;
  };
  Option* find(std::string_view name);

  std::string command_;
  std::string summary_;
  std::string operands_;
  std::size_t max_operands_;
  OperandHandler on_operand_;
  std::vector<Option> options_;
};

// The values of an option that takes one of a few names, such as
// --precision double|float|mixed, named as the library names them, so that
// the help, the parser and the summaries spell them alike.
template <class E>
struct Choices {
  std::vector<E> values;
  const char* (*name_of)(E) noexcept;

  // "double|float|mixed" with separator "|"; "double, float or mixed" with
  // ", " and " or ".
  std::string names(std::string_view separator, std::string_view last_separator) const {
    std::string text;
    for (std::size_t i = 0; i < values.size(); ++i) {
      if (i != 0) text += i + 1 < values.size() ? separator : last_separator;
      text += name_of(values[i]);
    }
    return text;
  }

  // Throws std::invalid_argument when `text` names none of the values.
  E parse(std::string_view text) const {
    for (E value : values)
      if (text == name_of(value)) return value;
    throw std::invalid_argument("'" + std::string(text) + "' is not " + names(", ", " or "));
  }
};

// Adds the option `name` (value names from `choices`), writing into
// `target`, whose value now is the default the help shows.
template <class E>
void add_choice(OptionParser& parser, std::string_view name, const Choices<E>& choices, E& target,
                std::string description) {
  parser.add_value({name}, choices.names("|", "|"), choices.name_of(target), std::move(description),
                   [&target, choices](std::string_view text) { target = choices.parse(text); });
}

// ---------------------------------------------------------------------------
// Options shared by the subcommands that solve pairs

// The batch options as the command line sets them. The precision starts as
// double rather than automatic: the pairs are read as double, and the help,
// the option checks and the summary can then name it.
struct SolverOptions : BatchOptions {
  SolverOptions() { precision = Precision::double_precision; }
};

// Adds --precision, --iterations, --accuracy, --formulation, --threads and
// --isa, writing into `options` (which must outlive the parser).
void add_solver_options(OptionParser& parser, SolverOptions& options);

// After parsing: rejects the combinations the library refuses (high accuracy
// in single precision), as a usage error of `parser`'s command rather than
// an exception from deep inside a solve.
void check_solver_options(const OptionParser& parser, const SolverOptions& options);

// The instruction set the batch path will run on, resolved now so that an
// unsupported choice stops the command before any work. Throws CommandError
// (usage_error) when the CPU lacks it or PWCONTACT_ISA is not valid.
Isa resolve_instruction_set(Isa requested);

// Adds --threads N (0 to 1024, 0: the OpenMP default) to `threads`; `what`
// names what does not depend on it ("results", "the pairs").
void add_threads_option(OptionParser& parser, int& threads, const std::string& what);

// The OpenMP thread count `threads` stands for (0: the OpenMP default).
int resolve_thread_count(int threads);

// Adds -o, --output OUT to `output` ("-": standard output); `what` names
// what is written ("the results", "the pairs").
void add_output_option(OptionParser& parser, std::string& output, const std::string& what);

}  // namespace pwcontact::cli
