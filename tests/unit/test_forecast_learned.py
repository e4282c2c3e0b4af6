"""The learned yardstick (asphalt_nscd.forecast.learned): a planted smooth function of the
formulas' inputs is learned on mixes left out; a held-out mix's measured values never reach its
fold, its inner tuning included; the same fold gives the same numbers; the random-row judge holds
every cell out once with its mix's other cells in training; the two judges compared; the model in
the configured set."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.forecast import learned
from asphalt_nscd.forecast.validation import binder_ids, cross_validate, with_binder_route
from asphalt_nscd.io import InputError, json_safe
from asphalt_nscd.lab.matched import read_matched

TABLE = Path(__file__).resolve().parents[2] / "data" / "binder_mix" / "mixes_35.tsv"


@pytest.fixture(scope="module")
def shipped():
    t = read_matched(TABLE)
    return with_binder_route(t, {}, pd.Series(dtype=str), "raw"), binder_ids(t)


def _planted(t: pd.DataFrame) -> pd.DataFrame:
    """The shipped mixes' inputs with |E*| and phase a smooth function of them: the binder's
    stiffness through a sigmoid, the voids and the gradation as small smooth terms."""
    lnG = np.log(t["binder_G_mix_MPa"].to_numpy(float))
    va, p4 = t["Va_pct"].to_numpy(float), t["rho4_pct"].to_numpy(float)
    lnE = np.log(50.0) + np.log(600.0) / (1.0 + np.exp(-0.6 * (lnG + 1.0))) - 0.04 * (va - 6.6) + 0.005 * (p4 - 47)
    phase = 8.0 + 0.35 * t["binder_delta_mix_deg"].to_numpy(float) + 0.3 * (va - 6.6)
    return t.assign(E_norm_MPa=np.exp(lnE), phase_deg=phase)


def test_a_planted_smooth_function_of_the_inputs_is_learned_on_mixes_left_out(shipped):
    t, ids = shipped
    planted = _planted(t)
    held = ["193", "218", "236"]
    rows, _ = cross_validate(planted, [learned.GradientBoosting()], ids, [[m] for m in held], "raw")
    e = 100.0 * np.abs(np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"]))
    d = np.abs(rows["phase_pred_deg"] - rows["phase_meas_deg"])
    spread = 100.0 * np.log(planted["E_norm_MPa"]).std()
    assert e.mean() < 0.05 * spread and e.mean() < 12.0, (e.mean(), spread)
    assert d.mean() < 0.1 * planted["phase_deg"].std() and d.mean() < 1.0, d.mean()


def test_the_held_out_mix_never_reaches_its_fold_nor_its_inner_tuning(shipped):
    """Ten mixes, one held out: its |E*| times 1000 and its phase plus 30 degrees leave its
    forecast (and its fold's tuned hyperparameters) exactly as they were; the same change on a
    training mix moves the forecast (the check can fail)."""
    t, ids = shipped
    mixes = list(dict.fromkeys(t["mix_id"]))[:10]
    t = t[t["mix_id"].isin(mixes)].reset_index(drop=True)
    model = learned.GradientBoosting()
    base, s0 = cross_validate(t, [model], ids, [["204"]], "raw")

    def moved(mix):
        sel = t["mix_id"] == mix
        return t.assign(
            E_norm_MPa=np.where(sel, 1000.0 * t["E_norm_MPa"], t["E_norm_MPa"]),
            phase_deg=np.where(sel, t["phase_deg"] + 30.0, t["phase_deg"]),
        )

    again, s1 = cross_validate(moved("204"), [model], ids, [["204"]], "raw")
    np.testing.assert_array_equal(base["E_pred_MPa"], again["E_pred_MPa"])
    np.testing.assert_array_equal(base["phase_pred_deg"], again["phase_pred_deg"])
    assert dict(s0[0]["state"]) == dict(s1[0]["state"])
    other, _ = cross_validate(moved(mixes[0]), [model], ids, [["204"]], "raw")
    assert not np.allclose(base["E_pred_MPa"], other["E_pred_MPa"])


def test_a_fold_is_reproducible_and_its_state_is_written_without_its_trees(shipped):
    t, _ = shipped
    train = t[t["mix_id"].isin(list(dict.fromkeys(t["mix_id"]))[:8])]
    a, b = learned.GradientBoosting().fit(train), learned.GradientBoosting().fit(train)
    test = t[t["mix_id"] == "243"]
    for x, y in zip(learned.GradientBoosting().predict(a, test)[:2], learned.GradientBoosting().predict(b, test)[:2]):
        np.testing.assert_array_equal(x, y)
    plain = json_safe(a)
    assert type(plain) is dict and plain == dict(a) and plain["n_mixes"] == 8
    assert {"logE_learning_rate", "logE_max_iter", "phase_max_leaf_nodes", "phase_inner_score"} <= set(plain)
    for target in learned.TARGETS:
        assert plain[f"{target}_max_iter"] in learned.GRID["max_iter"]
    E, P, source = learned.GradientBoosting().predict(a, test.assign(Va_pct=np.nan))
    assert np.isnan(E).all() and np.isnan(P).all() and source == "model"


def test_by_rows_holds_each_cell_out_once_with_its_mix_in_training(shipped):
    t, _ = shipped
    t = t[t["mix_id"].isin(list(dict.fromkeys(t["mix_id"]))[:6])].reset_index(drop=True)
    grid = {"learning_rate": (0.2,), "max_leaf_nodes": (3,), "min_samples_leaf": (20,), "max_iter": (25,)}
    rows = learned.by_rows(t, learned.GradientBoosting(grid=grid, inner="rows"), "raw", k=6, seed=3)
    assert len(rows) == len(t) and rows["fold"].nunique() == 6
    keys = rows[["mix_id", "temperature_C", "frequency_Hz"]].astype(str).agg("|".join, axis=1)
    assert keys.is_unique
    assert (rows.groupby("fold")["mix_id"].nunique() > 1).all()  # a fold's cells come from several mixes
    assert np.isfinite(rows[["E_pred_MPa", "phase_pred_deg"]].to_numpy(float)).all()
    with pytest.raises(InputError, match="by-row folds"):
        learned.by_rows(t, learned.GradientBoosting(grid=grid), "raw", k=1)


def test_the_two_judges_compared_per_mix():
    """compare: each judge's mean over mixes of per-mix mean |error|, and the geometric-mean
    ratio of the per-mix errors (by hand on two mixes)."""

    def rows(errors):
        out = []
        for mix, (e, p) in errors.items():
            out.append(
                pd.DataFrame(
                    {
                        "mix_id": mix,
                        "model": "gradient_boosting",
                        "binder_route": "curve",
                        "temperature_C": [-10.0, 21.1],
                        "E_meas_MPa": 100.0,
                        "E_pred_MPa": 100.0 * np.exp(np.array(e) / 100.0),
                        "phase_meas_deg": 20.0,
                        "phase_pred_deg": 20.0 + np.array(p),
                    }
                )
            )
        return pd.concat(out, ignore_index=True)

    by_mix = rows({"a": ([40.0, -20.0], [2.0, 4.0]), "b": ([10.0, 10.0], [1.0, -1.0])})
    by_row = rows({"a": ([10.0, 5.0], [1.0, 1.0]), "b": ([5.0, -5.0], [0.5, 0.5])})
    c = learned.compare(by_mix, by_row).set_index(["quantity", "temperature_C"], drop=False)
    overall = c[c["temperature_C"].isna()].set_index("quantity")
    np.testing.assert_allclose(overall.loc["logE", "by_mix"], (30.0 + 10.0) / 2)
    np.testing.assert_allclose(overall.loc["logE", "by_rows"], (7.5 + 5.0) / 2)
    np.testing.assert_allclose(overall.loc["logE", "ratio"], np.sqrt(4.0 * 2.0))
    np.testing.assert_allclose(overall.loc["phase", "ratio"], np.sqrt(3.0 * 2.0))
    assert list(c.columns) == learned.COMPARE_COLUMNS and len(c) == 2 * 3
    assert (overall["ratio_ci_low"] <= overall["ratio"]).all()


def test_the_learned_model_is_in_the_configured_set_and_the_schema_names_it():
    from asphalt_nscd import config
    from asphalt_nscd.forecast.models import label, model_set

    cfg = config.checked([])["forecast"]
    assert cfg["learned"] == ["gradient_boosting"]
    assert "gradient_boosting_learned" in [label(m) for m in model_set(cfg, None)]
    assert "gradient_boosting_learned" not in [label(m) for m in model_set(cfg | {"learned": []}, None)]
    with pytest.raises(InputError):
        learned.GradientBoosting(inner="mixes")
    with pytest.raises(InputError, match="grid"):
        learned.GradientBoosting(grid={"learning_rate": (0.1,)})


def test_the_schema_refuses_an_unknown_learned_model(tmp_path):
    from asphalt_nscd import config

    overlay = tmp_path / "o.yaml"
    overlay.write_text("forecast:\n  learned: [neural_net]\n")
    with pytest.raises(InputError, match="learned"):
        config.checked([str(Path(__file__).resolve().parents[2] / "config" / "config.yaml"), str(overlay)])


def test_features_need_their_columns():
    with pytest.raises(InputError, match="binder_G_mix_MPa"):
        learned.features(pd.DataFrame({"temperature_C": [1.0]}))


def test_the_configured_grid_is_the_one_tuned_and_the_schema_checks_it(shipped, tmp_path):
    """``forecast.learned_grid`` reaches the model (its fold's choice lies in that grid, not in the
    module's); null is the module's GRID; a grid missing a key or with an empty list is refused naming
    the key."""
    from asphalt_nscd import config
    from asphalt_nscd.forecast.models import model_set

    base = config.checked([])["forecast"]
    assert base["learned_grid"] is None
    (default,) = [m for m in model_set(base, None) if isinstance(m, learned.GradientBoosting)]
    assert default.grid == learned.GRID
    grid = {"learning_rate": [0.05], "max_leaf_nodes": [4], "min_samples_leaf": [7], "max_iter": [30, 60]}
    (model,) = [m for m in model_set(base | {"learned_grid": grid}, None) if isinstance(m, learned.GradientBoosting)]
    t, _ = shipped
    state = model.fit(t[t["mix_id"].isin(list(dict.fromkeys(t["mix_id"]))[:6])])
    for target in learned.TARGETS:
        assert state[f"{target}_learning_rate"] == 0.05 and state[f"{target}_max_leaf_nodes"] == 4
        assert state[f"{target}_min_samples_leaf"] == 7 and state[f"{target}_max_iter"] in (30, 60)
    smoke = config.checked([str(Path(__file__).resolve().parents[2] / "config" / "smoke.yaml")])["forecast"]
    assert set(smoke["learned_grid"]) == set(learned.GRID)
    for bad in ("{learning_rate: [0.1], max_leaf_nodes: [3], min_samples_leaf: [20]}", "{learning_rate: []}"):
        overlay = tmp_path / "o.yaml"
        overlay.write_text(f"forecast:\n  learned_grid: {bad}\n")
        with pytest.raises(InputError, match="learned_grid"):
            config.checked([str(overlay)])
