"""Append the wall time and CPU of one invocation, measured by ``/usr/bin/time -v``, to
``timings.csv`` (the timings the README and the reference pages quote).

    /usr/bin/time -v -o TIME make table TABLE=data/measured/uiuc_fdmix1_utm/complex_modulus.csv
    .venv/bin/python reference/timings/add.py TIME --what "make table, shipped UIUC table" \\
        --command "make table TABLE=..." --date 2026-11-26 --context "venv set up, 2 cores shared"

Columns: what, date, command, commit (that the run used), wall_s, cpu_s (user + system of
the invocation and every process it waited for), max_rss_mb, context.
"""

from __future__ import annotations

import argparse
import re
import subprocess
from pathlib import Path

import pandas as pd

OUT = Path(__file__).with_name("timings.csv")


def parse_time_file(text: str) -> dict:
    """Wall time (s), CPU (s) and peak RSS (MB) of a ``/usr/bin/time -v`` report."""

    def field(name: str) -> str:
        m = re.search(rf"^\s*{re.escape(name)}:\s*(.+)$", text, flags=re.M)
        if m is None:
            raise SystemExit(f"time file: no line '{name}'")
        return m.group(1).strip()

    parts = [float(x) for x in field("Elapsed (wall clock) time (h:mm:ss or m:ss)").split(":")]
    wall = sum(p * 60.0**k for k, p in enumerate(reversed(parts)))
    cpu = float(field("User time (seconds)")) + float(field("System time (seconds)"))
    rss = float(field("Maximum resident set size (kbytes)")) / 1024.0
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "max_rss_mb": round(rss, 1)}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("time_file")
    ap.add_argument("--what", required=True)
    ap.add_argument("--command", required=True)
    ap.add_argument("--date", required=True, help="YYYY-MM-DD of the run")
    ap.add_argument("--context", default="", help="what else ran on the machine, setup state")
    ap.add_argument("--commit", help="commit the run used (default: the working tree's HEAD)")
    args = ap.parse_args(argv)
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    commit = args.commit or head
    row = {"what": args.what, "date": args.date, "command": args.command, "commit": commit}
    row.update(parse_time_file(Path(args.time_file).read_text()))
    row["context"] = args.context
    old = pd.read_csv(OUT) if OUT.exists() else pd.DataFrame()
    pd.concat([old, pd.DataFrame([row])], ignore_index=True).to_csv(OUT, index=False)


if __name__ == "__main__":
    main()
