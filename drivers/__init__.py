"""rigd's drivers, one package per plant (docs/ARCHITECTURE.md)."""

import rigd  # noqa: F401  (points numba's cache at a folder of this source: rigd.jitcache)
