"""The door of the chain: the shipped UIUC table and its sidecar, mutated the ways lab tables
go wrong (encodings, delimiters, columns, cells, units, sidecars), through ``asphalt-nscd
measured`` as the workflow runs it. Each mutation is refused with a one-line error naming the
file (and the line, column or key), accepted with a warning naming the likely cause, or
accepted as the valid table it is; none gives a traceback, none is accepted in silence when
it is nonsense. ``pytest tests/unit/test_lab_door.py -v`` lists every case and its outcome."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main

SHIPPED = Path(__file__).resolve().parents[2] / "data" / "measured" / "uiuc_fdmix1_utm"
TABLE = pd.read_csv(SHIPPED / "complex_modulus.csv")
SIDECAR = json.loads((SHIPPED / "complex_modulus.test.json").read_text())


def _csv(frame: pd.DataFrame) -> bytes:
    return frame.to_csv(index=False).encode()


def _sidecar(**changes) -> dict:
    side = json.loads(json.dumps(SIDECAR))
    for key, value in changes.items():
        if key.startswith("table."):
            side["table"][key[6:]] = value
        elif value is _DROP:
            side.pop(key)
        else:
            side[key] = value
    return side


_DROP = object()
HOT = TABLE["temperature_F"] == TABLE["temperature_F"].max()

#: name -> (table bytes, sidecar (dict, or raw text), expected outcome, pattern of the error or warning).
#: Outcomes: refused (exit 2, one line naming the file), warned (accepted, a warning naming the
#: likely cause), accepted (no warning), same (accepted, and the replicate summary is the shipped
#: table's: a valid way of writing the same table)
CASES = {
    # --- the file itself
    "empty file": (b"", None, "refused", r"complex_modulus\.csv: .*(empty|no data|no columns)"),
    "header only": (_csv(TABLE.iloc[:0]), None, "refused", r"no data rows"),
    "semicolon delimiter": (TABLE.to_csv(index=False, sep=";").encode(), None, "same", None),
    "latin-1 specimen names": (
        _csv(TABLE.assign(specimen=TABLE["specimen"] + "\u00e9")).decode().encode("latin-1"),
        None,
        "same",
        None,
    ),
    "UTF-8 byte-order mark": (b"\xef\xbb\xbf" + _csv(TABLE), None, "same", None),
    "CRLF line ends": (_csv(TABLE).replace(b"\n", b"\r\n"), None, "same", None),
    "CR-only line ends (old spreadsheet exports)": (_csv(TABLE).replace(b"\n", b"\r"), None, "same", None),
    "trailing blank line": (_csv(TABLE) + b"\n", None, "same", None),
    "trailing rows of empty cells (a spreadsheet export)": (
        _csv(TABLE) + (b"," * (TABLE.shape[1] - 1) + b"\n") * 3,
        None,
        "same",
        None,
    ),
    "tab-separated, an optional last column left empty": (
        TABLE.assign(operator="").to_csv(index=False, sep="\t").encode(),
        None,
        "same",
        None,
    ),
    "rows shuffled": (_csv(TABLE.sample(frac=1.0, random_state=3)), None, "same", None),
    "an extra column": (_csv(TABLE.assign(operator="jd")), None, "same", None),
    "only the 10 Hz rows": (_csv(TABLE[TABLE["frequency_Hz"] == 10.0]), None, "accepted", None),
    "two rows": (_csv(TABLE.iloc[:2]), None, "accepted", None),
    # --- columns
    "phase column missing": (_csv(TABLE.drop(columns="phase_deg")), None, "refused", r"phase"),
    "phase column twice": (
        TABLE.assign(p2=TABLE["phase_deg"]).to_csv(index=False).replace(",p2", ",phase_deg", 1).encode(),
        None,
        "refused",
        r"line 1 \(header\): duplicated column\(s\) \['phase_deg'\]",
    ),
    # --- cells
    "a word in a modulus cell": (
        _csv(
            TABLE.astype({"E_norm_MPa": object}).assign(E_norm_MPa=lambda t: t["E_norm_MPa"].where(t.index != 4, "abc"))
        ),
        None,
        "refused",
        r"line 6.*E_norm_MPa",
    ),
    "an empty modulus cell": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"].where(TABLE.index != 4))),
        None,
        "refused",
        r"line 6.*E_norm_MPa",
    ),
    "a modulus of 1e300": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"].where(TABLE.index != 4, 1e300))),
        None,
        "refused",
        r"line 6.*E_norm_MPa.*out of",
    ),
    "a modulus of 1e-300": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"].where(TABLE.index != 4, 1e-300))),
        None,
        "refused",
        r"line 6.*E_norm_MPa.*out of",
    ),
    "a frequency of 1e300": (
        _csv(TABLE.assign(frequency_Hz=TABLE["frequency_Hz"].where(TABLE.index != 4, 1e300))),
        None,
        "refused",
        r"line 6.*frequency_Hz.*out of",
    ),
    "a temperature of -1000 degF": (
        _csv(TABLE.assign(temperature_F=TABLE["temperature_F"].where(TABLE.index != 4, -1000.0))),
        None,
        "refused",
        r"line 6.*temperature_F.*out of",
    ),
    "a duplicated row": (_csv(pd.concat([TABLE, TABLE.iloc[[4]]])), None, "refused", r"duplicate"),
    "decimal commas, semicolons": (TABLE.to_csv(index=False, decimal=",", sep=";").encode(), None, "same", None),
    "decimal commas, unquoted, commas": (
        TABLE.to_csv(index=False, decimal=",", quoting=3, escapechar="\\").encode(),
        None,
        "refused",
        r"line 2",
    ),
    # --- units
    "every modulus x 1e6 (Pa declared MPa)": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"] * 1e6)),
        None,
        "refused",
        r"E_norm_MPa.*out of",
    ),
    "ksi values declared MPa": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"] / 6.894757)),
        None,
        "warned",
        r"ksi \(x 6\.895\)",
    ),
    "phases in radians": (_csv(TABLE.assign(phase_deg=np.radians(TABLE["phase_deg"]))), None, "warned", r"radians"),
    "hot isotherm 10 x stiffer": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"].where(~HOT, TABLE["E_norm_MPa"] * 10))),
        None,
        "warned",
        r"stiffer",
    ),
    "hot isotherm 100 x stiffer": (
        _csv(TABLE.assign(E_norm_MPa=TABLE["E_norm_MPa"].where(~HOT, TABLE["E_norm_MPa"] * 100))),
        None,
        "refused",
        r"E_norm_MPa.*out of range",
    ),
    "a phase of 75 deg": (
        _csv(TABLE.assign(phase_deg=TABLE["phase_deg"].where(TABLE.index != 4, 75.0))),
        None,
        "warned",
        r"above 60",
    ),
    # --- sidecars
    "sidecar declares ksi for E_norm_MPa": (
        _csv(TABLE),
        _sidecar(**{"table.modulus_unit": "ksi"}),
        "refused",
        r"ksi.*MPa|MPa.*ksi",
    ),
    "sidecar declares degC for temperature_F": (
        _csv(TABLE),
        _sidecar(**{"table.temperature_unit": "C"}),
        "refused",
        r"temperature_F",
    ),
    "sidecar diameter NaN": (
        _csv(TABLE),
        '{"test": "uniaxial_cylinder", "diameter_mm": NaN, "height_mm": 150}',
        "refused",
        r"diameter_mm",
    ),
    "sidecar height Infinity": (
        _csv(TABLE),
        '{"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": Infinity}',
        "refused",
        r"height_mm",
    ),
    "sidecar a 1e300 mm specimen": (
        _csv(TABLE),
        '{"test": "uniaxial_cylinder", "diameter_mm": 1e300, "height_mm": 150}',
        "refused",
        r"complex_modulus\.test\.json: key 'diameter_mm'.*at most 1000 mm",
    ),
    "sidecar a 0 mm specimen": (
        _csv(TABLE),
        '{"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 0}',
        "refused",
        r"complex_modulus\.test\.json: key 'height_mm'",
    ),
    "sidecar a 1e6 kg moving mass": (
        _csv(TABLE),
        '{"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 150, "moving_mass_kg": 1e6}',
        "refused",
        r"key 'moving_mass_kg'.*at most 100 kg",
    ),
    "sidecar without its test key": (_csv(TABLE), _sidecar(test=_DROP), "refused", r"'test'"),
    "sidecar maps two quantities to one column": (
        _csv(TABLE),
        _sidecar(**{"table.columns": {"temperature": "temperature_F", "frequency": "temperature_F"}}),
        "refused",
        r"temperature_F",
    ),
    "sidecar maps the modulus to the temperature column": (
        _csv(TABLE),
        _sidecar(**{"table.columns": {"temperature": "temperature_F", "modulus": "temperature_F"}}),
        "refused",
        r"temperature_F",
    ),
    "sidecar not JSON": (_csv(TABLE), "{test: uniaxial", "refused", r"complex_modulus\.test\.json"),
    "sidecar an unknown test": (_csv(TABLE), _sidecar(test="four_point_bending_beam_x"), "refused", r"test"),
}


def run_case(name: str, folder: Path) -> tuple[str, str]:
    """Run ``asphalt-nscd measured`` on the case's table and sidecar in ``folder``: (outcome,
    the error or the warnings)."""
    import contextlib
    import io

    table, side, _, _ = CASES[name]
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "complex_modulus.csv"
    path.write_bytes(table)
    side = SIDECAR if side is None else side
    (folder / "complex_modulus.test.json").write_text(side if isinstance(side, str) else json.dumps(side))
    err, records = io.StringIO(), []
    handler = logging.Handler()
    handler.emit = records.append
    log = logging.getLogger("asphalt_nscd")
    log.addHandler(handler)
    try:
        with contextlib.redirect_stderr(err):
            status = main(
                ["measured", str(path), "-o", str(folder / "out.csv"), "--summary", str(folder / "summary.csv")]
            )
    finally:
        log.removeHandler(handler)
    warned = [r.getMessage() for r in records if r.levelno == logging.WARNING]
    if status != 0:
        return "refused", err.getvalue().strip()
    return ("warned" if warned else "accepted"), "\n".join(warned)


@pytest.mark.parametrize("name", list(CASES))
def test_the_door_refuses_warns_or_accepts(name, tmp_path):
    import re

    _, _, expected, pattern = CASES[name]
    outcome, message = run_case(name, tmp_path)
    assert "Traceback" not in message
    assert outcome == ("accepted" if expected == "same" else expected), f"{name}: {outcome}: {message}"
    if expected == "same":
        reference = tmp_path / "reference"
        assert (
            main(
                [
                    "measured",
                    str(SHIPPED / "complex_modulus.csv"),
                    "-o",
                    str(reference / "t.csv"),
                    "--summary",
                    str(reference / "s.csv"),
                ]
            )
            == 0
        )
        pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "summary.csv"), pd.read_csv(reference / "s.csv"))
    if outcome == "refused":
        assert message.startswith("error: ") and "\n" not in message, message
        assert str(tmp_path) in message, message  # names the file
    if pattern:
        assert re.search(pattern, message), f"{name}: {message}"
    if outcome != "refused":
        assert (tmp_path / "out.csv").is_file()
    else:
        assert not (tmp_path / "out.csv").exists() and not (tmp_path / "summary.csv").exists()
