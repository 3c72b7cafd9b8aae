// `pwcontact mc`: hard-ellipsoid Monte Carlo on a moving scene, the
// demonstration of trial-move queries. Spheroids start on a dilute lattice
// and are compressed, sweep by sweep, to a packing fraction without ever
// overlapping; the final scene is written for `pwcontact screen`.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/float32_scene.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"
#include "pwcontact/monte_carlo.hpp"
#include "pwcontact/scene_files.hpp"

namespace pwcontact::cli {
namespace {

// Spheroids of this many shapes (aspect ratios log-spaced over [1/3, 3]):
// the types of the GSD file.
constexpr std::size_t shape_count = 16;

struct McOptions {
  std::size_t particles = 500;
  std::uint64_t seed = 1;
  double packing = 0.5;
  std::size_t sweeps = 200000;
  int threads = 0;
  std::string output;
};

OptionParser mc_parser(McOptions& options) {
  OptionParser parser(
      "mc",
      "Hard-ellipsoid Monte Carlo (NVT, translation and rotation moves, Metropolis for hard "
      "particles: a move is accepted when the moved spheroid overlaps nothing, decided "
      "exactly by the contact function) on a moving scene. N spheroids of 16 shapes "
      "(aspect ratios log-spaced over 1/3 .. 3, each with the volume of a sphere of radius "
      "0.5, random orientations) start on a simple cubic lattice (packing fraction ~0.055) "
      "in a periodic box, which is compressed after every sweep as far as the exact mu of "
      "the closest pair allows (halfway to contact: never an overlap), until the packing "
      "fraction is reached. After every sweep a full screen of the scene must find no "
      "overlap (else the run stops with an error, exit status 3). Too few spheroids for the "
      "packing fraction (a box narrower than twice 1.1 times the largest diameter, which the "
      "screens need) is refused before the first sweep (exit status 2). Sweeps are checkerboard "
      "sweeps of batched trial queries in scenes of many cells (the same result for every "
      "thread count), one trial at a time in small ones. Standard error shows the progress, "
      "the step sizes and the acceptance rate; the final scene goes to -o FILE: GSD (.gsd: "
      "the hoomd schema as HOOMD-blue reads it: float32 positions, orientations and box, "
      "centres wrapped into the box centred on the origin, every pair of the rounded scene "
      "at mu >= 1 + 1e-6 (where rounding brings a pair closer, centres and box are scaled "
      "up by a factor of about the least that keeps it, said on standard error); types A0 .. "
      "A15 with "
      "their Ellipsoid shapes) "
      "or text "
      "(any other name: 'pwcontact screen --format axes' lines, x y z a b c qw qx qy qz, "
      "with the box in a comment line and the command that reads it back).");
  parser.add_value({"--n"}, "N", "500", "number of spheroids", [&options](std::string_view value) {
    options.particles = std::size_t(parse_integer(value, 1, 10'000'000));
  });
  parser.add_value({"--seed"}, "S", "1", "seed of the lattice's shapes and of the moves",
                   [&options](std::string_view value) { options.seed = parse_unsigned(value); });
  parser.add_value({"--packing"}, "PHI", "0.5",
                   "packing fraction to reach: total spheroid volume over box volume, in (0, 0.7)",
                   [&options](std::string_view value) {
                     options.packing = parse_positive_number(value);
                     if (!(options.packing < 0.7)) throw std::invalid_argument("must be below 0.7");
                   });
  parser.add_value({"--sweeps"}, "K", "200000",
                   "the most sweeps the compression may take (exit status 3 if it falls short)",
                   [&options](std::string_view value) {
                     options.sweeps = std::size_t(parse_integer(value, 1, std::int64_t(1) << 40));
                   });
  add_threads_option(parser, options.threads, "the sweeps");
  parser.add_value({"-o", "--output"}, "FILE", "(none)",
                   "where the final scene goes: GSD for a .gsd name, else axes text",
                   [&options](std::string_view value) {
                     // (An empty name, -o "$UNSET", wrote nothing and said nothing.)
                     if (value.empty()) throw std::invalid_argument("needs a file name");
                     options.output = std::string(value);
                   });
  return parser;
}

std::string mc_options_help() {
  McOptions options;
  return mc_parser(options).help();
}

bool parse_mc_only(const Arguments& arguments) {
  McOptions options;
  return mc_parser(options).parse(arguments);
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The scene as one GSD frame. GsdWriter rewrites the file's header when it
// finishes, so the frame is made in memory (32 bytes a particle) and then
// written through `out` as one block.
void write_gsd(const HardParticleMC& mc, OutputFile& out, int threads) {
  const ParticleStore& s = mc.particles();
  const std::size_t n = s.size();
  std::map<std::array<double, 3>, std::uint32_t> type_of_shape;
  std::vector<std::uint32_t> typeid_(n);
  for (std::size_t i = 0; i < n; ++i) {
    auto found = type_of_shape.emplace(mc.semi_axes()[i], std::uint32_t(type_of_shape.size()));
    typeid_[i] = found.first->second;
  }
  std::vector<std::string> names(type_of_shape.size()), shapes(type_of_shape.size());
  for (const auto& [axes, t] : type_of_shape) {
    names[t] = "A" + std::to_string(t);
    char json[160];
    std::snprintf(json, sizeof json,
                  "{\"type\": \"Ellipsoid\", \"a\": %.17g, \"b\": %.17g, \"c\": %.17g}", axes[0],
                  axes[1], axes[2]);
    shapes[t] = json;
  }
  // float32 as HOOMD-blue reads the hoomd schema, centres in [-L/2, L/2),
  // every pair of the rounded scene at mu >= 1 + 1e-6 (float32_scene.hpp):
  // 1e-6 leaves room for readers that use a quaternion of norm 1 +- 1e-7 as
  // it is, as HOOMD-blue's rotations do.
  std::vector<std::array<double, 3>> centre(n);
  for (std::size_t i = 0; i < n; ++i) centre[i] = {s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]};
  const Box& box = mc.box();
  const Float32Scene rounded =
      round_to_float32(box, centre, mc.semi_axes(), mc.orientation(), 1e-6, threads);
  if (rounded.scale != 1) {
    const double ratio = box.length[0] / double(rounded.box[0]) * box.length[1] /
                         double(rounded.box[1]) * box.length[2] / double(rounded.box[2]);
    std::fprintf(stderr,
                 "pwcontact mc: rounded to float32, a pair came within 1e-6 of contact: the GSD "
                 "frame's centres and box are scaled by 1 + %.2g (packing fraction %.6f)\n",
                 rounded.scale - 1, mc.packing() * ratio);
  }
  std::ostringstream frame(std::ios::binary);
  GsdWriter writer(frame);
  writer.write("configuration/step", std::vector<std::uint64_t>{mc.sweeps()}, 1);
  const std::uint8_t three = 3;
  writer.write_chunk("configuration/dimensions", 1, 1, 1, &three);
  writer.write("configuration/box", std::vector<float>(rounded.box.begin(), rounded.box.end()), 6);
  writer.write("particles/N", std::vector<std::uint32_t>{std::uint32_t(n)}, 1);
  writer.write("particles/types", names);
  writer.write("particles/typeid", typeid_, n);
  writer.write("particles/type_shapes", shapes);
  writer.write("particles/position", rounded.position, n);
  writer.write("particles/orientation", rounded.orientation, n);
  writer.end_frame();
  writer.finish();
  out.write(frame.str());
  out.commit();
}

// A path as a POSIX shell reads it back: as it is when it holds only
// characters no shell treats specially, else in single quotes (a quote
// itself closed, escaped and reopened).
std::string shell_quoted(const std::string& path) {
  const bool plain = !path.empty() && std::all_of(path.begin(), path.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) ||
           std::string_view("_./+,:@%=-").find(c) != std::string_view::npos;
  });
  if (plain) return path;
  std::string quoted = "'";
  for (char c : path) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// The scene as `pwcontact screen --format axes` lines, after a header of
// comment lines (made as a string: a fixed buffer cut a long path short, and
// with it the header's last newline, which put particle 0 into a comment).
void write_text(const HardParticleMC& mc, OutputFile& out, const std::string& path) {
  const ParticleStore& s = mc.particles();
  const Box& box = mc.box();
  std::string lengths;
  for (int k = 0; k < 3; ++k) {
    char number[max_number_chars];
    lengths += ' ';
    lengths.append(number, write_number(number, box.length[k]));
  }
  char summary[160];
  std::snprintf(
      summary, sizeof summary,
      "# pwcontact mc: %zu spheroids, packing fraction %.6f after %zu sweeps, periodic box",
      s.size(), mc.packing(), mc.sweeps());
  out.write(std::string(summary) + lengths + "\n# read back: pwcontact screen --format axes --box" +
            lengths + " " + shell_quoted(path) + "\n# x y z a b c qw qx qy qz\n");
  char line[400];  // (ten numbers of at most max_number_chars characters)
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto& a = mc.semi_axes()[i];
    const auto& q = mc.orientation()[i];
    std::snprintf(line, sizeof line,
                  "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", s.centre(0)[i],
                  s.centre(1)[i], s.centre(2)[i], a[0], a[1], a[2], q[0], q[1], q[2], q[3]);
    out.write(line);
  }
  out.commit();
}

ExitStatus run_mc(const Arguments& arguments) {
  McOptions options;
  if (!mc_parser(options).parse(arguments)) {
    std::fputs(full_help(mc_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  HardParticleMCOptions mc_options;
  mc_options.packing = options.packing;
  mc_options.seed = options.seed;
  mc_options.threads = resolve_thread_count(options.threads);
  resolve_instruction_set(Isa::automatic);
  const Stopwatch clock;
  // The output is opened first: a path that cannot be written is refused
  // before the run, not after it (the file appears, whole, at the end).
  std::optional<OutputFile> out;
  if (!options.output.empty()) out.emplace(options.output);
  HardParticleMC mc =
      HardParticleMC::dilute_spheroids(options.particles, options.seed, 3, mc_options, shape_count);
  const double start_packing = mc.packing();
  std::fprintf(stderr, "pwcontact mc: %zu spheroids, packing fraction %.4f -> %g, %d threads\n",
               options.particles, start_packing, options.packing, mc_options.threads);
  std::size_t proposed = 0, accepted = 0;
  {
    ProgressBar bar("compressing");
    try {
      mc.compress_to_packing(options.sweeps, [&](std::size_t sweeps, double packing,
                                                 double acceptance) {
        // Progress in the log of the volume, which the compression shrinks.
        const double fraction =
            std::log(packing / start_packing) / std::log(options.packing / start_packing);
        char note[120];
        std::snprintf(note, sizeof note, "sweep %zu, packing %.4f, acceptance %.2f, d %.3g, a %.3g",
                      sweeps, packing, acceptance, mc.translation(), mc.rotation());
        bar.update(fraction, note);
        accepted += std::size_t(acceptance * double(options.particles) + 0.5);
        proposed += options.particles;
      });
    } catch (const std::runtime_error& e) {
      throw CommandError(ExitStatus::failed, e.what());
    } catch (const std::invalid_argument& e) {
      // (Before any sweep: --n too small for --packing.)
      throw CommandError(ExitStatus::usage_error, e.what());
    } catch (const std::logic_error& e) {
      throw CommandError(ExitStatus::failed, e.what());
    }
  }
  const std::size_t overlapping = mc.overlapping_pairs();
  if (overlapping != 0)
    throw CommandError(ExitStatus::failed,
                       std::to_string(overlapping) + " overlapping pairs at the end");
  std::fprintf(stderr,
               "pwcontact mc: packing fraction %.4f after %zu sweeps in %s, acceptance %.3f, no "
               "overlap (full screen after every sweep)\n",
               mc.packing(), mc.sweeps(), describe_seconds(clock.seconds()).c_str(),
               proposed ? double(accepted) / double(proposed) : 0.0);
  if (out) {
    if (ends_with(options.output, ".gsd")) {
      try {
        write_gsd(mc, *out, mc_options.threads);
      } catch (const CommandError&) {
        throw;  // (the output's own failures keep their status)
      } catch (const std::logic_error& e) {
        // (The rounding to float32 and its screens: after a run that
        // succeeded, a failure of the run's own output, exit status 3.)
        throw CommandError(ExitStatus::failed, e.what());
      } catch (const std::runtime_error& e) {
        throw CommandError(ExitStatus::failed, e.what());
      }
    } else
      write_text(mc, *out, options.output);
    std::fprintf(stderr, "pwcontact mc: wrote %s\n", options.output.c_str());
  }
  return ExitStatus::success;
}

}  // namespace

const Subcommand mc_subcommand = {
    "mc", "hard-ellipsoid Monte Carlo: spheroids compressed, never overlapping", mc_options_help,
    run_mc, parse_mc_only};

}  // namespace pwcontact::cli
