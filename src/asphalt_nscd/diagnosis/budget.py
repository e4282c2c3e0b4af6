"""What the simulation gets wrong, computed: error budget, named causes, extended law and gain.

:func:`diagnose` computes the JSON report of ``asphalt-nscd diagnose`` from what the earlier
steps wrote and refits nothing upstream (inputs: :mod:`asphalt_nscd.diagnosis.inputs`;
page, figure, tables: :mod:`asphalt_nscd.diagnosis.render`). Its parts:

1. noise levels from the replicate scatter; data artifacts, corrected table and master curve
   as ``asphalt-nscd master-curve`` wrote them (:mod:`asphalt_nscd.diagnosis.artifacts`);
2. baseline: the simulation or, without it, the macro Burger's fits per temperature
   (``rheology.calibration.fit_table``), against the measured replicate means;
3. model-form and simulation causes (:mod:`asphalt_nscd.diagnosis.causes`);
4. error budget per temperature (MRE and signed bias of |E*| and Phi): data artifacts, model
   form, micro-macro transfer, numerics;
5. the extended law (:mod:`asphalt_nscd.rheology.extended`) from its law file, its in-sample
   MRE and the gain: ``nscd``, ``macro`` and, given the network factors, ``law_only`` rows;
6. held-out errors of every model (:func:`heldout_report`, rows of ``asphalt-nscd crossval``),
   the headline numbers.

MRE (paper Table 4): mean over an isotherm's frequencies of |model - data| / data, in percent
(:mod:`asphalt_nscd.rheology.metrics`); bias: the signed mean. Temperatures are JSON keys
formatted with ``%g``.

Budget terms and gain rows: docs/choices.md, Extended mode: generalized law and transfer
correction; causes: docs/choices.md, Diagnosis: causes with measured error rates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ..io import InputError, json_safe
from ..rheology import law_file
from ..rheology.calibration import burgers_model, fit_table
from ..rheology.kramers_kronig import isotherm_residuals
from ..rheology.metrics import cell_means, signed_relative_errors, temperature_key
from . import causes, effects, synthetic
from .artifacts import ArtifactRecord

#: The page's one set of targets, on held-out errors pooled over the interpolated cells of a
#: scheme: the absolute log error of |E*| (%) and the absolute phase error (deg), judged with
#: their 95 % intervals (:func:`target_verdict`). In-sample errors carry no target.
TARGETS = {"abs_logE_pct": 5.0, "abs_phase_deg": 1.5}


def T_key(T) -> str:
    return f"{float(T):g}"


def compare(model: pd.DataFrame, data: pd.DataFrame) -> pd.DataFrame:
    """Per-temperature MRE and bias (%) of ``model`` against ``data`` (both cell tables with
    ``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``), on their common cells."""
    m = model.merge(data, on=["temperature_C", "frequency_Hz"], suffixes=("_m", "_d"))
    rE = pd.Series(signed_relative_errors(m["E_norm_MPa_m"], m["E_norm_MPa_d"]), index=m.index)
    rP = pd.Series(signed_relative_errors(m["phase_deg_m"], m["phase_deg_d"]), index=m.index)
    m = m.assign(aE=100 * rE.abs(), aP=100 * rP.abs(), bE=100 * rE, bP=100 * rP)
    g = m.groupby("temperature_C")
    return pd.DataFrame(
        {
            "mre_E_norm_pct": g["aE"].mean(),
            "mre_phase_pct": g["aP"].mean(),
            "bias_E_norm_pct": g["bE"].mean(),
            "bias_phase_pct": g["bP"].mean(),
            "n": g.size(),
        }
    )


def cells_from_complex(cells: pd.DataFrame, E) -> pd.DataFrame:
    E = np.asarray(E)
    return pd.DataFrame(
        {
            "temperature_C": cells["temperature_C"].to_numpy(float),
            "frequency_Hz": cells["frequency_Hz"].to_numpy(float),
            "E_norm_MPa": np.abs(E),
            "phase_deg": np.degrees(np.angle(E)),
        }
    )


def simulation_cells(df: pd.DataFrame | None) -> pd.DataFrame | None:
    """Means per (T, f) of simulated rows (:func:`asphalt_nscd.rheology.metrics.cell_means`),
    None without rows."""
    if df is None or len(df) == 0:
        return None
    return cell_means(df)


def split_simulated(sim: pd.DataFrame | None, harmonic: pd.DataFrame | None):
    """Split a simulated table with a ``solver`` column into (time-domain, harmonic) rows."""
    if sim is not None and "solver" in sim.columns:
        is_h = sim["solver"].astype(str).str.lower().str.startswith("harmonic")
        h = sim[is_h]
        harmonic = pd.concat([harmonic, h]) if harmonic is not None else (h if len(h) else None)
        sim = sim[~is_h]
        sim = sim if len(sim) else None
    return sim, harmonic


def derived_time_integration(sim: pd.DataFrame | None, harmonic: pd.DataFrame | None):
    """Phase error table (frequency_Hz, dt_s, phase_error_deg) from paired NSCD/harmonic rows."""
    if sim is None or harmonic is None or "dt_s" not in sim.columns:
        return None
    h = simulation_cells(harmonic)
    s = sim.groupby(["temperature_C", "frequency_Hz", "dt_s"], as_index=False)["phase_deg"].mean()
    m = s.merge(h, on=["temperature_C", "frequency_Hz"], suffixes=("", "_h"))
    if len(m) < 2:
        return None
    return pd.DataFrame(
        {"frequency_Hz": m["frequency_Hz"], "dt_s": m["dt_s"], "phase_error_deg": m["phase_deg"] - m["phase_deg_h"]}
    )


def gain_rows(before: pd.DataFrame, after: pd.DataFrame, after_measured: pd.DataFrame, temps) -> dict:
    """{T key: {"E_norm": {before, after, after_vs_measured}, "phase": {...}}} on common temperatures."""
    out = {}
    for T in temps:
        if T not in after.index or T not in before.index:
            continue
        out[T_key(T)] = {
            q: {
                "before": float(before.loc[T, col]),
                "after": float(after.loc[T, col]),
                "after_vs_measured": float(after_measured.loc[T, col]) if T in after_measured.index else None,
            }
            for q, col in (("E_norm", "mre_E_norm_pct"), ("phase", "mre_phase_pct"))
        }
    return out


def _by_T(frame: pd.DataFrame, col: str) -> dict:
    return {T_key(T): float(v) for T, v in frame[col].items()}


@dataclass
class DiagnosisInputs:
    """What :func:`diagnose` reads: its parameters, one field each.

    Attributes
    ----------
    measured : DataFrame
        Validated measured table (``lab.measured.load_measured``).
    search : ArtifactRecord
        Artifact search and master curve of ``measured``
        (:func:`asphalt_nscd.diagnosis.artifacts.read` of ``asphalt-nscd master-curve``):
        noise, artifact entries, master curve (MPa), significance level and shift law.
    corrected : DataFrame
        The artifact-corrected table of that search (same rows as ``measured``).
    laws : dict or None
        The extended law per temperature {T degC: GeneralizedBurgers in MPa, MPa s} at every
        measured temperature (:func:`asphalt_nscd.rheology.law_file.read_mpa` of the law file
        of ``extend-law``, the one the extended simulation ran with). None: no extended law
        (``law_failure`` says why); the paper's Burger's law per isotherm stands in, no gain.
    simulated : DataFrame, optional
        Time-domain (NSCD) results, reduced rows (``temperature_C, frequency_Hz,
        E_norm_MPa, phase_deg``; a ``solver`` column with ``harmonic`` marks harmonic rows;
        ``dt_s`` allows the time-integration test).
    harmonic : DataFrame, optional
        Harmonic-solver results of the numerical sample (same columns).
    time_errors : DataFrame, optional
        Time-integration phase errors ``frequency_Hz, dt_s, phase_error_deg``.
    simulated_extended : DataFrame, optional
        Results of the simulation rerun with the extended law (else the extended macro law
        stands for it).
    macro_params : DataFrame, optional
        Burger's parameters the simulation was given (``temperature_C, Em_MPa, eta_m_MPa_s,
        Ek_MPa, eta_k_MPa_s``); default: fitted here to the measured table (the baseline of
        the budget, not an upstream step).
    transfer : dict, optional
        Network factor NF_s (dimensionless) per sample name of the extended simulation
        (``harmonic-transfer`` JSONs): adds the ``law_only`` gain source, NF_s E*_law (mean
        over the samples; module docstring).
    crossval : DataFrame, optional
        Rows of ``asphalt-nscd crossval`` (:func:`asphalt_nscd.diagnosis.inputs.read_crossval`,
        lofo and/or loto): the gain table and the page give the held-out MRE beside the
        in-sample one (:func:`heldout_report`).
    law_info : dict, optional
        ``selection`` and ``model`` of the law file (``extend-law``): the chosen settings and
        their cross-validation curve, shown on the page.
    law_failure : str, optional
        Why there is no extended law (with ``laws`` None), quoted in the report.
    cause_tolerances : dict, optional
        ``network_factor`` and ``time_integration_deg`` (default :data:`causes.TOLERANCES`).
    card : dict, optional
        The material card's JSON (``export-law``: ``prony.json``): what it carries and loses,
        and its errors against the measured means per temperature, for the page.
    without_flagged : dict, optional
        ``extend-law --without-flagged``'s JSON: the law without the rows beyond a
        data-quality limit (compared with the selected law on the page), or its note.
    """

    measured: pd.DataFrame
    search: ArtifactRecord
    corrected: pd.DataFrame
    laws: dict | None
    simulated: pd.DataFrame | None = None
    harmonic: pd.DataFrame | None = None
    time_errors: pd.DataFrame | None = None
    simulated_extended: pd.DataFrame | None = None
    macro_params: pd.DataFrame | None = None
    transfer: dict | None = None
    crossval: pd.DataFrame | None = None
    law_info: dict | None = None
    law_failure: str | None = None
    cause_tolerances: dict | None = None
    card: dict | None = None
    without_flagged: dict | None = None


@dataclass
class Cells:
    """Stage :func:`cells_stage`. Cell tables hold one row per (temperature_C, frequency_Hz) with
    ``E_norm_MPa`` (MPa) and ``phase_deg`` (deg); comparison tables are :func:`compare`'s."""

    table: pd.DataFrame  #: the measured table prepared for the effects (:func:`effects.prepare_table`)
    simulated: pd.DataFrame | None  #: time-domain rows, harmonic rows split off
    harmonic: pd.DataFrame | None  #: harmonic rows, given or split off ``simulated``
    time_errors: pd.DataFrame | None  #: phase errors ``frequency_Hz, dt_s, phase_error_deg``
    measured: pd.DataFrame  #: replicate means of the measured table
    corrected: pd.DataFrame  #: replicate means of the artifact-corrected table
    burgers_measured: pd.DataFrame  #: Burger's parameters fitted per temperature (MPa, MPa s)
    burgers: pd.DataFrame  #: Burger's parameters of the simulation (``macro_params``, else the fit)
    burgers_cells: pd.DataFrame  #: the macro Burger's law at the measured cells
    sim: pd.DataFrame | None  #: cell means of the time-domain rows
    harm: pd.DataFrame | None  #: cell means of the harmonic rows
    baseline_model: str  #: what the baseline is
    base: pd.DataFrame  #: comparison of the baseline with the measured cells
    temps: list  #: measured temperatures, degC, ascending


@dataclass
class Causes:
    """Stage :func:`causes_stage`: candidate causes (dicts of :mod:`asphalt_nscd.diagnosis.causes`)."""

    entries: list  #: the artifact entries of the search, then the model-form and simulation causes
    named: list  #: the detected entries, highest score first


@dataclass
class Budget:
    """Stage :func:`budget_stage`: MRE and bias (%) per temperature and component."""

    table: pd.DataFrame  #: rows ``temperature_C, component, mre_*_pct, bias_*_pct``
    by_temperature: dict  #: {T key: {component: {mre_*_pct, bias_*_pct} or None}}


@dataclass
class Law:
    """Stage :func:`law_stage`: the extended law at the measured temperatures."""

    laws: dict  #: {T degC: law in MPa, MPa s}: the extended law, else Burger's per isotherm
    model: str  #: what the law is (or why the Burger's law stands in for it)
    cells: pd.DataFrame  #: the law at the cells of the corrected table


@dataclass
class Extended:
    """Stage :func:`extended_stage`: the "after" model and its errors."""

    simulated_cells: pd.DataFrame | None  #: cell means of the extended NSCD rows
    transfer: dict  #: :func:`transfer_summary`
    nscd_after: str  #: the extended NSCD simulation, described
    model: str  #: the "after" model: the extended NSCD simulation, else the extended macro law
    vs_corrected: pd.DataFrame  #: comparison of the "after" model with the corrected cells
    vs_measured: pd.DataFrame  #: the same against the measured cells
    law_vs_corrected: pd.DataFrame  #: comparison of the extended macro law with the corrected cells
    law_vs_measured: pd.DataFrame  #: the same against the measured cells


@dataclass
class Gains:
    """Stage :func:`gains_stage`: gain rows (:func:`gain_rows`) per source."""

    gain: dict  #: primary source: baseline -> "after" model
    sources: dict  #: {"before": "nscd" | "macro", "after": "nscd" | "macro"} of ``gain``
    macro: dict  #: macro Burger's law -> extended macro law
    nscd: dict | None  #: NSCD -> extended NSCD (``gain`` when both are simulations)
    law_only: dict | None  #: baseline -> NF_s E*_law (given network factors)
    law_only_model: str | None  #: the ``law_only`` model, described


def diagnose(
    measured: pd.DataFrame,
    search: ArtifactRecord,
    corrected: pd.DataFrame,
    laws: dict | None,
    simulated: pd.DataFrame | None = None,
    harmonic: pd.DataFrame | None = None,
    time_errors: pd.DataFrame | None = None,
    simulated_extended: pd.DataFrame | None = None,
    macro_params: pd.DataFrame | None = None,
    transfer: dict | None = None,
    crossval: pd.DataFrame | None = None,
    law_info: dict | None = None,
    law_failure: str | None = None,
    cause_tolerances: dict | None = None,
    card: dict | None = None,
    without_flagged: dict | None = None,
) -> tuple[dict, dict]:
    """Diagnose a measured table from what the earlier steps wrote (and optional simulation
    results); nothing upstream is refitted here: the stages of :func:`diagnosis_of`.

    Parameters
    ----------
    measured, search, corrected, laws, simulated, ... : the fields of
        :class:`DiagnosisInputs`, in its order (described there).

    Returns
    -------
    (report, extra)
        ``report``: the JSON-serialisable report; ``extra``: ``laws`` (dict T ->
        GeneralizedBurgers in MPa), ``corrected`` (DataFrame), ``budget`` (DataFrame),
        ``master`` (MasterCurveFit).

    Raises
    ------
    InputError
        if ``laws`` lacks a measured temperature, or if an extended row ran with a network
        factor that differs from ``transfer``'s.
    """
    inputs = DiagnosisInputs(
        measured,
        search,
        corrected,
        laws,
        simulated=simulated,
        harmonic=harmonic,
        time_errors=time_errors,
        simulated_extended=simulated_extended,
        macro_params=macro_params,
        transfer=transfer,
        crossval=crossval,
        law_info=law_info,
        law_failure=law_failure,
        cause_tolerances=cause_tolerances,
        card=card,
        without_flagged=without_flagged,
    )
    return diagnosis_of(inputs)


def diagnosis_of(inputs: DiagnosisInputs) -> tuple[dict, dict]:
    """(report, extra) of :func:`diagnose` from its ``inputs``, by the stages in order:
    :func:`cells_stage`, :func:`causes_stage`, :func:`budget_stage`, :func:`law_stage`,
    :func:`extended_stage`, :func:`gains_stage`, :func:`report_stage`.

    Raises
    ------
    InputError as :func:`diagnose`.
    """
    cells = cells_stage(inputs)
    found = causes_stage(inputs, cells)
    budget = budget_stage(cells)
    law = law_stage(inputs, cells)
    extended = extended_stage(inputs, cells, law)
    gains = gains_stage(cells, law, extended)
    report = report_stage(inputs, cells, found, budget, law, extended, gains)
    extra = {"laws": law.laws, "corrected": inputs.corrected, "budget": budget.table, "master": inputs.search.master}
    return report, extra


def cells_stage(inputs: DiagnosisInputs) -> Cells:
    """Cell means of the measured, corrected and simulated tables, the macro Burger's law at the
    measured cells and the baseline: the time-domain simulation if given, else that law.

    Harmonic rows of ``simulated`` (``solver`` column) join the harmonic ones; without
    ``time_errors``, they come from paired time-domain and harmonic rows
    (:func:`derived_time_integration`)."""
    table = effects.prepare_table(inputs.measured)
    simulated, harmonic = split_simulated(inputs.simulated, inputs.harmonic)
    time_errors = inputs.time_errors
    if time_errors is None:
        time_errors = derived_time_integration(simulated, harmonic)

    meas_cells = cell_means(table)
    corr_cells = cell_means(inputs.corrected)
    burgers_measured = fit_table(table)
    burgers = inputs.macro_params if inputs.macro_params is not None else burgers_measured
    burgers_cells = cells_from_complex(
        meas_cells, causes.burgers_predict(burgers, meas_cells["temperature_C"], meas_cells["frequency_Hz"])
    )
    sim_cells, harm_cells = simulation_cells(simulated), simulation_cells(harmonic)

    if sim_cells is not None:
        baseline_model, baseline_cells = "NSCD simulation (time domain, Burger's bond law)", sim_cells
    else:
        baseline_model, baseline_cells = "macro Burger's model (Eqs. 27-29) fitted per temperature", burgers_cells
    return Cells(
        table=table,
        simulated=simulated,
        harmonic=harmonic,
        time_errors=time_errors,
        measured=meas_cells,
        corrected=corr_cells,
        burgers_measured=burgers_measured,
        burgers=burgers,
        burgers_cells=burgers_cells,
        sim=sim_cells,
        harm=harm_cells,
        baseline_model=baseline_model,
        base=compare(baseline_cells, meas_cells),
        temps=sorted(meas_cells["temperature_C"].unique()),
    )


def causes_stage(inputs: DiagnosisInputs, cells: Cells) -> Causes:
    """Candidate causes: the search's artifact entries, then the broad relaxation spectrum,
    the static modulus, the network factor (harmonic rows, else time-domain rows) and the
    time integration (:mod:`asphalt_nscd.diagnosis.causes`, tolerances ``cause_tolerances``
    over :data:`causes.TOLERANCES`)."""
    search = inputs.search
    tol = {**causes.TOLERANCES, **(inputs.cause_tolerances or {})}
    entries = [dict(e) for e in search.effects]
    entries.append(causes.broad_spectrum(cells.table, search.master, cells.burgers_measured, inputs.corrected))
    entries.append(causes.static_modulus(inputs.corrected, search.master, search.alpha, search.calibration))
    transfer_src = cells.harmonic if cells.harmonic is not None else cells.simulated
    entries.append(
        causes.network_factor(
            transfer_src,
            cells.burgers,
            "harmonic" if cells.harmonic is not None else "simulated",
            tolerance=tol["network_factor"],
        )
    )
    entries.append(causes.time_integration(cells.time_errors, tolerance_deg=tol["time_integration_deg"]))
    named = sorted([e for e in entries if e["detected"]], key=lambda e: -e["score"])
    return Causes(entries=entries, named=named)


def budget_stage(cells: Cells) -> Budget:
    """Error budget per measured temperature: data artifacts (measured vs corrected), model
    form (macro Burger's vs corrected), micro-macro transfer (harmonic response vs its macro
    Burger's law), numerics (time domain vs harmonic) and the total (baseline vs measured);
    a component without its inputs is None."""
    comps = {
        "data_artifacts": compare(cells.measured, cells.corrected),
        "model_form": compare(cells.burgers_cells, cells.corrected),
        "micro_macro_transfer": None,
        "numerics": None,
        "total": cells.base,
    }
    harm = cells.harm
    if harm is not None:
        hb = cells_from_complex(
            harm, causes.burgers_predict(cells.burgers, harm["temperature_C"], harm["frequency_Hz"])
        )
        comps["micro_macro_transfer"] = compare(harm, hb.dropna())
        if cells.sim is not None:
            comps["numerics"] = compare(cells.sim, harm)
    rows: list[dict] = []
    by_T: dict[str, dict[str, Any]] = {}
    for T in cells.temps:
        by_T[T_key(T)] = {}
        for name, frame in comps.items():
            if frame is None or T not in frame.index:
                by_T[T_key(T)][name] = None
                continue
            row = frame.loc[T]
            vals = {k: float(row[k]) for k in ("mre_E_norm_pct", "mre_phase_pct", "bias_E_norm_pct", "bias_phase_pct")}
            by_T[T_key(T)][name] = vals
            rows.append({"temperature_C": T, "component": name, **vals})
    return Budget(table=pd.DataFrame(rows), by_temperature=by_T)


def law_stage(inputs: DiagnosisInputs, cells: Cells) -> Law:
    """The extended law at the measured temperatures and at the corrected cells; without one
    (``laws`` None), the macro Burger's fit per isotherm stands in and the model text says why.

    Raises InputError if ``laws`` lacks a measured temperature."""
    laws, law_failure = inputs.laws, inputs.law_failure
    if laws is None:  # the report goes on with the paper's Burger's law per isotherm standing in
        law_failure = f"extended law not computable: {law_failure or 'no law given'}"
        laws = {float(r["temperature_C"]): burgers_model(r, unit=1.0) for _, r in cells.burgers_measured.iterrows()}
    else:
        law_failure = None
        missing = [float(T) for T in cells.temps if temperature_key(laws, T) is None]
        if missing:
            raise InputError(
                f"extended laws: no law at {missing} degC (the measured temperatures); given: {sorted(laws)}"
            )
        laws = {float(T): laws[temperature_key(laws, T)] for T in cells.temps}
    corr = cells.corrected
    E_law = law_file.complex_modulus(laws, corr["temperature_C"], corr["frequency_Hz"])
    selected = ((inputs.law_info or {}).get("selection") or {}).get("chosen_label")
    law_model = (
        "generalized Burger's law (Maxwell + N Kelvin-Voigt + static spring) per temperature from the "
        "selected temperature-aware law of the corrected data"
        + (f" (2S2P1D backbone, selected settings: {selected})" if selected else "")
    )
    if law_failure is not None:
        law_model = f"{law_failure}; the macro Burger's law per temperature stands in for it (no gain)"
    return Law(laws=laws, model=law_model, cells=cells_from_complex(corr, E_law))


def extended_stage(inputs: DiagnosisInputs, cells: Cells, law: Law) -> Extended:
    """The "after" model (the NSCD simulation rerun with the extended law, else the extended
    macro law), its transfer correction (:func:`transfer_summary`) and the errors of it and of
    the law against the corrected and the measured cells.

    Raises InputError as :func:`transfer_summary`."""
    ext_sim_cells = simulation_cells(inputs.simulated_extended)
    tr = transfer_summary(inputs.simulated_extended, inputs.transfer)
    nscd_after = "NSCD simulation (time domain, generalized Burger's bond law" + (
        f", transfer correction E*/NF_s, NF_s = {nf_text(tr['network_factor_applied'])})"
        if tr["applied"]
        else ", no transfer correction)"
    )
    if ext_sim_cells is not None:
        ext_cells, ext_model = ext_sim_cells, nscd_after
    else:
        ext_cells, ext_model = law.cells, law.model
    return Extended(
        simulated_cells=ext_sim_cells,
        transfer=tr,
        nscd_after=nscd_after,
        model=ext_model,
        vs_corrected=compare(ext_cells, cells.corrected),
        vs_measured=compare(ext_cells, cells.measured),
        law_vs_corrected=compare(law.cells, cells.corrected),
        law_vs_measured=compare(law.cells, cells.measured),
    )


def gains_stage(cells: Cells, law: Law, extended: Extended) -> Gains:
    """Gain rows per source: the primary one (baseline -> "after" model), ``macro`` (macro
    Burger's -> extended macro law), ``nscd`` (when both are simulations) and, given network
    factors, ``law_only`` (baseline -> NF_s E*_law, :func:`law_only_gain`)."""
    macro_before = compare(cells.burgers_cells, cells.measured)
    gain = gain_rows(cells.base, extended.vs_corrected, extended.vs_measured, cells.temps)
    sources = {
        "before": "nscd" if cells.sim is not None else "macro",
        "after": "nscd" if extended.simulated_cells is not None else "macro",
    }
    gain_macro = gain_rows(macro_before, extended.law_vs_corrected, extended.law_vs_measured, cells.temps)
    gain_nscd = gain if sources == {"before": "nscd", "after": "nscd"} else None
    gain_law_only, law_only_model = law_only_gain(cells, law, extended)
    return Gains(
        gain=gain,
        sources=sources,
        macro=gain_macro,
        nscd=gain_nscd,
        law_only=gain_law_only,
        law_only_model=law_only_model,
    )


def law_only_gain(cells: Cells, law: Law, extended: Extended) -> tuple[dict | None, str | None]:
    """(gain rows, model text) of the ``law_only`` source: the inertia-free harmonic response
    NF_s E*_law(w) with the mean network factor, on the cells of the extended NSCD run when
    there is one (its gain rows' cells), else on the corrected cells; (None, None) without
    network factors."""
    tr = extended.transfer
    if tr["law_only_network_factor"] is None:
        return None, None
    nf = tr["law_only_network_factor"]
    on = extended.simulated_cells if extended.simulated_cells is not None else cells.corrected
    on = on[[temperature_key(law.laws, T) is not None for T in on["temperature_C"]]]
    E_lo = nf * law_file.complex_modulus(law.laws, on["temperature_C"], on["frequency_Hz"])
    lo_cells = cells_from_complex(on, E_lo)
    gain = gain_rows(cells.base, compare(lo_cells, cells.corrected), compare(lo_cells, cells.measured), cells.temps)
    model = (
        "harmonic response without inertia, generalized Burger's bond law, no transfer "
        f"correction: NF_s x E*_law, NF_s = {nf_text(tr['network_factor_harmonic'])}"
    )
    return gain, model


def report_stage(
    inputs: DiagnosisInputs, cells: Cells, found: Causes, budget: Budget, law: Law, extended: Extended, gains: Gains
) -> dict:
    """The JSON report of ``asphalt-nscd diagnose`` (:func:`asphalt_nscd.io.json_safe`) from the
    stages before."""
    measured, search, temps, base = inputs.measured, inputs.search, cells.temps, cells.base
    order = {"data": 0, "model_form": 1, "simulation": 2}
    report = {
        "measured": {
            "n_rows": int(len(measured)),
            "n_specimens": int(measured["specimen"].nunique()),
            "temperatures_C": [float(T) for T in temps],
            "frequencies_Hz": sorted(float(f) for f in measured["frequency_Hz"].unique()),
        },
        "noise": {
            "sigma_lnE": search.sigma[0],
            "sigma_phase_deg": search.sigma[1],
            "from_replicates": search.noise_from_replicates,
        },
        "artifact_screening": search.screening,
        "master_curve": master_curve_block(search, temps),
        **kramers_kronig_blocks(cells.table),
        "baseline": {
            "model": cells.baseline_model,
            "reference": "measured replicate means",
            "mre_E_norm_pct": _by_T(base, "mre_E_norm_pct"),
            "mre_phase_pct": _by_T(base, "mre_phase_pct"),
            "bias_E_norm_pct": _by_T(base, "bias_E_norm_pct"),
            "bias_phase_pct": _by_T(base, "bias_phase_pct"),
        },
        "error_budget": budget.by_temperature,
        "effects": sorted(found.entries, key=lambda e: order[e["category"]]),
        "causes": [e["name"] for e in found.named],
        "extended": extended_block(inputs.law_info, law, extended),
        "gain": gains.gain,
        "gain_sources": gain_sources_block(cells, law, extended, gains),
        "gain_nscd": gains.nscd,
        "gain_macro": gains.macro,
        "gain_law_only": gains.law_only,
        "transfer": extended.transfer,
        "heldout": heldout_report(inputs.crossval, measured) if inputs.crossval is not None else None,
        "targets": {
            **TARGETS,
            "applies_to": "held-out errors pooled over the interpolated cells of a scheme, "
            "judged with their 95 % intervals",
        },
        "selection": search.selection,
        "units": dict(search.units) or {"modulus": "MPa", "temperature": "C"},
        "calibration": calibration_summary(search.calibration),
        "findings": findings_block(inputs),
        "material_card": card_block(inputs.card),
        "data_quality": search.quality,
        "law_without_flagged": without_flagged_text(inputs.without_flagged, law.laws, measured)
        if inputs.laws is not None
        else None,
    }
    return json_safe(report)


def gain_sources_block(cells: Cells, law: Law, extended: Extended, gains: Gains) -> dict:
    """The ``gain_sources`` block: the sources of the primary gain (:class:`Gains`), the models
    before and after of each gain source, and the references the gains are measured against."""
    return {
        **gains.sources,
        "models": {
            "nscd": {"before": "NSCD simulation (time domain, Burger's bond law)", "after": extended.nscd_after},
            "macro": {"before": "macro Burger's model (Eqs. 27-29) per temperature", "after": law.model},
            "law_only": {"before": cells.baseline_model, "after": gains.law_only_model},
        },
        "reference": {"before": "measured replicate means", "after": "artifact-corrected measured replicate means"},
    }


def findings_block(inputs: DiagnosisInputs) -> dict:
    """The ``findings`` block: the notes of the artifact search's master curve, of the selected
    law and of the material card's law (when the card's law is not the selected one)."""
    card = inputs.card
    return {
        "artifact search master curve (2S2P1D of the corrected table)": inputs.search.findings,
        "selected law": ((inputs.law_info or {}).get("model") or {}).get("findings") or [],
        "law of the material card": [] if not card or card.get("is_selected_law", True) else card.get("findings") or [],
    }


def master_curve_block(search: ArtifactRecord, temps) -> dict:
    """The ``master_curve`` block: 2S2P1D parameters, shift law and log10 a_T per temperature,
    chi2 per degree of freedom."""
    master = search.master
    return {
        "model": "2S2P1D",
        "shift": search.shift,
        "T_ref_C": master.T_ref_C,
        "parameters": {k: float(v) for k, v in master.core().items()},
        "log10_aT": {T_key(T): float(master.log_shift(T)) for T in temps},
        "chi2_per_dof": master.rss / max(master.n_residuals - master.n_params, 1),
    }


def kramers_kronig_blocks(table: pd.DataFrame) -> dict:
    """The Kramers-Kronig blocks: mean absolute phase residual per isotherm (deg), its
    percentile among clean synthetic tables at the table's frequencies and replicate count,
    and that reference distribution."""
    kk_T = isotherm_residuals(table)
    kk_ref = synthetic.kk_reference(sorted(table["frequency_Hz"].unique()), int(table["specimen"].nunique()))
    return {
        "kramers_kronig_mean_abs_residual_deg": {T_key(T): float(v) for T, v in kk_T.items()},
        "kramers_kronig_percentile": {T_key(T): float(100.0 * np.mean(kk_ref <= v)) for T, v in kk_T.items()},
        "kramers_kronig_reference": {
            "n_isotherms": int(kk_ref.size),
            "median_deg": float(np.median(kk_ref)),
            "p99_deg": float(np.percentile(kk_ref, 99)),
            "max_deg": float(kk_ref.max()),
            "source": "clean synthetic tables of every truth family (causal laws) at the "
            "table's frequencies and replicate count",
        },
    }


def extended_block(law_info: dict | None, law: Law, extended: Extended) -> dict:
    """The ``extended`` block: the "after" model and the law, their in-sample MRE per
    temperature (%), the law's parameters (Pa, Pa s) and its selected settings."""
    ext, ext_meas = extended.vs_corrected, extended.vs_measured
    return {
        "model": extended.model,
        "law": law.model,
        "reference": "artifact-corrected measured replicate means",
        "parameters": law_file.to_json(law.laws)["temperatures"],
        "parameter_units": {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"},
        "mre_E_norm_pct": _by_T(ext, "mre_E_norm_pct"),
        "mre_phase_pct": _by_T(ext, "mre_phase_pct"),
        "mre_E_norm_pct_vs_measured": _by_T(ext_meas, "mre_E_norm_pct"),
        "mre_phase_pct_vs_measured": _by_T(ext_meas, "mre_phase_pct"),
        "law_mre_E_norm_pct": _by_T(extended.law_vs_corrected, "mre_E_norm_pct"),
        "law_mre_phase_pct": _by_T(extended.law_vs_corrected, "mre_phase_pct"),
        "selection": (law_info or {}).get("selection"),
        "T_ref_C": ((law_info or {}).get("model") or {}).get("T_ref_C"),
    }


def target_verdict(value: float, low: float, high: float, target: float) -> str:
    """A held-out error against its target, judged with its 95 % interval: ``met`` (the
    interval lies below the target), ``missed`` (above), ``undecided`` (the target lies inside
    the interval: within the measured reference's own noise); without an interval, ``met`` or
    ``missed`` by the point value."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "met" if value <= target else "missed"
    return "met" if high <= target else "missed" if low > target else "undecided"


def without_flagged_text(obj: dict | None, laws: dict, measured: pd.DataFrame) -> str | None:
    """One paragraph comparing the selected law with the law fitted without the rows beyond a
    data-quality limit (``extend-law --without-flagged``), at every measured cell: mean and
    largest |ln ratio| of |E*| (%) and |difference| of Phi (deg) per temperature; None without
    it."""
    if obj is None:
        return None
    if "temperatures" not in obj:
        return f"Law without the flagged rows: {obj.get('note', 'none')}."
    other = {float(T): g.scaled(1e-6) for T, g in law_file.validate(obj, "law without flagged rows").items()}
    cells = cell_means(measured)
    parts = []
    for T, g in cells.groupby("temperature_C"):
        key = temperature_key(other, T)
        if key is None or temperature_key(laws, T) is None:
            continue
        f = g["frequency_Hz"].to_numpy(float)
        a = law_file.complex_modulus(other, np.full(f.size, T), f)
        b = law_file.complex_modulus(laws, np.full(f.size, T), f)
        dE = 100 * np.abs(np.log(np.abs(a) / np.abs(b)))
        dP = np.abs(np.degrees(np.angle(a) - np.angle(b)))
        parts.append(f"{T:g} degC {dE.mean():.2f} / {dE.max():.2f} % and {dP.mean():.2f} / {dP.max():.2f} deg")
    src = obj.get("source", {})
    return (
        f"Fitted without the {src.get('n_flagged', '?')} flagged rows (of {src.get('n_rows', '?')}; settings "
        f"{(obj.get('selection') or {}).get('chosen_label', '?')}), the law differs from the selected one by "
        "(mean / largest |ln ratio| of |E*|, |difference| of Phi, over the measured cells): " + "; ".join(parts) + "."
    )


def card_block(card: dict | None) -> dict | None:
    """What the page says of the material card (``export-law``'s JSON), or None."""
    if card is None:
        return None
    keys = (
        "carries",
        "selected_law",
        "is_selected_law",
        "fit",
        "selected_fit",
        "selected_carriable",
        "corrections",
        "loss",
        "check",
        "T_ref_C",
        "E_0_MPa",
        "shift",
        "display",
        "findings",
        "terms_selection",
        "nu",
        "nu_source",
        "interconversion",
    )
    return {k: card.get(k) for k in keys} | {"n_terms": len(card.get("terms", []))}


def calibration_summary(calibration: dict | None) -> dict | None:
    """What the page says of the table's calibration (without the per-table statistics)."""
    if calibration is None:
        return None
    a = calibration["artifacts"]
    return {
        "n_tables": calibration["n_tables"],
        "seed": calibration["seed"],
        "familywise_rate": calibration["familywise_rate"],
        "groups": calibration["groups"],
        "clean_model": calibration["clean_model"],
        "artifacts": {
            **{k: v for k, v in a.items() if k not in ("null_min_p", "nulls")},
            "nulls": {
                name: {k: v for k, v in n.items() if k != "null_min_p"} for name, n in (a.get("nulls") or {}).items()
            },
        },
        "static": {"level": calibration["static"]["level"], "model": calibration["static"]["model"]},
    }


#: schemes of the held-out validation and what they leave out
SCHEME_TEXT = {
    "lofo": "one frequency left out at every temperature (the lowest and highest are extrapolations)",
    "loto": "one isotherm left out (the coldest and hottest are extrapolations)",
    "loso": "one specimen left out, scored against that specimen (a new specimen)",
}


def heldout_report(rows: pd.DataFrame, measured: pd.DataFrame | None = None) -> dict:
    """The ``heldout`` block of the report from crossval rows
    (:mod:`asphalt_nscd.diagnosis.scores`).

    ``scores``: every summary row (per scheme, kind, model, temperature, extrapolation, and
    pooled with ``temperature_C`` None); ``headline``: per scheme, kind and model the pooled
    interpolated and extrapolated scores with their intervals, the worst temperature (marked),
    and for held-out rows the targets (:data:`TARGETS`) with their verdicts
    (:func:`target_verdict`); ``not_computable``: per scheme, why its folds could not be
    computed when none could; ``time_domain_check``; ``reference`` and ``protocol`` (text).
    """
    from .scores import headline, summarize

    summ = summarize(rows, measured)
    heads = []
    # the time-domain model holds one cell (the agreement check below), not a headline
    for _, h in headline(summ[summ["model"] != "nscd_time_domain"]).iterrows():
        d = h.to_dict()
        if d["kind"] == "held_out":
            d["targets"] = dict(TARGETS)
            d["verdict_E_norm"] = target_verdict(
                d["interp_abs_logE_pct"],
                d["interp_abs_logE_ci95_low"],
                d["interp_abs_logE_ci95_high"],
                TARGETS["abs_logE_pct"],
            )
            d["verdict_phase"] = target_verdict(
                d["interp_abs_phase_deg"],
                d["interp_abs_phase_ci95_low"],
                d["interp_abs_phase_ci95_high"],
                TARGETS["abs_phase_deg"],
            )
        heads.append(d)
    not_computable = {}
    for scheme, g in rows[rows["kind"] == "held_out"].groupby("scheme"):
        if not g["computable"].any():
            not_computable[scheme] = "; ".join(sorted(set(g["reason"].astype(str))))
    td = []
    held = rows[(rows["kind"] == "held_out") & rows["computable"]]
    keys = ["scheme", "fold", "temperature_C", "frequency_Hz"]
    both = held[held["model"] == "nscd_time_domain"].merge(
        held[held["model"] == "nscd_sample"], on=keys, suffixes=("_td", "_h")
    )
    for _, r in both.iterrows():
        td.append(
            {
                "scheme": r["scheme"],
                "fold": str(r["fold"]),
                "temperature_C": r["temperature_C"],
                "frequency_Hz": r["frequency_Hz"],
                "E_norm_MPa_time_domain": r["E_norm_MPa_predicted_td"],
                "E_norm_MPa_harmonic": r["E_norm_MPa_predicted_h"],
                "phase_deg_time_domain": r["phase_deg_predicted_td"],
                "phase_deg_harmonic": r["phase_deg_predicted_h"],
                "E_norm_relative_difference": r["E_norm_MPa_predicted_td"] / r["E_norm_MPa_predicted_h"] - 1.0,
                "phase_difference_deg": r["phase_deg_predicted_td"] - r["phase_deg_predicted_h"],
            }
        )
    return json_safe(
        {
            "scores": summ.to_dict(orient="records"),
            "headline": heads,
            "not_computable": not_computable,
            "time_domain_check": td,
            "schemes": {k: v for k, v in SCHEME_TEXT.items() if k in set(rows["scheme"])},
            "reference": "the specimens' ln|E*| and Phi (their mean per cell; loso: the held-out specimen)",
            "protocol": "every fold refits the whole procedure (artifact correction at the table's "
            "calibrated level, nested selection of the settings, law) without its held-out "
            "rows; extrapolated cells (the ends of the tested frequencies or temperatures) "
            "reported apart",
        }
    )


def nf_text(nf: dict | None) -> str:
    """``0.909 (s1), 0.912 (s2)`` from {sample: NF_s}."""
    return ", ".join(f"{v:.4g} ({k})" for k, v in (nf or {}).items()) or "n/a"


def transfer_summary(simulated_extended: pd.DataFrame | None, transfer: dict | None) -> dict:
    """What the extended NSCD rows say about the transfer correction, and the NF_s to use
    for the ``law_only`` source.

    Returns
    -------
    dict: ``applied`` (True: the extended rows carry ``transfer_network_factor``; False: they
    do not; None: no extended rows), ``network_factor_applied`` ({sample: NF_s} of the rows),
    ``network_factor_applied_mean``, ``network_factor_harmonic`` ({sample: NF_s} given, else
    the applied ones), ``law_only_network_factor`` (their mean, or None), ``definition``.

    Raises
    ------
    InputError
        if a sample's rows carry several factors, or a factor that differs (relative 1e-9)
        from the one given in ``transfer`` for the same sample.
    """
    applied, per_sample = None, {}
    ext = simulated_extended
    if ext is not None and len(ext):
        applied = "transfer_network_factor" in ext.columns
        if applied:
            nf = pd.to_numeric(ext["transfer_network_factor"], errors="coerce")
            samples = ext["sample"].astype(str) if "sample" in ext.columns else pd.Series("all", index=ext.index)
            if not np.isfinite(nf.to_numpy(float)).all():
                raise InputError(
                    "extended NSCD rows: column 'transfer_network_factor' is empty or not a number "
                    "on some rows (rows with and without the transfer correction are mixed)"
                )
            for name, values in nf.groupby(samples):
                if not np.allclose(values, values.iloc[0], rtol=1e-12, atol=0):
                    raise InputError(
                        f"extended NSCD rows: sample {name!r} ran with several network factors "
                        f"{sorted(set(values.round(12)))}"
                    )
                per_sample[str(name)] = float(values.iloc[0])
    given = {str(k): float(v) for k, v in (transfer or {}).items()}
    for name, v in per_sample.items():
        if name in given and not np.isclose(v, given[name], rtol=1e-9, atol=0):
            raise InputError(
                f"extended NSCD rows: sample {name!r} ran with network factor {v:.10g} but the "
                f"transfer JSON gives {given[name]:.10g} (stale simulation or JSON)"
            )
    harmonic = given or dict(per_sample)
    return {
        "applied": applied,
        "network_factor_applied": per_sample or None,
        "network_factor_applied_mean": float(np.mean(list(per_sample.values()))) if per_sample else None,
        "network_factor_harmonic": harmonic or None,
        "law_only_network_factor": float(np.mean(list(harmonic.values()))) if harmonic else None,
        "definition": "NF_s = sample |E*| / macro |E*| without inertia (harmonic solver, real, law "
        "independent); transfer correction: bonds calibrated with E*(w) / NF_s",
    }
