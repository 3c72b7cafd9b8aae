// The moving scene (scene.hpp): one uniform grid in the screening's cell
// space, each cell with a fixed number of slots, so that a move rewrites a
// slot in place or takes one slot out of a cell and puts it into another.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "kernels/kernel_api.hpp"
#include "number_text.hpp"
#include "pair_overlap_solver.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/moving_scene.hpp"
#include "screen/cell_lists.hpp"
#include "screen/huge_pages.hpp"
#include "screen/pair_prefilters.hpp"
#include "thread_count.hpp"

namespace pwcontact {

using detail::number_text;
namespace {

// What the coarse test reads of a member, its centre wrapped into the box
// (as given along open axes) and its bounding radius, is kept per cell in
// tiles of four rows (Impl::coarse, kernels::CoarseMembers), so that a
// register of members is tested at a time. The rest of a member, read only for the pairs the
// bounding spheres leave, is one cache line in the order of the cells (a sweep through the scene
// reads it from cache, not from the particle store's arrays in the order of the indices). Its
// index is there too (a member met is one line read, not two), and whether it is a sphere, whose
// radius is then sqrt(q[0]) exactly as the store computes it (as the screen's members keep it).
struct alignas(64) Detail {
  double q[6];
  double inscribed;
  std::uint32_t index;
  std::uint32_t sphere;  // 1: a sphere, of radius sqrt(q[0])
};
static_assert(sizeof(Detail) == 64, "a member's detail is one cache line");

// Undecided pairs of a single query solved together: a few SIMD blocks, so
// that a query that meets an overlap early stops early.
constexpr std::size_t pairs_per_solve = 16;

// Pairs of a batch of trials solved together (one thread's share at a time).
constexpr std::size_t batch_solve_pairs = 1024;

std::string particle_name(std::size_t i) { return "particle " + std::to_string(i); }

// The checks of entry k of a batched call, `check(who)`, with the entry
// named in the message on failure ("<who>, move 4: ..."). No string is made
// unless a check fails (one per entry cost a heap allocation per move).
template <class Check>
void check_entry(const char* who, const char* entry, std::size_t k, Check&& check) {
  auto named = [&](const char* what) {
    const std::string text = what, prefix = who;
    const std::string name = prefix + ", " + entry + " " + std::to_string(k);
    return text.compare(0, prefix.size(), prefix) == 0 ? name + text.substr(prefix.size())
                                                       : name + ": " + text;
  };
  try {
    check(who);
  } catch (const std::out_of_range& e) {
    throw std::out_of_range(named(e.what()));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(named(e.what()));
  }
}

// Open axes: beyond this many particles outside the region the grid covers
// (in its outer cells), the grid is rebuilt over the particles' new extent.
std::size_t outside_limit(std::size_t n) { return n / 4 + 64; }

// A trial particle as the prefilters take it (its form copied: six
// contiguous numbers).
struct TrialSide {
  double q[6];
  screen::Side side;
  explicit TrialSide(const ParticleStore::Particle& t) {
    for (int k = 0; k < 6; ++k) q[k] = t.q()[k];
    side = {0, t.bounding_radius(), t.inscribed_radius(), t.sphere_radius(), q};
  }
  TrialSide(const TrialSide&) = delete;
};

// Which cells a search visits: the trial's own, the others about it, or
// both (own first).
enum class Cells { own, others, all };

// A cell's slots: `room` of them (whole tiles of the coarse test's) from slot `start` of the
// scene's arrays. (When every cell has the same room, as in a uniform scene, a query computes a
// cell's start from its index instead: loaded, it delayed the loads of the cell's members that
// depend on it, and single queries at 0.3 took 5-9 % longer.)
struct CellSlots {
  std::uint64_t start;
  std::uint32_t room, unused;
};

}  // namespace

struct MovingScene::Impl {
  ParticleStore store;
  Box box;
  MovingSceneOptions options;
  screen::CellLists lists;     // the geometry, origin and slack; grids[0]: the cells (no members)
  double grid_radius = 0;      // the bounding radius the cells are sized for (0: empty scene)
  double side = 0;             // the narrowest cell, in cell space
  std::size_t base_room = 0;   // the slots of a cell that holds few particles
  std::vector<double> coarse;  // per cell, from 4 start: its tiles (kernels::CoarseMembers)
  kernels::BoundingKernel bounding_spheres_meet = nullptr;  // of the scene's instruction set
  std::vector<Detail> details;                              // per slot
  std::vector<CellSlots> slots;                             // per cell
  std::vector<std::uint32_t> count;                         // per cell: slots in use
  bool uniform_rooms = true;                                // every cell's room base_room
  std::vector<std::uint64_t> where;                         // per particle: its slot
  std::vector<std::uint32_t> home;                          // per particle: its cell
  std::vector<std::uint8_t> outside;  // per particle (open axes): beyond the grid's region
  std::size_t outside_count = 0;
  MovingSceneCounters counters;
  std::vector<std::uint32_t> stamp;  // per cell, for move_many's test of distinct cells
  std::uint32_t generation = 0;
  BatchOptions solve_options;  // resolved once

  const screen::ClassGrid& grid() const { return lists.grids[0]; }
  std::size_t cells() const { return count.size(); }

  // The cell of a centre as given, and whether it lies in the region the
  // cells cover (always, along periodic axes).
  std::uint32_t cell_of(const std::array<double, 3>& centre, bool* inside = nullptr) const {
    double u[3];
    lists.cell_space_of_centre(centre.data(), u);
    const screen::ClassGrid& g = grid();
    int c[3];
    bool in = true;
    for (int k = 0; k < 3; ++k) {
      c[k] = lists.cell_of(g, k, u[k]);
      if (!lists.geometry.periodic[k])
        in = in && u[k] >= 0 && u[k] * g.inverse_side[k] < double(g.cells[k]);
    }
    if (inside) *inside = in;
    return std::uint32_t((std::size_t(c[0]) * std::size_t(g.cells[1]) + std::size_t(c[1])) *
                             std::size_t(g.cells[2]) +
                         std::size_t(c[2]));
  }

  // Periodic boxes: the reach of two particles of bounding radius `radius`
  // at the largest cutoff must fit twice across the box.
  // (The box's perpendicular widths are computed once, at construction:
  // recomputed here, they were a cost of every move.)
  std::array<double, 3> widths = {0, 0, 0};
  void check_box(double radius, double cutoff, const char* who) const {
    check_reach(cutoff * 2 * radius, who, "", [&] {
      return "cutoff * 2 R = " + number_text(cutoff * 2 * radius) + " (cutoff " +
             number_text(cutoff) + ", bounding radius " + number_text(radius);
    });
  }
  // A reach that must fit twice across every periodic axis; `terms()` says
  // what it is made of (built only for the message).
  template <class Terms>
  void check_reach(double reach, const char* who, const char* subject, const Terms& terms) const {
    if (!box.periodic) return;
    for (int k = 0; k < 3; ++k)
      if (box.periodic_along(k) && !(2 * reach <= widths[k]))
        throw std::invalid_argument(std::string(who) + ": the periodic box is too small" + subject +
                                    ": its width " + detail::number_text(widths[k]) +
                                    " across axis " + std::to_string(k) +
                                    " is less than twice the reach " + terms() +
                                    "; the minimum image convention would miss pairs)");
  }

  // Particle i into slot `slot` of `cell`.
  void write_slot(std::size_t cell, std::size_t slot, std::size_t i) {
    const CellSlots& c = slots[cell];
    const std::uint64_t at = c.start + slot;
    double* row = tiles_from(c.start) + kernels::coarse_place(slot);
    const double x[3] = {store.centre(0)[i], store.centre(1)[i], store.centre(2)[i]};
    double wrapped[3];
    lists.geometry.wrap(x, wrapped);
    constexpr std::size_t tile = kernels::coarse_tile;
    row[0] = wrapped[0];
    row[tile] = wrapped[1];
    row[2 * tile] = wrapped[2];
    row[3 * tile] = store.bounding_radius()[i];
    home[i] = std::uint32_t(cell);
    Detail& d = details[at];
    for (int k = 0; k < 6; ++k) d.q[k] = store.q(k)[i];
    d.inscribed = store.inscribed_radius()[i];
    const double sphere = store.sphere_radius()[i];
    d.sphere = sphere > 0 && std::sqrt(d.q[0]) == sphere;
    d.index = std::uint32_t(i);
    where[i] = at;
  }

  void set_outside(std::size_t i, bool out) {
    if (bool(outside[i]) == out) return;
    outside[i] = out;
    if (out)
      ++outside_count;
    else
      --outside_count;
  }

  // Takes particle i's slot out of its cell (the cell's last slot fills it).
  void vacate(std::size_t i) {
    CellSlots& c = slots[home[i]];
    const std::uint64_t at = where[i];
    std::uint32_t& in_use = count[home[i]];
    const std::uint64_t last = c.start + (in_use - 1);
    if (at != last) {
      double* block = tiles_from(c.start);
      double* to = block + kernels::coarse_place(std::size_t(at - c.start));
      const double* from = block + kernels::coarse_place(std::size_t(last - c.start));
      for (std::size_t d = 0; d < 4; ++d)
        to[d * kernels::coarse_tile] = from[d * kernels::coarse_tile];
      details[at] = details[last];
      where[details[at].index] = at;  // (its home is this cell already)
    }
    --in_use;
  }

  // Puts particle i into `cell`, which has a free slot.
  void occupy(std::size_t i, std::size_t cell) {
    write_slot(cell, count[cell], i);
    ++count[cell];
  }
  bool full(std::size_t cell) const { return count[cell] == slots[cell].room; }

  // The grid sized for every particle (and for at least `radius`), every
  // particle placed.
  void rebuild(double radius) {
    const std::size_t n = store.size();
    const std::vector<double>& bounding = store.bounding_radius();
    for (std::size_t i = 0; i < n; ++i) radius = std::max(radius, bounding[i]);
    // An empty scene holds no size: its first particle rebuilds the grid for
    // its own (a size of 1 here would refuse every query in a box narrower
    // than 4 max_cutoff, whatever the particles that come).
    grid_radius = radius;
    if (!(radius > 0)) radius = 1;  // (the cells of an empty scene: any size)
    const double cutoff = options.max_cutoff;
    lists = screen::CellLists();
    lists.box = box;
    lists.geometry = screen::BoxGeometry(box);
    const screen::BoxGeometry& geometry = lists.geometry;
    std::array<double, 3> low{}, high{};
    for (int k = 0; k < 3; ++k) {
      if (geometry.periodic[k]) continue;
      double lo = 0, hi = 0;
      if (n > 0) {
        lo = hi = store.centre(k)[0];
        for (std::size_t i = 1; i < n; ++i) {
          lo = std::min(lo, store.centre(k)[i]);
          hi = std::max(hi, store.centre(k)[i]);
        }
      }
      // Centres whose differences overflow (beyond +-1e308): the grid then
      // covers the origin only along this axis, its outer cells take the
      // rest (correct, and as slow as such a scene deserves).
      if (!std::isfinite(hi - lo)) lo = hi = 0;
      low[k] = lo;
      high[k] = hi;
    }
    lists.cutoff = cutoff;
    lists.largest_reach = cutoff * radius;
    // Open axes: the region covered reaches a cell beyond the particles on
    // each side, for the ones that move a little; the slack is the region's
    // (screen::coarse_slack).
    auto slack_over = [&](const std::array<double, 3>& from, const std::array<double, 3>& to) {
      std::array<double, 3> width{};
      for (int k = 0; k < 3; ++k)
        if (!geometry.periodic[k]) width[std::size_t(k)] = to[k] - from[k];
      return screen::coarse_slack(geometry, 2 * cutoff * radius, width);
    };
    lists.slack = slack_over(low, high);
    side = 2 * cutoff * radius + 4 * lists.slack;
    // The grid over [low, high] along the open axes: cells of the reach,
    // grown alike along every axis while they are more than twice the
    // particles (and 64); where they had to grow, over the region without
    // the farthest particles when that makes them at most half as wide (one
    // at 1e9 beside 20,000 in a cube of 35 made 39,720 x 1 x 1 cells, queries
    // 10 times slower). The outer cells take everything beyond the region,
    // as after a move (at most 3/32 of the particles, within outside_limit).
    const double limit = std::max(64.0, 2.0 * double(n));
    const std::array<double, 3> sides = {side, side, side};
    screen::ClassGrid g;
    g.largest_reach = cutoff * radius;
    double grown = screen::size_cells(geometry, sides, low, high, side, limit, g);
    // Where they had to grow, first over the region without its long empty
    // stretches along the open axes (screen::fold_empty_stretches: clusters
    // far apart), in cell-space coordinates from `low` along a folded axis.
    const std::array<double, 3> fold_origin = low;
    lists.origin = low;
    // The region without the outliers, in the centres' coordinates (taken
    // once, for the fold's comparison and the trim).
    std::array<double, 3> trim_from = low, trim_to = high;
    if (screen::worth_trimming(n, grown))
      screen::region_without_outliers(store, geometry, trim_from, trim_to);
    if (screen::worth_trimming(n, grown) &&
        screen::fold_empty_stretches(store, geometry, low, high, 4 * cutoff * radius, lists)) {
      std::array<double, 3> from = low, to = high;
      lists.fold_region(from, to);
      const double slack = slack_over(from, to);
      const double folded_side = 2 * cutoff * radius + 4 * slack;
      screen::ClassGrid folded;
      folded.largest_reach = cutoff * radius;
      const double folded_grown = screen::size_cells(
          geometry, {folded_side, folded_side, folded_side}, from, to, folded_side, limit, folded);
      // Kept only where its cells are finer than the trim's alone would
      // make them (as in the screen's cell lists).
      const double trimmed_side = 2 * cutoff * radius + 4 * slack_over(trim_from, trim_to);
      screen::ClassGrid trial;
      const double trimmed =
          trimmed_side * screen::size_cells(geometry, {trimmed_side, trimmed_side, trimmed_side},
                                            trim_from, trim_to, trimmed_side, limit, trial);
      const double unfolded =
          screen::trimmed_is_finer(grown * side, trimmed) ? trimmed : grown * side;
      if (folded_grown * folded_side < unfolded) {
        g = std::move(folded);
        grown = folded_grown;
        low = from;
        high = to;
        lists.slack = slack;
        side = folded_side;
      } else {
        for (screen::OpenFold& fold : lists.fold) fold = screen::OpenFold();
      }
    }
    if (screen::worth_trimming(n, grown)) {
      // (The quantiles of the centres, then where folded their cell-space
      // coordinates: the fold is non-decreasing.)
      std::array<double, 3> from = trim_from, to = trim_to;
      lists.fold_region(from, to);
      screen::ClassGrid trimmed;
      trimmed.largest_reach = g.largest_reach;
      const double slack = slack_over(from, to);
      const double trimmed_side = 2 * cutoff * radius + 4 * slack;
      const double trimmed_grown =
          screen::size_cells(geometry, {trimmed_side, trimmed_side, trimmed_side}, from, to,
                             trimmed_side, limit, trimmed);
      if (screen::trimmed_is_finer(grown * side, trimmed_grown * trimmed_side)) {
        g = std::move(trimmed);
        low = from;
        lists.slack = slack;
        side = trimmed_side;
      }
    }
    for (int k = 0; k < 3; ++k) {
      screen::OpenFold& fold = lists.fold[std::size_t(k)];
      if (fold.pivot.empty()) {
        lists.origin[k] = geometry.periodic[k] ? 0 : low[k] - side;
      } else {
        lists.origin[k] = fold_origin[k] + (low[k] - side);
        screen::fold_base(fold, lists.origin[k]);
      }
    }
    side = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) side = std::min(side, 1 / g.inverse_side[k]);
    lists.grids.assign(1, std::move(g));

    const std::size_t cell_total =
        std::size_t(grid().cells[0]) * std::size_t(grid().cells[1]) * std::size_t(grid().cells[2]);
    std::vector<std::uint32_t> cell(n);
    std::vector<std::uint32_t> occupancy(cell_total, 0);
    outside.assign(n, 0);
    outside_count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      bool inside = true;
      cell[i] = cell_of({store.centre(0)[i], store.centre(1)[i], store.centre(2)[i]}, &inside);
      ++occupancy[cell[i]];
      set_outside(i, !inside);
    }
    const std::uint32_t fullest =
        cell_total ? *std::max_element(occupancy.begin(), occupancy.end()) : 0;
    // Room for the cells to fill up by half before the next rebuild: every
    // cell as much as the fullest one needs, as long as that is a few times
    // the mean (a uniform scene: one layout, no cell fuller than a few
    // times the mean); beyond, in a clustered scene, the cells of the
    // cluster get rooms of their own (a uniform room for the fullest made
    // memory grow as cells x fullest, ~N^2).
    auto padded = [](std::size_t r) {
      return (r + kernels::coarse_tile - 1) / kernels::coarse_tile * kernels::coarse_tile;
    };
    const double mean = cell_total ? double(n) / double(cell_total) : 0;
    const std::size_t most = padded(std::size_t(4 * mean) + 16);
    base_room =
        padded(std::min(std::max<std::size_t>({8, fullest + fullest / 2 + 2, base_room}), most));
    // In huge pages where the kernel offers them, as the screen's arrays: a
    // query reads a few cache lines of each of up to ~15 cells, each cell's
    // slots kilobytes apart (measured 3 % faster at 0.3).
    screen::assign_in_huge_pages(slots, cell_total, CellSlots{0, 0, 0});
    screen::assign_in_huge_pages(count, cell_total, 0u);
    uniform_rooms = true;
    std::uint64_t total = 0;
    for (std::size_t c = 0; c < cell_total; ++c) {
      const std::size_t room = std::max(base_room, padded(occupancy[c] + occupancy[c] / 2 + 2));
      slots[c] = {total, std::uint32_t(room), 0};
      uniform_rooms = uniform_rooms && room == base_room;
      total += room;
    }
    screen::assign_in_huge_pages(coarse, std::size_t(total) * 4, 0.0);
    screen::assign_in_huge_pages(details, std::size_t(total), Detail{});
    screen::assign_in_huge_pages(where, n, std::uint64_t(0));
    home.assign(n, 0);
    for (std::size_t i = 0; i < n; ++i) occupy(i, cell[i]);
    stamp.assign(cell_total, 0);
    generation = 0;
    ++counters.rebuilds;
  }

  // Particle i (already stored) into its cell; a rebuild when the cells are
  // too small for it or its cell is full, or when too many particles have
  // left an open box's region.
  void place(std::size_t i, bool fresh) {
    bool inside = true;
    const std::size_t cell =
        cell_of({store.centre(0)[i], store.centre(1)[i], store.centre(2)[i]}, &inside);
    const bool too_large = store.bounding_radius()[i] > grid_radius;
    if (!fresh) {
      const std::size_t old_cell = home[i];
      if (!too_large && old_cell == cell) {
        write_slot(cell, std::size_t(where[i] - slots[cell].start), i);
        set_outside(i, !inside);
        return;
      }
      vacate(i);
    }
    set_outside(i, !inside);
    if (too_large || full(cell) || outside_count > outside_limit(store.size())) {
      // (The full cell gets room for half as many again as it then holds.)
      rebuild(store.bounding_radius()[i]);
      return;
    }
    occupy(i, cell);
    if (!fresh) ++counters.cell_changes;
  }

  void check_index(std::size_t i, const char* who) const {
    if (i >= store.size())
      throw std::out_of_range(std::string(who) + ": " + particle_name(i) + " does not exist (" +
                              std::to_string(store.size()) + " particles)");
  }
  // A query's `exclude`: none or a particle (an index out of range was taken
  // as none, silently, where Python refused it).
  void check_exclude(std::int64_t exclude, const char* who) const {
    if (exclude != MovingScene::none && !(exclude >= 0 && std::uint64_t(exclude) < store.size()))
      throw std::out_of_range(std::string(who) + ": exclude " + std::to_string(exclude) +
                              " is neither none (-1) nor a particle (" +
                              std::to_string(store.size()) + " particles)");
  }

  // A trial against the stored particles, at `cutoff`: its reach to the
  // largest of them must fit twice across a periodic box (the minimum image
  // would otherwise answer for the wrong image).
  void check_trial(const Particle& trial, double cutoff, const char* who) const {
    const double reach = cutoff * (trial.bounding_radius() + grid_radius);
    check_reach(reach, who, " for the trial particle", [&] {
      return "cutoff * (R_trial + R_max) = " + number_text(reach) + " (cutoff " +
             number_text(cutoff) + ", bounding radius " + number_text(trial.bounding_radius()) +
             ", the scene's largest " + number_text(grid_radius);
    });
  }

  void check_particle(const Particle& p, const char* who) const {
    store.check_type(p, who);
    check_box(p.bounding_radius(), options.max_cutoff, who);
  }

  // ---------------------------------------------------------------------
  // Queries

  // A cell's coarse members: its tiles, from its first slot (a whole
  // number of tiles from the first cell's).
  kernels::CoarseMembers coarse_of(std::uint64_t start) const {
    return {coarse.data() + start * 4};
  }
  double* tiles_from(std::uint64_t start) { return coarse.data() + start * 4; }

  // A cell's first slot: from its index where every cell has the same room
  // (see CellSlots), else as kept.
  std::uint64_t cell_start(std::size_t cell) const {
    return uniform_rooms ? cell * base_room : slots[cell].start;
  }

  // Single overlap queries (overlaps()) in the order of the cells (a sweep,
  // as Monte Carlo codes make them) ask next for the cell after this one in
  // memory, whose lines the queries so far have rarely touched: when a
  // query's own cell is the last query's (on this thread) or the one after
  // it, the next cell's tiles, detail lines and indices are asked for, to
  // be in cache when its queries come, a few queries later. Queries in any
  // other order never ask. (Measured on the benchmark's scenes, sweep
  // order, a harness alternating with and without: tiles and details +4-7 %
  // at packing 0.3 and +2 % at 0.5, the indices another +6-9 % at 0.3.
  // neighbors() does not ask: not measured.)
  void prefetch_next_cell(std::size_t own_cell) const {
    thread_local std::size_t last = std::size_t(-2);
    const bool sweeping = own_cell == last || own_cell == last + 1;
    last = own_cell;
    if (!sweeping || own_cell + 1 >= cells()) return;
    const std::size_t next = own_cell + 1;
    const std::uint64_t start = cell_start(next);
    const std::uint32_t in_use = count[next];
    const char* tiles = reinterpret_cast<const char*>(coarse_of(start).tiles);
    // (Whole tiles: each of a tile's four rows is a line.)
    const std::size_t tile_bytes = 4 * kernels::coarse_tile * sizeof(double);
    const std::size_t bytes =
        (in_use + kernels::coarse_tile - 1) / kernels::coarse_tile * tile_bytes;
    for (std::size_t at = 0; at < bytes; at += 64) __builtin_prefetch(tiles + at);
    for (std::uint32_t k = 0; k < in_use; ++k) __builtin_prefetch(&details[start + k]);
  }

  // Where a query looks: the trial's wrapped centre (and in cell space), the
  // largest reach about it, its own cell, and whether the reach spans a
  // periodic axis (then every member is taken by the minimum image). Made
  // once per trial and cutoff, for both parts of a search; the runs of cells
  // about the own one are made only when those cells are searched.
  struct NearSearch {
    double w[3], u[3];
    double reach;
    bool nearest_image;
    double trial_reach, scale;
    std::size_t own_cell;
  };

  NearSearch near_search(const Particle& trial, double cutoff) const {
    NearSearch q;
    const screen::BoxGeometry& geometry = lists.geometry;
    double* u = q.u;
    geometry.wrap(trial.centre().data(), q.w);
    lists.cell_space(q.w, u);
    const double reach = cutoff * (trial.bounding_radius() + grid_radius) + 4 * lists.slack;
    q.reach = reach;
    const screen::ClassGrid& g = grid();
    // Whether a run spans a periodic axis, from the reach first (the runs
    // themselves are made only when the other cells are searched).
    q.nearest_image = false;
    for (int k = 0; k < 3; ++k)
      if (screen::runs_may_span(lists, g, k, reach)) {
        screen::CellRuns runs;
        screen::runs_within(lists, g, k, u[k], reach, runs);
        q.nearest_image = q.nearest_image || runs.nearest_image;
      }
    q.trial_reach = cutoff * trial.bounding_radius();
    q.scale = cutoff;
    const std::size_t ny = std::size_t(g.cells[1]), nz = std::size_t(g.cells[2]);
    q.own_cell =
        (std::size_t(lists.cell_of(g, 0, u[0])) * ny + std::size_t(lists.cell_of(g, 1, u[1]))) *
            nz +
        std::size_t(lists.cell_of(g, 2, u[2]));
    return q;
  }

  // Every stored particle but `exclude` whose bounding sphere meets the
  // trial's (near_search), in the scene's search order (the trial's own
  // cell first, then the cells by their runs; slots in order), in the cells
  // `part` names: visit(index, detail, bounding, r, rr) with r = c_index -
  // c_trial by the minimum image; a false return stops the search.
  template <class Visit>
  void for_each_near(const NearSearch& search, std::int64_t exclude, Visit&& visit,
                     Cells part = Cells::all) const {
    if (store.size() == 0) return;
    const screen::BoxGeometry& geometry = lists.geometry;
    const bool nearest_image = search.nearest_image;
    const double trial_reach = search.trial_reach, scale = search.scale;
    const kernels::BoundingKernel meet_of = bounding_spheres_meet;
    const screen::ClassGrid& g = grid();
    const std::size_t ny = std::size_t(g.cells[1]), nz = std::size_t(g.cells[2]);
    // The members that meet are held, their details and indices prefetched,
    // and visited after the scan of each run of cells along z (a row, or
    // the part of one on each side of a periodic face): the loads of their cache
    // lines then overlap instead of each stalling its own visit (on the
    // 1M-particle scene at 0.3 they were most of a query's time), and an
    // overlap met in an early row spares the scan of the later ones (visits
    // after the whole scan were 5 % slower). The trial's own cell is visited
    // on its own first: the nearest particles, where an overlap is most
    // likely met, end the search soonest.
    struct Held {
      std::size_t at;
      double r[3], rr, bounding;
    };
    constexpr std::size_t hold = 64;
    Held held[hold];
    std::size_t holding = 0;
    // Both lambdas below are inlined by force: called from several places,
    // GCC kept them out of line, and each call then read the search's state
    // (held, holding, the trial's origin, the visitor) through the closure
    // from memory; inlined, single queries took 7-13 % less time at both
    // packings of the benchmark.
    auto visit_held = [&]() __attribute__((always_inline)) {
      for (std::size_t h = 0; h < holding; ++h) {
        const Held& c = held[h];
        const Detail& d = details[c.at];
        if (std::int64_t(d.index) == exclude) continue;
        if (!visit(d.index, d, c.bounding, c.r, c.rr)) return false;
      }
      holding = 0;
      return true;
    };
    // One cell's members seen from `origin` (the trial's position less the
    // image shift of the cell); false when a visit stops the search. The
    // bounding spheres are tested a register of members at a time by the
    // kernel (a superset), then exactly here for the few it lets through: on
    // a packing at 0.5, 7 of 128 members scanned a query meet.
    auto scan = [&](std::size_t cell, const double origin[3]) __attribute__((always_inline)) {
      const std::uint64_t start = cell_start(cell);
      const kernels::CoarseMembers m = coarse_of(start);
      const std::uint32_t end = count[cell];
      constexpr std::size_t tile = kernels::coarse_tile;
      for (std::uint32_t first = 0; first < end; first += 32) {
        const std::uint32_t n = std::min<std::uint32_t>(end - first, 32);
        const kernels::CoarseMembers part = {m.tiles + kernels::coarse_place(first)};
        std::uint32_t meet = nearest_image ? (n == 32 ? ~0u : (1u << n) - 1)  // tested below
                                           : meet_of(part, n, origin, trial_reach, scale);
        for (; meet != 0; meet &= meet - 1) {
          const std::uint32_t k = first + std::uint32_t(__builtin_ctz(meet));
          const double* row = m.tiles + kernels::coarse_place(k);
          Held& c = held[holding];
          c.r[0] = row[0] - origin[0];
          c.r[1] = row[tile] - origin[1];
          c.r[2] = row[2 * tile] - origin[2];
          if (nearest_image) geometry.minimum_image(c.r);
          c.rr = c.r[0] * c.r[0] + c.r[1] * c.r[1] + c.r[2] * c.r[2];
          c.bounding = row[3 * tile];
          const double limit = trial_reach + scale * c.bounding;
          if (c.rr >= limit * limit + screen::square_slack) continue;
          c.at = start + k;
          __builtin_prefetch(&details[c.at]);
          if (++holding == hold && !visit_held()) return false;
        }
      }
      return true;
    };
    // The cells about the trial's own, each run with the trial seen from its
    // image shift (made here once: made inside the cells' loops, their
    // stores and reloads stalled a query for about 80 ns at 0.5).
    const std::size_t own_cell = search.own_cell;
    screen::CellRuns runs[3];
    double origins[2][2][2][3];
    auto prepare_others = [&]() {
      for (int k = 0; k < 3; ++k)
        screen::runs_within(lists, g, k, search.u[k], search.reach, runs[k]);
      for (int ra = 0; ra < runs[0].count; ++ra)
        for (int rb = 0; rb < runs[1].count; ++rb)
          for (int rc = 0; rc < runs[2].count; ++rc) {
            const int shift[3] = {runs[0].shift[ra], runs[1].shift[rb], runs[2].shift[rc]};
            double image[3];
            geometry.shift_vector(shift, image);
            for (int k = 0; k < 3; ++k) origins[ra][rb][rc][k] = search.w[k] - image[k];
          }
    };
    if (part != Cells::others && (!scan(own_cell, search.w) || !visit_held())) return;
    if (part == Cells::own) return;
    prepare_others();
    for (int ra = 0; ra < runs[0].count; ++ra)
      for (int a = runs[0].first[ra]; a <= runs[0].last[ra]; ++a)
        for (int rb = 0; rb < runs[1].count; ++rb)
          for (int b = runs[1].first[rb]; b <= runs[1].last[rb]; ++b)
            for (int rc = 0; rc < runs[2].count; ++rc) {
              const double* origin = origins[ra][rb][rc];
              const bool unshifted =
                  runs[0].shift[ra] == 0 && runs[1].shift[rb] == 0 && runs[2].shift[rc] == 0;
              for (int c = runs[2].first[rc]; c <= runs[2].last[rc]; ++c) {
                const std::size_t cell =
                    (std::size_t(a) * ny + std::size_t(b)) * nz + std::size_t(c);
                if (unshifted && cell == own_cell) continue;
                if (!scan(cell, origin)) return;
              }
              if (!visit_held()) return;
            }
    visit_held();
  }
};

namespace {

// A stored particle as the prefilters take it.
screen::Side member_side(std::uint32_t i, const Detail& d, double bounding) {
  return {i, bounding, d.inscribed, d.sphere ? std::sqrt(d.q[0]) : 0.0, d.q};
}

// Undecided pairs waiting for the overlap kernels, in search order, with
// the trial they belong to.
struct Pending {
  PairBatch<double> batch;
  std::vector<std::uint32_t> index, trial;
  std::vector<std::uint8_t> overlap;
  std::vector<Status> status;

  explicit Pending(std::size_t capacity) {
    batch.reserve(capacity);
    index.reserve(capacity);
    trial.reserve(capacity);
  }
  std::size_t size() const { return index.size(); }
  void add(std::uint32_t t, std::uint32_t i, const double r[3], const double* q_trial,
           const double* q_member) {
    batch.push_back(r, q_trial, q_member);
    index.push_back(i);
    trial.push_back(t);
  }
  void clear() {
    if (index.empty()) return;  // (a query's usual case: resize is 15 vectors' worth)
    batch.resize(0);
    index.clear();
    trial.clear();
  }
  void truncate(std::size_t n) {
    batch.resize(n);
    index.resize(n);
    trial.resize(n);
  }
  // The overlap answers of pairs [begin, begin + n) (n at most the solver's
  // capacity); a pair that the solver cannot answer is an error, never a
  // silent "apart".
  void solve(detail::PairOverlapSolver& solver, std::size_t begin, std::size_t n) {
    overlap.resize(size());
    status.resize(size());
    PairBatchView<double> part = batch.view();
    part.size = n;
    for (auto& p : part.r12) p += begin;
    for (auto& p : part.q1) p += begin;
    for (auto& p : part.q2) p += begin;
    solver.solve(part, overlap.data() + begin, status.data() + begin);
    for (std::size_t k = begin; k < begin + n; ++k)
      if (!is_valid(status[k]))
        throw std::runtime_error("MovingScene: the overlap of a trial particle with particle " +
                                 std::to_string(index[k]) + " has no answer (" +
                                 status_name(status[k]) + ")");
  }
};

// Per thread: an overlap solver for the scene's options.
detail::PairOverlapSolver& thread_solver(const BatchOptions& options, std::size_t capacity) {
  struct Cached {
    BatchOptions options;
    std::size_t capacity = 0;
    std::unique_ptr<detail::PairOverlapSolver> solver;
  };
  thread_local Cached cached;
  const BatchOptions& o = cached.options;
  if (!cached.solver || cached.capacity < capacity || o.isa != options.isa ||
      o.precision != options.precision || o.formulation != options.formulation ||
      o.iterations != options.iterations) {
    cached.solver = std::make_unique<detail::PairOverlapSolver>(options, 1.0, capacity);
    cached.options = options;
    cached.capacity = capacity;
  }
  return *cached.solver;
}

}  // namespace

MovingScene::MovingScene(ParticleStore particles, const Box& box, const MovingSceneOptions& options)
    : impl_(new Impl) {
  if (!(options.max_cutoff >= 1) || !std::isfinite(options.max_cutoff))
    throw std::invalid_argument("MovingScene: max_cutoff must be at least 1 and finite, got " +
                                detail::number_text(options.max_cutoff));
  if (particles.size() >= (std::size_t(1) << 31))
    throw std::invalid_argument("MovingScene: at most 2^31 - 1 particles");
  particles.require_set("MovingScene");
  impl_->store = std::move(particles);
  detail::check_box(box);  // (a Box filled in by hand: as its factories check it)
  impl_->box = box;
  if (box.periodic) impl_->widths = box.perpendicular_widths();
  impl_->options = options;
  impl_->solve_options = options.batch;
  impl_->solve_options.isa = resolve_isa(options.batch.isa);
  impl_->solve_options.accuracy = Accuracy::standard;
  impl_->solve_options.threads = 1;
  impl_->bounding_spheres_meet =
      kernels::kernels_for(impl_->solve_options.isa).bounding_spheres_meet;
  // The options checked once, as overlap_batch checks them.
  detail::PairOverlapSolver check(impl_->solve_options, 1.0, 1);
  const std::vector<double>& bounding = impl_->store.bounding_radius();
  const double largest = bounding.empty() ? 0 : *std::max_element(bounding.begin(), bounding.end());
  impl_->check_box(largest, options.max_cutoff, "MovingScene");
  impl_->rebuild(0);
}

MovingScene::~MovingScene() = default;
MovingScene::MovingScene(MovingScene&&) noexcept = default;
MovingScene& MovingScene::operator=(MovingScene&&) noexcept = default;

std::size_t MovingScene::size() const noexcept { return impl_->store.size(); }
const ParticleStore& MovingScene::particles() const noexcept { return impl_->store; }
const Box& MovingScene::box() const noexcept { return impl_->box; }
const MovingSceneCounters& MovingScene::counters() const noexcept { return impl_->counters; }

std::size_t MovingScene::bytes() const noexcept {
  const Impl& s = *impl_;
  return s.slots.capacity() * sizeof(CellSlots) + s.count.capacity() * sizeof(std::uint32_t) +
         s.coarse.capacity() * sizeof(double) + s.details.capacity() * sizeof(Detail) +
         s.where.capacity() * sizeof(std::uint64_t) + s.home.capacity() * sizeof(std::uint32_t) +
         s.outside.capacity() + s.stamp.capacity() * sizeof(std::uint32_t);
}

MovingScene::Particle MovingScene::trial(const std::array<double, 3>& centre,
                                         const std::array<double, 6>& q) const {
  return ParticleStore::particle(centre, q);
}
MovingScene::Particle MovingScene::trial_axes(const std::array<double, 3>& centre,
                                              const std::array<double, 3>& semi_axes,
                                              const std::array<double, 4>& quaternion) const {
  return ParticleStore::particle_axes(centre, semi_axes, quaternion);
}
MovingScene::Particle MovingScene::trial_typed(const std::array<double, 3>& centre,
                                               std::uint32_t type,
                                               const std::array<double, 4>& quaternion) const {
  return impl_->store.particle_typed(centre, type, quaternion);
}

std::uint32_t MovingScene::insert(const Particle& p) {
  Impl& s = *impl_;
  const std::size_t i = s.store.size();
  if (i + 1 >= (std::size_t(1) << 31))
    throw std::invalid_argument("MovingScene::insert: at most 2^31 - 1 particles");
  s.check_particle(p, "MovingScene::insert");
  s.store.add_particle(p);
  s.where.push_back(0);
  s.home.push_back(0);
  s.outside.push_back(0);
  s.place(i, true);
  ++s.counters.inserts;
  return std::uint32_t(i);
}

std::uint32_t MovingScene::remove(std::size_t i) {
  Impl& s = *impl_;
  s.check_index(i, "MovingScene::remove");
  const std::size_t last = s.store.size() - 1;
  s.vacate(i);
  s.set_outside(i, false);
  if (i != last) {
    s.where[i] = s.where[last];
    s.home[i] = s.home[last];
    s.details[s.where[i]].index = std::uint32_t(i);
    s.outside[i] = s.outside[last];
  }
  s.where.pop_back();
  s.home.pop_back();
  s.outside.pop_back();
  s.store.swap_remove(i);
  if (s.store.size() == 0) s.rebuild(0);  // (emptied: the next particle sizes the cells)
  ++s.counters.removes;
  return std::uint32_t(last);
}

void MovingScene::move(std::size_t i, const Particle& p) {
  Impl& s = *impl_;
  s.check_index(i, "MovingScene::move");
  s.check_particle(p, "MovingScene::move");
  s.store.set_particle(i, p);
  s.place(i, false);
  ++s.counters.moves;
}

bool MovingScene::move_in_own_cells(std::size_t i, const Particle& p) {
  Impl& s = *impl_;
  // Checks first (no exception may leave a parallel region: false instead).
  if (i >= s.store.size() || !(p.bounding_radius() <= s.grid_radius) || !s.store.type_fits(p))
    return false;
  bool inside = true;
  const std::size_t to = s.cell_of(p.centre(), &inside);
  const std::size_t from = s.home[i];
  // (Open boxes: a move into or out of the region the grid covers changes
  // the count of particles outside it, which the threads share: left to
  // move(). Moving in without it left the count too high.)
  if (inside == bool(s.outside[i])) return false;
  if (to != from && s.full(to)) return false;
  s.store.set_particle(i, p);
  if (to == from) {
    s.write_slot(to, std::size_t(s.where[i] - s.slots[to].start), i);
  } else {
    s.vacate(i);
    s.occupy(i, to);
  }
  return true;
}

void MovingScene::move_many(const std::uint32_t* index, const Particle* particles,
                            std::size_t count, int threads) {
  Impl& s = *impl_;
  const int team = detail::thread_count(threads, "MovingScene::move_many");
  for (std::size_t k = 0; k < count; ++k)
    check_entry("MovingScene::move_many", "move", k, [&](const char* who) {
      s.check_index(index[k], who);
      s.check_particle(particles[k], who);
    });
  // Parallel only when every move keeps to cells no other move touches,
  // needs no rebuild, and finds room in its new cell. (Open boxes: nor may
  // the count of particles outside the grid's region pass its limit at any
  // move, where the moves one after another rebuild the grid in the middle:
  // the grid, and so the search order of the queries after, depended on the
  // thread count.)
  if (++s.generation == 0) {
    std::fill(s.stamp.begin(), s.stamp.end(), 0);
    s.generation = 1;
  }
  bool independent = threads != 1 && count > 1;
  std::vector<std::uint32_t> new_cell(independent ? count : 0);
  std::vector<std::uint8_t> new_inside(independent ? count : 0);  // (within the grid's region)
  std::ptrdiff_t outside = std::ptrdiff_t(s.outside_count);
  const std::ptrdiff_t outside_most = std::ptrdiff_t(outside_limit(s.store.size()));
  for (std::size_t k = 0; k < count && independent; ++k) {
    const std::size_t i = index[k];
    const std::uint32_t from = s.home[i];
    bool inside = true;
    const std::uint32_t to = s.cell_of(particles[k].centre(), &inside);
    new_cell[k] = to;
    new_inside[k] = inside;
    outside += std::ptrdiff_t(!inside) - std::ptrdiff_t(s.outside[i]);
    independent = particles[k].bounding_radius() <= s.grid_radius && (to == from || !s.full(to)) &&
                  outside <= outside_most && s.stamp[from] != s.generation;
    s.stamp[from] = s.generation;
    if (to != from) {
      independent = independent && s.stamp[to] != s.generation;
      s.stamp[to] = s.generation;
    }
  }
  if (!independent) {
    for (std::size_t k = 0; k < count; ++k) move(index[k], particles[k]);
    return;
  }
  std::size_t changes = 0;
  std::ptrdiff_t outside_change = 0;
#pragma omp parallel for num_threads(team) reduction(+ : changes, outside_change) schedule(static)
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = index[k];
    s.store.set_particle(i, particles[k]);  // (cannot throw: checked above)
    const bool inside = new_inside[k];
    outside_change += std::ptrdiff_t(!inside) - std::ptrdiff_t(s.outside[i]);
    s.outside[i] = !inside;
    const std::size_t from = s.home[i];
    if (from == new_cell[k]) {
      s.write_slot(from, std::size_t(s.where[i] - s.slots[from].start), i);
    } else {
      s.vacate(i);
      s.occupy(i, new_cell[k]);
      ++changes;
    }
  }
  s.outside_count = std::size_t(std::ptrdiff_t(s.outside_count) + outside_change);
  s.counters.cell_changes += changes;
  s.counters.moves += count;
}

namespace {

// One trial's overlap question, asked of its own cell first and then of the
// other cells about it (a rejected Monte Carlo trial of a packing at 0.5
// overlaps a particle of its own cell in 58 % of cases, and then the other
// cells need no scan). Of each part, in two stages: the prefilters over
// every candidate first (stopping at the first overlap they decide), then
// the kernels on the candidates left, in search order. The answer: in the
// own cell, the first candidate the prefilters find overlapping, else the
// first of the solved ones that overlaps; then the same in the other cells;
// else none. The prefilters include the certificates of the overlap
// kernels, taken in scalar arithmetic for a few evaluations
// (screen::certify_overlap): only the pairs they leave reach the kernels.
// The answer does not depend on how the solved pairs are grouped, so a
// batch of trials gets what single queries get. prefilter_trial is the
// first stage of one part: it returns the decided answer (or none), with
// the undecided candidates appended to `pending` when there is none.
template <class Impl, class NearSearch>
std::int64_t prefilter_trial(const Impl& s, const TrialSide& t, const NearSearch& search,
                             std::uint32_t slot, std::int64_t exclude, Pending& pending,
                             Cells part) {
  const std::size_t first_pending = pending.size();
  std::int64_t found = MovingScene::none;
  s.for_each_near(
      search, exclude,
      [&](std::uint32_t i, const Detail& d, double bounding, const double r[3], double rr) {
        double mu2 = 0;
        switch (
            screen::decide_near_pair(t.side, member_side(i, d, bounding), r, rr, 1.0, false, mu2)) {
          case screen::NearPair::spheres:
          case screen::NearPair::same_form:
            if (!(mu2 < 1)) return true;
            [[fallthrough]];
          case screen::NearPair::in: found = i; return false;
          case screen::NearPair::out_by_projection: return true;
          case screen::NearPair::undecided: break;
        }
        switch (screen::certify_overlap(r, t.q, d.q, 1.0)) {
          case screen::Certified::overlapping: found = i; return false;
          case screen::Certified::apart: return true;
          case screen::Certified::undecided: pending.add(slot, i, r, t.q, d.q); return true;
        }
        return true;
      },
      part);
  if (found != MovingScene::none && pending.size() > first_pending) pending.truncate(first_pending);
  return found;
}

}  // namespace

std::int64_t MovingScene::overlaps(const Particle& trial, std::int64_t exclude) const {
  const Impl& s = *impl_;
  thread_local Pending pending(64);
  s.check_trial(trial, 1.0, "MovingScene::overlaps");
  s.check_exclude(exclude, "MovingScene::overlaps");
  const TrialSide t(trial);
  const auto search = s.near_search(trial, 1.0);
  s.prefetch_next_cell(search.own_cell);
  for (Cells part : {Cells::own, Cells::others}) {
    pending.clear();
    const std::int64_t decided = prefilter_trial(s, t, search, 0, exclude, pending, part);
    if (decided != none) return decided;
    if (pending.size() == 0) continue;
    // The kernels a SIMD block or two at a time, stopping at the first overlap.
    detail::PairOverlapSolver& solver = thread_solver(s.solve_options, pairs_per_solve);
    for (std::size_t begin = 0; begin < pending.size(); begin += pairs_per_solve) {
      const std::size_t n = std::min(pairs_per_solve, pending.size() - begin);
      pending.solve(solver, begin, n);
      for (std::size_t k = begin; k < begin + n; ++k)
        if (pending.overlap[k]) return pending.index[k];
    }
  }
  return none;
}

std::size_t MovingScene::overlap_count(const Particle& trial, std::int64_t exclude) const {
  return neighbors(trial, 1.0, false, exclude).size();
}

std::vector<Neighbor> MovingScene::neighbors(const Particle& trial, double cutoff, bool with_mu2,
                                             std::int64_t exclude) const {
  const Impl& s = *impl_;
  if (!(cutoff > 0) || !std::isfinite(cutoff) ||
      !(cutoff * cutoff >= std::numeric_limits<double>::min()) || !std::isfinite(cutoff * cutoff))
    throw std::invalid_argument(
        "MovingScene::neighbors: the cutoff must be positive and finite, and its square a "
        "normal number (mu^2 is compared with it), got " +
        number_text(cutoff));
  s.check_trial(trial, cutoff, "MovingScene::neighbors");
  s.check_exclude(exclude, "MovingScene::neighbors");
  const TrialSide t(trial);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Neighbor> out;
  Pending pending(64);
  s.for_each_near(
      s.near_search(trial, cutoff), exclude,
      [&](std::uint32_t i, const Detail& d, double bounding, const double r[3], double rr) {
        double mu2 = 0;
        switch (screen::decide_near_pair(t.side, member_side(i, d, bounding), r, rr, cutoff,
                                         with_mu2, mu2)) {
          case screen::NearPair::spheres:
          case screen::NearPair::same_form:
            if (mu2 < cutoff * cutoff) out.push_back({i, with_mu2 ? mu2 : nan});
            break;
          case screen::NearPair::in: out.push_back({i, nan}); break;
          case screen::NearPair::out_by_projection: break;
          case screen::NearPair::undecided:
            // (Without mu^2 the certificates decide most of them, as in overlaps.)
            switch (with_mu2 ? screen::Certified::undecided
                             : screen::certify_overlap(r, t.q, d.q, cutoff * cutoff)) {
              case screen::Certified::overlapping: out.push_back({i, nan}); break;
              case screen::Certified::apart: break;
              case screen::Certified::undecided: pending.add(0, i, r, t.q, d.q); break;
            }
            break;
        }
        return true;
      });
  const std::size_t n = pending.size();
  if (n > 0) {
    const BatchOptions& options = s.solve_options;
    std::vector<Status> status(n);
    if (with_mu2) {
      std::vector<double> mu2(n);
      contact_function_batch(pending.batch.view(), {mu2.data(), nullptr, status.data()}, options);
      for (std::size_t k = 0; k < n; ++k) {
        if (!is_valid(status[k]) && status[k] != Status::out_of_range)
          throw std::runtime_error(
              "MovingScene::neighbors: mu^2 of a trial particle and particle " +
              std::to_string(pending.index[k]) + " has no answer (" + status_name(status[k]) + ")");
        if (mu2[k] < cutoff * cutoff) out.push_back({pending.index[k], mu2[k]});
      }
    } else {
      std::vector<std::uint8_t> overlap(n);
      overlap_batch(pending.batch.view(), {overlap.data(), status.data()}, options, cutoff);
      for (std::size_t k = 0; k < n; ++k) {
        if (!is_valid(status[k]))
          throw std::runtime_error(
              "MovingScene::neighbors: the pair of a trial particle and particle " +
              std::to_string(pending.index[k]) + " has no answer (" + status_name(status[k]) + ")");
        if (overlap[k]) out.push_back({pending.index[k], nan});
      }
    }
  }
  std::sort(out.begin(), out.end(),
            [](const Neighbor& a, const Neighbor& b) { return a.index < b.index; });
  return out;
}

void MovingScene::overlaps(const Particle* trials, const std::int64_t* exclude, std::size_t count,
                           std::int64_t* first_overlap, int threads) const {
  const Impl& s = *impl_;
  const int team = detail::thread_count(threads, "MovingScene::overlaps");
  for (std::size_t t = 0; t < count; ++t)
    check_entry("MovingScene::overlaps", "trial", t, [&](const char* who) {
      s.check_trial(trials[t], 1.0, who);
      if (exclude) s.check_exclude(exclude[t], who);
    });
  detail::ParallelErrors errors;
  // Trials in blocks per thread: each block's undecided pairs solved in
  // calls of many pairs, the SIMD lanes across trials.
  constexpr std::size_t block = 64;
  const std::size_t blocks = (count + block - 1) / block;
#pragma omp parallel num_threads(team)
  {
    Pending pending(batch_solve_pairs);
    std::vector<Impl::NearSearch> searches(block);  // of a block's trials, for both parts
#pragma omp for schedule(dynamic, 1)
    for (std::size_t b = 0; b < blocks; ++b)
      errors.run([&] {
        detail::PairOverlapSolver& solver = thread_solver(s.solve_options, batch_solve_pairs);
        const std::size_t begin = b * block, end = std::min(count, begin + block);
        for (std::size_t t = begin; t < end; ++t) {
          first_overlap[t] = none;
          searches[t - begin] = s.near_search(trials[t], 1.0);
        }
        // The trials' own cells, then the other cells of the trials without
        // an answer (prefilter_trial's order).
        for (Cells part : {Cells::own, Cells::others}) {
          pending.clear();
          for (std::size_t t = begin; t < end; ++t)
            if (part == Cells::own || first_overlap[t] == none)
              first_overlap[t] =
                  prefilter_trial(s, TrialSide(trials[t]), searches[t - begin], std::uint32_t(t),
                                  exclude ? exclude[t] : none, pending, part);
          // The first overlapping pair of each trial without a decided answer.
          for (std::size_t at = 0; at < pending.size(); at += solver.capacity()) {
            const std::size_t n = std::min(solver.capacity(), pending.size() - at);
            pending.solve(solver, at, n);
          }
          for (std::size_t k = pending.size(); k-- > 0;)
            if (pending.overlap[k]) first_overlap[pending.trial[k]] = pending.index[k];
        }
      });
  }
  errors.rethrow_if_failed();
}

std::array<int, 3> MovingScene::cells() const noexcept { return impl_->grid().cells; }

std::array<int, 3> MovingScene::cell_of(const std::array<double, 3>& centre) const {
  for (double x : centre)
    if (!std::isfinite(x))
      throw std::invalid_argument("MovingScene::cell_of: the centre is not finite");
  const std::size_t cell = impl_->cell_of(centre);
  const auto& n = impl_->grid().cells;
  return {int(cell / (std::size_t(n[1]) * n[2])), int(cell / n[2] % n[1]), int(cell % n[2])};
}

std::array<int, 3> MovingScene::cell_of_particle(std::size_t i) const {
  impl_->check_index(i, "MovingScene::cell_of_particle");
  const std::size_t cell = impl_->home[i];
  const auto& n = impl_->grid().cells;
  return {int(cell / (std::size_t(n[1]) * n[2])), int(cell / n[2] % n[1]), int(cell % n[2])};
}

}  // namespace pwcontact
