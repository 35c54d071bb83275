# Two commands for a fresh Debian 12 machine (root):
#   make run    install everything, then build the main target results/slide/metrics.csv
#   make test   install everything, then run the test suite
# Both are idempotent: the install step is skipped when nothing it depends on changed.

SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.graphdem-installed
APT_STAMP := $(VENV)/.graphdem-apt
TARGET ?= results/slide/metrics.csv
CORES ?= 2
# Debian packages, each with the command that tells it is there (-: none, dpkg decides): the DEM engines, venv,
# Chromium with its WebDriver for the test that renders snakemake --report in a browser, and a C++ compiler with
# the Python headers for torch.compile's CPU kernels (runtime switch compile; python3-config names the headers of
# the python3 the venv is made from).
APT_PACKAGES := lammps:lmp yade:yade python3-venv:- chromium:chromium chromium-driver:chromedriver g++:g++ \
  python3-dev:python3-config

.PHONY: install run test lint clean-results

install: $(STAMP)

# Installs only what is missing (a machine with lammps and yade still gets chromium); rechecked when this
# Makefile changes.
$(APT_STAMP): Makefile
	@missing=""; \
	for entry in $(APT_PACKAGES); do \
	  pkg=$${entry%%:*}; cmd=$${entry#*:}; \
	  if [ "$$cmd" != "-" ] && command -v "$$cmd" >/dev/null; then continue; fi; \
	  dpkg-query -W -f='$${Status}' "$$pkg" 2>/dev/null | grep -q "ok installed" || missing="$$missing $$pkg"; \
	done; \
	if [ -z "$$missing" ]; then \
	  echo "[install] apt packages already present"; \
	else \
	  echo "[install] apt-get install$$missing"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing; \
	fi
	@mkdir -p $(VENV) && touch $@

# The tested set: constraints.txt pins every dependency exactly (pyproject.toml gives only ranges). torch goes
# first, on its own, at its pin 2.13.0: the CPU build (a bare `torch` would pull gigabytes of CUDA packages).
$(STAMP): pyproject.toml constraints.txt $(APT_STAMP)
	@$(PY) -m pip --version >/dev/null 2>&1 || python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -c constraints.txt torch
	$(PY) -m pip install -q -c constraints.txt -e '.[dev]'
	@touch $@

run: install
	@echo "[run] building $(TARGET) with $(CORES) cores"
	$(VENV)/bin/snakemake -c$(CORES) $(TARGET)

test: install
	$(VENV)/bin/ruff check generators surrogate evaluation graphdem workflow/graphdem_workflow tests
	$(VENV)/bin/python -m pytest -q -n $(CORES) --dist loadgroup --no-loadscope-reorder --durations=15

lint: install
	$(VENV)/bin/ruff check generators surrogate evaluation graphdem workflow/graphdem_workflow tests

clean-results:
	rm -rf results/*/ .snakemake
