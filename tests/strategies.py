"""Reusable hypothesis strategies: measured complex-modulus tables.

:func:`measured_tables` draws tidy tables with the columns of
:mod:`asphalt_nscd.lab.measured` over the domain every step must accept:
1-5 specimens, 3-8 temperatures (-20..60 degC), 3-9 frequencies (0.01-100 Hz), balanced
or unbalanced grids (one specimen row missing, or one whole (T, f) cell missing), phase
angles in [1, 60] deg, optional ``strain_microstrain`` and ``test_order`` columns.

Values: ``physical`` tables come from a 2S2P1D + WLF truth with parameters drawn over
(and a little beyond) the published ranges for mixes and binder-rich mixes, a log-normal
factor per specimen and point noise; phases are clipped into [1, 60] deg. ``wild`` tables
have |E*| and Phi drawn independently per cell (log-uniform 5 MPa - 40 GPa, 1-60 deg):
nothing a laboratory would report, but a table ``measured`` accepts, so the chain must not
crash on it either. Use ``kind`` to restrict to one of them.

Example::

    from hypothesis import given
    from strategies import measured_tables

    @given(measured_tables(max_specimens=3))
    def test_something(table): ...
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import strategies as st

COLUMNS = ("specimen", "temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg")


@st.composite
def truths(draw) -> dict:
    """2S2P1D + WLF parameters (MPa, s, K) of a mix or a binder-rich mix."""
    u = lambda lo, hi: draw(st.floats(lo, hi, allow_nan=False, allow_infinity=False))
    return {
        "E0_MPa": 10 ** u(4.2, 4.65),
        "E00_MPa": 10 ** u(0.0, 2.6),
        "delta": u(1.2, 4.0),
        "k": u(0.12, 0.26),
        "h": u(0.45, 0.72),
        "beta": 10 ** u(1.5, 4.0),
        "tau_ref_s": 10 ** u(-3.0, 0.5),
        "C1": u(15.0, 40.0),
        "C2_K": u(110.0, 260.0),
        "T_ref_C": 15.0,
    }


@st.composite
def measured_tables(
    draw,
    min_specimens: int = 1,
    max_specimens: int = 5,
    min_temperatures: int = 3,
    max_temperatures: int = 8,
    min_frequencies: int = 3,
    max_frequencies: int = 9,
    kind: str | None = None,
) -> pd.DataFrame:
    """A measured table (module docstring); the arguments narrow the domain."""
    from asphalt_nscd.diagnosis.synthetic import truth_modulus

    n_spec = draw(st.integers(min_specimens, max_specimens))
    temps = sorted(
        draw(st.lists(st.integers(-20, 60), min_size=min_temperatures, max_size=max_temperatures, unique=True))
    )
    # frequencies on a 0.1-decade grid from 0.01 to 100 Hz
    logf = sorted(
        draw(st.lists(st.integers(-20, 20), min_size=min_frequencies, max_size=max_frequencies, unique=True)),
        reverse=True,
    )
    freqs = [round(10 ** (k / 10), 6) for k in logf]
    kind = kind or draw(st.sampled_from(["physical", "physical", "physical", "wild"]))
    missing = draw(st.sampled_from(["none", "row", "cell"]))
    with_strain = draw(st.booleans())
    with_order = draw(st.booleans())
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    truth = draw(truths()) if kind == "physical" else None
    rows = []
    for s in range(n_spec):
        c = rng.normal(0.0, 0.04)
        order = 0
        for T in temps:
            for f in freqs:
                order += 1
                if truth is not None:
                    E = complex(truth_modulus(truth, f, float(T)))
                    E_norm = abs(E) * np.exp(c + rng.normal(0.0, 0.015))
                    phase = np.degrees(np.angle(E)) + rng.normal(0.0, 0.3)
                else:
                    E_norm = 10 ** rng.uniform(np.log10(5.0), np.log10(4e4))
                    phase = rng.uniform(1.0, 60.0)
                row = {
                    "specimen": f"S{s + 1}",
                    "temperature_C": float(T),
                    "frequency_Hz": f,
                    "E_norm_MPa": float(round(E_norm, 4)),
                    "phase_deg": float(round(np.clip(phase, 1.0, 60.0), 3)),
                }
                if with_strain:
                    row["strain_microstrain"] = round(float(rng.uniform(20.0, 150.0)), 1)
                if with_order:
                    row["test_order"] = order
                rows.append(row)
    table = pd.DataFrame(rows)
    if missing == "row" and len(table) > 1:
        table = table.drop(index=draw(st.integers(0, len(table) - 1)))
    elif missing == "cell":
        T = draw(st.sampled_from(temps))
        f = draw(st.sampled_from(freqs))
        table = table[~((table["temperature_C"] == T) & (table["frequency_Hz"] == f))]
    return table.reset_index(drop=True)


def write_table(table: pd.DataFrame, directory, name: str = "table.csv"):
    """Write ``table`` as a CSV in ``directory``; returns its path."""
    from pathlib import Path

    path = Path(directory) / name
    table.to_csv(path, index=False)
    return path
