"""Benchmarks: ``make bench`` prints one JSON object with every figure.

Each section is a module in this package with a ``run() -> dict`` function, listed once in
:data:`SECTIONS`. ``python -m bench [SECTION ...]`` runs all or some of them.
"""

SECTIONS = ["loop", "identify", "diagnose", "export_memory", "socket_load", "design", "reynolds",
            "structure", "web", "hostile"]
