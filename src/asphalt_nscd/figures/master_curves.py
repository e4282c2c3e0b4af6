"""The figures a pavement engineer expects of a complex-modulus table: master curves, shift
factors, per-cell residuals, and the sigmoidal (MEPDG) master curve beside 2S2P1D.

* :func:`master_curve_figure` -- |E*| and Phi against the reduced frequency at the master
  curve's reference temperature: the artifact-corrected measured points coloured by
  temperature (shifted by the 2S2P1D master curve's shift law), the 2S2P1D master curve, the
  temperature-aware extended law at its reference temperature (its Prony chain), and the
  sigmoid (|E*|; its phase by Booij-Thoone, dashed);
* :func:`shift_factor_figure` -- log10 aT against temperature: the 2S2P1D shift law with its
  values at the tested isotherms, the extended law's and the sigmoid's polynomial;
* :func:`residual_figure` -- per cell, the extended law's error against the measured
  replicate means: |E*| (%) and Phi (deg) against frequency, one line per isotherm
  (in-sample: the law was fitted to these cells).
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def _colours(temps):
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("viridis")
    span = max(float(np.ptp(temps)), 1e-9)
    return {float(T): cmap((float(T) - float(np.min(temps))) / span) for T in temps}


def _law_shift(model: dict):
    """log10 aT(T) of the extended law's shift (WLF or Arrhenius, at its T_ref)."""
    from ..rheology.shift import arrhenius_log_shift

    s, T_ref = model["shift"], float(model["T_ref_C"])
    if str(s["law"]).upper() == "WLF":
        return lambda T: -s["C1"] * (np.asarray(T, float) - T_ref) / (s["C2_K"] + np.asarray(T, float) - T_ref)
    return lambda T: arrhenius_log_shift(np.asarray(T, float), T_ref, s["Ea_kJ_mol"] * 1e3)


def master_curve_figure(master, corrected: pd.DataFrame, law: dict | None, sigmoid: dict | None):
    """The master-curve figure (module docstring); ``master``: MasterCurveFit (MPa),
    ``corrected``: the artifact-corrected table, ``law``: the law JSON (or None),
    ``sigmoid``: :func:`asphalt_nscd.rheology.sigmoid.fit_sigmoid` (or None)."""
    import matplotlib.pyplot as plt

    from ..rheology.master_curve import master_curve_table
    from ..rheology.sigmoid import sigmoid_log_modulus, sigmoid_phase_deg

    tab = master_curve_table(master, corrected)
    data, model = tab[tab["kind"] == "data"], tab[tab["kind"] == "model"]
    colours = _colours(data["temperature_C"].unique())
    fig, (axE, axP) = plt.subplots(1, 2, figsize=(11, 4.4))
    for T, g in data.groupby("temperature_C"):
        axE.loglog(g["reduced_frequency_Hz"], g["E_norm_MPa"], "o", ms=4, color=colours[float(T)], label=f"{T:g} °C")
        axP.semilogx(g["reduced_frequency_Hz"], g["phase_deg"], "o", ms=4, color=colours[float(T)])
    fr = model["reduced_frequency_Hz"].to_numpy(float)
    axE.loglog(fr, model["E_norm_MPa"], "k-", lw=1.6, label=f"2S2P1D, {master.shift.upper()} (T_ref {master.T_ref_C:g} °C)")
    axP.semilogx(fr, model["phase_deg"], "k-", lw=1.6)
    if law and law.get("model", {}).get("prony_at_T_ref"):
        from ..rheology.export import _chain

        chain = _chain(law["model"]["prony_at_T_ref"]).scaled(1e-6)
        E = chain.complex_modulus(2 * np.pi * fr)
        T_law = float(law["model"]["T_ref_C"])
        axE.loglog(fr, np.abs(E), "C2--", lw=1.4, label=f"extended law (T_ref {T_law:g} °C)")
        axP.semilogx(fr, np.degrees(np.angle(E)), "C2--", lw=1.4)
    if sigmoid is not None:
        axE.loglog(fr, 10 ** sigmoid_log_modulus(sigmoid, fr, sigmoid["T_ref_C"]), "C1:", lw=1.8,
                   label="sigmoid (MEPDG)")
        axP.semilogx(fr, sigmoid_phase_deg(sigmoid, fr, sigmoid["T_ref_C"]), "C1:", lw=1.4)
    axE.set_xlabel("reduced frequency (Hz)")
    axE.set_ylabel("|E*| (MPa)")
    axP.set_xlabel("reduced frequency (Hz)")
    axP.set_ylabel("phase angle (deg)")
    axE.legend(fontsize=7, ncol=2)
    axE.grid(True, which="both", lw=0.3)
    axP.grid(True, which="both", lw=0.3)
    fig.suptitle("Master curve: measured (artifact-corrected) points, 2S2P1D, extended law, sigmoid", fontsize=10)
    fig.tight_layout()
    return fig


def shift_factor_figure(master, law: dict | None, sigmoid: dict | None, temperatures):
    """log10 aT against temperature (module docstring)."""
    import matplotlib.pyplot as plt

    temps = np.sort(np.asarray(temperatures, float))
    T = np.linspace(temps.min() - 5, temps.max() + 5, 100)
    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    ax.plot(T, master.log_shift(T), "k-", label=f"2S2P1D master curve ({master.shift.upper()})")
    ax.plot(temps, master.log_shift(temps), "ko")
    if law and law.get("model"):
        ax.plot(T, _law_shift(law["model"])(T), "C2--", label=f"extended law ({law['model']['shift']['law']})")
    if sigmoid is not None:
        d = T - sigmoid["T_ref_C"]
        ax.plot(T, sigmoid["a1_per_C"] * d + sigmoid["a2_per_C2"] * d**2, "C1:", label="sigmoid (quadratic)")
    ax.set_xlabel("temperature (°C)")
    ax.set_ylabel("log10 aT")
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def residual_table(measured: pd.DataFrame, law: dict) -> pd.DataFrame:
    """Per cell: the extended law's |E*| error (%) and Phi error (deg) against the replicate
    means of ``measured`` (in-sample). Columns ``temperature_C, frequency_Hz, E_norm_MPa,
    phase_deg, E_norm_MPa_law, phase_deg_law, error_E_norm_pct, error_phase_deg``."""
    from ..rheology import law_file
    from ..rheology.metrics import cell_means

    cells = cell_means(measured)
    laws = {T: g.scaled(1e-6) for T, g in law_file.validate(law, "law JSON").items()}
    E = law_file.complex_modulus(laws, cells["temperature_C"], cells["frequency_Hz"], "law JSON")
    out = cells[["temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg"]].copy()
    out["E_norm_MPa_law"] = np.abs(E)
    out["phase_deg_law"] = np.degrees(np.angle(E))
    out["error_E_norm_pct"] = 100 * (out["E_norm_MPa_law"] / out["E_norm_MPa"] - 1)
    out["error_phase_deg"] = out["phase_deg_law"] - out["phase_deg"]
    return out


def residual_figure(residuals: pd.DataFrame):
    """Per-cell residuals of the extended law (module docstring)."""
    import matplotlib.pyplot as plt

    colours = _colours(residuals["temperature_C"].unique())
    fig, (axE, axP) = plt.subplots(1, 2, figsize=(10, 3.8))
    for T, g in residuals.groupby("temperature_C"):
        g = g.sort_values("frequency_Hz")
        axE.semilogx(g["frequency_Hz"], g["error_E_norm_pct"], "o-", color=colours[float(T)], label=f"{T:g} °C")
        axP.semilogx(g["frequency_Hz"], g["error_phase_deg"], "o-", color=colours[float(T)])
    for ax, lab in ((axE, "law - measured |E*| (%)"), (axP, "law - measured phase (deg)")):
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel(lab)
        ax.grid(True, which="both", lw=0.3)
    axE.legend(fontsize=7)
    fig.suptitle("Extended law against the measured replicate means, per cell (in-sample)", fontsize=10)
    fig.tight_layout()
    return fig
