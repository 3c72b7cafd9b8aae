#include "cli/command_line.hpp"

#include <omp.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <optional>

#include "cli/text_output.hpp"

namespace pwcontact::cli {
namespace {

// Help and usage lines are wrapped to fit an 80-column terminal.
constexpr std::size_t line_width = 79;
constexpr std::size_t option_column = 30;

bool is_option_like(std::string_view argument) { return argument.size() > 1 && argument[0] == '-'; }

std::string quoted(std::string_view text) { return "'" + std::string(text) + "'"; }

std::string supported_isa_list() {
  std::string list;
  for (Isa isa : supported_isas()) list += std::string(list.empty() ? "" : ", ") + isa_name(isa);
  return list;
}

// "auto", or a count from 0 (automatic as well, the library's convention) to
// max_fixed_iterations.
int parse_iterations(std::string_view text) {
  if (text == "auto") return automatic_iterations;
  if (text.empty() || text.find_first_not_of("0123456789") != std::string_view::npos)
    throw std::invalid_argument(quoted(text) + " is neither auto nor a count from 1 to " +
                                std::to_string(max_fixed_iterations));
  return int(parse_integer(text, 0, max_fixed_iterations));
}

}  // namespace

std::int64_t parse_integer(std::string_view text, std::int64_t min, std::int64_t max) {
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc() && end == text.data() + text.size() && min <= value && value <= max)
    return value;
  if (error == std::errc::invalid_argument || end != text.data() + text.size())
    throw std::invalid_argument(quoted(text) + " is not a whole number");
  throw std::invalid_argument(quoted(text) + " is out of range (" + std::to_string(min) + " to " +
                              std::to_string(max) + ")");
}

std::uint64_t parse_unsigned(std::string_view text) {
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::result_out_of_range)
    throw std::invalid_argument(quoted(text) + " does not fit in 64 bits");
  if (error != std::errc() || end != text.data() + text.size())
    throw std::invalid_argument(quoted(text) + " is not a whole number >= 0");
  return value;
}

double parse_positive_number(std::string_view text) {
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error == std::errc::invalid_argument || end != text.data() + text.size())
    throw std::invalid_argument(quoted(text) + " is not a number");
  if (error != std::errc() || !(value > 0) || !std::isfinite(value))
    throw std::invalid_argument(quoted(text) + " is not a positive finite number");
  return value;
}

double parse_cutoff(std::string_view text) {
  const double cutoff = parse_positive_number(text);
  const double square = cutoff * cutoff;
  if (!(square >= std::numeric_limits<double>::min()) || !std::isfinite(square))
    throw std::invalid_argument(quoted(text) +
                                " has a square outside the range of normal doubles (mu^2 is "
                                "compared with cutoff^2): from 1.5e-154 to 1.34e154");
  return cutoff;
}

// ---------------------------------------------------------------------------

OptionParser::OptionParser(std::string command, std::string summary, std::string operands,
                           std::size_t max_operands, OperandHandler on_operand)
    : command_(std::move(command)),
      summary_(std::move(summary)),
      operands_(std::move(operands)),
      max_operands_(max_operands),
      on_operand_(std::move(on_operand)) {}

void OptionParser::add_value(std::initializer_list<std::string_view> names, std::string value_name,
                             std::string default_text, std::string description,
                             ValueHandler on_value) {
  Option option;
  option.names.assign(names.begin(), names.end());
  option.value_name = std::move(value_name);
  option.default_text = std::move(default_text);
  option.description = std::move(description);
  option.on_value = std::move(on_value);
  options_.push_back(std::move(option));
}

void OptionParser::add_flag(std::initializer_list<std::string_view> names, std::string description,
                            FlagHandler on_flag) {
  Option option;
  option.names.assign(names.begin(), names.end());
  option.default_text = "off";
  option.description = std::move(description);
  option.on_flag = std::move(on_flag);
  options_.push_back(std::move(option));
}

OptionParser::Option* OptionParser::find(std::string_view name) {
  for (Option& option : options_)
    if (std::find(option.names.begin(), option.names.end(), name) != option.names.end())
      return &option;
  return nullptr;
}

bool OptionParser::given(std::string_view name) const {
  for (const Option& option : options_)
    if (std::find(option.names.begin(), option.names.end(), name) != option.names.end())
      return option.given;
  return false;
}

void OptionParser::fail(const std::string& message) const {
  throw CommandError(ExitStatus::usage_error, message, usage());
}

bool OptionParser::parse(const Arguments& arguments) {
  bool options_ended = false;
  std::size_t operand_count = 0;
  for (std::size_t i = 0; i < arguments.size(); ++i) {
    const std::string_view argument = arguments[i];
    if (!options_ended && argument == "--") {
      options_ended = true;
      continue;
    }
    if (options_ended || !is_option_like(argument)) {
      if (operand_count == max_operands_)
        fail("unexpected argument " + quoted(argument) +
             (max_operands_ == 0 ? std::string(" (this command takes no operands)")
                                 : " (the command takes " + operands_ + ")"));
      on_operand_(argument);
      ++operand_count;
      continue;
    }
    if (argument == "-h" || argument == "--help") return false;

    // "--name=value" carries its value inline; otherwise it is the next argument.
    std::string_view name = argument;
    std::optional<std::string_view> inline_value;
    if (const std::size_t equals = argument.find('=');
        argument.substr(0, 2) == "--" && equals != std::string_view::npos) {
      name = argument.substr(0, equals);
      inline_value = argument.substr(equals + 1);
    }
    Option* option = find(name);
    if (!option) fail("unknown option " + quoted(name));
    option->given = true;

    if (option->on_flag) {
      if (inline_value) fail("option " + std::string(name) + " takes no value");
      option->on_flag();
      continue;
    }
    if (!inline_value && i + 1 == arguments.size())
      fail("option " + std::string(name) + " needs a value (" + option->value_name + ")");
    const std::string_view value = inline_value ? *inline_value : arguments[++i];
    try {
      option->on_value(value);
    } catch (const std::invalid_argument& e) {
      fail("option " + std::string(name) + ": " + e.what());
    }
  }
  return true;
}

std::string OptionParser::synopsis() const {
  // Every option in brackets, wrapped under the command name.
  std::vector<std::string> words;
  for (const Option& option : options_)
    words.push_back("[" + option.names.front() +
                    (option.value_name.empty() ? "" : " " + option.value_name) + "]");
  if (!operands_.empty()) words.push_back(operands_);

  std::string text = "Usage: pwcontact " + command_;
  const std::size_t indent = text.size();
  std::size_t column = text.size();
  for (const std::string& word : words) {
    if (column + 1 + word.size() > line_width) {
      text += "\n" + std::string(indent, ' ');
      column = indent;
    }
    text += " " + word;
    column += 1 + word.size();
  }
  return text + "\n";
}

std::string OptionParser::usage() const {
  return synopsis() + "Run 'pwcontact " + command_ + " --help' for the options.\n";
}

std::string OptionParser::help() const {
  std::string text = synopsis() + "\n" + wrap_words(summary_, 0, line_width) + "\n\nOptions:\n";

  auto add_row = [&text](const std::string& left, const std::string& description) {
    std::string row = "  " + left;
    if (row.size() + 2 > option_column) {  // too long: the description goes below
      text += row + "\n";
      row.clear();
    }
    row.resize(option_column, ' ');
    text += row + wrap_words(description, option_column, line_width) + "\n";
  };
  for (const Option& option : options_) {
    std::string left;
    for (const std::string& name : option.names) left += (left.empty() ? "" : ", ") + name;
    if (!option.value_name.empty()) left += " " + option.value_name;
    add_row(left, option.description + " (default: " + option.default_text + ")");
  }
  add_row("-h, --help", "show this help and exit");
  return text;
}

// ---------------------------------------------------------------------------

void add_solver_options(OptionParser& parser, SolverOptions& options) {
  add_choice(parser, "--precision",
             Choices<Precision>{
                 {Precision::double_precision, Precision::single_precision, Precision::mixed},
                 precision_name},
             options.precision,
             "arithmetic of the batch path: double; float, on the numbers rounded to "
             "float (mu^2 to ~1e-5 relative, the fastest); or mixed, float iterations "
             "then a double Newton step and a double convergence check (double accuracy; "
             "measured about as fast as double on AVX-512, see the README). Pairs the "
             "lanes do not finish are answered in "
             "double by the reference path (status 1)");
  parser.add_value(
      {"--iterations"}, "N|auto", "auto",
      "Newton iterations of the batch path. auto (also 0): each pair iterates "
      "until its convergence check passes, up to " +
          std::to_string(max_automatic_iterations) + " evaluations. N from 1 to " +
          std::to_string(max_fixed_iterations) +
          ": every pair gets N (mixed precision "
          "adds a double finish; overlap mode stops a pair once it is decided). "
          "Pairs that still fail the check are recomputed by the reference path "
          "(status 1, ok_fallback)",
      [&options](std::string_view value) { options.iterations = parse_iterations(value); });
  add_choice(parser, "--accuracy",
             Choices<Accuracy>{{Accuracy::standard, Accuracy::high}, accuracy_name},
             options.accuracy,
             "standard: mu^2 to the floor of the arithmetic (~eps times the condition "
             "of Q); high: the last evaluation refined with an error-free residual, "
             "which squares that floor, ~eps + (eps cond)^2 (double or mixed "
             "precision only)");
  add_choice(
      parser, "--formulation",
      Choices<Formulation>{{Formulation::automatic, Formulation::newton, Formulation::log_odds},
                           formulation_name},
      options.formulation,
      "the Newton iteration of the batch path (advanced): auto, the measured best "
      "for the precision; newton, in lambda; log_odds, in ln(lambda / (1 - lambda)), "
      "fewer iterations on elongated shapes but not faster since cold double solves step "
      "on the polynomial form (README). The summary names the one used");
  add_threads_option(parser, options.threads, "results");
  parser.add_value({"--isa"}, "auto|sse2|avx2|avx512|fallback",
                   "auto = PWCONTACT_ISA if set, else the best; here " +
                       std::string(isa_name(supported_isas().front())),
                   "instruction set of the batch path; this CPU runs " + supported_isa_list(),
                   [&options](std::string_view value) {
                     const std::optional<Isa> isa = parse_isa(value);
                     if (!isa)
                       throw std::invalid_argument(quoted(value) +
                                                   " is not auto, sse2, avx2, avx512 or fallback");
                     options.isa = *isa;
                   });
}

void check_solver_options(const OptionParser& parser, const SolverOptions& options) {
  if (options.accuracy == Accuracy::high && options.precision == Precision::single_precision)
    parser.fail(
        "--accuracy high refines mu^2 in double: it needs --precision double or mixed, "
        "not float");
}

Isa resolve_instruction_set(Isa requested) {
  try {
    return resolve_isa(requested);
  } catch (const std::exception& e) {
    // Unsupported instruction set (runtime_error) or bad PWCONTACT_ISA
    // (invalid_argument): both are the caller's choice, not an I/O problem.
    throw CommandError(ExitStatus::usage_error,
                       std::string(e.what()) + "; this CPU runs: " + supported_isa_list());
  }
}

void add_threads_option(OptionParser& parser, int& threads, const std::string& what) {
  parser.add_value(
      {"--threads"}, "N", "0 = all OpenMP offers, here " + std::to_string(omp_get_max_threads()),
      "OpenMP threads, 0 to 1024; " + what + " do not depend on it",
      [&threads](std::string_view value) { threads = int(parse_integer(value, 0, 1024)); });
}

int resolve_thread_count(int threads) { return threads > 0 ? threads : omp_get_max_threads(); }

void add_output_option(OptionParser& parser, std::string& output, const std::string& what) {
  parser.add_value({"-o", "--output"}, "OUT", "- = standard output",
                   "write " + what +
                       " to OUT; it appears only when the run succeeds (written "
                       "beside it, then renamed into place)",
                   [&output](std::string_view path) { output = path; });
}

}  // namespace pwcontact::cli
