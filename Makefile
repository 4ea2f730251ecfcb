# rigd — two commands do everything on a fresh machine: `make demo` and `make test`.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache
export MPLBACKEND ?= Agg
# Python writes no bytecode cache when PYTHONDONTWRITEBYTECODE is set (some shells and CI images
# set it): then every process — each pytest worker, each `rigd` command and daemon a test starts,
# the daemon's socket and writer processes — compiled every module of rigd again, and pytest
# rewrote the asserts of every test module again (≈ 7 CPU-s per pytest process, 0.3-0.5 s per
# command). The caches go to __pycache__ folders (git-ignored) beside the sources.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: demo test test-long lint bench figures peers-deps venv clean

venv: $(STAMP)

# recipes that precede `bench` print nothing on stdout: `make bench` stdout is one JSON object
# constraints.txt pins every package to the versions the figures in docs/figures/*.json were
# made with (each file names its package versions): the structured H∞ design has near-equal
# optima, and newer numpy/scipy releases move the demo's damping figures by 10-20 %
# (regenerate together when you upgrade: `pip freeze`, `make demo`, `make bench`)
$(STAMP): pyproject.toml constraints.txt
	@echo "make: creating $(VENV) and installing rigd into it" >&2
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@$(BIN)/python -m pip install -q --upgrade pip setuptools wheel >&2
	@$(BIN)/python -m pip install -q -c constraints.txt -e '.[test]' >&2
	@touch $(STAMP)

# the demo, then its figures saved as docs/figures/demo.json (host, load, commit, date,
# packages) and docs/figures.md + the README's figures table rendered from the JSON files
# (the load averages before it starts: the host's own load, without the demo's)
demo: $(STAMP)
	rm -rf demo-out   # the demo's own output is replaced on every run (run dirs never are)
	@lb="$$(cut -d' ' -f1-3 /proc/loadavg)"; set -x; \
	$(ONE_BLAS_THREAD) $(BIN)/rigd demo --out demo-out && \
	$(BIN)/python -m tools.figures save-demo demo-out/summary.json --load-before "$$lb"

# render docs/figures.md and the README's figures table from the committed docs/figures/*.json
figures: $(STAMP)
	$(BIN)/python -m tools.figures

# style/correctness rules and the layering contracts (pyproject.toml: tool.ruff, tool.importlinter)
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

# `make test`: lint, then pytest in two parts AT ONCE; both always run, one exit status (fails if
# either fails). 1. Everything but the timing-sensitive tests, on PYTEST_WORKERS processes
# (pytest-xdist; worksteal: the long diagnosis tests do not leave one worker idle at the end),
# at `nice` TEST_NICE so that they only take the CPU the other part leaves. 2. The
# timing-sensitive tests (real-time daemons, sockets, the browser console) in REALTIME_WORKERS
# processes of their own, beside part 1 at normal priority: they take about one core (a real-time
# loop sleeps, then spins the end of each period), so run after part 1 (as before) they left
# the other core idle for ≈ 6 min; they pass with every core busy (`under-load`), and part 1
# yields to them. Their output is printed when part 1 ends. BLAS pinned to one thread per process so that they do not fight over the 2
# cores. Each test is in exactly one part: part 1 ignores what part 2 runs. Outputs that tests
# of both parts read (the quick demo, tests/sharedruns.py) are made once, in a temporary
# folder ($RIGD_TEST_SHARED) removed at the end. Plain `python -m pytest` still runs the whole
# suite serially.
# Before both parts, tests/warm_kernels.py compiles the big numba kernels (the loop's cycle, both
# simulated plants) once into numba's cache, a few processes in parallel: on a clean clone the
# cache is empty and otherwise every worker and every daemon the tests start compiled the same
# kernels at the same time (minutes of CPU each on 2 cores); after it they load them. Part 2
# starts once the loop's, the paper plant's, the models' and the serial kernels are in (its
# daemons run the paper plant); the physics-grade plant's long compilation (the quick demo's
# plant, part 1) goes on beside it and part 1 starts when it is done.
# tests/experiments/test_operator_impact.py runs a real-time loop (SCHED_FIFO, above every
# niced worker): in part 1 it took the CPU from part 2's real-time tests. tests/faults: the
# fault-injection tests on real daemons (listed once the folder exists).
REALTIME_TESTS := tests/service tests/loop tests/web tests/browser \
                  tests/experiments/test_daemon_experiment.py \
                  tests/experiments/test_operator_impact.py $(wildcard tests/faults)
# soak and endurance runs carry the pytest marker `long` (pyproject.toml): `make test` leaves
# them out, `make test-long` runs them (and .ci/run runs it after `make test`)
NOT_LONG := -m "not long"
PYTEST_WORKERS ?= 2
# part 2's tests mostly wait on real time (a daemon's start, seconds of a 5 kHz loop): two
# processes (one file each at a time: --dist loadfile keeps a module's daemon fixture in one
# process) halve its wall time for little CPU; they pass beside each other as under under-load
REALTIME_WORKERS ?= 1
TEST_NICE ?= 10
ONE_BLAS_THREAD := OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
# a job started with `&` in make's (non-interactive) shell ignores SIGINT, and so would its
# pytest: this restores it before exec'ing the command, so that Ctrl-C (and the trap below)
# stop part 2 through pytest's KeyboardInterrupt, with its fixtures' teardown (the daemons)
SIGINT_BACK := $(BIN)/python -c "import os, signal, sys; signal.signal(signal.SIGINT, \
               signal.SIG_DFL); os.execv(sys.argv[1], sys.argv[1:])"

test: lint
	@rc=0; rt=; wr=; RIGD_TEST_SHARED=$$(mktemp -d); export RIGD_TEST_SHARED; \
	trap 'test -z "$$rt" || kill -INT $$rt 2>/dev/null; test -z "$$wr" || kill $$wr 2>/dev/null; rm -rf "$$RIGD_TEST_SHARED"' EXIT; \
	trap 'exit 130' INT TERM; \
	echo "make test [0/2]: numba's kernels compiled once into its cache (tests/warm_kernels.py)"; \
	$(ONE_BLAS_THREAD) $(BIN)/python tests/warm_kernels.py reynolds & wr=$$!; \
	$(ONE_BLAS_THREAD) $(BIN)/python tests/warm_kernels.py --parallel sim models serial || rc=1; \
	echo "make test [2/2]: timing-sensitive tests, $(REALTIME_WORKERS) workers, beside part 1 (output when part 1 ends): $(REALTIME_TESTS)"; \
	$(ONE_BLAS_THREAD) $(SIGINT_BACK) $(BIN)/python -m pytest -q -n $(REALTIME_WORKERS) \
	    --dist loadfile $(NOT_LONG) $(REALTIME_TESTS) \
	    >"$$RIGD_TEST_SHARED/realtime.log" 2>&1 & rt=$$!; \
	wait $$wr || rc=1; wr=; \
	echo "make test [1/2]: compute tests, $(PYTEST_WORKERS) workers at nice $(TEST_NICE)"; \
	$(ONE_BLAS_THREAD) nice -n $(TEST_NICE) $(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) \
	    --dist worksteal $(NOT_LONG) $(addprefix --ignore=,$(REALTIME_TESTS)) tests || rc=1; \
	echo "make test [2/2]: timing-sensitive tests (waiting for them to end)"; \
	wait $$rt || rc=1; rt=; \
	cat "$$RIGD_TEST_SHARED/realtime.log"; \
	exit $$rc

# `make test-long`: the soak/endurance tests and the further cases of the costly behaviour tests
# (marker `long`: another seed or rescaling of one make test runs), one process, after the kernels are
# warm; pytest's "no test selected" (exit 5) is a pass while there are none
test-long: $(STAMP)
	@$(ONE_BLAS_THREAD) $(BIN)/python tests/warm_kernels.py
	@$(ONE_BLAS_THREAD) $(BIN)/python -m pytest -q -m long tests; rc=$$?; \
	if [ $$rc = 5 ]; then echo "make test-long: no test is marked long"; rc=0; fi; exit $$rc

# every section's figures to docs/figures/bench-<section>.json, the pages rendered from them
bench: $(STAMP)
	@$(BIN)/python -m bench --save

# `python -m bench peers` compares with SysIdentPy's NARX: its wheel caps numpy at 2.3.5
# (metadata only; it runs on the pinned 2.4.6), so it is installed without its dependencies
peers-deps: $(STAMP)
	$(BIN)/pip install --no-deps -c constraints.txt sysidentpy

clean:
	rm -rf $(VENV) demo-out build *.egg-info
