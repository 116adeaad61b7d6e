"""A report whose direction passes within the tracked window's angle of the convex hull of another
track's nearer member points (not inside it, and no single point of it inside the window's angle)
gets a range sigma that reaches that track's depth (``ObstacleFusion._occluded_by_members``, the
hull widened by the window angle).

Truth by hand: a mono rig (camera at the body origin, 0.15 deg per px: the angle of the 11-px
window's half-width is 5.5 * 0.15 = 0.825 deg) flies along +x at 5 m/s for 20 frames at 30 fps,
so the body ends at o = (19 / 6, 0, 0). Track 2: three corners of a far wall at
(20 + 0.05 i, 6, 0.05 i), i = -1, 0, 1 (17.9-18.0 m from o). Track 1: four corners of a near plate
halfway along o's ray u toward the far wall's middle corner (~9 m), set off that ray in the
plane-tangent coordinates (w, v) about u by (a, +-1.0 deg) and (a + 1.0 deg, +-1.0 deg): the
plate's edge nearest u lies a off it, its nearest corner hypot(a, 1.0) off (> 0.825 deg for every a
used, so ``_window_neighbours`` leaves the far report). a = 0.6 deg: the edge within the window
angle of u (the plate's surface, which spans at least its corners' hull, reaches into the window of
the tracked far corner: the far point may be hidden behind it); a = 1.5 deg: clear of it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.fusion import FusionSettings
from estimators.rig import mono_forward_rig
from tests.estimators.fusion_helpers import WALL_FAR, WALL_O_END, far_wall_report

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
FAR = WALL_FAR
O_END = WALL_O_END


def _near_plate(a_deg: float, width_deg: float = 1.0, half_deg: float = 1.0,
                phi_deg: float = 0.0) -> list[np.ndarray]:
    """The near plate's four corners, halfway along o_end's ray toward FAR[1], at the tangent-plane
    offsets (a, +-half), (a + width, +-half) deg about that ray, in axes (w, v) turned by phi about
    it."""
    d = FAR[1] - O_END
    half = 0.5 * float(np.linalg.norm(d))
    u = d / np.linalg.norm(d)
    w0 = np.cross(u, [1.0, 0.0, 0.0])
    w0 /= np.linalg.norm(w0)
    v0 = np.cross(u, w0)
    c, s_ = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    w, v = c * w0 + s_ * v0, -s_ * w0 + c * v0
    out = []
    for x in (a_deg, a_deg + width_deg):
        for y in (-half_deg, half_deg):
            q = u + math.tan(math.radians(x)) * w + math.tan(math.radians(y)) * v  # (gnomonic offsets)
            out.append(O_END + half * q / np.linalg.norm(q))
    return out


def _far_report(a_deg: float, settings: FusionSettings | None = None, window_px: int = 11, **plate):
    return far_wall_report(mono_forward_rig(MODEL), _near_plate(a_deg, **plate), settings, window_px)


def _angles_deg(a_deg: float, r, **plate) -> tuple[float, float]:
    """(nearest plate corner, the plate's nearest edge) off the far report's direction, deg."""
    u = np.asarray(r.bearing_body, float)  # (the body frame is W's here: no rotation)
    u = u / np.linalg.norm(u)
    P = np.array([(p - O_END) / np.linalg.norm(p - O_END) for p in _near_plate(a_deg, **plate)])
    corner = math.degrees(math.acos(min(1.0, float((P @ u).max()))))
    # the edge between the two corners at tangent offset a: its great circle's angular distance
    n = np.cross(P[0], P[1])
    n /= np.linalg.norm(n)
    edge = math.degrees(math.asin(abs(float(n @ u))))
    return corner, edge


def test_a_far_point_within_the_window_angle_of_a_nearer_tracks_hull_gets_a_sigma_reaching_it():
    r = _far_report(0.6)
    r_far = [float(np.linalg.norm(p - O_END)) for p in FAR]
    assert min(r_far) - 1e-3 <= r.range_m <= max(r_far) + 1e-3  # a far corner's own point
    corner, edge = _angles_deg(0.6, r)
    assert corner > 0.825 + 0.05  # no single plate point inside the window angle
    assert edge < 0.825 - 0.05  # the plate's hull within it
    r_near = [float(np.linalg.norm(p - O_END)) for p in _near_plate(0.6)]
    assert r.range_sigma_m >= r.range_m - float(np.median(r_near)) - 1e-6
    # the widening is the window margin's: the same scene with the window terms off
    r_off = _far_report(0.6, window_px=0)
    assert r_off.range_m == pytest.approx(r.range_m)
    assert r_off.range_sigma_m < 0.1 * (r.range_m - max(r_near))


def test_a_far_point_beyond_the_window_angle_of_the_hull_keeps_its_sigma():
    r = _far_report(1.5)
    _corner, edge = _angles_deg(1.5, r)
    assert edge > 0.825 + 0.05
    r_off = _far_report(1.5, window_px=0)
    assert r.range_m == pytest.approx(r_off.range_m)
    assert r.range_sigma_m == r_off.range_sigma_m < 1.0


def test_a_hull_within_the_window_angle_is_found_when_the_report_lies_outside_the_tracks_cap():
    """The pre-selection by track (the cap about the near points' mean direction) must reach the
    window's angle past it: a plate 2 deg long toward the report and 1.4 deg high, its nearest edge
    0.6 deg off u, its corners' cap (radius hypot(1, 0.7) = 1.22 deg about the plate's middle)
    1.6 deg from u, so u is 0.38 deg outside the cap and 0.6 deg from the hull."""
    plate = {"width_deg": 2.0, "half_deg": 0.7}
    r = _far_report(0.6, **plate)
    corner, edge = _angles_deg(0.6, r, **plate)
    assert corner > 0.825 + 0.05 and edge < 0.825 - 0.05
    u = np.asarray(r.bearing_body, float) / np.linalg.norm(r.bearing_body)
    P = np.array([(p - O_END) / np.linalg.norm(p - O_END) for p in _near_plate(0.6, **plate)])
    c = P.sum(axis=0) / np.linalg.norm(P.sum(axis=0))
    cap = max(math.degrees(math.acos(min(1.0, float(p @ c)))) for p in P)
    assert math.degrees(math.acos(float(u @ c))) > cap + 0.3  # u outside the cap of the plate
    r_near = [float(np.linalg.norm(p - O_END)) for p in _near_plate(0.6, **plate)]
    assert r.range_sigma_m >= r.range_m - float(np.median(r_near)) - 1e-6


@pytest.mark.parametrize("phi_deg", [0.0, 22.5, 45.0, 67.5])
def test_the_hull_is_widened_by_at_least_0_92_window_angles_in_every_direction(phi_deg):
    """The regular octagon about each point (circumradius tan(rho)) widens the hull by at least
    tan(rho) cos(pi / 8) in every direction, 0.762 deg for rho = 0.825 deg: a plate edge 0.72 deg
    off u is within it however the plate is turned about u (a square, inradius 0.71 rho = 0.58 deg,
    would miss it for turns more than 29 deg off its vertices, one of these four turns at least)."""
    plate = {"phi_deg": phi_deg}
    r = _far_report(0.72, **plate)
    corner, edge = _angles_deg(0.72, r, **plate)
    assert corner > 0.825 + 0.05 and edge < 0.762 - 0.02
    r_near = [float(np.linalg.norm(p - O_END)) for p in _near_plate(0.72, **plate)]
    assert r.range_sigma_m >= r.range_m - float(np.median(r_near)) - 1e-6


def test_the_widened_hull_still_needs_occluder_min_members_points():
    """Four plate corners within the window angle's reach, but occluder_min_members 5: no hull."""
    r = _far_report(0.6, FusionSettings(occluder_min_members=5))
    r_near = [float(np.linalg.norm(p - O_END)) for p in _near_plate(0.6)]
    assert r.range_sigma_m < 0.1 * (r.range_m - max(r_near))
