"""Sieve analyses (asphalt_nscd.lab.sieve): ASTM E11 names, the forms of a report, the passing curve
(the discrete model's, to the last bit) and the Witczak figures, and the refusals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from asphalt_nscd.forecast.formulation import SIEVES_MM, passing_curve
from asphalt_nscd.io import InputError
from asphalt_nscd.lab.matched import read_matched
from asphalt_nscd.lab.sieve import from_values, from_witczak, read_sieve_analysis, sieve_opening_mm

TABLE = Path(__file__).resolve().parents[2] / "data" / "binder_mix" / "mixes_35.tsv"

#: a 19 mm Superpave gradation (% passing), the kind a lab reports
LAB = {
    "1 in": 100,
    "3/4 in": 97,
    "1/2 in": 85,
    "3/8 in": 74,
    "No. 4": 48,
    "No. 8": 33,
    "No. 16": 23,
    "No. 30": 16,
    "No. 50": 11,
    "No. 100": 7.5,
    "No. 200": 5.0,
}


@pytest.mark.parametrize(
    "name,mm",
    [
        ("1 1/2 in", 37.5),
        ("1 in", 25.0),
        ('3/4"', 19.0),
        ("¾ in", 19.0),
        ("1/2 inch", 12.5),
        ("3/8 in", 9.5),
        ("No. 4", 4.75),
        ("#8", 2.36),
        ("No 16", 1.18),
        ("No. 200", 0.075),
        ("no. 3 1/2", 5.6),
        ("0.530 in", 13.2),
        ("19", 19.0),
        ("0.075 mm", 0.075),
        ("75 um", 0.075),
        ("75 µm", 0.075),
        ("No. 200 (75 µm)", 0.075),
        (12.5, 12.5),
    ],
)
def test_sieve_names_read_as_astm_e11_openings(name, mm):
    assert sieve_opening_mm(name) == pytest.approx(mm, rel=1e-12)


@pytest.mark.parametrize("name", ["No. 9", "3/5 in", "Pan x", "abc", "No. 4 (9.5 mm)", -3, 1e6, "1 1/2"])
def test_unknown_sieves_are_refused(name):
    with pytest.raises(InputError, match="where"):
        sieve_opening_mm(name, "where")


def test_the_four_figures_and_the_top_size_give_the_discrete_models_curve_to_the_bit():
    table = read_matched(TABLE).groupby("mix_id").first()
    openings = np.array(list(SIEVES_MM) + [0.05, 0.075, 4.75, 9.5, 18.9, 19.0, 24.9, 25.0, 40.0])
    for mix_id, row in table.iterrows():
        analysis = from_witczak(row["rho34_pct"], row["rho38_pct"], row["rho4_pct"], row["rho200_pct"])
        ref = passing_curve(row.rename(mix_id), openings)
        assert np.array_equal(analysis.passing_at(openings), np.array([ref[float(s)] for s in openings])), mix_id
        w = analysis.witczak()
        assert w == pytest.approx({k: row[k] for k in w}, rel=0, abs=1e-12)


def test_a_full_analysis_reads_its_measured_sieves_and_interpolates_log_log_between():
    a = from_values(LAB, "lab")
    assert a.top_size_mm == 25.0 and a.openings_mm[0] == 0.075
    w = a.witczak()
    assert w == {"rho34_pct": 3.0, "rho38_pct": 26.0, "rho4_pct": 52.0, "rho200_pct": 5.0}
    # without the 3/8 in sieve: the log-log line between 1/2 in (85 %) and No. 4 (48 %)
    b = from_values({k: v for k, v in LAB.items() if k != "3/8 in"}, "lab")
    n = math.log(85 / 48) / math.log(12.5 / 4.75)
    assert b.witczak()["rho38_pct"] == pytest.approx(100 - 48 * (9.5 / 4.75) ** n, rel=1e-12)
    assert b.passing_at([12.5, 4.75]) == pytest.approx([85, 48], rel=1e-12)
    # at and above the top size: 100
    assert list(a.passing_at([25.0, 31.5, 100.0])) == [100.0, 100.0, 100.0]


def test_cumulative_and_per_sieve_retained_read_as_the_same_curve():
    passing = from_values(LAB, "lab")
    cum = from_values({k: 100 - v for k, v in LAB.items()}, "lab", form="cumulative_retained")
    p = np.array(list(LAB.values()))[::-1]  # increasing sieves
    per = dict(zip(list(LAB)[::-1], np.diff(np.append(p, 100.0))))
    per["Pan"] = 5.0
    retained = from_values(per, "lab", form="retained")
    for other in (cum, retained):
        assert np.allclose(other.passing_pct, passing.passing_pct, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "values,form,pattern",
    [
        (
            {**LAB, "3/8 in": 90},
            "passing",
            r"sieve '1/2 in'.*less than 90 % passing the smaller 9.5 mm sieve.*not a cumulative",
        ),
        ({**LAB, "No. 4": 130}, "passing", r"130 out of range; expected a percentage in 0-100"),
        ({**LAB, "No. 4": "x"}, "passing", r"'x' is not a number"),
        ({**LAB, "4.75 mm": 48}, "passing", r"4.75 mm sieve is given twice"),
        ({k: v for k, v in LAB.items() if k != "No. 200"}, "passing", r"no sieve at or below 0.075 mm"),
        ({k: v for k, v in LAB.items() if k != "1 in"}, "passing", r"no sieve with 100 % passing"),
        ({**LAB, "No. 200": 0}, "passing", r"0 % passing the 0.075 mm sieve"),
        ({**LAB, "No. 9": 30}, "passing", r"'No. 9' is not a sieve of ASTM E11"),
        ({"1 in": 10, "No. 4": 50, "No. 200": 30, "Pan": 5}, "retained", r"sum to 95 %; expected 100"),
        ({"1 in": 0, "No. 200": 100, "Pan": 0}, "passing", r"a pan row belongs to per-sieve % retained"),
    ],
)
def test_malformed_analyses_are_refused_naming_the_sieve(values, form, pattern):
    with pytest.raises(InputError, match=pattern) as err:
        from_values(values, "mix.yaml: key 'gradation'", form)
    assert str(err.value).startswith("mix.yaml: key 'gradation'")


def test_witczak_figures_are_never_extrapolated_below_the_finest_sieve():
    a = from_values({"3/4 in": 100, "No. 4": 50, "No. 100": 8, "0.075": 6}, "lab")
    assert a.witczak()["rho200_pct"] == 6
    with pytest.raises(InputError, match="no sieve at or below 0.075"):
        from_values({"3/4 in": 100, "No. 4": 50, "No. 100": 8}, "lab")


def test_a_lab_file_with_common_headers_and_one_with_a_sidecar(tmp_path):
    f = tmp_path / "grading.csv"
    f.write_text("Sieve Size,Cumulative % Retained,Remarks\n" + "".join(f"{k},{100 - v},x\n" for k, v in LAB.items()))
    a = read_sieve_analysis(f)
    assert np.allclose(a.passing_pct, from_values(LAB, "x").passing_pct)
    g = tmp_path / "g2.tsv"
    g.write_text("opening\tvalue\n" + "".join(f"{sieve_opening_mm(k)}\t{v}\n" for k, v in LAB.items()))
    with pytest.raises(InputError, match=r"no value column"):
        read_sieve_analysis(g)
    (tmp_path / "g2.test.json").write_text(json.dumps({"table": {"form": "passing", "columns": {"value": "value"}}}))
    assert np.allclose(read_sieve_analysis(g).passing_pct, a.passing_pct)
    (tmp_path / "g2.test.json").write_text(json.dumps({"table": {"form": "passing", "colums": {}}}))
    with pytest.raises(InputError, match=r"g2\.test\.json: key 'table\.colums': unknown key"):
        read_sieve_analysis(g)
    bad = tmp_path / "bad.csv"
    bad.write_text("Sieve,% Passing\n3/4 in,100\nNo. 4,\nNo. 200,5\n")
    with pytest.raises(InputError, match=r"bad\.csv: line 3, column '% Passing': empty cell"):
        read_sieve_analysis(bad)
    bad.write_text("Sieve,% Passing\n3/4 in,100\nNo. 44,50\nNo. 200,5\n")
    with pytest.raises(InputError, match=r"bad\.csv: line 3, column 'Sieve': 'No. 44' is not a sieve"):
        read_sieve_analysis(bad)
