"""Collect runs of ``asphalt-nscd diagnose-bench`` (one or several JSON files of the same
configuration, e.g. families or power curves run as separate processes) into this folder's
small tables: the summary without the per-table runs, the family-wise false alarms, detection
and power tables, and one row per table with its p-values.

    python collect.py OUTDIR RUN.json [RUN.json ...]

Writes ``OUTDIR/<configuration>_summary.json``, ``<configuration>.csv``,
``<configuration>_power.csv`` and ``<configuration>_tables.csv.gz``. Raises SystemExit when
the runs mix configurations, base seeds or detector settings."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd

from asphalt_nscd.diagnosis import bench

SAME = ("configuration", "base_seed", "alpha", "tolerance", "effect_scale")


def merge(results: list[dict]) -> dict:
    """One result from runs of the same configuration: summaries recomputed on all tables."""
    for key in SAME:
        values = {json.dumps(r[key]) for r in results}
        if len(values) > 1:
            raise SystemExit(f"runs differ in {key}: {sorted(values)}")
    runs = [run for r in results for run in r["runs"]]
    families = list(dict.fromkeys(f for r in results for f in r["families"]))
    summary = bench.summarize(runs, families)
    fw = bench.family_wise(runs, families)
    first = results[0]
    return {
        **{k: first[k] for k in SAME},
        "design": first["design"],
        "families": families,
        "n_clean_per_family": max(r["n_clean_per_family"] for r in results),
        "n_planted_per_family_and_artifact": max(r["n_planted_per_family_and_artifact"] for r in results),
        "power_tables_per_size": max(r["power_tables_per_size"] for r in results),
        "effect_sizes": first["effect_sizes"],
        "goals": first["goals"],
        "family_wise": fw,
        "family_wise_ok": {f: bool(v["false_alarm_any"]["ok"]) for f, v in fw.items()},
        "level_for_goal": bench.level_for_goal(runs, families),
        "power_curves": bench.power_curves(runs),
        "summary": summary,
        "goals_met": bench.goals_met(summary),
        "n_tables": len(runs),
        "cpu_seconds_tables": sum(run["cpu_seconds"] for run in runs),
        "calibration_tables": max((r.get("calibration_tables", 0) for r in results), default=0),
        "cpu_seconds_calibration": sum(run.get("calibration_cpu_seconds", 0.0) for run in runs),
        "runs": runs,
    }


def tables(runs: list[dict]) -> pd.DataFrame:
    rows = []
    for run in runs:
        row = {
            k: run[k]
            for k in (
                "family",
                "kind",
                "index",
                "seed",
                "schedule",
                "power_size",
                "n_specimens",
                "min_p",
                "level",
                "screening_chi2_per_dof",
                "cpu_seconds",
            )
        }
        row.update({k: run[k] for k in ("detected_calibrated", "calibrated_level") if k in run})
        row.update({k: ";".join(run[k]) for k in ("planted", "detected", "testable", "not_identifiable")})
        row.update({f"p_{k}": v for k, v in run["p_values"].items()})
        row.update({f"size_{k}": v for k, v in run["sizes"].items()})
        rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str]) -> None:
    if len(argv) < 2:
        raise SystemExit(__doc__)
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    merged = merge([json.loads(Path(p).read_text()) for p in argv[1:]])
    conf = merged["configuration"]
    bench.bench_table(merged).to_csv(out / f"{conf}.csv", index=False, float_format="%.4g")
    bench.power_table(merged).to_csv(out / f"{conf}_power.csv", index=False, float_format="%.4g")
    tables(merged["runs"]).to_csv(out / f"{conf}_tables.csv.gz", index=False, float_format="%.6g")
    (out / f"{conf}_summary.json").write_text(
        json.dumps({k: v for k, v in merged.items() if k != "runs"}, indent=1) + "\n"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
