"""estimators.geometry at the edges a fisheye makes normal: bearings behind the direction of flight,
an obstacle passing abeam, tiny parallax (baseline nearly along the bearing), rays near 180 deg
apart.

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

R = math.radians


def _sigma_closed_form(d, t1, t2, sigma):
    S = math.sin(t1 + t2)
    return sigma * d * math.sqrt(math.sin(t2) ** 2 + (math.sin(t1) * math.cos(t1 + t2)) ** 2) / S**2


def _noisy(rng, b, sigma, n):
    """n unit vectors about unit b with isotropic tangent-plane noise of std sigma (radians)."""
    e = np.eye(3)[np.argmin(np.abs(b))]
    u1 = np.cross(b, e)
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(b, u1)
    z = rng.standard_normal((n, 2)) * sigma
    v = b + z[:, :1] * u1 + z[:, 1:] * u2
    return v / np.linalg.norm(v, axis=1, keepdims=True)


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
    mc = g.triangulate_batch(c_a, _noisy(rng, b_a, 1e-10, n), c_b, _noisy(rng, b_b, 1e-10, n),
                             min_parallax_rad=0.0)
    assert mc.valid.all()
    std = float(np.std(mc.range_m))
    assert std == pytest.approx(_sigma_closed_form(1.0, t1, t2, 1e-10), rel=0.06)
    r = g.planar_triangulate(1.0, t1, t2, bearing_sigma_rad=1e-10)
    assert r.range_sigma_m == pytest.approx(std, rel=0.06)
