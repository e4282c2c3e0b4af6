# Complex modulus of asphalt concrete by NSCD: the reproducible workflow.
# Run: `make run` (default config) or `snakemake --cores 2 --configfile config/smoke.yaml`.
# One rule file per package it drives (workflow/rules/<stage>.smk, in the order of asphalt_nscd.STAGES).
# Threads and resources live in the workflow profiles: profiles/default (loaded automatically, a 2-core
# workstation) and profiles/slurm (`--workflow-profile profiles/slurm`).
import os
import sys
import time
from pathlib import Path

from snakemake.utils import min_version, validate

import asphalt_nscd
from asphalt_nscd import STAGES
from asphalt_nscd import config as config_files
from asphalt_nscd import plan

min_version("9.0")

# One BLAS and one OpenMP thread per job unless the user's environment sets a count: the jobs run side by
# side, one per core, and the libraries' own threads would contend for the same cores (docs/choices.md,
# "Threads of the libraries"). Set before any job starts; every job's process inherits it.
os.environ.update(plan.thread_environment(os.environ))
# The package's byte code, written once for the jobs of the run (each would otherwise compile its sources
# where PYTHONDONTWRITEBYTECODE is set): a cache, no result depends on it.
plan.byte_compile(Path(asphalt_nscd.__file__).parent)

# the start of this run: the rule logs written since hold its errors and warnings (printed below)
RUN_START = time.time()


configfile: "config/config.yaml"


# The overlays given with --configfile (config/paper.yaml, config/smoke.yaml) come first in Snakemake's
# merge; their keys go back to config/config.yaml's order, so a job's command line does not depend on them.
config_files.restore_default_order(config)


validate(config, "workflow/schemas/config.schema.yaml")


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"


# one rule file per stage of the package, in the package's order (asphalt_nscd.STAGES)
for stage in STAGES:

    include: f"workflow/rules/{stage}.smk"


# Every file of the report is a target beside its index: a result that is missing (deleted, or removed with a job
# that failed) is rebuilt by the next run even while the index is up to date.
rule all:
    default_target: True
    input:
        plan.REPORT_INDEX,
        plan.report_input(workflow, config),
        plan.forecast_dir(config),


# Snakemake reports a failed rule as "check log file(s)": print the project's own one-line errors (file, row or
# key, what was expected), the exception line of a command that failed unexpectedly, and the warnings (a material
# card that loses accuracy, a unit or a parameter out of range, phases that look like radians: often the cause of a
# later failure), from the rule logs of this run.
onerror:
    for line in plan.console_messages(RUN_START, "warning"):
        print(f"warning: {line}", file=sys.stderr)
    for line in plan.console_messages(RUN_START, "error"):
        print(line, file=sys.stderr)
    for line in plan.crash_messages(RUN_START):
        print(line, file=sys.stderr)


onsuccess:
    for line in plan.console_messages(RUN_START, "warning"):
        print(f"warning: {line}", file=sys.stderr)
