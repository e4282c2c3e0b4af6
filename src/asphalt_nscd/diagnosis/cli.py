"""Subcommands of the diagnosis step (registered by asphalt_nscd.cli). They parse arguments and
call the library; reading, validation and physics live in the modules they call.

* ``calibrate-search`` — the level of the artifact search calibrated on the table itself
                       (parametric bootstrap of its fitted clean model, JSON)
                       (:mod:`asphalt_nscd.diagnosis.calibration`).
* ``master-curve``   — artifact search and master curve of a measured table, written once
                       (JSON) with the artifact-corrected table (CSV)
                       (:mod:`asphalt_nscd.diagnosis.artifacts`).
* ``extend-law``     — the temperature-aware extended (generalized Burger's) law from a measured
                       table alone, settings chosen by cross-validation, written at any
                       temperatures (law file, Pa and Pa s, :mod:`asphalt_nscd.rheology.law_file`):
                       the input of the extended campaign.
* ``crossval``       — held-out (lofo / loto) and in-sample predictions of the paper's Burger's
                       law, the extended law and the NSCD sample (nested: every fold refits the
                       whole extend-law procedure).
* ``diagnose``       — what the simulation gets wrong: error budget, named causes and gain of
                       the extended law (JSON report; optional tables, figure and page), from
                       the outputs of ``master-curve`` and ``extend-law``.
* ``synth``          — synthetic measured table (2S2P1D truth of a family, planted effects), its
                       truth and its test geometry as JSON sidecars.
* ``diagnose-bench`` — false-alarm and detection rates of the artifact detection, with 95 %
                       intervals, per truth family (:mod:`asphalt_nscd.diagnosis.bench`).
"""

from __future__ import annotations

from pathlib import Path


def _measured_option(p) -> None:
    p.add_argument(
        "--measured",
        type=Path,
        required=True,
        help="measured table (specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg "
        "[, strain_microstrain, test_order])",
    )


def _config_option(p, *groups: str) -> None:
    """``--config``: the option values of ``groups`` from a workflow config
    (:func:`asphalt_nscd.diagnosis.settings.option_values`; applied by asphalt_nscd.cli.main)."""
    from ..config import config_option

    config_option(p, lambda cfg, args: _option_values(cfg, *groups), "its diagnosis section")


def _option_values(cfg, *groups):
    from .settings import option_values

    return option_values(cfg, *groups)


def _search_options(p) -> None:
    """Options of the artifact search (master-curve, extend-law, crossval)."""
    _measured_option(p)
    p.add_argument("--alpha", type=float, default=1e-3, help="significance level of the tests (default 1e-3)")
    p.add_argument(
        "--shift",
        choices=["wlf", "arrhenius"],
        default="wlf",
        help="shift law of the master curve of the artifact search",
    )
    p.add_argument(
        "--t-ref", type=float, default=None, help="reference temperature, degC (default: tested one nearest the median)"
    )
    p.add_argument(
        "--identifiability-null",
        type=float,
        default=0.995,
        help="a candidate whose signature has at least this cosine with the screening model's span is "
        "not identifiable (default 0.995)",
    )
    p.add_argument(
        "--identifiability-rival",
        type=float,
        default=0.95,
        help="a candidate whose signature has at least this canonical correlation with its rival's "
        "(beyond the screening model) is not identifiable (default 0.95)",
    )
    p.add_argument(
        "--calibration",
        type=Path,
        default=None,
        help="the table's calibration (output of 'calibrate-search' with the same search options): "
        "the first step's level (default: the nominal alpha / m)",
    )


def search_limits(args) -> dict:
    """Identifiability limits of the search options. Raises InputError outside (0, 1]."""
    from ..io import InputError

    limits = {"null": float(args.identifiability_null), "rival": float(args.identifiability_rival)}
    for k, v in limits.items():
        if not 0.0 < v <= 1.0:
            raise InputError(f"--identifiability-{k}: expected a number in (0, 1], got {v}")
    return limits


def read_calibration(args) -> dict | None:
    """The calibration JSON of ``--calibration`` (None without it), checked against the search
    options. Raises InputError naming the file and the key."""
    from ..io import InputError, read_json

    if args.calibration is None:
        return None
    cal = read_json(args.calibration, "calibration JSON")
    try:
        level = float(cal["artifacts"]["level"])
        cal["static"]["null_F"], cal["artifacts"]["null_min_p"]
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            f"{args.calibration}: key {exc.args[0]!r}: missing or malformed; expected the output of "
            "'asphalt-nscd calibrate-search'"
        ) from None
    theirs = {"alpha": cal.get("alpha"), "shift": cal.get("shift"), "limits": cal.get("limits")}
    mine = {"alpha": float(args.alpha), "shift": args.shift, "limits": search_limits(args)}
    if theirs != mine:
        raise InputError(
            f"{args.calibration}: computed with {theirs}, this command's search uses {mine}; rerun "
            "'asphalt-nscd calibrate-search' with the same options"
        )
    if not 0.0 < level <= 1.0:
        raise InputError(f"{args.calibration}: key 'artifacts.level': expected a level in (0, 1], got {level}")
    return cal


def _fit_options(p) -> None:
    """Options of the artifact search and of the extended law (extend-law, crossval)."""
    _search_options(p)
    _config_option(p, "search", "law")
    g = p.add_argument_group(
        "extended law: candidate settings, chosen by cross-validation (asphalt_nscd.diagnosis.crossval)"
    )
    g.add_argument(
        "--law-shifts",
        nargs="+",
        choices=["wlf", "arrhenius"],
        default=list(LAW_DEFAULTS["shifts"]),
        help="shift laws tried (default: wlf arrhenius)",
    )
    g.add_argument(
        "--law-statics",
        nargs="+",
        choices=["none", "constant", "trend"],
        default=list(LAW_DEFAULTS["statics"]),
        help="static modulus forms tried: none (a liquid), constant, trend (log-linear in T) (default: all three)",
    )
    g.add_argument(
        "--law-verticals",
        nargs="+",
        choices=["off", "on"],
        default=list(LAW_DEFAULTS["verticals"]),
        help="vertical shift (log-linear in T) tried (default: off on)",
    )
    g.add_argument(
        "--law-refines",
        nargs="+",
        default=list(LAW_DEFAULTS["refines"]),
        help="per-isotherm refinement weights kappa tried, 'off' for none (default: off 1)",
    )
    g.add_argument(
        "--law-per-decades",
        nargs="+",
        type=float,
        default=list(LAW_DEFAULTS["per_decades"]),
        help="Prony retardation times per decade tried (default: 2 4)",
    )
    g.add_argument(
        "--margin-decades",
        type=float,
        default=2.0,
        help="decades beyond the tested band: Prony fit band and merging of far units (default 2)",
    )
    g.add_argument(
        "--tolerances-pct",
        type=float,
        nargs=2,
        default=[3.0, 5.0],
        metavar=("E", "PHI"),
        help="MRE of |E*| and of Phi (%%) normalising the fit residuals and the selection score (default 3 5)",
    )
    g.add_argument(
        "--no-one-se",
        action="store_true",
        help="choose the best cross-validation score, not the simplest within one standard error",
    )
    g.add_argument(
        "--no-artifacts",
        action="store_true",
        help="fit the law to the table as given (no artifact search and correction)",
    )
    g.add_argument(
        "--card-fit",
        choices=["least_squares", "robust"],
        default=LAW_DEFAULTS["card_fit"],
        help="loss of the law a material card carries: least_squares (every cell weighs by its square: "
        "a card is judged at every measured cell) or robust (the selected law's soft L1) "
        "(default: least_squares)",
    )
    g.add_argument(
        "--card-shift",
        choices=["wlf", "law"],
        default=LAW_DEFAULTS["card_shift"],
        help="shift law of the law a material card carries: wlf (the card's own, which Abaqus and "
        "LS-DYNA take natively) or law (the selected law's) (default: wlf)",
    )


#: default candidate settings of the extended law: config/config.yaml's diagnosis.law in the
#: options' spelling (verticals off/on = false/true, refines off = null); tests/unit/test_config.py
#: checks them equal, with the other option defaults that config/config.yaml also sets
LAW_DEFAULTS = {
    "shifts": ("wlf", "arrhenius"),
    "statics": ("none", "constant", "trend"),
    "verticals": ("off", "on"),
    "refines": ("off", "1"),
    "per_decades": (2.0, 4.0),
    "card_fit": "least_squares",
    "card_shift": "wlf",
}


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    _add_calibrate_search(subparsers)
    _add_master_curve(subparsers)
    _add_extend_law(subparsers)
    _add_crossval(subparsers)
    _add_diagnose(subparsers)
    _add_synth(subparsers)
    _add_diagnose_bench(subparsers)
    _add_own_table(subparsers)


def _add_own_table(subparsers) -> None:
    """``own-table-config`` and ``publish-table``: the two ends of ``make table`` (README, "Your
    own table"): the configuration overlay naming the table, and the folder of its complete run."""
    p = subparsers.add_parser(
        "own-table-config", help="configuration overlay of make table: the measured table (and its sidecar)"
    )
    p.add_argument("table", type=Path, help="the lab's measured table (any path: spaces, non-ASCII, quotes)")
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="its test-geometry sidecar (default: <table stem>.test.json beside it, if any)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="overlay YAML for snakemake --configfile")
    p.set_defaults(func=_own_table_config)
    p = subparsers.add_parser(
        "publish-table", help="copy a complete own-table run to results/tables/<name>/ with its manifest"
    )
    p.add_argument("files", type=Path, nargs="+", help="the run's results (paths under results/)")
    p.add_argument("--table", type=Path, required=True, help="the lab's table the run read (measured.table)")
    p.add_argument(
        "--measured",
        type=Path,
        required=True,
        help="the validated table of the lab step (results/lab/measured.csv): every result must carry its SHA-256",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="the folder of this table's complete run")
    p.set_defaults(func=_publish_table)


def _own_table_config(args) -> int:
    import yaml

    from ..io import InputError, write_text

    for what, path in (("TABLE", args.table), ("TEST", args.test)):
        if path is not None and not path.is_file():
            raise InputError(
                f"{what}={path}: file not found (expected the lab's "
                f"{'table' if what == 'TABLE' else 'test-geometry sidecar'})"
            )
    measured = {"table": str(args.table), **({"test": str(args.test)} if args.test is not None else {})}
    write_text(
        "# written by make table (asphalt-nscd own-table-config): the table of this run\n"
        + yaml.safe_dump({"measured": measured}, allow_unicode=True, sort_keys=False),
        args.output,
    )
    return 0


def _publish_table(args) -> int:
    from ..io import content_sha256, publish_directory, read_json

    results = [(f, read_json(f, "result JSON")) for f in args.files if f.suffix == ".json"]
    stamp = same_table(args.measured, results)
    root = args.measured.resolve().parents[1]  # results/ (the lab step writes results/lab/measured.csv)
    manifest = {
        "table": str(args.table),
        "table_sha256": content_sha256(args.table),
        "measured": str(args.measured),
        "measured_sha256": stamp,
        "written_utc": _utc_now(),
        "about": "the last complete run of make table on this table; a run that fails or is stopped "
        "leaves this folder as it was",
    }
    out = publish_directory(args.files, root, args.output, manifest)
    print(f"the complete results of {args.table}: {out}/ ({len(set(args.files))} files, manifest.json)")
    return 0


def _utc_now() -> str:
    from datetime import datetime, timezone

    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def _add_calibrate_search(subparsers) -> None:
    """``calibrate-search``: the artifact search's level calibrated on the table itself (JSON)."""
    p = subparsers.add_parser(
        "calibrate-search",
        help="the artifact search's level calibrated on the table itself (parametric bootstrap, JSON)",
        description="Simulate tables from the measured table's own fitted clean model (its "
        "screening fit with smooth shifts, its specimen factors, point scatter and cell "
        "misfit, its design), run the whole artifact procedure and the static-modulus test on "
        "each, and write the levels that hold the procedure's family-wise false-alarm rate "
        "(asphalt_nscd.diagnosis.calibration).",
    )
    _search_options(p)
    _config_option(p, "search", "calibration")
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="test-geometry JSON of the measured table (default: the sidecar <measured stem>.test.json next to it)",
    )
    p.add_argument(
        "--tables",
        type=int,
        default=200,
        help="bootstrap tables (default 200; at least 2 / rate - 1, 39 at the default rate)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=20261123,
        help="seed of the bootstrap tables (default 20261123, config diagnosis.calibration.seed)",
    )
    p.add_argument(
        "--familywise-rate",
        type=float,
        default=0.05,
        help="family-wise false-alarm rate of the whole procedure (default 0.05)",
    )
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="calibration JSON: the clean model, the levels, the statistic on every table, the out-of-sample rate",
    )
    p.set_defaults(func=_calibrate_search)


def _add_master_curve(subparsers) -> None:
    """``master-curve``: artifact search and master curve of a measured table (JSON) and the
    artifact-corrected table (CSV)."""
    p = subparsers.add_parser(
        "master-curve",
        help="artifact search and master curve of a measured table (JSON) and the artifact-corrected table (CSV)",
        description="Search the measured table for data artifacts (nested master-curve "
        "fits, asphalt_nscd.diagnosis.effects), correct them and fit the 2S2P1D master "
        "curve of the corrected table; write the result for 'extend-law --master-curve' and "
        "'diagnose --master-curve'.",
    )
    _search_options(p)
    _config_option(p, "search")
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="test-geometry JSON of the measured table (default: the sidecar <measured stem>.test.json "
        "next to it, else an unknown test: inertia not testable)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="master-curve JSON: settings, noise, artifact screening and entries, corrected "
        "artifacts, master curve (MPa)",
    )
    p.add_argument("--corrected", type=Path, required=True, help="artifact-corrected measured table (CSV)")
    p.set_defaults(func=_master_curve)


def _add_extend_law(subparsers) -> None:
    """``extend-law``: temperature-aware extended (generalized Burger's) law (law JSON)."""
    p = subparsers.add_parser(
        "extend-law",
        help="temperature-aware extended (generalized Burger's) law (law JSON)",
        description="Fit the temperature-aware generalized Burger's law (one 2S2P1D "
        "backbone and Prony chain at a reference temperature, a shift law, optional "
        "static-modulus trend, vertical shift and per-isotherm refinement; settings chosen "
        "by cross-validation) to the artifact-corrected measured table, without any "
        "simulation input, and write it at the requested temperatures as a law JSON (Pa, "
        "Pa s) for 'run-2pb --law-json' and 'diagnose --law-json'.",
    )
    _fit_options(p)
    p.add_argument(
        "--temperatures",
        type=float,
        nargs="+",
        default=None,
        help="temperatures of the law JSON entries, degC (default: the measured ones); outside the "
        "calibrated range the entry is marked as an extrapolation",
    )
    p.add_argument(
        "--exclude-frequency",
        type=float,
        nargs="+",
        default=[],
        help="fit without every row at these frequencies, Hz (the law of a lofo fold)",
    )
    p.add_argument(
        "--exclude-temperature",
        type=float,
        nargs="+",
        default=[],
        help="fit without every row at these temperatures, degC (the law of a loto fold)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="law JSON: units, law, temperatures {T: Em, eta_m (null: no dashpot), Ek[], eta_k[], "
        "E_inf, in-sample MREs, extrapolation}, model, selection, source (Pa and Pa s)",
    )
    p.add_argument(
        "--master-curve",
        type=Path,
        default=None,
        help="the artifact search of 'master-curve' on the same --measured table (with "
        "--corrected-table): used instead of searching again",
    )
    p.add_argument(
        "--corrected-table",
        type=Path,
        default=None,
        help="the artifact-corrected table of 'master-curve' (with --master-curve)",
    )
    p.add_argument(
        "--corrected",
        type=Path,
        default=None,
        help="output: the table the law was fitted on (artifact-corrected unless --no-artifacts) (CSV)",
    )
    p.add_argument(
        "--cv-curve",
        type=Path,
        default=None,
        help="cross-validation curve of the selection: one row per candidate setting (CSV)",
    )
    p.add_argument(
        "--without-flagged",
        type=Path,
        default=None,
        help="output: the law fitted without the rows beyond a data-quality limit (law JSON), or a JSON "
        "saying that no row is flagged (asphalt_nscd.lab.checks)",
    )
    p.add_argument(
        "--card-law",
        type=Path,
        default=None,
        help="output: the law a material card carries (law JSON): the selected settings without what a "
        "Prony series with a shift function cannot carry, with --card-shift, fitted with --card-fit "
        "(the selected law itself when it is that law)",
    )
    p.set_defaults(func=_extend_law)


def _add_crossval(subparsers) -> None:
    """``crossval``: held-out (lofo/loto) predictions of Burger's, the extended law and the NSCD
    sample."""
    p = subparsers.add_parser(
        "crossval",
        help="held-out (lofo/loto) predictions of Burger's, the extended law and the NSCD sample",
        description="Leave-one-frequency-out or leave-one-temperature-out validation "
        "(asphalt_nscd.diagnosis.crossval): every fold refits the whole procedure of "
        "'extend-law' (artifact correction, nested selection of the settings, law) without "
        "its held-out rows and predicts them; in-sample rows beside.",
    )
    _fit_options(p)
    p.add_argument(
        "--scheme",
        choices=["lofo", "loto", "loso"],
        required=True,
        help="lofo: leave one frequency out; loto: leave one temperature out; loso: leave one specimen "
        "out (scored against the held-out specimen)",
    )
    p.add_argument(
        "--sample",
        type=Path,
        default=None,
        help="numerical sample (results/samples/<s>.h5): adds the nscd_sample model (harmonic "
        "solver, bonds = fold's law / NF_s); needs --transfer",
    )
    p.add_argument(
        "--transfer",
        type=Path,
        default=None,
        help="the sample's network factor JSON (asphalt-nscd harmonic-transfer): NF_s, kinematics, nu",
    )
    p.add_argument(
        "--inertia",
        choices=["full", "none"],
        default="full",
        help="inertia of the harmonic solution of the sample (default full, as the 2PB test)",
    )
    p.add_argument(
        "--time-domain",
        type=Path,
        nargs="+",
        default=None,
        help="reduced rows of the time-domain NSCD test of the sample with one fold's law "
        "(run-2pb --law-json <extend-law --exclude-...>): added as model nscd_time_domain",
    )
    p.add_argument(
        "--no-burgers",
        action="store_true",
        help="skip the paper's Burger's law per isotherm (its fits are the slow part on tables far "
        "from any viscoelastic law)",
    )
    p.add_argument(
        "--burgers-starts",
        type=int,
        default=8,
        help="local least-squares runs of each Burger's fit per isotherm (default 8)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV, one row per (fold, model, cell): scheme, fold, kind (held_out | in_sample), "
        "model, temperature_C, frequency_Hz, measured and predicted E_norm_MPa and phase_deg, "
        "relative errors, extrapolation, settings, computable, reason",
    )
    p.add_argument(
        "--summary",
        type=Path,
        default=None,
        help="CSV: scores per scheme, kind, model, temperature and extrapolation, and pooled: signed "
        "and absolute mean log error of |E*| (%%) and Phi error (deg) with 95 %% intervals over "
        "the specimens, the paper's MRE (asphalt_nscd.diagnosis.scores)",
    )
    p.add_argument(
        "--curve",
        type=Path,
        default=None,
        help="CSV: the selection curve of the whole table (fold 'all') and of every fold",
    )
    p.add_argument(
        "--figure",
        type=Path,
        default=None,
        help="figure: measured, in-sample and held-out isotherms of the extended law",
    )
    p.set_defaults(func=_crossval)


def _add_diagnose(subparsers) -> None:
    """``diagnose``: error budget, named causes, extended law and gain of the simulation."""
    p = subparsers.add_parser(
        "diagnose",
        help="error budget, named causes, extended law and gain of the simulation",
        description="Read the measured table, the artifact search and master curve "
        "('master-curve'), the extended law ('extend-law') and the simulation results, "
        "and write what the simulation gets wrong; nothing upstream is refitted.",
    )
    _measured_option(p)
    p.add_argument(
        "--master-curve",
        type=Path,
        required=True,
        help="artifact search and master curve of the measured table (output of 'master-curve')",
    )
    p.add_argument(
        "--corrected-table",
        type=Path,
        required=True,
        help="artifact-corrected measured table (output of 'master-curve')",
    )
    p.add_argument(
        "--simulated",
        type=Path,
        nargs="+",
        default=None,
        help="time-domain (NSCD) results with the Burger's bond law: reduced rows (temperature_C, "
        "frequency_Hz, E_norm_MPa, phase_deg [, solver, dt_s]) or numerical isotherms "
        "(E_norm_MPa_mean, phase_deg_mean); several files are concatenated; without it the "
        "baseline is the macro Burger's fit",
    )
    p.add_argument(
        "--harmonic",
        type=Path,
        nargs="+",
        default=None,
        help="harmonic-solver results of the simulated sample(s) (same columns; concatenated)",
    )
    p.add_argument(
        "--time-integration",
        type=Path,
        nargs="+",
        default=None,
        help="time-integration phase errors (frequency_Hz, dt_s, phase_error_deg [, theta]; "
        "e.g. results/campaign/measured/dt_policy_phase_error.csv; concatenated)",
    )
    p.add_argument(
        "--theta",
        type=float,
        default=None,
        help="Moreau-Jean theta of the simulation: keep only these rows of a time-integration table "
        "with a theta column (e.g. results/nscd/phase_error.csv)",
    )
    p.add_argument(
        "--simulated-extended",
        type=Path,
        nargs="+",
        default=None,
        help="NSCD results rerun with the extended law (same columns as --simulated)",
    )
    p.add_argument(
        "--transfer",
        type=Path,
        nargs="+",
        default=None,
        help="network factor JSON(s) of the extended simulation's samples (output of "
        "'harmonic-transfer', e.g. results/harmonic/transfer/s1.json): the gain table adds "
        "the extended law without the transfer correction (NF_s x E*, inertia-free harmonic "
        "response), separating the gain of the law from that of the correction",
    )
    p.add_argument(
        "--law-json",
        type=Path,
        required=True,
        help="the extended law the extended simulation ran with (output of 'extend-law')",
    )
    p.add_argument(
        "--crossval",
        type=Path,
        nargs="+",
        default=None,
        help="outputs of 'asphalt-nscd crossval' (lofo and/or loto): the gain table and the page "
        "give the held-out MRE beside the in-sample one",
    )
    p.add_argument(
        "--law-without-flagged",
        type=Path,
        default=None,
        help="the law fitted without the rows beyond a data-quality limit (extend-law --without-flagged), "
        "compared with the selected law on the page",
    )
    p.add_argument(
        "--card",
        type=Path,
        default=None,
        help="the material card's JSON (export-law: prony.json): what it carries and loses and its errors "
        "against the measured means, on the page",
    )
    p.add_argument(
        "--macro-params",
        type=Path,
        default=None,
        help="Burger's parameters given to the simulation (temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, "
        "eta_k_MPa_s); default: fitted to the measured table",
    )
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="test-geometry JSON of the measured table (default: the sidecar <measured stem>.test.json "
        "next to it, else an unknown test: inertia not testable)",
    )
    _config_option(p, "causes")
    p.add_argument(
        "--tolerance-network-factor",
        type=float,
        default=0.01,
        help="tolerance of the network factor's departure from 1 (relative, default 0.01)",
    )
    p.add_argument(
        "--tolerance-phase-deg",
        type=float,
        default=0.1,
        help="tolerance of the time-integration phase error, deg (default 0.1)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="report JSON")
    p.add_argument("--budget-csv", type=Path, default=None, help="error budget table (CSV)")
    p.add_argument("--effects-csv", type=Path, default=None, help="candidate causes table (CSV)")
    p.add_argument(
        "--gain-csv",
        type=Path,
        default=None,
        help="MRE before/after per temperature and source (nscd: NSCD simulations; macro: macro laws) (CSV)",
    )
    p.add_argument("--figure", type=Path, default=None, help="stacked error-budget figure (PNG/PDF/SVG)")
    p.add_argument(
        "--page",
        type=Path,
        default=None,
        help="Markdown page 'What the simulation gets wrong' (links the figure by its file name)",
    )
    p.set_defaults(func=_diagnose)


def _add_synth(subparsers) -> None:
    """``synth``: synthetic measured table with planted effects (truth in a JSON sidecar)."""
    p = subparsers.add_parser("synth", help="synthetic measured table with planted effects (truth in a JSON sidecar)")
    p.add_argument("--seed", type=int, required=True, help="random seed")
    p.add_argument(
        "--effects",
        type=str,
        default="",
        help="comma-separated effects: time_lag, inertia_uncorrected, temperature_offset, "
        "strain_nonlinearity, self_heating (default: none)",
    )
    p.add_argument(
        "--schedule",
        choices=["paper_2pb", "aashto_t342", "ampt_pp61"],
        default=None,
        help="test schedule (default: drawn from the seed)",
    )
    p.add_argument(
        "--family",
        choices=["wlf", "glassy_drift", "arrhenius", "static_drift", "poly_shift", "mixed"],
        default="wlf",
        help="truth family (default wlf: 2S2P1D + WLF, the detector's own model)",
    )
    p.add_argument("--specimens", type=int, default=None, help="number of replicates 1-5 (default: drawn, 2-4)")
    p.add_argument("-o", "--output", type=Path, required=True, help="measured-table CSV")
    p.add_argument("--truth", type=Path, default=None, help="truth JSON (default: <output stem>.truth.json)")
    p.add_argument(
        "--no-test-sidecar", action="store_true", help="do not write the test-geometry sidecar <output stem>.test.json"
    )
    p.set_defaults(func=_synth)


def _add_diagnose_bench(subparsers) -> None:
    """``diagnose-bench``: false-alarm and detection rates of the artifact detection (with 95 %
    intervals)."""
    p = subparsers.add_parser(
        "diagnose-bench",
        help="false-alarm and detection rates of the artifact detection (with 95 %% intervals)",
        description="Draw clean and planted synthetic tables from truth families inside "
        "and outside the detector's model, diagnose their artifacts and report per artifact "
        "and family the false-alarm rate (clean tables) and the detection rate at the stated "
        "effect sizes, with exact binomial 95 % confidence intervals.",
    )
    p.add_argument("--clean", type=int, default=20, help="clean tables per family (default 20, config diagnosis.bench)")
    p.add_argument("--planted", type=int, default=8, help="planted tables per family and artifact (default 8)")
    p.add_argument(
        "--families",
        type=str,
        default=None,
        help="comma-separated truth families (default: all: wlf, glassy_drift, arrhenius, "
        "static_drift, poly_shift, mixed, huet_sayegh, gmaxwell, sigmoidal)",
    )
    p.add_argument(
        "--base-seed",
        type=int,
        default=None,
        help="base seed of every table's seed (default: a fresh one, recorded in the JSON)",
    )
    p.add_argument("--alpha", type=float, default=1e-3, help="significance level (default 1e-3)")
    p.add_argument(
        "--effect-scale",
        type=float,
        default=1.0,
        help="factor on every stated effect size (default 1; e.g. 0.5 for the power curve)",
    )
    p.add_argument("--tolerance", type=float, default=0.25, help="relative tolerance of the estimates (default 0.25)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    p.add_argument(
        "--configuration",
        choices=["random", "shipped", "paper"],
        default="random",
        help="design of the tables: random (drawn per table), shipped (the shipped table's: AASHTO T 342, "
        "3 specimens, no test order), paper (2PB 6 x 5, 4 specimens, test order) (default random)",
    )
    p.add_argument(
        "--power",
        type=int,
        default=0,
        help="tables per size of the power curves of the offset, time lag and mass (default 0: none)",
    )
    p.add_argument("--power-table", type=Path, default=None, help="power-curve CSV (with --power)")
    p.add_argument(
        "--calibration-tables",
        type=int,
        default=0,
        help="bootstrap tables of the calibration of each clean table with a nominal alarm: the "
        "family-wise false alarms of the complete procedure (default 0: nominal level only)",
    )
    p.add_argument(
        "-o", "--output", type=Path, required=True, help="benchmark JSON (summary and every table's outcome)"
    )
    p.add_argument(
        "--table",
        type=Path,
        default=None,
        help="bench table CSV: per artifact and family, detection and false-alarm counts, rates, 95 %% CIs",
    )
    _config_option(p, "bench")
    p.set_defaults(func=_bench)


def law_options(args):
    """:class:`~asphalt_nscd.diagnosis.crossval.Options` from the options of :func:`_fit_options`.

    Raises InputError naming the option on a bad value.
    """
    from ..io import InputError
    from .crossval import Options, candidate_grid

    tol = tuple(float(v) / 100.0 for v in args.tolerances_pct)
    if not all(t > 0 for t in tol):
        raise InputError(f"--tolerances-pct: expected two positive percentages, got {args.tolerances_pct}")
    refines = []
    for v in args.law_refines:
        if str(v).lower() in ("off", "none", "null"):
            refines.append(None)
            continue
        try:
            refines.append(float(v))
        except ValueError:
            raise InputError(f"--law-refines: expected 'off' or a positive number, got {v!r}") from None
    if not args.margin_decades >= 0:
        raise InputError(f"--margin-decades: expected >= 0, got {args.margin_decades}")
    try:
        grid = candidate_grid(
            shifts=args.law_shifts,
            statics=args.law_statics,
            verticals=[v == "on" for v in args.law_verticals],
            refines=refines,
            per_decades=args.law_per_decades,
        )
    except ValueError as exc:
        raise InputError(f"--law-refines/--law-per-decades: {exc}") from None
    cal = read_calibration(args)
    return Options(
        candidates=tuple(grid),
        tolerances=tol,
        margin_decades=args.margin_decades,
        artifacts=not args.no_artifacts,
        alpha=args.alpha,
        artifact_shift=args.shift,
        T_ref_C=args.t_ref,
        one_se=not args.no_one_se,
        limits=search_limits(args),
        level=None if cal is None else float(cal["artifacts"]["level"]),
        card_fit=args.card_fit,
        card_shift=args.card_shift,
    )


def _calibrate_search(args) -> int:
    from ..io import InputError, write_json
    from ..lab.measured import load_measured
    from .calibration import calibrate, min_tables

    if not 0.0 < args.familywise_rate < 1.0:
        raise InputError(f"--familywise-rate: expected a rate in (0, 1), got {args.familywise_rate}")
    if args.tables < min_tables(args.familywise_rate):
        raise InputError(
            f"--tables (config diagnosis.calibration.tables): expected >= {min_tables(args.familywise_rate)} "
            "bootstrap tables per null to hold a "
            f"family-wise rate of {args.familywise_rate:g} (fewer cannot name any artifact), got {args.tables}"
        )
    if args.jobs < 1:
        raise InputError(f"--jobs: expected >= 1, got {args.jobs}")
    from .artifacts import check_design

    measured = load_measured(args.measured, test=args.test)
    check_design(measured, str(args.measured))
    cal = calibrate(
        measured,
        alpha=args.alpha,
        shift=args.shift,
        test=measured.attrs["test"],
        limits=search_limits(args),
        n_tables=args.tables,
        seed=args.seed,
        rate=args.familywise_rate,
        jobs=args.jobs,
    )
    cal["source"] = _table_source(args.measured)
    write_json(cal, args.output)
    return 0


def _master_curve(args) -> int:
    from ..io import write_csv, write_json
    from ..lab.measured import load_measured
    from . import artifacts

    measured = load_measured(args.measured, test=args.test)
    artifacts.check_design(measured, str(args.measured))
    analysis = artifacts.analyse(
        measured,
        alpha=args.alpha,
        shift=args.shift,
        T_ref_C=args.t_ref,
        calibration=read_calibration(args),
        limits=search_limits(args),
    )
    rec = artifacts.record(analysis, alpha=args.alpha, shift=args.shift, T_ref_C=args.t_ref)
    write_json(artifacts.to_json(rec, _table_source(args.measured)), args.output)
    write_csv(analysis["corrected"].drop(columns=["test_step", "test_step_centre"], errors="ignore"), args.corrected)
    return 0


def _warn_implausible(curve, card: bool) -> None:
    """Console warning when the selected law (or the material card's law) has parameters at a
    bound or outside the documented physical ranges (the ``findings`` of the candidate curve)."""
    import logging

    if curve is None or "plausible" not in curve:
        return
    roles = [("chosen", "selected law")] + ([("chosen_card", "law of the material card")] if card else [])
    for column, role in roles:
        rows = curve[curve[column].astype(bool) & ~curve["plausible"].astype(bool)]
        for _, r in rows.iterrows():
            logging.getLogger("asphalt_nscd").warning(
                "the %s (%s) has implausible parameters: %s", role, r["settings"], r["findings"]
            )


def _extend_law(args) -> int:
    from ..io import InputError, write_csv
    from ..lab.measured import load_measured
    from ..rheology import law_file
    from . import artifacts
    from .crossval import exclude_rows, fit_extended, law_file_object

    if (args.master_curve is None) != (args.corrected_table is None):
        raise InputError("--master-curve and --corrected-table: give both (the outputs of 'master-curve') or neither")
    if args.master_curve is not None and (args.exclude_frequency or args.exclude_temperature):
        raise InputError(
            "--master-curve: the artifact search of the whole table; not with --exclude-frequency/"
            "--exclude-temperature (a fold searches its own rows)"
        )
    measured = exclude_rows(
        load_measured(args.measured), args.exclude_frequency, args.exclude_temperature, where=args.measured
    )
    if not (args.exclude_frequency or args.exclude_temperature):
        artifacts.check_design(measured, str(args.measured))
    given = None
    if args.master_curve is not None:
        given = (artifacts.read_corrected(args.corrected_table), artifacts.read(args.master_curve))
    options = law_options(args)
    fit = fit_extended(measured, options, artifacts=given)
    if fit.law is None:
        raise InputError(f"{args.measured}: no extended law could be fitted: {fit.reason}")
    temps = args.temperatures if args.temperatures else sorted(measured["temperature_C"].unique())
    source = {
        **_table_source(args.measured),
        "excluded_frequencies_Hz": list(args.exclude_frequency),
        "excluded_temperatures_C": list(args.exclude_temperature),
    }
    law_file.write(law_file_object(fit, measured, temps, options, source), args.output)
    _warn_implausible(fit.curve, card=args.card_law is not None)
    if args.card_law is not None:
        if fit.card_law is None:
            raise InputError(
                f"{args.measured}: no law that a Prony series with a shift function carries could be "
                "fitted (the material card has no law to carry)"
            )
        if fit.card_law is not fit.law:
            import logging

            assert fit.settings is not None and fit.card_settings is not None  # chosen with the fitted laws
            why = (
                "has what a Prony series with a shift function cannot carry"
                if not fit.settings.carriable
                else f"is refitted for the card (diagnosis.material_card: --card-fit {options.card_fit}, --card-shift "
                f"{options.card_shift})"
            )
            log = logging.getLogger("asphalt_nscd")
            (log.info if fit.settings.carriable else log.warning)(
                "the selected law (%s) %s; the material card carries %s (its errors: export-law)",
                fit.settings.label(),
                why,
                fit.card_settings.label(),
            )
        law_file.write(law_file_object(fit, measured, temps, options, source, card=True), args.card_law)
    if args.without_flagged is not None:
        _without_flagged(measured, options, temps, source, args.without_flagged)
    if args.corrected is not None:
        write_csv(fit.corrected, args.corrected)
    if args.cv_curve is not None:
        write_csv(fit.curve, args.cv_curve)
    return 0


def _without_flagged(measured, options, temps, source: dict, path) -> None:
    """The law of the rows within every data-quality limit (their own artifact search and
    selection), or a note that no row is flagged (``extend-law --without-flagged``)."""
    from ..io import write_json
    from ..lab.checks import quality_columns, quality_flags
    from ..rheology import law_file
    from .crossval import fit_extended, law_file_object

    test = measured.attrs.get("test")
    flags = quality_flags(measured, getattr(test, "quality_limits", None))
    n = int(flags["flagged"].sum())
    if n == 0:
        write_json(
            {
                "n_flagged": 0,
                "n_rows": int(len(measured)),
                "note": "no row beyond a data-quality limit"
                if quality_columns(measured)
                else "the table carries no data-quality indicators",
            },
            path,
        )
        return
    kept = measured[~flags["flagged"].to_numpy()]
    fit = fit_extended(kept, options)
    if fit.law is None:
        write_json(
            {
                "n_flagged": n,
                "n_rows": int(len(measured)),
                "note": f"no law could be fitted without the flagged rows: {fit.reason}",
            },
            path,
        )
        return
    obj = law_file_object(
        fit,
        kept,
        [T for T in temps if T in set(kept["temperature_C"])],
        options,
        {**source, "n_flagged": n, "n_rows": int(len(measured))},
    )
    law_file.write(obj, path)


def _crossval(args) -> int:
    import pandas as pd

    from ..io import InputError, write_csv
    from ..lab.measured import load_measured
    from . import crossval as cv
    from . import artifacts, render
    from .inputs import read_simulated_many

    measured = load_measured(args.measured)
    artifacts.check_design(measured, str(args.measured))
    sample = None
    if (args.sample is None) != (args.transfer is None):
        raise InputError("--sample and --transfer: give both (the sample and its network factor JSON) or neither")
    if args.sample is not None:
        sample = cv.SampleModel.load(args.sample, args.transfer, inertia=args.inertia)
    td = read_simulated_many(args.time_domain) if args.time_domain else None
    if args.burgers_starts < 1:
        raise InputError(f"--burgers-starts: expected >= 1, got {args.burgers_starts}")
    options = law_options(args)
    options.burgers_starts = args.burgers_starts
    options.burgers = not args.no_burgers
    res = cv.crossval(measured, args.scheme, options, sample=sample, time_domain=td)
    write_csv(res.rows, args.output)
    if args.summary is not None:
        from .scores import summarize

        write_csv(summarize(res.rows, measured), args.summary)
    if args.curve is not None:
        write_csv(res.curves if len(res.curves) else pd.DataFrame(columns=["scheme", "fold", "settings"]), args.curve)
    if args.figure is not None:
        render.crossval_figure(res.rows, res.full.law, args.figure)
    return 0


def _table_source(path) -> dict:
    """The ``source`` stamp of a result: the measured table's path and SHA-256 (:func:`same_table`)."""
    from ..io import content_sha256

    return {"measured": str(path), "measured_sha256": content_sha256(path)}


def same_table(measured_path, results: list) -> str:
    """SHA-256 of the measured table at ``measured_path``, after checking that every result of
    ``results`` ((path, JSON object) pairs of the master curve, the law, the material card ...)
    was computed from it (their ``source.measured_sha256``; results without one are not checked).

    Raises InputError naming the result and both tables' stamps when one came from another table
    (a result left from an earlier run beside a new table)."""
    from ..io import InputError, content_sha256

    mine = content_sha256(measured_path)
    for path, obj in results:
        src = obj.get("source") if isinstance(obj, dict) else None  # a test JSON's "source" is a text
        theirs = src.get("measured_sha256") if isinstance(src, dict) else None
        if theirs is not None and theirs != mine:
            raise InputError(
                f"{path}: computed from another measured table (sha256 {theirs[:12]}) than "
                f"{measured_path} (sha256 {mine[:12]}); rerun the workflow so that every result "
                "comes from the same table"
            )
    return mine


def _diagnose(args) -> int:
    from ..io import InputError, read_json, write_csv, write_json, write_text
    from ..lab.measured import load_measured
    from ..rheology import law_file
    from . import artifacts, inputs, render
    from .budget import diagnose

    measured = load_measured(args.measured, test=args.test)
    card = read_json(args.card, "material card JSON") if args.card is not None else None
    master_json = read_json(args.master_curve, "master-curve JSON")  # each result read once
    law_json = read_json(args.law_json, "law JSON")
    stamp = same_table(
        args.measured,
        [
            (args.master_curve, master_json),
            (args.law_json, law_json),
            *([(args.card, card)] if card is not None else []),
        ],
    )
    if not (args.tolerance_network_factor > 0 and args.tolerance_phase_deg > 0):
        raise InputError(
            "--tolerance-network-factor and --tolerance-phase-deg: expected positive numbers, got "
            f"{args.tolerance_network_factor}, {args.tolerance_phase_deg}"
        )
    temps = sorted(measured["temperature_C"].unique())
    report, extra = diagnose(
        measured,
        artifacts.record_from(master_json, args.master_curve),
        artifacts.read_corrected(args.corrected_table),
        laws=law_file.laws_mpa(law_file.validate(law_json, args.law_json), temps, args.law_json),
        law_info=law_file.info_of(law_json),
        simulated=inputs.read_simulated_many(args.simulated),
        harmonic=inputs.read_simulated_many(args.harmonic),
        time_errors=inputs.read_time_errors(args.time_integration, args.theta) if args.time_integration else None,
        simulated_extended=inputs.read_simulated_many(args.simulated_extended),
        macro_params=inputs.read_macro_params(args.macro_params) if args.macro_params is not None else None,
        transfer=inputs.read_network_factors(args.transfer) if args.transfer else None,
        crossval=inputs.read_crossval(args.crossval) if args.crossval else None,
        cause_tolerances={
            "network_factor": args.tolerance_network_factor,
            "time_integration_deg": args.tolerance_phase_deg,
        },
        card=card,
        without_flagged=read_json(args.law_without_flagged, "law without flagged rows")
        if args.law_without_flagged is not None
        else None,
    )
    report["measured"]["test"] = measured.attrs["test"].to_json()
    report["measured"]["path"] = str(args.measured)
    report["measured"]["sha256"] = stamp
    report["measured"]["warnings"] = list(measured.attrs.get("warnings", []))
    write_json(report, args.output)
    if args.budget_csv is not None:
        write_csv(extra["budget"], args.budget_csv)
    if args.effects_csv is not None:
        write_csv(render.effects_table(report), args.effects_csv)
    if args.gain_csv is not None:
        write_csv(render.gain_table(report), args.gain_csv)
    if args.figure is not None:
        render.budget_figure(extra["budget"], args.figure, report["baseline"]["model"])
    if args.page is not None:
        write_text(render.markdown_page(report, args.figure.name if args.figure is not None else None), args.page)
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
    table, truth = synthetic.generate(
        args.seed, effects, schedule=args.schedule, n_specimens=args.specimens, family=args.family
    )
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
    from .bench import bench_table, power_table, run_bench

    if args.clean < 0 or args.planted < 0 or args.clean + args.planted + max(args.power, 0) == 0:
        raise InputError(
            f"--clean, --planted, --power: expected >= 0 and not all 0, got {args.clean}, {args.planted}, {args.power}"
        )
    if args.jobs < 1:
        raise InputError(f"--jobs: expected >= 1, got {args.jobs}")
    if not 0 < args.alpha < 1 or not args.effect_scale > 0:
        raise InputError(f"--alpha in (0, 1) and --effect-scale > 0 expected, got {args.alpha}, {args.effect_scale}")
    families = (
        list(synthetic.FAMILIES)
        if args.families is None
        else [f.strip() for f in args.families.split(",") if f.strip()]
    )
    unknown = [f for f in families if f not in synthetic.FAMILIES]
    if unknown or not families:
        raise InputError(f"--families: unknown {unknown}; expected some of {list(synthetic.FAMILIES)}")
    if args.power < 0:
        raise InputError(f"--power: expected >= 0, got {args.power}")
    from .calibration import min_tables

    if args.calibration_tables != 0 and args.calibration_tables < min_tables():
        raise InputError(f"--calibration-tables: expected 0 or >= {min_tables()}, got {args.calibration_tables}")
    result = run_bench(
        args.clean,
        args.planted,
        args.base_seed,
        families,
        args.alpha,
        args.effect_scale,
        args.tolerance,
        args.jobs,
        args.configuration,
        args.power,
        args.calibration_tables,
    )
    write_json(result, args.output)
    if args.table is not None:
        write_csv(bench_table(result), args.table, float_format="%.4g")
    if args.power_table is not None:
        write_csv(power_table(result), args.power_table, float_format="%.4g")
    return 0
