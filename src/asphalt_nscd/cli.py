"""Command-line interface ``asphalt-nscd``: one subcommand per workflow step.

Each subpackage's ``cli`` module defines ``register(subparsers)`` which adds its
subcommands; handlers import heavy modules (numba kernels, matplotlib) lazily so that
``asphalt-nscd --help`` stays fast. Bad input raises :class:`asphalt_nscd.io.InputError`,
reported as ``error: ...`` with exit status 2. SIGTERM (what Snakemake and SLURM send to a
job they stop) raises ``SystemExit(143)``, so that temporary files are removed and a long
simulation resumes from its last checkpoint when rerun.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from .io import InputError, request_termination

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


def _terminate(signum, frame) -> None:
    """SIGTERM handler: unwind like an exception (atomic writers remove their temporary files)."""
    request_termination(signum)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    signal.signal(signal.SIGTERM, _terminate)
    try:
        status = args.func(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
