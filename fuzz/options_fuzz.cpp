// The option parser of every subcommand on arbitrary argument lists (the
// input split at NUL bytes, the first byte choosing the subcommand): it
// accepts, asks for help, or refuses with a usage error, never anything else.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "cli/command_line.hpp"
#include "cli/subcommands.hpp"
#include "fuzz_checks.hpp"

using namespace pwcontact;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const cli::Subcommand* const subcommands[] = {&cli::contact_subcommand, &cli::screen_subcommand,
                                                &cli::demo_subcommand, &cli::pairs_subcommand};
  const cli::Subcommand& subcommand = *subcommands[data[0] % 4];
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  std::vector<std::string> words;
  std::size_t start = 0;
  for (std::size_t k = 0; k <= text.size() && words.size() < 24; ++k)
    if (k == text.size() || text[k] == '\0') {
      words.push_back(text.substr(start, k - start));
      start = k + 1;
    }
  const cli::Arguments arguments(words.begin(), words.end());
  try {
    subcommand.parse_only(arguments);
  } catch (const cli::CommandError& e) {
    fuzz::expect(e.exit_status() == cli::ExitStatus::usage_error,
                 "a bad command line is a usage error");
  }
  return 0;
}
