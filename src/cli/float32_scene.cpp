#include "cli/float32_scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "number_text.hpp"

namespace pwcontact::cli {
namespace {

// x in the float32 box [-l/2, l/2) as the hoomd schema centres it. The
// double is wrapped first, then rounded; a rounding onto l/2 itself is the
// same point as -l/2 (one period away), and one below -l/2 is taken up to it
// (a move of at most an ulp, which the screen of the rounded scene sees).
float wrapped_float(double x, double length, float length_float) {
  double w = x - length * std::floor(x / length + 0.5);
  if (!(w < length / 2)) w -= length;
  const float half = length_float / 2;
  float f = float(w);
  if (f >= half) f = -half;
  return std::max(f, -half);
}

}  // namespace

Float32Scene round_to_float32(const Box& box, const std::vector<std::array<double, 3>>& centre,
                              const std::vector<std::array<double, 3>>& semi_axes,
                              const std::vector<std::array<double, 4>>& orientation, double margin,
                              int threads) {
  const std::size_t n = centre.size();
  if (semi_axes.size() != n || orientation.size() != n)
    throw std::invalid_argument(
        "round_to_float32: centres, semi-axes and orientations differ in count");
  if (!box.periodic || box.two_dimensional || !box.orthorhombic())
    throw std::invalid_argument("round_to_float32: the box must be periodic, 3D and orthorhombic");
  if (!(margin > 0 && margin < 1e-3))
    throw std::invalid_argument("round_to_float32: the margin must lie in (0, 1e-3)");
  Float32Scene out;
  out.position.resize(3 * n);
  out.orientation.resize(4 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 4; ++k) out.orientation[4 * i + k] = float(orientation[i][std::size_t(k)]);
  const double wanted = 1 + margin;
  ScreenOptions options;
  options.cutoff = 1 + 2 * margin;
  options.with_mu2 = true;
  options.threads = threads;
  ScreenedPairs pairs;
  double scale = 1;
  // Each round scales by what the closest pair needs and a little more
  // (2^k float ulps): rounding again moves that pair too.
  for (int round = 0; round < 24; ++round) {
    std::array<double, 3> length{};
    for (int k = 0; k < 3; ++k) {
      out.box[std::size_t(k)] = float(scale * box.length[std::size_t(k)]);
      length[std::size_t(k)] = out.box[std::size_t(k)];
    }
    out.box[3] = out.box[4] = out.box[5] = 0;
    ParticleStore rounded;
    rounded.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      std::array<double, 3> c{};
      for (int k = 0; k < 3; ++k) {
        const float f = wrapped_float(scale * centre[i][std::size_t(k)],
                                      scale * box.length[std::size_t(k)], out.box[std::size_t(k)]);
        out.position[3 * i + std::size_t(k)] = f;
        c[std::size_t(k)] = f;
      }
      const std::array<double, 4> q = {out.orientation[4 * i], out.orientation[4 * i + 1],
                                       out.orientation[4 * i + 2], out.orientation[4 * i + 3]};
      rounded.add_axes(c, semi_axes[i], q);  // (normalised, as readers do)
    }
    screen_pairs(rounded, Box::periodic_box(length[0], length[1], length[2]), options, pairs);
    double mu2_min = options.cutoff * options.cutoff;
    for (double m : pairs.mu2) mu2_min = std::min(mu2_min, m);
    out.mu_min = std::sqrt(mu2_min);
    out.scale = scale;
    if (out.mu_min >= wanted) return out;
    scale *= wanted / std::max(out.mu_min, 0.5) * (1 + std::ldexp(1.0, round - 23));
    if (!(scale < 1 + 1e-3)) break;
  }
  throw std::runtime_error(
      "round_to_float32: no scale up to 1 + 1e-3 keeps the rounded scene's pairs "
      "at mu >= 1 + " +
      pwcontact::detail::number_text(margin) + " (closest " +
      pwcontact::detail::number_text(out.mu_min) + ")");
}

}  // namespace pwcontact::cli
