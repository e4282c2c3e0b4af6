"""Measured-table ingestion: validation errors name file, line and column; nothing is written."""

from pathlib import Path

import numpy as np
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.measured import load_measured, read_summary, summarize

REPO = Path(__file__).resolve().parents[2]
UIUC = REPO / "data" / "measured" / "uiuc_fdmix1_utm" / "complex_modulus.csv"

GOOD = """specimen,temperature_C,frequency_Hz,E_norm_MPa,phase_deg,strain_microstrain,test_order,operator
A,10,3,12000,15.0,50,1,jq
B,10,3,13000,16.0,48,2,jq
A,10,10,15000,12.0,50,3,cc
B,10,10,16000,13.0,49,4,cc
"""


def write(tmp_path, text, name="table.csv"):
    path = tmp_path / name
    path.write_text(text) if isinstance(text, str) else path.write_bytes(text)
    return path


def test_good_table_is_typed_sorted_and_carries_extra_columns(tmp_path):
    df = load_measured(write(tmp_path, GOOD))
    assert list(df.columns[:5]) == ["specimen", "temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg"]
    assert df["test_order"].dtype.kind == "i"
    assert df["operator"].tolist() == ["jq", "jq", "cc", "cc"]
    assert df["E_norm_MPa"].dtype == float


def test_summary_mean_and_sample_std(tmp_path):
    s = summarize(load_measured(write(tmp_path, GOOD)))
    assert list(s.columns) == [
        "temperature_C",
        "frequency_Hz",
        "n",
        "E_norm_MPa_mean",
        "E_norm_MPa_std",
        "phase_deg_mean",
        "phase_deg_std",
    ]
    row = s[s["frequency_Hz"] == 3].iloc[0]
    assert row["n"] == 2
    assert row["E_norm_MPa_mean"] == pytest.approx(12500.0)
    assert row["E_norm_MPa_std"] == pytest.approx(np.std([12000, 13000], ddof=1))
    assert row["phase_deg_std"] == pytest.approx(np.std([15.0, 16.0], ddof=1))


def test_shipped_measured_table():
    df = load_measured(UIUC)
    assert len(df) == 90
    s = summarize(df)
    assert len(s) == 30 and (s["n"] == 3).all()


BAD_CASES = {
    "missing column": (GOOD.replace("phase_deg,", "phi,"), r"line 1.*phase_deg"),
    "non-numeric value": (GOOD.replace("13000", "13k"), r"line 3, column 'E_norm_MPa'.*non-numeric"),
    "NaN value": (GOOD.replace("16000", ""), r"line 5, column 'E_norm_MPa'.*NaN"),
    "NaN literal": (GOOD.replace("16.0", "nan"), r"line 3, column 'phase_deg'.*NaN"),
    "zero modulus": (GOOD.replace("15000", "0"), r"line 4, column 'E_norm_MPa'.*out of range"),
    "negative modulus": (GOOD.replace("15000", "-5"), r"line 4, column 'E_norm_MPa'"),
    "phase 90": (GOOD.replace("12.0", "90"), r"line 4, column 'phase_deg'.*\[0, 90\)"),
    "negative phase": (GOOD.replace("15.0", "-1"), r"line 2, column 'phase_deg'"),
    "non-integer test order": (GOOD.replace(",2,jq", ",2.5,jq"), r"line 3, column 'test_order'"),
    "missing specimen": (GOOD.replace("B,10,3", ",10,3"), r"line 3, column 'specimen'"),
    "duplicate key": (GOOD.replace("B,10,10,16000,13.0,49,4", "A,10,10,16000,13.0,49,3"), r"lines 4, 5.*duplicate"),
    "empty file": ("", r"empty"),
    "header only": (GOOD.splitlines()[0] + "\n", r"no data rows"),
    "binary content": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", r"not a CSV"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_table_error_names_file_row_column_and_writes_nothing(tmp_path, case):
    text, pattern = BAD_CASES[case]
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=pattern) as info:
        load_measured(path)
    assert str(path) in str(info.value)
    out, summary = tmp_path / "out" / "measured.csv", tmp_path / "out" / "summary.csv"
    assert main(["measured", str(path), "-o", str(out), "--summary", str(summary)]) == 2
    assert not out.exists() and not summary.exists()


def test_non_csv_suffix_rejected(tmp_path):
    path = write(tmp_path, '{"specimen": "A"}', name="table.json")
    with pytest.raises(InputError, match=r"table\.json.*\.csv"):
        load_measured(path)


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_measured(tmp_path / "nope.csv")


def test_cli_writes_table_and_summary(tmp_path):
    out, summary = tmp_path / "m.csv", tmp_path / "s.csv"
    assert main(["measured", str(UIUC), "-o", str(out), "--summary", str(summary)]) == 0
    assert out.exists() and summary.exists()
    back = load_measured(out)
    assert "temperature_F" in back.columns and len(back) == 90  # the lab's column, carried along


def test_read_summary_round_trip_and_errors(tmp_path):
    summary = summarize(load_measured(write(tmp_path, GOOD)))
    summary.loc[len(summary)] = [20.0, 3.0, 1, 900.0, np.nan, 30.0, np.nan]  # one specimen: std NaN
    path = tmp_path / "summary.csv"
    summary.to_csv(path, index=False)
    back = read_summary(path)
    assert back.equals(summary.astype({"n": int}))
    text = path.read_text()
    for bad, message in (
        (text.replace("phase_deg_mean", "phase"), r"line 1.*'phase_deg_mean'"),
        (text.replace("12500", "12k5"), r"line 2, column 'E_norm_MPa_mean'.*non-numeric"),
        (text.replace(",900.0,", ",-900.0,"), r"line 4, column 'E_norm_MPa_mean'.*out of range"),
        (text.replace("20.0,3.0,1,", "20.0,3.0,0,"), r"line 4, column 'n'.*out of range"),
        (text.replace("20.0,3.0,", "10.0,3.0,"), r"lines 2, 4: repeated"),
        ("temperature_C,frequency_Hz,n,E_norm_MPa_mean,E_norm_MPa_std,phase_deg_mean,phase_deg_std\n", "no data rows"),
    ):
        bad_path = write(tmp_path, bad, "bad_summary.csv")
        with pytest.raises(InputError, match=message) as err:
            read_summary(bad_path)
        assert str(err.value).startswith(str(bad_path))
    with pytest.raises(InputError, match="file not found"):
        read_summary(tmp_path / "missing.csv")
