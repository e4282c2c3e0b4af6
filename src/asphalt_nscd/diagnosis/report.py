"""What the simulation gets wrong: error budget, named causes, extended law and gain.

:func:`diagnose` runs the whole chain on a measured table and returns the JSON report of
``asphalt-nscd diagnose``:

1. noise levels from replicate scatter (:func:`rheology.master_curve.replicate_noise`);
2. data artifacts by forward selection of nested master-curve fits
   (:mod:`asphalt_nscd.diagnosis.effects`), and the corrected table;
3. baseline: the simulation (``simulated``) or, without it, the macro Burger's fits per
   temperature (``rheology.calibration.fit_table``) against the measured replicate means;
4. model-form and simulation causes (:mod:`asphalt_nscd.diagnosis.causes`);
5. error budget per temperature (MRE of |E*| and Phi and signed bias):
   data artifacts (measured vs corrected), model form (Burger's vs corrected data),
   micro-macro transfer (harmonic response vs its macro law), numerics (time-domain vs
   harmonic);
6. extended law: a generalized Burger's law per temperature from the 2S2P1D/WLF master
   curve of the corrected data (:mod:`asphalt_nscd.diagnosis.extend`), its MRE and the gain.

MRE (paper Table 4): mean over the frequencies of an isotherm of |model - data| / data, in
percent, against the replicate means; bias: the signed mean. Temperatures are JSON keys
formatted with ``%g``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError
from ..rheology.master_curve import fit_master_curve
from ..rheology.kramers_kronig import kk_residuals
from . import causes, effects, extend

#: Targets of the issue for the extended model, percent.
TARGETS = {"E_norm_mre_pct": 3.0, "phase_mre_pct": 5.0}
SIM_COLUMNS = ("temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg")


def _key(T) -> str:
    return f"{float(T):g}"


def compare(model: pd.DataFrame, data: pd.DataFrame) -> pd.DataFrame:
    """Per-temperature MRE and bias (%) of ``model`` against ``data`` (both cell tables with
    ``temperature_C, frequency_Hz, E_norm_MPa, phase_deg``), on their common cells."""
    m = model.merge(data, on=["temperature_C", "frequency_Hz"], suffixes=("_m", "_d"))
    rE = m["E_norm_MPa_m"] / m["E_norm_MPa_d"] - 1.0
    rP = m["phase_deg_m"] / m["phase_deg_d"] - 1.0
    m = m.assign(aE=100 * rE.abs(), aP=100 * rP.abs(), bE=100 * rE, bP=100 * rP)
    g = m.groupby("temperature_C")
    return pd.DataFrame({"mre_E_norm_pct": g["aE"].mean(), "mre_phase_pct": g["aP"].mean(),
                         "bias_E_norm_pct": g["bE"].mean(), "bias_phase_pct": g["bP"].mean(),
                         "n": g.size()})


def _cells_from_complex(cells: pd.DataFrame, E) -> pd.DataFrame:
    E = np.asarray(E)
    return pd.DataFrame({"temperature_C": cells["temperature_C"].to_numpy(float),
                         "frequency_Hz": cells["frequency_Hz"].to_numpy(float),
                         "E_norm_MPa": np.abs(E), "phase_deg": np.degrees(np.angle(E))})


def read_simulated(path) -> pd.DataFrame:
    """Read a simulated/harmonic result table (reduced complex-modulus rows).

    Raises InputError naming the file and the missing column or bad row.
    """
    try:
        df = pd.read_csv(path)
    except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a readable CSV file ({exc})") from None
    missing = [c for c in SIM_COLUMNS if c not in df.columns]
    if missing:
        raise InputError(f"{path}: line 1 (header): missing column(s) {missing}; expected {list(SIM_COLUMNS)}")
    for c in SIM_COLUMNS:
        v = pd.to_numeric(df[c], errors="coerce")
        bad = np.flatnonzero(~np.isfinite(v.to_numpy(float)))
        if bad.size:
            raise InputError(f"{path}: line {bad[0] + 2}, column '{c}': expected a finite number")
        df[c] = v.astype(float)
    bad = np.flatnonzero((df["E_norm_MPa"] <= 0).to_numpy() | (df["frequency_Hz"] <= 0).to_numpy())
    if bad.size:
        raise InputError(f"{path}: line {bad[0] + 2}: E_norm_MPa and frequency_Hz must be > 0")
    return df


def _sim_cells(df: pd.DataFrame | None) -> pd.DataFrame | None:
    if df is None or len(df) == 0:
        return None
    return (df.groupby(["temperature_C", "frequency_Hz"], as_index=False)
            .agg(E_norm_MPa=("E_norm_MPa", "mean"), phase_deg=("phase_deg", "mean")))


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
    h = _sim_cells(harmonic)
    s = sim.groupby(["temperature_C", "frequency_Hz", "dt_s"], as_index=False)["phase_deg"].mean()
    m = s.merge(h, on=["temperature_C", "frequency_Hz"], suffixes=("", "_h"))
    if len(m) < 2:
        return None
    return pd.DataFrame({"frequency_Hz": m["frequency_Hz"], "dt_s": m["dt_s"],
                         "phase_error_deg": m["phase_deg"] - m["phase_deg_h"]})


def _by_T(frame: pd.DataFrame, col: str) -> dict:
    return {_key(T): float(v) for T, v in frame[col].items()}


def diagnose(measured: pd.DataFrame, simulated: pd.DataFrame | None = None,
             harmonic: pd.DataFrame | None = None, time_errors: pd.DataFrame | None = None,
             simulated_extended: pd.DataFrame | None = None, macro_params: pd.DataFrame | None = None,
             alpha: float = 1e-3, shift: str = "wlf", T_ref_C: float | None = None,
             per_decade: float = 2.0, margin_decades: float = 1.0, refine: bool = True,
             prior_weight: float = 0.01) -> tuple[dict, dict]:
    """Diagnose a measured table (and optional simulation results).

    Parameters
    ----------
    measured : DataFrame
        Validated measured table (``lab.measured.load_measured``).
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
        Ek_MPa, eta_k_MPa_s``); default: fitted here to the measured table.
    alpha : float
        Significance level of every test.
    shift, T_ref_C : master-curve shift law and reference temperature.
    per_decade, margin_decades, refine, prior_weight : see :func:`extend.calibrate`.

    Returns
    -------
    (report, extra)
        ``report``: the JSON-serialisable report; ``extra``: ``laws`` (dict T ->
        GeneralizedBurgers in MPa), ``corrected`` (DataFrame), ``budget`` (DataFrame),
        ``master`` (MasterCurveFit).

    Raises
    ------
    InputError
        if the measured table has fewer than 2 temperatures or 3 frequencies per isotherm.
    """
    n_T = measured["temperature_C"].nunique()
    if n_T < 2 or measured.groupby("temperature_C")["frequency_Hz"].nunique().min() < 3:
        raise InputError("measured table: need >= 2 temperatures and >= 3 frequencies per temperature")
    simulated, harmonic = split_simulated(simulated, harmonic)
    if time_errors is None:
        time_errors = derived_time_integration(simulated, harmonic)

    search = effects.ArtifactSearch(measured, alpha=alpha, T_ref_C=T_ref_C, shift=shift)
    result = search.run()
    final = result["final"]
    corrected = search.corrected(final)
    master = fit_master_curve(corrected, shift=shift, T_ref_C=final.T_ref_C, sigma=search.sigma,
                              x0=final.x[:len(final.x) - sum(len(t.names) for t in final.terms)])

    meas_cells = causes.cell_means(search.df)
    corr_cells = causes.cell_means(corrected)
    burgers = macro_params if macro_params is not None else causes.burgers_table(search.df)
    burgers_cells = _cells_from_complex(meas_cells, causes.burgers_predict(
        burgers, meas_cells["temperature_C"], meas_cells["frequency_Hz"]))
    sim_cells, harm_cells = _sim_cells(simulated), _sim_cells(harmonic)

    if sim_cells is not None:
        baseline_model, baseline_cells = "NSCD simulation (time domain, Burger's bond law)", sim_cells
    else:
        baseline_model, baseline_cells = "macro Burger's model (Eqs. 27-29) fitted per temperature", burgers_cells
    base = compare(baseline_cells, meas_cells)

    entries = effects.effect_entries(search, result)
    entries.append(causes.broad_spectrum(corrected, master, causes.burgers_table(corrected), alpha))
    entries.append(causes.static_modulus(corrected, master, alpha))
    transfer_src = harmonic if harmonic is not None else simulated
    entries.append(causes.network_factor(transfer_src, burgers, alpha,
                                         "harmonic" if harmonic is not None else "simulated"))
    entries.append(causes.time_integration(time_errors, alpha))
    order = {"data": 0, "model_form": 1, "simulation": 2}
    named = sorted([e for e in entries if e["detected"]], key=lambda e: -e["score"])

    # error budget
    comps = {"data_artifacts": compare(meas_cells, corr_cells),
             "model_form": compare(burgers_cells, corr_cells),
             "micro_macro_transfer": None, "numerics": None, "total": base}
    if harm_cells is not None:
        hb = _cells_from_complex(harm_cells, causes.burgers_predict(burgers, harm_cells["temperature_C"],
                                                                     harm_cells["frequency_Hz"]))
        comps["micro_macro_transfer"] = compare(harm_cells, hb.dropna())
        if sim_cells is not None:
            comps["numerics"] = compare(sim_cells, harm_cells)
    temps = sorted(meas_cells["temperature_C"].unique())
    budget_rows, budget_json = [], {}
    for T in temps:
        budget_json[_key(T)] = {}
        for name, frame in comps.items():
            if frame is None or T not in frame.index:
                budget_json[_key(T)][name] = None
                continue
            row = frame.loc[T]
            vals = {k: float(row[k]) for k in ("mre_E_norm_pct", "mre_phase_pct", "bias_E_norm_pct", "bias_phase_pct")}
            budget_json[_key(T)][name] = vals
            budget_rows.append({"temperature_C": T, "component": name, **vals})
    budget = pd.DataFrame(budget_rows)

    # extended law and gain
    laws = extend.calibrate(master, corrected, per_decade=per_decade, margin_decades=margin_decades,
                            refine=refine, prior_weight=prior_weight)
    if simulated_extended is not None:
        ext_cells = _sim_cells(simulated_extended)
        ext_model = "NSCD simulation with the generalized Burger's bond law"
    else:
        E = np.array([laws[float(T)].complex_modulus(2 * np.pi * f)
                      for T, f in zip(corr_cells["temperature_C"], corr_cells["frequency_Hz"])])
        ext_cells = _cells_from_complex(corr_cells, E)
        ext_model = ("generalized Burger's law (Maxwell + N Kelvin-Voigt + static spring) per temperature "
                     "from the 2S2P1D/WLF master curve of the corrected data")
    ext = compare(ext_cells, corr_cells)
    ext_meas = compare(ext_cells, meas_cells)
    gain = {}
    for T in temps:
        if T not in ext.index or T not in base.index:
            continue
        gain[_key(T)] = {"E_norm": {"before": float(base.loc[T, "mre_E_norm_pct"]),
                                    "after": float(ext.loc[T, "mre_E_norm_pct"])},
                         "phase": {"before": float(base.loc[T, "mre_phase_pct"]),
                                   "after": float(ext.loc[T, "mre_phase_pct"])}}
    met = {k: bool(v["E_norm"]["after"] <= TARGETS["E_norm_mre_pct"] and v["phase"]["after"] <= TARGETS["phase_mre_pct"])
           for k, v in gain.items()}

    kk = kk_residuals(search.df)
    kk_T = kk.groupby("temperature_C")["phase_kk_residual_deg"].agg(lambda r: float(np.mean(np.abs(r))))
    core = master.core()
    report = {
        "measured": {"n_rows": int(len(measured)), "n_specimens": int(measured["specimen"].nunique()),
                     "temperatures_C": [float(T) for T in temps],
                     "frequencies_Hz": sorted(float(f) for f in measured["frequency_Hz"].unique())},
        "noise": {"sigma_lnE": search.sigma[0], "sigma_phase_deg": search.sigma[1],
                  "from_replicates": search.noise_from_replicates},
        "master_curve": {"model": "2S2P1D", "shift": shift, "T_ref_C": master.T_ref_C,
                         "parameters": {k: float(v) for k, v in core.items()},
                         "log10_aT": {_key(T): float(master.log_shift(T)) for T in temps},
                         "chi2_per_dof": master.rss / max(master.n_residuals - master.n_params, 1)},
        "kramers_kronig_mean_abs_residual_deg": {_key(T): float(v) for T, v in kk_T.items()},
        "baseline": {"model": baseline_model, "reference": "measured replicate means",
                     "mre_E_norm_pct": _by_T(base, "mre_E_norm_pct"), "mre_phase_pct": _by_T(base, "mre_phase_pct"),
                     "bias_E_norm_pct": _by_T(base, "bias_E_norm_pct"), "bias_phase_pct": _by_T(base, "bias_phase_pct")},
        "error_budget": budget_json,
        "effects": sorted(entries, key=lambda e: order[e["category"]]),
        "causes": [e["name"] for e in named],
        "extended": {"model": ext_model, "reference": "artifact-corrected measured replicate means",
                     "parameters": extend.laws_to_json(laws)["temperatures"],
                     "parameter_units": {"Em": "Pa", "eta_m": "Pa s", "Ek": "Pa", "eta_k": "Pa s", "E_inf": "Pa"},
                     "mre_E_norm_pct": _by_T(ext, "mre_E_norm_pct"), "mre_phase_pct": _by_T(ext, "mre_phase_pct"),
                     "mre_E_norm_pct_vs_measured": _by_T(ext_meas, "mre_E_norm_pct"),
                     "mre_phase_pct_vs_measured": _by_T(ext_meas, "mre_phase_pct")},
        "gain": gain,
        "targets": {**TARGETS, "met": met},
    }
    report = json_safe(report)
    extra = {"laws": laws, "corrected": corrected, "budget": budget, "master": master,
             "mre_E": {float(T): float(v) for T, v in ext["mre_E_norm_pct"].items()},
             "mre_phase": {float(T): float(v) for T, v in ext["mre_phase_pct"].items()}}
    return report, extra


def json_safe(obj):
    """Recursively turn NumPy scalars into Python ones and non-finite floats into None."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def budget_figure(budget: pd.DataFrame, path) -> None:
    """Stacked bars of the error budget per temperature (top Phi, bottom |E*| MRE), saved to
    ``path`` atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import savefig

    comps = ["data_artifacts", "model_form", "micro_macro_transfer", "numerics"]
    temps = sorted(budget["temperature_C"].unique()) if len(budget) else []
    fig, axes = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    x = np.arange(len(temps))
    for ax, col, label in zip(axes, ["mre_phase_pct", "mre_E_norm_pct"], ["MRE of Phi (%)", "MRE of |E*| (%)"]):
        bottom = np.zeros(len(temps))
        for c in comps:
            sub = budget[budget["component"] == c].set_index("temperature_C")
            vals = np.array([sub[col].get(T, 0.0) if len(sub) else 0.0 for T in temps], float)
            ax.bar(x, vals, bottom=bottom, label=c.replace("_", " "))
            bottom += vals
        tot = budget[budget["component"] == "total"].set_index("temperature_C")
        if len(tot):
            ax.plot(x, [tot[col].get(T, np.nan) for T in temps], "k_", markersize=30, mew=2,
                    label="total (simulation vs measured)")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[1].set_xticks(x, [f"{T:g}" for T in temps])
    axes[1].set_xlabel("temperature (degC)")
    fig.suptitle("Error budget of the simulation per temperature")
    savefig(fig, path)
    plt.close(fig)


def markdown_page(report: dict, figure: str | None = None) -> str:
    """The report page "What the simulation gets wrong" (Markdown) from a diagnose report."""
    lines = ["# What the simulation gets wrong", "",
             f"Baseline: {report['baseline']['model']}, against the {report['baseline']['reference']}.",
             f"Extension: {report['extended']['model']}, against the {report['extended']['reference']}.", "",
             "| T (degC) | MRE \\|E*\\| before (%) | after (%) | MRE Phi before (%) | after (%) | targets met |",
             "|---|---|---|---|---|---|---|"]
    for T, g in report["gain"].items():
        lines.append(f"| {T} | {g['E_norm']['before']:.2f} | {g['E_norm']['after']:.2f} | "
                     f"{g['phase']['before']:.2f} | {g['phase']['after']:.2f} | {report['targets']['met'][T]} |")
    lines += ["", f"Targets: |E*| MRE <= {report['targets']['E_norm_mre_pct']:g} %, "
              f"Phi MRE <= {report['targets']['phase_mre_pct']:g} %.", "", "## Named causes (most important first)", ""]
    by = {e["name"]: e for e in report["effects"]}
    if not report["causes"]:
        lines.append("None at the chosen significance level.")
    for name in report["causes"]:
        e = by[name]
        p = "n/a" if e["p_value"] is None else f"{e['p_value']:.2g}"
        lines.append(f"- **{name}** ({e['category']}, p = {p}, score {e['score']:.2f}): {e['evidence']}")
    lines += ["", "## Candidates not named", ""]
    for e in report["effects"]:
        if not e["detected"]:
            p = "" if e["p_value"] is None else f" (p = {e['p_value']:.2g})"
            lines.append(f"- {e['name']}{p}: {e['evidence']}")
    kk = report.get("kramers_kronig_mean_abs_residual_deg", {})
    if kk:
        lines += ["", "Kramers-Kronig consistency of the measured isotherms (mean |Phi - Phi_Booij-Thoone|, deg): "
                  + ", ".join(f"{T} degC: {v:.2f}" for T, v in kk.items())
                  + ". A value well above the approximation's own error (1-2 deg for mixes) points to an "
                  "isotherm whose |E*| and Phi no causal linear viscoelastic law matches together."]
    lines += ["", "## Error budget (MRE %, \\|E*\\| / Phi)", "",
              "| T (degC) | data artifacts | model form | micro-macro transfer | numerics | total |",
              "|---|---|---|---|---|---|"]
    for T, comp in report["error_budget"].items():
        cells = []
        for c in ("data_artifacts", "model_form", "micro_macro_transfer", "numerics", "total"):
            v = comp.get(c)
            cells.append("n/a" if v is None else f"{v['mre_E_norm_pct']:.2f} / {v['mre_phase_pct']:.2f}")
        lines.append(f"| {T} | " + " | ".join(cells) + " |")
    if figure:
        lines += ["", f"![error budget]({figure})"]
    return "\n".join(lines) + "\n"
