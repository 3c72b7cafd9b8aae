// Blocks of lanes: loading pairs into SIMD registers (from the caller's arrays
// or from the lanes kept between passes), nondimensionalising them, and
// keeping the lanes that are not finished for the next pass.
//
// A block is U SIMD groups of W lanes, solved side by side: one group's
// Newton step is a long chain of dependent divisions and multiply-adds, so
// interleaving groups keeps the floating-point units busy while each chain
// waits. Every function is a template on the architecture (see
// contact_kernel.hpp for why).
#pragma once

#include "kernels/target.hpp"

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#include "kernels/kernel_api.hpp"
#include "kernels/simd_math.hpp"

// The loops over the U interleaved groups must be unrolled: only then do the
// groups' instructions mix and their state live in registers (GCC otherwise
// keeps them rolled; measured 3-4 %).
#define PWCONTACT_UNROLL _Pragma("GCC unroll 4")

namespace pwcontact::kernels::PWCONTACT_TARGET {

// Groups interleaved per instruction set, by measurement (1M random pairs,
// one thread): AVX-512's 32 registers hold three groups' state (U = 3 is
// 3-4 % faster than 2, U = 1 is 12 % slower); with 16 registers, two.
template <class Arch>
inline constexpr int interleaved_groups = is_avx512<Arch> ? 3 : 2;

template <class T>
struct KernelTolerance;
template <>
struct KernelTolerance<double> {
  // The convergence check's tolerances on the gain of one more Newton step,
  // relative to f (see FullBlock::finish): with the second-order correction,
  // and on the rigorous bound without it.
  static constexpr double corrected_gain = 1e-11;
  // lambda to ~1e-12 (and the peer library's check, mu1^2 = mu2^2 = mu^2 at
  // the returned lambda, to ~1e-11 on its family).
  static constexpr double corrected_gain_with_lambda = 1e-13;
  // Accuracy::high: the refined f is good to ~eps, but the gain comes from
  // the unrefined g, whose noise (~eps cond f) becomes a spurious gain where
  // g' is small (lambda* near 0 or 1, crossed needles and discs): up to the
  // tolerance itself. A gain is added only when it is this small, so that
  // even all noise it errs by a few eps (was 1e-11: 36 times the high
  // accuracy bound on needles of aspect 1e5 with status ok).
  static constexpr double corrected_gain_high = 4 * std::numeric_limits<double>::epsilon();
  static constexpr double high_width = 1e-3;
  static constexpr double bounded_gain = 4 * std::numeric_limits<double>::epsilon();
  // The corrected answer f + gain errs by the third-order term of the Newton
  // model, ~(1/3) |g''/g'| |step| gain. Near the ends of [0, 1], where g has
  // near poles (lambda* close to 0 or 1: very different sizes), g''/g' is
  // ~3 / min(lambda, 1 - lambda) = 3 / w, so the error is ~gain |step| / w:
  // accepted when that is below this many eps of f.
  static constexpr double third_order = std::numeric_limits<double>::epsilon();
  // When lambda (or the geometry) is asked for, the Newton step must also be
  // this small relative to w: the reported lambda, the step's, then errs by
  // ~|g''/(2 g')| step^2 ~ 1.5 (step / w)^2 w, ~1e-12 w.
  static constexpr double lambda_step = 0x1p-20;
  // The expansion behind the corrected answer (doc/theory.md eq. 24) is a
  // series in step / w, w the distance to g's nearest pole: it is trusted
  // only for steps at most this fraction of w (the reference path's stall
  // test takes the same). A step as long as lambda with a negligible
  // predicted gain is no convergence: beside a disc thinner than ~1e-15 the
  // radial guess is lambda ~ its thickness, g' ~ 1 / lambda^3 there, and
  // Newton's steps grow from lambda / 2 to lambda* ~ 0.03 (was: answered
  // f + gain 0.1 % below mu^2 with status ok, found by kernels_fuzz).
  static constexpr double model_step = 1.0 / 16;
  // Lanes the kernels take: f'(0) = r^T Q1^-1 r and -f'(1) = r^T Q2^-1 r
  // (the squared distance in units of each ellipsoid's extent along r12)
  // within these bounds and within this factor of each other (so that the
  // sizes are at most ~2^60 apart and lambda* at least ~2^-60 from 0 and 1).
  // Every quantity of a solve, of degree -1 to 1 in the length scale, then
  // stays within ~2^+-400 of the scale's power, and the overlap kernel's
  // accurate solve (|r|^4, r^T Q r) within 2^+-600. Others go to the
  // reference path, which scales r and Q separately. (in_range: the same
  // from the inputs, where the slopes are not computed: both forms' largest
  // diagonal entries within form_ratio of the larger D, |r|^2 within the
  // distance factors of D.)
  static constexpr double slope_low = 0x1p-240, slope_high = 0x1p240, slope_ratio = 0x1p-120;
  static constexpr double form_ratio = 0x1p-100;
  static constexpr double distance_squared_low = 0x1p-200, distance_squared_high = 0x1p200;
  // Inputs whose largest diagonal entry lies in this range are solved as
  // they are; others are first rescaled. The widest products the kernels
  // form (n det in the initial guess and the overlap bounds) are of degree 12
  // in the length scale, ~2^(6e) for a diagonal 2^e: the range keeps them
  // far from overflow and underflow, so that the scaling, which is exact,
  // changes no result whether it is applied or not.
  static constexpr double safe_scale_low = 0x1p-100, safe_scale_high = 0x1p100;
  // A double lane that is ill-conditioned would gain nothing from the
  // fallback, which runs in double too.
  static constexpr bool checks_growth = false;
  static constexpr double max_growth = 0;
};
template <>
struct KernelTolerance<float> {
  // (float: measured at the float floor for gains up to 1e-5 f on random pairs)
  static constexpr float corrected_gain = 1e-5f;
  static constexpr float corrected_gain_with_lambda = 1e-7f;
  static constexpr float corrected_gain_high = 4 * std::numeric_limits<float>::epsilon();
  static constexpr float high_width = 1e-3f;
  static constexpr float bounded_gain = 4 * std::numeric_limits<float>::epsilon();
  static constexpr float third_order = std::numeric_limits<float>::epsilon();
  // The last step's own error in lambda: ~1.5 (2^-11)^2 w ~ 4e-7 w. The
  // rounding of g in float is larger where g is ill-conditioned (measured:
  // |lambda - lambda*| up to 1.5e-4 w for sizes 1e4 apart, 3e-5 w for
  // aspect 100 near tangency), so no bound on lambda is promised in float.
  static constexpr float lambda_step = 0x1p-11f;
  static constexpr float model_step = 1.0f / 16;  // (as in double)
  // (float's range is 2^+-126: quantities within ~2^+-61 of the scale's
  // power; sizes at most ~2^15 apart, lambda* at least ~3e-5 from 0 and 1)
  static constexpr float slope_low = 0x1p-30f, slope_high = 0x1p30f, slope_ratio = 0x1p-30f;
  static constexpr float form_ratio = 0x1p-24f;
  static constexpr float distance_squared_low = 0x1p-24f, distance_squared_high = 0x1p24f;
  static constexpr float safe_scale_low = 0x1p-10f, safe_scale_high = 0x1p10f;
  // A float lane whose factorisation shows element growth above this is
  // finished in double: beyond it float can lose more than ~1e-5 (measured on
  // the pw85 and log-uniform families; random pairs with semi-axes in [0.5, 2]
  // stay below 6).
  static constexpr bool checks_growth = true;
  static constexpr float max_growth = 16;
};

// The 15 numbers of a pair in order: r12 x y z, q1[0..5], q2[0..5].
inline constexpr int pair_components = 15;

template <class T>
PWCONTACT_INLINE const T* component(const PairSpan<T>& in, int k) {
  return k < 3 ? in.r12[k] : k < 9 ? in.q1[k - 3] : in.q2[k - 9];
}

// 0, 1, 2, ... in static storage: loading them is cheaper than building
// them lane by lane on the stack, which stalls the load (store forwarding
// cannot combine many small stores into one wide load).
template <class T>
alignas(64) inline constexpr T lane_numbers[16] = {0, 1, 2,  3,  4,  5,  6,  7,
                                                   8, 9, 10, 11, 12, 13, 14, 15};

// Numbers from one pair to the next in component k's array.
template <class T>
PWCONTACT_INLINE std::ptrdiff_t component_stride(const PairSpan<T>& in, int k) {
  return in.stride[k < 3 ? 0 : k < 9 ? 1 : 2];
}

// Component k of pair i.
template <class T>
PWCONTACT_INLINE T element(const PairSpan<T>& in, int k, std::size_t i) {
  return component(in, k)[std::ptrdiff_t(i) * component_stride(in, k)];
}

// Component k of pairs i, i + 1, ... in the lanes of a B: one load from a
// column of its own, else a gather (rows of an array of structures, a
// broadcast with stride 0, an array read backwards).
template <class B, class T>
PWCONTACT_INLINE B load_component(const PairSpan<T>& in, int k, std::size_t i) {
  const std::ptrdiff_t stride = component_stride(in, k);
  const T* first = component(in, k) + std::ptrdiff_t(i) * stride;
  if (stride == 1) return B::load_unaligned(first);
  // (Measured on Zen 4: a 512-bit gather costs what two 256-bit ones do.)
  using Index = std::conditional_t<sizeof(T) == 8, std::int64_t, std::int32_t>;
  using I = xsimd::batch<Index, typename B::arch_type>;
  const I offsets = I::load_aligned(lane_numbers<Index>) * I(Index(stride));
  return B::gather(first, offsets);
}

template <class B>
PWCONTACT_INLINE B& component(PairLanes<B>& p, int k) {
  return k < 3 ? p.r[k] : k < 9 ? p.q1[k - 3] : p.q2[k - 9];
}

template <class B>
PWCONTACT_INLINE const B& component(const PairLanes<B>& p, int k) {
  return k < 3 ? p.r[k] : k < 9 ? p.q1[k - 3] : p.q2[k - 9];
}

// The kernels' scratch memory (kernel_api.hpp: scratch_values_per_pair
// arrays of capacity + padding doubles per thread), divided here and only
// here: array k of type T begins k arrays of T in (arrays of float take half
// the room). What lies where, each from array 0:
//   - the lanes kept between passes (KeptLanes: the pair, the kernel's named
//     state, the chunk positions), footprint arrays;
//   - after them, full answers: lambda and the bracket by chunk position
//     (contact_kernel.hpp, state_by_position); overlap answers: the pairs
//     the cheap pass left, in double, and their positions
//     (overlap_kernel.hpp, gather_undecided).
// `arrays_used` is checked against the room at compile time.
template <class T, std::size_t arrays_used>
PWCONTACT_INLINE T* scratch_array(const Scratch& scratch, std::size_t k) {
  static_assert(arrays_used * sizeof(T) <= scratch_values_per_pair * sizeof(double),
                "the scratch layout needs more room than kernel_api.hpp gives it");
  return static_cast<T*>(scratch.memory) + k * (scratch.capacity + scratch_padding_pairs);
}

// Lanes kept between passes, in the scratch memory: the nondimensionalised
// pair and `State` more numbers per lane (named by the kernel's slot enum:
// FullSlot, OverlapSlot), and where the pair sits in the chunk.
template <class T, int State>
struct KeptLanes {
  static constexpr int arrays = pair_components + State;
  // Arrays of T the kept lanes occupy (the positions take one).
  static constexpr std::size_t footprint = arrays + 1;
  T* values[arrays];  // the pair's 15 components (component()), then the state
  std::uint32_t* index;
  std::size_t count = 0;

  PWCONTACT_INLINE explicit KeptLanes(const Scratch& scratch) {
    for (int k = 0; k < arrays; ++k)
      values[k] = scratch_array<T, footprint>(scratch, std::size_t(k));
    index = reinterpret_cast<std::uint32_t*>(scratch_array<T, footprint>(scratch, arrays));
  }
};

// The largest diagonal entry of Q1 and Q2, for nondimensionalising.
template <class B>
PWCONTACT_INLINE B largest_diagonal(const PairLanes<B>& p) {
  return xsimd::max(xsimd::max(xsimd::max(p.q1[0], p.q1[3]), p.q1[5]),
                    xsimd::max(xsimd::max(p.q2[0], p.q2[3]), p.q2[5]));
}

// Whether the kernels' arithmetic holds a lane's numbers (see
// KernelTolerance::form_ratio), with the limits of lanes of type Limits:
// both forms within form_ratio of the larger's scale, and the centres either
// coincident (exactly) or |r|^2 within the distance range of that scale.
// Lanes outside go to the reference path: never an overflow, an underflow
// or a float lane's r rounded to zero answered as valid.
template <class Limits, class B>
PWCONTACT_INLINE auto in_range(const PairLanes<B>& p) {
  using Tolerance = KernelTolerance<Limits>;
  const B m1 = xsimd::max(xsimd::max(p.q1[0], p.q1[3]), p.q1[5]);
  const B m2 = xsimd::max(xsimd::max(p.q2[0], p.q2[3]), p.q2[5]);
  const B largest = xsimd::max(m1, m2), smallest = xsimd::min(m1, m2);
  const B rr = p.r[0] * p.r[0] + p.r[1] * p.r[1] + p.r[2] * p.r[2];
  const auto coincident = (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
  return (smallest >= largest * B(Tolerance::form_ratio)) &
         (coincident | ((rr >= largest * B(Tolerance::distance_squared_low)) &
                        (rr <= largest * B(Tolerance::distance_squared_high))));
}

// Whether the kernels' arithmetic holds a lane, from its slopes f'(0) = s1
// and -f'(1) = s2 (see KernelTolerance::slope_low); coincident centres are
// decided apart. Lanes outside go to the reference path: never an overflow,
// an underflow or a lambda* that T cannot resolve answered as valid.
template <class B>
PWCONTACT_INLINE auto slopes_in_range(const B& s1, const B& s2) {
  using Tolerance = KernelTolerance<typename B::value_type>;
  const B smallest = xsimd::min(s1, s2), largest = xsimd::max(s1, s2);
  return (smallest >= B(Tolerance::slope_low)) & (largest <= B(Tolerance::slope_high)) &
         (smallest >= largest * B(Tolerance::slope_ratio));
}

// A sufficient condition for slopes_in_range (double lanes) that needs no
// solve: from the traces t_i and determinants d_i of positive definite forms
// (lambda_max <= t_i, lambda_min >= d_i / t_i^2, so s_i = r^T Qi^-1 r is in
// [rr / t_i, rr t_i^2 / d_i]), with t_i^3 <= 2^40 d_i, t_min >= 2^-60 t_max
// and rr within 2^+-60 of t_max: s_i >= 2^-60, s_i <= 2^60 2^40 2^60 = 2^160
// and s1 / s2 >= 2^-60 / 2^40 = 2^-100, well inside the bounds. (d_i as
// computed errs by at most ~30 eps t_i^3 = 2^-47 t_i^3, which the factor
// 2^40 covers; every other rounding is a few eps.) Random and elongated
// shapes (aspect ratios to 500: t^3 / d ~ 2^21) meet it; a register with a
// lane that does not computes the slopes.
template <class B>
PWCONTACT_INLINE auto slopes_surely_in_range(const PairLanes<B>& p, const B& d1, const B& d2) {
  static_assert(std::is_same<typename B::value_type, double>::value, "bounds for double lanes");
  const B t1 = p.q1[0] + p.q1[3] + p.q1[5], t2 = p.q2[0] + p.q2[3] + p.q2[5];
  const B t_max = xsimd::max(t1, t2);
  const B rr = p.r[0] * p.r[0] + p.r[1] * p.r[1] + p.r[2] * p.r[2];
  const B conditioning(0x1p40), ratio(0x1p-60), distance(0x1p60);
  return (t1 * t1 * t1 <= conditioning * d1) & (t2 * t2 * t2 <= conditioning * d2) &
         (xsimd::min(t1, t2) >= ratio * t_max) & (rr >= t_max / distance) &
         (rr <= t_max * distance);
}

// The power-of-two scaling (eq. 36) has two other copies: the scalar one in
// pack_unfinished (contact_kernel.hpp), for the lanes it packs, and the
// reference path's detail::ScaledPair (include/pwcontact/reference.hpp),
// which brings the largest diagonal entry into [1/4, 1) instead of [1, 4)
// (its Q is this one's over 4, exactly) and scales r by a power of its own.
// tests/shared_math_test.cpp holds the three together bit for bit.
//
// Nondimensionalises by a power of two (exact): r -> r t, Q -> Q t^2 with
// t = 1 / 2^floor(log2 sqrt(largest diagonal)); mu^2 is invariant. Only done
// when some lane's scale is far from 1, where products of entries could
// overflow or underflow: the scaling is exact, so skipping it elsewhere
// changes no result. Returns t (1 where not scaled).
template <class B>
PWCONTACT_INLINE B nondimensionalise(PairLanes<B>& p, bool always = false) {
  using T = typename B::value_type;
  const B largest = largest_diagonal(p);
  const B low(KernelTolerance<T>::safe_scale_low), high(KernelTolerance<T>::safe_scale_high);
  if (!always && xsimd::all((largest >= low) & (largest <= high))) return B(1);
  const B infinity(std::numeric_limits<T>::infinity());
  B t;
  if (xsimd::any((largest > B(0)) & (largest < B(std::numeric_limits<T>::min())))) {
    // A subnormal diagonal (rare): its exponent bits do not give its scale.
    // (For the lane whose largest entry it is, t^2 >= 2^1024 overflows: its
    // Q becomes infinite, it fails all_finite and goes to the reference path.
    // The other lanes of the register get the t of the exponent bits.)
    const B power = xsimd::bitwise_and(xsimd::sqrt(largest), infinity);  // exponent bits only
    t = xsimd::select((power > B(0)) & (power < infinity), B(1) / power, B(1));
  } else {
    // The same t from the exponent bits alone (no square root or division:
    // measured 4 % of a mixed-precision solve): for largest = m 2^e with m in
    // [1, 2), sqrt(largest) is in [1, 2) 2^floor(e/2) (rounding cannot reach
    // the next power of two), so t = 2^-floor(e/2), an arithmetic shift of
    // the unbiased exponent.
    using I = xsimd::batch<xsimd::as_integer_t<T>, typename B::arch_type>;
    constexpr int mantissa_bits = std::numeric_limits<T>::digits - 1;
    constexpr int bias = std::numeric_limits<T>::max_exponent - 1;
    const I e = (xsimd::bitwise_cast<I>(largest) >> mantissa_bits) - I(bias);
    const I biased_t = I(bias) - (e >> 1);
    t = xsimd::select((largest > B(0)) & (largest < infinity),
                      xsimd::bitwise_cast<B>(biased_t << mantissa_bits), B(1));
  }
  const B t2 = t * t;
  const auto apart = (p.r[0] != B(0)) | (p.r[1] != B(0)) | (p.r[2] != B(0));
  for (int k = 0; k < 3; ++k) p.r[k] *= t;
  for (int k = 0; k < 6; ++k) {
    p.q1[k] *= t2;
    p.q2[k] *= t2;
  }
  // A tiny r (subnormal) scaled down can round to zero: the lane would look
  // coincident (mu^2 = 0, valid). It is marked not usable (a zero scale) and
  // left to the reference path, which scales r and Q separately.
  const auto lost = apart & (p.r[0] == B(0)) & (p.r[1] == B(0)) & (p.r[2] == B(0));
  return xsimd::select(lost, B(0), t);
}

// The sum of the inputs is finite when they all are (a NaN or an infinity
// makes it NaN or infinite), and only rarely otherwise (overflow): a lane
// that fails this cheap test goes to the reference path, which decides.
template <class B>
PWCONTACT_INLINE auto all_finite(const PairLanes<B>& p) {
  B sum = p.r[0] + p.r[1] + p.r[2];
  for (int k = 0; k < 6; ++k) sum += p.q1[k] + p.q2[k];
  return (sum - sum) == B(0);
}

// Rows of G numbers side by side (stride G: a C-ordered (N, 3) or (N, 6)
// array) into G registers of 8 double lanes, by shuffles: lane l of
// component c is number 8 j + e of the 8 G loaded, with 8 j + e = G l + c.
// Two registers' numbers are picked by one two-source permute and the
// results joined by blends. Measured on Zen 4 for 8 pairs in L1: 3.5 ns a
// pair by shuffles for q1 and q2, 6.3 ns by gathers. Pairs of tables by
// (component, register pair), built at compile time.
template <int G>
struct RowShuffles {
  static_assert(G == 3 || G == 6);
  static constexpr int pairs = (G + 1) / 2;  // register pairs: (0, 1), (2, 3), (4, 5)
  alignas(64) std::int64_t index[G][pairs][8] = {};
  unsigned char from[G][pairs] = {};  // lanes taken from register pair j
  constexpr RowShuffles() {
    for (int c = 0; c < G; ++c)
      for (int l = 0; l < 8; ++l) {
        const int p = G * l + c, j = p / 16;
        index[c][j][l] = p % 16;
        from[c][j] = static_cast<unsigned char>(from[c][j] | (1u << l));
      }
  }
};

template <int G>
inline constexpr RowShuffles<G> row_shuffles{};

template <int G>
PWCONTACT_INLINE void load_rows_avx512(const double* first, __m512d* out) {
  constexpr RowShuffles<G> const& t = row_shuffles<G>;
  __m512d r[2 * RowShuffles<G>::pairs];
  for (int j = 0; j < G; ++j) r[j] = _mm512_loadu_pd(first + 8 * j);
  if constexpr (G % 2 == 1) r[G] = r[G - 1];  // (an odd count: the last pair repeats a register)
  for (int c = 0; c < G; ++c) {
    __m512d v = _mm512_permutex2var_pd(r[0], _mm512_load_si512(t.index[c][0]), r[1]);
    for (int j = 1; j < RowShuffles<G>::pairs; ++j)
      if (t.from[c][j])
        v = _mm512_mask_blend_pd(
            __mmask8(t.from[c][j]), v,
            _mm512_permutex2var_pd(r[2 * j], _mm512_load_si512(t.index[c][j]), r[2 * j + 1]));
    out[c] = v;
  }
}

// Whether components [first, first + G) (one of r12, q1, q2) are packed
// rows of G numbers in their order: G numbers from one pair to the next, and
// component first + c at c numbers past component first. A stride of G
// alone is not enough: the columns of a C-ordered array read backwards
// (numpy's a[:, ::-1]) or one column broadcast to G (np.broadcast_to) have
// it too, with their components elsewhere in the row.
template <int G, class T>
PWCONTACT_INLINE bool packed_rows(const PairSpan<T>& in, int first) {
  if (component_stride(in, first) != G) return false;
  const T* row = component(in, first);
  for (int c = 1; c < G; ++c)
    if (component(in, first + c) != row + c) return false;
  return true;
}

// Components [first, first + G) of pairs i, i + 1, ... (one of r12, q1,
// q2) into `out`: by shuffles where the pairs are packed rows of G doubles
// (packed_rows) and the lanes are AVX-512's 8 doubles, else component by
// component.
template <class B, int G, class T>
PWCONTACT_INLINE void load_group(const PairSpan<T>& in, int first, std::size_t i, B* out) {
  using Arch = typename B::arch_type;
  if constexpr (is_avx512<Arch> && std::is_same<T, double>::value) {
    if (packed_rows<G>(in, first)) {
      __m512d v[G];
      load_rows_avx512<G>(component(in, first) + std::ptrdiff_t(i) * G, v);
      for (int c = 0; c < G; ++c) out[c] = v[c];
      return;
    }
  }
  for (int c = 0; c < G; ++c) out[c] = load_component<B>(in, first + c, i);
}

// All 15 components of pairs i, i + 1, ...
template <class B, class T>
PWCONTACT_INLINE void load_all(const PairSpan<T>& in, std::size_t i, PairLanes<B>& p) {
  load_group<B, 3>(in, 0, i, p.r);
  load_group<B, 6>(in, 3, i, p.q1);
  load_group<B, 6>(in, 9, i, p.q2);
}

// Loads W pairs from the caller's arrays at position i into T lanes,
// converting double pairs to float lanes when T is float (two double
// registers per float register); nondimensionalises in the input's type,
// before any narrowing, so that extreme scales survive it.
template <class Arch, class T, class In>
PWCONTACT_INLINE void load_pairs(const PairSpan<In>& in, std::size_t i,
                                 PairLanes<xsimd::batch<T, Arch>>& p,
                                 xsimd::batch<T, Arch>& scale) {
  if constexpr (std::is_same<T, In>::value) {
    load_all(in, i, p);
    scale = nondimensionalise(p);
  } else {
    static_assert(std::is_same<T, float>::value && std::is_same<In, double>::value);
    using D = xsimd::batch<double, Arch>;
    constexpr std::size_t half = D::size;
    PairLanes<D> lo, hi;
    load_all(in, i, lo);
    load_all(in, i + half, hi);
    // Always scaled before narrowing: float's range is narrower than the
    // double kernels' safe range, and a pair and its power-of-two multiples
    // must round to the same floats (then they get the same answer).
    // A lane out of float's range is marked by a zero scale (not usable),
    // decided in double: narrowing could round its r to zero.
    D scale_lo = nondimensionalise(lo, true), scale_hi = nondimensionalise(hi, true);
    scale_lo = xsimd::select(in_range<float>(lo), scale_lo, D(0));
    scale_hi = xsimd::select(in_range<float>(hi), scale_hi, D(0));
    for (int k = 0; k < pair_components; ++k)
      component(p, k) = narrow<Arch>(component(lo, k), component(hi, k));
    scale = narrow<Arch>(scale_lo, scale_hi);
  }
}

// Copies the last, partial block of a span into a padded local buffer whose
// missing lanes repeat the first pair of the tail (a valid problem that costs
// nothing special), so that nothing is read past the end.
template <class In, std::size_t Block>
struct PaddedTail {
  alignas(64) In buffer[pair_components][Block];
  alignas(64) In lambda_buffer[Block];
  PairSpan<In> span{};  // (aggregate initialisation: no constructor to emit)

  PaddedTail(const PairSpan<In>& in, std::size_t first, std::size_t rest) {
    for (int k = 0; k < pair_components; ++k) {
      for (std::size_t l = 0; l < Block; ++l)
        buffer[k][l] = element(in, k, first + (l < rest ? l : 0));
      if (k < 3)
        span.r12[k] = buffer[k];
      else if (k < 9)
        span.q1[k - 3] = buffer[k];
      else
        span.q2[k - 9] = buffer[k];
    }
    if (in.lambda_start) {
      for (std::size_t l = 0; l < Block; ++l)
        lambda_buffer[l] = in.lambda_start[first + (l < rest ? l : 0)];
      span.lambda_start = lambda_buffer;
    }
  }
};

// Where the lanes of one group go in the outputs: W consecutive positions
// from `base`, or the positions listed in `index`; `real` of them (the rest
// is padding).
struct LanePositions {
  std::size_t base;
  const std::uint32_t* index;  // null: consecutive
  std::size_t real;

  PWCONTACT_INLINE std::size_t operator[](std::size_t l) const {
    return index ? index[l] : base + l;
  }
};

// Compressing four lanes by a mask without AVX-512: for each of the 16
// masks, the source lane of each destination lane (the chosen lanes first,
// in order; the rest repeat lane 0, stored past the count, where nothing
// reads them), as 32-bit lane indices of a 128-bit register (`lanes`) and as the
// pairs of 32-bit halves of a register of four doubles (`halves`).
struct CompressFour {
  alignas(16) std::int32_t lanes[16][4];
  alignas(32) std::int32_t halves[16][8];
  constexpr CompressFour() : lanes(), halves() {
    for (int mask = 0; mask < 16; ++mask) {
      int to = 0;
      for (int from = 0; from < 4; ++from)
        if (mask & (1 << from)) {
          lanes[mask][to] = from;
          halves[mask][2 * to] = 2 * from;
          halves[mask][2 * to + 1] = 2 * from + 1;
          ++to;
        }
      for (; to < 4; ++to) halves[mask][2 * to + 1] = 1;
    }
  }
};
inline constexpr CompressFour compress_four{};

// The lanes of four doubles selected by `mask` (4 bits) moved to the front,
// in order, by the permutation compress_four gives. (A template, made only
// where an AVX2 branch calls it: as a plain function the SSE2 target's
// translation unit compiled it too, and warned of its AVX return type.)
template <int = 0>
PWCONTACT_INLINE __m256d compress_four_doubles(__m256d values, unsigned mask) {
  const __m256i permutation =
      _mm256_load_si256(reinterpret_cast<const __m256i*>(compress_four.halves[mask]));
  return _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(values), permutation));
}

// AVX2: the mask bits of a register (lane_bits) spread to one byte each
// (0xFF for a set lane), lane 0 in the lowest byte.
struct SpreadFour {
  std::uint32_t bytes[16];
  constexpr SpreadFour() : bytes() {
    for (unsigned mask = 0; mask < 16; ++mask)
      for (unsigned l = 0; l < 4; ++l)
        if (mask & (1u << l)) bytes[mask] |= 0xFFu << (8 * l);
  }
};
inline constexpr SpreadFour spread_four{};
template <class Arch, class T>
PWCONTACT_INLINE std::uint64_t lane_bytes(const xsimd::batch_bool<T, Arch>& flag) {
  const unsigned bits = lane_bits(flag);
  return std::uint64_t(spread_four.bytes[bits & 0xFu]) |
         (std::uint64_t(spread_four.bytes[(bits >> 4) & 0xFu]) << 32);
}

// Appends the lanes of one group selected by `keep` to the kept lanes, given
// copies of the group's registers in the kept arrays' order (copies, so that
// no register's address escapes and the compiler keeps them in registers)
// and the lanes' positions:
// AVX-512 compresses each array in a register and stores it whole, AVX2
// permutes each one and stores it whole, SSE2 copies lane by lane.
template <class Arch, class T, int State>
PWCONTACT_INLINE void keep_lanes(KeptLanes<T, State>& kept, const xsimd::batch_bool<T, Arch>& keep,
                                 const xsimd::batch<T, Arch>* values, const LanePositions& at) {
  using B = xsimd::batch<T, Arch>;
  constexpr std::size_t W = B::size;
  constexpr int arrays = KeptLanes<T, State>::arrays;
  const std::size_t first = kept.count;
  if (xsimd::none(keep)) return;
  if constexpr (is_avx512<Arch>) {
    // Compress in a register and store the whole register: the kept arrays
    // have room past their end, and Zen 4 microcodes compress-to-memory.
    const auto mask = keep.data;
    for (int k = 0; k < arrays; ++k) {
      if constexpr (std::is_same<T, double>::value)
        _mm512_storeu_pd(kept.values[k] + first, _mm512_maskz_compress_pd(mask, values[k]));
      else
        _mm512_storeu_ps(kept.values[k] + first, _mm512_maskz_compress_ps(mask, values[k]));
    }
    // Positions: consecutive from a base, or listed; only kept lanes are
    // real, so reading a full register of listed positions stays in the array.
    if constexpr (std::is_same<T, double>::value) {
      const __m256i idx = at.index ? _mm256_loadu_si256(reinterpret_cast<const __m256i*>(at.index))
                                   : _mm256_add_epi32(_mm256_set1_epi32(int(at.base)),
                                                      _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(kept.index + first),
                          _mm256_maskz_compress_epi32(mask, idx));
    } else {
      const __m512i idx = at.index ? _mm512_loadu_si512(at.index)
                                   : _mm512_add_epi32(_mm512_set1_epi32(int(at.base)),
                                                      _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8,
                                                                        9, 10, 11, 12, 13, 14, 15));
      _mm512_storeu_si512(kept.index + first, _mm512_maskz_compress_epi32(mask, idx));
    }
    kept.count += std::size_t(__builtin_popcount(unsigned(mask)));
  } else if constexpr (is_avx2<Arch>) {
    // Compress by permutations looked up from the mask (compress_four) and
    // store whole registers: four doubles, or eight floats as two halves of
    // four. (Copied lane by lane through the stack instead, the pw85
    // family's double answers, half of whose lanes are kept, took ~20 %
    // longer.)
    const unsigned mask = lane_bits(keep);
    kept.count = first + std::size_t(__builtin_popcount(mask));
    // The positions lane by lane, from the mask's bits (a few integer
    // stores; the listed ones would need a permutation of their own).
    std::size_t c = first;
    for (unsigned m = mask; m != 0; m &= m - 1)
      kept.index[c++] = std::uint32_t(at[std::size_t(__builtin_ctz(m))]);
    if constexpr (std::is_same<T, double>::value) {
      for (int k = 0; k < arrays; ++k)
        _mm256_storeu_pd(kept.values[k] + first, compress_four_doubles(values[k], mask));
    } else {
      const unsigned low = mask & 0xFu, high = mask >> 4;
      const std::size_t second = first + std::size_t(__builtin_popcount(low));
      const __m128i low_lanes =
          _mm_load_si128(reinterpret_cast<const __m128i*>(compress_four.lanes[low]));
      const __m128i high_lanes =
          _mm_load_si128(reinterpret_cast<const __m128i*>(compress_four.lanes[high]));
      for (int k = 0; k < arrays; ++k) {
        const __m256 v = values[k];
        _mm_storeu_ps(kept.values[k] + first,
                      _mm_permutevar_ps(_mm256_castps256_ps128(v), low_lanes));
        _mm_storeu_ps(kept.values[k] + second,
                      _mm_permutevar_ps(_mm256_extractf128_ps(v, 1), high_lanes));
      }
    }
  } else {
    bool lanes[W];
    keep.store_unaligned(lanes);
    alignas(64) T tmp[arrays][W];
    for (int k = 0; k < arrays; ++k) values[k].store_aligned(tmp[k]);
    std::size_t c = first;
    for (std::size_t l = 0; l < W; ++l) {
      if (!lanes[l]) continue;
      for (int k = 0; k < arrays; ++k) kept.values[k][c] = tmp[k][l];
      kept.index[c] = std::uint32_t(at[l]);
      ++c;
    }
    kept.count = c;
  }
}

// Writes one register of T lanes to an array of Out at their positions.
template <class Arch, class T, class Out>
PWCONTACT_INLINE void write_lanes(Out* target, const LanePositions& at,
                                  const xsimd::batch<T, Arch>& v) {
  using B = xsimd::batch<T, Arch>;
  constexpr std::size_t W = B::size;
  if (!at.index && at.real == W) {
    if constexpr (std::is_same<T, Out>::value) {
      v.store_unaligned(target + at.base);
    } else {
      xsimd::batch<double, Arch> lo, hi;
      widen<Arch>(v, lo, hi);
      lo.store_unaligned(target + at.base);
      hi.store_unaligned(target + at.base + W / 2);
    }
    return;
  }
  alignas(64) T lanes[W];
  v.store_aligned(lanes);
  for (std::size_t l = 0; l < at.real; ++l) target[at[l]] = Out(lanes[l]);
}

// Writes one byte for each lane in `which`: `yes` where `flag`, `no` elsewhere.
template <class Arch, class T>
PWCONTACT_INLINE void write_flags(std::uint8_t* target, const LanePositions& at,
                                  const xsimd::batch_bool<T, Arch>& which,
                                  const xsimd::batch_bool<T, Arch>& flag, std::uint8_t yes,
                                  std::uint8_t no) {
  constexpr std::size_t W = xsimd::batch<T, Arch>::size;
  if constexpr (is_avx512<Arch>) {
    if (!at.index && at.real == W) {
      const __m128i bytes = _mm_mask_blend_epi8(static_cast<__mmask16>(flag.data),
                                                _mm_set1_epi8(char(no)), _mm_set1_epi8(char(yes)));
      _mm_mask_storeu_epi8(target + at.base, static_cast<__mmask16>(which.data), bytes);
      return;
    }
  }
  if constexpr (is_avx2<Arch>) {
    if (!at.index && at.real == W) {
      // The W bytes read, blended where `which` and written back whole (the
      // chunk's bytes are this thread's alone), each lane's byte spread from
      // its mask bit by a table.
      const std::uint64_t written = lane_bytes<Arch, T>(which), set = lane_bytes<Arch, T>(flag);
      const std::uint64_t bytes =
          (set & (0x0101010101010101u * yes)) | (~set & (0x0101010101010101u * no));
      std::uint64_t old = 0;
      std::memcpy(&old, target + at.base, W);
      const std::uint64_t blended = (old & ~written) | (bytes & written);
      std::memcpy(target + at.base, &blended, W);
      return;
    }
  }
  bool write[W], lanes[W];
  which.store_unaligned(write);
  flag.store_unaligned(lanes);
  for (std::size_t l = 0; l < at.real; ++l)
    if (write[l]) target[at[l]] = lanes[l] ? yes : no;
}

// How many lanes are set (padding lanes are never set by the callers).
template <class Arch, class T>
PWCONTACT_INLINE std::uint64_t count_lanes(const xsimd::batch_bool<T, Arch>& flag) {
  if constexpr (is_avx512<Arch>) {
    return std::uint64_t(__builtin_popcount(unsigned(flag.data)));
  } else if constexpr (is_avx2<Arch>) {
    return std::uint64_t(__builtin_popcount(lane_bits(flag)));
  } else {
    constexpr std::size_t W = xsimd::batch<T, Arch>::size;
    bool lanes[W];
    flag.store_unaligned(lanes);
    std::uint64_t n = 0;
    for (std::size_t l = 0; l < W; ++l) n += lanes[l];
    return n;
  }
}

// Writes a status per lane: `ok` where `finished`, needs_fallback elsewhere.
template <class Arch, class T>
PWCONTACT_INLINE void write_statuses(Status* target, const LanePositions& at,
                                     const xsimd::batch_bool<T, Arch>& finished) {
  write_flags<Arch, T>(reinterpret_cast<std::uint8_t*>(target), at, finished | !finished, finished,
                       std::uint8_t(Status::ok), std::uint8_t(needs_fallback));
}

// Asks for the inputs of [i, i + count) to be brought into cache. For work
// that is light per pair (the overlap prefilter) fifteen input streams are
// more than the hardware prefetcher keeps ahead of (measured: the prefilter
// then waits on memory most of the time); heavier work hides the latency.
template <class Arch, class In>
PWCONTACT_INLINE void prefetch_pairs(const PairSpan<In>& in, std::size_t i, std::size_t count,
                                     std::size_t n) {
  constexpr std::size_t line = 64 / sizeof(In);  // numbers in a cache line
  if (i >= n) return;
  const std::size_t end = i + count < n ? i + count : n;
  // Each of r12, q1, q2: its columns (stride 1) a line at a time, or its
  // rows (the group's components share them) over the bytes they span.
  constexpr int groups[3][2] = {{0, 3}, {3, 9}, {9, 15}};
  for (int g = 0; g < 3; ++g) {
    const std::ptrdiff_t stride = in.stride[g];
    if (stride == 1) {
      for (std::size_t j = i; j < end; j += line)
        for (int k = groups[g][0]; k < groups[g][1]; ++k) __builtin_prefetch(component(in, k) + j);
      continue;
    }
    const In* a = component(in, groups[g][0]) + std::ptrdiff_t(i) * stride;
    const In* b = component(in, groups[g][0]) + std::ptrdiff_t(end - 1) * stride;
    const char* low = reinterpret_cast<const char*>(a < b ? a : b);
    const char* high =
        reinterpret_cast<const char*>((a < b ? b : a) + (groups[g][1] - groups[g][0]));
    if (stride > 15 || stride < -15) {  // rows far apart: a prefetch per row (the group's numbers)
      for (std::size_t j = i; j < end; ++j)
        __builtin_prefetch(component(in, groups[g][0]) + std::ptrdiff_t(j) * stride);
      continue;
    }
    for (const char* at = low; at < high; at += 64) __builtin_prefetch(at);
  }
}

// Runs `body(span, from, position, real)` over a span of n pairs in blocks:
// `real` pairs loaded from position `from` of `span`, answered at chunk
// position `position`; the last block is padded (PaddedTail) so that nothing
// is read past n.
template <class Arch, std::size_t Block, class In, class Body>
PWCONTACT_INLINE void for_each_block(const PairSpan<In>& in, std::size_t n, Body&& body,
                                     std::size_t prefetch_blocks = 0) {
  std::size_t i = 0;
  for (; i + Block <= n; i += Block) {
    if (prefetch_blocks) prefetch_pairs<Arch>(in, i + prefetch_blocks * Block, Block, n);
    body(in, i, i, Block);
  }
  if (i < n) {
    const PaddedTail<In, Block> tail(in, i, n - i);
    body(tail.span, 0, i, n - i);
  }
}

// What the full-answer and overlap blocks share: U groups of lanes, their
// pairs, scale factors, brackets and positions, and the safeguarded step.
template <class Arch, class T>
class LaneGroups {
 public:
  using B = xsimd::batch<T, Arch>;
  using M = xsimd::batch_bool<T, Arch>;
  static constexpr std::size_t W = B::size;
  static constexpr int U = interleaved_groups<Arch>;
  static constexpr std::size_t size = U * W;

 protected:
  LaneGroups(const ChunkSettings& settings, ChunkCounters& counters)
      : settings_(settings), counters_(counters) {}

  std::size_t lanes_in_group(std::size_t real, int u) const {
    const std::size_t first = std::size_t(u) * W;
    return real > first ? (real - first < W ? real - first : W) : 0;
  }

  // Lanes that hold a pair of the span rather than padding.
  PWCONTACT_INLINE M real_lanes(int u) const {
    if (at_[u].real == W) return B(0) == B(0);
    return B::load_aligned(lane_numbers<T>) < B(T(at_[u].real));
  }

  // Loads group u from the caller's arrays (see start() of the blocks).
  template <class In>
  PWCONTACT_INLINE void load(const PairSpan<In>& in, std::size_t from, std::size_t position,
                             const std::uint32_t* index, std::size_t real, int u) {
    const std::size_t offset = std::size_t(u) * W;
    load_pairs<Arch, T, In>(in, from + offset, pair_[u], scale_[u]);
    at_[u] = {position + offset, index ? index + offset : nullptr, lanes_in_group(real, u)};
  }

  // A lane the kernels can answer: finite inputs, and a scale factor that its
  // arithmetic can represent (float lanes on double pairs at scales beyond
  // float's range are left to the reference path). The blocks add the
  // range of the lane's numbers (slopes_in_range, in_range).
  PWCONTACT_INLINE M usable(int u) const {
    return this->real_lanes(u) & all_finite(pair_[u]) & (scale_[u] > B(0)) &
           (scale_[u] < B(std::numeric_limits<T>::infinity()));
  }

  void count_evaluations(int evaluations) {
    std::size_t real = 0;
    for (int u = 0; u < U; ++u) real += at_[u].real;
    counters_.lane_evaluations += std::uint64_t(real) * std::uint64_t(evaluations);
  }

  // One safeguarded step: narrows the bracket with the sign of g, takes the
  // formulation's step, and bisects when the step leaves the bracket (an
  // inclusive test: at convergence the step lands on a bracket end).
  PWCONTACT_INLINE M advance(const Evaluation<B>& e, int u) {
    hi_[u] = xsimd::select(e.g > B(0), e.lambda, hi_[u]);
    lo_[u] = xsimd::select(e.g < B(0), e.lambda, lo_[u]);
    const B next =
        settings_.formulation == Formulation::log_odds ? log_odds_step(e) : newton_step(e);
    const M newton = (lo_[u] <= next) & (next <= hi_[u]);
    lambda_[u] = xsimd::select(newton, next, (lo_[u] + hi_[u]) * B(0.5));
    return newton;
  }

  const ChunkSettings& settings_;
  ChunkCounters& counters_;
  PairLanes<B> pair_[U];
  B scale_[U], lambda_[U], lo_[U], hi_[U];
  M live_[U];
  LanePositions at_[U];
};

}  // namespace pwcontact::kernels::PWCONTACT_TARGET
