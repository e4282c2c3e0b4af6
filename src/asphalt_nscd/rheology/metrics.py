"""Error measures and table matching shared by calibration, campaign and diagnosis.

One place for three small concepts that every comparison of a model with a complex-modulus
table uses:

* **Mean relative error** (paper Table 4): over the cells of an isotherm,
  MRE = mean |x_model - x_data| / |x_data| x 100 %, for the norm of E* and for the phase
  angle Phi alike (:func:`relative_errors`, :func:`mre_pct`). Reference = the measured
  replicate means unless a caller says otherwise.
* **Replicate means** (:func:`cell_means`): one row per tested cell (temperature_C,
  frequency_Hz) with the replicate count and the means of |E*|, Phi and ln|E*|.
* **Temperature matching** (:func:`same_temperature`, :func:`at_temperature`,
  :func:`temperature_key`): two temperatures are the same isotherm when they differ by at
  most :data:`TEMPERATURE_TOL_C` = 1e-6 degC (absolute, no relative part). Tables and law
  files give temperatures with at most a few decimals (law JSON keys are written with
  ``%g``, 6 significant digits), so one absolute tolerance well below any tested step and
  above the rounding of a written key is the rule; it replaces the four tolerances the
  modules used before (1e-9 degC absolute, NumPy's default 1e-5 relative + 1e-8, 1e-12 + 1e-12
  relative/absolute). Frequencies (:func:`same_frequency`) match within a relative
  :data:`FREQUENCY_RTOL` = 1e-12 (they span decades, so the rule is relative).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: two temperatures (degC) within this absolute difference are the same isotherm
TEMPERATURE_TOL_C = 1e-6
#: two frequencies within this relative difference are the same tested frequency
FREQUENCY_RTOL = 1e-12


def signed_relative_errors(model, reference) -> np.ndarray:
    """(model - reference) / |reference| element-wise (fractions; the bias), arrays of one shape."""
    model = np.asarray(model, float)
    reference = np.asarray(reference, float)
    return (model - reference) / np.abs(reference)


def relative_errors(model, reference) -> np.ndarray:
    """|model - reference| / |reference| element-wise (fractions), arrays of one shape."""
    return np.abs(signed_relative_errors(model, reference))


def mre_pct(model, reference) -> float:
    """Mean relative error in percent, 100 mean |model - reference| / |reference| (module
    docstring); NaN for empty input."""
    e = relative_errors(model, reference)
    return float(100.0 * np.mean(e)) if e.size else float("nan")


def cell_means(df: pd.DataFrame) -> pd.DataFrame:
    """Replicate means per (temperature_C, frequency_Hz), sorted: ``temperature_C,
    frequency_Hz, n, E_norm_MPa, phase_deg, lnE`` (count; means of |E*| in MPa, Phi in deg,
    ln|E*|). ``df``: rows with ``temperature_C, frequency_Hz, E_norm_MPa > 0, phase_deg``."""
    d = df.assign(lnE=np.log(df["E_norm_MPa"]))
    return d.groupby(["temperature_C", "frequency_Hz"], as_index=False).agg(
        n=("E_norm_MPa", "size"),
        E_norm_MPa=("E_norm_MPa", "mean"),
        phase_deg=("phase_deg", "mean"),
        lnE=("lnE", "mean"),
    )


def same_temperature(a, b) -> np.ndarray | np.bool_:
    """True where temperatures ``a`` and ``b`` (degC, broadcast) are the same isotherm
    (|a - b| <= :data:`TEMPERATURE_TOL_C`; an infinite temperature is never an isotherm)."""
    return np.abs(np.subtract(a, b, dtype=float)) <= TEMPERATURE_TOL_C


def same_frequency(a, b) -> np.ndarray | np.bool_:
    """True where frequencies ``a`` and ``b`` (Hz, > 0, broadcast) are the same."""
    return np.isclose(a, b, rtol=FREQUENCY_RTOL, atol=0.0)


def at_temperature(frame: pd.DataFrame, temperature_C: float, column: str = "temperature_C") -> pd.DataFrame:
    """The rows of ``frame`` at ``temperature_C`` (:func:`same_temperature`)."""
    return frame[same_temperature(frame[column].to_numpy(float), float(temperature_C))]


def temperature_key(keys, temperature_C: float):
    """The first of ``keys`` (temperatures, degC) that is ``temperature_C``, or None."""
    return next((k for k in keys if same_temperature(float(k), float(temperature_C))), None)
