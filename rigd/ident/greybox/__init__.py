"""Grey-box structures of the paper and the mechanical n-DOF model.

* :mod:`rigd.ident.greybox.mechanical` — the mass-normalised p̈ + D ṗ + K p = B u structure
  (Eqs. 4-6) and the generic n-DOF model of records from other rigs;
* :mod:`rigd.ident.greybox.rotor` — the paper's bearing 𝔐_b (Eqs. 5-7) and actuator 𝔐_a
  (Eqs. 8-10) on it;
* :mod:`rigd.ident.greybox.submodels` — ``structure_for`` (the base structure of a
  sub-model) and ``DEFAULT_HOLD``;
* :mod:`rigd.ident.greybox.order` — the mechanical model's order search (parallel modes
  from the residual), :mod:`rigd.ident.greybox.parallel` — those modes.

The general LTI and process families and the black-box references live in
:mod:`rigd.ident.lti`.
"""
