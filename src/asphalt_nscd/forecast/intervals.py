"""Prediction intervals of every forecast |E*| and phase angle, calibrated on mixes left out.

A forecast's interval is built from the held-out residuals of :func:`.validation.cross_validate`
(each mix forecast by the model fitted without it), per (model, coefficients, binder route,
temperature), for any model that writes such rows:

* residuals r = 100 ln(E_meas / E_pred) (%) and d = Phi_meas - Phi_pred (degrees), measured
  minus forecast, so that an interval [lo, hi] of r gives [E_pred e^(lo/100), E_pred e^(hi/100)];
* **each mix weighs the same.** The cells of one mix share its binder, gradation and the
  model's error for that mix, so they are not exchangeable with the cells of another mix; mixes
  are. A calibration mix k with N_k cells at the temperature gives each of its residuals the
  weight 1 / ((K + 1) N_k), K calibration mixes, and the new mix the mass 1 / (K + 1) at
  +infinity: the pooled empirical CDF of the mixes (Dunn, Wasserman & Ramdas 2023, "Distribution-
  free prediction sets for two-layer hierarchical models", JASA 118:2491-2502, "CDF pooling")
  with the finite-sample correction of split conformal prediction (Lei, G'Sell, Rinaldo,
  Tibshirani & Wasserman 2018, "Distribution-free predictive inference for regression", JASA
  113:1094-1111: the (K + 1)-th point at +infinity);
* **equal tails, chosen before any result was seen** (:data:`TAILS`): the upper offset is the
  weighted quantile at 1 - alpha/2 of r, the lower one minus that of -r (each tail misses at
  most alpha/2). A formula carries a bias that changes with temperature (its scores' ``bias``
  columns); an interval centred on the forecast would be wider by about twice that bias.
  ``symmetric`` (|r| at 1 - alpha) is the alternative, kept for comparison.

Guarantee (:func:`group_quantile`): for a fixed forecasting rule and exchangeable mixes, the
expected fraction of a new mix's cells inside is at least 1 - alpha, and at most 1 - alpha +
2 (1 + 1/N)/(K + 1) with equal tails (90 % to 96.7 % for 34 mixes of 6 cells). The residuals
here come from refitting without each mix: the "jackknife" of Barber, Candes, Ramdas &
Tibshirani (2021), "Predictive inference with the jackknife+", Ann. Statist. 49:486-507, whose
coverage rests on the fit being stable to one mix more or less (their jackknife+ guarantees
1 - 2 alpha without it, but needs every fold's model at the new mix); the nested coverage
measures what the guarantee leaves open.

**Coverage, nested** (:func:`nested`, :func:`coverage`): each mix's interval is calibrated on
the other mixes' held-out residuals only, never its own, and its cells are counted inside or
not. Per (model, coefficients, route, quantity) and per temperature and overall, the mean over
mixes of each mix's fraction of covered cells, with a t(n - 1) interval over the mixes (the
mixes are the sampling unit). A mix's residuals come from a fit that did see the other mixes
(its fold trained on them), so the nesting excludes the mix's own residual from its interval,
not its data from the other mixes' folds.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError

#: nominal level of the prediction intervals
LEVEL = 0.90
#: the interval's form (module docstring): ``equal`` tails on signed residuals, or ``symmetric``
TAILS = ("equal", "symmetric")
#: keys of a calibration group
KEYS = ["model", "coefficients", "binder_route", "temperature_C"]
#: the two quantities: residual column, offset column stem, unit
QUANTITIES = {"logE": ("r_logE_pct", "dlogE", "pct"), "phase": ("r_phase_deg", "dphase", "deg")}
#: columns of :func:`calibrate`
INTERVAL_COLUMNS = [
    "label",
    *KEYS,
    "level",
    "tails",
    "n_mixes",
    "n_cells",
    "dlogE_low_pct",
    "dlogE_high_pct",
    "dphase_low_deg",
    "dphase_high_deg",
]
#: columns of :func:`coverage`
COVERAGE_COLUMNS = [
    "label",
    "model",
    "coefficients",
    "binder_route",
    "quantity",
    "temperature_C",
    "level",
    "tails",
    "n_mixes",
    "n_cells",
    "coverage",
    "coverage_ci_low",
    "coverage_ci_high",
    "cell_coverage",
    "below",
    "above",
    "width_mean",
    "confidence",
]
#: columns the rows of :func:`.validation.cross_validate` must have here
ROW_NEEDS = [
    "mix_id",
    "model",
    "coefficients",
    "binder_route",
    "temperature_C",
    "E_meas_MPa",
    "phase_meas_deg",
    "E_pred_MPa",
    "phase_pred_deg",
]


def group_quantile(scores, groups, p: float) -> float:
    """The mix-weighted conformal quantile (module docstring) of ``scores`` at level ``p``.

    Parameters
    ----------
    scores : (n,) residuals of the calibration cells; non-finite ones are left out.
    groups : (n,) the mix of each cell.
    p : level in (0, 1).

    Returns
    -------
    float
        The smallest score s with sum of the weights 1/((K + 1) N_k) of the scores <= s at least
        ``p``; +inf when the K mixes' weight K/(K + 1) is below ``p`` (too few mixes) or no
        score is finite.

    Notes
    -----
    For K + 1 exchangeable mixes (the cells within a mix may be anything), write G for the
    mix-weighted CDF of all K + 1 mixes' scores and q for this quantile (the new mix at
    +infinity). G >= the corrected CDF, so q >= the p-quantile of G, whose expected value at
    the new mix is at least p by exchangeability of the mixes; q <= the (p + 1/(K + 1))-quantile
    of G. So the expected fraction of the new mix's scores <= q is at least p and, for distinct
    scores and at least N cells per mix, at most p + (1 + 1/N)/(K + 1) (twice that excess over
    the two tails of :func:`offsets`). With one cell per mix this is split conformal's
    ceil(p (K + 1))-th smallest score.
    """
    s = np.asarray(scores, float)
    g = np.asarray(groups)
    ok = np.isfinite(s)
    s, g = s[ok], g[ok]
    if s.size == 0:
        return np.inf
    _, inv, counts = np.unique(g, return_inverse=True, return_counts=True)
    w = 1.0 / ((counts.size + 1) * counts[inv])
    order = np.argsort(s, kind="stable")
    cum = np.cumsum(w[order])
    i = int(np.searchsorted(cum, p - 1e-12, side="left"))
    return float(s[order][i]) if i < s.size else np.inf


def offsets(residuals, groups, level: float = LEVEL, tails: str = "equal") -> tuple[float, float]:
    """(lower, upper) offsets of the interval of a new mix's residual from calibration
    ``residuals`` (n,) of the mixes ``groups`` (n,) at ``level`` (module docstring).

    Raises InputError for a level outside (0, 1) or unknown tails."""
    if not 0.0 < level < 1.0:
        raise InputError(f"prediction interval level {level}: expected a number in (0, 1)")
    r = np.asarray(residuals, float)
    alpha = 1.0 - level
    if tails == "equal":
        return -group_quantile(-r, groups, 1.0 - alpha / 2.0), group_quantile(r, groups, 1.0 - alpha / 2.0)
    if tails == "symmetric":
        h = group_quantile(np.abs(r), groups, 1.0 - alpha)
        return -h, h
    raise InputError(f"prediction interval tails {tails!r}: expected one of {TAILS}")


def residuals(rows: pd.DataFrame, where: str = "held-out rows") -> pd.DataFrame:
    """``rows`` (:data:`.validation.ROW_COLUMNS`) with ``label`` (when missing), ``r_logE_pct`` =
    100 ln(E_meas / E_pred) and ``r_phase_deg`` = Phi_meas - Phi_pred (NaN where a value is
    missing or not positive).

    Raises InputError naming ``where`` when a column is missing."""
    from ..io import require_columns

    require_columns(rows, ROW_NEEDS, where, "held-out rows of forecast-crossval")
    out = rows.copy()
    out["mix_id"] = out["mix_id"].astype(str)
    if "label" not in out:
        out["label"] = _labels(out)
    E_meas, E_pred = out["E_meas_MPa"].to_numpy(float), out["E_pred_MPa"].to_numpy(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = 100.0 * np.log(E_meas / E_pred)
    out["r_logE_pct"] = np.where((E_meas > 0) & (E_pred > 0), r, np.nan)
    out["r_phase_deg"] = out["phase_meas_deg"].to_numpy(float) - out["phase_pred_deg"].to_numpy(float)
    return out


def _labels(rows: pd.DataFrame) -> list[str]:
    from .dem import MODELS as DEM_MODELS

    return [m if m in DEM_MODELS else f"{m}_{c}" for m, c in zip(rows["model"], rows["coefficients"])]


def _groups(d: pd.DataFrame):
    return d.groupby(KEYS, sort=False, dropna=False)


def calibrate(rows: pd.DataFrame, level: float = LEVEL, tails: str = "equal") -> pd.DataFrame:
    """The intervals of a new mix's forecast: per (model, coefficients, binder route,
    temperature), offsets calibrated on every mix of the held-out ``rows``.

    Returns
    -------
    DataFrame, columns :data:`INTERVAL_COLUMNS`
        ``dlogE_low_pct, dlogE_high_pct``: the interval of 100 ln(E / E_forecast), %;
        ``dphase_low_deg, dphase_high_deg``: that of Phi - Phi_forecast, degrees; ``n_mixes``
        and ``n_cells`` with a finite |E*| residual. Infinite offsets when too few mixes.
    """
    d = residuals(rows)
    out = []
    for key, g in _groups(d):
        row = dict(zip(KEYS, key)) | {"label": g["label"].iloc[0], "level": level, "tails": tails}
        row["n_mixes"] = int(g.loc[np.isfinite(g["r_logE_pct"]), "mix_id"].nunique())
        row["n_cells"] = int(np.isfinite(g["r_logE_pct"]).sum())
        for _, (col, stem, unit) in QUANTITIES.items():
            lo, hi = offsets(g[col], g["mix_id"], level, tails)
            row[f"{stem}_low_{unit}"], row[f"{stem}_high_{unit}"] = lo, hi
        out.append(row)
    return pd.DataFrame(out, columns=INTERVAL_COLUMNS)


def apply(
    forecast: pd.DataFrame,
    intervals: pd.DataFrame,
    route: str,
    E_column: str = "E_norm_MPa",
    phase_column: str = "phase_deg",
    label_column: str = "model",
) -> pd.DataFrame:
    """``forecast`` with ``E_low_MPa, E_high_MPa, phase_low_deg, phase_high_deg``: each row's
    forecast with the offsets of its model (``label_column`` holds the model's label, as in
    forecast.csv) and temperature for the binder ``route`` (:func:`calibrate`). The phase
    bounds are held within [0, 90] degrees (a viscoelastic solid's range). A row whose model or
    temperature has no calibration gets NaN bounds.

    Raises InputError when a column is missing."""
    from ..io import require_columns

    require_columns(forecast, [label_column, "temperature_C", E_column, phase_column], "forecast table")
    require_columns(intervals, INTERVAL_COLUMNS, "interval table")
    iv = intervals[intervals["binder_route"] == route]
    key = ["label", "_T"]
    iv = iv.assign(_T=iv["temperature_C"].astype(float).round(6))[
        [*key, "dlogE_low_pct", "dlogE_high_pct", "dphase_low_deg", "dphase_high_deg"]
    ]
    f = forecast.reset_index(drop=True)
    m = f[[label_column, "temperature_C"]].rename(columns={label_column: "label"})
    m = m.assign(label=m["label"].astype(str), _T=m["temperature_C"].astype(float).round(6))[key]
    m = m.merge(iv.drop_duplicates(key), on=key, how="left")
    E, P = f[E_column].to_numpy(float), f[phase_column].to_numpy(float)
    out = f.copy()
    with np.errstate(over="ignore"):
        out["E_low_MPa"] = E * np.exp(m["dlogE_low_pct"].to_numpy(float) / 100.0)
        out["E_high_MPa"] = E * np.exp(m["dlogE_high_pct"].to_numpy(float) / 100.0)
    out["phase_low_deg"] = np.clip(P + m["dphase_low_deg"].to_numpy(float), 0.0, 90.0)
    out["phase_high_deg"] = np.clip(P + m["dphase_high_deg"].to_numpy(float), 0.0, 90.0)
    return out


def nested(rows: pd.DataFrame, level: float = LEVEL, tails: str = "equal") -> pd.DataFrame:
    """Every held-out cell with its interval calibrated on the OTHER mixes of its (model,
    coefficients, route, temperature): :func:`residuals`' columns plus ``dlogE_low_pct,
    dlogE_high_pct, dphase_low_deg, dphase_high_deg`` and ``logE_covered``,
    ``phase_covered`` (1.0 inside, 0.0 outside, NaN for a missing residual)."""
    d = residuals(rows).reset_index(drop=True)
    for _, (col, stem, unit) in QUANTITIES.items():
        d[f"{stem}_low_{unit}"] = np.nan
        d[f"{stem}_high_{unit}"] = np.nan
    for _, g in _groups(d):
        mixes = g["mix_id"].to_numpy()
        for mix in pd.unique(mixes):
            own = mixes == mix
            idx = g.index[own]
            for _, (col, stem, unit) in QUANTITIES.items():
                lo, hi = offsets(g[col].to_numpy(float)[~own], mixes[~own], level, tails)
                d.loc[idx, f"{stem}_low_{unit}"] = lo
                d.loc[idx, f"{stem}_high_{unit}"] = hi
    for q, (col, stem, unit) in QUANTITIES.items():
        r = d[col].to_numpy(float)
        inside = (r >= d[f"{stem}_low_{unit}"].to_numpy(float)) & (r <= d[f"{stem}_high_{unit}"].to_numpy(float))
        d[f"{q}_covered"] = np.where(np.isfinite(r), inside.astype(float), np.nan)
    return d


def coverage(rows: pd.DataFrame, level: float = LEVEL, tails: str = "equal", confidence: float = 0.95) -> pd.DataFrame:
    """Nested coverage of the intervals (module docstring) per (model, coefficients, binder
    route, quantity), overall (``temperature_C`` NaN) and per temperature.

    Returns
    -------
    DataFrame, columns :data:`COVERAGE_COLUMNS`
        ``coverage``: mean over mixes of each mix's fraction of cells inside its interval, with
        its t(n - 1) interval (``confidence``) over the ``n_mixes``; ``cell_coverage``: the
        fraction of all ``n_cells``; ``below``/``above``: mean fraction under/over the interval;
        ``width_mean``: mean over mixes of hi - lo (% for logE, degrees for phase; inf when a
        group has too few mixes).
    """
    from ..diagnosis.scores import t_interval

    d = nested(rows, level, tails)
    out = []
    for (model, coef, route), g in d.groupby(["model", "coefficients", "binder_route"], sort=False):
        for q, (col, stem, unit) in QUANTITIES.items():
            cells = g[np.isfinite(g[col])]
            cells = cells.assign(
                _below=(cells[col] < cells[f"{stem}_low_{unit}"]).astype(float),
                _above=(cells[col] > cells[f"{stem}_high_{unit}"]).astype(float),
                _width=cells[f"{stem}_high_{unit}"] - cells[f"{stem}_low_{unit}"],
            )
            for T in [np.nan, *sorted(cells["temperature_C"].unique())]:
                sel = cells if np.isnan(T) else cells[cells["temperature_C"] == T]
                if sel.empty:
                    continue
                per_mix = sel.groupby("mix_id")[[f"{q}_covered", "_below", "_above", "_width"]].mean()
                v = per_mix[f"{q}_covered"].to_numpy(float)
                lo, hi = t_interval(v, confidence)
                out.append(
                    {
                        "label": g["label"].iloc[0],
                        "model": model,
                        "coefficients": coef,
                        "binder_route": route,
                        "quantity": q,
                        "temperature_C": T,
                        "level": level,
                        "tails": tails,
                        "n_mixes": len(per_mix),
                        "n_cells": len(sel),
                        "coverage": float(v.mean()),
                        "coverage_ci_low": lo,
                        "coverage_ci_high": hi,
                        "cell_coverage": float(sel[f"{q}_covered"].mean()),
                        "below": float(per_mix["_below"].mean()),
                        "above": float(per_mix["_above"].mean()),
                        "width_mean": float(per_mix["_width"].mean()),
                        "confidence": confidence,
                    }
                )
    return pd.DataFrame(out, columns=COVERAGE_COLUMNS)
