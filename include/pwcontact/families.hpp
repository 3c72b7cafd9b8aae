// Standard families of pairs: the same inputs for the tests, the benchmark and
// the demo, reproducible from a seed on every platform.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "pwcontact/batch.hpp"
#include "pwcontact/screen.hpp"

namespace pwcontact {

// Random pairs: independent uniformly random orientations, each semi-axis
// uniform in [min_semi_axis, max_semi_axis] (or log-uniform), centre
// distance uniform in [0, max_distance] along a uniformly random direction.
struct RandomFamily {
  double min_semi_axis = 0.5;
  double max_semi_axis = 2.0;
  double max_distance = 6.0;
  bool log_uniform_axes = false;
};

PairBatch<double> random_pairs(std::size_t n, std::uint64_t seed, const RandomFamily& family = {});

// The peer library's reference family: the 108 spheroids with radii a, c in
// {0.01999, 1.999, 9.999} and axis along one of the 12 icosahedron vertices,
// all 108 x 108 ordered pairs, at r12 = d n for the 12 vertex directions n and
// d in {0.15, 1.1, 11.0}: 419,904 pairs, aspect ratios up to 500.
inline constexpr std::size_t pw85_family_size = 108 * 108 * 12 * 3;
PairBatch<double> pw85_family();

// The same pairs rounded to float.
PairBatch<float> to_float(const PairBatch<double>& pairs);

// A scene of n random spheroids in a periodic cubic box: centres uniform,
// orientations uniform, aspect ratios (polar over equatorial radius)
// log-uniform in [1 / max_aspect, max_aspect], each with the volume of a
// sphere of radius 0.5, the box sized for the packing fraction (total
// spheroid volume over box volume). identical_shapes: every spheroid
// prolate with aspect ratio max_aspect instead, all of one shape type (the
// same shape, only the orientation differs; the same centres). Each block of particles draws from its
// own generator seeded by (seed, block): the same scene on every platform
// and for every thread count.
struct SpheroidScene {
  ParticleStore particles;
  Box box;
  // spheroid_scene: per particle, the semi-axes (a, a, c) along the body
  // axes and the unit quaternion (w, x, y, z) that orients them, from which
  // its Q was made (for moves that turn it). Empty for ellipse_scene.
  std::vector<std::array<double, 3>> semi_axes;
  std::vector<std::array<double, 4>> orientation;
};
SpheroidScene spheroid_scene(std::size_t n, std::uint64_t seed, double packing = 0.3,
                             double max_aspect = 3, bool identical_shapes = false,
                             int threads = 0,
                             const std::function<void(double fraction)>& progress = {});

// A scene of n random ellipses in a periodic square two-dimensional box:
// centres uniform, angles uniform, aspect ratios log-uniform in
// [1 / max_aspect, max_aspect], each with the area of a circle of radius
// 0.5, the box sized for the packing fraction (total ellipse area over box
// area). Reproducible on every platform and thread count, as spheroid_scene.
SpheroidScene ellipse_scene(std::size_t n, std::uint64_t seed, double packing = 0.5,
                            double max_aspect = 3, int threads = 0);

}  // namespace pwcontact
