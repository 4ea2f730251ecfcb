"""Every significance threshold of identification and diagnosis, in one place.

Each constant is used by name wherever the rule applies (rigd.ident.greybox.order, rigd.ident.hold,
rigd.effects.detectability, rigd.diagnose.engine, rigd.diagnose.unexplained,
rigd.diagnose.probes); none is defined twice. It lives in :mod:`rigd.ident` (the lowest of
those layers) so that every layer can import it. Fit points are points of
:func:`rigd.ident.figures.fit_percent` (100·(1 − NRMSE)); shares are shares of a residual's
error energy on the validation part (0..1).
"""

from __future__ import annotations

#: Practical significance, fit points (%): the least validation fit an effect, a mode or
#: structure left in the residual must be worth to be named (the effects' refit, the
#: order search's next mode, ``unexplained``'s structure, the yardstick's warning, the
#: detectability of an effect a record could show).
MIN_FIT_GAIN = 0.5

#: Statistical significance: level of the F tests (an effect's signature, a probe, the
#: detectability of an effect in a record).
P_LEVEL = 1e-3

#: Share of the validation error energy a refit must remove (with a significant signature)
#: for the effect to be significant; also the least share of the residual an effect must
#: be able to take for a record to show it (detectability).
MIN_REFIT_GAIN = 0.10

#: Share of the validation error energy a refit must remove to be significant on its own
#: (with a decisive F test) when the linearised signature explains less than its
#: ``min_score``: a strong effect's first-order signature can be poor.
STRONG_REFIT_GAIN = 0.5

#: Least share of the error energy a localisation of unexplained structure (a band, an
#: amplitude range, a stretch, a direction) or a probe must hold to be reported.
MIN_SHARE = 0.10

#: Residual rms above this multiple of the measurement-noise estimate counts as structured.
LEVEL_RATIO = 1.5

#: Fit points by which the non-default input hold must win to be chosen from the data.
HOLD_MARGIN_POINTS = 0.1

#: Relative distance from an existing mode for a candidate mode to count as new.
MODE_SEPARATION = 0.1

#: Confidence of the whiteness and residual–input cross-correlation tests (two-sided, as
#: MATLAB's ``resid``).
CORR_CONFIDENCE = 0.99
