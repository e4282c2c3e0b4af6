"""`extend-law` and `crossval` go through any table `asphalt-nscd measured` accepts (1-5
specimens, 3-8 temperatures, 3-9 frequencies from 0.01 to 100 Hz, missing cells, phases 1-60
deg, optional strain and test-order columns): property-based tests over generated tables
(hypothesis, fixed derandomized profile), and a fixed AMPT-shaped regression table."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from asphalt_nscd.rheology import law_file
from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis.crossval import ROW_COLUMNS
from asphalt_nscd.lab.measured import load_measured
from asphalt_nscd.rheology.models import two_s2p1d_modulus

AMPT = Path(__file__).resolve().parents[1] / "data" / "ampt_like_mix.csv"
#: fixed profile: deterministic examples (CI), no example database, modest count
PROFILE = settings(
    max_examples=20,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
)
FREQUENCY_GRID = tuple(float(f) for f in np.round(np.logspace(-2, 2, 33), 6))
#: small candidate sets keep the tests short; two settings make the nested selection run
LAW = [
    "--law-shifts",
    "wlf",
    "--law-statics",
    "constant",
    "trend",
    "--law-verticals",
    "off",
    "--law-refines",
    "off",
    "--law-per-decades",
    "2",
]
ONE = [
    "--law-shifts",
    "wlf",
    "--law-statics",
    "constant",
    "--law-verticals",
    "off",
    "--law-refines",
    "off",
    "--law-per-decades",
    "2",
    "--no-artifacts",
    "--burgers-starts",
    "1",
]


@st.composite
def tables(draw):
    n_spec = draw(st.integers(1, 5))
    temps = sorted(draw(st.lists(st.integers(-20, 70), min_size=3, max_size=8, unique=True)))
    freqs = sorted(draw(st.lists(st.sampled_from(FREQUENCY_GRID), min_size=3, max_size=9, unique=True)))
    kind = draw(st.sampled_from(["mix", "noise"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    T, f = (a.ravel() for a in np.meshgrid(np.array(temps, float), np.array(freqs), indexing="ij"))
    if kind == "mix":  # a 2S2P1D/WLF mix, phases clipped to 1-60 deg
        tau = np.exp(rng.uniform(np.log(0.005), np.log(1.0))) * 10.0 ** (-27.0 * (T - 20) / (180.0 + T - 20))
        E = two_s2p1d_modulus(
            2 * np.pi * f,
            rng.uniform(20, 300),
            rng.uniform(25e3, 45e3),
            rng.uniform(1.5, 3.5),
            rng.uniform(0.12, 0.25),
            rng.uniform(0.45, 0.7),
            rng.uniform(50, 5000),
            tau,
        )
        E_norm, phase = np.abs(E), np.clip(np.degrees(np.angle(E)), 1.0, 60.0)
    else:  # anything the loader accepts: no consistent viscoelastic behaviour at all
        E_norm, phase = np.exp(rng.uniform(np.log(5.0), np.log(4e4), T.size)), rng.uniform(1.0, 60.0, T.size)
    rows = []
    for s in range(n_spec):
        c = np.exp(rng.normal(0, 0.04))
        rows.append(
            pd.DataFrame(
                {
                    "specimen": f"S{s + 1}",
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa": E_norm * c * np.exp(rng.normal(0, 0.02, T.size)),
                    "phase_deg": np.clip(phase + rng.normal(0, 0.3, T.size), 1.0, 60.0),
                }
            )
        )
    table = pd.concat(rows, ignore_index=True)
    if draw(st.booleans()):
        table["strain_microstrain"] = np.round(rng.uniform(30, 150, len(table)), 1)
    if draw(st.booleans()):
        table["test_order"] = table.groupby("specimen").cumcount() + 1
    n_missing = draw(st.integers(0, 3))  # missing cells (all replicates of a (T, f))
    cells = table[["temperature_C", "frequency_Hz"]].drop_duplicates()
    gone = cells.sample(n=min(n_missing, len(cells) - 1), random_state=int(rng.integers(1 << 31)))
    key = pd.MultiIndex.from_frame(table[["temperature_C", "frequency_Hz"]])
    table = table[~key.isin(pd.MultiIndex.from_frame(gone))]
    return table.reset_index(drop=True), kind


def _write(tmp_path, table):
    path = tmp_path / "M.csv"
    table.to_csv(path, index=False)
    load_measured(path)  # the loader accepts every generated table
    return path


@PROFILE
@given(drawn=tables())
def test_extend_law_goes_through_any_accepted_table(tmp_path_factory, drawn):
    table, _ = drawn
    d = tmp_path_factory.mktemp("prop_extend")
    path = _write(d, table)
    out = d / "law.json"
    unmeasured = float(np.mean(table["temperature_C"].unique())) + 0.5
    assert (
        main(
            [
                "extend-law",
                "--measured",
                str(path),
                *LAW,
                "--temperatures",
                *[str(t) for t in sorted(table["temperature_C"].unique())],
                str(unmeasured),
                "-o",
                str(out),
                "--cv-curve",
                str(d / "c.csv"),
            ]
        )
        == 0
    )
    laws = law_file.read(out)  # the campaign's reader accepts it: positive, finite
    assert len(laws) == table["temperature_C"].nunique() + (unmeasured not in set(table["temperature_C"]))
    w = 2 * np.pi * np.array([0.01, 1.0, 100.0])
    for law in laws.values():
        E = law.complex_modulus(w)
        assert np.all(np.isfinite(E)) and np.all(E.real > 0) and np.all(E.imag >= 0)
    curve = pd.read_csv(d / "c.csv")
    assert curve["chosen"].sum() == 1


@PROFILE
@given(drawn=tables())
def test_crossval_goes_through_any_accepted_table(tmp_path_factory, drawn):
    """The Burger's fits run on the mix-like tables only (on noise they are slow, not wrong)."""
    table, kind = drawn
    d = tmp_path_factory.mktemp("prop_cv")
    path = _write(d, table)
    cells = table[["temperature_C", "frequency_Hz"]].drop_duplicates()
    n_T = table["temperature_C"].nunique()
    for scheme in ("lofo", "loto"):
        out = d / f"{scheme}.csv"
        burgers = [] if kind == "mix" and scheme == "lofo" else ["--no-burgers"]
        assert (
            main(
                [
                    "crossval",
                    "--measured",
                    str(path),
                    "--scheme",
                    scheme,
                    *ONE,
                    *burgers,
                    "-o",
                    str(out),
                    "--summary",
                    str(d / "s.csv"),
                ]
            )
            == 0
        )
        rows = pd.read_csv(out)
        assert list(rows.columns) == list(ROW_COLUMNS)
        law = rows[(rows["model"] == "extended_law") & (rows["kind"] == "held_out")]
        # every cell is held out exactly once
        assert len(law) == len(cells)
        assert not law.duplicated(["temperature_C", "frequency_Hz"]).any()
        ok = law["computable"].astype(bool)
        assert np.all(np.isfinite(law.loc[ok, ["E_norm_MPa_predicted", "phase_deg_predicted"]].to_numpy()))
        assert law.loc[~ok, "reason"].astype(str).str.len().gt(3).all()  # not computable: a reason
        if scheme == "loto" and n_T == 3:
            assert not ok.any() and law["reason"].str.contains("leaves 2 temperature").all()
        b = rows[rows["model"] == "burgers"]
        assert b.loc[~b["computable"].astype(bool), "reason"].astype(str).str.len().gt(3).all()


def test_ampt_shaped_regression_table(tmp_path):
    """3 specimens x (4, 21, 37 degC) x (25 ... 0.1 Hz) with a strain column: the law (artifact
    search on, nested selection) at the measured and an unmeasured temperature; lofo computable
    and close to the data, loto not computable (two temperatures left) with the reason."""
    out = tmp_path / "law.json"
    assert (
        main(["extend-law", "--measured", str(AMPT), *LAW, "--temperatures", "4", "21", "30", "37", "-o", str(out)])
        == 0
    )
    obj = json.loads(out.read_text())
    assert set(obj["temperatures"]) == {"4", "21", "30", "37"}
    assert not any(v["extrapolation"] for v in obj["temperatures"].values())
    assert "strain_nonlinearity" in " ".join(obj["source"]["notes"]) or obj["source"]["artifacts_corrected"] == []
    for T in ("4", "21", "37"):
        assert obj["temperatures"][T]["in_sample_mre_E_norm_pct_vs_measured"] < 3.0
    law30 = law_file.read(out)[30.0]
    E21, E30, E37 = (law_file.read(out)[T].complex_modulus(2 * np.pi * 1.0) for T in (21.0, 30.0, 37.0))
    assert abs(E37) < abs(E30) < abs(E21) and law30.n_kelvin >= 2
    for scheme in ("lofo", "loto"):
        assert (
            main(
                [
                    "crossval",
                    "--measured",
                    str(AMPT),
                    "--scheme",
                    scheme,
                    *LAW,
                    "-o",
                    str(tmp_path / f"{scheme}.csv"),
                    "--summary",
                    str(tmp_path / f"{scheme}_s.csv"),
                ]
            )
            == 0
        )
    lofo = pd.read_csv(tmp_path / "lofo.csv")
    held = lofo[(lofo["kind"] == "held_out") & (lofo["model"] == "extended_law")]
    assert len(held) == 18 and held["computable"].all()
    s = pd.read_csv(tmp_path / "lofo_s.csv")
    s = s[(s["kind"] == "held_out") & (s["model"] == "extended_law")]
    assert s["mre_E_norm_pct"].max() < 5.0 and s["mre_phase_pct"].max() < 8.0
    loto = pd.read_csv(tmp_path / "loto.csv")
    lh = loto[(loto["kind"] == "held_out") & (loto["model"] == "extended_law")]
    assert len(lh) == 18 and not lh["computable"].any() and lh["reason"].str.contains("leaves 2").all()
