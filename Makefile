# rigd — two commands do everything on a fresh machine: `make demo` and `make test`.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache
export MPLBACKEND ?= Agg

.PHONY: demo test lint bench venv clean

venv: $(STAMP)

# recipes that precede `bench` print nothing on stdout: `make bench` stdout is one JSON object
$(STAMP): pyproject.toml
	@echo "make: creating $(VENV) and installing rigd into it" >&2
	@test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@$(BIN)/python -m pip install -q --upgrade pip setuptools wheel >&2
	@$(BIN)/python -m pip install -q -e '.[test]' >&2
	@touch $(STAMP)

demo: $(STAMP)
	rm -rf demo-out   # the demo's own output is replaced on every run (run dirs never are)
	$(BIN)/rigd demo --out demo-out

# style/correctness rules and the layering contracts (pyproject.toml: tool.ruff, tool.importlinter)
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

test: lint
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	@$(BIN)/python -m bench

clean:
	rm -rf $(VENV) demo-out build *.egg-info
