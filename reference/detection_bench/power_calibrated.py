"""Power of the complete procedure along a power curve: the planted tables of one artifact at
chosen sizes, each calibrated on itself as the workflow calibrates a table.

    python power_calibrated.py DIR DESIGN --artifact temperature_offset --sizes 3,4,6 [--per-size 10]
        [--tables 200] [--jobs 1]

Reads ``DIR/<design>_summary.json`` and ``DIR/<design>_tables.csv.gz`` (``collect.py``); the
power-curve tables (kind ``power:<artifact>``) are regenerated from the summary's plan
(:func:`asphalt_nscd.diagnosis.bench.plan`, its base seed), the first ``--per-size`` of each size
(they cycle over the truth families; ``--per-size`` one count or one per size). A table the nominal procedure names the artifact on is
calibrated on itself (:func:`asphalt_nscd.diagnosis.bench.calibrate_alarms`'s step: both nulls,
``--tables`` bootstrap tables of each, curtailed once decided) and searched again at the
calibrated level; a table without a nominal detection has none after calibration. Writes
``DIR/<design>_power_calibrated.csv``: per size, tables, nominal and calibrated detections, the
calibrated rate and its one-sided 95 % lower bound; each table's calibration is kept in
``DIR/<design>_power_calibration.jsonl`` as it ends (a stopped run resumes; a line of another
number of tables or level rule is not read back).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pandas as pd

from asphalt_nscd.diagnosis import bench, calibration
from asphalt_nscd.io import read_json_lines, write_csv


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("design", choices=sorted(bench.CONFIGURATIONS))
    ap.add_argument("--artifact", required=True, choices=sorted(bench.POWER_SIZES))
    ap.add_argument("--sizes", required=True, help="sizes of the power curve, comma-separated (its size key's unit)")
    ap.add_argument(
        "--per-size",
        default="10",
        help="planted tables per size: one count, or one per size, comma-separated (default 10)",
    )
    ap.add_argument("--tables", type=int, default=200, help="bootstrap tables per calibration (default 200)")
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    args = ap.parse_args(argv)
    if args.tables < calibration.min_tables():
        ap.error(
            f"--tables: at least {calibration.min_tables()} bootstrap tables (fewer can name nothing), got {args.tables}"
        )
    d, conf = args.dir, args.design
    summary = json.loads((d / f"{conf}_summary.json").read_text())
    tables = pd.read_csv(d / f"{conf}_tables.csv.gz")
    sizes = [float(s) for s in args.sizes.split(",")]
    counts = [int(n) for n in str(args.per_size).split(",")]
    if len(counts) not in (1, len(sizes)):
        raise SystemExit(f"--per-size: one count or one per size ({len(sizes)}), got {args.per_size}")
    per_size = dict(zip(sizes, counts * len(sizes) if len(counts) == 1 else counts))
    kind = f"power:{args.artifact}"
    cases = bench.plan(
        summary["base_seed"],
        summary["families"],
        0,
        0,
        summary["effect_scale"],
        conf,
        int(summary["power_tables_per_size"]),
    )
    chosen = [
        c for c in cases if c["kind"] == kind and c["power_size"] in sizes and c["index"] < per_size[c["power_size"]]
    ]
    missing = sorted(set(sizes) - {c["power_size"] for c in chosen})
    if missing:
        raise SystemExit(
            f"--sizes: {missing} not on the {args.artifact} power curve {bench.POWER_SIZES[args.artifact]}"
        )
    committed = {
        (r["kind"], float(r["power_size"]), int(r["index"])): r for _, r in tables.iterrows() if r["kind"] == kind
    }
    checkpoint = d / f"{conf}_power_calibration.jsonl"
    done = {
        (rec["power_size"], rec["index"], rec["seed"]): rec
        for rec in read_json_lines(checkpoint, "power record", ("power_size", "index", "seed", "n_tables"))
        if bench.is_current(rec, args.tables)
    }
    rows = []
    for c in chosen:
        ref = committed[(kind, c["power_size"], c["index"])]
        if int(ref["seed"]) != c["seed"]:
            raise SystemExit(f"{kind} #{c['index']} at {c['power_size']}: seed differs from {conf}_tables.csv.gz")
        key = (c["power_size"], c["index"], c["seed"])
        if key not in done:
            nominal = bench.run_case(c, summary["alpha"])
            rec = {
                "power_size": c["power_size"],
                "index": c["index"],
                "seed": c["seed"],
                "family": c["family"],
                **bench.checkpoint_tag(args.tables),
                "min_p": nominal["min_p"],
                "nominal": nominal["detected"],
            }
            if args.artifact in nominal["detected"]:
                out = bench._calibrated_level((c, summary["alpha"], args.tables, nominal["min_p"]))
                rec |= {
                    "calibrated_level": out["level"],
                    "binding_null": out["binding_null"],
                    "null_levels": out["null_levels"],
                    "cpu_s": out["cpu_seconds"],
                    "calibrated": bench._named_at(c, summary["alpha"], out),
                }
            else:
                rec |= {"calibrated": [], "cpu_s": 0.0}
            with open(checkpoint, "a") as fh:
                fh.write(json.dumps(rec) + "\n")
            done[key] = rec
            print(
                f"{args.artifact} {c['power_size']:g} #{c['index']} ({c['family']}): nominal "
                f"{args.artifact in rec['nominal']}, calibrated {args.artifact in rec['calibrated']}",
                flush=True,
            )
        rows.append(done[key])
    per = pd.DataFrame(rows)
    out = []
    for size, g in per.groupby("power_size"):
        k = int(sum(args.artifact in x for x in g["calibrated"]))
        out.append(
            {
                "configuration": conf,
                "artifact": args.artifact,
                "size_key": bench.POWER_SIZES[args.artifact][0],
                "size": size,
                "n": len(g),
                "detected_nominal": int(sum(args.artifact in x for x in g["nominal"])),
                "detected_calibrated": k,
                "detection_rate_calibrated": k / len(g),
                "detection_lower_95": bench.lower_bound(k, len(g)),
                "binding_maxwell": int((g.get("binding_null", pd.Series(dtype=str)) == "maxwell").sum()),
                "cpu_s": float(g["cpu_s"].sum()),
            }
        )
    write_csv(pd.DataFrame(out), d / f"{conf}_power_calibrated.csv")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
