"""Tests of estimators.geometry: closed forms by hand, degenerate cases, input errors.

Expected values are worked out by hand here (3-4-5 triangles, equilateral and isosceles triangles,
the law of sines with math.sin), never taken from the code under test. Property tests (hypothesis)
are in test_geometry_properties.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators import geometry as g
from estimators.errors import InputError
from tests.estimators.fusion_helpers import noisy_units

SQ3 = math.sqrt(3.0)


# --------------------------------------------------------------------------- triangulate: hand-worked


def test_triangulate_345_triangle():
    # A = 0, B = (3,0,0), P = (3,4,0): |AP| = 5, |BP| = 4, angle between the rays acos(4/5)
    r = g.triangulate([0, 0, 0], [0.6, 0.8, 0], [3, 0, 0], [0, 1, 0])
    assert isinstance(r, g.Triangulation)
    np.testing.assert_allclose(r.p, [3, 4, 0], atol=1e-12)
    assert r.range_m == pytest.approx(4.0, abs=1e-12)  # from c_b by default
    assert r.depth_a_m == pytest.approx(5.0, abs=1e-12)
    assert r.depth_b_m == pytest.approx(4.0, abs=1e-12)
    assert r.parallax_rad == pytest.approx(math.acos(0.8), abs=1e-12)
    assert r.miss_m == pytest.approx(0.0, abs=1e-12)
    assert r.range_sigma_m == 0.0


def test_triangulate_origin_and_unnormalised_bearings():
    r = g.triangulate([0, 0, 0], [3, 4, 0], [3, 0, 0], [0, 7, 0], origin=[0, 0, 0])
    assert r.range_m == pytest.approx(5.0, abs=1e-12)
    r = g.triangulate([0, 0, 0], [0.6, 0.8, 0], [3, 0, 0], [0, 1, 0], origin=[3, 0, 4])
    assert r.range_m == pytest.approx(math.hypot(4, 4), abs=1e-12)  # P - origin = (0, 4, -4)


def test_triangulate_skew_rays_midpoint_and_miss():
    # ray a: the x axis at z = 0; ray b: from (5, -5, 2) along +y (skew, 2 m apart in z).
    # closest points (5, 0, 0) and (5, 0, 2): midpoint (5, 0, 1), miss 2, depths 5 and 5.
    r = g.triangulate([0, 0, 0], [1, 0, 0], [5, -5, 2], [0, 1, 0])
    np.testing.assert_allclose(r.p, [5, 0, 1], atol=1e-12)
    assert r.miss_m == pytest.approx(2.0)
    assert r.depth_a_m == pytest.approx(5.0)
    assert r.depth_b_m == pytest.approx(5.0)
    assert r.range_m == pytest.approx(math.sqrt(25 + 1))  # from (5,-5,2) to (5,0,1)
    assert r.parallax_rad == pytest.approx(math.pi / 2)


def test_triangulate_beyond_90_degrees_off_an_axis():
    # camera looks along +z, the obstacle is behind the image plane (100 deg off axis): the bearings
    # are plain 3-vectors, so this is an ordinary triangulation. P = (0, 4, -1): from (0,0,0) and (0,2,0)
    p = np.array([0.0, 4.0, -1.0])
    c_a, c_b = np.zeros(3), np.array([0.0, 2.0, 0.0])
    r = g.triangulate(c_a, p - c_a, c_b, p - c_b)
    np.testing.assert_allclose(r.p, p, atol=1e-12)
    assert r.range_m == pytest.approx(math.hypot(2, 1))


@pytest.mark.parametrize(
    "th1_deg, th2_deg, d, range_b, range_a, z",
    [
        # equilateral: all sides d, height d sqrt(3)/2
        (60, 60, 2.0, 2.0, 2.0, SQ3),
        # right angle at A: AC = d tan(th2) = 2, BC = d / cos(45) = 2 sqrt(2), height 2
        (90, 45, 2.0, 2 * math.sqrt(2), 2.0, 2.0),
        # obtuse at A (thesis eq. 3.9 case): 120/30/30 isosceles, AC = d = 1, BC = sqrt(3), height sqrt(3)/2
        (120, 30, 1.0, SQ3, 1.0, SQ3 / 2),
        # obtuse at B (eq. 3.10 case): mirror image
        (30, 120, 1.0, 1.0, SQ3, SQ3 / 2),
    ],
)
def test_planar_triangulate_hand_triangles(th1_deg, th2_deg, d, range_b, range_a, z):
    t1, t2 = math.radians(th1_deg), math.radians(th2_deg)
    rb = g.planar_triangulate(d, t1, t2)
    ra = g.planar_triangulate(d, t1, t2, origin="a")
    assert rb.range_m == pytest.approx(range_b, rel=1e-12)
    assert ra.range_m == pytest.approx(range_a, rel=1e-12)
    assert rb.p[1] == pytest.approx(z, rel=1e-12)  # eq. 3.1's Z: distance from the baseline
    # eq. 3.2's CF, from the midpoint (d/2, 0): C = A + AC (cos th1, sin th1)
    cx, cy = range_a * math.cos(t1), range_a * math.sin(t1)
    cf = g.planar_triangulate(d, t1, t2, origin="mid")
    assert cf.range_m == pytest.approx(math.hypot(cx - d / 2, cy), rel=1e-12)


def test_planar_triangulate_law_of_sines_table_4_2():
    # Table 4.2's inputs: d = 165.1 cm, th1 = 72.5, th2 = 80 deg -> |BC| = d sin th1 / sin(th1 + th2)
    d = 1.651
    expect = d * math.sin(math.radians(72.5)) / math.sin(math.radians(152.5))
    r = g.planar_triangulate(d, math.radians(72.5), math.radians(80))
    assert r.range_m == pytest.approx(expect, rel=1e-12)
    assert 100 * expect == pytest.approx(341.005, abs=1e-3)


# --------------------------------------------------------------------------- degenerate -> Unobservable


@pytest.mark.parametrize(
    "args, reason",
    [
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0]), "parallel rays"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1e-6, 0]), "parallel rays"),  # below min parallax
        (([0, 0, 0], [1, 0, 0], [5, 0, 0], [-1, 0, 0]), "parallel rays"),  # anti-parallel, collinear
        (([1, 2, 3], [1, 0, 0], [1, 2, 3], [0, 1, 0]), "zero baseline"),
        # lines meet at (2, 2, 0): depth -2 sqrt(2) on ray a, +2 on ray b
        (([0, 0, 0], [-1, -1, 0], [2, 0, 0], [0, 1, 0]), "point behind camera a"),
        # lines meet at (2, -2, 0): depth +2 sqrt(2) on ray a, -2 on ray b
        (([0, 0, 0], [1, -1, 0], [2, 0, 0], [0, 1, 0]), "point behind camera b"),
        (([0, 0, 0], [-1, 1, 0], [2, 0, 0], [1, 1, 0]), "point behind both cameras"),
    ],
)
def test_triangulate_degenerate(args, reason):
    r = g.triangulate(*args)
    assert isinstance(r, g.Unobservable)
    assert reason in r.reason
    assert not r  # Unobservable is falsy


@pytest.mark.parametrize(
    "th1, th2, reason",
    [(100, 80, "angles sum to >= 180 deg"), (120, 75, "angles sum to >= 180 deg"), (0, 45, "interior angle")],
)
def test_planar_degenerate(th1, th2, reason):
    r = g.planar_triangulate(1.0, math.radians(th1), math.radians(th2))
    assert isinstance(r, g.Unobservable) and reason in r.reason
    assert isinstance(g.planar_triangulate(0.0, 1.0, 1.0), g.Unobservable)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"c_a": [0, 0]},
        {"c_a": [0, 0, float("nan")]},
        {"b_a": [0, 0, 0]},
        {"b_b": [float("inf"), 0, 0]},
        {"origin": [1, 2]},
        {"bearing_sigma_rad": -1.0},
        {"bearing_sigma_rad": float("nan")},
        {"c_b": "abc"},
    ],
)
def test_triangulate_malformed_input_raises(kwargs):
    base = dict(c_a=[0, 0, 0], b_a=[0.6, 0.8, 0], c_b=[3, 0, 0], b_b=[0, 1, 0])
    base.update(kwargs)
    extra = {k: base.pop(k) for k in ("origin", "bearing_sigma_rad") if k in base}
    with pytest.raises(InputError):
        g.triangulate(base["c_a"], base["b_a"], base["c_b"], base["b_b"], **extra)


# --------------------------------------------------------------------------- range sigma


@pytest.mark.parametrize(
    "c_a, c_b, p, sigma",
    [
        ([0, 0, 0], [0, 0.3, 0], [5.0, 1.0, 0.5], 2e-3),  # stereo-like, 0.3 m baseline, 5 m
        ([0, 0, 0], [1.5, 0, 0], [3.0, 2.5, -0.5], 5e-3),  # mono parallax, 1.5 m of motion
    ],
)
def test_range_sigma_matches_monte_carlo(c_a, c_b, p, sigma):
    c_a, c_b, p = map(np.asarray, (c_a, c_b, p))
    b_a = (p - c_a) / np.linalg.norm(p - c_a)
    b_b = (p - c_b) / np.linalg.norm(p - c_b)
    r0 = g.triangulate(c_a, b_a, c_b, b_b, bearing_sigma_rad=sigma)
    rng = np.random.default_rng(7)
    n = 2000
    BA, BB = noisy_units(rng, b_a, sigma, n), noisy_units(rng, b_b, sigma, n)
    batch = g.triangulate_batch(c_a, BA, c_b, BB)  # row-wise equal to triangulate (tested below)
    assert batch.valid.all()
    std = float(np.std(batch.range_m))
    assert r0.range_sigma_m == pytest.approx(std, rel=0.15)
    assert r0.range_sigma_m > 0


# --------------------------------------------------------------------------- moving-obstacle bounds


def test_bounds_zero_displacement_is_the_triangulation():
    # 3-4-5: the only consistent depth on ray b is 4
    b = g.moving_obstacle_bounds([0, 0, 0], [0.6, 0.8, 0], [3, 0, 0], [0, 1, 0], 0.0)
    assert b.range_min_m == pytest.approx(4.0, abs=1e-6)
    assert b.range_max_m == pytest.approx(4.0, abs=1e-6)


def test_bounds_hand_worked_right_angle():
    # ray a: from the origin along +x; ray b: from (3, -4, 0) along +y, meets ray a at (3,0,0) (depth 4).
    # dist(c_b + r y, ray a) = |r - 4| (foot at x = 3 >= 0), so with D = 1: depths [3, 5].
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [3, -4, 0], [0, 1, 0], 1.0)
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((3.0, 5.0), abs=1e-12)
    assert (b.range_min_m, b.range_max_m) == pytest.approx((3.0, 5.0), abs=1e-12)
    # ranges from another origin (0, 0, 0): |(3, r - 4)| over r in [3, 5]: interior minimum 3 at r = 4,
    # maximum sqrt(9 + 1) at both ends
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [3, -4, 0], [0, 1, 0], 1.0, origin=[0, 0, 0])
    assert b.range_min_m == pytest.approx(3.0, abs=1e-12)
    assert b.range_max_m == pytest.approx(math.sqrt(10), abs=1e-12)


def test_bounds_half_line_uses_distance_to_the_camera_centre():
    # ray a from the origin along +x; ray b from (-3, -4, 0) along +y passes the *line* a at (-3, 0, 0),
    # behind camera a: the distance to the half-line is the distance to c_a = sqrt(9 + (r - 4)^2).
    # D = 5: (r - 4)^2 <= 16 -> r in [0, 8].  D = 3: only r = 4.  D = 2.9: empty -> inconsistent.
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [-3, -4, 0], [0, 1, 0], 5.0)
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((0.0, 8.0), abs=1e-12)
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [-3, -4, 0], [0, 1, 0], 3.0)
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((4.0, 4.0), abs=1e-6)
    r = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [-3, -4, 0], [0, 1, 0], 2.9)
    assert isinstance(r, g.Unobservable) and "inconsistent with max speed" in r.reason


def test_bounds_default_speed_is_the_drones():
    # no max displacement given: the obstacle moves at most as far as the drone, the baseline
    # |(-3, -4, 0)| = 5; as worked above, D = 5 gives depths [0, 8]
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [-3, -4, 0], [0, 1, 0])
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((0.0, 8.0), abs=1e-12)
    # planar: d = 1, angles 90/45 deg: the rays meet at (0, 1) (depth sqrt 2 from B = (1, 0));
    # D = d = 1 allows every point of ray b within 1 of ray a (the +y axis): x = 1 - r/sqrt2 >= 0
    # up to r = 2 sqrt 2 (x = -1 is distance 1 from the axis)
    b = g.planar_moving_obstacle_bounds(1.0, math.pi / 2, math.pi / 4)
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((0.0, 2 * math.sqrt(2)), abs=1e-12)


def test_bounds_unbounded_for_parallel_rays_and_infinite_speed():
    # same direction, 1 m apart: any depth is within D = 2 of ray a -> [0, None)
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], 2.0)
    assert b.range_min_m == pytest.approx(0.0) and b.range_max_m is None and b.depth_max_m is None
    b = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0], math.inf)
    assert b.range_min_m == 0.0 and b.range_max_m is None
    # same direction, 1 m apart, D = 0.5: inconsistent
    r = g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], 0.5)
    assert isinstance(r, g.Unobservable)


def test_bounds_malformed_input_raises():
    with pytest.raises(InputError):
        g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [3, -4, 0], [0, 1, 0], -1.0)
    with pytest.raises(InputError):
        g.moving_obstacle_bounds([0, 0, 0], [1, 0, 0], [3, -4, 0], [0, 1, 0], float("nan"))
    with pytest.raises(InputError):
        g.moving_obstacle_bounds([0, 0, 0], [0, 0, 0], [3, -4, 0], [0, 1, 0], 1.0)


# --------------------------------------------------------------------------- velocity


def test_velocity_345():
    v = g.velocity_from_fixes([1, 1, 1], 10.0, [4, 5, 1], 12.0, sigma_1=0.3, sigma_2=0.4)
    np.testing.assert_allclose(v.v, [1.5, 2.0, 0.0])
    assert v.speed_mps == pytest.approx(2.5)
    assert v.heading_rad == pytest.approx(math.atan2(4, 3))
    assert v.speed_sigma_mps == pytest.approx(0.5 / 2.0)  # sqrt(0.09 + 0.16) / dt
    assert g.velocity_from_fixes([0, 0, 0], 0, [0, -1, 0], 1).heading_rad == pytest.approx(-math.pi / 2)
    assert g.velocity_from_fixes([0, 0, 0], 0, [0, -1, 0], 1).speed_sigma_mps is None


def test_velocity_covariance_along_the_motion():
    S = np.diag([0.04, 1.0, 1.0])  # only the x variance matters for motion along x
    v = g.velocity_from_fixes([0, 0, 0], 0.0, [2, 0, 0], 0.5, sigma_1=S)
    assert v.speed_sigma_mps == pytest.approx(0.2 / 0.5)


def test_velocity_degenerate_and_malformed():
    r = g.velocity_from_fixes([0, 0, 0], 1.0, [1, 0, 0], 1.0)
    assert isinstance(r, g.Unobservable) and "zero time interval" in r.reason
    with pytest.raises(InputError):
        g.velocity_from_fixes([0, 0, 0], 2.0, [1, 0, 0], 1.0)
    with pytest.raises(InputError):
        g.velocity_from_fixes([0, 0, 0], float("nan"), [1, 0, 0], 1.0)
    with pytest.raises(InputError):
        g.velocity_from_fixes([0, 0], 0.0, [1, 0, 0], 1.0)
    with pytest.raises(InputError):
        g.velocity_from_fixes([0, 0, 0], 0.0, [1, 0, 0], 1.0, sigma_1=np.ones((2, 2)))


# --------------------------------------------------------------------------- batch == scalar


def test_triangulate_batch_equals_scalar_rowwise():
    rng = np.random.default_rng(3)
    n = 300
    c_a = rng.uniform(-5, 5, (n, 3))
    c_b = rng.uniform(-5, 5, (n, 3))
    p = rng.uniform(-10, 10, (n, 3))
    b_a, b_b = p - c_a, p - c_b
    b_a[::5] = -b_a[::5]  # behind camera a
    b_b[1::7] = b_a[1::7]  # parallel
    c_b[2::11] = c_a[2::11]  # zero baseline
    b_b[3::13] = -b_b[3::13]  # behind camera b
    batch = g.triangulate_batch(c_a, b_a, c_b, b_b, origin=[0.5, -1.0, 2.0], bearing_sigma_rad=1e-3)
    assert len(batch) == n and 0 < batch.valid.sum() < n
    assert np.all(np.isfinite(batch.p)) and np.all(np.isfinite(batch.range_sigma_m))
    for i in range(n):
        ref = g.triangulate(c_a[i], b_a[i], c_b[i], b_b[i], origin=[0.5, -1.0, 2.0], bearing_sigma_rad=1e-3)
        got = batch.row(i)
        assert type(got) is type(ref)
        if isinstance(ref, g.Unobservable):
            assert got.reason == ref.reason and not batch.valid[i]
            assert np.all(batch.p[i] == 0) and batch.range_m[i] == 0
        else:
            np.testing.assert_allclose(got.p, ref.p, rtol=1e-12, atol=1e-12)
            for f in ("range_m", "depth_a_m", "depth_b_m", "parallax_rad", "miss_m"):
                assert getattr(got, f) == pytest.approx(getattr(ref, f), rel=1e-12, abs=1e-12)
            assert got.range_sigma_m == pytest.approx(ref.range_sigma_m, rel=1e-6)
    reasons = {r for r in batch.reason if r}
    assert {"zero baseline", "parallel rays", "point behind camera a"} <= reasons


def test_triangulate_batch_broadcast_and_errors():
    # one shared camera pair, two points: 3-4-5 and its mirror in z
    b = g.triangulate_batch([0, 0, 0], [[0.6, 0.8, 0], [0.6, 0, 0.8]], [3, 0, 0], [[0, 1, 0], [0, 0, 1]])
    np.testing.assert_allclose(b.range_m, [4.0, 4.0])
    np.testing.assert_allclose(b.p, [[3, 4, 0], [3, 0, 4]], atol=1e-12)
    with pytest.raises(InputError):
        g.triangulate_batch(np.zeros((2, 3)), np.ones((3, 3)), [1, 0, 0], [0, 1, 0])
    with pytest.raises(InputError):
        g.triangulate_batch(np.zeros((2, 3)), [[1, 0, 0], [0, 0, 0]], [1, 0, 0], [0, 1, 0])
    with pytest.raises(InputError):
        g.triangulate_batch([[0, 0, float("nan")]], [1, 0, 0], [1, 0, 0], [0, 1, 0])


def test_planar_malformed_input_raises():
    with pytest.raises(InputError):
        g.planar_triangulate(1.0, float("nan"), 1.0)
    with pytest.raises(InputError):
        g.planar_triangulate(-1.0, 1.0, 1.0)
    with pytest.raises(InputError):
        g.planar_moving_obstacle_bounds(-1.0, 1.0, 1.0, 0.5)
    with pytest.raises(InputError):
        g.planar_moving_obstacle_bounds(1.0, float("nan"), 1.0, 0.5)
    assert isinstance(g.planar_moving_obstacle_bounds(0.0, 1.0, 1.0, 0.5), g.Unobservable)


def test_moving_obstacle_bounds_unchecked_matches_checked_and_takes_tuples():
    # hand case: rays from (0,0,0) along (0.6, 0.8, 0) and from (1,0,0) along (0,1,0), D = 0.5.
    # Ray b: (1, r, 0); its distance to line a is |0.8 - 0.6 r| (2-D cross product); <= 0.5 for
    # r in [0.5, 2.1667]; the foot on a is s = 0.6 + 0.8 r >= 0 there. Ranges from c_b: r itself.
    res = g.moving_obstacle_bounds_unchecked(
        (0.0, 0.0, 0.0), (0.6, 0.8, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.5, (1.0, 0.0, 0.0)
    )
    assert res.depth_min_m == pytest.approx(0.5)
    assert res.depth_max_m == pytest.approx(1.3 / 0.6)
    assert res.range_min_m == pytest.approx(0.5)
    assert res.range_max_m == pytest.approx(1.3 / 0.6)
    rng = np.random.default_rng(2)
    for _ in range(50):
        c_a, c_b, o = rng.normal(size=(3, 3))
        b_a, b_b = (x / np.linalg.norm(x) for x in rng.normal(size=(2, 3)))
        D = float(rng.uniform(0.0, 3.0))
        a = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, D, origin=o)
        b = g.moving_obstacle_bounds_unchecked(
            tuple(c_a), tuple(b_a), tuple(c_b), tuple(b_b), D, tuple(o)
        )
        assert type(a) is type(b)
        if isinstance(a, g.RangeBounds):
            assert b.range_min_m == pytest.approx(a.range_min_m, rel=1e-9, abs=1e-9)
            assert (a.range_max_m is None) == (b.range_max_m is None)


def test_moving_obstacle_bounds_batch_matches_the_scalar_closed_form():
    # random rays (also parallel, coincident-centre and infinite-D rows): each row equals the
    # scalar function, whose closed form is checked by hand above
    rng = np.random.default_rng(4)
    n = 400
    c_a, c_b, o = rng.normal(size=(3, n, 3))
    b_a, b_b = (x / np.linalg.norm(x, axis=1, keepdims=True) for x in rng.normal(size=(2, n, 3)))
    b_b[:20] = b_a[:20]  # parallel
    c_b[20:30] = c_a[20:30]  # zero baseline
    D = rng.uniform(0.0, 3.0, n)
    D[30:40] = np.inf
    D[40:50] = 0.0
    r_min, r_max, d_min, d_max, valid = g.moving_obstacle_bounds_batch(c_a, b_a, c_b, b_b, D, o)
    for i in range(n):
        s = g.moving_obstacle_bounds_unchecked(c_a[i], b_a[i], c_b[i], b_b[i], float(D[i]), o[i])
        assert valid[i] == isinstance(s, g.RangeBounds), i
        if valid[i]:
            assert r_min[i] == pytest.approx(s.range_min_m, rel=1e-9, abs=1e-9)
            assert d_min[i] == pytest.approx(s.depth_min_m, rel=1e-9, abs=1e-9)
            if s.range_max_m is None:
                assert math.isinf(r_max[i]) and math.isinf(d_max[i])
            else:
                assert r_max[i] == pytest.approx(s.range_max_m, rel=1e-9, abs=1e-9)
                assert d_max[i] == pytest.approx(s.depth_max_m, rel=1e-9, abs=1e-9)
