"""Network factor against resolution: the rows of real (lattice) samples and the summary fit."""

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.harmonic.resolution import resolution_rows, resolution_summary
from asphalt_nscd.sample.settings import level_name
from asphalt_nscd.io import InputError
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import write_sample


def test_level_name():
    assert level_name(0.7, 6.3) == "x0.7_cut6.3" and level_name(1, 2.0) == "x1_cut2"


def test_rows_of_lattice_samples(tmp_path):
    samples = []
    for n, seed in ((40, 1), (60, 2)):
        path = tmp_path / f"s{seed}.h5"
        write_sample(path, lattice_sample(n, seed=seed))
        samples.append((f"n{n}", path))
    rows = resolution_rows(samples, kinematics=("contact", "barycentre"))
    assert len(rows) == 4 and (rows["network_factor"] > 0).all()
    assert set(rows["n_spheres"]) == {40, 60}
    # the barycentre kinematics resists rigid rotations: a stiffer sample than the contact one
    for _, g in rows.groupby("sample"):
        nf = g.set_index("bond_kinematics")["network_factor"]
        assert nf["barycentre"] > nf["contact"]


def test_summary_recovers_a_planted_trend():
    """NF = 1.05 + 2 N^(-1/3) with seed scatter of +-0.01: the level means, their intervals
    (which contain the truth) and the fit's NF_inf within two standard errors of 1.05."""
    rng = np.random.default_rng(0)
    rows = []
    for n in (200, 1500, 9000, 40000):
        for seed in range(4):
            nf = 1.05 + 2 * n ** (-1 / 3) + rng.normal(0, 0.01)
            rows.append({"bond_kinematics": "contact", "level": f"n{n}", "n_spheres": n, "network_factor": nf})
    levels, fits = resolution_summary(pd.DataFrame(rows))
    assert list(levels["n_spheres_mean"]) == [200, 1500, 9000, 40000]
    truth = 1.05 + 2 * levels["n_spheres_mean"] ** (-1 / 3)
    assert (
        (levels["network_factor_ci95_low"] < truth + 0.02) & (truth - 0.02 < levels["network_factor_ci95_high"])
    ).all()
    f = fits.iloc[0]
    assert abs(f["nf_inf"] - 1.05) < 2 * f["nf_inf_se"] + 1e-3 and f["c"] == pytest.approx(2.0, rel=0.1)
    with pytest.raises(InputError):
        resolution_summary(pd.DataFrame())


def test_no_limit_is_claimed_from_a_fit_the_data_reject():
    """Levels that are not monotone in N (the paper-scale study's contact kinematics, committed
    in reference/paper_scale/resolution.csv) reject NF_inf + c N^(-1/3) against the seeds'
    scatter: no limit is stated; a planted trend keeps its accepted fit."""
    from pathlib import Path

    rows = pd.read_csv(Path(__file__).resolve().parents[2] / "reference" / "paper_scale" / "resolution.csv")
    _, fits = resolution_summary(rows)
    for _, f in fits.iterrows():
        assert f["dof"] == 2 and f["chi2"] > 50 and f["p_value"] < 1e-10
        assert not f["accepted"] and np.isnan(f["nf_inf"]) and np.isnan(f["nf_inf_se"])
        assert np.isfinite(f["nf_inf_unaccepted"])
    rng = np.random.default_rng(1)
    planted = [
        {"bond_kinematics": "contact", "level": f"n{n}", "n_spheres": n, "network_factor": 1 + n ** (-1 / 3) + e}
        for n in (200, 1500, 9000, 40000)
        for e in rng.normal(0, 0.01, 4)
    ]
    f = resolution_summary(pd.DataFrame(planted))[1].iloc[0]
    assert f["accepted"] and f["p_value"] >= 0.05 and np.isfinite(f["nf_inf"])
