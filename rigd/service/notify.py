"""sd_notify(3) without a dependency: tell systemd READY, STATUS, WATCHDOG and STOPPING.

The daemon runs as ``Type=notify``: systemd passes the path of a Unix *datagram* socket in
``NOTIFY_SOCKET`` (a file path, or an abstract-namespace name written with a leading ``@``)
and, when ``WatchdogSec=`` is set, the watchdog period in ``WATCHDOG_USEC`` (µs) and the pid
it applies to in ``WATCHDOG_PID``. The daemon must send ``WATCHDOG=1`` more often than that
period; :class:`Notifier` recommends half of it (:attr:`Notifier.watchdog_interval_s`).

Without ``NOTIFY_SOCKET`` (not under systemd, or ``--no-notify``) every call is a no-op.
"""

from __future__ import annotations

import os
import socket
import threading
import time

#: while starting (kernels compiling into a cold numba cache: 42 s measured on a loaded 2-core
#: machine), ``EXTEND_TIMEOUT_USEC`` is sent this often, each asking for this much more, s
EXTEND_EVERY_S = 10.0
EXTEND_BY_S = 30.0
#: ... for at most this long in total: a start-up still not READY after it is a hang, and
#: ``TimeoutStartSec=`` fails it as before
EXTEND_MAX_S = 300.0


class Notifier:
    """Send ``sd_notify`` datagrams.

    Parameters
    ----------
    address : str, optional
        Socket address; default ``$NOTIFY_SOCKET``. ``@name`` means the abstract namespace.
    environ : mapping, optional
        Where to read ``NOTIFY_SOCKET``/``WATCHDOG_USEC``/``WATCHDOG_PID`` (default
        ``os.environ``).
    """

    def __init__(self, address: str | None = None, environ=None):
        env = os.environ if environ is None else environ
        self.address = address if address is not None else env.get("NOTIFY_SOCKET") or None
        usec = env.get("WATCHDOG_USEC")
        pid = env.get("WATCHDOG_PID")
        try:
            usec_i = int(usec) if usec else 0
            if pid and int(pid) != os.getpid():
                usec_i = 0  # the watchdog is meant for another process
        except ValueError:
            usec_i = 0
        #: Watchdog period requested by systemd, s (0 = no watchdog).
        self.watchdog_s = usec_i / 1e6
        self._sock: socket.socket | None = None
        self.sent = 0
        self.errors = 0

    @property
    def enabled(self) -> bool:
        """True when there is a socket to notify."""
        return bool(self.address)

    @property
    def watchdog_interval_s(self) -> float:
        """Interval at which to send ``WATCHDOG=1``: half of ``WATCHDOG_USEC``, s (0 = off)."""
        return self.watchdog_s / 2.0

    def notify(self, *fields: str) -> bool:
        """Send ``fields`` (``"READY=1"``, ``"STATUS=..."``) as one datagram; True if sent.

        Never raises: a missing or broken notify socket must not take the daemon down.
        """
        if not self.address:
            return False
        addr = self.address
        if addr.startswith("@"):
            addr = "\0" + addr[1:]
        msg = "\n".join(f.replace("\n", " ") for f in fields).encode("utf-8", "replace")
        try:
            if self._sock is None:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
                # never block: a receiver that does not read (queue full) costs a dropped
                # notification, not a hung shutdown or watchdog thread
                self._sock.setblocking(False)
            self._sock.sendto(msg, addr)
            self.sent += 1
            return True
        except OSError:  # incl. BlockingIOError when the receiver's queue is full
            self.errors += 1
            return False

    def ready(self, status: str | None = None) -> bool:
        """``READY=1`` (plus ``STATUS=``, and ``MAINPID=`` for forking helpers); ends the
        start-up extension (:func:`extend_start_up`)."""
        _READY.set()
        f = ["READY=1", f"MAINPID={os.getpid()}"]
        if status:
            f.append(f"STATUS={status}")
        return self.notify(*f)

    def status(self, text: str) -> bool:
        """``STATUS=text``: shown by ``systemctl status``."""
        return self.notify(f"STATUS={text}")

    def watchdog(self) -> bool:
        """``WATCHDOG=1``: keep-alive ping."""
        return self.notify("WATCHDOG=1")

    def stopping(self, status: str | None = None) -> bool:
        """``STOPPING=1``: the daemon is shutting down."""
        return self.notify("STOPPING=1", *([f"STATUS={status}"] if status else []))

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


_READY = threading.Event()


def extend_start_up(environ=None, *, every_s: float = EXTEND_EVERY_S,
                    by_s: float = EXTEND_BY_S, max_s: float = EXTEND_MAX_S) -> bool:
    """Keep systemd's start timeout from running out while the daemon compiles its kernels.

    A thread sends ``EXTEND_TIMEOUT_USEC=<by_s>`` every ``every_s`` (``STATUS=`` says why) until
    ``READY=1`` is sent (:meth:`Notifier.ready`) or ``max_s`` have passed — never longer: a
    start-up that hangs still fails ``TimeoutStartSec=``. No-op without ``NOTIFY_SOCKET``;
    True if the thread runs.
    """
    n = Notifier(environ=environ)
    if not n.enabled:
        return False

    def run() -> None:
        t0 = time.monotonic()
        while not _READY.is_set() and time.monotonic() - t0 < max_s:
            n.notify(f"EXTEND_TIMEOUT_USEC={int(by_s * 1e6)}",
                     f"STATUS=starting: compiling the loop's kernels "
                     f"({time.monotonic() - t0:.0f} s)")
            _READY.wait(every_s)
        n.close()

    threading.Thread(target=run, name="rigd-start-up", daemon=True).start()
    return True
