"""rigd — real-time control daemon and grey-box modelling workflow for a rotor-gas bearing rig.

The package follows the paper "Modelling of Rotor-gas bearings for Feedback Controller Design"
(Theisen, Galeazzi, Santos, Niemann). Names from the paper (r_p, y_p, K∞, W_p, W_u, Ω, P_I)
are used in code and explained where they are defined.
"""

__version__ = "0.1.0"

from rigd import jitcache as _jitcache  # noqa: E402  (before any kernel compiles)

_jitcache.configure()
