"""The service's spawned helpers (SIGHUP's re-read, the socket process): :mod:`rigd.spawn`.

Kept as the service's name for it (the import contract "the loop's process never imports the
file readers" lists it among the daemon's modules).
"""

from rigd.spawn import call, run

__all__ = ["call", "run"]
