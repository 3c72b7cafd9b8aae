// `pwcontact demo`: the main job on an embedded default. A scene of random
// spheroids in a periodic box is generated and screened for overlapping
// pairs; the summary gives every stage's counts and time.
#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "cli/screen_summary.hpp"
#include "cli/subcommands.hpp"
#include "cli/text_output.hpp"
#include "fixtures/families.hpp"

namespace pwcontact::cli {
namespace {

constexpr std::size_t default_ellipsoids = 1'000'000;
constexpr std::uint64_t default_seed = 1;

struct DemoOptions {
  std::size_t ellipsoids = default_ellipsoids;
  std::uint64_t seed = default_seed;
  double packing = 0.3;           // volume of the spheroids over the box's
  double max_aspect = 3;          // aspect ratios log-uniform in [1 / max, max]
  bool identical_shapes = false;  // every aspect ratio max_aspect instead
  double cutoff = 1;
  int threads = 0;
};

OptionParser demo_parser(DemoOptions& options) {
  OptionParser parser(
      "demo",
      "Generates a scene of random spheroids in a periodic cubic box (centres uniform, "
      "orientations uniform, aspect ratios log-uniform in [1/A, A], each with the volume "
      "of a sphere of radius 0.5, the box sized for the packing fraction) and screens it "
      "for the pairs with mu < cutoff (overlapping pairs with the default cutoff 1), as "
      "'pwcontact screen' would, then prints the summary: the scene, each stage's counts "
      "and time, the rates. On a terminal a progress bar shows the stages that take "
      "longer than a second. No input is needed; the same seed gives the same scene on "
      "every platform.");
  parser.add_value({"--n"}, "N", std::to_string(default_ellipsoids), "number of spheroids",
                   [&options](std::string_view value) {
                     options.ellipsoids =
                         std::size_t(parse_integer(value, 1, (std::int64_t(1) << 31) - 1));
                   });
  parser.add_value({"--seed"}, "S", std::to_string(default_seed), "seed of the scene",
                   [&options](std::string_view value) { options.seed = parse_unsigned(value); });
  parser.add_value({"--packing"}, "PHI", "0.3",
                   "packing fraction: total spheroid volume over box volume, in (0, 1)",
                   [&options](std::string_view value) {
                     options.packing = parse_positive_number(value);
                     if (!(options.packing < 1)) throw std::invalid_argument("must be below 1");
                   });
  parser.add_value({"--max-aspect"}, "A", "3",
                   "largest aspect ratio (polar over equatorial radius, and its inverse), >= 1",
                   [&options](std::string_view value) {
                     options.max_aspect = parse_positive_number(value);
                     if (!(options.max_aspect >= 1)) throw std::invalid_argument("must be >= 1");
                   });
  parser.add_flag({"--identical"},
                  "identical shapes: every spheroid prolate with aspect ratio A (only the "
                  "orientations differ; the same centres)",
                  [&options] { options.identical_shapes = true; });
  parser.add_value({"--cutoff"}, "MU", "1", "a pair is found when mu < MU; positive and finite",
                   [&options](std::string_view value) { options.cutoff = parse_cutoff(value); });
  add_threads_option(parser, options.threads, "the pairs");
  return parser;
}

std::string demo_options_help() {
  DemoOptions options;
  return demo_parser(options).help();
}

bool parse_demo_only(const Arguments& arguments) {
  DemoOptions options;
  return demo_parser(options).parse(arguments);
}

ExitStatus run_demo(const Arguments& arguments) {
  DemoOptions options;
  if (!demo_parser(options).parse(arguments)) {
    std::fputs(full_help(demo_subcommand).c_str(), stdout);
    return ExitStatus::success;
  }
  const int threads = resolve_thread_count(options.threads);
  resolve_instruction_set(Isa::automatic);  // a bad PWCONTACT_ISA: a usage error, now
  const Stopwatch generating;
  SpheroidScene scene;
  {
    ProgressBar bar("generating the scene");
    scene = spheroid_scene(options.ellipsoids, options.seed, options.packing, options.max_aspect,
                           options.identical_shapes, threads,
                           [&bar](double fraction) { bar.update(fraction); });
  }
  const double generate_seconds = generating.seconds();
  const ParticleStore& particles = scene.particles;
  const double box = scene.box.length[0];
  char shapes[96];
  if (options.identical_shapes)
    std::snprintf(shapes, sizeof shapes, "identical shapes, aspect ratio %g", options.max_aspect);
  else
    std::snprintf(shapes, sizeof shapes, "aspect ratios 1/%g to %g", options.max_aspect,
                  options.max_aspect);
  std::printf(
      "pwcontact demo: %zu spheroids (%s, packing fraction %g), "
      "periodic box %.4g, seed %llu (generated in %s)\n",
      particles.size(), shapes, options.packing, box, static_cast<unsigned long long>(options.seed),
      describe_seconds(generate_seconds).c_str());
  std::fflush(stdout);

  ScreenOptions screen_options;
  screen_options.cutoff = options.cutoff;
  screen_options.threads = threads;
  ScreenedPairs pairs;
  ScreenReport report;
  {
    ProgressBar bar("screening: candidates");
    screen_options.progress = [&bar](double fraction) { bar.update(fraction); };
    try {
      report = screen_pairs(particles, scene.box, screen_options, pairs);
    } catch (const std::invalid_argument& e) {
      throw CommandError(ExitStatus::usage_error, e.what());
    }
  }
  std::fputs(describe_screen(report, scene.box, options.cutoff).c_str(), stdout);
  return ExitStatus::success;
}

}  // namespace

const Subcommand demo_subcommand = {"demo",
                                    "the main job on an embedded default: 1M spheroids screened",
                                    demo_options_help, run_demo, parse_demo_only};

}  // namespace pwcontact::cli
