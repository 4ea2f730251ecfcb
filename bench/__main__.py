"""Run the benchmark sections and print one JSON object (see bench/__init__.py).

``python -m bench [--save] [SECTION ...]``: with ``--save`` each section's figures are also
written to ``docs/figures/bench-<section>.json`` with where they were measured (host, load,
commit, date, package versions: tools/figures/artefact.py), and docs/figures.md and the
README's figures table are rendered from them (``make bench`` saves).
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import time
from pathlib import Path

from bench import SECTIONS

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str]) -> int:
    save = "--save" in argv
    wanted = [a for a in argv if a != "--save"] or SECTIONS
    result: dict = {}
    for name in wanted:
        try:
            mod = importlib.import_module(f"bench.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"bench.{name}":
                print(f"bench: section {name!r} not built yet, skipped", file=sys.stderr)
                continue
            raise
        print(f"bench: running {name} ...", file=sys.stderr, flush=True)
        load_before = list(os.getloadavg())   # the host's load, without this section's
        t0 = time.monotonic()
        figures = mod.run()
        result.update(figures)
        if save:
            from tools.figures import artefact

            path = artefact.save_bench_section(ROOT, name, figures, time.monotonic() - t0,
                                               load_before)
            print(f"bench: saved {path.relative_to(ROOT)}", file=sys.stderr, flush=True)
    if save:
        from tools.figures.__main__ import main as render

        render(["--root", str(ROOT)])
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
