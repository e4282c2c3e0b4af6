"""Subcommands of the figures/report step (registered by asphalt_nscd.cli)."""

from __future__ import annotations

import shutil
from pathlib import Path

from ..io import InputError, atomic_path, write_text


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
