"""Degenerate settings are an answer, not an exception: a zero velocity prior and no process noise
leave a stereo track's velocity covariance singular, and the moving test of its filter
(``ObstacleFusion._filter_moving``, abafde5) must still decide (before: numpy LinAlgError)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _inv_small, _Sighting, _Track, _View
from estimators.rig import stereo_forward_rig


def test_filter_moving_with_a_singular_velocity_covariance_decides_without_raising():
    model = Equidistant(fx=200.0, fy=200.0, cx=319.5, cy=179.5, width=640, height=360)
    s = FusionSettings(velocity_prior_sigma_mps=0.0, max_accel_mps2=0.0)
    fus = ObstacleFusion(stereo_forward_rig(model, 0.30), ConstantVelocity(3.0), s)
    tr = _Track(1, "orb")
    tr.kf = fus._new_kf(np.array([0.0, 0.0, 3.0]), np.eye(3) * 0.01, 0.0)  # P_vv = 0
    tr.moving, tr.t_kf = True, 0.0
    assert fus._filter_moving(tr, 0.1) is False  # v = 0 with no spread: zero is not rejected
    # a velocity measured on one axis only (the others still singular): 1 m/s at sigma 0.1 m/s
    # along x rejects zero (chi 100 > chi2_3 gate), at sigma 10 m/s it does not (chi 0.01)
    for sigma, moving in ((0.1, True), (10.0, False)):
        tr.kf.x = np.array([0.0, 0.0, 3.0, 1.0, 0.0, 0.0])
        tr.kf.P = np.zeros((6, 6))
        tr.kf.P[3, 3] = sigma**2
        assert fus._filter_moving(tr, 0.1) is moving


def test_update_with_a_singular_innovation_covariance_is_rejected_not_raised():
    """S = H P H^T + R exactly singular (a zero-variance position and a zero bearing sigma): the
    cofactor inverse has no determinant to divide by. The bearing is rejected like a gated one and
    the filter is left as it was (before: ZeroDivisionError from ``_inv_small``)."""
    model = Equidistant(fx=200.0, fy=200.0, cx=319.5, cy=179.5, width=640, height=360)
    fus = ObstacleFusion(stereo_forward_rig(model, 0.30), ConstantVelocity(3.0), FusionSettings())
    tr = _Track(1, "orb")
    tr.kf = fus._new_kf(np.array([0.0, 0.0, 3.0]), np.zeros((3, 3)), 0.0)  # P = 0
    x0, P0 = tr.kf.x.copy(), tr.kf.P.copy()
    b = np.array([0.01, 0.0, 1.0]) / np.hypot(0.01, 1.0)  # 0.57 deg off the state's ray
    assert fus._bearing_update(tr, _View("cam0", np.zeros(3), b, 0.0)) is False
    assert (tr.gated, tr.gated_run) == (1, 1)
    np.testing.assert_array_equal(tr.kf.x, x0)
    np.testing.assert_array_equal(tr.kf.P, P0)
    # the same bearing with a non-zero sigma is fused (S = sigma^2 I is invertible; NIS 0.25)
    assert fus._bearing_update(tr, _View("cam0", np.zeros(3), b, 0.02)) is True


@pytest.mark.parametrize("k", [1, 2, 3])
def test_inv_small_of_a_singular_matrix_is_none_and_of_a_regular_one_the_inverse(k):
    assert _inv_small(np.zeros((k, k))) is None
    S = np.diag(np.arange(1.0, k + 1.0))
    if k > 1:
        S[0, -1] = S[-1, 0] = 0.5
        assert _inv_small(np.ones((k, k))) is None  # a singular non-zero one: equal rows
    np.testing.assert_allclose(_inv_small(S) @ S, np.eye(k), atol=1e-15)


def test_mono_init_pair_with_non_finite_camera_centres_is_a_reason_not_an_error():
    """Every baseline NaN (camera centres not finite): no earlier sighting is the longest baseline,
    and the initialisation answers with a reason (before: AttributeError on None)."""
    model = Equidistant(fx=200.0, fy=200.0, cx=319.5, cy=179.5, width=640, height=360)
    fus = ObstacleFusion(stereo_forward_rig(model, 0.30), ConstantVelocity(3.0), FusionSettings())
    nan = np.full(3, np.nan)
    view = _View("cam0", nan, np.array([0.0, 0.0, 1.0]), 1e-3)
    past = _Sighting(0.0, 0, nan, (view,))
    now = _Sighting(0.1, 1, nan, (view,))
    tr = _Track(1, "orb")
    tr.history.append(past)
    assert fus._mono_init_pair(tr, now) == "no earlier sighting with a finite baseline"
