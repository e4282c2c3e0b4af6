"""The figures of a material card (``asphalt-nscd export-law``; :mod:`asphalt_nscd.rheology.export`),
in the units the lab wrote its table in (:class:`asphalt_nscd.lab.table_format.DisplayUnits`):

* :func:`isochrones_figure` -- |E*| and Phi against temperature at each tested frequency: the
  measured replicate means (markers) and the card (lines, evaluated on a fine temperature grid
  through its WLF shift), so that a card which misses an isotherm shows where;
* :func:`relaxation_creep_figure` -- the card's relaxation modulus E(t) and creep compliance
  D(t) at each tested temperature (the columns of ``relaxation_creep.csv``), log-log;
* :func:`terms_curve_figure` -- the largest difference of the card to the law it carries
  against the number of Prony terms tried, with the tolerance, so that the chosen N shows why.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..lab.table_format import DisplayUnits


def isochrones_figure(card: dict, errors: pd.DataFrame, units: DisplayUnits = DisplayUnits()):
    """Isochrones of the measured means and of the card.

    ``card``: the card JSON (``prony.json``: ``E_inf_MPa``, ``terms``, ``shift``); ``errors``:
    ``card_errors.csv`` (columns ``temperature_C, frequency_Hz, E_norm_MPa_measured,
    phase_deg_measured``, one row per measured cell). Returns the matplotlib figure (two
    panels: |E*| in the lab's unit on a log axis, Phi in degrees)."""
    import matplotlib.pyplot as plt

    from ..rheology.export import card_modulus

    T_lo, T_hi = float(errors["temperature_C"].min()), float(errors["temperature_C"].max())
    grid = np.linspace(T_lo, T_hi, 121)
    freqs = sorted(errors["frequency_Hz"].unique())
    cmap = plt.get_cmap("plasma")
    fig, (ax_E, ax_P) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    for k, f in enumerate(freqs):
        colour = cmap(k / max(len(freqs) - 1, 1) * 0.85)
        E = card_modulus(card, np.full_like(grid, f), grid)
        cells = errors[errors["frequency_Hz"] == f].sort_values("temperature_C")
        x, xc = units.temperature_value(grid), units.temperature_value(cells["temperature_C"].to_numpy(float))
        ax_E.plot(x, units.modulus_value(np.abs(E)), color=colour, lw=1.2, label=f"{f:g} Hz")
        ax_E.plot(xc, units.modulus_value(cells["E_norm_MPa_measured"].to_numpy(float)), "o", color=colour, ms=4)
        ax_P.plot(x, np.degrees(np.angle(E)), color=colour, lw=1.2)
        ax_P.plot(xc, cells["phase_deg_measured"], "o", color=colour, ms=4)
    t_label = "temperature (degC)" if units.temperature == "C" else "temperature (degF)"
    ax_E.set_yscale("log")
    ax_E.set_xlabel(t_label)
    ax_E.set_ylabel(f"|E*| ({units.modulus})")
    ax_P.set_xlabel(t_label)
    ax_P.set_ylabel("phase angle (deg)")
    ax_E.legend(fontsize=7, title="card (lines), measured means (markers)", title_fontsize=7)
    n = len(card.get("terms", []))
    fig.suptitle(f"Isochrones: the material card ({n} Prony terms, WLF shift) against the measured means")
    return fig


def relaxation_creep_figure(functions: pd.DataFrame, units: DisplayUnits = DisplayUnits()):
    """E(t) and D(t) of the card at each temperature of ``functions`` (``relaxation_creep.csv``:
    ``temperature_C, time_s, E_MPa, D_per_MPa``). Returns the matplotlib figure."""
    import matplotlib.pyplot as plt

    temps = sorted(functions["temperature_C"].unique())
    cmap = plt.get_cmap("viridis")
    fig, (ax_E, ax_D) = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    for k, T in enumerate(temps):
        rows = functions[functions["temperature_C"] == T].sort_values("time_s")
        colour = cmap(k / max(len(temps) - 1, 1))
        label = units.temperature_text(float(T))
        ax_E.loglog(rows["time_s"], units.modulus_value(rows["E_MPa"].to_numpy(float)), color=colour, label=label)
        ax_D.loglog(rows["time_s"], 1.0 / units.modulus_value(1.0 / rows["D_per_MPa"].to_numpy(float)), color=colour)
    ax_E.set_xlabel("time t (s)")
    ax_E.set_ylabel(f"relaxation modulus E(t) ({units.modulus})")
    ax_D.set_xlabel("time t (s)")
    ax_D.set_ylabel(f"creep compliance D(t) (1/{units.modulus})")
    ax_E.legend(fontsize=7)
    fig.suptitle("The material card's relaxation modulus and creep compliance (interconverted exactly)")
    return fig


def terms_curve_figure(card: dict):
    """The error-versus-N curve of the card's term selection (``terms_selection.curve`` of
    ``prony.json``: one {n, max_E_pct, max_phase_deg} per N tried) against the tolerance
    (``terms_selection.tolerance``). Returns the matplotlib figure (|E*| % and Phi deg on log axes
    against N, the tolerances dashed, the chosen N marked)."""
    import matplotlib.pyplot as plt

    sel = card["terms_selection"]
    curve = pd.DataFrame(sel["curve"])
    tol = sel["tolerance"]
    fig, (ax_E, ax_P) = plt.subplots(1, 2, figsize=(10, 3.8), constrained_layout=True)
    for ax, col, t, label in (
        (ax_E, "max_E_pct", tol["E_norm_pct"], "largest |E*| difference (%)"),
        (ax_P, "max_phase_deg", tol["phase_deg"], "largest phase difference (deg)"),
    ):
        ax.semilogy(curve["n"], curve[col], "o-", ms=4, color="tab:blue")
        ax.axhline(t, ls="--", color="tab:red", lw=1, label=f"tolerance {t:g}")
        ax.axvline(sel["n_terms"], ls=":", color="0.3", lw=1, label=f"chosen N = {sel['n_terms']}")
        ax.set_xlabel("number of Prony terms N")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    fig.suptitle(
        "The card against the law it carries, by number of Prony terms (band widened by "
        f"{sel.get('margin_decades', 1):g} decade and the measured cells)"
    )
    return fig
