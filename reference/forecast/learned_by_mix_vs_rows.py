"""The learned yardstick judged two ways on the 35 shipped mixes: mixes left out, and random rows.

``gradient_boosting`` (asphalt_nscd.forecast.learned) forecasts every cell of the shipped table
(data/binder_mix/mixes_35.tsv) twice per binder route: by leave one mix out (the project's judge:
the mix forecast was never seen) and by random rows (35 folds of a seeded shuffle of the 1,050
cells, so each training set is as large; a mix's other conditions are in its training set), once
with the model as it is (its hyperparameters tuned by inner folds of mixes: ``rows_tuned_by`` mix)
and once tuned as a judge by random rows would tune it (inner folds of random cells:
``rows_tuned_by`` rows); the by-mix columns are the same in both. Both
errors are the mean over the 35 mixes of each mix's mean |100 ln(forecast/measured)| (%) or mean
|phase error| (degrees), with 95 % t intervals over the mixes; ``ratio`` is by-mix / by-rows,
the geometric mean over the mixes of the per-mix ratio with the t interval of its log
(asphalt_nscd.forecast.learned.compare). Overall (``temperature_C`` empty) and per temperature.

    python reference/forecast/learned_by_mix_vs_rows.py -o reference/forecast/learned_by_mix_vs_rows.csv

The binder master curves are fitted as ``asphalt-nscd forecast-binders`` fits them. About 4 minutes
of CPU (6 x 35 fits, each tuned by its inner folds).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from asphalt_nscd.forecast.binder import check_points, fit_binder_ladder
from asphalt_nscd.forecast.learned import GradientBoosting, by_rows, compare
from asphalt_nscd.forecast.models import binder_points
from asphalt_nscd.forecast.validation import binder_ids, cross_validate, mix_folds, with_binder_route
from asphalt_nscd.lab.matched import read_matched

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"
ROUTES = ("curve", "raw")
#: seed of the random-row folds
SEED = 1


def curves(table):
    """The binder master curves of ``forecast-binders`` (asphalt_nscd.forecast.cli)."""
    points = binder_points(table, binder_ids(table)).drop(columns="mixes")
    return {b: fit_binder_ladder(g)[0] for b, g in check_points(points).groupby("binder")}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True)
    args = ap.parse_args(argv)
    import pandas as pd

    table = read_matched(TABLE)
    ids = binder_ids(table)
    fitted = curves(table)
    mixes = list(dict.fromkeys(table.dropna(subset=["E_norm_MPa"])["mix_id"]))
    out = []
    for route in ROUTES:
        routed = with_binder_route(table, fitted, ids, route)
        by_mix, _ = cross_validate(routed, [GradientBoosting()], ids, mix_folds(mixes), route)
        for tuning in ("mix", "rows"):
            by_row = by_rows(routed, GradientBoosting(inner=tuning), route, k=len(mixes), seed=SEED)
            out.append(compare(by_mix, by_row).assign(rows_tuned_by=tuning))
    frame = pd.concat(out, ignore_index=True)
    columns = ["model", "binder_route", "rows_tuned_by"]
    frame = frame[columns + [c for c in frame.columns if c not in columns]]
    frame.to_csv(args.output, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
