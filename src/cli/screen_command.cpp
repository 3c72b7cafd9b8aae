// `pwcontact screen`: every pair of a scene of ellipsoids with mu < cutoff,
// from a file of particles.
#include <omp.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/number_table.hpp"
#include "cli/screen_command.hpp"
#include "cli/screen_summary.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"
#include "pwcontact/scene_files.hpp"

namespace pwcontact::cli {
namespace {

// Where the scene comes from: text, one particle per line (q: x y z and Q,
// 6 numbers, upper triangle, row-major; axes: x y z, semi-axes a b c and a
// unit quaternion w x y z; ellipse: x y a b theta), or a simulation file.
enum class SceneFormat { q, axes, ellipse, gsd, lammps_data, lammps_dump };
const char* format_name(SceneFormat f) noexcept {
  switch (f) {
    case SceneFormat::q: return "q";
    case SceneFormat::axes: return "axes";
    case SceneFormat::ellipse: return "ellipse";
    case SceneFormat::gsd: return "gsd";
    case SceneFormat::lammps_data: return "lammps-data";
    case SceneFormat::lammps_dump: return "lammps-dump";
  }
  return "?";
}
bool is_text(SceneFormat f) {
  return f == SceneFormat::q || f == SceneFormat::axes || f == SceneFormat::ellipse;
}
std::size_t numbers_per_particle(SceneFormat f) {
  return f == SceneFormat::q ? 9 : f == SceneFormat::axes ? 10 : 5;
}

// What is written: the pairs, the number of pairs of each particle, or each
// particle's neighbours.
enum class ScreenOutput { pairs, counts, neighbors };
const char* output_name(ScreenOutput o) noexcept {
  return o == ScreenOutput::pairs ? "pairs" : o == ScreenOutput::counts ? "counts" : "neighbors";
}

struct ScreenCommandOptions {
  std::vector<double> box;  // --box as given: lengths, then tilts
  double cutoff = 1;
  std::optional<SceneFormat> format;  // from the file's name when not given
  std::optional<std::int64_t> frame;  // -1, the last, when not given
  std::optional<LammpsColumns> columns;
  ScreenOutput outputs = ScreenOutput::pairs;
  bool with_mu2 = false;
  int threads = 0;
  std::string input = "-";
  std::string output = "-";
  std::string gsd_output;  // --write-gsd: the frame with the counts
};

// A finite number (a tilt may be negative or zero).
bool parse_finite(std::string_view text, double& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc() && end == text.data() + text.size() && std::isfinite(value);
}

// "LX,LY,LZ[,XY,XZ,YZ]": the numbers of --box=... .
std::vector<double> parse_box_numbers(std::string_view text) {
  std::vector<double> numbers;
  const std::string whole(text);
  while (true) {
    const std::size_t comma = text.find(',');
    double value = 0;
    if (!parse_finite(text.substr(0, comma), value) || numbers.size() == 6)
      throw std::invalid_argument("'" + whole +
                                  "' is not LX,LY,LZ[,XY,XZ,YZ] or LX,LY[,XY] (finite numbers)");
    numbers.push_back(value);
    if (comma == std::string_view::npos) return numbers;
    text = text.substr(comma + 1);
  }
}

// "--columns x=xu,shapex=c_s[1],...": the dump's column of each quantity.
LammpsColumns parse_columns(std::string_view text) {
  static const char* const names[10] = {"x",      "y",     "z",     "shapex", "shapey",
                                        "shapez", "quatw", "quati", "quatj",  "quatk"};
  LammpsColumns columns;
  if (text.empty())  // (--columns= was taken as the usual names, silently)
    throw std::invalid_argument("needs NAME=COLUMN,... (without it, the usual names are taken)");
  std::string* targets[10] = {
      &columns.position[0],   &columns.position[1],  &columns.position[2],   &columns.shape[0],
      &columns.shape[1],      &columns.shape[2],     &columns.quaternion[0], &columns.quaternion[1],
      &columns.quaternion[2], &columns.quaternion[3]};
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    const std::size_t equals = item.find('=');
    std::string_view name = item.substr(0, equals);
    const std::string_view column =
        equals == std::string_view::npos ? std::string_view() : item.substr(equals + 1);
    int k = 0;
    while (k < 10 && name != names[k]) ++k;
    if (k == 10 || column.empty())
      throw std::invalid_argument("'" + std::string(item) +
                                  "' is not NAME=COLUMN with NAME one of x y z shapex shapey "
                                  "shapez quatw quati quatj quatk");
    *targets[k] = std::string(column);
    text = comma == std::string_view::npos ? std::string_view() : text.substr(comma + 1);
  }
  return columns;
}

OptionParser screen_parser(ScreenCommandOptions& options) {
  OptionParser parser(
      "screen",
      "Finds every pair of ellipsoids in FILE (standard input if FILE is absent or -) "
      "with mu < cutoff: with cutoff 1 the overlapping pairs, with a cutoff above 1 a "
      "neighbour list with a skin (mu scales both ellipsoids about their centres).\n\n"
      "Input, by --format (else from FILE's name: .gsd gsd, .data lammps-data, .dump and "
      ".lammpstrj lammps-dump, anything else q). Text, one particle per line: q: x y z "
      "q[0..5] (9 numbers: the centre, then Q = sum a_i^2 v_i v_i^T as its upper "
      "triangle, row-major: Q00 Q01 Q02 Q11 Q12 Q22); axes: x y z a b c qw qx qy qz (10 "
      "numbers: the centre, the semi-axes along the body axes, and the unit quaternion of "
      "the rotation; it is normalised); ellipse: x y a b theta (5 numbers: an ellipse in "
      "the plane, semi-axes a and b, the a axis at theta radians from x; solved exactly "
      "as the ellipsoid a, b, min(a, b) in the z = 0 plane). Blank lines and lines "
      "starting with '#' are skipped. Simulation files: gsd: HOOMD-blue's GSD (the frame's "
      "particles/position, orientation, typeid, types and type_shapes, Ellipsoid a b c, "
      "Sphere diameter or, in 2D, Ellipsoid or Ellipse a b; configuration/box and dimensions, 2 "
      "for ellipses; absent chunks "
      "as the schema defines them, from frame 0); lammps-data: a LAMMPS data file of "
      "atom_style ellipsoid (the Ellipsoids section's shapes are diameters); lammps-dump: "
      "a LAMMPS text dump (dump custom) with positions, shapes (diameters) and "
      "quaternions, columns found by name (x y z or xu yu zu, shapex shapey shapez, "
      "quatw quati quatj quatk) or as --columns maps them. A malformed line or file, a "
      "truncated file, an unknown type, a zero semi-axis or a quaternion that cannot be "
      "normalised stops the run naming the line, frame or particle (exit status 2, "
      "nothing written).\n\n"
      "Output, by --outputs: pairs: one pair per line, 'i j' (0-based indices of the "
      "particles in the order of the input, i < j), and with --with-mu2 'i j mu2' (17 "
      "significant digits), sorted by i then j whatever the thread count; counts: one "
      "line per particle, the number of pairs it is in (with cutoff 1, its overlaps); "
      "neighbors: one line per particle, its neighbours in increasing order (both "
      "directions: j among i's and i among j's), with --with-mu2 each followed by mu2. "
      "Pairs are decided by the bounding spheres, by their projections on the line of "
      "centres and by the inscribed spheres where they can be, pairs of spheres and "
      "pairs of one form (identical and aligned) in closed form, the rest by the batch "
      "path's certified overlap answers (or mu^2); the answer agrees with mu^2 < "
      "cutoff^2 whenever |mu^2 - cutoff^2| > 1e-9 cutoff^2.\n\n"
      "A summary goes to standard error: particles, candidate pairs from the cell "
      "lists, decided by the prefilters, solved, found, the time of each stage and the "
      "rates.",
      "[FILE]", 1, [&options](std::string_view file) { options.input = file; });
  parser.add_value(
      {"--box"}, "LX LY LZ [XY XZ YZ]", "open boundaries",
      "for the text formats: a periodic box with these edge lengths (positive) "
      "and tilt factors (unitless, HOOMD-blue's convention: lattice vectors "
      "(LX, 0, 0), (XY LY, LY, 0), (XZ LZ, YZ LZ, LZ); LAMMPS's tilt lengths "
      "xy xz yz are XY = xy/LY, XZ = xz/LZ, YZ = yz/LZ), pairs by the minimum "
      "image convention; for ellipses LX LY [XY], periodic in the plane. Also "
      "--box=LX,LY,LZ[,XY,XZ,YZ]. The width of the box across each pair of "
      "faces must be more than twice the largest reach cutoff * 2 R_max (the bounding radii "
      "are rounded up by a few eps: a box of exactly twice is refused). "
      "Simulation files give their own box",
      // (take_box takes both forms, in order: this is for the help.)
      [&options](std::string_view value) { options.box = parse_box_numbers(value); });
  parser.add_value({"--cutoff"}, "MU", "1", "a pair is found when mu < MU; positive and finite",
                   [&options](std::string_view value) { options.cutoff = parse_cutoff(value); });
  const Choices<SceneFormat> formats{
      {SceneFormat::q, SceneFormat::axes, SceneFormat::ellipse, SceneFormat::gsd,
       SceneFormat::lammps_data, SceneFormat::lammps_dump},
      format_name};
  parser.add_value(
      {"--format"}, formats.names("|", "|"), "from FILE's name",
      "how FILE gives the particles (see Input)",
      [&options, formats](std::string_view text) { options.format = formats.parse(text); });
  parser.add_value({"--frame"}, "N", "-1, the last",
                   "the frame of a GSD file or LAMMPS dump to screen (0-based; negative "
                   "counts from the end)",
                   [&options](std::string_view text) {
                     options.frame =
                         parse_integer(text, -(std::int64_t(1) << 62), std::int64_t(1) << 62);
                   });
  parser.add_value({"--columns"}, "NAME=COLUMN,...", "the usual names",
                   "for a LAMMPS dump: the columns of the ITEM: ATOMS line that hold x y z "
                   "shapex shapey shapez quatw quati quatj quatk, e.g. "
                   "shapex=c_s[1],shapey=c_s[2],shapez=c_s[3] (the rest by their usual names)",
                   [&options](std::string_view text) { options.columns = parse_columns(text); });
  add_choice(parser, "--outputs",
             Choices<ScreenOutput>{
                 {ScreenOutput::pairs, ScreenOutput::counts, ScreenOutput::neighbors}, output_name},
             options.outputs, "what is written (see Output)");
  parser.add_flag({"--with-mu2"},
                  "also write mu^2 of every pair found (the inscribed spheres then decide "
                  "nothing: every pair not found apart is solved, or taken in closed form)",
                  [&options] { options.with_mu2 = true; });
  parser.add_value({"--write-gsd"}, "OUT", "none",
                   "with a gsd input: also write OUT, a GSD file of the frame screened (every "
                   "chunk it has or takes from frame 0) with log/particles/overlaps, the number "
                   "of pairs each particle is in, for OVITO to colour by (like -o, it appears "
                   "only when the run succeeds; - is standard output, when -o is a file)",
                   [&options](std::string_view path) {
                     if (path.empty()) throw std::invalid_argument("needs a file name");
                     options.gsd_output = path;
                   });
  add_threads_option(parser, options.threads, "the lines written");
  add_output_option(parser, options.output, "the output");
  return parser;
}

std::string screen_options_help() {
  ScreenCommandOptions options;
  return screen_parser(options).help();
}

// "--box LX LY LZ [XY XZ YZ]" takes up to six arguments: taken out here,
// before the parser (which gives every option one value) sees the rest. The
// numbers that follow --box are its own (a file named like a number can be
// given as ./NAME or after --).
Arguments take_box(const Arguments& arguments, ScreenCommandOptions& options,
                   const OptionParser& parser) {
  Arguments rest;
  for (std::size_t k = 0; k < arguments.size(); ++k) {
    if (arguments[k] == "--") {
      rest.insert(rest.end(), arguments.begin() + std::ptrdiff_t(k), arguments.end());
      break;
    }
    // (The --box=... form taken here too, in its place among the others:
    // left to the parser, it came after every spaced --box and always won.)
    if (arguments[k].rfind("--box=", 0) == 0) {
      try {
        options.box = parse_box_numbers(std::string_view(arguments[k]).substr(6));
      } catch (const std::invalid_argument& e) {
        parser.fail(std::string("option --box: ") + e.what());
      }
      continue;
    }
    if (arguments[k] != "--box") {
      rest.push_back(arguments[k]);
      continue;
    }
    options.box.clear();
    double value = 0;
    while (k + 1 < arguments.size() && options.box.size() < 6 &&
           parse_finite(arguments[k + 1], value)) {
      options.box.push_back(value);
      ++k;
    }
    if (options.box.empty())
      parser.fail("option --box: needs the box, LX LY LZ [XY XZ YZ] (LX LY [XY] for ellipses)");
  }
  return rest;
}

// The format FILE's name implies: .gsd, .data, .dump or .lammpstrj, else q.
SceneFormat format_from_name(const std::string& path) {
  auto ends_with = [&](std::string_view suffix) {
    return path.size() >= suffix.size() &&
           path.compare(path.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  if (ends_with(".gsd")) return SceneFormat::gsd;
  if (ends_with(".data")) return SceneFormat::lammps_data;
  if (ends_with(".dump") || ends_with(".lammpstrj")) return SceneFormat::lammps_dump;
  return SceneFormat::q;
}

// The box of --box for a text format, checked against what the format takes.
Box box_of(const ScreenCommandOptions& options, SceneFormat format, const OptionParser& parser) {
  const std::vector<double>& b = options.box;
  if (b.empty()) return Box::open();
  if (!is_text(format))
    parser.fail(std::string("option --box: a ") + format_name(format) + " file gives its own box");
  const bool ellipses = format == SceneFormat::ellipse;
  const std::size_t lengths = ellipses ? 2 : 3;
  if (!(b.size() == lengths || b.size() == 2 * lengths - (ellipses ? 1 : 0)))
    parser.fail(
        std::string("option --box: ") + std::to_string(b.size()) + " numbers; " +
        (ellipses ? "ellipses take LX LY or LX LY XY" : "expected LX LY LZ or LX LY LZ XY XZ YZ"));
  try {
    if (ellipses) return Box::two_dimensional_box(b[0], b[1], b.size() == 3 ? b[2] : 0);
    return b.size() == 3 ? Box::periodic_box(b[0], b[1], b[2])
                         : Box::triclinic(b[0], b[1], b[2], b[3], b[4], b[5]);
  } catch (const std::invalid_argument& e) {
    parser.fail(std::string("option --box: ") + e.what());
  }
}

// The particles of the input, a block at a time, each block stored in
// parallel: the reader's own memory is that of a block. A particle the store
// refuses stops the run with its index and line (the first one, whatever
// the thread count).
ParticleStore read_particles(const std::string& path, SceneFormat format, int threads,
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
            if (format == SceneFormat::q)
              particles.set(first + i, {c[0][i], c[1][i], c[2][i]},
                            {c[3][i], c[4][i], c[5][i], c[6][i], c[7][i], c[8][i]});
            else if (format == SceneFormat::ellipse)
              particles.set_ellipse(first + i, c[0][i], c[1][i], c[2][i], c[3][i], c[4][i]);
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
                             source + ": " +
                                 (format == SceneFormat::ellipse ? "ellipse " : "ellipsoid ") +
                                 std::to_string(first + bad) + " (line " +
                                 std::to_string(block.line[bad]) + "): " + message);
      });
  return particles;
}

// The command line, checked: the format resolved, the box built.
struct ScreenCommand {
  ScreenCommandOptions options;
  SceneFormat format = SceneFormat::q;
  Box box;
};

// The arguments into `command`; false when help was asked for.
bool parse_screen(const Arguments& arguments, ScreenCommand& command) {
  ScreenCommandOptions& options = command.options;
  OptionParser parser = screen_parser(options);
  const Arguments rest = take_box(arguments, options, parser);
  if (!parser.parse(rest)) return false;
  command.format = options.format ? *options.format : format_from_name(options.input);
  command.box = box_of(options, command.format, parser);
  if (options.frame && command.format != SceneFormat::gsd &&
      command.format != SceneFormat::lammps_dump)
    parser.fail(std::string("option --frame: a ") + format_name(command.format) +
                " input has one frame (--frame is for gsd and lammps-dump)");
  if (options.columns && command.format != SceneFormat::lammps_dump)
    parser.fail(std::string("option --columns: for a lammps-dump input, not ") +
                format_name(command.format));
  if (!options.gsd_output.empty() && command.format != SceneFormat::gsd)
    parser.fail(std::string("option --write-gsd: for a gsd input, not ") +
                format_name(command.format));
  // (Both to standard output appended the binary frame to the text lines;
  // both to one file left the frame alone in it.)
  if (!options.gsd_output.empty() && same_destination(options.gsd_output, options.output))
    parser.fail("option --write-gsd: " +
                std::string(options.output == "-" ? "the pairs go to standard output"
                                                  : "-o names the same file") +
                "; give the GSD frame and the " + output_name(options.outputs) +
                " different places");
  if (!is_text(command.format) && options.input == "-")
    parser.fail(std::string("a ") + format_name(command.format) +
                " input is read from a file, not standard input: give FILE");
  return true;
}

bool parse_screen_only(const Arguments& arguments) {
  ScreenCommand command;
  return parse_screen(arguments, command);
}

// The scene of the input: particles, box, and where they came from.
struct LoadedScene {
  ParticleStore particles;
  Box box;
  std::string source;  // "scene.gsd (gsd, frame 3 of 4)"
};

LoadedScene load_scene(const ScreenCommand& command, int threads) {
  LoadedScene loaded;
  const ScreenCommandOptions& options = command.options;
  if (is_text(command.format)) {
    loaded.particles = read_particles(options.input, command.format, threads, loaded.source);
    loaded.box = command.box;
    return loaded;
  }
  Scene scene;
  const int previous_threads = omp_get_max_threads();
  omp_set_num_threads(threads);  // the readers' parallel loops
  try {
    const std::int64_t frame = options.frame ? *options.frame : -1;
    if (command.format == SceneFormat::gsd)
      scene = read_gsd(options.input, frame);
    else if (command.format == SceneFormat::lammps_data)
      scene = read_lammps_data(options.input);
    else
      scene = read_lammps_dump(options.input, frame,
                               options.columns ? *options.columns : LammpsColumns{});
  } catch (const std::invalid_argument& e) {
    throw CommandError(ExitStatus::usage_error, e.what());
  } catch (const std::runtime_error& e) {
    throw CommandError(ExitStatus::io_error, e.what());
  }
  omp_set_num_threads(previous_threads);
  loaded.particles = std::move(scene.particles);
  loaded.box = scene.box;
  loaded.source = options.input + " (" + format_name(command.format);
  if (scene.frames > 1 || command.format != SceneFormat::lammps_data)
    loaded.source +=
        ", frame " + std::to_string(scene.frame) + " of " + std::to_string(scene.frames);
  loaded.source += ")";
  return loaded;
}

// The output lines of `outputs`, formatted in parallel, in order.
void write_output(OutputFile& output, ScreenOutput outputs, bool with_mu2,
                  const ScreenedPairs& pairs, std::size_t particles, int threads) {
  if (outputs == ScreenOutput::pairs) {
    write_lines_in_order(output, pairs.size(), threads, [&](std::string& text, std::size_t k) {
      char line[2 * 12 + max_number_chars + 4];
      char* end = std::to_chars(line, line + 12, pairs.i[k]).ptr;
      *end++ = ' ';
      end = std::to_chars(end, end + 12, pairs.j[k]).ptr;
      if (with_mu2) {
        *end++ = ' ';
        end = write_number(end, pairs.mu2[k]);
      }
      *end++ = '\n';
      text.append(line, end);
    });
  } else if (outputs == ScreenOutput::counts) {
    const std::vector<std::uint32_t> counts = pair_counts(pairs, particles);
    write_lines_in_order(output, particles, threads, [&](std::string& text, std::size_t p) {
      char line[16];
      char* end = std::to_chars(line, line + 12, counts[p]).ptr;
      *end++ = '\n';
      text.append(line, end);
    });
  } else {
    const NeighborList list = neighbor_list(pairs, particles, true);
    write_lines_in_order(output, particles, threads, [&](std::string& text, std::size_t p) {
      char word[12 + max_number_chars + 4];
      for (std::size_t k = list.offsets[p]; k < list.offsets[p + 1]; ++k) {
        char* end = word;
        if (k > list.offsets[p]) *end++ = ' ';
        end = std::to_chars(end, end + 12, list.neighbors[k]).ptr;
        if (with_mu2) {
          *end++ = ' ';
          end = write_number(end, list.mu2[k]);
        }
        text.append(word, end);
      }
      text += '\n';
    });
  }
}

// `pwcontact screen` on one process, or on every rank of a distributed run
// (ScreenRanks, screen_command.hpp): the root alone opens the outputs,
// reads the input and writes the results; every rank parses the same
// arguments and takes part in the screen.
ExitStatus run_screen_on(const Arguments& arguments, const ScreenRanks* ranks) {
  const bool root = !ranks || ranks->root;
  ScreenCommand command;
  if (!parse_screen(arguments, command)) {
    if (root) std::fputs(full_help(screen_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  const ScreenCommandOptions& options = command.options;
  const int threads = resolve_thread_count(options.threads);
  // PWCONTACT_ISA and the CPU, checked before the input is read: a bad value
  // is a usage error now rather than after the reading.
  resolve_instruction_set(Isa::automatic);
  std::optional<OutputFile> output, gsd_output;
  LoadedScene scene;
  double read_seconds = 0;
  // The root's failure to open or read is every rank's: its exit status is
  // shared before the screen (the other ranks return it, the root throws).
  int status = 0;
  std::optional<CommandError> failure;
  if (root) {
    try {
      output.emplace(options.output);
      if (!options.gsd_output.empty()) gsd_output.emplace(options.gsd_output);
      const Stopwatch reading;
      scene = load_scene(command, threads);
      read_seconds = reading.seconds();
    } catch (const CommandError& e) {
      if (!ranks) throw;
      status = int(e.exit_status());
      failure = e;
    }
  }
  if (ranks) {
    status = ranks->share_status(status);
    if (failure) throw *failure;
    if (status != 0) return ExitStatus(status);
    scene.box = ranks->share_box(scene.box);
  }

  ScreenOptions screen_options;
  screen_options.cutoff = options.cutoff;
  screen_options.with_mu2 = options.with_mu2;
  screen_options.threads = threads;
  ScreenedPairs pairs;
  ScreenReport report;
  try {
    report = ranks ? ranks->screen(scene.particles, scene.box, screen_options, pairs)
                   : screen_pairs(scene.particles, scene.box, screen_options, pairs);
  } catch (const std::invalid_argument& e) {
    throw CommandError(ExitStatus::usage_error,
                       (root ? scene.source + ": " : std::string()) + e.what());
  }
  if (!root) return ExitStatus::success;

  const Stopwatch writing;
  // The GSD frame is made before anything is written: a frame that cannot
  // be made (a chunk of the input it cannot copy) then fails the run before
  // the pairs reach standard output, which cannot be taken back.
  std::ostringstream gsd_bytes;
  if (gsd_output) {
    try {
      write_gsd_frame_with_values(options.input, options.frame ? *options.frame : -1, "overlaps",
                                  pair_counts(pairs, scene.particles.size()), gsd_bytes);
    } catch (const std::invalid_argument& e) {
      throw CommandError(ExitStatus::usage_error, e.what());
    } catch (const std::runtime_error& e) {
      throw CommandError(ExitStatus::io_error, e.what());
    }
  }
  write_output(*output, options.outputs, options.with_mu2, pairs, scene.particles.size(), threads);
  if (gsd_output) gsd_output->write(gsd_bytes.str());
  // The main output first: if it cannot be written, the GSD file (still a
  // temporary) is removed with it, as --help promises ("appears only when
  // the run succeeds"; committed first, it outlived a failed run).
  output->commit();
  if (gsd_output) gsd_output->commit();
  std::fprintf(stderr,
               "pwcontact screen: %zu %s from %s (read in %s), %zu pairs, %s to %s "
               "(written in %s)\n%s",
               scene.particles.size(),
               scene.box.two_dimensional || command.format == SceneFormat::ellipse ? "ellipses"
                                                                                   : "ellipsoids",
               scene.source.c_str(), describe_seconds(read_seconds).c_str(), pairs.size(),
               output_name(options.outputs), output->name().c_str(),
               describe_seconds(writing.seconds()).c_str(),
               ranks ? ranks->describe(report).c_str()
                     : describe_screen(report, scene.box, options.cutoff).c_str());
  if (gsd_output)
    std::fprintf(stderr, "  the frame with log/particles/overlaps to %s\n",
                 gsd_output->name().c_str());
  return ExitStatus::success;
}

ExitStatus run_screen(const Arguments& arguments) { return run_screen_on(arguments, nullptr); }

}  // namespace

const Subcommand screen_subcommand = {
    "screen", "every pair of a scene with mu < cutoff (overlaps, neighbour lists)",
    screen_options_help, run_screen, parse_screen_only};

ExitStatus run_screen_over(const Arguments& arguments, const ScreenRanks& ranks) {
  return run_screen_on(arguments, &ranks);
}

}  // namespace pwcontact::cli
