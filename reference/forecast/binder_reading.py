"""The binder's frequency as the published formulas read it: at the table's binder frequency (f / 2 pi Hz
on the shipped table) or at the mix's own frequency f, every formula held out by mix under both.

    python reference/forecast/binder_reading.py -o reference/forecast/binder_reading.csv \\
        --paired reference/forecast/binder_reading_paired.csv

Reads ``data/binder_mix/mixes_35.tsv`` with its sidecar, fits every binder's master curve as the
forecast does (its checks and fit ladder, ``asphalt_nscd.forecast.binder``) and reads it at the
two frequencies (``asphalt_nscd.forecast.binder_study.with_binder_reading``): Witczak 1-37A,
1-40D and Hirsch, published and recalibrated coefficients, leave one mix out, binder through its
curve. Writes:

* ``-o``: the scores per reading (``declared``, ``mix``), formula, group and temperature with t
  intervals over mixes (``asphalt_nscd.forecast.validation.score``), with
  ``binder_over_mix_frequency``, the median ratio of the frequency the binder is read at to the
  mix's frequency (1 / 2 pi for ``declared`` on the shipped table, 1 for ``mix``);
* ``--paired``: per formula and temperature, the per-mix difference ``mix`` minus ``declared`` of
  the mean |E*| and phase errors with t intervals over the mixes (negative: the mix's own
  frequency forecasts better).

Witczak 1-37A reads no binder frequency (its viscosity is the MEPDG's at 10 rad/s at the mix's
temperature), so its two readings are the same forecast by construction.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast import binder_study as S
from asphalt_nscd.forecast.baselines import MODELS
from asphalt_nscd.forecast.binder import check_points
from asphalt_nscd.forecast.models import binder_points
from asphalt_nscd.forecast.validation import (
    COEFFICIENTS,
    Baseline,
    binder_ids,
    cross_validate,
    mix_folds,
    score,
    with_binder_route,
)
from asphalt_nscd.io import write_csv
from asphalt_nscd.lab.matched import read_matched

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True)
    ap.add_argument("--paired", type=Path, required=True)
    args = ap.parse_args(argv)
    matched = read_matched(TABLE)
    ids = binder_ids(matched)
    checked = check_points(binder_points(matched, ids).drop(columns="mixes"))
    curves, _ = S.variant_curves(checked, *S.VARIANTS[0])
    models = [Baseline(m, c) for m in MODELS for c in COEFFICIENTS]
    folds = mix_folds(matched["mix_id"].unique())
    rows, frames = {}, []
    for reading in S.READINGS:
        table = with_binder_route(S.with_binder_reading(matched, reading), curves, ids, "curve")
        ratio = float(np.median(table["binder_frequency_Hz"] / table["frequency_Hz"]))
        r, _ = cross_validate(table, models, ids, folds, "curve")
        rows[reading] = r
        s = score(r).assign(reading=reading, binder_over_mix_frequency=ratio)
        frames.append(s.assign(label=s["model"] + "_" + s["coefficients"]))
    scores = pd.concat(frames, ignore_index=True)
    first = ["reading", "binder_over_mix_frequency", "label"]
    write_csv(scores[first + [c for c in scores.columns if c not in first]], args.output, float_format="%.6g")
    paired = S.paired_difference(rows["declared"], rows["mix"])
    write_csv(paired.assign(label=paired["model"] + "_" + paired["coefficients"]), args.paired, float_format="%.6g")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
