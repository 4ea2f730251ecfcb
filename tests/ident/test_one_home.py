"""One ``fit_percent`` and one home for every significance threshold (issue 20, item 9):
no module of rigd defines the fit measure or a threshold of rigd.ident.thresholds again."""

import ast
from pathlib import Path

import numpy as np

import rigd
from rigd.ident import thresholds as T
from rigd.ident.figures import fit_percent

ROOT = Path(rigd.__file__).parent
NAMES = {n for n in vars(T) if n.isupper()}


def _modules():
    for p in sorted(ROOT.rglob("*.py")):
        yield p, ast.parse(p.read_text(), str(p))


def test_fit_percent_is_defined_once():
    """(Result properties named ``fit_percent`` are read-outs, not definitions.)"""
    defs = [str(p.relative_to(ROOT)) for p, tree in _modules() for node in tree.body
            if isinstance(node, ast.FunctionDef) and node.name == "fit_percent"]
    assert defs == ["ident/figures.py"], defs


def test_no_threshold_is_given_a_number_outside_its_home():
    """A module may use a threshold (import it, or name it for its own rule), never set
    one of the thresholds' names to a number of its own."""
    found = []
    for p, tree in _modules():
        if p.name == "thresholds.py":
            continue
        for node in tree.body:
            if isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                names = {t.id for t in targets if isinstance(t, ast.Name)}
                if names & NAMES and isinstance(node.value, ast.Constant):
                    found.append((str(p.relative_to(ROOT)), sorted(names & NAMES)))
    assert found == [], found


def test_every_threshold_has_a_docstring_comment():
    text = Path(T.__file__).read_text().splitlines()
    for name in NAMES:
        i = next(k for k, line in enumerate(text) if line.startswith(f"{name} ="))
        assert text[i - 1].startswith("#:"), name


def test_fit_percent_definition():
    """100 % for a perfect simulation, 0 % for the mean, negative for worse."""
    rng = np.random.default_rng(0)
    y = rng.standard_normal((200, 2))
    assert np.allclose(fit_percent(y, y), 100.0)
    assert np.allclose(fit_percent(y, np.tile(y.mean(axis=0), (200, 1))), 0.0)
    assert np.all(fit_percent(y, -y) < 0)
    assert fit_percent(y[:, 0], y[:, 0] + 0.1).shape == (1,)


def test_no_inline_fit_formula_outside_its_home():
    """The fit's formula 100·(1 − ‖e‖/‖y − ȳ‖) is written once (design's impact fit used to
    keep its own copy); every other figure calls fit_percent."""
    import re

    pat = re.compile(r"100(\.0)?\s*\*\s*\(\s*1(\.0)?\s*-\s*(np\.linalg\.norm|num\b)")
    found = [str(p.relative_to(ROOT)) for p in sorted(ROOT.rglob("*.py"))
             if p.name != "figures.py" and pat.search(p.read_text())]
    assert found == [], found
    assert pat.search((ROOT / "ident" / "figures.py").read_text())
