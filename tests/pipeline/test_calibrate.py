"""``fisheye-des calibrate``: synthetic boards with known intrinsics, CLI errors, and real photographs."""

from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from estimators.calibration import load_rig
from estimators.cameras import KannalaBrandt
from estimators.errors import CalibrationError, InputError, SourceError
from estimators.rig import forward_T_C_B
from estimators.se3 import Pose, rot_y
from pipeline.cli import main
from pipeline.commands.calibrate import (
    Board,
    ViewResult,
    calibrate_inputs,
    calibrate_stereo_views,
    calibrate_views,
    detect_corners,
    iter_frames,
)

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"

TRUE = KannalaBrandt(fx=190.0, fy=190.5, cx=321.3, cy=238.6, width=640, height=480,
                     k1=-0.02, k2=0.01, k3=-0.004, k4=0.0005)
BOARD = Board(cols=9, rows=6, square_m=0.03)

# Board poses (rotation vector rad, translation m of the board origin in C), spread over the image.
POSES = [
    ((0.1, -0.2, 0.05), (-0.12, -0.08, 0.28)),
    ((-0.3, 0.35, 0.1), (-0.25, -0.05, 0.25)),
    ((0.35, 0.3, -0.1), (0.0, -0.2, 0.22)),
    ((-0.25, -0.45, 0.2), (0.05, 0.02, 0.24)),
    ((0.5, 0.1, 0.0), (-0.15, 0.06, 0.2)),
    ((-0.2, 0.4, 0.3), (-0.2, -0.12, 0.26)),
    ((-0.4, -0.1, 0.3), (-0.05, -0.15, 0.3)),
    ((0.2, -0.55, -0.1), (0.02, -0.1, 0.22)),
]


_RAYS: dict = {}


def _rays(model: KannalaBrandt, ss: int) -> tuple[np.ndarray, np.ndarray]:
    """Bearings of the ss x ss sub-pixel samples of every pixel (cached: independent of the pose)."""
    key = (model, ss)
    if key not in _RAYS:
        offs = (np.arange(ss) + 0.5) / ss - 0.5
        v, u = np.mgrid[0:model.height, 0:model.width].astype(float)
        uv = np.concatenate([np.stack([(u + du).ravel(), (v + dv).ravel()], axis=1)
                             for dv in offs for du in offs])
        _RAYS[key] = model.pixel_to_bearing(uv, within_image=False)
    return _RAYS[key]


def render_board(model: KannalaBrandt, rvec, tvec, board: Board = BOARD, ss: int = 2) -> np.ndarray:
    """Ray-cast a checkerboard (white margin of one square, grey background) through ``model``.

    ``ss`` x ``ss`` samples per pixel, then a light blur; returns (H,W) uint8.
    """
    R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=float))
    t = np.asarray(tvec, dtype=float)
    b, valid = _rays(model, ss)
    # Board axes r0, r1 and normal n (columns of R) in C; the plane is n . p = n . t. The ray
    # lam b meets it at lam = (n . t)/(n . b); board coordinates x = r0 . (lam b - t), y likewise.
    proj = np.einsum("ni,ij->nj", b, R)  # (N,3): b . r0, b . r1, b . n (einsum: BLAS matmul is slow here)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (R[:, 2] @ t) / proj[:, 2]
    hit = valid & (lam > 0)
    lam = np.where(hit, lam, 0.0)
    # squares span [-s, cols*s) x [-s, rows*s), so the inner corners are at (i s, j s); a white
    # margin of one more square around them
    x = (lam * proj[:, 0] - R[:, 0] @ t) / board.square_m
    y = (lam * proj[:, 1] - R[:, 1] @ t) / board.square_m
    on_board = hit & (x >= -1) & (x < board.cols) & (y >= -1) & (y < board.rows)
    margin = hit & (x >= -2) & (x < board.cols + 1) & (y >= -2) & (y < board.rows + 1)
    val = np.full(b.shape[0], 110.0)
    val[margin] = 235.0
    val[on_board & ((np.floor(x) + np.floor(y)) % 2 == 0)] = 20.0
    img = val.reshape(ss * ss, model.height, model.width).mean(axis=0)
    return cv2.GaussianBlur(img, (0, 0), 0.7).round().clip(0, 255).astype(np.uint8)


def true_corners(model: KannalaBrandt, rvec, tvec, board: Board = BOARD) -> np.ndarray:
    R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=float))
    p_C = board.object_points() @ R.T + np.asarray(tvec, dtype=float)
    uv, valid = model.bearing_to_pixel(p_C)
    assert valid.all()
    return uv


@pytest.fixture(scope="module")
def board_images(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("boards")
    for i, (r, t) in enumerate(POSES):
        cv2.imwrite(str(d / f"view_{i:02d}.png"), render_board(TRUE, r, t))
    return d


def test_board_object_points_follow_opencv_order():
    obj = Board(3, 2, 0.5).object_points()
    np.testing.assert_allclose(obj, [[0, 0, 0], [0.5, 0, 0], [1, 0, 0],
                                     [0, 0.5, 0], [0.5, 0.5, 0], [1, 0.5, 0]])


def test_detect_corners_on_a_rendered_board_is_sub_pixel(board_images):
    r, t = POSES[0]
    img = cv2.imread(str(board_images / "view_00.png"), cv2.IMREAD_GRAYSCALE)
    c = detect_corners(img, BOARD)
    assert c is not None and c.shape == (54, 2)
    truth = true_corners(TRUE, r, t)
    # the detector may number the corners from either end of the board
    err = np.abs(c - truth).max(axis=1)
    if err.max() > 5:
        err = np.abs(c[::-1] - truth).max(axis=1)
    # measured: median 0.15 px, max 0.34 px (small squares of ~10 px, 2x2 supersampled edges)
    assert np.median(err) < 0.25 and err.max() < 0.6


def test_calibration_recovers_known_intrinsics_exactly_from_exact_corners():
    views = [ViewResult(f"v{i}", true_corners(TRUE, r, t)) for i, (r, t) in enumerate(POSES)]
    res = calibrate_views(views, BOARD, (640, 480))
    assert res.rms_px < 1e-9
    m = res.model
    for k in ("fx", "fy", "cx", "cy"):
        assert getattr(m, k) == pytest.approx(getattr(TRUE, k), rel=1e-9)
    np.testing.assert_allclose([m.k1, m.k2, m.k3, m.k4], [TRUE.k1, TRUE.k2, TRUE.k3, TRUE.k4], atol=1e-9)


def test_the_board_s_angular_coverage_is_reported_beside_the_lens_field():
    """The fit holds up to the board's farthest corner; the camchain's max_angle_rad (the model's, up to
    180 deg when unset) goes further: the report says how far each reaches (real sets: 41-84 deg of
    corners against 107-180 deg written)."""
    from pipeline.commands.calibrate import board_coverage_deg

    views = [ViewResult(f"v{i}", true_corners(TRUE, r, t)) for i, (r, t) in enumerate(POSES)]
    res = calibrate_views(views, BOARD, (640, 480))
    seen, lens = board_coverage_deg(res)
    uv = np.concatenate([v.corners for v in views])
    b, _ = TRUE.pixel_to_bearing(uv, within_image=False)
    assert seen == pytest.approx(np.degrees(np.arccos(b[:, 2])).max(), abs=1e-6)
    assert seen < 90 and lens == pytest.approx(180.0, abs=1e-3)  # no --max-angle-deg: the lens's 180 deg
    res = calibrate_views(views, BOARD, (640, 480), max_angle_rad=np.radians(100.0))  # --max-angle-deg 100
    assert board_coverage_deg(res) == pytest.approx((seen, 100.0), abs=1e-6)


def test_calibration_with_noise_and_bad_views():
    rng = np.random.default_rng(3)
    views = [ViewResult(f"v{i}", true_corners(TRUE, r, t) + rng.normal(0, 0.1, (54, 2)))
             for i, (r, t) in enumerate(POSES)]
    bad = true_corners(TRUE, *POSES[0])
    bad[10:20] += 6.0  # a misdetected stretch of corners
    views += [ViewResult("misdetected", bad), ViewResult("no board", None, reason="board not found")]
    res = calibrate_views(views, BOARD, (640, 480))
    assert [v.name for v in res.used] == [f"v{i}" for i in range(len(POSES))]
    assert res.views[-2].reason.startswith("reprojection outlier") and not res.views[-2].used
    assert res.views[-1].reason == "board not found" and not res.views[-1].used
    # noise of 0.1 px per coordinate: residual norm RMS ~ 0.1 sqrt(2) (less the fitted parameters)
    assert 0.08 < res.rms_px < 0.16
    # the lens mapping where the boards were seen (up to 64 degrees off the axis); measured 0.17 px
    m = res.model
    th = np.radians(np.arange(0, 61, 5.0))
    b = np.stack([np.sin(th), np.zeros_like(th), np.cos(th)], axis=1)
    r_true = TRUE.bearing_to_pixel(b)[0][:, 0] - TRUE.cx
    r_ours = m.bearing_to_pixel(b)[0][:, 0] - m.cx
    assert np.abs(r_ours - r_true).max() < 0.3


def test_stereo_calibration_recovers_a_known_baseline_with_flipped_corner_numbering():
    # cam1 8 cm to the right of cam0 (+x of C), turned 2 degrees about y: p_c1 = R p_c0 + t,
    # t = -R c1 with c1 = (0.08, 0, 0) in cam0.
    R = rot_y(np.radians(2.0))
    T_c1_c0 = Pose(R, -R @ np.array([0.08, 0.0, 0.0]))
    right_model = KannalaBrandt(fx=192.0, fy=191.7, cx=318.9, cy=241.2, width=640, height=480,
                                k1=-0.015, k2=0.008, k3=-0.003, k4=0.0004)
    left, right = [], []
    for i, (r, t) in enumerate(POSES):
        left.append(ViewResult(f"l{i}", true_corners(TRUE, r, t)))
        Rb, _ = cv2.Rodrigues(np.asarray(r, dtype=float))
        p_c1 = T_c1_c0.apply(BOARD.object_points() @ Rb.T + np.asarray(t, dtype=float))
        uv, valid = right_model.bearing_to_pixel(p_c1)
        assert valid.all()
        # the detector may number the right camera's corners from the other end
        right.append(ViewResult(f"r{i}", uv[::-1] if i % 3 == 1 else uv))
    st = calibrate_stereo_views(left, right, BOARD, (640, 480), (640, 480))
    assert len(st.pairs) == len(POSES)
    assert st.rms_px < 1e-6
    np.testing.assert_allclose(st.T_c1_c0.R, T_c1_c0.R, atol=1e-8)
    np.testing.assert_allclose(st.T_c1_c0.t, T_c1_c0.t, atol=1e-8)
    assert st.baseline_m == pytest.approx(0.08, abs=1e-8)
    # the rig: B midway between the cameras, cam0 forward, cam1 at its right (body -y)
    cam0, cam1 = st.rig["cam0"], st.rig["cam1"]
    np.testing.assert_allclose(cam0.centre_B, [0.0, 0.04, 0.0], atol=1e-8)
    np.testing.assert_allclose(cam1.centre_B, [0.0, -0.04, 0.0], atol=1e-8)
    np.testing.assert_allclose(cam0.T_C_B.R, forward_T_C_B().R, atol=1e-12)
    np.testing.assert_allclose((cam1.T_C_B @ cam0.T_C_B.inverse()).t, T_c1_c0.t, atol=1e-8)


def test_stereo_needs_as_many_right_frames_as_left():
    v = [ViewResult("a", None)]
    with pytest.raises(InputError, match=r"got 1 left and 2 right"):
        calibrate_stereo_views(v, v + v, BOARD, (640, 480), (640, 480))


def test_cli_writes_a_kalibr_file_and_reports_rms(board_images, tmp_path, capsys):
    out = tmp_path / "camchain.yaml"
    rc = main(["calibrate", str(board_images / "*.png"), "--board", "9x6", "--square-m", "0.03",
               "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "overall RMS reprojection error:" in text and "view_03.png: rms" in text
    assert re.search(r"board corners seen up to [\d.]+ deg off the optical axis; the camchain's lens half "
                     r"field \(max_angle_rad\) is [\d.]+ deg: bearings beyond [\d.]+ deg are extrapolated",
                     text)
    rig = load_rig(out)
    assert rig.names == ("cam0",)
    # measured on these renders: rms 0.20 px, fx within 0.2 % (aliasing of 2x2-supersampled edges)
    assert float(re.search(r"overall RMS reprojection error: ([\d.]+) px", text).group(1)) < 0.4
    assert rig["cam0"].model.fx == pytest.approx(TRUE.fx, rel=5e-3)


def test_cli_video_input(board_images, tmp_path, capsys):
    video = tmp_path / "boards.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 10, (640, 480), isColor=False)
    if not w.isOpened():
        pytest.skip("no FFV1 writer in this OpenCV build")
    for f in sorted(board_images.glob("*.png")):
        img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
        for _ in range(2):
            w.write(img)
    w.release()
    frames = list(iter_frames([str(video)], every=2))
    assert [n.split("#")[1] for n, _ in frames] == [f"frame{i}" for i in range(0, 16, 2)]
    rc = main(["calibrate", str(video), "--every", "2", "--board", "9x6", "--square-m", "0.03",
               "--out", str(tmp_path / "c.yaml")])
    assert rc == 0, capsys.readouterr().out


@pytest.mark.parametrize(
    "args, error, match",
    [
        (["--board", "9by6"], InputError,
         r"--board: expected COLSxROWS inner corners such as 9x6, got '9by6'"),
        (["--board", "9x6", "--square-m", "-1"], InputError, r"--square-m: expected a square size > 0"),
        (["--board", "7x5"], CalibrationError, r"the board \(7x5 inner corners\) was found in 0 of 1 views"),
        (["--model", "double_sphere"], InputError, r"--model: 'double_sphere' cannot be calibrated here"),
    ],
)
def test_cli_errors(board_images, tmp_path, capsys, args, error, match):
    base = ["calibrate", str(board_images / "view_00.png"), "--square-m", "0.03", "--board", "9x6",
            "--out", str(tmp_path / "c.yaml")]
    rc = main(base + args)
    assert rc == 2
    err = capsys.readouterr().err
    assert err.startswith("fisheye-des: error: ")
    assert re.search(match, err), err
    with pytest.raises(error, match=match):
        main(["--debug"] + base + args)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda d: str(d / "missing.png"), r"missing.png: no such file or folder"),
        (lambda d: (d / "bad.png").write_bytes(b"not a png") and str(d / "bad.png"),
         r"bad.png: cannot be read as an image"),
        (lambda d: (d / "empty").mkdir() or str(d / "empty"), r"empty: folder holds no images"),
        (lambda d: str(d / "*.nothing"), r"the pattern matches no files"),
    ],
)
def test_unreadable_inputs_are_source_errors(tmp_path, make, match):
    with pytest.raises(SourceError, match=match):
        list(iter_frames([make(tmp_path)]))


# ----------------------------------------------------------------------------------- real data
def _need(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return path


@pytest.mark.realdata
@pytest.mark.parametrize(
    "folder, board, max_rms_px",
    [
        # board sizes from the data's README / checkerboard_sizes.txt; RMS measured on all views:
        ("urban_fisheye2", Board(6, 8, 0.117), 0.3),  # 0.105 px (15 views)
        ("urban_fisheye1", Board(6, 8, 0.0325), 0.6),  # 0.385 px (15 views)
        ("scaramuzza_ladybug", Board(5, 8, 0.030), 0.6),  # 0.387 px (9 views)
    ],
)
def test_real_ocamcalib_sets(folder, board, max_rms_px):
    path = _need(DATA / "ocamcalib_fisheye" / folder)
    files = sorted(str(f) for f in path.glob("*.jpg"))[:8]
    res = calibrate_inputs(files, board)
    assert len(res.used) >= 7
    assert res.rms_px < max_rms_px
    _assert_matches_cv2(res)


@pytest.mark.realdata
@pytest.mark.parametrize("side", ["left", "right"])
def test_real_stereopi_agrees_with_the_upstream_calibration(side):
    folder = _need(DATA / "stereopi_fisheye")
    files = [str(folder / "pairs" / f"{side}_{i:02d}.png") for i in range(1, 13)]
    res = calibrate_inputs(files, Board(9, 6, 0.025))
    assert len(res.used) == 12
    assert res.rms_px < 0.3  # measured 0.10-0.11 px
    _assert_matches_cv2(res)
    # Independent check: upstream's cv2.fisheye calibration of the same camera at 320x240 from
    # 48 views (README: left fx 167.894 cx 172.392 cy 116.111; right fx 167.878 cx 151.453
    # cy 122.553), scaled to 640x480.
    up = np.load(folder / "calibration_240p" / f"camera_calibration_{side}.npz")
    K = up["camera_matrix"]
    fx2, cx2, cy2 = K[0, 0] * 2, (K[0, 2] + 0.5) * 2 - 0.5, (K[1, 2] + 0.5) * 2 - 0.5
    m = res.model
    assert m.fx == pytest.approx(fx2, rel=0.01)
    assert m.cx == pytest.approx(cx2, abs=2.0) and m.cy == pytest.approx(cy2, abs=2.0)


def _assert_matches_cv2(res):
    """Our KB model reproduces cv2.fisheye.projectPoints of the calibrated board corners (< 1e-6 px)."""
    obj = res.board.object_points()
    for r, t in zip(res.rvecs, res.tvecs, strict=True):
        proj, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), r, t, res.K, res.D)
        R, _ = cv2.Rodrigues(r)
        uv, valid = res.model.bearing_to_pixel(obj @ R.T + t.reshape(1, 3), within_image=False)
        assert valid.all()
        assert np.abs(uv - proj.reshape(-1, 2)).max() < 1e-6


@pytest.mark.realdata
def test_real_stereopi_stereo_cli(tmp_path, capsys):
    pairs = _need(DATA / "stereopi_fisheye" / "pairs")
    out = tmp_path / "stereopi.yaml"
    rc = main(["calibrate", str(pairs / "left_0*.png"), "--right", str(pairs / "right_0*.png"),
               "--board", "9x6", "--square-m", "0.025", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0, text
    rig = load_rig(out)
    assert rig.kind == "stereo" and rig.names == ("cam0", "cam1")
    # README (upstream corners, stereoCalibrate): |T| = 2.589 squares = 64.7 mm, R = 0.94 deg
    d = rig["cam0"].centre_B - rig["cam1"].centre_B
    assert np.linalg.norm(d) == pytest.approx(0.0647, abs=0.002)
    assert d[1] > 0.06  # cam0 (left) is on the body's left, +y
    R = (rig["cam1"].T_C_B @ rig["cam0"].T_C_B.inverse()).R
    assert np.degrees(np.arccos((np.trace(R) - 1) / 2)) == pytest.approx(0.94, abs=0.3)
    stereo_rms = float(re.search(r"stereo: \d+ pairs, RMS ([\d.]+) px", text).group(1))
    assert stereo_rms < 0.3  # measured 0.11 px


def test_folder_images_in_natural_order(tmp_path):
    """view_2 before view_10 (plain name order: view_10, view_11, view_2): the order --right pairs in."""
    for k in (1, 2, 10, 11):
        cv2.imwrite(str(tmp_path / f"view_{k}.png"), np.full((8, 8), k, np.uint8))
    assert [Path(n).name for n, _ in iter_frames([str(tmp_path)])] == [
        "view_1.png", "view_2.png", "view_10.png", "view_11.png"]
    got = [Path(n).name for n, _ in iter_frames([str(tmp_path / "view_*.png")])]
    assert got[:2] == ["view_1.png", "view_2.png"]


def test_every_with_images_only_is_refused(board_images, tmp_path, capsys):
    """--every applies to videos; with image inputs only it was silently ignored."""
    rc = main(["calibrate", str(board_images), "--every", "3", "--board", "9x6", "--square-m", "0.03",
               "--out", str(tmp_path / "c.yaml")])
    assert rc == 2 and not (tmp_path / "c.yaml").exists()
    err = capsys.readouterr().err
    n = len(list(board_images.glob("*.png")))
    assert err.startswith("fisheye-des: error: --every 3: takes every n-th frame of a video, and the inputs "
                          f"are {n} images, which are all used; expected a "
                          "video input, or no --every"), err
