"""``fisheye-des calibrate``: Kannala-Brandt calibration from checkerboard images or a video.

``fisheye-des calibrate IMAGES_OR_VIDEO... --board COLSxROWS --square-m S --out camchain.yaml``
(stereo: ``--right RIGHT_IMAGES_OR_VIDEO...``, frames paired in order: a folder's or glob's images in
natural name order, ``pipeline.sources.natural_key``)

Inputs may be image files, folders of images, glob patterns (quoted, so that the shell leaves them
alone) or video files (every ``--every``-th frame is used; every image is used, so ``--every`` with
image inputs only is an error). Corners are found with ``cv2.findChessboardCorners`` and refined
with ``cv2.cornerSubPix`` (falling back to ``cv2.findChessboardCornersSB``); views without the whole
board, and views ``cv2.fisheye.calibrate`` finds ill-conditioned, are rejected with the reason. The
result is written as a Kalibr camchain (``estimators.calibration.save_kalibr``; one camera ``cam0``,
assumed to look forward from the body origin: the extrinsics are not calibrated here), and the
per-view and overall RMS reprojection errors (px) are printed. With ``--right`` both cameras are
calibrated, then their relative pose with ``cv2.fisheye.stereoCalibrate`` (intrinsics fixed); the
camchain then holds cam0 (left) and cam1 (right) with ``T_cn_cnm1``, the body origin midway between
them.
"""

from __future__ import annotations

import glob as globmod
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from estimators.errors import CalibrationError, InputError, SourceError


@dataclass(frozen=True)
class Board:
    """A checkerboard: ``cols`` x ``rows`` inner corners, squares of ``square_m`` metres."""

    cols: int
    rows: int
    square_m: float

    @staticmethod
    def parse(spec: str, square_m: float) -> Board:
        """``"9x6"`` (inner corners per row x per column) and the square size in metres."""
        m = re.fullmatch(r"\s*(\d+)\s*[xX*]\s*(\d+)\s*", spec or "")
        if not m:
            raise InputError(f"--board: expected COLSxROWS inner corners such as 9x6, got {spec!r}")
        cols, rows = int(m.group(1)), int(m.group(2))
        if cols < 2 or rows < 2:
            raise InputError(f"--board: expected at least 2x2 inner corners, got {spec!r}")
        if not np.isfinite(square_m) or square_m <= 0:
            raise InputError(f"--square-m: expected a square size > 0 in metres, got {square_m!r}")
        return Board(cols, rows, float(square_m))

    def object_points(self) -> np.ndarray:
        """(cols*rows, 3) corner positions on the board plane z = 0, metres, row-major like OpenCV."""
        gx, gy = np.meshgrid(np.arange(self.cols), np.arange(self.rows))
        return np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1) * self.square_m


@dataclass
class ViewResult:
    """One input view: its name, the detected corners (N,2) px or None, and its fate."""

    name: str
    corners: np.ndarray | None
    used: bool = False
    rms_px: float | None = None
    reason: str = ""


@dataclass
class FisheyeCalibration:
    """Result of :func:`calibrate_views`.

    Attributes:
        model: the calibrated KannalaBrandt camera model.
        K: (3,3) camera matrix; D: (4,) coefficients, as cv2.fisheye returns them.
        rms_px: RMS reprojection error over all corners of the used views, px
            (sqrt of the mean squared 2-D residual norm).
        views: every view, used or rejected, with its RMS or the reason.
        rvecs, tvecs: board poses of the used views (cv2 convention), in ``views`` order.
        board: the checkerboard.
    """

    model: object
    K: np.ndarray
    D: np.ndarray
    rms_px: float
    views: list[ViewResult]
    rvecs: list[np.ndarray] = field(default_factory=list)
    tvecs: list[np.ndarray] = field(default_factory=list)
    board: Board | None = None

    @property
    def used(self) -> list[ViewResult]:
        return [v for v in self.views if v.used]


# ------------------------------------------------------------------------------------- inputs
def expand_inputs(inputs: list[str]) -> list[Path]:
    """The files of ``inputs`` (image files, folders, glob patterns, videos), in order: a folder's images
    and a glob's files in natural name order (``frame_2`` before ``frame_10``,
    ``pipeline.sources.natural_key``).

    Raises:
        SourceError: a path that does not exist, a folder without images, a pattern that matches nothing.
    """
    from pipeline.sources import IMAGE_SUFFIXES, natural_key

    out: list[Path] = []
    for spec in inputs:
        p = Path(spec)
        if p.is_dir():
            files = sorted((f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES), key=natural_key)
            if not files:
                raise SourceError(f"{spec}: folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
        elif p.is_file():
            files = [p]
        elif any(ch in spec for ch in "*?["):
            files = sorted((Path(f) for f in globmod.glob(spec) if Path(f).is_file()), key=natural_key)
            if not files:
                raise SourceError(f"{spec}: the pattern matches no files")
        else:
            raise SourceError(f"{spec}: no such file or folder")
        out += files
    return out


def iter_frames(inputs: list[str], every: int = 10) -> Iterator[tuple[str, np.ndarray]]:
    """Grey frames ``(name, (H,W) uint8)`` from image files, folders, glob patterns and videos.

    Images of a folder or glob are taken in natural name order (:func:`expand_inputs`); from a video
    every ``every``-th frame. A path that does not exist or cannot be decoded is a SourceError.
    """
    import cv2

    from pipeline.sources import IMAGE_SUFFIXES, VIDEO_SUFFIXES

    if every < 1:
        raise InputError(f"--every: expected an integer >= 1, got {every}")
    for f in expand_inputs(inputs):
        if f.suffix.lower() in VIDEO_SUFFIXES:
            yield from _video_frames(f, every)
            continue
        img = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
        if img is None:
            if f.suffix.lower() in IMAGE_SUFFIXES:
                raise SourceError(f"{f}: cannot be read as an image")
            yield from _video_frames(f, every)  # unknown suffix: let FFmpeg try
            continue
        yield str(f), img


def every_for(every: int | None, inputs: list[str]) -> int:
    """``--every`` as given, 10 by default; given with image inputs only it is refused (every image is
    used: it applies to videos, and files whose suffix is no image suffix are tried as videos).

    Raises:
        InputError: ``every`` given and no input file could be a video.
    """
    if every is None:
        return 10
    from pipeline.sources import IMAGE_SUFFIXES

    files = expand_inputs(inputs)
    if all(f.suffix.lower() in IMAGE_SUFFIXES for f in files):
        raise InputError(f"--every {every}: takes every n-th frame of a video, and the inputs are "
                         f"{len(files)} image{'s' if len(files) != 1 else ''}, which are all used; expected "
                         "a video input, or no --every (to use fewer images, give fewer)")
    return every


def _video_frames(path: Path, every: int) -> Iterator[tuple[str, np.ndarray]]:
    import cv2

    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        raise SourceError(f"{path}: cannot be opened as an image or a video")
    try:
        i = 0
        got_any = False
        while True:
            ok, frame = cap.read()
            if not ok:
                break
            got_any = True
            if i % every == 0:
                grey = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
                yield f"{path}#frame{i}", grey
            i += 1
        if not got_any:
            raise SourceError(f"{path}: the video has no readable frames")
    finally:
        cap.release()


# ------------------------------------------------------------------------------------ corners
def detect_corners(grey: np.ndarray, board: Board) -> np.ndarray | None:
    """Inner corners of ``board`` in a grey image -> (cols*rows, 2) px (sub-pixel), or None.

    ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` with a window below half the corner
    spacing; ``cv2.findChessboardCornersSB`` when the first finds nothing.
    """
    import cv2

    pattern = (board.cols, board.rows)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, c = cv2.findChessboardCorners(grey, pattern, flags)
    if ok:
        c = c.reshape(-1, 2).astype(np.float32)
        grid = c.reshape(board.rows, board.cols, 2)
        spacing = min(
            np.linalg.norm(np.diff(grid, axis=1), axis=2).min(),
            np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
        )
        hw = int(np.clip(0.3 * spacing, 2, 11))
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
        c = cv2.cornerSubPix(grey, c.reshape(-1, 1, 2), (hw, hw), (-1, -1), crit)
        return c.reshape(-1, 2).astype(np.float64)
    ok, c = cv2.findChessboardCornersSB(grey, pattern, cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if ok:
        return c.reshape(-1, 2).astype(np.float64)
    return None


# -------------------------------------------------------------------------------- calibration
def calibrate_views(
    views: list[ViewResult],
    board: Board,
    image_size: tuple[int, int],
    max_angle_rad: float | None = None,
    min_views: int = 3,
    outlier_factor: float = 5.0,
    outlier_min_px: float = 1.0,
) -> FisheyeCalibration:
    """``cv2.fisheye.calibrate`` over the views with corners; ill-conditioned views and outliers are dropped.

    Args:
        views: detected views (``corners`` (N,2) px or None for failed detection).
        board: the checkerboard.
        image_size: (width, height) px.
        max_angle_rad: optional lens half-FOV for the resulting model.
        min_views: fewest usable views to attempt a calibration.
        outlier_factor, outlier_min_px: a view whose RMS exceeds both ``outlier_factor`` times the
            median view RMS and ``outlier_min_px`` is rejected and the calibration rerun.
    """
    import cv2

    from estimators.cameras import KannalaBrandt

    obj = board.object_points()
    active = [v for v in views if v.corners is not None]
    if len(active) < min_views:
        raise CalibrationError(
            f"calibrate: the board ({board.cols}x{board.rows} inner corners) was found in {len(active)} of "
            f"{len(views)} views; at least {min_views} are needed (check --board COLSxROWS)"
        )
    w, h = int(image_size[0]), int(image_size[1])
    flags = (
        cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC
        | cv2.fisheye.CALIB_FIX_SKEW
        | cv2.fisheye.CALIB_USE_INTRINSIC_GUESS
        | cv2.fisheye.CALIB_CHECK_COND
    )
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)

    def run(vs: list[ViewResult]):
        # cv2.fisheye initialises the board poses on the z=1 plane with the guessed K and D = 0,
        # which fails (ill-conditioned views) when the guess puts corners near or past 90 degrees.
        # Guess an equidistant focal length from the farthest corner, assumed at `a` rad off the
        # axis, for a few values of `a`; the first that converges wins.
        pts = np.concatenate([v.corners for v in vs])
        r_max = float(np.hypot(pts[:, 0] - (w - 1) / 2, pts[:, 1] - (h - 1) / 2).max())
        objp = [obj.reshape(1, -1, 3).astype(np.float64) for _ in vs]
        imgp = [v.corners.reshape(1, -1, 2).astype(np.float64) for v in vs]
        flagged: list[int] = []
        last = ""
        for a in (1.2, 1.0, 1.4, 0.8, 1.6):
            f0 = max(r_max / a, 1.0)
            K0 = np.array([[f0, 0.0, (w - 1) / 2], [0.0, f0, (h - 1) / 2], [0.0, 0.0, 1.0]])
            try:
                _, K, D, rvecs, tvecs = cv2.fisheye.calibrate(
                    objp, imgp, (w, h), K0, np.zeros((4, 1)), flags=flags, criteria=crit
                )
                return K, D.reshape(-1), list(rvecs), list(tvecs), None
            except cv2.error as e:
                last = str(e).strip().splitlines()[-1] if str(e).strip() else repr(e)
                m = re.search(r"input array (\d+)", str(e))
                if m and int(m.group(1)) < len(vs):
                    flagged.append(int(m.group(1)))
        return None, None, None, None, (flagged[0] if flagged else None, last)

    def per_view_sq(vs, K, D, rvecs, tvecs):
        out = []
        for v, r, t in zip(vs, rvecs, tvecs, strict=True):
            proj, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), r, t, K, D)
            out.append(np.sum((proj.reshape(-1, 2) - v.corners) ** 2, axis=1))
        return out

    for _ in range(len(active)):
        if len(active) < min_views:
            raise CalibrationError(
                f"calibrate: only {len(active)} usable views left; at least {min_views} are needed"
            )
        K, D, rvecs, tvecs, failure = run(active)
        if failure is not None:
            idx, msg = failure
            if idx is None:
                raise CalibrationError(f"calibrate: cv2.fisheye.calibrate failed: {msg}")
            bad = active.pop(idx)
            bad.reason = "ill-conditioned in cv2.fisheye.calibrate (CALIB_CHECK_COND)"
            continue
        # Views far worse than the rest (a misdetected corner, motion blur) are dropped once each.
        sq = per_view_sq(active, K, D, rvecs, tvecs)
        rms_v = np.array([np.sqrt(e.mean()) for e in sq])
        limit = max(outlier_factor * float(np.median(rms_v)), outlier_min_px)
        worst = int(np.argmax(rms_v))
        if rms_v[worst] > limit and len(active) > min_views:
            bad = active.pop(worst)
            bad.rms_px = float(rms_v[worst])
            bad.reason = (f"reprojection outlier: rms {rms_v[worst]:.2f} px > {limit:.2f} px "
                          f"({outlier_factor:g} x the median view)")
            continue
        break
    else:  # pragma: no cover - the loop always ends by break or raise
        raise CalibrationError("calibrate: no stable calibration found")
    for v, e2 in zip(active, sq, strict=True):
        v.used = True
        v.rms_px = float(np.sqrt(e2.mean()))
    rms = float(np.sqrt(np.concatenate(sq).mean()))
    model = KannalaBrandt(
        fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2], width=int(image_size[0]), height=int(image_size[1]),
        k1=D[0], k2=D[1], k3=D[2], k4=D[3], max_angle_rad=max_angle_rad,
    )
    return FisheyeCalibration(model, K, D, rms, views, list(rvecs), list(tvecs), board)


def detect_views(
    inputs: list[str], board: Board, every: int = 10, echo=None
) -> tuple[list[ViewResult], tuple[int, int]]:
    """Read the inputs and detect the board in every frame -> (views, (width, height) px)."""
    views: list[ViewResult] = []
    size: tuple[int, int] | None = None
    for name, grey in iter_frames(inputs, every):
        h, w = grey.shape[:2]
        if size is None:
            size = (w, h)
        if (w, h) != size:
            reason = f"image size {w}x{h} differs from {size[0]}x{size[1]}"
            views.append(ViewResult(name, None, reason=reason))
            continue
        c = detect_corners(grey, board)
        views.append(ViewResult(name, c, reason="" if c is not None else "board not found"))
        if echo is not None:
            echo(f"  {name}: {'board found' if c is not None else 'board not found'}")
    if size is None:
        raise SourceError("calibrate: no frames were read from the inputs")
    return views, size


def calibrate_inputs(
    inputs: list[str], board: Board, every: int = 10, max_angle_rad: float | None = None, echo=None
) -> FisheyeCalibration:
    """Read the inputs, detect the board in every frame and calibrate (see :func:`calibrate_views`)."""
    views, size = detect_views(inputs, board, every, echo)
    return calibrate_views(views, board, size, max_angle_rad=max_angle_rad)


@dataclass
class StereoCalibration:
    """Result of :func:`calibrate_stereo_views`.

    Attributes:
        left, right: the per-camera calibrations (cam0, cam1).
        T_c1_c0: pose of cam0 in cam1, ``p_c1 = R p_c0 + t`` (Kalibr's ``T_cn_cnm1`` of cam1), metres.
        rms_px: RMS reprojection error of ``cv2.fisheye.stereoCalibrate`` (intrinsics fixed), px.
        pairs: names of the (left, right) pairs used.
        rig: the stereo rig; B is centred between the cameras with the axes of cam0's forward mount.
    """

    left: FisheyeCalibration
    right: FisheyeCalibration
    T_c1_c0: object
    rms_px: float
    pairs: list[tuple[str, str]]
    rig: object

    @property
    def baseline_m(self) -> float:
        return float(np.linalg.norm(self.T_c1_c0.t))


def _flip_board_pose(rvec: np.ndarray, tvec: np.ndarray, board: Board) -> tuple[np.ndarray, np.ndarray]:
    """Board pose for the corners numbered from the other end (the board turned 180 deg about its z)."""
    import cv2

    R, _ = cv2.Rodrigues(rvec)
    # reversed numbering: p_board = F p_board', F = Rz(180 deg) p' + ((cols-1) s, (rows-1) s, 0)
    Rf = np.diag([-1.0, -1.0, 1.0])
    tf = np.array([(board.cols - 1) * board.square_m, (board.rows - 1) * board.square_m, 0.0])
    R2 = R @ Rf
    t2 = R @ tf + tvec.reshape(3)
    return cv2.Rodrigues(R2)[0], t2


def calibrate_stereo_views(
    left_views: list[ViewResult],
    right_views: list[ViewResult],
    board: Board,
    size_left: tuple[int, int],
    size_right: tuple[int, int],
    max_angle_rad: float | None = None,
) -> StereoCalibration:
    """Calibrate both cameras, then their relative pose with ``cv2.fisheye.stereoCalibrate``.

    ``left_views[i]`` and ``right_views[i]`` are simultaneous frames. Pairs where both cameras'
    views were used by their own calibration feed the stereo step. The detector may number a
    board's corners from either end; per pair the right camera's numbering is flipped when that
    makes the relative rotation smaller (the cameras of a stereo pair look roughly the same way).
    """
    import cv2

    from estimators.rig import Camera, Rig, forward_T_C_B
    from estimators.se3 import Pose

    if len(left_views) != len(right_views):
        raise InputError(
            f"calibrate --right: expected as many right frames as left frames (pairs in natural name order); "
            f"got {len(left_views)} left and {len(right_views)} right"
        )
    left = calibrate_views(left_views, board, size_left, max_angle_rad=max_angle_rad)
    right = calibrate_views(right_views, board, size_right, max_angle_rad=max_angle_rad)
    pose_l = {v.name: (r, t) for v, r, t in zip(left.used, left.rvecs, left.tvecs, strict=True)}
    pose_r = {v.name: (r, t) for v, r, t in zip(right.used, right.rvecs, right.tvecs, strict=True)}
    objp, img_l, img_r, pairs = [], [], [], []
    obj = board.object_points()
    for vl, vr in zip(left_views, right_views, strict=True):
        if not (vl.used and vr.used):
            continue
        rl, tl = pose_l[vl.name]
        Rl = cv2.Rodrigues(rl)[0]
        best = None
        for flip in (False, True):
            rr, tr = pose_r[vr.name]
            if flip:
                rr, tr = _flip_board_pose(rr, tr, board)
            # relative rotation R_c1_c0 = R_c1_board R_board_c0
            Rrel = cv2.Rodrigues(rr)[0] @ Rl.T
            ang = float(np.arccos(np.clip((np.trace(Rrel) - 1) / 2, -1.0, 1.0)))
            if best is None or ang < best[0]:
                best = (ang, flip)
        corners_r = vr.corners[::-1] if best[1] else vr.corners
        objp.append(obj.reshape(1, -1, 3).astype(np.float64))
        img_l.append(vl.corners.reshape(1, -1, 2).astype(np.float64))
        img_r.append(corners_r.reshape(1, -1, 2).astype(np.float64))
        pairs.append((vl.name, vr.name))
    if len(pairs) < 3:
        raise CalibrationError(
            f"calibrate --right: the board was usable in both cameras in {len(pairs)} pairs; "
            "at least 3 are needed"
        )
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        out = cv2.fisheye.stereoCalibrate(
            objp, img_l, img_r, left.K, left.D.reshape(4, 1), right.K, right.D.reshape(4, 1),
            tuple(size_left), flags=cv2.fisheye.CALIB_FIX_INTRINSIC, criteria=crit,
        )
    except cv2.error as e:
        msg = str(e).strip()
        raise CalibrationError(f"calibrate --right: cv2.fisheye.stereoCalibrate failed: {msg}") from None
    rms, R, T = float(out[0]), np.asarray(out[5], dtype=float), np.asarray(out[6], dtype=float).reshape(3)
    T_c1_c0 = Pose(R, T)
    # B: axes of cam0's forward mount, origin midway between the camera centres.
    R_B_C0 = forward_T_C_B().R.T
    d_B = R_B_C0 @ T_c1_c0.inverse().t  # cam1's centre relative to cam0's, in B
    T_C0_B = forward_T_C_B(-0.5 * d_B)
    rig = Rig((Camera("cam0", left.model, T_C0_B), Camera("cam1", right.model, T_c1_c0 @ T_C0_B)))
    return StereoCalibration(left, right, T_c1_c0, rms, pairs, rig)


# ------------------------------------------------------------------------------------ command
def register(app: typer.Typer) -> None:
    @app.command("calibrate")
    def calibrate(
        inputs: Annotated[
            list[str], typer.Argument(help="Checkerboard images, folders, glob patterns or videos.")
        ],
        board: Annotated[str, typer.Option("--board", help="Inner corners COLSxROWS, e.g. 9x6.")],
        square_m: Annotated[float, typer.Option("--square-m", help="Checkerboard square size in metres.")],
        out: Annotated[Path, typer.Option("--out", help="Kalibr camchain.yaml to write.")] = Path(
            "camchain.yaml"
        ),
        model: Annotated[
            str, typer.Option("--model", help="Camera model to fit (kannala_brandt only: cv2.fisheye's).")
        ] = "kannala_brandt",
        every: Annotated[
            int | None,
            typer.Option("--every", help="Use every n-th frame of a video (default 10); images are all used, "
                         "so --every with image inputs only is an error."),
        ] = None,
        max_angle_deg: Annotated[
            float | None, typer.Option("--max-angle-deg", help="Lens half field of view to record (degrees).")
        ] = None,
        verbose: Annotated[
            bool, typer.Option("--verbose", "-v", help="Print every frame's detection.")
        ] = False,
        right: Annotated[
            list[str] | None,
            typer.Option(
                "--right",
                help="Stereo: the right camera's images/folder/glob/video (repeatable); frames pair "
                "with the inputs in natural name order (frame_2 before frame_10). Writes a 2-camera "
                "camchain with T_cn_cnm1.",
            ),
        ] = None,
    ) -> None:
        """Calibrate a fisheye camera (Kannala-Brandt, cv2.fisheye) and write a Kalibr camchain."""
        from estimators.calibration import save_kalibr
        from estimators.rig import Camera, Rig, forward_T_C_B

        if model != "kannala_brandt":
            raise InputError(f"--model: {model!r} cannot be calibrated here; expected: kannala_brandt")
        b = Board.parse(board, square_m)
        every = every_for(every, list(inputs) + list(right or []))
        max_rad = None if max_angle_deg is None else float(np.radians(max_angle_deg))
        echo = typer.echo if verbose else None
        if right:
            lv, ls = detect_views(inputs, b, every, echo)
            rv, rs = detect_views(right, b, every, echo)
            st = calibrate_stereo_views(lv, rv, b, ls, rs, max_angle_rad=max_rad)
            for label, res in (("cam0 (left)", st.left), ("cam1 (right)", st.right)):
                typer.echo(f"{label}:")
                _report(res)
            typer.echo(
                f"stereo: {len(st.pairs)} pairs, RMS {st.rms_px:.3f} px, "
                f"baseline {st.baseline_m * 1000:.1f} mm, "
                f"t_c1_c0 {np.array2string(st.T_c1_c0.t, precision=4)} m"
            )
            save_kalibr(st.rig, out)
        else:
            res = calibrate_inputs(inputs, b, every=every, max_angle_rad=max_rad, echo=echo)
            _report(res)
            save_kalibr(Rig((Camera("cam0", res.model, forward_T_C_B()),)), out)
        typer.echo(f"wrote {out}")


def _report(res: FisheyeCalibration) -> None:
    typer.echo(f"views: {len(res.views)} read, {len(res.used)} used")
    for v in res.views:
        if v.used:
            typer.echo(f"  {v.name}: rms {v.rms_px:.3f} px")
        else:
            typer.echo(f"  {v.name}: rejected ({v.reason})")
    m = res.model
    typer.echo(
        f"kannala_brandt: fx {m.fx:.3f} fy {m.fy:.3f} cx {m.cx:.3f} cy {m.cy:.3f} "
        f"k1..k4 {m.k1:.6f} {m.k2:.6f} {m.k3:.6f} {m.k4:.6f} ({m.width}x{m.height} px)"
    )
    typer.echo(f"overall RMS reprojection error: {res.rms_px:.3f} px")
    seen_deg, lens_deg = board_coverage_deg(res)
    typer.echo(f"board corners seen up to {seen_deg:.1f} deg off the optical axis; the camchain's lens half "
               f"field (max_angle_rad) is {lens_deg:.1f} deg: bearings beyond {seen_deg:.1f} deg are "
               "extrapolated" + (" (--max-angle-deg sets the lens's half field)" if lens_deg > seen_deg + 5
                                 else ""))


def board_coverage_deg(res: FisheyeCalibration) -> tuple[float, float]:
    """(the largest angle off the optical axis of a used view's board corner, the model's
    ``max_angle_rad``), degrees: the calibration is fitted up to the first; between the two the lens
    model is an extrapolation."""
    uv = np.concatenate([v.corners for v in res.used]).reshape(-1, 2)
    b, valid = res.model.pixel_to_bearing(uv, within_image=False)
    seen = np.degrees(np.arccos(np.clip(b[valid, 2], -1.0, 1.0)))
    return float(seen.max()) if seen.size else 0.0, float(np.degrees(res.model.max_angle_rad))
