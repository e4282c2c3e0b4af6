"""The resolution study's level summary and fit from its committed per-sample rows, without the
samples: ``asphalt_nscd.harmonic.resolution.resolution_summary`` on ``resolution.csv`` (the rows
``asphalt-nscd harmonic-resolution`` wrote), as that command writes them.

    python resolution_fit.py reference/paper_scale

Writes ``resolution_summary.csv`` and ``resolution_fits.csv`` beside ``resolution.csv``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd

from asphalt_nscd.harmonic.resolution import resolution_summary
from asphalt_nscd.io import write_csv


def main(argv: list[str]) -> None:
    if len(argv) != 1:
        raise SystemExit(__doc__)
    d = Path(argv[0])
    levels, fits = resolution_summary(pd.read_csv(d / "resolution.csv"))
    write_csv(levels, d / "resolution_summary.csv")
    write_csv(fits, d / "resolution_fits.csv")


if __name__ == "__main__":
    main(sys.argv[1:])
