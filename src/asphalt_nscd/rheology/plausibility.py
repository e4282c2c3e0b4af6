"""Plausible ranges of the laws' parameters for asphalt mixes, and parameters at a fit bound.

A law can fit a table well with parameters no asphalt mix has (an activation energy of
321 kJ/mol with a vertical shift of 1.4 decades per 100 K; a 2S2P1D glassy modulus at the
200 GPa bound of its fit). :func:`check_parameters` compares fitted values with
:data:`PLAUSIBLE` (name: low, high, unit, source) and with the bounds of the fit that produced
them (:func:`at_bound`); the diagnosis reports both, and the law's selection takes an
implausible law over a plausible one only when its held-out gain exceeds the gain's own
uncertainty (:mod:`asphalt_nscd.diagnosis.crossval`).

Ranges (wider than the usual values, so that a value outside them is a finding, not a
preference; docs/choices.md, Extended law: plausible parameters):

* 2S2P1D (Olard & Di Benedetto 2003, Road Mater. Pavement Des. 4(2) 185-224, and the mixes
  of Mangiafico et al. 2015, Mater. Struct. 48: E0 28-45 GPa, E00 30-300 MPa, delta 1.5-3.5,
  k 0.15-0.25, h 0.5-0.7, beta 100-3000 on reported mixes): E0 15-60 GPa, E00 1-2000 MPa,
  delta 0.3-20, k 0.05-0.45, h 0.3-0.95, beta 1-1e7;
* shift: WLF C1 5-80 and C2 50-600 K at a reference temperature of a mix test (the universal
  constants 17.44 and 51.6 K of Williams, Landel & Ferry 1955 hold at the glass transition;
  mix fits at 10-25 degC report C1 20-35, C2 130-230 K); Arrhenius activation energy
  100-300 kJ/mol (SHRP binder model below the defining temperature: 261 kJ/mol, Christensen &
  Anderson 1992, J. Assoc. Asphalt Paving Technol. 61);
* the law's trends (:mod:`asphalt_nscd.rheology.extended`): a vertical shift within
  0.3 decade per 100 K (the density-temperature factor of Ferry's rule is about 0.04 decade
  per 100 K) and a static-modulus trend within 2 decades per 100 K.
"""

from __future__ import annotations

import numpy as np

#: name -> (low, high, unit, what the range rests on)
PLAUSIBLE = {
    "E0_MPa": (15e3, 60e3, "MPa", "glassy modulus of asphalt mixes (2S2P1D fits: 28-45 GPa)"),
    "E00_MPa": (1.0, 2000.0, "MPa", "static (long-time) modulus of mixes (2S2P1D fits: 30-300 MPa)"),
    "delta": (0.3, 20.0, "-", "2S2P1D delta of mixes (fits: 1.5-3.5)"),
    "k": (0.05, 0.45, "-", "2S2P1D exponent k of mixes (fits: 0.15-0.25)"),
    "h": (0.3, 0.95, "-", "2S2P1D exponent h of mixes (fits: 0.5-0.7)"),
    "beta": (1.0, 1e7, "-", "2S2P1D beta of mixes (fits: 100-3000)"),
    "C1": (5.0, 80.0, "-", "WLF C1 of mixes at 10-25 degC (fits: 20-35)"),
    "C2_K": (50.0, 600.0, "K", "WLF C2 of mixes at 10-25 degC (fits: 130-230 K)"),
    "Ea_kJ_mol": (100.0, 300.0, "kJ/mol", "apparent activation energy (SHRP binder model: 261 kJ/mol)"),
    "vertical_trend_per_100K": (-0.3, 0.3, "decade / 100 K", "vertical shift (density factor ~0.04 decade / 100 K)"),
    "static_trend_per_100K": (-2.0, 2.0, "decade / 100 K", "trend of the static modulus with temperature"),
}
#: a value within this fraction of its bound's range from a bound is at the bound
AT_BOUND_FRACTION = 1e-4


def check_value(name: str, value: float) -> dict | None:
    """The finding for one parameter (``name, value, low, high, unit, source, finding``
    = ``implausible``), or None if it lies inside :data:`PLAUSIBLE` or has no range there."""
    if name not in PLAUSIBLE or not np.isfinite(value):
        return None
    lo, hi, unit, source = PLAUSIBLE[name]
    if lo <= value <= hi:
        return None
    return {
        "name": name,
        "value": float(value),
        "low": lo,
        "high": hi,
        "unit": unit,
        "source": source,
        "finding": "implausible",
    }


def at_bound(names, x, lower, upper, fixed=()) -> list[dict]:
    """Parameters of a fit at one of its box bounds (within :data:`AT_BOUND_FRACTION` of the
    range): ``name, value, bound`` (low | high), ``finding`` = ``at bound``. ``fixed``: names
    held at their value (not fitted), skipped."""
    out = []
    for n, v, lo, hi in zip(names, np.asarray(x, float), np.asarray(lower, float), np.asarray(upper, float)):
        if n in fixed or not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
            continue
        tol = AT_BOUND_FRACTION * (hi - lo)
        if v <= lo + tol or v >= hi - tol:
            out.append(
                {
                    "name": n,
                    "value": float(v),
                    "bound": "low" if v <= lo + tol else "high",
                    "low": float(lo),
                    "high": float(hi),
                    "finding": "at bound",
                }
            )
    return out


def check_parameters(values: dict, bounds: dict | None = None) -> list[dict]:
    """Findings of a law's natural parameters ``values`` ({name: value}, the names of
    :data:`PLAUSIBLE`) and, given ``bounds`` ({fit parameter name: (value, low, high)}), of
    its fit parameters at a bound."""
    found = [f for f in (check_value(n, v) for n, v in values.items()) if f is not None]
    if bounds:
        names = list(bounds)
        vals, lo, hi = (np.array([bounds[n][i] for n in names], float) for i in range(3))
        found += at_bound(names, vals, lo, hi)
    return found


def describe(findings: list[dict]) -> str:
    """One line per finding, for the page and the console."""
    parts = []
    for f in findings:
        if f["finding"] == "at bound":
            parts.append(
                f"{f['name']} = {f['value']:.6g} at the {f['bound']} bound of its fit [{f['low']:.6g}, {f['high']:.6g}]"
            )
        else:
            parts.append(
                f"{f['name']} = {f['value']:.4g} {f['unit']} outside the plausible "
                f"{f['low']:.4g}-{f['high']:.4g} ({f['source']})"
            )
    return "; ".join(parts)
