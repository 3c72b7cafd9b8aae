"""The persistent scene of trial moves, against brute force."""
import numpy as np
import pytest

import pwcontact as pw


def overlapping(scene, position, q, exclude):
    """Indices the trial overlaps, by contact_function on every stored particle."""
    stored = scene.positions
    forms = scene.q
    d = scene._box.wrap_vectors(stored - position) if scene._box is not None else stored - position
    r = pw.contact_function(d, q, forms, outputs=("mu2",))
    hit = set(np.flatnonzero(r.mu2 < 1).tolist())
    hit.discard(exclude)
    return hit


def test_a_random_sequence_of_moves_agrees_with_brute_force():
    rng = np.random.default_rng(11)
    n = 300
    box = pw.Box(9, 9, 9, 0.2, 0.1, -0.1)
    positions = rng.uniform(0, 9, (n, 3))
    axes = np.tile([0.3, 0.3, 0.7], (n, 1))
    orientations = rng.normal(size=(n, 4))
    scene = pw.MovingScene(positions, orientations, axes, box=box)
    assert len(scene) == n
    for step in range(400):
        i = int(rng.integers(0, len(scene)))
        position = scene.positions[i] + rng.uniform(-0.5, 0.5, 3)
        orientation = rng.normal(size=4)
        q = pw.quadratic_form([0.3, 0.3, 0.7], orientation)[0]
        expected = overlapping(scene, position, q, i)
        found = scene.overlaps(position, orientation, [0.3, 0.3, 0.7], exclude=i)
        assert (found is None) == (not expected)
        if found is not None:
            assert found in expected
        assert scene.overlap_count(position, orientation, [0.3, 0.3, 0.7], exclude=i) == len(expected)
        if found is None:
            scene.move(i, position, orientation, [0.3, 0.3, 0.7])
        if step % 50 == 0:
            index, mu2 = scene.neighbors(position, q=q, cutoff=1.5, with_mu2=True, exclude=i)
            assert np.all(mu2 < 1.5**2)
    k = scene.insert([1.0, 1.0, 1.0], None, [0.2, 0.2, 0.2])
    assert k == n and len(scene) == n + 1
    assert scene.remove(0) == n and len(scene) == n


def test_bad_moves_raise_and_leave_the_scene_unchanged():
    scene = pw.MovingScene(np.zeros((1, 3)), None, [0.5, 0.5, 0.5], box=None)
    before = scene.positions.copy()
    with pytest.raises(IndexError):
        scene.move(5, [1, 1, 1], None, [0.5, 0.5, 0.5])
    with pytest.raises(ValueError):
        scene.move(0, [np.nan, 1, 1], None, [0.5, 0.5, 0.5])
    with pytest.raises(ValueError):
        scene.move(0, [1, 1, 1], q=[1, 0, 0, -1, 0, 1])
    assert np.array_equal(scene.positions, before)
    assert scene.overlaps([0.9, 0, 0], None, [0.5, 0.5, 0.5]) == 0
    assert scene.overlaps([1.1, 0, 0], None, [0.5, 0.5, 0.5]) is None
    # A trial's numbers as numpy rows (of any dtype), tuples or lists; wrong
    # counts named.
    assert scene.overlaps(np.array([0.9, 0, 0], dtype=np.float32), np.array([1.0, 0, 0, 0]),
                          np.array([0.5, 0.5, 0.5])) == 0
    assert scene.overlaps((1.1, 0, 0), (1, 0, 0, 0), (0.5, 0.5, 0.5)) is None
    for position, message in (([1, 2], "position must be 3 numbers"),
                              (np.zeros(4), r"position must have shape \(3,\)"),
                              (np.zeros((1, 3)), r"position must have shape \(3,\)")):
        with pytest.raises(ValueError, match=message):
            scene.overlaps(position, None, [0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="orientation must"):
        scene.overlaps([0, 0, 0], [1, 0, 0], [0.5, 0.5, 0.5])


def test_many_trials_at_once_answer_as_the_single_queries():
    rng = np.random.default_rng(12)
    n = 400
    positions = rng.uniform(0, 10, (n, 3))
    orientations = rng.normal(size=(n, 4))
    scene = pw.MovingScene(positions, orientations, [0.25, 0.25, 0.8], box=pw.Box.cube(10))
    m = 300
    which = rng.integers(0, n, m)
    trial_positions = positions[which] + rng.uniform(-0.4, 0.4, (m, 3))
    trial_orientations = rng.normal(size=(m, 4))
    single = [scene.overlaps(trial_positions[k], trial_orientations[k], [0.25, 0.25, 0.8], exclude=int(which[k]))
              for k in range(m)]
    expected = np.array([-1 if f is None else f for f in single])
    assert 0 < np.count_nonzero(expected >= 0) < m
    for threads in (1, 2):
        got = scene.overlaps_many(trial_positions, trial_orientations, [0.25, 0.25, 0.8], exclude=which,
                                  threads=threads)
        assert got.dtype == np.int64 and np.array_equal(got, expected)
    bad = trial_orientations.copy()
    bad[7] = 0
    with pytest.raises(ValueError, match="trial 7"):
        scene.overlaps_many(trial_positions, bad, [0.25, 0.25, 0.8])
    with pytest.raises(ValueError, match="exclude must have shape"):
        scene.overlaps_many(trial_positions, trial_orientations, [0.25, 0.25, 0.8], exclude=which[:5])


def test_move_many_moves_as_single_moves_do():
    rng = np.random.default_rng(13)
    n = 500
    box = pw.Box.cube(12)
    positions = rng.uniform(0, 12, (n, 3))
    orientations = rng.normal(size=(n, 4))
    axes = [0.2, 0.2, 0.5]
    for threads in (1, 2):
        together = pw.MovingScene(positions, orientations, axes, box=box)
        one_by_one = pw.MovingScene(positions, orientations, axes, box=box)
        # Moves of particles far apart (independent cells) and a few that are
        # not (the same particle's neighbours): both kinds must come out as
        # the moves one after another.
        which = rng.choice(n, 40, replace=False)
        new_positions = positions[which] + rng.uniform(-0.3, 0.3, (40, 3))
        new_orientations = rng.normal(size=(40, 4))
        together.move_many(which, new_positions, new_orientations, axes, threads=threads)
        for k in range(40):
            one_by_one.move(int(which[k]), new_positions[k], new_orientations[k], axes)
        assert np.array_equal(together.positions, one_by_one.positions)
        assert np.array_equal(together.q, one_by_one.q)
        # The scene answers for the moved particles where they now are.
        for k in range(0, 40, 7):
            i = int(which[k])
            assert (together.overlaps(new_positions[k], new_orientations[k], axes, exclude=i)
                    == one_by_one.overlaps(new_positions[k], new_orientations[k], axes, exclude=i))


def test_move_many_checks_every_move_first():
    scene = pw.MovingScene(np.array([[0.0, 0, 0], [3.0, 0, 0]]), None, [0.5, 0.5, 0.5], box=None)
    before = scene.positions.copy()
    moves = np.array([[0.5, 0, 0], [3.5, 0, 0]])
    for bad in ([0, 2], [0, -1]):
        with pytest.raises(IndexError, match="particle"):
            scene.move_many(bad, moves, None, [0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="move 1"):
        scene.move_many([0, 1], np.array([[0.5, 0, 0], [np.nan, 0, 0]]), None, [0.5, 0.5, 0.5])
    with pytest.raises(ValueError, match="shape"):
        scene.move_many([0], moves, None, [0.5, 0.5, 0.5])
    assert np.array_equal(scene.positions, before)
    scene.move_many([0, 1], moves, None, [0.5, 0.5, 0.5])
    assert np.array_equal(scene.positions, moves)


def brute_force_pairs(positions, q, box, cutoff):
    """{(i, j): mu2} of every pair i < j with mu2 < cutoff**2, by
    contact_function on all N (N - 1) / 2 pairs (minimum images)."""
    n = len(positions)
    i, j = np.triu_indices(n, 1)
    d = box.wrap_vectors(positions[j] - positions[i])
    r = pw.contact_function(d, q[i], q[j], outputs=("mu2",))
    assert np.all(pw.is_valid(r.status))
    keep = r.mu2 < cutoff**2
    return {(int(a), int(b)): float(m) for a, b, m in zip(i[keep], j[keep], r.mu2[keep])}, r.mu2, i, j


def test_the_skin_list_gives_every_step_the_pairs_brute_force_finds():
    rng = np.random.default_rng(14)
    n = 240
    box = pw.Box(8, 8, 8, 0.1, 0.0, -0.2)
    axes = np.column_stack([rng.uniform(0.2, 0.4, n), rng.uniform(0.2, 0.4, n), rng.uniform(0.4, 0.9, n)])
    positions = rng.uniform(0, 8, (n, 3))
    orientations = rng.normal(size=(n, 4))
    orientations /= np.linalg.norm(orientations, axis=1)[:, None]
    cutoff = 1.3
    nl = pw.SkinNeighborList(cutoff, 0.2, threads=2)
    kept = rebuilt = 0
    for step in range(12):
        if step == 8:
            positions[0] += 1.5  # far beyond the skin: a rebuild
        result = nl.update(positions, orientations, axes, box=box)
        q = pw.quadratic_form(axes, orientations)
        expected, mu2_all, i_all, j_all = brute_force_pairs(positions, q, box, cutoff)
        found = {(int(a), int(b)): float(m) for (a, b), m in zip(result.pairs, result.mu2)}
        # The set of pairs: the same, but for pairs within 1e-9 of the cutoff,
        # where the two solves' last bits may fall either side (none expected).
        near = set((int(a), int(b)) for a, b, m in zip(i_all, j_all, mu2_all)
                   if abs(m - cutoff**2) < 1e-9 * cutoff**2)
        assert set(found) - near == set(expected) - near
        # mu^2 of each pair to the batch path's accuracy (<= 1e-13 relative on
        # random pairs, README; 1e-11 leaves room for a warm start's last step).
        for key, m in found.items():
            if key in expected:
                assert abs(m - expected[key]) <= 1e-11 * expected[key], key
        assert np.all(result.pairs[:, 0] < result.pairs[:, 1])
        report = result.report
        assert report["found"] == len(found) and report["listed"] >= report["found"]
        if report["rebuilt"]:
            rebuilt += 1
        else:
            kept += 1
            assert report["largest_move"] <= 0.2
        if step == 8:
            assert report["rebuilt"]
        # A slow step: moves and turns well inside the skin most of the time.
        positions += rng.normal(scale=0.0005, size=(n, 3))
        turn = rng.normal(scale=0.0005, size=(n, 4))
        orientations = orientations + turn
        orientations /= np.linalg.norm(orientations, axis=1)[:, None]
    assert kept >= 6 and rebuilt >= 2 and nl.rebuilds == rebuilt


def test_the_skin_list_refuses_bad_input():
    with pytest.raises(ValueError, match="cutoff"):
        pw.SkinNeighborList(0.5, 0.1)
    with pytest.raises(ValueError, match="skin"):
        pw.SkinNeighborList(1.2, 0.0)
    with pytest.raises(ValueError, match="threads"):
        pw.SkinNeighborList(1.2, 0.1, threads=-1)
    nl = pw.SkinNeighborList(1.2, 0.1)
    with pytest.raises(ValueError):
        nl.update(np.array([[0.0, 0, 0], [np.nan, 0, 0]]), None, [0.5, 0.5, 0.5], box=pw.Box.cube(5))
    result = nl.update(np.array([[0.0, 0, 0], [1.1, 0, 0]]), None, [0.5, 0.5, 0.5], box=pw.Box.cube(5))
    assert result.pairs.tolist() == [[0, 1]] and abs(result.mu2[0] - 1.1**2) < 1e-12


def min_mu2(scene):
    """The smallest mu^2 over every pair of the state, by contact_function
    on all N (N - 1) / 2 pairs (minimum images)."""
    positions, box = scene["positions"], scene["box"]
    q = pw.quadratic_form(scene["semi_axes"], scene["orientations"])
    i, j = np.triu_indices(len(positions), 1)
    r = pw.contact_function(box.wrap_vectors(positions[j] - positions[i]), q[i], q[j], outputs=("mu2",))
    assert np.all(pw.is_valid(r.status))
    return float(r.mu2.min())


def test_monte_carlo_compresses_without_ever_holding_an_overlap():
    mc = pw.HardParticleMC.dilute_spheroids(60, seed=3, packing=0.3, threads=2)
    start = mc.packing
    assert 0 < start < 0.3 and mc.sweeps == 0
    seen = []

    def progress(sweeps, packing, acceptance):
        # The callback may read the state: checked against brute force after
        # every sweep of the compression.
        assert min_mu2(mc.scene()) >= 1
        seen.append((sweeps, packing, acceptance))

    mc.compress_to_packing(max_sweeps=5000, progress=progress)
    assert mc.packing >= 0.3 * (1 - 1e-12)
    assert len(seen) == mc.sweeps > 0 and [s for s, _, _ in seen] == list(range(1, len(seen) + 1))
    assert all(0 <= a <= 1 for _, _, a in seen)
    assert mc.overlapping_pairs() == 0
    report = mc.sweep()
    assert report["proposed"] == 60 and 0 < report["accepted"] <= report["proposed"]
    assert min_mu2(mc.scene()) >= 1
    # The same seed gives the same state.
    again = pw.HardParticleMC.dilute_spheroids(60, seed=3, packing=0.3, threads=1)
    again.compress_to_packing(max_sweeps=5000)
    again.sweep()
    assert np.array_equal(again.scene()["positions"], mc.scene()["positions"])


def test_monte_carlo_from_arrays_and_bad_input():
    scene = pw.HardParticleMC.dilute_spheroids(20, seed=5).scene()
    # 20 spheroids at 0.2 would need a box narrower than the compression's
    # screens allow: refused before any sweep.
    few = pw.HardParticleMC(scene["positions"], scene["orientations"], scene["semi_axes"], box=scene["box"],
                            packing=0.2, seed=9)
    with pytest.raises(ValueError, match="20 particles are too few for the packing fraction"):
        few.compress_to_packing()
    assert few.sweeps == 0
    mc = pw.HardParticleMC(scene["positions"], scene["orientations"], scene["semi_axes"], box=scene["box"],
                           packing=0.1, seed=9)
    assert abs(mc.packing - pw.HardParticleMC.dilute_spheroids(20, seed=5).packing) < 1e-12
    mc.sweep()
    assert min_mu2(mc.scene()) >= 1
    with pytest.raises(ValueError, match="periodic"):
        pw.HardParticleMC(scene["positions"], scene["orientations"], scene["semi_axes"], box=None)
    with pytest.raises(ValueError, match="packing"):
        pw.HardParticleMC(scene["positions"], scene["orientations"], scene["semi_axes"], box=scene["box"],
                          packing=1.5)
    with pytest.raises(ValueError, match="semi_axes"):
        pw.HardParticleMC(scene["positions"], scene["orientations"], scene["semi_axes"][:5], box=scene["box"])
    # An exception from the progress callback ends the compression there,
    # and the state stays usable.
    class Stop(Exception):
        pass

    def stop_at_three(sweeps, packing, acceptance):
        if sweeps == 3:
            raise Stop

    with pytest.raises(Stop):
        mc.compress_to_packing(progress=stop_at_three)
    assert mc.sweeps == 4 and mc.overlapping_pairs() == 0
    # An overlapping start: the compression finds it and says so.
    overlapping = pw.HardParticleMC(np.zeros((2, 3)), None, [0.5, 0.5, 0.5], box=pw.Box.cube(10))
    with pytest.raises(RuntimeError, match="overlap"):
        overlapping.compress()


def test_queries_from_other_threads_while_the_scene_grows():
    # Queries run without the GIL; inserts (which rebuild the cells and move
    # their arrays) meanwhile must wait for them, and they for the inserts.
    import threading

    rng = np.random.default_rng(15)
    box = pw.Box.cube(20)
    scene = pw.MovingScene(rng.uniform(0, 20, (50, 3)), None, [0.3, 0.3, 0.3], box=box)
    stop = threading.Event()
    failures = []

    def query():
        local = np.random.default_rng(16)
        while not stop.is_set():
            try:
                found = scene.overlaps(local.uniform(0, 20, 3), None, [0.3, 0.3, 0.3])
                assert found is None or 0 <= found < 2050
                scene.overlaps_many(local.uniform(0, 20, (8, 3)), None, [0.3, 0.3, 0.3], threads=1)
            except Exception as e:  # noqa: BLE001 (reported below)
                failures.append(e)
                return

    threads = [threading.Thread(target=query) for _ in range(2)]
    for t in threads:
        t.start()
    for k in range(2000):
        # Each a little larger than the last: each insert rebuilds the cells.
        radius = 0.3 + 1e-4 * k
        scene.insert(rng.uniform(0, 20, 3), None, [radius, radius, radius])
    stop.set()
    for t in threads:
        t.join()
    assert not failures, failures
    assert len(scene) == 2050
    for _ in range(20):
        position = rng.uniform(0, 20, 3)
        q = pw.quadratic_form([0.3, 0.3, 0.3], [1, 0, 0, 0])[0]  # (identity: the same as no orientation)
        expected = overlapping(scene, position, q, -1)
        found = scene.overlaps(position, None, [0.3, 0.3, 0.3])
        assert (found is None) == (not expected) and (found is None or found in expected)
