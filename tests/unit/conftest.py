"""Shared fixtures of the unit tests."""

import numpy as np
import pytest


@pytest.fixture(scope="module")
def tiny_sample(tmp_path_factory):
    """A 40-sphere bonded lattice sample (docs/design.md format), light head plate (1 g)."""
    from asphalt_nscd.sample.lattice import lattice_sample
    from asphalt_nscd.sample.store import write_sample

    path = tmp_path_factory.mktemp("sample") / "s1.h5"
    write_sample(path, lattice_sample(40, seed=3, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    return path
