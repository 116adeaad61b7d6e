"""Tests of estimators.thesis: the printed formulas, their agreement with the general estimators where the
thesis is self-consistent, and the reproduction of the chapter-4 / appendix-A tables.

Expected numbers are worked out here independently: the law of sines with math.sin, 3-4-5 triangles,
and a brute-force scan of depths along a ray for the moving-obstacle bounds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from estimators import geometry as g
from estimators import thesis as th

R = math.radians
angle = st.floats(1.0, 178.0)


def law_of_sines_from_b(d, t1_deg, t2_deg):
    """|BC| in triangle ABC with |AB| = d, interior angles t1 at A, t2 at B (written independently)."""
    return d * math.sin(R(t1_deg)) / math.sin(R(180.0 - t1_deg - t2_deg))


# --------------------------------------------------------------------------- printed formulas, by hand


def test_eq_3_8_equilateral_and_3_1_height():
    assert th.eq_3_8_mono_Y(2.0, 60, 60) == pytest.approx(2.0)
    assert th.eq_3_1_stereo_Z(2.0, 60, 60) == pytest.approx(math.sqrt(3))
    # 90/45: |BC| = d / cos 45, height = d
    assert th.eq_3_8_mono_Y(2.0, 90, 45) == pytest.approx(2 * math.sqrt(2))
    assert th.eq_3_1_stereo_Z(2.0, 90, 45) == pytest.approx(2.0)


def test_eq_3_9_and_3_10_obtuse_hand_values():
    # 120/30/30 isosceles with d = 1: |BC| = sqrt(3); mirrored 30/120: |BC| = 1
    assert th.eq_3_9_mono_CB(1.0, 120, 30) == pytest.approx(math.sqrt(3))
    assert th.eq_3_10_mono_CB(1.0, 30, 120) == pytest.approx(1.0)


def test_eq_3_2_midpoint_range_hand_value():
    # 120/30 with d = 1: C = A + 1 (cos 120, sin 120) = (-0.5, sqrt(3)/2); F = (0.5, 0): CF = sqrt(1 + 3/4)
    assert th.eq_3_2_stereo_CF(1.0, 120, 30) == pytest.approx(math.sqrt(1.75))
    # the printed "9 deg" gives something else
    assert th.eq_3_2_stereo_CF(1.0, 120, 30, as_printed=True) != pytest.approx(math.sqrt(1.75), rel=1e-3)



@pytest.mark.parametrize("t1, t2", [(90, 90), (120, 60), (30, 150)])
def test_printed_range_formulas_report_parallel_rays_unobservable(t1, t2):
    """theta1 + theta2 = 180 deg: the rays are parallel, no triangle. eq. 3.9 and 3.2 divided by
    tan(0) (ZeroDivisionError) and eq. 3.8, 3.10 and 3.1 by cos(90 deg) = 6e-17 (~1e16 m): now each
    answers Unobservable, as the general estimators do; a degree off, a finite range again (law of
    sines by hand: d sin t1 / sin(t1 + t2 - 1))."""
    from estimators.geometry import Unobservable

    printed = (th.eq_3_1_stereo_Z, th.eq_3_2_stereo_CF, th.eq_3_8_mono_Y, th.eq_3_9_mono_CB,
               th.eq_3_10_mono_CB)
    for f in printed:
        r = f(1.0, t1, t2)
        assert isinstance(r, Unobservable) and "parallel rays" in r.reason, (f.__name__, r)
    assert th.eq_3_8_mono_Y(1.0, t1, t2 - 1) == pytest.approx(math.sin(R(t1)) / math.sin(R(t1 + t2 - 1)))

def test_eq_3_11_and_3_12_right_triangles():
    # th4 = 90: FB = sqrt(FC^2 + CB^2) = 5 for 3, 4
    assert th.eq_3_11_FB(4.0, 3.0, 90) == pytest.approx(5.0)
    # th3 = 90 (right angle at G): BG = sqrt(CB^2 - CG^2) = 4 for CB = 5, CG = 3; printed gives sqrt(34)
    assert th.eq_3_12_BG_corrected(5.0, 3.0, 90) == pytest.approx(4.0)
    assert th.eq_3_12_BG(5.0, 3.0, 90) == pytest.approx(math.sqrt(34))
    # printed eq. 3.12 can even be negative: th2 = 140, CB = sin10/sin150, CG = 1
    cb = law_of_sines_from_b(1.0, 10, 140)
    assert th.eq_3_12_BG(cb, 1.0, 140) == pytest.approx(
        math.sqrt(cb**2 + math.sin(R(140)) ** 2) - math.cos(R(40))
    )
    assert th.eq_3_12_BG(cb, 1.0, 140) < 0


def test_eq_3_6_split_square_root_hand_values():
    # th1 = th2 = 90: a = AB = 3, b = BD - AC = 5 - 1 = 4 -> derived 5, as printed |a| + |b| = 7
    assert th.eq_3_6_nonparallel_faster_obstacle(3.0, 1.0, 5.0, 90, 90) == pytest.approx(5.0)
    assert th.eq_3_6_as_printed(3.0, 1.0, 5.0, 90, 90) == pytest.approx(7.0)
    assert th.eq_3_5_nonparallel_slower_obstacle(3.0, 1.0, 5.0, 90, 90) == pytest.approx(5.0)


def test_percentage_error_and_spacing():
    assert th.percentage_error(341.1, 407.9) == pytest.approx(100 * 66.8 / 407.9)
    assert th.eq_3_7_spacing(0.1, 1341.1) == pytest.approx(134.11)


# --------------------------------------------------------------------------- agreement with geometry.py


@settings(max_examples=150, deadline=None)
@given(t1=angle, t2=angle, d=st.floats(0.05, 5.0))
def test_general_triangulation_is_the_thesis_planar_case(t1, t2, d):
    assume(t1 + t2 < 178.0)
    r = g.planar_triangulate(d, R(t1), R(t2))
    assert isinstance(r, g.Triangulation)
    y = law_of_sines_from_b(d, t1, t2)
    assert r.range_m == pytest.approx(y, rel=1e-9)
    assert th.eq_3_8_mono_Y(d, t1, t2) == pytest.approx(y, rel=1e-9)  # eq. 3.8 for every angle pair
    assert r.p[1] == pytest.approx(th.eq_3_1_stereo_Z(d, t1, t2), rel=1e-9)  # eq. 3.1's Z
    mid = g.planar_triangulate(d, R(t1), R(t2), origin="mid").range_m
    if t1 > 90:  # eq. 3.2 and 3.9 are derived for th1 > 90, eq. 3.10 for th2 > 90
        assert th.eq_3_2_stereo_CF(d, t1, t2) == pytest.approx(mid, rel=1e-9)
        assert th.eq_3_9_mono_CB(d, t1, t2) == pytest.approx(y, rel=1e-9)
    if t2 > 90:
        assert th.eq_3_10_mono_CB(d, t1, t2) == pytest.approx(y, rel=1e-9)


@settings(max_examples=150, deadline=None)
@given(t1=angle, t2=angle, AB=st.floats(0.0, 3.0), AC=st.floats(0.1, 5.0), BD=st.floats(0.1, 5.0))
def test_speed_equations_are_velocity_from_fixes(t1, t2, AB, AC, BD):
    # Figures 3.6-3.9: drone A -> B along +x, obstacle C seen from A at th1, D seen from B at th2
    C = np.array([AC * math.cos(R(t1)), AC * math.sin(R(t1)), 0.0])
    D = np.array([AB - BD * math.cos(R(t2)), BD * math.sin(R(t2)), 0.0])
    v = g.velocity_from_fixes(C, 0.0, D, 0.1)
    moved = v.speed_mps * 0.1
    assert th.eq_3_5_nonparallel_slower_obstacle(AB, AC, BD, t1, t2) == pytest.approx(moved, abs=1e-9)
    assert th.eq_3_6_nonparallel_faster_obstacle(AB, AC, BD, t1, t2) == pytest.approx(moved, abs=1e-9)
    # eq. 3.3/3.4 are the signed x-displacement (exact when the motion is parallel to the drone's)
    assert th.eq_3_3_parallel_slower_obstacle(AB, AC, BD, t1, t2) == pytest.approx(D[0] - C[0], abs=1e-9)
    assert th.eq_3_4_parallel_faster_obstacle(AB, AC, BD, t1, t2) == pytest.approx(D[0] - C[0], abs=1e-9)


def _feasible_depths_brute(d, t1, t2, D, n=200001, r_max=None):
    """Depths r >= 0 along ray b whose distance to ray a is <= D, by a dense scan (independent)."""
    c_a, c_b = np.zeros(2), np.array([d, 0.0])
    b_a = np.array([math.cos(R(t1)), math.sin(R(t1))])
    b_b = np.array([-math.cos(R(t2)), math.sin(R(t2))])
    r = np.linspace(0.0, r_max, n)
    q = c_b + r[:, None] * b_b
    s = np.maximum(0.0, (q - c_a) @ b_a)
    dist = np.linalg.norm(q - (c_a + s[:, None] * b_a), axis=1)
    ok = r[dist <= D]
    return ok.min(), ok.max(), r[1] - r[0]


@pytest.mark.parametrize(
    "t1, t2, d, D", [(62.5, 77.5, 1.27, 0.762), (72.5, 80, 1.651, 0.5), (30, 120, 1.0, 0.3)]
)
def test_planar_bounds_match_brute_force(t1, t2, d, D):
    b = g.planar_moving_obstacle_bounds(d, R(t1), R(t2), D)
    lo, hi, step = _feasible_depths_brute(d, t1, t2, D, r_max=20.0)
    assert b.depth_min_m == pytest.approx(lo, abs=2 * step)
    assert b.depth_max_m == pytest.approx(hi, abs=2 * step)


@settings(max_examples=150, deadline=None)
@given(t1=angle, t2=angle, d=st.floats(0.05, 3.0), D=st.floats(0.0, 3.0))
def test_bounds_contain_the_thesis_fb_and_motion_along_the_baseline(t1, t2, d, D):
    assume(t1 + t2 < 178.0)
    b = g.planar_moving_obstacle_bounds(d, R(t1), R(t2), D)
    assert isinstance(b, g.RangeBounds)
    cb = law_of_sines_from_b(d, t1, t2)
    hi = math.inf if b.range_max_m is None else b.range_max_m
    tol = 1e-9 * (1 + cb + D)
    # any point within D of the static C is reachable: the bounds contain [CB - D, CB + D] (clamped)
    assert b.range_min_m <= max(cb - D, 0.0) + tol and cb + D <= hi + tol
    # so they contain eq. 3.11's FB and the law-of-cosines distances to C -+ D u (motion along AB)
    assert b.range_min_m - tol <= th.eq_3_11_FB(cb, D, t1) <= hi + tol
    for x in th.along_baseline_distances(cb, D, t2):
        assert b.range_min_m - tol <= x <= hi + tol


def test_printed_eq_3_12_can_exceed_the_feasible_range():
    # th1 = 10, th2 = 50, d = D = 1: the farthest feasible point on ray b (brute force) is nearer than BG
    d, t1, t2, D = 1.0, 10.0, 50.0, 1.0
    _, hi, step = _feasible_depths_brute(d, t1, t2, D, r_max=5.0)
    cb = law_of_sines_from_b(d, t1, t2)
    assert th.eq_3_12_BG(cb, D, t2) > hi + 10 * step
    b = g.planar_moving_obstacle_bounds(d, R(t1), R(t2), D)
    assert b.range_max_m == pytest.approx(hi, abs=2 * step)


# --------------------------------------------------------------------------- reproduction of the tables

# Inputs as printed (cm, deg): the thesis's distance is computed from the "Experimental" angles.
# Expected: |BC| by the law of sines, error against the second figure's measured distance.
TABLE_INPUTS = {
    "4.2": (165.1, 72.5, 80, 407.9),
    "4.3": (139.7, 57.5, 86.67, 222.3),
    "4.4": (127.0, 62.5, 77.5, 210.1),
    "4.5": (10.2, 85, 84.6, 257.6),
    "4.6": (15.2, 85, 84.8, 256.3),
    "4.7": (20.3, 85, 85.8, 256.5),
    "4.8": (25.4, 85, 87.5, 255.5),
    "4.9": (30.5, 85, 88.3, 255.8),
    "4.11": (30.5, 72.5, 100.58, 324.1),
    "4.12": (30.5, 73.3, 98.3, 235.2),
    "4.13": (30.5, 79.2, 90.4, 195.1),
    "A.1": (152.4, 64.2, 82.5, 293.4),
    "A.2": (101.6, 83.3, 55.8, 236.5),
    "A.3": (101.6, 82.9, 86.7, 423.926),
}

EXPECTED_TABLE_VERDICTS = {
    "sec 4.1.2": "reproduces",
    "4.2": "reproduces",
    "4.3": "reproduces",
    "4.6": "reproduces",
    "4.7": "reproduces",
    "4.8": "reproduces",
    "4.9": "reproduces",
    "4.11": "reproduces",
    "4.12": "reproduces",
    "4.13": "reproduces",
    "A.1": "reproduces",
    "A.2": "reproduces",
    "A.3": "reproduces",
    "4.4": "does not reproduce",
    "4.5": "does not reproduce",
    "4.10": "does not reproduce",
    "4.14": "does not reproduce",
    "4.15": "does not reproduce",
}


@pytest.fixture(scope="module")
def rows():
    return th.reproduce()


def _row(rows, table, quantity):
    hits = [r for r in rows if r.table == table and r.quantity.startswith(quantity)]
    assert len(hits) == 1, (table, quantity, hits)
    return hits[0]


@pytest.mark.parametrize("table", sorted(TABLE_INPUTS))
def test_reproduced_distance_and_error(rows, table):
    d, t1, t2, truth = TABLE_INPUTS[table]
    y = law_of_sines_from_b(d, t1, t2)
    r = _row(rows, table, "experimental distance")
    assert r.ours == pytest.approx(y, rel=1e-9)
    assert r.diff == pytest.approx(r.thesis - y, rel=1e-9)
    e = _row(rows, table, "percentage error")
    assert e.ours == pytest.approx(abs(y - truth) / truth * 100, rel=1e-9)


def test_hand_checked_table_values(rows):
    # a few worked out with a calculator: 165.1 sin72.5 / sin152.5 = 341.005; 25.4 sin85 / sin7.5 = 193.856
    assert _row(rows, "4.2", "experimental distance").ours == pytest.approx(341.005, abs=1e-3)
    assert _row(rows, "4.8", "experimental distance").ours == pytest.approx(193.856, abs=1e-3)
    assert _row(rows, "4.5", "experimental distance").ours == pytest.approx(56.289, abs=1e-3)
    assert _row(rows, "4.4", "experimental distance").ours == pytest.approx(175.253, abs=1e-3)


def test_angle_errors_table_4_10(rows):
    for spacing, (t1m, t1e), (t2m, t2e), ok_right in [
        (10.2, (83, 85), (87, 84.6), False),  # 2.76 printed as 2.78
        (15.2, (83, 85), (86.5, 84.8), True),
        (20.3, (83, 85), (87, 85.8), False),  # 1.38 printed as 1.34
        (25.4, (83, 85), (88, 87.5), True),
        (30.5, (83, 85), (89, 88.3), True),
    ]:
        left = _row(rows, "4.10", f"angle error left ({spacing} cm")
        right = _row(rows, "4.10", f"angle error right ({spacing} cm")
        assert left.ours == pytest.approx(abs(t1e - t1m) / t1m * 100)
        assert right.ours == pytest.approx(abs(t2e - t2m) / t2m * 100)
        assert left.verdict == "reproduces"
        assert (right.verdict == "reproduces") is ok_right


def test_unobservable_rows(rows):
    r = _row(rows, "4.14", "experimental distance")
    assert r.ours is None and r.verdict == "does not reproduce" and "180" in r.note
    for q in ("moved distance", "speed of obstacle"):
        assert _row(rows, "4.15", q).ours is None


def test_moving_test_bounds_contain_the_measured_range(rows):
    # D = 76.2 cm (the measured motion): brute-force feasible depths along ray b contain 210.1 cm
    lo, hi, step = _feasible_depths_brute(127.0, 62.5, 77.5, 76.2, r_max=1000.0)
    r = _row(rows, "4.4", "bounds, D = 76.2")
    assert r.extra["range_min_cm"] == pytest.approx(lo, abs=2 * step)
    assert r.extra["range_max_cm"] == pytest.approx(hi, abs=2 * step)
    assert r.extra["truth_inside"] and lo <= 210.1 <= hi


def test_table_verdicts(rows):
    summary = th.table_summary(rows)
    assert {k: v.split(":")[0] for k, v in summary.items()} == EXPECTED_TABLE_VERDICTS


def test_inconsistency_lines():
    lines = th.inconsistencies()
    text = "\n".join(lines)
    for needle in (
        "eq. 3.2: prints tan(9 deg",
        "eq. 3.6",
        "eq. 3.12",
        "Table 4.5: the distance 141.9",
        "2.76% and 1.38%",
        "78.17% differs from Table 4.5's 78.27%",
        "187.5 deg",
        "Table 4.11: its error 25.61%",
    ):
        assert needle in text, needle
    assert len(lines) == len(set(lines)) >= 20
