"""Subcommands of the diagnosis step (registered by asphalt_nscd.cli).

* ``diagnose``       — what the simulation gets wrong: error budget, named causes, extended
                       law and gain (JSON report; optional law JSON, tables and figure).
* ``synth``          — synthetic measured table (2S2P1D + WLF truth, planted effects) and its
                       truth as a JSON sidecar.
* ``diagnose-bench`` — detection and false-alarm rates of the artifact detection over seeds.
"""

from __future__ import annotations

from pathlib import Path


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser("diagnose", help="error budget, named causes, extended law and gain of the simulation")
    p.add_argument("--measured", type=Path, required=True,
                   help="measured table (specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg "
                        "[, strain_microstrain, test_order])")
    p.add_argument("--simulated", type=Path, default=None,
                   help="simulation results (temperature_C, frequency_Hz, E_norm_MPa, phase_deg [, solver, dt_s]); "
                        "without it the baseline is the macro Burger's fit")
    p.add_argument("--harmonic", type=Path, default=None, help="harmonic-solver results of the sample (same columns)")
    p.add_argument("--time-integration", type=Path, default=None,
                   help="time-integration phase errors (frequency_Hz, dt_s, phase_error_deg)")
    p.add_argument("--theta", type=float, default=None,
                   help="Moreau-Jean theta of the simulation: keep only these rows of a time-integration table "
                        "with a theta column (e.g. results/nscd/phase_error.csv)")
    p.add_argument("--simulated-extended", type=Path, default=None,
                   help="simulation results rerun with the extended law (same columns as --simulated)")
    p.add_argument("--macro-params", type=Path, default=None,
                   help="Burger's parameters given to the simulation (temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, "
                        "eta_k_MPa_s); default: fitted to the measured table")
    p.add_argument("--alpha", type=float, default=1e-3, help="significance level of the tests (default 1e-3)")
    p.add_argument("--shift", choices=["wlf", "arrhenius"], default="wlf", help="shift law of the master curve")
    p.add_argument("--t-ref", type=float, default=None,
                   help="reference temperature of the master curve, degC (default: tested one nearest the median)")
    p.add_argument("--per-decade", type=float, default=2.0,
                   help="Kelvin-Voigt retardation times per decade of the extended law (default 2)")
    p.add_argument("--margin-decades", type=float, default=1.0,
                   help="decades added on both sides of the tested band for the extended law (default 1)")
    p.add_argument("--no-refine", action="store_true",
                   help="keep the extended law on the master curve (no per-isotherm refinement)")
    p.add_argument("--prior-weight", type=float, default=0.01,
                   help="penalty keeping the refined compliances near the master-curve law (default 0.01)")
    p.add_argument("-o", "--output", type=Path, required=True, help="report JSON")
    p.add_argument("--laws", type=Path, default=None,
                   help="generalized Burger's law per temperature (JSON, Pa and Pa s)")
    p.add_argument("--budget-csv", type=Path, default=None, help="error budget table (CSV)")
    p.add_argument("--effects-csv", type=Path, default=None, help="candidate causes table (CSV)")
    p.add_argument("--gain-csv", type=Path, default=None, help="MRE before/after per temperature (CSV)")
    p.add_argument("--corrected", type=Path, default=None, help="artifact-corrected measured table (CSV)")
    p.add_argument("--figure", type=Path, default=None, help="stacked error-budget figure (PNG/PDF/SVG)")
    p.add_argument("--page", type=Path, default=None,
                   help="Markdown page 'What the simulation gets wrong' (links the figure by its file name)")
    p.set_defaults(func=_diagnose)

    p = subparsers.add_parser("synth", help="synthetic measured table with planted effects (truth in a JSON sidecar)")
    p.add_argument("--seed", type=int, required=True, help="random seed")
    p.add_argument("--effects", type=str, default="",
                   help="comma-separated effects: time_lag, inertia_uncorrected, temperature_offset, "
                        "strain_nonlinearity, self_heating (default: none)")
    p.add_argument("--schedule", choices=["paper_2pb", "aashto_t342"], default=None,
                   help="test schedule (default: drawn from the seed)")
    p.add_argument("--specimens", type=int, default=None, help="number of replicates 1-4 (default: drawn, 2-4)")
    p.add_argument("-o", "--output", type=Path, required=True, help="measured-table CSV")
    p.add_argument("--truth", type=Path, default=None, help="truth JSON (default: <output stem>.truth.json)")
    p.set_defaults(func=_synth)

    p = subparsers.add_parser("diagnose-bench", help="detection and false-alarm rates over synthetic seeds")
    p.add_argument("--seeds", type=int, default=200, help="number of synthetic tables (default 200)")
    p.add_argument("--base-seed", type=int, default=0, help="base seed of the scenario draws (default 0)")
    p.add_argument("--alpha", type=float, default=1e-3, help="significance level (default 1e-3)")
    p.add_argument("--tolerance", type=float, default=0.25, help="relative tolerance of the estimates (default 0.25)")
    p.add_argument("-o", "--output", type=Path, required=True, help="benchmark JSON")
    p.set_defaults(func=_bench)


def _read_optional(path):
    from .report import read_simulated

    return None if path is None else read_simulated(path)


def _diagnose(args) -> int:
    import numpy as np
    import pandas as pd

    from ..io import InputError, write_csv, write_json, write_text
    from ..lab.measured import load_measured
    from . import extend
    from .report import budget_figure, diagnose, markdown_page

    measured = load_measured(args.measured)
    time_errors = None
    if args.time_integration is not None:
        try:
            time_errors = pd.read_csv(args.time_integration)
        except (OSError, pd.errors.ParserError) as exc:
            raise InputError(f"{args.time_integration}: not a readable CSV file ({exc})") from None
        missing = {"frequency_Hz", "dt_s", "phase_error_deg"} - set(time_errors.columns)
        if missing:
            raise InputError(f"{args.time_integration}: line 1 (header): missing column(s) {sorted(missing)}")
        if args.theta is not None and "theta" in time_errors.columns:
            time_errors = time_errors[np.isclose(time_errors["theta"].astype(float), args.theta)]
            if time_errors.empty:
                raise InputError(f"{args.time_integration}: column 'theta': no row with theta = {args.theta:g}")
    macro = None
    if args.macro_params is not None:
        try:
            macro = pd.read_csv(args.macro_params)
        except (OSError, pd.errors.ParserError) as exc:
            raise InputError(f"{args.macro_params}: not a readable CSV file ({exc})") from None
        missing = {"temperature_C", "Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s"} - set(macro.columns)
        if missing:
            raise InputError(f"{args.macro_params}: line 1 (header): missing column(s) {sorted(missing)}")
    report, extra = diagnose(
        measured, simulated=_read_optional(args.simulated), harmonic=_read_optional(args.harmonic),
        time_errors=time_errors, simulated_extended=_read_optional(args.simulated_extended),
        macro_params=macro, alpha=args.alpha, shift=args.shift, T_ref_C=args.t_ref,
        per_decade=args.per_decade, margin_decades=args.margin_decades, refine=not args.no_refine,
        prior_weight=args.prior_weight)
    report["measured"]["path"] = str(args.measured)
    write_json(report, args.output)
    if args.laws is not None:
        write_json(extend.laws_to_json(extra["laws"], extra["mre_E"], extra["mre_phase"]), args.laws)
    if args.budget_csv is not None:
        write_csv(extra["budget"], args.budget_csv)
    if args.effects_csv is not None:
        rows = [{"name": e["name"], "category": e["category"], "detected": e["detected"],
                 "testable": e["testable"], "score": e["score"], "p_value": e["p_value"],
                 "estimate": "; ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                       for k, v in e["estimate"].items()),
                 "evidence": e["evidence"]} for e in report["effects"]]
        write_csv(pd.DataFrame(rows), args.effects_csv)
    if args.gain_csv is not None:
        rows = [{"temperature_C": float(T), "E_norm_mre_before_pct": g["E_norm"]["before"],
                 "E_norm_mre_after_pct": g["E_norm"]["after"], "phase_mre_before_pct": g["phase"]["before"],
                 "phase_mre_after_pct": g["phase"]["after"], "targets_met": report["targets"]["met"][T]}
                for T, g in report["gain"].items()]
        write_csv(pd.DataFrame(rows), args.gain_csv)
    if args.corrected is not None:
        write_csv(extra["corrected"].drop(columns=["test_step"], errors="ignore"), args.corrected)
    if args.figure is not None:
        budget_figure(extra["budget"], args.figure)
    if args.page is not None:
        write_text(markdown_page(report, args.figure.name if args.figure is not None else None), args.page)
    return 0


def _synth(args) -> int:
    from ..io import InputError, write_csv, write_json
    from . import synthetic

    effects = [e.strip() for e in args.effects.split(",") if e.strip()]
    unknown = [e for e in effects if e not in synthetic.EFFECTS]
    if unknown:
        raise InputError(f"--effects: unknown effect(s) {unknown}; expected {list(synthetic.EFFECTS)}")
    if args.specimens is not None and not 1 <= args.specimens <= 4:
        raise InputError(f"--specimens: expected 1-4, got {args.specimens}")
    table, truth = synthetic.generate(args.seed, effects, schedule=args.schedule, n_specimens=args.specimens)
    truth_path = args.truth or args.output.with_name(args.output.stem + ".truth.json")
    write_csv(table, args.output)
    write_json(truth, truth_path)
    return 0


def _bench(args) -> int:
    from ..io import InputError, write_json
    from .bench import run_bench

    if args.seeds < 1:
        raise InputError(f"--seeds: expected >= 1, got {args.seeds}")
    write_json(run_bench(args.seeds, args.base_seed, args.alpha, args.tolerance), args.output)
    return 0
