"""The before/after benchmark's comparison of two forecast score tables (reference/timings/ab_bench.py)."""

import importlib.util
import math
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def ab_bench():
    spec = importlib.util.spec_from_file_location("ab_bench", REPO / "reference" / "timings" / "ab_bench.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
