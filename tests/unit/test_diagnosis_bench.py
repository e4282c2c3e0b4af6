"""diagnose-bench: seeds, plan, binomial intervals, summary and the command."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from asphalt_nscd.cli import main
from asphalt_nscd.diagnosis import bench, synthetic
from asphalt_nscd.io import InputError


def test_exact_binomial_interval():
    lo, hi = bench.binomial_ci(0, 200)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025 ** (1 / 200), rel=1e-9)  # Clopper-Pearson, k = 0
    lo, hi = bench.binomial_ci(200, 200)
    assert hi == 1.0 and lo == pytest.approx(0.025 ** (1 / 200), rel=1e-9)
    lo, hi = bench.binomial_ci(10, 100)
    assert lo < 0.1 < hi and bench.binomial_ci(0, 0) == (None, None)


def test_plan_is_reproducible_and_plants_at_the_stated_size():
    a = bench.plan(5, ["wlf", "mixed"], 3, 2)
    b = bench.plan(5, ["wlf", "mixed"], 3, 2)
    assert a == b and len(a) == 2 * (3 + 2 * 6)
    assert a != bench.plan(6, ["wlf", "mixed"], 3, 2)
    assert len({c["seed"] for c in a}) == len(a)
    for c in a:
        if c["kind"] == "clean":
            assert c["effects"] == [] and c["magnitudes"] == {}
            continue
        size = c["magnitudes"][c["kind"]]
        for k, v in bench.EFFECT_SIZES[c["kind"]].items():
            assert abs(size[k]) == v
        assert c["schedule"] in bench.PLANTED_SCHEDULES.get(c["kind"], tuple(synthetic.SCHEDULES))
        if c["kind"] == "temperature_offset":
            temps = synthetic.SCHEDULES[c["schedule"]][0]
            assert temps[0] < size["temperature_C"] < temps[-1]


def test_summary_counts_false_alarms_on_clean_tables_only():
    runs = [
        {
            "family": "wlf",
            "kind": "clean",
            "detected": ["time_lag"],
            "testable": list(bench.KINDS[1:]),
            "estimate_ok": {},
        },
        {"family": "wlf", "kind": "clean", "detected": [], "testable": list(bench.KINDS[1:]), "estimate_ok": {}},
        {
            "family": "wlf",
            "kind": "time_lag",
            "detected": ["time_lag", "self_heating"],
            "testable": list(bench.KINDS[1:]),
            "estimate_ok": {"time_lag": True},
        },
    ]
    s = bench.summarize(runs, ["wlf"])
    assert s["time_lag"]["wlf"]["false_alarm"]["k"] == 1 and s["time_lag"]["wlf"]["false_alarm"]["n"] == 2
    assert s["time_lag"]["wlf"]["detection"]["rate"] == 1.0
    assert s["self_heating"]["wlf"]["false_alarm"]["k"] == 0
    assert s["self_heating"]["wlf"]["cross_talk"]["k"] == 1
    assert s["time_lag"]["all"]["false_alarm"]["n"] == 2


def test_bench_command_is_reproducible_from_its_base_seed(tmp_path):
    args = ["diagnose-bench", "--clean", "1", "--planted", "1", "--families", "mixed", "--base-seed", "3"]
    assert main(args + ["-o", str(tmp_path / "a.json"), "--table", str(tmp_path / "a.csv")]) == 0
    a = json.loads((tmp_path / "a.json").read_text())
    assert a["base_seed"] == 3 and a["n_tables"] == 7 and a["families"] == ["mixed"]
    table = pd.read_csv(tmp_path / "a.csv")
    assert set(table["artifact"]) == {"any", *bench.KINDS[1:]} and set(table["family"]) == {"mixed", "all"}
    assert {"detection_ci_low", "false_alarm_ci_high", "effect_size"} <= set(table.columns)
    # worker processes (the workflow's --jobs {threads}) give the same table to the byte
    assert main(args + ["--jobs", "2", "-o", str(tmp_path / "j.json"), "--table", str(tmp_path / "j.csv")]) == 0
    assert (tmp_path / "j.csv").read_bytes() == (tmp_path / "a.csv").read_bytes()
    assert (
        main(
            [
                "diagnose-bench",
                "--clean",
                "1",
                "--planted",
                "0",
                "--families",
                "mixed",
                "--base-seed",
                "3",
                "-o",
                str(tmp_path / "b.json"),
            ]
        )
        == 0
    )
    b = json.loads((tmp_path / "b.json").read_text())
    # the clean table of the same seed, the same outcome (all but its measured compute time)
    assert {**b["runs"][0], "cpu_seconds": 0} == {**a["runs"][0], "cpu_seconds": 0}
    # default: a fresh base seed, recorded
    assert (
        main(["diagnose-bench", "--clean", "1", "--planted", "0", "--families", "wlf", "-o", str(tmp_path / "c.json")])
        == 0
    )
    assert isinstance(json.loads((tmp_path / "c.json").read_text())["base_seed"], int)
    assert main(["diagnose-bench", "--families", "bogus", "-o", str(tmp_path / "d.json")]) == 2


def test_configurations_plant_what_their_design_can_test_and_power_cases():
    shipped = bench.plan(5, ["wlf"], 2, 1, configuration="shipped", power=2)
    kinds = {c["kind"] for c in shipped}
    assert kinds == {"clean", "time_lag", "temperature_offset", "power:temperature_offset", "power:time_lag"}
    assert all(c["schedule"] == "aashto_t342" and c["test_order"] is False for c in shipped)
    power = [c for c in shipped if c["kind"] == "power:temperature_offset"]
    assert len(power) == 2 * len(bench.POWER_SIZES["temperature_offset"][1])
    assert sorted({abs(c["magnitudes"]["temperature_offset"]["offset_C"]) for c in power}) == sorted(
        bench.POWER_SIZES["temperature_offset"][1]
    )
    paper = bench.plan(5, ["wlf"], 1, 1, configuration="paper")
    assert {c["kind"] for c in paper} == set(bench.KINDS)
    with pytest.raises(ValueError, match="unknown configuration"):
        bench.plan(5, ["wlf"], 1, 1, configuration="lab")
    # the shipped design: no order, no strain, a uniaxial test of unknown size, 3 specimens
    out = bench.run_case(next(c for c in shipped if c["kind"] == "clean"))
    assert out["n_specimens"] == 3 and set(out["testable"]) <= {"time_lag", "temperature_offset"}


def test_level_for_goal_and_power_curves():
    def clean(fam, p):
        return {"family": fam, "kind": "clean", "min_p": p}

    # 100 clean tables per family, one with min_p 1e-4 in family a: below that level no alarm
    runs = [clean("a", 0.5)] * 99 + [clean("a", 1e-4)] + [clean("b", 0.5)] * 100
    c = bench.level_for_goal(runs, ["a", "b"])
    assert c == 1e-4  # at any larger level family a has one alarm in 100: a 95 % upper bound of 5.4 %
    assert bench.binomial_ci(1, 100)[1] > 0.05 and bench.binomial_ci(0, 100)[1] < 0.05
    runs = [
        {
            "kind": "power:time_lag",
            "power_size": s,
            "detected": ["time_lag"] if s >= 0.2 else [],
            "estimate_ok": {"time_lag": s >= 0.2},
        }
        for s in bench.POWER_SIZES["time_lag"][1]
        for _ in range(4)
    ]
    pc = bench.power_curves(runs)["time_lag"]
    assert [r["detection"]["k"] for r in pc["curve"]] == [0, 0, 4, 4, 4]
    # 4 of 4 is a point estimate of 100 %, its one-sided 95 % lower bound 0.05^(1/4) = 47 %
    assert pc["size_95_point"] == 0.2 and pc["size_95"] is None
    assert pc["curve"][2]["detection_lower_95"] == pytest.approx(0.05**0.25)
    # the power shown needs enough tables: 59 of 59 bound it above 95 %, 58 of 59 do not
    assert bench.lower_bound(59, 59) > 0.95 > bench.lower_bound(58, 59)
    assert bench.power_sizes([{"size": 0.3, "detection": {"k": 59, "n": 59, "rate": 1.0}}])["size_95"] == 0.3
    assert bench.lower_bound(48, 50) == pytest.approx(0.879, abs=1e-3) and bench.lower_bound(0, 5) == 0.0


def test_calibrated_alarms_recount_the_complete_procedure():
    """Only clean tables with a nominal alarm are calibrated (the calibrated level is never
    above the nominal one); a table stays an alarm only below its calibrated level; a run
    whose table the plan does not regenerate is refused."""
    result = bench.run_bench(3, 0, base_seed=11, families=["gmaxwell"], configuration="shipped")
    runs = result["runs"]
    # pretend the first table raised a nominal alarm, at two statistics around its calibrated level
    runs[0]["detected"], runs[0]["min_p"] = ["time_lag"], 1e-30
    runs[1]["detected"], runs[1]["min_p"] = ["temperature_offset"], runs[1]["level"] * 0.999
    bench.calibrate_alarms(result, n_tables=40)
    assert result["calibration_tables"] == 40
    for r in runs[:2]:
        assert 0.0 < r["calibrated_level"] <= r["level"]
        assert r["detected_calibrated"] == (r["min_p"] < r["calibrated_level"])
    assert runs[0]["detected_calibrated"]
    assert "calibrated_level" not in runs[2] and runs[2]["detected_calibrated"] is False
    fw = result["family_wise"]["gmaxwell"]
    assert fw["false_alarm_any_calibrated"]["n"] == 3
    assert fw["false_alarm_any_calibrated"]["k"] == sum(r["detected_calibrated"] for r in runs)
    table = bench.bench_table(result)
    assert "any, calibrated on the table" in set(table["artifact"])
    runs[0]["seed"] += 1
    with pytest.raises(ValueError, match="not in the result's plan"):
        bench.calibrate_alarms(result, n_tables=40)


def test_a_stopped_calibration_resumes_from_its_checkpoint(tmp_path, monkeypatch):
    """Each table's calibration is appended to the checkpoint as it ends; a rerun reads it back
    instead of calibrating again (same decisions), and a table not in it is calibrated."""
    import copy
    import json

    result = bench.run_bench(2, 0, base_seed=11, families=["gmaxwell"], configuration="shipped")
    for r in result["runs"]:
        r["detected"], r["min_p"] = ["time_lag"], 1e-30
    fresh = copy.deepcopy(result)
    ckpt = tmp_path / "calibration.jsonl"
    bench.calibrate_alarms(result, n_tables=40, checkpoint=ckpt)
    lines = [json.loads(x) for x in ckpt.read_text().splitlines()]
    assert [(x["family"], x["index"]) for x in lines] == [("gmaxwell", r["index"]) for r in result["runs"]]
    # the second table's line lost (a run stopped after the first): only that table is calibrated again
    ckpt.write_text(json.dumps(lines[0]) + "\n")
    calls = []
    real = bench._calibrated_level
    monkeypatch.setattr(bench, "_calibrated_level", lambda args: calls.append(args) or real(args))
    bench.calibrate_alarms(fresh, n_tables=40, checkpoint=ckpt)
    assert len(calls) == 1 and calls[0][0]["index"] == result["runs"][1]["index"]
    for a, b in zip(result["runs"], fresh["runs"]):
        assert a["calibrated_level"] == b["calibrated_level"] and a["detected_calibrated"] == b["detected_calibrated"]
    assert len(ckpt.read_text().splitlines()) == 2
    # a run killed while writing leaves its last line cut short: it is dropped and calibrated again
    good = ckpt.read_text()
    ckpt.write_text(good.splitlines()[0] + "\n" + good.splitlines()[1][:25])
    calls.clear()
    again = bench.calibrate_alarms(copy.deepcopy(fresh), n_tables=40, checkpoint=ckpt)

    def untimed(rec):
        return {**rec, "out": {k: v for k, v in rec["out"].items() if k != "cpu_seconds"}}

    rewritten = [untimed(json.loads(x)) for x in ckpt.read_text().splitlines()]
    assert len(calls) == 1 and rewritten == [untimed(x) for x in lines]
    assert [r["calibrated_level"] for r in again["runs"]] == [r["calibrated_level"] for r in result["runs"]]
    # a broken line before the last is not a cut: refused with the file and line named
    ckpt.write_text("not json\n" + good)
    with pytest.raises(InputError, match="line 1 is not a calibration record"):
        bench.calibrate_alarms(copy.deepcopy(fresh), n_tables=40, checkpoint=ckpt)
    # JSON that is not a record (a key missing) is refused the same way, not a KeyError
    ckpt.write_text(good.splitlines()[0] + "\n" + json.dumps({"family": "gmaxwell"}) + "\n")
    with pytest.raises(InputError, match="line 2 is not a calibration record .expected the keys"):
        bench.calibrate_alarms(copy.deepcopy(fresh), n_tables=40, checkpoint=ckpt)
    ckpt.write_text(good)
    # below, only whether a table is calibrated again is asked: the calibration is stood in for by
    # the first table's record (a real one costs seconds)
    monkeypatch.setattr(bench, "_calibrated_level", lambda args: calls.append(args) or dict(lines[0]["out"]))
    # another number of bootstrap tables does not read the checkpoint's calibrations
    calls.clear()
    bench.calibrate_alarms(copy.deepcopy(fresh), n_tables=41, checkpoint=ckpt)
    assert len(calls) == 2
    # nor do lines computed under another rule of the calibrated level
    ckpt.write_text("".join(json.dumps({**json.loads(x), "level_rule": "older"}) + "\n" for x in good.splitlines()))
    calls.clear()
    bench.calibrate_alarms(copy.deepcopy(fresh), n_tables=40, checkpoint=ckpt)
    assert len(calls) == 2


def test_bench_help_names_every_truth_family(capsys):
    with pytest.raises(SystemExit):
        main(["diagnose-bench", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    default = text.split("--families FAMILIES comma-separated")[1].split("--base-seed")[0]
    assert all(f in default for f in synthetic.FAMILIES), default


def test_a_calibration_curtailed_at_the_tables_statistic_decides_as_the_whole_one():
    """Run in turn (one table of each null) and stopped once k = floor(rate (B + 1)) of one null's
    bootstrap tables reach the statistic decided on, a calibration gives the same
    decision as all its tables: at a statistic that many tables reach it stops early with a level
    at most that statistic (no alarm); at one that none reaches it runs every table of both nulls
    and gives the whole calibration's level, the smaller of the nulls'."""
    from asphalt_nscd.diagnosis.calibration import calibrate

    case = next(c for c in bench.plan(11, ["gmaxwell"], 1, 0, configuration="shipped") if c["kind"] == "clean")
    table, _, test = bench.case_table(case)
    full = calibrate(table, test=test, n_tables=40, seed=3, static=False)["artifacts"]
    nulls = full["nulls"]
    assert set(nulls) == {"2s2p1d", "maxwell"} and not full["calibrated_level_bound"]
    assert all(v["n_run"] == 40 for v in nulls.values()) and full["n_run"] == 80
    # the more conservative null binds
    assert full["calibrated_level"] == min(v["calibrated_level"] for v in nulls.values())
    assert full["null_min_p"] == nulls[full["binding_null"]]["null_min_p"]
    m = np.sort(np.concatenate([v["null_min_p"] for v in nulls.values()]))
    high = calibrate(table, test=test, n_tables=40, seed=3, static=False, decide=float(m[-1]))["artifacts"]
    assert high["n_run"] < 80 and high["calibrated_level_bound"]
    assert high["level"] <= m[-1] and not (m[-1] < high["level"])  # no alarm, as with every table
    low = calibrate(table, test=test, n_tables=40, seed=3, static=False, decide=float(m[0]) / 2)["artifacts"]
    assert low["n_run"] == 80 and low["calibrated_level"] == full["calibrated_level"] and low["level"] == full["level"]


def test_planted_tables_are_recounted_at_their_calibrated_level():
    """A planted table of the stated size, calibrated on itself (both nulls), is searched again
    at its calibrated level: what it names then is a subset of what the nominal level named (Holm
    at a lower level), a 0.3 ms time lag (p-value far below any calibrated level) is still named,
    and the recount is tabulated with its one-sided 95 % lower bound; artifacts not asked for
    are not recounted. A false-alarm count carries its one-sided upper bound (0 of 100: 2.95 %)."""
    result = bench.run_bench(0, 1, base_seed=11, families=["wlf"], configuration="shipped")
    bench.calibrate_alarms(result, n_tables=40, planted=1, artifacts=("time_lag",))
    lag = [r for r in result["runs"] if r["kind"] == "time_lag"]
    other = [r for r in result["runs"] if r["kind"] == "temperature_offset"]
    assert len(lag) == 1 and "time_lag" in lag[0]["detected"]
    assert 0.0 < lag[0]["calibrated_level"] <= lag[0]["level"]
    assert set(lag[0]["detected_calibrated"]) <= set(lag[0]["detected"]) and "time_lag" in lag[0]["detected_calibrated"]
    assert all("detected_calibrated" not in r for r in other)
    d = result["detection_calibrated"]["time_lag"]["wlf"]
    assert d["calibrated"]["k"] == d["nominal"]["k"] == 1 and d["calibrated_lower_95"] == pytest.approx(0.05)
    table = bench.bench_table(result)
    row = table[(table["artifact"] == "time_lag, calibrated on the table") & (table["family"] == "wlf")].iloc[0]
    assert row["detected"] == 1 and row["n_planted"] == 1
    assert bench.upper_bound(0, 100) == pytest.approx(1 - 0.05 ** (1 / 100)) and bench.upper_bound(3, 3) == 1.0
    # one-sided at 95 %: between the rate and the two-sided interval's upper end (97.5 % one-sided)
    assert 0.03 < bench.upper_bound(3, 100) < bench.binomial_ci(3, 100)[1] and bench.upper_bound(0, 0) is None
