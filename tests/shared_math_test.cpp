// The arithmetic the kernels and the reference path both write, held together
// bit for bit: the LDL^T factorisation of Q and its solves (doc/theory.md
// eq. 38), one evaluation of f, g and g' at lambda (eqs. 10, 11, 17, 19), and
// the power-of-two scaling (eq. 36). Each is written twice, on SIMD
// registers (src/kernels/simd_math.hpp, lane_blocks.hpp, contact_kernel.hpp)
// and in scalar templates (include/pwcontact/reference.hpp), because the
// kernels may include no inline code but templates of their own target
// namespace (src/kernels/target.hpp).
//
// Why agreement must be exact: the kernel bodies are included here in a
// target namespace of this test's own, and run on SSE2 registers. This file
// is compiled with the baseline x86-64 flags (no FMA) and
// -ffp-contract=off (tests/CMakeLists.txt), as is the reference path in it,
// so every operation of either copy is one IEEE operation rounded once. The
// same operations in the same order on the same inputs give the same bits;
// any difference between the copies (a term reordered, a formula changed)
// shows as a mismatch. (Under AVX2 and AVX-512 the kernels fuse multiply-adds
// and agree with the reference path only to rounding.)
//
// One difference is by design, and the LDL^T tests are built around it: the
// kernels divide once per pivot and multiply by 1/d_i (in l_ij, in the solves
// and in the forms), the reference path divides by d_i, and a * (1/d) is
// a / d only when d is a power of two (on random forms l10 differs in a
// quarter of the cases, by an ulp, and f in 40 %, by up to ~12 ulps). So
// those tests take forms whose pivots are powers of two; everything else
// still rounds (l10 a1, the subtractions, the substitutions, Q(lambda), the
// sums of the forms).
#define PWCONTACT_TARGET sse2_shared_math_test
#include "kernels/contact_kernel.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "pwcontact/reference.hpp"
#include "screen/pair_prefilters.hpp"
#include "test_support.hpp"

namespace pwtest {
namespace {

namespace kernel = pwcontact::kernels::sse2_shared_math_test;
namespace detail = pwcontact::detail;
using Arch = xsimd::sse2;
using B = xsimd::batch<double, Arch>;
using Form = std::array<double, 6>;

// Two copies' values of one quantity, compared bit for bit.
void expect_same_bits(double kernel_value, double other_value, const std::string& what) {
  if (std::memcmp(&kernel_value, &other_value, sizeof(double)) == 0) return;
  ADD_FAILURE() << what << ": kernel " << std::hexfloat << kernel_value << ", other copy "
                << other_value;
}

double uniform(std::mt19937_64& engine, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(engine);
}

double random_power_of_two(std::mt19937_64& engine, int lo, int hi) {
  return std::ldexp(1.0, std::uniform_int_distribution<int>(lo, hi)(engine));
}

// A symmetric positive definite form whose pivots d0, d1, d2, as the
// reference path's Ldlt3 computes them, are powers of two: each pivot
// chosen, and the diagonal entry it comes from solved for, so that the
// rounded subtractions of eq. 38 give exactly that power (candidates that
// round otherwise are drawn again). The off-diagonal entries are random, and
// the pivots smaller than what cancels in them, as in forms of elongated
// shapes.
Form form_with_power_of_two_pivots(std::mt19937_64& engine) {
  for (;;) {
    Form a;
    a[0] = random_power_of_two(engine, -3, 3);
    const double scale = std::sqrt(a[0]);
    a[1] = uniform(engine, -2, 2) * scale;
    a[2] = uniform(engine, -2, 2) * scale;
    a[4] = uniform(engine, -2, 2);
    const double l10 = a[1] / a[0], l20 = a[2] / a[0];  // exact: a[0] is a power of two
    const double d1 = random_power_of_two(engine, -6, 2);
    a[3] = l10 * a[1] + d1;
    const double t = a[4] - l20 * a[1];
    const double d2 = random_power_of_two(engine, -6, 2);
    a[5] = l20 * a[2] + t / d1 * t + d2;
    const detail::Ldlt3<double> reference(a.data());
    if (reference.d0 == a[0] && reference.d1 == d1 && reference.d2 == d2) return a;
  }
}

// x with mu x + lambda y == target as both copies round it (eq. 10), if a
// few ulps around the real solution hold one.
std::optional<double> convex_preimage(double target, double mu, double lambda, double y) {
  double x = (target - lambda * y) / mu;
  for (int step = 0; step < 64; ++step) {
    const double value = mu * x + lambda * y;
    if (value == target) return x;
    x = std::nextafter(x, value < target ? HUGE_VAL : -HUGE_VAL);
  }
  return std::nullopt;
}

B broadcast(double x) { return B(x); }

void broadcast(const double* x, int n, B* out) {
  for (int k = 0; k < n; ++k) out[k] = B(x[k]);
}

// One pair in every lane.
kernel::PairLanes<B> lanes_of(const double r[3], const double q1[6], const double q2[6]) {
  kernel::PairLanes<B> lanes;
  broadcast(r, 3, lanes.r);
  broadcast(q1, 6, lanes.q1);
  broadcast(q2, 6, lanes.q2);
  return lanes;
}
kernel::PairLanes<B> lanes_of(const Pair<double>& p) {
  return lanes_of(p.r12.data(), p.q1.data(), p.q2.data());
}

TEST(SharedMath, FactorisationAgreesBitForBitWherePivotsArePowersOfTwo) {
  std::mt19937_64 engine(38);
  for (int i = 0; i < 20000; ++i) {
    const Form a = form_with_power_of_two_pivots(engine);
    B lanes[6];
    broadcast(a.data(), 6, lanes);
    const kernel::Ldlt<B> f = kernel::factor(lanes);
    const detail::Ldlt3<double> reference(a.data());
    const std::string what = "form " + std::to_string(i);
    expect_same_bits(f.d0.get(0), reference.d0, what + ", d0");
    expect_same_bits(f.d1.get(0), reference.d1, what + ", d1");
    expect_same_bits(f.d2.get(0), reference.d2, what + ", d2");
    expect_same_bits(f.l10.get(0), reference.l10, what + ", l10");
    expect_same_bits(f.l20.get(0), reference.l20, what + ", l20");
    expect_same_bits(f.l21.get(0), reference.l21, what + ", l21");
    if (HasFailure()) return;
  }
}

TEST(SharedMath, SolvesAndFormsAgreeBitForBitWherePivotsArePowersOfTwo) {
  std::mt19937_64 engine(39);
  for (int i = 0; i < 20000; ++i) {
    const Form a = form_with_power_of_two_pivots(engine);
    B lanes[6];
    broadcast(a.data(), 6, lanes);
    const kernel::Ldlt<B> f = kernel::factor(lanes);
    const detail::Ldlt3<double> reference(a.data());
    const double b[3] = {uniform(engine, -4, 4), uniform(engine, -4, 4), uniform(engine, -4, 4)};
    B b_lanes[3];
    broadcast(b, 3, b_lanes);
    const std::string what = "form " + std::to_string(i);

    // y = L^-1 b
    B y_lanes[3];
    kernel::forward(f, b_lanes, y_lanes);
    double y[3];
    reference.forward(b, y);
    for (int k = 0; k < 3; ++k) expect_same_bits(y_lanes[k].get(0), y[k], what + ", L^-1 b");

    // x = L^-T D^-1 y: the kernels' backward() scales by the reciprocal
    // pivots itself, the reference path's takes D^-1 y (formed in its
    // evaluate(), as here).
    B x_lanes[3];
    kernel::backward(f, y_lanes, x_lanes);
    const double z[3] = {y[0] / reference.d0, y[1] / reference.d1, y[2] / reference.d2};
    double x[3];
    reference.backward(z, x);
    for (int k = 0; k < 3; ++k) expect_same_bits(x_lanes[k].get(0), x[k], what + ", Q^-1 b");

    // b^T Q^-1 b, the slopes of eq. 16
    expect_same_bits(kernel::inverse_quadratic_form(f, b_lanes).get(0),
                     detail::inverse_quadratic_form(reference, b), what + ", b^T Q^-1 b");
    if (HasFailure()) return;
  }
}

// One evaluation (eqs. 10, 11, 17, 19) at a lambda where Q(lambda) = mu Q1 +
// lambda Q2, as both copies round it, is a form with power-of-two pivots:
// Q1 solved for entry by entry from that form and a random Q2.
TEST(SharedMath, EvaluationAgreesBitForBitWherePivotsArePowersOfTwo) {
  std::mt19937_64 engine(40);
  int evaluations = 0;
  while (evaluations < 20000) {
    const Form q = form_with_power_of_two_pivots(engine);
    const double lambda = uniform(engine, 0.05, 0.95), mu = 1 - lambda;
    // Q2 a positive definite form of about a tenth of Q's size.
    const Form shape = form_with_power_of_two_pivots(engine);
    Form q2, q1;
    for (int k = 0; k < 6; ++k) q2[k] = 0.1 * shape[k];
    bool found = true;
    for (int k = 0; k < 6 && found; ++k) {
      const std::optional<double> x = convex_preimage(q[k], mu, lambda, q2[k]);
      found = x.has_value();
      if (found) q1[k] = *x;
    }
    if (!found) continue;
    const detail::Ldlt3<double> q1_factor(q1.data());
    if (!(q1_factor.d0 > 0 && q1_factor.d1 > 0 && q1_factor.d2 > 0)) continue;  // Q1 not SPD
    const double r[3] = {uniform(engine, -3, 3), uniform(engine, -3, 3), uniform(engine, -3, 3)};

    const kernel::PairLanes<B> pair = lanes_of(r, q1.data(), q2.data());
    const kernel::Evaluation<B> e = kernel::evaluate(pair, broadcast(lambda));
    const detail::Residual<double> reference = detail::evaluate(r, q1.data(), q2.data(), lambda);
    const std::string what = "evaluation " + std::to_string(evaluations);
    for (int k = 0; k < 6; ++k) ASSERT_EQ(e.q[k].get(0), q[k]) << what << ": Q(lambda) as built";
    expect_same_bits(e.f.get(0), reference.f, what + ", f");
    expect_same_bits(e.g.get(0), reference.g, what + ", g");
    expect_same_bits(e.dg.get(0), reference.dg, what + ", g'");
    if (HasFailure()) return;
    ++evaluations;
  }
}

// Random pairs at scales k (r -> k r, Q -> k^2 Q) out to where products of
// Q's entries would overflow or underflow double.
std::vector<Pair<double>> pairs_at_scales(const std::vector<double>& factors) {
  std::vector<Pair<double>> out;
  const std::vector<Pair<double>> pairs = make_random_pairs(2000, 36);
  for (std::size_t i = 0; i < pairs.size(); ++i)
    out.push_back(scaled(pairs[i], factors[i % factors.size()]));
  return out;
}

const std::vector<double> normal_scales = {1e-150, 1e-100, 1e-30, 1e-3,  1,
                                           7,      1e3,    1e30,  1e100, 1e150};
// Q's entries ~1e-320, subnormal: the largest diagonal entry's exponent bits
// do not give its scale, and the kernels take a square root instead.
const std::vector<double> subnormal_scale = {1e-160};

// The kernels scale r and Q by t = 2^-floor(e/2) for the largest diagonal
// entry m 2^e (lane_blocks.hpp, nondimensionalise), so that it lands in
// [1, 4); the reference path scales Q by 2^(-2 q_exponent) into [1/4, 1)
// (ScaledPair: frexp of a square root) and r by a power of its own. Both are
// exact (eq. 36), and their exponents must be one apart: the kernels' Q is
// the reference path's times 4, bit for bit, and the kernels' r is r times t
// exactly. (The inputs' entries lie within a few decades of each other: none
// becomes subnormal when scaled, where a power-of-two scaling would round.)
void expect_scalings_agree(const std::vector<Pair<double>>& pairs) {
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair<double>& p = pairs[i];
    kernel::PairLanes<B> lanes = lanes_of(p);
    const double t = kernel::nondimensionalise(lanes, true).get(0);
    const detail::ScaledPair<double> reference(p.r12.data(), p.q1.data(), p.q2.data());
    const std::string what = "pair " + std::to_string(i);
    expect_same_bits(t, std::ldexp(1.0, 1 - reference.q_exponent), what + ", t");
    for (int k = 0; k < 6; ++k) {
      expect_same_bits(lanes.q1[k].get(0), std::ldexp(reference.q1[k], 2), what + ", Q1");
      expect_same_bits(lanes.q2[k].get(0), std::ldexp(reference.q2[k], 2), what + ", Q2");
    }
    for (int k = 0; k < 3; ++k)
      expect_same_bits(lanes.r[k].get(0), std::ldexp(p.r12[k], 1 - reference.q_exponent),
                       what + ", r");
    if (::testing::Test::HasFailure()) return;
  }
}

TEST(SharedMath, PowerOfTwoScalingsOfKernelsAndReferenceAgreeBitForBit) {
  expect_scalings_agree(pairs_at_scales(normal_scales));
}

// The moving scene's scalar certificates (screen::certify_overlap) take the
// kernels' arithmetic, reciprocal pivots included: their factorisation,
// evaluation and scaling are a third copy, held to the kernels' bit for bit
// on any positive definite forms (no power-of-two pivots needed here).
TEST(SharedMath, TheCertificatesFactorEvaluateAndScaleAsTheKernelsDoBitForBit) {
  namespace certificate = pwcontact::screen::certificate;
  const std::vector<Pair<double>> pairs = pairs_at_scales(normal_scales);
  std::mt19937_64 engine(45);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair<double>& p = pairs[i];
    const std::string what = "pair " + std::to_string(i);
    kernel::PairLanes<B> lanes = lanes_of(p);
    const double t = kernel::nondimensionalise(lanes, true).get(0);
    const double largest = std::max({p.q1[0], p.q1[3], p.q1[5], p.q2[0], p.q2[3], p.q2[5]});
    expect_same_bits(t, certificate::scale_to_unit(largest), what + ", t");
    double r[3], q1[6], q2[6];
    for (int k = 0; k < 3; ++k) r[k] = lanes.r[k].get(0);
    for (int k = 0; k < 6; ++k) q1[k] = lanes.q1[k].get(0), q2[k] = lanes.q2[k].get(0);
    const kernel::Ldlt<B> f = kernel::factor(lanes.q1);
    const certificate::Factors c(q1);
    const double kernel_values[9] = {f.d0.get(0),     f.d1.get(0),     f.d2.get(0),
                                     f.inv_d0.get(0), f.inv_d1.get(0), f.inv_d2.get(0),
                                     f.l10.get(0),    f.l20.get(0),    f.l21.get(0)};
    const double certificate_values[9] = {c.d0,     c.d1,  c.d2,  c.inv_d0, c.inv_d1,
                                          c.inv_d2, c.l10, c.l20, c.l21};
    for (int k = 0; k < 9; ++k)
      expect_same_bits(kernel_values[k], certificate_values[k],
                       what + ", factor entry " + std::to_string(k));
    const double lambda = uniform(engine, 0.02, 0.98);
    const kernel::Evaluation<B> e = kernel::evaluate(lanes, broadcast(lambda));
    const certificate::Evaluation at = certificate::evaluate(r, q1, q2, lambda);
    expect_same_bits(e.f.get(0), at.f, what + ", f");
    expect_same_bits(e.g.get(0), at.g, what + ", g");
    expect_same_bits(e.dg.get(0), at.dg, what + ", g'");
    if (HasFailure()) return;
  }
}

// Not so where Q's largest diagonal entry is subnormal: the kernels' t is
// the reference path's (the check of t passes), but t^2 >= 2^1024 overflows,
// so the kernels' scaled Q is infinite; the lane then fails the kernels'
// finiteness test (LaneGroups::usable) and goes to the reference path,
// which answers it. Scaling Q by t twice would let the kernels keep such
// lanes, and move their answers from the reference path to the kernels:
// left for a decision, and disabled until then (it fails as things stand).
TEST(SharedMath, DISABLED_SubnormalDiagonalsAreScaledAsTheReferencePathScalesThem) {
  expect_scalings_agree(pairs_at_scales(subnormal_scale));
}

// The kernels' other copy of the scaling, the scalar one that packs the lanes
// a first pass left unfinished (contact_kernel.hpp, pack_unfinished: frexp
// of a square root), gives the pair and t that loading them into registers
// gave (load_pairs: nondimensionalise), bit for bit: double lanes beyond the
// safe range, and float lanes on double pairs (always scaled, then rounded).
template <class T>
void expect_packed_lanes_scaled_as_loaded(const std::vector<Pair<double>>& pairs) {
  using Lanes = xsimd::batch<T, Arch>;
  constexpr std::size_t width = Lanes::size;
  const std::size_t n = pairs.size() / width * width;
  std::vector<double> columns[kernel::pair_components];
  for (auto& column : columns) column.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) columns[k][i] = pairs[i].r12[k];
    for (int k = 0; k < 6; ++k) {
      columns[3 + k][i] = pairs[i].q1[k];
      columns[9 + k][i] = pairs[i].q2[k];
    }
  }
  pwcontact::kernels::PairSpan<double> span{};
  for (int k = 0; k < 3; ++k) span.r12[k] = columns[k].data();
  for (int k = 0; k < 6; ++k) {
    span.q1[k] = columns[3 + k].data();
    span.q2[k] = columns[9 + k].data();
  }

  // Every lane left unfinished, at lambda 1/2 in [0, 1].
  const std::vector<pwcontact::Status> status(n, pwcontact::kernels::needs_fallback);
  std::vector<T> lambda(n, T(0.5)), lo(n, T(0)), hi(n, T(1));
  const std::size_t bytes = pwcontact::kernels::scratch_bytes(n);
  const std::unique_ptr<void, decltype(&std::free)> memory(std::aligned_alloc(64, bytes),
                                                           &std::free);
  const pwcontact::kernels::Scratch scratch{memory.get(), n};
  kernel::FullKept<T> kept(scratch);
  kernel::pack_unfinished<Arch>(span, n, status.data(), {lambda.data(), lo.data(), hi.data()},
                                kept);
  ASSERT_EQ(kept.count, n);

  std::size_t compared = 0;
  for (std::size_t i = 0; i < n; i += width) {
    kernel::PairLanes<Lanes> loaded;
    Lanes t;
    kernel::load_pairs<Arch, T, double>(span, i, loaded, t);
    for (std::size_t l = 0; l < width; ++l) {
      // Only lanes the kernels keep are ever packed: not a float lane beyond
      // float's range (marked by t = 0), nor one whose scaled Q overflowed
      // (a subnormal diagonal, see above); both go to the reference path.
      bool kept_lane = t.get(l) > T(0) && t.get(l) < std::numeric_limits<T>::infinity();
      for (int k = 0; k < kernel::pair_components; ++k)
        kept_lane = kept_lane && std::isfinite(kernel::component(loaded, k).get(l));
      if (!kept_lane) continue;
      ++compared;
      const std::size_t c = i + l;
      ASSERT_EQ(kept.index[c], c);
      const std::string what = "pair " + std::to_string(c);
      // (Compared as doubles: a float widens exactly, bits and all.)
      expect_same_bits(kept.values[kernel::full_scale][c], t.get(l), what + ", t");
      for (int k = 0; k < kernel::pair_components; ++k)
        expect_same_bits(kept.values[k][c], kernel::component(loaded, k).get(l),
                         what + ", component " + std::to_string(k));
    }
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GT(compared, n / 2);
}

std::vector<Pair<double>> pairs_at_every_scale() {
  std::vector<double> factors = normal_scales;
  factors.insert(factors.end(), subnormal_scale.begin(), subnormal_scale.end());
  return pairs_at_scales(factors);
}

TEST(SharedMath, PackedLanesAreScaledAsLoadedLanesInDouble) {
  std::vector<Pair<double>> outside;  // only lanes beyond the safe range are scaled in double
  for (const Pair<double>& p : pairs_at_every_scale()) {
    const double largest = std::max({p.q1[0], p.q1[3], p.q1[5], p.q2[0], p.q2[3], p.q2[5]});
    if (largest < 0x1p-100 || largest > 0x1p100) outside.push_back(p);
  }
  ASSERT_GT(outside.size(), 500u);
  expect_packed_lanes_scaled_as_loaded<double>(outside);
}

TEST(SharedMath, PackedLanesAreScaledAsLoadedLanesInFloat) {
  // Float lanes take only pairs whose scaled numbers float holds (in_range):
  // the scale of the pair does not matter, its spread does.
  expect_packed_lanes_scaled_as_loaded<float>(pairs_at_every_scale());
}

// The polynomial form of the contact function (doc/theory.md eq. 46), which
// the full kernel's cold first pass steps on before its first factorised
// evaluation, against the quad-precision table: its steps from the radial
// guess converge to lambda*, and the radial guess is exact for spheres. The
// random and pw85 families are conditioned to 1e1 and 2.5e5: lambda* to
// 1e-12 and 1e-8 of its distance to 0 or 1 (the coefficients carry the
// cofactors' rounding, ~eps cond, and the maximiser of a flat f moves by
// more than the rounding of f; the answer never comes from this form).
// The random family must settle within the steps the kernel takes at most
// before its factorised check (3 with lambda asked for, and
// polynomial_extra_steps; the test takes them all, without the kernel's stop
// for a lane that has settled); pw85 pairs the
// kernel leaves unsettled go on in factorised passes (measured: 48 of its
// 1,000 here after 9 steps, none after 24), so there the form is held to
// lambda* after 24 steps, and most pairs to the kernel's 9.
TEST(SharedMath, PolynomialStepsConvergeToTheOraclesLambda) {
  const pwtest::ReferenceTable table = pwtest::load_reference_pairs();
  ASSERT_TRUE(table.error.empty()) << table.error;
  int checked = 0, pw85_settled_in_kernel = 0;
  for (const pwtest::ReferenceRecord& record : table.records) {
    const bool random = record.family == "random";
    if (!random && record.family != "pw85") continue;
    const Pair<double>& pair = record.pair;
    const kernel::PairLanes<B> p = lanes_of(pair);
    const kernel::Adjugate<B> a1(p.q1), a2(p.q2);
    const kernel::ContactPolynomials<B> polynomials(p.r, p.q1, p.q2, a1, a2);
    const double expected = double(record.lambda);
    const double width = std::min(expected, 1 - expected);
    const double tolerance = (random ? 1e-12 : 1e-8) * width;
    B lambda = polynomials.radial_guess(), lo(0), hi(1);
    const int in_kernel = 3 + kernel::polynomial_extra_steps;
    for (int step = 0; step < (random ? in_kernel : 24); ++step) {
      polynomials.step(lambda, lo, hi);
      if (!random && step + 1 == in_kernel && std::abs(lambda.get(0) - expected) <= tolerance)
        ++pw85_settled_in_kernel;
    }
    EXPECT_NEAR(lambda.get(0), expected, tolerance)
        << record.family << " pair " << checked << ": mu^2 " << double(record.mu2);
    ++checked;
  }
  std::printf("[ measured ] pw85 pairs settled within the kernel's %d steps: %d of 1000\n",
              3 + kernel::polynomial_extra_steps, pw85_settled_in_kernel);
  EXPECT_GE(pw85_settled_in_kernel, 900);
  EXPECT_EQ(checked, 2000);
  // Spheres of radii a and b: lambda* = a / (a + b) from the guess alone.
  for (const auto& [a, b] : {std::pair{1.0, 2.0}, std::pair{0.3, 7.0}, std::pair{5.0, 5.0}}) {
    const double r[3] = {0.3, -1.1, 2.0};
    const Form q1{a * a, 0, 0, a * a, 0, a * a}, q2{b * b, 0, 0, b * b, 0, b * b};
    const kernel::PairLanes<B> p = lanes_of(r, q1.data(), q2.data());
    const kernel::Adjugate<B> a1(p.q1), a2(p.q2);
    const kernel::ContactPolynomials<B> polynomials(p.r, p.q1, p.q2, a1, a2);
    EXPECT_NEAR(polynomials.radial_guess().get(0), a / (a + b), 4e-16) << a << ", " << b;
  }
}

// The start of the cold steps where a form is elongated (contact_kernel.hpp,
// polynomial_elongated and polynomial_starts), on the pw85 pairs of the
// quad-precision table: the start ContactPolynomials::largest_of picks has
// the largest f of the radial guess and the fixed starts by f evaluated in
// long double from the pair (up to the polynomial form's own rounding:
// starts whose f differ by less than 1e-9 f are not told apart), and from it
// the kernel's steps (three, then up to polynomial_extra_steps while a lane
// still moves by more than polynomial_settled of its width) leave fewer
// pairs more than 2^-20 of their width from lambda* (each of those a later
// factorised pass) than from the radial guess.
TEST(SharedMath, ElongatedPairsStartWhereFIsLargest) {
  const pwtest::ReferenceTable table = pwtest::load_reference_pairs();
  ASSERT_TRUE(table.error.empty()) << table.error;
  int elongated = 0, off_from_radial = 0, off_from_start = 0;
  for (const pwtest::ReferenceRecord& record : table.records) {
    if (record.family != "pw85") continue;
    const Pair<double>& pair = record.pair;
    const kernel::PairLanes<B> p = lanes_of(pair);
    const kernel::Adjugate<B> a1(p.q1), a2(p.q2);
    auto beyond = [](const Form& q, const B& det) {
      const double t = q[0] + q[3] + q[5];
      return t * t * t > kernel::polynomial_elongated * det.get(0);
    };
    if (!beyond(pair.q1, a1.det) && !beyond(pair.q2, a2.det)) continue;
    ++elongated;
    const kernel::ContactPolynomials<B> polynomials(p.r, p.q1, p.q2, a1, a2);
    const B radial = polynomials.radial_guess();
    const B start = polynomials.largest_of(radial, kernel::polynomial_starts);
    auto f = [&](long double lambda) {
      std::array<long double, 6> q;
      std::array<long double, 3> r;
      for (int k = 0; k < 6; ++k) q[k] = (1 - lambda) * pair.q1[k] + lambda * pair.q2[k];
      for (int k = 0; k < 3; ++k) r[k] = pair.r12[k];
      return lambda * (1 - lambda) *
             detail::inverse_quadratic_form(detail::Ldlt3<long double>(q.data()), r.data());
    };
    const long double f_start = f(start.get(0));
    EXPECT_GE(f_start, f(radial.get(0)) * (1 - 1e-9L)) << "pw85 pair " << elongated;
    for (double fixed : kernel::polynomial_starts)
      EXPECT_GE(f_start, f(fixed) * (1 - 1e-9L)) << "pw85 pair " << elongated << ", " << fixed;
    const double expected = double(record.lambda);
    const double width = std::min(expected, 1 - expected);
    auto off_after_steps = [&](B lambda) {
      B lo(0), hi(1), moved(0);
      for (int step = 0; step < 3; ++step) moved = polynomials.step(lambda, lo, hi);
      for (int step = 0; step < kernel::polynomial_extra_steps; ++step) {
        const double l = lambda.get(0);
        if (!(moved.get(0) > kernel::polynomial_settled * std::min(l, 1 - l))) break;
        moved = polynomials.step(lambda, lo, hi);
      }
      return !(std::abs(lambda.get(0) - expected) <= 0x1p-20 * width);
    };
    off_from_radial += off_after_steps(radial);
    off_from_start += off_after_steps(start);
  }
  std::printf(
      "[ measured ] elongated pw85 pairs: %d; more than 2^-20 of their width from lambda* after "
      "the steps: %d from the radial guess, %d from the start\n",
      elongated, off_from_radial, off_from_start);
  EXPECT_GE(elongated, 500);
  EXPECT_LE(2 * off_from_start, off_from_radial);
}

}  // namespace
}  // namespace pwtest
