"""screen, Box, the scene readers, and agreement with the command line."""
import subprocess

import numpy as np
import pytest

import pwcontact as pw

gsd_hoomd = pytest.importorskip("gsd.hoomd")


def brute_force_pairs(positions, q, box, cutoff):
    """Every pair with mu < cutoff by contact_function over all pairs (the
    minimum image is the only image: the scenes below keep cutoff reaches
    under half the box)."""
    n = len(positions)
    i, j = np.triu_indices(n, 1)
    d = positions[j] - positions[i]
    if box is not None:
        d = box.wrap_vectors(d)
    r = pw.contact_function(d, q[i], q[j], outputs=("mu2",))
    assert pw.is_valid(r.status).all()
    keep = r.mu2 < cutoff * cutoff
    return np.stack([i[keep], j[keep]], axis=1).astype(np.uint32), r.mu2[keep]


def random_scene(n, seed, box_length, aspect=3.0):
    rng = np.random.default_rng(seed)
    positions = rng.uniform(-box_length / 2, box_length / 2, (n, 3))
    c = np.exp(rng.uniform(-np.log(aspect), np.log(aspect), n))
    a = c ** -0.5
    axes = np.stack([a, a, c], axis=1) * 0.5
    orientations = rng.normal(size=(n, 4))
    orientations /= np.linalg.norm(orientations, axis=1, keepdims=True)
    return positions, orientations, axes


@pytest.mark.parametrize("tilts", [(0, 0, 0), (0.3, -0.2, 0.1)])
@pytest.mark.parametrize("cutoff", [1.0, 1.4])
def test_screen_finds_exactly_the_brute_force_pairs(tilts, cutoff):
    positions, orientations, axes = random_scene(900, 3, 12.0)
    box = pw.Box(12, 12, 12, *tilts)
    res = pw.screen(positions, orientations, axes, box=box, cutoff=cutoff, with_mu2=True)
    q = pw.quadratic_form(axes, orientations)
    pairs, mu2 = brute_force_pairs(positions, q, box, cutoff)
    assert res.pairs.dtype == np.uint32 and res.pairs.shape[1] == 2
    assert np.array_equal(res.pairs, pairs)
    assert np.allclose(res.mu2, mu2, rtol=1e-12)
    # counts and offsets agree with the pairs.
    assert np.array_equal(res.counts, np.bincount(res.pairs.ravel(), minlength=900))
    for i in (0, 17, 899):
        block = res.pairs[res.offsets[i]:res.offsets[i + 1]]
        assert (block[:, 0] == i).all()
        assert len(block) == np.count_nonzero(res.pairs[:, 0] == i)


def test_open_box_and_every_shape_input_give_the_same_pairs():
    positions, orientations, axes = random_scene(300, 4, 6.0)
    q = pw.quadratic_form(axes, orientations)
    by_axes = pw.screen(positions, orientations, axes, cutoff=1.2)
    by_q = pw.screen(positions, q=q, cutoff=1.2)
    types = np.unique(axes, axis=0, return_inverse=True)
    by_type = pw.screen(positions, orientations, type_semi_axes=types[0], typeid=types[1], cutoff=1.2)
    pairs, _ = brute_force_pairs(positions, q, None, 1.2)
    for res in (by_axes, by_q, by_type):
        assert np.array_equal(res.pairs, pairs)
    assert pw.screen(positions[:1], orientations[:1], axes[:1]).pairs.shape == (0, 2)


def test_screen_input_errors():
    positions, orientations, axes = random_scene(10, 5, 6.0)
    with pytest.raises(ValueError, match="one way"):
        pw.screen(positions, orientations, axes, q=pw.quadratic_form(axes, orientations))
    with pytest.raises(ValueError, match="positions"):
        pw.screen(positions[:, :2], orientations, axes)
    with pytest.raises(ValueError, match="semi_axes has 9 rows"):
        pw.screen(positions, orientations, axes[:9])
    bad = axes.copy()
    bad[4, 1] = -1
    with pytest.raises(ValueError, match="4"):
        pw.screen(positions, orientations, bad)
    with pytest.raises(ValueError, match="box lengths"):
        pw.Box(1, -1, 1)
    with pytest.raises(TypeError):
        pw.screen(positions, orientations, axes, cutof=1.0)


def test_box_from_the_conventions_users_hold():
    assert pw.Box.from_box([2, 3, 4, 0.1, 0.2, 0.3]).matrix[0, 1] == pytest.approx(0.3)
    assert pw.Box.from_box({"Lx": 2, "Ly": 3, "Lz": 4, "xy": 0.5}).xy == 0.5
    assert pw.Box.from_box([2, 3]).is2D and pw.Box.from_box([2, 3, 0, 0, 0, 0]).is2D

    class FreudLike:  # freud.box.Box and hoomd.Box expose these attributes
        Lx, Ly, Lz, xy, xz, yz, is2D = 5.0, 6.0, 7.0, 0.1, 0.0, -0.1, False

    b = pw.Box.from_box(FreudLike())
    assert (b.Lx, b.yz, b.is2D) == (5.0, -0.1, False)
    d = b.wrap_vectors([[4.9, 0, 0]])
    assert d[0, 0] == pytest.approx(-0.1)


def write_gsd(path, positions, orientations, axes_by_type, typeid, box):
    frame = gsd_hoomd.Frame() if hasattr(gsd_hoomd, "Frame") else gsd_hoomd.Snapshot()
    frame.particles.N = len(positions)
    frame.particles.position = positions.astype(np.float32)
    frame.particles.orientation = orientations.astype(np.float32)
    frame.particles.types = [f"T{k}" for k in range(len(axes_by_type))]
    frame.particles.typeid = typeid.astype(np.uint32)
    frame.particles.type_shapes = [{"type": "Ellipsoid", "a": float(a), "b": float(b), "c": float(c)}
                                   for a, b, c in axes_by_type]
    frame.configuration.box = box
    with gsd_hoomd.open(str(path), "wb") as f:
        f.append(frame)


def test_a_gsd_file_screens_to_the_pairs_of_the_command_line(tmp_path, cli):
    rng = np.random.default_rng(8)
    n = 2000
    box = [14.0, 14.0, 14.0, 0.2, 0.0, -0.1]
    positions = rng.uniform(-7, 7, (n, 3))
    orientations = rng.normal(size=(n, 4))
    orientations /= np.linalg.norm(orientations, axis=1, keepdims=True)
    axes = np.array([[0.5, 0.5, 1.2], [0.8, 0.4, 0.4], [0.6, 0.6, 0.6]])
    typeid = rng.integers(0, 3, n)
    path = tmp_path / "scene.gsd"
    write_gsd(path, positions, orientations, axes, typeid, box)
    scene = pw.read_gsd(str(path))
    assert scene["positions"].shape == (n, 3) and scene["type_names"] == ["T0", "T1", "T2"]
    res = pw.screen(**scene, cutoff=1.3, with_mu2=True)
    out = subprocess.run([cli, "screen", "--cutoff", "1.3", "--with-mu2", str(path)], check=True,
                         capture_output=True, text=True).stdout
    rows = [line.split() for line in out.splitlines() if line and not line.startswith("#")]
    cli_pairs = np.array([[int(r[0]), int(r[1])] for r in rows], dtype=np.uint32).reshape(-1, 2)
    cli_mu2 = np.array([float(r[2]) for r in rows])
    assert len(res) > 100
    assert np.array_equal(res.pairs, cli_pairs)
    # The command line prints 17 significant digits: the same doubles.
    assert np.array_equal(res.mu2, cli_mu2)
    # The library's own GSD reader, through the module, agrees too.
    native = pw.read_gsd_native(str(path))
    assert np.array_equal(pw.screen(**native, cutoff=1.3).pairs, cli_pairs)
    arrays = res.to_freud_arrays()
    assert len(arrays["query_point_indices"]) == 2 * len(res)
    assert np.all(np.diff(arrays["query_point_indices"].astype(np.int64)) >= 0)


def test_read_gsd_names_what_is_wrong(tmp_path):
    path = tmp_path / "spheres.gsd"
    frame = gsd_hoomd.Frame() if hasattr(gsd_hoomd, "Frame") else gsd_hoomd.Snapshot()
    frame.particles.N = 2
    frame.particles.position = np.array([[0, 0, 0], [1.5, 0, 0]], dtype=np.float32)
    frame.particles.types = ["A"]
    frame.particles.type_shapes = [{"type": "Polyhedron"}]
    frame.configuration.box = [10, 10, 10, 0, 0, 0]
    with gsd_hoomd.open(str(path), "wb") as f:
        f.append(frame)
    with pytest.raises(ValueError, match="type 'A' has no Ellipsoid or Sphere shape"):
        pw.read_gsd(str(path))
    with pytest.raises(ValueError, match="frame 3"):
        pw.read_gsd(str(path), frame=3)
    # The frame an integer (a bool was read as frame 1, a float raised an
    # empty TypeError); numpy integers taken.
    for frame_of_wrong_type in (True, 0.0):
        with pytest.raises(ValueError, match="frame must be an integer"):
            pw.read_gsd(str(path), frame=frame_of_wrong_type)
    # A shape without the number it needs names it (was: KeyError 'c').
    frame.particles.type_shapes = [{"type": "Ellipsoid", "a": 1.0, "b": 1.0}]
    with gsd_hoomd.open(str(path), "wb") as f:
        f.append(frame)
    with pytest.raises(ValueError, match="needs a number 'c'"):
        pw.read_gsd(str(path), frame=np.int64(0))


def test_gsd_integers_of_other_types_must_be_whole_numbers_in_both_readers(tmp_path):
    # particles/typeid written at the file layer as int64 2**32 + 1 and as
    # float64 0.9 (the hoomd schema's type is uint32): both readers refuse
    # them naming the chunk, where each read them as types 1 and 0.
    gsd_fl = pytest.importorskip("gsd.fl")

    def chars(rows):
        width = max(len(r) for r in rows) + 1
        out = np.zeros((len(rows), width), dtype=np.int8)
        for k, r in enumerate(rows):
            out[k, :len(r)] = np.frombuffer(r.encode(), dtype=np.int8)
        return out

    for typeid, shown in ((np.array([0, 2**32 + 1], np.int64), "4294967297"), (np.array([0, 0.9]), "0.9")):
        path = tmp_path / f"typeid_{typeid.dtype}.gsd"
        with gsd_fl.open(name=str(path), mode="wb", application="test", schema="hoomd",
                         schema_version=[1, 4]) as f:
            f.write_chunk(name="configuration/box", data=np.array([10, 10, 10, 0, 0, 0], np.float32))
            f.write_chunk(name="particles/N", data=np.array([2], np.uint32))
            f.write_chunk(name="particles/types", data=chars(["Big", "Small"]))
            f.write_chunk(name="particles/type_shapes",
                          data=chars(['{"type": "Sphere", "diameter": 2}', '{"type": "Sphere", "diameter": 0.2}']))
            f.write_chunk(name="particles/position", data=np.array([[0, 0, 0], [1.5, 0, 0]], np.float32))
            f.write_chunk(name="particles/typeid", data=typeid)
            f.end_frame()
        for reader in (pw.read_gsd, pw.read_gsd_native):
            with pytest.raises(ValueError, match=f"particles/typeid.*row 1: {shown} is not a whole number"):
                reader(str(path))


def test_a_screen_result_keeps_the_positions_it_was_made_from():
    # The caller's array changed in place afterwards (as a SkinNeighborList
    # loop's is): the result's vectors are those of its own step.
    positions = np.array([[0.0, 0, 0], [1.5, 0, 0]])
    res = pw.screen(positions, semi_axes=[1.0, 1, 1], cutoff=1.0, box=pw.Box.cube(10))
    positions[1, 0] = 1.8
    np.testing.assert_allclose(res.to_freud_arrays()["vectors"], [[1.5, 0, 0], [-1.5, 0, 0]])


def test_threads_do_not_change_the_pairs():
    scene = pw.spheroid_scene(20000, 2, 0.4)
    one = pw.screen(**scene, cutoff=1.2, with_mu2=True, threads=1)
    two = pw.screen(**scene, cutoff=1.2, with_mu2=True, threads=2)
    assert np.array_equal(one.pairs, two.pairs) and np.array_equal(one.mu2, two.mu2)


def test_a_workspace_reused_across_scenes_gives_the_brute_force_pairs():
    workspace = pw.ScreenWorkspace()
    assert workspace.bytes == 0
    steps = [(600, 5, 10.0, 1.0, True), (450, 6, 8.0, 1.3, False), (900, 7, 12.0, 1.1, True),
             (600, 5, 10.0, 1.0, False)]
    for n, seed, length, cutoff, with_mu2 in steps:
        positions, orientations, axes = random_scene(n, seed, length)
        box = pw.Box(length, length, length)
        res = pw.screen(positions, orientations, axes, box=box, cutoff=cutoff, with_mu2=with_mu2,
                        workspace=workspace)
        pairs, mu2 = brute_force_pairs(positions, pw.quadratic_form(axes, orientations), box,
                                       cutoff)
        assert len(pairs) > 50
        assert np.array_equal(res.pairs, pairs)
        if with_mu2:
            assert np.allclose(res.mu2, mu2, rtol=1e-12)
        assert workspace.bytes > n * 8
    workspace.release()
    assert workspace.bytes == 0
    with pytest.raises(TypeError, match="ScreenWorkspace"):
        pw.screen(positions, orientations, axes, box=box, workspace=object())


DATA = __import__("pathlib").Path(__file__).resolve().parents[2] / "tests" / "data"


def cli_pairs(cli, path, cutoff, *extra):
    out = subprocess.run([cli, "screen", "--cutoff", str(cutoff), "--with-mu2", *extra, str(path)],
                         check=True, capture_output=True, text=True).stdout
    rows = [line.split() for line in out.splitlines() if line and not line.startswith("#")]
    return (np.array([[int(r[0]), int(r[1])] for r in rows], dtype=np.uint32).reshape(-1, 2),
            np.array([float(r[2]) for r in rows]))


@pytest.mark.parametrize("name", ["hoomd_triclinic.gsd", "hoomd_ellipses_2d.gsd"])
def test_files_written_by_hoomd_screen_as_the_command_line_does(cli, name):
    """GSD files HOOMD-blue wrote (tests/data): 3D triclinic, and ellipses in 2D."""
    path = DATA / name
    for cutoff in (1.0, 1.5):
        expected, mu2 = cli_pairs(cli, path, cutoff)
        scene = pw.read_gsd(str(path))
        got = pw.screen(**scene, cutoff=cutoff, with_mu2=True)
        assert np.array_equal(got.pairs, expected)
        # float32 positions widened alike; the forms from the same semi-axes
        # and quaternions (the 2D reader's from an angle): mu2 to a few ulps.
        assert np.allclose(got.mu2, mu2, rtol=1e-13, atol=0)
        native = pw.screen(**pw.read_gsd_native(str(path)), cutoff=cutoff, with_mu2=True)
        assert np.array_equal(native.pairs, expected) and np.array_equal(native.mu2, mu2)


def test_the_monte_carlo_scene_is_a_float32_hoomd_frame_with_no_pair_within_1e6_of_contact(
        cli, tmp_path):
    """`pwcontact mc -o x.gsd` writes the hoomd schema as HOOMD-blue reads it
    (float32 chunks, centres in [-L/2, L/2)), and the rounded scene keeps every
    pair at mu >= 1 + 1e-6: checked here by contact_function over every pair
    (the minimum image: the box is wider than twice any reach), not by the
    screen the command itself ran."""
    path = tmp_path / "mc.gsd"
    subprocess.run([cli, "mc", "--n", "64", "--packing", "0.3", "--seed", "3", "-o", str(path)],
                   check=True, capture_output=True)
    with gsd_hoomd.open(str(path), "rb") as f:
        frame = f[0]
    assert frame.particles.position.dtype == np.float32
    assert frame.particles.orientation.dtype == np.float32
    assert np.asarray(frame.configuration.box).dtype == np.float32
    box = np.asarray(frame.configuration.box, dtype=np.float64)
    assert np.all(box[3:] == 0)
    position = frame.particles.position.astype(np.float64)
    assert np.all(position >= -box[:3] / 2) and np.all(position < box[:3] / 2)
    quaternion = frame.particles.orientation.astype(np.float64)
    assert np.allclose(np.linalg.norm(quaternion, axis=1), 1, rtol=0, atol=3e-7)
    shapes = frame.particles.type_shapes
    axes = np.array([[shapes[t]["a"], shapes[t]["b"], shapes[t]["c"]]
                     for t in frame.particles.typeid])
    q = pw.quadratic_form(axes, quaternion)
    n = len(position)
    i, j = np.triu_indices(n, 1)
    d = position[j] - position[i]
    d -= box[:3] * np.round(d / box[:3])
    r = pw.contact_function(d, q[i], q[j], outputs=("mu2",))
    assert pw.is_valid(r.status).all()
    # mu2 to ~1e-13 (README's double bound on these compact shapes) against a
    # margin of 2e-6 in mu2.
    assert r.mu2.min() >= (1 + 1e-6) ** 2 * (1 - 1e-12)
    assert r.mu2.min() < 1.2  # compressed: some pairs are near contact


@pytest.mark.parametrize("name", ["lammps_triclinic.data", "lammps_triclinic.dump"])
def test_lammps_files_through_the_cpp_readers(cli, name):
    path = DATA / name
    extra = []
    if name.endswith(".data"):
        scene = pw.read_lammps_data(str(path))
    else:
        # The dump's shapes and quaternions are a compute's columns.
        names = {"shapex": "c_s[1]", "shapey": "c_s[2]", "shapez": "c_s[3]",
                 "quatw": "c_q[1]", "quati": "c_q[2]", "quatj": "c_q[3]", "quatk": "c_q[4]"}
        with pytest.raises(ValueError, match="no column shapex"):
            pw.read_lammps_dump(str(path))
        with pytest.raises(ValueError, match="unknown keys shape"):
            pw.read_lammps_dump(str(path), columns={"shape": "c_s[1]"})
        scene = pw.read_lammps_dump(str(path), columns=names)
        extra = ["--columns", ",".join(f"{k}={v}" for k, v in names.items())]
    assert scene["positions"].shape[1] == 3 and len(scene["id"]) == len(scene["positions"])
    got = pw.screen(**scene, cutoff=1.4, with_mu2=True)
    expected, mu2 = cli_pairs(cli, path, 1.4, *extra)
    assert np.array_equal(got.pairs, expected) and np.array_equal(got.mu2, mu2)
    with pytest.raises(ValueError):
        pw.read_lammps_data(str(DATA / "hoomd_triclinic.gsd"))


def test_a_two_dimensional_box_takes_only_particles_in_the_plane():
    positions = np.array([[0.0, 0, 0], [1.5, 0, 0]])
    box = pw.Box(10, 10, is2D=True)
    ok = pw.screen(positions, None, [1.0, 0.5, 0.5], box=box, cutoff=1.0)
    assert np.array_equal(ok.pairs, [[0, 1]])
    with pytest.raises(ValueError, match="particle 1 has z"):
        pw.screen(positions + [[0, 0, 0], [0, 0, 0.1]], None, [1.0, 0.5, 0.5], box=box)
    tilted = np.array([[1.0, 0, 0, 0], [0.9, 0.3, 0, 0]])
    with pytest.raises(ValueError, match="orientation of particle 1"):
        pw.screen(positions, tilted, [1.0, 0.5, 0.5], box=box)


def test_semi_axes_given_as_a_pair_of_type_arrays():
    positions = np.array([[0.0, 0, 0], [1.5, 0, 0], [5, 5, 5]])
    res = pw.screen(positions, None, (np.array([[1.0, 0.5, 0.5], [0.2, 0.2, 0.2]]), np.array([0, 0, 1])))
    assert np.array_equal(res.pairs, [[0, 1]])
