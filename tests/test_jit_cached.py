"""Every numba kernel of rigd and its drivers is compiled with ``cache=True``: a kernel without
it is compiled again in every process (each xdist worker, each daemon the tests start, each
``rigd run``), and ``tests/warm_kernels.py`` cannot compile it ahead for them."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: compiled per process on purpose: any plant kernel signature (rigd/loop/cycle.py)
UNCACHED = {("rigd/loop/cycle.py", "lockstep_batch_generic")}


def _jit_calls(tree: ast.AST):
    """(name it is bound to, the ``njit``/``jit`` call) for each decorator or assignment."""
    def is_jit(node):
        f = node.func if isinstance(node, ast.Call) else node
        return (isinstance(f, ast.Name) and f.id in ("njit", "jit")) or (
            isinstance(f, ast.Attribute) and f.attr in ("njit", "jit"))

    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            for d in node.decorator_list:
                if is_jit(d):
                    yield node.name, d
        elif isinstance(node, ast.Assign) and isinstance(node.value, ast.Call):
            inner = node.value.func
            if isinstance(inner, ast.Call) and is_jit(inner):   # name = njit(...)(f)
                yield node.targets[0].id, inner


def _cached(call) -> bool:
    return isinstance(call, ast.Call) and any(
        k.arg == "cache" and isinstance(k.value, ast.Constant) and k.value.value is True
        for k in call.keywords)


def test_every_kernel_is_cached():
    found, missing = 0, []
    for top in ("rigd", "drivers"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            for name, call in _jit_calls(ast.parse(path.read_text(), rel)):
                found += 1
                if not _cached(call) and (rel, name) not in UNCACHED:
                    missing.append(f"{rel}: {name}")
    assert found > 50, f"only {found} kernels found: the scan no longer sees them"
    assert not missing, "numba kernels without cache=True: " + ", ".join(missing)


def test_the_scan_sees_a_missing_cache():
    src = ("import numba\n@numba.njit\ndef a(x):\n    return x\n"
           "@numba.njit(cache=True)\ndef b(x):\n    return x\n"
           "c = numba.njit(nogil=True)(a)\n")
    got = {name: _cached(call) for name, call in _jit_calls(ast.parse(src))}
    assert got == {"a": False, "b": True, "c": False}
