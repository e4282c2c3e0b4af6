"""Leave-mixes-out validation of the forecasts: folds by mix, errors per temperature, intervals.

A forecast is judged on mixes it never saw (docs/validation.md, "Forecasts from the binder").
The folds hold out whole mixes: leave one mix out (the default), or k folds of mixes drawn with
a seed. Inside a fold everything fitted is fitted on the training mixes only (a model's
recalibrated coefficients, a DEM constant); what a forecast of the held-out mix reads is its
own binder (through the binder's master curve, fitted on the binder's data alone:
:mod:`.binder`), gradation and volumetrics, never its measured |E*| or phase.

Scores (per model, binder route, temperature and overall):

* |E*| as a log ratio, e = 100 ln(E_pred / E_meas) per cell, %: ``abs_logE_pct`` the mean over
  mixes of each mix's mean |e|, ``max_abs_logE_pct`` the largest |e| of any cell,
  ``bias_logE_pct`` the mean over mixes of each mix's mean e;
* the phase angle in degrees, d = Phi_pred - Phi_meas: ``abs_phase_deg``, ``max_abs_phase_deg``,
  ``bias_phase_deg`` likewise.

Intervals: a t(n - 1) interval over the n mixes of the group (the mixes are the sampling
unit; 35 mixes), on the per-mix means. Groups: every mix, mixes whose binder also serves a
training mix of their fold (``binder_seen``) and mixes whose binder does not; and the cells whose
binder is read within (``binder_measured``) or outside (``binder_extrapolated``) the temperatures
of the points its master curve was fitted on (:meth:`.binder.BinderCurve.extrapolated`; the same
cells on both routes), each mix's mean over its cells of the group.

The Witczak equations give |E*| only: their phase angle is the Booij-Thoone estimate
(pi/2) d ln|E*| / d ln w of the forecast isotherm (Booij & Thoone 1982; :mod:`asphalt_nscd.rheology.kramers_kronig`),
labelled ``phase_source = booij_thoone``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..io import InputError

BINDER_ROUTES = ("curve", "raw")
COEFFICIENTS = ("published", "recalibrated")
#: columns of :func:`cross_validate`'s rows
ROW_COLUMNS = [
    "mix_id",
    "fold",
    "binder_id",
    "binder_seen",
    "model",
    "coefficients",
    "binder_route",
    "temperature_C",
    "frequency_Hz",
    "E_meas_MPa",
    "phase_meas_deg",
    "E_pred_MPa",
    "phase_pred_deg",
    "phase_source",
    "binder_extrapolated",
]


@dataclass(frozen=True)
class Baseline:
    """A published formula with its published or recalibrated coefficients (:mod:`.baselines`)."""

    model: str
    coefficients: str = "published"

    @property
    def name(self) -> str:
        return f"{self.model} ({self.coefficients})"

    def available(self, table: pd.DataFrame) -> bool:
        """Whether ``table`` gives every input the formula reads (a table without viscosity gives
        Witczak 1-37A its input only through the binder's master curve)."""
        return all(table[c].notna().all() for c in _inputs_needed(self.model))

    def fit(self, train: pd.DataFrame) -> dict | None:
        """The coefficients for a fold: None (published) or recalibrated on ``train`` (rows of
        the training mixes with measured |E*| and phase)."""
        if self.coefficients == "published":
            return None
        from . import baselines

        rows = train.dropna(subset=["E_norm_MPa", "phase_deg", *_inputs_needed(self.model)])
        if rows.empty:
            raise InputError(f"{self.name}: no training row with every input the model needs")
        return baselines.recalibrate(
            self.model,
            mix_of(rows),
            rows["frequency_Hz"].to_numpy(float),
            rows["binder_G_MPa"].to_numpy(float) * 1e6,
            rows["binder_delta_deg"].to_numpy(float),
            rows["binder_eta_Pa_s"].to_numpy(float),
            rows["E_norm_MPa"].to_numpy(float),
            rows["phase_deg"].to_numpy(float),
        )

    def predict(self, coef: dict | None, rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, str]:
        """(|E*| MPa, phase deg, phase source) for ``rows``; NaN where an input is missing."""
        from . import baselines

        E, phase = baselines.predict(
            self.model,
            mix_of(rows),
            rows["frequency_Hz"].to_numpy(float),
            rows["binder_G_MPa"].to_numpy(float) * 1e6,
            rows["binder_delta_deg"].to_numpy(float),
            rows["binder_eta_Pa_s"].to_numpy(float),
            coef=coef,
        )
        E = np.asarray(E, float)
        if phase is not None:
            return E, np.asarray(phase, float), "model"
        return E, booij_thoone_isotherms(rows, E), "booij_thoone"


def model_label(model) -> str:
    """A model's name in tables: a discrete model's own name (``dem...``, with ``@<variant>`` on a sample
    variant's: ``dem_p2@cut6.3_x2.5``), else ``<formula>_<coefficients>``."""
    if model.model.startswith("dem"):
        variant = getattr(model, "variant", "")
        return f"{model.model}@{variant}" if variant else model.model
    return f"{model.model}_{model.coefficients}"


def _inputs_needed(model: str) -> tuple:
    return ("binder_eta_Pa_s",) if model == "witczak_1_37a" else ("binder_G_MPa", "binder_delta_deg")


def mix_of(rows: pd.DataFrame):
    """The formulation of ``rows`` as :class:`.baselines.Mix` (one value per row)."""
    from .baselines import Mix

    return Mix(
        rho34=rows["rho34_pct"].to_numpy(float),
        rho38=rows["rho38_pct"].to_numpy(float),
        rho4=rows["rho4_pct"].to_numpy(float),
        rho200=rows["rho200_pct"].to_numpy(float),
        Va=rows["Va_pct"].to_numpy(float),
        Vbeff=rows["Vbeff_pct"].to_numpy(float),
    )


def booij_thoone_isotherms(rows: pd.DataFrame, E: np.ndarray) -> np.ndarray:
    """Booij-Thoone phase (deg) of each (mix, temperature) isotherm of the forecast ``E``
    (:func:`asphalt_nscd.rheology.kramers_kronig.booij_thoone_phase`, degree 2 in ln f); NaN
    for an isotherm of one frequency or with a missing value."""
    from ..rheology.kramers_kronig import booij_thoone_phase

    out = np.full(len(rows), np.nan)
    keys = rows[["mix_id", "temperature_C"]].astype(str).agg("|".join, axis=1).to_numpy()
    f = rows["frequency_Hz"].to_numpy(float)
    for key in dict.fromkeys(keys):
        idx = np.flatnonzero(keys == key)
        if np.unique(f[idx]).size >= 2 and np.all(np.isfinite(E[idx])) and np.all(E[idx] > 0):
            out[idx] = booij_thoone_phase(f[idx], E[idx])
    return out


def binder_ids(table: pd.DataFrame) -> pd.Series:
    """A binder id per mix (index ``mix_id``): mixes whose binder columns are identical at
    every condition share a binder (:func:`.binder.binder_ids`)."""
    from .binder import binder_ids as ids

    return ids(table)


def with_binder_route(table: pd.DataFrame, curves: dict, binder_of_mix: pd.Series, route: str) -> pd.DataFrame:
    """``table`` with its binder columns as the forecast reads them.

    ``raw``: the table's own values. ``curve``: the binder master curve's |G*| and delta at each
    temperature and at the frequency the table's binder columns refer to (``binder_frequency_Hz``:
    the published formulas read the binder as their calibration data gave it), and its MEPDG
    viscosity at each temperature (:mod:`.binder`). Columns ``binder_G_mix_MPa`` and
    ``binder_delta_mix_deg`` hold the binder at the mix's own frequency, which the discrete model
    reads (the curve's; the raw values on the raw route). Column ``binder_extrapolated`` (nullable
    bool, both routes): the cell's temperature lies outside those of the points its binder's curve
    was fitted on (:func:`binder_extrapolated`); missing for a binder without a curve on the raw route.

    Raises InputError for an unknown route or a mix whose binder has no curve (curve route)."""
    if route not in BINDER_ROUTES:
        raise InputError(f"binder route {route!r}: expected one of {BINDER_ROUTES}")
    out = table.copy()
    out["binder_G_mix_MPa"], out["binder_delta_mix_deg"] = out["binder_G_MPa"], out["binder_delta_deg"]
    out["binder_extrapolated"] = binder_extrapolated(out, curves, binder_of_mix)
    if route == "raw":
        return out
    from .binder import viscosity_Pa_s

    b = out["mix_id"].map(binder_of_mix)
    for binder, idx in out.groupby(b).groups.items():
        if binder not in curves:
            raise InputError(f"binder {binder}: no master curve (mixes {sorted(set(out.loc[idx, 'mix_id']))})")
        c = curves[binder]
        T = out.loc[idx, "temperature_C"].to_numpy(float)
        fb = out.loc[idx, "binder_frequency_Hz"].to_numpy(float)
        f = out.loc[idx, "frequency_Hz"].to_numpy(float)
        out.loc[idx, "binder_G_MPa"] = c.G_Pa(T, fb) / 1e6
        out.loc[idx, "binder_delta_deg"] = c.delta_deg(T, fb)
        out.loc[idx, "binder_G_mix_MPa"] = c.G_Pa(T, f) / 1e6
        out.loc[idx, "binder_delta_mix_deg"] = c.delta_deg(T, f)
        out.loc[idx, "binder_eta_Pa_s"] = viscosity_Pa_s(c, T)
    return out


def binder_extrapolated(table: pd.DataFrame, curves: dict, binder_of_mix: pd.Series) -> pd.Series:
    """Per row of ``table`` (columns ``mix_id``, ``temperature_C``): True where the master curve of
    the mix's binder is read outside the temperatures of the points it was fitted on (below the
    coldest or above the warmest: :meth:`.binder.BinderCurve.extrapolated`), False inside; <NA>
    for a mix whose binder has no curve in ``curves``, or one that does not record its
    temperatures. Series of pandas' nullable boolean dtype, index of ``table``. A definition by
    temperature, hence the same for every frequency at which the curve is read."""
    flag = pd.Series(pd.NA, index=table.index, dtype="boolean")
    b = table["mix_id"].map(binder_of_mix)
    for binder, idx in table.groupby(b).groups.items():
        if binder in curves and curves[binder].temperatures_used_C:
            flag.loc[idx] = curves[binder].extrapolated(table.loc[idx, "temperature_C"].to_numpy(float))
    return flag


def mix_folds(mixes, k: int | None = None, seed: int = 1) -> list[list[str]]:
    """Held-out mixes of each fold: one mix per fold (``k`` None), or ``k`` folds of a seeded
    shuffle of the mixes (sizes differing by at most one).

    Raises InputError if k is not in 2..n_mixes."""
    mixes = list(dict.fromkeys(str(m) for m in mixes))
    if k is None:
        return [[m] for m in mixes]
    if not 2 <= k <= len(mixes):
        raise InputError(f"forecast folds: k = {k} folds of {len(mixes)} mixes; expected 2..{len(mixes)}")
    order = np.random.default_rng(seed).permutation(len(mixes))
    return [sorted(mixes[i] for i in part) for part in np.array_split(order, k)]


def cross_validate(
    table: pd.DataFrame, models: list, binder_of_mix: pd.Series, folds: list[list[str]], route: str, jobs: int = 1
) -> pd.DataFrame:
    """Held-out predictions of every model for the mixes of every fold.

    Parameters
    ----------
    table : matched table (:mod:`asphalt_nscd.lab.matched`) with the binder columns of ``route``
        (:func:`with_binder_route`); only mixes with measured |E*| and phase take part.
    models : objects with ``model``, ``coefficients``, ``fit(train)`` and ``predict(state, rows)``
        (:class:`Baseline`; the DEM models of :mod:`.dem` have the same two methods).
    binder_of_mix : binder id per mix_id. folds : held-out mixes per fold (:func:`mix_folds`).
    route : label of the binder route, written into the rows.
    jobs : worker processes over the folds (the same numbers for any count: each fold is computed
        alone and the results are gathered in fold order).

    Returns
    -------
    (rows, states)
        rows: DataFrame, columns :data:`ROW_COLUMNS`, one row per held-out cell and model;
        states: one dict per (fold, model): ``fold, model, coefficients, binder_route, state``
        (the fitted coefficients or constants; None for published coefficients).

    The fit of a fold sees the training mixes' rows only: a held-out mix's measured values are
    not in ``train`` (the leak test multiplies them and checks the forecast does not move).
    """
    global _JOB
    _JOB = (table.dropna(subset=["E_norm_MPa", "phase_deg"]), models, binder_of_mix, folds, route)
    if jobs > 1 and len(folds) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(min(jobs, len(folds)), mp_context=mp.get_context("fork")) as pool:
            results = list(pool.map(_one_fold, range(len(folds))))
    else:
        results = [_one_fold(k) for k in range(len(folds))]
    _JOB = None
    frames = [f for fr, _ in results for f in fr]
    states = [st for _, sts in results for st in sts]
    if not frames:
        raise InputError("forecast cross-validation: no mix with measured |E*| and phase to hold out")
    return pd.concat(frames, ignore_index=True)[ROW_COLUMNS], states


#: the arguments of the running :func:`cross_validate` (read by forked workers, not pickled)
_JOB: tuple | None = None


def _one_fold(k: int) -> tuple[list, list]:
    """The rows and states of fold ``k`` of the running :func:`cross_validate`."""
    from threadpoolctl import threadpool_limits

    if _JOB is None:
        raise RuntimeError("_one_fold runs only inside cross_validate")
    measured, models, binder_of_mix, folds, route = _JOB
    held = folds[k]
    train = measured[~measured["mix_id"].isin(held)]
    test = measured[measured["mix_id"].isin(held)]
    frames: list = []
    states: list = []
    if test.empty:
        return frames, states
    seen = set(binder_of_mix.loc[train["mix_id"].unique()])
    with threadpool_limits(1):  # BLAS threads on small least-squares problems only contend (docs/choices.md)
        for model in models:
            state = model.fit(train)
            states.append(
                {
                    "fold": k,
                    "model": model.model,
                    "coefficients": model.coefficients,
                    "binder_route": route,
                    "state": state,
                }
            )
            E, P, source = model.predict(state, test.drop(columns=["E_norm_MPa", "phase_deg"]))
            frames.append(
                pd.DataFrame(
                    {
                        "mix_id": test["mix_id"].to_numpy(),
                        "fold": k,
                        "binder_id": test["mix_id"].map(binder_of_mix).to_numpy(),
                        "binder_seen": test["mix_id"].map(binder_of_mix).isin(seen).to_numpy(),
                        "model": model.model,
                        "coefficients": model.coefficients,
                        "binder_route": route,
                        "temperature_C": test["temperature_C"].to_numpy(),
                        "frequency_Hz": test["frequency_Hz"].to_numpy(),
                        "E_meas_MPa": test["E_norm_MPa"].to_numpy(),
                        "phase_meas_deg": test["phase_deg"].to_numpy(),
                        "E_pred_MPa": E,
                        "phase_pred_deg": P,
                        "phase_source": source,
                        "binder_extrapolated": (
                            test["binder_extrapolated"].to_numpy()
                            if "binder_extrapolated" in test
                            else pd.array([pd.NA] * len(test), dtype="boolean")
                        ),
                    }
                )
            )
    return frames, states


#: columns of :func:`score`
SCORE_COLUMNS = [
    "model",
    "coefficients",
    "binder_route",
    "group",
    "temperature_C",
    "n_mixes",
    "n_cells",
    "abs_logE_pct",
    "abs_logE_ci_low",
    "abs_logE_ci_high",
    "max_abs_logE_pct",
    "bias_logE_pct",
    "bias_logE_ci_low",
    "bias_logE_ci_high",
    "abs_phase_deg",
    "abs_phase_ci_low",
    "abs_phase_ci_high",
    "max_abs_phase_deg",
    "bias_phase_deg",
    "bias_phase_ci_low",
    "bias_phase_ci_high",
    "confidence",
]
GROUPS = ("all", "binder_seen", "binder_unseen", "binder_measured", "binder_extrapolated")


def score(rows: pd.DataFrame, confidence: float = 0.95) -> pd.DataFrame:
    """Held-out errors of :func:`cross_validate`'s rows per (model, coefficients, binder route,
    group, temperature) and overall (``temperature_C`` NaN), with t intervals over mixes
    (module docstring). Cells with a missing prediction are left out and counted by
    ``n_cells``; a group of one mix has no interval (NaN). The groups ``binder_measured`` and
    ``binder_extrapolated`` take the cells whose ``binder_extrapolated`` is known (rows without
    that column have none)."""
    from ..diagnosis.scores import t_interval

    d = rows.assign(
        e=100.0 * np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"]),
        p=rows["phase_pred_deg"] - rows["phase_meas_deg"],
    )
    flag = d["binder_extrapolated"] if "binder_extrapolated" in d else pd.Series(pd.NA, index=d.index, dtype=object)
    known = flag.notna().to_numpy()
    extrapolated = np.zeros(len(d), bool)
    extrapolated[known] = flag[known].astype(bool).to_numpy()
    d = d.assign(_binder_measured=known & ~extrapolated, _binder_extrapolated=known & extrapolated)
    out = []
    for (model, coef, route), g in d.groupby(["model", "coefficients", "binder_route"], sort=False):
        for group in GROUPS:
            if group == "all":
                sel = g
            elif group in ("binder_measured", "binder_extrapolated"):
                sel = g[g[f"_{group}"]]
            else:
                sel = g[g["binder_seen"] == (group == "binder_seen")]
            for T in [np.nan, *sorted(sel["temperature_C"].unique())]:
                cells = sel if np.isnan(T) else sel[sel["temperature_C"] == T]
                if cells.empty:
                    continue
                row = {"model": model, "coefficients": coef, "binder_route": route, "group": group}
                row.update(temperature_C=T, confidence=confidence)
                per_mix = cells.groupby("mix_id").agg(
                    ae=("e", lambda v: np.nanmean(np.abs(v)) if np.isfinite(v).any() else np.nan),
                    be=("e", lambda v: np.nanmean(v) if np.isfinite(v).any() else np.nan),
                    ap=("p", lambda v: np.nanmean(np.abs(v)) if np.isfinite(v).any() else np.nan),
                    bp=("p", lambda v: np.nanmean(v) if np.isfinite(v).any() else np.nan),
                )
                row.update(n_mixes=int(per_mix["ae"].notna().sum()), n_cells=int(np.isfinite(cells["e"]).sum()))
                for col, name, cells_col in (
                    ("ae", "abs_logE", "e"),
                    ("be", "bias_logE", None),
                    ("ap", "abs_phase", "p"),
                    ("bp", "bias_phase", None),
                ):
                    v = per_mix[col].dropna().to_numpy(float)
                    key = f"{name}_pct" if "logE" in name else f"{name}_deg"
                    row[key] = float(v.mean()) if v.size else np.nan
                    lo, hi = t_interval(v, confidence) if v.size >= 2 else (np.nan, np.nan)
                    row[f"{name}_ci_low"], row[f"{name}_ci_high"] = lo, hi
                    if cells_col is not None:
                        a = np.abs(cells[cells_col].to_numpy(float))
                        row[f"max_{key}"] = float(np.nanmax(a)) if np.isfinite(a).any() else np.nan
                out.append(row)
    return pd.DataFrame(out)[SCORE_COLUMNS]


#: columns of :func:`error_split`
SPLIT_COLUMNS = [
    "model",
    "coefficients",
    "binder_route",
    "n_mixes",
    "total_pct",
    "total_ci_low",
    "total_ci_high",
    "without_level_pct",
    "without_level_ci_low",
    "without_level_ci_high",
    "without_temperature_pct",
    "without_temperature_ci_low",
    "without_temperature_ci_high",
    "level_pct",
    "temperature_pct",
    "rest_pct",
    "confidence",
]


def missing_modulus(E_meas, phase_meas_deg, E_pred, phase_pred_deg) -> np.ndarray:
    """What a forecast misses as a complex modulus, relative to the measured one.

    m = 100 (E*_meas - E*_pred) / |E*_meas| per cell, E* = |E*| e^{i phi}: its real part is the storage
    modulus missing (in phase with the strain), its imaginary part the loss modulus missing (in
    quadrature), both in percent of the measured |E*|. Its phase angle says what kind of stiffness is
    missing: an elastic part near 0 deg, a part that behaves like the binder near the binder's phase
    angle. A forecast too stiff at the measured phase angle gives a negative real part. The residual is
    linear, so it weighs a mix forecast too stiff more than one forecast too soft by the same log ratio.

    Parameters
    ----------
    E_meas, E_pred : (n,) |E*| (any one unit). phase_meas_deg, phase_pred_deg : (n,) degrees.

    Returns
    -------
    (n,) complex, percent.
    """
    measured = np.asarray(E_meas, float) * np.exp(1j * np.radians(np.asarray(phase_meas_deg, float)))
    predicted = np.asarray(E_pred, float) * np.exp(1j * np.radians(np.asarray(phase_pred_deg, float)))
    return 100.0 * (measured - predicted) / np.abs(measured)


def error_split(rows: pd.DataFrame, confidence: float = 0.95) -> pd.DataFrame:
    """Each model's held-out |E*| error split by oracle offsets into the mix's level, its
    temperature dependence and the rest.

    With e = 100 ln(E_pred / E_meas) per held-out cell: ``total`` is the mean over mixes of each
    mix's mean |e|; ``without_level`` the same after subtracting each mix's own mean e (an oracle
    that knew every mix's level); ``without_temperature`` after subtracting each (mix, temperature)
    mean e (an oracle that also knew every isotherm's level). The parts are the differences:
    ``level_pct`` = total - without_level, ``temperature_pct`` = without_level -
    without_temperature, ``rest_pct`` = without_temperature (what remains inside an isotherm: its
    frequency dependence). t intervals over mixes at ``confidence``. A model that forecasts each
    mix's level better shrinks ``level_pct``; one that follows each mix's temperature dependence
    better shrinks ``temperature_pct``.
    """
    from ..diagnosis.scores import t_interval

    d = rows.assign(e=100.0 * np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"]))
    d = d[np.isfinite(d["e"])]
    out = []
    for (model, coef, route), g in d.groupby(["model", "coefficients", "binder_route"], sort=False):
        g = g.assign(
            level=g["e"] - g.groupby("mix_id")["e"].transform("mean"),
            temp=g["e"] - g.groupby(["mix_id", "temperature_C"])["e"].transform("mean"),
        )
        row = {"model": model, "coefficients": coef, "binder_route": route, "confidence": confidence}
        per_mix = g.groupby("mix_id")[["e", "level", "temp"]].agg(lambda v: float(np.mean(np.abs(v))))
        row["n_mixes"] = int(len(per_mix))
        for col, name in (("e", "total"), ("level", "without_level"), ("temp", "without_temperature")):
            v = per_mix[col].to_numpy(float)
            row[f"{name}_pct"] = float(v.mean())
            row[f"{name}_ci_low"], row[f"{name}_ci_high"] = (
                t_interval(v, confidence) if v.size >= 2 else (np.nan, np.nan)
            )
        row["level_pct"] = row["total_pct"] - row["without_level_pct"]
        row["temperature_pct"] = row["without_level_pct"] - row["without_temperature_pct"]
        row["rest_pct"] = row["without_temperature_pct"]
        out.append(row)
    return pd.DataFrame(out, columns=SPLIT_COLUMNS)
