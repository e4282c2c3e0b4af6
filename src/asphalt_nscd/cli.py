"""Command-line interface ``asphalt-nscd``: one subcommand per workflow step.

Each subpackage's ``cli`` module defines ``register(subparsers)`` which adds its
subcommands; handlers import heavy modules (numba kernels, matplotlib) lazily so that
``asphalt-nscd --help`` stays fast. Bad input raises :class:`asphalt_nscd.io.InputError`,
reported as ``error: ...`` with exit status 2. SIGTERM (what Snakemake and SLURM send to a
job they stop) raises ``SystemExit(143)``, so that temporary files are removed and a long
simulation resumes from its last checkpoint when rerun.

When the environment variable ``ASPHALT_NSCD_CPU_LOG`` names a file (the workflow sets it to
``benchmarks/process_cpu.jsonl``), every command appends one JSON line to it at its end: its
arguments, exit status and the exact CPU of its process and of the worker processes it waited
for (``getrusage``, interpreter start-up and imports included), unlike Snakemake's sampled
``benchmark:`` records (:func:`cpu_record`).
"""

from __future__ import annotations

import os

# One BLAS thread per command unless the user sets another count: a workflow runs its jobs side by side
# (one per core), and OpenBLAS's own threads then spin-wait for work: the harmonic sweep of a 1,624-sphere
# sample took 21.3 s of CPU with them and 13.3 s without, in the same wall time, |E*| and phases within 4e-13. Set
# before numpy and scipy load OpenBLAS, which reads it once (docs/choices.md, Resources and profiles).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import functools  # noqa: E402
import importlib  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

from . import STAGES  # noqa: E402
from .io import InputError, request_termination  # noqa: E402

#: Environment variable naming the JSON-lines file that every command appends its CPU record to
#: (:func:`cpu_record`); unset: no record.
CPU_LOG_ENV = "ASPHALT_NSCD_CPU_LOG"

#: Subpackages contributing subcommands: the stages (:data:`asphalt_nscd.STAGES`).
SUBCOMMAND_PACKAGES = STAGES


#: Help groups of the subcommands: the package that registers a command names its group; the
#: benchmarks (commands ending in "bench") form a group of their own.
COMMAND_GROUPS = {
    "lab": "data",
    "rheology": "calibration",
    "sample": "samples",
    "nscd": "simulation",
    "campaign": "simulation",
    "harmonic": "harmonic",
    "diagnosis": "diagnosis",
    "forecast": "forecast",
    "figures": "figures",
}
GROUP_ORDER = (
    "data",
    "calibration",
    "samples",
    "simulation",
    "harmonic",
    "diagnosis",
    "forecast",
    "figures",
    "benchmarks",
)


def build_parser() -> argparse.ArgumentParser:
    """The ``asphalt-nscd`` parser: every subcommand of :data:`SUBCOMMAND_PACKAGES`, listed by
    group with its one-line description; ``--version``, ``--verbose``, ``--quiet``."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="asphalt-nscd",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="NSCD modelling of the complex modulus of asphalt concrete (Quezada & Chazallon 2020), "
        "from the lab table to the material card.",
    )
    parser.add_argument("--version", action="version", version=f"asphalt-nscd {__version__}")
    level = parser.add_mutually_exclusive_group()
    level.add_argument("-v", "--verbose", action="store_true", help="log the steps of a command (DEBUG)")
    level.add_argument("-q", "--quiet", action="store_true", help="log warnings and errors only")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    groups: dict[str, list] = {g: [] for g in GROUP_ORDER}
    for name in SUBCOMMAND_PACKAGES:
        before = set(sub.choices)
        importlib.import_module(f"asphalt_nscd.{name}.cli").register(sub)
        for cmd in sub.choices:
            if cmd in before:
                continue
            group = "benchmarks" if cmd.endswith("bench") else COMMAND_GROUPS[name]
            groups[group].append(cmd)
    helps = {a.dest: a.help for a in sub._choices_actions}
    for cmd, p in sub.choices.items():
        if not p.description:  # every command's --help opens with its one-line description
            p.description = helps.get(cmd)
    width = max(len(c) for c in sub.choices) + 2
    lines = ["commands, by step of the chain:"]
    for group in GROUP_ORDER:
        if groups[group]:
            lines.append(f"\n  {group}:")
            lines += [f"    {cmd:<{width}}{(helps.get(cmd) or '').replace('%%', '%')}" for cmd in groups[group]]
    parser.epilog = "\n".join(lines) + "\n\n'asphalt-nscd COMMAND --help' describes a command and its options."
    sub._choices_actions = []  # listed above by group, not once more unordered
    return parser


@functools.lru_cache(maxsize=1)
def _commands() -> dict:
    """Subcommand name -> its parser (built once per process)."""
    return dict(next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices)


def config_values(command: str, cfg, **args) -> dict:
    """The option values command ``command`` takes from the merged, checked config ``cfg`` when
    run with the options ``args`` (argument name -> value; the others at their defaults): what
    a rule keeps as its ``settings`` parameter, so that a change of them, and only of them,
    reruns it.

    Raises
    ------
    KeyError
        for a command that takes no values from a config.
    """
    sub = _commands()[command]
    values = sub.get_default("config_values")
    if values is None:
        raise KeyError(f"asphalt-nscd {command} takes no option values from --config")
    defaults = {a.dest: a.default for a in sub._actions if a.dest != "help"}
    known = set(defaults)
    return {
        k: v
        for k, v in values(cfg, argparse.Namespace(**{**defaults, **args, "command": command})).items()
        if k in known
    }


def with_config_values(parser: argparse.ArgumentParser, args: argparse.Namespace, argv) -> argparse.Namespace:
    """``args`` of a command that takes its option values from a workflow config: when the
    command declares ``config_values`` (:func:`asphalt_nscd.config.config_option`) and was given ``--config
    FILE...``, the files are merged and checked against the workflow's schemas
    (:func:`asphalt_nscd.config.checked`), the values become the command's defaults, and the
    command line is parsed again, so that an option given on it wins.

    Raises
    ------
    InputError
        naming the config file and key that cannot be read or that the schemas refuse.
    """
    values = getattr(args, "config_values", None)
    if values is None or not getattr(args, "config", None):
        return args
    from . import config

    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[args.command]
    known = {a.dest for a in sub._actions}
    sub.set_defaults(**{k: v for k, v in values(config.checked(args.config), args).items() if k in known})
    return parser.parse_args(argv)


def _terminate(signum, frame) -> None:
    """SIGTERM handler: unwind like an exception (atomic writers remove their temporary files)."""
    request_termination(signum)


def cpu_record(argv: list[str], status: int | str, wall_s: float) -> dict:
    """The CPU record of this process at its end: ``argv`` (the command's arguments),
    ``status`` (exit status, or the name of the exception that ended it), ``user_s`` and
    ``system_s`` (s, this process from its start, interpreter and imports included, plus the
    child processes it waited for: the worker pools of the benchmarks and the searches),
    ``max_rss_mb`` (MB, the largest resident set of this process or of one child) and
    ``wall_s`` (s, from the start of :func:`main`). Source: ``getrusage(2)``, exact where
    Snakemake's ``benchmark:`` samples the process tree (every 1 s, later every 30 s) and loses
    the CPU after its last sample; only the interpreter's exit after the record is not in it
    (about 0.1 s with numba loaded on an idle machine, up to 0.3 s seen under load)."""
    import resource

    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {
        "argv": list(argv),
        "status": status,
        "user_s": round(own.ru_utime + children.ru_utime, 4),
        "system_s": round(own.ru_stime + children.ru_stime, 4),
        "max_rss_mb": round(max(own.ru_maxrss, children.ru_maxrss) / 1024.0, 1),  # Linux: KiB
        "wall_s": round(wall_s, 4),
        "pid": os.getpid(),
        "end": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }


def append_cpu_record(path: str, record: dict) -> None:
    """Append ``record`` as one JSON line to ``path`` (its folder created), under an exclusive
    lock, so that jobs ending together do not interleave. A log that cannot be written warns on
    stderr and does not fail the command."""
    import fcntl
    import json
    from pathlib import Path

    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        with open(path, "a", encoding="utf-8") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            fh.write(json.dumps(record) + "\n")
            fh.flush()
    except OSError as exc:
        print(f"warning: {path}: the CPU record of this command could not be written ({exc})", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    start = time.perf_counter()
    args_list = sys.argv[1:] if argv is None else list(argv)
    status: int | str = "interrupted"
    try:
        status = _main(argv)
        return status
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
        raise
    except BaseException as exc:
        status = type(exc).__name__
        raise
    finally:
        log = os.environ.get(CPU_LOG_ENV)
        if log:
            append_cpu_record(log, cpu_record(args_list, status, time.perf_counter() - start))


def _main(argv: list[str] | None) -> int:
    import logging

    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO,
        format="%(asctime)s %(name)s %(levelname)s: %(message)s",
        stream=sys.stderr,
    )
    logging.getLogger("asphalt_nscd").debug("asphalt-nscd %s", " ".join(sys.argv[1:] if argv is None else argv))
    signal.signal(signal.SIGTERM, _terminate)
    try:
        args = with_config_values(parser, args, argv)
        status = args.func(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the file system's errors (a directory not writable, a full disk): one line
        where = exc.filename if exc.filename is not None else "file system"
        print(
            f"error: {where}: {exc.strerror or exc} (a file or folder could not be read or written; check the "
            "path and its permissions)",
            file=sys.stderr,
        )
        return 2
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
