"""Synthetic measured complex-modulus tables with known truth and planted artifacts.

Truth (:func:`random_truth`): a 2S2P1D master curve with WLF shifts (Tref = 15 degC),
parameters drawn in ranges published for asphalt mixes (Olard & Di Benedetto 2003;
Mangiafico et al. 2015; Nguyen et al. 2009). Truth families (:func:`random_family`): ``wlf``
is the detector's own model; the others depart from it as real mixes do (glassy modulus
drifting with temperature, Arrhenius or quadratic shifts, temperature-dependent static
modulus, all at once; :data:`HARD_FAMILIES`: Huet-Sayegh, a random generalized Maxwell
spectrum, the MEPDG sigmoid). Schedules (:data:`SCHEDULES`): the paper's 2PB, AASHTO T 342
and AMPT PP 61, each with its declared test geometry, recorded in the truth as a sidecar
would give it.

:func:`generate` draws the specimens (log-normal |E*| factor, phase offset), the point noise
of ln|E*| and Phi, ``strain_microstrain`` and ``test_order`` (temperatures ascending; within
an isotherm the order of ``order``), and plants effects at random sizes:
``time_lag``, ``inertia_uncorrected``, ``temperature_offset``, ``strain_nonlinearity``,
``temperature_drift`` and ``self_heating`` (both along the test order: by default each
specimen's frequencies in a random order, ``order``); the truth
JSON uses the estimate keys of the diagnosis report. :func:`kk_reference` gives the
Kramers-Kronig statistic of clean isotherms, the reference of its percentile.

Every range and its source: docs/choices.md, Diagnosis: causes with measured error rates
(truth and planted sizes); the strain range: docs/choices.md, Diagnosis: strain nonlinearity.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..rheology.models import two_s2p1d_modulus
from ..rheology.shift import arrhenius_log_shift, wlf_log_shift

#: Test schedules (temperatures degC, frequencies Hz in test order).
SCHEDULES = {
    "paper_2pb": ([-10.0, 0.0, 10.0, 15.0, 20.0, 30.0], [40.0, 25.0, 10.0, 6.0, 3.0]),
    "aashto_t342": ([-10.0, 4.0, 21.0, 37.0, 54.0], [25.0, 10.0, 5.0, 1.0, 0.5, 0.1]),
    "ampt_pp61": ([4.0, 21.0, 37.0], [25.0, 10.0, 5.0, 1.0, 0.5, 0.1]),
}
#: Test of each schedule: the paper's 2PB trapezoid, or a uniaxial cylinder of 100 mm x
#: 150 mm (AASHTO T 342 / PP 61 specimen).
SCHEDULE_TESTS = {"paper_2pb": "2pb_trapezoid", "aashto_t342": "uniaxial_cylinder", "ampt_pp61": "uniaxial_cylinder"}
#: Truth families: the detector's own model (wlf) and mild departures from it (see
#: :func:`random_family`).
FAMILIES = (
    "wlf",
    "glassy_drift",
    "arrhenius",
    "static_drift",
    "poly_shift",
    "mixed",
    "huet_sayegh",
    "gmaxwell",
    "sigmoidal",
)
#: families whose truth is not a 2S2P1D master curve and which carry the measurement
#: structure of real tables (:func:`random_family`)
HARD_FAMILIES = ("huet_sayegh", "gmaxwell", "sigmoidal")
#: Names of the effects the generator can plant.
EFFECTS = (
    "time_lag",
    "inertia_uncorrected",
    "temperature_offset",
    "strain_nonlinearity",
    "self_heating",
    "temperature_drift",
)
T_REF_TRUTH_C = 15.0
#: largest planted change of E1 by the inertia term, relative to the true E1
INERTIA_MAX_FRACTION = 0.3


def schedule_test(schedule: str):
    """Declared test (:class:`asphalt_nscd.lab.geometry.DeclaredTest`) of a schedule."""
    from ..lab.geometry import AASHTO_CYLINDER, PAPER_2PB

    return PAPER_2PB if SCHEDULE_TESTS[schedule] == "2pb_trapezoid" else AASHTO_CYLINDER


def random_truth(rng: np.random.Generator) -> dict:
    """Draw 2S2P1D + WLF parameters (MPa, s, K) in the published ranges above."""
    return {
        "E0_MPa": float(rng.uniform(28e3, 45e3)),
        "E00_MPa": float(np.exp(rng.uniform(np.log(30.0), np.log(300.0)))),
        "delta": float(rng.uniform(1.5, 3.5)),
        "k": float(rng.uniform(0.15, 0.25)),
        "h": float(rng.uniform(0.5, 0.7)),
        "beta": float(np.exp(rng.uniform(np.log(100.0), np.log(3000.0)))),
        "tau_ref_s": float(np.exp(rng.uniform(np.log(0.01), np.log(0.5)))),
        "C1": float(rng.uniform(20.0, 35.0)),
        "C2_K": float(rng.uniform(130.0, 230.0)),
        "T_ref_C": T_REF_TRUTH_C,
    }


def random_family(name: str, rng: np.random.Generator) -> dict:
    """Departures of truth family ``name`` from 2S2P1D + WLF (keys merged into the truth).

    =============  ======================================================================
    wlf            none: the detector's own model
    glassy_drift   E0(T) = E0 exp(-g (T - Tref)), g 0.2-0.4 % per degC (``E0_drift_per_C``)
    arrhenius      log10 aT = Ea/(R ln 10) (1/T - 1/Tref), Ea 150-250 kJ/mol (``Ea_kJ_mol``;
                   replaces C1, C2)
    static_drift   E00(T) = E00 exp(-s (T - Tref)), s 0.5-1.5 % per degC (``E00_drift_per_C``)
    poly_shift     log10 aT = -a (T - Tref) + c (T - Tref)^2 (MEPDG-like quadratic), a 0.10-0.20
                   per degC, c 2e-4-1.2e-3 per degC^2 (``shift_slope_per_C``,
                   ``shift_curvature_per_C2``; replaces C1, C2)
    mixed          glassy_drift + static_drift + poly_shift at once
    huet_sayegh    the Huet-Sayegh model (2S2P1D without its linear dashpot: a solid at long
                   times), WLF shift
    gmaxwell       a generalized Maxwell series E00 + sum E_i i w r_i / (1 + i w r_i) with a
                   random positive spectrum: 30 relaxation times over 14 decades around
                   tau_ref, weights a broad log-normal envelope times exp of a smoothed
                   random walk (``spectrum``); quadratic shift (as poly_shift)
    sigmoidal      the MEPDG sigmoid (AASHTO R 84) log10|E*| = d + a / (1 + exp(b - g log10 w_r)),
                   d = log10 E00, a = log10(E0 / E00), b in [-1.5, 0.5], g in [0.4, 0.6];
                   phase by Booij & Thoone's first-order Kramers-Kronig relation
                   Phi = (pi / 2) d ln|E*| / d ln w; quadratic shift
    =============  ======================================================================

    The hard families (:data:`HARD_FAMILIES`) also carry the measurement structure of real
    tables: each specimen's |E*| factor drifts with temperature (a log slope per degC drawn
    with standard deviation ``specimen_T_slope_sigma``, 0.05-0.15 % per degC), and every
    (T, f) cell has an error shared by its specimens (the lack of fit of any smooth law to a
    real table; standard deviations ``cell_misfit_ratio`` = 0.5-2 times the point noise), so
    that their screening chi-square per degree of freedom spans that of real tables.

    Raises ValueError on an unknown family.
    """
    if name not in FAMILIES:
        raise ValueError(f"unknown truth family '{name}'; expected one of {', '.join(FAMILIES)}")
    out: dict[str, Any] = {"family": name}
    if name in HARD_FAMILIES:
        out["model"] = name
        out["specimen_T_slope_sigma"] = float(rng.uniform(0.0005, 0.0015))
        out["cell_misfit_ratio"] = float(rng.uniform(0.5, 2.0))
    if name in ("gmaxwell", "sigmoidal"):
        out["shift_slope_per_C"] = float(rng.uniform(0.10, 0.20))
        out["shift_curvature_per_C2"] = float(rng.uniform(2e-4, 1.2e-3))
    if name == "gmaxwell":
        lt = np.linspace(-8.0, 6.0, 30)  # log10(r_i / tau_ref)
        walk = np.convolve(rng.normal(0.0, 0.5, lt.size + 4), np.ones(5) / 5.0, mode="valid")
        w = np.exp(-0.5 * ((lt + 1.0) / 2.5) ** 2 + walk)
        out["spectrum"] = {"log10_time_over_tau_ref": lt.tolist(), "weights": (w / w.sum()).tolist()}
    if name == "sigmoidal":
        out["sigmoid_beta"] = float(rng.uniform(-1.5, 0.5))
        out["sigmoid_gamma"] = float(rng.uniform(0.4, 0.6))
    if name in ("glassy_drift", "mixed"):
        out["E0_drift_per_C"] = float(rng.uniform(0.002, 0.004))
    if name in ("static_drift", "mixed"):
        out["E00_drift_per_C"] = float(rng.uniform(0.005, 0.015))
    if name == "arrhenius":
        out["Ea_kJ_mol"] = float(rng.uniform(150.0, 250.0))
    if name in ("poly_shift", "mixed"):
        out["shift_slope_per_C"] = float(rng.uniform(0.10, 0.20))
        out["shift_curvature_per_C2"] = float(rng.uniform(2e-4, 1.2e-3))
    return out


def truth_log_shift(truth: dict, temperature_C) -> np.ndarray:
    """log10 aT of the truth's shift law (WLF, Arrhenius or quadratic; see :func:`random_family`)."""
    T = np.asarray(temperature_C, float)
    if "Ea_kJ_mol" in truth:
        return arrhenius_log_shift(T, truth["T_ref_C"], truth["Ea_kJ_mol"] * 1e3)
    if "shift_slope_per_C" in truth:
        d = T - truth["T_ref_C"]
        return -truth["shift_slope_per_C"] * d + truth["shift_curvature_per_C2"] * d**2
    return wlf_log_shift(T, truth["T_ref_C"], truth["C1"], truth["C2_K"])


def truth_modulus(truth: dict, frequency_Hz, temperature_C) -> np.ndarray:
    """Complex modulus (MPa) of the truth at arrays of frequency (Hz) and temperature (degC)."""
    T = np.asarray(temperature_C, float)
    f = np.asarray(frequency_Hz, float)
    tau = truth["tau_ref_s"] * 10.0 ** truth_log_shift(truth, T)
    dT = T - truth["T_ref_C"]
    E0 = truth["E0_MPa"] * np.exp(-truth.get("E0_drift_per_C", 0.0) * dT)
    E00 = truth["E00_MPa"] * np.exp(-truth.get("E00_drift_per_C", 0.0) * dT)
    model = truth.get("model", "2s2p1d")
    omega = 2 * np.pi * f
    if model == "gmaxwell":
        spec = truth["spectrum"]
        rho = np.asarray(tau)[..., None] * 10.0 ** np.asarray(spec["log10_time_over_tau_ref"])
        iwr = 1j * omega[..., None] * rho
        return E00 + (E0 - E00) * np.sum(np.asarray(spec["weights"]) * iwr / (1.0 + iwr), axis=-1)
    if model == "sigmoidal":
        d, a = np.log10(E00), np.log10(E0 / E00)
        b, g = truth["sigmoid_beta"], truth["sigmoid_gamma"]
        x = np.log10(omega * tau)
        e = np.exp(b - g * x)
        log_E = d + a / (1.0 + e)
        dlog = a * g * e / (1.0 + e) ** 2  # d log10|E*| / d log10 w = d ln|E*| / d ln w
        return 10.0**log_E * np.exp(1j * 0.5 * np.pi * dlog)
    beta = np.inf if model == "huet_sayegh" else truth["beta"]
    return two_s2p1d_modulus(omega, E00, E0, truth["delta"], truth["k"], truth["h"], beta, tau)


def random_effect(name: str, rng: np.random.Generator, temperatures, test: str = "2pb_trapezoid") -> dict:
    """Random magnitude of one planted effect (keys as in the diagnosis estimates);
    ``test``: the schedule's test (the uncorrected mass of a uniaxial machine is 2-20 kg)."""
    if name == "time_lag":
        return {"time_lag_ms": float(np.exp(rng.uniform(np.log(0.2), np.log(1.5))))}
    if name == "inertia_uncorrected":
        sign = 1.0 if rng.random() < 0.7 else -1.0
        lo, hi = (100.0, 400.0) if test == "2pb_trapezoid" else (2000.0, 20000.0)
        return {"mass_factor_g": float(sign * rng.uniform(lo, hi))}
    if name == "temperature_offset":  # an inner isotherm (the detector does not test the ends)
        inner = list(temperatures)[1:-1] or list(temperatures)
        return {
            "temperature_C": float(rng.choice(inner)),
            "offset_C": float(rng.choice([-1.0, 1.0]) * rng.uniform(3.0, 5.0)),
        }
    if name == "strain_nonlinearity":
        return {"modulus_drop_per_100_microstrain": float(rng.uniform(0.02, 0.06))}
    if name == "self_heating":
        return {
            "modulus_drop_pct_per_test": float(rng.uniform(0.5, 2.0)),
            "phase_rise_pct_per_test": float(rng.uniform(0.5, 2.0)),
        }
    if name == "temperature_drift":  # rate at the hottest isotherm, scaled down to 0 at the coldest
        return {"drift_C_per_test": float(rng.uniform(0.5, 1.5)), "temperature_C": float(max(temperatures))}
    raise ValueError(f"unknown effect '{name}'; expected one of {', '.join(EFFECTS)}")


def generate(
    seed: int,
    effects=(),
    schedule: str | None = None,
    n_specimens: int | None = None,
    magnitudes: dict | None = None,
    family: str = "wlf",
    frequencies_Hz=None,
    test_order: bool = True,
    order: str = "random",
    vertical_per_100K: float = 0.0,
) -> tuple[pd.DataFrame, dict]:
    """Generate a synthetic measured table and its truth.

    Parameters
    ----------
    seed : int
        Seed of the NumPy generator (everything is drawn from it; the family's departures
        from a child generator ``default_rng([seed, 1])``, so that a ``wlf`` table does not
        depend on the family code).
    effects : sequence of str
        Planted effects (names of :data:`EFFECTS`), zero, one or more.
    schedule : str, optional
        Key of :data:`SCHEDULES`; default drawn at random.
    n_specimens : int, optional
        Number of replicates (1-5); default drawn in 2-4.
    magnitudes : dict, optional
        ``{effect: {key: value}}`` overriding the random magnitudes.
    family : str
        Truth family (:data:`FAMILIES`, :func:`random_family`).
    frequencies_Hz : sequence of float, optional
        Frequencies in test order (default the schedule's), e.g. those of a measured table.
    test_order : bool
        Keep the ``test_order`` column (False: a table that gives no order, as many labs'
        do; an effect along the tests is then not testable).
    order : {"random", "standard", "repeat"}
        The order of an isotherm's tests: ``random`` (each specimen's frequencies in a random
        order, drawn from a child generator ``default_rng([seed, 4])``), ``standard`` (the
        schedule's, monotone in frequency) or ``repeat`` (the schedule's, then its first
        frequency again: a check many labs run). An effect along the tests (self-heating, a
        temperature drift) can be told from one along the frequency in the random and repeat
        orders only (docs/choices.md, Diagnosis: what a table can identify). The repeat's own
        draws come from ``default_rng([seed, 5])``; the other rows do not depend on the order.
    vertical_per_100K : float
        A vertical shift of the material (not an artifact): every |E*| times
        10^(v (T - T_ref) / 100 K), decades per 100 K (a thermorheologically complex mix; 0: none).

    Returns
    -------
    (DataFrame, dict)
        Table with the measured-table columns ``specimen, temperature_C, frequency_Hz,
        E_norm_MPa, phase_deg, strain_microstrain, test_order``; truth with ``seed,
        schedule, family, test`` (the declared test geometry, as a sidecar would give it),
        ``n_specimens, parameters, noise, effects``.

    Raises
    ------
    ValueError
        on an unknown effect, schedule or family, or n_specimens outside 1-5.
    """
    rng = np.random.default_rng(seed)
    effects = list(dict.fromkeys(effects))
    for e in effects:
        if e not in EFFECTS:
            raise ValueError(f"unknown effect '{e}'; expected one of {', '.join(EFFECTS)}")
    if schedule is None:
        schedule = str(rng.choice(sorted(SCHEDULES)))
    if schedule not in SCHEDULES:
        raise ValueError(f"unknown schedule '{schedule}'; expected one of {', '.join(SCHEDULES)}")
    temps, freqs = SCHEDULES[schedule]
    if frequencies_Hz is not None:
        freqs = [float(f) for f in frequencies_Hz]
    test = schedule_test(schedule)
    if n_specimens is None:
        n_specimens = int(rng.integers(2, 5))
    if not 1 <= n_specimens <= 5:
        raise ValueError(f"n_specimens must lie in 1-5, got {n_specimens}")
    truth = random_truth(rng)
    truth.update(random_family(family, np.random.default_rng([seed, 1])))
    if vertical_per_100K:
        truth["vertical_per_100K"] = float(vertical_per_100K)
    noise = {
        "specimen_lnE_sigma": float(rng.uniform(0.02, 0.05)),
        "specimen_phase_sigma_deg": 0.15,
        "point_lnE_sigma": float(rng.uniform(0.005, 0.02)),
        "point_phase_sigma_deg": float(rng.uniform(0.1, 0.4)),
    }
    planted = {e: random_effect(e, rng, temps, test.test) for e in effects}
    for e, values in (magnitudes or {}).items():
        if e in planted:
            planted[e].update(values)
    gamma = test.form_factor_per_mm
    if "inertia_uncorrected" in planted:
        TT, FF = np.meshgrid(temps, freqs)
        E = truth_modulus(truth, FF, TT)
        per_g = gamma * 1e-6 * (2 * np.pi * FF) ** 2  # E1 deficit per g of mass, MPa
        inertia = planted["inertia_uncorrected"]
        if "E_deficit_pct" in inertia:  # size given: the largest E1 deficit, % of |E*|
            inertia["mass_factor_g"] = float(
                np.sign(inertia.get("mass_factor_g", 1.0)) * inertia["E_deficit_pct"] / 100 * np.min(np.abs(E) / per_g)
            )
        # a lab would not report E1 changed by more than INERTIA_MAX_FRACTION (phase near 90 deg)
        dmu_max = INERTIA_MAX_FRACTION * np.min(E.real / per_g)
        if abs(inertia["mass_factor_g"]) > dmu_max:
            inertia["mass_factor_g"] = float(np.sign(inertia["mass_factor_g"]) * dmu_max)
        inertia["E_deficit_pct"] = float(100 * np.max(abs(inertia["mass_factor_g"]) * per_g / np.abs(E)))

    # measurement structure of the hard families, from a child generator (the other families'
    # tables do not depend on it): specimen factors drifting with T, errors shared by a cell
    hard = np.random.default_rng([seed, 3])
    slope = hard.normal(0.0, truth.get("specimen_T_slope_sigma", 0.0), n_specimens)
    ratio = truth.get("cell_misfit_ratio", 0.0)
    cell_err = {
        (T, f): (
            hard.normal(0.0, ratio * noise["point_lnE_sigma"]),
            hard.normal(0.0, ratio * noise["point_phase_sigma_deg"]),
        )
        for T in temps
        for f in freqs
    }
    if order not in ("random", "standard", "repeat"):
        raise ValueError(f"unknown order '{order}'; expected random, standard or repeat")
    repeat = order == "repeat"
    rng_order = np.random.default_rng([seed, 4])
    rng_repeat = np.random.default_rng([seed, 5])
    n_max = len(freqs) - (0 if repeat else 1)  # last test step of an isotherm

    def point(draw, s, c, p0, T, f, n):
        T_eff = T
        if "temperature_offset" in planted and T == planted["temperature_offset"]["temperature_C"]:
            T_eff += planted["temperature_offset"]["offset_C"]
        if "temperature_drift" in planted:
            rate = planted["temperature_drift"]["drift_C_per_test"] * (T - min(temps)) / (max(temps) - min(temps))
            T_eff += rate * (n - 0.5 * n_max)
        strain = draw.uniform(30.0, 150.0)
        ce, cp = cell_err[(T, f)]
        E = (
            complex(truth_modulus(truth, f, T_eff))
            * np.exp(c + slope[s] * (T - truth["T_ref_C"]) + ce + 1j * np.radians(p0 + cp))
            * 10.0 ** (vertical_per_100K * (T_eff - truth["T_ref_C"]) / 100.0)
        )
        if "self_heating" in planted:
            sh = planted["self_heating"]
            E = abs(E) * np.exp(
                -sh["modulus_drop_pct_per_test"] / 100 * n
                + 1j * np.angle(E) * (1 + sh["phase_rise_pct_per_test"] / 100 * n)
            )
        if "strain_nonlinearity" in planted:
            E *= np.exp(-planted["strain_nonlinearity"]["modulus_drop_per_100_microstrain"] * strain / 100.0)
        if "inertia_uncorrected" in planted:
            E -= gamma * 1e-6 * planted["inertia_uncorrected"]["mass_factor_g"] * (2 * np.pi * f) ** 2
        if "time_lag" in planted:
            E *= np.exp(1j * 2 * np.pi * f * planted["time_lag"]["time_lag_ms"] * 1e-3)
        lnE = np.log(abs(E)) + draw.normal(0.0, noise["point_lnE_sigma"])
        phase = np.degrees(np.angle(E)) + draw.normal(0.0, noise["point_phase_sigma_deg"])
        return {
            "specimen": f"S{s + 1}",
            "temperature_C": T,
            "frequency_Hz": f,
            "E_norm_MPa": float(np.exp(lnE)),
            "phase_deg": float(np.clip(phase, 0.01, 89.9)),
            "strain_microstrain": round(float(strain), 2),
        }

    rows = []
    for s in range(n_specimens):
        c = rng.normal(0.0, noise["specimen_lnE_sigma"])
        p0 = rng.normal(0.0, noise["specimen_phase_sigma_deg"])
        done = 0
        for T in temps:
            steps = rng_order.permutation(len(freqs)) if order == "random" else np.arange(len(freqs))
            for i, f in enumerate(freqs):
                rows.append({**point(rng, s, c, p0, T, f, int(steps[i])), "test_order": done + int(steps[i]) + 1})
            done += len(freqs)
            if repeat:
                done += 1
                rows.append({**point(rng_repeat, s, c, p0, T, freqs[0], len(freqs)), "test_order": done})
    table = (
        pd.DataFrame(rows)
        .sort_values(["temperature_C", "frequency_Hz", "specimen", "test_order"])
        .reset_index(drop=True)
    )
    if not test_order:
        table = table.drop(columns="test_order")
    info = {
        "seed": int(seed),
        "schedule": schedule,
        "family": family,
        "test": test.to_json(),
        "test_order": bool(test_order),
        "order": order,
        "n_specimens": n_specimens,
        "parameters": truth,
        "noise": noise,
        "effects": planted,
    }
    return table, info


def kk_reference(
    frequencies_Hz, n_specimens: int, n_tables: int = 200, seed: int = 20261122, families=FAMILIES
) -> np.ndarray:
    """Kramers-Kronig statistic (mean |Phi - Phi_Booij-Thoone| per isotherm, deg,
    :func:`asphalt_nscd.rheology.kramers_kronig.isotherm_residuals`) of causal synthetic
    isotherms: ``n_tables`` clean tables (families taken in turn; every truth is a causal
    linear viscoelastic law, the sigmoid through Booij-Thoone itself) on the AASHTO T 342
    temperatures at ``frequencies_Hz`` with ``n_specimens`` replicates and the generator's
    noise. Returns the statistics of every isotherm, shape (n_tables x 5,), the reference a
    measured isotherm's value is placed in (a percentile, not a verdict)."""
    from ..rheology.kramers_kronig import isotherm_residuals

    freqs = sorted((float(f) for f in frequencies_Hz), reverse=True)
    out = []
    for i in range(int(n_tables)):
        fam = families[i % len(families)]
        t, _ = generate(
            int(np.random.SeedSequence([seed, i]).generate_state(1)[0]),
            schedule="aashto_t342",
            n_specimens=int(min(max(n_specimens, 1), 5)),
            family=fam,
            frequencies_Hz=freqs,
            test_order=False,
        )
        out.extend(isotherm_residuals(t).to_numpy(float))
    return np.asarray(out)
