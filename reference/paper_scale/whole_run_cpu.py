"""CPU of a whole workflow run: every job's exact CPU record, Snakemake's sampled benchmarks, and
the whole invocation under ``/usr/bin/time``.

Every job's command appends its exact CPU to ``benchmarks/process_cpu.jsonl``
(``asphalt_nscd.cli.cpu_record``: ``getrusage`` of the process and the workers it waited for,
start-up and imports included; only the interpreter's exit after the record, about 0.1 s, is
missing). Snakemake's ``benchmark:`` records are the CPU of a job's processes as last sampled by
psutil: every second for the first 30 samples, then every 30 s, so a job loses the CPU after its
last sample (up to 1 s for a short job, 30 s for a long one). ``/usr/bin/time -v`` of the
invocation (``--time-file``) counts everything: the jobs, their exits and Snakemake itself.

Usage, from the run's working directory:

    .venv/bin/python /path/to/reference/paper_scale/whole_run_cpu.py [--time-file TIME ...] [-o OUT.csv]

Writes one row per command (its jobs' exact CPU; a job run more than once counts its last
successful run), the sum of the records, the CPU of the other records (jobs that failed or were
stopped, and earlier runs of a job), the sum of the benchmarks and, with ``--time-file``, the
invocations' total and what is outside every record (Snakemake, the interpreters' exits). A run
resumed by Snakemake after a stop gives one ``--time-file`` per invocation.
"""

from __future__ import annotations

import argparse
import glob
import json
import re
from pathlib import Path

import pandas as pd
from collect import benchmark_cpu  # this folder's collect.py: one reader of the benchmark files

from asphalt_nscd.plan import CPU_LOG as _CPU_LOG  # where the workflow's jobs append their records

CPU_LOG = Path(_CPU_LOG)


def job_records(path: Path) -> tuple[pd.DataFrame, int, float]:
    """The last successful record of each distinct command line in the CPU log ``path``, as a table
    (command, cpu_s, wall_s, max_rss_mb), how many other records (failed, stopped or earlier runs)
    it holds, and their CPU seconds."""
    last: dict[tuple, dict] = {}
    n = 0
    cpu_all = 0.0
    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        n += 1
        rec = json.loads(line)
        cpu_all += rec["user_s"] + rec["system_s"]
        if rec["status"] == 0:
            last[tuple(rec["argv"])] = rec
    rows = [
        {
            "command": argv[0] if argv else "",
            "cpu_s": rec["user_s"] + rec["system_s"],
            "wall_s": rec["wall_s"],
            "max_rss_mb": rec["max_rss_mb"],
        }
        for argv, rec in last.items()
    ]
    jobs = pd.DataFrame(rows, columns=["command", "cpu_s", "wall_s", "max_rss_mb"])
    return jobs, n - len(last), cpu_all - float(jobs["cpu_s"].sum())


def time_total(path: Path) -> float:
    """User + system seconds of a ``/usr/bin/time -v`` report."""
    text = path.read_text()
    seconds = [float(re.search(rf"{kind} time \(seconds\): ([0-9.]+)", text).group(1)) for kind in ("User", "System")]
    return sum(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--time-file",
        type=Path,
        action="append",
        default=[],
        help="/usr/bin/time -v report of an invocation (repeat for a resumed run)",
    )
    parser.add_argument("-o", "--output", type=Path, default=None, help="CSV of the rows (default: print only)")
    args = parser.parse_args()
    rows = []
    if CPU_LOG.exists():
        jobs, other, other_cpu = job_records(CPU_LOG)
        per_command = jobs.groupby("command").agg(n_jobs=("cpu_s", "size"), cpu_s=("cpu_s", "sum"))
        for command, r in per_command.sort_values("cpu_s", ascending=False).iterrows():
            rows.append({"what": f"asphalt-nscd {command}", "n_jobs": int(r["n_jobs"]), "cpu_s": r["cpu_s"]})
        records = float(jobs["cpu_s"].sum())
        rows.append({"what": "every job (exact records)", "n_jobs": len(jobs), "cpu_s": records})
        if other:
            rows.append(
                {"what": "other records: failed, stopped or repeated runs", "n_jobs": other, "cpu_s": other_cpu}
            )
        all_records = records + other_cpu
    else:
        records = all_records = None
    bench = [benchmark_cpu(Path(p)) for p in sorted(glob.glob("benchmarks/**/*.tsv", recursive=True))]
    rows.append({"what": "every job (Snakemake benchmarks, sampled)", "n_jobs": len(bench), "cpu_s": sum(bench)})
    if args.time_file:
        total = sum(time_total(path) for path in args.time_file)
        what = "the whole invocation" if len(args.time_file) == 1 else f"the {len(args.time_file)} invocations"
        rows.append({"what": f"{what} (/usr/bin/time)", "n_jobs": None, "cpu_s": total})
        if all_records is not None:
            rows.append(
                {
                    "what": "outside every record: Snakemake, interpreter exits",
                    "n_jobs": None,
                    "cpu_s": total - all_records,
                }
            )
    table = pd.DataFrame(rows, columns=["what", "n_jobs", "cpu_s"])
    table["cpu_s"] = table["cpu_s"].round(1)
    table["core_hours"] = (table["cpu_s"] / 3600.0).round(3)
    table["n_jobs"] = table["n_jobs"].astype("Int64")
    print(table.to_string(index=False))
    if args.output is not None:
        table.to_csv(args.output, index=False)


if __name__ == "__main__":
    main()
