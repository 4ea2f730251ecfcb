"""The files a request or a signal names, read and validated outside the loop's process.

The loop's process (the daemon: :mod:`rigd.service.daemon`, :mod:`rigd.service.bridge`,
:class:`rigd.service.protocol.Dispatcher`) never opens, reads or parses a file a client names
(import contract in pyproject.toml). The functions here run

* in the socket process (:mod:`rigd.service.frontend`), for ``controller.load`` and
  ``experiment.start``: the content the *client* read from its file with its own rights (a
  controller's matrices, :func:`rigd.controller.to_wire`; an experiment's text) is parsed,
  validated and checked there — no file a client names is ever opened here (no confused
  deputy: the daemon's rights never read for a client); what is forwarded to the daemon is
  the result, small and packed — a controller as its four matrices, the rate and its
  source's name (:func:`pack_controller`), an experiment as its validated spec;
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


_GATES: dict[tuple, Any] = {}


def gates_for(opts: dict[str, Any] | None):
    """The :class:`rigd.controller.Gates` of the rig config's ``controller_gates`` (as
    :meth:`rigd.rigconfig.LoadedConfig.gate_options` gives them), the nominal plant read once
    per file (:func:`rigd.controller.gates_from`); None without options.

    Raises
    ------
    InputError
        The nominal plant file is missing or invalid.
    """
    from rigd.controller import gates_from

    if not opts:
        return None
    key = (opts.get("max_gain"), opts.get("nominal_plant"))
    if key not in _GATES:
        _GATES[key] = gates_from(opts)
    return _GATES[key]


def read_controller(wire: dict[str, Any], source: str, fs_hz: float | None,
                    gates: dict[str, Any] | None = None) -> dict[str, Any]:
    """Check the controller the client read and sent (:func:`rigd.controller.to_wire`: its
    matrices, never a path to open) for a loop at ``fs_hz`` and the config's ``gates``
    (:func:`gates_for`); packed.

    Raises
    ------
    InputError
    """
    from rigd.controller import from_wire

    return pack_controller(from_wire(wire, source=source, expected_fs_hz=fs_hz,
                                     gates=gates_for(gates)))


def read_experiment(path: str | None, spec: dict | None,
                    text: str | None = None) -> dict[str, Any]:
    """An experiment file's ``text`` (read and sent by the client; ``path`` is its name) or
    an inline spec, validated and packed for the daemon: ``{"spec", "source",
    "spec_sha256", "name", "kind"}`` — the validated spec as plain JSON values (no model
    object crosses: the loop's process never imports the experiment schemas), re-read by
    the experiment process (:func:`rigd.experiments.process.unpack`).

    Raises
    ------
    InputError
    """
    import hashlib

    from rigd.configio import read_yaml
    from rigd.experiments.schemas import spec_from_dict, validate_spec

    if spec is not None:
        s, _ = spec_from_dict(spec)
        source, sha, name = "<spec>", None, s.name or s.kind
    else:
        if text is None:
            raise InputError("the experiment file's content is missing: the daemon opens no "
                             "file a client names", str(path))
        s, _ = validate_spec(read_yaml(path, text))
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
    from rigd.controller import load_controller
    from rigd.rigconfig import load_config

    try:
        new = load_config(config_path)
        ctrl = controller
        if ctrl is None and new.config.controller is not None:
            c = Path(new.config.controller)
            ctrl = str(c if c.is_absolute() else Path(config_path).parent / c)
        # the daemon's own files (its config names them), not a client's: read here
        packed = pack_controller(load_controller(
            ctrl, expected_fs_hz=fs_hz, gates=gates_for(new.gate_options()))) \
            if ctrl is not None else None
        b = new.config.model_dump(mode="json")
        changed = sorted(k for k in set(old_sections) | set(b)
                         if k != "controller" and old_sections.get(k) != b.get(k))
        return "ok", {"controller": ctrl, "packed": packed, "needs_restart": changed}
    except InputError as exc:
        return "refused", str(exc)
