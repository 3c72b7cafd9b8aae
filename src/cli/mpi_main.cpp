// `pwcontact-mpi screen`: `pwcontact screen` over MPI ranks, run as
//   mpirun -np N pwcontact-mpi screen [OPTION]... [FILE]
// with the options and output of `pwcontact screen` (byte for byte the same
// output). Rank 0 reads the scene and passes every particle to the screen
// over the ranks (pwcontact/mpi.hpp), whose migration sends each to the rank
// of its subdomain; the pairs are gathered back on rank 0, which writes them.
#include <mpi.h>

#include <cstdio>
#include <exception>
#include <new>
#include <string>

#include "cli/command_line.hpp"
#include "cli/screen_command.hpp"
#include "cli/screen_summary.hpp"
#include "cli/text_output.hpp"
#include "pwcontact/mpi.hpp"

#ifndef PWCONTACT_VERSION
#error "PWCONTACT_VERSION must be defined by the build (the project version)"
#endif

namespace pwcontact::cli {
namespace {

const char* const usage_text =
    "Usage: mpirun -np N pwcontact-mpi screen [OPTION]... [FILE]\n"
    "       pwcontact-mpi --help | --version\n"
    "`pwcontact screen` over the ranks of an MPI run: the same options, the same\n"
    "output; rank 0 reads FILE and writes the results, every rank screens its\n"
    "subdomain\n"
    "(see 'pwcontact help screen' for the options).\n";

// What the distributed screen did, for the summary (the slowest rank's
// times, every rank's ghosts).
struct Distributed {
  pwcontact::mpi::DistributedReport root;
  int ranks = 1;
  double seconds[3] = {0, 0, 0};  // migration, ghosts, screen: the largest over the ranks
  unsigned long long ghosts = 0, owned_most = 0;
};

ExitStatus run(const Arguments& arguments, int rank, int size, Distributed& distributed) {
  const bool root = rank == 0;
  if (arguments.empty() || arguments.front() == "-h" || arguments.front() == "--help") {
    if (arguments.empty())
      throw CommandError(ExitStatus::usage_error, "no subcommand given", usage_text);
    if (root) std::fputs(usage_text, stdout);
    return ExitStatus::success;
  }
  if (arguments.front() == "--version") {
    if (root) std::puts("pwcontact-mpi " PWCONTACT_VERSION);
    return ExitStatus::success;
  }
  if (arguments.front() != "screen")
    throw CommandError(
        ExitStatus::usage_error,
        "the subcommand over MPI is screen, not '" + std::string(arguments.front()) + "'",
        usage_text);
  ScreenRanks ranks;
  ranks.root = root;
  ranks.share_status = [](int status) {
    MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    return status;
  };
  ranks.share_box = [](const Box& box) {
    double numbers[8] = {
        double(box.periodic), box.length[0], box.length[1], box.length[2],
        box.tilt[0],          box.tilt[1],   box.tilt[2],   double(box.two_dimensional)};
    MPI_Bcast(numbers, 8, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    Box shared;
    shared.periodic = numbers[0] != 0;
    shared.length = {numbers[1], numbers[2], numbers[3]};
    shared.tilt = {numbers[4], numbers[5], numbers[6]};
    shared.two_dimensional = numbers[7] != 0;
    return shared;
  };
  ranks.screen = [&](const ParticleStore& particles, const Box& box, const ScreenOptions& options,
                     ScreenedPairs& out) {
    std::vector<std::uint64_t> tags(particles.size());
    for (std::size_t k = 0; k < tags.size(); ++k) tags[k] = k;
    pwcontact::mpi::TaggedPairs local;
    const pwcontact::mpi::DistributedReport report =
        pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, particles, tags, box, options, local);
    const pwcontact::mpi::TaggedPairs all = pwcontact::mpi::gather_pairs(MPI_COMM_WORLD, local);
    double seconds[3] = {report.seconds_migration, report.seconds_ghosts, report.seconds_screen};
    MPI_Reduce(seconds, distributed.seconds, 3, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
    unsigned long long ghosts = report.ghosts, owned = report.owned;
    MPI_Reduce(&ghosts, &distributed.ghosts, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    MPI_Reduce(&owned, &distributed.owned_most, 1, MPI_UNSIGNED_LONG_LONG, MPI_MAX, 0,
               MPI_COMM_WORLD);
    distributed.root = report;
    distributed.ranks = size;
    out = {};
    out.i.assign(all.i.begin(), all.i.end());  // (tags below 2^31: the screen's limit)
    out.j.assign(all.j.begin(), all.j.end());
    out.mu2 = all.mu2;
    return report.screen;
  };
  ranks.describe = [&](const ScreenReport&) {
    const auto& d = distributed.root.dims;
    char text[400];
    std::snprintf(text, sizeof text,
                  "  over %d MPI ranks (grid %d x %d x %d): at most %llu particles a rank, %llu "
                  "ghosts in all; the slowest rank's migration %s, ghost exchange %s, screen %s\n",
                  distributed.ranks, d[0], d[1], d[2], distributed.owned_most, distributed.ghosts,
                  describe_seconds(distributed.seconds[0]).c_str(),
                  describe_seconds(distributed.seconds[1]).c_str(),
                  describe_seconds(distributed.seconds[2]).c_str());
    return std::string(text);
  };
  const Arguments rest(arguments.begin() + 1, arguments.end());
  return run_screen_over(rest, ranks);
}

}  // namespace
}  // namespace pwcontact::cli

int main(int argc, char** argv) {
  using namespace pwcontact::cli;
  MPI_Init(&argc, &argv);
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  ensure_standard_descriptors();
  const Arguments arguments(argv + 1, argv + argc);
  int status = 0;
  Distributed distributed;
  try {
    status = int(run(arguments, rank, size, distributed));
    if (rank == 0 && (std::fflush(stdout) != 0 || std::ferror(stdout)))
      throw CommandError(ExitStatus::io_error, "cannot write <stdout>");
  } catch (const CommandError& error) {
    if (rank == 0)
      std::fprintf(stderr, "pwcontact-mpi screen: %s\n%s", error.what(), error.usage().c_str());
    status = int(error.exit_status());
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "pwcontact-mpi screen: rank %d: out of memory\n", rank);
    MPI_Abort(MPI_COMM_WORLD, int(ExitStatus::io_error));
  } catch (const std::exception& error) {
    std::fprintf(stderr, "pwcontact-mpi screen: rank %d: %s\n", rank, error.what());
    MPI_Abort(MPI_COMM_WORLD, 4);
  }
  MPI_Finalize();
  return status;
}
