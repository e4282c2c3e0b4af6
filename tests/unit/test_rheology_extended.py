"""Temperature-aware extended law: backbone fit, the law at any temperature (Prony chain shifted
by aT, JSON format), causality, and the causal-fit bound of one isotherm."""

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.rheology import law_file
from asphalt_nscd.cli import main
from asphalt_nscd.rheology import extended
from asphalt_nscd.rheology.extended import LawSettings
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.models import two_s2p1d_modulus
from asphalt_nscd.rheology.shift import wlf_log_shift

F = np.array([25.0, 10.0, 5.0, 1.0, 0.5, 0.1])
TEMPS = np.array([-10.0, 4.0, 21.0, 37.0, 54.0])
#: a thermorheologically simple truth: 2S2P1D at 21 degC, WLF
TRUTH = {
    "E00": 120.0,
    "E0": 36e3,
    "delta": 2.2,
    "k": 0.19,
    "h": 0.58,
    "beta": 400.0,
    "tau": 0.05,
    "C1": 28.0,
    "C2": 200.0,
    "T_ref": 21.0,
}


def truth_modulus(f, T):
    t = TRUTH
    tau = t["tau"] * 10.0 ** wlf_log_shift(T, t["T_ref"], t["C1"], t["C2"])
    return two_s2p1d_modulus(
        2 * np.pi * np.asarray(f, float), t["E00"], t["E0"], t["delta"], t["k"], t["h"], t["beta"], tau
    )


def truth_cells(temps=TEMPS, freqs=F):
    T, f = np.meshgrid(temps, freqs, indexing="ij")
    E = truth_modulus(f.ravel(), T.ravel())
    return pd.DataFrame(
        {
            "temperature_C": T.ravel(),
            "frequency_Hz": f.ravel(),
            "n": 1,
            "E_norm_MPa": np.abs(E),
            "phase_deg": np.degrees(np.angle(E)),
        }
    )


@pytest.fixture(scope="module")
def law():
    return extended.fit_law(truth_cells(), LawSettings(per_decade=4.0))


def test_backbone_recovers_a_thermorheologically_simple_truth(law):
    m = extended.law_metrics(law, truth_cells())
    assert m["rel_err_E_norm"].max() < 0.01 and m["rel_err_phase"].max() < 0.02
    bb = law.backbone
    assert bb.T_ref_C == 21.0
    # the shift law is the truth's (checked away from the fitted temperatures too)
    for T in (-5.0, 12.0, 45.0):
        assert bb.log_shift(T) == pytest.approx(wlf_log_shift(T, 21.0, TRUTH["C1"], TRUTH["C2"]), abs=0.05)


@pytest.mark.parametrize("T", [-3.0, 12.5, 29.0, 46.0])
def test_law_at_an_unmeasured_temperature_matches_the_truth(law, T):
    """Temperatures between the fitted isotherms: the Prony chain shifted by aT (the law JSON
    entry) reproduces the truth there, though no data were fitted at T."""
    f = np.logspace(-1, np.log10(25.0), 9)
    E = law.law_at(T).complex_modulus(2 * np.pi * f)
    ref = truth_modulus(f, T)
    np.testing.assert_allclose(np.abs(E), np.abs(ref), rtol=0.01)
    np.testing.assert_allclose(np.degrees(np.angle(E)), np.degrees(np.angle(ref)), atol=0.3)


def test_law_at_shifts_the_prony_chain_and_keeps_it_causal(law):
    """Without reduction the law at T is the T_ref chain with times x aT (closed form); every
    unit is positive (a positive retardation spectrum: causal, passive)."""
    T = 30.0
    aT = 10 ** law.backbone.log_shift(T)
    full = law.law_at(T, reduce=False)
    p = law.prony
    np.testing.assert_allclose(
        np.array(full.eta_k) / np.array(full.Ek), np.array(p.eta_k) / np.array(p.Ek) * aT, rtol=1e-12
    )
    c = full.Em / p.Em
    np.testing.assert_allclose(full.Ek, np.array(p.Ek) * c, rtol=1e-12)
    for T in (-10.0, 21.0, 54.0):
        reduced = law.law_at(T)
        assert reduced.n_kelvin < law.prony.n_kelvin  # far units merged
        assert reduced.Em > 0 and min(reduced.Ek) > 0 and min(reduced.eta_k) > 0 and reduced.E_inf >= 0
        # merging far units changes nothing inside the band by more than 10^-margin
        f = np.logspace(-1, np.log10(25.0), 15)
        E1, E2 = reduced.complex_modulus(2 * np.pi * f), law.law_at(T, reduce=False).complex_modulus(2 * np.pi * f)
        assert np.max(np.abs(E1 / E2 - 1)) < 0.01
    # storage and loss moduli of a passive law: E1 > 0, E2 >= 0 everywhere
    w = np.logspace(-6, 6, 200)
    E = law.law_at(37.0).complex_modulus(w)
    assert np.all(E.real > 0) and np.all(E.imag >= 0)


def test_trend_vertical_and_refinement_change_the_law_with_temperature():
    cells = truth_cells()
    # a static modulus that falls with temperature and a vertical factor: both recovered
    E = truth_modulus(cells["frequency_Hz"], cells["temperature_C"])
    b = 10 ** (-0.2 * (cells["temperature_C"] - 21.0) / 100.0)
    cells = cells.assign(E_norm_MPa=np.abs(E) * b)
    law = extended.fit_law(cells, LawSettings(vertical=True))
    assert law.backbone.value("vertical_trend_per_100K") == pytest.approx(-0.2, abs=0.03)
    ref = extended.fit_law(cells, LawSettings(refine=1.0))
    assert any(n.startswith("dlog10_E00_") for n in ref.backbone.names)
    # the per-isotherm deviations are interpolated between the isotherms
    bb = ref.backbone
    d4, d21 = bb._deviation("aT", 4.0), bb._deviation("aT", 21.0)
    assert bb._deviation("aT", 12.5) == pytest.approx(0.5 * (d4 + d21))
    assert bb._deviation("aT", -40.0) == pytest.approx(bb._deviation("aT", -10.0))


def test_law_outside_the_wlf_domain_is_an_input_error(law):
    with pytest.raises(InputError, match="WLF domain"):
        law.law_at(21.0 - law.backbone.value("C2_K") - 1.0)


def test_settings_validation_and_order():
    with pytest.raises(ValueError, match="shift"):
        LawSettings(shift="vft")
    with pytest.raises(ValueError, match="static"):
        LawSettings(static="sometimes")
    with pytest.raises(ValueError, match="refine"):
        LawSettings(refine=-1.0)
    simple, flexible = LawSettings(static="none"), LawSettings(static="trend", vertical=True, refine=1.0)
    assert simple.complexity() < flexible.complexity()
    assert simple.n_params(5) == 8 and flexible.n_params(5) == 9 + 2 + 15


def test_extend_law_writes_the_json_at_requested_temperatures(tmp_path):
    """`extend-law --temperatures` writes entries at unmeasured temperatures in the format that
    run-2pb reads; each evaluates E*(w) = E_inf + [1/Em + 1/(iw eta_m) + sum 1/(Ek + iw eta_k)]^-1."""
    rng = np.random.default_rng(3)
    cells = truth_cells()
    rows = []
    for s in ("a", "b"):
        noise = np.exp(rng.normal(0, 0.01, len(cells)))
        rows.append(
            cells.assign(
                specimen=s,
                E_norm_MPa=cells["E_norm_MPa"] * noise,
                phase_deg=cells["phase_deg"] + rng.normal(0, 0.1, len(cells)),
            )
        )
    table = pd.concat(rows).drop(columns="n")
    m = tmp_path / "M.csv"
    table.to_csv(m, index=False)
    out = tmp_path / "law.json"
    assert (
        main(
            [
                "extend-law",
                "--measured",
                str(m),
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
                "--temperatures",
                "12.5",
                "30",
                "60",
                "-o",
                str(out),
                "--cv-curve",
                str(tmp_path / "c.csv"),
            ]
        )
        == 0
    )
    obj = json.loads(out.read_text())
    assert set(obj["temperatures"]) == {"12.5", "30", "60"}
    assert obj["temperatures"]["60"]["extrapolation"] is True and obj["temperatures"]["30"]["extrapolation"] is False
    laws = law_file.read(out)
    for T in (12.5, 30.0):
        d = obj["temperatures"][f"{T:g}"]
        f = np.array([0.3, 3.0, 20.0])
        w = 2 * np.pi * f
        D = 1 / d["Em"] + (0 if d["eta_m"] is None else 1 / (1j * w * d["eta_m"]))
        D = D + sum(1 / (ek + 1j * w * ck) for ek, ck in zip(d["Ek"], d["eta_k"]))
        E = (d["E_inf"] + 1 / D) * 1e-6
        np.testing.assert_allclose(E, laws[T].complex_modulus(w) * 1e-6, rtol=1e-12)
        np.testing.assert_allclose(np.abs(E), np.abs(truth_modulus(f, T)), rtol=0.03)
    assert obj["selection"]["chosen"]["static"] == "constant"
    assert obj["model"]["T_ref_C"] == 21.0 and obj["model"]["shift"]["law"] == "WLF"
    curve = pd.read_csv(tmp_path / "c.csv")
    assert len(curve) == 1 and bool(curve["chosen"].iloc[0])


def _target():
    """Replicate means of a 2S2P1D isotherm (MPa, deg): causal by construction."""
    E = two_s2p1d_modulus(2 * np.pi * F, 80.0, 35e3, 2.5, 0.18, 0.55, 500.0, 0.02)
    return np.abs(E), np.degrees(np.angle(E))


def test_best_causal_fit_matches_a_causal_isotherm():
    E, ph = _target()
    best = extended.best_causal_fit(F, E, ph)
    assert best["objective"] < 0.1
    assert best["mre_E_norm_pct"] < 0.3 and best["mre_phase_pct"] < 0.5


def test_best_causal_fit_flags_a_kramers_kronig_inconsistent_isotherm():
    # |E*| ~ w^0.5 is a power law whose causal phase is 0.5 x 90 = 45 deg (exact); a phase of
    # 20 deg cannot go with it: no positive spectrum meets 3 % / 5 %
    f = np.logspace(-1, np.log10(25.0), 6)
    E = 1000.0 * f**0.5
    ph = np.full(f.size, 20.0)
    best = extended.best_causal_fit(f, E, ph)
    assert best["objective"] > 1.5
    # while the consistent phase is matched
    assert extended.best_causal_fit(f, E, np.full(f.size, 45.0))["objective"] < 0.2


def test_tolerances_option_rejects_non_positive_values(tmp_path, capsys):
    m = tmp_path / "M.csv"
    truth_cells().assign(specimen="a").drop(columns="n").to_csv(m, index=False)
    assert main(["extend-law", "--measured", str(m), "--tolerances-pct", "0", "5", "-o", str(tmp_path / "x.json")]) != 0
    assert "--tolerances-pct" in capsys.readouterr().err
    assert main(["extend-law", "--measured", str(m), "--law-refines", "lots", "-o", str(tmp_path / "x.json")]) != 0
    assert "--law-refines" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_an_unresolved_static_trend_stays_near_zero():
    """Cold isotherms (-10 ... 20 degC, |E*| >> E00) barely resolve the temperature trend of
    E00: with noise, a free trend runs to its bounds (+-3 decades per 100 K on these tables);
    the weak prior keeps it near 0."""
    trends = []
    for seed in range(6):
        rng = np.random.default_rng(seed)
        cells = truth_cells(
            temps=np.array([-10.0, 0.0, 10.0, 15.0, 20.0]), freqs=np.array([40.0, 25.0, 10.0, 6.0, 3.0])
        )
        cells = cells.assign(
            E_norm_MPa=cells["E_norm_MPa"] * np.exp(rng.normal(0, 0.01, len(cells))),
            phase_deg=cells["phase_deg"] + rng.normal(0, 0.2, len(cells)),
        )
        law = extended.fit_law(cells, LawSettings(static="trend"))
        trends.append(law.backbone.value("static_trend_per_100K"))
    assert np.max(np.abs(trends)) < 0.5
