// The batch options that trade speed for accuracy: every precision, every
// formulation, automatic and fixed iterations and both accuracies, on every
// instruction set, against the long double oracle on the random family; and
// the combinations the library rejects.
#include <stdexcept>

#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::Accuracy;
using pwcontact::Formulation;
using pwcontact::Precision;

// One setting of the knobs; float_pairs: the pairs are given as float.
struct Knobs {
  Precision precision;
  Formulation formulation;
  int iterations;
  Accuracy accuracy;
  bool float_pairs;
};

std::string knobs_name(const Knobs& k) {
  return std::string(k.float_pairs ? "float_pairs_" : "") + pwcontact::precision_name(k.precision) +
         "_" + pwcontact::formulation_name(k.formulation) + "_" +
         (k.iterations == 0 ? std::string("auto") : "fixed" + std::to_string(k.iterations)) + "_" +
         pwcontact::accuracy_name(k.accuracy);
}

void PrintTo(const Knobs& knobs, std::ostream* os) { *os << knobs_name(knobs); }

std::vector<Knobs> every_knob_setting() {
  std::vector<Knobs> out;
  const Formulation formulations[] = {Formulation::automatic, Formulation::newton,
                                      Formulation::log_odds};
  // Fixed counts: 2 leaves most lanes to the reference path, 5 few.
  for (Formulation formulation : formulations)
    for (int iterations : {0, 2, 5}) {
      for (Precision precision : {Precision::double_precision, Precision::mixed})
        for (Accuracy accuracy : {Accuracy::standard, Accuracy::high})
          out.push_back({precision, formulation, iterations, accuracy, false});
      out.push_back(
          {Precision::single_precision, formulation, iterations, Accuracy::standard, false});
      out.push_back(
          {Precision::single_precision, formulation, iterations, Accuracy::standard, true});
    }
  return out;
}

// The random family as double and as float pairs, with the long double oracle
// of each (float pairs widened exactly): computed once per process.
struct RandomFamily {
  std::vector<Pair<double>> pairs;
  std::vector<Pair<float>> float_pairs;
  std::vector<ContactResult<long double>> oracle, float_oracle;
};

const RandomFamily& random_family() {
  static const RandomFamily family = [] {
    RandomFamily out;
    out.pairs = make_random_pairs(20000, 61);
    out.float_pairs = convert_all<float>(out.pairs);
    out.oracle = long_double_oracles(out.pairs);
    out.float_oracle = long_double_oracles(convert_all<double>(out.float_pairs));
    return out;
  }();
  return family;
}

template <class T>
void expect_within_bounds(const std::vector<Pair<T>>& pairs,
                          const std::vector<ContactResult<long double>>& oracle, const Knobs& knobs,
                          Isa isa) {
  const BatchOptions options = with_precision(with_isa(isa, knobs.iterations), knobs.precision,
                                              knobs.formulation, knobs.accuracy);
  const BatchRun<T> run = run_batch(make_batch(pairs), options);
  const std::string what = std::string(pwcontact::isa_name(isa)) + " " + knobs_name(knobs);

  EXPECT_EQ(run.report.precision, knobs.precision) << what;
  EXPECT_EQ(run.report.iterations, knobs.iterations) << what;
  EXPECT_EQ(run.report.accuracy, knobs.accuracy) << what;
  if (knobs.formulation == Formulation::automatic)
    EXPECT_NE(run.report.formulation, Formulation::automatic) << what << ": not resolved";
  else
    EXPECT_EQ(run.report.formulation, knobs.formulation) << what;
  EXPECT_EQ(run.report.invalid, 0u) << what;

  MaxError mu2_error, lambda_error;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    ASSERT_TRUE(pwcontact::is_valid(run.status[i]))
        << what << ", pair " << i << ": " << pwcontact::status_name(run.status[i]);
    mu2_error.add(i, relative_error(run.mu2[i], oracle[i].mu2));
    lambda_error.add(i, absolute_error(run.lambda[i], oracle[i].lambda));
  }
  print_measured(what + ", mu2 relative error", mu2_error);
  print_measured(what + ", lambda absolute error", lambda_error);
  std::printf("[ measured ] %s: %.2f evaluations per pair, %zu fallbacks\n", what.c_str(),
              run.report.mean_evaluations, run.report.fallbacks);
  // The tolerances of the random family for lanes iterating in this
  // precision (test_support, LaneTolerance), now against the oracle:
  // - double and mixed: mu2 1e-13, the promised accuracy (cond(Q) <= 16 here,
  //   the floor is a few eps); measured at most 9.9e-16 over every setting
  //   and instruction set (Accuracy::high: 7.5e-16). lambda 1e-12, as
  //   documented when asked for; measured 8.9e-14.
  // - single, float pairs or double pairs rounded to float: mu2 4e-6, about
  //   8 times the float floor; measured 5.7e-7 (both). lambda 4e-6;
  //   measured 1.5e-7.
  const Tolerances bounds = tolerances_for(knobs.precision);
  EXPECT_LE(mu2_error.value, bounds.mu2) << what << ", pair " << mu2_error.index;
  EXPECT_LE(lambda_error.value, bounds.lambda) << what << ", pair " << lambda_error.index;
}

class EveryKnob : public ::testing::TestWithParam<std::tuple<Isa, Knobs>> {};

TEST_P(EveryKnob, RandomFamilyIsWithinTheBoundOfItsPrecision) {
  const auto& [isa, knobs] = GetParam();
  const RandomFamily& family = random_family();
  if (knobs.float_pairs)
    expect_within_bounds(family.float_pairs, family.float_oracle, knobs, isa);
  else
    expect_within_bounds(family.pairs, family.oracle, knobs, isa);
}

INSTANTIATE_TEST_SUITE_P(EveryIsa, EveryKnob,
                         ::testing::Combine(::testing::ValuesIn(isas()),
                                            ::testing::ValuesIn(every_knob_setting())),
                         [](const auto& info) {
                           return std::string(pwcontact::isa_name(std::get<0>(info.param))) + "_" +
                                  knobs_name(std::get<1>(info.param));
                         });

// ---------------------------------------------------------------------------
// Resolution of the automatic settings, and the combinations that are rejected.

TEST(Knobs, AutomaticPrecisionIsThatOfThePairs) {
  const PairBatch<double> pairs = make_batch(make_random_pairs(100, 62));
  EXPECT_EQ(run_batch(pairs).report.precision, Precision::double_precision);
  EXPECT_EQ(run_batch(pwcontact::to_float(pairs)).report.precision, Precision::single_precision);
}

// Calls contact_function_batch on a few pairs with `options`.
template <class T>
void solve_few(const BatchOptions& options) {
  const PairBatch<T> pairs = make_batch(convert_all<T>(make_random_pairs(10, 63)));
  run_batch(pairs, options);
}

TEST(Knobs, HighAccuracyInSinglePrecisionThrows) {
  // The refinement works in double (batch.hpp: double or mixed precision only).
  const BatchOptions single =
      with_precision({}, Precision::single_precision, Formulation::automatic, Accuracy::high);
  EXPECT_THROW(solve_few<double>(single), std::invalid_argument);
  EXPECT_THROW(solve_few<float>(single), std::invalid_argument);
  const BatchOptions automatic =
      with_precision({}, Precision::automatic, Formulation::automatic, Accuracy::high);
  EXPECT_THROW(solve_few<float>(automatic), std::invalid_argument) << "float pairs";
  EXPECT_NO_THROW(solve_few<double>(automatic)) << "double pairs";
}

TEST(Knobs, DoubleAndMixedPrecisionThrowForFloatPairs) {
  for (Precision precision : {Precision::double_precision, Precision::mixed})
    EXPECT_THROW(solve_few<float>(with_precision({}, precision)), std::invalid_argument)
        << pwcontact::precision_name(precision);
}

TEST(Knobs, NegativeIterationsOrThreadsThrow) {
  EXPECT_THROW(solve_few<double>(with_isa(Isa::automatic, -1)), std::invalid_argument);
  EXPECT_THROW(solve_few<double>(with_isa(Isa::automatic, 0, -1)), std::invalid_argument);
}

// Values cast from outside their enumerations are malformed calls: refused,
// not taken for a default (precision, accuracy, formulation were), nor
// blamed on the CPU (isa was).
TEST(Knobs, ValuesOutsideTheirEnumerationsThrowInvalidArgument) {
  for (int value : {-1, 9, 77}) {
    pwcontact::BatchOptions options;
    options.isa = Isa(value);
    EXPECT_THROW(solve_few<double>(options), std::invalid_argument) << "isa " << value;
    options = {};
    options.precision = pwcontact::Precision(value);
    EXPECT_THROW(solve_few<double>(options), std::invalid_argument) << "precision " << value;
    options = {};
    options.accuracy = pwcontact::Accuracy(value);
    EXPECT_THROW(solve_few<double>(options), std::invalid_argument) << "accuracy " << value;
    options = {};
    options.formulation = pwcontact::Formulation(value);
    EXPECT_THROW(solve_few<double>(options), std::invalid_argument) << "formulation " << value;
  }
}

TEST(Knobs, NamesRoundTrip) {
  for (Precision p : {Precision::automatic, Precision::double_precision,
                      Precision::single_precision, Precision::mixed})
    EXPECT_EQ(pwcontact::parse_precision(pwcontact::precision_name(p)), p);
  for (Accuracy a : {Accuracy::standard, Accuracy::high})
    EXPECT_EQ(pwcontact::parse_accuracy(pwcontact::accuracy_name(a)), a);
  for (Formulation f : {Formulation::automatic, Formulation::newton, Formulation::log_odds})
    EXPECT_EQ(pwcontact::parse_formulation(pwcontact::formulation_name(f)), f);
  EXPECT_FALSE(pwcontact::parse_precision("half"));
  EXPECT_FALSE(pwcontact::parse_accuracy("extreme"));
  EXPECT_FALSE(pwcontact::parse_formulation("halley"));
}

}  // namespace
}  // namespace pwtest
