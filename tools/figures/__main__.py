"""``python -m tools.figures [--check] [--root DIR]`` renders docs/figures.md and the README's
figures table from docs/figures/*.json; ``python -m tools.figures save-demo SUMMARY`` saves a
demo run's figures as docs/figures/demo.json first (``make demo`` does both)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tools.figures import FIGURES_MD, README, ROOT, artefact, pages

#: the sections ``make bench`` runs (bench/__init__.py SECTIONS), read without importing rigd
_SECTIONS_FILE = Path("bench") / "__init__.py"


def bench_sections(root: Path) -> list[str]:
    import ast

    tree = ast.parse((root / _SECTIONS_FILE).read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "SECTIONS":
            return list(ast.literal_eval(node.value))
    return []


def rendered(root: Path) -> dict[Path, str]:
    """What the two pages should hold, rendered in memory from the committed artefacts."""
    arts = artefact.load_all(root)
    readme = (root / README).read_text()
    return {FIGURES_MD: pages.render_figures_md(arts, bench_sections(root)),
            README: pages.rewrite_readme(readme, arts)}


def stale(root: Path) -> list[Path]:
    """The pages whose committed text differs from :func:`rendered`."""
    return [p for p, text in rendered(root).items()
            if not (root / p).exists() or (root / p).read_text() != text]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.figures", description=__doc__)
    ap.add_argument("--root", type=Path, default=ROOT, help="repository root")
    ap.add_argument("--check", action="store_true",
                    help="render in memory; exit 1 when a committed page differs")
    ap.add_argument("action", nargs="?", choices=["render", "save-demo"], default="render")
    ap.add_argument("summary", nargs="?", type=Path, help="save-demo: demo-out/summary.json")
    ap.add_argument("--load-before", metavar="L1,L5,L15",
                    help="save-demo: the load averages when the demo began (/proc/loadavg)")
    a = ap.parse_args(argv)
    try:
        if a.action == "save-demo":
            if a.summary is None:
                ap.error("save-demo needs the demo's summary.json")
            lb = None
            if a.load_before:
                try:
                    lb = [float(v) for v in a.load_before.replace(",", " ").split()[:3]]
                except ValueError:
                    ap.error(f"--load-before {a.load_before!r}: expected three numbers")
            print(f"figures: wrote {artefact.save_demo(a.root, a.summary, lb)}",
                  file=sys.stderr)
        if a.check:
            bad = stale(a.root)
            for p in bad:
                print(f"figures: {p} does not match docs/figures/*.json: run "
                      "`python -m tools.figures`", file=sys.stderr)
            return 1 if bad else 0
        for p, text in rendered(a.root).items():
            (a.root / p).write_text(text)
            print(f"figures: rendered {p}", file=sys.stderr)
    except (OSError, ValueError, KeyError) as exc:
        print(f"figures: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
