"""Ingestion of measured complex-modulus tables (docs/design.md, "Measured tables").

A measured table is a CSV with one row per (specimen, temperature, frequency):

==================  ========  ===========================================
column              unit      rule
==================  ========  ===========================================
specimen            –         required, non-empty text
temperature_C       degC      required, finite number
frequency_Hz        Hz        required, > 0
E_norm_MPa          MPa       required, > 0 (norm of the complex modulus)
phase_deg           degrees   required, in [0, 90)
strain_microstrain  1e-6      optional, > 0
test_order          –         optional, integer
(any other)         –         carried along unchanged
==================  ========  ===========================================

A lab's own table (other column names, ksi or psi, degF, E1 and E2) is read through the
``table`` block of its sidecar (:mod:`asphalt_nscd.lab.table_format`) and converted to these
columns; the carried columns keep the lab's originals.

(specimen, temperature_C, frequency_Hz) must be unique, or, with a ``test_order``, unique
with its test order (a frequency tested again at the end of an isotherm: a repeat, which
is what lets an effect along the tests be told from one along the frequency). The test that produced the table
(2PB trapezoid, uniaxial cylinder or unknown, with its dimensions) is declared in a JSON
sidecar ``<table stem>.test.json`` or an explicit file (:mod:`asphalt_nscd.lab.geometry`);
:func:`load_measured` attaches it to the frame as ``frame.attrs["test"]``. Any violation raises
:class:`asphalt_nscd.io.InputError` naming the file, the file line (the header is line 1)
and the column; nothing is written by the callers in that case.

``summarize`` gives the replicate mean and the sample standard deviation (ddof = 1; NaN
for a single specimen) of |E*| and Phi per (temperature, frequency) (the measured summary,
``results/lab/measured_summary.csv``); :func:`read_summary` reads it back and checks it
(columns :data:`SUMMARY_COLUMNS`, one row per (temperature, frequency)).
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError

REQUIRED_COLUMNS = ("specimen", "temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg")
OPTIONAL_COLUMNS = ("strain_microstrain", "test_order")
KEY_COLUMNS = ("specimen", "temperature_C", "frequency_Hz")
SUMMARY_COLUMNS = (
    "temperature_C",
    "frequency_Hz",
    "n",
    "E_norm_MPa_mean",
    "E_norm_MPa_std",
    "phase_deg_mean",
    "phase_deg_std",
)

#: column -> (check on finite float values, expectation in the error message)
_RANGES = {
    "temperature_C": (lambda v: np.ones_like(v, dtype=bool), "a finite temperature in degC"),
    "frequency_Hz": (lambda v: v > 0, "a frequency > 0 Hz"),
    "E_norm_MPa": (lambda v: v > 0, "|E*| > 0 MPa"),
    "phase_deg": (lambda v: (v >= 0) & (v < 90), "a phase angle in [0, 90) degrees"),
    "strain_microstrain": (lambda v: v > 0, "a strain amplitude > 0 microstrain"),
    "test_order": (lambda v: v == np.round(v), "an integer test order"),
}


#: summary column -> (check on the values, expectation); the std columns may be NaN (n = 1)
_SUMMARY_RANGES = {
    "temperature_C": _RANGES["temperature_C"],
    "frequency_Hz": _RANGES["frequency_Hz"],
    "n": (lambda v: (v >= 1) & (v == np.round(v)), "a replicate count, an integer >= 1"),
    "E_norm_MPa_mean": _RANGES["E_norm_MPa"],
    "E_norm_MPa_std": (lambda v: np.isnan(v) | (v >= 0), "a standard deviation >= 0 MPa (or NaN for n = 1)"),
    "phase_deg_mean": _RANGES["phase_deg"],
    "phase_deg_std": (lambda v: np.isnan(v) | (v >= 0), "a standard deviation >= 0 degrees (or NaN for n = 1)"),
}


def _line(index: int | np.integer) -> int:
    """File line of data row ``index`` (0-based; header on line 1)."""
    return int(index) + 2


def _numeric_column(
    path, frame: pd.DataFrame, column: str, ranges: dict, allow_nan: bool = False, label: str | None = None
) -> np.ndarray:
    """The values of ``frame[column]`` as floats, checked against ``ranges[column]``.

    Raises InputError naming the file, the line and the column on a non-numeric or missing
    value (unless ``allow_nan``) or a value out of range."""
    raw = frame[column]
    text = pd.Series([str(v).strip() for v in raw], index=raw.index, dtype=object)
    values = pd.to_numeric(raw if pd.api.types.is_numeric_dtype(raw) else text, errors="coerce").to_numpy(dtype=float)
    check, expected = ranges[column]
    name = label or column
    for i in range(len(values)):
        if not np.isfinite(values[i]) and not (
            allow_nan and np.isnan(values[i]) and text.iloc[i].lower() in {"", "nan", "na", "null"}
        ):
            kind = (
                "missing value (NaN)"
                if text.iloc[i] == "" or text.iloc[i].lower() in {"nan", "na", "null"}
                else "non-numeric value"
            )
            raise InputError(f"{path}: line {_line(i)}, column '{name}': {kind} {raw.iloc[i]!r}; expected {expected}")
    bad = np.flatnonzero(~check(values))
    if bad.size:
        i = bad[0]
        raise InputError(
            f"{path}: line {_line(i)}, column '{name}': value {values[i]:g} out of range; expected {expected}"
        )
    return values


def load_measured(path, test=None) -> pd.DataFrame:
    """Read and validate a measured complex-modulus table.

    Parameters
    ----------
    path : str or Path
        CSV file with the columns of the module docstring.
    test : str or Path, optional
        Test-geometry JSON of the table; default the sidecar ``<stem>.test.json`` next to
        it if present, else an unknown test (:func:`asphalt_nscd.lab.geometry.declared_test`).

    Returns
    -------
    DataFrame, shape (n_rows, n_columns)
        Required columns first (specimen as str, the others float), optional ones next
        (test_order as int), other columns carried along; rows sorted by temperature,
        frequency and specimen. ``attrs["test"]``: the declared test
        (:class:`asphalt_nscd.lab.geometry.DeclaredTest`); ``attrs["warnings"]``: the
        plausibility warnings of the values (:func:`asphalt_nscd.lab.checks.check_values`).

    Raises
    ------
    InputError
        if the file is missing, empty, not a CSV text table, lacks a required column,
        holds a non-numeric, NaN or out-of-range value (:mod:`.checks`: values no
        complex-modulus test of a bituminous material gives), or repeats a
        (specimen, temperature_C, frequency_Hz) key (with the same test_order, when the table
        has one) — naming file, line and column; or if
        the test-geometry JSON is invalid (naming that file and the key).
    """
    from .geometry import declared_test
    from .table_format import to_own_columns

    path = Path(path)
    frame = _read_text_table(path)
    declared = declared_test(path, test)
    labels: dict[str, str] = {}
    if declared.table is not None:  # a lab's table: its columns and units declared in the sidecar
        if len(frame) == 0:
            raise InputError(f"{path}: no data rows after the header")
        frame, labels = to_own_columns(frame, declared.table, path)
    missing = [c for c in REQUIRED_COLUMNS if c not in frame.columns]
    if missing:
        from .geometry import sidecar_path

        raise InputError(
            f"{path}: line 1 (header): missing column(s) {missing}; "
            f"found {list(frame.columns)}, expected at least {list(REQUIRED_COLUMNS)}, or a declaration of the "
            f"table's columns and units in key 'table' of {sidecar_path(path).name} (asphalt_nscd.lab.table_format: "
            "modulus_unit MPa|GPa|kPa|ksi|psi, temperature_unit C|F, modulus_form norm_phase|storage_loss)"
        )
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows after the header")

    out = pd.DataFrame(index=frame.index)
    spec = frame["specimen"].str.strip()
    empty = np.flatnonzero((spec == "").to_numpy())
    if empty.size:
        raise InputError(
            f"{path}: line {_line(empty[0])}, column 'specimen': empty value (NaN); expected a specimen name"
        )
    out["specimen"] = spec
    numeric = [c for c in (*REQUIRED_COLUMNS[1:], *OPTIONAL_COLUMNS) if c in frame.columns]
    for column in numeric:
        values = _numeric_column(path, frame, column, _RANGES, label=labels.get(column))
        out[column] = values.astype(int) if column == "test_order" else values

    _reject_duplicate_keys(path, out)
    from .checks import check_values

    unit = declared.table.modulus_unit if declared.table is not None else "MPa"
    warned = check_values(out, path, unit, labels)
    for text in warned:
        logging.getLogger("asphalt_nscd").warning("%s", text)

    for column in frame.columns:
        if column not in out.columns:
            try:  # carried along: numeric if every value parses, text otherwise
                out[column] = pd.to_numeric(frame[column])
            except (ValueError, TypeError):
                out[column] = frame[column]
    order = ["temperature_C", "frequency_Hz", "specimen"] + (["test_order"] if "test_order" in out.columns else [])
    out = out.sort_values(order, kind="stable").reset_index(drop=True)
    out.attrs["test"] = declared
    out.attrs["warnings"] = list(warned)
    return out


def _read_text_table(path: Path, allowed_suffixes: tuple = (".csv",)) -> pd.DataFrame:
    """The CSV at ``path`` as text cells (str, no NaN), header names stripped. Columns may be
    separated by commas, semicolons or tabs (the header's most frequent one); a table separated
    by semicolons or tabs may write decimal commas (``0,5``), read as points. Blank lines at the
    end of the file are ignored.

    Raises InputError if the file is missing, not a .csv, empty, binary, not readable as CSV
    (a line with more fields than the header: decimal commas in a comma-separated file?), or
    repeats a column name."""
    import csv
    import io

    if not path.is_file():
        raise InputError(f"{path}: file not found")
    if path.suffix.lower() not in allowed_suffixes:
        raise InputError(f"{path}: expected a {'/'.join(allowed_suffixes)} file, got suffix '{path.suffix}'")
    raw = path.read_bytes()
    if not raw.strip():
        raise InputError(f"{path}: file is empty; expected a header line with columns {list(REQUIRED_COLUMNS)}")
    if b"\x00" in raw:
        raise InputError(f"{path}: not a CSV text file (binary content)")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    # line endings of every origin: CR LF (Windows), LF, and CR alone (old spreadsheet exports)
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    # trailing blank lines, and trailing rows of empty cells (a spreadsheet's export of formatted empty rows); the
    # last row's own empty cells stay (an optional last column left empty in a tab-separated file)
    lines = text.split("\n")
    while lines and not lines[-1].strip(" \t,;"):
        lines.pop()
    text = "\n".join(lines) + "\n"
    first = text.splitlines()[0]
    sep = max((",", ";", "\t"), key=first.count)
    header = next(csv.reader([first], delimiter=sep))
    names = [h.strip() for h in header]
    dups = sorted({n for n in names if names.count(n) > 1})
    if dups:
        raise InputError(f"{path}: line 1 (header): duplicated column(s) {dups}")
    for i, row in enumerate(csv.reader(io.StringIO(text), delimiter=sep)):
        if row and len(row) != len(header):
            hint = (
                " (unquoted decimal commas in a comma-separated file? write 0.5, or separate the columns with ';')"
                if sep == "," and len(row) > len(header) and re.search(r"\d,\d", text)
                else ""
            )
            raise InputError(f"{path}: line {i + 1}: {len(row)} fields, the header has {len(header)}{hint}")
    try:
        frame = pd.read_csv(
            io.StringIO(text), dtype=str, keep_default_na=False, skip_blank_lines=False, sep=sep, index_col=False
        )
    except pd.errors.ParserError as exc:
        raise InputError(f"{path}: not a readable CSV file ({exc})") from None
    if sep != ",":
        decimal = re.compile(r"^\s*-?\d+,\d+(?:[eE][-+]?\d+)?\s*$")
        for c in frame.columns:
            col = frame[c]
            if col.str.match(decimal).any():
                frame[c] = col.str.replace(",", ".", regex=False).where(col.str.match(decimal), col)
    frame.columns = names
    return frame


def _reject_duplicate_keys(path: Path, out: pd.DataFrame) -> None:
    """Raise InputError naming the file lines of the first repeated (specimen, temperature_C,
    frequency_Hz) key of ``out`` (rows in file order), if any; with a ``test_order`` column a
    key repeated at another test order is a repeated test, not a duplicate."""
    key = list(KEY_COLUMNS) + (["test_order"] if "test_order" in out.columns else [])
    dup = out.duplicated(subset=key, keep=False).to_numpy()
    if dup.any():
        rows = np.flatnonzero(dup)
        first = out.iloc[rows[0]]
        same = rows[
            (out["specimen"].iloc[rows] == first["specimen"]).to_numpy()
            & (out["temperature_C"].iloc[rows] == first["temperature_C"]).to_numpy()
            & (out["frequency_Hz"].iloc[rows] == first["frequency_Hz"]).to_numpy()
            & ((out["test_order"].iloc[rows] == first["test_order"]).to_numpy() if "test_order" in key else True)
        ]
        raise InputError(
            f"{path}: lines {', '.join(str(_line(i)) for i in same)}, columns {key}: duplicate row "
            f"(specimen={first['specimen']!r}, temperature_C={first['temperature_C']:g}, frequency_Hz={first['frequency_Hz']:g})"
        )


def summarize(df: pd.DataFrame) -> pd.DataFrame:
    """Replicate mean and scatter of |E*| and Phi per (temperature, frequency).

    Parameters
    ----------
    df : DataFrame
        Validated table from :func:`load_measured` (or any frame with the required columns).

    Returns
    -------
    DataFrame, one row per (temperature_C, frequency_Hz), sorted
        ``temperature_C, frequency_Hz, n, E_norm_MPa_mean, E_norm_MPa_std, phase_deg_mean,
        phase_deg_std`` (MPa, degrees; std is the sample standard deviation, ddof = 1, NaN
        when n = 1).
    """
    grouped = df.groupby(["temperature_C", "frequency_Hz"], sort=True)
    out = grouped.agg(
        n=("E_norm_MPa", "size"),
        E_norm_MPa_mean=("E_norm_MPa", "mean"),
        E_norm_MPa_std=("E_norm_MPa", "std"),
        phase_deg_mean=("phase_deg", "mean"),
        phase_deg_std=("phase_deg", "std"),
    ).reset_index()
    return out[list(SUMMARY_COLUMNS)]


def read_summary(path) -> pd.DataFrame:
    """Read and check a measured summary written from :func:`summarize` (the measured means
    per (temperature, frequency), ``results/lab/measured_summary.csv``).

    Returns
    -------
    DataFrame, one row per (temperature_C, frequency_Hz), columns as in the file (at least
    :data:`SUMMARY_COLUMNS`; MPa, degrees), values as pandas parses them.

    Raises
    ------
    InputError
        naming the file, and the line and column where it applies: the file is missing or not
        a CSV table, a column of :data:`SUMMARY_COLUMNS` is missing, a value is non-numeric,
        missing (a std may be NaN) or out of range (frequency > 0 Hz, mean |E*| > 0 MPa, mean
        phase in [0, 90) degrees, n an integer >= 1, std >= 0), or a (temperature_C,
        frequency_Hz) pair is repeated.
    """
    from ..io import read_csv, require_columns

    frame = read_csv(path)
    require_columns(
        frame, SUMMARY_COLUMNS, path, f"{list(SUMMARY_COLUMNS)} (a measured summary of 'asphalt-nscd measured')"
    )
    if len(frame) == 0:
        raise InputError(f"{path}: no data rows after the header")
    for column in SUMMARY_COLUMNS:
        _numeric_column(path, frame, column, _SUMMARY_RANGES, allow_nan=column.endswith("_std"))
    dup = np.flatnonzero(frame.duplicated(subset=["temperature_C", "frequency_Hz"], keep=False).to_numpy())
    if dup.size:
        row = frame.iloc[dup[0]]
        raise InputError(
            f"{path}: lines {', '.join(str(_line(i)) for i in dup)}: repeated (temperature_C, "
            f"frequency_Hz) = ({row['temperature_C']:g}, {row['frequency_Hz']:g}); expected one "
            "row per (temperature, frequency)"
        )
    return frame
