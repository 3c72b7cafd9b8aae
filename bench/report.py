#!/usr/bin/python3
"""pwcontact's benchmark reports, from Google Benchmark's JSON output.

The benchmark programs (pwcontact_bench, pwcontact_trade) time and measure;
this script only reads what they wrote with
--benchmark_out=FILE --benchmark_out_format=json and reports it:

  report.py summary FILE.json
      the summary of a pwcontact_bench run: every configuration's figures,
      its ratio to brent_baseline, the thread scaling, the project's targets
      met or NOT MET, and the fastest fixed iteration counts;

  report.py trade FILE.json [--csv=PATH] [--markdown=PATH] [--plot=PATH | --no-plot]
      the speed/accuracy trade of a pwcontact_trade run: the trade table as
      CSV and Markdown (the targets, the best setting per family and
      precision, the overlap screening, every configuration), and a PNG plot
      of max relative error against throughput drawn by gnuplot.

Throughputs are the medians over the repetitions (Google Benchmark's
"_median" aggregate), or the one run without repetitions; every ratio is to
brent_baseline on the same family with 1 thread, in the same run. The
accuracy figures are the benchmarks' counters (bench/paths.hpp), computed in
C++ against the long double oracle. Standard library only: run it with
/usr/bin/python3 or any Python >= 3.9.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys

NAN = float("nan")

# ---------------------------------------------------------------------------
# Configurations (bench/configuration.hpp)

FULL_PATHS = ("batch_double", "batch_mixed", "batch_single", "batch_float")
OVERLAP_PATHS = ("overlap_double", "overlap_mixed", "overlap_single", "overlap_float")
SCALAR_PATHS = ("scalar_reference", "brent_baseline")
FAMILIES = ("random", "pw85", "extreme", "scene")


def is_scalar(path):
    return path in SCALAR_PATHS


def is_batch(path):
    return not is_scalar(path)


def is_overlap(path):
    return path in OVERLAP_PATHS


def precision_label(path):
    """The arithmetic of a path and, in float, whether the pairs were rounded before the call."""
    suffix = path.split("_")[-1]
    return {
        "mixed": "mixed",
        "single": "float, double pairs",
        "float": "float, float pairs",
    }.get(suffix, "double")


class Configuration:
    """One path solving one family with given settings, named as the benchmarks name it:
    <path>/<family>/isa:<isa>/iterations:<n>[/formulation:<f>][/accuracy:high]/threads:<t>
    for the batch paths, <path>/<family>/threads:1 for the scalar ones."""

    def __init__(self, path, family, isa="auto", iterations=0, threads=1,
                 formulation="auto", accuracy="standard"):
        self.path = path
        self.family = family
        self.isa = isa
        self.iterations = iterations
        self.threads = threads
        self.formulation = formulation
        self.accuracy = accuracy

    @staticmethod
    def parse(name):
        parts = name.split("/")
        if len(parts) < 2:
            raise ValueError("not a pwcontact configuration: " + name)
        c = Configuration(parts[0], parts[1])
        for part in parts[2:]:
            key, _, value = part.partition(":")
            if key in ("iterations", "threads"):
                setattr(c, key, int(value))
            elif key in ("isa", "formulation", "accuracy"):
                setattr(c, key, value)
            else:
                raise ValueError("not a pwcontact configuration: " + name)
        return c

    def settings_name(self):
        name = self.path + "/" + self.family
        if is_batch(self.path):
            name += "/isa:%s/iterations:%d" % (self.isa, self.iterations)
            if self.formulation != "auto":
                name += "/formulation:" + self.formulation
            if self.accuracy != "standard":
                name += "/accuracy:" + self.accuracy
        return name

    def name(self):
        return self.settings_name() + "/threads:%d" % self.threads

    def with_threads(self, threads):
        return Configuration(self.path, self.family, self.isa, self.iterations, threads,
                             self.formulation, self.accuracy)


# ---------------------------------------------------------------------------
# Measurements (bench/measurement.hpp)

# The counters every configuration reports besides its throughput (bench/measurement.hpp).
MAX_REL_ERR = "max_rel_err"
P999_REL_ERR = "p999_rel_err"
MEDIAN_REL_ERR = "median_rel_err"
MAX_REL_ERR_DOUBLE_INPUT = "max_rel_err_double_input"
FALLBACKS = "fallbacks"
FALLBACKS_PER_PAIR = "fallbacks_per_pair"
INVALID = "invalid"
MEAN_EVALUATIONS = "mean_evaluations"
DECIDED_EARLY_PER_PAIR = "decided_early_per_pair"
OVERLAPPING_PER_PAIR = "overlapping_per_pair"
MISCLASSIFIED_BEYOND = "misclassified_beyond"
MISCLASSIFIED_WITHIN = "misclassified_within"
NEAR_TANGENT_PAIRS = "near_tangent_pairs"
NEAR_TANGENT_MISCLASSIFIED_BEYOND = "near_tangent_misclassified_beyond"
NEAR_TANGENT_MISCLASSIFIED_WITHIN = "near_tangent_misclassified_within"
ITEMS_PER_SECOND = "items_per_second"  # pairs per second

COUNTERS = (MAX_REL_ERR, P999_REL_ERR, MEDIAN_REL_ERR, MAX_REL_ERR_DOUBLE_INPUT, FALLBACKS,
            FALLBACKS_PER_PAIR, INVALID, MEAN_EVALUATIONS, DECIDED_EARLY_PER_PAIR,
            OVERLAPPING_PER_PAIR, MISCLASSIFIED_BEYOND, MISCLASSIFIED_WITHIN, NEAR_TANGENT_PAIRS,
            NEAR_TANGENT_MISCLASSIFIED_BEYOND, NEAR_TANGENT_MISCLASSIFIED_WITHIN)

# Above this coefficient of variation over repetitions a ratio is flagged: on a
# shared machine a foreign process can take a core for whole seconds.
NOISY_CV = 0.10


class Measurement:
    """What one configuration measured: its throughput (the median over
    repetitions when there are several), the coefficient of variation and
    the fastest repetition (NaN when not reported), and its counters."""

    def __init__(self, configuration, pairs_per_second, cv, best, counters):
        self.configuration = configuration
        self.pairs_per_second = pairs_per_second
        self.pairs_per_second_cv = cv
        self.best_pairs_per_second = best
        self.counters = counters

    def counter(self, name):
        return self.counters.get(name, NAN)


def median(values):
    """The median as Google Benchmark computes its "_median" aggregate; NaN for none."""
    if not values:
        return NAN
    ordered = sorted(values)
    mid = len(ordered) // 2
    return ordered[mid] if len(ordered) % 2 else (ordered[mid - 1] + ordered[mid]) / 2


def cell(value, fmt="%.2e"):
    """A table cell: "-" for a figure that was not measured."""
    return "-" if math.isnan(value) else fmt % value


def misclassification_cell(m, near_tangent):
    """"beyond/within" misclassification counts on the family or its near-tangent set."""
    beyond = m.counter(NEAR_TANGENT_MISCLASSIFIED_BEYOND if near_tangent else MISCLASSIFIED_BEYOND)
    within = m.counter(NEAR_TANGENT_MISCLASSIFIED_WITHIN if near_tangent else MISCLASSIFIED_WITHIN)
    return "-" if math.isnan(beyond) else "%.0f/%.0f" % (beyond, within)


class Run:
    """A benchmark program's JSON output: its context and its measurements, in
    the order the program registered them."""

    def __init__(self, path):
        with open(path, encoding="utf-8") as f:
            data = json.load(f)  # (Google Benchmark writes NaN and Infinity, as json reads them)
        self.context = data.get("context", {})
        self.default_isa = self.context.get("pwcontact_default_isa", "auto")
        self.label = self.context.get("pwcontact_label", "")
        self.repetitions = 1
        records = {}
        for position, run in enumerate(data.get("benchmarks", [])):
            self._add(records, position, run)
        self.measurements = []
        for record in sorted(records.values(), key=lambda r: r["order"]):
            m = self._measurement(record)
            if m:
                self.measurements.append(m)
        self.table = Table(self.measurements)
        # The pairs of each generated family (random, extreme, scene) in this run: the
        # targets are for families of TARGET_GENERATED_PAIRS (smaller ones stay in cache).
        try:
            self.table.generated_pairs = int(self.context["pwcontact_generated_pairs"])
        except (KeyError, ValueError):
            self.table.generated_pairs = None

    def _add(self, records, position, run):
        if run.get("error_occurred"):
            return
        name = run.get("run_name", run.get("name", ""))
        if name.endswith("/real_time"):
            name = name[: -len("/real_time")]
        try:
            configuration = Configuration.parse(name)
        except ValueError:
            return  # not one of pwcontact's configurations
        record = records.setdefault(name, {
            "configuration": configuration,
            # Registration order; with random interleaving the runs come shuffled.
            "order": (run.get("family_index", position), position),
            "rates": [], "median": NAN, "cv": NAN, "counters": {},
        })
        rate = float(run.get(ITEMS_PER_SECOND, NAN))
        # Of the aggregates, the median gives the throughput (robust on a noisy
        # machine) and the coefficient of variation says how noisy it was. The
        # iteration runs may be absent (--benchmark_report_aggregates_only).
        if run.get("run_type") == "aggregate":
            if run.get("aggregate_name") == "cv":
                record["cv"] = rate
            if run.get("aggregate_name") != "median":
                return
            record["median"] = rate
        else:
            record["rates"].append(rate)
        self.repetitions = max(self.repetitions, int(run.get("repetitions", 1)))
        for counter in COUNTERS:
            if counter in run:
                record["counters"][counter] = float(run[counter])

    @staticmethod
    def _measurement(record):
        rate = record["median"] if not math.isnan(record["median"]) else median(record["rates"])
        if math.isnan(rate):
            return None
        best = max(record["rates"]) if record["rates"] else NAN
        counters = dict(record["counters"])
        counters[ITEMS_PER_SECOND] = rate
        return Measurement(record["configuration"], rate, record["cv"], best, counters)

    def context_list(self, key, convert=str):
        text = self.context.get(key, "")
        return [convert(item) for item in text.split(",") if item]


class Table:
    """The measurements of one run, looked up by configuration."""

    def __init__(self, rows):
        self.rows = rows
        self.by_name = {}
        for m in rows:
            self.by_name.setdefault(m.configuration.name(), m)

    def find(self, configuration):
        return self.by_name.get(configuration.name())

    def brent_baseline(self, family):
        return self.find(Configuration("brent_baseline", family))

    def brent_rate(self, family):
        brent = self.brent_baseline(family)
        return brent.pairs_per_second if brent else NAN

    def speedup(self, m):
        """Throughput as a multiple of brent_baseline's on the same family."""
        return m.pairs_per_second / self.brent_rate(m.configuration.family)

    def thread_scaling(self, one_thread, threads, best=False):
        """Throughput with `threads` threads over the same configuration with 1."""
        one = self.find(one_thread)
        more = self.find(one_thread.with_threads(threads))
        if not one or not more:
            return NAN
        if best:
            return more.best_pairs_per_second / one.best_pairs_per_second
        return more.pairs_per_second / one.pairs_per_second

    def best_scaling_note(self, one_thread, threads):
        """"; best repetitions d.ef": tells foreign load on the machine apart from poor scaling."""
        best = self.thread_scaling(one_thread, threads, best=True)
        return "" if math.isnan(best) else "; best repetitions %.2f" % best

    @staticmethod
    def noise_note(behind_ratio):
        """"; noisy: cv N%" when a throughput behind a ratio varied a lot between repetitions."""
        worst = 0.0
        for m in behind_ratio:
            if m and m.pairs_per_second_cv > worst:
                worst = m.pairs_per_second_cv
        return "; noisy: cv up to %.0f%%, rerun" % (100 * worst) if worst > NOISY_CV else ""


def divide(a, b):
    """a / b as C++ computes it: NaN for NaN, +-inf for a nonzero a over 0."""
    try:
        return a / b
    except ZeroDivisionError:
        return NAN if a == 0 or math.isnan(a) else math.copysign(math.inf, a)


# ---------------------------------------------------------------------------
# Targets (the project's speed and accuracy targets on this machine, 1 thread)

class Target:
    """A path, family and accuracy with default settings and 1 thread (isa "auto" stands for
    the run's default instruction set). Full answers: the bound on the max relative error of
    mu^2; overlap answers are held to no misclassification beyond 1e-9 of tangency instead, on
    the family and on its near-tangent set (a run without either has no verdict). min_speedup:
    over brent_baseline on the same family; 0: throughput reported only."""

    def __init__(self, configuration, max_rel_err, min_speedup):
        self.configuration = configuration
        self.max_rel_err = max_rel_err
        self.min_speedup = min_speedup


def defaults(path, family, accuracy="standard"):
    return Configuration(path, family, accuracy=accuracy)


TARGETS = (
    Target(defaults("batch_double", "pw85"), 2e-11, 20),
    Target(defaults("batch_float", "random"), 1e-5, 80),
    Target(defaults("batch_mixed", "random"), 1e-13, 40),
    Target(defaults("overlap_double", "scene"), 0, 100),
    # The accurate mode must beat the double floor (~1.1e-11 on pw85).
    Target(defaults("batch_double", "pw85", "high"), 1e-13, 0),
    # Kept from before the mixed and overlap paths existed.
    Target(defaults("batch_double", "random"), 1e-13, 30),
    Target(defaults("batch_float", "random"), 1e-5, 60),
    # Faster where the library was weakest: full answers in double, and float
    # overlap answers on elongated shapes (~3x HOOMD-blue's test there).
    Target(defaults("batch_double", "random"), 1e-13, 60),
    Target(defaults("batch_double", "pw85"), 2e-11, 40),
    Target(defaults("overlap_float", "pw85"), 0, 55),
)

# Thread scaling: (path, family, threads, min_scaling) against 1 thread, default settings.
THREAD_SCALING_TARGETS = (
    ("batch_double", "random", 2, 1.8),
    ("batch_float", "random", 2, 1.8),
)


def target_configuration(configuration, default_isa):
    """The target's configuration on this run's default instruction set."""
    c = configuration.with_threads(configuration.threads)  # a copy
    if c.isa == "auto":
        c.isa = default_isa
    return c


def within_accuracy(t, m):
    """Whether `m` is as accurate as the target asks (not whether it is fast enough)."""
    if not is_overlap(t.configuration.path):
        return m.counter(MAX_REL_ERR) <= t.max_rel_err  # False for NaN
    # NaN (not measured) compares false: only a measured zero is within, on the family and
    # on its near-tangent set.
    return (m.counter(MISCLASSIFIED_BEYOND) == 0
            and m.counter(NEAR_TANGENT_MISCLASSIFIED_BEYOND) == 0)


def accuracy_measured(t, m):
    """Whether `m` has every figure its target's accuracy is judged by."""
    if not is_overlap(t.configuration.path):
        return not math.isnan(m.counter(MAX_REL_ERR))
    return not (math.isnan(m.counter(MISCLASSIFIED_BEYOND))
                or math.isnan(m.counter(NEAR_TANGENT_MISCLASSIFIED_BEYOND)))


# The size of the generated families the targets are set on (the benchmarks' default).
TARGET_GENERATED_PAIRS = 1 << 20


def off_size_note(t, table):
    """Why a run's figures do not decide the target: its generated family is another size
    than the target's (pw85 is one fixed family)."""
    n = getattr(table, "generated_pairs", None)
    if t.configuration.family == "pw85" or n is None or n == TARGET_GENERATED_PAIRS:
        return ""
    return "; on %d pairs, the target is for %d: no verdict" % (n, TARGET_GENERATED_PAIRS)


def fastest_within(table, t, default_isa, fixed_iterations_only):
    """The fastest measured configuration of the target's path, family and accuracy, with 1
    thread on the default instruction set, that is within its accuracy (with
    `fixed_iterations_only`, among fixed iteration counts); and how many were measured with
    every figure the target's accuracy is judged by (the others are left out)."""
    wanted = target_configuration(t.configuration, default_isa)
    best, considered = None, 0
    for m in table.rows:
        c = m.configuration
        if (c.path != wanted.path or c.family != wanted.family or c.accuracy != wanted.accuracy
                or c.isa != wanted.isa or c.threads != 1
                or (fixed_iterations_only and c.iterations == 0)
                or not accuracy_measured(t, m)):
            continue
        considered += 1
        if not within_accuracy(t, m):
            continue
        if not best or m.pairs_per_second > best.pairs_per_second:
            best = m
    return best, considered


def verdict(met):
    return "met" if met else "NOT MET"


def speedup_text(speedup):
    return "brent_baseline not measured" if math.isnan(speedup) else "%.1fx brent_baseline" % speedup


def misclassification_text(m, beyond, within):
    b, w = m.counter(beyond), m.counter(within)
    return "-" if math.isnan(b) else "%.0f beyond (%.0f within)" % (b, w)


def accuracy_text(t, m):
    if is_overlap(t.configuration.path):
        return ("misclassified %s 1e-9 of tangency on the family, %s on %.0f near-tangent pairs "
                "(target: none beyond)" % (
                    misclassification_text(m, MISCLASSIFIED_BEYOND, MISCLASSIFIED_WITHIN),
                    misclassification_text(m, NEAR_TANGENT_MISCLASSIFIED_BEYOND,
                                           NEAR_TANGENT_MISCLASSIFIED_WITHIN),
                    m.counter(NEAR_TANGENT_PAIRS)))
    text = "max rel err %.2e (target <= %g)" % (m.counter(MAX_REL_ERR), t.max_rel_err)
    error_double_input = m.counter(MAX_REL_ERR_DOUBLE_INPUT)
    if not math.isnan(error_double_input):
        text += "; %.2e against the double inputs" % error_double_input
    return text


def target_line(t, table, m):
    """"  met      <name>: <speed>, <accuracy>[; noise]" for one measurement."""
    speed_target = t.min_speedup > 0
    speedup = table.speedup(m)
    met = within_accuracy(t, m) and (not speed_target or speedup >= t.min_speedup)
    off_size = off_size_note(t, table)
    decided = ((not speed_target or not math.isnan(speedup)) and accuracy_measured(t, m)
               and not off_size)
    line = "  %-8s %s: " % (verdict(met) if decided else "-", m.configuration.name())
    if speed_target:
        line += "%s (target >= %gx), " % (speedup_text(speedup), t.min_speedup)
    else:
        line += "%.3g pairs/s = %s, " % (m.pairs_per_second, speedup_text(speedup))
    line += accuracy_text(t, m)
    if not speed_target:
        line += "; %.3g fallbacks per pair" % m.counter(FALLBACKS_PER_PAIR)
    line += off_size
    return line + Table.noise_note([m, table.brent_baseline(t.configuration.family)])


def print_targets(out, table, default_isa):
    """One line per target for the default settings; then the thread scaling targets."""
    for t in TARGETS:
        c = target_configuration(t.configuration, default_isa)
        m = table.find(c)
        if m:
            out.write(target_line(t, table, m) + "\n")
        else:
            out.write("  %-8s %s: not measured\n" % ("-", c.name()))
    for path, family, threads, min_scaling in THREAD_SCALING_TARGETS:
        c = target_configuration(defaults(path, family), default_isa)
        scaling = table.thread_scaling(c, threads)
        off_size = off_size_note(Target(c, 0, 0), table)
        out.write("  %-8s %s: threads:%d / threads:1 = %s (target >= %g)" % (
            "-" if math.isnan(scaling) or off_size else verdict(scaling >= min_scaling),
            c.name(), threads, cell(scaling, "%.2f"), min_scaling))
        out.write(table.best_scaling_note(c, threads) + off_size +
                  Table.noise_note([table.find(c), table.find(c.with_threads(threads))]) + "\n")


def print_targets_best_in_sweep(out, table, default_isa):
    """One line per target for the fastest measured configuration within its accuracy,
    whatever its iteration count and formulation."""
    for t in TARGETS:
        m, candidates = fastest_within(table, t, default_isa, False)
        if m:
            out.write(target_line(t, table, m) + "\n")
            continue
        off_size = off_size_note(t, table)
        out.write("  %-8s %s: %s%s\n" % (
            "NOT MET" if candidates and not off_size else "-",
            target_configuration(t.configuration, default_isa).name(),
            "no measured setting is within the accuracy" if candidates else "not measured",
            off_size if candidates else ""))


# ---------------------------------------------------------------------------
# The summary of a pwcontact_bench run

def print_table(out, table):
    width = max([13] + [len(m.configuration.name()) for m in table.rows])
    row = "%-*s %10s %6s %8s %10s %10s %10s %13s %10s %10s %8s %10s %10s\n"
    out.write(row % (width, "configuration", "pairs/s", "cv", "x brent", "max err", "p99.9 err",
                     "median err", "max err (dbl)", "fallb/pair", "evals/pair", "invalid",
                     "misclass.", "near-tang."))
    for m in table.rows:
        out.write(row % (
            width, m.configuration.name(), cell(m.pairs_per_second, "%.3g"),
            cell(100 * m.pairs_per_second_cv, "%.0f%%"), cell(table.speedup(m), "%.2f"),
            cell(m.counter(MAX_REL_ERR)), cell(m.counter(P999_REL_ERR)),
            cell(m.counter(MEDIAN_REL_ERR)), cell(m.counter(MAX_REL_ERR_DOUBLE_INPUT)),
            cell(m.counter(FALLBACKS_PER_PAIR), "%.3g"), cell(m.counter(MEAN_EVALUATIONS), "%.2f"),
            cell(m.counter(INVALID), "%.0f"), misclassification_cell(m, False),
            misclassification_cell(m, True)))


def print_thread_scaling(out, table):
    printed = 0
    for m in table.rows:
        c = m.configuration
        if not is_batch(c.path) or c.threads == 1 or not table.find(c.with_threads(1)):
            continue
        one_thread = c.with_threads(1)
        out.write("  %-60s threads:%d / threads:1 = %.2f%s\n" % (
            one_thread.name(), c.threads, table.thread_scaling(one_thread, c.threads),
            table.best_scaling_note(one_thread, c.threads)))
        printed += 1
    if printed == 0:
        out.write("  not measured\n")


def print_iteration_choice(out, table, default_isa):
    """Which fixed iteration count gives the most pairs per second while staying within each
    target's accuracy, on the default instruction set, 1 thread."""
    for t in TARGETS:
        default_settings = target_configuration(t.configuration, default_isa)
        line = "  %s: " % default_settings.name()
        best, candidates = fastest_within(table, t, default_isa, True)
        if not best:
            out.write(line + ("no measured fixed iteration count is within the accuracy\n"
                              if candidates else "no fixed iteration count measured\n"))
            continue
        line += ("fastest iterations:%d, %.3g pairs/s = %sx brent_baseline, "
                 "%.3g fallbacks per pair" % (
                     best.configuration.iterations, best.pairs_per_second,
                     cell(table.speedup(best), "%.1f"), best.counter(FALLBACKS_PER_PAIR)))
        d = table.find(default_settings)
        if d:
            line += "; default (automatic) %.3g pairs/s, fastest / default = %.2f" % (
                d.pairs_per_second, divide(best.pairs_per_second, d.pairs_per_second))
        out.write(line + "\n")


def print_summary(out, run):
    table, isa = run.table, run.default_isa
    out.write(
        "\nSummary (%s; real time; errors: relative error of mu^2 against the long double "
        "oracle on the inputs each path solved, \"dbl\" against the double inputs)\n" % (
            "medians of %d repetitions" % run.repetitions if run.repetitions > 1
            else "single runs, no repetitions"))
    out.write(
        "(misclass.: overlap answers on the family that disagree with the oracle's mu^2 < 1, "
        "farther from tangency than |mu^2 - 1| = 1e-9 / closer; near-tang.: the same for "
        "overlap answers or mu^2 < 1 of full answers on the family's near-tangent set.)\n"
        "(Google Benchmark prints small counters with SI prefixes: m 1e-3, u 1e-6, n 1e-9, "
        "p 1e-12, f 1e-15, a 1e-18, z 1e-21.)\n\n")
    print_table(out, table)
    out.write("\nThread scaling (same configuration, more threads / 1 thread)\n")
    print_thread_scaling(out, table)
    out.write("\nTargets (1 thread; default settings are isa:auto = isa:%s and iterations:0 = "
              "automatic)\n" % isa)
    print_targets(out, table, isa)
    out.write("\nFixed iteration counts swept on isa:%s, 1 thread\n" % isa)
    print_iteration_choice(out, table, isa)


# ---------------------------------------------------------------------------
# The trade of a pwcontact_trade run

# best_in_group: settings whose max error is within this factor of the lowest
# a precision reached count as equally accurate (one decade: the same level
# on the plot, e.g. 3e-6 and 7e-7 in float, 1e-11 and 9e-12 on pw85 in double).
BEST_ACCURACY_FACTOR = 10


class PrecisionGroup:
    """One precision of the full answer, as the plot and the best-setting table group
    configurations: a full batch path with an accuracy."""

    def __init__(self, path, accuracy):
        self.path = path
        self.accuracy = accuracy

    def label(self):
        label = precision_label(self.path)
        if self.accuracy == "high":
            label += ", accuracy high"
        return label


# In a fixed order: the plot's colours follow it.
PRECISION_GROUPS = (
    PrecisionGroup("batch_double", "standard"), PrecisionGroup("batch_double", "high"),
    PrecisionGroup("batch_mixed", "standard"), PrecisionGroup("batch_mixed", "high"),
    PrecisionGroup("batch_single", "standard"), PrecisionGroup("batch_float", "standard"),
)

FAMILY_DESCRIPTIONS = {
    "random": "semi-axes uniform in [0.5, 2], centre distance uniform in [0, 6]",
    "pw85": "the peer library's 419,904 cases, aspect ratios up to 500",
    "extreme": "semi-axes log-uniform in [0.03, 30] (aspect and size ratios up to 1e3), centre "
               "distance uniform in [0, 60]",
    "scene": "random family's shapes, centre distance scaled so that mu is uniform in [0.5, 1.5]",
}


class Trade:
    """A trade run: its measurements, and how they were taken (for the headers)."""

    def __init__(self, run, label):
        self.run = run
        self.table = run.table
        self.isa = run.default_isa
        self.label = label
        self.threads = run.context_list("pwcontact_threads", int) or sorted(
            {m.configuration.threads for m in run.measurements})
        self.families = run.context_list("pwcontact_families") or [
            f for f in FAMILIES if any(m.configuration.family == f for m in run.measurements)]

    def description(self):
        threads = ", ".join(str(t) for t in self.threads)
        context = self.run.context
        return ("isa %s; medians of %d repetitions of at least %.3g s of calls each, %s "
                "thread(s); %s pairs per generated family, %s per near-tangent set" % (
                    self.isa, self.run.repetitions,
                    float(context.get("pwcontact_min_time", "nan")), threads,
                    context.get("pwcontact_generated_pairs", "?"),
                    context.get("pwcontact_near_tangent_pairs", "?")))

    def one_thread_rows(self):
        """One row per configuration, with 1 thread (the other thread counts are looked up
        beside them), in registration order."""
        return [m for m in self.table.rows if m.configuration.threads == 1]

    def rate_with(self, one_thread, threads):
        m = self.table.find(one_thread.configuration.with_threads(threads))
        return m.pairs_per_second if m else NAN

    def group_rows(self, family, group):
        return [m for m in self.table.rows
                if m.configuration.family == family and m.configuration.path == group.path
                and m.configuration.accuracy == group.accuracy and m.configuration.threads == 1
                and not math.isnan(m.counter(MAX_REL_ERR))]

    def best_in_group(self, family, group):
        """The fastest 1-thread configuration of `group` on `family` whose max relative error
        is within BEST_ACCURACY_FACTOR of the lowest the group reached there."""
        rows = self.group_rows(family, group)
        lowest = min([math.inf] + [m.counter(MAX_REL_ERR) for m in rows])
        best = None
        for m in rows:
            if (m.counter(MAX_REL_ERR) <= BEST_ACCURACY_FACTOR * lowest
                    and (not best or m.pairs_per_second > best.pairs_per_second)):
                best = m
        return best

    def automatic_in_group(self, family, group):
        """The group's configuration with automatic iterations and formulation: the
        library's defaults."""
        for m in self.group_rows(family, group):
            if m.configuration.iterations == 0 and m.configuration.formulation == "auto":
                return m
        return None


def print_best_settings(out, trade):
    for family in trade.families:
        for group in PRECISION_GROUPS:
            best = trade.best_in_group(family, group)
            if not best:
                continue
            out.write("  %-8s %-26s %-72s %9.3g pairs/s %6.1fx brent  max err %.2e\n" % (
                family, group.label(), best.configuration.settings_name(),
                best.pairs_per_second, trade.table.speedup(best), best.counter(MAX_REL_ERR)))


def csv_number(value, fmt="%.6g"):
    """A CSV field: numbers as they are, NaN as an empty field."""
    return "" if math.isnan(value) else fmt % value


def csv_text(text):
    """A CSV text field, quoted when it holds a comma or a quote (RFC 4180)."""
    if "," not in text and '"' not in text:
        return text
    return '"' + text.replace('"', '""') + '"'


CSV_COUNTERS = (MAX_REL_ERR, P999_REL_ERR, MEDIAN_REL_ERR, MAX_REL_ERR_DOUBLE_INPUT,
                FALLBACKS_PER_PAIR, MEAN_EVALUATIONS, DECIDED_EARLY_PER_PAIR,
                OVERLAPPING_PER_PAIR, MISCLASSIFIED_BEYOND, MISCLASSIFIED_WITHIN,
                NEAR_TANGENT_PAIRS, NEAR_TANGENT_MISCLASSIFIED_BEYOND,
                NEAR_TANGENT_MISCLASSIFIED_WITHIN, INVALID)


def answer_name(path):
    if is_scalar(path):
        return "scalar"
    return "overlap" if is_overlap(path) else "full"


def write_csv(path, trade):
    table = trade.table
    lines = []
    header = "configuration,path,family,answer,precision,formulation,accuracy,iterations"
    for t in trade.threads:
        header += ",pairs_per_second_%d_threads,cv_%d_threads,x_brent_%d_threads" % (t, t, t)
    lines.append(header + "".join("," + name for name in CSV_COUNTERS))
    for m in trade.one_thread_rows():
        c = m.configuration
        batch = is_batch(c.path)
        fields = [c.settings_name(), c.path, c.family, answer_name(c.path),
                  csv_text(precision_label(c.path) if batch else "double"),
                  c.formulation if batch else "", c.accuracy if batch else "",
                  str(c.iterations) if batch else ""]
        brent = table.brent_rate(c.family)
        for t in trade.threads:
            timed = table.find(c.with_threads(t))
            rate = timed.pairs_per_second if timed else NAN
            fields += [csv_number(rate),
                       csv_number(timed.pairs_per_second_cv if timed else NAN, "%.3f"),
                       csv_number(rate / brent, "%.3f")]
        fields += [csv_number(m.counter(name)) for name in CSV_COUNTERS]
        lines.append(",".join(fields))
    write_text(path, "\n".join(lines) + "\n")


def md_rate(rate):
    return cell(rate, "%.3g")


def md_ratio(ratio):
    return cell(ratio, "%.1f")


def speed_cells(m, brent):
    """"pairs/s | × brent" cells of a measurement; dashes without one."""
    if not m:
        return "- | -"
    return md_rate(m.pairs_per_second) + " | " + md_ratio(m.pairs_per_second / brent)


def counter_cell(m, name, fmt="%.2e"):
    return cell(m.counter(name) if m else NAN, fmt)


def markdown_family_table(out, trade, family):
    table = trade.table
    out.append("\n### %s family\n\n%s.\n\n" % (family, FAMILY_DESCRIPTIONS.get(family, "")))
    header = "| configuration |"
    for t in trade.threads:
        header += " pairs/s, %d thr | × brent |" % t
    header += (" max err | p99.9 err | median err | max err, dbl inputs | fallbacks/pair | "
               "evals/pair | decided early | misclassified >1e-9/≤1e-9 | "
               "near-tangent >1e-9/≤1e-9 |\n|---|")
    header += "---:|---:|" * len(trade.threads)
    out.append(header + "---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    brent = table.brent_rate(family)
    for m in trade.one_thread_rows():
        if m.configuration.family != family:
            continue
        line = "| `%s` |" % m.configuration.settings_name()
        for t in trade.threads:
            rate = trade.rate_with(m, t)
            line += " %s | %s |" % (md_rate(rate), md_ratio(rate / brent))
        line += " %s |\n" % " | ".join([
            cell(m.counter(MAX_REL_ERR)), cell(m.counter(P999_REL_ERR)),
            cell(m.counter(MEDIAN_REL_ERR)), cell(m.counter(MAX_REL_ERR_DOUBLE_INPUT)),
            cell(m.counter(FALLBACKS_PER_PAIR), "%.3g"), cell(m.counter(MEAN_EVALUATIONS), "%.2f"),
            cell(m.counter(DECIDED_EARLY_PER_PAIR), "%.3f"), misclassification_cell(m, False),
            misclassification_cell(m, True)])
        out.append(line)


def markdown_best_settings(out, trade):
    out.append("| family | precision | best setting | pairs/s | × brent | max err | p99.9 err | "
               "near-tangent >1e-9/≤1e-9 | defaults: pairs/s | × brent | max err |\n"
               "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    for family in trade.families:
        for group in PRECISION_GROUPS:
            best = trade.best_in_group(family, group)
            if not best:
                continue
            automatic = trade.automatic_in_group(family, group)
            brent = trade.table.brent_rate(family)
            out.append("| %s | %s | `%s` | %s | %s | %s | %s | %s | %s |\n" % (
                family, group.label(), best.configuration.settings_name(),
                speed_cells(best, brent), counter_cell(best, MAX_REL_ERR),
                counter_cell(best, P999_REL_ERR), misclassification_cell(best, True),
                speed_cells(automatic, brent), counter_cell(automatic, MAX_REL_ERR)))


def markdown_overlap_screening(out, trade):
    """The fastest overlap configuration per family and precision that makes no
    misclassification beyond 1e-9 of tangency, on the family nor on its near-tangent set."""
    out.append("| family | path | fastest without misclassification beyond 1e-9 | pairs/s | "
               "× brent | decided early | evals/pair | near-tangent >1e-9/≤1e-9 | "
               "defaults: pairs/s | × brent |\n"
               "|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n")
    for family in trade.families:
        for path in OVERLAP_PATHS:
            screening = Target(Configuration(path, family, trade.isa), 0, 0)
            best, _ = fastest_within(trade.table, screening, trade.isa, False)
            automatic = trade.table.find(screening.configuration)
            if not best and not automatic:
                continue
            brent = trade.table.brent_rate(family)
            out.append("| %s | %s | %s | %s | %s | %s | %s | %s |\n" % (
                family, path, "`%s`" % best.configuration.settings_name() if best else "none",
                speed_cells(best, brent), counter_cell(best, DECIDED_EARLY_PER_PAIR, "%.3f"),
                counter_cell(best, MEAN_EVALUATIONS, "%.2f"),
                misclassification_cell(best, True) if best else "-",
                speed_cells(automatic, brent)))


class Lines(list):
    """Collects text as the print_* functions write it."""

    def write(self, text):
        self.append(text)


def write_markdown(path, trade):
    out = Lines()
    out.append("# pwcontact: the speed/accuracy trade\n\n")
    if trade.label:
        out.append("Measured: %s.\n\n" % trade.label)
    out.append(trade.description() + ".\n\n")
    out.append(
        "Throughput in pairs per second (real time); × brent: over brent_baseline's on the same "
        "family with 1 thread, measured in the same run. Errors: relative error of μ² against "
        "the long double oracle on the inputs each path solved (float pairs: the float-rounded "
        "ones; \"dbl inputs\": against the double pairs). Misclassified: answers to \"μ < 1?\" "
        "(overlap answers, or μ² < 1 of full answers) that disagree with the oracle, farther "
        "from tangency than |μ² − 1| = 1e-9 (errors) / closer (tolerated), on the family "
        "(overlap answers) and on the family's near-tangent set (μ² = 1 ± ε, ε log-uniform in "
        "[1e-12, 1e-2]). Full answers ask for μ², λ and the status; overlap answers for the "
        "answer and the status.\n")
    out.append("\n## Targets: the fastest measured setting within each target's accuracy\n\n"
               "```text\n")
    print_targets_best_in_sweep(out, trade.table, trade.isa)
    out.append("```\n\n## Targets: the library's default settings\n\n```text\n")
    print_targets(out, trade.table, trade.isa)
    out.append("```\n\n## Best setting per family and precision (full answer, 1 thread)\n\n")
    out.append("The fastest setting whose max error is within a factor %g of the lowest that "
               "precision reached on the family; defaults: automatic iterations and "
               "formulation.\n\n" % BEST_ACCURACY_FACTOR)
    markdown_best_settings(out, trade)
    out.append("\n## Overlap screening (1 thread)\n\n")
    markdown_overlap_screening(out, trade)
    out.append("\n## Every configuration\n")
    for family in trade.families:
        markdown_family_table(out, trade, family)
    write_text(path, "".join(out))


# ---------------------------------------------------------------------------
# The plot (gnuplot)

# Errors are plotted on a log scale: exact answers (0) are drawn at this
# floor, and an error above the ceiling (or a NaN answer, infinite error) at
# the top.
PLOT_ERROR_FLOOR = 1e-17
PLOT_ERROR_CEILING = 1e-2

GROUP_COLOURS = ("#1f77b4", "#6baed6", "#2ca02c", "#98df8a", "#ff7f0e", "#d62728")

PANEL_TITLES = {
    "random": "random family: semi-axes in [0.5, 2]",
    "pw85": "pw85 family: 419,904 cases, aspect ratios up to 500",
    "extreme": "extreme family: semi-axes log-uniform in [0.03, 30]",
    "scene": "scene-like mix: mu uniform in [0.5, 1.5]",
}


def plotted_error(error):
    if math.isnan(error):
        return PLOT_ERROR_CEILING
    return min(max(error, PLOT_ERROR_FLOOR), PLOT_ERROR_CEILING)


def point_type(c):
    """Filled for automatic iterations, open for fixed; circles for Newton (and the automatic
    formulation), triangles for log_odds."""
    automatic = c.iterations == 0
    if c.formulation == "log_odds":
        return 9 if automatic else 8
    return 7 if automatic else 6


def pareto_front(rows):
    """The group's points that no other point beats in both speed and error, by increasing
    throughput: the curve through the trade."""
    front, lowest = [], math.inf
    for m in sorted(rows, key=lambda m: -m.pairs_per_second):
        error = plotted_error(m.counter(MAX_REL_ERR))
        if error < lowest:
            front.append(m)
            lowest = error
    return front[::-1]


def data_block(rows):
    """One "x y" (and point type) line per measurement, as a gnuplot data block."""
    text = "".join("%.6g %.6g %d  # %s\n" % (
        m.pairs_per_second, plotted_error(m.counter(MAX_REL_ERR)), point_type(m.configuration),
        m.configuration.settings_name()) for m in rows)
    return text + "\n\n"  # gnuplot: the next index


def gp_quoted(text):
    """A single-quoted gnuplot string: a quote inside is doubled."""
    return "'" + text.replace("'", "''") + "'"


def gp_text(text):
    """A double-quoted gnuplot string, where "\\n" starts a new line."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return '"' + escaped + '"'


def target_corners(trade, family):
    """The targets on `family` drawn as corners: a configuration meets a target when its point
    lies below and right of the corner. Their labels sit at the right end of the horizontal
    lines, stacked where error bounds coincide."""
    brent = trade.table.brent_rate(family)
    labels_at = {}  # labels already placed at each error bound
    gp = ""
    for t in TARGETS:
        c = t.configuration
        if c.family != family or is_overlap(c.path):
            continue
        group = PrecisionGroup(c.path, c.accuracy)
        y = t.max_rel_err
        speed = t.min_speedup > 0 and not math.isnan(brent)
        x = t.min_speedup * brent if speed else 0
        style = "nohead dt %d lw 1.5 lc rgb '#555555'" % (2 if speed else 3)
        start = "first %g, first %g" % (x, y) if speed else "graph 0, first %g" % y
        gp += "set arrow from " + start + " to graph 1, first %g " % y + style + "\n"
        if speed:
            gp += "set arrow from first %g, graph 0 to first %g, first %g " % (x, x, y) + style
            gp += "\nset label '%gx' at first %g, graph 0.02 rotate by 90 offset -0.3,0 " \
                  "font ',8'\n" % (t.min_speedup, x)
        if speed:
            text = "target: %s >= %gx brent, <= %g" % (group.label(), t.min_speedup, y)
        else:
            text = "target: %s <= %g (speed reported)" % (group.label(), y)
        stacked = labels_at.get(y, 0)
        labels_at[y] = stacked + 1
        gp += "set label \"%s\" at graph 0.99, first %g right offset 0,%.1f font ',8' " \
              "noenhanced\n" % (text, y, 0.6 + 1.1 * stacked)
    return gp


def plot_script(png, work_files, trade):
    """The gnuplot script that draws `png`, and its data files by name."""
    points_path = work_files + "_points.dat"
    fronts_path = work_files + "_fronts.dat"
    brent_path = work_files + "_brent.dat"
    panels = [f for f in trade.families if f != "scene"]  # the scene is for overlap answers
    if not panels:
        raise ReportError("no family to plot (the scene has no full sweep)")
    title = ("pwcontact: max relative error of mu^2 against throughput (1 thread, full answer)" +
             (" - " + trade.label if trade.label else "") +
             "\npoints: every configuration; lines: the fastest at each accuracy")
    gp = ("# Drawn by bench/report.py: max relative error of mu^2 against throughput.\n"
          "set terminal pngcairo size %d,780 font 'sans,10'\n" % (660 * len(panels)) +
          "set output " + gp_quoted(png) + "\n" +
          "set multiplot layout 1,%d title %s noenhanced\n" % (len(panels), gp_text(title)) +
          "set logscale xy\nset format x '10^{%L}'\nset format y '10^{%L}'\n" +
          "set yrange [%g:%g]\n" % (PLOT_ERROR_FLOOR, PLOT_ERROR_CEILING) +
          "set xlabel 'pairs per second, 1 thread'\nset ylabel 'max relative error of mu^2'\n"
          "set grid\nset key below maxrows 5 font ',9' noenhanced\n"
          # Room on both sides: brent_baseline and the fastest points are at the ends.
          "set offsets graph 0.05, graph 0.05, 0, 0\n")
    points = fronts = brent_data = ""
    block = brent_block = 0
    for family in panels:
        gp += "unset arrow\nunset label\n"
        gp += "set title " + gp_quoted(PANEL_TITLES.get(family, family)) + " noenhanced font ',9'\n"
        gp += target_corners(trade, family)
        clauses = []
        for colour, group in zip(GROUP_COLOURS, PRECISION_GROUPS):
            rows = trade.group_rows(family, group)
            if not rows:
                continue
            points += data_block(rows)
            fronts += data_block(pareto_front(rows))
            clauses.append("%s index %d using 1:2 with lines lw 2 lc rgb '%s' title %s" % (
                gp_quoted(fronts_path), block, colour, gp_quoted(group.label())))
            clauses.append(
                "%s index %d using 1:2:3 with points pt variable ps 1.1 lc rgb '%s' notitle" % (
                    gp_quoted(points_path), block, colour))
            block += 1
        b = trade.table.brent_baseline(family)
        if b:
            brent_data += "%.6g %.6g\n\n\n" % (b.pairs_per_second,
                                               plotted_error(b.counter(MAX_REL_ERR)))
            clauses.append("%s index %d using 1:2 with points pt 3 ps 2.2 lw 2 lc rgb 'black' "
                           "title 'brent_baseline'" % (gp_quoted(brent_path), brent_block))
            brent_block += 1
        clauses += [
            "keyentry with points pt 7 lc rgb 'gray40' title 'newton, automatic iterations'",
            "keyentry with points pt 6 lc rgb 'gray40' title 'newton, fixed iterations'",
            "keyentry with points pt 9 lc rgb 'gray40' title 'log_odds, automatic iterations'",
            "keyentry with points pt 8 lc rgb 'gray40' title 'log_odds, fixed iterations'",
        ]
        gp += "plot " + ", \\\n     ".join(clauses) + "\n"
    gp += "unset multiplot\n"
    return gp, {points_path: points, fronts_path: fronts, brent_path: brent_data}


def draw_plot(png, work_files, trade):
    """Writes the gnuplot script and its data as <work_files>.gp and <work_files>_*.dat, then
    runs gnuplot on them when it is installed. Returns the script's path and whether the plot
    was drawn."""
    script, data = plot_script(png, work_files, trade)
    script_path = work_files + ".gp"
    for path, text in data.items():
        write_text(path, text)
    write_text(script_path, script)
    if not shutil.which("gnuplot"):
        return script_path, False
    result = subprocess.run(["gnuplot", script_path], check=False)
    if result.returncode != 0:
        raise ReportError("gnuplot failed on " + script_path)
    return script_path, True


# ---------------------------------------------------------------------------
# Command line

class ReportError(Exception):
    pass


def write_text(path, text):
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def without_extension(path, extension):
    return path[: -len(extension)] if path.endswith(extension) and path != extension else path


def summary_command(args):
    print_summary(sys.stdout, Run(args.json))
    return 0


def trade_command(args):
    run = Run(args.json)
    trade = Trade(run, args.label if args.label is not None else run.label)
    directory = os.path.dirname(os.path.abspath(args.json))
    csv_path = args.csv or os.path.join(directory, "trade.csv")
    markdown_path = args.markdown or os.path.join(directory, "trade.md")
    plot_path = args.plot or os.path.join(directory, "trade.png")
    write_csv(csv_path, trade)
    write_markdown(markdown_path, trade)
    out = sys.stdout
    out.write("Targets, fastest measured setting within each target's accuracy (1 thread)\n")
    print_targets_best_in_sweep(out, trade.table, trade.isa)
    out.write("\nTargets, default settings\n")
    print_targets(out, trade.table, trade.isa)
    out.write("\nBest setting per family and precision (full answer, 1 thread; fastest within "
              "10x of the lowest max error)\n")
    print_best_settings(out, trade)
    out.write("\nCSV: %s\nMarkdown: %s\n" % (csv_path, markdown_path))
    if args.no_plot:
        return 0
    # The script and its data stay beside the JSON: the plot may be published alone.
    work_files = os.path.join(directory, without_extension(os.path.basename(args.json), ".json"))
    script_path, drawn = draw_plot(plot_path, work_files, trade)
    out.flush()
    if not drawn:
        sys.stderr.write(
            "report.py: gnuplot is not installed: the plot %s was NOT drawn. Its gnuplot script "
            "is %s; install Debian's gnuplot-nox (apt-get install gnuplot-nox) and run "
            "`gnuplot %s`, or pass --no-plot to write only the CSV and Markdown tables.\n" % (
                plot_path, script_path, script_path))
        return 3
    out.write("Plot: %s\n" % plot_path)
    return 0


def main(argv):
    parser = argparse.ArgumentParser(
        description="pwcontact's benchmark reports, from Google Benchmark's JSON output "
                    "(--benchmark_out=FILE --benchmark_out_format=json).")
    commands = parser.add_subparsers(dest="command", required=True)
    summary = commands.add_parser(
        "summary", help="the summary of a pwcontact_bench run: ratios to brent_baseline, "
                        "thread scaling, the targets met or NOT MET")
    summary.add_argument("json", help="pwcontact_bench's JSON output")
    summary.set_defaults(run=summary_command)
    trade = commands.add_parser(
        "trade", help="the speed/accuracy trade of a pwcontact_trade run: CSV, Markdown and "
                      "a gnuplot plot")
    trade.add_argument("json", help="pwcontact_trade's JSON output")
    trade.add_argument("--csv", help="the CSV table (default: trade.csv beside the JSON)")
    trade.add_argument("--markdown", help="the Markdown report (default: trade.md beside the JSON)")
    trade.add_argument("--plot", help="the PNG plot (default: trade.png beside the JSON); its "
                                      "gnuplot script and data go beside the JSON")
    trade.add_argument("--no-plot", action="store_true",
                       help="write no plot (gnuplot is then not needed)")
    trade.add_argument("--label", help="the commit measured, for the headers (default: the "
                                       "run's pwcontact_label)")
    trade.set_defaults(run=trade_command)
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (OSError, ValueError, ReportError) as error:
        sys.stderr.write("report.py: %s\n" % error)
        return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
