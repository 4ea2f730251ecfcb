"""The scheduling priority of ``rigd web``'s event loop: the console's SAFE path.

The event loop accepts the browser's connections, parses each request and runs the SAFE
handler, which writes the daemon's SAFE word (:mod:`rigd.service.safe_request`). On a machine
whose cores are busy with other work, a normal-priority process waits its turn behind every
runnable process before it even reads the request: measured with 200 browser streams and
six busy loops on 2 cores, 1-37 ms from the request's send to the handler (up to 94 ms in a
full test run), against 0.5-1.7 ms with the event loop at ``SCHED_FIFO`` 10.

So the event loop's thread takes ``SCHED_FIFO`` at a low priority — below the daemon's loop
(``clock.priority``, 80 by default) and its service threads (one below it) — with
``SCHED_RESET_ON_FORK``: the threads and processes it starts (the worker threads that read
files and check uploads) run at normal priority, so nothing slow inherits it. The event loop
itself does little per request (9 % of a core relays 200 streams at 10 updates/s), and the
kernel's real-time throttling (``kernel.sched_rt_runtime_us``) leaves other work a share even
if it ever spun. Best effort: without the permission (``CAP_SYS_NICE`` or ``LimitRTPRIO``) it
stays at normal priority and says so on its start line.
"""

from __future__ import annotations

import os

#: ``rigd web --rt-priority`` default: low, below the daemon's loop and service threads
DEFAULT_PRIORITY = 10


def take_rt_priority(priority: int) -> str:
    """Put the calling thread at ``SCHED_FIFO`` ``priority`` (reset on fork), best effort.

    Parameters
    ----------
    priority : int
        1-99; 0 leaves the thread at normal priority.

    Returns
    -------
    str
        What the thread runs at, for the start line: ``"SCHED_FIFO 10"``, or ``"normal
        priority (...)"`` saying why.
    """
    if priority <= 0:
        return "normal priority (--rt-priority 0)"
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK,
                              os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        why = getattr(exc, "strerror", None) or exc.__class__.__name__
        return f"normal priority (SCHED_FIFO {priority} not permitted: {why})"
    return f"SCHED_FIFO {priority}"
