"""Data artifacts: detection by nested master-curve fits (forward selection with F-tests).

The reference model of a measured table is a 2S2P1D master curve with WLF shifts, a |E*|
factor and a phase offset per specimen (:mod:`asphalt_nscd.rheology.master_curve`). Each
candidate artifact adds a term with its own physical parameter:

======================  =================================================  ==================
name                    measured = f(true)                                 parameter
======================  =================================================  ==================
time_lag                E* exp(i 2 pi f dt): Phi + 360 f dt, |E*| same      ``time_lag_ms``
inertia_uncorrected     E1 - gamma 1e-6 dmu w^2 (2PB Eq. 1, paper geometry) ``mass_factor_g``
temperature_offset      isotherm T measured at T + dT (one isotherm)        ``offset_C``
strain_nonlinearity     |E*| exp(-b (eps - eps_ref) / 100 microstrain)      ``modulus_drop_per_100_microstrain``
self_heating            n-th test of an isotherm (n = 0, 1, ...) at T + c n, ``heating_C_per_test``,
                        then |E*| exp(-a n), Phi (1 + b n)                  ``extra_drop_pct_per_test``,
                                                                            ``extra_phase_pct_per_test``
======================  =================================================  ==================

Strain nonlinearity is measured from the mean strain eps_ref of the table: the term then
does not change the overall |E*| level, which the master curve carries (E0 and E00), so the
screening fits with E00 held fixed do not bias it; the corrected table is brought to the
small-strain limit eps -> 0 (the linear viscoelastic modulus). The ln|E*| noise is taken
from the replicate scatter with the strain effect regressed out
(:func:`~asphalt_nscd.rheology.master_curve.replicate_noise` with the strain covariate):
otherwise a real strain effect, which differs between the replicates of a cell, inflates
the noise level and deflates its own F statistic.

Forward selection: starting from the reference model, every candidate not yet selected is
added in turn and tested by the extra-sum-of-squares F-test (residuals weighted by the
replicate noise). While the current model fits to within noise, these screening fits hold
the weakly identified 2S2P1D parameters E00 and beta at the current fit
(``SHAPE_PARAMETERS``); when it does not (reduced chi-square > ``INADEQUATE_CHI2``) they are
free. The candidate with the smallest p-value enters if p < alpha (the temperature offset
is tried on every isotherm, its p-value Bonferroni-corrected by the number of isotherms;
strain nonlinearity can only lower |E*| and is tested one-sided),
has the physical sign (strain nonlinearity and self-heating lower |E*|)
and a practical size (``PRACTICAL_MINIMUM``); it is then refitted with every parameter free.
The loop stops when no candidate enters. In the selected model every detected effect gets a
drop-one F-test, a Jacobian standard error and its share of the misfit ("score": mean
change of Phi (%) plus of |E*| (%) it causes). A measured point is corrected by the
complex ratio of the fitted model without and with the artifacts.

Choice: alpha defaults to 1e-3 (config ``diagnosis.alpha``); a lower alpha trades detection
of small effects against false alarms from model misfit of real data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from ..rheology.kramers_kronig import kk_time_lag
from ..rheology.master_curve import MasterCurveFit, MasterCurveProblem, Term, data_arrays, replicate_noise

#: 2S2P1D parameters held at the current fit while candidates are screened: the weakly
#: identified pair (E00, beta) otherwise lets a new term switch the fit to another branch
#: of their ridge, which inflates the F statistic of null effects.
SHAPE_PARAMETERS = ("log10_E00_MPa", "log10_beta")
#: Reduced chi-square above which the current model is taken as inadequate: candidates are
#: then screened with every parameter free.
INADEQUATE_CHI2 = 2.0
#: Practical size below which a significant artifact is not named: time lag, largest phase
#: shift (deg); inertia, largest change of E1 relative to |E*| (%); temperature offset,
#: degC (the temperature tolerance of the test standards is of this order); strain
#: nonlinearity, change of |E*| over the tested strain range (%); self-heating, drop of
#: |E*| over an isotherm (%). Nonlinear least squares with nearly unidentifiable parameters
#: make the F-test somewhat anti-conservative; these floors keep statistically significant
#: but physically negligible terms from being named.
PRACTICAL_MINIMUM = {"time_lag": 0.2, "inertia_uncorrected": 0.5, "temperature_offset": 0.5,
                     "strain_nonlinearity": 0.5, "self_heating": 1.0}

ARTIFACTS = ("time_lag", "inertia_uncorrected", "temperature_offset", "strain_nonlinearity",
             "self_heating")


def gamma_per_mm() -> float:
    """Form factor gamma (1/mm) of the paper's 2PB specimen (EN 12697-26, paper Eq. 3)."""
    from ..lab.en12697 import Specimen2PB

    return float(Specimen2PB().gamma_per_mm)


def prepare_table(df: pd.DataFrame) -> pd.DataFrame:
    """Add ``test_step``: 0-based rank of ``test_order`` within (specimen, temperature)."""
    out = df.reset_index(drop=True).copy()
    out["specimen"] = out["specimen"].astype(str)
    if "test_order" in out.columns:
        out["test_step"] = (out.groupby(["specimen", "temperature_C"])["test_order"]
                            .rank(method="dense").to_numpy(float) - 1.0)
    return out


def testability(df: pd.DataFrame) -> dict:
    """For each artifact: (testable, reason)."""
    n_T = df["temperature_C"].nunique()
    n_f = df["frequency_Hz"].nunique()
    out = {}
    ok = n_T >= 2 and n_f >= 3
    out["time_lag"] = (ok, "" if ok else "needs >= 2 temperatures and >= 3 frequencies")
    out["inertia_uncorrected"] = out["time_lag"]
    ok = n_T >= 4 and n_f >= 2
    out["temperature_offset"] = (ok, "" if ok else
                                 "needs >= 4 isotherms (the WLF law has 3 shift parameters)")
    if "strain_microstrain" not in df.columns:
        out["strain_nonlinearity"] = (False, "the table has no strain_microstrain column")
    else:
        ls = np.log(df["strain_microstrain"].to_numpy(float))
        within = ls - df.groupby("specimen")["strain_microstrain"].transform(lambda s: np.log(s).mean()).to_numpy()
        ok = float(np.std(within)) > 0.05
        out["strain_nonlinearity"] = (ok, "" if ok else "strain amplitude does not vary within specimens")
    if "test_step" not in df.columns:
        out["self_heating"] = (False, "the table has no test_order column")
    else:
        ok = float(df["test_step"].max()) >= 2
        out["self_heating"] = (ok, "" if ok else "fewer than 3 tests per isotherm and specimen")
    return out


def make_term(name: str, temperature_C: float | None = None, strain_ref_microstrain: float = 0.0) -> Term:
    """Measurement-model term of one artifact (see the module table).

    ``temperature_C``: isotherm of a temperature offset; ``strain_ref_microstrain``: the
    strain at which the strain-nonlinearity term is 1 (default 0: the small-strain limit).

    Terms act in the order of the measurement chain: temperature (offset, self-heating),
    strain nonlinearity, inertia (on E1 of the specimen), then the time lag (on the phase
    read between the channels).
    """
    if name == "time_lag":
        return Term(name, ["time_lag_ms"], [0.0], [-5.0], [5.0],
                    apply=lambda x, E, d: E * np.exp(1j * 2 * np.pi * d["f"] * x[0] * 1e-3), order=3)
    if name == "inertia_uncorrected":
        g = gamma_per_mm()
        return Term(name, ["mass_factor_g"], [0.0], [-5000.0], [5000.0],
                    apply=lambda x, E, d: E - g * 1e-6 * x[0] * (2 * np.pi * d["f"]) ** 2, order=2)
    if name == "temperature_offset":
        T_k = float(temperature_C)
        return Term(name, ["offset_C"], [0.0], [-15.0], [15.0],
                    delta_T=lambda x, d: x[0] * (d["T"] == T_k))
    if name == "strain_nonlinearity":
        return Term(name, ["modulus_drop_per_100_microstrain"], [0.0], [-0.5], [0.5],
                    apply=lambda x, E, d: E * np.exp(-x[0] * (d["strain_microstrain"] - strain_ref_microstrain)
                                                     / 100.0), order=1)
    if name == "self_heating":
        def heat(x, E, d):
            n = d["test_step"]
            return np.abs(E) * np.exp(-x[1] / 100 * n + 1j * np.angle(E) * (1 + x[2] / 100 * n))
        return Term(name, ["heating_C_per_test", "extra_drop_pct_per_test", "extra_phase_pct_per_test"],
                    [0.0, 0.0, 0.0], [-5.0, -30.0, -30.0], [5.0, 30.0, 30.0],
                    delta_T=lambda x, d: x[0] * d["test_step"], apply=heat, order=0)
    raise ValueError(f"unknown artifact '{name}'")


@dataclass
class Candidate:
    name: str
    term: Term
    temperature_C: float | None = None


def f_test(rss0: float, rss1: float, q: int, dof1: int) -> tuple[float, float]:
    """Extra-sum-of-squares F statistic and p-value of a nested model with q more parameters."""
    if dof1 <= 0 or rss1 <= 0:
        return np.nan, np.nan
    F = max(rss0 - rss1, 0.0) / q / (rss1 / dof1)
    return float(F), float(stats.f.sf(F, q, dof1))


def one_sided(name: str, estimate: float, p: float) -> float:
    """One-sided p-value for strain nonlinearity (it can only lower |E*|); two-sided otherwise."""
    if name != "strain_nonlinearity" or not np.isfinite(p):
        return p
    return p / 2 if estimate > 0 else 1 - p / 2


class ArtifactSearch:
    """Forward selection of artifacts on a tidy measured table (see the module docstring)."""

    def __init__(self, df: pd.DataFrame, alpha: float = 1e-3, T_ref_C=None, shift: str = "wlf"):
        self.df = prepare_table(df)
        self.alpha = float(alpha)
        self.data = data_arrays(self.df)
        self.testable = testability(self.df)
        strain = ("strain_microstrain",) if self.testable["strain_nonlinearity"][0] else ()
        #: reference strain of the strain-nonlinearity term (mean of the table), microstrain
        self.strain_ref = float(np.mean(self.data["strain_microstrain"])) if strain else 0.0
        sE, sP = replicate_noise(self.df, covariates=strain)
        self.noise_from_replicates = sE is not None
        self.sigma = (max(sE, 2e-3), max(sP, 0.03)) if sE is not None else (0.02, 0.5)
        self.shift = shift
        self.T_ref_C = T_ref_C

    def problem(self, terms) -> MasterCurveProblem:
        return MasterCurveProblem(self.data, shift=self.shift, T_ref_C=self.T_ref_C, terms=terms,
                                  sigma_lnE=self.sigma[0], sigma_phase_deg=self.sigma[1])

    def fit(self, terms, x0=None, fixed=()) -> MasterCurveFit:
        return self.problem(terms).fit(x0=x0, fixed=fixed)

    def candidates(self) -> list:
        out = []
        for name in ARTIFACTS:
            if not self.testable[name][0]:
                continue
            if name == "temperature_offset":
                out += [Candidate(name, make_term(name, T), float(T)) for T in self.data["temperatures"]]
            elif name == "strain_nonlinearity":
                out.append(Candidate(name, make_term(name, strain_ref_microstrain=self.strain_ref)))
            else:
                out.append(Candidate(name, make_term(name)))
        return out

    def _try(self, base: MasterCurveFit, terms, cand: Candidate):
        """Fit base + cand, warm-started (and from +-3 degC for a temperature offset).

        Re-anchoring: the reduced model is refitted from the extended solution with the new
        parameter removed; if that lowers its residual the reduced fit was a local minimum,
        and the better one is returned as ``base`` and used in the F-test.
        """
        k = len(cand.term.names)
        starts = [cand.term.x0] if cand.name != "temperature_offset" else [[0.0], [-3.0], [3.0]]
        p_full = base.x.size + k
        inadequate = base.rss / max(base.n_residuals - p_full, 1) > INADEQUATE_CHI2
        fixed = () if inadequate else SHAPE_PARAMETERS
        best = None
        for s in starts:
            x0 = np.concatenate([base.x, s])
            fit = self.fit(terms + [cand.term], x0=x0, fixed=fixed)
            if best is None or fit.rss < best.rss:
                best = fit
        again = self.fit(terms, x0=best.x[:-k], fixed=fixed)
        if again.rss < base.rss:
            base = again
        F, p = f_test(base.rss, best.rss, k, best.n_residuals - p_full)
        p = one_sided(cand.name, best.x[-1], p)
        if cand.name == "temperature_offset":
            p = min(1.0, p * len(self.data["temperatures"]))
        return best, F, p, base

    def _sign_ok(self, name: str, values, fit: MasterCurveFit) -> bool:
        """Physical sign and practical size of an estimate (see PRACTICAL_MINIMUM)."""
        d = self.data
        value = float(values[0])
        if name == "self_heating":
            value = self.heating_effect(fit, values)[0]
        if name in ("strain_nonlinearity", "self_heating") and value <= 0:
            return False
        if name == "time_lag":
            size = abs(360.0 * d["f"].max() * value * 1e-3)
        elif name == "inertia_uncorrected":
            size = 100 * np.max(gamma_per_mm() * 1e-6 * abs(value) * (2 * np.pi * d["f"]) ** 2 / np.exp(d["lnE"]))
        elif name == "temperature_offset":
            size = abs(value)
        elif name == "strain_nonlinearity":
            eps = d["strain_microstrain"]
            size = 100 * value * (eps.max() - eps.min()) / 100.0
        else:  # self_heating: mean |E*| drop over an isotherm, %
            size = value * d["test_step"].max()
        return size >= PRACTICAL_MINIMUM[name]

    def run(self) -> dict:
        """Forward selection; returns ``base`` and ``final`` fits, ``selected`` candidates,
        and ``tests``: per artifact name the entry of the report (see :func:`effect_entry`)."""
        base = self.fit([])
        current, selected = base, []
        cands = self.candidates()
        while True:
            results = []
            for c in cands:
                if any(s.name == c.name for s in selected):
                    continue
                fit, F, p, anchor = self._try(current, [s.term for s in selected], c)
                if anchor.rss < current.rss * (1 - 1e-6):  # escaped a local minimum: start the round again
                    current = anchor
                    break
                results.append((p, F, c, fit))
            else:
                anchor = None
            if anchor is not None:
                continue
            ok = [(p, F, c, fit) for p, F, c, fit in results
                  if np.isfinite(p) and p < self.alpha
                  and self._sign_ok(c.name, fit.x[fit.x.size - len(c.term.names):], fit)]
            if not ok:
                break
            p, F, c, fit = min(ok, key=lambda r: r[0])
            # refit from the default starts too, keeping the better solution
            cold = self.fit([s.term for s in selected] + [c.term])
            current = cold if cold.rss < fit.rss else fit
            selected.append(c)
        final = current
        tests = {}
        sizes = [len(c.term.names) for c in selected]
        first = final.x.size - sum(sizes)
        for i, c in enumerate(selected):
            start = first + sum(sizes[:i])
            idx = list(range(start, start + sizes[i]))
            others = [s.term for j, s in enumerate(selected) if j != i]
            keep = np.ones(final.x.size, bool)
            keep[idx] = False
            reduced = self.fit(others, x0=final.x[keep])
            F, p = f_test(reduced.rss, final.rss, sizes[i], final.n_residuals - final.n_params)
            p = one_sided(c.name, final.x[start], p)
            if c.name == "temperature_offset":
                p = min(1.0, p * len(self.data["temperatures"]))
            tests[c.name] = {"detected": True, "p": p, "F": F, "cand": c, "fit": final, "index": idx}
        # not selected: the test of the last round (against the final model); for the
        # temperature offset the most significant isotherm
        for p, F, c, fit in sorted(results, key=lambda r: (np.nan_to_num(r[0], nan=2.0))):
            if c.name not in tests:
                k = len(c.term.names)
                tests[c.name] = {"detected": False, "p": p, "F": F, "cand": c, "fit": fit,
                                 "index": list(range(fit.x.size - k, fit.x.size))}
        return {"base": base, "final": final, "selected": selected, "tests": tests}

    def heating_effect(self, fit: MasterCurveFit, values) -> tuple[float, float]:
        """Mean drop of |E*| (%) and rise of Phi (%) per earlier test of the same isotherm,
        caused by the self-heating parameters ``values`` (3,) on the master curve of ``fit``,
        over the points with n > 0."""
        d = self.data
        n = d["test_step"]
        sel = n > 0
        E0 = fit.modulus(d["f"], d["T"])
        E1 = make_term("self_heating").apply(np.asarray(values, float), fit.modulus(d["f"], d["T"] + values[0] * n), d)
        drop = -np.log(np.abs(E1[sel]) / np.abs(E0[sel])) / n[sel] * 100
        rise = (np.angle(E1[sel]) / np.angle(E0[sel]) - 1) / n[sel] * 100
        return float(np.mean(drop)), float(np.mean(rise))

    # -------------------------------------------------------------- report pieces
    def impact(self, fit: MasterCurveFit, index) -> tuple[float, float]:
        """Mean |change| of Phi (%) and of |E*| (%) caused by parameters ``index`` of ``fit``."""
        prob = self.problem(fit.terms)
        E1 = prob.measured_modulus(fit.x)
        x0 = fit.x.copy()
        x0[index] = 0.0
        E0 = prob.measured_modulus(x0)
        dphi = np.abs(np.angle(E1) - np.angle(E0)) / np.abs(np.angle(E0))
        dE = np.abs(np.log(np.abs(E1) / np.abs(E0)))
        return float(100 * np.mean(dphi)), float(100 * np.mean(dE))

    def corrected(self, fit: MasterCurveFit) -> pd.DataFrame:
        """Measured table with the fitted artifacts of ``fit`` removed.

        Each point is multiplied by the complex ratio of the model without artifacts to the
        model with them (specimen factors kept), which inverts every term exactly; a strain
        nonlinearity b is corrected to the small-strain limit (the term is fitted about the
        table's mean strain eps_ref, so every point is further multiplied by
        exp(b eps_ref / 100)).
        """
        prob = self.problem(fit.terms)
        n_art = sum(len(t.names) for t in fit.terms)
        x_clean = fit.x.copy()
        if n_art:
            x_clean[-n_art:] = 0.0
        ratio = prob.measured_modulus(x_clean) / prob.measured_modulus(fit.x)
        if "modulus_drop_per_100_microstrain" in fit.names:
            ratio = ratio * np.exp(fit.param("modulus_drop_per_100_microstrain") * self.strain_ref / 100.0)
        E = self.df["E_norm_MPa"].to_numpy(float) * np.exp(1j * np.radians(self.df["phase_deg"].to_numpy(float)))
        Ec = E * ratio
        out = self.df.copy()
        out["E_norm_MPa"] = np.abs(Ec)
        out["phase_deg"] = np.degrees(np.angle(Ec))
        return out


def _evidence(name: str, est: dict, F: float, p: float, search: ArtifactSearch, fit: MasterCurveFit) -> str:
    stat = f"F = {F:.3g}, p = {p:.2g}"
    if name == "time_lag":
        kk = kk_time_lag(search.df)
        return (f"phase residual of the master curve linear in f (Phi + 360 f dt): dt = "
                f"{est['time_lag_ms']:.3f} +- {est['time_lag_ms_se']:.3f} ms ({stat}); the "
                f"Kramers-Kronig (Booij-Thoone) phase residual gives dt = {kk['time_lag_ms']:.3f} "
                f"+- {kk['time_lag_se_ms']:.3f} ms")
    if name == "inertia_uncorrected":
        f_max = float(search.df["frequency_Hz"].max())
        dE1 = gamma_per_mm() * 1e-6 * est["mass_factor_g"] * (2 * np.pi * f_max) ** 2
        return (f"in-phase modulus deficit proportional to w^2 (2PB Eq. 1 mass term): mass factor "
                f"{est['mass_factor_g']:.0f} +- {est['mass_factor_g_se']:.0f} g (paper 2PB geometry), "
                f"i.e. E1 lowered by {dE1:.0f} MPa at {f_max:g} Hz ({stat})")
    if name == "temperature_offset":
        return (f"the isotherm labelled {est['temperature_C']:g} degC (the most significant one) fits "
                f"the WLF shift law of the others best at {est['temperature_C'] + est['offset_C']:.1f} degC "
                f"(offset {est['offset_C']:+.2f} +- {est['offset_C_se']:.2f} degC, {stat}, "
                f"Bonferroni over {len(search.data['temperatures'])} isotherms)")
    if name == "strain_nonlinearity":
        return (f"|E*| falls with strain amplitude: {100 * est['modulus_drop_per_100_microstrain']:.2f} "
                f"+- {100 * est['modulus_drop_per_100_microstrain_se']:.2f} % per 100 microstrain ({stat})")
    if name == "self_heating":
        return (f"|E*| changes by {-est['modulus_drop_pct_per_test']:+.2f} +- "
                f"{est['modulus_drop_pct_per_test_se']:.2f} % and Phi by "
                f"{est['phase_rise_pct_per_test']:+.2f} +- {est['phase_rise_pct_per_test_se']:.2f} % per "
                f"earlier test of the same isotherm and specimen (temperature rise "
                f"{est['heating_C_per_test']:.2f} degC per test plus direct terms; {stat}, 3 degrees of freedom)")
    return stat


def effect_entries(search: ArtifactSearch, result: dict) -> list:
    """Report entries (name, detected, testable, score, p_value, estimate, evidence)."""
    entries = []
    for name in ARTIFACTS:
        testable, reason = search.testable[name]
        if not testable:
            entries.append({"name": name, "category": "data", "detected": False, "testable": False,
                            "score": 0.0, "p_value": None, "estimate": {},
                            "evidence": f"not testable: {reason}"})
            continue
        t = result["tests"][name]
        fit, idx = t["fit"], t["index"]
        est = {}
        for i in idx:
            est[fit.names[i]] = float(fit.x[i])
            est[f"{fit.names[i]}_se"] = float(fit.se[i])
        if name == "temperature_offset":
            est["temperature_C"] = t["cand"].temperature_C
        if name == "self_heating":
            vals = fit.x[idx]
            g0 = np.array(search.heating_effect(fit, vals))
            J = np.zeros((2, len(idx)))
            for j in range(len(idx)):
                step = np.zeros(len(idx))
                step[j] = 1e-4 * max(1.0, abs(vals[j]))
                J[:, j] = (np.array(search.heating_effect(fit, vals + step)) - g0) / step[j]
            se = np.sqrt(np.clip(np.diag(J @ fit.cov[np.ix_(idx, idx)] @ J.T), 0, None))
            est.update({"modulus_drop_pct_per_test": float(g0[0]), "modulus_drop_pct_per_test_se": float(se[0]),
                        "phase_rise_pct_per_test": float(g0[1]), "phase_rise_pct_per_test_se": float(se[1])})
        dphi, dE = search.impact(fit, idx)
        est["phase_change_pct"] = dphi
        est["E_norm_change_pct"] = dE
        entries.append({"name": name, "category": "data", "detected": bool(t["detected"]),
                        "testable": True, "score": dphi + dE,
                        "p_value": None if not np.isfinite(t["p"]) else float(t["p"]),
                        "estimate": est,
                        "evidence": _evidence(name, est, t["F"], t["p"], search, fit)})
    return entries
