"""rigd.jitcache: numba's cache folder follows the source, so a changed callee in another file
is never served from a kernel compiled against the old one (real numba, real processes)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from rigd import jitcache

ROOT = Path(__file__).resolve().parents[1]

CALLEE = "import numba\n\n@numba.njit(cache=True)\ndef g(x):\n    return x + {k}.0\n"
CALLER = textwrap.dedent("""\
    import numba
    from pkg.callee import g

    @numba.njit(cache=True)
    def f(x):
        return 2.0 * g(x)
    """)
RUN = textwrap.dedent("""\
    import sys
    from pathlib import Path
    sys.path.insert(0, {tmp!r})
    if {keyed}:
        from rigd import jitcache
        jitcache.configure([Path({tmp!r}) / "pkg"])
    from pkg.caller import f
    print(f(1.0))
    """)


def _run(tmp: Path, cache: Path, keyed: bool) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    out = subprocess.run([sys.executable, "-c", RUN.format(tmp=str(tmp), keyed=keyed)],
                         env=env, capture_output=True, text=True, timeout=300, check=True)
    return float(out.stdout.split()[-1])


def _package(tmp: Path, k: int) -> None:
    pkg = tmp / "pkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "caller.py").write_text(CALLER)
    (pkg / "callee.py").write_text(CALLEE.format(k=k))


def _edit_callee(tmp: Path, k: int) -> None:
    p = tmp / "pkg" / "callee.py"
    st = p.stat()
    p.write_text(CALLEE.format(k=k) + "# edited\n")
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))


def test_plain_numba_serves_a_stale_caller_and_the_keyed_cache_does_not(tmp_path):
    """The premise (numba alone keeps f compiled against the old g) and the fix, side by side."""
    _package(tmp_path, 1)
    plain, keyed = tmp_path / "plain", tmp_path / "keyed"
    assert _run(tmp_path, plain, False) == 4.0 and _run(tmp_path, keyed, True) == 4.0
    _edit_callee(tmp_path, 10)
    assert _run(tmp_path, plain, False) == 4.0, "numba's own check caught the change after all"
    assert _run(tmp_path, keyed, True) == 22.0
    assert len([p for p in keyed.iterdir() if p.name.startswith(jitcache.PREFIX)]) == 2


def test_digest_follows_content_size_and_time(tmp_path):
    _package(tmp_path, 1)
    d0 = jitcache.source_digest([tmp_path / "pkg"])
    assert jitcache.source_digest([tmp_path / "pkg"]) == d0
    _edit_callee(tmp_path, 1)
    assert jitcache.source_digest([tmp_path / "pkg"]) != d0


def test_importing_rigd_keys_the_cache_once_and_children_inherit_it(tmp_path):
    """``import rigd`` sets the folder (numba sees it), and a process started with that
    environment keys it to the same folder instead of nesting another."""
    code = ("import os, rigd, numba.core.config as c; "
            "print(os.environ['NUMBA_CACHE_DIR']); print(c.CACHE_DIR)")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert out[0] == out[1]
    assert Path(out[0]).parent == tmp_path and Path(out[0]).name.startswith(jitcache.PREFIX)
    env["NUMBA_CACHE_DIR"] = out[0]
    again = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                           text=True, timeout=120, check=True).stdout.split()
    assert again == out


def test_unset_cache_dir_is_keyed_too(tmp_path):
    """A plain ``rigd`` from a shell (no ``NUMBA_CACHE_DIR``) gets a source-keyed folder as
    well, under the virtual environment (or ``~/.cache/rigd/numba``), never numba's default
    ``__pycache__`` beside each file, where a caller outlives its changed callee."""
    code = ("import os, rigd, numba.core.config as c; "
            "print(os.environ['NUMBA_CACHE_DIR']); print(c.CACHE_DIR)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert out[0] == out[1]
    assert Path(out[0]).name.startswith(jitcache.PREFIX)
    assert Path(out[0]).parent == jitcache.default_base()


def test_folders_of_other_source_unused_for_a_week_are_removed(tmp_path):
    """A new source tree's first process removes the ``src-`` folders unused for
    ``STALE_DAYS`` (checkouts and upgrades piled up 11 MB each), keeps recent ones and its
    own, and leaves anything that is not a cache folder alone."""
    import time

    day = 86400.0
    old, recent, mine, other = (tmp_path / n for n in ("src-old", "src-recent", "src-mine",
                                                       "notes"))
    for p in (old, recent, mine, other):
        p.mkdir()
        (p / "k.nbi").write_text("x")
    now = time.time()
    os.utime(old, (now - 10 * day, now - 10 * day))
    os.utime(recent, (now - 1 * day, now - 1 * day))
    os.utime(mine, (now - 30 * day, now - 30 * day))
    os.utime(other, (now - 30 * day, now - 30 * day))
    assert jitcache.prune(tmp_path, mine) == [old]
    assert not old.exists() and recent.is_dir() and mine.is_dir() and other.is_dir()
    assert mine.stat().st_mtime > now - day          # marked used: kept next time too
    # and it happens when rigd is imported by the top process of a tree
    os.utime(recent, (now - 10 * day, now - 10 * day))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    subprocess.run([sys.executable, "-c", "import rigd"], env=env, timeout=120, check=True)
    assert not recent.exists() and other.is_dir()
