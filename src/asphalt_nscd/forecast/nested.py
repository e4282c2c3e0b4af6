"""Model choice inside the fold: a forecast whose form is selected on the training mixes only.

:class:`Selected` wraps candidate models (any objects with the interface of
:class:`.validation.Baseline`: ``fit(train)``, ``predict(state, rows)``, ``available(table)``).
Its ``fit`` sees the training mixes of an outer fold and nothing else: it splits them into
``inner_folds`` folds of mixes (:func:`.validation.mix_folds`, seeded), fits every candidate on each
inner training part, scores it on the inner held-out mixes, picks the candidate with the least
inner score, and refits that one on all the training mixes. The held-out mix of the outer fold
never reaches the choice (the leak test multiplies its measured values and checks that neither
the choice nor the forecast moves).

Inner score: the mean over inner held-out mixes of each mix's mean |100 ln(E_pred / E_meas)| plus
its mean |Phi_pred - Phi_meas| in degrees times :data:`PHASE_WEIGHT_PCT_PER_DEG` (1 degree counted
as 1 %, a choice: the two errors are reported in these units and have similar spreads on the
shipped mixes). The state records every candidate's inner score, so that the variants tried in
every fold are logged (:func:`selection_log`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError

#: weight of one degree of phase error against one % of |E*| error in the inner score
PHASE_WEIGHT_PCT_PER_DEG = 1.0


def label_of(model) -> str:
    """A candidate's label: its model name, or ``<formula>_<coefficients>`` for a baseline."""
    from .validation import model_label

    return model_label(model)


def inner_score(model, state, test: pd.DataFrame) -> float:
    """The inner score (module docstring) of a fitted candidate on held-out rows with measured values."""
    E, P, _ = model.predict(state, test.drop(columns=["E_norm_MPa", "phase_deg"]))
    e = np.abs(100.0 * np.log(np.asarray(E, float) / test["E_norm_MPa"].to_numpy(float)))
    p = np.abs(np.asarray(P, float) - test["phase_deg"].to_numpy(float))
    per_mix = pd.DataFrame({"mix": test["mix_id"].to_numpy(), "s": e + PHASE_WEIGHT_PCT_PER_DEG * p})
    per_mix = per_mix.groupby("mix")["s"].mean()
    return float(per_mix.mean()) if per_mix.notna().any() else np.inf


class Selected:
    """The candidate with the least inner held-out score, chosen and refitted inside each fold.

    Parameters
    ----------
    name : the model's label in tables.
    candidates : the models to choose from (fitted afresh in every inner fold).
    inner_folds : folds of the training mixes (k of :func:`.validation.mix_folds`).
    seed : the seed of the inner split.
    """

    coefficients = "selected"

    def __init__(self, name: str, candidates: list, inner_folds: int = 5, seed: int = 1):
        if not candidates:
            raise InputError(f"selected model {name!r}: no candidate to choose from")
        self.model, self.candidates = name, list(candidates)
        self.inner_folds, self.seed = int(inner_folds), int(seed)

    def available(self, table: pd.DataFrame) -> bool:
        return any(c.available(table) for c in self.candidates)

    def fit(self, train: pd.DataFrame) -> dict:
        """The choice on ``train`` (module docstring): ``chosen`` (label), ``state`` (its constants
        fitted on all of ``train``), ``inner`` ({label: inner score}), ``inner_folds``."""
        from .validation import mix_folds

        measured = train.dropna(subset=["E_norm_MPa", "phase_deg"])
        usable = [c for c in self.candidates if c.available(measured)]
        mixes = sorted(measured["mix_id"].unique())
        k = min(self.inner_folds, len(mixes))
        if k < 2 or not usable:
            raise InputError(f"selected model {self.model!r}: {len(mixes)} training mixes; at least 2 are needed")
        folds = mix_folds(mixes, k, self.seed)
        scores = {}
        for cand in usable:
            per_fold = []
            for held in folds:
                inner_train = measured[~measured["mix_id"].isin(held)]
                inner_test = measured[measured["mix_id"].isin(held)]
                per_fold.append((inner_score(cand, cand.fit(inner_train), inner_test), len(held)))
            s, n = np.array(per_fold).T
            scores[label_of(cand)] = float(np.sum(s * n) / np.sum(n))
        chosen = min(scores, key=lambda name: scores[name])
        model = next(c for c in usable if label_of(c) == chosen)
        return {"chosen": chosen, "state": model.fit(measured), "inner": scores, "inner_folds": k}

    def predict(self, state: dict, rows: pd.DataFrame):
        """The chosen candidate's forecast of ``rows`` with its refitted state.

        Raises InputError when the chosen candidate is not among this model's candidates (e.g. its
        sample variant's responses were not given)."""
        model = next((c for c in self.candidates if label_of(c) == state["chosen"]), None)
        if model is None:
            raise InputError(
                f"{self.model}: its chosen candidate {state['chosen']!r} is not among "
                f"{[label_of(c) for c in self.candidates]} (are that sample variant's responses given?)"
            )
        return model.predict(state["state"], rows)


def selection_log(states: list) -> pd.DataFrame:
    """Every variant tried in every fold with its inner score and whether it was chosen: one row per
    (fold, selected model, binder route, candidate), from the states of
    :func:`.validation.cross_validate` (those of :class:`Selected` models only)."""
    rows = []
    for st in states:
        s = st.get("state")
        if not isinstance(s, dict) or "inner" not in s:
            continue
        for cand, score in s["inner"].items():
            rows.append(
                {
                    "fold": st["fold"],
                    "model": st["model"],
                    "binder_route": st["binder_route"],
                    "candidate": cand,
                    "inner_score": score,
                    "chosen": cand == s["chosen"],
                    "inner_folds": s["inner_folds"],
                }
            )
    return pd.DataFrame(
        rows, columns=["fold", "model", "binder_route", "candidate", "inner_score", "chosen", "inner_folds"]
    )
