"""Test geometry of a measured table: which test produced it, and its form factor.

A measured complex-modulus table says nothing about the test that produced it, yet the
inertia of the moving mass enters the measured modulus through the test's own geometric
form factor gamma (1/mm), E* = gamma F*/z* (z* the displacement over the reference length):

* ``2pb_trapezoid`` — two-point bending on a trapezoidal cantilever (EN 12697-26 Annex A,
  paper Eq. 3), gamma of :class:`asphalt_nscd.lab.en12697.Specimen2PB` from its dimensions
  ``B_mm, b_mm, e_mm, h_mm`` (and masses ``M_kg, m_kg``);
* ``uniaxial_cylinder`` — tension-compression on a cylinder (AASHTO T 342, PP 61/AMPT,
  EN 12697-26 Annex D): E = (F/A) (h/z), so gamma = h/A with A = pi d^2/4, keys
  ``diameter_mm, height_mm`` (``height_mm``: the length over which the displacement is
  measured) and optionally ``moving_mass_kg``;
* ``unknown`` — no geometry: geometry-dependent effects (inertia) are not testable.

An uncorrected moving mass m lowers the in-phase modulus by gamma m w^2 in every test
(2PB: paper Eq. 1; uniaxial: the inertial force m w^2 z read by the load cell, times h/A).
A dimension given as ``null`` means "not stated by the source": the test is declared but
its form factor is unknown, and inertia is again not testable.

Declaration (choice, docs/choices.md "Diagnosis"): a JSON sidecar next to the table, named
``<table stem>.test.json`` (``complex_modulus.csv`` -> ``complex_modulus.test.json``), or a
file given explicitly (config ``measured.test``, option ``--test``). Without either the test
is ``unknown``: the 2PB trapezoid is never assumed. The file is validated against
:data:`SCHEMA` (JSON schema, draft 2020-12); an error names the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..io import InputError

if TYPE_CHECKING:
    from .table_format import TableFormat

TESTS = ("2pb_trapezoid", "uniaxial_cylinder", "unknown")

#: Largest dimension (mm) and mass (kg) a declaration may give: no complex-modulus specimen or moving
#: mass of a laboratory test comes near them (EN 12697-26 and AASHTO T 342 specimens are 25-250 mm, under 10 kg).
MAX_DIMENSION_MM = 1000.0
MAX_MASS_KG = 100.0
_POSITIVE_OR_NULL = {"type": ["number", "null"], "exclusiveMinimum": 0, "maximum": MAX_DIMENSION_MM}
_MASS_OR_NULL = {"type": ["number", "null"], "exclusiveMinimum": 0, "maximum": MAX_MASS_KG}
#: JSON schema of a test-geometry declaration (sidecar ``<table stem>.test.json``).
SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "Test geometry of a measured complex-modulus table",
    "type": "object",
    "properties": {
        "test": {"enum": list(TESTS), "description": "the test that produced the table"},
        "description": {"type": "string", "description": "free text: machine, standard, source"},
        "source": {"type": "string", "description": "where the declared values come from"},
        "B_mm": {**_POSITIVE_OR_NULL, "description": "2PB base width, mm"},
        "b_mm": {**_POSITIVE_OR_NULL, "description": "2PB head width, mm"},
        "e_mm": {**_POSITIVE_OR_NULL, "description": "2PB thickness, mm"},
        "h_mm": {**_POSITIVE_OR_NULL, "description": "2PB height, mm"},
        "M_kg": {**_MASS_OR_NULL, "description": "2PB specimen mass, kg"},
        "m_kg": {**_MASS_OR_NULL, "description": "2PB moving mass at the head, kg"},
        "diameter_mm": {**_POSITIVE_OR_NULL, "description": "cylinder diameter, mm"},
        "height_mm": {**_POSITIVE_OR_NULL, "description": "length over which the axial displacement is measured, mm"},
        "moving_mass_kg": {**_MASS_OR_NULL, "description": "uniaxial moving mass, kg"},
        "table": {
            "type": "object",
            "description": "how the lab wrote the table: units, form of the modulus, column names "
            "(asphalt_nscd.lab.table_format)",
        },
        "display": {
            "type": "object",
            "properties": {
                "modulus_unit": {"enum": ["MPa", "GPa", "kPa", "ksi", "psi"]},
                "temperature_unit": {"enum": ["C", "F"]},
            },
            "required": ["modulus_unit", "temperature_unit"],
            "additionalProperties": False,
            "description": "the units the lab wrote a table in that is now in the project's columns "
            "(figures and pages show them, SI beside)",
        },
        "quality_limits": {
            "type": "object",
            "additionalProperties": {"type": "number", "exclusiveMinimum": 0},
            "description": "limits of the table's data-quality indicators (asphalt_nscd.lab.checks)",
        },
    },
    "required": ["test"],
    "additionalProperties": False,
    "allOf": [
        {
            "if": {"properties": {"test": {"const": "2pb_trapezoid"}}},
            "then": {
                "required": ["B_mm", "b_mm", "e_mm", "h_mm"],
                "not": {
                    "anyOf": [
                        {"required": ["diameter_mm"]},
                        {"required": ["height_mm"]},
                        {"required": ["moving_mass_kg"]},
                    ]
                },
            },
        },
        {
            "if": {"properties": {"test": {"const": "uniaxial_cylinder"}}},
            "then": {
                "required": ["diameter_mm", "height_mm"],
                "not": {"anyOf": [{"required": [k]} for k in ("B_mm", "b_mm", "e_mm", "h_mm", "M_kg", "m_kg")]},
            },
        },
    ],
}
#: keys whose value fixes the form factor, per test
FORM_KEYS = {
    "2pb_trapezoid": ("B_mm", "b_mm", "e_mm", "h_mm"),
    "uniaxial_cylinder": ("diameter_mm", "height_mm"),
    "unknown": (),
}
#: optional mass keys, per test
MASS_KEYS = {"2pb_trapezoid": ("M_kg", "m_kg"), "uniaxial_cylinder": ("moving_mass_kg",), "unknown": ()}


@dataclass(frozen=True)
class DeclaredTest:
    """A test declaration (see the module docstring).

    ``values``: the declared keys (mm, kg; None = not stated); ``origin``: the file (or
    "default") it came from.
    """

    test: str = "unknown"
    values: dict = field(default_factory=dict)
    origin: str = "no test declared"
    source: str = ""
    description: str = ""
    #: how the lab wrote the table (:class:`asphalt_nscd.lab.table_format.TableFormat`), or None
    table: TableFormat | None = None
    #: the units to show the table in ({modulus_unit, temperature_unit}; empty: MPa and degC)
    display: dict = field(default_factory=dict)
    #: limits of the data-quality indicators (over asphalt_nscd.lab.checks.LIMITS)
    quality_limits: dict = field(default_factory=dict)

    @property
    def form_factor_per_mm(self) -> float | None:
        """gamma (1/mm) with E* = gamma F*/z*, or None when the test or a dimension is unknown."""
        keys = FORM_KEYS[self.test]
        if not keys or any(self.values.get(k) is None for k in keys):
            return None
        v = self.values
        if self.test == "2pb_trapezoid":
            from .en12697 import Specimen2PB

            return float(Specimen2PB(b_mm=v["b_mm"], B_mm=v["B_mm"], e_mm=v["e_mm"], h_mm=v["h_mm"]).gamma_per_mm)
        return float(v["height_mm"] / (math.pi * v["diameter_mm"] ** 2 / 4.0))

    @property
    def label(self) -> str:
        """Short description, e.g. ``uniaxial_cylinder (d = 100 mm, h = 150 mm)``."""
        if self.test == "unknown":
            return "unknown test"
        dims = ", ".join(f"{k} = {self.values[k]:g}" for k in FORM_KEYS[self.test] if self.values.get(k) is not None)
        return f"{self.test} ({dims or 'dimensions not stated'})"

    def inertia_testability(self) -> tuple[bool, str]:
        """(testable, reason): inertia needs the declared test's form factor."""
        if self.test == "unknown":
            return False, (
                f"the test geometry is unknown ({self.origin}); declare it in a "
                "'<table stem>.test.json' sidecar or config measured.test"
            )
        if self.form_factor_per_mm is None:
            missing = [k for k in FORM_KEYS[self.test] if self.values.get(k) is None]
            return False, f"{self.test} with {', '.join(missing)} not stated ({self.origin}): no form factor"
        return True, ""

    def to_json(self) -> dict:
        """The declaration as schema-valid JSON (``source`` says where it was declared)."""
        if self.source.startswith("declared in"):
            source = self.source
        else:
            source = f"declared in {self.origin}" + (f": {self.source}" if self.source else "")
        out = {"test": self.test, **self.values, "source": source}
        if self.description:
            out["description"] = self.description
        if self.display:
            out["display"] = dict(self.display)
        if self.quality_limits:
            out["quality_limits"] = dict(self.quality_limits)
        return out


def from_dict(obj, where: str) -> DeclaredTest:
    """Validate a declaration (parsed JSON) against :data:`SCHEMA`.

    Raises
    ------
    InputError
        naming ``where`` (the file) and the offending key.
    """
    import jsonschema

    if not isinstance(obj, dict):
        raise InputError(f"{where}: expected a JSON object with key 'test' ({' | '.join(TESTS)})")
    if "test" not in obj:
        raise InputError(f"{where}: key 'test' missing; expected one of {list(TESTS)}")
    for k, v in obj.items():
        if isinstance(v, float) and not math.isfinite(v):
            raise InputError(f"{where}: key '{k}': {v} is not a finite number; expected a positive number or null")
    validator = jsonschema.Draft202012Validator(SCHEMA)
    errors = sorted(validator.iter_errors(obj), key=lambda e: (list(e.absolute_path), e.message))
    if errors:
        e = errors[0]
        key = "/".join(str(p) for p in e.absolute_path) or "(top level)"
        if e.validator == "additionalProperties":
            extra = sorted(set(obj) - set(SCHEMA["properties"]))
            key = ", ".join(extra)
            msg = f"unknown key(s); allowed: {sorted(SCHEMA['properties'])}"
        elif e.validator == "required":
            msg = e.message
            key = msg.split("'")[1] if "'" in msg else key
        elif e.validator == "not":
            own = set(FORM_KEYS[obj["test"]]) | set(MASS_KEYS[obj["test"]])
            other = {k for t in TESTS for k in FORM_KEYS[t] + MASS_KEYS[t]} - own
            key = ", ".join(sorted(set(obj) & other))
            msg = f"not a key of test '{obj['test']}' (its keys: {sorted(own)})"
        elif e.validator in ("maximum", "exclusiveMinimum"):
            unit, top = ("kg", MAX_MASS_KG) if key.endswith("_kg") else ("mm", MAX_DIMENSION_MM)
            msg = f"{e.instance!r} {unit} is outside any specimen's range; expected a number > 0 and at most {top:g} {unit}, or null"
        else:
            msg = e.message
        raise InputError(f"{where}: key '{key}': {msg}")
    test = obj["test"]
    values = {
        k: (None if v is None else float(v))
        for k, v in obj.items()
        if k not in ("test", "description", "source", "table", "display", "quality_limits")
    }
    b_mm, B_mm = values.get("b_mm"), values.get("B_mm")
    if test == "2pb_trapezoid" and b_mm is not None and B_mm is not None and b_mm >= B_mm:
        raise InputError(
            f"{where}: key 'b_mm': head width {b_mm:g} mm must be smaller than the base width B_mm = {B_mm:g} mm"
        )
    table = None
    display = dict(obj.get("display", {}))
    limits = dict(obj.get("quality_limits", {}))
    if "table" in obj:
        from .table_format import TableFormat

        table = TableFormat.from_dict(obj["table"], str(where))
        display = {"modulus_unit": table.modulus_unit, "temperature_unit": table.temperature_unit}
        limits = {**limits, **table.quality_limits}
    if display == {"modulus_unit": "MPa", "temperature_unit": "C"}:
        display = {}
    return DeclaredTest(
        test=test,
        values=values,
        origin=str(where),
        source=str(obj.get("source", "")),
        description=str(obj.get("description", "")),
        table=table,
        display=display,
        quality_limits=limits,
    )


def load_test(path) -> DeclaredTest:
    """Read and validate a test-geometry JSON file.

    Raises
    ------
    InputError
        if the file is missing, not JSON, or fails :data:`SCHEMA` (naming the file and key).
    """
    from ..io import read_json

    obj = read_json(path, what="test-geometry JSON")
    return from_dict(obj, str(path))


def sidecar_path(table_path) -> Path:
    """``<table stem>.test.json`` next to the table."""
    p = Path(table_path)
    return p.with_name(p.stem + ".test.json")


def declared_test(table_path, explicit=None) -> DeclaredTest:
    """The declared test of a measured table: ``explicit`` file if given, else the sidecar
    next to the table if it exists, else ``unknown``.

    Raises InputError as :func:`load_test`.
    """
    if explicit is not None:
        return load_test(explicit)
    side = sidecar_path(table_path)
    if side.is_file():
        return load_test(side)
    return DeclaredTest(origin=f"no sidecar {side.name} next to {Path(table_path).name}")


#: The specimens of the synthetic schedules (:mod:`asphalt_nscd.diagnosis.synthetic`): the
#: paper's 2PB trapezoid and the AASHTO T 342 / PP 61 cylinder (100 mm x 150 mm).
PAPER_2PB = DeclaredTest(
    "2pb_trapezoid",
    {"B_mm": 56.0, "b_mm": 25.0, "e_mm": 25.0, "h_mm": 250.0, "M_kg": 0.6, "m_kg": 0.235},
    "paper 2PB specimen",
)
AASHTO_CYLINDER = DeclaredTest("uniaxial_cylinder", {"diameter_mm": 100.0, "height_mm": 150.0}, "AASHTO T 342 specimen")
