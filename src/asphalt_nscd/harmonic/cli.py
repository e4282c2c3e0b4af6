"""Subcommands of the harmonic step (registered by asphalt_nscd.cli).

* ``harmonic``               — steady-state |E*|, Phi of a sample per (T, f) (Eqs. 1-5).
* ``harmonic-compare``       — harmonic vs NSCD time-domain per (T, f, dt) and solver rtol.
* ``harmonic-sensitivity``   — Burger's parameters at +-p % (Section 4.2, finer grid).
* ``harmonic-network-factor``— sample |E*| / macro |E*| and phase difference tables.
* ``harmonic-plot``          — isotherms, Black diagram, Cole-Cole: macro, sample, measured.
* ``harmonic-kinematics``    — network factor per (bond kinematics, head rotation, T, f).
* ``harmonic-transfer``      — network factor NF_s of a sample (no inertia, law independent):
                               the transfer JSON of ``run-2pb --network-factor-json``.
* ``harmonic-resolution``    — network factor against the samples' resolution (levels, seeds).
* ``harmonic-bench``         — timing and peak memory on an N-sphere sample (JSON).

``--bond-kinematics contact|barycentre`` and ``--head-rotation free|clamped`` select the
model of :mod:`asphalt_nscd.harmonic.solver` (default contact + free, also the NSCD core's
default; ``harmonic-compare`` passes the same options to the time-domain core).
"""

from __future__ import annotations

from pathlib import Path

from ..nscd.state import BOND_KINEMATICS, HEAD_AMPLITUDE_M, HEAD_ROTATIONS
from ..rheology.laws import POISSON_RATIO


def _add_kinematics_options(p, bond_kinematics: str = "contact", head_rotation: str = "free") -> None:
    p.add_argument(
        "--bond-kinematics",
        choices=list(BOND_KINEMATICS),
        default=bond_kinematics,
        help="contact: 6 DOF per sphere, bond acting at the contact point (torques); "
        "barycentre: 3 DOF per sphere, bond at the barycentres (the NSCD core) "
        f"(default {bond_kinematics}; see asphalt_nscd.harmonic.solver)",
    )
    p.add_argument(
        "--head-rotation",
        choices=list(HEAD_ROTATIONS),
        default=head_rotation,
        help="free: the head plate rotates under the bond moments (cantilever of "
        f"Eq. 3); clamped: it only translates (default {head_rotation})",
    )


def _add_law_options(
    p, temperature_required: bool = False, bond_kinematics: str = "contact", head_rotation: str = "free"
) -> None:
    p.add_argument("--sample", type=Path, required=True, help="sample file results/samples/<s>.h5")
    p.add_argument(
        "--parameters",
        type=Path,
        required=True,
        help="Burger's parameters CSV: temperature_C, Em_MPa, eta_m_MPa_s, Ek_MPa, "
        "eta_k_MPa_s (e.g. results/calibration/paper_table3.csv)",
    )
    p.add_argument(
        "--temperature",
        type=float,
        nargs="+" if not temperature_required else 1,
        default=[],
        help="temperature, degC (required without --config)"
        if temperature_required
        else "temperatures, degC (default: every row of --parameters)",
    )
    p.add_argument(
        "--amplitude-m", type=float, default=HEAD_AMPLITUDE_M, help=f"head amplitude A, m ({HEAD_AMPLITUDE_M})"
    )
    p.add_argument("--nu", type=float, default=POISSON_RATIO, help=f"Poisson's ratio of Eqs. 8-11 ({POISSON_RATIO})")
    _add_kinematics_options(p, bond_kinematics, head_rotation)


def config_values(cfg, args) -> dict:
    """Option values of this step's commands from a merged, checked workflow config
    (``--config``; an option given on the command line wins): the ``harmonic`` section, and for
    the commands that check or correct the time-domain test (harmonic-compare,
    harmonic-transfer, harmonic-resolution) that test's kinematics (``nscd.bond_kinematics``,
    ``campaign.test.head_rotation``, ``campaign.test.nu``). ``harmonic --grid paper|sweep``
    takes its frequencies from ``harmonic.paper_frequencies_Hz`` or ``harmonic.sweep``."""
    from ..sample import rig

    harm = cfg["harmonic"]
    solver = {"inertia": harm["inertia"], "solver": harm["solver"], "rtol": float(harm["rtol"])}
    kinematics = {"bond_kinematics": harm["bond_kinematics"], "head_rotation": harm["head_rotation"]}
    time_domain = rig.kinematics(cfg)
    command = args.command
    if command == "harmonic":
        out = {**solver, **kinematics}
        if getattr(args, "grid", None) == "paper":
            out["frequency"] = [float(f) for f in harm["paper_frequencies_Hz"]]
        elif getattr(args, "grid", None) == "sweep":
            sweep = harm["sweep"]
            out["sweep"] = [float(sweep["fmin_Hz"]), float(sweep["fmax_Hz"]), float(sweep["points"])]
        return out
    if command == "harmonic-sensitivity":
        sens = harm["sensitivity"]
        return {
            "temperature": [float(sens["temperature_C"])],
            "frequency": [float(f) for f in sens["frequencies_Hz"]],
            "levels": [float(x) for x in sens["levels_percent"]],
            "inertia": harm["inertia"],
            **kinematics,
        }
    if command == "harmonic-compare":
        comp = harm["compare"]
        return {
            "temperature": [float(t) for t in comp["temperatures_C"]],
            "frequency": [float(f) for f in comp["frequencies_Hz"]],
            "dt": [float(x) for x in comp["dt_s"]],
            "rtol": [float(x) for x in comp["rtol"]],
            "cycles": int(comp["cycles"]),
            "settle_factor": float(comp["settle_factor"]),
            "bond_kinematics": time_domain["bond_kinematics"],
            "head_rotation": time_domain["head_rotation"],
        }
    if command == "harmonic-kinematics":
        kin = harm["kinematics_study"]
        return {
            "temperature": [float(t) for t in kin["temperatures_C"]],
            "frequency": [float(f) for f in kin["frequencies_Hz"]],
            "inertia": list(kin["inertia"]),
        }
    if command == "harmonic-transfer":
        return time_domain
    if command == "harmonic-resolution":
        res = harm["resolution"]
        from ..sample.settings import level_name

        levels = [level_name(lv["scale"], lv["cut_mm"]) for lv in res["levels"]]
        return {
            "levels": [name for name in levels for _ in res["seeds"]],
            "head_rotation": time_domain["head_rotation"],
            "nu": time_domain["nu"],
        }
    if command == "harmonic-bench":
        bench = harm["bench"]
        return {"n": int(bench["n_spheres"]), "td_steps": int(bench["time_domain_steps"]), **kinematics}
    return {}


def _config_option(p) -> None:
    from ..config import config_option

    config_option(
        p,
        config_values,
        "its harmonic section (and the time-domain test's kinematics: nscd.bond_kinematics, "
        "campaign.test.head_rotation, campaign.test.nu)",
    )


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    _add_harmonic(subparsers)
    _add_harmonic_compare(subparsers)
    _add_harmonic_sensitivity(subparsers)
    _add_harmonic_network_factor(subparsers)
    _add_harmonic_plot(subparsers)
    _add_harmonic_kinematics(subparsers)
    _add_harmonic_transfer(subparsers)
    _add_harmonic_resolution(subparsers)
    _add_harmonic_bench(subparsers)


def _add_harmonic(subparsers) -> None:
    """``harmonic``: steady-state complex modulus of a bonded sample (frequency domain, Eqs. 1-5)."""
    p = subparsers.add_parser(
        "harmonic", help="steady-state complex modulus of a bonded sample (frequency domain, Eqs. 1-5)"
    )
    _add_law_options(p)
    p.add_argument("--frequency", type=float, nargs="+", default=None, help="frequencies, Hz")
    p.add_argument(
        "--frequencies-from",
        type=Path,
        default=None,
        help="table with temperature_C, frequency_Hz (e.g. measured summary): its frequencies at each temperature",
    )
    p.add_argument(
        "--sweep",
        type=float,
        nargs=3,
        default=None,
        metavar=("FMIN", "FMAX", "N"),
        help="N log-spaced frequencies from FMIN to FMAX, Hz",
    )
    p.add_argument(
        "--grid",
        choices=["paper", "sweep"],
        default=None,
        help="with --config: the frequencies of harmonic.paper_frequencies_Hz (paper) or the grid of "
        "harmonic.sweep (sweep)",
    )
    p.add_argument(
        "--inertia",
        choices=["full", "none"],
        default="full",
        help="full: sphere masses in the dynamics, head inertia in the force; none: "
        "quasi-static (see asphalt_nscd.harmonic.solver)",
    )
    p.add_argument(
        "--solver",
        choices=["reuse", "direct"],
        default="reuse",
        help="reuse: real LUs only (G per sample; with inertia GMRES preconditioned "
        "by G - Re(s) M, shared by nearby (T, f)); direct: one complex LU per "
        "(T, f)",
    )
    p.add_argument("--rtol", type=float, default=1e-12, help="GMRES relative tolerance (reuse)")
    p.add_argument("--mode", default="", help="label written in a 'mode' column (paper/measured)")
    p.add_argument(
        "-o", "--output", type=Path, required=True, help="CSV: one reduced row per (T, f) + macro law + network factor"
    )
    _config_option(p)
    p.set_defaults(func=_harmonic)


def _add_harmonic_compare(subparsers) -> None:
    """``harmonic-compare``: harmonic vs NSCD time-domain |E*|, Phi per (T, f, dt, rtol)."""
    p = subparsers.add_parser("harmonic-compare", help="harmonic vs NSCD time-domain |E*|, Phi per (T, f, dt, rtol)")
    _add_law_options(p)
    p.add_argument(
        "--frequency", type=float, nargs="+", default=None, help="frequencies, Hz (required without --config)"
    )
    p.add_argument("--dt", type=float, nargs="+", default=None, help="time steps, s (required without --config)")
    p.add_argument(
        "--rtol",
        type=float,
        nargs="+",
        default=[1e-4, 1e-6, 1e-8, 1e-10, 1e-12],
        help="harmonic GMRES tolerances to compare with the direct solution",
    )
    p.add_argument("--cycles", type=int, default=5, help="minimum loading cycles (5)")
    p.add_argument(
        "--settle-factor", type=float, default=6.0, help="minimum duration in units of max(eta_m/Em, eta_k/Ek) (6)"
    )
    p.add_argument("--theta", type=float, default=0.5, help="Moreau-Jean theta (0.5)")
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV of differences")
    p.add_argument("--figure", type=Path, default=None, help="PNG: difference vs dt and rtol")
    _config_option(p)
    p.set_defaults(func=_compare)


def _add_harmonic_sensitivity(subparsers) -> None:
    """``harmonic-sensitivity``: harmonic |E*|, Phi with each Burger's parameter at +-p %."""
    p = subparsers.add_parser("harmonic-sensitivity", help="harmonic |E*|, Phi with each Burger's parameter at +-p %%")
    _add_law_options(p, temperature_required=True)
    p.add_argument(
        "--frequency", type=float, nargs="+", default=None, help="frequencies, Hz (required without --config)"
    )
    p.add_argument(
        "--levels",
        type=float,
        nargs="+",
        default=[10, 20, 30, 40, 50],
        help="parameter changes p, %% (each applied as -p and +p)",
    )
    p.add_argument("--inertia", choices=["full", "none"], default="full", help="see 'harmonic'")
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV")
    p.add_argument("--figure", type=Path, default=None, help="PNG at the first frequency")
    _config_option(p)
    p.set_defaults(func=_sensitivity)


def _add_harmonic_network_factor(subparsers) -> None:
    """``harmonic-network-factor``: network factor tables from harmonic CSVs (sample, mode columns)."""
    p = subparsers.add_parser(
        "harmonic-network-factor", help="network factor tables from harmonic CSVs (sample, mode columns)"
    )
    p.add_argument("inputs", type=Path, nargs="+", help="outputs of 'harmonic' with --mode")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV per (sample, mode, T, f): network_factor, phase_difference_deg",
    )
    p.add_argument("--summary", type=Path, required=True, help="CSV: mean and std over samples")
    p.set_defaults(func=_network_factor)


def _add_harmonic_plot(subparsers) -> None:
    """``harmonic-plot``: isotherms, Black and Cole-Cole: macro law, sample, measured."""
    p = subparsers.add_parser("harmonic-plot", help="isotherms, Black and Cole-Cole: macro law, sample, measured")
    p.add_argument("--harmonic", type=Path, nargs="+", required=True, help="'harmonic' sweep CSVs (one per sample)")
    p.add_argument(
        "--measured",
        type=Path,
        default=None,
        help="measured summary (temperature_C, frequency_Hz, E_norm_MPa_mean, ...)",
    )
    p.add_argument("--title", default=None, help="figure title")
    for name in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole"):
        p.add_argument(f"--{name}", type=Path, default=None, help=f"PNG of the {name} plot")
    p.set_defaults(func=_plot)


def _add_harmonic_kinematics(subparsers) -> None:
    """``harmonic-kinematics``: network factor per (bond kinematics, head rotation, T, f)."""
    p = subparsers.add_parser("harmonic-kinematics", help="network factor per (bond kinematics, head rotation, T, f)")
    p.add_argument("--sample", type=Path, required=True, help="sample file results/samples/<s>.h5")
    p.add_argument(
        "--parameters",
        type=Path,
        required=True,
        help="Burger's parameters CSV (e.g. results/calibration/paper_table3.csv)",
    )
    p.add_argument(
        "--temperature",
        type=float,
        nargs="+",
        default=[],
        help="temperatures, degC (default: every row of --parameters)",
    )
    p.add_argument(
        "--frequency", type=float, nargs="+", default=None, help="frequencies, Hz (required without --config)"
    )
    p.add_argument(
        "--amplitude-m", type=float, default=HEAD_AMPLITUDE_M, help=f"head amplitude A, m ({HEAD_AMPLITUDE_M})"
    )
    p.add_argument("--nu", type=float, default=POISSON_RATIO, help=f"Poisson's ratio of Eqs. 8-11 ({POISSON_RATIO})")
    p.add_argument(
        "--inertia",
        choices=["full", "none"],
        nargs="+",
        default=["none", "full"],
        help="inertia modes (see 'harmonic'; default both)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="CSV per (bond_kinematics, head_rotation, inertia, T, f): network_factor, phase_difference_deg",
    )
    _config_option(p)
    p.set_defaults(func=_kinematics)


def _add_harmonic_transfer(subparsers) -> None:
    """``harmonic-transfer``: network factor NF_s of a sample (transfer JSON for run-2pb)."""
    p = subparsers.add_parser(
        "harmonic-transfer",
        help="network factor NF_s of a sample (transfer JSON for run-2pb)",
        description="Network factor NF_s = sample |E*| / macro |E*| of the "
        "inertia-free sample (real, independent of the law, temperature and "
        "frequency; asphalt_nscd.harmonic.transfer): one real factorisation. "
        "Use the kinematics of the time-domain test it corrects (config "
        "nscd.bond_kinematics, campaign.test.head_rotation, campaign.test.nu).",
    )
    p.add_argument("--sample", type=Path, required=True, help="sample file results/samples/<s>.h5")
    p.add_argument("--nu", type=float, default=POISSON_RATIO, help=f"Poisson's ratio of Eqs. 8-11 ({POISSON_RATIO})")
    _add_kinematics_options(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        required=True,
        help="transfer JSON: network_factor, sample, bond_kinematics, head_rotation, nu, units",
    )
    _config_option(p)
    p.set_defaults(func=_transfer)


def _add_harmonic_resolution(subparsers) -> None:
    """``harmonic-resolution``: network factor against sample resolution (table, summary, figure)."""
    p = subparsers.add_parser(
        "harmonic-resolution",
        help="network factor against sample resolution (table, summary, figure)",
        description="Network factor NF_s of samples prepared at several resolutions "
        "(scale, PSD cut) under each bond kinematics, the seeds' mean and 95 %% interval "
        "per level and the fit NF_inf + c N^(-1/3) (asphalt_nscd.harmonic.resolution): "
        "does the micro-macro transfer of Eqs. 30-33 tend to 1?",
    )
    p.add_argument(
        "--samples",
        nargs="+",
        required=True,
        metavar="[LEVEL=]PATH",
        help="sample files, each with its resolution level name (e.g. x0.7_cut6.3=results/samples/s1.h5) "
        "or with the names in --levels",
    )
    p.add_argument(
        "--levels",
        nargs="+",
        default=None,
        metavar="LEVEL",
        help="the level name of each of --samples given without one (with --config: each level of "
        "harmonic.resolution.levels once per seed, in the config's order)",
    )
    p.add_argument(
        "--kinematics",
        nargs="+",
        choices=list(BOND_KINEMATICS),
        default=list(BOND_KINEMATICS),
        help="bond kinematics computed",
    )
    p.add_argument("--head-rotation", choices=list(HEAD_ROTATIONS), default="free", help="head rotation")
    p.add_argument("--nu", type=float, default=POISSON_RATIO, help=f"Poisson's ratio of Eqs. 8-11 ({POISSON_RATIO})")
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV, one row per (sample, kinematics)")
    p.add_argument("--summary", type=Path, required=True, help="CSV per (kinematics, level): mean, sd, 95 %% CI")
    p.add_argument("--fits", type=Path, required=True, help="CSV per kinematics: NF_inf, its s.e., c")
    p.add_argument("--figure", type=Path, required=True, help="figure (png)")
    _config_option(p)
    p.set_defaults(func=_resolution)


def _add_harmonic_bench(subparsers) -> None:
    """``harmonic-bench``: benchmark the harmonic solver (JSON); run it with OPENBLAS_NUM_THREADS=1
    (one core, as under Snakemake)."""
    p = subparsers.add_parser(
        "harmonic-bench",
        help="benchmark the harmonic solver (JSON); run it with OPENBLAS_NUM_THREADS=1 (one core, as under Snakemake)",
    )
    p.add_argument(
        "--n",
        type=int,
        default=2000,
        help="spheres of the generated lattice sample (default 2000, config harmonic.bench)",
    )
    p.add_argument("--sample", type=Path, default=None, help="use this sample file instead of generating one")
    p.add_argument("--seed", type=int, default=0, help="seed of the generated sample")
    p.add_argument(
        "--frequency",
        type=float,
        nargs="+",
        default=[10.0, 3.0, 6.0, 25.0, 40.0],
        help="frequencies, Hz, solved in this order (default 10 3 6 25 40: the first near the sample's resonance)",
    )
    p.add_argument(
        "--orderings",
        nargs="*",
        default=["metis", "mmd", "colamd"],
        choices=["metis", "mmd", "colamd"],
        help="orderings compared on the factorisation of G in the same run",
    )
    p.add_argument(
        "--skip-baseline", action="store_true", help="do not time the previous inertia path (MMD + GMRES with G^-1)"
    )
    p.add_argument("--td-steps", type=int, default=10, help="NSCD steps timed (0: skip; default 10)")
    p.add_argument(
        "--skip-direct", action="store_true", help="do not time the complex LU per (T, f) (minutes on 10^4 spheres)"
    )
    _add_kinematics_options(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="JSON")
    _config_option(p)
    p.set_defaults(func=_bench)


def _need(args, *dests: str) -> None:
    """Raise InputError naming the options among ``dests`` neither given nor taken from --config."""
    from ..io import InputError

    missing = [f"--{d.replace('_', '-')}" for d in dests if getattr(args, d) in (None, [])]
    if missing:
        raise InputError(f"asphalt-nscd {args.command}: give {', '.join(missing)} (or --config)")


def _load(args):
    from ..io import InputError
    from ..rheology.calibration import read_parameters
    from ..sample.store import read_sample, specimen_geometry_mm
    from .network import network_from_sample
    from .response import select_temperatures
    from .solver import HarmonicSystem

    sample = read_sample(args.sample)
    network = network_from_sample(sample)
    try:
        system = HarmonicSystem(
            network, nu=args.nu, bond_kinematics=args.bond_kinematics, head_rotation=args.head_rotation
        )
    except ValueError as exc:
        raise InputError(f"{args.sample}: --nu/--bond-kinematics/--head-rotation: {exc}") from None
    params = select_temperatures(read_parameters(args.parameters), args.temperature, args.parameters)
    return system, params, specimen_geometry_mm(sample)


def _harmonic(args) -> int:
    import pandas as pd

    from ..io import write_csv
    from ..rheology.calibration import burgers_model
    from .response import frequency_plan, harmonic_rows

    system, params, geometry = _load(args)
    plan = frequency_plan(params, args.frequency, args.frequencies_from, args.sweep)
    rows = []
    for prow, freqs in plan:
        rows += harmonic_rows(
            system,
            burgers_model(prow),
            prow["temperature_C"],
            freqs,
            geometry,
            amplitude=args.amplitude_m,
            inertia=args.inertia,
            solver=args.solver,
            rtol=args.rtol,
        )
    frame = pd.DataFrame(rows)
    frame.insert(0, "mode", args.mode)
    frame.insert(0, "sample", system.network.name)
    write_csv(frame, args.output)
    return 0


def _compare(args) -> int:
    from ..io import savefig, write_csv
    from .analysis import compare_time_domain
    from .figures import plot_compare

    _need(args, "frequency", "dt")
    system, params, geometry = _load(args)
    frame = compare_time_domain(
        args.sample,
        system,
        params,
        args.frequency,
        args.dt,
        args.rtol,
        geometry,
        amplitude=args.amplitude_m,
        n_cycles=args.cycles,
        settle_factor=args.settle_factor,
        theta=args.theta,
        nu=args.nu,
        bond_kinematics=args.bond_kinematics,
        head_rotation=args.head_rotation,
    )
    frame.insert(0, "sample", system.network.name)
    write_csv(frame, args.output)
    if args.figure:
        import matplotlib.pyplot as plt

        fig = plot_compare(frame)
        savefig(fig, args.figure)
        plt.close(fig)
    return 0


def _sensitivity(args) -> int:
    from ..io import savefig, write_csv
    from .analysis import sensitivity_table
    from .figures import plot_sensitivity

    _need(args, "temperature", "frequency")
    system, params, geometry = _load(args)
    frame = sensitivity_table(
        system, params.iloc[0], args.frequency, args.levels, geometry, amplitude=args.amplitude_m, inertia=args.inertia
    )
    frame.insert(0, "sample", system.network.name)
    write_csv(frame, args.output)
    if args.figure:
        import matplotlib.pyplot as plt

        fig = plot_sensitivity(frame, args.frequency[0])
        savefig(fig, args.figure)
        plt.close(fig)
    return 0


def _network_factor(args) -> int:
    from ..io import write_csv
    from .analysis import network_factor_table
    from .response import read_harmonic_rows

    table, summary = network_factor_table([read_harmonic_rows(path) for path in args.inputs])
    write_csv(table, args.output)
    write_csv(summary, args.summary)
    return 0


def _transfer(args) -> int:
    from .transfer import write_transfer

    write_transfer(
        args.sample, args.output, nu=args.nu, bond_kinematics=args.bond_kinematics, head_rotation=args.head_rotation
    )
    return 0


def _resolution(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..io import InputError, savefig, write_csv
    from .figures import plot_resolution
    from .resolution import resolution_rows, resolution_summary

    samples = []
    named = [item.partition("=") for item in args.samples]
    if not all(sep for _, sep, _ in named):
        if args.levels is None or len(args.levels) != len(args.samples) or any(sep for _, sep, _ in named):
            raise InputError(
                f"--samples: give every sample as LEVEL=PATH, or plain paths with one --levels name each "
                f"({len(args.samples)} samples, {0 if args.levels is None else len(args.levels)} level names)"
            )
        named = [(level, "=", path) for level, path in zip(args.levels, args.samples)]
    for level, _, path in named:
        if not level or not path:
            raise InputError(f"--samples {level}={path}: expected LEVEL=PATH")
        samples.append((level, path))
    rows = resolution_rows(samples, kinematics=args.kinematics, head_rotation=args.head_rotation, nu=args.nu)
    levels, fits = resolution_summary(rows)
    write_csv(rows, args.output)
    write_csv(levels, args.summary)
    write_csv(fits, args.fits)
    fig = plot_resolution(rows, levels, fits)
    savefig(fig, args.figure)
    plt.close(fig)
    return 0


def _kinematics(args) -> int:
    from ..io import write_csv
    from ..rheology.calibration import read_parameters
    from ..sample.store import read_sample, specimen_geometry_mm
    from .analysis import kinematics_study
    from .network import network_from_sample
    from .response import select_temperatures

    _need(args, "frequency")
    sample = read_sample(args.sample)
    network = network_from_sample(sample)
    params = select_temperatures(read_parameters(args.parameters), args.temperature, args.parameters)
    if any(f <= 0 for f in args.frequency):
        from ..io import InputError

        raise InputError(f"--frequency: frequencies must be positive, got {args.frequency}")
    frame = kinematics_study(
        network,
        params,
        args.frequency,
        specimen_geometry_mm(sample),
        nu=args.nu,
        inertia_modes=args.inertia,
        amplitude=args.amplitude_m,
    )
    write_csv(frame, args.output)
    return 0


def _plot(args) -> int:
    import matplotlib.pyplot as plt
    import pandas as pd

    from ..rheology.plots import CurveSet, rheology_figure
    from ..io import savefig
    from ..lab.measured import read_summary
    from .response import read_harmonic_rows

    sweep = pd.concat([read_harmonic_rows(p, extra=("sample",)) for p in args.harmonic], ignore_index=True)
    sets = []
    macro = sweep.drop_duplicates(["temperature_C", "frequency_Hz"])[
        ["temperature_C", "frequency_Hz", "macro_E_norm_MPa", "macro_phase_deg"]
    ].rename(columns={"macro_E_norm_MPa": "E_norm_MPa", "macro_phase_deg": "phase_deg"})
    sets.append(CurveSet("macro Burger's model", macro, kind="line", linestyle="--"))
    for name, g in sweep.groupby("sample"):
        sets.append(CurveSet(f"sample {name} (harmonic)", g, kind="line", linestyle="-", style={"alpha": 0.8}))
    if args.measured is not None:
        temps = set(sweep["temperature_C"].round(6))
        measured = read_summary(args.measured)
        measured = measured[measured["temperature_C"].round(6).isin(temps)]
        if len(measured):
            sets.append(CurveSet("measured", measured, kind="points"))
    for name in ("isotherms-modulus", "isotherms-phase", "black", "cole-cole"):
        target = getattr(args, name.replace("-", "_"))
        if target is not None:
            fig = rheology_figure(sets, name, title=args.title)
            savefig(fig, target)
            plt.close(fig)
    return 0


def _bench(args) -> int:
    import tempfile

    from ..io import write_json
    from ..rheology.laws import GeneralizedBurgers
    from ..sample.lattice import lattice_sample
    from ..sample.store import STANDARD_SPECIMEN_MM, read_sample, specimen_geometry_mm, write_sample
    from .analysis import benchmark

    # Table 3 of the paper at 15 degC, read in Pa (docs: data/paper/table3_burgers.csv).
    law = GeneralizedBurgers.burgers(Em=2.43e7, eta_m=3.71e6, Ek=4.84e7, eta_k=7.73e5)
    geometry = dict(STANDARD_SPECIMEN_MM)
    with tempfile.TemporaryDirectory() as tmp:
        path = args.sample
        if path is None:
            path = Path(tmp) / f"lattice_{args.n}.h5"
            write_sample(path, lattice_sample(args.n, seed=args.seed))
        if args.sample is not None:
            geometry = specimen_geometry_mm(read_sample(path))
        result = benchmark(
            path,
            law,
            args.frequency,
            geometry,
            td_steps=args.td_steps,
            bond_kinematics=args.bond_kinematics,
            head_rotation=args.head_rotation,
            direct=not args.skip_direct,
            orderings=tuple(args.orderings),
            baseline=not args.skip_baseline,
        )
    import os

    result["OPENBLAS_NUM_THREADS"] = os.environ.get("OPENBLAS_NUM_THREADS", "unset")
    result.update(
        {
            "sample": str(args.sample) if args.sample else f"lattice n={args.n}",
            "law": "paper Table 3, 15 degC, Pa reading",
            "linear_solver": "scipy.sparse.linalg.splu (SuperLU), symmetric mode, METIS nested "
            "dissection (pymetis); inertia: GMRES preconditioned by G - Re(s) M",
        }
    )
    write_json(result, args.output)
    return 0
