"""What the Python binding costs, measured against the C++ calls on the same
numbers in one process (medians of interleaved repetitions):

  contact_function   1M random pairs (semi-axes 0.5 .. 2, |r12| up to ~5) from
                     numpy (N, 3) / (N, 6) arrays, against contact_function_batch
                     on the same pairs already in its SoA layout (target: within 10 %)
  screen             the 1M-spheroid demo scene (packing 0.3, aspect 1/3 .. 3)
                     from numpy arrays, against screen_pairs on a ParticleStore
                     built beforehand (target: within 15 %)
  per-pair loop      a Python loop calling the scalar reference path once per
                     pair (how pw85's bindings are used), against one
                     contact_function call on the same pairs
  trial moves        a Python loop of MovingScene.overlaps, one trial per
                     call, against one overlaps_many call (1 thread) on the
                     same trials (100,000 spheroids of the demo's kind, each
                     trial a particle moved by up to 0.1 along each axis; the
                     same answers, checked)

Run from the build tree (bash scripts/run.sh python-bench [--threads N]) or with
PYTHONPATH=build/release/python /usr/bin/python3 bench/python_overhead.py.
"""
import argparse
import statistics
import sys
import time

import numpy as np

import pwcontact as pw
from pwcontact import _pwcontact as core


def random_pairs(n, seed):
    rng = np.random.default_rng(seed)
    q1 = pw.quadratic_form(rng.uniform(0.5, 2, (n, 3)), rng.normal(size=(n, 4)))
    q2 = pw.quadratic_form(rng.uniform(0.5, 2, (n, 3)), rng.normal(size=(n, 4)))
    r12 = rng.normal(size=(n, 3)) * 2
    return r12, q1, q2


def median_pair(python_call, cpp_call, repetitions):
    """Interleaved: python, C++, python, C++, ... (a noisy shared machine
    slows both alike); medians of each."""
    py_times, cpp_times = [], []
    for _ in range(repetitions):
        start = time.perf_counter()
        python_call()
        py_times.append(time.perf_counter() - start)
        cpp_times.append(cpp_call())
    return statistics.median(py_times), statistics.median(cpp_times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--threads", type=int, default=1, help="OpenMP threads (default 1; 0: all)")
    parser.add_argument("--pairs", type=int, default=1_000_000)
    parser.add_argument("--particles", type=int, default=1_000_000)
    parser.add_argument("--repetitions", type=int, default=7)
    parser.add_argument("--loop-pairs", type=int, default=100_000)
    parser.add_argument("--trial-particles", type=int, default=100_000)
    parser.add_argument("--trials", type=int, default=100_000)
    args = parser.parse_args(argv)
    t = args.threads
    print(f"pwcontact {pw.__file__}; isa {pw.supported_isas()[0]}; threads {t}; "
          f"medians of {args.repetitions} interleaved repetitions")

    r12, q1, q2 = random_pairs(args.pairs, 1)
    n = args.pairs
    out = {"mu2": np.empty(n), "lambda": np.empty(n), "status": np.empty(n, np.uint8)}
    columns = [np.asfortranarray(a) for a in (r12, q1, q2)]
    # Each Python call against the C++ call on the same pairs in columns with
    # outputs alike: new result arrays against outputs the C++ call allocates
    # (both first touch fresh memory within the timing), out= arrays reused
    # against outputs written beforehand.
    cases = [
        ("C-ordered (N, 3) / (N, 6) rows, new result arrays", lambda: pw.contact_function(r12, q1, q2, threads=t), True),
        ("C-ordered rows, out= arrays reused", lambda: pw.contact_function(r12, q1, q2, threads=t, out=out), False),
        ("column-major arrays (read in place), new result arrays",
         lambda: pw.contact_function(*columns, threads=t), True),
        ("column-major arrays, out= arrays reused", lambda: pw.contact_function(*columns, threads=t, out=out), False),
    ]
    for name, call, fresh in cases:
        py, cpp = median_pair(call, lambda: core._time_batch(r12, q1, q2, t, fresh_outputs=fresh), args.repetitions)
        over = py / cpp - 1
        outputs = "allocated in the call" if fresh else "written beforehand"
        print(f"contact_function, {n} random pairs (mu2, lambda), {name}: python {py * 1e3:.1f} ms, "
              f"C++ (outputs {outputs}) {cpp * 1e3:.1f} ms: overhead {100 * over:+.1f} % (target <= 10 %: "
              f"{'met' if over <= 0.10 else 'NOT met'})")
    # What the rows cost in C++ itself (the same arrays through a strided
    # PairBatchView), against the binding on them: the layout's share and
    # the binding's.
    py, rows = median_pair(lambda: pw.contact_function(r12, q1, q2, threads=t, out=out),
                           lambda: core._time_batch(r12, q1, q2, t, rows=True), args.repetitions)
    cpp = statistics.median(core._time_batch(r12, q1, q2, t) for _ in range(args.repetitions))
    print(f"  of which the layout: C++ on the same C-ordered rows (strided view) {rows * 1e3:.1f} ms, "
          f"{100 * (rows / cpp - 1):+.1f} % over its columns ({cpp * 1e3:.1f} ms); the binding on the "
          f"rows (out= reused) {py * 1e3:.1f} ms, {100 * (py / rows - 1):+.1f} % over C++ on them")

    scene = pw.spheroid_scene(args.particles, 1, 0.3, 3.0)
    box = scene["box"]._core()
    build = []

    def cpp_screen():
        screen_seconds, build_seconds = core._time_screen(scene["positions"], scene["orientations"],
                                                          scene["semi_axes"], box, 1.0, t)
        build.append(build_seconds)
        return screen_seconds

    py, cpp = median_pair(lambda: pw.screen(**scene, threads=t), cpp_screen, max(3, args.repetitions // 2))
    store = statistics.median(build)
    over = py / cpp - 1
    print(f"screen, {args.particles} spheroids (packing 0.3) from numpy arrays: python {py * 1e3:.1f} ms, "
          f"C++ screen_pairs {cpp * 1e3:.1f} ms: overhead {100 * over:+.1f} % (target <= 15 %: "
          f"{'met' if over <= 0.15 else 'NOT met'}); of the python call, the ParticleStore built from the "
          f"arrays (which a C++ caller builds too) {store * 1e3:.1f} ms: against C++ store + screen_pairs "
          f"{100 * (py / (cpp + store) - 1):+.1f} %")

    m = args.loop_pairs
    a, b, c = r12[:m], q1[:m], q2[:m]
    start = time.perf_counter()
    for k in range(m):
        pw.reference(a[k], b[k], c[k])
    loop = time.perf_counter() - start
    start = time.perf_counter()
    pw.contact_function(a, b, c, threads=t)
    batch = time.perf_counter() - start
    print(f"per-pair Python loop over the scalar reference path, {m} pairs: {loop * 1e3:.0f} ms "
          f"({m / loop / 1e6:.3f} M pairs/s); one contact_function call: {batch * 1e3:.1f} ms "
          f"({m / batch / 1e6:.2f} M pairs/s): {loop / batch:.0f} x")
    moving = pw.spheroid_scene(args.trial_particles, 2, 0.3, 3.0)
    scene = pw.MovingScene(**moving)
    rng = np.random.default_rng(3)
    which = rng.integers(0, args.trial_particles, args.trials)
    positions = moving["positions"][which] + rng.uniform(-0.1, 0.1, (args.trials, 3))
    orientations = moving["orientations"][which]
    axes = moving["semi_axes"][which]
    start = time.perf_counter()
    single = [scene.overlaps(positions[k], orientations[k], axes[k], exclude=int(which[k]))
              for k in range(args.trials)]
    loop = time.perf_counter() - start
    start = time.perf_counter()
    many = scene.overlaps_many(positions, orientations, axes, exclude=which, threads=1)
    batch = time.perf_counter() - start
    if not np.array_equal(many, [-1 if f is None else f for f in single]):
        raise SystemExit("overlaps_many disagrees with the single queries")
    print(f"trial moves, {args.trials} trials on {args.trial_particles} spheroids (packing 0.3): a Python loop of "
          f"MovingScene.overlaps {loop / args.trials * 1e6:.2f} us a trial; one overlaps_many call "
          f"{batch / args.trials * 1e6:.2f} us a trial: {loop / batch:.1f} x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
