"""Model-form and simulation causes of the error of the paper's Burger's-based simulation.

Model form (tested on the artifact-corrected data)
--------------------------------------------------
``broad_spectrum``
    A Burger's model has one Maxwell and one Kelvin-Voigt time; mixes have a broad, power-law
    spectrum. Test: variance-ratio F-test of the per-isotherm Burger's fits (4 parameters per
    isotherm) against the 2S2P1D/WLF master curve (about 9 parameters for the whole table),
    both on the cell means weighted by the replicate noise: F = (chi2_B/dof_B)/(chi2_M/dof_M).
    Estimate: the exponents k, h of the 2S2P1D parabolic elements, the decades of reduced
    frequency spanned by the data and the number of Kelvin-Voigt units a Prony fit (2 per
    decade) of the master curve keeps over that span.
``static_modulus``
    Mixes keep a long-time modulus E00 (aggregate skeleton), so Phi peaks and falls; a
    Burger's model is a liquid. Test: extra-sum-of-squares F-test of the master curve with E00
    free against E00 = 0. Estimate: ``static_modulus_MPa`` (Jacobian s.e. by the delta method).

Simulation (tested when their inputs exist)
-------------------------------------------
``network_factor``
    Micro-macro transfer of Eqs. 30-33: the harmonic response of the sample against the macro
    law it was given. Test: one-sample t-test of ln(|E*|_sample / |E*|_macro) over the rows.
    Estimate: ``network_factor`` = exp(mean) and the mean phase difference.
``time_integration``
    Phase error of the time stepping. From a table ``frequency_Hz, dt_s, phase_error_deg``
    (or NSCD minus harmonic rows with ``dt_s``): least squares
    phase_error = c (360 f dt) through the origin, t-test of c. Estimate:
    ``phase_error_per_phase_step`` c (deg of error per deg of w dt) and the error at the
    largest tested f dt.

Choice: practical thresholds join the statistical ones so that a significant but negligible
effect (below 1 % of |E*| or 0.1 deg of Phi) is not named a cause.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from ..rheology.laws import GeneralizedBurgers
from ..rheology.master_curve import MasterCurveFit, fit_master_curve
from ..rheology.models import fit_generalized_kelvin, log_time_grid
from .effects import f_test


def cell_means(df: pd.DataFrame) -> pd.DataFrame:
    """Replicate means per (temperature_C, frequency_Hz): ``n, E_norm_MPa, phase_deg, lnE``."""
    d = df.assign(lnE=np.log(df["E_norm_MPa"]))
    return (d.groupby(["temperature_C", "frequency_Hz"], as_index=False)
            .agg(n=("E_norm_MPa", "size"), E_norm_MPa=("E_norm_MPa", "mean"),
                 phase_deg=("phase_deg", "mean"), lnE=("lnE", "mean")))


def burgers_table(df: pd.DataFrame) -> pd.DataFrame:
    """Per-temperature Burger's fits (``rheology.calibration.fit_table``), MPa and MPa s."""
    from ..rheology.calibration import fit_table

    return fit_table(df)


def burgers_law(row) -> GeneralizedBurgers:
    """Burger's law (MPa, MPa s) of one row of :func:`burgers_table`."""
    return GeneralizedBurgers.burgers(row["Em_MPa"], row["eta_m_MPa_s"], row["Ek_MPa"], row["eta_k_MPa_s"])


def burgers_predict(params: pd.DataFrame, temperature_C, frequency_Hz) -> np.ndarray:
    """Complex modulus (MPa) of the per-temperature Burger's laws at the given points."""
    T = np.asarray(temperature_C, float)
    f = np.asarray(frequency_Hz, float)
    out = np.full(T.shape, np.nan, dtype=complex)
    for _, row in params.iterrows():
        sel = np.isclose(T, row["temperature_C"])
        out[sel] = burgers_law(row).complex_modulus(2 * np.pi * f[sel])
    return out


def broad_spectrum(corrected: pd.DataFrame, master: MasterCurveFit, burgers: pd.DataFrame,
                   alpha: float) -> dict:
    """Report entry of ``broad_spectrum`` (see the module docstring)."""
    cm = cell_means(corrected)
    sE, sP = master.sigma_lnE, master.sigma_phase_deg
    w = np.sqrt(cm["n"].to_numpy(float))

    def chi2(E):
        rE = (np.log(np.abs(E)) - cm["lnE"].to_numpy()) / sE * w
        rP = (np.degrees(np.angle(E)) - cm["phase_deg"].to_numpy()) / sP * w
        return float(np.sum(rE**2 + rP**2))

    E_B = burgers_predict(burgers, cm["temperature_C"], cm["frequency_Hz"])
    E_M = master.modulus(cm["frequency_Hz"], cm["temperature_C"])
    n_T = cm["temperature_C"].nunique()
    n_core = sum(1 for n in master.names if not n.startswith(("ln_factor_", "phase_offset_deg_")))
    dof_B = 2 * len(cm) - 4 * n_T
    dof_M = 2 * len(cm) - n_core
    c = master.core()
    i_h, i_r = master.names.index("h"), master.names.index("k_over_h")
    k_se = float(np.hypot(master.x[i_r] * master.se[i_h], master.x[i_h] * master.se[i_r]))
    # breadth of the spectrum: decades of reduced frequency covered by the data, and the
    # number of Kelvin-Voigt units a Prony fit (2 per decade) of the master curve keeps there
    fr_data = cm["frequency_Hz"].to_numpy(float) * 10 ** master.log_shift(cm["temperature_C"].to_numpy(float))
    span = float(np.log10(fr_data.max() / fr_data.min()))
    wp = 2 * np.pi * np.logspace(np.log10(fr_data.min()), np.log10(fr_data.max()), 80)
    E00 = master.core()["E00_MPa"] * np.exp(master.specimen_mean[0])
    prony = fit_generalized_kelvin(wp, master.modulus(wp / (2 * np.pi), master.T_ref_C),
                                   log_time_grid(wp.min(), wp.max(), per_decade=2.0), E_inf=E00)
    mre = lambda E: float(100 * np.mean(np.abs(np.degrees(np.angle(E)) / cm["phase_deg"] - 1)))
    est = {"k": c["k"], "k_se": k_se, "h": c["h"], "h_se": float(master.se[i_h]),
           "reduced_frequency_span_decades": span, "kelvin_units_needed": prony.n_kelvin,
           "burgers_mre_phase_pct": mre(E_B), "master_curve_mre_phase_pct": mre(E_M)}
    entry = {"name": "broad_spectrum", "category": "model_form", "estimate": est}
    if dof_B <= 0 or dof_M <= 0:
        return {**entry, "detected": False, "testable": False, "score": 0.0, "p_value": None,
                "evidence": "not testable: too few frequencies per isotherm for a Burger's lack-of-fit test"}
    F = (chi2(E_B) / dof_B) / (chi2(E_M) / dof_M)
    p = float(stats.f.sf(F, dof_B, dof_M))
    detected = p < alpha and est["burgers_mre_phase_pct"] > est["master_curve_mre_phase_pct"]
    return {**entry, "detected": bool(detected), "testable": True,
            "score": max(est["burgers_mre_phase_pct"] - est["master_curve_mre_phase_pct"], 0.0),
            "p_value": p,
            "evidence": (f"per-isotherm Burger's fits leave {F:.3g} times the residual variance of one "
                         f"2S2P1D/WLF master curve (F({dof_B},{dof_M}), p = {p:.2g}); phase MRE "
                         f"{est['burgers_mre_phase_pct']:.1f} % vs {est['master_curve_mre_phase_pct']:.1f} %. "
                         f"Over the {span:.1f} decades of reduced frequency of the data the master curve needs "
                         f"{prony.n_kelvin} Kelvin-Voigt units (a Burger's model has 1); power-law "
                         f"exponents k = {c['k']:.3f}, h = {c['h']:.3f}")}


def static_modulus(corrected: pd.DataFrame, master: MasterCurveFit, alpha: float) -> dict:
    """Report entry of ``static_modulus`` (see the module docstring)."""
    liquid = fit_master_curve(corrected, shift=master.shift, T_ref_C=master.T_ref_C, static_modulus=False,
                              sigma=(master.sigma_lnE, master.sigma_phase_deg))
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
    est = {"static_modulus_MPa": float(E00), "static_modulus_MPa_se": se,
           "phase_peak_deg": float(ph.max()), "phase_peak_reduced_frequency_Hz": f_peak,
           "phase_peak_in_data": inside, "T_ref_C": master.T_ref_C}
    significant = np.isfinite(p) and p < alpha and E00 > 2 * se
    cm = cell_means(corrected)
    ph_s = np.angle(master.modulus(cm["frequency_Hz"], cm["temperature_C"]))
    ph_l = np.angle(liquid.modulus(cm["frequency_Hz"], cm["temperature_C"]))
    score = float(100 * np.mean(np.abs(ph_l / ph_s - 1)))
    return {"name": "static_modulus", "category": "model_form", "detected": bool(significant),
            "testable": True, "score": score, "p_value": None if not np.isfinite(p) else float(p),
            "estimate": est,
            "evidence": (f"a master curve with a long-time modulus E00 = {E00:.0f} +- {se:.0f} MPa fits "
                         f"better than a liquid one (E00 = 0): F = {F:.3g}, p = {p:.2g}. Phi peaks at "
                         f"{ph.max():.1f} deg at reduced frequency {f_peak:.3g} Hz ({master.T_ref_C:g} degC), "
                         f"{'inside' if inside else 'outside'} the tested range; a Burger's model "
                         f"(E_inf = 0) tends to 90 deg at low frequency")}


def network_factor(sample: pd.DataFrame | None, burgers: pd.DataFrame, alpha: float,
                   source: str = "") -> dict:
    """Report entry of ``network_factor``: sample (harmonic) response vs its macro law."""
    entry = {"name": "network_factor", "category": "simulation", "estimate": {}}
    if sample is None or len(sample) < 2:
        return {**entry, "detected": False, "testable": False, "score": 0.0, "p_value": None,
                "evidence": "not testable: needs the harmonic (or simulated) response of the numerical "
                            "sample (--harmonic or --simulated table with >= 2 rows)"}
    E_macro = burgers_predict(burgers, sample["temperature_C"], sample["frequency_Hz"])
    ok = np.isfinite(E_macro)
    r = np.log(sample["E_norm_MPa"].to_numpy(float)[ok] / np.abs(E_macro[ok]))
    d = sample["phase_deg"].to_numpy(float)[ok] - np.degrees(np.angle(E_macro[ok]))
    if r.size < 2:
        return {**entry, "detected": False, "testable": False, "score": 0.0, "p_value": None,
                "evidence": "not testable: the sample table shares no temperature with the macro fits"}
    sd = float(r.std(ddof=1))
    if sd > 1e-12 * max(abs(r.mean()), 1e-300):
        p = float(2 * stats.t.sf(abs(r.mean()) / (sd / np.sqrt(r.size)), r.size - 1))
    else:  # identical ratios: exact (no scatter)
        p = 0.0 if abs(r.mean()) > 0 else 1.0
    factor = float(np.exp(r.mean()))
    se = float(factor * r.std(ddof=1) / np.sqrt(r.size))
    est = {"network_factor": factor, "network_factor_se": se,
           "phase_difference_deg": float(d.mean()),
           "phase_difference_deg_se": float(d.std(ddof=1) / np.sqrt(d.size))}
    detected = p < alpha and abs(factor - 1) > 0.01
    return {**entry, "estimate": est, "detected": bool(detected), "testable": True,
            "score": float(100 * np.mean(np.abs(r)) + 100 * np.mean(np.abs(d) / np.abs(np.degrees(np.angle(E_macro[ok]))))),
            "p_value": p,
            "evidence": (f"{source} |E*| of the sample / macro Burger's law = {factor:.3f} +- {se:.3f} over "
                         f"{r.size} points (t-test p = {p:.2g}); mean phase difference {d.mean():+.2f} deg")}


def time_integration(errors: pd.DataFrame | None, alpha: float) -> dict:
    """Report entry of ``time_integration`` from a table ``frequency_Hz, dt_s, phase_error_deg``."""
    entry = {"name": "time_integration", "category": "simulation", "estimate": {}}
    need = {"frequency_Hz", "dt_s", "phase_error_deg"}
    if errors is None or not need <= set(errors.columns) or len(errors) < 2:
        return {**entry, "detected": False, "testable": False, "score": 0.0, "p_value": None,
                "evidence": "not testable: needs a time-integration phase-error table (frequency_Hz, dt_s, "
                            "phase_error_deg; --time-integration) or NSCD and harmonic rows with dt_s"}
    x = 360.0 * errors["frequency_Hz"].to_numpy(float) * errors["dt_s"].to_numpy(float)
    y = errors["phase_error_deg"].to_numpy(float)
    c = float(np.sum(x * y) / np.sum(x * x))
    res = y - c * x
    se = float(np.sqrt(np.sum(res**2) / max(y.size - 1, 1) / np.sum(x * x)))
    tstat = c / se if se > 0 else np.inf
    p = float(2 * stats.t.sf(abs(tstat), max(y.size - 1, 1)))
    worst = float(c * x.max())
    detected = p < alpha and abs(worst) > 0.1
    return {**entry, "detected": bool(detected), "testable": True, "score": abs(worst),
            "p_value": p,
            "estimate": {"phase_error_per_phase_step": c, "phase_error_per_phase_step_se": se,
                         "phase_error_deg_at_max_f_dt": worst},
            "evidence": (f"phase error of the time stepping = {c:.3g} +- {se:.2g} x (360 f dt) deg "
                         f"(t-test p = {p:.2g}), {worst:+.2f} deg at the largest f dt tested")}
