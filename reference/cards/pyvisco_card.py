"""The card NREL's pyvisco 1.0.4 writes for a measured table, with its defaults, judged as the
project judges its own card: at every measured (T, f) against the lab's replicate means.

pyvisco is a baseline, not a dependency of the project: it needs numpy < 2 and pandas < 2, so it
runs in a virtual environment of its own (README.md of this folder):

    python3.11 -m venv .venv-pyvisco
    .venv-pyvisco/bin/pip install pyvisco==1.0.4 "numpy<2" "pandas<2" "scipy<1.14" "matplotlib<3.10"
    .venv-pyvisco/bin/python reference/cards/pyvisco_card.py results/lab/measured_summary.csv --t-ref 21 \
        --table data/measured/uiuc_fdmix1_utm/complex_modulus.csv -o reference/cards/pyvisco.csv

Input: a measured summary of ``asphalt-nscd measured`` (``temperature_C, frequency_Hz,
E_norm_MPa_mean, phase_deg_mean``). pyvisco's steps, each with its defaults: raw frequency
sweeps per temperature (storage and loss moduli of the replicate means), shift factors by
pairwise overlap of the isotherms (``master.get_aT``), WLF fitted to them, discretisation
(``round`` window), Prony fit in the frequency domain, and its minimisation of the number of
terms (``opt.nprony``, window ``min``, the suggested N). The card is evaluated with its WLF
shift, as an FE code would. Output: one row, the four figures of ``reference/cards/cards.csv``
(|E*| as 100 |ln ratio|, %; Phi in deg; mean and largest over the cells).
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
from pyvisco import load, master, opt, prony, shift


def pyvisco_card(cells: pd.DataFrame, t_ref_C: float) -> tuple[dict, float, float, float]:
    """(Prony series dict of pyvisco, its T_ref, C1, C2) of the cell means
    (``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``)."""
    rows = ["f,E_stor,E_loss,T,Set", "Hz,MPa,MPa,C,-"]
    for k, (T, g) in enumerate(cells.groupby("temperature_C")):
        for r in g.itertuples():
            E = r.E_norm_MPa * np.exp(1j * np.radians(r.phase_deg))
            rows.append(f"{r.frequency_Hz},{E.real},{E.imag},{T},{k}")
    df_raw, arr_ref, _ = load.user_raw("\n".join(rows).encode(), "freq", "E")
    ref = float(arr_ref.iloc[(arr_ref - t_ref_C).abs().argsort()[:1]].values[0])
    df_aT, _ = master.get_aT(df_raw, ref)
    df_master = master.smooth(master.get_curve(df_raw, df_aT, ref), 1)
    wlf = shift.fit_WLF(df_master.RefT, df_aT)
    first, _ = prony.fit(prony.discretize(df_master, "round", 0), df_master, opt=False)
    series, n_opt, _ = opt.nprony(df_master, first, window="min")
    return series[n_opt], ref, float(wlf.C1.iloc[0]), float(wlf.C2.iloc[0])


def card_errors(series: dict, ref: float, C1: float, C2: float, cells: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """|ln(|E*|card / |E*|measured)| (%) and |Phi_card - Phi_measured| (deg) at every cell."""
    a = series["df_terms"]["alpha_i"].to_numpy(float)
    tau = series["df_terms"]["tau_i"].to_numpy(float)
    d = cells["temperature_C"].to_numpy(float) - ref
    w = 2 * np.pi * cells["frequency_Hz"].to_numpy(float) * 10.0 ** (-C1 * d / (C2 + d))
    iwt = 1j * w[:, None] * tau
    E = series["E_0"] * ((1 - a.sum()) + (a * iwt / (1 + iwt)).sum(axis=1))
    dE = 100 * np.abs(np.log(np.abs(E) / cells["E_norm_MPa"].to_numpy(float)))
    dP = np.abs(np.degrees(np.angle(E)) - cells["phase_deg"].to_numpy(float))
    return dE, dP


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("summary", type=Path, help="measured summary (asphalt-nscd measured --summary)")
    p.add_argument("--t-ref", type=float, default=21.0, help="reference temperature, degC (the nearest tested one)")
    p.add_argument(
        "--table",
        type=Path,
        required=True,
        help="the measured table the summary came from (its name and SHA-256 go in the row)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV row of the four figures")
    args = p.parse_args()
    s = pd.read_csv(args.summary)
    cells = s.rename(columns={"E_norm_MPa_mean": "E_norm_MPa", "phase_deg_mean": "phase_deg"})
    series, ref, C1, C2 = pyvisco_card(cells, args.t_ref)
    dE, dP = card_errors(series, ref, C1, C2, cells)
    row = {
        "table": str(args.table),
        "table_sha256": hashlib.sha256(args.table.read_bytes()).hexdigest()[:16],
        "tool": "pyvisco 1.0.4 (defaults; WLF shift)",
        "n_terms": len(series["df_terms"]),
        "T_ref_C": ref,
        "C1": C1,
        "C2_K": C2,
        "n_cells": len(cells),
        "card_vs_measured_logE_pct_mean": dE.mean(),
        "card_vs_measured_logE_pct_max": dE.max(),
        "card_vs_measured_phase_deg_mean": dP.mean(),
        "card_vs_measured_phase_deg_max": dP.max(),
    }
    pd.DataFrame([row]).to_csv(args.output, index=False, float_format="%.4g")


if __name__ == "__main__":
    main()
