"""The sigmoidal (MEPDG) master curve recovers a planted sigmoid; the master-curve figures
command writes its figures and the parameter table from the workflow's own files."""

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.rheology.sigmoid import PARAMETERS, fit_sigmoid, sigmoid_log_modulus


def test_fit_recovers_a_planted_sigmoid():
    truth = {
        "delta": 1.8,
        "alpha": 2.6,
        "beta": -0.8,
        "gamma": -0.5,
        "a1_per_C": -0.12,
        "a2_per_C2": 4e-4,
        "T_ref_C": 21.0,
    }
    T, f = np.meshgrid([-10.0, 4.0, 21.0, 37.0, 54.0], [25.0, 10.0, 5.0, 1.0, 0.5, 0.1])
    E = 10 ** sigmoid_log_modulus(truth, f.ravel(), T.ravel())
    table = pd.DataFrame({"temperature_C": T.ravel(), "frequency_Hz": f.ravel(), "E_norm_MPa": E})
    p = fit_sigmoid(table, 21.0)
    for k in PARAMETERS:
        assert p[k] == pytest.approx(truth[k], rel=1e-4, abs=1e-7), k
    assert p["rmse_log10"] < 1e-8


def test_master_curve_figures_from_the_chain(tmp_path):
    """master-curve -> extend-law -> master-curve-figures on a synthetic table."""
    from asphalt_nscd.diagnosis import synthetic

    table, _ = synthetic.generate(4, schedule="aashto_t342", n_specimens=2)
    table.to_csv(tmp_path / "m.csv", index=False)
    assert (
        main(
            [
                "master-curve",
                "--measured",
                str(tmp_path / "m.csv"),
                "-o",
                str(tmp_path / "mc.json"),
                "--corrected",
                str(tmp_path / "c.csv"),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "extend-law",
                "--measured",
                str(tmp_path / "m.csv"),
                "--law-shifts",
                "wlf",
                "--law-statics",
                "constant",
                "--law-verticals",
                "off",
                "--law-refines",
                "off",
                "--law-per-decades",
                "2",
                "--master-curve",
                str(tmp_path / "mc.json"),
                "--corrected-table",
                str(tmp_path / "c.csv"),
                "-o",
                str(tmp_path / "law.json"),
            ]
        )
        == 0
    )
    out = {k: tmp_path / f"{k}.png" for k in ("master", "shift", "res")}
    assert (
        main(
            [
                "master-curve-figures",
                "--master-curve",
                str(tmp_path / "mc.json"),
                "--corrected-table",
                str(tmp_path / "c.csv"),
                "--law-json",
                str(tmp_path / "law.json"),
                "--master-figure",
                str(out["master"]),
                "--shift-figure",
                str(out["shift"]),
                "--residual-figure",
                str(out["res"]),
                "--residual-table",
                str(tmp_path / "res.csv"),
                "--sigmoid",
                str(tmp_path / "sig.csv"),
            ]
        )
        == 0
    )
    assert all(p.stat().st_size > 10_000 for p in out.values())
    sig = pd.read_csv(tmp_path / "sig.csv")
    assert list(sig["model"]) == ["sigmoid (MEPDG, AASHTO R 84)", "2S2P1D"]
    assert sig.loc[0, "rmse_log10"] < 0.05 and sig.loc[1, "rmse_log10"] < 0.05
    res = pd.read_csv(tmp_path / "res.csv")
    assert len(res) == 30 and res["error_E_norm_pct"].abs().max() < 10
