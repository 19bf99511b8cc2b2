# Two entry points for a fresh machine (see README):
#   make run    create .venv if needed, then run the pipeline on config/config.yaml
#   make test   create .venv if needed, then run the test suite
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
CORES ?= 2

.PHONY: run test bench clean-results

$(BIN)/.installed: workflow/pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e "./workflow[test]"
	touch $@

run: $(BIN)/.installed
	$(BIN)/snakemake --cores $(CORES)

test: $(BIN)/.installed
	$(BIN)/python -m pytest -q tests

bench: $(BIN)/.installed
	$(BIN)/python bench/render_bench.py

clean-results:
	rm -rf results .snakemake
