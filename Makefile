# rigd — two commands do everything on a fresh machine: `make demo` and `make test`.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache
export MPLBACKEND ?= Agg

.PHONY: demo test lint bench peers-deps venv clean

venv: $(STAMP)

# recipes that precede `bench` print nothing on stdout: `make bench` stdout is one JSON object
# constraints.txt pins every package to the versions the README's figures were made with: the
# structured H∞ design has near-equal optima, and a fresh install that took newer numpy/scipy
# releases moved the demo's damping figures by 10-20 % (regenerate both together when you
# upgrade: `pip freeze`, `make demo`, tools/readme_demo_table.py, `make bench`)
$(STAMP): pyproject.toml constraints.txt
	@echo "make: creating $(VENV) and installing rigd into it" >&2
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@$(BIN)/python -m pip install -q --upgrade pip setuptools wheel >&2
	@$(BIN)/python -m pip install -q -c constraints.txt -e '.[test]' >&2
	@touch $(STAMP)

demo: $(STAMP)
	rm -rf demo-out   # the demo's own output is replaced on every run (run dirs never are)
	$(ONE_BLAS_THREAD) $(BIN)/rigd demo --out demo-out   # one BLAS thread, as make test: the figures the README states and test_readme_figures checks

# style/correctness rules and the layering contracts (pyproject.toml: tool.ruff, tool.importlinter)
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

# `make test`: lint, then pytest in two parts; both always run, one exit status (fails if either
# fails). 1. Everything but the timing-sensitive tests, on PYTEST_WORKERS processes
# (pytest-xdist; worksteal: the long diagnosis tests do not leave one worker idle at the end),
# BLAS pinned to one thread per worker so that two workers do not fight over the 2 cores.
# 2. The timing-sensitive tests (real-time daemons, sockets, the browser console) alone and
# serially, as before. Each test is in exactly one part: part 1 ignores what part 2 runs.
# Plain `python -m pytest` still runs the whole suite serially.
REALTIME_TESTS := tests/service tests/loop tests/web tests/browser \
                  tests/experiments/test_daemon_experiment.py
PYTEST_WORKERS ?= 2
ONE_BLAS_THREAD := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1

test: lint
	@rc=0; \
	echo "make test [1/2]: compute tests, $(PYTEST_WORKERS) workers"; \
	$(ONE_BLAS_THREAD) $(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist worksteal \
	    $(addprefix --ignore=,$(REALTIME_TESTS)) tests || rc=1; \
	echo "make test [2/2]: timing-sensitive tests, serially: $(REALTIME_TESTS)"; \
	$(BIN)/python -m pytest -q $(REALTIME_TESTS) || rc=1; \
	exit $$rc

bench: $(STAMP)
	@$(BIN)/python -m bench

# `python -m bench peers` compares with SysIdentPy's NARX: its wheel caps numpy at 2.3.5
# (metadata only; it runs on the pinned 2.4.6), so it is installed without its dependencies
peers-deps: $(STAMP)
	$(BIN)/pip install --no-deps -c constraints.txt sysidentpy

clean:
	rm -rf $(VENV) demo-out build *.egg-info
