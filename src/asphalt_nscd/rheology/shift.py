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
