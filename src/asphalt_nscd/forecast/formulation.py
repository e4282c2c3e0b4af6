"""A mix's formulation as the discrete model reads it: gradation curve, phase volumes, sample.

Gradation (:func:`passing_curve`)
---------------------------------
A matched table gives four points of the cumulative gradation (% passing by mass of
aggregate): 100 - rho34 at 19 mm, 100 - rho38 at 9.5 mm, 100 - rho4 at 4.75 mm and rho200 at
0.075 mm, and 100 % at the top size: 25 mm when rho34 > 0 (some aggregate is retained on
19 mm), else 19 mm. Between two points the curve is a power law, P = P_a (d / d_a)^n (linear
in log P against log d), the form of Fuller & Thompson's maximum-density curves (Fuller &
Thompson 1907, Trans. ASCE 59; Talbot's exponent n per segment); it is monotone by
construction and exact at the given sieves. Below 0.075 mm the last segment's exponent is
kept. The curve is read at the sieves of the paper's Table 1 series (EN 13043 basic set plus
set 2: :data:`SIEVES_MM`) and cut at ``cut_mm`` as the paper cuts (:mod:`asphalt_nscd.sample.psd`).

Phase volumes (:func:`phase_volumes`), per unit volume of mix
-------------------------------------------------------------
Aggregate 1 - VMA/100 (VMA = Va + Vbeff), split by mass fractions into coarse (above the cut),
fine (0.075 mm to the cut) and filler (below 0.075 mm): one specific gravity for every size (the
table gives none). Mastic = effective binder + filler; mortar = mastic + fine aggregate; the
discrete model's spheres are the coarse aggregate, its bonds the mortar, air voids in the
mortar. Filler volume fraction of the mastic phi_f = V_filler / (V_filler + Vbeff); fine
aggregate fraction of the mortar phi_s = V_fine / (V_fine + V_mastic).

The sample of a mix (:func:`sample_settings`)
--------------------------------------------
The preparation of Section 3.2.1 (:mod:`asphalt_nscd.sample.prepare`) with the mix's own
gradation above the cut, in a cube of side ``size_dmax`` times the largest sphere diameter
(the mixes were tested in uniaxial compression; a cube holds a given number of largest
particles across its width with far fewer spheres than the 2PB trapezoid), deposited in a box
of that footprint with a layer ``layer_over_side`` times the side, the trapezoid machinery
cutting the cube (B = b = e = h) at the layer's mid-height. Spheres then shrink to the mix's
coarse-aggregate volume fraction, or at least by the paper's 10 % of their volume
(:func:`asphalt_nscd.sample.prepare.finish`).

Sample variants (:func:`sample_variants`)
-----------------------------------------
The cut and the cube's size are modelling choices, not properties of the mix: the configured
pair (``forecast.dem.cut_mm``, ``size_dmax``) is the base sample, and ``forecast.dem.variants``
lists further pairs, each named ``cut<cut>_x<size>`` (:func:`variant_name`) and prepared for
every mix, so that the choice among them is made inside each fold (:mod:`.nested`).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pandas as pd

from ..io import InputError

#: sieve openings (mm) the gradation is read at: the paper's Table 1 series (EN 13043 basic set + set 2)
SIEVES_MM = (0.063, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0, 6.3, 8.0, 10.0, 12.5, 14.0, 16.0, 20.0, 25.0, 31.5)
#: the table's sieves: (opening mm, column, passing = 100 - value (retained) or value (passing))
TABLE_SIEVES = (
    (19.0, "rho34_pct", True),
    (9.5, "rho38_pct", True),
    (4.75, "rho4_pct", True),
    (0.075, "rho200_pct", False),
)


def variant_name(cut_mm: float, size_dmax: float) -> str:
    """The name of a sample variant: ``cut<cut_mm>_x<size_dmax>``, e.g. ``cut6.3_x2.5``."""
    return f"cut{float(cut_mm):g}_x{float(size_dmax):g}"


def sample_variants(dem: dict) -> dict[str, tuple[float, float]]:
    """name -> (cut_mm, size_dmax) of the further sample variants of ``forecast.dem`` (its
    ``variants`` list; the base pair ``cut_mm, size_dmax`` is not among them).

    Raises InputError when a variant lacks ``cut_mm`` or ``size_dmax`` or repeats the base or another."""
    base = variant_name(dem["cut_mm"], dem["size_dmax"])
    out: dict[str, tuple[float, float]] = {}
    for i, v in enumerate(dem.get("variants") or []):
        try:
            cut, size = float(v["cut_mm"]), float(v["size_dmax"])
        except (KeyError, TypeError, ValueError):
            raise InputError(
                f"forecast.dem.variants[{i}]: expected {{cut_mm: mm, size_dmax: ratio}}, got {v!r}"
            ) from None
        name = variant_name(cut, size)
        if name == base or name in out:
            raise InputError(f"forecast.dem.variants[{i}]: {name} repeats the base sample or another variant")
        out[name] = (cut, size)
    return out


def passing_points(mix: pd.Series) -> tuple[np.ndarray, np.ndarray]:
    """The measured points of a mix's cumulative gradation: sieve openings (mm, increasing)
    and % passing, with 100 % at the top size (module docstring); a mix with a ``gradation``
    entry (a full sieve analysis, ``"<mm>:<% passing>;..."``, :func:`gradation_text`) gives
    every sieve of that analysis instead of the table's four.

    Raises InputError when the points are not cumulative (passing falls as the sieve grows)."""
    text = mix.get("gradation") if hasattr(mix, "get") else None
    if isinstance(text, str) and text.strip():
        pts = {float(k): float(v) for k, v in (item.split(":") for item in text.split(";"))}
    else:
        pts = {d: (100.0 - float(mix[c]) if retained else float(mix[c])) for d, c, retained in TABLE_SIEVES}
        top = 25.0 if float(mix["rho34_pct"]) > 0 else 19.0
        pts[top] = 100.0
    d = np.array(sorted(pts))
    p = np.array([pts[k] for k in d])
    if np.any(np.diff(p) < 0) or p[0] <= 0:
        raise InputError(f"mix {mix.get('mix_id', '?')}: gradation points {dict(zip(d, p))} are not a cumulative curve")
    return d, p


def gradation_text(openings_mm, passing_pct) -> str:
    """A sieve analysis as the ``gradation`` entry of a mix (:func:`passing_points`): exact decimals."""
    return ";".join(f"{float(d)!r}:{float(p)!r}" for d, p in zip(openings_mm, passing_pct))


def passing_curve(mix: pd.Series, sieves=SIEVES_MM) -> dict[float, float]:
    """% passing at each of ``sieves`` (mm) by the piecewise power law through
    :func:`passing_points` (module docstring); 100 at and above the top size."""
    d, p = passing_points(mix)
    out = {}
    x, y = np.log(d), np.log(p)
    for s in sieves:
        if s >= d[-1]:
            out[float(s)] = 100.0
        elif s <= d[0]:
            n = (y[1] - y[0]) / (x[1] - x[0])
            out[float(s)] = float(np.exp(y[0] + n * (math.log(s) - x[0])))
        else:
            out[float(s)] = float(np.exp(np.interp(math.log(s), x, y)))
    return out


def phase_volumes(mix: pd.Series, cut_mm: float) -> dict:
    """Volume fractions of the mix (module docstring, per unit volume of mix, 0-1) and the
    mastic's and mortar's inclusion fractions.

    Returns
    -------
    dict: ``air, binder, aggregate, coarse, fine, filler, mastic, mortar`` (fractions of the mix),
    ``phi_filler`` (filler in mastic), ``phi_fine`` (fine aggregate in mortar), ``VMA_pct``,
    ``VFA_pct``, ``passing_at_cut_pct``.
    """
    Va, Vbeff = float(mix["Va_pct"]) / 100.0, float(mix["Vbeff_pct"]) / 100.0
    agg = 1.0 - Va - Vbeff
    p_cut = _passing_at(mix, cut_mm)
    p200 = float(mix["rho200_pct"])
    coarse = agg * (1.0 - p_cut / 100.0)
    fine = agg * max(p_cut - p200, 0.0) / 100.0
    filler = agg * p200 / 100.0
    mastic = Vbeff + filler
    return {
        "air": Va,
        "binder": Vbeff,
        "aggregate": agg,
        "coarse": coarse,
        "fine": fine,
        "filler": filler,
        "mastic": mastic,
        "mortar": mastic + fine,
        "phi_filler": filler / mastic,
        "phi_fine": fine / (fine + mastic),
        "VMA_pct": 100.0 * (Va + Vbeff),
        "VFA_pct": 100.0 * Vbeff / (Va + Vbeff),
        "passing_at_cut_pct": p_cut,
    }


def _passing_at(mix: pd.Series, size_mm: float) -> float:
    return passing_curve(mix, (float(size_mm),))[float(size_mm)]


def sample_settings(base: dict, mix: pd.Series, cut_mm: float, size_dmax: float, layer_over_side: float) -> tuple:
    """The sample section of a mix's preparation, its gradation and its target solid fraction.

    Parameters
    ----------
    base : the run's sample section merged over :data:`asphalt_nscd.sample.settings.DEFAULTS`
        (deposition, vibration, stabilisation, solver and densities are taken from it).
    mix : one row of the matched table (formulation columns). cut_mm : the PSD cut (mm).
    size_dmax : cube side / largest sphere diameter. layer_over_side : deposited layer height /
        cube side.

    Returns
    -------
    (cfg, passing, solid_fraction): the sample section (scale 1, the cube as B = b = e = h,
    ``psd.cut_mm``, layer height, lattice cell = the largest diameter, box height for the
    lattice), the % passing per sieve (:func:`passing_curve`), and the mix's coarse-aggregate
    volume fraction (:func:`phase_volumes`).

    Raises InputError when no sieve class lies above the cut.
    """
    from ..sample import psd

    passing = passing_curve(mix)
    cfg = copy.deepcopy(base)
    try:
        d, frac = psd.class_fractions(passing, cut_mm=cut_mm, class_diameter=cfg["psd"]["class_diameter"])
    except ValueError as exc:
        raise InputError(f"mix {mix.get('mix_id', '?')}: {exc}") from exc
    d_max_mm = float(d.max()) * 1e3
    side = size_dmax * d_max_mm
    cfg["scale"] = 1.0
    cfg["specimen"] = {"B_mm": side, "b_mm": side, "e_mm": side, "h_mm": side}
    cfg["psd"] = {**cfg["psd"], "cut_mm": float(cut_mm), "layer_height_mm": layer_over_side * side}
    cfg["lattice_mm"] = max(d_max_mm, 2.0 * float(cut_mm))
    volume = cfg["psd"]["solid_fraction"] * side * side * cfg["psd"]["layer_height_mm"] * 1e-9
    counts = psd.sphere_counts(volume, d, frac)
    cell = cfg["lattice_mm"] * 1e-3
    small = int(np.sum(counts[d <= 0.5 * cell]))
    items = int(np.sum(counts[d > 0.5 * cell])) + math.ceil(small / 8)
    per_layer = max(1, int(math.floor(side / cfg["lattice_mm"] + 1e-9))) ** 2
    cfg["box_height_mm"] = (math.ceil(items / per_layer) + 1) * cfg["lattice_mm"]
    cfg["sample_mass_kg"] = 2650.0 * side**3 * 1e-9 * (1.0 - phase_volumes(mix, cut_mm)["mortar"])
    cfg["top_plate_mass_kg"] = 0.1 * cfg["sample_mass_kg"]
    return cfg, passing, phase_volumes(mix, cut_mm)["coarse"]


#: Hveem surface-area factors, m^2/kg of aggregate per % passing (UFC 3-250-03, Table C-1; the Asphalt
#: Institute's MS-2 factors / 100), by sieve opening (mm); the largest sieve's factor applies to 100 % passing
SURFACE_AREA_FACTORS = {
    4.75: 0.00409,
    2.36: 0.00819,
    1.18: 0.01639,
    0.6: 0.02867,
    0.3: 0.06144,
    0.15: 0.12289,
    0.075: 0.32771,
}
#: the largest sieve's factor, m^2/kg per % passing (applied to its 100 %)
SURFACE_AREA_TOP = 0.00409
#: bulk specific gravity of the aggregate where the table gives none (a typical siliceous or limestone aggregate)
AGGREGATE_SPECIFIC_GRAVITY = 2.65


def surface_area_m2_kg(mix: pd.Series) -> float:
    """The aggregate's specific surface (m^2/kg) by Hveem's surface-area factors
    (:data:`SURFACE_AREA_FACTORS`) on the mix's passing curve (:func:`passing_curve`)."""
    passing = passing_curve(mix, tuple(SURFACE_AREA_FACTORS))
    return SURFACE_AREA_TOP * 100.0 + sum(f * passing[float(d)] for d, f in SURFACE_AREA_FACTORS.items())


def film_thickness_m(mix: pd.Series, specific_gravity: float = AGGREGATE_SPECIFIC_GRAVITY) -> float:
    """The mix's average binder film thickness (m): the effective binder volume over the aggregate's
    surface, T_F = V_be / (SA W) (Hveem; NCAT, "Asphalt film thickness debunked", Asphalt
    Technology News, spring 2017), per unit volume of mix: V_be = Vbeff / 100, W = (1 - VMA / 100)
    G_sb rho_w with G_sb = ``specific_gravity`` (the table gives none). Typical dense-graded
    mixes: 6-13 um (Kandhal & Chakraborty 1996, TRR 1535)."""
    v = phase_volumes(mix, 0.075)
    return float(v["binder"] / (surface_area_m2_kg(mix) * v["aggregate"] * specific_gravity * 1000.0))
