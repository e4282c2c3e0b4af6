"""Sample preparation with the NSCD core: a tiny deposition, the whole chain, determinism, CLI."""

import json

import numpy as np
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.sample import dynamics, geometry, settings
from asphalt_nscd.sample.prepare import prepare_sample
from asphalt_nscd.sample.store import read_sample

TINY = {
    "seeds": [5],
    "scale": 0.4,  # h = 100 mm, e = 10 mm, B = 22.4 mm
    "psd": {"cut_mm": 8.0},  # 8 and 10 mm spheres, ~50 in the layer
    "box_height_mm": 300.0,
    "deposition": {"time_step_s": 4e-4, "duration_s": 0.8, "settle_velocity_m_s": 0.02},
    "vibration": {"duration_s": 0.04, "time_step_s": 4e-4, "settle_duration_s": 0.02},
    "stabilisation": {"steps": 20},
    "solver": {"tolerance": 1e-3, "max_iterations": 100},
}


@pytest.fixture(scope="module")
def tiny_cfg():
    return settings.merge(settings.DEFAULTS, TINY)


def test_tiny_deposition_ends_at_rest_in_the_box(tiny_cfg):
    geo = settings.scaled_geometry(tiny_cfg)
    r = np.repeat([4e-3, 5e-3], [12, 6])
    p0 = geometry.lattice_positions(r, geo["box"], geo["lattice"], np.random.default_rng(2))
    p, info = dynamics.deposit(p0, r, tiny_cfg, geo)
    assert info["at_rest"] and info["max_speed_end_m_s"] < 0.02
    assert p[:, 2].max() < p0[:, 2].max()  # they fell
    L, W, _ = geo["box"]
    tol = 0.02 * r.min()
    assert np.all(p[:, 2] - r > -tol)
    assert np.all(p[:, 0] - r > -tol) and np.all(p[:, 0] + r < L + tol)
    assert np.all(p[:, 1] - r > -tol) and np.all(p[:, 1] + r < W + tol)
    assert geometry.max_overlap(p, r) < tol
    # a settled granular layer: every sphere is supported (touches the floor or a sphere)
    i, j, _ = geometry.sphere_pairs_within(p, r, tol)
    supported = np.zeros(r.size, bool)
    supported[i] = supported[j] = True
    supported |= p[:, 2] - r < tol
    assert supported.all()


def test_prepare_chain_invariants_and_determinism(tiny_cfg):
    a = prepare_sample(tiny_cfg, 5)
    b = prepare_sample(tiny_cfg, 5)
    np.testing.assert_array_equal(a.sample.position, b.sample.position)
    for key in a.sample.bonds:
        np.testing.assert_array_equal(a.sample.bonds[key], b.sample.bonds[key])
    s = a.sample
    geo = settings.scaled_geometry(tiny_cfg)
    assert s.mass.sum() == pytest.approx(geo["sample_mass"], rel=1e-12)
    assert s.plate_mass[1] == pytest.approx(0.235 * 0.4**3)
    # 10 % volume shrink of 8 and 10 mm spheres
    np.testing.assert_allclose(np.unique(np.round(s.radius, 12)), np.array([4e-3, 5e-3]) * 0.9 ** (1 / 3))
    # bonds only for gaps below d_min (8 mm), recomputed from the stored reference gaps
    assert np.all(s.bonds["delta0"] < 8e-3)
    assert (s.bonds["j"] == -1).any() and (s.bonds["j"] == -2).any()
    # the stabilised sample stays inside the trapezoid up to the sag under gravity
    trap = a.trapezoid
    grown = geometry.Trapezoid(B=trap.B + 2e-4, b=trap.b + 2e-4, e=trap.e + 2e-4, h=trap.h)
    shifted = s.position + np.array([0, 0, 1e-4])
    assert grown.contains(shifted).all()
    summ = a.summary
    assert summ["n_spheres"] == s.radius.size == sum(summ["counts_sample"].values())
    assert 0 < summ["porosity_before_shrink"] < summ["porosity"] < 1
    assert summ["bonds_per_sphere"] == pytest.approx(2 * np.sum(s.bonds["j"] >= 0) / s.radius.size)
    c = prepare_sample(tiny_cfg, 6)
    assert c.sample.radius.size != s.radius.size or not np.allclose(c.sample.position, s.position)


def test_prepare_sample_cli(tmp_path):
    cfg = tmp_path / "sample.json"
    cfg.write_text(json.dumps(TINY))
    out = tmp_path / "s5.h5"
    argv = [
        "prepare-sample",
        "--config",
        str(cfg),
        "--seed",
        "5",
        "-o",
        str(out),
        "--vtk-dir",
        str(tmp_path / "vtk"),
        "--figure",
        str(tmp_path / "stages.png"),
        "--summary",
        str(tmp_path / "summary.json"),
        "--bench",
        str(tmp_path / "bench.json"),
    ]
    assert main(argv) == 0
    s = read_sample(out)
    assert s.attrs["seed"] == 5 and s.attrs["stage"] == "final" and s.attrs["config"]["scale"] == 0.4
    assert s.attrs["h_m"] == pytest.approx(0.1)
    assert sorted(p.name for p in (tmp_path / "vtk").iterdir()) == [
        "bonds.vtu",
        "stage_a_deposit.vtu",
        "stage_b_vibrated.vtu",
        "stage_c_sample.vtu",
    ]
    assert (tmp_path / "stages.png").stat().st_size > 1000
    assert json.loads((tmp_path / "summary.json").read_text())["n_spheres"] == s.radius.size
    # the preparation's own benchmark record, as prepare-bench writes it (test_prepare_bench_cli)
    rec = json.loads((tmp_path / "bench.json").read_text())
    assert rec["case"] == "prepare" and rec["seed"] == 5 and rec["sample"]["n_spheres"] == s.radius.size
    assert rec["phases"]["total"]["cpu_s"] > 0 and rec["config"] == str(cfg)


def test_rest_measure_rms_ends_deposition_no_later_than_max(tiny_cfg):
    """The rms speed never exceeds the largest speed: the 'rms' test ends the deposition at
    the same check or earlier, and the layer is then at rest by its own measure."""
    geo = settings.scaled_geometry(tiny_cfg)
    r = np.repeat([4e-3, 5e-3], [12, 6])
    p0 = geometry.lattice_positions(r, geo["box"], geo["lattice"], np.random.default_rng(2))
    _, info_max = dynamics.deposit(p0, r, tiny_cfg, geo)
    cfg = settings.merge(tiny_cfg, {"deposition": {"rest_measure": "rms"}})
    p, info_rms = dynamics.deposit(p0, r, cfg, geo)
    assert info_rms["rest_measure"] == "rms" and info_rms["at_rest"]
    assert info_rms["steps"] <= info_max["steps"]
    assert info_rms["rest_speed_end_m_s"] <= info_rms["max_speed_end_m_s"]
    bad = settings.merge(tiny_cfg, {"deposition": {"rest_measure": "mean"}})
    with pytest.raises(InputError, match="rest_measure"):
        dynamics.deposit(p0, r, bad, geo)


def test_prepare_bench_cli(tmp_path):
    """prepare-bench: one preparation timed by phase (CPU and wall, summing to the total),
    NLGS statistics per dynamic stage, counts beside Table 2, and the sample file."""
    cfg = tmp_path / "sample.json"
    cfg.write_text(json.dumps(TINY))
    out = tmp_path / "bench.json"
    assert (
        main(
            ["prepare-bench", "--config", str(cfg), "--seed", "5", "-o", str(out), "--sample", str(tmp_path / "s5.h5")]
        )
        == 0
    )
    rec = json.loads(out.read_text())
    s = read_sample(tmp_path / "s5.h5")
    assert rec["case"] == "prepare" and rec["seed"] == 5
    assert rec["sample"]["n_spheres"] == s.radius.size
    assert rec["sample"]["n_bonds"] == s.bonds["i"].size
    assert rec["sample"]["density_paper_kg_m3"] == 3415.0
    phases = ["lattice", "deposition", "vibration", "cut_flip", "plates_shrink", "bonds", "stabilisation"]
    for key in ("cpu_s", "wall_s"):
        parts = sum(rec["phases"][p][key] for p in phases)
        assert parts == pytest.approx(rec["phases"]["total"][key], rel=1e-9)
    vib = rec["phases"]["vibration_shaking"]["cpu_s"] + rec["phases"]["vibration_settling"]["cpu_s"]
    assert vib <= rec["phases"]["vibration"]["cpu_s"] + 1e-3
    dep = rec["nscd"]["deposition"]
    assert dep["steps"] > 0 and 1 <= dep["mean_nlgs_iterations"] <= dep["max_nlgs_iterations"] <= 100
    rows = {row["diameter_mm"]: row for row in rec["table2"]}
    assert rows[2.0]["n_paper"] == 11798 and rows[8.0]["n_layer"] > 0
    assert rec["table2_max_abs_pct"] == pytest.approx(
        max(abs(r["rel_diff_pct"]) for r in rec["table2"] if r["rel_diff_pct"] is not None)
    )
