// pwcontact_moves: trial-move queries on a moving scene, as hard-particle
// Monte Carlo asks them, timed with Google Benchmark:
//   moves/single/<order>/packing:P       MovingScene::overlaps for one trial
//                                        (a translation of up to 0.1 and a
//                                        turn of up to 0.1 rad of one
//                                        particle), then MovingScene::move when
//                                        it overlaps nothing; one thread. The
//                                        scene: the demo's (1M spheroids,
//                                        aspect ratios 1/3 .. 3, random, with
//                                        overlaps) at packing 0.3, or a hard
//                                        packing at 0.5 (10^3 periodic copies of
//                                        the Monte Carlo example's packed state
//                                        of 1000 spheroids). <order>: trials
//                                        in the order of the scene's cells (a
//                                        sweep, as a checkerboard domain runs
//                                        them) or of random particles.
//   mc/sweep/packing:P/threads:T         one sweep of the Monte Carlo example
//                                        (HardParticleMC::sweep) on the scene
//   skin/<warm|cold>/packing:0.5         a neighbour list with a skin kept
//                                        across slow steps: the solve of its
//                                        pairs from their last lambda or cold
//   moves/batched/packing:P/threads:T    the same trials, one per domain of a
//                                        checkerboard (every fourth cell along
//                                        each axis), by the batched query and
//                                        move_many: the sweep of the Monte
//                                        Carlo example
//   fcl/single/packing:P                 FCL's DynamicAABBTreeCollisionManager
//                                        with fcl::Ellipsoidd objects: per
//                                        trial, the object moved (update) and
//                                        collide until the first contact, the
//                                        move undone (untimed) when it
//                                        collides; the first 20,000 trials of
//                                        particles away from the faces (FCL has
//                                        no periodic box), on 100,000 spheroids
//                                        at 0.3 and 64,000 at 0.5 (FCL's tree
//                                        upkeep does not scale to 1M). Ours is
//                                        timed on exactly these trials from the
//                                        same state (moves/fcl_trials in the
//                                        summary); moves/interior/... is ours on
//                                        200,000 trials of the same kind.
// then a summary: queries per second, the ratio to FCL on the same trials
// (target >= 20), FCL's answers that disagree with the exact mu^2 (and how
// many of those pairs are within 1e-9 of tangency), the 2-thread sweep over
// 1 thread (target >= 1.8), and what the warm start saves (target >= 30 %).
#include <benchmark/benchmark.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "fixtures/families.hpp"
#include "pwcontact/pwcontact.hpp"

#ifdef PWCONTACT_WITH_FCL
#include <fcl/fcl.h>
#endif

namespace {

using pwcontact::MovingScene;
using pwcontact::ParticleStore;
using Particle = ParticleStore::Particle;

constexpr std::size_t particles = 1000000;
constexpr std::size_t trials_per_iteration = 200000;
// FCL answers the first trials of the interior sequence, and ours is timed
// on the same ones for the ratio.
constexpr std::size_t fcl_trials = 20000;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A scene with the semi-axes and orientations its particles were made from.
struct World {
  pwcontact::SpheroidScene scene;
};

// q1 q2 (Hamilton product, (w, x, y, z)).
std::array<double, 4> multiply(const std::array<double, 4>& a, const std::array<double, 4>& b) {
  return {a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
          a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
          a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
          a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]};
}

// The packed state at 0.5: the Monte Carlo example's (HardParticleMC from
// 1000 spheroids on a dilute lattice, seed 1) as 10^3 periodic copies; the
// demo's scene at 0.3.
// `small`: the scenes FCL is compared on, 100,000 spheroids at 0.3 (the
// demo's kind) and 4^3 copies (64,000) at 0.5: FCL's update re-balances its
// tree (setup() after every update), measured 20 ms per update with 1M
// objects, 1.5 ms with 100,000.
const World& world(double packing, bool small = false) {
  static std::map<std::pair<double, bool>, World> worlds;
  auto found = worlds.find({packing, small});
  if (found != worlds.end()) return found->second;
  World w;
  const int copies = small ? 4 : 10;
  if (packing < 0.4) {
    w.scene = pwcontact::spheroid_scene(small ? 100000 : particles, 1, 0.3, 3);
  } else {
    pwcontact::HardParticleMCOptions options;
    options.packing = 0.5;
    options.seed = 1;
    pwcontact::HardParticleMC mc = pwcontact::HardParticleMC::dilute_spheroids(1000, 1, 3, options);
    mc.compress_to_packing();
    const ParticleStore& small = mc.particles();
    const double l = mc.box().length[0];
    pwcontact::SpheroidScene& s = w.scene;
    s.box = pwcontact::Box::periodic_box(copies * l, copies * l, copies * l);
    for (int a = 0; a < copies; ++a)
      for (int b = 0; b < copies; ++b)
        for (int c = 0; c < copies; ++c)
          for (std::size_t i = 0; i < small.size(); ++i) {
            // Each centre wrapped into the small box first (Monte Carlo moves
            // take them anywhere): the copies then fill the large box, and a
            // scene without periodic images (FCL's) sees every neighbour of
            // a particle away from the faces.
            auto wrapped = [&](int k) {
              return small.centre(k)[i] - l * std::floor(small.centre(k)[i] / l);
            };
            const std::array<double, 3> centre = {wrapped(0) + a * l, wrapped(1) + b * l,
                                                  wrapped(2) + c * l};
            s.particles.add_axes(centre, mc.semi_axes()[i], mc.orientation()[i]);
            s.semi_axes.push_back(mc.semi_axes()[i]);
            s.orientation.push_back(mc.orientation()[i]);
          }
  }
  return worlds.emplace(std::make_pair(packing, small), std::move(w)).first->second;
}

struct Trial {
  std::uint32_t index;
  std::array<double, 3> centre;
  std::array<double, 4> orientation;
};

// Trial moves of the particles (a translation of up to 0.1 along each axis
// and a turn by up to 0.1 rad about a random axis), in sweep order (by the
// scene's cells) or random order; `interior`: only particles at least 3
// from every face (where FCL, without a periodic box, sees what we see).
std::vector<Trial> make_trials(const World& w, const MovingScene& scene, bool sweep_order,
                               bool interior, std::size_t count) {
  std::mt19937_64 engine(7);
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> normal(0, 1);
  const ParticleStore& s = w.scene.particles;
  const double l = w.scene.box.length[0];
  std::vector<std::uint32_t> order;
  for (std::uint32_t i = 0; i < s.size(); ++i) {
    bool inside = true;
    for (int k = 0; k < 3; ++k) {
      const double x = s.centre(k)[i] - l * std::floor(s.centre(k)[i] / l);
      inside = inside && x > 3 && x < l - 3;
    }
    if (!interior || inside) order.push_back(i);
  }
  if (sweep_order) {
    std::vector<std::uint64_t> key(s.size());
    for (std::uint32_t i : order) {
      const auto c = scene.cell_of_particle(i);
      key[i] = (std::uint64_t(c[0]) << 40) | (std::uint64_t(c[1]) << 20) | std::uint64_t(c[2]);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return key[a] < key[b]; });
  } else {
    std::shuffle(order.begin(), order.end(), engine);
  }
  std::vector<Trial> trials;
  for (std::size_t k = 0; trials.size() < count; ++k) {
    const std::uint32_t i = order[k % order.size()];
    Trial t;
    t.index = i;
    for (int d = 0; d < 3; ++d) t.centre[d] = s.centre(d)[i] + 0.1 * (2 * unit(engine) - 1);
    const double angle = 0.1 * unit(engine);
    double axis[3] = {normal(engine), normal(engine), normal(engine)};
    const double norm = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    const std::array<double, 4> turn = {std::cos(angle / 2), std::sin(angle / 2) * axis[0] / norm,
                                        std::sin(angle / 2) * axis[1] / norm,
                                        std::sin(angle / 2) * axis[2] / norm};
    t.orientation = multiply(turn, w.scene.orientation[i]);
    trials.push_back(t);
  }
  return trials;
}

std::map<std::string, std::vector<double>>& rates() {
  static std::map<std::string, std::vector<double>> r;
  return r;
}
std::map<std::string, double>& facts() {
  static std::map<std::string, double> f;
  return f;
}

std::string packing_name(double packing) { return packing < 0.4 ? "0.3" : "0.5"; }

// Pauses the benchmark's timer for the rest of an iteration once the timed
// work is done (pause()), and resumes it when destroyed: declared first in
// the loop's body, it is destroyed last, so that the scene and trials the
// iteration made (a million particles' cells: tens of milliseconds) are
// freed untimed, as they were made.
class UntimedTeardown {
 public:
  explicit UntimedTeardown(benchmark::State& state) : state_(state) {}
  UntimedTeardown(const UntimedTeardown&) = delete;
  void pause() {
    state_.PauseTiming();
    paused_ = true;
  }
  ~UntimedTeardown() {
    if (paused_) state_.ResumeTiming();
  }

 private:
  benchmark::State& state_;
  bool paused_ = false;
};

void single_benchmark(benchmark::State& state, double packing, bool sweep_order, bool interior) {
  const World& w = world(packing, interior);
  const std::string name = std::string(interior ? "moves/interior/" : "moves/single/") +
                           (sweep_order ? "sweep" : "random") + "/packing:" + packing_name(packing);
  std::size_t accepted = 0, queries = 0;
  for (auto _ : state) {
    UntimedTeardown teardown(state);
    state.PauseTiming();
    MovingScene scene(w.scene.particles, w.scene.box);
    const std::vector<Trial> trials =
        make_trials(w, scene, sweep_order, interior, trials_per_iteration);
    std::vector<Particle> made;
    made.reserve(trials.size());
    for (const Trial& t : trials)
      made.push_back(
          ParticleStore::particle_axes(t.centre, w.scene.semi_axes[t.index], t.orientation));
    state.ResumeTiming();
    const double start = now();
    for (std::size_t k = 0; k < made.size(); ++k) {
      const std::int64_t hit = scene.overlaps(made[k], trials[k].index);
      if (hit == MovingScene::none) {
        scene.move(trials[k].index, made[k]);
        ++accepted;
      }
    }
    const double seconds = now() - start;
    queries += made.size();
    teardown.pause();

    rates()[name].push_back(double(made.size()) / seconds);
  }
  state.counters["queries_per_s"] =
      benchmark::Counter(double(queries), benchmark::Counter::kIsRate);
  state.counters["acceptance"] = double(accepted) / double(queries);
}

// Every fourth cell along each axis holds one trial per round (a
// checkerboard's independent domains): batched queries, then move_many.
void batched_benchmark(benchmark::State& state, double packing, int threads) {
  const World& w = world(packing);
  const std::string name =
      "moves/batched/packing:" + packing_name(packing) + "/threads:" + std::to_string(threads);
  std::size_t queries = 0, accepted = 0;
  for (auto _ : state) {
    UntimedTeardown teardown(state);
    state.PauseTiming();
    MovingScene scene(w.scene.particles, w.scene.box);
    const std::vector<Trial> trials = make_trials(w, scene, true, false, trials_per_iteration);
    // Rounds: in each, at most one trial per domain of the round's colour.
    std::vector<std::vector<std::uint32_t>> rounds;
    {
      std::map<std::pair<int, std::array<int, 3>>, std::size_t> used;  // (colour, domain) -> trials
      for (std::uint32_t k = 0; k < trials.size(); ++k) {
        const auto c = scene.cell_of_particle(trials[k].index);
        const auto to = scene.cell_of(trials[k].centre);
        if (c != to) continue;  // a trial that leaves its cell: not in this sweep
        const int colour = (c[0] % 4 == 0) + 2 * (c[1] % 4 == 0) + 4 * (c[2] % 4 == 0);
        if (colour != 7) continue;
        const std::size_t round = used[{colour, c}]++;
        if (rounds.size() <= round) rounds.resize(round + 1);
        rounds[round].push_back(k);
      }
    }
    std::vector<Particle> made;
    for (const Trial& t : trials)
      made.push_back(
          ParticleStore::particle_axes(t.centre, w.scene.semi_axes[t.index], t.orientation));
    state.ResumeTiming();
    const double start = now();
    std::vector<Particle> batch_trials;
    std::vector<std::int64_t> exclude, hit;
    std::vector<std::uint32_t> moving;
    std::vector<Particle> moved;
    std::size_t done = 0;
    for (const auto& round : rounds) {
      batch_trials.clear();
      exclude.clear();
      for (std::uint32_t k : round) {
        batch_trials.push_back(made[k]);
        exclude.push_back(trials[k].index);
      }
      hit.resize(round.size());
      scene.overlaps(batch_trials.data(), exclude.data(), round.size(), hit.data(), threads);
      moving.clear();
      moved.clear();
      for (std::size_t m = 0; m < round.size(); ++m)
        if (hit[m] == MovingScene::none) {
          moving.push_back(trials[round[m]].index);
          moved.push_back(made[round[m]]);
        }
      scene.move_many(moving.data(), moved.data(), moving.size(), threads);
      accepted += moving.size();
      done += round.size();
    }
    const double seconds = now() - start;
    queries += done;
    teardown.pause();

    rates()[name].push_back(double(done) / seconds);
  }
  state.counters["queries_per_s"] =
      benchmark::Counter(double(queries), benchmark::Counter::kIsRate);
  state.counters["acceptance"] = queries ? double(accepted) / double(queries) : 0;
}

// One checkerboard sweep of the Monte Carlo example (HardParticleMC::sweep:
// a trial per particle on average, batched per round, moves by move_many)
// on the scene, with 1 or 2 threads.
void sweep_benchmark(benchmark::State& state, double packing, int threads) {
  const World& w = world(packing);
  const std::string name =
      "mc/sweep/packing:" + packing_name(packing) + "/threads:" + std::to_string(threads);
  const ParticleStore& s = w.scene.particles;
  std::size_t proposed = 0, accepted = 0;
  for (auto _ : state) {
    UntimedTeardown teardown(state);
    state.PauseTiming();
    std::vector<std::array<double, 3>> centre(s.size());
    for (std::size_t i = 0; i < s.size(); ++i)
      centre[i] = {s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]};
    pwcontact::HardParticleMCOptions options;
    options.threads = threads;
    options.adapt_steps = false;
    pwcontact::HardParticleMC mc(w.scene.box, std::move(centre), w.scene.semi_axes,
                                 w.scene.orientation, options);
    state.ResumeTiming();
    const pwcontact::SweepReport r = mc.sweep();
    teardown.pause();
    proposed += r.proposed;
    accepted += r.accepted;
    rates()[name].push_back(double(r.proposed) / r.seconds);
    // (A trial that leaves its domain is rejected without a query.)
    rates()[name + "/queried"].push_back(double(r.proposed - r.left_domain) / r.seconds);
  }
  state.counters["trials_per_s"] =
      benchmark::Counter(double(proposed), benchmark::Counter::kIsRate);
  state.counters["acceptance"] = proposed ? double(accepted) / double(proposed) : 0;
}

// Seconds of the solve per step of a neighbour list kept across steps (the
// packed state, every particle moved by up to 5e-4 along each axis and
// turned by up to 5e-4 rad per step; mu_cut 1.3, skin 0.1, one thread),
// warm-started from each pair's last lambda or cold.
std::map<std::string, std::vector<double>>& solve_seconds() {
  static std::map<std::string, std::vector<double>> s;
  return s;
}

void skin_benchmark(benchmark::State& state, bool warm) {
  const World& w = world(0.5);
  const std::string name = std::string("skin/") + (warm ? "warm" : "cold") + "/packing:0.5";
  const ParticleStore& start = w.scene.particles;
  const std::size_t n = start.size();
  double evaluations = 0;
  std::size_t steps = 0;
  for (auto _ : state) {
    state.PauseTiming();
    std::vector<std::array<double, 3>> centre(n);
    std::vector<std::array<double, 4>> orientation = w.scene.orientation;
    for (std::size_t i = 0; i < n; ++i)
      centre[i] = {start.centre(0)[i], start.centre(1)[i], start.centre(2)[i]};
    pwcontact::SkinOptions options;
    options.cutoff = 1.3;
    options.skin = 0.1;
    options.warm_start = warm;
    options.threads = 1;
    pwcontact::SkinNeighborList list(options);
    pwcontact::ScreenedPairs pairs;
    std::mt19937_64 engine(11);
    std::uniform_real_distribution<double> unit(-1, 1);
    for (int step = 0; step < 6; ++step) {
      ParticleStore s;
      s.reserve(n);
      for (std::size_t i = 0; i < n; ++i)
        s.add_axes(centre[i], w.scene.semi_axes[i], orientation[i]);
      const pwcontact::SkinReport r = list.update(s, w.scene.box, pairs);
      // The first step builds the list, the second solves it cold either way.
      if (step >= 2 && !r.rebuilt) {
        solve_seconds()[name].push_back(r.seconds_solve);
        solve_seconds()[name + "/update"].push_back(r.seconds_total);
        evaluations += r.mean_evaluations;
        ++steps;
      }
      for (std::size_t i = 0; i < n; ++i) {
        for (double& x : centre[i]) x += 5e-4 * unit(engine);
        const double half = 2.5e-4 * unit(engine);
        double axis[3] = {unit(engine), unit(engine), unit(engine)};
        const double norm =
            std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]) + 1e-300;
        orientation[i] =
            multiply({std::cos(half), std::sin(half) * axis[0] / norm,
                      std::sin(half) * axis[1] / norm, std::sin(half) * axis[2] / norm},
                     orientation[i]);
      }
    }
    state.ResumeTiming();
  }
  state.counters["mean_evaluations"] = steps ? evaluations / double(steps) : 0;
}

#ifdef PWCONTACT_WITH_FCL
// Contact within 1e-9 of tangency: the pair's mu^2 by the reference path.
void fcl_benchmark(benchmark::State& state, double packing) {
  const World& w = world(packing, true);
  const std::string name = "fcl/single/packing:" + packing_name(packing);
  const ParticleStore& s = w.scene.particles;
  std::size_t queries = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const MovingScene scene(s, w.scene.box);
    const std::vector<Trial> trials = make_trials(w, scene, true, true, fcl_trials);
    std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
    std::vector<fcl::CollisionObjectd*> pointers;
    auto transform = [](const std::array<double, 3>& c, const std::array<double, 4>& q) {
      fcl::Transform3d t = fcl::Transform3d::Identity();
      t.linear() = fcl::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
      t.translation() = fcl::Vector3d(c[0], c[1], c[2]);
      return t;
    };
    for (std::size_t i = 0; i < s.size(); ++i) {
      const auto& a = w.scene.semi_axes[i];
      auto geometry = std::make_shared<fcl::Ellipsoidd>(a[0], a[1], a[2]);
      objects.push_back(std::make_unique<fcl::CollisionObjectd>(
          geometry,
          transform({s.centre(0)[i], s.centre(1)[i], s.centre(2)[i]}, w.scene.orientation[i])));
      objects.back()->setUserData(reinterpret_cast<void*>(i));
      pointers.push_back(objects.back().get());
    }
    fcl::DynamicAABBTreeCollisionManagerd manager;
    manager.registerObjects(pointers);
    manager.setup();
    std::vector<fcl::Transform3d> current(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) current[i] = objects[i]->getTransform();
    struct Query {
      fcl::CollisionObjectd* self;
      bool hit = false;
    };
    // Ours on exactly these trials from the same state, timed alone (each
    // query and its move, as in moves/single): the rate FCL's is compared
    // with. Five runs, each from a fresh scene; their median.
    {
      std::vector<Particle> made;
      made.reserve(trials.size());
      for (const Trial& t : trials)
        made.push_back(
            ParticleStore::particle_axes(t.centre, w.scene.semi_axes[t.index], t.orientation));
      for (int run = 0; run < 5; ++run) {
        MovingScene timed(s, w.scene.box);
        const double start = now();
        for (std::size_t k = 0; k < made.size(); ++k)
          if (timed.overlaps(made[k], trials[k].index) == MovingScene::none)
            timed.move(trials[k].index, made[k]);
        rates()["moves/fcl_trials/packing:" + packing_name(packing)].push_back(double(made.size()) /
                                                                               (now() - start));
      }
    }
    // Our scene beside FCL's, kept in the same state: every trial is decided
    // by our exact answer in both (so that one disagreement does not make
    // the states, and every later answer, differ); FCL's own answer is
    // compared with it. Only FCL's calls are timed.
    MovingScene ours(s, w.scene.box);
    std::size_t differ = 0, differ_near = 0, missed = 0;
    std::vector<double> gaps;  // |mu^2 - 1| of the disagreeing trials' nearest pair
    double fcl_seconds = 0, collide_seconds = 0;
    state.ResumeTiming();
    for (std::size_t k = 0; k < trials.size(); ++k) {
      const std::uint32_t i = trials[k].index;
      fcl::CollisionObjectd* o = objects[i].get();
      const fcl::Transform3d moved = transform(trials[k].centre, trials[k].orientation);
      const double start = now();
      o->setTransform(moved);
      o->computeAABB();
      manager.update(o);
      const double collide_start = now();
      Query query{o};
      manager.collide(o, &query,
                      [](fcl::CollisionObjectd* a, fcl::CollisionObjectd* b, void* data) {
                        Query& q = *static_cast<Query*>(data);
                        if (a == b) return false;
                        fcl::CollisionRequestd request;
                        fcl::CollisionResultd result;
                        fcl::collide(a, b, request, result);
                        q.hit = result.isCollision();
                        return q.hit;  // stop at the first contact
                      });
      const double end = now();
      fcl_seconds += end - start;
      collide_seconds += end - collide_start;
      const Particle trial = ParticleStore::particle_axes(trials[k].centre, w.scene.semi_axes[i],
                                                          trials[k].orientation);
      const bool overlapping = ours.overlaps(trial, i) != MovingScene::none;
      if (query.hit != overlapping) {
        ++differ;
        // How near tangency: the trial's smallest mu^2 with any particle.
        double nearest = INFINITY;
        for (const pwcontact::Neighbor& n : ours.neighbors(trial, 1.01, true, i))
          nearest = std::min(nearest, n.mu2);
        differ_near += std::abs(nearest - 1) <= 1e-9;
        missed += overlapping;  // FCL says apart, the exact answer overlapping
        gaps.push_back(std::abs(nearest - 1));
      }
      if (overlapping) {
        o->setTransform(current[i]);
        o->computeAABB();
        manager.update(o);
      } else {
        current[i] = moved;
        ours.move(i, trial);
      }
    }
    state.PauseTiming();
    queries += trials.size();
    rates()[name].push_back(double(trials.size()) / fcl_seconds);
    rates()[name + "/collide_only"].push_back(double(trials.size()) / collide_seconds);
    facts()["fcl_disagreements/packing:" + packing_name(packing)] = double(differ);
    facts()["fcl_disagreements_near/packing:" + packing_name(packing)] = double(differ_near);
    facts()["fcl_missed/packing:" + packing_name(packing)] = double(missed);
    std::sort(gaps.begin(), gaps.end());
    if (!gaps.empty()) {
      facts()["fcl_gap_min/packing:" + packing_name(packing)] = gaps.front();
      facts()["fcl_gap_median/packing:" + packing_name(packing)] = gaps[gaps.size() / 2];
      facts()["fcl_gap_max/packing:" + packing_name(packing)] = gaps.back();
    }
    state.ResumeTiming();
  }
  state.counters["queries_per_s"] =
      benchmark::Counter(double(queries), benchmark::Counter::kIsRate);
}
#endif

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

void print_summary() {
  std::printf("\nSummary (medians over every timed iteration of this run):\n");
  const double warm = median(solve_seconds()["skin/warm/packing:0.5"]);
  const double cold = median(solve_seconds()["skin/cold/packing:0.5"]);
  if (!std::isnan(warm) && !std::isnan(cold))
    std::printf(
        "  neighbour list kept across steps: solve %.1f ms warm, %.1f ms cold: warm start "
        "saves %.0f %% (target >= 30 %%): %s\n",
        warm * 1e3, cold * 1e3, 100 * (1 - warm / cold),
        1 - warm / cold >= 0.3 ? "met" : "NOT met");
  const double warm_update = median(solve_seconds()["skin/warm/packing:0.5/update"]);
  const double cold_update = median(solve_seconds()["skin/cold/packing:0.5/update"]);
  if (!std::isnan(warm_update) && !std::isnan(cold_update))
    std::printf(
        "  neighbour list kept across steps: whole update (criterion, gather, solve, output) "
        "%.1f ms warm, %.1f ms cold\n",
        warm_update * 1e3, cold_update * 1e3);
  for (const auto& [name, r] : rates())
    std::printf("  %-40s %8.3f M queries/s (%zu runs)\n", name.c_str(), median(r) / 1e6, r.size());
  for (const char* p : {"0.3", "0.5"}) {
    const std::string packing = std::string("packing:") + p;
    auto get = [&](const std::string& n) {
      auto f = rates().find(n);
      return f == rates().end() ? NAN : median(f->second);
    };
    const double single = get("moves/single/sweep/" + packing);
    const double random = get("moves/single/random/" + packing);
    const double interior = get("moves/fcl_trials/" + packing);
    const double fcl = get("fcl/single/" + packing);
    const double fcl_collide = get("fcl/single/" + packing + "/collide_only");
    const double one = get("moves/batched/" + packing + "/threads:1");
    const double two = get("moves/batched/" + packing + "/threads:2");
    if (!std::isnan(single))
      std::printf(
          "  %s: single queries %.2f M/s in sweep order, %.2f M/s in random order "
          "(target >= 3 M/s per core): %s\n",
          packing.c_str(), single / 1e6, random / 1e6, single >= 3e6 ? "met" : "NOT met");
    if (!std::isnan(fcl))
      std::printf(
          "  %s: against FCL on the same %zu interior trials from the same state (ours "
          "%.2f M/s, FCL %.4f M/s, each with its moves): %.1fx (target >= 20x): %s; "
          "FCL disagrees with the exact answer on %.0f of them (%.0f within "
          "1e-9 of tangency)\n",
          packing.c_str(), fcl_trials, interior / 1e6, fcl / 1e6, interior / fcl,
          interior / fcl >= 20 ? "met" : "NOT met", facts()["fcl_disagreements/" + packing],
          facts()["fcl_disagreements_near/" + packing]);
    if (facts()["fcl_disagreements/" + packing] > 0)
      std::printf(
          "  %s: of FCL's disagreements, %.0f say apart where the pair overlaps; the "
          "nearest pair's |mu^2 - 1| min %.3g, median %.3g, max %.3g\n",
          packing.c_str(), facts()["fcl_missed/" + packing], facts()["fcl_gap_min/" + packing],
          facts()["fcl_gap_median/" + packing], facts()["fcl_gap_max/" + packing]);
    if (!std::isnan(fcl_collide))
      std::printf(
          "  %s: against FCL's collide alone (its update, an O(N) re-balance, left out): "
          "%.1fx\n",
          packing.c_str(), interior / fcl_collide);
    if (!std::isnan(two))
      std::printf("  %s: batched rounds (every fourth cell), 2 threads over 1: %.2fx\n",
                  packing.c_str(), two / one);
    const double sweep1 = get("mc/sweep/" + packing + "/threads:1");
    const double sweep2 = get("mc/sweep/" + packing + "/threads:2");
    if (!std::isnan(sweep2))
      std::printf(
          "  %s: Monte Carlo checkerboard sweep %.2f M trials/s with 1 thread, %.2f with 2 "
          "(%.2f and %.2f M queries/s: trials that leave their domain are rejected "
          "unqueried): %.2fx (target >= 1.8x): %s\n",
          packing.c_str(), sweep1 / 1e6, sweep2 / 1e6,
          get("mc/sweep/" + packing + "/threads:1/queried") / 1e6,
          get("mc/sweep/" + packing + "/threads:2/queried") / 1e6, sweep2 / sweep1,
          sweep2 / sweep1 >= 1.8 ? "met" : "NOT met");
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  for (double packing : {0.3, 0.5}) {
    const std::string p = packing_name(packing);
    for (bool sweep : {true, false})
      benchmark::RegisterBenchmark(
          (std::string("moves/single/") + (sweep ? "sweep" : "random") + "/packing:" + p).c_str(),
          single_benchmark, packing, sweep, false)
          ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark(("moves/interior/sweep/packing:" + p).c_str(), single_benchmark,
                                 packing, true, true)
        ->Unit(benchmark::kMillisecond);
#ifdef PWCONTACT_WITH_FCL
    benchmark::RegisterBenchmark(("fcl/single/packing:" + p).c_str(), fcl_benchmark, packing)
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);
#endif
    for (int threads : {1, 2})
      benchmark::RegisterBenchmark(
          ("moves/batched/packing:" + p + "/threads:" + std::to_string(threads)).c_str(),
          batched_benchmark, packing, threads)
          ->Unit(benchmark::kMillisecond);
  }
  for (double packing : {0.3, 0.5})
    for (int threads : {1, 2})
      benchmark::RegisterBenchmark(
          ("mc/sweep/packing:" + packing_name(packing) + "/threads:" + std::to_string(threads))
              .c_str(),
          sweep_benchmark, packing, threads)
          ->Unit(benchmark::kMillisecond);
  for (bool warm : {true, false})
    benchmark::RegisterBenchmark(
        (std::string("skin/") + (warm ? "warm" : "cold") + "/packing:0.5").c_str(), skin_benchmark,
        warm)
        ->Unit(benchmark::kMillisecond)
        ->Iterations(1);
  benchmark::RunSpecifiedBenchmarks();
  print_summary();
  benchmark::Shutdown();
  return 0;
}
