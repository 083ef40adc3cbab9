# Two commands do all the set-up: `make demo` and `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
OUT ?= output/demo

.PHONY: demo check test test-long test-all extras bench lint docs docs-tables clean clean-cache

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[all,dev]"
	$(BIN)/python -m mirror_avatar.warm_up
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/mirror-avatar reproduce --out $(OUT)

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/mypy
	$(BIN)/lint-imports

docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet

# The documents' tables of declared keys (a protocol's, the IMS generator's), written from them.
docs-tables: $(STAMP)
	$(BIN)/python docs/keys.py

# The tests print their 15 slowest; `check` is the inner loop (lint and the unit tests).
# Three tiers: `make test` (about 10 minutes on two cores) leaves out the tests marked `long`
# (end-to-end runs of seconds to a minute each: avatar builds, pilots, reproduce, the cluster, the
# longer browser flows), which `make test-long` runs and CI runs after it, and `slow` (minutes of
# work each), which only `make test-all` runs.
# WORKERS: one test process per core; a worker that runs out of tests takes half of another's
# queue (worksteal), so no worker is left with a backlog at the end. The tests whose trials run
# on the wall clock (browser, realtime) run after the others, one at a time: beside a worker's
# CPU-bound tests on two cores, a lab server's ticks fell seconds behind and ended its trials.
WORKERS ?= $(shell nproc)
PYTEST := $(BIN)/pytest -p no:cacheprovider --durations=15
PARALLEL := $(PYTEST) -n $(WORKERS) --dist worksteal
ON_THE_CLOCK := browser or realtime

# The tests of a tier ($(1): a marker expression), the ones on the wall clock last, one at a time.
define tier
	$(PARALLEL) -m "($(1)) and not ($(ON_THE_CLOCK))"
	$(PYTEST) -m "($(1)) and ($(ON_THE_CLOCK))"
endef

check: lint
	$(PARALLEL) -m "not slow and not long" tests/unit

test: lint docs
	$(call tier,not slow and not long)

test-long: $(STAMP)
	$(call tier,long and not slow)

test-all: lint docs
	$(call tier,not slow and not long)
	$(call tier,long or slow)

# Each optional extra on a fresh virtual environment, with the commands it serves (minutes of
# installing from the registries, so not part of `test`; .ci/run runs it after `make test`).
extras: $(STAMP)
	$(BIN)/python tests/extras/check_extras.py

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py --out benchmarks/results.md

clean: clean-cache
	rm -rf $(VENV) output site .pytest_cache .ruff_cache .mypy_cache

clean-cache:
	find src benchmarks -name '*.nbi' -delete -o -name '*.nbc' -delete
