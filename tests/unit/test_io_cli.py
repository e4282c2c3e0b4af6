"""Atomic output, the CLI dispatcher and report collection."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from asphalt_nscd import cli
from asphalt_nscd import io
from asphalt_nscd.io import atomic_path, write_json


def test_atomic_path_leaves_nothing_on_failure(tmp_path):
    target = tmp_path / "sub" / "out.json"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("partial")
            raise RuntimeError("job failed")
    assert not target.exists()
    assert list(target.parent.iterdir()) == []


def test_atomic_path_replaces_on_success(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old")
    write_json({"a": 1}, target)
    assert target.read_text() == '{\n  "a": 1\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_every_subpackage_registers_subcommands():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert "collect-report" in sub.choices


def test_collect_report_copies_and_indexes(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    fig = tmp_path / "results" / "lab" / "fig.png"
    fig.parent.mkdir(parents=True)
    fig.write_bytes(b"\x89PNG fake")
    table = tmp_path / "results" / "calibration" / "t.csv"
    table.parent.mkdir(parents=True)
    table.write_text("a,b\n1,2\n")
    status = cli.main(
        [
            "collect-report",
            "results/lab/fig.png",
            "results/calibration/t.csv",
            "--out-dir",
            "results/report",
            "-o",
            "results/report/index.md",
        ]
    )
    assert status == 0
    index = (tmp_path / "results/report/index.md").read_text()
    assert "![lab/fig.png](lab/fig.png)" in index and "[calibration/t.csv](calibration/t.csv)" in index
    assert (tmp_path / "results/report/calibration/t.csv").read_text() == "a,b\n1,2\n"


def test_collect_report_missing_input_is_an_error(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    status = cli.main(["collect-report", "results/nope.png", "--out-dir", "r", "-o", "r/index.md"])
    assert status == 2
    assert "results/nope.png" in capsys.readouterr().err
    assert not (tmp_path / "r" / "index.md").exists()


def test_atomic_output_has_the_usual_file_mode(tmp_path):
    import os
    import stat

    target = tmp_path / "out.json"
    write_json({}, target)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask


def test_stale_temporaries_of_a_killed_writer_are_removed(tmp_path):
    target = tmp_path / "run.h5"
    stale = [tmp_path / ".run.h5.abc123.tmp", tmp_path / ".run.h5.zz.tmp"]
    keep = [tmp_path / ".other.h5.abc.tmp", tmp_path / "run.h5.ckpt.h5"]
    for p in stale + keep:
        p.write_text("x")
    assert io.remove_stale_temporaries(target) == sorted(stale)
    assert all(not p.exists() for p in stale) and all(p.exists() for p in keep)


def test_termination_request_unwinds_and_is_remembered(monkeypatch):
    monkeypatch.setitem(io._TERMINATION, "signal", None)
    io.check_termination()  # no request: nothing happens
    with pytest.raises(SystemExit) as exc:
        io.request_termination(15)
    assert exc.value.code == 143
    with pytest.raises(SystemExit):  # a swallowed SystemExit still stops the next step
        io.check_termination()


def _run(tmp_path, monkeypatch, *argv) -> int:
    monkeypatch.chdir(tmp_path)
    return cli.main(list(argv))


def test_own_table_overlay_keeps_a_path_with_spaces_quotes_and_non_ascii(tmp_path, monkeypatch, capsys):
    import yaml

    name = "my lab \u00ef/m\u00efx 'q\" (ksi).csv"
    (tmp_path / name).parent.mkdir()
    (tmp_path / name).write_text("x\n")
    assert _run(tmp_path, monkeypatch, "own-table-config", name, "-o", "results/own_table.yaml") == 0
    overlay = yaml.safe_load((tmp_path / "results" / "own_table.yaml").read_text(encoding="utf-8"))
    assert overlay == {"measured": {"table": name}}
    assert _run(tmp_path, monkeypatch, "own-table-config", "missing.csv", "-o", "o.yaml") == 2
    assert "TABLE=missing.csv: file not found" in capsys.readouterr().err
    assert not (tmp_path / "o.yaml").exists()


def _results(root, sha="a" * 64):
    """A results/ tree of one table: the validated table and a law JSON stamped with ``sha``."""
    import json

    (root / "results" / "lab").mkdir(parents=True, exist_ok=True)
    (root / "results" / "diagnosis").mkdir(parents=True, exist_ok=True)
    (root / "results" / "lab" / "measured.csv").write_text("specimen\nA\n")
    law = root / "results" / "diagnosis" / "law.json"
    law.write_text(json.dumps({"source": {"measured_sha256": sha}}))
    return root / "results" / "lab" / "measured.csv", law


def test_publish_table_puts_a_complete_run_in_place_and_keeps_it_when_the_next_fails(tmp_path, monkeypatch, capsys):
    """The folder of a table's complete run, with its manifest; a next run whose results come from
    another table, or lack a file, is refused and leaves the folder as it was."""
    import json

    (tmp_path / "mix.csv").write_text("lab table\n")
    measured, law = _results(tmp_path)
    law.write_text(json.dumps({"source": {"measured_sha256": io.content_sha256(measured)}}))
    # a test JSON whose "source" says where its values come from (a text, not a stamp)
    (tmp_path / "results" / "lab" / "measured.test.json").write_text(json.dumps({"source": "the lab's report"}))
    args = [
        "publish-table",
        "results/lab/measured.csv",
        "results/diagnosis/law.json",
        "results/lab/measured.test.json",
        "--table",
        "mix.csv",
        "--measured",
        "results/lab/measured.csv",
        "-o",
        "results/tables/mix",
    ]
    assert _run(tmp_path, monkeypatch, *args) == 0
    out = tmp_path / "results" / "tables" / "mix"
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["table_sha256"] == io.content_sha256(tmp_path / "mix.csv")
    assert set(manifest["files"]) == {"lab/measured.csv", "diagnosis/law.json", "lab/measured.test.json"}
    assert manifest["files"]["diagnosis/law.json"] == io.content_sha256(law)
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    # a new table beside the old law: refused, the folder untouched
    measured.write_text("specimen\nB\n")
    assert _run(tmp_path, monkeypatch, *args) == 2
    assert "computed from another measured table" in capsys.readouterr().err
    # a missing result: refused, the folder untouched
    law.write_text(json.dumps({"source": {"measured_sha256": io.content_sha256(measured)}}))
    assert _run(tmp_path, monkeypatch, *args[:3], "results/diagnosis/page.md", *args[3:]) == 2
    assert "page.md: file not found" in capsys.readouterr().err
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    assert sorted(p.name for p in out.parent.iterdir()) == ["mix"]  # no staging copy left
    # the complete run of the new table replaces it
    assert _run(tmp_path, monkeypatch, *args) == 0
    assert json.loads((out / "manifest.json").read_text())["measured_sha256"] == io.content_sha256(measured)


def test_collect_report_gives_each_step_one_section(tmp_path, monkeypatch):
    """Files of one step that the rules list apart (a step's tables in its rule file, its figures
    in the figures' rule file) land in one section, the steps in the order of their first file."""
    monkeypatch.chdir(tmp_path)
    files = ["results/calibration/fit.csv", "results/samples/s1.png", "results/calibration/fig.png"]
    for f in files:
        Path(f).parent.mkdir(parents=True, exist_ok=True)
        Path(f).write_text("x")
    assert cli.main(["collect-report", *files, "--out-dir", "results/report", "-o", "results/report/index.md"]) == 0
    text = Path("results/report/index.md").read_text()
    assert text.count("## calibration") == 1 and text.count("## samples") == 1
    assert text.index("calibration/fit.csv") < text.index("calibration/fig.png") < text.index("## samples")
    assert Path("results/report/calibration/fig.png").read_text() == "x"


def test_collect_report_refused_for_a_missing_input_copies_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("results/lab").mkdir(parents=True)
    Path("results/lab/a.csv").write_text("x")
    args = ["collect-report", "results/lab/a.csv", "results/lab/none.csv", "--out-dir", "results/report"]
    assert cli.main([*args, "-o", "results/report/index.md"]) == 2
    assert not Path("results/report").exists()


def test_every_command_appends_its_exact_cpu_record(tmp_path):
    """With ASPHALT_NSCD_CPU_LOG set (the workflow sets it for its jobs), a command appends one
    JSON line at its end, failed or not: its arguments, exit status and getrusage CPU, which is
    what the parent sees its child cost (start-up and imports included) but the interpreter's exit
    after it."""
    import json
    import resource
    import subprocess
    import sys

    log = tmp_path / "cpu" / "process_cpu.jsonl"
    env = {**os.environ, "ASPHALT_NSCD_CPU_LOG": str(log)}
    runs = [["run-2pb", "--help"], ["reduce", str(tmp_path / "missing.csv"), "--meta", "m.json", "-o", "o.json"]]
    seen = []
    for argv in runs:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        proc = subprocess.run([sys.executable, "-m", "asphalt_nscd", *argv], env=env, capture_output=True, text=True)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        seen.append((proc.returncode, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime))
    records = [json.loads(line) for line in log.read_text().splitlines()]
    assert [r["argv"] for r in records] == runs
    assert [r["status"] for r in records] == [code for code, _ in seen]
    assert seen[0][0] == 0 and seen[1][0] != 0
    for record, (_, child_cpu) in zip(records, seen):
        cpu = record["user_s"] + record["system_s"]
        assert cpu <= child_cpu + 0.02, (cpu, child_cpu)  # nothing counted that the process did not spend
        # the start-up (interpreter, imports: about 0.8 s of the 1 s) counts; only the exit comes after
        # the record (0.1 s on an idle machine, 0.3 s seen beside a full test run)
        assert cpu > 0.5 * child_cpu, (cpu, child_cpu)
        assert record["max_rss_mb"] > 10 and record["wall_s"] > 0


def test_a_command_runs_one_blas_thread_unless_the_user_sets_a_count():
    """The CLI sets OPENBLAS_NUM_THREADS=1 before numpy or scipy can load OpenBLAS (which reads it
    once): jobs run side by side, and idle OpenBLAS threads spin. A count the user set is kept."""
    import subprocess
    import sys

    probe = "import sys, os; import asphalt_nscd.cli; assert 'numpy' not in sys.modules; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"
    out = subprocess.run(
        [sys.executable, "-c", probe],
        env={**env, "OPENBLAS_NUM_THREADS": "3"},
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "3"


def test_json_lines_checkpoint_drops_a_cut_last_line_and_refuses_a_bad_one(tmp_path):
    from asphalt_nscd.io import InputError, read_json_lines

    path = tmp_path / "done.jsonl"
    assert read_json_lines(path, "record", ("a",)) == []
    path.write_text('{"a": 1}\n{"a": 2}\n{"a": ')  # the last line cut by a killed run
    assert read_json_lines(path, "record", ("a",)) == [{"a": 1}, {"a": 2}]
    assert path.read_text() == '{"a": 1}\n{"a": 2}\n'  # removed from the file: appending goes on cleanly
    path.write_text('{"a": 1}\nnot json\n{"a": 3}\n')
    with pytest.raises(InputError, match=r"done\.jsonl: line 2 is not a record \(JSON\); remove the file"):
        read_json_lines(path, "record", ("a",))
    path.write_text('{"a": 1}\n{"b": 2}\n')
    with pytest.raises(InputError, match=r"line 2 is not a record \(expected the keys a\)"):
        read_json_lines(path, "record", ("a",))
