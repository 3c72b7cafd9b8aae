// The subcommands of `pwcontact`, each in its own file, all described the
// same way so that main() can dispatch to them and list them in the help.
#pragma once

#include <string>
#include <string_view>

#include "cli/command_line.hpp"

namespace pwcontact::cli {

struct Subcommand {
  std::string_view name;
  std::string_view summary;  // one line, for the overview
  // Synopsis, description and option table (without the status codes and
  // exit statuses, which the full help adds once).
  std::string (*options_help)();
  // Runs with the arguments after the subcommand name, handling --help
  // itself. Throws CommandError for what the user must fix.
  ExitStatus (*run)(const Arguments& arguments);
  // Only parses and checks the arguments, as run() does before any work
  // (false: help was asked for); throws as run() does. For the tests and
  // the option parser's fuzz target.
  bool (*parse_only)(const Arguments& arguments);
};

extern const Subcommand contact_subcommand;
extern const Subcommand screen_subcommand;
extern const Subcommand demo_subcommand;
extern const Subcommand pairs_subcommand;
extern const Subcommand mc_subcommand;

// What `pwcontact SUBCOMMAND --help` prints: the subcommand's options help,
// the status codes and the exit statuses.
std::string full_help(const Subcommand& subcommand);

}  // namespace pwcontact::cli
