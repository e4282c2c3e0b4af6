"""Held-out validation (`asphalt-nscd crossval`): folds, no leakage of a held-out cell into its
fold's fit (nested selection and artifact correction included), not-computable folds, scores
against an independent computation, the NSCD-sample model and the CLI."""

import json

import numpy as np
import pandas as pd
import pytest
from diagnosis_chain import cli_chain

from asphalt_nscd.cli import main
from scipy import stats

from asphalt_nscd.diagnosis import crossval as cv
from asphalt_nscd.diagnosis import scores, synthetic
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


@pytest.mark.parametrize(
    "scheme, column, value, other", [("lofo", "frequency_Hz", 1.0, "10"), ("loto", "temperature_C", 21.0, "37")]
)
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
    """The summary's scores per temperature = an independent computation: the paper's MRE from
    the replicate means of the table as given (| |E|p/|E|m - 1 |, | Phi_p - Phi_m | / Phi_m), the
    signed log error of |E*| against the mean of the specimens' ln|E*| and its t(n-1) interval
    over the specimens; interpolated and extrapolated cells (the end frequencies) apart."""
    means = table.groupby(["temperature_C", "frequency_Hz"])[["E_norm_MPa", "phase_deg"]].mean().reset_index()
    held = lofo.rows[(lofo.rows["kind"] == "held_out") & (lofo.rows["model"] == "extended_law")]
    m = held.merge(means, on=["temperature_C", "frequency_Hz"])
    eE = (m["E_norm_MPa_predicted"] / m["E_norm_MPa"] - 1).abs()
    eP = (m["phase_deg_predicted"] - m["phase_deg"]).abs() / m["phase_deg"]
    ref = (
        pd.DataFrame({"T": m["temperature_C"], "x": m["extrapolation"], "E": 100 * eE, "P": 100 * eP})
        .groupby(["T", "x"])
        .mean()
    )
    s = scores.summarize(lofo.rows, table)
    s = s[(s["kind"] == "held_out") & (s["model"] == "extended_law") & s["temperature_C"].notna()]
    s = s.set_index(["temperature_C", "extrapolation"])
    np.testing.assert_allclose(s.loc[ref.index, "mre_E_norm_pct"], ref["E"], rtol=1e-12)
    np.testing.assert_allclose(s.loc[ref.index, "mre_phase_pct"], ref["P"], rtol=1e-12)
    # signed log error and its t interval at one temperature, computed by hand
    T = 21.0
    h = held[(held["temperature_C"] == T) & ~held["extrapolation"]]
    spec = table[table["temperature_C"] == T]
    lnE = spec.assign(l=np.log(spec["E_norm_MPa"])).pivot_table(index="specimen", columns="frequency_Hz", values="l")
    pred = np.log(h.set_index("frequency_Hz")["E_norm_MPa_predicted"])
    d = pred - lnE[pred.index].mean(axis=0)
    b = (pred - lnE[pred.index]).mean(axis=1)
    half = stats.t.ppf(0.975, b.size - 1) * b.std(ddof=1) / np.sqrt(b.size)
    row = s.loc[(T, False)]
    assert row["bias_logE_pct"] == pytest.approx(100 * d.mean(), rel=1e-10)
    assert row["bias_logE_ci95_low"] == pytest.approx(100 * (b.mean() - half), rel=1e-10)
    assert row["abs_logE_ci95_low"] < row["abs_logE_ci95_high"]
    assert row["abs_logE_pct"] == row["abs_logE_vs_means_pct"] == pytest.approx(100 * d.abs().mean(), rel=1e-10)
    head = scores.headline(scores.summarize(lofo.rows, table))
    hd = head[(head["kind"] == "held_out") & (head["model"] == "extended_law")].iloc[0]
    inner = held[~held["extrapolation"]]
    assert hd["interp_n_cells"] == len(inner) and hd["extrap_n_cells"] == len(held) - len(inner)
    assert hd["worst_T_C"] in set(table["temperature_C"])
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
    assert lofo.rows.loc[(lofo.rows["kind"] == "held_out") & (lofo.rows["model"] == "extended_law"), "computable"].all()
    # five temperatures: the end ones are extrapolations, pooled apart from the inner ones
    five = cv.crossval(table, "loto", cv.Options())
    s = scores.summarize(five.rows, table)
    s = s[(s["kind"] == "held_out") & (s["model"] == "extended_law")]
    per_T = s[s["temperature_C"].notna()].set_index("temperature_C")["extrapolation"].to_dict()
    assert per_T == {-10.0: True, 4.0: False, 21.0: False, 37.0: False, 54.0: True}
    h = scores.headline(s).iloc[0]
    assert h["worst_T_C"] in (4.0, 21.0, 37.0) and h["interp_n_cells"] == 18 and h["extrap_n_cells"] == 12
    assert (
        five.rows.loc[(five.rows["model"] == "burgers") & (five.rows["kind"] == "held_out"), "reason"]
        .str.contains("no temperature dependence")
        .all()
    )


def test_loso_scores_each_specimen_against_itself_and_never_sees_it(table):
    """Leave one specimen out: every fold trains on the other specimens and is scored against the
    held-out specimen's own values; changing that specimen's values changes its reference, not its
    fold's prediction, while the in-sample fit moves."""
    res = cv.crossval(table, "loso", cv.Options())
    held = res.rows[(res.rows["kind"] == "held_out") & (res.rows["model"] == "extended_law")]
    assert set(held["fold"]) == set(table["specimen"]) and held["computable"].all()
    for spec, g in held.groupby("fold"):
        own = table[table["specimen"] == spec].set_index(["temperature_C", "frequency_Hz"])["E_norm_MPa"]
        np.testing.assert_allclose(
            g.set_index(["temperature_C", "frequency_Hz"])["E_norm_MPa_measured"],
            own.loc[g.set_index(["temperature_C", "frequency_Hz"]).index],
            rtol=1e-12,
        )
    bad = table.copy()
    hit = bad["specimen"] == "S1"
    bad.loc[hit, "E_norm_MPa"] *= 3.0
    moved = cv.crossval(bad, "loso", cv.Options())
    a, b = _held(res.rows, "S1"), _held(moved.rows, "S1")
    np.testing.assert_array_equal(a["E_norm_MPa_predicted"], b["E_norm_MPa_predicted"])
    assert np.allclose(b["E_norm_MPa_measured"], 3.0 * a["E_norm_MPa_measured"])
    s = scores.summarize(res.rows, table)
    pooled = s[
        (s["scheme"] == "loso") & (s["kind"] == "held_out") & (s["model"] == "extended_law") & s["temperature_C"].isna()
    ].iloc[0]
    assert pooled["n_specimens"] == table["specimen"].nunique() and "a new specimen" in pooled["interval"]
    assert pooled["abs_logE_ci95_low"] <= pooled["abs_logE_pct"] <= pooled["abs_logE_ci95_high"]


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
    args = [
        "crossval",
        "--measured",
        str(m),
        "--scheme",
        "lofo",
        "--law-statics",
        "constant",
        "--law-shifts",
        "wlf",
        "--law-verticals",
        "off",
        "--law-refines",
        "off",
        "--law-per-decades",
        "2",
    ]
    assert (
        main(
            [
                *args,
                "--time-domain",
                str(td),
                "-o",
                str(out["cv.csv"]),
                "--summary",
                str(out["s.csv"]),
                "--curve",
                str(out["c.csv"]),
                "--figure",
                str(out["f.png"]),
            ]
        )
        == 0
    )
    rows = pd.read_csv(out["cv.csv"])
    t = rows[rows["model"] == "nscd_time_domain"]
    assert len(t) == 1 and str(t["fold"].iloc[0]) == "10" and t["rel_err_E_norm"].iloc[0] == pytest.approx(0, abs=1e-12)
    assert out["f.png"].stat().st_size > 0 and len(pd.read_csv(out["s.csv"])) > 0
    # a time-domain row at a cell that is not measured, or --sample without --transfer: clear errors
    pd.DataFrame({"temperature_C": [22.0], "frequency_Hz": [10.0], "E_norm_MPa": [1.0], "phase_deg": [10.0]}).to_csv(
        td, index=False
    )
    assert main([*args, "--time-domain", str(td), "-o", str(tmp_path / "x.csv")]) != 0
    assert main([*args, "--sample", str(m), "-o", str(tmp_path / "x.csv")]) != 0
    assert not (tmp_path / "x.csv").exists()


def test_diagnose_puts_held_out_beside_in_sample(tmp_path, table):
    m = tmp_path / "M.csv"
    table.to_csv(m, index=False)
    opts = [
        "--law-statics",
        "constant",
        "--law-shifts",
        "wlf",
        "--law-verticals",
        "off",
        "--law-refines",
        "off",
        "--law-per-decades",
        "2",
    ]
    for scheme in ("lofo", "loto"):
        assert (
            main(["crossval", "--measured", str(m), "--scheme", scheme, *opts, "-o", str(tmp_path / f"{scheme}.csv")])
            == 0
        )
    out = {k: tmp_path / k for k in ("r.json", "gain.csv", "page.md")}
    chain = cli_chain(m, tmp_path / "chain", opts)
    assert (
        main(
            [
                "diagnose",
                *chain["args"],
                "--crossval",
                str(tmp_path / "lofo.csv"),
                str(tmp_path / "loto.csv"),
                "-o",
                str(out["r.json"]),
                "--gain-csv",
                str(out["gain.csv"]),
                "--page",
                str(out["page.md"]),
            ]
        )
        == 0
    )
    gain = pd.read_csv(out["gain.csv"]).set_index("temperature_C")
    rows = pd.read_csv(tmp_path / "lofo.csv")
    s = scores.summarize(rows, table)
    inner = s[
        (s["kind"] == "held_out") & (s["model"] == "extended_law") & ~s["extrapolation"] & s["temperature_C"].notna()
    ].set_index("temperature_C")
    np.testing.assert_allclose(
        gain.loc[inner.index, "abs_logE_pct_after_heldout_lofo"], inner["abs_logE_pct"], rtol=1e-9
    )
    assert (gain["heldout_after_model"] == "extended_law").all()
    assert gain["abs_logE_pct_before_heldout_lofo"].notna().all()  # Burger's per isotherm
    assert gain["abs_logE_pct_before_heldout_loto"].isna().all()  # not defined for Burger's
    ext = gain["heldout_extrapolation_loto"].to_dict()
    assert ext[-10.0] and not ext[21.0]
    page = out["page.md"].read_text()
    assert "## Held-out errors" in page and page.index("Held-out") < page.index("in-sample)")
    rep = json.loads(out["r.json"].read_text())
    assert {h["scheme"] for h in rep["heldout"]["headline"]} == {"lofo", "loto"}
    heads = [h for h in rep["heldout"]["headline"] if h["kind"] == "held_out"]
    assert all(h["verdict_E_norm"] in ("met", "missed", "undecided") for h in heads)
    # one set of targets on the page, on the held-out errors
    assert page.count("Targets:") == 1 and "targets met" not in page


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


def test_noise_floor_and_intervals_over_specimens():
    """The noise floor is the relative standard error of the replicate means (a 4 % specimen
    scatter with 3 specimens gives ~4/sqrt(3) %); the signed interval is t(n-1) over the
    specimens; the absolute error is the observed one against the lab's means, and the interval
    of the error against the mix collapses to it when the specimens agree and widens with their
    scatter (here a pure specimen level: 2 degrees of freedom, the others none); a t interval's
    coverage is its level."""
    from asphalt_nscd.diagnosis.budget import target_verdict

    rows_t, pred = [], []
    for T in (0.0, 20.0):
        for f in (1.0, 10.0):
            for s, c in enumerate((0.96, 1.0, 1.04)):
                rows_t.append(
                    {
                        "specimen": f"S{s}",
                        "temperature_C": T,
                        "frequency_Hz": f,
                        "E_norm_MPa": 1000.0 * c,
                        "phase_deg": 20.0 * c,
                    }
                )
            pred.append(
                {
                    "scheme": "lofo",
                    "fold": f"{f:g}",
                    "kind": "held_out",
                    "model": "m",
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa_predicted": 1050.0,
                    "phase_deg_predicted": 21.0,
                    "E_norm_MPa_measured": 1000.0,
                    "phase_deg_measured": 20.0,
                    "rel_err_E_norm": 0.05,
                    "rel_err_phase": 0.05,
                    "extrapolation": False,
                    "computable": True,
                }
            )
    table = pd.DataFrame(rows_t)
    floor = scores.noise_floor(table).set_index("temperature_C")
    assert floor.loc[0.0, "noise_floor_E_norm_pct"] == pytest.approx(4.0 / np.sqrt(3), rel=1e-9)
    assert floor.loc[0.0, "n_specimens"] == 3
    rows = pd.DataFrame(pred)
    summ = scores.summarize(rows, table)
    assert list(summ.columns) == scores.SUMMARY_COLUMNS
    r = summ[summ["temperature_C"] == 0.0].iloc[0]
    lnE = np.log(1000.0 * np.array([0.96, 1.0, 1.04]))
    b = np.log(1050.0) - lnE
    half = stats.t.ppf(0.975, 2) * b.std(ddof=1) / np.sqrt(3)
    assert r["bias_logE_pct"] == pytest.approx(100 * b.mean())
    assert r["bias_logE_ci95_low"] == pytest.approx(100 * (b.mean() - half))
    assert r["abs_logE_pct"] == pytest.approx(100 * abs(np.log(1050.0) - lnE.mean()))
    assert r["abs_logE_ci95_low"] < r["abs_logE_pct"] < r["abs_logE_ci95_high"]
    assert (r["dof_specimen"], r["dof_specimen_temperature"], r["dof_cell"]) == (2, 2, 4)
    same = table.assign(E_norm_MPa=1000.0, phase_deg=20.0)
    r0 = scores.summarize(rows, same)
    r0 = r0[r0["temperature_C"] == 0.0].iloc[0]
    assert r0["abs_logE_ci95_low"] == pytest.approx(100 * np.log(1.05)) == r0["abs_logE_ci95_high"]
    assert r["abs_logE_ci95_high"] - r["abs_logE_ci95_low"] > 1.0
    # the t interval covers the mean at its level (normal samples of 3)
    rng = np.random.default_rng(0)
    cover = [lo <= 0.0 <= hi for lo, hi in (scores.t_interval(rng.normal(0, 1, 3)) for _ in range(4000))]
    assert abs(np.mean(cover) - 0.95) < 0.015
    assert target_verdict(5.0, 4.0, 6.0, 5.5) == "undecided"
    assert target_verdict(5.0, 4.0, 5.2, 5.5) == "met" and target_verdict(6.0, 5.6, 6.4, 5.5) == "missed"
    assert target_verdict(5.0, np.nan, np.nan, 5.5) == "met"


def test_nested_components_recover_the_three_levels_with_their_degrees_of_freedom():
    """Specimens' values planted with a specimen level (sd 3), a specimen-isotherm level (sd 4)
    and cell scatter (sd 1): the mean squares have their expected values n_T n_f s_u^2 + n_f s_v^2
    + s_e^2, n_f s_v^2 + s_e^2 and s_e^2 (averaged over tables), with the balanced design's
    degrees of freedom; the draws of the lab's cell means less the mix's have the variance
    (s_u^2 + s_v^2 + s_e^2) / n at a cell and a t(n - 1) level."""
    n, n_T, n_f = 3, 5, 6
    su, sv, se = 3.0, 4.0, 1.0
    rng = np.random.default_rng(3)
    ms = []
    for _ in range(300):
        rows = []
        u = rng.normal(0, su, n)
        v = rng.normal(0, sv, (n, n_T))
        for s in range(n):
            for T in range(n_T):
                for f in range(n_f):
                    rows.append((f"S{s}", float(T), float(f), T + f + u[s] + v[s, T] + rng.normal(0, se)))
        spec = pd.DataFrame(rows, columns=["specimen", "T", "f", "lnE"]).assign(phase=0.0)
        comp = scores.nested_components(spec.set_index(["specimen", "T", "f"]))
        ms.append([comp["lnE"]["ms"][k] for k in ("specimen", "specimen_temperature", "cell")])
    assert comp["lnE"]["dof"] == {"specimen": 2, "specimen_temperature": 8, "cell": 50}
    expected = [n_T * n_f * su**2 + n_f * sv**2 + se**2, n_f * sv**2 + se**2, se**2]
    np.testing.assert_allclose(np.mean(ms, axis=0), expected, rtol=0.12)
    comp["lnE"]["ms"] = dict(zip(("specimen", "specimen_temperature", "cell"), expected))
    comp["lnE"]["dof"] = {"specimen": 10**6, "specimen_temperature": 10**6, "cell": 10**6}
    w = scores.population_draws(comp, "lnE", n_sim=20000)
    assert w.shape == (20000, n_T * n_f)
    assert np.var(w[:, 7]) == pytest.approx((su**2 + sv**2 + se**2) / n, rel=0.05)
    comp["lnE"]["dof"]["specimen"] = 2
    level = scores.population_draws(comp, "lnE", n_sim=20000).mean(axis=1)
    half = stats.t.ppf(0.975, 2) * np.sqrt(expected[0] / (n * n_T * n_f))
    assert np.mean(np.abs(level) < half) == pytest.approx(0.95, abs=0.01)


def test_held_out_rows_get_the_drift_correction_they_get_inside_the_whole_table():
    """A temperature drift fitted on a lofo fold's training rows and evaluated at the held-out
    rows alone (one frequency) corrects each of them exactly as it corrects that row inside the
    whole table: the drift is centred on the middle of the isotherm's tests in the whole table,
    a centre that travels with the rows (it was the middle of the steps of the rows given, so a
    held-out frequency alone was corrected about itself)."""
    from asphalt_nscd.diagnosis.effects import ArtifactSearch, prepare_table

    t, _ = synthetic.generate(
        8,
        ["temperature_drift"],
        schedule="aashto_t342",
        n_specimens=3,
        magnitudes={"temperature_drift": {"drift_C_per_test": 1.2}},
    )
    whole = prepare_table(t)
    for f in (25.0, 1.0):
        held = whole[whole["frequency_Hz"] == f]
        search = ArtifactSearch(whole[whole["frequency_Hz"] != f])
        drift = next(c for c in search.all_candidates() if c.name == "temperature_drift")
        model = cv.MeasurementModel(search.fit([drift.term]))
        alone, inside = model.correction(held), model.correction(whole)[held.index.to_numpy()]
        np.testing.assert_allclose(alone, inside, rtol=1e-12)
        assert np.max(np.abs(np.log(np.abs(alone)))) > 0.01  # a real correction, not 1


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_card_law_weighs_every_cell(seed):
    """The law a material card carries is fitted by least squares at every cell: on a table
    with one cell 25 % too stiff (the hottest isotherm's highest frequency, as a lab's outlying
    cell), it misses that cell by less than the robust fit of the same settings does, and the
    default card law has the card's WLF shift; with the robust loss and the law's own shift it is
    the selected law itself."""
    from asphalt_nscd.rheology.extended import LawSettings
    from asphalt_nscd.rheology.metrics import cell_means

    table, _ = synthetic.generate(seed, schedule="aashto_t342", n_specimens=3, test_order=False)
    hot = (table["temperature_C"] == table["temperature_C"].max()) & (
        table["frequency_Hz"] == table["frequency_Hz"].max()
    )
    table.loc[hot, "E_norm_MPa"] *= 1.25
    cells = cell_means(table)
    k = int(
        np.flatnonzero(
            (cells["temperature_C"] == table["temperature_C"].max()).to_numpy()
            & (cells["frequency_Hz"] == table["frequency_Hz"].max()).to_numpy()
        )[0]
    )

    def miss(law):
        E = law.complex_modulus(cells["frequency_Hz"].to_numpy(), cells["temperature_C"].to_numpy())
        return 100 * abs(np.log(abs(E[k]) / cells["E_norm_MPa"].iloc[k]))

    arrhenius = (LawSettings(shift="arrhenius", static="constant"),)
    same = cv.fit_extended(table, cv.Options(candidates=arrhenius, artifacts=False, card_shift="law"))
    assert same.card_settings == same.settings and same.card_law is not same.law
    assert same.law.backbone.loss == "robust" and same.card_law.backbone.loss == "least_squares"
    assert miss(same.card_law) < miss(same.law) - 1.0
    default = cv.fit_extended(table, cv.Options(candidates=arrhenius, artifacts=False))
    assert default.card_settings == LawSettings(shift="wlf", static="constant")
    assert miss(default.card_law) < miss(default.law) - 1.0
    robust = cv.fit_extended(
        table, cv.Options(candidates=arrhenius, artifacts=False, card_fit="robust", card_shift="law")
    )
    assert robust.card_law is robust.law


def test_the_levels_a_fold_did_not_see_are_drawn_given_its_errors():
    """Held-out errors d = g - x contain the levels x of the lab's scatter that the fold's law
    did not see: drawn given d, a cell scatter that explains all of d (a perfect law, g = 0; d
    centred within each isotherm, as the cell level is drawn) leaves an error against the mix
    near 0, where drawn independently it would double; without any scatter the draws are d itself."""
    cells = pd.DataFrame({"T": np.repeat([0.0, 20.0], 4), "f": np.tile([1.0, 2.0, 5.0, 10.0], 2), "n": 3})
    comp = {"cells": cells, "n_f": {0.0: 4, 20.0: 4}, "n_specimens": 3}
    d = np.array([0.02, -0.03, 0.01, 0.0, 0.03, -0.01, 0.0, -0.02])
    comp["lnE"] = {
        "ms": {"specimen": 0.0, "specimen_temperature": 0.0, "cell": 3 * float(np.mean(d**2))},
        "dof": {"specimen": 2, "specimen_temperature": 2, "cell": 10**6},
    }
    parts = scores.population_parts(comp, "lnE", n_sim=4000)
    parts["T"] = cells["T"].to_numpy(float)
    cols = np.arange(8)
    given = np.mean(np.abs(scores.error_draws(d, parts, cols, "lofo")), axis=1)
    independent = np.mean(np.abs(scores.error_draws(d, parts, cols, "")), axis=1)
    assert np.median(given) < 0.2 * np.mean(np.abs(d)) < np.mean(np.abs(d)) < np.median(independent)
    comp["lnE"]["ms"] = {k: 0.0 for k in comp["lnE"]["ms"]}
    parts = scores.population_parts(comp, "lnE", n_sim=200)
    parts["T"] = cells["T"].to_numpy(float)
    for scheme in ("lofo", "loto", ""):
        np.testing.assert_allclose(scores.error_draws(d, parts, cols, scheme), np.tile(d, (200, 1)), atol=1e-15)


def test_an_isotherms_own_deviation_does_not_lower_its_share_of_the_lab_level():
    """Three held-out isotherms, the law exact (g = 0) and the lab's level at one of them far
    (x = -0.08 in ln|E*|, 2.7 times its standard deviation 0.03; the others 0.005): drawn given the
    errors with the law's error variance estimated from the *other* isotherms, that isotherm's
    error against the mix is mostly attributed to the lab's level (a fraction of |dbar| left);
    with the moment of every isotherm, its own deviation inflates it and more than half stays.
    With one isotherm both are the same draw."""
    T = np.repeat([4.0, 21.0, 37.0], 3)
    d = np.repeat([0.08, 0.005, -0.005], 3)
    var = np.full((4000, T.size), 0.03**2)
    logo = scores._given(d, T, var, np.random.default_rng(1), own=False)
    pooled = scores._given(d, T, var, np.random.default_rng(1), own=True)
    far = T == 4.0
    left_logo = np.median(np.abs(d[far][0] + logo[:, far][:, 0]))
    left_pooled = np.median(np.abs(d[far][0] + pooled[:, far][:, 0]))
    assert left_logo < 0.25 * 0.08 and left_pooled > 0.5 * 0.08
    one = T == 21.0
    np.testing.assert_allclose(
        scores._given(d[one], T[one], var[:, one], np.random.default_rng(2), own=False),
        scores._given(d[one], T[one], var[:, one], np.random.default_rng(2), own=True),
    )


def test_the_leave_one_specimen_out_interval_covers_a_new_specimens_error():
    """The interval of a leave-one-specimen-out absolute error (the mean over the folds of the
    expected error of each fold's law against a new specimen of the mix) covers that error in
    about 95 % of tables of 3 specimens drawn from a nested model, whichever level of scatter
    dominates (the specimens' overall level, per isotherm, or their cells'), each fold's law being its training
    specimens' mean plus a smooth departure of its own; it contains the observed error."""
    rng = np.random.default_rng(20261126)
    temps, freqs = [-10.0, 4.0, 21.0, 37.0, 54.0], [0.1, 0.5, 1.0, 5.0, 10.0, 25.0]
    T = np.repeat(temps, len(freqs))
    f = np.tile(freqs, len(temps))
    t_idx = np.searchsorted(temps, T)
    mu = rng.normal(0.0, 1.0, T.size)
    names = np.array(["S1", "S2", "S3"])
    fold = np.repeat(names, T.size)
    for s_u, s_v, s_e in ((0.02, 0.05, 0.016), (0.1, 0.4, 0.3), (0.08, 0.03, 0.016)):
        inside = []
        for _ in range(200):
            y = (
                mu[None, :]
                + rng.normal(0.0, s_u, (3, 1))
                + rng.normal(0.0, s_v, (3, len(temps)))[:, t_idx]
                + rng.normal(0.0, s_e, (3, T.size))
            )
            eps = rng.normal(0.0, 0.3 * s_v, (3, len(temps)))[:, t_idx]  # each fold's smooth departure
            train = np.stack([(y.sum(axis=0) - y[k]) / 2 for k in range(3)])
            pred = train + eps
            truth = np.mean(scores.folded_normal_mean(pred - mu[None, :], s_u**2 + s_v**2 + s_e**2))
            spec = pd.DataFrame({"specimen": fold, "T": np.tile(T, 3), "f": np.tile(f, 3), "lnE": y.ravel()})
            spec["phase"] = spec["lnE"]
            comp = scores.nested_components(spec.set_index(["specimen", "T", "f"]))
            levels = scores.level_variances(comp, "lnE")
            # a coarser calibration than the scores' (LOSO_CALIBRATION, whose coverage reference/crossval measures)
            lo, hi = scores.loso_abs_interval(
                pred.ravel(), y.ravel(), train.ravel(), fold, np.tile(T, 3), levels, n_sim=1000, calibration=(100, 100)
            )
            assert lo <= np.mean(np.abs(pred - y)) <= hi
            inside.append(lo <= truth <= hi)
        assert 0.88 <= np.mean(inside) <= 0.99, ((s_u, s_v, s_e), np.mean(inside))
    with pytest.raises(ValueError, match="not drawn"):  # the calibration takes the levels at their estimates
        scores.loso_abs_interval(
            pred.ravel(), y.ravel(), train.ravel(), fold, np.tile(T, 3), scores.level_variances(comp, "lnE", 10)
        )
    assert scores.folded_normal_mean(np.array([0.3, -0.3]), 0.0).tolist() == [0.3, 0.3]


def test_the_calibrations_levels_are_the_tables_mean_squares():
    """The second bootstrap level of the loso interval estimates each simulated table's levels as
    the table's own are estimated: on a balanced table of specimens the vectorised mean squares
    equal nested_components' through level_variances, several tables at once."""
    rng = np.random.default_rng(7)
    temps, freqs = [-10.0, 4.0, 21.0, 37.0], [0.1, 1.0, 10.0, 25.0, 5.0]
    T = np.repeat(temps, len(freqs))
    f = np.tile(freqs, len(temps))
    ti = np.searchsorted(temps, T)
    x = (
        rng.normal(0.0, 0.1, (6, 3, 1))
        + rng.normal(0.0, 0.05, (6, 3, len(temps)))[:, :, ti]
        + rng.normal(0.0, 0.02, (6, 3, T.size))
    )
    got = scores._balanced_levels(x, ti, len(temps))
    assert got.shape == (6, 3)
    for b in range(6):
        spec = pd.DataFrame(
            {
                "specimen": np.repeat(["A", "B", "C"], T.size),
                "T": np.tile(T, 3),
                "f": np.tile(f, 3),
                "lnE": x[b].ravel(),
            }
        )
        spec["phase"] = spec["lnE"]
        levels = scores.level_variances(scores.nested_components(spec.set_index(["specimen", "T", "f"])), "lnE")
        want = [levels["specimen"], levels["specimen_temperature"], levels["cell"]]
        np.testing.assert_allclose(got[b], want, rtol=1e-10, atol=1e-15)
    # the simulated folds' expected error is the folded normal's mean, which is SciPy's folded normal
    g, var = rng.normal(0.0, 0.1, 7), rng.uniform(1e-4, 0.02, 7)
    want_mean = [stats.foldnorm(abs(a) / np.sqrt(v), scale=np.sqrt(v)).mean() for a, v in zip(g, var)]
    np.testing.assert_allclose(scores.folded_normal_mean(g, var), want_mean, rtol=1e-12)
    z = (rng.normal(size=(5, 3, 1)), rng.normal(size=(5, 3, len(temps)))[:, :, ti], rng.normal(size=(5, 3, T.size)))
    s2 = np.array([0.01, 0.002, 0.0004])
    eps = rng.normal(0.0, 0.05, (3, T.size))
    drawn, expected, sims = scores._loso_ratio(z, s2, eps)
    p = (sims.sum(axis=1, keepdims=True) - sims) / 2 + eps
    np.testing.assert_allclose(drawn, np.mean(np.abs(p - sims), axis=(1, 2)), rtol=1e-12)
    np.testing.assert_allclose(expected, np.mean(scores.folded_normal_mean(p, s2.sum()), axis=(1, 2)), rtol=1e-12)
    assert float(scores.folded_normal_mean(0.0, 1.0)) == pytest.approx(np.sqrt(2 / np.pi))
    # one cell per isotherm leaves no cell level: refused, and the interval falls back (nan, nan)
    one = np.arange(len(temps))
    with pytest.raises(ValueError, match="no isotherm holds two cells"):
        scores._balanced_levels(x[:, :, :: len(freqs)], one, len(temps))
    fold = np.repeat(["A", "B", "C"], len(temps))
    pred = rng.normal(0.0, 0.1, fold.size)
    got_ci = scores.loso_abs_interval(
        pred, pred + 0.1, pred * 0.5, fold, np.tile(temps, 3), dict(zip(scores.LEVELS, s2))
    )
    assert np.isnan(got_ci).all()


def test_the_committed_loso_coverage_is_of_the_shipped_calibration():
    """reference/crossval/loso_evaluation.csv measures the coverage of the calibrated loso interval
    at the scores' calibration sizes: a change of LOSO_CALIBRATION needs that measurement again."""
    from pathlib import Path

    e = pd.read_csv(Path(__file__).resolve().parents[2] / "reference" / "crossval" / "loso_evaluation.csv")
    row = e[e["rule"] == "calibrated"].iloc[0]
    assert (int(row["calibration_tables"]), int(row["calibration_draws"])) == scores.LOSO_CALIBRATION
    assert e.loc[e["rule"] == "calibrated", "replicates"].min() >= 1000
