"""One composition mechanism for effects: input blocks → base → output blocks, Lur'e feedback.

A composed model (Hammerstein–Wiener with a Lur'e feedback block; docs/ARCHITECTURE.md,
"Composition of effects") is

    y = N_out(G(N_in(u), −φ(C_f x))),

* *input blocks* N_in (``Effect.input_block(u, θe, data) -> u′``): delay, lags, hysteresis
  and creep of the drives, an input polynomial;
* the *base* G: any model family (``rigd.ident.model.Model``);
* a *feedback block* (``Effect.state_block(θe, data) -> MechanicalFeedback``): φ of the
  base's states [p, ṗ] into its force input; the blocks of every state-level effect are
  summed and handed to the base's simulator, which must carry them (``requires =
  ("mechanical",)``; :func:`carries`);
* *output blocks* (``Effect.output_block(y, θe, data) -> y′``): in series (an output
  polynomial) or in parallel (a lag, a mode, an integrator, run-out harmonics).

:class:`Composed` is one flat structure: the base's parameters, then each effect's in the
order added. Input blocks run from the last-added effect to the first and output blocks from
the first to the last — the order of the nested wrappers it replaces, so model files written
by them (effects by name, parameters by name) rebuild into the same model.

Each effect declares its ``sites`` (``input``, ``output``, ``state``) and what the base must
carry (``requires``: ``mechanical``, ``rotation``); an effect whose requirement the base lacks
is refused with the sentence of ``Effect.not_offered``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from rigd.effects.scales import RecordScale
from rigd.ident.feedback import MechanicalFeedback
from rigd.ident.iddata import get_phi, replace_inputs
from rigd.ident.model import Model, base_of

__all__ = ["Composed", "compose", "carries", "SITES", "REQUIREMENTS"]

#: where an effect acts: before the base, after it, fed back into its states, or into one
#: mode's coordinate of a modal base (rigd.ident.lti.nonlinear_mode)
SITES = ("input", "output", "state", "mode")
#: what an effect may require: velocity states [p, ṗ] the simulator feeds back into
#: (``mechanical``); a shaft angle in the record (``rotation``); complex-pair blocks whose
#: modal coordinate a restoring force can act on (``mode``)
REQUIREMENTS = ("mechanical", "rotation", "mode")

Sim = Callable[[Any], np.ndarray]


def carries(structure: Any, data: Any = None) -> set[str]:
    """What the base of ``structure`` can carry (:data:`REQUIREMENTS`).

    The model states two (``Model.carries``): ``mechanical`` — its states are [p, ṗ] and its
    simulator takes the feedback of state-level effects; ``mode`` — a general LTI model in
    modal form with at least one complex pair (:class:`rigd.ident.lti.statespace.
    StateSpaceModel`). ``rotation``: the record ``data`` has a shaft angle (``phi``); without
    ``data`` it is not known and assumed carried.
    """
    out = set(base_of(structure).carries)
    if data is None or get_phi(data) is not None:
        out.add("rotation")
    return out


def _of_base(name: str) -> property:
    """A read-only attribute of a composed model that is its base's ``name``."""
    return property(lambda self: getattr(self.base, name),
                    doc=f"The base model's ``{name}`` (rigd.ident.model.Model).")


class Composed(Model):
    """A base model with effects composed around it (module docstring).

    Parameters
    ----------
    base : Model
        The base model (a :class:`Composed` is unwrapped: its effects come first).
    effects : sequence of Effect
        The effects, in the order added.

    Raises
    ------
    ValueError
        An effect the base cannot carry (``Effect.not_offered``'s sentence).
    """

    def __init__(self, base: Any, effects: Sequence[Any]):
        if isinstance(base, Composed):
            effects = list(base.effect_list) + list(effects)
            base = base.base
        self.base = base
        self.effect_list = list(effects)
        seen = [e.name for e in self.effect_list]
        twice = sorted({n for n in seen if seen.count(n) > 1})
        if twice:
            raise ValueError(f"{', '.join(twice)} added twice: an effect enters a model once")
        for k, e in enumerate(self.effect_list):
            for o in self.effect_list[:k]:
                if e.clashes_with(o):
                    raise ValueError(f"{e.name} cannot be simulated beside {o.name} in one "
                                     "model")
        for e in self.effect_list:
            if not e.sites or not set(e.sites) <= set(SITES):
                raise ValueError(f"{e.name} declares no site of {SITES} (Effect.sites)")
            why = e.not_offered(base)
            if why is not None:
                raise ValueError(why)
        self.nb = len(base.names)
        names, self._slices = list(base.names), []
        for e in self.effect_list:
            en = list(e.param_names(base))
            self._slices.append(slice(len(names), len(names) + len(en)))
            names += en
        self.names = names
        self.effects = list(base.effects) + [e.name for e in self.effect_list]
        #: scales of the data the structure is fitted on (bounds relative to the record)
        self.record: RecordScale | None = None

    # --- what the base states, seen through the effects (Model's attributes of the base:
    # its indices into θ, which come first, and what it carries, delays, hold) --------------
    kind = _of_base("kind")
    x0_index = _of_base("x0_index")
    offset_index = _of_base("offset_index")
    noise_index = _of_base("noise_index")
    velocity_index = _of_base("velocity_index")
    carries = _of_base("carries")
    n_integrators = _of_base("n_integrators")
    n_parallel_modes = _of_base("n_parallel_modes")
    delays = _of_base("delays")
    hold = _of_base("hold")
    _n_est = _of_base("_n_est")
    # the channels: the effects change no count or name of them
    nu = _of_base("nu")
    ny = _of_base("ny")
    input_names = _of_base("input_names")
    output_names = _of_base("output_names")

    def scale(self, theta: np.ndarray) -> np.ndarray:
        return self.base.scale(theta)

    def predict(self, theta: np.ndarray, data: Any) -> np.ndarray | None:
        return self.base.predict(theta, data)

    def linear_part(self, theta: np.ndarray):
        return self.base.linear_part(np.asarray(theta, float)[:self.nb])

    def output_offset(self, theta: np.ndarray) -> np.ndarray | None:
        return self.base.output_offset(np.asarray(theta, float)[:self.nb])

    def describe(self) -> str:
        return self.base.describe()

    @property
    def fixed_names(self) -> list[str]:
        """Parameters no fit moves (``Effect.fixed_names``: e.g. the centres of a curve,
        set from the estimation data); rigd.ident.pem.fit keeps them where they are."""
        return [n for e in self.effect_list for n in e.fixed_names(self.base)]

    # --- composition --------------------------------------------------------------------
    def with_effect(self, effect: Any) -> Composed:
        """This model with one more effect (added last)."""
        return Composed(self.base, self.effect_list + [effect])

    def parts(self, theta: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """(base parameters, [each effect's parameters])."""
        th = np.asarray(theta, dtype=float)
        return th[:self.nb], [th[s] for s in self._slices]

    def bind_record(self, data: Any) -> None:
        """Make the effects' bounds relative to ``data`` (the estimation data): its rate,
        length and signal spreads (:class:`rigd.effects.scales.RecordScale`). Called by the
        fit (rigd.ident.pem.fit) and the diagnosis refit; without it the effects'
        record-free bounds apply."""
        self.record = RecordScale.of(data)

    def theta0(self, data: Any) -> np.ndarray:
        return np.concatenate([np.asarray(self.base.theta0(data), float)]
                              + [np.asarray(e.theta0_effect(self.base, data), float)
                                 for e in self.effect_list])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower/upper bounds (the base's if it has them, else unbounded; the effects'
        relative to the bound record, else record-free)."""
        lb, ub = self.base.bounds()
        los, his = [np.asarray(lb, float)], [np.asarray(ub, float)]
        for e in self.effect_list:
            lo, hi = (e.record_bounds(self.base, self.record) if self.record is not None
                      else e.param_bounds(self.base))
            los.append(np.asarray(lo, float))
            his.append(np.asarray(hi, float))
        return np.concatenate(los), np.concatenate(his)

    def typical(self) -> np.ndarray | None:
        """Typical sizes of the effects' parameters on the bound record (1 where an effect
        states none; None without a record)."""
        if self.record is None:
            return None
        out = []
        for e, s in zip(self.effect_list, self._slices):
            t = e.param_typical(self.base, self.record)
            out.append(np.ones(s.stop - s.start) if t is None else np.asarray(t, float))
        return np.concatenate(out) if out else np.zeros(0)

    # --- simulation ---------------------------------------------------------------------
    def feedback(self, theta: np.ndarray, data: Any) -> MechanicalFeedback | None:
        """The sum of the state-level effects' feedback blocks at ``theta`` (None: none)."""
        _, te = self.parts(theta)
        fb = None
        for e, t in zip(self.effect_list, te):
            if "state" in e.sites:
                blk = e.state_block(t, data)
                if blk is not None:  # None: the effect simulates its state model itself
                    fb = blk if fb is None else fb.plus(blk)
        return fb

    def _core(self, tb: np.ndarray, te: list[np.ndarray], data: Any) -> Sim:
        """The base's simulation with the feedback blocks in it."""
        own = [(e, t) for e, t in zip(self.effect_list, te)
               if ("state" in e.sites or "mode" in e.sites)
               and e.state_simulate is not None and e.owns_state(self.base)]
        fb = self.feedback(np.concatenate([tb] + te), data)
        if own:
            if len(own) > 1:
                raise ValueError(f"{' and '.join(e.name for e, _ in own)} each bring their "
                                 "own state model; one model carries one of them")
            e, t = own[0]
            return lambda d: np.asarray(e.state_simulate(self.base, tb, t, fb, d), float)
        if fb is None:
            return lambda d: np.asarray(self.base.simulate(tb, d), float)
        return lambda d: np.asarray(self.base.simulate(tb, d, fb), float)

    def simulate(self, theta: np.ndarray, data: Any) -> np.ndarray:
        """Simulated output (n, ny): the input blocks, the base with the feedback blocks,
        the output blocks (module docstring)."""
        tb, te = self.parts(theta)
        sim = self._core(tb, te, data)
        for e, t in zip(self.effect_list, te):
            if "input" in e.sites or "output" in e.sites:
                sim = _wrapped(e, t, sim)
        return np.asarray(sim(data), dtype=float)

    def output_sensitivities(self, theta: np.ndarray, data: Any):
        """The base's exact output sensitivities (:func:`rigd.ident.jacobian`) when the
        effects leave the output linear in the base's linear parameters: each acts on the
        inputs (the base then sees the effects' inputs, in the order :meth:`simulate` applies
        them) or adds a path of its own parallel to the base (``additive_output``: y + g(u));
        a mode-site effect gives those it can from them (:meth:`Effect.sensitivities`: the
        base's outside its mode, its own that enter linearly); None otherwise, or when the
        base has none.

        Returns
        -------
        (indices, dY) or None
            ``indices`` into ``theta`` (the base's parameters first, then the effects'),
            ``dY[k]`` = ∂ŷ/∂θ[indices[k]] (k, n, ny).
        """
        method = type(self.base).output_sensitivities
        if method is None:
            return None
        tb, te = self.parts(theta)
        site = None          # the mode-site effect and its first index in theta
        for e, t, sl in zip(self.effect_list, te, self._slices):
            sites = set(e.sites)
            if sites == {"mode"}:
                site = (e, t, sl.start)
            elif not sites <= {"input", "output"} or ("output" in sites
                                                       and not e.additive_output):
                return None
        d = data
        # simulate()'s nesting: the last effect added is the outermost, its input block first
        for e, t in reversed(list(zip(self.effect_list, te))):
            if "input" in e.sites:
                u = np.asarray(d.inputs, float)
                v = e.input_block(u, t, d)
                if v is not u:
                    d = replace_inputs(d, v)
        out = method(self.base, tb, d)
        if out is None or site is None:
            return out
        e, t, start = site
        got = e.sensitivities(self.base, tb, t, d, *out)
        if got is None:
            return None
        base_idx, own_idx, dY = got
        return np.concatenate([base_idx, start + own_idx]).astype(int), dY

    # --- linear part and read-outs -------------------------------------------------------
    def linear_ss(self, theta: np.ndarray, fs: float, G0: Any = None):
        """(G, included, left_out): the base's linear part (continuous python-control
        StateSpace; ``G0`` in its place, e.g. a range model of the same base; ``fs`` the
        rate, Hz, of the record the parameters were fitted on) with each effect's
        small-signal linear block applied in the order added (:meth:`Effect.linear`: an
        input block in series before the base, an output block in parallel); ``included``
        the effects applied, ``left_out`` {name: why not}."""
        tb, te = self.parts(theta)
        G = self.base.ss(tb) if G0 is None else G0
        included, left_out = [], {}
        for e, t in zip(self.effect_list, te):
            Gx = e.linear(G, t, self.base, fs)
            if Gx is None:
                left_out[e.name] = e.linear_note
            else:
                G = Gx
                included.append(e.name)
        return G, included, left_out

    def ss(self, theta: np.ndarray):
        return self.base.ss(np.asarray(theta, float)[:self.nb])

    def continuous(self, theta: np.ndarray):
        return self.base.continuous(np.asarray(theta, float)[:self.nb])

    def readouts(self, theta: np.ndarray) -> dict[str, Any]:
        theta = np.asarray(theta, float)
        out = dict(self.base.readouts(theta[:self.nb]))
        out.update({n: float(v) for n, v in zip(self.names[self.nb:], theta[self.nb:])})
        return out

    def spec(self) -> dict[str, Any]:
        d = dict(self.base.spec())
        d["effects"] = list(self.effects)
        return d

    def __deepcopy__(self, memo: dict) -> Composed:
        new = Composed.__new__(Composed)
        memo[id(self)] = new
        for k, v in vars(self).items():
            # the effects are the catalogue's stateless instances: shared, not copied
            setattr(new, k, list(v) if k == "effect_list" else copy.deepcopy(v, memo))
        return new


def _wrapped(effect: Any, theta_e: np.ndarray, inner: Sim) -> Sim:
    """``inner`` with ``effect``'s input block before it and its output block after it."""
    def sim(data: Any) -> np.ndarray:
        d = data
        if "input" in effect.sites:
            u = np.asarray(data.inputs, float)
            v = effect.input_block(u, theta_e, data)
            if v is not u:
                d = replace_inputs(data, v)
        y = inner(d)
        if "output" in effect.sites:
            y = effect.output_block(np.asarray(y, float), theta_e, data)
        return y
    return sim


def compose(structure: Any, effects: Sequence[Any]) -> Composed:
    """``structure`` with ``effects`` added in order (one flat :class:`Composed`)."""
    return Composed(structure, effects)
