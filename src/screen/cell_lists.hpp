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
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pwcontact/screen.hpp"

namespace pwcontact::screen {

// One class's grid: its members sorted by cell (counting sort, stable, so
// the order is that of the particle indices within a cell).
struct ClassGrid {
  double radius = 0;                   // the largest bounding radius in the class
  std::array<int, 3> cells = {1, 1, 1};
  std::array<double, 3> inverse_side = {0, 0, 0};  // cells per unit length
  std::vector<std::uint32_t> cell_start;  // cells + 1 offsets into members
  std::vector<std::uint32_t> members;     // particle indices, by cell
};

struct CellLists {
  Box box;
  std::array<double, 3> origin = {0, 0, 0};  // open boxes: the lower corner of all centres
  std::vector<std::uint8_t> size_class;      // per particle
  std::vector<ClassGrid> grids;              // by class, largest radii first

  // The cell of a position along axis k (wrapped into the box when periodic).
  int cell_of(const ClassGrid& grid, int k, double x) const;
};

// Builds the classes and their grids (threads for the per-particle work).
CellLists build_cell_lists(const ParticleStore& particles, const Box& box, double cutoff,
                           int threads);

// Calls visit(j) for every particle j of `grid` in the cells around the
// position p (at most 27 cells, each visited once even when a periodic grid
// has fewer than 3 cells along an axis).
template <class Visit>
void for_each_neighbour(const CellLists& lists, const ClassGrid& grid,
                        const std::array<double, 3>& p, Visit&& visit) {
  int centre[3], offsets[3][3], count[3];
  for (int k = 0; k < 3; ++k) {
    centre[k] = lists.cell_of(grid, k, p[k]);
    const int n = grid.cells[k];
    count[k] = 0;
    for (int d = -1; d <= 1; ++d) {
      int c = centre[k] + d;
      if (lists.box.periodic) {
        c = (c + n) % n;
        bool seen = false;
        for (int m = 0; m < count[k]; ++m) seen = seen || offsets[k][m] == c;
        if (seen) continue;
      } else if (c < 0 || c >= n) {
        continue;
      }
      offsets[k][count[k]++] = c;
    }
  }
  for (int a = 0; a < count[0]; ++a)
    for (int b = 0; b < count[1]; ++b)
      for (int c = 0; c < count[2]; ++c) {
        const std::size_t cell =
            (std::size_t(offsets[0][a]) * std::size_t(grid.cells[1]) + std::size_t(offsets[1][b])) *
                std::size_t(grid.cells[2]) +
            std::size_t(offsets[2][c]);
        for (std::uint32_t m = grid.cell_start[cell]; m < grid.cell_start[cell + 1]; ++m)
          visit(grid.members[m]);
      }
}

}  // namespace pwcontact::screen
