"""Any table that ``measured`` accepts goes through the chain without a traceback.

Property-based tests (hypothesis, profile ``ci`` of tests/conftest.py) over the tables of
:func:`strategies.measured_tables`, and fixed regression tables (tests/data, written by
tests/data/make_regression_tables.py): the AMPT-like 3 specimens x 3 temperatures x 6
frequencies table of the second real mix, a 3-frequency table, an unbalanced table and an
extreme-phase table.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from diagnosis_chain import diagnose_table as diagnose
from hypothesis import given, settings
from strategies import measured_tables, write_table

from asphalt_nscd.diagnosis.render import markdown_page
from asphalt_nscd.io import json_safe
from asphalt_nscd.lab.measured import load_measured
from asphalt_nscd.rheology.calibration import PARAM_COLUMNS, fit_table

DATA = Path(__file__).resolve().parents[1] / "data"
REGRESSION = ["ampt_like_3x3x6.csv", "three_frequencies.csv", "unbalanced.csv", "extreme_phase.csv"]


def _check_report(report: dict, table: pd.DataFrame) -> None:
    json.dumps(json_safe(report))
    names = [e["name"] for e in report["effects"]]
    assert len(names) == len(set(names)) == 10
    for e in report["effects"]:
        assert isinstance(e["testable"], bool)
        if not e["testable"]:
            assert e["evidence"].startswith("not testable: ") and len(e["evidence"]) > 20
            assert not e["detected"]
    assert set(report["causes"]) <= set(names)
    assert report["measured"]["temperatures_C"] == sorted(table["temperature_C"].unique().tolist())
    markdown_page(report)


@given(measured_tables())
def test_measured_and_fit_accept_every_generated_table(table):
    with tempfile.TemporaryDirectory() as d:
        measured = load_measured(write_table(table, d))
    assert len(measured) == len(table)
    params = fit_table(measured)
    assert params["temperature_C"].tolist() == sorted(table["temperature_C"].unique())
    assert np.isfinite(params[list(PARAM_COLUMNS)].to_numpy()).all()
    assert (params[list(PARAM_COLUMNS)].to_numpy() > 0).all()


@settings(max_examples=10)
@given(measured_tables(max_specimens=4, max_temperatures=6, max_frequencies=7))
def test_diagnose_runs_on_every_generated_table(table):
    with tempfile.TemporaryDirectory() as d:
        measured = load_measured(write_table(table, d))
    report, extra = diagnose(measured)
    _check_report(report, table)
    assert len(extra["corrected"]) == len(table)


def test_fit_accepts_three_frequencies():
    """Three complex points are six real numbers for four parameters."""
    from asphalt_nscd.rheology.calibration import burgers_isotherm, fit_burgers

    truth = {"Em_MPa": 30000.0, "eta_m_MPa_s": 3000.0, "Ek_MPa": 9000.0, "eta_k_MPa_s": 300.0}
    f = np.array([10.0, 1.0, 0.1])
    E, phi = burgers_isotherm(truth, f)
    fit = fit_burgers(f, E, phi)
    for k, v in truth.items():
        assert fit[k] == pytest.approx(v, rel=1e-5)
    assert np.isfinite(fit["Em_MPa_se"])  # 6 residuals, 4 parameters: 2 degrees of freedom
    two = fit_burgers(f[:2], E[:2], phi[:2])  # exactly determined: no standard error
    assert np.isnan(two["Em_MPa_se"]) and two["mre_E_pct"] < 1e-6
    with pytest.raises(ValueError, match="2 or more distinct frequencies"):
        fit_burgers([1.0, 1.0, 1.0], E[:3], phi[:3])


def test_regression_tables_are_the_generator_output():
    sys.path.insert(0, str(DATA))
    import make_regression_tables as gen

    for name, frame in gen.tables().items():
        stored = pd.read_csv(DATA / name)
        pd.testing.assert_frame_equal(stored, frame.reset_index(drop=True), check_dtype=False, rtol=1e-12)
    for name, obj in gen.SIDECARS.items():
        assert json.loads((DATA / name).read_text()) == obj


@pytest.mark.parametrize("name", REGRESSION)
def test_regression_table_goes_through_diagnose(name):
    measured = load_measured(DATA / name)
    report, _ = diagnose(measured)
    _check_report(report, measured)
    by = {e["name"]: e for e in report["effects"]}
    # synthetic 2S2P1D tables: a Burger's law cannot follow them, no artifact was planted
    assert by["broad_spectrum"]["testable"] and by["broad_spectrum"]["detected"]
    assert not any(
        by[n]["detected"]
        for n in ("time_lag", "inertia_uncorrected", "temperature_offset", "strain_nonlinearity", "self_heating")
    )


def test_ampt_like_table_declares_a_uniaxial_test_and_inertia_uses_its_form_factor():
    measured = load_measured(DATA / "ampt_like_3x3x6.csv")
    test = measured.attrs["test"]
    assert test.test == "uniaxial_cylinder"
    assert test.form_factor_per_mm == pytest.approx(150.0 / (np.pi * 50.0**2))
    report, _ = diagnose(measured)
    inertia = {e["name"]: e for e in report["effects"]}["inertia_uncorrected"]
    assert inertia["testable"]
    assert "uniaxial_cylinder" in inertia["evidence"]
    # without the sidecar the geometry is unknown: inertia is not testable, the rest goes on
    with tempfile.TemporaryDirectory() as d:
        bare = load_measured(write_table(pd.read_csv(DATA / "ampt_like_3x3x6.csv"), d))
    assert bare.attrs["test"].test == "unknown"
    report, _ = diagnose(bare)
    inertia = {e["name"]: e for e in report["effects"]}["inertia_uncorrected"]
    assert not inertia["testable"] and "geometry is unknown" in inertia["evidence"]


def test_prony_without_glassy_compliance_does_not_stop_diagnose(monkeypatch):
    """Second real mix: ``ValueError: Prony fit gave no glassy compliance (J0 = 0)`` from
    rheology.models.fit_generalized_kelvin, called by causes.broad_spectrum, stopped
    diagnose. The count of Kelvin-Voigt units is now reported as not computable, with the
    reason, and the rest of the report goes on."""
    from asphalt_nscd.diagnosis import causes
    from asphalt_nscd.rheology.models import fit_generalized_kelvin

    # the failure itself: a target with no glassy compliance (a single Kelvin-Voigt unit)
    w = np.logspace(-2, 2, 30)
    with pytest.raises(ValueError, match="no glassy compliance"):
        fit_generalized_kelvin(w, 100.0 + 1j * w * 10.0, np.logspace(-3, 1, 9))

    def no_glassy(*args, **kwargs):
        raise ValueError("Prony fit gave no glassy compliance (J0 = 0); give glassy_modulus or widen the grid")

    monkeypatch.setattr(causes, "fit_generalized_kelvin", no_glassy)
    measured = load_measured(DATA / "ampt_like_3x3x6.csv")
    report, _ = diagnose(measured)
    _check_report(report, measured)
    bs = {e["name"]: e for e in report["effects"]}["broad_spectrum"]
    assert bs["testable"] and bs["estimate"]["kelvin_units_needed"] is None
    assert "no glassy compliance" in bs["estimate"]["kelvin_units_reason"]


@pytest.mark.parametrize("name", ["ampt_like_3x3x6.csv", "three_frequencies.csv"])
def test_cli_chain_runs_on_regression_tables(tmp_path, name):
    """measured -> fit -> master-curve -> extend-law -> diagnose, as the workflow calls them."""
    exe = [sys.executable, "-m", "asphalt_nscd.cli"]
    src = DATA / name

    def run(*args):
        proc = subprocess.run(exe + list(args), capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "Traceback" not in proc.stderr

    run(
        "measured",
        str(src),
        "-o",
        str(tmp_path / "measured.csv"),
        "--summary",
        str(tmp_path / "summary.csv"),
        "--test-output",
        str(tmp_path / "measured.test.json"),
    )
    run("fit", "--measured", str(tmp_path / "measured.csv"), "--model", "burgers", "-o", str(tmp_path / "burgers.csv"))
    run(
        "master-curve",
        "--measured",
        str(tmp_path / "measured.csv"),
        "-o",
        str(tmp_path / "mc.json"),
        "--corrected",
        str(tmp_path / "corrected.csv"),
    )
    run(
        "extend-law",
        "--measured",
        str(tmp_path / "measured.csv"),
        "--master-curve",
        str(tmp_path / "mc.json"),
        "--corrected-table",
        str(tmp_path / "corrected.csv"),
        "-o",
        str(tmp_path / "law.json"),
    )
    run(
        "diagnose",
        "--measured",
        str(tmp_path / "measured.csv"),
        "--master-curve",
        str(tmp_path / "mc.json"),
        "--corrected-table",
        str(tmp_path / "corrected.csv"),
        "--macro-params",
        str(tmp_path / "burgers.csv"),
        "--law-json",
        str(tmp_path / "law.json"),
        "-o",
        str(tmp_path / "report.json"),
        "--page",
        str(tmp_path / "p.md"),
    )
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["measured"]["test"]["test"] == json.loads((tmp_path / "measured.test.json").read_text())["test"]


def test_crossval_says_what_a_table_too_thin_for_a_master_curve_lacks(tmp_path, capsys):
    """A table of one frequency per isotherm: crossval stops with the design's message (as
    master-curve and extend-law do) instead of writing rows that nothing can be computed from."""
    from asphalt_nscd.cli import main

    table = pd.read_csv(DATA / "three_frequencies.csv")
    one = table[table["frequency_Hz"] == table["frequency_Hz"].max()]
    path = tmp_path / "one_frequency.csv"
    one.to_csv(path, index=False)
    assert (
        main(["crossval", "--measured", str(path), "--scheme", "lofo", "--no-burgers", "-o", str(tmp_path / "cv.csv")])
        == 2
    )
    assert "needs >= 2 isotherms with >= 3 tested frequencies" in capsys.readouterr().err
    assert not (tmp_path / "cv.csv").exists()
