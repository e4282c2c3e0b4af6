"""Error control of the whole artifact procedure, calibrated on the table itself.

The artifact procedure (:class:`asphalt_nscd.diagnosis.effects.ArtifactSearch`: the
identifiability check, every candidate, the forward steps under Holm, the temperature-offset
test) names an artifact if and only if its statistic ``min_p`` (the smallest first-step
p-value among candidates of the right sign and practical size, and the offset test's) is below
the first step's level. Its nominal level alpha / m holds only where the F-tests' assumptions
hold; a table that the screening model fits worse than its replicate scatter allows (a reduced
chi-square above 1) makes every nominal p-value too small. So the level is calibrated on the
table itself (Westfall & Young 1993, *Resampling-based multiple testing*, the single-step
min-P procedure), by a parametric bootstrap of the table's own fitted clean model:

* **the clean model**: the screening fit of the table (2S2P1D master curve, vertical factor
  per isotherm, specimen factors and phase offsets as fitted) with the free shifts replaced by
  the smooth shift law through them (no temperature offset) and no artifact;
* **its noise**: the replicate (point) scatter of ln|E*| and Phi, plus a misfit shared by
  the specimens of a cell, normal with the variance the screening fit leaves in the cell
  means beyond the point scatter (its own cell misfit);
* **the table's design**: the same rows, specimens, strains and test order.

On B such tables (seeded) the whole procedure runs and gives min_p_b. The calibrated level
is the largest c with #{b : min_p_b < c} <= rate x B (rate: the family-wise false-alarm rate,
config ``diagnosis.calibration.familywise_rate``); the procedure uses min(c, alpha / m)
(the nominal level, whose false-alarm rates the detection benchmark measures, stays a
ceiling). The rate it gives is measured out of sample by cross-fitting (each half's level
judged on the other half), with its Clopper-Pearson interval; a named artifact's calibrated
p-value is (1 + #{min_p_b <= p}) / (B + 1) (:func:`asphalt_nscd.diagnosis.effects.adjusted_p`).

The static-modulus test (the master curve with E00 free against E00 = 0, in
:mod:`asphalt_nscd.diagnosis.causes`) is calibrated the same way on tables of the table's
liquid master curve (E00 = 0, shift law of the search) with the same noise: its p-value is
(1 + #{F_b >= F}) / (B + 1). The family is the two groups, artifacts and static modulus, each
at half the family-wise rate (Bonferroni).

Choices and their measurements: docs/choices.md, Diagnosis: error control on the table itself.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

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


@dataclass
class CleanModel:
    """A table's fitted clean model (module docstring).

    ``E``: complex modulus of every row of ``rows`` (MPa, shape (n,)); ``sigma_point``: point
    scatter of ln|E*| and Phi (deg); ``sigma_cell``: the cell misfit's standard deviations
    (same units); ``x0``: the parameters of the fit (a warm start for the simulated tables);
    ``rows``: the design (the table without its measured values)."""

    E: np.ndarray
    sigma_point: tuple
    sigma_cell: tuple
    x0: np.ndarray
    rows: pd.DataFrame


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
    return CleanModel(E=E, sigma_point=point, sigma_cell=cell, x0=x, rows=search.df[keep].copy())


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


def critical_level(min_p, rate: float) -> float:
    """The largest c with #{min_p_b < c} <= rate x B (the (floor(rate B) + 1)-th smallest
    statistic; 1 when rate B >= B)."""
    m = np.sort(np.asarray(min_p, float))
    k = int(np.floor(rate * m.size))
    return float(m[k]) if k < m.size else 1.0


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
        A statistic to decide on (the table's own ``min_p``): the bootstrap tables are run in
        turn and stopped once more than rate x B of them reach it (``min_p_b <= decide``): the
        calibrated level is then at most ``decide``, so ``decide`` is no alarm whatever the other
        tables give (curtailed sampling: the same decision as all B tables). ``null_min_p``
        then holds the tables run, ``n_run`` their number and ``calibrated_level`` is the upper
        bound the run tables give (``calibrated_level_bound``: True).

    Returns
    -------
    dict (JSON-ready): ``n_tables, seed, familywise_rate``, ``clean_model`` (its noise and
    cell misfit, the observed screening reduced chi-square), ``artifacts`` (``family_size``,
    ``nominal_level``, ``calibrated_level`` c, ``level`` = min(c, nominal),
    ``null_min_p`` (B values), the cross-fitted ``rate`` with its 95 % interval), ``static``
    (``null_F`` (B values) and the level), ``cpu_seconds``.

    Raises
    ------
    ValueError
        on n_tables < 20 or a rate outside (0, 1).
    """
    if int(n_tables) < 20:
        raise ValueError(f"n_tables must be >= 20, got {n_tables}")
    if not 0.0 < rate < 1.0:
        raise ValueError(f"rate must lie in (0, 1), got {rate}")
    c0 = _cpu()
    search = ArtifactSearch(table, alpha=alpha, shift=shift, test=test, limits=limits)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        observed = search.run()
    base = observed["base"]
    model = clean_model(search, base)
    rng = np.random.default_rng([int(seed), 1])
    sims = [simulate(model, rng) for _ in range(int(n_tables))]
    group_rate = rate / GROUPS
    tasks = [(t, test, alpha, shift, limits, model.x0) for t in sims]
    curtailed = False
    if decide is None:
        stat = _map(_artifact_stat, tasks, jobs)
    else:
        stat, reach = [], 0
        for task in tasks:
            stat.append(_artifact_stat(task))
            reach += stat[-1] <= decide
            if reach > np.floor(group_rate * len(tasks)):
                curtailed = len(stat) < len(tasks)
                break
    m = np.asarray(stat, float)
    nominal = float(observed["nominal_level"])
    # with every table run, the (floor(rate B) + 1)-th smallest statistic; curtailed, the
    # (floor(rate B) + 1)-th smallest of those run, an upper bound of it
    c = float(np.sort(m)[int(np.floor(group_rate * len(tasks)))]) if curtailed else critical_level(m, group_rate)
    # out of sample: each half's level judged on the other half
    half = m.size // 2
    a, b = m[:half], m[half:]
    alarms = int(
        np.sum(b < min(critical_level(a, group_rate), nominal))
        + np.sum(a < min(critical_level(b, group_rate), nominal))
    )
    lo, hi = binomial_ci(alarms, m.size)
    out = {
        "n_tables": int(n_tables),
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
            "observed_min_p": float(observed["min_p"]),
            "null_min_p": [float(v) for v in m],
            "n_run": int(m.size),
            "calibrated_level_bound": curtailed,
            "rate": {
                "k": alarms,
                "n": int(m.size),
                "rate": alarms / m.size,
                "ci95": [lo, hi],
                "method": "cross-fitted halves: each half's level judged on the other half",
            },
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


def static_p(F: float, calibration: dict | None) -> float | None:
    """Calibrated p-value (1 + #{F_b >= F}) / (B + 1) of an observed static-modulus F (None
    without a calibration or a finite F)."""
    if calibration is None or F is None or not np.isfinite(F):
        return None
    null = np.asarray(calibration["static"]["null_F"], float)
    return float((1 + np.sum(null >= F)) / (null.size + 1))
