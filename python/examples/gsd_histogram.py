"""A GSD file -> its pairs -> a histogram, as README's Python section shows.

    /usr/bin/python3 python/examples/gsd_histogram.py [FILE.gsd] [-o OUT.png]

Without FILE, writes a scene first (40,000 spheroids of aspect 1/3 .. 3 at
packing fraction 0.3, with python3-gsd) to show the whole round trip. Needs
python3-matplotlib for the figure.
"""
import argparse
import os
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import gsd.hoomd  # noqa: E402

import pwcontact as pw  # noqa: E402


def write_demo(path):
    """The demo scene as HOOMD-blue would hold it: one Ellipsoid type per shape."""
    scene = pw.spheroid_scene(40_000, seed=1, packing=0.3)
    shapes, typeid = np.unique(scene["semi_axes"], axis=0, return_inverse=True)
    frame = gsd.hoomd.Frame() if hasattr(gsd.hoomd, "Frame") else gsd.hoomd.Snapshot()
    frame.particles.N = len(typeid)
    box = scene["box"]
    frame.configuration.box = [box.Lx, box.Ly, box.Lz, 0, 0, 0]
    frame.particles.position = box.wrap_vectors(scene["positions"]).astype(np.float32)
    frame.particles.orientation = scene["orientations"].astype(np.float32)
    frame.particles.types = [f"S{k}" for k in range(len(shapes))]
    frame.particles.typeid = typeid.astype(np.uint32)
    frame.particles.type_shapes = [{"type": "Ellipsoid", "a": a, "b": b, "c": c} for a, b, c in shapes]
    with gsd.hoomd.open(path, "wb") as f:
        f.append(frame)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", nargs="?", help="a GSD file (default: a demo scene written first)")
    parser.add_argument("-o", "--output", default="pwcontact_histogram.png")
    args = parser.parse_args()
    path = args.file
    if path is None:
        path = os.path.join(tempfile.mkdtemp(), "demo.gsd")
        write_demo(path)

    scene = pw.read_gsd(path)  # positions, orientations, type_semi_axes, typeid, box
    near = pw.screen(**scene, cutoff=1.5, with_mu2=True)  # every pair with mu < 1.5
    overlapping = near.mu2 < 1
    per_particle = np.bincount(near.pairs[overlapping].ravel(), minlength=len(scene["positions"]))

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    left.hist(near.mu2, bins=120, color="tab:blue")
    left.axvline(1.0, color="k", lw=1)
    left.set_xlabel(r"$\mu^2$ of the pairs with $\mu < 1.5$")
    left.set_ylabel("pairs")
    left.set_title(f"{len(near):,} pairs, {overlapping.sum():,} overlapping")
    counts = np.bincount(per_particle)
    right.bar(np.arange(len(counts)), counts, color="tab:orange")
    right.set_xlabel("overlaps per particle")
    right.set_ylabel("particles")
    right.set_yscale("log")
    right.set_title(f"{len(scene['positions']):,} spheroids, packing 0.3")
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    print(f"{path}: {len(near)} pairs with mu < 1.5, {overlapping.sum()} overlapping; wrote {args.output}")


if __name__ == "__main__":
    main()
