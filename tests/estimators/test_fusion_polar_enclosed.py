"""``estimators.fusion._polar_enclosed``: which groups of points, given by their polar angles about
an origin, enclose it (no half-plane through the origin holds them all: the largest gap between
their sorted angles, the wrap included, is below pi). Truth by hand from the angles."""

from __future__ import annotations

import math

import numpy as np

from estimators.fusion import _polar_enclosed

PI = math.pi


def _enc(groups: list[list[float]], order=None) -> list[bool]:
    ang = np.array([a for grp in groups for a in grp], dtype=float)
    grp = np.array([q for q, g in enumerate(groups) for _ in g], dtype=np.int64)
    if order is not None:  # (input order need not be by group or angle)
        ang, grp = ang[order], grp[order]
    return _polar_enclosed(ang, grp, len(groups)).tolist()


def test_closed_form_groups():
    groups = [
        [0.0, 2 * PI / 3, -2 * PI / 3],  # gaps 2pi/3: enclosed
        [0.0, 0.5 * PI, 0.9 * PI],  # the wrap 1.1 pi: not
        [-0.9 * PI, 0.9 * PI, 0.0],  # gaps 0.9 pi, 0.9 pi, the wrap 0.2 pi: enclosed
        [-0.9 * PI, 0.9 * PI, 0.95 * PI],  # a gap of 1.8 pi: not
        [0.0, 0.999 * PI],  # two points: the wrap 1.001 pi: not
        [0.3],  # one point: the wrap 2 pi: not
        [-0.5 * PI, 0.0, 0.499 * PI, PI],  # gaps 0.5, 0.499, 0.501, the wrap 0.5 pi: enclosed
    ]
    want = [True, False, True, False, False, False, True]
    assert _enc(groups) == want
    n = sum(len(g) for g in groups)
    assert _enc(groups, np.random.default_rng(3).permutation(n)) == want


def test_an_empty_group_is_not_enclosed_wherever_it_stands():
    tri = [0.0, 2 * PI / 3, -2 * PI / 3]
    assert _enc([[], tri]) == [False, True]
    assert _enc([tri, []]) == [True, False]
    assert _enc([tri, [], [], tri]) == [True, False, False, True]
    assert _enc([[], []]) == [False, False]  # no points at all


def test_points_on_a_line_through_the_origin_do_not_enclose_it():
    """A closed half-plane holds them (the origin on the hull's edge, not inside): gap pi exactly."""
    assert _enc([[0.0, PI], [0.0, 0.5 * PI, PI], [-0.5 * PI, 0.5 * PI, PI]]) == [False, False, False]
    assert _enc([[-0.4 * PI, 0.5 * PI, PI]]) == [True]  # (the first point off the line: inside)


def test_angles_in_any_two_pi_range():
    """The angles need not lie in (-pi, pi]: a group's gaps are its own, not the step from the
    previous group's last angle (0.3 -> 3.5 rad here)."""
    tri = [3.5, 3.5 + 2 * PI / 3, 3.5 + 4 * PI / 3]
    assert _enc([[0.1, 0.2, 0.3], tri]) == [False, True]
