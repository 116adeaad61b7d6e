"""Rig and standard mounts, pinned with hand-worked bearings.

Body FLU (x forward, y left, z up); camera x right, y down, z forward.
"""

from __future__ import annotations

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.errors import ConfigError, InputError
from estimators.rig import (
    Camera,
    Rig,
    forward_T_C_B,
    mono_forward_rig,
    stereo_forward_rig,
    top_bottom_rig,
)
from estimators.se3 import Pose

MODEL = Equidistant(fx=300.0, fy=300.0, cx=319.5, cy=239.5, width=640, height=480,
                    max_angle_rad=np.radians(95.0))


def _pixel(cam: Camera, p_B) -> np.ndarray:
    p_C = cam.T_C_B.apply(np.asarray(p_B, dtype=float)[None])
    uv, valid = cam.model.bearing_to_pixel(p_C)
    assert valid.all()
    return uv[0]


def test_forward_camera_hand_worked_bearings():
    cam = mono_forward_rig(MODEL)["cam0"]
    np.testing.assert_allclose(cam.T_C_B.apply([5.0, 0.0, 0.0]), [0.0, 0.0, 5.0])  # ahead -> optical axis
    np.testing.assert_allclose(cam.T_C_B.apply([0.0, 2.0, 0.0]), [-2.0, 0.0, 0.0])  # left -> -x_C
    np.testing.assert_allclose(cam.T_C_B.apply([0.0, 0.0, 3.0]), [0.0, -3.0, 0.0])  # up -> -y_C
    np.testing.assert_allclose(_pixel(cam, [5.0, 0.0, 0.0]), [MODEL.cx, MODEL.cy], atol=1e-12)
    u, v = _pixel(cam, [5.0, 1.0, 0.0])  # ahead and to the left
    assert u < MODEL.cx and v == pytest.approx(MODEL.cy)
    u, v = _pixel(cam, [5.0, 0.0, 1.0])  # ahead and above
    assert v < MODEL.cy and u == pytest.approx(MODEL.cx)
    # 45 degrees to the right: r = f * pi/4 to the right of the centre (equidistant)
    u, v = _pixel(cam, [1.0, -1.0, 0.0])
    assert u == pytest.approx(MODEL.cx + 300.0 * np.pi / 4) and v == pytest.approx(MODEL.cy)


def test_forward_camera_offset_is_the_camera_centre():
    T = forward_T_C_B((0.1, 0.2, -0.05))
    np.testing.assert_allclose(T.inverse().t, [0.1, 0.2, -0.05], atol=1e-15)
    np.testing.assert_allclose(T.apply([0.1, 0.2, -0.05]), [0.0, 0.0, 0.0], atol=1e-15)


def test_stereo_forward_rig_left_is_cam0():
    rig = stereo_forward_rig(MODEL, baseline_m=0.3)
    assert rig.kind == "stereo" and rig.names == ("cam0", "cam1")
    np.testing.assert_allclose(rig["cam0"].centre_B, [0.0, 0.15, 0.0], atol=1e-15)
    np.testing.assert_allclose(rig["cam1"].centre_B, [0.0, -0.15, 0.0], atol=1e-15)
    # A point straight ahead of the body origin is to the right of the left camera (u > cx) and
    # to the left of the right camera (u < cx): positive disparity u0 - u1.
    u0, _ = _pixel(rig["cam0"], [4.0, 0.0, 0.0])
    u1, _ = _pixel(rig["cam1"], [4.0, 0.0, 0.0])
    assert u0 > MODEL.cx > u1
    # equidistant: angle off the axis = atan(0.15 / 4) -> r = f * angle
    assert u0 - MODEL.cx == pytest.approx(300.0 * np.arctan2(0.15, 4.0))


def test_top_bottom_rig_hand_worked_bearings():
    rig = top_bottom_rig(MODEL, separation_m=0.2)
    up, down = rig["cam0"], rig["cam1"]
    np.testing.assert_allclose(up.centre_B, [0, 0, 0.1], atol=1e-15)
    np.testing.assert_allclose(down.centre_B, [0, 0, -0.1], atol=1e-15)
    np.testing.assert_allclose(_pixel(up, [0.0, 0.0, 5.0]), [MODEL.cx, MODEL.cy], atol=1e-12)
    np.testing.assert_allclose(_pixel(down, [0.0, 0.0, -5.0]), [MODEL.cx, MODEL.cy], atol=1e-12)
    # nose of the drone at the top of both images
    assert _pixel(up, [1.0, 0.0, 5.0])[1] < MODEL.cy
    assert _pixel(down, [1.0, 0.0, -5.0])[1] < MODEL.cy
    # up camera: body left (+y) is image right; down camera: body left is image left
    assert _pixel(up, [0.0, 1.0, 5.0])[0] > MODEL.cx
    assert _pixel(down, [0.0, 1.0, -5.0])[0] < MODEL.cx
    # a point on the horizon ahead is 90 degrees off both axes (both 95-degree lenses see it)
    uv, valid = up.model.bearing_to_pixel(up.T_C_B.apply(np.array([[100.0, 0.0, 0.1]])), within_image=False)
    assert valid.all()
    assert uv[0, 1] == pytest.approx(MODEL.cy - 300.0 * np.pi / 2, abs=0.5)


@pytest.mark.parametrize("rig_fn", [lambda: mono_forward_rig(MODEL), lambda: stereo_forward_rig(MODEL, 0.1),
                                    lambda: top_bottom_rig(MODEL)])
def test_mount_rotations_are_proper(rig_fn):
    for cam in rig_fn():
        R = cam.T_C_B.R
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0)


def test_rig_kind_lookup_and_validation():
    c0 = Camera("a", MODEL, Pose.identity())
    c1 = Camera("b", MODEL, Pose.identity())
    c2 = Camera("c", MODEL, Pose.identity())
    assert Rig((c0,)).kind == "mono"
    assert Rig((c0, c1, c2)).kind == "multi"
    rig = Rig([c0, c1])
    assert rig["b"] is c1 and rig[0] is c0 and "a" in rig and len(rig) == 2
    with pytest.raises(InputError, match=r"no camera named 'x'; cameras: a, b"):
        rig["x"]
    with pytest.raises(ConfigError, match="at least one camera"):
        Rig(())
    with pytest.raises(ConfigError, match="duplicated: a"):
        Rig((c0, Camera("a", MODEL, Pose.identity())))
    with pytest.raises(ConfigError, match="baseline_m > 0"):
        stereo_forward_rig(MODEL, 0.0)
    with pytest.raises(InputError, match="expected a CameraModel"):
        Camera("a", "equidistant", Pose.identity())


def test_camera_equality_compares_model_and_pose():
    a = Camera("cam0", MODEL, forward_T_C_B())
    assert a == Camera("cam0", MODEL, forward_T_C_B())
    assert a != Camera("cam0", MODEL, forward_T_C_B((0.0, 0.0, 0.1)))
    assert a != Camera("cam0", MODEL.scaled(0.5), forward_T_C_B())
