"""The coverage count of the held-out intervals (reference/crossval/summarize.py)."""

import reference_scripts
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]


def _summarize():
    return reference_scripts.load("reference/crossval/summarize.py")


def test_the_clopper_pearson_interval_has_its_known_values():
    s = _summarize()
    assert s.clopper_pearson(0, 10) == pytest.approx((0.0, 0.3084971), abs=1e-6)
    low, high = s.clopper_pearson(95, 100)
    assert low == pytest.approx(0.8871651, abs=1e-6) and high == pytest.approx(0.9835681, abs=1e-6)


def test_a_planted_coverage_is_counted_and_the_committed_table_follows_its_runs():
    """Truths inside their intervals in a known share of 2,000 replicates: the count finds it;
    the committed coverage.csv is the count of the committed runs."""
    s = _summarize()
    rng = np.random.default_rng(7)
    n = 2000
    inside = rng.random(n) < 0.9
    truth = np.where(inside, 1.0, np.where(rng.random(n) < 0.5, -1.0, 3.0))
    runs = pd.DataFrame(
        {
            "scheme": "lofo",
            "quantity": "logE",
            "temperature": "pooled",
            "abs_low": 0.0,
            "abs_high": 2.0,
            "true_abs": truth,
            "bias_low": 0.0,
            "bias_high": 2.0,
            "true_bias": truth,
        }
    )
    row = s.summarize(runs).iloc[0]
    assert row["coverage_pct"] == pytest.approx(100 * inside.mean())
    assert row["coverage_ci_low"] < 90 < row["coverage_ci_high"] and not row["in_goal_93_97"]
    assert row["truth_below_pct"] + row["truth_above_pct"] == pytest.approx(100 * (1 - inside.mean()))
    committed = pd.read_csv(ROOT / "reference" / "crossval" / "coverage_runs.csv.gz", dtype={"temperature": str})
    table = pd.read_csv(ROOT / "reference" / "crossval" / "coverage.csv", dtype={"temperature": str})
    pd.testing.assert_frame_equal(s.summarize(committed).reset_index(drop=True), table, check_dtype=False)
