// Cell lists by size class: candidate pairs of a scene without making every
// cell as large as the largest particle's reach.
//
// Particles fall into classes by bounding radius R, halving from the
// largest: class c holds R in (R_max / 2^(c+1), R_max / 2^c] (the last class
// takes everything smaller). Each class has its own grid, with cells at least
// as wide as the reach of two of its largest members, cutoff * 2 R_c. A pair
// of classes a, b with R_b >= R_a (b <= a) is found from the members of a
// in the grid of b: their reach cutoff (R_i + R_j) <= cutoff * 2 R_b is at
// most a cell of b, so the 27 cells around a member hold every partner.
// Each pair is met once: within a class from its lower index, across
// classes from the smaller particle.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include <omp.h>

#include "pwcontact/screen.hpp"

namespace pwcontact::screen {

// One class's grid: its members sorted by cell (counting sort, stable, so
// the order is that of the particle indices within a cell), with copies of
// what the candidate search reads, in that order: a cell's members are then
// contiguous in memory (the search streams through them instead of jumping
// across the particle arrays). Positions are kept as given, with the number
// of box lengths that wraps them into the box (periodic boxes), so that a
// pair's r12 is the plain difference of its centres plus one multiple of the
// box length, rounded once (wrapped coordinates would cost eps L of it).
struct ClassGrid {
  double radius = 0;                   // the largest bounding radius in the class
  std::array<int, 3> cells = {1, 1, 1};
  std::array<double, 3> inverse_side = {0, 0, 0};  // cells per unit length
  std::vector<std::uint32_t> cell_start;  // cells + 1 offsets into members
  std::vector<std::uint32_t> members;     // particle indices, by cell
  std::vector<double> position[3], bounding, inscribed, sphere, q[6];  // by member
  std::vector<std::int32_t> image[3];  // floor(x / L) per member (periodic), else 0
};

struct CellLists {
  Box box;
  std::array<double, 3> origin = {0, 0, 0};  // open boxes: the lower corner of all centres
  std::vector<std::uint8_t> size_class;      // per particle
  std::vector<ClassGrid> grids;              // by class, largest radii first

  // A coordinate wrapped into [0, L] when periodic (as given otherwise).
  double wrapped(int k, double x) const {
    if (!box.periodic) return x;
    const double l = box.length[k];
    return x - l * std::floor(x / l);
  }
  // The cell of a (wrapped) coordinate along axis k.
  int cell_of(const ClassGrid& grid, int k, double x) const;
};

// Builds the classes and their grids (threads for the per-particle work).
CellLists build_cell_lists(const ParticleStore& particles, const Box& box, double cutoff,
                           int threads);

// Calls visit(begin, end, shift, nearest_image) for the members [begin, end)
// of every cell of `grid` around the wrapped position p (at most 27 cells,
// each once). shift (-1, 0 or 1 box lengths) takes a member's wrapped
// position to its image nearest p's cell (periodic wrap-around); where a
// periodic grid has fewer than 3 cells along an axis one cell can neighbour
// p's from both sides, and nearest_image asks the caller to take the minimum
// image itself.
template <class Visit>
void for_each_neighbour_cell(const CellLists& lists, const ClassGrid& grid,
                             const std::array<double, 3>& p, Visit&& visit) {
  int cell[3][3], count[3];
  int shift[3][3];
  bool nearest_image = false;
  for (int k = 0; k < 3; ++k) {
    const int centre = lists.cell_of(grid, k, p[k]);
    const int n = grid.cells[k];
    count[k] = 0;
    if (lists.box.periodic && n < 3) {
      nearest_image = true;
      for (int c = 0; c < n; ++c) cell[k][count[k]] = c, shift[k][count[k]++] = 0;
      continue;
    }
    for (int d = -1; d <= 1; ++d) {
      int c = centre + d;
      int s = 0;
      if (lists.box.periodic) {
        if (c < 0) c += n, s = -1;
        if (c >= n) c -= n, s = 1;
      } else if (c < 0 || c >= n) {
        continue;
      }
      cell[k][count[k]] = c;
      shift[k][count[k]++] = s;
    }
  }
  for (int a = 0; a < count[0]; ++a)
    for (int b = 0; b < count[1]; ++b) {
      const std::size_t row =
          (std::size_t(cell[0][a]) * std::size_t(grid.cells[1]) + std::size_t(cell[1][b])) *
          std::size_t(grid.cells[2]);
      for (int c = 0; c < count[2]; ++c) {
        const std::size_t at = row + std::size_t(cell[2][c]);
        const int s[3] = {shift[0][a], shift[1][b], shift[2][c]};
        visit(grid.cell_start[at], grid.cell_start[at + 1], s, nearest_image);
      }
    }
}

// A candidate pair: particle i (class class_i, place at_i in its grid) and
// j (class_j, at_j), r = c_j - c_i by the nearest image.
struct Candidate {
  std::uint32_t i, j, at_i, at_j;
  std::size_t class_i, class_j;
  double r[3];
};

// Every candidate pair once (within a class from the lower index, across
// classes from the smaller particle): calls on_candidate(thread, candidate)
// in the thread that finds it, then done(thread) when the thread has no more.
// Each class's members are taken in cell order (the neighbour cells of
// consecutive members are the same, and in cache), shared among the threads;
// progress (may be empty) hears the fraction done now and then.
template <class OnCandidate, class Done>
void search_candidates(const CellLists& lists, const Box& box, int threads,
                       const std::function<void(double)>& progress, OnCandidate&& on_candidate,
                       Done&& done) {
  std::size_t total = 0;
  std::vector<std::size_t> done_before(lists.grids.size() + 1, 0);  // members of earlier classes
  for (std::size_t g = 0; g < lists.grids.size(); ++g) {
    done_before[g + 1] = done_before[g] + lists.grids[g].members.size();
    total += lists.grids[g].members.size();
  }
#pragma omp parallel num_threads(threads)
  {
    const int thread = omp_get_thread_num();
    Candidate c;
    for (std::size_t own = 0; own < lists.grids.size(); ++own) {
      const ClassGrid& home = lists.grids[own];
#pragma omp for schedule(dynamic, 1024)
      for (std::size_t at = 0; at < home.members.size(); ++at) {
        if (progress && thread == 0 && at % 16384 == 0)
          progress((double(done_before[own]) + double(at)) / double(total));
        c.i = home.members[at];
        c.at_i = std::uint32_t(at);
        c.class_i = own;
        // The cell search takes the wrapped position; r the given centres
        // plus one multiple of the box length per axis.
        const double centre[3] = {home.position[0][at], home.position[1][at], home.position[2][at]};
        const std::array<double, 3> p = {lists.wrapped(0, centre[0]), lists.wrapped(1, centre[1]),
                                         lists.wrapped(2, centre[2])};
        const std::int32_t image_i[3] = {home.image[0][at], home.image[1][at], home.image[2][at]};
        // Classes of radii at least as large as i's (indices 0 .. own).
        for (std::size_t g = 0; g <= own; ++g) {
          const ClassGrid& grid = lists.grids[g];
          c.class_j = g;
          for_each_neighbour_cell(
              lists, grid, p,
              [&](std::uint32_t begin, std::uint32_t end, const int (&shift)[3],
                  bool nearest_image) {
                for (std::uint32_t m = begin; m < end; ++m) {
                  c.j = grid.members[m];
                  if (g == own && c.j <= c.i) continue;  // within a class, from the lower index
                  c.at_j = m;
                  for (int k = 0; k < 3; ++k) {
                    c.r[k] = grid.position[k][m] - centre[k];
                    const int lengths = shift[k] - (grid.image[k][m] - image_i[k]);
                    if (lengths != 0) c.r[k] += double(lengths) * box.length[k];
                  }
                  if (nearest_image)
                    for (int k = 0; k < 3; ++k)
                      c.r[k] -= box.length[k] * std::nearbyint(c.r[k] / box.length[k]);
                  on_candidate(thread, c);
                }
              });
        }
      }
    }
    done(thread);
  }
}

}  // namespace pwcontact::screen
