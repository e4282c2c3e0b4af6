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
