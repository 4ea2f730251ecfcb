"""structlog set-up: JSON lines for journald when not on a terminal, console lines on one.

Never log from inside the cycle: the loop hands events to a queue that a slow thread logs.
"""

from __future__ import annotations

import logging
import sys

import structlog

_configured = False


class _StderrProxy:
    """Writes to whatever ``sys.stderr`` is at the time of the write."""

    def write(self, text: str) -> int:
        return sys.stderr.write(text)

    def flush(self) -> None:
        sys.stderr.flush()

    def isatty(self) -> bool:
        return hasattr(sys.stderr, "isatty") and sys.stderr.isatty()


def configure(level: str = "info", *, json: bool | None = None, stream=None) -> None:
    """Configure structlog once for the process.

    Parameters
    ----------
    level : str
        ``debug``, ``info``, ``warning``, ``error``.
    json : bool, optional
        Force JSON lines (True) or console lines (False); default: JSON unless ``stream`` is a
        terminal.
    stream : file, optional
        Where to write (default ``sys.stderr``).
    """
    global _configured
    if stream is None:
        # resolve sys.stderr at each write, not now: it may be replaced later (tests, daemons)
        stream = _StderrProxy()
    if json is None:
        json = not (hasattr(stream, "isatty") and stream.isatty())
    renderer = (structlog.processors.JSONRenderer() if json
                else structlog.dev.ConsoleRenderer(colors=False))
    structlog.configure(
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.processors.add_log_level,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
            structlog.processors.format_exc_info,
            renderer,
        ],
        wrapper_class=structlog.make_filtering_bound_logger(
            getattr(logging, level.upper(), logging.INFO)),
        logger_factory=structlog.PrintLoggerFactory(file=stream),
        cache_logger_on_first_use=False,
    )
    _configured = True


def get_logger(name: str = "rigd", **bind):
    """A bound structlog logger (configures defaults on first use)."""
    if not _configured:
        configure()
    return structlog.get_logger(name).bind(**bind)
