"""The coverage of the held-out errors' 95 % intervals, from the replicate rows of ``coverage.py``.

    .venv/bin/python reference/crossval/summarize.py reference/crossval/coverage_runs.csv.gz \
        -o reference/crossval/coverage.csv

One row per scheme, quantity (``logE``: |E*| as 100 |ln ratio| %, ``phase``: degrees) and
temperature (``pooled``: the interpolated cells together): the number of replicates, the share
whose interval contains the replicate's true error (``coverage``) with its Clopper-Pearson 95 %
interval, the shares of truths below and above the interval, and the same coverage for the
signed error (``bias``; not defined for loso, whose truth is a new specimen's error).
"""

from __future__ import annotations

import argparse

import pandas as pd
from scipy.stats import beta

from asphalt_nscd.io import write_csv


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of k successes in n (Clopper & Pearson 1934)."""
    a = (1.0 - level) / 2.0
    low = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return low, high


def summarize(runs: pd.DataFrame) -> pd.DataFrame:
    """Coverage per scheme, quantity and temperature (see the module docstring)."""
    r = runs.assign(
        inside=(runs["abs_low"] <= runs["true_abs"]) & (runs["true_abs"] <= runs["abs_high"]),
        below=runs["true_abs"] < runs["abs_low"],
        above=runs["true_abs"] > runs["abs_high"],
        bias_inside=(runs["bias_low"] <= runs["true_bias"]) & (runs["true_bias"] <= runs["bias_high"]),
    )
    out = []
    for (scheme, q, T), g in r.groupby(["scheme", "quantity", "temperature"], sort=False):
        n, k = len(g), int(g["inside"].sum())
        low, high = clopper_pearson(k, n)
        has_bias = g["true_bias"].notna().all()
        out.append(
            {
                "scheme": scheme,
                "quantity": q,
                "temperature": T,
                "replicates": n,
                "coverage_pct": 100.0 * k / n,
                "coverage_ci_low": 100.0 * low,
                "coverage_ci_high": 100.0 * high,
                "truth_below_pct": 100.0 * g["below"].mean(),
                "truth_above_pct": 100.0 * g["above"].mean(),
                "bias_coverage_pct": 100.0 * g["bias_inside"].mean() if has_bias else float("nan"),
                "in_goal_93_97": bool(93.0 <= 100.0 * k / n <= 97.0),
            }
        )
    return pd.DataFrame(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    write_csv(summarize(pd.read_csv(a.runs, dtype={"temperature": str})), a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
