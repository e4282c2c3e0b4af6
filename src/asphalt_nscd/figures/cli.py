"""Subcommands of the figures/report step (registered by asphalt_nscd.cli)."""

from __future__ import annotations

import shutil
from pathlib import Path

from ..io import InputError, atomic_path, read_csv, write_text


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
    p.add_argument("--points", action="append", default=[], metavar="LABEL=CSV",
                   help="a curve set drawn as markers (error bars from *_std columns); repeatable")
    p.add_argument("--lines", action="append", default=[], metavar="LABEL=CSV",
                   help="a curve set drawn as lines (e.g. model curves); repeatable")
    p.add_argument("--title", default=None, help="figure title")
    for plot in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole"):
        p.add_argument(f"--{plot}", type=Path, default=None, metavar="PNG", help=f"write the {plot} figure here")
    p.set_defaults(func=_plot_rheology)


def _collect_report(args) -> int:
    """Copy each file to OUT_DIR/<path below results/> and write a Markdown index."""
    lines = ["# Report", "", "Figures and tables of the workflow, by step.", ""]
    section = None
    for src in args.files:
        if not src.is_file():
            raise InputError(f"{src}: report input does not exist")
        rel = src.relative_to("results") if src.parts and src.parts[0] == "results" else Path(src.name)
        dest = args.out_dir / rel
        if dest.resolve() != src.resolve():
            with atomic_path(dest) as tmp:
                shutil.copyfile(src, tmp)
        step = rel.parts[0] if len(rel.parts) > 1 else "other"
        if step != section:
            lines += ["", f"## {step}", ""]
            section = step
        link = rel.as_posix()
        if src.suffix.lower() in {".png", ".svg", ".jpg"}:
            lines.append(f"![{link}]({link})")
        else:
            lines.append(f"- [{link}]({link})")
    write_text("\n".join(lines) + "\n", args.output)
    return 0


def _parse_set(spec: str, kind: str):
    from .rheology_plots import CurveSet

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
    from .rheology_plots import rheology_figure

    sets = [_parse_set(s, "points") for s in args.points] + [_parse_set(s, "line") for s in args.lines]
    if not sets:
        raise InputError("plot-rheology: give at least one --points or --lines curve set")
    outputs = {plot: getattr(args, plot.replace("-", "_")) for plot in
               ("isotherms-modulus", "isotherms-phase", "black", "cole-cole")}
    if not any(outputs.values()):
        raise InputError("plot-rheology: give at least one output (--isotherms-modulus, --isotherms-phase, --black, --cole-cole)")
    for plot, path in outputs.items():
        if path is None:
            continue
        fig = rheology_figure(sets, plot, title=args.title)
        savefig(fig, path)
        plt.close(fig)
    return 0
