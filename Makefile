# Two entry points (see README): `make run` and `make test`.
# Both create .venv with Python 3.11 if missing and install the pinned dependencies.
# Threads and resources of the rules: profiles/default/config.yaml, which Snakemake loads by itself.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
CORES  ?= 2
# CONFIG: config/config.yaml, or an overlay merged over it by Snakemake (config/paper.yaml, config/smoke.yaml)
CONFIG ?= config/config.yaml

.PHONY: run test setup report dry-run bench clean table forecast

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

# Your own table: make table TABLE=path/to/table.csv [TEST=path/to/sidecar.json]
# (the sidecar <table>.test.json next to the table is found by itself; README, "Your own table").
# The paths reach the workflow through a YAML overlay written by asphalt-nscd (no shell or JSON quoting of them),
# so a path with spaces, quotes or non-ASCII characters works: make table "TABLE=my lab/mïx.csv".
# The complete run is copied to results/tables/<folder>-<table>/ once every step has succeeded.
TABLE_OVERLAY := results/own_table.yaml
table: setup
	@test -n "$$TABLE" || { echo "usage: make table TABLE=path/to/table.csv [TEST=path/to/table.test.json]" >&2; exit 2; }
	$(BIN)/asphalt-nscd own-table-config "$$TABLE" $${TEST:+--test "$$TEST"} -o $(TABLE_OVERLAY)
	$(BIN)/snakemake own_table --cores $(CORES) --rerun-incomplete --configfile config/config.yaml config/table.yaml $(TABLE_OVERLAY)

# A forecast from the binder.
#   make forecast MIX=path/to/mix.yaml: new mixes (binder DSR sweeps, sieve analysis, volumetrics; data/README.md, "Mix
#     files") forecast with the models trained on the shipped table (results/forecast/trained, made by make run, or
#     here if missing); published in results/mixes/<folder>-<stem>/.
#   make forecast TABLE=path/to/matched_table.tsv (its sidecar <table>.test.json beside it): every mix whose |E*| and
#     phase cells are empty is forecast by every model fitted on the mixes that have them; published in
#     results/forecasts/<folder>-<table>/ (worked in <folder>-<table>.work/: make run's results/forecast stays as it is).
# (README, "Your mix, forecast".)
FORECAST_OVERLAY := results/forecast_table.yaml
forecast: setup
	@test -n "$$TABLE$$MIX" || { echo "usage: make forecast MIX=path/to/mix.yaml | make forecast TABLE=path/to/matched_table.tsv" >&2; exit 2; }
	$(BIN)/asphalt-nscd forecast-config $${MIX:+--mix "$$MIX"} $${TABLE:+--table "$$TABLE"} -o $(FORECAST_OVERLAY)
	$(BIN)/snakemake $${MIX:+forecast_mix} $${TABLE:+forecast_publish} --cores $(CORES) --rerun-incomplete --configfile $(CONFIG) $(FORECAST_OVERLAY)

report: setup
	$(BIN)/snakemake --cores $(CORES) --configfile $(CONFIG) --report results/report.html

dry-run: setup
	$(BIN)/snakemake -n --configfile $(CONFIG)

# The suite on one worker process per core (pytest-xdist): each test module on one worker, so that its
# module fixtures are built once; the modules of the slow tests (the smoke run of the workflow) start first
# (tests/conftest.py), the others share the remaining workers in the order they are collected.
# `make test PYTEST_ARGS=` runs it in one process; --durations=20 prints the slowest twenty tests.
PYTEST_ARGS ?= -n $(CORES) --dist loadscope --no-loadscope-reorder --durations=20
test: setup
	$(BIN)/python -m pytest $(PYTEST_ARGS)

bench: setup
	$(BIN)/asphalt-nscd bench --case bonded --n 2000 -o results/bench/bonded.json
	$(BIN)/asphalt-nscd bench --case granular --n 2000 -o results/bench/granular.json
	$(BIN)/asphalt-nscd forecast-bench --config $(CONFIG) --table data/binder_mix/mixes_35.tsv --mixes 197 211 -o results/bench/forecast_mix.json

clean:
	rm -rf results logs benchmarks .snakemake
