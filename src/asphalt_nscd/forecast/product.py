"""Your mix, forecast: the trained state of every forecast model, and its use on mixes it never saw.

**The trained state** (``results/forecast/trained/``, written by ``asphalt-nscd forecast`` of the
workflow): ``state.json`` holds, for the training table's binder route, every model's constants
fitted on all the training mixes (the published formulas' recalibrated coefficients, the discrete
models' constants, the learned model's tuned settings), the conditions grid (temperatures and
frequencies), the binder frequency convention of the training table (binder at f x ratio Hz), the
prediction intervals calibrated on the training mixes left out (:mod:`.intervals`), the training
mixes' ranges (:func:`ranges`) and the forecast configuration (sample settings, binder curve
settings). ``training_table.csv`` holds the training rows as the models read them (the learned
model is refitted from it, deterministically; the summary figures draw its measured curves).

**A new mix** (:func:`forecast_mixes`), from a mix file (:mod:`asphalt_nscd.lab.mix_input`: the
binder as DSR sweeps, the gradation as a sieve analysis, the volumetrics as a lab reports them):
its binder's points pass the quality checks and carry a master curve (:mod:`.binder`, the
viscosity shift when viscosities are given, else Arrhenius); its rows are the training grid with
the binder read through that curve at the training table's frequency convention; its sample is
prepared from its own full sieve analysis and volumetrics (:mod:`.formulation`, Section 3.2.1)
and solved once (:mod:`.dem`); every model forecasts it with the trained constants and every
forecast carries its interval. A mix outside the training mixes' ranges (:func:`extrapolation`)
is named, and its intervals are marked ``extrapolated``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..io import InputError

STATE = "state.json"
TRAINING = "training_table.csv"
#: the per-mix inputs whose training range is recorded, with their labels
RANGE_COLUMNS = {
    "Va_pct": "air voids Va (%)",
    "Vbeff_pct": "effective binder Vbeff (%)",
    "VMA_pct": "VMA (%)",
    "VFA_pct": "VFA (%)",
    "Pb_pct": "binder content Pb (%)",
    "rho34_pct": "retained on 19 mm (%)",
    "rho38_pct": "retained on 9.5 mm (%)",
    "rho4_pct": "retained on 4.75 mm (%)",
    "rho200_pct": "passing 0.075 mm (%)",
    "pg_high_C": "PG high (degC)",
    "pg_low_C": "PG low (degC)",
}


#: where the last complete forecast of each table is published (rule forecast_publish)
FORECASTS = "results/forecasts"


def table_folder(table) -> str:
    """``results/forecasts/<folder>-<stem>``: the folder of the last complete forecast of the matched
    table ``table`` (its folder's name and its stem; ``<stem>`` alone for a table in the working folder)."""
    table = Path(table)
    folder = table.resolve().parent.name
    return f"{FORECASTS}/{folder}-{table.stem}" if folder and table.parent != Path(".") else f"{FORECASTS}/{table.stem}"


def table_work_dir(table) -> str:
    """The forecast chain's working folder for make forecast TABLE=``table`` (forecast.work_dir):
    ``<its published folder>.work/forecast``, beside the folder its complete run is published to, so that
    make run's own chain (results/forecast) stays as it is."""
    return f"{table_folder(table)}.work/forecast"


def _with_volumetrics(table: pd.DataFrame) -> pd.DataFrame:
    return table.assign(
        VMA_pct=table["Va_pct"] + table["Vbeff_pct"],
        VFA_pct=100.0 * table["Vbeff_pct"] / (table["Va_pct"] + table["Vbeff_pct"]),
    )


def ranges(train: pd.DataFrame) -> dict:
    """The training mixes' ranges: ``{column: [low, high]}`` of :data:`RANGE_COLUMNS` (those the table
    has) and ``binder_log10_G_Pa``: ``{temperature: [low, high]}`` of log10 of the binder's |G*| at
    the mix's frequency over the training rows."""
    t = _with_volumetrics(train)
    out: dict[str, object] = {
        c: [float(t[c].min()), float(t[c].max())] for c in RANGE_COLUMNS if c in t and t[c].notna().any()
    }
    g = np.log10(t["binder_G_mix_MPa"] * 1e6)
    out["binder_log10_G_Pa"] = {
        f"{T:.6g}": [float(v.min()), float(v.max())] for T, v in g.groupby(t["temperature_C"].round(6))
    }
    return out


def write_state(
    directory, cfg: dict, train: pd.DataFrame, fits: list, best: str, intervals: pd.DataFrame | None, route: str
) -> None:
    """Write the trained state (module docstring) into ``directory`` (each file atomically).

    ``train``: the training rows with the route's binder columns; ``fits``: ``{model, state}`` per
    model label fitted on them; ``intervals``: :func:`.intervals.calibrate`'s table (or None)."""
    from ..io import json_safe, write_csv, write_json

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    ratio = (train["binder_frequency_Hz"] / train["frequency_Hz"]).median()
    state = {
        "about": "the forecast models fitted on every training mix (asphalt_nscd.forecast.product)",
        "binder_route": route,
        "best_model": best,
        "grid": {
            "temperatures_C": sorted(float(x) for x in train["temperature_C"].unique()),
            "frequencies_Hz": sorted(float(x) for x in train["frequency_Hz"].unique()),
        },
        "binder_frequency_ratio": float(ratio),
        "training_mixes": sorted(str(m) for m in train["mix_id"].unique()),
        "ranges": ranges(train),
        "forecast": cfg,
        "fits": fits,
        "intervals": [] if intervals is None else intervals.to_dict(orient="records"),
    }
    write_csv(train, d / TRAINING)
    write_json(json_safe(state), d / STATE)


def read_state(directory) -> tuple[dict, pd.DataFrame]:
    """(state, training table) of a trained state; InputError naming the folder otherwise."""
    from ..io import read_csv, read_json

    d = Path(directory)
    if not (d / STATE).is_file():
        raise InputError(
            f"{d}: no trained forecast state ({STATE}); run `make run` (or the workflow's forecast_predict)"
        )
    state = read_json(d / STATE, what="trained forecast state")
    for key in ("fits", "grid", "binder_frequency_ratio", "forecast", "ranges"):
        if key not in state:
            raise InputError(f"{d / STATE}: not a trained forecast state (no {key!r})")
    # JSON has no infinity: an unbounded offset (too few calibration mixes for the level) is
    # written as null and read back as -inf (low) or +inf (high)
    for rec in state.get("intervals") or []:
        for key, value in rec.items():
            if value is None and key.endswith(("_low_pct", "_low_deg", "_high_pct", "_high_deg")):
                rec[key] = -np.inf if "_low_" in key else np.inf
    return state, read_csv(d / TRAINING, dtype={"mix_id": str})


def new_mix_table(mixes: list, state: dict) -> tuple[pd.DataFrame, dict, pd.DataFrame, pd.Series, list]:
    """The rows the models read for new mixes (module docstring).

    Returns (table with the route's binder columns, binder curves by binder id, the binders'
    checked points, binder id per mix, warnings). Raises InputError naming the mix whose binder
    carries no master curve."""
    from .binder import check_points, fit_binder_ladder, viscosity_Pa_s
    from .formulation import gradation_text
    from .validation import with_binder_route

    grid = state["grid"]
    ratio = float(state["binder_frequency_ratio"])
    rows, curves, points, binder_of_mix, warnings = [], {}, [], {}, []
    for m in mixes:
        b = f"{m.mix_id}-binder"
        pts = m.binder_points.assign(binder=b)[
            ["binder", "temperature_C", "frequency_Hz", "G_Pa", "delta_deg", "eta_Pa_s"]
        ]
        try:
            checked = check_points(pts)
            curve, rung, shift = fit_binder_ladder(checked)
        except ValueError as exc:
            raise InputError(
                f"{m.sources.get('mix_file', '?')}: mix {m.mix_id!r}: its binder's sweeps: {exc}"
            ) from None
        if rung != "passed":
            warnings.append(f"mix {m.mix_id}: too few binder points pass the checks; curve on the {rung} points")
        if shift != "viscosity":
            warnings.append(
                f"mix {m.mix_id}: no binder viscosity at 2 temperatures: the master curve's shift is {shift}"
            )
        curves[b] = curve
        points.append(checked)
        binder_of_mix[m.mix_id] = b
        form = m.formulation()
        T, f = np.meshgrid(grid["temperatures_C"], grid["frequencies_Hz"], indexing="ij")
        T, f = T.ravel(), f.ravel()
        fb = f * ratio
        rows.append(
            pd.DataFrame(
                {
                    "mix_id": m.mix_id,
                    "temperature_C": T,
                    "frequency_Hz": f,
                    "E_norm_MPa": np.nan,
                    "phase_deg": np.nan,
                    "binder_G_MPa": curve.G_Pa(T, fb) / 1e6,
                    "binder_delta_deg": curve.delta_deg(T, fb),
                    "binder_eta_Pa_s": viscosity_Pa_s(curve, T),
                    "binder_frequency_Hz": fb,
                    **{k: form[k] for k in form},
                    "pg_high_C": np.nan if m.pg_high_C is None else m.pg_high_C,
                    "pg_low_C": np.nan if m.pg_low_C is None else m.pg_low_C,
                    "gradation": gradation_text(*m.passing),
                }
            )
        )
    table = pd.concat(rows, ignore_index=True)
    bom = pd.Series(binder_of_mix, name="binder").rename_axis("mix_id")
    routed = with_binder_route(table, curves, bom, "curve")
    return routed, curves, pd.concat(points, ignore_index=True), bom, warnings


def extrapolation(state: dict, table: pd.DataFrame) -> pd.DataFrame:
    """One row per (mix, input) outside the training mixes' range: ``mix_id, input, value, low, high``."""
    r = state["ranges"]
    t = _with_volumetrics(table)
    out = []
    for mix, g in t.groupby("mix_id", sort=False):
        first = g.iloc[0]
        for c, label in RANGE_COLUMNS.items():
            if c in r and c in g and np.isfinite(first[c]):
                lo, hi = r[c]
                if not lo <= first[c] <= hi:
                    out.append({"mix_id": mix, "input": label, "value": float(first[c]), "low": lo, "high": hi})
        for T, (lo, hi) in r.get("binder_log10_G_Pa", {}).items():
            sel = g[np.isclose(g["temperature_C"], float(T), atol=1e-3)]
            if sel.empty:
                continue
            v = np.log10(sel["binder_G_mix_MPa"].to_numpy(float) * 1e6)
            if v.min() < lo or v.max() > hi:
                bad = v[(v < lo) | (v > hi)]
                out.append(
                    {
                        "mix_id": mix,
                        "input": f"binder log10 |G*| (Pa) at {float(T):.1f} degC",
                        "value": float(bad[np.argmax(np.abs(bad - (lo + hi) / 2))]),
                        "low": lo,
                        "high": hi,
                    }
                )
    return pd.DataFrame(out, columns=["mix_id", "input", "value", "low", "high"])


def prepare_responses(table: pd.DataFrame, config: dict, workdir, progress=print) -> dict:
    """The discrete model's sample response of every mix of ``table`` for every seed of
    ``forecast.dem.seeds``, on the base sample and on every variant of ``forecast.dem.variants``
    (:func:`.formulation.sample_variants`): packing, sample and response (Section 3.2.1 and
    :mod:`.dem`), each written to ``workdir`` (a variant's to its own subfolder) and read back when
    it exists (a stopped run resumes). Returns mix_id -> responses (:func:`.models.read_responses`)."""
    from ..sample import settings
    from ..sample.prepare import finish, load_packing, pack, save_packing
    from . import formulation
    from .dem import Response, sample_response

    dem = config["forecast"]["dem"]
    base = settings.merge(settings.DEFAULTS, config.get("sample") or {})
    variants = {"": (float(dem["cut_mm"]), float(dem["size_dmax"]))} | formulation.sample_variants(dem)
    out: dict = {}
    for variant, (cut, size) in variants.items():
        work = Path(workdir) / variant
        work.mkdir(parents=True, exist_ok=True)
        where = f" ({variant})" if variant else ""
        for mix, g in table.groupby("mix_id", sort=False):
            cfg, passing, coarse = formulation.sample_settings(
                base, g.iloc[0], cut, size, float(dem["layer_over_side"])
            )
            for seed in dem.get("seeds", [1]):
                rpath = work / f"{mix}_s{seed}_response.npz"
                if not rpath.is_file():
                    ppath = work / f"{mix}_s{seed}_packing.npz"
                    if not ppath.is_file():
                        progress(f"mix {mix}, seed {seed}{where}: packing its sample")
                        save_packing(ppath, pack(cfg, int(seed), passing))
                    progress(f"mix {mix}, seed {seed}{where}: its sample and response")
                    result = finish(load_packing(ppath), cfg, int(seed), solid_fraction=coarse)
                    result.sample.attrs["mix_id"] = str(mix)
                    try:
                        resp = sample_response(result.sample, str(mix), int(seed))
                    except InputError as exc:
                        progress(f"warning: mix {mix}{where}: no discrete forecast ({exc})")
                        resp = Response.empty(str(mix), int(seed), result.sample)
                    resp.variant = variant
                    resp.save(rpath)
                out.setdefault(str(mix), []).append(Response.load(rpath))
    return out


def forecast_mixes(state: dict, training: pd.DataFrame, table: pd.DataFrame, responses: dict) -> pd.DataFrame:
    """Every trained model's forecast of the mixes of ``table`` with its prediction interval.

    Columns: ``mix_id, temperature_C, frequency_Hz, model, E_norm_MPa, phase_deg, E_low_MPa,
    E_high_MPa, phase_low_deg, phase_high_deg, extrapolated`` (the mix lies outside the training
    ranges: its interval is that of the training mixes, which it does not resemble)."""
    from . import intervals
    from .learned import GradientBoosting
    from .models import label, model_set

    cfg = state["forecast"]
    route = state["binder_route"]
    models = {label(m): m for m in model_set(cfg, responses)}
    frames = []
    for fit in state["fits"]:
        model = models.get(fit["model"])
        if model is None or not model.available(table):
            continue
        st = fit["state"]
        if isinstance(model, GradientBoosting):
            st = model.fit(training)  # the trees are refitted (deterministic), not stored
        E, P, _ = model.predict(st, table)
        frames.append(
            pd.DataFrame(
                {
                    "mix_id": table["mix_id"].to_numpy(),
                    "temperature_C": table["temperature_C"].to_numpy(),
                    "frequency_Hz": table["frequency_Hz"].to_numpy(),
                    "model": fit["model"],
                    "E_norm_MPa": E,
                    "phase_deg": P,
                }
            )
        )
    if not frames:
        raise InputError("trained state: no model of the state can forecast these mixes")
    out = pd.concat(frames, ignore_index=True)
    cal = pd.DataFrame(state.get("intervals") or [])
    if len(cal):
        out = intervals.apply(out, cal, route)
    outside = set(extrapolation(state, table)["mix_id"])
    out["extrapolated"] = out["mix_id"].isin(outside)
    return out


def binder_inputs(curves: dict, binder_of_mix: pd.Series, temperatures_C) -> pd.DataFrame:
    """The binder inputs Pavement ME also asks for: per mix and temperature, |G*| (Pa) and delta
    (degrees) at 10 rad/s from the binder's master curve, and the MEPDG viscosity (Pa s)."""
    from .binder import viscosity_Pa_s

    rows = []
    for mix, b in binder_of_mix.items():
        c = curves[b]
        for T in temperatures_C:
            f = 10.0 / (2.0 * np.pi)
            rows.append(
                {
                    "mix_id": mix,
                    "temperature_C": float(T),
                    "temperature_F": float(T) * 1.8 + 32.0,
                    "G_10rad_s_Pa": float(c.G_Pa(T, f)),
                    "delta_10rad_s_deg": float(c.delta_deg(T, f)),
                    "viscosity_Pa_s": float(viscosity_Pa_s(c, np.array([T]))[0]),
                }
            )
    return pd.DataFrame(rows)


def state_summary(state: dict) -> str:
    """One line: the trained state's training mixes, best model and interval level."""
    cal = state.get("intervals") or []
    level = f"{cal[0]['level']:.0%}" if cal and "level" in cal[0] else "no"
    return (
        f"trained on {len(state.get('training_mixes', []))} mixes, best model {state.get('best_model')}, "
        f"{level} prediction intervals"
    )
