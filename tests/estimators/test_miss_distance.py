"""The distance at closest approach and its sigma (``estimators.fusion._miss_distances``, reported
as ``miss_distance_m`` / ``miss_distance_sigma_m`` beside ``ttc_s``).

Expected values are worked by hand from the geometry (t* = -r.w / |w|^2, the miss |r + t* w|) and
from the covariance written here; the Jacobian is checked against central differences of the
distance itself, and the head-on sigma against samples.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.fusion import _miss_distances


def _one(r, w, P):
    r, w = np.asarray(r, float), np.asarray(w, float)
    t = -(r @ w) / (w @ w)
    d, s = _miss_distances(r[None], w[None], np.array([t]), np.asarray(P, float)[None])
    return float(d[0]), float(s[0])


def _P(pos, vel=(0.0, 0.0, 0.0), cross=None):
    P = np.zeros((6, 6))
    P[:3, :3] = np.diag(pos)
    P[3:, 3:] = np.diag(vel)
    if cross is not None:
        P[:3, 3:] = P[3:, :3] = np.asarray(cross, float)
    return P


def test_head_on_static_obstacle_misses_by_zero_with_the_lateral_position_sigma():
    # obstacle 10 m straight ahead, closing at 5 m/s: t* = 2 s, the miss 0; a static hypothesis
    # (position covariance only): the error of the miss is the position's error across the approach,
    # y and z: sigma^2 = 0.04 + 0.09 (the along-track 0.25 does not move the miss)
    d, s = _one([10.0, 0.0, 0.0], [-5.0, 0.0, 0.0], _P((0.25, 0.04, 0.09)))
    assert d == pytest.approx(0.0, abs=1e-12)
    assert s == pytest.approx(math.sqrt(0.13), rel=1e-12)
    # with a velocity covariance the position at t* = 2 s is the uncertain one: P_pp + 4 P_vv
    # across the approach, (0.04 + 4 * 0.01) + (0.09 + 4 * 0.04)
    d, s = _one([10.0, 0.0, 0.0], [-5.0, 0.0, 0.0], _P((0.25, 0.04, 0.09), (0.01, 0.01, 0.04)))
    assert d == pytest.approx(0.0, abs=1e-12)
    assert s == pytest.approx(math.sqrt(0.08 + 0.25), rel=1e-12)


def test_head_on_along_a_diagonal():
    # head-on along (1, 1, 1) / sqrt(3) (another fallback direction across the approach): with
    # P_pp = diag(a, b, c) the variance across u is tr - u^T P u = 2 (a + b + c) / 3
    r = 6.0 * np.ones(3) / math.sqrt(3.0)
    d, s = _one(r, -2.0 * r, _P((0.01, 0.04, 0.16)))
    assert d == pytest.approx(0.0, abs=1e-9)
    assert s == pytest.approx(math.sqrt(2.0 * 0.21 / 3.0), rel=1e-9)


def test_abeam_obstacle_misses_by_its_lateral_offset():
    # obstacle 6 m ahead and 2 m to the left, closing at 3 m/s along x: t* = 2 s, miss 2 m along y.
    # The miss moves with y and, at t* = 2 s, with 2 v_y: n^T C n = P_yy + 2 * 2 P_y,vy + 4 P_vy,vy
    # = 0.01 + 0.012 + 0.01 = 0.032. Across both (z) the miss changes only to second order,
    # sqrt(2^2 + dz^2) - 2: s_e = P_zz + 4 P_vz,vz = 0.08 adds s_e^2 / (d^2 + s_e) = 0.0064 / 4.08
    cross = np.zeros((3, 3))
    cross[1, 1] = 0.003
    d, s = _one([6.0, 2.0, 0.0], [-3.0, 0.0, 0.0], _P((0.09, 0.01, 0.04), (0.04, 0.0025, 0.01), cross))
    assert d == pytest.approx(2.0, rel=1e-12)
    assert s == pytest.approx(math.sqrt(0.032 + 0.0064 / 4.08), rel=1e-12)
    # the along-track uncertainty (x, v_x) moves neither the miss nor its sigma
    d2, s2 = _one([6.0, 2.0, 0.0], [-3.0, 0.0, 0.0], _P((9.0, 0.01, 0.04), (4.0, 0.0025, 0.01), cross))
    assert (d2, s2) == pytest.approx((d, s), rel=1e-12)


def test_the_sigma_is_the_first_order_propagation_through_the_miss_distance():
    # a random closing case with a small covariance (the second-order term across is ~1e-9 of the
    # variance): sigma^2 = J P J^T with J the central-difference gradient of
    # x = (p, v) -> |r + t*(r, w) w| (t* recomputed: its own variation does not enter, t* being
    # stationary in the distance)
    rng = np.random.default_rng(7)
    r = rng.normal(size=3) * 5.0
    w = -r / 2.0 + rng.normal(size=3) * 2.0
    assert r @ w < 0
    A = rng.normal(size=(6, 6)) * 1e-3
    P = A @ A.T + np.eye(6) * 1e-8

    def miss(x):
        rr, ww = x[:3], x[3:]
        t = -(rr @ ww) / (ww @ ww)
        return float(np.linalg.norm(rr + t * ww))

    x0 = np.concatenate([r, w])
    h = 1e-6
    J = np.array([(miss(x0 + h * e) - miss(x0 - h * e)) / (2 * h) for e in np.eye(6)])
    d, s = _one(r, w, P)
    assert d == pytest.approx(miss(x0), rel=1e-12)
    assert s * s == pytest.approx(float(J @ P @ J), rel=1e-5)


def test_near_head_on_sigma_is_the_rms_error_of_the_distance():
    # near a head-on course the distance is far from linear in the position (|m| is never
    # negative): the sigma is the root mean square of (true distance - reported distance) over
    # positions drawn from P, or at most 31 % more; at d = 0 exactly the mean square of |m|,
    # sqrt(0.09 + 0.09) here. The first order alone (sqrt(P_yy) = 0.3 for a miss along y) is under
    # it where the uncertainty across (z) is the larger
    rng = np.random.default_rng(3)
    w = np.array([-4.0, 0.0, 0.0])
    for sd in ((0.2, 0.3, 0.3), (0.2, 0.1, 0.5)):
        P = _P(np.square(sd))
        x = rng.normal(size=(200_000, 3)) * sd
        for off in (0.0, 0.05, 0.1, 0.3, 0.6, 1.2):
            r = np.array([8.0, off, 0.0])
            d, s = _one(r, w, P)
            true_d = np.hypot(off + x[:, 1], x[:, 2])  # (a point closing along x: its y, z offset)
            rms = float(np.sqrt(np.mean((true_d - d) ** 2)))
            assert d == pytest.approx(off, rel=1e-12)
            assert 0.99 * rms <= s <= 1.32 * rms, (sd, off)
            if sd[2] > 2 * sd[1] and 0 < off <= 0.3:
                assert sd[1] < 0.8 * rms  # (the first order's sigma)
    d0, s0 = _one([8.0, 0.0, 0.0], w, _P((0.04, 0.09, 0.09)))
    assert d0 == 0.0 and s0 == pytest.approx(math.sqrt(0.18), rel=1e-12)


@pytest.mark.parametrize("r, w", [
    ([1e-9, 5.0, 0.0], [-3.0, 0.0, 0.0]),  # t* -> 0: the closest approach is now, 5 m away
    ([10.0, 0.5, 0.0], [-2e-6, 0.0, 0.0]),  # w -> 0: t* = 5e6 s
    ([10.0, 0.0, 0.0], [-2e-6, 0.0, 0.0]),  # w -> 0 head-on
])
def test_degenerate_cases_stay_finite(r, w):
    P = _P((0.04, 0.01, 0.01), (1e-4, 1e-4, 1e-4))
    with np.errstate(all="raise"):
        d, s = _one(r, w, P)
    r, w = np.asarray(r), np.asarray(w)
    t = -(r @ w) / (w @ w)
    assert d == pytest.approx(float(np.linalg.norm(r + t * w)), rel=1e-9, abs=1e-12)
    assert math.isfinite(s) and s > 0
    if t < 1.0:  # now: the position's own 0.1 m across w (y), + across both (z): 0.01^2 / (25 + 0.01)
        assert s == pytest.approx(math.sqrt(0.01 + 1e-4 / 25.01), rel=1e-9)
    else:  # in 5e6 s: the velocity's 0.01 m/s times t* across w, in both directions (the 0.5 m
        # offset is nothing beside 5e4 m: as good as head-on)
        assert s == pytest.approx(math.sqrt(2.0) * 0.01 * t, rel=1e-6)
