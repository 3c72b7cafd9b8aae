// The project's speed and accuracy targets on this machine (1 thread, ratios
// to brent_baseline measured in the same run), and how a run's measurements
// are judged against them.
#pragma once

#include <cstddef>
#include <ostream>
#include <vector>

#include "configuration.hpp"
#include "measurement.hpp"

namespace pwcontact::bench {

struct Target {
  // The path, family and accuracy the target is about, with default settings
  // and 1 thread (Isa::automatic stands for the run's default instruction set).
  Configuration configuration;
  // Full answers: the bound on the max relative error of mu^2. Overlap
  // answers are held to no misclassification beyond tangency_tolerance
  // instead, on the family and on its near-tangent set when measured.
  double max_rel_err;
  double min_speedup;  // over brent_baseline on the same family; 0: throughput reported only
};

const std::vector<Target>& targets();

// Thread scaling: `threads` threads against 1, default settings.
struct ThreadScalingTarget {
  Path path;
  Family family;
  int threads;
  double min_scaling;
};

const std::vector<ThreadScalingTarget>& thread_scaling_targets();

// The target's configuration on this run's default instruction set.
Configuration target_configuration(const Target& t, Isa default_isa);

// Whether `m` is as accurate as the target asks (not whether it is fast enough).
bool within_accuracy(const Target& t, const Measurement& m);

// The fastest measured configuration of the target's path, family and
// accuracy, with 1 thread on the default instruction set, that is within
// its accuracy; with `fixed_iterations_only`, among fixed iteration counts.
// Null when none is; `candidates`, when given, receives how many were measured.
const Measurement* fastest_within(const Table& table, const Target& t, Isa default_isa,
                                  bool fixed_iterations_only, std::size_t* candidates = nullptr);

// One line per target, "  met|NOT MET|-  <configuration>: <figures>", for the
// default settings; then the thread scaling targets.
void print_targets(std::ostream& out, const Table& table, Isa default_isa);

// One line per target for the fastest measured configuration within its
// accuracy, whatever its iteration count and formulation.
void print_targets_best_in_sweep(std::ostream& out, const Table& table, Isa default_isa);

}  // namespace pwcontact::bench
