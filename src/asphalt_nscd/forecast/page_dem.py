"""The forecast page's sections on the discrete model: the ladder by number of constants, the goals,
the error split, the choice inside the fold, and the learned yardstick.

Every number comes from the chain's tables (scores, held-out rows, fold constants, error split,
selection log, interval coverage); :func:`sections` returns the Markdown lines that
:func:`.page.page` places on the page.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import render
from .physical import ALL_STEPS as STEPS
from .physical import CONSTANTS, PREVIOUS

#: the published formula a constant-free forecast is held against (the best published one on the shipped table)
PUBLISHED_YARDSTICK = "witczak_1_40d_published"


def _overall(scores, route, label, group="all"):
    s = scores[
        (scores["binder_route"] == route)
        & (scores["group"] == group)
        & scores["temperature_C"].isna()
        & (scores["label"] == label)
    ]
    return None if s.empty else s.iloc[0]


def _fmt(r, key="abs_logE", digits=1) -> str:
    unit = "pct" if "logE" in key else "deg"
    return render._fmt_ci(r[f"{key}_{unit}"], r[f"{key}_ci_low"], r[f"{key}_ci_high"], digits)


def _paired_text(errors, a, b, route, column, confidence) -> str:
    d = render.paired(errors, a, b, route, column, confidence)
    if d.empty:
        return "–"
    r = d[d["temperature_C"].isna()].iloc[0]
    return f"{r['mean']:+.1f} [{r['ci_low']:+.1f}, {r['ci_high']:+.1f}]"


def _fold_constants(constants: dict, model: str, route: str) -> pd.DataFrame:
    rows = []
    for fit in constants.get("fits", []):
        if fit["model"] != model or fit["binder_route"] != route:
            continue
        st = fit.get("state") or {}
        if "chosen" in st:
            continue
        rows.append({k: st.get(k, np.nan) for k in CONSTANTS} | {"at_bound": ",".join(st.get("at_bound") or [])})
    return pd.DataFrame(rows)


def ladder_section(scores, rows, constants, route, confidence) -> list[str]:
    """The discrete models side by side by their number of fitted constants, each step's held-out
    gain over the step before it (paired over the same mixes), the constants' range over the folds
    against their documented ranges, and the goals."""
    labels = set(scores["label"])
    steps = [(name, free) for name, free in STEPS if name in labels]
    if not steps:
        return []
    errors = render.per_mix_errors(rows)
    L = [
        "## The discrete model by its number of constants",
        "",
        "`dem_physical` fits nothing on mixes: its bonds are mortar bridges whose modulus comes from the binder "
        "by micromechanics (filler, air and fine aggregate, a packing-limited differential scheme) in series with "
        "the stones' elastic compliance, and skeleton contacts through a mastic film of the mix's average film "
        "thickness (squeeze film in series with the stones). Each further step frees one physical constant, "
        "fitted on the training mixes of every fold inside its documented range (`asphalt_nscd.forecast.physical`).",
        "",
        "| model | constants fitted | \\|E*\\| error (%) | phase error (deg) | gain over the step it adds to: \\|E*\\| (points) "
        "| phase (deg) | folds with a constant at a bound |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, free in steps:
        prev = PREVIOUS.get(name) if PREVIOUS.get(name) in labels else None
        r = _overall(scores, route, name)
        c = _fold_constants(constants, name, route)
        n_bound = int((c["at_bound"] != "").sum()) if len(c) else 0
        gain_e = _paired_text(errors, name, prev, route, "e", confidence) if prev else "–"
        gain_p = _paired_text(errors, name, prev, route, "p", confidence) if prev else "–"
        L.append(
            f"| {name} | {len(free)}: {', '.join(free) or 'none'} | {_fmt(r)} | {_fmt(r, 'abs_phase')} | {gain_e} | "
            f"{gain_p} | {n_bound} of {len(c)} |"
        )
    for name, what in (
        ("dem", "1: C_m (legacy)"),
        ("dem_extended", "4: C_m, C_a, C_s, n_s (legacy)"),
        ("dem_selected", "chosen in each fold"),
    ):
        r = _overall(scores, route, name)
        if r is not None:
            L.append(f"| {name} | {what} | {_fmt(r)} | {_fmt(r, 'abs_phase')} | – | – | – |")
    L += [
        "",
        "Gains are paired differences over the same held-out mixes against the step each adds constants to "
        "(`dem_c1` to `dem_physical`, ..., `dem_p2` to `dem_physical`, `dem_p3` to `dem_p2`; negative: better). "
        "`dem_c1` to `dem_c4` carry the skeleton through a mastic film, `dem_p2` and `dem_p3` as a parabolic "
        "element.",
        "",
    ]
    L += physics_line(constants)
    L += _constants_table(constants, [n for n, _ in steps], route)
    L += _goals(scores, errors, route, confidence, constants)
    return L


def physics_line(constants: dict) -> list[str]:
    """The physics options the ladder ran with, from its fits' records (none: a record without them)."""
    for fit in constants.get("fits", []):
        st = fit.get("state") or {}
        if fit["model"] in dict(STEPS) and "air_phase" in st:
            strain, pc = st.get("contact_strain"), st.get("compaction_pressure")
            contacts = [f"also as Hertz contacts at strain {strain:g} (`contact_strain`)"] if strain else []
            if pc:
                contacts.append(
                    f"{'their' if strain else 'also as stone contacts whose'} patches pressed by the "
                    f"compaction at {pc / 1e3:g} kPa (`compaction_pressure_Pa`)"
                )
            return [
                f"Physics options of this run: air voids in the {st['air_phase']} (`forecast.dem.air_phase`), "
                f"skeleton contacts {', '.join(contacts) or 'through their films only (`contact_strain`)'}, "
                f"mortar bridges {'confined by their stones' if st.get('confinement') else 'free'} "
                "(`bridge_confinement`), the mortar's fine aggregate "
                + (
                    f"a skeleton of its own pressed at {st['fine_skeleton_pressure'] / 1e3:g} kPa "
                    "(`fine_skeleton_pressure_Pa`)"
                    + (
                        f", the direct contacts of a network of {st['fine_neighbours']:g} neighbours"
                        " (`fine_contact_neighbours`)."
                        if st.get("fine_neighbours")
                        else " beside the mortar."
                    )
                    if st.get("fine_skeleton_pressure")
                    else "without a skeleton of its own (`fine_skeleton_pressure_Pa`)."
                ),
                "",
            ]
    return []


def _constants_table(constants, names, route) -> list[str]:
    L = [
        "Constants fitted in the folds against their documented ranges:",
        "",
        "| model | constant | smallest | largest | documented range | folds at a bound |",
        "|---|---|---|---|---|---|",
    ]
    any_row = False
    for name in names:
        c = _fold_constants(constants, name, route)
        free = dict(STEPS)[name]
        for k in free:
            if k not in c:
                continue
            v = c[k].to_numpy(float)
            rng = CONSTANTS[k]
            n_at = int(c["at_bound"].str.contains(k).sum())
            L.append(
                f"| {name} | {k} | {v.min():.4g} | {v.max():.4g} | [{rng.low:g}, {rng.high:g}] | {n_at} of {len(v)} |"
            )
            any_row = True
    return (L + [""]) if any_row else []


def _goals(scores, errors, route, confidence, constants) -> list[str]:
    L = ["**Goals.**", ""]
    phys, pub = _overall(scores, route, "dem_physical"), _overall(scores, route, PUBLISHED_YARDSTICK)
    if phys is not None and pub is not None:
        met = phys["abs_logE_pct"] <= pub["abs_logE_pct"]
        L.append(
            f"- `dem_physical` (no constant fitted on mixes) against the published formula {PUBLISHED_YARDSTICK}: "
            f"{phys['abs_logE_pct']:.1f} % against {pub['abs_logE_pct']:.1f} % — {'met' if met else 'not met'} "
            f"(paired: {_paired_text(errors, 'dem_physical', PUBLISHED_YARDSTICK, route, 'e', confidence)} points)."
        )
    dems = scores[
        (scores["binder_route"] == route)
        & (scores["group"] == "all")
        & scores["temperature_C"].isna()
        & scores["label"].str.startswith("dem")
        & ~scores["label"].isin(["dem", "dem_extended"])
    ]
    hirsch = _overall(scores, route, "hirsch_recalibrated")
    if len(dems) and hirsch is not None:
        best = dems.loc[dems["abs_logE_pct"].idxmin()]
        okE = best["abs_logE_pct"] <= hirsch["abs_logE_pct"]
        okP = best["abs_phase_deg"] <= hirsch["abs_phase_deg"]
        L.append(
            f"- The best discrete model with physically bounded constants, by |E*| ({best['label']}: {best['abs_logE_pct']:.1f} %, "
            f"{best['abs_phase_deg']:.1f}°) against recalibrated Hirsch ({hirsch['abs_logE_pct']:.1f} %, "
            f"{hirsch['abs_phase_deg']:.1f}°): {'met' if okE else 'not met'} in |E*| (paired "
            f"{_paired_text(errors, best['label'], 'hirsch_recalibrated', route, 'e', confidence)} points), "
            f"{'met' if okP else 'not met'} in phase (paired "
            f"{_paired_text(errors, best['label'], 'hirsch_recalibrated', route, 'p', confidence)} deg)."
        )
        legacy = _overall(scores, route, "dem_extended")
        if legacy is not None:
            L.append(
                f"- For comparison, the legacy `dem_extended` (four constants without physical bounds): "
                f"{legacy['abs_logE_pct']:.1f} % and {legacy['abs_phase_deg']:.1f}° (paired with recalibrated Hirsch "
                f"{_paired_text(errors, 'dem_extended', 'hirsch_recalibrated', route, 'e', confidence)} points, "
                f"{_paired_text(errors, 'dem_extended', 'hirsch_recalibrated', route, 'p', confidence)} deg)."
            )
    outside = 0
    total = 0
    for name, free in STEPS:
        c = _fold_constants(constants, name, route)
        for k in free:
            if k in c:
                v = c[k].to_numpy(float)
                total += v.size
                outside += int(np.sum((v < CONSTANTS[k].low - 1e-12) | (v > CONSTANTS[k].high + 1e-12)))
    if total:
        L.append(
            f"- Every fitted constant of the ladder inside its documented range in every fold: "
            f"{'met' if outside == 0 else 'not met'} ({outside} of {total} fitted values outside)."
        )
    return L + [""]


def split_section(split: pd.DataFrame) -> list[str]:
    """Each model's held-out |E*| error split by oracle offsets (:func:`.validation.error_split`)."""
    if split is None or split.empty:
        return []
    s = split.sort_values("total_pct")
    L = [
        "## Where the error lies: the mix's level, its temperature dependence, the rest",
        "",
        "Each model's held-out |E*| error, then what would remain if an oracle removed each mix's own mean offset "
        "(its level), then also each isotherm's mean offset (the mix's temperature dependence); the rest is the "
        "frequency dependence inside an isotherm. Parts: total − without level (level), without level − without "
        "temperature (temperature dependence), and the rest.",
        "",
        "| model | route | total (%) | without level (%) | without level and temperature (%) | level part | "
        "temperature part | rest |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for _, r in s.iterrows():
        L.append(
            f"| {r['label']} | {r['binder_route']} | "
            f"{render._fmt_ci(r['total_pct'], r['total_ci_low'], r['total_ci_high'])} | "
            f"{render._fmt_ci(r['without_level_pct'], r['without_level_ci_low'], r['without_level_ci_high'])} | "
            f"{render._fmt_ci(r['without_temperature_pct'], r['without_temperature_ci_low'], r['without_temperature_ci_high'])} | "
            f"{r['level_pct']:.1f} | {r['temperature_pct']:.1f} | {r['rest_pct']:.1f} |"
        )
    ref = s[s["label"] == "hirsch_recalibrated"]
    if len(ref):
        ref = ref.iloc[0]
        L += ["", f"Against recalibrated Hirsch ({ref['binder_route']} route), which part each model reduces:", ""]
        for _, r in s[(s["binder_route"] == ref["binder_route"]) & (s["label"] != "hirsch_recalibrated")].iterrows():
            parts = {
                "level": r["level_pct"] - ref["level_pct"],
                "temperature dependence": r["temperature_pct"] - ref["temperature_pct"],
                "rest": r["rest_pct"] - ref["rest_pct"],
            }
            less = [f"{k} ({v:+.1f})" for k, v in parts.items() if v < 0]
            more = [f"{k} ({v:+.1f})" for k, v in parts.items() if v >= 0]
            L.append(
                f"- {r['label']}: smaller in {', '.join(less) or 'no part'}; larger in {', '.join(more) or 'no part'} (points)."
            )
    return L + [""]


def selection_section(selection: pd.DataFrame) -> list[str]:
    """How often each candidate was chosen inside the folds, and its mean inner score."""
    if selection is None or selection.empty:
        return []
    g = selection.groupby("candidate").agg(
        chosen=("chosen", "sum"), folds=("fold", "nunique"), inner=("inner_score", "mean")
    )
    rule = str(selection["rule"].iloc[0]) if "rule" in selection else "best"
    how = (
        "the simplest candidate (fewest constants fitted, then the base sample before a variant) whose excess over "
        "the least inner held-out score is within one standard error of that excess, paired over the inner mixes "
        "(the one-standard-error rule)"
        if rule == "one_se"
        else "the candidate with the least inner held-out score"
    )
    L = [
        "## The choice inside the fold",
        "",
        f"`dem_selected` picks, in each of its {int(selection['fold'].nunique())} folds, {how} "
        f"({int(selection['inner_folds'].iloc[0])} inner folds of the training mixes; score = "
        "mean |100 ln(E_pred/E_meas)| + mean |phase error| in degrees, per inner mix) and refits it on all the "
        "training mixes; the held-out mix never reaches the choice. The candidates are the ladder's steps on the "
        "base sample and on each sample variant: `<step>@cut<c>_x<s>` is the step on every mix's sample cut at c mm "
        "in a cube of s largest diameters, a step without suffix the base sample (`forecast.dem.cut_mm`, "
        "`size_dmax`). Every variant tried and its inner score, fold by fold: `selection_log.csv`.",
        "",
        "| candidate | folds chosen | mean inner score |",
        "|---|---|---|",
    ]
    for name, r in g.sort_values("inner").iterrows():
        L.append(f"| {name} | {int(r['chosen'])} of {int(r['folds'])} | {r['inner']:.1f} |")
    return L + [""]


def coverage_section(coverage: pd.DataFrame | None, route: str, labels=None) -> list[str]:
    """The prediction intervals' nested coverage of held-out cells per model, quantity and temperature
    (:func:`.intervals.coverage`), for ``labels`` (default: every label of the route)."""
    if coverage is None or coverage.empty:
        return []
    c = coverage[coverage["binder_route"] == route]
    if labels is not None:
        c = c[c["label"].isin(labels)]
    if c.empty:
        return []
    temps = sorted(c["temperature_C"].dropna().unique())
    L = [
        "## Prediction intervals",
        "",
        f"Every forecast carries a {float(c['level'].iloc[0]):.0%} prediction interval calibrated on the held-out "
        "residuals of the other mixes (grouped split-conformal with equal tails, each mix weighted equally; "
        "`asphalt_nscd.forecast.intervals`). Coverage of held-out cells, nested (no mix calibrates its own "
        f"interval): mean over mixes of each mix's covered fraction (%), overall with its {float(c['confidence'].iloc[0]):.0%} "
        "t interval, and per temperature:",
        "",
        "| model | quantity | all | " + " | ".join(f"{T:.1f} °C" for T in temps) + " |",
        "|---|---|---|" + "---|" * len(temps),
    ]
    for (label, q), g in c.groupby(["label", "quantity"], sort=False):
        a = g[g["temperature_C"].isna()]
        if a.empty:
            continue
        a = a.iloc[0]
        cells = [f"{100 * a['coverage']:.1f} [{100 * a['coverage_ci_low']:.1f}, {100 * a['coverage_ci_high']:.1f}]"]
        for T in temps:
            r = g[g["temperature_C"] == T]
            cells.append("–" if r.empty else f"{100 * r.iloc[0]['coverage']:.1f}")
        L.append(f"| {label} | {q} | " + " | ".join(cells) + " |")
    return L + [""]


def learned_section(scores: pd.DataFrame, learned_rows: pd.DataFrame | None, route: str) -> list[str]:
    """The learned yardstick beside the formulas, and how much better it would look judged by random rows."""
    r = _overall(scores, route, "gradient_boosting_learned")
    if r is None:
        return []
    L = [
        "## A data-driven yardstick",
        "",
        "Gradient-boosted trees (scikit-learn) on the formulas' inputs — the binder's |G*| and phase angle at the "
        "condition, temperature, frequency, the four sieve figures, Va, Vbeff, VMA, VFA — tuned inside each fold by "
        "inner folds of the training mixes, judged on the same mixes left out: "
        f"{_fmt(r)} % in |E*| and {_fmt(r, 'abs_phase')}° in phase: what the data alone reach on this table.",
    ]
    if learned_rows is not None and len(learned_rows):
        a = learned_rows[(learned_rows["quantity"] == "logE") & learned_rows["temperature_C"].isna()]
        if len(a):
            a = a.iloc[0]
            L.append(
                f"Judged instead by random rows (cells of the same mix on both sides of the split, tuned by rows), the "
                f"same model would show {a['by_rows']:.1f} % [{a['by_rows_ci_low']:.1f}, {a['by_rows_ci_high']:.1f}]: "
                f"{a['ratio']:.1f} times better [{a['ratio_ci_low']:.1f}, {a['ratio_ci_high']:.1f}] than it forecasts a "
                "mix it never saw (`learned_by_rows.csv`). A figure judged by rows is not a forecast of a new mix."
            )
    return L + [""]
