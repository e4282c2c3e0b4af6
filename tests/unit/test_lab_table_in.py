"""A lab's table in, answers it can trust out: a material card exact to the law it carries or
the loss stated, units checked against the values, data-quality indicators and outlying cells
reported, the page in the lab's units."""

import json
import logging

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis import synthetic
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.measured import load_measured
from asphalt_nscd.rheology import export

KSI = 6.894757293168361
SEARCH = ["--alpha", "0.001", "--shift", "wlf", "--identifiability-null", "0.995", "--identifiability-rival", "0.95"]
#: a small candidate grid with and without the vertical shift a card cannot carry
GRID = [
    "--law-shifts",
    "wlf",
    "arrhenius",
    "--law-statics",
    "constant",
    "--law-verticals",
    "off",
    "on",
    "--law-refines",
    "off",
    "--law-per-decades",
    "2",
]


def lab_table(tmp_path, seed=3, vertical=0.0, unit="ksi", quality=None, outlier=None, name="lab", header="|E*| (ksi)"):
    """An AMPT-like table as a US lab writes it (degF, |E*| in ``unit`` with US headers) and its
    sidecar; ``quality``: data-quality columns added; ``outlier``: (T degC, f Hz, phase shift deg)
    applied to every specimen's cell."""
    t, truth = synthetic.generate(
        seed, [], schedule="ampt_pp61", n_specimens=3, vertical_per_100K=vertical, test_order=False
    )
    if outlier is not None:
        T, f, dphi = outlier
        hit = (t["temperature_C"] == T) & (t["frequency_Hz"] == f)
        t.loc[hit, "phase_deg"] += dphi
    frame = pd.DataFrame(
        {
            "Specimen ID": t["specimen"],
            "Temp (F)": t["temperature_C"] * 1.8 + 32,
            "Frequency (Hz)": t["frequency_Hz"],
            header: t["E_norm_MPa"] / KSI,
            "Phase Angle (deg)": t["phase_deg"],
        }
    )
    table = {
        "modulus_unit": unit,
        "temperature_unit": "F",
        "modulus_form": "norm_phase",
        "columns": {"modulus": header},
    }
    if quality is not None:
        for col, values in quality.items():
            frame[col] = values
        table["quality"] = {"load_standard_error_pct": "Load SE (%)", "phase_uniformity_deg": "Phase Unif (deg)"}
    path = tmp_path / f"{name}.csv"
    frame.to_csv(path, index=False)
    (tmp_path / f"{name}.test.json").write_text(
        json.dumps({"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 150, "table": table})
    )
    return path


def chain(tmp_path, table):
    """measured -> calibrate-search -> master-curve -> extend-law -> export-law, as the workflow."""
    d = {
        k: tmp_path / k
        for k in (
            "m.csv",
            "ms.csv",
            "m.test.json",
            "cal.json",
            "mc.json",
            "corr.csv",
            "law.json",
            "card.json",
            "wf.json",
            "cards",
        )
    }
    assert (
        main(
            [
                "measured",
                str(table),
                "-o",
                str(d["m.csv"]),
                "--summary",
                str(d["ms.csv"]),
                "--test-output",
                str(d["m.test.json"]),
            ]
        )
        == 0
    )
    m = ["--measured", str(d["m.csv"])]
    assert (
        main(
            [
                "calibrate-search",
                *m,
                "--test",
                str(d["m.test.json"]),
                *SEARCH,
                "--tables",
                "40",
                "--seed",
                "0",
                "-o",
                str(d["cal.json"]),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "master-curve",
                *m,
                "--test",
                str(d["m.test.json"]),
                *SEARCH,
                "--calibration",
                str(d["cal.json"]),
                "-o",
                str(d["mc.json"]),
                "--corrected",
                str(d["corr.csv"]),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "extend-law",
                *m,
                *SEARCH,
                *GRID,
                "--calibration",
                str(d["cal.json"]),
                "--master-curve",
                str(d["mc.json"]),
                "--corrected-table",
                str(d["corr.csv"]),
                "-o",
                str(d["law.json"]),
                "--card-law",
                str(d["card.json"]),
                "--without-flagged",
                str(d["wf.json"]),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "export-law",
                "--law-json",
                str(d["card.json"]),
                "--selected-law-json",
                str(d["law.json"]),
                "--measured",
                str(d["ms.csv"]),
                "--test",
                str(d["m.test.json"]),
                "-o",
                str(d["cards"]),
            ]
        )
        == 0
    )
    return d


def test_a_vertical_shift_law_gets_a_card_exact_to_the_law_it_carries_with_the_loss_stated(tmp_path, caplog):
    """A ksi/degF table of a mix with a vertical shift (1 decade per 100 K): whatever law is
    selected, the card is exact (the default 1 % / 0.2 deg) to the law it carries; when the selected law
    has a vertical shift, the card carries the best law without one and states, per temperature,
    what it loses against the selected law and its own error against the measured means -- in
    the card's header (degF with degC beside), its JSON and the log's warnings."""
    caplog.set_level(logging.INFO, logger="asphalt_nscd")
    d = chain(tmp_path, lab_table(tmp_path, vertical=1.0))
    card = json.loads((d["cards"] / "prony.json").read_text())
    law = json.loads(d["law.json"].read_text())
    tol = card["check"]["tolerances"]
    assert (tol["E_norm_pct"], tol["phase_deg"]) == export.CARD_TOLERANCE == (1.0, 0.2)
    assert card["exact"] and card["check"]["max_E_norm_difference_pct"] <= tol["E_norm_pct"]
    assert card["check"]["max_phase_difference_deg"] <= tol["phase_deg"]
    selected = law["selection"]["chosen"]
    carriable = not selected["vertical"] and selected["static"] != "trend" and selected["refine"] is None
    # the card's law: the selected settings a card carries, WLF, fitted by least squares (diagnosis.material_card)
    carried = json.loads(d["card.json"].read_text())
    assert carried["model"]["fit_loss"] == "least_squares" and carried["model"]["settings"]["shift"] == "wlf"
    assert not carried["model"]["settings"]["vertical"] and carried["model"]["settings"]["refine"] is None
    assert not card["is_selected_law"] and card["fit"] == "least_squares" and card["selected_fit"] == "robust"
    header = (d["cards"] / "abaqus.inp").read_text()
    assert "degF (" in header and "card vs measured" in header
    errors = pd.read_csv(d["cards"] / "card_errors.csv")
    assert len(errors) == 18 and {"card_vs_measured_logE_pct", "card_vs_law_phase_deg"} <= set(errors.columns)
    per_T = {r["temperature_C"]: r for r in card["loss"]}
    assert set(per_T) == {4.0, 21.0, 37.0, "all"}
    assert "not the selected" in header
    if not carriable:
        assert per_T["all"]["card_vs_law_logE_pct_max"] > tol["E_norm_pct"]  # the loss is real, and stated
        warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
        assert any("cannot carry" in w for w in warned) and "cannot carry" in header


def test_a_unit_declared_wrong_by_6_895_is_named(tmp_path, caplog):
    """The same ksi table declared in MPa: the stiffest cold cell reads 3,000-odd MPa, far below
    any mix at 4 degC; the warning names ksi (x 6.895). A table declared ksi whose header says
    MPa is refused with both units named; an impossible modulus is refused with its line."""
    caplog.set_level(logging.WARNING, logger="asphalt_nscd")
    path = lab_table(tmp_path, unit="MPa", header="Dynamic Modulus")
    table = load_measured(path)
    warned = " ".join(r.getMessage() for r in caplog.records)
    assert "ksi (x 6.895)" in warned and "stiffest cell" in warned
    # and on the page, where the user reads the diagnosis
    from asphalt_nscd.diagnosis.render import quality_lines

    assert any("ksi (x 6.895)" in w for w in table.attrs["warnings"])
    page = "\n".join(quality_lines({"measured": {"warnings": table.attrs["warnings"]}}))
    assert "Checks of the values as read" in page and "ksi (x 6.895)" in page
    good = load_measured(lab_table(tmp_path, name="ok"))
    assert good["E_norm_MPa"].max() > 10000
    t = pd.read_csv(path).rename(columns={"Dynamic Modulus": "E_norm_MPa"})
    t.to_csv(tmp_path / "x.csv", index=False)
    side = json.loads((tmp_path / "lab.test.json").read_text())
    side["table"] = {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase"}
    (tmp_path / "x.test.json").write_text(json.dumps(side))
    with pytest.raises(InputError, match="names the unit MPa.*declares ksi"):
        load_measured(tmp_path / "x.csv")
    t = pd.read_csv(tmp_path / "ok.csv")
    t.loc[3, "|E*| (ksi)"] = 1e300
    t.to_csv(tmp_path / "big.csv", index=False)
    (tmp_path / "big.test.json").write_text((tmp_path / "ok.test.json").read_text())
    # the lab's own column is named beside the project's
    with pytest.raises(InputError, match=r"line 5, column E_norm_MPa \(from '\|E\*\| \(ksi\)' in ksi\).*out of range"):
        load_measured(tmp_path / "big.csv")


def test_quality_flags_and_an_outlying_cell_are_reported_not_dropped(tmp_path):
    """A table with AASHTO T 378 quality columns (a few rows beyond the limits) and one cell
    whose phase is 4 degrees off its isotherm on every specimen: the flagged rows are listed
    with the reason, the law is refitted without them, and the outlying cell is named with its
    size; every row stays in the table."""
    rng = np.random.default_rng(0)
    n = 3 * 3 * 6
    load_se = rng.uniform(1, 8, n)
    load_se[[2, 40]] = [14.0, 21.0]
    phase_u = rng.uniform(0.2, 2.0, n)
    phase_u[7] = 4.5
    path = lab_table(tmp_path, quality={"Load SE (%)": load_se, "Phase Unif (deg)": phase_u}, outlier=(4.0, 25.0, 4.0))
    d = chain(tmp_path, path)
    mc = json.loads(d["mc.json"].read_text())
    ind = mc["quality"]["indicators"]
    assert ind["n_flagged"] == 3 and ind["n_rows"] == n
    assert any("load_standard_error_pct 21 > 10" in r["reason"] for r in ind["flagged"])
    out = mc["quality"]["outliers"]
    assert out and out[0]["temperature_C"] == 4.0 and out[0]["frequency_Hz"] == 25.0 and out[0]["quantity"] == "phase"
    assert out[0]["size"] == pytest.approx(4.0, abs=1.5)
    # an artifact whose evidence rests on the outlying cell (a phase excess at the highest
    # frequency reads as a time lag) is not named
    assert mc["artifacts_corrected"] == []
    wf = json.loads(d["wf.json"].read_text())
    assert wf["source"]["n_flagged"] == 3 and "temperatures" in wf
    assert len(pd.read_csv(d["corr.csv"])) == n  # nothing dropped


def test_the_page_speaks_the_labs_units_and_names_what_ran(tmp_path):
    """The diagnosis page of a degF/ksi table gives temperatures in degF with degC beside, says
    that no simulation ran, has one set of targets, and a loto scheme with 3 isotherms says why
    it has no fold."""
    d = chain(tmp_path, lab_table(tmp_path))
    for scheme in ("lofo", "loto"):
        assert (
            main(
                [
                    "crossval",
                    "--measured",
                    str(d["m.csv"]),
                    *SEARCH,
                    *GRID[:8],
                    "--law-refines",
                    "off",
                    "--law-per-decades",
                    "2",
                    "--calibration",
                    str(d["cal.json"]),
                    "--scheme",
                    scheme,
                    "-o",
                    str(tmp_path / f"{scheme}.csv"),
                    "--figure",
                    str(tmp_path / f"{scheme}.png"),
                ]
            )
            == 0
        )
    page = tmp_path / "page.md"
    assert (
        main(
            [
                "diagnose",
                "--measured",
                str(d["m.csv"]),
                "--test",
                str(d["m.test.json"]),
                "--master-curve",
                str(d["mc.json"]),
                "--corrected-table",
                str(d["corr.csv"]),
                "--law-json",
                str(d["law.json"]),
                "--card",
                str(d["cards"] / "prony.json"),
                "--law-without-flagged",
                str(d["wf.json"]),
                "--crossval",
                str(tmp_path / "lofo.csv"),
                str(tmp_path / "loto.csv"),
                "-o",
                str(tmp_path / "r.json"),
                "--page",
                str(page),
                "--figure",
                str(tmp_path / "b.png"),
            ]
        )
        == 0
    )
    text = page.read_text()
    assert "no simulation ran" in text and "39.2 (4)" in text and "T (degF (degC))" in text
    assert text.count("Targets:") == 1 and "loto*: no fold could be computed" in text
    assert "simulation vs measured" not in text and "## Material card" in text and "## Data quality" in text


def test_quality_indicators_have_limits():
    from asphalt_nscd.lab.checks import LIMITS
    from asphalt_nscd.lab.table_format import QUALITY_INDICATORS

    assert tuple(LIMITS) == QUALITY_INDICATORS


def test_an_implausible_selected_or_card_law_is_warned_about(caplog):
    """A selected law or a card law with parameters at a bound or outside the documented ranges
    is named on the console with its findings; a plausible one is not."""
    from asphalt_nscd.diagnosis.cli import _warn_implausible

    curve = pd.DataFrame(
        {
            "settings": ["a", "b", "c"],
            "plausible": [True, False, False],
            "findings": ["", "beta = 1e+09 at the high bound", "E0 outside"],
            "chosen": [True, False, False],
            "chosen_card": [False, True, False],
        }
    )
    caplog.set_level(logging.WARNING, logger="asphalt_nscd")
    _warn_implausible(curve, card=False)
    assert not caplog.records
    _warn_implausible(curve, card=True)
    warned = [r.getMessage() for r in caplog.records]
    assert len(warned) == 1 and "law of the material card (b)" in warned[0] and "beta = 1e+09" in warned[0]
    curve["chosen"] = [False, False, True]
    caplog.clear()
    _warn_implausible(curve, card=False)
    assert "selected law (c) has implausible parameters: E0 outside" in caplog.records[0].getMessage()


def test_results_from_another_table_are_refused_by_the_page(tmp_path):
    """The master curve, law and card carry the SHA-256 of the measured table they came from;
    the diagnosis refuses to put a result from an earlier table beside a new one, naming it."""
    from asphalt_nscd.diagnosis.cli import same_table

    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("x\n1\n")
    b.write_text("x\n2\n")
    from asphalt_nscd.io import content_sha256

    ha = content_sha256(a)
    assert same_table(a, [("law.json", {"source": {"measured_sha256": ha}}), ("old.json", {"source": {}})]) == ha
    with pytest.raises(InputError, match=r"law\.json: computed from another measured table"):
        same_table(
            b,
            [
                ("mc.json", {"source": {"measured_sha256": content_sha256(b)}}),
                ("law.json", {"source": {"measured_sha256": ha}}),
            ],
        )


def test_the_chain_stamps_its_results_with_the_table(tmp_path):
    d = chain(tmp_path, lab_table(tmp_path))
    from asphalt_nscd.io import content_sha256

    h = content_sha256(d["m.csv"])
    for key in ("cal.json", "mc.json", "law.json", "card.json"):
        assert json.loads(d[key].read_text())["source"]["measured_sha256"] == h, key
    assert json.loads((d["cards"] / "prony.json").read_text())["source"]["measured_sha256"] == h
    assert f"sha256 {h}" in (d["cards"] / "abaqus.inp").read_text()
    assert f"sha256 {h}" in (d["cards"] / "lsdyna.k").read_text()
