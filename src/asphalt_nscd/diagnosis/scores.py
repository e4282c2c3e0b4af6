"""Scores of held-out and in-sample predictions, with intervals that mean what they say.

The rows of ``asphalt-nscd crossval`` (:mod:`asphalt_nscd.diagnosis.crossval`) give a
prediction per held-out cell. Per (scheme, kind, model, temperature, extrapolation), and
pooled over the temperatures (``temperature_C`` NaN):

* **|E*| as a log ratio**: d_c = ln(E_pred,c) - mean_s ln(E_s,c) against the mean of the
  specimens' ln|E*| (the geometric replicate mean), in %: the signed mean ``bias_logE_pct``
  = 100 mean_c d_c and the absolute error against the lab's means ``abs_logE_pct`` =
  100 mean_c |d_c| (the observed error; ``abs_logE_vs_means_pct`` repeats it);
* **Phi in degrees**: the same with Phi_pred - mean_s Phi_s (``bias_phase_deg``,
  ``abs_phase_deg``);
* the paper's MRE (Table 4: | |E*|_p / |E*|_m - 1 |, | Phi_p - Phi_m | / Phi_m, against the
  arithmetic replicate means, %) beside them, for comparison with the paper.

Intervals (95 %) over the specimens, which are what the reference is sampled from:

* signed means: a t(n - 1) interval over the specimens, b_s = mean_c (pred_c - y_s,c) (the
  mean of the b_s is the bias on a balanced table);
* absolute means: the interval of the error against the *mix*, the population of specimens
  the lab's ones were drawn from, mean_c |pred_c - mu_c|. The lab's means differ from the
  mix's by w_c = a + B_T + C_c, three levels of the specimens' scatter, each estimated from
  the specimen-by-cell table with its own degrees of freedom (:func:`nested_components`): the
  specimens' overall level a (n - 1 degrees of freedom), their level per isotherm B_T
  ((n - 1)(n_T - 1)) and the cell-to-cell scatter C_c ((n - 1) n_T (n_f - 1)). Each level's
  mean square is drawn from its scaled inverse chi-square (its uncertainty with its own
  degrees of freedom: the level term alone gives the t(n - 1) interval), then w
  (:func:`population_draws`); the interval is the 2.5 and 97.5 percentiles of
  mean_c |d_c + w_c| over the cells scored. The levels a fold's law did not see at its held-out
  cells (:data:`UNSEEN`) are already in its errors with the opposite sign: they are drawn given
  the errors (:func:`error_draws`). The interval's coverage, with the law refitted inside every
  replicate, is measured by simulation from a table's fitted model
  (``reference/crossval/coverage.py``);
* leave one specimen out (``loso``): the reference of a fold is the held-out specimen itself,
  so the fold's own mean error is the sample; signed and absolute means get t(n - 1)
  intervals over the folds (three specimens: two degrees of freedom, an interval that cannot
  bound the error usefully).

A bootstrap over 3 specimens (10 distinct resamples: the range of the single-specimen errors)
is not used (docs/choices.md, Diagnosis: held-out errors and their intervals).
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
from scipy import special, stats

#: random-effect draws of an absolute error's interval
N_SIMULATIONS = 4000
#: columns of :func:`summarize`
SUMMARY_COLUMNS = [
    "scheme",
    "kind",
    "model",
    "temperature_C",
    "extrapolation",
    "n_cells",
    "n_not_computable",
    "bias_logE_pct",
    "bias_logE_ci95_low",
    "bias_logE_ci95_high",
    "abs_logE_pct",
    "abs_logE_ci95_low",
    "abs_logE_ci95_high",
    "abs_logE_vs_means_pct",
    "bias_phase_deg",
    "bias_phase_ci95_low",
    "bias_phase_ci95_high",
    "abs_phase_deg",
    "abs_phase_ci95_low",
    "abs_phase_ci95_high",
    "abs_phase_vs_means_deg",
    "mre_E_norm_pct",
    "mre_phase_pct",
    "n_specimens",
    "dof_specimen",
    "dof_specimen_temperature",
    "dof_cell",
    "interval",
    "noise_floor_E_norm_pct",
    "noise_floor_phase_pct",
]
#: what the intervals are, per scheme kind
INTERVALS = {
    "specimens": (
        "signed: t(n-1) over the specimens; absolute: the observed error against the lab's means, "
        "with the interval of the error against the mix (specimen, specimen-isotherm and cell levels, "
        "each with its own degrees of freedom)"
    ),
    "loso": (
        "signed: t(n-1) over the held-out specimens; absolute: the expected error of each fold's law against "
        "a new specimen of the mix, by a parametric bootstrap of the folds from the specimens' levels of scatter, "
        "its percentiles calibrated by a second bootstrap level (prepivoting)"
    ),
    "loso_nominal": (
        "signed: t(n-1) over the held-out specimens; absolute: the expected error of each fold's law against "
        "a new specimen of the mix, by a parametric bootstrap of the folds from the specimens' levels of scatter "
        "(the specimen level drawn), at its nominal percentiles"
    ),
    "loso_t": "t(n-1) over the held-out specimens",
}
_KEYS = ["scheme", "kind", "model", "temperature_C", "extrapolation"]


def _round_T(values) -> np.ndarray:
    return np.round(np.asarray(values, float), 6)


def specimen_values(table: pd.DataFrame) -> pd.DataFrame:
    """Per (specimen, temperature, frequency): the mean ln|E*| and Phi (deg) of that
    specimen's tests of the cell (a repeated test averaged). Index (specimen, T rounded to
    1e-6 degC, f); columns ``lnE, phase``."""
    t = pd.DataFrame(
        {
            "specimen": table["specimen"].astype(str).to_numpy(),
            "T": _round_T(table["temperature_C"]),
            "f": table["frequency_Hz"].to_numpy(float),
            "lnE": np.log(table["E_norm_MPa"].to_numpy(float)),
            "phase": table["phase_deg"].to_numpy(float),
        }
    )
    return t.groupby(["specimen", "T", "f"])[["lnE", "phase"]].mean()


def t_interval(values, level: float = 0.95) -> tuple[float, float]:
    """t(n - 1) interval of the mean of ``values`` (NaN, NaN for fewer than 2 finite ones)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return np.nan, np.nan
    half = stats.t.ppf(0.5 + level / 2, v.size - 1) * v.std(ddof=1) / np.sqrt(v.size)
    return float(v.mean() - half), float(v.mean() + half)


def binomial_ci(k: int, n: int, level: float = 0.95) -> tuple[float | None, float | None]:
    """Exact (Clopper-Pearson) confidence interval of a proportion k/n; (None, None) for n = 0."""
    if n <= 0:
        return None, None
    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="exact")
    return float(ci.low), float(ci.high)


def nested_components(spec: pd.DataFrame) -> dict:
    """The specimens' scatter about their cell means in three nested levels, per quantity
    (``lnE``, ``phase`` of :func:`specimen_values`): mean squares ``ms`` and degrees of freedom
    ``dof`` of the specimens' overall level (``specimen``), their level per isotherm
    (``specimen_temperature``) and the cell-to-cell scatter (``cell``), from the deviations
    r_s,c = y_s,c - mean_s y_s,c of the cells tested by >= 2 specimens (a balanced table of n
    specimens, n_T isotherms and n_f frequencies: n - 1, (n - 1)(n_T - 1), (n - 1) n_T (n_f - 1)
    degrees of freedom; expected mean squares n_T n_f s_u^2 + n_f s_v^2 + s_e^2,
    n_f s_v^2 + s_e^2 and s_e^2). Also ``cells`` (DataFrame ``T, f, n``: the cells and their
    specimens) and ``n_f`` ({T: cells of the isotherm}). A level without degrees of freedom has
    ``ms`` nan."""
    t = spec.reset_index()
    n_c = t.groupby(["T", "f"])["specimen"].transform("size")
    t = t[n_c >= 2].copy()
    cells = t.groupby(["T", "f"]).size().rename("n").reset_index()
    n_f = cells.groupby("T").size().to_dict()
    out: dict = {"cells": cells, "n_f": n_f}
    n_spec = t["specimen"].nunique()
    for q in ("lnE", "phase"):
        r = t[q] - t.groupby(["T", "f"])[q].transform("mean")
        frame = t[["specimen", "T"]].assign(r=r.to_numpy())
        g = frame.groupby(["specimen", "T"])["r"]
        R = g.transform("mean")
        e = frame["r"] - R
        st = frame.assign(R=R).groupby(["specimen", "T"]).agg(R=("R", "first"), k=("r", "size")).reset_index()
        Rs = (
            st.groupby("specimen").apply(lambda x: np.average(x["R"], weights=x["k"]), include_groups=False)
            if len(st)
            else pd.Series(dtype=float)  # no cell tested by two specimens: no scatter to split
        )
        K = st.groupby("specimen")["k"].sum()
        st["Rs"] = st["specimen"].map(Rs)
        dof = {
            "specimen": n_spec - 1,
            "specimen_temperature": int(st.groupby("specimen").size().sub(1).sum() - max(len(n_f) - 1, 0)),
            "cell": int((st["k"] - 1).sum() - sum(v - 1 for v in n_f.values())),
        }
        ss = {
            "specimen": float((K * Rs**2).sum()),
            "specimen_temperature": float((st["k"] * (st["R"] - st["Rs"]) ** 2).sum()),
            "cell": float((e**2).sum()),
        }
        out[q] = {
            "ms": {k: (ss[k] / dof[k] if dof[k] > 0 else np.nan) for k in dof},
            "dof": {k: max(int(v), 0) for k, v in dof.items()},
        }
    out["n_specimens"] = int(n_spec)
    return out


def population_parts(comp: dict, quantity: str, n_sim: int = N_SIMULATIONS, seed: int = 0) -> dict | None:
    """The three levels of w_c, the lab's cell mean less the mix's (the population of
    specimens), drawn at the cells of ``comp["cells"]`` in the units of ``quantity`` (ln|E*| or
    deg): ``a`` (n_sim, 1) ~ N(0, MS_u / (n N)); ``B`` (n_sim, cells) the isotherm's term,
    N(0, MS_v / (n n_f,T)) centred over the isotherms, and its variance ``var_B``; ``C``
    (n_sim, cells) ~ N(0, MS_e / n_c) centred within the isotherm, and ``var_C``. Every mean
    square is drawn as MS dof / chi2_dof, with its own degrees of freedom; a level without
    degrees of freedom is 0. None with fewer than 2 specimens."""
    cells = comp["cells"]
    q = comp[quantity]
    N = len(cells)
    if comp["n_specimens"] < 2 or N == 0 or q["dof"]["specimen"] < 1:
        return None
    rng = np.random.default_rng(seed)
    n_bar = float(cells["n"].mean())

    def ms(level):
        dof = q["dof"][level]
        m = q["ms"][level]
        if dof < 1 or not np.isfinite(m):
            return np.zeros(n_sim)
        return m * dof / rng.chisquare(dof, n_sim)

    T = cells["T"].to_numpy(float)
    temps = np.unique(T)
    col = np.searchsorted(temps, T)
    nf = np.array([comp["n_f"][t] for t in temps], float)
    m_u, m_v, m_e = ms("specimen"), ms("specimen_temperature"), ms("cell")
    a = rng.normal(0.0, 1.0, (n_sim, 1)) * np.sqrt(m_u / (n_bar * N))[:, None]
    var_T = m_v[:, None] / (n_bar * nf[None, :]) if temps.size > 1 else np.zeros((n_sim, temps.size))
    z = rng.normal(0.0, 1.0, (n_sim, temps.size)) * np.sqrt(var_T)
    z -= z.mean(axis=1, keepdims=True)
    var_C = m_e[:, None] / cells["n"].to_numpy(float)[None, :]
    c = rng.normal(0.0, 1.0, (n_sim, N)) * np.sqrt(var_C)
    for k in range(temps.size):
        sel = col == k
        c[:, sel] -= c[:, sel].mean(axis=1, keepdims=True)
    return {"a": a, "B": z[:, col], "var_B": var_T[:, col], "C": c, "var_C": var_C}


def population_draws(comp: dict, quantity: str, n_sim: int = N_SIMULATIONS, seed: int = 0) -> np.ndarray:
    """Draws (n_sim, cells of ``comp["cells"]``) of w_c = a + B_T + C_c (:func:`population_parts`);
    nan with fewer than 2 specimens."""
    parts = population_parts(comp, quantity, n_sim, seed)
    if parts is None:
        return np.full((n_sim, len(comp["cells"])), np.nan)
    return parts["a"] + parts["B"] + parts["C"]


#: the levels of the lab's scatter a fold's law did not see at its held-out cells (their
#: share of a held-out error is drawn given that error): the held-out cell's own scatter, and
#: the specimens' level per isotherm, which a shift law (one activation energy, or WLF's two
#: constants) cannot follow from the isotherm's other frequencies (lofo) and which a held-out
#: isotherm does not show at all (loto); the specimens' overall level is seen in every fold
UNSEEN = {"lofo": ("specimen_temperature", "cell"), "loto": ("specimen_temperature", "cell")}


def _given(d: np.ndarray, groups: np.ndarray, var: np.ndarray, rng, own: bool = True) -> np.ndarray:
    """Draws of a level's term x at the cells of ``d`` given the held-out errors d = g - x
    (g the law's own error, independent of x): per group of cells sharing x, the normal
    conditional x | mean_group(d) ~ N(-lam dbar, (1 - lam) var), lam = var / E[dbar^2]
    (the share of the errors' second moment the level explains, at most 1); ``var``
    (n_sim, cells) the level's drawn variance.

    E[dbar^2] = var + s^2, s^2 the variance of the law's own error g over the groups. With
    ``own`` (the cell level) it is the mean of dbar^2 over every group. Without (the isotherm
    level: one group per isotherm of the scored cells, the three interpolated ones in the shipped
    design of five), s^2 is estimated from the *other* groups, the mean of
    their dbar^2 less their drawn variance (at least 0), so that one group's own large deviation,
    which is as likely the lab's level at that isotherm as the law's error, does not lower its own
    lam (empirical Bayes with the prior variance estimated leave-one-group-out); with one group,
    as with ``own``."""
    u, inv = np.unique(groups, return_inverse=True)
    dbar = np.array([d[inv == k].mean() for k in range(u.size)])
    v = np.stack([var[:, inv == k][:, 0] for k in range(u.size)], axis=1)  # (n_sim, groups)
    if own or u.size < 2:
        lam = np.minimum(v / max(float(np.mean(dbar**2)), 1e-300), 1.0)
    else:
        sq = dbar**2
        others = (sq.sum() - sq) / (u.size - 1)  # (groups,)
        v_others = (v.sum(axis=1, keepdims=True) - v) / (u.size - 1)  # (n_sim, groups)
        lam = v / np.maximum(v + np.maximum(others[None, :] - v_others, 0.0), 1e-300)
    x = -lam * dbar[None, :] + np.sqrt((1.0 - lam) * v) * rng.normal(0.0, 1.0, v.shape)
    return x[:, inv]


def error_draws(d: np.ndarray, parts: dict, cols: np.ndarray, scheme: str) -> np.ndarray:
    """Draws (n_sim, cells) of the errors against the mix, pred_c - mu_c = d_c + w_c, at the
    cells ``cols`` (columns of ``parts``) of the errors ``d`` against the lab's means: the
    levels the fold's law saw (:data:`UNSEEN`) drawn independently, the ones it did not see
    given ``d`` (:func:`_given`); in-sample and other rows: every level independently."""
    unseen = UNSEEN.get(scheme, ())
    d = np.asarray(d, float)
    # draws of the conditional levels seeded by the cells themselves: a row's interval does not
    # depend on which other rows were scored before it
    rng = np.random.default_rng([len(scheme), *(int(c) for c in cols)])
    out = d[None, :] + parts["a"]
    if "specimen_temperature" in unseen:
        T = parts["T"][cols]
        out = out + _given(d, T, parts["var_B"][:, cols], rng, own=False)
    else:
        out = out + parts["B"][:, cols]
    if "cell" in unseen:
        r = d - (_group_means(d, parts["T"][cols]) if "specimen_temperature" in unseen else 0.0)
        out = out + _given(r, np.arange(d.size), parts["var_C"][:, cols], rng)
    else:
        out = out + parts["C"][:, cols]
    return out


def _group_means(x: np.ndarray, groups: np.ndarray) -> np.ndarray:
    u, inv = np.unique(groups, return_inverse=True)
    return np.array([x[inv == k].mean() for k in range(u.size)])[inv]


def abs_interval(e: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """(low, high) of the mean absolute error against the mix, mean_c |e_c|, from the draws
    ``e`` (n_sim, cells) of :func:`error_draws`; nan without draws."""
    if e.size == 0 or not np.isfinite(e).all():
        return np.nan, np.nan
    a = np.mean(np.abs(e), axis=1)
    lo, hi = np.percentile(a, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


class _Population:
    """The levels of :func:`population_parts` for both quantities of a table, by cell."""

    def __init__(self, spec: pd.DataFrame, n_sim: int = N_SIMULATIONS, seed: int = 0):
        self.comp = nested_components(spec)
        cells = self.comp["cells"]
        self.index = {(float(T), float(f)): i for i, (T, f) in enumerate(zip(cells["T"], cells["f"]))}
        self.parts = {}
        for k, q in enumerate(("lnE", "phase")):
            p = population_parts(self.comp, q, n_sim, seed + k)
            if p is not None:
                p["T"] = cells["T"].to_numpy(float)
            self.parts[q] = p

    def columns(self, T, f) -> np.ndarray:
        """Draw columns of the cells (T, f); -1 where a cell has < 2 specimens."""
        return np.array([self.index.get((float(a), float(b)), -1) for a, b in zip(T, f)], int)


def _specimen_scores(g: pd.DataFrame, spec: pd.DataFrame, pop: _Population, scheme: str = "") -> dict:
    """Scores of rows ``g`` (one group, computable rows of ``scheme``; held-out rows condition
    the levels their folds did not see) against the specimens' values, the absolute errors'
    intervals from the draws ``pop``."""
    cells = pd.DataFrame(
        {
            "T": _round_T(g["cell_temperature_C"]),
            "f": g["frequency_Hz"].to_numpy(float),
            "pE": np.log(g["E_norm_MPa_predicted"].to_numpy(float)),
            "pP": g["phase_deg_predicted"].to_numpy(float),
        }
    )
    specimens = sorted(spec.index.get_level_values(0).unique())
    YE = np.full((len(specimens), len(cells)), np.nan)
    YP = np.full_like(YE, np.nan)
    for i, s in enumerate(specimens):
        sub = spec.loc[s]
        for j, (T, f) in enumerate(zip(cells["T"], cells["f"])):
            if (T, f) in sub.index:
                YE[i, j], YP[i, j] = sub.loc[(T, f), "lnE"], sub.loc[(T, f), "phase"]
    out = {"n_specimens": int(np.isfinite(YE).any(axis=1).sum()), "interval": INTERVALS["specimens"]}
    out.update({f"dof_{k}": v for k, v in pop.comp["lnE"]["dof"].items()})
    cols = pop.columns(cells["T"], cells["f"])
    for q, pred, Y, scale, key in (
        ("logE", cells["pE"].to_numpy(), YE, 100.0, "lnE"),
        ("phase", cells["pP"].to_numpy(), YP, 1.0, "phase"),
    ):
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a cell no specimen tested: NaN, dropped below
            d = pred - np.nanmean(Y, axis=0)
            b_s = np.nanmean(pred[None, :] - Y, axis=1)
        keep = np.isfinite(d)
        d, c = d[keep], cols[keep]
        unit = "pct" if q == "logE" else "deg"
        lo, hi = t_interval(b_s)
        parts = pop.parts[key]
        if parts is not None and (c >= 0).all():
            a_lo, a_hi = abs_interval(error_draws(d, parts, c, scheme))
        else:
            a_lo, a_hi = np.nan, np.nan
        observed = float(np.mean(np.abs(d)))
        out.update(
            {
                f"bias_{q}_{unit}": scale * float(np.mean(d)),
                f"abs_{q}_{unit}": scale * observed,
                f"abs_{q}_vs_means_{unit}": scale * observed,
                f"bias_{q}_ci95_low": scale * lo,
                f"bias_{q}_ci95_high": scale * hi,
                f"abs_{q}_ci95_low": scale * a_lo,
                f"abs_{q}_ci95_high": scale * a_hi,
            }
        )
    return out


def level_variances(comp: dict, quantity: str, n_sim: int = 0, seed: int = 0) -> dict | None:
    """The variances of a specimen's three levels of deviation from the mix, from the mean
    squares of :func:`nested_components` (expected mean squares n_T n_f s_u^2 + n_f s_v^2 +
    s_e^2, n_f s_v^2 + s_e^2 and s_e^2; n_f the mean cells per isotherm; each floored at 0):
    ``specimen`` (s_u^2), ``specimen_temperature`` (s_v^2), ``cell`` (s_e^2). With ``n_sim`` > 0
    the specimen level, whose mean square has only n - 1 degrees of freedom (2 with 3
    specimens), is drawn as MS_u dof / chi2_dof (seeded by ``seed``), as :func:`population_parts`
    draws it: ``specimen`` is then an array of shape (n_sim,); the other two levels, with many
    more degrees of freedom, keep their estimates. None with fewer than 2 specimens or without
    the cell level."""
    q = comp[quantity]
    ms = q["ms"]
    if comp["n_specimens"] < 2 or not np.isfinite(ms["cell"]) or not comp["n_f"]:
        return None
    n_T = len(comp["n_f"])
    n_f = float(np.mean(list(comp["n_f"].values())))
    m_u = ms["specimen"] if np.isfinite(ms["specimen"]) else 0.0
    m_v = ms["specimen_temperature"] if np.isfinite(ms["specimen_temperature"]) else ms["cell"]
    dof_u = q["dof"]["specimen"]
    if n_sim > 0 and dof_u >= 1:
        m_u = m_u * dof_u / np.random.default_rng([seed, 13]).chisquare(dof_u, n_sim)
    return {
        "specimen": np.maximum(m_u - m_v, 0.0) / (n_T * n_f),
        "specimen_temperature": max(m_v - ms["cell"], 0.0) / n_f,
        "cell": float(ms["cell"]),
    }


def folded_normal_mean(g, var) -> np.ndarray:
    """E|g - x| for x ~ N(0, var), elementwise (broadcast shapes): s sqrt(2/pi) exp(-g^2 / 2 s^2)
    + g (1 - 2 Phi(-g / s)), s = sqrt(var); |g| where var = 0 (the mean of a folded normal)."""
    g = np.asarray(g, float)
    s = np.sqrt(np.maximum(np.asarray(var, float), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = g / s  # 1 - 2 Phi(-z) = erf(z / sqrt 2)
        out = s * np.sqrt(2.0 / np.pi) * np.exp(-0.5 * z * z) + g * special.erf(z / np.sqrt(2.0))
    return np.where(s > 0, out, np.abs(g))


#: the three levels of scatter of :func:`level_variances`, in the order of the (..., 3) arrays of the loso interval
LEVELS = ("specimen", "specimen_temperature", "cell")

#: tables and draws per table of the second bootstrap level that calibrates :func:`loso_abs_interval`
#: in the scores (None: its nominal percentiles, with the specimen level drawn as MS dof / chi2_dof)
LOSO_CALIBRATION: tuple[int, int] | None = (300, 250)


def _balanced_levels(x: np.ndarray, ti: np.ndarray, n_T: int) -> np.ndarray:
    """The three levels of :func:`level_variances` (specimen, specimen-isotherm, cell; floored at 0)
    of balanced specimens ``x`` (..., n, cells) whose cells lie on the isotherms ``ti`` (cells,) of
    ``n_T``: the mean squares of :func:`nested_components` on every table of the leading axes at
    once. Returns shape (..., 3). Raises ValueError without the cell level's degrees of freedom
    (no isotherm with two cells), where :func:`level_variances` has no levels either."""
    n = x.shape[-2]
    if np.bincount(ti).max(initial=0) < 2:
        raise ValueError("_balanced_levels: no isotherm holds two cells, so the cell level has no degrees of freedom")
    r = x - x.mean(axis=-2, keepdims=True)
    k = np.bincount(ti, minlength=n_T).astype(float)  # cells per isotherm
    R = (r @ (ti[:, None] == np.arange(n_T)[None, :]).astype(float)) / k  # (..., n, n_T)
    Rs = (R * k).sum(-1) / k.sum()
    ss_u = k.sum() * (Rs**2).sum(-1)
    ss_v = (k * (R - Rs[..., None]) ** 2).sum((-1, -2))
    ss_e = ((r - R[..., ti]) ** 2).sum((-1, -2))
    d_v, d_e = (n - 1) * (n_T - 1), (n - 1) * (k - 1).sum()
    m_u, m_e = ss_u / (n - 1), ss_e / d_e
    m_v = ss_v / d_v if d_v > 0 else m_e
    n_f = k.mean()
    return np.stack([np.maximum(m_u - m_v, 0.0) / (n_T * n_f), np.maximum(m_v - m_e, 0.0) / n_f, m_e], axis=-1)


def loso_abs_interval(
    pred: np.ndarray,
    observed: np.ndarray,
    train_mean: np.ndarray,
    fold: np.ndarray,
    T: np.ndarray,
    levels: dict | None,
    level: float = 0.95,
    n_sim: int = N_SIMULATIONS,
    calibration: tuple[int, int] | None = LOSO_CALIBRATION,
) -> tuple[float, float]:
    """Interval of a leave-one-specimen-out absolute error, the mean over the folds of a fold's
    expected error against a new specimen of the mix, mean_c E|pred_c - y_new,c|.

    Each fold's observed error against its held-out specimen, A_k = mean_c |pred_k,c - y_k,c|,
    estimates its fold's expectation T_k without bias (the fold's law did not see that
    specimen); but a specimen's deviation from the mix is shared by its cells (its level, and
    its level per isotherm), so A_k is skewed, and the folds' errors are not independent (each
    specimen is held out by one fold and trains the others), so three of them do not show their
    spread. The interval is model-based, a parametric bootstrap of the folds (Efron & Tibshirani
    1993, *An introduction to the bootstrap*, ch. 6): each fold's law is its training specimens'
    mean plus its own departure from it, eps_k,c = pred_k,c - (mean of the training specimens'
    values, ``train_mean``); new specimens x*_1..n are drawn from the table's levels of scatter
    (``levels``, :func:`level_variances`: a specimen's level, its level per isotherm, its cells'
    scatter); each fold then predicts mean_{j != k} x*_j + eps_k, its error against its own
    held-out x*_k is A*_k and its expectation against a new specimen is T*_k = mean_c
    E|pred*_k,c - x_new| (a folded normal's mean, :func:`folded_normal_mean`). The ratio R* =
    mean_k A*_k / mean_k T*_k does not depend on the scale of the scatter, only on its levels'
    proportions; the interval is mean_k A_k divided by two percentiles of R*.

    The specimen level is estimated from n - 1 degrees of freedom (2 with 3 specimens), so the
    percentiles at the estimated levels do not cover at their nominal rate. With ``calibration``
    = (B, M) they are calibrated by a second bootstrap level (prepivoting; Beran 1987,
    Biometrika 74, 457-468; Hall & Martin 1988, Biometrika 75, 661-671): B tables of specimens
    drawn from the estimated levels give each its ratio R_b against its true expectation and its
    own levels (the mean squares of :func:`nested_components`, :func:`_balanced_levels`); M draws
    at those levels give u_b, the fraction of their ratios below R_b; the percentiles used are
    the (1 - level) / 2 and (1 + level) / 2 quantiles of the u_b instead of the nominal ones.
    Without it (None) the nominal percentiles of R* at ``levels``, which may then hold a drawn
    specimen level (shape (n_sim,)).

    ``pred``, ``observed`` (the held-out specimen's value), ``train_mean``, ``fold``, ``T``: shape
    (rows,); (nan, nan) without levels or on folds that do not score the same cells. Raises
    ValueError for a drawn level with ``calibration``."""
    if levels is None or not len(pred):
        return np.nan, np.nan
    pred, observed, train_mean = (np.asarray(x, float) for x in (pred, observed, train_mean))
    folds = np.unique(fold)
    n = folds.size
    if n < 2 or not np.isfinite(train_mean).all():
        return np.nan, np.nan
    temps, t_idx = np.unique(np.round(np.asarray(T, float), 6), return_inverse=True)
    sel = [np.flatnonzero(fold == k) for k in folds]
    if len({s.size for s in sel}) != 1:  # the folds score different cells: not a balanced table
        return np.nan, np.nan
    cells = sel[0]
    if not all(
        np.array_equal(np.round(np.asarray(T, float)[s], 6), np.round(np.asarray(T, float)[cells], 6)) for s in sel
    ):
        return np.nan, np.nan
    ti = t_idx[cells]
    eps = np.stack([pred[s] - train_mean[s] for s in sel])  # (n, cells)
    estimate = float(np.mean([np.mean(np.abs(pred[s] - observed[s])) for s in sel]))
    if calibration is None:
        lo, hi = _loso_nominal(eps, ti, temps.size, levels, level, n_sim, np.random.default_rng([len(pred), n, 7]))
        return estimate / hi, estimate / lo
    if any(np.ndim(levels[k]) for k in levels):
        raise ValueError("loso_abs_interval: a calibrated interval takes the levels at their estimates, not drawn")
    if np.bincount(ti).max() < 2:  # the folds' cells hold no cell level to calibrate with (_balanced_levels)
        return np.nan, np.nan
    n_outer, n_inner = calibration
    rng = np.random.default_rng([len(pred), n, 11])

    def unit(m: int) -> tuple:  # standard normal draws of m tables: level, level per isotherm, cells
        return (
            rng.normal(0.0, 1.0, (m, n, 1)),
            rng.normal(0.0, 1.0, (m, n, temps.size))[:, :, ti],
            rng.normal(0.0, 1.0, (m, n, cells.size)),
        )

    s2 = np.array([float(levels[k]) for k in LEVELS])
    drawn, expected, x = _loso_ratio(unit(n_outer), s2, eps)
    ratio = drawn / expected
    own = _balanced_levels(x, ti, temps.size)  # (n_outer, 3)
    inner = tuple(z[None] for z in unit(n_inner))
    u = np.empty(n_outer)
    chunk = 16
    for b in range(0, n_outer, chunk):
        d_i, e_i, _ = _loso_ratio(inner, own[b : b + chunk, None, :], eps)
        with np.errstate(divide="ignore", invalid="ignore"):
            u[b : b + chunk] = np.mean(d_i / e_i <= ratio[b : b + chunk, None], axis=1)
    p_lo, p_hi = np.quantile(u, [(1 - level) / 2, (1 + level) / 2])
    d_s, e_s, _ = _loso_ratio(unit(n_sim), s2, eps)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = np.quantile(d_s / e_s, [p_lo, p_hi])
    return estimate / float(hi), estimate / float(lo)


def _loso_ratio(z: tuple, s2: np.ndarray, eps: np.ndarray) -> tuple:
    """(drawn, expected, x) of :func:`loso_abs_interval`'s simulated folds: standard normal draws
    ``z`` (three arrays (..., n, 1 | cells)) scaled by the levels ``s2`` (..., 3), specimens x;
    mean_k A*_k and mean_k T*_k over the last two axes."""
    n = eps.shape[0]
    s = np.sqrt(np.maximum(s2, 0.0))
    x = z[0] * s[..., 0, None, None] + z[1] * s[..., 1, None, None] + z[2] * s[..., 2, None, None]
    p = (x.sum(-2, keepdims=True) - x) / (n - 1) + eps
    drawn = np.mean(np.abs(p - x), axis=(-1, -2))
    expected = np.mean(folded_normal_mean(p, np.maximum(s2, 0.0).sum(-1)[..., None, None]), axis=(-1, -2))
    return drawn, expected, x


def _loso_nominal(eps, ti, n_T, levels, level, n_sim, rng) -> tuple[float, float]:
    """The nominal percentiles of R* (:func:`loso_abs_interval` without calibration); a level of
    shape (n_sim,) is drawn per simulation."""
    n = eps.shape[0]
    z = (
        rng.normal(0.0, 1.0, (n_sim, n, 1)),
        rng.normal(0.0, 1.0, (n_sim, n, n_T))[:, :, ti],
        rng.normal(0.0, 1.0, (n_sim, n, ti.size)),
    )
    s2 = np.stack(np.broadcast_arrays(*(np.asarray(levels[k], float) for k in LEVELS)), axis=-1)
    drawn, expected, _ = _loso_ratio(z, s2, eps)
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, hi = np.percentile(drawn / expected, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


def _training_means(spec: pd.DataFrame, fold: np.ndarray, T: np.ndarray, f: np.ndarray) -> dict:
    """Per row (a held-out specimen ``fold`` at the cell (T, f)): the mean of the other
    specimens' values at that cell (``lnE``, ``phase``; nan where none tested it)."""
    t = spec.reset_index()
    out = {}
    for q in ("lnE", "phase"):
        total = t.groupby(["T", "f"])[q].sum()
        count = t.groupby(["T", "f"])[q].size()
        own = t.set_index(["specimen", "T", "f"])[q]
        keys = pd.MultiIndex.from_arrays([T, f])
        mine = own.reindex(pd.MultiIndex.from_arrays([np.asarray(fold, str), T, f])).to_numpy(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[q] = (total.reindex(keys).to_numpy(float) - mine) / (count.reindex(keys).to_numpy(float) - 1)
    return out


def _loso_scores(g: pd.DataFrame, spec: pd.DataFrame | None = None, pop: _Population | None = None) -> dict:
    """Scores of leave-one-specimen-out rows: each fold's reference is its own specimen. The
    signed means get a t(n - 1) interval over the folds; the absolute means the model-based
    interval of :func:`loso_abs_interval` (with the table's specimens ``spec`` and their levels
    of scatter ``pop``; without them, or on folds that do not score the same cells, a t(n - 1)
    interval over the folds)."""
    eE = np.log(g["E_norm_MPa_predicted"].to_numpy(float) / g["E_norm_MPa_measured"].to_numpy(float))
    eP = g["phase_deg_predicted"].to_numpy(float) - g["phase_deg_measured"].to_numpy(float)
    fold = g["fold"].astype(str).to_numpy()
    model_based = spec is not None and pop is not None
    kind = ("loso" if LOSO_CALIBRATION else "loso_nominal") if model_based else "loso_t"
    out = {"n_specimens": int(np.unique(fold).size), "interval": INTERVALS[kind]}
    if model_based:
        assert spec is not None and pop is not None
        T = _round_T(g["cell_temperature_C"] if "cell_temperature_C" in g else g["temperature_C"])
        f = g["frequency_Hz"].to_numpy(float)
        train = _training_means(spec, fold, T, f)
        reference = {
            "logE": (
                np.log(g["E_norm_MPa_predicted"].to_numpy(float)),
                np.log(g["E_norm_MPa_measured"].to_numpy(float)),
                train["lnE"],
            ),
            "phase": (
                g["phase_deg_predicted"].to_numpy(float),
                g["phase_deg_measured"].to_numpy(float),
                train["phase"],
            ),
        }
    for q, e, scale, unit in (("logE", eE, 100.0, "pct"), ("phase", eP, 1.0, "deg")):
        per = pd.DataFrame({"fold": fold, "e": e, "a": np.abs(e)}).groupby("fold").mean()
        lo, hi = t_interval(per["e"])
        a_lo, a_hi = np.nan, np.nan
        if model_based and pop is not None:
            pred, obs, train_q = reference[q]
            # calibrated: the levels at their estimates; nominal: the specimen level drawn
            n_draw = 0 if LOSO_CALIBRATION else N_SIMULATIONS
            levels = level_variances(pop.comp, "lnE" if q == "logE" else "phase", n_draw, len(g))
            a_lo, a_hi = loso_abs_interval(pred, obs, train_q, fold, T, levels, calibration=LOSO_CALIBRATION)
        if not (np.isfinite(a_lo) and np.isfinite(a_hi)):
            out["interval"] = INTERVALS["loso_t"]
            a_lo, a_hi = t_interval(per["a"])
            a_lo = max(a_lo, 0.0) if np.isfinite(a_lo) else a_lo  # an absolute error is >= 0
        out.update(
            {
                f"bias_{q}_{unit}": scale * float(e.mean()),
                f"abs_{q}_{unit}": scale * float(np.abs(e).mean()),
                f"abs_{q}_vs_means_{unit}": scale * float(np.abs(e).mean()),
                f"bias_{q}_ci95_low": scale * lo,
                f"bias_{q}_ci95_high": scale * hi,
                f"abs_{q}_ci95_low": scale * a_lo,
                f"abs_{q}_ci95_high": scale * a_hi,
            }
        )
    return out


def noise_floor(table: pd.DataFrame) -> pd.DataFrame:
    """Per temperature, the noise floor of a replicate-mean reference: the mean over the
    isotherm's cells of the standard error of the replicate mean, relative to the mean, for
    |E*| and for Phi (%), and the number of specimens.

    Columns ``temperature_C, noise_floor_E_norm_pct, noise_floor_phase_pct, n_specimens``;
    nan where a cell has a single replicate (no scatter to measure).
    """
    g = table.groupby(["temperature_C", "frequency_Hz"])
    cells = pd.DataFrame(
        {
            "n": g["E_norm_MPa"].size(),
            "se_E": g["E_norm_MPa"].std(ddof=1) / np.sqrt(g["E_norm_MPa"].size()) / g["E_norm_MPa"].mean(),
            "se_P": g["phase_deg"].std(ddof=1) / np.sqrt(g["phase_deg"].size()) / g["phase_deg"].mean(),
        }
    )
    cells = cells.reset_index()
    out = (
        cells.groupby("temperature_C")
        .agg(noise_floor_E_norm_pct=("se_E", "mean"), noise_floor_phase_pct=("se_P", "mean"))
        .reset_index()
    )
    out[["noise_floor_E_norm_pct", "noise_floor_phase_pct"]] *= 100.0
    spec = table.groupby("temperature_C")["specimen"].nunique().rename("n_specimens").reset_index()
    return out.merge(spec, on="temperature_C")


def summarize(rows: pd.DataFrame, table: pd.DataFrame | None = None) -> pd.DataFrame:
    """Scores per (scheme, kind, model, temperature, extrapolation) and pooled over the
    temperatures (``temperature_C`` NaN), columns :data:`SUMMARY_COLUMNS` (module docstring).
    Without the measured ``table`` only the loso rows and the MREs get scores (the others
    need the specimens' values)."""
    spec = specimen_values(table) if table is not None else None
    pop = _Population(spec) if spec is not None else None
    floor = noise_floor(table) if table is not None else None
    out = []
    rows = rows.assign(extrapolation=rows["extrapolation"].astype(bool), cell_temperature_C=rows["temperature_C"])
    pooled = rows.assign(temperature_C=np.nan)
    for frame in (rows, pooled):
        for key, g in frame.groupby(_KEYS, sort=True, dropna=False):
            ok = g[g["computable"]]
            r = dict(zip(_KEYS, key))
            r.update(
                {
                    "n_cells": int(len(ok)),
                    "n_not_computable": int(len(g) - len(ok)),
                    "mre_E_norm_pct": 100 * float(ok["rel_err_E_norm"].mean()) if len(ok) else np.nan,
                    "mre_phase_pct": 100 * float(ok["rel_err_phase"].mean()) if len(ok) else np.nan,
                }
            )
            if len(ok):
                if key[0] == "loso" and key[1] == "held_out":
                    r.update(_loso_scores(ok, spec, pop))
                elif spec is not None:
                    assert pop is not None  # made with spec
                    r.update(_specimen_scores(ok, spec, pop, key[0] if key[1] == "held_out" else ""))
            if floor is not None:
                f = (
                    floor
                    if np.isnan(r["temperature_C"])
                    else floor[np.isclose(floor["temperature_C"], r["temperature_C"], atol=1e-6, rtol=0)]
                )
                r["noise_floor_E_norm_pct"] = float(f["noise_floor_E_norm_pct"].mean()) if len(f) else np.nan
                r["noise_floor_phase_pct"] = float(f["noise_floor_phase_pct"].mean()) if len(f) else np.nan
            out.append(r)
    return pd.DataFrame(out).reindex(columns=SUMMARY_COLUMNS)


def headline(summary: pd.DataFrame) -> pd.DataFrame:
    """Per (scheme, kind, model): the pooled scores over the interpolated cells (lofo without
    its end frequencies, loto without its end temperatures; every cell of loso and of the
    in-sample rows) with their intervals, the pooled extrapolated ones apart, and the
    temperature whose absolute |E*| error is the largest (marked, not the headline).
    Columns: ``scheme, kind, model`` and, prefixed ``interp_`` / ``extrap_``, the score
    columns of :data:`SUMMARY_COLUMNS`; ``worst_T_C``, ``worst_abs_logE_pct``."""
    scores = [c for c in SUMMARY_COLUMNS if c not in _KEYS]
    out = []
    for key, g in summary.groupby(["scheme", "kind", "model"], sort=True):
        row = dict(zip(["scheme", "kind", "model"], key))
        pooled = g[g["temperature_C"].isna()]
        for label, sel in (("interp", ~pooled["extrapolation"]), ("extrap", pooled["extrapolation"])):
            p = pooled[sel]
            for c in scores:
                row[f"{label}_{c}"] = p.iloc[0][c] if len(p) else np.nan
        per_T = g[g["temperature_C"].notna() & ~g["extrapolation"]].dropna(subset=["abs_logE_pct"])
        if len(per_T):
            w = per_T.loc[per_T["abs_logE_pct"].idxmax()]
            row["worst_T_C"], row["worst_abs_logE_pct"] = float(w["temperature_C"]), float(w["abs_logE_pct"])
        else:
            row["worst_T_C"], row["worst_abs_logE_pct"] = np.nan, np.nan
        out.append(row)
    return pd.DataFrame(out)
