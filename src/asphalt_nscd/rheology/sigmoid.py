"""The sigmoidal master curve of the MEPDG (AASHTO R 84 / NCHRP 1-37A), the form US labs report.

    log10 |E*| = delta + alpha / (1 + exp(beta + gamma log10 f_r)),    f_r = f aT(T),
    log10 aT = a1 (T - T_ref) + a2 (T - T_ref)^2                         (degC)

|E*| in MPa, f in Hz. delta is the log of the long-time (static) modulus, delta + alpha that
of the glassy modulus; beta and gamma set the position and the steepness of the transition
(gamma < 0 with the sign convention above for a modulus that rises with frequency). The
phase angle is not part of the R 84 form; :func:`sigmoid_phase_deg` gives the Booij-Thoone
estimate (pi / 2) d ln|E*| / d ln f of it for display. Fitted by least squares on log10|E*|
of every measured row (:func:`fit_sigmoid`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError

PARAMETERS = ("delta", "alpha", "beta", "gamma", "a1_per_C", "a2_per_C2")


def sigmoid_log_modulus(p: dict, frequency_Hz, temperature_C) -> np.ndarray:
    """log10 |E*| (MPa) of the sigmoid ``p`` (keys :data:`PARAMETERS` and ``T_ref_C``)."""
    T = np.asarray(temperature_C, float) - p["T_ref_C"]
    x = np.log10(np.asarray(frequency_Hz, float)) + p["a1_per_C"] * T + p["a2_per_C2"] * T**2
    return p["delta"] + p["alpha"] / (1.0 + np.exp(p["beta"] + p["gamma"] * x))


def sigmoid_phase_deg(p: dict, frequency_Hz, temperature_C) -> np.ndarray:
    """Booij-Thoone phase (deg) of the sigmoid: 90 d log10|E*| / d log10 f."""
    T = np.asarray(temperature_C, float) - p["T_ref_C"]
    x = np.log10(np.asarray(frequency_Hz, float)) + p["a1_per_C"] * T + p["a2_per_C2"] * T**2
    e = np.exp(p["beta"] + p["gamma"] * x)
    return 90.0 * (-p["alpha"] * p["gamma"] * e / (1.0 + e) ** 2)


def fit_sigmoid(table: pd.DataFrame, T_ref_C: float) -> dict:
    """Least-squares fit of the sigmoid to log10 |E*| of a measured table (columns
    ``temperature_C, frequency_Hz, E_norm_MPa``).

    Returns
    -------
    dict: the parameters (:data:`PARAMETERS`), ``T_ref_C``, ``rmse_log10`` (root mean square
    residual of log10|E*|), ``mre_E_norm_pct`` (mean relative error of |E*|, %, in-sample),
    ``n_rows``.

    Raises
    ------
    InputError if the table has fewer rows than parameters or the fit fails.
    """
    from scipy.optimize import least_squares

    T = table["temperature_C"].to_numpy(float)
    f = table["frequency_Hz"].to_numpy(float)
    y = np.log10(table["E_norm_MPa"].to_numpy(float))
    if y.size <= len(PARAMETERS):
        raise InputError(f"sigmoid master curve: {y.size} rows for {len(PARAMETERS)} parameters")
    lo, hi = y.min(), y.max()
    x0 = [lo - 0.3, hi - lo + 0.6, -1.0, -0.5, -0.1, 0.0]

    def resid(v):
        p = dict(zip(PARAMETERS, v), T_ref_C=T_ref_C)
        return sigmoid_log_modulus(p, f, T) - y

    best = None
    for beta in (-2.0, -1.0, 0.0, 1.0):
        x0[2] = beta
        try:
            res = least_squares(resid, x0, bounds=([-2, 0.1, -20, -5, -1, -0.05], [6, 8, 20, -0.01, 1, 0.05]))
        except ValueError:
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None or not best.success:
        raise InputError("sigmoid master curve: the least-squares fit failed")
    p = dict(zip(PARAMETERS, (float(v) for v in best.x)), T_ref_C=float(T_ref_C))
    r = resid(best.x)
    p.update(
        {
            "rmse_log10": float(np.sqrt(np.mean(r**2))),
            "mre_E_norm_pct": float(100 * np.mean(np.abs(10.0**r - 1.0))),
            "n_rows": int(y.size),
        }
    )
    return p
