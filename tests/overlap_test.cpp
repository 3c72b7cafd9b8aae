// Overlap-only answers (overlap_batch) on every instruction set, in every
// precision, with automatic and fixed iterations and several cutoffs: the
// yes/no answer against the exact classification mu^2 < cutoff^2 from a
// high-precision oracle, on families from easy to near tangent; the
// report's accounting; invalid pairs; malformed calls. And the moving
// scene's scalar certificates against the same classification.
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "screen/pair_prefilters.hpp"
#include "test_support.hpp"

namespace pwtest {
namespace {

using pwcontact::Precision;

// batch.hpp: the answer agrees with mu^2 < cutoff^2 whenever
// |mu^2 - cutoff^2| > 1e-9 cutoff^2 (Q conditioned up to ~1e8, which covers
// every family here). Pairs inside that band may go either way.
constexpr double decided_band = 1e-9;

// Pairs with their exact mu^2, and as a batch.
struct Classified {
  std::vector<Pair<double>> pairs;
  std::vector<long double> mu2;
  PairBatch<double> batch;
};

Classified with_oracle(std::vector<Pair<double>> pairs) {
  Classified out{std::move(pairs), {}, {}};
  std::size_t failed = 0;
  for (const auto& result : long_double_oracles(out.pairs)) {
    failed += result.status != Status::ok;
    out.mu2.push_back(result.mu2);
  }
  EXPECT_EQ(failed, 0u) << "pairs the oracle could not solve";
  return out;
}

// Random shapes at centre distances spread around contact, as in a dense
// scene: r12 scaled so that mu is uniform in [0.5, 1.5].
Classified scene_like_mix() {
  const auto shapes = make_random_pairs(20000, 91);
  const auto base = long_double_oracles(shapes);
  std::mt19937_64 engine(92);
  std::vector<Pair<double>> pairs;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const long double mu = 0.5L + (long double)(engine() >> 11) * 0x1.0p-53L;
    pairs.push_back(scaled_to_mu2(shapes[i], base[i].mu2, mu * mu));
  }
  return with_oracle(std::move(pairs));
}

Classified near_tangent(double cutoff) {
  Classified out;
  for (const NearTangent& t : near_tangent_pairs(cutoff)) {
    out.pairs.push_back(t.pair);
    out.mu2.push_back(t.mu2);
  }
  return out;
}

enum class FamilyName { random, pw85, scene_like, near_tangent };

const char* family_name(FamilyName name) {
  switch (name) {
    case FamilyName::random: return "random";
    case FamilyName::pw85: return "pw85";
    case FamilyName::scene_like: return "scene_like";
    case FamilyName::near_tangent: return "near_tangent";
  }
  return "unknown";
}

// Built once per process and cutoff (only the near-tangent set depends on
// it); as_float: the pairs rounded to float, with their own exact mu^2.
const Classified& family(FamilyName name, double cutoff, bool as_float) {
  static std::map<std::tuple<FamilyName, double, bool>, Classified> cache;
  const auto key = std::make_tuple(name, name == FamilyName::near_tangent ? cutoff : 1.0, as_float);
  const auto found = cache.find(key);
  if (found != cache.end()) return found->second;
  Classified built;
  if (as_float) {
    built = with_oracle(convert_all<double>(convert_all<float>(family(name, cutoff, false).pairs)));
  } else {
    switch (name) {
      case FamilyName::random: built = with_oracle(make_random_pairs(20000, 93)); break;
      case FamilyName::pw85: built = with_oracle(pairs_of(pwcontact::pw85_family())); break;
      case FamilyName::scene_like: built = scene_like_mix(); break;
      case FamilyName::near_tangent: built = near_tangent(cutoff); break;
    }
  }
  built.batch = make_batch(built.pairs);
  return cache.emplace(key, std::move(built)).first->second;
}

// How the pairs are given and solved: double pairs in a precision, or the
// pairs rounded to float (classified against their own mu^2).
struct Setting {
  Precision precision;
  bool float_pairs;
  int iterations;
};

std::string setting_name(const Setting& s) {
  return std::string(s.float_pairs ? "float pairs" : pwcontact::precision_name(s.precision)) +
         ", iterations " + std::to_string(s.iterations);
}

std::vector<Setting> every_setting() {
  std::vector<Setting> out;
  for (int iterations : {0, 2}) {
    for (Precision p : {Precision::double_precision, Precision::mixed, Precision::single_precision})
      out.push_back({p, false, iterations});
    out.push_back({Precision::single_precision, true, iterations});
  }
  return out;
}

// The accounting every overlap report must satisfy: each valid pair is
// decided exactly once, by a prefilter, a certificate or the reference path.
void expect_report_accounts_for_every_pair(const OverlapRun& run, std::size_t valid,
                                           const std::string& what) {
  const BatchReport& r = run.report;
  EXPECT_EQ(r.decided_by_prefilter + r.decided_by_certificate + r.fallbacks, valid) << what;
  EXPECT_EQ(r.pairs, run.overlap.size()) << what;
  EXPECT_EQ(r.pairs - r.invalid, valid) << what;
  std::size_t overlapping = 0;
  for (std::uint8_t o : run.overlap) overlapping += o;
  EXPECT_EQ(r.overlapping, overlapping) << what;
}

struct Classification {
  std::size_t wrong = 0, in_band = 0, first_wrong = 0, malformed = 0;
};

// Compares every answer outside the band with mu^2 < cutoff^2; counts the
// answers that are not a valid status with overlap 0 or 1.
Classification classify(const OverlapRun& run, const std::vector<long double>& mu2, double cutoff) {
  Classification c;
  const long double c2 = (long double)cutoff * cutoff;
  for (std::size_t i = 0; i < mu2.size(); ++i) {
    c.malformed += !pwcontact::is_valid(run.status[i]) || run.overlap[i] > 1;
    if (std::fabs(mu2[i] - c2) <= decided_band * c2) {
      ++c.in_band;
      continue;
    }
    if ((run.overlap[i] == 1) != (mu2[i] < c2) && c.wrong++ == 0) c.first_wrong = i;
  }
  return c;
}

void expect_agrees_with_exact(const Classified& f, const Setting& setting, Isa isa, double cutoff,
                              const std::string& what) {
  const BatchOptions options = with_precision(with_isa(isa, setting.iterations), setting.precision);
  // The float family's pairs are floats widened: to_float gives them back exactly.
  const OverlapRun run = setting.float_pairs
                             ? run_overlap(pwcontact::to_float(f.batch), options, cutoff)
                             : run_overlap(f.batch, options, cutoff);
  const Classification c = classify(run, f.mu2, cutoff);
  EXPECT_EQ(c.malformed, 0u) << what << ": answers that are not a valid status and 0 or 1";
  const BatchReport& r = run.report;
  std::printf(
      "[ measured ] %s: %zu wrong outside the band (%zu in it); decided by prefilter %zu, "
      "certificate %zu, reference %zu; %.2f evaluations per pair\n",
      what.c_str(), c.wrong, c.in_band, r.decided_by_prefilter, r.decided_by_certificate,
      r.fallbacks, r.mean_evaluations);
  EXPECT_EQ(c.wrong, 0u) << what << ", first pair " << c.first_wrong << ": mu2 "
                         << double(f.mu2[c.first_wrong]) << ", overlap "
                         << int(run.overlap[c.first_wrong]);
  expect_report_accounts_for_every_pair(run, f.mu2.size(), what);
}

// Needles and discs (semi-axes 1, 1 and an aspect ratio of 10^2 .. 10^4,
// or the flat counterpart), random orientations (cond(Q(lambda*)) up to
// ~1e8, the documented reach of the band), at 2e-9 .. 1e-7 of tangency,
// both sides: the pairs the kernels leave go to the reference path, whose
// double answer errs by up to ~16 eps cond (4e-7). Was: 7 of 7,985 such
// pairs answered on the wrong side (status ok_fallback), the first of them
// below, 6.3e-9 beyond tangency at cond 7e7; the long-double path now
// decides near the cutoff. The oracle: the 50-digit one (long double, the
// path that decides, would not be an independent check).
Classified ill_conditioned_near_tangent() {
  std::mt19937_64 engine(97);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<Pair<double>> shapes;
  Pair<double> first;
  first.r12 = {9.474108888637145, 16.844973084334445, 6.521373887934123};
  first.q1 = {78931354.57929142,  122418605.71880941, -35223678.58431226,
              189865179.39624625, -54630175.80618247, 15718820.627493534};
  first.q2 = {2448.658518896454,  23502.06296282362,  -96831.35096673893,
              225624.57360074657, -929598.2600353714, 3830058.194158628};
  auto form = [&]() {
    const double aspect = std::pow(10.0, 2 + 2 * unit(engine));
    const Eigen::Vector3d axes =
        unit(engine) < 0.5 ? Eigen::Vector3d(1, 1, aspect) : Eigen::Vector3d(aspect, aspect, 1);
    const Eigen::Matrix3d r = random_rotation(engine);
    return pack(r * axes.cwiseProduct(axes).asDiagonal() * r.transpose());
  };
  for (int k = 0; k < 3000; ++k) {
    Pair<double> p;
    p.q1 = form();
    p.q2 = form();
    const Eigen::Matrix3d r = random_rotation(engine);
    for (int d = 0; d < 3; ++d) p.r12[d] = r(d, 0);
    shapes.push_back(p);
  }
  const auto base = long_double_oracles(shapes);
  std::vector<Pair<double>> pairs = {first};
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const long double offset = std::pow(10.0L, -8.7L + 1.7L * (long double)unit(engine));
    pairs.push_back(scaled_to_mu2(shapes[i], base[i].mu2, i % 2 ? 1 + offset : 1 - offset));
  }
  Classified out{std::move(pairs), {}, {}};
  for (const auto& result : fifty_digit_oracles(out.pairs)) {
    EXPECT_EQ(result.status, Status::ok);
    out.mu2.push_back(result.mu2);
  }
  out.batch = make_batch(out.pairs);
  return out;
}

TEST(OverlapFallback, IllConditionedPairsNearTangencyAreDecidedOnTheirSide) {
  const Classified f = ill_conditioned_near_tangent();
  for (Isa isa : isas())
    for (Precision precision : {Precision::double_precision, Precision::mixed}) {
      const std::string what = std::string("needles and discs near tangency, ") +
                               pwcontact::isa_name(isa) + ", " +
                               pwcontact::precision_name(precision);
      const OverlapRun run = run_overlap(f.batch, with_precision(with_isa(isa, 0), precision), 1.0);
      const Classification c = classify(run, f.mu2, 1.0);
      std::printf("[ measured ] %s: %zu wrong outside the band (%zu in it), %zu by the reference\n",
                  what.c_str(), c.wrong, c.in_band, run.report.fallbacks);
      EXPECT_EQ(c.malformed, 0u) << what;
      EXPECT_EQ(c.wrong, 0u) << what << ", first pair " << c.first_wrong
                             << ": mu2 - 1 = " << double(f.mu2[c.first_wrong] - 1) << ", overlap "
                             << int(run.overlap[c.first_wrong]);
      EXPECT_GT(run.report.fallbacks, 500u) << what << ": the pairs reach the reference path";
    }
}

// The three ways the tests below ask for overlap answers: double pairs in
// double and in mixed precision, and the pairs rounded to float.
enum class OverlapWay { double_pairs, mixed, float_pairs };
constexpr OverlapWay overlap_ways[] = {OverlapWay::double_pairs, OverlapWay::mixed,
                                       OverlapWay::float_pairs};
const char* way_name(OverlapWay way) {
  return way == OverlapWay::float_pairs ? "float pairs"
         : way == OverlapWay::mixed     ? "mixed"
                                        : "double";
}
OverlapRun run_overlap_way(const PairBatch<double>& batch, Isa isa, OverlapWay way) {
  if (way == OverlapWay::float_pairs)
    return run_overlap(pwcontact::to_float(batch), with_isa(isa, 0), 1.0);
  const Precision precision =
      way == OverlapWay::mixed ? Precision::mixed : Precision::double_precision;
  return run_overlap(batch, with_precision(with_isa(isa, 0), precision), 1.0);
}

// Pairs symmetric about the plane halfway between their centres: r12 along
// x and Q2 the mirror image of Q1 (the signs of its xy and xz entries
// flipped, exact in floating point), as in the pw85 family. Their lambda* is
// 1/2, where the radial guess lands, and g is exactly 0 there. Discs and
// needles of aspect ratio 10 .. 500, overlapping (mu^2 in [0.01, 0.8], where
// the radial bound, eq. 31, decides little: r12 crosses the thin
// directions) and apart (mu^2 in [1.25, 4]). Was: a lane with g = 0 kept
// the upper bound of its first guess and took the same evaluation again up
// to the cap of 40, then the reference path (1,216 pairs of the pw85
// family, all overlapping, mu^2 ~ 0.002 .. 0.13); the scalar certificates
// left such pairs undecided. The horizontal tangent there bounds mu^2 by f.
Classified mirror_symmetric_pairs() {
  Engine engine(98);
  std::vector<Pair<double>> shapes;
  for (int k = 0; k < 2000; ++k) {
    const double aspect = std::pow(10.0, 1 + 1.7 * uniform01(engine));
    const Eigen::Vector3d axes =
        k % 2 ? Eigen::Vector3d(1, 1, aspect) : Eigen::Vector3d(aspect, aspect, 1);
    const Eigen::Matrix3d rotation = random_rotation(engine);
    Pair<double> p;
    p.r12 = {1, 0, 0};
    p.q1 = pack(rotation * axes.cwiseProduct(axes).asDiagonal() * rotation.transpose());
    p.q2 = p.q1;
    p.q2[1] = -p.q1[1];  // (x -> -x: Q2 = P Q1 P with P = diag(-1, 1, 1))
    p.q2[2] = -p.q1[2];
    shapes.push_back(p);
  }
  const auto base = long_double_oracles(shapes);
  std::vector<Pair<double>> pairs;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const long double u = (long double)uniform01(engine);
    const long double target = i % 2 ? std::pow(80.0L, u) / 100 : 1.25L * std::pow(3.2L, u);
    pairs.push_back(scaled_to_mu2(shapes[i], base[i].mu2, target));
  }
  return with_oracle(std::move(pairs));
}

TEST(OverlapSymmetric, PairsSymmetricAboutTheMidplaneAreDecidedByTheKernels) {
  Classified f = mirror_symmetric_pairs();
  f.batch = make_batch(f.pairs);
  for (Isa isa : isas())
    for (OverlapWay way : overlap_ways) {  // (rounding to float keeps the mirror exact)
      const std::string what = std::string("pairs symmetric about the midplane, ") +
                               pwcontact::isa_name(isa) + ", " + way_name(way);
      const OverlapRun run = run_overlap_way(f.batch, isa, way);
      const Classification c = classify(run, f.mu2, 1.0);
      std::printf("[ measured ] %s: %zu wrong, %zu by the reference, %.2f evaluations per pair\n",
                  what.c_str(), c.wrong, run.report.fallbacks, run.report.mean_evaluations);
      EXPECT_EQ(c.malformed, 0u) << what;
      EXPECT_EQ(c.wrong, 0u) << what << ", first pair " << c.first_wrong;
      // mu^2 is at least 20 % from the cutoff, beyond any margin (256 eps times
      // growths up to ~1e6 in double): nothing is left to the reference path.
      if (isa != Isa::fallback && !on_portable_target()) {
        EXPECT_EQ(run.report.fallbacks, 0u) << what << ": pairs left to the reference path";
      }
    }
  for (std::size_t i = 0; i < f.pairs.size(); ++i) {
    const Pair<double>& p = f.pairs[i];
    const pwcontact::screen::Certified answer =
        pwcontact::screen::certify_overlap(p.r12.data(), p.q1.data(), p.q2.data(), 1.0);
    ASSERT_NE(answer, pwcontact::screen::Certified::undecided)
        << "scalar certificates, pair " << i << ": mu2 " << double(f.mu2[i]);
    EXPECT_EQ(answer == pwcontact::screen::Certified::overlapping, f.mu2[i] < 1)
        << "scalar certificates, pair " << i;
  }
}

// Needles tip to tip and discs face to face on a shared axis, turned by one
// random rotation: the extents along r12 (eqs. 31, 32) are exact for them,
// so what keeps a decision on its side near tangency is the margin alone.
// Their forms are beyond the cheap pass's trace test (needles of aspect 4
// .. 16, tr^3 / det ~ a^4; discs of aspect 6 .. 160, ~8 a^2; double needles
// to aspect 1000), so in float and mixed precision every lane takes its own
// margin, 256 eps rho (eq. 47), where rho grows as ~0.2 a^4 (needles) and
// ~0.6 a^2 (discs) and the rounding of the extents with it. mu^2 is 1 +- delta,
// delta log-uniform in [1e-6, 0.3], across those margins; the oracle is the
// 50-digit one on the pairs as each run reads them (float pairs rounded).
// With a margin of 256 eps, without rho, float pairs and mixed precision
// answer pairs on the wrong side.
struct CoaxialFamily {
  Classified pairs, as_float;
};
CoaxialFamily coaxial_elongated_pairs() {
  Engine engine(99);
  std::vector<Pair<double>> shapes;
  for (int k = 0; k < 1200; ++k) {
    const int kind = k % 3;  // needles, discs, long needles
    const double spread = kind == 0 ? 4 : kind == 1 ? 6 : 16;
    const double top = kind == 0 ? 16 : kind == 1 ? 160 : 1000;
    auto aspect = [&] { return spread * std::pow(top / spread, uniform01(engine)); };
    const double a = aspect(), b = aspect();
    const Eigen::Matrix3d rotation = random_rotation(engine);
    auto form = [&](double x) {
      const Eigen::Vector3d axes = kind == 1 ? Eigen::Vector3d(1, x, x) : Eigen::Vector3d(x, 1, 1);
      return pack(rotation * axes.cwiseProduct(axes).asDiagonal() * rotation.transpose());
    };
    Pair<double> p;
    for (int d = 0; d < 3; ++d) p.r12[std::size_t(d)] = rotation(d, 0);
    p.q1 = form(a);
    p.q2 = form(b);
    shapes.push_back(p);
  }
  const auto base = long_double_oracles(shapes);
  std::vector<Pair<double>> pairs;
  for (std::size_t i = 0; i < shapes.size(); ++i) {
    const long double delta = 1e-6L * std::pow(3e5L, (long double)uniform01(engine));
    pairs.push_back(scaled_to_mu2(shapes[i], base[i].mu2, i % 2 ? 1 + delta : 1 - delta));
  }
  CoaxialFamily out;
  auto with_fifty_digits = [](std::vector<Pair<double>> set) {
    Classified c{std::move(set), {}, {}};
    for (const auto& result : fifty_digit_oracles(c.pairs)) {
      EXPECT_EQ(result.status, Status::ok);
      c.mu2.push_back(result.mu2);
    }
    c.batch = make_batch(c.pairs);
    return c;
  };
  out.as_float = with_fifty_digits(convert_all<double>(convert_all<float>(pairs)));
  out.pairs = with_fifty_digits(std::move(pairs));
  return out;
}

TEST(OverlapOwnMargin, CoaxialElongatedPairsAreDecidedOnTheirSide) {
  const CoaxialFamily f = coaxial_elongated_pairs();
  for (Isa isa : isas())
    for (OverlapWay way : overlap_ways) {
      const Classified& set = way == OverlapWay::float_pairs ? f.as_float : f.pairs;
      const std::string what = std::string("coaxial needles and discs, ") +
                               pwcontact::isa_name(isa) + ", " + way_name(way);
      const OverlapRun run = run_overlap_way(set.batch, isa, way);
      const Classification c = classify(run, set.mu2, 1.0);
      const BatchReport& r = run.report;
      std::printf(
          "[ measured ] %s: %zu wrong outside the band (%zu in it); decided by prefilter %zu, "
          "certificate %zu, reference %zu\n",
          what.c_str(), c.wrong, c.in_band, r.decided_by_prefilter, r.decided_by_certificate,
          r.fallbacks);
      EXPECT_EQ(c.malformed, 0u) << what;
      EXPECT_EQ(c.wrong, 0u) << what << ", first pair " << c.first_wrong
                             << ": mu2 - 1 = " << double(set.mu2[c.first_wrong] - 1) << ", overlap "
                             << int(run.overlap[c.first_wrong]);
      expect_report_accounts_for_every_pair(run, set.mu2.size(), what);
      // The extents decide the pairs beyond their margins: about half here.
      if (isa != Isa::fallback && !on_portable_target()) {
        EXPECT_GT(r.decided_by_prefilter, set.mu2.size() / 4) << what;
      }
    }
}

class Overlap : public ::testing::TestWithParam<std::tuple<FamilyName, Isa>> {};

TEST_P(Overlap, AgreesWithTheExactClassificationOutsideTheDocumentedBand) {
  const auto& [name, isa] = GetParam();
  for (double cutoff : {1.0, 0.8, 1.2})
    for (const Setting& setting : every_setting()) {
      const std::string what = std::string(family_name(name)) + ", cutoff " +
                               testing::PrintToString(cutoff) + ", " + pwcontact::isa_name(isa) +
                               ", " + setting_name(setting);
      expect_agrees_with_exact(family(name, cutoff, setting.float_pairs), setting, isa, cutoff,
                               what);
    }
}

INSTANTIATE_TEST_SUITE_P(EveryFamilyAndIsa, Overlap,
                         ::testing::Combine(::testing::Values(FamilyName::random, FamilyName::pw85,
                                                              FamilyName::scene_like,
                                                              FamilyName::near_tangent),
                                            ::testing::ValuesIn(isas())),
                         [](const auto& info) {
                           return std::string(family_name(std::get<0>(info.param))) + "_" +
                                  pwcontact::isa_name(std::get<1>(info.param));
                         });

// ---------------------------------------------------------------------------
// The scalar certificates a moving scene takes before its kernels
// (screen::certify_overlap, the bounds of eqs. 27, 29 and 31 with eq. 40's
// margins): a decision is a bound clearing the cutoff by at least its
// margin (>= 256 eps), so every pair they decide must be decided as the
// oracle classifies it, near tangency too (the oracle's mu^2 errs by ~1e-16
// or less: long double, or exact for the near-tangent set). Without the
// margins, 8 evaluations decide one near-tangent pair wrongly. And they
// decide most pairs away from tangency, which is what they are for.

class OverlapCertificates : public ::testing::TestWithParam<FamilyName> {};

TEST_P(OverlapCertificates, DecideOnlyAsTheExactClassificationDoes) {
  const FamilyName name = GetParam();
  for (double cutoff : {1.0, 0.8, 1.2}) {
    const Classified& f = family(name, cutoff, false);
    const long double c2 = (long double)cutoff * cutoff;
    for (int evaluations : {0, 1, 2, 8}) {
      std::size_t decided = 0, wrong = 0, far = 0, far_decided = 0, first_wrong = 0;
      for (std::size_t i = 0; i < f.pairs.size(); ++i) {
        const Pair<double>& p = f.pairs[i];
        const pwcontact::screen::Certified answer = pwcontact::screen::certify_overlap(
            p.r12.data(), p.q1.data(), p.q2.data(), cutoff * cutoff, evaluations);
        const bool is_decided = answer != pwcontact::screen::Certified::undecided;
        const bool far_from_tangency = std::fabs(f.mu2[i] - c2) > 0.01L * c2;
        decided += is_decided;
        far += far_from_tangency;
        far_decided += far_from_tangency && is_decided;
        const bool overlapping = answer == pwcontact::screen::Certified::overlapping;
        if (is_decided && overlapping != (f.mu2[i] < c2) && wrong++ == 0) first_wrong = i;
      }
      const std::string what = std::string(family_name(name)) + ", cutoff " +
                               testing::PrintToString(cutoff) + ", " + std::to_string(evaluations) +
                               " evaluations";
      std::printf(
          "[ measured ] %s: %zu of %zu pairs decided, %zu of the %zu beyond 1 %% of "
          "tangency\n",
          what.c_str(), decided, f.pairs.size(), far_decided, far);
      EXPECT_EQ(wrong, 0u) << what << ", first pair " << first_wrong << ": mu2 "
                           << double(f.mu2[first_wrong]);
      // (Measured: 2 evaluations decide every pair beyond 1 % of tangency
      // on the random and scene-like families, 97.7-98.8 % on pw85's.)
      if (evaluations >= 2 && far > 0) {
        EXPECT_GE(double(far_decided), 0.95 * double(far)) << what;
      }
    }
  }
}

// The same at scales from 2^-530 (forms with subnormal entries) to 2^500:
// the scene-like pairs with r12 scaled by 2^k and the forms by 2^2k, each
// set with the oracle's mu^2 of its own (rounded) inputs. The certificates
// scale the pair back first, so they decide as many pairs wherever the
// scaled inputs are exact (|k| <= 500), and none wrongly anywhere.
TEST(OverlapCertificates, DecideOnlyAsTheOracleDoesAtExtremeScales) {
  const Classified& base = family(FamilyName::scene_like, 1, false);
  const std::vector<Pair<double>> shapes(base.pairs.begin(), base.pairs.begin() + 4000);
  std::size_t decided_at_unit_scale = 0;
  for (int k : {0, -530, -500, -250, 250, 500}) {
    std::vector<Pair<double>> scaled = shapes;
    for (Pair<double>& p : scaled) {
      for (double& x : p.r12) x = std::ldexp(x, k);
      for (double& x : p.q1) x = std::ldexp(x, 2 * k);
      for (double& x : p.q2) x = std::ldexp(x, 2 * k);
    }
    const Classified f = with_oracle(scaled);
    std::size_t decided = 0, wrong = 0;
    for (std::size_t i = 0; i < f.pairs.size(); ++i) {
      const Pair<double>& p = f.pairs[i];
      const pwcontact::screen::Certified answer =
          pwcontact::screen::certify_overlap(p.r12.data(), p.q1.data(), p.q2.data(), 1.0);
      if (answer == pwcontact::screen::Certified::undecided) continue;
      ++decided;
      wrong += (answer == pwcontact::screen::Certified::overlapping) != (f.mu2[i] < 1);
    }
    std::printf("[ measured ] scale 2^%d: %zu of %zu pairs decided\n", k, decided, f.pairs.size());
    EXPECT_EQ(wrong, 0u) << "scale 2^" << k;
    if (k == 0) decided_at_unit_scale = decided;
    if (k >= -500) {
      EXPECT_EQ(decided, decided_at_unit_scale) << "scale 2^" << k;
    }
  }
  EXPECT_GT(decided_at_unit_scale, 3900u);
}

INSTANTIATE_TEST_SUITE_P(EveryFamily, OverlapCertificates,
                         ::testing::Values(FamilyName::random, FamilyName::pw85,
                                           FamilyName::scene_like, FamilyName::near_tangent),
                         [](const auto& info) { return std::string(family_name(info.param)); });

// ---------------------------------------------------------------------------

// Invalid pairs among valid ones: overlap 0 and the status the reference path
// gives them; the valid ones are still accounted for.
TEST(OverlapCall, InvalidPairsGiveOverlapZeroAndTheirStatus) {
  auto pairs = make_random_pairs(500, 94);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t i = 0; i < pairs.size(); i += 7) {
    switch (i % 4) {
      case 0: pairs[i].r12[2] = nan; break;
      case 1: pairs[i].q1 = {1, 2, 0, 1, 0, 1}; break;  // indefinite
      case 2: pairs[i].q2 = {1, 0, 0, 1, 0, 0}; break;  // singular
      default: pairs[i].q2[4] = std::numeric_limits<double>::infinity(); break;
    }
  }
  for (Isa isa : isas()) {
    const OverlapRun run = run_overlap(make_batch(pairs), with_isa(isa));
    std::size_t valid = 0;
    for (std::size_t i = 0; i < pairs.size(); ++i) {
      const Status expected = reference(pairs[i]).status;
      valid += pwcontact::is_valid(expected);
      if (pwcontact::is_valid(expected)) continue;
      EXPECT_EQ(run.status[i], expected) << pwcontact::isa_name(isa) << ", pair " << i;
      EXPECT_EQ(run.overlap[i], 0) << pwcontact::isa_name(isa) << ", pair " << i;
    }
    EXPECT_EQ(run.report.invalid, pairs.size() - valid);
    EXPECT_GT(run.report.invalid, 0u);
    expect_report_accounts_for_every_pair(run, valid, pwcontact::isa_name(isa));
  }
}

TEST(OverlapCall, NullStatusGivesTheSameAnswers) {
  const PairBatch<double> batch = make_batch(make_random_pairs(3000, 95));
  for (Isa isa : isas()) {
    const OverlapRun with = run_overlap(batch, with_isa(isa), 1, true);
    const OverlapRun without = run_overlap(batch, with_isa(isa), 1, false);
    EXPECT_EQ(with.overlap, without.overlap) << pwcontact::isa_name(isa);
    EXPECT_EQ(with.report.fallbacks, without.report.fallbacks) << pwcontact::isa_name(isa);
  }
}

template <class T>
void expect_bad_cutoffs_rejected() {
  const PairBatch<T> batch = make_batch(convert_all<T>(make_random_pairs(10, 96)));
  const double infinity = std::numeric_limits<double>::infinity();
  for (double cutoff : {0.0, -0.0, -1.0, std::nan(""), infinity, -infinity})
    EXPECT_THROW(run_overlap(batch, {}, cutoff), std::invalid_argument) << "cutoff " << cutoff;
}

TEST(OverlapCall, CutoffThatIsNotPositiveAndFiniteThrows) {
  expect_bad_cutoffs_rejected<double>();
  expect_bad_cutoffs_rejected<float>();
}

TEST(OverlapCall, NullOverlapThrows) {
  const PairBatch<double> batch = make_batch(make_random_pairs(10, 97));
  std::vector<Status> status(batch.size());
  EXPECT_THROW(pwcontact::overlap_batch(batch.view(), {nullptr, status.data()}),
               std::invalid_argument);
}

}  // namespace
}  // namespace pwtest
