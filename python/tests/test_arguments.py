"""Malformed calls are refused, naming the argument: nothing given is silently
ignored, truncated or taken for something else (the package's rule:
malformed calls raise ValueError; an index that does not exist,
IndexError; a file that cannot be opened, OSError)."""
import math
import os

import numpy as np
import pytest

import pwcontact as pw


def two_spheres_scene(**kw):
    return pw.MovingScene(np.array([[0.0, 0, 0], [4.0, 0, 0]]), None, [1.0, 1.0, 1.0], **kw)


# MovingScene is built from the particles' arguments screen takes.


def test_moving_scene_refuses_an_unknown_keyword_as_screen_does():
    positions = np.array([[0.0, 0, 0], [4.0, 0, 0]])
    with pytest.raises(TypeError, match="'bx'"):
        pw.MovingScene(positions, None, [1, 1, 1], bx=pw.Box.cube(5))
    with pytest.raises(TypeError, match="'bx'"):
        pw.screen(positions, None, [1, 1, 1], bx=pw.Box.cube(5))
    # What read_gsd / read_lammps_* return beside the particles is accepted.
    scene = pw.MovingScene(positions, None, [1, 1, 1], box=pw.Box.cube(10), type_names=["A"], frame=0)
    assert len(scene) == 2


def test_moving_scene_takes_semi_axes_as_type_semi_axes_and_typeid():
    positions = np.array([[0.0, 0, 0], [1.5, 0, 0], [5.0, 0, 0]])
    types = np.array([[1.0, 1.0, 1.0], [0.4, 0.4, 0.4]])
    typeid = np.array([0, 1, 1])
    scene = pw.MovingScene(positions, None, (types, typeid), box=pw.Box.cube(20))
    keywords = pw.MovingScene(positions, None, type_semi_axes=types, typeid=typeid, box=pw.Box.cube(20))
    np.testing.assert_array_equal(scene.q, keywords.q)
    assert scene.overlap_count([0.5, 0, 0], semi_axes=[0.7, 0.7, 0.7]) == 2


def test_a_two_dimensional_moving_scene_is_checked_in_its_plane_as_screen_checks():
    box = pw.Box(10, 10, is2D=True)
    axes = [1.0, 1.0, 0.5]
    off_plane = np.array([[0.0, 0, 0], [0.5, 0, 5.0]])
    with pytest.raises(ValueError, match="particle 1 has z = 5"):
        pw.screen(off_plane, None, axes, box=box)
    with pytest.raises(ValueError, match="particle 1 has z = 5"):
        pw.MovingScene(off_plane, None, axes, box=box)
    tilted = [math.cos(0.5), math.sin(0.5), 0, 0]
    with pytest.raises(ValueError, match="not a rotation about z"):
        pw.MovingScene(off_plane * [1, 1, 0], [[1, 0, 0, 0], tilted], axes, box=box)
    scene = pw.MovingScene(off_plane * [1, 1, 0], None, axes, box=box)
    with pytest.raises(ValueError, match="the trial has z = 5"):
        scene.overlaps([0.5, 0, 5.0], semi_axes=axes)
    with pytest.raises(ValueError, match="the trial has z = 7"):
        scene.insert([0.5, 0, 7.0], semi_axes=axes)
    with pytest.raises(ValueError, match="z = 7"):
        scene.move(0, [0.5, 0, 7.0], semi_axes=axes)
    with pytest.raises(ValueError, match="not a rotation about z"):
        scene.neighbors([1.8, 0, 0], tilted, [1, 0.3, 0.3])
    with pytest.raises(ValueError, match="not a rotation about z"):
        scene.overlap_count([1.8, 0, 0], tilted, [1, 0.3, 0.3])
    with pytest.raises(ValueError, match="trial 1 has z = 2"):
        scene.overlaps_many([[6.0, 0, 0], [6.0, 0, 2.0]], semi_axes=axes)
    with pytest.raises(ValueError, match="move 0 has z = 2"):
        scene.move_many([1], [[6.0, 0, 2.0]], semi_axes=axes)
    assert len(scene) == 2 and np.all(scene.positions[:, 2] == 0)
    # A rotation about z is in the plane.
    about_z = [math.cos(0.5), 0, 0, math.sin(0.5)]
    assert scene.overlaps([1.5, 0, 0], about_z, [1, 0.3, 0.3]) is not None


# overlaps_many: the trials are the common rows of its arrays.


def test_overlaps_many_broadcasts_one_position_against_many_shapes():
    scene = two_spheres_scene(box=pw.Box.cube(20))
    q = np.tile(pw.sphere(1), (5, 1))
    q[1::2] = pw.sphere(0.1)
    found = scene.overlaps_many([1.5, 0, 0], q=q)
    assert found.shape == (5,)
    assert found.tolist() == [0, -1, 0, -1, 0]
    found = scene.overlaps_many([3.0, 0, 0], np.tile([1.0, 0, 0, 0], (3, 1)), [0.5, 0.5, 0.5])
    assert found.tolist() == [1, 1, 1]
    with pytest.raises(ValueError, match="positions 2.*q 5"):
        scene.overlaps_many(np.zeros((2, 3)), q=q)


# Indices that do not exist, and indices or type ids that are not integers.


@pytest.mark.parametrize("exclude", [99, 2, -5])
def test_an_exclude_that_does_not_exist_is_refused(exclude):
    scene = two_spheres_scene(box=pw.Box.cube(20))
    for query in (scene.overlaps, scene.overlap_count, scene.neighbors):
        with pytest.raises(IndexError, match=f"exclude: particle {exclude} does not exist \\(2 particles"):
            query([0.5, 0, 0], semi_axes=[1, 1, 1], exclude=exclude)
    with pytest.raises(IndexError, match=f"exclude\\[1\\]: particle {exclude} does not exist"):
        scene.overlaps_many([[0.5, 0, 0], [3.5, 0, 0]], semi_axes=[1, 1, 1], exclude=[0, exclude])
    # -1 and None: no exclusion.
    assert scene.overlaps([0.5, 0, 0], semi_axes=[1, 1, 1], exclude=-1) == 0
    assert scene.overlaps([0.5, 0, 0], semi_axes=[1, 1, 1], exclude=None) == 0
    assert scene.overlaps([0.5, 0, 0], semi_axes=[1, 1, 1], exclude=0) is None
    assert scene.overlaps_many([[0.5, 0, 0]], semi_axes=[1, 1, 1], exclude=[-1]).tolist() == [0]


def test_indices_and_type_ids_must_be_integers():
    scene = two_spheres_scene(box=pw.Box.cube(20))
    with pytest.raises(ValueError, match="exclude must be an integer"):
        scene.overlaps([0.5, 0, 0], semi_axes=[1, 1, 1], exclude=0.9)
    with pytest.raises(ValueError, match="exclude must be integers"):
        scene.overlaps_many([[0.5, 0, 0]], semi_axes=[1, 1, 1], exclude=[0.9])
    with pytest.raises(ValueError, match="indices must be integers"):
        scene.move_many([1.7], [[8.0, 0, 0]], semi_axes=[1, 1, 1])
    with pytest.raises(ValueError, match="must be an integer"):
        scene.move(1.7, [8.0, 0, 0], semi_axes=[1, 1, 1])
    with pytest.raises(ValueError, match="must be an integer"):
        scene.remove(1.7)
    np.testing.assert_array_equal(scene.positions, [[0, 0, 0], [4, 0, 0]])
    with pytest.raises(IndexError, match="particle -1 does not exist"):
        scene.remove(-1)
    scene.move_many([], np.zeros((0, 3)), semi_axes=[1, 1, 1])  # nothing to move
    n = 3
    positions = np.array([[0.0, 0, 0], [3, 0, 0], [6, 0, 0]])
    types = np.array([[1.0, 1, 1], [0.5, 0.5, 0.5]])
    for build in (pw.screen, pw.MovingScene, pw.SkinNeighborList().update):
        with pytest.raises(ValueError, match="typeid must be integers"):
            build(positions, type_semi_axes=types, typeid=np.full(n, 0.9), box=pw.Box.cube(20))
        with pytest.raises(ValueError, match="typeid of particle 2 is -1"):
            build(positions, type_semi_axes=types, typeid=[0, 1, -1], box=pw.Box.cube(20))
        # Beyond 2**32 - 1 the core's 32-bit type ids would wrap to type 0 or 1.
        with pytest.raises(ValueError, match="typeid of particle 1 is 4294967296"):
            build(positions, type_semi_axes=types, typeid=np.array([0, 2**32, 1]), box=pw.Box.cube(20))
    typed = pw.MovingScene(positions, type_semi_axes=types, typeid=[0, 1, 1], box=pw.Box.cube(20))
    for typeid in (-1, 0.9, True, "0"):
        with pytest.raises(ValueError, match="typeid"):
            typed.overlaps([1.0, 0, 0], typeid=typeid)
    assert typed.overlaps([1.0, 0, 0], typeid=np.uint8(1)) == 0


# Arguments that would be ignored.


def test_arguments_that_would_be_ignored_are_refused():
    positions = np.array([[0.0, 0, 0], [1.5, 0, 0]])
    q = np.tile(pw.sphere(1), (2, 1))
    for build in (pw.screen, pw.MovingScene, pw.SkinNeighborList().update):
        with pytest.raises(ValueError, match="typeid.*semi_axes"):
            build(positions, None, np.ones((2, 3)), typeid=[0, 0])
        with pytest.raises(ValueError, match="orientations.*q"):
            build(positions, [[1, 0, 0, 0], [0, 1, 0, 0]], q=q)
    # typeid beside q is what read_lammps_* return: accepted (the forms are the shapes).
    assert len(pw.screen(positions, q=q, typeid=[0, 0])) == 1
    scene = pw.MovingScene(positions, q=q)
    with pytest.raises(ValueError, match="orientation.*q"):
        scene.overlaps([0.5, 0, 0], [0, 1, 0, 0], q=pw.sphere(1))
    with pytest.raises(ValueError, match="orientations.*q"):
        scene.overlaps_many([[0.5, 0, 0]], [[0, 1, 0, 0]], q=pw.sphere(1))
    with pytest.raises(ValueError, match="orientations.*q"):
        scene.move_many([0], [[0.5, 0, 0]], [[0, 1, 0, 0]], q=pw.sphere(1))


def test_out_with_an_unknown_key_is_refused():
    mu = np.zeros(1)
    with pytest.raises(ValueError, match=r"out\['mu'\].*mu2, lambda, status"):
        pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(1), out={"mu": mu})
    with pytest.raises(ValueError, match=r"out\['lambda'\].*outputs"):
        pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(1), outputs=("mu2",),
                            out={"lambda": np.zeros(1)})
    r = pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(1), out={"mu2": mu})
    assert r.mu2 is not None and mu[0] == pytest.approx(1.0)


# Values of the wrong kind are ValueError naming the argument.


@pytest.mark.parametrize("iterations", [2.7, "5", True, 3.0, np.float64(3), "auto "])
def test_iterations_must_be_auto_or_an_integer(iterations):
    with pytest.raises(ValueError, match="iterations must be 'auto' or an integer"):
        pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(1), iterations=iterations)
    with pytest.raises(ValueError, match="iterations must be 'auto' or an integer"):
        pw.overlap([2.0, 0, 0], pw.sphere(1), pw.sphere(1), iterations=iterations)


def test_iterations_as_numpy_integers_are_taken():
    r = pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(1), iterations=np.int64(5))
    assert pw.is_valid(r.status).all()


def test_iterations_take_the_command_lines_range():
    # 0 is automatic and 1 .. 1000 fixed, as --iterations and BatchOptions
    # take them (41 .. 1000 were refused here alone); beyond, ValueError.
    q = pw.sphere(1)
    auto = pw.contact_function([1.5, 0, 0], q, q)
    for iterations in (0, None, 41, 1000):
        r = pw.contact_function([1.5, 0, 0], q, q, iterations=iterations)
        assert pw.is_valid(r.status).all()
        np.testing.assert_allclose(r.mu2, 0.5625, rtol=1e-15)
        assert pw.overlap([1.5, 0, 0], q, q, iterations=iterations).overlap.all()
    assert pw.contact_function([1.5, 0, 0], q, q, iterations=0).report == auto.report
    for iterations in (-1, 1001, 2**31 - 1):
        for call in (pw.contact_function, pw.overlap):
            with pytest.raises(ValueError, match=rf"iterations must be 'auto' or an integer "
                                                 rf"0 \.\. 1000 \(0: auto\), got {iterations}"):
                call([1.5, 0, 0], q, q, iterations=iterations)


def test_counts_and_seeds_must_be_non_negative_integers():
    with pytest.raises(ValueError, match="seed"):
        pw.HardParticleMC(np.zeros((1, 3)), None, [0.5, 0.5, 0.5], box=pw.Box.cube(5), seed=-1)
    with pytest.raises(ValueError, match="seed"):
        pw.HardParticleMC(np.zeros((1, 3)), None, [0.5, 0.5, 0.5], box=pw.Box.cube(5), seed=1.5)
    with pytest.raises(ValueError, match="n must be"):
        pw.HardParticleMC.dilute_spheroids(-1)
    with pytest.raises(ValueError, match="seed"):
        pw.HardParticleMC.dilute_spheroids(8, seed=-1)
    mc = pw.HardParticleMC.dilute_spheroids(8, packing=0.1)
    with pytest.raises(ValueError, match="max_sweeps"):
        mc.compress_to_packing(-1)
    with pytest.raises(ValueError, match="n must be"):
        pw.spheroid_scene(-1)
    with pytest.raises(ValueError, match="seed"):
        pw.spheroid_scene(10, seed=-2)


def test_reference_names_an_argument_of_the_wrong_shape():
    with pytest.raises(ValueError, match=r"r12 must be 3 numbers, got shape \(2,\)"):
        pw.reference([3, 0], pw.sphere(1), pw.sphere(1))
    with pytest.raises(ValueError, match="q2 must be 6 numbers"):
        pw.reference([3, 0, 0], pw.sphere(1), [1, 0, 0])
    mu2, lam, status = pw.reference([3, 0, 0], pw.sphere(1), pw.sphere(1))
    assert status == pw.Status.ok and mu2 == pytest.approx(2.25)


def test_a_missing_file_is_file_not_found(tmp_path):
    missing = str(tmp_path / "missing")
    for read in (pw.read_lammps_data, pw.read_lammps_dump, pw.read_gsd_native, pw.read_gsd):
        with pytest.raises(FileNotFoundError, match="missing"):
            read(missing)
    # A file of another format: ValueError from both GSD readers (the gsd
    # package raised RuntimeError).
    other = tmp_path / "other.gsd"
    other.write_text("not a GSD file\n" * 20)
    for read in (pw.read_gsd, pw.read_gsd_native):
        with pytest.raises(ValueError, match="other.gsd"):
            read(str(other))
    with pytest.raises(OSError):
        pw.read_lammps_data(str(tmp_path))  # a directory


# spheroid_scene's numbers are checked before the C++ call.


@pytest.mark.parametrize("max_aspect", [0, -1, 0.5, math.nan, math.inf, 1e300])
def test_spheroid_scene_refuses_a_max_aspect_out_of_range(max_aspect):
    with pytest.raises(ValueError, match="max_aspect"):
        pw.spheroid_scene(10, max_aspect=max_aspect)


@pytest.mark.parametrize("packing", [0, -0.1, 1, 5, math.nan, math.inf])
def test_spheroid_scene_refuses_a_packing_out_of_range(packing):
    with pytest.raises(ValueError, match="packing"):
        pw.spheroid_scene(10, packing=packing)


def test_spheroid_scene_takes_the_documented_ranges():
    scene = pw.spheroid_scene(10, packing=0.99, max_aspect=1)
    assert scene["positions"].shape == (10, 3)
    assert pw.spheroid_scene(10, max_aspect=1000)["semi_axes"].shape == (10, 3)


# The names the documentation gives exist.


def test_documented_names_are_exported():
    assert isinstance(pw.with_mpi, bool) and pw.with_mpi == pw._pwcontact.with_mpi
    for name in ("with_mpi", "is_valid", "read_gsd_native", "STATUS_DESCRIPTIONS"):
        assert name in pw.__all__
    stub = open(os.path.join(os.path.dirname(pw.__file__), "__init__.pyi")).read()
    for name in pw.__all__:
        assert f"{name}" in stub, name


def test_an_output_not_asked_for_says_so():
    r = pw.contact_function([2.0, 0, 0], pw.sphere(1), pw.sphere(0.5), outputs=("lambda",))
    with pytest.raises(KeyError, match="not among the outputs"):
        r.mu2
    with pytest.raises(KeyError, match="not among the outputs"):
        r.normal


def test_float32_with_high_accuracy_needs_double_precision():
    args = [np.float32([2, 0, 0]), pw.sphere(1).astype(np.float32), pw.sphere(1).astype(np.float32)]
    with pytest.raises(ValueError, match="double or mixed"):
        pw.contact_function(*args, accuracy="high")
    assert 'float32 pairs with accuracy="high"' in " ".join(pw.contact_function.__doc__.split())
    r = pw.contact_function(*args, accuracy="high", precision="double")
    assert r.mu2.dtype == np.float64 and r.mu2[0] == pytest.approx(1.0)


@pytest.mark.parametrize("threads", [-1, 1025, 100000, 2.7, "2", True])
def test_threads_must_be_an_integer_from_0_to_1024(threads):
    # (100000 threads segfaulted the interpreter in overlaps_many and
    # screen; 2.7 was truncated to 2.)
    r12 = np.array([[3.0, 0, 0]])
    q = np.array([[1.0, 0, 0, 1, 0, 1]])
    positions = np.array([[0.0, 0, 0], [4.0, 0, 0]])
    calls = [
        lambda: pw.contact_function(r12, q, q, threads=threads),
        lambda: pw.overlap(r12, q, q, threads=threads),
        lambda: pw.screen(positions, None, [1, 1, 1], threads=threads),
        lambda: two_spheres_scene().overlaps_many(positions, semi_axes=[1, 1, 1], threads=threads),
        lambda: pw.SkinNeighborList(1.2, 0.1, threads=threads),
    ]
    for call in calls:
        with pytest.raises(ValueError, match="threads"):
            call()


def test_the_core_refuses_more_than_1024_threads_too():
    r12 = np.array([[3.0, 0, 0]])
    q = np.array([[1.0, 0, 0, 1, 0, 1]])
    with pytest.raises(ValueError, match="threads must be in 0 .. 1024"):
        pw._core.overlap(r12, q, q, 1.0, "auto", "auto", 100000, "auto")


def test_indices_beyond_int64_are_index_errors_naming_them():
    # (remove(2**64) was pybind11's TypeError with a signature; a uint64
    # index of 2**64 - 1 in move_many was named "particle -1".)
    scene = two_spheres_scene()
    with pytest.raises(IndexError, match=f"particle {2**64} does not exist"):
        scene.remove(2**64)
    with pytest.raises(IndexError, match=f"particle {2**64} does not exist"):
        scene.move(2**64, [0.0, 0, 0], semi_axes=[1, 1, 1])
    huge = np.array([1, 2**64 - 1], dtype=np.uint64)
    with pytest.raises(IndexError, match=f"move 1: particle {2**64 - 1} does not exist"):
        scene.move_many(huge, [[0.0, 0, 0], [4.0, 0, 0]], semi_axes=[1, 1, 1])
    assert len(scene) == 2


def test_dilute_spheroids_takes_the_command_lines_sixteen_shapes():
    mixed = pw.HardParticleMC.dilute_spheroids(100, seed=1)
    sixteen = pw.HardParticleMC.dilute_spheroids(100, seed=1, shapes=16)
    assert len({tuple(a) for a in np.round(sixteen.scene()["semi_axes"], 12)}) <= 16
    assert len({tuple(a) for a in np.round(mixed.scene()["semi_axes"], 12)}) > 16
    with pytest.raises(ValueError, match="shapes"):
        pw.HardParticleMC.dilute_spheroids(100, shapes=-1)


def test_arguments_beyond_their_types_are_value_errors_naming_them(tmp_path):
    q = pw.sphere(1.0)
    with pytest.raises(ValueError, match=r"iterations must be 'auto' or an integer 0 \.\. 1000 \(0: auto\)"):
        pw.contact_function([0, 0, 3.0], q, q, iterations=2**64)
    with pytest.raises(ValueError, match="lambda_start must be an array of numbers"):
        pw.contact_function([0, 0, 3.0], q, q, lambda_start=object())
    with pytest.raises(ValueError, match="n must be"):
        pw.spheroid_scene(2**64)
    with pytest.raises(ValueError, match="lacks Ly"):
        pw.Box.from_box({"Lx": 3})
    # One separation vector (3,) is wrapped as one.
    np.testing.assert_allclose(pw.Box.cube(10).wrap_vectors([9.0, 0, 0]), [-1.0, 0, 0])
