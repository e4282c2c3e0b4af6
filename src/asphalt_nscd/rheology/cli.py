"""Subcommands of the rheology step (registered by asphalt_nscd.cli).

* ``fit``            — Burger's calibration per temperature of a measured table (Eqs. 27-29).
* ``table3``         — the paper's Table 3 converted to MPa under a unit reading (Pa / kPa).
* ``burgers-curves`` — model isotherms of a parameter table on a log-spaced frequency grid.
* ``refit-check``    — isotherms generated from a parameter table, fitted back (verification).
* ``micro``          — bond parameters from r_min and l0 (Eqs. 30-33, 8-11).
"""

from __future__ import annotations

from pathlib import Path


def _add_fit_options(p) -> None:
    p.add_argument("--weight-log-modulus", type=float, default=1.0, help="weight of the ln|E*| residuals (default 1)")
    p.add_argument(
        "--weight-phase", type=float, default=1.0, help="weight of the phase residuals in radians (default 1)"
    )
    p.add_argument(
        "--n-starts",
        type=int,
        default=8,
        help="local least-squares runs from the best grid starting values (default 8)",
    )


def config_values(cfg, args) -> dict:
    """Option values of this step's commands from the ``calibration`` section of a merged,
    checked workflow config (``--config``; an option given on the command line wins), and
    export-law's tolerance (``diagnosis.material_card.tolerance``)."""
    cal = cfg["calibration"]
    micro, curves = cal["micro"], cal["curves"]
    weights = {
        "weight_log_modulus": float(cal["weight_log_modulus"]),
        "weight_phase": float(cal["weight_phase"]),
        "n_starts": int(cal["n_starts"]),
    }
    by_command = {
        "fit": {"model": cal["model"], **weights},
        "refit-check": {"frequencies": [float(f) for f in cal["refit_frequencies_Hz"]], **weights},
        "table3": {"units": cal["table3_units"]},
        "burgers-curves": {
            "fmin": float(curves["fmin_Hz"]),
            "fmax": float(curves["fmax_Hz"]),
            "points": int(curves["points"]),
        },
        "micro": {
            "r_min_mm": [float(r) for r in micro["r_min_mm"]],
            "l0_mm": [float(x) for x in micro["l0_mm"]],
            "nu": float(micro["poisson_ratio"]),
            "grain_mass_kg": None if micro.get("grain_mass_kg") is None else float(micro["grain_mass_kg"]),
        },
        "export-law": {"tolerance": [float(x) for x in cfg["diagnosis"]["material_card"]["tolerance"]]},
    }
    return by_command.get(args.command, {})


def _config_option(p) -> None:
    from ..config import config_option

    config_option(p, config_values, "its calibration section")


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    _add_fit(subparsers)
    _add_table3(subparsers)
    _add_burgers_curves(subparsers)
    _add_refit_check(subparsers)
    _add_micro(subparsers)
    _add_export_law(subparsers)


def _add_fit(subparsers) -> None:
    """``fit``: fit a Burger's model per temperature to a measured table (Eqs. 27-29)."""
    p = subparsers.add_parser("fit", help="fit a Burger's model per temperature to a measured table (Eqs. 27-29)")
    p.add_argument(
        "--measured",
        type=Path,
        required=True,
        help="measured table (specimen, temperature_C, frequency_Hz, E_norm_MPa, phase_deg)",
    )
    p.add_argument("--model", choices=["burgers"], default="burgers", help="macro model (only 'burgers')")
    _add_fit_options(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV, one row per temperature: temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s, *_se, fit errors",
    )
    _config_option(p)
    p.set_defaults(func=_fit)


def _add_table3(subparsers) -> None:
    """``table3``: convert the paper's Table 3 (as printed) to MPa, MPa s."""
    p = subparsers.add_parser("table3", help="convert the paper's Table 3 (as printed) to MPa, MPa s")
    p.add_argument("table", type=Path, help="data/paper/table3_burgers.csv")
    p.add_argument(
        "--units",
        choices=["Pa", "kPa"],
        default="Pa",
        help="reading of the printed values (default Pa, as printed; see data/paper/SOURCE.md)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV in MPa, MPa s")
    _config_option(p)
    p.set_defaults(func=_table3)


def _add_burgers_curves(subparsers) -> None:
    """``burgers-curves``: Burger's model isotherms of a parameter table."""
    p = subparsers.add_parser("burgers-curves", help="Burger's model isotherms of a parameter table")
    p.add_argument(
        "--parameters", type=Path, required=True, help="CSV: temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, eta_k_MPa_s"
    )
    p.add_argument(
        "--fmin", type=float, default=0.05, help="lowest frequency, Hz (default 0.05, config calibration.curves)"
    )
    p.add_argument("--fmax", type=float, default=50.0, help="highest frequency, Hz (default 50)")
    p.add_argument("--points", type=int, default=61, help="log-spaced frequencies (default 61)")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV: temperature_C, frequency_Hz, E_norm_MPa, phase_deg, E1_MPa, E2_MPa",
    )
    _config_option(p)
    p.set_defaults(func=_curves)


def _add_refit_check(subparsers) -> None:
    """``refit-check``: generate isotherms from a parameter table and fit them back (verification)."""
    p = subparsers.add_parser(
        "refit-check", help="generate isotherms from a parameter table and fit them back (verification)"
    )
    p.add_argument("--parameters", type=Path, required=True, help="CSV in MPa, MPa s (e.g. output of table3)")
    p.add_argument(
        "--frequencies",
        type=float,
        nargs="+",
        default=[3.0, 6.0, 10.0, 25.0, 40.0],
        help="frequencies of the generated isotherms, Hz (default: the paper's 3 6 10 25 40)",
    )
    _add_fit_options(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV: true and refitted parameters and relative errors per temperature",
    )
    _config_option(p)
    p.set_defaults(func=_refit_check)


def _add_micro(subparsers) -> None:
    """``micro``: bond parameters from macro Burger's parameters, r_min and l0 (Eqs. 30-33, 8-11)."""
    p = subparsers.add_parser(
        "micro", help="bond parameters from macro Burger's parameters, r_min and l0 (Eqs. 30-33, 8-11)"
    )
    p.add_argument("--parameters", type=Path, required=True, help="CSV in MPa, MPa s")
    p.add_argument(
        "--r-min-mm",
        type=float,
        nargs="+",
        default=None,
        help="smaller radius of each bonded pair, mm (required without --config)",
    )
    p.add_argument(
        "--l0-mm",
        type=float,
        nargs="+",
        default=None,
        help="initial barycentre distance of each bond, mm (same count as --r-min-mm, or one; required "
        "without --config)",
    )
    p.add_argument("--nu", type=float, default=0.35, help="Poisson's ratio of Eqs. 8-11 (default 0.35)")
    p.add_argument(
        "--grain-mass-kg",
        type=float,
        default=None,
        help="typical grain mass; adds dt_e_s = sqrt(m_g/Km) (paper: 2.86e-5 kg)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV, one row per (temperature, bond)")
    _config_option(p)
    p.set_defaults(func=_micro)


def _add_export_law(subparsers) -> None:
    """``export-law``: material cards of a temperature-aware law: Abaqus, LS-DYNA, JSON and CSV
    Prony series."""
    p = subparsers.add_parser(
        "export-law",
        help="material cards of a temperature-aware law: Abaqus, LS-DYNA, JSON and CSV Prony series",
        description="Relaxation Prony series at the law's reference temperature with its WLF shift "
        "(asphalt_nscd.rheology.export), written as an Abaqus input fragment (*ELASTIC, *VISCOELASTIC "
        "TIME=PRONY, *TRS WLF), an LS-DYNA *MAT_GENERAL_VISCOELASTIC card, a JSON and a CSV; checked "
        "against the law at every measured cell.",
    )
    p.add_argument(
        "--law-json",
        type=Path,
        required=True,
        help="the law the card carries: law JSON of 'asphalt-nscd extend-law --card-law' "
        "(results/diagnosis/card_law.json)",
    )
    p.add_argument(
        "--selected-law-json",
        type=Path,
        default=None,
        help="the selected law (extend-law -o), against which the card's loss is stated (default: the --law-json law)",
    )
    p.add_argument(
        "--measured",
        type=Path,
        required=True,
        help="measured summary (temperature_C, frequency_Hz, E_norm_MPa_mean, phase_deg_mean: "
        "asphalt-nscd measured --summary) whose cells the card is checked at",
    )
    p.add_argument(
        "--test",
        type=Path,
        default=None,
        help="the measured table's test JSON (asphalt-nscd measured --test-output): the units the lab "
        "wrote the table in, for the cards' comments (the cards themselves stay in MPa, s, degC)",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="directory of the cards")
    p.add_argument("--name", default="ASPHALT_MIX", help="material name of the Abaqus card")
    p.add_argument(
        "--tolerance",
        type=float,
        nargs=2,
        default=None,
        metavar=("E_PCT", "PHASE_DEG"),
        help="largest difference of the card to its law over the measured reduced band widened by a decade "
        "at each end and at every measured cell: |E*| %% and Phi deg (default 1 0.2, config "
        "diagnosis.material_card.tolerance); the fewest Prony terms that meet it",
    )
    p.add_argument(
        "--nu",
        type=float,
        default=None,
        help="Poisson's ratio of the cards (constant; default: the paper's 0.35, Eqs. 8-11)",
    )
    p.add_argument(
        "--corrected",
        type=Path,
        default=None,
        help="the artifact-corrected table the laws were fitted on (extend-law --corrected, or "
        "master-curve's): the card's errors against it and what the correction changes, per "
        "temperature",
    )
    _config_option(p)
    p.set_defaults(func=_export)


def _export(args) -> int:
    import logging

    import numpy as np

    from ..io import InputError, atomic_path, read_json, write_csv, write_json
    from ..lab.measured import read_summary
    from . import export

    law = read_json(args.law_json, "law JSON")
    selected = read_json(args.selected_law_json, "selected law JSON") if args.selected_law_json else law
    summary = read_summary(args.measured)
    cells = summary[["temperature_C", "frequency_Hz"]].drop_duplicates()
    tolerance = tuple(args.tolerance) if args.tolerance is not None else export.CARD_TOLERANCE
    nu, nu_source = (export.POISSON_RATIO, export.POISSON_SOURCE) if args.nu is None else (args.nu, "given (--nu)")
    try:
        if not all(v > 0 for v in tolerance):
            raise InputError(f"--tolerance: expected two positive numbers, got {list(tolerance)}")
        if not -1.0 < nu < 0.5:
            raise InputError(f"--nu: expected a Poisson's ratio in (-1, 0.5), got {nu}")
        card = export.prony_card(law, cells, tolerance=tolerance, nu=nu)
    except InputError as exc:
        raise InputError(f"{args.law_json}: {exc}") from None
    c = card["check"]
    if not card["exact"]:
        raise InputError(
            f"{args.law_json}: the Prony series with a WLF shift misses the law it carries by "
            f"{c['max_E_norm_difference_pct']:.3g} % |E*| (at {c['at_E'][0]:g} degC, {c['at_E'][1]:g} Hz) and "
            f"{c['max_phase_difference_deg']:.3g} deg (at {c['at_phase'][0]:g} degC, {c['at_phase'][1]:g} Hz), above "
            f"{tolerance[0]:g} % / {tolerance[1]:g} deg; not carried by a single Prony + shift "
            f"law: {', '.join(c['not_carried']) or 'none of the law settings (more terms: --per-decade?)'}; no card "
            "written (give it the law of 'extend-law --card-law')"
        )
    corrected = None
    if args.corrected is not None:
        from ..io import checked, read_csv
        from .metrics import cell_means

        corrected = cell_means(
            checked(
                read_csv(args.corrected),
                args.corrected,
                ("temperature_C", "frequency_Hz", "E_norm_MPa", "phase_deg"),
                positive=("frequency_Hz", "E_norm_MPa"),
            )
        )
    try:
        errors = export.card_errors(card, summary, selected, corrected)
    except InputError as exc:
        raise InputError(
            f"{args.corrected if corrected is not None else args.selected_law_json or args.law_json}: {exc}"
        ) from None
    if (
        corrected is not None
        and not (
            errors[["corrected_vs_measured_logE_pct", "corrected_vs_measured_phase_deg"]].abs().to_numpy() > 1e-3
        ).any()
    ):
        errors = export.card_errors(card, summary, selected)  # no correction was made: the table as measured
    carried = (law.get("model") or {}).get("settings") or {}
    chosen = (selected.get("selection") or {}).get("chosen_label") or ""
    about = law.get("card") or {}
    display = {}
    if args.test is not None:
        from ..lab.geometry import load_test
        from ..lab.table_format import DisplayUnits

        display = DisplayUnits.of(load_test(args.test)).as_dict()
    card.update(
        {
            "carries": about.get("settings") or "",
            "selected_law": chosen,
            "is_selected_law": bool(about.get("is_selected_law", True)),
            "fit": about.get("fit") or (law.get("model") or {}).get("fit_loss"),
            "selected_fit": about.get("selected_fit") or (selected.get("model") or {}).get("fit_loss"),
            "selected_carriable": (selected.get("model") or {}).get("carriable_by_a_prony_card"),
            "corrections": [str(a) for a in (law.get("model") or {}).get("artifacts_corrected") or []],
            "carried_settings": carried,
            "findings": (law.get("model") or {}).get("findings") or [],
            "nu_source": nu_source,
            "display": display,
            "loss": export.loss_by_temperature(errors),
            "source": {k: v for k, v in (law.get("source") or {}).items() if k in ("measured", "measured_sha256")},
        }
    )
    try:
        band = card["terms_selection"]["band_rad_s"]
        times = np.logspace(-np.log10(band[1]), -np.log10(band[0]), 81)
        functions = export.relaxation_and_creep(card, sorted(summary["temperature_C"].unique()), times)
    except ValueError as exc:  # a liquid card: no finite creep limit
        raise InputError(f"{args.law_json}: {exc}") from None
    card["interconversion"] = export.interconversion_summary(functions)
    log = logging.getLogger("asphalt_nscd")
    for line in export.loss_lines(card):
        log.info("material card: %s", line)
    worse = export.worse_than_selected(card)
    if worse:
        log.warning(
            "material card: against the lab's means the card is worse than the selected law in %s "
            "(card_errors.csv; the card's header)",
            "; ".join(worse),
        )
    out = args.output
    out.mkdir(parents=True, exist_ok=True)
    for name, text in (("abaqus.inp", export.abaqus_card(card, args.name)), ("lsdyna.k", export.lsdyna_card(card))):
        with atomic_path(out / name) as tmp:
            tmp.write_text(text)
    write_json(export.card_json(card), out / "prony.json")
    write_csv(export.card_table(card), out / "prony.csv")
    write_csv(errors, out / "card_errors.csv")
    write_csv(functions, out / "relaxation_creep.csv")
    return 0


def _weights(args) -> dict:
    return {"log_E": args.weight_log_modulus, "phase_rad": args.weight_phase}


def _fit(args) -> int:
    from ..io import InputError, write_csv
    from ..lab.measured import load_measured
    from .calibration import fit_table

    measured = load_measured(args.measured)
    try:
        table = fit_table(measured, weights=_weights(args), n_starts=args.n_starts)
    except InputError as exc:
        raise InputError(f"{args.measured}: {exc}") from None
    except ValueError as exc:  # bad weights
        raise InputError(f"fit options: {exc}") from None
    write_csv(table, args.output, float_format="%.8g")
    return 0


def _table3(args) -> int:
    from ..io import write_csv
    from .calibration import load_table3

    table = load_table3(args.table, units=args.units)
    table.insert(len(table.columns), "units_reading", args.units)
    write_csv(table, args.output, float_format="%.8g")
    return 0


def _curves(args) -> int:
    import numpy as np

    from ..io import InputError, write_csv
    from .calibration import burgers_curves, read_parameters

    if not (0 < args.fmin < args.fmax) or args.points < 2:
        raise InputError(
            f"burgers-curves: need 0 < fmin < fmax and points >= 2, got {args.fmin}, {args.fmax}, {args.points}"
        )
    table = read_parameters(args.parameters)
    f = np.logspace(np.log10(args.fmin), np.log10(args.fmax), args.points)
    write_csv(burgers_curves(table, f), args.output, float_format="%.8g")
    return 0


def _refit_check(args) -> int:
    from ..io import write_csv
    from .calibration import read_parameters, refit_check

    table = read_parameters(args.parameters)
    result = refit_check(table, args.frequencies, weights=_weights(args), n_starts=args.n_starts)
    write_csv(result, args.output, float_format="%.10g")
    return 0


def _micro(args) -> int:
    import numpy as np

    from ..io import InputError, write_csv
    from .calibration import micro_parameters, read_parameters

    if args.r_min_mm is None or args.l0_mm is None:
        raise InputError("micro: give --r-min-mm and --l0-mm, or --config (calibration.micro)")
    r = np.asarray(args.r_min_mm) * 1e-3
    l0 = np.asarray(args.l0_mm) * 1e-3
    if r.size != l0.size and 1 not in (r.size, l0.size):
        raise InputError(f"micro: --r-min-mm has {r.size} values but --l0-mm has {l0.size}")
    table = read_parameters(args.parameters)
    try:
        micro = micro_parameters(table, r, l0, nu=args.nu, grain_mass_kg=args.grain_mass_kg)
    except ValueError as exc:
        raise InputError(f"micro: {exc}") from None
    write_csv(micro, args.output, float_format="%.8g")
    return 0
