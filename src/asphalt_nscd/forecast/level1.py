"""Where users take a forecast: the Level 1 |E*| table a pavement designer enters, and its sigmoid.

For every forecast mix, by the model the cross-validation found best (lowest mean held-out
|E*| log error over the mixes, :func:`best_model`):

* the |E*| table of the MEPDG / AASHTOWare Pavement ME Level 1 dynamic-modulus input: one row
  per temperature (degF and degC), one column per frequency (Hz), in psi and in MPa
  (:func:`designer_tables`);
* its sigmoidal master curve, log10|E*| = delta + alpha / (1 + exp(beta + gamma log10 f_r)),
  f_r = f aT, log10 aT = a1 (T - T_ref) + a2 (T - T_ref)^2 (AASHTO R 84 form,
  :mod:`asphalt_nscd.rheology.sigmoid`), T_ref = 21.1 degC (70 degF), with delta in MPa and in psi.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..io import InputError

#: reference temperature of the sigmoid, degC (70 degF, the MEPDG's)
T_REF_C = (70.0 - 32.0) / 1.8
#: log10 of MPa per psi
LOG10_MPA_PER_PSI = math.log10(6.894757293168361e-3)


def best_model(scores: pd.DataFrame, route: str) -> str:
    """The label of the model with the lowest overall mean held-out |E*| log error over every mix
    (``group`` all, ``temperature_C`` empty) for the binder ``route``.

    Raises InputError when the scores hold no such row."""
    rows = scores[(scores["group"] == "all") & scores["temperature_C"].isna() & (scores["binder_route"] == route)]
    rows = rows.dropna(subset=["abs_logE_pct"])
    if rows.empty:
        raise InputError(f"forecast scores: no overall row for the binder route {route!r}")
    return str(rows.loc[rows["abs_logE_pct"].idxmin(), "label"])


def designer_tables(forecast: pd.DataFrame, model: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(Level 1 tables, sigmoids) of every mix of ``forecast`` (columns of forecast.csv) by ``model``.

    Level 1 tables: columns ``mix_id, model, unit, temperature_F, temperature_C`` and one column
    ``<f> Hz`` per frequency (with ``<f> Hz low`` and ``<f> Hz high``, the prediction interval, when
    ``forecast`` has ``E_low_MPa, E_high_MPa``), one row per (mix, unit, temperature). Sigmoids: one row per mix,
    the :data:`asphalt_nscd.rheology.sigmoid.PARAMETERS`, ``T_ref_C``, ``delta_psi``, ``rmse_log10``
    (NaN parameters for a mix with too few conditions to fit)."""
    from ..rheology.sigmoid import PARAMETERS, fit_sigmoid

    rows = forecast[forecast["model"] == model]
    tables, sigmoids = [], []
    for mix, g in rows.groupby("mix_id", sort=False):
        bounds = [("", "E_norm_MPa")] + ([(" low", "E_low_MPa"), (" high", "E_high_MPa")] if "E_low_MPa" in g else [])
        for unit, scale in (("psi", 1.0 / 6.894757293168361e-3), ("MPa", 1.0)):
            parts = []
            for suffix, column in bounds:
                w = g.pivot_table(index="temperature_C", columns="frequency_Hz", values=column) * scale
                w = w.sort_index().sort_index(axis=1)
                w.columns = [f"{f:g} Hz{suffix}" for f in w.columns]
                parts.append(w)
            wide = pd.concat(parts, axis=1)
            wide = wide[sorted(wide.columns, key=lambda c: (float(c.split(" Hz")[0]), c))]
            wide.insert(0, "temperature_F", np.round(wide.index.to_numpy() * 1.8 + 32.0, 6))
            tables.append(wide.reset_index().assign(mix_id=mix, model=model, unit=unit))
        try:
            p = fit_sigmoid(g, T_REF_C)
        except InputError:
            p = {k: np.nan for k in PARAMETERS} | {"T_ref_C": T_REF_C, "rmse_log10": np.nan}
        sigmoids.append({"mix_id": mix, "model": model, **{k: p[k] for k in (*PARAMETERS, "T_ref_C", "rmse_log10")}})
    level1 = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame(columns=["mix_id", "model", "unit"])
    first = ["mix_id", "model", "unit", "temperature_F", "temperature_C"]
    level1 = level1[[c for c in first if c in level1] + [c for c in level1 if c not in first]]
    sig = pd.DataFrame(sigmoids, columns=["mix_id", "model", *PARAMETERS, "T_ref_C", "rmse_log10"])
    sig.insert(3, "delta_psi", sig["delta"] - LOG10_MPA_PER_PSI)
    return level1, sig
