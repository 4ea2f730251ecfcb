"""The controller file: the discrete K∞(z) that ``rigd design`` writes and the loop runs.

K∞ is the outer H∞ controller of the paper (Sec. 5): a 2-input (shaft displacement
p = [e_x, e_y], µm) 2-output (lumped valve references r = [r_x, r_y], V) discrete state space
at the loop rate, obtained by Tustin discretisation of the reduced K∞(s). It is the
negative-feedback K of Eq. 11, S_o = (I + G_p K∞)⁻¹: the loop feeds it ``-(p - p_eq)``.

File format (YAML, see docs/ARCHITECTURE.md)::

    rigd_controller: 1
    fs_hz: 5000.0
    inputs: [e_x, e_y]
    outputs: [r_x, r_y]
    A: [[...]]; B: [[...]]; C: [[...]]; D: [[...]]

:func:`load_controller` refuses a file that could harm the rig before it reaches the loop:
wrong rate, wrong dimensions, non-finite numbers, an unstable K∞(z), and an unstable closed
loop — with the plant model given by the caller or, failing that, the design model
``design_plant`` that ``rigd design`` embeds in the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field, field_validator

from rigd.bounded import MAX_CONTROLLER_BYTES
from rigd.configio import StrictModel, dump_yaml, read_yaml, validate
from rigd.errors import InputError

FORMAT_VERSION = 1
#: largest K∞ order the loop runs (it reserves room for this many states; rigd.loop.layout)
MAX_ORDER = 64
Matrix = list[list[float]]


class ContinuousSS(StrictModel):
    A: Matrix
    B: Matrix
    C: Matrix
    D: Matrix


class ControllerFile(StrictModel):
    """Schema of the controller YAML."""

    rigd_controller: int = Field(FORMAT_VERSION, ge=1, le=FORMAT_VERSION)
    fs_hz: float = Field(gt=0)
    inputs: list[str] = ["e_x", "e_y"]
    outputs: list[str] = ["r_x", "r_y"]
    A: Matrix
    B: Matrix
    C: Matrix
    D: Matrix
    continuous: ContinuousSS | None = None
    model_hash: str | None = None
    weights: dict[str, Any] | None = None
    closed_loop_stable: bool | None = None
    #: the design model G_p(z) (ZOH at fs_hz, r -> p); when present the loader re-checks the
    #: closed loop with it, so an edited or mismatched K∞ is refused before it reaches the loop
    design_plant: ContinuousSS | None = None
    gamma: float | None = None
    note: str | None = None

    @field_validator("inputs")
    @classmethod
    def _inputs(cls, v: list[str]) -> list[str]:
        if v != ["e_x", "e_y"]:
            raise ValueError("K∞ inputs must be [e_x, e_y]")
        return v

    @field_validator("outputs")
    @classmethod
    def _outputs(cls, v: list[str]) -> list[str]:
        if v != ["r_x", "r_y"]:
            raise ValueError("K∞ outputs must be [r_x, r_y]")
        return v


@dataclass
class Controller:
    """A validated discrete controller x⁺ = A x + B e, y = C x + D e at ``fs_hz``."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    fs_hz: float
    source: str = "<memory>"
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def order(self) -> int:
        return self.A.shape[0]

    def to_statespace(self):
        """The controller as a python-control discrete StateSpace (dt = 1/fs)."""
        import control

        return control.ss(self.A, self.B, self.C, self.D, 1.0 / self.fs_hz)


def _as_matrix(name: str, rows: Matrix, where: str) -> np.ndarray:
    try:
        m = np.array(rows, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} is not a numeric matrix (ragged rows?)", where) from None
    if m.ndim != 2:
        raise InputError(f"{name} must be a matrix (list of rows), got {m.ndim} dimension(s)",
                         where)
    if not np.all(np.isfinite(m)):
        raise InputError(f"{name} contains NaN or Inf", where)
    return m


def check_controller(A, B, C, D, *, fs_hz: float, expected_fs_hz: float | None,
                     where: str, plant=None) -> None:
    """Raise :class:`InputError` unless (A, B, C, D) is a safe K∞(z) for this loop.

    Parameters
    ----------
    plant : control.StateSpace, optional
        Plant model G_p (u = r → p, discrete at ``fs_hz`` or continuous). When given, the
        closed loop with negative feedback must be stable.
    """
    if expected_fs_hz is not None and abs(fs_hz - expected_fs_hz) > 1e-9 * expected_fs_hz:
        raise InputError(f"controller rate fs_hz={fs_hz:g} Hz differs from the loop rate "
                         f"{expected_fs_hz:g} Hz", where)
    n = A.shape[0]
    if A.shape != (n, n):
        raise InputError(f"A must be square, got {A.shape[0]}x{A.shape[1]}", where)
    if n > MAX_ORDER:
        raise InputError(f"controller order {n} is too high for the loop (at most {MAX_ORDER})",
                         where)
    if B.shape != (n, 2):
        raise InputError(f"B must be {n}x2 (states x inputs e_x, e_y), got "
                         f"{B.shape[0]}x{B.shape[1]}", where)
    if C.shape != (2, n):
        raise InputError(f"C must be 2x{n} (outputs r_x, r_y x states), got "
                         f"{C.shape[0]}x{C.shape[1]}", where)
    if D.shape != (2, 2):
        raise InputError(f"D must be 2x2, got {D.shape[0]}x{D.shape[1]}", where)
    if n:
        rho = float(np.max(np.abs(np.linalg.eigvals(A))))
        if rho >= 1.0:
            raise InputError(f"K∞(z) is unstable: spectral radius of A is {rho:.6f} >= 1", where)
    if plant is not None:
        import control

        K = control.ss(A, B, C, D, 1.0 / fs_hz)
        G = plant if plant.dt else control.c2d(plant, 1.0 / fs_hz, "zoh")
        if G.ninputs != 2 or G.noutputs != 2:
            raise InputError("plant model must be 2x2 for the closed-loop check", where)
        L = control.feedback(G * K, np.eye(2), sign=-1)
        poles = L.poles()
        rho = float(np.max(np.abs(poles))) if len(poles) else 0.0
        if rho >= 1.0:
            raise InputError(f"closed loop with this controller is unstable on the given plant "
                             f"(largest |pole| = {rho:.6f})", where)


def load_controller(path: str | Path, *, expected_fs_hz: float | None = None,
                    plant=None, text: str | None = None) -> Controller:
    """Read, validate and check a controller YAML (see module docstring).

    Raises
    ------
    InputError
        With the file (and line/key where known) and the problem.
    """
    loaded = read_yaml(path, text, limit=MAX_CONTROLLER_BYTES, what="controller file")
    spec = validate(loaded, ControllerFile)
    where = str(path)
    A = _as_matrix("A", spec.A, where) if spec.A else np.zeros((0, 0))
    B = _as_matrix("B", spec.B, where) if spec.B else np.zeros((0, 2))
    C = _as_matrix("C", spec.C, where) if spec.C else np.zeros((2, 0))
    D = _as_matrix("D", spec.D, where)
    if spec.closed_loop_stable is False:
        raise InputError("controller is marked closed_loop_stable: false by its design", where)
    if plant is None and spec.design_plant is not None:
        import control

        dp = spec.design_plant
        mats = [_as_matrix(f"design_plant.{k}", getattr(dp, k), where) for k in "ABCD"]
        try:
            plant = control.ss(*mats, 1.0 / spec.fs_hz)
        except (ValueError, TypeError) as exc:
            raise InputError(f"design_plant is not a valid state space: {exc}", where) from None
    check_controller(A, B, C, D, fs_hz=spec.fs_hz, expected_fs_hz=expected_fs_hz,
                     where=where, plant=plant)
    meta = spec.model_dump(exclude={"A", "B", "C", "D", "design_plant"})
    return Controller(A, B, C, D, spec.fs_hz, where, meta)


def for_loop(controller, fs_hz: float) -> Controller:
    """A controller checked for a loop at ``fs_hz`` before it is handed over.

    A path goes through :func:`load_controller`; a :class:`Controller` object gets the same
    checks as a file (rate, matrix shapes, order <= :data:`MAX_ORDER`, finite, stable), so
    nothing unchecked can raise in (or corrupt) the loop thread.

    Raises
    ------
    InputError
    """
    if not isinstance(controller, Controller):
        return load_controller(controller, expected_fs_hz=fs_hz)
    where = str(controller.source)
    mats = [_as_matrix(f"controller {name}", getattr(controller, name), where)
            for name in "ABCD"]
    check_controller(*mats, fs_hz=float(controller.fs_hz), expected_fs_hz=fs_hz, where=where)
    return controller


def save_controller(path: str | Path, A, B, C, D, *, fs_hz: float, **extra: Any) -> None:
    """Write a controller YAML atomically after the same checks the loader makes."""
    A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in (A, B, C, D))
    check_controller(A, B, C, D, fs_hz=fs_hz, expected_fs_hz=None, where=str(path),
                     plant=extra.pop("plant", None))
    doc: dict[str, Any] = {"rigd_controller": FORMAT_VERSION, "fs_hz": float(fs_hz),
                           "inputs": ["e_x", "e_y"], "outputs": ["r_x", "r_y"],
                           "A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist()}
    for k, v in extra.items():
        if v is not None:
            doc[k] = v
    ControllerFile.model_validate(doc)
    dump_yaml(path, doc)
