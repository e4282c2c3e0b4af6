"""Scores of held-out and in-sample predictions, with intervals that mean what they say.

The rows of ``asphalt-nscd crossval`` (:mod:`asphalt_nscd.diagnosis.crossval`) give a
prediction per held-out cell. Per (scheme, kind, model, temperature, extrapolation), and
pooled over the temperatures (``temperature_C`` NaN):

* **|E*| as a log ratio**: d_c = ln(E_pred,c) - mean_s ln(E_s,c) against the mean of the
  specimens' ln|E*| (the geometric replicate mean), in %: the signed mean ``bias_logE_pct``
  = 100 mean_c d_c, and the absolute error against the population of specimens
  ``abs_logE_pct`` (the median of its random-effect distribution below; against these
  specimens' means, 100 mean_c |d_c|: ``abs_logE_vs_means_pct``);
* **Phi in degrees**: the same with Phi_pred - mean_s Phi_s (``bias_phase_deg``,
  ``abs_phase_deg``);
* the paper's MRE (Table 4: | |E*|_p / |E*|_m - 1 |, | Phi_p - Phi_m | / Phi_m, against the
  arithmetic replicate means, %) beside them, for comparison with the paper.

Intervals (95 %) over the specimens, which are what the reference is sampled from:

* signed means: a t(n - 1) interval over the specimens, b_s = mean_c (pred_c - y_s,c) (the
  mean of the b_s is the bias on a balanced table);
* absolute means: a random-effect model of the reference, y_s,c = mu_c + u_s + e_s,c
  (specimen effect u ~ N(0, tau^2), residual e ~ N(0, sigma^2), both estimated from the
  specimen-by-cell table); the error against the population means mu_c is distributed as
  mean_c |d_c + k (u* + e*_c)| with u* ~ N(0, tau^2/n), e*_c ~ N(0, sigma^2/n) and
  k = sqrt((n - 1) / chi2_{n-1}) for the uncertainty of the variances (so that n = 3 specimens
  give t-like widths): its median is the point value, its 2.5 and 97.5 percentiles the
  interval (the error against the sample means, smaller when the model sits within the
  reference's own noise, is given beside);
* leave one specimen out (``loso``): the reference of a fold is the held-out specimen itself,
  so the fold's own mean error is the sample; signed and absolute means get t(n - 1)
  intervals over the folds.

A bootstrap over 3 specimens has 10 distinct resamples and makes its "interval" the range of
the single-specimen errors; it is not used (docs/choices.md, Diagnosis: held-out errors and
their intervals).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import stats

#: random-effect draws of an absolute error's interval
N_SIMULATIONS = 4000
#: columns of :func:`summarize`
SUMMARY_COLUMNS = [
    "scheme",
    "kind",
    "model",
    "temperature_C",
    "extrapolation",
    "n_cells",
    "n_not_computable",
    "bias_logE_pct",
    "bias_logE_ci95_low",
    "bias_logE_ci95_high",
    "abs_logE_pct",
    "abs_logE_ci95_low",
    "abs_logE_ci95_high",
    "abs_logE_vs_means_pct",
    "bias_phase_deg",
    "bias_phase_ci95_low",
    "bias_phase_ci95_high",
    "abs_phase_deg",
    "abs_phase_ci95_low",
    "abs_phase_ci95_high",
    "abs_phase_vs_means_deg",
    "mre_E_norm_pct",
    "mre_phase_pct",
    "n_specimens",
    "interval",
    "noise_floor_E_norm_pct",
    "noise_floor_phase_pct",
]
#: what the intervals are, per scheme kind
INTERVALS = {
    "specimens": "signed: t(n-1) over the specimens; absolute: random-effect model of the specimens",
    "loso": "t(n-1) over the held-out specimens",
}
_KEYS = ["scheme", "kind", "model", "temperature_C", "extrapolation"]


def _round_T(values) -> np.ndarray:
    return np.round(np.asarray(values, float), 6)


def specimen_values(table: pd.DataFrame) -> pd.DataFrame:
    """Per (specimen, temperature, frequency): the mean ln|E*| and Phi (deg) of that
    specimen's tests of the cell (a repeated test averaged). Index (specimen, T rounded to
    1e-6 degC, f); columns ``lnE, phase``."""
    t = pd.DataFrame(
        {
            "specimen": table["specimen"].astype(str).to_numpy(),
            "T": _round_T(table["temperature_C"]),
            "f": table["frequency_Hz"].to_numpy(float),
            "lnE": np.log(table["E_norm_MPa"].to_numpy(float)),
            "phase": table["phase_deg"].to_numpy(float),
        }
    )
    return t.groupby(["specimen", "T", "f"])[["lnE", "phase"]].mean()


def t_interval(values, level: float = 0.95) -> tuple[float, float]:
    """t(n - 1) interval of the mean of ``values`` (NaN, NaN for fewer than 2 finite ones)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return np.nan, np.nan
    half = stats.t.ppf(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size)
    return float(v.mean() - half), float(v.mean() + half)


def binomial_ci(k: int, n: int, level: float = 0.95) -> tuple[float | None, float | None]:
    """Exact (Clopper-Pearson) confidence interval of a proportion k/n; (None, None) for n = 0."""
    if n <= 0:
        return None, None
    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return float(ci.low), float(ci.high)


def variance_components(Y: np.ndarray) -> tuple[float, float, int]:
    """(tau^2, sigma^2, n) of a specimen-by-cell table ``Y`` (n_specimens, n_cells; NaN where
    a specimen did not test a cell): the specimen effects' variance and the residual variance
    of the additive model y = mu_c + u_s + e (moment estimates, tau^2 floored at 0)."""
    Y = np.asarray(Y, float)
    keep = np.isfinite(Y).any(axis=1)
    Y = Y[keep]
    n = Y.shape[0]
    if n < 2:
        return np.nan, np.nan, n
    m = np.nanmean(Y, axis=0)
    u = np.nanmean(Y - m, axis=1)
    r = Y - m - u[:, None]
    ok = np.isfinite(r)
    n_c = max(int(np.isfinite(Y).any(axis=0).sum()), 1)
    dof = max(ok.sum() - n_c - n + 1, 1)
    sigma2 = float(np.nansum(r**2) / dof)
    tau2 = float(max(float(np.var(u, ddof=1)) - sigma2 / n_c, 0.0))
    return tau2, sigma2, n


def abs_interval(
    d: np.ndarray, Y: np.ndarray, n_sim: int = N_SIMULATIONS, seed: int = 0, level: float = 0.95
) -> tuple[float, float, float]:
    """(median, low, high) of the mean absolute error against the population means, from the
    random-effect model of the reference (module docstring). ``d``: errors against the sample
    means (n_cells,); ``Y``: the specimen-by-cell table (n_specimens, n_cells). NaNs with fewer
    than 2 specimens."""
    tau2, sigma2, n = variance_components(Y)
    if n < 2 or not np.isfinite(sigma2):
        return np.nan, np.nan, np.nan
    rng = np.random.default_rng(seed)
    k = np.sqrt((n - 1) / rng.chisquare(n - 1, n_sim))
    u = rng.normal(0.0, np.sqrt(tau2 / n), n_sim)
    e = rng.normal(0.0, np.sqrt(sigma2 / n), (n_sim, d.size))
    a = np.mean(np.abs(d[None, :] + k[:, None] * (u[:, None] + e)), axis=1)
    mid, lo, hi = np.percentile(a, [50.0, 50 * (1 - level), 50 * (1 + level)])
    return float(mid), float(lo), float(hi)


def _specimen_scores(g: pd.DataFrame, spec: pd.DataFrame) -> dict:
    """Scores of rows ``g`` (one group, computable rows) against the specimens' values."""
    cells = pd.DataFrame(
        {
            "T": _round_T(g["cell_temperature_C"]),
            "f": g["frequency_Hz"].to_numpy(float),
            "pE": np.log(g["E_norm_MPa_predicted"].to_numpy(float)),
            "pP": g["phase_deg_predicted"].to_numpy(float),
        }
    )
    specimens = sorted(spec.index.get_level_values(0).unique())
    YE = np.full((len(specimens), len(cells)), np.nan)
    YP = np.full_like(YE, np.nan)
    for i, s in enumerate(specimens):
        sub = spec.loc[s]
        for j, (T, f) in enumerate(zip(cells["T"], cells["f"])):
            if (T, f) in sub.index:
                YE[i, j], YP[i, j] = sub.loc[(T, f), "lnE"], sub.loc[(T, f), "phase"]
    out = {"n_specimens": int(np.isfinite(YE).any(axis=1).sum()), "interval": INTERVALS["specimens"]}
    for q, pred, Y, scale in (("logE", cells["pE"].to_numpy(), YE, 100.0), ("phase", cells["pP"].to_numpy(), YP, 1.0)):
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a cell no specimen tested: NaN, dropped below
            d = pred - np.nanmean(Y, axis=0)
            b_s = np.nanmean(pred[None, :] - Y, axis=1)
        keep = np.isfinite(d)
        d, Y = d[keep], Y[:, keep]
        unit = "pct" if q == "logE" else "deg"
        lo, hi = t_interval(b_s)
        a_mid, a_lo, a_hi = abs_interval(d, Y)
        observed = float(np.mean(np.abs(d)))
        out.update(
            {
                f"bias_{q}_{unit}": scale * float(np.mean(d)),
                f"abs_{q}_{unit}": scale * (a_mid if np.isfinite(a_mid) else observed),
                f"abs_{q}_vs_means_{unit}": scale * observed,
                f"bias_{q}_ci95_low": scale * lo,
                f"bias_{q}_ci95_high": scale * hi,
                f"abs_{q}_ci95_low": scale * a_lo,
                f"abs_{q}_ci95_high": scale * a_hi,
            }
        )
    return out


def _loso_scores(g: pd.DataFrame) -> dict:
    """Scores of leave-one-specimen-out rows: each fold's reference is its own specimen."""
    eE = np.log(g["E_norm_MPa_predicted"].to_numpy(float) / g["E_norm_MPa_measured"].to_numpy(float))
    eP = g["phase_deg_predicted"].to_numpy(float) - g["phase_deg_measured"].to_numpy(float)
    fold = g["fold"].astype(str).to_numpy()
    out = {"n_specimens": int(np.unique(fold).size), "interval": INTERVALS["loso"]}
    for q, e, scale, unit in (("logE", eE, 100.0, "pct"), ("phase", eP, 1.0, "deg")):
        per = pd.DataFrame({"fold": fold, "e": e, "a": np.abs(e)}).groupby("fold").mean()
        lo, hi = t_interval(per["e"])
        a_lo, a_hi = t_interval(per["a"])
        a_lo = max(a_lo, 0.0) if np.isfinite(a_lo) else a_lo  # an absolute error is >= 0
        out.update(
            {
                f"bias_{q}_{unit}": scale * float(e.mean()),
                f"abs_{q}_{unit}": scale * float(np.abs(e).mean()),
                f"abs_{q}_vs_means_{unit}": scale * float(np.abs(e).mean()),
                f"bias_{q}_ci95_low": scale * lo,
                f"bias_{q}_ci95_high": scale * hi,
                f"abs_{q}_ci95_low": scale * a_lo,
                f"abs_{q}_ci95_high": scale * a_hi,
            }
        )
    return out


def noise_floor(table: pd.DataFrame) -> pd.DataFrame:
    """Per temperature, the noise floor of a replicate-mean reference: the mean over the
    isotherm's cells of the standard error of the replicate mean, relative to the mean, for
    |E*| and for Phi (%), and the number of specimens.

    Columns ``temperature_C, noise_floor_E_norm_pct, noise_floor_phase_pct, n_specimens``;
    nan where a cell has a single replicate (no scatter to measure).
    """
    g = table.groupby(["temperature_C", "frequency_Hz"])
    cells = pd.DataFrame(
        {
            "n": g["E_norm_MPa"].size(),
            "se_E": g["E_norm_MPa"].std(ddof=1) / np.sqrt(g["E_norm_MPa"].size()) / g["E_norm_MPa"].mean(),
            "se_P": g["phase_deg"].std(ddof=1) / np.sqrt(g["phase_deg"].size()) / g["phase_deg"].mean(),
        }
    )
    cells = cells.reset_index()
    out = (
        cells.groupby("temperature_C")
        .agg(noise_floor_E_norm_pct=("se_E", "mean"), noise_floor_phase_pct=("se_P", "mean"))
        .reset_index()
    )
    out[["noise_floor_E_norm_pct", "noise_floor_phase_pct"]] *= 100.0
    spec = table.groupby("temperature_C")["specimen"].nunique().rename("n_specimens").reset_index()
    return out.merge(spec, on="temperature_C")


def summarize(rows: pd.DataFrame, table: pd.DataFrame | None = None) -> pd.DataFrame:
    """Scores per (scheme, kind, model, temperature, extrapolation) and pooled over the
    temperatures (``temperature_C`` NaN), columns :data:`SUMMARY_COLUMNS` (module docstring).
    Without the measured ``table`` only the loso rows and the MREs get scores (the others
    need the specimens' values)."""
    spec = specimen_values(table) if table is not None else None
    floor = noise_floor(table) if table is not None else None
    out = []
    rows = rows.assign(extrapolation=rows["extrapolation"].astype(bool), cell_temperature_C=rows["temperature_C"])
    pooled = rows.assign(temperature_C=np.nan)
    for frame in (rows, pooled):
        for key, g in frame.groupby(_KEYS, sort=True, dropna=False):
            ok = g[g["computable"]]
            r = dict(zip(_KEYS, key))
            r.update(
                {
                    "n_cells": int(len(ok)),
                    "n_not_computable": int(len(g) - len(ok)),
                    "mre_E_norm_pct": 100 * float(ok["rel_err_E_norm"].mean()) if len(ok) else np.nan,
                    "mre_phase_pct": 100 * float(ok["rel_err_phase"].mean()) if len(ok) else np.nan,
                }
            )
            if len(ok):
                if key[0] == "loso" and key[1] == "held_out":
                    r.update(_loso_scores(ok))
                elif spec is not None:
                    r.update(_specimen_scores(ok, spec))
            if floor is not None:
                f = (
                    floor
                    if np.isnan(r["temperature_C"])
                    else floor[np.isclose(floor["temperature_C"], r["temperature_C"], atol=1e-6, rtol=0)]
                )
                r["noise_floor_E_norm_pct"] = float(f["noise_floor_E_norm_pct"].mean()) if len(f) else np.nan
                r["noise_floor_phase_pct"] = float(f["noise_floor_phase_pct"].mean()) if len(f) else np.nan
            out.append(r)
    return pd.DataFrame(out).reindex(columns=SUMMARY_COLUMNS)


def headline(summary: pd.DataFrame) -> pd.DataFrame:
    """Per (scheme, kind, model): the pooled scores over the interpolated cells (lofo without
    its end frequencies, loto without its end temperatures; every cell of loso and of the
    in-sample rows) with their intervals, the pooled extrapolated ones apart, and the
    temperature whose absolute |E*| error is the largest (marked, not the headline).
    Columns: ``scheme, kind, model`` and, prefixed ``interp_`` / ``extrap_``, the score
    columns of :data:`SUMMARY_COLUMNS`; ``worst_T_C``, ``worst_abs_logE_pct``."""
    scores = [c for c in SUMMARY_COLUMNS if c not in _KEYS]
    out = []
    for key, g in summary.groupby(["scheme", "kind", "model"], sort=True):
        row = dict(zip(["scheme", "kind", "model"], key))
        pooled = g[g["temperature_C"].isna()]
        for label, sel in (("interp", ~pooled["extrapolation"]), ("extrap", pooled["extrapolation"])):
            p = pooled[sel]
            for c in scores:
                row[f"{label}_{c}"] = p.iloc[0][c] if len(p) else np.nan
        per_T = g[g["temperature_C"].notna() & ~g["extrapolation"]].dropna(subset=["abs_logE_pct"])
        if len(per_T):
            w = per_T.loc[per_T["abs_logE_pct"].idxmax()]
            row["worst_T_C"], row["worst_abs_logE_pct"] = float(w["temperature_C"]), float(w["abs_logE_pct"])
        else:
            row["worst_T_C"], row["worst_abs_logE_pct"] = np.nan, np.nan
        out.append(row)
    return pd.DataFrame(out)
