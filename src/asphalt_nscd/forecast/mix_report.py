"""What a designer takes away from a forecast of a new mix: one page and one figure per mix.

:func:`summary_page` writes the Markdown summary of one mix (its inputs, the models' forecasts
at a glance, the Level 1 table of the best model with its prediction interval, the AASHTO R 84
sigmoid, the binder inputs Pavement ME asks for, and every input outside the training mixes'
ranges); :func:`master_curve_figure` draws its forecast |E*| master curve (reduced frequency by
the sigmoid's shift) with its interval band, and the training mixes' measured |E*| faint behind.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

PSI_PER_MPA = 1.0 / 6.894757293168361e-3


def master_curve_figure(mix_id: str, forecast: pd.DataFrame, sigmoid: pd.Series, training: pd.DataFrame, best: str):
    """The figure (matplotlib) of one mix: forecast |E*| of ``best`` against reduced frequency with
    its interval band, and the training mixes' measured |E*| (grey, shifted by the same sigmoid's
    shift law) behind."""
    import matplotlib.pyplot as plt

    f = forecast[(forecast["mix_id"] == mix_id) & (forecast["model"] == best)].sort_values(
        ["temperature_C", "frequency_Hz"]
    )
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    has_shift = np.all(np.isfinite([sigmoid.get("a1_per_C", np.nan), sigmoid.get("a2_per_C2", np.nan)]))

    def reduced(T, fr):
        if not has_shift:
            return np.asarray(fr, float)
        dT = np.asarray(T, float) - sigmoid["T_ref_C"]
        return np.asarray(fr, float) * 10.0 ** (sigmoid["a1_per_C"] * dT + sigmoid["a2_per_C2"] * dT**2)

    for _, g in training.groupby("mix_id"):
        ax.loglog(reduced(g["temperature_C"], g["frequency_Hz"]), g["E_norm_MPa"], ".", color="0.8", ms=3, zorder=1)
    x = reduced(f["temperature_C"], f["frequency_Hz"])
    order = np.argsort(x)
    if {"E_low_MPa", "E_high_MPa"} <= set(f):
        ax.fill_between(
            x[order],
            f["E_low_MPa"].to_numpy()[order],
            f["E_high_MPa"].to_numpy()[order],
            color="C0",
            alpha=0.2,
            label="prediction interval",
            zorder=2,
        )
    ax.loglog(x[order], f["E_norm_MPa"].to_numpy()[order], "o-", color="C0", ms=4, label=f"forecast ({best})", zorder=3)
    ax.plot([], [], ".", color="0.8", label="training mixes, measured")
    ax.set_xlabel("reduced frequency (Hz)" + ("" if has_shift else " (no shift fitted)"))
    ax.set_ylabel("|E*| (MPa)")
    ax.set_title(f"mix {mix_id}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def summary_page(
    mix_id: str,
    mix,
    forecast: pd.DataFrame,
    level1: pd.DataFrame,
    sigmoid: pd.Series,
    binder: pd.DataFrame,
    outside: pd.DataFrame,
    state: dict,
    figure: str,
) -> str:
    """The Markdown summary of one mix (module docstring)."""
    best = state["best_model"]
    f = forecast[forecast["mix_id"] == mix_id]
    cal = state.get("intervals") or []
    level = f"{cal[0]['level']:.0%}" if cal else "no"
    L = [f"# Forecast of mix {mix_id}", ""]
    L += [
        f"From its binder ({mix.sources.get('binder_file', '?')}), its sieve analysis and its volumetrics "
        f"({mix.sources.get('mix_file', '?')}), by models trained on {len(state.get('training_mixes', []))} mixes. "
        f"Best model on the training mixes left out: **{best}**; every forecast carries a {level} prediction "
        "interval calibrated on the training mixes left out.",
        "",
    ]
    if len(outside):
        L += ["**Outside the training mixes' ranges (the intervals are extrapolated):**", ""]
        for _, r in outside.iterrows():
            L.append(f"- {r['input']}: {r['value']:.4g}, training range {r['low']:.4g} to {r['high']:.4g}")
        L.append("")
    v = mix.volumetrics
    L += [
        "## Inputs",
        "",
        f"Va {v['Va_pct']:.2f} %, Vbeff {v['Vbeff_pct']:.2f} %, VMA {v['VMA_pct']:.2f} %, VFA {v['VFA_pct']:.1f} %"
        + (f", Pb {v['Pb_pct']:.2f} %" if v.get("Pb_pct") is not None else "")
        + "; Witczak sieve figures: "
        + ", ".join(f"{k.replace('_pct', '')} {val:.1f}" for k, val in mix.witczak.items())
        + ".",
        "",
        f"![forecast master curve]({figure})",
        "",
        f"## Level 1 |E*| table ({best}; `level1_tables.csv` has psi and MPa)",
        "",
    ]
    t = level1[(level1["mix_id"] == mix_id) & (level1["unit"] == "MPa")]
    freqs = [c for c in t.columns if c.endswith(" Hz")]
    L.append("| T (°C) | T (°F) | " + " | ".join(f"{c} (MPa)" for c in freqs) + " |")
    L.append("|---|---|" + "---|" * len(freqs))
    for _, r in t.iterrows():
        cells = []
        for c in freqs:
            lo, hi = r.get(f"{c} low", np.nan), r.get(f"{c} high", np.nan)
            band = f" [{lo:.0f}, {hi:.0f}]" if np.isfinite(lo) and np.isfinite(hi) else ""
            cells.append(f"{r[c]:.0f}{band}")
        L.append(f"| {r['temperature_C']:.1f} | {r['temperature_F']:.0f} | " + " | ".join(cells) + " |")
    L += [
        "",
        "## AASHTO R 84 sigmoid",
        "",
        "log10|E*| = delta + alpha / (1 + exp(beta + gamma log10 f_r)), log10 aT = a1 (T - T_ref) + a2 (T - T_ref)^2 (a1_per_C, a2_per_C2), "
        f"T_ref = {sigmoid['T_ref_C']:.1f} °C: "
        + ", ".join(
            f"{k} = {sigmoid[k]:.5g}"
            for k in ("delta", "alpha", "beta", "gamma", "a1_per_C", "a2_per_C2")
            if k in sigmoid
        )
        + f" (delta in log10 MPa; {sigmoid.get('delta_psi', np.nan):.5g} in log10 psi).",
        "",
        "## The binder (its master curve from the sweeps)",
        "",
        "| T (°C) | T (°F) | \\|G*\\| at 10 rad/s (kPa) | δ at 10 rad/s (°) | MEPDG viscosity from the curve (Pa s) |",
        "|---|---|---|---|---|",
    ]
    for _, r in binder[binder["mix_id"] == mix_id].iterrows():
        L.append(
            f"| {r['temperature_C']:.1f} | {r['temperature_F']:.0f} | {r['G_10rad_s_Pa'] / 1e3:.4g} | "
            f"{r['delta_10rad_s_deg']:.1f} | {r['viscosity_Pa_s']:.3g} |"
        )
    L += [
        "",
        "## Every model at 10 Hz",
        "",
        "| model | " + " | ".join(f"{T:.1f} °C" for T in sorted(f["temperature_C"].unique())) + " |",
    ]
    temps = sorted(f["temperature_C"].unique())
    L.append("|---|" + "---|" * len(temps))
    at10 = f[np.isclose(f["frequency_Hz"], 10.0)]
    for model, g in at10.groupby("model", sort=False):
        g = g.set_index("temperature_C")
        L.append(
            f"| {model} | "
            + " | ".join(f"{g.loc[T, 'E_norm_MPa']:.0f} MPa, {g.loc[T, 'phase_deg']:.1f}°" for T in temps)
            + " |"
        )
    return "\n".join(L) + "\n"
