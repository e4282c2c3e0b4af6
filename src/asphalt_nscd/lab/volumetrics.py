"""A mix's volumetrics in the forms a lab reports them, to air voids, effective binder, VMA and VFA.

Keys (any consistent subset; % by volume of mix unless said): ``Va`` (air voids), ``Vbeff``
(effective binder), ``VMA``, ``VFA`` (% of VMA), ``Pb`` (binder, % by mass of mix), ``Gmm``,
``Gmb``, ``Gb``, ``Gsb`` (specific gravities of the loose mix, compacted mix, binder and aggregate
bulk). Forms: (a) Va with Vbeff (and Pb); (b) VMA with VFA (and Va or Pb); (c) Pb with Gmm, Gmb, Gb,
Gsb; any two of Va, Vbeff, VMA, VFA, alone or beside the specific gravities, also do.

Relations (Asphalt Institute MS-2, 7th ed., ch. 5; AASHTO R 35; checked against the MS-2
reproductions of the volumetric chapter, e.g. transcalc.com "ASPHALT MIX DESIGN" MS-2 pages):
    Va = 100 (1 - Gmb/Gmm);  VMA = 100 - Gmb Ps/Gsb  (Ps = 100 - Pb);
    Gse = (100 - Pb) / (100/Gmm - Pb/Gb);  Pba = 100 Gb (Gse - Gsb) / (Gsb Gse)  (% of aggregate);
    Pbe = Pb - Pba Ps/100;  Vbeff = Pbe Gmb/Gb;  VFA = 100 (VMA - Va)/VMA = 100 Vbeff/VMA.
They imply VMA = Va + Vbeff exactly. Every relation whose inputs are known is applied (also Gmb =
Gmm (1 - Va/100) and Gmb = (100 - VMA) Gsb/Ps); a quantity obtained twice must agree within
:data:`TOLERANCES`: the rounding of a lab report (gravities to 0.001, Pb, Va, VMA, Vbeff to 0.1 %,
VFA to 1 %) moves the quantities derived from the gravities by up to Va 0.09, VMA 0.12, Vbeff 0.12,
VFA 0.8 and Gse 0.004 over 3,000 dense mixes (:func:`rounding_spread`), and a chain of reported
percentages (VMA against Va + Vbeff) by up to 0.15: volumes agree within 0.2, VFA within 1.5.

Refused (:class:`asphalt_nscd.io.InputError` naming the place, the key and what was expected): an
unknown key or a value that is not a number; a form that gives neither Va nor Vbeff; two values of
one quantity that disagree; Va or Vbeff outside (0, 30) %, Pb outside (0, 20) % (the matched
tables' ranges); VFA outside [0, 100]; VMA <= Va; a specific gravity outside :data:`G_RANGES`; Gse
below Gsb by more than :data:`GSE_TOL` (negative absorption: 5 times the rounding effect,
room for the repeatability of the Gmm and Gsb tests); Vbeff larger than the binder volume Pb can fill, Pb Gmb/Gb (+
the Vbeff tolerance), with Gmb given or derived, else bounded by :data:`GMB_BOUND` and Gb by
:data:`GB_BOUND` when not given (dense mixes of natural aggregate: Gmb 2.2-2.6; binders: Gb
1.00-1.05).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..io import InputError

#: key -> (meaning, unit) of a volumetric report
KEYS = {
    "Va": ("air voids", "% of mix volume"),
    "Vbeff": ("effective binder volume", "% of mix volume"),
    "VMA": ("voids in the mineral aggregate", "% of mix volume"),
    "VFA": ("voids filled with binder", "% of VMA"),
    "Pb": ("binder content", "% of mix mass"),
    "Gmm": ("maximum specific gravity of the mix", "-"),
    "Gmb": ("bulk specific gravity of the compacted mix", "-"),
    "Gb": ("specific gravity of the binder", "-"),
    "Gsb": ("bulk specific gravity of the aggregate", "-"),
}
#: other names of the keys (the project's matched-table columns and common report names)
ALIASES = {
    "Va_pct": "Va",
    "VTM": "Va",
    "Vbe": "Vbeff",
    "Vbeff_pct": "Vbeff",
    "VMA_pct": "VMA",
    "VFB": "VFA",
    "VFA_pct": "VFA",
    "Pb_pct": "Pb",
}
#: largest disagreement of two values of one quantity (module docstring)
TOLERANCES = {"Va": 0.2, "Vbeff": 0.2, "VMA": 0.2, "VFA": 1.5, "Gmm": 0.006, "Gmb": 0.006}
#: Gse may fall below Gsb by this much before the absorption is refused as negative
GSE_TOL = 0.02
#: (low, high) of the percentages (refused outside; open intervals but VFA)
PCT_RANGES = {"Va": (0.0, 30.0), "Vbeff": (0.0, 30.0), "Pb": (0.0, 20.0), "VMA": (0.0, 60.0), "VFA": (0.0, 100.0)}
#: (low, high) of the specific gravities: binders 1.00-1.05 (MS-2 uses 1.030); aggregates 2.4-3.0, slags
#: up to about 3.5; a mix lies between its binder and its aggregate
G_RANGES = {"Gb": (0.9, 1.2), "Gsb": (1.5, 4.0), "Gmm": (1.5, 4.0), "Gmb": (1.2, 4.0), "Gse": (1.5, 4.5)}
#: bounds used when Gmb or Gb is not known, for Vbeff <= Pb Gmb / Gb
GMB_BOUND = 2.7
GB_BOUND = 1.0


@dataclass(frozen=True)
class Volumetrics:
    """A mix's volumetrics (module docstring): percentages as named, specific gravities
    dimensionless, None where the report does not determine them. ``derived``: quantity -> how it
    was obtained (``given`` or the relation and its inputs)."""

    Va_pct: float
    Vbeff_pct: float
    VMA_pct: float
    VFA_pct: float
    Pb_pct: float | None = None
    Gmm: float | None = None
    Gmb: float | None = None
    Gb: float | None = None
    Gsb: float | None = None
    Gse: float | None = None
    Pba_pct: float | None = None
    Pbe_pct: float | None = None
    derived: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """``Va_pct, Vbeff_pct, Pb_pct, VMA_pct, VFA_pct`` (Pb None when not derivable)."""
        return {
            "Va_pct": self.Va_pct,
            "Vbeff_pct": self.Vbeff_pct,
            "Pb_pct": self.Pb_pct,
            "VMA_pct": self.VMA_pct,
            "VFA_pct": self.VFA_pct,
        }


def _relations():
    """(output, inputs, function, text) in the order they are tried: measured gravities first."""
    return (
        ("Va", ("Gmm", "Gmb"), lambda v: 100.0 * (1.0 - v["Gmb"] / v["Gmm"]), "Va = 100 (1 - Gmb/Gmm)"),
        ("Gmb", ("Gmm", "Va"), lambda v: v["Gmm"] * (1.0 - v["Va"] / 100.0), "Gmb = Gmm (1 - Va/100)"),
        ("Gmm", ("Gmb", "Va"), lambda v: v["Gmb"] / (1.0 - v["Va"] / 100.0), "Gmm = Gmb / (1 - Va/100)"),
        (
            "VMA",
            ("Gmb", "Gsb", "Pb"),
            lambda v: 100.0 - v["Gmb"] * (100.0 - v["Pb"]) / v["Gsb"],
            "VMA = 100 - Gmb Ps/Gsb",
        ),
        (
            "Gmb",
            ("VMA", "Gsb", "Pb"),
            lambda v: (100.0 - v["VMA"]) * v["Gsb"] / (100.0 - v["Pb"]),
            "Gmb = (100 - VMA) Gsb/Ps",
        ),
        ("Gse", ("Gmm", "Pb", "Gb"), _gse, "Gse = (100 - Pb)/(100/Gmm - Pb/Gb)"),
        ("Pba", ("Gse", "Gsb", "Gb"), lambda v: 100.0 * v["Gb"] * (v["Gse"] - v["Gsb"]) / (v["Gsb"] * v["Gse"]), "Pba"),
        ("Pbe", ("Pb", "Pba"), lambda v: v["Pb"] - v["Pba"] * (100.0 - v["Pb"]) / 100.0, "Pbe = Pb - Pba Ps/100"),
        ("Vbeff", ("Pbe", "Gmb", "Gb"), lambda v: v["Pbe"] * v["Gmb"] / v["Gb"], "Vbeff = Pbe Gmb/Gb"),
        ("VMA", ("Va", "Vbeff"), lambda v: v["Va"] + v["Vbeff"], "VMA = Va + Vbeff"),
        ("Vbeff", ("VMA", "Va"), lambda v: v["VMA"] - v["Va"], "Vbeff = VMA - Va"),
        ("Va", ("VMA", "Vbeff"), lambda v: v["VMA"] - v["Vbeff"], "Va = VMA - Vbeff"),
        ("Vbeff", ("VMA", "VFA"), lambda v: v["VFA"] * v["VMA"] / 100.0, "Vbeff = VFA VMA/100"),
        ("Va", ("VMA", "VFA"), lambda v: v["VMA"] * (1.0 - v["VFA"] / 100.0), "Va = VMA (1 - VFA/100)"),
        ("VMA", ("Va", "VFA"), _vma_from_va_vfa, "VMA = Va/(1 - VFA/100)"),
        ("VMA", ("Vbeff", "VFA"), _vma_from_vbeff_vfa, "VMA = 100 Vbeff/VFA"),
        ("VFA", ("Vbeff", "VMA"), lambda v: 100.0 * v["Vbeff"] / v["VMA"], "VFA = 100 Vbeff/VMA"),
    )


def _gse(v):
    den = 100.0 / v["Gmm"] - v["Pb"] / v["Gb"]
    return (100.0 - v["Pb"]) / den if den > 0 else math.nan


def _vma_from_va_vfa(v):
    return v["Va"] / (1.0 - v["VFA"] / 100.0) if v["VFA"] < 100.0 else math.nan


def _vma_from_vbeff_vfa(v):
    return 100.0 * v["Vbeff"] / v["VFA"] if v["VFA"] > 0.0 else math.nan


def convert(values, where: str) -> Volumetrics:
    """The volumetrics of a lab's report (module docstring).

    Parameters
    ----------
    values : mapping
        Keys of :data:`KEYS` (or :data:`ALIASES`) -> numbers (%, or dimensionless gravities).
    where : str
        The place of the report (e.g. ``"mix.yaml: mix '211': key 'volumetrics'"``), named by
        every message with the key (``where.Va``).

    Returns
    -------
    Volumetrics

    Raises
    ------
    InputError
        module docstring ("Refused"), naming ``where``, the key and what was expected.
    """
    if not hasattr(values, "items"):
        raise InputError(f"{where}: expected a mapping of {list(KEYS)}, got {type(values).__name__}")
    given: dict[str, float] = {}
    for key, raw in values.items():
        name = ALIASES.get(str(key), str(key))
        if name not in KEYS:
            raise InputError(f"{_at(where, key)}: unknown key; expected some of {list(KEYS)}")
        if name in given:
            raise InputError(f"{_at(where, key)}: {name} given twice")
        if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
            raise InputError(
                f"{_at(where, key)}: {raw!r} is not a finite number; expected the {KEYS[name][0]} ({KEYS[name][1]})"
            )
        given[name] = float(raw)
    for key, v in given.items():
        if key in G_RANGES:
            lo, hi = G_RANGES[key]
            if not lo <= v <= hi:
                raise InputError(f"{_at(where, key)}: {v:g} out of range; expected the {KEYS[key][0]} in {lo:g}-{hi:g}")
        else:
            _check_pct(where, key, v, "given")
    if "VMA" in given and "Va" in given and given["VMA"] <= given["Va"]:
        raise InputError(
            f"{_at(where, 'VMA')}: VMA {given['VMA']:.4g} % <= Va {given['Va']:.4g} %: no room for binder; expected VMA > Va"
        )
    known = dict(given)
    how = {k: "given" for k in given}
    changed = True
    while changed:
        changed = False
        for out, inputs, fn, text in _relations():
            if not all(k in known for k in inputs):
                continue
            value = fn(known)
            source = f"{text} from {', '.join(inputs)}"
            if not math.isfinite(value):
                raise InputError(f"{where}: {out} cannot be computed by {source}: the values contradict each other")
            if out in known:
                tol = TOLERANCES.get(out)
                if tol is not None and abs(value - known[out]) > tol:
                    raise InputError(
                        f"{_at(where, _key_of(out, given))}: {out} = {known[out]:.4g} ({how[out]}) but {source} gives "
                        f"{value:.4g}; expected agreement within {tol:g}"
                    )
                continue
            known[out], how[out] = value, source
            changed = True
            if out in PCT_RANGES:
                _check_pct(where, out, value, source)
            elif out in G_RANGES:
                lo, hi = G_RANGES[out]
                if not lo <= value <= hi:
                    raise InputError(f"{where}: {out} = {value:.4g} by {source}: out of range {lo:g}-{hi:g}")
    if "Va" not in known or "Vbeff" not in known:
        raise InputError(
            f"{where}: the air voids and the effective binder volume cannot be determined from {sorted(given)}; give "
            "Va with Vbeff (and Pb), VMA with VFA (and Va or Pb), or Pb with Gmm, Gmb, Gb and Gsb"
        )
    if known["VMA"] <= known["Va"]:
        raise InputError(
            f"{_at(where, _key_of('VMA', given))}: VMA {known['VMA']:.4g} % <= Va {known['Va']:.4g} %: no binder"
        )
    if "Gse" in known and "Gsb" in known and known["Gse"] < known["Gsb"] - GSE_TOL:
        raise InputError(
            f"{_at(where, 'Gsb')}: Gse = {known['Gse']:.4f} (from Gmm, Pb, Gb) is below Gsb = {known['Gsb']:.4f} by more than "
            f"{GSE_TOL:g}: a negative binder absorption; expected Gse >= Gsb (check Gmm, Gsb, Pb)"
        )
    _check_fill(where, known, how, given)
    return Volumetrics(
        Va_pct=known["Va"],
        Vbeff_pct=known["Vbeff"],
        VMA_pct=known["VMA"],
        VFA_pct=known["VFA"],
        Pb_pct=known.get("Pb"),
        Gmm=known.get("Gmm"),
        Gmb=known.get("Gmb"),
        Gb=known.get("Gb"),
        Gsb=known.get("Gsb"),
        Gse=known.get("Gse"),
        Pba_pct=known.get("Pba"),
        Pbe_pct=known.get("Pbe"),
        derived=how,
    )


def _at(where: str, key: str) -> str:
    """``where`` with ``key`` appended to its key: ``"f: key 'volumetrics'"`` -> ``"f: key 'volumetrics.Va'"``."""
    return f"{where[:-1]}.{key}'" if where.endswith("'") else f"{where}.{key}"


def _key_of(name: str, given: dict) -> str:
    return name if name in given else f"{name} (derived)"


def _check_pct(where: str, key: str, v: float, how: str) -> None:
    lo, hi = PCT_RANGES[key]
    ok = lo <= v <= hi if key == "VFA" else lo < v < hi
    if not ok:
        bracket = f"[{lo:g}, {hi:g}]" if key == "VFA" else f"({lo:g}, {hi:g})"
        origin = "" if how == "given" else f" (by {how})"
        raise InputError(
            f"{_at(where, key)}: {v:.4g}{origin} out of range; expected the {KEYS[key][0]} in {bracket} ({KEYS[key][1]})"
        )


def binder_volume_bound(Pb_pct, Gmb: float | None = None, Gb: float | None = None):
    """The largest effective binder volume (% of mix) a binder content Pb (% of mix mass; a float
    or an array, returned in that shape) can fill: the whole binder volume Pb Gmb/Gb, with Gmb <=
    :data:`GMB_BOUND` and Gb >= :data:`GB_BOUND` when not known (module docstring)."""
    return Pb_pct * (GMB_BOUND if Gmb is None else Gmb) / (GB_BOUND if Gb is None else Gb)


def _check_fill(where: str, known: dict, how: dict, given: dict) -> None:
    if "Pb" not in known:
        return
    Gmb, Gb = known.get("Gmb"), known.get("Gb")
    bound = binder_volume_bound(known["Pb"], Gmb, Gb)
    if known["Vbeff"] > bound + TOLERANCES["Vbeff"]:
        estimate = (
            f"Gmb {Gmb:.4g} ({how['Gmb']})" if Gmb is not None else f"Gmb <= {GMB_BOUND:g} (not given; give Gmb or Gmm)"
        ) + (f", Gb {Gb:.4g}" if Gb is not None else f", Gb >= {GB_BOUND:g} (not given)")
        raise InputError(
            f"{_at(where, _key_of('Vbeff', given))}: Vbeff {known['Vbeff']:.4g} % is more binder than Pb {known['Pb']:.4g} % "
            f"can fill: expected Vbeff <= Pb Gmb/Gb = {bound:.4g} % with {estimate}"
        )


def rounding_spread(n: int = 2000, seed: int = 0) -> dict:
    """Largest disagreement (quantity -> value) between a lab's rounded report of Va, VMA, Vbeff
    (to 0.1 %) and VFA (to 1 %) and the same quantities derived from its specific gravities rounded
    to 0.001 and Pb to 0.1 %, over ``n`` dense mixes drawn uniformly (Pb 4-7 %, Gb 1.00-1.05, Gsb
    2.50-2.90, Gse - Gsb 0-0.15, Va 3-8 %; seeded by ``seed``): the evidence of
    :data:`TOLERANCES`."""
    import numpy as np

    rng = np.random.default_rng(seed)
    worst = {"Va": 0.0, "VMA": 0.0, "Vbeff": 0.0, "VFA": 0.0, "Gse": 0.0}
    for _ in range(n):
        Pb, Gb, Gsb = rng.uniform(4.0, 7.0), rng.uniform(1.0, 1.05), rng.uniform(2.5, 2.9)
        Gse, Va = Gsb + rng.uniform(0.0, 0.15), rng.uniform(3.0, 8.0)
        Gmm = 100.0 / ((100.0 - Pb) / Gse + Pb / Gb)
        exact = {"Pb": Pb, "Gmm": Gmm, "Gmb": Gmm * (1.0 - Va / 100.0), "Gb": Gb, "Gsb": Gsb}
        true = convert(exact, "rounding_spread")
        rounded = {k: round(v, 1 if k == "Pb" else 3) for k, v in exact.items()}
        lab = convert(rounded, "rounding_spread")
        report: dict[str, float] = {"Va": round(true.Va_pct, 1), "VMA": round(true.VMA_pct, 1)}
        report.update(Vbeff=round(true.Vbeff_pct, 1), VFA=float(round(true.VFA_pct)), Gse=float(true.Gse or 0.0))
        derived = {"Va": lab.Va_pct, "VMA": lab.VMA_pct, "Vbeff": lab.Vbeff_pct, "VFA": lab.VFA_pct}
        derived["Gse"] = float(lab.Gse or 0.0)
        for k in worst:
            worst[k] = max(worst[k], abs(derived[k] - report[k]))
    return worst
