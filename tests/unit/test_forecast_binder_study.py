"""The forecast's binder, stated: extrapolated cells, the glassy modulus, the binder's left-out
isotherms, the frequency at which the published formulas read the binder, and the page's sections
(asphalt_nscd.forecast.binder, .validation, .binder_study, .binder_report)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast import binder as B
from asphalt_nscd.forecast import binder_report as R
from asphalt_nscd.forecast import binder_study as S
from asphalt_nscd.forecast import validation as V
from asphalt_nscd.io import InputError

TEMPS = (-10.0, 4.4, 21.1, 37.8, 54.4)
FREQS = (25.0, 10.0, 5.0, 1.0, 0.5, 0.1)
#: a CAM + WLF binder (PG 64-22-like)
TRUE = B.BinderCurve("S", log10_wc_rad_s=3.0, v=0.15, w=0.95, shift="wlf", shift_params={"C1": 13.0, "C2_K": 100.0})


def points(curve: B.BinderCurve = TRUE, temps=TEMPS, freqs=FREQS) -> pd.DataFrame:
    """The tidy binder table of ``curve`` at ``temps`` x ``freqs``."""
    T, f = (a.ravel() for a in np.meshgrid(temps, freqs, indexing="ij"))
    return pd.DataFrame(
        {
            "binder": curve.binder,
            "temperature_C": T,
            "frequency_Hz": f,
            "G_Pa": curve.G_Pa(T, f),
            "delta_deg": curve.delta_deg(T, f),
        }
    )


def with_cold_plateau(s: pd.DataFrame) -> pd.DataFrame:
    """The two coldest isotherms replaced by the source's flat ~17 MPa plateau (SOURCE.md)."""
    s = s.copy()
    cold = (s["temperature_C"] < 10.0).to_numpy()
    k = np.tile(np.arange(6)[::-1], 2)
    s.loc[cold, "G_Pa"] = 17e6 * (1.0 + 0.01 * k)
    s.loc[cold, "delta_deg"] = 60.0 - 6.0 * k
    return s


# ---- the flag -------------------------------------------------------------------------------


def test_a_curve_is_extrapolated_outside_the_temperatures_of_its_passing_isotherms():
    checked = B.check_points(with_cold_plateau(points()))
    c = B.fit_curve(checked, shift="wlf")
    assert c.temperatures_used_C == pytest.approx([21.1, 37.8, 54.4])
    T = np.array([-10.0, 4.4, 21.1, 30.0, 37.8, 54.4, 54.42, 60.0])
    assert c.extrapolated(T).tolist() == [True, True, False, False, False, False, False, True]
    # an isotherm that fails inside the span leaves its temperature interpolated, not extrapolated
    s = points()
    s.loc[s["temperature_C"] == 21.1, "delta_deg"] -= 25.0
    inner = B.check_points(s)
    assert not inner.loc[inner["temperature_C"] == 21.1, "passed"].any()
    c2 = B.fit_curve(inner, shift="wlf")
    assert not c2.extrapolated(np.array(TEMPS)).any()
    with pytest.raises(ValueError, match="does not record the temperatures"):
        TRUE.extrapolated(0.0)


def _matched(curve: B.BinderCurve, mixes, E=None, binder_frequency=None) -> pd.DataFrame:
    """A matched table of ``mixes`` sharing one binder: the binder at f / 2 pi Hz (the shipped
    table's convention), volumetrics varying with the mix, |E*| and phase set by ``E``."""
    rows = []
    for k, mix in enumerate(mixes):
        for T in TEMPS:
            for f in FREQS:
                fb = f / (2 * np.pi) if binder_frequency is None else binder_frequency(f)
                rows.append(
                    {
                        "mix_id": mix,
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "binder_frequency_Hz": fb,
                        "binder_G_MPa": float(curve.G_Pa(T, fb)) / 1e6,
                        "binder_delta_deg": float(curve.delta_deg(T, fb)),
                        "binder_eta_Pa_s": np.nan,
                        "rho34_pct": 2.0 + k,
                        "rho38_pct": 20.0 + 2 * k,
                        "rho4_pct": 45.0 + 1.5 * k,
                        "rho200_pct": 4.0 + 0.3 * k,
                        "Va_pct": 4.0 + 0.5 * k,
                        "Vbeff_pct": 11.0 - 0.3 * k,
                        "E_norm_MPa": 1000.0,
                        "phase_deg": 20.0,
                    }
                )
    return pd.DataFrame(rows)


def test_the_routed_table_and_the_held_out_rows_carry_the_flag_on_both_routes():
    checked = B.check_points(with_cold_plateau(points()))
    curves = {"S": B.fit_curve(checked, shift="wlf")}
    table = _matched(TRUE, ["a", "b", "c"])
    ids = pd.Series({"a": "S", "b": "S", "c": "S"})
    cold = (table["temperature_C"] < 10.0).to_numpy()
    for route in V.BINDER_ROUTES:
        t = V.with_binder_route(table, curves, ids, route)
        assert t["binder_extrapolated"].tolist() == cold.tolist(), route
        rows, _ = V.cross_validate(t, [V.Baseline("hirsch")], ids, V.mix_folds(["a", "b", "c"]), route)
        assert list(rows.columns) == V.ROW_COLUMNS and rows["binder_extrapolated"].sum() == 3 * 12
    raw = V.with_binder_route(table, {}, ids, "raw")  # no curve: not known
    assert raw["binder_extrapolated"].isna().all()


def test_the_measured_and_extrapolated_groups_partition_every_cell():
    rng = np.random.default_rng(5)
    n_mixes, temps = 6, (-10.0, 4.4, 21.1, 37.8)
    rows = pd.DataFrame(
        {
            "mix_id": np.repeat([f"m{i}" for i in range(n_mixes)], len(temps) * 2),
            "binder_seen": True,
            "model": "hirsch",
            "coefficients": "published",
            "binder_route": "curve",
            "temperature_C": np.tile(np.repeat(temps, 2), n_mixes),
            "E_meas_MPa": 1000.0,
            "E_pred_MPa": 1000.0 * np.exp(0.3 * rng.standard_normal(n_mixes * len(temps) * 2)),
            "phase_meas_deg": 20.0,
            "phase_pred_deg": 20.0 + rng.standard_normal(n_mixes * len(temps) * 2),
        }
    )
    # extrapolated below 10 degC, and at 21.1 degC for the first two mixes (a binder passing only warm)
    flag = (rows["temperature_C"] < 10.0) | ((rows["temperature_C"] == 21.1) & rows["mix_id"].isin(["m0", "m1"]))
    rows["binder_extrapolated"] = pd.array(flag, dtype="boolean")
    s = V.score(rows)
    assert set(s["group"]) == set(V.GROUPS) - {"binder_unseen"}  # every binder seen here
    for T in [np.nan, *temps]:
        sel = s[s["temperature_C"].isna()] if np.isnan(T) else s[s["temperature_C"] == T]
        n = sel.set_index("group")["n_cells"]
        assert n["all"] == n.get("binder_measured", 0) + n.get("binder_extrapolated", 0)
    e = s[(s["group"] == "binder_extrapolated") & s["temperature_C"].isna()].iloc[0]
    cells = rows[flag]
    per_mix = cells.groupby("mix_id").apply(
        lambda g: np.mean(np.abs(100 * np.log(g["E_pred_MPa"] / g["E_meas_MPa"]))), include_groups=False
    )
    assert e["n_mixes"] == n_mixes and e["abs_logE_pct"] == pytest.approx(per_mix.mean())
    m21 = s[(s["group"] == "binder_measured") & (s["temperature_C"] == 21.1)].iloc[0]
    assert m21["n_mixes"] == n_mixes - 2
    # rows without the column score as before: no cell group
    assert not V.score(rows.drop(columns="binder_extrapolated"))["group"].isin(["binder_measured"]).any()


# ---- the glassy modulus and the left-out isotherms --------------------------------------------


def test_a_fitted_glassy_modulus_is_recovered_where_the_data_reach_it_and_held_to_its_bounds():
    truth = B.BinderCurve("G", 2.0, 0.2, 1.0, "arrhenius", {"Ea_J_mol": 180e3}, Gg_Pa=2e9)
    cold = points(truth, temps=(-30.0, -20.0, -10.0, 4.4, 21.1))
    assert truth.G_Pa(-30.0, 25.0) > 0.5 * truth.Gg_Pa  # the data reach the glassy modulus
    fitted = B.fit_curve(cold, shift="arrhenius", glassy="fitted")
    fixed = B.fit_curve(cold, shift="arrhenius")
    assert fitted.Gg_Pa == pytest.approx(2e9, rel=0.02) and fixed.Gg_Pa == B.GLASSY_MODULUS_PA
    assert fitted.rmse_lnG < 1e-3 < fixed.rmse_lnG
    stiff = points(B.BinderCurve("H", 2.0, 0.2, 1.0, "arrhenius", {"Ea_J_mol": 180e3}, Gg_Pa=6e9), temps=(-30.0, 4.4))
    assert B.fit_curve(stiff, shift="arrhenius", glassy="fitted").Gg_Pa == pytest.approx(B.GLASSY_BOUNDS_PA[1])
    assert B.BinderCurve.from_dict(fitted.as_dict()).Gg_Pa == fitted.Gg_Pa
    with pytest.raises(ValueError, match="glassy modulus 'free'"):
        B.fit_curve(cold, shift="arrhenius", glassy="free")


def test_each_passing_isotherm_is_left_out_and_the_true_shift_law_extrapolates_best():
    checked = B.check_points(points())  # a WLF binder, every point passing
    variants = [("arrhenius", "fixed"), ("wlf", "fixed")]
    cases = S.isotherm_cases(checked, variants)
    assert list(cases.columns) == S.CASE_COLUMNS
    left = cases[cases["position"] != "full"]
    assert len(cases[cases["position"] == "full"]) == 2 and len(left) == 2 * len(TEMPS)
    pos = left[left["shift"] == "wlf"].set_index("left_out_C")["position"]
    assert pos[-10.0] == "colder" and pos[54.4] == "warmer" and pos[21.1] == "interior"
    wlf = left[left["shift"] == "wlf"]
    assert wlf["fitted"].all() and (wlf["rmse_lnG"] < 1e-3).all()  # the binder's own law: exact
    summary = S.summarize_isotherms(cases, reference=("arrhenius", "fixed"))
    assert list(summary.columns) == S.SUMMARY_COLUMNS
    r = summary[(summary["shift"] == "wlf") & (summary["position"] == "colder")].iloc[0]
    assert r["n_paired"] == 1 and r["diff_rmse_lnG"] < 0  # WLF better than Arrhenius on a WLF binder
    a = summary[(summary["shift"] == "arrhenius") & (summary["position"] == "all")].iloc[0]
    assert a["n_paired"] == 0 and np.isnan(a["diff_rmse_lnG"])


def test_a_variant_that_the_points_cannot_carry_is_recorded_not_fitted():
    few = points(temps=(21.1, 37.8), freqs=(10.0, 1.0, 0.1))  # 6 points: viscosity-sized, not WLF
    cases = S.isotherm_cases(B.check_points(few), [("wlf", "fixed"), ("arrhenius", "fixed")])
    full = cases[cases["position"] == "full"].set_index("shift")
    assert not full.loc["wlf", "fitted"] and np.isnan(full.loc["wlf", "rmse_lnG"])
    assert not (cases["position"] != "full").any()  # one temperature would stay: no left-out case


# ---- the binder's frequency ---------------------------------------------------------------------


def _planted(formula: str, reading: str, seed: int, n_mixes: int = 10):
    """A table whose |E*| the published ``formula`` gives (3 % noise) with the binder read at
    ``reading``'s frequency, its binder columns at f / 2 pi Hz; the true curve, the binder of each mix."""
    from asphalt_nscd.forecast.baselines import predict

    curve = B.BinderCurve(
        "S", 3.0, 0.15, 0.95, "wlf", {"C1": 13.0, "C2_K": 100.0}, temperatures_used_C=[21.1, 37.8, 54.4]
    )
    mixes = [f"m{i}" for i in range(n_mixes)]
    t = _matched(curve, mixes)
    fb = t["binder_frequency_Hz"] if reading == "declared" else t["frequency_Hz"]
    G = curve.G_Pa(t["temperature_C"].to_numpy(), fb.to_numpy())
    d = curve.delta_deg(t["temperature_C"].to_numpy(), fb.to_numpy())
    E, _ = predict(formula, V.mix_of(t), t["frequency_Hz"].to_numpy(), G, d, None)
    rng = np.random.default_rng(seed)
    t["E_norm_MPa"] = E * np.exp(0.03 * rng.standard_normal(len(t)))
    return t, {"S": curve}, pd.Series(dict.fromkeys(mixes, "S"))


@pytest.mark.parametrize("formula", ["hirsch", "witczak_1_40d"])
@pytest.mark.parametrize("truth", S.READINGS)
@pytest.mark.parametrize("seed", [11, 12, 13])
def test_a_formula_scores_better_at_the_reading_its_data_were_made_at(formula, truth, seed):
    t, curves, ids = _planted(formula, truth, seed)
    folds = V.mix_folds(ids.index)
    rows = {}
    for reading in S.READINGS:
        routed = V.with_binder_route(S.with_binder_reading(t, reading), curves, ids, "curve")
        rows[reading], _ = V.cross_validate(routed, [V.Baseline(formula)], ids, folds, "curve")
    err = {r: V.score(rows[r]).query("group == 'all' and temperature_C != temperature_C").iloc[0] for r in rows}
    other = next(r for r in S.READINGS if r != truth)
    assert err[truth]["abs_logE_pct"] < 4.0 < err[other]["abs_logE_pct"]  # 3 % noise: ~2.4 % at the truth
    d = S.paired_difference(rows[truth], rows[other])
    overall = d[d["temperature_C"].isna()].iloc[0]
    assert list(d.columns) == S.PAIRED_COLUMNS and overall["n_mixes"] == len(ids)
    assert overall["diff_abs_logE_ci_low"] > 0  # the other reading is worse, resolved over the mixes


def test_the_declared_reading_keeps_the_table_and_an_unknown_one_is_refused():
    t, _, _ = _planted("hirsch", "declared", 1, n_mixes=2)
    pd.testing.assert_frame_equal(S.with_binder_reading(t, "declared"), t)
    assert (S.with_binder_reading(t, "mix")["binder_frequency_Hz"] == t["frequency_Hz"]).all()
    with pytest.raises(InputError, match="binder reading 'rad'"):
        S.with_binder_reading(t, "rad")


# ---- the page's sections ------------------------------------------------------------------------


def _score_row(**kw):
    base = {c: np.nan for c in V.SCORE_COLUMNS}
    base.update(binder_route="curve", confidence=0.95)
    base.update(kw)
    return base


def test_the_extrapolated_cells_section_states_both_groups_from_the_scores():
    s = pd.DataFrame(
        [
            _score_row(model="hirsch", coefficients="published", group="all", n_cells=60, n_mixes=5, abs_logE_pct=50.0),
            _score_row(model="hirsch", coefficients="published", group="all", temperature_C=-10.0, n_cells=30),
            _score_row(model="hirsch", coefficients="published", group="all", temperature_C=21.1, n_cells=30),
            _score_row(
                model="hirsch",
                coefficients="published",
                group="binder_extrapolated",
                n_cells=36,
                n_mixes=5,
                abs_logE_pct=61.25,
                abs_logE_ci_low=50.0,
                abs_logE_ci_high=72.5,
                abs_phase_deg=7.5,
            ),
            _score_row(
                model="hirsch", coefficients="published", group="binder_extrapolated", temperature_C=-10.0, n_cells=30
            ),
            _score_row(
                model="hirsch", coefficients="published", group="binder_extrapolated", temperature_C=21.1, n_cells=6
            ),
            _score_row(
                model="hirsch",
                coefficients="published",
                group="binder_measured",
                n_cells=24,
                n_mixes=4,
                abs_logE_pct=33.3,
            ),
        ]
    )
    L = R.extrapolated_cells_section(s, "curve")
    text = "\n".join(L)
    assert L[0] == "## Cells forecast from an extrapolated binder"
    assert "-10.0 °C: 30 of 30; 21.1 °C: 6 of 30." in text
    assert "| hirsch_published | 4 | 33.3 | – | 5 | 61.2 [50.0, 72.5] | 7.5 |" in text
    assert R.extrapolated_cells_section(s, "raw") == []
    assert R.extrapolated_cells_section(s[s["group"] == "all"], "curve") == []


def _reading_table():
    rows = []
    for reading, ratio, e in (("declared", 1 / (2 * np.pi), 88.8), ("mix", 1.0, 51.5)):
        for T, scale in ((np.nan, 1.0), (-10.0, 1.5)):
            rows.append(
                _score_row(
                    model="hirsch",
                    coefficients="published",
                    group="all",
                    temperature_C=T,
                    abs_logE_pct=e * scale,
                    abs_logE_ci_low=e * scale - 10,
                    abs_logE_ci_high=e * scale + 10,
                    abs_phase_deg=7.2,
                )
                | {"reading": reading, "binder_over_mix_frequency": ratio}
            )
    return pd.DataFrame(rows)


def test_the_reading_section_names_both_frequencies_and_scores_each():
    table = _reading_table()
    paired = pd.DataFrame(
        [
            {
                "model": "hirsch",
                "coefficients": "published",
                "temperature_C": np.nan,
                "n_mixes": 35,
                "diff_abs_logE_pct": -37.3,
                "diff_abs_logE_ci_low": -45.0,
                "diff_abs_logE_ci_high": -29.6,
                "diff_abs_phase_deg": -2.4,
                "diff_abs_phase_ci_low": np.nan,
                "diff_abs_phase_ci_high": np.nan,
                "confidence": 0.95,
            }
        ]
    )
    text = "\n".join(R.binder_reading_section(table, paired))
    assert "(f/2π Hz, f the mix's frequency in Hz) and at the mix's own frequency (f Hz)" in text
    assert "| hirsch_published | 88.8 [78.8, 98.8] | 7.2 | 51.5 [41.5, 61.5] | 7.2 |" in text
    assert "| hirsch_published | -10.0 | 133.2 [123.2, 143.2] | 77.2 [67.2, 87.2] | 7.2 | 7.2 |" in text
    assert "| hirsch_published | 35 | -37.3 [-45.0, -29.6] | -2.4 |" in text
    assert R.binder_reading_section(table[table["reading"] == "mix"]) == []


def test_the_extrapolation_section_lists_every_variant_with_its_difference_to_the_default():
    t = pd.DataFrame(
        [
            {"check": "curves", "shift": "viscosity", "glassy": "fixed", "n_binders": 16, "n_passing_rung": 16}
            | {"Gg_min_Pa": 1e9, "Gg_max_Pa": 1e9, "n_Gg_at_bound": 0}
            | {"log10_aT_coldest_min": 3.86, "log10_aT_coldest_max": 4.9},
            {"check": "curves", "shift": "wlf", "glassy": "fitted", "n_binders": 16, "n_passing_rung": 7}
            | {"Gg_min_Pa": 3e8, "Gg_max_Pa": 3e8, "n_Gg_at_bound": 16}
            | {"log10_aT_coldest_min": 3.3, "log10_aT_coldest_max": 7.6},
            {"check": "isotherm", "shift": "viscosity", "glassy": "fixed", "position": "all", "n_cases": 35}
            | {"n_binders": 14, "rmse_lnG": 0.239, "rmse_lnG_ci_low": 0.147, "rmse_lnG_ci_high": 0.330},
            {"check": "isotherm", "shift": "arrhenius", "glassy": "fixed", "position": "colder", "n_cases": 5}
            | {"n_binders": 5, "rmse_lnG": 0.75, "diff_rmse_lnG": 0.262, "diff_rmse_lnG_ci_low": 0.059}
            | {"diff_rmse_lnG_ci_high": 0.466},
            _score_row(model="hirsch", coefficients="recalibrated", group="all", abs_logE_pct=32.1)
            | {"check": "held_out", "shift": "wlf", "glassy": "fixed", "diff_abs_logE_pct": 1.5}
            | {"diff_abs_logE_ci_low": -0.5, "diff_abs_logE_ci_high": 3.5, "abs_phase_deg": 3.5},
        ]
    )
    text = "\n".join(R.extrapolation_section(t))
    assert "| viscosity, Gg 1 GPa | 16 | 16 | 1 | 0 | 3.86–4.90 |" in text
    assert "| viscosity, Gg 1 GPa | 35 (14) | 0.24 [0.15, 0.33] | – | 0 | – | – |" in text
    assert "| arrhenius, Gg 1 GPa | 0 | – | – | 5 | 0.75 | +0.26 [+0.06, +0.47] |" in text
    assert "| wlf, Gg fitted | 16 | 7 | 0.3 | 16 | 3.30–7.60 |" in text
    assert "| wlf, Gg fitted | 0 | – | – | 0 | – | – |" in text  # no left-out case it can carry
    assert "| hirsch_recalibrated | wlf, Gg 1 GPa | 32.1 | +1.5 [-0.5, +3.5] | – | – | 3.5 |" in text
    assert R.extrapolation_section(t[t["check"] == "curves"]) == []


def test_a_variant_takes_the_fit_ladder_with_its_own_shift_law():
    s = with_cold_plateau(points())
    checked = B.check_points(s[s["frequency_Hz"].isin([25.0, 5.0, 0.5])])  # 9 passing points
    curves, fits = S.variant_curves(checked, "wlf", "fixed")  # WLF needs 10: a lower rung
    assert fits.iloc[0]["rung"] != "passed" and curves["S"].shift == "wlf"
    assert -10.0 in curves["S"].temperatures_used_C and not curves["S"].extrapolated(-10.0)
    curves, fits = S.variant_curves(checked, "arrhenius", "fixed")  # Arrhenius needs 8: its passing points
    assert fits.iloc[0]["rung"] == "passed" and curves["S"].extrapolated(-10.0)
    c, rung, shift = B.fit_binder_ladder(checked)  # no viscosity: Arrhenius, as before
    assert (rung, shift) == ("passed", "arrhenius")
