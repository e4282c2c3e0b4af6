"""Subcommands of the nscd step (registered by asphalt_nscd.cli).

``asphalt-nscd verify -o verify.json [--csv verify.csv] [--phase-table phase.csv]
[--figure verify.png]`` runs the verification cases of :mod:`.verify`.

``asphalt-nscd bench-summary a.json b.json -o bench.csv`` tabulates bench records.

``asphalt-nscd bench --case bonded|granular --n N [--steps S] [--baseline-steps B]
[--tolerance TOL] [--settle-steps K] [--seed SEED] [--linear-tolerance TOL]
[--bond-kinematics contact|barycentre] [--settle-speed V] [--threads T]
[--linear-solver cg|cg_ssor] [--bonded-contact after_break|open_at_bonding|always]
[--start rest|periodic] [--ssor-omega W] -o bench.json`` runs one benchmark.
"""

from .state import BOND_KINEMATICS, BONDED_CONTACT


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser("verify", help="NSCD core verification against closed forms")
    p.add_argument("-o", "--output", required=True, help="JSON list of verification rows")
    p.add_argument("--csv", help="the same rows as CSV")
    p.add_argument("--phase-table", help="CSV of the phase error vs omega dt and theta")
    p.add_argument("--figure", help="figure (PNG/PDF) of the phase error table")
    p.add_argument("--phase-dts", default="1e-5,2e-5,5e-5,1e-4,2e-4",
                   help="time steps (s) of the phase error table, comma-separated")
    p.add_argument("--phase-thetas", default="0.5,0.55,1.0",
                   help="theta values of the phase error table, comma-separated")
    p.add_argument("--phase-frequencies", default="3,40",
                   help="frequencies (Hz) of the phase error table, comma-separated")
    p.add_argument("--strict", action="store_true", help="exit 1 if a case fails")
    p.set_defaults(func=_verify)

    b = subparsers.add_parser("bench", help="NSCD core benchmark (JSON)")
    b.add_argument("--case", required=True, choices=["bonded", "granular"])
    b.add_argument("--n", type=int, required=True, help="number of spheres")
    b.add_argument("--steps", type=int, default=20, help="timed steps")
    b.add_argument("--baseline-steps", type=int, default=5,
                   help="timed NLGS steps of the bonded baseline")
    b.add_argument("--tolerance", type=float, default=1e-7, help="NLGS tolerance")
    b.add_argument("--settle-steps", type=int, default=5000,
                   help="most untimed settling steps of the granular case")
    b.add_argument("--settle-speed", type=float, default=5e-3,
                   help="granular settling ends when the largest sphere speed (m/s) is below")
    b.add_argument("--threads", type=int, default=1,
                   help="numba threads of the parallel kernels (NSCDParameters.threads)")
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--linear-tolerance", type=float, default=1e-7,
                   help="relative residual of the conjugate gradient (bonded case)")
    b.add_argument("--bond-kinematics", choices=list(BOND_KINEMATICS), default="contact",
                   help="where the bonds act (bonded case; NSCDParameters.bond_kinematics)")
    b.add_argument("--linear-solver", choices=["cg", "cg_ssor"], default="cg",
                   help="conjugate gradient of the bonded case: block-Jacobi (cg) or SSOR "
                        "(cg_ssor, also times cg on the same steps)")
    b.add_argument("--bonded-contact", choices=list(BONDED_CONTACT), default="after_break",
                   help="contact of the bonded pairs (bonded case; NSCDParameters.bonded_contact)")
    b.add_argument("--start", choices=["rest", "periodic"], default="rest",
                   help="bonded case: from rest under gravity, or in the periodic steady "
                        "state without gravity (the 2PB setting)")
    b.add_argument("--ssor-omega", type=float, default=None,
                   help="relaxation factor of cg_ssor in (0, 2) (default: NSCDParameters')")
    b.add_argument("-o", "--output", required=True, help="JSON record")
    b.set_defaults(func=_bench)

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
    from . import verify

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
        savefig(verify.plot_phase_table(table), args.figure)
    failed = [r for r in rows if not r["passed"]]
    for r in failed:
        print(f"FAILED {r['case']}: {r['quantity']} numerical={r['numerical']:.6g} "
              f"analytic={r['analytic']:.6g} rel={r['relative_error']:.3g}")
    return 1 if (failed and args.strict) else 0


def _bench(args) -> int:
    from ..io import write_json
    from .bench import run_bench

    rec = run_bench(args.case, args.n, steps=args.steps, baseline_steps=args.baseline_steps,
                    tolerance=args.tolerance, settle_steps=args.settle_steps, seed=args.seed,
                    linear_tolerance=args.linear_tolerance,
                    bond_kinematics=args.bond_kinematics, threads=args.threads,
                    settle_speed=args.settle_speed, linear_solver=args.linear_solver,
                    bonded_contact=args.bonded_contact, start=args.start,
                    ssor_omega=args.ssor_omega)
    write_json(rec, args.output)
    return 0


def _bench_summary(args) -> int:
    from ..io import write_csv
    from .bench import summary_table

    write_csv(summary_table(args.inputs), args.output)
    return 0
