"""Held-out validation (`asphalt-nscd crossval`): folds, no leakage of a held-out cell into its
fold's fit (nested selection and artifact correction included), not-computable folds, scores
against an independent computation, the NSCD-sample model and the CLI."""

import json

import numpy as np
import pandas as pd
import pytest
from diagnosis_chain import cli_chain

from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis import crossval as cv
from asphalt_nscd.diagnosis import synthetic
from asphalt_nscd.sample.lattice import lattice_sample
from asphalt_nscd.sample.store import write_sample
from asphalt_nscd.harmonic.transfer import write_transfer

#: two candidates: the nested selection runs in every fold
OPTIONS = cv.Options(candidates=tuple(cv.candidate_grid(statics=("constant", "trend"))))


@pytest.fixture(scope="module")
def table():
    t, _ = synthetic.generate(5, [], schedule="aashto_t342", n_specimens=2)
    return t


@pytest.fixture(scope="module")
def lofo(table):
    return cv.crossval(table, "lofo", OPTIONS)


def _held(rows, fold, model="extended_law"):
    r = rows[(rows["fold"] == fold) & (rows["kind"] == "held_out") & (rows["model"] == model)]
    return r.sort_values(["temperature_C", "frequency_Hz"]).reset_index(drop=True)


@pytest.mark.parametrize("scheme, column, value, other", [("lofo", "frequency_Hz", 1.0, "10"),
                                                          ("loto", "temperature_C", 21.0, "37")])
def test_a_held_out_value_never_reaches_its_fold(table, lofo, scheme, column, value, other):
    """Multiply the held-out rows' |E*| by 10 and shift their phase by 15 deg: the fold's
    predictions (artifact correction, nested choice of the settings and law all refitted) do
    not move at all, while a fold that trains on those rows does move."""
    base = lofo if scheme == "lofo" else cv.crossval(table, scheme, OPTIONS)
    hit = np.isclose(table[column], value)
    bad = table.copy()
    bad.loc[hit, "E_norm_MPa"] *= 10.0
    bad.loc[hit, "phase_deg"] += 15.0
    moved = cv.crossval(bad, scheme, OPTIONS)
    fold = f"{value:g}"
    a, b = _held(base.rows, fold), _held(moved.rows, fold)
    assert len(a) == hit.sum() / table["specimen"].nunique() and a["computable"].all()
    np.testing.assert_array_equal(a["E_norm_MPa_predicted"], b["E_norm_MPa_predicted"])
    np.testing.assert_array_equal(a["phase_deg_predicted"], b["phase_deg_predicted"])
    # ... the measured reference of course changes, and a fold trained on the rows moves
    assert np.all(b["E_norm_MPa_measured"] > 5 * a["E_norm_MPa_measured"])
    c, d = _held(base.rows, other), _held(moved.rows, other)
    assert np.max(np.abs(d["E_norm_MPa_predicted"] / c["E_norm_MPa_predicted"] - 1)) > 0.01
    # the in-sample fit sees every row
    ins = lambda r: r[(r["kind"] == "in_sample") & (r["model"] == "extended_law")]["E_norm_MPa_predicted"]
    assert not np.allclose(ins(base.rows).to_numpy(), ins(moved.rows).to_numpy())


def test_folds_rows_and_nested_selection(table, lofo):
    rows = lofo.rows
    assert list(rows.columns) == list(cv.ROW_COLUMNS)
    freqs = sorted(table["frequency_Hz"].unique())
    held = rows[(rows["kind"] == "held_out") & (rows["model"] == "extended_law")]
    assert sorted(held["fold"].unique(), key=float) == [f"{f:g}" for f in freqs]
    # each fold holds exactly the cells at its frequency, at every temperature
    for f, g in held.groupby("fold"):
        assert np.allclose(g["frequency_Hz"], float(f)) and len(g) == table["temperature_C"].nunique()
    # the lowest and highest frequency folds are frequency extrapolations
    assert held.loc[held["fold"] == f"{freqs[0]:g}", "extrapolation"].all()
    assert not held.loc[held["fold"] == f"{freqs[2]:g}", "extrapolation"].any()
    # a selection curve per fold and for the whole table, one setting chosen in each
    curves = lofo.curves
    assert set(curves["fold"]) == {"all", *held["fold"]}
    assert (curves.groupby("fold")["chosen"].sum() == 1).all()
    assert curves["cv_score"].notna().all() and (curves["n_folds"] > 0).all()
    # Burger's per isotherm is predicted too; in-sample rows beside
    assert rows.loc[(rows["model"] == "burgers") & (rows["kind"] == "held_out"), "computable"].all()
    assert {"held_out", "in_sample"} == set(rows["kind"])


def test_scores_follow_the_protocol(table, lofo):
    """MRE per temperature of the summary = an independent computation from the replicate means
    of the table as given (| |E|p/|E|m - 1 |, | Phi_p - Phi_m | / Phi_m)."""
    means = table.groupby(["temperature_C", "frequency_Hz"])[["E_norm_MPa", "phase_deg"]].mean().reset_index()
    held = lofo.rows[(lofo.rows["kind"] == "held_out") & (lofo.rows["model"] == "extended_law")]
    m = held.merge(means, on=["temperature_C", "frequency_Hz"])
    eE = (m["E_norm_MPa_predicted"] / m["E_norm_MPa"] - 1).abs()
    eP = (m["phase_deg_predicted"] - m["phase_deg"]).abs() / m["phase_deg"]
    ref = pd.DataFrame({"T": m["temperature_C"], "E": 100 * eE, "P": 100 * eP}).groupby("T").mean()
    s = cv.summarize(lofo.rows)
    s = s[(s["kind"] == "held_out") & (s["model"] == "extended_law")].set_index("temperature_C")
    np.testing.assert_allclose(s.loc[ref.index, "mre_E_norm_pct"], ref["E"], rtol=1e-12)
    np.testing.assert_allclose(s.loc[ref.index, "mre_phase_pct"], ref["P"], rtol=1e-12)
    head = cv.headline(cv.summarize(lofo.rows))
    h = head[(head["kind"] == "held_out") & (head["model"] == "extended_law")].iloc[0]
    assert h["worst_E_norm_pct"] == pytest.approx(ref["E"].max())
    # on a thermorheologically simple table the held-out law is within a few percent
    assert ref["E"].max() < 6 and ref["P"].max() < 10


def test_loto_reports_end_temperatures_apart_and_three_temperatures_as_not_computable(table):
    three = table[table["temperature_C"].isin([4.0, 21.0, 37.0])]
    res = cv.crossval(three, "loto", cv.Options())
    held = res.rows[(res.rows["kind"] == "held_out") & (res.rows["model"] == "extended_law")]
    assert not held["computable"].any()
    assert held["reason"].str.contains("leaves 2 temperature").all()
    # the in-sample rows are still there, and the lofo folds of the same table are computable
    assert res.rows.loc[res.rows["kind"] == "in_sample", "computable"].all()
    lofo = cv.crossval(three, "lofo", cv.Options())
    assert lofo.rows.loc[(lofo.rows["kind"] == "held_out") & (lofo.rows["model"] == "extended_law"),
                         "computable"].all()
    # five temperatures: the end ones are extrapolations, left out of the loto headline
    five = cv.crossval(table, "loto", cv.Options())
    s = cv.summarize(five.rows)
    s = s[(s["kind"] == "held_out") & (s["model"] == "extended_law")]
    assert s.set_index("temperature_C")["extrapolation"].to_dict() == {-10.0: True, 4.0: False, 21.0: False,
                                                                       37.0: False, 54.0: True}
    h = cv.headline(s)
    assert h.iloc[0]["worst_E_norm_T_C"] in (4.0, 21.0, 37.0)
    assert five.rows.loc[(five.rows["model"] == "burgers") & (five.rows["kind"] == "held_out"),
                         "reason"].str.contains("no temperature dependence").all()


def test_unbalanced_table_fold_removes_what_it_names(table):
    """A frequency tested at one temperature only: its fold holds that one cell; the Burger's
    law of an isotherm left with too few points is not computable, with the reason."""
    t = table[~((table["frequency_Hz"] == 0.5) & (table["temperature_C"] != 21.0))]
    t = t[~((t["temperature_C"] == 54.0) & (t["frequency_Hz"].isin([1.0, 5.0, 10.0])))]
    res = cv.crossval(t, "lofo", cv.Options())
    held = res.rows[res.rows["kind"] == "held_out"]
    one = held[(held["fold"] == "0.5") & (held["model"] == "extended_law")]
    assert len(one) == 1 and one["temperature_C"].iloc[0] == 21.0 and one["computable"].all()
    b54 = held[(held["model"] == "burgers") & (held["temperature_C"] == 54.0)]
    assert not b54["computable"].any() and b54["reason"].str.contains("Burger's fit at 54").all()


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    d = tmp_path_factory.mktemp("cv_sample")
    path = d / "s1.h5"
    write_sample(path, lattice_sample(40, seed=4, radius_range=(0.9e-3, 1.5e-3), plate_mass=(np.inf, 1e-3)))
    transfer = d / "s1.json"
    write_transfer(path, transfer)
    return path, transfer


def test_nscd_sample_reproduces_the_fold_law_without_inertia(table, sample):
    """Bonds calibrated with E*/NF_s: the inertia-free sample modulus is the fold's law exactly
    (K(w) = E*(w) G); with inertia it differs a little (the head and sphere masses)."""
    small = table[table["frequency_Hz"].isin([0.1, 1.0, 10.0, 25.0])]
    none = cv.SampleModel.load(*sample, inertia="none")
    res = cv.crossval(small, "lofo", cv.Options(), sample=none)
    r = res.rows
    law, nscd = (r[r["model"] == m].reset_index(drop=True) for m in ("extended_law", "nscd_sample"))
    assert len(law) == len(nscd) > 0 and nscd["computable"].all()
    np.testing.assert_allclose(nscd["E_norm_MPa_predicted"], law["E_norm_MPa_predicted"], rtol=1e-8)
    np.testing.assert_allclose(nscd["phase_deg_predicted"], law["phase_deg_predicted"], rtol=1e-8, atol=1e-8)
    full = cv.SampleModel.load(*sample, inertia="full")
    held = law[law["kind"] == "held_out"].iloc[0]
    fold = cv.fit_extended(small[small["frequency_Hz"] != held["frequency_Hz"]], cv.Options())
    E, P = full.predict(fold.law.law_at(held["temperature_C"]), held["temperature_C"], [held["frequency_Hz"]])[0]
    assert E == pytest.approx(held["E_norm_MPa_predicted"], rel=0.05) and E != held["E_norm_MPa_predicted"]


def test_cli_crossval_outputs_and_time_domain_rows(tmp_path, table):
    m = tmp_path / "M.csv"
    table.to_csv(m, index=False)
    td = tmp_path / "td.csv"
    means = table.groupby(["temperature_C", "frequency_Hz"])[["E_norm_MPa", "phase_deg"]].mean().reset_index()
    means[(means["temperature_C"] == 21.0) & (means["frequency_Hz"] == 10.0)].to_csv(td, index=False)
    out = {k: tmp_path / k for k in ("cv.csv", "s.csv", "c.csv", "f.png")}
    args = ["crossval", "--measured", str(m), "--scheme", "lofo", "--law-statics", "constant", "--law-shifts", "wlf",
            "--law-verticals", "off", "--law-refines", "off", "--law-per-decades", "2"]
    assert main([*args, "--time-domain", str(td), "-o", str(out["cv.csv"]), "--summary", str(out["s.csv"]),
                 "--curve", str(out["c.csv"]), "--figure", str(out["f.png"])]) == 0
    rows = pd.read_csv(out["cv.csv"])
    t = rows[rows["model"] == "nscd_time_domain"]
    assert len(t) == 1 and str(t["fold"].iloc[0]) == "10" and t["rel_err_E_norm"].iloc[0] == pytest.approx(0, abs=1e-12)
    assert out["f.png"].stat().st_size > 0 and len(pd.read_csv(out["s.csv"])) > 0
    # a time-domain row at a cell that is not measured, or --sample without --transfer: clear errors
    pd.DataFrame({"temperature_C": [22.0], "frequency_Hz": [10.0], "E_norm_MPa": [1.0],
                  "phase_deg": [10.0]}).to_csv(td, index=False)
    assert main([*args, "--time-domain", str(td), "-o", str(tmp_path / "x.csv")]) != 0
    assert main([*args, "--sample", str(m), "-o", str(tmp_path / "x.csv")]) != 0
    assert not (tmp_path / "x.csv").exists()


def test_diagnose_puts_held_out_beside_in_sample(tmp_path, table):
    m = tmp_path / "M.csv"
    table.to_csv(m, index=False)
    opts = ["--law-statics", "constant", "--law-shifts", "wlf", "--law-verticals", "off", "--law-refines", "off",
            "--law-per-decades", "2"]
    for scheme in ("lofo", "loto"):
        assert main(["crossval", "--measured", str(m), "--scheme", scheme, *opts,
                     "-o", str(tmp_path / f"{scheme}.csv")]) == 0
    out = {k: tmp_path / k for k in ("r.json", "gain.csv", "page.md")}
    chain = cli_chain(m, tmp_path / "chain", opts)
    assert main(["diagnose", *chain["args"], "--crossval", str(tmp_path / "lofo.csv"),
                 str(tmp_path / "loto.csv"), "-o", str(out["r.json"]), "--gain-csv", str(out["gain.csv"]),
                 "--page", str(out["page.md"])]) == 0
    gain = pd.read_csv(out["gain.csv"]).set_index("temperature_C")
    rows = pd.read_csv(tmp_path / "lofo.csv")
    held = rows[(rows["kind"] == "held_out") & (rows["model"] == "extended_law")]
    ref = 100 * held.groupby("temperature_C")["rel_err_E_norm"].mean()
    np.testing.assert_allclose(gain.loc[ref.index, "E_norm_mre_after_heldout_lofo_pct"], ref, rtol=1e-9)
    assert (gain["heldout_after_model"] == "extended_law").all()
    assert gain["E_norm_mre_before_heldout_lofo_pct"].notna().all()  # Burger's per isotherm
    assert gain["E_norm_mre_before_heldout_loto_pct"].isna().all()  # not defined for Burger's
    assert gain["loto_extrapolation"].to_dict()[-10.0] and not gain["loto_extrapolation"].to_dict()[21.0]
    page = out["page.md"].read_text()
    assert "## Held-out errors (headline" in page and page.index("Held-out") < page.index("in-sample)")
    rep = json.loads(out["r.json"].read_text())
    assert {h["scheme"] for h in rep["heldout"]["headline"]} == {"lofo", "loto"}


def test_held_out_predictions_carry_the_folds_artifacts():
    """A planted time lag (Phi + 360 f dt): each fold corrects it on its training rows, fits
    the law to the corrected means, and predicts the measured held-out cells through its own
    measurement model (law / R): the held-out phase error stays at the noise level, while the
    bare law (the corrected material) is off by the lag."""
    t, truth = synthetic.generate(4, ["time_lag"], schedule="paper_2pb", n_specimens=3)
    dt = truth["effects"]["time_lag"]["time_lag_ms"] * 1e-3
    res = cv.crossval(t, "lofo", cv.Options())
    held = res.rows[(res.rows["kind"] == "held_out") & (res.rows["model"] == "extended_law")]
    assert held["rel_err_phase"].mean() < 0.03
    fit = res.fold_fits["40"]
    assert fit.artifacts == ["time_lag"]
    cell = held[held["fold"] == "40"].iloc[0]
    bare = np.degrees(np.angle(fit.law.law_at(cell["temperature_C"]).complex_modulus(2 * np.pi * 40.0)))
    assert cell["phase_deg_predicted"] - bare == pytest.approx(360 * 40.0 * dt, rel=0.2)


@pytest.mark.parametrize("seed", [5, 17])
def test_measurement_model_applies_the_training_correction_with_vertical_shifts(seed):
    """A held-out row gets exactly the correction the training rows got: on a table with a
    planted time lag and planted vertical shifts (|E*| x exp(v_T), v up to +-0.15 per
    isotherm), the measurement model of the artifact search evaluated at the training rows
    reproduces the corrected table's |E*| and Phi row by row. (Before the fix the model also
    cleared the fitted vertical shifts, a factor exp(-v_T) the training table never had.)"""
    t, _ = synthetic.generate(seed, ["time_lag"], schedule="aashto_t342", n_specimens=3)
    temps = np.sort(t["temperature_C"].unique())
    v = dict(zip(temps, np.linspace(-0.15, 0.15, temps.size)))
    t = t.copy()
    t["E_norm_MPa"] *= np.exp(t["temperature_C"].map(v).to_numpy(float))
    corrected, names, _, model = cv.correct_artifacts(t, cv.Options())
    assert "time_lag" in names and model is not None
    fit = model.fit
    verticals = [fit.param(n) for n in fit.names if n.startswith("ln_vertical_")]
    assert max(abs(x) for x in verticals) > 0.05  # the vertical shifts are really fitted
    R = model.correction(t)
    E = t["E_norm_MPa"].to_numpy(float) * np.exp(1j * np.radians(t["phase_deg"].to_numpy(float)))
    Ec = E * R
    np.testing.assert_allclose(np.abs(Ec), corrected["E_norm_MPa"].to_numpy(float), rtol=1e-10)
    np.testing.assert_allclose(np.degrees(np.angle(Ec)), corrected["phase_deg"].to_numpy(float), atol=1e-9)


def test_noise_floor_and_specimen_bootstrap():
    """The noise floor is the relative standard error of the replicate means (a 4 % specimen
    scatter with 3 specimens gives ~4/sqrt(3) %); the bootstrap interval of an MRE contains the
    point value, collapses to it when the specimens agree, and widens with their scatter."""
    from asphalt_nscd.diagnosis.budget import target_verdict

    rng = np.random.default_rng(1)
    rows_t, pred = [], []
    for T in (0.0, 20.0):
        for f in (1.0, 10.0):
            for s, c in enumerate((0.96, 1.0, 1.04)):
                rows_t.append({"specimen": f"S{s}", "temperature_C": T, "frequency_Hz": f,
                               "E_norm_MPa": 1000.0 * c, "phase_deg": 20.0 * c})
            pred.append({"scheme": "lofo", "fold": f"{f:g}", "kind": "held_out", "model": "m", "temperature_C": T,
                         "frequency_Hz": f, "E_norm_MPa_predicted": 1050.0, "phase_deg_predicted": 21.0,
                         "computable": True})
    table = pd.DataFrame(rows_t)
    floor = cv.noise_floor(table).set_index("temperature_C")
    assert floor.loc[0.0, "noise_floor_E_norm_pct"] == pytest.approx(4.0 / np.sqrt(3), rel=1e-9)
    assert floor.loc[0.0, "n_specimens"] == 3
    rows = pd.DataFrame(pred)
    ci = cv.specimen_bootstrap(rows, table, n_boot=500).set_index("temperature_C")
    assert ci.loc[0.0, "mre_E_norm_ci95_low"] < 5.0 < ci.loc[0.0, "mre_E_norm_ci95_high"]
    same = table.assign(E_norm_MPa=1000.0, phase_deg=20.0)
    ci0 = cv.specimen_bootstrap(rows, same, n_boot=200).set_index("temperature_C")
    assert ci0.loc[0.0, "mre_E_norm_ci95_low"] == pytest.approx(5.0) == ci0.loc[0.0, "mre_E_norm_ci95_high"]
    rows["rel_err_E_norm"], rows["rel_err_phase"], rows["n_replicates"] = 0.05, 0.05, 3
    rows["extrapolation"] = False
    summ = cv.summarize(rows, table, n_boot=200)
    assert list(summ.columns) == cv.SUMMARY_COLUMNS and summ["noise_floor_E_norm_pct"].notna().all()
    assert target_verdict(5.0, 4.0, 6.0, 5.5) == "undecided"
    assert target_verdict(5.0, 4.0, 5.2, 5.5) == "met" and target_verdict(6.0, 5.6, 6.4, 5.5) == "missed"
    assert target_verdict(5.0, np.nan, np.nan, 5.5) == "met"
