"""Sample file round trip, VTU output and the Table 2 CLI."""

import json

import h5py
import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.harmonic.network import network_from_sample
from asphalt_nscd.sample.lattice import lattice_sample, sample_from_bonds
from asphalt_nscd.sample.store import (
    SampleData,
    read_sample,
    specimen_geometry_mm,
    write_bonds_vtu,
    write_sample,
    write_vtu,
)


def _sample():
    rng = np.random.default_rng(1)
    n = 5
    return SampleData(
        position=rng.random((n, 3)),
        radius=rng.random(n) * 1e-3 + 1e-3,
        mass=rng.random(n) * 1e-3,
        plate_point=np.array([[0, 0, 0], [0, 0, 0.25]], dtype=float),
        plate_normal=np.array([[0, 0, 1], [0, 0, -1]], dtype=float),
        plate_mass=np.array([np.inf, 0.235]),
        bonds={
            "i": np.array([0, 1, 2]),
            "j": np.array([1, -1, -2]),
            "delta0": np.array([1e-4, 2e-4, 3e-4]),
            "l0": np.array([3e-3, 2e-3, 1.5e-3]),
            "r_min": np.array([1e-3, 1.2e-3, 1.1e-3]),
        },
        attrs={
            "seed": 7,
            "scale": 0.5,
            "density_kg_m3": 3415.0,
            "friction": 0.7,
            "d_min_m": 2e-3,
            "config": {"scale": 0.5},
            "stage": "final",
        },
    )


def test_hdf5_round_trip(tmp_path):
    s = _sample()
    path = tmp_path / "s7.h5"
    write_sample(path, s)
    back = read_sample(path)
    for name in ("position", "radius", "mass", "plate_point", "plate_normal", "plate_mass"):
        np.testing.assert_array_equal(getattr(back, name), getattr(s, name))
    for key, value in s.bonds.items():
        np.testing.assert_array_equal(back.bonds[key], value)
    assert back.attrs["seed"] == 7 and back.attrs["config"] == {"scale": 0.5}
    assert back.attrs["units"]["spheres/inertia"] == "kg m^2"
    with h5py.File(path) as f:
        np.testing.assert_allclose(f["spheres/inertia"][()], 0.4 * s.mass * s.radius**2)
        assert f["bonds/j"].dtype == np.int64
        assert f["spheres/position"].attrs["unit"] == "m"
    with pytest.raises(InputError, match="not found"):
        read_sample(tmp_path / "missing.h5")


def test_vtu_files(tmp_path):
    import meshio

    s = _sample()
    write_vtu(tmp_path / "a.vtu", s.position, s.radius)
    mesh = meshio.read(tmp_path / "a.vtu")
    np.testing.assert_allclose(mesh.points, s.position)
    np.testing.assert_allclose(mesh.point_data["diameter"], 2 * s.radius)
    write_bonds_vtu(tmp_path / "b.vtu", s)
    mesh = meshio.read(tmp_path / "b.vtu")
    assert mesh.cells[0].data.tolist() == [[0, 1]]  # plate bonds are not lines


def test_sample_table_cli(tmp_path):
    summary = tmp_path / "s1_summary.json"
    summary.write_text(json.dumps({"counts_sample": {"6.3": 100, "8": 40, "10": 10}}))
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("sample:\n  scale: 0.5\n  psd:\n    cut_mm: 6.3\n")
    out = tmp_path / "table.csv"
    assert main(["sample-table", "--config", str(cfg), "--summaries", str(summary), "-o", str(out)]) == 0
    t = pd.read_csv(out).set_index("diameter_mm")
    assert t.loc[2.0, "n_paper"] == 11798 and t.loc[2.0, "n_rule_full_scale"] == 11807
    assert t.loc[2.0, "n_config_layer"] == 0 and t.loc[6.3, "n_config_layer"] == 101
    assert t.loc[8.0, "n_sample_mean"] == 40
    bad = tmp_path / "bad.yaml"
    bad.write_text("sample:\n  scal: 0.5\n")
    assert main(["sample-table", "--config", str(bad), "-o", str(out)]) == 2


def test_bond_geometry_of_a_built_sample():
    # sphere 0 at z = 5 mm (r = 1 mm), sphere 1 at 3 mm distance (r = 1.2 mm); plates z = 0, 10 mm
    s = sample_from_bonds(
        [[0, 0, 5e-3], [3e-3, 0, 5e-3]], [1e-3, 1.2e-3], [1e-4, 2e-4], [[0, 0, 0], [0, 0, 0.01]], [0, 0, 1], [1, -1, -2]
    )
    np.testing.assert_allclose(s.bonds["l0"], [3e-3, 5e-3, 5e-3])
    np.testing.assert_allclose(s.bonds["r_min"], [1e-3, 1e-3, 1.2e-3])
    np.testing.assert_allclose(s.bonds["delta0"], [0.8e-3, 4e-3, 3.8e-3])


def test_one_store_for_the_core_and_the_harmonic_solver(tmp_path):
    """The harmonic solver's network is built from the store's data: same arrays, the file's
    name, the specimen size of the root attributes for the head inertia."""
    path = tmp_path / "lat.h5"
    write_sample(path, lattice_sample(30, seed=2, plate_mass=(np.inf, 1e-3)))
    s = read_sample(path)
    net = network_from_sample(s)
    assert net.name == s.name == "lat" and net.n_spheres == 30 and net.n_bonds == len(s.bonds["i"])
    np.testing.assert_array_equal(net.position, s.position)
    np.testing.assert_array_equal(net.rotational_inertia, s.inertia)
    np.testing.assert_allclose(net.scale, np.pi * s.bonds["r_min"] ** 2 / s.bonds["l0"])
    assert specimen_geometry_mm(s) == {"b_mm": 25.0, "B_mm": 56.0, "e_mm": 25.0, "h_mm": 250.0}
    with h5py.File(path, "a") as f:
        f.attrs["b_m"], f.attrs["e_m"], f.attrs["h_m"] = 0.02, 0.01, 0.2
    s = read_sample(path)
    assert specimen_geometry_mm(s) == {"b_mm": 20.0, "B_mm": 56.0, "e_mm": 10.0, "h_mm": 200.0}
    t = 1e-3 / (7850 * 0.02 * 0.01)  # head inertia of a 1 g steel cuboid 20 x 10 mm
    assert network_from_sample(s).plate_inertia[2] == pytest.approx(1e-3 * (0.02**2 + 0.01**2) / 12)
    assert network_from_sample(s).plate_inertia[0] == pytest.approx(1e-3 * (0.01**2 + t**2) / 12 + 1e-3 * t**2 / 4)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda f: f.__delitem__("spheres/inertia"), "dataset 'spheres/inertia' missing"),
        (
            lambda f: (f.__delitem__("bonds/r_min"), f.create_dataset("bonds/r_min", data=np.ones(2))),
            "dataset 'bonds/r_min' has 2 rows, expected 3",
        ),
        (
            lambda f: (f.__delitem__("plates/point"), f.create_dataset("plates/point", data=np.zeros((2, 2)))),
            r"dataset 'plates/point' has shape \(2, 2\)",
        ),
        (lambda f: f["bonds/i"].__setitem__(0, 9), "dataset 'bonds/i' must lie in"),
        (lambda f: f["bonds/j"].__setitem__(0, 0), "dataset 'bonds/j' must lie in"),
        (lambda f: f["bonds/l0"].__setitem__(1, 0.0), "dataset 'bonds/l0' must be positive"),
        (lambda f: f["spheres/mass"].__setitem__(1, np.nan), "dataset 'spheres/mass' must be positive"),
    ],
)
def test_bad_sample_file_names_the_dataset(tmp_path, edit, message):
    path = tmp_path / "s7.h5"
    write_sample(path, _sample())
    with h5py.File(path, "a") as f:
        edit(f)
    with pytest.raises(InputError, match=message) as err:
        read_sample(path)
    assert str(err.value).startswith(str(path))
