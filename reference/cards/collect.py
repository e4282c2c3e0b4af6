"""Collect the material cards of the tables run with ``make table`` into ``cards.csv`` and
their per-cell errors into ``card_errors.csv``.

Reads every ``results/tables/<folder>-<table>/diagnosis/material_cards/prony.json`` (the last
complete run of each table, with its manifest) and writes one row per table and temperature
(and ``all``): the number of Prony terms, the stated tolerance and what was achieved against
the law, and the card's and the selected law's errors against the lab's replicate means as
written (|E*| as 100 |ln ratio| %, Phi in degrees; in-sample: the law was fitted to these
cells); ``card_errors.csv``: the card's ``card_errors.csv`` of every table, one row per measured
cell (the lab's mean, the card's and the selected law's values and errors), with the table's
name. Run from the repository root: ``.venv/bin/python reference/cards/collect.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd


def main(root: Path = Path("results/tables"), out: Path = Path(__file__).with_name("cards.csv")) -> int:
    rows, cells = [], []
    for card_path in sorted(root.glob("*/diagnosis/material_cards/prony.json")):
        folder = card_path.parents[2]
        manifest = json.loads((folder / "manifest.json").read_text())
        card = json.loads(card_path.read_text())
        sel = card["terms_selection"]
        errors = card_path.with_name("card_errors.csv")
        if errors.exists():
            cells.append(pd.read_csv(errors).assign(table=manifest["table"]))
        for loss in card["loss"]:
            rows.append(
                {
                    "table": manifest["table"],
                    "table_sha256": manifest["table_sha256"][:16],
                    "n_terms": sel["n_terms"],
                    "tolerance_E_pct": sel["tolerance"]["E_norm_pct"],
                    "tolerance_phase_deg": sel["tolerance"]["phase_deg"],
                    "card_vs_law_max_E_pct_cells": card["check"]["max_E_norm_difference_pct"],
                    "card_vs_law_max_phase_deg_cells": card["check"]["max_phase_difference_deg"],
                    "carries": card.get("carries"),
                    "card_law_fit": card.get("fit"),
                    "carries_selected_law": card["is_selected_law"],
                    "interconversion_max_residual": (card.get("interconversion") or {}).get("max_abs_residual"),
                    **loss,
                }
            )
    if not rows:
        print(f"error: no card under {root}/*/diagnosis/material_cards/ (run make table first)", file=sys.stderr)
        return 2
    pd.DataFrame(rows).to_csv(out, index=False, float_format="%.4g")
    print(f"{out}: {len(rows)} rows")
    if cells:
        frame = pd.concat(cells, ignore_index=True)
        frame = frame[["table"] + [c for c in frame.columns if c != "table"]]
        frame.to_csv(out.with_name("card_errors.csv"), index=False, float_format="%.6g")
    return 0


if __name__ == "__main__":
    sys.exit(main())
