"""Shared pytest set-up."""

import os
import sys
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
ROOT = Path(__file__).resolve().parents[1]
os.environ.setdefault("NUMBA_CACHE_DIR", str(ROOT / ".venv" / "numba-cache"))
SHARED = ROOT.parent / "shared"
if str(ROOT) not in sys.path:  # `bench` and helper scripts importable in tests
    sys.path.insert(0, str(ROOT))


def pytest_report_header(config):
    """Say whether the browser tests (tests/browser) run or are skipped, and why."""
    from browserkit import report_header

    return report_header()


@pytest.fixture(scope="session")
def quick_demo(tmp_path_factory):
    """The output folder of one ``rigd demo --quick`` (the default, physics-grade plant), made
    once per test run and shared by its processes (``tests/sharedruns.py``): read by
    ``tests/design/test_demo_e2e.py`` and ``tests/browser/test_demo_page.py``. Tests only read
    it."""
    from sharedruns import shared_folder

    from rigd.cli import main

    def make(out):
        assert main(["demo", "--quick", "--out", str(out)]) == 0

    return shared_folder("demo-quick", make, tmp_path_factory)


@pytest.fixture(scope="session")
def truth_design(tmp_path_factory):
    """One ``rigd design --model G_p.yaml --weights config/design.yaml -o controller.yaml
    --json --report rep`` on the simulated plant's truth (``tests/design/design_helpers.py``),
    made once per test run (``tests/sharedruns.py``): the folder holds ``G_p.yaml``,
    ``controller.yaml``, ``design.json`` (what the command printed) and ``rep/``. Read by
    ``tests/design/test_design_chain.py`` (the command's outputs) and
    ``tests/design/test_controller_refusal.py`` (its controller, and variants of it). Tests
    only read it."""
    import contextlib
    import io

    if str(ROOT / "tests" / "design") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests" / "design"))
    from design_helpers import truth_model_file
    from sharedruns import shared_folder

    from rigd.cli import main

    def make(out):
        out.mkdir()
        model = truth_model_file(out / "G_p.yaml")
        printed = io.StringIO()
        with contextlib.redirect_stdout(printed):
            rc = main(["design", "--model", str(model), "--weights",
                       str(ROOT / "config" / "design.yaml"), "-o", str(out / "controller.yaml"),
                       "--json", "--report", str(out / "rep")])
        assert rc == 0, printed.getvalue()
        (out / "design.json").write_text(printed.getvalue())

    return shared_folder("design-truth", make, tmp_path_factory)


# RIGD_TEST_CPU_LOG=FILE: append each test's CPU seconds (this process and the children it
# waited for: CLI runs, daemons) to FILE.<pid>, a line "cpu_s<TAB>nodeid". CPU time, unlike
# --durations' wall time, does not depend on what runs beside the test: it is what a test
# costs the 2 cores `make test` shares.
_CPU_LOG = os.environ.get("RIGD_TEST_CPU_LOG")
if _CPU_LOG:
    import resource

    def _cpu_now():
        s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(
            resource.RUSAGE_CHILDREN)
        return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(item, nextitem):
        t0 = _cpu_now()
        yield
        with open(f"{_CPU_LOG}.{os.getpid()}", "a") as f:
            f.write(f"{_cpu_now() - t0:.2f}\t{item.nodeid}\n")
