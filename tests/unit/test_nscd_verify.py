"""The verification table of the NSCD core (asphalt-nscd verify) passes its tolerances."""

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.nscd import verify


@pytest.fixture(scope="module")
def verify_rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("nscd_verify")
    status = main(
        [
            "verify",
            "-o",
            str(out / "verify.json"),
            "--csv",
            str(out / "verify.csv"),
            "--phase-table",
            str(out / "phase.csv"),
            "--figure",
            str(out / "phase.png"),
            "--phase-frequencies",
            "40",
            "--phase-dts",
            "2e-5,1e-4",
            "--phase-thetas",
            "0.5,1.0",
            "--strict",
        ]
    )
    rows = json.loads((out / "verify.json").read_text())
    return status, rows, out


def test_verify_cli_writes_all_outputs(verify_rows):
    status, rows, out = verify_rows
    assert status == 0
    for name in ("verify.csv", "phase.csv", "phase.png"):
        assert (out / name).stat().st_size > 0
    cols = {"case", "quantity", "numerical", "analytic", "relative_error", "tolerance", "passed"}
    assert cols <= set(rows[0])


@pytest.mark.parametrize(
    "case",
    [
        "creep_normal",
        "creep_tangential",
        "relaxation",
        "sinusoid",
        "phase_table",
        "rest",
        "incline_block",
        "incline_rolling",
        "column",
        "impact",
        "breakage_normal",
        "breakage_tangential",
        "dissipation",
        "fast_path",
        "fast_path_contacts",
        "solver_tolerance",
    ],
)
def test_verification_case_passes(verify_rows, case):
    _, rows, _ = verify_rows
    sel = [r for r in rows if r["case"] == case]
    assert sel, f"no rows for {case}"
    for r in sel:
        assert r["passed"], r
        assert r["relative_error"] <= r["tolerance"]


def test_phase_error_table_theta_one_lags_and_converges():
    """Backward Euler (theta = 1) lags, with an error ~ proportional to omega dt; theta = 0.5
    is second order (error / 4 when dt / 2)."""
    t = verify.phase_error_table(verify.LAW_15C, (2 * np.pi * 40,), (5e-5, 1e-4), (0.5, 1.0))
    e1 = t[t.theta == 1.0].sort_values("dt_s").phase_error_deg.to_numpy()
    e05 = t[t.theta == 0.5].sort_values("dt_s").phase_error_deg.to_numpy()
    assert np.all(e1 < 0)
    assert e1[1] / e1[0] == pytest.approx(2.0, rel=0.05)
    assert abs(e05[1] / e05[0]) == pytest.approx(4.0, rel=0.1)
    assert isinstance(t, pd.DataFrame)


def test_relaxation_closed_form_matches_burgers_limits():
    """The matrix-exponential relaxation starts at Km x gap and decays (Maxwell fluid)."""
    micro = verify.bond_law(verify.LAW_15C)
    r = verify.relaxation_response(micro, 1e-6, [1e-9, 10.0])
    assert r[0] == pytest.approx(-micro.Em * 1e-6, rel=1e-6)
    assert abs(r[1]) < 1e-3 * abs(r[0])
