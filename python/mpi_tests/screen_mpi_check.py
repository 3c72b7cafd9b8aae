"""screen(..., comm=) over MPI ranks against the single-process screen, run
under mpirun by ctest (python.screen_mpi_<N>_ranks): every rank makes the
same scenes, passes its share of the particles (round robin, with tags; or
contiguous blocks, numbered by rank without tags), and rank 0 compares the
gathered pairs and mu^2 with screen() on the whole scene, exactly (the
round-robin screens through one ScreenWorkspace per rank). Exits
non-zero (on every rank) when a check fails."""
import sys

import numpy as np
from mpi4py import MPI

import pwcontact as pw

comm = MPI.COMM_WORLD
rank, size = comm.Get_rank(), comm.Get_size()
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)


def scene(n, seed, box_length):
    rng = np.random.default_rng(seed)
    positions = rng.uniform(0, box_length, size=(n, 3))
    # Polydisperse: equatorial radii over a factor 4, aspect ratios 1/3 .. 3.
    a = np.exp(rng.uniform(np.log(0.15), np.log(0.6), size=n))
    c = a * np.exp(rng.uniform(np.log(1 / 3), np.log(3), size=n))
    semi_axes = np.stack([a, a, c], axis=1)
    orientations = rng.normal(size=(n, 4))
    orientations /= np.linalg.norm(orientations, axis=1)[:, None]
    return positions, orientations, semi_axes


boxes = {
    "periodic": [12.0, 12.0, 12.0, 0, 0, 0],
    "triclinic": [12.0, 12.0, 12.0, 0.3, 0.2, 0.1],
    "open": None,
}
workspace = pw.ScreenWorkspace()  # this rank's, reused by the round-robin screens
for name, box in boxes.items():
    positions, orientations, semi_axes = scene(4000, 7, 12.0)
    whole = pw.screen(positions, orientations, semi_axes, box=box, cutoff=1.1, with_mu2=True,
                      threads=1)
    # Round robin with tags.
    mine = np.arange(rank, len(positions), size)
    got = pw.screen(positions[mine], orientations[mine], semi_axes[mine], box=box, cutoff=1.1,
                    with_mu2=True, threads=1, comm=comm, tags=mine, gather=True,
                    workspace=workspace)
    check(workspace.bytes > 0, f"{name}: the workspace holds nothing after a screen")
    if rank == 0:
        check(len(whole) > 500, f"{name}: only {len(whole)} pairs")
        check(got.pairs.dtype == np.uint64, f"{name}: pairs of dtype {got.pairs.dtype}")
        check(np.array_equal(got.pairs, whole.pairs.astype(np.uint64)),
              f"{name}, round robin: {len(got)} pairs gathered, {len(whole)} from one process")
        check(np.array_equal(got.mu2, whole.mu2), f"{name}, round robin: mu2 differs")
    else:
        check(len(got) == 0, f"{name}: {len(got)} pairs gathered on rank {rank}")
    check(got.report["dims"][0] * got.report["dims"][1] * got.report["dims"][2] == size,
          f"{name}: grid {got.report['dims']} for {size} ranks")
    # Contiguous blocks without tags: numbered by rank, rank 0's first.
    first, last = rank * len(positions) // size, (rank + 1) * len(positions) // size
    local = pw.screen(positions[first:last], orientations[first:last], semi_axes[first:last],
                      box=box, cutoff=1.1, threads=1, comm=comm)
    gathered = comm.gather(local.pairs, root=0)
    if rank == 0:
        pairs = np.concatenate(gathered)
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        check(np.array_equal(pairs, whole.pairs.astype(np.uint64)),
              f"{name}, blocks without tags: {len(pairs)} pairs over the ranks, {len(whole)} "
              "from one process")
        check(local.mu2 is None, f"{name}: mu2 without with_mu2")

# A bad cutoff is an error on every rank.
try:
    pw.screen(np.zeros((1, 3)), None, np.ones(3), cutoff=0.0, comm=comm)
    check(False, "cutoff 0 accepted")
except ValueError:
    pass
try:
    pw.screen(np.zeros((1, 3)), None, np.ones(3), comm="MPI_COMM_WORLD")
    check(False, "a string accepted as comm")
except TypeError:
    pass
try:
    pw.screen(np.zeros((1, 3)), None, np.ones(3), tags=[0])
    check(False, "tags accepted without comm")
except ValueError:
    pass

# An error in one rank's input only (the last rank's) is raised on every
# rank: its own exception there, a ValueError naming it on the others. (The
# other ranks waited for ever in the first collective call.) Each case is
# followed by a good screen: the ranks' collective calls stay in step.
bad = size - 1
box2d = pw.Box(20, 20, is2D=True)
cases = [
    ("negative semi-axes", ValueError, "semi-axes must be positive",
     lambda mine: pw.screen(np.zeros((2, 3)) + [[1, 1, 1], [5, 5, 5]], None,
                            [-1.0, 0.4, 0.3] if mine else [1.0, 0.4, 0.3], box=pw.Box.cube(20),
                            comm=comm)),
    ("tags of the wrong length", ValueError, "tags must have shape",
     lambda mine: pw.screen(np.zeros((2, 3)) + [[1, 1, 1], [5, 5, 5]], None, [1.0, 0.4, 0.3],
                            tags=[2 * rank] if mine else [2 * rank, 2 * rank + 1],
                            box=pw.Box.cube(20), comm=comm)),
    ("a particle off the plane of a 2D box", ValueError, "z = 3",
     lambda mine: pw.screen(np.array([[1.0, 1, 3 if mine else 0]]), None, [1.0, 0.5, 0.2],
                            box=box2d, comm=comm)),
    ("an unknown keyword", TypeError, "'bx'",
     lambda mine: pw.screen(np.array([[1.0, 1, 1]]), None, [1.0, 0.5, 0.2], comm=comm,
                            **({"bx": 1} if mine else {}))),
    # (Not a ValueError: raised before the core, it once left the others
    # waiting as well.)
    ("a cutoff beyond a double", OverflowError, "too large",
     lambda mine: pw.screen(np.array([[1.0, 1, 1]]), None, [1.0, 0.5, 0.2], box=pw.Box.cube(20),
                            cutoff=10**400 if mine else 1.0, comm=comm)),
    ("tags that are not integers", ValueError, "tags must be integers",
     lambda mine: pw.screen(np.array([[1.0, 1, 1]]), None, [1.0, 0.5, 0.2], box=pw.Box.cube(20),
                            tags=[0.5] if mine else [rank], comm=comm)),
    ("negative tags", ValueError, "tags must be non-negative",
     lambda mine: pw.screen(np.array([[1.0, 1, 1]]), None, [1.0, 0.5, 0.2], box=pw.Box.cube(20),
                            tags=[-1] if mine else [rank], comm=comm)),
]
for name, kind, text, call in cases:
    try:
        call(rank == bad)
        check(False, f"{name} on rank {bad}: no error on rank {rank}")
    except Exception as e:  # noqa: BLE001 (the kind is checked)
        if rank == bad:
            check(type(e) is kind and text in str(e),
                  f"{name}: rank {rank} raised {type(e).__name__}: {e}")
        else:
            check(type(e) is ValueError and f"rank {bad}" in str(e) and text in str(e),
                  f"{name}: rank {rank} raised {type(e).__name__}: {e}")
    after = pw.screen(np.array([[1.0 + rank, 1, 1]]), None, [1.0, 0.4, 0.3], box=pw.Box.cube(20),
                      comm=comm, gather=True)
    if rank == 0:
        check(len(after.pairs) == max(0, size - 1), f"after {name}: {len(after.pairs)} pairs")

# Settings that differ between ranks (box, cutoff, gather, tags given or
# not): a ValueError on every rank, not pairs by different rules or a rank
# waiting alone (tags on one rank only hung, or paired by mismatched scans).
if size > 1:
    for name, kw in [("cutoff", lambda: {"cutoff": 1.0 + 0.5 * (rank == bad)}),
                     ("box", lambda: {"box": pw.Box.cube(20 + (rank == bad))}),
                     ("gather", lambda: {"gather": rank == bad}),
                     ("tags", lambda: {"tags": np.array([rank], dtype=np.uint64)}
                      if rank == bad else {}),
                     ("tags", lambda: {"tags": np.array([rank], dtype=np.uint64)}
                      if rank != bad else {})]:
        arguments = {"box": pw.Box.cube(20), **kw()}
        try:
            pw.screen(np.array([[1.0 + rank, 1, 1]]), None, [1.0, 0.4, 0.3], comm=comm, **arguments)
            check(False, f"a {name} that differs between ranks: no error on rank {rank}")
        except ValueError as e:
            check("every rank must pass the same" in str(e), f"{name} differs: rank {rank}: {e}")
    after = pw.screen(np.array([[1.0 + rank, 1, 1]]), None, [1.0, 0.4, 0.3], box=pw.Box.cube(20),
                      comm=comm, gather=True)
    if rank == 0:
        check(len(after.pairs) == size - 1, f"after the differing settings: {len(after.pairs)} pairs")

for what in failures:
    print(f"rank {rank}: FAILED: {what}", flush=True)
failed = comm.allreduce(len(failures), op=MPI.SUM)
if rank == 0:
    print(f"screen(comm=) on {size} ranks: {'all checks passed' if failed == 0 else f'{failed} failures'}")
sys.exit(1 if failed else 0)
