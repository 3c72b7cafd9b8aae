// Shared machinery of the test suite: pairs in the scalar layout, the
// high-precision oracle, batch calls with their outputs, error statistics,
// the quad-precision reference data, and geometric transformations of a pair.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <ostream>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include "fixtures/families.hpp"
#include "pwcontact/pwcontact.hpp"

namespace pwcontact {
// Readable parameter values in test names and messages.
inline void PrintTo(Isa isa, std::ostream* os) { *os << isa_name(isa); }
inline void PrintTo(Status status, std::ostream* os) { *os << status_name(status); }
inline void PrintTo(Precision precision, std::ostream* os) { *os << precision_name(precision); }
inline void PrintTo(Formulation formulation, std::ostream* os) {
  *os << formulation_name(formulation);
}
}  // namespace pwcontact

namespace pwtest {

using pwcontact::BatchOptions;
using pwcontact::BatchReport;
using pwcontact::ContactResult;
using pwcontact::Isa;
using pwcontact::PairBatch;
using pwcontact::Status;

// ---------------------------------------------------------------------------
// One pair in the scalar layout: r12 = c2 - c1, Q1 and Q2 as 6 numbers each.

template <class T>
struct Pair {
  std::array<T, 3> r12{};
  std::array<T, 6> q1{};
  std::array<T, 6> q2{};
};

template <class T>
Pair<T> pair_at(const PairBatch<T>& batch, std::size_t i) {
  Pair<T> p;
  batch.get(i, p.r12.data(), p.q1.data(), p.q2.data());
  return p;
}

// Element-wise conversion (rounding when To is narrower).
template <class To, class From>
Pair<To> convert(const Pair<From>& p) {
  Pair<To> out;
  for (int k = 0; k < 3; ++k) out.r12[k] = To(p.r12[k]);
  for (int k = 0; k < 6; ++k) {
    out.q1[k] = To(p.q1[k]);
    out.q2[k] = To(p.q2[k]);
  }
  return out;
}

// A batch whose arrays have exactly pairs.size() elements, so that a read or
// write past the end is a heap overflow that AddressSanitizer reports.
template <class T>
PairBatch<T> make_batch(const std::vector<Pair<T>>& pairs) {
  PairBatch<T> batch(pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i)
    batch.set(i, pairs[i].r12.data(), pairs[i].q1.data(), pairs[i].q2.data());
  return batch;
}

template <class To, class From>
std::vector<Pair<To>> convert_all(const std::vector<Pair<From>>& pairs) {
  std::vector<Pair<To>> out;
  out.reserve(pairs.size());
  for (const auto& p : pairs) out.push_back(convert<To>(p));
  return out;
}

template <class T>
std::vector<Pair<T>> pairs_of(const PairBatch<T>& batch) {
  std::vector<Pair<T>> out(batch.size());
  for (std::size_t i = 0; i < batch.size(); ++i) out[i] = pair_at(batch, i);
  return out;
}

// Random pairs of the benchmark's random family (semi-axes in [0.5, 2],
// distance in [0, 6]), or any other RandomFamily.
std::vector<Pair<double>> make_random_pairs(std::size_t n, std::uint64_t seed,
                                            const pwcontact::RandomFamily& family = {});

// ---------------------------------------------------------------------------
// The scalar reference path, and the same template in higher precision as the oracle.

template <class T>
ContactResult<T> reference(const Pair<T>& p, const pwcontact::ReferenceOptions& options = {}) {
  return pwcontact::contact_function<T>(p.r12.data(), p.q1.data(), p.q2.data(), options);
}

// The inputs are taken as exact and widened to long double (64-bit mantissa,
// 11 more bits than double).
ContactResult<long double> long_double_oracle(const Pair<double>& p);

// Per pair, in OpenMP threads: the double reference on the pairs widened to
// double (exactly), and the long double oracle.
template <class T>
std::vector<ContactResult<double>> double_references(const std::vector<Pair<T>>& pairs);
std::vector<ContactResult<long double>> long_double_oracles(const std::vector<Pair<double>>& pairs);

// The same template in 50 decimal digits (Boost.Multiprecision
// cpp_bin_float_50), where long double is not enough: for very
// ill-conditioned pairs, or to know mu^2 to far better than 1e-14. The
// results are rounded to long double. Per pair, in OpenMP threads (~0.1 ms
// per pair).
std::vector<ContactResult<long double>> fifty_digit_oracles(const std::vector<Pair<double>>& pairs);

// ---------------------------------------------------------------------------
// Pairs at a chosen mu^2

// The pair with r12 scaled by sqrt(target / mu2), mu2 being its exact
// contact function: mu^2 is homogeneous of degree 2 in r12, so the new pair's
// mu^2 is the target, up to the rounding of r12 to double (~1e-16 relative).
// The scale factor is computed in long double (pwcontact::scale_to_mu2 and
// scale_r12, fixtures/families.hpp).
Pair<double> scaled_to_mu2(const Pair<double>& p, long double mu2, long double target);

// Pairs built at a known relative distance from tangency at a cutoff c:
// mu^2 = c^2 (1 + offset) with |offset| = 1e-3, 1e-4, ..., 1e-14, both signs.
enum class TangentKind {
  spheres,            // radii 1e-3 to 7, size ratios to 1e3: mu = |r| / (a1 + a2)
  coaxial_spheroids,  // aspect ratios to 10, r12 along the common axis: mu = |r| / (c1 + c2)
  general,            // random family shapes (semi-axes in [0.5, 2]), random direction
  elongated,          // semi-axes log-uniform in [0.1, 10] (aspect ratios to 100)
};
const char* tangent_kind_name(TangentKind kind);
// Spheres, coaxial spheroids and general pairs are well conditioned (cond(Q) <= 100).
constexpr bool well_conditioned(TangentKind kind) { return kind != TangentKind::elongated; }

struct NearTangent {
  Pair<double> pair;
  long double mu2;  // exact for the stored inputs, to ~1e-19 relative
  double offset;    // the nominal mu^2 / c^2 - 1 it was built for
  TangentKind kind;
};

// The closed-form kinds take mu^2 from their closed form, the others from
// the 50-digit oracle, both evaluated on the stored double inputs, so that
// the rounding of the inputs is accounted for exactly.
std::vector<NearTangent> near_tangent_pairs(double cutoff = 1);

// ---------------------------------------------------------------------------
// Batch calls

// The optional outputs a batch call asks for (mu2 is always asked for).
struct Requested {
  bool lambda = true;
  bool status = true;
  bool contact_point = false;
  bool normal = false;
  bool gradient = false;

  bool any_geometry() const { return contact_point || normal || gradient; }
  static Requested mu2_only() { return {false, false, false, false, false}; }
  static Requested everything() { return {true, true, true, true, true}; }
};

// "mu2+lambda+status+contact_point+...", to name a request in messages.
std::string describe(const Requested& requested);

// A three-component output, one array per component.
template <class T>
using Components = std::array<std::vector<T>, 3>;

// What a batch call wrote. Arrays that were not asked for are empty.
template <class T>
struct BatchRun {
  std::vector<T> mu2, lambda;
  std::vector<Status> status;
  Components<T> contact_point, normal, gradient;
  BatchReport report;
};

// Calls the batch path with outputs of exactly pairs.size() elements framed by
// guard values, and fails the current test if any guard was overwritten.
template <class T>
BatchRun<T> run_batch(const PairBatch<T>& pairs, const BatchOptions& options = {},
                      const Requested& requested = {});

// The outputs of the listed lanes, in that order.
template <class T>
BatchRun<T> select_lanes(const BatchRun<T>& run, const std::vector<std::size_t>& lanes);

// Appends the lanes of every output array of `from` to those of `to`
// (reports are not merged).
template <class T>
void append_lanes(BatchRun<T>& to, const BatchRun<T>& from);

// The same bits in mu2 and in every output array that both runs have; on
// failure names the first lane that differs and how many do. `what` names
// the comparison.
template <class T>
void expect_bitwise_equal(const BatchRun<T>& a, const BatchRun<T>& b, const std::string& what);

// What an overlap-only call wrote (status empty when it was not asked for).
struct OverlapRun {
  std::vector<std::uint8_t> overlap;
  std::vector<Status> status;
  BatchReport report;
};

// overlap_batch with guarded outputs, as run_batch.
template <class T>
OverlapRun run_overlap(const PairBatch<T>& pairs, const BatchOptions& options = {},
                       double cutoff = 1, bool with_status = true);

BatchOptions with_isa(Isa isa, int iterations = 0, int threads = 0);
// The same options with another precision (and formulation, and accuracy).
BatchOptions with_precision(BatchOptions options, pwcontact::Precision precision,
                            pwcontact::Formulation formulation = pwcontact::Formulation::automatic,
                            pwcontact::Accuracy accuracy = pwcontact::Accuracy::standard);

template <class T>
constexpr bool single_precision = std::is_same_v<T, float>;

// "what, isa, precision", to name a case in messages.
template <class T>
std::string label(const std::string& what, Isa isa) {
  return what + ", " + pwcontact::isa_name(isa) + ", " + (single_precision<T> ? "float" : "double");
}

// Every supported instruction set as a test parameter, with readable names.
std::vector<Isa> isas();
std::string isa_param_name(const ::testing::TestParamInfo<Isa>& info);

// ---------------------------------------------------------------------------
// Errors

// |got - expected| / |expected|; |got| when expected is 0; infinite when got
// is NaN, so that a NaN can never pass a tolerance.
double relative_error(long double got, long double expected);
// |got - expected|, infinite when either is NaN.
double absolute_error(long double got, long double expected);

// The largest error seen and where.
struct MaxError {
  double value = 0;
  std::size_t index = 0;
  std::size_t count = 0;
  void add(std::size_t i, double error);
};

// Prints a measured figure so that the suite's log documents the accuracy.
void print_measured(const std::string& what, const MaxError& error);

// How far a batch lane may be from the scalar reference path run in double on
// the same inputs (for float lanes: the float inputs, widened exactly).
template <class T>
struct LaneTolerance;
template <>
struct LaneTolerance<double> {
  // The promised accuracy of the batch path on random pairs (semi-axes in
  // [0.5, 2]); converged lanes and the reference differ by a few eps
  // (measured 1.1e-15).
  static constexpr double mu2 = 1e-13;
  // lambda is pinned down less sharply than mu2 (mu2 is stationary in it);
  // measured 7e-16, and ~1e3 times that still rejects any lane mix-up.
  static constexpr double lambda = 1e-12;
  // Between mu2 computed alone and mu2 computed with lambda (or any geometric
  // output), whose convergence checks differ (batch.hpp): both are converged
  // to the double floor (measured up to 1.1e-15 from the reference), so 4e-15
  // (18 eps) bounds their difference. Measured: 9.1e-16 (sse2), 8.1e-16
  // (avx2, avx512).
  static constexpr double mu2_alone = 4e-15;
  // The contact point, normal and gradient against the reference path's at
  // its lambda, relative to each vector's length: they are computed at the
  // lane's lambda, within ~1e-12 of the maximiser (batch.hpp; measured 1e-13
  // on this family), and move by O(1) times that: 1e-11 allows for a
  // derivative of 10. Measured over every precision but float, iteration
  // count and instruction set: 2.0e-13 (contact point), 5.8e-14 (normal),
  // 1.1e-13 (gradient).
  static constexpr double geometry = 1e-11;
};
template <>
struct LaneTolerance<float> {
  // The float floor on this family is ~5e-7 (f evaluated in float at the
  // exact lambda; measured here up to 4.6e-7 over 20000 lanes); the kernel's
  // element-growth check sends lanes that would lose more to the double
  // fallback. 4e-6 (~34 float eps) leaves a margin of 8 over the floor and
  // stays below the promised 1e-5.
  static constexpr double mu2 = 4e-6;
  // Measured 4e-7; the margin is the same as for mu2.
  static constexpr double lambda = 4e-6;
  // Both answers lie within the float floor of the exact answer for the float
  // inputs (measured up to 5.2e-7 from the reference), so they differ by up
  // to twice that, ~1e-6. Measured: 6.2e-7 (sse2), 4.3e-7 (avx2, avx512);
  // 2e-6 leaves a factor 3.
  static constexpr double mu2_alone = 2e-6;
  // Float lanes: lambda within ~1.5e-7 (measured) and the float floor of the
  // solve, ~5e-7. Measured: 7.3e-7 (contact point), 2.8e-7 (normal), 3.5e-7
  // (gradient); 1e-5 (the float accuracy promised for mu2 on this family)
  // leaves a factor ~14.
  static constexpr double geometry = 1e-5;
};

// Three-component outputs, in long double for comparisons.
using Vector3L = Eigen::Matrix<long double, 3, 1>;

template <class T>
Vector3L lane_vector(const Components<T>& v, std::size_t i) {
  return {v[0][i], v[1][i], v[2][i]};
}

template <class T>
Vector3L as_vector(const T (&v)[3]) {
  return {v[0], v[1], v[2]};
}

// |got - expected| / |expected| (|got - expected| when expected is 0);
// infinite when either has a NaN.
double vector_error(const Vector3L& got, const Vector3L& expected);

// The reference path's contact_geometry at its own lambda, per pair (float
// pairs widened exactly); references[i] must be valid.
template <class T>
std::vector<pwcontact::ContactGeometry<double>> reference_geometries(
    const std::vector<Pair<T>>& pairs, const std::vector<ContactResult<double>>& references);

// Every geometric output `run` has (and a valid status in every lane),
// lane by lane against `expected`, within `tolerance` relative to each
// vector's length; prints the largest errors. `what` names the case.
template <class T>
void expect_geometry_matches(const BatchRun<T>& run,
                             const std::vector<pwcontact::ContactGeometry<double>>& expected,
                             double tolerance, const std::string& what);

struct LaneErrors {
  MaxError mu2, lambda;
};

// LaneTolerance<T> as values, to choose between them at run time.
struct Tolerances {
  double mu2, lambda, geometry;
};

template <class T>
Tolerances tolerances_of() {
  return {LaneTolerance<T>::mu2, LaneTolerance<T>::lambda, LaneTolerance<T>::geometry};
}

// Those of lanes that iterate in `precision`: float's in single precision,
// whatever the type of the pairs (they are rounded to float), else double's.
Tolerances tolerances_for(pwcontact::Precision precision);

// Every lane i: a valid status, mu2[i] and lambda[i] (when asked for) within
// the tolerances of references[i]. `label` names the case in failure messages.
template <class T>
LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>& references,
                                        const BatchRun<T>& run, const std::string& label,
                                        const Tolerances& tolerances = tolerances_of<T>());

// ---------------------------------------------------------------------------
// The independent quad-precision reference values (PWCONTACT_REFERENCE_PAIRS)

struct ReferenceRecord {
  std::string family;
  Pair<double> pair;
  long double mu2 = 0;
  long double lambda = 0;
};

struct ReferenceTable {
  std::vector<ReferenceRecord> records;
  std::string error;  // empty when the file was read completely
};

ReferenceTable load_reference_pairs(const std::string& path = PWCONTACT_REFERENCE_PAIRS);

// ---------------------------------------------------------------------------
// Geometry of a pair

Eigen::Matrix3d unpack(const std::array<double, 6>& q);
std::array<double, 6> pack(const Eigen::Matrix3d& m);

// Haar-uniform rotation from a seeded engine (reproducible on every platform).
Eigen::Matrix3d random_rotation(std::mt19937_64& engine);

// The whole pair rotated: r -> R r, Q -> R Q R^T.
Pair<double> rotated(const Pair<double>& p, const Eigen::Matrix3d& rotation);
// The whole pair scaled: r -> k r, Q -> k^2 Q.
Pair<double> scaled(const Pair<double>& p, double k);
// The two ellipsoids exchanged: Q1 <-> Q2 and r12 -> -r12.
Pair<double> swapped(const Pair<double>& p);

// Random numbers that are the same on every platform (std:: distributions
// are not).
using Engine = std::mt19937_64;
// Uniform in [0, 1) (the fixtures' own).
using pwcontact::uniform01;
// Uniform in [0.5, 2]: a semi-axis of the random family.
double ordinary_axis(Engine& engine);
// Semi-axes a along the axes of a rotation (a random one from the engine).
pwcontact::QuadraticForm oriented(const std::array<double, 3>& a, const Eigen::Matrix3d& rotation);
pwcontact::QuadraticForm oriented(const std::array<double, 3>& a, Engine& engine);
// A random shape of the random family, its semi-axes multiplied by `size`.
pwcontact::QuadraticForm ordinary_shape(Engine& engine, double size = 1);

// The condition number of Q(lambda) = (1 - lambda) Q1 + lambda Q2 (eq. 10)
// in long double, infinite where it is not positive definite: at the exact
// maximiser, what bounds the accuracy of any solve in floating point.
double condition_at(const Pair<double>& p, long double lambda);

// Pairs with their exact answers (the 50-digit oracle) and the condition of
// Q(lambda*) at them (infinite where the oracle has no answer).
struct Solved {
  std::vector<Pair<double>> pairs;
  std::vector<ContactResult<long double>> exact;
  std::vector<double> condition;
};
Solved solved(std::vector<Pair<double>> pairs);

// A pair from its centre separation and two quadratic forms.
Pair<double> make_pair(const std::array<double, 3>& r, const pwcontact::QuadraticForm& q1,
                       const pwcontact::QuadraticForm& q2);

// ---------------------------------------------------------------------------
// Environment

// Whether calls that leave the instruction set automatic run on the portable
// target (a build without the x86 kernels, or PWCONTACT_ISA=fallback), which
// answers every pair on the reference path: status ok_fallback, no kernel
// evaluations. Tests of what the x86 kernels themselves report skip there.
bool on_portable_target();

// Sets (or with nullopt unsets) an environment variable for the lifetime of
// the object and restores the previous state afterwards (and has the
// library read PWCONTACT_ISA again).
class ScopedEnvironment {
 public:
  ScopedEnvironment(std::string name, std::optional<std::string> value);
  ~ScopedEnvironment();
  ScopedEnvironment(const ScopedEnvironment&) = delete;
  ScopedEnvironment& operator=(const ScopedEnvironment&) = delete;

 private:
  std::string name_;
  std::optional<std::string> previous_;
};

}  // namespace pwtest
