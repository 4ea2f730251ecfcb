"""One pipeline: what ``rigd diagnose`` names and fits is what ``rigd identify --add NAME``
refits. On records the project generates from equations it does not model (a Duffing
oscillator, a Wiener and a Hammerstein process, a structure under a shaker with a clearance
in one mode's load path, each of another seed and size than the diagnosis tests use), the
first effect the forward selection adds is refitted by
``identify --add`` with that effect and the defaults of both commands
(:func:`rigd.diagnose.added.refit_as_diagnosed`): the held-out fit is the diagnosis's to 0.05
point."""

from __future__ import annotations

import benchmarks as B  # tests/diagnose/benchmarks.py
import pytest

from rigd import api
from rigd.diagnose.diagnosis import diagnose_record
from tests.gen import joint, nonlinear

RECORDS = {
    "duffing": lambda: B.duffing(seed=3, n=2400, strength=0.35),
    "wiener": lambda: nonlinear.wiener(n=3000, seed=1).record(),
    "hammerstein": lambda: nonlinear.hammerstein(n=3000, seed=2).record(),
    "clearance": lambda: joint.joint_structure(level=3.0, joint="clearance",
                                               modes=joint.FIVE_MODES[:3], n=2048, periods=2,
                                               n_outputs=1, seed=2).record(),
}


# make test runs the Wiener and the Hammerstein process (the curve's sites); the Duffing
# oscillator (cubic stiffness, which the README's Silverbox commands refit with identify --add
# in make test) and the clearance joint run in make test-long (CI)
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.long)
                                  if n in ("duffing", "clearance") else n
                                  for n in sorted(RECORDS)])
def test_identify_add_refits_what_diagnose_fitted(name):
    rec = RECORDS[name]()
    part = diagnose_record(rec).parts[0]
    assert len(part.steps) >= 2, [(f.effect, f.significant) for f in part.findings[:3]]
    step = part.steps[1]
    assert step.fit_percent > part.steps[0].fit_percent + 1.0   # a real gain, not noise
    model = api.identify(rec, add=[step.added], yardstick=False).model   # identify --add
    sub = model.submodels[part.submodel]
    assert list(sub.structure.effects) == [step.added]
    assert sub.fit_percent["validation_mean"] == pytest.approx(step.fit_percent, abs=0.05)
