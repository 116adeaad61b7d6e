"""Composite detectors (``orb+navlights``, ``"<keypoints>+<boxes>"``), navlights on small distant
drones, and the BoxTracker's rule that one obstacle found by both detectors is reported once.

Expected values come from the drawn frames (where the lights and the textured patch are put), not
from the code under test."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from estimators.errors import ConfigError
from estimators.rig import mono_forward_rig
from tests.trackers.conftest import Patch, SphereScene, assert_same_feature_tracks, equidistant, rot_axis
from trackers.detectors import Detections, Detector, available_detectors, make_detector
from trackers.detectors.composite import CompositeDetector
from trackers.detectors.orb import OrbDetector
from trackers.features import lens_mask
from trackers.frontend import FrontEnd
from trackers.grouping import BoxTracker, ObstacleTrack

RED, GREEN, WHITE = (0, 0, 255), (0, 255, 0), (255, 255, 255)


def draw_lights(img: np.ndarray, red_uv, green_uv, radius: int = 2, white_uv=None) -> np.ndarray:
    """Draw filled lights (BGR) at integer pixel centres; radius 0 = a single pixel."""
    for uv, col in ((red_uv, RED), (green_uv, GREEN), (white_uv, WHITE)):
        if uv is None:
            continue
        u, v = int(round(uv[0])), int(round(uv[1]))
        if radius == 0:
            img[v, u] = col
        else:
            cv2.circle(img, (u, v), radius, col, -1)
    return img


def textured_bgr(model, seed: int = 1) -> np.ndarray:
    return cv2.cvtColor(SphereScene(model, seed=seed).render(), cv2.COLOR_GRAY2BGR)


# ------------------------------------------------------------------------------- the composite
def test_orb_navlights_is_registered_and_returns_keypoints_and_a_box():
    model = equidistant()
    img = draw_lights(textured_bgr(model), (170, 120), (150, 120), radius=3)
    assert "orb+navlights" in available_detectors()
    det = make_detector("orb+navlights")
    assert det.produces_keypoints and det.produces_boxes and det.name == "orb+navlights"
    d = det.detect(img, lens_mask(model))
    assert len(d) >= 50 and d.descriptors is not None and d.descriptors.shape == (len(d), 32)
    assert len(d.boxes) == 1 and d.labels == ("drone",)
    x1, y1, x2, y2 = d.boxes[0]
    assert x1 <= 150 and x2 >= 170 and y1 <= 120 <= y2
    # the keypoint part is the ORB detector itself (the FeatureTracker runs it as ORB alone)
    assert isinstance(det.keypoint_part, OrbDetector)
    assert len(det.detect_boxes(img, lens_mask(model)).boxes) == 1


def test_any_keypoint_and_box_detector_combine_by_name():
    det = make_detector("orb+navlights", navlights={"min_value": 200}, orb={"max_features": 100})
    assert det.box_part.min_value == 200 and det.keypoint_part.max_features == 100
    class Boxes(Detector):
        produces_keypoints, produces_boxes = False, True

        def detect(self, image, mask=None):
            return Detections(boxes=np.array([[1.0, 2.0, 3.0, 4.0]]), labels=("thing",))

    c = CompositeDetector(OrbDetector(max_features=50), Boxes())
    img = SphereScene(equidistant()).render()
    d = c.detect(img)
    assert len(d) > 0 and d.labels == ("thing",)


@pytest.mark.parametrize(
    "name,opts,match",
    [
        ("orb+navlights", {"bogus": {}}, "bogus"),
        ("orb+navlights", {"navlights": {"nosuch": 1}}, "nosuch"),
        ("orb+navlights", {"navlights": {"min_value": 300}}, "min_value"),
        ("orb+navlights", {"navlights": 3}, "mapping"),
        ("orb+navlights", {"navlights": {"min_area_px": 0}}, "min_area_px"),
        ("orb+navlights", {"navlights": {"require_white": 1}}, "require_white"),
        ("navlights+orb", {}, "gives no keypoints"),
        ("orb+orb", {}, "two different"),
        ("orb+nosuch", {}, "unknown detector"),
        ("orb+", {}, "expected '<keypoint detector>\\+<box detector>'"),
        ("+navlights", {}, "two names, one"),
        ("orb+navlights+kornia", {}, "two names, one"),
        ("orb+navlights", {"orb": {"max_features": 0}}, "max_features"),
    ],
)
def test_bad_composite_options_are_config_errors(name, opts, match):
    with pytest.raises(ConfigError, match=match):
        make_detector(name, **opts)


def test_composite_on_a_grey_frame_gives_keypoints_only():
    model = equidistant()
    grey = SphereScene(model).render()
    d = make_detector("orb+navlights").detect(grey, lens_mask(model))
    assert len(d) >= 50 and len(d.boxes) == 0


def test_front_end_feature_tracks_are_those_of_orb_alone():
    """Without lights the composite's front end reports what ORB's does, track for track (same ids,
    bearings, members, label ``orb``)."""
    model = equidistant()
    rig = mono_forward_rig(model)
    scene = SphereScene(model, blank_env=True)
    a, b = FrontEnd(rig, detector="orb"), FrontEnd(rig, detector="orb+navlights")
    for k in range(10):
        p = [Patch(rot_axis([0, 1, 0], np.radians(0.6) * k) @ np.array([0.3, 0.0, 1.0]), np.radians(18))]
        g = scene.render(np.eye(3), p)
        oa = a.process({"cam0": g}, k, k / 30)
        ob = b.process({"cam0": cv2.cvtColor(g, cv2.COLOR_GRAY2BGR)}, k, k / 30)
        assert_same_feature_tracks(oa, ob)
    assert any(o.status == "confirmed" for o in oa)


# -------------------------------------------------------------- one obstacle, reported once
def _patch_sequence(model, n: int, lights_on_patch: bool, light_offset_rad: float = 0.0,
                    radius_rad: float = np.radians(16), half_span_px: float = 4.0):
    """BGR frames of a textured patch (angular radius ``radius_rad``) moving on a blank environment,
    lights ``2 half_span_px`` apart drawn on it (or ``light_offset_rad`` away), and the patch centre's
    direction per frame."""
    scene = SphereScene(model, blank_env=True)
    out = []
    for k in range(n):
        d = rot_axis([0, 1, 0], np.radians(0.6) * k) @ np.array([0.25, 0.05, 1.0])
        d = d / np.linalg.norm(d)
        img = cv2.cvtColor(scene.render(np.eye(3), [Patch(d, radius_rad, seed=3)]), cv2.COLOR_GRAY2BGR)
        dl = rot_axis([0, 1, 0], light_offset_rad) @ d
        uv, _ = model.bearing_to_pixel(dl[None])
        u, v = uv[0]
        if lights_on_patch or light_offset_rad:
            draw_lights(img, (u + half_span_px, v), (u - half_span_px, v), radius=1)
        out.append((img, d))
    return out


def _reports_on(obs, d_C: np.ndarray, radius_rad: float):
    return [
        o for o in obs
        if o.status != "lost" and any(np.arccos(np.clip(v.b_C @ d_C, -1, 1)) < radius_rad for v in o.views)
    ]


def test_a_textured_drone_with_lights_is_reported_once_with_the_box_label():
    """A textured patch of a drone's size with lights at its wingtips (the feature track lies on the
    box): one report, the feature track's (2 without the link: ``boxes={"link_s": 100 / 30}``)."""
    model = equidistant()
    counts = {}
    for frames in (3, 100):
        fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights", boxes={"link_s": frames / 30})
        counts[frames] = []
        seq = _patch_sequence(model, 14, True, radius_rad=np.radians(9), half_span_px=9.0)
        for k, (img, d) in enumerate(seq):
            on = _reports_on(fe.process({"cam0": img}, k, k / 30), d, np.radians(9))
            counts[frames].append(len(on))
            if frames == 3:
                last = on
    assert counts[3][-4:] == [1, 1, 1, 1] and counts[100][-4:] == [2, 2, 2, 2], counts
    assert last[0].label == "orb" and last[0].attributes.get("box_label") == "drone"
    assert last[0].attributes.get("heading") == "towards"  # green drawn left of red
    assert len(last[0].views[0].feature_ids) >= 3


@pytest.mark.parametrize("offset_deg", [25.0, 9.0])
def test_lights_off_a_feature_track_keep_their_own_report(offset_deg):
    """Lights 25 deg beside the 16 deg patch (a drone beside an obstacle), or 9 deg off its centre
    (inside it, off its bearing: not linked, see BoxTracker) keep their own drone report."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    seq = _patch_sequence(model, 12, False, light_offset_rad=np.radians(offset_deg))
    for k, (img, d_k) in enumerate(seq):
        obs, d = fe.process({"cam0": img}, k, k / 30), d_k
    drones = [o for o in obs if o.status != "lost" and o.label == "drone"]
    feats = [o for o in _reports_on(obs, d, np.radians(16)) if o.label == "orb"]
    assert len(drones) == 1 and len(feats) >= 1 and all("box_label" not in o.attributes for o in feats)


def _ft(tid, b_members: np.ndarray) -> ObstacleTrack:
    b = b_members.mean(axis=0)
    return ObstacleTrack(tid, "cam0", np.arange(len(b_members)) + 100 * tid, b / np.linalg.norm(b),
                         member_b_C=b_members)


def test_box_tracker_links_only_a_feature_track_on_the_box_that_moves_with_it():
    model = equidistant()
    cam = mono_forward_rig(model).cameras[0]
    rad_px = model.max_angle_rad / model.image_circle()[2]
    bt = BoxTracker(iter(range(1, 100)))
    for k in range(6):
        u0 = 160.0 + 2 * k  # the box moves 2 px a frame
        det = Detections(boxes=np.array([[u0 - 4, 116.0, u0 + 4, 124.0]]), labels=("drone",),
                         attributes=({"heading": "away"},))
        on, _ = model.pixel_to_bearing(np.array([[u0 - 2, 119.0], [u0 + 2, 121.0], [u0, 120.0]]))
        below, _ = model.pixel_to_bearing(np.array([[u0 - 3, 140.0], [u0 + 3, 141.0], [u0, 139.0]]))
        still, _ = model.pixel_to_bearing(np.array([[158.0, 119.0], [162.0, 121.0], [160.0, 120.0]]))
        f_on, f_below, f_still = _ft(7, on), _ft(8, below), _ft(9, still)
        seen, _ = bt.update(cam, det, [f_below, f_on] if k < 5 else [f_below, f_still], t_s=k / 30)
        if k < 3:  # not yet link_s (3 frames at 30 fps) together: the box is reported
            assert len(seen) == 1 and "box_label" not in f_on.attributes
        elif k < 5:  # linked to the track on the box that moves with it; the ground below is not
            assert seen == [] and bt.links == {1: 7}
            assert f_on.attributes["box_label"] == "drone" and f_on.attributes["heading"] == "away"
            assert "box_label" not in f_below.attributes
        else:  # a track on the box that does not move with it (it stays at u = 160) is not linked
            assert len(seen) == 1 and bt.links == {} and "box_label" not in f_still.attributes
    assert rad_px > 0


def test_box_tracker_does_not_link_a_track_on_the_box_that_stays_still():
    """The motion rule alone: a feature track that sits on the box in every frame (u = 164 +- 2, the
    box's centre goes 160 -> 170 at 2 px a frame, so the track stays within its radius of ~6 + 3 px)
    but does not move with it (4 px apart over link_frames 3 frames, link_tol_px 2) is never linked:
    a drone passing in front of a textured obstacle must not be hidden behind that obstacle's track."""
    model = equidistant()
    cam = mono_forward_rig(model).cameras[0]
    bt = BoxTracker(iter(range(1, 100)))
    for k in range(6):
        u0 = 160.0 + 2 * k
        det = Detections(boxes=np.array([[u0 - 4, 116.0, u0 + 4, 124.0]]), labels=("drone",),
                         attributes=({"heading": "away"},))
        still, _ = model.pixel_to_bearing(np.array([[162.0, 119.0], [166.0, 121.0], [164.0, 120.0]]))
        f_still = _ft(9, still)
        seen, _ = bt.update(cam, det, [f_still], t_s=k / 30)
        assert len(seen) == 1 and bt.links == {} and "box_label" not in f_still.attributes


@pytest.mark.parametrize("opts", [{"link_s": -0.1}, {"link_tol_px": -1.0}, {"confirm_s": "0.1"},
                                  {"max_missed_s": float("nan")}, {"link_min_members": True}])
def test_box_tracker_bad_options_are_config_errors(opts):
    with pytest.raises(ConfigError):
        BoxTracker(iter(range(5)), **opts)


# ------------------------------------------------------------- navlights on a distant drone
def sky(size=(240, 320)) -> np.ndarray:
    """A bright, slightly blue sky (HSV V ~238, S ~53 as the simulator's horizon sky)."""
    return np.full(size + (3,), (238, 200, 188), np.uint8)


def test_navlights_finds_one_pixel_lights_without_the_white_one():
    """A drone 40 m away: its lights are single pixels 3-4 px apart, its white light merged into the
    dark body (tuned scene moving_headon). The old defaults (2 px blobs, white required) saw none."""
    img = sky()
    img[119:121, 157:163] = (40, 40, 40)  # the dark body
    draw_lights(img, (163, 120), (157, 120), radius=0)
    d = make_detector("navlights").detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["heading"] == "towards"
    assert d.attributes[0]["white_uv"] is None and d.box_scores[0] < 1.0
    x1, y1, x2, y2 = d.boxes[0]
    assert x1 <= 157 and x2 >= 163 and y1 <= 120 <= y2
    assert len(make_detector("navlights", require_white=True).detect(img).boxes) == 0
    # with the white light between them the score is 1
    draw_lights(img, (163, 120), (157, 120), radius=0, white_uv=(160, 119))
    d = make_detector("navlights").detect(img)
    assert d.box_scores[0] == 1.0 and d.attributes[0]["white_uv"] == [160.0, 119.0]


def test_navlights_a_lone_light_and_a_coloured_surface():
    """A drone seen from the side shows one wingtip light: a box without heading. A bright green
    surface cut into pieces by noise is not a light."""
    img = sky()
    draw_lights(img, None, (100, 60), radius=1)
    d = make_detector("navlights").detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["heading"] is None and d.box_scores[0] < 0.5
    assert len(make_detector("navlights", single_lights=False).detect(img).boxes) == 0
    rng = np.random.default_rng(3)
    surf = sky()
    hsv = np.zeros((60, 60, 3), np.uint8)
    hsv[..., 0] = 75
    hsv[..., 1] = rng.integers(100, 190, (60, 60))
    hsv[..., 2] = rng.integers(150, 220, (60, 60))
    surf[90:150, 130:190] = cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)
    assert len(make_detector("navlights").detect(surf).boxes) == 0


def test_navlights_takes_a_bool_mask_as_a_uint8_one():
    """A lens mask given as bool (or 0/1) finds the same lights as the 0/255 uint8 one, and a mask
    that hides the lights finds none (before: cv2.error on a bool mask)."""
    img = sky()
    img[119:121, 157:163] = (40, 40, 40)
    draw_lights(img, (163, 120), (157, 120), radius=0)
    det = make_detector("navlights")
    on = np.zeros(img.shape[:2], np.uint8)
    on[100:140, 140:180] = 255
    want = det.detect(img, on).boxes
    assert len(want) == 1
    np.testing.assert_array_equal(make_detector("navlights").detect(img, on > 0).boxes, want)
    off = np.ones(img.shape[:2], bool)
    off[100:140, 140:180] = False
    assert len(make_detector("navlights").detect(img, off).boxes) == 0
