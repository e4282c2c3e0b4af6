"""Extended bond law: one temperature-aware generalized Burger's law for a measured table.

:class:`ThermoLaw` is a 2S2P1D backbone (Olard & Di Benedetto 2003) at every temperature,

    E*(w, T) = b(T) [E00(T) + (E0 - E00(T)) / (1 + delta (i w tau_T)^-k + (i w tau_T)^-h
                                                 + (i w beta tau_T)^-1)],   tau_T = tau aT(T)

with T_ref the training temperature nearest the median, a shift law aT, WLF or Arrhenius
(:mod:`asphalt_nscd.rheology.shift`), a static modulus E00 ``none`` / ``constant`` / ``trend``
(log10 E00 linear in T), an optional vertical shift log10 b(T) = v (T - T_ref) / 100 K and an
optional per-isotherm refinement of log10 aT, log10 b, log10 E00 (``refine`` = kappa, penalty
kappa (d / 0.05 decade)^2). :func:`fit_backbone` fits it to the training cell means.
:meth:`ThermoLaw.law_at` turns the chain at T_ref once into a Prony (generalized Kelvin) chain
(:func:`~asphalt_nscd.rheology.models.fit_generalized_kelvin`, NNLS: causal and passive),
scales it to T (times x aT(T), moduli x b(T) (E0 - E00(T)) / (E0 - E00(T_ref)),
E_inf = b(T) E00(T)) and merges the units outside the tested band, giving the per-temperature
law of :mod:`asphalt_nscd.rheology.law_file`, E_inf + [1/Em + 1/(i w eta_m) + sum 1/(Ek + i w eta_k)]^-1.
:func:`best_causal_fit` bounds what any causal linear law can reach on one isotherm.

Choices (docs/choices.md, Diagnosis: the temperature-aware extended law and held-out validation):
* a parametric backbone, not a free spectrum; settings chosen by held-out error
  (:mod:`asphalt_nscd.diagnosis.crossval`), never by in-sample error;
* soft-L1 loss on residuals scaled by the tolerances (3 %, 5 %) (``loss="robust"``: a cell the
  backbone cannot follow weighs less than its square); ``loss="least_squares"`` weighs every cell
  by its square (the law a material card carries: :mod:`asphalt_nscd.diagnosis.crossval`); weak
  priors on the trends;
* ``per_decade`` retardation times per decade, ``margin_decades`` for the band and the merging.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from ..io import InputError
from . import law_file
from .laws import GeneralizedBurgers
from .metrics import at_temperature, relative_errors
from .models import fit_generalized_kelvin, log_time_grid, two_s2p1d_modulus
from .shift import arrhenius_log_shift

#: phases below this (deg) are weighted as if they were this large
PHASE_FLOOR_DEG = 1.0
#: default normalising tolerances (relative MRE of |E*| and of Phi) of the fit residuals
TOLERANCES = (0.03, 0.05)
#: deviation scale of the per-isotherm refinement, decades
REFINE_SCALE_DECADES = 0.05
#: the temperature trends of log10 E00 and log10 b, and their prior scale (decades per 100 K)
TREND_NAMES = ("static_trend_per_100K", "vertical_trend_per_100K")
TREND_SCALE = 1.0
SHIFTS = ("wlf", "arrhenius")
STATICS = ("none", "constant", "trend")
#: fit losses of :func:`fit_backbone`: its name -> scipy.optimize.least_squares' ``loss``
LOSSES = {"robust": "soft_l1", "least_squares": "linear"}
#: quantities of the per-isotherm refinement: log10 aT, log10 b, log10 E00
REFINED = ("aT", "b", "E00")
CORE_NAMES = ("log10_E0_MPa", "log10_delta", "k_over_h", "h", "log10_beta", "log10_tau_s")


@dataclass(frozen=True)
class LawSettings:
    """Complexity settings of the temperature-aware law (see the module docstring).

    ``shift``: ``wlf`` | ``arrhenius``; ``static``: ``none`` | ``constant`` | ``trend``;
    ``vertical``: bool; ``refine``: kappa > 0 of the per-isotherm refinement, or None (off);
    ``per_decade``: retardation times per decade of the Prony series (> 0).

    Raises
    ------
    ValueError
        on an unknown shift or static option, a non-positive kappa or density.
    """

    shift: str = "wlf"
    static: str = "constant"
    vertical: bool = False
    refine: float | None = None
    per_decade: float = 2.0

    def __post_init__(self):
        if self.shift not in SHIFTS:
            raise ValueError(f"shift: expected one of {list(SHIFTS)}, got {self.shift!r}")
        if self.static not in STATICS:
            raise ValueError(f"static: expected one of {list(STATICS)}, got {self.static!r}")
        if self.refine is not None and not (np.isfinite(self.refine) and self.refine > 0):
            raise ValueError(f"refine: expected a positive weight or None, got {self.refine!r}")
        if not (np.isfinite(self.per_decade) and self.per_decade > 0):
            raise ValueError(f"per_decade: expected a positive number, got {self.per_decade!r}")
        object.__setattr__(self, "vertical", bool(self.vertical))
        object.__setattr__(self, "per_decade", float(self.per_decade))
        if self.refine is not None:
            object.__setattr__(self, "refine", float(self.refine))

    @property
    def carriable(self) -> bool:
        """Whether a relaxation Prony series with a shift function (a material card,
        :mod:`asphalt_nscd.rheology.export`) carries the law: no vertical shift, no static
        modulus trend, no per-isotherm refinement."""
        return not self.vertical and self.static != "trend" and self.refine is None

    @property
    def structure(self) -> tuple:
        """The settings that change the backbone fit (all but ``per_decade``)."""
        return (self.shift, self.static, self.vertical, self.refine)

    def n_params(self, n_temperatures: int) -> int:
        """Number of backbone parameters for ``n_temperatures`` training isotherms."""
        return (
            len(CORE_NAMES)
            + (2 if self.shift == "wlf" else 1)
            + (self.static != "none")
            + (self.static == "trend")
            + self.vertical
            + ((2 + (self.static != "none")) * n_temperatures if self.refine else 0)
        )

    def complexity(self, n_temperatures: int = 5) -> tuple:
        """Sort key from the simplest to the most flexible setting (a total order): number
        of backbone parameters, then weaker refinement, density, shift, static, vertical."""
        return (
            self.n_params(n_temperatures),
            -(self.refine or np.inf),
            self.per_decade,
            SHIFTS.index(self.shift),
            STATICS.index(self.static),
            self.vertical,
        )

    def label(self) -> str:
        """``wlf, static=constant, vertical=off, refine=off, 2/decade``."""
        ref = "off" if self.refine is None else f"{self.refine:g}"
        return (
            f"{self.shift}, static={self.static}, vertical={'on' if self.vertical else 'off'}, "
            f"refine={ref}, {self.per_decade:g}/decade"
        )

    def as_dict(self) -> dict:
        return {
            "shift": self.shift,
            "static": self.static,
            "vertical": self.vertical,
            "refine": self.refine,
            "per_decade": self.per_decade,
        }


def backbone_names(settings: LawSettings, temperatures) -> list:
    """Parameter names of the backbone of ``settings`` with training isotherms ``temperatures``
    (degC): the core 2S2P1D ones, the shift constants, then the optional ones."""
    names = list(CORE_NAMES) + (["C1", "C2_K"] if settings.shift == "wlf" else ["Ea_kJ_mol"])
    if settings.static != "none":
        names.append("log10_E00_MPa")
    if settings.static == "trend":
        names.append("static_trend_per_100K")
    if settings.vertical:
        names.append("vertical_trend_per_100K")
    if settings.refine:
        names += [
            f"dlog10_{kind}_{T:g}"
            for kind in REFINED
            for T in temperatures
            if kind != "E00" or settings.static != "none"
        ]
    return names


@dataclass
class Backbone:
    """Fitted backbone modulus of :class:`ThermoLaw` (module docstring), MPa.

    ``names``/``x``: parameter layout and values; ``temperatures``: training isotherms (degC,
    sorted) of the refinement; ``cost``: the objective at the solution; ``lower`` /
    ``upper``: the fit's bounds (None when not fitted here); ``loss``: the fit loss (a key of
    :data:`LOSSES`).
    """

    settings: LawSettings
    T_ref_C: float
    temperatures: np.ndarray
    names: list
    x: np.ndarray
    cost: float = np.nan
    lower: np.ndarray | None = None
    upper: np.ndarray | None = None
    loss: str = "robust"

    def findings(self) -> list[dict]:
        """Parameters outside their plausible range for a mix, and fit parameters at a bound
        (:mod:`asphalt_nscd.rheology.plausibility`); the per-isotherm deviations are
        regularised, not bounded physically, and are not checked."""
        from .plausibility import at_bound, check_parameters

        c = self.core()
        values = {
            k: v for k, v in c.items() if k != "tau_s" and not (k == "E00_MPa" and self.settings.static == "none")
        }
        for name in ("C1", "C2_K", "Ea_kJ_mol", "vertical_trend_per_100K", "static_trend_per_100K"):
            if name in self.names:
                values[name] = self.value(name)
        found = check_parameters(values)
        if self.lower is not None and self.upper is not None:
            keep = [i for i, n in enumerate(self.names) if not n.startswith("dlog10_")]
            found += at_bound([self.names[i] for i in keep], self.x[keep], self.lower[keep], self.upper[keep])
        return found

    def value(self, name: str, default: float = 0.0) -> float:
        return float(self.x[self.names.index(name)]) if name in self.names else default

    def _deviation(self, kind: str, T) -> np.ndarray:
        T = np.asarray(T, float)
        if not self.settings.refine:
            return np.zeros_like(T)
        vals = np.array([self.value(f"dlog10_{kind}_{t:g}") for t in self.temperatures])
        if not vals.any():
            return np.zeros_like(T)
        return np.interp(T, self.temperatures, vals)

    def log_shift(self, T) -> np.ndarray:
        """log10 aT (with the refinement deviation) at ``T`` (degC), same shape."""
        T = np.asarray(T, float)
        if self.settings.shift == "wlf":
            C1, C2 = self.value("C1"), self.value("C2_K")
            dT = T - self.T_ref_C
            base = -C1 * dT / np.maximum(C2 + dT, 1e-6)
        else:
            base = arrhenius_log_shift(T, self.T_ref_C, self.value("Ea_kJ_mol") * 1e3)
        return base + self._deviation("aT", T)

    def log_vertical(self, T) -> np.ndarray:
        """log10 b(T) at ``T`` (degC)."""
        T = np.asarray(T, float)
        return self.value("vertical_trend_per_100K") * (T - self.T_ref_C) / 100.0 + self._deviation("b", T)

    def static_modulus(self, T) -> np.ndarray:
        """E00(T) before the vertical shift, MPa (0 for ``static = none``)."""
        T = np.asarray(T, float)
        if self.settings.static == "none":
            return np.zeros_like(T)
        return 10.0 ** (
            self.value("log10_E00_MPa")
            + self.value("static_trend_per_100K") * (T - self.T_ref_C) / 100.0
            + self._deviation("E00", T)
        )

    def interp_weights(self, T) -> np.ndarray:
        """(n, n_T) weights of the training isotherms in the linear interpolation (constant
        beyond the ends) of a per-isotherm deviation at ``T`` (degC, shape (n,))."""
        T = np.asarray(T, float)
        t = self.temperatures
        W = np.zeros((T.size, t.size))
        for j in range(t.size):
            e = np.zeros(t.size)
            e[j] = 1.0
            W[:, j] = np.interp(T, t, e)
        return W

    def log_jacobian(self, frequency_Hz, temperature_C) -> tuple[np.ndarray, np.ndarray]:
        """E* (MPa, shape (n,)) and the derivatives of ln E* with respect to ``x`` (complex,
        (n, len(x))): the exact Jacobian of the fit residuals (:func:`fit_backbone`)."""
        f = np.asarray(frequency_Hz, float)
        T = np.asarray(temperature_C, float)
        c = self.core()
        ln10 = np.log(10.0)
        idx = {n: i for i, n in enumerate(self.names)}
        J = np.zeros((f.size, len(self.names)), complex)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            L = self.log_shift(T)
            x = 1j * 2 * np.pi * f * c["tau_s"] * 10.0**L
            k, h, dl, beta = c["k"], c["h"], c["delta"], c["beta"]
            xk, xh, xb = x ** (-k), x ** (-h), 1.0 / (x * beta)
            D = 1.0 + dl * xk + xh + xb
            E00 = self.static_modulus(T)
            E0 = c["E0_MPa"]
            chain = (E0 - E00) / D
            core = E00 + chain
            E = core * 10.0 ** self.log_vertical(T)
            dcore_dD = -chain / D
            lnx = np.log(x)
            dD = {
                "log10_delta": ln10 * dl * xk,
                "log10_beta": -ln10 * xb,
                "k_over_h": -dl * xk * lnx * h,
                "h": -dl * xk * lnx * (k / h) - xh * lnx,
            }
            x_dDdx = -k * dl * xk - h * xh - xb  # x dD/dx
            dD["log10_tau_s"] = ln10 * x_dDdx
            for n, v in dD.items():
                J[:, idx[n]] = dcore_dD * v / core
            J[:, idx["log10_E0_MPa"]] = ln10 * E0 / D / core
            dT = T - self.T_ref_C
            if self.settings.shift == "wlf":
                C1, C2 = self.value("C1"), self.value("C2_K")
                dL = {"C1": -dT / (C2 + dT), "C2_K": C1 * dT / (C2 + dT) ** 2}
            else:
                from .shift import KELVIN, R_GAS

                dL = {"Ea_kJ_mol": 1e3 / (R_GAS * ln10) * (1.0 / (T + KELVIN) - 1.0 / (self.T_ref_C + KELVIN))}
            W = self.interp_weights(T) if self.settings.refine else None
            if W is not None:
                for j, t in enumerate(self.temperatures):
                    dL[f"dlog10_aT_{t:g}"] = W[:, j]
            for n, v in dL.items():
                J[:, idx[n]] = dcore_dD * ln10 * x_dDdx * v / core
            if self.settings.static != "none":
                dE00 = ln10 * E00 * (1.0 - 1.0 / D) / core  # d ln core / d log10 E00(T)
                J[:, idx["log10_E00_MPa"]] = dE00
                if "static_trend_per_100K" in idx:
                    J[:, idx["static_trend_per_100K"]] = dE00 * dT / 100.0
                if W is not None:
                    for j, t in enumerate(self.temperatures):
                        J[:, idx[f"dlog10_E00_{t:g}"]] = dE00 * W[:, j]
            if "vertical_trend_per_100K" in idx:
                J[:, idx["vertical_trend_per_100K"]] = ln10 * dT / 100.0
            if W is not None:
                for j, t in enumerate(self.temperatures):
                    J[:, idx[f"dlog10_b_{t:g}"]] = ln10 * W[:, j]
        return E, J

    def core(self) -> dict:
        """2S2P1D constants at T_ref: ``E0_MPa, E00_MPa, delta, k, h, beta, tau_s``."""
        h = self.value("h")
        return {
            "E0_MPa": 10 ** self.value("log10_E0_MPa"),
            "E00_MPa": float(self.static_modulus(self.T_ref_C)),
            "delta": 10 ** self.value("log10_delta"),
            "k": self.value("k_over_h") * h,
            "h": h,
            "beta": 10 ** self.value("log10_beta"),
            "tau_s": 10 ** self.value("log10_tau_s"),
        }

    def modulus(self, frequency_Hz, temperature_C) -> np.ndarray:
        """Backbone complex modulus (MPa) at broadcast (f Hz, T degC)."""
        f, T = np.broadcast_arrays(np.asarray(frequency_Hz, float), np.asarray(temperature_C, float))
        c = self.core()
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):  # trial points of a fit
            E00 = self.static_modulus(T)
            tau = c["tau_s"] * 10.0 ** self.log_shift(T)
            E = two_s2p1d_modulus(2 * np.pi * f, E00, c["E0_MPa"], c["delta"], c["k"], c["h"], c["beta"], tau)
            return E * 10.0 ** self.log_vertical(T)


def _cell_arrays(cells: pd.DataFrame):
    T = cells["temperature_C"].to_numpy(float)
    f = cells["frequency_Hz"].to_numpy(float)
    E = cells["E_norm_MPa"].to_numpy(float) * np.exp(1j * np.radians(cells["phase_deg"].to_numpy(float)))
    ph = np.radians(np.maximum(cells["phase_deg"].to_numpy(float), PHASE_FLOOR_DEG))
    return T, f, E, ph


def _bounds(name: str, T, E, T_ref) -> tuple[float, float]:
    Emax, Emin = float(np.abs(E).max()), float(np.abs(E).min())
    table = {
        "log10_E0_MPa": (np.log10(Emax) - 0.05, max(5.3, np.log10(Emax) + 1.0)),
        "log10_delta": (-1.5, 1.7),
        "k_over_h": (0.03, 0.97),
        "h": (0.1, 0.99),
        "log10_beta": (-1.0, 9.0),
        "log10_tau_s": (-12.0, 8.0),
        "C1": (0.5, 200.0),
        "C2_K": (max(T_ref - T.min() + 5.0, 5.0), 3000.0),
        "Ea_kJ_mol": (10.0, 1000.0),
        "log10_E00_MPa": (-2.0, min(np.log10(Emin) + 0.3, np.log10(Emax) - 0.1)),
        "static_trend_per_100K": (-3.0, 3.0),
        "vertical_trend_per_100K": (-3.0, 3.0),
    }
    return table.get(name, (-2.0, 2.0))


def _cold_starts(names, T, E, T_ref) -> list:
    Emax, Emin = float(np.abs(E).max()), float(np.abs(E).min())
    base = {
        "log10_E0_MPa": min(np.log10(Emax) + 0.25, 5.2),
        "log10_delta": np.log10(2.0),
        "k_over_h": 0.33,
        "h": 0.6,
        "log10_beta": 3.0,
        "C1": 25.0,
        "C2_K": max(170.0, T_ref - T.min() + 40.0),
        "Ea_kJ_mol": 200.0,
        "log10_E00_MPa": np.log10(Emin) - 0.7,
    }
    return [{**base, "log10_tau_s": lt} for lt in (-4.0, -2.5, -1.0, 0.5)]


def fit_backbone(
    cells: pd.DataFrame,
    settings: LawSettings,
    T_ref_C: float | None = None,
    tolerances=TOLERANCES,
    start: dict | None = None,
    loss: str = "robust",
    starts: list | None = None,
) -> Backbone:
    """Fit the backbone of :class:`ThermoLaw` to cell means (module docstring).

    Parameters
    ----------
    cells : DataFrame
        ``temperature_C, frequency_Hz, E_norm_MPa, phase_deg`` (one row per cell: replicate
        means; degC, Hz, MPa, deg), at least 2 temperatures.
    settings : LawSettings
    T_ref_C : float, optional
        Reference temperature, degC (default: the tested one nearest the median).
    tolerances : (float, float)
        tol_E, tol_Phi normalising the residuals (fractions).
    start : dict, optional
        Starting values by parameter name (e.g. a simpler fit's); missing ones start at 0
        (deviations, trends) or at the default starting point. Without it several cold
        starts are tried.
    loss : str
        ``robust`` (soft L1 of the scaled residuals) or ``least_squares`` (:data:`LOSSES`).
    starts : list of dict, optional
        Further starting points tried besides ``start`` or the cold starts (the lowest
        objective wins).

    Returns
    -------
    Backbone

    Raises
    ------
    ValueError
        with fewer than 2 temperatures, fewer residuals than parameters, an unknown loss, or no
        successful fit.
    """
    from scipy.optimize import least_squares

    if loss not in LOSSES:
        raise ValueError(f"fit_backbone: loss: expected one of {list(LOSSES)}, got {loss!r}")
    T, f, E, ph = _cell_arrays(cells)
    temps = np.unique(T)
    if temps.size < 2:
        raise ValueError("the temperature-aware law needs at least 2 temperatures")
    if T_ref_C is None:
        T_ref_C = float(temps[np.argmin(np.abs(temps - np.median(temps)))])
    names = backbone_names(settings, temps)
    n_reg = sum(n.startswith("dlog10_") for n in names)
    if 2 * T.size < len(names) - n_reg:
        raise ValueError(f"{2 * T.size} residuals for {len(names) - n_reg} parameters of '{settings.label()}'")
    lo, hi = np.array([[*_bounds(n, T, E, T_ref_C)] for n in names]).T
    proto = Backbone(settings, float(T_ref_C), temps, names, np.zeros(len(names)))
    tol_E, tol_P = tolerances
    # penalised parameters: the per-isotherm deviations (weight sqrt(kappa) / 0.05 decade) and
    # the two temperature trends (weight 1 per TREND_SCALE: a weak prior that keeps a trend the
    # data do not resolve, e.g. E00 over cold isotherms only, near 0)
    reg = np.array([n.startswith("dlog10_") or n in TREND_NAMES for n in names])
    w_reg = np.array(
        [
            1.0 / TREND_SCALE if n in TREND_NAMES else np.sqrt(settings.refine or 0.0) / REFINE_SCALE_DECADES
            for n in np.array(names)[reg]
        ]
    )

    def resid(x):
        proto.x = x
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            r = np.log(proto.modulus(f, T) / E)
            out = np.concatenate([r.real / tol_E, r.imag / (ph * tol_P), w_reg * x[reg]])
        return np.where(np.isfinite(out), out, 1e3)

    R = np.zeros((int(reg.sum()), len(names)))
    R[np.arange(R.shape[0]), np.flatnonzero(reg)] = w_reg

    def jac(x):
        proto.x = x
        _, D = proto.log_jacobian(f, T)
        out = np.vstack([D.real / tol_E, D.imag / (ph * tol_P)[:, None], R])
        return np.where(np.isfinite(out), out, 0.0)

    starts = ([start] if start is not None else _cold_starts(names, T, E, T_ref_C)) + list(starts or [])
    best = None
    for s in starts:
        x0 = np.array([s.get(n, 0.0) for n in names], float)
        x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        try:
            res = least_squares(
                resid,
                x0,
                jac=jac,
                bounds=(lo, hi),
                method="trf",
                loss=LOSSES[loss],
                f_scale=1.0,
                x_scale="jac",
                max_nfev=2000,
            )
        except ValueError:
            continue
        if best is None or res.cost < best.cost:
            best = res
    if best is None:
        raise ValueError(f"backbone fit '{settings.label()}' failed from every starting point")
    return Backbone(settings, float(T_ref_C), temps, names, best.x.copy(), float(best.cost), lo, hi, loss)


@dataclass
class ThermoLaw:
    """Temperature-aware generalized Burger's law (module docstring), MPa and MPa s.

    ``backbone``: the fitted :class:`Backbone`; ``prony``: the generalized Kelvin chain of
    the backbone at T_ref (E_inf = E00(T_ref), MPa); ``band_Hz``: tested frequency band
    (f_min, f_max) of the training table; ``temperature_range_C``: its tested temperatures
    (min, max) -- the calibrated range; ``margin_decades``: see the module docstring.
    """

    backbone: Backbone
    prony: GeneralizedBurgers
    band_Hz: tuple
    temperature_range_C: tuple
    margin_decades: float = 2.0
    info: dict = field(default_factory=dict)

    @property
    def settings(self) -> LawSettings:
        return self.backbone.settings

    @property
    def T_ref_C(self) -> float:
        return self.backbone.T_ref_C

    def inside(self, temperature_C: float) -> bool:
        """Whether ``temperature_C`` lies in the calibrated range (tested temperatures)."""
        lo, hi = self.temperature_range_C
        return bool(lo - 1e-9 <= temperature_C <= hi + 1e-9)

    def law_at(self, temperature_C: float, reduce: bool = True) -> GeneralizedBurgers:
        """The law at one temperature (MPa, MPa s; module docstring).

        ``reduce``: merge the Kelvin-Voigt units whose retardation time lies
        ``margin_decades`` outside the tested band into the Maxwell spring or dashpot.

        Raises
        ------
        InputError
            if the shift law is undefined at ``temperature_C`` (WLF: T - T_ref <= -C2).
        """
        bb = self.backbone
        T = float(temperature_C)
        if bb.settings.shift == "wlf" and bb.value("C2_K") + T - bb.T_ref_C <= 0:
            raise InputError(
                f"temperature {T:g} degC: outside the WLF domain (T - T_ref <= -C2 = "
                f"{-bb.value('C2_K'):.4g} K, T_ref = {bb.T_ref_C:g} degC)"
            )
        with np.errstate(over="ignore"):
            aT = float(10.0 ** bb.log_shift(T))
            b = float(10.0 ** bb.log_vertical(T))
        if not (np.isfinite(aT) and aT > 0 and np.isfinite(b) and b > 0):
            raise InputError(
                f"temperature {T:g} degC: the shift factors overflow (log10 aT = "
                f"{float(bb.log_shift(T)):.4g}); the law is undefined there"
            )
        E0 = bb.core()["E0_MPa"]
        E00_T = float(bb.static_modulus(T))
        if not E00_T < E0:
            raise InputError(
                f"temperature {T:g} degC: the static modulus trend reaches the glassy modulus "
                f"({E00_T:.4g} >= {E0:.4g} MPa); the law is undefined there"
            )
        c = b * (E0 - E00_T) / (E0 - float(bb.static_modulus(bb.T_ref_C)))
        p = self.prony
        Em, eta_m = p.Em * c, p.eta_m * c * aT
        Ek = np.asarray(p.Ek, float) * c
        eta_k = np.asarray(p.eta_k, float) * c * aT
        E_inf = b * E00_T
        if reduce and Ek.size:
            w_lo = 2 * np.pi * self.band_Hz[0] / 10**self.margin_decades
            w_hi = 2 * np.pi * self.band_Hz[1] * 10**self.margin_decades
            t = eta_k / Ek
            fast, slow = t < 1.0 / w_hi, t > 1.0 / w_lo
            J0 = 1.0 / Em + np.sum(1.0 / Ek[fast])
            phi = (0.0 if np.isinf(eta_m) else 1.0 / eta_m) + np.sum(1.0 / eta_k[slow])
            keep = ~(fast | slow)
            Em, eta_m = 1.0 / J0, (1.0 / phi if phi > 0 else np.inf)
            Ek, eta_k = Ek[keep], eta_k[keep]
        return GeneralizedBurgers(Em=Em, eta_m=eta_m, Ek=tuple(Ek), eta_k=tuple(eta_k), E_inf=E_inf)

    def complex_modulus(self, frequency_Hz, temperature_C) -> np.ndarray:
        """E* (MPa) of :meth:`law_at` at each (f Hz, T degC) pair (1-d arrays of equal length)."""
        f = np.atleast_1d(np.asarray(frequency_Hz, float))
        T = np.atleast_1d(np.asarray(temperature_C, float))
        f, T = np.broadcast_arrays(f, T)
        out = np.empty(f.shape, complex)
        for t in np.unique(T):
            sel = T == t
            out[sel] = self.law_at(float(t)).complex_modulus(2 * np.pi * f[sel])
        return out

    def laws(self, temperatures) -> dict:
        """{T (float): law_at(T)} for the given temperatures (degC)."""
        return {float(T): self.law_at(float(T)) for T in temperatures}

    def to_json(self, temperatures, references: dict | None = None) -> dict:
        """The law-file object (:func:`asphalt_nscd.rheology.law_file.to_json`) at ``temperatures`` (degC), plus
        ``model`` (:meth:`description`).

        Each entry also holds ``extrapolation`` (outside the calibrated range) and, at a
        temperature of a reference cell table, the in-sample MREs (%) against it:
        ``references`` maps a key suffix to cell means (``temperature_C, frequency_Hz,
        E_norm_MPa, phase_deg``), giving ``in_sample_mre_E_norm_pct<suffix>`` and
        ``in_sample_mre_phase_pct<suffix>``.

        Raises InputError if the law is undefined at a requested temperature.
        """
        temps = sorted({float(T) for T in temperatures})
        obj = law_file.to_json(self.laws(temps))
        for T in temps:
            d = obj["temperatures"][f"{T:g}"]
            d["extrapolation"] = not self.inside(T)
            for suffix, cells in (references or {}).items():
                g = at_temperature(cells, T)
                if len(g):
                    m = law_metrics(self, g.assign(temperature_C=T))
                    d[f"in_sample_mre_E_norm_pct{suffix}"] = float(100 * m["rel_err_E_norm"].mean())
                    d[f"in_sample_mre_phase_pct{suffix}"] = float(100 * m["rel_err_phase"].mean())
        obj["model"] = self.description()
        return obj

    def description(self) -> dict:
        """JSON-ready model description (the ``model`` object of the law JSON)."""
        bb = self.backbone
        p = self.prony.scaled(1e6).as_dict()
        if not np.isfinite(p["eta_m"]):
            p["eta_m"] = None
        shift = (
            {"law": "WLF", "C1": bb.value("C1"), "C2_K": bb.value("C2_K")}
            if bb.settings.shift == "wlf"
            else {"law": "Arrhenius", "Ea_kJ_mol": bb.value("Ea_kJ_mol")}
        )
        return {
            "form": "2S2P1D backbone at T_ref with shift law, static modulus, vertical shift and "
            "per-isotherm refinement; Prony (generalized Kelvin) chain at T_ref shifted by aT",
            "settings": bb.settings.as_dict(),
            "T_ref_C": bb.T_ref_C,
            "calibrated_temperature_range_C": list(self.temperature_range_C),
            "frequency_band_Hz": list(self.band_Hz),
            "margin_decades": self.margin_decades,
            "shift": shift,
            "fit_loss": bb.loss,
            "backbone": {k: float(v) for k, v in zip(bb.names, bb.x)},
            "backbone_2s2p1d_at_T_ref": {k: float(v) for k, v in bb.core().items()},
            "vertical_trend_decades_per_100K": bb.value("vertical_trend_per_100K"),
            "carriable_by_a_prony_card": bb.settings.carriable,
            "findings": bb.findings(),
            "prony_at_T_ref": {**p, "units": "Pa, Pa s"},
            **self.info,
        }


#: reduced-frequency band (decades, margins included) beyond which the Prony grid of :func:`fit_law`
#: is thinned to keep its size; asphalt mixes span about 10-20 (a wider band is an implausible shift
#: law, e.g. of phases in radians or of noise)
MAX_BAND_DECADES = 40.0


def fit_law(
    cells: pd.DataFrame,
    settings: LawSettings,
    T_ref_C: float | None = None,
    tolerances=TOLERANCES,
    margin_decades: float = 2.0,
    backbone: Backbone | None = None,
    loss: str = "robust",
    starts: list | None = None,
) -> ThermoLaw:
    """Fit :class:`ThermoLaw` to cell means (``temperature_C, frequency_Hz, E_norm_MPa,
    phase_deg``); ``backbone``: an already fitted one of the same structure (reused); ``loss``,
    ``starts``: of :func:`fit_backbone` (without ``backbone``).

    Raises ValueError as :func:`fit_backbone`, when the shift law spreads the cells over an
    infinite band, or if the Prony fit fails. Over a band wider than :data:`MAX_BAND_DECADES`
    the relaxation times are thinned to at most that many decades' worth.
    """
    bb = (
        backbone
        if backbone is not None
        else fit_backbone(cells, settings, T_ref_C, tolerances, loss=loss, starts=starts)
    )
    if backbone is not None and backbone.settings.structure != settings.structure:
        raise ValueError("fit_law: the given backbone has another structure than the settings")
    bb = Backbone(settings, bb.T_ref_C, bb.temperatures, bb.names, bb.x, bb.cost, bb.lower, bb.upper, bb.loss)
    T = cells["temperature_C"].to_numpy(float)
    f = cells["frequency_Hz"].to_numpy(float)
    with np.errstate(over="ignore", invalid="ignore"):
        wr = 2 * np.pi * f * 10.0 ** bb.log_shift(T)
        w_lo, w_hi = wr.min() / 10**margin_decades, wr.max() * 10**margin_decades
        span = float(np.log10(w_hi / w_lo)) if w_lo > 0 else np.inf
    if not np.isfinite(span):
        raise ValueError("fit_law: the shift law spreads the tested cells over an infinite band of reduced frequency")
    # a band wider than a mix's (an implausible shift law, reported by the plausibility checks) keeps at most
    # MAX_BAND_DECADES x per_decade relaxation times: bounded work, coarser series
    per_decade = settings.per_decade * min(1.0, MAX_BAND_DECADES / span)
    omega = np.logspace(np.log10(w_lo), np.log10(w_hi), int(np.ceil(10 * min(span, MAX_BAND_DECADES))) + 1)
    c = bb.core()
    E_ref = two_s2p1d_modulus(omega, c["E00_MPa"], c["E0_MPa"], c["delta"], c["k"], c["h"], c["beta"], c["tau_s"])
    tau = log_time_grid(w_lo, w_hi, per_decade=per_decade, margin_decades=0.5)
    prony = fit_generalized_kelvin(
        omega, E_ref, tau, E_inf=c["E00_MPa"], dashpot=True, glassy_modulus=c["E0_MPa"] - c["E00_MPa"]
    )
    return ThermoLaw(
        bb, prony, (float(f.min()), float(f.max())), (float(T.min()), float(T.max())), float(margin_decades)
    )


def law_metrics(law, cells: pd.DataFrame) -> pd.DataFrame:
    """Per-cell relative errors of a law against cell means.

    ``law``: a :class:`ThermoLaw` or a dict {T: GeneralizedBurgers (MPa)}. Returns ``cells``
    with ``E_norm_MPa_model, phase_deg_model, rel_err_E_norm, rel_err_phase`` (fractions:
    | |E*|_model / |E*| - 1 | and | Phi_model - Phi | / Phi).
    """
    f = cells["frequency_Hz"].to_numpy(float)
    T = cells["temperature_C"].to_numpy(float)
    if isinstance(law, ThermoLaw):
        E = law.complex_modulus(f, T)
    else:
        E = np.array([law[float(t)].complex_modulus(2 * np.pi * x) for t, x in zip(T, f)])
    out = cells.copy()
    out["E_norm_MPa_model"] = np.abs(E)
    out["phase_deg_model"] = np.degrees(np.angle(E))
    out["rel_err_E_norm"] = relative_errors(out["E_norm_MPa_model"], out["E_norm_MPa"])
    out["rel_err_phase"] = relative_errors(out["phase_deg_model"], out["phase_deg"])
    return out


def _minimax_lp(residuals, jacobian, p0, trust_floor, tolerances, prior_weight, max_iter=200, free=None):
    """Sequential linear programming for min over p >= 0 of
    max(mean|a(p)|/tol_a, mean|b(p)|/tol_b) + 0.01 (mean|a|/tol_a + mean|b|/tol_b)
    + prior_weight mean(|p - p0| / (p0 + trust_floor)).

    ``residuals(p) -> (a, b)`` (each (m,)), ``jacobian(p) -> (Ja, Jb)`` (each (m, n));
    ``trust_floor`` (n,) > 0: scale of a parameter that is zero; ``free`` (n,) bool: the
    parameters that may change (default all). Returns (p, objective).
    """
    from scipy.optimize import linprog

    tol_a, tol_b = tolerances
    ref = p0 + trust_floor

    def objective(p):
        a, b = residuals(p)
        ra, rb = np.mean(np.abs(a)) / tol_a, np.mean(np.abs(b)) / tol_b
        return max(ra, rb) + 0.01 * (ra + rb) + prior_weight * np.mean(np.abs(p - p0) / ref)

    p = np.asarray(p0, float).copy()
    n = p.size
    free = np.ones(n, bool) if free is None else np.asarray(free, bool)
    f = objective(p)
    delta = 1.0
    for _ in range(max_iter):
        a, b = residuals(p)
        Ja, Jb = jacobian(p)
        m = a.size
        # variables: dp (n), slack |a| (m), slack |b| (m), slack |p + dp - p0| (n), t
        nv = n + 2 * m + n + 1
        ia, ib, iq, it = n, n + m, n + 2 * m, nv - 1
        c = np.zeros(nv)
        c[it] = 1.0
        c[ia:ib] = 0.01 / (m * tol_a)
        c[ib:iq] = 0.01 / (m * tol_b)
        c[iq:it] = prior_weight / (n * ref)
        rows, rhs = [], []
        for J, r, i0 in ((Ja, a, ia), (Jb, b, ib)):
            for k in range(m):
                for sgn in (1.0, -1.0):
                    row = np.zeros(nv)
                    row[:n] = sgn * J[k]
                    row[i0 + k] = -1.0
                    rows.append(row)
                    rhs.append(-sgn * r[k])
        for i in range(n):
            for sgn in (1.0, -1.0):
                row = np.zeros(nv)
                row[i] = sgn
                row[iq + i] = -1.0
                rows.append(row)
                rhs.append(-sgn * (p[i] - p0[i]))
        for i0, tol in ((ia, tol_a), (ib, tol_b)):
            row = np.zeros(nv)
            row[i0 : i0 + m] = 1.0 / (m * tol)
            row[it] = -1.0
            rows.append(row)
            rhs.append(0.0)
        step = np.where(free, delta * (p + trust_floor), 0.0)
        bounds = [(max(-p[i], -step[i]), step[i]) for i in range(n)] + [(0.0, None)] * (2 * m + n + 1)
        lp = linprog(c, A_ub=np.array(rows), b_ub=np.array(rhs), bounds=bounds, method="highs")
        if lp.status != 0:
            delta *= 0.5
        else:
            p_new = np.maximum(p + lp.x[:n], 0.0)
            f_new = objective(p_new)
            if f_new < f - 1e-10:
                p, f = p_new, f_new
                delta = min(2.0 * delta, 10.0)
                continue
            delta *= 0.5
        if delta < 1e-6:
            break
    return p, f


def best_causal_fit(frequency_Hz, E_norm_MPa, phase_deg, tolerances=TOLERANCES, per_decade: float = 4.0) -> dict:
    """Closest causal linear viscoelastic fit to one isotherm (a consistency diagnostic).

    A generalized Maxwell series E* = E_inf + sum_i E_i i w rho_i / (1 + i w rho_i) with
    E_inf, E_i >= 0 (a positive relaxation spectrum: every passive linear viscoelastic solid
    or, with rho -> inf, liquid; it obeys the Kramers-Kronig relations) with ``per_decade``
    relaxation times per decade over 7 decades on both sides of 1/w at the centre of the
    band (log scale). Started from the NNLS fit of the complex modulus in relative terms
    (:func:`~asphalt_nscd.rheology.models.fit_generalized_maxwell`), then the larger of
    MRE(|E*|)/tol_E and MRE(Phi)/tol_Phi is minimised by sequential linear programming (no
    prior). The result is an upper bound of the best any causal law can do (a local
    optimum; the LP steps make it robust on these small problems).

    Parameters
    ----------
    frequency_Hz, E_norm_MPa, phase_deg : arrays (m,), Hz, MPa, deg (replicate means).

    Returns
    -------
    dict: ``objective`` (the minimax ratio: <= 1 means both tolerances can be met),
    ``mre_E_norm_pct``, ``mre_phase_pct`` of that fit, ``n_modes``.
    """
    from .models import fit_generalized_maxwell

    f = np.asarray(frequency_Hz, float)
    Ed = np.asarray(E_norm_MPa, float)
    ph = np.asarray(phase_deg, float)
    ph_rad = np.radians(ph)
    ph_scale = np.radians(np.maximum(ph, PHASE_FLOOR_DEG))
    w = 2 * np.pi * f
    centre = -np.log10(np.sqrt(w.min() * w.max()))
    rho = np.logspace(centre - 7.0, centre + 7.0, int(round(14 * per_decade)) + 1)
    A = np.column_stack([np.ones(w.size, complex), (1j * w[:, None]) * rho / (1.0 + 1j * w[:, None] * rho)])
    start = fit_generalized_maxwell(w, Ed * np.exp(1j * np.radians(ph)), rho)
    p0 = np.concatenate([[start["E_inf"]], start["E_i"]])

    def residuals(p):
        E = A @ p
        return np.abs(E) / Ed - 1.0, (np.angle(E) - ph_rad) / ph_scale

    def jacobian(p):
        E = A @ p
        return (
            np.real(np.conj(E)[:, None] * A) / (np.abs(E) * Ed)[:, None],
            np.imag(A / E[:, None]) / ph_scale[:, None],
        )

    floor = np.full(p0.size, 1e-3 * Ed.max() / p0.size)
    p, _ = _minimax_lp(residuals, jacobian, p0, floor, tolerances, 0.0, max_iter=400)
    a, b = residuals(p)
    mE, mP = 100 * np.mean(np.abs(a)), 100 * np.mean(np.abs(b))
    return {
        "objective": float(max(mE / (100 * tolerances[0]), mP / (100 * tolerances[1]))),
        "mre_E_norm_pct": float(mE),
        "mre_phase_pct": float(mP),
        "n_modes": int(np.sum(p[1:] > 0)),
    }
