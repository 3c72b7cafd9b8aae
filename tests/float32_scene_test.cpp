// The Monte Carlo example's scene rounded to float32 for a GSD frame
// (cli/float32_scene.hpp): every pair of the rounded scene at mu >= 1 +
// margin, checked on spheres, whose mu is their distance over the sum of
// their radii (an analytic oracle: no solve).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "cli/float32_scene.hpp"

namespace {

using pwcontact::Box;
using pwcontact::cli::Float32Scene;
using pwcontact::cli::round_to_float32;

constexpr double margin = 1e-6;

// Spheres of radius 0.5 at these centres, in a cube of edge `length`.
Float32Scene rounded_spheres(const std::vector<std::array<double, 3>>& centre, double length) {
  const std::vector<std::array<double, 3>> axes(centre.size(), {0.5, 0.5, 0.5});
  const std::vector<std::array<double, 4>> turn(centre.size(), {1, 0, 0, 0});
  return round_to_float32(Box::periodic_box(length, length, length), centre, axes, turn, margin, 1);
}

// The smallest mu of the rounded spheres, in double from the float32
// numbers: the minimum image in the float32 box (twice the reach or more).
double closest_mu(const Float32Scene& s) {
  const std::size_t n = s.position.size() / 3;
  double closest = INFINITY;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      double d2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double l = s.box[std::size_t(k)];
        double d = double(s.position[3 * j + std::size_t(k)]) - s.position[3 * i + std::size_t(k)];
        d -= l * std::round(d / l);
        d2 += d * d;
      }
      closest = std::min(closest, std::sqrt(d2));  // over radii 0.5 + 0.5
    }
  return closest;
}

void expect_inside_the_box(const Float32Scene& s) {
  for (std::size_t i = 0; i < s.position.size(); ++i) {
    const float half = s.box[i % 3] / 2;
    EXPECT_GE(s.position[i], -half) << i;
    EXPECT_LT(s.position[i], half) << i;
  }
}

TEST(Float32Scene, APairRoundedIntoAnOverlapIsScaledApartByTheLeastFactor) {
  // 0.3 and 1.3 + 1e-9 are 1 + 1e-9 apart (mu = 1 + 1e-9); as float32,
  // 0.30000001 and 1.29999995: 0.99999994, an overlap.
  ASSERT_LT(double(1.3f) - double(0.3f), 1.0);
  const Float32Scene s = rounded_spheres({{0.3, 0, 0}, {1.3 + 1e-9, 0, 0}}, 10);
  EXPECT_GE(closest_mu(s), 1 + margin);
  EXPECT_GE(s.mu_min, 1 + margin);
  // The least factor, give or take the float32 ulps of a second rounding:
  // (1 + 1e-6) / 0.99999994 = 1 + 1.06e-6.
  EXPECT_GT(s.scale, 1 + 1e-6);
  EXPECT_LT(s.scale, 1 + 2e-6);
  EXPECT_FLOAT_EQ(s.box[0], float(10 * s.scale));
  EXPECT_EQ(s.box[3], 0.0f);
  expect_inside_the_box(s);
}

TEST(Float32Scene, APairAcrossTheFaceOfTheBoxIsScaledApartToo) {
  // 1 + 1e-9 apart through the periodic face at x = +-5.
  const Float32Scene s = rounded_spheres({{4.65, 1, 2}, {-4.35 + 1e-9, 1, 2}, {0, 0, 0}}, 10);
  EXPECT_GE(closest_mu(s), 1 + margin);
  EXPECT_LT(s.scale, 1 + 1e-5);
  expect_inside_the_box(s);
}

TEST(Float32Scene, PairsFarFromContactAreRoundedWithoutScaling) {
  const std::vector<std::array<double, 3>> centre = {
      {0.3, 0.1, 0.2}, {1.5, 0.1, 0.2}, {-3.2, 2.5, 4.1}, {17.1, -23.3, 2}};
  const Float32Scene s = rounded_spheres(centre, 10);
  EXPECT_EQ(s.scale, 1.0);
  EXPECT_EQ(s.position[0], 0.3f);
  EXPECT_EQ(s.position[3], 1.5f);
  // A centre outside the box is wrapped into [-5, 5): 17.1 - 20, -23.3 + 20.
  EXPECT_FLOAT_EQ(s.position[9], -2.9f);
  EXPECT_FLOAT_EQ(s.position[10], -3.3f);
  EXPECT_GE(closest_mu(s), 1.2 - 1e-6);
  expect_inside_the_box(s);
}

TEST(Float32Scene, ACentreThatRoundsOntoTheUpperFaceIsWrappedToTheLowerOne) {
  // 5 - 1e-10 is inside [-5, 5) in double; as float32 it is 5, outside.
  const Float32Scene s = rounded_spheres({{5 - 1e-10, 0, 0}, {0, 0, 0}}, 10);
  EXPECT_EQ(s.position[0], -5.0f);
  expect_inside_the_box(s);
}

TEST(Float32Scene, TheMonteCarloBoxesOnlyAreTaken) {
  const std::vector<std::array<double, 3>> centre = {{0, 0, 0}};
  const std::vector<std::array<double, 3>> axes = {{0.5, 0.5, 0.5}};
  const std::vector<std::array<double, 4>> turn = {{1, 0, 0, 0}};
  EXPECT_THROW(
      round_to_float32(Box::triclinic(10, 10, 10, 0.1, 0, 0), centre, axes, turn, margin, 1),
      std::invalid_argument);
  EXPECT_THROW(round_to_float32(Box::open(), centre, axes, turn, margin, 1), std::invalid_argument);
  EXPECT_THROW(round_to_float32(Box::periodic_box(10, 10, 10), centre, {}, turn, margin, 1),
               std::invalid_argument);
}

}  // namespace
