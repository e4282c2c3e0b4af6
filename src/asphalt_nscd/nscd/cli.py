"""Subcommands of the nscd step (registered by asphalt_nscd.cli).

``asphalt-nscd verify -o verify.json [--csv verify.csv] [--phase-table phase.csv]
[--figure verify.png]`` runs the verification cases of :mod:`.verify`.

``asphalt-nscd bench-summary a.json b.json -o bench.csv`` tabulates the records of
``asphalt-nscd bench`` (registered by :mod:`asphalt_nscd.campaign.cli`: its periodic start
needs the harmonic solver).
"""


def config_values(cfg, args) -> dict:
    """Option values of this step's commands from the ``nscd`` section of a merged, checked
    workflow config (``--config``; an option given on the command line wins): the phase error
    table of ``verify`` (nscd.verify) and the benchmark settings of ``bench`` (nscd.bench, the
    case's tolerance, the core's bond kinematics and bonded contact)."""
    nscd = cfg["nscd"]
    if args.command == "verify":
        ver = nscd["verify"]
        return {
            "phase_frequencies": ",".join(f"{float(x):g}" for x in ver["phase_frequencies_Hz"]),
            "phase_dts": ",".join(f"{float(x):g}" for x in ver["phase_dts_s"]),
            "phase_thetas": ",".join(f"{float(x):g}" for x in ver["phase_thetas"]),
        }
    bench = nscd["bench"]
    return {
        "steps": int(bench["steps"]),
        "baseline_steps": int(bench["baseline_steps"]),
        "settle_steps": int(bench["settle_steps"]),
        "settle_speed": float(bench["settle_speed_m_s"]),
        "tolerance": float(bench["granular_tolerance" if args.case == "granular" else "tolerance"]),
        "bond_kinematics": nscd["bond_kinematics"],
        "bonded_contact": nscd["bonded_contact"],
    }


def config_option(p) -> None:
    """``--config``: the option values of :func:`config_values`."""
    from ..config import config_option as option

    option(p, config_values, "its nscd section")


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser("verify", help="NSCD core verification against closed forms")
    p.add_argument("-o", "--output", required=True, help="JSON list of verification rows")
    p.add_argument("--csv", help="the same rows as CSV")
    p.add_argument("--phase-table", help="CSV of the phase error vs omega dt and theta")
    p.add_argument("--figure", help="figure (PNG/PDF) of the phase error table")
    p.add_argument(
        "--phase-dts",
        default="1e-5,2e-5,5e-5,1e-4,2e-4",
        help="time steps (s) of the phase error table, comma-separated",
    )
    p.add_argument(
        "--phase-thetas", default="0.5,0.55,1.0", help="theta values of the phase error table, comma-separated"
    )
    p.add_argument(
        "--phase-frequencies", default="3,40", help="frequencies (Hz) of the phase error table, comma-separated"
    )
    p.add_argument("--strict", action="store_true", help="exit 1 if a case fails")
    config_option(p)
    p.set_defaults(func=_verify)

    c = subparsers.add_parser("bench-summary", help="table of NSCD benchmark JSON records")
    c.add_argument("inputs", nargs="+", help="bench JSON files")
    c.add_argument("-o", "--output", required=True, help="CSV, one row per record")
    c.set_defaults(func=_bench_summary)


def _floats(text, name):
    from ..io import InputError

    try:
        vals = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError as exc:
        raise InputError(f"option {name}: expected comma-separated numbers, got {text!r}") from exc
    if not vals:
        raise InputError(f"option {name}: empty list")
    return vals


def _verify(args) -> int:
    import numpy as np
    import pandas as pd

    from ..io import savefig, write_csv, write_json
    from . import figures, verify

    dts = _floats(args.phase_dts, "--phase-dts")
    thetas = _floats(args.phase_thetas, "--phase-thetas")
    freqs = _floats(args.phase_frequencies, "--phase-frequencies")
    rows, table = verify.run_all(tuple(2 * np.pi * f for f in freqs), dts, thetas)
    write_json(rows, args.output)
    if args.csv:
        write_csv(pd.DataFrame(rows), args.csv)
    if args.phase_table:
        write_csv(table, args.phase_table)
    if args.figure:
        savefig(figures.plot_phase_table(table), args.figure)
    failed = [r for r in rows if not r["passed"]]
    for r in failed:
        print(
            f"FAILED {r['case']}: {r['quantity']} numerical={r['numerical']:.6g} "
            f"analytic={r['analytic']:.6g} rel={r['relative_error']:.3g}"
        )
    return 1 if (failed and args.strict) else 0


def _bench_summary(args) -> int:
    from ..io import write_csv
    from .bench import summary_table

    write_csv(summary_table(args.inputs), args.output)
    return 0
