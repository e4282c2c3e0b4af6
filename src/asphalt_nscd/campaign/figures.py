"""Figures of the numerical 2PB test and campaign (analogues of the paper's Figs. 6-14).

* :func:`dt_study_figure` — Fig. 6: force over the last cycle and |E*|, Phi versus dt.
* :func:`last_cycle_figure` — Fig. 7: head displacement and force over the last cycle.
* :func:`velocity_profile_figure` — Fig. 8: mean particle velocity (x) versus height.
* :func:`isotherm_figures` — Figs. 9-10: numerical versus reference isotherms (shared
  :mod:`asphalt_nscd.rheology.plots`).
* :func:`sensitivity_figure` — Figs. 11-14: one Burger's parameter at x0.5, x1, x1.5.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _last_cycle(rec: dict):
    f = float(rec["attrs"]["frequency_Hz"])
    t = rec["time_s"]
    m = t >= t[-1] - 1.0 / f
    return t[m] - t[m][0], rec["displacement_m"][m], rec["force_N"][m]


def dt_study_figure(records: list[dict], rows: pd.DataFrame, reference: tuple[float, float] | None = None):
    """Fig. 6 analogue. ``records``: test records at several dt (same T, f); ``rows``: their
    reduced rows (dt_s, E_norm_MPa, phase_deg, sample); ``reference``: Burger's (|E*| MPa,
    Phi deg) at the same (T, f)."""
    plt = _plt()
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for rec in sorted(records, key=lambda r: r["attrs"]["dt_s"]):
        t, _, F = _last_cycle(rec)
        axes[0].plot(t * 1e3, F, label=f"dt = {rec['attrs']['dt_s']:.0e} s")
    axes[0].set_xlabel("time in the last cycle (ms)")
    axes[0].set_ylabel("head force (N)")
    axes[0].legend(fontsize=8)
    g = (
        rows.groupby("dt_s")
        .agg(E=("E_norm_MPa", "mean"), Es=("E_norm_MPa", "std"), P=("phase_deg", "mean"), Ps=("phase_deg", "std"))
        .reset_index()
        .fillna(0.0)
    )
    axes[1].errorbar(g["dt_s"], g["E"], yerr=g["Es"], marker="o", capsize=3, label="NSCD")
    axes[2].errorbar(g["dt_s"], g["P"], yerr=g["Ps"], marker="o", capsize=3, label="NSCD")
    if reference is not None:
        axes[1].axhline(reference[0], color="k", ls="--", label="Burger's (Table 3)")
        axes[2].axhline(reference[1], color="k", ls="--", label="Burger's (Table 3)")
    axes[1].set_yscale("log")
    for ax, lab in ((axes[1], "|E*| (MPa)"), (axes[2], "phase angle Φ (°)")):
        ax.set_xscale("log")
        ax.set_xlabel("time step dt (s)")
        ax.set_ylabel(lab)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    T = rows["temperature_C"].iloc[0]
    f = rows["frequency_Hz"].iloc[0]
    fig.suptitle(f"Time-step influence, {T:g} °C, {f:g} Hz", fontsize=10)
    fig.tight_layout()
    return fig


def last_cycle_figure(rec: dict):
    """Fig. 7 analogue: imposed head displacement and head force over the last cycle."""
    plt = _plt()
    t, x, F = _last_cycle(rec)
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(t * 1e3, x * 1e6, color="tab:blue", label="displacement")
    ax.set_xlabel("time in the last cycle (ms)")
    ax.set_ylabel("head displacement (µm)", color="tab:blue")
    ax2 = ax.twinx()
    ax2.plot(t * 1e3, F, color="tab:red", label="force")
    ax2.set_ylabel("head force (N)", color="tab:red")
    a = rec["attrs"]
    ax.set_title(
        f"{a.get('sample', '')} {a.get('temperature_C', float('nan')):g} °C, "
        f"{a['frequency_Hz']:g} Hz, dt = {a['dt_s']:.2g} s",
        fontsize=10,
    )
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def velocity_profile_figure(rec: dict):
    """Fig. 8 analogue: mean particle velocity along x per height bin at instants of the last
    cycle, normalised by the head velocity amplitude A w."""
    plt = _plt()
    p = rec["profile"]
    a = rec["attrs"]
    vmax = a["amplitude_m"] * 2 * np.pi * a["frequency_Hz"]
    z = p["z_m"]
    t0 = p["time_s"][0] - (p["time_s"][1] - p["time_s"][0]) if len(p["time_s"]) > 1 else 0.0
    fig, ax = plt.subplots(figsize=(5.0, 5.0))
    cmap = plt.get_cmap("viridis")
    n = len(p["time_s"])
    for k in range(n):
        phase = 360.0 * ((p["time_s"][k] - t0) * a["frequency_Hz"])
        ax.plot(
            p["vx_m_s"][k] / vmax,
            z * 1e3,
            marker="o",
            ms=3,
            color=cmap(k / max(n - 1, 1)),
            label=f"{phase:.0f}° of the cycle",
        )
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlabel("mean particle velocity v_x / (A ω)")
    ax.set_ylabel("height z (mm)")
    ax.set_title(f"{a.get('temperature_C', float('nan')):g} °C, {a['frequency_Hz']:g} Hz", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


def isotherm_figures(
    isotherms: pd.DataFrame,
    curves: pd.DataFrame | None,
    reference_label: str,
    reference_points: pd.DataFrame | None = None,
    title: str = "",
    curve_label: str = "Burger's model",
):
    """Figs. 9-10 analogues: |E*| and Phi isotherms, NSCD sample means (± sd over samples)
    against reference curves (legend ``curve_label``, e.g. "generalized Burger's law") and/or
    points (legend ``reference_label``). Returns (fig_modulus, fig_phase)."""
    from ..rheology.plots import CurveSet, rheology_figure

    sets = [
        CurveSet(
            "NSCD (mean ± sd over samples)",
            isotherms[
                [
                    "temperature_C",
                    "frequency_Hz",
                    "E_norm_MPa_mean",
                    "E_norm_MPa_std",
                    "phase_deg_mean",
                    "phase_deg_std",
                ]
            ],
            kind="points",
        )
    ]
    if reference_points is not None:
        sets.append(CurveSet(reference_label, reference_points, kind="points", marker="x"))
    if curves is not None:
        sets.append(CurveSet(curve_label, curves, kind="line"))
    return (
        rheology_figure(sets, "isotherms-modulus", title=title),
        rheology_figure(sets, "isotherms-phase", title=title),
    )


def sensitivity_figure(table: pd.DataFrame, parameter: str, curves: dict | None = None, temperature_C=20.0):
    """Figs. 11-14 analogue for one parameter: |E*| and Phi versus frequency for each factor
    (NSCD points, mean ± sd), with the Burger's curves of each factor (``curves``:
    {factor: DataFrame frequency_Hz, E_norm_MPa, phase_deg})."""
    plt = _plt()
    sub = table[table["parameter"] == parameter].sort_values(["factor", "frequency_Hz"])
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    cmap = plt.get_cmap("plasma")
    factors = sorted(sub["factor"].unique())
    for n, fac in enumerate(factors):
        c = cmap(0.85 * n / max(len(factors) - 1, 1))
        g = sub[sub["factor"] == fac]
        lab = f"{parameter} × {fac:g}"
        axes[0].errorbar(
            g["frequency_Hz"],
            g["E_norm_MPa_mean"],
            yerr=g["E_norm_MPa_std"],
            marker="o",
            ls="none",
            color=c,
            capsize=3,
            label=f"NSCD {lab}",
        )
        axes[1].errorbar(
            g["frequency_Hz"],
            g["phase_deg_mean"],
            yerr=g["phase_deg_std"],
            marker="o",
            ls="none",
            color=c,
            capsize=3,
            label=f"NSCD {lab}",
        )
        if curves and fac in curves:
            cv = curves[fac]
            axes[0].plot(cv["frequency_Hz"], cv["E_norm_MPa"], color=c, ls="--", label=f"Burger's {lab}")
            axes[1].plot(cv["frequency_Hz"], cv["phase_deg"], color=c, ls="--")
    axes[0].set_yscale("log")
    axes[0].set_ylabel("|E*| (MPa)")
    axes[1].set_ylabel("phase angle Φ (°)")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("frequency (Hz)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"Sensitivity to {parameter} at {temperature_C:g} °C (paper mode)", fontsize=10)
    fig.tight_layout()
    return fig
