"""Linear time-invariant models and the black-box reference estimators.

* :mod:`.linear` — :class:`LinearModel` (discrete innovation form A, B, C, D, K, x0 with the
  operating point), free-run simulation, one-step prediction, :func:`heldout` (free run of
  the validation part from the predictor's state at the end of the estimation part);
* :mod:`.arx` — least-squares MIMO ARX (:func:`fit_arx`, :func:`select_arx`);
* :mod:`.subspace` — PO-MOESP subspace estimate (:func:`n4sid`, :func:`select_subspace`)
  returning A, B, C, D, K, x0 and the singular values;
* :mod:`.delay` — per-input delay (:func:`estimate_delays`: ARX impulse response and
  prewhitened cross-correlation, with a confidence);
* :mod:`.lsq` — least squares by an accumulated QR (memory bounded);
* :mod:`.statespace` — the general LTI model family in real-block modal form
  (:class:`StateSpaceModel`, a :class:`rigd.ident.model.Model`), start values from
  :mod:`.modal` (subspace poles, gains by least squares).
"""

from rigd.ident.lti.arx import ArxModel, ArxSelection, fit_arx, select_arx
from rigd.ident.lti.delay import DelayEstimate, estimate_delays
from rigd.ident.lti.linear import LinearModel, heldout
from rigd.ident.lti.subspace import SubspaceResult, n4sid, select_subspace

__all__ = ["ArxModel", "ArxSelection", "DelayEstimate", "LinearModel", "SubspaceResult",
           "estimate_delays", "fit_arx", "heldout", "n4sid", "select_arx", "select_subspace"]
