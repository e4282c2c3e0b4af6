"""What the simulation gets wrong, rendered: the gain and cause tables, the error-budget figure
and the report page, from the report that :func:`asphalt_nscd.diagnosis.budget.diagnose`
computed (nothing is computed here but formatting).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import effects
from .budget import T_key, nf_text, targets_met

#: crossval model of the held-out "after" (and "before") of each gain source
HELDOUT_MODELS = {"macro": ("burgers", "extended_law"), "nscd": (None, "nscd_sample"),
                  "law_only": (None, None)}


def _heldout_value(report: dict, scheme: str, model: str | None, T: str, q: str):
    h = report.get("heldout") or {}
    try:
        return h["mre"][scheme]["held_out"][model][T][q]
    except (KeyError, TypeError):
        return None


def gain_table(report: dict) -> pd.DataFrame:
    """The gain table of a diagnose report: one row per temperature and source.

    Columns: ``temperature_C, source`` (``nscd``: NSCD simulation before and after; ``macro``:
    macro laws; ``nscd_before_macro_after`` / ``macro_before_nscd_after`` when only one
    simulation was given; ``law_only``: the extended law without the transfer correction,
    NF_s E*_law, when the network factors are known), ``before_model, after_model``,
    ``transfer_correction`` (the "after" includes the transfer correction E*/NF_s),
    ``network_factor`` (mean NF_s of the "after": applied, or multiplied in for ``law_only``;
    empty when none), ``E_norm_mre_before_pct,
    E_norm_mre_after_pct, phase_mre_before_pct, phase_mre_after_pct`` (before: against the
    measured replicate means; after: against the artifact-corrected ones, %),
    ``E_norm_mre_after_vs_measured_pct, phase_mre_after_vs_measured_pct`` and
    ``targets_met`` (after-MREs within the targets). The "after" columns are in-sample (the
    law was fitted on every cell). With crossval rows in the report (``heldout``), the held-out
    MREs of the matching crossval model beside them: ``heldout_before_model``,
    ``heldout_after_model`` (``burgers`` / ``extended_law`` for ``macro``, ``nscd_sample`` for
    ``nscd``; empty when there is none), ``{E_norm,phase}_mre_{before,after}_heldout_{lofo,loto}_pct``
    (against the measured means) and ``loto_extrapolation`` (the temperature is an end of the
    tested range).
    """
    src = report["gain_sources"]
    models = src["models"]
    blocks = []
    primary = "nscd" if src["before"] == src["after"] == "nscd" else (
        "macro" if src["before"] == src["after"] == "macro" else f"{src['before']}_before_{src['after']}_after")
    blocks.append((primary, report["gain"], models[src["before"]]["before"], models[src["after"]]["after"]))
    if primary != "macro":
        blocks.append(("macro", report["gain_macro"], models["macro"]["before"], models["macro"]["after"]))
    if report.get("gain_law_only") is not None:
        blocks.append(("law_only", report["gain_law_only"], models["law_only"]["before"],
                       models["law_only"]["after"]))
    tr = report.get("transfer") or {}
    applied = bool(tr.get("applied"))
    rows = []
    for source, gain, before_model, after_model in blocks:
        met = targets_met(gain)
        nscd_after = source == "nscd" or source.endswith("_nscd_after")
        corrected = nscd_after and applied
        nf = (tr.get("network_factor_applied_mean") if corrected else
              tr.get("law_only_network_factor") if source == "law_only" else None)
        base = source.split("_before_")[-1].replace("_after", "") if "_before_" in source else source
        hb, ha = HELDOUT_MODELS.get(base, (None, None))
        if "_before_" in source:
            hb = HELDOUT_MODELS[source.split("_before_")[0]][0]
        for T, g in gain.items():
            held = {}
            if report.get("heldout") is not None:
                held = {"heldout_before_model": hb or "", "heldout_after_model": ha or ""}
                for when, model in (("before", hb), ("after", ha)):
                    for scheme in ("lofo", "loto"):
                        for q, key in (("E_norm", "E_norm_mre_pct"), ("phase", "phase_mre_pct")):
                            v = _heldout_value(report, scheme, model, T, key) if model else None
                            held[f"{q}_mre_{when}_heldout_{scheme}_pct"] = np.nan if v is None else float(v)
                loto = ((report["heldout"]["mre"].get("loto") or {}).get("held_out") or {})
                ext = next((m[T]["extrapolation"] for m in loto.values() if T in m), None)
                held["loto_extrapolation"] = ext
            rows.append({"temperature_C": float(T), "source": source, "before_model": before_model,
                         "after_model": after_model, "transfer_correction": corrected,
                         "network_factor": np.nan if nf is None else float(nf),
                         "E_norm_mre_before_pct": g["E_norm"]["before"], "E_norm_mre_after_pct": g["E_norm"]["after"],
                         "phase_mre_before_pct": g["phase"]["before"], "phase_mre_after_pct": g["phase"]["after"],
                         "E_norm_mre_after_vs_measured_pct": g["E_norm"]["after_vs_measured"],
                         "phase_mre_after_vs_measured_pct": g["phase"]["after_vs_measured"],
                         "targets_met": met[T], **held})
    return pd.DataFrame(rows)


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


def _bracket(v) -> str:
    """`` (v)`` with 2 decimals, or nothing for a missing value."""
    return "" if v is None or v != v else f" ({v:.2f})"


HELDOUT_LABELS = {"burgers": "Burger's per isotherm (paper)", "extended_law": "extended law",
                  "nscd_sample": "NSCD sample (harmonic, law / NF_s)",
                  "nscd_time_domain": "NSCD sample (time domain, one fold)"}


def _pair(d: dict | None) -> str:
    """``E [lo-hi] / Phi [lo-hi]`` of one MRE entry (the intervals where the report has them)."""
    if not d or d.get("E_norm_mre_pct") is None:
        return "n/a"

    def one(value, ci):
        ok = ci is not None and len(ci) == 2 and all(v is not None and np.isfinite(v) for v in ci)
        return f"{value:.2f}" + (f" [{ci[0]:.2f}-{ci[1]:.2f}]" if ok else "")

    return f"{one(d['E_norm_mre_pct'], d.get('E_norm_ci95_pct'))} / {one(d['phase_mre_pct'], d.get('phase_ci95_pct'))}"


def _ci(d: dict, prefix: str) -> str:
    """``[lo-hi] (floor f)`` of a headline entry's interval and noise floor (%), or ''."""
    lo, hi, fl = (d.get(f"{prefix}_{k}") for k in ("ci95_low", "ci95_high", "noise_floor_pct"))
    text = f"[{lo:.2f}-{hi:.2f}]" if lo is not None and hi is not None and np.isfinite(lo) and np.isfinite(hi) else ""
    if fl is not None and np.isfinite(fl):
        text += f" (floor {fl:.2f})"
    return text


def heldout_lines(report: dict) -> list:
    """Markdown lines of the held-out headline (empty without crossval rows in the report)."""
    h = report.get("heldout")
    if not h:
        return []
    mre = h["mre"]
    lines = ["## Held-out errors (headline; MRE %, norm of E* / Phi, against the measured means)", "",
             "Each fold refits the whole procedure (artifact correction, nested choice of the law's settings, "
             "law) without its held-out rows: *lofo* leaves one frequency out at every temperature, *loto* "
             "one isotherm (the end temperatures are extrapolations, marked *extrap.*). *In-sample*: the "
             "same model fitted on every cell. Brackets: the 95 % interval of each MRE by a bootstrap over "
             "the specimens (the reference means resampled, the predictions kept); *floor*: the noise floor "
             "of the reference at that temperature, the mean relative standard error of the replicate "
             "means. A target is *met* when the interval lies below it, *missed* when above, *undecided* "
             "when it lies inside.", ""]
    heads = [x for x in h["headline"] if x["kind"] == "held_out"]
    if heads:
        lines += ["| scheme | model | worst T: MRE norm of E* [95 % CI] (floor) | worst T: MRE Phi [95 % CI] "
                  "(floor) | held-out target | verdict E* / Phi |", "|---|---|---|---|---|---|"]
        for x in heads:
            t = x.get("targets") or {}
            tgt = f"<= {t['E_norm_mre_pct']:g} / {t['phase_mre_pct']:g}" if t else "n/a"
            where = "inner temperatures" if x["scheme"] == "loto" else "all temperatures"
            verdict = f"{x.get('verdict_E_norm', 'n/a')} / {x.get('verdict_phase', 'n/a')}"
            lines.append(f"| {x['scheme']} ({where}) | {HELDOUT_LABELS.get(x['model'], x['model'])} | "
                         f"{x['worst_E_norm_pct']:.2f} {_ci(x, 'worst_E_norm')} ({x['worst_E_norm_T_C']:g} degC) | "
                         f"{x['worst_phase_pct']:.2f} {_ci(x, 'worst_phase')} ({x['worst_phase_T_C']:g} degC) | "
                         f"{tgt} | {verdict} |")
        lines.append("")
    for t in h.get("time_domain_check") or []:
        lines += [f"Time domain vs harmonic solution of the NSCD sample with the law of the {t['scheme']} fold "
                  f"{t['fold']} at {t['temperature_C']:g} degC, {t['frequency_Hz']:g} Hz (held out): norm of E* "
                  f"{t['E_norm_MPa_time_domain']:.5g} vs {t['E_norm_MPa_harmonic']:.5g} MPa "
                  f"({100 * t['E_norm_relative_difference']:+.3f} %), Phi {t['phase_deg_time_domain']:.3f} vs "
                  f"{t['phase_deg_harmonic']:.3f} deg ({t['phase_difference_deg']:+.3f} deg).", ""]
    models = [m for m in HELDOUT_LABELS if any(m in (mre.get(s) or {}).get(k, {}) for s in mre
                                                for k in ("held_out", "in_sample"))]
    temps = sorted({float(T) for s in mre.values() for k in s.values() for m in k.values() for T in m})
    lines += ["| T (degC) | model | held out, lofo | held out, loto | in-sample |", "|---|---|---|---|---|"]
    for T in temps:
        key = T_key(T)
        for m in models:
            lofo = ((mre.get("lofo") or {}).get("held_out") or {}).get(m, {}).get(key)
            loto = ((mre.get("loto") or {}).get("held_out") or {}).get(m, {}).get(key)
            ins = None
            for s in ("lofo", "loto"):
                ins = ins or ((mre.get(s) or {}).get("in_sample") or {}).get(m, {}).get(key)
            if lofo is None and loto is None and ins is None:
                continue
            lt = _pair(loto) + (" (extrap.)" if loto and loto.get("extrapolation") else "")
            lines.append(f"| {T:g} | {HELDOUT_LABELS[m]} | {_pair(lofo)} | {lt} | {_pair(ins)} |")
    return lines + [""]


def selection_lines(report: dict) -> list:
    """Markdown lines of the extended law's chosen settings and the best rows of their
    cross-validation curve (empty when the report has no selection)."""
    sel = (report.get("extended") or {}).get("selection")
    if not sel:
        return []
    curve = pd.DataFrame(sel.get("curve") or [])
    rule = sel.get("rule") or "simplest candidate within one standard error of the best inner-CV score"
    lines = ["## Settings of the extended law, chosen by cross-validation", "",
             f"Chosen: **{sel.get('chosen_label', '')}** ({rule}). Score: mean over the inner folds (every "
             "frequency, every interior temperature left out) of max(MRE norm of E* / tol_E, MRE Phi / "
             "tol_Phi); lower is better.", ""]
    if len(curve) and "cv_score" in curve:
        lines += ["| setting | fitted parameters | CV score | s.e. | chosen |", "|---|---|---|---|---|"]
        shown = curve.sort_values("cv_score").head(6)
        shown = pd.concat([shown, curve[curve["chosen"].astype(bool) & ~curve.index.isin(shown.index)]])
        for _, r in shown.iterrows():
            sc = "n/a" if pd.isna(r["cv_score"]) else f"{r['cv_score']:.3f}"
            se = "n/a" if pd.isna(r.get("cv_score_se")) else f"{r['cv_score_se']:.3f}"
            lines.append(f"| {r['settings']} | {int(r['n_params'])} | {sc} | {se} | {bool(r['chosen'])} |")
        lines += ["", f"{len(curve)} candidates in all (the whole curve: extended_law_cv_curve.csv)."]
    return lines + [""]


def _p_text(p) -> str:
    """``p = 0.0012``, ``p < 1e-6`` or ``no p-value (effect size)``."""
    return "no p-value (effect size)" if p is None else effects.p_phrase(p)


def markdown_page(report: dict, figure: str | None = None) -> str:
    """The report page "What the simulation gets wrong" (Markdown) from a diagnose report: header,
    held-out errors, selected settings, gain, causes, Kramers-Kronig consistency, error budget and
    the budget figure's link (``figure``, a file name)."""
    lines = ["# What the simulation gets wrong", "",
             f"Baseline: {report['baseline']['model']}, against the {report['baseline']['reference']}.",
             f"Extension: {report['extended']['model']}, against the {report['extended']['reference']}.", ""]
    lines += heldout_lines(report)
    lines += selection_lines(report)
    lines += gain_lines(report)
    lines += cause_lines(report)
    lines += kramers_kronig_lines(report)
    lines += budget_lines(report)
    if figure:
        lines += ["", f"![error budget]({figure})"]
    return "\n".join(lines) + "\n"


def gain_lines(report: dict) -> list[str]:
    """Page section: the gain of the extended law per temperature and source (before -> after MRE,
    %, transfer correction noted) and the targets."""
    src = report.get("gain_sources")
    labels = {"nscd": "NSCD simulation", "macro": "macro law", "law_only": "extended law, no correction"}
    lines = []
    if src is not None:
        rows = gain_table(report)
        tr = report.get("transfer") or {}
        if tr.get("applied"):
            note = (" The NSCD rows after the extension include the transfer correction: every bond is "
                    "calibrated with E*(w) / NF_s, NF_s the sample's network factor (sample |E*| / macro "
                    "|E*| without inertia, harmonic solver; Eqs. 30-33 assume NF_s = 1), NF_s = "
                    f"{nf_text(tr['network_factor_applied'])}. The NSCD rows before it (the paper's "
                    "method) are not corrected.")
        elif tr.get("applied") is False:
            note = " The NSCD rows after the extension carry no transfer correction (Eqs. 30-33 as printed)."
        else:
            note = ""
        if report.get("gain_law_only") is not None:
            note += (" *Extended law, no correction* rows: the inertia-free harmonic response of the samples "
                     "with the generalized Burger's bond law as Eqs. 30-33 transfer it, NF_s x E*_law, "
                     f"NF_s = {nf_text(tr.get('network_factor_harmonic'))}; before -> these rows is the "
                     "gain of the law, these rows -> the NSCD rows after is the gain of the correction "
                     "(and of the remaining inertia and time integration).")
        lines += ["## Gain of the extended law per temperature (MRE %, before -> after, in-sample)", "",
                  "Source: *NSCD simulation* rows compare the time-domain NSCD runs (Burger's bond law "
                  "before, generalized Burger's bond law after); *macro law* rows compare the macro laws "
                  "themselves (Burger's before, generalized Burger's after), no simulation. "
                  f"Before: against the {src['reference']['before']}; after: against the "
                  f"{src['reference']['after']} (in brackets: against the measured means)." + note, "",
                  "| T (degC) | source | MRE \\|E*\\| before | after | MRE Phi before | after | targets met |",
                  "|---|---|---|---|---|---|---|"]
        order = {"law_only": 1, "macro": 2}
        rows = rows.assign(_o=rows["source"].map(lambda x: order.get(x, 0)))
        for _, r in rows.sort_values(["temperature_C", "_o"]).iterrows():
            if r["source"] in labels:
                label = labels[r["source"]]
            else:
                b, _, a = r["source"].partition("_before_")
                label = f"{labels[b]} -> {labels[a.replace('_after', '')]}"
            if r["transfer_correction"]:
                label += f" (+ transfer correction, NF_s = {r['network_factor']:.4g})"
            lines.append(f"| {r['temperature_C']:g} | {label} | {r['E_norm_mre_before_pct']:.2f} | "
                         f"{r['E_norm_mre_after_pct']:.2f}{_bracket(r['E_norm_mre_after_vs_measured_pct'])} | "
                         f"{r['phase_mre_before_pct']:.2f} | {r['phase_mre_after_pct']:.2f}"
                         f"{_bracket(r['phase_mre_after_vs_measured_pct'])} | {bool(r['targets_met'])} |")
    else:
        lines += ["| T (degC) | MRE \\|E*\\| before (%) | after (%) | MRE Phi before (%) | after (%) | targets met |",
                  "|---|---|---|---|---|---|"]
        for T, g in report["gain"].items():
            lines.append(f"| {T} | {g['E_norm']['before']:.2f} | {g['E_norm']['after']:.2f} | "
                         f"{g['phase']['before']:.2f} | {g['phase']['after']:.2f} | {report['targets']['met'][T]} |")
    lines += ["", f"Targets: |E*| MRE <= {report['targets']['E_norm_mre_pct']:g} %, "
              f"Phi MRE <= {report['targets']['phase_mre_pct']:g} %."]
    return lines


def cause_lines(report: dict) -> list[str]:
    """Page section: the named causes (most important first), the candidates not named and
    what their p-values mean (artifact screening range)."""
    lines = ["", "## Named causes (most important first)", ""]
    by = {e["name"]: e for e in report["effects"]}
    if not report["causes"]:
        lines.append("None at the chosen significance level and tolerances.")
    for name in report["causes"]:
        e = by[name]
        lines.append(f"- **{name}** ({e['category']}, {_p_text(e['p_value'])}, score {e['score']:.2f}): "
                     f"{e['evidence']}")
    lines += ["", "## Candidates not named", ""]
    for e in report["effects"]:
        if not e["detected"]:
            p = "" if e["p_value"] is None else f" ({_p_text(e['p_value'])})"
            lines.append(f"- {e['name']}{p}: {e['evidence']}")
    scr = report.get("artifact_screening") or {}
    where = ""
    if scr:
        where = (f" The screening model fits this table with a reduced chi-square of {scr['chi2_per_dof']:.2f} "
                 f"(clean benchmark tables: 99 % below {scr['bench_clean_chi2_per_dof_q99']:.2f}, all below "
                 f"{scr['bench_clean_chi2_per_dof_max']:.2f}): "
                 + ("inside the range where the false-alarm rates were measured."
                    if scr["within_bench_range"] else
                    "beyond 99 % of the clean tables on which the false-alarm rates were measured, so the "
                    "data-artifact p-values below are nominal: the model misfits this table, and a term can "
                    "absorb misfit."))
    lines += ["", "Data artifacts: nominal p-values of nested master-curve tests; the false-alarm rates of "
              "these decisions are measured by `asphalt-nscd diagnose-bench` on tables drawn from truths "
              "outside the detector's model (docs/choices.md, Diagnosis)." + where + " broad_spectrum: held-out "
              "(leave one frequency out) errors, no p-value; network_factor and time_integration: "
              "deterministic effects with their numerical uncertainty against a tolerance, no p-value."]
    return lines


def kramers_kronig_lines(report: dict) -> list[str]:
    """Page paragraph: Kramers-Kronig consistency of the measured isotherms (mean |Phi -
    Phi_Booij-Thoone|, deg) with their percentiles among clean synthetic tables; none without it."""
    lines = []
    kk = report.get("kramers_kronig_mean_abs_residual_deg", {})
    if kk:
        pct = report.get("kramers_kronig_percentile") or {}
        ref = report.get("kramers_kronig_reference") or {}
        ref_text = (f" Among {ref['n_isotherms']} isotherms of clean synthetic tables of causal laws at the same "
                    f"frequencies and replicate count the statistic has median {ref['median_deg']:.2f} deg and 99th "
                    f"percentile {ref['p99_deg']:.2f} deg; the percentile of each measured isotherm is given in "
                    "brackets. It places an isotherm, it does not decide causality: a high percentile says that its "
                    "|E*| and Phi agree less than a causal law's usually do at this noise." if ref else "")
        lines += ["", "Kramers-Kronig consistency of the measured isotherms (mean |Phi - Phi_Booij-Thoone|, deg): "
                  + ", ".join(f"{T} degC: {v:.2f}" + (f" ({pct[T]:.1f} %)" if T in pct else "")
                              for T, v in kk.items()) + "." + ref_text]
    return lines


def budget_lines(report: dict) -> list[str]:
    """Page section: the error budget table (MRE %, |E*| / Phi, per temperature and component)
    and what each component compares."""
    lines = ["", "## Error budget (MRE %, \\|E*\\| / Phi)", "",
             "| T (degC) | data artifacts | model form | micro-macro transfer | numerics | total |",
             "|---|---|---|---|---|---|"]
    for T, comp in report["error_budget"].items():
        cells = []
        for c in ("data_artifacts", "model_form", "micro_macro_transfer", "numerics", "total"):
            v = comp.get(c)
            cells.append("n/a" if v is None else f"{v['mre_E_norm_pct']:.2f} / {v['mre_phase_pct']:.2f}")
        lines.append(f"| {T} | " + " | ".join(cells) + " |")
    total = "the NSCD simulation" if report["baseline"]["model"].startswith("NSCD") else "the macro Burger's law"
    lines += ["", "Components: data artifacts = measured vs artifact-corrected means; model form = macro "
              "Burger's law vs corrected means; micro-macro transfer = harmonic response of the NSCD "
              "sample vs its macro Burger's law (n/a without harmonic results); numerics = NSCD "
              "simulation vs harmonic response (n/a without both); total = "
              f"{total} vs the measured means."]
    return lines


def effects_table(report: dict) -> pd.DataFrame:
    """The cause table of a diagnose report: one row per candidate effect, ``name, category,
    detected, testable, score, p_value, estimate`` (``key=value`` pairs, floats with 4
    significant digits) and ``evidence``."""
    rows = [{"name": e["name"], "category": e["category"], "detected": e["detected"],
             "testable": e["testable"], "score": e["score"], "p_value": e["p_value"],
             "estimate": "; ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                   for k, v in e["estimate"].items()),
             "evidence": e["evidence"]} for e in report["effects"]]
    return pd.DataFrame(rows)
