"""A sieve analysis as a lab reports it: the aggregate's passing curve and the four Witczak figures.

A sieve is named by its opening in mm (``19``, ``"0.075 mm"``, ``"75 um"``) or by its US
designation (``"1 1/2 in"``, ``"3/4 in"``, ``"3/8 in"``, ``"No. 4"``, ``"#8"``, ``"No. 200"``),
read as the opening of ASTM E11 Table 1 (:data:`US_INCH_SIEVES_MM`, :data:`US_NUMBER_SIEVES_MM`:
"1 in" is the 25.0 mm sieve, not 25.4 mm). A value per sieve is % passing (the default), the
cumulative % retained (passing = 100 - value), or the % retained on each sieve (passing on a
sieve = 100 - the sum retained on it and on every larger one; a ``Pan`` row, if given, closes the
sum at 100 within :data:`RETAINED_SUM_TOL_PCT`), all by mass of aggregate.

The passing curve (:meth:`SieveAnalysis.passing_at`) runs through the measured points up to the
top size (the smallest sieve with 100 % passing; 100 % at and above it) and is a power law between
two sieves, P = P_a (d / d_a)^n, i.e. linear in log P against log d (Fuller & Thompson 1907); below
the finest sieve it keeps the finest segment's exponent. It is, arithmetic included, the curve of
:func:`asphalt_nscd.forecast.formulation.passing_curve`: an analysis of the four Witczak sieves and
the top size reads exactly as that function reads the same four figures (but for a mix with nothing
retained on 9.5 mm, where that function's segment from 9.5 to 19 mm reads 100 + 4e-14, this 100).

The Witczak figures (:meth:`SieveAnalysis.witczak`): rho34, rho38, rho4 = 100 - % passing 19,
9.5, 4.75 mm (cumulative % retained) and rho200 = % passing 0.075 mm, read on the curve: a sieve
the lab did not use is interpolated, linear in log(passing) against log(opening), between the two
measured sieves around it. Nothing is extrapolated: 0.075 mm must lie within the measured sieves
and 19 mm at or below the top size (else 100 % passing).

Files: ``.csv``, ``.tsv`` or ``.txt`` with a sieve column and a value column, found by their common
headers (``Sieve``, ``Sieve size``, ``% Passing``, ``Cumulative % Retained``, ``% Retained``, ...)
or declared in the sidecar ``<stem>.test.json`` (``"table": {"form": "passing" |
"cumulative_retained" | "retained", "columns": {"sieve": ..., "value": ...}}``, the lab tables'
convention, :mod:`.table_format`). Refused (:class:`asphalt_nscd.io.InputError` naming the file,
line and column, or the key): an unknown sieve name, a sieve given twice, a value outside 0-100 or
not a number, passing that falls as the sieve grows, no sieve at or below 0.075 mm, no sieve with
100 % passing (the top size), 0 % passing at a sieve (no log-log curve), per-sieve percentages that
do not sum to 100.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np

from ..io import InputError

#: ASTM E11 Table 1, alternative designations in inches -> standard opening (mm)
US_INCH_SIEVES_MM = {
    Fraction(5): 125.0,
    Fraction("4.24"): 106.0,
    Fraction(4): 100.0,
    Fraction(7, 2): 90.0,
    Fraction(3): 75.0,
    Fraction(5, 2): 63.0,
    Fraction("2.12"): 53.0,
    Fraction(2): 50.0,
    Fraction(7, 4): 45.0,
    Fraction(3, 2): 37.5,
    Fraction(5, 4): 31.5,
    Fraction("1.06"): 26.5,
    Fraction(1): 25.0,
    Fraction(7, 8): 22.4,
    Fraction(3, 4): 19.0,
    Fraction(5, 8): 16.0,
    Fraction("0.530"): 13.2,
    Fraction(1, 2): 12.5,
    Fraction(7, 16): 11.2,
    Fraction(3, 8): 9.5,
    Fraction(5, 16): 8.0,
    Fraction("0.265"): 6.7,
    Fraction(1, 4): 6.3,
}
#: ASTM E11 Table 1, alternative designations "No. N" -> standard opening (mm)
US_NUMBER_SIEVES_MM = {
    Fraction(7, 2): 5.6,
    Fraction(4): 4.75,
    Fraction(5): 4.0,
    Fraction(6): 3.35,
    Fraction(7): 2.8,
    Fraction(8): 2.36,
    Fraction(10): 2.0,
    Fraction(12): 1.7,
    Fraction(14): 1.4,
    Fraction(16): 1.18,
    Fraction(18): 1.0,
    Fraction(20): 0.85,
    Fraction(25): 0.71,
    Fraction(30): 0.6,
    Fraction(35): 0.5,
    Fraction(40): 0.425,
    Fraction(45): 0.355,
    Fraction(50): 0.3,
    Fraction(60): 0.25,
    Fraction(70): 0.212,
    Fraction(80): 0.18,
    Fraction(100): 0.15,
    Fraction(120): 0.125,
    Fraction(140): 0.106,
    Fraction(170): 0.09,
    Fraction(200): 0.075,
    Fraction(230): 0.063,
    Fraction(270): 0.053,
    Fraction(325): 0.045,
    Fraction(400): 0.038,
    Fraction(450): 0.032,
    Fraction(500): 0.025,
    Fraction(635): 0.02,
}
#: the Witczak sieves: (figure, opening mm, retained: the figure is 100 - passing)
WITCZAK_SIEVES = (
    ("rho34_pct", 19.0, True),
    ("rho38_pct", 9.5, True),
    ("rho4_pct", 4.75, True),
    ("rho200_pct", 0.075, False),
)
FORMS = ("passing", "cumulative_retained", "retained")
#: (smallest, largest) opening (mm) read as a sieve: ASTM E11 spans 20 um to 125 mm
OPENING_RANGE_MM = (0.005, 300.0)
#: per-sieve % retained with a pan row must sum to 100 within this (AASHTO T 27 accepts a mass after
#: sieving within 0.3 % of the mass before; each percentage rounded to 0.1 adds up to 0.05 per sieve)
RETAINED_SUM_TOL_PCT = 1.0
#: two openings closer than this (relative) are the same sieve
SAME_SIEVE_RTOL = 1e-9
SUFFIXES = (".csv", ".tsv", ".txt")
#: column quantity -> common header names (compared lower case, letters and digits only, a trailing
#: bracketed unit dropped)
ALIASES = {
    "sieve": ["sieve", "sievesize", "sievedesignation", "sieveno", "sievenumber", "size", "opening", "sieveopening"],
    "passing": ["passing", "percentpassing", "passingpercent", "pctpassing", "cumulativepassing", "totalpassing"],
    "cumulative_retained": [
        "cumulativeretained",
        "cumulativepercentretained",
        "cumretained",
        "totalretained",
        "percentretainedcumulative",
    ],
    "retained": ["retained", "percentretained", "individualretained", "retainedonsieve", "individualpercentretained"],
}
_UNICODE_FRACTIONS = {"½": " 1/2", "¼": " 1/4", "¾": " 3/4", "⅛": " 1/8", "⅜": " 3/8", "⅝": " 5/8", "⅞": " 7/8"}


def _fraction(text: str) -> Fraction | None:
    """``"1 1/2"``, ``"3/4"``, ``"1"``, ``"0.530"`` as a Fraction, else None."""
    m = re.fullmatch(r"(?:(\d+)\s+)?(\d+)\s*/\s*(\d+)|(\d+(?:\.\d+)?)", text.strip())
    if not m:
        return None
    if m.group(4) is not None:
        return Fraction(m.group(4))
    whole = int(m.group(1) or 0)
    if int(m.group(3)) == 0:
        return None
    return whole + Fraction(int(m.group(2)), int(m.group(3)))


def sieve_opening_mm(name, where: str = "sieve") -> float:
    """The opening (mm) of a sieve named as a lab names it.

    Parameters
    ----------
    name : str or number
        A number (mm), ``"<number> mm"``, ``"<number> um"`` (or ``µm``), ``"<inches> in"`` (also
        ``"3/4\\""``, ``"1 1/2 inch"``, ``"¾ in"``) or ``"No. N"`` / ``"#N"`` / ``"No N"`` (ASTM E11).
    where : str
        What the name came from (file, line, column or key), for the message.

    Returns
    -------
    float, mm: the ASTM E11 standard opening of a US designation, else the number given.

    Raises
    ------
    InputError
        naming ``where``: a name that is not a sieve of ASTM E11 or an opening outside
        :data:`OPENING_RANGE_MM`.
    """
    if isinstance(name, bool):
        raise InputError(f"{where}: {name!r} is not a sieve")
    if isinstance(name, str) and re.fullmatch(r"[^()]+\([^()]+\)\s*", name.strip()):
        # "3/4 in (19.0 mm)", "No. 200 (75 um)": both names must be the same sieve
        first, second = name.strip()[:-1].split("(")
        a, b = sieve_opening_mm(first, where), sieve_opening_mm(second, where)
        if abs(a - b) > 0.05 * max(a, b):
            raise InputError(f"{where}: {name!r} names two sieves, {a:g} mm and {b:g} mm")
        return a
    if isinstance(name, (int, float)):
        value, unit = float(name), "mm"
    else:
        text = str(name).strip().lower()
        for k, v in _UNICODE_FRACTIONS.items():
            text = text.replace(k, v)
        text = re.sub(r"\s+", " ", text.replace("″", '"').replace("''", '"')).strip()
        m_in = re.fullmatch(r"(.+?)\s*(?:in\.?|inch|inches|\")", text)
        m_no = re.fullmatch(r"(?:no\.?|number|#)\s*(.+)", text)
        m_mm = re.fullmatch(r"(\d+(?:\.\d*)?|\.\d+)(?:e-?\d+)?\s*(mm|um|µm|μm)?", text)
        if m_in:
            inches = _fraction(m_in.group(1))
            if inches is None or inches not in US_INCH_SIEVES_MM:
                raise InputError(
                    f"{where}: {name!r} is not a sieve of ASTM E11 (inch sieves: "
                    f"{', '.join(_inch_text(k) for k in sorted(US_INCH_SIEVES_MM, reverse=True)[:12])}, ...)"
                )
            return US_INCH_SIEVES_MM[inches]
        if m_no:
            number = _fraction(m_no.group(1))
            if number is None or number not in US_NUMBER_SIEVES_MM:
                raise InputError(
                    f"{where}: {name!r} is not a sieve of ASTM E11 (No. 3 1/2, 4, 5, 6, 7, 8, 10, 12, 14, 16, 18, 20, "
                    "25, 30, 35, 40, 45, 50, 60, 70, 80, 100, 120, 140, 170, 200, 230, 270, 325, 400, 450, 500, 635)"
                )
            return US_NUMBER_SIEVES_MM[number]
        if not m_mm:
            raise InputError(
                f"{where}: {name!r} is not a sieve: expected an opening in mm (19, '0.075 mm', '75 um') or a US "
                "designation ('3/4 in', 'No. 4', '#200')"
            )
        try:
            value = float(text.split()[0].rstrip("muµμ"))
        except ValueError:
            raise InputError(f"{where}: {name!r} is not a sieve opening") from None
        unit = "mm" if m_mm.group(2) in (None, "mm") else "um"
        value = value / 1000.0 if unit == "um" else value
    lo, hi = OPENING_RANGE_MM
    if not (math.isfinite(value) and lo <= value <= hi):
        raise InputError(f"{where}: opening {value:g} mm out of range; expected a sieve of {lo:g}-{hi:g} mm")
    return value


def _inch_text(f: Fraction) -> str:
    whole, rest = divmod(f, 1)
    if rest == 0:
        return f"{whole} in"
    if f.denominator > 16:
        return f"{float(f):g} in"
    return f"{whole} {rest} in" if whole else f"{rest} in"


@dataclass(frozen=True)
class SieveAnalysis:
    """A checked sieve analysis (module docstring).

    ``openings_mm`` and ``passing_pct``: every sieve given, openings increasing (shape (n,)),
    % passing by mass of aggregate; ``names``: the sieves as the lab named them; ``where``: where
    it came from (file or key).
    """

    openings_mm: np.ndarray
    passing_pct: np.ndarray
    names: tuple
    where: str = ""

    @property
    def top_size_mm(self) -> float:
        """The smallest sieve with 100 % passing (mm)."""
        return float(self.openings_mm[np.flatnonzero(self.passing_pct >= 100.0)[0]])

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """The curve's points: openings (mm, increasing) up to the top size and their % passing."""
        k = int(np.flatnonzero(self.passing_pct >= 100.0)[0])
        return self.openings_mm[: k + 1].copy(), self.passing_pct[: k + 1].copy()

    def passing_at(self, openings_mm) -> np.ndarray:
        """% passing at ``openings_mm`` (mm, any shape; returned in that shape) on the piecewise
        power law through :meth:`points`: 100 at and above the top size, the finest segment's
        exponent below the finest sieve (the arithmetic of
        :func:`asphalt_nscd.forecast.formulation.passing_curve`).

        Raises ValueError for an opening that is not a positive number."""
        d, p = self.points()
        s = np.asarray(openings_mm, float)
        if not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError(f"passing_at: openings must be positive numbers (mm), got {openings_mm!r}")
        x, y = np.log(d), np.log(p)
        out = np.empty(s.shape)
        for idx, v in np.ndenumerate(s):
            if v >= d[-1]:
                out[idx] = 100.0
            elif v <= d[0]:
                n = (y[1] - y[0]) / (x[1] - x[0])
                out[idx] = float(np.exp(y[0] + n * (math.log(v) - x[0])))
            else:
                out[idx] = float(np.exp(np.interp(math.log(v), x, y)))
        return out

    def witczak(self) -> dict:
        """``rho34_pct, rho38_pct, rho4_pct`` (cumulative % retained on 19, 9.5, 4.75 mm) and
        ``rho200_pct`` (% passing 0.075 mm): the measured value at a measured sieve, else the curve
        between the two measured sieves around it (module docstring).

        Raises InputError naming the analysis when 0.075 mm lies below the finest sieve (no
        extrapolation)."""
        d, p = self.points()
        out = {}
        for name, size, retained in WITCZAK_SIEVES:
            same = np.flatnonzero(np.isclose(d, size, rtol=SAME_SIEVE_RTOL, atol=0.0))
            if size >= d[-1]:
                value = 100.0
            elif same.size:
                value = float(p[same[0]])
            elif size < d[0]:
                raise InputError(
                    f"{self.where}: no sieve at or below {size:g} mm (finest {d[0]:g} mm): {name} would be an "
                    "extrapolation; give the No. 200 (0.075 mm) sieve"
                )
            else:
                k = int(np.searchsorted(d, size))  # d[k - 1] < size < d[k]: kept between them (exp(log p) rounds)
                value = min(max(float(self.passing_at(size)), float(p[k - 1])), float(p[k]))
            out[name] = 100.0 - value if retained else value
        return out


def from_values(values, where: str, form: str = "passing") -> SieveAnalysis:
    """A sieve analysis from (sieve name, value) pairs or a mapping {sieve name: value}.

    Parameters
    ----------
    values : mapping or sequence of pairs
        Sieve names (:func:`sieve_opening_mm`; ``Pan`` for the pan, ``form="retained"`` only) and
        values in % by mass of aggregate.
    where : str
        The origin (file, key) named by every message; a pair may carry its own place as a third
        item (e.g. ``"file: line 4"``).
    form : one of :data:`FORMS` (module docstring).

    Returns
    -------
    SieveAnalysis

    Raises
    ------
    InputError
        naming ``where`` (and the sieve): module docstring, "Refused".
    """
    if form not in FORMS:
        raise InputError(f"{where}: form {form!r}; expected one of {list(FORMS)}")
    items = list(values.items()) if hasattr(values, "items") else [tuple(v) for v in values]
    rows = []
    pan = None
    for item in items:
        name, value = item[0], item[1]
        place = item[2] if len(item) > 2 else f"{where}: sieve {name!r}"
        x = _percent(value, place, form)
        if isinstance(name, str) and name.strip().lower() == "pan":
            if form != "retained":
                raise InputError(f"{place}: a pan row belongs to per-sieve % retained (form 'retained'), not {form!r}")
            pan = x
            continue
        rows.append((sieve_opening_mm(name, place), str(name), x, place))
    if not rows:
        raise InputError(f"{where}: no sieve given")
    rows.sort(key=lambda r: r[0])
    d = np.array([r[0] for r in rows])
    for k in range(1, len(rows)):
        if math.isclose(d[k], d[k - 1], rel_tol=SAME_SIEVE_RTOL):
            raise InputError(
                f"{rows[k][3]}: the {d[k]:g} mm sieve is given twice ({rows[k - 1][1]!r} and {rows[k][1]!r})"
            )
    v = np.array([r[2] for r in rows])
    p: np.ndarray
    if form == "passing":
        p = v
    elif form == "cumulative_retained":
        p = 100.0 - v
    else:
        cum = np.cumsum(v[::-1])[::-1]  # retained on a sieve and on every larger one
        total = float(cum[0]) + (pan or 0.0)
        if pan is not None and abs(total - 100.0) > RETAINED_SUM_TOL_PCT:
            raise InputError(
                f"{where}: the per-sieve % retained and the pan sum to {total:.4g} %; expected 100 within "
                f"{RETAINED_SUM_TOL_PCT:g} %"
            )
        if pan is None and cum[0] > 100.0 + RETAINED_SUM_TOL_PCT:
            raise InputError(f"{where}: the per-sieve % retained sum to {cum[0]:.4g} %, more than 100")
        p = np.clip(100.0 - cum * (100.0 / total if pan is not None else 1.0), 0.0, 100.0)
    return _checked(d, p, tuple(r[1] for r in rows), [r[3] for r in rows], where, form)


def _percent(value, place: str, form: str) -> float:
    if isinstance(value, bool):
        raise InputError(f"{place}: {value!r} is not a percentage")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{place}: {value!r} is not a number; expected a % {form.replace('_', ' ')}") from None
    if not (math.isfinite(v) and 0.0 <= v <= 100.0):
        raise InputError(f"{place}: {v:g} out of range; expected a percentage in 0-100 (% {form.replace('_', ' ')})")
    return v


def _checked(d, p, names, places, where: str, form: str) -> SieveAnalysis:
    """The analysis after the checks of the module docstring (cumulative, a sieve <= 0.075 mm,
    the top size, no 0 % passing)."""
    falls = np.flatnonzero(np.diff(p) < 0)
    if falls.size:
        k = int(falls[0])
        raise InputError(
            f"{places[k + 1]}: {p[k + 1]:g} % passing the {d[k + 1]:g} mm sieve is less than {p[k]:g} % passing the "
            f"smaller {d[k]:g} mm sieve ({names[k]!r}): not a cumulative gradation (read as form {form!r})"
        )
    if d[0] > 0.075 * (1 + SAME_SIEVE_RTOL):
        raise InputError(
            f"{where}: no sieve at or below 0.075 mm (No. 200), finest {d[0]:g} mm: the filler content (% passing "
            "0.075 mm) is needed"
        )
    if not np.any(p >= 100.0):
        raise InputError(
            f"{where}: no sieve with 100 % passing (largest {d[-1]:g} mm, {p[-1]:g} %): the top size is needed to "
            "close the curve; add the next larger sieve with 100"
        )
    zero = np.flatnonzero(p <= 0.0)
    if zero.size:
        k = int(zero[-1])
        raise InputError(
            f"{places[k]}: 0 % passing the {d[k]:g} mm sieve: the log-log passing curve needs > 0 at every sieve; "
            "leave out the sieves nothing passes"
        )
    return SieveAnalysis(np.asarray(d, float), np.asarray(p, float), tuple(names), where)


def from_witczak(
    rho34_pct: float, rho38_pct: float, rho4_pct: float, rho200_pct: float, where: str = ""
) -> SieveAnalysis:
    """The sieve analysis of a matched table's four figures with the top size of
    :func:`asphalt_nscd.forecast.formulation.passing_points` (25 mm when rho34 > 0, else 19 mm).

    Raises InputError as :func:`from_values`."""
    values = {19.0: 100.0 - rho34_pct, 9.5: 100.0 - rho38_pct, 4.75: 100.0 - rho4_pct, 0.075: rho200_pct}
    if rho34_pct > 0:
        values[25.0] = 100.0
    return from_values(values, where or "Witczak figures")


def read_sieve_analysis(path, sidecar=None) -> SieveAnalysis:
    """Read and check a sieve-analysis file (module docstring: headers, sidecar, checks).

    Parameters
    ----------
    path : str or Path
        ``.csv``, ``.tsv`` or ``.txt``, one row per sieve.
    sidecar : str or Path, optional
        Its declaration; default ``<stem>.test.json`` beside it, if present.

    Returns
    -------
    SieveAnalysis

    Raises
    ------
    InputError
        naming the file (the line and column of a bad value) or the sidecar and its key.
    """
    from .measured import _read_text_table

    path = Path(path)
    fmt = _read_sidecar(path, sidecar)
    frame = _read_text_table(path, allowed_suffixes=SUFFIXES)
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows after the header")
    declared = fmt.get("columns", {})
    keys = {_header_key(h): h for h in reversed(list(frame.columns))}

    def find(quantity):
        if quantity in declared:
            if declared[quantity] not in frame.columns:
                raise InputError(
                    f"{fmt['where']}: key 'table.columns.{quantity}': column {declared[quantity]!r} is not in the "
                    f"header {list(frame.columns)}"
                )
            return declared[quantity]
        return next((keys[a] for a in ALIASES[quantity] if a in keys), None)

    sieve_col = find("sieve")
    form = fmt.get("form")
    value_col = declared.get("value")
    if value_col is not None and value_col not in frame.columns:
        raise InputError(
            f"{fmt['where']}: key 'table.columns.value': column {value_col!r} is not in the header {list(frame.columns)}"
        )
    if value_col is None:
        forms = [form] if form else list(FORMS)
        found = [(f, find(f)) for f in forms]
        found = [(f, c) for f, c in found if c is not None]
        if found:
            form, value_col = found[0]
    if sieve_col is None or value_col is None:
        raise InputError(
            f"{path}: line 1 (header): no {'sieve' if sieve_col is None else 'value'} column in {list(frame.columns)}; "
            "name them 'sieve' and '% passing' (or 'cumulative % retained', '% retained'), or map them in key "
            "'table.columns' of the sidecar (asphalt_nscd.lab.sieve)"
        )
    form = form or "passing"
    pairs = []
    for i, (name, value) in enumerate(zip(frame[sieve_col].str.strip(), frame[value_col].str.strip())):
        place = f"{path}: line {i + 2}, column '{value_col}'"
        if name == "":
            raise InputError(f"{path}: line {i + 2}, column '{sieve_col}': empty sieve name")
        if value == "":
            raise InputError(f"{place}: empty cell; expected a % {form.replace('_', ' ')}")
        if name.lower() != "pan":
            sieve_opening_mm(name, f"{path}: line {i + 2}, column '{sieve_col}'")
        pairs.append((name, value, place))
    return from_values(pairs, str(path), form)


def _header_key(name: str) -> str:
    s = str(name).strip().lower().replace("%", " percent ")
    s = re.sub(r"[\(\[][^\)\]]*[\)\]]\s*$", "", s).strip()
    return re.sub(r"[^a-z0-9]", "", s)


#: JSON schema of a sieve-analysis sidecar (``<stem>.test.json``)
SIDECAR_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "properties": {
        "description": {"type": "string"},
        "source": {"type": "string"},
        "table": {
            "type": "object",
            "properties": {
                "form": {"enum": list(FORMS)},
                "columns": {
                    "type": "object",
                    "properties": {"sieve": {"type": "string"}, "value": {"type": "string"}},
                    "additionalProperties": False,
                },
            },
            "additionalProperties": False,
        },
    },
    "additionalProperties": False,
}


def _read_sidecar(path: Path, explicit) -> dict:
    """The ``table`` block of a sieve analysis's sidecar (empty without one), with ``where``."""
    from ..io import read_json
    from .geometry import sidecar_path

    side = Path(explicit) if explicit is not None else sidecar_path(path)
    if not side.is_file():
        if explicit is not None:
            raise InputError(f"{side}: file not found (the sidecar of {path})")
        return {"where": f"no sidecar {side.name}"}
    obj = read_json(side, what="sidecar JSON")
    validate(obj, SIDECAR_SCHEMA, str(side))
    return {**obj.get("table", {}), "where": str(side)}


def validate(obj, schema: dict, where: str, prefix: str = "") -> None:
    """Check ``obj`` against a JSON schema (draft 2020-12) as the project's sidecars and configs are
    checked (:func:`asphalt_nscd.config.check`).

    Raises
    ------
    InputError
        ``"<where>: key '<prefix><path>': <what the schema expects>"`` for the most relevant error.
    """
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema)
    error = jsonschema.exceptions.best_match(validator.iter_errors(obj))
    if error is None:
        return
    path = ".".join(str(k) for k in error.absolute_path)
    key = f"{prefix}{path}" if path else (prefix.rstrip(".") or "(top level)")
    if error.validator == "additionalProperties":
        allowed = sorted(error.schema.get("properties", {}))
        extra = sorted(set(error.instance) - set(allowed)) if isinstance(error.instance, dict) else []
        key = ".".join(p for p in (key if key != "(top level)" else "", extra[0] if extra else "") if p)
        raise InputError(f"{where}: key '{key}': unknown key; allowed: {allowed}")
    raise InputError(f"{where}: key '{key}': {error.message}")
