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

# Each command of `python -m repro` has the target of its name (tests/test_make.py checks it); the
# paper's names of three (table-race, table-thresholds, fig-scaling) are aliases.
.PHONY: help setup reproduce test lint claims race bus-thresholds bus-eval fig-bus-lambda \
	fig-bus-batch fig-bus-arrivals fig-bus-load wildfire-heuristics bench-bus bench-wildfire \
	wildfire-eval bench-learn plot-runs scaling fig-transfer wildfire-behaviour render train \
	beyond-races beyond-mgae beyond-sb3 beyond-order beyond-transfer-dt learner-ablation c9-inputs \
	clean \
	table-race table-thresholds fig-scaling
.DEFAULT_GOAL := help

help:
	@echo "make reproduce   # every driver at SCALE=$(SCALE), then its verdicts (results/$(SCALE)/claims.md; paper: paper_claims.md)"
	@echo "make test        # lint (ruff), then the test suite"
	@grep -E '^[a-z0-9-]+:.*## ' $(MAKEFILE_LIST) | sed 's/:.*## /\t/' | sort

# torch is installed first and on its own so that pip takes a CPU build: the `+cpu` build from a
# local wheel or index where the machine has one (PyPI has none, so this fails fast elsewhere), else
# from PyTorch's CPU index, else the default build (macOS, where it is CPU-only anyway).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q "torch==$(TORCH_VERSION)+cpu" 2>/dev/null \
	  || $(BIN)/pip install -q "torch==$(TORCH_VERSION)+cpu" --extra-index-url https://download.pytorch.org/whl/cpu \
	  || $(BIN)/pip install -q "torch==$(TORCH_VERSION)"
	$(BIN)/pip install -q -e ".[test]"
	touch $@

setup: $(STAMP) ## create .venv and install the suite

test: lint ## lint, then run the test suite
	$(PY) -m pytest

lint: $(STAMP) ## ruff: style (100 columns) and likely bugs (pyproject.toml says which rules)
	$(BIN)/ruff check repro tests

reproduce: $(STAMP) ## run every driver at SCALE, then its verdicts: a smoke check below paper scale
	$(MAKE) race SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) bus-thresholds SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) fig-bus-lambda SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) fig-bus-batch SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) fig-bus-arrivals SCALE=$(SCALE)
	$(MAKE) fig-bus-load SCALE=$(SCALE)
	$(MAKE) scaling SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) fig-transfer SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) fig-transfer SCALE=$(SCALE) SEED=$(SEED) ARGS="--sim-version 2017-04-22"
	$(MAKE) fig-transfer SCALE=$(SCALE) SEED=$(SEED) ARGS=--corrected
	$(MAKE) wildfire-heuristics SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) wildfire-behaviour SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) beyond-races SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) beyond-mgae SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) beyond-sb3 SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) beyond-order SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) beyond-transfer-dt SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) learner-ablation SCALE=$(SCALE) SEED=$(SEED)
	$(MAKE) c9-inputs SCALE=$(SCALE) SEED=$(SEED)
	$(REPRO) claims --results-dir results/$(SCALE)

claims: $(STAMP) ## render paper_claims.md from results/paper/ (ARGS="--results-dir results/quick": a smoke check)
	$(REPRO) claims $(ARGS)

race: $(STAMP) ## race-condition table and figure (C10; alias table-race)
	$(REPRO) race --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-thresholds: $(STAMP) ## Optimized Thresholds by differential evolution (bus baseline; alias table-thresholds)
	$(REPRO) bus-thresholds --scale $(SCALE) --seed $(SEED) $(ARGS)

bus-eval: $(STAMP) ## return, loads and regularity of a bus policy (ARGS="--policy thresholds")
	$(REPRO) bus-eval $(ARGS)

train: $(STAMP) ## train a shared policy with PS-TRPO and M-GAE (ARGS="--env bus --epochs 10 --out runs/b")
	$(REPRO) train --scale $(SCALE) --seed $(SEED) $(ARGS)

fig-bus-lambda: $(STAMP) ## bus training curves over lambda (C1, C2; needs bus-thresholds)
	$(REPRO) fig-bus-lambda --scale $(SCALE) --seed $(SEED) $(ARGS)

fig-bus-batch: $(STAMP) ## bus training curves over the batch size (C3; needs bus-thresholds)
	$(REPRO) fig-bus-batch --scale $(SCALE) --seed $(SEED) $(ARGS)

fig-bus-arrivals: $(STAMP) ## bus arrival times per policy (C5; needs bus-thresholds, fig-bus-lambda)
	$(REPRO) fig-bus-arrivals --scale $(SCALE) $(ARGS)

fig-bus-load: $(STAMP) ## bus loads at the paper's records per policy (C4, C5; needs bus-thresholds, fig-bus-lambda)
	$(REPRO) fig-bus-load --scale $(SCALE) $(ARGS)

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

scaling: $(STAMP) ## event-driven vs time-stepped compute against N, table and figure (C11; alias fig-scaling)
	$(REPRO) scaling --scale $(SCALE) --seed $(SEED) $(ARGS)

fig-transfer: $(STAMP) ## train on ED and FS simulators, test on ED (C8, C9; ARGS="--sim-version 2017-04-22", "--learner suite", "--corrected")
	$(REPRO) fig-transfer --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-heuristics: $(STAMP) ## heuristic policies on the transfer study's ED test episodes (C8, C9)
	$(REPRO) wildfire-heuristics --scale $(SCALE) --seed $(SEED) $(ARGS)

wildfire-behaviour: $(STAMP) ## frequencies of a long ED-trained policy vs the flowchart (C6, C7)
	$(REPRO) wildfire-behaviour --scale $(SCALE) --seed $(SEED) $(ARGS)

beyond-races: $(STAMP) ## X2: races in the wildfire simulator, dT against N, beside C10 (after race)
	$(REPRO) beyond-races --scale $(SCALE) --seed $(SEED) $(ARGS)

beyond-order: $(STAMP) ## X4: C9's pair under both same-instant orders (reuses fig-transfer's runs)
	$(REPRO) beyond-order --scale $(SCALE) --seed $(SEED) $(ARGS)

learner-ablation: $(STAMP) ## X5: the transfer study, one learner setting at a time from the authors' (reuses fig-transfer's runs)
	$(REPRO) learner-ablation --scale $(SCALE) --seed $(SEED) $(ARGS)

c9-inputs: $(STAMP) ## C9's policies tested with health and sojourn clamped (after fig-transfer --sim-version 2017-04-22)
	$(REPRO) c9-inputs --scale $(SCALE) --seed $(SEED) $(ARGS)

beyond-mgae: $(STAMP) ## X1: M-GAE vs two other advantage estimators (reuses fig-bus-lambda's, fig-transfer's runs)
	$(REPRO) beyond-mgae --scale $(SCALE) --seed $(SEED) $(ARGS)

beyond-sb3: $(STAMP) ## X6: SB3's PPO with its GAE and with M-GAE against PS-TRPO, wildfire and bus
	$(REPRO) beyond-sb3 --scale $(SCALE) --seed $(SEED) $(ARGS)

beyond-transfer-dt: $(STAMP) ## X3: transfer to ED against 13 dT, race rate beside it (reuses fig-transfer's runs)
	$(REPRO) beyond-transfer-dt --scale $(SCALE) --seed $(SEED) $(ARGS)

# the paper's names
table-race: race
table-thresholds: bus-thresholds
fig-scaling: scaling

clean: ## remove the virtual environment and caches, numba's compiled kernels too (results and figures stay)
	rm -rf $(VENV) .pytest_cache .hypothesis
	find repro tests -name __pycache__ -prune -exec rm -rf {} +
