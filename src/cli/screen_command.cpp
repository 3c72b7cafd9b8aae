// `pwcontact screen`: every pair of a scene of ellipsoids with mu < cutoff,
// from a file of particles.
#include <omp.h>

#include <cstdio>
#include <stdexcept>

#include "cli/number_table.hpp"
#include "cli/screen_summary.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"

namespace pwcontact::cli {
namespace {

// The two particle formats: x y z and Q (6 numbers, upper triangle,
// row-major), or x y z, semi-axes a b c and a unit quaternion w x y z.
enum class ParticleFormat { q, axes };
const char* format_name(ParticleFormat f) noexcept { return f == ParticleFormat::q ? "q" : "axes"; }
std::size_t numbers_per_particle(ParticleFormat f) { return f == ParticleFormat::q ? 9 : 10; }

struct ScreenCommandOptions {
  Box box = Box::open();
  double cutoff = 1;
  ParticleFormat format = ParticleFormat::q;
  bool with_mu2 = false;
  int threads = 0;
  std::string input = "-";
  std::string output = "-";
};

// "LX,LY,LZ": the lengths of --box=LX,LY,LZ.
Box parse_box(std::string_view text) {
  const std::string whole(text);
  double length[3];
  for (int a = 0; a < 3; ++a) {
    const std::size_t comma = text.find(',');
    if ((a < 2) != (comma != std::string_view::npos))
      throw std::invalid_argument("'" + whole +
                                  "' is not three lengths LX,LY,LZ (or give them as --box LX LY LZ)");
    length[a] = parse_positive_number(text.substr(0, comma));
    text = a < 2 ? text.substr(comma + 1) : std::string_view();
  }
  return Box::periodic_box(length[0], length[1], length[2]);
}

OptionParser screen_parser(ScreenCommandOptions& options) {
  OptionParser parser(
      "screen",
      "Finds every pair of ellipsoids in FILE (standard input if FILE is absent or -) "
      "with mu < cutoff: with cutoff 1 the overlapping pairs, with a cutoff above 1 a "
      "neighbour list with a skin (mu scales both ellipsoids about their centres).\n\n"
      "Input: one ellipsoid per line. --format q: x y z q[0..5] (9 numbers: the centre, "
      "then Q = sum a_i^2 v_i v_i^T as its upper triangle, row-major: Q00 Q01 Q02 Q11 "
      "Q12 Q22); --format axes: x y z a b c qw qx qy qz (10 numbers: the centre, the "
      "semi-axes along the body axes, and the unit quaternion of the rotation; it is "
      "normalised). Blank lines and lines starting with '#' are skipped. A line that "
      "does not hold the format's numbers, a non-finite number, or an ellipsoid whose Q "
      "is not positive definite stops the run with its line (exit status 2, nothing "
      "written).\n\n"
      "Output: one pair per line, 'i j' (0-based indices of the ellipsoids in input "
      "order, i < j), and with --with-mu2 'i j mu2' (17 significant digits), sorted by "
      "i then j whatever the thread count. Pairs are decided by the bounding spheres, "
      "by their projections on the line of centres and by the inscribed spheres where "
      "they can be, pairs of spheres and pairs of one form (identical and aligned) in "
      "closed form, the rest by "
      "the batch path's certified overlap answers (or mu^2); the answer agrees with "
      "mu^2 < cutoff^2 whenever "
      "|mu^2 - cutoff^2| > 1e-9 cutoff^2.\n\n"
      "A summary goes to standard error: particles, candidate pairs from the cell "
      "lists, decided by the prefilters, solved, found, the time of each stage and the "
      "rates.",
      "[FILE]", 1, [&options](std::string_view file) { options.input = file; });
  parser.add_value({"--box"}, "LX LY LZ", "open boundaries",
                   "a periodic orthorhombic box with these edge lengths (three numbers, "
                   "positive and finite; or --box=LX,LY,LZ), pairs by the minimum image "
                   "convention; it must be at least twice the largest reach cutoff * 2 R_max "
                   "along every axis",
                   // Only the --box=LX,LY,LZ form reaches here (take_box takes the other).
                   [&options](std::string_view value) { options.box = parse_box(value); });
  parser.add_value({"--cutoff"}, "MU", "1", "a pair is found when mu < MU; positive and finite",
                   [&options](std::string_view value) { options.cutoff = parse_cutoff(value); });
  add_choice(parser, "--format",
             Choices<ParticleFormat>{{ParticleFormat::q, ParticleFormat::axes}, format_name},
             options.format, "how each line gives an ellipsoid (see Input)");
  parser.add_flag({"--with-mu2"},
                  "also write mu^2 of every pair found (the inscribed spheres then decide "
                  "nothing: every pair not found apart is solved, or taken in closed form)",
                  [&options] { options.with_mu2 = true; });
  add_threads_option(parser, options.threads, "the pairs");
  add_output_option(parser, options.output, "the pairs");
  return parser;
}

std::string screen_options_help() {
  ScreenCommandOptions options;
  return screen_parser(options).help();
}

// "--box LX LY LZ" takes three arguments: taken out here, before the parser
// (which gives every option one value) sees the rest.
Arguments take_box(const Arguments& arguments, ScreenCommandOptions& options,
                   const OptionParser& parser) {
  Arguments rest;
  for (std::size_t k = 0; k < arguments.size(); ++k) {
    if (arguments[k] == "--") {
      rest.insert(rest.end(), arguments.begin() + std::ptrdiff_t(k), arguments.end());
      break;
    }
    if (arguments[k] != "--box") {
      rest.push_back(arguments[k]);
      continue;
    }
    if (k + 3 >= arguments.size()) parser.fail("option --box: needs three lengths, LX LY LZ");
    double length[3];
    for (int a = 0; a < 3; ++a) {
      try {
        length[a] = parse_positive_number(arguments[k + 1 + std::size_t(a)]);
      } catch (const std::invalid_argument& e) {
        parser.fail(std::string("option --box: ") + e.what());
      }
    }
    options.box = Box::periodic_box(length[0], length[1], length[2]);
    k += 3;
  }
  return rest;
}

// The particles of the input, a block at a time, each block stored in
// parallel: the reader's own memory is that of a block. A particle the store
// refuses stops the run with its index and line (the first one, whatever
// the thread count).
ParticleStore read_particles(const std::string& path, ParticleFormat format, int threads,
                             std::string& source) {
  TextInput input(path);
  source = input.name();
  ParticleStore particles;
  for_each_number_block(
      input, numbers_per_particle(format), threads, true, [&](NumberColumns& block) {
        const auto& c = block.columns;
        const std::size_t first = particles.size(), n = block.records();
        particles.resize(first + n);
        std::size_t bad = n;  // the first particle refused, n if none
        std::string message;
        const std::ptrdiff_t count = std::ptrdiff_t(n);
#pragma omp parallel for schedule(static) num_threads(threads)
        for (std::ptrdiff_t signed_i = 0; signed_i < count; ++signed_i) {
          const std::size_t i = std::size_t(signed_i);
          try {
            if (format == ParticleFormat::q)
              particles.set(first + i, {c[0][i], c[1][i], c[2][i]},
                            {c[3][i], c[4][i], c[5][i], c[6][i], c[7][i], c[8][i]});
            else
              particles.set_axes(first + i, {c[0][i], c[1][i], c[2][i]},
                                 {c[3][i], c[4][i], c[5][i]}, {c[6][i], c[7][i], c[8][i], c[9][i]});
          } catch (const std::exception& e) {
#pragma omp critical(pwcontact_read_particles)
            if (i < bad) {
              bad = i;
              message = e.what();
            }
          }
        }
        if (bad < n)
          throw CommandError(ExitStatus::usage_error,
                             source + ": ellipsoid " + std::to_string(first + bad) + " (line " +
                                 std::to_string(block.line[bad]) + "): " + message);
      });
  return particles;
}

// The arguments into `options`; false when help was asked for.
bool parse_screen(const Arguments& arguments, ScreenCommandOptions& options) {
  OptionParser parser = screen_parser(options);
  const Arguments rest = take_box(arguments, options, parser);
  return parser.parse(rest);
}

bool parse_screen_only(const Arguments& arguments) {
  ScreenCommandOptions options;
  return parse_screen(arguments, options);
}

ExitStatus run_screen(const Arguments& arguments) {
  ScreenCommandOptions options;
  if (!parse_screen(arguments, options)) {
    std::fputs(full_help(screen_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  const int threads = resolve_thread_count(options.threads);
  // PWCONTACT_ISA and the CPU, checked before the input is read: a bad value
  // is a usage error now rather than after the reading.
  resolve_instruction_set(Isa::automatic);
  OutputFile output(options.output);

  const Stopwatch reading;
  std::string source;
  const ParticleStore particles = read_particles(options.input, options.format, threads, source);
  const double read_seconds = reading.seconds();

  ScreenOptions screen_options;
  screen_options.cutoff = options.cutoff;
  screen_options.with_mu2 = options.with_mu2;
  screen_options.threads = threads;
  ScreenedPairs pairs;
  ScreenReport report;
  try {
    report = screen_pairs(particles, options.box, screen_options, pairs);
  } catch (const std::invalid_argument& e) {
    throw CommandError(ExitStatus::usage_error, e.what());
  }

  const Stopwatch writing;
  write_lines_in_order(output, pairs.size(), threads, [&](std::string& text, std::size_t k) {
    char line[2 * 12 + max_number_chars + 4];
    char* end = std::to_chars(line, line + 12, pairs.i[k]).ptr;
    *end++ = ' ';
    end = std::to_chars(end, end + 12, pairs.j[k]).ptr;
    if (options.with_mu2) {
      *end++ = ' ';
      end = write_number(end, pairs.mu2[k]);
    }
    *end++ = '\n';
    text.append(line, end);
  });
  output.commit();
  std::fprintf(stderr, "pwcontact screen: %zu ellipsoids from %s (read in %s), %zu pairs to %s "
               "(written in %s)\n%s",
               particles.size(), source.c_str(), describe_seconds(read_seconds).c_str(),
               pairs.size(), output.name().c_str(), describe_seconds(writing.seconds()).c_str(),
               describe_screen(report, options.box, options.cutoff).c_str());
  return ExitStatus::success;
}

}  // namespace

const Subcommand screen_subcommand = {
    "screen", "every pair of a scene of ellipsoids with mu < cutoff (overlaps, neighbour lists)",
    screen_options_help, run_screen, parse_screen_only};

}  // namespace pwcontact::cli
