"""Box detectors on frames wider than the front end's ``max_width``: the boxes come from the full-size
frame (colour, one-pixel lights intact) and are mapped to the small frame the tracker works on
(``Detections.scaled``); the keypoints see the same small grey frame as with ORB alone.

Expected values come from where the lights are drawn and from the camera model's own scaling
(``CameraModel.scaled``), not from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import InputError
from estimators.rig import mono_forward_rig
from tests.trackers.conftest import Patch, SphereScene, assert_same_feature_tracks, equidistant, rot_axis
from trackers.detectors import Detections
from trackers.frontend import FrontEnd


def test_scaled_maps_pixels_as_the_camera_model_maps_its_principal_point():
    model = equidistant(480, 360)
    f = 2.0 / 3.0
    small = model.scaled(f)
    d = Detections(
        keypoints=np.array([[model.cx, model.cy]], np.float32),
        scores=np.ones(1, np.float32),
        boxes=np.array([[10.0, 20.0, 30.0, 41.0]]),
        labels=("drone",),
        attributes=({"red_uv": [30.0, 41.0]},),
    )
    s = d.scaled(f)
    np.testing.assert_allclose(s.keypoints[0], [small.cx, small.cy], atol=1e-4)
    # p' = (p + 0.5) f - 0.5, worked by hand: 10 -> 6.5, 20 -> 13.1667, 30 -> 19.8333, 41 -> 27.1667
    np.testing.assert_allclose(s.boxes[0], [6.5, 13.5 - 1 / 3, 20.0 - 1 / 6, 27.5 - 1 / 3], atol=1e-9)
    assert s.labels == ("drone",) and s.attributes == ({"red_uv": [30.0, 41.0]},)  # frame pixels kept
    assert d.scaled(1.0) is d
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(InputError, match="factor"):
            d.scaled(bad)


def _wide_rig():
    return mono_forward_rig(equidistant(480, 360))


def test_one_pixel_lights_on_a_wide_frame_are_found_where_they_are_drawn():
    """A red and a green light of ONE pixel each on a 480x360 frame tracked at 320 px wide: a
    2/3 resize would spread each over less than a pixel's worth of its neighbours; read on the
    full-size frame they give one drone box whose reported pixel is the pair's centre (full-frame
    pixels, as CameraView.uv always is)."""
    rig = _wide_rig()
    model = rig.cameras[0].model
    img = np.full((360, 480, 3), 200, np.uint8)  # flat grey: no white light near the pair
    img[180, 300] = (0, 0, 255)  # red
    img[180, 292] = (0, 255, 0)  # green: on the image-left of red, heading towards us
    fe = FrontEnd(rig, detector="orb+navlights", max_width=320)
    assert fe.scale["cam0"] == pytest.approx(2 / 3)
    obs = fe.process({"cam0": img}, 0, 0.0)
    drones = [o for o in obs if o.label == "drone"]
    assert len(drones) == 1 and drones[0].attributes["heading"] == "towards"
    np.testing.assert_allclose(drones[0].views[0].uv, [296.0, 180.0], atol=1e-6)
    assert drones[0].attributes["red_uv"] == [300.0, 180.0]  # full-frame pixels
    # its bearing is the full-size model's bearing of that pixel
    b, ok = model.pixel_to_bearing(np.array([[296.0, 180.0]]))
    assert ok[0] and np.degrees(np.arccos(np.clip(b[0] @ drones[0].views[0].b_C, -1, 1))) < 0.05


def test_wide_frame_feature_tracks_are_those_of_orb_alone():
    """On a frame wider than max_width the composite's feature tracks are ORB's, track for track:
    the keypoints see the grey frame shrunk as for ORB alone (not a shrunk colour frame made grey)."""
    rig = _wide_rig()
    model = rig.cameras[0].model
    scene = SphereScene(model, blank_env=True)
    rng = np.random.default_rng(7)
    a = FrontEnd(rig, detector="orb", max_width=320)
    b = FrontEnd(rig, detector="orb+navlights", max_width=320)
    for k in range(8):
        p = [Patch(rot_axis([0, 1, 0], np.radians(0.6) * k) @ np.array([0.3, 0.0, 1.0]), np.radians(18))]
        g = scene.render(np.eye(3), p)
        # a colour frame: per-pixel colour noise, so that shrinking it and then making it grey
        # is not making it grey and then shrinking it (rounding differs)
        noise = rng.integers(-20, 21, g.shape + (3,))
        bgr = np.clip(g[..., None].astype(int) + noise, 0, 255).astype(np.uint8)
        oa = a.process({"cam0": bgr}, k, k / 30)
        ob = b.process({"cam0": bgr}, k, k / 30)
        assert_same_feature_tracks(oa, ob)
    assert any(o.status == "confirmed" for o in oa)
