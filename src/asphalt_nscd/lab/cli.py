"""Subcommands of the lab step (registered by asphalt_nscd.cli).

* ``reduce``   — EN 12697-26 reduction of a force/displacement record (Eqs. 1-5).
* ``measured`` — validate a measured complex-modulus table, write the tidy table and the
  replicate summary.
* ``matched``  — read a matched binder-mix table and write it in the project's columns.
"""

from __future__ import annotations

from pathlib import Path


def _reduce_config_values(cfg, args) -> dict:
    """``reduce --config``: the lab's analysis window ``lab.window_s`` (unless --window-cycles)."""
    window = cfg["lab"].get("window_s")
    return {} if args.window_cycles is not None or window is None else {"window_s": float(window)}


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser(
        "reduce",
        help="EN 12697-26 2PB reduction of a head displacement/force record to |E*|, phase (Eqs. 1-5)",
    )
    p.add_argument("record", type=Path, help="CSV with columns time_s, displacement_m, force_N")
    p.add_argument(
        "--meta",
        type=Path,
        required=True,
        help="JSON sidecar with b_mm, B_mm, e_mm, h_mm, M_kg, m_kg, temperature_C, frequency_Hz",
    )
    window = p.add_mutually_exclusive_group()
    window.add_argument(
        "--window-s",
        type=float,
        default=None,
        help="analyse the last WINDOW_S seconds (lab: 10; default: whole record)",
    )
    window.add_argument(
        "--window-cycles", type=float, default=None, help="analyse the last WINDOW_CYCLES cycles (simulation: 1)"
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="one-row CSV of the reduced results")
    from ..config import config_option

    config_option(p, _reduce_config_values, "lab.window_s")
    p.set_defaults(func=_reduce)

    p = subparsers.add_parser(
        "measured",
        help="validate a measured complex-modulus table; write the tidy table and the replicate summary",
    )
    p.add_argument(
        "table",
        type=Path,
        help="CSV: specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg [, strain_microstrain, test_order, ...]",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="validated tidy table (CSV)")
    p.add_argument(
        "--summary", type=Path, required=True, help="replicate mean and std per (temperature_C, frequency_Hz) (CSV)"
    )
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="test-geometry JSON of the table (default: the sidecar <table stem>.test.json next to "
        "it, else an unknown test); see asphalt_nscd.lab.geometry",
    )
    p.add_argument(
        "--test-output",
        type=Path,
        default=None,
        help="write the declared test (validated) as JSON, e.g. next to -o as <stem>.test.json",
    )
    p.set_defaults(func=_measured)

    m = subparsers.add_parser(
        "matched",
        help="read a matched binder-mix table (as published, with its sidecar); write it in the project's columns",
        description="Read a matched binder-mix table -- each mix's measured |E*| and phase (empty where they are to "
        "be forecast) beside its binder's |G*|, phase angle and viscosity and its gradation and volumetrics -- in "
        "its own headers and units declared in the sidecar <table stem>.test.json (asphalt_nscd.lab.matched), "
        "check it, and write it in the project's columns and units.",
    )
    m.add_argument("table", type=Path, help="the table (.csv, .tsv or .txt)")
    m.add_argument("--sidecar", type=Path, default=None, help="its sidecar (default: <table stem>.test.json beside it)")
    m.add_argument("-o", "--output", type=Path, required=True, help="the table in the project's columns (CSV)")
    m.add_argument("--mixes", nargs="+", default=None, help="keep only these mixes (default: every mix)")
    m.add_argument(
        "--config",
        nargs="+",
        metavar="FILE",
        default=None,
        help="workflow config files (YAML, merged as Snakemake merges them): their forecast.mixes, unless --mixes",
    )
    m.set_defaults(func=_matched)


def _reduce(args) -> int:
    import pandas as pd

    from ..io import InputError, write_csv
    from .en12697 import read_record, reduce_record

    columns, specimen, conditions = read_record(args.record, args.meta)
    try:
        row = reduce_record(
            columns["time_s"],
            columns["displacement_m"],
            columns["force_N"],
            specimen,
            conditions["frequency_Hz"],
            window_s=args.window_s,
            window_cycles=args.window_cycles,
        )
    except ValueError as exc:
        raise InputError(f"{args.record}: {exc}") from None
    row = {"record": args.record.stem, "temperature_C": conditions["temperature_C"], **row}
    write_csv(pd.DataFrame([row]), args.output, float_format="%.10g")
    return 0


def _measured(args) -> int:
    from ..io import write_csv, write_json
    from .measured import load_measured, summarize

    frame = load_measured(args.table, test=args.test)
    summary = summarize(frame)
    write_csv(frame, args.output)
    write_csv(summary, args.summary, float_format="%.6g")
    if args.test_output is not None:
        write_json(frame.attrs["test"].to_json(), args.test_output)
    return 0


def _matched(args) -> int:
    from .matched import read_matched, write_matched

    from ..io import InputError

    table = read_matched(args.table, args.sidecar)
    if args.mixes is None and args.config:
        from .. import config

        mixes = config.checked(args.config)["forecast"].get("mixes")
        args.mixes = None if not mixes else [str(x) for x in mixes]
    if args.mixes:
        missing = sorted(set(args.mixes) - set(table["mix_id"]))
        if missing:
            raise InputError(f"{args.table}: no mix {missing} (config forecast.mixes)")
        table = table[table["mix_id"].isin(args.mixes)]
    write_matched(table, args.output)
    return 0
