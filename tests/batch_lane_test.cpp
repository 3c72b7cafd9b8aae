// The batch path lane by lane, on every instruction set this CPU supports:
// every lane against the scalar reference, tails, thread-count independence,
// the report, the instruction-set override and the fallback.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::ContactOutputs;

class BatchLanes : public ::testing::TestWithParam<Isa> {};
INSTANTIATE_TEST_SUITE_P(EverySupportedIsa, BatchLanes, ::testing::ValuesIn(isas()),
                         isa_param_name);

template <class Vector>
Vector first(const Vector& all, std::size_t n) {
  return {all.begin(), all.begin() + std::ptrdiff_t(n)};
}

// Every batch size from 1 to 3 lanes + 1 covers: a lone partial group, exact
// single and double groups (the kernel interleaves two), and tails of every
// length after them. The inputs have exactly n elements, so a read past the
// end is a heap overflow under AddressSanitizer; the outputs are guarded.
template <class T>
void expect_every_lane_matches_reference(Isa isa) {
  const std::size_t lanes = std::size_t(pwcontact::simd_lanes(isa, single_precision<T>));
  const auto pool = convert_all<T>(make_random_pairs(3 * lanes + 1, 21));
  const auto references = double_references(pool);
  LaneErrors worst;
  for (std::size_t n = 1; n <= pool.size(); ++n) {
    const auto pairs = first(pool, n);
    const BatchRun<T> run = run_batch(make_batch(pairs), with_isa(isa));
    const LaneErrors errors = expect_lanes_match_reference(
        first(references, n), run, label<T>("batch of " + std::to_string(n), isa));
    worst.mu2.add(n, errors.mu2.value);
    worst.lambda.add(n, errors.lambda.value);
  }
  print_measured(label<T>("every lane vs reference, mu2 relative error", isa), worst.mu2);
  print_measured(label<T>("every lane vs reference, lambda absolute error", isa), worst.lambda);
}

TEST_P(BatchLanes, EveryLaneOfEveryBatchSizeMatchesReferenceInDouble) {
  expect_every_lane_matches_reference<double>(GetParam());
}

TEST_P(BatchLanes, EveryLaneOfEveryBatchSizeMatchesReferenceInFloat) {
  expect_every_lane_matches_reference<float>(GetParam());
}

// A larger sample of lanes than the size sweep, for the float tolerance:
// the sweep sees only a few dozen pairs.
template <class T>
void expect_many_lanes_match_reference(Isa isa) {
  const auto pairs = convert_all<T>(make_random_pairs(20000, 22));
  const BatchRun<T> run = run_batch(make_batch(pairs), with_isa(isa));
  const LaneErrors errors =
      expect_lanes_match_reference(double_references(pairs), run, label<T>("20000 lanes", isa));
  print_measured(label<T>("20000 random lanes, mu2 relative error", isa), errors.mu2);
  print_measured(label<T>("20000 random lanes, lambda absolute error", isa), errors.lambda);
}

TEST_P(BatchLanes, ManyRandomLanesMatchReferenceInDouble) {
  expect_many_lanes_match_reference<double>(GetParam());
}

TEST_P(BatchLanes, ManyRandomLanesMatchReferenceInFloat) {
  expect_many_lanes_match_reference<float>(GetParam());
}

// Lanes at wildly different scales side by side (Q -> k^2 Q, r -> k r with k
// cycling through the factors), out to where products of Q's entries would
// overflow or underflow the type unless the kernel nondimensionalises.
template <class T>
void expect_extreme_scales_match_reference(Isa isa, const std::vector<double>& factors) {
  auto pairs = make_random_pairs(1000, 34);
  for (std::size_t i = 0; i < pairs.size(); ++i)
    pairs[i] = scaled(pairs[i], factors[i % factors.size()]);
  const auto converted = convert_all<T>(pairs);
  const BatchRun<T> run = run_batch(make_batch(converted), with_isa(isa));
  expect_lanes_match_reference(double_references(converted), run, label<T>("extreme scales", isa));
}

TEST_P(BatchLanes, ExtremeScalesMatchReferenceInDouble) {
  expect_extreme_scales_match_reference<double>(GetParam(),
                                                {1e-150, 1e-100, 1e-10, 1, 1e10, 1e100, 1e150});
}

TEST_P(BatchLanes, ExtremeScalesMatchReferenceInFloat) {
  // Float's range is 1e+-38: k^2 q stays normal for k in [1e-15, 1e15].
  expect_extreme_scales_match_reference<float>(GetParam(), {1e-15, 1e-6, 1, 1e6, 1e15});
}

// ---------------------------------------------------------------------------

// The same pairs behind 1 .. 2 lanes + 1 other pairs: each pair moves to
// every lane position and between the kernel's two-group blocks, single
// groups and the padded tail. Its answer must not move with it.
template <class T>
void expect_position_changes_nothing(Isa isa) {
  const std::size_t lanes = std::size_t(pwcontact::simd_lanes(isa, single_precision<T>));
  const auto pairs = convert_all<T>(make_random_pairs(200, 32));
  const BatchRun<T> alone = run_batch(make_batch(pairs), with_isa(isa));
  for (std::size_t shift = 1; shift <= 2 * lanes + 1; ++shift) {
    auto shifted = convert_all<T>(make_random_pairs(shift, 33));
    shifted.insert(shifted.end(), pairs.begin(), pairs.end());
    std::vector<std::size_t> moved(pairs.size());
    for (std::size_t i = 0; i < pairs.size(); ++i) moved[i] = shift + i;
    const BatchRun<T> run = run_batch(make_batch(shifted), with_isa(isa));
    expect_bitwise_equal(select_lanes(run, moved), alone,
                         label<T>("shifted by " + std::to_string(shift), isa));
  }
}

TEST_P(BatchLanes, ResultsDoNotDependOnThePositionInTheBatchInDouble) {
  expect_position_changes_nothing<double>(GetParam());
}

TEST_P(BatchLanes, ResultsDoNotDependOnThePositionInTheBatchInFloat) {
  expect_position_changes_nothing<float>(GetParam());
}

// The evaluations of the first pass in automatic mode, read off the report of
// a batch of spheres: the initial guess is exact for two spheres, so every
// lane passes its convergence check at the end of the first pass. The batch
// size is a multiple of every kernel's block (lanes times interleaved
// groups: 4 to 48), so that no padding lane could enter the mean.
template <class T>
double first_pass_evaluations(Isa isa) {
  std::vector<Pair<T>> spheres;
  for (const auto& p : make_random_pairs(48 * 8, 35)) {
    Pair<double> sphere = p;  // its r12, radii from its diagonals
    sphere.q1 = pwcontact::sphere(std::sqrt(p.q1[0]));
    sphere.q2 = pwcontact::sphere(std::sqrt(p.q2[3]));
    spheres.push_back(convert<T>(sphere));
  }
  const BatchRun<T> run = run_batch(make_batch(spheres), with_isa(isa));
  EXPECT_EQ(run.report.fallbacks, 0u) << label<T>("spheres", isa);
  return run.report.mean_evaluations;
}

// Tens of the driver's chunks (a few thousand pairs each) and a partial one,
// from a family with semi-axes over two decades, so that lanes take every
// path: in automatic mode some are packed and continue in later passes, with
// a small fixed count many go to the reference path. Returns the
// single-thread report.
template <class T>
BatchReport expect_thread_count_changes_nothing(Isa isa, int iterations) {
  pwcontact::RandomFamily family;
  family.min_semi_axis = 0.1;
  family.max_semi_axis = 10;
  family.log_uniform_axes = true;
  const PairBatch<T> batch =
      make_batch(convert_all<T>(make_random_pairs(20 * 2048 + 37, 23, family)));
  const std::string what = "iterations " + std::to_string(iterations) + ", ";
  const BatchRun<T> one = run_batch(batch, with_isa(isa, iterations, 1));
  for (int threads : {2, 3}) {
    const BatchRun<T> many = run_batch(batch, with_isa(isa, iterations, threads));
    EXPECT_EQ(many.report.threads, threads);
    expect_bitwise_equal(one, many, label<T>(what + std::to_string(threads) + " threads", isa));
  }
  return one.report;
}

template <class T>
void expect_automatic_mode_independent_of_thread_count(Isa isa) {
  if (isa == Isa::fallback) {
    // (No passes to count: the portable target answers on the reference path.)
    expect_thread_count_changes_nothing<T>(isa, 0);
    return;
  }
  const double first_pass = first_pass_evaluations<T>(isa);
  const BatchReport report = expect_thread_count_changes_nothing<T>(isa, 0);
  std::printf("[ measured ] %s: %.3f evaluations per pair (first pass %.3f), %zu fallbacks\n",
              label<T>("log-uniform family, automatic", isa).c_str(), report.mean_evaluations,
              first_pass, report.fallbacks);
  EXPECT_GT(report.mean_evaluations, first_pass) << "the family should need later passes";
}

// Two evaluations leave most lanes of this family unconverged.
template <class T>
void expect_fixed_count_independent_of_thread_count(Isa isa) {
  const BatchReport report = expect_thread_count_changes_nothing<T>(isa, 2);
  EXPECT_GT(report.fallbacks, 0u) << "the family should exercise the fallback";
}

TEST_P(BatchLanes, AutomaticIterationsAreBitwiseIdenticalForOneTwoAndThreeThreadsInDouble) {
  expect_automatic_mode_independent_of_thread_count<double>(GetParam());
}

TEST_P(BatchLanes, AutomaticIterationsAreBitwiseIdenticalForOneTwoAndThreeThreadsInFloat) {
  expect_automatic_mode_independent_of_thread_count<float>(GetParam());
}

TEST_P(BatchLanes, FixedIterationsAreBitwiseIdenticalForOneTwoAndThreeThreadsInDouble) {
  expect_fixed_count_independent_of_thread_count<double>(GetParam());
}

TEST_P(BatchLanes, FixedIterationsAreBitwiseIdenticalForOneTwoAndThreeThreadsInFloat) {
  expect_fixed_count_independent_of_thread_count<float>(GetParam());
}

// ---------------------------------------------------------------------------

// Random pairs with every third one made invalid in a different way, so that
// the report has valid, fallback and invalid statuses to count.
template <class T>
PairBatch<T> mixed_batch(std::size_t n) {
  auto pairs = convert_all<T>(make_random_pairs(n, 24));
  for (std::size_t i = 0; i < n; i += 3) {
    if (i % 2 == 0)
      pairs[i].r12[1] = std::numeric_limits<T>::quiet_NaN();
    else
      pairs[i].q2[0] = -1;
  }
  return make_batch(pairs);
}

template <class T>
void expect_report_consistent_with_statuses(Isa isa, int iterations, int threads) {
  const std::size_t n = 5000;
  const BatchRun<T> run = run_batch(mixed_batch<T>(n), with_isa(isa, iterations, threads));
  const BatchReport& report = run.report;
  std::size_t counted[pwcontact::status_count] = {};
  for (Status s : run.status) {
    ASSERT_LT(int(s), pwcontact::status_count) << "status outside the enumeration";
    ++counted[int(s)];
  }
  std::size_t invalid = 0, total = 0;
  for (int s = 0; s < pwcontact::status_count; ++s) {
    EXPECT_EQ(report.status_counts[s], counted[s]) << pwcontact::status_name(Status(s));
    total += report.status_counts[s];
    if (!pwcontact::is_valid(Status(s))) invalid += counted[s];
  }
  EXPECT_EQ(report.pairs, n);
  EXPECT_EQ(total, n);
  EXPECT_EQ(report.invalid, invalid);
  EXPECT_GT(report.invalid, 0u);
  // Every fallback on a valid pair succeeds in the reference path.
  EXPECT_EQ(report.fallbacks, counted[int(Status::ok_fallback)]);
  EXPECT_EQ(report.isa, isa);
  EXPECT_EQ(report.iterations, iterations);  // 0 stays 0: automatic
  EXPECT_GE(report.threads, 1);
  if (threads > 0) {
    EXPECT_LE(report.threads, threads);
  }
}

TEST_P(BatchLanes, ReportAgreesWithTheStatusesInDouble) {
  expect_report_consistent_with_statuses<double>(GetParam(), 0, 0);
  expect_report_consistent_with_statuses<double>(GetParam(), 2, 2);
}

TEST_P(BatchLanes, ReportAgreesWithTheStatusesInFloat) {
  expect_report_consistent_with_statuses<float>(GetParam(), 0, 0);
  expect_report_consistent_with_statuses<float>(GetParam(), 2, 2);
}

// ---------------------------------------------------------------------------
// One fixed Newton iteration from the radial guess leaves most lanes far from
// converged (the error is still ~1e-7 after four on this family): they must
// come back from the fallback, flagged and counted, and the lanes that do pass
// the check after one iteration must be as accurate as any other.

template <class T>
void expect_fallback_lanes_flagged_and_accurate(Isa isa) {
  const auto pairs = convert_all<T>(make_random_pairs(4096, 25));
  const BatchRun<T> run = run_batch(make_batch(pairs), with_isa(isa, 1));
  std::size_t flagged = 0;
  for (Status s : run.status) flagged += s == Status::ok_fallback;
  std::printf("[ measured ] %s: %zu of %zu lanes fell back\n",
              label<T>("one iteration", isa).c_str(), flagged, pairs.size());
  EXPECT_GT(flagged, pairs.size() / 2);
  EXPECT_EQ(run.report.fallbacks, flagged);
  EXPECT_EQ(run.report.iterations, 1);
  expect_lanes_match_reference(double_references(pairs), run, label<T>("one iteration", isa));
}

TEST_P(BatchLanes, FallbackLanesAreFlaggedCountedAndAccurateInDouble) {
  expect_fallback_lanes_flagged_and_accurate<double>(GetParam());
}

TEST_P(BatchLanes, FallbackLanesAreFlaggedCountedAndAccurateInFloat) {
  expect_fallback_lanes_flagged_and_accurate<float>(GetParam());
}

// ---------------------------------------------------------------------------
// Choosing the instruction set.

TEST_P(BatchLanes, OptionForcesTheIsa) {
  const ScopedEnvironment no_override("PWCONTACT_ISA", std::nullopt);
  const PairBatch<double> batch = make_batch(make_random_pairs(10, 26));
  EXPECT_EQ(run_batch(batch, with_isa(GetParam())).report.isa, GetParam());
  EXPECT_EQ(run_batch(pwcontact::to_float(batch), with_isa(GetParam())).report.isa, GetParam());
}

TEST_P(BatchLanes, EnvironmentVariableChoosesTheIsaWhenAutomatic) {
  const ScopedEnvironment override_isa("PWCONTACT_ISA", pwcontact::isa_name(GetParam()));
  EXPECT_EQ(pwcontact::resolve_isa(Isa::automatic), GetParam());
  EXPECT_EQ(run_batch(make_batch(make_random_pairs(10, 27))).report.isa, GetParam());
}

TEST_P(BatchLanes, OptionWinsOverTheEnvironmentVariable) {
  // Point the environment at another supported ISA where there is one.
  const std::vector<Isa> all = isas();
  const Isa other = all.size() > 1 && all.front() == GetParam() ? all.back() : all.front();
  const ScopedEnvironment override_isa("PWCONTACT_ISA", pwcontact::isa_name(other));
  EXPECT_EQ(run_batch(make_batch(make_random_pairs(10, 28)), with_isa(GetParam())).report.isa,
            GetParam());
}

TEST(IsaChoice, WithoutOverrideTheBestSupportedIsaIsUsed) {
  const ScopedEnvironment no_override("PWCONTACT_ISA", std::nullopt);
  EXPECT_EQ(run_batch(make_batch(make_random_pairs(10, 29))).report.isa, isas().front());
  const ScopedEnvironment automatic("PWCONTACT_ISA", "auto");
  EXPECT_EQ(run_batch(make_batch(make_random_pairs(10, 29))).report.isa, isas().front());
}

TEST(IsaChoice, UnknownEnvironmentValueThrowsNamingIt) {
  const ScopedEnvironment override_isa("PWCONTACT_ISA", "avx9000");
  const PairBatch<double> batch = make_batch(make_random_pairs(10, 30));
  std::vector<double> mu2(batch.size());
  try {
    pwcontact::contact_function_batch(batch.view(), ContactOutputs<double>{mu2.data()});
    ADD_FAILURE() << "no exception for PWCONTACT_ISA=avx9000";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("avx9000"), std::string::npos) << e.what();
  }
}

TEST(IsaChoice, LaneCountsMatchTheRegisterWidths) {
  // 128, 256 and 512-bit registers.
  const std::pair<Isa, int> widths[] = {{Isa::sse2, 16}, {Isa::avx2, 32}, {Isa::avx512, 64}};
  for (const auto& [isa, bytes] : widths) {
    if (!pwcontact::isa_supported(isa)) continue;
    EXPECT_EQ(pwcontact::simd_lanes(isa, false), bytes / 8) << pwcontact::isa_name(isa);
    EXPECT_EQ(pwcontact::simd_lanes(isa, true), bytes / 4) << pwcontact::isa_name(isa);
  }
}

// ---------------------------------------------------------------------------
// Optional and required outputs.

void expect_same_counts(const BatchReport& a, const BatchReport& b, const std::string& what) {
  EXPECT_EQ(a.fallbacks, b.fallbacks) << what;
  EXPECT_EQ(a.invalid, b.invalid) << what;
  EXPECT_EQ(a.mean_evaluations, b.mean_evaluations) << what;
  for (int s = 0; s < pwcontact::status_count; ++s)
    EXPECT_EQ(a.status_counts[s], b.status_counts[s])
        << what << ", " << pwcontact::status_name(Status(s));
}

// The status array only receives the statuses: leaving it out (the driver
// then keeps them internally) changes no other output and no count, with the
// other outputs the same.
template <class T>
void expect_null_status_changes_nothing(Isa isa, int iterations) {
  const PairBatch<T> batch = mixed_batch<T>(1000);
  for (Requested without : {Requested::mu2_only(), Requested{}}) {
    without.status = false;
    Requested with = without;
    with.status = true;
    const std::string what = label<T>(
        describe(with) + " vs " + describe(without) + ", iterations " + std::to_string(iterations),
        isa);
    const BatchRun<T> a = run_batch(batch, with_isa(isa, iterations), with);
    const BatchRun<T> b = run_batch(batch, with_isa(isa, iterations), without);
    expect_bitwise_equal(a, b, what);
    expect_same_counts(a.report, b.report, what);
  }
}

TEST_P(BatchLanes, NullStatusChangesNeitherResultsNorCounts) {
  for (int iterations : {0, 2}) {
    expect_null_status_changes_nothing<double>(GetParam(), iterations);
    expect_null_status_changes_nothing<float>(GetParam(), iterations);
  }
}

// Asking for lambda tightens the convergence check (batch.hpp), so mu2 may
// change in its last bits: both answers stay within the accuracy promised
// against the reference path, and within LaneTolerance<T>::mu2_alone of each
// other.
template <class T>
void expect_lambda_request_keeps_mu2_within_accuracy(Isa isa) {
  const auto pairs = convert_all<T>(make_random_pairs(20000, 36));
  const PairBatch<T> batch = make_batch(pairs);
  const auto references = double_references(pairs);
  const BatchRun<T> with_lambda = run_batch(batch, with_isa(isa));
  Requested no_lambda;
  no_lambda.lambda = false;
  const BatchRun<T> without = run_batch(batch, with_isa(isa), no_lambda);
  expect_lanes_match_reference(references, with_lambda, label<T>("mu2 and lambda", isa));
  expect_lanes_match_reference(references, without, label<T>("mu2 alone", isa));
  MaxError difference;
  for (std::size_t i = 0; i < pairs.size(); ++i)
    difference.add(i, relative_error(without.mu2[i], with_lambda.mu2[i]));
  print_measured(label<T>("mu2 alone vs mu2 with lambda, relative difference", isa), difference);
  EXPECT_LE(difference.value, LaneTolerance<T>::mu2_alone) << "lane " << difference.index;
}

TEST_P(BatchLanes, AskingForLambdaKeepsMu2WithinTheAccuracyBoundInDouble) {
  expect_lambda_request_keeps_mu2_within_accuracy<double>(GetParam());
}

TEST_P(BatchLanes, AskingForLambdaKeepsMu2WithinTheAccuracyBoundInFloat) {
  expect_lambda_request_keeps_mu2_within_accuracy<float>(GetParam());
}

TEST(BatchCall, NullMu2Throws) {
  const PairBatch<double> batch = make_batch(make_random_pairs(10, 31));
  std::vector<double> lambda(batch.size());
  std::vector<Status> status(batch.size());
  EXPECT_THROW(pwcontact::contact_function_batch(
                   batch.view(), ContactOutputs<double>{nullptr, lambda.data(), status.data()}),
               std::invalid_argument);
  const PairBatch<float> single = pwcontact::to_float(batch);
  std::vector<float> lambda_f(batch.size());
  EXPECT_THROW(pwcontact::contact_function_batch(
                   single.view(), ContactOutputs<float>{nullptr, lambda_f.data(), status.data()}),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Strided views (PairBatchView's strides): pairs read in place from an array
// of structures (rows of 15 numbers), backwards (a negative stride), and one
// form shared by every pair (stride 0) get the answers of the same pairs in
// columns of their own, bit for bit: every output of the full answer, a warm
// start, and the overlap answers, in every precision the type has. The
// pairs include invalid ones (statuses) and the tail of a partial block.

// Every output of contact_function_batch and overlap_batch, as bits.
template <class T>
struct AllOutputs {
  std::vector<T> mu2, lambda, point, normal, gradient;
  std::vector<Status> status, overlap_status;
  std::vector<std::uint8_t> overlap;
};

template <class T>
AllOutputs<T> solve_all(const pwcontact::PairBatchView<T>& view, const BatchOptions& options) {
  const std::size_t n = view.size;
  AllOutputs<T> o;
  o.mu2.resize(n), o.lambda.resize(n), o.point.resize(3 * n), o.normal.resize(3 * n),
      o.gradient.resize(3 * n), o.status.resize(n), o.overlap_status.resize(n), o.overlap.resize(n);
  ContactOutputs<T> out{o.mu2.data(), o.lambda.data(), o.status.data()};
  for (int k = 0; k < 3; ++k) {
    out.contact_point[k] = o.point.data() + k * n;
    out.normal[k] = o.normal.data() + k * n;
    out.gradient[k] = o.gradient.data() + k * n;
  }
  pwcontact::contact_function_batch(view, out, options);
  pwcontact::overlap_batch(view, {o.overlap.data(), o.overlap_status.data()}, options, 1.0);
  return o;
}

template <class T>
bool same_bits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

template <class T>
void expect_same_outputs(const AllOutputs<T>& a, const AllOutputs<T>& b, const std::string& what) {
  EXPECT_TRUE(same_bits(a.mu2, b.mu2)) << what << ": mu2";
  EXPECT_TRUE(same_bits(a.lambda, b.lambda)) << what << ": lambda";
  EXPECT_TRUE(same_bits(a.point, b.point)) << what << ": contact_point";
  EXPECT_TRUE(same_bits(a.normal, b.normal)) << what << ": normal";
  EXPECT_TRUE(same_bits(a.gradient, b.gradient)) << what << ": gradient";
  EXPECT_TRUE(same_bits(a.status, b.status)) << what << ": status";
  EXPECT_TRUE(same_bits(a.overlap, b.overlap)) << what << ": overlap";
  EXPECT_TRUE(same_bits(a.overlap_status, b.overlap_status)) << what << ": overlap status";
}

// The view of pairs stored as rows (Pair<T> is 15 contiguous numbers),
// from pair `first` on, `step` rows from one pair to the next.
template <class T>
pwcontact::PairBatchView<T> rows_view(const std::vector<Pair<T>>& rows, std::size_t first,
                                      std::ptrdiff_t step, std::size_t n) {
  static_assert(sizeof(Pair<T>) == 15 * sizeof(T), "Pair<T> is 15 numbers side by side");
  pwcontact::PairBatchView<T> v;
  v.size = n;
  for (int k = 0; k < 3; ++k) v.r12[k] = &rows[first].r12[std::size_t(k)];
  for (int k = 0; k < 6; ++k) {
    v.q1[k] = &rows[first].q1[std::size_t(k)];
    v.q2[k] = &rows[first].q2[std::size_t(k)];
  }
  v.r12_stride = v.q1_stride = v.q2_stride = 15 * step;
  return v;
}

template <class T>
void expect_strided_views_match_columns(Isa isa) {
  const std::size_t n = 1003;  // not a multiple of any block
  std::vector<Pair<T>> rows = convert_all<T>(make_random_pairs(n, 41));
  for (std::size_t i = 0; i < n; i += 97) rows[i].q1[0] = -1;  // invalid: statuses
  rows[5].r12[2] = std::numeric_limits<T>::quiet_NaN();
  std::vector<Pair<T>> reversed(rows.rbegin(), rows.rend());
  std::vector<Pair<T>> shared = rows;  // every q2 the first pair's
  for (Pair<T>& p : shared) p.q2 = rows[0].q2;
  const PairBatch<T> columns = make_batch(rows), reversed_columns = make_batch(reversed),
                     shared_columns = make_batch(shared);
  std::vector<pwcontact::Precision> precisions = {pwcontact::Precision::automatic,
                                                  pwcontact::Precision::single_precision};
  if (std::is_same<T, double>::value) precisions.push_back(pwcontact::Precision::mixed);
  for (pwcontact::Precision precision : precisions) {
    const BatchOptions options = with_precision(with_isa(isa, 0, 1), precision);
    const std::string name =
        std::string(pwcontact::isa_name(isa)) + ", precision " + std::to_string(int(precision));
    const AllOutputs<T> expected = solve_all(columns.view(), options);
    expect_same_outputs(solve_all(rows_view(rows, 0, 1, n), options), expected, name + ", rows");
    expect_same_outputs(solve_all(rows_view(reversed, n - 1, -1, n), options), expected,
                        name + ", rows read backwards");
    // Packed rows, as C-ordered (N, 3) and (N, 6) arrays hold them (AVX-512
    // reads 8 double rows by shuffles, not gathers).
    std::vector<T> r(3 * n), a(6 * n), b(6 * n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < 3; ++k) r[3 * i + k] = rows[i].r12[k];
      for (std::size_t k = 0; k < 6; ++k)
        a[6 * i + k] = rows[i].q1[k], b[6 * i + k] = rows[i].q2[k];
    }
    pwcontact::PairBatchView<T> packed;
    packed.size = n;
    for (int k = 0; k < 3; ++k) packed.r12[k] = r.data() + k;
    for (int k = 0; k < 6; ++k) packed.q1[k] = a.data() + k, packed.q2[k] = b.data() + k;
    packed.r12_stride = 3;
    packed.q1_stride = packed.q2_stride = 6;
    expect_same_outputs(solve_all(packed, options), expected, name + ", packed rows of 3 and 6");
    // Rows as far apart, whose components are not side by side in their
    // order: each row's numbers backwards (numpy's a[:, ::-1] of a C-ordered
    // array), and r12 = (x, x, x) from one number a row (np.broadcast_to of a
    // column to (N, 3): a column step of 0). Taken for packed rows, the
    // first gave wrong answers with status ok.
    std::vector<T> r_back(3 * n), a_back(6 * n), b_back(6 * n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < 3; ++k) r_back[3 * i + 2 - k] = rows[i].r12[k];
      for (std::size_t k = 0; k < 6; ++k)
        a_back[6 * i + 5 - k] = rows[i].q1[k], b_back[6 * i + 5 - k] = rows[i].q2[k];
    }
    pwcontact::PairBatchView<T> backwards = packed;
    for (int k = 0; k < 3; ++k) backwards.r12[k] = r_back.data() + 2 - k;
    for (int k = 0; k < 6; ++k) backwards.q1[k] = a_back.data() + 5 - k;
    for (int k = 0; k < 6; ++k) backwards.q2[k] = b_back.data() + 5 - k;
    expect_same_outputs(solve_all(backwards, options), expected,
                        name + ", packed rows, each row's numbers backwards");
    std::vector<Pair<T>> diagonal = rows;  // r12 = (x, x, x)
    for (Pair<T>& p : diagonal) p.r12 = {p.r12[0], p.r12[0], p.r12[0]};
    pwcontact::PairBatchView<T> one_column = packed;
    for (int k = 0; k < 3; ++k) one_column.r12[k] = r.data();
    expect_same_outputs(solve_all(one_column, options),
                        solve_all(make_batch(diagonal).view(), options),
                        name + ", r12 one number a row broadcast to three");
    pwcontact::PairBatchView<T> broadcast = shared_columns.view();
    for (int k = 0; k < 6; ++k) broadcast.q2[k] = &rows[0].q2[std::size_t(k)];
    broadcast.q2_stride = 0;
    expect_same_outputs(solve_all(broadcast, options), solve_all(shared_columns.view(), options),
                        name + ", one q2 for every pair");
    (void)reversed_columns;
  }
  // A warm start read beside strided pairs.
  std::vector<T> start(n);
  for (std::size_t i = 0; i < n; ++i) start[i] = T(0.05 + 0.9 * double(i % 17) / 16);
  pwcontact::PairBatchView<T> warm_columns = columns.view(), warm_rows = rows_view(rows, 0, 1, n);
  warm_columns.lambda_start = warm_rows.lambda_start = start.data();
  expect_same_outputs(solve_all(warm_rows, with_isa(isa, 0, 1)),
                      solve_all(warm_columns, with_isa(isa, 0, 1)),
                      std::string(pwcontact::isa_name(isa)) + ", warm start");
}

TEST_P(BatchLanes, StridedViewsGiveTheAnswersOfColumnsBitForBitInDouble) {
  expect_strided_views_match_columns<double>(GetParam());
}

TEST_P(BatchLanes, StridedViewsGiveTheAnswersOfColumnsBitForBitInFloat) {
  expect_strided_views_match_columns<float>(GetParam());
}

// A negative count, converted to std::size_t, is refused: size -1 computed
// nothing and returned, -3000 read and wrote far beyond the arrays.
TEST(BatchCall, NegativeCountsThrow) {
  const std::vector<Pair<double>> rows = make_random_pairs(4, 3);
  const PairBatch<double> batch = make_batch(rows);
  std::vector<double> mu2(4);
  std::vector<Status> status(4);
  std::vector<std::uint8_t> overlap(4);
  for (const long count : {-1L, -3000L}) {
    pwcontact::PairBatchView<double> view = batch.view();
    view.size = std::size_t(count);
    EXPECT_THROW(pwcontact::contact_function_batch(view, {mu2.data(), nullptr, status.data()}),
                 std::invalid_argument)
        << count;
    EXPECT_THROW(pwcontact::overlap_batch(view, {overlap.data(), status.data()}),
                 std::invalid_argument)
        << count;
  }
}

TEST(BatchCall, StridesBeyondTheGathersReachThrow) {
  const PairBatch<double> batch = make_batch(make_random_pairs(10, 31));
  pwcontact::PairBatchView<double> view = batch.view();
  view.q1_stride = std::ptrdiff_t(1) << 27;
  std::vector<double> mu2(batch.size());
  EXPECT_THROW(pwcontact::contact_function_batch(view, ContactOutputs<double>{mu2.data()}),
               std::invalid_argument);
}

// A column read a register at a time from a line boundary never splits a
// register between two cache lines (CacheLineAllocator: streamed pairs were
// 11 % slower in double, 25 % in mixed precision, off the boundary). Every
// way a batch gets its storage: growing one pair at a time, resize, reserve,
// a copy, a move, and the small sizes malloc would serve from its heap;
// large columns also start at different offsets modulo 4 KiB (L1 sets).
template <class T>
void expect_columns_on_cache_lines(const pwcontact::PairBatch<T>& batch, const char* how) {
  const pwcontact::PairBatchView<T> view = batch.view();
  auto on_line = [](const T* p) { return reinterpret_cast<std::uintptr_t>(p) % 64 == 0; };
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(on_line(view.r12[k])) << how << ": r12[" << k << "]";
  for (int k = 0; k < 6; ++k) {
    EXPECT_TRUE(on_line(view.q1[k])) << how << ": q1[" << k << "]";
    EXPECT_TRUE(on_line(view.q2[k])) << how << ": q2[" << k << "]";
  }
}

template <class T>
void check_cache_line_columns() {
  const T r[3] = {1, 2, 3}, q[6] = {1, 0, 0, 1, 0, 1};
  for (std::size_t n : {1, 3, 17, 1000, 100000}) {
    pwcontact::PairBatch<T> grown;
    for (std::size_t i = 0; i < n; ++i) grown.push_back(r, q, q);
    expect_columns_on_cache_lines(grown, "push_back");
    pwcontact::PairBatch<T> sized(n);
    expect_columns_on_cache_lines(sized, "constructed");
    pwcontact::PairBatch<T> reserved;
    reserved.reserve(n);
    reserved.push_back(r, q, q);
    expect_columns_on_cache_lines(reserved, "reserve");
    const pwcontact::PairBatch<T> copy = grown;
    expect_columns_on_cache_lines(copy, "copy");
    const pwcontact::PairBatch<T> moved = std::move(grown);
    expect_columns_on_cache_lines(moved, "move");
    if (n * sizeof(T) >= pwcontact::CacheLineAllocator<T>::staggered_from) {
      // Large columns are staggered: not all at one offset modulo 4 KiB.
      std::set<std::uintptr_t> offsets;
      const pwcontact::PairBatchView<T> view = sized.view();
      for (int k = 0; k < 3; ++k)
        offsets.insert(reinterpret_cast<std::uintptr_t>(view.r12[k]) % 4096);
      for (int k = 0; k < 6; ++k) {
        offsets.insert(reinterpret_cast<std::uintptr_t>(view.q1[k]) % 4096);
        offsets.insert(reinterpret_cast<std::uintptr_t>(view.q2[k]) % 4096);
      }
      EXPECT_GE(offsets.size(), 8u) << n << " pairs";
    }
    T got_r[3], got_q1[6], got_q2[6];
    copy.get(n - 1, got_r, got_q1, got_q2);
    EXPECT_EQ(got_r[2], T(3));
  }
}

TEST(PairBatchStorage, EveryColumnStartsOnACacheLine) {
  check_cache_line_columns<double>();
  check_cache_line_columns<float>();
}

}  // namespace
}  // namespace pwtest
