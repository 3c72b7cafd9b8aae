// The full-answer batch kernel: mu^2 (and lambda, the contact point, the
// normal, the gradient on demand) of many pairs at once, one pair per SIMD
// lane, with safeguarded Newton iterations.
//
// This body is written once and compiled once per instruction set, each time
// in its own translation unit with its own flags (contact_sse2.cpp, ...),
// inside that target's namespace (target.hpp), so that the copies compiled
// with different flags are distinct symbols and none can replace another at
// link time; the test kernels.targets_share_no_definitions checks the
// objects.
//
// A chunk is solved in passes. The first pass loads every pair, checks it,
// nondimensionalises it, takes the initial guess and runs a few evaluations;
// the last one of a pass decides, lane by lane, whether the lane is finished
// (its convergence check). Lanes that are not are kept, packed into full
// registers, and continue in the next pass (automatic iterations), or go to
// the reference path (fixed iterations). Lanes step together and diverge
// only through select. Equation numbers refer to doc/theory.md.
#pragma once

#include "kernels/target.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "kernels/kernel_api.hpp"
#include "kernels/lane_blocks.hpp"
#include "kernels/simd_math.hpp"

namespace pwcontact::kernels::PWCONTACT_TARGET {

// Evaluations of the first pass in automatic mode, by measurement on the
// random family: after 3 (double) or 2 (float) the convergence check passes
// for 96-98 % of the lanes, and the rest continue, packed, one evaluation per
// pass (a longer first pass wastes evaluations on most lanes, a shorter one
// packs most lanes: both measured slower). When lambda or a geometric output
// is asked for, the check is stricter (see KernelTolerance) and one more
// evaluation gets back there. On elongated shapes (the pw85 family) about
// half the lanes continue, which is what makes automatic iterations 5x
// faster there than a fixed count with the scalar fallback.
template <class T>
PWCONTACT_INLINE int first_pass_evaluations(const ChunkSettings& settings) {
  const int plain = std::is_same<T, double>::value ? 3 : 2;
  return settings.outputs != 0 ? plain + 1 : plain;
}

// Steps on the polynomial form (eq. 46) that take the place of the
// factorised steps of a cold first pass in automatic mode, in double at
// standard accuracy, Newton in lambda: as many as that pass takes before its
// last evaluation, so that the lanes reach the same convergence check, each
// counted as an evaluation; 0 elsewhere. A lane whose last step still moved
// lambda by more than polynomial_settled of its distance to 0 or 1 (Newton is
// then not yet in its quadratic phase: elongated shapes) takes up to
// polynomial_extra_steps more. Measured (1M random pairs and the pw85
// family, lambda asked for, 1 thread, from memory): 25.6-25.9 against
// 27.0-27.2 ms, and 12.7-13.2 against 18.4-18.6 ms. Warm starts keep the
// factorised step: from a good lambda the coefficients cost more than the
// evaluation they save (random pairs from lambda* (1 +- 1e-6): 23.4 against
// 19.2 ms).
inline constexpr int polynomial_extra_steps = 6;
inline constexpr double polynomial_settled = 1e-3;

// Where either form is elongated (tr^3 / det above polynomial_elongated,
// a bound on its condition number: needles of aspect ratio beyond ~5.5,
// discs beyond ~11; random pairs with semi-axes in [0.5, 2] stay below
// 364), the radial guess can lie far from lambda*, near the end of [0, 1]
// where f' has a near pole, and Newton then takes many steps. The steps
// start instead from whichever of the radial guess and these lambdas has
// the largest f on the polynomial form: f is concave, so each start lies in
// the interval about lambda* where f exceeds f(start), and the largest f
// has the shortest. Measured on the pw85 family (one call, 1 thread):
// 5.21 -> 4.57 evaluations a pair (a scalar model of the steps: 4.14 ->
// 3.54 steps, and 5.1 % -> 1.0 % of the lanes still more than 2^-20 of
// their width from lambda* after them, each a later pass); more fixed
// starts saved more steps but cost more than they saved.
inline constexpr double polynomial_elongated = 1e3;
inline constexpr double polynomial_starts[] = {0.05, 0.95};

template <class T, class In>
PWCONTACT_INLINE int polynomial_steps(const ChunkSettings& settings, bool cold_automatic) {
  if constexpr (!std::is_same<T, double>::value || !std::is_same<In, double>::value) {
    return 0;
  } else {
    const bool applies = cold_automatic && settings.accuracy == Accuracy::standard &&
                         settings.formulation != Formulation::log_odds;
    return applies ? first_pass_evaluations<T>(settings) - 1 : 0;
  }
}

// A mixed-precision solve: float steps from the radial guess in automatic
// mode, then double evaluations (a Newton step from the float lambda and the
// evaluation that checks it). Three float steps, by measurement on the
// random family (1M pairs, one thread): after two, 10 % of the lanes fail the
// double check and need more passes (35.8 ms); after three, 0.1 % (32.0 ms).
inline constexpr int mixed_float_steps = 3;
inline constexpr int mixed_double_evaluations = 1;

// lambda for coincident centres, where every lambda is a maximiser (f = 0):
// the one that is exact for spheres in the limit of small r, from the traces
// (as the reference path).
template <class B>
PWCONTACT_INLINE B trace_lambda(const PairLanes<B>& p) {
  const B t1 = xsimd::sqrt(p.q1[0] + p.q1[3] + p.q1[5]);
  const B t2 = xsimd::sqrt(p.q2[0] + p.q2[3] + p.q2[5]);
  return t1 / (t1 + t2);
}

// What the geometric outputs need of a group: s = Q^-1 r at the reported
// lambda (0 for coincident centres), Q1, lambda and the scale factor t.
template <class B>
struct GeometryLanes {
  B s[3];
  B q1[6];
  B lambda;
  B scale;
};

// The contact point, normal and gradient asked for (Outputs).
template <unsigned Outputs, class Arch, class T, class Out>
PWCONTACT_INLINE void write_geometry(const ResultSpan<Out>& out, const LanePositions& at,
                                     const GeometryLanes<xsimd::batch<T, Arch>>& g) {
  using B = xsimd::batch<T, Arch>;
  const B mu = B(1) - g.lambda;
  // The pair was scaled by t (r -> t r, Q -> t^2 Q), so Q^-1 r in the
  // caller's units is t s, and (1 - lambda) Q1 Q^-1 r is (1 - lambda) Q1 s / t.
  if constexpr ((Outputs & with_contact_point) != 0) {
    B x[3];
    symmetric_times(g.q1, g.s, x);
    const B factor = mu / g.scale;
    for (int k = 0; k < 3; ++k) write_lanes<Arch, T, Out>(out.contact_point[k], at, factor * x[k]);
  }
  if constexpr ((Outputs & with_normal) != 0) {
    // Coincident centres have no normal: 0 there.
    const B norm = xsimd::sqrt(dot3(g.s, g.s));
    const B inverse = xsimd::select(norm > B(0), B(1) / norm, B(0));
    for (int k = 0; k < 3; ++k) write_lanes<Arch, T, Out>(out.normal[k], at, g.s[k] * inverse);
  }
  if constexpr ((Outputs & with_gradient) != 0) {
    const B factor = B(2) * g.lambda * mu * g.scale;
    for (int k = 0; k < 3; ++k) write_lanes<Arch, T, Out>(out.gradient[k], at, factor * g.s[k]);
  }
}

// Selects the specialisation for the outputs asked for; out of line and fed
// copies, so that asking for none costs the hot path nothing.
template <class Arch, class T, class Out>
__attribute__((noinline)) void write_geometry(const ResultSpan<Out> out, const LanePositions at,
                                              const GeometryLanes<xsimd::batch<T, Arch>> g,
                                              unsigned outputs) {
  switch (outputs & geometry_outputs) {
// clang-format off
#define PWCONTACT_GEOMETRY_CASE(bits) \
  case bits: write_geometry<bits, Arch, T, Out>(out, at, g); break;
    PWCONTACT_GEOMETRY_CASE(2) PWCONTACT_GEOMETRY_CASE(4) PWCONTACT_GEOMETRY_CASE(6)
    PWCONTACT_GEOMETRY_CASE(8) PWCONTACT_GEOMETRY_CASE(10) PWCONTACT_GEOMETRY_CASE(12)
    PWCONTACT_GEOMETRY_CASE(14)
#undef PWCONTACT_GEOMETRY_CASE
    // clang-format on
  }
}

// What a full-answer lane keeps between passes besides its pair: its slots
// in the kept arrays, after the pair's components.
enum FullSlot : int {
  full_scale = pair_components,  // the power of two the pair was scaled by
  full_lambda,
  full_lo,  // the bracket of the maximiser
  full_hi,
  full_slots_end
};
inline constexpr int full_state = full_slots_end - pair_components;
template <class T>
using FullKept = KeptLanes<T, full_state>;

// How a pass hands over the lanes it did not finish.
enum class Handoff {
  none,      // leave them to the reference path (status needs_fallback)
  adaptive,  // registers with many: append them to the kept lanes; with a
             // few: write their lambda and bracket at their chunk position
             // for pack_unfinished() (first passes)
  packed,    // append them to the kept lanes (later passes)
};

// lambda and the bracket of a chunk's lanes, by chunk position.
template <class T>
struct StateByPosition {
  T* lambda = nullptr;
  T* lo = nullptr;
  T* hi = nullptr;
};

// Packs the lanes the first pass left unfinished (status needs_fallback,
// lambda not NaN) into the kept lanes: the pair, nondimensionalised in its
// own type before any narrowing (as load_pairs does), the scale and the state.
template <class Arch, class T, class In>
void pack_unfinished(const PairSpan<In>& in, std::size_t n, const Status* status,
                     const StateByPosition<T>& state, FullKept<T>& kept) {
  // The lanes are found with memchr: on random pairs, where the first pass
  // finishes all but ~0.1 % of the lanes, the byte-by-byte scan it replaces
  // cost ~2.5 % of a cold solve and ~4 % of a warm-started one (1M pairs
  // solved from cache 2,048 at a time, one thread).
  static_assert(sizeof(Status) == 1, "statuses are searched for as bytes");
  const unsigned char* const first = reinterpret_cast<const unsigned char*>(status);
  const unsigned char* const end = first + n;
  for (const unsigned char* at = first; at < end; ++at) {
    at = static_cast<const unsigned char*>(
        __builtin_memchr(at, int(std::uint8_t(needs_fallback)), std::size_t(end - at)));
    if (at == nullptr) break;
    const std::size_t i = std::size_t(at - first);
    if (!(state.lambda[i] == state.lambda[i])) continue;
    In v[pair_components];
    for (int k = 0; k < pair_components; ++k) v[k] = element(in, k, i);
    static constexpr int diagonals[6] = {3, 6, 8, 9, 12, 14};
    In largest = v[3];
    for (int k : diagonals) largest = v[k] > largest ? v[k] : largest;
    In t = 1;
    // (As load_pairs: always when narrowing, else only out of the safe range.)
    const bool narrowing = !std::is_same<T, In>::value;
    // (The scalar copy of nondimensionalise, lane_blocks.hpp: the same t.)
    if ((narrowing || !(largest >= In(KernelTolerance<T>::safe_scale_low) &&
                        largest <= In(KernelTolerance<T>::safe_scale_high))) &&
        largest > 0 && largest < std::numeric_limits<In>::infinity()) {
      // sqrt = m 2^e with m in [1/2, 1): the power of two below is 2^(e - 1).
      // (Builtins, not std:: overloads: no inline library code in this file.)
      int e = 0;
      __builtin_frexp(__builtin_sqrt(double(largest)), &e);
      t = In(__builtin_ldexp(1.0, 1 - e));
    }
    const std::size_t c = kept.count++;
    for (int k = 0; k < pair_components; ++k) kept.values[k][c] = T(v[k] * (k < 3 ? t : t * t));
    kept.values[full_scale][c] = T(t);
    kept.values[full_lambda][c] = state.lambda[i];
    kept.values[full_lo][c] = state.lo[i];
    kept.values[full_hi][c] = state.hi[i];
    kept.index[c] = std::uint32_t(i);
  }
}

// The convergence test of a lane after evaluation e, a pure function of the
// evaluation, the bracket [lo, hi] and whether the safeguarded step stayed in
// it (doc/theory.md eqs. 23-26 for the corrected answer f + gain, eq. 28 for
// the bound):
// Near the maximum f is a parabola in lambda, and
// one more Newton step would raise f by the gain g^2 / (2 g'). A lane is
// finished when that step stayed in the bracket (the model holds), the
// gain is below corrected_gain f, and the model's own error, the
// third-order term ~gain |step| / w with w = min(lambda, 1 - lambda)
// (see KernelTolerance::third_order), is below an eps of f: the answer
// is then f + gain. Without the third-order test a lane with lambda*
// near 0 or 1 (very different sizes) would stop where the step is a
// sizeable fraction of w and the gain's error hundreds of eps.
// The model is trusted only for a step below model_step w (the expansion
// is a series in step / w): a negligible gain at a step as long as w says
// nothing about how far lambda* lies.
// When lambda or what depends on it is asked for, the step must also
// be below lambda_step w: lambda itself (the Newton step's) is then
// accurate to ~1e-12 w (a small gain alone does not make it so where f
// is flat: crossed needles and discs, whose g' is tiny).
// Otherwise (a bisection step, round-off noise in g near convergence)
// the rigorous concavity bound mu^2 - f <= |g| (hi - lo) below a few
// ulp of f finishes it, with the answer f (and, when lambda is asked
// for, the same bound on the step).
// The model is Newton's whatever the formulation. Its step is g / g'
// as divided, never the difference of lambda before and after the step
// taken: where lambda* lies within a few thousand ulps of 0 or 1, a
// step below half an ulp of lambda rounds to no step at all, and a
// rounded-away step would pass every test above with a gain of 0 (was:
// started at 1 - 1e-16 beside lambda* = 1 - 1e-12, mu^2 1e-8 low with
// status ok). Such a lane cannot move; it goes on to the reference path,
// which seeks a maximiser near 1 on the mirrored pair.
template <class B>
struct Convergence {
  typename B::batch_bool_type corrected;  // finished, with the answer f + gain
  typename B::batch_bool_type bounded;    // finished by the bound, with the answer f
  B gain;                                 // g^2 / (2 g') (eq. 23)
  B newton_lambda;                        // lambda - g / g', as divided
};

template <class T, class B>
PWCONTACT_INLINE Convergence<B> convergence_test(
    const Evaluation<B>& e, const B& lo, const B& hi,
    const typename B::batch_bool_type& newton_in_bracket, bool newton_formulation,
    bool lambda_asked, const B& gain_tolerance) {
  using M = typename B::batch_bool_type;
  const B step = e.g / e.dg;
  const B newton_lambda = e.lambda - step;
  const M in_bracket =
      newton_formulation ? newton_in_bracket : (lo <= newton_lambda) & (newton_lambda <= hi);
  const B gain = B(0.5) * e.g * step;
  const B width = xsimd::min(e.lambda, e.mu);
  const B abs_step = xsimd::abs(step);
  M small_step = B(0) == B(0);
  if (lambda_asked) small_step = abs_step <= B(KernelTolerance<T>::lambda_step) * width;
  const M corrected = in_bracket & (e.dg > B(0)) & (gain <= gain_tolerance * e.f) &
                      (abs_step <= B(KernelTolerance<T>::model_step) * width) &
                      (gain * abs_step <= B(KernelTolerance<T>::third_order) * width * e.f) &
                      small_step;
  const M bounded =
      (xsimd::abs(e.g) * (hi - lo) <= B(KernelTolerance<T>::bounded_gain) * e.f) & small_step;
  return {corrected, bounded, gain, newton_lambda};
}

// Whether a first pass starts from the caller's lambda (T lanes on T pairs
// only: float lanes on double pairs take the radial guess).
template <class T, class In>
PWCONTACT_INLINE bool warm_start(const PairSpan<In>& in) {
  return std::is_same<T, In>::value && in.lambda_start != nullptr;
}

// A block of U groups of lanes, solved for the full answer.
template <class Arch, class T>
class FullBlock : public LaneGroups<Arch, T> {
  using Base = LaneGroups<Arch, T>;
  using Base::at_, Base::pair_, Base::scale_, Base::lambda_, Base::lo_, Base::hi_, Base::live_,
      Base::settings_;

 public:
  using Base::size, Base::U, Base::W;
  using typename Base::B;
  using typename Base::M;

  FullBlock(const ChunkSettings& settings, ChunkCounters& counters, FullKept<T>& kept)
      : Base(settings, counters),
        kept_(kept),
        gain_tolerance_(settings.accuracy == Accuracy::high
                            ? KernelTolerance<T>::corrected_gain_high
                        : settings.outputs != 0 ? KernelTolerance<T>::corrected_gain_with_lambda
                                                : KernelTolerance<T>::corrected_gain) {}

  // A first pass's block, loaded from position `from` of `in` and answered at
  // position `position` of the chunk (they differ for a padded tail), `real`
  // pairs in it: checks, nondimensionalises, and starts from the radial guess.
  template <class In>
  PWCONTACT_INLINE void start(const PairSpan<In>& in, std::size_t from, std::size_t position,
                              std::size_t real) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, nullptr, real, u);
      const PairLanes<B>& p = pair_[u];
      const Ldlt<B> f1 = factor(p.q1), f2 = factor(p.q2);
      const B s1 = inverse_quadratic_form(f1, p.r), s2 = inverse_quadratic_form(f2, p.r);
      // A warm start (a previous solve's lambda) where one is given
      // (first_guess; the radial guess's square roots and division measured
      // ~3 % of a warm-started solve). The checks are the cold start's
      // whichever: those of the mixed-precision double block (the entries'
      // range, without the slopes) let lanes of forms with entries near
      // 1e-300 through to answers 30 % wrong.
      lambda_[u] = interior_or_midpoint(first_guess(in, from + std::size_t(u) * W, s1, s2));
      lo_[u] = B(0);
      hi_[u] = B(1);
      // Coincident centres: mu^2 = 0.
      const M coincident = (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
      live_[u] = this->usable(u) & factorised_checks(p, f1, f2, s1, s2, coincident);
      coincident_[u] = live_[u] & coincident;
      lambda_coincident_[u] = xsimd::any(coincident_[u]) ? trace_lambda(pair_[u]) : B(0);
    }
  }

  // A cold first pass's block in double (polynomial_steps): the checks from
  // adjugates (start_from's), and for a register with a lane they refuse
  // start's factorised ones too (a lane either takes is taken: every lane
  // start takes), then `steps` safeguarded Newton steps on the polynomial
  // form (eq. 46) from the radial guess, and up to polynomial_extra_steps
  // more for a lane whose last step was not yet negligible. The bracket they narrow is not kept:
  // their signs are not the factorised evaluation's, and the convergence
  // test's bound needs a bracket that surely holds lambda*.
  template <class In>
  PWCONTACT_INLINE void start_polynomial(const PairSpan<In>& in, std::size_t from,
                                         std::size_t position, std::size_t real, int steps) {
    ContactPolynomials<B> polynomials[U];
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, nullptr, real, u);
      const PairLanes<B>& p = pair_[u];
      const Adjugate<B> a1(p.q1), a2(p.q2);
      const M coincident = (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
      const M usable = this->usable(u);
      M live = usable & adjugate_checks(p, a1, a2, coincident);
      if (xsimd::any(usable & !live)) {
        const Ldlt<B> f1 = factor(p.q1), f2 = factor(p.q2);
        const B s1 = inverse_quadratic_form(f1, p.r), s2 = inverse_quadratic_form(f2, p.r);
        live = live | (usable & factorised_checks(p, f1, f2, s1, s2, coincident));
      }
      polynomials[u] = ContactPolynomials<B>(p.r, p.q1, p.q2, a1, a2);
      lambda_[u] = interior_or_midpoint(polynomials[u].radial_guess());
      // An elongated form (tr^3 / det beyond polynomial_elongated, a bound
      // on its condition number): the start is whichever of the radial guess
      // and a few fixed lambdas has the largest f (see polynomial_starts).
      const B t1 = p.q1[0] + p.q1[3] + p.q1[5], t2 = p.q2[0] + p.q2[3] + p.q2[5];
      const B elongated_beyond(polynomial_elongated);
      const M elongated =
          (t1 * t1 * t1 > elongated_beyond * a1.det) | (t2 * t2 * t2 > elongated_beyond * a2.det);
      if (xsimd::any(elongated & live))
        lambda_[u] = xsimd::select(
            elongated, polynomials[u].largest_of(lambda_[u], polynomial_starts), lambda_[u]);
      lo_[u] = B(0);
      hi_[u] = B(1);
      live_[u] = live;
      coincident_[u] = live & coincident;
      lambda_coincident_[u] = xsimd::any(coincident_[u]) ? trace_lambda(pair_[u]) : B(0);
    }
    B moved[U];
    for (int it = 0; it < steps; ++it) {
      PWCONTACT_UNROLL for (int u = 0; u < U; ++u) moved[u] =
          polynomials[u].step(lambda_[u], lo_[u], hi_[u]);
    }
    this->count_evaluations(steps);
    // Lane by lane (a lane's answer must not depend on its neighbours in
    // the register: the same bits whatever the batch's partition); the
    // groups with a lane still going step side by side, so that their
    // chains of dependent arithmetic (a division in each) overlap (one group
    // after another, each step waited for the last).
    for (int it = 0; it < polynomial_extra_steps; ++it) {
      bool stepped = false;
      PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
        const B width = xsimd::min(lambda_[u], B(1) - lambda_[u]);
        const M going = (moved[u] > B(polynomial_settled) * width) & live_[u];
        if (!xsimd::any(going)) continue;
        stepped = true;
        B lambda = lambda_[u], lo = lo_[u], hi = hi_[u];
        const B step = polynomials[u].step(lambda, lo, hi);
        lambda_[u] = xsimd::select(going, lambda, lambda_[u]);
        lo_[u] = xsimd::select(going, lo, lo_[u]);
        hi_[u] = xsimd::select(going, hi, hi_[u]);
        moved[u] = xsimd::select(going, step, B(0));
        this->counters_.lane_evaluations += count_lanes<Arch, T>(going);
      }
      if (!stepped) break;
    }
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      // (NaN from a lane whose coefficients overflowed: the midpoint.)
      lambda_[u] = interior_or_midpoint(lambda_[u]);
      lo_[u] = B(0);
      hi_[u] = B(1);
    }
  }

  // The float block of a mixed-precision solve: only the initial guess and
  // the bracket; the double block that follows makes the checks.
  template <class In>
  PWCONTACT_INLINE void start_guess(const PairSpan<In>& in, std::size_t from, std::size_t position,
                                    std::size_t real) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, nullptr, real, u);
      lambda_[u] = initial_guess(pair_[u]);
      lo_[u] = B(0);
      hi_[u] = B(1);
      live_[u] = this->real_lanes(u);
      coincident_[u] = B(0) != B(0);
      lambda_coincident_[u] = B(0);
    }
  }

  // The double block of a mixed-precision solve: starts from the lambda the
  // float lanes reached (lambda_start, one per lane of the block; NaN where
  // they failed), with the bracket [0, 1]. It takes only lanes that the cold
  // start would take: the entries' range (in_range) does not bound the
  // forms' smallest eigenvalues, the slopes do (was, found by kernels_fuzz:
  // both forms flat to ~1e-307 along r12, mu^2 only: f overflowed, mu2 = inf
  // with status ok). The slopes are not computed: a sufficient condition
  // from traces and determinants decides (slopes_surely_in_range), and the
  // few lanes it refuses (forms conditioned beyond ~1e12, sizes or distances
  // beyond 2^60 of each other) go to the reference path. (Measured on random
  // pairs: that test costs 3 %; computing the slopes for the lanes it
  // refuses, even where there are none, another 3-4 %, computing them always
  // 7 %.)
  PWCONTACT_INLINE void start_from(const PairSpan<T>& in, std::size_t from, std::size_t position,
                                   std::size_t real, const T* lambda_start) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      this->load(in, from, position, nullptr, real, u);
      const PairLanes<B>& p = pair_[u];
      const B start = B::load_unaligned(lambda_start + std::size_t(u) * W);
      lambda_[u] = interior_or_midpoint(start);
      lo_[u] = B(0);
      hi_[u] = B(1);
      const Adjugate<B> a1(p.q1), a2(p.q2);
      const M coincident = (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
      live_[u] = this->usable(u) & adjugate_checks(p, a1, a2, coincident);
      coincident_[u] = live_[u] & coincident;
      lambda_coincident_[u] = xsimd::any(coincident_[u]) ? trace_lambda(pair_[u]) : B(0);
    }
  }

  // A later pass's block: the kept lanes from position j on (count in all).
  PWCONTACT_INLINE void resume(std::size_t j, std::size_t count) {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      const std::size_t at = j + std::size_t(u) * W;
      for (int k = 0; k < pair_components; ++k)
        component(pair_[u], k) = B::load_unaligned(kept_.values[k] + at);
      scale_[u] = B::load_unaligned(kept_.values[full_scale] + at);
      lambda_[u] = B::load_unaligned(kept_.values[full_lambda] + at);
      lo_[u] = B::load_unaligned(kept_.values[full_lo] + at);
      hi_[u] = B::load_unaligned(kept_.values[full_hi] + at);
      at_[u] = {0, kept_.index + at, at < count ? (count - at < W ? count - at : W) : 0};
      live_[u] = this->real_lanes(u);
      coincident_[u] = B(0) != B(0);
      lambda_coincident_[u] = B(0);
    }
  }

  // Safeguarded steps, each one evaluation; a pass is some steps and finish().
  PWCONTACT_INLINE void iterate(int steps) {
    for (int it = 0; it < steps; ++it) {
      PWCONTACT_UNROLL for (int u = 0; u < U; ++u) this->advance(evaluate(pair_[u], lambda_[u]), u);
    }
    this->count_evaluations(steps);
  }

  // The lambda the lanes reached, one per lane of the block, NaN where a
  // lane is not live (the float part of a mixed-precision solve).
  PWCONTACT_INLINE void store_lambda(double* target) const {
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      const B lambda = xsimd::select(live_[u] & !coincident_[u], lambda_[u],
                                     B(std::numeric_limits<T>::quiet_NaN()));
      write_lanes<Arch, T, double>(target, {std::size_t(u) * W, nullptr, W}, lambda);
    }
  }

  // The last evaluation of a pass: decides which lanes are finished, writes
  // their answers, and hands the others over (see Handoff).
  template <class Out>
  PWCONTACT_INLINE void finish(const ResultSpan<Out>& out, Handoff handoff,
                               const StateByPosition<T>& state = {}) {
    this->count_evaluations(1);
    PWCONTACT_UNROLL for (int u = 0; u < U; ++u) {
      Evaluation<B> e = evaluate(pair_[u], lambda_[u]);
      // Accuracy::high: f, s and g refined before the step and the test read g.
      Refined<B> answer{e.f, {e.s[0], e.s[1], e.s[2]}, e.g};
      if (settings_.accuracy == Accuracy::high) {
        answer = refined_f(pair_[u], e.ldlt, e.lambda, e.mu, answer);
        e.g = answer.g;
      }
      const M newton = this->advance(e, u);
      const Convergence<B> test = convergence_test<T>(e, lo_[u], hi_[u], newton,
                                                      settings_.formulation == Formulation::newton,
                                                      settings_.outputs != 0, gain_tolerance_);
      const M corrected = test.corrected;
      const B gain = test.gain, newton_lambda = test.newton_lambda;
      M done = test.corrected | test.bounded;
      // A float lane too ill-conditioned for float goes to the reference path
      // (in double) now: more float iterations would not help it.
      M hopeless = B(0) != B(0);
      if constexpr (KernelTolerance<T>::checks_growth) {
        hopeless = growth(e.ldlt, e.q) > B(KernelTolerance<T>::max_growth);
        done = done & !hopeless;
      }
      // Accuracy::high with lambda* near 0 or 1: f is flat there and the
      // unrefined g that decides convergence is mostly noise; such a lane
      // goes to the reference path in long double now.
      if (settings_.accuracy == Accuracy::high) {
        const M near_end = xsimd::min(e.lambda, e.mu) < B(KernelTolerance<T>::high_width);
        hopeless = hopeless | near_end;
        done = done & !near_end;
      }

      answer.f = xsimd::select(corrected, answer.f + gain, answer.f);
      // A valid answer is a normal number of T (f > 0 inside (0, 1) for
      // distinct centres, and finite as every quantity of a lane in range;
      // but mu^2 itself is not bounded by the lane's range: two discs thin
      // along r12's directions have mu^2 ~ 1e-38 with slopes ~1, found by
      // kernels_fuzz in float): anything else the arithmetic produced
      // (lambda rounded onto 0 or 1, where f = 0; a subnormal mu^2, which is
      // out_of_range) goes to the reference path, whatever the tests above
      // said. (f is mu^2: the scaling by t leaves it unchanged.)
      const M usable_answer = (answer.f >= B(std::numeric_limits<T>::min())) &
                              (answer.f <= B(std::numeric_limits<T>::max()));
      const M finished = live_[u] & ((done & usable_answer) | coincident_[u]);
      write_lanes<Arch, T, Out>(out.mu2, at_[u], xsimd::select(coincident_[u], B(0), answer.f));
      // The reported lambda is the Newton step's, kept in the bracket: for a
      // lane finished by the bound the step may leave the bracket by
      // round-off, and the bracket's end is then the better estimate. (Lanes
      // in range have lambda* at least ~2^-60 from 0 and 1, ~2^-15 in float.)
      const B reported = xsimd::select(coincident_[u], lambda_coincident_[u],
                                       xsimd::min(xsimd::max(newton_lambda, lo_[u]), hi_[u]));
      write_answer(out, u, e, answer.s, reported);
      write_statuses<Arch, T>(out.status, at_[u], finished);

      // (A lane done whose answer is not usable is neither: the reference path.)
      hand_over(u, live_[u] & !done & !coincident_[u] & !hopeless, handoff, state);
    }
  }

 private:
  // A first lambda strictly inside (0, 1), the midpoint otherwise (NaN, or
  // a guess rounded onto an end).
  PWCONTACT_INLINE static B interior_or_midpoint(const B& lambda) {
    return xsimd::select((lambda > B(0)) & (lambda < B(1)), lambda, B(0.5));
  }

  // The cold start's checks of a lane (beside usable()), from the
  // factorisations and the slopes s_i = r^T Qi^-1 r.
  PWCONTACT_INLINE static M factorised_checks(const PairLanes<B>& p, const Ldlt<B>& f1,
                                              const Ldlt<B>& f2, const B& s1, const B& s2,
                                              const M& coincident) {
    return positive_definite(f1, p.q1) & positive_definite(f2, p.q2) &
           (coincident | slopes_in_range(s1, s2));
  }

  // A sufficient form of them from adjugates and determinants (double lanes):
  // the entries' range, definiteness, and slopes_surely_in_range.
  PWCONTACT_INLINE static M adjugate_checks(const PairLanes<B>& p, const Adjugate<B>& a1,
                                            const Adjugate<B>& a2, const M& coincident) {
    return in_range<T>(p) & a1.positive_definite(p.q1) & a2.positive_definite(p.q2) &
           (coincident | slopes_surely_in_range(p, a1.det, a2.det));
  }

  // Initial guess exact for spheres: lambda = rho1 / (rho1 + rho2), rho_i the
  // distance from centre i to its surface along r12, from s_i = r^T Qi^-1 r
  // (f'(0) = s1, -f'(1) = s2; see the reference path):
  // lambda = 1 / (1 + sqrt(s1 / s2)). A guess needs no precision, so the s_i
  // come from adjugates and determinants (one division for both, instead of
  // six for two factorisations); where round-off spoils them (very elongated
  // shapes), the guess falls back to 1/2.
  PWCONTACT_INLINE static B initial_guess(const PairLanes<B>& p) {
    const Adjugate<B> adj1(p.q1), adj2(p.q2);
    const B ratio = (adj1.form(p.r) * adj2.det) / (adj2.form(p.r) * adj1.det);
    const B guess = B(1) / (B(1) + xsimd::sqrt(ratio));
    return interior_or_midpoint(guess);
  }

  // The radial guess from s_i = r^T Qi^-1 r: exact for spheres (see
  // initial_guess).
  PWCONTACT_INLINE static B radial_guess(const B& s1, const B& s2) {
    const B w1 = xsimd::sqrt(s2), w2 = xsimd::sqrt(s1);
    return w1 / (w1 + w2);
  }

  // Where the lanes of pairs [at, at + W) start: the caller's lambda where one
  // is given (warm_start) and inside (0, 1), the radial guess elsewhere,
  // computed only when some lane needs it.
  template <class In>
  PWCONTACT_INLINE static B first_guess(const PairSpan<In>& in, std::size_t at, const B& s1,
                                        const B& s2) {
    if constexpr (std::is_same<T, In>::value) {
      if (warm_start<T>(in)) {
        const B given = B::load_unaligned(in.lambda_start + at);
        const M warm = (given > B(0)) & (given < B(1));
        return xsimd::all(warm) ? given : xsimd::select(warm, given, radial_guess(s1, s2));
      }
    }
    return radial_guess(s1, s2);
  }

  // Hands over the lanes of group u that are not finished (`unfinished`):
  // kept for the next pass, left by chunk position for pack_unfinished, or
  // left to the reference path, as `handoff` says.
  PWCONTACT_INLINE void hand_over(int u, const M& unfinished, Handoff handoff,
                                  const StateByPosition<T>& state) {
    if (handoff == Handoff::adaptive && xsimd::any(unfinished)) {
      // A register with many unfinished lanes is packed right away (one
      // masked compress per array); one with a few leaves them by position,
      // to be packed lane by lane (pack_unfinished), which is cheaper for a
      // few and costlier for many (measured: random pairs, with a few per
      // register, and the pw85 family, with half, each gain ~10 %).
      const bool many = count_lanes<Arch, T>(unfinished) * 4 > W;
      if (many) keep_registers(u, unfinished);
      const B nan(std::numeric_limits<T>::quiet_NaN());
      write_lanes<Arch, T, T>(state.lambda, at_[u],
                              many ? nan : xsimd::select(unfinished, lambda_[u], nan));
      write_lanes<Arch, T, T>(state.lo, at_[u], lo_[u]);
      write_lanes<Arch, T, T>(state.hi, at_[u], hi_[u]);
    } else if (handoff == Handoff::adaptive) {
      write_lanes<Arch, T, T>(state.lambda, at_[u], B(std::numeric_limits<T>::quiet_NaN()));
    } else if (handoff == Handoff::packed) {
      keep_registers(u, unfinished);
    }
  }

  // Appends the lanes of group u selected by `which` to the kept lanes.
  PWCONTACT_INLINE void keep_registers(int u, const M& which) {
    B values[FullKept<T>::arrays];
    for (int k = 0; k < pair_components; ++k) values[k] = component(pair_[u], k);
    values[full_scale] = scale_[u];
    values[full_lambda] = lambda_[u];
    values[full_lo] = lo_[u];
    values[full_hi] = hi_[u];
    keep_lanes<Arch, T, full_state>(kept_, which, values, at_[u]);
  }

  // lambda, when asked for, and the geometric outputs, each only when asked
  // for: those are computed out of the hot path by a specialisation per
  // combination (write_geometry), from copies of the registers they need.
  template <class Out>
  PWCONTACT_INLINE void write_answer(const ResultSpan<Out>& out, int u, const Evaluation<B>& e,
                                     const B (&s_evaluated)[3], const B& lambda) {
    if (settings_.outputs & with_lambda) write_lanes<Arch, T, Out>(out.lambda, at_[u], lambda);
    if (settings_.outputs & geometry_outputs) {
      // s = Q^-1 r at the reported lambda, to first order in the step:
      // ds/dlambda = -Q^-1 (Q2 - Q1) s = -L^-T D^-1 (L^-1 b - L^-1 a).
      B dy[3], ds[3];
      for (int k = 0; k < 3; ++k) dy[k] = e.yb[k] - e.ya[k];
      backward(e.ldlt, dy, ds);
      const B step = lambda - e.lambda;
      GeometryLanes<B> g;
      for (int k = 0; k < 3; ++k)
        g.s[k] = xsimd::select(coincident_[u], B(0), s_evaluated[k] - step * ds[k]);
      for (int k = 0; k < 6; ++k) g.q1[k] = pair_[u].q1[k];
      g.lambda = lambda;
      g.scale = scale_[u];
      write_geometry<Arch, T, Out>(out, at_[u], g, settings_.outputs);
    }
  }

  FullKept<T>& kept_;
  const B gain_tolerance_;
  B lambda_coincident_[U];
  M coincident_[U];
};

// A block of the first pass: `first` evaluations from the radial guess.
// One function per kind of block, so that the block's code exists once and
// its state stays in registers (a block's steps inlined into each other).
template <class Arch, class T, class In, class Out>
__attribute__((noinline)) void first_pass_block(
    const PairSpan<In>& span, std::size_t from, std::size_t position, std::size_t real, int first,
    int polynomial, Handoff handoff, const StateByPosition<T>& state, const ResultSpan<Out>& out,
    const ChunkSettings& settings, ChunkCounters& counters, FullKept<T>& kept) {
  FullBlock<Arch, T> block(settings, counters, kept);
  if constexpr (std::is_same<T, double>::value) {
    if (polynomial > 0) {
      block.start_polynomial(span, from, position, real, polynomial);
      block.finish(out, handoff, state);
      return;
    }
  }
  block.start(span, from, position, real);
  block.iterate(first - 1);
  block.finish(out, handoff, state);
}

// A block of a mixed-precision solve: float lanes (twice as many per
// register) take the first steps from the radial guess, then the same pairs,
// reloaded from cache as two blocks of double lanes, take it from there with
// the double convergence check. One pass over memory.
template <class Arch>
__attribute__((noinline)) void mixed_block(const PairSpan<double>& span, std::size_t from,
                                           std::size_t position, std::size_t real, int float_steps,
                                           Handoff handoff, const StateByPosition<double>& state,
                                           const ResultSpan<double>& out,
                                           const ChunkSettings& settings, ChunkCounters& counters,
                                           FullKept<double>& kept, FullKept<float>& never_kept) {
  constexpr std::size_t half = FullBlock<Arch, double>::size;
  static_assert(FullBlock<Arch, float>::size == 2 * half);
  alignas(64) double lambda_start[2 * half];
  {
    FullBlock<Arch, float> lanes(settings, counters, never_kept);  // they only hand lambda over
    lanes.start_guess(span, from, position, real);
    lanes.iterate(float_steps);
    lanes.store_lambda(lambda_start);
  }
  for (std::size_t h = 0; h < 2 && h * half < real; ++h) {
    FullBlock<Arch, double> block(settings, counters, kept);
    block.start_from(span, from + h * half, position + h * half,
                     real - h * half < half ? real - h * half : half, lambda_start + h * half);
    block.iterate(mixed_double_evaluations - 1);
    block.finish(out, handoff, state);
  }
}

// A block of a later pass: kept lanes from position j (count in all).
template <class Arch, class T, class Out>
__attribute__((noinline)) void later_pass_block(std::size_t j, std::size_t count, bool keep,
                                                const ResultSpan<Out>& out,
                                                const ChunkSettings& settings,
                                                ChunkCounters& counters, FullKept<T>& kept) {
  FullBlock<Arch, T> block(settings, counters, kept);
  block.resume(j, count);
  block.finish(out, keep ? Handoff::packed : Handoff::none);
}

// The passes after the first, in automatic mode: the kept lanes, packed,
// one evaluation per pass, until none is left or the cap is reached.
template <class Arch, class T, class Out>
void later_passes(FullKept<T>& kept, const ResultSpan<Out>& out, int done,
                  const ChunkSettings& settings, ChunkCounters& counters) {
  constexpr std::size_t size = FullBlock<Arch, T>::size;
  while (kept.count > 0 && done < settings.max_iterations) {
    const std::size_t count = kept.count;
    kept.count = 0;  // packed in place: a block is read before anything is written over it
    ++done;
    for (std::size_t j = 0; j < count; j += size)
      later_pass_block<Arch, T, Out>(j, count, done < settings.max_iterations, out, settings,
                                     counters, kept);
  }
}

// lambda and the bracket by chunk position, in the scratch arrays after the
// kept lanes' (lane_blocks.hpp, scratch_array).
template <class T>
PWCONTACT_INLINE StateByPosition<T> state_by_position(const Scratch& scratch) {
  constexpr std::size_t first = FullKept<T>::footprint, used = first + 3;
  return {scratch_array<T, used>(scratch, first), scratch_array<T, used>(scratch, first + 1),
          scratch_array<T, used>(scratch, first + 2)};
}

// Full answer, arithmetic T, pairs In, results Out (float lanes on double
// pairs round them once on loading and widen the results on writing).
template <class Arch, class T, class In, class Out>
void solve_full(const PairSpan<In>& in, const ResultSpan<Out>& out, std::size_t n,
                const ChunkSettings& settings, const Scratch& scratch, ChunkCounters& counters) {
  FullKept<T> kept(scratch);
  const StateByPosition<T> state = state_by_position<T>(scratch);
  const bool automatic = settings.iterations == automatic_iterations;
  // A warm start (lambda_start given) is a Newton step or so from the
  // answer: one step and the check (lanes that fail it go on in the later
  // passes, one evaluation each).
  const bool warm = warm_start<T>(in);
  const int first =
      automatic ? (warm ? 2 : first_pass_evaluations<T>(settings)) : settings.iterations;
  const Handoff handoff =
      automatic && first < settings.max_iterations ? Handoff::adaptive : Handoff::none;
  const int polynomial = polynomial_steps<T, In>(settings, automatic && !warm);
  for_each_block<Arch, FullBlock<Arch, T>::size>(
      in, n,
      [&](const PairSpan<In>& span, std::size_t from, std::size_t position, std::size_t real) {
        first_pass_block<Arch, T, In, Out>(span, from, position, real, first, polynomial, handoff,
                                           state, out, settings, counters, kept);
      },
      4);
  if (handoff == Handoff::adaptive) {
    pack_unfinished<Arch>(in, n, out.status, state, kept);
    later_passes<Arch, T>(kept, out, first, settings, counters);
  }
}

// Mixed precision (see mixed_block): the answer has double accuracy.
template <class Arch>
void solve_full_mixed(const PairSpan<double>& in, const ResultSpan<double>& out, std::size_t n,
                      const ChunkSettings& settings, const Scratch& scratch,
                      ChunkCounters& counters) {
  FullKept<double> kept(scratch);
  FullKept<float> never_kept(scratch);
  const StateByPosition<double> state = state_by_position<double>(scratch);
  const bool automatic = settings.iterations == automatic_iterations;
  const int float_steps = automatic ? mixed_float_steps : settings.iterations;
  const Handoff handoff = automatic && mixed_double_evaluations < settings.max_iterations
                              ? Handoff::adaptive
                              : Handoff::none;
  for_each_block<Arch, FullBlock<Arch, float>::size>(
      in, n,
      [&](const PairSpan<double>& span, std::size_t from, std::size_t position, std::size_t real) {
        mixed_block<Arch>(span, from, position, real, float_steps, handoff, state, out, settings,
                          counters, kept, never_kept);
      },
      1);
  if (handoff == Handoff::adaptive) {
    pack_unfinished<Arch>(in, n, out.status, state, kept);
    later_passes<Arch, double>(kept, out, mixed_double_evaluations, settings, counters);
  }
}

}  // namespace pwcontact::kernels::PWCONTACT_TARGET
