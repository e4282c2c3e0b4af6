"""Extended campaign mode: the law-JSON reader (good and bad files), `run-2pb --law-json` and
`campaign-isotherms --law-json`."""

from cli_options import set_options
import json
import math

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.campaign import study
from asphalt_nscd.cli import main
from asphalt_nscd.rheology import law_file
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import write_sample
from asphalt_nscd.io import InputError
from asphalt_nscd.rheology.calibration import burgers_model, load_table3
from asphalt_nscd.rheology.laws import GeneralizedBurgers

TABLE3 = "data/paper/table3_burgers.csv"
#: a law with a static spring and no Maxwell dashpot (Pa, Pa s), and one with both
SOLID = GeneralizedBurgers(Em=3e9, eta_m=np.inf, Ek=(2e9, 5e8), eta_k=(2e6, 5e7), E_inf=4e7)
LIQUID = GeneralizedBurgers(Em=2.4e7, eta_m=3.7e6, Ek=(4.8e7,), eta_k=(7.7e5,), E_inf=0.0)


def _json(laws):
    """Law JSON text of laws in Pa (law_file.to_json takes MPa)."""
    return law_file.to_json({T: law.scaled(1e-6) for T, law in laws.items()})


def _write(path, obj):
    path.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return path


@pytest.fixture()
def good(tmp_path):
    return _write(tmp_path / "laws.json", _json({-10.0: SOLID, 21.0: LIQUID}))


def test_reader_round_trips_the_extend_law_output(good):
    laws = law_file.read(good)
    assert sorted(laws) == [-10.0, 21.0]
    for T, ref in ((-10.0, SOLID), (21.0, LIQUID)):  # null eta_m -> no dashpot (inf)
        got = laws[T].as_dict()
        for k, v in ref.as_dict().items():
            np.testing.assert_allclose(got[k], v, rtol=1e-14)
    assert laws[-10.0].eta_m == np.inf
    w = 2 * np.pi * np.array([0.1, 10.0])
    np.testing.assert_allclose(law_file.law_at(laws, 21.0).complex_modulus(w), LIQUID.complex_modulus(w), rtol=1e-14)
    with pytest.raises(InputError, match=r"laws.json.*no law at 4 degC.*available"):
        law_file.law_at(laws, 4.0, where=str(good))
    row = study.law_summary(laws[-10.0])
    assert row == {"n_kelvin": 2, "Em_MPa": 3e3, "eta_m_MPa_s": math.inf, "E_inf_MPa": 40.0}


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda o: "{not json", "not valid JSON"),
        (lambda o: {"units": o["units"]}, "key 'temperatures'"),
        (lambda o: {**o, "temperatures": {}}, "key 'temperatures'"),
        (lambda o: {**o, "units": {**o["units"], "Em": "MPa"}}, "key 'units'"),
        (lambda o: {**o, "temperatures": {"warm": o["temperatures"]["21"]}}, "key 'temperatures.warm'"),
        (
            lambda o: {**o, "temperatures": {"21": {k: v for k, v in o["temperatures"]["21"].items() if k != "E_inf"}}},
            r"key 'temperatures.21': missing field\(s\) \['E_inf'\]",
        ),
        (
            lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "Ek": [-1.0]}}},
            r"key 'temperatures.21.Ek\[0\]'.*positive",
        ),
        (
            lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "eta_k": [1.0, 2.0]}}},
            "Ek has 1 units but eta_k has 2",
        ),
        (
            lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "eta_m": "big"}}},
            "key 'temperatures.21.eta_m'",
        ),
        (lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "Em": 0}}}, "key 'temperatures.21.Em'"),
        (
            lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "E_inf": -5.0}}},
            "key 'temperatures.21.E_inf'.*non-negative",
        ),
        (
            lambda o: {**o, "temperatures": {"21": {**o["temperatures"]["21"], "Ek": 4.8e7}}},
            "key 'temperatures.21.Ek': expected a list",
        ),
        (
            lambda o: {**o, "temperatures": {"21": o["temperatures"]["21"], "21.0": o["temperatures"]["21"]}},
            "given twice",
        ),
    ],
)
def test_reader_rejects_bad_files_naming_file_and_key(tmp_path, good, edit, message):
    bad = _write(tmp_path / "bad.json", edit(json.loads(good.read_text())))
    with pytest.raises(InputError, match=message) as err:
        law_file.read(bad)
    assert str(err.value).startswith(str(bad))


def test_reader_missing_file(tmp_path):
    with pytest.raises(InputError, match="nope.json: cannot read"):
        law_file.read(tmp_path / "nope.json")


def test_law_curves_and_reference_match_the_law():
    laws = {21.0: LIQUID}
    c = study.law_curves(laws, [21.0, 21.0], [1.0, 10.0])
    e = LIQUID.complex_modulus(2 * np.pi * np.array([1.0, 10.0])) * 1e-6
    np.testing.assert_allclose(c["E_norm_MPa"], np.abs(e), rtol=1e-12)
    np.testing.assert_allclose(c["phase_deg"], np.degrees(np.angle(e)), rtol=1e-12)
    r = study.law_reference(laws, [21.0], [10.0])
    assert r["E_norm_MPa_ref"].iloc[0] == pytest.approx(abs(e[1])) and len(c) == 2
    with pytest.raises(InputError, match="my.json.*no law at 4 degC"):
        study.law_curves(laws, [4.0], [1.0], where="my.json")


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    path = tmp_path_factory.mktemp("sample") / "s1.h5"
    write_sample(path, lattice_sample(30, seed=2, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    return path


SETTINGS = json.dumps(
    {
        "n_cycles": 2,
        "dt_policy": "steps_per_cycle",
        "steps_per_cycle": 40,
        "dt_max_s": 0.02,
        "checkpoint_every": 0,
        "profile_instants": 4,
    }
)


def _run(sample, tmp_path, name, source, freq=10):
    return main(
        [
            "run-2pb",
            "--sample",
            str(sample),
            *source,
            "--temperature",
            "20",
            "--frequency",
            str(freq),
            *set_options(SETTINGS),
            "--no-progress",
            "--mode",
            "extended",
            "-o",
            str(tmp_path / f"{name}.h5"),
            "--row",
            str(tmp_path / f"{name}.csv"),
        ]
    )


def test_run_2pb_law_json_equals_the_burgers_table_run(sample, tmp_path):
    """A law JSON holding the Table 3 Burger's law at 20 degC gives the same test as --parameters."""
    params = study.parameters_at(load_table3(TABLE3, units="Pa"), 20)
    law = burgers_model(params)
    path = _write(tmp_path / "laws.json", _json({20.0: law}))
    assert _run(sample, tmp_path, "table", ["--parameters", TABLE3, "--table3-units", "Pa"]) == 0
    assert _run(sample, tmp_path, "json", ["--law-json", str(path)]) == 0
    a, b = pd.read_csv(tmp_path / "table.csv").iloc[0], pd.read_csv(tmp_path / "json.csv").iloc[0]
    assert b["E_norm_MPa"] == pytest.approx(a["E_norm_MPa"], rel=1e-9)
    assert b["phase_deg"] == pytest.approx(a["phase_deg"], rel=1e-9, abs=1e-9)
    assert b["mode"] == "extended" and b["n_kelvin"] == 1 and b["law_json"] == str(path)
    assert b["Em_MPa"] == pytest.approx(params["Em_MPa"]) and b["E_inf_MPa"] == 0.0


def test_run_2pb_law_json_errors(sample, tmp_path, capsys):
    path = _write(tmp_path / "laws.json", _json({21.0: LIQUID}))
    assert _run(sample, tmp_path, "x", ["--law-json", str(path)]) == 2  # no law at 20 degC
    err = capsys.readouterr().err
    assert str(path) in err and "no law at 20 degC" in err
    assert _run(sample, tmp_path, "x", ["--law-json", str(path), "--factor", "Em=2"]) == 2
    assert "--factor" in capsys.readouterr().err
    bad = _write(tmp_path / "bad.json", {"temperatures": {"20": {"Em": 1.0}}})
    assert _run(sample, tmp_path, "x", ["--law-json", str(bad)]) == 2
    assert "bad.json: key 'temperatures.20': missing field(s)" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # --parameters and --law-json are exclusive
        _run(sample, tmp_path, "x", ["--law-json", str(path), "--parameters", TABLE3])
    assert not (tmp_path / "x.csv").exists()


def test_campaign_isotherms_with_law_json(sample, tmp_path):
    law = GeneralizedBurgers(Em=2.0e7, eta_m=5e6, Ek=(4e7, 1e8), eta_k=(5e5, 1e7), E_inf=1e6)
    path = _write(tmp_path / "laws.json", _json({20.0: law}))
    rows = []
    for f in (3, 40):
        assert _run(sample, tmp_path, f"20C_{f}Hz", ["--law-json", str(path)], freq=f) == 0
        rows.append(str(tmp_path / f"20C_{f}Hz.csv"))
    out = tmp_path / "out"
    assert (
        main(
            [
                "campaign-isotherms",
                "--rows",
                *rows,
                "--law-json",
                str(path),
                "--isotherms",
                str(out / "iso.csv"),
                "--table4",
                str(out / "t4.csv"),
                "--figure-modulus",
                str(out / "f9.png"),
                "--figure-phase",
                str(out / "f10.png"),
            ]
        )
        == 0
    )
    iso = pd.read_csv(out / "iso.csv")
    e = law.complex_modulus(2 * np.pi * iso["frequency_Hz"].to_numpy()) * 1e-6
    np.testing.assert_allclose(iso["E_norm_MPa_ref"], np.abs(e), rtol=1e-9)  # reference = the law
    assert pd.read_csv(out / "t4.csv")["n_frequencies"].iloc[0] == 2
    assert (out / "f9.png").stat().st_size > 1000
