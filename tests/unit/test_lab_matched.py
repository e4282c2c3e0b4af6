"""The matched binder-mix table through its door: the shipped file as published, its sidecar, and
the ways such a table goes wrong (units, block order, line endings, cells, gradations), each
refused with a one-line error naming the file and the line, column or key, or read as the same
table."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.matched import COLUMNS, read_matched, write_matched

SHIPPED = Path(__file__).resolve().parents[2] / "data" / "binder_mix"
TABLE = SHIPPED / "mixes_35.tsv"
SIDECAR = json.loads((SHIPPED / "mixes_35.test.json").read_text())
RAW = (TABLE.read_bytes()).decode("utf-8")


def _write(folder: Path, text: str | bytes, sidecar: dict | str | None = None, name: str = "mixes.tsv") -> Path:
    path = folder / name
    path.write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    side = SIDECAR if sidecar is None else sidecar
    path.with_name(path.stem + ".test.json").write_text(side if isinstance(side, str) else json.dumps(side))
    return path


def _sidecar(**table) -> dict:
    side = json.loads(json.dumps(SIDECAR))
    side["table"].update(table)
    return side


def _lines() -> list[str]:
    return RAW.rstrip("\n").split("\n")


@pytest.fixture(scope="module")
def shipped() -> pd.DataFrame:
    return read_matched(TABLE)


def test_the_shipped_table_reads_in_si_with_its_block_order(shipped):
    assert shipped.shape[0] == 35 * 30 and list(shipped.columns[: len(COLUMNS)]) == list(COLUMNS)
    assert shipped["mix_id"].nunique() == 35
    first = shipped[shipped["mix_id"] == "193"]
    # the file's first row: mix 193 at 14 degF (-10 degC) and 25 Hz, |E*| 2149650.767 psi, phase 0.106665797 rad
    row = first[(first["temperature_C"] == -10.0) & (first["frequency_Hz"] == 25.0)].iloc[0]
    assert row["E_norm_MPa"] == pytest.approx(2149650.767 * 6.894757293168361e-3, rel=1e-12)
    assert row["phase_deg"] == pytest.approx(math.degrees(0.106665797), rel=1e-12)
    assert row["binder_G_MPa"] == pytest.approx(3305.744883 * 6.894757293168361e-3, rel=1e-12)
    assert row["binder_eta_Pa_s"] == pytest.approx(6.64023e12 * 1e-3, rel=1e-12)
    # the binder columns refer to an angular frequency of 25 rad/s (data/binder_mix/SOURCE.md)
    assert row["binder_frequency_Hz"] == pytest.approx(25.0 / (2 * math.pi), rel=1e-12)
    assert sorted(first["temperature_C"].round(6).unique()) == pytest.approx(
        [-10.0, 4.444444, 21.111111, 37.777778, 54.444444]
    )
    # the source's reduced frequency, computed from the mix's own shift factors, is not read
    assert "w" not in shipped.columns and shipped.attrs["dropped_columns"] == ["w"]


def test_the_project_format_reads_back_identically(shipped, tmp_path):
    path = tmp_path / "matched.csv"
    write_matched(shipped, path)
    again = read_matched(path)
    pd.testing.assert_frame_equal(again.reset_index(drop=True), shipped.reset_index(drop=True), check_dtype=False)


def test_empty_cells_are_the_mixes_to_forecast(tmp_path):
    lines = _lines()
    out = [lines[0]] + [
        "\t".join([c if k not in (1, 2) else "" for k, c in enumerate(ln.split("\t"))])
        if ln.startswith("193\t")
        else ln
        for ln in lines[1:]
    ]
    table = read_matched(_write(tmp_path, "\n".join(out) + "\n"))
    todo = table[table["E_norm_MPa"].isna()]
    assert set(todo["mix_id"]) == {"193"} and len(todo) == 30 and todo["phase_deg"].isna().all()


def test_pb_is_optional_and_checked_where_given(tmp_path, shipped):
    """No model reads the binder content Pb: a table without its column, or with one mix's cells left
    empty, reads the same table with Pb NaN there; where given, a Vbeff it cannot fill is refused."""
    header, *rows = _lines()
    cells = [ln.split("\t") for ln in rows]
    k = header.split("\t").index("Pb")
    no_column = "\n".join("\t".join(c[:k] + c[k + 1 :]) for c in [header.split("\t"), *cells]) + "\n"
    side = json.loads(json.dumps(SIDECAR))
    del side["table"]["columns"]["Pb"]
    emptied = "\n".join(
        [header] + ["\t".join(c[:k] + [""] + c[k + 1 :]) if c[0] == "211" else "\t".join(c) for c in cells]
    )
    for folder, text, sidecar, gone in (
        ("no_column", no_column, side, set(shipped["mix_id"])),
        ("emptied", emptied + "\n", None, {"211"}),
    ):
        (tmp_path / folder).mkdir()
        table = read_matched(_write(tmp_path / folder, text, sidecar))
        nan = table["Pb_pct"].isna()
        assert set(table.loc[nan, "mix_id"]) == gone and set(table.loc[~nan, "mix_id"]).isdisjoint(gone)
        pd.testing.assert_frame_equal(table.drop(columns="Pb_pct"), shipped.drop(columns="Pb_pct"))
    (tmp_path / "short").mkdir()
    short = "\n".join(
        [header] + ["\t".join(c[:k] + ["2.0"] + c[k + 1 :]) if c[0] == "211" else "\t".join(c) for c in cells]
    )
    with pytest.raises(InputError, match=r"Vbeff .* is more binder than Pb 2 % can fill"):
        read_matched(_write(tmp_path / "short", short + "\n"))


@pytest.mark.parametrize(
    "name,mutate,pattern",
    [
        (
            "modulus declared MPa (psi values)",
            lambda t: (t, _sidecar(modulus_unit="MPa")),
            r"line 2, column '\|E\*\|'.*out of range",
        ),
        (
            "binder declared MPa (psi values)",
            lambda t: (t, _sidecar(binder_modulus_unit="MPa")),
            r"column '\|G\*\|'.*binder",
        ),
        (
            "mix phase declared deg (radians)",
            lambda t: (t, _sidecar(phase_unit="deg")),
            r"column 'φ'.*radians declared as degrees",
        ),
        ("binder phase declared deg (radians)", lambda t: (t, _sidecar(binder_phase_unit="deg")), r"'δb'.*radians"),
        (
            "temperatures declared warm first",
            lambda t: (
                t,
                _sidecar(order={"temperatures": [130, 100, 70, 40, 14], "frequencies_Hz": [25, 10, 5, 1, 0.5, 0.1]}),
            ),
            r"viscosity of mix '193' rises with the temperature.*table\.order",
        ),
        (
            "frequencies declared slow first",
            lambda t: (
                t,
                _sidecar(order={"temperatures": [14, 40, 70, 100, 130], "frequencies_Hz": [0.1, 0.5, 1, 5, 10, 25]}),
            ),
            r"falls with the frequency.*wrong order",
        ),
        (
            "a mix one row short",
            lambda t: ("\n".join(_lines()[:-1]) + "\n", None),
            r"lines .*mix '243' has 29 rows.*30",
        ),
        (
            "a word in a modulus cell",
            lambda t: (t.replace("2149650.767", "abc", 1), None),
            r"line 2, column '\|E\*\|': value 'abc'",
        ),
        (
            "a phase without its modulus",
            lambda t: (t.replace("2149650.767", "", 1), None),
            r"line 2, column '\|E\*\|': empty while",
        ),
        ("a mix id with a slash", lambda t: (t.replace("\n193\t", "\n19/3\t"), None), r"mix identifier '19/3'"),
        (
            "an unknown sidecar key",
            lambda t: (t, _sidecar(phase_units="rad")),
            r"key 'table\.phase_units': unknown key",
        ),
        ("an unknown unit", lambda t: (t, _sidecar(viscosity_unit="mPa s")), r"key 'table\.viscosity_unit'"),
        (
            "a mapped column missing",
            lambda t: (t.replace("ρ200", "p200", 1), None),
            r"key 'table\.columns\.rho200': column 'ρ200' is not",
        ),
        (
            "a 1e300 mm specimen",
            lambda t: (t, {**SIDECAR, "diameter_mm": 1e300}),
            r"key 'diameter_mm'.*at most 1000 mm",
        ),
    ],
)
def test_bad_tables_are_refused_naming_file_and_place(tmp_path, name, mutate, pattern):
    text, side = mutate(RAW)
    path = _write(tmp_path, text, side)
    with pytest.raises(InputError, match=pattern) as err:
        read_matched(path)
    assert path.stem in str(err.value) and "\n" not in str(err.value)  # the table or its sidecar


def test_a_gradation_that_is_not_cumulative_is_refused(tmp_path):
    lines = _lines()
    cols = lines[1].split("\t")
    cols[5] = "40"  # retained on 9.5 mm above the 4.75 mm figure (33): not cumulative
    bad = [lines[0], "\t".join(cols), *lines[2:]]
    with pytest.raises(InputError, match=r"line 2, columns rho34/rho38/rho4/rho200: .*not a cumulative gradation"):
        read_matched(_write(tmp_path, "\n".join(bad) + "\n"))


def test_a_formulation_that_changes_within_a_mix_is_refused(tmp_path):
    lines = _lines()
    cols = lines[5].split("\t")
    cols[9] = "7.0"  # Va of the 4th row of mix 193 (ID, |E*|, φ, w, ρ3/4, ρ3/8, ρ4, ρ200, Pb, Va, ...)
    bad = [*lines[:5], "\t".join(cols), *lines[6:]]
    with pytest.raises(InputError, match=r"line 6, column 'Va': 7 differs from the first row of its mix"):
        read_matched(_write(tmp_path, "\n".join(bad) + "\n"))


@pytest.mark.parametrize("ending", [b"\r\n", b"\r"], ids=["CRLF", "CR only"])
def test_line_endings_of_old_exports_read_the_same_table(tmp_path, shipped, ending):
    table = read_matched(_write(tmp_path, TABLE.read_bytes().replace(b"\n", ending)))
    pd.testing.assert_frame_equal(table, shipped)


def test_the_matched_command_writes_nothing_on_a_bad_table(tmp_path, capsys):
    path = _write(tmp_path, RAW, _sidecar(modulus_unit="MPa"))
    out = tmp_path / "out.csv"
    assert main(["matched", str(path), "-o", str(out)]) == 2
    assert not out.exists() and not list(tmp_path.glob(".out.csv*"))
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "mixes.tsv" in err[0]


def test_the_matched_command_keeps_the_mixes_asked_for(tmp_path):
    out = tmp_path / "out.csv"
    assert main(["matched", str(TABLE), "-o", str(out), "--mixes", "193", "204"]) == 0
    table = read_matched(out)
    assert sorted(table["mix_id"].unique()) == ["193", "204"] and np.all(table.groupby("mix_id").size() == 30)
    assert main(["matched", str(TABLE), "-o", str(out), "--mixes", "193", "999"]) == 2


def _plant(mix: str, column: int, value, rows=range(30)) -> str:
    """The shipped file with ``value`` written in ``column`` of the given rows (0-29, file order)
    of ``mix``."""
    lines = _lines()
    idx = [i for i, ln in enumerate(lines) if ln.startswith(f"{mix}\t")]
    for k in rows:
        cols = lines[idx[k]].split("\t")
        cols[column] = value
        lines[idx[k]] = "\t".join(cols)
    return "\n".join(lines) + "\n"


def _reversed_frequencies(mix: str) -> str:
    lines = _lines()
    idx = [i for i, ln in enumerate(lines) if ln.startswith(f"{mix}\t")]
    for b in range(5):
        block = idx[6 * b : 6 * b + 6]
        for i, j in zip(block, block[::-1]):
            lines[i] = _lines()[j]
    return "\n".join(lines) + "\n"


# columns of the file: ID, |E*|, φ, w, ρ3/4, ρ3/8, ρ4, ρ200, Pb, Va, Vbeff, PG_HIGH, PG_LOW, |G*|, δb, η
@pytest.mark.parametrize(
    "text,pattern",
    [
        (
            _plant("211", 15, "1e300", range(6)),
            r"line 422, column 'η': value 1e\+297 out of range; expected a binder viscosity in 0\.01-1e\+13 Pa s "
            r"\(the value in Pa s, read as cP",
        ),
        (
            _plant("193", 2, "0", [15]),
            r"line 17, column 'φ': phase angle 0 deg of mix '193' at 21\.11 degC, 1 Hz jumps from its neighbours "
            r"in the isotherm \(34\.3 deg at 0\.5 Hz, 24\.8 deg at 5 Hz\)",
        ),
        (_plant("193", 2, "0", [18]), r"line 20, column 'φ': phase angle 0 deg of mix '193' at 37\.78 degC, 25 Hz"),
        (_plant("193", 2, "0.11", [15]), r"line 17, column 'φ': phase angle 6\.3 deg of mix '193'"),
        (
            _reversed_frequencies("211"),
            r"lines 422-451, mix '211': its \|E\*\| falls with the frequency in 100% of its blocks: its frequencies "
            r"are written in reverse order\?",
        ),
        (
            _plant("211", 10, "18.5"),
            r"line 422, column 'Vbeff': Vbeff 18\.5 % is more binder than Pb 6\.735 % can fill; expected Vbeff <= "
            r"Pb Gmb/Gb <= 18\.18 % \(Gmb <= 2\.7, Gb >= 1",
        ),
    ],
    ids=["viscosity 1e300 cP", "phase 0 inside", "phase 0 at an end", "phase / 5", "one mix reversed", "Vbeff > Pb"],
)
def test_planted_defects_are_refused_naming_file_row_and_column(tmp_path, text, pattern):
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=pattern) as err:
        read_matched(path)
    assert "mixes.tsv" in str(err.value) and "\n" not in str(err.value)


def test_the_shipped_table_passes_the_new_checks_without_a_word(caplog):
    """No warning, and the margins of the new checks on the shipped values: viscosity within its
    range, phases within a factor 2.1 of a neighbour, Vbeff/Pb <= 2.39 of the 2.7 bound."""
    import logging

    from asphalt_nscd.lab.matched import PHASE_JUMP_RATIO, VISCOSITY_RANGE_PA_S

    with caplog.at_level(logging.WARNING, logger="asphalt_nscd"):
        table = read_matched(TABLE)
    assert table.attrs["warnings"] == [] and not [r for r in caplog.records if r.levelno >= logging.WARNING]
    eta = table["binder_eta_Pa_s"]
    assert VISCOSITY_RANGE_PA_S[0] < eta.min() and eta.max() < VISCOSITY_RANGE_PA_S[1] / 30
    first = table.groupby("mix_id").first()
    assert (first["Vbeff_pct"] / first["Pb_pct"]).max() < 2.4
    worst = 0.0
    for _, g in table.groupby(["mix_id", "temperature_C"]):
        y = g.sort_values("frequency_Hz")["phase_deg"].to_numpy()
        ratio = np.maximum(y[1:], y[:-1]) / np.minimum(y[1:], y[:-1])
        nearest = np.minimum(np.append(ratio, np.inf), np.insert(ratio, 0, np.inf))
        worst = max(worst, float(nearest.max()))
    assert 2.0 < worst < PHASE_JUMP_RATIO / 1.4
