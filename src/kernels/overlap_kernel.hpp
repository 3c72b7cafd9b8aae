// The overlap-only batch kernel: whether mu < cutoff for many pairs at once,
// decided with certificates so that most lanes stop early.
//
// Bounds on mu^2 (equation numbers refer to doc/theory.md):
// - before any evaluation, from extents along the centre line r = r12:
//   the points at distance rho_i = |r| / sqrt(r^T Qi^-1 r) from centre i
//   towards the other centre lie in ellipsoid i, so scaled by mu the two
//   ellipsoids share a point of the segment once mu (rho1 + rho2) >= |r|:
//   mu^2 <= 1 / (1/sqrt(s0) + 1/sqrt(s1))^2 with s_i = r^T Qi^-1 r (eq. 31); and the
//   support extents h_i = sqrt(r^T Qi r) / |r| give a separating plane
//   perpendicular to r while mu (h1 + h2) < |r|: mu^2 >= |r|^4 / (sqrt(r^T Q1 r)
//   + sqrt(r^T Q2 r))^2 (eq. 32). Both are exact for spheres.
// - after an evaluation at lambda: mu^2 >= f(lambda) (eqs. 6, 27), and since f
//   is concave, its tangents at the bracket ends lie above it: mu^2 is at most
//   the height where they cross (eq. 29).
// A bound decides a lane when it clears cutoff^2 by more than its rounding
// error, estimated as a multiple of eps times the element growth of the
// factorisations behind it (the float kernels were measured below ~100 growth
// eps; the margin is 256 growth eps; eq. 40); bounds that have met within
// their margins leave the lane to the reference path (eq. 45). Each bound
// and the decision are pure functions of an evaluation and a bracket
// (extent_bounds, bounds_after, certificate_decision); OverlapBlock keeps
// their inputs as lane state between passes.
#pragma once

#include "kernels/target.hpp"

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include "kernels/kernel_api.hpp"
#include "kernels/lane_blocks.hpp"
#include "kernels/simd_math.hpp"

namespace pwcontact::kernels::PWCONTACT_TARGET {

template <class T>
inline constexpr T certificate_margin_per_growth = 256 * std::numeric_limits<T>::epsilon();

// The cheap first pass decides lanes whose Q both have tr^3 / det (a bound
// on the condition number) at most this with a margin of 256 eps times it
// (see OverlapBlock::prefilter): double up to aspect ratios ~30 for
// needles and ~350 for discs (tr^3 / det ~ a^4 and 8 a^2), float up to most
// of the random family's shapes (semi-axes within a factor 4: tr^3 / det up
// to 364, for semi-axes 0.5, 0.5 and 2; 0.09 % of its forms are beyond 256).
template <class T>
inline constexpr T prefilter_conditioning = std::is_same<T, double>::value ? T(1e6) : T(256);
// A lane the trace test or its range refuses takes its own margin instead,
// 256 eps times the ratio rho of the magnitudes cancelled in n_i, det Qi and
// H_i to their values (eq. 47), when that margin is at most this: the
// first-order error it covers, at most ~28 eps rho with the rounding of a
// double pair to float (mixed precision), is then at most ~0.06.
// Such a lane is decided by the extents only (its evaluation would need the
// trace test's range argument).
inline constexpr double prefilter_largest_margin = 0.5;
// The range of such a lane: n_i, det Qi, H_i and |r|^2 within
// [floor, 1 / floor], so that their products (n1 n2, n_i det Qj, |r|^4) are
// normal numbers, and the larger trace below `top`, so that nothing formed
// on the way (cofactors, magnitudes) overflows. A product that underflows
// on the way errs by less than the smallest normal number (even flushed to
// zero), times at most |r|^2 <= 1 / floor: 2^-86 (float) against n_i >=
// 2^-40, far below eps.
template <class T>
inline constexpr T prefilter_floor = std::is_same<T, double>::value ? T(0x1p-400) : T(0x1p-40);
template <class T>
inline constexpr T prefilter_top = std::is_same<T, double>::value ? T(0x1p100) : T(0x1p12);
// How far ahead the prefilter asks for its inputs, in blocks (measured).
inline constexpr std::size_t prefilter_prefetch_blocks = 8;

// ---------------------------------------------------------------------------
// The certificates as pure functions of an evaluation and a bracket: the
// bounds on mu^2 each piece of information gives, and the decision they
// make. OverlapBlock keeps their inputs and results as its lane state.

// Bounds on mu^2 with their margins applied, and the margin they carry (the
// largest of every bound folded in so far, eq. 40).
template <class B>
struct CertifiedBounds {
  B lower;   // mu^2 >= lower
  B upper;   // mu^2 <= upper
  B margin;  // relative rounding allowance of the computed bounds
};

// f and g = -f' at the ends of the bracket [lo, hi]: g_lo < 0 <= g_hi.
template <class B>
struct BracketEnds {
  B f_lo, g_lo, f_hi, g_hi;
};

// The margin of the extents' bounds (eq. 40): the slopes carry the growth of
// their factorisations, the support extents H_i = r^T Qi r the ratio of
// |r|^T |Qi| |r| to their value.
template <class B>
PWCONTACT_INLINE B extents_margin(const PairLanes<B>& p, const Ldlt<B>& f1, const Ldlt<B>& f2,
                                  const B& h1, const B& h2) {
  using T = typename B::value_type;
  B abs_r[3];
  for (int k = 0; k < 3; ++k) abs_r[k] = xsimd::abs(p.r[k]);
  B abs_q1[6], abs_q2[6];
  for (int k = 0; k < 6; ++k) abs_q1[k] = xsimd::abs(p.q1[k]), abs_q2[k] = xsimd::abs(p.q2[k]);
  const B spread =
      xsimd::max(quadratic_form(abs_q1, abs_r) / h1, quadratic_form(abs_q2, abs_r) / h2);
  return B(certificate_margin_per_growth<T>) *
         xsimd::max(xsimd::max(growth(f1, p.q1), growth(f2, p.q2)), spread);
}

// Before any evaluation, from the extents along r (eqs. 31, 32): the
// support extents bound mu^2 from below by |r|^4 / (sqrt(H1) + sqrt(H2))^2
// with H_i = r^T Qi r (rr = |r|^2), the radial extents from above by
// `radial` (eq. 31, squared, formed by the caller from its slopes). The
// margin is eq. 40's (accurate pass) or eq. 41's (cheap pass). Coincident
// centres (r = 0) have mu^2 = 0 (eq. 35): upper 0.
template <class B>
PWCONTACT_INLINE CertifiedBounds<B> extent_bounds(const B& rr, const B& h1, const B& h2,
                                                  const B& radial, const B& margin,
                                                  const typename B::batch_bool_type& coincident) {
  const B support = xsimd::sqrt(h1) + xsimd::sqrt(h2);
  const B lower = rr * rr / (support * support) * (B(1) - margin);
  const B upper = radial * (B(1) + margin);
  return {lower, xsimd::select(coincident, B(0), upper), margin};
}

// The radial bound (eq. 31) from n_i = r^T adj(Qi) r and det Qi, with
// s_i = n_i / det_i: 1 / (1/sqrt(s1) + 1/sqrt(s2))^2 =
// n1 n2 / (sqrt(n1 det2) + sqrt(n2 det1))^2, and the guess at its maximiser
// (eq. 30), without a division per slope.
template <class B>
struct RadialExtents {
  B bound, guess;
  RadialExtents(const B& n1, const B& n2, const B& det1, const B& det2) {
    const B root = xsimd::sqrt(n2 * det1);
    const B extents = xsimd::sqrt(n1 * det2) + root;
    bound = n1 * n2 / (extents * extents);
    guess = root / extents;
  }
};

// The bracket ends after evaluation e, as the safeguarded step narrows the
// bracket (eq. 20: g > 0 makes lambda the upper end, g < 0 the lower). g = 0
// makes it the upper end too (OverlapBlock::tighten narrows the bracket to
// it): its tangent is then horizontal at f, and the crossing (eq. 29) is f
// itself. Left out, a lane whose g is exactly 0 kept the bound of its first
// guess and took the same evaluation again, since its Newton step is 0, up
// to the cap and the reference path: a pair symmetric about the plane
// halfway between the centres, whose lambda* = 1/2 is where the radial
// guess lands (1,216 overlapping pairs of the pw85 family, mu^2 ~ 0.002 to
// 0.13, 40 evaluations each and then the reference path).
template <class B>
PWCONTACT_INLINE BracketEnds<B> ends_after(const BracketEnds<B>& ends, const Evaluation<B>& e) {
  const auto above = e.g >= B(0), below = e.g < B(0);
  return {xsimd::select(below, e.f, ends.f_lo), xsimd::select(below, e.g, ends.g_lo),
          xsimd::select(above, e.f, ends.f_hi), xsimd::select(above, e.g, ends.g_hi)};
}

// Where the tangents of the concave f at the bracket ends cross, a bound on
// mu^2 from above (eq. 29): f_lo - g_lo (x - lo) = f_hi - g_hi (x - hi).
template <class B>
PWCONTACT_INLINE B tangent_crossing(const B& lo, const B& hi, const BracketEnds<B>& ends) {
  const B x = (ends.f_hi - ends.f_lo + ends.g_hi * hi - ends.g_lo * lo) / (ends.g_hi - ends.g_lo);
  return ends.f_lo - ends.g_lo * (x - lo);
}

// The bounds after evaluation e, with [lo, hi] and `ends` already narrowed
// by it: f(lambda) from below (eq. 27), the tangents' crossing from above
// (eq. 29), each with the margin, widened to the growth of Q(lambda)'s
// factorisation (eq. 40).
template <class B>
PWCONTACT_INLINE CertifiedBounds<B> bounds_after(const CertifiedBounds<B>& bounds,
                                                 const Evaluation<B>& e, const B& lo, const B& hi,
                                                 const BracketEnds<B>& ends) {
  using T = typename B::value_type;
  const B margin =
      xsimd::max(bounds.margin, B(certificate_margin_per_growth<T>) * growth(e.ldlt, e.q));
  const B tangent = tangent_crossing(lo, hi, ends);
  return {xsimd::max(bounds.lower, e.f * (B(1) - margin)),
          xsimd::min(bounds.upper, tangent * (B(1) + margin)), margin};
}

// What certified bounds decide against the cutoff mu_c^2 (eq. 45).
template <class B>
struct CertificateDecision {
  typename B::batch_bool_type overlapping;  // mu^2 < cutoff: upper below it
  typename B::batch_bool_type apart;        // mu^2 >= cutoff: lower at or above it
  typename B::batch_bool_type settled;      // the bounds have met within their rounding: more
                                            // evaluations would hardly narrow them
};

template <class B>
PWCONTACT_INLINE CertificateDecision<B> certificate_decision(const CertifiedBounds<B>& bounds,
                                                             const B& cutoff) {
  return {bounds.upper < cutoff, bounds.lower >= cutoff,
          bounds.upper <= bounds.lower * (B(1) + B(8) * bounds.margin)};
}

// What an undecided lane keeps between passes besides its pair: its slots
// in the kept arrays, after the pair's components.
enum OverlapSlot : int {
  overlap_lambda = pair_components,
  overlap_lo,  // the bracket, with f and g at its ends (for the tangents)
  overlap_hi,
  overlap_f_lo,
  overlap_g_lo,
  overlap_f_hi,
  overlap_g_hi,
  overlap_lower,  // the certified bounds on mu^2, margins applied
  overlap_upper,
  overlap_margin,  // the largest margin so far
  overlap_slots_end
};
inline constexpr int overlap_state = overlap_slots_end - pair_components;
template <class T>
using OverlapKept = KeptLanes<T, overlap_state>;

template <class Arch, class T>
class OverlapBlock : public LaneGroups<Arch, T> {
  using Base = LaneGroups<Arch, T>;
  using Base::at_, Base::pair_, Base::lambda_, Base::lo_, Base::hi_, Base::live_, Base::settings_,
      Base::counters_;

 public:
  using Base::size, Base::U, Base::W;
  using typename Base::B;
  using typename Base::M;

  OverlapBlock(const ChunkSettings& settings, ChunkCounters& counters, OverlapKept<T>& kept)
      : Base(settings, counters), kept_(kept), cutoff_(T(settings.cutoff_mu2)) {}

  // A first pass's block (see FullBlock::start), answered at `position` of
  // the chunk or at the positions in `index`: checks, nondimensionalises,
  // and decides what the extents along r12 decide.
  template <class In>
  PWCONTACT_INLINE void start(const PairSpan<In>& in, std::size_t from, std::size_t position,
                              const std::uint32_t* index, std::size_t real, const OverlapSpan& out,
                              bool keep) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, index, real, u);
      const PairLanes<B>& p = pair_[u];
      const Ldlt<B> f1 = factor(p.q1), f2 = factor(p.q2);
      const B s0 = inverse_quadratic_form(f1, p.r), s1 = inverse_quadratic_form(f2, p.r);
      const M coincident = (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
      live_[u] = this->usable(u) & positive_definite(f1, p.q1) & positive_definite(f2, p.q2) &
                 (coincident | slopes_in_range(s0, s1));
      const B root0 = xsimd::sqrt(s0), root1 = xsimd::sqrt(s1);
      lambda_[u] = root1 / (root0 + root1);
      lo_[u] = B(0);
      hi_[u] = B(1);
      f_lo_[u] = B(0);
      g_lo_[u] = -s0;  // g = -f', f'(0) = s0
      f_hi_[u] = B(0);
      g_hi_[u] = s1;

      const B h1 = quadratic_form(p.q1, p.r), h2 = quadratic_form(p.q2, p.r);
      const B radial = B(1) / (B(1) / root0 + B(1) / root1);  // eq. 31, from the slopes
      set_bounds(u, extent_bounds(dot3(p.r, p.r), h1, h2, radial * radial,
                                  extents_margin(p, f1, f2, h1, h2), coincident));
      live_[u] = live_[u] & !decide_only(u, out, &ChunkCounters::decided_by_prefilter);
    }
    // The lanes left take their first evaluation right away, before any
    // packing: most of them are decided by it.
    step(out, keep);
  }

  // The first, cheap pass: the extents along r12 from adjugates and
  // determinants instead of factorisations (no division per pivot). Its
  // rounding errors are bounded through the condition number: for positive
  // definite Q, lambda_max <= tr Q and lambda_min >= det Q / lambda_max^2, so
  // cond Q <= tr^3 / det; with tr^3 <= K det, the relative errors of
  // r^T Q r, r^T adj(Q) r and det Q are a few tens of eps K (each cofactor
  // errs by ~eps lambda_max^2, while r^T adj(Q) r >= det |r|^2 / lambda_max).
  // Lanes beyond K, or out of prefilter_in_range, take margins of their own
  // (own_margin, eq. 47) and the extents only. All the undecided lanes are
  // left (status needs_fallback) to the accurate solve (start() and the
  // passes after it), which also makes the exact validity checks.
  template <class In>
  PWCONTACT_INLINE void prefilter(const PairSpan<In>& in, std::size_t from, std::size_t position,
                                  std::size_t real, const OverlapSpan& out) {
    const B conditioning(prefilter_conditioning<T>);
    M own_lanes[U];
    OwnInputs own_inputs[U];
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, nullptr, real, u);
      const PairLanes<B>& p = pair_[u];
      const Adjugate<B> a1(p.q1), a2(p.q2);
      const B h1 = quadratic_form(p.q1, p.r), h2 = quadratic_form(p.q2, p.r);
      const B t1 = p.q1[0] + p.q1[3] + p.q1[5], t2 = p.q2[0] + p.q2[3] + p.q2[5];
      const M conditioned =
          (t1 * t1 * t1 <= conditioning * a1.det) & (t2 * t2 * t2 <= conditioning * a2.det);
      const B rr = dot3(p.r, p.r);
      const M usable = this->usable(u) & a1.positive_definite(p.q1) & a2.positive_definite(p.q2);
      live_[u] = usable & conditioned & prefilter_in_range(t1, t2, rr);
      // The lanes the trace test or its range refuses: their own margins,
      // after the block (own_margin).
      own_lanes[u] = usable & !live_[u];
      const B margin(certificate_margin_per_growth<T> * prefilter_conditioning<T>);  // eq. 41
      // n_i = r^T adj(Qi) r, so that s_i = n_i / det_i.
      const B n1 = a1.form(p.r), n2 = a2.form(p.r);
      const RadialExtents<B> radial(n1, n2, a1.det, a2.det);
      // The extents without their margin (exact: times 1), and with it.
      const CertifiedBounds<B> extents = extent_bounds(rr, h1, h2, radial.bound, B(0), rr == B(0));
      set_bounds(u, {extents.lower * (B(1) - margin), extents.upper * (B(1) + margin), margin});
      if (xsimd::any(own_lanes[u])) {
        own_inputs[u] = {p,
                         n1,
                         n2,
                         a1.det,
                         a2.det,
                         h1,
                         h2,
                         rr,
                         xsimd::max(t1, t2),
                         extents.lower,
                         extents.upper};
      }
      live_[u] = live_[u] & !decide_only(u, out, &ChunkCounters::decided_by_prefilter, true);
      if (xsimd::none(live_[u])) continue;

      // One Newton evaluation for the lanes left, from the radial guess:
      // f(lambda) from below, and from above the tangents at the new bracket
      // ends (one of them at lambda = 0 or 1, with slope s1 = n1 / det1 or
      // s2 = n2 / det2, whose rounding the margin already covers).
      const B slope0 = n1 / a1.det, slope1 = n2 / a2.det;
      lambda_[u] = radial.guess;
      lo_[u] = B(0);
      hi_[u] = B(1);
      f_lo_[u] = B(0);
      g_lo_[u] = -slope0;
      f_hi_[u] = B(0);
      g_hi_[u] = slope1;
      tighten(u);  // (with the margin set above: the prefilter's, eq. 41)
      counters_.lane_evaluations += at_[u].real;
      decide_only(u, out, &ChunkCounters::decided_by_certificate);
    }
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      if (xsimd::none(own_lanes[u])) continue;
      // (Copies, made above: were the block's own pair passed, it could not
      // be kept in registers through the loop above, measured 5-10 % slower
      // on the scene family, whose registers seldom come here.)
      const B margin = own_margin(own_inputs[u]);
      live_[u] = own_lanes[u] & (margin <= B(T(prefilter_largest_margin)));
      set_bounds(u, {own_inputs[u].lower * (B(1) - margin), own_inputs[u].upper * (B(1) + margin),
                     margin});
      decide_only(u, out, &ChunkCounters::decided_by_prefilter);
    }
  }

  // A later pass's block: the kept lanes from position j on (count in all).
  PWCONTACT_INLINE void resume(std::size_t j, std::size_t count) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      const std::size_t at = j + std::size_t(u) * W;
      for (int k = 0; k < pair_components; ++k)
        component(pair_[u], k) = B::load_unaligned(kept_.values[k] + at);
      auto slot = [&](int k) { return B::load_unaligned(kept_.values[k] + at); };
      lambda_[u] = slot(overlap_lambda);
      lo_[u] = slot(overlap_lo);
      hi_[u] = slot(overlap_hi);
      f_lo_[u] = slot(overlap_f_lo);
      g_lo_[u] = slot(overlap_g_lo);
      f_hi_[u] = slot(overlap_f_hi);
      g_hi_[u] = slot(overlap_g_hi);
      lower_[u] = slot(overlap_lower);
      upper_[u] = slot(overlap_upper);
      margin_[u] = slot(overlap_margin);
      at_[u] = {0, kept_.index + at, at < count ? (count - at < W ? count - at : W) : 0};
      live_[u] = this->real_lanes(u);
    }
  }

  // One evaluation per lane: tightens both bounds and decides what they decide.
  PWCONTACT_INLINE void step(const OverlapSpan& out, bool keep) {
    this->count_evaluations(1);
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      tighten(u);
      decide(u, out, keep, &ChunkCounters::decided_by_certificate);
    }
  }

 private:
  // The cheap pass forms products of degree up to 12 in the length scale
  // (n_i det_j, n1 n2, |r|^4): it takes only lanes whose numbers keep them
  // within the type's normal range, decided from the traces (the larger
  // t_max within [D, 3 D] of the scale D) and |r|^2. With both traces within
  // a factor 2^-100 (float: 2^-16) of each other, |r|^2 within 2^+-200
  // (2^+-16) of t_max, t_max within 2^+-30 (2^+-4) of 1 and cond(Q) <= 1e6
  // (256), those products stay within 2^+-800 (2^+-115). The other lanes go
  // to the accurate solve, whose quantities are of degree -1 to 4.
  static PWCONTACT_INLINE M prefilter_in_range(const B& t1, const B& t2, const B& rr) {
    constexpr bool single = std::is_same<T, float>::value;
    const B ratio(single ? T(0x1p-16) : T(0x1p-100));
    const B low(single ? T(0x1p-16) : T(0x1p-200)), high(single ? T(0x1p16) : T(0x1p200));
    const B smallest(single ? T(0x1p-4) : T(0x1p-30)), largest(single ? T(0x1p4) : T(0x1p30));
    const B t_max = xsimd::max(t1, t2);
    return (xsimd::min(t1, t2) >= ratio * t_max) & (rr >= low * t_max) & (rr <= high * t_max) &
           (t_max >= smallest) & (t_max <= largest);
  }

  // The cheap pass for the lanes the trace test refuses (elongated shapes)
  // or whose range it does not take (sizes far apart): the extents only
  // (eqs. 31, 32), with the lane's own margin (eq. 47), 256 eps times rho,
  // the largest ratio of the magnitudes cancelled in n_i, det Qi and H_i
  // (Adjugate::form_magnitude, det_magnitude; |r|^T |Qi| |r|) to their
  // computed values, which their rounding errors are at most gamma_9,
  // gamma_6 and gamma_6 of; infinite unless n_i, det Qi, H_i and |r|^2 lie
  // within prefilter_floor and its reciprocal and the larger trace below
  // prefilter_top. A lane is taken when its margin is at most
  // prefilter_largest_margin. Out of line, after the block, from copies of
  // what the block computed: inlined into the block's loop it made the scene
  // family's cheap pass 5-10 % slower (interleaved runs), though 1.4 % of
  // its float registers and none of its double ones hold such a lane.
  struct OwnInputs {
    PairLanes<B> p;
    B n1, n2, det1, det2, h1, h2, rr, t_max;
    B lower, upper;  // the extents' bounds, without margin
  };
  __attribute__((noinline)) static B own_margin(const OwnInputs& in) {
    const PairLanes<B>& p = in.p;
    B abs_r[3], abs_q1[6], abs_q2[6];
    for (int k = 0; k < 3; ++k) abs_r[k] = xsimd::abs(p.r[k]);
    for (int k = 0; k < 6; ++k) abs_q1[k] = xsimd::abs(p.q1[k]), abs_q2[k] = xsimd::abs(p.q2[k]);
    const B rho = xsimd::max(
        xsimd::max(xsimd::max(Adjugate<B>::form_magnitude(p.q1, abs_r) / in.n1,
                              Adjugate<B>::form_magnitude(p.q2, abs_r) / in.n2),
                   xsimd::max(Adjugate<B>::det_magnitude(p.q1) / in.det1,
                              Adjugate<B>::det_magnitude(p.q2) / in.det2)),
        xsimd::max(quadratic_form(abs_q1, abs_r) / in.h1, quadratic_form(abs_q2, abs_r) / in.h2));
    // (Each number tested on its own: min and max of a NaN and a number give
    // the number on these instruction sets.)
    const B floor(prefilter_floor<T>), ceiling(T(1) / prefilter_floor<T>);
    const auto within = [&](const B& x) { return (x >= floor) & (x <= ceiling); };
    const M in_range = within(in.n1) & within(in.n2) & within(in.det1) & within(in.det2) &
                       within(in.h1) & within(in.h2) & within(in.rr) &
                       (in.t_max <= B(prefilter_top<T>));
    return xsimd::select(in_range, B(certificate_margin_per_growth<T>) * rho,
                         B(std::numeric_limits<T>::infinity()));
  }

  // One evaluation at lambda, a safeguarded step, and the bounds it gives
  // (bounds_after).
  PWCONTACT_INLINE void tighten(int u) {
    const Evaluation<B> e = evaluate(pair_[u], lambda_[u]);
    const BracketEnds<B> ends = ends_after(bracket_ends(u), e);
    f_lo_[u] = ends.f_lo;
    g_lo_[u] = ends.g_lo;
    f_hi_[u] = ends.f_hi;
    g_hi_[u] = ends.g_hi;
    this->advance(e, u);
    // (g = 0: lambda is the upper end, as in ends_after; advance() narrows
    // only for g > 0, and its step from g = 0 stays at lambda, in the bracket.)
    hi_[u] = xsimd::select(e.g == B(0), e.lambda, hi_[u]);
    set_bounds(u, bounds_after(bounds(u), e, lo_[u], hi_[u], ends));
  }

  PWCONTACT_INLINE BracketEnds<B> bracket_ends(int u) const {
    return {f_lo_[u], g_lo_[u], f_hi_[u], g_hi_[u]};
  }
  PWCONTACT_INLINE CertifiedBounds<B> bounds(int u) const {
    return {lower_[u], upper_[u], margin_[u]};
  }
  PWCONTACT_INLINE void set_bounds(int u, const CertifiedBounds<B>& bounds) {
    lower_[u] = bounds.lower;
    upper_[u] = bounds.upper;
    margin_[u] = bounds.margin;
  }

  // Writes the live lanes' answers (decided or not: status ok or
  // needs_fallback), counts the decided ones and returns them. Lanes that are
  // not live keep what an earlier pass wrote, except in the first pass,
  // which writes every real lane.
  PWCONTACT_INLINE M decide_only(int u, const OverlapSpan& out, std::uint64_t ChunkCounters::*count,
                                 bool every_real_lane = false) {
    const CertificateDecision<B> decision = certificate_decision(bounds(u), B(cutoff_));
    const M overlapping = live_[u] & decision.overlapping;
    const M decided = overlapping | (live_[u] & decision.apart);
    const LanePositions& at = at_[u];
    const M written = every_real_lane ? this->real_lanes(u) : live_[u];
    write_flags<Arch, T>(out.overlap, at, written, overlapping, 1, 0);
    write_flags<Arch, T>(reinterpret_cast<std::uint8_t*>(out.status), at, written, decided,
                         std::uint8_t(Status::ok), std::uint8_t(needs_fallback));
    counters_.*count += count_lanes<Arch, T>(decided);
    return decided;
  }

  // decide_only, then keeps the undecided lanes or leaves them to the
  // reference path.
  PWCONTACT_INLINE void decide(int u, const OverlapSpan& out, bool keep,
                               std::uint64_t ChunkCounters::*count) {
    const M decided = decide_only(u, out, count);
    // Bounds that have met within their rounding straddle the cutoff: more
    // iterations would hardly decide the lane, the reference path will (eq. 45).
    const M undecidable = certificate_decision(bounds(u), B(cutoff_)).settled;
    if (keep) {
      B values[OverlapKept<T>::arrays];
      for (int k = 0; k < pair_components; ++k) values[k] = component(pair_[u], k);
      values[overlap_lambda] = lambda_[u];
      values[overlap_lo] = lo_[u];
      values[overlap_hi] = hi_[u];
      values[overlap_f_lo] = f_lo_[u];
      values[overlap_g_lo] = g_lo_[u];
      values[overlap_f_hi] = f_hi_[u];
      values[overlap_g_hi] = g_hi_[u];
      values[overlap_lower] = lower_[u];
      values[overlap_upper] = upper_[u];
      values[overlap_margin] = margin_[u];
      keep_lanes<Arch, T, overlap_state>(kept_, live_[u] & !decided & !undecidable, values, at_[u]);
    }
  }

  OverlapKept<T>& kept_;
  T cutoff_;
  B f_lo_[U], g_lo_[U], f_hi_[U], g_hi_[U], lower_[U], upper_[U], margin_[U];
};

// A block of the first pass and a block of a later pass (see
// first_pass_block in contact_kernel.hpp for why they are functions).
template <class Arch, class T, class In>
__attribute__((noinline)) void overlap_first_block(const PairSpan<In>& span, std::size_t from,
                                                   std::size_t position, const std::uint32_t* index,
                                                   std::size_t real, const OverlapSpan& out,
                                                   const ChunkSettings& settings,
                                                   ChunkCounters& counters, OverlapKept<T>& kept) {
  OverlapBlock<Arch, T> block(settings, counters, kept);
  block.start(span, from, position, index, real, out, true);
}

template <class Arch, class T>
__attribute__((noinline)) void overlap_later_block(std::size_t j, std::size_t count, bool keep,
                                                   const OverlapSpan& out,
                                                   const ChunkSettings& settings,
                                                   ChunkCounters& counters, OverlapKept<T>& kept) {
  OverlapBlock<Arch, T> block(settings, counters, kept);
  block.resume(j, count);
  block.step(out, keep);
}

// The passes after the first: the undecided lanes, packed, one evaluation
// per pass, until none is left or the cap is reached.
template <class Arch, class T>
void later_overlap_passes(OverlapKept<T>& kept, const OverlapSpan& out,
                          const ChunkSettings& settings, ChunkCounters& counters) {
  constexpr std::size_t size = OverlapBlock<Arch, T>::size;
  const int cap =
      settings.iterations == automatic_iterations ? settings.max_iterations : settings.iterations;
  for (int done = 0; kept.count > 0 && done < cap;) {
    const std::size_t count = kept.count;
    kept.count = 0;  // packed in place: a block is read before anything is written over it
    ++done;
    for (std::size_t j = 0; j < count; j += size)
      overlap_later_block<Arch, T>(j, count, done < cap, out, settings, counters, kept);
  }
}

// Overlap only, arithmetic T on pairs In; `index` (may be null) gives the
// chunk positions of the pairs when they were gathered from elsewhere.
template <class Arch, class T, class In>
void solve_overlap_on(const PairSpan<In>& in, const std::uint32_t* index, std::size_t n,
                      const OverlapSpan& out, const ChunkSettings& settings, OverlapKept<T>& kept,
                      ChunkCounters& counters) {
  for_each_block<Arch, OverlapBlock<Arch, T>::size>(
      in, n,
      [&](const PairSpan<In>& span, std::size_t from, std::size_t position, std::size_t real) {
        overlap_first_block<Arch, T, In>(span, from, position, index ? index + position : nullptr,
                                         real, out, settings, counters, kept);
      });
  later_overlap_passes<Arch, T>(kept, out, settings, counters);
}

// A block of the cheap first pass.
template <class Arch, class T, class In>
__attribute__((noinline)) void overlap_prefilter_block(const PairSpan<In>& span, std::size_t from,
                                                       std::size_t position, std::size_t real,
                                                       const OverlapSpan& out,
                                                       const ChunkSettings& settings,
                                                       ChunkCounters& counters,
                                                       OverlapKept<T>& kept) {
  OverlapBlock<Arch, T> block(settings, counters, kept);
  block.prefilter(span, from, position, real, out);
}

// Copies the pairs the first pass left (status needs_fallback) into the
// scratch arrays beyond the kept lanes', with their chunk positions.
template <class Arch, class In>
PairSpan<double> gather_undecided(const PairSpan<In>& in, std::size_t n, const Status* status,
                                  const Scratch& scratch, std::uint32_t*& positions,
                                  std::size_t& count) {
  // (After the kept lanes' arrays, in scratch_array's layout.)
  constexpr std::size_t first = OverlapKept<double>::footprint, used = first + pair_components + 1;
  double* columns[pair_components];
  for (int k = 0; k < pair_components; ++k)
    columns[k] = scratch_array<double, used>(scratch, first + std::size_t(k));
  positions = reinterpret_cast<std::uint32_t*>(
      scratch_array<double, used>(scratch, first + pair_components));
  count = 0;
  std::size_t i = 0;
  if constexpr (is_avx512<Arch>) {
    // Eight pairs at a time from columns of their own: the lanes left
    // compressed in a register and stored whole (the arrays have room past
    // their end), in the order of the loop below. (Measured on the pw85
    // family in single precision, where about half the lanes are left: the
    // loop below alone took 28 % of the kernels' time.)
    if (in.stride[0] == 1 && in.stride[1] == 1 && in.stride[2] == 1) {
      const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
      for (; i + 8 <= n; i += 8) {
        // (Of the statuses, only needs_fallback, 0xFF, has its top bit set.)
        const __mmask8 left = __mmask8(
            _mm_movemask_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(status + i))));
        if (left == 0) continue;
        for (int k = 0; k < pair_components; ++k) {
          const In* column = component(in, k) + i;
          __m512d values;
          if constexpr (std::is_same<In, double>::value)
            values = _mm512_loadu_pd(column);
          else
            values = _mm512_cvtps_pd(_mm256_loadu_ps(column));
          _mm512_storeu_pd(columns[k] + count, _mm512_maskz_compress_pd(left, values));
        }
        const __m256i at = _mm256_add_epi32(_mm256_set1_epi32(int(i)), lane);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(positions + count),
                            _mm256_maskz_compress_epi32(left, at));
        count += std::size_t(__builtin_popcount(unsigned(left)));
      }
    }
  } else if constexpr (is_avx2<Arch>) {
    // Four pairs at a time, compressed by a permutation of the register's
    // 32-bit halves looked up from the four lanes' mask (AVX2 has no
    // compress) and stored whole. (Measured on the pw85 family in single
    // precision, where about four fifths of the lanes are left: the loop
    // below alone took a quarter of the kernels' time.)
    if (in.stride[0] == 1 && in.stride[1] == 1 && in.stride[2] == 1) {
      for (; i + 4 <= n; i += 4) {
        std::uint32_t bytes;
        std::memcpy(&bytes, status + i, sizeof bytes);
        // (Of the statuses, only needs_fallback, 0xFF, has its top bit set.)
        const unsigned left = unsigned(_mm_movemask_epi8(_mm_cvtsi32_si128(int(bytes)))) & 0xFu;
        if (left == 0) continue;
        for (int k = 0; k < pair_components; ++k) {
          const In* column = component(in, k) + i;
          __m256d values;
          if constexpr (std::is_same<In, double>::value)
            values = _mm256_loadu_pd(column);
          else
            values = _mm256_cvtps_pd(_mm_loadu_ps(column));
          _mm256_storeu_pd(columns[k] + count, compress_four_doubles(values, left));
        }
        const __m128i at = _mm_add_epi32(_mm_set1_epi32(int(i)), _mm_setr_epi32(0, 1, 2, 3));
        _mm_storeu_si128(
            reinterpret_cast<__m128i*>(positions + count),
            _mm_castps_si128(_mm_permutevar_ps(
                _mm_castsi128_ps(at),
                _mm_load_si128(reinterpret_cast<const __m128i*>(compress_four.lanes[left])))));
        count += std::size_t(__builtin_popcount(left));
      }
    }
  }
  for (; i < n; ++i) {
    if (status[i] != needs_fallback) continue;
    for (int k = 0; k < pair_components; ++k) columns[k][count] = double(element(in, k, i));
    positions[count++] = std::uint32_t(i);
  }
  PairSpan<double> span{};
  for (int k = 0; k < pair_components; ++k) {
    const double* column = columns[k];
    if (k < 3)
      span.r12[k] = column;
    else if (k < 9)
      span.q1[k - 3] = column;
    else
      span.q2[k - 9] = column;
  }
  return span;
}

// Overlap only: the cheap first pass in arithmetic Cheap, then the accurate
// solve in arithmetic T on the pairs it left, gathered (in double: float
// pairs are exact in it, and T narrows them again on loading).
template <class Arch, class Cheap, class T, class In>
void solve_overlap_in_two_passes(const PairSpan<In>& in, const OverlapSpan& out, std::size_t n,
                                 const ChunkSettings& settings, const Scratch& scratch,
                                 ChunkCounters& counters) {
  {
    OverlapKept<Cheap> unused(scratch);  // the first pass keeps nothing
    for_each_block<Arch, OverlapBlock<Arch, Cheap>::size>(
        in, n,
        [&](const PairSpan<In>& span, std::size_t from, std::size_t position, std::size_t real) {
          overlap_prefilter_block<Arch, Cheap, In>(span, from, position, real, out, settings,
                                                   counters, unused);
        },
        prefilter_prefetch_blocks);
  }
  std::uint32_t* positions = nullptr;
  std::size_t count = 0;
  const PairSpan<double> rest =
      gather_undecided<Arch>(in, n, out.status, scratch, positions, count);
  OverlapKept<T> kept(scratch);
  solve_overlap_on<Arch, T, double>(rest, positions, count, out, settings, kept, counters);
}

template <class Arch, class T, class In>
void solve_overlap(const PairSpan<In>& in, const OverlapSpan& out, std::size_t n,
                   const ChunkSettings& settings, const Scratch& scratch, ChunkCounters& counters) {
  solve_overlap_in_two_passes<Arch, T, T, In>(in, out, n, settings, scratch, counters);
}

// Mixed and single precision (double pairs, or float pairs): the cheap pass
// in float lanes (twice as many per register, with float margins), and the
// accurate solve of the pairs it leaves in double lanes, on the pairs
// widened exactly (float pairs). For overlap answers the two precisions are
// one kernel: float lanes cannot certify elongated pairs (their margins grow
// with the element growth: 41 % of the pw85 family's lanes ended in the
// reference path), and a float accurate solve measured slower than a double
// one on the pairs the cheap pass leaves, on both families (1M scene pairs:
// 11.4 against 10.8 ms; the pw85 family: 23.1 ms with its leftovers finished
// in double, against 16.4 ms).
template <class Arch, class In>
void solve_overlap_float_first(const PairSpan<In>& in, const OverlapSpan& out, std::size_t n,
                               const ChunkSettings& settings, const Scratch& scratch,
                               ChunkCounters& counters) {
  solve_overlap_in_two_passes<Arch, float, double, In>(in, out, n, settings, scratch, counters);
}

}  // namespace pwcontact::kernels::PWCONTACT_TARGET
