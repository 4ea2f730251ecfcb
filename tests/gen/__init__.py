"""Generated test records, independent of rigd's models (scipy/numpy only): each generator
returns a :class:`Generated` — inputs, outputs, rate, names, units and the truth (delays,
orders, poles, parameters) — for the tests of identification and diagnosis on systems rigd
has never seen. Modules:

* :mod:`.signals` — excitations (held random steps, multisines, PRBS);
* :mod:`.linear` — continuous LTI plants simulated exactly through a zero-order hold (or on
  a finer grid for fractional delays): first-order thermal plants with a transport delay,
  an integrator under P/PI feedback (closed-loop data), 2-input mechanical structures with
  3 or 6 modes;
* :mod:`.nonlinear` — Hammerstein and Wiener systems (static curve + linear dynamics) and a
  Bouc–Wen hysteretic oscillator.

Use: ``from tests.gen import linear; g = linear.thermal(delay=3)``; ``g.write_csv(path)``
and ``g.cli_args()`` give the file and the options of ``rigd identify``.
"""

from tests.gen.record import Generated

__all__ = ["Generated"]
