"""How the forecast reads its binder: the curve's extrapolation and the frequency of the reading.

Two questions about the binder every forecast reads (:mod:`.binder`, :mod:`.validation`):

* **Extrapolation.** Where a binder's points fail their checks (the cold isotherms of the shipped
  table) its master curve is the extrapolation of its shift law. The variants compared
  (:data:`VARIANTS`): each shift law of :data:`.binder.SHIFT_FORMS` with the glassy modulus fixed
  at 1 GPa or fitted (:data:`.binder.GLASSY_FORMS`). :func:`isotherm_cases` judges them on the
  binder's own data: each temperature with passing points left out in turn, while 2 or more stay,
  the curve fitted on the rest predicts the left-out points (rmse of ln|G*| and of delta);
  ``position`` says whether the left-out isotherm lies below (``colder``), inside (``interior``)
  or above (``warmer``) the temperatures that stay: ``colder`` is the extrapolation the cold cells
  of a forecast rely on. :func:`variant_curves` gives every binder's curve under a variant (the
  fit ladder of :func:`.binder.fit_binder_ladder`, its rung recorded), for held-out forecasts.
* **Reading.** The published formulas read the binder at the frequency of the table's binder
  columns (``binder_frequency_Hz``; f / 2 pi Hz on the shipped table), or at the mix's own
  frequency f (:func:`with_binder_reading`, :data:`READINGS`).

:func:`summarize_isotherms` gives per variant the mean over binders of each binder's mean rmse,
with a t interval over binders, and its difference to the default variant on the cases both fit;
:func:`paired_difference` the per-mix difference of two sets of held-out rows (same mixes, same
models) with a t interval over mixes.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError
from .binder import GLASSY_BOUNDS_PA, GLASSY_FORMS, SHIFT_FORMS, fit_binder_ladder, fit_curve

#: the binder curve variants compared: (shift law, glassy modulus), the default first
VARIANTS = tuple((shift, glassy) for shift in SHIFT_FORMS for glassy in GLASSY_FORMS)
#: how the published formulas read the binder: at the table's binder frequency, or at the mix's own frequency
READINGS = ("declared", "mix")
#: columns of :func:`isotherm_cases`
CASE_COLUMNS = [
    "binder",
    "shift",
    "glassy",
    "left_out_C",
    "position",
    "n_train",
    "n_test",
    "fitted",
    "rmse_lnG",
    "rmse_delta_deg",
    "Gg_Pa",
    "Gg_at_bound",
    "coldest_C",
    "log10_aT_coldest",
]


def _position(T: float, kept: np.ndarray) -> str:
    return "colder" if T < kept.min() else "warmer" if T > kept.max() else "interior"


def isotherm_cases(checked: pd.DataFrame, variants=VARIANTS) -> pd.DataFrame:
    """Every binder's passing isotherms left out in turn, under every variant (module docstring).

    Parameters
    ----------
    checked : DataFrame, the rows of :func:`.binder.check_points` (``passed``; ``eta_Pa_s`` for the
        viscosity shift) of one or many binders.
    variants : iterable of (shift law, glassy form).

    Returns
    -------
    DataFrame, columns :data:`CASE_COLUMNS`: per binder and variant one row for the fit on all its
    passing points (``left_out_C`` NaN, ``position`` ``full``; rmse in-sample) and one per
    left-out temperature (rmse on the left-out passing points). ``fitted`` False (and NaN
    values) where the points kept cannot carry the variant (:func:`.binder.fit_curve`'s rule).
    ``log10_aT_coldest``: the curve's log10 shift factor at the binder's coldest temperature
    (``coldest_C``, passing or not); ``Gg_at_bound``: a fitted glassy modulus within 1e-3 in
    log10 of :data:`.binder.GLASSY_BOUNDS_PA`.
    """
    out = []
    for binder, g in checked.groupby("binder", sort=True):
        passing = g[g["passed"]]
        temps = np.unique(passing["temperature_C"].to_numpy(float))
        coldest = float(g["temperature_C"].min())
        cases = [(np.nan, g)] + [(float(T), g.assign(passed=g["passed"] & (g["temperature_C"] != T))) for T in temps]
        for T, train in cases:
            kept = np.unique(train.loc[train["passed"], "temperature_C"].to_numpy(float))
            if np.isfinite(T) and kept.size < 2:
                continue
            test = passing if not np.isfinite(T) else passing[passing["temperature_C"] == T]
            for shift, glassy in variants:
                row = {
                    "binder": binder,
                    "shift": shift,
                    "glassy": glassy,
                    "left_out_C": T,
                    "position": "full" if not np.isfinite(T) else _position(T, kept),
                    "n_train": int(train["passed"].sum()),
                    "n_test": len(test),
                    "coldest_C": coldest,
                }
                try:
                    c = fit_curve(train, shift=shift, glassy=glassy)
                except ValueError:
                    out.append({**row, "fitted": False})
                    continue
                Tt, f = test["temperature_C"].to_numpy(float), test["frequency_Hz"].to_numpy(float)
                lnG = np.log(c.G_Pa(Tt, f) / test["G_Pa"].to_numpy(float))
                dd = c.delta_deg(Tt, f) - test["delta_deg"].to_numpy(float)
                log_gg = np.log10(c.Gg_Pa)
                at_bound = glassy == "fitted" and min(abs(log_gg - np.log10(b)) for b in GLASSY_BOUNDS_PA) < 1e-3
                row.update(
                    fitted=True,
                    rmse_lnG=float(np.sqrt(np.mean(lnG**2))),
                    rmse_delta_deg=float(np.sqrt(np.mean(dd**2))),
                    Gg_Pa=c.Gg_Pa,
                    Gg_at_bound=bool(at_bound),
                    log10_aT_coldest=float(c.log_shift(coldest)),
                )
                out.append(row)
    return pd.DataFrame(out).reindex(columns=CASE_COLUMNS)


#: columns of :func:`summarize_isotherms`
SUMMARY_COLUMNS = [
    "shift",
    "glassy",
    "position",
    "n_cases",
    "n_binders",
    "rmse_lnG",
    "rmse_lnG_ci_low",
    "rmse_lnG_ci_high",
    "rmse_delta_deg",
    "rmse_delta_ci_low",
    "rmse_delta_ci_high",
    "n_paired",
    "n_binders_paired",
    "diff_rmse_lnG",
    "diff_rmse_lnG_ci_low",
    "diff_rmse_lnG_ci_high",
    "diff_rmse_delta_deg",
    "diff_rmse_delta_ci_low",
    "diff_rmse_delta_ci_high",
    "confidence",
]


def _over_binders(p: pd.DataFrame, column: str, confidence: float) -> tuple[float, float, float]:
    """Mean over binders of each binder's mean ``column``, with its t(n_binders - 1) interval."""
    from ..diagnosis.scores import t_interval

    v = p.groupby("binder")[column].mean().to_numpy(float)
    lo, hi = t_interval(v, confidence) if v.size >= 2 else (np.nan, np.nan)
    return (float(v.mean()) if v.size else np.nan), lo, hi


def summarize_isotherms(cases: pd.DataFrame, reference=VARIANTS[0], confidence: float = 0.95) -> pd.DataFrame:
    """Left-out isotherm errors of :func:`isotherm_cases` per variant and ``position`` (``all``: the
    left-out cases of every position). On the cases the variant fits: the mean over binders of
    each binder's mean rmse (ln|G*|, delta in degrees), with a t(n_binders - 1) interval (NaN for
    one binder). Paired with the ``reference`` variant on the cases both fit (``n_paired``):
    the same mean of the per-case difference variant - reference (negative: the variant is
    better; NaN for the reference itself). Columns :data:`SUMMARY_COLUMNS`."""
    left = cases[(cases["position"] != "full") & cases["fitted"].astype(bool)]
    key = ["binder", "left_out_C"]
    ref = left[(left["shift"] == reference[0]) & (left["glassy"] == reference[1])]
    out = []
    for (shift, glassy), g in left.groupby(["shift", "glassy"], sort=False):
        pair = g.merge(ref[[*key, "rmse_lnG", "rmse_delta_deg"]], on=key, suffixes=("", "_ref"))
        pair = pair.assign(d_lnG=pair["rmse_lnG"] - pair["rmse_lnG_ref"])
        pair = pair.assign(d_delta=pair["rmse_delta_deg"] - pair["rmse_delta_deg_ref"])
        for position in ("all", "colder", "interior", "warmer"):
            p = g if position == "all" else g[g["position"] == position]
            q = pair if position == "all" else pair[pair["position"] == position]
            if p.empty:
                continue
            row = {"shift": shift, "glassy": glassy, "position": position, "confidence": confidence}
            row.update(n_cases=len(p), n_binders=p["binder"].nunique())
            row["rmse_lnG"], row["rmse_lnG_ci_low"], row["rmse_lnG_ci_high"] = _over_binders(p, "rmse_lnG", confidence)
            row["rmse_delta_deg"], row["rmse_delta_ci_low"], row["rmse_delta_ci_high"] = _over_binders(
                p, "rmse_delta_deg", confidence
            )
            is_ref = (shift, glassy) == tuple(reference)
            row.update(n_paired=0 if is_ref else len(q), n_binders_paired=0 if is_ref else q["binder"].nunique())
            if not is_ref and len(q):
                row["diff_rmse_lnG"], row["diff_rmse_lnG_ci_low"], row["diff_rmse_lnG_ci_high"] = _over_binders(
                    q, "d_lnG", confidence
                )
                row["diff_rmse_delta_deg"], row["diff_rmse_delta_ci_low"], row["diff_rmse_delta_ci_high"] = (
                    _over_binders(q, "d_delta", confidence)
                )
            out.append(row)
    return pd.DataFrame(out).reindex(columns=SUMMARY_COLUMNS)


def variant_curves(checked: pd.DataFrame, shift: str, glassy: str) -> tuple[dict, pd.DataFrame]:
    """Every binder's curve under one variant, by the fit ladder (:func:`.binder.fit_binder_ladder`
    with ``shift`` on every rung). Returns (binder -> curve, one row per binder: ``binder, shift,
    glassy, rung, Gg_Pa``). ValueError (naming the binder) when no rung carries the variant."""
    curves, rows = {}, []
    for binder, g in checked.groupby("binder", sort=True):
        c, rung, _ = fit_binder_ladder(g, shift=shift, glassy=glassy)
        curves[binder] = c
        rows.append({"binder": binder, "shift": shift, "glassy": glassy, "rung": rung, "Gg_Pa": c.Gg_Pa})
    return curves, pd.DataFrame(rows)


def with_binder_reading(table: pd.DataFrame, reading: str) -> pd.DataFrame:
    """``table`` (a matched table, before :func:`.validation.with_binder_route`) with the frequency
    at which the binder curve is read for the published formulas: ``declared`` keeps the table's
    ``binder_frequency_Hz`` (f / 2 pi Hz on the shipped table), ``mix`` sets it to the mix's own
    ``frequency_Hz``. Only the curve route reads it (the raw route's values are the table's).
    Raises InputError for an unknown reading."""
    if reading not in READINGS:
        raise InputError(f"binder reading {reading!r}: expected one of {READINGS}")
    return table.copy() if reading == "declared" else table.assign(binder_frequency_Hz=table["frequency_Hz"])


#: columns of :func:`paired_difference`
PAIRED_COLUMNS = [
    "model",
    "coefficients",
    "temperature_C",
    "n_mixes",
    "diff_abs_logE_pct",
    "diff_abs_logE_ci_low",
    "diff_abs_logE_ci_high",
    "diff_abs_phase_deg",
    "diff_abs_phase_ci_low",
    "diff_abs_phase_ci_high",
    "confidence",
]


def paired_difference(a: pd.DataFrame, b: pd.DataFrame, confidence: float = 0.95) -> pd.DataFrame:
    """Per (model, coefficients) and temperature (NaN: every temperature), the mean over mixes of
    the mix's mean |100 ln(E_pred / E_meas)| (and |phase error|, degrees) in ``b`` minus that in
    ``a``, with a t(n - 1) interval over the mixes present in both (negative: ``b`` better).
    ``a``, ``b``: rows of :func:`.validation.cross_validate`. Columns :data:`PAIRED_COLUMNS`."""
    from ..diagnosis.scores import t_interval

    def per_mix(rows):
        d = rows.assign(
            e=np.abs(100.0 * np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"])),
            p=np.abs(rows["phase_pred_deg"] - rows["phase_meas_deg"]),
        )
        keys = ["model", "coefficients", "mix_id"]
        overall = d.groupby(keys)[["e", "p"]].mean().reset_index().assign(temperature_C=np.nan)
        by_T = d.groupby([*keys, "temperature_C"])[["e", "p"]].mean().reset_index()
        return pd.concat([overall, by_T], ignore_index=True).assign(T=lambda x: x["temperature_C"].fillna(-999.0))

    m = per_mix(a).merge(per_mix(b), on=["model", "coefficients", "mix_id", "T"], suffixes=("_a", "_b"))
    out = []
    for (model, coef, T), g in m.groupby(["model", "coefficients", "T"], sort=False):
        row = {"model": model, "coefficients": coef, "temperature_C": np.nan if T == -999.0 else T}
        row.update(n_mixes=len(g), confidence=confidence)
        for col, name in (("e", "diff_abs_logE"), ("p", "diff_abs_phase")):
            v = (g[f"{col}_b"] - g[f"{col}_a"]).dropna().to_numpy(float)
            lo, hi = t_interval(v, confidence) if v.size >= 2 else (np.nan, np.nan)
            key = f"{name}_pct" if col == "e" else f"{name}_deg"
            row.update({key: float(v.mean()) if v.size else np.nan, f"{name}_ci_low": lo, f"{name}_ci_high": hi})
        out.append(row)
    return pd.DataFrame(out, columns=PAIRED_COLUMNS)
