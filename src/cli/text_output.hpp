// What the command line writes: numbers formatted fast and locale-free,
// result files that appear whole or not at all, and the shared pieces of
// help text and summaries (status codes, exit statuses, times and rates).
#pragma once

#include <unistd.h>

#include <omp.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

#include "parallel_errors.hpp"
#include "pwcontact/batch.hpp"

namespace pwcontact::cli {

// Room for one number in the general format with 17 significant digits:
// sign, 17 digits, point, and an exponent such as "e-308".
inline constexpr std::size_t max_number_chars = 32;

// Writes `value` with 17 significant digits (shortest of fixed and
// scientific, as printf's %.17g) and returns the end. Every NaN is written
// as "nan": its sign bit carries no meaning here.
template <class T>
char* write_number(char* out, T value) {
  if (std::isnan(value)) {
    constexpr std::string_view nan = "nan";
    return std::copy(nan.begin(), nan.end(), out);
  }
  return std::to_chars(out, out + max_number_chars, value, std::chars_format::general, 17).ptr;
}

// Fills a closed standard descriptor (0, 1 or 2) with /dev/null, so that no
// file opened later takes its number; called first thing in main().
void ensure_standard_descriptors();

// Whether two output paths ("-": standard output) name one file: one
// existing file (through a link, /dev/stdout beside -), or the same path
// once made absolute and normal (./name beside name, before either exists).
bool same_destination(const std::string& a, const std::string& b);

// Where the results go: standard output ("-"), or a file that is written
// under a temporary name in the same directory and renamed into place by
// commit(), so that a failed run never leaves a partial file behind (devices
// and pipes, which cannot be replaced, are written directly). The temporary
// file is also removed when SIGINT, SIGTERM, SIGHUP or SIGQUIT ends the
// program, or std::terminate.
class OutputFile {
 public:
  // Throws CommandError(io_error) when the file cannot be created.
  explicit OutputFile(const std::string& path);
  ~OutputFile();  // removes the temporary file unless committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  const std::string& name() const noexcept { return name_; }

  // Failures are remembered and reported by commit(), so that writing needs
  // no exception handling (which must not cross an OpenMP region).
  void write(std::string_view text) noexcept;

  // Flushes, closes and (for a file) renames into place.
  // Throws CommandError(io_error) if anything failed.
  void commit();

 private:
  std::string name_;            // the path as given, or "<stdout>"
  std::string target_path_;     // where the temporary file is renamed to
  std::string temporary_path_;  // empty when writing directly
  std::FILE* file_ = nullptr;
  bool owns_file_ = false;  // false for standard output
  int error_ = 0;           // errno of the first failed write
  bool committed_ = false;
  int pending_slot_ = -1;  // registered for removal on a signal
};

// Writes the lines produced by format_line(std::string& text, std::size_t i)
// for i = 0 .. lines - 1, in order. Blocks of lines are formatted in parallel
// and written one after the other as they are ready.
template <class FormatLine>
void write_lines_in_order(OutputFile& output, std::size_t lines, int threads,
                          const FormatLine& format_line) {
  constexpr std::size_t lines_per_block = 16384;
  const std::size_t blocks = (lines + lines_per_block - 1) / lines_per_block;
  detail::ParallelErrors errors;  // (formatting allocates)
#pragma omp parallel num_threads(threads)
  {
    std::string text;
#pragma omp for ordered schedule(static, 1)
    for (std::size_t block = 0; block < blocks; ++block) {
      errors.run([&] {
        text.clear();
        const std::size_t end = std::min(lines, (block + 1) * lines_per_block);
        for (std::size_t i = block * lines_per_block; i < end; ++i) format_line(text, i);
      });
#pragma omp ordered
      if (!errors.failed()) output.write(text);
    }
  }
  errors.rethrow_if_failed();
}

// Wall-clock time since construction.
class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// A progress bar on standard error, shown only on a terminal and only once a
// stage has taken more than a second.
class ProgressBar {
 public:
  explicit ProgressBar(const char* stage) : stage_(stage), shown_(isatty(STDERR_FILENO) == 1) {}
  // With a note after the percentage (e.g. the acceptance rate).
  ~ProgressBar() {
    if (drawn_) std::fputs("\r\033[K", stderr);
  }
  void update(double fraction, const std::string& note = {}) {
    if (!shown_ || clock_.seconds() < 1) return;
    constexpr int width = 40;
    const int filled = int(std::clamp(fraction, 0.0, 1.0) * width);
    std::fprintf(stderr, "\r%-28s [%.*s%*s] %3d %% %s\033[K", stage_, filled,
                 "########################################", width - filled, "",
                 int(fraction * 100), note.c_str());
    std::fflush(stderr);
    drawn_ = true;
  }

 private:
  const char* stage_;
  bool shown_, drawn_ = false;
  Stopwatch clock_;
};

// "0.52 s", "12.3 ms", "45 us".
std::string describe_seconds(double seconds);
// "24.7 M pairs/s", or "n/a" when the time was too short to measure.
std::string describe_rate(std::size_t pairs, double seconds);
// The statuses that occurred, with their counts: "ok 998, non_finite_input 2".
std::string describe_status_counts(const BatchReport& report);

// `text` with its words on lines of at most `width` columns, continuation
// lines indented by `indent` spaces (the first line is assumed to start at
// column `indent` already). A '\n' in `text` forces a line break.
std::string wrap_words(std::string_view text, std::size_t indent, std::size_t width);

// Help text: every status code with its number, name and meaning.
std::string status_code_table();
// Help text: what the exit statuses mean.
std::string exit_status_text();

}  // namespace pwcontact::cli
