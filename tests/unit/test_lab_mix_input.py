"""The mix file of a forecast (asphalt_nscd.lab.mix_input): the shipped example is what its command
writes and reads back as the matched table's mix; the forms of a mix file; every error naming the
mix file, the mix and the key."""

from __future__ import annotations

import reference_scripts
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast.formulation import SIEVES_MM, passing_curve
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.matched import FORMULATION, read_matched
from asphalt_nscd.lab.mix_input import read_mix_file

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "data" / "forecast_example"
TABLE = REPO / "data" / "binder_mix" / "mixes_35.tsv"
FHWA = REPO / "data" / "measured" / "tfhrc_ptf_binder_dsr" / "binder_frequency_sweep.csv"


def _script():
    return reference_scripts.load("reference/forecast/lab_forms_example.py")


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    return read_matched(TABLE)


def test_the_example_is_what_its_command_writes(table):
    files = _script().example_files(table)
    assert sorted(files) == sorted(p.name for p in EXAMPLE.iterdir())
    for name, text in files.items():
        assert (EXAMPLE / name).read_text(encoding="utf-8") == text, name


def test_the_example_reads_back_as_the_tables_mix(table):
    (mix,) = read_mix_file(EXAMPLE / "mix_211.yaml")
    rows = table[table["mix_id"] == "211"]
    first = rows.iloc[0]
    assert mix.mix_id == "211" and mix.warnings == []
    for k in ("rho34_pct", "rho38_pct", "rho4_pct", "rho200_pct"):
        assert mix.witczak[k] == pytest.approx(first[k], rel=1e-9, abs=1e-12)
    for k in ("Va_pct", "Vbeff_pct", "Pb_pct"):
        assert mix.volumetrics[k] == pytest.approx(first[k], rel=1e-9)
    assert (mix.pg_high_C, mix.pg_low_C) == (first["pg_high_C"], first["pg_low_C"])
    assert mix.formulation() == pytest.approx({k: first[k] for k in (*FORMULATION, "pg_high_C", "pg_low_C")}, rel=1e-9)
    got = mix.binder_points.sort_values(["temperature_C", "frequency_Hz"]).reset_index(drop=True)
    ref = rows.sort_values(["temperature_C", "binder_frequency_Hz"]).reset_index(drop=True)
    assert len(got) == 30 and got["n_specimens"].eq(1).all()
    np.testing.assert_allclose(got["temperature_C"], ref["temperature_C"], rtol=1e-9, atol=0)
    np.testing.assert_allclose(got["frequency_Hz"], ref["binder_frequency_Hz"], rtol=1e-9)
    np.testing.assert_allclose(got["G_Pa"], ref["binder_G_MPa"] * 1e6, rtol=1e-9)
    np.testing.assert_allclose(got["delta_deg"], ref["binder_delta_deg"], rtol=1e-9)
    np.testing.assert_allclose(got["eta_Pa_s"], ref["binder_eta_Pa_s"], rtol=1e-9)
    # the discrete model's curve of the table's mix
    ref_curve = passing_curve(first)
    assert np.array_equal(mix.passing_at(list(SIEVES_MM)), np.array([ref_curve[s] for s in SIEVES_MM]))


def _mix_file(folder: Path, mixes: list, name: str = "mixes.yaml") -> Path:
    import yaml

    path = folder / name
    path.write_text(yaml.safe_dump({"mixes": mixes}, sort_keys=False))
    return path


def _mix(**changes) -> dict:
    base = {
        "id": "A",
        "binder": {"file": str(FHWA), "id": 3, "pg_grade": "PG 64-22"},
        "gradation": {"1 in": 100, "3/4 in": 96, "3/8 in": 72, "No. 4": 50, "No. 8": 35, "No. 200": 5.5},
        "volumetrics": {"Va": 4.0, "VMA": 15.0, "Pb": 5.2},
    }
    for k, v in changes.items():
        if v is None:
            base.pop(k)
        elif isinstance(v, dict) and isinstance(base.get(k), dict) and k == "binder":
            base[k] = {a: b for a, b in {**base[k], **v}.items() if b is not None}
        else:
            base[k] = v
    return base


def test_a_file_of_several_mixes_in_other_forms(tmp_path):
    (tmp_path / "sieve.csv").write_text(
        "Sieve,Cumulative % Retained\n1 in,0\n3/4 in,4\n3/8 in,28\nNo. 4,50\nNo. 200,94.5\n"
    )
    mixes = [
        _mix(),
        _mix(
            id="B",
            binder={"id": "7", "pg_grade": None, "viscosity": {"unit": "P", "values": {58: 3000.0, 70: 600.0}}},
            gradation="sieve.csv",
            volumetrics={"Va": 4.0, "Vbeff": 11.0},
        ),
        _mix(
            id="C",
            gradation={"form": "cumulative_retained", "sieves": {"1 in": 0, "3/4 in": 4, "No. 4": 50, "No. 200": 94.5}},
        ),
    ]
    a, b, c = read_mix_file(_mix_file(tmp_path, mixes))
    assert a.binder_points["binder"].unique().tolist() == ["3"] and a.sources["binder_id"] == "3"
    assert (a.pg_high_C, a.pg_low_C) == (64.0, -22.0) and b.pg_high_C is None
    assert a.volumetrics == pytest.approx(
        {"Va_pct": 4.0, "Vbeff_pct": 11.0, "Pb_pct": 5.2, "VMA_pct": 15.0, "VFA_pct": 11 / 0.15}
    )
    assert b.volumetrics["Pb_pct"] is None and b.sources["gradation"].endswith("sieve.csv")
    assert a.witczak == b.witczak == pytest.approx({"rho34_pct": 4, "rho38_pct": 28, "rho4_pct": 50, "rho200_pct": 5.5})
    assert c.witczak["rho38_pct"] == pytest.approx(100 - 50 * (9.5 / 4.75) ** (math.log(96 / 50) / math.log(19 / 4.75)))
    eta = b.binder_points.groupby("temperature_C")["eta_Pa_s"].first()
    assert (
        eta[58.0] == pytest.approx(300.0) and eta[70.0] == pytest.approx(60.0) and eta.drop([58.0, 70.0]).isna().all()
    )
    assert len(b.viscosity) == 2 and a.viscosity.empty


@pytest.mark.parametrize(
    "mixes,pattern",
    [
        ([_mix(volumetrics=None)], r"mix 'A': key '\(the mix\)': 'volumetrics' is a required property"),
        ([_mix(colour="red")], r"mix 'A': key 'colour': unknown key"),
        ([_mix(id="a/b")], r"mix 'a/b': key 'id': 'a/b' does not match"),
        ([_mix(), _mix()], r"mix 'A': key 'id': mix 'A' is given twice"),
        ([_mix(binder={"id": "99"})], r"mix 'A': key 'binder\.id': no binder '99' in .*binder_frequency_sweep\.csv"),
        ([_mix(binder={"id": None})], r"mix 'A': key 'binder\.id': .* holds binders \['1', '2'"),
        ([_mix(binder={"file": "nowhere.csv"})], r"mix 'A': key 'binder\.file': .*nowhere\.csv: file not found"),
        ([_mix(binder={"pg_grade": "PG 64"})], r"mix 'A': key 'binder\.pg_grade': 'PG 64' is not a performance grade"),
        (
            [_mix(binder={"viscosity": {"unit": "Pa s", "values": {60: "x"}}})],
            r"mix 'A': key 'binder\.viscosity\.values\.60': 'x' is not of type 'number'",
        ),
        (
            [_mix(gradation={"3/4 in": 100, "No. 4": 120, "No. 200": 5})],
            r"mix 'A': key 'gradation': sieve 'No. 4': 120 out of range",
        ),
        ([_mix(gradation={"form": "passing"})], r"mix 'A': key 'gradation': expected \{form: passing"),
        ([_mix(gradation="nope.csv")], r"mix 'A': key 'gradation': .*nope\.csv: file not found"),
        ([_mix(volumetrics={"Va": 4.0, "VMA": 3.0})], r"mix 'A': key 'volumetrics\.VMA': VMA 3 % <= Va 4 %"),
        (
            [_mix(volumetrics={"Va": 4.0, "VMA": "15"})],
            r"mix 'A': key 'volumetrics\.VMA': '15' is not of type 'number'",
        ),
        (
            [_mix(volumetrics={"Va": 4.0, "VMA": 15.0, "VFA": 50.0})],
            r"mix 'A': key 'volumetrics\.Vbeff': Vbeff = 11 \(given\)|VFA",
        ),
    ],
)
def test_errors_name_the_mix_file_the_mix_and_the_key(tmp_path, mixes, pattern):
    path = _mix_file(tmp_path, mixes)
    with pytest.raises(InputError, match=pattern) as err:
        read_mix_file(path)
    text = str(err.value)
    assert text.startswith(str(path)) and "\n" not in text


def test_an_error_inside_the_sweep_keeps_its_line_and_column(tmp_path):
    rows = pd.read_csv(EXAMPLE / "binder_211_dsr.csv")
    rows.loc[7, "Phase Angle (°)"] = 95.0
    rows.to_csv(tmp_path / "b.csv", index=False)
    path = _mix_file(tmp_path, [_mix(binder={"file": "b.csv", "id": None})])
    with pytest.raises(
        InputError, match=r"mix 'A': key 'binder\.file': .*b\.csv: line 9, column 'Phase Angle \(°\)': value 95"
    ):
        read_mix_file(path)


def test_pg_grade_given_in_the_sidecar_and_the_mix_file_is_refused(tmp_path):
    rows = pd.read_csv(EXAMPLE / "binder_211_dsr.csv")
    rows.to_csv(tmp_path / "b.csv", index=False)
    (tmp_path / "b.test.json").write_text(json.dumps({"binder": {"pg_grade": "PG 76-22"}}))
    path = _mix_file(tmp_path, [_mix(binder={"file": "b.csv", "id": None})])
    with pytest.raises(InputError, match=r"mix 'A': key 'binder\.pg_grade': also given in .*b\.test\.json"):
        read_mix_file(path)
    (mix,) = read_mix_file(
        _mix_file(tmp_path, [_mix(binder={"file": "b.csv", "id": None, "pg_grade": None})], "m2.yaml")
    )
    assert (mix.pg_high_C, mix.pg_low_C) == (76.0, -22.0)


def test_yaml_numbers_with_exponents_and_bad_yaml(tmp_path):
    path = tmp_path / "m.yaml"
    text = (EXAMPLE / "mix_211.yaml").read_text().replace("binder_211_dsr.csv", str(EXAMPLE / "binder_211_dsr.csv"))
    text = text.replace("sieve_211.csv", str(EXAMPLE / "sieve_211.csv")).replace("30785200000.0", "3.07852e10")
    path.write_text(text)
    (mix,) = read_mix_file(path)
    assert mix.viscosity["eta_Pa_s"].iloc[0] == 3.07852e10
    path.write_text("mixes: [\n")
    with pytest.raises(InputError, match=r"m\.yaml: not valid YAML"):
        read_mix_file(path)
    path.write_text("- 1\n")
    with pytest.raises(InputError, match=r"m\.yaml: expected a mapping with key 'mixes'"):
        read_mix_file(path)
