# pneufdd developer commands. Every target creates .venv and installs what it needs.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
# numba keeps its compiled kernels here, so repeated runs skip compilation.
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache
export MPLBACKEND ?= Agg

.PHONY: demo test lint format typecheck unit bench clean prebuilt

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# The twin compiled ahead of time (docs/twin.md): short commands start without loading
# numba. Compiled only when the sources changed; without a C compiler the JIT runs
# (same results), so a failed build does not stop the target that wanted it.
prebuilt: $(STAMP)
	-$(BIN)/pneufdd build-twin

demo: $(STAMP) prebuilt
	$(BIN)/pneufdd demo --out build/demo

lint: $(STAMP)
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/ruff check src tests benchmarks

format: $(STAMP)
	$(BIN)/ruff format src tests benchmarks
	$(BIN)/ruff check --fix src tests benchmarks

typecheck: $(STAMP)
	$(BIN)/mypy

# the suite runs on numba's JIT, like CI's fresh clone; tests/test_sim_prebuilt.py
# builds its own prebuilt twin and compares the two
unit: $(STAMP)
	PNEUFDD_PREBUILT=0 $(BIN)/pytest -q -n 2

test: lint typecheck unit

bench: $(STAMP) prebuilt
	$(BIN)/python benchmarks/run.py

clean:
	rm -rf $(VENV) build .numba_cache .pytest_cache .mypy_cache .ruff_cache

# Issue 14/39: the full bad-input corpus (>= 1,000 invocations, each a fresh process
# under a 4 GB cap and a 120 s limit); `make test` runs a quick slice in-process
# (tests/test_fuzz_cli.py). One command, or another seed:
#   make fuzz FUZZ_ARGS="--command monitor --command 'reference build' --seed 97000300"
FUZZ_ARGS ?=
.PHONY: fuzz
fuzz: $(STAMP)
	$(BIN)/python tests/fuzzing.py --out build/fuzz --json build/fuzz/outcomes.json $(FUZZ_ARGS)
