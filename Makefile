PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# everything but Ray (its only test is slow): what `make test` needs, installed from
# pyproject.toml by uv (from PyPI: parallel downloads, no byte-compilation; a fresh
# install took 16 s against pip's 32 s on the 2-core CPU), or, should uv not install,
# by pip (upgraded first: Python 3.11's pip 23 resolved 55 s slower; --no-compile)
TEST_STAMP := $(VENV)/.installed-test
INSTALL = $(BIN)/python -m pip install --quiet uv && $(BIN)/uv pip install --quiet \
	--python $(BIN)/python -e ".[$(1)]" || ($(BIN)/python -m pip install --quiet --upgrade pip \
	&& $(BIN)/python -m pip install --quiet --no-compile -e ".[$(1)]")

.PHONY: install test test-all lint reproduce bench bench-quick fuzz clean

$(TEST_STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV)
	$(call INSTALL,test)
	@touch $(TEST_STAMP)

$(STAMP): $(TEST_STAMP)
	$(call INSTALL,dev)
	@touch $(STAMP)

install: $(STAMP)

lint: $(TEST_STAMP)
	$(BIN)/ruff check jaxbal experiments tests benchmarks
	$(BIN)/ruff format --check jaxbal experiments tests benchmarks

# --dist worksteal: each worker starts with a contiguous half of the files, so a file's
# tests share the programs they compile (the suite is compile-bound), and the worker
# that finishes first takes tests from the other's queue (8m04 -> 7m31 on the 2-core
# CPU, same run, against --dist loadfile, which left the end of the run to one worker)
test: lint
	$(BIN)/python -m pytest -n 2 --dist worksteal -q -m "not slow"

test-all: lint $(STAMP)
	$(BIN)/python -m pytest -n 2 --dist worksteal -q

fuzz: $(STAMP)
	JAXBAL_FUZZ=long $(BIN)/python -m pytest -q tests/test_fuzz.py tests/test_fuzz_entry_points.py --hypothesis-show-statistics

reproduce: $(STAMP)
	$(BIN)/jaxbal reproduce --out results

bench: $(STAMP)
	$(BIN)/python benchmarks/run.py --out benchmarks/results

# smoke run of every section at small sizes (10 min on the busy 2-core CPU: compilation);
# writes to a temporary folder, never benchmarks/results nor the README
bench-quick: $(STAMP)
	$(BIN)/python benchmarks/run.py --quick

clean:
	rm -rf $(VENV) results .pytest_cache
