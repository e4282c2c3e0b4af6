"""Snakemake's own CPU under its job-rate limiter's timespan: the default 100/1s against 1000/10s.

Every pass of Snakemake's scheduler loop starts a timer of the limiter's timespan that wakes the loop
again, and every finished job adds a pass, so the timers multiply with the finished jobs
(profiles/default/config.yaml, docs/choices.md "Snakemake's own CPU"). This script runs a workflow of
N jobs that only sleep (one root job, then N jobs waiting for 2 cores, as the 2PB jobs of the paper
configuration wait) under both timespans side by side, with the default profile's selector (greedy,
subsample 20), and writes each Snakemake process's CPU (getrusage of the child) and wall time.

Usage (any clone with the project's environment):

    .venv/bin/python reference/paper_scale/snakemake_timers.py --jobs 600 --sleep 0.5 -o snakemake_timers.csv
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from asphalt_nscd.io import write_csv

SNAKEFILE = """\
N = int(config["n_jobs"])
SLEEP = float(config["sleep_s"])
rule all:
    input: expand("out/{i}", i=range(N))
rule root:
    output: "root"
    shell: "touch {output}"
rule job:
    input: "root"
    output: "out/{i}"
    shell: "sleep {SLEEP}; touch {output}"
"""

#: variant -> --max-jobs-per-timespan (100/1s is Snakemake's default, passed explicitly)
VARIANTS = {"snakemake default (100/1s)": "100/1s", "profiles/default (1000/10s)": "1000/10s"}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=600, help="jobs waiting for the 2 cores (default 600)")
    parser.add_argument("--sleep", type=float, default=0.5, help="seconds each job sleeps (default 0.5)")
    parser.add_argument("-o", "--output", type=Path, required=True, help="CSV of the two runs")
    args = parser.parse_args(argv)
    snakemake = Path(sys.executable).with_name("snakemake")
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        running = {}
        for name, timespan in VARIANTS.items():
            work = Path(tmp) / str(len(running))
            work.mkdir()
            (work / "Snakefile").write_text(SNAKEFILE)
            cmd = [str(snakemake), "--cores", "2", "--quiet", "--workflow-profile", "none", "--scheduler", "greedy"]
            cmd += ["--scheduler-subsample", "20", "--max-jobs-per-timespan", timespan]
            cmd += ["--config", f"n_jobs={args.jobs}", f"sleep_s={args.sleep}"]
            with open(work / "snakemake.log", "w") as log:
                proc = subprocess.Popen(cmd, cwd=work, stdout=log, stderr=subprocess.STDOUT)
            running[proc.pid] = (name, timespan, proc, work, time.monotonic())
        while running:
            pid, status, usage = os.wait4(-1, 0)
            if pid not in running:
                continue
            name, timespan, proc, work, start = running.pop(pid)
            if os.waitstatus_to_exitcode(status) != 0:
                for _, _, other, _, _ in running.values():
                    other.terminate()
                sys.exit(f"snakemake ({name}) failed; its log:\n{(work / 'snakemake.log').read_text()[-3000:]}")
            rows[name] = {
                "variant": name,
                "max_jobs_per_timespan": timespan,
                "jobs": args.jobs,
                "sleep_s": args.sleep,
                "cpu_s": round(usage.ru_utime + usage.ru_stime, 2),
                "wall_s": round(time.monotonic() - start, 1),
            }
    table = pd.DataFrame([rows[name] for name in VARIANTS])
    table["cpu_ratio_to_default"] = (table["cpu_s"] / table["cpu_s"].iloc[0]).round(3)
    write_csv(table, args.output)
    print(table.to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
