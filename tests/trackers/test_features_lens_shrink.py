"""Shrinking wide frames (FrontEnd ``max_width``): only the lens box the feature tracker reads is
resized, with the same pixels as a whole-frame cv2.resize, so tracking is unchanged."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from estimators.rig import Camera, Rig, forward_T_C_B
from tests.trackers.conftest import SphereScene, equidistant, rot_axis
from trackers.frontend import FrontEnd, _shrink_box


@pytest.mark.parametrize(("size", "small"), [((1920, 1080), (1280, 720)), ((1600, 1200), (1280, 960))])
def test_part_of_the_frame_resizes_to_the_whole_frames_pixels(size, small):
    """cv2.resize INTER_AREA of the returned part equals the same part of cv2's whole-frame resize
    (the independent reference), and the part holds the requested box."""
    (w, h), (sw, sh) = size, small
    model = equidistant(sw, sh)
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur((rng.random((h, w)) * 255).astype(np.uint8), (0, 0), 1.2)
    whole = cv2.resize(img, (sw, sh), interpolation=cv2.INTER_AREA)
    box = (sw // 4 + 1, 3, 3 * sw // 4 - 1, sh - 5)
    sx0, sy0, sx1, sy1, x0, y0, x1, y1 = _shrink_box((w, h), model, box)
    assert x0 <= box[0] and y0 <= box[1] and x1 >= box[2] and y1 >= box[3]
    part = cv2.resize(img[sy0:sy1, sx0:sx1], (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    np.testing.assert_array_equal(part, whole[y0:y1, x0:x1])
    assert _shrink_box((w, h), model, (0, 0, sw, sh)) is None  # the whole frame: nothing to save


def test_front_end_tracks_the_same_with_the_lens_box_shrunk():
    """A 960x540 camera tracked at max_width 640: the features (ids, pixels) are the same whether
    the whole frame or only the lens box is resized (the rest is never read)."""
    model = equidistant(960, 540)
    rig = Rig((Camera("cam0", model, forward_T_C_B()),))
    scene = SphereScene(model)
    frames = [scene.render(rot_axis([0, 1, 0], np.radians(0.5) * k)) for k in range(6)]
    a, b = FrontEnd(rig, max_width=640), FrontEnd(rig, max_width=640)
    assert a._shrink["cam0"] is not None
    b._shrink = {}  # whole-frame resize
    for k, img in enumerate(frames):
        a.process({"cam0": img}, k, k / 30)
        b.process({"cam0": img}, k, k / 30)
        fa, fb = a.last_features["cam0"], b.last_features["cam0"]
        assert len(fa) > 50
        np.testing.assert_array_equal(fa.ids, fb.ids)
        np.testing.assert_array_equal(fa.uv, fb.uv)
