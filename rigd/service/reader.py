"""The files a request or a signal names, read and validated outside the loop's process.

The loop's process (the daemon: :mod:`rigd.service.daemon`, :mod:`rigd.service.bridge`,
:class:`rigd.service.protocol.Dispatcher`) never opens, reads or parses a file a client names
(import contract in pyproject.toml). The functions here run

* in the socket process (:mod:`rigd.service.frontend`), for ``controller.load`` and
  ``experiment.start``: the file is checked (regular, size limit: :mod:`rigd.bounded`), read,
  parsed and validated there; what is forwarded to the daemon is the result, small and
  packed — a controller as its four matrices, the rate and its source's name
  (:func:`pack_controller`), an experiment as its validated spec;
* in a spawned one-shot helper process (:func:`rigd.service.spawned.run`) for the daemon's
  SIGHUP re-read (:func:`reload_files`).

Every refusal is an :class:`~rigd.errors.InputError` with one line naming the file and the
problem; in a helper process it comes back as ``("refused", message)``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rigd.errors import InputError


def pack_controller(ctrl) -> dict[str, Any]:
    """A validated :class:`rigd.controller.Controller` as what crosses into the loop's process:
    ``A, B, C, D`` (float64 arrays), ``fs_hz`` and ``source`` (its name, for ``status``)."""
    import numpy as np

    out: dict[str, Any] = {k: np.ascontiguousarray(getattr(ctrl, k), dtype=np.float64)
                           for k in "ABCD"}
    out["fs_hz"] = float(ctrl.fs_hz)
    out["source"] = str(ctrl.source)
    return out


def read_controller(path: str, fs_hz: float | None) -> dict[str, Any]:
    """Read, validate and check the controller YAML ``path`` for a loop at ``fs_hz``; packed.

    Raises
    ------
    InputError
    """
    from rigd.controller import load_controller

    return pack_controller(load_controller(path, expected_fs_hz=fs_hz))


def read_experiment(path: str | None, spec: dict | None) -> dict[str, Any]:
    """A file or an inline spec validated and packed for the daemon: ``{"spec", "source",
    "spec_sha256", "name", "kind"}`` — the validated spec as plain JSON values (no model
    object crosses: the loop's process never imports the experiment schemas), re-read by
    the experiment process (:func:`rigd.experiments.process.unpack`).

    Raises
    ------
    InputError
    """
    import hashlib

    from rigd.experiments.schemas import load_experiment, spec_from_dict

    if spec is not None:
        s, _ = spec_from_dict(spec)
        source, sha, name = "<spec>", None, s.name or s.kind
    else:
        s, _, text = load_experiment(path)
        source = str(path)
        sha = "sha256:" + hashlib.sha256(text.encode("utf-8")).hexdigest()
        name = s.name or Path(source).stem     # as rigd.experiments.runner.Experiment.name
    return {"spec": s.model_dump(mode="json"), "source": source, "spec_sha256": sha,
            "name": name, "kind": s.kind}


def warm_up() -> None:
    """Import the readers' modules now (the socket process does it before it serves), so
    that the first ``controller.load`` or ``experiment.start`` does not pay for the imports:
    tens of seconds on a machine at load 30."""
    import rigd.controller  # noqa: F401
    import rigd.experiments.schemas  # noqa: F401


def reload_files(config_path: str, controller: str | None, fs_hz: float | None,
                 old_sections: dict[str, Any]) -> tuple[str, Any]:
    """SIGHUP's re-read, in a helper process: the config file and the controller it names (or
    ``controller``, the one given on the command line).

    Returns
    -------
    ("ok", {"controller": path or None, "packed": packed controller or None,
            "needs_restart": [changed top-level sections but ``controller``]})
    or ("refused", one-line message)
    """
    from rigd.rigconfig import load_config

    try:
        new = load_config(config_path)
        ctrl = controller
        if ctrl is None and new.config.controller is not None:
            c = Path(new.config.controller)
            ctrl = str(c if c.is_absolute() else Path(config_path).parent / c)
        packed = read_controller(ctrl, fs_hz) if ctrl is not None else None
        b = new.config.model_dump(mode="json")
        changed = sorted(k for k in set(old_sections) | set(b)
                         if k != "controller" and old_sections.get(k) != b.get(k))
        return "ok", {"controller": ctrl, "packed": packed, "needs_restart": changed}
    except InputError as exc:
        return "refused", str(exc)
