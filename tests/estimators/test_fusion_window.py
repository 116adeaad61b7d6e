"""On any rig, a report whose direction has, inside the tracked window's angle, a member point
at another depth gets a range sigma that reaches that depth (``ObstacleFusion._window_neighbours``).

Truth by hand: a mono rig (camera at the body origin, 0.15 deg per px: 382 px per rad, so the
angle of an 11-px window's half-width is 5.5 / 382 = 0.0144 rad = 0.83 deg) flies along +x at
5 m/s for 20 frames at 30 fps, so the body ends at o = (19 / 6, 0, 0). Track 2: three corners of
a far wall at (20 + 0.05 i, 6, 0.05 i), i = -1, 0, 1 (17.9-18.0 m from o, within 0.2 deg of each
other). Track 1: three corners of a near plate halfway along o's ray toward the far wall's middle
corner, the first of them turned 0.4 deg off that ray (inside every far corner's window angle)
or 3 deg off (outside it), the others 0.3 m beyond it in that direction (~9 m from o; the plate
does not surround the far corners' directions: ``_occluded_by_members`` leaves them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.errors import InputError
from estimators.fusion import FusionSettings, ObstacleFusion
from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.estimators.fusion_helpers import WALL_FAR, WALL_O_END, WALL_SPEED, far_wall_report

MODEL = Equidistant.from_deg_per_px(0.15, 1280, 1280)
SPEED = WALL_SPEED
FAR = WALL_FAR
O_END = WALL_O_END


def _near_plate(off_deg: float) -> list[np.ndarray]:
    """The near plate's corners: halfway along o_end's ray toward FAR[1], turned off_deg about x."""
    d = FAR[1] - O_END
    half = 0.5 * float(np.linalg.norm(d))
    u = d / np.linalg.norm(d)
    w = np.cross(u, [1.0, 0.0, 0.0])
    w /= np.linalg.norm(w)
    a = math.radians(off_deg)
    p0 = O_END + half * (math.cos(a) * u + math.sin(a) * w)
    v = np.cross(u, w)
    return [p0, p0 + 0.3 * w, p0 + 0.3 * w + 0.3 * v]  # (away from the far corners: not around them)


def _far_report(off_deg: float, settings: FusionSettings | None = None, window_px: int = 11):
    return far_wall_report(mono_forward_rig(MODEL), _near_plate(off_deg), settings, window_px)


def test_a_member_point_at_another_depth_inside_the_window_angle_widens_the_sigma():
    r = _far_report(0.4)
    r_far = [float(np.linalg.norm(p - O_END)) for p in FAR]
    assert min(r_far) - 1e-3 <= r.range_m <= max(r_far) + 1e-3  # a far corner's own point
    r_near = max(float(np.linalg.norm(p - O_END)) for p in _near_plate(0.4))  # ~9 m
    assert r.range_sigma_m >= 0.95 * (r.range_m - r_near)
    # the same scene without the term: the far point's own sigma
    r_off = _far_report(0.4, window_px=0)
    assert r_off.range_m == pytest.approx(r.range_m)
    assert r_off.range_sigma_m < 0.1 * (r.range_m - r_near)


def test_a_member_point_outside_the_window_angle_leaves_the_sigma():
    r = _far_report(3.0)
    r_off = _far_report(3.0, window_px=0)
    assert r.range_m == pytest.approx(r_off.range_m)
    assert r.range_sigma_m == r_off.range_sigma_m < 1.0


def _fusion(model, scale: float | None = None, window_px=11) -> ObstacleFusion:
    return ObstacleFusion(mono_forward_rig(model), ConstantVelocity(SPEED),
                          pixel_scale=None if scale is None else {"cam0": scale},
                          window_px=None if window_px is None else {"cam0": window_px})


def test_the_window_angle_follows_the_rig_focal_length():
    # the same 11 px (half-width 5.5 px) on a lens of half the pixels per radian is twice the angle
    fus = _fusion(MODEL)
    coarse = _fusion(Equidistant.from_deg_per_px(0.30, 640, 640))
    assert fus._window_rad == pytest.approx(5.5 * math.radians(0.15))
    assert coarse._window_rad == pytest.approx(2.0 * fus._window_rad)
    # a 7-px window: half-width 3.5 px; no window given: no window term
    assert _fusion(MODEL, window_px=7)._window_rad == pytest.approx(3.5 * math.radians(0.15))
    assert _fusion(MODEL, window_px=None)._window_rad == 0.0


def test_on_a_rig_of_two_windows_the_widest_angle_is_taken():
    """cam0 0.15 deg per px with an 11-px window (5.5 x 0.15 = 0.825 deg half-width), cam1 0.30 deg
    per px with a 5-px window (2.5 x 0.30 = 0.75 deg): 0.825 deg; cam1 at 7 px: 3.5 x 0.30 = 1.05."""
    rig = stereo_forward_rig(MODEL, 0.30, model_right=Equidistant.from_deg_per_px(0.30, 640, 640))
    a, b = rig.names
    fus = ObstacleFusion(rig, ConstantVelocity(SPEED), window_px={a: 11, b: 5})
    assert fus._window_rad == pytest.approx(math.radians(0.825))
    fus = ObstacleFusion(rig, ConstantVelocity(SPEED), window_px={a: 11, b: 7})
    assert fus._window_rad == pytest.approx(math.radians(1.05))


def test_a_frame_tracked_downscaled_takes_the_angle_of_its_tracked_pixels():
    """A 1920-px-wide lens of 0.10 deg per px tracked downscaled to 1280 px (the front end's
    max_width: pixel_scale 2/3) tracks 0.15 deg pixels: the 11-px window's 5.5-px half-width is
    5.5 x 0.15 deg, as on MODEL, not 5.5 x 0.10 deg (the full frame's pixels)."""
    wide = Equidistant.from_deg_per_px(0.10, 1920, 1920)
    full = _fusion(wide)
    tracked = _fusion(wide, 1280 / 1920)
    assert full._window_rad == pytest.approx(5.5 * math.radians(0.10))
    assert tracked._window_rad == pytest.approx(5.5 * math.radians(0.15))
    # the feature sigma's pixel part likewise: a 2560-px lens of 0.15 deg per px tracked at half
    # scale has 0.30 deg pixels, as a 1280-px lens of 0.30 deg per px (coarser than the reference
    # focal length 204.5 px/rad: sigma x 204.5 / (1 / 0.30 deg))
    coarse = _fusion(Equidistant.from_deg_per_px(0.30, 1280, 1280))
    halved = _fusion(Equidistant.from_deg_per_px(0.15, 2560, 2560), 0.5)
    s0 = FusionSettings().feature_sigma_rad
    want = s0 * FusionSettings().feature_sigma_focal_px * math.radians(0.30)
    assert coarse.settings.feature_sigma_rad == pytest.approx(want)
    assert halved.settings.feature_sigma_rad == pytest.approx(want)
    assert halved._window_rad == pytest.approx(coarse._window_rad)


@pytest.mark.parametrize("bad", [0.0, -0.5, 1.5, float("nan"), "half", None, True, np.True_, "0.5"])
def test_a_pixel_scale_outside_0_1_is_refused(bad):
    with pytest.raises(InputError, match=r"pixel_scale\['cam0'\].*\(0, 1\]"):
        ObstacleFusion(mono_forward_rig(MODEL), ConstantVelocity(SPEED), pixel_scale={"cam0": bad})


@pytest.mark.parametrize("bad", [0, -5, float("nan"), float("inf"), "eleven", None, True, np.True_, "11"])
def test_a_window_that_is_not_a_positive_width_is_refused(bad):
    # (a bool is no width: True would be a 1-px window; a string is not a number, as the tracker's
    # win_px refuses "11")
    with pytest.raises(InputError, match=r"window_px\['cam0'\].*> 0, got"):
        ObstacleFusion(mono_forward_rig(MODEL), ConstantVelocity(SPEED), window_px={"cam0": bad})


def test_numpy_numbers_are_widths_and_scales():
    fus = ObstacleFusion(mono_forward_rig(MODEL), ConstantVelocity(SPEED),
                         pixel_scale={"cam0": np.float32(1.0)}, window_px={"cam0": np.int64(11)})
    assert fus._window_rad == pytest.approx(5.5 * math.radians(0.15))


@pytest.mark.parametrize("keyword", ["pixel_scale", "window_px"])
def test_a_camera_the_rig_does_not_have_is_refused(keyword):
    """A misspelt camera name would leave that camera at no window (or the full frame's scale)
    without a word: refused, naming the rig's cameras; so is a value that is not a mapping."""
    rig = stereo_forward_rig(MODEL, 0.30)
    good = {"pixel_scale": 0.5, "window_px": 11}[keyword]
    with pytest.raises(InputError, match=rf"{keyword}\['cam2'\]: not a camera of the rig.*cam0, cam1"):
        ObstacleFusion(rig, ConstantVelocity(SPEED), **{keyword: {"cam0": good, "cam2": good}})
    with pytest.raises(InputError, match=rf"{keyword}: expected a mapping camera name -> number"):
        ObstacleFusion(rig, ConstantVelocity(SPEED), **{keyword: good})


def _far_report_stereo(off_deg: float, settings: FusionSettings | None = None, window_px: int = 11):
    """The scene above seen by a stereo rig (baseline 0.3 m, cam0 at y = +0.15 m): both tracks in
    both cameras, every ray exact."""
    return far_wall_report(stereo_forward_rig(MODEL, 0.30), _near_plate(off_deg), settings, window_px)


def test_on_a_stereo_rig_a_member_point_inside_the_window_angle_widens_the_sigma_too():
    # (the occlusion term off: from the body origin between the two cameras the plate's corners
    # enclose the far corner's direction, and that term alone would reach the plate's depth)
    on = FusionSettings(occluder_min_members=0)
    r = _far_report_stereo(0.4, on)
    r_far = [float(np.linalg.norm(p - O_END)) for p in FAR]
    assert r.range_m is not None and "mono" in r.source  # the static-point fix
    assert min(r_far) - 1e-3 <= r.range_m <= max(r_far) + 1e-3
    r_near = max(float(np.linalg.norm(p - O_END)) for p in _near_plate(0.4))
    assert r.range_sigma_m >= 0.95 * (r.range_m - r_near)
    r_off = _far_report_stereo(0.4, on, window_px=0)
    assert r_off.range_m == pytest.approx(r.range_m)
    assert r_off.range_sigma_m < 0.1 * (r.range_m - r_near)
    # outside the window angle: nothing
    r3, r3_off = _far_report_stereo(3.0, on), _far_report_stereo(3.0, on, window_px=0)
    assert r3.range_sigma_m == r3_off.range_sigma_m < 1.0
