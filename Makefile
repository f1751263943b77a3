# Gecko: `make serve` runs the service, `make test` runs the tests. Both bootstrap everything.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.gecko-installed
HOST ?= 127.0.0.1
PORT ?= 8000
WORKERS ?= 1
SHUTDOWN_GRACE_S ?= 10
export GECKO_HOME ?= $(CURDIR)/.gecko

.PHONY: help setup data serve test test-fast lint format bench clean

help: ## list the targets
	@grep -E '^[a-z-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  %-10s %s\n", $$1, $$2}'

$(STAMP): pyproject.toml scripts/bootstrap.sh tools/package-lock.json
	@bash scripts/bootstrap.sh "$(PYTHON)" "$(VENV)"
	@touch $(STAMP)

setup: $(STAMP) ## create .venv and install Gecko with its test and dev tools

data: setup ## build the built-in characters' offline data (cached; instant when up to date)
	@$(VENV)/bin/gecko-build-data --all --cache-dir "$(GECKO_HOME)/cache"

serve: data ## run the service on HOST:PORT (127.0.0.1:8000) with built-in scenes and characters
	@$(VENV)/bin/uvicorn service.app:create_app --factory --host $(HOST) --port $(PORT) --workers $(WORKERS) --timeout-graceful-shutdown $(SHUTDOWN_GRACE_S) --no-access-log

test: data ## run the whole test suite
	@$(PY) -m pytest

test-fast: setup ## run the tests, skipping those marked slow
	@$(PY) -m pytest -m "not slow"

lint: setup ## ruff, mypy (strict) and the import-layer contract
	@$(VENV)/bin/ruff check .
	@$(VENV)/bin/ruff format --check .
	@$(VENV)/bin/mypy service planner trajectory clients
	@$(VENV)/bin/lint-imports

format: setup ## apply ruff's formatting and safe fixes
	@$(VENV)/bin/ruff format .
	@$(VENV)/bin/ruff check --fix .

bench: data ## run every benchmark (prints medians, asserts nothing)
	@for b in bench/*.py; do case $$b in bench/_*) continue;; esac; echo "== $$b"; $(PY) $$b || exit 1; done

clean: ## remove the virtual environment and caches (keeps uploaded scenes)
	rm -rf $(VENV) $(GECKO_HOME)/cache .pytest_cache .mypy_cache .ruff_cache
