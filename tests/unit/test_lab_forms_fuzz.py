"""The readers of a mix's lab forms under random input (hypothesis, profile of tests/conftest.py):
a valid DSR sweep, sieve analysis or volumetric report in random units, names and forms reads back
as its truth; a malformed one ends in an InputError, never in another exception, never accepted; a
mix file with any of its values replaced by junk is read (if still valid) or refused the same way."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import dsr_sweeps, sieve_analyses, volumetric_reports

from asphalt_nscd.io import InputError
from asphalt_nscd.lab.dsr import read_dsr
from asphalt_nscd.lab.sieve import from_values, read_sieve_analysis, sieve_opening_mm
from asphalt_nscd.lab.volumetrics import convert


def _write_sweep(folder: Path, columns: dict, sidecar: dict | None) -> Path:
    path = folder / "sweep.csv"
    pd.DataFrame(columns).to_csv(path, index=False)
    side = path.with_name("sweep.test.json")
    if sidecar is not None:
        side.write_text(json.dumps(sidecar))
    return path


def _expected(truth: pd.DataFrame) -> pd.DataFrame:
    g = truth.assign(lnG=np.log(truth["G_Pa"])).groupby(["binder", "temperature_C", "frequency_Hz"])
    out = g.agg(lnG=("lnG", "mean"), delta_deg=("delta_deg", "mean")).reset_index()
    return out.assign(G_Pa=np.exp(out.pop("lnG"))).sort_values(["binder", "temperature_C", "frequency_Hz"])


@given(dsr_sweeps())
def test_a_valid_sweep_in_any_units_reads_back_as_its_truth(sweep):
    truth, columns, sidecar = sweep
    with tempfile.TemporaryDirectory() as d:
        got = read_dsr(_write_sweep(Path(d), columns, sidecar))
    exp = _expected(truth).reset_index(drop=True)
    got = got.sort_values(["binder", "temperature_C", "frequency_Hz"]).reset_index(drop=True)
    assert got.attrs["warnings"] == [] and len(got) == len(exp)
    assert (got["binder"] == exp["binder"]).all()
    np.testing.assert_allclose(got["temperature_C"], exp["temperature_C"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["frequency_Hz"], exp["frequency_Hz"], rtol=1e-12)
    np.testing.assert_allclose(got["G_Pa"], exp["G_Pa"], rtol=1e-9)
    np.testing.assert_allclose(got["delta_deg"], exp["delta_deg"], rtol=1e-9, atol=1e-9)
    assert got["eta_Pa_s"].isna().all()


#: malformations of a sweep: (name, function of (columns, sidecar, rng) -> (columns, sidecar, raw text or None))
def _cell(columns, which, value, rng):
    cols = {k: list(v) for k, v in columns.items()}
    key = [k for k in cols if which(k)][0]
    cols[key][int(rng.integers(len(cols[key])))] = value
    return cols


def _sweep_malformations():
    num = lambda k: k.split(" (")[0] not in ("Binder", "Replicate")  # noqa: E731
    mod = lambda k: "Modulus" in k  # noqa: E731
    return {
        "word in a cell": lambda c, s, r: (_cell(c, num, "abc", r), s),
        "empty cell": lambda c, s, r: (_cell(c, num, "", r), s),
        "nan cell": lambda c, s, r: (_cell(c, num, "nan", r), s),
        "inf cell": lambda c, s, r: (_cell(c, num, "inf", r), s),
        "negative modulus": lambda c, s, r: (_cell(c, mod, "-5.0", r), s),
        "temperature 500": lambda c, s, r: (_cell(c, lambda k: k.startswith("Temperature"), "500.0", r), s),
        "frequency 0": lambda c, s, r: (_cell(c, lambda k: "Frequency" in k, "0.0", r), s),
        "duplicated row": lambda c, s, r: ({k: list(v) + [v[0]] for k, v in c.items()}, s),
        "one temperature": lambda c, s, r: (_keep(c, lambda T, rows: T == rows[0]), s),
        "two frequencies": lambda c, s, r: (_keep(c, lambda f, rows: f in sorted(set(rows))[:2], "Frequency"), s),
        "unknown sidecar key": lambda c, s, r: (c, {**(s or {}), "tabel": {}}),
        "contradicting unit": lambda c, s, r: (_relabel(c), s),
        "no modulus column": lambda c, s, r: ({k: v for k, v in c.items() if not mod(k)}, s),
    }


def _keep(columns, rule, what="Temperature"):
    key = [k for k in columns if k.startswith(what) or what in k][0]
    rows = list(columns[key])
    keep = [i for i, x in enumerate(rows) if rule(x, rows)]
    return {k: [v[i] for i in keep] for k, v in columns.items()}


def _relabel(columns):
    """Declare a unit in the header that the sidecar contradicts, or a wrong unit in the header."""
    out = {}
    for k, v in columns.items():
        if "Modulus" in k and k.endswith(")"):
            k = k.rsplit(" (", 1)[0] + " (kelvin)"
        elif "Modulus" in k:
            k = k + " (°C)"
        out[k] = v
    return out


@given(dsr_sweeps(), st.sampled_from(sorted(_sweep_malformations())), st.integers(0, 2**32 - 1))
def test_a_malformed_sweep_ends_in_an_input_error(sweep, name, seed):
    truth, columns, sidecar = sweep
    columns, sidecar = _sweep_malformations()[name](columns, sidecar, np.random.default_rng(seed))
    with tempfile.TemporaryDirectory() as d:
        path = _write_sweep(Path(d), columns, sidecar)
        with pytest.raises(InputError) as err:
            read_dsr(path)
    assert "sweep" in str(err.value) and "\n" not in str(err.value)


@given(st.binary(max_size=400))
def test_any_bytes_as_a_sweep_end_in_an_input_error(data):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "sweep.csv"
        path.write_bytes(data)
        with pytest.raises(InputError):
            read_dsr(path)


@given(sieve_analyses())
def test_a_valid_sieve_analysis_in_any_form_reads_back(analysis):
    passing, form, values = analysis
    a = from_values(values, "lab", form)
    assert a.openings_mm.tolist() == sorted(passing)
    np.testing.assert_allclose(a.passing_pct, [passing[d] for d in sorted(passing)], rtol=0, atol=1e-9)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "sieve.csv"
        head = {"passing": "% Passing", "cumulative_retained": "Cumulative % Retained", "retained": "% Retained"}[form]
        path.write_text(f"Sieve,{head}\n" + "".join(f"{k},{v!r}\n" for k, v in values.items()))
        b = read_sieve_analysis(path)
    np.testing.assert_allclose(b.passing_pct, a.passing_pct, rtol=0, atol=1e-12)
    w = a.witczak()
    assert w["rho200_pct"] == pytest.approx(passing[0.075], abs=1e-9)
    assert 0 <= w["rho34_pct"] <= w["rho38_pct"] <= w["rho4_pct"] <= 100 - w["rho200_pct"] + 1e-9


def _sieve_malformations():
    def swap(v, r):  # passing falls as the sieve grows (the values are in increasing sieve order)
        names = list(v)
        i = int(r.integers(0, len(names) - 1))
        return {**v, names[i + 1]: v[names[i]] - 0.5}

    return {
        "above 100": lambda v, f, r: ({**v, next(iter(v)): 130.0}, f),
        "negative": lambda v, f, r: ({**v, next(iter(v)): -1.0}, f),
        "not a number": lambda v, f, r: ({**v, next(iter(v)): "x"}, f),
        "unknown sieve": lambda v, f, r: ({**v, "No. 9": 50.0}, f),
        "duplicate sieve": lambda v, f, r: ({**v, f"{sieve_opening_mm(next(iter(v))):g} mm ": 1.0}, f),
        "no fine sieve": lambda v, f, r: ({k: x for k, x in v.items() if k not in ("No. 200", "0.075 mm", "Pan")}, f),
        "not cumulative": lambda v, f, r: (swap(v, r), "passing"),
    }


@given(sieve_analyses(), st.sampled_from(sorted(_sieve_malformations())), st.integers(0, 2**32 - 1))
def test_a_malformed_sieve_analysis_ends_in_an_input_error(analysis, name, seed):
    passing, form, values = analysis
    if name == "not cumulative":
        values = {n: passing[sieve_opening_mm(n)] for n in values if n != "Pan"}
    values, form = _sieve_malformations()[name](values, form, np.random.default_rng(seed))
    with pytest.raises(InputError, match="^lab"):
        from_values(values, "lab", form)


@given(volumetric_reports())
def test_a_valid_volumetric_report_in_any_form_reads_back(report):
    truth, given_values = report
    v = convert(given_values, "mix.yaml: key 'volumetrics'")
    for k in ("Va", "Vbeff", "VMA", "VFA"):
        assert getattr(v, f"{k}_pct") == pytest.approx(truth[k], rel=1e-9)


@given(volumetric_reports(), st.sampled_from(["VFA 120", "Va 40", "Va off", "key", "text", "Gse < Gsb", "VMA < Va"]))
def test_a_malformed_volumetric_report_ends_in_an_input_error(report, name):
    truth, values = report
    bad = {
        "VFA 120": {"Va": truth["Va"], "VFA": 120.0},
        "Va 40": {"Va": 40.0, "Vbeff": truth["Vbeff"]},
        "Va off": {**truth, "Va": truth["Va"] + 0.5},
        "key": {**values, "AirVoids": 4.0},
        "text": {**values, "Pb": "five"},
        "Gse < Gsb": {k: truth[k] for k in ("Pb", "Gmm", "Gmb", "Gb")} | {"Gsb": truth["Gsb"] + 0.2},
        "VMA < Va": {"Va": truth["Va"], "VMA": truth["Va"] * 0.9},
    }[name]
    with pytest.raises(InputError, match=r"^mix\.yaml: key 'volumetrics"):
        convert(bad, "mix.yaml: key 'volumetrics'")


EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "forecast_example"


def _paths(obj, prefix=()):
    """Every key path of a parsed mix file (containers and leaves)."""
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, i))


_JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=6),
    st.lists(st.integers(), max_size=2),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


@given(st.data())
def test_a_mix_file_with_any_value_replaced_is_read_or_refused_with_an_input_error(data):
    import shutil

    import yaml

    from asphalt_nscd.lab.mix_input import read_mix_file

    doc = yaml.safe_load((EXAMPLE / "mix_211.yaml").read_text())
    paths = list(_paths(doc))
    path = data.draw(st.sampled_from(paths[1:]))
    junk = data.draw(_JUNK)
    target = doc
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = junk
    with tempfile.TemporaryDirectory() as d:
        for name in ("binder_211_dsr.csv", "binder_211_dsr.test.json", "sieve_211.csv"):
            shutil.copy(EXAMPLE / name, Path(d) / name)
        mix_file = Path(d) / "mix.yaml"
        mix_file.write_text(yaml.safe_dump(doc))
        try:
            (mix,) = read_mix_file(mix_file)
        except InputError as exc:
            assert str(exc).startswith(str(mix_file)) and "\n" not in str(exc)
            return
    # accepted: the replacement left a valid mix (e.g. another valid number)
    assert all(np.isfinite(v) for v in mix.witczak.values())
    assert 0 < mix.volumetrics["Va_pct"] < 30 and 0 < mix.volumetrics["Vbeff_pct"] < 30
