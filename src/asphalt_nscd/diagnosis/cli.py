"""Subcommands of the diagnosis step (registered by asphalt_nscd.cli).

* ``extend-law``     — the extended (generalized Burger's) law per temperature from a measured
                       table alone (law JSON, Pa and Pa s): the input of the extended campaign.
* ``diagnose``       — what the simulation gets wrong: error budget, named causes, extended
                       law and gain (JSON report; optional law JSON, tables and figure).
* ``synth``          — synthetic measured table (2S2P1D truth of a family, planted effects), its
                       truth and its test geometry as JSON sidecars.
* ``diagnose-bench`` — false-alarm and detection rates of the artifact detection, with 95 %
                       intervals, per truth family (:mod:`asphalt_nscd.diagnosis.bench`).
"""

from __future__ import annotations

from pathlib import Path


def _fit_options(p) -> None:
    """Options of the artifact search, master curve and extended-law fit (diagnose, extend-law)."""
    p.add_argument("--measured", type=Path, required=True,
                   help="measured table (specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg "
                        "[, strain_microstrain, test_order])")
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
    p.add_argument("--no-balance", action="store_true",
                   help="skip the minimax step of the per-isotherm refinement (least squares only)")
    p.add_argument("--balance-tolerances-pct", type=float, nargs=2, default=[3.0, 5.0], metavar=("E", "PHI"),
                   help="MRE of |E*| and of Phi (%%) normalising the two errors of the minimax step (default 3 5)")


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser("extend-law", help="extended (generalized Burger's) law per temperature (law JSON)",
                              description="Fit the generalized Burger's law per temperature (Maxwell + N "
                              "Kelvin-Voigt units + static spring) to the 2S2P1D/WLF master curve of the "
                              "artifact-corrected measured table, without any simulation input; write it as a "
                              "law JSON (Pa, Pa s) for 'run-2pb --law-json' and 'diagnose --law-json'.")
    _fit_options(p)
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="law JSON: units, law, temperatures {T: Em, eta_m (null: no dashpot), Ek[], eta_k[], "
                        "E_inf, mre_E_norm_pct, mre_phase_pct}, Pa and Pa s")
    p.add_argument("--corrected", type=Path, default=None, help="artifact-corrected measured table (CSV)")
    p.set_defaults(func=_extend_law)

    p = subparsers.add_parser("diagnose", help="error budget, named causes, extended law and gain of the simulation")
    _fit_options(p)
    p.add_argument("--simulated", type=Path, nargs="+", default=None,
                   help="time-domain (NSCD) results with the Burger's bond law: reduced rows (temperature_C, "
                        "frequency_Hz, E_norm_MPa, phase_deg [, solver, dt_s]) or numerical isotherms "
                        "(E_norm_MPa_mean, phase_deg_mean); several files are concatenated; without it the "
                        "baseline is the macro Burger's fit")
    p.add_argument("--harmonic", type=Path, nargs="+", default=None,
                   help="harmonic-solver results of the simulated sample(s) (same columns; concatenated)")
    p.add_argument("--time-integration", type=Path, nargs="+", default=None,
                   help="time-integration phase errors (frequency_Hz, dt_s, phase_error_deg [, theta]; "
                        "e.g. results/campaign/measured/dt_policy_phase_error.csv; concatenated)")
    p.add_argument("--theta", type=float, default=None,
                   help="Moreau-Jean theta of the simulation: keep only these rows of a time-integration table "
                        "with a theta column (e.g. results/nscd/phase_error.csv)")
    p.add_argument("--simulated-extended", type=Path, nargs="+", default=None,
                   help="NSCD results rerun with the extended law (same columns as --simulated)")
    p.add_argument("--transfer", type=Path, nargs="+", default=None,
                   help="network factor JSON(s) of the extended simulation's samples (output of "
                        "'harmonic-transfer', e.g. results/harmonic/transfer/s1.json): the gain table adds "
                        "the extended law without the transfer correction (NF_s x E*, inertia-free harmonic "
                        "response), separating the gain of the law from that of the correction")
    p.add_argument("--law-json", type=Path, default=None,
                   help="the extended law the extended simulation ran with (output of 'extend-law'); "
                        "default: fitted here with --per-decade ... --prior-weight")
    p.add_argument("--macro-params", type=Path, default=None,
                   help="Burger's parameters given to the simulation (temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, "
                        "eta_k_MPa_s); default: fitted to the measured table")
    p.add_argument("--test", type=Path, default=None,
                   help="test-geometry JSON of the measured table (default: the sidecar <measured stem>.test.json "
                        "next to it, else an unknown test: inertia not testable)")
    p.add_argument("--tolerance-network-factor", type=float, default=0.01,
                   help="tolerance of the network factor's departure from 1 (relative, default 0.01)")
    p.add_argument("--tolerance-phase-deg", type=float, default=0.1,
                   help="tolerance of the time-integration phase error, deg (default 0.1)")
    p.add_argument("-o", "--output", type=Path, required=True, help="report JSON")
    p.add_argument("--laws", type=Path, default=None,
                   help="generalized Burger's law per temperature (JSON, Pa and Pa s)")
    p.add_argument("--budget-csv", type=Path, default=None, help="error budget table (CSV)")
    p.add_argument("--effects-csv", type=Path, default=None, help="candidate causes table (CSV)")
    p.add_argument("--gain-csv", type=Path, default=None,
                   help="MRE before/after per temperature and source (nscd: NSCD simulations; macro: macro "
                        "laws) (CSV)")
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
    p.add_argument("--schedule", choices=["paper_2pb", "aashto_t342", "ampt_pp61"], default=None,
                   help="test schedule (default: drawn from the seed)")
    p.add_argument("--family", choices=["wlf", "glassy_drift", "arrhenius", "static_drift", "poly_shift", "mixed"],
                   default="wlf", help="truth family (default wlf: 2S2P1D + WLF, the detector's own model)")
    p.add_argument("--specimens", type=int, default=None, help="number of replicates 1-5 (default: drawn, 2-4)")
    p.add_argument("-o", "--output", type=Path, required=True, help="measured-table CSV")
    p.add_argument("--truth", type=Path, default=None, help="truth JSON (default: <output stem>.truth.json)")
    p.add_argument("--no-test-sidecar", action="store_true",
                   help="do not write the test-geometry sidecar <output stem>.test.json")
    p.set_defaults(func=_synth)

    p = subparsers.add_parser("diagnose-bench",
                              help="false-alarm and detection rates of the artifact detection (with 95 % intervals)",
                              description="Draw clean and planted synthetic tables from truth families inside "
                              "and outside the detector's model, diagnose their artifacts and report per artifact "
                              "and family the false-alarm rate (clean tables) and the detection rate at the stated "
                              "effect sizes, with exact binomial 95 % confidence intervals.")
    p.add_argument("--clean", type=int, default=200, help="clean tables per family (default 200)")
    p.add_argument("--planted", type=int, default=40,
                   help="planted tables per family and artifact (default 40)")
    p.add_argument("--families", type=str, default=None,
                   help="comma-separated truth families (default: all: wlf, glassy_drift, arrhenius, "
                        "static_drift, poly_shift, mixed)")
    p.add_argument("--base-seed", type=int, default=None,
                   help="base seed of every table's seed (default: a fresh one, recorded in the JSON)")
    p.add_argument("--alpha", type=float, default=1e-3, help="significance level (default 1e-3)")
    p.add_argument("--effect-scale", type=float, default=1.0,
                   help="factor on every stated effect size (default 1; e.g. 0.5 for the power curve)")
    p.add_argument("--tolerance", type=float, default=0.25, help="relative tolerance of the estimates (default 0.25)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("-o", "--output", type=Path, required=True, help="benchmark JSON (summary and every table's outcome)")
    p.add_argument("--table", type=Path, default=None,
                   help="bench table CSV: per artifact and family, detection and false-alarm counts, rates, 95 %% CIs")
    p.set_defaults(func=_bench)


def _read_optional(paths):
    from .report import read_simulated_many

    return None if not paths else read_simulated_many(paths)


def _read_time_errors(paths, theta):
    """Time-integration phase-error tables (concatenated), rows of ``theta`` only when the
    table has a theta column. Raises InputError naming the file and column."""
    import numpy as np
    import pandas as pd

    from ..io import InputError

    frames = []
    for path in paths:
        try:
            t = pd.read_csv(path)
        except (OSError, pd.errors.ParserError, UnicodeDecodeError) as exc:
            raise InputError(f"{path}: not a readable CSV file ({exc})") from None
        missing = {"frequency_Hz", "dt_s", "phase_error_deg"} - set(t.columns)
        if missing:
            raise InputError(f"{path}: line 1 (header): missing column(s) {sorted(missing)}")
        for c in ("frequency_Hz", "dt_s", "phase_error_deg"):
            v = pd.to_numeric(t[c], errors="coerce").to_numpy(float)
            bad = np.flatnonzero(~np.isfinite(v))
            if bad.size:
                raise InputError(f"{path}: line {bad[0] + 2}, column '{c}': expected a finite number")
            t[c] = v
        if theta is not None and "theta" in t.columns:
            t = t[np.isclose(t["theta"].astype(float), theta)]
            if t.empty:
                raise InputError(f"{path}: column 'theta': no row with theta = {theta:g}")
        frames.append(t)
    return pd.concat(frames, ignore_index=True)


def _fit_kwargs(args) -> dict:
    return dict(alpha=args.alpha, shift=args.shift, T_ref_C=args.t_ref, per_decade=args.per_decade,
                margin_decades=args.margin_decades, refine=not args.no_refine, prior_weight=args.prior_weight,
                balance=not args.no_balance, tolerances=_tolerances(args))


def _tolerances(args) -> tuple[float, float]:
    from ..io import InputError

    tol = tuple(float(v) / 100.0 for v in args.balance_tolerances_pct)
    if not all(t > 0 for t in tol):
        raise InputError(f"--balance-tolerances-pct: expected two positive percentages, got {args.balance_tolerances_pct}")
    return tol


def _extend_law(args) -> int:
    from ..io import write_csv, write_json
    from ..lab.measured import load_measured
    from . import extend
    from .report import extended_laws

    measured = load_measured(args.measured)
    out = extended_laws(measured, **_fit_kwargs(args))
    obj = extend.laws_to_json(out["laws"], out["mre_E"], out["mre_phase"])
    for T, d in obj["temperatures"].items():
        d["mre_E_norm_pct_vs_measured"] = out["mre_E_measured"].get(float(T))
        d["mre_phase_pct_vs_measured"] = out["mre_phase_measured"].get(float(T))
    a = out["analysis"]
    obj["source"] = {"measured": str(args.measured), "master_curve": "2S2P1D", "shift": args.shift,
                     "T_ref_C": float(a["master"].T_ref_C),
                     "artifacts_corrected": [c.name for c in a["result"]["selected"]],
                     "per_decade": args.per_decade, "margin_decades": args.margin_decades,
                     "refine": not args.no_refine, "prior_weight": args.prior_weight,
                     "balance": not args.no_balance, "balance_tolerances_pct": list(args.balance_tolerances_pct),
                     "mre_reference": "artifact-corrected measured replicate means"}
    write_json(obj, args.output)
    if args.corrected is not None:
        write_csv(a["corrected"].drop(columns=["test_step"], errors="ignore"), args.corrected)
    return 0


def _diagnose(args) -> int:
    import pandas as pd

    from ..campaign.study import read_law_json
    from ..io import InputError, write_csv, write_json, write_text
    from ..lab.measured import load_measured
    from . import extend
    from .report import budget_figure, diagnose, markdown_page

    measured = load_measured(args.measured, test=args.test)
    if not (args.tolerance_network_factor > 0 and args.tolerance_phase_deg > 0):
        raise InputError("--tolerance-network-factor and --tolerance-phase-deg: expected positive numbers, got "
                         f"{args.tolerance_network_factor}, {args.tolerance_phase_deg}")
    time_errors = None if not args.time_integration else _read_time_errors(args.time_integration, args.theta)
    laws = None
    if args.law_json is not None:
        laws = {T: law.scaled(1e-6) for T, law in read_law_json(args.law_json).items()}
        missing = [float(T) for T in sorted(measured["temperature_C"].unique())
                   if not any(abs(T - k) < 1e-9 for k in laws)]
        if missing:
            raise InputError(f"{args.law_json}: key 'temperatures': no law at {missing} degC (measured "
                             f"temperatures); given: {sorted(laws)}")
    macro = None
    if args.macro_params is not None:
        try:
            macro = pd.read_csv(args.macro_params)
        except (OSError, pd.errors.ParserError) as exc:
            raise InputError(f"{args.macro_params}: not a readable CSV file ({exc})") from None
        missing = {"temperature_C", "Em_MPa", "eta_m_MPa_s", "Ek_MPa", "eta_k_MPa_s"} - set(macro.columns)
        if missing:
            raise InputError(f"{args.macro_params}: line 1 (header): missing column(s) {sorted(missing)}")
    transfer = None
    if args.transfer:
        from ..harmonic.transfer import read_transfer_json

        transfer = {}
        for path in args.transfer:
            obj = read_transfer_json(path)
            if obj["sample"] in transfer:
                raise InputError(f"{path}: key 'sample': sample {obj['sample']!r} given twice in --transfer")
            transfer[obj["sample"]] = obj["network_factor"]
    report, extra = diagnose(
        measured, simulated=_read_optional(args.simulated), harmonic=_read_optional(args.harmonic),
        time_errors=time_errors, simulated_extended=_read_optional(args.simulated_extended),
        macro_params=macro, laws=laws, transfer=transfer,
        cause_tolerances={"network_factor": args.tolerance_network_factor,
                          "time_integration_deg": args.tolerance_phase_deg}, **_fit_kwargs(args))
    report["measured"]["test"] = measured.attrs["test"].to_json()
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
        write_csv(extra["gain_rows"], args.gain_csv)
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
    if args.specimens is not None and not 1 <= args.specimens <= 5:
        raise InputError(f"--specimens: expected 1-5, got {args.specimens}")
    table, truth = synthetic.generate(args.seed, effects, schedule=args.schedule, n_specimens=args.specimens,
                                      family=args.family)
    truth_path = args.truth or args.output.with_name(args.output.stem + ".truth.json")
    write_csv(table, args.output)
    write_json(truth, truth_path)
    if not args.no_test_sidecar:
        from ..lab.geometry import sidecar_path

        write_json(truth["test"], sidecar_path(args.output))
    return 0


def _bench(args) -> int:
    from ..io import InputError, write_csv, write_json
    from . import synthetic
    from .bench import bench_table, run_bench

    if args.clean < 0 or args.planted < 0 or args.clean + args.planted == 0:
        raise InputError(f"--clean, --planted: expected >= 0 and not both 0, got {args.clean}, {args.planted}")
    if args.jobs < 1:
        raise InputError(f"--jobs: expected >= 1, got {args.jobs}")
    if not 0 < args.alpha < 1 or not args.effect_scale > 0:
        raise InputError(f"--alpha in (0, 1) and --effect-scale > 0 expected, got {args.alpha}, {args.effect_scale}")
    families = list(synthetic.FAMILIES) if args.families is None else [f.strip() for f in args.families.split(",") if f.strip()]
    unknown = [f for f in families if f not in synthetic.FAMILIES]
    if unknown or not families:
        raise InputError(f"--families: unknown {unknown}; expected some of {list(synthetic.FAMILIES)}")
    result = run_bench(args.clean, args.planted, args.base_seed, families, args.alpha, args.effect_scale,
                       args.tolerance, args.jobs)
    write_json(result, args.output)
    if args.table is not None:
        write_csv(bench_table(result), args.table, float_format="%.4g")
    return 0
