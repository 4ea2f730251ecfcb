"""Stand-ins for the experiment process (:mod:`rigd.experiments.process`), spawned by
:class:`~rigd.service.experiment_host.ExperimentHost` when a test sets its ``entry`` to
``("experiment_children", NAME)``: each takes ``main``'s arguments (conn, stop, request,
run_dir, runs_root, facts) and misbehaves in one way."""

import os
import time


def silent(conn, stop, *_):
    """Never says a word (a start hung in its imports)."""
    time.sleep(3600)


def exits(conn, stop, *_):
    """Ends at once without a word (a start that crashed)."""
    os._exit(3)


def runs_until_stopped(conn, stop, request, *_):
    """Says it runs, then waits for ``stop`` up to the spec's ``wait_s`` (forever if None):
    ``interrupted`` when stopped, else ``complete``."""
    conn.send(("state", {"state": "running", "name": "stand-in", "kind": "prbs"}))
    stopped = stop.wait(request["spec"].get("wait_s"))
    conn.send(("done", {"state": "interrupted" if stopped else "complete",
                        "message": "stopped on request" if stopped else ""}))
    conn.close()
