"""The skeleton's exponent measured: ``dem_extended`` with an elastic skeleton (n_s held at 0) against
the fitted parabolic one, held out on the same folds of a forecast run.

    python reference/forecast/skeleton_exponent.py RUN_DIR -o reference/forecast/skeleton_exponent.csv

Reads RUN_DIR/results/forecast/ (matched table, binder curves, responses) and writes the scores of
both variants (every mix, binder through its curve; :func:`asphalt_nscd.forecast.validation.score`)
with a column ``skeleton``: ``elastic`` or ``parabolic``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from asphalt_nscd.forecast.dem import DemModel
from asphalt_nscd.forecast.models import read_curves, read_responses
from asphalt_nscd.forecast.validation import binder_ids, cross_validate, mix_folds, score, with_binder_route
from asphalt_nscd.io import write_csv
from asphalt_nscd.lab.matched import read_matched


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--cut-mm", type=float, default=4.0)
    p.add_argument("-o", "--output", required=True)
    a = p.parse_args(argv)
    res = a.run / "results" / "forecast"
    matched = read_matched(res / "matched.csv")
    ids = binder_ids(matched)
    table = with_binder_route(matched, read_curves(res / "binder_curves.json"), ids, "curve")
    responses = read_responses(sorted((res / "responses").glob("*.npz")))
    folds = mix_folds(matched["mix_id"].unique())
    frames = []
    for name, exponent in (("elastic", 0.0), ("parabolic", None)):
        rows, _ = cross_validate(table, [DemModel("dem_extended", responses, a.cut_mm, exponent)], ids, folds, "curve")
        rows["label"] = "dem_extended"
        s = score(rows)
        frames.append(s[s["group"] == "all"].assign(skeleton=name))
    write_csv(pd.concat(frames, ignore_index=True), a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
