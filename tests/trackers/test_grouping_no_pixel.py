"""A track whose representative bearing does not project (issue 4): the representative moves on with
its members, so as an obstacle leaves the lens's field its centre goes beyond the field while some
members are still seen. Such a track has no pixel: ``ObstacleTrack.uv`` and the reported
``CameraView.uv`` are None (not (0, 0), the image's corner), and the front end does not densify
around it. Truth: the equidistant model's closed form r = f theta about (cx, cy), worked here, and
the angles the points and discs are placed at."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.rig import mono_forward_rig
from tests.trackers.conftest import Patch, SphereScene, equidistant, rot_axis
from tests.trackers.test_grouping import PointFeatures, unit
from trackers.detectors import Detections
from trackers.frontend import FrontEnd
from trackers.grouping import BoxTracker, ObstacleGrouper, ObstacleTrack


def closed_form_pixel(model, b: np.ndarray) -> np.ndarray:
    """Equidistant projection by hand: u = cx + f theta x / rho, v = cy + f theta y / rho."""
    theta = np.arccos(np.clip(b[2], -1.0, 1.0))
    rho = np.hypot(b[0], b[1])
    return np.array([model.cx + model.fx * theta * b[0] / rho, model.cy + model.fy * theta * b[1] / rho])


def off_axis(b: np.ndarray) -> float:
    return float(np.arccos(np.clip(b[2], -1.0, 1.0)))


def pixel_checked(model, b: np.ndarray, uv, half: float, where: str) -> bool:
    """Check a representative's pixel: None beyond the lens's field (``half`` rad off-axis), else
    the closed-form pixel of its bearing. True when ``b`` is beyond the field."""
    if off_axis(b) > half:
        assert uv is None, f"{where}: representative {np.degrees(off_axis(b)):.2f} deg off-axis, uv {uv}"
        return True
    np.testing.assert_allclose(uv, closed_form_pixel(model, b), atol=1e-6)
    return False


def test_a_representative_beyond_the_lens_field_has_no_pixel():
    """A 120 deg lens (field 60 deg off-axis); a 4 x 4 grid of points 6 px apart centred 50 deg off
    the axis drifts outwards at 0.4 deg per frame, each point dropped once it is beyond the field.
    From ~frame 26 the grid's centre (the track's representative) is beyond 60 deg while points
    are still seen: uv is None in exactly those frames, the closed-form pixel in the others, and
    None again once the track coasts with no member left."""
    model = equidistant(fov_deg=120.0)
    half = model.max_angle_rad
    gr = ObstacleGrouper(iter(range(1, 1000)), confirm_s=0.1)
    ft = PointFeatures(model)
    step = 6.0 * half / model.image_circle()[2]
    a = np.radians(50.0)
    c0, e2 = np.array([np.sin(a), 0, np.cos(a)]), np.array([0, 1.0, 0])
    e1 = np.array([np.cos(a), 0, -np.sin(a)])  # outwards, tangent at c0
    base = {
        k: unit(c0 + (x - 1.5) * step * e1 + (y - 1.5) * step * e2)
        for k, (x, y) in enumerate([(x, y) for x in range(4) for y in range(4)])
    }
    beyond = within = 0
    tid = None
    for k in range(40):
        R = rot_axis([0, 1, 0], np.radians(0.4) * k)
        pts = {i: R @ b for i, b in base.items()}
        keep = [i for i, b in pts.items() if off_axis(b) < half]
        ft.set(keep, np.array([pts[i] for i in keep]).reshape(-1, 3), k / 30.0)
        seen, _ = gr.update(ft, k / 30.0)
        assert len(seen) <= 1
        for tr in seen:
            tid = tr.id if tid is None else tid
            assert tr.id == tid
            if pixel_checked(model, tr.b_C, tr.uv, half, f"frame {k}"):
                beyond += 1
            else:
                within += 1
    assert beyond >= 5 and within >= 20, (beyond, within)
    # every point gone: the track coasts on a predicted bearing and has no pixel
    ft.set([], np.zeros((0, 3)), 40 / 30.0)
    seen, _ = gr.update(ft, 40 / 30.0)
    assert not seen and tid in gr.tracks and gr.tracks[tid].uv is None


@pytest.mark.parametrize("size, max_width", [((320, 240), None), ((640, 480), 320)])
def test_no_densify_and_no_pixel_for_a_view_beyond_the_lens_field(size, max_width):
    """Rendered: the tests' 200 deg lens (field 100 deg off-axis), a textured disc of 8 deg radius
    drifting outwards from 88 deg off-axis at 0.5 deg per frame across the lens's rim. The track on
    it is still seen (2-3 features) when its representative is beyond 100 deg: that view's uv is
    None; every other view's uv is the closed-form pixel of its bearing (full-frame pixels, also
    when a 640 x 480 lens is tracked downscaled to 320 px); densify is asked only for the pixels
    of seen tracks' representatives, never for the image's corner."""
    model = equidistant(*size)
    half = model.max_angle_rad
    scene = SphereScene(model, blank_env=True)
    fe = FrontEnd(mono_forward_rig(model), max_width=max_width)
    ft = fe.trackers["cam0"]
    f = fe.scale["cam0"]
    asked: list[np.ndarray] = []
    densify = ft.densify

    def spy(image, centres_uv, radii_px, frame, t_s, *a, **k):
        asked.extend((np.asarray(centres_uv, float) + 0.5) / f - 0.5)  # full-frame pixels
        return densify(image, centres_uv, radii_px, frame, t_s, *a, **k)

    ft.densify = spy
    r, th0 = np.radians(8.0), half - np.radians(12.0)
    beyond = within = 0
    shown: list[np.ndarray] = []
    for k in range(36):
        th = th0 + np.radians(0.5) * k
        img = scene.render(None, [Patch(np.array([np.sin(th), 0.0, np.cos(th)]), r, seed=3)])
        for o in fe.process({"cam0": img}, k, k / 30.0):
            for v in o.views:
                if pixel_checked(model, v.b_C, v.uv, half, f"frame {k}"):
                    beyond += 1
                else:
                    within += 1
                    shown.append(v.uv)
    assert beyond >= 3 and within >= 20, (beyond, within)
    assert asked, "densify was never asked"
    cx, cy, rad = model.image_circle()
    for c in asked:
        assert np.hypot(c[0] - cx, c[1] - cy) <= rad, f"densify asked outside the lens circle: {c}"
        assert min(np.abs(c - s).max() for s in shown) < 1e-6, f"densify centre {c} is no seen track's pixel"


@pytest.mark.parametrize("how", ["no features", "coast", "box"])
def test_an_unseen_track_has_no_pixel(how):
    """A track seen near the axis (uv its closed-form pixel) and then unseen for a frame has no pixel
    (uv None, not the stale one of the frame before), on each path an unseen track takes: the
    grouper's update with none of its members left, the grouper's coast (a frame without usable
    features) and a box tracker's frame without its box."""
    model = equidistant(fov_deg=120.0)
    if how == "box":
        cam = mono_forward_rig(model).cameras[0]
        bt = BoxTracker(iter(range(1, 100)))
        u0, v0 = model.cx + 20.0, model.cy - 10.0
        box = Detections(boxes=np.array([[u0 - 4, v0 - 4, u0 + 4, v0 + 4]]), labels=("drone",),
                         attributes=({},))
        for k in range(3):
            (tr,), _ = bt.update(cam, box, t_s=k / 30)
        np.testing.assert_allclose(tr.uv, [u0, v0], atol=1e-9)  # the box's centre, a pixel
        seen, _ = bt.update(cam, Detections(), t_s=0.1)
        assert not seen and not tr.seen and tr.uv is None
        return
    gr = ObstacleGrouper(iter(range(1, 1000)), confirm_s=0.1)
    ft = PointFeatures(model)
    a = np.radians(10.0)
    c0 = np.array([np.sin(a), 0, np.cos(a)])
    e1, e2 = np.array([np.cos(a), 0, -np.sin(a)]), np.array([0, 1.0, 0])
    step = np.radians(0.5)
    grid = [(x - 1.5, y - 1.5) for x in range(4) for y in range(4)]
    pts = np.array([unit(c0 + x * step * e1 + y * step * e2) for x, y in grid])
    for k in range(6):
        ft.set(range(16), pts, k / 30.0)
        seen, _ = gr.update(ft, k / 30.0)
    (tr,) = seen
    np.testing.assert_allclose(tr.uv, closed_form_pixel(model, tr.b_C), atol=1e-6)
    if how == "coast":
        gr.coast(6 / 30.0)
    else:
        ft.set([], np.zeros((0, 3)), 6 / 30.0)
        seen, _ = gr.update(ft, 6 / 30.0)
        assert not seen
    assert tr.id in gr.tracks and not tr.seen and tr.uv is None


def test_unseen_leaves_a_track_without_view_members_or_pixel():
    """``ObstacleTrack.unseen``, the one way every path (coasting, lost by takeover, by extended
    texture, by misses; box tracks too) leaves a track with no view this frame."""
    tr = ObstacleTrack(7, "cam0", np.array([3, 4], np.int64), unit([0.0, 0.0, 1.0]),
                       uv=np.array([320.0, 240.0]))
    tr.member_b_C = np.array([unit([0.01, 0.0, 1.0]), unit([0.0, 0.01, 1.0])])
    tr.unseen()
    assert tr.seen is False and tr.uv is None
    assert tr.members.shape == (0,) and tr.member_b_C.shape == (0, 3)
    with pytest.raises(ValueError):  # the shared empties cannot be written through
        tr.member_b_C[...] = 0.0
