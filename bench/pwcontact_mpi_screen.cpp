// pwcontact_mpi_screen: the screen over MPI ranks on the demo's scene, for
// the figures of README's "Screening over MPI": per rank, the particles it
// owns, the ghosts it receives and the bytes it sends, and the wall time of
// each stage. Run under mpirun:
//   mpirun --allow-run-as-root [--oversubscribe] -np P pwcontact_mpi_screen [N] [REPEATS]
// Every rank makes the same scene (spheroid_scene: N spheroids, default 1M,
// packing 0.3, aspect ratios 1/3 .. 3, seed 1) and passes the particles in
// its own subdomain's slab of indices (round robin would time the first
// migration of a scene that starts anywhere; this times a scene that is
// already in place, as after the first call: every particle owned by the
// rank that passes it). The first call places them; the following REPEATS
// (default 3) calls start from the placed particles, and their median wall
// time (the slowest rank's) is reported, with rank 0 writing one table.
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "fixtures/families.hpp"
#include "pwcontact/mpi.hpp"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const std::size_t n = argc > 1 ? std::strtoull(argv[1], nullptr, 10) : 1000000;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 3;
  const pwcontact::SpheroidScene scene = pwcontact::spheroid_scene(n, 1, 0.3, 3, false, 1);
  pwcontact::ScreenOptions options;
  options.threads = 1;

  // The first call from round robin: the particles each rank owns.
  pwcontact::ParticleStore given;
  std::vector<std::uint64_t> tags;
  for (std::size_t i = std::size_t(rank); i < n; i += std::size_t(ranks)) {
    given.add_particle(scene.particles.particle_at(i));
    tags.push_back(i);
  }
  pwcontact::mpi::TaggedPairs local;
  MPI_Barrier(MPI_COMM_WORLD);
  double start = MPI_Wtime();
  pwcontact::mpi::DistributedReport first =
      pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, given, tags, scene.box, options, local);
  double first_seconds = MPI_Wtime() - start;
  MPI_Allreduce(MPI_IN_PLACE, &first_seconds, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);

  // The owned particles, as the next steps of a simulation hold them: the
  // particles of the pairs do not say which are owned, so each rank takes
  // those whose centre lies in its slab of the grid (the decomposition's
  // subdomains are the grid's cells of fractional coordinates).
  const pwcontact::Box& box = scene.box;
  pwcontact::ParticleStore mine;
  std::vector<std::uint64_t> mine_tags;
  for (std::size_t i = 0; i < n; ++i) {
    int cell[3];
    for (int k = 0; k < 3; ++k) {
      double s = scene.particles.centre(k)[i] / box.length[k];
      s -= std::floor(s);
      cell[k] = std::min(first.dims[k] - 1, int(s * first.dims[k]));
    }
    if (cell[0] == first.coords[0] && cell[1] == first.coords[1] && cell[2] == first.coords[2]) {
      mine.add_particle(scene.particles.particle_at(i));
      mine_tags.push_back(i);
    }
  }
  std::vector<double> wall, migration, ghosts, screen;
  pwcontact::mpi::DistributedReport report;
  for (int r = 0; r < repeats; ++r) {
    MPI_Barrier(MPI_COMM_WORLD);
    start = MPI_Wtime();
    report = pwcontact::mpi::screen_pairs(MPI_COMM_WORLD, mine, mine_tags, box, options, local);
    double seconds = MPI_Wtime() - start;
    MPI_Allreduce(MPI_IN_PLACE, &seconds, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    wall.push_back(seconds);
    migration.push_back(report.seconds_migration);
    ghosts.push_back(report.seconds_ghosts);
    screen.push_back(report.seconds_screen);
  }
  // Per rank: owned, ghosts, bytes; rank 0 prints every rank's line.
  const double line[8] = {double(report.owned),
                          double(report.ghosts),
                          double(report.ghost_bytes_sent),
                          double(report.migration_bytes_sent),
                          double(report.neighbours),
                          median(migration),
                          median(ghosts),
                          median(screen)};
  std::vector<double> all(8 * std::size_t(ranks));
  MPI_Gather(line, 8, MPI_DOUBLE, all.data(), 8, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  std::size_t pairs = local.size(), total_pairs = 0;
  MPI_Reduce(&pairs, &total_pairs, 1, MPI_UNSIGNED_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
  if (rank == 0) {
    std::printf("%d ranks (grid %d x %d x %d), %zu spheroids, 1 thread a rank: %zu pairs found\n",
                ranks, first.dims[0], first.dims[1], first.dims[2], n, total_pairs);
    std::printf("first call (round robin, every particle migrated): %.3f s\n", first_seconds);
    std::printf("placed particles, median of %d: %.3f s (slowest rank)\n", repeats, median(wall));
    std::printf(
        "rank  owned     ghosts    ghost/owned  ghost MB sent  migration MB  neighbours  "
        "migration s  ghosts s  screen s\n");
    for (int r = 0; r < ranks; ++r) {
      const double* x = all.data() + 8 * std::size_t(r);
      std::printf("%4d  %8.0f  %8.0f  %11.3f  %13.2f  %12.2f  %10.0f  %11.4f  %8.4f  %8.3f\n", r,
                  x[0], x[1], x[0] > 0 ? x[1] / x[0] : 0.0, x[2] / 1e6, x[3] / 1e6, x[4], x[5],
                  x[6], x[7]);
    }
  }
  MPI_Finalize();
  return 0;
}
