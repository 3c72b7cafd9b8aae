// A periodic scene in float32, as the hoomd schema of GSD stores it and
// HOOMD-blue reads it: centres wrapped into the box centred on the origin,
// orientations (w, x, y, z) and the box [Lx, Ly, Lz, xy, xz, yz].
//
// Rounding to float32 moves a centre by up to half an ulp of L/2 (1.5e-5
// in a box of 800) and turns a particle by ~1e-7 rad, so a pair that the
// double scene holds just apart can be rounded into an overlap. The rounded
// scene is therefore screened as a reader sees it (float32 numbers,
// quaternions normalised) for any pair with mu < 1 + margin; if there is
// one, every centre and the box are scaled by s > 1 and rounded again. mu^2
// is homogeneous of degree 2 in r12 (eqs. 6 and 11: the maximum over lambda
// of a quadratic form in r12), so scaling every centre and the box by s
// scales every pair's mu, periodic images included, by s: the s that takes
// the closest pair to 1 + margin keeps every other pair apart too.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "pwcontact/pwcontact.hpp"

namespace pwcontact::cli {

struct Float32Scene {
  std::vector<float> position;     // N x 3, in [-L/2, L/2) of the float32 box
  std::vector<float> orientation;  // N x 4, the double quaternions rounded
  std::array<float, 6> box{};      // Lx Ly Lz, tilts 0
  double scale = 1;                // centres and box were scaled by this (>= 1)
  double mu_min = 0;               // the closest pair's mu in the rounded scene (or
                                   // 1 + 2 margin when none is that close)
};

// `centre`, `semi_axes` and unit quaternions `orientation` of N particles
// in an orthorhombic periodic `box` (std::invalid_argument for tilts or an
// open axis), whose pairs are all at mu >= 1: rounded as above, every pair
// of the result at mu >= 1 + margin (std::runtime_error if no scale up to
// 1 + 1e-3 gets there; std::invalid_argument from the screens for a box
// narrower than twice the reach at cutoff 1 + 2 margin). The scale is the
// least the closest pair needs, found again after each rounding, so a
// little above it where float32's ulp is coarse (measured 1 + 1.1e-6 in a
// box of 10, 1 + 5.8e-6 in a box of 1000). `threads` for the screens (0:
// all).
Float32Scene round_to_float32(const Box& box, const std::vector<std::array<double, 3>>& centre,
                              const std::vector<std::array<double, 3>>& semi_axes,
                              const std::vector<std::array<double, 4>>& orientation, double margin,
                              int threads);

}  // namespace pwcontact::cli
