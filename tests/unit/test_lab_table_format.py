"""Measured tables as labs write them: ksi/psi/GPa, degF, E1/E2, AASHTO and EN column names,
declared in the sidecar; wrong or missing declarations name the file and the key."""

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.io import InputError
from asphalt_nscd.lab.measured import load_measured
from asphalt_nscd.lab.table_format import MODULUS_UNITS, _key

SHIPPED = "data/measured/uiuc_fdmix1_utm/complex_modulus.csv"


@pytest.fixture(scope="module")
def own():
    return load_measured(SHIPPED)


def _write(tmp_path, frame, table, test="unknown"):
    frame.to_csv(tmp_path / "lab.csv", index=False)
    (tmp_path / "lab.test.json").write_text(json.dumps({"test": test, **({"table": table} if table else {})}))
    return tmp_path / "lab.csv"


def test_shipped_table_is_read_in_its_original_degF(own):
    raw = pd.read_csv(SHIPPED)
    assert "temperature_F" in raw.columns and "temperature_C" not in raw.columns
    assert sorted(own["temperature_C"].unique()) == [-10.0, 4.0, 21.0, 37.0, 54.0]
    assert own.attrs["test"].table.temperature_unit == "F"


def test_ksi_degF_aashto_headers(tmp_path, own):
    lab = pd.DataFrame(
        {
            "Specimen ID": own.specimen,
            "Temp (F)": own.temperature_C * 1.8 + 32,
            "Frequency (Hz)": own.frequency_Hz,
            "|E*| (ksi)": own.E_norm_MPa / MODULUS_UNITS["ksi"],
            "Phase Angle (deg)": own.phase_deg,
        }
    )
    t = load_measured(
        _write(tmp_path, lab, {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase"})
    )
    np.testing.assert_allclose(t["E_norm_MPa"], own["E_norm_MPa"], rtol=1e-12)
    np.testing.assert_allclose(t["temperature_C"], own["temperature_C"], atol=1e-9)
    assert "|E*| (ksi)" in t.columns  # the lab's columns are carried along


def test_storage_and_loss_moduli_in_gpa(tmp_path, own):
    phi = np.radians(own.phase_deg)
    lab = pd.DataFrame(
        {
            "sample": own.specimen,
            "temperature": own.temperature_C,
            "freq": own.frequency_Hz,
            "E1 (GPa)": own.E_norm_MPa * np.cos(phi) / 1e3,
            "E2 (GPa)": own.E_norm_MPa * np.sin(phi) / 1e3,
        }
    )
    t = load_measured(
        _write(tmp_path, lab, {"modulus_unit": "GPa", "temperature_unit": "C", "modulus_form": "storage_loss"})
    )
    np.testing.assert_allclose(t["E_norm_MPa"], own["E_norm_MPa"], rtol=1e-12)
    np.testing.assert_allclose(t["phase_deg"], own["phase_deg"], atol=1e-10)


def test_psi_is_a_thousandth_of_ksi_and_a_column_map(tmp_path, own):
    lab = pd.DataFrame(
        {
            "ID": own.specimen,
            "T_test": own.temperature_C,
            "f": own.frequency_Hz,
            "Dyn mod": own.E_norm_MPa / MODULUS_UNITS["psi"],
            "angle": own.phase_deg,
        }
    )
    cols = {"temperature": "T_test", "modulus": "Dyn mod", "phase": "angle"}
    t = load_measured(
        _write(
            tmp_path,
            lab,
            {"modulus_unit": "psi", "temperature_unit": "C", "modulus_form": "norm_phase", "columns": cols},
        )
    )
    np.testing.assert_allclose(t["E_norm_MPa"], own["E_norm_MPa"], rtol=1e-12)


@pytest.mark.parametrize(
    "table,match",
    [
        (None, "missing column.*key 'table' of lab.test.json"),
        ({"temperature_unit": "F", "modulus_form": "norm_phase"}, "key 'table.modulus_unit' missing"),
        ({"modulus_unit": "kips", "temperature_unit": "F", "modulus_form": "norm_phase"}, "'kips' is not one of"),
        (
            {"modulus_unit": "ksi", "temperature_unit": "K", "modulus_form": "norm_phase"},
            "key 'table.temperature_unit'",
        ),
        (
            {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase", "columns": {"phase": "Phi"}},
            "key 'table.columns.phase': column 'Phi' is not in",
        ),
        ({"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "storage_loss"}, "no column for the storage"),
        (
            {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase", "units": "x"},
            "key 'table.units': unknown key",
        ),
    ],
)
def test_bad_declarations_name_the_file_and_key(tmp_path, own, table, match):
    lab = pd.DataFrame(
        {
            "Specimen ID": own.specimen,
            "Temp (F)": own.temperature_C * 1.8 + 32,
            "Frequency (Hz)": own.frequency_Hz,
            "|E*| (ksi)": own.E_norm_MPa,
            "Phase (deg)": own.phase_deg,
        }
    )
    with pytest.raises(InputError, match=match):
        load_measured(_write(tmp_path, lab, table))


def test_non_numeric_value_names_the_lab_column(tmp_path, own):
    lab = pd.DataFrame(
        {
            "Specimen": own.specimen,
            "Temp (F)": (own.temperature_C * 1.8 + 32).astype(object),
            "Frequency": own.frequency_Hz,
            "E* (ksi)": own.E_norm_MPa,
            "Phase": own.phase_deg,
        }
    )
    lab.loc[3, "Temp (F)"] = "warm"
    with pytest.raises(InputError, match=r"line 5, column 'Temp \(F\)'.*'warm'"):
        load_measured(
            _write(tmp_path, lab, {"modulus_unit": "ksi", "temperature_unit": "F", "modulus_form": "norm_phase"})
        )


def test_header_reduction():
    assert _key("|E*| (ksi)") == "absestar" and _key("Phase Angle [deg]") == "phaseangle" and _key("E'") == "eprime"
