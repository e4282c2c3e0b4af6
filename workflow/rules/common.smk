# Shared helpers. Every config section has its own JSON schema, validated at load.
# Each rule file appends the figures and tables the report collects to REPORT_FILES
# (paths under results/); `rule all` builds results/report/, which gathers them.
from pathlib import Path

SCHEMAS = Path(workflow.basedir) / "workflow" / "schemas"
for _section in config:
    _schema = SCHEMAS / f"{_section}.schema.yaml"
    if _schema.exists():
        validate(config[_section], str(_schema))

REPORT_FILES = []


def report_targets():
    """The default target: results/report/ with every figure and table of the workflow."""
    return ["results/report/index.md"]
