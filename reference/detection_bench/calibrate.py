"""The complete procedure on this folder's benchmark: every clean table on which the nominal
procedure names an artifact, and the first planted tables of each family and artifact at the
stated size, calibrated on itself as the workflow calibrates a table
(``asphalt_nscd.diagnosis.bench.calibrate_alarms``: its two fitted nulls, the screening model's
and the relaxation spectrum's, ``--tables`` bootstrap tables of each seeded by the table's seed,
the artifact procedure's level at a family-wise rate of 5 % over the two groups, the smaller of
the nulls' levels), so that the whole procedure's family-wise false-alarm rate per truth family
and its power at the stated sizes are counted. A table without a nominal alarm cannot raise one
after calibration (the calibrated level is never above the nominal one).

    python calibrate.py DIR DESIGN [--tables 200] [--planted 0] [--artifacts A,B] [--jobs 1] [--power-only]

Reads ``DIR/<design>_summary.json`` and ``DIR/<design>_tables.csv.gz`` (written by
``collect.py``); writes ``DIR/<design>_calibrated.csv`` (one row per table calibrated, clean or
planted (``kind``): its statistic as committed and as recomputed, the calibrated level and each
null's, how many bootstrap tables of each null were run (a calibration stops once its decision
is known: more than its share of one null's tables reach the table's statistic; the level is
then an upper bound) and how many reach the statistic, the decision (a planted table: what the
search names at the calibrated level), CPU seconds) and rewrites ``<design>.csv``,
``<design>_power.csv``, ``<design>_summary.json`` and the table rows with the calibrated
decisions and the power's one-sided 95 % lower bounds. ``--planted N``: the first N planted
tables of each family and artifact (0: none; ``--artifacts``: of these artifacts only). Each table's calibration is kept in
``DIR/<design>_calibration.jsonl`` as it ends: a stopped run resumes there. ``--power-only``
recomputes the power columns from the summary without calibrating.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import pandas as pd

from asphalt_nscd.diagnosis import bench, calibration


def _list(v) -> list:
    return [] if pd.isna(v) or str(v) == "" else str(v).split(";")


def clean_runs(tables: pd.DataFrame, planted: int = 0, artifacts=bench.ARTIFACTS) -> list[dict]:
    """The clean tables' runs as ``bench.family_wise`` reads them, and the first ``planted``
    planted tables of each family and artifact (of ``artifacts``) at the stated size."""
    kinds = tables["kind"]
    clean = tables[(kinds == "clean") | (kinds.isin(artifacts) & (tables["index"] < planted))]
    return [
        {
            "family": r["family"],
            "kind": r["kind"],
            "index": int(r["index"]),
            "seed": int(r["seed"]),
            "min_p": float(r["min_p"]),
            "level": float(r["level"]),
            "detected": _list(r["detected"]),
            "screening_chi2_per_dof": float(r["screening_chi2_per_dof"]),
        }
        for _, r in clean.iterrows()
    ]


def calibrated_row(r: dict, n_tables: int) -> dict:
    """One row of ``<design>_calibrated.csv`` (module docstring) from a calibrated run."""
    row = {
        "kind": r["kind"],
        "family": r["family"],
        "index": r["index"],
        "seed": r["seed"],
        "named_at_nominal_level": ";".join(r["detected"]),
        "min_p": r["min_p"],
        "min_p_recomputed": r["calibration_min_p"],
        "nominal_level": r["level"],
        "calibrated_level": r["calibrated_level"],
        "binding_null": r["calibration_binding_null"],
        "bootstrap_tables": n_tables,
    }
    for name in bench._nulls_tag():
        row[f"level_{name}"] = r["calibration_null_levels"][name]
        row[f"tables_run_{name}"] = r["calibration_tables_run"][name]
        row[f"at_or_below_{name}"] = r["calibration_null_below"][name]
    row["calibrated_level_is_bound"] = r.get("calibrated_level_is_bound", False)
    det = r["detected_calibrated"]
    row["alarm_after_calibration"] = bool(det)
    row["named_after_calibration"] = det if isinstance(det, bool) else ";".join(det)
    if isinstance(det, bool):
        row["named_after_calibration"] = row["named_at_nominal_level"] if det else ""
    row["cpu_s"] = r["calibration_cpu_seconds"]
    return row


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
    ap.add_argument("--planted", type=int, default=0, help="planted tables per family and artifact (default 0)")
    ap.add_argument("--artifacts", default=",".join(bench.ARTIFACTS), help="planted artifacts recounted (default all)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--power-only", action="store_true", help="recompute the power columns only")
    args = ap.parse_args(argv)
    if args.tables < calibration.min_tables():
        ap.error(
            f"--tables: at least {calibration.min_tables()} bootstrap tables (fewer can name nothing), got {args.tables}"
        )
    d, conf = args.dir, args.design
    summary = json.loads((d / f"{conf}_summary.json").read_text())
    tables = pd.read_csv(d / f"{conf}_tables.csv.gz")
    refresh_power(summary)
    if not args.power_only:
        keys = ("base_seed", "families", "n_clean_per_family", "n_planted_per_family_and_artifact", "effect_scale")
        result = {k: summary[k] for k in (*keys, "configuration")}
        result["alpha"] = summary["alpha"]
        kinds = tuple(a for a in args.artifacts.split(",") if a)
        unknown = [a for a in kinds if a not in bench.ARTIFACTS]
        if unknown:
            raise SystemExit(f"--artifacts: unknown {unknown}; expected some of {', '.join(bench.ARTIFACTS)}")
        result["runs"] = runs = clean_runs(tables, args.planted, kinds)
        t0 = time.perf_counter()
        bench.calibrate_alarms(
            result,
            n_tables=args.tables,
            jobs=args.jobs,
            checkpoint=d / f"{conf}_calibration.jsonl",
            planted=args.planted,
            artifacts=kinds,
        )
        rows = [calibrated_row(r, args.tables) for r in runs if "calibrated_level" in r]
        pd.DataFrame(rows).to_csv(d / f"{conf}_calibrated.csv", index=False, float_format="%.6g")
        fw = result["family_wise"]
        summary["family_wise"] = fw
        summary["family_wise_ok"] = {f: bool(v["false_alarm_any"]["ok"]) for f, v in fw.items()}
        summary["family_wise_calibrated_ok"] = {f: bool(v["false_alarm_any_calibrated"]["ok"]) for f, v in fw.items()}
        summary["detection_calibrated"] = result["detection_calibrated"]
        summary["calibration_tables"] = int(args.tables)
        summary["planted_calibrated"] = {"per_family": int(args.planted), "artifacts": list(kinds)}
        summary["calibration_nulls"] = bench._nulls_tag()
        summary["cpu_seconds_calibration"] = float(sum(r["cpu_s"] for r in rows))
        summary["wall_seconds_calibration"] = time.perf_counter() - t0
        cal = {(r["kind"], r["family"], r["index"]): r for r in runs}
        key = list(zip(tables["kind"], tables["family"], tables["index"].astype(int)))
        clean = (tables["kind"] == "clean").to_numpy()
        tables.loc[clean, "detected_calibrated"] = [cal[k]["detected_calibrated"] for k, c in zip(key, clean) if c]
        tables["calibrated_level"] = [cal[k].get("calibrated_level") if k in cal else None for k in key]
        tables["named_calibrated"] = [
            ";".join(cal[k]["detected_calibrated"]) if k in cal and k[0] != "clean" else None for k in key
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
