"""Figures of the NSCD core's verification (``asphalt-nscd verify --figure``)."""

from __future__ import annotations

import numpy as np
import pandas as pd


def plot_phase_table(table: pd.DataFrame):
    """Figure: phase error (deg) vs omega dt, one line per (frequency, theta)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    for (f, th), g in table.groupby(["frequency_Hz", "theta"]):
        g = g.sort_values("omega_dt")
        ax.loglog(g.omega_dt, np.abs(g.phase_error_deg).clip(lower=1e-8), "o-", label=f"{f:g} Hz, theta = {th:g}")
    ax.axhline(0.01, color="k", lw=0.8, ls="--")
    ax.set_xlabel("omega dt (rad)")
    ax.set_ylabel("|phase error| (deg)")
    ax.set_title("Bond law under imposed sinusoidal gap (Table 3, 15 degC)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
