// Hard-particle Monte Carlo on a MovingScene (monte_carlo.hpp).
#include "pwcontact/monte_carlo.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>

#include "number_text.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/ellipsoid.hpp"
#include "thread_count.hpp"

namespace pwcontact {
namespace {

constexpr double pi = 3.14159265358979323846;

// compress()'s screens: pairs with mu below it bound how far the box may
// shrink (halfway to contact), those beyond it leave the full step.
constexpr double compress_cutoff = 1.1;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A random stream per (seed, sweep, purpose, domain): splitmix64 of their mix.
std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  std::uint64_t z = a + 0x9E3779B97F4A7C15ull * (b + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double uniform01(std::mt19937_64& engine) { return double(engine() >> 11) * 0x1.0p-53; }

// q1 q2 (Hamilton product, (w, x, y, z)).
std::array<double, 4> multiply(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

// A turn by an angle uniform in [0, largest] about a uniformly random axis,
// composed with q and normalised (so that orientations do not drift).
std::array<double, 4> turned(const std::array<double, 4>& q, double largest,
                             std::mt19937_64& engine) {
  double axis[3], norm2;
  do {
    for (double& x : axis) x = 2 * uniform01(engine) - 1;
    norm2 = axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2];
  } while (norm2 > 1 || norm2 < 1e-6);
  const double half = largest * uniform01(engine) / 2, s = std::sin(half) / std::sqrt(norm2);
  std::array<double, 4> out = multiply({std::cos(half), s * axis[0], s * axis[1], s * axis[2]}, q);
  const double n = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
  for (double& x : out) x /= n;
  return out;
}

}  // namespace

struct HardParticleMC::State {
  Box box;
  std::vector<std::array<double, 3>> semi_axes;
  std::vector<std::array<double, 4>> orientation;
  HardParticleMCOptions options;
  std::unique_ptr<MovingScene> scene;
  double volume = 0;  // of the particles
  double translation = 0, rotation = 0;
  std::size_t sweeps = 0;
  // compress()'s screens, one a sweep in compress_to_packing: the memory of
  // the last one kept for the next.
  ScreenWorkspace workspace;
  ScreenedPairs near;

  int threads() const { return detail::thread_count(options.threads, "HardParticleMC"); }

  void make_scene(const std::vector<std::array<double, 3>>& centre) {
    ParticleStore store;
    store.reserve(centre.size());
    for (std::size_t i = 0; i < centre.size(); ++i)
      store.add_axes(centre[i], semi_axes[i], orientation[i]);
    MovingSceneOptions o;
    o.batch = options.batch;
    scene = std::make_unique<MovingScene>(std::move(store), box, o);
  }

  std::vector<std::array<double, 3>> centres() const {
    const ParticleStore& s = scene->particles();
    std::vector<std::array<double, 3>> c(s.size());
    for (std::size_t i = 0; i < s.size(); ++i)
      c[i] = {s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]};
    return c;
  }

  double box_volume() const { return box.length[0] * box.length[1] * box.length[2]; }
};

HardParticleMC::HardParticleMC(const Box& box, std::vector<std::array<double, 3>> centre,
                               std::vector<std::array<double, 3>> semi_axes,
                               std::vector<std::array<double, 4>> orientation,
                               const HardParticleMCOptions& options)
    : state_(new State) {
  if (!box.periodic || box.two_dimensional)
    throw std::invalid_argument("HardParticleMC: needs a periodic three-dimensional box");
  if (centre.size() != semi_axes.size() || centre.size() != orientation.size())
    throw std::invalid_argument("HardParticleMC: " + std::to_string(centre.size()) + " centres, " +
                                std::to_string(semi_axes.size()) + " semi-axes and " +
                                std::to_string(orientation.size()) + " orientations");
  if (!(options.packing > 0 && options.packing < 1))
    throw std::invalid_argument("HardParticleMC: the packing fraction must be in (0, 1), got " +
                                detail::number_text(options.packing));
  if (!(options.translation > 0) || !std::isfinite(options.translation) ||
      !(options.rotation >= 0) || !std::isfinite(options.rotation))
    throw std::invalid_argument(
        "HardParticleMC: step sizes must be finite, the translation positive");
  detail::thread_count(options.threads, "HardParticleMC");
  State& s = *state_;
  s.box = box;
  s.semi_axes = std::move(semi_axes);
  s.orientation = std::move(orientation);
  s.options = options;
  s.translation = options.translation;
  s.rotation = options.rotation;
  s.make_scene(centre);  // (refuses zero and non-finite quaternions, naming the particle)
  // Unit quaternions, as orientation() promises and a GSD file wants (a
  // quaternion already unit to rounding is kept as given, bit for bit).
  for (auto& q : s.orientation) {
    const double norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    if (std::abs(norm2 - 1) > 8 * std::numeric_limits<double>::epsilon())
      for (double& x : q) x /= std::sqrt(norm2);
  }
  for (const auto& a : s.semi_axes) s.volume += 4.0 / 3.0 * pi * a[0] * a[1] * a[2];
}

HardParticleMC::~HardParticleMC() = default;
HardParticleMC::HardParticleMC(HardParticleMC&&) noexcept = default;
HardParticleMC& HardParticleMC::operator=(HardParticleMC&&) noexcept = default;

HardParticleMC HardParticleMC::dilute_spheroids(std::size_t n, std::uint64_t seed,
                                                double max_aspect,
                                                const HardParticleMCOptions& options,
                                                std::size_t shapes) {
  if (n == 0) throw std::invalid_argument("HardParticleMC: no particles");
  if (!(max_aspect >= 1) || !std::isfinite(max_aspect))
    throw std::invalid_argument("HardParticleMC: the largest aspect ratio must be >= 1");
  std::mt19937_64 engine(mix(seed, 0x5eed));
  std::vector<std::array<double, 3>> axes(n), centre(n);
  std::vector<std::array<double, 4>> orientation(n);
  double largest = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double draw = uniform01(engine);
    if (shapes == 1) draw = 0.5;
    if (shapes > 1) draw = std::floor(draw * double(shapes)) / double(shapes - 1);
    const double aspect = std::exp(std::log(max_aspect) * (2 * draw - 1));
    const double a = 0.5 / std::cbrt(aspect);  // a^2 c = 0.5^3
    axes[i] = {a, a, a * aspect};
    largest = std::max({largest, a, a * aspect});
    std::array<double, 4> q;
    double norm2;
    do {
      for (double& x : q) x = 2 * uniform01(engine) - 1;
      norm2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    } while (norm2 > 1 || norm2 < 1e-6);
    for (double& x : q) x /= std::sqrt(norm2);
    orientation[i] = q;
  }
  // At least two sites along each axis: a box one site wide is narrower than
  // twice a particle's reach, which no scene takes (one particle then gets
  // compress_to_packing's message on too few particles, not the scene's).
  std::size_t side = 2;
  while (side * side * side < n) ++side;
  const double spacing = 1.02 * 2 * largest, length = spacing * double(side);
  for (std::size_t i = 0; i < n; ++i)
    centre[i] = {spacing * (double(i % side) + 0.5), spacing * (double(i / side % side) + 0.5),
                 spacing * (double(i / (side * side)) + 0.5)};
  return HardParticleMC(Box::periodic_box(length, length, length), std::move(centre),
                        std::move(axes), std::move(orientation), options);
}

SweepReport HardParticleMC::sweep() {
  State& s = *state_;
  const double start = now();
  MovingScene& scene = *s.scene;
  const ParticleStore& store = scene.particles();
  const std::size_t n = store.size();
  if (n == 0) return {};
  const std::array<int, 3> cells = scene.cells();
  const std::uint64_t sweep_seed = mix(s.options.seed, s.sweeps);
  // The grouping of cells into domains, shifted by a random number of cells
  // along each axis, uniform over the axis. (A shift of 0 or 1 left, with an
  // odd number of cells, the face between the last two cells between domains
  // under both: no centre ever crossed it, and a density step across it
  // relaxed only by particles going round the whole box.)
  std::mt19937_64 shift_engine(mix(sweep_seed, 0x5417));
  int offset[3], domains[3];
  for (int k = 0; k < 3; ++k) {
    offset[k] = int(shift_engine() % std::uint64_t(cells[k]));
    domains[k] = (cells[k] + 1) / 2;
  }
  auto domain_along = [&](int k, int c) { return ((c + offset[k]) % cells[k]) / 2; };
  auto colour_along = [&](int k, int d) {
    if (domains[k] == 1) return 0;
    return (domains[k] % 2 == 1 && d == domains[k] - 1) ? 2 : d % 2;
  };
  auto domain_of = [&](const std::array<int, 3>& c) {
    return (std::size_t(domain_along(0, c[0])) * std::size_t(domains[1]) +
            std::size_t(domain_along(1, c[1]))) *
               std::size_t(domains[2]) +
           std::size_t(domain_along(2, c[2]));
  };
  const std::size_t domain_count = std::size_t(domains[0]) * domains[1] * domains[2];
  // Particles by domain (they stay in it: moves that leave are rejected).
  std::vector<std::uint32_t> start_of(domain_count + 1, 0), member(n), domain_of_particle(n);
  for (std::uint32_t i = 0; i < n; ++i) {
    domain_of_particle[i] = std::uint32_t(domain_of(scene.cell_of_particle(i)));
    ++start_of[domain_of_particle[i] + 1];
  }
  for (std::size_t d = 0; d < domain_count; ++d) start_of[d + 1] += start_of[d];
  {
    std::vector<std::uint32_t> fill(start_of.begin(), start_of.end() - 1);
    for (std::uint32_t i = 0; i < n; ++i) member[fill[domain_of_particle[i]]++] = i;
  }
  // Domains by colour.
  std::vector<std::vector<std::uint32_t>> by_colour(27);
  for (int a = 0; a < domains[0]; ++a)
    for (int b = 0; b < domains[1]; ++b)
      for (int c = 0; c < domains[2]; ++c) {
        const std::size_t d = (std::size_t(a) * domains[1] + b) * domains[2] + c;
        if (start_of[d + 1] == start_of[d]) continue;
        by_colour[colour_along(0, a) * 9 + colour_along(1, b) * 3 + colour_along(2, c)].push_back(
            std::uint32_t(d));
      }

  SweepReport report;
  const int threads = s.threads();
  // Few domains (a small box): one trial at a time, in a single stream. (The
  // choice depends on the scene only, never on the thread count.)
  if (domain_count < 64) {
    std::mt19937_64 engine(mix(sweep_seed, 0x51));
    for (std::size_t t = 0; t < n; ++t) {
      const std::uint32_t i = std::uint32_t(uniform01(engine) * double(n));
      std::array<double, 3> centre = {store.centre(0)[i], store.centre(1)[i], store.centre(2)[i]};
      for (double& x : centre) x += s.translation * (2 * uniform01(engine) - 1);
      const std::array<double, 4> q =
          s.rotation > 0 ? turned(s.orientation[i], s.rotation, engine) : s.orientation[i];
      const MovingScene::Particle trial = ParticleStore::particle_axes(centre, s.semi_axes[i], q);
      ++report.proposed;
      if (scene.overlaps(trial, i) != MovingScene::none) continue;
      scene.move(i, trial);
      s.orientation[i] = q;
      ++report.accepted;
    }
    finish_sweep(report, start);
    return report;
  }
  // Colour by colour, the domains in parallel, each running its own trials
  // one after another (its cells and their neighbours stay in cache): a
  // query, and the move applied at once when it overlaps nothing. Domains of
  // one colour are a cell apart, so no query of one reaches a cell another
  // writes. A move that needs more than its two cells (a full cell: a
  // rebuild) is applied after the colour, in one thread, and ends its
  // domain's trials for the colour.
  struct Deferred {
    std::uint32_t particle;
    std::array<double, 4> orientation;
    std::optional<MovingScene::Particle> trial;
  };
  for (int colour = 0; colour < 27; ++colour) {
    const std::vector<std::uint32_t>& active = by_colour[colour];
    if (active.empty()) continue;
    const std::size_t m = active.size();
    std::vector<Deferred> deferred(m);
    std::size_t proposed = 0, accepted = 0, left = 0;
    detail::ParallelErrors errors;
#pragma omp parallel for num_threads(threads) schedule(dynamic, 4) reduction(+ : proposed, accepted, left)
    for (std::size_t k = 0; k < m; ++k)
      errors.run([&] {
        const std::uint32_t d = active[k];
        std::mt19937_64 engine(mix(sweep_seed, (std::uint64_t(colour) << 40) ^ d));
        const std::size_t count = start_of[d + 1] - start_of[d];
        for (std::size_t t = 0; t < count; ++t) {
          ++proposed;
          const std::uint32_t i =
              member[start_of[d] + std::size_t(uniform01(engine) * double(count))];
          std::array<double, 3> centre = {store.centre(0)[i], store.centre(1)[i],
                                          store.centre(2)[i]};
          for (double& x : centre) x += s.translation * (2 * uniform01(engine) - 1);
          const std::array<double, 4> q =
              s.rotation > 0 ? turned(s.orientation[i], s.rotation, engine) : s.orientation[i];
          if (domain_of(scene.cell_of(centre)) != d) {
            ++left;
            continue;
          }
          const MovingScene::Particle trial =
              ParticleStore::particle_axes(centre, s.semi_axes[i], q);
          if (scene.overlaps(trial, i) != MovingScene::none) continue;
          ++accepted;
          if (!scene.move_in_own_cells(i, trial)) {
            deferred[k] = {i, q, trial};
            break;
          }
          s.orientation[i] = q;
        }
      });
    errors.rethrow_if_failed();
    for (const Deferred& move : deferred)
      if (move.trial) {
        scene.move(move.particle, *move.trial);
        s.orientation[move.particle] = move.orientation;
        ++report.deferred;
      }
    report.proposed += proposed;
    report.accepted += accepted;
    report.left_domain += left;
  }
  finish_sweep(report, start);
  return report;
}

void HardParticleMC::finish_sweep(SweepReport& report, double start) {
  State& s = *state_;
  ++s.sweeps;
  if (s.options.adapt_steps && report.proposed > 0) {
    // Towards 30 % acceptance, by at most a factor 1.5 per sweep; the
    // translation at most a quarter of the largest bounding radius.
    const double acceptance = double(report.accepted) / double(report.proposed);
    const double factor = std::min(1.5, std::max(0.5, acceptance / 0.3));
    double largest = 0;
    for (const auto& a : s.semi_axes) largest = std::max({largest, a[0], a[1], a[2]});
    s.translation = std::min(largest / 4, std::max(1e-9, s.translation * factor));
    s.rotation = std::min(pi, std::max(1e-9, s.rotation * factor));
  }
  report.seconds = now() - start;
}

std::size_t HardParticleMC::overlapping_pairs() const {
  ScreenedPairs pairs;
  ScreenOptions options;
  options.threads = state_->options.threads;
  options.batch = state_->options.batch;
  screen_pairs(state_->scene->particles(), state_->box, options, pairs);
  return pairs.size();
}

double HardParticleMC::compress() {
  State& s = *state_;
  const double target = s.options.packing;
  const double now_packing = packing();
  ScreenOptions options;
  options.cutoff = compress_cutoff;
  options.with_mu2 = true;
  options.threads = s.options.threads;
  options.batch = s.options.batch;
  screen_pairs(s.scene->particles(), s.box, options, s.near, s.workspace);
  double mu2_min = 1.21;
  for (double m : s.near.mu2) mu2_min = std::min(mu2_min, m);
  if (!(mu2_min >= 1))
    throw std::logic_error("HardParticleMC::compress: the state overlaps (mu^2 " +
                           detail::number_text(mu2_min) + ")");
  // Closer than 1e-6 to contact: no room (nor trust in the last digits).
  const double mu_min = std::sqrt(mu2_min);
  if (now_packing >= target || mu_min < 1 + 1e-6) return now_packing;
  const double s_target = std::cbrt(now_packing / target);
  const double scale = std::max(s_target, 1 / std::sqrt(mu_min));
  Box box = s.box;
  for (double& l : box.length) l *= scale;
  std::vector<std::array<double, 3>> centre = s.centres();
  for (auto& c : centre)
    for (double& x : c) x *= scale;
  s.box = box;
  s.make_scene(centre);
  return packing();
}

void HardParticleMC::compress_to_packing(
    std::size_t max_sweeps, const std::function<void(std::size_t, double, double)>& progress) {
  State& s = *state_;
  const double target = s.options.packing * (1 - 1e-12);
  // The box this reaches must still hold compress()'s screens (its
  // cutoff): too few particles for the packing fraction leave a
  // box narrower than twice that reach, and the run used to stop there,
  // sweeps later, with the screen's message about a cutoff never given.
  if (packing() < s.options.packing) {
    double largest = 0;
    for (const auto& a : s.semi_axes) largest = std::max({largest, a[0], a[1], a[2]});
    const double scale = std::cbrt(packing() / s.options.packing);
    const std::array<double, 3> widths = s.box.perpendicular_widths();
    const double needed = 2 * compress_cutoff * 2 * largest;
    for (int k = 0; k < 3; ++k)
      if (!(widths[k] * scale >= needed))
        throw std::invalid_argument(
            "HardParticleMC: " + std::to_string(s.semi_axes.size()) +
            " particles are too few for the packing fraction " +
            detail::number_text(s.options.packing) + ": its box would be " +
            detail::number_text(widths[k] * scale) + " wide across axis " + std::to_string(k) +
            ", less than the " + std::to_string(needed) +
            " that the screens of the compression need (twice 1.1 times the largest "
            "diameter); take more particles or a lower packing fraction");
  }
  std::size_t done = 0;
  while (packing() < target) {
    if (done >= max_sweeps)
      throw std::runtime_error("HardParticleMC: the packing fraction " +
                               detail::number_text(packing()) + " after " + std::to_string(done) +
                               " sweeps, short of " + detail::number_text(s.options.packing));
    const SweepReport r = sweep();
    ++done;
    compress();  // (a full screen_pairs, which finds any overlap: std::logic_error)
    if (progress)
      progress(done, packing(), r.proposed ? double(r.accepted) / double(r.proposed) : 0);
  }
}

const ParticleStore& HardParticleMC::particles() const { return state_->scene->particles(); }
const Box& HardParticleMC::box() const { return state_->box; }
const std::vector<std::array<double, 3>>& HardParticleMC::semi_axes() const {
  return state_->semi_axes;
}
const std::vector<std::array<double, 4>>& HardParticleMC::orientation() const {
  return state_->orientation;
}
double HardParticleMC::packing() const { return state_->volume / state_->box_volume(); }
double HardParticleMC::translation() const { return state_->translation; }
double HardParticleMC::rotation() const { return state_->rotation; }
std::size_t HardParticleMC::sweeps() const { return state_->sweeps; }

}  // namespace pwcontact
