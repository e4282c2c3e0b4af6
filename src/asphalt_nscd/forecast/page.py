"""The forecast page: which model forecasts best where and by how much, in plain words.

:func:`page` writes the Markdown of ``forecast.md`` from the chain's tables: the table and its
binders' quality, every model's held-out errors (mixes left out, binder through its master curve,
the raw binder beside), the paired comparisons that decide "best", what the discrete model gets
wrong and what its extension gains, its constants against their physical ranges, and the
forecasts with their Level 1 tables. Numbers come from the tables it is given; nothing is typed in.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import render

#: physical range (low, high) of the discrete model's constants: a bond or a contact stiffer than the stone
#: it joins (C_a, C_s above 1) is not physical; the mortar's modulus is a lower bound (Hashin-Shtrikman), so
#: its bridge cannot be softer than it (C_m below 1); the skeleton's exponent lies between an elastic
#: contact (0) and one that follows the mortar (1)
PHYSICAL = {"C_m": (1.0, np.inf), "C_a": (0.0, 1.0), "C_s": (0.0, 1.0), "n_s": (0.0, 1.0)}


def _overall(scores, route, label, group="all"):
    s = scores[
        (scores["binder_route"] == route)
        & (scores["group"] == group)
        & scores["temperature_C"].isna()
        & (scores["label"] == label)
    ]
    return None if s.empty else s.iloc[0]


def _best_baseline(scores, route) -> str | None:
    s = scores[
        (scores["binder_route"] == route)
        & (scores["group"] == "all")
        & scores["temperature_C"].isna()
        & scores["label"].str.endswith("_recalibrated")
    ]
    return None if s.empty else str(s.loc[s["abs_logE_pct"].idxmin(), "label"])


def _sentence_pair(errors, a, b, route, column, unit, confidence) -> list[str]:
    """Lines: per temperature and overall, a - b with its interval, resolved or not."""
    d = render.paired(errors, a, b, route, column, confidence)
    out = []
    for _, r in d.iterrows():
        where = "over every condition" if np.isnan(r["temperature_C"]) else f"at {r['temperature_C']:.1f} °C"
        if np.isfinite(r["ci_low"]) and (r["ci_high"] < 0 or r["ci_low"] > 0):
            verdict = f"{a if r['mean'] < 0 else b} is better"
        else:
            verdict = "not resolved (the interval holds 0)"
        out.append(
            f"- {where}: {a} minus {b} = {r['mean']:+.1f} {unit} [{r['ci_low']:+.1f}, {r['ci_high']:+.1f}]"
            f" over {int(r['n_mixes'])} mixes: {verdict}"
        )
    return out


def _constants(constants: dict) -> pd.DataFrame:
    rows = []
    for fit in constants.get("fits", []):
        state = fit.get("state") or {}
        for k in PHYSICAL:
            if k in state and fit["model"].startswith("dem"):
                rows.append({"model": fit["model"], "route": fit["binder_route"], "constant": k, "value": state[k]})
        if state.get("at_bound"):
            rows.append({"model": fit["model"], "route": fit["binder_route"], "constant": "at_bound", "value": 1.0})
    return pd.DataFrame(rows, columns=["model", "route", "constant", "value"])


def page(
    table_name: str,
    matched: pd.DataFrame,
    points: pd.DataFrame,
    rows: pd.DataFrame,
    scores: pd.DataFrame,
    constants: dict,
    forecast: pd.DataFrame,
    best: str,
    route: str,
    confidence: float,
    figures: dict,
    split: pd.DataFrame | None = None,
    selection: pd.DataFrame | None = None,
    coverage: pd.DataFrame | None = None,
    learned_rows: pd.DataFrame | None = None,
) -> str:
    """The Markdown page (module docstring). ``figures``: name -> path relative to the page;
    ``split``, ``selection``, ``coverage``: the error split, the selection log and the intervals'
    coverage (:mod:`.page_dem`)."""
    from . import binder_report, page_dem

    measured = matched.dropna(subset=["E_norm_MPa"])["mix_id"].unique()
    todo = matched[matched["E_norm_MPa"].isna()]["mix_id"].unique()
    errors = render.per_mix_errors(rows)
    L = [f"# Forecast of {table_name}: |E*| and phase from binder, gradation and volumetrics", ""]
    L += [
        f"{len(measured)} mixes with measured |E*| and phase, {len(todo)} to forecast, "
        f"{points['binder'].nunique()} binders. Every error below is held out: each mix is forecast by models "
        "fitted on the other mixes only (leave one mix out); the binder is read through its master curve "
        f"(route `{route}`) unless said. |E*| errors are 100 |ln(forecast/measured)| (%), phase errors in degrees; "
        f"intervals are {confidence:.0%} t intervals over the held-out mixes.",
        "",
        "## Which model forecasts best",
        "",
    ]
    where = render.best_where(scores, route)
    for _, r in where.iterrows():
        at = "Over every condition" if np.isnan(r["temperature_C"]) else f"At {r['temperature_C']:.1f} °C"
        L.append(
            f"- {at}: lowest |E*| error {r['best_E']} ({r['best_E_pct']:.1f} %), lowest phase error "
            f"{r['best_phase']} ({r['best_phase_deg']:.1f}°)."
        )
    overall = scores[(scores["binder_route"] == route) & (scores["group"] == "all") & scores["temperature_C"].isna()]
    for column, key, unit in (("e", "abs_logE_pct", "%"), ("p", "abs_phase_deg", "deg")):
        ranked = overall.sort_values(key)["label"].tolist()
        if len(ranked) >= 2:
            d = render.paired(errors, ranked[0], ranked[1], route, column, confidence)
            r = d[d["temperature_C"].isna()].iloc[0]
            resolved = np.isfinite(r["ci_high"]) and r["ci_high"] < 0
            L.append(
                f"- {'|E*|' if column == 'e' else 'Phase'}: {ranked[0]} against the runner-up {ranked[1]}, paired over "
                f"{int(r['n_mixes'])} mixes: {r['mean']:+.1f} {unit} [{r['ci_low']:+.1f}, {r['ci_high']:+.1f}]"
                f" ({'resolved' if resolved else 'not resolved: the interval holds 0'})."
            )
    base = _best_baseline(scores, route)
    dem_labels = [lab for lab in ("dem_extended", "dem") if lab in set(scores["label"])]
    if (
        base
        and dem_labels
        and not any(lab.startswith("dem_") and lab not in ("dem_extended",) for lab in set(scores["label"]))
    ):
        top = dem_labels[0]
        b, t = _overall(scores, route, base), _overall(scores, route, top)
        goal_E = t["abs_logE_pct"] <= b["abs_logE_pct"]
        goal_P = t["abs_phase_deg"] <= b["abs_phase_deg"]
        L += [
            "",
            f"**The discrete model against the best recalibrated formula ({base}).** {top}: "
            f"{t['abs_logE_pct']:.1f} % and {t['abs_phase_deg']:.1f}°; {base}: {b['abs_logE_pct']:.1f} % and "
            f"{b['abs_phase_deg']:.1f}°. Goal (no worse in mean |E*| log error and in mean phase error): "
            f"{'met' if goal_E else 'not met'} in |E*|, {'met' if goal_P else 'not met'} in phase. Paired over the "
            "same mixes (negative: the discrete model is better):",
            "",
            *_sentence_pair(errors, top, base, route, "e", "%", confidence),
            *_sentence_pair(errors, top, base, route, "p", "deg", confidence),
        ]
    L += ["", "## Held-out errors", "", render.score_table(scores, route), ""]
    L += [f"![predicted against measured]({figures['predictions']})", ""]
    L += ["### |E*| error by temperature", "", render.temperature_table(scores, route, "abs_logE_pct", "%"), ""]
    L += ["### Phase error by temperature", "", render.temperature_table(scores, route, "abs_phase_deg", "deg"), ""]
    L += page_dem.ladder_section(scores, rows, constants, route, confidence)
    L += page_dem.selection_section(selection)
    L += page_dem.split_section(split)
    L += page_dem.learned_section(scores, learned_rows, route)
    L += _route_section(scores, route)
    L += _seen_section(scores, route)
    L += _dem_section(scores, route, constants, errors, confidence, rows, matched)
    L += binder_report.extrapolated_cells_section(scores, route)
    L += _binder_section(points, figures)
    L += page_dem.coverage_section(coverage, route)
    L += _forecast_section(forecast, best, todo)
    return "\n".join(L) + "\n"


def _route_section(scores, route) -> list[str]:
    other = [r for r in scores["binder_route"].unique() if r != route]
    if not other:
        return []
    o = other[0]
    L = ["## The binder through its master curve against the table's raw values", ""]
    L += [
        "| model | \\|E*\\| error, curve (%) | raw (%) | phase error, curve (deg) | raw (deg) |",
        "|---|---|---|---|---|",
    ]
    for lab in scores["label"].unique():
        a, b = _overall(scores, route, lab), _overall(scores, o, lab)
        if a is None or b is None:
            continue
        L.append(
            f"| {lab} | {a['abs_logE_pct']:.1f} | {b['abs_logE_pct']:.1f} | {a['abs_phase_deg']:.1f} | {b['abs_phase_deg']:.1f} |"
        )
    return L + [""]


def _seen_section(scores, route) -> list[str]:
    L = ["## Mixes whose binder serves a training mix, and mixes whose binder does not", ""]
    L += [
        "| model | binder seen: mixes, \\|E*\\| error (%) | binder unseen: mixes, \\|E*\\| error (%) |",
        "|---|---|---|",
    ]
    for lab in scores["label"].unique():
        a, b = _overall(scores, route, lab, "binder_seen"), _overall(scores, route, lab, "binder_unseen")
        fa = (
            f"{int(a['n_mixes'])}, {render._fmt_ci(a['abs_logE_pct'], a['abs_logE_ci_low'], a['abs_logE_ci_high'])}"
            if a is not None
            else "–"
        )
        fb = (
            f"{int(b['n_mixes'])}, {render._fmt_ci(b['abs_logE_pct'], b['abs_logE_ci_low'], b['abs_logE_ci_high'])}"
            if b is not None
            else "–"
        )
        L.append(f"| {lab} | {fa} | {fb} |")
    return L + [""]


def _dem_section(scores, route, constants, errors, confidence, rows, matched) -> list[str]:
    if "dem" not in set(scores["label"]):
        return []
    L = ["## What the discrete model gets wrong, and what its extension gains", ""]
    s = scores[(scores["binder_route"] == route) & (scores["group"] == "all") & scores["temperature_C"].notna()]
    L += [
        "| T (°C) | dem: \\|E*\\| bias (%) | dem: phase bias (deg) | dem_extended: \\|E*\\| bias (%) | dem_extended: phase bias (deg) |"
    ]
    L += ["|---|---|---|---|---|"]
    for T in sorted(s["temperature_C"].unique()):
        a = s[(s["label"] == "dem") & (s["temperature_C"] == T)]
        b = s[(s["label"] == "dem_extended") & (s["temperature_C"] == T)]
        if a.empty:
            continue
        a = a.iloc[0]
        bb = b.iloc[0] if len(b) else None
        L.append(
            f"| {T:.1f} | {a['bias_logE_pct']:+.0f} | {a['bias_phase_deg']:+.1f} | "
            + (f"{bb['bias_logE_pct']:+.0f} | {bb['bias_phase_deg']:+.1f} |" if bb is not None else "– | – |")
        )
    L += [
        "",
        "The bonds of `dem` carry the mortar alone, so the sample's modulus is the mortar's times a network "
        "constant and its phase angle is the binder's: far too soft and too viscous where the binder is soft, too "
        "stiff where it is glassy (the biases above). `dem_extended` adds the two load paths a mix has and rigid "
        "spheres in a mortar lack: the stones' own compliance in series with every bond (the glassy limit) and the "
        "aggregate skeleton, contacts on the pairs in contact in the packed layer whose stiffness follows the "
        "mortar's only as its power n_s (a parabolic element: the load path that does not follow the binder).",
        "",
    ]
    if "dem_extended" in set(scores["label"]):
        L += ["Held-out gain of the extension, paired over the same mixes (negative: `dem_extended` better):", ""]
        L += _sentence_pair(errors, "dem_extended", "dem", route, "e", "%", confidence)
        L += _sentence_pair(errors, "dem_extended", "dem", route, "p", "deg", confidence)
    L += _trend_lines(rows, matched, route, confidence)
    c = _constants(constants)
    if len(c):
        L += ["", "Constants fitted in the folds (every fold, both routes), against their physical range:", ""]
        L += [
            "| model | constant | smallest | largest | physical range | folds outside it |",
            "|---|---|---|---|---|---|",
        ]
        for (model, k), g in c[c["constant"] != "at_bound"].groupby(["model", "constant"]):
            lo, hi = PHYSICAL[k]
            n_out = int(np.sum((g["value"] < lo) | (g["value"] > hi)))
            bounds = f"[{lo:g}, ∞)" if np.isinf(hi) else f"({lo:g}, {hi:g}]"
            L.append(
                f"| {model} | {k} | {g['value'].min():.3g} | {g['value'].max():.3g} | {bounds} | {n_out} of {len(g)} |"
            )
        n_bound = int(np.sum(c["constant"] == "at_bound"))
        L += ["", f"Fits with a constant at its search bound: {n_bound}."]
    return L + [""]


def _features(matched: pd.DataFrame, cut_mm: float) -> pd.DataFrame:
    """Per mix: its coarse-aggregate volume fraction above the cut (%) and its VMA (%)."""
    from .formulation import phase_volumes

    first = matched.groupby("mix_id", sort=False).first()
    v = {m: phase_volumes(r.assign(mix_id=m) if hasattr(r, "assign") else r, cut_mm) for m, r in first.iterrows()}
    return pd.DataFrame(
        {"coarse_pct": {m: 100 * x["coarse"] for m, x in v.items()}, "VMA_pct": {m: x["VMA_pct"] for m, x in v.items()}}
    )


def _trend_lines(rows, matched, route, confidence, cut_mm: float = 4.0) -> list[str]:
    """The table's own trend of |E*| with the coarse-aggregate fraction and VMA, per temperature,
    and the trend each model leaves in its held-out errors (render.trends)."""
    labels = [lab for lab in ("dem", "dem_extended", "hirsch_recalibrated") if lab in set(rows["label"])]
    t = render.trends(rows, _features(matched, cut_mm), route, labels, confidence)
    if t.empty:
        return []
    L = [
        "",
        "**The table's own trend with the gradation and the voids.** Slope over the mixes, per temperature, of the "
        "measured 100 ln|E*| and of each model's held-out error 100 ln(forecast/measured), per percentage point of "
        f"coarse-aggregate volume (above the {cut_mm:g} mm cut) and of VMA (a model that follows the table's trend "
        "leaves a slope near 0):",
        "",
        "| T (°C) | per | " + " | ".join(["measured", *labels]) + " |",
        "|---|---|" + "---|" * (1 + len(labels)),
    ]
    for (T, feature), g in t.groupby(["temperature_C", "feature"], sort=True):
        cells = []
        for lab in ["measured", *labels]:
            r = g[g["label"] == lab]
            cells.append("–" if r.empty else _ci(r.iloc[0]))
        L.append(f"| {T:.1f} | {feature.replace('_pct', '')} | " + " | ".join(cells) + " |")
    return L + [""]


def _ci(r) -> str:
    return f"{r['slope']:+.1f} [{r['ci_low']:+.1f}, {r['ci_high']:+.1f}]"


def _binder_section(points, figures) -> list[str]:
    L = ["## The binders' own data quality", ""]
    p = points.copy()
    p["T"] = p["temperature_C"].round(1)
    L += ["| T (°C) | points | passed | left out: reasons |", "|---|---|---|---|"]
    for T, g in p.groupby("T"):
        reasons = g.loc[~g["passed"], "reason"].str.split(";").explode().value_counts()
        text = ", ".join(f"{k} {v}" for k, v in reasons.items()) or "–"
        L.append(f"| {T:.1f} | {len(g)} | {int(g['passed'].sum())} | {text} |")
    L += [
        "",
        "Every forecast reads the binder through its master curve fitted on the points that pass (CAM with the "
        "binder's A-VTS viscosity shift); the points left out, with their reasons, are in `binder_points.csv`.",
        "",
        f"![binder master curves]({figures['binders']})",
        "",
    ]
    return L


def _forecast_section(forecast, best, todo) -> list[str]:
    L = ["## Forecasts", ""]
    if len(todo) == 0:
        return L + ["No mix of the table has empty |E*| and phase cells: nothing to forecast.", ""]
    L += [
        f"{len(todo)} mixes forecast by every model (`forecast.csv`): {', '.join(map(str, todo))}. Their Level 1 "
        f"dynamic-modulus tables (temperatures × frequencies, psi and MPa, `level1_tables.csv`) and sigmoidal "
        f"master curves (`sigmoid_master_curves.csv`) are those of {best}, the model with the lowest held-out |E*| "
        "error over every condition.",
        "",
    ]
    return L
