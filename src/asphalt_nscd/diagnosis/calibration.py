"""Error control of the whole artifact procedure, calibrated on the table itself.

The artifact procedure (:class:`asphalt_nscd.diagnosis.effects.ArtifactSearch`) names an
artifact if and only if its statistic ``min_p`` (the smallest first-step p-value among
candidates of the right sign and practical size, and the offset test's) is below the first
step's level. Its nominal level alpha / m holds only where the F-tests' assumptions hold: a
table the screening model fits worse than its replicate scatter allows makes every nominal
p-value too small, and where the screening model cannot follow the material its misfit runs
smoothly along frequency and temperature, as an artifact's signature does. So the level is
calibrated on the table (Westfall & Young 1993, the single-step min-P procedure) by parametric
bootstraps of two fitted clean models of it (Davison & Hinkley 1997, section 4.2), and the more
conservative level is used:

* **the screening null** (``2s2p1d``): the screening fit (2S2P1D master curve, vertical factor
  per isotherm, specimen factors and phase offsets) with the smooth shift law and no artifact;
* **the relaxation-spectrum null** (``maxwell``, :func:`maxwell_model`): a generalized Maxwell
  master curve with any non-negative spectrum on a log-spaced grid (NNLS inside a least-squares
  fit of the shift law, vertical and specimen factors; :data:`MAXWELL_DENSITIES` terms per
  decade, widened by :data:`MAXWELL_MARGIN_DECADES`, the density of smallest BIC). Every linear
  viscoelastic, thermorheologically simple material has such a spectrum (Tschoegl 1989, ch. 3),
  so its tables carry the screening model's smooth misfit as it is; what no such material gives
  (time lag, inertia, an isotherm off the shift law, strain or test-order dependence) is not in it;
* **their noise**: the replicate scatter of ln|E*| and Phi plus a misfit shared by a cell's
  specimens (the variance the null's own fit leaves in the cell means beyond the point scatter);
* **the table's design**: the same rows, specimens, strains and test order.

On B seeded tables of each null the whole procedure gives min_p_b; a null's calibrated level is
its k-th smallest min_p_b, k = floor(rate (B + 1)) (config ``diagnosis.calibration.familywise_rate``),
a Monte Carlo test (Davison & Hinkley 1997, 4.2.1): a table of the null is named with probability
k / (B + 1) <= rate, exactly when its calibrated p-value (1 + #{min_p_b <= p}) / (B + 1), the larger
over the nulls (:func:`asphalt_nscd.diagnosis.effects.adjusted_p`), is at most the rate; too few
tables for k >= 1 are refused (:func:`min_tables`). The procedure uses the smaller of the nulls'
levels and alpha / m; its rate is measured out of sample by cross-fitted halves (Clopper-Pearson),
when each half has the tables to set a level of its own.

The static-modulus test (:mod:`asphalt_nscd.diagnosis.causes`) is calibrated on tables of the
liquid master curve (E00 = 0) with the screening null's noise, p = (1 + #{F_b >= F}) / (B + 1).
The family is the two groups, artifacts and static modulus, each at half the family-wise rate.

Choices and their measurements: docs/choices.md, Diagnosis: error control on the table itself.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..rheology.master_curve import fit_master_curve
from .effects import ArtifactSearch, f_test
from .scores import binomial_ci

#: bootstrap tables of a calibration (config ``diagnosis.calibration.tables``)
N_TABLES = 200
#: family-wise false-alarm rate the procedure is calibrated to (config ``diagnosis.calibration.familywise_rate``)
FAMILYWISE_RATE = 0.05
#: groups of the family (artifacts, static modulus), each at FAMILYWISE_RATE / GROUPS
GROUPS = 2
#: the nulls of the artifact procedure's calibration (module docstring), in the order their
#: tables are run; each null's tables are drawn from the generator ``default_rng([seed, k])``
NULLS = {"2s2p1d": 1, "maxwell": 3}
#: the rule of the calibrated level (:func:`critical_level`), recorded with every benchmark
#: checkpoint line so that a line computed under another rule is not read back
LEVEL_RULE = "k-th smallest, k = floor(rate (B + 1))"
#: terms per decade of relaxation time tried for the relaxation-spectrum null (the smallest BIC is used)
MAXWELL_DENSITIES = (1.0, 1.5, 2.0)
#: decades of relaxation time beyond the table's reduced band at each end of the spectrum's grid
MAXWELL_MARGIN_DECADES = 2.0


@dataclass
class CleanModel:
    """A table's fitted clean model (module docstring).

    ``E``: complex modulus of every row of ``rows`` (MPa, shape (n,)); ``sigma_point``: point
    scatter of ln|E*| and Phi (deg); ``sigma_cell``: the cell misfit's standard deviations
    (same units); ``x0``: the parameters of the fit (a warm start for the simulated tables);
    ``rows``: the design (the table without its measured values); ``info``: its description
    (JSON-ready)."""

    E: np.ndarray
    sigma_point: tuple
    sigma_cell: tuple
    x0: np.ndarray
    rows: pd.DataFrame
    #: what the model is (for the calibration JSON and the page)
    info: dict = field(default_factory=dict)


def cell_misfit(rows: pd.DataFrame, residual_lnE, residual_phase, sigma_point, n_params: int) -> tuple:
    """Standard deviations (ln|E*|, Phi in deg) of a misfit shared by a cell's specimens:
    the mean squared cell-mean residual (per degree of freedom, cells minus ``n_params``)
    less the point scatter's share sigma^2 / n_cell, floored at 0. Residuals unweighted,
    shapes (n,)."""
    key = rows["temperature_C"].round(6).astype(str) + "|" + rows["frequency_Hz"].astype(str)
    frame = pd.DataFrame(
        {"k": key.to_numpy(), "e": np.asarray(residual_lnE, float), "p": np.asarray(residual_phase, float)}
    )
    g = frame.groupby("k")
    n = g.size().to_numpy(float)
    dof = max(n.size - int(n_params), 1)
    out = []
    for col, s in (("e", sigma_point[0]), ("p", sigma_point[1])):
        m = g[col].mean().to_numpy(float)
        out.append(float(np.sqrt(max(np.sum(m**2) / dof - np.mean(s**2 / n), 0.0))))
    return tuple(out)


def clean_model(search: ArtifactSearch, base) -> CleanModel:
    """The clean model of ``search``'s table from its screening fit ``base`` (module
    docstring): smooth shifts in place of the free ones, everything else as fitted."""
    x = np.asarray(base.x, float).copy()
    temps, a, cov = search.free_shifts(base)
    res, g, _ = search._smooth_law(temps, a, cov)
    smooth = g(temps, res.x, search.T_screen) - g(np.array([search.T_screen]), res.x, search.T_screen)[0]
    for i, T in enumerate(temps):
        name = f"log10_aT_{T:g}"
        if name in base.names:
            x[base.names.index(name)] = smooth[i]
    prob = search.problem([])
    E = prob.measured_modulus(x)
    sE, sP = search.replicate_sigma
    point = (sE if sE is not None else search.sigma[0], sP if sP is not None else search.sigma[1])
    fitted = prob.measured_modulus(base.x)
    d = search.data
    n_spec = len(d["specimens"])
    cell = cell_misfit(
        search.df,
        np.log(np.abs(fitted)) - d["lnE"],
        np.degrees(np.angle(fitted)) - d["phase"],
        point,
        base.n_params - 2 * (n_spec - 1),
    )
    keep = [c for c in search.df.columns if c not in ("E_norm_MPa", "phase_deg")]
    info = {
        "model": "2S2P1D screening fit",
        "shifts": f"smooth {search.shift.upper()} law through the free shifts",
        "chi2_per_dof": float(search.chi2_per_dof(base)),
    }
    return CleanModel(E=E, sigma_point=point, sigma_cell=cell, x0=x, rows=search.df[keep].copy(), info=info)


def relaxation_grid(omega, per_decade: float, margin: float = MAXWELL_MARGIN_DECADES) -> np.ndarray:
    """Relaxation times (s, shape (n,)) log-spaced at ``per_decade`` per decade from
    10^-margin / max(omega) to 10^margin / min(omega) (``omega``: reduced angular frequencies,
    rad/s)."""
    lo = -np.log10(np.max(omega)) - margin
    hi = -np.log10(np.min(omega)) + margin
    return 10.0 ** np.linspace(lo, hi, int(np.ceil((hi - lo) * per_decade)) + 1)


def maxwell_columns(omega, rho) -> np.ndarray:
    """Columns of a generalized Maxwell series at ``omega`` (rad/s, shape (m,)): 1 (the static
    modulus) and i w rho_j / (1 + i w rho_j) per relaxation time, shape (m, 1 + n)."""
    iw = 1j * np.asarray(omega, float)[:, None]
    return np.column_stack([np.ones(iw.shape[0], complex), iw * rho / (1.0 + iw * rho)])


def maxwell_weights(C: np.ndarray, Y: np.ndarray, sigma) -> np.ndarray:
    """Non-negative weights x (MPa, shape (1 + n,)) of the columns ``C`` (m, 1 + n) fitting
    the complex modulus ``Y`` (m,): least squares on the first-order residuals of ln|E*| and Phi
    (Re and Im of (C x - Y) / Y, divided by ``sigma`` = (sigma of ln|E*|, of Phi in deg)),
    scipy.optimize.nnls on scaled columns."""
    from scipy.optimize import nnls

    A = C * (np.exp(-1j * np.angle(Y)) / np.abs(Y))[:, None]
    M = np.vstack([A.real / sigma[0], A.imag / np.radians(sigma[1])])
    b = np.concatenate([np.full(Y.size, 1.0 / sigma[0]), np.zeros(Y.size)])
    norms = np.linalg.norm(M, axis=0)
    norms[norms == 0] = 1.0
    x, _ = nnls(M / norms, b, maxiter=100 * M.shape[1])
    return x / norms


class _MaxwellFit:
    """The relaxation-spectrum null's fit (module docstring) on a search's table: parameters
    theta = (shift law constants but its offset, ln vertical factor per isotherm but the reference, ln |E*|
    factor and phase offset (deg) per specimen but the first), the spectrum by NNLS inside."""

    def __init__(self, search, per_decade: float):
        from .effects import _shift_law

        d = search.data
        self.data, self.sigma, self.T_ref = d, search.sigma, search.T_screen
        # the law's free offset (its first constant) is the spectrum's: held at 0
        self.law, x0, lo, hi = _shift_law(search.shift)
        self.n_law = len(x0) - 1
        temps = d["temperatures"]
        self.others = np.flatnonzero(np.abs(temps - self.T_ref) > 1e-9)
        self.t_idx = np.searchsorted(temps, d["T"])
        self.n_spec = len(d["specimens"])
        self.Y0 = np.exp(d["lnE"] + 1j * np.radians(d["phase"]))
        self.per_decade = per_decade
        k, m = self.others.size, self.n_spec - 1
        lo_law, hi_law = np.array(lo[1:], float), np.array(hi[1:], float)
        if search.shift == "wlf":  # C2 + T - T_ref > 0 at every isotherm
            lo_law[1] = max(lo_law[1], self.T_ref - temps.min() + 1.0)
        self.lower = np.concatenate([lo_law, np.full(k, -1.0), np.full(m, -1.0), np.full(m, -10.0)])
        self.upper = np.concatenate([hi_law, np.full(k, 1.0), np.full(m, 1.0), np.full(m, 10.0)])
        self.rho = np.zeros(0)

    def split(self, theta):
        k, m = self.others.size, self.n_spec - 1
        law = np.concatenate([[0.0], theta[: self.n_law]])
        v = np.zeros(self.data["temperatures"].size)
        v[self.others] = theta[self.n_law : self.n_law + k]
        c = np.concatenate([[0.0], theta[self.n_law + k : self.n_law + k + m]])
        p = np.concatenate([[0.0], theta[self.n_law + k + m :]])
        return law, v, c, p

    def log_shift(self, law, T) -> np.ndarray:
        """log10 aT of the shift law ``law`` at ``T`` (degC), 0 at the reference isotherm."""
        return self.law(T, law, self.T_ref)

    def factors(self, theta):
        """(K, omega): each row's vertical and specimen factor (complex) and reduced angular
        frequency (rad/s)."""
        d = self.data
        law, v, c, p = self.split(theta)
        K = np.exp(v[self.t_idx] + c[d["spec"]] + 1j * np.radians(p[d["spec"]]))
        return K, 2 * np.pi * d["f"] * 10.0 ** self.log_shift(law, d["T"])

    def modulus(self, theta, x=None):
        """Fitted modulus of every row (MPa) and the spectrum weights (NNLS when not given)."""
        K, omega = self.factors(theta)
        C = maxwell_columns(omega, self.rho)
        if x is None:
            x = maxwell_weights(C, self.Y0 / K, self.sigma)
        return (C @ x) * K, x

    def residuals(self, theta) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            E, _ = self.modulus(theta)
            r = np.concatenate(
                [
                    (np.log(np.abs(E)) - self.data["lnE"]) / self.sigma[0],
                    (np.degrees(np.angle(E)) - self.data["phase"]) / self.sigma[1],
                ]
            )
        return np.where(np.isfinite(r), r, 1e3)

    def fit(self, theta0):
        from scipy.optimize import least_squares

        theta0 = np.clip(theta0, self.lower + 1e-9, self.upper - 1e-9)
        _, omega = self.factors(theta0)
        self.rho = relaxation_grid(omega, self.per_decade)
        res = least_squares(self.residuals, theta0, bounds=(self.lower, self.upper), x_scale="jac", max_nfev=300)
        E, x = self.modulus(res.x)
        r = self.residuals(res.x)
        return res.x, x, E, float(np.sum(r**2))


def maxwell_model(search: ArtifactSearch, base, clean: CleanModel) -> CleanModel:
    """The relaxation-spectrum null of ``search``'s table (module docstring), started from its
    screening fit ``base`` (its free shifts give the shift law's start, its specimen terms
    theirs); every density of :data:`MAXWELL_DENSITIES` is fitted and the one with the smallest
    BIC = rss + p ln(n) (weighted residuals, p = positive spectrum weights + the other
    parameters) is kept. Its mean uses the fitted smooth shift law, its cell misfit the fit's
    residuals (cells minus the parameters that describe cell means), ``x0`` and the point
    scatter those of ``clean`` (the screening null)."""
    d = search.data
    temps, a, cov = search.free_shifts(base)
    res, _, _ = search._smooth_law(temps, a, cov)
    names = base.names
    spec = [float(base.x[names.index(n)]) for n in names if n.startswith("ln_factor_")]
    spec += [float(base.x[names.index(n)]) for n in names if n.startswith("phase_offset_deg_")]
    n_res = 2 * d["f"].size
    best = None
    for per_decade in MAXWELL_DENSITIES:
        fit = _MaxwellFit(search, per_decade)
        theta0 = np.concatenate([res.x[1:], np.zeros(fit.others.size), spec])
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            theta, x, E, rss = fit.fit(theta0)
        n_pos = int(np.sum(x > 0))
        p = n_pos + theta.size
        bic = rss + p * np.log(n_res)
        if best is None or bic < best[0]:
            best = (bic, fit, theta, x, E, rss, n_pos)
    assert best is not None  # MAXWELL_DENSITIES is not empty
    bic, fit, theta, x, E, rss, n_pos = best
    n_spec = fit.n_spec
    cell = cell_misfit(
        search.df,
        np.log(np.abs(E)) - d["lnE"],
        np.degrees(np.angle(E)) - d["phase"],
        clean.sigma_point,
        n_pos + theta.size - 2 * (n_spec - 1),
    )
    info = {
        "model": "generalized Maxwell (Prony) master curve, non-negative spectrum",
        "shifts": f"{search.shift.upper()} law fitted with the spectrum",
        "terms_per_decade": float(fit.per_decade),
        "relaxation_times": int(fit.rho.size),
        "positive_terms": int(np.sum(x[1:] > 0)),
        "chi2_per_dof": float(rss / max(n_res - n_pos - theta.size, 1)),
        "bic": float(bic),
    }
    return CleanModel(E=E, sigma_point=clean.sigma_point, sigma_cell=cell, x0=clean.x0, rows=clean.rows, info=info)


def simulate(model: CleanModel, rng: np.random.Generator, E=None) -> pd.DataFrame:
    """One table of ``model`` (``E``: another complex modulus per row, e.g. the liquid
    model's): the design's rows with |E*| and Phi drawn from the model with its cell misfit
    and point scatter."""
    rows = model.rows
    E = model.E if E is None else np.asarray(E)
    key = rows["temperature_C"].round(6).astype(str) + "|" + rows["frequency_Hz"].astype(str)
    codes, uniq = pd.factorize(key)
    ce = rng.normal(0.0, model.sigma_cell[0], uniq.size)[codes]
    cp = rng.normal(0.0, model.sigma_cell[1], uniq.size)[codes]
    lnE = np.log(np.abs(E)) + ce + rng.normal(0.0, model.sigma_point[0], E.size)
    phase = np.degrees(np.angle(E)) + cp + rng.normal(0.0, model.sigma_point[1], E.size)
    out = rows.copy()
    out["E_norm_MPa"] = np.exp(lnE)
    out["phase_deg"] = np.clip(phase, 0.01, 89.9)
    return out


def level_rank(rate: float, n_tables: int) -> int:
    """k = floor(rate (B + 1)), the rank of the null statistic that is the calibrated level of a
    Monte Carlo test at ``rate`` on B = ``n_tables`` tables (module docstring; 0: none can be
    named)."""
    return int(np.floor(rate * (int(n_tables) + 1) + 1e-9))


def fewest_tables(rate: float) -> int:
    """The fewest tables B with :func:`level_rank` (``rate``, B) >= 1, the fewest on which a
    Monte Carlo level at ``rate`` can name anything: B >= 1 / rate - 1."""
    return int(np.ceil(1.0 / rate - 1.0 - 1e-9))


def min_tables(rate: float = FAMILYWISE_RATE) -> int:
    """The fewest bootstrap tables per null with which the artifact procedure, at its share
    rate / GROUPS of the family-wise ``rate``, can name anything (:func:`fewest_tables`:
    B >= GROUPS / rate - 1; 39 at the default 0.05), and at least 20."""
    return max(20, fewest_tables(rate / GROUPS))


def critical_level(min_p, rate: float) -> float:
    """The calibrated level of the B statistics ``min_p`` of a null's tables at ``rate``: their
    k-th smallest, k = :func:`level_rank` (a new table of the null has p < level with probability
    k / (B + 1) <= rate, and p < level exactly when (1 + #{min_p_b <= p}) / (B + 1) <= rate, the
    calibrated p-value of :func:`asphalt_nscd.diagnosis.effects.adjusted_p`); 0 when k = 0 (too
    few tables for the rate: nothing is named); 1 when k > B."""
    m = np.sort(np.asarray(min_p, float))
    k = level_rank(rate, m.size)
    if k == 0:
        return 0.0
    return float(m[k - 1]) if k <= m.size else 1.0


def cross_fitted_rate(stat: dict, group_rate: float, nominal: float) -> dict:
    """The calibrated level's false-alarm rate out of sample: the B statistics of each null split
    in halves, each half's level (the smaller over the nulls' :func:`critical_level` and the
    ``nominal`` one) judged on the other half, per null (Clopper-Pearson 95 % interval).

    Parameters
    ----------
    stat : dict
        Per null, its tables' statistics min_p_b, shape (B,).
    group_rate : float
        The artifacts' share of the family-wise rate.
    nominal : float
        The nominal level alpha / m.

    Returns
    -------
    dict: ``k, n, rate, ci95`` under the null where the rate is largest, ``null``, ``per_null``
    (each null's ``k, n, rate, ci95``), ``method``, ``half_tables`` (the smaller half) and
    ``half_min_tables`` (the fewest with :func:`level_rank` >= 1). When a half is fewer (it names
    nothing by construction, a vacuous rate of 0), ``k``, ``rate`` and ``ci95`` are None.
    """
    halves = {}
    for name, v in stat.items():
        w = np.asarray(v, float)
        halves[name] = (w[: w.size // 2], w[w.size // 2 :])
    half_tables = min(min(h[0].size, h[1].size) for h in halves.values())
    need = fewest_tables(group_rate)
    can_name = half_tables >= need
    # each half's level: the smaller over the nulls' calibrated levels and the nominal one
    level = [min([critical_level(h[i], group_rate) for h in halves.values()] + [nominal]) for i in (0, 1)]

    rates: dict[str, dict] = {}
    for name, (first, second) in halves.items():
        n = first.size + second.size
        if not can_name or n == 0:
            rates[name] = {"k": None, "n": n, "rate": None, "ci95": None}
            continue
        k = int(np.sum(second < level[0]) + np.sum(first < level[1]))
        lo, hi = binomial_ci(k, n)
        rates[name] = {"k": k, "n": n, "rate": k / n, "ci95": [lo, hi]}
    worst = max(rates, key=lambda n: rates[n]["rate"] or 0.0)
    return {
        **rates[worst],
        "null": worst,
        "per_null": rates,
        "method": "cross-fitted halves: each half's level judged on the other half, under each null",
        "half_tables": int(half_tables),
        "half_min_tables": need,
    }


def _artifact_stat(args) -> float:
    table, test, alpha, shift, limits, x0 = args
    search = ArtifactSearch(table, alpha=alpha, shift=shift, test=test, limits=limits)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return float(search.run(level=0.0, x0=x0)["min_p"])


def _static_stat(args) -> float:
    table, shift, T_ref_C, x_full, x_liquid = args
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        full = fit_master_curve(table, shift=shift, T_ref_C=T_ref_C, x0=x_full)
        liquid = fit_master_curve(table, shift=shift, T_ref_C=T_ref_C, static_modulus=False, x0=x_liquid)
    F, _ = f_test(liquid.rss, full.rss, 1, full.n_residuals - full.n_params)
    return float(F) if np.isfinite(F) else 0.0


def _map(fn, tasks, jobs: int):
    if jobs > 1 and len(tasks) > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            return list(pool.map(fn, tasks, chunksize=max(1, len(tasks) // (4 * jobs))))
    return [fn(t) for t in tasks]


def calibrate(
    table: pd.DataFrame,
    alpha: float = 1e-3,
    shift: str = "wlf",
    test=None,
    limits=None,
    n_tables: int = N_TABLES,
    seed: int = 0,
    rate: float = FAMILYWISE_RATE,
    jobs: int = 1,
    static: bool = True,
    decide: float | None = None,
) -> dict:
    """Calibrate the artifact procedure and the static-modulus test on ``table`` (module
    docstring).

    Parameters
    ----------
    table : DataFrame
        Measured table (``lab.measured.load_measured``).
    alpha, shift, test, limits
        The search's settings (:class:`~asphalt_nscd.diagnosis.effects.ArtifactSearch`).
    n_tables : int
        Bootstrap tables B (>= 20).
    seed : int
        Seed of the tables (the same seed, table and settings give the same numbers).
    rate : float
        Family-wise false-alarm rate of the whole procedure, in (0, 1).
    jobs : int
        Worker processes.
    static : bool
        Calibrate the static-modulus test too (False: the artifact procedure only, e.g. the
        detection benchmark's recount of its false alarms; ``static`` is then None).
    decide : float, optional
        A statistic to decide on (the table's own ``min_p``): the nulls' bootstrap tables are
        run in turn (one of each null) and stopped once k (:func:`level_rank`) of one null's reach
        it (``min_p_b <= decide``): the calibrated level is then at most ``decide``, so ``decide``
        is no alarm whatever the other tables give (curtailed sampling: the same decision as
        all B tables of both nulls). The nulls' ``null_min_p`` then hold the tables run,
        ``n_run`` their number and ``calibrated_level`` is the upper bound the run tables give
        (``calibrated_level_bound``: True).

    Returns
    -------
    dict (JSON-ready): ``n_tables, seed, familywise_rate``, ``clean_model`` (the screening
    null's noise and cell misfit, the observed screening reduced chi-square), ``artifacts``
    (``family_size``, ``nominal_level``, ``calibrated_level`` c (the smaller over the nulls),
    ``level`` = min(c, nominal), ``binding_null``, ``nulls`` (per null of :data:`NULLS`: its
    ``calibrated_level``, ``null_min_p`` (B values), ``n_run`` and ``model``, what it is and its
    cell misfit), ``null_min_p`` (the binding null's), the cross-fitted ``rate`` with its 95 %
    interval (under the null where it is largest; ``per_null``; ``k``, ``rate`` and ``ci95``
    None when a half of the tables is too few to set its own level, fewer than
    ``half_min_tables``), ``exact_rate`` k / (B + 1), the probability that the level names a
    table of a null (exchangeability)), ``static`` (``null_F`` (B values) and the level),
    ``cpu_seconds``.

    Raises
    ------
    ValueError
        on a rate outside (0, 1), or fewer tables than :func:`min_tables` (with which nothing
        could be named).
    """
    if not 0.0 < rate < 1.0:
        raise ValueError(f"rate must lie in (0, 1), got {rate}")
    if int(n_tables) < min_tables(rate):
        raise ValueError(
            f"n_tables must be >= {min_tables(rate)} to hold a family-wise rate of {rate:g} "
            f"({rate / GROUPS:g} per group), got {n_tables}"
        )
    c0 = _cpu()
    search = ArtifactSearch(table, alpha=alpha, shift=shift, test=test, limits=limits)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        observed = search.run()
        base = observed["base"]
        model = clean_model(search, base)
        models = {"2s2p1d": model, "maxwell": maxwell_model(search, base, model)}
    group_rate = rate / GROUPS
    B = int(n_tables)
    k = level_rank(group_rate, B)
    tasks = {}
    for name, m in models.items():
        rng = np.random.default_rng([int(seed), NULLS[name]])
        tasks[name] = [(simulate(m, rng), test, alpha, shift, limits, m.x0) for _ in range(B)]
    stat: dict[str, list] = {name: [] for name in models}
    curtailed = False
    if decide is None:
        flat = [(name, t) for name in models for t in tasks[name]]
        for (name, _), v in zip(flat, _map(_artifact_stat, [t for _, t in flat], jobs)):
            stat[name].append(v)
    else:
        # the nulls' tables in turn, stopped once either null has more than its share reaching
        # ``decide``: the calibrated level is then at most ``decide`` whatever the other tables give
        for b in range(B):
            for name in models:
                stat[name].append(_artifact_stat(tasks[name][b]))
            if any(np.sum(np.asarray(stat[n]) <= decide) >= k for n in models):
                curtailed = b + 1 < B
                break
    nominal = float(observed["nominal_level"])
    per_null: dict[str, dict] = {}
    for name, m in models.items():
        v = np.asarray(stat[name], float)
        if curtailed:  # the k-th smallest of the tables run bounds the level from above
            c = float(np.sort(v)[k - 1])
        else:
            c = critical_level(v, group_rate)
        per_null[name] = {
            "calibrated_level": c,
            "null_min_p": [float(x) for x in v],
            "n_run": int(v.size),
            "model": {
                **m.info,
                "sigma_cell_lnE": float(m.sigma_cell[0]),
                "sigma_cell_phase_deg": float(m.sigma_cell[1]),
            },
        }
    binding = min(per_null, key=lambda n: per_null[n]["calibrated_level"])
    c = per_null[binding]["calibrated_level"]
    rate_out = cross_fitted_rate(stat, group_rate, nominal)
    out = {
        "n_tables": B,
        "seed": int(seed),
        "familywise_rate": float(rate),
        "groups": GROUPS,
        "alpha": float(alpha),
        "shift": shift,
        "limits": dict(search.limits),
        "clean_model": {
            "sigma_point_lnE": float(model.sigma_point[0]),
            "sigma_point_phase_deg": float(model.sigma_point[1]),
            "sigma_cell_lnE": float(model.sigma_cell[0]),
            "sigma_cell_phase_deg": float(model.sigma_cell[1]),
            "screening_chi2_per_dof": float(search.chi2_per_dof(base)),
            "shifts": f"smooth {shift.upper()} law through the free shifts",
        },
        "artifacts": {
            "family_size": int(observed["family_size"]),
            "nominal_level": nominal,
            "calibrated_level": c,
            "level": min(c, nominal),
            "binding": "calibrated" if c < nominal else "nominal",
            "binding_null": binding,
            "observed_min_p": float(observed["min_p"]),
            "null_min_p": per_null[binding]["null_min_p"],
            "nulls": per_null,
            "n_run": int(sum(p["n_run"] for p in per_null.values())),
            "calibrated_level_bound": curtailed,
            "rate": rate_out,
            # by exchangeability, a table of a null is named at its level with probability k / (B + 1)
            "exact_rate": k / (B + 1),
        },
        "static": None,
    }
    if not static:
        out["cpu_seconds"] = _cpu() - c0
        return out
    # the static modulus: tables of the liquid master curve
    T_ref = search.T_screen
    full = fit_master_curve(search.df, shift=shift, T_ref_C=T_ref, sigma=search.sigma)
    liquid = fit_master_curve(search.df, shift=shift, T_ref_C=T_ref, static_modulus=False, sigma=search.sigma)
    assert liquid.fitted is not None  # set by every fit
    E_liq = liquid.fitted["E_norm_MPa_model"].to_numpy(float) * np.exp(
        1j * np.radians(liquid.fitted["phase_deg_model"].to_numpy(float))
    )
    rng_s = np.random.default_rng([int(seed), 2])
    sims_s = [simulate(model, rng_s, E=E_liq) for _ in range(int(n_tables))]
    F = _map(_static_stat, [(t, shift, T_ref, full.x, liquid.x) for t in sims_s], jobs)
    out["static"] = {
        "level": float(group_rate),
        "null_F": [float(v) for v in F],
        "model": f"liquid 2S2P1D master curve (E00 = 0), {shift.upper()} shifts",
    }
    out["cpu_seconds"] = _cpu() - c0
    return out


def _cpu() -> float:
    """CPU seconds of this process and its finished worker processes."""
    import resource

    return time.process_time() + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime


def null_statistics(calibration: dict | None) -> list | None:
    """The procedure's statistic on each null's tables of a calibration (a list of lists, one
    per null; a calibration written with one null gives one), None without a calibration: what
    :func:`asphalt_nscd.diagnosis.effects.adjusted_p` takes."""
    if calibration is None:
        return None
    a = calibration["artifacts"]
    if "nulls" in a:
        return [list(v["null_min_p"]) for v in a["nulls"].values()]
    return [list(a["null_min_p"])]


def static_p(F: float, calibration: dict | None) -> float | None:
    """Calibrated p-value (1 + #{F_b >= F}) / (B + 1) of an observed static-modulus F (None
    without a calibration or a finite F)."""
    if calibration is None or F is None or not np.isfinite(F):
        return None
    null = np.asarray(calibration["static"]["null_F"], float)
    return float((1 + np.sum(null >= F)) / (null.size + 1))
