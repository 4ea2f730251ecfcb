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

import math
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
    #: the file's design model G_p(z) as (A, B, C, D) at ``fs_hz`` (None: the file has none)
    design_plant: tuple | None = None

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


#: default of ``controller_gates.max_gain_v_per_um`` (rig config): K∞'s largest gain over
#: frequency, V/µm — a 0.1 µm error would then drive the whole 10 V range (the shipped design
#: peaks near 5 V/µm)
MAX_GAIN_V_PER_UM = 100.0
#: the nominal plant model shipped with rigd (the paper's rig at 4000 rpm, 7 bar: the design
#: model of config/controller.yaml): ``controller_gates.nominal_plant``'s default
NOMINAL_PLANT = Path(__file__).with_name("nominal_plant.yaml")
#: frequencies at which the gain is evaluated, 0 .. Nyquist
_N_FREQ = 512


class PlantModelFile(StrictModel):
    """A plant model file (``controller_gates.nominal_plant``): G_p from r = [r_x, r_y] (V)
    to p = [e_x, e_y] (µm); discrete at ``fs_hz`` (zero-order hold), or continuous when
    ``fs_hz`` is absent."""

    A: Matrix
    B: Matrix
    C: Matrix
    D: Matrix
    fs_hz: float | None = Field(None, gt=0)
    note: str | None = None


@dataclass(frozen=True)
class Gates:
    """What a controller must pass beyond the file checks (the rig config's
    ``controller_gates``): its peak gain at most ``max_gain`` V/µm, and — when its file has no
    ``design_plant`` — a stable closed loop on ``nominal`` (:class:`PlantSS`, or None)."""

    max_gain: float | None = MAX_GAIN_V_PER_UM
    nominal: Any = None
    nominal_source: str = ""


def gates_from(opts: dict[str, Any] | None) -> Gates | None:
    """:class:`Gates` from the rig config's ``controller_gates`` as plain values
    (:meth:`rigd.rigconfig.LoadedConfig.gate_options`: ``max_gain``, ``nominal_plant``
    path); the nominal plant read here. None without options.

    Raises
    ------
    InputError
        The nominal plant file is missing or invalid (named, with the config key).
    """
    if not opts:
        return None
    path = opts.get("nominal_plant")
    try:
        plant = load_plant(path) if path else None
    except InputError as exc:
        raise InputError(f"controller_gates.nominal_plant: {exc}") from None
    return Gates(max_gain=opts.get("max_gain"), nominal=plant, nominal_source=str(path or ""))


@dataclass(frozen=True)
class PlantSS:
    """A plant model G_p as state-space matrices, all the controller checks need of it.

    ``dt`` is the sample period, s (0: continuous). The checks take this or a
    python-control ``StateSpace`` (same attribute names); they do not import python-control:
    with scipy.signal and matplotlib it cost every process that loads a controller (the
    daemon's socket process reads the config's nominal plant at its start) ≈ 1.5 CPU-s.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float = 0.0

    @property
    def ninputs(self) -> int:
        return self.B.shape[1]

    @property
    def noutputs(self) -> int:
        return self.C.shape[0]


def plant_ss(mats, dt: float, where: str, what: str = "plant model") -> PlantSS:
    """(A, B, C, D) as a :class:`PlantSS` with sample period ``dt`` (0: continuous).

    Raises
    ------
    InputError
        The shapes do not make a state space (named: which matrix, which size).
    """
    A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in mats)
    n = A.shape[0] if A.size else 0
    if A.size == 0:
        A = np.zeros((0, 0))
        B = B.reshape(0, D.shape[1]) if B.size == 0 else B
        C = C.reshape(D.shape[0], 0) if C.size == 0 else C
    if A.shape != (n, n):
        raise InputError(f"{what}: A must be square, got {A.shape[0]}x{A.shape[1]}", where)
    if B.shape[0] != n or C.shape[1] != n or D.shape != (C.shape[0], B.shape[1]):
        raise InputError(f"{what}: not a valid state space: A {A.shape[0]}x{A.shape[1]}, "
                         f"B {B.shape[0]}x{B.shape[1]}, C {C.shape[0]}x{C.shape[1]}, "
                         f"D {D.shape[0]}x{D.shape[1]}", where)
    return PlantSS(A, B, C, D, float(dt))


def load_plant(path: str | Path) -> PlantSS:
    """Read a plant model file (:class:`PlantModelFile`) as a :class:`PlantSS`.

    Raises
    ------
    InputError
        Naming the file and the key (never quoting the file's content).
    """
    spec = validate(read_yaml(path, None, limit=MAX_CONTROLLER_BYTES, what="plant model file"),
                    PlantModelFile)
    where = str(path)
    mats = [_as_matrix(k, getattr(spec, k), where) for k in "ABCD"]
    G = plant_ss(mats, 0.0 if spec.fs_hz is None else 1.0 / spec.fs_hz, where)
    if G.ninputs != 2 or G.noutputs != 2:
        raise InputError(f"the plant model must have 2 inputs (r_x, r_y) and 2 outputs (e_x, "
                         f"e_y), got {G.ninputs} and {G.noutputs}", where)
    return G


def peak_gain(A, B, C, D) -> tuple[float, float]:
    """Largest singular value of K(e^{jω}) = C (e^{jω} I - A)⁻¹ B + D over ``_N_FREQ``
    frequencies from 0 to Nyquist, and the normalised frequency ω/π where it is reached;
    ``inf`` when it overflows (entries like 1e300)."""
    n = A.shape[0]
    w = np.linspace(0.0, np.pi, _N_FREQ)
    with np.errstate(all="ignore"):
        if n:
            z = np.exp(1j * w)[:, None, None] * np.eye(n) - A
            H = C @ np.linalg.solve(z, np.broadcast_to(B, (len(w), n, 2))) + D
        else:
            H = np.broadcast_to(D.astype(complex), (len(w), 2, 2))
        if not np.all(np.isfinite(H)):
            return math.inf, 0.0
        sv = np.linalg.svd(H, compute_uv=False)[:, 0]
    k = int(np.argmax(sv))
    return float(sv[k]), float(w[k] / np.pi)


def check_gates(A, B, C, D, *, fs_hz: float, where: str, gates: Gates | None,
                has_design_plant: bool) -> None:
    """Raise :class:`InputError` unless the controller passes ``gates`` (:class:`Gates`)."""
    if gates is None:
        return
    if gates.max_gain is not None:
        g, f = peak_gain(A, B, C, D)
        if not g <= gates.max_gain:
            at = "" if not math.isfinite(g) else f" at {f * fs_hz / 2:.0f} Hz"
            what = "overflows (entries of B, C or D too large)" if not math.isfinite(g) \
                else f"{g:.4g} V/µm{at}"
            raise InputError(f"K∞ gain {what} exceeds controller_gates.max_gain_v_per_um = "
                             f"{gates.max_gain:g} (rig config)", where)
    if not has_design_plant and gates.nominal is not None:
        closed_loop_check(A, B, C, D, fs_hz=fs_hz, where=where, plant=gates.nominal,
                          on=f"the nominal plant {gates.nominal_source} (the file has no "
                             f"design_plant)")


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
        closed_loop_check(A, B, C, D, fs_hz=fs_hz, where=where, plant=plant)


def closed_loop_check(A, B, C, D, *, fs_hz: float, where: str, plant,
                      on: str = "the given plant") -> None:
    """Raise :class:`InputError` unless the negative-feedback loop of K∞ (A, B, C, D at
    ``fs_hz``) with ``plant`` (:class:`PlantSS` or a python-control ``StateSpace``; discrete,
    or continuous and then held: zero-order hold at ``fs_hz``) is stable; ``on`` names the
    plant in the message."""
    G = _plant_at(plant, 1.0 / fs_hz, where)
    if G.ninputs != 2 or G.noutputs != 2:
        raise InputError("plant model must be 2x2 for the closed-loop check", where)
    rho = _closed_loop_radius(G, np.asarray(A, float), np.asarray(B, float),
                              np.asarray(C, float), np.asarray(D, float), where)
    if not rho < 1.0:
        raise InputError(f"closed loop with this controller is unstable on {on} "
                         f"(largest |pole| = {rho:.6f})", where)


def _plant_at(plant, dt: float, where: str) -> PlantSS:
    """``plant`` discrete at ``dt``: held (zero-order hold) if continuous, re-sampled (zoh
    both ways) if discrete at another period; a discrete plant of unspecified period
    (python-control's ``dt=True``) is taken as at ``dt``."""
    G = plant_ss((plant.A, plant.B, plant.C, plant.D), 0.0, where)
    pdt = plant.dt
    if pdt is True or (pdt and abs(float(pdt) - dt) <= 1e-9 * dt):
        return PlantSS(G.A, G.B, G.C, G.D, dt)
    if pdt:       # another rate (rare): back to continuous first (the zoh inverted)
        G = _unhold(G, float(pdt), where)
    from rigd.lti import zoh

    Ad, Bd = zoh(G.A, G.B, dt) if G.A.size else (G.A, G.B)
    return PlantSS(Ad, Bd, G.C, G.D, dt)


def _unhold(G: PlantSS, dt: float, where: str) -> PlantSS:
    """The continuous plant whose zero-order hold at ``dt`` is ``G``: the matrix logarithm
    of [[A_d, B_d], [0, I]] over ``dt``. InputError if there is none (a pole at z ≤ 0)."""
    import scipy.linalg

    n, m = G.B.shape
    E = np.block([[G.A, G.B], [np.zeros((m, n)), np.eye(m)]])
    with np.errstate(all="ignore"):
        L = scipy.linalg.logm(E) / dt
    if not np.all(np.isfinite(L)) or np.max(np.abs(L.imag)) > 1e-6 * max(1.0, np.max(np.abs(L))):
        raise InputError(f"the plant model (discrete at {1 / dt:g} Hz) has no continuous "
                         f"equivalent to re-sample it at the loop rate (a pole at z <= 0)",
                         where)
    return PlantSS(L.real[:n, :n], L.real[:n, n:], G.C, G.D, 0.0)


def _closed_loop_radius(G: PlantSS, Ak, Bk, Ck, Dk, where: str) -> float:
    """Largest |pole| of the loop e = −y, u = K∞ e, y = G u (both discrete, same rate).

    With M = (I + D_g D_k)⁻¹ (the algebraic loop through the feedthroughs) the closed-loop
    state matrix over [x_g; x_k] is
    [[A_g − B_g D_k M C_g,  B_g (I − D_k M D_g) C_k], [−B_k M C_g,  A_k − B_k M D_g C_k]].
    """
    ng, nk = G.A.shape[0], Ak.shape[0]
    Ak, Bk, Ck = Ak.reshape(nk, nk), Bk.reshape(nk, 2), Ck.reshape(2, nk)
    I2 = np.eye(2)
    try:
        M = np.linalg.solve(I2 + G.D @ Dk, I2)
    except np.linalg.LinAlgError:
        raise InputError("closed loop with this controller is ill-posed (I + D_g D_k is "
                         "singular)", where) from None
    Acl = np.block([[G.A - G.B @ Dk @ M @ G.C, G.B @ (I2 - Dk @ M @ G.D) @ Ck],
                    [-Bk @ M @ G.C, Ak - Bk @ M @ G.D @ Ck]])
    if ng + nk == 0:
        return 0.0
    if not np.all(np.isfinite(Acl)):
        return math.inf
    return float(np.max(np.abs(np.linalg.eigvals(Acl))))


def load_controller(path: str | Path, *, expected_fs_hz: float | None = None,
                    plant=None, text: str | None = None,
                    gates: Gates | None = None) -> Controller:
    """Read, validate and check a controller YAML (see module docstring); with ``gates``
    (:class:`Gates`, the rig config's ``controller_gates``) also its peak gain and, when the
    file has no ``design_plant``, its closed loop on the nominal plant.

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
    design = None
    if spec.design_plant is not None:
        dp = spec.design_plant
        design = tuple(_as_matrix(f"design_plant.{k}", getattr(dp, k), where) for k in "ABCD")
    if plant is None and design is not None:
        plant = design_statespace(design, spec.fs_hz, where)
    check_controller(A, B, C, D, fs_hz=spec.fs_hz, expected_fs_hz=expected_fs_hz,
                     where=where, plant=plant)
    check_gates(A, B, C, D, fs_hz=spec.fs_hz, where=where, gates=gates,
                has_design_plant=plant is not None)
    meta = spec.model_dump(exclude={"A", "B", "C", "D", "design_plant"})
    return Controller(A, B, C, D, spec.fs_hz, where, meta, design)


def design_statespace(mats, fs_hz: float, where: str) -> PlantSS:
    """A file's design plant (A, B, C, D) as a discrete :class:`PlantSS` at ``fs_hz``;
    InputError if it is not one."""
    return plant_ss(mats, 1.0 / fs_hz, where, what="design_plant")


# --- the controller as it crosses a socket: its matrices, never its file -----------------
def _wire_matrix(m: np.ndarray) -> dict[str, Any]:
    import base64

    m = np.ascontiguousarray(m, dtype="<f8")
    return {"shape": [int(m.shape[0]), int(m.shape[1])],
            "f64": base64.b64encode(m.tobytes()).decode("ascii")}


def _unwire_matrix(name: str, d: dict[str, Any], where: str) -> np.ndarray:
    import base64
    import binascii

    try:
        rows, cols = (int(x) for x in d["shape"])
        raw = base64.b64decode(d["f64"], validate=True)
    except (KeyError, TypeError, ValueError, binascii.Error):
        raise InputError(f"{name}: not a matrix (shape [rows, cols] and f64: base64 of "
                         f"little-endian float64)", where) from None
    if rows < 0 or cols < 0 or rows > MAX_ORDER + 2 or cols > MAX_ORDER + 2 \
            or len(raw) != 8 * rows * cols:
        raise InputError(f"{name}: {len(raw)} bytes do not hold a {rows}x{cols} float64 "
                         f"matrix of at most {MAX_ORDER + 2} rows and columns", where)
    m = np.frombuffer(raw, dtype="<f8").reshape(rows, cols).astype(np.float64)
    if not np.all(np.isfinite(m)):
        raise InputError(f"{name} contains NaN or Inf", where)
    return m


def to_wire(ctrl: Controller) -> dict[str, Any]:
    """A loaded controller as plain JSON values for the control socket: ``fs_hz``, the four
    matrices (base64 float64, exact) and the design plant's (or ``None``) — what the client
    sends instead of a path (the daemon opens no file a client names)."""
    out: dict[str, Any] = {"fs_hz": float(ctrl.fs_hz)}
    for k in "ABCD":
        out[k] = _wire_matrix(getattr(ctrl, k))
    dp = ctrl.design_plant
    out["design_plant"] = None if dp is None else dict(zip("ABCD", map(_wire_matrix, dp)))
    return out


def from_wire(wire: dict[str, Any], *, source: str, expected_fs_hz: float | None,
              gates: Gates | None = None) -> Controller:
    """:func:`to_wire`'s values back to a :class:`Controller`, with every check a file gets
    (rate, shapes, order, finite, stable K∞, the closed loop on its design plant) and
    ``gates``.

    Raises
    ------
    InputError
        Naming ``source`` (the client's label for its file) and the problem.
    """
    where = source
    try:
        fs_hz = float(wire["fs_hz"])
    except (KeyError, TypeError, ValueError):
        raise InputError("fs_hz: a number is needed", where) from None
    if not (math.isfinite(fs_hz) and fs_hz > 0):
        raise InputError("fs_hz must be a positive number", where)
    A, B, C, D = (_unwire_matrix(k, wire.get(k), where) for k in "ABCD")
    if A.size == 0:
        A, B, C = np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0))
    design = None
    if wire.get("design_plant") is not None:
        dp = wire["design_plant"]
        design = tuple(_unwire_matrix(f"design_plant.{k}", dp.get(k), where) for k in "ABCD")
    plant = design_statespace(design, fs_hz, where) if design is not None else None
    check_controller(A, B, C, D, fs_hz=fs_hz, expected_fs_hz=expected_fs_hz, where=where,
                     plant=plant)
    check_gates(A, B, C, D, fs_hz=fs_hz, where=where, gates=gates,
                has_design_plant=plant is not None)
    return Controller(A, B, C, D, fs_hz, where, {}, design)


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
