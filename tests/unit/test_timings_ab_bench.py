"""The before/after benchmark's comparison of two forecast score tables (reference/timings/ab_bench.py)."""

import reference_scripts
import math
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def ab_bench():
    return reference_scripts.load("reference/timings/ab_bench.py")


TABLE = "model,group,abs_logE_pct,abs_phase_deg,bias_logE_pct\ndem,all,36.9,4.3,\nhirsch,all,32.1,3.5,-1.0\n"


def test_two_equal_score_tables_differ_by_nothing(ab_bench):
    assert ab_bench.score_difference(TABLE, TABLE) == 0.0  # the empty (NaN) cell on both sides counts as equal


def test_a_moved_score_is_its_largest_difference(ab_bench):
    moved = TABLE.replace("4.3", "4.3000002").replace("-1.0", "-1.5")
    assert ab_bench.score_difference(TABLE, moved) == pytest.approx(0.5)
    assert ab_bench.score_difference(TABLE, TABLE.replace(",-1.0", ",")) == math.inf  # NaN on one side only


def test_score_tables_of_other_rows_or_columns_are_infinitely_apart(ab_bench):
    assert ab_bench.score_difference(TABLE, TABLE.replace("hirsch", "witczak")) == math.inf
    assert ab_bench.score_difference(TABLE, TABLE.replace("bias_logE_pct", "bias_phase_deg")) == math.inf
    assert ab_bench.score_difference(TABLE, TABLE + "dem,cold,40.0,5.0,1.0\n") == math.inf


def _response(scale: float = 1.0, lam_shift: float = 0.0):
    import numpy as np

    from asphalt_nscd.forecast.dem import Response

    n = 5
    return Response(
        mix_id="m",
        seed=1,
        side_m=0.05,
        p0=2.0,
        p1=1.0,
        lam=np.linspace(0.1, 2.0, n) + lam_shift,
        alpha=np.full(n, 0.1) * scale,
        beta=np.full(n, 0.2),
        n_spheres=4,
        n_bonds=6,
        n_skeleton=2,
        p1_f=0.5,
        lam_f=np.linspace(0.2, 1.0, n),
        alpha_f=np.full(n, 0.1),
        beta_f=np.full(n, 0.05),
    )


def test_the_response_case_compares_the_factors_of_both_sides(ab_bench, tmp_path):
    """Equal responses differ by nothing; a moved eigenvalue or projection is seen at its relative size; a
    response on one side only is infinitely apart."""
    before, after = tmp_path / "before", tmp_path / "after"
    before.mkdir()
    after.mkdir()
    _response().save(before / "a_s1.npz")
    _response().save(after / "a_s1.npz")
    assert ab_bench.factor_difference(before, after) == 0.0
    _response(lam_shift=1e-6).save(after / "a_s1.npz")
    assert 1e-9 < ab_bench.factor_difference(before, after) < 1e-5
    _response(scale=1.01).save(after / "a_s1.npz")
    assert ab_bench.factor_difference(before, after) > 1e-5
    _response().save(after / "b_s1.npz")
    assert ab_bench.factor_difference(before, after) == math.inf


def test_the_response_case_takes_the_smallest_median_and_largest_samples_first(ab_bench, tmp_path):
    samples = tmp_path / "results" / "forecast" / "samples"
    samples.mkdir(parents=True)
    for k, size in enumerate([30, 10, 50, 20, 40]):
        (samples / f"{k}_s1.h5").write_bytes(b"x" * size)
    (samples / "0_s1_summary.json").write_text("{}")
    order = [p.name for p in ab_bench.response_samples(tmp_path, None)]
    assert order == ["1_s1.h5", "0_s1.h5", "2_s1.h5", "3_s1.h5", "4_s1.h5"]
    assert [p.name for p in ab_bench.response_samples(tmp_path, 2)] == order[:2]
    with pytest.raises(SystemExit, match="finished make run"):
        ab_bench.response_samples(tmp_path / "nothing", None)


def test_the_diagnose_case_runs_the_bench_on_its_selection_and_keeps_its_table(ab_bench, tmp_path, monkeypatch):
    """The diagnose case runs each side's diagnose-bench on the selection asked for (one worker) in its own
    folder beside the side's data and config, and keeps the rate table it wrote for the comparison."""
    seen = []

    def fake_timed(cmd, cwd, env, log):
        seen.append((cmd, env["PYTHONPATH"].split(":")[0]))
        Path(cmd[cmd.index("--table") + 1]).write_text("family,detection_rate\nwlf,0.5\n")
        return {"command": " ".join(cmd), "returncode": 0, "wall_s": 1.0, "cpu_s": 1.0}

    monkeypatch.setattr(ab_bench, "timed", fake_timed)
    args = ab_bench.argparse.Namespace(configfile=["config/config.yaml"], bench_tables=[3, 2], families=["wlf"])
    tree, work = tmp_path / "tree", tmp_path / "work"
    (tree / "data").mkdir(parents=True)
    (tree / "config").mkdir()
    rec = ab_bench.run_case("diagnose", tree, work, tmp_path / "log", args)
    cmd, path = seen[0]
    assert cmd[1:4] == ["diagnose-bench", "--config", "config/config.yaml"] and path == str(tree / "src")
    given = dict(zip(cmd, cmd[1:]))
    assert (given["--clean"], given["--planted"], given["--families"], given["--jobs"]) == ("3", "2", "wlf", "1")
    assert (work / "config").resolve() == tree / "config" and (work / "data").resolve() == tree / "data"
    assert rec["_scores"] == "family,detection_rate\nwlf,0.5\n"
    assert ab_bench.score_difference(rec["_scores"], rec["_scores"]) == 0.0


def test_a_record_names_no_folder_of_this_machine(ab_bench, tmp_path):
    """The written record replaces the bench's temporary folder by $WORK and drops the interpreter's and the
    repository's folders, so a committed record holds no outside path."""
    exe = Path(ab_bench.sys.executable).parent
    text = (
        f"{exe}/asphalt-nscd x --config {ab_bench.REPO}/config/c.yaml -o {tmp_path}/after/b.csv --run {ab_bench.REPO}"
    )
    assert ab_bench.portable(text, tmp_path) == "asphalt-nscd x --config config/c.yaml -o $WORK/after/b.csv --run ."
