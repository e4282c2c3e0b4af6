"""The leave-one-specimen-out interval's draw of the specimen level: variants tried on a development
seed, each scored on the same kept replicates (the folds refitted once, the loso rows scored again).

    M=results/lab/measured.csv   # make run's reduction of the shipped table (the same 90 rows as make table's)
    S="arrhenius, static=constant, vertical=off, refine=off, 2/decade"
    for first in 0 125; do
      .venv/bin/python reference/crossval/coverage.py $M --settings "$S" --replicates 125 --first $first \
          --seed 20261126 -o runs_$first.csv --keep keep_$first.pkl
    done
    .venv/bin/python reference/crossval/loso_variants.py $M keep_0.pkl keep_125.pkl --seed 20261126 \
        -o reference/crossval/loso_variants.csv

The interval (``asphalt_nscd.diagnosis.scores.loso_abs_interval``) is the observed error over the
percentiles of a simulated ratio whose spread depends on the proportions of the specimens' three
levels of scatter; the specimen level's mean square has 2 degrees of freedom with 3 specimens, so
how it is drawn sets the width. Variants (a replacement of ``scores.level_variances``, the percentiles
nominal, or the calibrated rule):

* ``calibrated``: the levels at their estimates, the percentiles calibrated by a second bootstrap level
  (prepivoting, ``scores.LOSO_CALIBRATION``; the shipped rule);
* ``drawn``: the specimen level's mean square drawn as MS dof / chi2_dof (the rule shipped before);
* ``plug_in``: every level at its estimate;
* ``sampling``: the specimen level's mean square drawn as MS chi2_dof / dof (its sampling law);
* ``gpq``: every mean square drawn as MS dof / chi2_dof and the levels their differences, the
  generalized pivotal quantities of the variance components (Weerahandi 1993, J. Am. Stat. Assoc.
  88, 899-905).
"""

from __future__ import annotations

import argparse
import contextlib
import pickle
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).parent))

import coverage  # noqa: E402
import summarize  # noqa: E402

from asphalt_nscd.diagnosis import scores  # noqa: E402
from asphalt_nscd.io import write_csv  # noqa: E402

SHIPPED = scores.level_variances


def _mean_squares(comp: dict, quantity: str) -> tuple:
    q = comp[quantity]
    ms, dof = q["ms"], q["dof"]
    n_T = len(comp["n_f"])
    n_f = float(np.mean(list(comp["n_f"].values())))
    m_u = ms["specimen"] if np.isfinite(ms["specimen"]) else 0.0
    fine_v = np.isfinite(ms["specimen_temperature"])
    m_v = ms["specimen_temperature"] if fine_v else ms["cell"]
    d_v = dof["specimen_temperature"] if fine_v else dof["cell"]
    return m_u, m_v, float(ms["cell"]), dof["specimen"], d_v, dof["cell"], n_T, n_f


def plug_in(comp: dict, quantity: str, n_sim: int = 0, seed: int = 0):
    return SHIPPED(comp, quantity)


def sampling(comp: dict, quantity: str, n_sim: int = 0, seed: int = 0):
    out = SHIPPED(comp, quantity)
    if out is None or n_sim <= 0:
        return out
    m_u, m_v, _, d_u, _, _, n_T, n_f = _mean_squares(comp, quantity)
    m_u = m_u * np.random.default_rng([seed, 13]).chisquare(d_u, n_sim) / d_u
    return {**out, "specimen": np.maximum(m_u - m_v, 0.0) / (n_T * n_f)}


def gpq(comp: dict, quantity: str, n_sim: int = 0, seed: int = 0):
    out = SHIPPED(comp, quantity)
    if out is None or n_sim <= 0:
        return out
    m_u, m_v, m_e, d_u, d_v, d_e, n_T, n_f = _mean_squares(comp, quantity)
    rng = np.random.default_rng([seed, 13])
    u = m_u * d_u / rng.chisquare(d_u, n_sim)
    v = m_v * d_v / rng.chisquare(d_v, n_sim)
    e = m_e * d_e / rng.chisquare(d_e, n_sim)
    return {
        "specimen": np.maximum(u - v, 0.0) / (n_T * n_f),
        "specimen_temperature": np.maximum(v - e, 0.0) / n_f,
        "cell": e,
    }


CALIBRATION = scores.LOSO_CALIBRATION

VARIANTS = {
    "calibrated": (None, "the levels at their estimates, the percentiles calibrated by prepivoting (shipped)"),
    "drawn": (SHIPPED, "the specimen level's mean square drawn as MS dof / chi2_dof (shipped before)"),
    "plug_in": (plug_in, "every level at its estimate"),
    "sampling": (sampling, "the specimen level's mean square drawn as MS chi2_dof / dof"),
    "gpq": (gpq, "every mean square drawn as MS dof / chi2_dof, the levels their differences (Weerahandi 1993)"),
}


@contextlib.contextmanager
def _rule(func):
    if func is not None:  # a draw of the levels at the nominal percentiles
        scores.level_variances, scores.LOSO_CALIBRATION = func, None
    try:
        yield
    finally:
        scores.level_variances, scores.LOSO_CALIBRATION = SHIPPED, CALIBRATION


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("measured")
    ap.add_argument("kept", nargs="+", help="pickles of coverage.py --keep")
    ap.add_argument("--seed", type=int, required=True, help="the seed the kept replicates were drawn with")
    ap.add_argument("--variants", nargs="+", choices=list(VARIANTS), help="score only these (default: all)")
    ap.add_argument("-o", "--output", required=True)
    a = ap.parse_args(argv)
    model = coverage.FittedModel(pd.read_csv(a.measured))
    kept: dict = {}
    for path in a.kept:
        with open(path, "rb") as fh:
            kept.update(pickle.load(fh))
    out = []
    only = a.variants or list(VARIANTS)
    for name, (func, description) in VARIANTS.items():
        if name not in only:
            continue
        rows = []
        with _rule(func):
            for i, (table, folds) in sorted(kept.items()):
                rng = np.random.default_rng([a.seed, i])
                model.simulate(rng)  # the truth's draws follow the table's, as in the run
                rows += [r for r in coverage.score(model, table, folds, rng, i) if r["scheme"] == "loso"]
        s = summarize.summarize(pd.DataFrame(rows).assign(true_bias=np.nan, bias_low=np.nan, bias_high=np.nan))
        out.append(s.drop(columns="bias_coverage_pct").assign(variant=name, description=description, seed=a.seed))
        print(name, s[["quantity", "coverage_pct"]].to_dict("records"), flush=True)
    frame = pd.concat(out, ignore_index=True)
    first = ["variant", "description", "seed"]
    write_csv(frame[first + [c for c in frame.columns if c not in first]], a.output)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
