"""The law file (rheology.law_file) and the shared error measures and matching rules
(rheology.metrics): round trips, the evaluation at (T, f), errors naming file and key."""

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.io import InputError
from asphalt_nscd.rheology import law_file, metrics
from asphalt_nscd.rheology.laws import GeneralizedBurgers

SOLID = GeneralizedBurgers(Em=30e3, eta_m=np.inf, Ek=(20e3, 2e3), eta_k=(20.0, 200.0), E_inf=150.0)  # MPa
LIQUID = GeneralizedBurgers.burgers(25e3, 4e3, 9e3, 300.0)


def test_write_read_round_trip_in_pa_and_mpa(tmp_path):
    path = tmp_path / "law.json"
    law_file.write(law_file.to_json({21.0: SOLID, 4.0: LIQUID}, {21.0: 1.5, 4.0: 2.5}, {21.0: 3.5, 4.0: 4.5}), path)
    obj = json.loads(path.read_text())
    assert list(obj["temperatures"]) == ["4", "21"] and obj["temperatures"]["21"]["eta_m"] is None
    assert obj["temperatures"]["4"]["in_sample_mre_E_norm_pct"] == 2.5
    pa = law_file.read(path)
    assert pa[21.0].Em == pytest.approx(30e9, rel=1e-15) and np.isinf(pa[21.0].eta_m)
    mpa = law_file.read_mpa(path, [21.0, 4.0 + 1e-9])
    assert list(mpa) == [21.0, 4.0 + 1e-9]
    w = 2 * np.pi * np.array([0.1, 1.0, 30.0])
    np.testing.assert_allclose(mpa[21.0].complex_modulus(w), SOLID.complex_modulus(w), rtol=1e-13)
    # evaluation at (T, f) pairs: the law of each pair's isotherm, E* in the laws' units
    E = law_file.complex_modulus(mpa, [21.0, 4.0 + 1e-9, 21.0], [0.1, 1.0, 30.0])
    expect = [SOLID.complex_modulus(w[0]), LIQUID.complex_modulus(w[1]), SOLID.complex_modulus(w[2])]
    np.testing.assert_allclose(E, expect, rtol=1e-13)
    with pytest.raises(InputError, match=r"law.json: key 'temperatures': no law at \[30.0\] degC"):
        law_file.read_mpa(path, [21.0, 30.0])
    with pytest.raises(InputError, match="where.json: key 'temperatures': no law at 21.1 degC"):
        law_file.law_at(mpa, 21.1, where="where.json")
    assert law_file.read_info(path) == {"selection": None, "model": None, "card": None}


def test_write_refuses_a_bad_object_and_leaves_no_file(tmp_path):
    obj = law_file.to_json({21.0: SOLID})
    obj["temperatures"]["21"]["Ek"] = [1.0]
    path = tmp_path / "bad.json"
    with pytest.raises(InputError, match=r"bad.json: key 'temperatures.21': Ek has 1 units but eta_k has 2"):
        law_file.write(obj, path)
    assert not path.exists()
    obj = law_file.to_json({21.0: SOLID})
    obj["temperatures"]["21.0000001"] = obj["temperatures"]["21"]  # the same isotherm (1e-6 degC rule)
    with pytest.raises(InputError, match="temperature 21 degC given twice"):
        law_file.validate(obj, "x.json")


def test_metrics_mre_matching_and_cell_means():
    assert metrics.mre_pct([1.1, 0.8], [1.0, 1.0]) == pytest.approx(15.0)
    assert metrics.mre_pct([-2.0], [-1.0]) == pytest.approx(100.0)  # relative to |reference|
    assert np.isnan(metrics.mre_pct([], []))
    assert metrics.same_temperature(21.0, 21.0 + 0.9e-6) and not metrics.same_temperature(21.0, 21.0 + 1.1e-6)
    assert metrics.same_frequency(1e3, 1e3 * (1 + 1e-13)) and not metrics.same_frequency(1e-3, 1e-3 + 1e-12)
    assert metrics.temperature_key([4.0, 21.0], 21.0000001) == 21.0 and metrics.temperature_key([4.0], 5.0) is None
    rows = pd.DataFrame(
        {
            "specimen": ["a", "b", "a"],
            "temperature_C": [21.0, 21.0, 4.0],
            "frequency_Hz": [1.0, 1.0, 1.0],
            "E_norm_MPa": [100.0, 400.0, 50.0],
            "phase_deg": [20.0, 30.0, 10.0],
        }
    )
    cm = metrics.cell_means(rows)
    assert cm["temperature_C"].tolist() == [4.0, 21.0] and cm["n"].tolist() == [1, 2]
    assert cm["E_norm_MPa"].tolist() == [50.0, 250.0] and cm["phase_deg"].tolist() == [10.0, 25.0]
    assert cm["lnE"].iloc[1] == pytest.approx(np.log(200.0))  # mean of logs: the geometric mean
    assert len(metrics.at_temperature(rows, 21.0 + 5e-7)) == 2
