// `pwcontact`: the command line. main() picks the subcommand, and turns every
// failure into a message on standard error and a documented exit status.
#include <cstdio>
#include <exception>
#include <new>
#include <string>

#include "cli/command_line.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"

#ifndef PWCONTACT_VERSION
#error "PWCONTACT_VERSION must be defined by the build (the project version)"
#endif

namespace pwcontact::cli {
namespace {

const Subcommand* const subcommands[] = {&demo_subcommand, &screen_subcommand, &contact_subcommand,
                                         &pairs_subcommand, &mc_subcommand};

const Subcommand* find_subcommand(std::string_view name) {
  for (const Subcommand* subcommand : subcommands)
    if (subcommand->name == name) return subcommand;
  return nullptr;
}

std::string subcommand_names() {
  std::string names;
  for (const Subcommand* subcommand : subcommands)
    names += (names.empty() ? "" : ", ") + std::string(subcommand->name);
  return names;
}

std::string synopsis() {
  return "Usage: pwcontact SUBCOMMAND [OPTION]... [OPERAND]...\n       (SUBCOMMAND: " +
         subcommand_names() + ")\n       pwcontact help [SUBCOMMAND] | --help | --version\n";
}

std::string usage() { return synopsis() + "Run 'pwcontact --help' for more.\n"; }

std::string overview_help() {
  std::string text = "pwcontact " PWCONTACT_VERSION
                     ": the Perram-Wertheim contact function mu^2 of two ellipsoids,\n"
                     "for very many pairs at once.\n\n" +
                     synopsis() + "\nSubcommands:\n";
  for (const Subcommand* subcommand : subcommands) {
    std::string row = "  " + std::string(subcommand->name);
    row.resize(12, ' ');
    text += row + std::string(subcommand->summary) + "\n";
  }
  text += "  help      this text, or the help of one subcommand\n";
  for (const Subcommand* subcommand : subcommands)
    text += "\n" + std::string(78, '-') + "\n" + subcommand->options_help();
  return text + "\n" + std::string(78, '-') + "\n" + status_code_table() + "\n" +
         exit_status_text();
}

ExitStatus run(const Arguments& arguments) {
  if (arguments.empty())
    throw CommandError(ExitStatus::usage_error, "no subcommand given", usage());
  const std::string_view first = arguments.front();
  const Arguments rest(arguments.begin() + 1, arguments.end());

  // (--version and --help take nothing after them: `pwcontact -h contact`
  // printed the overview, not contact's help, and said nothing.)
  if ((first == "--version" || first == "-h" || first == "--help") && !rest.empty())
    throw CommandError(
        ExitStatus::usage_error,
        std::string(first) + " takes no argument, got '" + std::string(rest.front()) + "'" +
            (first == "--version"
                 ? std::string()
                 : " (for a subcommand's help: pwcontact help " + std::string(rest.front()) + ")"),
        usage());
  if (first == "--version") {
    std::puts("pwcontact " PWCONTACT_VERSION);
    return ExitStatus::success;
  }
  if (first == "-h" || first == "--help" || (first == "help" && rest.empty())) {
    std::fputs(overview_help().c_str(), stdout);
    return ExitStatus::success;
  }
  if (first == "help") {
    const Subcommand* subcommand = find_subcommand(rest.front());
    if (!subcommand || rest.size() > 1)
      throw CommandError(ExitStatus::usage_error,
                         "help takes one subcommand name (" + subcommand_names() + ")", usage());
    std::fputs(full_help(*subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  if (const Subcommand* subcommand = find_subcommand(first)) return subcommand->run(rest);
  throw CommandError(ExitStatus::usage_error,
                     (first.substr(0, 1) == "-" ? "unknown option '" : "unknown subcommand '") +
                         std::string(first) + "'",
                     usage());
}

}  // namespace

}  // namespace pwcontact::cli

int main(int argc, char** argv) {
  using namespace pwcontact::cli;
  ensure_standard_descriptors();
  const Arguments arguments(argv + 1, argv + argc);
  // Messages name the subcommand they come from, as in "pwcontact contact: ...".
  std::string prefix = "pwcontact";
  if (!arguments.empty() && find_subcommand(arguments.front()))
    prefix += " " + std::string(arguments.front());
  try {
    const ExitStatus status = run(arguments);
    // Help, version and the demo report go to standard output: a failure to
    // write them is an I/O error like any other.
    if (std::fflush(stdout) != 0 || std::ferror(stdout))
      throw CommandError(ExitStatus::io_error, "cannot write <stdout>");
    return int(status);
  } catch (const CommandError& error) {
    std::fprintf(stderr, "%s: %s\n%s", prefix.c_str(), error.what(), error.usage().c_str());
    return int(error.exit_status());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: out of memory\n", prefix.c_str());
    return int(ExitStatus::io_error);
  } catch (const std::exception& error) {
    // The library throws only for calls it cannot honour (e.g. an instruction
    // set the CPU lacks); those are the user's choices, hence status 2.
    std::fprintf(stderr, "%s: %s\n", prefix.c_str(), error.what());
    return int(ExitStatus::usage_error);
  }
}
