"""Balanced truncation's Hankel singular values (rigd.design.reduce)."""

import warnings

import control
import numpy as np

from rigd.design.reduce import hankel_singular_values, reduce_controller


def test_a_non_minimal_controller_gives_all_its_values_and_no_library_warning():
    """A stable K with a mode twice over (one state too many): SLICOT's remark that it
    lowered its own truncation order to the minimal one is not passed on; the values are
    all there, the one of the redundant state ≈ 0 and the others those of the minimal K."""
    K = control.ss(np.diag([-1.0, -1.0, -2.0]), [[1.0], [1.0], [1.0]], [[1.0, 1.0, 1.0]], 0.0)
    K_min = control.ss(np.diag([-1.0, -2.0]), [[1.0], [1.0]], [[2.0, 1.0]], 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hsv = hankel_singular_values(K)
        hsv_min = hankel_singular_values(K_min)
    assert hsv.shape == (3,)
    assert hsv[-1] < 1e-12 * hsv[0]
    assert np.allclose(hsv[:2], hsv_min, rtol=1e-9)


def test_truncation_to_the_minimal_order_keeps_the_response():
    K = control.ss(np.diag([-1.0, -1.0, -2.0]), [[1.0], [1.0], [1.0]], [[1.0, 1.0, 1.0]], 0.0)
    Kr = reduce_controller(K, 2)
    w = np.logspace(-2, 2, 30)
    assert Kr.nstates == 2
    assert np.allclose(np.abs(Kr(1j * w)).ravel(), np.abs(K(1j * w)).ravel(), rtol=1e-6)


def test_an_unstable_controller_has_no_hankel_values():
    assert hankel_singular_values(control.ss([[0.5]], [[1.0]], [[1.0]], 0.0)).size == 0
