"""Shared fixtures: the oracle data and the command line beside the build."""
import os
import pathlib

import numpy as np
import pytest


def shared_dir() -> pathlib.Path:
    given = os.environ.get("PWCONTACT_SHARED")
    if given:
        return pathlib.Path(given)
    return pathlib.Path(__file__).resolve().parents[2].parent / "shared"


@pytest.fixture(scope="session")
def reference_pairs():
    """The 3,000 pairs with mu2 and lambda from an independent quad-precision
    solver: {family: (r12, q1, q2, mu2, lambda)}."""
    path = shared_dir() / "data" / "reference_pairs.txt"
    if not path.exists():
        pytest.fail(f"the oracle data is missing: {path}")
    families = {}
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            fields = line.split()
            families.setdefault(fields[0], []).append([float(x) for x in fields[1:]])
    out = {}
    for name, rows in families.items():
        a = np.array(rows)
        out[name] = (a[:, 0:3], a[:, 3:9], a[:, 9:15], a[:, 15], a[:, 16])
    return out


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("PWCONTACT_CLI")
    if not path or not os.path.exists(path):
        pytest.skip("PWCONTACT_CLI (the pwcontact command) is not given")
    return path
