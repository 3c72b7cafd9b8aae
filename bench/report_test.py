#!/usr/bin/python3
"""bench/report.py on the JSON of two very short benchmark runs (pwcontact_bench and
pwcontact_trade on small random and scene families), and on a hand-written JSON whose
verdicts are known: the summary, the trade's CSV and Markdown, and the plot (or, without
gnuplot, the message that says so). Run by ctest (bench.report_script):

  report_test.py --bench PWCONTACT_BENCH --trade PWCONTACT_TRADE --work-dir DIR
"""

import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import unittest

REPORT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "report.py")
ARGS = None

# Small families and short timings: the figures are noise, only their path
# from the benchmarks through the JSON to the reports is checked.
SHORT_RUN = ["--benchmark_min_time=0.001", "--benchmark_repetitions=2",
             "--benchmark_out_format=json"]


def run(command):
    return subprocess.run(command, capture_output=True, text=True, timeout=240, check=False)


def run_ok(test, command):
    result = run(command)
    test.assertEqual(result.returncode, 0, "%s\n%s%s" % (" ".join(command), result.stdout,
                                                         result.stderr))
    return result


def medians(json_path):
    """The run's context, and the items_per_second and the counters of each benchmark's
    "_median" aggregate, by benchmark name (without /real_time)."""
    with open(json_path, encoding="utf-8") as f:
        data = json.load(f)
    rates, counters = {}, {}
    for run_ in data["benchmarks"]:
        if run_.get("aggregate_name") == "median":
            name = run_["run_name"][: -len("/real_time")]
            rates[name] = run_["items_per_second"]
            counters[name] = run_
    return data["context"], rates, counters


class BenchSummary(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.json = os.path.join(ARGS.work_dir, "bench.json")
        result = run([ARGS.bench, "--pwcontact_random_pairs=1024", "--pwcontact_iterations=4",
                      "--benchmark_filter=/(random|scene)/", "--benchmark_out=" + cls.json]
                     + SHORT_RUN)
        assert result.returncode == 0, result.stdout + result.stderr
        cls.context, cls.rates, cls.counters = medians(cls.json)
        cls.isa = cls.context["pwcontact_default_isa"]
        cls.summary = run([sys.executable, REPORT, "summary", cls.json])

    def test_summary_succeeds(self):
        self.assertEqual(self.summary.returncode, 0, self.summary.stderr)
        self.assertIn("Summary (medians of 2 repetitions; real time;", self.summary.stdout)

    def test_every_measured_configuration_has_a_row_with_its_ratio_to_brent(self):
        rows = {line.split()[0]: line.split() for line in self.summary.stdout.splitlines()
                if "/threads:" in line and not line.startswith(" ")}
        self.assertEqual(set(rows), set(self.rates))
        for name, rate in self.rates.items():
            brent = self.rates["brent_baseline/%s/threads:1" % name.split("/")[1]]
            self.assertEqual(rows[name][1], "%.3g" % rate, name)
            self.assertEqual(rows[name][3], "%.2f" % (rate / brent), name)
            error = self.counters[name].get("max_rel_err")
            self.assertEqual(rows[name][4], "-" if error is None else "%.2e" % error, name)

    def test_targets_have_a_verdict_or_say_they_were_not_measured(self):
        lines = self.summary.stdout.splitlines()
        start = next(i for i, line in enumerate(lines) if line.startswith("Targets (1 thread"))
        targets = lines[start + 1:start + 13]
        self.assertEqual(
            targets[0], "  -        batch_double/pw85/isa:%s/iterations:0/threads:1: not measured"
            % self.isa)
        default = "batch_double/random/isa:%s/iterations:0/threads:1" % self.isa
        speedup = self.rates[default] / self.rates["brent_baseline/random/threads:1"]
        # Families of 1024 pairs, not the targets' 1048576: figures, no verdicts.
        off_size = "; on 1024 pairs, the target is for 1048576: no verdict"
        self.assertRegex(
            targets[5], r"^  -        %s: %s \(target >= 30x\), max rel err %s "
            r"\(target <= 1e-13\)%s" % (re.escape(default),
                                        re.escape("%.1fx brent_baseline" % speedup),
                                        re.escape("%.2e" % self.counters[default]["max_rel_err"]),
                                        re.escape(off_size)))
        self.assertRegex(targets[3], r"^  -        overlap_double/scene/.*misclassified "
                                     r"\d+ beyond \(\d+ within\) 1e-9 of tangency on the family"
                                     r".*%s" % re.escape(off_size))
        self.assertRegex(targets[10], r"^  -        %s: threads:2 / threads:1 = "
                                     r"\d+\.\d\d \(target >= 1.8\).*%s"
                                     % (re.escape(default), re.escape(off_size)))


class TradeReport(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = os.path.join(ARGS.work_dir, "trade")
        shutil.rmtree(cls.dir, ignore_errors=True)
        os.makedirs(cls.dir)
        cls.json = os.path.join(cls.dir, "trade.json")
        result = run([ARGS.trade, "--pwcontact_sweep=quick", "--pwcontact_pairs=1024",
                      "--pwcontact_near_tangent=128", "--pwcontact_families=random,scene",
                      "--pwcontact_iterations=4", "--pwcontact_label=commit under test",
                      "--benchmark_out=" + cls.json] + SHORT_RUN)
        assert result.returncode == 0, result.stdout + result.stderr
        cls.context, cls.rates, cls.counters = medians(cls.json)
        cls.csv = os.path.join(cls.dir, "out", "trade.csv")
        cls.markdown = os.path.join(cls.dir, "out", "trade.md")
        cls.png = os.path.join(cls.dir, "out", "trade.png")
        cls.report = run([sys.executable, REPORT, "trade", cls.json, "--csv=" + cls.csv,
                          "--markdown=" + cls.markdown, "--plot=" + cls.png])

    def test_csv_has_one_row_per_setting_with_its_figures(self):
        self.assertTrue(os.path.exists(self.csv), self.report.stderr)
        with open(self.csv, encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        one_thread = [n[: -len("/threads:1")] for n in self.rates if n.endswith("/threads:1")]
        self.assertEqual(sorted(r["configuration"] for r in rows), sorted(one_thread))
        brent = {r["family"]: float(r["pairs_per_second_1_threads"]) for r in rows
                 if r["path"] == "brent_baseline"}
        for r in rows:
            name = r["configuration"]
            rate = self.rates[name + "/threads:1"]
            self.assertEqual(r["pairs_per_second_1_threads"], "%.6g" % rate, name)
            self.assertEqual(r["x_brent_1_threads"],
                             "%.3f" % (rate / self.rates["brent_baseline/%s/threads:1"
                                                         % r["family"]]), name)
            self.assertGreater(brent[r["family"]], 0)
            counters = self.counters[name + "/threads:1"]
            error = counters.get("max_rel_err")
            self.assertEqual(r["max_rel_err"], "" if error is None else "%.6g" % error, name)
            if r["answer"] == "overlap":
                self.assertEqual(r["near_tangent_misclassified_beyond"],
                                 "%.6g" % counters["near_tangent_misclassified_beyond"], name)
            if r["path"].startswith("batch_"):
                self.assertNotEqual(r["pairs_per_second_2_threads"], "", name)

    def test_markdown_has_every_section_and_configuration(self):
        with open(self.markdown, encoding="utf-8") as f:
            text = f.read()
        self.assertIn("Measured: commit under test.", text)
        self.assertIn("isa %s; medians of 2 repetitions of at least 0.001 s of calls each, 1, 2 "
                      "thread(s); 1024 pairs per generated family, 128 per near-tangent set."
                      % self.context["pwcontact_default_isa"], text)
        for section in ("## Targets: the fastest measured setting within each target's accuracy",
                        "## Targets: the library's default settings",
                        "## Best setting per family and precision (full answer, 1 thread)",
                        "## Overlap screening (1 thread)", "### random family",
                        "### scene family"):
            self.assertIn(section, text)
        for name in self.rates:
            if name.endswith("/threads:1"):
                self.assertIn("| `%s` |" % name[: -len("/threads:1")], text)

    def test_plot_is_drawn_or_its_absence_said(self):
        script = os.path.join(self.dir, "trade.gp")
        self.assertTrue(os.path.exists(script), self.report.stderr)
        if shutil.which("gnuplot"):
            self.assertEqual(self.report.returncode, 0, self.report.stderr)
            with open(self.png, "rb") as f:
                self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")
        else:
            self.assertEqual(self.report.returncode, 3)
            self.assertIn("gnuplot is not installed", self.report.stderr)
            self.assertFalse(os.path.exists(self.png))


def benchmark(name, rate, cv=None, **counters):
    """One configuration's runs as Google Benchmark writes them with two repetitions."""
    runs = []
    for index, value in enumerate((rate * 0.99, rate * 1.01)):
        runs.append(dict(run_name=name + "/real_time", run_type="iteration", repetitions=2,
                         repetition_index=index, items_per_second=value, **counters))
    runs.append(dict(run_name=name + "/real_time", run_type="aggregate", aggregate_name="median",
                     repetitions=2, items_per_second=rate, **counters))
    if cv is not None:
        runs.append(dict(run_name=name + "/real_time", run_type="aggregate", aggregate_name="cv",
                         repetitions=2, items_per_second=cv))
    return runs


class KnownVerdicts(unittest.TestCase):
    """The targets' wording and verdicts on figures chosen for them."""

    @classmethod
    def setUpClass(cls):
        full = dict(invalid=0, fallbacks_per_pair=0, mean_evaluations=4)
        runs = (
            benchmark("brent_baseline/random/threads:1", 1e6, max_rel_err=1.3e-15)
            + benchmark("brent_baseline/pw85/threads:1", 1e6, max_rel_err=1.6e-11)
            + benchmark("brent_baseline/scene/threads:1", 1e6, max_rel_err=1.3e-15)
            + benchmark("batch_double/random/isa:avx2/iterations:0/threads:1", 3.5e7,
                        max_rel_err=1.2e-15, **full)
            + benchmark("batch_double/random/isa:avx2/iterations:0/threads:2", 6.615e7,
                        max_rel_err=1.2e-15, **full)
            + benchmark("batch_mixed/random/isa:avx2/iterations:0/threads:1", 3.9e7, cv=0.2,
                        max_rel_err=1.14e-15, **full)
            + benchmark("batch_float/random/isa:avx2/iterations:0/threads:1", 9.0e7,
                        max_rel_err=4.4e-7, max_rel_err_double_input=5.06e-7, **full)
            + benchmark("batch_double/pw85/isa:avx2/iterations:0/accuracy:high/threads:1",
                        1.01e7, max_rel_err=5.3e-15, **full)
            + benchmark("overlap_double/scene/isa:avx2/iterations:0/threads:1", 6.9e7,
                        invalid=0, misclassified_beyond=0, misclassified_within=0,
                        near_tangent_pairs=65536, near_tangent_misclassified_beyond=0,
                        near_tangent_misclassified_within=2))
        cls.json = os.path.join(ARGS.work_dir, "known.json")
        with open(cls.json, "w", encoding="utf-8") as f:
            json.dump({"context": {"pwcontact_default_isa": "avx2",
                                   "pwcontact_generated_pairs": "1048576"},
                       "benchmarks": runs}, f)
        cls.summary = run([sys.executable, REPORT, "summary", cls.json])
        # The same overlap figures without the near-tangent set, and the full answers on
        # families of 4096 pairs: neither decides its target.
        undecided = (
            benchmark("brent_baseline/random/threads:1", 1e6, max_rel_err=1.3e-15)
            + benchmark("brent_baseline/scene/threads:1", 1e6, max_rel_err=1.3e-15)
            + benchmark("batch_double/random/isa:avx2/iterations:0/threads:1", 7e7,
                        max_rel_err=1.2e-15, **full)
            + benchmark("overlap_double/scene/isa:avx2/iterations:0/threads:1", 1.2e8,
                        invalid=0, misclassified_beyond=0, misclassified_within=0)
            + benchmark("brent_baseline/pw85/threads:1", 1e6, max_rel_err=1.6e-11)
            + benchmark("overlap_float/pw85/isa:avx2/iterations:0/threads:1", 6e7,
                        invalid=0, misclassified_beyond=0, misclassified_within=0))
        cls.undecided_json = os.path.join(ARGS.work_dir, "undecided.json")
        with open(cls.undecided_json, "w", encoding="utf-8") as f:
            json.dump({"context": {"pwcontact_default_isa": "avx2",
                                   "pwcontact_generated_pairs": "4096"},
                       "benchmarks": undecided}, f)
        cls.undecided = run([sys.executable, REPORT, "summary", cls.undecided_json])
        cls.undecided_trade = run([sys.executable, REPORT, "trade", cls.undecided_json,
                                   "--csv=" + os.path.join(ARGS.work_dir, "undecided.csv"),
                                   "--markdown=" + os.path.join(ARGS.work_dir, "undecided.md"),
                                   "--no-plot"])

    def test_figures_that_cannot_decide_a_target_give_no_verdict(self):
        self.assertEqual(self.undecided.returncode, 0, self.undecided.stderr)
        lines = self.undecided.stdout.splitlines()
        off_size = "; on 4096 pairs, the target is for 1048576: no verdict"
        overlap = [line for line in lines if "overlap_double/scene/isa:avx2" in line
                   and "target >= 100x" in line]
        self.assertEqual(overlap, [
            "  -        overlap_double/scene/isa:avx2/iterations:0/threads:1: 120.0x "
            "brent_baseline (target >= 100x), misclassified 0 beyond (0 within) 1e-9 of "
            "tangency on the family, - on nan near-tangent pairs (target: none beyond)"
            + off_size])
        # pw85 is one size: only the missing near-tangent set leaves it undecided.
        self.assertIn(
            "  -        overlap_float/pw85/isa:avx2/iterations:0/threads:1: 60.0x brent_baseline "
            "(target >= 55x), misclassified 0 beyond (0 within) 1e-9 of tangency on the "
            "family, - on nan near-tangent pairs (target: none beyond)", lines)
        # The best setting within the accuracy: none decided without the near-tangent set
        # (it said NOT MET, "no measured setting is within the accuracy").
        self.assertEqual(self.undecided_trade.returncode, 0, self.undecided_trade.stderr)
        self.assertIn("  -        overlap_float/pw85/isa:avx2/iterations:0/threads:1: not measured",
                      self.undecided_trade.stdout.splitlines())
        full = [line for line in lines if line.startswith("  ")
                and "batch_double/random/isa:avx2/iterations:0/threads:1: 70.0x" in line]
        self.assertEqual(len(full), 2, lines)  # the 30x and the 60x targets
        for line in full:
            self.assertTrue(line.startswith("  -        "), line)
            self.assertTrue(line.endswith(off_size), line)

    def test_targets_read_as_specified(self):
        self.assertEqual(self.summary.returncode, 0, self.summary.stderr)
        lines = self.summary.stdout.splitlines()
        start = lines.index("Targets (1 thread; default settings are isa:auto = isa:avx2 and "
                            "iterations:0 = automatic)")
        self.assertEqual(lines[start + 1:start + 13], [
            "  -        batch_double/pw85/isa:avx2/iterations:0/threads:1: not measured",
            "  met      batch_float/random/isa:avx2/iterations:0/threads:1: 90.0x brent_baseline "
            "(target >= 80x), max rel err 4.40e-07 (target <= 1e-05); 5.06e-07 against the "
            "double inputs",
            "  NOT MET  batch_mixed/random/isa:avx2/iterations:0/threads:1: 39.0x brent_baseline "
            "(target >= 40x), max rel err 1.14e-15 (target <= 1e-13); noisy: cv up to 20%, "
            "rerun",
            "  NOT MET  overlap_double/scene/isa:avx2/iterations:0/threads:1: 69.0x "
            "brent_baseline (target >= 100x), misclassified 0 beyond (0 within) 1e-9 of "
            "tangency on the family, 0 beyond (2 within) on 65536 near-tangent pairs (target: "
            "none beyond)",
            "  met      batch_double/pw85/isa:avx2/iterations:0/accuracy:high/threads:1: "
            "1.01e+07 pairs/s = 10.1x brent_baseline, max rel err 5.30e-15 (target <= 1e-13); "
            "0 fallbacks per pair",
            "  met      batch_double/random/isa:avx2/iterations:0/threads:1: 35.0x brent_baseline "
            "(target >= 30x), max rel err 1.20e-15 (target <= 1e-13)",
            "  met      batch_float/random/isa:avx2/iterations:0/threads:1: 90.0x brent_baseline "
            "(target >= 60x), max rel err 4.40e-07 (target <= 1e-05); 5.06e-07 against the "
            "double inputs",
            "  NOT MET  batch_double/random/isa:avx2/iterations:0/threads:1: 35.0x brent_baseline "
            "(target >= 60x), max rel err 1.20e-15 (target <= 1e-13)",
            "  -        batch_double/pw85/isa:avx2/iterations:0/threads:1: not measured",
            "  -        overlap_float/pw85/isa:avx2/iterations:0/threads:1: not measured",
            "  met      batch_double/random/isa:avx2/iterations:0/threads:1: threads:2 / "
            "threads:1 = 1.89 (target >= 1.8); best repetitions 1.89",
            "  -        batch_float/random/isa:avx2/iterations:0/threads:1: threads:2 / "
            "threads:1 = - (target >= 1.8)",
        ])

    def test_a_file_that_is_not_json_is_an_error(self):
        path = os.path.join(ARGS.work_dir, "not.json")
        with open(path, "w", encoding="utf-8") as f:
            f.write("pairs per second\n")
        result = run([sys.executable, REPORT, "summary", path])
        self.assertEqual(result.returncode, 2)
        self.assertIn("report.py:", result.stderr)



if __name__ == "__main__":
    parser = argparse.ArgumentParser()
    parser.add_argument("--bench", required=True)
    parser.add_argument("--trade", required=True)
    parser.add_argument("--work-dir", required=True)
    ARGS, rest = parser.parse_known_args()
    os.makedirs(ARGS.work_dir, exist_ok=True)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
