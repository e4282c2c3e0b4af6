"""Prediction intervals of the forecasts (asphalt_nscd.forecast.intervals): the mix-weighted
conformal quantile by hand, its finite-sample coverage of a new mix by simulation (exact for one
cell per mix), nesting (a mix's own residual never enters its interval), monotone in the level,
the bounds of a forecast table, and the forecast-coverage command."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.forecast import intervals
from asphalt_nscd.io import InputError


def test_the_mix_weighted_quantile_by_hand():
    # mixes a (1, 2) and b (3): weights 1/6, 1/6, 1/3 and 1/3 at +inf
    s, g = [1.0, 2.0, 3.0], ["a", "a", "b"]
    assert intervals.group_quantile(s, g, 0.15) == 1.0
    assert intervals.group_quantile(s, g, 0.30) == 2.0
    assert intervals.group_quantile(s, g, 0.50) == 3.0
    assert intervals.group_quantile(s, g, 0.70) == np.inf  # beyond the two mixes' weight 2/3
    assert intervals.group_quantile([np.nan, 1.0], ["a", "b"], 0.4) == 1.0  # NaN left out: one mix, weight 1/2
    lo, hi = intervals.offsets([-1.0, 1.0, -2.0, 2.0], ["a", "a", "b", "b"], 0.2, "symmetric")
    assert (lo, hi) == (-1.0, 1.0)
    with pytest.raises(InputError, match="level"):
        intervals.offsets([1.0], ["a"], 1.2)
    with pytest.raises(InputError, match="tails"):
        intervals.offsets([1.0], ["a"], 0.9, "left")


def _simulated_coverage(rng, K, cells, level, tails, reps):
    """Per-rep fraction of a new mix's cells inside its interval, the K + 1 mixes exchangeable:
    a heavy-tailed mix effect shared by its cells, skewed cell noise, ``cells(rng)`` cells per mix."""
    cover = np.empty(reps)
    for r in range(reps):
        n = np.array([cells(rng) for _ in range(K + 1)])
        effect = 3.0 * rng.standard_t(3, size=K + 1)
        res = [effect[k] + rng.lognormal(0.0, 1.0, size=n[k]) for k in range(K + 1)]
        lo, hi = intervals.offsets(np.concatenate(res[:K]), np.repeat(np.arange(K), n[:K]), level, tails)
        cover[r] = np.mean((res[K] >= lo) & (res[K] <= hi))
    return cover


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_one_cell_per_mix_is_split_conformal_with_its_exact_coverage(seed):
    """K = 24 mixes of one cell at 90 %: the ceil(0.9 x 25) = 23rd smallest |r|, expected
    coverage exactly 23/25 = 0.92, inside 1 - alpha <= coverage <= 1 - alpha + 1/(K + 1)."""
    cover = _simulated_coverage(np.random.default_rng(seed), 24, lambda rng: 1, 0.9, "symmetric", 6000)
    se = cover.std(ddof=1) / np.sqrt(cover.size)
    assert abs(cover.mean() - 23 / 25) < 4 * se
    assert 0.9 - 4 * se <= cover.mean() <= 0.9 + 1 / 25 + 4 * se


@pytest.mark.parametrize("tails", intervals.TAILS)
@pytest.mark.parametrize("seed", [21, 22])
def test_a_new_mix_is_covered_within_the_finite_sample_bounds(tails, seed):
    """34 calibration mixes of 4-6 cells, as the shipped table per temperature: the expected
    fraction of a new mix's cells inside lies in [1 - alpha, 1 - alpha + m (1 + 1/N_min)/(K + 1)],
    m = 2 with equal tails, 1 symmetric (module docstring)."""
    K, level = 34, 0.9
    rng = np.random.default_rng(seed)
    cover = _simulated_coverage(rng, K, lambda r: int(r.integers(4, 7)), level, tails, 4000)
    se = cover.std(ddof=1) / np.sqrt(cover.size)
    excess = (2 if tails == "equal" else 1) * (1 + 1 / 4) / (K + 1)
    assert level - 4 * se <= cover.mean() <= level + excess + 4 * se


def test_without_the_mass_at_infinity_a_new_mix_is_undercovered():
    """What the finite-sample correction buys: the plain mix-weighted quantile (no new mix at
    +inf) of the same residuals covers less than 1 - alpha, beyond the simulation's noise (the
    check above would catch its loss)."""
    rng = np.random.default_rng(5)
    K, reps, cover = 34, 4000, []
    for _ in range(reps):
        effect = 3.0 * rng.standard_t(3, size=K + 1)
        res = effect[:, None] + rng.lognormal(0.0, 1.0, size=(K + 1, 6))
        s = res[:K].ravel()
        lo, hi = np.quantile(s, 0.05), np.quantile(s, 0.95)
        cover.append(np.mean((res[K] >= lo) & (res[K] <= hi)))
    cover = np.asarray(cover)
    assert cover.mean() + 4 * cover.std(ddof=1) / np.sqrt(reps) < 0.9


def _rows(n_mixes=35, temperatures=(-10.0, 21.1), seed=0):
    """Held-out rows of one model: measured = forecast x exp(mix effect + cell noise)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_mixes):
        effect = 0.3 * rng.normal()
        for T in temperatures:
            f = np.array([0.1, 0.5, 1.0, 5.0, 10.0, 25.0])
            E_pred = 1000.0 * np.exp(-0.05 * T) * f**0.2
            out.append(
                pd.DataFrame(
                    {
                        "mix_id": f"m{k:02d}",
                        "fold": k,
                        "model": "hirsch",
                        "coefficients": "recalibrated",
                        "binder_route": "curve",
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "E_meas_MPa": E_pred * np.exp(effect + 0.1 * rng.normal(size=6)),
                        "phase_meas_deg": 20.0 + 3.0 * effect + rng.normal(size=6),
                        "E_pred_MPa": E_pred,
                        "phase_pred_deg": np.full(6, 20.0),
                        "phase_source": "model",
                    }
                )
            )
    return pd.concat(out, ignore_index=True)


def test_a_mix_never_calibrates_its_own_interval():
    """A huge residual planted on one mix (its forecast 1000 times the measured |E*|, 60 degrees
    off) leaves that mix's nested interval as it was and is not covered, while it widens another
    mix's interval (it enters the others' calibration)."""
    rows = _rows()
    planted = rows.copy()
    sel = planted["mix_id"] == "m07"
    planted.loc[sel, "E_pred_MPa"] *= 1000.0
    planted.loc[sel, "phase_pred_deg"] += 60.0
    cols = ["dlogE_low_pct", "dlogE_high_pct", "dphase_low_deg", "dphase_high_deg"]
    a, b = intervals.nested(rows), intervals.nested(planted)
    pd.testing.assert_frame_equal(a.loc[sel, cols], b.loc[sel, cols])
    assert (b.loc[sel, "logE_covered"] == 0).all() and (b.loc[sel, "phase_covered"] == 0).all()
    other = rows["mix_id"] == "m03"
    assert (b.loc[other, "dlogE_low_pct"] < a.loc[other, "dlogE_low_pct"]).all()
    assert (b.loc[other, "dphase_low_deg"] < a.loc[other, "dphase_low_deg"]).all()


def test_intervals_and_coverage_grow_with_the_level():
    rows = _rows(seed=3)
    levels = [0.5, 0.7, 0.8, 0.9, 0.95]
    for tails in intervals.TAILS:
        cal = [intervals.calibrate(rows, lv, tails).sort_values("temperature_C") for lv in levels]
        for a, b in zip(cal, cal[1:]):
            for stem in ("dlogE", "dphase"):
                unit = "pct" if stem == "dlogE" else "deg"
                assert (b[f"{stem}_low_{unit}"].to_numpy() <= a[f"{stem}_low_{unit}"].to_numpy()).all()
                assert (b[f"{stem}_high_{unit}"].to_numpy() >= a[f"{stem}_high_{unit}"].to_numpy()).all()
        cov = [intervals.coverage(rows, lv, tails) for lv in levels]
        overall = [c[c["temperature_C"].isna()].set_index("quantity")["cell_coverage"] for c in cov]
        for a, b in zip(overall, overall[1:]):
            assert (b >= a).all()
        assert (overall[-1] > overall[0]).all()


def test_the_coverage_table_counts_mixes_and_carries_t_intervals():
    rows = _rows()
    cov = intervals.coverage(rows, 0.9)
    assert list(cov.columns) == intervals.COVERAGE_COLUMNS
    assert set(cov["quantity"]) == {"logE", "phase"} and len(cov) == 2 * 3
    assert (cov["n_mixes"] == 35).all()
    assert (cov.loc[cov["temperature_C"].isna(), "n_cells"] == 35 * 12).all()
    assert (cov["coverage_ci_low"] <= cov["coverage"]).all() and (cov["coverage"] <= cov["coverage_ci_high"]).all()
    np.testing.assert_allclose(cov["coverage"] + cov["below"] + cov["above"], 1.0)
    assert (cov["label"] == "hirsch_recalibrated").all()


def test_a_forecast_table_gets_its_bounds():
    iv = pd.DataFrame(
        [
            {
                "label": "hirsch_recalibrated",
                "model": "hirsch",
                "coefficients": "recalibrated",
                "binder_route": "curve",
                "temperature_C": 21.1,
                "level": 0.9,
                "tails": "equal",
                "n_mixes": 34,
                "n_cells": 204,
                "dlogE_low_pct": -50.0,
                "dlogE_high_pct": 30.0,
                "dphase_low_deg": -4.0,
                "dphase_high_deg": 6.0,
            }
        ]
    )
    forecast = pd.DataFrame(
        {
            "mix_id": ["x", "x", "x"],
            "temperature_C": [21.1, 21.1, 4.4],
            "frequency_Hz": [1.0, 10.0, 1.0],
            "model": ["hirsch_recalibrated", "dem", "hirsch_recalibrated"],
            "E_norm_MPa": [1000.0, 2000.0, 5000.0],
            "phase_deg": [2.0, 30.0, 20.0],
        }
    )
    out = intervals.apply(forecast, iv, "curve")
    np.testing.assert_allclose(out.loc[0, ["E_low_MPa", "E_high_MPa"]].to_numpy(float), 1000 * np.exp([-0.5, 0.3]))
    assert out.loc[0, "phase_low_deg"] == 0.0 and out.loc[0, "phase_high_deg"] == 8.0  # held within [0, 90]
    assert out.loc[[1, 2], ["E_low_MPa", "phase_high_deg"]].isna().all().all()  # no calibration for them
    assert (
        out.loc[[0], ["E_low_MPa"]].notna().all().all()
        and intervals.apply(forecast, iv, "raw")["E_low_MPa"].isna().all()
    )


def test_the_coverage_command(tmp_path, capsys):
    rows = _rows()
    rows.insert(4, "label", "hirsch_recalibrated")
    rows.to_csv(tmp_path / "rows.csv", index=False)
    forecast = pd.DataFrame(
        {
            "mix_id": ["new"],
            "temperature_C": [21.1],
            "frequency_Hz": [1.0],
            "model": ["hirsch_recalibrated"],
            "E_norm_MPa": [1000.0],
            "phase_deg": [20.0],
        }
    )
    forecast.to_csv(tmp_path / "forecast.csv", index=False)
    out = {k: str(tmp_path / f"{k}.csv") for k in ("coverage", "intervals", "bounded")}
    args = ["forecast-coverage", str(tmp_path / "rows.csv"), "-o", out["coverage"], "--intervals", out["intervals"]]
    assert main([*args, "--forecast", str(tmp_path / "forecast.csv"), "--forecast-output", out["bounded"]]) == 0
    cov, iv = pd.read_csv(out["coverage"]), pd.read_csv(out["intervals"])
    assert list(cov.columns) == intervals.COVERAGE_COLUMNS and list(iv.columns) == intervals.INTERVAL_COLUMNS
    assert (iv["n_mixes"] == 35).all() and (iv["level"] == 0.9).all()
    bounded = pd.read_csv(out["bounded"])
    assert bounded.loc[0, "E_low_MPa"] < 1000.0 < bounded.loc[0, "E_high_MPa"]
    rows.drop(columns="E_pred_MPa").to_csv(tmp_path / "bad.csv", index=False)
    capsys.readouterr()
    bad = [
        "forecast-coverage",
        str(tmp_path / "bad.csv"),
        "-o",
        str(tmp_path / "c2.csv"),
        "--intervals",
        out["intervals"],
    ]
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert "bad.csv" in err and "E_pred_MPa" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c2.csv").exists()
    assert main([*args, "--forecast", str(tmp_path / "forecast.csv")]) == 2
    assert "--forecast-output" in capsys.readouterr().err
