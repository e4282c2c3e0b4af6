"""The forecast's commands as the workflow chains them, on six shipped mixes (one emptied, no viscosity
column): binders and their curves, held-out errors with intervals, the forecast of the emptied mix by
every model, its Level 1 tables and sigmoid, the page; and the folds and scores they rest on."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.forecast import dem, level1, validation
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.matched import read_matched, write_matched
from asphalt_nscd.sample.lattice import lattice_sample

TABLE = Path(__file__).resolve().parents[2] / "data" / "binder_mix" / "mixes_35.tsv"
MIXES = ["193", "195", "204", "209", "218", "236"]


@pytest.fixture(scope="module")
def chain(tmp_path_factory):
    """The commands run in order on a matched table of six mixes, mix 236 emptied, viscosity dropped."""
    out = tmp_path_factory.mktemp("forecast")
    t = read_matched(TABLE)
    t = t[t["mix_id"].isin(MIXES)].copy()
    t.loc[t["mix_id"] == "236", ["E_norm_MPa", "phase_deg"]] = np.nan
    t["binder_eta_Pa_s"] = np.nan
    write_matched(t, out / "matched.csv")
    responses = []
    for k, m in enumerate(MIXES):
        s = lattice_sample(40, seed=k, aspect=(1.0, 1.0, 1.0), radius_range=(1.9e-3, 2.0e-3), jitter=0.0)
        side = float(s.plate_point[1, 2])
        s.attrs.update(B_m=side, e_m=side, h_m=side, shrink_radius_factor=0.95)
        dem.sample_response(s, m, 1).save(out / f"{m}_s1.npz")
        responses.append(str(out / f"{m}_s1.npz"))
    files = {k: str(out / v) for k, v in (("points", "points.csv"), ("curves", "curves.json"))}
    assert main(["forecast-binders", str(out / "matched.csv"), "-o", files["points"], "--curves", files["curves"]]) == 0
    common = ["--matched", str(out / "matched.csv"), "--curves", files["curves"], "--responses", *responses]
    cv = [str(out / n) for n in ("rows.csv", "scores.csv", "constants.json", "split.csv", "selection.csv", "lr.csv")]
    extra = ["--split", cv[3], "--selection", cv[4], "--learned-rows", cv[5], "--jobs", "2"]
    assert main(["forecast-crossval", *common, "-o", cv[0], "--scores", cv[1], "--constants", cv[2], *extra]) == 0
    cov = [str(out / n) for n in ("coverage.csv", "intervals.csv")]
    assert main(["forecast-coverage", cv[0], "-o", cov[0], "--intervals", cov[1]]) == 0
    fc = [str(out / n) for n in ("forecast.csv", "level1.csv", "sigmoid.csv", "fconstants.json")]
    args = ["--scores", cv[1], "-o", fc[0], "--level1", fc[1], "--sigmoid", fc[2], "--constants", fc[3]]
    args += ["--intervals", cov[1], "--state", str(out / "trained")]
    assert main(["forecast", *common, *args]) == 0
    page = out / "page" / "forecast.md"
    pargs = ["--table-name", "six mixes", "--matched", str(out / "matched.csv"), "--points", files["points"]]
    pargs += ["--curves", files["curves"], "--rows", cv[0], "--scores", cv[1], "--constants", cv[2]]
    pargs += ["--forecast", fc[0], "--forecast-constants", fc[3], "-o", str(page)]
    pargs += ["--split", cv[3], "--selection", cv[4], "--coverage", cov[0], "--learned-rows", cv[5]]
    assert main(["forecast-page", *pargs]) == 0
    return out


def test_every_model_is_scored_where_its_inputs_exist(chain):
    scores = pd.read_csv(chain / "scores.csv")
    labels = {r: set(g["label"]) for r, g in scores.groupby("binder_route")}
    # without a viscosity column, Witczak 1-37A reads its viscosity from the binder's master curve only
    assert "witczak_1_37a_recalibrated" in labels["curve"] and "witczak_1_37a_recalibrated" not in labels["raw"]
    assert {"hirsch_published", "hirsch_recalibrated", "witczak_1_40d_published", "dem", "dem_extended"} <= labels[
        "raw"
    ]
    overall = scores[scores["temperature_C"].isna() & (scores["group"] == "all")]
    assert (overall["n_mixes"] == 5).all()  # the five measured mixes, each held out once
    ok = overall["abs_logE_ci_low"] <= overall["abs_logE_pct"]
    assert ok.all() and (overall["abs_logE_pct"] <= overall["abs_logE_ci_high"]).all()


def test_the_emptied_mix_is_forecast_by_every_model_with_its_level1_tables(chain):
    forecast = pd.read_csv(chain / "forecast.csv", dtype={"mix_id": str})
    assert set(forecast["mix_id"]) == {"236"} and forecast.groupby("model").size().eq(30).all()
    assert {"dem", "dem_extended", "hirsch_recalibrated", "witczak_1_37a_published"} <= set(forecast["model"])
    assert np.isfinite(forecast[["E_norm_MPa", "phase_deg"]].to_numpy()).all()
    best = json.loads((chain / "fconstants.json").read_text())["best_model"]
    tables = pd.read_csv(chain / "level1.csv", dtype={"mix_id": str})
    assert set(tables["model"]) == {best} and len(tables) == 10
    psi = tables[tables["unit"] == "psi"].set_index("temperature_C")["25 Hz"]
    mpa = tables[tables["unit"] == "MPa"].set_index("temperature_C")["25 Hz"]
    np.testing.assert_allclose(psi * 6.894757293168361e-3, mpa, rtol=1e-12)
    sig = pd.read_csv(chain / "sigmoid.csv", dtype={"mix_id": str})
    assert sig.iloc[0]["rmse_log10"] < 0.1 and sig.iloc[0]["delta_psi"] > sig.iloc[0]["delta"]


def test_the_page_says_which_model_is_best_and_how_the_binder_route_matters(chain):
    page = (chain / "page" / "forecast.md").read_text()
    assert "## Which model forecasts best" in page and "**Goals.**" in page
    assert "## The discrete model by its number of constants" in page and "| dem_physical | 0: none |" in page
    assert "## Where the error lies" in page and "## The choice inside the fold" in page
    assert "## Prediction intervals" in page and "## A data-driven yardstick" in page
    assert "## The binder through its master curve against the table's raw values" in page
    assert "## The binders' own data quality" in page and "left out: reasons" in page
    assert (chain / "page" / "figures" / "predicted_vs_measured.png").stat().st_size > 20_000
    assert (chain / "page" / "figures" / "binder_master_curves.png").stat().st_size > 20_000


def test_folds_by_mix_and_t_intervals():
    assert validation.mix_folds(["a", "b", "c"]) == [["a"], ["b"], ["c"]]
    k = validation.mix_folds([str(i) for i in range(10)], k=3, seed=4)
    assert sorted(sum(k, [])) == sorted(str(i) for i in range(10)) and sorted(map(len, k)) == [3, 3, 4]
    assert k == validation.mix_folds([str(i) for i in range(10)], k=3, seed=4)
    with pytest.raises(InputError, match="k = 11 folds of 10 mixes"):
        validation.mix_folds([str(i) for i in range(10)], k=11)
    from scipy import stats

    rows = pd.DataFrame(
        {
            "mix_id": np.repeat(["a", "b", "c", "d"], 2),
            "binder_seen": True,
            "model": "m",
            "coefficients": "published",
            "binder_route": "raw",
            "temperature_C": np.tile([10.0, 20.0], 4),
            "E_meas_MPa": 100.0,
            "E_pred_MPa": 100.0 * np.exp(np.array([0.1, 0.3, -0.2, 0.0, 0.05, 0.15, 0.4, 0.2])),
            "phase_meas_deg": 20.0,
            "phase_pred_deg": 21.0,
        }
    )
    s = validation.score(rows)
    r = s[(s["group"] == "all") & s["temperature_C"].isna()].iloc[0]
    per_mix = 100 * np.array([0.2, 0.1, 0.1, 0.3])
    half = stats.t.ppf(0.975, 3) * per_mix.std(ddof=1) / 2
    assert r["abs_logE_pct"] == pytest.approx(per_mix.mean())
    assert r["abs_logE_ci_high"] - r["abs_logE_pct"] == pytest.approx(half)
    assert r["max_abs_logE_pct"] == pytest.approx(40.0) and r["abs_phase_deg"] == pytest.approx(1.0)


def test_the_best_model_is_the_lowest_overall_error_of_the_route():
    scores = pd.DataFrame(
        {
            "label": ["a", "b", "a", "b"],
            "group": "all",
            "temperature_C": np.nan,
            "binder_route": ["curve", "curve", "raw", "raw"],
            "abs_logE_pct": [30.0, 20.0, 10.0, 40.0],
        }
    )
    assert level1.best_model(scores, "curve") == "b" and level1.best_model(scores, "raw") == "a"
