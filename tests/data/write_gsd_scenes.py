"""Writes the two committed GSD scenes of scene_files_test with python3-gsd.

  cd tests/data && /usr/bin/python3 write_gsd_scenes.py

hoomd_triclinic.gsd: 60 particles of two types in a triclinic box (HOOMD's
convention, unitless tilts): type A the ellipsoid of semi-axes 0.6, 0.35,
0.25, type B the sphere of diameter 0.7, random orientations.
hoomd_ellipses_2d.gsd: 80 ellipses (a 0.6, b 0.3) in a two-dimensional box
with tilt xy 0.25, rotations about z only (configuration/dimensions = 2).
Centres are uniform in the box's fractional coordinates.
"""
import gsd.hoomd
import numpy as np

Frame = getattr(gsd.hoomd, 'Frame', None) or gsd.hoomd.Snapshot


def centres(rng, n, box, dimensions):
    lx, ly, lz, xy, xz, yz = box
    h = np.array([[lx, xy * ly, xz * lz], [0, ly, yz * lz], [0, 0, lz]])
    s = rng.uniform(-0.5, 0.5, size=(n, 3))
    if dimensions == 2:
        s[:, 2] = 0
    return (s @ h.T).astype(np.float32)


def random_quaternions(rng, n):
    q = rng.normal(size=(n, 4))
    return (q / np.linalg.norm(q, axis=1)[:, None]).astype(np.float32)


def write(name, frame):
    with gsd.hoomd.open(name, 'wb') as out:
        out.append(frame)


rng = np.random.default_rng(20261123)

f = Frame()
f.configuration.box = [6, 6, 5, 0.3, -0.2, 0.1]
f.particles.N = 60
f.particles.types = ['A', 'B']
f.particles.typeid = (np.arange(60) % 2).astype(np.uint32)
f.particles.position = centres(rng, 60, f.configuration.box, 3)
f.particles.orientation = random_quaternions(rng, 60)
f.particles.type_shapes = [{'type': 'Ellipsoid', 'a': 0.6, 'b': 0.35, 'c': 0.25},
                           {'type': 'Sphere', 'diameter': 0.7}]
write('hoomd_triclinic.gsd', f)

f = Frame()
f.configuration.dimensions = 2
f.configuration.box = [9, 8, 0, 0.25, 0, 0]
f.particles.N = 80
f.particles.types = ['E']
f.particles.position = centres(rng, 80, f.configuration.box, 2)
angle = rng.uniform(0, 2 * np.pi, size=80)
f.particles.orientation = np.stack(
    [np.cos(angle / 2), 0 * angle, 0 * angle, np.sin(angle / 2)], axis=1).astype(np.float32)
f.particles.type_shapes = [{'type': 'Ellipsoid', 'a': 0.6, 'b': 0.3}]
write('hoomd_ellipses_2d.gsd', f)
