// screen_pairs: cell lists, prefilters, compaction, the batch path, and the
// pairs found in a deterministic order (see screen.hpp).
#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "number_text.hpp"
#include "parallel_errors.hpp"
#include "pwcontact/reference.hpp"
#include "pwcontact/screen.hpp"
#include "screen/cell_lists.hpp"
#include "screen/pair_prefilters.hpp"
#include "screen/radix_sort.hpp"
#include "thread_count.hpp"

namespace pwcontact {
using screen::Side;
namespace {

// A pair the prefilters left: its indices i < j, r12 = c_j - c_i (minimum
// image), and the two forms (copied while they are in cache).
struct Undecided {
  std::uint32_t i, j;
  double r[3];
  double q1[6], q2[6];
};

// What one thread's share of the particles produced, and its buffers: the
// pairs the prefilters leave are solved a chunk at a time, while they are in
// cache, rather than gathered for the whole scene first (which would build a
// batch of 120 bytes per pair in memory).
struct ThreadPairs {
  std::vector<Undecided> undecided;  // waiting for the next chunk's solve
  std::vector<std::uint64_t> found;  // i << 32 | j
  std::vector<double> found_mu2;     // with_mu2
  std::size_t candidates = 0, out = 0, out_by_projection = 0, in = 0, spheres = 0, same_form = 0,
              solved = 0, invalid = 0, fallbacks = 0;
  double evaluations = 0;  // summed over the solved pairs
  double seconds_compaction = 0, seconds_solve = 0;
  BatchReport last;  // of the last chunk solved (settings as resolved)
  PairBatch<double> batch;
  std::vector<Status> status;
  std::vector<std::uint8_t> overlap;
  std::vector<double> mu2;

  // Ready for a screen: counts zeroed, buffers emptied (their storage kept).
  void start() {
    undecided.clear();
    found.clear();
    found_mu2.clear();
    candidates = out = out_by_projection = in = spheres = same_form = solved = invalid = fallbacks =
        0;
    evaluations = seconds_compaction = seconds_solve = 0;
    last = BatchReport();
  }
};

// Pairs solved per call of the batch path: enough to amortise a call, few
// enough that the chunk stays in cache between compaction and solve.
constexpr std::size_t solve_chunk = 8192;

std::uint64_t pair_key(std::uint32_t i, std::uint32_t j) { return (std::uint64_t(i) << 32) | j; }

// Compacts the waiting pairs into the thread's batch and solves them (one
// thread: the screen's threads are already busy), keeping those found.
void solve_waiting(ThreadPairs& t, const ScreenOptions& options) {
  const std::size_t n = t.undecided.size();
  if (n == 0) return;
  const double start = omp_get_wtime();
  t.batch.resize(n);
  for (std::size_t at = 0; at < n; ++at) {
    const Undecided& u = t.undecided[at];
    for (int k = 0; k < 3; ++k) t.batch.r12(k)[at] = u.r[k];
    for (int k = 0; k < 6; ++k) {
      t.batch.q1(k)[at] = u.q1[k];
      t.batch.q2(k)[at] = u.q2[k];
    }
  }
  t.status.resize(n);
  const double compacted = omp_get_wtime();
  BatchOptions batch_options = options.batch;
  batch_options.threads = 1;
  const double cutoff2 = options.cutoff * options.cutoff;
  if (options.with_mu2) {
    t.mu2.resize(n);
    t.last = contact_function_batch(t.batch.view(), {t.mu2.data(), nullptr, t.status.data()},
                                    batch_options);
    for (std::size_t at = 0; at < n; ++at)
      // (A mu^2 below the normal range, out_of_range, is a pair found.)
      if ((is_valid(t.status[at]) || t.status[at] == Status::out_of_range) && t.mu2[at] < cutoff2) {
        t.found.push_back(pair_key(t.undecided[at].i, t.undecided[at].j));
        t.found_mu2.push_back(t.mu2[at]);
      }
  } else {
    t.overlap.resize(n);
    t.last = overlap_batch(t.batch.view(), {t.overlap.data(), t.status.data()}, batch_options,
                           options.cutoff);
    for (std::size_t at = 0; at < n; ++at)
      if (t.overlap[at]) t.found.push_back(pair_key(t.undecided[at].i, t.undecided[at].j));
  }
  t.solved += n;
  // Pairs whose mu^2 is out of range are answered (found or not): not invalid here.
  t.invalid += t.last.invalid - t.last.status_counts[int(Status::out_of_range)];
  t.fallbacks += t.last.fallbacks;
  t.evaluations += t.last.mean_evaluations * double(n);
  t.undecided.clear();
  t.seconds_compaction += compacted - start;
  t.seconds_solve += omp_get_wtime() - compacted;
}

// The first prefilter: apart when the bounding spheres scaled by the cutoff
// do not meet (most candidates: kept to a few operations, before anything
// else about the pair is loaded; the cell search has already dropped the
// pairs a coarse form of this test decides).
inline bool apart_by_bounding_spheres(ThreadPairs& mine, double cutoff, double rr,
                                      double bounding_sum) {
  const double reach = cutoff * bounding_sum;
  if (rr < reach * reach + screen::square_slack) return false;
  ++mine.out;
  return true;
}

// The pair (p, o) with r = c_o - c_p that the bounding spheres left: what
// the prefilters decide is counted and kept; the rest waits for the next
// chunk's solve.
inline void classify_near_pair(ThreadPairs& mine, const ScreenOptions& options, const Side& p,
                               const Side& o, const double r[3], double rr) {
  const double cutoff = options.cutoff;
  const bool p_first = p.index < o.index;
  const std::uint32_t a = p_first ? p.index : o.index, b = p_first ? o.index : p.index;
  auto decide = [&](double mu2) {
    if (mu2 < cutoff * cutoff) {
      mine.found.push_back(pair_key(a, b));
      if (options.with_mu2) mine.found_mu2.push_back(mu2);
    }
  };
  double mu2 = 0;
  switch (screen::decide_near_pair(p, o, r, rr, cutoff, options.with_mu2, mu2)) {
    case screen::NearPair::spheres:
      ++mine.spheres;
      decide(mu2);
      return;
    case screen::NearPair::same_form:
      ++mine.same_form;
      decide(mu2);
      return;
    case screen::NearPair::in:
      mine.found.push_back(pair_key(a, b));
      ++mine.in;
      return;
    case screen::NearPair::out_by_projection: ++mine.out_by_projection; return;
    case screen::NearPair::undecided: break;
  }
  // r12 from the lower index to the higher: the pair as (a, b).
  const double sign = p_first ? 1 : -1;
  const Side& first = p_first ? p : o;
  const Side& second = p_first ? o : p;
  // (Built here and appended, rather than appended value-initialised and
  // filled: zeroing it first took a tenth of this function.)
  Undecided u;
  u.i = a;
  u.j = b;
  for (int k = 0; k < 3; ++k) u.r[k] = sign * r[k];
  for (int k = 0; k < 6; ++k) {
    u.q1[k] = first.q[k];
    u.q2[k] = second.q[k];
  }
  mine.undecided.push_back(u);
  if (mine.undecided.size() == solve_chunk) solve_waiting(mine, options);
}

// The options checked, with what they leave to be resolved settled here,
// before any thread starts: an error inside the search's threads would
// otherwise be one per thread.
ScreenOptions checked(const ParticleStore& particles, const Box& box, ScreenOptions options) {
  if (!(options.cutoff > 0) || !std::isfinite(options.cutoff))
    throw std::invalid_argument("screen_pairs: the cutoff must be positive and finite, got " +
                                detail::number_text(options.cutoff));
  // mu^2 is compared with cutoff^2: it must be a normal number.
  const double cutoff2 = options.cutoff * options.cutoff;
  if (!(cutoff2 >= std::numeric_limits<double>::min()) || !std::isfinite(cutoff2))
    throw std::invalid_argument(
        "screen_pairs: the cutoff's square is outside the range of normal doubles, cutoff " +
        detail::number_text(options.cutoff));
  // PWCONTACT_ISA and the CPU are read once, here.
  options.batch.isa = resolve_isa(options.batch.isa);
  detail::thread_count(options.threads, "screen_pairs");
  // Cell indices are 32-bit and grids have up to two cells per particle.
  if (particles.size() >= (std::size_t(1) << 31))
    throw std::invalid_argument("screen_pairs: at most 2^31 - 1 particles");
  // (A slot resize() left unset has a reach of 0, which no grid of cells can
  // be sized for: the cell lists' search for a grid never ended.)
  particles.require_set("screen_pairs");
  detail::check_box(box);  // (a Box filled in by hand: as its factories check it)
  if (!box.periodic || particles.size() == 0) return options;
  const std::vector<double>& bounding = particles.bounding_radius();
  const double largest = *std::max_element(bounding.begin(), bounding.end());
  const double reach = options.cutoff * 2 * largest;
  const std::array<double, 3> widths = box.perpendicular_widths();
  for (int k = 0; k < 3; ++k)
    if (box.periodic_along(k) && !(2 * reach <= widths[k]))
      throw std::invalid_argument(
          "screen_pairs: the periodic box is too small for the cutoff: its width " +
          detail::number_text(widths[k]) + " across axis " + std::to_string(k) +
          (box.orthorhombic() ? std::string() : " (between the faces of the tilted box)") +
          " is less than twice the largest reach (the reach cutoff * 2 R_max is " +
          detail::number_text(reach) + "; the minimum image convention would miss pairs)");
  return options;
}

}  // namespace

namespace {

// The elements of the lists (one per thread of the search), sorted by
// their pair keys key(x) (pair_key of two indices below `particles`), each
// once (elements of equal keys are the same pair), handed to emit(x) in
// that order: each list sorted by radix in a thread of its own, merged two
// by two while more than four remain, and the last ones merged straight
// into emit (no merged copy: on a 4M-particle scene a fresh array for it
// cost more than the merge). scratch: the sorts' second arrays, one per
// list (kept for the next screen by a workspace).
template <class T, class Key, class Emit>
void sorted_union(std::vector<std::vector<T>>& lists, std::vector<std::vector<T>>& scratch,
                  int threads, std::size_t particles, Key key, Emit emit) {
  const auto less = [&key](const T& x, const T& y) { return key(x) < key(y); };
  const int bits = screen::index_bits(particles);
  detail::ParallelErrors errors;
  const std::ptrdiff_t count = std::ptrdiff_t(lists.size());
  scratch.resize(lists.size());
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::ptrdiff_t t = 0; t < count; ++t)
    errors.run([&] {
      const std::size_t l = std::size_t(t);
      screen::radix_sort_pair_keys(lists[l], bits, key, &scratch[l]);
    });
  errors.rethrow_if_failed();
  lists.erase(std::remove_if(lists.begin(), lists.end(), [](const auto& l) { return l.empty(); }),
              lists.end());
  // Neighbours merged in rounds (list 2k with 2k + 1: each element copied
  // once a round, and equal keys kept in the lists' order).
  while (lists.size() > 4) {
    std::vector<std::vector<T>> fewer((lists.size() + 1) / 2);
    for (std::size_t k = 0; k < fewer.size(); ++k) {
      if (2 * k + 1 == lists.size()) {
        fewer[k].swap(lists[2 * k]);
        continue;
      }
      const std::vector<T>& a = lists[2 * k];
      const std::vector<T>& b = lists[2 * k + 1];
      fewer[k].resize(a.size() + b.size());
      std::merge(a.begin(), a.end(), b.begin(), b.end(), fewer[k].begin(), less);
      std::vector<T>().swap(lists[2 * k]);
      std::vector<T>().swap(lists[2 * k + 1]);
    }
    lists.swap(fewer);
  }
  // The heads of the remaining lists: the least key next, a key equal to
  // the last emitted skipped.
  std::size_t head[4] = {0, 0, 0, 0};
  bool any = false;
  std::uint64_t last = 0;
  for (;;) {
    int best = -1;
    for (std::size_t l = 0; l < lists.size(); ++l)
      if (head[l] < lists[l].size() &&
          (best < 0 || key(lists[l][head[l]]) < key(lists[std::size_t(best)][head[best]])))
        best = int(l);
    if (best < 0) break;
    const T& x = lists[std::size_t(best)][head[best]++];
    if (any && key(x) == last) continue;
    any = true;
    last = key(x);
    emit(x);
  }
}

// The sorts' lists and second arrays (pair keys alone, or with mu^2): a
// workspace's, or the call's own.
struct SortMemory {
  std::vector<std::vector<std::uint64_t>> keys, key_scratch;
  std::vector<std::vector<std::pair<std::uint64_t, double>>> keyed, keyed_scratch;
};

}  // namespace

// What a screen keeps for the next (see ScreenWorkspace): the cell lists'
// arrays, the threads' buffers, the sort's lists and their second arrays.
// bytes() reads `held`, which a screen sets when it ends (and release()
// zeroes), never the vectors themselves: a running screen resizes them, and
// bytes() may be asked from another thread meanwhile.
struct ScreenWorkspace::Impl {
  screen::CellListMemory cells;
  std::vector<ThreadPairs> threads;
  SortMemory sort;
  std::atomic<bool> busy{false};
  std::atomic<std::size_t> held{0};
  std::size_t capacity_bytes() const noexcept;
};

namespace {

// Sums what the threads counted into the report, and the pairs found,
// sorted by (i, j) and each once, into out. t1: when the search began.
// kept: a workspace's memory, or null. (out: emptied by the caller.)
void finish(std::vector<ThreadPairs>& per_thread, const ScreenOptions& options, int threads,
            std::size_t particles, double t1, ScreenReport& report, ScreenedPairs& out,
            ScreenWorkspace::Impl* kept) {
  // Compaction and solve ran inside the search, chunk by chunk: their times
  // are the threads' summed times shared out over the threads, and the
  // search's time what remains of the stage.
  double compaction = 0, solve = 0, evaluations = 0;
  for (const ThreadPairs& t : per_thread) {
    report.candidate_pairs += t.candidates;
    report.decided_out += t.out;
    report.decided_out_by_projection += t.out_by_projection;
    report.decided_in += t.in;
    report.decided_spheres += t.spheres;
    report.decided_same_form += t.same_form;
    report.solved += t.solved;
    report.invalid += t.invalid;
    report.batch.fallbacks += t.fallbacks;
    evaluations += t.evaluations;
    compaction += t.seconds_compaction;
    solve += t.seconds_solve;
    if (t.solved) {
      report.batch.isa = t.last.isa;
      report.batch.precision = t.last.precision;
      report.batch.formulation = t.last.formulation;
      report.batch.iterations = t.last.iterations;
    }
  }
  report.batch.pairs = report.solved;
  report.batch.invalid = report.invalid;
  report.batch.threads = threads;
  report.batch.mean_evaluations = report.solved ? evaluations / double(report.solved) : 0;
  double t2 = omp_get_wtime();
  report.seconds_compaction = compaction / threads;
  report.seconds_solve = solve / threads;
  report.seconds_candidates =
      std::max(0.0, (t2 - t1) - report.seconds_compaction - report.seconds_solve);
  const double t4 = t2;

  // The pairs found, sorted by (i, j), each once (a pair listed twice by
  // the candidate lists is kept once).
  std::size_t upper = 0;  // the pairs found, counted with repeats
  for (const ThreadPairs& t : per_thread) upper += t.found.size();
  SortMemory own;
  SortMemory& sort = kept ? kept->sort : own;
  out.i.reserve(upper);
  out.j.reserve(upper);
  auto emit_pair = [&out](std::uint64_t key) {
    out.i.push_back(std::uint32_t(key >> 32));
    out.j.push_back(std::uint32_t(key));
  };
  if (options.with_mu2) {
    out.mu2.reserve(upper);
    std::vector<std::vector<std::pair<std::uint64_t, double>>>& lists = sort.keyed;
    lists.resize(per_thread.size());
    for (std::size_t t = 0; t < per_thread.size(); ++t) {
      ThreadPairs& mine = per_thread[t];
      lists[t].clear();
      lists[t].reserve(mine.found.size());
      for (std::size_t k = 0; k < mine.found.size(); ++k)
        lists[t].push_back({mine.found[k], mine.found_mu2[k]});
      if (kept) {
        mine.found.clear();
        mine.found_mu2.clear();
      } else {
        std::vector<std::uint64_t>().swap(mine.found);
        std::vector<double>().swap(mine.found_mu2);
      }
    }
    sorted_union(
        lists, sort.keyed_scratch, threads, particles, [](const auto& x) { return x.first; },
        [&](const std::pair<std::uint64_t, double>& x) {
          emit_pair(x.first);
          out.mu2.push_back(x.second);
        });
  } else {
    // (The threads' found pairs swapped in: their buffers then hold the
    // lists' old storage, emptied, for the next screen.)
    std::vector<std::vector<std::uint64_t>>& lists = sort.keys;
    lists.resize(per_thread.size());
    for (std::size_t t = 0; t < per_thread.size(); ++t) {
      lists[t].clear();
      lists[t].swap(per_thread[t].found);
    }
    sorted_union(
        lists, sort.key_scratch, threads, particles, [](std::uint64_t x) { return x; }, emit_pair);
  }
  if (out.size() < upper / 2) {  // (repeats in a candidate list of one's own)
    out.i.shrink_to_fit();
    out.j.shrink_to_fit();
    out.mu2.shrink_to_fit();
  }
  report.found = out.size();
  report.seconds_output = omp_get_wtime() - t4;
}

// screen_pairs, in a workspace's memory when kept is not null.
ScreenReport screen_in(const ParticleStore& particles, const Box& box, const ScreenOptions& given,
                       ScreenedPairs& out, ScreenWorkspace::Impl* kept) {
  const ScreenOptions options = checked(particles, box, given);
  ScreenReport report;
  report.particles = particles.size();
  if (kept) {
    out.i.clear();
    out.j.clear();
    out.mu2.clear();
  } else {
    out = {};
  }
  const int threads = detail::thread_count(options.threads, "screen_pairs");
  report.threads = threads;
  const double cutoff = options.cutoff;

  double t0 = omp_get_wtime();
  screen::CellLists lists =
      screen::build_cell_lists(particles, box, cutoff, threads, kept ? &kept->cells : nullptr);
  report.size_classes = lists.grids.size();
  report.identical_shapes = lists.identical_shapes;
  report.one_type = lists.one_type;
  double t1 = omp_get_wtime();
  report.seconds_cells = t1 - t0;

  // Candidates and prefilters; the undecided pairs solved chunk by chunk.
  std::vector<ThreadPairs> own;
  std::vector<ThreadPairs>& per_thread = kept ? kept->threads : own;
  per_thread.resize(static_cast<std::size_t>(threads));
  for (ThreadPairs& t : per_thread) t.start();
  screen::search_candidates<true>(
      lists, threads, options.progress,
      [&](int thread, const screen::Candidate& c) {
        ThreadPairs& mine = per_thread[std::size_t(thread)];
        const screen::Member& i = *c.i;
        const screen::Member& j = *c.j;
        const double rr = c.r[0] * c.r[0] + c.r[1] * c.r[1] + c.r[2] * c.r[2];
        const double bi = c.coarse_i->bounding, bj = c.coarse_j->bounding;
        if (apart_by_bounding_spheres(mine, options.cutoff, rr, bi + bj)) return;
        classify_near_pair(mine, options, {i.index, bi, i.inscribed, i.sphere_radius(), i.q},
                           {j.index, bj, j.inscribed, j.sphere_radius(), j.q}, c.r, rr);
      },
      [&](int thread, std::size_t compared, std::size_t passed) {
        ThreadPairs& mine = per_thread[std::size_t(thread)];
        mine.candidates += compared;
        mine.out += compared - passed;  // by the coarse form of the bounding test
        solve_waiting(mine, options);
      });
  if (options.progress) options.progress(1);
  finish(per_thread, options, threads, particles.size(), t1, report, out, kept);
  if (kept) kept->cells.grids = std::move(lists.grids);
  return report;
}

}  // namespace

ScreenReport screen_pairs(const ParticleStore& particles, const Box& box,
                          const ScreenOptions& options, ScreenedPairs& out) {
  return screen_in(particles, box, options, out, nullptr);
}

ScreenWorkspace::ScreenWorkspace() : impl_(std::make_unique<Impl>()) {}
ScreenWorkspace::~ScreenWorkspace() = default;
ScreenWorkspace::ScreenWorkspace(ScreenWorkspace&&) noexcept = default;
ScreenWorkspace& ScreenWorkspace::operator=(ScreenWorkspace&&) noexcept = default;

std::size_t ScreenWorkspace::bytes() const noexcept { return impl_ ? impl_->held.load() : 0; }

// (Only while the busy flag is held: by the screen that ends, or release().)
std::size_t ScreenWorkspace::Impl::capacity_bytes() const noexcept {
  std::size_t total = cells.bytes();
  for (const ThreadPairs& t : threads)
    total += t.undecided.capacity() * sizeof(Undecided) +
             t.found.capacity() * sizeof(std::uint64_t) + t.found_mu2.capacity() * sizeof(double) +
             t.batch.size() * 15 * sizeof(double) + t.status.capacity() * sizeof(Status) +
             t.overlap.capacity() + t.mu2.capacity() * sizeof(double);
  for (const auto* lists : {&sort.keys, &sort.key_scratch})
    for (const auto& l : *lists) total += l.capacity() * sizeof(std::uint64_t);
  for (const auto* lists : {&sort.keyed, &sort.keyed_scratch})
    for (const auto& l : *lists) total += l.capacity() * sizeof(std::pair<std::uint64_t, double>);
  return total;
}

void ScreenWorkspace::release() {
  if (!impl_) return;
  // The flag a screen holds, taken for the release too: a screen running
  // refuses the release, and a screen asked for meanwhile is refused.
  if (impl_->busy.exchange(true))
    throw std::logic_error(
        "ScreenWorkspace::release: the workspace is in use by a screen (release it after)");
  impl_->cells = screen::CellListMemory();
  std::vector<ThreadPairs>().swap(impl_->threads);
  impl_->sort = SortMemory();
  impl_->held = 0;
  impl_->busy = false;
}

ScreenReport screen_pairs(const ParticleStore& particles, const Box& box,
                          const ScreenOptions& options, ScreenedPairs& out,
                          ScreenWorkspace& workspace) {
  if (!workspace.impl_) throw std::invalid_argument("screen_pairs: the workspace was moved from");
  ScreenWorkspace::Impl& kept = *workspace.impl_;
  if (kept.busy.exchange(true))
    throw std::logic_error(
        "screen_pairs: the workspace is in use by another call (one call at a time)");
  // On the way out, normal or by an exception: what the workspace now holds,
  // then the flag.
  struct Release {
    ScreenWorkspace::Impl& kept;
    ~Release() {
      kept.held = kept.capacity_bytes();
      kept.busy = false;
    }
  } release{kept};
  return screen_in(particles, box, options, out, &kept);
}

ScreenReport screen_candidates(const ParticleStore& particles, const Box& box,
                               const std::uint32_t* first, const std::uint32_t* second,
                               std::size_t count, const ScreenOptions& given, ScreenedPairs& out) {
  const ScreenOptions options = checked(particles, box, given);
  if (count > 0 && (!first || !second))
    throw std::invalid_argument("screen_candidates: null candidate arrays");
  const std::size_t n = particles.size();
  for (std::size_t k = 0; k < count; ++k)
    if (first[k] >= n || second[k] >= n || first[k] == second[k])
      throw std::invalid_argument("screen_candidates: candidate " + std::to_string(k) + " (" +
                                  std::to_string(first[k]) + ", " + std::to_string(second[k]) +
                                  ") is not a pair of two of the " + std::to_string(n) +
                                  " particles");
  ScreenReport report;
  report.particles = n;
  out = {};
  const int threads = detail::thread_count(options.threads, "screen_pairs");
  report.threads = threads;
  const double t1 = omp_get_wtime();
  const std::vector<double>& bounding = particles.bounding_radius();
  const std::vector<double>& inscribed = particles.inscribed_radius();
  const std::vector<double>& sphere = particles.sphere_radius();
  std::vector<ThreadPairs> per_thread(static_cast<std::size_t>(threads));
  const screen::BoxGeometry geometry(box);
  detail::ParallelErrors errors;
#pragma omp parallel num_threads(threads)
  {
    ThreadPairs& mine = per_thread[std::size_t(omp_get_thread_num())];
#pragma omp for schedule(static)
    for (std::size_t k = 0; k < count; ++k)
      errors.run([&] {
        const std::uint32_t i = first[k], j = second[k];
        // The centres wrapped into the box (as the cell lists do), then the
        // minimum image of their difference.
        const double xi[3] = {particles.centre(0)[i], particles.centre(1)[i],
                              particles.centre(2)[i]};
        const double xj[3] = {particles.centre(0)[j], particles.centre(1)[j],
                              particles.centre(2)[j]};
        double wi[3], wj[3], r[3];
        geometry.wrap(xi, wi);
        geometry.wrap(xj, wj);
        for (int a = 0; a < 3; ++a) r[a] = wj[a] - wi[a];
        geometry.minimum_image(r);
        const double rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        ++mine.candidates;
        if (apart_by_bounding_spheres(mine, options.cutoff, rr, bounding[i] + bounding[j])) return;
        double qi[6], qj[6];
        for (int a = 0; a < 6; ++a) {
          qi[a] = particles.q(a)[i];
          qj[a] = particles.q(a)[j];
        }
        classify_near_pair(mine, options, {i, bounding[i], inscribed[i], sphere[i], qi},
                           {j, bounding[j], inscribed[j], sphere[j], qj}, r, rr);
      });
    errors.run([&] { solve_waiting(mine, options); });
  }
  errors.rethrow_if_failed();
  finish(per_thread, options, threads, particles.size(), t1, report, out, nullptr);
  return report;
}

void for_each_candidate_pair(const ParticleStore& particles, const Box& box, double cutoff,
                             int threads,
                             const std::function<void(int thread, std::uint32_t i, std::uint32_t j,
                                                      const double r12[3])>& visit) {
  ScreenOptions given;
  given.cutoff = cutoff;
  given.threads = threads;
  const ScreenOptions options = checked(particles, box, given);
  threads = detail::thread_count(options.threads, "for_each_candidate_pair");
  const screen::CellLists lists = screen::build_cell_lists(particles, box, cutoff, threads);
  screen::search_candidates<false>(
      lists, threads, {},
      [&](int thread, const screen::Candidate& c) {
        if (c.i->index < c.j->index) {
          visit(thread, c.i->index, c.j->index, c.r);
        } else {
          const double r[3] = {-c.r[0], -c.r[1], -c.r[2]};
          visit(thread, c.j->index, c.i->index, r);
        }
      },
      [](int, std::size_t, std::size_t) {});
}

namespace {

// The pairs as screen_pairs gives them: of the particles, i < j, sorted by
// i then j, each once (the neighbour list's rows come sorted from that).
void check_pairs(const ScreenedPairs& pairs, std::size_t particles, const char* caller) {
  if (pairs.j.size() != pairs.i.size() ||
      (!pairs.mu2.empty() && pairs.mu2.size() != pairs.i.size()))
    throw std::invalid_argument(std::string(caller) + ": i, j and mu2 differ in length");
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const auto i = pairs.i[k], j = pairs.j[k];
    const char* wrong = nullptr;
    if (j >= particles)
      wrong = "is not of the particles";
    else if (i >= j)
      wrong = "has i >= j";
    else if (k > 0 && (i < pairs.i[k - 1] || (i == pairs.i[k - 1] && j <= pairs.j[k - 1])))
      wrong = "is out of order (the pairs must be sorted by i, then j, each once)";
    if (wrong)
      throw std::invalid_argument(std::string(caller) + ": pair " + std::to_string(k) + " (" +
                                  std::to_string(i) + ", " + std::to_string(j) + ") " + wrong +
                                  " of " + std::to_string(particles));
  }
}

}  // namespace

std::vector<std::uint32_t> pair_counts(const ScreenedPairs& pairs, std::size_t particles) {
  check_pairs(pairs, particles, "pair_counts");
  std::vector<std::uint32_t> counts(particles, 0);
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    ++counts[pairs.i[k]];
    ++counts[pairs.j[k]];
  }
  return counts;
}

NeighborList neighbor_list(const ScreenedPairs& pairs, std::size_t particles,
                           bool both_directions) {
  check_pairs(pairs, particles, "neighbor_list");
  NeighborList list;
  list.offsets.assign(particles + 1, 0);
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    ++list.offsets[pairs.i[k] + 1];
    if (both_directions) ++list.offsets[pairs.j[k] + 1];
  }
  for (std::size_t p = 0; p < particles; ++p) list.offsets[p + 1] += list.offsets[p];
  const bool with_mu2 = !pairs.mu2.empty();
  list.neighbors.resize(list.offsets.back());
  if (with_mu2) list.mu2.resize(list.offsets.back());
  std::vector<std::size_t> next(list.offsets.begin(), list.offsets.end() - 1);
  // In the pairs' order (i, then j), particle k receives i < k from the
  // pairs (i, k) before j > k from the pairs (k, j): each row comes sorted.
  auto append = [&](std::uint32_t to, std::uint32_t neighbor, std::size_t k) {
    const std::size_t at = next[to]++;
    list.neighbors[at] = neighbor;
    if (with_mu2) list.mu2[at] = pairs.mu2[k];
  };
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    append(pairs.i[k], pairs.j[k], k);
    if (both_directions) append(pairs.j[k], pairs.i[k], k);
  }
  return list;
}

}  // namespace pwcontact
