"""Property tests (hypothesis) of estimators.geometry over random 3-D geometry.

- triangulate recovers a noise-free point exactly;
- no estimator ever returns NaN or raises on finite input, including degenerate draws;
- moving_obstacle_bounds always contains the true range of an obstacle that moved at most D, and is
  tight: its end points lie exactly on the constraint dist(point, ray a) = D (or at depth 0);
- velocity_from_fixes recovers the velocity exactly.
The distance to a half-line used to check the bounds is written here independently.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from estimators import geometry as g
from estimators.errors import InputError

coord = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(coord, coord, coord).map(np.array)
unit_raw = st.tuples(*(st.floats(-1.0, 1.0, allow_nan=False),) * 3).map(np.array)
# more examples for a thorough run: FISHEYE_DES_HYPOTHESIS_EXAMPLES=5000 pytest tests/estimators
SETTINGS = settings(max_examples=int(os.environ.get("FISHEYE_DES_HYPOTHESIS_EXAMPLES", "120")), deadline=None)


def _unit(v):
    return v / np.linalg.norm(v)


def _dist_to_half_line(q, c, b):
    """Distance from q to {c + s b, s >= 0} (b unit), written independently of the code under test."""
    s = max(0.0, float(np.dot(q - c, b)))
    return float(np.linalg.norm(q - (c + s * b)))


def _finite_record(r) -> bool:
    vals = []
    for v in vars(r).values():
        if v is None:
            continue
        vals.extend(np.atleast_1d(np.asarray(v, dtype=float)).tolist())
    return all(math.isfinite(x) for x in vals)


@SETTINGS
@given(c_a=vec3, c_b=vec3, p=vec3)
def test_triangulate_recovers_noise_free_point(c_a, c_b, p):
    assume(np.linalg.norm(c_b - c_a) > 0.05)
    assume(np.linalg.norm(p - c_a) > 0.1 and np.linalg.norm(p - c_b) > 0.1)
    b_a, b_b = _unit(p - c_a), _unit(p - c_b)
    parallax = math.acos(float(np.clip(b_a @ b_b, -1, 1)))
    assume(math.radians(1.0) < parallax < math.radians(179.0))
    r = g.triangulate(c_a, b_a, c_b, b_b)
    assert isinstance(r, g.Triangulation)
    scale = 1.0 + float(np.abs(np.concatenate([c_a, c_b, p])).max())
    np.testing.assert_allclose(r.p, p, atol=1e-8 * scale / math.sin(parallax))
    assert r.range_m == pytest.approx(float(np.linalg.norm(p - c_b)), abs=1e-8 * scale / math.sin(parallax))
    assert r.depth_a_m == pytest.approx(float(np.linalg.norm(p - c_a)), abs=1e-7 * scale / math.sin(parallax))
    assert r.miss_m < 1e-7 * scale


mode = st.sampled_from(["free", "parallel", "antiparallel", "same_centre", "near_parallel", "collinear"])


@SETTINGS
@given(m=mode, c_a=vec3, c_b=vec3, b_a=unit_raw, b_b=unit_raw, eps=st.floats(0, 1e-3),
       D=st.floats(0.0, 50.0), sigma=st.floats(0.0, 0.1))
def test_no_nan_ever(m, c_a, c_b, b_a, b_b, eps, D, sigma):
    assume(np.linalg.norm(b_a) > 1e-3 and np.linalg.norm(b_b) > 1e-3)
    if m == "parallel":
        b_b = b_a.copy()
    elif m == "antiparallel":
        b_b = -b_a
    elif m == "same_centre":
        c_b = c_a.copy()
    elif m == "near_parallel":
        b_b = b_a + eps * b_b
        assume(np.linalg.norm(b_b) > 1e-3)
    elif m == "collinear":  # both rays on the baseline line
        b_a = _unit(c_b - c_a) if np.linalg.norm(c_b - c_a) > 1e-6 else b_a
        b_b = -b_a
    for origin in (None, c_a):
        r = g.triangulate(c_a, b_a, c_b, b_b, origin=origin, bearing_sigma_rad=sigma)
        assert isinstance(r, g.Unobservable | g.Triangulation)
        if isinstance(r, g.Triangulation):
            assert _finite_record(r)
        else:
            assert r.reason
        bnd = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, D, origin=origin)
        assert isinstance(bnd, g.Unobservable | g.RangeBounds)
        if isinstance(bnd, g.RangeBounds):
            assert _finite_record(bnd)
            assert 0 <= bnd.depth_min_m and (bnd.depth_max_m is None or bnd.depth_min_m <= bnd.depth_max_m)
            assert bnd.range_max_m is None or bnd.range_min_m <= bnd.range_max_m + 1e-9


@SETTINGS
@given(d=st.floats(0.0, 10.0), t1=st.floats(0.0, math.pi), t2=st.floats(0.0, math.pi))
def test_planar_no_nan_and_sum_rule(d, t1, t2):
    r = g.planar_triangulate(d, t1, t2)
    if d > 0 and 0 < t1 < math.pi and 0 < t2 < math.pi and t1 + t2 < math.pi:
        assert isinstance(r, g.Triangulation | g.Unobservable)  # e.g. unobservable: behind, rounding
        if isinstance(r, g.Triangulation):
            assert _finite_record(r)
    else:
        assert isinstance(r, g.Unobservable)
    if t1 + t2 >= math.pi and d > 0 and 0 < t1 < math.pi and 0 < t2 < math.pi:
        assert r.reason == "angles sum to >= 180 deg"


@SETTINGS
@given(c_a=vec3, c_b=vec3, p_a=vec3, direction=unit_raw, frac=st.floats(0.0, 1.0),
       D=st.floats(0.0, 10.0), origin=st.one_of(st.none(), vec3))
def test_bounds_contain_truth_and_are_tight(c_a, c_b, p_a, direction, frac, D, origin):
    assume(np.linalg.norm(direction) > 1e-3)
    p_b = p_a + frac * D * _unit(direction)  # moved at most D, any direction
    assume(np.linalg.norm(p_a - c_a) > 1e-3 and np.linalg.norm(p_b - c_b) > 1e-3)
    b_a, b_b = _unit(p_a - c_a), _unit(p_b - c_b)
    o = c_b if origin is None else origin
    bnd = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, D, origin=origin)
    assert isinstance(bnd, g.RangeBounds), bnd
    scale = 1.0 + float(np.abs(np.concatenate([c_a, c_b, p_a, p_b, o])).max())
    tol = 1e-6 * scale
    # the truth is inside, in depth along ray b and in range from the origin
    depth_true = float(np.linalg.norm(p_b - c_b))
    range_true = float(np.linalg.norm(p_b - o))
    assert bnd.depth_min_m - tol <= depth_true
    assert bnd.depth_max_m is None or depth_true <= bnd.depth_max_m + tol
    assert bnd.range_min_m - tol <= range_true
    assert bnd.range_max_m is None or range_true <= bnd.range_max_m + tol
    # tight: each finite end point is feasible and, unless it is depth 0, on the boundary dist = D
    for r in (bnd.depth_min_m, bnd.depth_max_m):
        if r is None:
            continue
        # rounding of a point at depth r is ~eps r (near-parallel rays reach r ~ 1e12)
        tol_r = 1e-5 * scale + 1e-13 * r
        dist = _dist_to_half_line(c_b + r * b_b, c_a, b_a)
        assert dist <= D + tol_r
        if r > tol:
            assert dist == pytest.approx(D, abs=tol_r)
    # the reported range extremes are attained by feasible points
    lo = bnd.depth_min_m
    hi = bnd.depth_max_m if bnd.depth_max_m is not None else lo + 1e3
    grid = np.linspace(lo, hi, 201)
    ranges = np.linalg.norm(c_b + grid[:, None] * b_b - o, axis=1)
    assert ranges.min() >= bnd.range_min_m - tol
    if bnd.range_max_m is not None:
        assert ranges.max() == pytest.approx(bnd.range_max_m, abs=tol + 1e-12 * bnd.range_max_m)


@SETTINGS
@given(c_a=vec3, c_b=vec3, p_a=vec3, direction=unit_raw, D=st.floats(0.01, 10.0), over=st.floats(1.05, 3.0))
def test_bounds_exclude_depths_needing_more_motion(c_a, c_b, p_a, direction, D, over):
    # a point on ray b farther than D from ray a (checked independently) is outside the interval
    assume(np.linalg.norm(direction) > 1e-3)
    p_b = p_a + over * D * _unit(direction)
    assume(np.linalg.norm(p_a - c_a) > 1e-3 and np.linalg.norm(p_b - c_b) > 1e-3)
    b_a, b_b = _unit(p_a - c_a), _unit(p_b - c_b)
    depth = float(np.linalg.norm(p_b - c_b))
    dist = _dist_to_half_line(p_b, c_a, b_a)
    assume(dist > D * 1.01)
    bnd = g.moving_obstacle_bounds(c_a, b_a, c_b, b_b, D)
    if isinstance(bnd, g.RangeBounds):
        inside = bnd.depth_min_m <= depth and (bnd.depth_max_m is None or depth <= bnd.depth_max_m)
        assert not inside


@SETTINGS
@given(p_1=vec3, v=vec3, t1=st.floats(-1e3, 1e3), dt=st.floats(1e-3, 10.0))
def test_velocity_exact(p_1, v, t1, dt):
    t2 = t1 + dt
    assume(t2 > t1)
    p_2 = p_1 + v * (t2 - t1)
    r = g.velocity_from_fixes(p_1, t1, p_2, t2)
    assert isinstance(r, g.Velocity)
    scale = 1.0 + float(np.abs(np.concatenate([p_1, p_2])).max())
    np.testing.assert_allclose(r.v, v, atol=1e-12 * scale / (t2 - t1) + 1e-9 * np.abs(v).max())
    assert r.speed_mps == pytest.approx(float(np.linalg.norm(v)), abs=1e-9 * (1 + scale / (t2 - t1)))
    if math.hypot(v[0], v[1]) > 1e-6:
        dh = r.heading_rad - math.atan2(v[1], v[0])
        assert abs(math.atan2(math.sin(dh), math.cos(dh))) < 1e-6  # equal up to the +-pi wrap


def test_zero_direction_is_input_error_not_unobservable():
    with pytest.raises(InputError):
        g.triangulate([0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0])
