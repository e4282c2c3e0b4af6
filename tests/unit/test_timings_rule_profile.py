"""The per-rule profile of a workflow run (reference/timings/rule_profile.py) on the workflow's own rule files."""

import reference_scripts
import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
RULES = REPO / "workflow" / "rules"
CONFIG = ["--config", "results/config/c.yaml"]

# argv of real jobs of the default run: a 2PB job and the time-domain check (both run-2pb), the lofo
# fold's law and the extended law (both extend-law, the first's rule written under an `if`), a checkpoint's
# command and a forecast packing (its benchmark path's wildcard spans two path parts)
RUN_2PB = ["run-2pb", "--sample", "results/samples/s2.h5", "--rig-state", "results/campaign/rig/s2.h5", "--sample-name"]
RUN_2PB += ["s2", "--mode", "measured", "--parameters", "p.csv", "--temperature", "54", "--frequency", "25", *CONFIG]
RUN_2PB += ["-o", "results/sim/measured/s2/54C_25Hz.h5", "--row", "results/sim/measured/s2/54C_25Hz.csv"]
TIME_DOMAIN = ["run-2pb", "--sample", "s1.h5", "--sample-name", "s1", "--mode", "crossval", "--law-json", "law.json"]
TIME_DOMAIN += ["--temperature", "21.0", "--frequency", "10.0", "--network-factor-json", "s1.json", *CONFIG]
TIME_DOMAIN += ["--settings-mode", "extended", "--verify", "-o", "td.h5", "--row", "td.csv"]
FOLD_LAW = ["extend-law", "--measured", "m.csv", *CONFIG, "--calibration", "c.json", "--exclude-frequency", "10.0"]
FOLD_LAW += ["--temperatures", "21.0", "-o", "fold_law.json"]
EXTEND_LAW = ["extend-law", "--measured", "m.csv", *CONFIG, "--master-curve", "mc.json", "--corrected-table", "c.csv"]
EXTEND_LAW += ["--calibration", "c.json", "-o", "law.json", "--cv-curve", "cv.csv", "--card-law", "card.json"]
EXTEND_LAW += ["--without-flagged", "wf.json"]
MATCHED = ["matched", "data/binder_mix/mixes_35.tsv", *CONFIG, "-o", "results/forecast/matched.csv"]
PACK = ["forecast-pack", *CONFIG, "--table", "matched.csv", "--mix", "196", "--seed", "1", "--cut-mm", "4.0"]
PACK += ["--size-dmax", "2.5", "-o", "results/forecast/samples/196_s1.npz"]


@pytest.fixture(scope="module")
def rule_profile():
    return reference_scripts.load("reference/timings/rule_profile.py")


def test_every_rule_of_the_workflow_is_read_with_its_command(rule_profile):
    blocks = rule_profile.rule_blocks(RULES)
    written = sum(
        text.count("\n    rule ") + text.count("\nrule ") for text in (p.read_text() for p in RULES.glob("*.smk"))
    )
    assert {"forecast_table", "crossval_fold_law", "crossval_time_domain", "extend_law", "run_2pb"} <= set(blocks)
    assert len(blocks) == written + 1  # the one checkpoint
    commands = rule_profile.rule_commands(rule_profile.rule_blocks(RULES))
    assert commands["forecast_table"][0] == "matched"
    # a rule's options are its own, not those of the rules written after it under an `if`
    assert "--exclude-frequency" not in commands["extend_law"][1]
    assert "--verify" in commands["crossval_time_domain"][1] and "--verify" not in commands["run_2pb"][1]


@pytest.mark.parametrize(
    ("argv", "rule"),
    [
        (RUN_2PB, "run_2pb"),
        (TIME_DOMAIN, "crossval_time_domain"),
        (FOLD_LAW, "crossval_fold_law"),
        (EXTEND_LAW, "extend_law"),
        (MATCHED, "forecast_table"),
        (PACK, "forecast_pack"),
    ],
)
def test_a_process_is_given_to_the_rule_that_ran_it(rule_profile, argv, rule):
    assert rule_profile.rule_of(argv, rule_profile.rule_commands(rule_profile.rule_blocks(RULES))) == rule


def _benchmark(path: Path, seconds: float, cpu: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"s\th:m:s\tmax_rss\tcpu_time\n{seconds}\t0:00:01\t100.0\t{cpu}\n")


def test_the_profile_sums_each_rules_jobs_and_processes(rule_profile, tmp_path):
    _benchmark(tmp_path / "benchmarks/sim/measured/s2/54C_25Hz.tsv", 3.0, 2.5)
    _benchmark(tmp_path / "benchmarks/sim/paper/s1/20C_40Hz.tsv", 2.0, 1.5)
    _benchmark(tmp_path / "benchmarks/results/forecast/pack_196_s1.tsv", 12.0, 11.0)
    _benchmark(tmp_path / "benchmarks/diagnosis/crossval_time_domain.tsv", 2.2, 1.9)
    _benchmark(tmp_path / "benchmarks/unknown/thing.tsv", 1.0, 1.0)
    records = [(RUN_2PB, 2.0, 0.5), (RUN_2PB, 0.75, 0.1), (TIME_DOMAIN, 1.5, 0.2), (PACK, 10.0, 1.0)]
    records += [(["no-such-command"], 0.2, 0.0)]
    lines = [json.dumps({"argv": a, "status": 0, "user_s": u, "system_s": s}) for a, u, s in records]
    (tmp_path / "benchmarks/process_cpu.jsonl").write_text("\n".join(lines) + "\n")

    table = rule_profile.profile(tmp_path, RULES).set_index("rule")
    run = table.loc["run_2pb"]
    assert (run.jobs, run.wall_s, run.cpu_s_benchmark) == (2, 5.0, 4.0)
    assert (run.processes, run.cpu_s, run.cpu_s_least_process) == (2, 3.35, 0.85)
    assert run.cpu_s_per_process == pytest.approx(1.68, abs=0.01)  # rounded to 2 decimals
    assert (table.loc["crossval_time_domain", "jobs"], table.loc["crossval_time_domain", "cpu_s"]) == (1, 1.7)
    assert (table.loc["forecast_pack", "wall_s"], table.loc["forecast_pack", "cpu_s"]) == (12.0, 11.0)
    assert table.loc["benchmarks/unknown/thing.tsv", "jobs"] == 1  # matched by no rule: kept under its path
    assert table.loc["(command no-such-command)", "processes"] == 1
    assert list(table["cpu_s"].dropna()) == sorted(table["cpu_s"].dropna(), reverse=True)


def test_a_run_without_benchmark_records_is_refused_naming_its_folder(rule_profile, tmp_path, capsys):
    with pytest.raises(ValueError, match=r"benchmarks: no benchmark records"):
        rule_profile.profile(tmp_path, RULES)
    out = tmp_path / "profile.csv"
    with pytest.raises(SystemExit) as stop:
        rule_profile.main([str(tmp_path), "-o", str(out)])
    assert stop.value.code == 2 and "no benchmark records" in capsys.readouterr().err
    assert not out.exists() and not list(tmp_path.glob("*.tmp"))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("s\th:m:s\tmax_rss\n", r"needs the columns s, cpu_time; missing cpu_time"),  # header only, no cpu_time
        ("wall\tcpu_time\n2.0\t1.0\n", r"missing s \(header: wall, cpu_time\)"),
        ("", r"not a Snakemake benchmark table"),
    ],
)
def test_a_benchmark_record_without_its_columns_is_refused_naming_the_file(rule_profile, tmp_path, text, expected):
    _benchmark(tmp_path / "benchmarks/sim/measured/s2/54C_25Hz.tsv", 3.0, 2.5)
    bad = tmp_path / "benchmarks/diagnosis/diagnose_bench.tsv"
    bad.parent.mkdir(parents=True)
    bad.write_text(text)
    with pytest.raises(ValueError, match=rf"diagnose_bench\.tsv: .*{expected}"):
        rule_profile.profile(tmp_path, RULES)


def test_a_header_only_benchmark_record_counts_no_job(rule_profile, tmp_path):
    _benchmark(tmp_path / "benchmarks/sim/measured/s2/54C_25Hz.tsv", 3.0, 2.5)
    (tmp_path / "benchmarks/diagnosis/diagnose_bench.tsv").parent.mkdir(parents=True)
    (tmp_path / "benchmarks/diagnosis/diagnose_bench.tsv").write_text("s\th:m:s\tmax_rss\tcpu_time\n")
    table = rule_profile.profile(tmp_path, RULES).set_index("rule")
    assert (table.loc["diagnose_bench", "jobs"], table.loc["diagnose_bench", "wall_s"]) == (0, 0.0)
    assert table.loc["run_2pb", "jobs"] == 1


@pytest.mark.parametrize(
    ("row", "expected"),
    [
        ("n/a\t0:00:01\t100.0\t1.0", r"row 2, column s: expected a number of seconds >= 0, got 'n/a'"),
        ("\t0:00:01\t100.0\t1.0", r"row 2, column s: expected a number of seconds >= 0, got ''"),
        ("2.0\t0:00:01\t100.0\tfast", r"row 2, column cpu_time: expected a number of seconds >= 0 or NA, got 'fast'"),
        ("-1.0\t0:00:01\t100.0\t1.0", r"row 2, column s: expected a number of seconds >= 0, got '-1.0'"),
    ],
)
def test_a_benchmark_value_that_is_no_time_is_refused_naming_its_row(rule_profile, tmp_path, row, expected):
    """Each record's wall and CPU seconds are numbers; Snakemake's NA (no CPU measured) counts as 0."""
    bad = tmp_path / "benchmarks/diagnosis/diagnose_bench.tsv"
    bad.parent.mkdir(parents=True)
    bad.write_text(f"s\th:m:s\tmax_rss\tcpu_time\n1.0\t0:00:01\t100.0\t1.0\n{row}\n")
    with pytest.raises(ValueError, match=rf"diagnose_bench\.tsv, {expected}"):
        rule_profile.profile(tmp_path, RULES)
    bad.write_text("s\th:m:s\tmax_rss\tcpu_time\n1.0\t0:00:01\t100.0\t1.0\n2.5\t0:00:02\t100.0\tNA\n")
    table = rule_profile.profile(tmp_path, RULES).set_index("rule")
    assert (table.loc["diagnose_bench", "wall_s"], table.loc["diagnose_bench", "cpu_s_benchmark"]) == (3.5, 1.0)


@pytest.mark.parametrize(
    "line",
    [
        '{"argv": ["run-2pb"], "user_s": 1.0}',  # no system_s
        '{"argv": [], "user_s": 1.0, "system_s": 0.1}',  # no command
        '{"argv": "run-2pb", "user_s": 1.0, "system_s": 0.1}',  # argv not a list
        '{"argv": ["run-2pb"], "user_s": "fast", "system_s": 0.1}',
        "not json",
    ],
)
def test_a_bad_process_record_is_refused_naming_its_line(rule_profile, tmp_path, line):
    good = json.dumps({"argv": RUN_2PB, "user_s": 1.0, "system_s": 0.1})
    (tmp_path / "benchmarks").mkdir()
    (tmp_path / "benchmarks/process_cpu.jsonl").write_text(f"{good}\n\n{line}\n")
    with pytest.raises(ValueError, match=r"process_cpu\.jsonl, line 3: expected a JSON object with argv"):
        rule_profile.profile(tmp_path, RULES)


def test_a_folder_without_rules_is_refused(rule_profile, tmp_path):
    _benchmark(tmp_path / "benchmarks/sim/measured/s2/54C_25Hz.tsv", 3.0, 2.5)
    with pytest.raises(ValueError, match=r"no rule in its \*\.smk files"):
        rule_profile.profile(tmp_path, tmp_path)
