"""Errors a user can cause and fix.

Every command-line entry point catches :class:`InputError` and prints its one-line message on
stderr with exit status 2 (no traceback). The message names *where* (file, line, key or request)
and *what* is wrong. :class:`DaemonGone` (the daemon ended, or a request it never took) is not
bad input: exit status 3 (:data:`EXIT_DAEMON_GONE`).
"""

from __future__ import annotations


class InputError(Exception):
    """Bad user input: a config, data file, CLI argument, socket request, controller file.

    Parameters
    ----------
    message : str
        What is wrong, in plain words.
    where : str, optional
        Where it is: ``"config/sim.yaml:12: plant.valves[2].gain"``, ``"data.csv:41"``, ...
    """

    def __init__(self, message: str, where: str | None = None):
        self.message = message
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


#: exit status of a client whose daemon ended (or is not there to take the request)
EXIT_DAEMON_GONE = 3


class DaemonGone(InputError):
    """The daemon ended (its process is gone, its socket refuses or closed without a reply)
    or never took the request: not bad input — exit status :data:`EXIT_DAEMON_GONE`."""

    exit_status = EXIT_DAEMON_GONE


class FaultError(RuntimeError):
    """A runtime fault of the rig (driver, sensor, supervisor) that puts it into the safe state."""
