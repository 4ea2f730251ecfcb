"""Safe YAML loading into typed, validated pydantic models, with file:line in every error.

Use :func:`load_model` for any YAML file a user writes (rig config, experiment, controller,
design weights). Unknown keys, wrong types and out-of-range values are refused with one
:class:`~rigd.errors.InputError` that names the file, the line and the key path, e.g.::

    config/sim.yaml:14: loop.fs_hz: Input should be greater than 0 (got -5)

Models should derive from :class:`StrictModel` (``extra='forbid'``, no silent coercion of
strings to numbers).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from rigd import bounded
from rigd.errors import InputError

M = TypeVar("M", bound=BaseModel)


class StrictModel(BaseModel):
    """Base for configuration models: unknown keys are errors, assignment is validated."""

    model_config = ConfigDict(extra="forbid", strict=False, validate_assignment=True,
                              frozen=False)


#: libyaml's parser when PyYAML was built with it (the wheels are): the same safe
#: constructors and marks, about six times less CPU than the pure-Python scanner — what an
#: 800 kB controller costs the niced socket process that reads it (docs/service.md)
_SAFE_BASE = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _LineLoader(_SAFE_BASE):  # type: ignore[misc, valid-type]
    """Safe loader that remembers the line of every mapping key and sequence item."""


def _construct_mapping(loader: _LineLoader, node: yaml.MappingNode, deep: bool = False):
    marks: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        marks[key] = key_node.start_mark.line + 1
    mapping = yaml.SafeLoader.construct_mapping(loader, node, deep=True)
    loader._rigd_lines[id(mapping)] = (marks, node.start_mark.line + 1)  # type: ignore[attr-defined]
    return mapping


def _construct_sequence(loader: _LineLoader, node: yaml.SequenceNode, deep: bool = False):
    seq = yaml.SafeLoader.construct_sequence(loader, node, deep=True)
    marks = {i: item.start_mark.line + 1 for i, item in enumerate(node.value)}
    loader._rigd_lines[id(seq)] = (marks, node.start_mark.line + 1)  # type: ignore[attr-defined]
    return seq


_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


class LoadedYaml:
    """Parsed YAML data plus the line of every key, for error messages."""

    def __init__(self, data: Any, lines: dict[int, tuple[dict[Any, int], int]], source: str):
        self.data = data
        self._lines = lines
        self.source = source

    def line_of(self, loc: tuple[Any, ...]) -> int | None:
        """Line (1-based) of the deepest existing node on the key path ``loc``."""
        node = self.data
        line = None
        for key in loc:
            entry = self._lines.get(id(node))
            if entry is None:
                break
            marks, start = entry
            line = start if line is None else line
            if key in marks:
                line = marks[key]
            else:
                break
            try:
                node = node[key]
            except (KeyError, IndexError, TypeError):
                break
        if line is None:
            entry = self._lines.get(id(self.data))
            line = entry[1] if entry else None
        return line


def read_text(path: str | Path, limit: int = bounded.MAX_YAML_BYTES,
              what: str = "file") -> str:
    """Read a UTF-8 text file, a regular one of at most ``limit`` bytes
    (:func:`rigd.bounded.read_text`); :class:`InputError` naming the file otherwise."""
    return bounded.read_text(path, limit, what)


def read_yaml(path: str | Path, text: str | None = None, *,
              limit: int = bounded.MAX_YAML_BYTES, what: str = "file") -> LoadedYaml:
    """Safe-load a YAML file (or ``text`` attributed to ``path``), keeping line numbers.

    The file must be a regular file of at most ``limit`` bytes, checked before it is read.

    Raises
    ------
    InputError
        The file is missing, unreadable, not a regular file, too large, not YAML, or empty.
    """
    path = str(path)
    if text is None:
        text = read_text(path, limit, what)
    loader = _LineLoader(text)
    loader._rigd_lines = {}  # type: ignore[attr-defined]
    try:
        data = loader.get_single_data()
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else path
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"not valid YAML: {problem}", where) from None
    finally:
        loader.dispose()
    if data is None:
        raise InputError("file is empty", path)
    return LoadedYaml(data, loader._rigd_lines, path)  # type: ignore[attr-defined]


def _fmt_loc(loc: tuple[Any, ...]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def validate(loaded: LoadedYaml, model: type[M], *, section: tuple[Any, ...] = ()) -> M:
    """Validate parsed YAML (or one ``section`` of it) into ``model``; first error raised."""
    data = loaded.data
    for key in section:
        data = data[key]
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = tuple(section) + tuple(
            p for p in err["loc"]
            if not (isinstance(p, str) and "[" in p and p.startswith("function")))
        line = loaded.line_of(loc)
        where = f"{loaded.source}:{line}" if line else loaded.source
        msg = err["msg"]
        if err["type"] == "extra_forbidden":
            msg = "unknown key"
        elif isinstance(err.get("input"), str):
            # never quoted: a file's text may be a secret (a token file named as a controller)
            msg = f"{msg} (got a string of {len(err['input'])} characters)"
        elif ("input" in err and err["type"] != "missing"
              and not isinstance(err["input"], (dict, list))):
            msg = f"{msg} (got {err['input']!r})"
        if len(exc.errors()) > 1:
            msg += f" (and {len(exc.errors()) - 1} more problem(s))"
        raise InputError(msg, f"{where}: {_fmt_loc(loc)}") from None


def load_model(path: str | Path, model: type[M], *, text: str | None = None) -> M:
    """Read and validate a YAML file into ``model`` (see module docstring)."""
    return validate(read_yaml(path, text), model)


def dump_yaml(path: str | Path, data: Any) -> None:
    """Write YAML atomically (temporary file + rename): never a half-written file."""
    from rigd.fileio import atomic_write_text

    atomic_write_text(path, yaml.safe_dump(data, sort_keys=False, default_flow_style=None))
