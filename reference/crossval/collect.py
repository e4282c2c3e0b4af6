"""Collect the held-out validation of a table run with ``make table`` into this folder.

Reads ``results/tables/<folder>-<table>/diagnosis/crossval/{lofo,loto,loso}.csv`` (the fold
rows of ``asphalt-nscd crossval``: one prediction per held-out cell, fold and model) and the
run's measured table ``lab/measured.csv``, and writes here, per scheme, the rows
(``<scheme>.csv``), their scores as ``asphalt-nscd crossval --summary`` writes them
(``<scheme>_summary.csv``, :func:`asphalt_nscd.diagnosis.scores.summarize`: the observed errors
against the lab's means and their intervals) and the headline of every scheme and model
(``headline.csv``, :func:`asphalt_nscd.diagnosis.scores.headline`: the interpolated cells
pooled, the extrapolated ones apart, the worst temperature marked). The scores are recomputed
from the rows, so a change of the scoring is a rerun of this script, not of the folds.

    .venv/bin/python reference/crossval/collect.py [results/tables/uiuc_fdmix1_utm-complex_modulus]
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from asphalt_nscd.diagnosis import scores
from asphalt_nscd.io import write_csv

SCHEMES = ("lofo", "loto", "loso")


def main(argv: list[str]) -> int:
    run = Path(argv[0]) if argv else Path("results/tables/uiuc_fdmix1_utm-complex_modulus")
    out = Path(__file__).parent
    table = pd.read_csv(run / "lab" / "measured.csv")
    heads = []
    for scheme in SCHEMES:
        src = run / "diagnosis" / "crossval" / f"{scheme}.csv"
        if not src.exists():
            print(f"error: {src} missing (run make table first)", file=sys.stderr)
            return 2
        rows = pd.read_csv(src)
        summary = scores.summarize(rows, table)
        write_csv(rows, out / f"{scheme}.csv", float_format="%.10g")
        write_csv(summary, out / f"{scheme}_summary.csv", float_format="%.6g")
        heads.append(scores.headline(summary))
    write_csv(pd.concat(heads, ignore_index=True), out / "headline.csv", float_format="%.6g")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
