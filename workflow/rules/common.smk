# Shared setup. Every config section has its own JSON schema, validated at load.
# The logic of the rule files (samples, campaign cases, options, report files) is the tested
# module asphalt_nscd.plan; each rule file imports it and only declares rules.
# Rule report_index (figures.smk) collects every output the rules flag with report() into results/report/
import os
import sys
from pathlib import Path

from asphalt_nscd import config as config_files
from asphalt_nscd import plan

# Jobs call the `asphalt-nscd` console script. Put the environment that runs Snakemake first on
# the PATH, so that `.venv/bin/snakemake` (make run) finds the package installed beside it
# without an activated virtual environment. Under --software-deployment-method conda the job's
# environment (workflow/envs/asphalt-nscd.yaml) is activated in front of this; its post-deploy
# script installs the package from ASPHALT_NSCD_SOURCE, the repository holding this workflow.
# Every job appends its exact CPU record to benchmarks/process_cpu.jsonl (ASPHALT_NSCD_CPU_LOG, plan.CPU_LOG).
os.environ.update(plan.job_environment(sys.executable, workflow.basedir, os.environ.get("PATH", ""), os.getcwd()))

# Threads and runtimes are resources of the workflow profiles (profiles/default, profiles/slurm):
# a config that still sets one of the former keys stops here with the key's new place, as does
# a forecast sample variant that repeats the base sample or another (checks no schema expresses).
plan.check_values(config)
for _section, _schema in plan.section_schemas(config, Path(workflow.basedir) / "workflow" / "schemas").items():
    validate(config[_section], _schema)

# The run's configuration, merged and checked, written once (results/config/<its hash>.yaml; a file is never
# rewritten under a running job): jobs read their settings from it (`--config "$ASPHALT_NSCD_RUN_CONFIG"`). Each rule
# keeps what its jobs read as a `settings` param, so a change of those settings, and only of those, reruns the jobs.
os.environ.update(ASPHALT_NSCD_RUN_CONFIG=config_files.write_run_config(config))  # set here, not required of the user
