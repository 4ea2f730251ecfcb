"""The bridge to the daemon: one control-socket connection per request
(:class:`rigd.service.client.ControlClient`, the client ``rigd ctl`` uses)."""

from __future__ import annotations

from typing import Any

from rigd.errors import InputError
from rigd.service.client import ControlClient

#: ``POST /api/<name>`` -> daemon socket command (the ``rigd ctl`` sub-commands, plus ``safe``)
COMMANDS = {
    "enable": "controller.enable",
    "disable": "controller.disable",
    "reset": "fault.reset",
    "load": "controller.load",
    "op": "operating_point.set",
    "start": "experiment.start",
    "stop": "experiment.stop",
    "safe": "safe",
}


class DaemonDown(Exception):
    """The daemon socket is missing, refuses or does not answer (-> HTTP 503)."""


class DaemonSilent(Exception):
    """Connected, but no (complete) reply in time (-> HTTP 504): a command may have
    been applied, so the caller must not assume either outcome."""


class DaemonRefused(Exception):
    """The daemon answered ``ok: false`` (its one line is the message; -> HTTP 409)."""


class Daemon:
    """Send requests to the daemon's control socket.

    Parameters
    ----------
    socket_path : str
    timeout : float
        Seconds to wait for a reply.
    """

    def __init__(self, socket_path: str, timeout: float = 10.0):
        self.socket_path = socket_path
        self.timeout = timeout

    def call(self, cmd: str, **args: Any) -> Any:
        """The ``result`` of one request.

        Raises
        ------
        DaemonDown
            Not reachable (message: one line naming the socket).
        DaemonSilent
            No complete reply within ``timeout`` (the request may have been applied).
        DaemonRefused
            The daemon refused the request (its error line).
        """
        client = ControlClient(self.socket_path, timeout=self.timeout)
        try:
            client.connect()
        except InputError as exc:
            raise DaemonDown(f"daemon not reachable: {exc}") from None
        try:
            reply = client.request(cmd, **args)
        except (InputError, OSError, ValueError) as exc:
            raise DaemonSilent(f"no complete reply from the daemon to {cmd} ({exc}); it may have "
                               "been applied before its deadline, never after: check the "
                               "status") from None
        finally:
            client.close()
        if not reply.get("ok"):
            raise DaemonRefused(" ".join(str(reply.get("error", "refused")).split()))
        return reply.get("result")
