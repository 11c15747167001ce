# csim developer targets. `make run` and `make test` set up .venv on first use.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install run test test-all batch bench bench-scaling lint docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/python -m csim.warmup
	touch $(STAMP)

install: $(STAMP)  ## create .venv, install csim with its test dependencies, compile the kernels once

run: $(STAMP)  ## run the default case
	$(BIN)/csim run configs/quick_return.yaml -o results/quick_return.h5

test: $(STAMP)  ## the default test suite (slow tests excluded), one worker per core
	$(BIN)/python -m pytest -n auto

test-all: $(STAMP)  ## every test, the slow ones included
	$(BIN)/python -m pytest -n auto -m ""

batch: $(STAMP)  ## the accuracy claims and the IFToMM benchmark problems, run and checked (configs/batch/); JUnit reports in results/
	$(BIN)/csim batch configs/batch/accuracy.yaml --junit results/batch_junit.xml
	$(BIN)/csim batch configs/batch/iftomm.yaml --junit results/batch_iftomm_junit.xml

bench: $(STAMP)  ## speed and accuracy benchmark, side by side in one run, then the scaling table
	$(BIN)/python bench/run.py
	$(BIN)/python bench/iftomm.py
	$(BIN)/python bench/scaling.py --plain-c

bench-scaling: $(STAMP)  ## the scaling table alone: derive, cc, first run and per-RHS time against mechanism size
	$(BIN)/python bench/scaling.py --plain-c

lint: $(STAMP)  ## ruff, at the version pinned in pyproject's lint extra
	$(BIN)/python -m pip install --quiet -e '.[lint]'
	$(BIN)/python -m ruff check csim tests bench

docs: $(STAMP)  ## build the documentation into site/ (mkdocs-material, strict: a broken link or anchor fails)
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	$(BIN)/python -m mkdocs build --strict

clean:
	rm -rf $(VENV) results site .pytest_cache build *.egg-info
