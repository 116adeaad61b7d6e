"""Calibration loaders and the Kalibr writer."""

from __future__ import annotations

import math
import textwrap

import cv2
import numpy as np
import pytest

from estimators.calibration import load_kalibr, load_rig, save_kalibr
from estimators.cameras import DoubleSphere, Equidistant, Eucm, KannalaBrandt
from estimators.errors import CalibrationError, InputError
from estimators.rig import Camera, Rig, forward_T_C_B, stereo_forward_rig, top_bottom_rig
from estimators.se3 import Pose, rot_z

KB = KannalaBrandt(fx=285.1, fy=286.3, cx=640.7, cy=399.2, width=1280, height=800,
                   k1=0.0123, k2=-0.00451, k3=0.000789, k4=-1.2e-05)


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def test_save_kalibr_load_rig_round_trip_is_identical(tmp_path):
    ds = DoubleSphere(fx=170.3, fy=171.9, cx=640.1, cy=400.2, width=1280, height=800, xi=-0.21, alpha=0.59,
                      max_angle_rad=math.radians(97.5))
    eu = Eucm(fx=340.0, fy=339.5, cx=639.0, cy=401.0, width=1280, height=800, alpha=0.61, beta=1.07)
    eq = Equidistant.from_deg_per_px(0.09375, 1920, 1080, max_angle_rad=math.radians(90))
    odd_pose = Pose(rot_z(0.3) @ forward_T_C_B().R, [0.01, -0.02, 0.3])
    rig = Rig((
        Camera("cam0", KB, forward_T_C_B((0.1, 0.05, 0.0))),
        Camera("cam1", ds, forward_T_C_B((0.1, -0.05, 0.0))),
        Camera("rear", eu, odd_pose),
        Camera("cam3", eq, top_bottom_rig(KB)["cam1"].T_C_B),
    ))
    p = save_kalibr(rig, tmp_path / "sub" / "camchain.yaml")
    back = load_rig(p)
    assert back == rig
    assert back.names == ("cam0", "cam1", "rear", "cam3") and back.kind == "multi"
    assert type(back["cam3"].model) is Equidistant


def test_saved_camchain_uses_kalibr_keys(tmp_path):
    import yaml

    p = save_kalibr(stereo_forward_rig(KB, 0.12), tmp_path / "c.yaml")
    d = yaml.safe_load(p.read_text())
    assert list(d) == ["cam0", "cam1"]
    c0, c1 = d["cam0"], d["cam1"]
    assert c0["camera_model"] == "pinhole" and c0["distortion_model"] == "equidistant"
    assert c0["intrinsics"] == [285.1, 286.3, 640.7, 399.2]
    assert c0["distortion_coeffs"] == [0.0123, -0.00451, 0.000789, -1.2e-05]
    assert c0["resolution"] == [1280, 800]
    assert "T_cn_cnm1" not in c0
    # cam1 is 0.12 m to the right of cam0: in cam1's optical frame cam0's centre is at x = -0.12
    T = np.array(c1["T_cn_cnm1"])
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(T[:3, 3], [-0.12, 0.0, 0.0], atol=1e-15)


KALIBR_STEREO_NO_IMU = """\
    cam0:
      cam_overlaps: [1]
      camera_model: pinhole
      distortion_coeffs: [-0.0132, 0.0211, -0.0167, 0.0041]
      distortion_model: equidistant
      intrinsics: [461.3, 460.1, 366.0, 248.7]
      resolution: [752, 480]
      rostopic: /cam0/image_raw
    cam1:
      T_cn_cnm1:
      - [1.0, 0.0, 0.0, -0.11]
      - [0.0, 1.0, 0.0, 0.0]
      - [0.0, 0.0, 1.0, 0.0]
      - [0.0, 0.0, 0.0, 1.0]
      cam_overlaps: [0]
      camera_model: ds
      distortion_coeffs: []
      distortion_model: none
      intrinsics: [-0.2847, 0.5989, 349.7, 348.7, 365.9, 249.0]
      resolution: [752, 480]
      rostopic: /cam1/image_raw
    """


def test_hand_written_kalibr_stereo_with_T_cn_cnm1(tmp_path):
    rig = load_rig(_write(tmp_path, "camchain.yaml", KALIBR_STEREO_NO_IMU))
    assert rig.kind == "stereo" and rig.names == ("cam0", "cam1")
    m0, m1 = rig["cam0"].model, rig["cam1"].model
    assert isinstance(m0, KannalaBrandt) and (m0.fx, m0.fy, m0.cx, m0.cy) == (461.3, 460.1, 366.0, 248.7)
    assert (m0.k1, m0.k2, m0.k3, m0.k4) == (-0.0132, 0.0211, -0.0167, 0.0041)
    assert (m0.width, m0.height) == (752, 480)
    assert isinstance(m1, DoubleSphere) and (m1.xi, m1.alpha, m1.fx, m1.cy) == (-0.2847, 0.5989, 349.7, 249.0)
    # no T_cam_imu: cam0 looks forward from the body origin
    np.testing.assert_allclose(rig["cam0"].T_C_B.matrix(), forward_T_C_B().matrix())
    # cam1's centre is 0.11 m along cam0's +x (image right) = body -y
    np.testing.assert_allclose(rig["cam1"].centre_B, [0.0, -0.11, 0.0], atol=1e-15)
    np.testing.assert_allclose(rig["cam1"].T_C_B.R, forward_T_C_B().R, atol=1e-15)


def test_kalibr_T_cam_imu_is_T_C_B_and_eucm(tmp_path):
    p = _write(tmp_path, "camchain-imucam.yaml", """\
        cam0:
          T_cam_imu:
          - [0.0, -1.0, 0.0, 0.02]
          - [0.0, 0.0, -1.0, 0.03]
          - [1.0, 0.0, 0.0, -0.05]
          - [0.0, 0.0, 0.0, 1.0]
          camera_model: eucm
          distortion_coeffs: []
          distortion_model: none
          intrinsics: [0.59, 1.12, 460.7, 459.4, 365.8, 249.3]
          resolution: [752, 480]
        """)
    rig = load_kalibr(p)
    cam = rig["cam0"]
    assert rig.kind == "mono"
    assert isinstance(cam.model, Eucm) and (cam.model.alpha, cam.model.beta) == (0.59, 1.12)
    # p_C = R p_B + t: the camera centre is at R^T (-t) = (0.05, 0.02, 0.03) in B
    np.testing.assert_allclose(cam.centre_B, [0.05, 0.02, 0.03], atol=1e-15)


def _kb_from_cv2_file(K, D, size):
    return KannalaBrandt(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2], width=size[0], height=size[1],
                         k1=D[0], k2=D[1], k3=D[2], k4=D[3])


@pytest.mark.parametrize("suffix", [".yaml", ".json", ".xml"])
def test_opencv_filestorage_written_by_cv2(tmp_path, suffix):
    K = np.array([[285.1, 0.0, 640.7], [0.0, 286.3, 399.2], [0.0, 0.0, 1.0]])
    D = np.array([[0.0123], [-0.00451], [0.000789], [-1.2e-05]])
    p = tmp_path / f"fisheye{suffix}"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("K", K)
    fs.write("D", D)
    fs.write("image_width", 1280)
    fs.write("image_height", 800)
    fs.release()
    rig = load_rig(p)
    assert rig.names == ("cam0",)
    assert rig["cam0"].model == _kb_from_cv2_file(K, D.ravel(), (1280, 800))


def test_opencv_filestorage_camera_matrix_and_image_size_sequence(tmp_path):
    K = np.array([[300.0, 0.0, 320.0], [0.0, 301.0, 240.0], [0.0, 0.0, 1.0]])
    D = np.array([0.01, 0.002, -0.003, 0.0004])
    p = tmp_path / "calib.yml"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("camera_matrix", K)
    fs.write("D", D.reshape(1, 4))
    fs.startWriteStruct("image_size", cv2.FileNode_SEQ)
    fs.write("", 640)
    fs.write("", 480)
    fs.endWriteStruct()
    fs.release()
    assert load_rig(p)["cam0"].model == _kb_from_cv2_file(K, D, (640, 480))


def test_ros_camera_info_file_layout(tmp_path):
    p = _write(tmp_path, "left.yaml", """\
        image_width: 640
        image_height: 480
        camera_name: left
        camera_matrix:
          rows: 3
          cols: 3
          data: [300.0, 0.0, 320.5, 0.0, 301.0, 240.5, 0.0, 0.0, 1.0]
        distortion_model: equidistant
        distortion_coefficients:
          rows: 1
          cols: 4
          data: [0.01, 0.002, -0.003, 0.0004]
        rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}
        projection_matrix: {rows: 3, cols: 4, data: [300, 0, 320.5, 0, 0, 301, 240.5, 0, 0, 0, 1, 0]}
        """)
    rig = load_rig(p)
    assert rig.names == ("left",)
    assert rig["left"].model == KannalaBrandt(fx=300.0, fy=301.0, cx=320.5, cy=240.5, width=640, height=480,
                                              k1=0.01, k2=0.002, k3=-0.003, k4=0.0004)


def test_ros_camera_info_message_layout(tmp_path):
    p = _write(tmp_path, "info.yaml", """\
        height: 480
        width: 640
        distortion_model: equidistant
        d: [0.01, 0.002, -0.003, 0.0004]
        k: [300.0, 0.0, 320.5, 0.0, 301.0, 240.5, 0.0, 0.0, 1.0]
        """)
    m = load_rig(p)["cam0"].model
    assert (m.fx, m.cy, m.k4, m.width) == (300.0, 240.5, 0.0004, 640)


def test_thesis_linear(tmp_path):
    p = _write(tmp_path, "thesis.yaml", """\
        model: thesis_linear
        deg_per_px: 0.09375
        width: 1920
        height: 1080
        max_angle_deg: 90
        """)
    m = load_rig(p)["cam0"].model
    assert isinstance(m, Equidistant)
    assert m.fx == pytest.approx(180 / (math.pi * 0.09375))
    assert (m.cx, m.cy) == (959.5, 539.5)
    assert m.max_angle_rad == pytest.approx(math.pi / 2)
    # 90 degrees is 90/0.09375 = 960 px from the centre
    uv, valid = m.bearing_to_pixel(np.array([[1.0, 0.0, 0.0]]), within_image=False)
    assert uv[0, 0] == pytest.approx(959.5 + 960.0)
    # without max_angle_deg: the thesis's 180-degree field of view
    p2 = _write(tmp_path, "thesis2.yaml", "model: thesis_linear\ndeg_per_px: 0.1\nresolution: [1920, 1080]\n")
    assert load_rig(p2)["cam0"].model.max_angle_rad == pytest.approx(math.pi / 2)


KALIBR_HEAD = textwrap.dedent("""\
    cam0:
      camera_model: {cm}
      distortion_model: {dm}
      distortion_coeffs: {dc}
      intrinsics: {intr}
      resolution: [640, 480]
    """)


@pytest.mark.parametrize(
    "text, match",
    [
        (KALIBR_HEAD.format(cm="pinhole", dm="radtan", dc="[0.1, 0.01, 0.0, 0.0]",
                            intr="[300, 300, 320, 240]"),
         r"camera 'cam0': camera_model 'pinhole' with distortion_model 'radtan' is not supported; "
         r"accepted: pinhole \+ equidistant"),
        (KALIBR_HEAD.format(cm="pinhole", dm="equidistant", dc="[0.1, 0.01, 0.0, 0.0, 0.0]",
                            intr="[300, 300, 320, 240]"),
         r"camera 'cam0': distortion_model 'equidistant' expects 4 distortion_coeffs \(k1..k4\), found 5"),
        (KALIBR_HEAD.format(cm="omni", dm="none", dc="[]", intr="[0.8, 300, 300, 320, 240]"),
         r"camera_model 'omni' with distortion_model 'none' is not supported"),
        (KALIBR_HEAD.format(cm="ds", dm="none", dc="[]", intr="[-0.2, 0.6, 300, 300, 320]"),
         r"camera 'cam0': intrinsics: expected 6 values, found 5"),
        (KALIBR_HEAD.format(cm="ds", dm="none", dc="[]", intr="[-0.2, 1.6, 300, 300, 320, 240]"),
         r"camera 'cam0': double_sphere: expected alpha in \[0, 1\], got 1.6"),
        ("cam0:\n  camera_model: pinhole\n  intrinsics: [1, 1, 1, 1]\n", r"missing 'resolution'"),
        (KALIBR_HEAD.format(cm="eucm", dm="none", dc="[]", intr="[0.6, 1.1, 300, 300, 320, 240]")
         + "cam2:\n  camera_model: eucm\n", r"without gaps; found cam0, cam2"),
        (KALIBR_HEAD.format(cm="eucm", dm="none", dc="[]", intr="[0.6, 1.1, 300, 300, 320, 240]")
         + "cam1:\n  camera_model: eucm\n  distortion_model: none\n"
           "  intrinsics: [0.6, 1.1, 300, 300, 320, 240]\n"
           "  resolution: [640, 480]\n", r"camera 'cam1': needs T_cam_imu or T_cn_cnm1"),
        (KALIBR_HEAD.format(cm="eucm", dm="none", dc="[]", intr="[0.6, 1.1, 300, 300, 320, 240]")
         + "  T_cam_imu: [[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n",
         r"camera 'cam0': T_cam_imu: .*not a rotation"),
        ("image_width: 640\nimage_height: 480\ndistortion_model: plumb_bob\n"
         "camera_matrix: {data: [300, 0, 320, 0, 300, 240, 0, 0, 1]}\n"
         "distortion_coefficients: {data: [0.1, 0.01, 0, 0, 0]}\n",
         r"distortion_model 'plumb_bob' is not supported; accepted: equidistant"),
        ("image_width: 640\nimage_height: 480\ndistortion_model: equidistant\n"
         "camera_matrix: {data: [300, 0, 320, 0, 300, 240, 0, 0, 1]}\n"
         "distortion_coefficients: {data: [0.1, 0.01, 0, 0, 0]}\n",
         r"expected 4 fisheye distortion coefficients \(k1..k4, Kannala-Brandt\), found 5"),
        ("K: [[300, 0, 320], [0, 300, 240], [0, 0, 1]]\nD: [0.1, 0.01, 0.0, 0.0]\n",
         r"no image size found; expected image_width \+ image_height"),
        ("model: thesis_linear\nwidth: 1920\nheight: 1080\n", r"needs deg_per_px"),
        ("foo: 1\nbar: [1, 2]\n",
         r"unrecognised calibration format \(top-level keys: foo, bar\); expected a Kalibr"),
        ("cam0: [unclosed\n", r"does not parse as YAML: line 2, column 1: expected ',' or ']'"),
        (KALIBR_HEAD.format(cm="ds", dm="none", dc="[]", intr="[-0.2, 0.6, 300, 300, 320, 240]")
         + "  max_angle_rad: wide\n", r"camera 'cam0': max_angle_rad must be a list of numbers"),
        ("- 1\n- 2\n", r"expected a mapping of calibration keys, got list"),
    ],
)
def test_load_errors_name_file_camera_found_and_accepted(tmp_path, text, match):
    p = _write(tmp_path, "calib.yaml", text)
    with pytest.raises(CalibrationError, match=match) as ei:
        load_rig(p)
    assert str(p) in str(ei.value)


def test_opencv_pinhole_radtan_is_rejected(tmp_path):
    p = tmp_path / "pinhole.yaml"
    fs = cv2.FileStorage(str(p), cv2.FILE_STORAGE_WRITE)
    fs.write("K", np.array([[300.0, 0, 320], [0, 300, 240], [0, 0, 1]]))
    fs.write("D", np.zeros((1, 5)))
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.release()
    with pytest.raises(CalibrationError, match=r"found 5 \(that looks like OpenCV's pinhole radtan model"):
        load_rig(p)


def test_missing_file(tmp_path):
    with pytest.raises(CalibrationError, match=r"nope.yaml: calibration file not found"):
        load_rig(tmp_path / "nope.yaml")


def test_errors_are_one_line(tmp_path):
    p = _write(tmp_path, "calib.yaml", "a: [1, 2\n b: ::\n")
    with pytest.raises(CalibrationError) as ei:
        load_rig(p)
    assert "\n" not in str(ei.value)
    j = _write(tmp_path, "calib.json", '{"K": [1, 2,')
    with pytest.raises(CalibrationError, match=r"does not parse as JSON: line 1, column 13"):
        load_rig(j)


def test_save_kalibr_to_an_unwritable_path_is_an_input_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    text = "model: thesis_linear\nwidth: 64\nheight: 48\ndeg_per_px: 0.1\n"
    rig = load_rig(_write(tmp_path, "c.yaml", text))
    with pytest.raises(InputError, match="cannot write the calibration"):
        save_kalibr(rig, blocker / "camchain.yaml")
