# drillstring: `make demo` runs the main job, `make test` runs lint + the whole suite,
# `make test-fast` the tests that need no FMU build and no host (markers in pyproject.toml).
# Both run on PYTEST_WORKERS processes (pytest-xdist; the tests of a file that share a
# module's fixture on one of them, the session's builds made once for all: tests/conftest.py).
# Both use one virtual environment, .venv, created with `python3 -m venv` on first use and
# reinstalled (editable, with the test extra: numba and the FMI hosts too) only when
# pyproject.toml changes.

PYTHON ?= python3
PYTEST_WORKERS ?= 2
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp

.PHONY: venv test test-fast demo lint format clean

venv: $(STAMP)

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install -e '.[test]'
	touch $(STAMP)

test: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/pytest -q -n $(PYTEST_WORKERS) --dist loadgroup

test-fast: venv
	$(BIN)/pytest -q -n $(PYTEST_WORKERS) --dist loadgroup -m "not fmu and not slow"

# The main job, a chain of artifacts each computed once (drillstring/apps/demo.py): the LMI design
# with A from the axial analysis and the input-constrained design for the rig's top drive, the
# FMUs built with the gains, then the figures, the co-simulation / monolithic agreement and the
# controllers on the top drive. Everything lands in out/ and build/.
demo: venv
	$(BIN)/drillstring design --out out/design --torque-limit tds-11sa
	$(BIN)/python build_fmus.py --gains out/design/gains.json --out build
	$(BIN)/drillstring demo --design out/design --fmus build --out out

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: venv
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

clean:
	rm -rf build out .pytest_cache .ruff_cache
