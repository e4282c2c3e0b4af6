"""What the simulation gets wrong, computed: error budget, named causes, extended law and gain.

:func:`diagnose` computes the JSON report of ``asphalt-nscd diagnose`` from what the earlier
steps wrote; it refits nothing upstream. Rendering (page, figure, tables) is
:mod:`asphalt_nscd.diagnosis.render`; reading the input files, :mod:`asphalt_nscd.diagnosis.inputs`.

1. noise levels from replicate scatter and
2. data artifacts by forward selection of nested master-curve fits
   (:mod:`asphalt_nscd.diagnosis.effects`), the corrected table and its master curve: read
   (``asphalt-nscd master-curve``, :mod:`asphalt_nscd.diagnosis.artifacts`);
3. baseline: the simulation (``simulated``) or, without it, the macro Burger's fits per
   temperature (``rheology.calibration.fit_table``) against the measured replicate means;
4. model-form and simulation causes (:mod:`asphalt_nscd.diagnosis.causes`);
5. error budget per temperature (MRE of |E*| and Phi and signed bias):
   data artifacts (measured vs corrected), model form (Burger's vs corrected data),
   micro-macro transfer (harmonic response vs its macro law), numerics (time-domain vs
   harmonic);
6. extended law: the temperature-aware generalized Burger's law at the measured
   temperatures (:mod:`asphalt_nscd.rheology.extended`, settings chosen by cross-validation in
   :func:`asphalt_nscd.diagnosis.crossval.fit_extended`), read from the law file the workflow
   wrote with ``asphalt-nscd extend-law`` and ran the NSCD campaign with; its in-sample MRE and
   the gain;
7. held-out errors (``crossval``, rows of ``asphalt-nscd crossval``): the MRE of every model
   on the cells each fold held out, beside the in-sample MRE (:func:`heldout_report`,
   :func:`asphalt_nscd.diagnosis.render.gain_table`, the page). These are the headline numbers: the
   "after" of the gain is in-sample (and the NSCD "after" reproduces its law by construction
   of the transfer correction).

Gain: MRE before -> after per temperature, from two sources, each row labelled:
``nscd`` (time-domain NSCD simulation with the Burger's bond law -> NSCD simulation rerun
with the extended law; only when both simulations are given) and ``macro`` (the macro
Burger's law -> the extended macro law, always). "Before" is against the measured replicate
means, "after" against the artifact-corrected ones (the extended law is calibrated on them);
the "after" against the measured means is reported beside.

Transfer correction: the extended NSCD rows may have run with the bonds calibrated with
E*(w) / NF_s (``run-2pb --network-factor-json``; column ``transfer_network_factor`` of the
rows), NF_s the sample's network factor (:mod:`asphalt_nscd.harmonic.transfer`); the report
says so and gives NF_s. Given the network factors (``transfer``), a third source ``law_only``
is added: the inertia-free harmonic response of the samples with the extended law and no
correction, NF_s E*_law(w) (exact: K(w) = E*(w) G; mean NF_s over the samples, on the
cells of the extended NSCD run, else on every measured cell), before = the primary "before". It
separates the gain of the law (before -> law_only) from the gain of the correction
(law_only -> nscd).

MRE (paper Table 4): mean over the frequencies of an isotherm of |model - data| / data, in
percent, against the replicate means (:mod:`asphalt_nscd.rheology.metrics`); bias: the signed
mean. Temperatures are JSON keys
formatted with ``%g``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError, json_safe
from ..rheology import law_file
from ..rheology.calibration import burgers_model, fit_table
from ..rheology.kramers_kronig import isotherm_residuals
from ..rheology.metrics import cell_means, signed_relative_errors, temperature_key
from . import causes, effects, synthetic
from .artifacts import ArtifactRecord

#: Targets for the extended model, percent (in-sample).
TARGETS = {"E_norm_mre_pct": 3.0, "phase_mre_pct": 5.0}
#: Held-out targets, percent: worst temperature (lofo), worst inner temperature (loto).
HELDOUT_TARGETS = {"lofo": {"E_norm_mre_pct": 5.0, "phase_mre_pct": 6.0},
                   "loto": {"E_norm_mre_pct": 6.0, "phase_mre_pct": 8.0}}


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
    return pd.DataFrame({"mre_E_norm_pct": g["aE"].mean(), "mre_phase_pct": g["aP"].mean(),
                         "bias_E_norm_pct": g["bE"].mean(), "bias_phase_pct": g["bP"].mean(),
                         "n": g.size()})


def cells_from_complex(cells: pd.DataFrame, E) -> pd.DataFrame:
    E = np.asarray(E)
    return pd.DataFrame({"temperature_C": cells["temperature_C"].to_numpy(float),
                         "frequency_Hz": cells["frequency_Hz"].to_numpy(float),
                         "E_norm_MPa": np.abs(E), "phase_deg": np.degrees(np.angle(E))})


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
    return pd.DataFrame({"frequency_Hz": m["frequency_Hz"], "dt_s": m["dt_s"],
                         "phase_error_deg": m["phase_deg"] - m["phase_deg_h"]})


def gain_rows(before: pd.DataFrame, after: pd.DataFrame, after_measured: pd.DataFrame, temps) -> dict:
    """{T key: {"E_norm": {before, after, after_vs_measured}, "phase": {...}}} on common temperatures."""
    out = {}
    for T in temps:
        if T not in after.index or T not in before.index:
            continue
        out[T_key(T)] = {q: {"before": float(before.loc[T, col]), "after": float(after.loc[T, col]),
                            "after_vs_measured": float(after_measured.loc[T, col])
                            if T in after_measured.index else None}
                        for q, col in (("E_norm", "mre_E_norm_pct"), ("phase", "mre_phase_pct"))}
    return out


def targets_met(gain: dict) -> dict:
    return {k: bool(v["E_norm"]["after"] <= TARGETS["E_norm_mre_pct"] and v["phase"]["after"] <= TARGETS["phase_mre_pct"])
            for k, v in gain.items()}


def _by_T(frame: pd.DataFrame, col: str) -> dict:
    return {T_key(T): float(v) for T, v in frame[col].items()}


def diagnose(measured: pd.DataFrame, search: ArtifactRecord, corrected: pd.DataFrame, laws: dict | None,
             simulated: pd.DataFrame | None = None, harmonic: pd.DataFrame | None = None,
             time_errors: pd.DataFrame | None = None, simulated_extended: pd.DataFrame | None = None,
             macro_params: pd.DataFrame | None = None, transfer: dict | None = None,
             crossval: pd.DataFrame | None = None, law_info: dict | None = None, law_failure: str | None = None,
             cause_tolerances: dict | None = None) -> tuple[dict, dict]:
    """Diagnose a measured table from what the earlier steps wrote (and optional simulation
    results); nothing upstream is refitted here.

    Parameters
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
    cause_tolerances : dict, optional
        ``network_factor`` and ``time_integration_deg`` (default :data:`causes.TOLERANCES`).

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
    table = effects.prepare_table(measured)
    master, alpha, shift = search.master, search.alpha, search.shift
    simulated, harmonic = split_simulated(simulated, harmonic)
    if time_errors is None:
        time_errors = derived_time_integration(simulated, harmonic)

    meas_cells = cell_means(table)
    corr_cells = cell_means(corrected)
    burgers_measured = fit_table(table)

    burgers = macro_params if macro_params is not None else burgers_measured
    burgers_cells = cells_from_complex(meas_cells, causes.burgers_predict(
        burgers, meas_cells["temperature_C"], meas_cells["frequency_Hz"]))
    sim_cells, harm_cells = simulation_cells(simulated), simulation_cells(harmonic)

    if sim_cells is not None:
        baseline_model, baseline_cells = "NSCD simulation (time domain, Burger's bond law)", sim_cells
    else:
        baseline_model, baseline_cells = "macro Burger's model (Eqs. 27-29) fitted per temperature", burgers_cells
    base = compare(baseline_cells, meas_cells)

    tol = {**causes.TOLERANCES, **(cause_tolerances or {})}
    entries = [dict(e) for e in search.effects]
    entries.append(causes.broad_spectrum(table, master, burgers_measured, corrected))
    entries.append(causes.static_modulus(corrected, master, alpha))
    transfer_src = harmonic if harmonic is not None else simulated
    entries.append(causes.network_factor(transfer_src, burgers, "harmonic" if harmonic is not None else "simulated",
                                         tolerance=tol["network_factor"]))
    entries.append(causes.time_integration(time_errors, tolerance_deg=tol["time_integration_deg"]))
    order = {"data": 0, "model_form": 1, "simulation": 2}
    named = sorted([e for e in entries if e["detected"]], key=lambda e: -e["score"])

    # error budget
    comps = {"data_artifacts": compare(meas_cells, corr_cells),
             "model_form": compare(burgers_cells, corr_cells),
             "micro_macro_transfer": None, "numerics": None, "total": base}
    if harm_cells is not None:
        hb = cells_from_complex(harm_cells, causes.burgers_predict(burgers, harm_cells["temperature_C"],
                                                                     harm_cells["frequency_Hz"]))
        comps["micro_macro_transfer"] = compare(harm_cells, hb.dropna())
        if sim_cells is not None:
            comps["numerics"] = compare(sim_cells, harm_cells)
    temps = sorted(meas_cells["temperature_C"].unique())
    budget_rows, budget_json = [], {}
    for T in temps:
        budget_json[T_key(T)] = {}
        for name, frame in comps.items():
            if frame is None or T not in frame.index:
                budget_json[T_key(T)][name] = None
                continue
            row = frame.loc[T]
            vals = {k: float(row[k]) for k in ("mre_E_norm_pct", "mre_phase_pct", "bias_E_norm_pct", "bias_phase_pct")}
            budget_json[T_key(T)][name] = vals
            budget_rows.append({"temperature_C": T, "component": name, **vals})
    budget = pd.DataFrame(budget_rows)

    # extended law and gain
    if laws is None:  # the report goes on with the paper's Burger's law per isotherm standing in
        law_failure = f"extended law not computable: {law_failure or 'no law given'}"
        laws = {float(r["temperature_C"]): burgers_model(r, unit=1.0) for _, r in burgers_measured.iterrows()}
    else:
        law_failure = None
        missing = [float(T) for T in temps if temperature_key(laws, T) is None]
        if missing:
            raise InputError(f"extended laws: no law at {missing} degC (the measured temperatures); "
                             f"given: {sorted(laws)}")
        laws = {float(T): laws[temperature_key(laws, T)] for T in temps}
    E_law = law_file.complex_modulus(laws, corr_cells["temperature_C"], corr_cells["frequency_Hz"])
    law_cells = cells_from_complex(corr_cells, E_law)
    law_model = ("generalized Burger's law (Maxwell + N Kelvin-Voigt + static spring) per temperature "
                 "from the 2S2P1D/WLF master curve of the corrected data")
    if law_failure is not None:
        law_model = f"{law_failure}; the macro Burger's law per temperature stands in for it (no gain)"
    ext_sim_cells = simulation_cells(simulated_extended)
    tr = transfer_summary(simulated_extended, transfer)
    nscd_after = "NSCD simulation (time domain, generalized Burger's bond law" + (
        f", transfer correction E*/NF_s, NF_s = {nf_text(tr['network_factor_applied'])})"
        if tr["applied"] else ", no transfer correction)")
    if ext_sim_cells is not None:
        ext_cells, ext_model = ext_sim_cells, nscd_after
    else:
        ext_cells, ext_model = law_cells, law_model
    ext = compare(ext_cells, corr_cells)
    ext_meas = compare(ext_cells, meas_cells)
    law_ext = compare(law_cells, corr_cells)
    law_ext_meas = compare(law_cells, meas_cells)
    macro_before = compare(burgers_cells, meas_cells)
    gain = gain_rows(base, ext, ext_meas, temps)
    sources = {"before": "nscd" if sim_cells is not None else "macro",
               "after": "nscd" if ext_sim_cells is not None else "macro"}
    gain_macro = gain_rows(macro_before, law_ext, law_ext_meas, temps)
    gain_nscd = gain if sources == {"before": "nscd", "after": "nscd"} else None
    met = targets_met(gain)
    gain_law_only, law_only_model = None, None
    if tr["law_only_network_factor"] is not None:
        nf = tr["law_only_network_factor"]
        # on the cells of the extended NSCD run when there is one (same cells as its gain rows)
        cells = ext_sim_cells if ext_sim_cells is not None else corr_cells
        cells = cells[[temperature_key(laws, T) is not None for T in cells["temperature_C"]]]
        E_lo = nf * law_file.complex_modulus(laws, cells["temperature_C"], cells["frequency_Hz"])
        lo_cells = cells_from_complex(cells, E_lo)
        gain_law_only = gain_rows(base, compare(lo_cells, corr_cells), compare(lo_cells, meas_cells), temps)
        law_only_model = ("harmonic response without inertia, generalized Burger's bond law, no transfer "
                          f"correction: NF_s x E*_law, NF_s = {nf_text(tr['network_factor_harmonic'])}")

    kk_T = isotherm_residuals(table)
    kk_ref = synthetic.kk_reference(sorted(table["frequency_Hz"].unique()), int(table["specimen"].nunique()))
    kk_pct = {T_key(T): float(100.0 * np.mean(kk_ref <= v)) for T, v in kk_T.items()}
    core = master.core()
    report = {
        "measured": {"n_rows": int(len(measured)), "n_specimens": int(measured["specimen"].nunique()),
                     "temperatures_C": [float(T) for T in temps],
                     "frequencies_Hz": sorted(float(f) for f in measured["frequency_Hz"].unique())},
        "noise": {"sigma_lnE": search.sigma[0], "sigma_phase_deg": search.sigma[1],
                  "from_replicates": search.noise_from_replicates},
        "artifact_screening": search.screening,
        "master_curve": {"model": "2S2P1D", "shift": shift, "T_ref_C": master.T_ref_C,
                         "parameters": {k: float(v) for k, v in core.items()},
                         "log10_aT": {T_key(T): float(master.log_shift(T)) for T in temps},
                         "chi2_per_dof": master.rss / max(master.n_residuals - master.n_params, 1)},
        "kramers_kronig_mean_abs_residual_deg": {T_key(T): float(v) for T, v in kk_T.items()},
        "kramers_kronig_percentile": kk_pct,
        "kramers_kronig_reference": {"n_isotherms": int(kk_ref.size), "median_deg": float(np.median(kk_ref)),
                                     "p99_deg": float(np.percentile(kk_ref, 99)), "max_deg": float(kk_ref.max()),
                                     "source": "clean synthetic tables of every truth family (causal laws) at the "
                                               "table's frequencies and replicate count"},
        "baseline": {"model": baseline_model, "reference": "measured replicate means",
                     "mre_E_norm_pct": _by_T(base, "mre_E_norm_pct"), "mre_phase_pct": _by_T(base, "mre_phase_pct"),
                     "bias_E_norm_pct": _by_T(base, "bias_E_norm_pct"), "bias_phase_pct": _by_T(base, "bias_phase_pct")},
        "error_budget": budget_json,
        "effects": sorted(entries, key=lambda e: order[e["category"]]),
        "causes": [e["name"] for e in named],
        "extended": {"model": ext_model, "law": law_model,
                     "reference": "artifact-corrected measured replicate means",
                     "parameters": law_file.to_json(laws)["temperatures"],
                     "parameter_units": {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"},
                     "mre_E_norm_pct": _by_T(ext, "mre_E_norm_pct"), "mre_phase_pct": _by_T(ext, "mre_phase_pct"),
                     "mre_E_norm_pct_vs_measured": _by_T(ext_meas, "mre_E_norm_pct"),
                     "mre_phase_pct_vs_measured": _by_T(ext_meas, "mre_phase_pct"),
                     "law_mre_E_norm_pct": _by_T(law_ext, "mre_E_norm_pct"),
                     "law_mre_phase_pct": _by_T(law_ext, "mre_phase_pct"),
                     "selection": (law_info or {}).get("selection"),
                     "T_ref_C": ((law_info or {}).get("model") or {}).get("T_ref_C")},
        "gain": gain,
        "gain_sources": {**sources,
                         "models": {"nscd": {"before": "NSCD simulation (time domain, Burger's bond law)",
                                             "after": nscd_after},
                                    "macro": {"before": "macro Burger's model (Eqs. 27-29) per temperature",
                                              "after": law_model},
                                    "law_only": {"before": baseline_model, "after": law_only_model}},
                         "reference": {"before": "measured replicate means",
                                       "after": "artifact-corrected measured replicate means"}},
        "gain_nscd": gain_nscd,
        "gain_macro": gain_macro,
        "gain_law_only": gain_law_only,
        "transfer": tr,
        "heldout": heldout_report(crossval, measured) if crossval is not None else None,
        "targets": {**TARGETS, "met": met, "met_macro": targets_met(gain_macro),
                    "met_nscd": targets_met(gain_nscd) if gain_nscd is not None else None,
                    "met_law_only": targets_met(gain_law_only) if gain_law_only is not None else None},
    }
    report = json_safe(report)
    extra = {"laws": laws, "corrected": corrected, "budget": budget, "master": master}
    return report, extra


def target_verdict(value: float, low: float, high: float, target: float) -> str:
    """A held-out MRE against its target, judged with its 95 % interval: ``met`` (the interval
    lies below the target), ``missed`` (above), ``undecided`` (the target lies inside the
    interval: within the measured reference's own noise); without an interval, ``met`` or
    ``missed`` by the point value."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return "met" if value <= target else "missed"
    return "met" if high <= target else "missed" if low > target else "undecided"


def heldout_report(rows: pd.DataFrame, measured: pd.DataFrame | None = None) -> dict:
    """The ``heldout`` block of the report from crossval rows.

    ``mre``: {scheme: {kind: {model: {T: {E_norm_mre_pct, phase_mre_pct, n_cells,
    n_not_computable, extrapolation, and with ``measured`` E_norm_ci95, phase_ci95 (bootstrap
    over specimens) and the noise floor}}}}}; ``headline``: worst temperature per scheme, kind
    and model (:func:`asphalt_nscd.diagnosis.crossval.headline`) with the held-out targets,
    whether they are met by the point values (``targets_met``) and judged against the
    interval (``verdict_E_norm``, ``verdict_phase``: :func:`target_verdict`); ``reference``
    and ``protocol`` (text).
    """
    from .crossval import headline, summarize

    summ = summarize(rows, measured)
    mre = {}
    for _, r in summ.iterrows():
        mre.setdefault(r["scheme"], {}).setdefault(r["kind"], {}).setdefault(r["model"], {})[T_key(r["temperature_C"])] = {
            "E_norm_mre_pct": r["mre_E_norm_pct"], "phase_mre_pct": r["mre_phase_pct"], "n_cells": int(r["n_cells"]),
            "n_not_computable": int(r["n_not_computable"]), "extrapolation": bool(r["extrapolation"]),
            "E_norm_ci95_pct": [r["mre_E_norm_ci95_low"], r["mre_E_norm_ci95_high"]],
            "phase_ci95_pct": [r["mre_phase_ci95_low"], r["mre_phase_ci95_high"]],
            "noise_floor_E_norm_pct": r["noise_floor_E_norm_pct"], "noise_floor_phase_pct": r["noise_floor_phase_pct"]}
    heads = []
    # the time-domain model holds one cell (the agreement check below), not a headline
    for _, h in headline(summ[summ["model"] != "nscd_time_domain"]).iterrows():
        d = h.to_dict()
        t = HELDOUT_TARGETS.get(d["scheme"]) if d["kind"] == "held_out" else None
        d["targets"] = t
        d["targets_met"] = (None if t is None else bool(d["worst_E_norm_pct"] <= t["E_norm_mre_pct"]
                                                        and d["worst_phase_pct"] <= t["phase_mre_pct"]))
        if t is not None:
            d["verdict_E_norm"] = target_verdict(d["worst_E_norm_pct"], d.get("worst_E_norm_ci95_low", np.nan),
                                                 d.get("worst_E_norm_ci95_high", np.nan), t["E_norm_mre_pct"])
            d["verdict_phase"] = target_verdict(d["worst_phase_pct"], d.get("worst_phase_ci95_low", np.nan),
                                                d.get("worst_phase_ci95_high", np.nan), t["phase_mre_pct"])
        heads.append(d)
    td = []
    held = rows[(rows["kind"] == "held_out") & rows["computable"]]
    keys = ["scheme", "fold", "temperature_C", "frequency_Hz"]
    both = held[held["model"] == "nscd_time_domain"].merge(held[held["model"] == "nscd_sample"], on=keys,
                                                           suffixes=("_td", "_h"))
    for _, r in both.iterrows():
        td.append({"scheme": r["scheme"], "fold": str(r["fold"]), "temperature_C": r["temperature_C"],
                   "frequency_Hz": r["frequency_Hz"], "E_norm_MPa_time_domain": r["E_norm_MPa_predicted_td"],
                   "E_norm_MPa_harmonic": r["E_norm_MPa_predicted_h"],
                   "phase_deg_time_domain": r["phase_deg_predicted_td"], "phase_deg_harmonic": r["phase_deg_predicted_h"],
                   "E_norm_relative_difference": r["E_norm_MPa_predicted_td"] / r["E_norm_MPa_predicted_h"] - 1.0,
                   "phase_difference_deg": r["phase_deg_predicted_td"] - r["phase_deg_predicted_h"]})
    return json_safe({"mre": mre, "headline": heads, "time_domain_check": td,
                      "reference": "measured replicate means as given",
                      "protocol": "lofo: every row at one frequency left out; loto: one isotherm left out "
                                  "(the end temperatures are extrapolations, reported apart); the whole procedure "
                                  "(artifact correction, nested selection of the settings, law) refitted without "
                                  "the held-out rows; MRE per temperature over its held-out cells"})


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
                raise InputError("extended NSCD rows: column 'transfer_network_factor' is empty or not a number "
                                 "on some rows (rows with and without the transfer correction are mixed)")
            for name, values in nf.groupby(samples):
                if not np.allclose(values, values.iloc[0], rtol=1e-12, atol=0):
                    raise InputError(f"extended NSCD rows: sample {name!r} ran with several network factors "
                                     f"{sorted(set(values.round(12)))}")
                per_sample[str(name)] = float(values.iloc[0])
    given = {str(k): float(v) for k, v in (transfer or {}).items()}
    for name, v in per_sample.items():
        if name in given and not np.isclose(v, given[name], rtol=1e-9, atol=0):
            raise InputError(f"extended NSCD rows: sample {name!r} ran with network factor {v:.10g} but the "
                             f"transfer JSON gives {given[name]:.10g} (stale simulation or JSON)")
    harmonic = given or dict(per_sample)
    return {"applied": applied, "network_factor_applied": per_sample or None,
            "network_factor_applied_mean": float(np.mean(list(per_sample.values()))) if per_sample else None,
            "network_factor_harmonic": harmonic or None,
            "law_only_network_factor": float(np.mean(list(harmonic.values()))) if harmonic else None,
            "definition": "NF_s = sample |E*| / macro |E*| without inertia (harmonic solver, real, law "
                          "independent); transfer correction: bonds calibrated with E*(w) / NF_s"}
