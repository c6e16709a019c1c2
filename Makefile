# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test lint docs bench clean

# setup.py builds the C loop library into the package (src/chaplygin/numeric/_dop853_loop.*)
$(STAMP): pyproject.toml setup.py
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,sweep]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/chaplygin demo

# on all cores (pytest-xdist); tests/conftest.py schedules: modules with costly shared fixtures
# stay on one worker, the longest start first
test: $(STAMP)
	$(BIN)/python -m pytest -n auto

# the house checks (also run by CI before the tests): lint, formatting, types, layers
$(VENV)/.lint: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[lint]'
	touch $(VENV)/.lint

lint: $(VENV)/.lint
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy
	$(BIN)/lint-imports

# the documentation site (mkdocs.yml) into site/: offline, warnings as errors; it runs the
# tutorial notebooks (docs/notebooks) so that their pages show the results
$(VENV)/.docs: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[docs]'
	touch $(VENV)/.docs

docs: $(VENV)/.docs
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

bench: $(STAMP)
	$(BIN)/python benchmarks/derive.py

clean:
	rm -rf $(VENV) .pytest_cache .hypothesis build dist site src/*.egg-info src/chaplygin/numeric/_dop853_loop.*
