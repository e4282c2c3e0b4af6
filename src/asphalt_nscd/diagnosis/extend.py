"""Extended bond law: a generalized Burger's law per temperature from the master curve.

The 2S2P1D master curve (fitted with WLF shifts to the artifact-corrected data) is the
calibration target. Its static modulus E00 becomes the parallel spring E_inf, its glassy
modulus E0 - E00 the Maxwell spring Em; the rest of the chain compliance 1/(E* - E00) is
turned by the non-negative least-squares Prony fit of
:func:`asphalt_nscd.rheology.models.fit_generalized_kelvin` into the Maxwell dashpot
eta_m in series with Kelvin-Voigt units on a log-spaced grid
of retardation times (``per_decade`` per decade over the tested band of that isotherm
widened by ``margin_decades`` on both sides). Units whose weight is zero are dropped.

Optional refinement (``refine=True``, default): the compliances of that Prony law are then
adjusted by least squares to the replicate means of the isotherm itself (ln|E*| and Phi in
relative terms), with a penalty that keeps them near the master-curve solution. This lets
the law follow an isotherm that the single master curve misses by a few percent (real data
are not exactly thermorheologically simple) without losing the physical, causal form.

The result is what the NSCD core and the harmonic solver take as their macro law
(:class:`asphalt_nscd.rheology.laws.GeneralizedBurgers`, Pa and Pa s), written by
:func:`laws_to_json` keyed by temperature.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..rheology.laws import GeneralizedBurgers
from ..rheology.master_curve import MasterCurveFit
from ..rheology.models import fit_generalized_kelvin, log_time_grid

#: phases below this (deg) are weighted as if they were this large in the refinement
PHASE_FLOOR_DEG = 1.0


def prony_from_master(master: MasterCurveFit, temperature_C: float, f_min: float, f_max: float,
                      per_decade: float = 1.0, margin_decades: float = 1.0) -> GeneralizedBurgers:
    """Generalized Burger's law (MPa, MPa s) fitted to the master curve at one temperature.

    Parameters
    ----------
    master : MasterCurveFit
        2S2P1D master curve (E00 >= 0 becomes E_inf).
    temperature_C : float
        Temperature, degC.
    f_min, f_max : float
        Tested frequency band at that temperature, Hz.
    per_decade, margin_decades : float
        Density of the retardation-time grid and widening of the band (decades).

    Returns
    -------
    GeneralizedBurgers in MPa and MPa s.
    """
    w_lo = 2 * np.pi * f_min / 10**margin_decades
    w_hi = 2 * np.pi * f_max * 10**margin_decades
    omega = np.logspace(np.log10(w_lo), np.log10(w_hi), 60)
    E = master.modulus(omega / (2 * np.pi), temperature_C)
    c = master.core()
    scale = np.exp(master.specimen_mean[0])
    tau = log_time_grid(w_lo, w_hi, per_decade=per_decade, margin_decades=0.5)
    return fit_generalized_kelvin(omega, E, tau, E_inf=float(c["E00_MPa"] * scale), dashpot=True,
                                  glassy_modulus=float((c["E0_MPa"] - c["E00_MPa"]) * scale))


def _with_compliances(law: GeneralizedBurgers, logJ: np.ndarray, tau: np.ndarray) -> GeneralizedBurgers:
    """``law`` with its dashpot fluidity and Kelvin-Voigt compliances set to exp(logJ) (Em kept)."""
    J = np.exp(logJ)
    return GeneralizedBurgers(Em=law.Em, eta_m=1.0 / J[0], Ek=tuple(1.0 / J[1:]),
                              eta_k=tuple(tau / J[1:]), E_inf=law.E_inf)


def refine_to_isotherm(law: GeneralizedBurgers, frequency_Hz, E_norm_MPa, phase_deg,
                       prior_weight: float = 0.01, tolerances=(0.03, 0.05)) -> GeneralizedBurgers:
    """Adjust the compliances of ``law`` (retardation times, Em and E_inf fixed) to one isotherm.

    The glassy modulus Em stays that of the master curve: it is not resolved by one isotherm
    and it sets the stiffest spring of the bond law, hence the NSCD time step.

    Residuals: ln|E*| model/data and (Phi model - Phi data) / max(Phi data, 1 deg), each
    divided by its tolerance (default 3 % and 5 %, the issue's targets), and
    ``prior_weight`` x the change of every ln compliance from ``law``. The refined law is
    returned only if it lowers this objective. An infinite dashpot is first given a long time
    (100 x the longest retardation time) so it can be adjusted.

    Parameters
    ----------
    law : GeneralizedBurgers (MPa, MPa s);  frequency_Hz, E_norm_MPa, phase_deg : arrays (m,).

    Returns
    -------
    GeneralizedBurgers (MPa, MPa s).
    """
    from scipy.optimize import least_squares

    f = np.asarray(frequency_Hz, float)
    lnE = np.log(np.asarray(E_norm_MPa, float))
    ph = np.asarray(phase_deg, float)
    tau = np.array([c / e for c, e in zip(law.eta_k, law.Ek)])
    eta_m = law.eta_m if np.isfinite(law.eta_m) else 100 * law.Em * (tau.max() if tau.size else 1.0)
    law = GeneralizedBurgers(Em=law.Em, eta_m=eta_m, Ek=law.Ek, eta_k=law.eta_k, E_inf=law.E_inf)
    x0 = np.log(np.concatenate([[1 / eta_m], 1 / np.asarray(law.Ek)]))
    omega = 2 * np.pi * f

    ph_scale = np.maximum(ph, PHASE_FLOOR_DEG)

    def resid(x):
        m = _with_compliances(law, x, tau)
        E = m.complex_modulus(omega)
        return np.concatenate([(np.log(np.abs(E)) - lnE) / tolerances[0],
                               (np.degrees(np.angle(E)) - ph) / ph_scale / tolerances[1],
                               prior_weight * (x - x0)])

    res = least_squares(resid, x0, method="trf", x_scale=1.0)
    if np.sum(res.fun**2) > np.sum(resid(x0) ** 2):  # never worse than the master-curve law
        return law
    return _with_compliances(law, res.x, tau)


def calibrate(master: MasterCurveFit, corrected: pd.DataFrame, per_decade: float = 2.0,
              margin_decades: float = 1.0, refine: bool = True, prior_weight: float = 0.01) -> dict:
    """Generalized Burger's law per tested temperature (MPa, MPa s): ``{T: law}``."""
    from .causes import cell_means

    cm = cell_means(corrected)
    laws = {}
    for T, g in cm.groupby("temperature_C"):
        law = prony_from_master(master, float(T), g["frequency_Hz"].min(), g["frequency_Hz"].max(),
                                per_decade, margin_decades)
        if refine:
            law = refine_to_isotherm(law, g["frequency_Hz"], g["E_norm_MPa"], g["phase_deg"], prior_weight)
        laws[float(T)] = prune(law)
    return laws


def prune(law: GeneralizedBurgers, ratio: float = 1e3) -> GeneralizedBurgers:
    """Drop Kelvin-Voigt units stiffer than ``ratio`` x Em: their compliance is below
    1/ratio of the glassy one, negligible, and each unit costs an internal variable per bond."""
    keep = [i for i, ek in enumerate(law.Ek) if ek <= ratio * law.Em]
    if len(keep) == law.n_kelvin or not keep:
        return law
    return GeneralizedBurgers(Em=law.Em, eta_m=law.eta_m, Ek=tuple(law.Ek[i] for i in keep),
                              eta_k=tuple(law.eta_k[i] for i in keep), E_inf=law.E_inf)


def mre_of_laws(laws: dict, table: pd.DataFrame) -> tuple[dict, dict]:
    """MRE (%) of |E*| and Phi of per-temperature laws (MPa) against the cell means of a table."""
    from .causes import cell_means

    cm = cell_means(table)
    mE, mP = {}, {}
    for T, g in cm.groupby("temperature_C"):
        if float(T) not in laws:
            continue
        E = laws[float(T)].complex_modulus(2 * np.pi * g["frequency_Hz"].to_numpy(float))
        mE[float(T)] = float(100 * np.mean(np.abs(np.abs(E) / g["E_norm_MPa"] - 1)))
        mP[float(T)] = float(100 * np.mean(np.abs(np.degrees(np.angle(E)) / g["phase_deg"] - 1)))
    return mE, mP


def laws_to_json(laws: dict, mre_E: dict | None = None, mre_phase: dict | None = None) -> dict:
    """JSON object keyed by temperature (``"%g"``) with the laws in Pa and Pa s.

    Fields per temperature: ``Em, eta_m, Ek (list), eta_k (list), E_inf`` (Pa, Pa s;
    ``eta_m`` null means no Maxwell dashpot) and, if given, ``mre_E_norm_pct, mre_phase_pct``.
    """
    out = {"units": {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"},
           "law": "GeneralizedBurgers: Maxwell (Em, eta_m) in series with Kelvin-Voigt units "
                  "(Ek[i], eta_k[i]), in parallel with E_inf",
           "temperatures": {}}
    for T, law in sorted(laws.items()):
        d = law.scaled(1e6).as_dict()
        if not np.isfinite(d["eta_m"]):
            d["eta_m"] = None
        if mre_E is not None:
            d["mre_E_norm_pct"] = mre_E.get(T)
            d["mre_phase_pct"] = mre_phase.get(T)
        out["temperatures"][f"{T:g}"] = d
    return out


def laws_from_json(obj: dict) -> dict:
    """Inverse of :func:`laws_to_json`: ``{T (float): GeneralizedBurgers in Pa, Pa s}``."""
    out = {}
    for key, d in obj["temperatures"].items():
        out[float(key)] = GeneralizedBurgers(Em=d["Em"], eta_m=np.inf if d["eta_m"] is None else d["eta_m"],
                                             Ek=tuple(d["Ek"]), eta_k=tuple(d["eta_k"]), E_inf=d["E_inf"])
    return out
