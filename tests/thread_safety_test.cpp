// The library called from several threads of the caller's at once (each
// call with its own OpenMP team): every call gets the answers it gets alone.
// Run under ThreadSanitizer by `bash scripts/run.sh tsan`, where it also
// shows that no state is shared without synchronisation.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

#include "test_support.hpp"

namespace pwtest {
namespace {

// What one caller does: full answers in double and float, overlap answers,
// the reference path, a screen; returned for comparison.
struct Answers {
  std::vector<double> mu2, lambda;
  std::vector<float> mu2_float;
  std::vector<std::uint8_t> overlap;
  std::vector<double> reference;
  std::vector<std::uint32_t> pairs_i, pairs_j;
};

Answers work(const PairBatch<double>& pairs, const PairBatch<float>& floats,
             const pwcontact::ParticleStore& scene, int threads) {
  Answers a;
  const std::size_t n = pairs.size();
  BatchOptions options;
  options.threads = threads;
  a.mu2.resize(n);
  a.lambda.resize(n);
  std::vector<Status> status(n);
  pwcontact::contact_function_batch(pairs.view(), {a.mu2.data(), a.lambda.data(), status.data()},
                                    options);
  a.mu2_float.resize(n);
  std::vector<Status> status_float(n);
  pwcontact::contact_function_batch(floats.view(),
                                    {a.mu2_float.data(), nullptr, status_float.data()}, options);
  a.overlap.resize(n);
  pwcontact::overlap_batch(pairs.view(), {a.overlap.data(), status.data()}, options, 1.0);
  for (std::size_t i = 0; i < n; i += 97) a.reference.push_back(reference(pair_at(pairs, i)).mu2);
  pwcontact::ScreenOptions screen;
  screen.threads = threads;
  pwcontact::ScreenedPairs found;
  pwcontact::screen_pairs(scene, pwcontact::Box::periodic_box(12, 12, 12), screen, found);
  a.pairs_i = found.i;
  a.pairs_j = found.j;
  return a;
}

TEST(ThreadSafety, CallsFromSeveralThreadsGetTheAnswersTheyGetAlone) {
  const PairBatch<double> pairs = pwcontact::random_pairs(20000, 17);
  const PairBatch<float> floats = make_batch(convert_all<float>(pairs_of(pairs)));
  pwcontact::ParticleStore scene;
  Engine engine(18);
  for (int k = 0; k < 1500; ++k)
    scene.add_axes({12 * uniform01(engine), 12 * uniform01(engine), 12 * uniform01(engine)},
                   {0.3 + 0.3 * uniform01(engine), 0.4, 0.5},
                   {uniform01(engine) - 0.5, uniform01(engine) - 0.5, uniform01(engine), 1});
  const Answers alone = work(pairs, floats, scene, 1);
  constexpr int callers = 4;
  std::vector<Answers> answers(callers);
  std::vector<std::thread> threads;
  for (int t = 0; t < callers; ++t)
    threads.emplace_back([&, t] { answers[t] = work(pairs, floats, scene, 1 + t % 2); });
  for (std::thread& thread : threads) thread.join();
  for (int t = 0; t < callers; ++t) {
    EXPECT_EQ(answers[t].mu2, alone.mu2) << "caller " << t;
    EXPECT_EQ(answers[t].lambda, alone.lambda) << "caller " << t;
    EXPECT_EQ(answers[t].mu2_float, alone.mu2_float) << "caller " << t;
    EXPECT_EQ(answers[t].overlap, alone.overlap) << "caller " << t;
    EXPECT_EQ(answers[t].reference, alone.reference) << "caller " << t;
    EXPECT_EQ(answers[t].pairs_i, alone.pairs_i) << "caller " << t;
    EXPECT_EQ(answers[t].pairs_j, alone.pairs_j) << "caller " << t;
  }
}

// A workspace's bytes() asked from another thread while screens run in it:
// the figure as of the last screen's end, read without touching the arrays
// the running screen resizes (ThreadSanitizer reports it otherwise), and
// the screens' pairs those of a screen without a workspace.
TEST(ThreadSafety, AWorkspacesBytesAskedDuringItsScreensFromAnotherThread) {
  pwcontact::ParticleStore scene;
  Engine engine(19);
  for (int k = 0; k < 1500; ++k)
    scene.add_axes({12 * uniform01(engine), 12 * uniform01(engine), 12 * uniform01(engine)},
                   {0.3 + 0.3 * uniform01(engine), 0.4, 0.5},
                   {uniform01(engine) - 0.5, uniform01(engine) - 0.5, uniform01(engine), 1});
  const pwcontact::Box box = pwcontact::Box::periodic_box(12, 12, 12);
  pwcontact::ScreenOptions options;
  options.threads = 2;
  pwcontact::ScreenedPairs alone;
  pwcontact::screen_pairs(scene, box, options, alone);
  pwcontact::ScreenWorkspace workspace;
  std::atomic<bool> done{false};
  std::vector<std::size_t> seen;
  std::thread asker([&] {
    while (!done.load()) {
      const std::size_t b = workspace.bytes();
      if (seen.empty() || seen.back() != b) seen.push_back(b);  // (the changes only)
    }
  });
  std::vector<std::size_t> after;
  for (int round = 0; round < 4; ++round) {
    pwcontact::ScreenedPairs found;
    pwcontact::screen_pairs(scene, box, options, found, workspace);
    EXPECT_EQ(found.i, alone.i) << "round " << round;
    EXPECT_EQ(found.j, alone.j) << "round " << round;
    after.push_back(workspace.bytes());
    if (round == 1) workspace.release();
  }
  done = true;
  asker.join();
  // Every figure seen is one a screen ended with, or 0 (new or released).
  for (std::size_t b : seen)
    EXPECT_TRUE(b == 0 || std::find(after.begin(), after.end(), b) != after.end()) << b;
  EXPECT_GT(after.back(), 0u);
}

TEST(ThreadSafety, AMovingSceneAnswersCallersInSeveralThreadsAndMovesInParallel) {
  // Queries are const: single and batched ones from several threads at once
  // (each with its own per-thread solver), then a sweep of HardParticleMC
  // (batched queries and parallel moves) with 2 threads against 1.
  pwcontact::HardParticleMCOptions options;
  options.threads = 1;
  auto one = pwcontact::HardParticleMC::dilute_spheroids(1500, 5, 3, options);
  options.threads = 2;
  auto two = pwcontact::HardParticleMC::dilute_spheroids(1500, 5, 3, options);
  for (int sweep = 0; sweep < 2; ++sweep) {
    one.sweep();
    two.sweep();
  }
  for (int k = 0; k < 3; ++k) EXPECT_EQ(one.particles().centre(k), two.particles().centre(k));
  const pwcontact::MovingScene scene(one.particles(), one.box());
  std::vector<pwcontact::MovingScene::Particle> trials;
  std::vector<std::int64_t> exclude;
  Engine engine(19);
  for (std::size_t i = 0; i < scene.size(); i += 3) {
    auto c = scene.particles().particle_at(i).centre();
    for (double& x : c) x += 1.5 * (uniform01(engine) - 0.5);
    trials.push_back(scene.particles().particle_at(i).moved_to(c));
    exclude.push_back(std::int64_t(i));
  }
  std::vector<std::int64_t> alone(trials.size());
  for (std::size_t k = 0; k < trials.size(); ++k) alone[k] = scene.overlaps(trials[k], exclude[k]);
  constexpr int callers = 4;
  std::vector<std::vector<std::int64_t>> single(callers), batched(callers);
  std::vector<std::thread> threads;
  for (int t = 0; t < callers; ++t)
    threads.emplace_back([&, t] {
      for (std::size_t k = 0; k < trials.size(); ++k)
        single[t].push_back(scene.overlaps(trials[k], exclude[k]));
      batched[t].resize(trials.size());
      scene.overlaps(trials.data(), exclude.data(), trials.size(), batched[t].data(), 1 + t % 2);
    });
  for (std::thread& thread : threads) thread.join();
  for (int t = 0; t < callers; ++t) {
    EXPECT_EQ(single[t], alone) << "caller " << t;
    EXPECT_EQ(batched[t], alone) << "caller " << t;
  }
}

}  // namespace
}  // namespace pwtest
