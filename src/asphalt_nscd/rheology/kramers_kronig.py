"""Kramers-Kronig consistency of |E*| and Phi: the Booij-Thoone approximation.

For a causal linear viscoelastic material, the phase angle follows from the slope of the
modulus on log axes (Booij & Thoone 1982, Rheol. Acta 21, 15-24)::

    Phi(w) ~ (pi / 2) d ln|E*| / d ln w                     (Phi in rad)

exact for a power law and accurate to a few percent for the broad spectra of bitumen and
mixes. A measured phase that departs from this prediction in a systematic way points to an
artifact of the measurement: a constant time lag between force and displacement adds
360 f dt (deg) to Phi and nothing to |E*|, so the residual Phi_meas - Phi_KK grows linearly
in f; an uncorrected inertia term lowers |E*| at high f and raises Phi.

Choice: within an isotherm the slope is taken from a polynomial of degree
``min(2, n_frequencies - 2)`` in ln w fitted by least squares to every replicate point.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def booij_thoone_phase(frequency_Hz, E_norm, degree: int = 2) -> np.ndarray:
    """Phase angle (deg) predicted from the slope of ln|E*| in ln f, one isotherm.

    Parameters
    ----------
    frequency_Hz : array, shape (m,)
        Frequencies, Hz (at least 2 distinct values; replicates allowed).
    E_norm : array, shape (m,)
        |E*|, any unit (> 0).
    degree : int
        Maximum polynomial degree of ln|E*| in ln f (reduced to ``n_distinct - 1``).

    Returns
    -------
    ndarray, shape (m,), degrees.

    Raises
    ------
    ValueError
        on fewer than 2 distinct frequencies or non-positive values.
    """
    f = np.asarray(frequency_Hz, dtype=float)
    E = np.asarray(E_norm, dtype=float)
    if np.any(f <= 0) or np.any(E <= 0):
        raise ValueError("frequencies and |E*| must be positive")
    n_distinct = np.unique(f).size
    if n_distinct < 2:
        raise ValueError("need at least 2 distinct frequencies for a slope")
    deg = int(min(degree, n_distinct - 1, max(1, n_distinct - 2)))
    x = np.log(f)
    coef = np.polyfit(x, np.log(E), deg)
    slope = np.polyval(np.polyder(coef), x)
    return np.degrees(0.5 * np.pi * slope)


def kk_residuals(df: pd.DataFrame, degree: int = 2) -> pd.DataFrame:
    """Measured minus Booij-Thoone phase for every row of a tidy table.

    Returns a copy of ``df`` with columns ``phase_kk_deg`` and ``phase_kk_residual_deg``.
    """
    out = df.copy()
    out["phase_kk_deg"] = np.nan
    for _, g in out.groupby("temperature_C"):
        out.loc[g.index, "phase_kk_deg"] = booij_thoone_phase(g["frequency_Hz"], g["E_norm_MPa"], degree)
    out["phase_kk_residual_deg"] = out["phase_deg"] - out["phase_kk_deg"]
    return out


def kk_time_lag(df: pd.DataFrame, degree: int = 2) -> dict:
    """Time lag from the Kramers-Kronig residual: residual = a_T + 360 f dt.

    An intercept per isotherm absorbs the bias of the approximation; the common slope gives
    dt. Returns ``time_lag_ms``, ``time_lag_se_ms`` (ordinary least squares).
    """
    r = kk_residuals(df, degree)
    temps = np.sort(r["temperature_C"].unique())
    X = np.column_stack(
        [r["frequency_Hz"].to_numpy(float) * 360.0] + [(r["temperature_C"] == T).to_numpy(float) for T in temps]
    )
    y = r["phase_kk_residual_deg"].to_numpy(float)
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    dof = max(len(y) - X.shape[1], 1)
    s2 = float(np.sum((y - X @ coef) ** 2) / dof)
    cov = s2 * np.linalg.pinv(X.T @ X)
    return {"time_lag_ms": float(coef[0] * 1e3), "time_lag_se_ms": float(np.sqrt(cov[0, 0]) * 1e3)}


def isotherm_residuals(df: pd.DataFrame, degree: int = 2) -> pd.Series:
    """Mean |Phi - Phi_Booij-Thoone| (deg) of each isotherm of a tidy table (index:
    temperature_C): the Kramers-Kronig consistency statistic of the isotherm."""
    r = kk_residuals(df, degree)
    return r.groupby("temperature_C")["phase_kk_residual_deg"].agg(lambda x: float(np.mean(np.abs(x))))
