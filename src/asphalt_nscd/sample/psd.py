"""Particle size distribution (Table 1) to sphere counts per diameter (Table 2).

Counting rule (our reading of Section 3.2.1; the paper does not spell it out)
-----------------------------------------------------------------------------
1. Table 1 gives the percentage passing each sieve. The mass fraction of a class is the
   difference between two consecutive sieves, e.g. 10-12.5 mm: 100 - 90 = 10 %.
2. The curve is cut at ``cut_mm`` (paper: 2 mm): classes below it belong to the mastic and
   are dropped; the kept fractions are renormalised to 1 (aggregates share one density,
   so mass fractions are volume fractions).
3. A class is represented by one sphere diameter, by default its *lower* sieve
   (``class_diameter: lower``): the classes 2-4, 4-6.3, 6.3-8, 8-10, 10-12.5 mm give the
   five diameters 2, 4, 6.3, 8, 10 mm of Table 2. ``upper`` and ``geometric_mean`` are
   offered as alternatives.
4. The total sphere volume is ``solid_fraction x layer volume`` with the layer of the paper
   (box footprint 250 x 25 mm, final height 60 mm) and ``solid_fraction = 0.70`` (a dense
   polydisperse packing after vibration). Class i gets
   ``N_i = round(solid_volume * f_i / (pi d_i^3 / 6))`` spheres.

With these choices the counts are 11807 / 1589 / 494 / 213 / 73 against the paper's
11798 / 1588 / 492 / 211 / 71 (Table 2): within 0.1 % for the two small classes and
+0.4 / +1.0 / +2.8 % for the 6.3, 8 and 10 mm classes. No single volume reproduces
Table 2 exactly: the volume implied by each class of Table 2 decreases from the small to the
large classes (7260 ... 7100 mm^3 per % of mass), so the paper must have rounded or
trimmed the large classes in a way it does not describe.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas

#: Table 1: sieve opening (mm) -> percentage passing.
TABLE1_PASSING = {
    12.5: 100.0,
    10.0: 90.0,
    8.0: 75.0,
    6.3: 58.0,
    4.0: 44.0,
    2.0: 31.0,
    1.0: 20.0,
    0.5: 15.0,
    0.25: 12.0,
    0.125: 9.0,
    0.063: 6.5,
}

#: Table 2: sphere diameter (mm) -> number of spheres in the paper's samples.
TABLE2_COUNTS = {2.0: 11798, 4.0: 1588, 6.3: 492, 8.0: 211, 10.0: 71}

CLASS_DIAMETERS = ("lower", "upper", "geometric_mean")


def class_fractions(
    passing: dict[float, float] | None = None,
    cut_mm: float = 2.0,
    class_diameter: str = "lower",
) -> tuple[np.ndarray, np.ndarray]:
    """Class diameters and renormalised mass fractions of the PSD cut at ``cut_mm``.

    Parameters
    ----------
    passing
        sieve opening (mm) -> % passing; Table 1 when None.
    cut_mm
        smallest sieve kept (mm); classes whose lower sieve is below it are dropped.
    class_diameter
        ``lower`` (paper's Table 2), ``upper`` or ``geometric_mean`` of the class sieves.

    Returns
    -------
    diameter_m : ndarray (K,)
        one diameter per kept class (m), increasing.
    fraction : ndarray (K,)
        mass (= volume) fractions of the kept classes, summing to 1.

    Raises
    ------
    ValueError
        if no class is kept, the curve is not non-decreasing, or ``class_diameter`` is unknown.
    """
    passing = TABLE1_PASSING if passing is None else passing
    if class_diameter not in CLASS_DIAMETERS:
        raise ValueError(f"class_diameter must be one of {CLASS_DIAMETERS}, got {class_diameter!r}")
    sieves = np.array(sorted(passing), dtype=float)
    pct = np.array([passing[s] for s in sieves], dtype=float)
    if np.any(np.diff(pct) < 0):
        raise ValueError("percentage passing must not decrease with the sieve opening")
    lower, upper = sieves[:-1], sieves[1:]
    frac = pct[1:] - pct[:-1]
    keep = (lower >= cut_mm * (1 - 1e-9)) & (frac > 0)
    if not keep.any():
        raise ValueError(f"no PSD class with lower sieve >= cut {cut_mm} mm")
    lower, upper, frac = lower[keep], upper[keep], frac[keep]
    d_mm = {"lower": lower, "upper": upper, "geometric_mean": np.sqrt(lower * upper)}[class_diameter]
    return d_mm * 1e-3, frac / frac.sum()


def sphere_counts(solid_volume_m3: float, diameter_m, fraction) -> np.ndarray:
    """Number of spheres per class so that class i fills ``fraction[i]`` of the solid volume.

    ``N_i = round(V_s f_i / (pi d_i^3 / 6))``.

    Parameters
    ----------
    solid_volume_m3
        total sphere volume (m^3).
    diameter_m, fraction : array_like (K,)
        class diameters (m) and volume fractions (sum 1).

    Returns
    -------
    ndarray of int (K,)

    Raises
    ------
    ValueError
        if the volume is not positive.
    """
    if not solid_volume_m3 > 0:
        raise ValueError(f"solid volume must be > 0, got {solid_volume_m3}")
    d = np.asarray(diameter_m, dtype=float)
    f = np.asarray(fraction, dtype=float)
    return np.rint(solid_volume_m3 * f / (np.pi * d**3 / 6.0)).astype(np.int64)


def table2_comparison(diameter_m, counts) -> pandas.DataFrame:
    """Our counts beside Table 2: columns ``diameter_mm, n_ours, n_paper, rel_diff_pct``.

    Classes absent on one side get NaN on that side.
    """
    import pandas as pd

    ours = {round(float(d) * 1e3, 3): int(n) for d, n in zip(diameter_m, counts)}
    keys = sorted(set(ours) | set(TABLE2_COUNTS))
    rows = []
    for d in keys:
        n_o = ours.get(d, np.nan)
        n_p = TABLE2_COUNTS.get(d, np.nan)
        rows.append(
            {
                "diameter_mm": d,
                "n_ours": n_o,
                "n_paper": n_p,
                "rel_diff_pct": 100.0 * (n_o - n_p) / n_p if np.isfinite(n_o) and np.isfinite(n_p) else np.nan,
            }
        )
    return pd.DataFrame(rows)
