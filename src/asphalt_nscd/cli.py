"""Command-line interface ``asphalt-nscd``: one subcommand per workflow step.

Each subpackage's ``cli`` module defines ``register(subparsers)`` which adds its
subcommands; handlers import heavy modules (numba kernels, matplotlib) lazily so that
``asphalt-nscd --help`` stays fast. Bad input raises :class:`asphalt_nscd.io.InputError`,
reported as ``error: ...`` with exit status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .io import InputError

#: Subpackages contributing subcommands, in the order of the workflow's chain.
SUBCOMMAND_PACKAGES = (
    "lab",
    "rheology",
    "sample",
    "nscd",
    "campaign",
    "harmonic",
    "diagnosis",
    "figures",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="asphalt-nscd",
        description="NSCD modelling of the complex modulus of asphalt concrete.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMAND_PACKAGES:
        importlib.import_module(f"asphalt_nscd.{name}.cli").register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        status = args.func(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
