"""The forecast's page and figures: which model forecasts best where, and by how much.

Reads the chain's tables (binder points, held-out rows and scores, fold constants, forecasts)
and writes the Markdown page ``forecast.md`` and its figures: predicted against measured |E*|
and phase per model, coloured by temperature (:func:`prediction_figure`), and every binder's
master curve with the points its quality checks left out (:func:`binder_figure`).

"Wins" are stated with paired comparisons over the same held-out mixes (:func:`paired`): the
per-mix difference of two models' mean errors, its mean and t interval; a difference whose
interval holds 0 is reported as not resolved.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..io import InputError

#: temperature colours of the figures (coldest blue to hottest red)
CMAP = "coolwarm"


def per_mix_errors(rows: pd.DataFrame) -> pd.DataFrame:
    """Each mix's mean |100 ln(E_pred/E_meas)| and mean |phase error| (deg) per (label, binder
    route, temperature; ``temperature_C`` NaN: every condition)."""
    d = rows.assign(
        e=np.abs(100.0 * np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"])),
        p=np.abs(rows["phase_pred_deg"] - rows["phase_meas_deg"]),
    )
    keys = ["label", "binder_route", "mix_id"]
    overall = d.groupby(keys)[["e", "p"]].mean().reset_index().assign(temperature_C=np.nan)
    by_T = d.groupby([*keys, "temperature_C"])[["e", "p"]].mean().reset_index()
    return pd.concat([overall, by_T], ignore_index=True)


def paired(errors: pd.DataFrame, a: str, b: str, route: str, column: str, confidence: float = 0.95) -> pd.DataFrame:
    """Per temperature (and overall, NaN), the mean over mixes of model ``a``'s per-mix error
    minus ``b``'s (``column`` ``e`` for |E*| in %, ``p`` for phase in degrees), its t interval and
    the number of mixes (negative: ``a`` better)."""
    from ..diagnosis.scores import t_interval

    e = errors[errors["binder_route"] == route]
    out = []
    for T in [np.nan, *sorted(e["temperature_C"].dropna().unique())]:
        sel = e[e["temperature_C"].isna()] if np.isnan(T) else e[e["temperature_C"] == T]
        w = sel.pivot_table(index="mix_id", columns="label", values=column)
        if a not in w or b not in w:
            continue
        diff = (w[a] - w[b]).dropna().to_numpy(float)
        lo, hi = t_interval(diff, confidence) if diff.size >= 2 else (np.nan, np.nan)
        out.append({"temperature_C": T, "mean": float(diff.mean()), "ci_low": lo, "ci_high": hi, "n_mixes": diff.size})
    return pd.DataFrame(out)


def trends(rows: pd.DataFrame, features: pd.DataFrame, route: str, labels, confidence: float = 0.95) -> pd.DataFrame:
    """The table's own trend with the formulation, and what each model leaves of it.

    For each temperature and each feature column of ``features`` (index mix_id: e.g. the coarse
    aggregate fraction, VMA), the least-squares slope over the mixes of the measured mean
    100 ln|E*| (``label`` "measured") and of each model's mean held-out error 100 ln(E_forecast /
    E_measured) (a slope near 0: the model follows the trend), with its t(n - 2) interval."""
    from scipy import stats

    d = rows[rows["binder_route"] == route].assign(
        e=100.0 * np.log(rows["E_pred_MPa"] / rows["E_meas_MPa"]), m=100.0 * np.log(rows["E_meas_MPa"])
    )
    out = []
    for T, g in d.groupby("temperature_C"):
        per = {"measured": g.groupby("mix_id")["m"].mean()}
        per |= {lab: g[g["label"] == lab].groupby("mix_id")["e"].mean() for lab in labels}
        for feature in features.columns:
            for lab, y in per.items():
                x = features[feature].reindex(y.index.astype(str)).to_numpy(float)
                ok = np.isfinite(x) & np.isfinite(y.to_numpy(float))
                if ok.sum() < 4:
                    continue
                fit = stats.linregress(x[ok], y.to_numpy(float)[ok])
                h = stats.t.ppf(0.5 + confidence / 2, ok.sum() - 2) * fit.stderr
                out.append(
                    {
                        "temperature_C": T,
                        "feature": feature,
                        "label": lab,
                        "slope": fit.slope,
                        "ci_low": fit.slope - h,
                        "ci_high": fit.slope + h,
                        "n_mixes": int(ok.sum()),
                    }
                )
    return pd.DataFrame(out)


def _fmt_ci(v, lo, hi, digits=1) -> str:
    if not np.isfinite(v):
        return "–"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{v:.{digits}f}"
    return f"{v:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def score_table(scores: pd.DataFrame, route: str, group: str = "all") -> str:
    """Markdown table of every model's overall held-out errors (route, group)."""
    s = scores[(scores["binder_route"] == route) & (scores["group"] == group) & scores["temperature_C"].isna()]
    s = s.sort_values("abs_logE_pct")
    lines = [
        "| model | mixes | mean abs ln error of \\|E*\\| (%) | largest (%) | bias (%) | mean abs phase error (deg) | largest (deg) | bias (deg) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for _, r in s.iterrows():
        lines.append(
            f"| {r['label']} | {int(r['n_mixes'])} | {_fmt_ci(r['abs_logE_pct'], r['abs_logE_ci_low'], r['abs_logE_ci_high'])}"
            f" | {r['max_abs_logE_pct']:.0f} | {_fmt_ci(r['bias_logE_pct'], r['bias_logE_ci_low'], r['bias_logE_ci_high'])}"
            f" | {_fmt_ci(r['abs_phase_deg'], r['abs_phase_ci_low'], r['abs_phase_ci_high'])}"
            f" | {r['max_abs_phase_deg']:.1f} | {_fmt_ci(r['bias_phase_deg'], r['bias_phase_ci_low'], r['bias_phase_ci_high'])} |"
        )
    return "\n".join(lines)


def temperature_table(scores: pd.DataFrame, route: str, column: str, unit: str) -> str:
    """Markdown table: one row per model, one column per temperature, of ``column`` (with its
    interval) for every mix (route)."""
    s = scores[(scores["binder_route"] == route) & (scores["group"] == "all") & scores["temperature_C"].notna()]
    temps = sorted(s["temperature_C"].unique())
    base = column.replace("_pct", "").replace("_deg", "")
    head = "| model | " + " | ".join(f"{T:.1f} °C" for T in temps) + " |"
    lines = [head, "|---|" + "---|" * len(temps)]
    order = scores[(scores["binder_route"] == route) & (scores["group"] == "all") & scores["temperature_C"].isna()]
    for lab in order.sort_values(column)["label"]:
        cells = []
        for T in temps:
            r = s[(s["label"] == lab) & (s["temperature_C"] == T)]
            cells.append(
                _fmt_ci(*(r.iloc[0][c] for c in (column, f"{base}_ci_low", f"{base}_ci_high"))) if len(r) else "–"
            )
        lines.append(f"| {lab} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + f"\n\n({unit}; 95 % t intervals over the held-out mixes)"


def best_where(scores: pd.DataFrame, route: str) -> pd.DataFrame:
    """Per temperature and overall: the model with the lowest mean abs |E*| log error and the one
    with the lowest mean abs phase error (every mix, ``route``)."""
    s = scores[(scores["binder_route"] == route) & (scores["group"] == "all")]
    out = []
    for T, g in s.groupby(s["temperature_C"].fillna(-999.0), sort=True):
        e, p = g.loc[g["abs_logE_pct"].idxmin()], g.loc[g["abs_phase_deg"].idxmin()]
        out.append(
            {
                "temperature_C": np.nan if T == -999.0 else T,
                "best_E": e["label"],
                "best_E_pct": e["abs_logE_pct"],
                "best_phase": p["label"],
                "best_phase_deg": p["abs_phase_deg"],
            }
        )
    return pd.DataFrame(out)


def prediction_figure(rows: pd.DataFrame, route: str):
    """Predicted against measured |E*| (top row) and phase (bottom row), one column per model,
    held-out cells of ``route`` coloured by temperature."""
    import matplotlib.pyplot as plt

    d = rows[rows["binder_route"] == route]
    labels = list(dict.fromkeys(d["label"]))
    if not labels:
        raise InputError(f"forecast rows: no held-out prediction for the binder route {route!r}")
    fig, axes = plt.subplots(2, len(labels), figsize=(2.6 * len(labels), 5.4), squeeze=False)
    temps = sorted(d["temperature_C"].unique())
    colours = plt.get_cmap(CMAP)(np.linspace(0, 1, len(temps)))
    for k, lab in enumerate(labels):
        g = d[d["label"] == lab]
        top, bottom = axes[0, k], axes[1, k]
        for T, c in zip(temps, colours):
            h = g[g["temperature_C"] == T]
            top.loglog(h["E_meas_MPa"], h["E_pred_MPa"], ".", ms=3, color=c, label=f"{T:.1f} °C")
            bottom.plot(h["phase_meas_deg"], h["phase_pred_deg"], ".", ms=3, color=c)
        lim = [d["E_meas_MPa"].min() / 2, d["E_meas_MPa"].max() * 2]
        top.plot(lim, lim, "k-", lw=0.6)
        bottom.plot([0, 60], [0, 60], "k-", lw=0.6)
        top.set_title(lab, fontsize=7)
        top.set_xlabel("measured |E*| (MPa)", fontsize=7)
        bottom.set_xlabel("measured phase (deg)", fontsize=7)
        bottom.set_ylim(-5, 95)
        for ax in (top, bottom):
            ax.tick_params(labelsize=6)
    axes[0, 0].set_ylabel("held-out forecast |E*| (MPa)", fontsize=7)
    axes[1, 0].set_ylabel("held-out forecast phase (deg)", fontsize=7)
    axes[0, 0].legend(fontsize=6, frameon=False)
    fig.suptitle(f"Mixes left out, binder read through its {route}", fontsize=9)
    fig.tight_layout()
    return fig


def binder_figure(points: pd.DataFrame, curves: dict):
    """Each binder's |G*| against reduced frequency: the points that pass (filled), those left
    out (crosses, by reason), and its master curve (:class:`.binder.BinderCurve`)."""
    import matplotlib.pyplot as plt

    binders = sorted(points["binder"].unique())
    n = len(binders)
    cols = int(np.ceil(np.sqrt(n)))
    rows_ = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows_, cols, figsize=(2.4 * cols, 2.1 * rows_), squeeze=False, sharey=True)
    temps = sorted(points["temperature_C"].unique())
    colours = dict(zip(temps, plt.get_cmap(CMAP)(np.linspace(0, 1, len(temps)))))
    for ax, b in zip(axes.ravel(), binders):
        g = points[points["binder"] == b]
        c = curves.get(b)
        for T, h in g.groupby("temperature_C"):
            x = np.log10(2 * np.pi * h["frequency_Hz"]) + (c.log_shift(T) if c else 0.0)
            ok = h["passed"].to_numpy(bool)
            ax.semilogy(x[ok], h["G_Pa"][ok], "o", ms=3, color=colours[T])
            ax.semilogy(x[~ok], h["G_Pa"][~ok], "x", ms=4, color=colours[T])
        if c is not None:
            w = np.linspace(-8, 12, 200)
            ax.semilogy(w, c.G_Pa(c.T_ref_C, 10**w / (2 * np.pi)), "k-", lw=0.8)
        ax.set_title(f"{b} (mixes {g['mixes'].iloc[0]})" if "mixes" in g else b, fontsize=6)
        ax.tick_params(labelsize=6)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.supxlabel("log10 reduced angular frequency (rad/s)", fontsize=8)
    fig.supylabel("binder |G*| (Pa)", fontsize=8)
    fig.suptitle("Binder master curves (CAM); crosses: points left out by the quality checks", fontsize=9)
    fig.tight_layout()
    return fig
