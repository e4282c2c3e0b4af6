# Two entry points (see README): `make run` and `make test`.
# Both create .venv with Python 3.11 if missing and install the pinned dependencies.
# Threads and resources of the rules: profiles/default/config.yaml, which Snakemake loads by itself.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
CORES  ?= 2
CONFIG ?= config/config.yaml

.PHONY: run test setup report dry-run bench clean

$(BIN)/asphalt-nscd: pyproject.toml requirements.lock
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "error: $(PYTHON) not found; set PYTHON=/path/to/python3.11" >&2; exit 1; }
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -r requirements.lock
	$(BIN)/python -m pip install --quiet --no-deps -e .
	touch $@

setup: $(BIN)/asphalt-nscd

run: setup
	$(BIN)/snakemake --cores $(CORES) --configfile $(CONFIG) --printshellcmds --rerun-incomplete

report: setup
	$(BIN)/snakemake --cores $(CORES) --configfile $(CONFIG) --report results/report.html

dry-run: setup
	$(BIN)/snakemake -n --configfile $(CONFIG)

test: setup
	$(BIN)/python -m pytest

bench: setup
	$(BIN)/asphalt-nscd bench --case bonded --n 2000 -o results/bench/bonded.json
	$(BIN)/asphalt-nscd bench --case granular --n 2000 -o results/bench/granular.json

clean:
	rm -rf results logs benchmarks .snakemake
