"""Test geometry of a measured table: sidecar declaration, schema validation, form factors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.en12697 import Specimen2PB
from asphalt_nscd.lab.geometry import DeclaredTest, declared_test, from_dict, load_test, sidecar_path
from asphalt_nscd.lab.measured import load_measured

REPO = Path(__file__).resolve().parents[2]
UIUC = REPO / "data/measured/uiuc_fdmix1_utm/complex_modulus.csv"


def test_form_factors_of_the_declared_tests():
    paper = from_dict(
        {"test": "2pb_trapezoid", "B_mm": 56, "b_mm": 25, "e_mm": 25, "h_mm": 250, "M_kg": 0.6, "m_kg": 0.235}, "x.json"
    )
    assert paper.form_factor_per_mm == pytest.approx(Specimen2PB().gamma_per_mm, rel=1e-12)
    cyl = from_dict({"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 150}, "x.json")
    # E = (F/A)(h/z): gamma = h / A
    assert cyl.form_factor_per_mm == pytest.approx(150.0 / (np.pi * 100.0**2 / 4))
    assert cyl.inertia_testability() == (True, "")
    unknown = DeclaredTest()
    assert unknown.form_factor_per_mm is None and not unknown.inertia_testability()[0]
    unstated = from_dict({"test": "uniaxial_cylinder", "diameter_mm": None, "height_mm": 150}, "s.json")
    ok, reason = unstated.inertia_testability()
    assert not ok and "diameter_mm" in reason and "s.json" in reason


@pytest.mark.parametrize(
    "obj,key",
    [
        ({"test": "4pb_beam"}, "test"),
        ({"test": "uniaxial_cylinder", "diameter_mm": 100}, "height_mm"),
        ({"test": "uniaxial_cylinder", "diameter_mm": -1, "height_mm": 150}, "diameter_mm"),
        ({"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 150, "width_mm": 3}, "width_mm"),
        ({"test": "2pb_trapezoid", "B_mm": 56, "b_mm": 60, "e_mm": 25, "h_mm": 250}, "b_mm"),
        ({"test": "2pb_trapezoid", "B_mm": 56, "b_mm": 25, "e_mm": 25, "h_mm": 250, "diameter_mm": 100}, "diameter_mm"),
        ({"diameter_mm": 100}, "test"),
    ],
)
def test_bad_declarations_name_the_file_and_key(tmp_path, obj, key):
    path = tmp_path / "t.test.json"
    path.write_text(json.dumps(obj))
    with pytest.raises(InputError) as err:
        load_test(path)
    assert str(path) in str(err.value) and key in str(err.value)


def test_sidecar_is_found_next_to_the_table_and_default_is_unknown(tmp_path):
    table = tmp_path / "mix.csv"
    load_measured(UIUC).drop(columns="temperature_F").to_csv(table, index=False)  # the project's own columns
    assert sidecar_path(table) == tmp_path / "mix.test.json"
    assert load_measured(table).attrs["test"].test == "unknown"
    (tmp_path / "mix.test.json").write_text(
        json.dumps({"test": "uniaxial_cylinder", "diameter_mm": 100, "height_mm": 150})
    )
    assert load_measured(table).attrs["test"].test == "uniaxial_cylinder"
    explicit = tmp_path / "other.json"
    explicit.write_text(json.dumps({"test": "unknown"}))
    assert declared_test(table, explicit).test == "unknown"


def test_shipped_mix_declares_a_uniaxial_test_of_unstated_dimensions():
    test = load_measured(UIUC).attrs["test"]
    assert test.test == "uniaxial_cylinder" and test.form_factor_per_mm is None
    ok, reason = test.inertia_testability()
    assert not ok and "not stated" in reason


def test_measured_cli_writes_a_valid_declaration(tmp_path):
    out = tmp_path / "measured.csv"
    assert (
        main(
            [
                "measured",
                str(UIUC),
                "-o",
                str(out),
                "--summary",
                str(tmp_path / "s.csv"),
                "--test-output",
                str(tmp_path / "measured.test.json"),
            ]
        )
        == 0
    )
    decl = load_test(tmp_path / "measured.test.json")
    assert decl.test == "uniaxial_cylinder" and "complex_modulus.test.json" in decl.source
    # the written declaration is found next to the tidy table
    assert load_measured(out).attrs["test"].test == "uniaxial_cylinder"
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    assert (
        main(
            [
                "measured",
                str(UIUC),
                "--test",
                str(bad),
                "-o",
                str(tmp_path / "m2.csv"),
                "--summary",
                str(tmp_path / "s2.csv"),
            ]
        )
        == 2
    )
    assert not (tmp_path / "m2.csv").exists()
