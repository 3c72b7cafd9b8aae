#include "cli/number_table.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <optional>

#include "cli/command_line.hpp"
#include "number_text.hpp"
#include "parallel_errors.hpp"

namespace pwcontact::cli {
namespace {

[[noreturn]] void fail_to_read(const std::string& name, int error) {
  throw CommandError(ExitStatus::io_error, "cannot read " + name + ": " + std::strerror(error));
}

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

using detail::printable;

const char* skip_blanks(const char* p, const char* end) {
  while (p != end && is_blank(*p)) ++p;
  return p;
}

const char* token_end(const char* p, const char* end) {
  while (p != end && !is_blank(*p)) ++p;
  return p;
}

// Calls on_line(begin, end) for every line of `text`, without its '\n'. A
// last line without '\n' counts too.
template <class OnLine>
void for_each_line(std::string_view text, const OnLine& on_line) {
  const char* p = text.data();
  const char* const end = p + text.size();
  while (p != end) {
    const char* newline = static_cast<const char*>(std::memchr(p, '\n', std::size_t(end - p)));
    const char* line_end = newline ? newline : end;
    on_line(p, line_end);
    p = newline ? newline + 1 : end;
  }
}

bool is_record(const char* begin, const char* end) {
  const char* first = skip_blanks(begin, end);
  return first != end && *first != '#';
}

// Parses the number at p, which must be followed by a blank or the end of
// the line. Returns the end of the number, or nullptr if the token is not one.
const char* parse_number(const char* p, const char* end, double& value) {
  const char* const start = p;
  // std::from_chars rejects a leading '+' (as it must), but "+1.5" and
  // "+inf" are numbers to every other tool that writes such tables.
  if (*p == '+' && ++p != end && (*p == '+' || *p == '-')) return nullptr;
  const auto [number_end, error] = std::from_chars(p, end, value);
  if (error == std::errc::invalid_argument) return nullptr;
  if (number_end != end && !is_blank(*number_end)) return nullptr;
  // Beyond double range from_chars leaves `value` alone; strtod rounds it to
  // +-inf or to 0 / a subnormal, as IEEE 754 would. It is locale-dependent,
  // but this program never leaves the "C" locale.
  if (error == std::errc::result_out_of_range)
    value = std::strtod(std::string(start, number_end).c_str(), nullptr);
  return number_end;
}

// Reads one record into `row`. Returns what is wrong, if anything.
std::optional<std::string> parse_record(const char* p, const char* end, double* row,
                                        std::size_t column_count) {
  std::size_t found = 0;
  for (p = skip_blanks(p, end); p != end; p = skip_blanks(p, end)) {
    if (found == column_count) {  // count the rest for the message
      for (; p != end; p = skip_blanks(token_end(p, end), end)) ++found;
      break;
    }
    const char* number_end = parse_number(p, end, row[found]);
    if (!number_end) {
      constexpr std::size_t shown = 40;
      const std::string_view token(p, std::min<std::size_t>(token_end(p, end) - p, shown));
      return "field " + std::to_string(found + 1) + ", '" + printable(token) + "', is not a number";
    }
    ++found;
    p = number_end;
  }
  if (found != column_count)
    return "expected " + std::to_string(column_count) + " numbers, found " + std::to_string(found);
  return std::nullopt;
}

// A run of whole lines, parsed by one thread.
struct Piece {
  std::string_view text;
  std::size_t lines = 0;         // lines in text
  std::size_t records = 0;       // lines in text that hold a record
  std::size_t first_line = 1;    // 1-based number of its first line in the input
  std::size_t first_record = 0;  // index of its first record in the input
  std::size_t error_line = 0;    // 0: no error
  std::string error;
};

// Up to `count` pieces of roughly equal size, each ending after a '\n'.
std::vector<Piece> split_into_pieces(std::string_view text, std::size_t count) {
  std::vector<Piece> pieces;
  std::size_t start = 0;
  for (std::size_t i = 1; i <= count && start < text.size(); ++i) {
    std::size_t end = text.size();
    if (i < count) {
      const std::size_t newline = text.find('\n', std::max(start, text.size() / count * i));
      if (newline != std::string_view::npos) end = newline + 1;
    }
    Piece piece;
    piece.text = text.substr(start, end - start);
    pieces.push_back(piece);
    start = end;
  }
  return pieces;
}

// Appends the records of consecutive blocks of whole lines to columns,
// numbering lines across blocks.
class ColumnsParser {
 public:
  ColumnsParser(const std::string& source, std::size_t column_count, int threads, bool line_numbers)
      : source_(source), threads_(threads), line_numbers_(line_numbers) {
    table_.columns.resize(column_count);
  }

  // Appends the records of `lines` (whole lines) to the table.
  void parse(std::string_view lines);
  NumberColumns take() { return std::move(table_); }
  NumberColumns& table() { return table_; }
  // Empties the table, keeping the line count (for the next block).
  void clear() {
    for (NumberColumns::Column& column : table_.columns) column.clear();
    table_.line.clear();
  }

 private:
  const std::string& source_;
  int threads_;
  bool line_numbers_;
  std::size_t lines_before_ = 0;  // lines of the blocks parsed so far
  NumberColumns table_;
};

void ColumnsParser::parse(std::string_view lines) {
  const std::size_t column_count = table_.columns.size();
  // Several pieces per thread balance the load when lines differ in length;
  // pieces below ~64 KiB would cost more to schedule than to parse.
  const std::size_t piece_count =
      std::clamp<std::size_t>(lines.size() / (std::size_t(64) << 10), 1, std::size_t(threads_) * 4);
  std::vector<Piece> pieces = split_into_pieces(lines, piece_count);
  const std::ptrdiff_t count = std::ptrdiff_t(pieces.size());

  // First pass, cheap: count lines and records, so that every piece knows
  // where its records go and what its line numbers are.
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_)
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    Piece& piece = pieces[std::size_t(i)];
    for_each_line(piece.text, [&piece](const char* begin, const char* end) {
      ++piece.lines;
      if (is_record(begin, end)) ++piece.records;
    });
  }
  std::size_t records = table_.records();
  std::size_t first_line = lines_before_ + 1;
  for (Piece& piece : pieces) {
    piece.first_record = records;
    piece.first_line = first_line;
    records += piece.records;
    first_line += piece.lines;
  }
  lines_before_ = first_line - 1;
  for (NumberColumns::Column& column : table_.columns) column.resize(records);
  if (line_numbers_) table_.line.resize(records);

  // Second pass: parse each piece straight into its rows of the columns.
  detail::ParallelErrors errors;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads_)
  for (std::ptrdiff_t i = 0; i < count; ++i)
    errors.run([&] {
      Piece& piece = pieces[std::size_t(i)];
      std::vector<double> row(column_count);
      std::size_t line = piece.first_line, record = piece.first_record;
      for_each_line(piece.text, [&](const char* begin, const char* end) {
        if (piece.error_line == 0 && is_record(begin, end)) {
          if (std::optional<std::string> error =
                  parse_record(begin, end, row.data(), column_count)) {
            piece.error_line = line;
            piece.error = std::move(*error);
          } else {
            for (std::size_t k = 0; k < column_count; ++k) table_.columns[k][record] = row[k];
            if (line_numbers_) table_.line[record] = line;
            ++record;
          }
        }
        ++line;
      });
    });
  errors.rethrow_if_failed();

  // Pieces are in input order: the first one with an error has the first
  // malformed line.
  for (const Piece& piece : pieces)
    if (piece.error_line != 0)
      throw CommandError(ExitStatus::usage_error,
                         source_ + ":" + std::to_string(piece.error_line) + ": " + piece.error);
}

}  // namespace

TextInput::TextInput(const std::string& path) {
  if (path == "-") {
    name_ = "<stdin>";
    descriptor_ = STDIN_FILENO;
    return;
  }
  name_ = path;
  descriptor_ = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (descriptor_ < 0)
    throw CommandError(ExitStatus::io_error, "cannot open " + path + ": " + std::strerror(errno));
  owns_descriptor_ = true;
}

TextInput::~TextInput() {
  if (owns_descriptor_) close(descriptor_);
}

void TextInput::read_lines(const std::function<void(std::string_view lines)>& on_lines) {
  struct stat before {};
  if (fstat(descriptor_, &before) != 0) fail_to_read(name_, errno);
  if (S_ISDIR(before.st_mode)) fail_to_read(name_, EISDIR);
  // Where reading starts: standard input may be a file already partly read
  // (`{ read -r header; pwcontact contact; } < file`), whose rest is the
  // input. (Not seekable, a pipe: 0.)
  const off_t start = S_ISREG(before.st_mode) ? lseek(descriptor_, 0, SEEK_CUR) : 0;
  const std::size_t expected = start > 0 && start <= before.st_size
                                   ? std::size_t(before.st_size - start)
                                   : std::size_t(before.st_size);

  // Read in blocks through one buffer, never mapped: memory stays that of a
  // block whatever the size of the input, and a file that shrinks while it
  // is read is an error below, not a SIGBUS. Blocks are handed over full,
  // not per read(), which yields at most 64 KiB from a pipe: each block is
  // parsed in parallel pieces, and that only pays for blocks of some MiB.
  // (Uninitialised: zeroing 16 MiB would cost more than a small input's reading.)
  const std::unique_ptr<char[]> storage(new char[block_bytes]);
  struct Buffer {
    char* data_;
    std::size_t size_;
    char* data() const { return data_; }
    std::size_t size() const { return size_; }
  } buffer{storage.get(), block_bytes};
  std::size_t filled = 0, total = 0;
  std::size_t lines_before = 0;  // whole lines handed over, for the message below
  for (;;) {
    const ssize_t got = read(descriptor_, buffer.data() + filled, buffer.size() - filled);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) fail_to_read(name_, errno);
    if (got == 0) break;
    filled += std::size_t(got);
    total += std::size_t(got);
    if (filled < buffer.size()) continue;
    const void* last_newline = memrchr(buffer.data(), '\n', filled);
    if (!last_newline)
      throw CommandError(ExitStatus::usage_error, name_ + ":" + std::to_string(lines_before + 1) +
                                                      ": line longer than " +
                                                      std::to_string(block_bytes >> 20) + " MiB");
    const std::size_t whole =
        std::size_t(static_cast<const char*>(last_newline) - buffer.data()) + 1;
    const std::string_view lines(buffer.data(), whole);
    on_lines(lines);
    lines_before += std::size_t(std::count(lines.begin(), lines.end(), '\n'));
    std::memmove(buffer.data(), buffer.data() + whole, filled - whole);
    filled -= whole;
  }
  if (filled > 0) on_lines(std::string_view(buffer.data(), filled));
  // A regular file that changed size while it was read (truncated,
  // appended to) was not read as one text. (Files that report no size, as
  // those of /proc, are read as they come.)
  struct stat after {};
  if (S_ISREG(before.st_mode) && before.st_size > 0 &&
      (fstat(descriptor_, &after) != 0 || after.st_size != before.st_size || total != expected))
    throw CommandError(ExitStatus::io_error,
                       "cannot read " + name_ + ": the file changed while it was read (" +
                           std::to_string(expected) + " bytes to read when opened, " +
                           std::to_string(total) + " read)");
}

NumberColumns read_number_columns(TextInput& input, std::size_t column_count, int threads,
                                  bool line_numbers) {
  ColumnsParser parser(input.name(), column_count, threads, line_numbers);
  input.read_lines([&parser](std::string_view lines) { parser.parse(lines); });
  return parser.take();
}

NumberColumns parse_number_columns(std::string_view text, std::size_t column_count, int threads,
                                   bool line_numbers, const std::string& source) {
  ColumnsParser parser(source, column_count, threads, line_numbers);
  parser.parse(text);
  return parser.take();
}

void for_each_number_block(TextInput& input, std::size_t column_count, int threads,
                           bool line_numbers,
                           const std::function<void(NumberColumns& block)>& on_block) {
  ColumnsParser parser(input.name(), column_count, threads, line_numbers);
  input.read_lines([&](std::string_view lines) {
    parser.clear();
    parser.parse(lines);
    if (parser.table().records() > 0) on_block(parser.table());
  });
}

}  // namespace pwcontact::cli
