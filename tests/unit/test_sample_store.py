"""Sample file round trip, VTU output and the Table 2 CLI."""

import json

import h5py
import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.sample.store import SampleData, read_sample, write_sample, write_bonds_vtu, write_vtu


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
        attrs={"seed": 7, "scale": 0.5, "density_kg_m3": 3415.0, "friction": 0.7, "d_min_m": 2e-3,
               "config": {"scale": 0.5}, "stage": "final"},
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
