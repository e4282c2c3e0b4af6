"""Subcommands of the forecast step (registered by asphalt_nscd.cli).

``forecast-binders``   the binders' data quality and master curves
``forecast-pack``      the packed layer of a mix's sample (Section 3.2.1 stages 1-4, the costly part)
``forecast-sample``    the mix's sample from its packing (cut, shrink to its volumetrics, bonds, stabilisation)
``forecast-response``  the sample's uniaxial response as a function of its bond moduli (:mod:`.dem`)
``forecast-crossval``  every model's held-out errors, mixes left out (:mod:`.validation`)
``forecast-coverage``  prediction intervals from the held-out rows and their nested coverage (:mod:`.intervals`)
``forecast``           every model's forecast of the mixes whose |E*| and phase are empty
``forecast-page``      the page and its figures
``forecast-publish``   the complete run, with its manifest, in the table's folder
``forecast-config``    the config overlay of ``make forecast TABLE=...``
``forecast-bench``     the discrete forecast's cost per mix (JSON)
"""

from __future__ import annotations

import argparse


def _config(args) -> dict:
    """The merged, checked workflow config of ``--config`` (config/config.yaml alone without it)."""
    from .. import config

    return config.checked(args.config or [])


def _add_config(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        nargs="+",
        metavar="FILE",
        default=None,
        help="workflow config files (YAML) merged as Snakemake merges --configfile (config/config.yaml of the "
        "working directory first); their forecast section, and the sample section's dynamics",
    )


def _add_mix(p: argparse.ArgumentParser) -> None:
    p.add_argument("--table", required=True, help="matched table in the project's columns (asphalt-nscd matched)")
    p.add_argument("--mix", required=True, help="mix_id of the mix")
    p.add_argument("--size-dmax", type=float, default=None, help="cube side / largest diameter (default: config)")
    p.add_argument("--cut-mm", type=float, default=None, help="PSD cut, mm (default: config forecast.dem.cut_mm)")


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser(
        "forecast-pack",
        help="the packed layer of a mix's sample: its gradation above the cut, deposited and vibrated",
        description="Stages 1-4 of the preparation (paper Section 3.2.1: lattice, deposition, vibration) with the "
        "mix's own gradation in the cubic box of forecast.dem (asphalt_nscd.forecast.formulation); writes the "
        "packing (.npz) that forecast-sample finishes.",
    )
    _add_config(p)
    _add_mix(p)
    p.add_argument("--seed", type=int, required=True, help="random seed of the lattice placement")
    p.add_argument("-o", "--output", required=True, help="packing file (.npz)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=False, help="progress bars")
    p.set_defaults(func=_pack)

    s = subparsers.add_parser(
        "forecast-sample",
        help="a mix's sample from its packing: cut, shrink to its coarse-aggregate volume, bonds, stabilisation",
        description="Stages 5-9 of the preparation on a forecast-pack layer: the cube cut at the layer's "
        "mid-height, spheres shrunk to the mix's coarse-aggregate volume fraction (at least the paper's 10 %% of "
        "their volume), bonds below the gap d_min, bonded stabilisation; writes the sample file (.h5).",
    )
    _add_config(s)
    _add_mix(s)
    s.add_argument("--packing", required=True, help="packing file of forecast-pack (.npz)")
    s.add_argument("-o", "--output", required=True, help="sample file (.h5)")
    s.add_argument("--summary", default=None, help="summary JSON of the sample")
    s.set_defaults(func=_sample)
    _register_chain(subparsers)
    _add_page(subparsers)
    _add_publish(subparsers)
    _add_overlay(subparsers)
    _add_bench(subparsers)
    _add_mix_forecast(subparsers)
    _add_coverage(subparsers)


def _register_chain(subparsers) -> None:
    b = subparsers.add_parser(
        "forecast-binders",
        help="the binders' own data quality and a master curve per binder on the points that pass",
        description="Identify the binders of a matched table (mixes with identical binder columns share one), check "
        "every binder point (bounds, |G*| monotonic in frequency, Kramers-Kronig, time-temperature; "
        "asphalt_nscd.forecast.binder) and fit a CAM master curve per binder on the points that pass.",
    )
    b.add_argument("matched", help="matched table in the project's columns (asphalt-nscd matched)")
    b.add_argument("-o", "--output", required=True, help="every binder point with passed and reason (CSV)")
    b.add_argument("--curves", required=True, help="the binder master curves (JSON)")
    b.set_defaults(func=_binders)

    r = subparsers.add_parser(
        "forecast-response",
        help="a mix sample's uniaxial response as a function of its bond moduli (exact, one eigensolve)",
        description="The harmonic uniaxial test of a forecast sample (head clamped, driven along the height, no "
        "inertia) as a rational function of zeta = skeleton / mortar modulus (asphalt_nscd.forecast.dem).",
    )
    r.add_argument("sample", help="sample file of forecast-sample (.h5)")
    r.add_argument("--mix", required=True, help="mix_id of the sample")
    r.add_argument("--seed", type=int, required=True, help="its preparation seed")
    r.add_argument(
        "--variant", default="", help="the sample variant it was prepared at, cut<mm>_x<size> (default: the base)"
    )
    r.add_argument("-o", "--output", required=True, help="response file (.npz)")
    r.set_defaults(func=_response)

    for name, func, what in (
        ("forecast-crossval", _crossval, "every model's held-out errors with mixes left out, per temperature"),
        ("forecast", _predict, "every model's forecast of the mixes whose |E*| and phase are empty"),
    ):
        c = subparsers.add_parser(name, help=what)
        _add_config(c)
        c.add_argument("--matched", required=True, help="matched table in the project's columns")
        c.add_argument("--curves", required=True, help="binder master curves of forecast-binders (JSON)")
        c.add_argument("--responses", nargs="*", default=[], help="DEM responses of the mixes (forecast-response)")
        c.set_defaults(func=func)
        if name == "forecast-crossval":
            c.add_argument("-o", "--output", required=True, help="held-out predictions, one row per cell and model")
            c.add_argument("--scores", required=True, help="errors per model, route, group and temperature (CSV)")
            c.add_argument("--constants", required=True, help="each fold's fitted coefficients and constants (JSON)")
            c.add_argument(
                "--split", required=True, help="each model's error split into level, temperature, rest (CSV)"
            )
            c.add_argument("--selection", required=True, help="every variant tried inside every fold (CSV)")
            c.add_argument("--jobs", type=int, default=1, help="worker processes over the folds (same numbers)")
            c.add_argument(
                "--learned-rows", required=True, help="the learned model judged by mix and by random rows (CSV)"
            )
        else:
            c.add_argument("-o", "--output", required=True, help="forecast.csv: one row per mix, condition and model")
            c.add_argument("--scores", required=True, help="scores of forecast-crossval (the best model per table)")
            c.add_argument("--level1", required=True, help="Level 1 |E*| tables of the forecast mixes (CSV)")
            c.add_argument("--sigmoid", required=True, help="sigmoidal master curves of the forecast mixes (CSV)")
            c.add_argument("--constants", required=True, help="the coefficients fitted on every measured mix (JSON)")
            c.add_argument("--intervals", default=None, help="prediction intervals of forecast-coverage (CSV)")
            c.add_argument(
                "--state", default=None, help="folder of the trained state to write (asphalt_nscd.forecast.product)"
            )


def _add_page(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-page",
        help="the forecast page: which model forecasts best where and by how much, with its figures",
        description="Write forecast.md (asphalt_nscd.forecast.page) and its figures (predicted against measured "
        "per model; the binder master curves with the points left out) from the chain's tables.",
    )
    _add_config(p)
    p.add_argument("--table-name", required=True, help="the table's name on the page")
    for name, what in (
        ("matched", "matched table"),
        ("points", "binder points of forecast-binders"),
        ("curves", "binder curves of forecast-binders"),
        ("rows", "held-out rows of forecast-crossval"),
        ("scores", "scores of forecast-crossval"),
        ("constants", "fold constants of forecast-crossval"),
        ("forecast", "forecast.csv of forecast"),
        ("forecast-constants", "constants of forecast (its best model)"),
        ("split", "error split of forecast-crossval"),
        ("selection", "selection log of forecast-crossval"),
        ("coverage", "interval coverage of forecast-coverage"),
        ("learned-rows", "the learned model by mix and by random rows, of forecast-crossval"),
    ):
        p.add_argument(f"--{name}", required=True, help=what)
    p.add_argument("-o", "--output", required=True, help="the page (.md); figures in figures/ beside it")
    p.set_defaults(func=_page)


def _page(args) -> int:
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import read_csv, read_json, savefig, write_text
    from ..lab.matched import read_matched
    from . import page, render
    from .models import read_curves

    cfg = _config(args)["forecast"]
    route = cfg["binder_routes"][0]
    rows, scores = read_csv(args.rows), read_csv(args.scores)
    points = read_csv(args.points)
    out = Path(args.output)
    figures = {"predictions": "figures/predicted_vs_measured.png", "binders": "figures/binder_master_curves.png"}
    fig = render.prediction_figure(rows, route)
    savefig(fig, out.parent / figures["predictions"])
    plt.close(fig)
    fig = render.binder_figure(points, read_curves(args.curves))
    savefig(fig, out.parent / figures["binders"])
    plt.close(fig)
    text = page.page(
        args.table_name,
        read_matched(args.matched),
        points,
        rows,
        scores,
        read_json(args.constants),
        read_csv(args.forecast, allow_empty=True),
        read_json(args.forecast_constants)["best_model"],
        route,
        cfg["confidence"],
        figures,
        split=read_csv(args.split, allow_empty=True),
        selection=read_csv(args.selection, allow_empty=True),
        coverage=read_csv(args.coverage, allow_empty=True),
        learned_rows=read_csv(args.learned_rows, allow_empty=True),
    )
    write_text(text, out)
    return 0


def _add_overlay(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-config",
        help="the config overlay of make forecast: forecast.table or forecast.mix set to a file (YAML)",
        description="Write the YAML overlay that sets forecast.table (make forecast TABLE=...; with it the chain's "
        "working folder forecast.work_dir, results/forecasts/<folder>-<table>.work/forecast, so that make run's own "
        "results/forecast stays as it is) and/or forecast.mix (make forecast MIX=...): the paths reach the workflow "
        "through this file, so a path with spaces, quotes or non-ASCII characters works.",
    )
    p.add_argument("table_arg", nargs="?", default=None, metavar="table", help="the matched table (as --table)")
    p.add_argument("--table", default=None, help="the matched table (its sidecar <table stem>.test.json beside it)")
    p.add_argument("--mix", default=None, help="a mix file of new mixes (YAML)")
    p.add_argument("-o", "--output", required=True, help="the overlay (YAML)")
    p.set_defaults(func=_overlay)


def _overlay(args) -> int:
    from pathlib import Path

    import yaml

    from ..io import InputError, write_text
    from .product import table_work_dir

    table = args.table or args.table_arg
    if not table and not args.mix:
        raise InputError("forecast-config: give a matched table (TABLE=...) or a mix file (MIX=...)")
    section = {}
    if table:
        if not Path(table).is_file():
            raise InputError(f"TABLE={table}: file not found (expected a matched binder-mix table)")
        section["table"] = str(table)
        section["work_dir"] = table_work_dir(table)  # make run's own chain (results/forecast) left alone
    if args.mix:
        if not Path(args.mix).is_file():
            raise InputError(f"MIX={args.mix}: file not found (expected a mix file, YAML: data/README.md, 'Mix files')")
        section["mix"] = str(args.mix)
    write_text(
        "# written by make forecast (asphalt-nscd forecast-config): the files of this run\n"
        + yaml.safe_dump({"forecast": section}, allow_unicode=True, sort_keys=False),
        args.output,
    )
    return 0


def _add_bench(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-bench",
        help="the discrete forecast's cost per mix: packing, sample, response, against one solve per condition (JSON)",
        description="Prepare the sample of each mix asked for and time its packing, its sample, its response "
        "(one generalized eigen-decomposition) and, as the baseline of the same run, one sparse solve per "
        "condition (asphalt_nscd.forecast.bench).",
    )
    _add_config(p)
    p.add_argument("--table", required=True, help="matched table (any format the door reads)")
    p.add_argument("--mixes", nargs="+", required=True, help="mix_id of the mixes to time")
    p.add_argument("--seed", type=int, default=1, help="preparation seed")
    p.add_argument("--conditions", type=int, default=30, help="conditions of the baseline's direct solves")
    p.add_argument("-o", "--output", required=True, help="benchmark JSON")
    p.set_defaults(func=_bench)


def _bench(args) -> int:
    from ..io import write_json
    from . import bench

    records = []
    for mix in args.mixes:
        args.mix, args.size_dmax, args.cut_mm = mix, None, None
        row, sample_cfg, passing, coarse = _mix_settings(args)
        records.append(bench.bench_mix(sample_cfg, passing, coarse, str(mix), args.seed, args.conditions))
    write_json({"machine": bench.machine(), "mixes": records}, args.output)
    return 0


def _add_publish(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-publish",
        help="copy a complete forecast run, with its manifest, to its folder (the last complete run stays)",
        description="Copy the forecast's files into the folder of the table (results/forecasts/<folder>-<table>/) "
        "with manifest.json (the table's and each file's SHA-256); the folder holds the last complete run.",
    )
    p.add_argument("files", nargs="+", help="the run's files (under results/)")
    p.add_argument("--table", required=True, help="the matched table the run read")
    p.add_argument("--root", required=True, help="the folder the files' paths are kept relative to")
    p.add_argument("-o", "--output", required=True, help="the folder to publish to")
    p.set_defaults(func=_publish)


def _publish(args) -> int:
    from datetime import datetime, timezone

    from ..io import content_sha256, publish_directory

    manifest = {
        "table": str(args.table),
        "table_sha256": content_sha256(args.table),
        "written_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "about": "the last complete forecast of this table (make forecast / make run); a run that fails or is "
        "stopped leaves this folder as it was",
    }
    out = publish_directory(args.files, args.root, args.output, manifest)
    print(f"the complete forecast of {args.table}: {out}/ ({len(set(args.files))} files, manifest.json)")
    return 0


def _read_inputs(args):
    """(forecast config, matched table, binder of each mix, curves, responses) of a chain command."""
    from ..lab.matched import read_matched
    from .models import read_curves, read_responses
    from .validation import binder_ids

    cfg = _config(args)["forecast"]
    matched = read_matched(args.matched)
    return cfg, matched, binder_ids(matched), read_curves(args.curves), read_responses(args.responses)


def _binders(args) -> int:
    import logging

    from ..io import InputError, write_csv, write_json
    from ..lab.matched import read_matched
    from .binder import check_points, fit_binder_ladder
    from .models import binder_points
    from .validation import binder_ids

    matched = read_matched(args.matched)
    points = binder_points(matched, binder_ids(matched))
    try:
        checked = check_points(points.drop(columns="mixes"))
        fits = {b: fit_binder_ladder(g) for b, g in checked.groupby("binder")}
    except ValueError as exc:
        raise InputError(f"{args.matched}: {exc}") from None
    checked = checked.merge(points[["binder", "temperature_C", "frequency_Hz", "mixes"]], how="left")
    mixes = points.groupby("binder")["mixes"].first().to_dict()
    for b, (_, rung, shift) in fits.items():
        if rung != "passed":
            logging.getLogger("asphalt_nscd").warning(
                "%s: binder %s (mixes %s): too few points pass its checks; its master curve is fitted on the points "
                "that pass the %s checks",
                args.matched,
                b,
                mixes.get(b, ""),
                rung.replace("_", " and "),
            )
    write_csv(checked, args.output)
    curves = {b: c.as_dict() | {"mixes": mixes.get(b, ""), "fitted_on": rung} for b, (c, rung, _) in fits.items()}
    write_json({"curves": curves}, args.curves)
    return 0


def _response(args) -> int:
    import logging

    from ..io import InputError
    from ..sample.store import read_sample
    from .dem import Response, sample_response

    sample = read_sample(args.sample)
    try:
        response = sample_response(sample, args.mix, args.seed)
    except InputError as exc:  # a sample that carries no load: the discrete models cannot forecast this mix
        logging.getLogger("asphalt_nscd").warning("mix %s: no discrete forecast (%s)", args.mix, exc)
        response = Response.empty(args.mix, args.seed, sample)
    response.variant = str(args.variant)
    response.save(args.output)
    return 0


def _crossval(args) -> int:
    import pandas as pd

    from ..io import json_safe, write_csv, write_json
    from .models import headline_only, model_set, routed_tables
    from .learned import COMPARE_COLUMNS, GradientBoosting, by_rows, compare
    from .learned import NAME as LEARNED_NAME
    from .nested import selection_log
    from .validation import cross_validate, error_split, mix_folds, score

    cfg, matched, binder_of_mix, curves, responses = _read_inputs(args)
    models = model_set(cfg, responses)
    measured = matched.dropna(subset=["E_norm_MPa"])["mix_id"].unique()
    folds = mix_folds(measured, cfg.get("folds"), cfg.get("seed", 1))
    frames, states, learned_rows = [], [], None
    for i, (route, table) in enumerate(routed_tables(matched, curves, binder_of_mix, cfg["binder_routes"]).items()):
        # the physical ladder and the choice inside the fold on the headline route only (their cost)
        use = [m for m in models if m.available(table) and (i == 0 or not headline_only(m))]
        rows, st = cross_validate(table, use, binder_of_mix, folds, route, jobs=args.jobs)
        frames.append(rows)
        states += st
        learned = [m for m in use if m.model == LEARNED_NAME]
        if i == 0 and learned:  # the same model judged by random rows, tuned by rows: how much better it would look
            judged = by_rows(
                table, GradientBoosting(grid=learned[0].grid, inner="rows"), route, k=min(10, len(table) // 2)
            )
            learned_rows = compare(rows[rows["model"] == LEARNED_NAME], judged, cfg["confidence"])
    rows = pd.concat(frames, ignore_index=True)
    rows.insert(4, "label", _labels(rows))
    write_csv(rows, args.output)
    write_csv(score(rows, cfg["confidence"]).assign(label=lambda s: _labels(s)), args.scores)
    write_csv(error_split(rows, cfg["confidence"]).assign(label=lambda s: _labels(s)), args.split)
    write_csv(selection_log(states), args.selection)
    write_csv(learned_rows if learned_rows is not None else pd.DataFrame(columns=COMPARE_COLUMNS), args.learned_rows)
    write_json(json_safe({"folds": folds, "fits": states}), args.constants)
    return 0


def _labels(scores):
    return [m if m.startswith("dem") else f"{m}_{c}" for m, c in zip(scores["model"], scores["coefficients"])]


def _predict(args) -> int:
    import pandas as pd

    from ..io import json_safe, read_csv, write_csv, write_json
    from . import intervals, level1, product
    from .models import label, model_set, routed_tables

    cfg, matched, binder_of_mix, curves, responses = _read_inputs(args)
    route = cfg["binder_routes"][0]
    table = routed_tables(matched, curves, binder_of_mix, [route])[route]
    train = table.dropna(subset=["E_norm_MPa", "phase_deg"])
    todo = table[table["E_norm_MPa"].isna()]
    frames, fits = [], []
    for model in (m for m in model_set(cfg, responses) if m.available(table)):
        state = model.fit(train)
        fits.append({"model": label(model), "binder_route": route, "state": state})
        if todo.empty:
            continue
        E, P, _ = model.predict(state, todo)
        frames.append(
            pd.DataFrame(
                {
                    "mix_id": todo["mix_id"].to_numpy(),
                    "temperature_C": todo["temperature_C"].to_numpy(),
                    "frequency_Hz": todo["frequency_Hz"].to_numpy(),
                    "model": label(model),
                    "E_norm_MPa": E,
                    "phase_deg": P,
                }
            )
        )
    columns = ["mix_id", "temperature_C", "frequency_Hz", "model", "E_norm_MPa", "phase_deg"]
    forecast = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=columns)
    cal = read_csv(args.intervals) if args.intervals else None
    if cal is not None and len(forecast):
        forecast = intervals.apply(forecast, cal, route)
        columns += ["E_low_MPa", "E_high_MPa", "phase_low_deg", "phase_high_deg"]
    best = level1.best_model(read_csv(args.scores), route)
    tables, sigmoids = level1.designer_tables(forecast, best)
    write_csv(forecast[columns], args.output)
    write_csv(tables, args.level1)
    write_csv(sigmoids, args.sigmoid)
    write_json(json_safe({"binder_route": route, "best_model": best, "fits": fits}), args.constants)
    if args.state:
        product.write_state(args.state, cfg, train, json_safe(fits), best, cal, route)
    return 0


def _mix_settings(args):
    """(mix row, sample section of the mix, passing curve, coarse volume fraction, seed-free settings)."""
    import pandas as pd

    from ..io import InputError
    from ..lab.matched import read_matched
    from ..sample import settings
    from . import formulation

    cfg = _config(args)
    dem = cfg["forecast"]["dem"]
    cut = float(args.cut_mm if args.cut_mm is not None else dem["cut_mm"])
    size = float(args.size_dmax if args.size_dmax is not None else dem["size_dmax"])
    table = read_matched(args.table)
    rows = table[table["mix_id"] == str(args.mix)]
    if rows.empty:
        raise InputError(f"{args.table}: no mix {args.mix!r} (mixes: {list(pd.unique(table['mix_id']))[:10]} ...)")
    base = settings.merge(settings.DEFAULTS, cfg.get("sample") or {})
    sample_cfg, passing, coarse = formulation.sample_settings(
        base, rows.iloc[0], cut, size, float(dem["layer_over_side"])
    )
    return rows.iloc[0], sample_cfg, passing, coarse


def _pack(args) -> int:
    from ..sample import dynamics
    from ..sample.prepare import pack, save_packing

    dynamics.PROGRESS = bool(args.progress)
    _, sample_cfg, passing, _ = _mix_settings(args)
    save_packing(args.output, pack(sample_cfg, args.seed, passing))
    return 0


def _sample(args) -> int:
    from ..io import write_json
    from ..sample import dynamics
    from ..sample.prepare import finish, load_packing, write_outputs

    dynamics.PROGRESS = False
    mix, sample_cfg, _, coarse = _mix_settings(args)
    packing = load_packing(args.packing)
    seed = int(packing.summary.get("seed", 0))
    result = finish(packing, sample_cfg, seed, solid_fraction=coarse)
    result.sample.attrs["mix_id"] = str(mix["mix_id"])
    result.summary.update(mix_id=str(mix["mix_id"]), coarse_volume_fraction=coarse)
    write_outputs(result, args.output)
    if args.summary:
        write_json(result.summary, args.summary)
    return 0


def _add_coverage(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-coverage",
        help="prediction intervals of every forecast from the held-out rows, and their coverage with mixes left out",
        description="From the held-out rows of forecast-crossval: the intervals of a new mix's |E*| and phase per "
        "model, binder route and temperature (conformal, each mix weighing the same; asphalt_nscd.forecast.intervals) "
        "and their nested coverage (each mix's interval calibrated on the other mixes only), with t intervals over "
        "the mixes; with --forecast, the forecast table with its bounds.",
    )
    _add_config(p)
    p.add_argument("rows", help="held-out rows of forecast-crossval (CSV)")
    p.add_argument("-o", "--output", required=True, help="coverage per model, route, quantity and temperature (CSV)")
    p.add_argument("--intervals", required=True, help="the intervals calibrated on every mix (CSV)")
    p.add_argument("--level", type=float, default=None, help="nominal level of the intervals (default: 0.9)")
    p.add_argument(
        "--tails", choices=("equal", "symmetric"), default="equal", help="equal tails (default) or symmetric"
    )
    p.add_argument("--forecast", default=None, help="forecast.csv of forecast: add its bounds")
    p.add_argument("--forecast-output", default=None, help="the forecast with E_low_MPa ... phase_high_deg (CSV)")
    p.set_defaults(func=_coverage)


def _coverage(args) -> int:
    from ..io import InputError, read_csv, write_csv
    from . import intervals

    if (args.forecast is None) != (args.forecast_output is None):
        raise InputError("forecast-coverage: --forecast and --forecast-output go together")
    cfg = _config(args)["forecast"]
    level = intervals.LEVEL if args.level is None else args.level
    rows = read_csv(args.rows, dtype={"mix_id": str})
    intervals.residuals(rows, args.rows)  # the columns checked, naming the file
    write_csv(intervals.coverage(rows, level, args.tails, cfg["confidence"]), args.output)
    calibrated = intervals.calibrate(rows, level, args.tails)
    write_csv(calibrated, args.intervals)
    if args.forecast:
        forecast = read_csv(args.forecast, allow_empty=True, dtype={"mix_id": str})
        write_csv(intervals.apply(forecast, calibrated, cfg["binder_routes"][0]), args.forecast_output)
    return 0


def _add_mix_forecast(subparsers) -> None:
    p = subparsers.add_parser(
        "forecast-mix",
        help="forecast new mixes from a mix file (binder DSR sweeps, sieve analysis, volumetrics) with the trained state",
        description="Read a mix file (asphalt_nscd.lab.mix_input), fit each binder's master curve on its sweeps, "
        "prepare and solve each mix's sample, forecast it with every model of the trained state "
        "(asphalt_nscd.forecast.product) with its prediction interval, name every input outside the training "
        "mixes' ranges, and write the Level 1 tables, the AASHTO R 84 sigmoids, the binder inputs and a summary "
        "page per mix; the folder is published complete, with manifest.json (a failed run keeps the last one).",
    )
    _add_config(p)
    p.add_argument("mix_file", help="the mix file (YAML)")
    p.add_argument("--state", required=True, help="folder of the trained state (results/forecast/trained)")
    p.add_argument("--work", default=None, help="folder of the samples, kept to resume (default: <output>.work)")
    p.add_argument("-o", "--output", required=True, help="the folder to publish to")
    p.set_defaults(func=_mix)


def _mix(args) -> int:
    import logging
    from datetime import datetime, timezone
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import InputError, content_sha256, publish_directory, savefig, write_csv, write_text
    from ..lab.mix_input import read_mix_file
    from . import level1, mix_report, product

    log = logging.getLogger("asphalt_nscd")
    config = _config(args)
    state, training = product.read_state(args.state)
    mixes = read_mix_file(args.mix_file)
    table, curves, points, binder_of_mix, warnings = product.new_mix_table(mixes, state)
    for w in warnings + [w for m in mixes for w in m.warnings]:
        log.warning("%s: %s", args.mix_file, w)
    out = Path(args.output)
    work = Path(args.work) if args.work else out.with_name(out.name + ".work")
    run_config = {**config, "forecast": {**config["forecast"], "dem": state["forecast"]["dem"]}}
    discrete = any(f["model"].startswith("dem") for f in state["fits"])
    responses = product.prepare_responses(table, run_config, work / "samples", progress=print) if discrete else {}
    forecast = product.forecast_mixes(state, training, table, responses)
    best = state["best_model"]
    if best not in set(forecast["model"]):
        raise InputError(f"{args.mix_file}: the trained state's best model {best!r} could not forecast these mixes")
    tables, sigmoids = level1.designer_tables(forecast, best)
    binder = product.binder_inputs(curves, binder_of_mix, state["grid"]["temperatures_C"])
    outside = product.extrapolation(state, table)
    for _, r in outside.iterrows():
        log.warning(
            "%s: mix %s: %s = %.4g lies outside the training mixes' range %.4g to %.4g: its forecast is an "
            "extrapolation (intervals marked extrapolated)",
            args.mix_file,
            r["mix_id"],
            r["input"],
            r["value"],
            r["low"],
            r["high"],
        )
    stage = work / "publish"
    files = []
    for frame, name in (
        (forecast, "forecast.csv"),
        (tables, "level1_tables.csv"),
        (sigmoids, "sigmoid_master_curves.csv"),
        (binder, "binder_inputs.csv"),
        (points, "binder_points.csv"),
        (outside, "extrapolation.csv"),
    ):
        write_csv(frame, stage / name)
        files.append(stage / name)
    for m in mixes:
        sig = sigmoids[sigmoids["mix_id"] == m.mix_id].iloc[0]
        fig = mix_report.master_curve_figure(m.mix_id, forecast, sig, training, best)
        figure = f"figures/{m.mix_id}_master_curve.png"
        savefig(fig, stage / figure)
        plt.close(fig)
        page = mix_report.summary_page(
            m.mix_id, m, forecast, tables, sig, binder, outside[outside["mix_id"] == m.mix_id], state, figure
        )
        write_text(page, stage / f"{m.mix_id}.md")
        files += [stage / figure, stage / f"{m.mix_id}.md"]
    manifest = {
        "mix_file": str(args.mix_file),
        "mix_file_sha256": content_sha256(args.mix_file),
        "trained_state_sha256": content_sha256(Path(args.state) / product.STATE),
        "written_utc": datetime.now(timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "about": "the last complete forecast of this mix file (make forecast MIX=...); " + product.state_summary(state),
    }
    dest = publish_directory([str(f) for f in files], stage, out, manifest)
    print(f"the forecast of {args.mix_file}: {dest}/ ({', '.join(m.mix_id + '.md' for m in mixes)}, manifest.json)")
    return 0
