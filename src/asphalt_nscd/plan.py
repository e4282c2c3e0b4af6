"""The workflow's plan: which jobs, files and command-line options the Snakemake rules need.

Every piece of Python logic of the rule files (``workflow/rules/*.smk``, ``Snakefile``) lives
here, so that the rule files only declare rules and the logic is unit-tested
(tests/unit/test_plan.py): the sample names and paths, the campaign modes and their cases (one
job per mode, sample, temperature, frequency and variant), the result files a target needs,
the CLI options of a case, the diagnosis inputs and the files the report collects. It drives
every step of the chain, so it sits at the package's top level and may import any layer.

Result files that several rules read are named once here (constants such as :data:`MEASURED`,
or functions of the wildcard values such as :func:`sample_file`); a rule's output that no
other rule names stays in its rule.

Plain functions take the workflow's config dict (validated, defaults filled) and wildcard
values, and return strings, lists or dicts. :func:`from_wildcards` turns one into the
Snakemake input or params function of a rule (an argument ``wildcards`` with attribute access);
the few params functions that read the job's input files take ``wildcards, input``.

No Snakemake import: a path that is wrong or a config that cannot be planned raises
:class:`asphalt_nscd.io.InputError` naming the key or the file.

Case names: ``{T}C_{f}Hz`` with an optional ``_dt{dt}`` (time-step study) or ``_{p}x{factor}``
(sensitivity study) suffix, numbers written with ``:g``; :func:`parse_case` turns a case name
back into its values and :func:`case_options` into the ``asphalt-nscd run-2pb`` options.
"""

from __future__ import annotations

import inspect
import math
import os
import re
from pathlib import Path

from .campaign import modes
from .campaign.modes import OWN_LAW_MODES, schedule
from .cli import CPU_LOG_ENV
from .io import InputError

#: the index of results/report/, the default target (rule all)
REPORT_INDEX = "results/report/index.md"

# result files that several rules read, each written by one rule
#: the measured table, tidy (rule measured_table)
MEASURED = "results/lab/measured.csv"
#: the lab summary (replicate means per cell) the measured and extended modes compare with
MEASURED_SUMMARY = "results/lab/measured_summary.csv"
#: the declared test geometry of the measured table (rule measured_table)
MEASURED_TEST = "results/lab/measured.test.json"
#: a Burger's parameter table (MPa, MPa s) of wildcard ``table`` (rules fit_burgers, paper_table3)
CALIBRATION_TABLE = "results/calibration/{table}.csv"
#: the Burger's parameters calibrated on the measured table (rule fit_burgers)
BURGERS_PARAMETERS = CALIBRATION_TABLE.format(table="burgers_parameters")
#: the paper's Table 3 under calibration.table3_units (rule paper_table3)
PAPER_TABLE3 = CALIBRATION_TABLE.format(table="paper_table3")
#: the extended bond law per temperature (rule extend_law) run by the extended mode
LAW_JSON = "results/diagnosis/generalized_burgers.json"
#: the law a material card carries (rule extend_law): the selected law, or the best law a Prony series with a
#: shift function carries when the selected one has a vertical shift, a static trend or a per-isotherm refinement
CARD_LAW_JSON = "results/diagnosis/card_law.json"
#: the artifact search and master curve of the measured table (rule master_curve)
MASTER_CURVE_JSON = "results/diagnosis/master_curve.json"
#: the artifact search's level calibrated on the measured table (rule calibrate_search)
CALIBRATION_JSON = "results/diagnosis/search_calibration.json"
#: the artifact-corrected measured table (rule master_curve)
CORRECTED_TABLE = "results/diagnosis/corrected_measured.csv"
#: the directory of the extended law's material cards (rule export_law)
MATERIAL_CARDS_DIR = "results/diagnosis/material_cards"
#: the material cards of the extended law: Abaqus, LS-DYNA, Prony series JSON and CSV
MATERIAL_CARDS = {
    "abaqus": f"{MATERIAL_CARDS_DIR}/abaqus.inp",
    "lsdyna": f"{MATERIAL_CARDS_DIR}/lsdyna.k",
    "json": f"{MATERIAL_CARDS_DIR}/prony.json",
    "table": f"{MATERIAL_CARDS_DIR}/prony.csv",
    "errors": f"{MATERIAL_CARDS_DIR}/card_errors.csv",
    "functions": f"{MATERIAL_CARDS_DIR}/relaxation_creep.csv",
}
#: the figures of rule card_figures: isochrones of the card against the measured means, its E(t) and D(t), its
#: error against the number of Prony terms
MATERIAL_CARD_FIGURES = {
    "isochrones": f"{MATERIAL_CARDS_DIR}/isochrones.png",
    "relaxation_creep": f"{MATERIAL_CARDS_DIR}/relaxation_creep.png",
    "terms_curve": f"{MATERIAL_CARDS_DIR}/terms_curve.png",
}
#: the figures of rule master_curve_figures: master curve, shift factors, the law's residuals
MASTER_CURVE_FIGURES = {
    "master": "results/diagnosis/figures/master_curve.png",
    "shift": "results/diagnosis/figures/shift_factors.png",
    "residuals": "results/diagnosis/figures/law_residuals.png",
}
#: the MEPDG sigmoid's parameters beside 2S2P1D's (rule master_curve_figures)
SIGMOID_TABLE = "results/diagnosis/sigmoid_master_curve.csv"
#: the diagnosis page (rule diagnose)
DIAGNOSIS_PAGE = "results/diagnosis/what_the_simulation_gets_wrong.md"
#: the unit readings of the paper's Table 3 (data/paper/SOURCE.md)
TABLE3_READINGS = ("Pa", "kPa")
#: modes running Table 3 under an explicit reading beside ``paper`` (which runs
#: calibration.table3_units): same schedule (campaign.paper), own overrides (campaign.paper_<unit>)
READING_MODES = tuple(f"paper_{u}" for u in TABLE3_READINGS)
#: main campaign modes with a numerical isotherms / Table 4 aggregation (wildcard constraint)
ISOTHERM_MODES = "|".join(modes.ISOTHERM_MODES)
#: the paper's Table 4 (MRE of its simulations against its experiments)
PAPER_TABLE4 = "data/paper/table4_mre.csv"
#: every job mode of rule run_2pb (wildcard constraint)
JOB_MODES = (
    "paper|paper_Pa|paper_kPa|measured|extended|dt_study|sensitivity|units_Pa|units_kPa|units_Pa_nobreak"
    "|units_kPa_nobreak"
)
#: modes of the dt-policy check (wildcard constraint)
POLICY_MODES = "paper|paper_Pa|paper_kPa|measured"
#: the Burger's parameters of the sensitivity study, in the order of its figures 11-14
SENS_PARAMETERS = ["Em", "eta_m", "Ek", "eta_k"]
#: the rheology plots of rule rheology_figures and the harmonic figures
RHEOLOGY_PLOTS = ["isotherms-modulus", "isotherms-phase", "black", "cole-cole"]
#: parameter modes of the harmonic solver
HARMONIC_MODES = ["paper", "measured"]
#: the Burger's parameter table of each harmonic mode
HARMONIC_PARAMETERS = {"paper": PAPER_TABLE3, "measured": BURGERS_PARAMETERS}
#: simulation inputs of rule diagnose (config diagnosis.<key>: auto, null or a CSV path)
DIAGNOSIS_INPUT_KEYS = ("simulated", "harmonic", "time_integration", "simulated_extended", "transfer")

#: config keys that were resources, removed from the configs -> where the profiles set them now
RESOURCE_KEYS = {
    "campaign.job_runtime_min": "set-resources of run_2pb and crossval_time_domain, runtime",
    "harmonic.compare.runtime_min": "set-resources of harmonic_compare, runtime",
    "nscd.threads": "set-threads of nscd_bench, passed to `asphalt-nscd bench --threads`",
}

_CASE = re.compile(
    r"^(?P<T>-?[\d.]+)C_(?P<f>[\d.e+-]+)Hz(?:_dt(?P<dt>[\d.e+-]+)|_(?P<p>Em|eta_m|Ek|eta_k)x(?P<x>[\d.]+))?$"
)


# ---------------------------------------------------------------------------------------------
# generic helpers


def number(x) -> str:
    """A number as written in case names and options: ``float(x)`` with ``:g`` (15 -> '15')."""
    return f"{float(x):g}"


#: The JSON-lines file, relative to the working directory, to which every job appends its exact CPU record
#: (:func:`asphalt_nscd.cli.cpu_record`); reference/paper_scale/whole_run_cpu.py sums it.
CPU_LOG = "benchmarks/process_cpu.jsonl"


def job_environment(python_executable: str, basedir: str, path: str, workdir: str = ".") -> dict:
    """Environment variables the workflow sets for its jobs: PATH with the directory of the
    Python running Snakemake first (so that ``.venv/bin/snakemake`` finds the ``asphalt-nscd``
    console script installed beside it), ASPHALT_NSCD_SOURCE, the repository holding the
    workflow (the conda environment's post-deploy script installs the package from it), and
    ASPHALT_NSCD_CPU_LOG, :data:`CPU_LOG` under ``workdir`` (absolute), where every job's
    command appends its CPU record."""
    return {
        "PATH": f"{Path(python_executable).parent}{os.pathsep}{path}",
        "ASPHALT_NSCD_SOURCE": str(Path(basedir).resolve()),
        CPU_LOG_ENV: str(Path(workdir).resolve() / CPU_LOG),
    }


#: Thread counts of the BLAS and OpenMP libraries that every job gets unless the user's environment sets them
#: (:func:`thread_environment`; docs/choices.md, "Threads of the libraries").
LIBRARY_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def thread_environment(environ) -> dict:
    """The library thread counts a job gets: 1 for each variable of :data:`LIBRARY_THREAD_VARIABLES`
    that ``environ`` (a mapping, e.g. ``os.environ``) leaves unset or empty; a value the user set is kept
    (not returned). A workflow runs one job per core, and each of OpenBLAS's and OpenMP's own threads
    then contends for the same cores (docs/choices.md, "Threads of the libraries"). Numba's threads are
    not among them: a threaded NSCD command gets its count from NUMBA_NUM_THREADS and ``--threads``."""
    return {name: "1" for name in LIBRARY_THREAD_VARIABLES if not environ.get(name)}


def byte_compile(package_dir) -> bool:
    """Write the byte code of every module under ``package_dir`` (``__pycache__``, as ``python -m
    compileall``) where it is missing or older than its source, so that the jobs of a run load it instead
    of compiling the package's sources each: an interpreter with PYTHONDONTWRITEBYTECODE set (or a
    read-only checkout) never writes it itself, and every job then compiles about 300 modules again.
    Returns False, changing nothing, where the directory is not writable (a package installed read-only);
    the byte code is a cache: its absence changes no result."""
    import compileall

    package_dir = Path(package_dir)
    if not os.access(package_dir, os.W_OK):
        return False
    try:
        return bool(compileall.compile_dir(package_dir, quiet=2, workers=1))
    except OSError:
        return False


def section_schemas(config: dict, schema_dir) -> dict:
    """Config section -> its JSON schema file (``{schema_dir}/{section}.schema.yaml``), for the
    sections that have one."""
    schemas = {}
    for section in config:
        schema = Path(schema_dir) / f"{section}.schema.yaml"
        if schema.exists():
            schemas[section] = str(schema)
    return schemas


def reject_resource_keys(config: dict) -> None:
    """Raise InputError if ``config`` holds a key of :data:`RESOURCE_KEYS`: threads and runtimes
    are resources of the workflow profiles (profiles/default, profiles/slurm), not science, and
    a config that still sets them would be silently ignored (docs/choices.md)."""
    for key, where in RESOURCE_KEYS.items():
        node = config
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                break
            node = node[part]
        else:
            raise InputError(
                f"config key {key} is a resource, not science: it moved to the workflow "
                f"profiles (profiles/default/config.yaml, profiles/slurm/config.yaml: "
                f"{where}); remove it from the config file"
            )


def check_values(config: dict) -> None:
    """The checks of a merged configuration its JSON schemas cannot express, made when the
    workflow loads so that a refusal is one line before any job: no former resource key
    (:func:`reject_resource_keys`), and the forecast's sample variants well formed and distinct
    from the base sample and from each other (:func:`asphalt_nscd.forecast.formulation.sample_variants`).

    Raises
    ------
    InputError
        naming the key (``forecast.dem.variants[i]``, a resource key) and what was expected.
    """
    from .forecast.formulation import sample_variants

    reject_resource_keys(config)
    dem = (config.get("forecast") or {}).get("dem") or {}
    if dem.get("variants"):
        sample_variants(dem)


def from_wildcards(func, config: dict):
    """The Snakemake input or params function of a plain function of this module: called with
    a job's ``wildcards``, it returns ``func(config, ...)`` with every parameter of ``func``
    after ``config`` that has no default taken from the wildcard of the same name, e.g.
    ``from_wildcards(mode_rows, config)(wildcards) == mode_rows(config, wildcards.mode)``."""
    params = list(inspect.signature(func).parameters.values())[1:]
    names = [p.name for p in params if p.default is inspect.Parameter.empty]

    def of_wildcards(wildcards):
        return func(config, *(getattr(wildcards, name) for name in names))

    of_wildcards.__name__ = f"{func.__name__}_of_wildcards"
    of_wildcards.__doc__ = f"{func.__name__}(config, {', '.join(names)}) of a job's wildcards"
    return of_wildcards


def command_settings(config: dict, command: str, **args) -> dict:
    """The option values ``asphalt-nscd command --config`` takes from the run's configuration
    when given the options ``args`` (:func:`asphalt_nscd.cli.config_values`): a rule keeps them
    as its ``settings`` parameter, so that a change of them, and only of them, reruns it."""
    from .cli import config_values

    return config_values(command, config, **args)


# ---------------------------------------------------------------------------------------------
# lab data


def lab_records(config: dict) -> dict:
    """Raw 2PB records of lab.records: record name (file stem) -> path."""
    return {Path(p).stem: p for p in config["lab"].get("records", [])}


def measured_test(config: dict) -> str:
    """The test-geometry JSON of the measured table: config measured.test, else the table's
    sidecar ``{stem}.test.json`` beside it."""
    given = config["measured"].get("test")
    if given:
        return given
    table = Path(config["measured"]["table"])
    return str(table.with_name(f"{table.stem}.test.json"))


def measured_test_input(config: dict) -> list:
    """Input of rule measured_table: the test JSON when configured or present, else none."""
    test = measured_test(config)
    return [test] if Path(test).is_file() or config["measured"].get("test") else []


def record_file(config: dict, record: str) -> str:
    """Path of the raw lab record ``record`` (lab.records)."""
    records = lab_records(config)
    if record not in records:
        raise InputError(f"config lab.records: no record named {record!r} (have {sorted(records)})")
    return records[record]


def record_meta(config: dict, record: str) -> str:
    """The metadata JSON beside a raw lab record (same stem, ``.json``)."""
    return str(Path(record_file(config, record)).with_suffix(".json"))


def nscd_bench_files(config: dict) -> list:
    """Benchmark JSONs of the NSCD core: bonded then granular, per nscd.bench sizes."""
    bench = config["nscd"]["bench"]
    return [f"results/bench/nscd_bonded_n{n}.json" for n in bench["bonded_n"]] + [
        f"results/bench/nscd_granular_n{n}.json" for n in bench["granular_n"]
    ]


def bench_settings(config: dict, case: str) -> dict:
    """What ``asphalt-nscd bench --case CASE`` takes from the run's config (:func:`command_settings`)."""
    return command_settings(config, "bench", case=case)


def bonded_contact(config: dict) -> str:
    """Contact of the bonded pairs (nscd.bonded_contact; its default is the schema's)."""
    return config["nscd"]["bonded_contact"]


# ---------------------------------------------------------------------------------------------
# samples


def sample_names(config: dict) -> list:
    """Sample names (wildcard values): s{seed} for each seed of sample.seeds."""
    return [f"s{seed}" for seed in config["sample"]["seeds"]]


def sample_file(name: str) -> str:
    """Path of the HDF5 sample file of sample ``name`` (e.g. s1)."""
    return f"results/samples/{name}.h5"


def rig_state_file(name: str) -> str:
    """Rig-state file of sample ``name`` (rule rig_state, read by its 2PB jobs)."""
    return f"results/campaign/rig/{name}.h5"


def rig_state_settings(config: dict) -> dict:
    """The test settings a rig state is computed for (:data:`asphalt_nscd.campaign.twopb.RIG_STATE_SETTINGS`
    of the jobs' settings, what ``rig-state --config`` reads), kept by rule rig_state as a parameter."""
    from .campaign.twopb import RIG_STATE_SETTINGS, job_settings

    settings = job_settings(config, "paper")
    return {k: settings[k] for k in RIG_STATE_SETTINGS}


def sample_settings(config: dict) -> dict:
    """What a sample job reads from the config, kept by the rules as a parameter so that a
    change of it reruns the samples: the sample section without the seed list (adding a seed
    reruns no other sample) and the bonded pairs' contact (nscd.bonded_contact)."""
    return {
        "sample": {k: v for k, v in config["sample"].items() if k != "seeds"},
        "bonded_contact": bonded_contact(config),
    }


def resolution_levels(config: dict) -> dict:
    """Levels of the network-factor resolution study (config harmonic.resolution.levels):
    name (:func:`asphalt_nscd.sample.settings.level_name`) -> {scale, cut_mm}."""
    from .sample.settings import level_name

    return {
        level_name(lv["scale"], lv["cut_mm"]): {"scale": float(lv["scale"]), "cut_mm": float(lv["cut_mm"])}
        for lv in config["harmonic"]["resolution"]["levels"]
    }


def resolution_sample_settings(config: dict, level: str) -> dict:
    """:func:`sample_settings` of a resolution level (what ``prepare-sample --level`` reads):
    the sample section with the level's scale and PSD cut."""
    try:
        lv = resolution_levels(config)[level]
    except KeyError:
        raise InputError(f"harmonic.resolution.levels: no level {level!r}") from None
    out = sample_settings(config)
    section = out["sample"]
    out["sample"] = {**section, "scale": lv["scale"], "psd": {**section.get("psd", {}), "cut_mm": lv["cut_mm"]}}
    return out


def resolution_samples(config: dict) -> list:
    """(level, sample file) of the resolution study: every level x harmonic.resolution.seeds; a
    level with the campaign's own scale and PSD cut uses the campaign's sample of that seed
    (results/samples/s{seed}.h5) when the seed is one of sample.seeds, else
    results/samples/resolution/{level}/s{seed}.h5."""
    own = (float(config["sample"].get("scale", 1.0)), float(config["sample"].get("psd", {}).get("cut_mm", 2.0)))
    out = []
    for name, lv in resolution_levels(config).items():
        for seed in config["harmonic"]["resolution"]["seeds"]:
            if (lv["scale"], lv["cut_mm"]) == own and seed in config["sample"]["seeds"]:
                out.append((name, sample_file(f"s{seed}")))
            else:
                out.append((name, f"results/samples/resolution/{name}/s{seed}.h5"))
    return out


# ---------------------------------------------------------------------------------------------
# campaign: modes, cases, rows


def case_name(T, f, suffix: str = "") -> str:
    """Case name of a test at T (degC) and f (Hz): ``{T}C_{f}Hz{suffix}``."""
    return f"{number(T)}C_{number(f)}Hz{suffix}"


def parse_case(case: str) -> dict:
    """Values of a case name as written: T, f and, when present, dt (time-step study) or p, x
    (sensitivity parameter and factor); absent parts are None. Raises InputError on a name
    :func:`case_name` cannot write."""
    m = _CASE.match(case)
    if m is None:
        raise InputError(f"bad campaign case name {case!r}: expected {{T}}C_{{f}}Hz[_dt{{dt}}|_{{p}}x{{factor}}]")
    return m.groupdict()


def campaign_samples(config: dict, n) -> list:
    """The first n samples of the sample list (all when n is None)."""
    samples = sample_names(config)
    return samples if n is None else samples[: int(n)]


def mode_samples(config: dict, mode: str) -> list:
    """Samples of the main campaign of one mode: campaign.n_samples (paper, measured) or
    campaign.extended.n_samples (extended)."""
    camp = config["campaign"]
    return campaign_samples(config, camp["extended"]["n_samples"] if mode == "extended" else camp["n_samples"])


def mode_rows(config: dict, mode: str, samples=None) -> list:
    """Reduced rows of the main campaign of one mode (paper, paper_<unit>, measured or
    extended; the extended mode runs the measured schedule), on ``samples`` (default: the
    mode's)."""
    sched = schedule(config, mode)
    return [
        f"results/sim/{mode}/{s}/{case_name(T, f)}.csv"
        for s in (mode_samples(config, mode) if samples is None else samples)
        for T in sched["temperatures_C"]
        for f in sched["frequencies_Hz"]
    ]


def dt_study_files(config: dict, ext: str) -> list:
    """Files (``ext``: h5 records or csv rows) of the time-step study (campaign.dt_study)."""
    d = config["campaign"]["dt_study"]
    return [
        f"results/sim/dt_study/{s}/{case_name(d['temperature_C'], d['frequency_Hz'], f'_dt{number(dt)}')}.{ext}"
        for s in campaign_samples(config, d["n_samples"])
        for dt in d["dt_s"]
    ]


def sensitivity_rows(config: dict) -> list:
    """Rows of the sensitivity study: sample x parameter x factor x frequency."""
    d = config["campaign"]["sensitivity"]
    return [
        f"results/sim/sensitivity/{s}/{case_name(d['temperature_C'], f, f'_{p}x{number(x)}')}.csv"
        for s in campaign_samples(config, d["n_samples"])
        for p in SENS_PARAMETERS
        for x in d["factors"]
        for f in d["frequencies_Hz"]
    ]


def _study_rows(config: dict, mode: str, study: dict) -> list:
    """Rows of ``mode`` at a study's temperature: its samples x its frequencies."""
    return [
        f"results/sim/{mode}/{s}/{case_name(study['temperature_C'], f)}.csv"
        for s in campaign_samples(config, study["n_samples"])
        for f in study["frequencies_Hz"]
    ]


def sensitivity_baseline(config: dict) -> list:
    """The x1 baseline of the sensitivity study: paper-mode rows at its temperature."""
    return _study_rows(config, "paper", config["campaign"]["sensitivity"])


def sensitivity_figures() -> list:
    """Figures 11-14 of the sensitivity study, one per Burger's parameter."""
    return [f"results/campaign/paper/figures/fig{11 + k}_sensitivity_{p}.png" for k, p in enumerate(SENS_PARAMETERS)]


def units_rows(config: dict, reading: str, nobreak: bool = False) -> list:
    """Rows of the units question under one reading (nobreak: unbreakable bonds); the
    paper-mode rows serve the reading the paper mode already runs with."""
    d = config["campaign"]["units_question"]
    mode = "paper" if reading == config["calibration"]["table3_units"] else f"units_{reading}"
    if nobreak:
        mode = f"units_{reading}_nobreak"
    return _study_rows(config, mode, d)


def last_cycle_record(config: dict) -> str:
    """The paper-mode record of the first sample at campaign.last_cycle (Figs. 7-8)."""
    last = config["campaign"]["last_cycle"]
    return f"results/sim/paper/{sample_names(config)[0]}/{case_name(last['temperature_C'], last['frequency_Hz'])}.h5"


# ---------------------------------------------------------------------------------------------
# campaign: one job's law and options


def mode_settings(config: dict, mode: str) -> dict:
    """The test settings of a job mode (:func:`asphalt_nscd.campaign.twopb.job_settings`, what
    ``run-2pb --config`` builds from the same config): campaign.test with the mode's overrides of
    dt_policy, yield_stress_Pa and start, the core's bond kinematics and solver, the reduced
    window. The rules keep it as a parameter so that a change of it reruns the mode's jobs."""
    from .campaign.twopb import job_settings

    return job_settings(config, mode)


def transfer_correction(config: dict) -> bool:
    """Whether the extended mode calibrates its bonds with E*(w) / NF_s (the sample's network
    factor; campaign.extended.transfer_correction, default true)."""
    return bool(config["campaign"]["extended"].get("transfer_correction", True))


def transfer_file(sample: str) -> str:
    """Network factor JSON of a sample (rule harmonic_transfer)."""
    return f"results/harmonic/transfer/{sample}.json"


def job_transfer(config: dict, mode: str, sample: str) -> list:
    """The transfer JSON a job needs: the extended mode's when the correction is on, else none."""
    return [transfer_file(sample)] if mode == "extended" and transfer_correction(config) else []


def mode_parameters(config: dict, mode: str) -> str:
    """Law file of a mode: calibrated Burger's table (measured), law JSON (extended), else the
    paper's Table 3 (calibration.table3)."""
    if mode == "measured":
        return BURGERS_PARAMETERS
    if mode == "extended":
        return LAW_JSON
    return config["calibration"]["table3"]


def law_option(config: dict, mode: str) -> str:
    """CLI option of the mode's law file: --law-json (extended) or --parameters."""
    return "--law-json" if mode == "extended" else "--parameters"


def case_options(config: dict, mode: str, sample: str, case: str) -> str:
    """``asphalt-nscd run-2pb`` options of one job's case name: its temperature and frequency,
    and its time step (dt study) or sensitivity factor. What the job takes from the run's
    config besides its test settings is :func:`job_values`."""
    c = parse_case(case)
    opts = f"--temperature {c['T']} --frequency {c['f']}"
    if c["dt"]:
        opts += f" --dt {c['dt']}"
    if c["p"]:
        opts += f" --factor {c['p']}={c['x']}"
    return opts


def job_values(config: dict, mode: str, sample: str, case: str) -> dict:
    """What a run_2pb job of ``case`` takes from the run's config besides its test settings
    (:func:`asphalt_nscd.campaign.modes.config_values`: the Table 3 reading, whether it is a
    verification job), kept by the rule as a parameter so that a change of them reruns it."""
    c = parse_case(case)
    return command_settings(
        config,
        "run-2pb",
        mode=mode,
        temperature=float(c["T"]),
        frequency=float(c["f"]),
        dt=float(c["dt"]) if c["dt"] else None,
        factor=[f"{c['p']}={c['x']}"] if c["p"] else [],
        law_json=mode_parameters(config, mode) if mode == "extended" else None,
    )


def isotherm_settings(config: dict, mode: str) -> dict:
    """What campaign-isotherms of ``mode`` takes from the run's config (its Table 3 reading and
    title; :func:`command_settings`)."""
    return command_settings(
        config,
        "campaign-isotherms",
        mode=mode,
        law_json=mode_parameters(config, mode) if mode == "extended" else None,
    )


def policy_settings(config: dict, mode: str) -> dict:
    """What campaign-dt-policy of ``mode`` takes from the run's config besides the test
    settings (Table 3 reading, temperature, frequencies; :func:`command_settings`)."""
    return command_settings(config, "campaign-dt-policy", settings_mode=mode)


def mode_paper_table4(config: dict, mode: str) -> list:
    """The paper's Table 4 shown beside a paper-parameter mode's Table 4 analogue, else none."""
    return [] if mode in OWN_LAW_MODES else [PAPER_TABLE4]


def input_options(**flags: str):
    """Params function of a rule whose command takes some inputs as options: ``key=flag`` ->
    ``flag path...`` for each named input ``key`` the job has (an empty input gives nothing),
    the paths shell-quoted."""
    import shlex

    def options(wildcards, input) -> str:
        out = []
        for key, flag in flags.items():
            paths = getattr(input, key, None) or []
            paths = [paths] if isinstance(paths, str) else list(paths)
            if paths:
                out.append(" ".join([flag, *(shlex.quote(str(p)) for p in paths)]))
        return " ".join(out)

    return options


def mode_summary(config: dict, mode: str) -> list:
    """The lab summary the isotherms of a mode are compared with (measured, extended), else none."""
    return [MEASURED_SUMMARY] if mode in OWN_LAW_MODES else []


# ---------------------------------------------------------------------------------------------
# harmonic solver


def harmonic_job_file(sample: str, mode: str) -> str:
    """The harmonic solution of a sample under a harmonic mode's parameters at its (T, f) (rule
    harmonic_jobs)."""
    return f"results/harmonic/jobs/{sample}_{mode}.csv"


def harmonic_sweep_file(sample: str, mode: str) -> str:
    """The dense frequency sweep of a sample under a harmonic mode's parameters (rule
    harmonic_sweep)."""
    return f"results/harmonic/sweep/{sample}_{mode}.csv"


def harmonic_frequency_option(wildcards, input) -> str:
    """Params function of rule harmonic_jobs: ``--grid paper`` (the paper's frequencies,
    harmonic.paper_frequencies_Hz, from the run's config) in the paper mode, else the measured
    (T, f) of the lab summary, the job's ``input.summary``."""
    return "--grid paper" if wildcards.mode == "paper" else f"--frequencies-from {input.summary}"


def harmonic_job_settings(config: dict, mode: str) -> dict:
    """What a harmonic_jobs job of ``mode`` takes from the run's config (:func:`command_settings`)."""
    return command_settings(config, "harmonic", grid="paper" if mode == "paper" else None)


def harmonic_parameters(config: dict, mode: str) -> str:
    """Burger's table of a harmonic mode (paper: Table 3 read; measured: calibrated)."""
    return HARMONIC_PARAMETERS[mode]


# ---------------------------------------------------------------------------------------------
# diagnosis


def diagnosis_auto_input(config: dict, key: str) -> list:
    """The workflow's own output(s) for a simulation input of rule diagnose (``auto``), on the
    extended mode's samples."""
    samples = mode_samples(config, "extended")
    if key == "simulated":
        return mode_rows(config, "measured", samples)
    if key == "simulated_extended":
        return mode_rows(config, "extended", samples)
    if key == "harmonic":
        return [harmonic_job_file(s, "measured") for s in samples]
    if key == "time_integration":
        return ["results/campaign/measured/dt_policy_phase_error.csv"]
    if key == "transfer":
        return [transfer_file(s) for s in samples]
    raise InputError(f"config diagnosis: unknown simulation input {key!r} (expected one of {DIAGNOSIS_INPUT_KEYS})")


def diagnosis_inputs(config: dict) -> dict:
    """Simulation inputs of rule diagnose: key -> files, for the keys of diagnosis that are
    ``auto`` (the workflow's outputs) or a path; null keys are left out."""
    inputs = {}
    for key in DIAGNOSIS_INPUT_KEYS:
        value = config["diagnosis"].get(key, "auto")
        if value == "auto":
            inputs[key] = diagnosis_auto_input(config, key)
        elif value:
            inputs[key] = [value]
    return inputs


def diagnosis_input_function(config: dict):
    """Input function of rule diagnose (for ``unpack``): :func:`diagnosis_inputs`, named by key."""

    def inputs(wildcards) -> dict:
        return diagnosis_inputs(config)

    return inputs


#: the option of each simulation input of rule diagnose (``diagnose --simulated ...``)
DIAGNOSIS_INPUT_OPTIONS = {key: f"--{key.replace('_', '-')}" for key in DIAGNOSIS_INPUT_KEYS}


def diagnosis_input_files(config: dict) -> list:
    """Every simulation file of rule diagnose, in the order of :func:`diagnosis_inputs`."""
    return [p for paths in diagnosis_inputs(config).values() for p in paths]


def diagnosis_settings(config: dict, *groups: str) -> dict:
    """The option values a diagnosis rule's command takes from the run's configuration
    (:func:`asphalt_nscd.diagnosis.settings.option_values` of ``groups``: search, law,
    calibration, causes), kept by the rule as a parameter so that a change of them reruns it."""
    from .diagnosis.settings import option_values

    return option_values(config, *groups)


def crossval_file(scheme: str, suffix: str = ".csv") -> str:
    """A file of the cross-validation ``scheme`` (rule crossval): its rows (``.csv``),
    ``_summary.csv``, ``_curve.csv`` or figure ``.png``."""
    return f"results/diagnosis/crossval/{scheme}{suffix}"


def crossval_files(config: dict, suffix: str = ".csv") -> list:
    """:func:`crossval_file` of every scheme of diagnosis.crossval.schemes."""
    return [crossval_file(scheme, suffix) for scheme in config["diagnosis"]["crossval"]["schemes"]]


def crossval_sample(config: dict) -> str:
    """The sample of the cross-validation: the extended mode's first."""
    return mode_samples(config, "extended")[0]


def crossval_time_domain_cell(config: dict):
    """The (T, f) of the time-domain check of the lofo cross-validation
    (diagnosis.crossval.time_domain): given, or ``auto``: the median tested temperature (the
    lower of the two middle ones) and its tested frequency nearest 10 Hz, read from
    measured.table; None when null. Returns a dict temperature_C, frequency_Hz. Raises
    InputError when the table cannot be read or a given cell is not measured."""
    value = config["diagnosis"]["crossval"]["time_domain"]
    if value is None:
        return None
    table = config["measured"]["table"]
    from .lab.measured import load_measured

    try:  # as the workflow reads it (a lab's columns and units converted through its sidecar)
        frame = load_measured(table, config["measured"].get("test"))
    except InputError as exc:
        raise InputError(
            f"config diagnosis.crossval.time_domain: cannot read the measured cells of {table} ({exc}); "
            "set the cell or null"
        ) from exc
    cells = {(float(T), float(f)) for T, f in zip(frame["temperature_C"], frame["frequency_Hz"])}
    if value == "auto":
        temps = sorted({T for T, _ in cells})
        T = temps[(len(temps) - 1) // 2]
        f = min((f for t, f in cells if t == T), key=lambda f: (abs(math.log10(f) - 1.0), f))
        return {"temperature_C": T, "frequency_Hz": f}
    if (float(value["temperature_C"]), float(value["frequency_Hz"])) not in cells:
        raise InputError(
            f"config diagnosis.crossval.time_domain: {value['temperature_C']} degC, "
            f"{value['frequency_Hz']} Hz is not a measured cell of {table}"
        )
    return value


def crossval_time_domain_case(config: dict):
    """Case name of the time-domain check, None without one."""
    cell = crossval_time_domain_cell(config)
    return case_name(cell["temperature_C"], cell["frequency_Hz"]) if cell else None


def crossval_time_domain_row(config: dict) -> str:
    """The reduced row of the time-domain check (rule crossval_time_domain)."""
    return f"results/diagnosis/crossval/time_domain_{crossval_time_domain_case(config)}.csv"


def crossval_time_domain_input(config: dict, scheme: str) -> list:
    """The time-domain row a cross-validation scheme reads: lofo with a time-domain cell."""
    if scheme == "lofo" and crossval_time_domain_cell(config):
        return [crossval_time_domain_row(config)]
    return []


def output_directory(wildcards, output) -> str:
    """Params function of a command that writes its files into one directory (rule export_law):
    the directory of the job's first output file."""
    return str(Path(output[0]).parent)


def report_wildcards(config: dict) -> dict:
    """Wildcard values of the report's files, per rule: rule name -> the list of wildcard
    dictionaries its report outputs are expanded with (:func:`report_files`). A rule without
    wildcards that is not listed reports its outputs once; a rule listed with an empty list
    reports none (the paper mode's studies when the campaign has no paper mode)."""
    camp = config["campaign"]
    paper = "paper" in camp["modes"]
    return {
        "reduce_record": [{"record": record} for record in sorted(lab_records(config))],
        "micro_parameters": [{"table": "burgers_parameters"}, {"table": "paper_table3"}],
        "prepare_sample": [{"seed": name[1:]} for name in sample_names(config)],
        # the extended mode always runs: the diagnosis compares it with the measured mode
        "campaign_isotherms": [{"mode": mode} for mode in [*camp["modes"], "extended"]],
        "campaign_dt_policy": [{"mode": mode} for mode in camp["modes"]],
        "campaign_dt_study": [{}] if paper else [],
        "campaign_last_cycle": [{}] if paper else [],
        "campaign_sensitivity": [{}] if paper else [],
        "campaign_units_question": [{}] if paper else [],
        "harmonic_figures": [{"mode": mode} for mode in HARMONIC_MODES],
        "crossval": [{"scheme": scheme} for scheme in config["diagnosis"]["crossval"]["schemes"]],
    }


def report_files(rules, config: dict) -> list:
    """Every file rule report_index collects into results/report/: the outputs the rules flag
    with Snakemake's ``report()``, in the order of the rules (the rule files in
    :data:`asphalt_nscd.STAGES` order), each rule's wildcards expanded with
    :func:`report_wildcards`. ``rules``: the workflow's rules (``workflow.rules``; anything with
    ``name`` and ``output`` whose items carry Snakemake's ``flags``).

    Raises InputError for a flagged output with wildcards that :func:`report_wildcards` does not
    give values for."""
    from snakemake.exceptions import WildcardError
    from snakemake.io import apply_wildcards

    values = report_wildcards(config)
    files = []
    for rule in rules:
        flagged = [str(out) for out in rule.output if "report" in getattr(out, "flags", {})]
        combos = values.get(rule.name, [{}])
        for pattern in flagged:
            for wildcards in combos:
                try:
                    files.append(apply_wildcards(pattern, wildcards))
                except WildcardError as err:
                    raise InputError(
                        f"rule {rule.name}: report output {pattern} has a wildcard without values"
                        " (plan.report_wildcards)"
                    ) from err
    return files


def report_input(workflow, config: dict):
    """The input function of rules report_index and all: :func:`report_files` of the workflow's
    rules, evaluated when Snakemake builds the jobs, once every rule file is read
    (``workflow``: the Snakefile's ``workflow`` object)."""

    def report_of_rules(wildcards):
        return report_files(workflow.rules, config)

    return report_of_rules


#: where ``make table`` puts the complete run of each table (rule own_table)
OWN_TABLES = "results/tables"


def own_table_dir(config: dict) -> str:
    """``results/tables/<folder>-<stem>``: the folder of the last complete ``make table`` run on
    measured.table (its folder's name and its file name without suffix, e.g.
    ``results/tables/uiuc_fdmix1_utm-complex_modulus``); a table at the working directory's
    root gives ``results/tables/<stem>``."""
    table = Path(config["measured"]["table"])
    folder = table.resolve().parent.name
    return (
        f"{OWN_TABLES}/{folder}-{table.stem}" if folder and table.parent != Path(".") else f"{OWN_TABLES}/{table.stem}"
    )


#: the lines of the project's commands that the console repeats after a run: their one-line
#: errors and their warnings (asphalt_nscd.cli writes both to the rule's log)
CONSOLE_PATTERNS = {"error": re.compile(r"^error: .*"), "warning": re.compile(r"\basphalt_nscd WARNING: (.*)")}


def _run_logs(since: float, log_dir: str) -> list[Path]:
    """The rule logs under ``log_dir`` written since ``since`` (epoch seconds), in the order of their times."""
    root = Path(log_dir)
    if not root.is_dir():
        return []
    return sorted(
        (p for p in root.rglob("*.log") if p.is_file() and p.stat().st_mtime >= since), key=lambda p: p.stat().st_mtime
    )


def console_messages(since: float, kind: str, log_dir: str = "logs") -> list[str]:
    """The project's messages of ``kind`` (``error`` or ``warning``, :data:`CONSOLE_PATTERNS`)
    in the rule logs under ``log_dir`` written since ``since`` (epoch seconds): ``log: line``,
    each once, in the order of the logs' times. Snakemake shows only "check log file(s)" for a
    failed rule; the Snakefile's onerror and onsuccess handlers print these instead."""
    out, seen = [], set()
    for path in _run_logs(since, log_dir):
        for line in path.read_text(errors="replace").splitlines():
            m = CONSOLE_PATTERNS[kind].search(line)
            if m:
                text = m.group(1) if m.groups() else m.group(0)
                if text not in seen:
                    seen.add(text)
                    out.append(f"{path}: {text}")
    return out


def crash_messages(since: float, log_dir: str = "logs") -> list[str]:
    """The unexpected failures in the rule logs under ``log_dir`` written since ``since`` (epoch
    seconds): for each log that ends a command in a Python traceback, ``log: failed unexpectedly:
    <the exception line> (the traceback is in the log)``, in the order of the logs' times. A bad
    input ends in the project's one-line error instead (:func:`console_messages`); this names the
    rest, which Snakemake shows only as "check log file(s)"."""
    out = []
    for path in _run_logs(since, log_dir):
        lines = path.read_text(errors="replace").splitlines()
        starts = [k for k, line in enumerate(lines) if line.startswith("Traceback (most recent call last):")]
        if not starts:
            continue
        tail = [line for line in lines[starts[-1] + 1 :] if line.strip() and not line[0].isspace()]
        if tail:
            out.append(f"{path}: failed unexpectedly: {tail[0]} (the traceback is in the log)")
    return out


# forecast: a mix's |E*| and phase from its binder, gradation and volumetrics (workflow/rules/forecast.smk)
#: the working area of the forecast chain of make run (forecast.work_dir's default)
FORECAST = "results/forecast"


#: what a forecast response file holds (a param of rule forecast_response: a response written before it is rewritten)
FORECAST_RESPONSE_CONTENTS = (
    "pencils of the bridges and the skeleton, series and Hertz contact geometry, bridge shape factors"
)


def forecast_root(config: dict) -> str:
    """The forecast chain's working folder: forecast.work_dir (:data:`FORECAST` when unset). make forecast
    TABLE=... sets it to ``results/forecasts/<folder>-<stem>.work/forecast`` (:func:`.forecast.product.table_work_dir`), so
    that a table's forecast leaves make run's own chain, and the models a mix file is forecast with, as they are."""
    return str((config.get("forecast") or {}).get("work_dir") or FORECAST)


def forecast_publish_root(wildcards, input) -> str:
    """The params function of rule forecast_publish: the folder its files' paths are kept relative to, the
    parent of the working folder (its first file, the matched table, lies in it): ``forecast/...`` in the
    published folder for every working folder."""
    return str(Path(input.files[0]).parent.parent)


def forecast_matched(config: dict) -> str:
    """The matched table in the project's columns (checkpoint forecast_table), in :func:`forecast_root`."""
    return f"{forecast_root(config)}/matched.csv"


def forecast_where(config: dict) -> str:
    """The wildcard constraint of a forecast sample's folder: :func:`forecast_root` (the base sample) or
    its variants/<name> (a variant)."""
    return re.escape(forecast_root(config)) + r"(/variants/cut[0-9.]+_x[0-9.]+)?"


def forecast_dir(config: dict) -> str:
    """``results/forecasts/<folder>-<stem>``: the folder of the last complete forecast of
    forecast.table (:func:`.forecast.product.table_folder`)."""
    from .forecast.product import table_folder

    return table_folder(config["forecast"]["table"])


def mix_dir(config: dict) -> str:
    """``results/mixes/<folder>-<stem>``: the folder of the last complete forecast of the mix file
    forecast.mix (make forecast MIX=...)."""
    mix = Path(config["forecast"]["mix"])
    folder = mix.resolve().parent.name
    return f"results/mixes/{folder}-{mix.stem}" if folder else f"results/mixes/{mix.stem}"


def forecast_sidecar(config: dict) -> list:
    """The sidecar ``<stem>.test.json`` of forecast.table when it exists (an input of the
    checkpoint, so that editing it reruns the chain)."""
    table = Path(config["forecast"]["table"])
    side = table.with_name(table.stem + ".test.json")
    return [str(side)] if side.is_file() else []


def forecast_mixes_setting(config: dict) -> list:
    """forecast.mixes as a list (empty: every mix): the checkpoint's parameter, so that changing the mixes
    reruns it; the command reads the setting itself from the run's checked configuration."""
    return [str(m) for m in (config["forecast"].get("mixes") or [])]


def matched_mixes(path) -> list:
    """The mix ids of a matched table in the project's columns, in file order (the checkpoint's
    output, already checked)."""
    import csv

    with open(path, newline="", encoding="utf-8") as fh:
        return list(dict.fromkeys(row["mix_id"] for row in csv.DictReader(fh)))


def forecast_variant(config: dict, where: str) -> dict:
    """The sample variant of a forecast sample folder (:func:`forecast_where`): ``name`` ("" for the
    base sample), ``cut_mm``, ``size_dmax``. Raises InputError for a variant the config does not list."""
    from .forecast.formulation import sample_variants
    from .io import InputError

    dem = config["forecast"].get("dem") or {}
    if where == forecast_root(config):
        return {"name": "", "cut_mm": float(dem["cut_mm"]), "size_dmax": float(dem["size_dmax"])}
    name = where.rsplit("/", 1)[-1]
    variants = sample_variants(dem)
    if name not in variants:
        raise InputError(f"{where}: sample variant {name!r} not in forecast.dem.variants {list(variants)}")
    cut, size = variants[name]
    return {"name": name, "cut_mm": cut, "size_dmax": size}


def forecast_responses(config: dict, matched) -> list:
    """The DEM response file of every (mix, seed) of the matched table, on the base sample and on each
    sample variant of forecast.dem.variants, or none when forecast.dem.models is empty."""
    from .forecast.formulation import sample_variants

    dem = config["forecast"].get("dem") or {}
    if not dem.get("models"):
        return []
    root = forecast_root(config)
    roots = [root] + [f"{root}/variants/{name}" for name in sample_variants(dem)]
    mixes = matched_mixes(matched)
    return [f"{root}/responses/{m}_s{s}.npz" for root in roots for m in mixes for s in dem.get("seeds", [1])]


def forecast_settings(config: dict) -> dict:
    """What the forecast's chain commands read from the config (a change reruns them): the
    forecast section without the seed list, without the mix file of new mixes (read by forecast_mix
    alone) and without the working folder (the outputs' paths already name it)."""
    dem = {k: v for k, v in (config["forecast"].get("dem") or {}).items() if k != "seeds"}
    return {**{k: v for k, v in config["forecast"].items() if k not in ("mix", "work_dir")}, "dem": dem}


def forecast_sample_settings(config: dict, where: str | None = None) -> dict:
    """What a mix's preparation in the folder ``where`` reads from the config (a change reruns it, and
    only it): its variant's cut and cube size, the layer (forecast.dem), and the sample section the
    dynamics come from."""
    dem = config["forecast"].get("dem") or {}
    variant = forecast_variant(config, forecast_root(config) if where is None else where)
    return {
        "dem": {
            "cut_mm": float(variant["cut_mm"]),
            "size_dmax": float(variant["size_dmax"]),
            "layer_over_side": dem.get("layer_over_side"),
        },
        "sample": {k: v for k, v in config["sample"].items() if k != "seeds"},
    }


def forecast_sample_param(config: dict):
    """The params function of a forecast preparation rule: :func:`forecast_sample_settings` of the
    job's folder (wildcard ``where``)."""

    def settings(wildcards):
        return forecast_sample_settings(config, wildcards.where)

    return settings


def forecast_variant_param(config: dict):
    """The params function of the forecast response rule: the name of the job's sample variant
    ("" for the base sample; :func:`forecast_variant` of wildcard ``where``)."""

    def variant(wildcards):
        return forecast_variant(config, wildcards.where)["name"]

    return variant


def forecast_responses_input(config: dict, checkpoints):
    """The input function of the forecast's chain rules: :func:`forecast_responses` of the matched
    table, which exists once checkpoint forecast_table has run (``checkpoints``: the Snakefile's)."""

    def responses(wildcards):
        return forecast_responses(config, checkpoints.forecast_table.get().output.matched)

    return responses
