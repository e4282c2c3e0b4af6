"""Binder DSR frequency sweeps as a binder lab writes them (AASHTO T 315 / EN 14770 long layouts).

One row per measured point: temperature, frequency and |G*| with the phase angle delta
(``norm_phase``) or the storage and loss moduli G', G'' (``storage_loss``: |G*| = hypot(G', G''),
delta = atan2(G'', G')); optionally a specimen (replicate) column and a binder column (a file of
several binders). Any temperatures and frequencies; units |G*| Pa, kPa, MPa, GPa, psi or ksi,
frequency Hz or rad/s, delta deg or rad, temperature C or F. Headers are found by their common
names (:data:`ALIASES`: ``Temperature (°C)``, ``Angular Frequency (rad/s)``, ``Complex Modulus |G*|
(kPa)``, ``Phase Angle (°)``, ``G' (Pa)``, ``G'' (Pa)``, ``Storage Modulus [Pa]``, ``lane``...), the
unit written in a header (``(kPa)``, ``[1/s]``, ``_Pa``) is read, and anything else is declared in
the ``table`` block of the sidecar ``<stem>.test.json`` as for the lab tables (:mod:`.table_format`,
:mod:`.matched`): ``modulus_unit``, ``temperature_unit``, ``frequency_unit``, ``phase_unit``,
``modulus_form``, ``columns`` ({quantity: header}). A declared unit that contradicts the header's is
refused; a modulus or frequency whose unit neither gives is refused (a bare "Frequency" could be Hz
or rad/s); temperature and phase default to C and degrees. The sidecar may also give each binder's
PG grade and viscosity (``binder`` for a one-binder file, its ``id`` naming it, else the file stem;
``binders`` keyed by the file's binder ids; :data:`SIDECAR_SCHEMA`).

Checks (:class:`asphalt_nscd.io.InputError` naming the file, line and column): a value that is not a
number; a temperature or frequency no binder test uses (:data:`asphalt_nscd.lab.checks.REFUSED`);
delta outside (0, 90] deg, or every delta below 1.6 read as degrees (radians); |G*| outside a
binder's 0.1 Pa - 3 GPa (:data:`asphalt_nscd.lab.matched.BINDER_G_RANGE_MPA`); a repeated (binder,
specimen, temperature, frequency); a binder with fewer than 2 temperatures or an isotherm with fewer
than 3 frequencies; temperatures that do not fall into isotherms (points of one isotherm lie within
:data:`ISOTHERM_TOL_C`). Warned (the lab tables' mechanism: ``attrs["warnings"]`` and the
``asphalt_nscd`` logger): a binder whose |G*| lies more than :data:`UNIT_BAND_DECADES` decades (median
over its points) from a typical binder at its temperatures and frequencies, log10 |G*| (Pa) =
:data:`CENTER` (a + b T + c log10 w, capped at a glassy 1 GPa), naming the units that bring it within
the band ("the values fit kPa (x 1000)"). The centre is the least-squares fit over the 10 FHWA
binders of data/measured/tfhrc_ptf_binder_dsr (10-82 degC) and the 16 binders of data/binder_mix
(-10-54 degC); their per-binder median residuals lie in -0.89..+0.16 decades. A 1,000-fold unit
slip (Pa, kPa, MPa) is caught; psi against kPa (x 6.9) is not.

Replicates (``replicates="mean"``): one point per (binder, isotherm, frequency), |G*| the geometric
and delta the arithmetic mean of its specimens, ``n_specimens`` their number; ``"keep"`` keeps every
specimen's rows (column ``specimen``). An isotherm's temperature is the mean of its points'.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError
from .matched import BINDER_FREQUENCY_UNITS, BINDER_G_RANGE_MPA, PHASE_UNITS, VISCOSITY_RANGE_PA_S, VISCOSITY_UNITS
from .table_format import MODULUS_UNITS, TEMPERATURE_UNITS

#: Pa per unit of |G*|, G', G''
MODULUS_UNITS_PA = {"Pa": 1.0, **{u: f * 1e6 for u, f in MODULUS_UNITS.items()}}
#: Hz per unit of frequency
FREQUENCY_UNITS = dict(BINDER_FREQUENCY_UNITS)
FORMS = ("norm_phase", "storage_loss")
QUANTITIES = ("binder", "specimen", "temperature", "frequency", "modulus", "phase", "storage", "loss")
#: the project's own column of a quantity (read without a declaration)
OWN_COLUMNS = {
    "binder": "binder",
    "specimen": "specimen",
    "temperature": "temperature_C",
    "frequency": "frequency_Hz",
    "modulus": "G_Pa",
    "phase": "delta_deg",
}
#: common header names (a header reduced: lower case, unit dropped, |G*| -> absgstar, G' -> gprime,
#: G'' -> gdoubleprime, then letters and digits only)
ALIASES = {
    "binder": ["binder", "binderid", "bindername", "bindercode", "asphaltbinder", "material", "materialid"],
    "specimen": ["specimen", "specimenid", "replicate", "rep", "replicateno", "run", "sample", "sampleid"],
    "temperature": ["temperature", "temp", "t", "testtemperature"],
    "frequency": ["angularfrequency", "angfrequency", "omega", "frequency", "freq", "f", "testfrequency"],
    "modulus": [
        "complexmodulus",
        "complexshearmodulus",
        "complexmodulusabsgstar",
        "complexmodulusgstar",
        "complexshearmodulusgstar",
        "absgstar",
        "gstar",
        "gnorm",
        "dynamicshearmodulus",
        "shearmodulus",
        "modulus",
    ],
    "phase": ["phaseangle", "phaseangledelta", "phase", "delta", "phaseshiftangle", "phaseshift", "lossangle"],
    "storage": ["storagemodulus", "storagemodulusgprime", "storageshearmodulus", "gprime", "g1", "gstorage"],
    "loss": ["lossmodulus", "lossmodulusgdoubleprime", "lossshearmodulus", "gdoubleprime", "g2", "gloss"],
}
#: unit text of a header (lower case, spaces and dots removed) -> (quantity kind, unit)
HEADER_UNITS = {
    **{u.lower(): ("modulus", u) for u in MODULUS_UNITS_PA},
    "c": ("temperature", "C"),
    "°c": ("temperature", "C"),
    "degc": ("temperature", "C"),
    "f": ("temperature", "F"),
    "°f": ("temperature", "F"),
    "degf": ("temperature", "F"),
    "hz": ("frequency", "Hz"),
    "rad/s": ("frequency", "rad/s"),
    "rads": ("frequency", "rad/s"),
    "rad/sec": ("frequency", "rad/s"),
    "1/s": ("frequency", "rad/s"),
    "s-1": ("frequency", "rad/s"),
    "rads-1": ("frequency", "rad/s"),
    "°": ("phase", "deg"),
    "deg": ("phase", "deg"),
    "degree": ("phase", "deg"),
    "degrees": ("phase", "deg"),
    "rad": ("phase", "rad"),
}
#: quantity -> the kind of unit it takes
UNIT_KIND = {"temperature": "temperature", "frequency": "frequency", "modulus": "modulus", "storage": "modulus"}
UNIT_KIND.update(loss="modulus", phase="phase")
#: points of one isotherm lie within this of each other, degC (a DSR holds its set point to 0.1 degC)
ISOTHERM_TOL_C = 0.5
MIN_TEMPERATURES = 2
MIN_FREQUENCIES = 3
#: (a, b, c) of the typical binder's log10 |G*| (Pa) = a + b T(degC) + c log10 w(rad/s) (module docstring)
CENTER = (7.20, -0.0599, 0.780)
GLASSY_LOG10_PA = 9.0
UNIT_BAND_DECADES = 1.5
#: output columns (mean replicates)
COLUMNS = ("binder", "temperature_C", "frequency_Hz", "G_Pa", "delta_deg", "eta_Pa_s", "n_specimens")
SUFFIXES = (".csv", ".tsv", ".txt")

_VISCOSITY = {
    "type": "object",
    "properties": {
        "unit": {"enum": list(VISCOSITY_UNITS)},
        "temperature_unit": {"enum": list(TEMPERATURE_UNITS)},
        "values": {"type": "object", "minProperties": 1, "additionalProperties": {"type": "number"}},
    },
    "required": ["unit", "values"],
    "additionalProperties": False,
    "description": "viscosity per temperature: {temperature: viscosity}",
}
_BINDER: dict = {
    "type": "object",
    "properties": {"pg_grade": {"type": "string"}, "viscosity": _VISCOSITY},
    "additionalProperties": False,
}
#: JSON schema of a DSR sweep's sidecar (``<stem>.test.json``)
SIDECAR_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "Sidecar of a binder DSR frequency sweep",
    "type": "object",
    "properties": {
        "test": {"enum": ["dsr_frequency_sweep"]},
        "description": {"type": "string"},
        "source": {"type": "string"},
        "plate_diameter_mm": {"type": "number", "exclusiveMinimum": 0},
        "gap_mm": {"type": "number", "exclusiveMinimum": 0},
        "table": {
            "type": "object",
            "properties": {
                "modulus_unit": {"enum": list(MODULUS_UNITS_PA)},
                "temperature_unit": {"enum": list(TEMPERATURE_UNITS)},
                "frequency_unit": {"enum": list(FREQUENCY_UNITS)},
                "phase_unit": {"enum": list(PHASE_UNITS)},
                "modulus_form": {"enum": list(FORMS)},
                "columns": {
                    "type": "object",
                    "propertyNames": {"enum": list(QUANTITIES)},
                    "additionalProperties": {"type": "string"},
                },
            },
            "additionalProperties": False,
        },
        "binder": {**_BINDER, "properties": {**_BINDER["properties"], "id": {"type": "string", "minLength": 1}}},
        "binders": {"type": "object", "additionalProperties": _BINDER},
    },
    "additionalProperties": False,
    "not": {"required": ["binder", "binders"]},
}


@dataclass(frozen=True)
class BinderInfo:
    """What a sweep's sidecar or a mix file says of one binder besides its sweep.

    ``pg_high_C``, ``pg_low_C``: its PG grade (degC) or None; ``viscosity``: DataFrame
    ``temperature_C, eta_Pa_s`` (degC, Pa s; temperatures increasing), empty if not given;
    ``where``: where they came from."""

    binder: str
    pg_high_C: float | None = None
    pg_low_C: float | None = None
    viscosity: pd.DataFrame = field(default_factory=lambda: pd.DataFrame(columns=["temperature_C", "eta_Pa_s"]))
    where: str = ""


def parse_pg_grade(text, where: str) -> tuple[float, float]:
    """(high, low) temperatures (degC) of a performance grade written ``"PG 64-22"`` (also
    ``"PG64-22"``, ``"64-22"``, ``"PG 64E-22"``: AASHTO M 320 / M 332).

    Raises InputError naming ``where``: not a grade, or a high temperature outside 40-100 degC or a
    low one outside -50-0 degC."""
    m = re.fullmatch(r"\s*(?:PG\s*)?(\d{2,3})\s*[SHVE]?\s*-\s*(\d{1,2})\s*", str(text), flags=re.IGNORECASE)
    if not m:
        raise InputError(f"{where}: {text!r} is not a performance grade; expected e.g. 'PG 64-22'")
    high, low = float(m.group(1)), -float(m.group(2))
    if not (40.0 <= high <= 100.0 and -50.0 <= low <= 0.0):
        raise InputError(
            f"{where}: grade {text!r}: expected a high temperature in 40-100 degC and a low one in -50-0 degC"
        )
    return high, low


def read_viscosity(obj, where: str) -> pd.DataFrame:
    """A binder's viscosity per temperature from ``{"unit": "Pa s" | "cP" | "P", "temperature_unit":
    "C" | "F" (default C), "values": {temperature: viscosity}}``.

    Returns
    -------
    DataFrame ``temperature_C, eta_Pa_s`` (degC, Pa s), temperatures increasing.

    Raises
    ------
    InputError
        naming ``where`` and the key: a temperature or viscosity that is not a number, a temperature
        given twice, a viscosity outside :data:`asphalt_nscd.lab.matched.VISCOSITY_RANGE_PA_S`, or a
        viscosity that does not fall as the temperature rises.
    """
    from .sieve import validate

    validate(obj, _VISCOSITY, where.rsplit(": key ", 1)[0], _prefix(where))
    unit, tu = obj["unit"], obj.get("temperature_unit", "C")
    rows = []
    for key, value in obj["values"].items():
        place = _join(where, f"values.{key}")
        try:
            T = float(key)
        except (TypeError, ValueError):
            raise InputError(f"{place}: not a temperature; expected a number (in {tu})") from None
        if not math.isfinite(T) or isinstance(value, bool) or not math.isfinite(float(value)):
            raise InputError(f"{place}: expected a finite temperature and viscosity")
        T_C = round((T - 32.0) / 1.8, 9) if tu == "F" else T
        eta = float(value) * VISCOSITY_UNITS[unit]
        lo, hi = VISCOSITY_RANGE_PA_S
        if not lo <= eta <= hi:
            raise InputError(
                f"{place}: {value:g} {unit} ({eta:.3g} Pa s) out of range; expected a binder viscosity "
                f"in {lo:g}-{hi:g} Pa s (asphalt_nscd.lab.matched.VISCOSITY_RANGE_PA_S)"
            )
        rows.append((T_C, eta, key))
    rows.sort()
    for a, b in zip(rows, rows[1:]):
        if abs(a[0] - b[0]) <= ISOTHERM_TOL_C:
            raise InputError(
                f"{_join(where, 'values')}: temperatures {a[2]} and {b[2]} are one temperature given twice"
            )
        if b[1] >= a[1]:
            raise InputError(
                f"{_join(where, 'values')}: the viscosity at {b[2]} ({b[1]:.3g} Pa s) is not below the one at {a[2]} "
                f"({a[1]:.3g} Pa s): a binder thins as it warms"
            )
    return pd.DataFrame({"temperature_C": [r[0] for r in rows], "eta_Pa_s": [r[1] for r in rows]})


def _prefix(where: str) -> str:
    """``"key 'binder.viscosity'"`` of a place ``"<file>: key 'binder.viscosity'"`` as a prefix."""
    m = re.search(r": key '([^']*)'$", where)
    return f"{m.group(1)}." if m else ""


def binder_info(binder: str, obj: dict | None, where: str) -> BinderInfo:
    """A :class:`BinderInfo` from a ``{"pg_grade": ..., "viscosity": ...}`` block at ``where`` (a
    place ``"<file>: key '<path>'"``); an empty one for None.

    Raises InputError as :func:`parse_pg_grade` and :func:`read_viscosity`."""
    if not obj:
        return BinderInfo(binder, where=where)
    high = low = None
    if obj.get("pg_grade") is not None:
        high, low = parse_pg_grade(obj["pg_grade"], _join(where, "pg_grade"))
    visc = BinderInfo(binder).viscosity
    if obj.get("viscosity") is not None:
        visc = read_viscosity(obj["viscosity"], _join(where, "viscosity"))
    return BinderInfo(binder, high, low, visc, where)


def _join(where: str, key: str) -> str:
    m = re.search(r"^(.*): key '([^']*)'$", where)
    return f"{m.group(1)}: key '{m.group(2)}.{key}'" if m else f"{where}: key '{key}'"


def with_viscosity(points: pd.DataFrame, viscosity: pd.DataFrame) -> pd.DataFrame:
    """``points`` (:func:`read_dsr`) with ``eta_Pa_s`` set on the rows whose isotherm lies within
    :data:`ISOTHERM_TOL_C` of a viscosity temperature (NaN elsewhere); a viscosity at a temperature
    the sweep lacks is not placed on any row."""
    out = points.copy()
    eta = np.full(len(out), np.nan)
    T = out["temperature_C"].to_numpy(float)
    for t, e in zip(viscosity["temperature_C"].to_numpy(float), viscosity["eta_Pa_s"].to_numpy(float)):
        eta[np.abs(T - t) <= ISOTHERM_TOL_C] = e
    out["eta_Pa_s"] = eta
    return out


def center_log10_G_Pa(temperature_C, frequency_Hz) -> np.ndarray:
    """log10 |G*| (Pa) of a typical binder (:data:`CENTER`, capped smoothly at a glassy 1 GPa) at
    temperatures (degC) and frequencies (Hz) broadcast together."""
    a, b, c = CENTER
    lin = a + b * np.asarray(temperature_C, float) + c * np.log10(2.0 * np.pi * np.asarray(frequency_Hz, float))
    return -np.logaddexp(-lin * np.log(10.0), -GLASSY_LOG10_PA * np.log(10.0)) / np.log(10.0)


def _split_header(header: str) -> tuple[str, str | None]:
    """(reduced name, unit text or None) of a header: ``"Complex Modulus |G*| (kPa)"`` ->
    ``("complexmodulusabsgstar", "kpa")``; ``"angular_frequency_rad_s"`` -> ``("angularfrequency", "rad/s")``."""
    h = str(header).strip()
    unit = None
    m = re.fullmatch(r"(.*?)[\s_]*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*", h)
    if m and m.group(1):
        h, unit = m.group(1), m.group(2)
    else:
        tokens = h.split("_")
        for n in (2, 1):
            if len(tokens) > n:
                tail = "/".join(tokens[-n:]) if n == 2 else tokens[-1]
                if _unit_text(tail) in HEADER_UNITS or (n == 2 and _unit_text(" ".join(tokens[-n:])) in HEADER_UNITS):
                    h, unit = "_".join(tokens[:-n]), tail
                    break
    s = h.lower()
    for old, new in (("|g*|", "absgstar"), ("g*", "gstar"), ("g''", "gdoubleprime"), ('g"', "gdoubleprime")):
        s = s.replace(old, new)
    for old, new in (("g″", "gdoubleprime"), ("g'", "gprime"), ("g′", "gprime"), ("δ", "delta"), ("ω", "omega")):
        s = s.replace(old, new)
    return re.sub(r"[^a-z0-9]", "", s), (None if unit is None else _unit_text(unit))


def _unit_text(text: str) -> str:
    return re.sub(r"[\s.·_]", "", str(text).strip().lower()).replace("deg°", "°")


@dataclass
class DsrFormat:
    """The ``table`` block of a DSR sweep's sidecar (module docstring); None: not declared."""

    modulus_unit: str | None = None
    temperature_unit: str | None = None
    frequency_unit: str | None = None
    phase_unit: str | None = None
    modulus_form: str | None = None
    columns: dict = field(default_factory=dict)
    where: str = "no sidecar"


def _read_sidecar(path: Path, explicit) -> tuple[dict, DsrFormat]:
    from ..io import read_json
    from .geometry import sidecar_path
    from .sieve import validate

    side = Path(explicit) if explicit is not None else sidecar_path(path)
    if not side.is_file():
        if explicit is not None:
            raise InputError(f"{side}: file not found (the sidecar of {path})")
        return {}, DsrFormat(where=f"no sidecar {side.name}")
    obj = read_json(side, what="sidecar JSON")
    validate(obj, SIDECAR_SCHEMA, str(side))
    return obj, DsrFormat(**obj.get("table", {}), where=str(side))


def read_dsr(path, sidecar=None, *, replicates: str = "mean") -> pd.DataFrame:
    """Read, convert and check a binder DSR frequency-sweep file (module docstring).

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.tsv`` or ``.txt``, one row per measured point.
    sidecar : str or Path, optional
        Its declaration; default ``<stem>.test.json`` beside it, if present.
    replicates : ``"mean"`` (default) or ``"keep"``
        One row per (binder, temperature, frequency), or one per specimen's point.

    Returns
    -------
    DataFrame
        ``binder`` (str), ``temperature_C`` (degC), ``frequency_Hz`` (Hz), ``G_Pa`` (|G*|, Pa),
        ``delta_deg`` (degrees), ``eta_Pa_s`` (Pa s at the isotherm's temperature, NaN unless
        given), and ``n_specimens`` (mean) or ``specimen`` (keep); binders in file order, then
        temperature and frequency increasing. ``attrs``: ``binders`` ({binder: :class:`BinderInfo`}),
        ``warnings`` (list of str), ``source`` ({``table``, ``declaration``}), ``units`` (the units
        read), ``dropped_columns``.

    Raises
    ------
    InputError
        naming the file, the line and the column, or the sidecar and its key (module docstring).
    """
    from .matched import _number
    from .measured import _read_text_table

    if replicates not in ("mean", "keep"):
        raise ValueError(f"replicates={replicates!r}: expected 'mean' or 'keep'")
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(f"{path}: expected a {'/'.join(SUFFIXES)} file, got suffix '{path.suffix}'")
    side, fmt = _read_sidecar(path, sidecar)
    frame = _read_text_table(path, allowed_suffixes=SUFFIXES)
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows after the header")
    found, units = _columns(path, frame, fmt)
    form = fmt.modulus_form or ("norm_phase" if {"modulus", "phase"} <= set(found) else "storage_loss")
    needed = ["temperature", "frequency"] + (["modulus", "phase"] if form == "norm_phase" else ["storage", "loss"])
    missing = [q for q in needed if q not in found]
    if missing:
        raise InputError(
            f"{path}: line 1 (header): no column for the {', '.join(missing)} ({form}) in {list(frame.columns)}; "
            f"name them as a DSR export does (e.g. {', '.join(repr(ALIASES[q][0]) for q in missing)}) or map them in "
            f"key 'table.columns' of {fmt.where if fmt.where != 'no sidecar' else 'the sidecar <stem>.test.json'}"
        )
    for q in needed:
        kind = UNIT_KIND[q]
        if units.get(kind) is None:
            raise InputError(
                f"{path}: column '{found[q]}': its unit is neither in the header nor declared; declare "
                f"'table.{kind}_unit' ({' | '.join(_UNIT_CHOICES[kind])}) in the sidecar"
            )
    labels = {q: f"'{c}'" for q, c in found.items()}
    out = pd.DataFrame(index=frame.index)
    single = (side.get("binder") or {}).get("id") or path.stem
    out["binder"] = _text(path, frame, found.get("binder"), default=single)
    out["specimen"] = _text(path, frame, found.get("specimen"), default="")
    T = _number(path, frame, found["temperature"], f"a temperature in {units['temperature']}")
    out["temperature_C"] = np.round((T - 32.0) / 1.8, 9) if units["temperature"] == "F" else T
    f = _number(path, frame, found["frequency"], f"a frequency in {units['frequency']}")
    out["frequency_Hz"] = f * FREQUENCY_UNITS[units["frequency"]]
    scale = MODULUS_UNITS_PA[units["modulus"]]
    if form == "norm_phase":
        out["G_Pa"] = _number(path, frame, found["modulus"], f"|G*| in {units['modulus']}") * scale
        d = _number(path, frame, found["phase"], f"a phase angle in {units['phase']}")
        out["delta_deg"] = d * PHASE_UNITS[units["phase"]]
        d_label = labels["phase"]
    else:
        G1 = _number(path, frame, found["storage"], f"G' in {units['modulus']}") * scale
        G2 = _number(path, frame, found["loss"], f"G'' in {units['modulus']}") * scale
        out["G_Pa"], out["delta_deg"] = np.hypot(G1, G2), np.degrees(np.arctan2(G2, G1))
        labels["modulus"] = f"'{found['storage']}' and '{found['loss']}'"
        d_label = labels["modulus"]
    _check_values(path, out, labels, d_label, units, form)
    out["temperature_C"] = _isotherms(path, out, labels)
    _check_duplicates(path, out)
    _check_grid(path, out)
    warnings = _unit_warnings(path, out, labels, units["modulus"])
    for text in warnings:
        logging.getLogger("asphalt_nscd").warning("%s", text)
    binders = list(dict.fromkeys(out["binder"]))
    infos = _binder_infos(side, fmt.where, binders, single)
    rows = out if replicates == "keep" else _mean(out)
    order = {b: k for k, b in enumerate(binders)}
    rows = (
        rows.assign(_b=rows["binder"].map(order))
        .sort_values(["_b", "temperature_C", "frequency_Hz"] + (["specimen"] if replicates == "keep" else []))
        .drop(columns="_b")
        .reset_index(drop=True)
    )
    pieces = [with_viscosity(g, infos[b].viscosity) for b, g in rows.groupby("binder", sort=False)]
    rows = pd.concat(pieces).reset_index(drop=True)
    cols = ["binder", "temperature_C", "frequency_Hz", "G_Pa", "delta_deg", "eta_Pa_s"]
    rows = rows[cols + (["specimen"] if replicates == "keep" else ["n_specimens"])]
    rows.attrs.update(
        binders=infos,
        warnings=list(warnings),
        source={"table": str(path), "declaration": fmt.where},
        units=dict(units, form=form),
        dropped_columns=[c for c in frame.columns if c not in found.values()],
    )
    return rows


_UNIT_CHOICES = {
    "modulus": list(MODULUS_UNITS_PA),
    "temperature": list(TEMPERATURE_UNITS),
    "frequency": list(FREQUENCY_UNITS),
    "phase": list(PHASE_UNITS),
}


def _columns(path: Path, frame: pd.DataFrame, fmt: DsrFormat) -> tuple[dict, dict]:
    """(quantity -> header, unit kind -> unit) of a sweep file: declared, own, or by alias; the
    units from the declaration and the headers (a contradiction refused)."""
    reduced = {h: _split_header(h) for h in frame.columns}
    found: dict[str, str] = {}
    for q in QUANTITIES:
        if q in fmt.columns:
            if fmt.columns[q] not in frame.columns:
                raise InputError(
                    f"{fmt.where}: key 'table.columns.{q}': column {fmt.columns[q]!r} is not in the header "
                    f"{list(frame.columns)}"
                )
            found[q] = fmt.columns[q]
            continue
        if OWN_COLUMNS.get(q) in frame.columns:
            found[q] = OWN_COLUMNS[q]
            continue
        keys = {}
        for h in reversed(list(frame.columns)):
            keys[reduced[h][0]] = h
        hit = next((keys[a] for a in ALIASES[q] if a in keys), None)
        if hit is not None and hit not in found.values():
            found[q] = hit
    seen: dict[str, str] = {}
    for q, c in found.items():
        if c in seen:
            raise InputError(f"{path}: column '{c}' is mapped to both the {seen[c]} and the {q}; one column each")
        seen[c] = q
    declared = {
        "modulus": fmt.modulus_unit,
        "temperature": fmt.temperature_unit,
        "frequency": fmt.frequency_unit,
        "phase": fmt.phase_unit,
    }
    units: dict[str, str | None] = {}
    unknown: dict[str, tuple] = {}
    for q, c in found.items():
        kind = UNIT_KIND.get(q)
        if kind is None:
            continue
        text = reduced[c][1]
        named = None
        if text is not None:
            hit = HEADER_UNITS.get(text)
            if hit is not None and hit[0] != kind:
                raise InputError(
                    f"{path}: column '{c}' names {hit[1]}, a {hit[0]} unit, for the {q}; expected "
                    f"{' | '.join(_UNIT_CHOICES[kind])} (or a column mapped in key 'table.columns' of the sidecar)"
                )
            if hit is None:
                unknown[kind] = (c, text)
            else:
                named = hit[1]
        if declared[kind] is not None and named is not None and named != declared[kind]:
            raise InputError(
                f"{path}: column '{c}' names the unit {named}, but {fmt.where} key 'table.{kind}_unit' declares "
                f"{declared[kind]}; declare the column's unit (or map another column)"
            )
        if units.get(kind) is not None and named is not None and named != units[kind]:
            raise InputError(f"{path}: columns of one {kind} in two units ({units[kind]} and {named}, column '{c}')")
        units[kind] = declared[kind] or named or units.get(kind)
    if units.get("frequency") is None and "frequency" in found:
        key = reduced[found["frequency"]][0]
        if "angular" in key or key == "omega":
            units["frequency"] = "rad/s"
    for kind in ("modulus", "temperature", "frequency", "phase"):
        if units.get(kind) is None and kind in unknown:
            c, text = unknown[kind]
            raise InputError(
                f"{path}: column '{c}': {text!r} in its header is not a {kind} unit ({' | '.join(_UNIT_CHOICES[kind])}); "
                f"declare 'table.{kind}_unit' in the sidecar"
            )
    units["temperature"] = units.get("temperature") or "C"
    units["phase"] = units.get("phase") or "deg"
    return found, units


def _text(path: Path, frame: pd.DataFrame, col: str | None, default: str) -> np.ndarray:
    if col is None:
        return np.full(len(frame), default, dtype=object)
    v = frame[col].str.strip()
    empty = np.flatnonzero((v == "").to_numpy())
    if empty.size:
        raise InputError(f"{path}: line {int(empty[0]) + 2}, column '{col}': empty cell; expected an identifier")
    return v.to_numpy(dtype=object)


def _check_values(path: Path, out: pd.DataFrame, labels: dict, d_label: str, units: dict, form: str) -> None:
    from .checks import REFUSED

    def fail(col, label, ok, expected):
        bad = np.flatnonzero(~ok)
        if bad.size:
            i = int(bad[0])
            raise InputError(
                f"{path}: line {i + 2}, column {label}: value {out[col].iloc[i]:g} out of range; expected {expected}"
            )

    for col, q in (("temperature_C", "temperature"), ("frequency_Hz", "frequency")):
        lo, hi, unit, what = REFUSED[col]
        v = out[col].to_numpy(float)
        fail(col, labels[q], (v >= lo) & (v <= hi), f"{what} in {lo:g}-{hi:g} {unit} (read as {units[q]})")
    d = out["delta_deg"].to_numpy(float)
    if form == "norm_phase" and units["phase"] == "deg" and d.size > 1 and d.max() < 1.6:
        raise InputError(
            f"{path}: column {d_label}: every phase angle is below 1.6 (largest {d.max():.3g}, read as degrees): "
            "radians? Declare 'table.phase_unit': 'rad' in the sidecar (or write the unit in the header)"
        )
    fail("delta_deg", d_label, (d > 0.0) & (d <= 90.0 + 1e-6), "a phase angle delta in (0, 90] degrees")
    G = out["G_Pa"].to_numpy(float)
    lo, hi = (x * 1e6 for x in BINDER_G_RANGE_MPA)
    bad = np.flatnonzero(~((G >= lo) & (G <= hi)))
    if bad.size:
        i = int(bad[0])
        hint = ""
        if G[i] > 0:
            T_i, f_i = out["temperature_C"].iloc[i], out["frequency_Hz"].iloc[i]
            hint = _fits(np.array([np.log10(G[i]) - center_log10_G_Pa(T_i, f_i)]), units["modulus"])
        raise InputError(
            f"{path}: line {i + 2}, column {labels['modulus']}: |G*| {G[i]:.4g} Pa out of range; expected a binder's "
            f"{lo:g}-{hi:g} Pa (read as {units['modulus']}){hint}"
        )


def _fits(residuals: np.ndarray, declared: str) -> str:
    """``"; the values fit kPa (x 1000)"``: the units that, declared instead of ``declared``, bring the
    median of ``residuals`` (decades from :data:`CENTER`) within :data:`UNIT_BAND_DECADES`."""
    med = float(np.median(residuals))
    f_d = MODULUS_UNITS_PA[declared]
    fits = [
        f"{u} (x {f_u / f_d:.4g})"
        for u, f_u in MODULUS_UNITS_PA.items()
        if u != declared and abs(med + math.log10(f_u / f_d)) <= UNIT_BAND_DECADES
    ]
    return f"; the values fit {' or '.join(fits)}" if fits else ""


def _isotherms(path: Path, out: pd.DataFrame, labels: dict) -> np.ndarray:
    """Each point's isotherm temperature (the mean of the isotherm's points), per binder."""
    T = out["temperature_C"].to_numpy(float).copy()
    for _, idx in out.groupby("binder", sort=False).indices.items():
        values = np.unique(T[idx])
        start = 0
        for k in range(1, len(values) + 1):
            if k == len(values) or values[k] - values[k - 1] > ISOTHERM_TOL_C:
                group = values[start:k]
                if group[-1] - group[0] > ISOTHERM_TOL_C:
                    i = int(idx[np.flatnonzero(np.isin(T[idx], group))[-1]])
                    raise InputError(
                        f"{path}: line {i + 2}, column {labels['temperature']}: temperatures from {group[0]:g} to "
                        f"{group[-1]:g} degC do not fall into isotherms {ISOTHERM_TOL_C:g} degC wide"
                    )
                if group.size > 1:
                    members = idx[np.isin(T[idx], group)]
                    T[members] = float(np.mean(out["temperature_C"].to_numpy(float)[members]))
                start = k
    return T


def _check_duplicates(path: Path, out: pd.DataFrame) -> None:
    key = ["binder", "specimen", "temperature_C", "frequency_Hz"]
    dup = np.flatnonzero(out.duplicated(subset=key, keep=False).to_numpy())
    if dup.size:
        r = out.iloc[dup[0]]
        same = dup[(out.iloc[dup][key] == r[key]).all(axis=1).to_numpy()]
        spec = f", specimen {r['specimen']!r}" if r["specimen"] else ""
        raise InputError(
            f"{path}: lines {', '.join(str(int(i) + 2) for i in same)}: repeated point (binder {r['binder']!r}{spec}, "
            f"{r['temperature_C']:g} degC, {r['frequency_Hz']:g} Hz); give replicates a specimen column"
        )


def _check_grid(path: Path, out: pd.DataFrame) -> None:
    for b, g in out.groupby("binder", sort=False):
        counts = g.groupby("temperature_C")["frequency_Hz"].nunique()
        if counts.size < MIN_TEMPERATURES:
            raise InputError(
                f"{path}: binder {b!r} is tested at {counts.size} temperature(s) ({', '.join(f'{t:g}' for t in counts.index)} "
                f"degC); a master curve needs {MIN_TEMPERATURES} or more"
            )
        few = counts[counts < MIN_FREQUENCIES]
        if few.size:
            T = few.index[0]
            rows = g.index[g["temperature_C"] == T]
            raise InputError(
                f"{path}: lines {int(rows[0]) + 2}-{int(rows[-1]) + 2}: binder {b!r} at {T:g} degC has {int(few.iloc[0])} "
                f"frequency(ies); an isotherm needs {MIN_FREQUENCIES} or more"
            )


def _unit_warnings(path: Path, out: pd.DataFrame, labels: dict, declared: str) -> list[str]:
    warned = []
    for b, g in out.groupby("binder", sort=False):
        r = np.log10(g["G_Pa"].to_numpy(float)) - center_log10_G_Pa(g["temperature_C"], g["frequency_Hz"])
        med = float(np.median(r))
        if abs(med) > UNIT_BAND_DECADES:
            warned.append(
                f"{path}: column {labels['modulus']}: binder {b!r}: |G*| read as {declared} lies {med:+.2g} decades "
                f"from a typical binder at its temperatures and frequencies (asphalt_nscd.lab.dsr.CENTER; a binder "
                f"lies within {UNIT_BAND_DECADES:g}){_fits(r, declared)}"
            )
    return warned


def _mean(out: pd.DataFrame) -> pd.DataFrame:
    g = out.assign(_lnG=np.log(out["G_Pa"].to_numpy(float))).groupby(
        ["binder", "temperature_C", "frequency_Hz"], sort=False
    )
    res = g.agg(_lnG=("_lnG", "mean"), delta_deg=("delta_deg", "mean"), n_specimens=("G_Pa", "size")).reset_index()
    res["G_Pa"] = np.exp(res.pop("_lnG").to_numpy())
    single = g.size().to_numpy() == 1
    first = g.first().reset_index()
    # a point measured once keeps its value exactly
    res.loc[single, "G_Pa"] = first.loc[single, "G_Pa"].to_numpy()
    res.loc[single, "delta_deg"] = first.loc[single, "delta_deg"].to_numpy()
    return res


def _binder_infos(side: dict, where: str, binders: list, single: str) -> dict:
    """{binder: BinderInfo} from the sidecar's ``binder`` / ``binders`` block (empty ones for the rest).

    Raises InputError naming the sidecar key of a binder the file lacks."""
    infos = {b: BinderInfo(b, where=where) for b in binders}
    if side.get("binder"):
        block = {k: v for k, v in side["binder"].items() if k != "id"}
        if single not in infos:
            raise InputError(
                f"{where}: key 'binder': the file holds binders {binders}; a sidecar of several binders gives "
                "them under 'binders', keyed by id"
            )
        infos[single] = binder_info(single, block, f"{where}: key 'binder'")
    for b, block in (side.get("binders") or {}).items():
        if b not in infos:
            raise InputError(f"{where}: key 'binders.{b}': no binder {b!r} in the file (its binders: {binders})")
        infos[b] = binder_info(b, block, f"{where}: key 'binders.{b}'")
    return infos
