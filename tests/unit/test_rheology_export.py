"""Material cards of the extended law: each exported card (Abaqus, LS-DYNA, JSON) evaluated
back at every measured (T, f) matches the law within the card's tolerance (default 1 % in |E*| and 0.2 deg in Phi); a law
a single Prony series with a WLF shift cannot carry is refused, naming what is lost (the law a
card carries instead: tests/unit/test_lab_table_in.py)."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis import synthetic
from asphalt_nscd.rheology import export, law_file

LAW = [
    "--law-shifts",
    "wlf",
    "--law-statics",
    "constant",
    "--law-refines",
    "off",
    "--law-per-decades",
    "2",
    "--no-artifacts",
]


def _law(tmp_path, extra=("--law-verticals", "off")):
    """The law JSON of a synthetic table and the table's measured summary."""
    table, _ = synthetic.generate(3, schedule="aashto_t342", n_specimens=2)
    table.drop(columns="test_order").to_csv(tmp_path / "m.csv", index=False)
    out = tmp_path / "law.json"
    assert main(["extend-law", "--measured", str(tmp_path / "m.csv"), *LAW, *extra, "-o", str(out)]) == 0
    assert (
        main(["measured", str(tmp_path / "m.csv"), "-o", str(tmp_path / "t.csv"), "--summary", str(tmp_path / "s.csv")])
        == 0
    )
    return out, tmp_path / "s.csv"


def _abaqus(text):
    lines = text.splitlines()
    k = lines.index("*ELASTIC, MODULI=INSTANTANEOUS")
    E0 = float(lines[k + 1].split(",")[0])
    j = lines.index("*VISCOELASTIC, TIME=PRONY")
    terms = []
    for ln in lines[j + 1 :]:
        if ln.startswith("*"):
            break
        g, kk, tau = (float(v) for v in ln.split(","))
        assert g == kk
        terms.append((g, tau))
    t = lines.index("*TRS, DEFINITION=WLF")
    T_ref, C1, C2 = (float(v) for v in lines[t + 1].split(","))
    return E0, terms, (T_ref, C1, C2)


def _lsdyna(text):
    rows = [ln for ln in text.splitlines() if not ln.startswith(("$", "*"))]
    fixed = [float(rows[0][10 * i : 10 * i + 10]) for i in range(8)]
    T_ref, C1, C2 = fixed[5], fixed[6], fixed[7]
    terms = [[float(r[10 * i : 10 * i + 10]) for i in range(4)] for r in rows[2:]]
    return terms, (T_ref, C1, C2)


def test_exported_cards_round_trip(tmp_path):
    law_path, table = _law(tmp_path)
    cards = tmp_path / "cards"
    assert main(["export-law", "--law-json", str(law_path), "--measured", str(table), "-o", str(cards)]) == 0
    cells = pd.read_csv(table)[["temperature_C", "frequency_Hz"]].drop_duplicates()
    T, f = cells["temperature_C"].to_numpy(float), cells["frequency_Hz"].to_numpy(float)
    laws = {t: g.scaled(1e-6) for t, g in law_file.read(law_path).items()}
    E_law = law_file.complex_modulus(laws, T, f)

    def check(E):
        assert np.max(np.abs(np.abs(E) / np.abs(E_law) - 1)) <= export.CARD_TOLERANCE[0] / 100
        assert np.max(np.abs(np.degrees(np.angle(E) - np.angle(E_law)))) <= export.CARD_TOLERANCE[1]

    def prony(E0, g_inf, terms, shift, wr_of):
        wr = wr_of(shift)
        E = np.full(wr.shape, E0 * g_inf, complex)
        for g, tau in terms:
            E += E0 * g * 1j * wr * tau / (1 + 1j * wr * tau)
        return E

    def wr_of(shift):
        T_ref, C1, C2 = shift
        return 2 * np.pi * f * 10.0 ** (-C1 * (T - T_ref) / (C2 + T - T_ref))

    card = json.loads((cards / "prony.json").read_text())
    assert card["exact"] and card["check"]["max_E_norm_difference_pct"] <= card["check"]["tolerances"]["E_norm_pct"]
    check(
        prony(
            card["E_0_MPa"],
            card["g_inf"],
            [(t["g"], t["tau_s"]) for t in card["terms"]],
            (card["shift"]["T_ref_C"], card["shift"]["C1"], card["shift"]["C2_K"]),
            wr_of,
        )
    )
    E0, terms, shift = _abaqus((cards / "abaqus.inp").read_text())
    g_inf = 1 - sum(g for g, _ in terms)  # Abaqus: the long-term part is what the g_i leave
    check(prony(E0, g_inf, terms, shift, wr_of))
    rows, shift = _lsdyna((cards / "lsdyna.k").read_text())
    nu = card["nu"]
    E_terms = [(gi * 2 * (1 + nu), 1 / beta if beta > 0 else math.inf) for gi, beta, _, _ in rows]
    wr = wr_of(shift)
    E = sum(e if math.isinf(tau) else e * 1j * wr * tau / (1 + 1j * wr * tau) for e, tau in E_terms)
    # the LS-DYNA card prints 4 significant digits: 0.05 %
    assert np.max(np.abs(np.abs(E) / np.abs(E_law) - 1)) <= 0.006
    table_csv = pd.read_csv(cards / "prony.csv")
    assert table_csv["g"].sum() == pytest.approx(1.0, rel=1e-9)


def test_a_law_with_a_vertical_shift_is_refused(tmp_path, capsys):
    law_path, table = _law(tmp_path, ("--law-verticals", "on"))
    law = json.loads(law_path.read_text())
    assert law["model"]["settings"]["vertical"]
    # make the vertical trend large: a Prony series with a shift cannot carry it
    law["model"]["backbone"]["vertical_trend_per_100K"] = 0.5
    laws = {float(k): v for k, v in law["temperatures"].items()}
    T_ref = law["model"]["T_ref_C"]
    for T, entry in laws.items():
        b = 10 ** (0.5 * (T - T_ref) / 100)
        for key in ("Em", "eta_m", "E_inf"):
            if entry.get(key) is not None:
                entry[key] *= b
        entry["Ek"] = [e * b for e in entry["Ek"]]
        entry["eta_k"] = [e * b for e in entry["eta_k"]]
    law["temperatures"] = {f"{T:g}": e for T, e in laws.items()}
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(law))
    out = tmp_path / "c"
    assert main(["export-law", "--law-json", str(bad), "--measured", str(table), "-o", str(out)]) == 2
    assert not (out / "abaqus.inp").exists() and not (out / "prony.json").exists()
    assert "vertical shift" in capsys.readouterr().err
    # there is no option that writes it anyway
    with pytest.raises(SystemExit):
        main(["export-law", "--law-json", str(bad), "--measured", str(table), "-o", str(out), "--allow-loss"])
    assert not out.exists() or not any(out.iterdir())


def test_arrhenius_is_carried_as_its_exact_wlf_form():
    """An Arrhenius shift is the WLF law with C2 = T_ref + 273.15 K and C1 = Ea / (R ln10 T_ref):
    the card's fitted WLF reproduces it to round-off over the calibrated range."""
    from asphalt_nscd.rheology.shift import arrhenius_log_shift

    T = np.linspace(-10, 54, 30)
    a = arrhenius_log_shift(T, 21.0, 200e3)
    C2 = 21.0 + 273.15
    C1 = 200e3 / (8.314462618 * np.log(10) * C2)
    assert np.allclose(export.wlf_log_shift(T, 21.0, C1, C2), a, atol=1e-9)


def test_fewest_terms_meets_its_tolerance_with_no_spare_term():
    """A 5-term relaxation series over 6 decades is matched within 0.5 % / 0.2 deg by at most
    5 free terms; every smaller N tried misses the tolerance, and the card's curve says so."""
    from asphalt_nscd.rheology.models import generalized_maxwell_modulus

    tau = np.logspace(-4, 2, 5)
    E_i = np.array([8000.0, 6000.0, 3000.0, 1200.0, 400.0])
    omega = np.logspace(-3, 5, 161)
    E = generalized_maxwell_modulus(omega, 50.0, E_i, tau)
    fit = export.fewest_terms(omega, E, (0.5, 0.2))
    assert fit["met"] and fit["n"] <= 5
    assert fit["max_E_pct"] <= 0.5 and fit["max_phase_deg"] <= 0.2
    for row in fit["curve"][:-1]:
        assert row["max_E_pct"] > 0.5 or row["max_phase_deg"] > 0.2
    E_fit = generalized_maxwell_modulus(omega, fit["E_inf"], fit["E_i"], fit["tau_s"])
    assert np.max(np.abs(np.log(np.abs(E_fit) / np.abs(E)))) <= 0.005 + 1e-9


def test_creep_compliance_is_the_exact_interconversion_of_the_card(tmp_path):
    """D(t) of a card: D(0) = 1/E_0, D(inf) = 1/E_inf, rising monotonically, and the
    interconversion identity int_0^t E(t - u) dD(u) = 1 holds to 1e-9 at every time and
    temperature written (relaxation_creep.csv), E_T(t) = E_ref(t / aT)."""
    law_path, table = _law(tmp_path)
    cards = tmp_path / "cards"
    assert main(["export-law", "--law-json", str(law_path), "--measured", str(table), "-o", str(cards)]) == 0
    card = json.loads((cards / "prony.json").read_text())
    ct = export.creep_terms(card)
    assert ct["D_0"] == pytest.approx(1 / card["E_0_MPa"], rel=1e-9)
    assert ct["D_inf"] == pytest.approx(1 / card["E_inf_MPa"], rel=1e-12) and (ct["d"] > 0).all()
    f = pd.read_csv(cards / "relaxation_creep.csv")
    assert f["check"].abs().max() < 1e-9
    for T, g in f.groupby("temperature_C"):
        assert np.all(np.diff(g["D_per_MPa"]) >= 0) and np.all(np.diff(g["E_MPa"]) <= 0)
        assert np.allclose(g["G_MPa"], g["E_MPa"] / (2 * (1 + card["nu"])))
    ref, hot = f[f["temperature_C"] == card["T_ref_C"]], f[f["temperature_C"] == f["temperature_C"].max()]
    assert hot["E_MPa"].iloc[10] < ref["E_MPa"].iloc[10]  # a warmer mix relaxes sooner
    ic = card["interconversion"]
    assert ic["met"] and ic["max_abs_residual"] == pytest.approx(f["check"].abs().max(), abs=1e-15)
    header = (cards / "abaqus.inp").read_text()
    assert "interconverted exactly" in header and "Poisson's ratio 0.35: the paper's value" in header
    assert f"{len(card['terms'])} Prony terms: the fewest within 1" in header
    # the card's figures: isochrones against the measured means, E(t) and D(t), the error against N
    figs = [str(tmp_path / "iso.png"), str(tmp_path / "rc.png"), str(tmp_path / "n.png")]
    base = [
        "card-figures",
        "--card",
        str(cards / "prony.json"),
        "--functions",
        str(cards / "relaxation_creep.csv"),
        "--isochrones",
        figs[0],
        "--relaxation-creep",
        figs[1],
        "--terms-curve",
        figs[2],
    ]
    assert main([*base, "--errors", str(cards / "card_errors.csv")]) == 0
    assert all(Path(p).stat().st_size > 20_000 for p in figs)
    pd.read_csv(cards / "card_errors.csv").drop(columns="phase_deg_measured").to_csv(tmp_path / "e.csv", index=False)
    assert main([*base, "--errors", str(tmp_path / "e.csv")]) == 2


def test_joint_refinement_lowers_the_largest_difference_in_tolerance_units():
    """Times and weights free together (after the variable projection of N terms) never make
    the largest difference, in units of the tolerances, worse; on a 5-term series fitted with
    3 terms they make it smaller."""
    from asphalt_nscd.rheology.models import generalized_maxwell_modulus

    tau = np.logspace(-4, 2, 5)
    omega = np.logspace(-3, 5, 161)
    E = generalized_maxwell_modulus(omega, 50.0, np.array([8000.0, 6000.0, 3000.0, 1200.0, 400.0]), tau)
    tol = (1.0, 0.2)

    def scaled(r):
        return max(100 * np.abs(r.real).max() / tol[0], np.degrees(np.abs(r.imag).max()) / tol[1])

    u = np.log10(np.logspace(-3.5, 1.5, 3))
    x, Ef = export._nnls_weights(omega, E, 10.0**u)
    r = np.log(Ef / E)
    x2, u2, r2 = export._joint_minimax(omega, E, x, u, r, tol, (-6.0, 4.0), scaled)
    assert scaled(r2) < scaled(r)
    assert (x2 >= 0).all() and len(u2) == 3
    E2 = generalized_maxwell_modulus(omega, x2[0], x2[1:], 10.0**u2)
    np.testing.assert_allclose(np.log(E2 / E), r2, atol=1e-12)


def test_a_correction_is_stated_per_temperature_and_the_card_judged_against_both_tables(tmp_path):
    """Given the corrected table the laws were fitted on, the card's errors are written against
    the lab's means and against the corrected ones, and what the correction changes is stated per
    temperature in the card's header and JSON: here |E*| x 1.1 at one isotherm only (9.53 % in
    log), nothing elsewhere; a corrected table equal to the measured one states nothing."""
    law_path, summary = _law(tmp_path)
    s = pd.read_csv(summary)
    T_hot = float(s["temperature_C"].max())
    rows = s.rename(columns={"E_norm_MPa_mean": "E_norm_MPa", "phase_deg_mean": "phase_deg"})
    corrected = rows.assign(
        E_norm_MPa=np.where(np.isclose(rows["temperature_C"], T_hot), 1.1, 1.0) * rows["E_norm_MPa"]
    )
    corrected.to_csv(tmp_path / "corrected.csv", index=False)
    cards = tmp_path / "cards"
    assert (
        main(
            [
                "export-law",
                "--law-json",
                str(law_path),
                "--measured",
                str(summary),
                "--corrected",
                str(tmp_path / "corrected.csv"),
                "-o",
                str(cards),
            ]
        )
        == 0
    )
    card = json.loads((cards / "prony.json").read_text())
    per_T = {r["temperature_C"]: r for r in card["loss"]}
    assert per_T[T_hot]["corrected_vs_measured_logE_pct_mean"] == pytest.approx(100 * np.log(1.1), rel=1e-4)
    assert all(r["corrected_vs_measured_logE_pct_max"] < 1e-3 for T, r in per_T.items() if T not in (T_hot, "all"))
    errors = pd.read_csv(cards / "card_errors.csv")
    np.testing.assert_allclose(
        errors["card_vs_corrected_logE_pct"] + errors["corrected_vs_measured_logE_pct"],
        errors["card_vs_measured_logE_pct"],
        atol=1e-9,
    )
    header = (cards / "abaqus.inp").read_text()
    assert "the correction changes the replicate means" in header and "card vs corrected" in header
    rows.to_csv(tmp_path / "same.csv", index=False)
    assert (
        main(
            [
                "export-law",
                "--law-json",
                str(law_path),
                "--measured",
                str(summary),
                "--corrected",
                str(tmp_path / "same.csv"),
                "-o",
                str(tmp_path / "cards2"),
            ]
        )
        == 0
    )
    header = (tmp_path / "cards2" / "abaqus.inp").read_text()
    assert "card vs corrected" not in header and "the correction changes" not in header
    rows.drop(columns="phase_deg").to_csv(tmp_path / "bad.csv", index=False)
    assert (
        main(
            [
                "export-law",
                "--law-json",
                str(law_path),
                "--measured",
                str(summary),
                "--corrected",
                str(tmp_path / "bad.csv"),
                "-o",
                str(tmp_path / "cards3"),
            ]
        )
        == 2
    )


def test_worse_than_selected_names_the_figures_beyond_the_tolerance():
    """The card is flagged against the selected law only in the overall figures where it is worse
    by more than the card's tolerance (|E*| % and Phi deg)."""
    row = {
        "temperature_C": "all",
        "card_vs_measured_logE_pct_mean": 2.0,
        "law_vs_measured_logE_pct_mean": 3.0,
        "card_vs_measured_logE_pct_max": 18.0,
        "law_vs_measured_logE_pct_max": 28.0,
        "card_vs_measured_phase_deg_mean": 1.1,
        "law_vs_measured_phase_deg_mean": 0.8,
        "card_vs_measured_phase_deg_max": 4.6,
        "law_vs_measured_phase_deg_max": 3.0,
    }
    card = {"loss": [row], "terms_selection": {"tolerance": {"E_norm_pct": 1.0, "phase_deg": 0.2}}}
    assert export.worse_than_selected(card) == [
        "mean Phi error 1.10 deg vs 0.80 deg",
        "max Phi error 4.60 deg vs 3.00 deg",
    ]
    row["card_vs_measured_phase_deg_mean"] = 0.95
    assert export.worse_than_selected(card) == ["max Phi error 4.60 deg vs 3.00 deg"]
    assert export.worse_than_selected({"loss": []}) == []


@pytest.mark.slow
def test_the_shipped_tables_card_is_no_worse_than_pyvisco(tmp_path):
    """The shipped UIUC table through the chain with the default configuration (measured,
    calibrate-search, master-curve, extend-law, export-law as the workflow runs them): its card,
    judged at every cell against the lab's replicate means, is no worse than NREL pyvisco 1.0.4's
    card (its defaults; reference/cards/pyvisco.csv, reference/cards/pyvisco_card.py) in any of
    the four figures (|E*| mean and largest log error, Phi mean and largest error), with at most
    16 Prony terms at the default tolerance, and its E(t) and D(t) interconvert to 0.5 %."""

    from asphalt_nscd import config as config_files
    from asphalt_nscd.io import content_sha256

    root = Path(__file__).resolve().parents[2]
    cfg = config_files.load([], default=root / "config" / "config.yaml")
    table = root / "data" / "measured" / "uiuc_fdmix1_utm" / "complex_modulus.csv"
    p = {
        k: tmp_path / k
        for k in ("m.csv", "s.csv", "t.json", "cal.json", "mc.json", "corr.csv", "law.json", "card.json", "cards")
    }
    search = ["--config", str(root / "config" / "config.yaml")]  # the default config's diagnosis options
    assert (
        main(
            [
                "measured",
                str(table),
                "-o",
                str(p["m.csv"]),
                "--summary",
                str(p["s.csv"]),
                "--test-output",
                str(p["t.json"]),
            ]
        )
        == 0
    )
    m = ["--measured", str(p["m.csv"]), "--test", str(p["t.json"])]
    assert main(["calibrate-search", *m, *search, "--seed", "0", "-o", str(p["cal.json"])]) == 0
    assert (
        main(
            [
                "master-curve",
                *m,
                *search,
                "--calibration",
                str(p["cal.json"]),
                "-o",
                str(p["mc.json"]),
                "--corrected",
                str(p["corr.csv"]),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "extend-law",
                "--measured",
                str(p["m.csv"]),
                *search,
                "--master-curve",
                str(p["mc.json"]),
                "--corrected-table",
                str(p["corr.csv"]),
                "--calibration",
                str(p["cal.json"]),
                "-o",
                str(p["law.json"]),
                "--card-law",
                str(p["card.json"]),
            ]
        )
        == 0
    )
    tol = cfg["diagnosis"]["material_card"]["tolerance"]
    assert (
        main(
            [
                "export-law",
                "--law-json",
                str(p["card.json"]),
                "--selected-law-json",
                str(p["law.json"]),
                "--measured",
                str(p["s.csv"]),
                "--corrected",
                str(p["corr.csv"]),
                "--test",
                str(p["t.json"]),
                "--tolerance",
                *map(str, tol),
                "-o",
                str(p["cards"]),
            ]
        )
        == 0
    )
    card = json.loads((p["cards"] / "prony.json").read_text())
    pyvisco = pd.read_csv(root / "reference" / "cards" / "pyvisco.csv").iloc[0]
    assert pyvisco["table_sha256"] == content_sha256(table)[:16]  # pyvisco's row is of this table
    overall = next(r for r in card["loss"] if r["temperature_C"] == "all")
    for q in ("logE_pct_mean", "logE_pct_max", "phase_deg_mean", "phase_deg_max"):
        assert overall[f"card_vs_measured_{q}"] <= pyvisco[f"card_vs_measured_{q}"], q
    assert len(card["terms"]) <= 16 and card["exact"] and card["interconversion"]["met"]
