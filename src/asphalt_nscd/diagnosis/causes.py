"""Model-form and simulation causes of the error of the paper's Burger's-based simulation.

Model form, tested on the measured data:
``broad_spectrum``
    A Burger's model has one Maxwell and one Kelvin-Voigt time; mixes have a broad spectrum.
    Leave one frequency out (docs/validation.md): the per-isotherm Burger's fits and the
    2S2P1D master curve, refitted without the frequency on the table as given, predict it;
    effect = difference of their held-out phase MREs (points) against the noise floor of the
    replicate means (at least 1 point). Needs >= 3 frequencies per isotherm.
``static_modulus``
    Mixes keep a long-time modulus E00; a Burger's model is a liquid. Extra-sum-of-squares
    F-test of the master curve with E00 free against E00 = 0, named when its nominal p-value is
    below alpha and, given the table's calibration (:mod:`asphalt_nscd.diagnosis.calibration`),
    its calibrated p-value (F against tables of the table's liquid master curve) below the
    static group's level; ``static_modulus_MPa`` with its delta-method standard error.

Simulation causes: deterministic effects with a numerical uncertainty U, against a tolerance
(config ``diagnosis.cause_tolerances``), no p-value:
``network_factor``
    Eqs. 30-33: NF = exp(mean over rows of ln(|E*|_sample / |E*|_macro)) of the harmonic rows,
    U = the largest relative departure of a row from NF; named when |NF - 1| - U > 1 %.
``time_integration``
    phase_error = c (360 f dt) through the origin; effect c x_max at the largest tested f dt,
    U = the largest departure of a row from that law; named when |c x_max| - U > 0.1 deg.

Choices (docs/choices.md, Diagnosis: causes with measured error rates).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..rheology.calibration import burgers_model
from ..rheology.master_curve import MasterCurveFit, fit_master_curve
from ..rheology.metrics import cell_means, mre_pct, same_frequency, same_temperature
from ..rheology.models import fit_generalized_kelvin, log_time_grid
from .effects import f_test, p_phrase


def burgers_predict(params: pd.DataFrame, temperature_C, frequency_Hz) -> np.ndarray:
    """Complex modulus (MPa) of the per-temperature Burger's laws at the given points."""
    T = np.asarray(temperature_C, float)
    f = np.asarray(frequency_Hz, float)
    out = np.full(T.shape, np.nan, dtype=complex)
    for _, row in params.iterrows():
        sel = same_temperature(T, row["temperature_C"])
        out[sel] = burgers_model(row, unit=1.0).complex_modulus(2 * np.pi * f[sel])
    return out


def lofo_predictions(df: pd.DataFrame, shift: str = "wlf", T_ref_C: float | None = None, sigma=None) -> pd.DataFrame:
    """Leave-one-frequency-out predictions of the per-isotherm Burger's fits and of the
    2S2P1D master curve (see the module docstring).

    Parameters
    ----------
    df : DataFrame
        Measured table (replicate rows).
    shift, T_ref_C : shift law and reference temperature of the master curve.
    sigma : (float, float), optional
        Noise of ln|E*| and Phi (deg) weighting the master-curve fit (default: replicate noise).

    Returns
    -------
    DataFrame, one row per held-out cell (temperature_C, frequency_Hz) that both models could
    predict: ``E_norm_MPa, phase_deg`` (replicate means), ``E_burgers_MPa, phase_burgers_deg,
    E_master_MPa, phase_master_deg``. Isotherms left with fewer than 2 frequencies by a fold
    are not predicted in that fold; a fold whose fit fails is skipped.
    """
    from ..io import InputError
    from ..rheology.calibration import fit_table

    cm = cell_means(df)
    rows = []
    for f_k in np.sort(df["frequency_Hz"].unique()):
        train = df[~same_frequency(df["frequency_Hz"], f_k)]
        held = cm[same_frequency(cm["frequency_Hz"], f_k)]
        n_f = train.groupby("temperature_C")["frequency_Hz"].nunique()
        ok_T = [T for T in held["temperature_C"] if n_f.get(T, 0) >= 2]
        if not ok_T or train["temperature_C"].nunique() < 2:
            continue
        try:
            B = fit_table(train[train["temperature_C"].isin(ok_T)])
            M = fit_master_curve(train, shift=shift, T_ref_C=T_ref_C, sigma=sigma)
        except (InputError, ValueError):
            continue
        h = held[held["temperature_C"].isin(ok_T)]
        E_B = burgers_predict(B, h["temperature_C"], h["frequency_Hz"])
        E_M = M.modulus(h["frequency_Hz"].to_numpy(float), h["temperature_C"].to_numpy(float))
        rows.append(
            pd.DataFrame(
                {
                    "temperature_C": h["temperature_C"].to_numpy(float),
                    "frequency_Hz": h["frequency_Hz"].to_numpy(float),
                    "E_norm_MPa": h["E_norm_MPa"].to_numpy(float),
                    "phase_deg": h["phase_deg"].to_numpy(float),
                    "E_burgers_MPa": np.abs(E_B),
                    "phase_burgers_deg": np.degrees(np.angle(E_B)),
                    "E_master_MPa": np.abs(E_M),
                    "phase_master_deg": np.degrees(np.angle(E_M)),
                }
            )
        )
    cols = [
        "temperature_C",
        "frequency_Hz",
        "E_norm_MPa",
        "phase_deg",
        "E_burgers_MPa",
        "phase_burgers_deg",
        "E_master_MPa",
        "phase_master_deg",
    ]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=cols)


def noise_floor(df: pd.DataFrame) -> tuple[float | None, float | None]:
    """Mean relative standard error of the replicate means of |E*| and of Phi, % (None
    without replicates)."""
    g = df.groupby(["temperature_C", "frequency_Hz"])
    n = g.size()
    if n.max() < 2:
        return None, None
    sel = n >= 2
    rE = (g["E_norm_MPa"].std() / g["E_norm_MPa"].mean() / np.sqrt(n))[sel]
    rP = (g["phase_deg"].std() / g["phase_deg"].mean() / np.sqrt(n))[sel]
    return float(100 * rE.mean()), float(100 * rP.mean())


def _prony_units(master: MasterCurveFit, fr_min: float, fr_max: float) -> tuple[int | None, str]:
    """Kelvin-Voigt units a Prony fit (2 per decade) of the master curve keeps over the
    reduced-frequency band, or (None, reason)."""
    wp = 2 * np.pi * np.logspace(np.log10(fr_min), np.log10(fr_max), 80)
    c = master.core()
    scale = np.exp(master.specimen_mean[0])
    try:
        prony = fit_generalized_kelvin(
            wp,
            master.modulus(wp / (2 * np.pi), master.T_ref_C),
            log_time_grid(wp.min(), wp.max(), per_decade=2.0),
            E_inf=c["E00_MPa"] * scale,
            glassy_modulus=(c["E0_MPa"] - c["E00_MPa"]) * scale,
        )
    except ValueError as exc:
        return None, str(exc)
    return prony.n_kelvin, ""


def broad_spectrum(
    measured: pd.DataFrame, master: MasterCurveFit, burgers: pd.DataFrame, corrected: pd.DataFrame | None = None
) -> dict:
    """Report entry of ``broad_spectrum`` (module docstring): held-out (lofo) errors of the
    per-isotherm Burger's fits and of the master curve on the measured table ``measured``.
    In-sample errors and descriptive estimates: ``burgers`` (per-isotherm fits to
    ``measured``) against its replicate means, ``master`` (fitted to ``corrected``, the
    artifact-corrected table, default ``measured``) against the corrected means."""
    cm = cell_means(measured)
    cc = cm if corrected is None else cell_means(corrected)
    c = master.core()
    i_h, i_r = master.names.index("h"), master.names.index("k_over_h")
    k_se = float(np.hypot(master.x[i_r] * master.se[i_h], master.x[i_h] * master.se[i_r]))
    fr_data = cm["frequency_Hz"].to_numpy(float) * 10 ** master.log_shift(cm["temperature_C"].to_numpy(float))
    span = float(np.log10(fr_data.max() / fr_data.min()))
    units, why = _prony_units(master, fr_data.min(), fr_data.max())

    def mre(E, ph, E_ref, ph_ref):
        return mre_pct(E, E_ref), mre_pct(ph, ph_ref)

    E_B = burgers_predict(burgers, cm["temperature_C"], cm["frequency_Hz"])
    E_M = master.modulus(cc["frequency_Hz"].to_numpy(float), cc["temperature_C"].to_numpy(float))
    okB = np.isfinite(E_B)
    inB = mre(np.abs(E_B[okB]), np.degrees(np.angle(E_B[okB])), cm["E_norm_MPa"][okB], cm["phase_deg"][okB])
    inM = mre(np.abs(E_M), np.degrees(np.angle(E_M)), cc["E_norm_MPa"], cc["phase_deg"])
    est = {
        "k": c["k"],
        "k_se": k_se,
        "h": c["h"],
        "h_se": float(master.se[i_h]),
        "reduced_frequency_span_decades": span,
        "kelvin_units_needed": units,
        "burgers_mre_E_norm_pct_in_sample": inB[0],
        "burgers_mre_phase_pct_in_sample": inB[1],
        "master_curve_mre_E_norm_pct_in_sample": inM[0],
        "master_curve_mre_phase_pct_in_sample": inM[1],
    }
    if units is None:
        est["kelvin_units_reason"] = why
    entry = {"name": "broad_spectrum", "category": "model_form", "estimate": est, "p_value": None}
    pred = lofo_predictions(
        measured, shift=master.shift, T_ref_C=master.T_ref_C, sigma=(master.sigma_lnE, master.sigma_phase_deg)
    )
    if len(pred) == 0:
        return {
            **entry,
            "detected": False,
            "testable": False,
            "score": 0.0,
            "evidence": "not testable: no fold of the leave-one-frequency-out comparison keeps 2 "
            "frequencies at an isotherm (needs >= 3 tested frequencies per isotherm)",
        }
    hoB = mre(pred["E_burgers_MPa"], pred["phase_burgers_deg"], pred["E_norm_MPa"], pred["phase_deg"])
    hoM = mre(pred["E_master_MPa"], pred["phase_master_deg"], pred["E_norm_MPa"], pred["phase_deg"])
    fE, fP = noise_floor(measured)
    floor = (max(fE if fE is not None else 0.0, 1.0), max(fP if fP is not None else 0.0, 1.0))
    dE, dP = hoB[0] - hoM[0], hoB[1] - hoM[1]
    est.update(
        {
            "burgers_mre_E_norm_pct_held_out": hoB[0],
            "burgers_mre_phase_pct_held_out": hoB[1],
            "master_curve_mre_E_norm_pct_held_out": hoM[0],
            "master_curve_mre_phase_pct_held_out": hoM[1],
            "held_out_difference_E_norm_points": dE,
            "held_out_difference_phase_points": dP,
            "noise_floor_E_norm_pct": fE,
            "noise_floor_phase_pct": fP,
            "threshold_E_norm_points": floor[0],
            "threshold_phase_points": floor[1],
            "n_held_out_cells": int(len(pred)),
            "folds": "leave one frequency out",
        }
    )
    detected = dP > floor[1] or dE > floor[0]
    kv = f"{units} Kelvin-Voigt units" if units is not None else f"an unknown number of Kelvin-Voigt units ({why})"
    return {
        **entry,
        "detected": bool(detected),
        "testable": True,
        "score": max(dP, 0.0) + max(dE, 0.0),
        "evidence": (
            f"held-out (leave one frequency out, {len(pred)} cells) MRE of Phi: per-isotherm Burger's "
            f"{hoB[1]:.1f} %, 2S2P1D master curve {hoM[1]:.1f} % (difference {dP:+.1f} points; |E*|: "
            f"{hoB[0]:.1f} % vs {hoM[0]:.1f} %, {dE:+.1f} points), threshold {floor[1]:.1f} / "
            f"{floor[0]:.1f} points (noise floor of the replicate means, at least 1). In-sample: Burger's "
            f"{inB[1]:.1f} %, master curve {inM[1]:.1f} %. Over the {span:.1f} decades of reduced "
            f"frequency of the data the master curve needs {kv} (a Burger's model has 1); power-law "
            f"exponents k = {c['k']:.3f}, h = {c['h']:.3f}"
        ),
    }


def static_modulus(
    corrected: pd.DataFrame, master: MasterCurveFit, alpha: float, calibration: dict | None = None
) -> dict:
    """Report entry of ``static_modulus`` (see the module docstring)."""
    from .calibration import static_p

    liquid = fit_master_curve(
        corrected,
        shift=master.shift,
        T_ref_C=master.T_ref_C,
        static_modulus=False,
        sigma=(master.sigma_lnE, master.sigma_phase_deg),
    )
    F, p = f_test(liquid.rss, master.rss, 1, master.n_residuals - master.n_params)
    i = master.names.index("log10_E00_MPa")
    E00 = 10 ** master.x[i]
    se = float(E00 * np.log(10) * master.se[i])
    aT = 10 ** master.log_shift(corrected["temperature_C"].to_numpy(float))
    fr_data = corrected["frequency_Hz"].to_numpy(float) * aT
    fr = np.logspace(np.log10(fr_data.min()) - 4, np.log10(fr_data.max()) + 1, 600)
    ph = np.degrees(np.angle(master.modulus(fr, master.T_ref_C)))
    f_peak = float(fr[np.argmax(ph)])
    inside = bool(fr_data.min() <= f_peak <= fr_data.max())
    est = {
        "static_modulus_MPa": float(E00),
        "static_modulus_MPa_se": se,
        "phase_peak_deg": float(ph.max()),
        "phase_peak_reduced_frequency_Hz": f_peak,
        "phase_peak_in_data": inside,
        "T_ref_C": master.T_ref_C,
    }
    p_cal = static_p(F, calibration)
    level = None if calibration is None else float(calibration["static"]["level"])
    calibrated, cal_text = True, ""
    if p_cal is not None:
        assert calibration is not None and level is not None  # static_p gives a p only with a calibration
        calibrated = p_cal < level
        cal_text = (
            f" (calibrated on {len(calibration['static']['null_F'])} tables of the table's liquid master "
            f"curve: p = {p_cal:.2g}, level {level:g})"
        )
    significant = np.isfinite(p) and p < alpha and E00 > 2 * se and calibrated
    cm = cell_means(corrected)
    ph_s = np.angle(master.modulus(cm["frequency_Hz"], cm["temperature_C"]))
    ph_l = np.angle(liquid.modulus(cm["frequency_Hz"], cm["temperature_C"]))
    score = float(100 * np.mean(np.abs(ph_l / ph_s - 1)))
    return {
        "name": "static_modulus",
        "category": "model_form",
        "detected": bool(significant),
        "testable": True,
        "identifiable": True,
        "score": score,
        "p_value": None if not np.isfinite(p) else float(p),
        "p_calibrated": p_cal,
        "estimate": est,
        "evidence": (
            f"a master curve with a long-time modulus E00 = {E00:.0f} +- {se:.0f} MPa fits "
            f"better than a liquid one (E00 = 0): F = {F:.3g}, {p_phrase(p)}{cal_text}. Phi peaks at "
            f"{ph.max():.1f} deg at reduced frequency {f_peak:.3g} Hz ({master.T_ref_C:g} degC), "
            f"{'inside' if inside else 'outside'} the tested range; a Burger's model "
            f"(E_inf = 0) tends to 90 deg at low frequency"
        ),
    }


#: Default tolerances of the deterministic simulation causes: relative departure of the
#: network factor from 1, and phase error of the time stepping (deg) (config
#: ``diagnosis.cause_tolerances``).
TOLERANCES = {"network_factor": 0.01, "time_integration_deg": 0.1}


def network_factor(
    sample: pd.DataFrame | None,
    burgers: pd.DataFrame,
    source: str = "",
    tolerance: float = TOLERANCES["network_factor"],
) -> dict:
    """Report entry of ``network_factor``: sample (harmonic) response vs its macro law, an
    effect with its numerical uncertainty against ``tolerance`` (module docstring)."""
    entry: dict[str, Any] = {"name": "network_factor", "category": "simulation", "estimate": {}, "p_value": None}
    if sample is None or len(sample) < 1:
        return {
            **entry,
            "detected": False,
            "testable": False,
            "score": 0.0,
            "evidence": "not testable: needs the harmonic (or simulated) response of the numerical "
            "sample (--harmonic or --simulated table)",
        }
    E_macro = burgers_predict(burgers, sample["temperature_C"], sample["frequency_Hz"])
    ok = np.isfinite(E_macro)
    if not ok.any():
        return {
            **entry,
            "detected": False,
            "testable": False,
            "score": 0.0,
            "evidence": "not testable: the sample table shares no temperature with the macro fits",
        }
    r = np.log(sample["E_norm_MPa"].to_numpy(float)[ok] / np.abs(E_macro[ok]))
    d = sample["phase_deg"].to_numpy(float)[ok] - np.degrees(np.angle(E_macro[ok]))
    factor = float(np.exp(r.mean()))
    rows = np.exp(r)
    U = float(np.max(np.abs(rows / factor - 1)))
    margin = abs(factor - 1) - U
    est = {
        "network_factor": factor,
        "network_factor_uncertainty": U * factor,
        "network_factor_min": float(rows.min()),
        "network_factor_max": float(rows.max()),
        "phase_difference_deg": float(d.mean()),
        "phase_difference_deg_min": float(d.min()),
        "phase_difference_deg_max": float(d.max()),
        "tolerance": tolerance,
        "n_rows": int(r.size),
    }
    detected = margin > tolerance
    return {
        **entry,
        "estimate": est,
        "detected": bool(detected),
        "testable": True,
        "score": float(100 * np.mean(np.abs(r)) + 100 * np.mean(np.abs(d) / np.abs(np.degrees(np.angle(E_macro[ok]))))),
        "evidence": (
            f"{source} |E*| of the sample / macro Burger's law = {factor:.4f} +- {U * factor:.4f} "
            f"(effect {100 * (factor - 1):+.2f} %, numerical uncertainty {100 * U:.2f} % = largest "
            f"departure of one of the {r.size} rows, range {rows.min():.4f}-{rows.max():.4f}; tolerance "
            f"{100 * tolerance:.2g} %: {'exceeded' if detected else 'not exceeded'}); phase difference "
            f"{d.mean():+.2f} deg (range {d.min():+.2f} to {d.max():+.2f})"
        ),
    }


def time_integration(errors: pd.DataFrame | None, tolerance_deg: float = TOLERANCES["time_integration_deg"]) -> dict:
    """Report entry of ``time_integration`` from a table ``frequency_Hz, dt_s, phase_error_deg``:
    an effect with its numerical uncertainty against ``tolerance_deg`` (module docstring)."""
    entry: dict[str, Any] = {"name": "time_integration", "category": "simulation", "estimate": {}, "p_value": None}
    need = {"frequency_Hz", "dt_s", "phase_error_deg"}
    if errors is None or not need <= set(errors.columns) or len(errors) < 1:
        return {
            **entry,
            "detected": False,
            "testable": False,
            "score": 0.0,
            "evidence": "not testable: needs a time-integration phase-error table (frequency_Hz, dt_s, "
            "phase_error_deg; --time-integration) or NSCD and harmonic rows with dt_s",
        }
    x = 360.0 * errors["frequency_Hz"].to_numpy(float) * errors["dt_s"].to_numpy(float)
    y = errors["phase_error_deg"].to_numpy(float)
    c = float(np.sum(x * y) / np.sum(x * x))
    U = float(np.max(np.abs(y - c * x)))
    worst = float(c * x.max())
    detected = abs(worst) - U > tolerance_deg
    return {
        **entry,
        "detected": bool(detected),
        "testable": True,
        "score": abs(worst),
        "estimate": {
            "phase_error_per_phase_step": c,
            "phase_error_deg_at_max_f_dt": worst,
            "uncertainty_deg": U,
            "tolerance_deg": tolerance_deg,
            "n_rows": int(y.size),
        },
        "evidence": (
            f"phase error of the time stepping = {c:.3g} x (360 f dt) deg: {worst:+.3f} deg at the "
            f"largest f dt tested, +- {U:.3f} deg (largest departure of one of the {y.size} rows "
            f"from the proportional law); tolerance {tolerance_deg:g} deg: "
            f"{'exceeded' if detected else 'not exceeded'}"
        ),
    }
