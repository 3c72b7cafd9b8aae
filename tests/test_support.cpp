#include "test_support.hpp"

#include <Eigen/Eigenvalues>
#include <boost/multiprecision/cpp_bin_float.hpp>
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

using Float50 = boost::multiprecision::cpp_bin_float_50;

std::vector<ContactResult<long double>> fifty_digit_oracles(
    const std::vector<Pair<double>>& pairs) {
  std::vector<ContactResult<long double>> out(pairs.size());
  const std::ptrdiff_t n = std::ptrdiff_t(pairs.size());
#pragma omp parallel for schedule(dynamic, 4)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    const ContactResult<Float50> exact = reference(convert<Float50>(pairs[i]));
    out[i] = {exact.mu2.convert_to<long double>(), exact.lambda.convert_to<long double>(),
              exact.status, exact.iterations};
  }
  return out;
}

Pair<double> scaled_to_mu2(const Pair<double>& p, long double mu2, long double target) {
  Pair<double> out = p;
  pwcontact::scale_r12(out.r12.data(), pwcontact::scale_to_mu2(mu2, target));
  return out;
}

const char* tangent_kind_name(TangentKind kind) {
  switch (kind) {
    case TangentKind::spheres: return "spheres";
    case TangentKind::coaxial_spheroids: return "coaxial spheroids";
    case TangentKind::general: return "general";
    case TangentKind::elongated: return "elongated";
  }
  return "unknown";
}

namespace {

// The nominal offsets of mu^2 / c^2 from 1: 1e-3 down to 1e-14, both signs.
std::vector<double> tangent_offsets() {
  std::vector<double> out;
  for (int e = 3; e <= 14; ++e)
    for (double sign : {1.0, -1.0}) out.push_back(sign * std::pow(10.0, -e));
  return out;
}

// A closed-form kind: r12 = d n with d = (rho1 + rho2) c sqrt(1 + offset),
// where rho_i is the extent of ellipsoid i along the unit vector n (an axis
// of both, or any direction for spheres) and rho_i^2 is the stored diagonal
// entry `entry` of Q_i; then mu = |r12| / (rho1 + rho2) exactly, evaluated
// in 50 digits from the stored, rounded r12.
void add_closed_form(std::vector<NearTangent>& out, TangentKind kind, const Pair<double>& shapes,
                     int entry, const std::array<double, 3>& n, double cutoff) {
  const Float50 extent = sqrt(Float50(shapes.q1[entry])) + sqrt(Float50(shapes.q2[entry]));
  for (double offset : tangent_offsets()) {
    const Float50 d = extent * cutoff * sqrt(1 + Float50(offset));
    NearTangent t{shapes, 0, offset, kind};
    Float50 length2 = 0;
    for (int k = 0; k < 3; ++k) {
      t.pair.r12[k] = (d * n[k]).convert_to<double>();
      length2 += Float50(t.pair.r12[k]) * t.pair.r12[k];
    }
    t.mu2 = (length2 / (extent * extent)).convert_to<long double>();
    out.push_back(t);
  }
}

// Shapes from a random family, each at every offset: r12 scaled from the
// exact mu^2 of the base pair, then the exact mu^2 of the rounded pair.
void add_solved(std::vector<NearTangent>& out, TangentKind kind,
                const std::vector<Pair<double>>& bases, double cutoff) {
  const auto base_mu2 = fifty_digit_oracles(bases);
  std::vector<NearTangent> built;
  std::vector<Pair<double>> pairs;
  for (std::size_t b = 0; b < bases.size(); ++b)
    for (double offset : tangent_offsets()) {
      const long double target = (long double)cutoff * cutoff * (1 + (long double)offset);
      pairs.push_back(scaled_to_mu2(bases[b], base_mu2[b].mu2, target));
      built.push_back({pairs.back(), 0, offset, kind});
    }
  const auto exact = fifty_digit_oracles(pairs);
  for (std::size_t i = 0; i < built.size(); ++i) {
    built[i].mu2 = exact[i].mu2;
    out.push_back(built[i]);
  }
}

}  // namespace

std::vector<NearTangent> near_tangent_pairs(double cutoff) {
  std::vector<NearTangent> out;
  std::mt19937_64 engine(81);
  const Eigen::Vector3d random_direction = random_rotation(engine).col(0);
  const std::array<double, 3> x_axis = {1, 0, 0};
  const std::array<double, 3> oblique = {random_direction[0], random_direction[1],
                                         random_direction[2]};
  const std::pair<double, double> radii[] = {{1, 1}, {0.5, 2}, {0.3, 0.7}, {1e-3, 1}, {7, 0.01}};
  for (const auto& [a1, a2] : radii)
    for (const auto& n : {x_axis, oblique})
      add_closed_form(out, TangentKind::spheres,
                      make_pair({0, 0, 0}, pwcontact::sphere(a1), pwcontact::sphere(a2)), 0, n,
                      cutoff);

  // (equatorial, polar) radii of the two spheroids.
  const std::array<double, 4> spheroids[] = {
      {0.5, 2, 2, 0.3}, {1, 1, 0.2, 2}, {3, 1, 1, 3}, {0.1, 1, 1, 0.1}};
  const int diagonal[3] = {0, 3, 5};
  for (int axis = 0; axis < 3; ++axis) {
    std::array<double, 3> n = {0, 0, 0};
    n[axis] = 1;
    for (const auto& s : spheroids)
      add_closed_form(out, TangentKind::coaxial_spheroids,
                      make_pair({0, 0, 0}, pwcontact::spheroid(s[0], s[1], n),
                                pwcontact::spheroid(s[2], s[3], n)),
                      diagonal[axis], n, cutoff);
  }

  add_solved(out, TangentKind::general, make_random_pairs(24, 82), cutoff);
  pwcontact::RandomFamily elongated;
  elongated.min_semi_axis = 0.1;
  elongated.max_semi_axis = 10;
  elongated.log_uniform_axes = true;
  add_solved(out, TangentKind::elongated, make_random_pairs(24, 83, elongated), cutoff);
  return out;
}

namespace {

// Outputs are allocated with guard elements on both sides holding a guard
// value; a write outside [0, n) changes one of them.
constexpr std::size_t guard_elements = 16;

template <class T>
T guard_value() {
  if constexpr (std::is_floating_point_v<T>)
    return T(-12345.25);
  else
    return static_cast<T>(0xA5);
}

// One output array of n elements between guards, or null when not wanted.
template <class T>
class Guarded {
 public:
  Guarded(std::size_t n, bool wanted)
      : n_(n), storage_(wanted ? n + 2 * guard_elements : 0, guard_value<T>()) {}

  T* data() { return storage_.empty() ? nullptr : storage_.data() + guard_elements; }

  // The n elements (none when not wanted); fails the test if a guard changed.
  std::vector<T> take(const std::string& name) const {
    if (storage_.empty()) return {};
    bool intact = true;
    for (std::size_t k = 0; k < guard_elements; ++k)
      intact = intact && storage_[k] == guard_value<T>() &&
               storage_[guard_elements + n_ + k] == guard_value<T>();
    EXPECT_TRUE(intact) << name << " written outside [0, " << n_ << ")";
    return {storage_.begin() + guard_elements, storage_.end() - guard_elements};
  }

 private:
  std::size_t n_;
  std::vector<T> storage_;
};

template <class T>
std::array<Guarded<T>, 3> guarded_components(std::size_t n, bool wanted) {
  return {Guarded<T>(n, wanted), Guarded<T>(n, wanted), Guarded<T>(n, wanted)};
}

template <class T>
Components<T> take_components(const std::array<Guarded<T>, 3>& arrays, const std::string& name) {
  Components<T> out;
  for (int k = 0; k < 3; ++k) out[k] = arrays[k].take(name + "[" + std::to_string(k) + "]");
  return out;
}

// Calls visit(name, array of a, array of b) for every output array of two runs.
template <class RunA, class RunB, class Visit>
void for_each_array(RunA& a, RunB& b, Visit&& visit) {
  visit("mu2", a.mu2, b.mu2);
  visit("lambda", a.lambda, b.lambda);
  visit("status", a.status, b.status);
  for (int k = 0; k < 3; ++k) {
    const std::string index = "[" + std::to_string(k) + "]";
    visit("contact_point" + index, a.contact_point[k], b.contact_point[k]);
    visit("normal" + index, a.normal[k], b.normal[k]);
    visit("gradient" + index, a.gradient[k], b.gradient[k]);
  }
}

template <class T>
bool same_bits(T a, T b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}

template <class T>
std::string printable(T value) {
  if constexpr (std::is_same_v<T, Status>) {
    return pwcontact::status_name(value);
  } else {
    std::ostringstream out;
    out << std::setprecision(std::numeric_limits<T>::max_digits10) << value;
    return out.str();
  }
}

}  // namespace

std::string describe(const Requested& requested) {
  std::string out = "mu2";
  const std::pair<bool, const char*> parts[] = {{requested.lambda, "lambda"},
                                                {requested.status, "status"},
                                                {requested.contact_point, "contact_point"},
                                                {requested.normal, "normal"},
                                                {requested.gradient, "gradient"}};
  for (const auto& [wanted, name] : parts)
    if (wanted) out += std::string("+") + name;
  return out;
}

template <class T>
BatchRun<T> run_batch(const PairBatch<T>& pairs, const BatchOptions& options,
                      const Requested& requested) {
  const std::size_t n = pairs.size();
  Guarded<T> mu2(n, true), lambda(n, requested.lambda);
  Guarded<Status> status(n, requested.status);
  auto contact_point = guarded_components<T>(n, requested.contact_point);
  auto normal = guarded_components<T>(n, requested.normal);
  auto gradient = guarded_components<T>(n, requested.gradient);
  pwcontact::ContactOutputs<T> out{mu2.data(), lambda.data(), status.data()};
  for (int k = 0; k < 3; ++k) {
    out.contact_point[k] = contact_point[k].data();
    out.normal[k] = normal[k].data();
    out.gradient[k] = gradient[k].data();
  }
  BatchRun<T> run;
  run.report = pwcontact::contact_function_batch(pairs.view(), out, options);
  run.mu2 = mu2.take("mu2");
  run.lambda = lambda.take("lambda");
  run.status = status.take("status");
  run.contact_point = take_components(contact_point, "contact_point");
  run.normal = take_components(normal, "normal");
  run.gradient = take_components(gradient, "gradient");
  return run;
}
template BatchRun<double> run_batch(const PairBatch<double>&, const BatchOptions&,
                                    const Requested&);
template BatchRun<float> run_batch(const PairBatch<float>&, const BatchOptions&, const Requested&);

template <class T>
BatchRun<T> select_lanes(const BatchRun<T>& run, const std::vector<std::size_t>& lanes) {
  BatchRun<T> out;
  for_each_array(run, out, [&lanes](const std::string&, const auto& from, auto& to) {
    if (from.empty()) return;
    for (std::size_t i : lanes) to.push_back(from[i]);
  });
  return out;
}
template BatchRun<double> select_lanes(const BatchRun<double>&, const std::vector<std::size_t>&);
template BatchRun<float> select_lanes(const BatchRun<float>&, const std::vector<std::size_t>&);

template <class T>
void append_lanes(BatchRun<T>& to, const BatchRun<T>& from) {
  for_each_array(to, from, [](const std::string&, auto& target, const auto& source) {
    target.insert(target.end(), source.begin(), source.end());
  });
}
template void append_lanes(BatchRun<double>&, const BatchRun<double>&);
template void append_lanes(BatchRun<float>&, const BatchRun<float>&);

template <class T>
void expect_bitwise_equal(const BatchRun<T>& a, const BatchRun<T>& b, const std::string& what) {
  ASSERT_EQ(a.mu2.size(), b.mu2.size()) << what;
  for_each_array(a, b, [&what](const std::string& name, const auto& x, const auto& y) {
    if (x.empty() || y.empty()) return;
    std::size_t differing = 0, first = 0;
    for (std::size_t i = x.size(); i-- > 0;)
      if (!same_bits(x[i], y[i])) {
        ++differing;
        first = i;
      }
    EXPECT_EQ(differing, 0u) << what << ": " << name << " differs in " << differing << " of "
                             << x.size() << " lanes, first lane " << first << ": "
                             << printable(x[first]) << " vs " << printable(y[first]);
  });
}
template void expect_bitwise_equal(const BatchRun<double>&, const BatchRun<double>&,
                                   const std::string&);
template void expect_bitwise_equal(const BatchRun<float>&, const BatchRun<float>&,
                                   const std::string&);

template <class T>
OverlapRun run_overlap(const PairBatch<T>& pairs, const BatchOptions& options, double cutoff,
                       bool with_status) {
  const std::size_t n = pairs.size();
  Guarded<std::uint8_t> overlap(n, true);
  Guarded<Status> status(n, with_status);
  OverlapRun run;
  run.report =
      pwcontact::overlap_batch(pairs.view(), {overlap.data(), status.data()}, options, cutoff);
  run.overlap = overlap.take("overlap");
  run.status = status.take("status");
  return run;
}
template OverlapRun run_overlap(const PairBatch<double>&, const BatchOptions&, double, bool);
template OverlapRun run_overlap(const PairBatch<float>&, const BatchOptions&, double, bool);

BatchOptions with_isa(Isa isa, int iterations, int threads) {
  BatchOptions options;
  options.isa = isa;
  options.iterations = iterations;
  options.threads = threads;
  return options;
}

BatchOptions with_precision(BatchOptions options, pwcontact::Precision precision,
                            pwcontact::Formulation formulation, pwcontact::Accuracy accuracy) {
  options.precision = precision;
  options.formulation = formulation;
  options.accuracy = accuracy;
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

double vector_error(const Vector3L& got, const Vector3L& expected) {
  const long double norm = expected.norm();
  const long double difference = (got - expected).norm();
  if (std::isnan(difference)) return std::numeric_limits<double>::infinity();
  return double(norm > 0 ? difference / norm : difference);
}

template <class T>
std::vector<pwcontact::ContactGeometry<double>> reference_geometries(
    const std::vector<Pair<T>>& pairs, const std::vector<ContactResult<double>>& references) {
  std::vector<pwcontact::ContactGeometry<double>> out;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Pair<double> p = convert<double>(pairs[i]);
    out.push_back(pwcontact::contact_geometry<double>(p.r12.data(), p.q1.data(), p.q2.data(),
                                                      references[i].lambda));
  }
  return out;
}
template std::vector<pwcontact::ContactGeometry<double>> reference_geometries(
    const std::vector<Pair<double>>&, const std::vector<ContactResult<double>>&);
template std::vector<pwcontact::ContactGeometry<double>> reference_geometries(
    const std::vector<Pair<float>>&, const std::vector<ContactResult<double>>&);

template <class T>
void expect_geometry_matches(const BatchRun<T>& run,
                             const std::vector<pwcontact::ContactGeometry<double>>& expected,
                             double tolerance, const std::string& what) {
  MaxError contact_point, normal, gradient;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    ASSERT_TRUE(pwcontact::is_valid(run.status[i])) << what << ", lane " << i;
    if (!run.contact_point[0].empty())
      contact_point.add(
          i, vector_error(lane_vector(run.contact_point, i), as_vector(expected[i].contact_point)));
    if (!run.normal[0].empty())
      normal.add(i, vector_error(lane_vector(run.normal, i), as_vector(expected[i].normal)));
    if (!run.gradient[0].empty())
      gradient.add(i, vector_error(lane_vector(run.gradient, i), as_vector(expected[i].gradient)));
  }
  const std::pair<const char*, const MaxError*> outputs[] = {
      {"contact point", &contact_point}, {"normal", &normal}, {"gradient", &gradient}};
  for (const auto& [name, error] : outputs) {
    if (error->count == 0) continue;
    print_measured(what + ", " + name + " relative error", *error);
    EXPECT_LE(error->value, tolerance) << what << ", " << name << " of lane " << error->index;
  }
}
template void expect_geometry_matches(const BatchRun<double>&,
                                      const std::vector<pwcontact::ContactGeometry<double>>&,
                                      double, const std::string&);
template void expect_geometry_matches(const BatchRun<float>&,
                                      const std::vector<pwcontact::ContactGeometry<double>>&,
                                      double, const std::string&);

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

Tolerances tolerances_for(pwcontact::Precision precision) {
  return precision == pwcontact::Precision::single_precision ? tolerances_of<float>()
                                                             : tolerances_of<double>();
}

template <class T>
LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>& references,
                                        const BatchRun<T>& run, const std::string& label,
                                        const Tolerances& tolerances) {
  LaneErrors errors;
  for (std::size_t i = 0; i < references.size(); ++i) {
    EXPECT_TRUE(pwcontact::is_valid(run.status[i]))
        << label << ", lane " << i << ": " << pwcontact::status_name(run.status[i]);
    errors.mu2.add(i, relative_error(run.mu2[i], references[i].mu2));
    if (!run.lambda.empty())
      errors.lambda.add(i, absolute_error(run.lambda[i], references[i].lambda));
  }
  EXPECT_LE(errors.mu2.value, tolerances.mu2) << label << ", mu2 of lane " << errors.mu2.index;
  EXPECT_LE(errors.lambda.value, tolerances.lambda)
      << label << ", lambda of lane " << errors.lambda.index;
  return errors;
}
template LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>&,
                                                 const BatchRun<double>&, const std::string&,
                                                 const Tolerances&);
template LaneErrors expect_lanes_match_reference(const std::vector<ContactResult<double>>&,
                                                 const BatchRun<float>&, const std::string&,
                                                 const Tolerances&);

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

double ordinary_axis(Engine& engine) { return 0.5 + 1.5 * uniform01(engine); }

pwcontact::QuadraticForm oriented(const std::array<double, 3>& a, const Eigen::Matrix3d& rotation) {
  const Eigen::Vector3d squares(a[0] * a[0], a[1] * a[1], a[2] * a[2]);
  return pack(rotation * squares.asDiagonal() * rotation.transpose());
}

pwcontact::QuadraticForm oriented(const std::array<double, 3>& a, Engine& engine) {
  return oriented(a, random_rotation(engine));
}

pwcontact::QuadraticForm ordinary_shape(Engine& engine, double size) {
  return oriented(
      {size * ordinary_axis(engine), size * ordinary_axis(engine), size * ordinary_axis(engine)},
      engine);
}

double condition_at(const Pair<double>& p, long double lambda) {
  using MatrixL = Eigen::Matrix<long double, 3, 3>;
  const MatrixL q =
      (1 - lambda) * unpack(p.q1).cast<long double>() + lambda * unpack(p.q2).cast<long double>();
  const auto eigenvalues = Eigen::SelfAdjointEigenSolver<MatrixL>(q).eigenvalues();
  if (!(eigenvalues[0] > 0)) return std::numeric_limits<double>::infinity();
  return double(eigenvalues[2] / eigenvalues[0]);
}

Solved solved(std::vector<Pair<double>> pairs) {
  Solved out{std::move(pairs), {}, {}};
  out.exact = fifty_digit_oracles(out.pairs);
  for (std::size_t i = 0; i < out.pairs.size(); ++i)
    out.condition.push_back(out.exact[i].status == Status::ok
                                ? condition_at(out.pairs[i], out.exact[i].lambda)
                                : std::numeric_limits<double>::infinity());
  return out;
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

bool on_portable_target() { return pwcontact::resolve_isa(Isa::automatic) == Isa::fallback; }

ScopedEnvironment::ScopedEnvironment(std::string name, std::optional<std::string> value)
    : name_(std::move(name)) {
  if (const char* old = std::getenv(name_.c_str())) previous_ = old;
  if (value)
    ::setenv(name_.c_str(), value->c_str(), 1);
  else
    ::unsetenv(name_.c_str());
  pwcontact::reread_isa_environment();  // (read once per process otherwise)
}

ScopedEnvironment::~ScopedEnvironment() {
  if (previous_)
    ::setenv(name_.c_str(), previous_->c_str(), 1);
  else
    ::unsetenv(name_.c_str());
  pwcontact::reread_isa_environment();
}

}  // namespace pwtest
