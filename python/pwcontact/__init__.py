"""The Perram-Wertheim contact function of ellipsoids, for many pairs at once.

mu is the factor by which two ellipsoids must both be scaled about their
centres to touch: mu**2 < 1 they overlap, > 1 they are apart. An ellipsoid is
given by its centre and its quadratic form Q (symmetric positive definite, 6
numbers: the upper triangle row by row, Q = R diag(a**2) R^T for semi-axes a
and rotation R); a pair by r12 = c2 - c1 and its two forms.

Arrays are numpy arrays (anything numpy converts); pairs are rows: r12 of
shape (N, 3), q1 and q2 of shape (N, 6), any of them of shape (3,) or (6,) to
broadcast one against many. float32 pairs are solved as float pairs (float32
results) unless another precision is asked for; every other dtype in double.
An array of the dtype computed in is read where it lies, whatever its
strides (no copy); another dtype is converted first (a copy). Per-pair
problems (a form that is not positive definite, a non-finite number) are
statuses, never exceptions; malformed calls (shapes, unknown options) raise
ValueError, as do values of the wrong kind (an index, a type id, a count or
a seed that is not an integer, or is negative; an argument that would be
ignored); an index that does not exist raises IndexError, a file that
cannot be opened OSError (FileNotFoundError when it does not exist). The
GIL is released during every computation over many pairs or particles (not
in reference(), a single pair).

Everything here is documented with the library's conventions in README.md.
"""

from __future__ import annotations

import enum
import math
import numbers
import operator
from typing import Any, Iterable, Mapping, Optional, Tuple, Union

import numpy as np

from . import _pwcontact as _core

__all__ = [
    "STATUS_DESCRIPTIONS",
    "Box",
    "ContactResult",
    "DistributedScreenResult",
    "HardParticleMC",
    "MovingScene",
    "OverlapResult",
    "ScreenResult",
    "ScreenWorkspace",
    "SkinNeighborList",
    "Status",
    "contact_function",
    "is_valid",
    "overlap",
    "quadratic_form",
    "read_gsd",
    "read_gsd_native",
    "read_lammps_data",
    "read_lammps_dump",
    "reference",
    "screen",
    "sphere",
    "spheroid",
    "spheroid_scene",
    "supported_isas",
    "with_mpi",
]

#: Whether this module was built with MPI (PWCONTACT_BUILD_MPI): screen(comm=...) needs it.
with_mpi: bool = bool(_core.with_mpi)

Status = enum.IntEnum("Status", [(name, code) for code, (name, _) in enumerate(_core.status_names())])
Status.__doc__ = "Per-pair status codes (the status arrays hold these values, as uint8)."
STATUS_DESCRIPTIONS = {Status(code): text for code, (_, text) in enumerate(_core.status_names())}


def _integer(value, name: str, low: Optional[int] = None, high: Optional[int] = None) -> int:
    """value as an int: a Python or numpy integer (not a bool, not a float,
    however whole), within [low, high]; ValueError naming it otherwise."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    try:
        i = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer, got {value!r}") from None
    if (low is not None and i < low) or (high is not None and i > high):
        bounds = f">= {low}" if high is None else f"in {low} .. {high}"
        raise ValueError(f"{name} must be {bounds}, got {i}")
    return i


def _integer_array(values, name: str) -> np.ndarray:
    """values as an array of integers (an empty sequence too); ValueError
    naming it for another dtype (floats are not truncated)."""
    a = np.asarray(values)
    if a.size == 0:
        return a.astype(np.int64)
    if a.dtype.kind not in "iu":
        raise ValueError(f"{name} must be integers, got dtype {a.dtype}")
    return a


_UINT64_MAX = 2**64 - 1

# As the command line's --threads (10**5 threads segfaulted the interpreter
# in the batched MovingScene query and in screen).
_MAX_THREADS = 1024


def _threads(value) -> int:
    """threads as an int in 0 .. 1024 (0: all); ValueError otherwise."""
    return _integer(value, "threads", 0, _MAX_THREADS)


def is_valid(status: Any) -> Any:
    """True where a status says the answer is valid (ok or ok_fallback)."""
    s = np.asarray(status)
    return (s == Status.ok) | (s == Status.ok_fallback)


def reference(r12, q1, q2) -> Tuple[float, float, Status]:
    """One pair through the scalar reference path (double): (mu2, lambda,
    status). r12 (3,), q1 and q2 (6,) (ValueError naming one of another
    shape). For a handful of pairs; contact_function is the fast path for
    many (a Python loop over this pays the interpreter's cost per pair)."""
    given = []
    for name, value, k in (("r12", r12, 3), ("q1", q1, 6), ("q2", q2, 6)):
        a = np.asarray(value, dtype=float)
        if a.shape != (k,):
            raise ValueError(f"{name} must be {k} numbers, got shape {a.shape}")
        given.append(a)
    mu2, lam, status = _core.reference(*given)
    return mu2, lam, Status(status)


def supported_isas() -> list:
    """The instruction sets this CPU runs, best first (e.g. ['avx512', 'avx2', 'sse2', 'fallback'])."""
    return _core.supported_isas()


class _Result:
    """Arrays by attribute and by key, and the call's report as attributes."""

    def __init__(self, arrays: dict, report: dict):
        self._arrays = arrays
        self.report = report
        for key, value in report.items():
            setattr(self, key, value)

    def __getitem__(self, key: str):
        if key not in self._arrays:
            raise KeyError(f"{key!r} is not among the outputs of this result "
                           f"(it has {', '.join(self._arrays)}; ask for it by outputs=)")
        return self._arrays[key]

    def __contains__(self, key: str) -> bool:
        return key in self._arrays

    def keys(self):
        return self._arrays.keys()

    def __repr__(self) -> str:
        shapes = ", ".join(f"{k}{tuple(np.shape(v))}" for k, v in self._arrays.items())
        return f"{type(self).__name__}({shapes}; {self.report})"


class ContactResult(_Result):
    """What contact_function computed.

    Arrays (by attribute, or by key), each when asked for by ``outputs``
    (KeyError saying so otherwise): ``mu2`` (N,) (asked for by default;
    computed either way, returned only when asked), ``lambda_`` (also
    ``result["lambda"]``, the maximiser lambda_0), and ``contact_point``,
    ``normal``, ``gradient`` (N, 3) (views of (3, N) arrays: columns
    contiguous); always ``status`` (N,) uint8 (see Status).
    Report attributes: ``pairs``, ``fallbacks`` (pairs the SIMD kernels left to
    the scalar reference path), ``finished_in_double`` (in single precision,
    pairs the float kernels left and the double kernels finished),
    ``invalid`` (pairs with an invalid status), ``mean_evaluations``, ``isa``,
    ``precision``.
    """

    @property
    def mu2(self):
        return self["mu2"]

    @property
    def lambda_(self):
        return self["lambda"]

    @property
    def status(self):
        return self["status"]

    @property
    def contact_point(self):
        return self["contact_point"]

    @property
    def normal(self):
        return self["normal"]

    @property
    def gradient(self):
        return self["gradient"]


class OverlapResult(_Result):
    """What overlap computed: ``overlap`` (N,) bool (mu < cutoff) and ``status``
    (N,) uint8; report attributes as ContactResult's, with
    ``decided_by_prefilter``, ``decided_by_certificate`` and ``overlapping``."""

    @property
    def overlap(self):
        return self["overlap"]

    @property
    def status(self):
        return self["status"]


_OUTPUTS = ("mu2", "lambda", "contact_point", "normal", "gradient")
_OUT_KEYS = ("mu2", "lambda", "status")


def _iterations(iterations) -> Union[str, int]:
    """"auto" (or None) or an integer (its range is the core's to check)."""
    if iterations is None or (isinstance(iterations, str) and iterations == "auto"):
        return "auto"
    if isinstance(iterations, (bool, np.bool_)) or not isinstance(iterations, numbers.Integral):
        raise ValueError(f"iterations must be 'auto' or an integer, got {iterations!r}")
    i = int(iterations)
    if not -2**31 <= i < 2**31:  # (the core names the range; beyond an int, say it here)
        raise ValueError(f"iterations must be 'auto' or an integer 0 .. 1000 (0: auto), got {i}")
    return i


def contact_function(r12, q1, q2, *, outputs: Iterable[str] = ("mu2", "lambda"),
                     precision: str = "auto", iterations: Union[str, int] = "auto",
                     accuracy: str = "standard", threads: int = 0, isa: str = "auto",
                     lambda_start=None, out: Optional[dict] = None) -> ContactResult:
    """mu**2 (and what else is asked for) of every pair.

    r12: (N, 3) or (3,); q1, q2: (N, 6) or (6,) (upper triangles, row-major).
    outputs: any of "mu2", "lambda", "contact_point", "normal", "gradient"
    (mu2 and status are always computed, mu2 returned only when asked; the
    others cost only when asked).
    precision: "auto" (float32 pairs in float, else double), "double",
    "float", "mixed". iterations: "auto" (each pair until its convergence
    check passes; also 0 or None) or a fixed count, an integer 1 .. 1000 (the
    command line's --iterations and BatchOptions.iterations take the same).
    accuracy: "standard" or "high" (the answer refined in double: float32
    pairs with accuracy="high" need precision="double" or "mixed",
    ValueError with "auto" or "float").
    threads: OpenMP threads, 0 .. 1024 (0: all). isa: "auto", "sse2", "avx2", "avx512", "fallback" (the reference path per pair, on any CPU).
    lambda_start: optional (N,) array, a lambda to start each pair from (a
    warm start, e.g. the previous step's; NaN for none).
    out: optional dict of arrays to write into, reused across calls:
    "mu2", "lambda" (of the result's dtype) and "status" (uint8), each
    C-contiguous of shape (N,); "lambda" only when it is among the outputs
    (ValueError for another key, or "lambda" not asked for). An input that
    shares memory with an out array is copied first (lambda_start may be
    out["lambda"] itself: a warm start in place); out arrays that overlap
    one another are refused (ValueError).

    Layout and cost: every layout is read in place. Arrays whose columns
    are contiguous (a Fortran-ordered (N, 3) array, or ``a.T`` of a
    C-ordered (3, N) one) are read fastest; the usual C-ordered rows are
    read by shuffles of 8 rows under AVX-512 and by gathers otherwise,
    5-8 % slower for the double full answer on 1M pairs (README: Python,
    the binding's cost).

    Returns a ContactResult. Raises ValueError for shapes and option values.
    """
    names = [outputs] if isinstance(outputs, str) else list(outputs)
    for name in names:
        if name not in _OUTPUTS:
            raise ValueError(f"unknown output {name!r} (outputs: {', '.join(_OUTPUTS)})")
    if out is not None:
        if not isinstance(out, dict):
            raise ValueError(f"out must be a dict of arrays, got {type(out).__name__}")
        for key in out:
            if key not in _OUT_KEYS:
                raise ValueError(f"out[{key!r}]: unknown key (out takes {', '.join(_OUT_KEYS)})")
        if "lambda" in out and "lambda" not in names:
            raise ValueError("out['lambda'] is given but 'lambda' is not among the outputs: it would "
                             "not be written")
        r12, q1, q2, lambda_start = _apart_from_out(out, r12, q1, q2, lambda_start)
    raw = _core.contact_function(r12, q1, q2, names, precision, _iterations(iterations), accuracy,
                                 _threads(threads), isa, lambda_start, out)
    report = raw.pop("report")
    if "mu2" not in names:
        raw.pop("mu2", None)
    return ContactResult(raw, report)


def _apart_from_out(out: dict, r12, q1, q2, lambda_start):
    """The inputs, each copied where an out array shares its memory (as numpy's
    ufuncs do: written while it is read, it gave wrong answers with valid
    statuses); lambda_start may be out['lambda'] itself (a warm start in
    place: each pair reads its own start before it writes its lambda). Out
    arrays that overlap one another are refused (ValueError)."""
    arrays = [(key, a) for key, a in out.items() if isinstance(a, np.ndarray)]
    for k, (key, a) in enumerate(arrays):
        for other, b in arrays[k + 1:]:
            if np.may_share_memory(a, b):
                raise ValueError(f"out[{key!r}] and out[{other!r}] share memory: give separate arrays")

    def apart(x, skip=None):
        if any(key != skip and np.may_share_memory(a, x) for key, a in arrays):
            return np.array(x, copy=True)
        return x

    lam = out.get("lambda")
    same_lambda = (isinstance(lam, np.ndarray) and isinstance(lambda_start, np.ndarray)
                   and lam.__array_interface__ == lambda_start.__array_interface__)
    start = None if lambda_start is None else apart(lambda_start, "lambda" if same_lambda else None)
    return apart(r12), apart(q1), apart(q2), start


def overlap(r12, q1, q2, cutoff: float = 1.0, *, precision: str = "auto",
            iterations: Union[str, int] = "auto", threads: int = 0, isa: str = "auto") -> OverlapResult:
    """Whether mu < cutoff for every pair, decided with certificates (most
    pairs without a full solve). Arguments as contact_function's; cutoff
    positive and finite. In double precision the answer agrees with
    mu**2 < cutoff**2 wherever |mu**2 - cutoff**2| > 1e-9 cutoff**2 (README:
    the overlap bound). Returns an OverlapResult."""
    raw = _core.overlap(r12, q1, q2, float(cutoff), precision, _iterations(iterations), _threads(threads), isa)
    report = raw.pop("report")
    return OverlapResult(raw, report)


def quadratic_form(semi_axes, orientation) -> np.ndarray:
    """Q = R diag(a**2) R^T of every particle: semi_axes (N, 3) or (3,),
    orientation (N, 4) or (4,) unit quaternions (w, x, y, z), as HOOMD-blue
    and GSD give them (normalised when not unit; zero raises ValueError).
    Returns (N, 6) float64."""
    q = _core.quadratic_form(semi_axes, orientation)
    bad = np.flatnonzero(~np.all(np.isfinite(np.atleast_2d(q)), axis=1))
    if len(bad):
        raise ValueError(f"the form of row {bad[0]} is not finite (semi-axes squared overflow)")
    return q


def sphere(radius: float) -> np.ndarray:
    """Q of a sphere of the given radius (6,)."""
    r = float(radius)
    if not (r > 0 and math.isfinite(r * r)):
        raise ValueError(f"radius must be positive and its square finite, got {radius!r}")
    return np.array([r * r, 0, 0, r * r, 0, r * r])


def spheroid(a: float, c: float, axis=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Q of a spheroid (6,): equatorial radius a, polar radius c along the unit
    axis n: Q = a**2 I + (c**2 - a**2) n n^T."""
    n = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(n)
    if not (norm > 0 and np.isfinite(norm)):
        raise ValueError(f"axis must be non-zero and finite, got {axis!r}")
    for name, v in (("a", a), ("c", c)):
        if not (float(v) > 0 and math.isfinite(float(v) ** 2)):
            raise ValueError(f"{name} must be positive and its square finite, got {v!r}")
    a, c = float(a), float(c)  # (numpy integers would square in their own type, and wrap)
    n = n / norm
    m = a * a * np.eye(3) + (c * c - a * a) * np.outer(n, n)
    return np.array([m[0, 0], m[0, 1], m[0, 2], m[1, 1], m[1, 2], m[2, 2]])


class Box:
    """A simulation box in HOOMD-blue's and freud's convention: lengths Lx,
    Ly, Lz and unitless tilt factors xy, xz, yz (box matrix columns
    (Lx, 0, 0), (xy Ly, Ly, 0), (xz Lz, yz Lz, Lz)); periodic along every
    axis (``periodic=False``: open, no images); 2D boxes (``is2D``) hold
    ellipses in the z = 0 plane."""

    def __init__(self, Lx: float, Ly: float, Lz: float = 0.0, xy: float = 0.0, xz: float = 0.0,
                 yz: float = 0.0, is2D: bool = False, periodic: bool = True):
        self.Lx, self.Ly, self.Lz = float(Lx), float(Ly), float(Lz)
        self.xy, self.xz, self.yz = float(xy), float(xz), float(yz)
        self.is2D = bool(is2D)
        self.periodic = bool(periodic)
        if self.is2D:
            self.Lz, self.xz, self.yz = 0.0, 0.0, 0.0
        lengths = (self.Lx, self.Ly) if self.is2D else (self.Lx, self.Ly, self.Lz)
        if self.periodic and not all(L > 0 and math.isfinite(L) for L in lengths):
            raise ValueError(f"box lengths must be positive and finite, got {lengths}")
        if not all(math.isfinite(t) for t in (self.xy, self.xz, self.yz)):
            raise ValueError("box tilts must be finite")

    @classmethod
    def cube(cls, L: float) -> "Box":
        return cls(L, L, L)

    @classmethod
    def open(cls) -> "Box":
        """No box: no periodic images."""
        return cls(0, 0, 0, periodic=False)

    @classmethod
    def from_box(cls, box: Any, dimensions: Optional[int] = None) -> "Box":
        """A Box from what HOOMD-blue, freud and GSD hold: a Box; a sequence
        [Lx, Ly] (2D), [Lx, Ly, Lz] or [Lx, Ly, Lz, xy, xz, yz] (GSD's
        configuration/box; Lz = 0 or dimensions=2 is 2D); a dict with keys
        Lx, Ly, Lz, xy, xz, yz (and dimensions); or any object with those
        attributes (freud.box.Box, hoomd.Box: is2D or dimensions)."""
        if isinstance(box, Box):
            return box
        if isinstance(box, Mapping):
            get = box.get
            missing = [k for k in ("Lx", "Ly") if get(k) is None]
            if missing:
                raise ValueError(f"a box dict needs Lx and Ly (and Lz, xy, xz, yz), it lacks {missing[0]}")
            two_d = bool(get("is2D", False)) or get("dimensions", dimensions) == 2 or float(get("Lz", 0)) == 0
            return cls(get("Lx"), get("Ly"), get("Lz", 0), get("xy", 0), get("xz", 0), get("yz", 0), is2D=two_d)
        if all(hasattr(box, k) for k in ("Lx", "Ly", "Lz")):
            two_d = bool(getattr(box, "is2D", False)) or getattr(box, "dimensions", dimensions) == 2
            return cls(box.Lx, box.Ly, box.Lz, getattr(box, "xy", 0), getattr(box, "xz", 0),
                       getattr(box, "yz", 0), is2D=two_d)
        values = [float(v) for v in np.asarray(box, dtype=float).ravel()]
        if len(values) == 2:
            return cls(values[0], values[1], 0, is2D=True)
        if len(values) == 3:
            values += [0.0, 0.0, 0.0]
        if len(values) != 6:
            raise ValueError(f"a box is [Lx, Ly], [Lx, Ly, Lz] or [Lx, Ly, Lz, xy, xz, yz]; got {len(values)} numbers")
        two_d = dimensions == 2 or values[2] == 0
        return cls(*values, is2D=two_d)

    @property
    def matrix(self) -> np.ndarray:
        """The box matrix (columns are the box vectors)."""
        return np.array([[self.Lx, self.xy * self.Ly, self.xz * self.Lz],
                         [0.0, self.Ly, self.yz * self.Lz],
                         [0.0, 0.0, self.Lz]])

    def wrap_vectors(self, d) -> np.ndarray:
        """Minimum images of separation vectors (N, 3) (unchanged in an open box)."""
        d = np.array(d, dtype=float, copy=True)
        if d.ndim == 1 and d.shape == (3,):
            return self.wrap_vectors(d[None])[0]
        if d.ndim != 2 or d.shape[1] != 3:
            raise ValueError(f"separation vectors must have shape (N, 3) or (3,), got {d.shape}")
        if not self.periodic:
            return d
        m = self.matrix
        if self.is2D:
            m = m.copy()
            m[2, 2] = 1.0
        f = np.linalg.solve(m, d.T).T
        axes = 2 if self.is2D else 3
        f[:, :axes] -= np.round(f[:, :axes])
        return (m @ f.T).T

    def _core(self):
        if not self.periodic:
            return None
        return (self.Lx, self.Ly, self.Lz, self.xy, self.xz, self.yz, 2 if self.is2D else 3)

    def __repr__(self) -> str:
        if not self.periodic:
            return "Box.open()"
        return (f"Box(Lx={self.Lx}, Ly={self.Ly}, Lz={self.Lz}, xy={self.xy}, xz={self.xz}, "
                f"yz={self.yz}, is2D={self.is2D})")


def _as_box(box) -> Optional[Box]:
    if box is None:
        return None
    return Box.from_box(box)


class ScreenResult:
    """The pairs a screen found.

    ``pairs`` (M, 2) uint32, each (i, j) with i < j, sorted; ``mu2`` (M,) when
    asked for (else None); ``counts`` (N,) uint32, the pairs each particle is
    in; ``offsets`` (N + 1,) int64, so that pairs[offsets[i]:offsets[i + 1]]
    are the pairs (i, j > i); ``report`` (a dict of the screen's counters).
    """

    def __init__(self, raw: dict, positions: np.ndarray, box: Optional[Box]):
        self.pairs = raw["pairs"]
        self.mu2 = raw["mu2"]
        self.counts = raw["counts"]
        self.offsets = raw["offsets"]
        self.report = raw["report"]
        # (A copy: the caller's array may change in place afterwards, as a
        # SkinNeighborList loop's does, and this result's vectors must not.)
        self._positions = np.array(positions, dtype=float, copy=True)
        self._box = box

    def __len__(self) -> int:
        return len(self.pairs)

    def to_freud_arrays(self) -> dict:
        """The keyword arguments of freud.locality.NeighborList.from_arrays:
        num_query_points, num_points, query_point_indices, point_indices and
        vectors (minimum images, from query point to point), both directions
        of every pair, sorted by query point; weights 1."""
        i, j = self.pairs[:, 0].astype(np.uint32), self.pairs[:, 1].astype(np.uint32)
        q = np.concatenate([i, j])
        p = np.concatenate([j, i])
        order = np.lexsort((p, q))
        q, p = q[order], p[order]
        d = self._positions[p] - self._positions[q]
        if self._box is not None:
            d = self._box.wrap_vectors(d)
        n = len(self._positions)
        return {"num_query_points": n, "num_points": n, "query_point_indices": q,
                "point_indices": p, "vectors": d, "weights": np.ones(len(q))}

    def __repr__(self) -> str:
        return f"ScreenResult({len(self.pairs)} pairs)"


def _real_array(values, name: str = "positions") -> np.ndarray:
    """values as float64, refusing what the cast would change rather than
    convert: complex numbers (numpy drops the imaginary part with a
    warning), strings, dates (ValueError naming the argument, as the core
    refuses them in the arguments it converts itself)."""
    a = np.asarray(values)
    if a.dtype.kind not in "fiubO":
        raise ValueError(f"{name} must be an array of real numbers, got dtype {a.dtype}")
    return np.asarray(a, dtype=float)


def _check_in_plane(positions, orientations, row: str = "particle") -> None:
    """A 2D scene: centres at z = 0, rotations about z (as the GSD reader
    checks). A bad one is named as `row` and its index, or as "the trial"
    when one row is given alone ((3,) or (4,)); arrays of other shapes are
    left to the core, which names them."""
    p = _real_array(positions)
    if p.ndim in (1, 2) and p.shape[-1] == 3:
        rows = p.reshape(-1, 3)
        off = np.flatnonzero(rows[:, 2] != 0)
        if len(off):
            who = "the trial" if p.ndim == 1 else f"{row} {off[0]}"
            raise ValueError(f"a two-dimensional box, but {who} has z = {rows[off[0], 2]!r}, not 0")
    if orientations is not None:
        o = np.asarray(orientations, dtype=float)
        if o.ndim not in (1, 2) or o.shape[-1] != 4:
            return
        rows = o.reshape(-1, 4)
        norm = np.sum(rows * rows, axis=1)
        tilted = np.flatnonzero(rows[:, 1] ** 2 + rows[:, 2] ** 2 > 1e-12 * norm)
        if len(tilted):
            whose = "" if o.ndim == 1 else f" of {row} {tilted[0]}"
            raise ValueError(f"a two-dimensional box, but the orientation{whose} "
                             f"({', '.join(map(repr, rows[tilted[0]]))}) is not a rotation about z")


def _typeid_array(typeid) -> np.ndarray:
    """Type ids: integers (not floats, which would be truncated), none negative."""
    t = _integer_array(typeid, "typeid")
    if t.ndim == 1:
        # (Beyond 2**32 - 1 the core's 32-bit type would wrap it to another type.)
        bad = np.flatnonzero((t < 0) | (t > 2**32 - 1))
        if len(bad):
            raise ValueError(f"typeid of particle {bad[0]} is {t[bad[0]]}: not a type")
    return t


def _scene_arguments(who: str, positions, orientations, semi_axes, type_semi_axes, typeid, box, ignored,
                     q=None):
    """The particles' arguments as screen() takes them: the keywords that
    read_gsd / read_lammps_* return beside them accepted and ignored (an
    unknown one is a TypeError), semi_axes=(type_semi_axes, typeid)
    unpacked, typeid checked (integers, none negative; refused beside
    semi_axes, which it would not change), orientations refused beside q
    (which holds them), the box made, a 2D scene checked in its plane.
    Returns (positions, semi_axes, type_semi_axes, typeid, box)."""
    for key in ignored:
        if key not in ("type_names", "frame", "frames", "id"):
            raise TypeError(f"{who}() got an unexpected keyword argument {key!r}")
    if isinstance(semi_axes, tuple) and len(semi_axes) == 2:
        if type_semi_axes is not None or typeid is not None:
            raise ValueError("give the shapes one way: semi_axes=(type_semi_axes, typeid) or the keywords")
        type_semi_axes, typeid = semi_axes
        semi_axes = None
    # (Two ways of giving the shapes at once are the core's "one way" error.)
    one_way = sum(x is not None for x in (semi_axes, type_semi_axes, q)) == 1
    if typeid is not None:
        if semi_axes is not None and one_way:
            raise ValueError("typeid is given with semi_axes, which it would not change: typeid goes with "
                             "type_semi_axes (the semi-axes of each type)")
        typeid = _typeid_array(typeid)
    if orientations is not None and q is not None and one_way:
        raise ValueError("orientations are given with q, which they would not change: the forms q hold "
                         "the orientations (orientations go with semi_axes or type_semi_axes)")
    b = _as_box(box)
    positions = _real_array(positions)
    if b is not None and b.is2D:
        _check_in_plane(positions, orientations)
    return positions, semi_axes, type_semi_axes, typeid, b


class DistributedScreenResult:
    """The pairs a screen over MPI ranks found (``screen(..., comm=...)``).

    ``pairs`` (M, 2) uint64 of global ids (tags), each (i, j) with i < j,
    sorted: this rank's pairs under the owner rule (every pair of the scene
    on exactly one rank), or with ``gather=True`` every pair on rank 0 (and
    none on the others), in the order screen() gives for particles indexed
    by tag; ``mu2`` (M,) when asked for (else None); ``report`` (a dict: the
    grid of ranks, this rank's place in it, particles owned, ghosts
    received, bytes sent, seconds of each stage).
    """

    def __init__(self, raw: dict):
        self.pairs = raw["pairs"]
        self.mu2 = raw["mu2"]
        self.report = raw["report"]

    def __len__(self) -> int:
        return len(self.pairs)


def screen(positions, orientations=None, semi_axes=None, *, q=None, type_semi_axes=None, typeid=None,
           box=None, cutoff: float = 1.0, with_mu2: bool = False, threads: int = 0,
           comm=None, tags=None, gather: bool = False, workspace: "ScreenWorkspace" = None,
           **ignored) -> Union[ScreenResult, DistributedScreenResult]:
    """Every pair of particles with mu < cutoff, exactly (cell lists, exact
    prefilters, the batch kernels on what they leave).

    positions (N, 3); the shapes one way: ``semi_axes`` (N, 3), or (3,) for
    one shape (searched as identical shapes), with ``orientations`` (N, 4)
    quaternions (w, x, y, z) (default: identity); or ``type_semi_axes`` (T, 3)
    with ``typeid`` (N,) (as GSD gives shapes per type; also accepted as
    ``semi_axes=(type_semi_axes, typeid)``); or ``q`` (N, 6) forms. typeid
    must be integers, none negative; beside semi_axes, or orientations
    beside q, would change nothing and are refused (ValueError); typeid
    beside q (as read_lammps_* return them) is accepted and ignored. In a 2D
    box the particles are ellipses in the z = 0 plane: z must be 0 and every
    orientation a rotation about z (ValueError naming the particle
    otherwise), the third semi-axis at most the smaller of the other two. box: None (open), a Box, or anything Box.from_box takes.
    cutoff >= 1 reports near pairs too (mu < cutoff). Keyword arguments that
    read_gsd / read_lammps_* return beside these (type_names, frame, ...)
    are accepted and ignored, so that ``screen(**read_gsd(path))`` works.

    comm: an mpi4py communicator (python3-mpi4py; a module built with MPI:
    ``pwcontact.with_mpi`` is True): a collective call, every rank passing the
    particles it holds (anywhere in the box) with their global ``tags`` (N,)
    (non-negative integers, each given once over the ranks; default:
    numbered by rank, rank 0's first); returns a DistributedScreenResult
    (pairs in tags; ``gather=True``: all of them on rank 0). box, cutoff,
    with_mu2 and gather must be the same on every rank (ValueError on every
    rank otherwise); threads is per rank. An error in any rank's input is
    raised on every rank: that rank's own exception there, a ValueError
    naming the rank on the others.

    workspace: a ScreenWorkspace kept across calls (a simulation screening
    every so many steps), whose memory each screen reuses (with comm: each
    rank's local screen, a workspace per rank); the same pairs.
    """
    if comm is not None:
        if not _core.with_mpi:
            raise RuntimeError("screen(comm=...): this pwcontact was built without MPI "
                               "(PWCONTACT_BUILD_MPI, with libopenmpi-dev installed)")
        if not hasattr(comm, "py2f"):
            raise TypeError(f"comm must be an mpi4py communicator, got {type(comm).__name__}")
        # This rank's arguments are checked here and in the core before any
        # collective call; an error is raised on every rank (this rank's own
        # exception here, a ValueError naming the rank elsewhere), never on
        # one rank alone while the others wait.
        local_error = None
        try:
            positions, semi_axes, type_semi_axes, typeid, b = _scene_arguments(
                "screen", positions, orientations, semi_axes, type_semi_axes, typeid, box, ignored,
                q)
            if workspace is not None and not isinstance(workspace, ScreenWorkspace):
                raise TypeError(f"workspace must be a ScreenWorkspace, got {type(workspace).__name__}")
            if tags is not None:
                tags = _integer_array(tags, "tags")
                if tags.size and tags.min() < 0:
                    raise ValueError(f"tags must be non-negative integers, got {tags.min()}")
            arguments = (positions, orientations, semi_axes, q, type_semi_axes, typeid,
                         None if b is None else b._core(), float(cutoff), bool(with_mu2),
                         _threads(threads), int(comm.py2f()), tags, bool(gather),
                         None if workspace is None else workspace._workspace)
        except BaseException as e:  # (any: OverflowError, MemoryError, KeyboardInterrupt)
            local_error = e
            arguments = (None, None, None, None, None, None, None, 1.0, False, 1,
                         int(comm.py2f()), None, False, None)
        try:
            raw = _core.screen_mpi(*arguments, "" if local_error is None else
                                   f"{type(local_error).__name__}: {local_error}")
        except ValueError:
            if local_error is not None:
                raise local_error from None
            raise
        if local_error is not None:  # (no rank failed in the core's agreement: cannot be)
            raise local_error
        return DistributedScreenResult(raw)
    positions, semi_axes, type_semi_axes, typeid, b = _scene_arguments(
        "screen", positions, orientations, semi_axes, type_semi_axes, typeid, box, ignored, q)
    if workspace is not None and not isinstance(workspace, ScreenWorkspace):
        raise TypeError(f"workspace must be a ScreenWorkspace, got {type(workspace).__name__}")
    kept = None if workspace is None else workspace._workspace
    if tags is not None or gather:
        raise ValueError("tags and gather are for screen(comm=...) over MPI ranks")
    raw = _core.screen(positions, orientations, semi_axes, q, type_semi_axes, typeid,
                       None if b is None else b._core(), float(cutoff), bool(with_mu2), _threads(threads),
                       kept)
    return ScreenResult(raw, positions, b)


class ScreenWorkspace:
    """Memory one screen leaves for the next: pass the same workspace to
    screen(..., workspace=...) in a loop, and each call after the first
    reuses the cell lists' copies of the particles and the buffers of the
    one before (about 155 bytes a particle) instead of fresh pages. The
    answers are the same. It holds that memory until release() or its end
    (``bytes`` says how much); one screen at a time (a second call from
    another thread meanwhile, or release() during one, raises
    RuntimeError). With screen(comm=...),
    each rank passes its own.
    """

    def __init__(self):
        self._workspace = _core.ScreenWorkspace()

    @property
    def bytes(self) -> int:
        """The memory held, in bytes, as of the end of the last screen in
        this workspace (0 when new or released). Asked while a screen runs
        in it (from another thread or its progress callback), it gives that
        figure, not the memory the running screen is growing."""
        return self._workspace.bytes

    def release(self) -> None:
        """Frees the memory held (the next screen asks for fresh pages)."""
        self._workspace.release()


class HardParticleMC:
    """Hard-particle Monte Carlo in a periodic box (NVT, translation and
    rotation moves, Metropolis for hard particles, a fixed seed) on a
    MovingScene: the library's example of trial moves, as the command line's
    ``pwcontact mc`` runs it. A sweep proposes one move per particle, by
    checkerboard domains over ``threads`` threads; it never holds an overlap.

    positions (N, 3), semi_axes (N, 3 | 3,), orientations (N, 4 | 4, | None:
    identity), box: a periodic three-dimensional Box (or what Box.from_box
    takes). The start may overlap (overlapping_pairs() tells): a sweep never
    makes an overlap but keeps those it is given, and compress() raises
    RuntimeError on an overlapping state. Orientations are normalised (those
    unit to rounding kept as given). packing: the
    fraction compress_to_packing() reaches; translation and rotation: the
    largest step along each axis and the largest turn (radians), scaled
    towards 30 % acceptance after each sweep when adapt_steps.
    """

    def __init__(self, positions, orientations=None, semi_axes=None, *, box=None, packing: float = 0.5,
                 translation: float = 0.1, rotation: float = 0.1, adapt_steps: bool = True,
                 seed: int = 1, threads: int = 0, _core_mc=None):
        if _core_mc is not None:
            self._mc = _core_mc
            return
        if semi_axes is None:
            raise ValueError("HardParticleMC needs semi_axes (N, 3) or (3,)")
        b = _as_box(box)
        if b is None or b.is2D or not b.periodic:
            raise ValueError("HardParticleMC needs a periodic three-dimensional box")
        self._mc = _core.HardParticleMC(_real_array(positions), orientations, semi_axes, b._core(),
                                        float(packing), float(translation), float(rotation), bool(adapt_steps),
                                        _integer(seed, "seed", 0, _UINT64_MAX), _threads(threads))

    @classmethod
    def dilute_spheroids(cls, n: int, seed: int = 1, max_aspect: float = 3.0, *, packing: float = 0.5,
                         translation: float = 0.1, rotation: float = 0.1, adapt_steps: bool = True,
                         threads: int = 0, shapes: int = 0) -> "HardParticleMC":
        """n spheroids (aspect ratios 1/max_aspect .. max_aspect, the volume
        of a sphere of radius 0.5) on a dilute lattice, none overlapping.
        shapes: 0, every spheroid an aspect ratio of its own (log-uniform);
        k > 0, drawn from k log-spaced over the range. ``pwcontact mc --n N
        --seed S`` starts from dilute_spheroids(N, S, shapes=16). n >= 1,
        seed >= 0 and shapes >= 0 integers, max_aspect as spheroid_scene
        takes it (ValueError naming the argument)."""
        return cls(None, _core_mc=_core.HardParticleMC.dilute_spheroids(
            _integer(n, "n", 1), _integer(seed, "seed", 0, _UINT64_MAX), _max_aspect(max_aspect),
            float(packing), float(translation), float(rotation), bool(adapt_steps), _threads(threads),
            _integer(shapes, "shapes", 0, 2**32)))

    def sweep(self) -> dict:
        """One move proposed per particle: {proposed, accepted, left_domain
        (rejected for leaving their domain), deferred (accepted moves into a
        full cell, applied after their colour of the checkerboard), seconds}."""
        return self._mc.sweep()

    def compress(self) -> float:
        """The box and centres scaled down as far as the closest pair allows
        (never an overlap); returns the packing fraction."""
        return self._mc.compress()

    def compress_to_packing(self, max_sweeps: int = 100000, progress=None) -> None:
        """Sweeps and compressions until the packing fraction given is
        reached (RuntimeError after max_sweeps short of it; max_sweeps a
        non-negative integer); progress(sweeps, packing, acceptance) after
        each sweep. ValueError before any sweep when the box at that
        packing fraction would be narrower than twice 1.1 times the largest
        diameter, which the screens after each sweep need (too few
        particles for it)."""
        self._mc.compress_to_packing(_integer(max_sweeps, "max_sweeps", 0), progress)

    def overlapping_pairs(self) -> int:
        """The pairs with mu < 1, by a full screen (0 for every state a sweep
        leaves)."""
        return self._mc.overlapping_pairs()

    def scene(self) -> dict:
        """The state as the keyword arguments of screen (positions,
        orientations, semi_axes, box)."""
        raw = self._mc.state()
        return {"positions": raw["positions"], "orientations": raw["orientations"],
                "semi_axes": raw["semi_axes"], "box": _box_of(raw["box"])}

    @property
    def packing(self) -> float:
        return self._mc.numbers()["packing"]

    @property
    def translation(self) -> float:
        return self._mc.numbers()["translation"]

    @property
    def rotation(self) -> float:
        return self._mc.numbers()["rotation"]

    @property
    def sweeps(self) -> int:
        return self._mc.numbers()["sweeps"]


class SkinNeighborList:
    """The pairs with mu < cutoff, step after step (anisotropic molecular
    dynamics: Gay-Berne, RE-squared), from a list of the pairs with
    mu < cutoff + skin that is kept while no particle has moved or turned
    beyond what the skin allows, and rebuilt (a screen) otherwise.

    The criterion is safe whatever the shapes: since the last rebuild
    particle i has moved by d_i and its form changed by |Q_i' - Q_i|_F; with
    rho_i its inscribed radius, m_i = (d_i + cutoff |Q_i' - Q_i|_F / (2 rho_i))
    / rho_i, and the list is kept while every m_i <= skin (README, "A scene
    that moves"). A kept list's pairs are solved again from the lambda each
    had at the last step (warm_start), in about half the evaluations.

    cutoff >= 1 and skin > 0, both finite (ValueError otherwise); threads:
    0 for all. update() takes the particles as screen() does and returns a
    ScreenResult with mu2 (pairs i < j, sorted), whose report says whether
    the list was rebuilt, the largest m_i since the last rebuild, the pairs
    listed, solved and found, the evaluations per solved pair and the
    seconds taken. A change of the particle count or of the box rebuilds.
    """

    def __init__(self, cutoff: float = 1.5, skin: float = 0.2, *, warm_start: bool = True,
                 threads: int = 0):
        self._list = _core.SkinNeighborList(float(cutoff), float(skin), bool(warm_start), _threads(threads))
        self.cutoff = float(cutoff)
        self.skin = float(skin)

    def update(self, positions, orientations=None, semi_axes=None, *, q=None, type_semi_axes=None,
               typeid=None, box=None, **ignored) -> ScreenResult:
        """The pairs with mu < cutoff of the particles as they are now."""
        positions, semi_axes, type_semi_axes, typeid, b = _scene_arguments(
            "update", positions, orientations, semi_axes, type_semi_axes, typeid, box, ignored, q)
        raw = self._list.update(positions, orientations, semi_axes, q, type_semi_axes, typeid,
                                None if b is None else b._core())
        return ScreenResult(raw, positions, b)

    @property
    def rebuilds(self) -> int:
        """How many updates rebuilt the list (the first one included)."""
        return self._list.rebuilds

    def __repr__(self) -> str:
        return f"SkinNeighborList(cutoff={self.cutoff!r}, skin={self.skin!r}, rebuilds={self.rebuilds})"


def _gsd_frame(trajectory, frame: int):
    frame = _integer(frame, "frame")
    n = len(trajectory)
    if n == 0:
        raise ValueError("the GSD file has no frames")
    index = frame if frame >= 0 else n + frame
    if not 0 <= index < n:
        raise ValueError(f"frame {frame} is not in the file ({n} frames)")
    return trajectory[index], index, n


def read_gsd(path: str, frame: int = -1) -> dict:
    """Frame `frame` (negative: from the end) of a GSD file, read with the
    gsd package (python3-gsd; Snapshot and Frame APIs), as the keyword
    arguments of screen: positions, orientations (w, x, y, z),
    type_semi_axes (from particles/type_shapes: Ellipsoid a, b, c; Sphere
    diameter / 2; in 2D Ellipse or Ellipsoid a, b), typeid, box (a Box:
    configuration/box, 2D by configuration/dimensions), with type_names and
    frame. ValueError names the file, frame and type of a shape it cannot
    take, or a file that is not GSD; FileNotFoundError, a file that does
    not exist."""
    import errno
    import os

    import gsd.hoomd

    # (gsd 2.7 reports a missing file as "Bad file descriptor" and a file
    # of another kind as a RuntimeError: named here as the other readers
    # name them.)
    if not os.path.exists(path):
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), path)
    try:
        opened = gsd.hoomd.open(path, "rb")
    except RuntimeError as e:
        raise ValueError(f"{path}: {e}") from None
    with opened as trajectory:
        snap, index, frames = _gsd_frame(trajectory, frame)
        particles = snap.particles

        def whole(values, name):
            # The schema's unsigned integers, stored as another type: taken
            # where each is a whole number uint32 holds, refused naming the
            # chunk otherwise, as the C++ reader (a typeid of 2**32 + 1 was
            # read as 1, of 0.9 as 0, without a word).
            a = np.atleast_1d(np.asarray(values))
            if a.dtype.kind == "f":
                bad = ~(np.isfinite(a) & (a >= 0) & (a < 2.0**32) & (a == np.floor(a)))
            elif a.dtype.kind in "iu":
                bad = (a < 0) | (a > 2**32 - 1)
            else:
                bad = np.ones(a.shape, dtype=bool)
            if bad.any():
                k = int(np.flatnonzero(bad)[0])
                raise ValueError(f"{path}: frame {index}: {name}, row {k}: {a[k]!r} is not a whole "
                                 f"number from 0 to 4294967295")
            return a.astype(np.uint32)

        n = int(whole(particles.N, "particles/N")[0])
        types = list(particles.types) if particles.types is not None else ["A"]
        shapes = list(particles.type_shapes) if particles.type_shapes is not None else []
        dimensions = (int(whole(snap.configuration.dimensions, "configuration/dimensions")[0])
                      if snap.configuration.dimensions is not None else 3)
        axes = []
        for t, name in enumerate(types):
            shape = shapes[t] if t < len(shapes) else {}
            kind = shape.get("type") if isinstance(shape, Mapping) else None
            def number(key):
                # (A number, as the C++ reader takes it: not a string, not absent.)
                v = shape.get(key)
                if isinstance(v, (bool, str)) or not isinstance(v, numbers.Real):
                    raise ValueError(f"{path}: frame {index}: the {kind} shape of type {name!r} needs "
                                     f"a number {key!r} in particles/type_shapes (got {shape!r})")
                return float(v)
            if kind == "Ellipsoid" or (kind == "Ellipse" and dimensions == 2):
                a, b = number("a"), number("b")
                # (In 2D the third semi-axis does not change mu: min(a, b), as the C++ reader.)
                c = min(a, b) if dimensions == 2 else number("c")
                axes.append([a, b, c])
            elif kind == "Sphere":
                r = number("diameter") / 2
                axes.append([r, r, r])
            else:
                raise ValueError(f"{path}: frame {index}: type {name!r} has no Ellipsoid or Sphere shape "
                                 f"(or Ellipse in 2D) in particles/type_shapes (got {shape!r})")
        position = np.asarray(particles.position, dtype=float).reshape(n, 3)
        orientation = (np.asarray(particles.orientation, dtype=float).reshape(n, 4)
                       if particles.orientation is not None else np.tile([1.0, 0, 0, 0], (n, 1)))
        typeid = (whole(particles.typeid, "particles/typeid")
                  if particles.typeid is not None else np.zeros(n, dtype=np.uint32))
        box = Box.from_box(list(snap.configuration.box), dimensions=dimensions)
    return {"positions": position, "orientations": orientation, "type_semi_axes": np.array(axes),
            "typeid": typeid, "box": box, "type_names": types, "frame": index}


def _box_of(raw) -> Optional[Box]:
    """The Box of the compiled core's (Lx, Ly, Lz, xy, xz, yz, dimensions,
    periodic); None for an open box."""
    lx, ly, lz, xy, xz, yz, dimensions, periodic = raw
    return Box(lx, ly, lz, xy, xz, yz, is2D=dimensions == 2) if periodic else None


def _readable(path) -> str:
    """The path as a string, once opened for reading: a file that cannot be
    read raises OSError here (FileNotFoundError when it does not exist),
    as python3-gsd's open does for read_gsd, not the C++ readers'
    RuntimeError."""
    path = str(path)
    with open(path, "rb"):
        pass
    return path


def _scene(raw: dict) -> dict:
    return {"positions": raw["positions"], "q": raw["q"], "box": _box_of(raw["box"]), "typeid": raw["typeid"],
            "type_names": raw["type_names"], "id": raw["id"], "frame": raw["frame"]}


def read_lammps_data(path: str) -> dict:
    """A LAMMPS data file of atom_style ellipsoid (the C++ reader: shapes are
    diameters there, tilts lengths), as the keyword arguments of screen:
    positions, q (forms), box, with typeid, type_names and id (atom ids).
    OSError (FileNotFoundError) for a file that cannot be opened."""
    return _scene(_core.read_lammps_data(_readable(path)))


def read_lammps_dump(path: str, frame: int = -1, columns: Optional[Mapping[str, str]] = None) -> dict:
    """Frame `frame` (negative: from the end) of a LAMMPS text dump (dump
    custom with positions, shapes as diameters, and quaternions), as
    read_lammps_data. Columns are found by their usual names (x y z or xu yu
    zu, shapex shapey shapez, quatw quati quatj quatk); ``columns`` maps
    those names to others, e.g. {"shapex": "c_s[1]", ...} for a compute's."""
    return _scene(_core.read_lammps_dump(_readable(path), _integer(frame, "frame"), dict(columns or {})))


def read_gsd_native(path: str, frame: int = -1) -> dict:
    """The same frame through the library's own C++ GSD reader (forms q, not
    semi-axes), as read_lammps_data: for comparing with `pwcontact screen`."""
    return _scene(_core.read_gsd(_readable(path), _integer(frame, "frame")))


# The largest max_aspect of the generated scenes: beyond ~1e7 the thinnest
# spheroids' forms are no longer positive definite in double.
_MAX_ASPECT = 1e6


def _max_aspect(max_aspect) -> float:
    a = float(max_aspect)
    if not 1 <= a <= _MAX_ASPECT:
        raise ValueError(f"max_aspect must be in 1 .. {_MAX_ASPECT:g}, got {max_aspect!r}")
    return a


def spheroid_scene(n: int, seed: int = 1, packing: float = 0.3, max_aspect: float = 3.0) -> dict:
    """The demo scene: n random spheroids (aspect 1/max_aspect .. max_aspect,
    volume of a sphere of radius 0.5) in a periodic cube at the packing
    fraction, as the keyword arguments of screen. n in 1 .. 2**31 - 1 and
    seed >= 0 integers; packing in (0, 1) (total spheroid volume over box volume, as
    ``pwcontact demo --packing``); max_aspect in 1 .. 1e6 (ValueError naming
    the argument otherwise)."""
    p = float(packing)
    if not 0 < p < 1:
        raise ValueError(f"packing must be in (0, 1), got {packing!r}")
    raw = _core.spheroid_scene(_integer(n, "n", 1, 2**31 - 1), _integer(seed, "seed", 0, _UINT64_MAX), p,
                               _max_aspect(max_aspect))
    return {"positions": raw["positions"], "orientations": raw["orientations"],
            "semi_axes": raw["semi_axes"], "box": _box_of(raw["box"])}


class MovingScene:
    """A scene kept between calls for trial moves (Monte Carlo): insert,
    remove, move in O(1), and queries of a trial particle against every
    stored one. Built from the particles' arguments of screen, checked as
    screen checks them: positions and one of semi_axes + orientations,
    type_semi_axes + typeid (or semi_axes=(type_semi_axes, typeid)), q;
    box; the keywords read_gsd / read_lammps_* return beside them accepted
    and ignored (so that ``MovingScene(**read_gsd(path))`` works), any other
    keyword a TypeError. In a 2D box every centre, stored or trial, has
    z = 0 and every orientation is a rotation about z (ValueError naming the
    particle, row or trial otherwise).

    A trial particle is given by ``position`` and one of ``semi_axes`` (with
    ``orientation``), ``q`` (no orientation: the form holds it), or
    ``typeid`` (a non-negative integer, with ``orientation``). ``exclude``
    is None or -1 (no particle excluded) or the index of a stored particle
    (IndexError naming it and the scene's size for one that does not
    exist); indices and type ids that are not integers are a ValueError.
    """

    none = None

    def __init__(self, positions, orientations=None, semi_axes=None, *, q=None, type_semi_axes=None,
                 typeid=None, box=None, **ignored):
        positions, semi_axes, type_semi_axes, typeid, b = _scene_arguments(
            "MovingScene", positions, orientations, semi_axes, type_semi_axes, typeid, box, ignored, q)
        self._box = b
        self._scene = _core.MovingScene(positions, orientations, semi_axes, q, type_semi_axes, typeid,
                                        None if b is None else b._core())

    def __len__(self) -> int:
        return len(self._scene)

    def _two_dimensional(self) -> bool:
        return self._box is not None and self._box.is2D

    def _trial(self, position, orientation, semi_axes, q, typeid):
        if orientation is not None and q is not None:
            raise ValueError("orientation is given with q, which it would not change: the form q holds the "
                             "orientation")
        if typeid is not None:
            typeid = _integer(typeid, "typeid", 0, 2**32 - 1)
        if self._two_dimensional():
            _check_in_plane(position, orientation, "trial")
        return self._scene.trial(position, orientation, semi_axes, q, typeid)

    def _rows(self, positions, orientations, q, row: str) -> np.ndarray:
        """The rows of overlaps_many / move_many, checked as a trial's."""
        if orientations is not None and q is not None:
            raise ValueError("orientations are given with q, which they would not change: the forms q hold "
                             "the orientations")
        positions = _real_array(positions)
        if self._two_dimensional():
            _check_in_plane(positions, orientations, row)
        return positions

    @staticmethod
    def _exclude(exclude) -> int:
        # (A single query's exclude is checked against the scene by the
        # binding, while it holds the scene: here only its kind, with the
        # common case, a Python int, first: a query costs a few microseconds.)
        if exclude is None:
            return -1
        if type(exclude) is not int:
            exclude = _integer(exclude, "exclude")
        if not -2**63 <= exclude < 2**63:
            raise IndexError(f"exclude: particle {exclude} does not exist")
        return exclude

    def overlaps(self, position, orientation=None, semi_axes=None, *, q=None, typeid=None,
                 exclude: Optional[int] = None) -> Optional[int]:
        """The index of a particle the trial overlaps (mu < 1), the first in
        the scene's search order, or None; `exclude` is the index the trial
        would replace."""
        i = self._scene.overlaps(self._trial(position, orientation, semi_axes, q, typeid),
                                 self._exclude(exclude))
        return None if i < 0 else int(i)

    def overlap_count(self, position, orientation=None, semi_axes=None, *, q=None, typeid=None,
                      exclude: Optional[int] = None) -> int:
        """How many stored particles the trial overlaps."""
        return self._scene.overlap_count(self._trial(position, orientation, semi_axes, q, typeid),
                                         self._exclude(exclude))

    def neighbors(self, position, orientation=None, semi_axes=None, *, q=None, typeid=None,
                  cutoff: float = 1.0, with_mu2: bool = False,
                  exclude: Optional[int] = None) -> Tuple[np.ndarray, np.ndarray]:
        """(indices, mu2) of every stored particle with mu < cutoff (mu2 NaN
        unless with_mu2)."""
        return self._scene.neighbors(self._trial(position, orientation, semi_axes, q, typeid), float(cutoff),
                                     bool(with_mu2), self._exclude(exclude))

    def overlaps_many(self, positions, orientations=None, semi_axes=None, *, q=None, exclude=None,
                      threads: int = 0) -> np.ndarray:
        """Many independent trials at once (e.g. one per domain of a
        checkerboard sweep): for each row, the index of a particle it
        overlaps (as overlaps() would answer it) or -1; identical to the
        single queries whatever the thread count. positions (M, 3 | 3,);
        shapes by semi_axes (M, 3 | 3,) with orientations (M, 4 | 4,), or q
        (M, 6 | 6,): M is the arrays' common row count, a single row
        broadcast against the others (ValueError naming the arrays whose
        row counts differ); exclude (M,) integers (-1: none; IndexError
        for one that does not exist). Returns (M,) int64."""
        positions = self._rows(positions, orientations, q, "trial")
        if exclude is not None:
            exclude = _integer_array(exclude, "exclude")
            n = len(self._scene)
            if exclude.ndim == 1:
                bad = np.flatnonzero((exclude < -1) | (exclude >= n))
                if len(bad):
                    raise IndexError(f"exclude[{bad[0]}]: particle {exclude[bad[0]]} does not exist "
                                     f"({n} particles; -1: none)")
        return self._scene.overlaps_many(positions, orientations, semi_axes, q, exclude, _threads(threads))

    def move_many(self, indices, positions, orientations=None, semi_axes=None, *, q=None,
                  threads: int = 0) -> None:
        """Moves particles indices[k] to rows k of positions, with shapes by
        semi_axes (M, 3 | 3,) with orientations (M, 4 | 4,), or q (M, 6 | 6,)
        (rows broadcast as in overlaps_many), as move() one after another
        would. Moves whose old and new cells are distinct from those of
        every other move (one per domain of a checkerboard sweep) run on
        `threads` threads (0: all); otherwise in order, in one thread. Every
        move is checked first: ValueError for indices that are not integers,
        IndexError for an index that does not exist, ValueError for a shape
        the store refuses, each naming the move, and the scene unchanged."""
        indices = _integer_array(indices, "indices")
        # (Checked here as Python integers: a uint64 index above 2**63 would
        # reach the core as a negative one.)
        bad = np.flatnonzero((indices < 0) | (indices >= len(self._scene))) if indices.size else []
        if len(bad):
            k = int(bad[0])
            raise IndexError(f"move {k}: particle {int(indices.flat[k])} does not exist "
                             f"({len(self._scene)} particles)")
        positions = self._rows(positions, orientations, q, "move")
        self._scene.move_many(indices, positions, orientations, semi_axes, q, _threads(threads))

    def insert(self, position, orientation=None, semi_axes=None, *, q=None, typeid=None) -> int:
        """Stores a particle; returns its index (len(scene) - 1)."""
        return self._scene.insert(self._trial(position, orientation, semi_axes, q, typeid))

    def _index(self, i) -> int:
        i = _integer(i, "the particle's index")
        if i < 0 or i >= len(self._scene):
            raise IndexError(f"particle {i} does not exist ({len(self._scene)} particles)")
        return i

    def remove(self, i: int) -> int:
        """Removes particle i; the last particle takes its index. Returns the
        index that moved to i (or i when it was the last). IndexError for an
        index that does not exist."""
        return self._scene.remove(self._index(i))

    def move(self, i: int, position, orientation=None, semi_axes=None, *, q=None, typeid=None) -> None:
        """Particle i's new centre and shape (IndexError for an index that does
        not exist, ValueError for a shape the store refuses; unchanged then)."""
        self._scene.move(self._index(i), self._trial(position, orientation, semi_axes, q, typeid))

    @property
    def positions(self) -> np.ndarray:
        return self._scene.positions()

    @property
    def q(self) -> np.ndarray:
        return self._scene.q()
