"""Subcommands of the figures/report step (registered by asphalt_nscd.cli)."""

from __future__ import annotations

import shutil

import numpy as np
from pathlib import Path

from ..io import InputError, atomic_path, read_csv, require_columns, write_text


def register(subparsers) -> None:
    """Add this step's subcommands to the ``asphalt-nscd`` parser."""
    p = subparsers.add_parser(
        "collect-report",
        help="copy the workflow's figures and tables into one report directory with an index",
    )
    p.add_argument("files", nargs="*", type=Path, help="figures (png/svg) and tables (csv/json/md)")
    p.add_argument("--out-dir", type=Path, required=True, help="report directory, e.g. results/report")
    p.add_argument("-o", "--output", type=Path, required=True, help="index file (Markdown)")
    p.set_defaults(func=_collect_report)

    p = subparsers.add_parser(
        "plot-rheology",
        help="isotherms of |E*| and phase, Black diagram, Cole-Cole plane of named curve sets",
    )
    p.add_argument(
        "--points",
        action="append",
        default=[],
        metavar="LABEL=CSV",
        help="a curve set drawn as markers (error bars from *_std columns); repeatable",
    )
    p.add_argument(
        "--lines",
        action="append",
        default=[],
        metavar="LABEL=CSV",
        help="a curve set drawn as lines (e.g. model curves); repeatable",
    )
    p.add_argument("--title", default=None, help="figure title")
    for plot in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole"):
        p.add_argument(f"--{plot}", type=Path, default=None, metavar="PNG", help=f"write the {plot} figure here")
    p.set_defaults(func=_plot_rheology)

    p = subparsers.add_parser(
        "master-curve-figures",
        help="master curve, shift factors, per-cell residuals and the sigmoidal (MEPDG) master curve",
        description="The figures of a measured table (asphalt_nscd.figures.master_curves): the master curve with "
        "the measured points coloured by temperature (2S2P1D, the extended law, the sigmoid), the shift "
        "factors, the extended law's per-cell residuals, and the sigmoidal MEPDG / AASHTO R 84 master "
        "curve fitted beside 2S2P1D with its parameters in a table.",
    )
    p.add_argument("--master-curve", type=Path, required=True, help="master-curve JSON (asphalt-nscd master-curve)")
    p.add_argument("--corrected-table", type=Path, required=True, help="artifact-corrected table of master-curve")
    p.add_argument("--law-json", type=Path, default=None, help="law JSON of extend-law (adds its curves)")
    p.add_argument("--master-figure", type=Path, required=True, help="master-curve figure (png)")
    p.add_argument("--shift-figure", type=Path, required=True, help="shift-factor figure (png)")
    p.add_argument("--residual-figure", type=Path, default=None, help="per-cell residuals of the law (png)")
    p.add_argument("--residual-table", type=Path, default=None, help="per-cell residuals of the law (csv)")
    p.add_argument("--sigmoid", type=Path, required=True, help="sigmoid parameters beside 2S2P1D's (csv)")
    p.set_defaults(func=_master_curve_figures)

    p = subparsers.add_parser(
        "card-figures",
        help="isochrones of a material card against the measured means; its E(t) and D(t); error against N",
        description="The figures of a material card (asphalt_nscd.figures.cards): |E*| and Phi against temperature "
        "at each tested frequency, the measured replicate means and the card; the card's relaxation "
        "modulus E(t) and creep compliance D(t) at each tested temperature; its largest difference to the "
        "law it carries against the number of Prony terms. In the lab's units.",
    )
    p.add_argument("--card", type=Path, required=True, help="card JSON (export-law: prony.json)")
    p.add_argument("--errors", type=Path, required=True, help="the card's cells (export-law: card_errors.csv)")
    p.add_argument(
        "--functions", type=Path, required=True, help="E(t), D(t) of the card (export-law: relaxation_creep.csv)"
    )
    p.add_argument("--isochrones", type=Path, required=True, help="isochrones figure (png)")
    p.add_argument("--relaxation-creep", type=Path, required=True, help="E(t) and D(t) figure (png)")
    p.add_argument(
        "--terms-curve",
        type=Path,
        required=True,
        help="the card's largest difference to its law against the number of Prony terms (png)",
    )
    p.set_defaults(func=_card_figures)


def _card_figures(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import read_json, savefig
    from ..lab.table_format import MODULUS_UNITS, DisplayUnits
    from . import cards

    card = read_json(args.card, "material card JSON")
    if not isinstance(card, dict) or not isinstance(card.get("terms"), list) or "shift" not in card:
        raise InputError(f"{args.card}: keys 'terms' and 'shift' expected (a card of asphalt-nscd export-law)")
    display = card.get("display") or {}
    units = DisplayUnits(display.get("modulus", "MPa"), display.get("temperature", "C"))
    if units.modulus not in MODULUS_UNITS or units.temperature not in ("C", "F"):
        raise InputError(f"{args.card}: key 'display': unknown units {display}")
    errors = read_csv(args.errors)
    functions = read_csv(args.functions)
    for frame, path, need in (
        (errors, args.errors, ("temperature_C", "frequency_Hz", "E_norm_MPa_measured", "phase_deg_measured")),
        (functions, args.functions, ("temperature_C", "time_s", "E_MPa", "D_per_MPa")),
    ):
        require_columns(frame, need, path)
    if not isinstance(card.get("terms_selection"), dict) or "curve" not in card["terms_selection"]:
        raise InputError(
            f"{args.card}: key 'terms_selection' with its 'curve' expected (a card of asphalt-nscd export-law)"
        )
    for fig, path in (
        (cards.isochrones_figure(card, errors, units), args.isochrones),
        (cards.relaxation_creep_figure(functions, units), args.relaxation_creep),
        (cards.terms_curve_figure(card), args.terms_curve),
    ):
        savefig(fig, path)
        plt.close(fig)
    return 0


def _master_curve_figures(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    from ..diagnosis.artifacts import read, read_corrected
    from ..io import read_json, savefig, write_csv
    from ..rheology.sigmoid import fit_sigmoid
    from . import master_curves as mc

    from ..lab.table_format import DisplayUnits

    rec = read(args.master_curve)
    master = rec.master
    corrected = read_corrected(args.corrected_table)
    units = DisplayUnits(**rec.units) if rec.units else DisplayUnits()
    law = read_json(args.law_json, "law JSON") if args.law_json else None
    sig = fit_sigmoid(corrected, master.T_ref_C)
    two = {
        "model": "2S2P1D",
        "shift": master.shift,
        "T_ref_C": master.T_ref_C,
        "rmse_log10": float(
            np.sqrt(
                np.mean(
                    (
                        np.log10(np.abs(master.modulus(corrected["frequency_Hz"], corrected["temperature_C"])))
                        - np.log10(corrected["E_norm_MPa"])
                    )
                    ** 2
                )
            )
        ),
    }
    rows = [
        {"model": "sigmoid (MEPDG, AASHTO R 84)", "shift": "quadratic", **sig},
        {
            **two,
            **{
                f"2S2P1D_{k}": v
                for k, v in dict(zip(master.names, master.x)).items()
                if not k.startswith(("ln_spec", "phase_spec"))
            },
        },
    ]
    write_csv(pd.DataFrame(rows), args.sigmoid)
    free = {float(T): float(v) for T, v in rec.free_shifts.items()} if rec.free_shifts else None
    for fig, path in (
        (mc.master_curve_figure(master, corrected, law, sig, units), args.master_figure),
        (mc.shift_factor_figure(master, law, sig, corrected["temperature_C"].unique(), free, units), args.shift_figure),
    ):
        savefig(fig, path)
        plt.close(fig)
    if law is not None and (args.residual_figure or args.residual_table):
        res = mc.residual_table(corrected, law)
        if args.residual_table:
            write_csv(res, args.residual_table)
        if args.residual_figure:
            fig = mc.residual_figure(res, units)
            savefig(fig, args.residual_figure)
            plt.close(fig)
    return 0


def _collect_report(args) -> int:
    """Copy each file to OUT_DIR/<path below results/> and write a Markdown index: one section
    per step (the first folder below results/), the steps in the order their first file comes,
    each step's files in their given order."""
    missing = [str(src) for src in args.files if not src.is_file()]
    if missing:  # before any copy: a refused report leaves nothing behind
        raise InputError(
            f"{missing[0]}: report input does not exist"
            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
        )
    sections: dict[str, list[str]] = {}
    for src in args.files:
        rel = src.relative_to("results") if src.parts and src.parts[0] == "results" else Path(src.name)
        dest = args.out_dir / rel
        if dest.resolve() != src.resolve():
            with atomic_path(dest) as tmp:
                shutil.copyfile(src, tmp)
        link = rel.as_posix()
        entry = f"![{link}]({link})" if src.suffix.lower() in {".png", ".svg", ".jpg"} else f"- [{link}]({link})"
        sections.setdefault(rel.parts[0] if len(rel.parts) > 1 else "other", []).append(entry)
    lines = ["# Report", "", "Figures and tables of the workflow, by step.", ""]
    for step, entries in sections.items():
        lines += ["", f"## {step}", "", *entries]
    write_text("\n".join(lines) + "\n", args.output)
    return 0


def _parse_set(spec: str, kind: str):
    from ..rheology.plots import CurveSet

    label, sep, path = spec.partition("=")
    if not sep or not label or not path:
        raise InputError(f"curve set {spec!r}: expected LABEL=PATH")
    frame = read_csv(path)
    try:
        return CurveSet(label, frame, kind=kind)
    except ValueError as exc:
        raise InputError(f"{path}: {exc}") from None


def _plot_rheology(args) -> int:
    """Draw the requested rheology plots of the given curve sets (one PNG per plot)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import savefig
    from ..rheology.plots import rheology_figure

    sets = [_parse_set(s, "points") for s in args.points] + [_parse_set(s, "line") for s in args.lines]
    if not sets:
        raise InputError("plot-rheology: give at least one --points or --lines curve set")
    outputs = {
        plot: getattr(args, plot.replace("-", "_"))
        for plot in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole")
    }
    if not any(outputs.values()):
        raise InputError(
            "plot-rheology: give at least one output (--isotherms-modulus, --isotherms-phase, --black, --cole-cole)"
        )
    for plot, path in outputs.items():
        if path is None:
            continue
        fig = rheology_figure(sets, plot, title=args.title)
        savefig(fig, path)
        plt.close(fig)
    return 0
