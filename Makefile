# rapid-cosim: one target per experiment; every target sets up what it needs from nothing.
PYTHON  ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
PY      := $(BIN)/python
RC      := $(BIN)/rapid-cosim
STAMP   := $(VENV)/.installed
SEED    ?= 1
N_JOBS  ?= 2

.DEFAULT_GOAL := help
.PHONY: help install fmus demo test test-fast bench clean

help:  ## list the targets
	@grep -E '^[a-zA-Z0-9_%-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-14s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml constraints.txt
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -c constraints.txt -e '.[test]'
	touch $(STAMP)

install: $(STAMP)  ## create .venv and install rapid-cosim with pinned dependencies

fmus: $(STAMP)  ## compile the iGrGen test benches into fmus/ (only what changed)
	$(RC) build

demo: fmus  ## set up and run the main job on the bundled data
	$(RC) demo

test: fmus  ## run the test suite
	$(PY) -m pytest -q

bench: fmus  ## print the performance figures
	$(PY) benchmarks/run.py

clean:  ## remove build outputs (fmus, results); keeps .venv
	rm -rf fmus/*.fmu fmus/*.json fmus/.work results
