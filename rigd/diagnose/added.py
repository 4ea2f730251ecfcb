"""``rigd identify --add NAME`` fitted as ``rigd diagnose`` fits NAME: one pipeline.

The diagnosis refits an effect from its signature on the fitted base: the starts the
signature gives (``Effect.refit_starts``: a mode effect at the mode whose regressors explain
most, a curve scaled to the first-order fit), the parameters it keeps (``Effect.refit_fixed``:
the sites of a static curve the signature did not choose stay at 0), the other forms it
tries (``Effect.refit_alternatives``: both block sites, the state site), and — when the
input hold was chosen by the linear base — the other hold once the effect is in
(:func:`rigd.diagnose.selection.refit_effect`, :func:`~rigd.diagnose.selection.try_hold`).
:func:`refit_as_diagnosed` runs exactly those steps for the effects asked, in the order
asked, so that what ``identify --add`` saves is what ``diagnose`` named and measured. It is
handed to :func:`rigd.ident.workflow.identify_record` as its ``refit`` (rigd.api.identify);
with ``--init`` the model file's parameters are the start instead (the plain refit).
"""

from __future__ import annotations

from typing import Any

from rigd.diagnose import selection as S
from rigd.diagnose.engine import base_context
from rigd.ident.pem import evaluate
from rigd.ident.pipeline import held_base


def refit_as_diagnosed(bf, applied: list[Any], sm: str, method: str,
                       meta: dict | None = None):
    """(structure, fit result): the base of ``bf`` (rigd.ident.pipeline.BaseFit) with the
    effects ``applied``, each refitted as the diagnosis's forward selection refits it
    (module docstring), on ``bf``'s estimation part; ``meta``: the record's metadata (its
    domain's words and what it offers, as in the diagnosis). The fit result's standard
    deviations are those of the last refit's Jacobian (:func:`rigd.ident.pem.evaluate`)."""
    ctx0, context, _ = base_context(bf.data, sm, bf.structure, bf.theta, bf.est, bf.val,
                                    meta)
    data_est = bf.data.slice(bf.est.start, bf.est.stop)
    other_hold = S.other_hold(bf)
    ctx, kept = ctx0, ()
    step, notes = None, []
    for eff in applied:
        ref = S.refit_effect(eff, ctx, eff.signature(ctx), data_est, None, method, kept)
        if ref.window is not None:
            notes.append(S.window_note(eff.name, *ref.window))
        step = S.Step(eff.name, ref.fit_percent, ref.structure, ref.theta, ref.yhat,
                      ref.fixed)
        if other_hold is not None:   # as the diagnosis: asked once, with the first effect
            alt = S.try_hold(step, ctx0, other_hold, data_est, method)
            step, other_hold = (step if alt is None else alt), None
        kept = tuple(step.fixed)
        ctx = context(step.structure, step.theta, step.yhat)
    res = evaluate(step.structure, data_est, step.theta,
                   status="refitted as rigd diagnose refits it")
    res.info["fixed"] = list(kept)
    res.info["notes"] = notes
    res.info["held_base"] = len(held_base(bf.structure, method))
    return step.structure, res
