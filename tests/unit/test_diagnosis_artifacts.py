"""The artifact search written once (diagnosis.artifacts): its JSON reads back to the very
numbers computed, and a bad file is named with its key."""

import json

import numpy as np
import pytest

from asphalt_nscd.diagnosis import artifacts, synthetic
from asphalt_nscd.io import InputError, write_csv, write_json


@pytest.fixture(scope="module")
def searched(tmp_path_factory):
    table, _ = synthetic.generate(3, ["time_lag"], schedule="paper_2pb", n_specimens=3)
    a = artifacts.analyse(table)
    rec = artifacts.record(a, alpha=1e-3, shift="wlf", T_ref_C=None)
    d = tmp_path_factory.mktemp("search")
    write_json(artifacts.to_json(rec, {"measured": "synthetic"}), d / "mc.json")
    write_csv(a["corrected"].drop(columns=["test_step"], errors="ignore"), d / "c.csv")
    return table, a, rec, d


def test_json_and_corrected_table_read_back_exactly(searched):
    table, a, rec, d = searched
    back = artifacts.read(d / "mc.json")
    assert back.artifacts == rec.artifacts and "time_lag" in back.artifacts
    assert back.effects == rec.effects and back.screening == rec.screening and back.sigma == rec.sigma
    m0, m1 = a["master"], back.master
    assert np.array_equal(m0.x, m1.x) and np.array_equal(m0.se, m1.se) and m0.rss == m1.rss
    assert m0.n_params == m1.n_params and m0.specimens == m1.specimens
    f, T = np.geomspace(0.1, 30, 7), np.linspace(-10, 30, 7)
    assert np.array_equal(m0.modulus(f, T), m1.modulus(f, T))
    corrected = artifacts.read_corrected(d / "c.csv")
    ref = a["corrected"].drop(columns=["test_step"], errors="ignore")
    for c in ("temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg"):
        assert np.array_equal(corrected[c].to_numpy(float), ref[c].to_numpy(float))
    assert (corrected["specimen"] == ref["specimen"].astype(str)).all()


def test_bad_files_are_named_with_the_key(searched, tmp_path):
    _, _, _, d = searched
    obj = json.loads((d / "mc.json").read_text())
    obj["master_curve"]["x"] = obj["master_curve"]["x"][:-1]
    bad = tmp_path / "mc.json"
    bad.write_text(json.dumps(obj))
    with pytest.raises(InputError, match="mc.json: not a master-curve JSON.*inconsistent sizes"):
        artifacts.read(bad)
    obj = json.loads((d / "mc.json").read_text())
    del obj["noise"]
    bad.write_text(json.dumps(obj))
    with pytest.raises(InputError, match="mc.json: key 'noise': missing"):
        artifacts.read(bad)
    c = tmp_path / "c.csv"
    lines = (d / "c.csv").read_text().splitlines()
    head = lines[0].split(",")
    row = lines[1].split(",")
    row[head.index("E_norm_MPa")] = "-3"
    c.write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n")
    with pytest.raises(InputError, match="c.csv: line 2, column 'E_norm_MPa': expected a finite number > 0"):
        artifacts.read_corrected(c)
