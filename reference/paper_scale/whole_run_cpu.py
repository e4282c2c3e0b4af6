"""CPU of a whole workflow run from its Snakemake benchmarks, with the benchmarks' sampling loss.

Snakemake's ``benchmark:`` records the CPU of a job's processes as last sampled by psutil: every
second for the first 30 samples, then every 30 s. The CPU after the last sample is lost: up to
1 s for a short job, up to 30 s for a long one. A 2PB job's row holds its own CPU
(``cpu_time_s``, from the job's start to its end), which misses only the process start-up;
measured with ``/usr/bin/time`` on three jobs of the paper configuration (an orbit job and two
time-domain jobs, 2026-11-25): 1.41-1.55 s.

Usage, from the run's working directory:

    .venv/bin/python /path/to/reference/paper_scale/whole_run_cpu.py [--start-up 1.45] [-o OUT.csv]

Writes one row per group (2PB jobs; every other rule's jobs), with the benchmarks' sum, the
corrected sum (2PB jobs: the larger of the benchmark and the row's CPU + start-up) and an upper
bound (every other job loses its whole sampling interval: 1 s below 30 s of wall time, else 30 s).
"""

from __future__ import annotations

import argparse
import glob
from pathlib import Path

import pandas as pd


def benchmark(path: str) -> tuple[float, float]:
    """(CPU s, wall s) of the last record of a Snakemake benchmark TSV."""
    table = pd.read_csv(path, sep="\t")
    return float(table["cpu_time"].iloc[-1]), float(table["s"].iloc[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start-up", type=float, default=1.45, help="2PB process CPU outside the row's own, s")
    parser.add_argument("-o", "--output", type=Path, default=None, help="CSV of the groups (default: print only)")
    args = parser.parse_args()
    rows = {"2PB jobs (rule run_2pb)": [0, 0.0, 0.0, 0.0], "every other rule": [0, 0.0, 0.0, 0.0]}
    for path in sorted(glob.glob("benchmarks/**/*.tsv", recursive=True)):
        cpu, wall = benchmark(path)
        if path.startswith("benchmarks/sim/"):
            record = Path("results") / Path(path).relative_to("benchmarks").with_suffix(".csv")
            own = float(pd.read_csv(record)["cpu_time_s"].iloc[0]) + args.start_up
            r = rows["2PB jobs (rule run_2pb)"]
            r[0] += 1
            r[1] += cpu
            r[2] += max(cpu, own)
            r[3] += max(cpu, own)
        else:
            r = rows["every other rule"]
            r[0] += 1
            r[1] += cpu
            r[2] += cpu
            r[3] += cpu + (30.0 if wall > 30.0 else 1.0)
    table = pd.DataFrame(
        [
            {"what": k, "n_jobs": v[0], "benchmarks_cpu_s": v[1], "corrected_cpu_s": v[2], "upper_cpu_s": v[3]}
            for k, v in rows.items()
        ]
    )
    total = table.drop(columns="what").sum()
    table.loc[len(table)] = {"what": "the whole run", **total.to_dict()}
    table[["benchmarks_cpu_s", "corrected_cpu_s", "upper_cpu_s"]] = table[
        ["benchmarks_cpu_s", "corrected_cpu_s", "upper_cpu_s"]
    ].round(0)
    print(table.to_string(index=False))
    if args.output is not None:
        table.to_csv(args.output, index=False)


if __name__ == "__main__":
    main()
