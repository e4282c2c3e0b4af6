"""Measured tables as labs write them: column names, units and the form of the modulus.

The project's own table (:mod:`.measured`) has the columns ``specimen, temperature_C,
frequency_Hz, E_norm_MPa, phase_deg``. A lab's table rarely does: an AASHTO T 342 / T 378
report gives |E*| in ksi or psi at temperatures in degF, an EN 12697-26 report may give the
storage and loss moduli E1, E2 in MPa or GPa. Such a table is read through its declaration,
the ``table`` block of its JSON sidecar ``<table stem>.test.json`` (the file that also
declares the test geometry, :mod:`.geometry`)::

    "table": {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase",
              "columns": {"temperature": "Temp (F)", "modulus": "|E*| (ksi)"}}

=================  ===================================================================
key                meaning
=================  ===================================================================
modulus_unit       MPa | GPa | kPa | ksi | psi (the unit of |E*|, or of E1 and E2)
temperature_unit   C | F
modulus_form       norm_phase (|E*| and the phase angle, degrees) | storage_loss (E1, E2)
columns            optional: the table's header of each quantity (``specimen``,
                   ``temperature``, ``frequency``, ``modulus``, ``phase``, ``storage``,
                   ``loss``, ``strain``, ``test_order``); a quantity not mapped is found by
                   its common names (:data:`ALIASES`, case, spaces and punctuation ignored)
quality            optional: the table's header of each data-quality indicator
                   (``load_standard_error_pct``, ``deformation_standard_error_pct``,
                   ``deformation_uniformity_pct``, ``phase_uniformity_deg``: AASHTO T 378),
                   read into columns ``quality_<indicator>``
quality_limits     optional: {indicator: limit} replacing the AASHTO T 378 limits
=================  ===================================================================

A table whose header has the project's own columns needs no declaration. Any other table
without one, or a declaration that names a missing column or an unknown unit, is an
:class:`asphalt_nscd.io.InputError` naming the file and the key. The conversion is exact:
1 ksi = 6.894757293168361 MPa (1 lbf/in^2 = 4.4482216152605 N / 0.00064516 m^2), T(degC) =
(T(degF) - 32) / 1.8, |E*| = sqrt(E1^2 + E2^2), Phi = atan2(E2, E1).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..io import InputError

#: MPa per unit of modulus
MODULUS_UNITS = {"MPa": 1.0, "GPa": 1e3, "kPa": 1e-3, "ksi": 6.894757293168361, "psi": 6.894757293168361e-3}
TEMPERATURE_UNITS = ("C", "F")
MODULUS_FORMS = ("norm_phase", "storage_loss")
#: the data-quality indicators a table may carry (AASHTO T 378; limits: asphalt_nscd.lab.checks.LIMITS)
QUALITY_INDICATORS = (
    "load_standard_error_pct",
    "deformation_standard_error_pct",
    "deformation_uniformity_pct",
    "phase_uniformity_deg",
)
#: the quantities a table maps to the project's columns
QUANTITIES = ("specimen", "temperature", "frequency", "modulus", "phase", "storage", "loss", "strain", "test_order")
#: common header names of each quantity in AASHTO, EN and lab tables (compared without case,
#: spaces, punctuation or a trailing unit in brackets)
ALIASES = {
    "specimen": ["specimen", "specimenid", "sample", "sampleid", "replicate", "rep", "specimenno", "id"],
    "temperature": ["temperature", "temp", "testtemperature", "t", "temperaturec", "temperaturef", "tempc", "tempf"],
    "frequency": ["frequency", "freq", "frequencyhz", "f", "loadingfrequency"],
    "modulus": [
        "enorm",
        "enormmpa",
        "e",
        "dynamicmodulus",
        "complexmodulus",
        "modulus",
        "estar",
        "normofthecomplexmodulus",
        "absestar",
    ],
    "phase": ["phase", "phasedeg", "phaseangle", "phi", "delta", "phaseangledeg"],
    "storage": ["e1", "estorage", "storagemodulus", "eprime", "e1mpa"],
    "loss": ["e2", "eloss", "lossmodulus", "edoubleprime", "e2mpa"],
    "strain": ["strain", "strainmicrostrain", "strainamplitude", "microstrain"],
    "test_order": ["testorder", "order", "sequence", "testno"],
}
#: the project's own column of each quantity
OWN_COLUMNS = {
    "specimen": "specimen",
    "temperature": "temperature_C",
    "frequency": "frequency_Hz",
    "modulus": "E_norm_MPa",
    "phase": "phase_deg",
    "strain": "strain_microstrain",
    "test_order": "test_order",
}


def _key(name: str) -> str:
    """A header reduced for comparison: lower case, a trailing '(unit)' or '[unit]' dropped,
    '|E*|' read as 'absestar', then letters and digits only."""
    s = str(name).strip().lower()
    s = re.sub(r"[\(\[][^\)\]]*[\)\]]\s*$", "", s).strip()
    s = s.replace("|e*|", "absestar").replace("e*", "estar").replace("e''", "edoubleprime").replace("e'", "eprime")
    return re.sub(r"[^a-z0-9]", "", s)


@dataclass
class TableFormat:
    """A table's declaration (module docstring); ``where`` names the file it came from."""

    modulus_unit: str = "MPa"
    temperature_unit: str = "C"
    modulus_form: str = "norm_phase"
    columns: dict = field(default_factory=dict)
    where: str = ""
    quality: dict = field(default_factory=dict)
    quality_limits: dict = field(default_factory=dict)

    @classmethod
    def from_dict(cls, obj, where: str) -> "TableFormat":
        """The ``table`` block of a sidecar (parsed JSON).

        Raises
        ------
        InputError naming ``where`` and the key (``table.<key>``) on an unknown key, unit or
        form, or a column map that is not {quantity: header}.
        """
        if not isinstance(obj, dict):
            raise InputError(
                f"{where}: key 'table': expected an object with modulus_unit, temperature_unit, modulus_form, columns"
            )
        allowed = {"modulus_unit", "temperature_unit", "modulus_form", "columns", "quality", "quality_limits"}
        extra = sorted(set(obj) - allowed)
        if extra:
            raise InputError(f"{where}: key 'table.{extra[0]}': unknown key; allowed: {sorted(allowed)}")
        for key, choices in (
            ("modulus_unit", list(MODULUS_UNITS)),
            ("temperature_unit", list(TEMPERATURE_UNITS)),
            ("modulus_form", list(MODULUS_FORMS)),
        ):
            if key not in obj:
                raise InputError(f"{where}: key 'table.{key}' missing; expected one of {choices}")
            if obj[key] not in choices:
                raise InputError(f"{where}: key 'table.{key}': {obj[key]!r} is not one of {choices}")
        cols = obj.get("columns", {})
        if not isinstance(cols, dict) or not all(isinstance(v, str) for v in cols.values()):
            raise InputError(
                f"{where}: key 'table.columns': expected {{quantity: header}} with quantities {list(QUANTITIES)}"
            )
        bad = sorted(set(cols) - set(QUANTITIES))
        if bad:
            raise InputError(
                f"{where}: key 'table.columns.{bad[0]}': unknown quantity; expected one of {list(QUANTITIES)}"
            )
        quality = obj.get("quality", {})
        if not isinstance(quality, dict) or not all(isinstance(v, str) for v in quality.values()):
            raise InputError(
                f"{where}: key 'table.quality': expected {{indicator: header}} with indicators "
                f"{list(QUALITY_INDICATORS)}"
            )
        limits = obj.get("quality_limits", {})
        for key, block in (("quality", quality), ("quality_limits", limits)):
            bad = sorted(set(block) - set(QUALITY_INDICATORS)) if isinstance(block, dict) else ["(not an object)"]
            if bad:
                raise InputError(
                    f"{where}: key 'table.{key}.{bad[0]}': unknown indicator; expected one of "
                    f"{list(QUALITY_INDICATORS)}"
                )
        for k, v in limits.items():
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not (v > 0 and math.isfinite(v)):
                raise InputError(f"{where}: key 'table.quality_limits.{k}': expected a positive number, got {v!r}")
        return cls(
            obj["modulus_unit"],
            obj["temperature_unit"],
            obj["modulus_form"],
            dict(cols),
            where,
            dict(quality),
            {k: float(v) for k, v in limits.items()},
        )

    def needed(self) -> tuple:
        """Quantities the table must give."""
        mod = ("modulus", "phase") if self.modulus_form == "norm_phase" else ("storage", "loss")
        return ("specimen", "temperature", "frequency") + mod

    def find(self, header, quantity: str) -> str | None:
        """The column of ``header`` holding ``quantity``: the declared one, else the first whose
        reduced name is one of its aliases, else None.

        Raises InputError (file and key) if a declared column is not in the header.
        """
        if quantity in self.columns:
            name = self.columns[quantity]
            if name not in header:
                raise InputError(
                    f"{self.where}: key 'table.columns.{quantity}': column {name!r} is not in the "
                    f"table's header {list(header)}"
                )
            return name
        keys = {_key(h): h for h in reversed(list(header))}
        for alias in ALIASES[quantity]:
            if alias in keys:
                return keys[alias]
        return None


def to_own_columns(frame: pd.DataFrame, fmt: TableFormat, path) -> tuple[pd.DataFrame, dict]:
    """The table in the project's columns and units.

    Parameters
    ----------
    frame : the CSV read as text (every column ``str``), header stripped.
    fmt : its declaration. path : the table file (for messages).

    Returns
    -------
    (frame, labels)
        ``frame``: the text columns with the project's columns (``temperature_C``,
        ``E_norm_MPa``, ``phase_deg``, ... as numbers formatted with ``repr``) added or
        replacing the lab's, the others kept; ``labels``: project column -> "its name
        (from the lab's column)" for messages.

    Raises
    ------
    InputError naming the file and the key or column: a quantity the declaration needs is not
    found, or a value the conversion needs is not a number.
    """
    out = frame.copy()
    labels = {}
    found = {}
    for q in fmt.needed() + ("strain", "test_order"):
        col = fmt.find(frame.columns, q)
        if col is None:
            if q in fmt.needed():
                raise InputError(
                    f"{path}: no column for the {q} ({'|'.join(ALIASES[q][:4])}, ...) in the header "
                    f"{list(frame.columns)}; map it in {fmt.where or 'the sidecar'} key "
                    f"'table.columns.{q}'"
                )
            continue
        found[q] = col
    _check_columns(found, fmt, path)

    def number(q):
        col = found[q]
        v = pd.to_numeric(frame[col].str.strip(), errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise InputError(
                f"{path}: line {int(bad[0]) + 2}, column '{col}': value {frame[col].iloc[bad[0]]!r} is "
                f"not a number; expected the {q} in {_unit(fmt, q)}"
            )
        return v

    T = number("temperature")
    if fmt.temperature_unit == "F":  # rounded to 1e-9 degC: 98.6 F reads 37, not 37.00000000000001
        T = np.round((T - 32.0) / 1.8, 9)
    scale = MODULUS_UNITS[fmt.modulus_unit]
    if fmt.modulus_form == "norm_phase":
        E, P = number("modulus") * scale, number("phase")
    else:
        E1, E2 = number("storage") * scale, number("loss") * scale
        E, P = np.hypot(E1, E2), np.degrees(np.arctan2(E2, E1))
    values = {"temperature_C": T, "E_norm_MPa": E, "phase_deg": P, "frequency_Hz": number("frequency")}
    sources = {
        "temperature_C": "temperature",
        "frequency_Hz": "frequency",
        "E_norm_MPa": "modulus" if fmt.modulus_form == "norm_phase" else "storage",
        "phase_deg": "phase" if fmt.modulus_form == "norm_phase" else "loss",
    }
    for own, v in values.items():
        src = found[sources[own]]
        if src == own:
            continue
        out[own] = [repr(float(x)) for x in v]
        labels[own] = f"{own} (from '{src}' in {_unit(fmt, sources[own])})"
    for q in ("specimen", "strain", "test_order"):
        if q in found and found[q] != OWN_COLUMNS[q]:
            out[OWN_COLUMNS[q]] = frame[found[q]]
            labels[OWN_COLUMNS[q]] = f"{OWN_COLUMNS[q]} (from '{found[q]}')"
    for indicator, col in fmt.quality.items():
        if col not in frame.columns:
            raise InputError(
                f"{fmt.where or path}: key 'table.quality.{indicator}': column {col!r} is not in the "
                f"table's header {list(frame.columns)}"
            )
        v = pd.to_numeric(frame[col].str.strip(), errors="coerce")
        bad = np.flatnonzero(v.isna().to_numpy() & (frame[col].str.strip() != "").to_numpy())
        if bad.size:
            raise InputError(
                f"{path}: line {int(bad[0]) + 2}, column '{col}': value {frame[col].iloc[bad[0]]!r} is "
                f"not a number; expected the data-quality indicator {indicator}"
            )
        out[f"quality_{indicator}"] = v.to_numpy(float)
    return out, labels


#: a unit written in a header: 'E_norm_MPa', '|E*| (ksi)', 'Temp (F)', 'temperature_degC'
_HEADER_UNIT = re.compile(r"(?:^|[\s_(\[/])(mpa|gpa|kpa|ksi|psi|degc|degf|°c|°f|c|f)(?:$|[\s_)\]])", re.IGNORECASE)


def header_unit(header: str, quantity: str) -> str | None:
    """The unit a header names for ``quantity`` (temperature: ``C`` | ``F``; a modulus: a key of
    :data:`MODULUS_UNITS`), or None."""
    for m in _HEADER_UNIT.finditer(str(header)):
        u = m.group(1).lower().replace("deg", "").replace("°", "")
        if quantity == "temperature" and u in ("c", "f"):
            return u.upper()
        if quantity in ("modulus", "storage", "loss"):
            for unit in MODULUS_UNITS:
                if u == unit.lower():
                    return unit
    return None


def _check_columns(found: dict, fmt: TableFormat, path) -> None:
    """Refuse a declaration that maps two quantities to one column, or whose unit contradicts
    the unit a mapped column's header names (both named)."""
    seen: dict[str, str] = {}
    for q, col in found.items():
        if col in seen:
            raise InputError(
                f"{path}: column '{col}' is mapped to both the {seen[col]} and the {q} "
                f"({fmt.where or 'the sidecar'} key 'table.columns'); one column per quantity"
            )
        seen[col] = q
    for q, col in found.items():
        declared = (
            fmt.temperature_unit
            if q == "temperature"
            else fmt.modulus_unit
            if q in ("modulus", "storage", "loss")
            else None
        )
        named = header_unit(col, q)
        if declared is not None and named is not None and named != declared:
            key = "temperature_unit" if q == "temperature" else "modulus_unit"
            raise InputError(
                f"{path}: column '{col}' names the unit {named}, but {fmt.where or 'the sidecar'} key "
                f"'table.{key}' declares {declared}; declare the column's unit (or map another column)"
            )


def _unit(fmt: TableFormat, q: str) -> str:
    return {
        "temperature": f"deg{fmt.temperature_unit}",
        "modulus": fmt.modulus_unit,
        "storage": fmt.modulus_unit,
        "loss": fmt.modulus_unit,
        "phase": "degrees",
        "frequency": "Hz",
    }.get(q, "the table's unit")


@dataclass(frozen=True)
class DisplayUnits:
    """The units a lab wrote its table in, for figures, tables and pages: values are kept in
    MPa and degC inside (SI) and shown in the lab's units with SI beside.

    ``modulus``: a key of :data:`MODULUS_UNITS`; ``temperature``: ``C`` or ``F``."""

    modulus: str = "MPa"
    temperature: str = "C"

    @classmethod
    def of(cls, test) -> "DisplayUnits":
        """The units of a declared test (:class:`asphalt_nscd.lab.geometry.DeclaredTest`: its
        ``display`` units; the project's own MPa and degC without)."""
        display = getattr(test, "display", None) or {}
        if not display:
            return cls()
        return cls(display["modulus_unit"], display["temperature_unit"])

    @property
    def is_si(self) -> bool:
        return self.modulus == "MPa" and self.temperature == "C"

    def modulus_value(self, E_MPa):
        """|E*| in the lab's unit from MPa (scalar or array)."""
        return (
            np.asarray(E_MPa, float) / MODULUS_UNITS[self.modulus]
            if np.ndim(E_MPa)
            else float(E_MPa) / MODULUS_UNITS[self.modulus]
        )

    def temperature_value(self, T_C):
        """Temperature in the lab's unit from degC (scalar or array)."""
        if self.temperature == "C":
            return T_C
        return np.asarray(T_C, float) * 1.8 + 32.0 if np.ndim(T_C) else float(T_C) * 1.8 + 32.0

    def modulus_text(self, E_MPa: float) -> str:
        """``4,000 ksi (27,579 MPa)``, or ``27,579 MPa`` in SI."""
        si = f"{E_MPa:,.4g} MPa" if E_MPa < 1e4 else f"{E_MPa:,.0f} MPa"
        if self.modulus == "MPa":
            return si
        v = self.modulus_value(E_MPa)
        return f"{v:,.4g} {self.modulus} ({si})"

    def temperature_text(self, T_C: float) -> str:
        """``69.8 degF (21 degC)``, or ``21 degC`` in SI."""
        if self.temperature == "C":
            return f"{T_C:g} degC"
        return f"{self.temperature_value(T_C):.4g} degF ({T_C:g} degC)"

    def temperature_header(self) -> str:
        return "T (degC)" if self.temperature == "C" else "T (degF (degC))"

    def temperature_cell(self, T_C: float) -> str:
        """A table cell: ``21`` or ``69.8 (21)``."""
        return f"{T_C:g}" if self.temperature == "C" else f"{self.temperature_value(T_C):.4g} ({T_C:g})"

    def modulus_label(self) -> str:
        return f"|E*| ({self.modulus})"

    def temperature_label(self) -> str:
        return "temperature (°C)" if self.temperature == "C" else "temperature (°F)"

    def as_dict(self) -> dict:
        return {"modulus": self.modulus, "temperature": self.temperature}
