"""The slowest tests of one ``make test`` run, from the ``--durations=20`` block pytest prints
(``make test`` passes it), as a table.

    bash .ci/run > ci.log 2>&1
    .venv/bin/python reference/timings/slowest_tests.py ci.log --date 2026-11-26 --commit abc1234 \\
        -o reference/timings/slowest_tests.csv

Columns: date, commit, rank, seconds, phase (call, setup or teardown: a module fixture's time is
the setup of its first test), test.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pandas as pd

LINE = re.compile(r"^\s*(\d+(?:\.\d+)?)s\s+(call|setup|teardown)\s+(\S.*)$")


def parse(text: str) -> pd.DataFrame:
    """Rows ``seconds, phase, test`` of the durations block of a pytest log (SystemExit if none)."""
    start = text.find("slowest 20 durations")
    if start < 0:
        raise SystemExit("no 'slowest 20 durations' block in the log (run make test, which passes --durations=20)")
    rows = []
    for line in text[start:].splitlines()[1:]:
        m = LINE.match(line)
        if m is None:
            if rows:
                break
            continue
        rows.append({"seconds": float(m.group(1)), "phase": m.group(2), "test": m.group(3).strip()})
    if not rows:
        raise SystemExit("the durations block lists no test")
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log")
    ap.add_argument("--date", required=True)
    ap.add_argument("--commit", required=True)
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    t = parse(Path(a.log).read_text(errors="replace"))
    t.insert(0, "rank", range(1, len(t) + 1))
    t.insert(0, "commit", a.commit)
    t.insert(0, "date", a.date)
    tmp = Path(a.output).with_suffix(".tmp")
    t.to_csv(tmp, index=False)
    tmp.replace(a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
