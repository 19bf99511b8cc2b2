# Two entry points for a fresh machine (see README):
#   make run    create .venv if needed, then run the pipeline on config/config.yaml
#               (make run CONFIG=config/tiny.yaml: a preset, or a file of yours, layered on it)
#   make test   create .venv, Chromium (report-deps) and npm (asset-deps) if needed, then the lint checks and the test suite
#   make report build results/report.html and screenshots of it (CONFIG as for run)
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
CORES ?= 2

# A CONFIG file that does not exist stops here, in one line naming it: Snakemake 9.27.1 itself
# answers a missing --configfile with a 26-line traceback (its loader opens the file outside the
# try that would have said "Config file ... not found."), before the Snakefile runs.
CONFIG ?=
ifneq ($(strip $(CONFIG)),)
ifeq ($(wildcard $(CONFIG)),)
$(error CONFIG=$(CONFIG): no such file (the presets: $(filter-out config/paper_results.yaml,$(wildcard config/*.yaml))))
endif
endif
CONFIGFILE := $(if $(strip $(CONFIG)),--configfile $(CONFIG))

.PHONY: run test lint bench clean-results report report-deps asset-deps slurm-test

$(BIN)/.installed: workflow/pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e "./workflow[workflow,test,slurm]"
	touch $@

run: $(BIN)/.installed asset-deps
	$(BIN)/snakemake --cores $(CORES) $(CONFIGFILE)

test: $(BIN)/.installed report-deps asset-deps lint
	$(BIN)/python -m pytest -q tests

# The SLURM profile on a single-node cluster started for the test (root; tests/slurm_cluster.sh).
slurm-test: $(BIN)/.installed
	$(BIN)/python -m pytest -q tests/test_pipeline.py -k slurm

# Lint and format checks (settings in pyproject.toml at the root); any violation fails.
lint: $(BIN)/.installed
	$(BIN)/ruff check .
	$(BIN)/snakefmt --config pyproject.toml --check workflow/Snakefile workflow/rules
	$(BIN)/snakemake --lint

# Speed, memory and accuracy measurements (bench/out/*.tsv); run on an idle machine.
bench: $(BIN)/.installed
	$(BIN)/python bench/spectral_bench.py
	$(BIN)/python bench/optimise_bench.py
	$(BIN)/python bench/observations_bench.py

clean-results:
	rm -rf results .snakemake

# $(call apt_install,TARGET,PACKAGES,WHAT IS LOST): Debian's PACKAGES, installed with apt-get as
# root or through passwordless sudo; a machine where neither works only warns.
apt_get = apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $(1) >/dev/null
define apt_install
	@if [ "$$(id -u)" = 0 ]; then $(call apt_get,$(2)) || echo "$(1): apt-get install $(2) failed" >&2; \
	elif sudo -n true 2>/dev/null; then sudo -n sh -c '$(call apt_get,$(2))' || echo "$(1): sudo apt-get install $(2) failed" >&2; \
	else echo "$(1): cannot install $(2) (not root, no passwordless sudo); $(3)" >&2; fi
endef

# Headless Chromium for the report screenshots (bench/report_screenshot.py,
# tests/test_pipeline.py): the screenshot test skips without it, except under CI
# (CI=true), where it fails.
CHROMIUM := $(shell command -v chromium || command -v chromium-browser || command -v google-chrome)
report-deps:
ifeq ($(CHROMIUM),)
	$(call apt_install,report-deps,chromium fonts-dejavu-core,report screenshots are skipped)
endif

# npm, which fetches the asset package of the captured light and the scans (rule
# fetch_asset_package, freqbrdf.scene.assets).
NPM := $(shell command -v npm)
asset-deps:
ifeq ($(NPM),)
	$(call apt_install,asset-deps,npm,captured light and scans need it)
endif

report: $(BIN)/.installed report-deps asset-deps
	$(BIN)/snakemake --cores $(CORES) $(CONFIGFILE)
	$(BIN)/snakemake --report results/report.html $(CONFIGFILE)
	$(BIN)/python bench/report_screenshot.py results/report.html --out results/report_screenshots
