# Thin wrappers over `python -m repro <command>`; see README.md. Every target sets up the virtual
# environment first, so a fresh clone needs only `make reproduce` or `make test`.

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
PY     := $(BIN)/python
REPRO  := $(PY) -m repro
SCALE  ?= quick
SEED   ?= 0
ARGS   ?=
TORCH_VERSION ?= 2.13.0
STAMP  := $(VENV)/.installed
# pytest-xdist workers of `make test`: auto, one per core; 0 runs the tests in this process
TEST_WORKERS ?= auto

# Each command of `python -m repro` has the target of its name, and each of its other names an
# alias target (tests/test_make.py checks both).
.PHONY: help setup reproduce test test-fast lint claims transfer transfer-heuristics transfer-dt \
	transfer-order transfer-ablation transfer-inputs bus-thresholds bus-lambda bus-batch \
	bus-lambda-pool bus-batch-pool transfer-pool \
	bus-arrivals bus-loads bus-eval race wildfire-races scaling wildfire-behaviour wildfire-penalty wildfire-eval \
	render advantage-estimators train plot-runs bench-bus bench-wildfire bench-learn clean \
	table-race table-thresholds fig-scaling fig-transfer wildfire-heuristics beyond-transfer-dt \
	beyond-order learner-ablation c9-inputs fig-bus-lambda fig-bus-batch fig-bus-arrivals \
	fig-bus-load beyond-races beyond-mgae beyond-sb3 interval-coverage advantage-sb3
.DEFAULT_GOAL := help

help:
	@echo "make reproduce   # every driver at SCALE=$(SCALE), then its verdicts (results/$(SCALE)/claims.md; paper: paper_claims.md)"
	@echo "make test        # lint (ruff), then the test suite"
	@grep -E '^[a-z0-9-]+:.*## ' $(MAKEFILE_LIST) | sed 's/:.*## /\t/' | sort

# torch is installed first and on its own so that pip takes a CPU build: the `+cpu` build from a
# local wheel or index where the machine has one (PyPI has none, so this fails fast elsewhere), else
# from PyTorch's CPU index, else the default build (macOS, where it is CPU-only anyway). The rest
# goes in with uv where PyPI has it (seconds, where pip takes a minute; the installed torch
# satisfies the suite's range, so uv keeps it), else with pip. Nothing is byte-compiled at install
# time (--no-compile, as uv): Python compiles a module on its first import and keeps the byte code,
# in .venv and in the git-ignored __pycache__ folders, so that only what the suite imports is
# compiled, once. For that the targets run with byte code writes allowed, whatever
# PYTHONDONTWRITEBYTECODE says in the caller's environment (some images set it): without them,
# each of the hundreds of processes a test run or a study starts compiles its imports anew.
PIP := $(BIN)/pip install -q --no-compile
unexport PYTHONDONTWRITEBYTECODE
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) --upgrade pip
	$(PIP) "torch==$(TORCH_VERSION)+cpu" 2>/dev/null \
	  || $(PIP) "torch==$(TORCH_VERSION)+cpu" --extra-index-url https://download.pytorch.org/whl/cpu \
	  || $(PIP) "torch==$(TORCH_VERSION)"
	($(PIP) uv && $(BIN)/uv pip install -q --python $(PY) -e ".[test]") 2>/dev/null \
	  || $(PIP) -e ".[test]"
	touch $@

setup: $(STAMP) ## create .venv and install the suite

test: lint ## lint, then run the test suite, one worker per core (TEST_WORKERS)
	$(PY) -m pytest -n $(TEST_WORKERS) --dist worksteal

test-fast: $(STAMP) ## the tests not marked slow (about a minute): while editing
	$(PY) -m pytest -n $(TEST_WORKERS) --dist worksteal -m "not slow"

lint: $(STAMP) ## ruff: style (100 columns) and likely bugs (pyproject.toml says which rules)
	$(BIN)/ruff check repro tests

reproduce: $(STAMP) ## every study at SCALE, their runs trained together, then the verdicts (ARGS="--studies transfer transfer-dt": some of them)
	$(REPRO) reproduce --scale $(SCALE) --seed $(SEED) $(ARGS)

claims: $(STAMP) ## render paper_claims.md from results/paper/ (ARGS="--results-dir results/quick": a smoke check; "--interval percentile": decided with the percentile bootstrap)
	$(REPRO) claims $(ARGS)

race: $(STAMP) ## race-condition table and figure (C10)
	$(REPRO) race --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-thresholds: $(STAMP) ## Optimized Thresholds by differential evolution (bus baseline)
	$(REPRO) bus-thresholds --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-eval: $(STAMP) ## return, loads and regularity of a bus policy (ARGS="--policy thresholds")
	$(REPRO) bus-eval $(ARGS)

train: $(STAMP) ## train a shared policy with PS-TRPO and M-GAE (ARGS="--env bus --epochs 10 --out runs/b")
	$(REPRO) train --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-lambda: $(STAMP) ## bus training curves over lambda (C1, C2; needs bus-thresholds)
	$(REPRO) bus-lambda --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-batch: $(STAMP) ## bus training curves over the batch size (C3; needs bus-thresholds)
	$(REPRO) bus-batch --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-lambda-pool: $(STAMP) ## bus-lambda on the released runner's shared-stream pool, as the paper's curves were drawn (C1, C2)
	$(REPRO) bus-lambda --sampler released-pool --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-batch-pool: $(STAMP) ## bus-batch on the released runner's shared-stream pool (C3)
	$(REPRO) bus-batch --sampler released-pool --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-arrivals: $(STAMP) ## bus arrival times per policy (C5; needs bus-thresholds, bus-lambda)
	$(REPRO) bus-arrivals --scale $(SCALE) $(ARGS)

bus-loads: $(STAMP) ## bus loads at the paper's records per policy (C4, C5; needs bus-thresholds, bus-lambda)
	$(REPRO) bus-loads --scale $(SCALE) $(ARGS)

bench-bus: $(STAMP) ## episodes/s of the fast bus engine and its SimPy reference
	$(REPRO) bench-bus --scale $(SCALE) --seed $(SEED) $(ARGS)

bench-wildfire: $(STAMP) ## decisions/s of the fast and SimPy wildfire engines (MLP policy)
	$(REPRO) bench-wildfire --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-eval: $(STAMP) ## ADR of a heuristic wildfire policy (ARGS="--policy flowchart ...")
	$(REPRO) wildfire-eval --seed $(SEED) $(ARGS)

render: $(STAMP) ## GIF of one episode (ARGS="--env wildfire --policy flowchart --out episode.gif")
	$(REPRO) render --seed $(SEED) $(ARGS)

bench-learn: $(STAMP) ## seconds per training epoch, simulation vs update (ARGS="--env wildfire")
	$(REPRO) bench-learn --scale $(SCALE) --seed $(SEED) $(ARGS)

plot-runs: $(STAMP) ## training curves of run folders with seed intervals (ARGS="runs/wildfire/seed0 runs/wildfire/seed1 --out runs.png")
	$(REPRO) plot-runs $(ARGS)

scaling: $(STAMP) ## event-driven vs time-stepped compute against N, table and figure (C11)
	$(REPRO) scaling --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer: $(STAMP) ## train on ED and FS simulators, test on ED (C8, C9; ARGS="--sim-version 2017-04-22", "--learner suite", "--corrected")
	$(REPRO) transfer --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-pool: $(STAMP) ## transfer --sim-version 2017-04-22 on the released runner's shared-stream pool, as the paper's runs were trained (C8, C9)
	$(REPRO) transfer --sim-version 2017-04-22 --sampler released-pool --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-heuristics: $(STAMP) ## heuristic policies on the transfer study's ED test episodes (C8, C9)
	$(REPRO) transfer-heuristics --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-behaviour: $(STAMP) ## frequencies of a long ED-trained policy vs the flowchart (C6, C7)
	$(REPRO) wildfire-behaviour --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-penalty: $(STAMP) ## the behaviour study over crowding penalties 1-20, as the authors measured it (C6, C7)
	$(REPRO) wildfire-penalty --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-races: $(STAMP) ## X2: races in the wildfire simulator, dT against N, beside C10 (after race)
	$(REPRO) wildfire-races --scale $(SCALE) --seed $(SEED) $(ARGS)

interval-coverage: $(STAMP) ## coverage of the claims' interval kinds at 3, 5 and 10 runs (after the studies whose per-seed scores it pools)
	$(REPRO) interval-coverage --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-order: $(STAMP) ## X4: C9's pair under both same-instant orders (reuses transfer's runs)
	$(REPRO) transfer-order --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-ablation: $(STAMP) ## X5: the transfer study, one learner setting at a time from the authors' (reuses transfer's runs)
	$(REPRO) transfer-ablation --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-inputs: $(STAMP) ## C9's policies tested with health and sojourn clamped (after transfer --sim-version 2017-04-22)
	$(REPRO) transfer-inputs --scale $(SCALE) --seed $(SEED) $(ARGS)

advantage-estimators: $(STAMP) ## X1: M-GAE vs two other advantage estimators (reuses bus-lambda's, transfer's runs)
	$(REPRO) advantage-estimators --scale $(SCALE) --seed $(SEED) $(ARGS)

advantage-sb3: $(STAMP) ## X6: SB3's PPO with its GAE and with M-GAE against PS-TRPO, wildfire and bus
	$(REPRO) advantage-sb3 --scale $(SCALE) --seed $(SEED) $(ARGS)

transfer-dt: $(STAMP) ## X3: transfer to ED against 13 dT, race rate beside it (reuses transfer's runs)
	$(REPRO) transfer-dt --scale $(SCALE) --seed $(SEED) $(ARGS)

# other names of the commands (repro/cli.py's ALIASES: the paper's names of its tables and figures,
# and the names the commands had before they were grouped by question)
table-race: race ## alias of race
table-thresholds: bus-thresholds ## alias of bus-thresholds
fig-scaling: scaling ## alias of scaling
fig-transfer: transfer ## alias of transfer
wildfire-heuristics: transfer-heuristics ## alias of transfer-heuristics
beyond-transfer-dt: transfer-dt ## alias of transfer-dt
beyond-order: transfer-order ## alias of transfer-order
learner-ablation: transfer-ablation ## alias of transfer-ablation
c9-inputs: transfer-inputs ## alias of transfer-inputs
fig-bus-lambda: bus-lambda ## alias of bus-lambda
fig-bus-batch: bus-batch ## alias of bus-batch
fig-bus-arrivals: bus-arrivals ## alias of bus-arrivals
fig-bus-load: bus-loads ## alias of bus-loads
beyond-races: wildfire-races ## alias of wildfire-races
beyond-mgae: advantage-estimators ## alias of advantage-estimators
beyond-sb3: advantage-sb3 ## alias of advantage-sb3

clean: ## remove the virtual environment and caches, numba's compiled kernels too (results and figures stay)
	rm -rf $(VENV) .pytest_cache .hypothesis
	find repro tests -name __pycache__ -prune -exec rm -rf {} +
