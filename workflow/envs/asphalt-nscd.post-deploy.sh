#!/usr/bin/env bash
# Snakemake runs this once in the freshly created conda environment (asphalt-nscd.yaml):
# install the asphalt-nscd package (console script `asphalt-nscd`) from the repository that
# holds the workflow; workflow/rules/common.smk exports its path as ASPHALT_NSCD_SOURCE.
set -euo pipefail
src="${ASPHALT_NSCD_SOURCE:?ASPHALT_NSCD_SOURCE is not set (workflow/rules/common.smk sets it)}"
test -f "$src/pyproject.toml" || { echo "error: no pyproject.toml in $src" >&2; exit 1; }
python -m pip install --no-deps --no-build-isolation -e "$src"
