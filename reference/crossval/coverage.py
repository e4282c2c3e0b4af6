"""Coverage of the held-out errors' 95 % intervals, measured by simulation from a table's fitted
model with the law refitted inside every replicate.

The fitted model of the measured table: its cell means (mean ln|E*| and mean Phi of the
specimens) as the mix's true means mu_c, and the specimens' scatter in the three nested levels
of ``asphalt_nscd.diagnosis.scores.nested_components`` (a specimen level u_s, a
specimen-isotherm level v_s,T and cell scatter e_s,c; variances from the expected mean
squares, floored at 0). Each replicate draws a table of the same design (the same specimens,
temperatures and frequencies) from it, runs ``asphalt-nscd crossval``'s folds on it with the
law's settings fixed at the given ones (``--settings``; the law is refitted in every fold, its
settings are not chosen again and the artifact search is not run: on the shipped table it
names no artifact), scores them with ``scores.summarize`` as the command does, and compares
each 95 % interval with the truth of that replicate:

* lofo and loto, absolute errors: the error of the replicate's held-out predictions against
  the mix, mean_c |pred_c - mu_c| over the interpolated cells (pooled, and per temperature);
* loso: the error of a fold's law (fitted on the other specimens) against a new specimen of
  the mix, E mean_c |pred_c - y_new,c|, averaged over the folds (Monte Carlo over new
  specimens drawn from the model);
* signed errors: the mean of pred_c - mu_c (lofo, loto).

    python coverage.py MEASURED.csv --settings "arrhenius, static=constant" --replicates 1000 \
        --seed 20261126 -o runs.csv [--first 0]

Writes one row per replicate, scheme, quantity and temperature (``pooled``: the interpolated
cells together) with the observed error, the interval and the truth; ``summarize.py`` turns the
rows into the coverage table. A replicate's numbers depend on ``--seed`` and its index only, so
runs of index ranges (``--first``) concatenate into one run.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import pandas as pd

from asphalt_nscd.diagnosis import crossval as cv
from asphalt_nscd.diagnosis import scores
from asphalt_nscd.rheology.extended import LawSettings

SCHEMES = ("lofo", "loto", "loso")
#: new specimens of the Monte Carlo truth of a loso fold
LOSO_NEW_SPECIMENS = 2000


def parse_settings(text: str) -> LawSettings:
    """``"arrhenius, static=constant, vertical=off, refine=off, 2/decade"`` (the law JSON's
    ``selection.chosen_label``; omitted keys take their defaults) as LawSettings."""
    parts = [p.strip() for p in text.split(",") if p.strip()]
    kw: dict = {"shift": parts[0]}
    for p in parts[1:]:
        if p.endswith("/decade"):
            kw["per_decade"] = float(p.split("/")[0])
            continue
        key, _, value = p.partition("=")
        if key == "static":
            kw["static"] = value
        elif key == "vertical":
            kw["vertical"] = value == "on"
        elif key == "refine":
            kw["refine"] = None if value == "off" else float(value)
        else:
            raise SystemExit(f"--settings: unknown key {key!r} in {text!r}")
    return LawSettings(**kw)


class FittedModel:
    """The measured table's fitted model (module docstring)."""

    def __init__(self, table: pd.DataFrame):
        self.table = table.reset_index(drop=True)
        spec = scores.specimen_values(self.table)
        comp = scores.nested_components(spec)
        means = spec.groupby(level=["T", "f"]).mean()
        self.mu = {q: means[q].to_dict() for q in ("lnE", "phase")}
        n_T = len(comp["n_f"])
        n_f = float(np.mean(list(comp["n_f"].values())))
        self.sd = {}
        for q in ("lnE", "phase"):
            ms = comp[q]["ms"]
            se2 = ms["cell"]
            sv2 = max((ms["specimen_temperature"] - ms["cell"]) / n_f, 0.0)
            su2 = max((ms["specimen"] - ms["specimen_temperature"]) / (n_T * n_f), 0.0)
            self.sd[q] = {"specimen": su2**0.5, "specimen_temperature": sv2**0.5, "cell": se2**0.5}
        self.specimens = sorted(self.table["specimen"].astype(str).unique())
        self.temperatures = sorted(self.table["temperature_C"].round(6).unique())
        T = self.table["temperature_C"].round(6).to_numpy(float)
        f = self.table["frequency_Hz"].to_numpy(float)
        self.keys = list(zip(T, f))
        self.s_idx = np.array([self.specimens.index(str(s)) for s in self.table["specimen"]])
        self.t_idx = np.searchsorted(self.temperatures, T)

    def effects(self, rng: np.random.Generator, q: str, n_specimens: int) -> tuple:
        """(u (n,), v (n, n_T)) of ``n_specimens`` specimens."""
        sd = self.sd[q]
        u = rng.normal(0.0, sd["specimen"], n_specimens)
        v = rng.normal(0.0, sd["specimen_temperature"], (n_specimens, len(self.temperatures)))
        return u, v

    def simulate(self, rng: np.random.Generator) -> pd.DataFrame:
        """A table of the design drawn from the model."""
        out = self.table.copy()
        for q, col in (("lnE", "E_norm_MPa"), ("phase", "phase_deg")):
            u, v = self.effects(rng, q, len(self.specimens))
            e = rng.normal(0.0, self.sd[q]["cell"], len(out))
            y = np.array([self.mu[q][k] for k in self.keys]) + u[self.s_idx] + v[self.s_idx, self.t_idx] + e
            out[col] = np.exp(y) if q == "lnE" else y
        return out

    def truth(self, q: str, T, f) -> np.ndarray:
        return np.array([self.mu[q][(round(float(a), 6), float(b))] for a, b in zip(T, f)])


def _held(rows: pd.DataFrame, interp_only: bool = True) -> pd.DataFrame:
    h = rows[(rows["kind"] == "held_out") & (rows["model"] == "extended_law") & rows["computable"].astype(bool)]
    return h[~h["extrapolation"].astype(bool)] if interp_only else h


def _errors(model: FittedModel, h: pd.DataFrame) -> dict:
    """Errors of held-out predictions against the mix: {'logE': 100 (ln pred - mu), 'phase': ...}."""
    T, f = h["temperature_C"].to_numpy(float), h["frequency_Hz"].to_numpy(float)
    return {
        "logE": 100.0 * (np.log(h["E_norm_MPa_predicted"].to_numpy(float)) - model.truth("lnE", T, f)),
        "phase": h["phase_deg_predicted"].to_numpy(float) - model.truth("phase", T, f),
    }


def _loso_truth(model: FittedModel, rows: pd.DataFrame, rng: np.random.Generator) -> dict:
    """E over new specimens of a fold's mean absolute error, averaged over the folds."""
    h = _held(rows, interp_only=False)
    out = {"logE": [], "phase": []}
    for _, g in h.groupby("fold"):
        T, f = g["temperature_C"].to_numpy(float), g["frequency_Hz"].to_numpy(float)
        t_idx = np.searchsorted(model.temperatures, np.round(T, 6))
        for q, key, pred, scale in (
            ("lnE", "logE", np.log(g["E_norm_MPa_predicted"].to_numpy(float)), 100.0),
            ("phase", "phase", g["phase_deg_predicted"].to_numpy(float), 1.0),
        ):
            u, v = model.effects(rng, q, LOSO_NEW_SPECIMENS)
            e = rng.normal(0.0, model.sd[q]["cell"], (LOSO_NEW_SPECIMENS, len(g)))
            y = model.truth(q, T, f)[None, :] + u[:, None] + v[:, t_idx] + e
            out[key].append(scale * float(np.mean(np.abs(pred[None, :] - y))))
    return {k: float(np.mean(v)) for k, v in out.items()}


def replicate(
    model: FittedModel,
    options: cv.Options,
    seed: int,
    index: int,
    keep: dict | None = None,
    schemes: tuple = SCHEMES,
) -> list[dict]:
    """One replicate's rows (module docstring) of ``schemes`` (a scheme's rows do not depend on
    the others'); ``keep``: a dict that receives the replicate's table and fold rows (to score them again)."""
    rng = np.random.default_rng([seed, index])
    table = model.simulate(rng)
    folds = {scheme: cv.crossval(table, scheme, options).rows for scheme in schemes}
    if keep is not None:
        keep[index] = (table, folds)
    return score(model, table, folds, rng, index, schemes)


def score(
    model: FittedModel,
    table: pd.DataFrame,
    folds: dict,
    rng: np.random.Generator,
    index: int,
    schemes: tuple = SCHEMES,
) -> list[dict]:
    """The rows of one replicate from its table and fold rows (of ``schemes``; the loso truth's
    draws follow the table's whatever the schemes, only loso draws)."""
    out = []
    for scheme in schemes:
        rows = folds[scheme]
        # only the rows scored here (the other groups' intervals cost time and are not read)
        summ = scores.summarize(rows[(rows["kind"] == "held_out") & (rows["model"] == "extended_law")], table)
        summ = summ[(summ["kind"] == "held_out") & (summ["model"] == "extended_law") & ~summ["extrapolation"]]
        h = _held(rows)
        if scheme == "loso":
            truth_abs = _loso_truth(model, rows, rng)
            groups = [("pooled", summ[summ["temperature_C"].isna()], None)]
        else:
            err = _errors(model, h)
            groups = [("pooled", summ[summ["temperature_C"].isna()], np.ones(len(h), bool))]
            for T in model.temperatures:
                sel = np.isclose(h["temperature_C"].to_numpy(float), T)
                if sel.any():
                    groups.append((f"{T:g}", summ[np.isclose(summ["temperature_C"], T)], sel))
        for label, s, sel in groups:
            if s.empty:
                continue
            s = s.iloc[0]
            for q, unit in (("logE", "pct"), ("phase", "deg")):
                row = {
                    "replicate": index,
                    "scheme": scheme,
                    "temperature": label,
                    "quantity": q,
                    "n_cells": int(s["n_cells"]),
                    "observed_abs": s[f"abs_{q}_{unit}"],
                    "abs_low": s[f"abs_{q}_ci95_low"],
                    "abs_high": s[f"abs_{q}_ci95_high"],
                    "observed_bias": s[f"bias_{q}_{unit}"],
                    "bias_low": s[f"bias_{q}_ci95_low"],
                    "bias_high": s[f"bias_{q}_ci95_high"],
                }
                if scheme == "loso":
                    row.update({"true_abs": truth_abs[q], "true_bias": np.nan})
                else:
                    e = err[q][sel]
                    row.update({"true_abs": float(np.mean(np.abs(e))), "true_bias": float(np.mean(e))})
                out.append(row)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("measured", help="the measured table (results/lab/measured.csv of the run)")
    ap.add_argument("--settings", required=True, help="the selected law's settings (law JSON selection.chosen_label)")
    ap.add_argument("--replicates", type=int, default=1000)
    ap.add_argument("--first", type=int, default=0, help="index of the first replicate (default 0)")
    ap.add_argument("--seed", type=int, default=20261126)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--schemes", nargs="+", choices=SCHEMES, default=list(SCHEMES), help="default: all three")
    ap.add_argument("--keep", help="pickle of every replicate's table and fold rows (to score them again)")
    ap.add_argument("--rescore", help="score the replicates of this pickle again instead of running them")
    args = ap.parse_args(argv)
    table = pd.read_csv(args.measured)
    model = FittedModel(table)
    options = cv.Options(candidates=(parse_settings(args.settings),), artifacts=False, burgers=False)
    rows: list = []
    t0 = time.process_time()
    if args.rescore:
        import pickle

        with open(args.rescore, "rb") as fh:
            kept = pickle.load(fh)
        for i, (table_i, folds) in sorted(kept.items()):
            rng = np.random.default_rng([args.seed, i])
            model.simulate(rng)  # the truth draws of loso follow the table's, as in the run
            rows += score(model, table_i, folds, rng, i, tuple(s for s in args.schemes if s in folds))
        pd.DataFrame(rows).assign(seed=args.seed).to_csv(args.output, index=False, float_format="%.6g")
        return
    keep: dict | None = {} if args.keep else None
    for i in range(args.first, args.first + args.replicates):
        rows += replicate(model, options, args.seed, i, keep, tuple(args.schemes))
        if (i - args.first + 1) % 25 == 0:
            pd.DataFrame(rows).to_csv(args.output, index=False, float_format="%.6g")
            _dump(keep, args.keep)
            print(f"{i - args.first + 1} replicates, {time.process_time() - t0:.0f} s CPU", file=sys.stderr, flush=True)
    frame = pd.DataFrame(rows)
    frame["seed"] = args.seed
    frame.to_csv(args.output, index=False, float_format="%.6g")
    _dump(keep, args.keep)


def _dump(keep: dict | None, path: str | None) -> None:
    if keep is not None and path:
        import pickle

        with open(path, "wb") as fh:
            pickle.dump(keep, fh)


if __name__ == "__main__":
    main()
