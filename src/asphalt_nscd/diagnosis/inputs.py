"""Input tables of ``asphalt-nscd diagnose`` (and ``crossval``), read and validated: the
simulated and harmonic rows, the crossval rows, the time-integration phase errors, the
Burger's parameters the simulation was given and the network factors of the samples. Every
reader raises :class:`asphalt_nscd.io.InputError` naming the file and the column, row or key.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError, checked, read_csv, require_columns
from .crossval import ROW_COLUMNS

SIM_COLUMNS = ("temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg")


def read_simulated(path) -> pd.DataFrame:
    """Read a simulated/harmonic result table (reduced complex-modulus rows).

    Numerical isotherms (``asphalt-nscd campaign-isotherms``: ``E_norm_MPa_mean,
    phase_deg_mean``, sample means per (T, f)) are read as rows of those means.

    Raises InputError naming the file and the missing column or bad row.
    """
    df = read_csv(path)
    if "E_norm_MPa" not in df.columns and {"E_norm_MPa_mean", "phase_deg_mean"} <= set(df.columns):
        df = df.drop(columns=[c for c in ("phase_deg",) if c in df.columns]).rename(
            columns={"E_norm_MPa_mean": "E_norm_MPa", "phase_deg_mean": "phase_deg"}
        )
    return checked(df, path, SIM_COLUMNS, positive=("E_norm_MPa", "frequency_Hz"))


def read_simulated_many(paths) -> pd.DataFrame | None:
    """:func:`read_simulated` of each path, concatenated (None for no path).

    Accepts reduced rows (``E_norm_MPa, phase_deg``) and the numerical isotherms of
    ``asphalt-nscd campaign-isotherms`` (``E_norm_MPa_mean, phase_deg_mean``, sample means).
    """
    if paths is None:
        return None
    paths = [paths] if isinstance(paths, (str, bytes)) or not hasattr(paths, "__iter__") else list(paths)
    frames = [read_simulated(p) for p in paths]
    return pd.concat(frames, ignore_index=True) if frames else None


def read_crossval(paths) -> pd.DataFrame:
    """Rows of ``asphalt-nscd crossval`` CSVs (concatenated).

    Raises InputError naming the file and the missing column.
    """
    frames = []
    for path in [paths] if isinstance(paths, (str, bytes)) or not hasattr(paths, "__iter__") else paths:
        df = read_csv(path)
        require_columns(df, ROW_COLUMNS, path, "the output of 'asphalt-nscd crossval'")
        df["computable"] = df["computable"].astype(str).str.lower().isin(["true", "1"])
        df["extrapolation"] = df["extrapolation"].astype(str).str.lower().isin(["true", "1"])
        frames.append(df)
    return pd.concat(frames, ignore_index=True)


#: columns of a time-integration phase-error table
TIME_ERROR_COLUMNS = ("frequency_Hz", "dt_s", "phase_error_deg")
#: columns of the Burger's parameter table the simulation was given (MPa, MPa s)
MACRO_COLUMNS = ("temperature_C", "Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s")


def read_time_errors(paths, theta: float | None = None) -> pd.DataFrame:
    """Time-integration phase-error tables (``frequency_Hz, dt_s, phase_error_deg``, Hz, s,
    deg), concatenated; rows of the Moreau-Jean ``theta`` only when a table has a ``theta``
    column. Raises InputError naming the file and the column or row."""
    frames = []
    for path in paths:
        t = checked(read_csv(path), path, TIME_ERROR_COLUMNS)
        if theta is not None and "theta" in t.columns:
            t = t[np.isclose(t["theta"].astype(float), theta)]
            if t.empty:
                raise InputError(f"{path}: column 'theta': no row with theta = {theta:g}")
        frames.append(t)
    return pd.concat(frames, ignore_index=True)


def read_macro_params(path) -> pd.DataFrame:
    """The Burger's parameters (``temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s``)
    the simulation was given. Raises InputError naming the file and the missing column."""
    return checked(read_csv(path), path, MACRO_COLUMNS)


def read_network_factors(paths) -> dict:
    """{sample name: network factor NF_s} of ``harmonic-transfer`` JSONs
    (:func:`asphalt_nscd.harmonic.transfer.read_transfer_json`). Raises InputError naming the
    file when a sample is given twice."""
    from ..harmonic.transfer import read_transfer_json

    out = {}
    for path in paths:
        obj = read_transfer_json(path)
        if obj["sample"] in out:
            raise InputError(f"{path}: key 'sample': sample {obj['sample']!r} given twice in --transfer")
        out[obj["sample"]] = obj["network_factor"]
    return out
