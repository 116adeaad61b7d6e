"""BoxTracker's ``link_older_only``: a box found before the feature track on it keeps its own report
(and id); a feature track found before the box still takes the box in. Positions are drawn by hand
(pixels on a box moving 2 px a frame), not taken from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from estimators.rig import mono_forward_rig
from tests.trackers.conftest import equidistant
from trackers.detectors import Detections
from trackers.grouping import BoxTracker, ObstacleTrack


def _ft(tid: int, b_members: np.ndarray) -> ObstacleTrack:
    b = b_members.mean(axis=0)
    return ObstacleTrack(tid, "cam0", np.arange(len(b_members)) + 100 * tid, b / np.linalg.norm(b),
                         member_b_C=b_members)


def _run(feature_id: int, older_only: bool, frames: int = 6):
    """A box (its track gets id 5) moving 2 px a frame with a feature track (``feature_id``) of three
    members on it moving alike; returns per frame (ids of the box tracks reported, the links)."""
    model = equidistant()
    cam = mono_forward_rig(model).cameras[0]
    bt = BoxTracker(iter(range(5, 100)), link_older_only=older_only)
    out = []
    for k in range(frames):
        u0 = 160.0 + 2 * k
        det = Detections(boxes=np.array([[u0 - 4, 116.0, u0 + 4, 124.0]]), labels=("drone",),
                         attributes=({"heading": "away"},))
        on, _ = model.pixel_to_bearing(np.array([[u0 - 2, 119.0], [u0 + 2, 121.0], [u0, 120.0]]))
        seen, _ = bt.update(cam, det, [_ft(feature_id, on)], t_s=k / 30)
        out.append(([t.id for t in seen], dict(bt.links)))
    return out


def test_a_box_found_first_keeps_its_report_beside_a_later_feature_track():
    """Feature track 7 is made after box track 5. By default the link hides box 5 from the 4th
    frame on (the drone's reported id changes from 5 to 7: an id switch); with link_older_only it
    is reported in every frame and nothing is linked."""
    default = _run(7, False)
    assert [ids for ids, _ in default] == [[5]] * 3 + [[]] * 3 and default[-1][1] == {5: 7}
    older = _run(7, True)
    assert [ids for ids, _ in older] == [[5]] * 6 and all(links == {} for _, links in older)


def test_a_feature_track_found_first_still_takes_the_box_in():
    """Feature track 3 was made before box track 5: linked as by default (one report, the feature
    track's, which the drone already had)."""
    assert _run(3, True) == _run(3, False)
    assert _run(3, True)[-1] == ([], {5: 3})


def test_link_older_only_must_be_a_bool():
    with pytest.raises(ConfigError, match="link_older_only"):
        BoxTracker(iter(range(5)), link_older_only=1)


def test_the_lens_scale_of_the_links_is_computed_once_per_camera_model(monkeypatch):
    """The links' tolerance is in the lens's mean radians per pixel (max angle / image circle radius),
    a property of the camera model: computed once per model object (``image_circle`` projects four
    rays, ~60 us a call, which every frame of every camera paid), again for another model object."""
    calls = []
    cls = type(equidistant())
    image_circle = cls.image_circle
    monkeypatch.setattr(cls, "image_circle", lambda self: calls.append(self) or image_circle(self))
    a, b = equidistant(), equidistant()
    bt = BoxTracker(iter(range(5, 100)))
    for k, model in enumerate((a, a, a, b, b)):
        bt.update(mono_forward_rig(model).cameras[0], Detections(), [], t_s=k / 30)
    assert calls == [a, b]
