"""The forecast page's sections on its binder: extrapolated cells, the binder's frequency, its extrapolation.

Each function returns Markdown lines (a ``##`` section, or nothing when its table has nothing
to say) from a table, every number read from it:

* :func:`extrapolated_cells_section`: the held-out errors of the cells whose binder is read
  outside the temperatures of its master curve's points (``binder_extrapolated``) beside those
  read within them (``binder_measured``), from the scores of :func:`.validation.score`;
* :func:`binder_reading_section`: each published formula scored with the binder read at the
  table's binder frequency and at the mix's own frequency, from the table of
  ``reference/forecast/binder_reading.py`` (and its paired differences);
* :func:`extrapolation_section`: the shift laws and glassy moduli compared on the binders' left-out
  isotherms and held out by mix, from the summary of ``reference/forecast/binder_extrapolation.py``.

|E*| errors are mean |100 ln(forecast / measured)| (%), phase errors mean |error| in degrees,
with the t intervals over mixes (or binders) that the tables carry.
"""

from __future__ import annotations

import numpy as np
import pandas as pd


def _ci(v, lo, hi, digits: int = 1, sign: bool = False) -> str:
    """``v [lo, hi]`` (the interval left out when not finite; "–" for a missing value)."""
    if v is None or not np.isfinite(v):
        return "–"
    f = f"{{:{'+' if sign else ''}.{digits}f}}"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f.format(v)
    return f"{f.format(v)} [{f.format(lo)}, {f.format(hi)}]"


def _one(frame: pd.DataFrame, **match) -> pd.Series | None:
    """The row of ``frame`` matching ``match`` (``temperature_C`` NaN matched as NaN), or None."""
    m = np.ones(len(frame), bool)
    for k, v in match.items():
        col = frame[k]
        m &= (col.isna() if isinstance(v, float) and np.isnan(v) else col == v).to_numpy()
    return frame[m].iloc[0] if m.any() else None


def _labels(frame: pd.DataFrame) -> pd.Series:
    return frame["label"] if "label" in frame else frame["model"] + "_" + frame["coefficients"]


def _T(T) -> str:
    return "all" if not np.isfinite(T) else f"{T:.1f}"


def extrapolated_cells_section(scores: pd.DataFrame, route: str) -> list[str]:
    """Markdown lines: the held-out errors of the cells forecast from an extrapolated binder apart
    from the others, per model, on the binder route ``route``.

    Parameters
    ----------
    scores : DataFrame of :func:`.validation.score` (columns :data:`.validation.SCORE_COLUMNS`,
        ``label`` optional).
    route : binder route of the rows shown.

    Returns
    -------
    list of str: a ``##`` section with the count of cells of each group per temperature and a
    table per model (mixes, |E*| and phase errors with their intervals in each group); empty
    when ``scores`` has neither group on ``route``.
    """
    s = scores[scores["binder_route"] == route].assign(label=lambda x: _labels(x))
    groups = ("binder_measured", "binder_extrapolated")
    if not s["group"].isin(groups).any():
        return []
    lab = s[(s["group"] == "all") & s["temperature_C"].isna()].sort_values("n_cells").iloc[-1]["label"]
    c = s[s["label"] == lab]
    L = [
        "## Cells forecast from an extrapolated binder",
        "",
        "A cell's binder is extrapolated when its temperature lies outside the temperatures of the points its "
        "binder's master curve was fitted on (the binder's passing isotherms): there the curve is its shift law's "
        "extrapolation, not data. Cells per temperature (extrapolated of all):",
        "",
    ]
    counts = []
    for T in sorted(c.loc[c["group"] == "all", "temperature_C"].dropna().unique()):
        a = _one(c, group="all", temperature_C=T)
        e = _one(c, group="binder_extrapolated", temperature_C=T)
        counts.append(f"{T:.1f} °C: {0 if e is None else int(e['n_cells'])} of {int(a['n_cells'])}")
    L += ["; ".join(counts) + ".", ""]
    L += [
        "| model | binder measured: mixes | \\|E*\\| error (%) | phase error (°) | binder extrapolated: mixes "
        "| \\|E*\\| error (%) | phase error (°) |",
        "|---|---|---|---|---|---|---|",
    ]
    overall = s[s["temperature_C"].isna()]
    for label in overall.loc[overall["group"] == "all"].sort_values("abs_logE_pct")["label"]:
        cells = []
        for group in groups:
            r = _one(overall, label=label, group=group)
            if r is None:
                cells += ["0", "–", "–"]
                continue
            cells += [
                str(int(r["n_mixes"])),
                _ci(r["abs_logE_pct"], r["abs_logE_ci_low"], r["abs_logE_ci_high"]),
                _ci(r["abs_phase_deg"], r["abs_phase_ci_low"], r["abs_phase_ci_high"]),
            ]
        L.append(f"| {label} | " + " | ".join(cells) + " |")
    return L + [""]


def _reading_name(ratio: float) -> str:
    """The frequency a binder is read at, as a multiple of the mix's frequency f."""
    if np.isclose(ratio, 1.0, rtol=1e-3):
        return "f"
    if np.isclose(ratio, 1.0 / (2.0 * np.pi), rtol=1e-3):
        return "f/2π"
    return f"{ratio:.3g} f"


def binder_reading_section(table: pd.DataFrame, paired: pd.DataFrame | None = None) -> list[str]:
    """Markdown lines: every published formula held out with the binder read at the table's binder
    frequency and at the mix's own frequency.

    Parameters
    ----------
    table : DataFrame of ``reference/forecast/binder_reading.py`` (``-o``): the columns of
        :func:`.validation.score` with ``reading`` (``declared``, ``mix``),
        ``binder_over_mix_frequency`` and ``label``.
    paired : its ``--paired`` table (:func:`.binder_study.paired_difference`), optional.

    Returns
    -------
    list of str: a ``##`` section: per formula the overall errors under both readings, the errors
    per temperature of the published coefficients, and (``paired`` given) the per-mix difference
    of the two readings with its interval; empty when ``table`` does not hold both readings.
    """
    t = table[(table["group"] == "all")].assign(label=lambda x: _labels(x))
    if set(t["reading"]) < {"declared", "mix"}:
        return []
    name = {r: _reading_name(float(g["binder_over_mix_frequency"].iloc[0])) for r, g in t.groupby("reading")}
    L = [
        "## The binder's frequency as the published formulas read it",
        "",
        f"Each formula held out by mix with its binder read at the table's binder frequency ({name['declared']} Hz, "
        f"f the mix's frequency in Hz) and at the mix's own frequency ({name['mix']} Hz). Witczak 1-37A reads the "
        "binder's viscosity at 10 rad/s, whatever the mix's frequency: its two readings are one forecast.",
        "",
        f"| formula | \\|E*\\| error, {name['declared']} (%) | phase error, {name['declared']} (°) | "
        f"\\|E*\\| error, {name['mix']} (%) | phase error, {name['mix']} (°) |",
        "|---|---|---|---|---|",
    ]
    overall = t[t["temperature_C"].isna()]
    for label in overall[overall["reading"] == "declared"].sort_values("abs_logE_pct")["label"]:
        cells = []
        for reading in ("declared", "mix"):
            r = _one(overall, label=label, reading=reading)
            cells += [
                _ci(r["abs_logE_pct"], r["abs_logE_ci_low"], r["abs_logE_ci_high"]) if r is not None else "–",
                _ci(r["abs_phase_deg"], r["abs_phase_ci_low"], r["abs_phase_ci_high"]) if r is not None else "–",
            ]
        L.append(f"| {label} | " + " | ".join(cells) + " |")
    published = sorted(lab for lab in t["label"].unique() if lab.endswith("_published"))
    if published:
        L += [
            "",
            "Per temperature, published coefficients (|E*| error %, phase error °):",
            "",
            "| formula | T (°C) | \\|E*\\|, "
            + name["declared"]
            + " | \\|E*\\|, "
            + name["mix"]
            + " | phase, "
            + name["declared"]
            + " | phase, "
            + name["mix"]
            + " |",
            "|---|---|---|---|---|---|",
        ]
        for label in published:
            for T in [np.nan, *sorted(t["temperature_C"].dropna().unique())]:
                a, b = (_one(t, label=label, reading=r, temperature_C=T) for r in ("declared", "mix"))
                if a is None or b is None:
                    continue
                L.append(
                    f"| {label} | {_T(T)} | "
                    + " | ".join(
                        _ci(r[v], r[f"{k}_ci_low"], r[f"{k}_ci_high"])
                        for v, k in (("abs_logE_pct", "abs_logE"), ("abs_phase_deg", "abs_phase"))
                        for r in (a, b)
                    )
                    + " |"
                )
    if paired is not None and len(paired):
        p = paired[paired["temperature_C"].isna()].assign(label=lambda x: _labels(x))
        L += [
            "",
            f"Reading at {name['mix']} minus reading at {name['declared']}, paired over the same mixes "
            "(negative: the mix's own frequency forecasts better):",
            "",
            "| formula | mixes | \\|E*\\| error (points) | phase error (°) |",
            "|---|---|---|---|",
        ]
        for _, r in p.sort_values("label").iterrows():
            L.append(
                f"| {r['label']} | {int(r['n_mixes'])} | "
                f"{_ci(r['diff_abs_logE_pct'], r['diff_abs_logE_ci_low'], r['diff_abs_logE_ci_high'], sign=True)} | "
                f"{_ci(r['diff_abs_phase_deg'], r['diff_abs_phase_ci_low'], r['diff_abs_phase_ci_high'], sign=True)} |"
            )
    return L + [""]


def _variant(shift: str, glassy: str) -> str:
    return f"{shift}, Gg {'fitted' if glassy == 'fitted' else '1 GPa'}"


#: the formulas shown per temperature by :func:`extrapolation_section`
PER_TEMPERATURE = ("hirsch_recalibrated", "hirsch_published", "witczak_1_37a_published", "witczak_1_40d_published")


def extrapolation_section(table: pd.DataFrame, labels=None, per_temperature=PER_TEMPERATURE) -> list[str]:
    """Markdown lines: the binder extrapolations compared (shift law, glassy modulus).

    Parameters
    ----------
    table : DataFrame, the summary of ``reference/forecast/binder_extrapolation.py``: rows with
        ``check`` ``curves`` (per variant: binders, rungs, glassy moduli), ``isotherm`` (columns of
        :data:`.binder_study.SUMMARY_COLUMNS`) and ``held_out`` (scores per variant, ``group``
        and ``temperature_C`` with the per-mix difference to the default variant,
        :data:`.binder_study.PAIRED_COLUMNS`).
    labels : the formulas shown held out (default: every one of the table).
    per_temperature : the formulas whose held-out |E*| and phase errors are shown per temperature
        under every variant (those the table holds).

    Returns
    -------
    list of str: a ``##`` section: the variants' fits, their left-out isotherm errors (all and
    colder) with the difference to the default variant, the formulas' held-out errors on every
    cell and on the extrapolated cells with the per-mix difference to the default variant, and
    those of ``per_temperature`` per temperature; empty when ``table`` has no row of either check.
    """
    iso = table[table["check"] == "isotherm"]
    held = table[table["check"] == "held_out"]
    curves = table[table["check"] == "curves"]
    if iso.empty and held.empty:
        return []
    L = ["## The binder's extrapolation: shift law and glassy modulus", ""]
    L += [
        "Variants: the shift law of each binder's master curve (A-VTS viscosity, WLF, Arrhenius) and CAM's glassy "
        "modulus Gg (fixed at 1 GPa, or fitted within its bounds); the first listed is the default.",
        "",
    ]
    if len(curves):
        L += [
            "| variant | binders | fitted on their passing points | glassy modulus (GPa) | at its bound "
            "| log10 aT at the coldest temperature |",
            "|---|---|---|---|---|---|",
        ]
        for _, r in curves.iterrows():
            lo, hi = (f"{r[k] / 1e9:.2g}" for k in ("Gg_min_Pa", "Gg_max_Pa"))
            gg = lo if lo == hi else f"{lo}–{hi}"
            L.append(
                f"| {_variant(r['shift'], r['glassy'])} | {int(r['n_binders'])} | {int(r['n_passing_rung'])} | {gg} | "
                f"{int(r['n_Gg_at_bound'])} | {r['log10_aT_coldest_min']:.2f}–{r['log10_aT_coldest_max']:.2f} |"
            )
        L.append("")
    if len(iso):
        L += [
            "Each binder's passing isotherms left out in turn while two or more stay (rmse of ln|G*| on the left-out "
            "points, mean over binders; colder: the left-out isotherm below those kept, the extrapolation the cold "
            "cells rely on; difference: to the default variant on the cases both fit, negative better):",
            "",
            "| variant | cases (binders) | rmse ln\\|G*\\| | difference | colder: cases | rmse ln\\|G*\\| | difference |",
            "|---|---|---|---|---|---|---|",
        ]
        variants = table[table["check"] != "held_out"][["shift", "glassy"]].drop_duplicates()
        for shift, glassy in variants.itertuples(index=False):
            g = iso[(iso["shift"] == shift) & (iso["glassy"] == glassy)]
            a, c = _one(g, position="all"), _one(g, position="colder")
            cells = [f"{int(a['n_cases'])} ({int(a['n_binders'])})" if a is not None else "0"]
            cells += [
                _ci(a["rmse_lnG"], a["rmse_lnG_ci_low"], a["rmse_lnG_ci_high"], 2) if a is not None else "–",
                _ci(a["diff_rmse_lnG"], a["diff_rmse_lnG_ci_low"], a["diff_rmse_lnG_ci_high"], 2, True)
                if a is not None
                else "–",
                str(int(c["n_cases"])) if c is not None else "0",
                _ci(c["rmse_lnG"], c["rmse_lnG_ci_low"], c["rmse_lnG_ci_high"], 2) if c is not None else "–",
                _ci(c["diff_rmse_lnG"], c["diff_rmse_lnG_ci_low"], c["diff_rmse_lnG_ci_high"], 2, True)
                if c is not None
                else "–",
            ]
            L.append(f"| {_variant(shift, glassy)} | " + " | ".join(cells) + " |")
        L.append("")
    if len(held):
        h = held.assign(label=lambda x: _labels(x))
        shown = list(labels) if labels is not None else sorted(h["label"].unique())
        L += [
            "Held out by mix under each variant (every cell, and the cells whose binder is extrapolated; "
            "difference: per mix, to the default variant, negative better):",
            "",
            "| formula | variant | \\|E*\\| error (%) | difference | extrapolated cells: \\|E*\\| error (%) | difference "
            "| phase error (°) |",
            "|---|---|---|---|---|---|---|",
        ]
        overall = h[h["temperature_C"].isna()]
        for label in shown:
            for (shift, glassy), g in overall[overall["label"] == label].groupby(["shift", "glassy"], sort=False):
                a, e = _one(g, group="all"), _one(g, group="binder_extrapolated")
                if a is None:
                    continue
                cells = [
                    _ci(a["abs_logE_pct"], a["abs_logE_ci_low"], a["abs_logE_ci_high"]),
                    _ci(a["diff_abs_logE_pct"], a["diff_abs_logE_ci_low"], a["diff_abs_logE_ci_high"], sign=True),
                    _ci(e["abs_logE_pct"], e["abs_logE_ci_low"], e["abs_logE_ci_high"]) if e is not None else "–",
                    _ci(e["diff_abs_logE_pct"], e["diff_abs_logE_ci_low"], e["diff_abs_logE_ci_high"], sign=True)
                    if e is not None
                    else "–",
                    _ci(a["abs_phase_deg"], a["abs_phase_ci_low"], a["abs_phase_ci_high"]),
                ]
                L.append(f"| {label} | {_variant(shift, glassy)} | " + " | ".join(cells) + " |")
        for label in per_temperature:
            by_T = h[(h["label"] == label) & (h["group"] == "all")]
            temps = sorted(by_T["temperature_C"].dropna().unique())
            if not temps:
                continue
            L += [
                "",
                f"{label} held out per temperature under each variant (|E*| error %; phase error °):",
                "",
                "| variant | " + " | ".join(f"{T:.1f} °C" for T in temps) + " |",
                "|---|" + "---|" * len(temps),
            ]
            for (shift, glassy), g in by_T.groupby(["shift", "glassy"], sort=False):
                cells = []
                for T in temps:
                    r = _one(g, temperature_C=T)
                    cells.append(
                        "–"
                        if r is None
                        else f"{_ci(r['abs_logE_pct'], r['abs_logE_ci_low'], r['abs_logE_ci_high'])}; "
                        f"{_ci(r['abs_phase_deg'], r['abs_phase_ci_low'], r['abs_phase_ci_high'])}"
                    )
                L.append(f"| {_variant(shift, glassy)} | " + " | ".join(cells) + " |")
    return L + [""]
