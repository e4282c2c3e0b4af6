"""`asphalt-nscd extend-law` then `diagnose` with every simulation input (NSCD rows of the
measured and extended modes, harmonic jobs, time-integration table): the simulation causes
are testable, the gain table and page label NSCD and macro rows, and the budget decomposes."""

import json

import numpy as np
import pandas as pd
import pytest
from diagnosis_chain import cli_chain

from asphalt_nscd.rheology import law_file
from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis.causes import burgers_predict
from asphalt_nscd.rheology.metrics import cell_means

TEMPS = [-10.0, 0.0, 10.0, 15.0, 20.0, 30.0]
MACRO = pd.DataFrame(
    {
        "temperature_C": TEMPS,
        "Em_MPa": 30e3,
        "eta_m_MPa_s": [3e5, 1e5, 3e4, 1e4, 5e3, 1e3],
        "Ek_MPa": 40e3,
        "eta_k_MPa_s": [400.0, 200.0, 100.0, 50.0, 30.0, 10.0],
    }
)
DT = 5e-5


def _mre(model: pd.DataFrame, data: pd.DataFrame) -> pd.DataFrame:
    """Independent MRE (%) per temperature of model cells against data cells."""
    m = model.merge(data, on=["temperature_C", "frequency_Hz"], suffixes=("_m", "_d"))
    m["aE"] = 100 * (m["E_norm_MPa_m"] / m["E_norm_MPa_d"] - 1).abs()
    m["aP"] = 100 * (m["phase_deg_m"] / m["phase_deg_d"] - 1).abs()
    return m.groupby("temperature_C")[["aE", "aP"]].mean()


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("diag")
    m = d / "M.csv"
    assert main(["synth", "--seed", "5", "--schedule", "paper_2pb", "--specimens", "3", "-o", str(m)]) == 0
    chain = cli_chain(m, d)
    laws_path = chain["law"]
    MACRO.to_csv(d / "macro.csv", index=False)
    grid = pd.DataFrame([(T, f) for T in TEMPS for f in (3.0, 10.0, 40.0)], columns=["temperature_C", "frequency_Hz"])
    E = burgers_predict(MACRO, grid["temperature_C"], grid["frequency_Hz"])
    paths = {"sim": [], "harm": []}
    for s, factor in (("s1", 1.19), ("s2", 1.21)):  # sample mean: network factor 1.2
        harm = grid.assign(
            sample=s, mode="measured", solver="reuse", E_norm_MPa=factor * np.abs(E), phase_deg=np.degrees(np.angle(E))
        )
        harm.to_csv(d / f"{s}_measured.csv", index=False)
        paths["harm"].append(str(d / f"{s}_measured.csv"))
        sim = harm.drop(columns="solver").assign(
            dt_s=DT, phase_deg=harm["phase_deg"] + 0.5 * 360 * grid["frequency_Hz"] * DT
        )
        sim.to_csv(d / f"{s}_nscd.csv", index=False)
        paths["sim"].append(str(d / f"{s}_nscd.csv"))
    # the extended run: 1.2 x the extended law, as numerical isotherms (sample means)
    laws = law_file.read(laws_path)
    Ex = np.array(
        [laws[T].complex_modulus(2 * np.pi * f) * 1e-6 for T, f in zip(grid["temperature_C"], grid["frequency_Hz"])]
    )
    ext = grid.assign(n_samples=2, E_norm_MPa_mean=1.2 * np.abs(Ex), phase_deg_mean=np.degrees(np.angle(Ex)))
    ext.to_csv(d / "iso_extended.csv", index=False)
    ti = pd.DataFrame(
        [
            (f, dt, th, c * 360 * f * dt)
            for f in (3.0, 40.0)
            for dt in (2e-5, 1e-4)
            for th, c in ((0.5, 0.5), (1.0, 2.0))
        ],
        columns=["frequency_Hz", "dt_s", "theta", "phase_error_deg"],
    )
    ti.to_csv(d / "ti.csv", index=False)
    out = {k: d / k for k in ("r.json", "gain.csv", "budget.csv", "page.md", "effects.csv", "fig.png")}
    assert (
        main(
            [
                "diagnose",
                *chain["args"],
                "--macro-params",
                str(d / "macro.csv"),
                "--simulated",
                *paths["sim"],
                "--harmonic",
                *paths["harm"],
                "--simulated-extended",
                str(d / "iso_extended.csv"),
                "--time-integration",
                str(d / "ti.csv"),
                "--theta",
                "0.5",
                "-o",
                str(out["r.json"]),
                "--gain-csv",
                str(out["gain.csv"]),
                "--budget-csv",
                str(out["budget.csv"]),
                "--page",
                str(out["page.md"]),
                "--effects-csv",
                str(out["effects.csv"]),
                "--figure",
                str(out["fig.png"]),
            ]
        )
        == 0
    )
    return {
        "dir": d,
        "measured": m,
        "laws": laws_path,
        "chain": chain,
        "grid": grid,
        "E": E,
        "Ex": Ex,
        "out": out,
        "report": json.loads(out["r.json"].read_text()),
    }


def test_simulation_causes_are_testable_with_estimates(run):
    by = {e["name"]: e for e in run["report"]["effects"]}
    nf, ti = by["network_factor"], by["time_integration"]
    assert nf["testable"] and ti["testable"]
    assert nf["estimate"]["network_factor"] == pytest.approx(1.2, rel=2e-3)
    assert ti["estimate"]["phase_error_per_phase_step"] == pytest.approx(0.5, rel=1e-9)  # theta 0.5 rows only
    causes = pd.read_csv(run["out"]["effects.csv"]).set_index("name")
    assert bool(causes.loc["network_factor", "testable"]) and bool(causes.loc["time_integration", "testable"])


def test_gain_table_nscd_before_after_and_macro(run):
    rep, grid = run["report"], run["grid"]
    assert rep["gain_sources"]["before"] == "nscd" and rep["gain_sources"]["after"] == "nscd"
    gain = pd.read_csv(run["out"]["gain.csv"])
    assert set(gain["source"]) == {"nscd", "macro"}
    assert len(gain) == 2 * len(TEMPS)
    assert gain.loc[gain["source"] == "nscd", "before_model"].str.startswith("NSCD").all()
    assert gain.loc[gain["source"] == "macro", "after_model"].str.startswith("generalized Burger's law").all()
    measured = cell_means(pd.read_csv(run["measured"]))
    corrected = cell_means(pd.read_csv(run["chain"]["corrected"]))
    E = run["E"]
    sim = grid.assign(
        E_norm_MPa=1.2 * np.abs(E), phase_deg=np.degrees(np.angle(E)) + 0.5 * 360 * grid["frequency_Hz"] * DT
    )
    ext = grid.assign(E_norm_MPa=1.2 * np.abs(run["Ex"]), phase_deg=np.degrees(np.angle(run["Ex"])))
    before, after = _mre(sim, measured), _mre(ext, corrected)
    nscd = gain[gain["source"] == "nscd"].set_index("temperature_C")
    for T in TEMPS:
        assert nscd.loc[T, "E_norm_mre_before_pct"] == pytest.approx(before.loc[T, "aE"], rel=1e-9)
        assert nscd.loc[T, "phase_mre_before_pct"] == pytest.approx(before.loc[T, "aP"], rel=1e-9)
        assert nscd.loc[T, "E_norm_mre_after_pct"] == pytest.approx(after.loc[T, "aE"], rel=1e-9)
        assert nscd.loc[T, "phase_mre_after_pct"] == pytest.approx(after.loc[T, "aP"], rel=1e-9)
        # a 1.2 network factor keeps the NSCD |E*| about 20 % off after the extension
        assert nscd.loc[T, "E_norm_mre_after_pct"] > 10
    # macro rows: Burger's law vs measured before; the law JSON's own MRE after
    laws_json = json.loads(run["laws"].read_text())["temperatures"]
    macro = gain[gain["source"] == "macro"].set_index("temperature_C")
    Em = burgers_predict(MACRO, measured["temperature_C"], measured["frequency_Hz"])  # every measured cell
    burgers = measured[["temperature_C", "frequency_Hz"]].assign(
        E_norm_MPa=np.abs(Em), phase_deg=np.degrees(np.angle(Em))
    )
    mb = _mre(burgers, measured)
    for T in TEMPS:
        assert macro.loc[T, "E_norm_mre_before_pct"] == pytest.approx(mb.loc[T, "aE"], rel=1e-9)
        assert macro.loc[T, "phase_mre_after_pct"] == pytest.approx(
            laws_json[f"{T:g}"]["in_sample_mre_phase_pct"], rel=1e-9
        )
    assert rep["gain_nscd"] == rep["gain"] and set(rep["gain_macro"]) == {f"{T:g}" for T in TEMPS}


def test_budget_decomposes_with_the_simulation_rows(run):
    budget = pd.read_csv(run["out"]["budget.csv"])
    assert set(budget["component"]) == {"data_artifacts", "model_form", "micro_macro_transfer", "numerics", "total"}
    b = budget.set_index(["temperature_C", "component"])
    for T in TEMPS:
        assert b.loc[(T, "micro_macro_transfer"), "mre_E_norm_pct"] == pytest.approx(20.0, rel=1e-6)
        assert b.loc[(T, "numerics"), "mre_E_norm_pct"] == pytest.approx(0.0, abs=1e-9)
        assert b.loc[(T, "numerics"), "mre_phase_pct"] > 0  # the time-step phase error of the NSCD rows


def test_page_labels_nscd_and_macro_rows(run):
    page = run["out"]["page.md"].read_text()
    assert "| 10 | NSCD simulation |" in page and "| 10 | macro law |" in page
    assert "total = the NSCD simulation vs the measured means" in page


def test_extend_law_from_the_written_search_equals_its_own_search(run, tmp_path):
    """The split keeps the law: extend-law on the search that master-curve wrote gives the very
    law file of extend-law searching the table itself (the workflow's outputs do not change)."""
    out = tmp_path / "l.json"
    assert (
        main(["extend-law", "--measured", str(run["measured"]), "-o", str(out), "--corrected", str(tmp_path / "c.csv")])
        == 0
    )
    assert json.loads(out.read_text()) == json.loads(run["laws"].read_text())
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "c.csv"), pd.read_csv(run["chain"]["corrected"]))


def test_diagnose_law_json_must_cover_the_measured_temperatures(run, tmp_path, capsys):
    obj = json.loads(run["laws"].read_text())
    del obj["temperatures"]["15"]
    bad = tmp_path / "laws.json"
    bad.write_text(json.dumps(obj))
    args = run["chain"]["args"]
    args = args[: args.index("--law-json")] + ["--law-json", str(bad)]
    assert main(["diagnose", *args, "-o", str(tmp_path / "r.json")]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: key 'temperatures': no law at [15.0] degC" in err
    assert not (tmp_path / "r.json").exists()
