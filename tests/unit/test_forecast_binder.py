"""Binder data quality and master curves (asphalt_nscd.forecast.binder)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast import binder as B

TEMPS = (-10.0, 4.4, 21.1, 37.8, 54.4)
FREQS = (25.0, 10.0, 5.0, 1.0, 0.5, 0.1)
PSI = 6894.757293168
#: a CAM + WLF binder (PG 64-22-like: 1-5 MPa, 50-65 deg at 21.1 degC; > 100 MPa at -10 degC)
TRUE = B.BinderCurve("S", log10_wc_rad_s=3.0, v=0.15, w=0.95, shift="wlf", shift_params={"C1": 13.0, "C2_K": 100.0})
#: mix 224 of mixes_35.tsv (binder PG 70-28): |G*| (psi), delta_b (rad), eta (cP); blocks of
#: 25, 10, 5, 1, 0.5, 0.1 Hz at -10, 4.4, 21.1, 37.8, 54.4 degC (SOURCE.md beside the file)
MIX_224 = """
1615.097124 0.212695192 1.43519E+14
1306.914358 0.296973735 1.43519E+14
1562.813119 0.362664431 1.43519E+14
2523.898043 0.521354633 1.43519E+14
2764.13793 0.592211683 1.43519E+14
2479.092702 0.762015911 1.43519E+14
5656.566439 0.480409737 8.32597E+11
3099.528109 0.484267673 8.32597E+11
2548.985262 0.489370327 8.32597E+11
2523.898043 0.521354633 8.32597E+11
2764.13793 0.592211683 8.32597E+11
2479.092702 0.762015911 8.32597E+11
1110.557475 0.781492734 7607196383
754.3729946 0.819284138 7607196383
628.7724054 0.851473713 7607196383
439.7221498 0.941129073 7607196383
360.4987436 0.987328674 7607196383
179.6707324 1.115099391 7607196383
118.68626 0.988074019 188790741.2
71.55528141 1.042014507 188790741.2
50.39960267 1.08597754 188790741.2
20.22766707 1.199299396 188790741.2
12.47024363 1.252961948 188790741.2
3.018194378 1.387219387 188790741.2
14.08802702 1.132861468 9908053.26
7.266608389 1.193178354 9908053.26
4.369374215 1.240816021 9908053.26
1.136320569 1.356979482 9908053.26
0.575188846 1.408528883 9908053.26
0.089701698 1.527053409 9908053.26
"""
SOURCE_FILE = Path("/work/shared/data/binder_mix/mixes_35.tsv")


def synthetic(curve: B.BinderCurve = TRUE) -> pd.DataFrame:
    """The tidy table of ``curve`` at the five test temperatures and six frequencies."""
    T, f = (a.ravel() for a in np.meshgrid(TEMPS, FREQS, indexing="ij"))
    return pd.DataFrame(
        {
            "binder": curve.binder,
            "temperature_C": T,
            "frequency_Hz": f,
            "G_Pa": curve.G_Pa(T, f),
            "delta_deg": curve.delta_deg(T, f),
        }
    )


def at(frame: pd.DataFrame, T: float, f: float | None = None) -> np.ndarray:
    m = frame["temperature_C"] == T
    return (m & (frame["frequency_Hz"] == f) if f is not None else m).to_numpy()


def mix_224() -> pd.DataFrame:
    v = np.array(MIX_224.split(), float).reshape(30, 3)
    T, f = np.repeat(TEMPS, 6), np.tile(FREQS, 5)
    return pd.DataFrame(
        {
            "binder": "B11",
            "temperature_C": T,
            "frequency_Hz": f,
            "G_Pa": v[:, 0] * PSI,
            "delta_deg": np.degrees(v[:, 1]),
            "eta_Pa_s": v[:, 2] * 1e-3,
        }
    )


def test_healthy_binder_passes_and_the_fit_recovers_its_parameters():
    points = B.check_points(synthetic())
    assert points["passed"].all(), points.loc[~points["passed"], ["temperature_C", "frequency_Hz", "reason"]]
    c = B.fit_curve(points, shift="wlf")
    assert (c.log10_wc_rad_s, c.v, c.w) == pytest.approx((3.0, 0.15, 0.95), rel=1e-4)
    assert (c.shift_params["C1"], c.shift_params["C2_K"]) == pytest.approx((13.0, 100.0), rel=1e-3)
    assert c.rmse_lnG < 1e-6 and c.rmse_delta_deg < 1e-5 and (c.n_used, c.n_left_out) == (30, 0)


def test_noisy_healthy_binder_passes_and_is_recovered_within_its_noise():
    rng = np.random.default_rng(3)
    s = synthetic()
    s["G_Pa"] *= np.exp(0.03 * rng.standard_normal(len(s)))
    s["delta_deg"] += 0.5 * rng.standard_normal(len(s))
    curves, points = B.fit_binders(s, shift="wlf")
    assert points["passed"].all()
    c = curves["S"]
    assert c.rmse_lnG < 0.04 and c.rmse_delta_deg < 0.7
    assert np.abs(np.log(c.G_Pa(-10.0, 25.0) / TRUE.G_Pa(-10.0, 25.0))) < 0.1


def test_a_falling_modulus_is_flagged_monotonic():
    s = synthetic()
    s.loc[at(s, 21.1, 5.0), "G_Pa"] *= 0.3  # below the 1 Hz value
    p = B.check_points(s)
    flagged = p[p["reason"] != ""]
    assert p.loc[at(p, 21.1, 5.0), "reason"].item() == "monotonic"
    assert set(flagged["reason"]) == {"monotonic"}
    assert set(zip(flagged["temperature_C"], flagged["frequency_Hz"])) <= {(21.1, 5.0), (21.1, 1.0)}


def test_a_phase_inconsistent_with_the_modulus_slope_is_flagged_kramers_kronig():
    s = synthetic()
    s.loc[at(s, 37.8, 5.0), "delta_deg"] -= 25.0
    p = B.check_points(s)
    assert p.loc[at(p, 37.8, 5.0), "reason"].item() == "kramers_kronig"
    assert p["passed"].sum() == len(p) - 1


def test_a_cold_plateau_is_flagged_time_temperature():
    s = synthetic()
    cold = (s["temperature_C"] < 10.0).to_numpy()
    k = np.tile(np.arange(6)[::-1], 2)  # frequency index, 0 at 0.1 Hz
    s.loc[cold, "G_Pa"] = 17e6 * (1.0 + 0.01 * k)  # monotone, flat: ~17 MPa
    s.loc[cold, "delta_deg"] = 60.0 - 6.0 * k  # 60 to 30 deg
    p = B.check_points(s)
    assert p.loc[cold, "reason"].str.contains("time_temperature").all()
    assert p.loc[~cold, "passed"].all()


def test_the_time_temperature_rule_is_silent_on_healthy_binders_of_either_shift_law():
    for curve in (
        TRUE,
        B.BinderCurve("A", 2.0, 0.2, 1.0, "arrhenius", {"Ea_J_mol": 180e3}),
        B.BinderCurve("W", 3.5, 0.12, 0.9, "wlf", {"C1": 20.0, "C2_K": 180.0}),
    ):
        assert B.check_points(synthetic(curve))["passed"].all(), curve.binder


def test_capped_phase_and_floored_modulus_are_flagged_bounds():
    s = synthetic()
    s.loc[at(s, 54.4, 0.1) | at(s, 54.4, 0.5), "delta_deg"] = 90.0
    s.loc[at(s, 54.4, 0.1), "G_Pa"] = 0.0145 * PSI  # the source's floor, 99.97 Pa
    p = B.check_points(s)
    assert list(p.loc[~p["passed"], "reason"]) == ["bounds", "bounds"]
    assert B.check_points(s, G_floor_Pa=10.0).loc[at(s, 54.4, 0.1), "reason"].item() == "bounds"  # still delta = 90


def test_real_excerpt_cold_plateau_is_flagged_and_the_curve_restores_a_stiff_cold_binder():
    curves, p = B.fit_binders(mix_224())
    cold = (p["temperature_C"] < 10.0).to_numpy()
    assert not p.loc[cold, "passed"].any()
    assert p.loc[at(p, 4.4), "reason"].str.contains("time_temperature").all()
    assert p.loc[at(p, -10.0), "reason"].str.contains("monotonic").all()
    c = curves["B11"]
    assert c.temperatures_used_C == [37.8, 54.4] and c.shift == "viscosity"
    # the file: 11 MPa at -10 degC and 25 Hz; a binder there is stiffer than 100 MPa (SOURCE.md)
    assert c.G_Pa(-10.0, 25.0) > 100e6 and c.delta_deg(-10.0, 25.0) < 25.0
    assert c.rmse_lnG < 0.3 and c.rmse_delta_deg < 4.0


@pytest.mark.skipif(not SOURCE_FILE.exists(), reason="mixes_35.tsv not on this machine")
def test_real_file_binders_and_cold_isotherms():
    d = pd.read_csv(SOURCE_FILE, sep="\t")
    mixes = pd.DataFrame(
        {
            "mix_id": d["ID"].astype(str),
            "temperature_C": np.tile(np.repeat(TEMPS, 6), len(d) // 30),
            "frequency_Hz": np.tile(FREQS, len(d) // 6),
            "binder_G_Pa": d["|G*|"] * PSI,
            "binder_delta_deg": np.degrees(d["δb"]),
            "binder_eta_Pa_s": d["η"] * 1e-3,
        }
    )
    ids = B.binder_ids(mixes)
    assert ids.nunique() == 16 and ids["224"] == "B11"
    first = mixes.groupby(mixes["mix_id"].map(ids))["mix_id"].transform("min") == mixes["mix_id"]
    tidy = mixes[first].rename(
        columns={"binder_G_Pa": "G_Pa", "binder_delta_deg": "delta_deg", "binder_eta_Pa_s": "eta_Pa_s"}
    )
    p = B.check_points(tidy.assign(binder=tidy["mix_id"].map(ids)))
    assert not p.loc[at(p, -10.0), "passed"].any()


def test_binder_ids_group_identical_binders_in_order_of_their_first_mix():
    rows = []
    for mix, G in (("7", 2.0), ("3", 1.0), ("5", 2.0)):
        for T in (4.4, 21.1):
            rows.append(
                {
                    "mix_id": mix,
                    "temperature_C": T,
                    "frequency_Hz": 10.0,
                    "binder_G_MPa": G * T,
                    "binder_delta_deg": 40.0,
                    "binder_eta_Pa_s": np.nan,
                }
            )
    frame = pd.DataFrame(rows)
    ids = B.binder_ids(frame)
    assert ids.to_dict() == {"3": "B01", "5": "B02", "7": "B02"}
    assert B.binder_ids(frame.sample(frac=1.0, random_state=1)).equals(ids)
    with pytest.raises(ValueError, match="binder_delta_deg"):
        B.binder_ids(frame.drop(columns="binder_delta_deg"))


def test_curve_as_dict_is_json_safe_and_round_trips():
    c = B.fit_curve(synthetic(), shift="arrhenius")
    back = B.BinderCurve.from_dict(json.loads(json.dumps(c.as_dict(), allow_nan=False)))
    T, f = np.array([-10.0, 21.1, 54.4]), np.array([25.0, 1.0, 0.1])
    assert np.array_equal(back.G_Pa(T, f), c.G_Pa(T, f)) and np.array_equal(back.delta_deg(T, f), c.delta_deg(T, f))
    assert np.array_equal(back.log_shift(T), c.log_shift(T)) and back.n_used == 30
    with pytest.raises(ValueError, match="shift law"):
        B.BinderCurve.from_dict({**c.as_dict(), "shift": "vft"})


def test_viscosity_shift_follows_the_a_vts_line():
    c = B.fit_curve(mix_224().assign(passed=lambda x: x["temperature_C"] > 30.0))
    eta = mix_224().groupby("temperature_C")["eta_Pa_s"].first()
    assert c.log_shift(eta.index.to_numpy()) == pytest.approx(np.log10(eta / eta[21.1]).to_numpy(), abs=0.01)


def test_mepdg_viscosity_tends_to_the_newtonian_viscosity():
    # w = 1: |G*| -> Gg w_r / wc far below the crossover, so eta -> Gg aT / wc (Pa s) and delta -> 90
    c = B.BinderCurve("N", 3.0, 0.6, 1.0, "wlf", {"C1": 13.0, "C2_K": 100.0})
    T = np.array([54.4, 70.0])
    assert c.delta_deg(T, 10 / (2 * np.pi)).min() > 89.0
    assert B.viscosity_Pa_s(c, T) == pytest.approx(c.Gg_Pa * 10 ** c.log_shift(T) / 10**c.log10_wc_rad_s, rel=0.02)
    G, d = c.G_Pa(21.1, 10 / (2 * np.pi)), c.delta_deg(21.1, 10 / (2 * np.pi))
    assert B.viscosity_Pa_s(c, 21.1) == pytest.approx(G / 10 / np.sin(np.radians(d)) ** 4.8628)


def test_bad_input_raises_naming_the_problem():
    s = synthetic()
    with pytest.raises(ValueError, match="delta_deg"):
        B.check_points(s.drop(columns="delta_deg"))
    with pytest.raises(ValueError, match="G_Pa"):
        B.check_points(s.assign(G_Pa=np.where(at(s, 4.4, 1.0), np.nan, s["G_Pa"])))
    with pytest.raises(ValueError, match="repeated"):
        B.check_points(pd.concat([s, s.iloc[:1]]))
    with pytest.raises(ValueError, match="shift law"):
        B.fit_curve(s, shift="vft")
    with pytest.raises(ValueError, match="binder S: 6 passing point"):
        B.fit_binders(s[at(s, 21.1)], shift="wlf")
    with pytest.raises(ValueError, match="binder S: the viscosity shift needs eta_Pa_s"):
        B.fit_binders(s)


def test_a_binder_whose_points_mostly_fail_still_gets_a_curve_on_a_lower_rung():
    """Phase angles 35 degrees off the |G*| slope: too few points pass Kramers-Kronig to carry a curve,
    which then comes from the points within bounds and monotonic (:data:`B.FIT_LADDER`); without
    viscosities the shift is Arrhenius. A healthy binder stays on the first rung."""
    frame = synthetic()
    bad = frame.assign(delta_deg=np.clip(frame["delta_deg"] - 35.0, 0.5, 89.0))
    checked = B.check_points(bad)
    assert checked["passed"].sum() < 8
    curve, rung, shift = B.fit_binder_ladder(checked)
    assert rung == "bounds_monotonic" and shift == "arrhenius" and curve.n_used > checked["passed"].sum()
    curve, rung, shift = B.fit_binder_ladder(B.check_points(frame))
    assert rung == "passed" and shift == "arrhenius" and curve.rmse_lnG < 0.5  # Arrhenius on a WLF binder: 0.32
