// Reading tables of numbers: one record per line, a fixed count of numbers
// separated by blanks, blank lines and '#' comment lines skipped. Pairs
// (15 numbers) and particles (9 or 10) are both read this way.
//
// Inputs of millions of lines are common, so the text is parsed with
// std::from_chars in parallel pieces straight into column storage, ready
// to be moved into a structure-of-arrays batch.
#pragma once

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "pwcontact/batch.hpp"

namespace pwcontact::cli {

// A text input: a file, or standard input for "-".
class TextInput {
 public:
  // Throws CommandError(io_error) when the input cannot be opened.
  explicit TextInput(const std::string& path);
  ~TextInput();
  TextInput(const TextInput&) = delete;
  TextInput& operator=(const TextInput&) = delete;

  const std::string& name() const noexcept { return name_; }  // the path, or "<stdin>"

  // Hands the whole text to `on_lines` in consecutive blocks of whole lines
  // of at most block_bytes (only the last may lack its '\n'), read through
  // one reused buffer, so that memory does not grow with the size of the
  // text. Throws CommandError(io_error) when reading fails or a regular file
  // changes size while it is read, CommandError(usage_error) for a line
  // longer than a block; exceptions from `on_lines` pass through.
  void read_lines(const std::function<void(std::string_view lines)>& on_lines);

  static constexpr std::size_t block_bytes = std::size_t(16) << 20;

 private:
  std::string name_;
  int descriptor_ = -1;
  bool owns_descriptor_ = false;
};

// Column k holds the k-th number of every record, records in input order,
// each on a cache line as PairBatch's columns (they are swapped into one).
struct NumberColumns {
  using Column = PairBatch<double>::Column;
  std::vector<Column> columns;
  std::vector<std::size_t> line;  // 1-based line of every record, when asked for
  std::size_t records() const { return columns.empty() ? 0 : columns.front().size(); }
};

// Reads every non-blank, non-comment line of `input` as exactly
// `column_count` numbers. Numbers are what std::from_chars reads in the
// general format, plus a leading '+'; "nan" and "inf" (any case) are numbers,
// and values beyond double range become +-inf or 0 as strtod rounds them.
// Blanks are spaces and tabs (and a carriage return, for files with CRLF
// line ends). A comment line starts with '#' after optional blanks.
//
// Throws CommandError(usage_error) for the first malformed line, as
// "<input name>:<line>: <what is wrong>", and CommandError(io_error) when
// reading fails.
// With line_numbers, NumberColumns::line gives each record's line (for
// messages about a record that is well formed but not acceptable).
NumberColumns read_number_columns(TextInput& input, std::size_t column_count, int threads,
                                  bool line_numbers = false);

// The same from text in memory (`source` names it in messages).
NumberColumns parse_number_columns(std::string_view text, std::size_t column_count, int threads,
                                   bool line_numbers, const std::string& source);

// The same, a block of records at a time (the records of at most
// TextInput::block_bytes of text, in input order; line numbers count from
// the start of the input): memory stays that of one block. `block` is
// reused for the next one.
void for_each_number_block(TextInput& input, std::size_t column_count, int threads,
                           bool line_numbers,
                           const std::function<void(NumberColumns& block)>& on_block);

}  // namespace pwcontact::cli
