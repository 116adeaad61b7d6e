"""estimators.geometry at the edges a fisheye makes normal: bearings behind the direction of flight,
an obstacle passing abeam, tiny parallax (baseline nearly along the bearing), rays near 180 deg
apart, the obstacle on the stereo baseline's axis, and the moving-obstacle bounds when the obstacle
may be faster than, as fast as or slower than the drone.

Expected values are closed forms worked here (the planar law of sines and its derivatives, the
distance of a point of ray b from line a) or brute force / Monte Carlo written here; none comes from
the code under test. The planar configuration is the thesis's: A = (0, 0, 0), B = (d, 0, 0), the
obstacle C at y > 0, th1 the interior angle at A, th2 at B; then
    |BC| = d sin th1 / sin(th1 + th2)                                    (law of sines, eq. 3.8)
    d|BC|/d th1 = d sin th2 / sin^2(th1 + th2),  d|BC|/d th2 = -d sin th1 cos(th1 + th2) / sin^2(th1 + th2)
and a bearing error out of the triangle's plane moves |BC| only to second order, so the first-order
range sigma for isotropic noise sigma on each bearing is
    sigma_r = sigma d sqrt(sin^2 th2 + sin^2 th1 cos^2(th1 + th2)) / sin^2(th1 + th2).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators import geometry as g
from tests.estimators.fusion_helpers import noisy_units

R = math.radians


def _sigma_closed_form(d, t1, t2, sigma):
    S = math.sin(t1 + t2)
    return sigma * d * math.sqrt(math.sin(t2) ** 2 + (math.sin(t1) * math.cos(t1 + t2)) ** 2) / S**2


# --------------------------------------------------------------------------- range and its sigma


@pytest.mark.parametrize(
    "t1, t2",
    [
        # rear hemisphere: C = (-10, 3) seen while flying A = 0 -> B = (1, 0) along +x: th1 = 163.30 deg
        # (107 deg behind the direction of flight at A), th2 = 15.26 deg, parallax 1.44 deg;
        # |BC| = sqrt(11^2 + 3^2) = 11.4018, sigma_r / sigma = 613.3 m/rad
        (math.atan2(3, -10), math.atan2(3, 11)),
        # abeam: C = (0.5, 2) between A and B: th1 = th2 = atan2(2, 0.5), the bearing sweeps through 90 deg
        (math.atan2(2, 0.5), math.atan2(2, 0.5)),
        # tiny parallax, the baseline nearly along the bearing: th1 = 1 rad, th1 + th2 = 180 deg - p.
        # |BC| = sin 1 / sin p = 8.4e5 m at p = 1e-6, sigma_r / sigma = 1.19e12 m/rad. A fixed 1e-6 rad
        # difference step gave +12 % at p = 3e-6, x1.9e9 at 1e-6 (across the singularity), x1e-3 at 1e-7
        (1.0, math.pi - 1.0 - 3e-6),
        (1.0, math.pi - 1.0 - 1e-6),
        (1.0, math.pi - 1.0 - 1e-7),
        # nearly 180 deg of parallax: C = (0.5, 1e-3) almost on the baseline between A and B
        (math.atan2(1e-3, 0.5), math.atan2(1e-3, 0.5)),
    ],
)
def test_range_sigma_is_the_closed_form_first_order(t1, t2):
    d = 1.0
    r = g.planar_triangulate(d, t1, t2, bearing_sigma_rad=1.0)
    assert isinstance(r, g.Triangulation)
    assert r.range_m == pytest.approx(d * math.sin(t1) / math.sin(t1 + t2), rel=1e-6)
    assert r.range_sigma_m == pytest.approx(_sigma_closed_form(d, t1, t2, 1.0), rel=1e-3)
    # the batch computes the same first order
    c_a, b_a, c_b, b_b = g.planar_rays(d, t1, t2)
    b = g.triangulate_batch(c_a, b_a[None], c_b, b_b[None], bearing_sigma_rad=1.0, min_parallax_rad=0.0)
    assert b.range_sigma_m[0] == pytest.approx(r.range_sigma_m, rel=1e-6)


def test_range_sigma_at_a_tiny_parallax_matches_monte_carlo():
    # p = 1e-6 rad at d = 1 m: |BC| = 8.41e5 m; with sigma = 1e-10 rad the range is linear in the noise
    # (sigma / p = 1e-4), so the samples' std is the first-order sigma, 1.19e12 * 1e-10 = 119 m
    t1, t2 = 1.0, math.pi - 1.0 - 1e-6
    c_a, b_a, c_b, b_b = g.planar_rays(1.0, t1, t2)
    rng = np.random.default_rng(5)
    n = 4000
    mc = g.triangulate_batch(c_a, noisy_units(rng, b_a, 1e-10, n), c_b, noisy_units(rng, b_b, 1e-10, n),
                             min_parallax_rad=0.0)
    assert mc.valid.all()
    std = float(np.std(mc.range_m))
    assert std == pytest.approx(_sigma_closed_form(1.0, t1, t2, 1e-10), rel=0.06)
    r = g.planar_triangulate(1.0, t1, t2, bearing_sigma_rad=1e-10)
    assert r.range_sigma_m == pytest.approx(std, rel=0.06)


@pytest.mark.parametrize(
    "p, sigma",
    [
        # vergence 0.57 deg: 0.1 m pair, 10 m ahead; first order sqrt(2) Z^2 sigma / b = 0.1414 m
        ([10.0, 0.05, 0.0], 1e-4),
        # behind the pair (the forward cameras' rear hemisphere), 1.8 deg of vergence
        ([-3.0, 0.05, 1.0], 1e-3),
    ],
)
def test_stereo_range_sigma_matches_monte_carlo_at_small_vergence_and_behind(p, sigma):
    c_a, c_b, p = np.zeros(3), np.array([0.0, 0.1, 0.0]), np.asarray(p)
    b_a, b_b = (p - c_a) / np.linalg.norm(p - c_a), (p - c_b) / np.linalg.norm(p - c_b)
    r = g.triangulate(c_a, b_a, c_b, b_b, bearing_sigma_rad=sigma)
    assert r.range_m == pytest.approx(float(np.linalg.norm(p - c_b)), rel=1e-9)
    if p[0] > 0:
        assert r.range_sigma_m == pytest.approx(math.sqrt(2) * 100 * sigma / 0.1, rel=0.01)
    rng = np.random.default_rng(11)
    n = 4000
    mc = g.triangulate_batch(c_a, noisy_units(rng, b_a, sigma, n), c_b, noisy_units(rng, b_b, sigma, n))
    assert mc.valid.all()
    assert r.range_sigma_m == pytest.approx(float(np.std(mc.range_m)), rel=0.08)


@pytest.mark.parametrize(
    "c_a, b_a, c_b, b_b, reason",
    [
        # the obstacle on the stereo baseline's axis, beyond camera b: both rays along the axis
        ([0, 0, 0], [0, 1, 0], [0, 0.1, 0], [0, 1, 0], "parallel rays"),
        # rays exactly antiparallel, not on one line (an obstacle passing abeam at infinity)
        ([0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], "parallel rays"),
    ],
)
def test_axis_and_antiparallel_rays_are_unobservable(c_a, b_a, c_b, b_b, reason):
    r = g.triangulate(c_a, b_a, c_b, b_b, bearing_sigma_rad=1e-3)
    assert isinstance(r, g.Unobservable) and reason in r.reason


def test_rays_nearly_antiparallel_meet_between_the_centres():
    # A = 0, B = (10, 0, 0), C = (5, 5e-3, 0): parallax 180 deg - 2e-3 rad; |BC| = sqrt(25 + 2.5e-5);
    # behind camera b's direction of flight (+x), in front of its ray
    e = 1e-3
    r = g.triangulate([0, 0, 0], [1, e, 0], [10, 0, 0], [-1, e, 0])
    assert isinstance(r, g.Triangulation)
    np.testing.assert_allclose(r.p, [5.0, 5e-3, 0.0], atol=1e-12)
    assert r.range_m == pytest.approx(math.sqrt(25 + 2.5e-5), rel=1e-12)
    assert r.parallax_rad == pytest.approx(math.pi - 2 * math.atan(e), abs=1e-12)


# --------------------------------------------------------------------------- moving-obstacle bounds


@pytest.mark.parametrize("D, lo, hi", [
    # abeam: A = (-0.5, 0), B = (0.5, 0), C = (0, 3), |AB| = 1. The distance of B + r b_b from line a
    # is |cross(b_a, B - A) + r cross(b_a, b_b)| = (3 / 9.25) |r - sqrt(9.25)| (feet at s > 0), so the
    # depths within D are sqrt(9.25) -+ 9.25 D / 3, clamped at 0: obstacle half as fast as the drone,
    # as fast, 1.5 times as fast
    (0.5, math.sqrt(9.25) - 9.25 * 0.5 / 3, math.sqrt(9.25) + 9.25 * 0.5 / 3),
    (1.0, 0.0, math.sqrt(9.25) + 9.25 / 3),
    (1.5, 0.0, math.sqrt(9.25) + 9.25 * 1.5 / 3),
])
def test_bounds_abeam_closed_form(D, lo, hi):
    C = np.array([0.0, 3.0, 0.0])
    c_a, c_b = np.array([-0.5, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])
    b = g.moving_obstacle_bounds(c_a, C - c_a, c_b, C - c_b, D)
    assert (b.depth_min_m, b.depth_max_m) == pytest.approx((lo, hi), abs=1e-12)
    assert (b.range_min_m, b.range_max_m) == pytest.approx((lo, hi), abs=1e-12)


def _brute_force_ranges(c_a, b_a, c_b, b_b, v_max, dt, o, s_max, r_max, n=1501):
    """Ranges from o of every sampled obstacle consistent with the two bearings and |v| <= v_max:
    it was at c_a + s b_a (s >= 0) and is at c_b + r b_b (r >= 0), so its velocity is the difference
    over dt. Returns (ranges of the feasible samples, the r grid step + s grid step)."""
    s = np.linspace(0.0, s_max, n)
    r = np.linspace(0.0, r_max, n)
    p_a = c_a + s[:, None] * b_a  # (n, 3)
    p_b = c_b + r[:, None] * b_b
    v = (p_b[None, :, :] - p_a[:, None, :]) / dt  # (n_s, n_r, 3)
    ok = np.linalg.norm(v, axis=2) <= v_max
    feasible_r = ok.any(axis=0)
    return np.linalg.norm(p_b[feasible_r] - o, axis=1), r[1] - r[0] + s[1] - s[0]


@pytest.mark.parametrize("where", ["ahead", "rear", "abeam", "same bearing"])
@pytest.mark.parametrize("speed_ratio", [2.0, 1.0, 0.5])
def test_bounds_contain_every_consistent_obstacle_and_are_attained(where, speed_ratio):
    # the drone flies 10 m/s along +x for dt = 0.1 s; the camera sits 0.2 m ahead of and 0.1 m above the
    # body origin o (ranges are from o). The obstacle truth is static at C, so the two bearings are real;
    # every obstacle with |v| <= v_max = speed_ratio * 10 m/s that gives the same two bearings must
    # have its range inside [range_min, range_max], and both ends must be attained (tight)
    dt, v_drone = 0.1, 10.0
    off = np.array([0.2, 0.0, 0.1])
    o_a, o_b = np.zeros(3), np.array([v_drone * dt, 0.0, 0.0])
    c_a, c_b = o_a + off, o_b + off
    C = {"ahead": [6.0, 2.0, -0.5], "rear": [-5.0, 2.5, 0.7], "abeam": [0.7, 3.0, -0.4],
         "same bearing": None}[where]
    if C is None:  # the bearing does not change: the obstacle moved exactly as the drone did
        b_a = b_b = np.array([1.0, 1.0, 0.2]) / np.linalg.norm([1.0, 1.0, 0.2])
    else:
        C = np.asarray(C)
        b_a, b_b = (C - c_a) / np.linalg.norm(C - c_a), (C - c_b) / np.linalg.norm(C - c_b)
    v_max = speed_ratio * v_drone
    b = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, v_max * dt, origin=o_b)
    ranges, step = _brute_force_ranges(c_a, b_a, c_b, b_b, v_max, dt, o_b, s_max=40.0, r_max=40.0)
    if not len(ranges):  # same bearing, half the drone's speed: the rays are 0.714 m apart, D = 0.5 m
        assert (where, speed_ratio) == ("same bearing", 0.5)
        assert isinstance(b, g.Unobservable) and "inconsistent with max speed" in b.reason
        return
    tol = 1e-9
    assert ranges.min() >= b.range_min_m - tol
    assert ranges.min() == pytest.approx(b.range_min_m, abs=2 * step)
    if b.range_max_m is None:
        # unbounded: the sampled feasible set reaches the end of the grid (the rays are parallel and
        # their distance apart, 1 m sin(angle to the flight) = 0.70 m, is within v_max dt)
        assert where == "same bearing" and ranges.max() > 39.0
    else:
        assert ranges.max() <= b.range_max_m + tol
        assert ranges.max() == pytest.approx(b.range_max_m, abs=2 * step)


def test_bounds_when_the_bearing_does_not_change_and_the_obstacle_moved_exactly_the_rays_gap():
    # parallel rays 1 m sin(45 deg) = sqrt(0.5) m apart: an obstacle that moved exactly that far (the
    # boundary between "inconsistent" and "unbounded", both checked above) can be at any range
    b_ = [1.0, 1.0, 0.0]
    r = g.moving_obstacle_bounds([0, 0, 0], b_, [1, 0, 0], b_, math.sqrt(0.5))
    assert isinstance(r, g.RangeBounds) and r.range_min_m == 0.0 and r.range_max_m is None
