"""Time-temperature superposition: WLF and Arrhenius shift factors.

A thermorheologically simple material has ``E*(omega, T) = E*(omega aT(T), Tref)``; the shift
factor aT multiplies the frequency (equivalently divides the characteristic times).

* WLF (Williams, Landel & Ferry 1955)::

      log10 aT = -C1 (T - Tref) / (C2 + T - Tref)          (T, Tref in degC, C2 in K)

  valid for T - Tref > -C2. Published values for asphalt mixes with Tref = 15 degC:
  C1 about 20-35, C2 about 120-250 K (Olard & Di Benedetto 2003; Mangiafico et al. 2015).
* Arrhenius::

      log10 aT = Ea / (R ln 10) (1/T - 1/Tref)              (T in K)

  with the apparent activation energy Ea (J/mol), typically 150-250 kJ/mol for bitumen
  below about 60 degC.
"""

from __future__ import annotations

import numpy as np

#: Gas constant, J/(mol K).
R_GAS = 8.314462618
#: 0 degC in K.
KELVIN = 273.15


def wlf_log_shift(temperature_C, T_ref_C: float, C1: float, C2: float) -> np.ndarray:
    """log10 aT of the WLF equation.

    Parameters
    ----------
    temperature_C : float or array, any shape
        Temperatures, degC.
    T_ref_C : float
        Reference temperature, degC.
    C1 : float
        Dimensionless WLF constant (> 0).
    C2 : float
        WLF constant, K (> 0).

    Returns
    -------
    ndarray, same shape as ``temperature_C``
        log10 of the shift factor (> 0 below Tref: slower response).

    Raises
    ------
    ValueError
        if C2 <= 0 or some T - Tref <= -C2 (outside the WLF domain).
    """
    dT = np.asarray(temperature_C, dtype=float) - T_ref_C
    if not C2 > 0:
        raise ValueError(f"WLF C2 must be positive, got {C2}")
    if np.any(C2 + dT <= 0):
        raise ValueError(f"WLF undefined for T - Tref <= -C2 (C2 = {C2} K, Tref = {T_ref_C} degC)")
    return -C1 * dT / (C2 + dT)


def arrhenius_log_shift(temperature_C, T_ref_C: float, Ea_J_mol: float) -> np.ndarray:
    """log10 aT of the Arrhenius law, same shape as ``temperature_C`` (degC); Ea in J/mol."""
    T = np.asarray(temperature_C, dtype=float) + KELVIN
    return Ea_J_mol / (R_GAS * np.log(10.0)) * (1.0 / T - 1.0 / (T_ref_C + KELVIN))


def wlf_temperature(log_aT, T_ref_C: float, C1: float, C2: float) -> np.ndarray:
    """Inverse of :func:`wlf_log_shift`: the temperature (degC) with the given log10 aT.

    Raises ValueError if some log10 aT <= -C1 (the WLF asymptote).
    """
    a = np.asarray(log_aT, dtype=float)
    if np.any(a <= -C1):
        raise ValueError(f"log10 aT must exceed -C1 = {-C1}")
    return T_ref_C - a * C2 / (C1 + a)


def fit_wlf(temperature_C, log_aT, T_ref_C: float) -> dict:
    """Least-squares WLF constants from shift factors (e.g. free shifts of a master curve).

    Parameters
    ----------
    temperature_C, log_aT : arrays, shape (n,), n >= 3
        Temperatures (degC) and log10 shift factors (log10 aT(Tref) = 0 is not imposed: an
        offset is fitted too, so the shifts may be relative to any isotherm).

    Returns
    -------
    dict
        ``C1, C2`` (K), ``offset`` (log10 aT at Tref of the given shifts), ``rmse`` (decades).

    Raises
    ------
    ValueError
        on fewer than 3 temperatures or arrays of different length.
    """
    from scipy.optimize import least_squares

    T = np.asarray(temperature_C, dtype=float)
    a = np.asarray(log_aT, dtype=float)
    if T.shape != a.shape or T.size < 3:
        raise ValueError("need at least 3 (temperature, log aT) pairs of equal length")
    c2_min = max(1.0, T_ref_C - T.min() + 1.0)

    def resid(x):
        c1, c2, off = x
        return off - c1 * (T - T_ref_C) / (c2 + T - T_ref_C) - a

    best = None
    for c2 in (max(c2_min + 10, 50.0), max(c2_min + 10, 150.0), max(c2_min + 10, 400.0)):
        res = least_squares(resid, [20.0, c2, 0.0], bounds=([0.1, c2_min, -50], [200.0, 5000.0, 50]))
        if best is None or res.cost < best.cost:
            best = res
    c1, c2, off = best.x
    return {"C1": float(c1), "C2": float(c2), "offset": float(off),
            "rmse": float(np.sqrt(np.mean(best.fun**2)))}


def fit_arrhenius(temperature_C, log_aT, T_ref_C: float) -> dict:
    """Linear least-squares Arrhenius fit: ``Ea_J_mol``, ``offset`` and ``rmse`` (decades).

    Raises ValueError on fewer than 2 temperatures.
    """
    T = np.asarray(temperature_C, dtype=float) + KELVIN
    a = np.asarray(log_aT, dtype=float)
    if T.shape != a.shape or T.size < 2:
        raise ValueError("need at least 2 (temperature, log aT) pairs of equal length")
    x = 1.0 / T - 1.0 / (T_ref_C + KELVIN)
    A = np.column_stack([x, np.ones_like(x)])
    coef, *_ = np.linalg.lstsq(A, a, rcond=None)
    return {"Ea_J_mol": float(coef[0] * R_GAS * np.log(10.0)), "offset": float(coef[1]),
            "rmse": float(np.sqrt(np.mean((A @ coef - a) ** 2)))}
