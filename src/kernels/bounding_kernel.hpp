// The coarse test of a moving scene's query (moving_scene.cpp): which of a
// cell's members have bounding spheres that may meet a trial's (the first
// test of doc/theory.md eq. 33), several members per register. Compiled once
// per target (target.hpp).
//
// The answer is a superset of the exact test |r|^2 < (reach + scale R_j)^2
// that the caller then makes member by member in its own (baseline)
// arithmetic: the lanes may round differently (FMA), so the limit is widened
// by a relative 1e-12 (the two roundings differ by a few eps relatively, all
// terms being positive) and by an absolute 1e-300 (where the squares
// underflow, the relative bound does not hold). A member the exact test
// keeps is never dropped here; the few let through in excess are dropped
// there.
#pragma once

#include "kernels/kernel_api.hpp"
#include "kernels/simd_math.hpp"

namespace pwcontact::kernels::PWCONTACT_TARGET {

template <class Arch>
std::uint32_t bounding_spheres_meet(const CoarseMembers& members, std::uint32_t n,
                                    const double origin[3], double reach, double scale) {
  using B = xsimd::batch<double, Arch>;
  constexpr std::uint32_t lanes = B::size;
  const B ox(origin[0]), oy(origin[1]), oz(origin[2]), r(reach), s(scale);
  const B widen(1 + 1e-12), floor(1e-300);
  std::uint32_t meet = 0;
  // Whole registers: a cell's room is whole tiles of coarse_tile members, a
  // multiple of the lanes, so lanes beyond n read the tile's unused slots,
  // masked off below.
  static_assert(coarse_tile % lanes == 0, "a register within one row of a tile");
  for (std::uint32_t k = 0; k < n; k += lanes) {
    const double* row = members.tiles + coarse_place(k);
    const B x = B::load_unaligned(row) - ox;
    const B y = B::load_unaligned(row + coarse_tile) - oy;
    const B z = B::load_unaligned(row + 2 * coarse_tile) - oz;
    const B limit = xsimd::fma(s, B::load_unaligned(row + 3 * coarse_tile), r);
    const B rr = xsimd::fma(x, x, xsimd::fma(y, y, z * z));
    meet |= lane_bits(rr < xsimd::fma(limit * limit, widen, floor)) << k;
  }
  return n >= 32 ? meet : meet & ((std::uint32_t(1) << n) - 1);
}

}  // namespace pwcontact::kernels::PWCONTACT_TARGET
