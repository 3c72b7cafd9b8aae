#include "test_support.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <utility>

namespace pwtest {

std::vector<Pair<double>> make_random_pairs(std::size_t n, std::uint64_t seed,
                                            const pwcontact::RandomFamily& family) {
  return pairs_of(pwcontact::random_pairs(n, seed, family));
}

ContactResult<long double> long_double_oracle(const Pair<double>& p) {
  return reference(convert<long double>(p));
}

template <class T>
std::vector<ContactResult<double>> double_references(const std::vector<Pair<T>>& pairs) {
  std::vector<ContactResult<double>> out(pairs.size());
  const std::ptrdiff_t n = std::ptrdiff_t(pairs.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::ptrdiff_t i = 0; i < n; ++i) out[i] = reference(convert<double>(pairs[i]));
  return out;
}
template std::vector<ContactResult<double>> double_references(const std::vector<Pair<double>>&);
template std::vector<ContactResult<double>> double_references(const std::vector<Pair<float>>&);

std::vector<ContactResult<long double>> long_double_oracles(
    const std::vector<Pair<double>>& pairs) {
  std::vector<ContactResult<long double>> out(pairs.size());
  const std::ptrdiff_t n = std::ptrdiff_t(pairs.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::ptrdiff_t i = 0; i < n; ++i) out[i] = long_double_oracle(pairs[i]);
  return out;
}

namespace {

// Outputs are allocated with guard elements on both sides holding these
// values; a write outside [0, n) changes one of them.
constexpr std::size_t guard_elements = 16;
constexpr Status guard_status = static_cast<Status>(0xA5);
template <class T>
constexpr T guard_value = T(-12345.25);

template <class T>
bool guards_intact(const std::vector<T>& v, T value) {
  const std::size_t n = v.size() - 2 * guard_elements;
  for (std::size_t k = 0; k < guard_elements; ++k)
    if (!(v[k] == value) || !(v[guard_elements + n + k] == value)) return false;
  return true;
}

template <class T>
void strip_guards(std::vector<T>& v) {
  v.erase(v.end() - guard_elements, v.end());
  v.erase(v.begin(), v.begin() + guard_elements);
}

}  // namespace

template <class T>
BatchRun<T> run_batch(const PairBatch<T>& pairs, const BatchOptions& options) {
  const std::size_t n = pairs.size(), padded = n + 2 * guard_elements;
  BatchRun<T> run;
  run.mu2.assign(padded, guard_value<T>);
  run.lambda.assign(padded, guard_value<T>);
  run.status.assign(padded, guard_status);
  run.report = pwcontact::contact_function_batch(
      pairs.view(),
      {run.mu2.data() + guard_elements, run.lambda.data() + guard_elements,
       run.status.data() + guard_elements},
      options);
  EXPECT_TRUE(guards_intact(run.mu2, guard_value<T>)) << "mu2 written outside [0, " << n << ")";
  EXPECT_TRUE(guards_intact(run.lambda, guard_value<T>))
      << "lambda written outside [0, " << n << ")";
  EXPECT_TRUE(guards_intact(run.status, guard_status)) << "status written outside [0, " << n << ")";
  strip_guards(run.mu2);
  strip_guards(run.lambda);
  strip_guards(run.status);
  return run;
}
template BatchRun<double> run_batch(const PairBatch<double>&, const BatchOptions&);
template BatchRun<float> run_batch(const PairBatch<float>&, const BatchOptions&);

namespace {

template <class T>
bool same_bits(T a, T b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

}  // namespace

template <class T>
void expect_bitwise_equal(const BatchRun<T>& a, const BatchRun<T>& b, const std::string& what) {
  ASSERT_EQ(a.mu2.size(), b.mu2.size()) << what;
  std::size_t differing = 0, first = 0;
  for (std::size_t i = a.mu2.size(); i-- > 0;)
    if (!same_bits(a.mu2[i], b.mu2[i]) || !same_bits(a.lambda[i], b.lambda[i]) ||
        a.status[i] != b.status[i]) {
      ++differing;
      first = i;
    }
  EXPECT_EQ(differing, 0u) << what << ": " << differing << " of " << a.mu2.size()
                           << " lanes differ, first lane " << first << ": mu2 "
                           << std::setprecision(std::numeric_limits<T>::max_digits10)
                           << a.mu2[first] << " vs " << b.mu2[first] << ", lambda "
                           << a.lambda[first] << " vs " << b.lambda[first] << ", status "
                           << pwcontact::status_name(a.status[first]) << " vs "
                           << pwcontact::status_name(b.status[first]);
}
template void expect_bitwise_equal(const BatchRun<double>&, const BatchRun<double>&,
                                   const std::string&);
template void expect_bitwise_equal(const BatchRun<float>&, const BatchRun<float>&,
                                   const std::string&);

BatchOptions with_isa(Isa isa, int iterations, int threads) {
  BatchOptions options;
  options.isa = isa;
  options.iterations = iterations;
  options.threads = threads;
  return options;
}

std::vector<Isa> isas() { return pwcontact::supported_isas(); }

std::string isa_param_name(const ::testing::TestParamInfo<Isa>& info) {
  return pwcontact::isa_name(info.param);
}

double relative_error(long double got, long double expected) {
  if (std::isnan(got) || std::isnan(expected)) return std::numeric_limits<double>::infinity();
  const long double difference = std::fabs(got - expected);
  return double(expected == 0 ? difference : difference / std::fabs(expected));
}

double absolute_error(long double got, long double expected) {
  if (std::isnan(got) || std::isnan(expected)) return std::numeric_limits<double>::infinity();
  return double(std::fabs(got - expected));
}

void MaxError::add(std::size_t i, double error) {
  ++count;
  if (!(error <= value)) {  // NaN errors win, so that they are reported
    value = std::isnan(error) ? std::numeric_limits<double>::infinity() : error;
    index = i;
  }
}

void print_measured(const std::string& what, const MaxError& error) {
  std::printf("[ measured ] %s: max %.3g over %zu (at %zu)\n", what.c_str(), error.value,
              error.count, error.index);
  std::fflush(stdout);
}

template <class T>
LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>& references,
                                        const BatchRun<T>& run, const std::string& label) {
  LaneErrors errors;
  for (std::size_t i = 0; i < references.size(); ++i) {
    EXPECT_TRUE(pwcontact::is_valid(run.status[i]))
        << label << ", lane " << i << ": " << pwcontact::status_name(run.status[i]);
    errors.mu2.add(i, relative_error(run.mu2[i], references[i].mu2));
    errors.lambda.add(i, absolute_error(run.lambda[i], references[i].lambda));
  }
  EXPECT_LE(errors.mu2.value, LaneTolerance<T>::mu2)
      << label << ", mu2 of lane " << errors.mu2.index;
  EXPECT_LE(errors.lambda.value, LaneTolerance<T>::lambda)
      << label << ", lambda of lane " << errors.lambda.index;
  return errors;
}
template LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>&,
                                                 const BatchRun<double>&, const std::string&);
template LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>&,
                                                 const BatchRun<float>&, const std::string&);

namespace {

constexpr int reference_fields = 1 + 15 + 2;  // family, inputs, mu2 and lambda

// Parses one data line into `record`; returns an error message or "".
std::string parse_record(const std::string& line, ReferenceRecord& record) {
  std::istringstream in(line);
  std::vector<std::string> fields;
  for (std::string field; in >> field;) fields.push_back(field);
  if (fields.size() != std::size_t(reference_fields))
    return "expected " + std::to_string(reference_fields) + " fields, found " +
           std::to_string(fields.size());

  std::vector<long double> numbers;
  for (std::size_t k = 1; k < fields.size(); ++k) {
    char* end = nullptr;
    errno = 0;
    numbers.push_back(std::strtold(fields[k].c_str(), &end));
    if (*end != '\0' || errno != 0) return "field " + std::to_string(k + 1) + " is not a number";
  }
  record.family = fields[0];
  // Inputs are exact doubles in the file; reading them through double keeps them so.
  for (int k = 0; k < 3; ++k) record.pair.r12[k] = std::strtod(fields[1 + k].c_str(), nullptr);
  for (int k = 0; k < 6; ++k) {
    record.pair.q1[k] = std::strtod(fields[4 + k].c_str(), nullptr);
    record.pair.q2[k] = std::strtod(fields[10 + k].c_str(), nullptr);
  }
  record.mu2 = numbers[15];
  record.lambda = numbers[16];
  return "";
}

}  // namespace

ReferenceTable load_reference_pairs(const std::string& path) {
  ReferenceTable table;
  std::ifstream file(path);
  if (!file) {
    table.error = "cannot open the reference data file " + path + ": " + std::strerror(errno);
    return table;
  }
  std::string line;
  for (int number = 1; std::getline(file, line); ++number) {
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    ReferenceRecord record;
    const std::string problem = parse_record(line, record);
    if (!problem.empty()) {
      table.error = path + ":" + std::to_string(number) + ": " + problem;
      table.records.clear();
      return table;
    }
    table.records.push_back(std::move(record));
  }
  if (table.records.empty()) table.error = "no reference pairs in " + path;
  return table;
}

Eigen::Matrix3d unpack(const std::array<double, 6>& q) {
  Eigen::Matrix3d m;
  m << q[0], q[1], q[2],  //
      q[1], q[3], q[4],   //
      q[2], q[4], q[5];
  return m;
}

std::array<double, 6> pack(const Eigen::Matrix3d& m) {
  return {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)};
}

Eigen::Matrix3d random_rotation(std::mt19937_64& engine) {
  // Shoemake's subgroup algorithm; std::uniform_real_distribution would give
  // different numbers on different standard libraries.
  auto uniform01 = [&engine] { return double(engine() >> 11) * 0x1.0p-53; };
  const double two_pi = 6.283185307179586;
  const double u1 = uniform01(), u2 = uniform01(), u3 = uniform01();
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  const Eigen::Quaterniond q(b * std::cos(two_pi * u3), a * std::sin(two_pi * u2),
                             a * std::cos(two_pi * u2), b * std::sin(two_pi * u3));
  return q.normalized().toRotationMatrix();
}

Pair<double> rotated(const Pair<double>& p, const Eigen::Matrix3d& rotation) {
  Pair<double> out;
  const Eigen::Vector3d r = rotation * Eigen::Vector3d(p.r12[0], p.r12[1], p.r12[2]);
  for (int k = 0; k < 3; ++k) out.r12[k] = r[k];
  out.q1 = pack(rotation * unpack(p.q1) * rotation.transpose());
  out.q2 = pack(rotation * unpack(p.q2) * rotation.transpose());
  return out;
}

Pair<double> scaled(const Pair<double>& p, double k) {
  Pair<double> out;
  for (int i = 0; i < 3; ++i) out.r12[i] = k * p.r12[i];
  for (int i = 0; i < 6; ++i) {
    out.q1[i] = k * k * p.q1[i];
    out.q2[i] = k * k * p.q2[i];
  }
  return out;
}

Pair<double> swapped(const Pair<double>& p) {
  Pair<double> out;
  for (int k = 0; k < 3; ++k) out.r12[k] = -p.r12[k];
  out.q1 = p.q2;
  out.q2 = p.q1;
  return out;
}

Pair<double> make_pair(const std::array<double, 3>& r, const pwcontact::QuadraticForm& q1,
                       const pwcontact::QuadraticForm& q2) {
  return {r, q1, q2};
}

ScopedEnvironment::ScopedEnvironment(std::string name, std::optional<std::string> value)
    : name_(std::move(name)) {
  if (const char* old = std::getenv(name_.c_str())) previous_ = old;
  if (value)
    ::setenv(name_.c_str(), value->c_str(), 1);
  else
    ::unsetenv(name_.c_str());
}

ScopedEnvironment::~ScopedEnvironment() {
  if (previous_)
    ::setenv(name_.c_str(), previous_->c_str(), 1);
  else
    ::unsetenv(name_.c_str());
}

}  // namespace pwtest
