"""Coverage of the forecasts' 90 % prediction intervals on the 35 shipped mixes, each mix left out.

Every model of the default configuration that needs no sample response (the published formulas
with published and recalibrated coefficients, and the learned yardstick) is cross-validated
leaving one mix out on data/binder_mix/mixes_35.tsv, on both binder routes
(asphalt_nscd.forecast.validation.cross_validate, as ``asphalt-nscd forecast-crossval``). Its
held-out rows give the nested coverage of asphalt_nscd.forecast.intervals (each mix's interval
calibrated on the other 34 mixes' held-out residuals only), per model, route, quantity (|E*|,
phase) and temperature (empty: every temperature), with equal tails (the default) and symmetric
intervals; 95 % t intervals over the mixes.

    python reference/forecast/interval_coverage.py -o reference/forecast/interval_coverage.csv

``--rows FILE`` adds the held-out rows of a run's ``forecast-crossval`` for the models this
script does not fit (the discrete models: results/forecast/crossval_rows.csv of ``make run``).
About 2 minutes of CPU, BLAS held to one thread.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from asphalt_nscd import config
from asphalt_nscd.forecast import intervals
from asphalt_nscd.forecast.binder import check_points, fit_binder_ladder
from asphalt_nscd.forecast.models import binder_points, model_set
from asphalt_nscd.forecast.validation import binder_ids, cross_validate, mix_folds, with_binder_route
from asphalt_nscd.lab.matched import read_matched

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"


def held_out_rows(table: pd.DataFrame) -> pd.DataFrame:
    """Held-out rows of every response-free model of config/config.yaml, both binder routes."""
    cfg = config.checked([ROOT / "config" / "config.yaml"], default=None)["forecast"]
    ids = binder_ids(table)
    points = binder_points(table, ids).drop(columns="mixes")
    curves = {b: fit_binder_ladder(g)[0] for b, g in check_points(points).groupby("binder")}
    folds = mix_folds(table.dropna(subset=["E_norm_MPa"])["mix_id"].unique())
    frames = []
    for route in cfg["binder_routes"]:
        routed = with_binder_route(table, curves, ids, route)
        models = [m for m in model_set(cfg, None) if m.available(routed)]
        frames.append(cross_validate(routed, models, ids, folds, route)[0])
    return pd.concat(frames, ignore_index=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True)
    ap.add_argument("--rows", type=Path, default=None, help="held-out rows of forecast-crossval to add")
    args = ap.parse_args(argv)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):  # the recalibrations' BLAS: its idle threads spin on a shared machine
        rows = held_out_rows(read_matched(TABLE))
    if args.rows is not None:
        more = pd.read_csv(args.rows, dtype={"mix_id": str})
        rows = pd.concat([rows, more[~more["model"].isin(set(rows["model"]))]], ignore_index=True)
    out = [intervals.coverage(rows, intervals.LEVEL, tails) for tails in intervals.TAILS]
    pd.concat(out, ignore_index=True).to_csv(args.output, index=False, float_format="%.6g")


if __name__ == "__main__":
    main()
