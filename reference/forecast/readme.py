"""Write reference/forecast/README.md from the committed tables beside it (every number computed here).

    python reference/forecast/readme.py            # write README.md
    python reference/forecast/readme.py --check    # exit 1 when README.md is not what the tables give

Reads ``<label>_crossval.csv``, ``<label>_per_mix.csv``, ``<label>_costs.csv``, ``<label>_constants.csv``
and ``<label>_seed_spread.csv`` for the labels ``default`` and ``reference``, the binder's reading and
extrapolation tables (``binder_reading.csv`` with ``binder_reading_paired.csv``,
``binder_extrapolation_summary.csv``, rendered by ``asphalt_nscd.forecast.binder_report``) and the size
study's ``size_study_summary.csv``, the candidate physics ``physics_probe.csv``, the answer to binder in place
of air ``volumetric_sensitivity.csv`` and the sample variants' cost
``variant_cost.csv``; a table that is missing leaves its section out.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROUTE = "curve"


def _read(name: str) -> pd.DataFrame | None:
    p = HERE / name
    return pd.read_csv(p, dtype={"mix_id": str}) if p.exists() else None


def _ci(v, lo, hi, d=1) -> str:
    return f"{v:.{d}f} [{lo:.{d}f}, {hi:.{d}f}]"


def _mean_ci(d, digits=1) -> str:
    """A paired difference over the mixes: its mean with the t(n - 1) 95 % interval."""
    from asphalt_nscd.diagnosis.scores import t_interval

    v = np.asarray(d, float)
    return _ci(v.mean(), *t_interval(v), d=digits)


def headline(scores: pd.DataFrame) -> list[str]:
    s = scores[(scores["binder_route"] == ROUTE) & (scores["group"] == "all") & scores["temperature_C"].isna()]
    lines = ["| model | mean abs 100 ln(E_f/E_m) (%) | mean abs phase error (°) | largest (%) |", "|---|---|---|---|"]
    for _, r in s.sort_values("abs_logE_pct").iterrows():
        lines.append(
            f"| {r['label']} | {_ci(r['abs_logE_pct'], r['abs_logE_ci_low'], r['abs_logE_ci_high'])} | "
            f"{_ci(r['abs_phase_deg'], r['abs_phase_ci_low'], r['abs_phase_ci_high'])} | {r['max_abs_logE_pct']:.0f} |"
        )
    return lines


def paired(per_mix: pd.DataFrame, a: str, b: str) -> list[str]:
    e = per_mix[per_mix["binder_route"] == ROUTE]
    lines = [f"| T (°C) | {a} − {b}: \\|E*\\| (%) | phase (°) |", "|---|---|---|"]
    for T in [np.nan, *sorted(e["temperature_C"].dropna().unique())]:
        sel = e[e["temperature_C"].isna()] if np.isnan(T) else e[e["temperature_C"] == T]
        cells = []
        for col in ("e", "p"):
            w = sel.pivot_table(index="mix_id", columns="label", values=col)
            cells.append(_mean_ci((w[a] - w[b]).dropna()))
        lines.append(f"| {'all' if np.isnan(T) else f'{T:.1f}'} | " + " | ".join(cells) + " |")
    return lines


def costs(c: pd.DataFrame) -> list[str]:
    c = (
        c.assign(variant=c["variant"].astype(object).where(c["variant"].notna(), ""))
        if "variant" in c
        else c.assign(variant="")
    )
    if "earlier_run" in c:  # preparations the run reused from an earlier run of the same samples
        c = c.assign(variant=c["variant"].where(~c["earlier_run"].astype(bool), c["variant"] + "*"))
    g = c.groupby(["command", "variant"])["cpu_s"]
    per_mix = c[c["command"].isin(["forecast-pack", "forecast-sample", "forecast-response"])]
    n = per_mix["mix_id"].nunique()
    lines = [
        "| command | sample | jobs | CPU total (s) | per job: mean (s) | largest (s) |",
        "|---|---|---|---|---|---|",
    ]
    for (cmd, variant), v in g:
        sample = variant.replace("*", "") or (
            "base" if cmd in ("forecast-pack", "forecast-sample", "forecast-response") else ""
        )
        sample += " (earlier run)" if variant.endswith("*") else ""
        lines.append(f"| {cmd} | {sample} | {v.size} | {v.sum():.0f} | {v.mean():.1f} | {v.max():.1f} |")
    lines += [
        "",
        f"Per mix (packing, sample and response over its seeds and samples): {per_mix['cpu_s'].sum() / n:.0f} s; "
        f"the whole chain {c['cpu_s'].sum():.0f} s of CPU.",
    ]
    if c["variant"].str.endswith("*").any():
        lines += [
            "",
            "(earlier run): preparations whose samples the run's configuration left unchanged, reused from the "
            "earlier run that prepared them, with that run's records.",
        ]
    return lines


def ladder(scores: pd.DataFrame, per_mix: pd.DataFrame | None) -> list[str]:
    """The physical ladder's steps side by side with each step's paired gain over the one before."""
    from asphalt_nscd.forecast.physical import ALL_STEPS as STEPS
    from asphalt_nscd.forecast.physical import PREVIOUS

    labels = set(scores["label"])
    steps = [(n, free) for n, free in STEPS if n in labels]
    if not steps or per_mix is None:
        return []
    s = scores[(scores["binder_route"] == ROUTE) & (scores["group"] == "all") & scores["temperature_C"].isna()]
    s = s.set_index("label")
    e = per_mix[(per_mix["binder_route"] == ROUTE) & per_mix["temperature_C"].isna()]
    L = [
        "",
        "The discrete model by its number of constants (`asphalt_nscd.forecast.physical`; gain: paired difference "
        "with the step before over the same mixes, negative is better):",
        "",
        "| model | constants fitted | \\|E*\\| (%) | phase (°) | gain \\|E*\\| (points) | gain phase (°) |",
        "|---|---|---|---|---|---|",
    ]
    for name, free in [*steps, ("dem_selected", ("chosen in each fold",))]:
        prev = PREVIOUS.get(name) if PREVIOUS.get(name) in s.index else None
        if name not in s.index:
            continue
        r = s.loc[name]
        gains = []
        for col in ("e", "p"):
            if prev is None:
                gains.append("–")
                continue
            w = e.pivot_table(index="mix_id", columns="label", values=col)
            gains.append(_mean_ci((w[name] - w[prev]).dropna()))
        L.append(
            f"| {name} | {len(free) if name != 'dem_selected' else '–'}: {', '.join(free) or 'none'} | "
            f"{_ci(r['abs_logE_pct'], r['abs_logE_ci_low'], r['abs_logE_ci_high'])} | "
            f"{_ci(r['abs_phase_deg'], r['abs_phase_ci_low'], r['abs_phase_ci_high'])} | {gains[0]} | {gains[1]} |"
        )
    return L


#: runs kept to compare dem_selected's choice (label, its configuration) beside the default run's own
CHOICE_RUNS = (
    ("variants", "with the sample variants (config/forecast_variants.yaml)"),
    ("rule_best", "with the sample variants, by the least inner score (config/forecast_rule_best.yaml after it)"),
)


def choice_section(scores: pd.DataFrame, per_mix: pd.DataFrame | None, selection: pd.DataFrame | None) -> list[str]:
    """``dem_selected`` under the default run's choice and under the kept runs of :data:`CHOICE_RUNS`
    (the same base samples; a sample variant's candidates added, another rule of the choice), held
    out, with the paired difference over the mixes and what each run chose."""
    if per_mix is None or selection is None or "rule" not in selection:
        return []
    runs = [("default", "the default configuration", scores, per_mix, selection)]
    for label, what in CHOICE_RUNS:
        sc, pm, sel = _read(f"{label}_crossval.csv"), _read(f"{label}_per_mix.csv"), _read(f"{label}_selection_log.csv")
        if sc is not None and pm is not None and sel is not None:
            runs.append((label, what, sc, pm, sel))
    if len(runs) < 2:
        return []
    L = [
        "",
        "### The choice compared",
        "",
        "`dem_selected` in the default run and in the kept runs of the same base samples "
        "(`forecast.dem.variants`, `forecast.dem.selection_rule`; difference: paired over the mixes against the "
        "default run, negative is better):",
        "",
        "| run | rule | \\|E*\\| (%) | phase (°) | difference \\|E*\\| (points) | difference phase (°) | folds on a sample variant | steps chosen |",
        "|---|---|---|---|---|---|---|---|",
    ]
    base_pm = per_mix[(per_mix["binder_route"] == ROUTE) & per_mix["temperature_C"].isna()]
    base_pm = base_pm[base_pm["label"] == "dem_selected"].set_index("mix_id")
    for label, what, sc, pm, sel in runs:
        r = sc[(sc["binder_route"] == ROUTE) & (sc["group"] == "all") & sc["temperature_C"].isna()]
        r = r[r["label"] == "dem_selected"].iloc[0]
        e = pm[(pm["binder_route"] == ROUTE) & pm["temperature_C"].isna() & (pm["label"] == "dem_selected")]
        e = e.set_index("mix_id")
        diffs = []
        for col in ("e", "p"):
            if label == "default":
                diffs.append("–")
                continue
            diffs.append(_mean_ci((e[col] - base_pm[col]).dropna()))
        chosen = sel[sel["chosen"].astype(bool) & (sel["binder_route"] == ROUTE)]
        rule = str(sel["rule"].iloc[0]) if "rule" in sel else "best"
        on_variant = int(chosen["candidate"].str.contains("@").sum())
        steps = chosen["candidate"].str.split("@").str[0].value_counts()
        L.append(
            f"| {what} (`{label}_*`) | {rule} | {_ci(r['abs_logE_pct'], r['abs_logE_ci_low'], r['abs_logE_ci_high'])} | "
            f"{_ci(r['abs_phase_deg'], r['abs_phase_ci_low'], r['abs_phase_ci_high'])} | {diffs[0]} | {diffs[1]} | "
            f"{on_variant} of {len(chosen)} | {', '.join(f'{k} {v}' for k, v in steps.items())} |"
        )
    return L


def _extra_sections(label: str, scores: pd.DataFrame, selection: pd.DataFrame | None) -> list[str]:
    """The run's choice inside the fold, error split, learned yardstick and intervals (as on its page)."""
    from asphalt_nscd.forecast import page_dem

    L: list[str] = []
    split = _read(f"{label}_error_split.csv")
    coverage, rows = _read(f"{label}_interval_coverage.csv"), _read(f"{label}_learned_by_rows.csv")
    for sec in (
        page_dem.selection_section(selection),
        page_dem.split_section(split[split["binder_route"] == ROUTE] if split is not None else None),
        page_dem.learned_section(scores, rows, ROUTE),
        page_dem.coverage_section(
            coverage, ROUTE, ["hirsch_recalibrated", "dem_selected", "gradient_boosting_learned"]
        ),
    ):
        if sec:
            L += ["", *[ln.replace("## ", "### ", 1) if ln.startswith("## ") else ln for ln in sec]]
    return L


def physics_section(pp: pd.DataFrame | None) -> list[str]:
    """``dem_physical`` (nothing fitted) under the candidate physics of its bond laws (``physics_probe.py``)."""
    if pp is None:
        return []
    L = [
        "",
        "## Candidate physics of dem_physical",
        "",
        "`dem_physical` fits nothing on mixes; here it forecasts every mix of the default run's samples with the air "
        "voids in the mastic (the default), added to the mortar at the fine aggregate's scale, or in pockets between "
        "the stones, the bridges dense and their section reduced by the pockets' share of the matrix, or in the "
        "binder, every inclusion's fraction then taken over the space it shares with the air "
        "(`forecast.dem.air_phase`), with the skeleton contacts also touching as Hertz contacts of the stones at "
        "the test's strain amplitude (`forecast.dem.contact_strain`, in parallel with their mastic films; none: "
        "the default), their patches kept at the size the compactor's 600 kPa pressed them to (AASHTO T 312; "
        "`forecast.dem.compaction_pressure_Pa`), and with the mortar bridges free or confined, layers bonded to their "
        "stones whose bulk modulus props them up as the binder softens (`forecast.dem.bridge_confinement`), and with "
        "the mortar's fine aggregate a skeleton of its own, smooth Hertz contacts pressed at a pressure of at most the "
        "compactor's 600 kPa and kept so, added to the mortar's moduli (Walton 1987; "
        "`forecast.dem.fine_skeleton_pressure_Pa`; its grid, 600, 60 and 6 kPa, laid out after a first look at these "
        "mixes' forecasts at 600 kPa) or, pressed at 600 kPa, as the direct contacts of a contact network: each fine "
        "particle shares a mortar bridge with z neighbours, 6 of them direct contacts (the isostatic skeleton, the "
        "skeleton beside the films) and the rest films (the mortar's estimate), the mortar the network's effective "
        "medium (Feng, Thorpe & Garboczi 1985; `forecast.dem.fine_contact_neighbours`; its grid, 8, 12 and 18 "
        "neighbours, laid out after an exploratory look at these mixes' forecasts with 8 to 24 neighbours at 600 and "
        "60 kPa) "
        "(`physics_probe.py`; "
        "95 % t intervals over the mixes; bias: mean signed error per temperature). The variants are compared on "
        "the mixes they are scored on; the last row chooses the variant for each mix left out on the other mixes "
        "only.",
        "",
    ]
    temps = " / ".join(f"{T:.1f}" for T in sorted(pp["temperature_C"].dropna().unique()))
    L += [
        f"| air voids in | contact strain | compaction (kPa) | bridges | fine skeleton (kPa) | fine network (z) "
        f"| \\|E*\\| (%) | phase (°) | bias \\|E*\\| (%) at {temps} °C | bias phase (°) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    if "confinement" not in pp:  # a table written before the confined bridges
        pp = pp.assign(confinement=False)
    if "compaction_pressure_Pa" not in pp:  # a table written before the compaction's patches
        pp = pp.assign(compaction_pressure_Pa=np.nan)
    if "fine_skeleton_pressure_Pa" not in pp:  # a table written before the fine aggregate's skeleton
        pp = pp.assign(fine_skeleton_pressure_Pa=np.nan)
    if "fine_contact_neighbours" not in pp:  # a table written before the fine aggregate's contact network
        pp = pp.assign(fine_contact_neighbours=np.nan)
    pp = pp.assign(bridges=np.where(pp["confinement"].astype(str) == "True", "confined", "free"))
    keys = [
        "air_phase",
        pp["contact_strain"].fillna(0.0),
        pp["compaction_pressure_Pa"].fillna(0.0),
        "bridges",
        pp["fine_skeleton_pressure_Pa"].fillna(0.0),
        pp["fine_contact_neighbours"].fillna(0.0),
    ]
    for (air, strain, pressure, bridges, fine, z), g in pp.groupby(keys, sort=False):
        a = g[g["temperature_C"].isna()].iloc[0]
        per_T = g[g["temperature_C"].notna()].sort_values("temperature_C")
        bias_e = " / ".join(f"{v:+.0f}" for v in per_T["bias_logE_pct"])
        bias_p = " / ".join(f"{v:+.1f}" for v in per_T["bias_phase_deg"])
        chosen_row = air == "chosen in the fold"
        L.append(
            f"| {air} | {'–' if chosen_row else (f'{strain:g}' if strain else 'none')} | "
            f"{'–' if chosen_row else (f'{pressure / 1e3:g}' if pressure else 'none')} | "
            f"{'–' if chosen_row else bridges} | "
            f"{'–' if chosen_row else (f'{fine / 1e3:g}' if fine else 'none')} | "
            f"{'–' if chosen_row else (f'{z:g}' if z else 'none')} | "
            f"{_ci(a['abs_logE_pct'], a['abs_logE_pct_ci_low'], a['abs_logE_pct_ci_high'])} | "
            f"{_ci(a['abs_phase_deg'], a['abs_phase_deg_ci_low'], a['abs_phase_deg_ci_high'])} | {bias_e} | {bias_p} |"
        )
    chosen = pp.loc[pp["air_phase"] == "chosen in the fold", "chosen"].dropna()
    if len(chosen):
        L += [
            "",
            f"Chosen in the fold (variant: mixes): {chosen.iloc[0]}. The largest strain tried, "
            f"{pp['contact_strain'].max():g}, is the top of the range AASHTO T 342 allows (50–150 microstrain): "
            "a choice of it is a choice at its bound."
            + (
                f" The smallest fine-skeleton pressure tried, {pp['fine_skeleton_pressure_Pa'].min() / 1e3:g} kPa, is "
                "the bottom of its grid: a choice of it is a choice at the grid's bound."
                if pp["fine_skeleton_pressure_Pa"].notna().any()
                else ""
            )
            + (
                f" The network's neighbours, {pp['fine_contact_neighbours'].min():g} to "
                f"{pp['fine_contact_neighbours'].max():g}, bound its grid: a choice of either is a choice at its bound."
                if pp["fine_contact_neighbours"].notna().any()
                else ""
            ),
        ]
    L += _fine_skeleton_reading(pp)
    return L + missing_section(pp)


def _fine_skeleton_reading(pp: pd.DataFrame) -> list[str]:
    """What the fine aggregate's skeleton does to the warmest isotherm, from the probe's rows."""
    probed = pp[pp["fine_skeleton_pressure_Pa"].notna() & (pp["air_phase"] != "chosen in the fold")]
    fine = probed[probed["fine_contact_neighbours"].isna()]
    if fine.empty:
        return []
    warm = fine[fine["temperature_C"] == fine["temperature_C"].max()]
    overall = fine[fine["temperature_C"].isna()]
    network = probed[probed["fine_contact_neighbours"].notna()]
    net_warm = network[network["temperature_C"] == network["temperature_C"].max()]
    net_all = network[network["temperature_C"].isna()]
    return [
        "",
        f"Read: the fine aggregate's skeleton lifts the warm forecasts, but as an elastic floor. At "
        f"{warm['temperature_C'].iloc[0]:.1f} °C, at every pressure tried, the forecast's phase angle falls "
        f"{-warm['bias_phase_deg'].max():.0f}–{-warm['bias_phase_deg'].min():.0f}° below the measured one "
        f"(mean abs phase error {overall['abs_phase_deg'].min():.1f}–{overall['abs_phase_deg'].max():.1f}° over all "
        "conditions). The warm mixes' missing stiffness is viscoelastic; a pressed granular skeleton, whose "
        "stiffness the temperature does not change, is not it."
        + (
            f" As the direct contacts of a contact network, the same skeleton keeps part of the films' viscous "
            f"response: at {net_warm['temperature_C'].iloc[0]:.1f} °C the phase angle's bias is "
            f"{net_warm['bias_phase_deg'].min():+.1f} to {net_warm['bias_phase_deg'].max():+.1f}° with "
            f"{net_all['fine_contact_neighbours'].min():g} to {net_all['fine_contact_neighbours'].max():g} neighbours "
            f"(mean abs phase error {net_all['abs_phase_deg'].min():.1f}–{net_all['abs_phase_deg'].max():.1f}°, "
            f"\\|E*\\| {net_all['abs_logE_pct'].min():.1f}–{net_all['abs_logE_pct'].max():.1f} %)."
            if len(net_all)
            else ""
        ),
    ]


#: the models the probe's choice inside the fold is paired with (the default run's held-out rows)
PAIRED_WITH = ("witczak_1_40d_published", "hirsch_recalibrated", "dem_selected", "gradient_boosting_learned")


def paired_choice_section(choice: pd.DataFrame | None, per_mix: pd.DataFrame | None) -> list[str]:
    """The probe's choice inside the fold (``physics_probe_per_mix.csv``) against the default run's held-out
    models, paired over the mixes both forecast: each mix's mean abs error, the choice's minus the model's, with
    its t(n - 1) 95 % interval (negative: the choice does better)."""
    if choice is None or per_mix is None:
        return []
    pm = per_mix[(per_mix["binder_route"] == ROUTE) & per_mix["temperature_C"].isna()]
    L = [
        "",
        "### The choice inside the fold against the default run's models, paired",
        "",
        "Each mix's mean abs error under the probe's choice inside the fold minus the same mix's under each model "
        "of the default run (held out by mix; 95 % t intervals over the mixes both forecast; negative: the choice "
        "does better). The choice's grid was laid out after a look at these mixes (above).",
        "",
        "| model | mixes | \\|E*\\| choice − model (points) | phase choice − model (°) |",
        "|---|---|---|---|",
    ]
    c = choice.set_index("mix_id")
    for label in PAIRED_WITH:
        m = pm[pm["label"] == label].set_index("mix_id")
        both = c.index.intersection(m.index)
        if len(both) < 2:
            continue
        de = c.loc[both, "abs_logE_pct"] - m.loc[both, "e"]
        dp = c.loc[both, "abs_phase_deg"] - m.loc[both, "p"]
        L.append(f"| {label} | {len(both)} | {_mean_ci(de)} | {_mean_ci(dp)} |")
    return L


def missing_section(pp: pd.DataFrame) -> list[str]:
    """What ``dem_physical`` misses as a complex modulus, per temperature, in the default configuration and
    under the variant chosen in the fold (``physics_probe.py``'s ``missing_*`` columns)."""
    if "missing_storage_pct" not in pp:  # a table written before the missing modulus was recorded
        return []
    L = [
        "",
        "### What it misses, as a complex modulus",
        "",
        "Each cell's (E\\*_m − E\\*_f) / \\|E\\*_m\\|: the storage modulus missing (in phase with the strain) "
        "and the loss modulus missing (in quadrature), in percent of the measured \\|E*\\| (the mix's mean, then "
        "the mean over the mixes, 95 % t interval), and the phase angle of that mean (–: both intervals hold "
        "zero), beside the binder's mean phase angle at the same cells. A missing elastic part reads near 0°, a "
        "part that behaves like the binder near the binder's phase angle. The residual is linear, so a mix "
        "forecast too stiff weighs more than one forecast too soft by the same log ratio.",
        "",
        "| dem_physical | temperature (°C) | storage (%) | loss (%) | its phase (°) | binder's phase (°) |",
        "|---|---|---|---|---|---|",
    ]
    default = pp[pp.index < pp.index[pp["temperature_C"].isna()][1]]  # the first variant: the default configuration

    def phase(r) -> str:
        held = [r[f"missing_{k}_pct_ci_low"] <= 0 <= r[f"missing_{k}_pct_ci_high"] for k in ("storage", "loss")]
        return "–" if all(held) else f"{r['missing_phase_deg']:.0f}"

    rows = [("default configuration", default), ("chosen in the fold", pp[pp["air_phase"] == "chosen in the fold"])]
    for label, g in rows:
        for _, r in g[g["temperature_C"].notna()].sort_values("temperature_C").iterrows():
            L.append(
                f"| {label} | {r['temperature_C']:.1f} | "
                f"{_ci(r['missing_storage_pct'], r['missing_storage_pct_ci_low'], r['missing_storage_pct_ci_high'], 0)} | "
                f"{_ci(r['missing_loss_pct'], r['missing_loss_pct_ci_low'], r['missing_loss_pct_ci_high'], 0)} | "
                f"{phase(r)} | {r['binder_delta_deg']:.0f} |"
            )
    return L


def volumetric_section(vs: pd.DataFrame | None) -> list[str]:
    """How each forecast answers binder in place of air voids at the same VMA (``volumetric_sensitivity.py``)."""
    if vs is None:
        return []
    temps = sorted(vs["temperature_C"].dropna().unique())
    L = [
        "",
        "### Binder in place of air voids, at the same VMA",
        "",
        "At a fixed VMA the aggregate and the discrete model's sample stay the same; moving 1 % of the mix's "
        "volume from air voids to effective binder changes each forecast by 100 d ln\\|E\\*\\| (percent; the "
        "mean over the mixes of each mix's mean, 95 % t interval; central difference, nothing refitted: "
        "`volumetric_sensitivity.py`). Softening: the share of mixes whose forecast softens.",
        "",
        "| model | all | " + " | ".join(f"{T:.1f} °C" for T in temps) + " | softening |",
        "|---|---|" + "---|" * len(temps) + "---|",
    ]
    for model, g in vs.groupby("model", sort=False):
        a = g[g["temperature_C"].isna()].iloc[0]
        per_T = g[g["temperature_C"].notna()].sort_values("temperature_C")
        cells = [
            _ci(r["dlnE_pct_per_pct"], r["dlnE_pct_per_pct_ci_low"], r["dlnE_pct_per_pct_ci_high"])
            for _, r in [(None, a), *per_T.iterrows()]
        ]
        L.append(f"| {model} | " + " | ".join(cells) + f" | {100 * a['share_softening']:.0f} % |")
    return L


def physics_ladder_section(scores, per_mix, p_scores, p_per_mix, costs, p_costs) -> list[str]:
    """The ladder in the default run and in the kept run with every candidate physics on
    (``config/forecast_physics.yaml``, ``physics_*``): each step held out, the paired difference over
    the mixes, and the CPU of the folds' fits in both runs."""
    from asphalt_nscd.forecast.physical import STEP_NAMES

    if any(t is None for t in (scores, per_mix, p_scores, p_per_mix)):
        return []
    L = [
        "",
        "## The ladder under the candidate physics",
        "",
        "Every step of the ladder in the default run and in a kept run of the same samples with the air voids in "
        "pockets, confined bridges, the skeleton contacts' patches pressed by the compactor's 600 kPa and the "
        "mortar's fine aggregate as a contact network of 12 neighbours, its direct contacts pressed at 600 kPa too "
        "(`config/forecast_physics.yaml`, "
        "`physics_*`), each held out by mix with its constants fitted in every fold (difference: paired over the "
        "mixes, physics run minus default run, negative is better):",
        "",
        "| model | \\|E*\\| default (%) | \\|E*\\| physics (%) | difference (points) | phase default (°) "
        "| phase physics (°) | difference (°) |",
        "|---|---|---|---|---|---|---|",
    ]

    def overall(sc, name):
        r = sc[(sc["binder_route"] == ROUTE) & (sc["group"] == "all") & sc["temperature_C"].isna()]
        r = r[r["label"] == name]
        return None if r.empty else r.iloc[0]

    def errors(pm, name):
        e = pm[(pm["binder_route"] == ROUTE) & pm["temperature_C"].isna() & (pm["label"] == name)]
        return e.set_index("mix_id")

    from asphalt_nscd.diagnosis.scores import t_interval

    verdict: dict[str, list[str]] = {"gain": [], "stay": [], "lose": []}
    for name in [*STEP_NAMES, "dem_selected"]:
        a, b = overall(scores, name), overall(p_scores, name)
        if a is None or b is None:
            continue
        ea, eb = errors(per_mix, name), errors(p_per_mix, name)
        lo, hi = t_interval((eb["e"] - ea["e"]).dropna().to_numpy(float))
        verdict["gain" if hi < 0 else "lose" if lo > 0 else "stay"].append(f"`{name}`")
        L.append(
            f"| {name} | {_ci(a['abs_logE_pct'], a['abs_logE_ci_low'], a['abs_logE_ci_high'])} | "
            f"{_ci(b['abs_logE_pct'], b['abs_logE_ci_low'], b['abs_logE_ci_high'])} | "
            f"{_mean_ci((eb['e'] - ea['e']).dropna())} | "
            f"{_ci(a['abs_phase_deg'], a['abs_phase_ci_low'], a['abs_phase_ci_high'])} | "
            f"{_ci(b['abs_phase_deg'], b['abs_phase_ci_low'], b['abs_phase_ci_high'])} | "
            f"{_mean_ci((eb['p'] - ea['p']).dropna())} |"
        )
    if costs is not None and p_costs is not None:
        cpu = [c.loc[c["command"] == "forecast-crossval", "cpu_s"].sum() for c in (costs, p_costs)]
        L += [
            "",
            f"The folds' fits (`forecast-crossval`) took {cpu[1]:.0f} s of CPU with the candidate physics against "
            f"{cpu[0]:.0f} s in the default run ({cpu[1] / cpu[0]:.1f} times; runs of different days on this shared "
            "machine): every evaluation of every fit computes the confined bridges' modulus, a mean over each "
            "sample's bond shapes.",
        ]
    said = {
        "gain": "gain in \\|E*\\| (the difference's interval below zero)",
        "stay": "stay where they were (its interval holds zero)",
        "lose": "lose (its interval above zero)",
    }
    parts = [f"{', '.join(v)} {said[k]}" for k, v in verdict.items() if v]
    L += [
        "",
        f"Read: under the candidate physics {'; '.join(parts)}. The default configuration keeps the options off.",
    ]
    return L


def binder_sections() -> list[str]:
    """The binder's reading and extrapolation sections (their tables' scripts named under each heading)."""
    from asphalt_nscd.forecast.binder_report import binder_reading_section, extrapolation_section

    L: list[str] = []
    reading, paired = _read("binder_reading.csv"), _read("binder_reading_paired.csv")
    summary = _read("binder_extrapolation_summary.csv")
    for sec, note in (
        (
            binder_reading_section(reading, paired) if reading is not None else [],
            "The 35 mixes, leave one mix out, binder through its curve (`binder_reading.py`).",
        ),
        (
            extrapolation_section(summary) if summary is not None else [],
            "Every binder of the table under each variant (`binder_extrapolation.py`); held out by mix, leave one "
            "mix out, with the binder read at the table's binder frequency, the extrapolated cells those of the "
            "default curves.",
        ),
    ):
        while sec and sec[-1] == "":
            sec = sec[:-1]
        if sec:
            L += ["", *sec[:2], note, "", *sec[2:]]
    return L


def render() -> str:
    """The page's text, every number computed from the committed tables."""
    L = [
        "# The forecast from the binder: reference tables",
        "",
        "Committed tables of the forecast's runs on the 35 shipped mixes (`data/binder_mix/`), written by "
        "`reference/forecast/collect.py`, and this page by `reference/forecast/readme.py` from them.",
        "",
        "```bash",
        "make run                                                     # default: 2.5 largest diameters, one seed",
        "python reference/forecast/collect.py . --label default -o reference/forecast",
        ".venv/bin/snakemake forecast_publish --cores 2 --configfile config/config.yaml config/forecast_variants.yaml",
        "python reference/forecast/collect.py . --label variants --models dem_selected -o reference/forecast",
        ".venv/bin/snakemake forecast_publish --cores 2 --configfile config/config.yaml config/forecast_variants.yaml \\",
        "    config/forecast_rule_best.yaml",
        "python reference/forecast/collect.py . --label rule_best --models dem_selected -o reference/forecast",
        ".venv/bin/snakemake forecast_publish --cores 2 --configfile config/config.yaml config/forecast_reference.yaml",
        "python reference/forecast/collect.py . --label reference -o reference/forecast  # 3.0 diameters, two seeds",
        "python reference/forecast/size_study.py SAMPLES -o reference/forecast/size_study.csv \\",
        "    --summary reference/forecast/size_study_summary.csv",
        "python reference/forecast/physics_probe.py . -o reference/forecast/physics_probe.csv \\",
        "    --per-mix reference/forecast/physics_probe_per_mix.csv",
        "python reference/forecast/volumetric_sensitivity.py . -o reference/forecast/volumetric_sensitivity.csv",
        ".venv/bin/snakemake forecast_publish --cores 2 --configfile config/config.yaml config/forecast_physics.yaml",
        "python reference/forecast/collect.py . --label physics --models dem_physical dem_c1 dem_c2 dem_c3 dem_c4 \\",
        "    dem_p2 dem_p3 dem_selected -o reference/forecast  # with physics_costs.csv from the run's CPU records",
        "python reference/forecast/variant_cost.py --mix 193 --variant 4:2.5 --variant 6.3:2.5 --variant 4:2 \\",
        "    --variant 2:2 -o reference/forecast/variant_cost.csv",
        "python reference/forecast/time_domain.py . --constants reference/forecast/default_constants.csv \\",
        "    -o reference/forecast/time_domain.csv",
        "python reference/forecast/binder_reading.py -o reference/forecast/binder_reading.csv \\",
        "    --paired reference/forecast/binder_reading_paired.csv",
        "python reference/forecast/binder_extrapolation.py -o reference/forecast/binder_extrapolation.csv \\",
        "    --isotherms reference/forecast/binder_extrapolation_isotherms.csv \\",
        "    --summary reference/forecast/binder_extrapolation_summary.csv",
        "python reference/forecast/readme.py",
        "```",
        "",
        "Errors are held out (leave one mix out, binder through its master curve), 95 % t intervals over the 35 mixes.",
    ]
    for label, what in (("default", "Default run"), ("reference", "Reference run")):
        scores, per_mix, c = _read(f"{label}_crossval.csv"), _read(f"{label}_per_mix.csv"), _read(f"{label}_costs.csv")
        if scores is None:
            continue
        L += ["", f"## {what}", "", *headline(scores)]
        if per_mix is not None and "dem_extended" in set(per_mix["label"]):
            best = (
                scores[
                    (scores["binder_route"] == ROUTE)
                    & (scores["group"] == "all")
                    & scores["temperature_C"].isna()
                    & scores["label"].str.endswith("_recalibrated")
                ]
                .sort_values("abs_logE_pct")["label"]
                .iloc[0]
            )
            L += [
                "",
                "`dem_extended` against the best recalibrated formula, paired over the mixes:",
                "",
                *paired(per_mix, "dem_extended", best),
            ]
        if c is not None:
            L += ["", "CPU (exact records of the run's commands, this shared 2-core machine):", "", *costs(c)]
        k = _read(f"{label}_constants.csv")
        if k is not None:
            L += [
                "",
                "Constants fitted on every measured mix (and the range over the folds):",
                "",
                "| model | constant | all mixes | folds: smallest | largest |",
                "|---|---|---|---|---|",
            ]
            L += [
                f"| {r['model']} | {r['constant']} | {r['all_mixes']:.4g} | {r['folds_min']:.4g} | {r['folds_max']:.4g} |"
                for _, r in k.iterrows()
            ]
        L += ladder(scores, per_mix)
        selection = _read(f"{label}_selection_log.csv")
        L += _extra_sections(label, scores, selection)
        if label == "default":
            L += choice_section(scores, per_mix, selection)
        sp = _read(f"{label}_seed_spread.csv")
        if sp is not None:
            m = sp.groupby("mix_id")["mean_abs_log_diff_pct"].mean()
            L += [
                "",
                f"Seeds: the forecast |E*| of `dem_extended` from one seed's sample differs from the mean over "
                f"the seeds by {m.mean():.1f} % on average over the mixes (largest mix {m.max():.1f} %).",
            ]
    L += binder_sections()
    sk = _read("skeleton_exponent.csv")
    if sk is not None:
        L += [
            "",
            "## The skeleton's exponent",
            "",
            "`dem_extended` on the default run's samples with its skeleton elastic "
            "(n_s held at 0) and parabolic (n_s fitted in each fold), held out (`skeleton_exponent.py`):",
            "",
            "| T (°C) | elastic: \\|E*\\| (%) | phase (°) | parabolic: \\|E*\\| (%) | phase (°) |",
            "|---|---|---|---|---|",
        ]
        for T, g in sk.groupby(sk["temperature_C"].fillna(-999.0), sort=True):
            e, p = (g[g["skeleton"] == k].iloc[0] for k in ("elastic", "parabolic"))
            cells = [
                _ci(r[value], r[f"{base}_ci_low"], r[f"{base}_ci_high"])
                for r in (e, p)
                for value, base in (("abs_logE_pct", "abs_logE"), ("abs_phase_deg", "abs_phase"))
            ]
            L.append(f"| {'all' if T == -999.0 else f'{T:.1f}'} | " + " | ".join(cells) + " |")
    td = _read("time_domain.csv")
    if td is not None:
        L += [
            "",
            "## The harmonic answer in the time domain",
            "",
            "`dem_extended`'s bonds (constants fitted on every mix of the default run, the mix's mortar at the "
            "condition) stepped in time by the NSCD core as Maxwell elements, on the default run's smallest, median "
            "and largest sample, at the table's two corners (`time_domain.py`): the time-domain |E*| and phase "
            "against the harmonic solve of the same network with the spheres' inertia, and that solve against "
            "the quasi-static response the forecast reads.",
            "",
            "| mix | spheres | T (°C) | f (Hz) | steps per cycle | \\|E*\\| (MPa) | time domain − harmonic: "
            "\\|E*\\| (%) | phase (°) | inertia (%) | steps with a contact | CPU (s) |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        L += [
            f"| {r['mix_id']} | {r['n_spheres']} | {r['temperature_C']:.1f} | {r['frequency_Hz']:g} | "
            f"{r['steps_per_cycle']} | {r['E_harmonic_MPa']:.0f} | {r['td_vs_harmonic_E_pct']:.2g} | "
            f"{r['td_vs_harmonic_phase_deg']:.2g} | {r['inertia_E_pct']:.1g} | {r['n_nonlinear_steps']} | {r['cpu_s']:.0f} |"
            for _, r in td.iterrows()
        ]
    L += physics_section(_read("physics_probe.csv"))
    L += paired_choice_section(_read("physics_probe_per_mix.csv"), _read("default_per_mix.csv"))
    L += volumetric_section(_read("volumetric_sensitivity.csv"))
    L += physics_ladder_section(
        _read("default_crossval.csv"),
        _read("default_per_mix.csv"),
        _read("physics_crossval.csv"),
        _read("physics_per_mix.csv"),
        _read("default_costs.csv"),
        _read("physics_costs.csv"),
    )
    vc = _read("variant_cost.csv")
    if vc is not None:
        L += [
            "",
            "## Sample variants",
            "",
            "One mix's sample at each cut and cube size, prepared and solved one process at a time "
            "(`variant_cost.py`; CPU of the command, its peak memory): the response's dense generalized "
            "eigen-decomposition grows as the cube of the spheres, so the variants of "
            "`config/forecast_variants.yaml` stop at the 4 mm cut.",
            "",
            "| sample | spheres | packing CPU (s) | sample CPU (s) | response CPU (s) | response memory (MB) |",
            "|---|---|---|---|---|---|",
        ]
        for name, g in vc.groupby("variant", sort=False):
            step = g.set_index("step")
            L.append(
                f"| {name} (mix {g['mix_id'].iloc[0]}) | {step.loc['forecast-sample', 'n_spheres']:.0f} | "
                f"{step.loc['forecast-pack', 'cpu_s']:.1f} | {step.loc['forecast-sample', 'cpu_s']:.1f} | "
                f"{step.loc['forecast-response', 'cpu_s']:.1f} | {step.loc['forecast-response', 'max_rss_mb']:.0f} |"
            )
    sz = _read("size_study_summary.csv")
    if sz is not None:
        L += [
            "",
            "## Size study",
            "",
            "Sample factor E*/e_1 (mortar alone, ζ = 0, and with the skeleton, ζ = 1): mean over "
            "the seeds and their coefficient of variation, per mix and cube size (side / largest diameter):",
            "",
            "| mix | coarse fraction | size | spheres | seeds | ζ = 0 | CV (%) | ζ = 1 | CV (%) | packing CPU (s) |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for _, r in sz.iterrows():
            L.append(
                f"| {r['mix_id']} | {r['coarse']:.2f} | {r['size_dmax']:g} | {r['n_spheres']:.0f} | {int(r['n_seeds'])} | "
                f"{r['factor_zeta0_mean']:.3f} | {r['factor_zeta0_cv_pct']:.1f} | {r['factor_zeta1_mean']:.3f} | "
                f"{r['factor_zeta1_cv_pct']:.1f} | {r['pack_cpu_s']:.0f} |"
            )
    return "\n".join(L) + "\n"


def main(argv=None) -> int:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare README.md with the tables' page, write nothing")
    args = ap.parse_args(argv)
    page, text = HERE / "README.md", render()
    if args.check:
        if page.read_text() != text:
            print(f"{page}: not what its tables give; rerun python reference/forecast/readme.py", file=sys.stderr)
            return 1
        return 0
    page.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
