"""Empirical baselines: the |E*| formulas pavement engineers use, published and recalibrated.

witczak_1_37a   viscosity-based sigmoid of Andrei, Witczak & Mirza (1999), the NCHRP 1-37A
                MEPDG model (Appendix CC-4)
witczak_1_40d   binder |G*|- and phase-angle-based sigmoid of Bari & Witczak (2006), NCHRP 1-40D
hirsch          law of mixtures with a contact volume Pc, Christensen, Pellinen & Bonaquist
                (2003); the only one of the three with a phase angle equation

Each model function gives its equation, its source and the units it is written in. Reviews that
restate all three: Garcia & Thompson (2007), FHWA-ICT-07-005; Kim et al. (2011), FHWA-HRT-10-035.

Units: SI at the edges (|E*| MPa, |G*| Pa, eta Pa s, angles degrees, f Hz, gradation and
volumes %); inside, each equation's own units (|E*| and |G*| psi, eta 10^6 P = 1e5 Pa s,
delta_b degrees), converted with :data:`PSI_MPA` and :data:`PA_S_PER_MEGAPOISE`. Binder inputs
are taken at the mix's temperature and loading frequency (same Hz): shifting them is the caller's.

Coefficients are named (:data:`PUBLISHED`), signs included, so each equation is a plain sum;
``coef`` arguments take any mapping holding all of a model's names (other keys are ignored, so a
:func:`recalibrate` result can be passed back).

Recalibration (:func:`recalibrate`): SciPy ``least_squares`` ("trf", ``x_scale="jac"``) of the
ln|E*| residuals over the training rows, from the starting coefficients, each coefficient moved
in units of its starting magnitude, u = (c - c0)/|c0| (log or logit steps for Hirsch's positive
and bounded ones). A weak ridge, sqrt(n) RIDGE u per coefficient, keeps directions the data do
not determine at their start (collinear gradations of few distinct mixes; 1-40D's a1, which only
scales its bracket): RIDGE = 1e-3 costs 1e-6 per row for a 100 % change, far below any data
residual. Hirsch keeps Pc in (0, 1) for every binder by construction: pc_b in (0, 1) and
pc_c = pc_a^pc_b + margin with margin > 0; its phase coefficients are then fitted on the phase
residuals (degrees) given the fitted Pc.
The fits' Jacobian is SciPy's "2-point" forward difference, its columns evaluated in one
broadcast call of the equation (:func:`_forward_difference_jacobian`) rather than one call each.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.special import expit, logit

#: MPa in one psi (1 psi = 6894.757293168361 Pa).
PSI_MPA = 6.894757293168361e-3
#: Pa s in 10^6 P (1 P = 0.1 Pa s).
PA_S_PER_MEGAPOISE = 1e5
#: Rounding allowed above a 90 degree binder phase angle (pi/2 rad printed to 10 digits).
DELTA_SLACK_DEG = 1e-6
#: Weight of the ridge towards the starting coefficients, per coefficient and per sqrt(row).
RIDGE = 1e-3

MODELS = ("witczak_1_37a", "witczak_1_40d", "hirsch")

#: Published coefficients, signs included (equations in each model's docstring).
PUBLISHED: dict[str, dict[str, float]] = {
    "witczak_1_37a": {
        "a0": 3.750063,  # -1.249937 with |E*| in 1e5 psi (Andrei et al. 1999)
        "a_p200": 0.029232,
        "a_p200_2": -0.001767,
        "a_p4": -0.002841,
        "a_Va": -0.058097,
        "a_Vr": -0.802208,
        "s0": 3.871977,
        "s_p4": -0.0021,
        "s_p38": 0.003958,
        "s_p38_2": -0.000017,
        "s_p34": 0.005470,
        "t0": -0.603313,
        "t_f": -0.313351,
        "t_eta": -0.393532,
    },
    "witczak_1_40d": {
        "a0": -0.349,
        "a1": 0.754,
        "a2": -0.0052,
        "b0": 6.65,
        "b_p200": -0.032,
        "b_p200_2": 0.0027,
        "b_p4": 0.011,
        "b_p4_2": -0.0001,
        "b_p38": 0.006,
        "b_p38_2": -0.00014,
        "b_Va": -0.08,
        "b_Vr": -1.06,
        "s0": 2.558,
        "s_Va": 0.032,
        "s_Vr": 0.713,
        "s_p38": 0.0124,
        "s_p38_2": -0.0001,
        "s_p34": -0.0098,
        "t0": -0.7814,
        "t_G": -0.5785,
        "t_delta": 0.8834,
    },
    "hirsch": {
        "Ea_psi": 4_200_000.0,
        "pc_a": 20.0,
        "pc_b": 0.58,
        "pc_c": 650.0,
        "phi_2": -21.0,
        "phi_1": -55.0,
    },
}

#: Hirsch's phase coefficients, fitted after (and given) its |E*| part.
_PHASE = ("phi_2", "phi_1")
#: The binder and loading inputs each model reads.
_USES = {
    "witczak_1_37a": ("frequency_Hz", "eta_Pa_s"),
    "witczak_1_40d": ("G_Pa", "delta_deg"),
    "hirsch": ("G_Pa",),
}


@dataclass(frozen=True, eq=False)
class Mix:
    """Gradation and volumetrics of mixes, one value per row (arrays or scalars, broadcastable).

    rho34, rho38, rho4 : cumulative % retained on the 19, 9.5 and 4.75 mm sieves (by mass of
    aggregate); rho200 : % passing the 0.075 mm sieve; Va, Vbeff : air voids and effective binder,
    % by volume of mix. Stored as float arrays. NaN is let through (a missing input gives a missing
    prediction); out-of-range values raise ValueError, as do cumulative retained percentages that
    decrease with sieve size (rho34 <= rho38 <= rho4 <= 100 - rho200; catches % passing given
    for % retained).
    """

    rho34: ArrayLike
    rho38: ArrayLike
    rho4: ArrayLike
    rho200: ArrayLike
    Va: ArrayLike
    Vbeff: ArrayLike

    def __post_init__(self):
        try:
            np.broadcast_shapes(*(np.shape(getattr(self, f.name)) for f in fields(self)))
        except ValueError:
            shapes = {f.name: np.shape(getattr(self, f.name)) for f in fields(self)}
            raise ValueError(f"Mix: fields not broadcastable together, shapes {shapes}") from None
        for f in fields(self):
            value = np.asarray(getattr(self, f.name), dtype=float)
            object.__setattr__(self, f.name, value)
            if np.any((value < 0) | (value > 100)):
                raise ValueError(f"Mix.{f.name}: expected % in [0, 100], got {value}")
        if np.any(self.Vbeff <= 0) or np.any(self.Va + self.Vbeff >= 100):
            raise ValueError(f"Mix: expected Vbeff > 0 and Va + Vbeff < 100, got Va={self.Va}, Vbeff={self.Vbeff}")
        chain = (("rho34", self.rho34), ("rho38", self.rho38), ("rho4", self.rho4), ("100 - rho200", 100 - self.rho200))
        for (low_name, low), (high_name, high) in zip(chain, chain[1:]):
            if np.any(low > high):
                raise ValueError(
                    f"Mix: cumulative % retained must not decrease with sieve size, got {low_name}={low} > "
                    f"{high_name}={high} (% passing given for % retained?)"
                )

    @property
    def VMA(self) -> np.ndarray:
        """Voids in the mineral aggregate, % = Va + Vbeff."""
        return np.asarray(self.Va) + np.asarray(self.Vbeff)

    @property
    def VFA(self) -> np.ndarray:
        """Voids filled with asphalt, % = 100 Vbeff / VMA."""
        return 100.0 * np.asarray(self.Vbeff) / self.VMA


def witczak_1_37a(mix: Mix, frequency_Hz: ArrayLike, eta_Pa_s: ArrayLike, coef=None) -> np.ndarray:
    """|E*| of the viscosity-based Witczak model of NCHRP 1-37A (MEPDG).

    Andrei, Witczak & Mirza (1999), "Development of a revised predictive model for the dynamic
    (complex) modulus of asphalt mixtures", NCHRP 1-37A interim report, = MEPDG (2004) Appendix
    CC-4 (equation number not verified here)::

        log10|E*| = a0 + 0.029232 p200 - 0.001767 p200^2 - 0.002841 p4 - 0.058097 Va
                    - 0.802208 Vbeff/(Vbeff + Va)
                    + (3.871977 - 0.0021 p4 + 0.003958 p38 - 0.000017 p38^2 + 0.005470 p34)
                      / (1 + exp(-0.603313 - 0.313351 log10 f - 0.393532 log10 eta))

    |E*| in psi with a0 = 3.750063 (MEPDG's form); Andrei et al. write |E*| in 1e5 psi with
    a0 = -1.249937, the same equation. eta in 10^6 P (= 1e5 Pa s), f in Hz. Some transcriptions
    print 0.02932 for p200's coefficient; 0.029232 (Andrei et al.) is taken.

    Parameters
    ----------
    mix : Mix
        Gradation and volumetrics, any shape broadcastable with the other inputs.
    frequency_Hz : array_like
        Loading frequency, Hz, > 0.
    eta_Pa_s : array_like
        Binder viscosity at the mix's temperature, Pa s, > 0 (1 cP = 1e-3 Pa s, 1 P = 0.1 Pa s).
    coef : mapping, optional
        Coefficients (names of ``PUBLISHED["witczak_1_37a"]``); the published ones by default.

    Returns
    -------
    ndarray, broadcast shape of the inputs
        |E*|, MPa.

    Raises
    ------
    ValueError
        on a non-positive frequency or viscosity, or coefficients missing a name.
    """
    return predict("witczak_1_37a", mix, frequency_Hz, None, None, eta_Pa_s, coef)[0]


def witczak_1_40d(mix: Mix, G_Pa: ArrayLike, delta_deg: ArrayLike, coef=None) -> np.ndarray:
    """|E*| of the binder-|G*|-based Witczak model of NCHRP 1-40D.

    Bari & Witczak (2006), "Development of a new revised version of the Witczak E* predictive
    model for hot mix asphalt mixtures", J. AAPT 75, 381-423 (Bari 2005, PhD thesis, Arizona
    State University; equation number not verified here)::

        log10|E*| = -0.349 + 0.754 |Gb*|^-0.0052 (6.65 - 0.032 p200 + 0.0027 p200^2 + 0.011 p4
                    - 0.0001 p4^2 + 0.006 p38 - 0.00014 p38^2 - 0.08 Va - 1.06 Vr)
                    + (2.558 + 0.032 Va + 0.713 Vr + 0.0124 p38 - 0.0001 p38^2 - 0.0098 p34)
                      / (1 + exp(-0.7814 - 0.5785 log10|Gb*| + 0.8834 log10 delta_b))

    Vr = Vbeff/(Vbeff + Va); |E*| and |Gb*| in psi, delta_b in degrees. |Gb*| and delta_b are
    taken at the mix's frequency in Hz (how Bari's database paired binder and mix frequencies was
    not verified here). The 0.754 multiplies the whole bracket, so only the products a1 b_k are
    determined by data (see the module's ridge).

    Parameters
    ----------
    mix : Mix
        Gradation and volumetrics, any shape broadcastable with the other inputs.
    G_Pa : array_like
        Binder |G*| at the mix's temperature and frequency, Pa, > 0.
    delta_deg : array_like
        Binder phase angle there, degrees, in (0, 90].
    coef : mapping, optional
        Coefficients (names of ``PUBLISHED["witczak_1_40d"]``); the published ones by default.

    Returns
    -------
    ndarray, broadcast shape of the inputs
        |E*|, MPa.

    Raises
    ------
    ValueError
        on a non-positive |G*|, a phase angle outside (0, 90], or coefficients missing a name.
    """
    return predict("witczak_1_40d", mix, None, G_Pa, delta_deg, None, coef)[0]


def hirsch(mix: Mix, G_Pa: ArrayLike, coef=None) -> tuple[np.ndarray, np.ndarray]:
    """|E*| and phase angle of the Hirsch model.

    Christensen, Pellinen & Bonaquist (2003), "Hirsch model for estimating the modulus of asphalt
    concrete", J. AAPT 72, 97-121 (equation numbers not verified here)::

        |E*| = Pc [Ea (1 - VMA/100) + 3|G*| VFA VMA/10000]
               + (1 - Pc) [(1 - VMA/100)/Ea + VMA/(3 VFA |G*|)]^-1
        Pc   = (20 + VFA 3|G*|/VMA)^0.58 / (650 + (VFA 3|G*|/VMA)^0.58)
        phi  = -21 (log10 Pc)^2 - 55 log10 Pc

    Ea = 4,200,000 psi (aggregate modulus), |E*| and |G*| in psi, phi in degrees, VMA and VFA in
    %. The 3 is E = 3G of the incompressible binder, not a coefficient. Published Pc is in
    (0.0087, 1), phi in (0, 36] degrees.

    Parameters
    ----------
    mix : Mix
        Volumetrics (only Va and Vbeff are read), broadcastable with ``G_Pa``.
    G_Pa : array_like
        Binder |G*| at the mix's temperature and frequency, Pa, > 0.
    coef : mapping, optional
        Coefficients (names of ``PUBLISHED["hirsch"]``); the published ones by default.

    Returns
    -------
    (ndarray, ndarray), broadcast shape of the inputs
        |E*|, MPa, and phase angle, degrees.

    Raises
    ------
    ValueError
        on a non-positive |G*| or coefficients missing a name.
    """
    E_MPa, phase = predict("hirsch", mix, None, G_Pa, None, None, coef)
    return E_MPa, cast(np.ndarray, phase)


def predict(
    model: str, mix: Mix, frequency_Hz, G_Pa, delta_deg, eta_Pa_s, coef=None
) -> tuple[np.ndarray, np.ndarray | None]:
    """|E*| and phase angle of any of :data:`MODELS`, from the inputs it reads.

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    mix : Mix
        Gradation and volumetrics.
    frequency_Hz, G_Pa, delta_deg, eta_Pa_s : array_like or None
        Loading frequency (Hz) and binder |G*| (Pa), phase angle (degrees) and viscosity (Pa s) at
        the mix's temperature; those the model does not read (see each model) may be None.
    coef : mapping, optional
        The model's coefficients; :data:`PUBLISHED` by default.

    Returns
    -------
    (ndarray, ndarray or None)
        |E*| (MPa) and phase angle (degrees; None for the Witczak models, which have no phase
        equation), of the broadcast shape of the inputs.

    Raises
    ------
    ValueError
        on an unknown model, a missing or out-of-range input the model reads, or coefficients
        missing a name.
    """
    c = _coefficients(model, coef, "coef")
    ln_E_psi, pc = _ln_modulus_psi(model, c, mix, _inputs(model, frequency_Hz, G_Pa, delta_deg, eta_Pa_s))
    E_MPa = np.exp(ln_E_psi) * PSI_MPA
    return E_MPa, None if pc is None else _hirsch_phase(c, pc)


def recalibrate(
    model: str,
    mix: Mix,
    frequency_Hz,
    G_Pa,
    delta_deg,
    eta_Pa_s,
    E_MPa,
    phase_deg=None,
    coef0=None,
    free=None,
) -> dict:
    """Least-squares coefficients of a model on training rows, from its published ones.

    Minimises sum_i (ln|E*|_model,i - ln|E*|_i)^2 + n RIDGE^2 sum_j u_j^2 over the free
    coefficients, u_j their change in units of their starting magnitude (module docstring), by
    SciPy's ``least_squares`` ("trf", ``x_scale="jac"``); deterministic. For Hirsch the phase
    coefficients are then fitted alike on phi_model - phi (degrees), given the fitted Pc, if
    ``phase_deg`` is given (else they stay at their start).

    Parameters
    ----------
    model : str
        One of :data:`MODELS`.
    mix : Mix
        Gradation and volumetrics of the rows.
    frequency_Hz, G_Pa, delta_deg, eta_Pa_s : array_like or None
        As in :func:`predict`; all inputs broadcast to n rows, shape (n,) or scalars.
    E_MPa : array_like, shape (n,)
        Measured |E*|, MPa, > 0.
    phase_deg : array_like, shape (n,), optional
        Measured phase angle, degrees; read for Hirsch only.
    coef0 : mapping, optional
        Starting coefficients (:data:`PUBLISHED` by default), also the ridge's centre. Hirsch's
        must have Ea_psi > 0, pc_a > 0, 0 < pc_b < 1, pc_c > pc_a^pc_b.
    free : iterable of str, optional
        Names of the coefficients to fit (default: all); the others stay at ``coef0``. Hirsch's
        pc_a and pc_b are fitted only with pc_c (the margin that keeps Pc < 1).

    Returns
    -------
    dict
        The model's coefficients (every name), ``rmse_ln_E`` (root mean square ln|E*| residual,
        in-sample) and ``n_rows``.

    Raises
    ------
    ValueError
        naming the row of a non-finite input the model reads (mix fields, binder inputs, |E*|,
        Hirsch's phase), on a non-positive |E*| or other input out of range, an unknown model or
        coefficient name, or Hirsch starting coefficients or ``free`` that break Pc in (0, 1).
    """
    start = _coefficients(model, coef0, "coef0")
    names = list(start) if free is None else list(dict.fromkeys(free))
    unknown = [n for n in names if n not in start]
    if unknown:
        raise ValueError(f"free: unknown coefficients {unknown} for {model}; expected names among {list(start)}")
    if model == "hirsch":
        _check_hirsch_start(start, names)
    raw = {"frequency_Hz": frequency_Hz, "G_Pa": G_Pa, "delta_deg": delta_deg, "eta_Pa_s": eta_Pa_s}
    rows, inputs, E, phase = _training_rows(model, mix, raw, E_MPa, phase_deg)
    ln_E = np.log(E)
    n = ln_E.size

    def ln_E_residuals(c):
        return _ln_modulus_psi(model, c, rows, inputs)[0] + np.log(PSI_MPA) - ln_E

    fitted = _fit(model, ln_E_residuals, start, [m for m in names if m not in _PHASE], n)
    pc = _ln_modulus_psi(model, fitted, rows, inputs)[1]
    if pc is not None and phase is not None:
        pc_fit, phase_fit = pc, phase
        fitted = _fit(
            model, lambda c: _hirsch_phase(c, pc_fit) - phase_fit, fitted, [m for m in names if m in _PHASE], n
        )
    rmse = float(np.sqrt(np.mean(ln_E_residuals(fitted) ** 2)))
    return {**fitted, "rmse_ln_E": rmse, "n_rows": n}


def _coefficients(model: str, coef, argument: str) -> dict[str, float]:
    """The model's coefficients from ``coef`` (all names required, others ignored)."""
    if model not in MODELS:
        raise ValueError(f"model: unknown {model!r}; expected one of {MODELS}")
    if coef is None:
        return dict(PUBLISHED[model])
    missing = [n for n in PUBLISHED[model] if n not in coef]
    if missing:
        raise ValueError(f"{argument}: missing coefficients {missing} of {model}")
    out = {n: float(coef[n]) for n in PUBLISHED[model]}
    if not all(np.isfinite(v) for v in out.values()):
        raise ValueError(f"{argument}: non-finite coefficients for {model}: {out}")
    return out


def _positive(name: str, value) -> np.ndarray:
    if value is None:
        raise ValueError(f"{name}: required by this model, got None")
    x = np.asarray(value, dtype=float)
    if np.any(x <= 0):
        raise ValueError(f"{name}: expected positive values, got {np.sum(x <= 0)} that are not: {x[x <= 0][:5]}")
    return x


def _inputs(model: str, frequency_Hz, G_Pa, delta_deg, eta_Pa_s) -> dict[str, np.ndarray]:
    """The binder and loading inputs of ``model`` in its equation's units, checked."""
    if model == "witczak_1_37a":
        eta = _positive("eta_Pa_s", eta_Pa_s) / PA_S_PER_MEGAPOISE
        return {"f_Hz": _positive("frequency_Hz", frequency_Hz), "eta_megapoise": eta}
    G = {"G_psi": _positive("G_Pa", G_Pa) * (1e-6 / PSI_MPA)}
    if model == "witczak_1_40d":
        delta = _positive("delta_deg", delta_deg)
        if np.any(delta > 90 + DELTA_SLACK_DEG):
            raise ValueError(
                f"delta_deg: expected a binder phase angle in (0, 90] degrees, got {delta[delta > 90][:5]}"
            )
        G["delta_deg"] = delta
    return G


def _ln_modulus_psi(model: str, c: dict, mix: Mix, x: dict) -> tuple[np.ndarray, np.ndarray | None]:
    """ln|E*| (psi) of ``model`` and, for Hirsch, its contact volume Pc (equations in the model
    functions' docstrings; ``x`` from :func:`_inputs`)."""
    p200, p4, p38, p34, Va = (np.asarray(v) for v in (mix.rho200, mix.rho4, mix.rho38, mix.rho34, mix.Va))
    Vr = np.asarray(mix.Vbeff) / mix.VMA
    if model == "witczak_1_37a":
        floor = c["a0"] + c["a_p200"] * p200 + c["a_p200_2"] * p200**2 + c["a_p4"] * p4 + c["a_Va"] * Va
        span = c["s0"] + c["s_p4"] * p4 + c["s_p38"] * p38 + c["s_p38_2"] * p38**2 + c["s_p34"] * p34
        z = c["t0"] + c["t_f"] * np.log10(x["f_Hz"]) + c["t_eta"] * np.log10(x["eta_megapoise"])
        return np.log(10.0) * (floor + c["a_Vr"] * Vr + span * expit(-z)), None
    G = x["G_psi"]
    if model == "witczak_1_40d":
        bracket = (
            c["b0"]
            + c["b_p200"] * p200
            + c["b_p200_2"] * p200**2
            + c["b_p4"] * p4
            + c["b_p4_2"] * p4**2
            + c["b_p38"] * p38
            + c["b_p38_2"] * p38**2
            + c["b_Va"] * Va
            + c["b_Vr"] * Vr
        )
        span = c["s0"] + c["s_Va"] * Va + c["s_Vr"] * Vr + c["s_p38"] * p38 + c["s_p38_2"] * p38**2 + c["s_p34"] * p34
        z = c["t0"] + c["t_G"] * np.log10(G) + c["t_delta"] * np.log10(x["delta_deg"])
        return np.log(10.0) * (c["a0"] + c["a1"] * G ** c["a2"] * bracket + span * expit(-z)), None
    VMA, VFA, Ea = mix.VMA, mix.VFA, c["Ea_psi"]
    contact = VFA * 3.0 * G / VMA
    pc = (c["pc_a"] + contact) ** c["pc_b"] / (c["pc_c"] + contact ** c["pc_b"])
    parallel = Ea * (1.0 - VMA / 100.0) + 3.0 * G * VFA * VMA / 10_000.0
    series = 1.0 / ((1.0 - VMA / 100.0) / Ea + VMA / (3.0 * VFA * G))
    return np.log(pc * parallel + (1.0 - pc) * series), pc


def _hirsch_phase(c: dict, pc: np.ndarray) -> np.ndarray:
    """Hirsch phase angle (degrees) from the contact volume Pc."""
    log_pc = np.log10(pc)
    return c["phi_2"] * log_pc**2 + c["phi_1"] * log_pc


def _check_hirsch_start(start: dict, free: list[str]) -> None:
    ok = start["Ea_psi"] > 0 and start["pc_a"] > 0 and 0 < start["pc_b"] < 1
    if not (ok and start["pc_c"] > start["pc_a"] ** start["pc_b"]):
        raise ValueError(
            f"coef0: Hirsch starting coefficients must have Ea_psi > 0, pc_a > 0, 0 < pc_b < 1 and "
            f"pc_c > pc_a^pc_b (Pc in (0, 1)), got {start}"
        )
    if ("pc_a" in free or "pc_b" in free) and "pc_c" not in free:
        raise ValueError("free: Hirsch's pc_a and pc_b are fitted only together with pc_c (keeps Pc < 1)")


def _training_rows(model: str, mix: Mix, raw: dict, E_MPa, phase_deg):
    """Rows of a fit: the mix, the model's inputs, |E*| and (Hirsch) phase, broadcast to 1-D,
    refusing a non-finite value the model reads with the row's index."""
    mix_names = ("Va", "Vbeff") if model == "hirsch" else tuple(f.name for f in fields(Mix))
    columns = {f"mix.{f.name}": getattr(mix, f.name) for f in fields(Mix)}
    columns.update({name: raw[name] for name in _USES[model]})
    columns["E_MPa"] = E_MPa
    if model == "hirsch" and phase_deg is not None:
        columns["phase_deg"] = phase_deg
    for name, value in columns.items():
        if value is None:
            raise ValueError(f"{name}: required by {model}, got None")
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in columns.values()))
    flat = {name: a.ravel() for name, a in zip(columns, arrays)}
    checked = [f"mix.{m}" for m in mix_names] + [k for k in flat if not k.startswith("mix.")]
    for name in checked:
        bad = np.flatnonzero(~np.isfinite(flat[name]))
        if bad.size:
            raise ValueError(f"row {bad[0]}: {name} is {flat[name][bad[0]]}; recalibrate needs finite inputs")
    if flat["E_MPa"].size == 0:
        raise ValueError("E_MPa: no training rows")
    rows = Mix(**{f.name: flat[f"mix.{f.name}"] for f in fields(Mix)})
    inputs = _inputs(model, *(flat.get(k) for k in ("frequency_Hz", "G_Pa", "delta_deg", "eta_Pa_s")))
    return rows, inputs, _positive("E_MPa", flat["E_MPa"]), flat.get("phase_deg")


def _coefficients_at(model: str, start: dict, names: list[str], u: np.ndarray) -> dict:
    """Coefficients after moves ``u`` of the free ``names`` from ``start``: relative steps
    c0 + |c0| u, except Hirsch's Ea_psi and pc_a (c0 e^u), pc_b (logistic) and pc_c (pc_a^pc_b
    plus the starting margin times e^u); :func:`_coefficients_batch` of one row, as floats."""
    batch = _coefficients_batch(model, start, names, np.asarray(u, dtype=float).reshape(1, -1))
    return {k: float(np.ravel(v)[0]) for k, v in batch.items()}


def _coefficients_batch(model: str, start: dict, names: list[str], U: np.ndarray) -> dict:
    """The coefficients after k rows of moves ``U`` (shape (k, len(names))) of the free ``names``
    from ``start`` (the steps of :func:`_coefficients_at`): each free coefficient a column of shape
    (k, 1), the others floats, so that the models' equations broadcast to (k, n) over n rows."""
    c: dict = dict(start)
    for j, name in enumerate(names):
        v = U[:, j : j + 1]
        if model == "hirsch" and name == "pc_c":
            continue  # set below, once pc_a and pc_b are
        if model == "hirsch" and name in ("Ea_psi", "pc_a"):
            c[name] = start[name] * np.exp(v)
        elif model == "hirsch" and name == "pc_b":
            c[name] = expit(logit(start[name]) + v)
        else:
            c[name] = start[name] + (abs(start[name]) or 1.0) * v
    if model == "hirsch" and "pc_c" in names:
        margin = start["pc_c"] - start["pc_a"] ** start["pc_b"]
        c["pc_c"] = c["pc_a"] ** c["pc_b"] + margin * np.exp(U[:, names.index("pc_c")][:, None])
    return c


def _forward_difference_jacobian(model: str, residuals, start: dict, names: list[str], ridge: float):
    """The Jacobian of :func:`_fit`'s residuals (data rows, then the ridge rows) by SciPy's
    "2-point" forward differences (the steps of ``scipy.optimize.approx_derivative``:
    sqrt(eps) max(1, |u|), sign of u), its len(names) + 1 evaluations done as one broadcast call of
    ``residuals`` on the coefficients of :func:`_coefficients_batch` instead of one call each."""
    m = len(names)
    rstep = np.finfo(float).eps ** 0.5

    def jac(u: np.ndarray) -> np.ndarray:
        h = rstep * ((u >= 0).astype(float) * 2 - 1) * np.maximum(1.0, np.abs(u))
        U = np.repeat(u[None, :], m + 1, axis=0)
        U[np.arange(1, m + 1), np.arange(m)] = u + h
        R = np.asarray(residuals(_coefficients_batch(model, start, names, U)))
        dx = (u + h) - u
        J = np.zeros((R.shape[1] + m, m))
        J[: R.shape[1]] = ((R[1:] - R[0]) / dx[:, None]).T
        J[R.shape[1] + np.arange(m), np.arange(m)] = (ridge * (u + h) - ridge * u) / dx
        return J

    return jac


def _fit(model: str, residuals, start: dict, names: list[str], n_rows: int) -> dict:
    """Least squares of ``residuals(coefficients)`` over the free ``names``, with the ridge;
    ``residuals`` broadcasts over coefficients given as columns (:func:`_coefficients_batch`)."""
    if not names:
        return dict(start)
    ridge = RIDGE * np.sqrt(n_rows)

    def fun(u):
        return np.concatenate([residuals(_coefficients_at(model, start, names, u)), ridge * u])

    jac = _forward_difference_jacobian(model, residuals, start, names, ridge)
    sol = least_squares(
        fun, np.zeros(len(names)), jac=jac, method="trf", x_scale="jac", ftol=1e-12, xtol=1e-12, gtol=1e-12
    )
    return _coefficients_at(model, start, names, sol.x)
