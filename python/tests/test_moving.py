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
