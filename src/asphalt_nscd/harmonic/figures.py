"""Figures of the harmonic solver's studies: the time-domain comparison
(:func:`.analysis.compare_time_domain`), the sensitivity study (:func:`.analysis.sensitivity_table`)
and the resolution study (:mod:`.resolution`)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .analysis import PARAM_COLUMNS


def plot_compare(frame: pd.DataFrame):
    """Figure: |d|E*|| (%) and |dPhi| (deg) vs dt per (T, f), and vs rtol (harmonic).

    Solid: head force read as bond reaction + exact head inertia; dashed (x): the NSCD core's
    ``driver_force`` reading (see :mod:`.timedomain`).
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(9, 6.5))
    td = frame[frame["kind"] == "time-domain"]
    hr = frame[frame["kind"] == "harmonic-rtol"]
    for (T, f), g in td.groupby(["temperature_C", "frequency_Hz"]):
        g = g.sort_values("dt_s")
        label = f"{T:g} °C, {f:g} Hz"
        (line,) = axes[0, 0].loglog(g["dt_s"], g["dE_norm_percent"].abs().clip(lower=1e-8), "o-", label=label)
        axes[1, 0].loglog(g["dt_s"], g["dphase_deg"].abs().clip(lower=1e-8), "o-", label=label)
        if "dE_norm_percent_other_reading" in g.columns:  # the core's driver_force reading
            for ax, col in ((axes[0, 0], "dE_norm_percent_other_reading"), (axes[1, 0], "dphase_deg_other_reading")):
                ax.loglog(g["dt_s"], g[col].abs().clip(lower=1e-8), "x--", color=line.get_color(), alpha=0.6)
    for (T, f), g in hr.groupby(["temperature_C", "frequency_Hz"]):
        g = g.sort_values("rtol")
        axes[0, 1].loglog(g["rtol"], g["dE_norm_percent"].abs().clip(lower=1e-14), "s-")
        axes[1, 1].loglog(g["rtol"], g["dphase_deg"].abs().clip(lower=1e-14), "s-", label=f"{T:g} °C, {f:g} Hz")
    for ax in axes[0]:
        ax.axhline(0.5, color="k", ls=":", lw=0.8)
    for ax in axes[1]:
        ax.axhline(0.1, color="k", ls=":", lw=0.8)
    axes[0, 0].set_ylabel("| |E*| time-domain / harmonic - 1 | (%)")
    axes[1, 0].set_ylabel("| Φ time-domain - Φ harmonic | (°)")
    axes[1, 0].set_xlabel("time step dt (s)")
    axes[1, 1].set_xlabel("harmonic GMRES relative tolerance")
    axes[0, 0].legend(fontsize=7)
    for ax in axes.ravel():
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return fig


def plot_sensitivity(frame: pd.DataFrame, frequency_Hz: float):
    """Figure: change of |E*| (%) and Phi (deg) vs parameter change, sample and macro law."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
    sub = frame[np.isclose(frame["frequency_Hz"], frequency_Hz)]
    for k, name in enumerate(PARAM_COLUMNS):
        g = pd.concat([sub[sub["parameter"] == name], sub[sub["parameter"] == "reference"]])
        g = g.sort_values("change_percent")
        color = f"C{k}"
        axes[0].plot(g["change_percent"], g["dE_norm_percent"], "o-", color=color, label=f"{name} (sample)")
        axes[0].plot(g["change_percent"], g["macro_dE_norm_percent"], "--", color=color, label=f"{name} (macro)")
        axes[1].plot(g["change_percent"], g["dphase_deg"], "o-", color=color)
        axes[1].plot(g["change_percent"], g["macro_dphase_deg"], "--", color=color)
    axes[0].set_ylabel("change of |E*| (%)")
    axes[1].set_ylabel("change of Φ (°)")
    for ax in axes:
        ax.set_xlabel("parameter change (%)")
        ax.grid(True, alpha=0.3)
    T = float(sub["temperature_C"].iloc[0]) if len(sub) else float("nan")
    fig.suptitle(f"Sensitivity at {T:g} °C, {frequency_Hz:g} Hz", fontsize=10)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def plot_resolution(rows: pd.DataFrame, levels: pd.DataFrame, fits: pd.DataFrame):
    """Network factor against the number of spheres (log axis), each sample and the level
    means with their 95 % intervals, the fit NF_inf + c N^(-1/3), one panel per kinematics."""
    import matplotlib.pyplot as plt

    kins = list(dict.fromkeys(rows["bond_kinematics"]))
    fig, axes = plt.subplots(1, len(kins), figsize=(5.2 * len(kins), 4.0), squeeze=False)
    for ax, kin in zip(axes[0], kins):
        r = rows[rows["bond_kinematics"] == kin]
        lv = levels[levels["bond_kinematics"] == kin]
        ax.plot(r["n_spheres"], r["network_factor"], "o", color="0.6", ms=4, label="samples")
        err = [
            lv["network_factor_mean"] - lv["network_factor_ci95_low"],
            lv["network_factor_ci95_high"] - lv["network_factor_mean"],
        ]
        ax.errorbar(
            lv["n_spheres_mean"],
            lv["network_factor_mean"],
            yerr=np.nan_to_num(np.array(err, float)),
            fmt="s-",
            color="C0",
            capsize=3,
            label="level mean (95 % CI)",
        )
        f = fits[fits["bond_kinematics"] == kin].iloc[0]
        if np.isfinite(f["nf_inf"]):
            n = np.logspace(np.log10(lv["n_spheres_mean"].min()), 6, 50)
            ax.plot(
                n,
                f["nf_inf"] + f["c"] * n ** (-1 / 3),
                "--",
                color="C1",
                label=f"NF_inf = {f['nf_inf']:.3g} ± {f['nf_inf_se']:.2g}",
            )
        elif np.isfinite(f.get("chi2", np.nan)):
            ax.plot(
                [], [], " ", label=f"no limit: NF_inf + c N^(-1/3) rejected (chi2 = {f['chi2']:.3g}, {f['dof']} dof)"
            )
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("spheres in the sample")
        ax.set_ylabel("network factor NF (sample |E*| / law |E*|)")
        ax.set_title(f"bond kinematics: {kin}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
