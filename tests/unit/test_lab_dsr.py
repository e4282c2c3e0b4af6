"""Binder DSR frequency sweeps (asphalt_nscd.lab.dsr): the FHWA sweeps shipped in data/measured, the
layouts and units of lab exports, the binder's PG grade and viscosity, and each way a sweep goes
wrong refused (or warned) naming the file, line and column."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.io import InputError
from asphalt_nscd.lab.dsr import CENTER, UNIT_BAND_DECADES, center_log10_G_Pa, parse_pg_grade, read_dsr

REPO = Path(__file__).resolve().parents[2]
FHWA = REPO / "data" / "measured" / "tfhrc_ptf_binder_dsr" / "binder_frequency_sweep.csv"
RAW = pd.read_csv(FHWA)
#: lane 1, first replicate, at 4 temperatures and 6 frequencies: a small sweep in the source's values
SMALL = RAW[
    (RAW["lane"] == 1)
    & (RAW["replicate"] == 1)
    & RAW["temperature_C"].isin([22.0, 46.0, 58.0, 70.0])
    & RAW["angular_frequency_rad_s"].isin([0.1, 0.316, 1.0, 3.16, 10.0, 100.0])
].reset_index(drop=True)
EXPORT = {
    "Temperature (°C)": SMALL["temperature_C"],
    "Angular Frequency (rad/s)": SMALL["angular_frequency_rad_s"],
    "Complex Modulus |G*| (kPa)": SMALL["G_norm_kPa"],
    "Phase Angle (°)": SMALL["phase_deg"],
}


def _write(folder: Path, columns: dict, sidecar: dict | None = None, name: str = "sweep.csv") -> Path:
    path = folder / name
    pd.DataFrame(columns).to_csv(path, index=False)
    if sidecar is not None:
        path.with_name(path.stem + ".test.json").write_text(json.dumps(sidecar))
    return path


@pytest.fixture(scope="module")
def fhwa() -> pd.DataFrame:
    return read_dsr(FHWA)


def test_the_fhwa_sweeps_read_as_ten_binders_in_si(fhwa):
    assert list(fhwa.columns) == [
        "binder",
        "temperature_C",
        "frequency_Hz",
        "G_Pa",
        "delta_deg",
        "eta_Pa_s",
        "n_specimens",
    ]
    assert list(dict.fromkeys(fhwa["binder"])) == [str(k) for k in range(1, 11)]
    assert fhwa.groupby("binder").size().eq(7 * 31).all() and fhwa.attrs["warnings"] == []
    # the file's first row: lane 1, 10 degC, 0.1 rad/s, |G*| 5410 kPa, delta 45.9 deg
    first = fhwa.iloc[0]
    assert (first["temperature_C"], first["delta_deg"], first["n_specimens"]) == (10.0, 45.9, 1)
    assert first["frequency_Hz"] == pytest.approx(0.1 / (2 * math.pi), rel=1e-15)
    assert first["G_Pa"] == pytest.approx(5410e3, rel=1e-15)
    # 58-82 degC: three replicates, |G*| their geometric mean, delta their mean
    reps = RAW[(RAW["lane"] == 3) & (RAW["temperature_C"] == 70.0) & (RAW["angular_frequency_rad_s"] == 10.0)]
    row = fhwa[
        (fhwa["binder"] == "3") & (fhwa["temperature_C"] == 70.0) & np.isclose(fhwa["frequency_Hz"], 10 / (2 * math.pi))
    ]
    assert len(reps) == 3 and row["n_specimens"].item() == 3
    assert row["G_Pa"].item() == pytest.approx(np.exp(np.log(reps["G_norm_kPa"] * 1e3).mean()), rel=1e-12)
    assert row["delta_deg"].item() == pytest.approx(reps["phase_deg"].mean(), rel=1e-12)
    kept = read_dsr(FHWA, replicates="keep")
    assert len(kept) == len(RAW) and "specimen" in kept.columns


def test_the_typical_binder_is_the_fit_over_the_shipped_binders(fhwa):
    """CENTER reproduces from the shipped data (FHWA sweeps, the matched table's binders), every
    shipped binder's median residual is well inside the band, and a 1000-fold unit slip is not."""
    from asphalt_nscd.forecast.binder import binder_ids
    from asphalt_nscd.lab.matched import read_matched

    m = read_matched(REPO / "data" / "binder_mix" / "mixes_35.tsv")
    m = m.assign(binder=m["mix_id"].map(binder_ids(m))).drop_duplicates(["binder", "temperature_C", "frequency_Hz"])
    both = pd.concat(
        [
            fhwa[["binder", "temperature_C", "frequency_Hz", "G_Pa"]],
            pd.DataFrame(
                {
                    "binder": "m" + m["binder"],
                    "temperature_C": m["temperature_C"],
                    "frequency_Hz": m["binder_frequency_Hz"],
                    "G_Pa": m["binder_G_MPa"] * 1e6,
                }
            ),
        ]
    )
    kept = read_dsr(FHWA, replicates="keep")
    raw = pd.concat([kept[["temperature_C", "frequency_Hz", "G_Pa"]], both[both["binder"].str.startswith("m")]])
    X = np.c_[np.ones(len(raw)), raw["temperature_C"], np.log10(2 * np.pi * raw["frequency_Hz"])]
    coef = np.linalg.lstsq(X, np.log10(raw["G_Pa"]), rcond=None)[0]
    assert coef == pytest.approx(CENTER, abs=0.006)
    r = np.log10(both["G_Pa"]) - center_log10_G_Pa(both["temperature_C"], both["frequency_Hz"])
    med = r.groupby(both["binder"]).median()
    assert med.abs().max() < 1.0 < UNIT_BAND_DECADES < 3.0 - med.abs().max()


def test_an_export_with_common_headers_needs_no_sidecar(tmp_path):
    sweep = read_dsr(_write(tmp_path, EXPORT))
    assert sweep["binder"].unique().tolist() == ["sweep"]
    assert sweep.attrs["units"] == {
        "temperature": "C",
        "frequency": "rad/s",
        "modulus": "kPa",
        "phase": "deg",
        "form": "norm_phase",
    }
    assert sorted(sweep["G_Pa"]) == pytest.approx(sorted(SMALL["G_norm_kPa"] * 1e3), rel=1e-15)


@pytest.mark.parametrize(
    "columns,sidecar",
    [
        (
            {
                "Temp (F)": SMALL["temperature_C"] * 1.8 + 32,
                "Frequency (Hz)": SMALL["angular_frequency_rad_s"] / (2 * math.pi),
                "|G*| (psi)": SMALL["G_norm_kPa"] / 6.894757293168361,
                "Phase angle (rad)": np.radians(SMALL["phase_deg"]),
            },
            None,
        ),
        (
            {
                "T": SMALL["temperature_C"],
                "w": SMALL["angular_frequency_rad_s"],
                "Storage Modulus [MPa]": SMALL["G1_kPa"] / 1e3,
                "Loss Modulus [MPa]": SMALL["G2_kPa"] / 1e3,
            },
            {"table": {"frequency_unit": "rad/s", "columns": {"frequency": "w"}}},
        ),
        (
            {
                "binder": "X",
                "temperature_C": SMALL["temperature_C"],
                "frequency_Hz": SMALL["angular_frequency_rad_s"] / (2 * math.pi),
            }
            | {"G_Pa": SMALL["G_norm_kPa"] * 1e3, "delta_deg": SMALL["phase_deg"]},
            None,
        ),
    ],
    ids=["degF Hz psi rad", "storage-loss MPa declared", "project columns"],
)
def test_other_units_and_forms_read_as_the_same_sweep(tmp_path, columns, sidecar):
    ref = read_dsr(_write(tmp_path, EXPORT, name="ref.csv"))
    got = read_dsr(_write(tmp_path, columns, sidecar))
    assert np.allclose(got["temperature_C"], ref["temperature_C"], rtol=0, atol=1e-9)
    assert np.allclose(got["frequency_Hz"], ref["frequency_Hz"], rtol=1e-12)
    # the source's G', G'' (3 significant digits) agree with its |G*| and delta within 0.8 % and 0.22 deg
    tol = (1e-2, 0.3) if "Storage Modulus [MPa]" in columns else (1e-9, 1e-9)
    assert np.allclose(got["G_Pa"], ref["G_Pa"], rtol=tol[0]) and np.allclose(
        got["delta_deg"], ref["delta_deg"], atol=tol[1]
    )


def test_pg_grade_and_viscosity_from_the_sidecar(tmp_path):
    side = {
        "binder": {
            "id": "B7",
            "pg_grade": "PG 64-22",
            "viscosity": {"unit": "cP", "temperature_unit": "F", "values": {"135.5": 1e8, "158": 2.5e6, "275": 400}},
        }
    }
    sweep = read_dsr(_write(tmp_path, EXPORT, side))
    info = sweep.attrs["binders"]["B7"]
    assert (info.pg_high_C, info.pg_low_C) == (64.0, -22.0)
    assert info.viscosity["temperature_C"].tolist() == pytest.approx([57.5, 70.0, 135.0])
    # placed on the isotherms within 0.5 degC (57.5 -> 58 and 70); 135 degC has no isotherm
    eta = sweep.groupby("temperature_C")["eta_Pa_s"].first()
    assert eta[58.0] == pytest.approx(1e5) and eta[70.0] == pytest.approx(2.5e3) and eta[[22.0, 46.0]].isna().all()
    assert parse_pg_grade("PG64E-28", "x") == (64.0, -28.0) and parse_pg_grade("76-16", "x") == (76.0, -16.0)


def _mutated(**changes) -> dict:
    cols = {k: v.copy() for k, v in EXPORT.items()}
    for k, (row, value) in changes.items():
        cols[k] = cols[k].astype(object)
        cols[k].iloc[row] = value
    return cols


@pytest.mark.parametrize(
    "columns,sidecar,pattern",
    [
        (_mutated(**{"Phase Angle (°)": (4, "abc")}), None, r"line 6, column 'Phase Angle \(°\)': value 'abc'"),
        (_mutated(**{"Phase Angle (°)": (4, 0.0)}), None, r"line 6, column 'Phase Angle \(°\)'.*delta in \(0, 90\]"),
        (
            _mutated(**{"Phase Angle (°)": (4, 93.0)}),
            None,
            r"line 6, column 'Phase Angle \(°\)': value 93 out of range",
        ),
        (
            _mutated(**{"Complex Modulus |G*| (kPa)": (4, 5e9)}),
            None,
            r"line 6, column 'Complex Modulus.*5e\+12 Pa out of range.*binder's",
        ),
        (
            {**EXPORT, "Complex Modulus |G*| (kPa)": EXPORT["Complex Modulus |G*| (kPa)"] * 1e3},
            None,
            r"line 5, column 'Complex Modulus \|G\*\| \(kPa\)': \|G\*\| 4\.51e\+09 Pa out of range.*fit Pa \(x 0\.001\)",
        ),
        (
            _mutated(**{"Temperature (°C)": (4, 250)}),
            None,
            r"line 6, column 'Temperature \(°C\)': value 250 out of range",
        ),
        (
            {**EXPORT, "Phase Angle (°)": np.radians(EXPORT["Phase Angle (°)"])},
            None,
            r"every phase angle is below 1\.6 .* radians\?",
        ),
        (
            {k: pd.concat([v, v.iloc[[3]]]) for k, v in EXPORT.items()},
            None,
            r"lines 5, 26: repeated point \(binder 'sweep', 22 degC, 0\.50\d* Hz\); give replicates a specimen column",
        ),
        (
            {k: v[SMALL["temperature_C"] == 46.0] for k, v in EXPORT.items()},
            None,
            r"binder 'sweep' is tested at 1 temperature\(s\) \(46 degC\); a master curve needs 2",
        ),
        (
            {
                k: v[(SMALL["temperature_C"] != 70.0) | SMALL["angular_frequency_rad_s"].isin([1.0, 10.0])]
                for k, v in EXPORT.items()
            },
            None,
            r"binder 'sweep' at 70 degC has 2 frequency\(ies\); an isotherm needs 3",
        ),
        (
            EXPORT,
            {"table": {"modulus_unit": "Pa"}},
            r"column 'Complex Modulus \|G\*\| \(kPa\)' names the unit kPa.*declares Pa",
        ),
        (
            {("Complex Modulus" if "Modulus" in k else k): v for k, v in EXPORT.items()},
            {"table": {"columns": {"modulus": "Complex Modulus"}}},
            r"column 'Complex Modulus': its unit is neither in the header nor declared; declare 'table\.modulus_unit'",
        ),
        (EXPORT, {"table": {"modulus_units": "kPa"}}, r"sweep\.test\.json: key 'table\.modulus_units': unknown key"),
        (
            EXPORT,
            {"table": {"modulus_unit": "bar"}},
            r"sweep\.test\.json: key 'table\.modulus_unit': 'bar' is not one of",
        ),
        (EXPORT, {"binders": {"Z": {"pg_grade": "PG 64-22"}}}, r"key 'binders\.Z': no binder 'Z' in the file"),
        (
            EXPORT,
            {"binder": {"pg_grade": "PG 64 22"}},
            r"key 'binder\.pg_grade': 'PG 64 22' is not a performance grade",
        ),
        (
            EXPORT,
            {"binder": {"viscosity": {"unit": "Pa s", "values": {"60": 200, "135": 500}}}},
            r"key 'binder\.viscosity\.values': the viscosity at 135 .* a binder thins as it warms",
        ),
        (
            EXPORT,
            {"binder": {"viscosity": {"unit": "cP", "values": {"14": 1e300, "60": 2e5}}}},
            r"key 'binder\.viscosity\.values\.14': 1e\+300 cP .* out of range; expected a binder viscosity in 0\.01-1e\+13 Pa s",
        ),
    ],
)
def test_bad_sweeps_are_refused_naming_the_place(tmp_path, columns, sidecar, pattern):
    columns = {k: v.reset_index(drop=True) for k, v in columns.items()}
    path = _write(tmp_path, columns, sidecar)
    with pytest.raises(InputError, match=pattern) as err:
        read_dsr(path)
    assert "sweep" in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("factor,declared,fits", [(1e3, "kPa", "Pa"), (1e-3, "kPa", "MPa"), (1e-3, "MPa", "GPa")])
def test_a_unit_the_values_contradict_is_warned_with_the_unit_they_fit(tmp_path, caplog, factor, declared, fits):
    """Pa written as kPa (x 1000), and the others: the sweep is read, a warning names the unit
    (at 46-70 degC, where the slip stays below the 3 GPa refusal)."""
    warm = SMALL["temperature_C"] >= 46.0
    cols = {k: v[warm].reset_index(drop=True) for k, v in EXPORT.items() if "Modulus" not in k}
    scale = {"kPa": 1.0, "MPa": 1e-3}[declared]
    cols[f"Complex Modulus |G*| ({declared})"] = (EXPORT["Complex Modulus |G*| (kPa)"] * factor * scale)[
        warm
    ].reset_index(drop=True)
    with caplog.at_level(logging.WARNING, logger="asphalt_nscd"):
        sweep = read_dsr(_write(tmp_path, cols))
    (text,) = sweep.attrs["warnings"]
    assert f"the values fit {fits} (x " in text and "decades from a typical binder" in text
    assert [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING] == [text]
