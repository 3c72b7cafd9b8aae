// Cell lists by size class: candidate pairs of a scene without making every
// cell as large as the largest particle's reach.
//
// Particles fall into classes by bounding radius R, halving from the
// largest: class c holds R in (R_max / 2^(c+1), R_max / 2^c] (the last class
// takes everything smaller). Each class has its own grid, with cells about
// as wide as the reach of two of its largest members, cutoff * 2 R_c
// (thinner along z). A pair of classes a, b with R_b >= R_a (b <= a) is
// found from the members of a in the grid of b: their reach cutoff (R_i +
// R_j) is at most cutoff R_i + cutoff R_b, and a member of a visits the
// cells of b within that of it along each axis. Each pair is met once:
// within a class from its earlier place in cell order, across classes from
// the smaller particle. A coarse distance test on wrapped positions drops
// most pairs before anything else about them is read.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <type_traits>
#include <utility>
#include <vector>

#include <omp.h>

#include "parallel_errors.hpp"
#include "pwcontact/screen.hpp"
#include "screen/pair_prefilters.hpp"
#include "screen/uninitialized.hpp"

namespace pwcontact::detail {
// Throws std::invalid_argument ("Box: ...") for a periodic box that Box's
// factories would refuse (particle_store.cpp, beside them).
void check_box(const Box& box);
}  // namespace pwcontact::detail

namespace pwcontact::screen {

// x wrapped into [0, l]. fmod is exact: the residue of the stored number,
// whatever its number of box lengths (no image count that could overflow,
// no rounding of a large x - n l); a negative residue then takes one
// rounding, to eps l, in adding l.
inline double wrap_into_box(double x, double l) {
  // The common cases first, with fmod's results: within one box length of
  // the box, fmod(x, l) is x or x - l (exact).
  if (x >= 0 && x < l) return x;
  if (x < 0 && x >= -l) return x + l;
  if (x >= l && x < 2 * l) return x - l;
  const double w = std::fmod(x, l);
  return w < 0 ? w + l : w;
}

// What the candidate search reads of every member it compares: the centre
// wrapped into [0, L] (periodic; as given otherwise) and the bounding
// radius, for a coarse distance test and the exact bounding-sphere test, in
// one half cache line.
struct CoarseMember {
  double wrapped[3];
  double bounding;
};

// The rest of a member, read only for the pairs that pass the coarse test
// (a few in a hundred), in one cache line: its form, inscribed radius,
// index, and whether it is a sphere (its radius then sqrt(q[0]), as the
// store computes it).
struct alignas(64) Member {
  double q[6];
  double inscribed;
  std::uint32_t index;  // in the particle store
  std::uint32_t sphere;
  double sphere_radius() const { return sphere ? std::sqrt(q[0]) : 0; }
};
static_assert(sizeof(Member) == 64, "a member's detail is one cache line");

// One class's grid: its members sorted by cell (counting sort, stable, so
// the order is that of the particle indices within a cell), copied in that
// order: a cell's members are then contiguous in memory, and so are those
// of a run of cells along z (the search streams through rows of cells
// instead of jumping across the particle arrays).
struct ClassGrid {
  double largest_reach = 0;  // cutoff * the largest bounding radius of the class
  std::array<int, 3> cells = {1, 1, 1};
  std::array<double, 3> inverse_side = {0, 0, 0};  // cells per unit length
  std::vector<std::uint32_t> cell_start;           // cells + 1 offsets into the members
  UninitializedVector<CoarseMember> coarse;        // by member
  UninitializedVector<Member> member;              // by member
  std::size_t size() const { return member.size(); }
};

// The box as the cell lists use it: which axes are periodic, the lattice
// vectors (the columns of h, Box), and the perpendicular widths.
//
// Cells are laid out in cell space: along a periodic axis k the fractional
// coordinate s_k = (h^-1 x)_k times the perpendicular width w_k (x_k itself
// when the box is orthorhombic), along an open axis the coordinate from the
// lowest centre. Two centres a distance d apart differ by at most d in
// every cell-space coordinate (|delta s_k| w_k is their distance across
// the planes of the other two lattice vectors), so that the cells within a
// reach of a member along each cell-space axis hold every partner within
// that reach, whatever the tilts.
// Along an open axis the differences of centres from `low` to `high` must
// be finite: std::invalid_argument ("<who>: the centres span more than the
// largest double ...") otherwise.
void check_centres_span(const char* who, int axis, double low, double high);

struct BoxGeometry {
  std::array<bool, 3> periodic = {false, false, false};
  bool triclinic = false;            // periodic with a tilt
  double h[3][3] = {};               // lattice vectors as columns (periodic axes)
  std::array<double, 3> width = {};  // perpendicular widths (periodic axes)

  BoxGeometry() = default;
  // Throws std::invalid_argument for a periodic box that Box's factories
  // would refuse (a Box filled in by hand: lengths not positive and finite,
  // tilts or lattice vectors not finite, a flat box).
  explicit BoxGeometry(const Box& box);

  double inverse_diagonal[3] = {};  // 1 / h[k][k] (periodic axes)

  // h^-1 x (upper triangular: back substitution), periodic axes only. By
  // the reciprocals of the diagonal rather than divisions (three dependent
  // divisions per particle and per image): each s[k] within a few eps of
  // its exact value either way, which the slack of the cells' windows and
  // of the coarse test allows for.
  void fractional(const double x[3], double s[3]) const {
    s[2] = periodic[2] ? x[2] * inverse_diagonal[2] : 0;
    s[1] = (x[1] - h[1][2] * s[2]) * inverse_diagonal[1];
    s[0] = (x[0] - h[0][1] * s[1] - h[0][2] * s[2]) * inverse_diagonal[0];
  }
  // s - floor(s), in [0, 1], by a conversion to a 64-bit integer where s
  // has a fraction (|s| < 2^52) instead of a call to floor (the library is
  // built for the baseline instruction set, which has no rounding
  // instruction); 0 for larger s, which are whole numbers.
  static double fraction_of(double s) {
    if (!(std::abs(s) < 4503599627370496.0)) return 0;
    const double whole = double(static_cast<std::int64_t>(s));  // toward zero
    return s - (whole > s ? whole - 1 : whole);
  }
  // Whether fractional coordinates s lie within a few box lengths of the
  // box, where wrapping through them is accurate to a few eps of the box's
  // lengths; beyond, the rounding of s itself (eps |s|) would move the
  // wrapped position by eps |s| box lengths, and beyond 2^52 by the whole
  // residue (wrap_far then).
  static bool near_box(const double s[3]) {
    constexpr double near = 4;
    return std::abs(s[0]) <= near && std::abs(s[1]) <= near && std::abs(s[2]) <= near;
  }
  // A triclinic box's wrap of a centre far from it: x less whole lattice
  // vectors, subtracted in double-double arithmetic (one lattice vector at
  // a time, from the last, until the centre's fractional coordinate along
  // it lies in [0, 1] as fractional() computes it from the result): within
  // a few eps of the box's lengths up to ~1/eps box lengths away, and
  // eps^2 |x| beyond, where wrapping through s lost eps |x|.
  void wrap_far(const double x[3], double w[3]) const;
  // x wrapped into the box along the periodic axes. Orthorhombic: the exact
  // residue per axis (wrap_into_box); triclinic: through the fractional
  // coordinates, to a few eps of the lengths (wrap_far beyond a few box
  // lengths).
  void wrap(const double x[3], double w[3]) const {
    if (!triclinic) {
      for (int k = 0; k < 3; ++k) w[k] = periodic[k] ? wrap_into_box(x[k], h[k][k]) : x[k];
      return;
    }
    double s[3];
    fractional(x, s);
    if (!near_box(s)) {
      wrap_far(x, w);
      return;
    }
    for (int k = 0; k < 3; ++k)
      if (periodic[k]) s[k] = fraction_of(s[k]);  // (s is rounded already: no fmod needed)
    for (int r = 0; r < 3; ++r) {
      if (!periodic[r]) {
        w[r] = x[r];
        continue;
      }
      w[r] = 0;
      for (int c = r; c < 3; ++c)
        if (periodic[c]) w[r] += h[r][c] * s[c];
    }
  }
  // The fractional coordinates of x reduced into [0, 1] along the periodic
  // axes (where in the box wrap() places it): s - floor s near the box;
  // beyond, those of the wrapped position, clamped (they lie in [0, 1] to
  // rounding; s itself is eps |s| off there, beyond 2^52 box lengths
  // wholly). Along open axes s is meaningless: the callers take x there.
  void reduced_fractional(const double x[3], double s[3]) const {
    fractional(x, s);
    if (near_box(s)) {
      for (int k = 0; k < 3; ++k)
        if (periodic[k]) s[k] = fraction_of(s[k]);
      return;
    }
    double w[3];
    wrap(x, w);
    fractional(w, s);
    for (int k = 0; k < 3; ++k)
      if (periodic[k]) s[k] = std::clamp(s[k], 0.0, 1.0);
  }
  // sum_k shift[k] a_k: the image shift of a run of cells.
  void shift_vector(const int shift[3], double v[3]) const {
    for (int r = 0; r < 3; ++r) {
      v[r] = 0;
      for (int c = r; c < 3; ++c)
        if (shift[c] != 0) v[r] += double(shift[c]) * h[r][c];
    }
  }
  // r by the minimum image: the nearest lattice point subtracted in
  // fractional coordinates (per axis when orthorhombic).
  void minimum_image(double r[3]) const {
    if (!triclinic) {
      for (int k = 0; k < 3; ++k)
        if (periodic[k]) r[k] -= h[k][k] * std::nearbyint(r[k] / h[k][k]);
      return;
    }
    double s[3];
    fractional(r, s);
    int shift[3];
    for (int k = 0; k < 3; ++k) shift[k] = periodic[k] ? -int(std::nearbyint(s[k])) : 0;
    double v[3];
    shift_vector(shift, v);
    for (int k = 0; k < 3; ++k) r[k] += v[k];
  }
};

// Along an open axis, the cell-space coordinate may fold the long empty
// stretches between the centres (two clusters far apart, a few particles
// far from the rest), so that the grid covers the particles rather than the
// space between them. The fold is a map u(x) that is non-decreasing and
// moves no two points farther apart (1-Lipschitz): a member within a reach
// of a position stays within that reach in cell space, so runs_within
// misses no partner, whatever the fold; it only brings far centres nearer,
// and the coarse test, in true coordinates, drops those pairs. Stretch j,
// [pivot_j, pivot_j + removed_j], maps to one point: u(x) = x - offset_j
// beyond it and u = held_j within it, where offset_j = offset_{j-1} +
// removed_j, held_j = pivot_j - offset_{j-1} and offset_{-1} is the
// origin (fold_base). u is computed as max(held_j, x - offset_j) for the
// last pivot at or below x, with held_j computed as u is just below the
// pivot (and at least held_{j-1}): continuous at every pivot as computed,
// non-decreasing, and 1-Lipschitz to within the rounding of x - offset_j,
// eps of u, as x - origin is without a fold. The roundings of the offsets
// only move where a held value gives way to x - offset_j.
struct OpenFold {
  std::vector<double> pivot, removed;  // the stretches, by pivot
  std::vector<double> held, offset;    // from them and the origin (fold_base)
};

// u(x) of a fold made with origin `origin` (x - origin without one).
inline double folded_coordinate(const OpenFold& f, double origin, double x) {
  if (f.pivot.empty()) return x - origin;
  const std::size_t j =
      std::size_t(std::upper_bound(f.pivot.begin(), f.pivot.end(), x) - f.pivot.begin());
  return j == 0 ? x - origin : std::max(f.held[j - 1], x - f.offset[j - 1]);
}

struct CellLists {
  Box box;
  BoxGeometry geometry;
  std::array<double, 3> origin = {0, 0, 0};  // open axes: the lowest centre coordinates
  std::array<OpenFold, 3> fold;              // open axes: folded stretches (mostly none)
  std::vector<ClassGrid> grids;              // by class, largest radii first
  // How far the coarse distance test (wrapped positions, reach rounded) may
  // be from the exact one, as a length: it lets a pair through when its
  // distance is within this of the reach, and the exact test decides.
  double slack = 0;
  double cutoff = 1;
  double largest_reach = 0;  // cutoff * the largest bounding radius
  // Every particle the same bounding and inscribed radius (to 1e-12): the
  // coarse test then compares every pair with one reach, read from no member.
  bool identical_shapes = false;
  bool one_type = false;  // every particle of one shape type

  // The cell-space coordinate of x along open axis k (OpenFold).
  double open_coordinate(int k, double x) const {
    return folded_coordinate(fold[std::size_t(k)], origin[std::size_t(k)], x);
  }
  // A region [from, to] of centres' coordinates in the coordinates of a
  // folded open axis, u(from) and u(to) (unchanged elsewhere).
  void fold_region(std::array<double, 3>& from, std::array<double, 3>& to) const {
    for (int k = 0; k < 3; ++k)
      if (!fold[std::size_t(k)].pivot.empty()) {
        from[std::size_t(k)] = open_coordinate(k, from[std::size_t(k)]);
        to[std::size_t(k)] = open_coordinate(k, to[std::size_t(k)]);
      }
  }
  // The cell-space coordinates of a wrapped centre (see BoxGeometry).
  void cell_space(const double w[3], double u[3]) const {
    if (geometry.triclinic) {
      double s[3];
      geometry.fractional(w, s);
      for (int k = 0; k < 3; ++k)
        u[k] = geometry.periodic[k] ? s[k] * geometry.width[k] : open_coordinate(k, w[k]);
      return;
    }
    for (int k = 0; k < 3; ++k) u[k] = geometry.periodic[k] ? w[k] : open_coordinate(k, w[k]);
  }
  // The cell-space coordinates of a centre as given (wrapped on the way):
  // for a triclinic box straight from its fractional coordinates, without
  // the Cartesian wrapped position.
  void cell_space_of_centre(const double x[3], double u[3]) const {
    if (geometry.triclinic) {
      double s[3];
      geometry.reduced_fractional(x, s);
      for (int k = 0; k < 3; ++k)
        u[k] = geometry.periodic[k] ? s[k] * geometry.width[k] : open_coordinate(k, x[k]);
      return;
    }
    double w[3];
    geometry.wrap(x, w);
    cell_space(w, u);
  }
  // The cell of a cell-space coordinate along axis k.
  int cell_of(const ClassGrid& grid, int k, double u) const {
    // Clamped before the conversion, which is undefined beyond int's range:
    // clamping is monotone and shrinks distances, so a member within a reach
    // of a position along the axis stays within the cells runs_within gives.
    const int n = grid.cells[k];
    const double c = u * grid.inverse_side[k];
    return c >= double(n - 1) ? n - 1 : (c > 0 ? int(c) : 0);
  }
};

// The coarse test's slack for a largest reach and the width of the grid's
// region along each open axis: the wrapped positions are within a few eps
// of the box's lengths of their exact values, the cell-space coordinates
// within a few eps of their own size, and the reach within a few eps of
// itself; a thousand times the largest. (Periodic: the wrapped positions,
// within the box whatever the centres: their coordinates at most the sum of
// a row of h. Open: a centre is its own wrapped position, exact, and its
// cell-space coordinate x - origin errs by eps of itself, at most the
// region's width plus a reach for a member within a reach of one inside
// it; members beyond that lie in the outer cells, as do their partners,
// whatever the rounding. So the centres' distance from the origin of
// coordinates, or a particle far from the rest, does not widen the slack:
// taken from the coordinates, one particle at x = 1e15 made every window
// span the grid.)
double coarse_slack(const BoxGeometry& geometry, double reach,
                    const std::array<double, 3>& open_width);

// The cells of a grid: `side[k]` wide along axis k where that gives at most
// `limit` cells in all, else grown alike along every axis until it does;
// across a periodic axis whole cells over the box's width, along an open
// axis over the region [from[k] - margin, to[k] + margin] (one cell more,
// for the rounding at its ends); at most 1e6 cells along an axis, wider
// there where the region needs more. Sets grid.cells and grid.inverse_side
// and returns the factor by which the cells grew (1: as asked; the widest
// axis's factor).
double size_cells(const BoxGeometry& geometry, const std::array<double, 3>& side,
                  const std::array<double, 3>& from, const std::array<double, 3>& to, double margin,
                  double limit, ClassGrid& grid);

// The region of the centres along the open axes without the farthest 1/64
// of them at each end: [from, to] per open axis (periodic axes: unchanged).
// A few particles far from the rest along an open axis would otherwise make
// the cells grow alike along every axis until there is one across the
// others (one particle at x = 1e9 beside 200,000 in a cube: one cell across
// y and z, every pair compared). Where the cells must grow, a grid over this
// region instead puts the far ones in its outer cells (cell_of clamps,
// runs_within stays correct), at most 3/32 of them.
void region_without_outliers(const ParticleStore& particles, const BoxGeometry& geometry,
                             std::array<double, 3>& from, std::array<double, 3>& to);

// Folds the long empty stretches of the open axes (OpenFold) between the
// centres in [low, high]: stretches longer than 2 keep between the centres
// found by a histogram of the axis (up to n bins, each with its lowest and
// highest centre: a stretch shorter than a bin inside one is not seen) are
// removed but for `keep` (a few cells of the largest reach), with the
// origin lists.origin. Returns whether any axis was folded. (Two clusters
// of 50,000 spheroids 1e6 apart made cells grown alike along every axis
// over the whole span: 100 times the pairs compared.)
bool fold_empty_stretches(const ParticleStore& particles, const BoxGeometry& geometry,
                          const std::array<double, 3>& low, const std::array<double, 3>& high,
                          double keep, CellLists& lists);
// The fold's held values and offsets from its stretches, with origin
// `base` (u(x) = x - base below the first stretch).
void fold_base(OpenFold& fold, double base);
// The pieces of fold_empty_stretches, for a fold of the centres of many
// ranks (src/mpi): the stretches of one axis to fold, (start, length) in
// order along it, of the values x[0 .. n) within [lo, hi]; of stretches
// between centres (start, length), in order, those to fold over an axis of
// that extent (longer than 2 kept, each at least 1/16 of the extent as
// folded so far, the longest first); and the fold of chosen stretches.
std::vector<std::pair<double, double>> stretches_to_fold(const double* x, std::size_t n, double lo,
                                                         double hi, double kept);
void choose_stretches(std::vector<std::pair<double, double>>& stretches, double extent,
                      double kept);
void set_fold(OpenFold& fold, const std::vector<std::pair<double, double>>& stretches, double kept,
              double base);

// Whether a grid whose cells grew by `grown` over the whole region is worth
// the trimmed region's: asked where the cells grew by more than half and
// there are particles enough for 1/64 of them to mean outliers (256), and
// taken when its cells are at most half as wide.
inline bool worth_trimming(std::size_t particles, double grown) {
  return particles >= 256 && grown > 1.5;
}
inline bool trimmed_is_finer(double cell_side, double trimmed_cell_side) {
  return trimmed_cell_side <= 0.5 * cell_side;
}

// Memory one build leaves for the next (a ScreenWorkspace's): the last
// lists' grids, whose arrays the next build's grids take over (by class
// rank, grown where too small), and the build's own per-particle arrays.
// Reused pages are already mapped: fresh ones are mapped and cleared by the
// kernel on their first touch, which on the 1M demo scene was most of the
// cell lists' time.
struct CellListMemory {
  std::vector<ClassGrid> grids;
  std::vector<std::uint8_t> size_class;
  std::vector<std::uint32_t> cell;
  std::vector<std::vector<std::uint32_t>> place;
  std::size_t bytes() const;
};

// Builds the classes and their grids (threads for the per-particle work),
// in the memory of an earlier build when given one (the same lists either
// way).
CellLists build_cell_lists(const ParticleStore& particles, const Box& box, double cutoff,
                           int threads, CellListMemory* memory = nullptr);

// A candidate pair: members i and j of their grids, r = c_j - c_i by the
// nearest image.
struct Candidate {
  const CoarseMember* coarse_i;
  const CoarseMember* coarse_j;
  const Member* i;
  const Member* j;
  double r[3];
};

// The cells of `grid` whose cell-space coordinate along axis k lies within
// `reach` of u (the reach with room for the rounding of u and of the cell
// indices), as at most two runs of consecutive cells, each with the shift
// (-1, 0 or 1 box lengths) that takes a member's wrapped position to its
// image within the reach (periodic wrap-around). Where the reach spans the
// whole periodic axis a cell can be within it from both sides: then one run
// of every cell, and nearest_image is set (the caller takes the minimum
// image itself). Cell indices are monotone in u (cell_of), so every member
// within the reach along the axis is in these cells.
struct CellRuns {
  int count = 0;
  int first[2], last[2], shift[2];
  bool nearest_image = false;
};

// (Written into `runs` in place: a CellRuns filled field by field and then
// copied whole stalls on the store-to-load forwarding of its fields.)
inline void runs_within(const CellLists& lists, const ClassGrid& grid, int k, double u,
                        double reach, CellRuns& runs) {
  runs = CellRuns();
  const int n = grid.cells[k];
  auto add = [&](int first, int last, int shift) {
    runs.first[runs.count] = first;
    runs.last[runs.count] = last;
    runs.shift[runs.count++] = shift;
  };
  if (!lists.geometry.periodic[k]) {
    add(lists.cell_of(grid, k, u - reach), lists.cell_of(grid, k, u + reach), 0);
    return;
  }
  const double low = std::floor((u - reach) * grid.inverse_side[k]);
  const double high = std::floor((u + reach) * grid.inverse_side[k]);
  if (!(high - low + 1 < n)) {
    runs.nearest_image = true;
    add(0, n - 1, 0);
    return;
  }
  const int lo = int(low), hi = int(high);
  if (lo < 0) {
    add(lo + n, n - 1, -1);
    if (hi >= 0) add(0, hi, 0);
  } else if (hi >= n) {
    if (lo < n) add(lo, n - 1, 0);
    add(std::max(0, lo - n), hi - n, 1);
  } else {
    add(lo, hi, 0);
  }
}
// Whether the runs within `reach` along periodic axis k may span the axis
// (runs_within's nearest_image), from the reach alone: the runs cover
// floor((u + reach) / side) - floor((u - reach) / side) + 1 cells, at most
// 2 reach / side + 2, so where that is below the axis's cells less one they
// cannot. Where this is true, runs_within decides.
inline bool runs_may_span(const CellLists& lists, const ClassGrid& grid, int k, double reach) {
  return lists.geometry.periodic[k] &&
         !(2 * reach * grid.inverse_side[k] + 3 < double(grid.cells[k]));
}
inline CellRuns runs_within(const CellLists& lists, const ClassGrid& grid, int k, double u,
                            double reach) {
  CellRuns runs;
  runs_within(lists, grid, k, u, reach, runs);
  return runs;
}

// Every candidate pair once (within a class the pair (at, m) from at < m,
// the places in cell order; across classes from the smaller particle). With
// `coarse_filter`, a pair only when the distance of the wrapped positions is
// less than its reach cutoff (R_i + R_j) plus the slack; without, every pair
// in the cells within the member's window. Calls on_candidate(thread,
// candidate) in the thread that finds it, after the scan of the member's
// cells, up to 32 at a time (r12 exact, by the nearest image: the same bits
// whether the image comes from the run of cells or from the minimum image
// where a window spans a whole axis), and done(thread,
// compared, passed) when the thread has no more: the pairs it compared and
// those it passed on. Each class's members are taken in cell order (the
// neighbour cells of consecutive members are the same, and in cache), shared
// among the threads; progress (may be empty) hears the fraction done now and
// then. An exception from the callbacks (or an allocation) stops the search
// and is rethrown here, after the threads have joined.
template <bool coarse_filter, class OnCandidate, class Done>
void search_candidates(const CellLists& lists, int threads,
                       const std::function<void(double)>& progress, OnCandidate&& on_candidate,
                       Done&& done) {
  const BoxGeometry& geometry = lists.geometry;
  std::size_t total = 0;
  std::vector<std::size_t> done_before(lists.grids.size() + 1, 0);  // members of earlier classes
  for (std::size_t g = 0; g < lists.grids.size(); ++g) {
    done_before[g + 1] = done_before[g] + lists.grids[g].size();
    total += lists.grids[g].size();
  }
  detail::ParallelErrors errors;
#pragma omp parallel num_threads(threads)
  {
    const int thread = omp_get_thread_num();
    std::size_t compared = 0, passed = 0;
    // The candidates of the member being searched, handed on after its scan.
    constexpr std::size_t capacity = 32;
    Candidate held[capacity];
    std::size_t waiting = 0;
    auto flush = [&] {
      for (std::size_t k = 0; k < waiting; ++k) on_candidate(thread, held[k]);
      waiting = 0;
    };
    for (std::size_t own = 0; own < lists.grids.size(); ++own) {
      const ClassGrid& home = lists.grids[own];
#pragma omp for schedule(dynamic, 1024)
      for (std::size_t at = 0; at < home.size(); ++at)
        errors.run([&] {
          if (progress && thread == 0 && at % 16384 == 0)
            progress((double(done_before[own]) + double(at)) / double(total));
          const Member* member_i = &home.member[at];
          const CoarseMember& coarse_i = home.coarse[at];
          const double reach_i = lists.cutoff * coarse_i.bounding + lists.slack;
          // (A particle so small that the squares below would be near the
          // subnormal numbers: no coarse test, every member emitted, the
          // exact tests after it decide.)
          const bool squares_hold = reach_i * reach_i >= closed_form_low;
          double u_i[3];  // i's cell-space coordinates
          lists.cell_space(coarse_i.wrapped, u_i);
          // Classes of radii at least as large as i's (indices 0 .. own).
          for (std::size_t g = 0; g <= own; ++g) {
            const ClassGrid& grid = lists.grids[g];
            // Every partner of i in this grid is within i's reach and the
            // grid's largest of i along each cell-space axis.
            const double window = reach_i + grid.largest_reach + 3 * lists.slack;
            const CellRuns runs[3] = {runs_within(lists, grid, 0, u_i[0], window),
                                      runs_within(lists, grid, 1, u_i[1], window),
                                      runs_within(lists, grid, 2, u_i[2], window)};
            const bool nearest_image =
                runs[0].nearest_image || runs[1].nearest_image || runs[2].nearest_image;
            // The members of one run of cells along z: contiguous.
            // (nearest_image and one_reach compile-time constants: the common
            // cases keep a tight loop.)
            auto visit_run = [&](auto nearest_image, auto one_reach, std::uint32_t begin,
                                 std::uint32_t end, const int(&shift)[3]) {
              if (g == own) begin = std::max(begin, std::uint32_t(at + 1));
              if (begin >= end) return;
              compared += end - begin;
              double image[3];  // the run's image shift, sum_k shift[k] a_k
              geometry.shift_vector(shift, image);
              double origin[3];  // i's wrapped position seen from the members' images
              for (int k = 0; k < 3; ++k) origin[k] = coarse_i.wrapped[k] - image[k];
              const CoarseMember* coarse = grid.coarse.data();
              auto emit = [&](std::uint32_t m) {
                ++passed;
                if (waiting == capacity) flush();
                Candidate& c = held[waiting++];
                c.i = member_i;
                c.coarse_i = &coarse_i;
                c.j = &grid.member[m];
                c.coarse_j = &coarse[m];
                // The pair's detail is read once the scan of i's cells is
                // over: fetched meanwhile (a line of a neighbouring row,
                // seldom in the nearest cache).
                __builtin_prefetch(c.j);
                // (Where a window spans a whole axis the minimum image adds
                // the whole shift, which is the run's along the other axes
                // for a pair within reach: the same sum either way, so the
                // same bits whatever the grid, as the screen over MPI ranks,
                // whose grids differ, requires.)
                for (int k = 0; k < 3; ++k) {
                  c.r[k] = coarse[m].wrapped[k] - coarse_i.wrapped[k];
                  if (!nearest_image && image[k] != 0) c.r[k] += image[k];
                }
                if (nearest_image) geometry.minimum_image(c.r);
              };
              if (!coarse_filter || nearest_image || !squares_hold) {
                for (std::uint32_t m = begin; m < end; ++m) {
                  if (coarse_filter && squares_hold) {
                    double d[3] = {coarse[m].wrapped[0] - origin[0],
                                   coarse[m].wrapped[1] - origin[1],
                                   coarse[m].wrapped[2] - origin[2]};
                    geometry.minimum_image(d);
                    const double limit = reach_i + lists.cutoff * coarse[m].bounding;
                    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] >= limit * limit) continue;
                  }
                  emit(m);
                }
                return;
              }
              // The coarse test without a branch per member (a few in ten
              // pass, unpredictably): the places of those that pass are
              // written in turn, then emitted.
              for (std::uint32_t first = begin; first < end; first += 64) {
                const std::uint32_t last = std::min<std::uint32_t>(end, first + 64);
                std::uint32_t pass[64], passing = 0;
                for (std::uint32_t m = first; m < last; ++m) {
                  const double dx = coarse[m].wrapped[0] - origin[0],
                               dy = coarse[m].wrapped[1] - origin[1],
                               dz = coarse[m].wrapped[2] - origin[2];
                  const double limit = reach_i + (one_reach ? lists.largest_reach
                                                            : lists.cutoff * coarse[m].bounding);
                  pass[passing] = m;
                  passing += std::uint32_t(dx * dx + dy * dy + dz * dz < limit * limit);
                }
                for (std::uint32_t k = 0; k < passing; ++k) emit(pass[k]);
              }
            };
            const std::size_t ny = std::size_t(grid.cells[1]), nz = std::size_t(grid.cells[2]);
            for (int ra = 0; ra < runs[0].count; ++ra)
              for (int a = runs[0].first[ra]; a <= runs[0].last[ra]; ++a)
                for (int rb = 0; rb < runs[1].count; ++rb)
                  for (int b = runs[1].first[rb]; b <= runs[1].last[rb]; ++b) {
                    const std::size_t row = (std::size_t(a) * ny + std::size_t(b)) * nz;
                    for (int rc = 0; rc < runs[2].count; ++rc) {
                      const int shift[3] = {runs[0].shift[ra], runs[1].shift[rb],
                                            runs[2].shift[rc]};
                      const std::uint32_t begin =
                          grid.cell_start[row + std::size_t(runs[2].first[rc])];
                      const std::uint32_t end =
                          grid.cell_start[row + std::size_t(runs[2].last[rc]) + 1];
                      if (nearest_image)
                        visit_run(std::true_type(), std::false_type(), begin, end, shift);
                      else if (lists.identical_shapes)
                        visit_run(std::false_type(), std::true_type(), begin, end, shift);
                      else
                        visit_run(std::false_type(), std::false_type(), begin, end, shift);
                    }
                  }
          }
          flush();
        });
    }
    errors.run([&] { done(thread, compared, passed); });
  }
  errors.rethrow_if_failed();
}

}  // namespace pwcontact::screen
