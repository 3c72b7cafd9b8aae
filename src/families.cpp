#include "pwcontact/families.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "pwcontact/ellipsoid.hpp"

namespace pwcontact {
namespace {

constexpr double two_pi = 6.283185307179586476925286766559;

// Uniform in [0, 1) from the top 53 bits: the same numbers on every platform
// (std::uniform_real_distribution is implementation-defined).
double uniform01(std::mt19937_64& engine) { return double(engine() >> 11) * 0x1.0p-53; }

// Uniformly random rotation (Shoemake's subgroup algorithm), as (w, x, y, z).
std::array<double, 4> random_quaternion(std::mt19937_64& engine) {
  const double u1 = uniform01(engine), u2 = uniform01(engine), u3 = uniform01(engine);
  const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
  return {b * std::cos(two_pi * u3), a * std::sin(two_pi * u2), a * std::cos(two_pi * u2),
          b * std::sin(two_pi * u3)};
}

}  // namespace

PairBatch<double> random_pairs(std::size_t n, std::uint64_t seed, const RandomFamily& family) {
  std::mt19937_64 engine(seed);
  PairBatch<double> pairs;
  pairs.reserve(n);
  const double lo = family.min_semi_axis, hi = family.max_semi_axis;
  auto semi_axis = [&] {
    const double u = uniform01(engine);
    return family.log_uniform_axes ? lo * std::pow(hi / lo, u) : lo + (hi - lo) * u;
  };
  for (std::size_t i = 0; i < n; ++i) {
    QuadraticForm q[2];
    for (auto& form : q) {
      const std::array<double, 3> axes{semi_axis(), semi_axis(), semi_axis()};
      form = quadratic_form_from_quaternion(axes, random_quaternion(engine));
    }
    const double distance = family.max_distance * uniform01(engine);
    const double z = 2 * uniform01(engine) - 1, phi = two_pi * uniform01(engine);
    const double rho = std::sqrt(std::max(0.0, 1 - z * z));
    const double r[3] = {distance * rho * std::cos(phi), distance * rho * std::sin(phi),
                         distance * z};
    pairs.push_back(r, q[0].data(), q[1].data());
  }
  return pairs;
}

PairBatch<double> pw85_family() {
  const double radii[3] = {0.01999, 1.999, 9.999};
  const double distances[3] = {0.15, 1.1, 11.0};
  const double g = (1 + std::sqrt(5.0)) / 2;  // golden ratio: icosahedron (0, +-1, +-g) and cyclic
  std::array<double, 3> directions[12];
  int k = 0;
  for (double s1 : {1.0, -1.0})
    for (double s2 : {1.0, -1.0}) {
      directions[k++] = {0, s1, s2 * g};
      directions[k++] = {s2 * g, 0, s1};
      directions[k++] = {s1, s2 * g, 0};
    }
  for (auto& d : directions) {
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (double& x : d) x /= norm;
  }
  std::vector<QuadraticForm> spheroids;
  for (double a : radii)
    for (double c : radii)
      for (const auto& n : directions) spheroids.push_back(spheroid(a, c, n));

  PairBatch<double> pairs;
  pairs.reserve(pw85_family_size);
  for (const auto& q1 : spheroids)
    for (const auto& q2 : spheroids)
      for (const auto& n : directions)
        for (double d : distances) {
          const double r[3] = {d * n[0], d * n[1], d * n[2]};
          pairs.push_back(r, q1.data(), q2.data());
        }
  return pairs;
}

SpheroidScene spheroid_scene(std::size_t n, std::uint64_t seed, double packing, double max_aspect,
                             bool identical_shapes, int threads, const std::function<void(double fraction)>& progress) {
  constexpr std::size_t block = 4096;
  const double volume = 4.0 / 3.0 * 3.14159265358979323846 * 0.125;
  const double length = std::cbrt(double(n) * volume / packing);
  SpheroidScene scene{{}, Box::periodic_box(length, length, length), {}, {}};
  // Identical shapes: one shape type (declared identical to the search).
  if (identical_shapes) {
    const double equatorial = 0.5 / std::cbrt(max_aspect);
    scene.particles.add_type({equatorial, equatorial, equatorial * max_aspect});
  }
  scene.particles.resize(n);
  scene.semi_axes.resize(n);
  scene.orientation.resize(n);
  const std::size_t blocks = (n + block - 1) / block;
  const double log_aspect = std::log(max_aspect);
  std::size_t done = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads > 0 ? threads : omp_get_max_threads())
  for (std::size_t b = 0; b < blocks; ++b) {
    std::mt19937_64 engine(seed * 0x9E3779B97F4A7C15ull + b);
    for (std::size_t i = b * block; i < std::min(n, (b + 1) * block); ++i) {
      const double draw = uniform01(engine);  // drawn either way: the same centres
      const double aspect = identical_shapes ? max_aspect : std::exp(log_aspect * (2 * draw - 1));
      const double equatorial = 0.5 / std::cbrt(aspect);  // a^2 c = 0.5^3
      const std::array<double, 3> centre = {length * uniform01(engine), length * uniform01(engine),
                                            length * uniform01(engine)};
      const std::array<double, 4> q = random_quaternion(engine);  // a unit quaternion
      scene.orientation[i] = q;
      if (identical_shapes) {
        scene.semi_axes[i] = scene.particles.type_semi_axes(0);
        scene.particles.set_typed(i, centre, 0, q);
      } else {
        scene.semi_axes[i] = {equatorial, equatorial, equatorial * aspect};
        scene.particles.set_axes(i, centre, scene.semi_axes[i], q);
      }
    }
    if (progress && omp_get_thread_num() == 0) {
      std::size_t now;
#pragma omp atomic read
      now = done;
      progress(double(now) / double(blocks));
    }
#pragma omp atomic
    ++done;
  }
  return scene;
}

SpheroidScene ellipse_scene(std::size_t n, std::uint64_t seed, double packing, double max_aspect,
                            int threads) {
  constexpr std::size_t block = 4096;
  const double area = 3.14159265358979323846 * 0.25;
  const double length = std::sqrt(double(n) * area / packing);
  SpheroidScene scene{{}, Box::two_dimensional_box(length, length), {}, {}};
  scene.particles.resize(n);
  const std::size_t blocks = (n + block - 1) / block;
  const double log_aspect = std::log(max_aspect);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads > 0 ? threads : omp_get_max_threads())
  for (std::size_t b = 0; b < blocks; ++b) {
    std::mt19937_64 engine(seed * 0x9E3779B97F4A7C15ull + b);
    for (std::size_t i = b * block; i < std::min(n, (b + 1) * block); ++i) {
      const double aspect = std::exp(log_aspect * (2 * uniform01(engine) - 1));
      const double minor = 0.5 / std::sqrt(aspect);  // a b = 0.5^2
      const double x = length * uniform01(engine), y = length * uniform01(engine);
      const double theta = 6.283185307179586 * uniform01(engine);
      scene.particles.set_ellipse(i, x, y, minor * aspect, minor, theta);
    }
  }
  return scene;
}

PairBatch<float> to_float(const PairBatch<double>& pairs) {
  PairBatch<float> out(pairs.size());
  auto copy = [](const std::vector<double>& from, std::vector<float>& to) {
    for (std::size_t i = 0; i < from.size(); ++i) to[i] = float(from[i]);
  };
  for (int k = 0; k < 3; ++k) copy(pairs.r12(k), out.r12(k));
  for (int k = 0; k < 6; ++k) {
    copy(pairs.q1(k), out.q1(k));
    copy(pairs.q2(k), out.q2(k));
  }
  return out;
}

}  // namespace pwcontact
