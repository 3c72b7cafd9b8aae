"""contact_function, overlap and quadratic_form from numpy."""
import threading
import time

import numpy as np
import pytest

import pwcontact as pw

# The batch path's documented accuracy on each oracle family (the same
# tolerances as tests/reference_data_test.cpp, whose comments derive them):
# relative on mu2, absolute on lambda.
TOLERANCE = {"random": (1e-13, 1e-13), "pw85": (2e-11, 1e-10), "spread": (2e-9, 1e-8)}


@pytest.mark.parametrize("family", sorted(TOLERANCE))
@pytest.mark.parametrize("isa", pw.supported_isas())
def test_double_answers_match_the_quad_precision_oracle(reference_pairs, family, isa):
    r12, q1, q2, mu2, lam = reference_pairs[family]
    r = pw.contact_function(r12, q1, q2, isa=isa)
    assert r.mu2.dtype == np.float64
    assert np.all(pw.is_valid(r.status))
    mu2_tol, lambda_tol = TOLERANCE[family]
    assert np.max(np.abs(r.mu2 - mu2) / mu2) <= mu2_tol
    assert np.max(np.abs(r.lambda_ - lam)) <= lambda_tol
    assert r.pairs == len(mu2) and r.isa == isa


def test_float32_pairs_stay_float32_and_are_accurate_to_float(reference_pairs):
    r12, q1, q2, mu2, _ = reference_pairs["random"]
    r = pw.contact_function(r12.astype(np.float32), q1.astype(np.float32), q2.astype(np.float32))
    assert r.mu2.dtype == np.float32 and r.lambda_.dtype == np.float32
    assert r.precision == "float"
    valid = pw.is_valid(r.status)
    assert valid.all()
    # The pairs as rounded to float differ from the oracle's by ~1e-7
    # relative in every number; mu2 moves by a few times that (cond(Q) <= 16).
    assert np.max(np.abs(r.mu2 - mu2) / mu2) < 1e-5
    # precision="double" on float32 pairs computes in double (float64 results).
    d = pw.contact_function(r12.astype(np.float32), q1.astype(np.float32), q2.astype(np.float32),
                            precision="double")
    assert d.mu2.dtype == np.float64


def test_geometry_outputs_satisfy_the_contact_conditions():
    rng = np.random.default_rng(5)
    n = 500
    axes = rng.uniform(0.5, 2, (n, 3))
    quat = rng.normal(size=(n, 4))
    q1 = pw.quadratic_form(axes, quat)
    q2 = pw.quadratic_form(rng.uniform(0.5, 2, (n, 3)), rng.normal(size=(n, 4)))
    r12 = rng.normal(size=(n, 3)) * 3
    r = pw.contact_function(r12, q1, q2, outputs=("mu2", "lambda", "contact_point", "normal", "gradient"))
    assert r.contact_point.shape == (n, 3) and r.normal.shape == (n, 3)
    # The contact point lies on ellipsoid 1 scaled by mu: x^T Q1^-1 x = mu^2.
    full = np.zeros((n, 3, 3))
    idx = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    for k, (a, b) in enumerate(idx):
        full[:, a, b] = full[:, b, a] = q1[:, k]
    x = r.contact_point
    on_surface = np.einsum("ni,ni->n", x, np.linalg.solve(full, x[..., None])[..., 0])
    assert np.max(np.abs(on_surface - r.mu2) / r.mu2) < 1e-9
    assert np.max(np.abs(np.linalg.norm(r.normal, axis=1) - 1)) < 1e-12


def test_mu2_only_and_lambda_keys():
    r = pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(0.5), outputs=("mu2",))
    assert "lambda" not in r and "mu2" in r
    assert r.mu2 == pytest.approx([(2 / 1.5) ** 2], rel=1e-15)
    r = pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(0.5), outputs=("lambda",))
    assert "mu2" not in r and r["lambda"][0] == pytest.approx(1 / 1.5, rel=1e-14)


def test_shape_and_option_errors_are_value_errors():
    q = pw.sphere(1)
    with pytest.raises(ValueError, match=r"r12 must have shape \(N, 3\)"):
        pw.contact_function(np.zeros((4, 4)), q, q)
    with pytest.raises(ValueError, match="q1 must have shape"):
        pw.contact_function(np.ones((4, 3)), np.ones((4, 5)), q)
    with pytest.raises(ValueError, match="different lengths"):
        pw.contact_function(np.ones((4, 3)), np.tile(q, (3, 1)), q)
    with pytest.raises(ValueError, match="unknown output"):
        pw.contact_function(np.ones((4, 3)), q, q, outputs=("mu3",))
    with pytest.raises(ValueError, match="precision"):
        pw.contact_function(np.ones((4, 3)), q, q, precision="quad")
    with pytest.raises(ValueError, match="iterations"):
        pw.contact_function(np.ones((4, 3)), q, q, iterations=-1)
    with pytest.raises(ValueError, match="threads"):
        pw.contact_function(np.ones((4, 3)), q, q, threads=-1)
    with pytest.raises(ValueError, match="cutoff"):
        pw.overlap(np.ones((4, 3)), q, q, cutoff=0)
    with pytest.raises(ValueError):
        pw.contact_function(np.array([["a", "b", "c"]]), q, q)


def test_broadcast_and_non_contiguous_inputs_give_the_same_bits(reference_pairs):
    r12, q1, q2, _, _ = reference_pairs["pw85"]
    base = pw.contact_function(r12, q1, q2)
    # Fortran order, a strided view, and a one-row broadcast against its tiling.
    f = pw.contact_function(np.asfortranarray(r12), np.asfortranarray(q1), q2)
    assert np.array_equal(f.mu2, base.mu2) and np.array_equal(f.lambda_, base.lambda_)
    wide = np.zeros((len(r12), 6))
    wide[:, ::2] = r12[:, [0, 0, 1]]
    wide[:, 1::2] = r12[:, [1, 2, 2]]
    strided = wide[:, [0, 1, 3]]  # a copy by fancy indexing: build a real strided view instead
    view = np.lib.stride_tricks.as_strided(wide, shape=(len(r12), 3), strides=(wide.strides[0], 16))
    view_values = np.stack([wide[:, 0], wide[:, 2], wide[:, 4]], axis=1)
    s = pw.contact_function(view, q1, q2)
    e = pw.contact_function(view_values, q1, q2)
    assert np.array_equal(s.mu2, e.mu2)
    one = pw.contact_function(r12, q1[7], q2)
    tiled = pw.contact_function(r12, np.tile(q1[7], (len(r12), 1)), q2)
    assert np.array_equal(one.mu2, tiled.mu2)
    del strided


@pytest.mark.parametrize("isa", pw.supported_isas())
def test_rows_read_backwards_and_odd_strides_give_the_bits_of_copies(reference_pairs, isa):
    # Every layout is read in place (the kernels' strided loads): reversed
    # rows (negative strides), and rows whose stride is not a whole number of
    # elements (read through a copy) answer as contiguous copies do, bit for bit.
    r12, q1, q2, _, _ = reference_pairs["random"]
    q1 = q1.copy()
    q1[::37, 0] = -1.0  # invalid pairs among the valid: statuses
    back = pw.contact_function(r12[::-1], q1[::-1], q2[::-1], isa=isa, outputs=("mu2", "lambda", "normal"))
    copy = pw.contact_function(np.ascontiguousarray(r12[::-1]), np.ascontiguousarray(q1[::-1]),
                               np.ascontiguousarray(q2[::-1]), isa=isa, outputs=("mu2", "lambda", "normal"))
    for name in ("mu2", "lambda_", "status", "normal"):
        assert np.array_equal(getattr(back, name), getattr(copy, name), equal_nan=name != "status"), name
    assert (back.status != 0).sum() > 0
    o_back = pw.overlap(r12[::-1], q1[::-1], q2[::-1], isa=isa)
    o_copy = pw.overlap(np.ascontiguousarray(r12[::-1]), np.ascontiguousarray(q1[::-1]),
                        np.ascontiguousarray(q2[::-1]), isa=isa)
    assert np.array_equal(o_back.overlap, o_copy.overlap) and np.array_equal(o_back.status, o_copy.status)
    # A byte stride of 28, not a whole number of float64: read through a copy
    # (the numbers read are whatever those bytes make; both calls see the same).
    n = 50
    base = np.random.default_rng(3).uniform(-3, 3, 4 * n + 8)
    odd = np.lib.stride_tricks.as_strided(base, shape=(n, 3), strides=(28, 8))
    unit = np.array([1.0, 0, 0, 1, 0, 1])
    a = pw.contact_function(odd, unit, unit, isa=isa)
    b = pw.contact_function(np.ascontiguousarray(odd), unit, unit, isa=isa)
    assert np.array_equal(a.mu2, b.mu2, equal_nan=True) and np.array_equal(a.status, b.status)


@pytest.mark.parametrize("isa", pw.supported_isas())
def test_rows_whose_columns_are_reversed_or_broadcast_give_the_bits_of_copies(reference_pairs, isa):
    # Rows 3 or 6 numbers apart whose columns are not side by side in their
    # order: a C-ordered array's columns reversed (strides (24, -8)), and one
    # column broadcast to (N, 3) (strides (24, 0)). Read as packed rows, the
    # first gave wrong mu2 with status ok from 24 pairs on.
    r12, q1, q2, _, _ = reference_pairs["random"]
    zyx = np.ascontiguousarray(r12[:, ::-1])
    q1_back = np.ascontiguousarray(q1[:, ::-1])
    reversed_views = (zyx[:, ::-1], q1_back[:, ::-1], q2)
    assert reversed_views[0].strides == (24, -8) and reversed_views[1].strides == (48, -8)
    got = pw.contact_function(*reversed_views, isa=isa, outputs=("mu2", "lambda"))
    want = pw.contact_function(r12, q1, q2, isa=isa, outputs=("mu2", "lambda"))
    assert np.array_equal(got.mu2, want.mu2) and np.array_equal(got.lambda_, want.lambda_)
    assert np.array_equal(got.status, want.status)
    o_got, o_want = pw.overlap(*reversed_views, isa=isa), pw.overlap(r12, q1, q2, isa=isa)
    assert np.array_equal(o_got.overlap, o_want.overlap) and np.array_equal(o_got.status, o_want.status)
    column = np.ascontiguousarray(np.repeat(r12[:, :1], 3, axis=1))  # (x, x, x) rows
    broadcast = np.broadcast_to(column[:, :1], (len(r12), 3))
    assert broadcast.strides[1] == 0
    b = pw.contact_function(broadcast, q1, q2, isa=isa)
    c = pw.contact_function(column, q1, q2, isa=isa)
    assert np.array_equal(b.mu2, c.mu2) and np.array_equal(b.status, c.status)


def test_integer_input_is_converted():
    r = pw.contact_function(np.array([[3, 0, 0]]), np.array([1, 0, 0, 1, 0, 1]), np.array([1, 0, 0, 1, 0, 1]))
    assert r.mu2[0] == pytest.approx(2.25, rel=1e-15)


def test_bad_pairs_among_good_ones_are_statuses_not_exceptions(reference_pairs):
    r12, q1, q2, mu2, _ = reference_pairs["random"]
    r12, q1, q2 = r12.copy(), q1.copy(), q2.copy()
    r12[10, 1] = np.nan
    q1[20] = [1, 0, 0, -1, 0, 1]  # indefinite
    q2[30] = [1, 0, 0, 1, 0, 0]  # singular
    r = pw.contact_function(r12, q1, q2)
    assert r.status[10] == pw.Status.non_finite_input
    assert r.status[20] == pw.Status.q1_not_positive_definite
    assert r.status[30] == pw.Status.q2_not_positive_definite
    assert np.isnan(r.mu2[[10, 20, 30]]).all()
    assert r.invalid == 3
    good = np.ones(len(mu2), bool)
    good[[10, 20, 30]] = False
    assert pw.is_valid(r.status[good]).all()
    assert np.max(np.abs(r.mu2[good] - mu2[good]) / mu2[good]) <= 1e-13
    o = pw.overlap(r12, q1, q2)
    assert o.status[10] == pw.Status.non_finite_input and not o.overlap[10]


def test_results_do_not_depend_on_the_thread_count(reference_pairs):
    r12, q1, q2, _, _ = reference_pairs["pw85"]
    big = [np.tile(a, (20, 1)) for a in (r12, q1, q2)]
    one = pw.contact_function(*big, threads=1)
    two = pw.contact_function(*big, threads=2)
    assert np.array_equal(one.mu2, two.mu2) and np.array_equal(one.lambda_, two.lambda_)
    assert np.array_equal(pw.overlap(*big, threads=1).overlap, pw.overlap(*big, threads=2).overlap)


def test_overlap_agrees_with_mu2_away_from_tangency(reference_pairs):
    for family in ("random", "pw85", "spread"):
        r12, q1, q2, mu2, _ = reference_pairs[family]
        for cutoff in (0.5, 1.0, 2.0):
            o = pw.overlap(r12, q1, q2, cutoff)
            # The documented bound: exact beyond 1e-9 of tangency (cond(Q) up to 1e8).
            clear = np.abs(mu2 - cutoff**2) > 1e-9 * cutoff**2
            assert np.array_equal(o.overlap[clear], (mu2 < cutoff**2)[clear])
            assert o.overlap.dtype == np.bool_


def test_quadratic_form_matches_the_rotation_it_names():
    rng = np.random.default_rng(2)
    axes = rng.uniform(0.3, 3, (50, 3))
    quat = rng.normal(size=(50, 4))
    q = pw.quadratic_form(axes, quat)
    u = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    w, x, y, z = u.T
    rot = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)
    m = rot @ (axes[:, :, None] ** 2 * np.transpose(rot, (0, 2, 1)))
    expected = m[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]]
    assert np.max(np.abs(q - expected)) < 1e-12 * np.max(axes) ** 2
    with pytest.raises(ValueError):
        pw.quadratic_form([1, 1, 1], [0, 0, 0, 0])
    with pytest.raises(ValueError, match="particle 0: semi_axes must be positive"):
        pw.quadratic_form([1, -1, 1], [1, 0, 0, 0])
    assert np.allclose(pw.spheroid(1, 2, (0, 0, 1)), [1, 0, 0, 1, 0, 4])


def test_the_gil_is_released_during_a_long_call():
    rng = np.random.default_rng(3)
    n = 2_000_000
    r12 = rng.normal(size=(n, 3)) * 3
    q = pw.quadratic_form(rng.uniform(0.5, 2, (n, 3)), rng.normal(size=(n, 4)))
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    time.sleep(0.01)
    start = time.perf_counter()
    pw.contact_function(r12, q, q[::-1], threads=1)
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # A held GIL would leave the counting thread no tick inside the call
    # (it lasts ~0.1 s; the thread ticks every ~1 ms when it can run).
    assert end - start > 0.02
    assert len(during) >= 3


def test_the_scalar_reference_path_for_one_pair(reference_pairs):
    r12, q1, q2, mu2, lam = reference_pairs["random"]
    for k in range(0, 1000, 97):
        m, l, status = pw.reference(r12[k], q1[k], q2[k])
        assert status == pw.Status.ok
        assert abs(m - mu2[k]) <= 1e-13 * mu2[k] and abs(l - lam[k]) <= 1e-13
    assert pw.reference([1, 0, 0], [1, 0, 0, -1, 0, 1], pw.sphere(1))[2] == pw.Status.q1_not_positive_definite


def test_out_arrays_are_written_in_place_and_checked(reference_pairs):
    r12, q1, q2, _, _ = reference_pairs["random"]
    n = len(r12)
    out = {"mu2": np.empty(n), "lambda": np.empty(n), "status": np.empty(n, np.uint8)}
    r = pw.contact_function(r12, q1, q2, out=out)
    assert r.mu2 is out["mu2"] or np.shares_memory(r.mu2, out["mu2"])
    assert np.array_equal(out["mu2"], pw.contact_function(r12, q1, q2).mu2)
    with pytest.raises(ValueError, match=r"out\['mu2'\] must have dtype"):
        pw.contact_function(r12, q1, q2, out={"mu2": np.empty(n, np.float32)})
    with pytest.raises(ValueError, match=r"out\['status'\] must have shape"):
        pw.contact_function(r12, q1, q2, out={"status": np.empty(n + 1, np.uint8)})
    with pytest.raises(ValueError, match="C-contiguous"):
        pw.contact_function(r12, q1, q2, out={"lambda": np.empty(2 * n)[::2]})


def test_column_major_inputs_are_read_in_place_with_the_same_answers(reference_pairs):
    r12, q1, q2, _, _ = reference_pairs["spread"]
    rows = pw.contact_function(r12, q1, q2, threads=2)
    columns = pw.contact_function(np.ascontiguousarray(r12.T).T, np.asfortranarray(q1),
                                  np.asfortranarray(q2), threads=2)
    assert np.array_equal(rows.mu2, columns.mu2) and np.array_equal(rows.lambda_, columns.lambda_)
    assert np.array_equal(rows.status, columns.status)


def test_out_arrays_that_share_memory_with_the_inputs_give_the_oracles_answers(reference_pairs):
    # An out array that is a column of an input (written while the kernels
    # read it): the inputs are copied first, as numpy's ufuncs do. Was: mu2
    # off by a factor of 30 with valid statuses.
    r12, q1, q2, mu2, lam = reference_pairs["random"]
    rf = np.asfortranarray(r12)
    r = pw.contact_function(rf, q1, q2, out={"mu2": rf[:, 0]})
    assert np.all(pw.is_valid(r.status))
    assert np.max(np.abs(r.mu2 - mu2) / mu2) <= 1e-13
    qf = np.asfortranarray(q1)
    r = pw.contact_function(r12, qf, q2, out={"lambda": qf[:, 0]})
    assert np.max(np.abs(r.mu2 - mu2) / mu2) <= 1e-13
    assert np.max(np.abs(r.lambda_ - lam)) <= 1e-13
    # A warm start in place (lambda_start is out['lambda']) is allowed and
    # right; a shifted view of it is copied first.
    start = lam.copy()
    r = pw.contact_function(r12, q1, q2, lambda_start=start, out={"lambda": start})
    assert np.max(np.abs(start - lam)) <= 1e-13
    buffer = np.concatenate([lam, [0.5]])
    r = pw.contact_function(r12, q1, q2, lambda_start=buffer[1:], out={"lambda": buffer[:-1]})
    assert np.max(np.abs(r.mu2 - mu2) / mu2) <= 1e-13
    # Out arrays that overlap one another cannot both be written.
    both = np.empty(len(mu2))
    with pytest.raises(ValueError, match="share memory"):
        pw.contact_function(r12, q1, q2, out={"mu2": both, "lambda": both})


@pytest.mark.parametrize("dtype", [">f4", np.dtype("f4", metadata={"units": "nm"})])
def test_float32_of_any_byte_order_or_metadata_is_solved_as_float32(reference_pairs, dtype):
    r12, q1, q2, mu2, _ = reference_pairs["random"]
    r = pw.contact_function(r12.astype(dtype), q1.astype(dtype), q2.astype(dtype))
    assert r.precision == "float" and r.mu2.dtype == np.float32
    assert np.max(np.abs(r.mu2 - mu2) / mu2) < 1e-5
    # An out array of float64 with metadata is float64.
    out = np.empty(len(mu2), dtype=np.dtype("f8", metadata={"units": "nm"}))
    pw.contact_function(r12, q1, q2, out={"mu2": out})
    assert np.max(np.abs(out - mu2) / mu2) <= 1e-13


def test_complex_and_string_inputs_are_refused_naming_them():
    q = pw.sphere(1.0)
    with pytest.raises(ValueError, match="r12 must be an array of real numbers"):
        pw.contact_function(np.array([[0, 0, 1.5 + 5j]]), q, q)
    with pytest.raises(ValueError, match="q1 must be an array of real numbers"):
        pw.contact_function([0, 0, 1.5], np.array(["1", "0", "0", "1", "0", "1"]), q)
    # Positions too, where the package converts them itself (a complex
    # position lost its imaginary part with only numpy's warning).
    positions = np.array([[0, 0, 0], [1.5 + 100j, 0, 0]])
    axes = [0.5, 0.5, 0.5]
    with pytest.raises(ValueError, match="positions must be an array of real numbers, got dtype complex"):
        pw.screen(positions, None, axes, box=pw.Box.cube(10))
    with pytest.raises(ValueError, match="positions must be an array of real numbers"):
        pw.MovingScene(positions, None, axes, box=pw.Box.cube(10))
    with pytest.raises(ValueError, match="positions must be an array of real numbers"):
        pw.HardParticleMC(positions, None, axes, box=pw.Box.cube(10))
    scene = pw.MovingScene(positions.real, None, axes, box=pw.Box.cube(10))
    with pytest.raises(ValueError, match="positions must be an array of real numbers"):
        scene.overlaps_many(positions, None, axes)
    with pytest.raises(ValueError, match="positions must be an array of real numbers"):
        pw.screen(np.array([["0", "0", "0"]]), None, axes)


def test_forms_from_numpy_integers_and_huge_radii():
    # Squared in float, not in the caller's integer type (which wrapped).
    assert pw.spheroid(np.int32(100000), 1)[0] == 1e10
    assert pw.spheroid(np.int64(2**32), 1)[0] == 2.0**64
    with pytest.raises(ValueError, match="square finite"):
        pw.sphere(1e200)
    with pytest.raises(ValueError, match="not finite"):
        pw.quadratic_form([1e200, 1, 1], [1, 0, 0, 0])


def test_outputs_may_be_one_name():
    r = pw.contact_function([0, 0, 3.0], pw.sphere(1), pw.sphere(1), outputs="mu2")
    assert r.mu2[0] == pytest.approx(2.25)
