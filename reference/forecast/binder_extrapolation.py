"""The binder's extrapolation compared: shift law (A-VTS viscosity, WLF, Arrhenius) and CAM's glassy
modulus (1 GPa, or fitted within 0.3-3 GPa), on the binders' own isotherms and held out by mix.

    python reference/forecast/binder_extrapolation.py -o reference/forecast/binder_extrapolation.csv \\
        --isotherms reference/forecast/binder_extrapolation_isotherms.csv \\
        --summary reference/forecast/binder_extrapolation_summary.csv

Reads ``data/binder_mix/mixes_35.tsv`` with its sidecar and checks every binder point
(``asphalt_nscd.forecast.binder``). Writes:

* ``--isotherms``: per binder and variant, the fit on its passing points (``position`` ``full``:
  its glassy modulus, the rung the forecast's fit ladder takes under the variant, its log10 shift
  factor at the binder's coldest temperature) and each passing temperature left out in turn while
  2 or more stay (``asphalt_nscd.forecast.binder_study.isotherm_cases``);
* ``-o``: every published formula (published and recalibrated coefficients) held out by mix
  (leave one mix out, the binder through its curve under each variant, read at the table's binder
  frequency), scored per temperature and group (``asphalt_nscd.forecast.validation.score``; the
  groups ``binder_measured`` / ``binder_extrapolated`` by the default curves, so that every variant
  is judged on the same cells), on every mix (``mixes`` ``all``) and on the mixes whose binder
  carries every variant on its passing points (``passing_fit``);
* ``--summary``: per variant its curves (``check`` ``curves``: binders fitted on their passing
  points, glassy moduli, log10 shift factors at the coldest temperature), the isotherm errors
  (``isotherm``, by position, with the difference to the default variant on the cases both fit)
  and, per formula, group and temperature, the held-out errors with the per-mix difference to the
  default variant (``held_out``; empty for the default itself).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from asphalt_nscd.forecast import binder_study as S
from asphalt_nscd.forecast.baselines import MODELS
from asphalt_nscd.forecast.binder import GLASSY_BOUNDS_PA, check_points
from asphalt_nscd.forecast.models import binder_points
from asphalt_nscd.forecast.validation import (
    COEFFICIENTS,
    Baseline,
    binder_extrapolated,
    binder_ids,
    cross_validate,
    mix_folds,
    score,
    with_binder_route,
)
from asphalt_nscd.io import write_csv
from asphalt_nscd.lab.matched import read_matched

ROOT = Path(__file__).resolve().parents[2]
TABLE = ROOT / "data" / "binder_mix" / "mixes_35.tsv"
GROUPS = ("all", "binder_measured", "binder_extrapolated")


def held_out(matched, checked, ids, flag, shift, glassy):
    """(held-out rows, one row per binder: its ladder rung, glassy modulus and log10 shift factor at
    its coldest temperature) of every published formula under one variant."""
    curves, fits = S.variant_curves(checked, shift, glassy)
    coldest = checked.groupby("binder")["temperature_C"].min()
    fits["log10_aT_coldest"] = [float(curves[b].log_shift(coldest[b])) for b in fits["binder"]]
    table = with_binder_route(matched, curves, ids, "curve").assign(binder_extrapolated=flag)
    models = [Baseline(m, c) for m in MODELS for c in COEFFICIENTS]
    rows, _ = cross_validate(table, models, ids, mix_folds(matched["mix_id"].unique()), "curve")
    return rows.assign(label=rows["model"] + "_" + rows["coefficients"]), fits


def curve_rows(fits: pd.DataFrame) -> pd.DataFrame:
    """Per variant: binders, those fitted on their passing points, the glassy moduli (range, at a
    bound) and the log10 shift factors at the binders' coldest temperatures (range)."""
    at_bound = np.zeros(len(fits), bool)
    fitted = (fits["glassy"] == "fitted").to_numpy()
    for b in GLASSY_BOUNDS_PA:
        at_bound |= fitted & (np.abs(np.log10(fits["Gg_Pa"].to_numpy(float) / b)) < 1e-3)
    g = fits.assign(at_bound=at_bound, on_passing=fits["rung"] == "passed").groupby(["shift", "glassy"], sort=False)
    out = g.agg(
        n_binders=("binder", "size"),
        n_passing_rung=("on_passing", "sum"),
        Gg_min_Pa=("Gg_Pa", "min"),
        Gg_max_Pa=("Gg_Pa", "max"),
        n_Gg_at_bound=("at_bound", "sum"),
        log10_aT_coldest_min=("log10_aT_coldest", "min"),
        log10_aT_coldest_max=("log10_aT_coldest", "max"),
    )
    return out.reset_index().assign(check="curves")


def cells(rows: pd.DataFrame, group: str) -> pd.DataFrame:
    """The held-out rows of a group of :data:`GROUPS`."""
    if group == "all":
        return rows
    return rows[rows["binder_extrapolated"].astype(bool) == (group == "binder_extrapolated")]


def summary(iso: pd.DataFrame, rows: dict, scores: pd.DataFrame, fits: pd.DataFrame) -> pd.DataFrame:
    """The summary table (module docstring)."""
    iso = iso.assign(check="isotherm")
    base = rows[S.VARIANTS[0]]
    frames = []
    for (shift, glassy), r in rows.items():
        if (shift, glassy) == S.VARIANTS[0]:
            continue
        for group in GROUPS:
            d = S.paired_difference(cells(base, group), cells(r, group)).assign(shift=shift, glassy=glassy, group=group)
            frames.append(d)
    d = pd.concat(frames, ignore_index=True)
    s = scores[scores["mixes"] == "all"].drop(columns=["n_cells", "confidence"])
    keys = ["shift", "glassy", "group", "model", "coefficients", "temperature_C"]
    held = s.merge(d.drop(columns=["n_mixes"]), on=keys, how="left", validate="one_to_one")
    held = held.assign(check="held_out", label=held["model"] + "_" + held["coefficients"])
    return pd.concat([curve_rows(fits), iso, held], ignore_index=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=Path, required=True)
    ap.add_argument("--isotherms", type=Path, required=True)
    ap.add_argument("--summary", type=Path, required=True)
    args = ap.parse_args(argv)
    matched = read_matched(TABLE)
    ids = binder_ids(matched)
    checked = check_points(binder_points(matched, ids).drop(columns="mixes"))
    cases = S.isotherm_cases(checked)
    default_curves, _ = S.variant_curves(checked, *S.VARIANTS[0])
    flag = binder_extrapolated(matched, default_curves, ids)
    rows, fits, frames = {}, [], []
    for shift, glassy in S.VARIANTS:
        rows[(shift, glassy)], f = held_out(matched, checked, ids, flag, shift, glassy)
        fits.append(f)
    fits = pd.concat(fits, ignore_index=True)
    on_passing = fits.groupby("binder")["rung"].apply(lambda r: bool((r == "passed").all()))
    passing_mixes = ids[ids.map(on_passing)].index
    for (shift, glassy), r in rows.items():
        for name, sel in (("all", r), ("passing_fit", r[r["mix_id"].isin(passing_mixes)])):
            frames.append(score(sel).assign(shift=shift, glassy=glassy, mixes=name))
    scores = pd.concat(frames, ignore_index=True)
    scores = scores[~scores["group"].isin(["binder_seen", "binder_unseen"])]
    scores = scores[["shift", "glassy", "mixes", *[c for c in scores.columns if c not in ("shift", "glassy", "mixes")]]]
    cases = cases.merge(fits[["binder", "shift", "glassy", "rung"]], on=["binder", "shift", "glassy"], how="left")
    cases.loc[cases["position"] != "full", "rung"] = np.nan
    iso = S.summarize_isotherms(cases)
    write_csv(cases.rename(columns={"rung": "ladder_rung"}), args.isotherms, float_format="%.6g")
    write_csv(scores, args.output, float_format="%.6g")
    write_csv(summary(iso, rows, scores, fits), args.summary, float_format="%.6g")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
