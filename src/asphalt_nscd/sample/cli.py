"""Subcommands of the sample step (registered by asphalt_nscd.cli).

``prepare-sample``  one numerical sample (Section 3.2.1) from the ``sample`` config section
``sample-table``    sphere counts per diameter beside the paper's Table 2
"""

from __future__ import annotations

import argparse


def _add_config_options(p: argparse.ArgumentParser) -> None:
    group = p.add_mutually_exclusive_group()
    group.add_argument(
        "--config",
        nargs="+",
        metavar="FILE",
        help="workflow config files (YAML) merged as Snakemake merges --configfile: "
        "config/config.yaml of the working directory first, then each FILE in order "
        "(e.g. config/paper.yaml, an overlay on it); their 'sample' section is used. "
        "A single YAML/JSON file holding the sample section alone is merged over the "
        "paper's full-scale values",
    )
    group.add_argument("--config-json", help="the sample section as a JSON string (used by the workflow)")


def _load_config(args):
    import json

    from ..io import InputError
    from . import settings

    if args.config:
        return settings.load(args.config)
    if args.config_json:
        try:
            data = json.loads(args.config_json)
        except ValueError as exc:
            raise InputError(f"--config-json: not valid JSON ({exc})") from exc
        if not isinstance(data, dict):
            raise InputError("--config-json: expected a JSON object of sample settings")
        return settings.merge(settings.DEFAULTS, data, "--config-json: sample")
    return settings.merge(settings.DEFAULTS, {})


def _add_bonded_contact(p: argparse.ArgumentParser) -> None:
    from ..nscd.state import BONDED_CONTACT

    p.add_argument(
        "--bonded-contact",
        choices=BONDED_CONTACT,
        default=None,
        help="contact of the bonded pairs in the stabilisation (config nscd.bonded_contact; "
        "default: the NSCD core's, after_break)",
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
        "sample file of docs/design.md. Without --config/--config-json the paper's full-scale values are used.",
    )
    _add_config_options(p)
    p.add_argument("--seed", type=int, required=True, help="random seed of the lattice placement")
    p.add_argument("-o", "--output", required=True, help="sample file (.h5)")
    p.add_argument("--vtk-dir", help="directory for the ParaView files of each stage (.vtu)")
    p.add_argument("--figure", help="Fig. 5-like picture of the stages (.png/.pdf)")
    p.add_argument("--summary", help="summary JSON (counts, porosity, coordination, bonds per sphere)")
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
    _add_config_options(b)
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
    result = prepare_sample(cfg, args.seed, bonded_contact=args.bonded_contact)
    write_outputs(result, args.output, vtk_dir=args.vtk_dir)
    if args.summary:
        write_json(result.summary, args.summary)
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
    from .bench import bench_record
    from .prepare import prepare_sample, write_outputs

    from . import dynamics

    dynamics.PROGRESS = bool(args.progress)
    cfg = _load_config(args)
    result = prepare_sample(cfg, args.seed, bonded_contact=args.bonded_contact)
    if args.sample:
        write_outputs(result, args.sample)
    if args.summary:
        write_json(result.summary, args.summary)
    rec = bench_record(result.summary)
    rec["config"] = " ".join(args.config) if args.config else "--config-json"
    write_json(rec, args.output)
    return 0


def _table(args) -> int:
    from ..io import write_csv
    from .prepare import counts_table

    cfg = _load_config(args)
    write_csv(counts_table(cfg, args.summaries), args.output)
    return 0
