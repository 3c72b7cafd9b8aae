// The per-type shapes of a GSD file (particles/type_shapes): one JSON object
// per type, of which the ellipsoids are {"type": "Ellipsoid", "a": .., "b":
// .., "c": ..} (semi-axes) and {"type": "Sphere", "diameter": ..}; in 2D the
// Ellipsoid's a and b are an ellipse's (and {"type": "Ellipse", "a", "b"} is
// taken too). A small parser for these flat
// objects (strings, numbers; nested values skipped), nothing more.
#pragma once

#include <array>
#include <exception>
#include <string>

namespace pwcontact::detail {

struct ShapeAxes {
  std::array<double, 3> a;  // semi-axes (in 2D the ellipse's a, b, then min(a, b))
};

// Throws std::invalid_argument naming what is wrong: not JSON, not an
// ellipsoid or a sphere, a missing or non-positive semi-axis.
ShapeAxes parse_shape(const std::string& json, bool two_dimensional);

// The ParticleStore's message about particle i without its "particle i: ",
// for a reader that names the particle its own way (atom id, line, frame).
inline std::string store_message(const std::exception& e, std::size_t i) {
  std::string what = e.what();
  const std::string prefix = "particle " + std::to_string(i) + ": ";
  if (what.rfind(prefix, 0) == 0) what.erase(0, prefix.size());
  return what;
}

}  // namespace pwcontact::detail
