"""Reusable hypothesis strategies: measured complex-modulus tables, and a mix's lab forms.

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

A mix's lab forms (:func:`dsr_sweeps`, :func:`sieve_analyses`, :func:`volumetric_reports`): a
binder's DSR sweep written in random units, forms and headers, a sieve analysis in random names and
forms, a volumetric report in one of its forms, each with the truth it must read back as.

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


# --- lab forms of a mix (asphalt_nscd.lab.dsr, .sieve, .volumetrics) ---------------------------------

#: written unit -> factor from the SI value (Pa, Hz, deg) to the written one, and the header text
_G_UNITS = {"Pa": (1.0, "Pa"), "kPa": (1e-3, "kPa"), "MPa": (1e-6, "MPa"), "psi": (1 / 6894.757293168361, "psi")}


@st.composite
def dsr_sweeps(draw) -> tuple[pd.DataFrame, dict, dict | None]:
    """(truth, columns, sidecar): a binder DSR sweep's true points in SI (one row per binder,
    specimen, temperature, frequency: ``binder, specimen, temperature_C, frequency_Hz, G_Pa,
    delta_deg``), the columns a lab writes for them in random units, form and headers (header text
    -> list of cells as text), and the sidecar declaring what the headers do not say (or None).

    |G*| lies within 0.8 decades of :data:`asphalt_nscd.lab.dsr.CENTER` (no unit warning), below
    2 GPa; delta in 1-89.9 deg; 1-2 binders, 1-3 specimens, 2-5 temperatures (integers in 0-80
    degC), 3-7 frequencies (0.1-100 rad/s on a 0.1-decade grid)."""
    from asphalt_nscd.lab.dsr import center_log10_G_Pa

    n_binders = draw(st.integers(1, 2))
    n_spec = draw(st.integers(1, 3))
    temps = sorted(draw(st.lists(st.integers(0, 80), min_size=2, max_size=5, unique=True)))
    logw = sorted(draw(st.lists(st.integers(-10, 20), min_size=3, max_size=7, unique=True)))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    rows = []
    for b in range(n_binders):
        offset = rng.uniform(-0.8, 0.8)
        for s in range(n_spec):
            for T in temps:
                for k in logw:
                    f = 10 ** (k / 10) / (2 * np.pi)
                    G = min(10 ** (float(center_log10_G_Pa(T, f)) + offset + rng.normal(0, 0.02)), 2e9)
                    rows.append((f"B{b + 1}", f"S{s + 1}", float(T), f, G, float(rng.uniform(1.0, 89.9))))
    truth = pd.DataFrame(rows, columns=["binder", "specimen", "temperature_C", "frequency_Hz", "G_Pa", "delta_deg"])
    g_unit = draw(st.sampled_from(sorted(_G_UNITS)))
    f_unit = draw(st.sampled_from(["Hz", "rad/s"]))
    t_unit = draw(st.sampled_from(["C", "F"]))
    p_unit = draw(st.sampled_from(["deg", "rad"]))
    form = draw(st.sampled_from(["norm_phase", "storage_loss"]))
    in_header = draw(st.booleans())
    scale = _G_UNITS[g_unit][0]
    w = truth["frequency_Hz"] * (2 * np.pi if f_unit == "rad/s" else 1.0)
    T = truth["temperature_C"] * 1.8 + 32 if t_unit == "F" else truth["temperature_C"]

    def head(name, unit):
        return f"{name} ({unit})" if in_header else name

    columns = {}
    if n_binders > 1:
        columns["Binder"] = truth["binder"]
    if n_spec > 1:
        columns["Replicate"] = truth["specimen"]
    columns[head("Temperature", {"C": "°C", "F": "°F"}[t_unit])] = T
    columns[head("Angular Frequency" if f_unit == "rad/s" else "Frequency", f_unit)] = w
    if form == "norm_phase":
        columns[head("Complex Modulus", g_unit)] = truth["G_Pa"] * scale
        d = np.radians(truth["delta_deg"]) if p_unit == "rad" else truth["delta_deg"]
        columns[head("Phase Angle", p_unit)] = d
    else:
        rad = np.radians(truth["delta_deg"])
        columns[head("Storage Modulus", g_unit)] = truth["G_Pa"] * scale * np.cos(rad)
        columns[head("Loss Modulus", g_unit)] = truth["G_Pa"] * scale * np.sin(rad)
    columns = {k: [repr(float(x)) if not isinstance(x, str) else x for x in v] for k, v in columns.items()}
    table = {}
    if not in_header:
        table = {"modulus_unit": g_unit, "frequency_unit": f_unit, "temperature_unit": t_unit, "modulus_form": form}
        if form == "norm_phase":
            table["phase_unit"] = p_unit
    if n_binders == 1:
        truth["binder"] = "sweep"
    return truth, columns, ({"table": table} if table else None)


#: ASTM E11 sieves (name, opening mm) a sieve analysis draws from
_SIEVES = [
    ("1 1/2 in", 37.5),
    ("1 in", 25.0),
    ("3/4 in", 19.0),
    ("1/2 in", 12.5),
    ("3/8 in", 9.5),
    ("No. 4", 4.75),
    ("No. 8", 2.36),
    ("No. 16", 1.18),
    ("No. 30", 0.6),
    ("No. 50", 0.3),
    ("No. 100", 0.15),
    ("No. 200", 0.075),
]


@st.composite
def sieve_analyses(draw) -> tuple[dict, str, dict]:
    """(passing, form, values): a cumulative gradation {opening mm: % passing} over 4-12 ASTM E11
    sieves with 100 % at the largest and the No. 200 sieve, and the same analysis written in
    ``form`` (passing, cumulative_retained or retained with a pan) as {sieve name: value}; names
    by US designation or opening in mm, drawn per sieve."""
    inner = draw(st.lists(st.sampled_from(_SIEVES[1:-1]), min_size=2, max_size=10, unique=True))
    chosen = sorted([_SIEVES[0], *inner, _SIEVES[-1]], key=lambda s: s[1])
    cuts = sorted(draw(st.lists(st.floats(0.5, 99.5), min_size=len(chosen) - 1, max_size=len(chosen) - 1)))
    values = [round(c, 1) for c in cuts] + [100.0]
    passing = {mm: p for (_, mm), p in zip(chosen, values)}
    form = draw(st.sampled_from(["passing", "cumulative_retained", "retained"]))
    names = [name if draw(st.booleans()) else f"{mm:g} mm" for name, mm in chosen]
    if form == "passing":
        out = dict(zip(names, values))
    elif form == "cumulative_retained":
        out = {n: 100.0 - v for n, v in zip(names, values)}
    else:
        nxt = values[1:] + [100.0]
        out = {n: b - a for n, a, b in zip(names, values, nxt)}
        out["Pan"] = values[0]
    return passing, form, out


@st.composite
def volumetric_reports(draw) -> tuple[dict, dict]:
    """(truth, report): a dense mix of natural aggregate (Pb 3.5-8 %, Gb 1.00-1.05, Gsb 2.4-2.75, Gse
    - Gsb 0-0.1, Va 2-10 %: Gmb below the 2.7 the forms without gravities assume) as ``Va, Vbeff, VMA, VFA, Pb, Gmm, Gmb, Gb, Gsb``, and one of the forms of
    :mod:`asphalt_nscd.lab.volumetrics` drawn from it (exact values)."""
    u = lambda lo, hi: draw(st.floats(lo, hi, allow_nan=False))
    Pb, Gb, Gsb, Va = u(3.5, 8.0), u(1.0, 1.05), u(2.4, 2.75), u(2.0, 10.0)
    Gse = Gsb + u(0.0, 0.1)
    Ps = 100.0 - Pb
    Gmm = 100.0 / (Ps / Gse + Pb / Gb)
    Gmb = Gmm * (1 - Va / 100)
    VMA = 100 - Gmb * Ps / Gsb
    truth = {"Va": Va, "VMA": VMA, "Vbeff": VMA - Va, "VFA": 100 * (VMA - Va) / VMA, "Pb": Pb}
    truth.update(Gmm=Gmm, Gmb=Gmb, Gb=Gb, Gsb=Gsb)
    forms = [
        ("Va", "Vbeff", "Pb"),
        ("VMA", "VFA", "Va"),
        ("VMA", "VFA", "Pb"),
        ("Pb", "Gmm", "Gmb", "Gb", "Gsb"),
        ("Va", "VMA"),
        ("Pb", "Gmm", "Va", "Gb", "Gsb"),
    ]
    keys = draw(st.sampled_from(forms))
    return truth, {k: truth[k] for k in keys}
