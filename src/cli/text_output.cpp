#include "cli/text_output.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>

#include "cli/command_line.hpp"
#include "cli/subcommands.hpp"

namespace pwcontact::cli {
namespace {

// Whether two stat results are one file (its device and inode).
bool same_file(const struct stat& a, const struct stat& b) {
  return a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}

[[noreturn]] void fail_to_write(const std::string& name, int error) {
  throw CommandError(ExitStatus::io_error, "cannot write " + name + ": " + std::strerror(error));
}

std::string formatted(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

// The temporary files being written (at most two: the output and a GSD
// file beside it), for the handlers below: a signal or std::terminate must
// not leave them behind either. Plain storage, read by a signal handler
// (which may only call async-signal-safe functions: unlink, signal, raise).
constexpr int pending_slots = 2;
char pending_temporary[pending_slots][4096];
volatile std::sig_atomic_t pending[pending_slots] = {0, 0};

void remove_pending() {
  for (int slot = 0; slot < pending_slots; ++slot)
    if (pending[slot]) unlink(pending_temporary[slot]);
}

extern "C" void remove_pending_and_reraise(int signal_number) {
  remove_pending();
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

void remove_pending_and_abort() {
  remove_pending();
  std::abort();
}

// Registers `path` as a pending temporary file in a free slot (-1: none
// free, or the path too long: then not removed by the handlers), installing
// the handlers on first use.
int set_pending(const std::string& path) {
  static const bool installed = [] {
    // (A signal the caller set to be ignored, as nohup does SIGHUP and a
    // shell SIGINT for a background job, stays ignored: handled, it ended
    // the run that was meant to survive it.)
    for (int signal_number : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
      struct sigaction current {};
      if (sigaction(signal_number, nullptr, &current) == 0 && current.sa_handler == SIG_IGN)
        continue;
      std::signal(signal_number, remove_pending_and_reraise);
    }
    std::set_terminate(remove_pending_and_abort);
    return true;
  }();
  (void)installed;
  if (path.size() >= sizeof pending_temporary[0]) return -1;
  for (int slot = 0; slot < pending_slots; ++slot)
    if (!pending[slot]) {
      std::memcpy(pending_temporary[slot], path.c_str(), path.size() + 1);
      pending[slot] = 1;
      return slot;
    }
  return -1;
}

void clear_pending(int slot) {
  if (slot >= 0) pending[slot] = 0;
}

}  // namespace

void ensure_standard_descriptors() {
  // open() returns the lowest free descriptor: a closed 0, 1 or 2 is filled
  // with /dev/null, so that no file opened later takes its place (an output
  // file on descriptor 0 would be read back as the input).
  for (int descriptor = 0; descriptor <= 2; ++descriptor) {
    if (fcntl(descriptor, F_GETFD) >= 0 || errno != EBADF) continue;
    const int opened = open("/dev/null", descriptor == 0 ? O_RDONLY : O_WRONLY);
    if (opened != descriptor) std::_Exit(int(ExitStatus::io_error));
  }
}

bool same_destination(const std::string& a, const std::string& b) {
  if (a == b) return true;
  auto identity = [](const std::string& path, struct stat& out) {
    return path == "-" ? fstat(fileno(stdout), &out) == 0 : stat(path.c_str(), &out) == 0;
  };
  struct stat sa {
  }, sb{};
  if (identity(a, sa) && identity(b, sb)) return same_file(sa, sb);
  if (a == "-" || b == "-") return false;
  std::error_code ignored;
  const auto normal_a = std::filesystem::weakly_canonical(std::filesystem::absolute(a), ignored);
  const auto normal_b = std::filesystem::weakly_canonical(std::filesystem::absolute(b), ignored);
  return !normal_a.empty() && normal_a == normal_b;
}

OutputFile::OutputFile(const std::string& path) {
  if (path == "-") {
    name_ = "<stdout>";
    file_ = stdout;
    return;
  }
  name_ = path;
  struct stat existing {};
  const bool exists = stat(path.c_str(), &existing) == 0;
  // The file standard output or error already is (-o /dev/stdout while the
  // shell appends to a log): written through that descriptor, as it is
  // open, not replaced by a new file (which lost what the log held).
  for (FILE* standard : {stdout, stderr}) {
    struct stat open_file {};
    if (exists && fstat(fileno(standard), &open_file) == 0 && same_file(open_file, existing)) {
      file_ = standard;
      return;
    }
  }
  if (exists && !S_ISREG(existing.st_mode)) {
    // A device or a pipe (/dev/null, a FIFO) is written in place: renaming
    // over it would replace the device itself. (A directory fails here.)
    file_ = std::fopen(path.c_str(), "wb");
    if (!file_) fail_to_write(name_, errno);
    owns_file_ = true;
    return;
  }

  // An existing file is replaced where it really is (through symbolic
  // links), keeping its permissions; a new one gets those of any new file.
  std::error_code error;
  target_path_ = exists ? std::filesystem::canonical(path, error).string() : path;
  if (error) target_path_ = path;
  const mode_t mask = umask(0);
  umask(mask);
  const mode_t mode = exists ? (existing.st_mode & 07777) : (0666 & ~mask);

  // A hidden name beside the target: rename() is atomic only within one file system.
  const std::filesystem::path target(target_path_);
  const std::filesystem::path directory = target.parent_path();
  std::string pattern = (directory.empty() ? std::string() : directory.string() + "/") + "." +
                        target.filename().string() + ".tmp-XXXXXX";
  // Created and registered with the handled signals blocked: a signal that
  // arrives in between (it did, under AddressSanitizer's slower start) is
  // delivered once the handlers know the file, which they then remove.
  sigset_t handled, previous;
  sigemptyset(&handled);
  for (int signal_number : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) sigaddset(&handled, signal_number);
  pthread_sigmask(SIG_BLOCK, &handled, &previous);
  const int descriptor = mkstemp(pattern.data());
  const int mkstemp_error = errno;
  if (descriptor >= 0) {
    temporary_path_ = pattern;
    pending_slot_ = set_pending(temporary_path_);
  }
  pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  if (descriptor < 0) fail_to_write(name_, mkstemp_error);
  fchmod(descriptor, mode);
  file_ = fdopen(descriptor, "wb");
  if (!file_) {
    const int fdopen_error = errno;
    close(descriptor);
    unlink(temporary_path_.c_str());
    clear_pending(pending_slot_);
    fail_to_write(name_, fdopen_error);
  }
  owns_file_ = true;
}

OutputFile::~OutputFile() {
  if (!owns_file_ || committed_) return;
  std::fclose(file_);
  if (!temporary_path_.empty()) unlink(temporary_path_.c_str());
  clear_pending(pending_slot_);
}

void OutputFile::write(std::string_view text) noexcept {
  if (error_ == 0 && std::fwrite(text.data(), 1, text.size(), file_) != text.size())
    error_ = errno ? errno : EIO;
}

void OutputFile::commit() {
  if (error_ == 0 && std::fflush(file_) != 0) error_ = errno;
  if (owns_file_) {
    // fclose also reports delayed write errors (e.g. a full disk).
    if (std::fclose(file_) != 0 && error_ == 0) error_ = errno;
    committed_ = true;  // closed either way
  }
  if (error_ == 0 && !temporary_path_.empty() &&
      std::rename(temporary_path_.c_str(), target_path_.c_str()) != 0)
    error_ = errno;
  clear_pending(pending_slot_);  // renamed into place, or removed below
  if (error_ == 0) return;
  if (!temporary_path_.empty()) unlink(temporary_path_.c_str());
  fail_to_write(name_, error_);
}

std::string wrap_words(std::string_view text, std::size_t indent, std::size_t width) {
  std::string out;
  std::size_t column = indent;
  bool line_start = true;
  for (std::size_t start = 0; start <= text.size();) {
    const std::size_t end = std::min(text.find_first_of(" \n", start), text.size());
    const std::string_view word = text.substr(start, end - start);
    if (!word.empty()) {
      if (!line_start && column + 1 + word.size() > width) {
        out += "\n" + std::string(indent, ' ');
        column = indent;
      } else if (!line_start) {
        out += ' ';
        ++column;
      }
      out += word;
      column += word.size();
      line_start = false;
    }
    if (end < text.size() && text[end] == '\n') {
      out += '\n';
      column = 0;
      line_start = true;
      if (end + 1 < text.size() && text[end + 1] != '\n') {
        out.append(indent, ' ');
        column = indent;
      }
    }
    start = end + 1;
  }
  return out;
}

std::string describe_seconds(double seconds) {
  if (seconds >= 1) return formatted("%.2f s", seconds);
  if (seconds >= 1e-3) return formatted("%.1f ms", seconds * 1e3);
  return formatted("%.0f us", seconds * 1e6);
}

std::string describe_rate(std::size_t pairs, double seconds) {
  if (!(seconds > 0)) return "n/a";
  const double rate = double(pairs) / seconds;
  if (rate >= 1e6) return formatted("%.3g M pairs/s", rate / 1e6);
  if (rate >= 1e3) return formatted("%.3g k pairs/s", rate / 1e3);
  return formatted("%.3g pairs/s", rate);
}

std::string describe_status_counts(const BatchReport& report) {
  std::string text;
  for (int s = 0; s < status_count; ++s)
    if (report.status_counts[s] != 0)
      text += std::string(text.empty() ? "" : ", ") + status_name(Status(s)) + " " +
              std::to_string(report.status_counts[s]);
  return text.empty() ? "none" : text;
}

std::string status_code_table() {
  constexpr std::size_t description_column = 31, width = 79;
  std::string text =
      "Status codes (the status column of 'pwcontact contact' output; with --scalar\n"
      "every valid answer is the reference path's own, status 0):\n";
  for (int s = 0; s < status_count; ++s) {
    std::string row = "  " + std::to_string(s) + "  " + status_name(Status(s));
    row.resize(std::max(description_column, row.size() + 2), ' ');
    text += row + wrap_words(status_description(Status(s)), description_column, width) + "\n";
  }
  return text;
}

std::string exit_status_text() {
  return "Exit status:\n"
         "  0  success (also when some pairs have an invalid status)\n"
         "  1  an input cannot be read or the output cannot be written\n"
         "  2  bad command line, malformed input line, or an instruction set\n"
         "     this CPU lacks\n"
         "  3  mc only: the packing fraction was not reached within the sweeps\n"
         "     allowed, or a screen found an overlap (nothing written)\n";
}

std::string full_help(const Subcommand& subcommand) {
  return subcommand.options_help() + "\n" + status_code_table() + "\n" + exit_status_text();
}

}  // namespace pwcontact::cli
