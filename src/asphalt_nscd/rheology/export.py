"""Material cards of a temperature-aware law: a relaxation Prony series with a shift law.

What a finite-element user needs of the extended law (:mod:`.extended`, the law JSON of
``asphalt-nscd extend-law``) is a linear viscoelastic material that Abaqus, LS-DYNA or ANSYS
read: the relaxation modulus at a reference temperature as a Prony series

    E(t) = E_inf + sum_i E_i exp(-t / tau_i) = E_0 [g_inf + sum_i g_i exp(-t / tau_i)],
    E*(w) = E_inf + sum_i E_i i w tau_i / (1 + i w tau_i),

with g_i = E_i / E_0, and a WLF shift, log10 aT = -C1 (T - T_ref) / (C2 + T - T_ref) (Abaqus
``*TRS, DEFINITION=WLF``; LS-DYNA ``*MAT_GENERAL_VISCOELASTIC`` TREF, A, B).

Construction (:func:`prony_card`):

* reference temperature: the law's T_ref (``model.T_ref_C`` of the law JSON);
* shift: the law's WLF constants; an Arrhenius law is replaced by the WLF law fitted to it
  over the calibrated range (least squares in log10 aT, the largest difference reported);
* Prony series: the fewest relaxation (generalized Maxwell) terms that stay within a stated
  tolerance of the law at T_ref (default 1 % in |E*| and 0.2 deg in Phi, the largest
  difference) over the reduced band of the calibrated cells (every tested (T, f) shifted to
  T_ref) widened by ``margin_decades`` (1 decade) at each end, and of the law at every
  calibrated cell through the card's shift (:func:`fewest_terms`): for
  N = 1, 2, ... free relaxation times (weights by NNLS for each set: variable projection)
  towards the largest difference (L8), then times and weights together (L8 to L32) until the
  tolerance is met; the error-versus-N curve is kept.

What a single Prony series with a shift law cannot carry: a vertical shift, a static modulus
that changes with temperature, the per-isotherm refinement of the law (its settings in the
law JSON). ``extend-law --card-law`` therefore writes the law a card carries: the selected
law when it has none of these, else the best candidate without them, fitted as such. The
card is compared with the law it carries at every calibrated cell and the largest
differences of |E*| (%) and Phi (deg) are written beside it (``check`` of the JSON); above
 the same stated tolerance (:data:`CARD_TOLERANCE` by default) the card is flagged ``exact:
false`` and ``asphalt-nscd export-law`` refuses to write it. What the card loses against the
selected law, and its own errors against the measured replicate means, per cell and per
temperature (:func:`card_errors`, :func:`loss_by_temperature`), are written in the card's
header, in its JSON and on the console.

Writers: :func:`abaqus_card`, :func:`lsdyna_card` (units N, mm, s, tonne: moduli in MPa),
:func:`card_json`, :func:`card_table`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ..io import InputError
from .laws import POISSON_RATIO


def _chain(obj: dict):
    """GeneralizedBurgers (Pa, Pa s) of the law JSON's ``model.prony_at_T_ref``."""
    from .laws import GeneralizedBurgers

    eta_m = obj.get("eta_m")
    return GeneralizedBurgers(
        Em=float(obj["Em"]),
        eta_m=math.inf if eta_m is None else float(eta_m),
        Ek=tuple(obj.get("Ek", ())),
        eta_k=tuple(obj.get("eta_k", ())),
        E_inf=float(obj.get("E_inf", 0.0)),
    )


def wlf_log_shift(T, T_ref: float, C1: float, C2: float) -> np.ndarray:
    """log10 aT of a WLF law (degC, K)."""
    d = np.asarray(T, float) - T_ref
    return -C1 * d / (C2 + d)


#: where the cards' default Poisson's ratio (:data:`asphalt_nscd.rheology.laws.POISSON_RATIO`) comes from
POISSON_SOURCE = "the paper's value for the mix (Quezada & Chazallon 2020, Eqs. 8-11: 'set to 0.35')"
#: largest |interconversion residual| of E(t) and D(t) accepted by the card's own check
INTERCONVERSION_TOLERANCE = 0.005

#: default tolerance of the card against its law, |E*| %, Phi deg: the largest difference over the
#: widened reduced band at T_ref (selection of the terms) and at every calibrated cell (``exact``)
CARD_TOLERANCE = (1.0, 0.2)
#: most Prony terms tried
MAX_TERMS = 40


def _nnls_weights(omega, E, tau):
    """(E_inf, E_i) >= 0 of a relaxation series with times ``tau`` fitted to E* (relative
    residuals), and the fitted E* (arrays of shape (m,))."""
    from scipy.optimize import nnls

    A = np.column_stack([np.ones_like(omega, complex)] + [1j * omega * t / (1 + 1j * omega * t) for t in tau])
    A = A / np.abs(E)[:, None]
    A2 = np.vstack([A.real, A.imag])
    norms = np.linalg.norm(A2, axis=0)
    b = np.concatenate([(E / np.abs(E)).real, (E / np.abs(E)).imag])
    x, _ = nnls(A2 / norms, b, maxiter=100 * A2.shape[1])
    x = x / norms
    return x, A @ x * np.abs(E)


def fewest_terms(omega, E, tolerance=CARD_TOLERANCE, max_terms: int = MAX_TERMS) -> dict:
    """The fewest relaxation terms within ``tolerance`` (|E*| %, Phi deg; the largest
    differences) of E* (complex, shape (m,)) at ``omega`` (rad/s, shape (m,)) (module
    docstring).

    Returns ``E_inf``, ``E_i`` (n,), ``tau_s`` (n,), ``max_E_pct``, ``max_phase_deg``, ``n``,
    ``met`` (bool) and ``curve`` (one {n, max_E_pct, max_phase_deg} per N tried)."""
    from scipy.optimize import least_squares

    lo, hi = -math.log10(omega.max()), -math.log10(omega.min())
    bounds = (lo - 1.0, hi + 1.0)
    tol_E, tol_P = tolerance

    def errors(u):
        x, Ef = _nnls_weights(omega, E, 10.0**u)
        r = np.log(Ef / E)
        return x, r

    def l2(u):
        _, r = errors(u)
        return np.concatenate([r.real, r.imag])

    def l8(u):  # towards the largest difference, in units of the tolerances
        _, r = errors(u)
        a = np.concatenate([r.real / (tol_E / 100.0), r.imag / math.radians(tol_P)])
        return np.sign(a) * np.abs(a) ** 4

    def scaled_max(r):  # the largest difference in units of the tolerances
        return max(100.0 * float(np.abs(r.real).max()) / tol_E, math.degrees(float(np.abs(r.imag).max())) / tol_P)

    curve: list[dict] = []
    best: dict[str, Any] | None = None
    for n in range(1, int(max_terms) + 1):
        u = np.linspace(lo, hi, n) if n > 1 else np.array([0.5 * (lo + hi)])
        u = least_squares(l2, u, bounds=bounds).x
        u = least_squares(l8, u, bounds=bounds).x
        x, r = errors(u)
        if 1.0 < scaled_max(r) <= JOINT_REFINEMENT_BELOW:
            x, u, r = _joint_minimax(omega, E, x, u, r, tolerance, bounds, scaled_max)
        eE, eP = 100.0 * float(np.abs(r.real).max()), math.degrees(float(np.abs(r.imag).max()))
        curve.append({"n": n, "max_E_pct": eE, "max_phase_deg": eP})
        keep = x[1:] > 0
        best = {
            "E_inf": float(x[0]),
            "E_i": x[1:][keep],
            "tau_s": 10.0 ** u[keep],
            "max_E_pct": eE,
            "max_phase_deg": eP,
            "n": int(keep.sum()),
            "met": eE <= tol_E and eP <= tol_P,
        }
        if best["met"]:
            break
    assert best is not None  # at least one number of terms is tried
    best["curve"] = curve
    return best


#: the variable-projection fit of N terms within this factor of the tolerance gets the joint
#: minimax refinement (:func:`_joint_minimax`) before one more term is tried
JOINT_REFINEMENT_BELOW = 2.0


def _joint_minimax(omega, E, x, u, r, tolerance, bounds, scaled_max):
    """Refine N terms towards the smallest largest difference in units of ``tolerance`` with the
    weights free too (positive through their logarithm; :func:`fewest_terms` fits them by NNLS
    for given times, which balances the |E*| and Phi differences in the least-squares sense, not
    against their tolerances): least squares of the residuals to the powers 8, 16, 32 (towards
    the L-infinity norm). Returns (weights (E_inf, E_i), log10 tau, log residuals), the input
    when the refinement does not lower the largest scaled difference."""
    from scipy.optimize import least_squares

    from .models import generalized_maxwell_modulus

    n = len(u)
    tol_E, tol_P = tolerance
    w0 = np.maximum(x, 1e-12 * max(float(x.max()), 1e-300))

    def model(v):
        w = np.exp(v[n:])
        return generalized_maxwell_modulus(omega, w[0], w[1:], 10.0 ** v[:n])

    def lp(v, p):
        rr = np.log(model(v) / E)
        a = np.concatenate([rr.real / (tol_E / 100.0), rr.imag / math.radians(tol_P)])
        return np.sign(a) * np.abs(a) ** (p / 2)

    lower = np.concatenate([np.full(n, bounds[0]), np.full(n + 1, -np.inf)])
    upper = np.concatenate([np.full(n, bounds[1]), np.full(n + 1, np.inf)])
    v = np.concatenate([u, np.log(w0)])
    for p in (8, 16, 32):
        v = least_squares(lp, v, bounds=(lower, upper), max_nfev=200 * (2 * n + 1), args=(p,)).x
    r_new = np.log(model(v) / E)
    if scaled_max(r_new) >= scaled_max(r):
        return x, u, r
    return np.exp(v[n:]), v[:n], r_new


def prony_card(
    law: dict, cells: pd.DataFrame, tolerance=CARD_TOLERANCE, margin_decades: float = 1.0, nu: float = POISSON_RATIO
) -> dict:
    """The material card of a law JSON object (module docstring).

    Parameters
    ----------
    law : the law JSON (:mod:`asphalt_nscd.rheology.law_file` format, with ``model``), with an
        entry at T_ref and at every temperature of ``cells``.
    cells : the calibrated (T degC, f Hz) cells (columns ``temperature_C, frequency_Hz``).
    tolerance : (|E*| %, Phi deg) the card must stay within over the widened band
        (:func:`fewest_terms`).
    margin_decades : decades added on each side of the reduced band.
    nu : Poisson's ratio of the card (constant; bulk and shear relax alike).

    Returns
    -------
    dict: ``T_ref_C``, ``E_0_MPa``, ``E_inf_MPa``, ``g_inf``, ``terms`` (list of {g, tau_s,
    E_MPa}), ``shift`` ({law: WLF, C1, C2_K, T_ref_C, from, max_log10_aT_difference}),
    ``nu``, ``check`` (largest |E*| difference %, Phi difference deg, at which cell, the
    settings that a Prony + shift card cannot carry), ``exact`` (bool).

    Raises
    ------
    InputError if the law has no ``model`` or no entry at its T_ref.
    """
    from . import law_file
    from .metrics import temperature_key

    model = law.get("model") if isinstance(law, dict) else None
    if not model or "T_ref_C" not in model or "shift" not in model:
        raise InputError("law JSON: key 'model' with T_ref_C and shift needed (written by asphalt-nscd extend-law)")
    entries = {T: g.scaled(1e-6) for T, g in law_file.validate(law, "law JSON").items()}
    T_ref = float(model["T_ref_C"])
    if temperature_key(entries, T_ref) is None:
        raise InputError(
            f"law JSON: key 'temperatures': no entry at T_ref = {T_ref:g} degC (write the law there: "
            "extend-law --temperatures)"
        )
    shift = model["shift"]
    T = cells["temperature_C"].to_numpy(float)
    f = cells["frequency_Hz"].to_numpy(float)
    C1, C2, from_law, diff = card_wlf(shift, T_ref, float(T.min()), float(T.max()))
    wr = 2 * np.pi * f * 10.0 ** wlf_log_shift(T, T_ref, C1, C2)
    w_lo, w_hi = wr.min() / 10**margin_decades, wr.max() * 10**margin_decades
    omega = np.logspace(math.log10(w_lo), math.log10(w_hi), int(20 * math.log10(w_hi / w_lo)) + 1)
    # the law's whole chain at T_ref (the per-temperature entries merge the units far outside
    # their own tested band; the card must cover every calibrated cell's reduced frequency)
    chain = model.get("prony_at_T_ref")
    law_ref = (_chain(chain) if chain else entries[temperature_key(entries, T_ref)].scaled(1e6)).scaled(1e-6)
    E_ref = law_ref.complex_modulus(omega)
    # the calibrated cells too, at their reduced frequencies under the card's WLF shift against the law at
    # their own temperature: the card is selected within the tolerance where it is checked (``exact``)
    E_cells = law_file.complex_modulus(entries, T, f, "law JSON")
    fit = fewest_terms(np.concatenate([omega, wr]), np.concatenate([E_ref, E_cells]), tolerance)
    E_i, tau = fit["E_i"], fit["tau_s"]
    order = np.argsort(tau)
    E_i, tau = E_i[order], tau[order]
    E_inf = float(fit["E_inf"])
    E_0 = E_inf + float(E_i.sum())
    card = {
        "T_ref_C": T_ref,
        "E_0_MPa": E_0,
        "E_inf_MPa": E_inf,
        "g_inf": E_inf / E_0,
        "terms": [{"g": float(e / E_0), "tau_s": float(t), "E_MPa": float(e)} for e, t in zip(E_i, tau)],
        "shift": {
            "law": "WLF",
            "C1": C1,
            "C2_K": C2,
            "T_ref_C": T_ref,
            "from": from_law,
            "max_log10_aT_difference": diff,
        },
        "nu": float(nu),
        "units": {"modulus": "MPa", "time": "s", "temperature": "degC"},
        "terms_selection": {
            "n_terms": len(E_i),
            "tolerance": {"E_norm_pct": tolerance[0], "phase_deg": tolerance[1]},
            "band_rad_s": [float(w_lo), float(w_hi)],
            "margin_decades": margin_decades,
            "max_E_norm_difference_pct": fit["max_E_pct"],
            "max_phase_difference_deg": fit["max_phase_deg"],
            "met": bool(fit["met"]),
            "curve": fit["curve"],
            "method": "fewest free relaxation times (variable projection, L2 then L8)",
        },
    }
    card["check"], card["exact"] = _card_check(card, entries, model.get("settings") or {}, T, f, tolerance)
    return card


def card_wlf(shift: dict, T_ref: float, lo: float, hi: float) -> tuple[float, float, str, float]:
    """The card's WLF shift (:func:`prony_card`): (C1, C2 in K, its origin, largest |log10 aT|
    difference to the law's shift). A WLF law is taken as it is; an Arrhenius one is replaced by
    the WLF law nearest it on [lo, hi] degC (least squares on 41 temperatures)."""
    if str(shift["law"]).upper() == "WLF":
        return float(shift["C1"]), float(shift["C2_K"]), "WLF of the law", 0.0
    from scipy.optimize import least_squares

    from .shift import arrhenius_log_shift

    grid = np.linspace(lo, hi, 41)
    target = arrhenius_log_shift(grid, T_ref, float(shift["Ea_kJ_mol"]) * 1e3)
    res = least_squares(
        lambda p: wlf_log_shift(grid, T_ref, p[0], p[1]) - target,
        [20.0, 150.0],
        bounds=([0.1, T_ref - lo + 1.0], [500.0, 1e5]),
    )
    C1, C2 = (float(v) for v in res.x)
    return C1, C2, "WLF fitted to the law's Arrhenius shift over the calibrated range", float(np.abs(res.fun).max())


def _card_check(
    card: dict, entries: dict, settings: dict, T: np.ndarray, f: np.ndarray, tolerance=CARD_TOLERANCE
) -> tuple[dict, bool]:
    """The card against the law at every calibrated cell (T degC, f Hz; arrays of shape (n,)):
    (the ``check`` block of :func:`prony_card`, whether it is within ``tolerance``, |E*| % and
    Phi deg)."""
    from . import law_file

    E_card = card_modulus(card, f, T)
    E_law = law_file.complex_modulus(entries, T, f, "law JSON")
    dE = 100 * np.abs(np.abs(E_card) / np.abs(E_law) - 1)
    dP = np.abs(np.degrees(np.angle(E_card) - np.angle(E_law)))
    lost = [
        name
        for name, on in (
            ("vertical shift", settings.get("vertical")),
            ("static modulus trend", settings.get("static") == "trend"),
            ("per-isotherm refinement", settings.get("refine") is not None),
        )
        if on
    ]
    iE, iP = int(np.argmax(dE)), int(np.argmax(dP))
    check = {
        "max_E_norm_difference_pct": float(dE[iE]),
        "at_E": [float(T[iE]), float(f[iE])],
        "max_phase_difference_deg": float(dP[iP]),
        "at_phase": [float(T[iP]), float(f[iP])],
        "n_cells": int(T.size),
        "not_carried": lost,
        "tolerances": {"E_norm_pct": float(tolerance[0]), "phase_deg": float(tolerance[1])},
    }
    return check, bool(dE[iE] <= tolerance[0] and dP[iP] <= tolerance[1])


def card_errors(
    card: dict, summary: pd.DataFrame, selected_law: dict, corrected: pd.DataFrame | None = None
) -> pd.DataFrame:
    """Per measured cell: the card's, the selected law's and the measured replicate means'
    |E*| (MPa) and Phi (deg), and the errors (|E*| as 100 ln(a / b), %, Phi in deg) of the card
    and of the law against the measured means and of the card against the law. ``summary``:
    ``temperature_C, frequency_Hz, E_norm_MPa_mean, phase_deg_mean``; ``selected_law``: its law
    JSON, with an entry at every measured temperature; ``corrected``: the artifact-corrected
    cell means the laws were fitted on (``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``),
    when a correction was made: their values and the card's errors against them too
    (``*_corrected``, ``card_vs_corrected_*``, ``corrected_vs_measured_*``).

    Raises InputError if the law lacks a measured temperature or ``corrected`` a measured cell."""
    from . import law_file

    T = summary["temperature_C"].to_numpy(float)
    f = summary["frequency_Hz"].to_numpy(float)
    entries = {t: g.scaled(1e-6) for t, g in law_file.validate(selected_law, "selected law JSON").items()}
    E_law = law_file.complex_modulus(entries, T, f, "selected law JSON")
    E_card = card_modulus(card, f, T)
    E_m = summary["E_norm_MPa_mean"].to_numpy(float)
    P_m = summary["phase_deg_mean"].to_numpy(float)
    out = pd.DataFrame(
        {
            "temperature_C": T,
            "frequency_Hz": f,
            "E_norm_MPa_measured": E_m,
            "phase_deg_measured": P_m,
            "E_norm_MPa_card": np.abs(E_card),
            "phase_deg_card": np.degrees(np.angle(E_card)),
            "E_norm_MPa_law": np.abs(E_law),
            "phase_deg_law": np.degrees(np.angle(E_law)),
        }
    )
    pairs = [("card", "measured"), ("law", "measured"), ("card", "law")]
    if corrected is not None:
        from .metrics import same_frequency, same_temperature

        Ec, Pc = np.empty(T.size), np.empty(T.size)
        cT, cf = corrected["temperature_C"].to_numpy(float), corrected["frequency_Hz"].to_numpy(float)
        for i in range(T.size):
            hit = np.flatnonzero(same_temperature(cT, T[i]) & same_frequency(cf, f[i]))
            if hit.size != 1:
                raise InputError(f"corrected table: {hit.size} cells at {T[i]:g} degC, {f[i]:g} Hz (expected 1)")
            Ec[i], Pc[i] = corrected["E_norm_MPa"].iloc[hit[0]], corrected["phase_deg"].iloc[hit[0]]
        out["E_norm_MPa_corrected"], out["phase_deg_corrected"] = Ec, Pc
        pairs += [("card", "corrected"), ("corrected", "measured")]
    for a, b in pairs:
        out[f"{a}_vs_{b}_logE_pct"] = 100 * np.log(out[f"E_norm_MPa_{a}"] / out[f"E_norm_MPa_{b}"])
        out[f"{a}_vs_{b}_phase_deg"] = out[f"phase_deg_{a}"] - out[f"phase_deg_{b}"]
    return out


def loss_by_temperature(errors: pd.DataFrame) -> list[dict]:
    """Per temperature (and ``all``): mean and max of the absolute errors of
    :func:`card_errors` (|E*| %, Phi deg) of the card and of the law against the measured means,
    of the card against the law and, with a corrected table, of the card against it and of the
    correction itself (corrected vs measured)."""
    out = []
    groups = [(float(T), g) for T, g in errors.groupby("temperature_C")] + [("all", errors)]
    pairs = [
        p
        for p in ("card_vs_measured", "law_vs_measured", "card_vs_law", "card_vs_corrected", "corrected_vs_measured")
        if f"{p}_logE_pct" in errors
    ]
    for T, g in groups:
        row = {"temperature_C": T, "n_cells": int(len(g))}
        for pair in pairs:
            for q in ("logE_pct", "phase_deg"):
                a = g[f"{pair}_{q}"].abs()
                row[f"{pair}_{q}_mean"] = float(a.mean())
                row[f"{pair}_{q}_max"] = float(a.max())
        out.append(row)
    return out


def source_lines(card: dict) -> list[str]:
    """The measured table the card's law was fitted to (path and SHA-256), for the card's header."""
    src = card.get("source") or {}
    if not src.get("measured_sha256"):
        return []
    return [f"fitted to the measured table {src.get('measured', '?')} (sha256 {src['measured_sha256']})"]


def loss_lines(card: dict, units=None) -> list[str]:
    """What the card loses, one line per temperature (the card's header and the console);
    ``units``: :class:`asphalt_nscd.lab.table_format.DisplayUnits` of the temperatures (default:
    the card's ``display`` units, else degC)."""
    from ..lab.table_format import DisplayUnits

    if card.get("loss") is None:
        return []
    if units is None:
        units = DisplayUnits(**card["display"]) if card.get("display") else DisplayUnits()
    lines = [
        carried_text(card) + "; |E*| (mean / max |ln ratio|, %) and Phi (mean / max |difference|, deg) per "
        "temperature, in-sample:"
    ]
    for r in card["loss"]:
        T = "all" if r["temperature_C"] == "all" else units.temperature_text(r["temperature_C"])
        lines.append(
            f"{T}: card vs measured {r['card_vs_measured_logE_pct_mean']:.2f} / "
            f"{r['card_vs_measured_logE_pct_max']:.2f} %, {r['card_vs_measured_phase_deg_mean']:.2f} / "
            f"{r['card_vs_measured_phase_deg_max']:.2f} deg; selected law vs measured "
            f"{r['law_vs_measured_logE_pct_mean']:.2f} / {r['law_vs_measured_logE_pct_max']:.2f} %, "
            f"{r['law_vs_measured_phase_deg_mean']:.2f} / {r['law_vs_measured_phase_deg_max']:.2f} deg; "
            f"card vs selected law {r['card_vs_law_logE_pct_mean']:.2f} / {r['card_vs_law_logE_pct_max']:.2f} %, "
            f"{r['card_vs_law_phase_deg_mean']:.2f} / {r['card_vs_law_phase_deg_max']:.2f} deg"
            + (
                f"; card vs corrected {r['card_vs_corrected_logE_pct_mean']:.2f} / "
                f"{r['card_vs_corrected_logE_pct_max']:.2f} %, {r['card_vs_corrected_phase_deg_mean']:.2f} / "
                f"{r['card_vs_corrected_phase_deg_max']:.2f} deg"
                if "card_vs_corrected_logE_pct_mean" in r
                else ""
            )
        )
    return lines + correction_lines(card, units)


def worse_than_selected(card: dict) -> list[str]:
    """The overall figures (mean and largest |E*| and Phi error against the lab's replicate
    means) in which the card is worse than the selected law by more than the card's tolerance,
    as text (empty: the card is as good as the selected law, or better, in all four)."""
    rows = [r for r in card.get("loss") or [] if r["temperature_C"] == "all"]
    if not rows:
        return []
    r, tol = rows[0], card.get("terms_selection", {}).get("tolerance", {})
    out = []
    for q, unit, t in (
        ("logE_pct", "%", tol.get("E_norm_pct", CARD_TOLERANCE[0])),
        ("phase_deg", "deg", tol.get("phase_deg", CARD_TOLERANCE[1])),
    ):
        for stat in ("mean", "max"):
            c, law = r[f"card_vs_measured_{q}_{stat}"], r[f"law_vs_measured_{q}_{stat}"]
            if c > law + t:
                name = "|E*|" if q == "logE_pct" else "Phi"
                out.append(f"{stat} {name} error {c:.2f} {unit} vs {law:.2f} {unit}")
    return out


def carried_text(card: dict) -> str:
    """One sentence: the law the card carries, how it was fitted, and whether it is the selected
    law (and why not)."""
    fits = {"least_squares": "by least squares at every measured cell", "robust": "by the robust (soft L1) fit"}
    how = fits.get(card.get("fit") or "", "")
    if card["is_selected_law"]:
        return f"the card carries the selected law '{card['carries']}'" + (f", fitted {how}" if how else "")
    text = f"the card carries the law '{card['carries']}'" + (f", fitted {how}" if how else "")
    if card.get("selected_carriable") is False:
        return (
            text
            + f", not the selected '{card['selected_law']}', which a Prony series with a shift function cannot carry"
        )
    return (
        text
        + f", not the selected '{card['selected_law']}'"
        + (f" (fitted {fits[card['selected_fit']]})" if card.get("selected_fit") in fits else "")
        + ": the card's law is refitted in the card's own shift and loss (diagnosis.material_card)"
    )


def correction_lines(card: dict, units=None) -> list[str]:
    """What the data correction the laws were fitted on changes, per temperature (the corrected
    replicate means against the measured ones; empty without a correction)."""
    from ..lab.table_format import DisplayUnits

    rows = [r for r in card.get("loss") or [] if "corrected_vs_measured_logE_pct_mean" in r]
    if (
        not rows
        or max(max(r["corrected_vs_measured_logE_pct_max"], r["corrected_vs_measured_phase_deg_max"]) for r in rows)
        == 0
    ):
        return []
    if units is None:
        units = DisplayUnits(**card["display"]) if card.get("display") else DisplayUnits()
    named = ", ".join(card.get("corrections") or []) or "the artifacts the diagnosis named"
    lines = [
        f"the laws were fitted to the table corrected for {named} (named by the diagnosis as identifiable from "
        "the table); the correction changes the replicate means (mean / max |change|, |E*| %, Phi deg):"
    ]
    for r in rows:
        T = "all" if r["temperature_C"] == "all" else units.temperature_text(r["temperature_C"])
        lines.append(
            f"{T}: {r['corrected_vs_measured_logE_pct_mean']:.2f} / {r['corrected_vs_measured_logE_pct_max']:.2f} %, "
            f"{r['corrected_vs_measured_phase_deg_mean']:.2f} / {r['corrected_vs_measured_phase_deg_max']:.2f} deg"
        )
    return lines


def creep_terms(card: dict) -> dict:
    """The creep compliance of a card, D(t) = D_inf - sum_j d_j exp(-t / lambda_j) (1/MPa,
    s), interconverted exactly from its relaxation series (Park & Schapery 1999, Int. J. Solids
    Struct. 36: the Laplace transforms satisfy s E(s) s D(s) = 1). sE(s) = E_inf + sum E_i s
    tau_i / (1 + s tau_i) has one real root between consecutive poles -1/tau_i; each root r_j
    gives lambda_j = -1/r_j and d_j = -1 / (r_j sE'(r_j)); D_inf = 1 / E_inf.

    Returns ``D_inf`` (1/MPa; inf for E_inf = 0), ``d`` (n,), ``lambda_s`` (n,), ``D_0``.

    Raises ValueError without a long-term modulus (a liquid card creeps without bound)."""
    from scipy.optimize import brentq

    E_inf = float(card["E_inf_MPa"])
    if not E_inf > 0:
        raise ValueError("the card has no long-term modulus (E_inf = 0): its creep has no finite limit")
    E = np.array([t["E_MPa"] for t in card["terms"]], float)
    tau = np.array([t["tau_s"] for t in card["terms"]], float)
    order = np.argsort(tau)[::-1]  # poles -1/tau from the closest to 0
    E, tau = E[order], tau[order]

    def sE(x):  # x = -s > 0: sE(-x)
        return E_inf + float(np.sum(E * (-x * tau) / (1.0 - x * tau)))

    def dsE(x):  # d sE / ds at s = -x
        return float(np.sum(E * tau / (1.0 - x * tau) ** 2))

    poles = 1.0 / tau  # x at the poles, increasing
    edges = np.concatenate([[0.0], poles])
    roots = []
    for a, b in zip(edges[:-1], edges[1:]):
        lo, hi = a + 1e-12 * (b - a) + (1e-300 if a == 0 else 0.0), b - 1e-12 * (b - a)
        roots.append(brentq(sE, lo, hi, xtol=1e-14 * b, rtol=1e-13, maxiter=500))
    r = -np.array(roots)  # s roots (negative)
    d = np.array([-1.0 / (rj * dsE(-rj)) for rj in r])
    D_inf = 1.0 / E_inf
    return {"D_inf": D_inf, "d": d, "lambda_s": -1.0 / r, "D_0": float(D_inf - d.sum())}


def relaxation_and_creep(card: dict, temperatures, times_s) -> pd.DataFrame:
    """E(t) and D(t) of a card at T_ref and at each of ``temperatures`` (degC) at the times
    ``times_s`` (s): columns ``temperature_C, time_s, E_MPa, G_MPa`` (shear relaxation E / (2
    (1 + nu)), nu of the card), ``D_per_MPa`` (creep compliance) and ``check`` (the
    interconversion identity int_0^t E(t - u) dD(u) = 1, evaluated in closed form, minus 1).
    At temperature T the times scale with aT of the card's shift: E_T(t) = E_ref(t / aT)."""
    ct = creep_terms(card)
    E = np.array([t["E_MPa"] for t in card["terms"]], float)
    tau = np.array([t["tau_s"] for t in card["terms"]], float)
    s = card["shift"]
    rows = []
    temps = [float(card["T_ref_C"])] + [float(T) for T in temperatures if abs(float(T) - card["T_ref_C"]) > 1e-9]
    for T in temps:
        aT = 10.0 ** wlf_log_shift(T, s["T_ref_C"], s["C1"], s["C2_K"])
        t = np.asarray(times_s, float) / aT  # reduced time
        Et = card["E_inf_MPa"] + np.exp(-t[:, None] / tau) @ E
        Dt = ct["D_inf"] - np.exp(-t[:, None] / ct["lambda_s"]) @ ct["d"]
        # int_0^t E(t-u) D'(u) du + E(t) D(0), D'(u) = sum d_j / l_j exp(-u / l_j), in closed form
        lam, d = ct["lambda_s"], ct["d"]
        conv = card["E_inf_MPa"] * (ct["D_inf"] - ct["D_0"] - np.exp(-t[:, None] / lam) @ d)
        for Ei, ti in zip(E, tau):
            k = 1.0 / lam - 1.0 / ti  # e^{-(t-u)/ti} e^{-u/lam}: int = e^{-t/ti} (1 - e^{-k t}) / k
            with np.errstate(over="ignore", invalid="ignore"):
                term = np.where(
                    np.abs(k)[None, :] * np.maximum(t[:, None], 1e-300) < 1e-8,
                    t[:, None],
                    (np.exp(-t[:, None] / ti) - np.exp(-t[:, None] / lam)) / k,
                )
            conv = conv + Ei * (term @ (d / lam))
        check = conv + Et * ct["D_0"] - 1.0
        for i in range(t.size):
            rows.append(
                {
                    "temperature_C": T,
                    "time_s": float(times_s[i]),
                    "E_MPa": float(Et[i]),
                    "G_MPa": float(Et[i] / (2.0 * (1.0 + card["nu"]))),
                    "D_per_MPa": float(Dt[i]),
                    "check": float(check[i]),
                }
            )
    return pd.DataFrame(rows)


def interconversion_summary(functions: pd.DataFrame) -> dict:
    """The interconversion check of :func:`relaxation_and_creep`'s table: the largest
    |int_0^t E(t - u) dD(u) - 1| over every temperature and time, against
    :data:`INTERCONVERSION_TOLERANCE` (``met``), with the method's source."""
    worst = float(np.abs(functions["check"].to_numpy(float)).max())
    return {
        "max_abs_residual": worst,
        "tolerance": INTERCONVERSION_TOLERANCE,
        "met": bool(worst <= INTERCONVERSION_TOLERANCE),
        "method": "exact interconversion of the Prony series (Park & Schapery 1999, Int. J. Solids Struct. 36: "
        "1653-1675); residual of the convolution identity int_0^t E(t-u) dD(u) = 1",
    }


def header_lines(card: dict) -> list[str]:
    """The card's own statements (the comment block of every card file): the selected number of
    terms with its tolerance and band, the law carried and how it was fitted, the Poisson's ratio
    and its source, the E(t)/D(t) interconversion check, the measured table, and the errors
    against the lab's means per temperature (:func:`loss_lines`)."""
    sel = card.get("terms_selection", {})
    tol = sel.get("tolerance", {})
    band = sel.get("band_rad_s", [float("nan"), float("nan")])
    lines = [
        f"{len(card['terms'])} Prony terms: the fewest within {tol.get('E_norm_pct', '?')} % |E*| and "
        f"{tol.get('phase_deg', '?')} deg of the law it carries over the reduced band {band[0]:.3g}-{band[1]:.3g} "
        f"rad/s at T_ref (the measured band widened by {sel.get('margin_decades', '?')} decade at each end) and at "
        f"the measured cells; achieved {sel.get('max_E_norm_difference_pct', float('nan')):.3g} % / "
        f"{sel.get('max_phase_difference_deg', float('nan')):.3g} deg",
        f"E(t) = E_0 (g_inf + sum g_i exp(-t/tau_i)) at T_ref = {card['T_ref_C']:g} degC; units MPa, s, degC; "
        f"g_inf = {card['g_inf']:.6g}",
        f"largest difference to the law it carries over {card['check']['n_cells']} measured cells: "
        f"{card['check']['max_E_norm_difference_pct']:.3g} % |E*|, {card['check']['max_phase_difference_deg']:.3g} "
        "deg phase",
    ]
    if card.get("nu_source"):
        lines.append(f"Poisson's ratio {card['nu']:g}: {card['nu_source']}; shear and bulk relax alike")
    ic = card.get("interconversion")
    if ic:
        lines.append(
            f"creep compliance D(t) interconverted exactly from E(t): largest residual "
            f"{100 * ic['max_abs_residual']:.2g} % (check {'met' if ic['met'] else 'MISSED'} at "
            f"{100 * ic['tolerance']:g} %)"
        )
    return lines + source_lines(card) + loss_lines(card)


def card_modulus(card: dict, frequency_Hz, temperature_C) -> np.ndarray:
    """E* (MPa) of a card at (f Hz, T degC) pairs: the Prony series at the shifted frequency."""
    f, T = np.broadcast_arrays(np.asarray(frequency_Hz, float), np.asarray(temperature_C, float))
    s = card["shift"]
    wr = 2 * np.pi * f * 10.0 ** wlf_log_shift(T, s["T_ref_C"], s["C1"], s["C2_K"])
    E = np.full(wr.shape, card["E_inf_MPa"], complex)
    for term in card["terms"]:
        iwt = 1j * wr * term["tau_s"]
        E = E + term["E_MPa"] * iwt / (1.0 + iwt)
    return E


def abaqus_card(card: dict, name: str = "ASPHALT_MIX") -> str:
    """Abaqus input-file fragment: ``*ELASTIC, MODULI=INSTANTANEOUS`` (E_0 in MPa, nu),
    ``*VISCOELASTIC, TIME=PRONY`` (g_i, k_i = g_i, tau_i: shear and bulk relax alike) and
    ``*TRS, DEFINITION=WLF`` (T_ref, C1, C2). Units MPa and s; temperatures in degC."""
    s = card["shift"]
    lines = [
        "** Linear viscoelastic material card written by asphalt-nscd export-law",
        *(f"** {line}" for line in header_lines(card)),
        f"*MATERIAL, NAME={name}",
        "*ELASTIC, MODULI=INSTANTANEOUS",
        f"{card['E_0_MPa']:.9g}, {card['nu']:.6g}",
        "*VISCOELASTIC, TIME=PRONY",
    ]
    lines += [f"{t['g']:.9g}, {t['g']:.9g}, {t['tau_s']:.9g}" for t in card["terms"]]
    lines += ["*TRS, DEFINITION=WLF", f"{s['T_ref_C']:.6g}, {s['C1']:.9g}, {s['C2_K']:.9g}"]
    return "\n".join(lines) + "\n"


def lsdyna_card(card: dict, mid: int = 1, density_t_mm3: float = 2.4e-9) -> str:
    """LS-DYNA ``*MAT_GENERAL_VISCOELASTIC`` (MAT_076) card in the consistent units N, mm, s,
    tonne (moduli in MPa): shear and bulk relaxation G_i = E_i / (2 (1 + nu)), K_i = E_i /
    (3 (1 - 2 nu)), decay BETA_i = 1/tau_i, the long-term moduli as terms of decay 0; WLF
    TREF, A = C1, B = C2. ``density_t_mm3``: the mix's density (2.4e-9 t/mm^3 = 2400 kg/m^3)."""
    nu = card["nu"]
    g, k = 1.0 / (2 * (1 + nu)), 1.0 / (3 * (1 - 2 * nu))
    s = card["shift"]
    terms = [(card["E_inf_MPa"], 0.0)] + [(t["E_MPa"], 1.0 / t["tau_s"]) for t in card["terms"]]
    bulk = card["E_0_MPa"] * k
    lines = [
        "$ Linear viscoelastic material card written by asphalt-nscd export-law (units N, mm, s, tonne; MPa); "
        "WLF shift (TREF, A = C1, B = C2)",
        *(f"$ {line}" for line in header_lines(card)),
        "*MAT_GENERAL_VISCOELASTIC",
        "$      MID        RO      BULK       PCF        EF      TREF         A         B",
        "".join(
            f"{v:>10}"
            for v in (
                mid,
                f"{density_t_mm3:.3e}",
                f"{bulk:.3e}",
                0,
                0,
                f"{s['T_ref_C']:.4g}",
                f"{s['C1']:.5g}",
                f"{s['C2_K']:.5g}",
            )
        ),
        "$    LCID1       NT     BSTART     TRAMP     LCIDK      NTK    BSTARTK    TRAMPK",
        "".join(f"{v:>10}" for v in (0, 0, 0, 0, 0, 0, 0, 0)),
        "$       GI     BETAI        KI    BETAKI",
    ]
    lines += ["".join(f"{v:>10.3e}" for v in (e * g, b, e * k, b)) for e, b in terms]
    return "\n".join(lines) + "\n"


def card_json(card: dict) -> dict:
    """The neutral JSON of a card (the card itself, JSON-ready)."""
    return {"format": "relaxation Prony series at T_ref with a WLF shift", **card}


def card_table(card: dict) -> pd.DataFrame:
    """The Prony terms as a table: ``i, g, tau_s, E_MPa`` (i = 0: the long-term term, tau inf)."""
    rows = [{"i": 0, "g": card["g_inf"], "tau_s": math.inf, "E_MPa": card["E_inf_MPa"]}]
    rows += [{"i": k + 1, **t} for k, t in enumerate(card["terms"])]
    return pd.DataFrame(rows)
