"""The complete procedure on this folder's benchmark: every clean table on which the nominal
procedure names an artifact, calibrated on itself as the workflow calibrates a table
(``asphalt_nscd.diagnosis.bench.calibrate_alarms``: its fitted clean model, ``--tables``
bootstrap tables seeded by the table's seed, the artifact procedure's level at a family-wise
rate of 5 % over the two groups), so that the whole procedure's family-wise false-alarm rate
per truth family is counted. A table without a nominal alarm cannot raise one after
calibration (the calibrated level is never above the nominal one).

    python calibrate.py DIR DESIGN [--tables 200] [--jobs 1] [--power-only]

Reads ``DIR/<design>_summary.json`` and ``DIR/<design>_tables.csv.gz`` (written by
``collect.py``); writes ``DIR/<design>_calibrated.csv`` (one row per table with a nominal
alarm: its statistic as committed and as recomputed, the calibrated level, how many bootstrap
tables were run (a calibration stops once its decision is known: more than its share of tables
reach the table's statistic; the level is then an upper bound) and how many reach the
statistic, the decision, CPU seconds) and rewrites ``<design>.csv``,
``<design>_power.csv``, ``<design>_summary.json`` and the table rows with the calibrated
decisions and the power's one-sided 95 % lower bounds. Each table's calibration is kept in
``DIR/<design>_calibration.jsonl`` as it ends: a stopped run resumes there. ``--power-only`` recomputes the power
columns from the summary without calibrating.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import pandas as pd

from asphalt_nscd.diagnosis import bench


def _list(v) -> list:
    return [] if pd.isna(v) or str(v) == "" else str(v).split(";")


def clean_runs(tables: pd.DataFrame) -> list[dict]:
    """The clean tables' runs as ``bench.family_wise`` reads them."""
    clean = tables[tables["kind"] == "clean"]
    return [
        {
            "family": r["family"],
            "kind": "clean",
            "index": int(r["index"]),
            "seed": int(r["seed"]),
            "min_p": float(r["min_p"]),
            "level": float(r["level"]),
            "detected": _list(r["detected"]),
            "screening_chi2_per_dof": float(r["screening_chi2_per_dof"]),
        }
        for _, r in clean.iterrows()
    ]


def refresh_power(summary: dict) -> None:
    """The power curves' one-sided 95 % lower bounds and the sizes that reach 95 % (shown and
    point estimate), from the curves' counts."""
    for pc in summary.get("power_curves", {}).values():
        for row in pc["curve"]:
            row["detection_lower_95"] = bench.lower_bound(row["detection"]["k"], row["detection"]["n"])
        pc.update(bench.power_sizes(pc["curve"]))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("design", choices=sorted(bench.CONFIGURATIONS))
    ap.add_argument("--tables", type=int, default=200, help="bootstrap tables per calibration (default 200)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--power-only", action="store_true", help="recompute the power columns only")
    args = ap.parse_args(argv)
    d, conf = args.dir, args.design
    summary = json.loads((d / f"{conf}_summary.json").read_text())
    tables = pd.read_csv(d / f"{conf}_tables.csv.gz")
    refresh_power(summary)
    if not args.power_only:
        result = {
            k: summary[k] for k in ("base_seed", "families", "n_clean_per_family", "effect_scale", "configuration")
        }
        result["alpha"] = summary["alpha"]
        result["runs"] = runs = clean_runs(tables)
        t0 = time.perf_counter()
        bench.calibrate_alarms(result, n_tables=args.tables, jobs=args.jobs, checkpoint=d / f"{conf}_calibration.jsonl")
        rows = [
            {
                "family": r["family"],
                "index": r["index"],
                "seed": r["seed"],
                "named_at_nominal_level": ";".join(r["detected"]),
                "min_p": r["min_p"],
                "min_p_recomputed": r["calibration_min_p"],
                "nominal_level": r["level"],
                "calibrated_level": r["calibrated_level"],
                "bootstrap_tables": args.tables,
                "bootstrap_tables_run": r.get("calibration_tables_run", args.tables),
                "bootstrap_min_p_at_or_below": r["calibration_null_below"],
                "calibrated_level_is_bound": r.get("calibrated_level_is_bound", False),
                "alarm_after_calibration": r["detected_calibrated"],
                "cpu_s": r["calibration_cpu_seconds"],
            }
            for r in runs
            if "calibrated_level" in r
        ]
        pd.DataFrame(rows).to_csv(d / f"{conf}_calibrated.csv", index=False, float_format="%.6g")
        fw = result["family_wise"]
        summary["family_wise"] = fw
        summary["family_wise_ok"] = {f: bool(v["false_alarm_any"]["ok"]) for f, v in fw.items()}
        summary["family_wise_calibrated_ok"] = {f: bool(v["false_alarm_any_calibrated"]["ok"]) for f, v in fw.items()}
        summary["calibration_tables"] = int(args.tables)
        summary["cpu_seconds_calibration"] = float(sum(r["cpu_s"] for r in rows))
        summary["wall_seconds_calibration"] = time.perf_counter() - t0
        cal = {(r["family"], r["index"]): r for r in runs if r["kind"] == "clean"}
        clean = tables["kind"] == "clean"
        tables.loc[clean, "detected_calibrated"] = [
            cal[(f, int(i))]["detected_calibrated"]
            for f, i in zip(tables.loc[clean, "family"], tables.loc[clean, "index"])
        ]
        tables.loc[clean, "calibrated_level"] = [
            cal[(f, int(i))].get("calibrated_level")
            for f, i in zip(tables.loc[clean, "family"], tables.loc[clean, "index"])
        ]
        tables.to_csv(d / f"{conf}_tables.csv.gz", index=False, float_format="%.6g")
    bench.bench_table(summary).to_csv(d / f"{conf}.csv", index=False, float_format="%.4g")
    bench.power_table(summary).to_csv(d / f"{conf}_power.csv", index=False, float_format="%.4g")
    (d / f"{conf}_summary.json").write_text(json.dumps(summary, indent=1) + "\n")


if __name__ == "__main__":
    from asphalt_nscd.io import InputError

    try:
        main()
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from None
