"""Cross-camera association of box tracks (navlights drones, box detectors): a box of each camera
on one obstacle is ONE observation with two views; boxes off each other's epipolar plane stay two.

Expected values come from where the boxes are put (the projection of chosen body-frame points
through each camera's mount and lens), not from the code under test."""

from __future__ import annotations

import numpy as np

from estimators.rig import stereo_forward_rig
from tests.trackers.conftest import blocky_texture, equidistant
from trackers.association import BoxStereo, box_pairs, boxes_compatible
from trackers.detectors import Detections, Detector
from trackers.frontend import FrontEnd


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class QueuedBoxes(Detector):
    """A box detector that returns queued boxes in call order (the front end asks cam0, then cam1)."""

    produces_keypoints, produces_boxes = False, True
    name = "queued"

    def __init__(self, queue: list[list[tuple[float, float]]], half_px: float = 3.0) -> None:
        self.queue, self.half_px = list(queue), half_px

    def detect(self, image, mask=None):
        centres = self.queue.pop(0)
        h = self.half_px
        if not centres:
            return Detections.empty()
        boxes = np.array([[u - h, v - h, u + h, v + h] for u, v in centres])
        return Detections(boxes=boxes, labels=("drone",) * len(boxes),
                          attributes=tuple({"heading": None} for _ in centres))


def _pixel(cam, p_B):
    """Pixel of body point p_B (3,) m in camera ``cam`` (its mount, then its lens)."""
    p_C = cam.T_C_B.apply(np.asarray(p_B, float))
    uv, ok = cam.model.bearing_to_pixel(unit(p_C)[None])
    assert ok[0]
    return tuple(float(x) for x in uv[0])


def _run(rig, p0_B, p1_B, frames=6):
    """Observations of each frame: cam0's box at the image of p0_B, cam1's at the image of p1_B."""
    c0, c1 = rig.cameras
    queue = [q for _ in range(frames) for q in ([_pixel(c0, p0_B)], [_pixel(c1, p1_B)])]
    fe = FrontEnd(rig, QueuedBoxes(queue))
    w, h = c0.model.width, c0.model.height
    img = blocky_texture(max(w, h), 24, seed=3)[:h, :w]
    return [fe.process({"cam0": img, "cam1": img}, f, f / 30.0) for f in range(frames)]


def test_one_drone_boxed_in_both_cameras_is_one_observation_with_two_views():
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    p_B = np.array([4.0, 0.5, -0.3])  # 4 m ahead (body x forward), between the cameras' rays
    out = _run(rig, p_B, p_B)
    last = [o for o in out[-1] if o.status != "lost"]
    assert len(last) == 1
    assert [v.camera for v in last[0].views] == ["cam0", "cam1"]
    assert all(len(v.feature_ids) == 0 for v in last[0].views)  # box tracks: no member features
    # the views' bearings are the two cameras' own bearings of the point
    for v, cam in zip(last[0].views, rig.cameras, strict=True):
        assert np.degrees(np.arccos(np.clip(v.b_C @ unit(cam.T_C_B.apply(p_B)), -1, 1))) < 0.5
    # reported twice in the first frame at most (the link needs 2 frames in a row), then once
    assert all(len([o for o in obs if o.status != "lost"]) == 1 for obs in out[1:])


def test_boxes_off_each_others_epipolar_plane_stay_two_observations():
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    p_B = np.array([4.0, 0.5, -0.3])
    # cam1's box 0.8 m higher (body z: off the plane through the horizontal baseline), ~11 deg
    out = _run(rig, p_B, p_B + [0.0, 0.0, 0.8])
    for obs in out:
        live = [o for o in obs if o.status != "lost"]
        assert len(live) == 2 and all(len(o.views) == 1 for o in live)


def test_box_pairs_epipolar_tolerance_ahead_and_ambiguity():
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    c0, c1 = rig.cameras
    T = c1.T_C_B @ c0.T_C_B.inverse()  # T_C1_C0
    p = np.array([5.0, 0.2, 0.1])  # body
    b0 = unit(c0.T_C_B.apply(p))[None]
    b1 = unit(c1.T_C_B.apply(p))[None]
    half = np.radians([0.5])
    i0, i1 = box_pairs(b0, half, b1, half, T.R, T.t)
    assert i0.tolist() == [0] and i1.tolist() == [0]
    # 2 deg off the epipolar plane (a vertical tilt of b1 for a horizontal baseline): out with a
    # 0.5 deg box, in with a 3 deg one
    a = np.radians(2.0)
    c, s = np.cos(a), np.sin(a)
    lift = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])  # about camera x (image rows move)
    b1_off = b1 @ lift.T
    assert len(box_pairs(b0, half, b1_off, half, T.R, T.t)[0]) == 0
    assert len(box_pairs(b0, np.radians([3.0]), b1_off, half, T.R, T.t)[0]) == 1
    # rays in the baseline's plane (epipolar-consistent) that diverge: cam0 (left, body y +0.15)
    # looking 31 deg left, cam1 (right) 31 deg right: the lines meet behind the cameras
    q0 = unit(np.asarray(c0.T_C_B.R) @ [5.0, 3.0, 0.0])[None]
    q1 = unit(np.asarray(c1.T_C_B.R) @ [5.0, -3.0, 0.0])[None]
    assert len(box_pairs(q1 @ np.asarray(T.R), half, q1, half, T.R, T.t)[0]) == 1  # parallel: far, ahead
    assert len(box_pairs(q0, half, q1, half, T.R, T.t)[0]) == 0
    # two cam1 boxes on cam0's box's epipolar curve (two ranges): ambiguous, no pair
    b1_far = unit(c1.T_C_B.apply(p * 4.0))[None]
    two = np.vstack([b1, b1_far])
    assert len(box_pairs(b0, np.radians([1.0]), two, np.radians([1.0, 1.0]), T.R, T.t)[0]) == 0
    # incompatible attributes: none
    assert len(box_pairs(b0, half, b1, half, T.R, T.t, compatible=np.array([[False]]))[0]) == 0


def test_attributes_and_persistence():
    assert boxes_compatible({"heading": "towards"}, {"heading": "towards"})
    assert not boxes_compatible({"heading": "towards"}, {"heading": "away"})
    assert boxes_compatible({"heading": None}, {"heading": "away"})
    assert not boxes_compatible({"red_uv": [1, 2], "green_uv": None}, {"red_uv": None, "green_uv": [3, 4]})
    assert boxes_compatible({"red_uv": [1, 2], "green_uv": [5, 6]}, {"red_uv": None, "green_uv": [3, 4]})
    st = BoxStereo(2)
    assert st.update([(1, 2)]) == []
    assert st.update([(1, 2), (3, 4)]) == [(1, 2)]
    assert st.update([(3, 4)]) == [(3, 4)]
    assert st.update([(1, 2)]) == []  # a gap restarts the run
