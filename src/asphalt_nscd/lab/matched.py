"""Matched binder-mix tables: a mix's measured |E*| and phase beside its binder and formulation.

One row per (mix, temperature, frequency) holding the mix's measured |E*| and phase angle (empty
where they are to be forecast), its binder's |G*| and phase angle delta at the same condition
(and the viscosity where given), and the mix's gradation and volumetrics. The project's own
columns (:data:`COLUMNS`; units and meaning in data/README.md, "Matched binder-mix tables"):
``mix_id, temperature_C, frequency_Hz, E_norm_MPa, phase_deg, binder_G_MPa, binder_delta_deg,
binder_eta_Pa_s, binder_frequency_Hz, rho34_pct, rho38_pct, rho4_pct, rho200_pct, Pb_pct, Va_pct,
Vbeff_pct`` and
optionally ``pg_high_C, pg_low_C`` (rho34, rho38, rho4: cumulative % retained on the 19, 9.5 and
4.75 mm sieves; rho200: % passing 0.075 mm; Pb % of mix mass, optional: no model reads it, so a column
absent or a cell left empty reads NaN; Va, Vbeff % of mix volume).

A table as published keeps its own headers and units: the ``table`` block of its JSON sidecar
``<table stem>.test.json`` declares them as for a lab's table (:mod:`.table_format`), with the
keys of a matched table (:class:`MatchedFormat`): ``phase_unit`` (deg | rad), the binder's
``binder_modulus_unit``, ``binder_phase_unit``, ``viscosity_unit`` (Pa s | cP | P) and
``binder_frequency_unit`` (Hz: the binder at the row's frequency; rad/s: at the angular frequency
of the row's value, f / 2 pi Hz, column ``binder_frequency_Hz``), ``columns``
({quantity: header}, quantities :data:`QUANTITY_COLUMNS`) and ``order``: the temperatures (in
``temperature_unit``) and frequencies of a file that does not carry them, each mix's rows being
one block per temperature in that order, each holding the frequencies in order. A column the
declaration does not map (the source's reduced frequency ``w``, computed from the mix's own
measured shift factors) is not read. Separators as for lab tables, suffix .csv, .tsv or .txt.

Checks (:class:`asphalt_nscd.io.InputError` naming the file, the line and the column): a value
that is not a number; a modulus or phase no mix or binder gives (mix: the lab tables' ranges;
binder |G*| 1e-7 to 3,000 MPa, delta in (0, 90], viscosity :data:`VISCOSITY_RANGE_PA_S`); |E*|
without its phase or the reverse; a formulation that changes within a mix; a gradation that is not
cumulative; Va or Vbeff outside 0-30 %, Pb outside 0-20 %, a Vbeff that Pb cannot fill (Vbeff <= Pb
Gmb/Gb with Gmb <= 2.7 and Gb >= 1.0, :mod:`.volumetrics`; the shipped mixes reach 2.39 Pb); a mix
whose rows do not fill the declared blocks; a repeated (mix, temperature, frequency); a mix id that
cannot name a file; a declared order the values contradict (a binder viscosity rising with
temperature, |E*| rising with temperature or falling with frequency in most blocks of the table or
of one mix); a mix phase angle that jumps from its isotherm's neighbours in frequency
(:data:`PHASE_JUMP_RATIO`). The mix values also pass the lab tables' plausibility warnings
(:func:`asphalt_nscd.lab.checks.check_values`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError
from .table_format import MODULUS_UNITS, TEMPERATURE_UNITS, _key

#: the project's columns of a matched table, in order (module docstring)
COLUMNS = (
    "mix_id",
    "temperature_C",
    "frequency_Hz",
    "E_norm_MPa",
    "phase_deg",
    "binder_G_MPa",
    "binder_delta_deg",
    "binder_eta_Pa_s",
    "binder_frequency_Hz",
    "rho34_pct",
    "rho38_pct",
    "rho4_pct",
    "rho200_pct",
    "Pb_pct",
    "Va_pct",
    "Vbeff_pct",
)
OPTIONAL_COLUMNS = ("pg_high_C", "pg_low_C")
#: per-mix columns: one value per mix
FORMULATION = ("rho34_pct", "rho38_pct", "rho4_pct", "rho200_pct", "Pb_pct", "Va_pct", "Vbeff_pct")
#: quantity of a declaration -> the project's column
QUANTITY_COLUMNS = {
    "mix": "mix_id",
    "temperature": "temperature_C",
    "frequency": "frequency_Hz",
    "modulus": "E_norm_MPa",
    "phase": "phase_deg",
    "binder_modulus": "binder_G_MPa",
    "binder_phase": "binder_delta_deg",
    "binder_viscosity": "binder_eta_Pa_s",
    "binder_frequency": "binder_frequency_Hz",
    "rho34": "rho34_pct",
    "rho38": "rho38_pct",
    "rho4": "rho4_pct",
    "rho200": "rho200_pct",
    "Pb": "Pb_pct",
    "Va": "Va_pct",
    "Vbeff": "Vbeff_pct",
    "pg_high": "pg_high_C",
    "pg_low": "pg_low_C",
}
#: common header names of each quantity (compared as :func:`asphalt_nscd.lab.table_format._key` reduces them)
ALIASES = {
    "mix": ["mix", "mixid", "id", "mixture", "mixtureid"],
    "temperature": ["temperature", "temp", "t", "temperaturec", "temperaturef"],
    "frequency": ["frequency", "freq", "f", "frequencyhz"],
    "modulus": ["enorm", "enormmpa", "absestar", "estar", "dynamicmodulus", "e"],
    "phase": ["phase", "phasedeg", "phaseangle", "phi", "φ"],
    "binder_modulus": ["bindergmpa", "bindergstar", "absgstar", "gstar", "g"],
    "binder_phase": ["binderdeltadeg", "binderdelta", "deltab", "δb", "delta"],
    "binder_viscosity": ["bindereta", "binderetapas", "eta", "η", "viscosity"],
    "binder_frequency": ["binderfrequencyhz", "binderfrequency"],
    "rho34": ["rho34pct", "rho34", "ρ34"],
    "rho38": ["rho38pct", "rho38", "ρ38"],
    "rho4": ["rho4pct", "rho4", "ρ4"],
    "rho200": ["rho200pct", "rho200", "ρ200"],
    "Pb": ["pbpct", "pb"],
    "Va": ["vapct", "va"],
    "Vbeff": ["vbeffpct", "vbeff"],
    "pg_high": ["pghighc", "pghigh"],
    "pg_low": ["pglowc", "pglow"],
}
NEEDED = ("mix", "modulus", "phase", "binder_modulus", "binder_phase", "rho34", "rho38", "rho4", "rho200", "Va")
PHASE_UNITS = {"deg": 1.0, "rad": 180.0 / math.pi}
#: what a row's frequency value means for its binder columns: Hz (the binder at the mix's frequency) or rad/s
#: (the binder at the angular frequency of that value, i.e. at frequency / (2 pi) Hz)
BINDER_FREQUENCY_UNITS = {"Hz": 1.0, "rad/s": 1.0 / (2.0 * math.pi)}
#: Pa s per unit of viscosity
VISCOSITY_UNITS = {"Pa s": 1.0, "cP": 1e-3, "P": 0.1}
#: (low, high) of a binder's viscosity, Pa s: above 0.01 Pa s (binders at 135 degC: 0.1-3 Pa s, AASHTO M 320
#: caps it at 3 Pa s, and the tests here stop at 100 degC); below ten times 1e12 Pa s, the viscosity that
#: defines a glass transition (Angell 1995, Science 267): a binder in a complex-modulus test is a liquid
#: above or near its glass transition (the shipped table's largest, A-VTS values at -10 degC: 3.1e11 Pa s)
VISCOSITY_RANGE_PA_S = (1e-2, 1e13)
#: a binder's |G*| (MPa): above a gel's 0.1 Pa, below a glassy binder's 3 GPa
BINDER_G_RANGE_MPA = (1e-7, 3000.0)
#: (low, high) of the volumetrics, % (a bituminous mix; refused outside)
VOLUMETRIC_RANGES = {"Va_pct": (0.0, 30.0), "Vbeff_pct": (0.0, 30.0), "Pb_pct": (0.0, 20.0)}
SUFFIXES = (".csv", ".tsv", ".txt")


def _reduced(name: str) -> str:
    """A header reduced for comparison (the lab tables' rule, Greek letters kept)."""
    s = _key(name)
    return s or "".join(ch for ch in str(name).lower() if ch.isalnum())


@dataclass
class MatchedFormat:
    """The ``table`` block of a matched table's sidecar (module docstring); ``where``: the file."""

    modulus_unit: str = "MPa"
    temperature_unit: str = "C"
    phase_unit: str = "deg"
    binder_modulus_unit: str = "MPa"
    binder_phase_unit: str = "deg"
    viscosity_unit: str = "Pa s"
    binder_frequency_unit: str = "Hz"
    columns: dict = field(default_factory=dict)
    order: dict | None = None
    where: str = ""

    @classmethod
    def from_dict(cls, obj, where: str) -> "MatchedFormat":
        """Parse and check a ``table`` block.

        Raises InputError naming ``where`` and the key (``table.<key>``): an unknown key, unit or
        quantity, a column map that is not {quantity: header}, an ``order`` that is not two
        non-empty lists of distinct numbers (frequencies > 0), or ``modulus_form`` other than
        ``norm_phase``.
        """
        if not isinstance(obj, dict):
            raise InputError(f"{where}: key 'table': expected an object (asphalt_nscd.lab.matched)")
        choices = {
            "modulus_unit": list(MODULUS_UNITS),
            "temperature_unit": list(TEMPERATURE_UNITS),
            "phase_unit": list(PHASE_UNITS),
            "binder_modulus_unit": list(MODULUS_UNITS),
            "binder_phase_unit": list(PHASE_UNITS),
            "viscosity_unit": list(VISCOSITY_UNITS),
            "binder_frequency_unit": list(BINDER_FREQUENCY_UNITS),
            "modulus_form": ["norm_phase"],
        }
        allowed = set(choices) | {"columns", "order"}
        extra = sorted(set(obj) - allowed)
        if extra:
            raise InputError(f"{where}: key 'table.{extra[0]}': unknown key; allowed: {sorted(allowed)}")
        for key, options in choices.items():
            if key in obj and obj[key] not in options:
                raise InputError(f"{where}: key 'table.{key}': {obj[key]!r} is not one of {options}")
        cols = obj.get("columns", {})
        if not isinstance(cols, dict) or not all(isinstance(v, str) for v in cols.values()):
            raise InputError(f"{where}: key 'table.columns': expected {{quantity: header}}")
        bad = sorted(set(cols) - set(QUANTITY_COLUMNS))
        if bad:
            raise InputError(
                f"{where}: key 'table.columns.{bad[0]}': unknown quantity; expected one of {list(QUANTITY_COLUMNS)}"
            )
        order = obj.get("order")
        if order is not None:
            order = _check_order(order, where)
        kwargs = {k: obj[k] for k in choices if k in obj and k != "modulus_form"}
        return cls(**kwargs, columns=dict(cols), order=order, where=str(where))

    def find(self, header, quantity: str) -> str | None:
        """The header of ``quantity``: the declared one, else the project's column, else the first
        alias; None if absent. Raises InputError if a declared header is not in the file."""
        if quantity in self.columns:
            name = self.columns[quantity]
            if name not in header:
                raise InputError(
                    f"{self.where}: key 'table.columns.{quantity}': column {name!r} is not in the table's header "
                    f"{list(header)}"
                )
            return name
        own = QUANTITY_COLUMNS[quantity]
        if own in header:
            return own
        keys = {_reduced(h): h for h in reversed(list(header))}
        for alias in ALIASES[quantity]:
            if alias in keys:
                return keys[alias]
        return None


def _check_order(order, where: str) -> dict:
    if not isinstance(order, dict) or set(order) != {"temperatures", "frequencies_Hz"}:
        raise InputError(
            f"{where}: key 'table.order': expected {{'temperatures': [...], 'frequencies_Hz': [...]}} "
            "(the blocks of each mix, in file order)"
        )
    out = {}
    for key in ("temperatures", "frequencies_Hz"):
        v = order[key]
        ok = (
            isinstance(v, list)
            and len(v) > 0
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        )
        if not ok or not all(math.isfinite(x) for x in v) or len(set(v)) != len(v):
            raise InputError(f"{where}: key 'table.order.{key}': expected a non-empty list of distinct numbers")
        if key == "frequencies_Hz" and min(v) <= 0:
            raise InputError(f"{where}: key 'table.order.frequencies_Hz': frequencies must be > 0 Hz")
        out[key] = [float(x) for x in v]
    return out


def read_sidecar(path: Path, explicit=None):
    """(declared test, MatchedFormat or None) of a matched table: its ``table`` block parsed
    here, the rest by :func:`asphalt_nscd.lab.geometry.from_dict`.

    Raises InputError naming the sidecar and the key."""
    from ..io import read_json
    from .geometry import DeclaredTest, from_dict, sidecar_path

    side = Path(explicit) if explicit is not None else sidecar_path(path)
    if not side.is_file():
        if explicit is not None:
            raise InputError(f"{side}: file not found (the sidecar of {path})")
        return DeclaredTest(origin=f"no sidecar {side.name} next to {path.name}"), None
    obj = read_json(side, what="sidecar JSON")
    if not isinstance(obj, dict):
        raise InputError(f"{side}: expected a JSON object with key 'test'")
    obj = dict(obj)
    block = obj.pop("table", None)
    test = from_dict(obj, str(side))
    return test, (None if block is None else MatchedFormat.from_dict(block, str(side)))


def read_matched(path, sidecar=None) -> pd.DataFrame:
    """Read, convert and check a matched binder-mix table.

    Parameters
    ----------
    path : str or Path
        The table (``.csv``, ``.tsv`` or ``.txt``), in the project's columns or declared in its
        sidecar (module docstring).
    sidecar : str or Path, optional
        The sidecar; default ``<table stem>.test.json`` next to the table.

    Returns
    -------
    DataFrame, one row per (mix, temperature, frequency)
        :data:`COLUMNS` (and :data:`OPTIONAL_COLUMNS` when given), SI-like units of the module
        docstring; mixes in file order, then temperature and frequency ascending.
        ``attrs``: ``test`` (the declared test), ``warnings`` (plausibility warnings), ``source``
        (file and declaration), ``dropped_columns`` (headers not read).

    Raises
    ------
    InputError
        naming the file, the line and the column (module docstring: Checks).
    """
    import logging

    from .checks import check_values
    from .measured import _read_text_table

    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise InputError(f"{path}: expected a {'/'.join(SUFFIXES)} file, got suffix '{path.suffix}'")
    test, fmt = read_sidecar(path, sidecar)
    frame = _read_text_table(path, allowed_suffixes=SUFFIXES)
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows after the header")
    fmt = fmt or MatchedFormat(where="no sidecar")
    found = {}
    for q in QUANTITY_COLUMNS:
        col = fmt.find(frame.columns, q)
        if col is not None:
            found[q] = col
    missing = [q for q in NEEDED if q not in found]
    if fmt.order is None:
        missing = [q for q in ("temperature", "frequency") if q not in found] + missing
    if "Vbeff" not in found:
        missing.append("Vbeff")
    if missing:
        raise InputError(
            f"{path}: line 1 (header): no column for {missing}; found {list(frame.columns)}. Name them "
            f"{[QUANTITY_COLUMNS[q] for q in missing]} or map them in key 'table.columns' of the sidecar "
            "(asphalt_nscd.lab.matched)"
        )
    seen: dict[str, str] = {}
    for q, col in found.items():
        if col in seen:
            raise InputError(f"{path}: column '{col}' is mapped to both the {seen[col]} and the {q}; one column each")
        seen[col] = q
    out = pd.DataFrame(index=frame.index)
    mix = frame[found["mix"]].str.strip()
    empty = np.flatnonzero((mix == "").to_numpy())
    if empty.size:
        raise InputError(f"{path}: line {int(empty[0]) + 2}, column '{found['mix']}': empty mix identifier")
    bad = np.flatnonzero(~mix.str.fullmatch(r"[\w.+-]+").to_numpy())
    if bad.size:
        raise InputError(
            f"{path}: line {int(bad[0]) + 2}, column '{found['mix']}': mix identifier {mix.iloc[bad[0]]!r}; expected "
            "letters, digits and . _ + - only (it names the mix's sample files)"
        )
    out["mix_id"] = mix
    if fmt.order is None:
        out["temperature_C"] = _number(path, frame, found["temperature"], "a temperature")
        out["frequency_Hz"] = _number(path, frame, found["frequency"], "a frequency in Hz")
    else:
        out["temperature_C"], out["frequency_Hz"] = _by_order(path, mix, fmt)
    if fmt.temperature_unit == "F":
        out["temperature_C"] = np.round((out["temperature_C"] - 32.0) / 1.8, 9)
    E = _number(path, frame, found["modulus"], f"|E*| in {fmt.modulus_unit} or empty", empty_ok=True)
    P = _number(path, frame, found["phase"], f"a phase angle in {fmt.phase_unit} or empty", empty_ok=True)
    half = np.flatnonzero(np.isnan(E) != np.isnan(P))
    if half.size:
        i = int(half[0])
        col = found["phase"] if np.isnan(P[i]) else found["modulus"]
        raise InputError(
            f"{path}: line {i + 2}, column '{col}': empty while the other of |E*| and phase is given; "
            "give both, or leave both empty to forecast them"
        )
    out["E_norm_MPa"] = E * MODULUS_UNITS[fmt.modulus_unit]
    out["phase_deg"] = P * PHASE_UNITS[fmt.phase_unit]
    out["binder_G_MPa"] = (
        _number(path, frame, found["binder_modulus"], f"the binder |G*| in {fmt.binder_modulus_unit}")
        * MODULUS_UNITS[fmt.binder_modulus_unit]
    )
    out["binder_delta_deg"] = (
        _number(path, frame, found["binder_phase"], f"the binder phase angle in {fmt.binder_phase_unit}")
        * PHASE_UNITS[fmt.binder_phase_unit]
    )
    if "binder_viscosity" in found:
        eta = _number(path, frame, found["binder_viscosity"], f"a viscosity in {fmt.viscosity_unit}", empty_ok=True)
        out["binder_eta_Pa_s"] = eta * VISCOSITY_UNITS[fmt.viscosity_unit]
    else:
        out["binder_eta_Pa_s"] = np.nan
    if "binder_frequency" in found:
        out["binder_frequency_Hz"] = _number(path, frame, found["binder_frequency"], "the binder's frequency in Hz")
    else:
        out["binder_frequency_Hz"] = out["frequency_Hz"] * BINDER_FREQUENCY_UNITS[fmt.binder_frequency_unit]
    for q in ("rho34", "rho38", "rho4", "rho200", "Pb", "Va", "Vbeff", "pg_high", "pg_low"):
        if q in found:  # Pb may be left empty: no model reads it (its checks apply where it is given)
            out[QUANTITY_COLUMNS[q]] = _number(path, frame, found[q], f"the {q} of the mix", empty_ok=q == "Pb")
    if "Pb" not in found:
        out["Pb_pct"] = np.nan
    labels = {QUANTITY_COLUMNS[q]: f"'{c}'" for q, c in found.items()}
    _check_ranges(path, out, labels, fmt)
    _check_mixes(path, out, labels)
    _check_order_of_values(path, out, fmt)
    _check_phase_jumps(path, out, labels)
    measured = out[np.isfinite(out["E_norm_MPa"].to_numpy())]
    warned = []
    if len(measured):
        probe = measured.assign(specimen=measured["mix_id"])
        warned = check_values(probe, path, fmt.modulus_unit, labels)
    for text in warned:
        logging.getLogger("asphalt_nscd").warning("%s", text)
    order = {m: k for k, m in enumerate(dict.fromkeys(out["mix_id"]))}
    out = (
        out.assign(_mix=out["mix_id"].map(order))
        .sort_values(["_mix", "temperature_C", "frequency_Hz"], kind="stable")
        .drop(columns="_mix")
        .reset_index(drop=True)
    )
    out = out[[c for c in (*COLUMNS, *OPTIONAL_COLUMNS) if c in out.columns]]
    out.attrs.update(
        test=test,
        warnings=list(warned),
        source={"table": str(path), "declaration": fmt.where},
        dropped_columns=[c for c in frame.columns if c not in found.values()],
    )
    return out


def _number(path, frame, col: str, expected: str, empty_ok: bool = False) -> np.ndarray:
    """Column ``col`` as floats; InputError naming the line of a non-number (or of an empty cell
    unless ``empty_ok``, which reads empty cells as NaN)."""
    text = frame[col].str.strip()
    v = pd.to_numeric(text, errors="coerce").to_numpy(float)
    blank = (text == "").to_numpy()
    bad = np.flatnonzero(~np.isfinite(v) & ~(blank & empty_ok))
    if bad.size:
        i = int(bad[0])
        what = "empty cell" if blank[i] else f"value {frame[col].iloc[i]!r} is not a finite number"
        raise InputError(f"{path}: line {i + 2}, column '{col}': {what}; expected {expected}")
    return np.where(blank, np.nan, v) if empty_ok else v


def _by_order(path, mix: pd.Series, fmt: MatchedFormat) -> tuple[np.ndarray, np.ndarray]:
    """Temperatures and frequencies of the rows from the declared block order."""
    order = fmt.order or {}
    temps, freqs = order["temperatures"], order["frequencies_Hz"]
    n = len(temps) * len(freqs)
    T = np.empty(len(mix))
    f = np.empty(len(mix))
    values = mix.to_numpy()
    start = 0
    seen = set()
    while start < len(values):
        stop = start
        while stop < len(values) and values[stop] == values[start]:
            stop += 1
        if values[start] in seen:
            raise InputError(
                f"{path}: line {start + 2}, column mix: the rows of mix {values[start]!r} are not consecutive; "
                f"{fmt.where} key 'table.order' reads each mix as one run of {n} rows"
            )
        seen.add(values[start])
        if stop - start != n:
            raise InputError(
                f"{path}: lines {start + 2}-{stop + 1}: mix {values[start]!r} has {stop - start} rows; the order "
                f"declared in {fmt.where} (key 'table.order') needs {len(temps)} temperatures x {len(freqs)} "
                f"frequencies = {n}"
            )
        T[start:stop] = np.repeat(temps, len(freqs))
        f[start:stop] = np.tile(freqs, len(temps))
        start = stop
    return T, f


def _fail(path, index, col: str, value, expected: str) -> None:
    raise InputError(f"{path}: line {int(index) + 2}, column {col}: value {value:g} out of range; expected {expected}")


def _check_ranges(path, out: pd.DataFrame, labels: dict, fmt: MatchedFormat) -> None:
    from .checks import REFUSED

    def check(col, ok, expected):
        bad = np.flatnonzero(~ok)
        if bad.size:
            _fail(path, out.index[bad[0]], labels.get(col, f"'{col}'"), out[col].iloc[bad[0]], expected)

    for col, ref in (
        ("temperature_C", "temperature_C"),
        ("frequency_Hz", "frequency_Hz"),
        ("binder_frequency_Hz", "frequency_Hz"),
    ):
        lo, hi, unit, what = REFUSED[ref]
        v = out[col].to_numpy(float)
        check(col, (v >= lo) & (v <= hi), f"{what} in {lo:g}-{hi:g} {unit}")
    E = out["E_norm_MPa"].to_numpy(float)
    lo, hi, _, what = REFUSED["E_norm_MPa"]
    check(
        "E_norm_MPa", np.isnan(E) | ((E >= lo) & (E <= hi)), f"{what} in {lo:g}-{hi:g} MPa (read as {fmt.modulus_unit})"
    )
    P = out["phase_deg"].to_numpy(float)
    check(
        "phase_deg", np.isnan(P) | ((P >= 0) & (P < 90)), f"a phase angle in [0, 90) degrees (read as {fmt.phase_unit})"
    )
    G = out["binder_G_MPa"].to_numpy(float)
    lo, hi = BINDER_G_RANGE_MPA
    check(
        "binder_G_MPa", (G >= lo) & (G <= hi), f"a binder |G*| in {lo:g}-{hi:g} MPa (read as {fmt.binder_modulus_unit})"
    )
    d = out["binder_delta_deg"].to_numpy(float)
    check(
        "binder_delta_deg",
        (d > 0) & (d <= 90 + 1e-6),
        f"a binder phase angle in (0, 90] degrees (read as {fmt.binder_phase_unit})",
    )
    eta = out["binder_eta_Pa_s"].to_numpy(float)
    lo, hi = VISCOSITY_RANGE_PA_S
    check(
        "binder_eta_Pa_s",
        np.isnan(eta) | ((eta >= lo) & (eta <= hi)),
        f"a binder viscosity in {lo:g}-{hi:g} Pa s (the value in Pa s, read as {fmt.viscosity_unit}; "
        "asphalt_nscd.lab.matched.VISCOSITY_RANGE_PA_S)",
    )
    for col, unit in (("phase_deg", fmt.phase_unit), ("binder_delta_deg", fmt.binder_phase_unit)):
        v = out[col].dropna().to_numpy(float)
        if v.size > 1 and v.max() < 1.6:
            raise InputError(
                f"{path}: column {labels.get(col, col)}: every phase angle is below 1.6 (largest {v.max():.3g}, read "
                f"as {unit}): radians declared as degrees? Declare the unit in key 'table."
                f"{'phase_unit' if col == 'phase_deg' else 'binder_phase_unit'}' of the sidecar"
            )
    for col in ("rho34_pct", "rho38_pct", "rho4_pct", "rho200_pct"):
        v = out[col].to_numpy(float)
        check(col, (v >= 0) & (v <= 100), "a percentage in 0-100")
    for col, (lo, hi) in VOLUMETRIC_RANGES.items():
        v = out[col].to_numpy(float)
        given = (v > lo) & (v < hi)
        check(
            col,
            given | np.isnan(v) if col == "Pb_pct" else given,
            f"a volume or mass percentage of a mix in ({lo:g}, {hi:g}) %",
        )
    from .volumetrics import GB_BOUND, GMB_BOUND, binder_volume_bound

    Pb, Vbeff = out["Pb_pct"].to_numpy(float), out["Vbeff_pct"].to_numpy(float)
    fill = binder_volume_bound(Pb)
    bad = np.flatnonzero(Vbeff > fill)  # where Pb is given
    if bad.size:
        i = bad[0]
        raise InputError(
            f"{path}: line {int(out.index[i]) + 2}, column {labels.get('Vbeff_pct', 'Vbeff_pct')}: Vbeff {Vbeff[i]:g} % "
            f"is more binder than Pb {Pb[i]:g} % can fill; expected Vbeff <= Pb Gmb/Gb <= {fill[i]:.4g} % (Gmb <= "
            f"{GMB_BOUND:g}, Gb >= {GB_BOUND:g}: asphalt_nscd.lab.volumetrics)"
        )
    r34, r38, r4, p200 = (out[c].to_numpy(float) for c in ("rho34_pct", "rho38_pct", "rho4_pct", "rho200_pct"))
    bad = np.flatnonzero(~((r34 <= r38) & (r38 <= r4) & (r4 <= 100.0 - p200)))
    if bad.size:
        i = bad[0]
        raise InputError(
            f"{path}: line {int(out.index[i]) + 2}, columns rho34/rho38/rho4/rho200: retained 19 mm {r34[i]:g}, "
            f"9.5 mm {r38[i]:g}, 4.75 mm {r4[i]:g}, passing 0.075 mm {p200[i]:g}: not a cumulative gradation "
            "(expected rho34 <= rho38 <= rho4 <= 100 - rho200)"
        )


def _check_mixes(path, out: pd.DataFrame, labels: dict) -> None:
    """One formulation per mix; one viscosity per (mix, temperature); no repeated condition."""
    key = ["mix_id", "temperature_C", "frequency_Hz"]
    dup = np.flatnonzero(out.duplicated(subset=key, keep=False).to_numpy())
    if dup.size:
        r = out.iloc[dup[0]]
        raise InputError(
            f"{path}: line {int(out.index[dup[0]]) + 2}: repeated (mix, temperature, frequency) = "
            f"({r['mix_id']}, {r['temperature_C']:g} degC, {r['frequency_Hz']:g} Hz)"
        )
    cols = list(FORMULATION) + [c for c in OPTIONAL_COLUMNS if c in out.columns]
    for by, columns in ((["mix_id"], cols), (["mix_id", "temperature_C"], ["binder_eta_Pa_s"])):
        for col in columns:
            first = out.groupby(by, sort=False)[col].transform("first")
            v, f0 = out[col].to_numpy(float), first.to_numpy(float)
            bad = np.flatnonzero(~((v == f0) | (np.isnan(v) & np.isnan(f0))))
            if bad.size:
                i = bad[0]
                where = "mix" if len(by) == 1 else "mix and temperature"
                raise InputError(
                    f"{path}: line {int(out.index[i]) + 2}, column {labels.get(col, col)}: {v[i]:g} differs from "
                    f"the first row of its {where} ({f0[i]:g}); expected one value per {where}"
                )


def _check_order_of_values(path, out: pd.DataFrame, fmt: MatchedFormat) -> None:
    """Refuse a table whose values contradict its temperatures or frequencies (a declared block
    order that is not the file's): viscosity rising with temperature, or |E*| rising with the
    temperature / falling with the frequency in most (mix, frequency) / (mix, temperature) blocks."""
    origin = f"the order declared in {fmt.where} (key 'table.order')" if fmt.order else "the temperature column"
    eta = out.groupby(["mix_id", "temperature_C"], sort=True)["binder_eta_Pa_s"].first().dropna()
    if len(eta):
        rises = eta.groupby(level=0).apply(lambda s: bool(np.any(np.diff(np.log(s.to_numpy())) > 0)))
        if rises.any():
            m = rises.index[np.argmax(rises.to_numpy())]
            raise InputError(
                f"{path}: the binder viscosity of mix {m!r} rises with the temperature (a binder thins as it warms): "
                f"check {origin}"
            )
    col = "E_norm_MPa" if out["E_norm_MPa"].notna().any() else "binder_G_MPa"
    data = out.dropna(subset=[col])
    for along, by, wrong, name in (
        ("temperature_C", "frequency_Hz", 1, "rises with the temperature"),
        ("frequency_Hz", "temperature_C", -1, "falls with the frequency"),
    ):
        slopes = []
        for _, g in data.groupby(["mix_id", by], sort=False):
            if g[along].nunique() >= 2:
                x, y = g[along].to_numpy(float), np.log(g[col].to_numpy(float))
                slopes.append(np.sign(np.polyfit(x if along == "temperature_C" else np.log(x), y, 1)[0]))
        if slopes and np.mean(np.array(slopes) == wrong) > 0.5:
            what = "frequencies" if along == "frequency_Hz" else "temperatures"
            raise InputError(
                f"{path}: {'mix |E*|' if col == 'E_norm_MPa' else 'binder |G*|'} {name} in "
                f"{np.mean(np.array(slopes) == wrong):.0%} of the blocks: the {what} are in the wrong order; "
                f"check {origin}"
            )
    _check_order_per_mix(path, out, origin)


def _check_order_per_mix(path, out: pd.DataFrame, origin: str) -> None:
    """Refuse a mix whose own blocks contradict the order: its |E*| (its binder's |G*| when it has no
    |E*|) falling with the frequency in most of its temperature blocks, or rising with the
    temperature in most of its frequency blocks (rows written in reverse order within its blocks).
    The shipped table: 0 % of any mix's blocks with |E*|, at most 20 % with the binder's |G*|."""
    for mix, g in out.groupby("mix_id", sort=False):
        col = "E_norm_MPa" if g["E_norm_MPa"].notna().any() else "binder_G_MPa"
        g = g.dropna(subset=[col])
        for along, by, wrong, name in (
            ("frequency_Hz", "temperature_C", -1, "falls with the frequency"),
            ("temperature_C", "frequency_Hz", 1, "rises with the temperature"),
        ):
            slopes = []
            for _, b in g.groupby(by, sort=False):
                if b[along].nunique() >= 2:
                    x = b[along].to_numpy(float)
                    slopes.append(
                        np.sign(np.polyfit(np.log(x) if along == "frequency_Hz" else x, np.log(b[col]), 1)[0])
                    )
            share = float(np.mean(np.array(slopes) == wrong)) if slopes else 0.0
            if share > 0.5:
                lines = f"{int(g.index.min()) + 2}-{int(g.index.max()) + 2}"
                what = "frequencies" if along == "frequency_Hz" else "temperatures"
                raise InputError(
                    f"{path}: lines {lines}, mix {mix!r}: its {'|E*|' if col == 'E_norm_MPa' else 'binder |G*|'} "
                    f"{name} in {share:.0%} of its blocks: its {what} are written in reverse order? check the mix's "
                    f"rows against {origin}"
                )


#: a mix phase angle jumps from its isotherm when it differs from each neighbour in frequency by a ratio
#: above PHASE_JUMP_RATIO and by more than PHASE_JUMP_DEG (AASHTO T 378's phase-uniformity limit). The shipped
#: table's largest ratio to the nearer neighbour is 2.07 (mix 217, -10 degC, 25 Hz): 3 leaves half again in log
PHASE_JUMP_RATIO = 3.0
PHASE_JUMP_DEG = 3.0


def _check_phase_jumps(path, out: pd.DataFrame, labels: dict) -> None:
    """Refuse a measured mix phase angle that jumps from both its neighbours in frequency within
    its isotherm (one neighbour at the ends): a ratio above :data:`PHASE_JUMP_RATIO` and a
    difference above :data:`PHASE_JUMP_DEG` from each (a phase written 0, or off by a factor)."""
    data = out.dropna(subset=["phase_deg"])
    for (mix, T), g in data.groupby(["mix_id", "temperature_C"], sort=False):
        g = g.sort_values("frequency_Hz")
        y = g["phase_deg"].to_numpy(float)
        if y.size < 3:
            continue
        for i in range(y.size):
            nb = [y[j] for j in (i - 1, i + 1) if 0 <= j < y.size]
            ratio = [max(y[i], v) / min(y[i], v) if min(y[i], v) > 0 else np.inf for v in nb]
            if all(r > PHASE_JUMP_RATIO and abs(y[i] - v) > PHASE_JUMP_DEG for r, v in zip(ratio, nb)):
                row = g.index[i]
                f = g["frequency_Hz"].to_numpy(float)
                near = ", ".join(f"{y[j]:.3g} deg at {f[j]:g} Hz" for j in (i - 1, i + 1) if 0 <= j < y.size)
                raise InputError(
                    f"{path}: line {int(row) + 2}, column {labels.get('phase_deg', 'phase_deg')}: phase angle "
                    f"{y[i]:.3g} deg of mix {mix!r} at {T:.4g} degC, {f[i]:g} Hz jumps from its neighbours in the "
                    f"isotherm ({near}): expected within a factor {PHASE_JUMP_RATIO:g} or {PHASE_JUMP_DEG:g} deg of one of them"
                )


def write_matched(frame: pd.DataFrame, path) -> None:
    """Write a matched table in the project's columns (atomic; empty cells for NaN)."""
    from ..io import write_csv

    missing = [c for c in COLUMNS if c not in frame.columns]
    if missing:
        raise InputError(f"{path}: a matched table needs the columns {missing}")
    cols = [c for c in (*COLUMNS, *OPTIONAL_COLUMNS) if c in frame.columns]
    write_csv(frame[cols], path)
