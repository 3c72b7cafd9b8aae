#include "screen/cell_lists.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "screen/huge_pages.hpp"

namespace pwcontact::screen {
namespace {

// Classes halve the bounding radius: beyond eight (a factor 128), the last
// class takes every smaller particle, whose cells are then larger than they
// need be (still correct).
constexpr int max_classes = 8;

// Cells per grid at most this many per member (and at least 64 in all):
// sparse scenes in open boundaries would otherwise ask for huge grids.
constexpr double max_cells_per_member = 2;

// Cells per reach along each axis: a cell as wide as 1 / this of the reach
// of two of a class's largest members. Each member visits the cells within
// its own reach plus the class's largest (runs_within), so finer cells fit
// that box more closely (fewer pairs compared) at the cost of more cells to
// look up. Along z a run of cells is one contiguous range of members
// whatever its length: finer cells there cost only the cell offsets' size.
// On the demo scene (1M spheroids), pairs compared per screen: 73M with the
// 3 x 3 x 3 cells about a member's cell, 48M with cells by the member's
// reach, 34M with z cells four to the reach; 1.5 cells to the reach across
// compared 26M but took 15 % longer (more rows of cells per member).
constexpr double cells_per_reach[3] = {1, 1, 4};

}  // namespace

void check_centres_span(const char* who, int axis, double low, double high) {
  if (std::isfinite(high - low)) return;
  char text[200];
  std::snprintf(text, sizeof text,
                "%s: the centres span more than the largest double along axis %d (from %.17g to "
                "%.17g): their differences overflow",
                who, axis, low, high);
  throw std::invalid_argument(text);
}

BoxGeometry::BoxGeometry(const Box& box) {
  detail::check_box(box);
  if (!box.periodic) return;
  for (int k = 0; k < 3; ++k) periodic[k] = box.periodic_along(k);
  triclinic = !box.orthorhombic();
  const double lx = box.length[0], ly = box.length[1], lz = box.length[2];
  const double xy = box.tilt[0], xz = box.tilt[1], yz = box.tilt[2];
  // h = [[Lx, xy Ly, xz Lz], [0, Ly, yz Lz], [0, 0, Lz]]; in 2D the open z
  // axis has no lattice vector.
  h[0][0] = lx;
  h[0][1] = xy * ly;
  h[1][1] = ly;
  if (periodic[2]) {
    h[0][2] = xz * lz;
    h[1][2] = yz * lz;
    h[2][2] = lz;
  }
  width = box.perpendicular_widths();
  for (int k = 0; k < 3; ++k) inverse_diagonal[k] = periodic[k] ? 1 / h[k][k] : 0;
}

namespace {

// (hi, lo) -= n h, as a double-double: n h = p + pe exactly (fma), hi - p =
// t + te exactly (two-sum), then renormalised. (std::fma: exact whatever
// the instruction set; a library call on the baseline, taken only for
// centres far from the box.)
void subtract_product(double& hi, double& lo, double n, double h) {
  const double p = n * h;
  const double pe = std::fma(n, h, -p);
  const double t = hi - p;
  const double back = t - hi;
  const double te = (hi - (t - back)) + (-p - back);
  const double low = lo + te - pe;
  hi = t + low;
  lo = low - (hi - t);
}

}  // namespace

void BoxGeometry::wrap_far(const double x[3], double w[3]) const {
  double hi[3] = {x[0], x[1], x[2]}, lo[3] = {0, 0, 0};
  for (int k = 2; k >= 0; --k) {
    if (!periodic[k]) continue;
    // Subtracting lattice vector k changes s_k by one and no other s_j
    // (h is upper triangular); rows k .. 2 are final once axis k is done.
    for (int round = 0; round < 64; ++round) {
      double now[3], s[3];
      for (int r = 0; r < 3; ++r) now[r] = hi[r] + lo[r];
      fractional(now, s);
      const double n = std::floor(s[k]);
      // In [0, 1], or within rounding of a face (wrapped positions are
      // clamped into the cells): done.
      if (n == 0 || (n == 1 && s[k] - 1 <= 1e-12) || (n == -1 && s[k] >= -1e-12)) break;
      if (!std::isfinite(n)) break;  // (s beyond double's range: no wrap can help)
      for (int r = 0; r <= k; ++r) subtract_product(hi[r], lo[r], n, h[r][k]);
    }
  }
  for (int r = 0; r < 3; ++r) w[r] = periodic[r] ? hi[r] + lo[r] : x[r];
}

double coarse_slack(const BoxGeometry& geometry, double reach,
                    const std::array<double, 3>& open_width) {
  double scale = reach;
  for (int k = 0; k < 3; ++k)
    scale = geometry.periodic[k]
                ? std::max(scale, std::abs(geometry.h[k][0]) + std::abs(geometry.h[k][1]) +
                                      std::abs(geometry.h[k][2]))
                : std::max(scale, open_width[std::size_t(k)] + 2 * reach);
  return 1e3 * std::numeric_limits<double>::epsilon() * scale;
}

double size_cells(const BoxGeometry& geometry, const std::array<double, 3>& side,
                  const std::array<double, 3>& from, const std::array<double, 3>& to, double margin,
                  double limit, ClassGrid& grid) {
  constexpr double most_cells = 1e6;  // along one axis
  for (double wider = 1;;) {
    double total = 1, grown = wider;
    for (int k = 0; k < 3; ++k) {
      double wide = wider * side[k];
      const bool periodic = geometry.periodic[k];
      const double extent = periodic ? geometry.width[k] : to[k] - from[k] + 2 * margin;
      double cells =
          periodic ? std::max(1.0, std::floor(extent / wide)) : std::floor(extent / wide) + 1;
      if (!(cells <= most_cells)) {
        // (NaN too: a side grown to infinity.) Wider cells along this axis
        // only, still over the whole region, and counted as grown: with
        // cells of the asked side the region's far part fell into the last
        // cell (550,000 spheres on a line compared 1.25e9 pairs), and no
        // fold or trim was tried.
        cells = most_cells;
        if (!periodic && std::isfinite(extent)) {
          wide = std::max(wide, extent / (most_cells - 1));
          grown = std::max(grown, wide / side[k]);
        }
      }
      grid.cells[k] = int(cells);
      grid.inverse_side[k] = periodic ? grid.cells[k] / extent : 1 / wide;
      total *= grid.cells[k];
    }
    if (total <= limit) return grown;
    wider *= std::cbrt(total / limit) * 1.01;
  }
}

void region_without_outliers(const ParticleStore& particles, const BoxGeometry& geometry,
                             std::array<double, 3>& from, std::array<double, 3>& to) {
  const std::size_t n = particles.size(), cut = n / 64;
  if (n == 0) return;
  std::vector<double> x;
  for (int k = 0; k < 3; ++k) {
    if (geometry.periodic[k]) continue;
    x = particles.centre(k);
    std::nth_element(x.begin(), x.begin() + std::ptrdiff_t(cut), x.end());
    const double first = x[cut];
    std::nth_element(x.begin() + std::ptrdiff_t(cut), x.end() - 1 - std::ptrdiff_t(cut), x.end());
    const double last = x[n - 1 - cut];
    if (!std::isfinite(last - first)) continue;  // (the caller's region stands)
    from[k] = first;
    to[k] = last;
  }
}

void fold_base(OpenFold& fold, double base) {
  const std::size_t stretches = fold.pivot.size();
  fold.held.resize(stretches);
  fold.offset.resize(stretches);
  double offset = base, held = -std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < stretches; ++j) {
    // The value u takes at the pivot from below, computed as
    // open_coordinate computes it there: u neither steps up nor down at the
    // pivot, whatever the roundings of the offsets (they only move where
    // the held value gives way to x - offset_j, by eps of the offsets).
    held = std::max(held, fold.pivot[j] - offset);
    fold.held[j] = held;
    offset += fold.removed[j];  // (removed > 0: the offsets do not decrease)
    fold.offset[j] = offset;
  }
}

namespace {

// The stretches longer than `longer` between the values xs[0 .. count)
// (all within [lo, hi], lo and hi among them), in increasing order, each
// as (its start, its length): the values counted into bins (as many as
// values, at least 16), the stretches between occupied bins taken, and
// each bin whose values span more than `longer` searched the same way.
// Each level narrows the span by the bins' count, so that gaps of every
// scale are found (clusters 1e2, 1e5 and 1e12 apart), in O(values) per
// level. `previous`: the highest value before these.
void find_stretches(const double* xs, std::size_t count, double lo, double hi, double longer,
                    double& previous, std::vector<std::pair<double, double>>& stretches) {
  if (count == 0) return;
  if (!(hi - lo > longer)) {
    if (lo - previous > longer) stretches.push_back({previous, lo - previous});
    previous = hi;
    return;
  }
  constexpr std::size_t few = 64;
  if (count <= few) {  // (sorted outright)
    double sorted[few];
    std::copy(xs, xs + count, sorted);
    std::sort(sorted, sorted + count);
    for (std::size_t i = 0; i < count; ++i) {
      if (sorted[i] - previous > longer) stretches.push_back({previous, sorted[i] - previous});
      previous = sorted[i];
    }
    return;
  }
  const std::size_t bins = std::min<std::size_t>(std::max<std::size_t>(count, 16), 1 << 22);
  const double per_length = double(bins) / (hi - lo);
  auto bin_of = [&](double x) { return std::min(bins - 1, std::size_t((x - lo) * per_length)); };
  std::vector<std::size_t> start(bins + 1, 0);
  for (std::size_t i = 0; i < count; ++i) ++start[bin_of(xs[i]) + 1];
  for (std::size_t b = 0; b < bins; ++b) start[b + 1] += start[b];
  std::vector<double> sorted(count);
  {
    std::vector<std::size_t> next(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < count; ++i) sorted[next[bin_of(xs[i])]++] = xs[i];
  }
  for (std::size_t b = 0; b < bins; ++b) {
    const double* in = sorted.data() + start[b];
    const std::size_t n = start[b + 1] - start[b];
    if (n == 0) continue;
    const auto [first, last] = std::minmax_element(in, in + n);
    find_stretches(in, n, *first, *last, longer, previous, stretches);
  }
}

}  // namespace

void choose_stretches(std::vector<std::pair<double, double>>& stretches, double extent,
                      double kept) {
  std::vector<std::size_t> order(stretches.size());
  for (std::size_t j = 0; j < order.size(); ++j) order[j] = j;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return stretches[a].second > stretches[b].second;
  });
  std::vector<std::uint8_t> taken(stretches.size(), 0);
  for (const std::size_t j : order) {
    if (!(stretches[j].second > 2 * kept && stretches[j].second >= extent / 16)) break;
    taken[j] = 1;
    extent -= stretches[j].second - kept;
  }
  std::size_t kept_ones = 0;
  for (std::size_t j = 0; j < stretches.size(); ++j)
    if (taken[j]) stretches[kept_ones++] = stretches[j];
  stretches.resize(kept_ones);
}

std::vector<std::pair<double, double>> stretches_to_fold(const double* x, std::size_t n, double lo,
                                                         double hi, double kept) {
  std::vector<std::pair<double, double>> stretches;
  if (n == 0 || !(hi - lo > 4 * kept)) return stretches;
  // A stretch to fold is at least 1/16 of the extent: where the longest run
  // of empty bins of a histogram of the axis (as many bins as values) is
  // shorter than that, none is (a uniform sparse scene: one pass over the
  // centres, no search).
  {
    const std::size_t bins = std::min<std::size_t>(n, std::size_t(1) << 24);
    const double per_length = double(bins) / (hi - lo);
    std::vector<std::uint8_t> occupied(bins, 0);
    for (std::size_t i = 0; i < n; ++i)
      occupied[std::min(bins - 1, std::size_t((x[i] - lo) * per_length))] = 1;
    std::size_t run = 0, longest_run = 0;
    for (const std::uint8_t o : occupied) {
      run = o ? 0 : run + 1;
      longest_run = std::max(longest_run, run);
    }
    if (double(longest_run + 2) < double(bins) / 16) return stretches;
  }
  double previous = lo;
  find_stretches(x, n, lo, hi, 2 * kept, previous, stretches);
  choose_stretches(stretches, hi - lo, kept);
  return stretches;
}

void set_fold(OpenFold& fold, const std::vector<std::pair<double, double>>& stretches, double kept,
              double base) {
  fold = OpenFold();
  for (const auto& [start, length] : stretches) {
    fold.pivot.push_back(start + 0.5 * kept);
    fold.removed.push_back(length - kept);
  }
  fold_base(fold, base);
}

bool fold_empty_stretches(const ParticleStore& particles, const BoxGeometry& geometry,
                          const std::array<double, 3>& low, const std::array<double, 3>& high,
                          double keep, CellLists& lists) {
  bool folded = false;
  for (int k = 0; k < 3; ++k) {
    OpenFold& fold = lists.fold[std::size_t(k)];
    fold = OpenFold();
    if (geometry.periodic[k]) continue;
    const std::vector<double>& x = particles.centre(k);
    set_fold(fold, stretches_to_fold(x.data(), x.size(), low[k], high[k], keep), keep,
             lists.origin[std::size_t(k)]);
    folded = folded || !fold.pivot.empty();
  }
  return folded;
}

std::size_t CellListMemory::bytes() const {
  std::size_t total = size_class.capacity() + cell.capacity() * sizeof(std::uint32_t);
  for (const std::vector<std::uint32_t>& counts : place)
    total += counts.capacity() * sizeof(std::uint32_t);
  for (const ClassGrid& grid : grids)
    total += grid.cell_start.capacity() * sizeof(std::uint32_t) +
             grid.coarse.capacity() * sizeof(CoarseMember) +
             grid.member.capacity() * sizeof(Member);
  return total;
}

CellLists build_cell_lists(const ParticleStore& particles, const Box& box, double cutoff,
                           int threads, CellListMemory* memory) {
  CellLists lists;
  lists.box = box;
  lists.geometry = BoxGeometry(box);
  const BoxGeometry& geometry = lists.geometry;
  const std::size_t n = particles.size();
  const std::vector<double>& bounding = particles.bounding_radius();
  if (n == 0) return lists;

  const std::vector<double>& inscribed = particles.inscribed_radius();
  const std::vector<std::uint32_t>& type = particles.type_id();
  double largest = 0, smallest = std::numeric_limits<double>::infinity();
  double inscribed_low = smallest, inscribed_high = 0;
  std::uint32_t type_low = ParticleStore::untyped, type_high = 0;
  std::array<double, 3> low, high;
  for (int k = 0; k < 3; ++k) {
    low[k] = std::numeric_limits<double>::infinity();
    high[k] = -low[k];
  }
#pragma omp parallel for num_threads(threads) reduction(max                                   \
                                                        : largest, inscribed_high, type_high) \
    reduction(min                                                                             \
              : smallest, inscribed_low, type_low)
  for (std::size_t i = 0; i < n; ++i) {
    largest = std::max(largest, bounding[i]);
    smallest = std::min(smallest, bounding[i]);
    inscribed_high = std::max(inscribed_high, inscribed[i]);
    inscribed_low = std::min(inscribed_low, inscribed[i]);
    type_low = std::min(type_low, type[i]);
    type_high = std::max(type_high, type[i]);
  }
  // Identical shapes: declared by one shape type (its particles have the
  // type's radii to the bit), else inferred from the radii. One reach for
  // every pair.
  lists.one_type = type_low == type_high && type_low != ParticleStore::untyped;
  lists.identical_shapes =
      lists.one_type || (largest - smallest <= 1e-12 * largest &&
                         inscribed_high - inscribed_low <= 1e-12 * inscribed_high);
  for (int k = 0; k < 3; ++k) {
    if (geometry.periodic[k]) continue;  // (only open axes need the extent)
    const std::vector<double>& c = particles.centre(k);
    double lo = low[k], hi = high[k];
#pragma omp parallel for num_threads(threads) reduction(min : lo) reduction(max : hi)
    for (std::size_t i = 0; i < n; ++i) {
      lo = std::min(lo, c[i]);
      hi = std::max(hi, c[i]);
    }
    low[k] = lo;
    high[k] = hi;
    // Open boundaries: differences of centres must be finite.
    check_centres_span("screen_pairs", k, lo, hi);
  }
  lists.origin = low;
  lists.cutoff = cutoff;
  lists.largest_reach = cutoff * largest;

  // The build's arrays: an earlier build's when given (their old contents
  // are overwritten before they are read), else the build's own.
  CellListMemory own;
  CellListMemory& kept = memory ? *memory : own;

  // Classes, then only the non-empty ones, largest radii first.
  std::vector<std::uint8_t>& size_class = kept.size_class;  // per particle: halvings, then its grid
  size_class.resize(n);
#pragma omp parallel for num_threads(threads)
  for (std::size_t i = 0; i < n; ++i) {
    const int halvings = std::ilogb(largest / bounding[i]);  // floor(log2), >= 0
    size_class[i] = std::uint8_t(std::min(std::max(halvings, 0), max_classes - 1));
  }
  std::size_t members[max_classes] = {};
  double radius[max_classes] = {};
  for (std::size_t i = 0; i < n; ++i) {
    ++members[size_class[i]];
    radius[size_class[i]] = std::max(radius[size_class[i]], bounding[i]);
  }
  int compact[max_classes];
  std::array<double, 3> side[max_classes];
  double cell_limit[max_classes], grown[max_classes];
  int most = 0;  // the class with the most members
  for (int c = 0; c < max_classes; ++c) {
    compact[c] = int(lists.grids.size());
    if (members[c] == 0) continue;
    ClassGrid grid;
    const std::size_t rank = lists.grids.size();
    if (rank < kept.grids.size()) {  // (the arrays only: every other field is set below)
      ClassGrid& old = kept.grids[rank];
      grid.cell_start.swap(old.cell_start);
      grid.coarse.swap(old.coarse);
      grid.member.swap(old.member);
    }
    grid.largest_reach = cutoff * radius[c];
    // Cells cells_per_reach to the reach of two of the class's largest
    // members; fewer (wider) when that would make too many.
    const double reach = 2 * cutoff * radius[c];
    side[c] = {reach / cells_per_reach[0], reach / cells_per_reach[1], reach / cells_per_reach[2]};
    cell_limit[c] = std::max(64.0, max_cells_per_member * double(members[c]));
    grown[c] = size_cells(geometry, side[c], low, high, 0, cell_limit[c], grid);
    if (members[c] > members[most]) most = c;
    lists.grids.push_back(std::move(grid));
  }
  // Where the cells had to grow: the grids over the open axes' region
  // without its long empty stretches (folded: clusters far apart), and then
  // without the farthest particles (the far ones in the outer cells) when
  // that makes the cells of the class with the most members at most half as
  // wide. The region's ends along an open axis: its centres' coordinates,
  // or where folded their cell-space coordinates (from the origin).
  std::array<double, 3> region_from = low, region_to = high;
  auto size_all = [&](const std::array<double, 3>& from, const std::array<double, 3>& to) {
    for (int c = 0; c < max_classes; ++c)
      if (members[c] > 0)
        grown[c] = size_cells(geometry, side[c], from, to, 0, cell_limit[c],
                              lists.grids[std::size_t(compact[c])]);
  };
  // The region without the outliers, in the centres' coordinates (taken
  // once, for the fold's comparison and the trim).
  std::array<double, 3> trim_from = low, trim_to = high;
  if (worth_trimming(n, grown[most]))
    region_without_outliers(particles, geometry, trim_from, trim_to);
  if (worth_trimming(n, grown[most]) &&
      fold_empty_stretches(particles, geometry, low, high, 4 * cutoff * largest, lists)) {
    std::array<double, 3> from = low, to = high;
    lists.fold_region(from, to);
    // Kept only where its cells are finer than the trim's alone would make
    // them (a few outliers spread over a few widths of the rest far away:
    // their own gaps too short to fold, the folded grid spent its cells on
    // them, where the trim leaves them to the outer cells).
    ClassGrid trial;
    const double folded = size_cells(geometry, side[most], from, to, 0, cell_limit[most], trial);
    const double trimmed =
        size_cells(geometry, side[most], trim_from, trim_to, 0, cell_limit[most], trial);
    const double unfolded = trimmed_is_finer(grown[most], trimmed) ? trimmed : grown[most];
    if (folded < unfolded) {
      size_all(from, to);
      region_from = from;
      region_to = to;
    } else {
      for (OpenFold& fold : lists.fold) fold = OpenFold();
    }
  }
  if (worth_trimming(n, grown[most])) {
    std::array<double, 3> from = trim_from, to = trim_to;
    lists.fold_region(from, to);
    ClassGrid trimmed;
    if (trimmed_is_finer(grown[most], size_cells(geometry, side[most], from, to, 0,
                                                 cell_limit[most], trimmed))) {
      size_all(from, to);
      for (int k = 0; k < 3; ++k) {
        OpenFold& fold = lists.fold[std::size_t(k)];
        if (fold.pivot.empty()) {
          lists.origin[std::size_t(k)] = from[k];
        } else {
          lists.origin[std::size_t(k)] += from[k];
          fold_base(fold, lists.origin[std::size_t(k)]);
        }
      }
      region_from = from;
      region_to = to;
    }
  }
  std::array<double, 3> width{};  // of the grids' region along the open axes
  for (int k = 0; k < 3; ++k)
    if (!geometry.periodic[k])
      width[std::size_t(k)] = lists.fold[std::size_t(k)].pivot.empty()
                                  ? region_to[k] - lists.origin[std::size_t(k)]
                                  : region_to[k] - region_from[k];
  lists.slack = coarse_slack(geometry, 2 * cutoff * largest, width);

  // Counting sort of each class's members by cell, in particle order.
  std::vector<std::uint32_t>& cell = kept.cell;
  cell.resize(n);
#pragma omp parallel for num_threads(threads)
  for (std::size_t i = 0; i < n; ++i) {
    size_class[i] = std::uint8_t(compact[size_class[i]]);  // (from here on: its grid)
    const ClassGrid& grid = lists.grids[size_class[i]];
    const double x[3] = {particles.centre(0)[i], particles.centre(1)[i], particles.centre(2)[i]};
    double u[3];
    lists.cell_space_of_centre(x, u);
    const int a = lists.cell_of(grid, 0, u[0]);
    const int b = lists.cell_of(grid, 1, u[1]);
    const int c = lists.cell_of(grid, 2, u[2]);
    cell[i] = std::uint32_t((std::size_t(a) * std::size_t(grid.cells[1]) + std::size_t(b)) *
                                std::size_t(grid.cells[2]) +
                            std::size_t(c));
  }
  // The members' places in parallel, as the serial counting sort gives
  // them (by cell, then by particle index): the particles in `parts`
  // contiguous chunks, each counted into a histogram of its own over every
  // grid's cells; a prefix over the cells, chunk after chunk within each
  // cell, turns the counts into each chunk's first place in each cell; each
  // chunk then places its particles. (At most 8 chunks, of 16,384
  // particles or more: a histogram takes 4 bytes a cell, up to 2 cells a
  // member.)
  const int parts =
      int(std::min<std::size_t>({std::size_t(std::max(threads, 1)), 8, n / 16384 + 1}));
  std::vector<std::size_t> first_cell(lists.grids.size() + 1, 0);  // of each grid, all grids'
  for (std::size_t g = 0; g < lists.grids.size(); ++g) {
    const ClassGrid& grid = lists.grids[g];
    first_cell[g + 1] = first_cell[g] + std::size_t(grid.cells[0]) * grid.cells[1] * grid.cells[2];
  }
  std::vector<std::vector<std::uint32_t>>& place = kept.place;
  place.resize(static_cast<std::size_t>(parts));
  auto chunk = [&](int p) { return n * std::size_t(p) / std::size_t(parts); };
#pragma omp parallel for num_threads(parts) schedule(static, 1)
  for (int p = 0; p < parts; ++p) {
    std::vector<std::uint32_t>& counts = place[std::size_t(p)];
    counts.assign(first_cell.back(), 0);
    for (std::size_t i = chunk(p); i < chunk(p + 1); ++i)
      ++counts[first_cell[size_class[i]] + cell[i]];
  }
  for (std::size_t g = 0; g < lists.grids.size(); ++g) {
    ClassGrid& grid = lists.grids[g];
    const std::size_t cells = first_cell[g + 1] - first_cell[g];
    grid.cell_start.resize(cells + 1);
    std::uint32_t at = 0;
    for (std::size_t c = 0; c < cells; ++c) {
      grid.cell_start[c] = at;
      for (std::vector<std::uint32_t>& counts : place) {
        const std::uint32_t here = counts[first_cell[g] + c];
        counts[first_cell[g] + c] = at;
        at += here;
      }
    }
    grid.cell_start[cells] = at;
    // (In huge pages: 96 bytes a member, filled in parallel right after.)
    reserve_in_huge_pages(grid.coarse, at);
    reserve_in_huge_pages(grid.member, at);
    grid.coarse.resize(at);
    grid.member.resize(at);
  }
  // cell[i] becomes particle i's place among its class's members.
#pragma omp parallel for num_threads(parts) schedule(static, 1)
  for (int p = 0; p < parts; ++p) {
    std::vector<std::uint32_t>& next = place[std::size_t(p)];
    for (std::size_t i = chunk(p); i < chunk(p + 1); ++i)
      cell[i] = next[first_cell[size_class[i]] + cell[i]]++;
  }
  if (!memory) {  // (else kept for the next build)
    std::vector<std::vector<std::uint32_t>>().swap(place);
  }

  // The copies in cell order, read in particle order (streaming reads,
  // scattered writes of a half and a whole cache line per particle: measured
  // faster than gathering them in cell order).
#pragma omp parallel for num_threads(threads)
  for (std::size_t i = 0; i < n; ++i) {
    ClassGrid& grid = lists.grids[size_class[i]];
    const std::size_t at = cell[i];
    CoarseMember& coarse = grid.coarse[at];
    Member& member = grid.member[at];
    const double x[3] = {particles.centre(0)[i], particles.centre(1)[i], particles.centre(2)[i]};
    double w[3];
    geometry.wrap(x, w);
    for (int k = 0; k < 3; ++k) coarse.wrapped[k] = w[k];
    coarse.bounding = bounding[i];
    for (int k = 0; k < 6; ++k) member.q[k] = particles.q(k)[i];
    member.inscribed = inscribed[i];
    // (A sphere's radius is sqrt(q[0]) as the store computes it; were it
    // ever not, the pair would be solved rather than taken in closed form.)
    const double sphere = particles.sphere_radius()[i];
    member.sphere = sphere > 0 && std::sqrt(member.q[0]) == sphere;
    member.index = std::uint32_t(i);
  }
  return lists;
}

}  // namespace pwcontact::screen
