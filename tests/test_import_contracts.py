"""The import contracts in pyproject.toml are real: lint-imports passes on a copy of the tree
and fails, naming the contract, once a forbidden import is written into the copy."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    """A copy of the packages (rigd, drivers as rigd_drivers) and pyproject.toml."""
    dst = tmp_path_factory.mktemp("tree")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "rigd", dst / "rigd", ignore=ignore)
    shutil.copytree(ROOT / "drivers", dst / "rigd_drivers", ignore=ignore)
    shutil.copy(ROOT / "pyproject.toml", dst / "pyproject.toml")
    return dst


def _lint(tree: Path) -> subprocess.CompletedProcess:
    # the copy first on the path, so grimp reads it and not the installed tree
    probe = ("import rigd, rigd_drivers, sys; "
             "sys.exit(0 if rigd.__file__.startswith(sys.argv[1]) and "
             "rigd_drivers.__file__.startswith(sys.argv[1]) else 1)")
    env = dict(os.environ, PYTHONPATH=str(tree))
    assert subprocess.run([sys.executable, "-c", probe, str(tree)], env=env,
                          cwd=tree).returncode == 0, "the copy is not what gets imported"
    return subprocess.run([str(LINT_IMPORTS), "--config", str(tree / "pyproject.toml"),
                           "--no-cache"], env=env, cwd=tree, capture_output=True, text=True,
                          timeout=300)


def test_the_tree_keeps_every_contract(tree):
    res = _lint(tree)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "0 broken" in res.stdout


@pytest.mark.parametrize("where, code, contract", [
    ("rigd/loop/_probe.py", "import rigd.ident.simulate\n",
     "The loop never imports identification"),
    ("rigd/data/_probe.py", "from rigd.effects import REGISTRY\n", "Layers:"),
    ("rigd/ident/_probe.py", "import rigd.diagnose.engine\n", "Layers:"),
    ("rigd_drivers/_probe.py", "import rigd.loop.layout\n", "Drivers import only"),
    ("rigd/design/_probe.py", "import rigd_drivers.plant.physics\n", "Below the API nothing"),
    # with base.py importing the probe back (below): a cycle between siblings
    ("rigd/effects/_probe.py", "import rigd.effects.runout\n", "No import cycles"),
])
def test_a_forbidden_import_breaks_its_contract(tree, where, code, contract):
    probe = tree / where
    extra = None
    if "effects/_probe" in where:   # a real cycle between two siblings of rigd.effects
        extra = tree / "rigd/effects/base.py"
        saved = extra.read_text()
        extra.write_text(saved + "\nimport rigd.effects._probe  # noqa: E402\n")
    probe.write_text(code)
    try:
        res = _lint(tree)
    finally:
        probe.unlink()
        if extra is not None:
            extra.write_text(saved)
    assert res.returncode != 0
    broken = res.stdout[res.stdout.index("Broken contracts"):]
    assert contract in broken, res.stdout
    assert "_probe" in broken


@pytest.mark.parametrize("module, code, contract", [
    # daemon, bridge, protocol run in the loop's process: importing the readers (directly or
    # through the socket process's module) breaks "The loop's process never imports ..."
    ("rigd/service/daemon.py", "from rigd.service.reader import read_controller",
     "The loop's process never imports the file readers"),
    ("rigd/service/bridge.py", "from rigd.service import frontend",
     "The loop's process never imports the file readers"),
    ("rigd/service/protocol.py", "import rigd.service.reader",
     "The loop's process never imports the file readers"),
    # HDF5 files are written by the writer process (spawned by module name)
    ("rigd/loop/recorder.py", "from rigd.recording.h5sink import H5Sink",
     "The loop's process never imports the HDF5 writer"),
    ("rigd/service/daemon.py", "import rigd.recording.writer",
     "The loop's process never imports the HDF5 writer"),
    ("rigd/loop/sinks.py", "import h5py", "The loop's process never imports h5py"),
    ("rigd/service/bridge.py", "import h5py", "The loop's process never imports h5py"),
    # experiments run in an experiment process of their own (rigd.experiments.process, 28fc022):
    # the loop's process importing any of rigd.experiments breaks that contract
    ("rigd/service/daemon.py", "import rigd.experiments.runner",
     "The loop's process never imports the experiments"),
    ("rigd/service/bridge.py", "from rigd.experiments import points",
     "The loop's process never imports the experiments"),
])
def test_the_loops_process_importing_a_reader_or_the_writer_breaks_its_contract(
        tree, module, code, contract):
    """What runs in the loop's process importing what must run outside it."""
    target = tree / module
    saved = target.read_text()
    target.write_text(saved + f"\n{code}  # noqa: E402\n")
    try:
        res = _lint(tree)
    finally:
        target.write_text(saved)
    assert res.returncode != 0
    broken = res.stdout[res.stdout.index("Broken contracts"):]
    assert contract in broken, res.stdout
    assert module.removesuffix(".py").replace("/", ".") in broken
