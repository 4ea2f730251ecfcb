"""rigd.diagnose.rebase: which diagnosis is kept once the linear part was chosen again with a
static curve in (the rule; the whole path on an independent Hammerstein record is
tests/diagnose/test_neutral_catalogue.py's ``hammerstein-input``)."""

from types import SimpleNamespace as NS

from rigd.diagnose import rebase
from rigd.ident.thresholds import MIN_FIT_GAIN


def _diag(base, final, added=("static_nonlinearity",)):
    steps = [NS(added=None, fit_percent=base)] + [NS(added=a, fit_percent=final) for a in added]
    return NS(final=steps[-1], steps=steps, fit_percent=base)


def _cand(states, delays):
    return NS(family="lti", states=states, delays=list(delays),
              structure=NS(delays=list(delays)))


def test_the_first_diagnosis_stays_unless_an_alternative_is_clearly_better():
    first = _diag(30.0, 86.3)
    near = [(_cand(3, [0]), _diag(14.0, 86.3 + 0.9 * MIN_FIT_GAIN))]
    kept, why = rebase.best_final(first, near)
    assert kept is first and "kept" in why
    assert rebase.best_final(first, []) == (first, None)


def test_among_close_finals_the_fewest_delays_then_states_win():
    first = _diag(30.0, 86.3)
    delayed = (_cand(3, [2]), _diag(29.4, 97.6))
    plain = (_cand(3, [0]), _diag(14.2, 97.6 - 0.5 * MIN_FIT_GAIN))
    bigger = (_cand(4, [0]), _diag(15.0, 97.6 - 0.2 * MIN_FIT_GAIN))
    kept, why = rebase.best_final(first, [delayed, bigger, plain])
    assert kept is plain[1]
    assert "3 state(s), input delays [0]" in why and "--order 3" in why
    # an alternative further than MIN_FIT_GAIN below the best is not a candidate
    far = (_cand(2, [0]), _diag(10.0, 97.6 - 2 * MIN_FIT_GAIN))
    assert rebase.best_final(first, [delayed, far])[0] is delayed[1]


def test_no_alternatives_without_a_curve_or_with_an_order_asked():
    bf = NS(order=NS(asked="auto", family="lti", states=1))
    assert rebase.alternatives(bf, _diag(30.0, 40.0, added=("delay",))) == []
    bf_asked = NS(order=NS(asked=2, family="lti", states=2))
    assert rebase.alternatives(bf_asked, _diag(30.0, 90.0)) == []
    bf_mech = NS(order=NS(asked="auto", family="mechanical", states=2))
    assert rebase.alternatives(bf_mech, _diag(30.0, 90.0)) == []


def test_alternatives_refit_the_added_effects_and_only_the_kept_one_gets_the_catalogue(
        monkeypatch):
    """rigd.diagnose.diagnosis._rebased: each alternative base is diagnosed over the effects
    the first diagnosis added (``only``); the whole catalogue runs once, on the candidate
    kept, and its final fit must still beat the first diagnosis."""
    from rigd.diagnose import diagnosis

    first = _diag(30.0, 86.3, added=("static_nonlinearity",))
    a3, a4 = _cand(3, [0]), _cand(4, [0])
    for c in (a3, a4):
        c.theta = None
    monkeypatch.setattr(rebase, "alternatives", lambda bf, sd: [a3, a4])
    monkeypatch.setattr(diagnosis, "_carried_worth", lambda *a, **k: None)
    finals = {(3, True): 97.6, (4, True): 97.7, (3, False): 97.9}
    calls = []

    def run(structure, theta, ys, worth=None, only=None):
        st = 3 if structure is a3.structure else 4
        calls.append((st, only))
        return _diag(14.0, finals[(st, only is not None)])

    notes: list[str] = []
    kept, info = diagnosis._rebased(NS(), first, None, run, "generic", notes)
    assert calls[:2] == [(3, ["static_nonlinearity"]), (4, ["static_nonlinearity"])]
    assert calls[2:] == [(3, None)]          # the catalogue on the fewest states only
    assert kept.final.fit_percent == 97.9 and info["states"] == 3
    # the whole catalogue no better than the first: the first diagnosis stays
    finals[(3, False)] = 86.3
    calls.clear()
    kept, info = diagnosis._rebased(NS(), first, None, run, "generic", notes)
    assert kept is first and info is None and len(calls) == 3
