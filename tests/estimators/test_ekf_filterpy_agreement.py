"""The fusion's own EKF predict / update (``estimators.fusion._ekf_predict`` / ``_ekf_update``:
filterpy's operations without its bookkeeping copies, S inverted by cofactors instead of scipy's
LAPACK inv) against filterpy's ``ExtendedKalmanFilter.predict`` / ``update`` themselves, the
independent reference: the state, covariance, innovation covariance, its inverse and the gain must
agree to rounding (1e-12 of each array's largest entry), for the 1-, 2- and 3-dimensional
measurements the fusion makes. (Until the fusion's speed work under the session-9 speed rule they
were bit for bit: filterpy's own inv.)"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter

from estimators.fusion import _H_POS, _H_VEL, _ekf_predict, _ekf_update


def _spd(rng: np.random.Generator, n: int, scale: float) -> np.ndarray:
    a = rng.normal(size=(n, n)) * scale
    return a @ a.T + np.eye(n) * scale * 1e-3


def _filter(rng: np.random.Generator) -> ExtendedKalmanFilter:
    kf = ExtendedKalmanFilter(dim_x=6, dim_z=2)  # as ObstacleFusion builds it
    kf.x = rng.normal(size=6) * 10.0
    kf.P = _spd(rng, 6, 2.0)
    dt = float(rng.uniform(0.005, 0.2))
    kf.F = np.eye(6)
    kf.F[:3, 3:] = np.eye(3) * dt
    kf.Q = _spd(rng, 6, 0.1)
    return kf


@pytest.mark.parametrize("dim_z", [1, 2, 3])
def test_predict_and_update_are_filterpys_to_rounding(dim_z):
    rng = np.random.default_rng(11 + dim_z)
    for _ in range(50):
        ref = _filter(rng)
        ours = copy.deepcopy(ref)
        ref.predict()
        _ekf_predict(ours)
        np.testing.assert_array_equal(ours.x, ref.x)  # (the same products: bit for bit)
        np.testing.assert_array_equal(ours.P, ref.P)
        H = rng.normal(size=(dim_z, 6))
        R = _spd(rng, dim_z, 0.05)
        y = rng.normal(size=dim_z)
        zero = np.zeros(dim_z)
        ref.update(y, HJacobian=lambda _x, H=H: H, Hx=lambda _x, zero=zero: zero, R=R)
        _ekf_update(ours, y, H, R)
        for name in ("x", "P", "y", "S", "SI", "K"):
            a, b = np.asarray(getattr(ours, name)), np.asarray(getattr(ref, name))
            assert a.shape == b.shape, name
            np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * float(np.abs(b).max()), err_msg=name)


@pytest.mark.parametrize("block", ["position", "velocity"])
def test_point_and_velocity_updates_are_filterpys_to_rounding(block):
    """The stereo point and feature-velocity updates pass the shared selection matrices H = [I 0] /
    [0 I] (``_H_POS`` / ``_H_VEL``), for which ``_ekf_update`` takes P's columns and block instead of
    the products with H: filterpy's update with the same H is the reference."""
    H = _H_POS if block == "position" else _H_VEL
    rng = np.random.default_rng(5 if block == "position" else 6)
    for _ in range(50):
        ref = _filter(rng)
        ours = copy.deepcopy(ref)
        R = _spd(rng, 3, 0.05)
        y = rng.normal(size=3)
        zero = np.zeros(3)
        ref.update(y, HJacobian=lambda _x: np.array(H), Hx=lambda _x, zero=zero: zero, R=R)
        assert _ekf_update(ours, y, H, R)
        for name in ("x", "P", "y", "S", "SI", "K"):
            a, b = np.asarray(getattr(ours, name)), np.asarray(getattr(ref, name))
            assert a.shape == b.shape, name
            np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12 * float(np.abs(b).max()), err_msg=name)
