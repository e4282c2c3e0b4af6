"""Outlying cells of a measured table against the screening model of the artifact search.

(The lab's own data-quality indicators are read and flagged where the table is read:
:mod:`asphalt_nscd.lab.checks`.)

* **Outlying cells** (:func:`cell_outliers`): a cell (temperature, frequency) whose replicate
  mean departs from the screening model of the artifact search (2S2P1D with free shift and
  vertical factor per isotherm, specimen factors: the isotherm's smooth course) refitted
  without that cell (a deleted residual: the cell cannot bend the model towards itself) by
  more than the replicate scatter, the refitted model's own uncertainty there and the table's
  typical cell misfit allow. z = r / sqrt(s_point^2 / n + v_pred + s_cell^2), s_cell the
  robust (median absolute) scatter of the deleted residuals beyond the rest, two-sided normal p-value, Bonferroni over the cells at ``alpha``; reported
  with their size (|E*| in %, Phi in deg), never dropped.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

#: family-wise level of the outlier test over the cells
OUTLIER_ALPHA = 0.01


def _rows_data(search, rows: pd.DataFrame) -> dict:
    """Model arrays of ``rows`` of the search's table with the whole table's specimen and
    isotherm lists (the parameter layout of its fits)."""
    from ..rheology.master_curve import data_arrays

    d = data_arrays(rows)
    d["specimens"], d["temperatures"] = list(search.data["specimens"]), search.data["temperatures"]
    d["spec"] = rows["specimen"].astype(str).map({s: i for i, s in enumerate(d["specimens"])}).to_numpy(int)
    return d


def _cell_key(df: pd.DataFrame) -> pd.Series:
    return df["temperature_C"].round(6).astype(str) + "|" + df["frequency_Hz"].astype(str)


def deleted_residuals(search, fit, without=()) -> pd.DataFrame:
    """Per cell (temperature, frequency): the replicate mean's departure from the screening
    model (with the fit's artifact terms) refitted without that cell, in ln|E*| and Phi (deg),
    with the number of tests ``n``, the cell's ``key`` and the variances of the refitted model's
    prediction of the cell mean ``vE``, ``vP`` (delta method on the refit's covariance);
    ``without``: keys of cells left out of every refit (and not scored). Columns ``key, T, f,
    n, rE, rP, vE, vP``."""
    terms = search.artifact_terms(fit)
    df = search.df
    key = _cell_key(df)
    gone = key.isin(set(without)).to_numpy()
    out = []
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in pd.unique(key[~gone]):
            cell = (key == k).to_numpy()
            rest = df[~cell & ~gone]
            try:
                sub = search.problem(terms, _rows_data(search, rest)).fit(x0=fit.x)
                prob = search.problem(terms, _rows_data(search, df[cell]))
                E = prob.measured_modulus(sub.x)
            except ValueError:
                continue
            # variance of the refitted model's prediction of the cell mean: g^T C g (delta method)
            free = np.flatnonzero(np.diag(sub.cov) > 0)
            g = np.zeros((2, free.size))
            for j, i in enumerate(free):
                h = 1e-6 * max(1.0, abs(sub.x[i]))
                xp = sub.x.copy()
                xp[i] += h
                Ep = prob.measured_modulus(xp)
                g[0, j] = np.mean(np.log(np.abs(Ep)) - np.log(np.abs(E))) / h
                g[1, j] = np.mean(np.degrees(np.angle(Ep) - np.angle(E))) / h
            C = sub.cov[np.ix_(free, free)]
            rows = df[cell]
            out.append(
                {
                    "key": k,
                    "T": float(rows["temperature_C"].iloc[0]),
                    "f": float(rows["frequency_Hz"].iloc[0]),
                    "n": int(cell.sum()),
                    "rE": float(np.mean(np.log(rows["E_norm_MPa"].to_numpy(float)) - np.log(np.abs(E)))),
                    "rP": float(np.mean(rows["phase_deg"].to_numpy(float) - np.degrees(np.angle(E)))),
                    "vE": float(g[0] @ C @ g[0]),
                    "vP": float(g[1] @ C @ g[1]),
                }
            )
    return pd.DataFrame(out, columns=["key", "T", "f", "n", "rE", "rP", "vE", "vP"])


def cell_outliers(search, fit, alpha: float = OUTLIER_ALPHA, max_cells: int = 5) -> list[dict]:
    """Outlying cells of the table of ``search`` (:class:`~asphalt_nscd.diagnosis.effects.ArtifactSearch`)
    against its screening fit ``fit`` (module docstring), each judged on the model refitted
    without it (:func:`deleted_residuals`, so that the cell cannot pull the model towards
    itself), one at a time: the most outlying cell beyond the Bonferroni threshold is named and
    left out of the next round's fits (so that it does not bend its neighbours' model either),
    up to ``max_cells``. One dict per named cell and quantity: ``temperature_C, frequency_Hz,
    quantity`` (``E_norm`` or ``phase``), ``size`` (|E*| %: 100 ln(measured / model); Phi:
    deg), ``z``, ``p`` (Bonferroni-adjusted over the cells and both quantities), ``n``."""
    s_pt = [v if v is not None else s for v, s in zip(search.replicate_sigma, search.sigma)]
    named: list[str] = []
    out: list[dict] = []
    for _ in range(int(max_cells)):
        cells = deleted_residuals(search, fit, named)
        if cells.empty:
            break
        n = cells["n"].to_numpy(float)
        m = len(cells) + len(named)
        found = []
        for q, col, var, s, scale in (("E_norm", "rE", "vE", s_pt[0], 100.0), ("phase", "rP", "vP", s_pt[1], 1.0)):
            r = cells[col].to_numpy(float)
            v = cells[var].to_numpy(float)
            mad = 1.4826 * np.median(np.abs(r - np.median(r)))
            s_cell = float(np.sqrt(max(mad**2 - np.mean(s**2 / n + v), 0.0)))
            z = r / np.sqrt(s**2 / n + v + s_cell**2)
            p = np.minimum(1.0, 2 * stats.norm.sf(np.abs(z)) * 2 * m)  # Bonferroni: cells x both quantities
            for k in np.flatnonzero(p < alpha):
                found.append(
                    {
                        "key": cells["key"].iloc[k],
                        "temperature_C": float(cells["T"].iloc[k]),
                        "frequency_Hz": float(cells["f"].iloc[k]),
                        "quantity": q,
                        "size": float(scale * r[k]),
                        "size_unit": "%" if q == "E_norm" else "deg",
                        "z": float(z[k]),
                        "p": float(p[k]),
                        "n": int(n[k]),
                        "cell_misfit_sd": scale * s_cell,
                    }
                )
        if not found:
            break
        top = max(found, key=lambda o: abs(o["z"]))
        named.append(top["key"])
        out += [{k: v for k, v in o.items() if k != "key"} for o in found if o["key"] == top["key"]]
    return out
