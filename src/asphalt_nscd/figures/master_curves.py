"""The figures a pavement engineer expects of a complex-modulus table: master curves, shift
factors, per-cell residuals, and the sigmoidal (MEPDG) master curve beside 2S2P1D.

Every figure draws the law that was selected (the extended law of ``extend-law``) in the
reduced frequency that law uses, f aT_law(T) at its reference temperature, and in the units
the lab wrote its table in (:class:`asphalt_nscd.lab.table_format.DisplayUnits`, SI beside):

* :func:`master_curve_figure` -- |E*| and Phi against that reduced frequency: the
  artifact-corrected measured points coloured by temperature and, per isotherm over its
  tested band, the selected law (solid), the 2S2P1D master curve of the artifact search
  (thin grey) and the sigmoid (dotted), each model at its own (T, f) and drawn at the law's
  reduced frequency, so that a law which is not thermorheologically simple shows as
  isotherms that do not collapse;
* :func:`shift_factor_figure` -- log10 aT against temperature, every shift relative to the
  selected law's reference temperature: the selected law's, the 2S2P1D master curve's (its
  law and the free shifts of the artifact search), the sigmoid's polynomial;
* :func:`residual_figure` -- per cell, the selected law's error against the measured
  replicate means: |E*| (%) and Phi (deg) against frequency, one line per isotherm
  (in-sample: the law was fitted to these cells).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..lab.table_format import DisplayUnits


def _colours(temps):
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("viridis")
    span = max(float(np.ptp(temps)), 1e-9)
    return {float(T): cmap((float(T) - float(np.min(temps))) / span) for T in temps}


def _law_shift(model: dict):
    """log10 aT(T) of the selected law's shift (WLF or Arrhenius, at its T_ref)."""
    from ..rheology.shift import arrhenius_log_shift

    s, T_ref = model["shift"], float(model["T_ref_C"])
    if str(s["law"]).upper() == "WLF":
        return lambda T: -s["C1"] * (np.asarray(T, float) - T_ref) / (s["C2_K"] + np.asarray(T, float) - T_ref)
    return lambda T: arrhenius_log_shift(np.asarray(T, float), T_ref, s["Ea_kJ_mol"] * 1e3)


def _secondary_modulus_axis(ax, units: DisplayUnits) -> None:
    """An MPa axis on the right of a |E*| axis in the lab's unit."""
    if units.modulus == "MPa":
        return
    k = units.modulus_value(1.0)
    sec = ax.secondary_yaxis("right", functions=(lambda v: v / k, lambda v: v * k))
    sec.set_ylabel("|E*| (MPa)")


def master_curve_figure(
    master, corrected: pd.DataFrame, law: dict | None, sigmoid: dict | None, units: DisplayUnits = DisplayUnits()
):
    """The master-curve figure (module docstring); ``master``: MasterCurveFit (MPa),
    ``corrected``: the artifact-corrected table, ``law``: the selected law's JSON (or None:
    the 2S2P1D master curve's shift is used), ``sigmoid``:
    :func:`asphalt_nscd.rheology.sigmoid.fit_sigmoid` (or None); ``units``: the lab's."""
    import matplotlib.pyplot as plt

    from ..rheology import law_file
    from ..rheology.sigmoid import sigmoid_log_modulus, sigmoid_phase_deg

    if law and law.get("model"):
        shift, T_ref = _law_shift(law["model"]), float(law["model"]["T_ref_C"])
        what = f"selected law ({law['model']['shift']['law']}, T_ref {units.temperature_text(T_ref)})"
        entries = {T: g.scaled(1e-6) for T, g in law_file.validate(law, "law JSON").items()}
    else:
        shift, T_ref, entries = master.log_shift, master.T_ref_C, None
        what = f"2S2P1D master curve ({master.shift.upper()}, T_ref {units.temperature_text(T_ref)})"
    cells = corrected.groupby(["temperature_C", "frequency_Hz"], as_index=False)[["E_norm_MPa", "phase_deg"]].mean()
    colours = _colours(cells["temperature_C"].unique())
    fig, (axE, axP) = plt.subplots(1, 2, figsize=(12, 4.6))
    for T, g in corrected.groupby("temperature_C"):
        T = float(T)
        aT = 10.0 ** float(shift(T))
        c = colours[T]
        axE.loglog(
            g["frequency_Hz"] * aT,
            units.modulus_value(g["E_norm_MPa"].to_numpy(float)),
            "o",
            ms=3.5,
            color=c,
            label=units.temperature_text(T),
        )
        axP.semilogx(g["frequency_Hz"] * aT, g["phase_deg"], "o", ms=3.5, color=c)
        f = np.logspace(np.log10(g["frequency_Hz"].min() / 2), np.log10(g["frequency_Hz"].max() * 2), 40)
        curves = [("2S2P1D", master.modulus(f, T), dict(color="0.45", lw=0.8))]
        if entries is not None:
            E_law = law_file.complex_modulus(entries, np.full(f.size, T), f, "law JSON")
            curves.append(("law", E_law, dict(color=c, lw=1.8)))
        if sigmoid is not None:
            E_sig = 10 ** sigmoid_log_modulus(sigmoid, f, T) * np.exp(1j * np.radians(sigmoid_phase_deg(sigmoid, f, T)))
            curves.append(("sigmoid", E_sig, dict(color=c, lw=1.2, ls=":")))
        for _, E, style in curves:
            axE.loglog(f * aT, units.modulus_value(np.abs(E)), **style)
            axP.semilogx(f * aT, np.degrees(np.angle(E)), **style)
    axE.plot([], [], "k-", lw=1.8, label="selected law" if entries is not None else "")
    axE.plot([], [], "-", color="0.45", lw=0.8, label="2S2P1D (artifact search)")
    if sigmoid is not None:
        axE.plot([], [], "k:", lw=1.2, label="sigmoid (MEPDG)")
    for ax in (axE, axP):
        ax.set_xlabel(f"reduced frequency (Hz) of the {what}")
        ax.grid(True, which="both", lw=0.3)
    axE.set_ylabel(units.modulus_label())
    _secondary_modulus_axis(axE, units)
    axP.set_ylabel("phase angle (deg)")
    axE.legend(fontsize=7, ncol=2)
    fig.suptitle(
        "Master curve: measured (artifact-corrected) points and, per isotherm, the selected law, 2S2P1D "
        "and the sigmoid",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def shift_factor_figure(
    master, law: dict | None, sigmoid: dict | None, temperatures, free_shifts=None, units: DisplayUnits = DisplayUnits()
):
    """log10 aT against temperature, all relative to the selected law's reference temperature
    (module docstring); ``free_shifts``: {T degC: log10 aT} of the artifact search (drawn as
    points), ``units``: the lab's."""
    import matplotlib.pyplot as plt

    temps = np.sort(np.asarray(temperatures, float))
    T = np.linspace(temps.min() - 5, temps.max() + 5, 100)
    T_ref = float(law["model"]["T_ref_C"]) if law and law.get("model") else master.T_ref_C
    x = units.temperature_value(T)
    fig, ax = plt.subplots(figsize=(6.0, 4.2))
    rel = master.log_shift(T) - master.log_shift(T_ref)
    ax.plot(x, rel, "k-", label=f"2S2P1D master curve ({master.shift.upper()})")
    if free_shifts:
        ts = np.array(sorted(free_shifts), float)
        vals = np.array([free_shifts[t] for t in sorted(free_shifts)], float)
        ref = np.interp(T_ref, ts, vals)
        ax.plot(units.temperature_value(ts), vals - ref, "ko", mfc="none", label="free shifts of the artifact search")
    if law and law.get("model"):
        sh = _law_shift(law["model"])
        ax.plot(x, sh(T) - sh(T_ref), "C2-", lw=2.0, label=f"selected law ({law['model']['shift']['law']})")
        ax.plot(units.temperature_value(temps), sh(temps) - sh(T_ref), "C2s")
    if sigmoid is not None:
        d = T - sigmoid["T_ref_C"]
        poly = sigmoid["a1_per_C"] * d + sigmoid["a2_per_C2"] * d**2
        d0 = T_ref - sigmoid["T_ref_C"]
        ax.plot(x, poly - (sigmoid["a1_per_C"] * d0 + sigmoid["a2_per_C2"] * d0**2), "C1:", label="sigmoid (quadratic)")
    ax.set_xlabel(units.temperature_label())
    if units.temperature == "F":
        sec = ax.secondary_xaxis(
            "top", functions=(lambda v: (np.asanyarray(v) - 32.0) / 1.8, lambda v: np.asanyarray(v) * 1.8 + 32.0)
        )
        sec.set_xlabel("temperature (°C)")
    ax.set_ylabel(f"log10 aT (relative to {units.temperature_text(T_ref)})")
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


def residual_figure(residuals: pd.DataFrame, units: DisplayUnits = DisplayUnits()):
    """Per-cell residuals of the selected law (module docstring); ``units``: the lab's."""
    import matplotlib.pyplot as plt

    colours = _colours(residuals["temperature_C"].unique())
    fig, (axE, axP) = plt.subplots(1, 2, figsize=(10, 3.8))
    for T, g in residuals.groupby("temperature_C"):
        g = g.sort_values("frequency_Hz")
        axE.semilogx(
            g["frequency_Hz"],
            g["error_E_norm_pct"],
            "o-",
            color=colours[float(T)],
            label=units.temperature_text(float(T)),
        )
        axP.semilogx(g["frequency_Hz"], g["error_phase_deg"], "o-", color=colours[float(T)])
    for ax, lab in ((axE, "law - measured |E*| (%)"), (axP, "law - measured phase (deg)")):
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel(lab)
        ax.grid(True, which="both", lw=0.3)
    axE.legend(fontsize=7)
    fig.suptitle("Selected law against the measured replicate means, per cell (in-sample)", fontsize=10)
    fig.tight_layout()
    return fig
