"""Master curves: 2S2P1D (or Huet-Sayegh) with WLF, Arrhenius or free shift factors, fitted
to every replicate point of a measured table at once.

Model of a measured point p (specimen s, temperature T, frequency f)::

    E*_p = exp(c_s) * E*_2S2P1D(2 pi f, tau = tau_ref * aT(T + dT_p))     (MPa)

with a log |E*| factor c_s per specimen (c_0 = 0: specimen scatter of the modulus), and the
measured artifacts of :class:`Term` objects (``dT_p`` comes from the terms; the diagnosis
adds time lags, inertia, temperature offsets, ...). Residuals are ln|E*| and Phi (degrees),
each divided by its noise level (from replicate scatter, :func:`replicate_noise`), so the
weighted residual sum of squares is a chi-square statistic and nested models can be compared
by F or likelihood-ratio tests.

Choices: parameters are searched in transformed coordinates (log10 of moduli, beta, tau; the
exponents as h and k/h so that 0 < k < h < 1 holds inside box bounds). The fit starts from a
few characteristic times and keeps the best local solution (SciPy ``least_squares``, trf).
Standard errors are Jacobian (Gauss-Newton) estimates with the residual variance.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .models import two_s2p1d_modulus
from .shift import arrhenius_log_shift


@dataclass
class Term:
    """An additive piece of the measurement model, with its own parameters.

    ``delta_T(x, data)`` returns a temperature perturbation per point (degC) or None;
    ``apply(x, E, data)`` returns the measured complex modulus from the true one (MPa).
    Both take the term's parameters ``x`` of shape (q,) or, for several parameter vectors at
    once, (m, q) with ``E`` of shape (m, n), and broadcast: row i of the result is the result
    for ``x[i]``, by the same operations.
    """

    name: str
    names: list
    x0: list
    lower: list
    upper: list
    delta_T: Callable | None = None
    apply: Callable | None = None
    #: terms' ``apply`` run in increasing ``order`` (not in the order of the parameter layout)
    order: int = 0


@dataclass
class MasterCurveFit:
    """Result of :func:`fit_master_curve` (see the module docstring)."""

    names: list
    x: np.ndarray
    se: np.ndarray
    cov: np.ndarray
    rss: float
    n_residuals: int
    shift: str
    T_ref_C: float
    static_modulus: bool
    temperatures: np.ndarray
    specimens: list
    sigma_lnE: float
    sigma_phase_deg: float
    terms: list = field(default_factory=list)
    residuals: np.ndarray | None = None
    fitted: pd.DataFrame | None = None
    #: mean over specimens of the ln|E*| factors and phase offsets (deg): the curve of
    #: :meth:`modulus` is that of the average specimen
    specimen_mean: tuple = (0.0, 0.0)

    n_free: int | None = None
    #: the fit's box bounds (None when not fitted here)
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None

    @property
    def n_params(self) -> int:
        """Number of fitted (free) parameters."""
        return int(self.x.size if self.n_free is None else self.n_free)

    def param(self, name: str) -> float:
        return float(self.x[self.names.index(name)])

    def param_se(self, name: str) -> float:
        return float(self.se[self.names.index(name)])

    def core(self) -> dict:
        """2S2P1D parameters in natural units (MPa, s) and the shift constants."""
        return _core_values(self.x, self.names, self.static_modulus)

    def findings(self, fixed=()) -> list[dict]:
        """2S2P1D and shift parameters outside their plausible range for a mix, and fitted
        parameters at a bound of the fit (:mod:`asphalt_nscd.rheology.plausibility`);
        ``fixed``: names held at their value (not checked against the bounds)."""
        from .plausibility import at_bound, check_parameters

        values = {
            k: v
            for k, v in self.core().items()
            if k not in ("tau_ref_s",) and not (k == "E00_MPa" and not self.static_modulus)
        }
        found = check_parameters(values)
        if self.lower is not None and self.upper is not None:
            core = [i for i, n in enumerate(self.names) if not n.startswith(("ln_factor_", "phase_offset_deg_"))]
            found += at_bound([self.names[i] for i in core], self.x[core], self.lower[core], self.upper[core], fixed)
        return found

    def log_shift(self, temperature_C) -> np.ndarray:
        """log10 aT of the fitted shift law at ``temperature_C`` (degC)."""
        return _log_shift(
            self.x, self.names, self.shift, self.T_ref_C, self.temperatures, np.asarray(temperature_C, dtype=float)
        )

    def modulus(self, frequency_Hz, temperature_C) -> np.ndarray:
        """True (artifact-free, specimen-average) complex modulus, MPa; broadcast shapes."""
        f, T = np.broadcast_arrays(np.asarray(frequency_Hz, float), np.asarray(temperature_C, float))
        E = _true_modulus(self.x, self.names, self.shift, self.T_ref_C, self.temperatures, self.static_modulus, f, T)
        return E * np.exp(self.specimen_mean[0] + 1j * np.radians(self.specimen_mean[1]))


def replicate_noise(df: pd.DataFrame, covariates=()) -> tuple[float | None, float | None]:
    """Point noise of ln|E*| and Phi (deg) from the scatter between replicates.

    ln|E*| residuals are taken about the cell mean (temperature, frequency) after removing
    a constant offset per specimen (specimen scatter); Phi about the cell mean. Pooled
    standard deviations with their degrees of freedom; (None, None) without replicates.

    ``covariates``: names of columns (e.g. ``strain_microstrain``) that vary between the
    replicates of a cell and may change ln|E*| linearly; they are regressed out of the
    ln|E*| scatter together with the cell means and specimen offsets (least squares, one
    degree of freedom each), so that a real effect of them does not inflate the noise.
    Without covariates the result is the same as that two-way fit on a balanced table.
    """
    d = df.copy()
    d["lnE"] = np.log(d["E_norm_MPa"])
    cell = d.groupby(["temperature_C", "frequency_Hz"])
    d["rE"] = d["lnE"] - cell["lnE"].transform("mean")
    d["rP"] = d["phase_deg"] - cell["phase_deg"].transform("mean")
    n_cells = cell.ngroups
    n_spec = d["specimen"].nunique()
    dof_p = len(d) - n_cells
    dof_e = dof_p - (n_spec - 1)
    if n_spec < 2 or dof_e <= 0:
        return None, None
    sP = float(np.sqrt(np.sum(d["rP"] ** 2) / dof_p))
    covariates = [c for c in covariates if c in d.columns]
    if not covariates:
        d["rE"] = d["rE"] - d.groupby("specimen")["rE"].transform("mean")
        return float(np.sqrt(np.sum(d["rE"] ** 2) / dof_e)), sP
    # two-way least squares: cell means + specimen offsets + linear covariates
    X = np.column_stack(
        [
            pd.get_dummies(cell.ngroup()).to_numpy(float),
            pd.get_dummies(d["specimen"].astype(str)).to_numpy(float)[:, 1:],
        ]
        + [d[c].to_numpy(float) for c in covariates]
    )
    y = d["lnE"].to_numpy(float)
    coef, _, rank, _ = np.linalg.lstsq(X, y, rcond=None)
    dof = len(y) - int(rank)
    if dof <= 0:
        return None, None
    return float(np.sqrt(np.sum((y - X @ coef) ** 2) / dof)), sP


def data_arrays(df: pd.DataFrame) -> dict:
    """Arrays of a tidy measured table used by the model (shapes (n,))."""
    specimens = sorted(df["specimen"].astype(str).unique())
    out = {
        "f": df["frequency_Hz"].to_numpy(float),
        "T": df["temperature_C"].to_numpy(float),
        "lnE": np.log(df["E_norm_MPa"].to_numpy(float)),
        "phase": df["phase_deg"].to_numpy(float),
        "spec": df["specimen"].astype(str).map({s: i for i, s in enumerate(specimens)}).to_numpy(int),
        "specimens": specimens,
        "temperatures": np.sort(df["temperature_C"].unique()).astype(float),
    }
    for col in ("strain_microstrain", "test_step", "test_step_centre"):
        if col in df.columns:
            out[col] = df[col].to_numpy(float)
    return out


def _core_names(shift: str, static_modulus: bool, temperatures) -> list:
    names = ["log10_E0_MPa", "log10_delta", "h", "k_over_h", "log10_beta", "log10_tau_ref_s"]
    if static_modulus:
        names.insert(0, "log10_E00_MPa")
    if shift == "wlf":
        names += ["C1", "C2_K"]
    elif shift == "arrhenius":
        names += ["Ea_kJ_mol"]
    elif shift == "free":
        names += [f"log10_aT_{T:g}" for T in temperatures]
    else:
        raise ValueError(f"unknown shift law '{shift}' (expected wlf, arrhenius or free)")
    return names


def _log_shift(x, names, shift, T_ref, temperatures, T):
    """log10 aT at ``T`` (degC) of the parameters ``x``: shape (p,), any ``T``; or (m, p) with
    ``T`` of shape (n,) or (m, n), giving (m, n), each row by the operations of one vector."""
    x = np.asarray(x, dtype=float)
    rows = x.ndim == 2

    def value(i):
        return x[:, i, None] if rows else x[i]

    if shift == "wlf":
        C1 = value(names.index("C1"))
        C2 = value(names.index("C2_K"))
        dT = T - T_ref
        return -C1 * dT / np.maximum(C2 + dT, 1e-6)
    if shift == "arrhenius":
        return arrhenius_log_shift(T, T_ref, value(names.index("Ea_kJ_mol")) * 1e3)
    # free shifts: piecewise-linear interpolation between the isotherms' shifts, extended
    # linearly beyond the end isotherms (a temperature perturbation of an end isotherm, e.g. a
    # drift along its tests, then moves it along the slope of its last segment)
    idx = _free_shift_index(tuple(names), float(T_ref), tuple(float(T_) for T_ in temperatures))
    vals = np.stack([np.zeros(x.shape[:-1]) if i < 0 else x[..., i] for i in idx], axis=-1)

    def shift_at(j):
        return vals[:, j, None] if rows else vals[j]

    if rows:
        T = np.broadcast_to(T, (len(x), np.shape(T)[-1]))
        out = np.array([np.interp(T_row, temperatures, v) for T_row, v in zip(T, vals)])
    else:
        out = np.interp(T, temperatures, vals)
    if len(temperatures) > 1:
        lo, hi = temperatures[0], temperatures[-1]
        s_lo = (shift_at(1) - shift_at(0)) / (temperatures[1] - lo)
        s_hi = (shift_at(-1) - shift_at(-2)) / (hi - temperatures[-2])
        out = np.where(T < lo, shift_at(0) + s_lo * (T - lo), np.where(T > hi, shift_at(-1) + s_hi * (T - hi), out))
    return out


@functools.lru_cache(maxsize=64)
def _free_shift_index(names: tuple, T_ref: float, temperatures: tuple) -> tuple:
    """Position in ``names`` of each isotherm's free shift (-1 for the reference isotherm,
    whose shift is 0); cached, as a fit asks for it at every residual evaluation."""
    return tuple(-1 if T_ == T_ref else names.index(f"log10_aT_{T_:g}") for T_ in temperatures)


def _pow10(v):
    """10 ** v of a scalar, or of an array one scalar at a time (NumPy's array power may differ from its
    scalar power in the last bit, so each element is the value one vector's scalar gets)."""
    if np.ndim(v) == 0:
        return 10**v
    return np.array([10**e for e in v], dtype=float)


def _core_values(x, names, static_modulus) -> dict:
    """The 2S2P1D constants (MPa, s; WLF or Arrhenius constants as fitted) of the parameter vector ``x``
    (shape (p,), scalars) or of each row of ``x`` (shape (m, p), arrays of shape (m,)); row i holds exactly
    the values of ``x[i]`` (:func:`_pow10`)."""
    x = np.asarray(x, dtype=float)
    g = {n: x.T[i] for i, n in enumerate(names)}  # a scalar of (p,), a column of (m, p)
    h = g["h"]
    out = {
        "E00_MPa": _pow10(g["log10_E00_MPa"]) if static_modulus else (0.0 if x.ndim == 1 else np.zeros(len(x))),
        "E0_MPa": _pow10(g["log10_E0_MPa"]),
        "delta": _pow10(g["log10_delta"]),
        "k": g["k_over_h"] * h,
        "h": h,
        "beta": _pow10(g["log10_beta"]),
        "tau_ref_s": _pow10(g["log10_tau_ref_s"]),
    }
    for key in ("C1", "C2_K", "Ea_kJ_mol"):
        if key in g:
            out[key] = g[key]
    return out


def _true_modulus(x, names, shift, T_ref, temperatures, static_modulus, f, T):
    """2S2P1D modulus at ``f`` (Hz, shape (n,)) and ``T`` (degC) of the parameters ``x``, MPa:
    shape (p,) gives (n,); (m, p), with ``T`` of shape (n,) or (m, n), gives (m, n). The
    scalars of each row are computed as for one vector, and the formula runs on broadcast
    arrays by the same elementwise operations, so row i is the value for ``x[i]``."""
    x = np.asarray(x, dtype=float)
    c = _core_values(x, names, static_modulus)
    if x.ndim > 1:
        c = {key: v[:, None] for key, v in c.items()}
    tau = c["tau_ref_s"] * 10.0 ** _log_shift(x, names, shift, T_ref, temperatures, T)
    return two_s2p1d_modulus(2 * np.pi * f, c["E00_MPa"], c["E0_MPa"], c["delta"], c["k"], c["h"], c["beta"], tau)


class MasterCurveProblem:
    """Parameter layout and residuals of the master-curve model with optional terms."""

    def __init__(
        self, data: dict, shift="wlf", T_ref_C=None, static_modulus=True, terms=(), sigma_lnE=0.02, sigma_phase_deg=0.5
    ):
        self.data = data
        self.shift = shift
        self.temperatures = data["temperatures"]
        if T_ref_C is None:
            T_ref_C = float(self.temperatures[np.argmin(np.abs(self.temperatures - np.median(self.temperatures)))])
        self.T_ref_C = float(T_ref_C)
        self.static_modulus = static_modulus
        self.terms = list(terms)
        self.sigma = (float(sigma_lnE), float(sigma_phase_deg))
        self.core_names = _core_names(shift, static_modulus, self.temperatures)
        if shift == "free":  # aT(Tref) = 1: no parameter for the reference isotherm
            self.core_names.remove(f"log10_aT_{self.T_ref_C:g}")
        n_spec = len(data["specimens"])
        self.spec_names = [f"ln_factor_{s}" for s in data["specimens"][1:]] + [
            f"phase_offset_deg_{s}" for s in data["specimens"][1:]
        ]
        self.names = self.core_names + self.spec_names + [n for t in self.terms for n in t.names]
        self._slices = []
        i = len(self.core_names) + len(self.spec_names)
        for t in self.terms:
            self._slices.append(slice(i, i + len(t.names)))
            i += len(t.names)
        self.n_spec = n_spec

    # ------------------------------------------------------------------ bounds, start
    def bounds(self):
        d = self.data
        Emax = float(np.exp(d["lnE"].max()))
        Emin = float(np.exp(d["lnE"].min()))
        lo, hi = [], []
        table = {
            "log10_E00_MPa": (-2.0, np.log10(Emin) + 0.3),
            "log10_E0_MPa": (np.log10(Emax) - 0.05, 5.3),
            "log10_delta": (-1.5, 1.7),
            "h": (0.1, 0.99),
            "k_over_h": (0.03, 0.97),
            "log10_beta": (-1.0, 9.0),
            "log10_tau_ref_s": (-12.0, 8.0),
            "C1": (0.5, 200.0),
            "C2_K": (max(self.T_ref_C - self.temperatures.min() + 5.0, 5.0), 3000.0),
            "Ea_kJ_mol": (10.0, 1000.0),
        }
        for n in self.core_names:
            a, b = table.get(n, (-20.0, 20.0))
            lo.append(a)
            hi.append(b)
        lo += [-1.0] * (self.n_spec - 1) + [-10.0] * (self.n_spec - 1)
        hi += [1.0] * (self.n_spec - 1) + [10.0] * (self.n_spec - 1)
        for t in self.terms:
            lo += list(t.lower)
            hi += list(t.upper)
        return np.array(lo, float), np.array(hi, float)

    def starts(self) -> list:
        d = self.data
        Emax = float(np.exp(d["lnE"].max()))
        Emin = float(np.exp(d["lnE"].min()))
        base = {
            "log10_E00_MPa": np.log10(Emin) - 0.7,
            "log10_E0_MPa": min(np.log10(Emax) + 0.25, 5.2),
            "log10_delta": np.log10(2.0),
            "h": 0.6,
            "k_over_h": 0.33,
            "log10_beta": 3.0,
            "C1": 25.0,
            "C2_K": max(170.0, self.T_ref_C - self.temperatures.min() + 40.0),
            "Ea_kJ_mol": 200.0,
        }
        for T in self.temperatures:
            base[f"log10_aT_{T:g}"] = -0.15 * (T - self.T_ref_C)
        term_x0 = [v for t in self.terms for v in t.x0]
        out = []
        for lt in (-4.0, -2.5, -1.0, 0.5):
            core = [base.get(n, lt) if n != "log10_tau_ref_s" else lt for n in self.core_names]
            out.append(np.array(core + [0.0] * len(self.spec_names) + term_x0, float))
        return out

    # ------------------------------------------------------------------ model
    def measured_modulus(self, x) -> np.ndarray:
        """Model of the measured complex modulus at every data point, MPa: shape (n,) for
        ``x`` of shape (p,); (m, n) for (m, p), row i the value for ``x[i]`` (the
        finite-difference Jacobian's points in one call)."""
        x = np.asarray(x, dtype=float)
        d = self.data
        T = d["T"]
        for t, sl in zip(self.terms, self._slices):
            if t.delta_T is not None:
                dT = t.delta_T(x[..., sl], d)
                if dT is not None:
                    T = T + dT
        E = _true_modulus(x, self.names, self.shift, self.T_ref_C, self.temperatures, self.static_modulus, d["f"], T)
        c, ph = self.specimen_terms(x)
        E = E * np.exp(c[..., d["spec"]] + 1j * np.radians(ph[..., d["spec"]]))
        for t, sl in sorted(zip(self.terms, self._slices), key=lambda ts: ts[0].order):
            if t.apply is not None:
                E = t.apply(x[..., sl], E, d)
        return E

    def specimen_terms(self, x):
        """ln|E*| factors and phase offsets (deg) per specimen, shapes (n_spec,) (first = 0);
        (m, n_spec) for ``x`` of shape (m, p)."""
        x = np.asarray(x, dtype=float)
        nc, m = len(self.core_names), self.n_spec - 1
        first = np.zeros(x.shape[:-1] + (1,))
        return (
            np.concatenate([first, x[..., nc : nc + m]], axis=-1),
            np.concatenate([first, x[..., nc + m : nc + 2 * m]], axis=-1),
        )

    def residuals(self, x) -> np.ndarray:
        """Weighted residuals (ln|E*| then phase), shape (2 n,); (m, 2 n) for ``x`` of shape (m, p)."""
        E = self.measured_modulus(x)
        d = self.data
        lnE = np.log(np.maximum(np.abs(E), 1e-300))
        ph = np.degrees(np.angle(E))
        rE = (lnE - d["lnE"]) / self.sigma[0]
        rP = (ph - d["phase"]) / self.sigma[1]
        r = np.concatenate([rE, rP], axis=-1)
        return np.where(np.isfinite(r), r, 1e3)

    # ------------------------------------------------------------------ fit
    def fit(self, x0=None, max_nfev=3000, fixed=()) -> MasterCurveFit:
        """Least-squares fit; ``fixed`` names parameters held at their value in ``x0``
        (their standard error is reported as 0 and they do not count as parameters)."""
        from scipy.optimize import least_squares

        lo, hi = self.bounds()
        free = np.array([n not in set(fixed) for n in self.names])
        if fixed and x0 is None:
            raise ValueError("fixed parameters need a starting point x0")
        starts = self.starts() if x0 is None else [np.asarray(x0, float)]
        best, best_x = None, None
        for s in starts:
            s = np.clip(s, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
            full = s.copy()

            def resid(z, full=full):
                full[free] = z
                return self.residuals(full)

            def resid_map(fun, zs, full=full):
                # SciPy's finite-difference Jacobian asks for its points through this map
                # (least_squares ``workers``): all of them are evaluated in one call
                Z = [np.asarray(z, dtype=float) for z in zs]
                if not Z:
                    return []
                X = np.tile(full, (len(Z), 1))
                X[:, free] = Z
                return list(self.residuals(X))

            try:
                res = least_squares(
                    resid,
                    s[free],
                    bounds=(lo[free], hi[free]),
                    method="trf",
                    x_scale="jac",
                    max_nfev=max_nfev,
                    workers=resid_map,
                )
            except ValueError:
                continue
            if best is None or res.cost < best.cost:
                best = res
                best_x = full.copy()
                best_x[free] = res.x
        if best is None:
            raise ValueError("master-curve fit failed from every starting point")
        n, p = best.fun.size, int(free.sum())
        rss = float(2.0 * best.cost)
        s2 = rss / max(n - p, 1)
        J = best.jac
        cov = np.zeros((free.size, free.size))
        cov[np.ix_(free, free)] = s2 * np.linalg.pinv(J.T @ J, rcond=1e-12)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        best.x = best_x
        E = self.measured_modulus(best.x)
        d = self.data
        fitted = pd.DataFrame(
            {
                "temperature_C": d["T"],
                "frequency_Hz": d["f"],
                "specimen": np.array(d["specimens"])[d["spec"]],
                "E_norm_MPa_model": np.abs(E),
                "phase_deg_model": np.degrees(np.angle(E)),
            }
        )
        return MasterCurveFit(
            names=list(self.names),
            x=best.x,
            se=se,
            cov=cov,
            rss=rss,
            n_residuals=n,
            n_free=p,
            shift=self.shift,
            T_ref_C=self.T_ref_C,
            static_modulus=self.static_modulus,
            temperatures=self.temperatures,
            specimens=list(d["specimens"]),
            sigma_lnE=self.sigma[0],
            sigma_phase_deg=self.sigma[1],
            terms=list(self.terms),
            residuals=best.fun,
            fitted=fitted,
            specimen_mean=tuple(float(np.mean(v)) for v in self.specimen_terms(best.x)),
            lower=lo,
            upper=hi,
        )


def fit_master_curve(
    df: pd.DataFrame,
    shift: str = "wlf",
    T_ref_C: float | None = None,
    static_modulus: bool = True,
    terms=(),
    sigma=None,
    x0=None,
) -> MasterCurveFit:
    """Fit a 2S2P1D master curve with a shift law to a tidy measured table.

    Parameters
    ----------
    df : DataFrame
        Columns ``specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg`` (one row per
        replicate point; optional ``strain_microstrain``, ``test_step`` used by terms).
    shift : {"wlf", "arrhenius", "free"}
        Shift law (free: one log10 aT per isotherm, aT(Tref) = 1).
    T_ref_C : float, optional
        Reference temperature, degC (default: the tested temperature nearest the median).
    static_modulus : bool
        Fit E00 (True) or fix E00 = 0.
    terms : sequence of Term
        Extra measurement-model terms (see :mod:`asphalt_nscd.diagnosis.effects`).
    sigma : (float, float), optional
        Noise of ln|E*| and of Phi (deg); default from :func:`replicate_noise`, or
        (0.02, 0.5) without replicates.
    x0 : array, optional
        Starting point (same layout as the problem's ``names``); default: a few starts.

    Returns
    -------
    MasterCurveFit

    Raises
    ------
    ValueError
        if fewer than 2 temperatures are given, the shift law is unknown or no fit succeeds.
    """
    data = data_arrays(df)
    if data["temperatures"].size < 2:
        raise ValueError("a master curve needs at least 2 temperatures")
    if sigma is None:
        sE, sP = replicate_noise(df)
        sigma = (max(sE, 2e-3), max(sP, 0.03)) if sE is not None and sP is not None else (0.02, 0.5)
    prob = MasterCurveProblem(
        data,
        shift=shift,
        T_ref_C=T_ref_C,
        static_modulus=static_modulus,
        terms=terms,
        sigma_lnE=sigma[0],
        sigma_phase_deg=sigma[1],
    )
    return prob.fit(x0=x0)


def master_curve_table(fit: MasterCurveFit, df: pd.DataFrame, n_points: int = 200) -> pd.DataFrame:
    """Measured points at their reduced frequency and the fitted curve, for plotting.

    Returns a DataFrame with ``kind`` in {data, model}, ``reduced_frequency_Hz``,
    ``E_norm_MPa``, ``phase_deg`` (data rows also ``temperature_C``, ``specimen``).
    """
    aT = 10.0 ** fit.log_shift(df["temperature_C"].to_numpy(float))
    data = pd.DataFrame(
        {
            "kind": "data",
            "temperature_C": df["temperature_C"].to_numpy(float),
            "specimen": df["specimen"].astype(str).to_numpy(),
            "reduced_frequency_Hz": df["frequency_Hz"].to_numpy(float) * aT,
            "E_norm_MPa": df["E_norm_MPa"].to_numpy(float),
            "phase_deg": df["phase_deg"].to_numpy(float),
        }
    )
    fr = np.logspace(
        np.log10(data["reduced_frequency_Hz"].min()) - 0.5, np.log10(data["reduced_frequency_Hz"].max()) + 0.5, n_points
    )
    E = fit.modulus(fr, fit.T_ref_C)
    model = pd.DataFrame(
        {"kind": "model", "reduced_frequency_Hz": fr, "E_norm_MPa": np.abs(E), "phase_deg": np.degrees(np.angle(E))}
    )
    return pd.concat([data, model], ignore_index=True)
