# Complex modulus of asphalt concrete by NSCD: the reproducible workflow.
# Run: `make run` (default config) or `snakemake --cores 2 --configfile config/smoke.yaml`.
# One rule file per package it drives (workflow/rules/{lab,rheology,nscd,sample,campaign,harmonic,
# diagnosis,figures}.smk). Threads and resources live in the workflow profiles: profiles/default
# (loaded automatically, a 2-core workstation) and profiles/slurm (`--workflow-profile profiles/slurm`).
from snakemake.utils import min_version, validate

from asphalt_nscd import config as config_files
from asphalt_nscd import plan

min_version("9.0")


configfile: "config/config.yaml"


# The overlays given with --configfile (config/paper.yaml, config/smoke.yaml) come first in Snakemake's
# merge; their keys go back to config/config.yaml's order, so a job's command line does not depend on them.
config_files.restore_default_order(config)


validate(config, "workflow/schemas/config.schema.yaml")


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/lab.smk"
include: "workflow/rules/rheology.smk"
include: "workflow/rules/nscd.smk"
include: "workflow/rules/sample.smk"
include: "workflow/rules/campaign.smk"
include: "workflow/rules/harmonic.smk"
include: "workflow/rules/diagnosis.smk"
include: "workflow/rules/figures.smk"


rule all:
    default_target: True
    input:
        plan.REPORT_INDEX,
