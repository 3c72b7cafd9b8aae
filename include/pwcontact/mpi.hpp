// Screening a scene distributed over MPI ranks (library pwcontact_mpi, built
// with PWCONTACT_BUILD_MPI; pwcontact itself does not link MPI).
//
// Each rank passes the particles it holds and their global ids (tags); the
// ranks then screen the scene together, as screen_pairs (screen.hpp) screens
// it on one machine:
//  1. decomposition: a Cartesian grid of ranks (MPI_Dims_create,
//     MPI_Cart_create) over the box's fractional coordinates along its
//     periodic axes, and over the extent of the centres (MPI_Allreduce) along
//     its open axes (a two-dimensional box is not split along z);
//  2. migration: every particle is sent to the rank whose subdomain holds
//     its centre (from any rank: the particles may start anywhere; over the
//     neighbours alone when every particle moved at most to a neighbour);
//  3. ghosts: rank r receives the particles j of other subdomains whose
//     centre lies within cutoff (R_j + min(R_j, R_max(r))) of its subdomain
//     (R: bounding radius, R_max(r) the largest of r's own particles), per
//     particle and per receiving rank: a small particle goes only as far as
//     twice its reach, whatever the large particles near it (they come to
//     it), so that a few large particles do not thicken every layer; each is
//     received once per rank, at its own centre (the periodic images are the
//     local screen's minimum image);
//  4. each rank screens its own and ghost particles with screen_pairs, in
//     the same box, and keeps a pair when it owns the pair's keeper: the
//     particle of the smaller bounding radius, of the smaller tag when the
//     radii are equal (the owner rule: every pair is found exactly once over
//     all ranks, see screen_mpi.cpp).
// The pairs and their mu^2 are those screen_pairs gives for the whole scene
// on one process with the particles indexed by tag, to the bit (the same
// radii, r12 and solve for every pair).
//
// Every function here is collective over the communicator: every rank calls
// it, with the same box and options (a box, cutoff, with_mu2 or solve option
// that differs between ranks is an error; so is a box with a NaN). An error in the input of any
// rank (std::invalid_argument) is thrown on every rank, with the message of the lowest rank that
// found one.
#pragma once

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact::mpi {

// Pairs of tags: i[k] < j[k], sorted by i then j, each once; mu2[k] when
// asked for.
struct TaggedPairs {
  std::vector<std::uint64_t> i, j;
  std::vector<double> mu2;
  std::size_t size() const noexcept { return i.size(); }
};

// What one rank did.
struct DistributedReport {
  std::array<int, 3> dims = {1, 1, 1};    // ranks along each axis
  std::array<int, 3> coords = {0, 0, 0};  // this rank's place in the grid
  std::size_t given = 0;                  // particles passed in on this rank
  std::size_t owned = 0;                  // particles in this rank's subdomain after migration
  std::size_t sent_away = 0;              // particles migrated from this rank
  bool migration_by_neighbours = false;   // every rank's migrants went to its neighbours:
                                          // migrated over the graph, not by MPI_Alltoallv
  std::size_t ghosts = 0;                 // particles received from other subdomains
  double largest_radius = -1;             // of the particles owned (-1: none)
  std::size_t neighbours = 0;             // ranks this one exchanges ghosts with
  std::size_t ghost_bytes_sent = 0, migration_bytes_sent = 0;
  ScreenReport screen;  // of the local screen (own and ghost particles)
  double seconds_migration = 0, seconds_ghosts = 0, seconds_screen = 0;
};

// Every pair of the distributed scene with mu < options.cutoff, as the pairs
// of this rank under the owner rule (in tags; with_mu2: their mu^2).
// particles[k] has the global id tags[k]; tags are unique over all ranks.
// options.threads is per rank. Throws std::invalid_argument (on every rank)
// for a tag count that is not the particle count, a tag given twice (where a
// rank sees both), a bad cutoff, or a periodic box narrower than twice the
// largest reach cutoff * 2 R_max (as screen_pairs).
//
// A particle whose reach is wider than a subdomain is handled: the ranks
// exchange ghosts with every rank within the largest reach (more than the
// 26 nearest, then), and each particle goes only to the ranks it can reach.
// The local screen's r12 of a pair is the single-process one to the bit,
// whatever either screen's cell lists (r12 is the plain difference of the
// wrapped centres plus the same lattice vector in both), and so is mu^2 when
// every rank passes the same options. The box, the cutoff, with_mu2, the
// solve's options (iterations, precision, accuracy, formulation) and the
// instruction set each rank runs (FMA or not changes the last bits) are
// compared across the ranks: ranks that differ are refused on every rank.
// An instruction set left automatic on every rank is the most capable one
// every rank runs (fallback < sse2 < avx2 < avx512): ranks on different
// CPUs agree on it.
DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint64_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out);
DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint32_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out);
// The same, each rank's local screen in its own workspace (screen.hpp: the
// memory of the rank's last screen reused), for a simulation that screens
// every so many steps: the same pairs.
DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint64_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out,
                               ScreenWorkspace& workspace);
DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint32_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out,
                               ScreenWorkspace& workspace);

// The pairs of every rank on `root`, sorted by i then j (for tags 0 .. N - 1:
// the order and the numbers of screen_pairs on the whole scene); empty on
// the other ranks.
TaggedPairs gather_pairs(MPI_Comm comm, const TaggedPairs& local, int root = 0);

}  // namespace pwcontact::mpi
