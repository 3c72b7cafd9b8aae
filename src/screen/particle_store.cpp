// The particle store: centres, quadratic forms, and the bounding and
// inscribed radii the screening prefilters use.
#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "pwcontact/ellipsoid.hpp"
#include "pwcontact/screen.hpp"

namespace pwcontact {

Box Box::periodic_box(double lx, double ly, double lz) {
  for (double l : {lx, ly, lz})
    if (!(l > 0) || !std::isfinite(l))
      throw std::invalid_argument("Box: a periodic box needs positive, finite lengths, got " +
                                  std::to_string(l));
  Box box;
  box.periodic = true;
  box.length = {lx, ly, lz};
  return box;
}

void ParticleStore::reserve(std::size_t n) {
  for (auto& v : centre_) v.reserve(n);
  for (auto& v : q_) v.reserve(n);
  bounding_.reserve(n);
  inscribed_.reserve(n);
  sphere_.reserve(n);
}

void ParticleStore::resize(std::size_t n) {
  for (auto& v : centre_) v.resize(n);
  for (auto& v : q_) v.resize(n);
  bounding_.resize(n);
  inscribed_.resize(n);
  sphere_.resize(n);
}

void ParticleStore::add(const std::array<double, 3>& centre, const std::array<double, 6>& q) {
  const std::size_t i = size();
  resize(i + 1);
  try {
    set(i, centre, q);
  } catch (...) {
    resize(i);
    throw;
  }
}

void ParticleStore::set(std::size_t i, const std::array<double, 3>& centre,
                        const std::array<double, 6>& q) {
  const std::string which = "ParticleStore: particle " + std::to_string(i);
  for (double c : centre)
    if (!std::isfinite(c)) throw std::invalid_argument(which + ": centre is not finite");
  for (double v : q)
    if (!std::isfinite(v)) throw std::invalid_argument(which + ": Q is not finite");
  Eigen::Matrix3d m;
  m << q[0], q[1], q[2], q[1], q[3], q[4], q[2], q[4], q[5];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(m, Eigen::EigenvaluesOnly);
  const double smallest = solver.eigenvalues()[0], largest = solver.eigenvalues()[2];
  // The eigenvalues of a symmetric 3x3 matrix computed by Eigen's QR
  // iteration err by a few eps |Q| (backward stable); 64 eps |Q| rounds the
  // radii outwards (bounding) and inwards (inscribed) beyond that, so that
  // both prefilters stay on the safe side.
  const double slack = 64 * std::numeric_limits<double>::epsilon() * std::abs(largest);
  if (!(smallest > slack))
    throw std::invalid_argument(which + ": Q is not positive definite (smallest eigenvalue " +
                                std::to_string(smallest) + ")");
  const double up = 1 + 4 * std::numeric_limits<double>::epsilon();
  for (int k = 0; k < 3; ++k) centre_[k][i] = centre[k];
  for (int k = 0; k < 6; ++k) q_[k][i] = q[k];
  bounding_[i] = std::sqrt(largest + slack) * up;
  inscribed_[i] = std::sqrt(smallest - slack) / up;
  const bool sphere = q[1] == 0 && q[2] == 0 && q[4] == 0 && q[0] == q[3] && q[0] == q[5];
  sphere_[i] = sphere ? std::sqrt(q[0]) : 0;
}

void ParticleStore::add_axes(const std::array<double, 3>& centre,
                             const std::array<double, 3>& semi_axes,
                             const std::array<double, 4>& quaternion) {
  // Equal semi-axes: a sphere whatever the rotation, stored as exactly a^2 I
  // (the rotated form would carry rounding off the diagonal), so that pairs
  // of spheres are recognised and decided in closed form.
  const QuadraticForm rotated = quadratic_form_from_quaternion(semi_axes, quaternion);  // checks it
  const bool equal = semi_axes[0] == semi_axes[1] && semi_axes[1] == semi_axes[2];
  add(centre, equal ? sphere(semi_axes[0]) : rotated);
}

}  // namespace pwcontact
