# Shared helpers. Every config section has its own JSON schema, validated at load.
# Each rule file appends the figures and tables the report collects to REPORT_FILES
# (paths under results/); `rule all` builds results/report/, which gathers them.
import os
import sys
from pathlib import Path

# Jobs call the `asphalt-nscd` console script. Put the environment that runs Snakemake first on
# the PATH, so that `.venv/bin/snakemake` (make run) finds the package installed beside it
# without an activated virtual environment. Under --software-deployment-method conda the job's
# environment (workflow/envs/asphalt-nscd.yaml) is activated in front of this; its post-deploy
# script installs the package from ASPHALT_NSCD_SOURCE, the repository holding this workflow.
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
os.environ["ASPHALT_NSCD_SOURCE"] = str(Path(workflow.basedir).resolve())

SCHEMAS = Path(workflow.basedir) / "workflow" / "schemas"
for _section in config:
    _schema = SCHEMAS / f"{_section}.schema.yaml"
    if _schema.exists():
        validate(config[_section], str(_schema))

REPORT_FILES = []


def report_targets():
    """The default target: results/report/ with every figure and table of the workflow."""
    return ["results/report/index.md"]
