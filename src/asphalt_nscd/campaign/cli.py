"""Subcommands of the campaign step (registered by asphalt_nscd.cli).

``rig-state``           what a sample's 2PB jobs share and no law changes (HDF5): held spheres, gravity
``run-2pb``             one numerical 2PB complex modulus test: record (HDF5) + reduced row (CSV);
                        ``--network-factor-json``: bond law divided by the sample's network factor
``campaign-isotherms``  numerical isotherms, Table 4 analogue, Figs. 9-10 analogues of one mode
``campaign-dt-study``   Fig. 6 analogue (time-step influence) and its table
``campaign-last-cycle`` Figs. 7-8 analogues (last cycle, velocity profile) from one record
``campaign-sensitivity`` sensitivity table and Figs. 11-14 analogues
``campaign-units``      the Table 3 units question (Pa versus kPa reading)
``campaign-dt-policy``  phase error of the time-step policy (bond law, phase_error_table)
``campaign-bench``      time per step of the 2PB test and projected campaign time (JSON)
``periodic-check``      periodic start vs from-rest protocol on a sample at several (mode, T, f)
``bench``               the NSCD core benchmark (:func:`asphalt_nscd.nscd.bench.run_bench`; its bonded
                        case's periodic start: :func:`.bench.bench_starter`)
"""

from __future__ import annotations

import argparse
from typing import Any


def _settings_options(p, config: bool = True):
    """The test settings of a command: ``--config`` (with ``config``) and ``--settings-mode``,
    ``--set`` and ``--window-cycles`` (:func:`_settings`)."""
    if config:
        p.add_argument(
            "--config",
            nargs="+",
            default=None,
            metavar="FILE",
            help="workflow config files (YAML) merged as Snakemake merges --configfile: "
            "config/config.yaml of the working directory first, then each FILE in order, checked "
            "against the workflow's schemas; the test settings are those of the jobs of "
            "--settings-mode (campaign section, nscd core, lab.simulation_window_cycles; "
            "asphalt_nscd.campaign.twopb.job_settings), and the mode's Table 3 reading (run-2pb: "
            "whether the job verifies the orbit; campaign-dt-policy: its temperature and "
            "frequencies; asphalt_nscd.campaign.modes). Default: TwoPBSettings' own values",
        )
        p.add_argument(
            "--settings-mode",
            default=None,
            metavar="MODE",
            help="the campaign mode whose settings --config gives (paper, paper_kPa, measured, "
            "extended, dt_study, ...; default: --mode, or paper)",
        )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override one test setting (a key of TwoPBSettings; VALUE read as YAML, e.g. "
        "n_cycles=3, start=rest, yield_stress_Pa=null); repeatable, applied after --config",
    )
    p.add_argument(
        "--window-cycles", type=float, default=None, help="last cycles reduced (config lab.simulation_window_cycles)"
    )


def _parameter_options(p, law_json: bool = False):
    """--parameters (and, with ``law_json``, the alternative --law-json) and --table3-units."""
    src = p.add_mutually_exclusive_group(required=True) if law_json else p
    src.add_argument(
        "--parameters",
        required=not law_json,
        help="Burger's parameter table: calibrated CSV in MPa, or the paper's Table 3 as printed",
    )
    if law_json:
        src.add_argument(
            "--law-json",
            default=None,
            help="generalized Burger's law per temperature (Pa, Pa s; output of "
            "'asphalt-nscd extend-law', e.g. results/diagnosis/generalized_burgers.json) "
            "instead of --parameters",
        )
    p.add_argument(
        "--table3-units",
        choices=("Pa", "kPa"),
        default=None,
        help="read --parameters as the paper's Table 3 under this unit reading",
    )


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    _add_bench(subparsers)
    _add_rig_state(subparsers)
    _add_run_2pb(subparsers)
    _add_campaign_isotherms(subparsers)
    _add_campaign_dt_study(subparsers)
    _add_campaign_last_cycle(subparsers)
    _add_campaign_sensitivity(subparsers)
    _add_campaign_units(subparsers)
    _add_campaign_dt_policy(subparsers)
    _add_campaign_bench(subparsers)
    _add_periodic_check(subparsers)


def _config_values(cfg, args) -> dict:
    from .modes import config_values

    return config_values(cfg, args)


def _add_rig_state(subparsers) -> None:
    """``rig-state``: what every 2PB job of a sample needs and no law changes
    (:func:`asphalt_nscd.campaign.twopb.write_rig_state`)."""
    p = subparsers.add_parser(
        "rig-state",
        help="the held spheres and the law-free gravity solution of a sample (HDF5 read by run-2pb --rig-state)",
        description="Compute once per sample what its 2PB jobs share: the spheres the bond network holds "
        "(asphalt_nscd.harmonic.solver.held_spheres) and, with gravity, the solution U_1 of the "
        "reference stiffness under the weights (asphalt_nscd.harmonic.periodic.gravity_unit), under "
        "the --config test settings (bond kinematics, head rotation, nu, gravity, mechanisms), with "
        "the sample file's SHA-256 (asphalt_nscd.campaign.twopb.write_rig_state). Neither depends on "
        "the law, T, f or dt.",
    )
    p.add_argument("--sample", required=True, help="sample file (.h5)")
    _settings_options(p)
    p.add_argument("-o", "--output", required=True, help="rig-state file (.h5)")
    p.set_defaults(func=_rig_state)


def _rig_state(args) -> int:
    from .twopb import write_rig_state

    write_rig_state(args.sample, _settings(args), args.output)
    return 0


def _add_run_2pb(subparsers) -> None:
    """``run-2pb``: one numerical 2PB complex modulus test (record + reduced row)."""
    p = subparsers.add_parser(
        "run-2pb",
        help="one numerical 2PB complex modulus test (record + reduced row)",
        description="Run (or resume from its checkpoint) the numerical 2PB test of a sample "
        "at one temperature and frequency, write the record (HDF5) and the row reduced by "
        "EN 12697-26 Eqs. 1-5 (CSV).",
    )
    p.add_argument("--sample", required=True, help="sample file (.h5)")
    p.add_argument("--sample-name", default=None, help="sample name for the row (default: file stem)")
    p.add_argument("--mode", default="paper", help="label of the parameter set (paper, measured, extended, ...)")
    _parameter_options(p, law_json=True)
    p.add_argument("--temperature", type=float, required=True, help="temperature, degC")
    p.add_argument("--frequency", type=float, required=True, help="loading frequency, Hz")
    p.add_argument(
        "--factor",
        action="append",
        default=[],
        metavar="NAME=X",
        help="multiply a Burger's parameter (Em, eta_m, Ek, eta_k) by X; repeatable (not with --law-json)",
    )
    p.add_argument("--dt", type=float, default=None, help="fixed time step, s (overrides the dt policy)")
    p.add_argument(
        "--network-factor-json",
        default=None,
        metavar="PATH",
        help="transfer correction: divide every modulus and viscosity of the bond law by the "
        "sample's network factor NF_s read from PATH (output of 'asphalt-nscd "
        "harmonic-transfer', e.g. results/harmonic/transfer/s1.json; its sample, "
        "bond_kinematics, head_rotation and nu must match the run), so that the "
        "inertia-free sample modulus equals the macro law (asphalt_nscd.harmonic.transfer)",
    )
    p.add_argument(
        "--rig-state",
        default=None,
        metavar="PATH",
        help="the sample's rig-state file (output of 'asphalt-nscd rig-state': held spheres and the "
        "law-free gravity solution; its sample file SHA-256 and settings must match the job's); "
        "default: the job computes both itself",
    )
    _settings_options(p)
    p.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="progress bar on stderr (the job log)"
    )
    p.add_argument(
        "--verify",
        action="store_true",
        help="a verification job: step in time whatever the settings' method says, and record the "
        "exact periodic orbit's result beside (asphalt_nscd.harmonic.orbit)",
    )
    p.add_argument("-o", "--output", required=True, help="record (.h5)")
    p.add_argument("--row", required=True, help="reduced row (.csv)")
    p.set_defaults(func=_run, config_values=_config_values)


def _add_campaign_isotherms(subparsers) -> None:
    """``campaign-isotherms``: numerical isotherms, Table 4 analogue, Figs. 9-10."""
    p = subparsers.add_parser("campaign-isotherms", help="numerical isotherms, Table 4 analogue, Figs. 9-10")
    p.add_argument("--rows", nargs="+", required=True, help="reduced rows (CSV) of one mode")
    _parameter_options(p, law_json=True)
    p.add_argument(
        "--measured-summary",
        default=None,
        help="measured means per (T, f) (results/lab/measured_summary.csv); default reference: "
        "the model isotherms of --parameters (or --law-json)",
    )
    p.add_argument("--paper-table4", default=None, help="the paper's Table 4 to show beside (paper mode)")
    p.add_argument("--fmin", type=float, default=0.05, help="lowest frequency of the model curves, Hz")
    p.add_argument("--fmax", type=float, default=50.0, help="highest frequency of the model curves, Hz")
    p.add_argument("--isotherms", required=True, help="output numerical isotherms CSV")
    p.add_argument("--table4", required=True, help="output Table 4 analogue CSV")
    p.add_argument("--figure-modulus", required=True, help="Fig. 9 analogue (png)")
    p.add_argument("--figure-phase", required=True, help="Fig. 10 analogue (png)")
    p.add_argument("--title", default="", help="figure title (with --config: the mode's)")
    p.add_argument(
        "--mode",
        default="paper",
        help="the campaign mode of the rows: with --config, its Table 3 reading and the title",
    )
    from ..config import config_option

    config_option(p, _config_values, "the mode's Table 3 reading (calibration.table3_units for paper)")
    p.set_defaults(func=_isotherms)


def _add_campaign_dt_study(subparsers) -> None:
    """``campaign-dt-study``: Fig. 6 analogue: influence of the time step."""
    p = subparsers.add_parser("campaign-dt-study", help="Fig. 6 analogue: influence of the time step")
    p.add_argument("--records", nargs="+", required=True, help="records (.h5) at several dt")
    p.add_argument("--rows", nargs="+", required=True, help="their reduced rows (CSV)")
    _parameter_options(p)
    p.add_argument("--table", required=True, help="output CSV")
    p.add_argument("--figure", required=True, help="output png")
    from ..config import config_option

    config_option(p, _config_values, "calibration.table3_units")
    p.set_defaults(func=_dt_study)


def _add_campaign_last_cycle(subparsers) -> None:
    """``campaign-last-cycle``: Figs. 7-8 analogues from one record."""
    p = subparsers.add_parser("campaign-last-cycle", help="Figs. 7-8 analogues from one record")
    p.add_argument("--record", required=True, help="record (.h5)")
    p.add_argument("--figure-cycle", required=True, help="Fig. 7 analogue (png)")
    p.add_argument("--figure-profile", required=True, help="Fig. 8 analogue (png)")
    p.set_defaults(func=_last_cycle)


def _add_campaign_sensitivity(subparsers) -> None:
    """``campaign-sensitivity``: sensitivity table and Figs. 11-14 analogues."""
    p = subparsers.add_parser("campaign-sensitivity", help="sensitivity table and Figs. 11-14 analogues")
    p.add_argument("--rows", nargs="+", required=True, help="reduced rows of the varied runs (CSV)")
    p.add_argument("--baseline", nargs="+", required=True, help="reduced rows of the unvaried runs (CSV)")
    _parameter_options(p)
    p.add_argument("--temperature", type=float, default=20.0, help="temperature, degC")
    p.add_argument("--table", required=True, help="output CSV")
    p.add_argument(
        "--figures",
        nargs=4,
        required=True,
        metavar="PNG",
        help="figures for Em, eta_m, Ek, eta_k (Figs. 11-14 analogues)",
    )
    from ..config import config_option

    config_option(p, _config_values, "calibration.table3_units and campaign.sensitivity.temperature_C")
    p.set_defaults(func=_sensitivity)


def _add_campaign_units(subparsers) -> None:
    """``campaign-units``: the Table 3 units question, both readings."""
    p = subparsers.add_parser("campaign-units", help="the Table 3 units question, both readings")
    p.add_argument("--table3", required=True, help="the paper's Table 3 as printed")
    p.add_argument("--rows-pa", nargs="+", required=True, help="reduced rows of the Pa-reading runs")
    p.add_argument("--rows-kpa", nargs="+", required=True, help="reduced rows of the kPa-reading runs")
    p.add_argument(
        "--rows-kpa-nobreak",
        nargs="+",
        default=None,
        help="reduced rows of the kPa-reading runs with unbreakable bonds",
    )
    p.add_argument("--sample", required=True, help="sample file of the runs (.h5)")
    p.add_argument(
        "--temperature", type=float, default=None, help="temperature of the runs, degC (required without --config)"
    )
    p.add_argument("--grain-mass-kg", type=float, default=2.86e-5, help="typical grain mass m_g, kg")
    p.add_argument("--r-min-mm", type=float, default=1.0, help="r_min of the representative bond, mm")
    p.add_argument("--l0-mm", type=float, default=2.0, help="l0 of the representative bond, mm")
    p.add_argument("-o", "--output", required=True, help="output CSV")
    p.add_argument(
        "--evidence",
        default=None,
        help="also write the paper's internal evidence on the unit of Table 3, computed under each "
        "reading (CSV; asphalt_nscd.campaign.study.reading_evidence)",
    )
    p.add_argument(
        "--measured-summary",
        default=None,
        help="measured summary (MPa) whose |E*| at the temperature and 10 Hz is the mix the moduli are "
        "compared with (--evidence; default: 5-30 GPa of dense mixes)",
    )
    from ..config import config_option

    config_option(p, _config_values, "campaign.units_question.temperature_C and the first bond of calibration.micro")
    p.set_defaults(func=_units)


def _add_campaign_dt_policy(subparsers) -> None:
    """``campaign-dt-policy``: phase error of the dt policy (one bond)."""
    p = subparsers.add_parser("campaign-dt-policy", help="phase error of the dt policy (one bond)")
    _parameter_options(p)
    p.add_argument(
        "--temperature",
        type=float,
        default=None,
        help="temperature, degC (with --config: the upper median of the mode's schedule)",
    )
    p.add_argument(
        "--frequencies",
        type=float,
        nargs="+",
        default=None,
        help="frequencies, Hz (with --config: the mode's schedule)",
    )
    _settings_options(p)
    p.add_argument("-o", "--output", required=True, help="output CSV")
    p.set_defaults(func=_dt_policy, config_values=_config_values)


def _add_campaign_bench(subparsers) -> None:
    """``campaign-bench``: time per step of the 2PB test and projected campaign time."""
    p = subparsers.add_parser(
        "campaign-bench",
        help="time per step of the 2PB test and projected campaign time",
        description="Time the 2PB test on a sample file or a bonded lattice sample and "
        "project the total time of the campaign of a config file (JSON output).",
    )
    p.add_argument("--sample", default=None, help="sample file (.h5); default: a lattice sample of --n-spheres")
    p.add_argument("--n-spheres", type=int, default=2000, help="spheres of the lattice sample")
    p.add_argument("--steps", type=int, default=200, help="timed steps")
    p.add_argument(
        "--config",
        action="append",
        default=[],
        help="workflow config (YAML) whose campaign is projected, merged over config/config.yaml "
        "of the working directory as Snakemake merges --configfile (e.g. config/paper.yaml, "
        "an overlay on it); repeatable, one projection each",
    )
    p.add_argument("--overhead-s", type=float, default=3.0, help="start-up time of one job, s")
    p.add_argument(
        "--per-job",
        action="store_true",
        help="time every job class (mode, T, f, dt) of each --config on --sample with the job's "
        "law, from rest and from the periodic start where configured (needs the law files)",
    )
    p.add_argument("--job-steps", type=int, default=10, help="timed steps per job class and start (--per-job)")
    p.add_argument(
        "--job-warmup",
        type=int,
        default=2,
        help="untimed steps before them (--per-job): numba compilation, and the one-time work of "
        "a job such as the response columns of the contacts of the fast path",
    )
    p.add_argument(
        "--modes", nargs="+", default=None, help="time and project only these modes' jobs (--per-job; e.g. paper)"
    )
    p.add_argument(
        "--baseline-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a test setting (key of TwoPBSettings, VALUE read as YAML) of a baseline timed in the "
        "same run, alternating with the configured ones (--per-job; e.g. fast_path_contacts=0); "
        "repeatable: adds s_per_step_baseline and speedup to each job class",
    )
    p.add_argument("--table3", default="data/paper/table3_burgers.csv", help="the paper's Table 3 (--per-job)")
    p.add_argument(
        "--parameters",
        default="results/calibration/burgers_parameters.csv",
        help="calibrated Burger's table, measured mode (--per-job)",
    )
    p.add_argument(
        "--law-json",
        default="results/diagnosis/generalized_burgers.json",
        help="generalized Burger's law JSON, extended mode (--per-job)",
    )
    p.add_argument(
        "--network-factor-json",
        default=None,
        help="transfer JSON of --sample, extended mode (--per-job; default: no correction)",
    )
    prep = p.add_mutually_exclusive_group()
    prep.add_argument(
        "--prepare-seconds",
        type=float,
        default=0.0,
        help="preparation time of one sample, s (added once per sample of the config)",
    )
    prep.add_argument(
        "--prepare-json",
        default=None,
        help="JSON holding the preparation time of one sample, s (e.g. the sample summary of "
        "prepare-sample, or a prepare-bench output) at --prepare-key",
    )
    p.add_argument(
        "--prepare-key", default="timings_s.total_s", help="dotted key of the preparation time in --prepare-json"
    )
    p.add_argument("-o", "--output", required=True, help="output JSON")
    p.set_defaults(func=_bench)


def _add_bench(subparsers) -> None:
    """``asphalt-nscd bench``: one benchmark of the NSCD core (:mod:`asphalt_nscd.nscd.bench`),
    its JSON record; the bonded case starts at rest or in the periodic steady state."""
    from ..nscd.state import BOND_KINEMATICS, BONDED_CONTACT

    b = subparsers.add_parser("bench", help="NSCD core benchmark (JSON)")
    b.add_argument("--case", required=True, choices=["bonded", "granular"])
    b.add_argument("--n", type=int, required=True, help="number of spheres")
    b.add_argument("--steps", type=int, default=20, help="timed steps")
    b.add_argument(
        "--baseline-steps",
        type=int,
        default=3,
        help="timed NLGS steps of the bonded baseline (default 3, config nscd.bench)",
    )
    b.add_argument("--tolerance", type=float, default=1e-7, help="NLGS tolerance")
    b.add_argument("--settle-steps", type=int, default=5000, help="most untimed settling steps of the granular case")
    b.add_argument(
        "--settle-speed",
        type=float,
        default=5e-3,
        help="granular settling ends when the largest sphere speed (m/s) is below",
    )
    b.add_argument(
        "--threads", type=int, default=1, help="numba threads of the parallel kernels (NSCDParameters.threads)"
    )
    b.add_argument("--seed", type=int, default=0)
    b.add_argument(
        "--linear-tolerance", type=float, default=1e-7, help="relative residual of the conjugate gradient (bonded case)"
    )
    b.add_argument(
        "--bond-kinematics",
        choices=list(BOND_KINEMATICS),
        default="contact",
        help="where the bonds act (bonded case; NSCDParameters.bond_kinematics)",
    )
    b.add_argument(
        "--linear-solver",
        choices=["cg", "cg_ssor"],
        default="cg",
        help="conjugate gradient of the bonded case: block-Jacobi (cg) or SSOR "
        "(cg_ssor, also times cg on the same steps)",
    )
    b.add_argument(
        "--bonded-contact",
        choices=list(BONDED_CONTACT),
        default="after_break",
        help="contact of the bonded pairs (bonded case; NSCDParameters.bonded_contact)",
    )
    b.add_argument(
        "--start",
        choices=["rest", "periodic"],
        default="rest",
        help="bonded case: from rest under gravity, or in the periodic steady state without gravity (the 2PB setting)",
    )
    b.add_argument(
        "--ssor-omega",
        type=float,
        default=None,
        help="relaxation factor of cg_ssor in (0, 2) (default: NSCDParameters')",
    )
    b.add_argument("-o", "--output", required=True, help="JSON record")
    from ..nscd.cli import config_option

    config_option(b)
    b.set_defaults(func=_core_bench)


def _core_bench(args) -> int:
    from ..io import write_json
    from ..nscd.bench import run_bench
    from .bench import bench_starter

    rec = run_bench(
        args.case,
        args.n,
        steps=args.steps,
        baseline_steps=args.baseline_steps,
        tolerance=args.tolerance,
        settle_steps=args.settle_steps,
        seed=args.seed,
        linear_tolerance=args.linear_tolerance,
        bond_kinematics=args.bond_kinematics,
        threads=args.threads,
        settle_speed=args.settle_speed,
        linear_solver=args.linear_solver,
        bonded_contact=args.bonded_contact,
        start=args.start,
        ssor_omega=args.ssor_omega,
        starter=bench_starter,
    )
    write_json(rec, args.output)
    return 0


def _add_periodic_check(subparsers) -> None:
    """``periodic-check``: periodic start vs from-rest protocol of the 2PB test (table)."""
    p = subparsers.add_parser(
        "periodic-check",
        help="periodic start vs from-rest protocol of the 2PB test (table)",
        description="For each case MODE:T:F run the 2PB test of the sample from rest for --long-cycles "
        "cycles (the reference; its first n_cycles are the paper's protocol) and from the periodic steady "
        "state (campaign.test.periodic_cycles), reduce each last cycle and tabulate |E*|, Phi, their "
        "differences, steps and solver iterations (asphalt_nscd.campaign.periodic.check_case).",
    )
    p.add_argument("--sample", required=True, help="sample file (.h5)")
    p.add_argument(
        "--cases",
        nargs="+",
        required=True,
        metavar="MODE:T:F",
        help="mode (paper, measured, extended, dt_study, sensitivity, units_Pa, units_kPa, "
        "units_kPa_nobreak; its law and test settings), temperature degC, frequency Hz",
    )
    p.add_argument(
        "--config",
        nargs="+",
        default=None,
        metavar="FILE",
        help="workflow config files (YAML) merged as Snakemake merges --configfile: "
        "config/config.yaml of the working directory first, then each FILE in order (e.g. "
        "config/paper.yaml, an overlay on it); the jobs' test settings per mode (campaign "
        "section, nscd.bond_kinematics, lab.simulation_window_cycles); default: TwoPBSettings' own values",
    )
    _settings_options(p, config=False)
    p.add_argument(
        "--table3",
        default="data/paper/table3_burgers.csv",
        help="the paper's Table 3 as printed (paper mode and studies)",
    )
    p.add_argument(
        "--table3-units",
        choices=("Pa", "kPa"),
        default=None,
        help="reading of --table3 for the paper mode (default: the config's calibration.table3_units, else Pa)",
    )
    p.add_argument("--parameters", default=None, help="calibrated Burger's table (MPa; measured mode)")
    p.add_argument("--law-json", default=None, help="generalized Burger's law JSON (extended mode)")
    p.add_argument(
        "--network-factor-json",
        default=None,
        help="transfer JSON of the sample (extended mode with the transfer correction)",
    )
    p.add_argument("--long-cycles", type=int, default=20, help="cycles of the from-rest reference run")
    p.add_argument(
        "--continuous",
        action="store_true",
        help="also start from the continuous steady state (s = i w) to measure the discrete correction",
    )
    p.add_argument("--cycles-table", default=None, help="output CSV of every from-rest cycle's |E*| and Phi")
    p.add_argument("-o", "--output", required=True, help="output CSV (one row per case)")
    p.set_defaults(func=_periodic_check)


def _periodic_check(args) -> int:
    import dataclasses
    import sys
    from pathlib import Path

    import pandas as pd

    from ..io import InputError, write_csv
    from . import periodic, study, twopb

    cfg = twopb.read_config(args.config) if args.config else None
    name = Path(args.sample).stem
    units = args.table3_units or (cfg or {}).get("calibration", {}).get("table3_units", "Pa")
    laws = study.JobLaws(
        table3=args.table3,
        table3_units=units,
        parameters=args.parameters,
        law_json=args.law_json,
        network_factor_json=args.network_factor_json,
        sample_name=name,
    )
    rows, cycles = [], []
    for case in args.cases:
        parts = case.split(":")
        try:
            mode, T, f = parts[0], float(parts[1]), float(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            raise InputError(f"--cases {case!r}: expected MODE:T:F (e.g. measured:54:0.1)") from None
        base = twopb.job_settings(cfg, mode) if cfg is not None else {}
        settings = _settings(args, base)
        law = laws.law(mode, T)
        meta = {
            "mode": mode,
            "sample": name,
            "temperature_C": T,
            "n_kelvin": law.n_kelvin,
            "start_config": settings.start,
        }
        print(f"periodic-check {case}", flush=True, file=sys.stderr)
        row, cyc = periodic.check_case(
            args.sample,
            law,
            f,
            dataclasses.replace(settings, start="periodic"),
            long_cycles=args.long_cycles,
            continuous=args.continuous,
            meta=meta,
        )
        rows.append(row)
        cycles += cyc
    write_csv(pd.DataFrame(rows), args.output)
    if args.cycles_table:
        write_csv(pd.DataFrame(cycles), args.cycles_table)
    return 0


def _overrides(items: list[str], option: str) -> dict:
    """The settings of ``KEY=VALUE`` items (VALUE read as YAML: 3, 1e-5, rest, null, true).

    Raises
    ------
    InputError
        naming ``option`` and the item that is not KEY=VALUE or whose VALUE is not YAML.
    """
    import yaml

    from ..io import InputError

    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        try:
            if not sep or not key.strip():
                raise ValueError("expected KEY=VALUE")
            out[key.strip()] = yaml.safe_load(text)
        except (ValueError, yaml.YAMLError) as exc:
            raise InputError(f"{option} {item!r}: {exc}") from None
    return out


def _settings(args, base: dict | None = None):
    """TwoPBSettings from ``base`` (e.g. a mode's config settings; default: those of --config
    and --settings-mode, else TwoPBSettings' own values) updated by each --set KEY=VALUE and by
    --window-cycles.

    Raises
    ------
    InputError
        naming the config file and key the schemas refuse, or the --set item that is not
        KEY=VALUE, not YAML, or not a setting.
    """
    from .. import config
    from .twopb import job_settings, settings_from

    if base is None and getattr(args, "config", None):
        mode = args.settings_mode or getattr(args, "mode", None) or "paper"
        base = job_settings(config.checked(args.config), mode)
    cfg = {**(base or {}), **_overrides(args.set, "--set")}
    if getattr(args, "window_cycles", None) is not None:
        cfg["window_cycles"] = args.window_cycles
    return settings_from(cfg)


def _read_rows(paths):
    import pandas as pd

    from ..io import read_csv

    return pd.concat([read_csv(p) for p in paths], ignore_index=True)


def _run(args) -> int:
    import dataclasses
    from pathlib import Path

    import pandas as pd

    from ..io import InputError, write_csv
    from ..rheology.calibration import burgers_model
    from . import study, twopb

    settings = _settings(args)
    if args.dt is not None:  # the job's dt on every path (a time-step study)
        settings = dataclasses.replace(settings, dt_policy="fixed", dt_s=args.dt, time_domain_steps_per_cycle=None)
    factors = {}
    for item in args.factor:
        name, _, value = item.partition("=")
        try:
            factors[name] = float(value)
        except ValueError:
            raise InputError(f"--factor {item!r}: expected NAME=number") from None
    if args.law_json is not None:
        if factors or args.table3_units:
            raise InputError("--law-json: --factor and --table3-units apply to a Burger's --parameters table only")
        from ..rheology import law_file

        law = law_file.law_at(law_file.read(args.law_json), args.temperature, where=args.law_json)
        params = {**study.law_summary(law), "law_json": str(args.law_json)}
    else:
        table = study.parameter_table(args.parameters, args.table3_units)
        params = study.parameters_at(table, args.temperature, factors, where=args.parameters)
        law = burgers_model(params)
    name = args.sample_name or Path(args.sample).stem
    if args.network_factor_json is not None:
        from ..harmonic.transfer import corrected_law

        law, nf = corrected_law(
            law,
            args.network_factor_json,
            sample=name,
            bond_kinematics=settings.bond_kinematics,
            head_rotation=settings.head_rotation,
            nu=settings.nu,
        )
        params = {**params, "transfer_network_factor": nf, "transfer_json": str(args.network_factor_json)}
    meta = {
        "mode": args.mode,
        "sample": name,
        "temperature_C": args.temperature,
        "table3_units": args.table3_units or "",
        "variant": ";".join(args.factor) or "base",
        "parameter": ";".join(f.partition("=")[0] for f in args.factor) or "",
        "factor": float(next(iter(factors.values()))) if len(factors) == 1 else 1.0,
        **{k: v for k, v in params.items()},
    }
    rec = twopb.run_test(
        args.sample,
        law,
        args.frequency,
        settings,
        args.output,
        meta=meta,
        progress=args.progress,
        verify=args.verify,
        rig_state=args.rig_state,
    )
    row = twopb.reduce_test(rec, settings.window_cycles)
    row.update({k: v for k, v in params.items()})
    first = ["temperature_C", "frequency_Hz", "sample", "mode"]
    frame = pd.DataFrame([row])
    write_csv(frame[first + [c for c in frame.columns if c not in first]], args.row)
    return 0


def _isotherms(args) -> int:
    import numpy as np
    import pandas as pd

    from ..io import savefig, write_csv
    from ..rheology.calibration import burgers_curves
    from . import figures, study

    rows = _read_rows(args.rows)
    temps = sorted(rows["temperature_C"].unique())
    freqs = np.geomspace(args.fmin, args.fmax, 61)
    if args.law_json is not None:
        from ..rheology import law_file

        laws = law_file.read(args.law_json)
        curves = study.law_curves(laws, temps, freqs, where=args.law_json)
        model = "generalized Burger's law"
    else:
        table = study.parameter_table(args.parameters, args.table3_units)
        curves = burgers_curves(table[table["temperature_C"].isin(temps)], freqs)
        model = "Burger's"
    points = None
    if args.measured_summary:
        from ..lab.measured import read_summary

        summary = read_summary(args.measured_summary)
        ref = study.measured_reference(summary)
        points = summary[summary["temperature_C"].isin(temps)]
        label = "measured (mean ± sd)"
    elif args.law_json is not None:
        ref = study.law_reference(
            laws, rows["temperature_C"], rows["frequency_Hz"], where=args.law_json
        ).drop_duplicates()
        label = model
    else:
        ref = study.burgers_reference(table, rows["temperature_C"], rows["frequency_Hz"]).drop_duplicates()
        label = "Burger's (Table 3)"
    iso = study.numerical_isotherms(rows, ref)
    write_csv(iso, args.isotherms)
    paper4 = pd.read_csv(args.paper_table4) if args.paper_table4 else None
    write_csv(study.table4(iso, paper4), args.table4)
    fm, fp = figures.isotherm_figures(
        iso,
        curves,
        label,
        reference_points=points,
        title=args.title,
        curve_label=f"{model} model" if args.law_json is None else f"{model} (law JSON)",
    )
    savefig(fm, args.figure_modulus)
    savefig(fp, args.figure_phase)
    return 0


def _dt_study(args) -> int:
    from ..io import savefig, write_csv
    from . import figures, study, twopb

    rows = _read_rows(args.rows)
    recs = [twopb.read_record(p) for p in args.records]
    table = study.parameter_table(args.parameters, args.table3_units)
    T, f = float(rows["temperature_C"].iloc[0]), float(rows["frequency_Hz"].iloc[0])
    ref = study.burgers_reference(table, [T], [f]).iloc[0]
    rows = rows.assign(E_norm_MPa_ref=ref["E_norm_MPa_ref"], phase_deg_ref=ref["phase_deg_ref"])
    keep = [
        "temperature_C",
        "frequency_Hz",
        "sample",
        "dt_s",
        "n_steps",
        "E_norm_MPa",
        "phase_deg",
        "E_norm_MPa_other_reading",
        "phase_deg_other_reading",
        "E_norm_MPa_ref",
        "phase_deg_ref",
        "n_nlgs_steps",
        "wall_time_s",
        "cpu_per_sphere_step_s",
    ]
    write_csv(rows[keep].sort_values(["sample", "dt_s"]), args.table)
    fig = figures.dt_study_figure(recs, rows, (ref["E_norm_MPa_ref"], ref["phase_deg_ref"]))
    savefig(fig, args.figure)
    return 0


def _last_cycle(args) -> int:
    from ..io import savefig
    from . import figures, twopb

    rec = twopb.read_record(args.record)
    savefig(figures.last_cycle_figure(rec), args.figure_cycle)
    savefig(figures.velocity_profile_figure(rec), args.figure_profile)
    return 0


def _sensitivity(args) -> int:
    import numpy as np

    from ..io import savefig, write_csv
    from ..rheology.calibration import burgers_isotherm
    from . import figures, study

    rows = _read_rows(args.rows)
    base = _read_rows(args.baseline)
    table = study.sensitivity_table(rows, base)
    tab = study.parameter_table(args.parameters, args.table3_units)
    f = np.geomspace(max(0.5 * table["frequency_Hz"].min(), 0.05), 2 * table["frequency_Hz"].max(), 41)
    write_csv(table, args.table)
    for name, path in zip(study.SENSITIVITY_PARAMETERS, args.figures):
        curves = {}
        for fac in table[table["parameter"] == name]["factor"].unique():
            e, p = burgers_isotherm(study.parameters_at(tab, args.temperature, {name: fac}), f)
            curves[fac] = {"frequency_Hz": f, "E_norm_MPa": e, "phase_deg": p}
        savefig(figures.sensitivity_figure(table, name, curves, args.temperature), path)
    return 0


def _units(args) -> int:
    from ..io import write_csv
    from ..sample.store import read_sample
    from . import study

    if args.temperature is None:
        from ..io import InputError

        raise InputError("campaign-units: give --temperature, or --config")
    micro = {"grain_mass_kg": args.grain_mass_kg, "r_min_mm": [args.r_min_mm], "l0_mm": [args.l0_mm]}
    rows = {"Pa": _read_rows(args.rows_pa), "kPa": _read_rows(args.rows_kpa)}
    if args.rows_kpa_nobreak:
        rows["kPa (unbreakable bonds)"] = _read_rows(args.rows_kpa_nobreak)
    out = study.units_question(args.table3, rows, read_sample(args.sample), args.temperature, micro)
    write_csv(out, args.output)
    if args.evidence:
        from ..lab.measured import read_summary

        mix = None
        if args.measured_summary:
            mix = study.mix_modulus_at(
                read_summary(args.measured_summary), args.temperature, float(out["reference_frequency_Hz"].iloc[0])
            )
        write_csv(study.reading_evidence(out, mix), args.evidence)
    return 0


def _dt_policy(args) -> int:
    from ..io import write_csv
    from . import study

    if args.temperature is None or not args.frequencies:
        from ..io import InputError

        raise InputError("campaign-dt-policy: give --temperature and --frequencies, or --config")
    table = study.parameter_table(args.parameters, args.table3_units)
    out = study.dt_policy_phase_table(table, args.temperature, args.frequencies, _settings(args))
    write_csv(out, args.output)
    return 0


def _prepare_seconds(args) -> float:
    """Preparation time of one sample, s: --prepare-seconds or the number at --prepare-key in
    --prepare-json."""
    from ..io import InputError
    from .bench import read_prepare_seconds

    if args.prepare_json is None:
        if args.prepare_seconds < 0:
            raise InputError(f"--prepare-seconds must be >= 0, got {args.prepare_seconds}")
        return float(args.prepare_seconds)
    return read_prepare_seconds(args.prepare_json, args.prepare_key)


def _bench(args) -> int:
    from pathlib import Path

    from ..io import InputError, write_json
    from . import bench, study, twopb

    if args.per_job and args.sample is None:
        raise InputError("campaign-bench --per-job needs --sample (a prepared sample file)")
    prepare_s = _prepare_seconds(args)
    baseline = _overrides(args.baseline_set, "--baseline-set") or None
    if baseline is not None:
        unknown = sorted(set(baseline) - set(twopb.TwoPBSettings.__dataclass_fields__))
        if unknown:
            raise InputError(f"--baseline-set: unknown setting(s) {unknown}; expected keys of TwoPBSettings")
        if not args.per_job:
            raise InputError("--baseline-set needs --per-job")
    cost = bench.measure_step_cost(args.sample, n_spheres=args.n_spheres, n_steps=args.steps)
    out: dict[str, Any] = {"measurement": cost, "prepare_s_per_sample": prepare_s, "projections": {}}
    for path in args.config:
        cfg = twopb.read_config(path)
        camp = cfg["campaign"]
        kin = cfg.get("nscd", {}).get("bond_kinematics", "contact")
        n_total = len(cfg.get("sample", {}).get("seeds", [1]))
        common = dict(overhead_s=args.overhead_s, bond_kinematics=kin, prepare_s_per_sample=prepare_s)
        single = {
            start or "configured": bench.project_campaign(camp, n_total, cost["s_per_step"], start=start, **common)
            for start in (None, "rest")
        }
        if not args.per_job:
            out["projections"][path] = single
            continue
        laws = study.JobLaws(
            table3=args.table3,
            table3_units=cfg.get("calibration", {}).get("table3_units", "Pa"),
            parameters=args.parameters,
            law_json=args.law_json,
            network_factor_json=args.network_factor_json,
            sample_name=Path(args.sample).stem,
        )
        jobs = bench.campaign_jobs(camp, n_total, bond_kinematics=kin)
        if args.modes:
            missing = set(args.modes) - {j["mode"] for j in jobs}
            if missing:
                raise InputError(
                    f"--modes {sorted(missing)}: no such jobs in {path} (modes: {sorted({j['mode'] for j in jobs})})"
                )
            jobs = [j for j in jobs if j["mode"] in args.modes]
        if args.job_steps < 1 or args.job_warmup < 0:
            raise InputError(
                f"--job-steps must be >= 1 and --job-warmup >= 0, got {args.job_steps} and {args.job_warmup}"
            )
        costs = bench.measure_job_costs(
            args.sample,
            camp,
            jobs,
            laws,
            n_steps=args.job_steps,
            warmup=args.job_warmup,
            bond_kinematics=kin,
            linear_solver=cfg.get("nscd", {}).get("linear_solver", "cg"),
            linear_tolerance=cfg.get("nscd", {}).get("linear_tolerance"),
            baseline=baseline,
        )

        def per_step(job, costs=costs):
            return costs[bench.job_class(job)][job["start"]]["s_per_step"]

        def solve(job, costs=costs):
            return costs[bench.job_class(job)]["periodic"]["solve_s"]

        out["projections"][path] = {
            start or "configured": bench.project_campaign(
                camp, n_total, per_step, start=start, periodic_solve_s=solve, modes=args.modes, **common
            )
            for start in (None, "rest")
        }
        out["projections"][path]["single_law"] = single
        out["projections"][path]["job_costs"] = [
            {"mode": k[0], "temperature_C": k[1], "frequency_Hz": k[2], "dt_s": k[3], "start": start, **v}
            for k, by_start in costs.items()
            for start, v in by_start.items()
        ]
    write_json(out, args.output)
    return 0
