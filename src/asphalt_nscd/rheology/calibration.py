"""Calibration of the paper's Burger's model on measured isotherms, and its micro parameters.

Macro law (paper Eqs. 27-29), via :meth:`GeneralizedBurgers.burgers`::

    D'  = 1/Em + Ek/(Ek^2 + w^2 eta_k^2)
    D'' = 1/(w eta_m) + w eta_k/(Ek^2 + w^2 eta_k^2)
    |E*| = 1/|D*|,   Phi = arctan(D''/D')

Fit, one temperature at a time (paper Section 3.2.2): the logarithms of (Em, eta_m, Ek, eta_k)
in MPa and MPa s, bounded to [1e-6, 1e9], minimise sum r^2 over every replicate point, with
r_i = (w_E [ln|E*|_model(f_i) - ln|E*|_i], w_Phi [Phi_model(f_i) - Phi_i]) (Phi in radians),
by SciPy's ``least_squares`` ("trf", analytic Jacobian) from the best ``n_starts`` points of a
grid built from the data. Standard errors: se(ln p) = sqrt(diag(s^2 (J^T J)^-1)),
s^2 = cost / (m - 4). Reported per temperature: rms of the ln|E*| and Phi residuals, the mean
relative errors of |E*| and Phi (%, paper Table 4) and the largest absolute phase error.

:func:`load_table3` reads the paper's Table 3 (``data/paper/table3_burgers.csv``, as printed)
under a unit reading, ``"Pa"`` or ``"kPa"`` (data/paper/SOURCE.md). Micro parameters
(Eqs. 30-33, 8-11): normal = macro x ``pi r_min^2 / l0``
(:func:`asphalt_nscd.rheology.laws.bond_scale`), tangential a further ``1/(2(1+nu))``
(:func:`~asphalt_nscd.rheology.laws.tangential_ratio`).

Choices (docs/choices.md, Calibration): the weights w_E = w_Phi = 1 (the complex-logarithm
residual), the multi-start, the two readings of Table 3's units.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError, read_csv, require_columns
from .laws import POISSON_RATIO, GeneralizedBurgers, bond_scale, tangential_ratio
from .metrics import mre_pct

#: Burger's parameter columns (MPa, MPa s) of a calibrated or converted table.
PARAM_COLUMNS = ("Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s")
#: Columns of data/paper/table3_burgers.csv, as printed in the paper.
TABLE3_COLUMNS = ("temperature_C", "Em_Pa", "eta_m_Pa_s", "Ek_Pa", "eta_k_Pa_s")
#: Multiplier from the printed Table 3 values to MPa / MPa s under each unit reading.
TABLE3_UNITS = {"Pa": 1e-6, "kPa": 1e-3}
#: Bounds of every parameter in MPa or MPa s.
PARAM_BOUNDS = (1e-6, 1e9)
DEFAULT_WEIGHTS = {"log_E": 1.0, "phase_rad": 1.0}
#: evaluations of the exploratory run from every start of :func:`fit_burgers`
EXPLORE_NFEV = 200


def load_table3(path, units: str = "Pa") -> pd.DataFrame:
    """Read the paper's Table 3 (as printed) and convert it to MPa and MPa s.

    Parameters
    ----------
    path : str or Path
        CSV with columns ``temperature_C, Em_Pa, eta_m_Pa_s, Ek_Pa, eta_k_Pa_s``.
    units : {"Pa", "kPa"}
        Reading of the printed values: "Pa" as printed in the header, "kPa" if the header's
        unit is a misprint for kPa (see data/paper/SOURCE.md).

    Returns
    -------
    DataFrame, one row per temperature
        ``temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s``.

    Raises
    ------
    InputError
        on an unknown unit reading, a missing column, or a non-positive value.
    """
    if units not in TABLE3_UNITS:
        raise InputError(f"{path}: unknown Table 3 unit reading {units!r}; expected one of {sorted(TABLE3_UNITS)}")
    raw = read_csv(path, comment="#")
    require_columns(raw, TABLE3_COLUMNS, path)
    out = pd.DataFrame({"temperature_C": pd.to_numeric(raw["temperature_C"], errors="coerce")})
    factor = TABLE3_UNITS[units]
    for src, dst in zip(TABLE3_COLUMNS[1:], PARAM_COLUMNS):
        values = pd.to_numeric(raw[src], errors="coerce")
        bad = np.flatnonzero(~(values > 0).to_numpy())
        if bad.size:
            raise InputError(
                f"{path}: line {bad[0] + 2}, column '{src}': expected a positive number, got {raw[src].iloc[bad[0]]!r}"
            )
        out[dst] = values * factor
    return out


def burgers_model(row, unit: float = 1e6) -> GeneralizedBurgers:
    """The Burger's model of a parameter row in MPa, MPa s (dict or Series), in SI (Pa, Pa s)
    by default; ``unit`` = 1.0 keeps MPa and MPa s (the diagnosis' units)."""
    return GeneralizedBurgers.burgers(
        Em=float(row["Em_MPa"]) * unit,
        eta_m=float(row["eta_m_MPa_s"]) * unit,
        Ek=float(row["Ek_MPa"]) * unit,
        eta_k=float(row["eta_k_MPa_s"]) * unit,
    )


def burgers_isotherm(params, frequency_Hz) -> tuple[np.ndarray, np.ndarray]:
    """|E*| (MPa) and Phi (degrees) of a Burger's model at frequencies (Hz) (Eqs. 27-29).

    ``params``: mapping with ``Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s``; ``frequency_Hz``
    any shape; returns two arrays of that shape.
    """
    norm, phase = burgers_model(params).norm_and_phase(2.0 * np.pi * np.asarray(frequency_Hz, dtype=float))
    return norm * 1e-6, phase


def burgers_curves(params_table: pd.DataFrame, frequency_Hz) -> pd.DataFrame:
    """Model isotherms of every row of a parameter table.

    Parameters
    ----------
    params_table : DataFrame
        ``temperature_C`` and the four ``PARAM_COLUMNS`` (MPa, MPa s).
    frequency_Hz : array, shape (k,)
        Frequencies, Hz.

    Returns
    -------
    DataFrame, shape (n_temperatures * k, 6)
        ``temperature_C, frequency_Hz, E_norm_MPa, phase_deg, E1_MPa, E2_MPa``.
    """
    f = np.asarray(frequency_Hz, dtype=float).ravel()
    frames = []
    for _, row in params_table.iterrows():
        e = burgers_model(row).complex_modulus(2.0 * np.pi * f) * 1e-6
        frames.append(
            pd.DataFrame(
                {
                    "temperature_C": float(row["temperature_C"]),
                    "frequency_Hz": f,
                    "E_norm_MPa": np.abs(e),
                    "phase_deg": np.degrees(np.angle(e)),
                    "E1_MPa": e.real,
                    "E2_MPa": e.imag,
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _weights(weights) -> tuple[float, float]:
    if weights is None:
        weights = DEFAULT_WEIGHTS
    if isinstance(weights, dict):
        unknown = set(weights) - set(DEFAULT_WEIGHTS)
        if unknown:
            raise ValueError(f"unknown weight keys {sorted(unknown)}; expected {sorted(DEFAULT_WEIGHTS)}")
        w = {**DEFAULT_WEIGHTS, **weights}
        w_e, w_p = w["log_E"], w["phase_rad"]
    else:
        w_e, w_p = weights
    if not (w_e >= 0 and w_p >= 0 and w_e + w_p > 0):
        raise ValueError(f"weights must be >= 0 and not both zero, got {(w_e, w_p)}")
    return float(w_e), float(w_p)


def _log_modulus(x: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Complex ln E* (E* in MPa) of log-parameters ``x = ln(Em, eta_m, Ek, eta_k)``.

    ``x`` shape (..., 4) (MPa, MPa s), ``omega`` shape (k,) rad/s; returns shape (..., k).
    Same formula as GeneralizedBurgers.complex_compliance (Eqs. 28-29), vectorised over
    parameter sets for the grid of starting values.
    """
    p = np.exp(np.asarray(x, dtype=float))
    Em, eta_m, Ek, eta_k = (p[..., i, None] for i in range(4))
    d = 1.0 / Em + 1.0 / (1j * omega * eta_m) + 1.0 / (Ek + 1j * omega * eta_k)
    return -np.log(d)


def _log_modulus_jacobian(x: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """d ln E* / d x of :func:`_log_modulus` for one parameter set ``x`` (4,): complex, shape
    (k, 4). With D the complex compliance (Eqs. 28-29), d ln E*/d ln p = -(dD/d ln p) / D."""
    Em, eta_m, Ek, eta_k = np.exp(np.asarray(x, dtype=float))
    kv = Ek + 1j * omega * eta_k
    D = 1.0 / Em + 1.0 / (1j * omega * eta_m) + 1.0 / kv
    dD = np.column_stack(
        [
            np.full(omega.shape, -1.0 / Em, dtype=complex),
            -1.0 / (1j * omega * eta_m),
            -Ek / kv**2,
            -1j * omega * eta_k / kv**2,
        ]
    )
    return -dD / D[:, None]


def fit_burgers(frequency_Hz, E_norm_MPa, phase_deg, weights=None, n_starts: int = 8) -> dict:
    """Fit the four Burger's parameters to one measured isotherm (Eqs. 27-29).

    Parameters
    ----------
    frequency_Hz, E_norm_MPa, phase_deg : arrays, shape (m,)
        Measured points (replicates allowed), Hz, MPa, degrees, at two or more distinct
        frequencies: each point gives two real numbers (ln|E*| and Phi), so two frequencies
        determine the four parameters and three (a lab testing 3 frequencies) leave two
        degrees of freedom.
    weights : dict or (float, float), optional
        ``{"log_E": w_E, "phase_rad": w_Phi}`` weights of the ln|E*| and Phi (radian)
        residuals; default 1 and 1 (the complex-log residual, see the module docstring).
    n_starts : int
        Number of local least-squares runs, started from the best points of the grid of
        starting values.

    Returns
    -------
    dict
        ``Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s``, their standard errors ``*_se``
        (NaN when 2 m <= 4: no residual degree of freedom), fit errors ``rmse_log_E, rmse_phase_deg, mre_E_pct,
        mre_phase_pct, max_abs_phase_err_deg``, ``n_points``, ``cost``, ``success``.

    Raises
    ------
    ValueError
        on arrays of different shape, fewer than 2 distinct frequencies, non-positive or non-finite
        frequencies or |E*|, or phases outside (0, 90) degrees.
    """
    from scipy.optimize import least_squares

    f = np.asarray(frequency_Hz, dtype=float).ravel()
    E = np.asarray(E_norm_MPa, dtype=float).ravel()
    phi = np.radians(np.asarray(phase_deg, dtype=float).ravel())
    if not (f.shape == E.shape == phi.shape):
        raise ValueError(f"frequency, |E*| and phase must have the same length, got {f.size}, {E.size}, {phi.size}")
    if np.unique(f).size < 2:
        raise ValueError(
            f"need points at 2 or more distinct frequencies (4 real numbers: |E*| and Phi at each) "
            f"to fit 4 parameters, got {np.unique(f).size} frequency"
        )
    if not (np.all(f > 0) and np.all(E > 0) and np.all(np.isfinite(f)) and np.all(np.isfinite(E))):
        raise ValueError("frequencies and |E*| must be positive and finite")
    if not np.all((phi > 0) & (phi < np.pi / 2)):
        raise ValueError("phase angles must lie in (0, 90) degrees for a Burger's model")
    w_e, w_p = _weights(weights)
    omega = 2.0 * np.pi * f
    target = np.log(E) + 1j * phi

    def residuals(x):
        d = _log_modulus(x, omega) - target
        return np.concatenate([w_e * d.real, w_p * d.imag])

    def jacobian(x):
        J = _log_modulus_jacobian(x, omega)
        return np.vstack([w_e * J.real, w_p * J.imag])

    # Grid of starting values from the data (MPa, MPa s).
    E_max = E.max()
    i_low = np.argmin(f)
    loss_compliance = np.sin(phi[i_low]) / E[i_low]
    eta_m0 = 1.0 / (omega[i_low] * loss_compliance)
    omega_mid = np.exp(np.mean(np.log(omega)))
    lo, hi = np.log(PARAM_BOUNDS[0]), np.log(PARAM_BOUNDS[1])
    grid = []
    for a in (1.0, 1.5, 3.0, 10.0):
        for b in (0.1, 0.3, 1.0, 3.0):
            for c in (0.1, 0.3, 1.0, 3.0, 10.0):
                for d in (0.01, 0.1, 1.0, 10.0, 100.0):
                    Em0 = a * E_max
                    Ek0 = c * Em0
                    grid.append(np.log([Em0, b * eta_m0, Ek0, d * Ek0 / omega_mid]))
    grid = np.clip(np.array(grid), lo + 1e-9, hi - 1e-9)
    d_grid = _log_modulus(grid, omega) - target
    cost_grid = np.sum((w_e * d_grid.real) ** 2 + (w_p * d_grid.imag) ** 2, axis=-1)
    starts = grid[np.argsort(cost_grid)[: max(1, int(n_starts))]]

    def solve(x0, max_nfev):
        return least_squares(
            residuals,
            x0,
            jac=jacobian,
            bounds=(lo, hi),
            method="trf",
            x_scale=1.0,
            xtol=1e-14,
            ftol=1e-14,
            gtol=1e-14,
            max_nfev=max_nfev,
        )

    # every start for a short run, then the two best to convergence (a start that has not
    # converged in EXPLORE_NFEV evaluations is slow because it crawls along a bound)
    runs = sorted((solve(x0, EXPLORE_NFEV) for x0 in starts), key=lambda r: r.cost)
    best = None
    for res in runs[:2]:
        if res.status == 0:  # stopped by the evaluation budget
            res = solve(res.x, 4000)
        if best is None or res.cost < best.cost:
            best = res
    assert best is not None  # runs holds at least one start
    x = best.x
    p = np.exp(x)
    m, n = 2 * f.size, 4
    se = np.full(4, np.nan)
    if m > n:
        J = best.jac
        s2 = 2.0 * best.cost / (m - n)
        cov = s2 * np.linalg.pinv(J.T @ J)
        se = p * np.sqrt(np.clip(np.diag(cov), 0.0, None))
    d = _log_modulus(x, omega) - target
    E_model = np.exp(d.real) * E
    phi_model = phi + d.imag
    out = {name: float(v) for name, v in zip(PARAM_COLUMNS, p)}
    out.update({f"{name}_se": float(v) for name, v in zip(PARAM_COLUMNS, se)})
    out.update(
        {
            "rmse_log_E": float(np.sqrt(np.mean(d.real**2))),
            "rmse_phase_deg": float(np.degrees(np.sqrt(np.mean(d.imag**2)))),
            "mre_E_pct": mre_pct(E_model, E),
            "mre_phase_pct": mre_pct(phi_model, phi),
            "max_abs_phase_err_deg": float(np.degrees(np.max(np.abs(d.imag)))),
            "n_points": int(f.size),
            "cost": float(best.cost),
            "success": bool(best.success),
        }
    )
    return out


def fit_table(measured_df: pd.DataFrame, weights=None, n_starts: int = 8) -> pd.DataFrame:
    """Fit a Burger's model per temperature of a measured table.

    Parameters
    ----------
    measured_df : DataFrame
        Tidy measured table (``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``; every
        replicate row is fitted) or a replicate summary (``E_norm_MPa_mean, phase_deg_mean``).
    weights, n_starts
        See :func:`fit_burgers`.

    Returns
    -------
    DataFrame, one row per temperature (sorted)
        ``temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s``, the ``*_se`` standard
        errors and the fit errors of :func:`fit_burgers`.

    Raises
    ------
    InputError
        if columns are missing or a temperature cannot be fitted (too few points, phase
        outside (0, 90) degrees).
    """
    cols = {"E": "E_norm_MPa", "phi": "phase_deg"}
    if "E_norm_MPa" not in measured_df.columns and "E_norm_MPa_mean" in measured_df.columns:
        cols = {"E": "E_norm_MPa_mean", "phi": "phase_deg_mean"}
    needed = ["temperature_C", "frequency_Hz", cols["E"], cols["phi"]]
    require_columns(measured_df, needed, "measured table")
    rows = []
    for T, group in measured_df.groupby("temperature_C", sort=True):
        try:
            fit = fit_burgers(
                group["frequency_Hz"], group[cols["E"]], group[cols["phi"]], weights=weights, n_starts=n_starts
            )
        except ValueError as exc:
            raise InputError(f"measured table, temperature_C={T:g}: {exc}") from None
        rows.append({"temperature_C": float(T), **fit})
    return pd.DataFrame(rows)


def refit_check(params_table: pd.DataFrame, frequency_Hz, weights=None, n_starts: int = 8) -> pd.DataFrame:
    """Generate exact isotherms from a parameter table and fit them back.

    Verifies that the calibration recovers known parameters (the paper's Table 3).

    Returns
    -------
    DataFrame, one row per temperature
        ``temperature_C``, the true and refitted parameters (``<name>`` and
        ``<name>_refit``) and the relative errors ``<name>_rel_err`` (refit/true - 1).
    """
    curves = burgers_curves(params_table, frequency_Hz)
    fitted = fit_table(curves, weights=weights, n_starts=n_starts).set_index("temperature_C")
    rows = []
    for _, row in params_table.iterrows():
        T = float(row["temperature_C"])
        out = {"temperature_C": T}
        for name in PARAM_COLUMNS:
            out[name] = float(row[name])
            out[f"{name}_refit"] = float(fitted.loc[T, name])
            out[f"{name}_rel_err"] = float(fitted.loc[T, name] / row[name] - 1.0)
        rows.append(out)
    return pd.DataFrame(rows)


def micro_parameters(
    params_table: pd.DataFrame, r_min_m, l0_m, nu: float = POISSON_RATIO, grain_mass_kg: float | None = None
) -> pd.DataFrame:
    """Bond (micro) parameters from macro Burger's parameters (Eqs. 30-33 and 8-11).

    Parameters
    ----------
    params_table : DataFrame
        ``temperature_C`` and ``PARAM_COLUMNS`` (MPa, MPa s).
    r_min_m, l0_m : arrays, shape (n_bonds,)
        Smaller radius of each bonded pair and initial barycentre distance, m.
    nu : float
        Poisson's ratio of Eqs. 8-11 (paper: 0.35).
    grain_mass_kg : float, optional
        A typical grain mass m_g; adds the elastic time scale ``dt_e_s = sqrt(m_g / Km)``
        of Section 3.2.2 (paper: about 2e-5 s at 15 degC).

    Returns
    -------
    DataFrame, shape (n_temperatures * n_bonds, ...)
        ``temperature_C, bond, r_min_m, l0_m, scale_m`` (pi r_min^2/l0), normal
        ``Km_N_m, Cm_N_s_m, Kk_N_m, Ck_N_s_m`` and tangential ``Km_t_N_m, Cm_t_N_s_m,
        Kk_t_N_m, Ck_t_N_s_m`` (and ``dt_e_s``).

    Raises
    ------
    ValueError
        if r_min or l0 is not positive or nu is outside (-1, 0.5).
    """
    r = np.atleast_1d(np.asarray(r_min_m, dtype=float))
    l0 = np.atleast_1d(np.asarray(l0_m, dtype=float))
    r, l0 = np.broadcast_arrays(r, l0)
    scale = bond_scale(r, l0)
    ratio = tangential_ratio(nu)
    frames = []
    for _, row in params_table.iterrows():
        macro = burgers_model(row)
        frame = pd.DataFrame(
            {
                "temperature_C": float(row["temperature_C"]),
                "bond": np.arange(r.size),
                "r_min_m": r,
                "l0_m": l0,
                "scale_m": scale,
                "Km_N_m": macro.Em * scale,
                "Cm_N_s_m": macro.eta_m * scale,
                "Kk_N_m": macro.Ek[0] * scale,
                "Ck_N_s_m": macro.eta_k[0] * scale,
            }
        )
        for name in ("Km_N_m", "Cm_N_s_m", "Kk_N_m", "Ck_N_s_m"):
            frame[name.replace("_N", "_t_N", 1)] = frame[name] * ratio
        if grain_mass_kg is not None:
            frame["dt_e_s"] = np.sqrt(grain_mass_kg / frame["Km_N_m"])
        frames.append(frame)
    return pd.concat(frames, ignore_index=True)


def read_parameters(path) -> pd.DataFrame:
    """Read a Burger's parameter table in MPa (``temperature_C`` + ``PARAM_COLUMNS``).

    Raises
    ------
    InputError
        if the file is missing or unreadable, or a column is missing or non-positive.
    """
    path = Path(path)
    frame = read_csv(path)
    require_columns(frame, ("temperature_C", *PARAM_COLUMNS), path)
    for c in PARAM_COLUMNS:
        bad = np.flatnonzero(~(pd.to_numeric(frame[c], errors="coerce") > 0).to_numpy())
        if bad.size:
            raise InputError(f"{path}: line {bad[0] + 2}, column '{c}': expected a positive number")
    return frame
