// The portable target: no SIMD kernel at all. It leaves every lane to the
// driver (status needs_fallback), which answers each pair on the reference
// path (reference.hpp) exactly as it answers the lanes a SIMD kernel leaves:
// status ok_fallback, counted in BatchReport::fallbacks, Accuracy::high in
// long double. Plain C++ with the baseline flags: it is the whole batch path
// where pwcontact is built without its x86 kernels, and anywhere with
// PWCONTACT_ISA=fallback, so that the driver, the screen and the tests can be
// run against answers that do not depend on a SIMD kernel. The iteration
// setting trades the kernels' work; there is none to trade here.
#include <cstddef>
#include <cstring>

#include "kernels/kernel_api.hpp"

namespace pwcontact::kernels {
namespace {

void leave_every_lane(Status* status, std::size_t n) {
  static_assert(sizeof(Status) == 1, "statuses are written as bytes");
  std::memset(status, int(std::uint8_t(needs_fallback)), n);
}

template <class In, class Out>
void solve_full(const PairSpan<In>&, const ResultSpan<Out>& out, std::size_t n,
                const ChunkSettings&, const Scratch&, ChunkCounters&) {
  leave_every_lane(out.status, n);
}

template <class In>
void solve_overlap(const PairSpan<In>&, const OverlapSpan& out, std::size_t n, const ChunkSettings&,
                   const Scratch&, ChunkCounters&) {
  leave_every_lane(out.status, n);
}

// The coarse test member by member, in the caller's own arithmetic (so
// exactly the test the caller makes after it, with its absolute slack of
// 2^-1000 for squares near the subnormal numbers: screen::square_slack).
std::uint32_t bounding_spheres_meet(const CoarseMembers& members, std::uint32_t n,
                                    const double origin[3], double reach, double scale) {
  std::uint32_t meet = 0;
  for (std::uint32_t k = 0; k < n; ++k) {
    const double* row = members.tiles + coarse_place(k);
    const double x = row[0] - origin[0], y = row[coarse_tile] - origin[1],
                 z = row[2 * coarse_tile] - origin[2];
    const double limit = reach + scale * row[3 * coarse_tile];
    meet |= std::uint32_t(x * x + y * y + z * z < limit * limit + 0x1p-1000) << k;
  }
  return meet;
}

}  // namespace

const KernelTable kernel_table_fallback = {
    "fallback",
    1,
    1,
    &solve_full<double, double>,
    &solve_full<double, double>,
    &solve_full<double, double>,
    &solve_full<float, float>,
    &solve_overlap<double>,
    &solve_overlap<double>,
    &solve_overlap<double>,
    &solve_overlap<float>,
    &bounding_spheres_meet,
};

}  // namespace pwcontact::kernels
