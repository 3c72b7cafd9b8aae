// screen_pairs over MPI ranks (see pwcontact/mpi.hpp): decomposition,
// migration, ghosts, the local screen and the owner rule.
//
// The owner rule. Of a pair (a, b) found by a rank's local screen, the
// keeper is the particle of the smaller bounding radius, of the smaller tag
// when the radii are equal (the radii travel with the particles: every rank
// compares the same numbers); the rank keeps the pair when it owns the keeper
// (its centre is in the rank's subdomain: it is not a ghost there).
// Ownership is unique, so no pair is kept twice; and the owner of the keeper
// a always finds the pair: mu < cutoff implies that the bounding spheres
// scaled by the cutoff meet, |r12| < cutoff (R_a + R_b), and R_a <= R_b and
// R_a <= R_max(owner) (the largest radius the owner holds) give
// |r12| < cutoff (R_b + min(R_b, R_max(owner))); a lies in the owner's
// subdomain, so b's centre lies within that distance of the subdomain in
// every cell-space coordinate (BoxGeometry: two centres a distance d apart
// differ by at most d in each, periodic images included), which is the test
// by which b is sent to the owner as a ghost. So a small particle goes only
// as far as twice its own reach, whatever the large particles near it (they
// come to it instead: HOOMD-blue's issue #756 is the lesson of one global
// ghost width), and a rank of small particles receives a large one without
// the many small ones around it. The owner screens a and b in the same box
// as the whole scene, with the same centres, forms and radii: the same
// minimum image r12 (the difference of the same wrapped positions, plus the
// one lattice vector that brings the pair within its reach), the same
// prefilters and the same solve, hence the same mu^2.
#include <omp.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <utility>

#include "mpi/agree.hpp"
#include "number_text.hpp"
#include "pwcontact/mpi.hpp"
#include "screen/cell_lists.hpp"
#include "screen/radix_sort.hpp"
#include "thread_count.hpp"

namespace pwcontact::detail {

// A particle on the wire: its tag's bits, centre, form and radii, as 13
// doubles (MPI sees only doubles; the tag's bits pass unchanged between
// ranks of one kind of machine).
struct ParticleRecord {
  static constexpr int doubles = 13;

  static void write(const ParticleStore& store, std::size_t k, std::uint64_t tag, double* out) {
    std::memcpy(&out[0], &tag, sizeof tag);
    for (int a = 0; a < 3; ++a) out[1 + a] = store.centre(a)[k];
    for (int a = 0; a < 6; ++a) out[4 + a] = store.q(a)[k];
    out[10] = store.bounding_radius()[k];
    out[11] = store.inscribed_radius()[k];
    out[12] = store.sphere_radius()[k];
  }
  static std::uint64_t tag(const double* in) {
    std::uint64_t t;
    std::memcpy(&t, &in[0], sizeof t);
    return t;
  }
  // The particle with the radii it was sent with (not recomputed: a particle
  // made by add_axes has radii from its semi-axes, which the eigenvalues of
  // its Q would not give to the bit). Untyped: types only guide the search.
  static ParticleStore::Particle read(const double* in) {
    ParticleStore::Particle p;
    for (int a = 0; a < 3; ++a) p.centre_[std::size_t(a)] = in[1 + a];
    for (int a = 0; a < 6; ++a) p.q_[std::size_t(a)] = in[4 + a];
    p.bounding_ = in[10];
    p.inscribed_ = in[11];
    p.sphere_ = in[12];
    p.type_ = ParticleStore::untyped;
    return p;
  }
};

}  // namespace pwcontact::detail

namespace pwcontact::mpi {

namespace detail {

// An error found by some ranks, thrown on every rank (the message of the
// lowest of them): a rank that threw alone would leave the others waiting in
// the next collective call.
void throw_if_any(MPI_Comm comm, const std::string& error, const char* caller) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  int mine = error.empty() ? INT_MAX : rank, first = INT_MAX;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == INT_MAX) return;
  std::string message = error;
  int length = int(message.size());
  MPI_Bcast(&length, 1, MPI_INT, first, comm);
  message.resize(std::size_t(length));
  MPI_Bcast(message.data(), length, MPI_CHAR, first, comm);
  throw std::invalid_argument(std::string(caller) + " (MPI, rank " + std::to_string(first) +
                              "): " + message);
}

}  // namespace detail

namespace {

using detail::throw_if_any;

using pwcontact::detail::ParticleRecord;

// What Box's constructors hold a periodic box to (a Box made field by field
// may not be): positive, finite lengths (but the z of a two-dimensional
// box) and finite tilts. Open boundaries have no lengths.
bool box_is_valid(const Box& box) {
  if (!box.periodic) return true;
  for (int k = 0; k < 3; ++k) {
    const double l = box.length[std::size_t(k)];
    if (!(box.two_dimensional && k == 2) && !(l > 0 && std::isfinite(l))) return false;
    if (!std::isfinite(box.tilt[std::size_t(k)])) return false;
  }
  return true;
}

// The instruction sets by what they run: a CPU that runs one runs every
// one below it (the portable path runs everywhere).
constexpr Isa by_capability[4] = {Isa::fallback, Isa::sse2, Isa::avx2, Isa::avx512};
int isa_capability(Isa isa) {
  for (int k = 0; k < 4; ++k)
    if (by_capability[k] == isa) return k;
  return 0;  // (automatic is resolved before this is asked)
}
Isa isa_of_capability(int k) { return by_capability[k < 0 ? 0 : (k > 3 ? 3 : k)]; }

// Frees the communicators and the datatype made here, however we leave.
struct Handles {
  MPI_Comm cart = MPI_COMM_NULL, graph = MPI_COMM_NULL;
  MPI_Datatype record = MPI_DATATYPE_NULL;
  ~Handles() {
    if (graph != MPI_COMM_NULL) MPI_Comm_free(&graph);
    if (cart != MPI_COMM_NULL) MPI_Comm_free(&cart);
    if (record != MPI_DATATYPE_NULL) MPI_Type_free(&record);
  }
};

// The Cartesian grid of ranks over the box: along each axis, a particle's
// unit coordinate t in [0, 1] (periodic: its fractional coordinate s - floor
// s; open: (x - low) / (high - low) over the centres of every rank, or over
// the region trim_open_slabs leaves, clamped to [0, 1]) falls in slab
// floor(t dims).
struct Decomposition {
  screen::BoxGeometry geometry;
  std::array<int, 3> dims = {1, 1, 1}, coords = {0, 0, 0};
  std::array<double, 3> low = {0, 0, 0}, extent = {0, 0, 0};  // open axes
  std::array<double, 3> width = {0, 0, 0};                    // cell-space width along each axis
  // Open axes folded (fold_open_slabs): low and extent are then in the
  // fold's coordinate u, made with origin fold_origin.
  std::array<screen::OpenFold, 3> fold;
  std::array<double, 3> fold_origin = {0, 0, 0};

  // The coordinate along open axis k that low and extent are in.
  double open_coordinate(int k, double x) const {
    const auto K = std::size_t(k);
    return fold[K].pivot.empty() ? x : screen::folded_coordinate(fold[K], fold_origin[K], x);
  }

  std::array<double, 3> unit(const double x[3]) const {
    std::array<double, 3> t{};
    double s[3];
    geometry.reduced_fractional(x, s);  // (as the cells take a centre)
    for (int k = 0; k < 3; ++k)
      if (geometry.periodic[k])
        t[std::size_t(k)] = s[k];
      else if (extent[std::size_t(k)] > 0)
        t[std::size_t(k)] = std::clamp(
            (open_coordinate(k, x[k]) - low[std::size_t(k)]) / extent[std::size_t(k)], 0.0, 1.0);
    return t;
  }
  int slab(int k, double t) const {
    const int d = dims[std::size_t(k)];
    const double c = t * d;
    return c >= double(d - 1) ? d - 1 : (c > 0 ? int(c) : 0);
  }
};

std::vector<int> displacements(const std::vector<int>& counts, std::size_t& total);

// Whether cells of the largest reach over the centres' extent would be
// more than twice the particles of all ranks (as where the cell lists
// grow): then the slabs are split over less than the whole extent.
bool slabs_too_wide(MPI_Comm comm, const ParticleStore& particles,
                    const screen::BoxGeometry& geometry, double largest_reach,
                    const std::array<double, 3>& extent) {
  unsigned long long mine = particles.size(), total = 0;
  MPI_Allreduce(&mine, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
  double cells = 1;
  for (int k = 0; k < 3; ++k)
    cells *= geometry.periodic[k]
                 ? std::max(1.0, std::floor(geometry.width[std::size_t(k)] / largest_reach))
                 : extent[std::size_t(k)] / largest_reach + 1;
  return cells > 2.0 * double(total) && largest_reach > 0;
}

// Clusters far apart along an open axis: the slabs split the whole extent,
// so that two clusters 1e6 apart on four ranks left the two middle ranks
// without particles. Where the slabs are too wide, each open axis is folded
// as the cell lists fold it (screen::fold_empty_stretches), with the same
// fold on every rank: each rank's centres occupy their span less the
// stretches its own fold would take; the stretches between the union of
// every rank's occupied intervals (empty on every rank: a rank's shorter
// stretches only fold less) are chosen as the cell lists choose them, over
// the whole extent. The slabs then split the folded coordinate, and the
// ghost test stays exact: the fold is non-decreasing and moves no two
// points apart (beyond a rounding of the coordinate, which the ghosts'
// slack takes), so a partner within a reach of a subdomain is within it in
// folded coordinates too.
void fold_open_slabs(MPI_Comm comm, const ParticleStore& particles, double largest_reach,
                     Decomposition& grid) {
  const std::size_t n = particles.size();
  const double kept = 2 * largest_reach;  // (the cell lists' 4 cutoff R_max)
  for (int k = 0; k < 3; ++k) {
    const auto K = std::size_t(k);
    if (grid.geometry.periodic[k] || !(grid.extent[K] > 4 * kept)) continue;
    // This rank's occupied intervals, (from, to) in order.
    std::vector<double> occupied;
    if (n > 0) {
      const std::vector<double>& x = particles.centre(k);
      const auto [lo, hi] = std::minmax_element(x.begin(), x.end());
      double from = *lo;
      for (const auto& [start, length] : screen::stretches_to_fold(x.data(), n, *lo, *hi, kept)) {
        occupied.insert(occupied.end(), {from, start});
        from = start + length;
      }
      occupied.insert(occupied.end(), {from, *hi});
    }
    int size = 0, mine = int(occupied.size());
    MPI_Comm_size(comm, &size);
    std::vector<int> counts(std::size_t(size), 0), displs(std::size_t(size), 0);
    MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
    std::size_t total = 0;
    displs = displacements(counts, total);
    std::vector<double> all(total);
    MPI_Allgatherv(occupied.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(),
                   MPI_DOUBLE, comm);
    // Their union, and the stretches between.
    std::vector<std::pair<double, double>> intervals;
    for (std::size_t j = 0; j + 1 < all.size(); j += 2) intervals.push_back({all[j], all[j + 1]});
    std::sort(intervals.begin(), intervals.end());
    std::vector<std::pair<double, double>> stretches;
    double reached = -std::numeric_limits<double>::infinity();
    for (const auto& [from, to] : intervals) {
      if (from - reached > 2 * kept && std::isfinite(reached))
        stretches.push_back({reached, from - reached});
      reached = std::max(reached, to);
    }
    screen::choose_stretches(stretches, grid.extent[K], kept);
    if (stretches.empty()) continue;
    grid.fold_origin[K] = grid.low[K];
    screen::set_fold(grid.fold[K], stretches, kept, grid.low[K]);
    grid.extent[K] =
        screen::folded_coordinate(grid.fold[K], grid.low[K], grid.low[K] + grid.extent[K]);
    grid.low[K] = 0;
  }
}

// A few particles far from the rest along an open axis: the slabs split
// the centres' whole extent, so one particle at x = 1e9 beside 200,000 in a
// cube left every particle but itself to one of two ranks. Where cells of
// the largest reach over the whole extent would be more than twice the
// particles of all ranks (as where the cell lists grow), the slabs split
// instead the region without the farthest 1/64 of the centres at each end
// of each open axis: the lowest of the ranks' 1/64 quantiles to the highest
// of their 63/64 (ranks of 256 particles or more; the same numbers on every
// rank), when it is at most half the extent. The end slabs take the rest
// (Decomposition::unit clamps), and the ghost test stays exact: clamping
// is monotone and shrinks distances, so a partner within a reach of a
// subdomain is within it in unit coordinates too.
void trim_open_slabs(MPI_Comm comm, const ParticleStore& particles, Decomposition& grid) {
  const std::size_t n = particles.size();
  const screen::BoxGeometry& geometry = grid.geometry;
  // Per open axis: -(the lowest 1/64 quantile), the highest 63/64 quantile
  // (in the folded coordinate where the axis is folded: it is
  // non-decreasing).
  double quantiles[6], bounds[6];
  for (double& q : quantiles) q = -std::numeric_limits<double>::infinity();
  if (n >= 256) {  // (the cell lists' region of this rank's centres)
    std::array<double, 3> from, to;
    from.fill(std::numeric_limits<double>::infinity());
    to.fill(-std::numeric_limits<double>::infinity());
    screen::region_without_outliers(particles, geometry, from, to);
    for (int k = 0; k < 3; ++k) {
      quantiles[k] = -grid.open_coordinate(k, from[std::size_t(k)]);
      quantiles[3 + k] = grid.open_coordinate(k, to[std::size_t(k)]);
    }
  }
  MPI_Allreduce(quantiles, bounds, 6, MPI_DOUBLE, MPI_MAX, comm);
  for (int k = 0; k < 3; ++k) {
    const auto K = std::size_t(k);
    const double from = -bounds[k], to = bounds[3 + k];
    if (geometry.periodic[k] || !(to >= from) || !(to - from <= 0.5 * grid.extent[K])) continue;
    grid.low[K] = from;
    grid.extent[K] = to - from;
  }
}

// Records (ParticleRecord::doubles each) by destination, packed for a
// v-collective: counts and displacements in records.
struct Outbox {
  std::vector<std::vector<double>> by_destination;
  void pack(std::vector<double>& data, std::vector<int>& counts, std::vector<int>& displs) const {
    counts.assign(by_destination.size(), 0);
    displs.assign(by_destination.size(), 0);
    std::size_t total = 0;
    for (std::size_t d = 0; d < by_destination.size(); ++d) {
      const std::size_t n = by_destination[d].size() / ParticleRecord::doubles;
      if (n > std::size_t(INT_MAX) || total > std::size_t(INT_MAX))
        throw std::invalid_argument("more than 2^31 particles sent from one rank at once");
      counts[d] = int(n);
      displs[d] = int(total);
      total += n;
    }
    if (total > std::size_t(INT_MAX))
      throw std::invalid_argument("more than 2^31 particles sent from one rank at once");
    data.clear();
    data.reserve(total * ParticleRecord::doubles);
    for (const auto& v : by_destination) data.insert(data.end(), v.begin(), v.end());
  }
};

std::vector<int> displacements(const std::vector<int>& counts, std::size_t& total) {
  std::vector<int> displs(counts.size(), 0);
  total = 0;
  for (std::size_t d = 0; d < counts.size(); ++d) {
    displs[d] = int(total);
    total += std::size_t(counts[d]);
  }
  return displs;
}

// Sends each destination its records and appends what this rank receives
// to `received`: over the neighbour graph (destinations in the graph's
// order), or to any rank of `comm` (destinations by rank) when `graph` is
// MPI_COMM_NULL. Collective; an outbox too large for int counts is an error
// on every rank. Returns the bytes sent.
std::size_t exchange(const Outbox& outbox, MPI_Comm comm, MPI_Comm graph, MPI_Datatype record,
                     std::vector<double>& received) {
  std::vector<double> send;
  std::vector<int> send_counts, send_displs;
  std::string error;
  try {
    outbox.pack(send, send_counts, send_displs);
  } catch (const std::exception& e) {
    error = e.what();
  }
  throw_if_any(comm, error);
  std::vector<int> receive_counts(outbox.by_destination.size(), 0);
  if (graph == MPI_COMM_NULL)
    MPI_Alltoall(send_counts.data(), 1, MPI_INT, receive_counts.data(), 1, MPI_INT, comm);
  else
    MPI_Neighbor_alltoall(send_counts.data(), 1, MPI_INT, receive_counts.data(), 1, MPI_INT, graph);
  std::size_t count = 0;
  const std::vector<int> receive_displs = displacements(receive_counts, count);
  const std::size_t kept = received.size();
  received.resize(kept + count * ParticleRecord::doubles);
  if (graph == MPI_COMM_NULL)
    MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), record,
                  received.data() + kept, receive_counts.data(), receive_displs.data(), record,
                  comm);
  else
    MPI_Neighbor_alltoallv(send.data(), send_counts.data(), send_displs.data(), record,
                           received.data() + kept, receive_counts.data(), receive_displs.data(),
                           record, graph);
  return send.size() * sizeof(double);
}

template <class Tag>
DistributedReport screen_distributed(MPI_Comm comm, const ParticleStore& particles,
                                     const std::vector<Tag>& tags, const Box& box,
                                     const ScreenOptions& options, TaggedPairs& out,
                                     ScreenWorkspace* workspace) {
  out = {};
  DistributedReport report;
  report.given = particles.size();
  int size = 1, rank = 0;
  MPI_Comm_size(comm, &size);
  MPI_Comm_rank(comm, &rank);

  // The input, checked on every rank before anything moves.
  std::string error;
  if (tags.size() != particles.size())
    error = std::to_string(tags.size()) + " tags for " + std::to_string(particles.size()) +
            " particles";
  else if (!(options.cutoff > 0) || !std::isfinite(options.cutoff) ||
           !std::isfinite(options.cutoff * options.cutoff) ||
           !(options.cutoff * options.cutoff >= std::numeric_limits<double>::min()))
    error = "the cutoff must be positive and finite (and its square a normal number)";
  else if (options.threads < 0 || options.threads > pwcontact::detail::max_threads)
    error =
        "threads must be in 0 .. " + std::to_string(pwcontact::detail::max_threads) + " (0: all)";
  else if (!box_is_valid(box))
    // (Before the ranks compare their boxes: a NaN drops out of a min or max
    // reduction, and one rank alone then threw where the others waited.)
    error = "a periodic box needs positive, finite lengths and finite tilts";
  else
    error = particles.unset_message();
  // The instruction set the solve will run on (FMA or not changes mu^2's
  // last bits: SSE2 and AVX2 differ on half of random pairs), resolved here
  // so that a rank that cannot resolve it fails with the others.
  Isa isa = Isa::fallback;
  if (error.empty()) try {
      isa = resolve_isa(options.batch.isa);
    } catch (const std::exception& e) {
      error = e.what();
    }
  throw_if_any(comm, error);
  // Left automatic on every rank, the instruction set is the most capable
  // one every rank runs: ranks on CPUs of different generations (or with
  // PWCONTACT_ISA on some) then agree instead of being refused. Each CPU
  // that runs one of fallback < sse2 < avx2 < avx512 runs those below it.
  ScreenOptions agreed = options;
  {
    const int asked_automatic = options.batch.isa == Isa::automatic ? 1 : 0;
    const int mine[2] = {asked_automatic, isa_capability(isa)};
    int least[2] = {0, 0};
    MPI_Allreduce(mine, least, 2, MPI_INT, MPI_MIN, comm);
    if (least[0] == 1) {
      isa = isa_of_capability(least[1]);
      try {
        agreed.batch.isa = resolve_isa(isa);  // (runs here: a lower one of this CPU's)
      } catch (const std::exception& e) {
        error = e.what();
      }
      throw_if_any(comm, error);
    }
  }
  // The box and the options that decide the pairs, the same on every rank:
  // ranks that differ would pair particles by different rules, or wait for
  // each other in calls the others do not make.
  // (The solve's options too, and the instruction set each rank runs: they
  // decide mu^2's last bits, and so the pairs within rounding of the
  // cutoff. One named on some ranks must be the one the others run.)
  {
    constexpr int count = 15;
    const double mine[count] = {box.length[0],
                                box.length[1],
                                box.length[2],
                                box.tilt[0],
                                box.tilt[1],
                                box.tilt[2],
                                double(box.periodic),
                                double(box.two_dimensional),
                                options.cutoff,
                                double(options.with_mu2),
                                double(options.batch.iterations),
                                double(static_cast<int>(options.batch.precision)),
                                double(static_cast<int>(options.batch.accuracy)),
                                double(static_cast<int>(options.batch.formulation)),
                                double(static_cast<int>(isa))};
    double low[count], high[count];
    MPI_Allreduce(mine, low, count, MPI_DOUBLE, MPI_MIN, comm);
    MPI_Allreduce(mine, high, count, MPI_DOUBLE, MPI_MAX, comm);
    const char* names[count] = {"box lengths",       "box lengths",        "box lengths",
                                "box tilts",         "box tilts",          "box tilts",
                                "box kinds",         "box kinds",          "cutoffs",
                                "with_mu2 settings", "batch iterations",   "batch precisions",
                                "batch accuracies",  "batch formulations", "instruction sets"};
    for (int k = 0; k < count; ++k)
      if (low[k] != high[k]) {
        // (Thrown on every rank alike: every rank has the same low and high.)
        auto value = [k](double v) {
          return k == count - 1 ? std::string(isa_name(static_cast<Isa>(int(v))))
                                : pwcontact::detail::number_text(v);
        };
        throw std::invalid_argument(std::string("screen_pairs (MPI): the ranks give different ") +
                                    names[k] + " (from " + value(low[k]) + " to " + value(high[k]) +
                                    "); every rank must pass the same box and options" +
                                    (k == count - 1 ? " and run the same instruction set "
                                                      "(left automatic on every rank, the ranks "
                                                      "take the one all of them run)"
                                                    : ""));
      }
  }

  const double start = MPI_Wtime();
  Decomposition grid;
  grid.geometry = screen::BoxGeometry(box);
  const screen::BoxGeometry& geometry = grid.geometry;
  // The largest bounding radius and the extent of the centres along each
  // axis, over all ranks.
  double local_max[7] = {0,
                         -std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity()};
  for (std::size_t k = 0; k < particles.size(); ++k) {
    local_max[0] = std::max(local_max[0], particles.bounding_radius()[k]);
    for (int a = 0; a < 3; ++a) {
      const double x = particles.centre(a)[k];
      local_max[1 + a] = std::max(local_max[1 + a], x);
      local_max[4 + a] = std::max(local_max[4 + a], -x);  // -low
    }
  }
  double global_max[7];
  MPI_Allreduce(local_max, global_max, 7, MPI_DOUBLE, MPI_MAX, comm);
  const double largest_radius = global_max[0];
  const double largest_reach = options.cutoff * 2 * largest_radius;
  if (box.periodic) {
    const std::array<double, 3> widths = box.perpendicular_widths();
    for (int k = 0; k < 3; ++k)
      if (box.periodic_along(k) && !(2 * largest_reach <= widths[std::size_t(k)]))
        throw std::invalid_argument(
            "screen_pairs (MPI): the periodic box is too small for the cutoff: its width " +
            std::to_string(widths[std::size_t(k)]) + " across axis " + std::to_string(k) +
            " is less than twice the largest reach cutoff * 2 R_max = " +
            std::to_string(largest_reach) + " (the minimum image convention would miss pairs)");
  }
  // Open axes: differences of centres must be finite, as the
  // single-process screen requires, over all ranks' centres (each rank's
  // own screen sees only its own and its ghosts: with two centres at
  // -1e308 and 1e308 on different ranks, 2 ranks answered where 1, 3 and 4
  // refused). Thrown on every rank alike: every rank has the same extents.
  for (int k = 0; k < 3; ++k)
    if (!geometry.periodic[k] && global_max[1 + k] >= -global_max[4 + k])
      screen::check_centres_span("screen_pairs (MPI)", k, -global_max[4 + k], global_max[1 + k]);
  std::array<int, 3> dims = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    const auto K = std::size_t(k);
    if (!geometry.periodic[k] && global_max[1 + k] >= -global_max[4 + k]) {
      grid.low[K] = -global_max[4 + k];
      grid.extent[K] = global_max[1 + k] - grid.low[K];
    }
  }
  if (slabs_too_wide(comm, particles, geometry, largest_reach, grid.extent)) {
    fold_open_slabs(comm, particles, largest_reach, grid);
    if (slabs_too_wide(comm, particles, geometry, largest_reach, grid.extent))
      trim_open_slabs(comm, particles, grid);
  }
  for (int k = 0; k < 3; ++k) {
    const auto K = std::size_t(k);
    grid.width[K] = geometry.periodic[k] ? geometry.width[K] : grid.extent[K];
    // No split along an axis of no extent (a plane of centres in open
    // boundaries), nor along the z of a two-dimensional box, whatever z its
    // centres have.
    if (!(grid.width[K] > 0) || (k == 2 && box.two_dimensional)) dims[K] = 1;
  }
  // (Every axis of no extent: a point, or no particles at all; the ranks
  // along x then, all but one of them empty.)
  if (dims[0] == 1 && dims[1] == 1 && dims[2] == 1) dims[0] = 0;
  MPI_Dims_create(size, 3, dims.data());
  Handles handles;
  const int periods[3] = {geometry.periodic[0], geometry.periodic[1], geometry.periodic[2]};
  MPI_Cart_create(comm, 3, dims.data(), periods, 0, &handles.cart);
  MPI_Comm cart = handles.cart;
  MPI_Comm_rank(cart, &rank);
  MPI_Cart_coords(cart, rank, 3, grid.coords.data());
  grid.dims = dims;
  report.dims = dims;
  report.coords = grid.coords;
  MPI_Type_contiguous(ParticleRecord::doubles, MPI_DOUBLE, &handles.record);
  MPI_Type_commit(&handles.record);
  auto rank_at = [&](const std::array<int, 3>& c) {
    int r = 0;
    MPI_Cart_rank(cart, c.data(), &r);
    return r;
  };

  // The ghost test, in unit coordinates along each axis: particle j goes to
  // the ranks r whose subdomain lies within cutoff (R_j + min(R_j,
  // R_max(r))) of its centre (cell-space distance / width), plus a slack for
  // the rounding of the coordinates (as the cell lists' coarse test).
  // (Periodic axes: centres may lie any number of box lengths away, and their
  // fractional coordinates err by eps of their size; open axes: as the cell
  // lists' coordinates from the origin of their region, screen::coarse_slack.)
  double periodic_coordinates = 0;
  for (int k = 0; k < 3; ++k)
    if (geometry.periodic[k])
      periodic_coordinates = std::max({periodic_coordinates, global_max[1 + k], global_max[4 + k]});
  const double slack =
      screen::coarse_slack(geometry, std::max(largest_reach, periodic_coordinates), grid.extent);
  auto unit_reach = [&](int k, double reach) {
    const double w = grid.width[std::size_t(k)];
    return w > 0 ? (reach + slack) / w + 8 * std::numeric_limits<double>::epsilon()
                 : std::numeric_limits<double>::infinity();
  };
  // The neighbourhood: every rank within the largest reach along each axis
  // (slabs -m .. m; m = 1 unless a particle reaches across more than a
  // slab), each once and not this rank (a particle of this rank is paired
  // with its own images by the local screen's minimum image). One or two
  // ranks along a periodic axis make the same rank a neighbour on both sides:
  // it is listed once, and receives each particle once.
  //
  // The exchange is MPI_Neighbor_alltoallv over a distributed graph of these
  // ranks (26 at most when the reach is within a subdomain): each rank's
  // cost is that of its neighbours and its ghosts, whatever the number of
  // ranks; MPI_Alltoallv with zero counts would cost O(P) per rank in counts
  // alone, O(P^2) over the machine.
  std::array<int, 3> reach_slabs = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    const auto K = std::size_t(k);
    const double m = std::floor(unit_reach(k, largest_reach) * dims[K]) + 1;
    const int cap = geometry.periodic[k] ? dims[K] : dims[K] - 1;
    reach_slabs[K] = dims[K] == 1 ? 0 : (m >= double(cap) ? cap : int(m));
  }
  const std::array<int, 3> span = {2 * reach_slabs[0] + 1, 2 * reach_slabs[1] + 1,
                                   2 * reach_slabs[2] + 1};
  // The rank at each offset (-1: outside open boundaries), and the sorted
  // neighbour ranks.
  std::vector<int> rank_of_offset(std::size_t(span[0] * span[1] * span[2]), -1);
  std::vector<int> neighbours;
  for (int a = 0; a < span[0]; ++a)
    for (int b = 0; b < span[1]; ++b)
      for (int c = 0; c < span[2]; ++c) {
        const int offset[3] = {a - reach_slabs[0], b - reach_slabs[1], c - reach_slabs[2]};
        std::array<int, 3> at{};
        bool inside = true;
        for (int k = 0; k < 3; ++k) {
          const auto K = std::size_t(k);
          int v = grid.coords[K] + offset[k];
          if (geometry.periodic[k])
            v = ((v % dims[K]) + dims[K]) % dims[K];
          else if (v < 0 || v >= dims[K])
            inside = false;
          at[K] = v;
        }
        if (!inside) continue;
        const int r = rank_at(at);
        rank_of_offset[std::size_t((a * span[1] + b) * span[2] + c)] = r;
        if (r != rank) neighbours.push_back(r);
      }
  std::sort(neighbours.begin(), neighbours.end());
  neighbours.erase(std::unique(neighbours.begin(), neighbours.end()), neighbours.end());
  report.neighbours = neighbours.size();
  // (The neighbourhood is symmetric: every rank takes the same offsets.)
  const int degree = int(neighbours.size());
  MPI_Dist_graph_create_adjacent(cart, degree, neighbours.data(), MPI_UNWEIGHTED, degree,
                                 neighbours.data(), MPI_UNWEIGHTED, MPI_INFO_NULL, 0,
                                 &handles.graph);

  // 1. Migration: each particle to the rank whose subdomain holds its
  // centre. When every particle of every rank stays or goes to a neighbour
  // (as after a move), over the graph (MPI_Neighbor_alltoallv: a rank's cost
  // that of its neighbours); otherwise from any rank to any rank
  // (MPI_Alltoallv: counts for every rank, O(P) per rank), so that the
  // particles may start anywhere (read by one rank, round robin).
  std::vector<double> owned;  // records
  {
    std::vector<int> destination(particles.size());
    int far = 0;
    for (std::size_t k = 0; k < particles.size(); ++k) {
      const double x[3] = {particles.centre(0)[k], particles.centre(1)[k], particles.centre(2)[k]};
      const std::array<double, 3> t = grid.unit(x);
      const int to = rank_at({grid.slab(0, t[0]), grid.slab(1, t[1]), grid.slab(2, t[2])});
      destination[k] = to;
      if (to != rank && !std::binary_search(neighbours.begin(), neighbours.end(), to)) far = 1;
    }
    int any_far = 0;
    MPI_Allreduce(&far, &any_far, 1, MPI_INT, MPI_MAX, cart);
    report.migration_by_neighbours = any_far == 0;
    Outbox outbox;
    outbox.by_destination.resize(any_far ? std::size_t(size) : neighbours.size());
    double record[ParticleRecord::doubles];
    for (std::size_t k = 0; k < particles.size(); ++k) {
      const int to = destination[k];
      ParticleRecord::write(particles, k, std::uint64_t(tags[k]), record);
      if (to == rank) {
        owned.insert(owned.end(), record, record + ParticleRecord::doubles);
        continue;
      }
      const std::size_t at =
          any_far ? std::size_t(to)
                  : std::size_t(std::lower_bound(neighbours.begin(), neighbours.end(), to) -
                                neighbours.begin());
      outbox.by_destination[at].insert(outbox.by_destination[at].end(), record,
                                       record + ParticleRecord::doubles);
      ++report.sent_away;
    }
    report.migration_bytes_sent =
        exchange(outbox, cart, any_far ? MPI_COMM_NULL : handles.graph, handles.record, owned);
  }
  const std::size_t owned_count = owned.size() / ParticleRecord::doubles;
  report.owned = owned_count;
  const double migrated = MPI_Wtime();
  report.seconds_migration = migrated - start;

  // 2. Ghosts.
  // Each neighbour's largest bounding radius (-1 without particles): j goes
  // to rank r only when within cutoff (R_j + min(R_j, R_max(r))) of r's
  // subdomain (the owner rule above), and a rank with no particles receives
  // none.
  double own_largest = owned_count ? 0 : -1;
  for (std::size_t p = 0; p < owned_count; ++p)
    own_largest = std::max(own_largest, owned[p * ParticleRecord::doubles + 10]);
  report.largest_radius = own_largest;
  std::vector<double> largest_of(neighbours.size(), -1);
  MPI_Neighbor_allgather(&own_largest, 1, MPI_DOUBLE, largest_of.data(), 1, MPI_DOUBLE,
                         handles.graph);
  double largest_neighbour = -1;
  for (double r : largest_of) largest_neighbour = std::max(largest_neighbour, r);
  std::vector<double> ghosts;
  {
    Outbox outbox;
    outbox.by_destination.resize(neighbours.size());
    std::vector<int> to;  // the neighbours (indices) one particle goes to
    // Per axis: the offsets of the slabs within reach, and their distance
    // (in unit coordinates) from the particle.
    std::vector<std::pair<int, double>> slabs[3];
    for (std::size_t p = 0; largest_neighbour >= 0 && p < owned_count; ++p) {
      const double* record = owned.data() + p * ParticleRecord::doubles;
      const double x[3] = {record[1], record[2], record[3]};
      const std::array<double, 3> t = grid.unit(x);
      const double reach = options.cutoff * (record[10] + std::min(record[10], largest_neighbour));
      for (int k = 0; k < 3; ++k) {
        const auto K = std::size_t(k);
        slabs[k].clear();
        const double r = unit_reach(k, reach);
        for (int o = -reach_slabs[K]; o <= reach_slabs[K]; ++o) {
          // The slab at this offset from the particle's own, unwrapped.
          const double lo = double(grid.coords[K] + o) / dims[K];
          const double hi = double(grid.coords[K] + o + 1) / dims[K];
          const double distance = std::max({0.0, lo - t[K], t[K] - hi});
          if (distance <= r) slabs[k].push_back({o + reach_slabs[K], distance});
        }
      }
      to.clear();
      for (const auto& [a, da] : slabs[0])
        for (const auto& [b, db] : slabs[1])
          for (const auto& [c, dc] : slabs[2]) {
            const int r = rank_of_offset[std::size_t((a * span[1] + b) * span[2] + c)];
            if (r < 0 || r == rank) continue;
            const auto n = std::size_t(std::lower_bound(neighbours.begin(), neighbours.end(), r) -
                                       neighbours.begin());
            if (largest_of[n] < 0) continue;
            const double reach_n =
                options.cutoff * (record[10] + std::min(record[10], largest_of[n]));
            if (da <= unit_reach(0, reach_n) && db <= unit_reach(1, reach_n) &&
                dc <= unit_reach(2, reach_n))
              to.push_back(int(n));
          }
      std::sort(to.begin(), to.end());
      to.erase(std::unique(to.begin(), to.end()), to.end());
      for (int n : to)
        outbox.by_destination[std::size_t(n)].insert(outbox.by_destination[std::size_t(n)].end(),
                                                     record, record + ParticleRecord::doubles);
    }
    ghosts.clear();
    report.ghost_bytes_sent = exchange(outbox, cart, handles.graph, handles.record, ghosts);
  }
  const std::size_t ghost_count = ghosts.size() / ParticleRecord::doubles;
  report.ghosts = ghost_count;
  const double exchanged = MPI_Wtime();
  report.seconds_ghosts = exchanged - migrated;

  // 3. The local screen, on the own and ghost particles in the order of
  // their tags (a pair's lower index is then its lower tag, as in the whole
  // scene indexed by tag), and the owner rule.
  struct Entry {
    std::uint64_t tag;
    const double* record;
    bool own;
  };
  std::vector<Entry> entries;
  entries.reserve(owned_count + ghost_count);
  for (std::size_t p = 0; p < owned_count; ++p) {
    const double* record = owned.data() + p * ParticleRecord::doubles;
    entries.push_back({ParticleRecord::tag(record), record, true});
  }
  for (std::size_t p = 0; p < ghost_count; ++p) {
    const double* record = ghosts.data() + p * ParticleRecord::doubles;
    entries.push_back({ParticleRecord::tag(record), record, false});
  }
  // (By the tags' digits, not by comparisons: std::sort took a third of
  // the time the local store and the owner rule take on a 1M-particle rank.
  // Stable, so a tag given twice is found next to itself.)
  screen::radix_sort_pair_keys(entries, 32, [](const Entry& e) { return e.tag; });
  for (std::size_t k = 1; k < entries.size(); ++k)
    if (entries[k].tag == entries[k - 1].tag) {
      error = "tag " + std::to_string(entries[k].tag) + " is given to two particles";
      break;
    }
  throw_if_any(cart, error);
  const int threads = pwcontact::detail::thread_count(options.threads, "screen_pairs (MPI)");
  ParticleStore store;
  ScreenedPairs pairs;
  try {
    // Sized once and filled in parallel (added one at a time, every array
    // of the store grew particle by particle).
    store.resize(entries.size());
    const std::ptrdiff_t count = std::ptrdiff_t(entries.size());
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::ptrdiff_t k = 0; k < count; ++k)
      store.set_particle(std::size_t(k), ParticleRecord::read(entries[std::size_t(k)].record));
    report.screen = workspace ? pwcontact::screen_pairs(store, box, agreed, pairs, *workspace)
                              : pwcontact::screen_pairs(store, box, agreed, pairs);
  } catch (const std::exception& e) {
    error = e.what();
  }
  throw_if_any(cart, error);
  // The owner rule. The pairs come by their first particle, and their second
  // is anywhere in the store: its radius (the store's, the record's number)
  // and its entry are fetched a few pairs ahead (each a cache miss
  // otherwise, most of the rule's time).
  const std::vector<double>& bounding = store.bounding_radius();
  constexpr std::size_t ahead = 16;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (k + ahead < pairs.size()) {
      __builtin_prefetch(&bounding[pairs.j[k + ahead]]);
      __builtin_prefetch(&entries[pairs.j[k + ahead]]);
    }
    const std::uint32_t a = pairs.i[k], b = pairs.j[k];  // (a has the smaller tag)
    const bool keeper_own = bounding[b] < bounding[a] ? entries[b].own : entries[a].own;
    if (!keeper_own) continue;
    out.i.push_back(entries[a].tag);
    out.j.push_back(entries[b].tag);
    if (options.with_mu2) out.mu2.push_back(pairs.mu2[k]);
  }
  report.seconds_screen = MPI_Wtime() - exchanged;
  return report;
}

}  // namespace

DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint64_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out) {
  return screen_distributed(comm, particles, tags, box, options, out, nullptr);
}

DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint32_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out) {
  return screen_distributed(comm, particles, tags, box, options, out, nullptr);
}

DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint64_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out,
                               ScreenWorkspace& workspace) {
  return screen_distributed(comm, particles, tags, box, options, out, &workspace);
}

DistributedReport screen_pairs(MPI_Comm comm, const ParticleStore& particles,
                               const std::vector<std::uint32_t>& tags, const Box& box,
                               const ScreenOptions& options, TaggedPairs& out,
                               ScreenWorkspace& workspace) {
  return screen_distributed(comm, particles, tags, box, options, out, &workspace);
}

TaggedPairs gather_pairs(MPI_Comm comm, const TaggedPairs& local, int root) {
  int size = 1, rank = 0;
  MPI_Comm_size(comm, &size);
  MPI_Comm_rank(comm, &rank);
  std::string error;
  if (local.j.size() != local.i.size() ||
      (!local.mu2.empty() && local.mu2.size() != local.i.size()))
    error = "i, j and mu2 differ in length";
  // mu2 from every rank when any has it (a rank with no pairs has none).
  int has_mu2 = local.mu2.empty() ? 0 : 1, any_mu2 = 0;
  MPI_Allreduce(&has_mu2, &any_mu2, 1, MPI_INT, MPI_MAX, comm);
  unsigned long long total = 0, count = local.size();
  MPI_Allreduce(&count, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, comm);
  if (error.empty() && total > (unsigned long long)INT_MAX)
    error = "more than 2^31 - 1 pairs for one rank";
  if (error.empty() && any_mu2 && local.mu2.size() != local.i.size())
    error = "some ranks have mu2 and this one has not";
  if (error.empty() && (root < 0 || root >= size))
    error = "root " + std::to_string(root) + " is not a rank of the " + std::to_string(size);
  throw_if_any(comm, error, "gather_pairs");
  const bool with_mu2 = any_mu2 != 0;
  int n = int(local.size());
  std::vector<int> counts(rank == root ? std::size_t(size) : 0);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, root, comm);
  std::size_t received = 0;
  std::vector<int> displs;
  if (rank == root) displs = displacements(counts, received);
  TaggedPairs all_pairs;
  all_pairs.i.resize(received);
  all_pairs.j.resize(received);
  MPI_Gatherv(local.i.data(), n, MPI_UINT64_T, all_pairs.i.data(), counts.data(), displs.data(),
              MPI_UINT64_T, root, comm);
  MPI_Gatherv(local.j.data(), n, MPI_UINT64_T, all_pairs.j.data(), counts.data(), displs.data(),
              MPI_UINT64_T, root, comm);
  if (with_mu2) {
    all_pairs.mu2.resize(received);
    MPI_Gatherv(local.mu2.data(), n, MPI_DOUBLE, all_pairs.mu2.data(), counts.data(), displs.data(),
                MPI_DOUBLE, root, comm);
  }
  if (rank != root) return {};
  std::vector<std::size_t> order(received);
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    return std::pair(all_pairs.i[x], all_pairs.j[x]) < std::pair(all_pairs.i[y], all_pairs.j[y]);
  });
  TaggedPairs sorted;
  sorted.i.resize(received);
  sorted.j.resize(received);
  if (with_mu2) sorted.mu2.resize(received);
  for (std::size_t k = 0; k < received; ++k) {
    sorted.i[k] = all_pairs.i[order[k]];
    sorted.j[k] = all_pairs.j[order[k]];
    if (with_mu2) sorted.mu2[k] = all_pairs.mu2[order[k]];
  }
  return sorted;
}

}  // namespace pwcontact::mpi
