"""Run the benchmark sections and print one JSON object (see bench/__init__.py)."""

from __future__ import annotations

import importlib
import json
import sys

from bench import SECTIONS


def main(argv: list[str]) -> int:
    wanted = argv or SECTIONS
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
        result.update(mod.run())
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
