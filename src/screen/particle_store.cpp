// The particle store: centres, quadratic forms, and the bounding and
// inscribed radii the screening prefilters use.
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "number_text.hpp"
#include "pwcontact/ellipsoid.hpp"
#include "pwcontact/screen.hpp"
#include "screen/huge_pages.hpp"

namespace pwcontact {

using detail::number_text;

namespace {

void check_lengths(std::initializer_list<double> lengths) {
  for (double l : lengths)
    if (!(l > 0) || !std::isfinite(l))
      throw std::invalid_argument("Box: a periodic box needs positive, finite lengths, got " +
                                  detail::number_text(l));
}

void check_tilts(std::initializer_list<double> tilts) {
  for (double t : tilts)
    if (!std::isfinite(t))
      throw std::invalid_argument("Box: tilt factors must be finite, got " + std::to_string(t));
}

}  // namespace

namespace detail {

void check_box(const Box& box) {
  if (!box.periodic) return;
  const int axes = box.two_dimensional ? 2 : 3;
  for (int k = 0; k < axes; ++k) check_lengths({box.length[std::size_t(k)]});
  check_tilts({box.tilt[0]});
  if (!box.two_dimensional) check_tilts({box.tilt[1], box.tilt[2]});
  // The lattice vectors' entries (xy Ly; xz Lz and yz Lz) and the widths
  // across the faces must be finite and the widths positive: lengths and
  // tilts finite each can still overflow there (Lx = Ly = 1e300, xy =
  // 1e10), and a box whose vectors are infinite, taken, lost every pair.
  const std::array<double, 3> tilts = box.lammps_tilts();
  const char* names[3] = {"xy Ly", "xz Lz", "yz Lz"};
  for (int k = 0; k < (box.two_dimensional ? 1 : 3); ++k)
    if (!std::isfinite(tilts[std::size_t(k)]))
      throw std::invalid_argument(std::string("Box: a lattice vector is not finite (") + names[k] +
                                  " = " + number_text(tilts[std::size_t(k)]) + ")");
  const std::array<double, 3> widths = box.perpendicular_widths();
  for (int k = 0; k < axes; ++k)
    if (!(widths[std::size_t(k)] > 0) || !std::isfinite(widths[std::size_t(k)]))
      throw std::invalid_argument("Box: the width across axis " + std::to_string(k) + " is " +
                                  number_text(widths[std::size_t(k)]) +
                                  " (the tilts leave the box flat or unbounded)");
}

}  // namespace detail

Box Box::periodic_box(double lx, double ly, double lz) { return triclinic(lx, ly, lz, 0, 0, 0); }

Box Box::triclinic(double lx, double ly, double lz, double xy, double xz, double yz) {
  Box box;
  box.periodic = true;
  box.length = {lx, ly, lz};
  box.tilt = {xy, xz, yz};
  detail::check_box(box);  // (lengths, tilts, lattice vectors, widths)
  return box;
}

Box Box::two_dimensional_box(double lx, double ly, double xy) {
  Box box;
  box.periodic = true;
  box.two_dimensional = true;
  box.length = {lx, ly, 0};
  box.tilt = {xy, 0, 0};
  detail::check_box(box);
  return box;
}

Box Box::from_lammps(double lx, double ly, double lz, double xy, double xz, double yz) {
  check_lengths({lx, ly, lz});
  check_tilts({xy, xz, yz});
  return triclinic(lx, ly, lz, xy / ly, xz / lz, yz / lz);
}

std::array<double, 3> Box::lammps_tilts() const {
  return {tilt[0] * length[1], tilt[1] * length[2], tilt[2] * length[2]};
}

std::array<double, 3> Box::perpendicular_widths() const {
  // V / |a_j x a_k| for the lattice vectors a1 = (Lx, 0, 0),
  // a2 = (xy Ly, Ly, 0), a3 = (xz Lz, yz Lz, Lz):
  // |a2 x a3| = Ly Lz sqrt(1 + xy^2 + (xy yz - xz)^2), |a3 x a1| = Lz Lx
  // sqrt(1 + yz^2), |a1 x a2| = Lx Ly. In 2D only x and y count.
  const double xy = tilt[0], xz = two_dimensional ? 0 : tilt[1], yz = two_dimensional ? 0 : tilt[2];
  const double c = xy * yz - xz;
  return {length[0] / std::sqrt(1 + xy * xy + c * c), length[1] / std::sqrt(1 + yz * yz),
          length[2]};
}

template <class Visit>
void ParticleStore::for_each_array(Visit&& visit) {
  for (auto& v : centre_) visit(v);
  for (auto& v : q_) visit(v);
  for (auto* v : {&bounding_, &inscribed_, &sphere_}) visit(*v);
}

void ParticleStore::reserve(std::size_t n) {
  for_each_array([n](std::vector<double>& v) { screen::reserve_in_huge_pages(v, n); });
  screen::reserve_in_huge_pages(type_id_, n);
}

void ParticleStore::resize(std::size_t n) {
  // Beyond the capacity: reserved (in huge pages) with the vector's
  // doubling, so that growing one particle at a time stays linear.
  const std::size_t capacity = centre_[0].capacity();
  if (n > capacity) reserve(std::max(n, 2 * capacity));
  for_each_array([n](std::vector<double>& v) { v.resize(n); });
  type_id_.resize(n, untyped);
}

std::size_t ParticleStore::first_unset() const noexcept {
  // (Every particle set has a positive bounding radius: its Q is positive
  // definite. resize() leaves zeros.)
  const std::vector<double>& bounding = bounding_radius();
  for (std::size_t i = 0; i < bounding.size(); ++i)
    if (!(bounding[i] > 0)) return i;
  return bounding.size();
}

std::string ParticleStore::unset_message() const {
  const std::size_t unset = first_unset();
  if (unset == size()) return "";
  return "particle " + std::to_string(unset) +
         " was never set (ParticleStore::resize leaves every particle to set or set_axes)";
}

void ParticleStore::require_set(const char* who) const {
  if (const std::string message = unset_message(); !message.empty())
    throw std::invalid_argument(std::string(who) + ": " + message);
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

namespace {

std::string particle_name(std::size_t i) { return "particle " + std::to_string(i); }

// make(who) for particle i, its name built only when a check fails: the
// checks are pure, so the second call throws what the first did, naming the
// particle. (Building the name for every particle cost ~10 % of a
// million-particle store's build.)
template <class Make>
ParticleStore::Particle named_particle(std::size_t i, Make&& make) {
  try {
    return make(std::string());
  } catch (const std::invalid_argument&) {
    return make(particle_name(i));
  }
}

void check_centre(const std::string& who, const std::array<double, 3>& centre) {
  for (double c : centre)
    if (!std::isfinite(c)) throw std::invalid_argument(who + ": centre is not finite");
}

}  // namespace

ParticleStore::Particle ParticleStore::particle(const std::array<double, 3>& centre,
                                                const std::array<double, 6>& q,
                                                const std::string& who) {
  check_centre(who, centre);
  for (double v : q)
    if (!std::isfinite(v)) throw std::invalid_argument(who + ": Q is not finite");
  Eigen::Matrix3d m;
  m << q[0], q[1], q[2], q[1], q[3], q[4], q[2], q[4], q[5];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(m, Eigen::EigenvaluesOnly);
  // The eigenvalues of a symmetric 3x3 matrix computed by Eigen's QR
  // iteration err by a few eps |Q| (backward stable); radii_of() rounds the
  // radii beyond that.
  return untyped_particle(who, centre, q, solver.eigenvalues()[0], solver.eigenvalues()[2]);
}

void ParticleStore::set(std::size_t i, const std::array<double, 3>& centre,
                        const std::array<double, 6>& q) {
  set_particle(i,
               named_particle(i, [&](const std::string& who) { return particle(centre, q, who); }));
}

namespace {

void check_semi_axes(const std::string& who, const std::array<double, 3>& semi_axes) {
  for (double a : semi_axes)
    if (!(a > 0) || !std::isfinite(a))
      throw std::invalid_argument(who + ": semi-axes must be positive and finite, got (" +
                                  number_text(semi_axes[0]) + ", " + number_text(semi_axes[1]) +
                                  ", " + number_text(semi_axes[2]) + ")");
}

// Q of semi-axes along the body axes rotated by the quaternion. Equal
// semi-axes: a sphere whatever the rotation, stored as exactly a^2 I (the
// rotated form would carry rounding off the diagonal), so that pairs of
// spheres are recognised and decided in closed form.
// (A zero or non-finite quaternion: std::invalid_argument naming `who`, for
// a sphere too: its orientation changes nothing, but a NaN there is a
// malformed input all the same, and was taken silently.)
QuadraticForm form_of_axes(const std::string& who, const std::array<double, 3>& semi_axes,
                           const std::array<double, 4>& quaternion) {
  const bool equal = semi_axes[0] == semi_axes[1] && semi_axes[1] == semi_axes[2];
  try {
    if (!equal) return quadratic_form_from_quaternion(semi_axes, quaternion);
    bool zero = true, finite = true;
    for (double c : quaternion) {
      zero = zero && c == 0;
      finite = finite && std::isfinite(c);
    }
    // (The rotation's own check and message, for the quaternion it refuses.)
    if (zero || !finite) quadratic_form_from_quaternion({1, 1, 1}, quaternion);
    return sphere(semi_axes[0]);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(who + ": " + e.what());
  }
}

// The smallest and largest eigenvalues untyped_particle() is given for such a Q, with
// no eigensolver: the stored Q is R diag(a^2) R^T rounded, a few eps a_max^2
// from the exact form in every entry, so by Weyl's inequality its
// eigenvalues are within a few eps a_max^2 of the squared semi-axes, which
// untyped_particle() rounds beyond.
std::pair<double, double> squared_extremes(const std::array<double, 3>& semi_axes) {
  const auto [smallest, largest] = std::minmax({semi_axes[0], semi_axes[1], semi_axes[2]});
  return {smallest * smallest, largest * largest};
}

// 64 eps |Q| rounds the radii outwards (bounding) and inwards (inscribed)
// beyond the few eps |Q| by which the eigenvalues may err, so that both
// prefilters stay on the safe side; Q is definite only beyond it.
double eigenvalue_slack(double largest) {
  return 64 * std::numeric_limits<double>::epsilon() * std::abs(largest);
}

// The bounding and inscribed radii of extreme eigenvalues smallest >
// slack and largest, rounded outwards and inwards.
std::pair<double, double> radii_of_extremes(double smallest, double largest, double slack) {
  const double up = 1 + 4 * std::numeric_limits<double>::epsilon();
  return {std::sqrt(largest + slack) * up, std::sqrt(smallest - slack) / up};
}

// A sphere's radius: Q exactly a^2 I (as stored for equal semi-axes), else 0.
double sphere_radius_of(const QuadraticForm& q) {
  const bool sphere = q[1] == 0 && q[2] == 0 && q[4] == 0 && q[0] == q[3] && q[0] == q[5];
  return sphere ? std::sqrt(q[0]) : 0;
}

}  // namespace

ParticleStore::Particle ParticleStore::particle_axes(const std::array<double, 3>& centre,
                                                     const std::array<double, 3>& semi_axes,
                                                     const std::array<double, 4>& quaternion,
                                                     const std::string& who) {
  check_centre(who, centre);
  check_semi_axes(who, semi_axes);
  const auto [smallest, largest] = squared_extremes(semi_axes);
  return untyped_particle(who, centre, form_of_axes(who, semi_axes, quaternion), smallest, largest);
}

void ParticleStore::set_axes(std::size_t i, const std::array<double, 3>& centre,
                             const std::array<double, 3>& semi_axes,
                             const std::array<double, 4>& quaternion) {
  // The common case straight into the arrays: the numbers particle_axes()
  // and radii_of() give, by the same functions (the same bits), without a
  // Particle in between and with the radii's square roots started before
  // the rotation's (the two chains overlap). A million particles with one
  // thread: 49-50 ms through a Particle, 38-40 ms this way. Anything
  // else (an index beyond the store, a non-finite centre, a bad semi-axis
  // or quaternion, a form too elongated to be definite) takes the general
  // path below, which throws what it always threw.
  bool valid = i < size() && (quaternion[0] != 0 || quaternion[1] != 0 || quaternion[2] != 0 ||
                              quaternion[3] != 0);
  for (int k = 0; k < 4; ++k) valid = valid && std::isfinite(quaternion[k]);
  for (int k = 0; k < 3; ++k)
    valid = valid && std::isfinite(centre[k]) && semi_axes[k] > 0 && std::isfinite(semi_axes[k]);
  if (valid) {
    const auto [smallest, largest] = squared_extremes(semi_axes);
    const double slack = eigenvalue_slack(largest);
    if (smallest > slack) {
      const auto [bounding, inscribed] = radii_of_extremes(smallest, largest, slack);
      // (A finite, non-zero quaternion: the rotation throws nothing.)
      const bool equal = semi_axes[0] == semi_axes[1] && semi_axes[1] == semi_axes[2];
      const QuadraticForm q =
          equal ? sphere(semi_axes[0]) : quadratic_form_from_quaternion(semi_axes, quaternion);
      for (int k = 0; k < 3; ++k) centre_[k][i] = centre[k];
      for (int k = 0; k < 6; ++k) q_[k][i] = q[k];
      bounding_[i] = bounding;
      inscribed_[i] = inscribed;
      sphere_[i] = sphere_radius_of(q);
      type_id_[i] = untyped;
      return;
    }
  }
  set_particle(i, named_particle(i, [&](const std::string& who) {
                 return particle_axes(centre, semi_axes, quaternion, who);
               }));
}

std::uint32_t ParticleStore::add_type(const std::array<double, 3>& semi_axes) {
  const std::size_t t = type_axes_.size();
  if (t >= untyped) throw std::invalid_argument("ParticleStore::add_type: too many types");
  check_semi_axes("type " + std::to_string(t), semi_axes);
  // The radii a particle of this type would get from untyped_particle() (the same
  // arithmetic on the same numbers: the same bits).
  const auto [smallest, largest] = squared_extremes(semi_axes);
  const QuadraticForm q = form_of_axes("type " + std::to_string(t), semi_axes, {1, 0, 0, 0});
  const Radii radii = radii_of("type " + std::to_string(t), q, smallest, largest);
  type_axes_.push_back(semi_axes);
  type_radii_.push_back(radii);
  return std::uint32_t(t);
}

const std::array<double, 3>& ParticleStore::type_semi_axes(std::uint32_t type) const {
  if (type >= type_axes_.size())
    throw std::invalid_argument("ParticleStore: type " + std::to_string(type) +
                                " does not exist (" + std::to_string(type_axes_.size()) +
                                " types)");
  return type_axes_[type];
}

ParticleStore::Particle ParticleStore::particle_typed(const std::array<double, 3>& centre,
                                                      std::uint32_t type,
                                                      const std::array<double, 4>& quaternion,
                                                      const std::string& who) const {
  check_centre(who, centre);
  if (type >= type_axes_.size())
    throw std::invalid_argument(who + ": type " + std::to_string(type) + " does not exist (" +
                                std::to_string(type_axes_.size()) + " types)");
  Particle p;
  p.centre_ = centre;
  p.q_ = form_of_axes(who, type_axes_[type], quaternion);
  const Radii& radii = type_radii_[type];
  p.bounding_ = radii.bounding;
  p.inscribed_ = radii.inscribed;
  p.sphere_ = radii.sphere;
  p.type_ = type;
  return p;
}

void ParticleStore::set_typed(std::size_t i, const std::array<double, 3>& centre,
                              std::uint32_t type, const std::array<double, 4>& quaternion) {
  set_particle(i, named_particle(i, [&](const std::string& who) {
                 return particle_typed(centre, type, quaternion, who);
               }));
}

ParticleStore::Particle ParticleStore::Particle::moved_to(
    const std::array<double, 3>& centre) const {
  check_centre("trial particle", centre);
  Particle p = *this;
  p.centre_ = centre;
  return p;
}

ParticleStore::Particle ParticleStore::particle_at(std::size_t i) const {
  if (i >= size())
    throw std::out_of_range("ParticleStore: " + particle_name(i) + " does not exist (" +
                            std::to_string(size()) + " particles)");
  Particle p;
  for (int k = 0; k < 3; ++k) p.centre_[k] = centre_[k][i];
  for (int k = 0; k < 6; ++k) p.q_[k] = q_[k][i];
  p.bounding_ = bounding_[i];
  p.inscribed_ = inscribed_[i];
  p.sphere_ = sphere_[i];
  p.type_ = type_id_[i];
  return p;
}

bool ParticleStore::type_fits(const Particle& p) const noexcept {
  if (p.type_ == untyped) return true;
  if (p.type_ >= type_axes_.size()) return false;
  // The radii of a typed particle are its type's, copied (particle_typed);
  // its Q is R diag(a^2) R^T, whose trace is sum a^2 to a few ulps.
  const Radii& radii = type_radii_[p.type_];
  const auto& a = type_axes_[p.type_];
  const double trace = p.q_[0] + p.q_[3] + p.q_[5];
  const double expected = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
  return p.bounding_ == radii.bounding && p.inscribed_ == radii.inscribed &&
         p.sphere_ == radii.sphere && std::abs(trace - expected) <= 1e-12 * expected;
}

// (`who` as a C string: a std::string made for it on every move cost a heap
// allocation per move.)
void ParticleStore::check_type(const Particle& p, const char* who) const {
  if (type_fits(p)) return;
  if (p.type_ >= type_axes_.size())
    throw std::invalid_argument(std::string(who) + ": type " + std::to_string(p.type_) +
                                " does not exist (" + std::to_string(type_axes_.size()) +
                                " types)");
  throw std::invalid_argument(std::string(who) + ": a particle of type " + std::to_string(p.type_) +
                              " whose shape is not that type's here (made by another store?)");
}

void ParticleStore::set_particle(std::size_t i, const Particle& p) {
  if (i >= size())
    throw std::out_of_range("ParticleStore: " + particle_name(i) + " does not exist (" +
                            std::to_string(size()) + " particles)");
  if (!type_fits(p)) check_type(p, particle_name(i).c_str());
  for (int k = 0; k < 3; ++k) centre_[k][i] = p.centre_[k];
  for (int k = 0; k < 6; ++k) q_[k][i] = p.q_[k];
  bounding_[i] = p.bounding_;
  inscribed_[i] = p.inscribed_;
  sphere_[i] = p.sphere_;
  type_id_[i] = p.type_;
}

void ParticleStore::add_particle(const Particle& p) {
  const std::size_t i = size();
  resize(i + 1);
  try {
    set_particle(i, p);
  } catch (...) {
    resize(i);
    throw;
  }
}

void ParticleStore::swap_remove(std::size_t i) {
  const std::size_t n = size();
  if (i >= n)
    throw std::out_of_range("ParticleStore: " + particle_name(i) + " does not exist (" +
                            std::to_string(n) + " particles)");
  for_each_array([i, n](std::vector<double>& v) {
    v[i] = v[n - 1];
    v.pop_back();
  });
  type_id_[i] = type_id_[n - 1];
  type_id_.pop_back();
}

void ParticleStore::add_typed(const std::array<double, 3>& centre, std::uint32_t type,
                              const std::array<double, 4>& quaternion) {
  const std::size_t i = size();
  resize(i + 1);
  try {
    set_typed(i, centre, type, quaternion);
  } catch (...) {
    resize(i);
    throw;
  }
}

ParticleStore::Radii ParticleStore::radii_of(const std::string& who, const std::array<double, 6>& q,
                                             double smallest, double largest) {
  // (Semi-axes beyond ~1.3e154 square to infinity: said so, where the slack
  // it made infinite read "not positive definite (smallest eigenvalue 1)".)
  if (!std::isfinite(largest))
    throw std::invalid_argument(who + ": Q is not finite (its largest eigenvalue, a semi-axis " +
                                "squared, overflows)");
  const double slack = eigenvalue_slack(largest);
  if (!(smallest > slack))
    throw std::invalid_argument(who + ": Q is not positive definite (smallest eigenvalue " +
                                number_text(smallest) + ")");
  const auto [bounding, inscribed] = radii_of_extremes(smallest, largest, slack);
  return {bounding, inscribed, sphere_radius_of(q)};
}

ParticleStore::Particle ParticleStore::untyped_particle(const std::string& who,
                                                        const std::array<double, 3>& centre,
                                                        const std::array<double, 6>& q,
                                                        double smallest, double largest) {
  const Radii radii = radii_of(who, q, smallest, largest);
  Particle p;
  p.centre_ = centre;
  p.q_ = q;
  p.bounding_ = radii.bounding;
  p.inscribed_ = radii.inscribed;
  p.sphere_ = radii.sphere;
  return p;
}

void ParticleStore::set_ellipse(std::size_t i, double x, double y, double a, double b,
                                double theta) {
  check_centre(particle_name(i), {x, y, 0});
  if (!(a > 0) || !std::isfinite(a) || !(b > 0) || !std::isfinite(b))
    throw std::invalid_argument(particle_name(i) +
                                ": semi-axes must be positive and finite, got (" + number_text(a) +
                                ", " + number_text(b) + ")");
  if (!std::isfinite(theta))
    throw std::invalid_argument(particle_name(i) + ": the angle is not finite");
  const double c = std::cos(theta), s = std::sin(theta), a2 = a * a, b2 = b * b;
  const double smallest = std::min(a, b);
  // Q = R diag(a^2, b^2) R^T in the plane, min(a, b)^2 along z; a circle
  // is stored exactly as a^2 I (a sphere), as add_axes does.
  const std::array<double, 6> q =
      a == b ? std::array<double, 6>{a2, 0, 0, a2, 0, a2}
             : std::array<double, 6>{
                   a2 * c * c + b2 * s * s, (a2 - b2) * c * s, 0, a2 * s * s + b2 * c * c, 0,
                   smallest * smallest};
  set_particle(i, untyped_particle(particle_name(i), {x, y, 0}, q, smallest * smallest,
                                   std::max(a, b) * std::max(a, b)));
}

void ParticleStore::add_ellipse(double x, double y, double a, double b, double theta) {
  const std::size_t i = size();
  resize(i + 1);
  try {
    set_ellipse(i, x, y, a, b, theta);
  } catch (...) {
    resize(i);
    throw;
  }
}

void ParticleStore::add_axes(const std::array<double, 3>& centre,
                             const std::array<double, 3>& semi_axes,
                             const std::array<double, 4>& quaternion) {
  const std::size_t i = size();
  resize(i + 1);
  try {
    set_axes(i, centre, semi_axes, quaternion);
  } catch (...) {
    resize(i);
    throw;
  }
}

}  // namespace pwcontact
