# Two entry points: `make demo` and `make test` (the layer contract, ruff, then every test). Each creates .venv when missing and installs
# what it needs; a stamp file keeps repeated runs fast until pyproject.toml changes.
PYTHON ?= python3
VENV ?= .venv
# Pinned to the CPU build on this machine's disk; override e.g. TORCH_SPEC="torch==2.14.1".
TORCH_SPEC ?= torch==2.13.0
PIP_FLAGS ?= -q --disable-pip-version-check
# The Khronos glTF validator (npm) for the GLB export test; installed only where npm exists.
GLTF_VALIDATOR ?= gltf-validator@2.0.0-dev.3.10
# three.js, whose loader and mixer tools/threejs_check.mjs runs on our GLBs (the client test tier)
THREE_JS ?= three@0.187.0
BIN := $(VENV)/bin
STAMP := $(VENV)/.hrr-installed
# Python's bytecode cache on even where the environment turns it off (PYTHONDONTWRITEBYTECODE=1 in some
# containers): a second test run then skips compiling the package and re-rewriting the asserts of every
# test module, about 7 s a pytest worker
export PYTHONDONTWRITEBYTECODE :=

.PHONY: install demo test test-fast test-slow clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/pip install $(PIP_FLAGS) "$(TORCH_SPEC)"
	$(BIN)/pip install $(PIP_FLAGS) -e ".[dev,preview,video,export,eval,sim,cluster,bodies,sign,onnx]"
	@if command -v npm >/dev/null 2>&1; then \
		mkdir -p $(VENV)/node && cd $(VENV)/node && npm install --silent --no-audit --no-fund $(GLTF_VALIDATOR) $(THREE_JS); \
	else echo "npm not found: the GLB validator test will be skipped"; fi
	touch $(STAMP)

install: $(STAMP)

demo: install
	$(BIN)/hrr-demo

# pytest-xdist: a worker per core, each test file on one worker (its module fixtures built once),
# each worker's torch and kernels on its share of the cores (tests/conftest.py); PARALLEL= runs serially
PARALLEL ?= -n auto --dist loadfile

# layers (import-linter, pyproject's contract), lint and format (ruff, 110 wide), then the tests; the slowest 15 are listed
# at the end so that the ten-minute budget (docs/testing.md) is watched on every run, CI's included
test: install
	$(BIN)/lint-imports
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/python -m pytest -q --durations=15 $(PARALLEL)

# The quick loop (docs/testing.md): no lint, and none of the tests that train a model or run the
# cloth simulator (pyproject's markers); about a minute. PYTEST_ARGS adds options, e.g. -x or tests/motion.
FAST_MARKERS ?= not slow and not sim
PYTEST_ARGS ?=
test-fast: install
	$(BIN)/python -m pytest -q -m "$(FAST_MARKERS)" $(PARALLEL) $(PYTEST_ARGS)

# what test-fast leaves out: the tests that train or simulate
test-slow: install
	$(BIN)/python -m pytest -q -m "not ($(FAST_MARKERS))" $(PARALLEL) $(PYTEST_ARGS)

clean:
	rm -rf $(VENV) hrr_work .pytest_cache
