"""What the simulation gets wrong, rendered: the gain and cause tables, the error-budget figure
and the report page, from the report that :func:`asphalt_nscd.diagnosis.budget.diagnose`
computed (nothing is computed here but formatting).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from ..lab.table_format import DisplayUnits
from . import effects
from .budget import T_key, nf_text


def _units(report: dict) -> DisplayUnits:
    """The units the lab wrote its table in (SI without a declaration)."""
    return DisplayUnits(**(report.get("units") or {}))


#: crossval model of the held-out "after" (and "before") of each gain source
HELDOUT_MODELS = {"macro": ("burgers", "extended_law"), "nscd": (None, "nscd_sample"), "law_only": (None, None)}


def _heldout_row(report: dict, scheme: str, model: str | None, T: str) -> dict | None:
    """The held-out score row of (scheme, model) at temperature ``T`` (its interpolated cells,
    else its extrapolated ones), or None."""
    h = report.get("heldout") or {}
    rows = [
        r
        for r in h.get("scores", [])
        if r["scheme"] == scheme
        and r["kind"] == "held_out"
        and r["model"] == model
        and r.get("temperature_C") is not None
        and T_key(r["temperature_C"]) == T
        and r["n_cells"]
    ]
    rows.sort(key=lambda r: r["extrapolation"])
    return rows[0] if rows else None


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
    ``E_norm_mre_after_vs_measured_pct, phase_mre_after_vs_measured_pct``. The "after" columns
    are in-sample (the law was fitted on every cell). With crossval rows in the report
    (``heldout``), the held-out errors of the matching crossval model beside them:
    ``heldout_before_model``, ``heldout_after_model`` (``burgers`` / ``extended_law`` for
    ``macro``, ``nscd_sample`` for ``nscd``; empty when there is none),
    ``{abs_logE_pct,abs_phase_deg}_{before,after}_heldout_{scheme}`` (absolute log error of
    |E*|, %, and absolute Phi error, deg, of the temperature's interpolated cells, else its
    extrapolated ones) and ``heldout_extrapolation_{scheme}``.
    """
    src = report["gain_sources"]
    models = src["models"]
    blocks = []
    primary = (
        "nscd"
        if src["before"] == src["after"] == "nscd"
        else ("macro" if src["before"] == src["after"] == "macro" else f"{src['before']}_before_{src['after']}_after")
    )
    blocks.append((primary, report["gain"], models[src["before"]]["before"], models[src["after"]]["after"]))
    if primary != "macro":
        blocks.append(("macro", report["gain_macro"], models["macro"]["before"], models["macro"]["after"]))
    if report.get("gain_law_only") is not None:
        blocks.append(("law_only", report["gain_law_only"], models["law_only"]["before"], models["law_only"]["after"]))
    tr = report.get("transfer") or {}
    applied = bool(tr.get("applied"))
    rows = []
    for source, gain, before_model, after_model in blocks:
        nscd_after = source == "nscd" or source.endswith("_nscd_after")
        corrected = nscd_after and applied
        nf = (
            tr.get("network_factor_applied_mean")
            if corrected
            else tr.get("law_only_network_factor")
            if source == "law_only"
            else None
        )
        base = source.split("_before_")[-1].replace("_after", "") if "_before_" in source else source
        hb, ha = HELDOUT_MODELS.get(base, (None, None))
        if "_before_" in source:
            hb = HELDOUT_MODELS[source.split("_before_")[0]][0]
        schemes = sorted((report.get("heldout") or {}).get("schemes", {}))
        for T, g in gain.items():
            held: dict[str, Any] = {}
            if report.get("heldout") is not None:
                held = {"heldout_before_model": hb or "", "heldout_after_model": ha or ""}
                for scheme in schemes:
                    ext = None
                    for when, model in (("before", hb), ("after", ha)):
                        r = _heldout_row(report, scheme, model, T) if model else None
                        held[f"abs_logE_pct_{when}_heldout_{scheme}"] = np.nan if r is None else r["abs_logE_pct"]
                        held[f"abs_phase_deg_{when}_heldout_{scheme}"] = np.nan if r is None else r["abs_phase_deg"]
                        ext = ext if r is None else r["extrapolation"]
                    held[f"heldout_extrapolation_{scheme}"] = ext
            rows.append(
                {
                    "temperature_C": float(T),
                    "source": source,
                    "before_model": before_model,
                    "after_model": after_model,
                    "transfer_correction": corrected,
                    "network_factor": np.nan if nf is None else float(nf),
                    "E_norm_mre_before_pct": g["E_norm"]["before"],
                    "E_norm_mre_after_pct": g["E_norm"]["after"],
                    "phase_mre_before_pct": g["phase"]["before"],
                    "phase_mre_after_pct": g["phase"]["after"],
                    "E_norm_mre_after_vs_measured_pct": g["E_norm"]["after_vs_measured"],
                    "phase_mre_after_vs_measured_pct": g["phase"]["after_vs_measured"],
                    **held,
                }
            )
    return pd.DataFrame(rows)


def budget_figure(budget: pd.DataFrame, path, baseline: str = "") -> None:
    """Stacked bars of the error budget per temperature (top Phi, bottom |E*| MRE), saved to
    ``path`` atomically; ``baseline``: the report's baseline model (the title and the total's
    label say what ran)."""
    simulated = baseline.startswith("NSCD")
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
            ax.plot(
                x,
                [tot[col].get(T, np.nan) for T in temps],
                "k_",
                markersize=30,
                mew=2,
                label="total (" + ("NSCD simulation" if simulated else "macro Burger's law") + " vs measured)",
            )
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[1].set_xticks(x, [f"{T:g}" for T in temps])
    axes[1].set_xlabel("temperature (degC)")
    fig.suptitle(
        "Error budget of the NSCD simulation per temperature"
        if simulated
        else "Error budget of the macro Burger's law per temperature (no simulation ran)"
    )
    savefig(fig, path)
    plt.close(fig)


def _bracket(v) -> str:
    """`` (v)`` with 2 decimals, or nothing for a missing value."""
    return "" if v is None or v != v else f" ({v:.2f})"


HELDOUT_LABELS = {
    "burgers": "Burger's per isotherm (paper)",
    "extended_law": "extended law (selected)",
    "card_law": "law of the material card",
    "nscd_sample": "NSCD sample (harmonic, law / NF_s)",
    "nscd_time_domain": "NSCD sample (time domain, one fold)",
}


def _num(v, fmt: str = ".2f") -> str:
    return "n/a" if v is None or not np.isfinite(v) else format(v, fmt)


def _with_ci(d: dict, key: str, fmt: str = ".2f") -> str:
    """``v [lo, hi]`` of ``d[key]`` and its ``_ci95_low/_high`` (the interval where finite)."""
    base = key.rsplit("_", 1)[0]
    v, lo, hi = d.get(key), d.get(f"{base}_ci95_low"), d.get(f"{base}_ci95_high")
    text = _num(v, fmt)
    if lo is not None and hi is not None and np.isfinite(lo) and np.isfinite(hi):
        text += f" [{lo:{fmt}}, {hi:{fmt}}]"
    return text


#: fewest specimens whose overall level (n - 1 degrees of freedom) bounds an error usefully: below,
#: the page says how far the upper end of the interval against the mix lies above the observed error
FEW_SPECIMENS = 5


def _few_specimens_lines(heads: list) -> list:
    """What a table of fewer than :data:`FEW_SPECIMENS` specimens cannot bound: per scheme with
    the interval against the mix (lofo, loto), the upper end of |E*|'s beside the observed
    error; empty otherwise."""
    rows = [
        x
        for x in heads
        if x["model"] == "extended_law"
        and x["scheme"] in ("lofo", "loto")
        and 2 <= (x.get("interp_n_specimens") or 0) < FEW_SPECIMENS
        and np.isfinite(x.get("interp_abs_logE_ci95_high", np.nan))
    ]
    if not rows:
        return []
    n = int(rows[0]["interp_n_specimens"])
    parts = "; ".join(
        f"{x['scheme']}: observed {x['interp_abs_logE_pct']:.2f} %, up to {x['interp_abs_logE_ci95_high']:.2f} % "
        "against the mix"
        for x in rows
    )
    loso = any(x["scheme"] == "loso" and x["model"] == "extended_law" for x in heads)
    return [
        "",
        f"With {n} specimens the mix's level is known to {n - 1} degrees of freedom only, so the error "
        f"against the mix is bounded loosely ({parts}): {n} specimens cannot bound the |E*| error usefully; "
        "the observed error against these specimens' means is what the table shows."
        + (
            f" The leave-one-specimen-out interval rests on {n} held-out specimens ({n - 1} degrees of "
            "freedom) and bounds the error for a new specimen no better."
            if loso
            else ""
        ),
    ]


def heldout_lines(report: dict) -> list:
    """Markdown lines of the held-out errors: the headline per scheme and model (pooled over the
    interpolated cells, with intervals and the one set of targets), the extrapolated cells
    apart, the full table per temperature with the worst marked, and the schemes that have no
    fold to compute (empty without crossval rows in the report)."""
    h = report.get("heldout")
    if not h:
        return []
    t = report["targets"]
    u = _units(report)
    # the material card's law is the selected one: its rows repeat the selected law's (kept in the CSV)
    same_card = bool((report.get("material_card") or {}).get("is_selected_law"))
    skip = {"nscd_time_domain"} | ({"card_law"} if same_card else set())
    lines = [
        "## Held-out errors",
        "",
        "Each fold refits the whole procedure (artifact correction at the table's calibrated level, nested "
        "choice of the law's settings, law) without its held-out rows: "
        + "; ".join(f"*{k}*: {v}" for k, v in h.get("schemes", {}).items())
        + ". "
        "|E*| errors are log ratios (%), ln(predicted / the specimens' mean); Phi errors are in degrees. "
        "*signed*: the mean error with its t(n-1) interval over the specimens; *absolute*: the mean absolute "
        "error against the lab's means (what was observed), and in brackets the 95 % interval of the error "
        "against the mix, the population the specimens were drawn from (the lab's means differ from the "
        "mix's by the specimens' overall level, their level per isotherm and their cell-to-cell scatter, "
        "each estimated with its own degrees of freedom; the coverage of these intervals is measured by "
        "simulation, reference/crossval/ in the repository). loso scores each specimen against itself: the "
        "signed mean with its t(n-1) interval over the held-out specimens, the absolute mean with the interval "
        "of a fold's error against a new specimen of the mix (a parametric bootstrap of the folds from the same "
        "three levels, the overall one drawn with its own degrees of freedom). "
        f"Targets: absolute |E*| error <= {t['abs_logE_pct']:g} % and absolute Phi error <= "
        f"{t['abs_phase_deg']:g} deg ({t['applies_to']}), on the error against the mix: *met* when the "
        "interval lies below, *missed* when above, *undecided* when it straddles the target.",
        "",
    ]
    heads = [x for x in h["headline"] if x["kind"] == "held_out" and x["model"] not in skip]
    if heads:
        lines += [
            "| scheme | model | cells | |E*| signed % | |E*| absolute % [vs the mix] | Phi signed deg | "
            "Phi absolute deg [vs the mix] | verdict |E*| / Phi |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for x in heads:
            if not (x.get("interp_n_cells") or 0):
                continue
            lines.append(
                f"| {x['scheme']} | {HELDOUT_LABELS.get(x['model'], x['model'])} | "
                f"{int(x['interp_n_cells'])} | {_with_ci(x, 'interp_bias_logE_pct')} | "
                f"{_with_ci(x, 'interp_abs_logE_pct')} | "
                f"{_with_ci(x, 'interp_bias_phase_deg')} | {_with_ci(x, 'interp_abs_phase_deg')} | "
                f"{x.get('verdict_E_norm', 'n/a')} / {x.get('verdict_phase', 'n/a')} |"
            )
        lines += _few_specimens_lines(heads)
        extrap = [x for x in heads if (x.get("extrap_n_cells") or 0) > 0]
        if extrap:
            lines += [
                "",
                "Extrapolated cells (outside the fold's tested frequencies or temperatures), apart:",
                "",
                "| scheme | model | cells | |E*| absolute % | Phi absolute deg |",
                "|---|---|---|---|---|",
            ]
            for x in extrap:
                lines.append(
                    f"| {x['scheme']} | {HELDOUT_LABELS.get(x['model'], x['model'])} | "
                    f"{int(x['extrap_n_cells'])} | {_with_ci(x, 'extrap_abs_logE_pct')} | "
                    f"{_with_ci(x, 'extrap_abs_phase_deg')} |"
                )
        lines.append("")
    for scheme, why in (h.get("not_computable") or {}).items():
        lines += [f"*{scheme}*: no fold could be computed ({why}); nothing is drawn for it.", ""]
    for td in h.get("time_domain_check") or []:
        lines += [
            f"Time domain vs harmonic solution of the NSCD sample with the law of the {td['scheme']} fold "
            f"{td['fold']} at {td['temperature_C']:g} degC, {td['frequency_Hz']:g} Hz (held out): norm of E* "
            f"{td['E_norm_MPa_time_domain']:.5g} vs {td['E_norm_MPa_harmonic']:.5g} MPa "
            f"({100 * td['E_norm_relative_difference']:+.3f} %), Phi {td['phase_deg_time_domain']:.3f} vs "
            f"{td['phase_deg_harmonic']:.3f} deg ({td['phase_difference_deg']:+.3f} deg).",
            "",
        ]
    per_T = [
        r
        for r in h["scores"]
        if r.get("temperature_C") is not None and r["kind"] == "held_out" and r["model"] not in skip and r["n_cells"]
    ]
    if per_T:
        worst: dict[tuple, float] = {}
        for r in per_T:
            if not r["extrapolation"] and r.get("abs_logE_pct") is not None:
                k = (r["scheme"], r["model"])
                if k not in worst or r["abs_logE_pct"] > worst[k]:
                    worst[k] = r["abs_logE_pct"]
        lines += [
            "Per temperature (held out; * the largest absolute |E*| error of that scheme and model among "
            "its interpolated temperatures; MRE: the paper's Table 4 measure against the replicate means, %):",
            "",
            f"| {u.temperature_header()} | scheme | model | cells | |E*| absolute % | Phi absolute deg | "
            "MRE |E*| / Phi % |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in sorted(per_T, key=lambda r: (r["temperature_C"], r["scheme"], r["model"], r["extrapolation"])):
            mark = (
                " *"
                if (not r["extrapolation"] and worst.get((r["scheme"], r["model"])) == r.get("abs_logE_pct"))
                else ""
            )
            ex = " (extrap.)" if r["extrapolation"] else ""
            lines.append(
                f"| {u.temperature_cell(r['temperature_C'])}{ex} | {r['scheme']} | "
                f"{HELDOUT_LABELS.get(r['model'], r['model'])} "
                f"| {r['n_cells']} | {_with_ci(r, 'abs_logE_pct')}{mark} | {_with_ci(r, 'abs_phase_deg')} | "
                f"{_num(r.get('mre_E_norm_pct'))} / {_num(r.get('mre_phase_pct'))} |"
            )
    return lines + [""]


def card_lines(report: dict) -> list:
    """Markdown lines of the material card: the law it carries, what it loses against the
    selected law and its own errors against the measured replicate means, per temperature (empty
    without a card in the report)."""
    card = report.get("material_card")
    if not card:
        return []

    from ..rheology.export import carried_text, worse_than_selected

    u = _units(report)
    sel = card.get("terms_selection") or {}
    tol, band = sel.get("tolerance") or {}, sel.get("band_rad_s")
    lines = [
        "## Material card",
        "",
        f"Relaxation Prony series of **{card['n_terms']} terms** at T_ref = {u.temperature_text(card['T_ref_C'])}, "
        f"E_0 = {u.modulus_text(card['E_0_MPa'])}, with a {card['shift']['law']} shift "
        f"({card['shift'].get('from', '')}): the fewest terms within "
        f"{tol.get('E_norm_pct', '?')} % |E*| and {tol.get('phase_deg', '?')} deg of the law it carries"
        + (
            f" over the reduced band {band[0]:.3g}-{band[1]:.3g} rad/s at T_ref (the measured band widened by "
            f"{sel.get('margin_decades', '?')} decade at each end) and at the measured cells"
            if band
            else ""
        )
        + f"; achieved {card['check']['max_E_norm_difference_pct']:.3g} % |E*| and "
        f"{card['check']['max_phase_difference_deg']:.3g} deg at the measured cells "
        "(error against the number of terms: material_cards/prony.json, terms_selection.curve).",
        "",
        carried_text(card)[0].upper() + carried_text(card)[1:] + ".",
    ]
    if not card["is_selected_law"]:
        lines[-1] += " Its held-out errors are the *law of the material card* rows above."
    worse = worse_than_selected(card)
    if worse:
        lines += [
            "",
            "**Against the lab's means the card is worse than the selected law in " + "; ".join(worse) + ".**",
        ]
    if card.get("nu") is not None:
        lines += [
            "",
            f"Poisson's ratio {card['nu']:g}, {card.get('nu_source') or 'given'}; the shear relaxation "
            "G(t) = E(t) / (2 (1 + nu)) is in material_cards/relaxation_creep.csv and the LS-DYNA card.",
        ]
    ic = card.get("interconversion")
    if ic:
        lines += [
            "",
            f"Creep compliance D(t) interconverted exactly from the relaxation series: largest residual of "
            f"the convolution identity {100 * ic['max_abs_residual']:.2g} % over every temperature and time "
            f"(check {'met' if ic['met'] else '**missed**'} at {100 * ic['tolerance']:g} %).",
        ]
    corrected = any("card_vs_corrected_logE_pct_mean" in r for r in card.get("loss") or [])
    lines += [
        "",
        f"| {u.temperature_header()} | cells | card vs measured: \\|E*\\| mean / max % | Phi mean / max deg | "
        "selected law vs measured: \\|E*\\| % | Phi deg | card vs selected law: \\|E*\\| % | Phi deg |"
        + (" card vs corrected: \\|E*\\| % | Phi deg | correction: \\|E*\\| % | Phi deg |" if corrected else ""),
        "|---|---|---|---|---|---|---|---|" + ("---|---|---|---|" if corrected else ""),
    ]
    for r in card.get("loss") or []:
        T = "all" if r["temperature_C"] == "all" else u.temperature_cell(r["temperature_C"])
        pairs = ["card_vs_measured", "law_vs_measured", "card_vs_law"]
        if corrected:
            pairs += ["card_vs_corrected", "corrected_vs_measured"]
        cells = [
            f"{r[f'{p}_logE_pct_mean']:.2f} / {r[f'{p}_logE_pct_max']:.2f} | "
            f"{r[f'{p}_phase_deg_mean']:.2f} / {r[f'{p}_phase_deg_max']:.2f}"
            for p in pairs
        ]
        lines.append(f"| {T} | {r['n_cells']} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "In-sample: against the measured replicate means the law was fitted on (every cell: "
        "material_cards/card_errors.csv).",
    ]
    if corrected:
        named = ", ".join(card.get("corrections") or []) or "the artifacts the diagnosis named"
        lines += [
            "",
            f"The laws were fitted to the table corrected for {named}, which the diagnosis names as "
            "identifiable from this table; *correction* is what it changes in the replicate means.",
        ]
    return lines + [""]


def findings_lines(report: dict) -> list:
    """Markdown lines of the parameters outside their plausible range for a mix or at a bound
    of their fit (empty when there are none)."""
    found = {k: v for k, v in (report.get("findings") or {}).items() if v}
    if not found:
        return []
    from ..rheology.plausibility import describe

    lines = ["## Parameters at a bound or outside the plausible range", ""]
    for what, items in found.items():
        lines.append(f"- {what}: {describe(items)}")
    return lines + ["", "Ranges and their sources: asphalt_nscd.rheology.plausibility (docs/choices.md).", ""]


def quality_lines(report: dict) -> list:
    """Markdown lines of the table's data quality: the lab's quality indicators and the rows
    beyond their limits, and the outlying cells with their size (never dropped)."""
    q = report.get("data_quality") or {}
    ind, out = q.get("indicators") or {}, q.get("outliers") or []
    u = _units(report)
    lines = ["## Data quality", ""]
    warned = (report.get("measured") or {}).get("warnings") or []
    if warned:
        lines += ["**Checks of the values as read** (units and plausible ranges; the table was used as declared):"]
        lines += [f"- {w}" for w in warned] + [""]
    if ind.get("columns"):
        lim = ", ".join(f"{k} <= {v:g}" for k, v in (ind.get("limits") or {}).items() if v is not None)
        lines.append(
            f"Quality indicators of the lab ({lim}): {ind['n_flagged']} of {ind['n_rows']} rows beyond a limit"
            + (":" if ind["n_flagged"] else ".")
        )
        for r in ind["flagged"][:20]:
            lines.append(
                f"- {r['specimen']}, {u.temperature_text(r['temperature_C'])}, {r['frequency_Hz']:g} Hz: {r['reason']}"
            )
        if ind["n_flagged"] > 20:
            lines.append(f"- ... and {ind['n_flagged'] - 20} more")
        wf = report.get("law_without_flagged")
        if wf:
            lines += ["", wf]
    else:
        lines.append(
            "The table carries no data-quality indicators (AASHTO T 378: load and deformation standard "
            "errors, deformation and phase uniformity; declare them in the sidecar's table.quality)."
        )
    lines.append("")
    if out:
        lines.append(
            "Outlying cells (replicate mean against the isotherm's smooth course in the screening model, "
            "beyond the replicate scatter and the table's typical cell misfit; Bonferroni over the cells at "
            "1 %; reported, not dropped):"
        )
        for o in out:
            misfit = (
                f"{o['cell_misfit_sd']:.2f} {o['size_unit']}"
                if o["cell_misfit_sd"] >= 0.005
                else "none beyond the replicate scatter"
            )
            lines.append(
                f"- {u.temperature_text(o['temperature_C'])}, {o['frequency_Hz']:g} Hz: {o['quantity']} "
                f"{o['size']:+.2f} {o['size_unit']} from the model (z = {o['z']:.2f}, p = {o['p']:.2g}, "
                f"{o['n']} replicates; typical cell misfit {misfit})"
            )
    else:
        lines.append("No outlying cell (replicate means against the isotherms' smooth course, Bonferroni at 1 %).")
    return lines + [""]


def selection_lines(report: dict) -> list:
    """Markdown lines of the extended law's chosen settings and the best rows of their
    cross-validation curve (empty when the report has no selection)."""
    sel = (report.get("extended") or {}).get("selection")
    if not sel:
        return []
    curve = pd.DataFrame(sel.get("curve") or [])
    rule = sel.get("rule") or "simplest candidate within one standard error of the best inner-CV score"
    lines = [
        "## Settings of the extended law, chosen by cross-validation",
        "",
        f"Selected: **{sel.get('chosen_label', '')}** ({rule}). Score: mean over the inner folds (every "
        "frequency, every interior temperature left out) of max(MRE norm of E* / tol_E, MRE Phi / "
        "tol_Phi); lower is better.",
        "",
    ]
    lines += [f"- {n}" for n in sel.get("notes") or []] + ([""] if sel.get("notes") else [])
    if len(curve) and "cv_score" in curve:
        lines += [
            "| setting | fitted parameters | CV score | s.e. | plausible | card carries it | selected |",
            "|---|---|---|---|---|---|---|",
        ]
        shown = curve.sort_values("cv_score").head(6)
        chosen = curve["chosen"].astype(bool) | curve.get("chosen_card", pd.Series(False, index=curve.index)).astype(
            bool
        )
        shown = pd.concat([shown, curve[chosen & ~curve.index.isin(shown.index)]])
        for _, r in shown.iterrows():
            sc = "n/a" if pd.isna(r["cv_score"]) else f"{r['cv_score']:.3f}"
            se = "n/a" if pd.isna(r.get("cv_score_se")) else f"{r['cv_score_se']:.3f}"
            plaus = "yes" if r.get("plausible", True) else f"no ({r.get('findings', '')})"
            sel_ = "**selected**" if r["chosen"] else ("card" if r.get("chosen_card") else "")
            lines.append(
                f"| {r['settings']} | {int(r['n_params'])} | {sc} | {se} | {plaus} | "
                f"{'yes' if r.get('carriable', True) else 'no'} | {sel_} |"
            )
        lines += ["", f"{len(curve)} candidates in all (the whole curve: extended_law_cv_curve.csv)."]
    return lines + [""]


def _p_text(p) -> str:
    """``p = 0.0012``, ``p < 1e-6`` or ``no p-value (effect size)``."""
    return "no p-value (effect size)" if p is None else effects.p_phrase(p)


def markdown_page(report: dict, figure: str | None = None) -> str:
    """The report page "What the simulation gets wrong" (Markdown) from a diagnose report: header,
    held-out errors, selected settings, gain, causes, Kramers-Kronig consistency, error budget and
    the budget figure's link (``figure``, a file name)."""
    simulated = report["baseline"]["model"].startswith("NSCD")
    title = (
        "What the simulation gets wrong"
        if simulated
        else "What the paper's Burger's law gets wrong on this table (no simulation ran)"
    )
    table = report.get("measured") or {}
    lines = [f"# {title}", ""]
    if table.get("path"):
        lines += [
            f"Measured table: {table['path']}"
            + (f" (sha256 {table['sha256'][:16]})" if table.get("sha256") else "")
            + ": the master curve, the law and the material card were checked to come from it.",
            "",
        ]
    lines += [
        f"Baseline: {report['baseline']['model']}, against the {report['baseline']['reference']}.",
        f"Extension: {report['extended']['model']}, against the {report['extended']['reference']}.",
        "",
    ]
    lines += heldout_lines(report)
    lines += card_lines(report)
    lines += selection_lines(report)
    lines += findings_lines(report)
    lines += quality_lines(report)
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
            note = (
                " The NSCD rows after the extension include the transfer correction: every bond is "
                "calibrated with E*(w) / NF_s, NF_s the sample's network factor (sample |E*| / macro "
                "|E*| without inertia, harmonic solver; Eqs. 30-33 assume NF_s = 1), NF_s = "
                f"{nf_text(tr['network_factor_applied'])}. The NSCD rows before it (the paper's "
                "method) are not corrected."
            )
        elif tr.get("applied") is False:
            note = " The NSCD rows after the extension carry no transfer correction (Eqs. 30-33 as printed)."
        else:
            note = ""
        if report.get("gain_law_only") is not None:
            note += (
                " *Extended law, no correction* rows: the inertia-free harmonic response of the samples "
                "with the generalized Burger's bond law as Eqs. 30-33 transfer it, NF_s x E*_law, "
                f"NF_s = {nf_text(tr.get('network_factor_harmonic'))}; before -> these rows is the "
                "gain of the law, these rows -> the NSCD rows after is the gain of the correction "
                "(and of the remaining inertia and time integration)."
            )
        lines += [
            "## Gain of the extended law per temperature (MRE %, before -> after, in-sample)",
            "",
            "Source: *NSCD simulation* rows compare the time-domain NSCD runs (Burger's bond law "
            "before, generalized Burger's bond law after); *macro law* rows compare the macro laws "
            "themselves (Burger's before, generalized Burger's after), no simulation. "
            f"Before: against the {src['reference']['before']}; after: against the "
            f"{src['reference']['after']} (in brackets: against the measured means)." + note,
            "",
            f"| {_units(report).temperature_header()} | source | MRE \\|E*\\| before | after | MRE Phi before | after |",
            "|---|---|---|---|---|---|",
        ]
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
            lines.append(
                f"| {_units(report).temperature_cell(r['temperature_C'])} | {label} | {r['E_norm_mre_before_pct']:.2f} | "
                f"{r['E_norm_mre_after_pct']:.2f}{_bracket(r['E_norm_mre_after_vs_measured_pct'])} | "
                f"{r['phase_mre_before_pct']:.2f} | {r['phase_mre_after_pct']:.2f}"
                f"{_bracket(r['phase_mre_after_vs_measured_pct'])} |"
            )
    else:
        lines += [
            f"| {_units(report).temperature_header()} | MRE \\|E*\\| before (%) | after (%) | MRE Phi before (%) | after (%) |",
            "|---|---|---|---|---|",
        ]
        for T, g in report["gain"].items():
            lines.append(
                f"| {_units(report).temperature_cell(float(T))} | {g['E_norm']['before']:.2f} | {g['E_norm']['after']:.2f} | "
                f"{g['phase']['before']:.2f} | {g['phase']['after']:.2f} |"
            )
    lines += [
        "",
        "In-sample: the law was fitted on every cell; no target applies (the targets are on the held-out "
        "errors above).",
    ]
    return lines


def _p_cell(p) -> str:
    return "n/a" if p is None else effects.format_p(p)


def artifact_lines(report: dict) -> list[str]:
    """Page section: what the table's design can identify (each candidate's collinearity with
    the screening model and with its rival), the level of the selection and its calibration on
    the table itself, and each candidate's nominal and calibrated p-values."""
    sel = report.get("selection") or {}
    cal = report.get("calibration")
    lines = [
        "",
        "## Data artifacts: what this table can identify, at a controlled error rate",
        "",
        "A candidate is tested only if the table's design tells its signature from the screening model's own "
        "freedom (cosine with the model's span, limit in brackets) and from its rival, the explanation that is "
        "not an artifact (largest canonical correlation beyond the model). The tested candidates are selected "
        "forward under Holm's step-down; the first step's level is the smaller of the nominal alpha / m and the "
        "level calibrated on this table.",
    ]
    if cal is not None:
        a, cm = cal["artifacts"], cal["clean_model"]
        lines[-1] += (
            f" Calibration: the whole procedure rerun on {cal['n_tables']} tables simulated from each of two "
            f"fitted clean models of this table (its design; seed {cal['seed']}): its screening fit with "
            f"{cm['shifts']}, its specimen factors, point scatter {100 * cm['sigma_point_lnE']:.1f} % / "
            f"{cm['sigma_point_phase_deg']:.2f} deg and cell misfit {100 * cm['sigma_cell_lnE']:.1f} % / "
            f"{cm['sigma_cell_phase_deg']:.2f} deg"
        )
        mx = (a.get("nulls") or {}).get("maxwell")
        if mx is not None:
            m = mx["model"]
            lines[-1] += (
                f"; and a generalized Maxwell (Prony) master curve with a positive relaxation spectrum "
                f"({m['terms_per_decade']:g} relaxation times per decade, {m['positive_terms']} positive; reduced "
                f"chi-square {m['chi2_per_dof']:.2f}), its {m['shifts']}, the same specimen factors and point "
                f"scatter and its own cell misfit {100 * m['sigma_cell_lnE']:.1f} % / "
                f"{m['sigma_cell_phase_deg']:.2f} deg, which follows any linear viscoelastic, thermorheologically "
                "simple material, so that the misfit of a spectrum the screening model cannot follow is in its "
                "tables as it is in this one"
            )
        levels = "; ".join(f"{name} {v['calibrated_level']:.3g}" for name, v in (a.get("nulls") or {}).items())
        lines[-1] += (
            f". The level holding the family-wise false-alarm rate at "
            f"{cal['familywise_rate'] / cal['groups']:g} (the artifacts' share of {cal['familywise_rate']:g}) is "
            f"{a['calibrated_level']:.3g}" + (f" (the smaller of the nulls': {levels})" if levels else "") + "; "
            f"nominal {a['nominal_level']:.3g}; used {a['level']:.3g} ({a['binding']})."
            + _calibration_rate_sentence(a, cal)
        )
    elif sel:
        lines[-1] += f" No calibration was given: the nominal level {sel.get('level', float('nan')):.3g} is used."
    lines += [
        "",
        "| candidate | testable | identifiable (null cosine; rival correlation) | p nominal | p calibrated | named |",
        "|---|---|---|---|---|---|",
    ]
    for e in report["effects"]:
        if e["category"] != "data":
            continue
        idf = e.get("identifiability") or {}
        if not e["testable"]:
            ident = "n/a"
        else:
            nc, rc = idf.get("null_correlation"), idf.get("rival_correlation")
            ident = (
                "yes" if e.get("identifiable") else "**no**"
            ) + f" ({_num(nc, '.3f') if nc is not None else '-'}; {_num(rc, '.3f') if rc is not None else '-'})"
        lines.append(
            f"| {e['name']} | {'yes' if e['testable'] else 'no'} | {ident} | {_p_cell(e.get('p_value'))} | "
            f"{_p_cell(e.get('p_calibrated'))} | {'**yes**' if e['detected'] else 'no'} |"
        )
    named = [e["name"] for e in report["effects"] if e["category"] == "data" and e["detected"]]
    lines += [
        "",
        "How far this holds is measured on synthetic tables of known truth, nine families of them, three "
        "outside the screening model (the detection benchmark, reference/detection_bench/ in the repository: the "
        "false-alarm rate of the whole procedure calibrated on each table, per family and design, and its power at "
        "the stated sizes). A truth the screening model cannot follow leaves a misfit that runs smoothly along "
        "frequency, as an artifact's signature does; the relaxation-spectrum null carries that misfit into its "
        "tables, so that misfit rarely passes for an artifact (a few clean generalized Maxwell tables in a hundred "
        "still raise one, those the screening fit misses most), and what no linear viscoelastic material gives (a "
        "phase growing with the test frequency at a fixed |E*|, an E1 deficit growing with its square, an isotherm "
        "off a smooth shift law) is what remains to be named. The price is power where both are present: a "
        "spectrum can take up part of an artifact's signature."
        + (f" The artifact named here ({', '.join(named)}) is below the level of both nulls." if named else ""),
    ]
    return lines


def cause_lines(report: dict) -> list[str]:
    """Page section: the named causes (most important first), the data artifacts' section
    (:func:`artifact_lines`), and the candidates not named with why."""
    lines = ["", "## Named causes (most important first)", ""]
    by = {e["name"]: e for e in report["effects"]}
    if not report["causes"]:
        lines.append("None at the chosen significance level and tolerances.")
    for name in report["causes"]:
        e = by[name]
        p = "" if e.get("p_calibrated") is None else f", calibrated p = {effects.format_p(e['p_calibrated'])}"
        lines.append(
            f"- **{name}** ({e['category']}, {_p_text(e['p_value'])}{p}, score {e['score']:.2f}): {e['evidence']}"
        )
    lines += artifact_lines(report)
    lines += ["", "## Candidates not named", ""]
    for e in report["effects"]:
        if not e["detected"]:
            p = "" if e["p_value"] is None else f" ({_p_text(e['p_value'])})"
            lines.append(f"- {e['name']}{p}: {e['evidence']}")
    lines += [
        "",
        "broad_spectrum: held-out (leave one frequency out) errors, no p-value; network_factor and "
        "time_integration: deterministic effects with their numerical uncertainty against a tolerance, no "
        "p-value.",
    ]
    return lines


def kramers_kronig_lines(report: dict) -> list[str]:
    """Page paragraph: Kramers-Kronig consistency of the measured isotherms (mean |Phi -
    Phi_Booij-Thoone|, deg) with their percentiles among clean synthetic tables; none without it."""
    lines = []
    kk = report.get("kramers_kronig_mean_abs_residual_deg", {})
    if kk:
        pct = report.get("kramers_kronig_percentile") or {}
        ref = report.get("kramers_kronig_reference") or {}
        ref_text = (
            f" Among {ref['n_isotherms']} isotherms of clean synthetic tables of causal laws at the same "
            f"frequencies and replicate count the statistic has median {ref['median_deg']:.2f} deg and 99th "
            f"percentile {ref['p99_deg']:.2f} deg; the percentile of each measured isotherm is given in "
            "brackets. It places an isotherm, it does not decide causality: a high percentile says that its "
            "|E*| and Phi agree less than a causal law's usually do at this noise."
            if ref
            else ""
        )
        lines += [
            "",
            "Kramers-Kronig consistency of the measured isotherms (mean |Phi - Phi_Booij-Thoone|, deg): "
            + ", ".join(f"{T} degC: {v:.2f}" + (f" ({pct[T]:.1f} %)" if T in pct else "") for T, v in kk.items())
            + "."
            + ref_text,
        ]
    return lines


def budget_lines(report: dict) -> list[str]:
    """Page section: the error budget table (MRE %, |E*| / Phi, per temperature and component)
    and what each component compares."""
    lines = [
        "",
        "## Error budget (MRE %, \\|E*\\| / Phi)",
        "",
        f"| {_units(report).temperature_header()} | data artifacts | model form | micro-macro transfer | numerics | total |",
        "|---|---|---|---|---|---|",
    ]
    for T, comp in report["error_budget"].items():
        cells = []
        for c in ("data_artifacts", "model_form", "micro_macro_transfer", "numerics", "total"):
            v = comp.get(c)
            cells.append("n/a" if v is None else f"{v['mre_E_norm_pct']:.2f} / {v['mre_phase_pct']:.2f}")
        lines.append(f"| {_units(report).temperature_cell(float(T))} | " + " | ".join(cells) + " |")
    total = "the NSCD simulation" if report["baseline"]["model"].startswith("NSCD") else "the macro Burger's law"
    lines += [
        "",
        "Components: data artifacts = measured vs artifact-corrected means; model form = macro "
        "Burger's law vs corrected means; micro-macro transfer = harmonic response of the NSCD "
        "sample vs its macro Burger's law (n/a without harmonic results); numerics = NSCD "
        "simulation vs harmonic response (n/a without both); total = "
        f"{total} vs the measured means.",
    ]
    return lines


def effects_table(report: dict) -> pd.DataFrame:
    """The cause table of a diagnose report: one row per candidate effect, ``name, category,
    detected, testable, score, p_value, estimate`` (``key=value`` pairs, floats with 4
    significant digits) and ``evidence``."""
    rows = [
        {
            "name": e["name"],
            "category": e["category"],
            "detected": e["detected"],
            "testable": e["testable"],
            "score": e["score"],
            "p_value": e["p_value"],
            "estimate": "; ".join(
                f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in e["estimate"].items()
            ),
            "evidence": e["evidence"],
        }
        for e in report["effects"]
    ]
    return pd.DataFrame(rows)


def crossval_figure(rows: pd.DataFrame, law, path, model: str = "extended_law") -> None:
    """Measured, in-sample and held-out isotherms of one model (top |E*|, bottom Phi vs f),
    saved atomically to ``path``; the in-sample law is drawn as curves when given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import InputError, savefig
    from .crossval import FIT_ERRORS

    sub = rows[rows["model"] == model]
    held = sub[(sub["kind"] == "held_out") & sub["computable"]]
    if len(sub) and held.empty:  # no fold computable: say why, draw nothing
        why = "; ".join(sorted(set(sub.loc[sub["kind"] == "held_out", "reason"].astype(str)))) or "no held-out cell"
        fig, ax = plt.subplots(figsize=(7, 2.5))
        ax.axis("off")
        ax.text(
            0.02, 0.5, f"{sub['scheme'].iloc[0]}: no fold could be computed\n{why}", wrap=True, va="center", fontsize=9
        )
        savefig(fig, path)
        plt.close(fig)
        return
    meas = sub.drop_duplicates(["temperature_C", "frequency_Hz"])
    temps = sorted(meas["temperature_C"].unique())
    fig, axes = plt.subplots(2, 1, figsize=(7, 8), sharex=True)
    colors = plt.get_cmap("viridis")(np.linspace(0, 0.9, max(len(temps), 1)))
    f_all = meas["frequency_Hz"].to_numpy(float)
    fg: np.ndarray | list = (
        np.logspace(np.log10(f_all.min()) - 0.2, np.log10(f_all.max()) + 0.2, 80) if f_all.size else []
    )
    scheme = sub["scheme"].iloc[0] if len(sub) else ""
    for T, color in zip(temps, colors):
        m = meas[meas["temperature_C"] == T].sort_values("frequency_Hz")
        h = sub[(sub["temperature_C"] == T) & (sub["kind"] == "held_out") & sub["computable"]]
        axes[0].plot(m["frequency_Hz"], m["E_norm_MPa_measured"], "o", color=color, label=f"{T:g} degC measured")
        axes[1].plot(m["frequency_Hz"], m["phase_deg_measured"], "o", color=color)
        axes[0].plot(h["frequency_Hz"], h["E_norm_MPa_predicted"], "x", color=color, ms=9, mew=2)
        axes[1].plot(h["frequency_Hz"], h["phase_deg_predicted"], "x", color=color, ms=9, mew=2)
        if law is not None and len(fg):
            try:
                E = law.complex_modulus(fg, np.full(len(fg), T))
            except (InputError, *FIT_ERRORS):
                continue
            axes[0].plot(fg, np.abs(E), "-", color=color, lw=1)
            axes[1].plot(fg, np.degrees(np.angle(E)), "-", color=color, lw=1)
    axes[0].plot([], [], "k-", lw=1, label="in-sample law (fitted on every cell)")
    axes[0].plot([], [], "kx", ms=9, mew=2, label=f"held out ({scheme}: fold's law)")
    axes[0].set_xscale("log")
    axes[0].set_yscale("log")
    axes[0].set_ylabel("norm of E* (MPa)")
    axes[1].set_ylabel("phase angle (deg)")
    axes[1].set_xlabel("frequency (Hz)")
    axes[0].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.suptitle(f"{model.replace('_', ' ')}: measured, in-sample and held-out ({scheme}) isotherms")
    savefig(fig, path)
    plt.close(fig)


def _calibration_rate_sentence(a: dict, cal: dict) -> str:
    """The calibrated level's false-alarm rate: exact by exchangeability, and out of sample by
    cross-fitted halves when each half has the tables to set a level of its own."""
    rate = a["rate"]
    out = ""
    if "exact_rate" in a:
        out += (
            f" A table of a null is named at the level with probability at most {100 * a['exact_rate']:.2f} % "
            f"(k / (B + 1) with B = {cal['n_tables']}: exact, the tables being exchangeable)."
        )
    if rate.get("rate") is None:
        return out + (
            f" No out-of-sample rate: halves of {rate['half_tables']} tables cannot set a "
            f"level of their own at this rate (at least {rate['half_min_tables']} each; "
            "diagnosis.calibration.tables)."
        )
    return out + (
        f" Out of sample (cross-fitted halves) the procedure at that level named an artifact on {rate['k']} of "
        f"{rate['n']} clean tables ({100 * rate['rate']:.1f} %, 95 % interval {100 * rate['ci95'][0]:.1f}-"
        f"{100 * rate['ci95'][1]:.1f} %"
        + (f", under the {rate['null']} null, where it is largest" if "null" in rate else "")
        + ")."
    )
