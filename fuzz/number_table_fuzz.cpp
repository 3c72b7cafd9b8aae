// The command line's number-table parser on arbitrary text: either every
// record with its column count and its line, in order, or a usage error
// naming a line of the text.
#include <cstdint>
#include <string>
#include <string_view>

#include "cli/command_line.hpp"
#include "cli/number_table.hpp"
#include "fuzz_checks.hpp"

using namespace pwcontact;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t columns = 1 + data[0] % 16;
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
  const std::size_t lines = std::size_t(std::count(text.begin(), text.end(), '\n')) + 1;
  try {
    const cli::NumberColumns table = cli::parse_number_columns(text, columns, 1, true, "fuzz");
    fuzz::expect(table.columns.size() == columns, "a column per number");
    for (const auto& column : table.columns)
      fuzz::expect(column.size() == table.records(), "every column a number per record");
    for (std::size_t r = 0; r < table.records(); ++r) {
      fuzz::expect(table.line[r] >= 1 && table.line[r] <= lines, "a record's line is in the text");
      if (r > 0) fuzz::expect(table.line[r] > table.line[r - 1], "records in line order");
    }
  } catch (const cli::CommandError& e) {
    fuzz::expect(e.exit_status() == cli::ExitStatus::usage_error,
                 "a malformed line is a usage error");
    const std::string message = e.what();
    fuzz::expect(message.rfind("fuzz:", 0) == 0, "the message names the input and the line");
    fuzz::expect(message.find('\0') == std::string::npos, "no NUL in a message");
  }
  return 0;
}
