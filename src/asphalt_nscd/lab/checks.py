"""Physical plausibility of a measured complex-modulus table, checked where it is read.

:func:`check_values` looks at a table already in the project's columns and units (MPa, degC,
Hz, degrees; :mod:`.measured`) and either refuses it (:class:`asphalt_nscd.io.InputError`
naming the file, the line and what was expected) or returns warnings, for what cannot be
decided from the values alone. One implementation for every reader of a measured table.

Refused (outside any complex-modulus test of a bituminous material):

* a temperature outside -60 to 100 degC (AASHTO T 342 / T 378 and EN 12697-26 test from
  -10 to 54 degC; binders and mixes are tested between about -40 and 80 degC);
* a frequency outside 1e-4 to 1e4 Hz (servo-hydraulic machines test 0.01-100 Hz);
* |E*| outside 0.1 MPa to 1e5 MPa (a mix's glassy modulus is 30-45 GPa; no bituminous mix
  exceeds about 60 GPa), with the unit that would make the values plausible named.

Warned about (the run goes on, the warning reaches the console and the page):

* the stiffest cell of the isotherms at or below 10 degC below 5,000 MPa or above 60,000 MPa
  (a mix there is 10-40 GPa at 1-25 Hz): a unit off by 6.895 (ksi), 1,000 (GPa, kPa) or 145
  (psi) is named when declaring it instead brings the value into that range (a table of a
  binder, |G*|, is another possibility);
* phases that all lie below 1.6 while the isotherms span more than half a decade of |E*|:
  radians, not degrees;
* a hotter isotherm stiffer than a colder one at a common frequency by more than 10 % (a
  mixed-up temperature column, degF read as degC, a wrong sign);
* a phase above 60 degrees (a mix's phase peaks at 30-45 degrees; E1 and E2 swapped?).

Data-quality indicators (:func:`quality_flags`, :func:`quality_report`): a lab's table may
carry, per test, the data-quality statistics of AASHTO T 378 (PP 61) -- load standard error,
deformation standard error, deformation uniformity, phase uniformity -- as columns
``quality_<indicator>`` (a lab's own headers are mapped in the sidecar's ``table.quality``
block, :mod:`.table_format`). A row beyond a limit (:data:`LIMITS`, AASHTO T 378-17 as AMPT
software reports them: load and deformation standard errors <= 10 %, deformation uniformity
<= 30 %, phase uniformity <= 3 deg; or the sidecar's ``table.quality_limits``) is flagged:
reported, and the law is fitted with and without the flagged rows, both shown.

Sources of the ranges: docs/choices.md, Measured tables: plausibility and data quality.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError

#: (low, high, unit, what) of every refused range
REFUSED = {
    "temperature_C": (-60.0, 100.0, "degC", "the temperature of a complex-modulus test"),
    "frequency_Hz": (1e-4, 1e4, "Hz", "the frequency of a complex-modulus test"),
    "E_norm_MPa": (0.1, 1e5, "MPa", "|E*| of a bituminous material"),
}
#: the stiffest cell at or below COLD_C should lie in this range, MPa
COLD_C = 10.0
COLD_RANGE_MPA = (5000.0, 60000.0)


def _line(index) -> int:
    return int(index) + 2


def check_values(table: pd.DataFrame, path, units: str = "MPa", labels: dict | None = None) -> list[str]:
    """Refuse impossible values and return the warnings of a measured table (module
    docstring). ``table``: the project's columns, rows in file order (index = data row);
    ``units``: the declared modulus unit (named in the messages); ``labels``: the lab's
    description of a converted column (:func:`.table_format.to_own_columns`).

    Raises InputError naming the file, the line and the column of the first impossible value."""
    for col, (lo, hi, unit, what) in REFUSED.items():
        v = table[col].to_numpy(float)
        bad = np.flatnonzero((v < lo) | (v > hi))
        if bad.size:
            i = bad[0]
            hint = ""
            if col == "E_norm_MPa":
                hint = _unit_hint(table, float(table["E_norm_MPa"].max()), units)
            name = (labels or {}).get(col) or f"'{col}'"
            raise InputError(
                f"{path}: line {_line(table.index[i])}, column {name}: value {v[i]:g} {unit} out of "
                f"range; expected {what} in {lo:g}-{hi:g} {unit}{hint}"
            )
    warnings = []
    cold = table[table["temperature_C"] <= COLD_C]
    if len(cold):
        top = float(cold["E_norm_MPa"].max())
        lo, hi = COLD_RANGE_MPA
        if not lo <= top <= hi:
            warnings.append(
                f"{path}: the stiffest cell at or below {COLD_C:g} degC has |E*| = {top:,.0f} MPa (read as "
                f"{units}); an asphalt mix there is {lo:,.0f}-{hi:,.0f} MPa{_unit_hint(table, top, units)}"
            )
    P = table["phase_deg"].to_numpy(float)
    lnE = np.log(table["E_norm_MPa"].to_numpy(float))
    if P.max() < 1.6 and np.ptp(lnE) > np.log(10) / 2:
        warnings.append(
            f"{path}: every phase angle is below 1.6 (largest {P.max():.3g}) while |E*| spans "
            f"{np.ptp(lnE) / np.log(10):.2g} decades: the phases look like radians (x 57.3 for degrees)"
        )
    if P.max() > 60.0:
        i = int(np.argmax(P))
        warnings.append(
            f"{path}: line {_line(table.index[i])}: phase angle {P[i]:.3g} deg above 60 deg (a mix's phase "
            "peaks at 30-45 deg): E1 and E2 swapped, or not a mix?"
        )
    warnings += _monotonic(table, path)
    return warnings


def _unit_hint(table: pd.DataFrame, value: float, units: str) -> str:
    """``; the values fit a table in ksi (x 6.895)`` for the units that, declared instead of
    ``units``, bring ``value`` (MPa as read: the stiffest cold cell or an impossible one) into
    the plausible range."""
    from .table_format import MODULUS_UNITS

    lo, hi = COLD_RANGE_MPA
    f_d = MODULUS_UNITS.get(units, 1.0)
    fits = [
        f"{u} (x {f_u / f_d:.4g})" for u, f_u in MODULUS_UNITS.items() if u != units and lo <= value * f_u / f_d <= hi
    ]
    return f"; the values fit a table in {' or '.join(fits)}" if fits else ""


def _monotonic(table: pd.DataFrame, path) -> list[str]:
    """A hotter isotherm stiffer than a colder one by more than 10 % at a common frequency."""
    means = table.groupby(["frequency_Hz", "temperature_C"])["E_norm_MPa"].mean()
    out = []
    for f, g in means.groupby(level=0):
        e = g.droplevel(0).sort_index()
        r = e.to_numpy()[1:] / e.to_numpy()[:-1]
        k = np.flatnonzero(r > 1.1)
        if k.size:
            j = int(k[0])
            T = e.index.to_numpy(float)
            out.append(
                f"{path}: at {f:g} Hz the {T[j + 1]:g} degC isotherm is {r[j]:.3g} times stiffer than the "
                f"{T[j]:g} degC one (a mix softens as it warms): a mixed-up temperature column or unit?"
            )
            break
    return out


#: indicator -> (limit, unit): the AASHTO T 378 data-quality limits (module docstring), one per
#: indicator of :data:`asphalt_nscd.lab.table_format.QUALITY_INDICATORS`
LIMITS = {
    "load_standard_error_pct": (10.0, "%"),
    "deformation_standard_error_pct": (10.0, "%"),
    "deformation_uniformity_pct": (30.0, "%"),
    "phase_uniformity_deg": (3.0, "deg"),
}


def quality_columns(table: pd.DataFrame) -> list[str]:
    """The ``quality_<indicator>`` columns of a table."""
    return [c for c in table.columns if str(c).startswith("quality_")]


def quality_flags(table: pd.DataFrame, limits: dict | None = None) -> pd.DataFrame:
    """Per row of ``table``: ``flagged`` (bool) and ``reason`` (the indicators beyond their
    limits with their values). ``limits``: {indicator: limit} over :data:`LIMITS`; an
    indicator column without a limit is reported as unknown (not flagged).

    Returns a frame with the index of ``table``."""
    lim = {k: v[0] for k, v in LIMITS.items()} | dict(limits or {})
    reasons: list[list[str]] = [[] for _ in range(len(table))]
    for col in quality_columns(table):
        name = col.removeprefix("quality_")
        if name not in lim:
            continue
        v = pd.to_numeric(table[col], errors="coerce").to_numpy(float)
        for i in np.flatnonzero(np.isfinite(v) & (np.abs(v) > lim[name])):
            reasons[i].append(f"{name} {v[i]:.3g} > {lim[name]:g}")
    return pd.DataFrame(
        {"flagged": [bool(r) for r in reasons], "reason": ["; ".join(r) for r in reasons]}, index=table.index
    )


def quality_report(table: pd.DataFrame, limits: dict | None = None) -> dict:
    """What the page says of the quality indicators: ``columns``, ``limits``, ``n_rows``,
    ``n_flagged`` and ``flagged`` (specimen, temperature_C, frequency_Hz, reason per flagged
    row), or ``columns`` empty when the table has none."""
    cols = quality_columns(table)
    if not cols:
        return {"columns": [], "n_rows": int(len(table)), "n_flagged": 0, "flagged": []}
    flags = quality_flags(table, limits)
    rows = table[flags["flagged"].to_numpy()]
    lim = {k: v[0] for k, v in LIMITS.items()} | dict(limits or {})
    return {
        "columns": cols,
        "limits": {c.removeprefix("quality_"): lim.get(c.removeprefix("quality_")) for c in cols},
        "n_rows": int(len(table)),
        "n_flagged": int(flags["flagged"].sum()),
        "flagged": [
            {
                "specimen": str(r["specimen"]),
                "temperature_C": float(r["temperature_C"]),
                "frequency_Hz": float(r["frequency_Hz"]),
                "reason": flags.loc[i, "reason"],
            }
            for i, r in rows.iterrows()
        ],
    }
