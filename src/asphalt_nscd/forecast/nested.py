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

Rule of the choice (``rule``): ``best`` takes the least inner score. ``one_se`` (the
one-standard-error rule, Breiman et al. 1984, *Classification and Regression Trees*, §3.4.3;
Hastie, Tibshirani & Friedman 2009, *Elements of Statistical Learning*, §7.10) takes the simplest
candidate not distinguishably worse than the best: a candidate qualifies when its excess over
the best, averaged over the inner held-out mixes, is at most one standard error of that paired
excess (per-mix differences, SD/sqrt(n)); among those qualifying the least complex one is taken
(its ``complexity``: the number of constants it fits, then the base sample before a sample
variant), ties by the least inner score. Near-tied leaders then resolve to the same, simpler
candidate in every fold instead of to the noise of the split.
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


#: the rules of the choice (module docstring)
RULES = ("best", "one_se")


def mix_scores(model, state, test: pd.DataFrame) -> pd.Series:
    """Each held-out mix's score (module docstring; index: mix_id) of a fitted candidate on rows
    with measured values; NaN for a mix it does not forecast."""
    E, P, _ = model.predict(state, test.drop(columns=["E_norm_MPa", "phase_deg"]))
    e = np.abs(100.0 * np.log(np.asarray(E, float) / test["E_norm_MPa"].to_numpy(float)))
    p = np.abs(np.asarray(P, float) - test["phase_deg"].to_numpy(float))
    per_mix = pd.DataFrame({"mix": test["mix_id"].to_numpy(), "s": e + PHASE_WEIGHT_PCT_PER_DEG * p})
    return per_mix.groupby("mix")["s"].mean()


def inner_score(per_mix: pd.Series) -> float:
    """The inner score (module docstring) of per-mix scores (:func:`mix_scores`); inf when no mix is scored."""
    return float(per_mix.mean()) if per_mix.notna().any() else np.inf


def complexity(model) -> tuple:
    """The order of simplicity of a candidate for the ``one_se`` rule: the number of constants it
    fits on mixes, then 0 for the base sample and 1 for a sample variant."""
    return (len(getattr(model, "free", ())), 1 if getattr(model, "variant", "") else 0)


def one_se_choice(scores: dict, per_mix: dict, order: dict) -> tuple[str, dict]:
    """The ``one_se`` choice (module docstring) and the standard error of each candidate's paired
    excess over the best (0 for the best; inf when fewer than 2 mixes are shared).

    Parameters
    ----------
    scores : {label: inner score}.
    per_mix : {label: per-mix inner scores (pd.Series by mix_id)}.
    order : {label: complexity key (:func:`complexity`)}.
    """
    best = min(scores, key=lambda name: scores[name])
    se = {}
    for name in scores:
        d = (per_mix[name] - per_mix[best]).dropna()
        se[name] = 0.0 if name == best else (float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) >= 2 else np.inf)
    qualifying = [n for n in scores if np.isfinite(scores[n]) and scores[n] - scores[best] <= se[n]]
    return min(qualifying, key=lambda n: (order[n], scores[n])), se


class Selected:
    """The candidate with the least inner held-out score, chosen and refitted inside each fold.

    Parameters
    ----------
    name : the model's label in tables.
    candidates : the models to choose from (fitted afresh in every inner fold).
    inner_folds : folds of the training mixes (k of :func:`.validation.mix_folds`).
    seed : the seed of the inner split.
    rule : the rule of the choice, one of :data:`RULES` (module docstring).

    Raises InputError for no candidate or an unknown rule.
    """

    coefficients = "selected"

    def __init__(self, name: str, candidates: list, inner_folds: int = 5, seed: int = 1, rule: str = "best"):
        if not candidates:
            raise InputError(f"selected model {name!r}: no candidate to choose from")
        if rule not in RULES:
            raise InputError(f"selected model {name!r}: rule {rule!r}; expected one of {list(RULES)}")
        self.model, self.candidates = name, list(candidates)
        self.inner_folds, self.seed, self.rule = int(inner_folds), int(seed), rule

    def available(self, table: pd.DataFrame) -> bool:
        return any(c.available(table) for c in self.candidates)

    def fit(self, train: pd.DataFrame) -> dict:
        """The choice on ``train`` (module docstring): ``chosen`` (label), ``state`` (its constants
        fitted on all of ``train``), ``inner`` ({label: inner score}), ``inner_se`` ({label: standard
        error of its paired excess over the best}), ``rule``, ``inner_folds``."""
        from .validation import mix_folds

        measured = train.dropna(subset=["E_norm_MPa", "phase_deg"])
        usable = [c for c in self.candidates if c.available(measured)]
        mixes = sorted(measured["mix_id"].unique())
        k = min(self.inner_folds, len(mixes))
        if k < 2 or not usable:
            raise InputError(f"selected model {self.model!r}: {len(mixes)} training mixes; at least 2 are needed")
        folds = mix_folds(mixes, k, self.seed)
        scores, per_mix = {}, {}
        for cand in usable:
            per_fold, mixes_scored = [], []
            for held in folds:
                inner_train = measured[~measured["mix_id"].isin(held)]
                inner_test = measured[measured["mix_id"].isin(held)]
                m = mix_scores(cand, cand.fit(inner_train), inner_test)
                mixes_scored.append(m)
                per_fold.append((inner_score(m), len(held)))
            s, n = np.array(per_fold).T
            scores[label_of(cand)] = float(np.sum(s * n) / np.sum(n))
            per_mix[label_of(cand)] = pd.concat(mixes_scored)
        if self.rule == "one_se":
            order = {label_of(c): complexity(c) for c in usable}
            chosen, se = one_se_choice(scores, per_mix, order)
        else:
            chosen, se = min(scores, key=lambda name: scores[name]), {}
        model = next(c for c in usable if label_of(c) == chosen)
        return {
            "chosen": chosen,
            "state": model.fit(measured),
            "inner": scores,
            "inner_se": se,
            "rule": self.rule,
            "inner_folds": k,
        }

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
                    "inner_se": s.get("inner_se", {}).get(cand, np.nan),
                    "rule": s.get("rule", "best"),
                    "chosen": cand == s["chosen"],
                    "inner_folds": s["inner_folds"],
                }
            )
    return pd.DataFrame(
        rows,
        columns=[
            "fold",
            "model",
            "binder_route",
            "candidate",
            "inner_score",
            "inner_se",
            "rule",
            "chosen",
            "inner_folds",
        ],
    )
