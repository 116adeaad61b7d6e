"""Pieces (trackers/association.py): a camera's second track on an obstacle that a two-camera track
covers joins it when its members triangulate at that track's depth. Expected values are worked by
hand on a rig whose second camera sits 0.3 m beside the first (R = I): the rays of a point on the
first camera's optical axis meet there, and the depth's sensitivity to each ray's angle follows
from the triangle's closed form."""

from __future__ import annotations

import numpy as np
import pytest

from trackers.association import (
    informative,
    piece_agrees,
    point_bearings,
    ray_depths,
    surface_agreement,
)

B = 0.3  # m: camera b's centre at (B, 0, 0) in C_a, so p_Cb = p_Ca + t with t = (-B, 0, 0)
R = np.eye(3)
T = np.array([-B, 0.0, 0.0])


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_ray_depths_meet_on_the_axis_with_the_triangles_sensitivity():
    """A point at z = 4 m on a's axis: b sees it along (-B, 0, 4). Ray b's angle theta to the
    axis (tan theta = B / z) gives z = B / tan(theta + delta): dz/ddelta = -B (1 + tan^2) / tan^2;
    ray a tilted by delta towards +x meets ray b (x = B - z B / 4) at s = B / (sin delta +
    (B / 4) cos delta): ds/ddelta = -B / (B / 4)^2. With both rays of sigma 1 mrad, the depth's
    sigma is 1e-3 hypot of the two."""
    z = 4.0
    b_a = np.array([[0.0, 0.0, 1.0]])
    b_b = unit([[-B, 0.0, z]])
    d, s, ok = ray_depths(b_a, b_b, R, T, 1e-3)
    tan = B / z
    expected = 1e-3 * np.hypot(B * (1 + tan**2) / tan**2, B / tan**2)
    assert ok[0]
    assert d[0] == pytest.approx(z, abs=1e-12)
    assert s[0] == pytest.approx(expected, rel=1e-9)
    # the same by finite differences of the closed forms above (independent of ray_depths)
    h = 1e-7
    dz_b = (B / np.tan(np.arctan(tan) + h) - B / np.tan(np.arctan(tan) - h)) / (2 * h)
    ds_a = (B / (np.sin(h) + tan * np.cos(h)) - B / (np.sin(-h) + tan * np.cos(-h))) / (2 * h)
    assert s[0] == pytest.approx(1e-3 * np.hypot(dz_b, ds_a), rel=1e-5)


def test_ray_depths_refuse_rays_that_do_not_meet_ahead():
    b_a = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    b_b = np.array(
        [
            [0.0, 0.0, 1.0],  # parallel: the point at infinity
            unit([B, 0.0, 4.0]),  # diverging: they would meet behind camera a
            unit([-B, 0.0, -4.0]),  # the point behind both
        ]
    )
    d, s, ok = ray_depths(b_a, b_b, R, T, 1e-3)
    assert not ok.any()
    assert np.isinf(d).all() and np.isinf(s).all()


def test_point_bearings_is_where_camera_b_sees_a_point_at_that_depth():
    """At depth 4 m along a's axis camera b (0.3 m to the +x side) sees (-0.3, 0, 4); and depths
    put along rays of a rotated rig come back from ray_depths."""
    got = point_bearings(np.array([[0.0, 0.0, 1.0]]), 4.0, R, T)
    np.testing.assert_allclose(got[0], unit([-B, 0.0, 4.0]), atol=1e-15)
    c, s_ = np.cos(0.2), np.sin(0.2)
    R_y = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    rng = np.random.default_rng(3)
    b_a = unit(rng.normal([0, 0, 1], 0.3, (20, 3)))
    depth = rng.uniform(1.0, 12.0, 20)
    d, _, ok = ray_depths(b_a, point_bearings(b_a, depth, R_y, T), R_y, T, 1e-3)
    assert ok.all()
    np.testing.assert_allclose(d, depth, rtol=1e-9)


def test_informative_means_the_inverse_depth_is_three_sigmas_from_zero():
    got = informative(np.array([3.0, 3.0, np.inf, 3.0]), np.array([0.99, 1.01, 0.1, np.inf]))
    assert got.tolist() == [True, False, False, False]


def test_surface_agreement_uses_the_neighbours_median_and_the_joint_sigma():
    """Six points at 4 m (sigma 0.1 m) near the new one, six at 8 m far from it in the image: the
    surface next to it is 4 m with variance (pi / 2) 0.01 / 6; a new point of sigma 0.05 m agrees
    within 3 sqrt(0.05^2 + that) = 0.2146 m."""
    uv_ref = np.array([[100.0 + 3 * i, 100.0] for i in range(6)] + [[400.0 + 3 * i, 100.0] for i in range(6)])
    d_ref = np.array([4.0] * 6 + [8.0] * 6)
    s_ref = np.full(12, 0.1)
    lim = 3 * np.sqrt(0.05**2 + (np.pi / 2) * 0.01 / 6)
    assert lim == pytest.approx(0.2146, abs=1e-4)
    uv_new = np.array([[110.0, 105.0]] * 3)
    d_new = np.array([4.0 + 0.99 * lim, 4.0 - 1.01 * lim, np.inf])
    got = surface_agreement(uv_new, d_new, np.array([0.05, 0.05, 0.05]), uv_ref, d_ref, s_ref)
    assert got.tolist() == [True, False, False]
    assert not surface_agreement(uv_new, d_new, np.full(3, 0.05), uv_ref[:0], d_ref[:0], s_ref[:0]).any()


def _triangulated(depths, xs_px, sigma_rad=2e-3):
    """Points at ``depths`` along rays of camera a fanned out across the image (pixel x ->
    angle sigma_rad x): their pixels, and depth and sigma as ray_depths triangulates them from the
    exact b rays."""
    ang = np.asarray(xs_px, float) * sigma_rad
    b_a = np.column_stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)])
    d, s, ok = ray_depths(b_a, point_bearings(b_a, np.asarray(depths, float), R, T), R, T, sigma_rad)
    assert ok.all()
    uv = np.column_stack([640 + np.asarray(xs_px, float), np.full(len(ang), 360.0)])
    return uv, d, s


def test_a_piece_beside_the_track_at_its_depth_joins_it():
    """One obstacle 3 m away split into two tracks side by side (2 mrad per px, 1 px sigma): the
    piece's depths equal the track's."""
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([3.0] * 5, np.arange(5, 30, 5))
    assert piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_an_obstacle_beside_the_track_at_another_depth_does_not_join_it():
    """Two obstacles side by side in the image, 3 m and 4 m away: near the axis the depth sigma is
    about sqrt(2) d^2 sigma / B (0.151 m at 4 m with a 0.3 m baseline and 2 mrad rays), so the
    1 m step is over 6 joint sigmas: no join."""
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([4.0] * 5, np.arange(5, 30, 5))
    np.testing.assert_allclose(s_p, np.sqrt(2) * 16 * 2e-3 / B, rtol=0.02)
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_far_pieces_whose_depth_says_nothing_do_not_join():
    """At 40 m the depth sigma (~10 m) holds any depth within 3 sigmas, so it is no evidence."""
    uv_t, d_t, s_t = _triangulated([40.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([40.0] * 5, np.arange(5, 30, 5))
    assert not informative(d_p, s_p).any()
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_a_piece_needs_three_agreeing_members_and_a_majority():
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    # two at the track's depth, two at 4 m: two agree (fewer than 3)
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 4.0, 4.0], np.arange(5, 25, 5))
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)
    # three agree, three do not: no majority
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 3.0, 4.0, 4.0, 4.0], np.arange(5, 35, 5))
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)
    # three agree, two do not
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 3.0, 4.0, 4.0], np.arange(5, 30, 5))
    assert piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)

