"""Subcommands of the sample step (registered by asphalt_nscd.cli).

``prepare-sample``  one numerical sample (Section 3.2.1) from the ``sample`` config section
``sample-table``    sphere counts per diameter beside the paper's Table 2
"""

from __future__ import annotations

import argparse


def _add_config_options(p: argparse.ArgumentParser, level: bool = False) -> None:
    p.add_argument(
        "--config",
        nargs="+",
        metavar="FILE",
        help="workflow config files (YAML) merged as Snakemake merges --configfile: "
        "config/config.yaml of the working directory first, then each FILE in order "
        "(e.g. config/paper.yaml, an overlay on it), checked against the workflow's schemas; "
        "their 'sample' section is used (and nscd.bonded_contact). "
        "A single YAML/JSON file holding the sample section alone is merged over the "
        "paper's full-scale values",
    )
    if level:
        p.add_argument(
            "--level",
            default=None,
            metavar="NAME",
            help="a level of the network-factor resolution study (harmonic.resolution.levels of "
            "--config, named x{scale}_cut{cut_mm}, e.g. x1_cut4): the sample section with its "
            "scale and PSD cut",
        )


def _load_config(args) -> dict:
    """The sample section of --config (with --level), or the paper's full-scale values."""
    from . import settings

    if args.config:
        return settings.load(args.config, level=getattr(args, "level", None))
    if getattr(args, "level", None):
        from ..io import InputError

        raise InputError("--level needs --config (a workflow config listing harmonic.resolution.levels)")
    return settings.merge(settings.DEFAULTS, {})


def _bonded_contact(args) -> str | None:
    """--bonded-contact, else nscd.bonded_contact of a workflow --config, else None (the core's)."""
    from . import settings

    if args.bonded_contact is not None or not args.config:
        return args.bonded_contact
    whole = settings.workflow_config(args.config)
    return ((whole or {}).get("nscd") or {}).get("bonded_contact")


def _add_bonded_contact(p: argparse.ArgumentParser) -> None:
    from ..nscd.state import BONDED_CONTACT

    p.add_argument(
        "--bonded-contact",
        choices=BONDED_CONTACT,
        default=None,
        help="contact of the bonded pairs in the stabilisation (default: nscd.bonded_contact of a "
        "workflow --config, else the NSCD core's, after_break)",
    )


def _add_progress(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="progress bars of the dynamic stages on stderr (the job log)",
    )


def register(subparsers) -> None:
    """Add this step's subcommands to the asphalt-nscd parser."""
    p = subparsers.add_parser(
        "prepare-sample",
        help="prepare one numerical sample (lattice, deposition, vibration, cut, flip, shrink, bonds)",
        description="Prepare one numerical 2PB sample (paper Section 3.2.1) and write the HDF5 "
        "sample file of docs/design.md. Without --config the paper's full-scale values are used.",
    )
    _add_config_options(p, level=True)
    p.add_argument("--seed", type=int, required=True, help="random seed of the lattice placement")
    p.add_argument("-o", "--output", required=True, help="sample file (.h5)")
    p.add_argument("--vtk-dir", help="directory for the ParaView files of each stage (.vtu)")
    p.add_argument("--figure", help="Fig. 5-like picture of the stages (.png/.pdf)")
    p.add_argument("--summary", help="summary JSON (counts, porosity, coordination, bonds per sphere)")
    p.add_argument("--bench", help="benchmark JSON of this preparation, phase by phase (as prepare-bench writes)")
    _add_bonded_contact(p)
    _add_progress(p)
    p.set_defaults(func=_prepare)

    b = subparsers.add_parser(
        "prepare-bench",
        help="time one sample preparation phase by phase (JSON)",
        description="Prepare one sample (as prepare-sample) and write a JSON record of the CPU and "
        "wall time of each phase, the NLGS statistics of the dynamic stages, and the counts, bonds, "
        "porosity and density beside the paper's (asphalt_nscd.sample.bench).",
    )
    _add_config_options(b, level=True)
    b.add_argument("--seed", type=int, required=True, help="random seed of the lattice placement")
    b.add_argument("-o", "--output", required=True, help="benchmark JSON record")
    b.add_argument("--sample", help="also write the sample file (.h5)")
    b.add_argument("--summary", help="also write the summary JSON of prepare-sample")
    _add_progress(b)
    _add_bonded_contact(b)
    b.set_defaults(func=_bench)

    t = subparsers.add_parser(
        "sample-table",
        help="sphere counts per diameter beside Table 2",
        description="Counts of the paper's rule (scale 1, cut 2 mm), of the configuration, and the mean "
        "counts inside the prepared samples (from their summaries), beside Table 2.",
    )
    _add_config_options(t)
    t.add_argument("--summaries", nargs="*", default=[], help="summary JSON files of prepared samples")
    t.add_argument("-o", "--output", required=True, help="CSV table")
    t.set_defaults(func=_table)


def _prepare(args) -> int:
    from ..io import savefig, write_json
    from . import dynamics
    from .prepare import prepare_sample, write_outputs

    dynamics.PROGRESS = bool(args.progress)
    cfg = _load_config(args)
    result = prepare_sample(cfg, args.seed, bonded_contact=_bonded_contact(args))
    write_outputs(result, args.output, vtk_dir=args.vtk_dir)
    if args.summary:
        write_json(result.summary, args.summary)
    if args.bench:
        _write_bench(result, args, args.bench)
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from .figures import stages_figure

        fig = stages_figure(result.stages, result.trapezoid)
        fig.suptitle(f"sample s{args.seed}: {result.summary['n_spheres']} spheres, scale {cfg['scale']}", fontsize=10)
        savefig(fig, args.figure)
        plt.close(fig)
    return 0


def _bench(args) -> int:
    from ..io import write_json
    from .prepare import prepare_sample, write_outputs

    from . import dynamics

    dynamics.PROGRESS = bool(args.progress)
    cfg = _load_config(args)
    result = prepare_sample(cfg, args.seed, bonded_contact=_bonded_contact(args))
    if args.sample:
        write_outputs(result, args.sample)
    if args.summary:
        write_json(result.summary, args.summary)
    _write_bench(result, args, args.output)
    return 0


def _write_bench(result, args, path) -> None:
    """The benchmark record of a preparation (:func:`asphalt_nscd.sample.bench.bench_record`) to ``path``."""
    from ..io import write_json
    from .bench import bench_record

    rec = bench_record(result.summary)
    rec["config"] = " ".join(args.config) if args.config else "paper full scale (no --config)"
    write_json(rec, path)


def _table(args) -> int:
    from ..io import write_csv
    from .prepare import counts_table

    cfg = _load_config(args)
    write_csv(counts_table(cfg, args.summaries), args.output)
    return 0
