"""Collect the committed tables of a forecast run (``make run`` or the reference overlay) into a folder.

    python reference/forecast/collect.py RUN_DIR --label default -o reference/forecast

RUN_DIR is the working directory of the run (it holds ``results/forecast/`` and
``benchmarks/process_cpu.jsonl``). Writes, each prefixed by the label:

* ``<label>_crossval.csv``: the held-out scores (``results/forecast/crossval.csv``);
* ``<label>_per_mix.csv``: each mix's mean held-out errors per model, route and temperature (the
  paired comparisons of the page, :func:`asphalt_nscd.forecast.render.per_mix_errors`);
* ``<label>_costs.csv``: the exact CPU (user + system, getrusage) of each mix's packing, sample and
  response (per sample variant: ``variant``, empty for the base sample), and of the chain's other commands, from the run's CPU records (the last record of
  each command line);
* ``<label>_constants.csv``: the discrete models' constants fitted on every measured mix (route
  curve) with those of every fold (smallest, largest);
* ``<label>_error_split.csv``, ``<label>_selection_log.csv``, ``<label>_interval_coverage.csv``,
  ``<label>_learned_by_rows.csv``: the run's error split, the variants tried inside every fold,
  the prediction intervals' nested coverage and the learned model judged by mix and by rows;
* with ``--models M ...`` only ``<label>_crossval.csv``, ``<label>_per_mix.csv`` (those models' rows),
  ``<label>_selection_log.csv`` and, where the run has CPU records, ``<label>_costs.csv``: a run kept to compare one model across settings (e.g. the
  rule of ``dem_selected``'s choice, ``forecast.dem.selection_rule``);
* ``<label>_seed_spread.csv`` (runs of several seeds): per mix and seed, the mean over the table's
  conditions of 100 |ln(E_seed / E_mean)|, |E*| of ``dem_extended`` at the fitted constants from one
  seed's sample against the geometric mean over the seeds.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast.dem import DemModel
from asphalt_nscd.forecast.models import read_curves, read_responses
from asphalt_nscd.forecast.physical import ALL_STEPS as STEPS
from asphalt_nscd.forecast.validation import binder_ids, with_binder_route
from asphalt_nscd.io import read_csv, read_json, write_csv
from asphalt_nscd.lab.matched import read_matched


#: the commands that prepare one mix's sample (their cost does not depend on the rest of the configuration)
ONE_SAMPLE = ("forecast-pack", "forecast-sample", "forecast-response")


def _cost_key(argv: list) -> tuple:
    """(command, sample variant, mix, seed) of a command line: a sample variant's files live in
    results/forecast/variants/<name>/ ("" the base sample)."""
    mix = argv[argv.index("--mix") + 1] if "--mix" in argv else ""
    seed = argv[argv.index("--seed") + 1] if "--seed" in argv else ""
    variant = ""
    if argv[0] in ONE_SAMPLE:
        variant = next((a.split("/variants/")[1].split("/")[0] for a in argv if "/variants/" in a), "")
    return argv[0], variant, mix, seed


def costs(run: Path) -> pd.DataFrame:
    """CPU of the run's last complete forecast: the commands given the configuration of its last
    successful ``forecast-crossval`` (or no configuration), the last record of each (command, sample
    variant, mix, seed). A mix's preparation that the run reused from an earlier run (a
    configuration whose change does not touch it) is taken from that run's last record, marked
    ``earlier_run``; the preparations of a sample variant the last cross-validation did not read are left out."""
    records = [json.loads(line) for line in (run / "benchmarks" / "process_cpu.jsonl").read_text().splitlines()]
    records = [r for r in records if r["argv"] and r["status"] == 0]
    final = [r["argv"] for r in records if r["argv"][0] == "forecast-crossval"][-1]
    config = final[final.index("--config") + 1]
    last, earlier = {}, {}
    for r in records:
        a = r["argv"]
        if not (a[0].startswith("forecast") or a[0] == "matched"):
            continue
        if "--config" not in a or config in a:
            last[_cost_key(a)] = r
        elif a[0] in ONE_SAMPLE:
            earlier[_cost_key(a)] = r
    reused = {k: r for k, r in earlier.items() if k not in last}
    # only the samples the final cross-validation read (its --responses): a variant the configuration dropped is not its cost
    used = {""} | {a.split("/variants/")[1].split("/")[0] for a in final if "/variants/" in a}
    last = {k: r for k, r in last.items() if k[0] not in ONE_SAMPLE or k[1] in used}
    reused = {k: r for k, r in reused.items() if k[1] in used}
    rows = [
        {
            "command": k[0],
            "variant": k[1],
            "mix_id": k[2],
            "seed": k[3],
            "cpu_s": r["user_s"] + r["system_s"],
            "max_rss_mb": r["max_rss_mb"],
            "earlier_run": k in reused,
        }
        for k, r in (*last.items(), *reused.items())
    ]
    return pd.DataFrame(rows).sort_values(["command", "variant", "mix_id", "seed"])


#: the constants each step of the physical ladder fits
PHYSICAL_FREE = dict(STEPS)


def constants(run: Path) -> pd.DataFrame:
    final = read_json(run / "results" / "forecast" / "forecast_constants.json")
    folds = read_json(run / "results" / "forecast" / "crossval_constants.json")["fits"]
    rows = []
    for fit in final["fits"]:
        if not fit["model"].startswith("dem"):
            continue
        names = PHYSICAL_FREE.get(fit["model"], ())
        for k, v in fit["state"].items():
            if not (k.startswith("C_") or k == "n_s" or k in names):
                continue
            per = [f["state"][k] for f in folds if f["model"] == fit["model"] and f["binder_route"] == "curve"]
            rows.append(
                {
                    "model": fit["model"],
                    "constant": k,
                    "all_mixes": v,
                    "folds_min": min(per),
                    "folds_max": max(per),
                    "n_folds": len(per),
                }
            )
    return pd.DataFrame(rows)


def seed_spread(run: Path, cut_mm: float) -> pd.DataFrame | None:
    res = run / "results" / "forecast"
    responses = read_responses(sorted((res / "responses").glob("*.npz")))
    if max(len(v) for v in responses.values()) < 2:
        return None
    matched = read_matched(res / "matched.csv")
    table = with_binder_route(matched, read_curves(res / "binder_curves.json"), binder_ids(matched), "curve")
    state = next(f["state"] for f in read_json(res / "forecast_constants.json")["fits"] if f["model"] == "dem_extended")
    rows = []
    for mix, resp in responses.items():
        t = table[table["mix_id"] == mix]
        logs = [np.log(DemModel("dem_extended", {mix: [r]}, cut_mm).predict(state, t)[0]) for r in resp]
        mean = np.mean(logs, axis=0)
        for r, lg in zip(resp, logs):
            rows.append(
                {
                    "mix_id": mix,
                    "seed": r.seed,
                    "n_spheres": r.n_spheres,
                    "mean_abs_log_diff_pct": float(100 * np.mean(np.abs(lg - mean))),
                }
            )
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("--label", required=True)
    p.add_argument("--cut-mm", type=float, default=4.0, help="the run's forecast.dem.cut_mm")
    p.add_argument("--models", nargs="+", help="keep only these models' scores (and the selection log)")
    p.add_argument("-o", "--output", type=Path, required=True)
    a = p.parse_args(argv)
    a.output.mkdir(parents=True, exist_ok=True)
    from asphalt_nscd.forecast.render import per_mix_errors

    scores = read_csv(a.run / "results" / "forecast" / "crossval.csv")
    rows = read_csv(a.run / "results" / "forecast" / "crossval_rows.csv", dtype={"mix_id": str})
    per_mix = per_mix_errors(rows).round(6)
    if a.models:
        scores, per_mix = scores[scores["label"].isin(a.models)], per_mix[per_mix["label"].isin(a.models)]
        missing = sorted(set(a.models) - set(scores["label"]))
        if missing:
            raise SystemExit(f"{a.run}/results/forecast/crossval.csv: no scores of {missing}")
    write_csv(scores, a.output / f"{a.label}_crossval.csv")
    write_csv(per_mix, a.output / f"{a.label}_per_mix.csv")
    if a.models:
        selection = read_csv(a.run / "results" / "forecast" / "selection_log.csv", allow_empty=True)
        write_csv(selection, a.output / f"{a.label}_selection_log.csv")
        if (a.run / "benchmarks" / "process_cpu.jsonl").is_file():  # the CPU of what the kept run ran
            write_csv(costs(a.run), a.output / f"{a.label}_costs.csv")
        return 0
    write_csv(costs(a.run), a.output / f"{a.label}_costs.csv")
    write_csv(constants(a.run), a.output / f"{a.label}_constants.csv")
    res = a.run / "results" / "forecast"
    for name in ("error_split", "selection_log", "interval_coverage", "learned_by_rows"):
        write_csv(read_csv(res / f"{name}.csv", allow_empty=True), a.output / f"{a.label}_{name}.csv")
    spread = seed_spread(a.run, a.cut_mm)
    if spread is not None:
        write_csv(spread, a.output / f"{a.label}_seed_spread.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
