// The optional outputs of the batch path, on every instruction set: the
// contact point, the common normal and the gradient, against the reference
// path's geometry at its lambda, against a finite difference of mu^2, and
// against the geometric identities of the theory (eqs. 8, 9, 14). Asking for
// one output must not change what the others receive.
#include <cmath>
#include <stdexcept>

#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::ContactOutputs;
using pwcontact::Formulation;
using pwcontact::Precision;
using MatrixL = Eigen::Matrix<long double, 3, 3>;

class Outputs : public ::testing::TestWithParam<Isa> {};
INSTANTIATE_TEST_SUITE_P(EverySupportedIsa, Outputs, ::testing::ValuesIn(isas()), isa_param_name);

// Every combination of lambda and the three geometric outputs (with status).
std::vector<Requested> every_request() {
  std::vector<Requested> out;
  for (unsigned bits = 0; bits < 16; ++bits)
    out.push_back({(bits & 1) != 0, true, (bits & 2) != 0, (bits & 4) != 0, (bits & 8) != 0});
  return out;
}

// Every combination of outputs on the same pairs: each geometric output
// matches the reference; whatever asks for at least one output gets the
// same bits in every array as the call that asks for everything (the
// outputs are computed from the same lanes); mu2 alone differs from that at
// most by the documented effect of its looser convergence check.
template <class T>
void expect_every_request_consistent(Isa isa) {
  const auto pairs = convert_all<T>(make_random_pairs(2000, 71));
  const PairBatch<T> batch = make_batch(pairs);
  const auto references = double_references(pairs);
  const BatchRun<T> everything = run_batch(batch, with_isa(isa), Requested::everything());
  expect_geometry_matches(everything, reference_geometries(pairs, references),
                          LaneTolerance<T>::geometry, label<T>("everything", isa));
  for (const Requested& requested : every_request()) {
    const std::string what = label<T>(describe(requested) + " vs everything", isa);
    const BatchRun<T> run = run_batch(batch, with_isa(isa), requested);
    if (requested.lambda || requested.any_geometry()) {
      expect_bitwise_equal(run, everything, what);
      continue;
    }
    MaxError difference;
    for (std::size_t i = 0; i < pairs.size(); ++i)
      difference.add(i, relative_error(run.mu2[i], everything.mu2[i]));
    EXPECT_LE(difference.value, LaneTolerance<T>::mu2_alone)
        << what << ", lane " << difference.index;
  }
}

TEST_P(Outputs, EveryCombinationMatchesTheReferenceAndLeavesTheOthersAloneInDouble) {
  expect_every_request_consistent<double>(GetParam());
}

TEST_P(Outputs, EveryCombinationMatchesTheReferenceAndLeavesTheOthersAloneInFloat) {
  expect_every_request_consistent<float>(GetParam());
}

// Every formulation and precision, with fixed and automatic iterations:
// lanes finished by the kernels in any pass, lanes that go on iterating
// after they converged (a fixed count of 5) and lanes finished by the
// reference path (2) all give the reference geometry.
TEST_P(Outputs, EveryFormulationPrecisionAndIterationCountGivesTheReferenceGeometry) {
  const auto pairs = make_random_pairs(2000, 72);
  const auto expected = reference_geometries(pairs, double_references(pairs));
  for (Formulation formulation : {Formulation::newton, Formulation::log_odds})
    for (Precision precision :
         {Precision::double_precision, Precision::mixed, Precision::single_precision})
      for (int iterations : {0, 2, 5}) {
        const BatchRun<double> run =
            run_batch(make_batch(pairs),
                      with_precision(with_isa(GetParam(), iterations), precision, formulation),
                      Requested::everything());
        expect_geometry_matches(
            run, expected, tolerances_for(precision).geometry,
            label<double>(std::string(pwcontact::formulation_name(formulation)) + " " +
                              pwcontact::precision_name(precision) + " iterations " +
                              std::to_string(iterations),
                          GetParam()));
      }
}

// ---------------------------------------------------------------------------
// The gradient against a central difference of mu^2 in r12, the oracle
// evaluating mu^2 in long double at r12 +- h e_k (exact in long double).

// mu^2 is homogeneous of degree 2 in r12, so its third derivatives scale as
// mu^2 / |r|^3: with h = 1e-6 |r| the truncation error is ~h^2 / |r|^2 =
// 1e-12 relative to the gradient (~mu^2 / |r|), and the oracle's rounding
// (~1e-18 relative) contributes ~1e-18 |r| / h = 1e-12.
constexpr long double relative_step = 1e-6L;

Vector3L central_difference(const Pair<double>& p) {
  const Pair<long double> base = convert<long double>(p);
  const long double h =
      relative_step *
      std::sqrt(base.r12[0] * base.r12[0] + base.r12[1] * base.r12[1] + base.r12[2] * base.r12[2]);
  Vector3L out;
  for (int k = 0; k < 3; ++k) {
    Pair<long double> forward = base, backward = base;
    forward.r12[k] += h;
    backward.r12[k] -= h;
    out[k] = (reference(forward).mu2 - reference(backward).mu2) / (2 * h);
  }
  return out;
}

TEST_P(Outputs, GradientMatchesACentralDifferenceOfMu2) {
  // Both error sources of the difference are ~1e-12 (see relative_step) and
  // the gradient's own ~1e-13; 1e-9 is a margin of ~1000 over the measured
  // 9.4e-13, and still far below the error of any wrong formula (a missing
  // factor lambda (1 - lambda) or 2 is an O(1) error).
  const double tolerance = 1e-9;
  const auto pairs = make_random_pairs(300, 73);
  std::vector<Vector3L> expected(pairs.size());
  const std::ptrdiff_t n = std::ptrdiff_t(pairs.size());
#pragma omp parallel for schedule(dynamic, 8)
  for (std::ptrdiff_t i = 0; i < n; ++i) expected[i] = central_difference(pairs[i]);
  Requested gradient_only = Requested::mu2_only();
  gradient_only.gradient = true;
  const BatchRun<double> run = run_batch(make_batch(pairs), with_isa(GetParam()), gradient_only);
  MaxError error;
  for (std::size_t i = 0; i < pairs.size(); ++i)
    error.add(i, vector_error(lane_vector(run.gradient, i), expected[i]));
  print_measured(label<double>("gradient vs central difference", GetParam()), error);
  EXPECT_LE(error.value, tolerance) << "pair " << error.index;
}

// ---------------------------------------------------------------------------
// Geometric identities, in long double from the batch's own outputs: the
// normal is a unit vector along s = Q(lambda)^-1 r12 (eq. 8); the contact
// point x0 lies on both ellipsoids scaled by mu (eq. 14):
//   (x0 - c1)^T (mu^2 Q1)^-1 (x0 - c1) = 1,  (x0 - c2)^T (mu^2 Q2)^-1 (x0 - c2) = 1
// with x0 - c2 = (x0 - c1) - r12.
//
// x0 is given relative to c1, so it is accurate relative to |x0 - c1|, and
// how far a surface identity h(x0) = 1 is off depends on the surface's
// slope there (a thin disc's h changes fast across it). Each identity is
// therefore read as the distance of x0 from the scaled surface, to first
// order |h - 1| / |grad h|, relative to |x0 - c1|: the position error the
// output has. A wrong contact point shows as an error of order 1.

// The first-order distance of x from the surface x^T (mu^2 Q)^-1 x = 1,
// relative to `scale`.
double distance_from_surface(const Vector3L& x, const MatrixL& q, long double mu2,
                             long double scale) {
  const Vector3L gradient = 2 * q.ldlt().solve(x) / mu2;  // of h(x) = x^T (mu^2 Q)^-1 x
  const long double h = x.dot(gradient) / 2;
  return double(std::fabs(h - 1) / (gradient.norm() * scale));
}

struct IdentityErrors {
  MaxError unit, parallel, on_first, on_second;
};

IdentityErrors identity_errors(const std::vector<Pair<double>>& pairs,
                               const BatchRun<double>& run) {
  IdentityErrors errors;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair<double>& p = pairs[i];
    const MatrixL q1 = unpack(p.q1).cast<long double>(), q2 = unpack(p.q2).cast<long double>();
    const Vector3L r(p.r12[0], p.r12[1], p.r12[2]);
    const long double lambda = run.lambda[i], mu2 = run.mu2[i];
    const Vector3L s = ((1 - lambda) * q1 + lambda * q2).ldlt().solve(r);
    const Vector3L normal = lane_vector(run.normal, i), x1 = lane_vector(run.contact_point, i);
    errors.unit.add(i, double(std::fabs(normal.norm() - 1)));
    errors.parallel.add(i, vector_error(normal, s.normalized()));
    errors.on_first.add(i, distance_from_surface(x1, q1, mu2, x1.norm()));
    errors.on_second.add(i, distance_from_surface(x1 - r, q2, mu2, x1.norm()));
  }
  return errors;
}

// Tolerances of the identities on one family.
struct IdentityTolerance {
  // |n| = 1: a normalisation in double, a few eps. Measured 2.9e-16.
  double unit;
  // n along s at the same lambda: the kernel extrapolates s to first order
  // from the lambda it evaluated to the lambda it reports (one Newton step,
  // up to ~1e-6), so the error is ~step^2 plus the rounding of s, ~eps cond(Q).
  double parallel;
  // x0 on the scaled surfaces, relative to |x0 - c1|: lambda's error
  // (~1e-12) times the speed of x0(lambda), plus the floor of mu^2.
  double on_surface;
};

void expect_identities_hold(const std::vector<Pair<double>>& pairs, Isa isa,
                            const IdentityTolerance& tolerance, const std::string& family) {
  const BatchRun<double> run = run_batch(make_batch(pairs), with_isa(isa), Requested::everything());
  const IdentityErrors errors = identity_errors(pairs, run);
  const std::string what = label<double>(family, isa);
  const std::tuple<const char*, const MaxError*, double> checks[] = {
      {"|normal| - 1", &errors.unit, tolerance.unit},
      {"normal vs Q^-1 r12 / |Q^-1 r12|", &errors.parallel, tolerance.parallel},
      {"contact point on scaled ellipsoid 1", &errors.on_first, tolerance.on_surface},
      {"contact point on scaled ellipsoid 2", &errors.on_second, tolerance.on_surface}};
  for (const auto& [name, error, bound] : checks) {
    print_measured(what + ", " + name, *error);
    EXPECT_LE(error->value, bound) << what << ", " << name << ", pair " << error->index;
  }
}

TEST_P(Outputs, NormalAndContactPointSatisfyTheGeometricIdentitiesOnRandomPairs) {
  // cond(Q) <= 16. Measured: 5.1e-14 (parallel), 2.4e-13 (on the surfaces);
  // the bounds leave a factor ~20 and ~40 (1e-11: lambda's documented ~1e-12
  // times a speed of x0(lambda) up to 10).
  expect_identities_hold(make_random_pairs(5000, 74), GetParam(), {1e-14, 1e-12, 1e-11}, "random");
}

TEST_P(Outputs, NormalAndContactPointSatisfyTheGeometricIdentitiesOnThePw85Family) {
  // Every 97th pair of the family (4329 pairs), aspect ratios up to 500 and
  // cond(Q) up to 2.5e5. Measured: 7.9e-12 (parallel; ~eps cond(Q)) and
  // 1.5e-11 (on the surfaces). 1e-10 is the peer library's tolerance on
  // mu_i^2 = mu^2 at the returned lambda, which the surface identities restate.
  std::vector<Pair<double>> sample;
  const PairBatch<double> family = pwcontact::pw85_family();
  for (std::size_t i = 0; i < family.size(); i += 97) sample.push_back(pair_at(family, i));
  expect_identities_hold(sample, GetParam(), {1e-14, 1e-10, 1e-10}, "pw85 sample");
}

// ---------------------------------------------------------------------------

// A three-component output is all three arrays or none (batch.hpp).
template <class T>
void expect_partial_triples_rejected() {
  const PairBatch<T> batch = make_batch(convert_all<T>(make_random_pairs(8, 75)));
  std::vector<T> mu2(8), component(8);
  for (int output = 0; output < 3; ++output)
    for (int given : {1, 2, 4, 3, 5, 6}) {  // one or two of the three components, as bits
      ContactOutputs<T> out{mu2.data()};
      T** triple = output == 0 ? out.contact_point : output == 1 ? out.normal : out.gradient;
      for (int k = 0; k < 3; ++k)
        if (given & (1 << k)) triple[k] = component.data();
      EXPECT_THROW(pwcontact::contact_function_batch(batch.view(), out), std::invalid_argument)
          << "output " << output << ", components given (bits) " << given;
    }
}

TEST(OutputsCall, PartiallyGivenTripleThrows) {
  expect_partial_triples_rejected<double>();
  expect_partial_triples_rejected<float>();
}

}  // namespace
}  // namespace pwtest
