"""A data-driven yardstick beside the formulas: gradient-boosted trees on the formulas' inputs.

``gradient_boosting`` (coefficients ``learned``) forecasts ln|E*| and the phase angle of a mix
at a condition from what the formulas read, and nothing else (:data:`FEATURES`): the binder's
|G*| and phase angle at the mix's temperature and frequency (``binder_G_mix_MPa``,
``binder_delta_mix_deg`` of the binder route), the temperature, ln of the frequency, the four
sieve figures (rho34, rho38, rho4 % retained, rho200 % passing), Va, Vbeff, VMA = Va + Vbeff
and VFA = 100 Vbeff / VMA. Two histogram gradient-boosting regressors of scikit-learn
(:class:`sklearn.ensemble.HistGradientBoostingRegressor`, squared error; Friedman 2001, "Greedy
function approximation: a gradient boosting machine", Ann. Statist. 29:1189-1232), one per
target.

**Tuned inside the fold.** :meth:`GradientBoosting.fit` sees the training mixes only and picks
the hyperparameters of each target on them by an inner cross-validation grouped by mix
(:data:`INNER_FOLDS` folds of mixes, :func:`.validation.mix_folds` with :data:`SEED`) over the
grid :data:`GRID` (learning rate, leaves per tree, least samples per leaf; the number of
iterations read off each fit's staged predictions), scored as the outer validation scores:
the mean over the inner held-out mixes of each mix's mean |100 ln(forecast/measured)| (|E*|)
or mean |phase error| (degrees). The choice with the lowest score (the first in grid order on a
tie) is refitted on every training mix. Seeded (``random_state``) and one thread (threadpoolctl):
the same table gives the same numbers.

**Judged by mix, and by random rows.** The forecast is scored like every model (mixes left
out, :func:`.validation.cross_validate`). :func:`by_rows` scores it by random cells (k folds of
cells, a mix's other conditions in the training set), with its inner tuning as it is or, with
``inner="rows"``, over folds of random cells too (the whole protocol of a judge by rows), and
:func:`compare` puts the judges side by side: how much better a model looks when the mix it
forecasts was seen at its other conditions, the usual judge of learned |E*| models.
"""

from __future__ import annotations

from itertools import product

import numpy as np
import pandas as pd

from ..io import InputError

#: the model's name and coefficients label in the tables
NAME, COEFFICIENTS = "gradient_boosting", "learned"
#: columns the features are read from (the routed table)
INPUTS = (
    "binder_G_mix_MPa",
    "binder_delta_mix_deg",
    "temperature_C",
    "frequency_Hz",
    "rho34_pct",
    "rho38_pct",
    "rho4_pct",
    "rho200_pct",
    "Va_pct",
    "Vbeff_pct",
)
#: the features, in order (:func:`features`)
FEATURES = (
    "binder_G_MPa",
    "binder_delta_deg",
    "temperature_C",
    "ln_frequency",
    "rho34_pct",
    "rho38_pct",
    "rho4_pct",
    "rho200_pct",
    "Va_pct",
    "Vbeff_pct",
    "VMA_pct",
    "VFA_pct",
)
#: the hyperparameter grid of the inner tuning
GRID = {
    "learning_rate": (0.1, 0.2),
    "max_leaf_nodes": (3, 6),
    "min_samples_leaf": (20, 60),
    "max_iter": (25, 50, 100),
}
#: inner folds of mixes
INNER_FOLDS = 3
#: seed of the inner folds and of the regressors
SEED = 1
#: the two targets: the measured column and its transform
TARGETS = ("logE", "phase")


def features(rows: pd.DataFrame) -> np.ndarray:
    """(n, 12) the :data:`FEATURES` of ``rows`` (routed table); NaN where an input is missing.

    Raises InputError when an input column is missing."""
    from ..io import require_columns

    require_columns(rows, INPUTS, "gradient boosting's rows", "a matched table with routed binder columns")
    va, vb = rows["Va_pct"].to_numpy(float), rows["Vbeff_pct"].to_numpy(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        vma = va + vb
        f = rows["frequency_Hz"].to_numpy(float)
        return np.column_stack(
            [
                rows["binder_G_mix_MPa"].to_numpy(float),
                rows["binder_delta_mix_deg"].to_numpy(float),
                rows["temperature_C"].to_numpy(float),
                np.where(f > 0, np.log(f), np.nan),
                *(rows[c].to_numpy(float) for c in ("rho34_pct", "rho38_pct", "rho4_pct", "rho200_pct")),
                va,
                vb,
                vma,
                100.0 * vb / vma,
            ]
        )


def _targets(rows: pd.DataFrame) -> dict:
    return {"logE": np.log(rows["E_norm_MPa"].to_numpy(float)), "phase": rows["phase_deg"].to_numpy(float)}


def _scale(target: str) -> float:
    """Residual units of the score: 100 ln (%) for |E*|, degrees for phase."""
    return 100.0 if target == "logE" else 1.0


def _per_mix_score(err: np.ndarray, mix: np.ndarray) -> float:
    """Mean over mixes of each mix's mean |err|."""
    return float(pd.Series(np.abs(err)).groupby(mix).mean().mean())


class LearnedState(dict):
    """A fold's state: the chosen hyperparameters and inner scores as dict items (what the
    constants JSON keeps), the two fitted regressors in ``estimators`` (not written)."""

    def __init__(self, items: dict, estimators: dict):
        super().__init__(items)
        self.estimators = estimators


class GradientBoosting:
    """``gradient_boosting`` with its hyperparameters tuned and its trees fitted on the training
    mixes of a fold (module docstring).

    Parameters
    ----------
    grid : hyperparameter grid (:data:`GRID` keys).
    inner_folds : folds of the inner tuning (at most the training mixes).
    seed : seed of the inner folds and of the regressors.
    inner : ``mix`` (the default: inner folds of whole mixes) or ``rows`` (inner folds of a
        seeded shuffle of the training cells: the tuning of a model judged by random rows,
        :func:`by_rows`).
    """

    model = NAME
    coefficients = COEFFICIENTS

    def __init__(self, grid: dict | None = None, inner_folds: int = INNER_FOLDS, seed: int = SEED, inner: str = "mix"):
        self.grid = dict(GRID if grid is None else grid)
        if set(self.grid) != set(GRID) or not all(len(v) for v in self.grid.values()):
            raise InputError(f"gradient boosting grid: expected a non-empty list for each of {sorted(GRID)}")
        if inner not in ("mix", "rows"):
            raise InputError(f"gradient boosting inner folds {inner!r}: expected 'mix' or 'rows'")
        self.inner_folds, self.seed, self.inner = int(inner_folds), int(seed), inner

    def available(self, table: pd.DataFrame) -> bool:
        """Whether ``table`` gives every input at every row."""
        return all(c in table and table[c].notna().all() for c in INPUTS)

    def _regressor(self, **params):
        from sklearn.ensemble import HistGradientBoostingRegressor

        return HistGradientBoostingRegressor(early_stopping=False, random_state=self.seed, **params)

    def _tune(self, X: np.ndarray, y: np.ndarray, mix: np.ndarray, target: str) -> tuple[dict, float]:
        """The grid point with the lowest inner cross-validation score, and that score."""
        from .validation import mix_folds

        mixes = list(dict.fromkeys(mix))
        k = min(self.inner_folds, len(mixes))
        if k < 2:
            raise InputError(f"gradient boosting: {len(mixes)} training mix; its inner tuning needs 2 or more")
        if self.inner == "mix":
            folds = [np.isin(mix, held) for held in mix_folds(mixes, k, self.seed)]
        else:
            order = np.random.default_rng(self.seed).permutation(len(y))
            folds = [np.isin(np.arange(len(y)), part) for part in np.array_split(order, k)]
        iters = sorted(self.grid["max_iter"])
        shapes = list(product(self.grid["learning_rate"], self.grid["max_leaf_nodes"], self.grid["min_samples_leaf"]))
        pred = np.full((len(shapes), len(iters), len(y)), np.nan)
        for test in folds:
            for s, (lr, leaves, leaf) in enumerate(shapes):
                est = self._regressor(
                    learning_rate=lr, max_leaf_nodes=leaves, min_samples_leaf=leaf, max_iter=iters[-1]
                ).fit(X[~test], y[~test])
                at = {n: j for j, n in enumerate(iters)}
                for n, p in enumerate(est.staged_predict(X[test]), start=1):
                    if n in at:
                        pred[s, at[n], test] = p
        best, best_score = None, np.inf
        for s, (lr, leaves, leaf) in enumerate(shapes):
            for j, n in enumerate(iters):
                score = _per_mix_score(_scale(target) * (pred[s, j] - y), mix)
                if score < best_score:
                    best_score = score
                    best = {"learning_rate": lr, "max_leaf_nodes": leaves, "min_samples_leaf": leaf, "max_iter": n}
        assert best is not None
        return best, best_score

    def fit(self, train: pd.DataFrame) -> LearnedState:
        """The fold's two regressors, tuned and fitted on ``train`` (rows of the training mixes
        with measured |E*| and phase; routed binder columns).

        Returns a :class:`LearnedState`: items ``<target>_<hyperparameter>``, ``<target>_inner_score``
        (% for logE, degrees for phase), ``n_rows``, ``n_mixes``.

        Raises InputError when fewer than two training mixes have every input."""
        from sklearn.ensemble import HistGradientBoostingRegressor  # noqa: F401 (its OpenMP loaded: limited below)
        from threadpoolctl import threadpool_limits

        rows = train.dropna(subset=["E_norm_MPa", "phase_deg", *INPUTS])
        rows = rows[rows["E_norm_MPa"] > 0]
        X = features(rows)
        ok = np.all(np.isfinite(X), axis=1)
        X, rows = X[ok], rows[ok]
        mix = rows["mix_id"].astype(str).to_numpy()
        items: dict = {"n_rows": int(len(rows)), "n_mixes": int(len(set(mix)))}
        estimators = {}
        with threadpool_limits(limits=1):
            for target, y in _targets(rows).items():
                params, score = self._tune(X, y, mix, target)
                estimators[target] = self._regressor(**params).fit(X, y)
                items |= {f"{target}_{k}": v for k, v in params.items()} | {f"{target}_inner_score": score}
        return LearnedState(items, estimators)

    def predict(self, state: LearnedState, rows: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, str]:
        """(|E*| MPa, phase deg, ``"model"``) for ``rows``; NaN where an input is missing."""
        from threadpoolctl import threadpool_limits

        X = features(rows)
        ok = np.all(np.isfinite(X), axis=1)
        E, P = np.full(len(rows), np.nan), np.full(len(rows), np.nan)
        if ok.any():
            with threadpool_limits(limits=1):
                E[ok] = np.exp(state.estimators["logE"].predict(X[ok]))
                P[ok] = state.estimators["phase"].predict(X[ok])
        return E, P, "model"


def by_rows(table: pd.DataFrame, model, route: str, k: int | None = None, seed: int = SEED) -> pd.DataFrame:
    """The model judged by random rows: ``k`` folds of a seeded shuffle of the measured cells
    (default: as many folds as mixes, so each training set is as large as leaving one mix out),
    each cell forecast by the model fitted on the other folds' cells, its own mix's other
    conditions among them.

    Returns rows in :data:`.validation.ROW_COLUMNS` (``fold`` the cell fold, ``binder_id`` and
    ``binder_seen`` empty).

    Raises InputError when the table has fewer than 2 measured cells per fold."""
    from .validation import ROW_COLUMNS

    measured = table.dropna(subset=["E_norm_MPa", "phase_deg"]).reset_index(drop=True)
    k = int(k or measured["mix_id"].nunique())
    if not 2 <= k <= len(measured) // 2:
        raise InputError(f"by-row folds: k = {k} folds of {len(measured)} cells; expected 2..{len(measured) // 2}")
    order = np.random.default_rng(seed).permutation(len(measured))
    frames = []
    for fold, part in enumerate(np.array_split(order, k)):
        test = measured.iloc[np.sort(part)]
        train = measured.drop(index=test.index)
        state = model.fit(train)
        E, P, source = model.predict(state, test.drop(columns=["E_norm_MPa", "phase_deg"]))
        frames.append(
            pd.DataFrame(
                {
                    "mix_id": test["mix_id"].astype(str).to_numpy(),
                    "fold": fold,
                    "binder_id": None,
                    "binder_seen": None,
                    "model": model.model,
                    "coefficients": model.coefficients,
                    "binder_route": route,
                    "temperature_C": test["temperature_C"].to_numpy(float),
                    "frequency_Hz": test["frequency_Hz"].to_numpy(float),
                    "E_meas_MPa": test["E_norm_MPa"].to_numpy(float),
                    "phase_meas_deg": test["phase_deg"].to_numpy(float),
                    "E_pred_MPa": E,
                    "phase_pred_deg": P,
                    "phase_source": source,
                    "binder_extrapolated": (
                        test["binder_extrapolated"].to_numpy()
                        if "binder_extrapolated" in test
                        else pd.array([pd.NA] * len(test), dtype="boolean")
                    ),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)[ROW_COLUMNS]


#: columns of :func:`compare`
COMPARE_COLUMNS = [
    "model",
    "binder_route",
    "quantity",
    "temperature_C",
    "n_mixes",
    "by_mix",
    "by_mix_ci_low",
    "by_mix_ci_high",
    "by_rows",
    "by_rows_ci_low",
    "by_rows_ci_high",
    "ratio",
    "ratio_ci_low",
    "ratio_ci_high",
    "confidence",
]


def compare(by_mix: pd.DataFrame, by_row: pd.DataFrame, confidence: float = 0.95) -> pd.DataFrame:
    """The same model's errors judged by mix (``by_mix``: rows of :func:`.validation.cross_validate`)
    and by random rows (``by_row``: rows of :func:`by_rows`), per (model, binder route, quantity)
    overall (``temperature_C`` NaN) and per temperature.

    Each error is the mean over mixes of each mix's mean |100 ln(forecast/measured)| (``logE``,
    %) or mean |phase error| (``phase``, degrees), with its t(n - 1) interval over the mixes;
    ``ratio`` = by_mix / by_rows as the geometric mean over the mixes of the per-mix ratio, with
    the t interval of its log (paired over the same mixes)."""
    from ..diagnosis.scores import t_interval

    def per_mix(rows):
        d = rows.assign(
            logE=100.0 * np.abs(np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"])),
            phase=np.abs(rows["phase_pred_deg"] - rows["phase_meas_deg"]),
            mix_id=rows["mix_id"].astype(str),
        )
        return d

    a, b = per_mix(by_mix), per_mix(by_row)
    out = []
    for (model, route), ga in a.groupby(["model", "binder_route"], sort=False):
        gb = b[(b["model"] == model) & (b["binder_route"] == route)]
        if gb.empty:
            continue
        for q in ("logE", "phase"):
            for T in [np.nan, *sorted(ga["temperature_C"].unique())]:
                sa = ga if np.isnan(T) else ga[ga["temperature_C"] == T]
                sb = gb if np.isnan(T) else gb[gb["temperature_C"] == T]
                ma, mb = sa.groupby("mix_id")[q].mean(), sb.groupby("mix_id")[q].mean()
                both = pd.concat([ma, mb], axis=1, keys=["a", "b"]).dropna()
                lr = np.log(both["a"] / both["b"]).replace([np.inf, -np.inf], np.nan).dropna().to_numpy(float)
                lo_r, hi_r = t_interval(lr, confidence)
                row = {"model": model, "binder_route": route, "quantity": q, "temperature_C": T}
                row["n_mixes"] = len(both)
                for name, v in (("by_mix", both["a"]), ("by_rows", both["b"])):
                    row[name] = float(v.mean())
                    row[f"{name}_ci_low"], row[f"{name}_ci_high"] = t_interval(v.to_numpy(float), confidence)
                row["ratio"] = float(np.exp(lr.mean())) if lr.size else np.nan
                row["ratio_ci_low"], row["ratio_ci_high"] = float(np.exp(lo_r)), float(np.exp(hi_r))
                row["confidence"] = confidence
                out.append(row)
    return pd.DataFrame(out, columns=COMPARE_COLUMNS)


#: learned models by their name in ``forecast.learned``
MODELS = {NAME: GradientBoosting}
