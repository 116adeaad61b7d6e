"""Feature tracking on the raw fisheye frame of one camera: KLT with a forward-backward check,
re-detection where coverage thins, ORB descriptors to re-acquire features lost for a few frames.

Everything happens in the distorted image (no dewarping), masked to the lens's image circle; each
feature's pixel position is turned into a unit bearing by the camera model (valid beyond 90 degrees
off-axis) in the camera frame C and the body frame B. Memory is bounded: at most ``max_features``
live features plus a pool of recently lost ones, each with a ring buffer of ``history`` samples.
"""

from __future__ import annotations

import itertools
import pickle
import uuid
import weakref
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import cv2
import numpy as np

from estimators.errors import ConfigError, InputError
from estimators.geometry import _isin
from trackers.clock import FrameClock, check_durations
from trackers.detectors.base import Detector
from trackers.detectors.orb import OrbDetector, bucket


@dataclass(frozen=True)
class Features:
    """The live features of one camera in one frame.

    Attributes:
        camera: camera name.
        ids: (N,) int64 feature ids, stable over each feature's life (unique over all cameras).
        uv: (N, 2) float32 pixel positions (OpenCV convention).
        b_C: (N, 3) unit bearings in the camera optical frame C.
        b_B: (N, 3) unit bearings in the body frame B (rotation only: directions, not positions).
        age: (N,) int frames each feature has been tracked (1 = detected this frame).
    """

    camera: str
    ids: np.ndarray
    uv: np.ndarray
    b_C: np.ndarray
    b_B: np.ndarray
    age: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class FeatureHistory:
    """The recent past of one feature, oldest first (at most the tracker's ``history`` samples).

    Attributes:
        uv: (K, 2) pixels; b_C: (K, 3) unit bearings in C; b_B: (K, 3) unit bearings in B;
        t_s: (K,) frame times in seconds; frame: (K,) frame indices.
    """

    uv: np.ndarray
    b_C: np.ndarray
    b_B: np.ndarray
    t_s: np.ndarray
    frame: np.ndarray


MAX_FEATURES = 500  # FeatureTracker's largest derived feature budget (a 720p lens's)
MIN_FEATURES = 250  # and its smallest
# the KLT window (tracked px, square): FeatureTracker's win_px default; the front end's stereo KLT and
# the fusion's window angle take the tracker's window (trackers.frontend.tracked_window)
KLT_WIN_PX = 11
POPCOUNT8 = np.array([bin(i).count("1") for i in range(256)], np.int64)  # bits set per byte value


@dataclass(frozen=True)
class _DetectJob:
    """What a detection reads of a FeatureTracker's state (``FeatureTracker._detect_job``), copied at
    the detection's frame: the room for new features (``free``), the live features' pixels uv (N, 2)
    (the mask new keypoints keep away from), the lost features' predicted pixels at the frame's time
    pred (L, 2), ids lost_ids (L,) and descriptors lost_desc (L, 32)."""

    free: int
    uv: np.ndarray
    pred: np.ndarray
    lost_ids: np.ndarray
    lost_desc: np.ndarray


@dataclass(frozen=True)
class _Found:
    """A detection's result (``_Finder.find``): keypoints uv (K, 2) float32 frame px, their
    descriptors (K, 32) uint8 or None, and lost_id (K,) the id of the lost feature each re-acquires
    (-1: a new feature)."""

    uv: np.ndarray
    desc: np.ndarray | None
    lost_id: np.ndarray

    @staticmethod
    def empty() -> _Found:
        return _Found(np.zeros((0, 2), np.float32), None, np.zeros(0, np.int64))


# the finders loaded where deferred detections run (``FeatureTracker.defer_detection``): each tracker's,
# sent once and loaded by ``_Finder.ready`` under the key the tracker holds (a worker process's registry;
# an executor in this process shares this one, and a tracker's entry goes with the tracker)
_FINDERS: dict[str, _Finder] = {}


@dataclass(frozen=True)
class _Finder:
    """A FeatureTracker's detection proper (``find``), apart from the tracker's state so that it may run
    in a worker (thread or process: picklable, with the detector) on a ``_DetectJob``: the tracker's
    detector, lens mask, the box the detector reads (``FeatureTracker.frame_box``), frame (H, W), grid,
    spacing and re-acquisition settings."""

    detector: Detector
    mask: np.ndarray
    box: tuple[int, int, int, int]
    shape_hw: tuple[int, int]
    grid: tuple[int, int]
    min_distance_px: float
    reacquire_radius_px: float
    reacquire_max_hamming: int

    @staticmethod
    def ready(key: str, blob: bytes) -> bool:
        """Load the finder pickled in ``blob`` where this runs and keep it under ``key`` for the deferred
        detections (``find_loaded``): ``defer_detection``'s set-up of its worker, which also checks that
        the detector's code imports there. Unpickled here, in the job, so that a detector the worker
        cannot load is this job's error, with its cause, not a worker process dying while it reads the
        job (``BrokenProcessPool``, the cause only in the worker's traceback)."""
        _FINDERS[key] = pickle.loads(blob)
        return True

    @staticmethod
    def find_loaded(key: str, job: _DetectJob, part: np.ndarray) -> _Found:
        """A deferred detection (``defer_detection``): ``find`` of the finder loaded under ``key``
        (``ready``), so that a job carries only the key, the state and the part of the frame."""
        finder = _FINDERS.get(key)
        if finder is None:
            raise RuntimeError(f"no finder {key!r} loaded where this detection runs (no _Finder.ready there)")
        return finder.find(job, part)

    def part(self, image: np.ndarray) -> np.ndarray:
        """The part of a full frame ``image`` that ``find`` reads, a view: ``box`` (ORB's: the lens's
        bounding box + 32 px, or the whole frame; the whole frame for other detectors)."""
        x0, y0, x1, y1 = self.box
        return image[y0:y1, x0:x1]

    def find(self, job: _DetectJob, part: np.ndarray) -> _Found:
        """The detection proper, on ``part``, the frame's ``box`` (``part(image)``), against the state
        copied in ``job``: the keypoints to add (frame px, descriptors) and the lost feature each
        re-acquires (its id, -1 for a new feature). Reads only ``job``, ``part`` and these settings, so
        it may run in another thread or process."""
        free = job.free
        # ORB runs on the lens's bounding box (``_det_box``: roi + 32 px, so that its coarse
        # levels see real pixels past the rim, not a reflected crop border), and describes only the
        # keypoints that can be kept; other detectors get the whole frame (their box)
        orb = isinstance(self.detector, OrbDetector)
        x0, y0, x1, y1 = self.box
        if part.shape[:2] != (y1 - y0, x1 - x0):
            raise InputError(
                f"detection: the frame part is {part.shape[1]}x{part.shape[0]} px, expected the box "
                f"{self.box} ({x1 - x0}x{y1 - y0} px)"
            )
        m = self.mask[y0:y1, x0:x1].copy()
        r = max(1, int(round(self.min_distance_px)))
        # keep new keypoints away from live features (int32 truncates as int() does; a list of
        # Python ints: the loop over numpy rows cost as much again as cv2.circle itself)
        for u, v in (job.uv.astype(np.int32) - np.array([x0, y0], np.int32)).tolist():
            cv2.circle(m, (u, v), r, 0, -1)
        if orb:
            det = self.detector.detect(
                part,
                m,
                origin=(x0, y0),
                frame_hw=self.shape_hw,
                select=lambda uv, _sc: self._worth_describing(uv, free, job),
            )
            if len(det):
                det = replace(det, keypoints=det.keypoints + np.array([x0, y0], np.float32))
        else:
            det = self.detector.detect(part, m)
        if not len(det):
            return _Found.empty()
        uv = det.keypoints
        ui = np.clip(np.round(uv[:, 0]).astype(np.intp) - x0, 0, x1 - x0 - 1)
        vi = np.clip(np.round(uv[:, 1]).astype(np.intp) - y0, 0, y1 - y0 - 1)
        inside = m.take(vi * m.shape[1] + ui) > 0
        det = det.select(inside)
        uv = uv.compress(inside, 0)
        if not len(uv):
            return _Found.empty()
        desc_all = (
            det.descriptors
            if det.descriptors is not None
            and det.descriptors.shape[1] == 32
            and det.descriptors.dtype == np.uint8
            else None
        )
        # a full tracker's ORB described only the keypoints near a lost feature (_worth_describing:
        # ORB's compute keeps their positions), so all of them are re-acquisition candidates and no
        # new feature is kept: neither the search for candidates nor the spacing of new ones again
        only_reacq = orb and free <= 0
        # re-acquisition first: lost features come back whatever the free capacity (their slots
        # are still held), so live features may briefly exceed max_features by the lost pool
        reacq_all = np.full(len(uv), -1, np.intp)
        if desc_all is not None and len(job.lost_ids):
            cand = np.arange(len(uv)) if only_reacq else self._near_lost(uv, job.pred)
            reacq_all = self._match_lost(uv, desc_all, cand, job.pred, job.lost_desc)
        re = (reacq_all >= 0).nonzero()[0]
        if only_reacq:
            keep = re
        else:
            # prefer keypoints in thin cells: round-robin over the grid, strongest first
            order = bucket(uv, det.scores, self.shape_hw, self.grid, per_cell=10**6)
            # spacing among the new ones: at most one per min_distance_px cell of a coarse grid
            # (the first in ``order`` wins), none in a cell of a re-acquired feature
            key = self._spacing_cells(uv)
            cand = order[reacq_all[order] < 0]
            cand = cand[~_isin(key[cand], key[re])]
            _, first = np.unique(key[cand], return_index=True)
            new_idx = cand[np.sort(first)][: max(free, 0)]
            keep = np.asarray(list(re) + list(new_idx), np.intp)
        reacq = reacq_all[keep]
        lost_id = np.where(reacq >= 0, job.lost_ids[np.maximum(reacq, 0)] if len(job.lost_ids) else -1, -1)
        return _Found(uv[keep], None if desc_all is None else desc_all[keep], lost_id)

    def _worth_describing(self, uv: np.ndarray, free: int, job: _DetectJob) -> np.ndarray:
        """Indices of the keypoints uv (K, 2) frame px (the detector's round-robin order) that
        ``_Finder.find`` may keep: those that may re-acquire a lost feature (of ``job``'s lost pool), and the
        first ``free`` (plus as many again as there are re-acquisition candidates, whose cells new ones
        avoid) of one per min_distance_px cell. Only these get ORB descriptors (at 720p ~600 -> ~100 per
        detection). With no room (``free`` <= 0) no new feature is kept, so only the re-acquisition
        candidates."""
        near = np.zeros(0, np.intp)
        if len(job.lost_ids):
            near = self._near_lost(uv, job.pred)
        if free <= 0:
            return near
        _, first = np.unique(self._spacing_cells(uv), return_index=True)
        new = np.sort(first)[: max(free, 0) + len(near)]
        return np.union1d(near, new)

    def _spacing_cells(self, uv: np.ndarray) -> np.ndarray:
        """The cell key of each keypoint uv (N, 2) px in a grid of min_distance_px (at least 1 px) cells,
        the new features' spacing (one per cell)."""
        cell = max(1.0, self.min_distance_px)
        gw = int(self.shape_hw[1] // cell) + 2
        return (uv[:, 1] // cell).astype(np.int64) * gw + (uv[:, 0] // cell).astype(np.int64)

    def _near_lost(self, uv: np.ndarray, pred: np.ndarray) -> np.ndarray:
        """Indices of the keypoints uv (N, 2) px that may re-acquire a lost feature: in a grid cell
        of the search radius next to a lost feature's predicted position, pred (L, 2) px
        (``_lost_predictions``)."""
        if not len(pred) or not len(uv):
            return np.zeros(0, np.intp)
        r = self.reacquire_radius_px
        gw = int(self.shape_hw[1] // r) + 3
        kc = (uv // r).astype(np.int64)
        pc = (pred // r).astype(np.int64)
        # the 3x3 cells around each prediction, (L, 3, 3) keys (y + dy) gw + (x + dx), in numpy (a
        # Python set of them took ~2 ms per detection with a few hundred lost features)
        d = np.arange(-1, 2, dtype=np.int64)
        near_cells = (pc[:, 1, None, None] + d[None, :, None]) * gw + (
            pc[:, 0, None, None] + d[None, None, :]
        )
        return _isin(kc[:, 1] * gw + kc[:, 0], near_cells.ravel()).nonzero()[0]

    def _match_lost(
        self, uv: np.ndarray, desc: np.ndarray, cand: np.ndarray, pred: np.ndarray, lost_desc: np.ndarray
    ) -> np.ndarray:
        """For each new keypoint uv (N, 2) px with descriptor desc (N, 32), the index of the lost
        feature it re-acquires, or -1; only the candidates ``cand`` (indices, ``_near_lost``) are
        matched against the lost features' predicted positions pred (L, 2) px and descriptors
        lost_desc (L, 32)."""
        out = np.full(len(uv), -1, np.intp)
        r = self.reacquire_radius_px
        if not len(cand):
            return out
        du = uv[cand, 0, None] - pred[None, :, 0]  # (c, L) squared px (as in _neighbour_velocity)
        dv = uv[cand, 1, None] - pred[None, :, 1]
        d2 = du * du + dv * dv
        near = d2 <= r**2
        if not near.any():
            return out
        # Hamming distances of 32-byte descriptors (popcount of XOR), for the near pairs only
        ii, jj = np.nonzero(near)
        ham = np.full(near.shape, 10**6, np.int64)
        xor = np.bitwise_xor(desc.take(cand[ii], 0), lost_desc.take(jj, 0))
        ham[ii, jj] = POPCOUNT8[xor].sum(axis=1)
        taken: set[int] = set()
        srt = np.sort(ham, axis=1)
        second = srt[:, 1] if ham.shape[1] > 1 else np.full(len(ham), 10**6)
        best = np.argmin(ham, axis=1)
        ok = (srt[:, 0] <= self.reacquire_max_hamming) & (srt[:, 0] < 0.8 * second)
        for i in ok.nonzero()[0][np.argsort(srt[ok, 0], kind="stable")]:
            j = int(best[i])
            # distinctive (Lowe's ratio 0.8 against the second-best lost feature) and close enough
            if ham[i, j] <= self.reacquire_max_hamming and ham[i, j] < 0.8 * second[i] and j not in taken:
                out[cand[i]] = j
                taken.add(j)
        return out


def lens_mask(model, margin_px: float = 3.0) -> np.ndarray:
    """(H, W) uint8 mask, 255 inside the lens's image circle shrunk by ``margin_px``, else 0.

    ``model`` is an ``estimators.cameras.CameraModel`` (``width``, ``height``, ``image_circle()``).
    A circle larger than the frame (a cropped / full-frame fisheye) is clipped to the frame.
    Raises InputError when the circle's centre lies outside the frame or its radius is < 8 px.
    """
    w, h = int(model.width), int(model.height)
    cx, cy, r = model.image_circle()
    if not (np.isfinite(r) and np.isfinite(cx) and np.isfinite(cy)):
        raise InputError(f"lens circle: expected a finite (cx, cy, radius), got {(cx, cy, r)}")
    if not (-0.5 <= cx <= w - 0.5 and -0.5 <= cy <= h - 0.5) or r < 8:
        raise InputError(
            f"lens circle (cx={cx:.1f}, cy={cy:.1f}, r={r:.1f} px) does not fit a {w}x{h} frame: "
            "expected its "
            "centre inside the frame and a radius of at least 8 px"
        )
    m = np.zeros((h, w), np.uint8)
    rr = max(1.0, r - margin_px)
    # cv2.circle with 4 fractional bits: centre and radius in 1/16 px.
    cv2.circle(m, (round(cx * 16), round(cy * 16)), round(rr * 16), 255, -1, cv2.LINE_8, 4)
    e = int(np.ceil(margin_px))  # keep features away from the frame border too (KLT window)
    if e > 0:
        m[:e], m[-e:], m[:, :e], m[:, -e:] = 0, 0, 0, 0
    return m


def _median(x: np.ndarray) -> float:
    """``float(np.median(x))`` of a non-empty 1-D float array, the same number for a fraction of the
    call (~20 us instead of ~80-120 us for 600 float32 values): the middle element of a partition, or
    the mean of the two middle ones as np.median takes it (their sum in x's dtype, halved in it); a
    NaN anywhere (np.median's answer is then NaN) goes to np.median itself."""
    n = len(x)
    k = n // 2
    part = np.partition(x, k if n % 2 else (k - 1, k))
    if np.isnan(part[k:]).any():  # (a NaN sorts last)
        return float(np.median(x))
    if n % 2:
        return float(part[k])
    return float((part[k - 1] + part[k]) / 2)  # numpy scalars: x's dtype throughout, as np.mean


def _check_int(name: str, value) -> None:
    """Raise ConfigError unless ``value`` is an integer (int or numpy integer, not a bool)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ConfigError(
            f"FeatureTracker: {name} must be an integer; got {value!r} ({type(value).__name__})"
        )


def klt_window_px(win_px=KLT_WIN_PX) -> int:
    """The side (px of the tracked image) of the square KLT window of the ``win_px`` setting: the
    one window the temporal KLT, the stereo KLT and the fusion's window angle take
    (``trackers.frontend.tracked_window``).

    Raises ConfigError unless win_px is an integer >= 3 (OpenCV's LK needs a window over 2 px).
    """
    _check_int("win_px", win_px)
    if win_px < 3:
        raise ConfigError(f"FeatureTracker: win_px (KLT window, px) expected an integer >= 3, got {win_px!r}")
    return int(win_px)


#: ``_lk_part``'s slack (coarsest-level px) around a search's expected path (``band``): how far its
#: coarse steps may stray from it and still read the pixels the whole image has there
BAND_SLACK = 2


def _lk_box(pts: np.ndarray, margin: float, shape: tuple[int, ...], align: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) px of an image of ``shape`` (H, W, ...) holding every point of ``pts`` (K, 2)
    px with ``margin`` px around, its origin on a multiple of ``align`` px (so the part's pyramid
    levels sample the image's own grid), clipped to the image; the whole image when no point is
    finite (a non-finite one is ignored: LK reports it lost)."""
    if not len(pts):
        return 0, 0, shape[1], shape[0]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    # every point finite exactly when hi - lo is (a NaN propagates through min and max; an infinite
    # extreme makes the difference infinite or NaN): the finite points' extremes are then these, and
    # only otherwise is the filter run
    if not np.isfinite(hi - lo).all():
        pts = pts.compress(np.isfinite(pts).all(axis=1), 0)
        if not len(pts):
            return 0, 0, shape[1], shape[0]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
    lo = np.floor(lo - margin)
    hi = np.ceil(hi + margin) + 1
    x0 = max(int(lo[0]) // align * align, 0)
    y0 = max(int(lo[1]) // align * align, 0)
    return x0, y0, min(int(hi[0]), shape[1]), min(int(hi[1]), shape[0])


def _lk_part(
    grey_prev: np.ndarray,
    grey_next: np.ndarray,
    p_prev: np.ndarray,
    p_next: np.ndarray,
    win_px: int,
    level: int,
    crit: tuple,
    box_prev: np.ndarray | None = None,
    flags: int = cv2.OPTFLOW_USE_INITIAL_FLOW,
    band: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``cv2.calcOpticalFlowPyrLK`` from ``p_prev`` (K, 1, 2) float32 in grey_prev, starting at
    ``p_next`` (K, 1, 2) float32 in grey_next, on the parts of the two images the search can read.

    LK's cost per call is mostly building both images' pyramids (and the previous image's
    derivatives), so it runs on the box of the points instead of the whole image: the previous
    image's box holds every window at every level with the reach of the pyramid's 5-tap filter
    (``(win_px // 2 + 6) 2^level`` px around the points), the next image's box that plus the
    search's reach around the starts (how far a point may travel: the coarsest level's window in
    full-resolution px, ``(win_px // 2) 2^(level + 1)``); LK runs on their union in both
    images (its two images have one size), its origin on a multiple of ``2^level`` px, so each
    level samples the full image's own grid: inside the box every pixel LK reads equals the whole
    image's. The answers still differ from the whole images' in the last bits (LK works in the part's
    float32 pixels, whose sums round otherwise), which an ill-conditioned window can carry to ~1 px
    (the same jump as its start moved by 1e-3 px on the whole images). A point whose search goes
    farther than that reach from its start reads the part's edge (OpenCV's reflected border where
    the whole image has pixels): it may be lost (status 0), or keep status 1 and land elsewhere than
    on the whole images.

    ``box_prev``: (J, 2) float32 points (a superset of ``p_prev``, also the starts) whose boxes
    make the parts instead of ``p_prev``'s and ``p_next``'s: each point's answer depends on the
    parts' origin (LK works in the part's float32 pixels), so a call on fewer points keeps the
    numbers of a call on all of them (None: the boxes of ``p_prev`` and ``p_next``).
    ``flags``: LK's (``cv2.OPTFLOW_USE_INITIAL_FLOW`` and optionally
    ``cv2.OPTFLOW_LK_GET_MIN_EIGENVALS``; p_next is the start either way).
    ``band``: (J, 2) float points in grey_next (the starts among them) along the paths the searches
    are expected to take (the stereo search's epipolar curves): the next image's box is then their
    box with the windows' margin and ``BAND_SLACK`` coarsest-level px around, within the reach box
    above (a search that strays farther from its path reads the part's edge, as one beyond the reach
    does). None: the reach in every direction.

    Returns:
        (p_next (K, 1, 2) float32 result in grey_next, status (K,) uint8, err (K,) float32: LK's
        residual, or the window's smallest eigenvalue with OPTFLOW_LK_GET_MIN_EIGENVALS).
    """
    if grey_prev.shape != grey_next.shape:  # LK takes two images of one size
        return _lk_whole(grey_prev, grey_next, p_prev, p_next, win_px, level, crit, flags)
    m = (win_px // 2 + 6) * 2.0**level
    reach_px = (win_px // 2) * 2.0 ** (level + 1)
    al = 2**level
    a = _lk_box((p_prev if box_prev is None else box_prev).reshape(-1, 2), m, grey_prev.shape, al)
    b = _lk_box((p_next if box_prev is None else box_prev).reshape(-1, 2), m + reach_px, grey_next.shape, al)
    if band is not None:
        c = _lk_box(band.reshape(-1, 2), m + BAND_SLACK * al, grey_next.shape, al)
        b = (max(b[0], c[0]), max(b[1], c[1]), min(b[2], c[2]), min(b[3], c[3]))
    # one box for both (LK's two images have one size): the union
    x0, y0, x1, y1 = min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])
    if x1 <= x0 or y1 <= y0:  # every point and start beyond one edge: no part (LK hangs on an empty image)
        return _lk_whole(grey_prev, grey_next, p_prev, p_next, win_px, level, crit, flags)
    o = np.array([x0, y0], np.float32)
    q, st, err = cv2.calcOpticalFlowPyrLK(
        grey_prev[y0:y1, x0:x1],
        grey_next[y0:y1, x0:x1],
        p_prev - o,
        p_next - o,
        winSize=(win_px, win_px),
        maxLevel=level,
        criteria=crit,
        flags=flags | cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return q + o, st.reshape(-1), err.reshape(-1)


def _lk_top_level(shape: tuple[int, ...], win_px: int, level: int) -> int:
    """The coarsest pyramid level OpenCV's LK searches on images of ``shape`` (H, W, ...) with a
    ``win_px`` window at maxLevel ``level``: ``cv2.buildOpticalFlowPyramid`` stops at the level whose
    next one (half the size, rounded up) is no larger than the window."""
    h, w = shape[0], shape[1]
    top = 0
    while top < level:
        w, h = (w + 1) // 2, (h + 1) // 2
        if w <= win_px or h <= win_px:
            break
        top += 1
    return top


def _lk_pyramids(pyr_prev, pyr_next, p_prev, p_next, win_px, level, crit, flags=cv2.OPTFLOW_USE_INITIAL_FLOW):
    """``_lk_whole`` on two images given with their pyramids (lists [image, cv2.pyrDown(image),
    cv2.pyrDown of that, ...], at least ``_lk_top_level`` + 1 levels): OpenCV's search level by
    level, coarsest first, one maxLevel-0 call a level, so that an image's levels are built once
    and not by every call that reads it (OpenCV's Python binding takes no prebuilt pyramid).

    The same numbers as the one call: OpenCV's LK builds each level by ``pyrDown`` of the one
    below and reads it through a reflected border of the window's width, as a maxLevel-0 call on
    that level builds its border; each level starts from the point and the level above's result
    scaled by powers of two (exact in float32), the coarsest from ``p_next`` so scaled (from
    ``p_prev`` when ``flags`` lack ``OPTFLOW_USE_INITIAL_FLOW``, as OpenCV's); a level above the
    finest sets no status there (a point it loses goes on from where it was), so the upper levels'
    statuses are not read, and they run with ``OPTFLOW_LK_GET_MIN_EIGENVALS`` (no residual pass,
    which moves nothing). The finest level's call gives the status and err (err
    of a lost point is OpenCV's unspecified value either way).
    tests/trackers/test_lk_pyramids.py holds the agreement on rendered frames."""
    top = _lk_top_level(pyr_prev[0].shape, win_px, level)
    # the coarsest level's start: p_next there, or the points themselves without USE_INITIAL_FLOW
    q = (p_next if flags & cv2.OPTFLOW_USE_INITIAL_FLOW else p_prev) * np.float32(1.0 / (1 << top))
    upper = cv2.OPTFLOW_USE_INITIAL_FLOW | cv2.OPTFLOW_LK_GET_MIN_EIGENVALS
    for lv in range(top, -1, -1):
        q, st, err = cv2.calcOpticalFlowPyrLK(
            pyr_prev[lv],
            pyr_next[lv],
            p_prev * np.float32(1.0 / (1 << lv)),
            q if lv == top else q * np.float32(2.0),
            winSize=(win_px, win_px),
            maxLevel=0,
            criteria=crit,
            flags=(flags | cv2.OPTFLOW_USE_INITIAL_FLOW) if lv == 0 else upper,
        )
    return q, st.reshape(-1), err.reshape(-1)


def _lk_whole(grey_prev, grey_next, p_prev, p_next, win_px, level, crit, flags=cv2.OPTFLOW_USE_INITIAL_FLOW):
    """``_lk_part`` on the whole images (the reference it must agree with)."""
    q, st, err = cv2.calcOpticalFlowPyrLK(
        grey_prev,
        grey_next,
        p_prev,
        p_next.copy(),
        winSize=(win_px, win_px),
        maxLevel=level,
        criteria=crit,
        flags=flags | cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return q, st.reshape(-1), err.reshape(-1)


class FeatureTracker:
    """KLT + ORB feature tracker of one camera (see the module docstring).

    Args:
        camera: an ``estimators.rig.Camera`` (name, model, T_C_B).
        detector: the keypoint Detector used for (re-)detection.
        ids: shared id counter (an ``itertools.count``) so ids are unique over the cameras.
        max_features: live features kept at most (default 500). None (opt-in, picked for CPU, not
            fitted): from the lens's size in pixels, one per ``px_per_feature`` px^2 of the lens
            mask, clipped to [250, 500] (``MIN_FEATURES``, ``MAX_FEATURES``): a 720p lens (radius
            338 px), and a 1080p frame tracked at 1280 px wide, get 500; a 640x480 lens (radius
            226 px) 250. It costs worst-obstacle coverage at 640x480 scale: a review's
            trackers.benchmark runs at that scale, 500 -> 250 features, turning's worst obstacle
            0.875 -> 0.118, moving_crossing's 0.838 -> 0.475, mean worst-obstacle coverage 0.552
            -> 0.469, for front-end CPU per frame 25-35 % less (mono_straight at 864x486 14.4 ->
            9.5 ms); the 640x480 bench clip's whole pipeline (one pinned core, CPU) 18.5-19.1 ms
            a frame with 500, 13.2-13.5 with None: still short of 100 fps (10 ms). Earlier
            measurement (7 presets rendered at 864x486, the 640x480 bench clip and the 640x360
            demo, 500 -> 250): mean coverage 0.806 -> 0.803, id switches 18 -> 22, turning 0.998
            -> 0.857 (one obstacle 0.95 -> 0.10). (The floor: small renders keep as many features as
            ``min_distance_px`` lets fit; a 384x216 lens holds ~300.)
        px_per_feature: see ``max_features`` (px^2 of lens per feature when the budget is derived,
            i.e. with max_features=None).
        grid: (cols, rows) coverage grid; a cell inside the lens with fewer than ``min_per_cell``
            features triggers re-detection.
        min_per_cell: see ``grid``.
        redetect_s: re-detect every this long (s; default 4/30: every 4th frame at 30 fps, the count
            it was fitted as; 0 = every frame), applied as a frame count at the frame rate seen
            (``FrameClock``, as the grouping's durations; none before two frame intervals are seen,
            save for 0, which needs no rate: the coverage trigger and the first frame still detect).
            A full tracker (``max_features`` live) every twice this long: its detection can only
            re-acquire lost features (about 0.7 per detection on the 640x480 and 1280x720 bench
            clips). (Was ``redetect_every`` 4
            frames: at 100 fps 25 detections a second against 7.5 at 30 fps. Never
            detecting while full was an option, ``full_redetect_factor`` 0, removed after a same-base
            A/B, 0 against 2: trackers.benchmark identical on 29 of 32 scenes (9 tuned, 5 held-out,
            18 validation), stereo_flying id switches 1 -> 2, heldout_stereo_flying's worst obstacle
            0.797 -> 0.750, val_stereo_flying switches 3 -> 2; accuracy --set all: mono identical,
            stereo obstacle-frame coverage down on every set (tuned 76.8 -> 75.4, held-out 75.3 ->
            74.7, validation 83.9 -> 83.5 %), held-out stereo heading 8.3 -> 13.0 deg (target 10)
            and range NEES 1.83 -> 2.07, validation NEES 2.99 -> 2.78; for about 1 ms a frame of
            detect + track CPU at 1280x720, as measured when the option was added.)
        win_px, levels: KLT window (px, the side of the square) and pyramid levels. The window is
            also the front end's stereo KLT's and the fusion's window angle (its half-width):
            ``trackers.frontend.tracked_window``.
        fb_max_px: forward-backward check: a feature is dropped when tracking it forward then
            backward misses its start by more than this (px).
        fb_levels: pyramid levels of the backward pass (0: the full-resolution image only). It
            starts from the forward result minus the motion prediction. Default 1: 0 cuts the KLT
            time by ~30 % (replayed KLT calls of a 640x480 clip: 5.5 -> 3.8 ms per frame) but a
            level-0 pass converges only within about half a window of its start, so when the
            prediction is several px off (a sudden yaw) good features fail the check: a sudden 8 px
            turn keeps 0.56 of the features with 0, 0.82 with 1; trackers.benchmark turning 0.871
            (worst obstacle 0.191) with 0, 1.000 with 1; noisy_1080p worst obstacle 0.29 vs 0.71.
        fb_retry: features failing a backward pass of fb_levels < levels are checked again with
            one more level (a pass on the full-resolution level alone converges only within about
            half a window of a wrong motion prediction: a sudden 8 px turn keeps 0.56 of the
            features, 0.81 with the retry, 0.82 with fb_levels=1). Off by default; with
            fb_levels=0 on the issue-4 presets its coverage effect is mixed (turning 0.871 ->
            1.000, noisy_1080p 0.839 -> 0.886, moving_crossing 0.812 -> 0.687, wide_angle 0.899
            -> 0.845: obstacles with features on them grouped with the background) and it tips
            the stereo two-view test.
        min_distance_px: new features keep this far from live ones.
        reacquire_s: lost features are remembered this long (s; default 8/30: 8 frames at 30 fps, the
            count it was fitted as; 0 = not at all) for re-acquisition, as a frame count at the rate
            seen (``FrameClock``, with ``redetect_s``: at 100 Hz 27 frames against a cadence of 13, so
            a lost feature meets a detection as at 30 fps; in frames, 8 at 100 Hz, most were
            forgotten before the next detection: re-acquired 55 -> 12 a second on a 100-fps render,
            24 with this).
        reacquire_radius_px: a new keypoint re-acquires a lost feature within this distance of its
            predicted position and with ``reacquire_max_hamming`` or fewer differing descriptor bits.
        history: samples kept per feature (ring buffer). The grouper's windows into it (the flow's
            1/6 s, step 3c's 1/3 s) reach at most ``history - 1`` frames back: 64 covers 1/3 s up to
            189 fps (32 did to 93 fps; at 30 fps both hold the windows whole, with the same results).
        max_residual: a track is also dropped when LK's residual (mean absolute grey difference of
            the window) exceeds this, 3x the frame's median residual and ``texture_k`` x the
            patch's own contrast (mean absolute deviation of its grey values over the window).
        texture_k: see ``max_residual`` (0 = no texture term). A replaced patch's residual is about
            1.4x its deviation, so 0.4 still drops it while a textured patch tracked with a small
            mismatch is kept (issue 4: fewer dying features on textured obstacles).
        margin_px: lens-circle margin (features closer to the circle's edge are dropped).
        klt_step_s: KLT's step (s): a feature is tracked from its position this long back (frames at the
            rate seen, the median frame interval: ``trackers.clock.FrameClock``; 1 frame before two
            intervals are seen, at most ``history``; 0: the previous frame), in that frame's
            image, the previous frame's position
            plus the motion prediction its initial guess; a feature detected (or re-acquired) since, from
            the frame it was detected (re-acquired) in. Each KLT step adds a small random error to the
            position, so a chain of frame-to-frame steps drifts from its physical point with the number of
            frames: at 100 fps ~3.3x faster per second than at 30 (hf22). Default 1/30 s: one frame at 30
            fps (outputs as before), 3 at 100 fps (median squared drift of fps100_mono_straight's static
            obstacles' features at 0.33 / 1.0 s of age 1.65 / 7.80 -> 0.46 / 2.11 px^2; 30-fps
            mono_straight 0.54 / 2.21). Costs a pair of LK calls a frame per reference frame in use (each
            call built both images' pyramids then: OpenCV 4.14's Python binding refuses a prebuilt one,
            ``cv2.buildOpticalFlowPyramid``'s list, in ``calcOpticalFlowPyrLK`` and
            ``SparsePyrLKOpticalFlow.calc`` alike; since session 31 the whole-crop pair runs level by
            level on pyramids built once a frame, ``_pyramid``, with the same numbers): on the bench's
            640x480 100-Hz clip the track stage took x1.21 in kf22's A/B of this step alone, and its
            median 3.44 -> 4.83 ms a frame in session
            22's full bench (with the re-detection in seconds and rk22's fixes; 720p 60 Hz 4.41 -> 6.11
            ms). The features younger than the step (densified and re-detected: 5-40 a frame on the
            bench clips, clustered around small obstacles) take their pairs on the parts of the crops
            their search reads (``_lk_part``): those pairs 1.16 -> 0.46 ms a frame at 720p 60 Hz, 1.14 ->
            0.55 at 640x480 100 Hz (the same calls timed both ways), the track stage's median 6.02 -> 5.24
            and 4.49 -> 3.76 ms (one core, loaded machine, 3 runs each with a null perturbation: docs
            ARCHITECTURE "The younger features' KLT on parts of the crops"). Stepping the younger
            features from the previous frame instead (two pairs at most) measured worse: docs
            ARCHITECTURE "KLT steps in seconds".

    KLT runs on the lens circle's bounding box (``roi``, origin on a multiple of 16 px so the
    crop's pyramid levels sample the frame's own grid): the same tracks as on the full frame
    (checked on a 1280x720 bench clip: same verdicts, positions within 0.001 px) for about half
    the pyramid work. Feature velocities are in px per second (``t_s``), so the KLT prediction
    stays right across dropped frames.
    """

    # its frame counts that are durations now: old key -> (new key, the old default in time); the front
    # end's option check (trackers.frontend.option_problem) names the replacement from it
    RENAMED: ClassVar[dict[str, tuple[str, str]]] = {
        "redetect_every": ("redetect_s", "every 4th frame at 30 fps = 4/30 s"),
        "reacquire_frames": ("reacquire_s", "8 frames at 30 fps = 8/30 s"),
    }

    def __init__(
        self,
        camera,
        detector: Detector,
        ids: Iterator[int] | None = None,
        max_features: int | None = 500,
        px_per_feature: float = 700.0,
        grid: tuple[int, int] = (16, 9),
        min_per_cell: int = 1,
        redetect_s: float = 4 / 30,
        win_px: int = KLT_WIN_PX,
        levels: int = 2,
        fb_max_px: float = 1.0,
        fb_levels: int = 1,
        fb_retry: bool = False,
        min_distance_px: float = 10.0,
        reacquire_s: float = 8 / 30,
        reacquire_radius_px: float = 15.0,
        reacquire_max_hamming: int = 40,
        history: int = 64,
        max_residual: float = 12.0,
        texture_k: float = 0.4,
        margin_px: float = 4.0,
        klt_step_s: float = 1.0 / 30.0,
        **old: Any,
    ) -> None:
        d = check_durations(
            "FeatureTracker",
            FeatureTracker.RENAMED,
            old,
            {"redetect_s": redetect_s, "reacquire_s": reacquire_s, "klt_step_s": klt_step_s},
        )
        self.redetect_s, self.reacquire_s = d["redetect_s"], d["reacquire_s"]
        self.klt_step_s = d["klt_step_s"]
        # integer options: an int (or numpy integer); a float such as 1.5 or a bool (True) is refused
        # rather than truncated by int()
        for opt, val in (
            ("max_features", max_features),
            ("min_per_cell", min_per_cell),
            ("levels", levels),
            ("fb_levels", fb_levels),
            ("reacquire_max_hamming", reacquire_max_hamming),
            ("history", history),
        ):
            if not (val is None and opt == "max_features"):
                _check_int(opt, val)
        if not (isinstance(grid, tuple | list) and len(grid) == 2):
            raise ConfigError(f"FeatureTracker: grid: expected (cols, rows), two integers; got {grid!r}")
        _check_int("grid[0]", grid[0])
        _check_int("grid[1]", grid[1])
        if (
            (max_features is not None and max_features < 1)
            or not px_per_feature > 0
            or history < 2
            or fb_max_px <= 0
            or fb_levels < 0
        ):
            raise ConfigError(
                "FeatureTracker: expected max_features >= 1 (or None), px_per_feature > 0, "
                "history >= 2, fb_max_px > 0, fb_levels >= 0; got "
                f"{max_features}, {px_per_feature}, {history}, "
                f"{fb_max_px}, {fb_levels}"
            )

        self.camera = camera
        self.name = camera.name
        self.model = camera.model
        self.R_C_B = np.asarray(camera.T_C_B.R, dtype=float)
        self.detector = detector
        self._ids = ids if ids is not None else itertools.count(1)
        self.grid = (int(grid[0]), int(grid[1]))
        self.min_per_cell = int(min_per_cell)
        k = klt_window_px(win_px)
        self.win = (k, k)
        self.levels = int(levels)
        self.fb_max_px = float(fb_max_px)
        self.fb_levels = int(fb_levels)
        self.fb_retry = bool(fb_retry)
        self.max_residual = float(max_residual)
        self.texture_k = float(texture_k)
        self.min_distance_px = float(min_distance_px)
        self.reacquire_radius_px = float(reacquire_radius_px)
        self.reacquire_max_hamming = int(reacquire_max_hamming)
        self.H = int(history)
        self.mask = lens_mask(self.model, margin_px)
        if max_features is None:  # opt-in: one feature per px_per_feature px^2 of the lens mask
            lens_px = int(np.count_nonzero(self.mask))
            max_features = min(MAX_FEATURES, max(MIN_FEATURES, round(lens_px / float(px_per_feature))))
        self.max_features = int(max_features)
        self.shape_hw = self.mask.shape
        # KLT runs on the bounding box of the lens circle: a fisheye's circle often fills half the
        # frame or less (a 1280x720 frame with a 338-px circle: 53%)
        ys, xs = np.nonzero(self.mask)
        pad = max(k, 16) + 4  # room for the KLT window and ORB's edge threshold
        h0, w0 = self.shape_hw
        # (origin on a multiple of 16 px so the crop's pyramid levels, up to the stereo search's
        # 4, sample the frame's own grid)
        self.roi = (
            max(0, (int(xs.min()) - pad) // 16 * 16) if len(xs) else 0,
            max(0, (int(ys.min()) - pad) // 16 * 16) if len(ys) else 0,
            min(w0, int(xs.max()) + pad + 1) if len(xs) else w0,
            min(h0, int(ys.max()) + pad + 1) if len(ys) else h0,
        )
        self._off = np.array(self.roi[:2], np.float32)
        # ORB's box: roi + 32 px (its coarse levels then see real pixels past the rim, not a
        # reflected border), or the whole frame when that saves under 30 % of it (640x480: 12 %);
        # ORB's coarse levels on a box sample another grid than the frame's, so its keypoints
        # move by up to a few pixels (1280x720: detection 5.7 -> 4.2 ms)
        bx = (max(0, self.roi[0] - 32), max(0, self.roi[1] - 32))
        bx += (min(w0, self.roi[2] + 32), min(h0, self.roi[3] + 32))
        small_box = (bx[2] - bx[0]) * (bx[3] - bx[1]) <= 0.7 * w0 * h0
        self._det_box = bx if small_box else (0, 0, w0, h0)
        # cells mostly inside the lens: the ones whose coverage is checked
        gx, gy = self.grid
        h, w = self.shape_hw
        cell_frac = cv2.resize((self.mask > 0).astype(np.float32), (gx, gy), interpolation=cv2.INTER_AREA)
        self._live_cells = (cell_frac > 0.5).reshape(-1)
        self._criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)
        self._finder = _Finder(
            detector,
            self.mask,
            self.frame_box,
            self.shape_hw,
            self.grid,
            self.min_distance_px,
            self.reacquire_radius_px,
            self.reacquire_max_hamming,
        )
        # live features
        self.ids = np.zeros(0, np.int64)
        self.uv = np.zeros((0, 2), np.float32)
        self.vel = np.zeros((0, 2), np.float32)  # px per second, for the KLT initial guess
        self.desc = np.zeros((0, 32), np.uint8)
        self.has_desc = np.zeros(0, bool)
        self.age = np.zeros(0, np.int64)
        self.slot = np.zeros(0, np.intp)
        self.b_C = np.zeros((0, 3))
        # recently lost features (for re-acquisition)
        self.lost_ids = np.zeros(0, np.int64)
        self.lost_uv = np.zeros((0, 2), np.float32)
        self.lost_vel = np.zeros((0, 2), np.float32)  # px/s
        self.lost_t = np.zeros(0)  # time (s) each was last seen
        self.lost_desc = np.zeros((0, 32), np.uint8)
        self.lost_age = np.zeros(0, np.int64)
        self.lost_slot = np.zeros(0, np.intp)
        self.lost_for = np.zeros(0, np.int64)
        # history ring buffers, one slot per live or recently lost feature
        cap = self.max_features * 3 + 64
        self._free = list(range(cap - 1, -1, -1))
        self._h_uv = np.zeros((cap, self.H, 2), np.float32)
        self._h_bC = np.zeros((cap, self.H, 3))
        self._h_bB = np.zeros((cap, self.H, 3))
        self._h_t = np.zeros((cap, self.H))
        self._h_frame = np.zeros((cap, self.H), np.int64)
        self._h_n = np.zeros(cap, np.int64)  # samples written (ring position = n % H)
        # the last frames' roi crops, oldest first, (frame index, time (s), crop): KLT's reference
        # images, the frames up to klt_step_s back (the frame rate seen by self.clock)
        self._refs: deque[tuple[int, float, np.ndarray]] = deque()
        # the reference crops' pyramids for the whole-crop KLT calls (``_pyramid``), by id(crop)
        self._pyrs: dict[int, list[np.ndarray]] = {}
        self._t_uv = 0.0  # time (s) of the positions in self.uv
        self.clock = FrameClock()  # the frame rate seen, for klt_step_s, redetect_s and reacquire_s
        self._frames_since_detect = FrameClock.UNKNOWN  # (the first frame detects)
        # the deferred schedule (``defer_detection``): the executor that runs ``_Finder.find``, and the
        # detection under way (its future, frame index, time) or None; _n_step: how many of _refs
        # are the KLT step's (the others are kept for that detection's frame)
        self._executor: Any = None
        self._finder_key: str | None = None  # the key of the finder loaded where the executor runs it
        self._pending: tuple[Any, int, float, int] | None = None  # (+ n_frames when submitted)
        self.deferred: dict[str, int] = {"joined": 0, "frames_late": 0}  # joined, frames after their own
        self._n_step = 0
        # the detection that joined this frame: (its frame, t_s, the ids of its features, their (K, 2) px
        # at that frame), for the coming KLT step
        self._joined: tuple[int, float, np.ndarray, np.ndarray] | None = None
        self.n_frames = 0
        self.last_stats: dict[str, float] = {}

    # ------------------------------------------------------------------------------ public
    @property
    def n_live(self) -> int:
        return len(self.ids)

    def defer_detection(self, executor: Any) -> None:
        """Run the re-detections off the frame's path (live mode): a frame's detection (``_Finder.find``
        on the part of the frame it reads and the state, both copied then: ``_Finder.part``,
        ``_detect_job``) is submitted to ``executor``
        (``submit(fn, *args)`` -> a ``concurrent.futures.Future``; live mode's is
        ``pipeline.live.detection_worker``, a process at a lower priority) and the frame goes on without
        it; its features join the tracker at the first frame that finds it done (``_merge``), tracked
        from their positions in the detection's frame into that one like any feature stepping from an
        older reference (the frame's crop is kept until then); their history and age are as for features
        detected in the join's frame (a new one: from there, age 1; a re-acquired one: its own, its lost
        age + 1). One detection at a time; one still under way when ``history`` reference frames are
        kept is waited for; its error is raised there (RuntimeError naming the frame). None: the
        synchronous schedule (the default: each detection in its own frame). A detection under way when
        the schedule is set is dropped (the end of a live run). The executor is first given the finder
        and waited for (``_Finder.ready``; it keeps it, so a job carries no finder): a worker that cannot
        take it (a detector that does not pickle, or does not load there) fails here, and a worker
        process's first detection does not wait for the detector's imports (kornia's torch: 64 frames at
        100 Hz otherwise)."""
        self._pending = None
        self._executor = None
        if executor is not None:
            key = uuid.uuid4().hex
            try:
                executor.submit(_Finder.ready, key, pickle.dumps(self._finder)).result()
            except Exception as e:
                raise RuntimeError(
                    f"FeatureTracker {self.name!r}: the detection worker cannot take this tracker's "
                    f"detector {type(self.detector).__name__} ({type(e).__name__}: {e}); detect in the "
                    "frames instead (live: live.deferred_detection false)"
                ) from e
            self._finder_key = key
            weakref.finalize(self, _FINDERS.pop, key, None)  # (an executor in this process: its copy)
        self._executor = executor

    def track(
        self, grey: np.ndarray, frame: int, t_s: float, image: np.ndarray | None = None
    ) -> tuple[Features, dict[str, float]]:
        """Track the live features into ``grey`` and top up coverage.

        Args:
            grey: (H, W) uint8 frame of this camera (the calibration's size).
            frame, t_s: frame index and time (s).
            image: the original frame passed to the detector (BGR or grey); default ``grey``.
        Returns:
            (the live Features, seconds spent {"track": ..., "detect": ...}).
        """
        import time

        t0 = time.perf_counter()
        # (OpenCV's Python binding takes images, not prebuilt pyramids (cv2.buildOpticalFlowPyramid's
        # list is refused): the whole-crop LK runs level by level on the crops' pyramids, built once
        # a frame (``_pyramid``); the younger features' calls build their parts' own)
        cur = self._crop(grey)
        self.last_stats = {}
        self.clock.tick(t_s)
        merged = 0.0
        if self._pending is not None:  # a deferred detection: its features join when it is done
            if self._pending[0].done() or len(self._refs) >= self.H:
                tm = time.perf_counter()
                self._merge_pending()
                merged = time.perf_counter() - tm
        if self._refs and len(self.ids):
            self._klt(cur, float(t_s) - self._t_uv)
        # KLT's step: klt_step_s as frames (1 before the rate is known), at most the history's
        # reach (the reference position is a history sample); a deferred detection's frame is kept
        # until its features have joined
        n = self.clock.frames(self.klt_step_s)
        self._refs.append((int(frame), float(t_s), cur))
        keep = 1 if n >= self.clock.UNKNOWN else min(n, self.H)
        t_det = np.inf if self._pending is None else self._pending[2]
        while len(self._refs) > keep and not self._refs[0][1] >= t_det:
            self._refs.popleft()
        self._n_step = min(len(self._refs), keep)
        live = {id(r[2]) for r in self._refs}
        self._pyrs = {k: v for k, v in self._pyrs.items() if k in live}
        self._t_uv = float(t_s)
        t1 = time.perf_counter()
        self._frames_since_detect += 1
        if self._pending is None and self._need_detection():
            self._detect(image if image is not None else grey, int(frame), float(t_s))
            self._frames_since_detect = 0
        t2 = time.perf_counter()
        self._bearings_and_history(frame, t_s)
        self.lost_for += 1
        self._forget_lost(self.lost_for > self.clock.frames(self.reacquire_s, 0))
        self.n_frames += 1
        t3 = time.perf_counter()
        return self.features(), {"track": (t1 - t0) + (t3 - t2) - merged, "detect": t2 - t1 + merged}

    def _merge_pending(self) -> None:
        """The deferred detection's features join (``defer_detection``): waited for when still under
        way; the coming KLT steps them from their positions at the detection's frame (``_joined``), the
        previous frame's position extrapolated from there (their velocity: the neighbours' or the lost
        feature's). They are as if detected in this frame: a new feature's first history sample is this
        frame's, age 1 (``age`` counts the samples: the grouper reads a feature's samples as one per
        frame); a re-acquired one keeps its history and age, its lost age + 1 (``_append``)."""
        fut, f_det, t_det, n_det = self._pending
        self._pending = None
        self.deferred["joined"] += 1
        self.deferred["frames_late"] += self.n_frames - n_det
        try:
            found = fut.result()
        except Exception as e:
            raise RuntimeError(
                f"FeatureTracker {self.name!r}: the deferred detection of frame {f_det} (t_s {t_det!r}) "
                f"failed: {type(e).__name__}: {e}"
            ) from e
        rows = self._merge(found)
        if len(rows):
            self._joined = (int(f_det), float(t_det), self.ids[rows].copy(), self.uv[rows].copy())
            self.uv[rows] += self.vel[rows] * np.float32(max(self._t_uv - t_det, 0.0))
            # the age each would have had detected in this frame, once tracked into it: 1 for a new
            # feature, a re-acquired one's lost age + 1 (``_append`` gave them that already, and KLT adds 1)
            self.age[rows] -= 1

    @property
    def crop(self) -> tuple[np.ndarray | None, np.ndarray]:
        """(the last tracked frame's grey lens crop ``roi`` (h, w) uint8 or None, its origin (2,)
        float32 px in the full frame: full-frame pixel = crop pixel + origin)."""
        return (self._refs[-1][2] if self._refs else None), self._off

    @property
    def frame_box(self) -> tuple[int, int, int, int]:
        """(x0, y0, x1, y1) px, the part of a frame the tracker reads: KLT's lens crop ``roi`` and
        ORB's detection box around it (``_det_box``, which contains ``roi``; the whole frame for
        other detectors). Pixels outside it are never read (the front end leaves them black when
        it shrinks a wide frame)."""
        if not isinstance(self.detector, OrbDetector):
            return (0, 0, self.shape_hw[1], self.shape_hw[0])
        return self._det_box

    def features(self) -> Features:
        """The live features now."""
        b_B = self.b_C @ self.R_C_B  # b_B = R_B_C b_C = R_C_B^T b_C (rows)
        return Features(self.name, self.ids.copy(), self.uv.copy(), self.b_C.copy(), b_B, self.age.copy())

    def history(self, feature_id: int) -> FeatureHistory:
        """The stored past of a live or recently lost feature, oldest first."""
        hit = (self.ids == feature_id).nonzero()[0]
        if len(hit):
            s = int(self.slot[hit[0]])
        else:
            hit = (self.lost_ids == feature_id).nonzero()[0]
            if not len(hit):
                raise InputError(f"feature {feature_id} is not tracked by camera {self.name!r}")
            s = int(self.lost_slot[hit[0]])
        n = int(self._h_n[s])
        k = min(n, self.H)
        idx = (np.arange(n - k, n)) % self.H
        return FeatureHistory(
            self._h_uv[s, idx].astype(float),
            self._h_bC[s, idx],
            self._h_bB[s, idx],
            self._h_t[s, idx],
            self._h_frame[s, idx],
        )

    def bearing_ago(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every live feature: its b_C and time up to ``k`` frames back.

        Returns:
            (b_C (N, 3) the oldest sample within the last k+1, t_s (N,) its time,
             valid (N,) bool: the feature has at least 2 samples).
        """
        n = self._h_n[self.slot]
        back = np.minimum(n - 1, k)
        fi = self.slot * self.H + (n - 1 - back) % self.H  # flat (slot, ring position) index
        return self._h_bC.reshape(-1, 3).take(fi, 0), self._h_t.reshape(-1)[fi], back > 0

    def previous_bearing(self) -> tuple[np.ndarray, np.ndarray]:
        """(b_C (N,3) one frame back, valid (N,)) for the live features (the sample before the latest)."""
        n = self._h_n[self.slot]
        return self._h_bC.reshape(-1, 3).take(self.slot * self.H + (n - 2) % self.H, 0), n >= 2

    def describe(self, grey: np.ndarray, idx: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """ORB descriptors of live features at their current positions.

        Args:
            grey: (H, W) uint8 current frame; idx: indices into the live features (default all).
        Returns:
            (descriptors (K, 32) uint8, rows (K,) indices into the live features that got one).
        """
        idx = np.arange(len(self.ids)) if idx is None else np.asarray(idx)
        if not len(idx):
            return np.zeros((0, 32), np.uint8), np.zeros(0, np.intp)
        if not hasattr(self, "_orb_desc"):
            self._orb_desc = cv2.ORB_create(edgeThreshold=15, patchSize=15)
        # on the lens crop ``roi`` (ORB blurs the whole image it is given): live features lie in the
        # lens mask, >= 20 px inside the crop's edges (or on the frame's own edges), farther than
        # the edge threshold (15 px) and the blurred patch (~12 px) reach, and the crop's origin is
        # even (a multiple of 16), so keypoints round to the same pixels: the same descriptors
        x0, y0 = 0, 0
        if grey.shape[:2] == self.shape_hw:
            x0, y0, x1, y1 = self.roi
            grey = grey[y0:y1, x0:x1]
        # (Python floats and ints from tolist: the same float32 keypoints as float(u) - x0 from
        # numpy scalars, without a numpy scalar conversion per coordinate)
        kps = [
            cv2.KeyPoint(u - x0, v - y0, 15.0, -1, 0, 0, i)
            for i, (u, v) in zip(idx.tolist(), self.uv[idx].tolist(), strict=True)
        ]
        kps, des = self._orb_desc.compute(grey, kps)
        if des is None or not kps:
            return np.zeros((0, 32), np.uint8), np.zeros(0, np.intp)
        return des, np.array([k.class_id for k in kps], np.intp)

    def densify(
        self,
        image: np.ndarray,
        centres_uv: np.ndarray,
        radii_px: np.ndarray,
        frame: int,
        t_s: float,
        per_roi: int = 6,
        min_distance_px: float = 5.0,
    ) -> int:
        """Add features around the given points (small obstacles with few features).

        Runs a sensitive ORB (FAST threshold 5, one level) on a crop around each point and adds up to
        ``per_roi`` new keypoints there, at least ``min_distance_px`` from live features and each
        other, within the lens mask; their bearings and first history sample are set now.

        Args:
            image: (H, W) grey or (H, W, 3) BGR frame of this camera (the calibration's size).
            centres_uv: (K, 2) pixels; radii_px: (K,) half sizes of the regions (px).
            frame, t_s: this frame's index and time (s).
        Returns:
            the number of features added.
        """
        from trackers.detectors.base import to_grey

        if not len(centres_uv):
            return 0
        grey = to_grey(image)
        if not hasattr(self, "_orb_roi"):
            # no mask is given to ORB (drawing a hole per nearby feature cost ~2 us each, ~1 ms
            # per frame): it keeps the strongest 150 corners of the region, and those in the lens
            # and min_distance_px from the live features are taken in numpy below
            self._orb_roi = cv2.ORB_create(
                nfeatures=150, scaleFactor=1.2, nlevels=1, edgeThreshold=8, patchSize=15, fastThreshold=5
            )
        h, w = self.shape_hw
        n0 = len(self.ids)
        room = self.max_features + self.max_features // 4 - n0  # a little above the global budget
        # the keypoints of all regions are appended at once (one _append, one bearing computation);
        # a region keeps min_distance_px from the live features and from earlier regions' new ones
        taken = self.uv
        md2 = float(min_distance_px) ** 2
        new_uv: list[np.ndarray] = []
        new_des: list[np.ndarray] = []
        # the regions' boxes, and which live features lie within min_distance_px of each box (one
        # (K, N) test for all regions; features added by earlier regions are tested per region)
        boxes = []
        centres = np.asarray(centres_uv, float).tolist()
        for (u, v), r in zip(centres, np.asarray(radii_px, float).tolist(), strict=True):
            r = int(max(12, r)) + 8
            x, y = int(u), int(v)
            boxes.append((max(0, x - r), max(0, y - r), min(w, x + r + 1), min(h, y + r + 1)))
        # the box edges widened by min_distance_px, rounded to float32 as a Python float compared
        # with the float32 positions is (the per-region test's numbers)
        bx = np.array(boxes, np.float64).reshape(-1, 4)
        lo = (bx[:, :2] - min_distance_px).astype(np.float32)
        hi = (bx[:, 2:] + min_distance_px).astype(np.float32)
        tu, tv = taken[:, 0], taken[:, 1]
        near_live = (
            (tu[None, :] >= lo[:, 0, None])
            & (tu[None, :] < hi[:, 0, None])
            & (tv[None, :] >= lo[:, 1, None])
            & (tv[None, :] < hi[:, 1, None])
        )
        n_live = len(taken)
        for k, (x0, y0, x1, y1) in enumerate(boxes):
            if room <= 0:
                break
            if x1 - x0 < 20 or y1 - y0 < 20:
                continue
            crop = grey[y0:y1, x0:x1]
            kps = self._orb_roi.detect(crop, None)
            if not kps:
                continue
            p = cv2.KeyPoint_convert(kps).reshape(-1, 2)
            p += np.array([x0, y0], np.float32)  # frame px
            pu_, pv_ = p[:, 0], p[:, 1]
            # (keypoints lie in the crop, so the rounded indices are >= 0)
            ui = np.minimum(np.rint(pu_).astype(np.intp), w - 1)
            vi = np.minimum(np.rint(pv_).astype(np.intp), h - 1)
            ok = self.mask.take(vi * w + ui) > 0
            near = near_live[k].nonzero()[0]
            if len(taken) > n_live:  # features added by earlier regions of this call
                tu, tv = taken[n_live:, 0], taken[n_live:, 1]
                more = (
                    (tu >= x0 - min_distance_px)
                    & (tu < x1 + min_distance_px)
                    & (tv >= y0 - min_distance_px)
                    & (tv < y1 + min_distance_px)
                ).nonzero()[0]
                near = np.concatenate([near, more + n_live])
            if len(near):  # at least min_distance_px from every live (or newly added) feature
                du = pu_[:, None] - taken[near, 0][None, :]
                dv = pv_[:, None] - taken[near, 1][None, :]
                du *= du
                dv *= dv
                du += dv
                ok &= du.min(axis=1) >= md2
            cand = ok.nonzero()[0]
            if not len(cand):
                continue
            resp = np.array([kps[i].response for i in cand.tolist()], np.float32)
            # strongest first, each at least min_distance_px from those already chosen
            chosen: list[int] = []
            want = min(per_roi, room)
            for i in cand[np.argsort(-resp, kind="stable")].tolist():
                pu, pv = float(p[i, 0]), float(p[i, 1])
                if all((pu - p[j, 0]) ** 2 + (pv - p[j, 1]) ** 2 >= md2 for j in chosen):
                    chosen.append(i)
                    if len(chosen) >= want:
                        break
            ck, des = self._orb_roi.compute(crop, [kps[i] for i in chosen])
            if des is None or not ck:
                continue
            uv = cv2.KeyPoint_convert(ck).reshape(-1, 2).astype(np.float32) + np.array([x0, y0], np.float32)
            new_uv.append(uv)
            new_des.append(des)
            taken = np.concatenate([taken, uv])
            room -= len(uv)
        if new_uv:
            uv = np.concatenate(new_uv)
            self._append(uv, np.concatenate(new_des), np.full(len(uv), -1, np.intp))
        added = len(self.ids) - n0
        if added:
            b, valid = self.model.pixel_to_bearing(self.uv[n0:].astype(np.float64))
            self.b_C[n0:] = b
            self._write_history(self.slot[n0:], self.uv[n0:], b, frame, t_s)
            if not np.all(valid):
                self._drop(n0 + (~valid).nonzero()[0], remember=False)
        return added

    # --------------------------------------------------------------------------- internals
    def _crop(self, image: np.ndarray) -> np.ndarray:
        """The lens's bounding box ``roi`` of a full frame, contiguous (pixel (x0, y0) = crop (0, 0))."""
        x0, y0, x1, y1 = self.roi
        if (x0, y0, x1, y1) == (0, 0, image.shape[1], image.shape[0]):
            return image
        return np.ascontiguousarray(image[y0:y1, x0:x1])

    def _klt(self, cur, dt_s: float) -> None:
        """Track the live features into ``cur`` (cropped to ``roi``), ``dt_s`` seconds after the
        previous frame (a dropped frame doubles it; <= 0: no motion prediction, velocities kept).

        Each feature steps from the oldest reference frame (``_refs``, ``klt_step_s`` back) its history
        has a sample in: its position there is LK's start in that frame, the previous frame's position
        plus the constant-velocity prediction its initial guess, and the backward pass returns to that
        frame (a feature detected or re-acquired since steps from the frame it was detected or re-acquired
        in). A feature's position chain so takes one step per ``klt_step_s``, not per frame: each step
        adds a small random error, and a chain of 100-fps steps drifted from its physical point ~3x faster
        per second than a 30-fps one (docs: ARCHITECTURE "KLT steps in seconds"). At <= 1 / klt_step_s fps
        every feature steps from the previous frame; above, one pair of LK calls a frame per reference
        frame in use: the oldest reference's (most features, about the lens) on the whole crops (level
        by level on their pyramids, built once a frame: ``_lk_pyramids``), the younger ones' (few,
        clustered) on the parts of the crops their
        search reads (``_lk_part``: the same pixels, so the same tracks but for the last bits of LK's
        float32 coordinates, which are the part's, and which an ill-conditioned window can carry to ~1 px).
        """
        off = self._off
        nref = len(self._refs)
        # the step's references (the newest nstep); older ones are kept for a deferred detection's
        # frame (``defer_detection``)
        nstep = min(nref, self._n_step)
        # each feature's lag j (0: the previous frame, nref - 1: the oldest reference) and its
        # position in the reference frame (ref_uv, full-frame px: a history sample, the same
        # float32 numbers as uv had then)
        lag = np.zeros(len(self.ids), np.intp)
        ref_uv = self.uv
        # each feature's time (s) since its reference frame, for its velocity: the step's own
        # displacement over it (the previous frame's dt_s for lag 0)
        dt_ref = np.full(len(self.ids), dt_s)
        if nref > 1:
            n = self._h_n[self.slot]
            ref_uv = self.uv.copy()
            for j in range(1, nstep):
                # the sample j back is that reference frame's when its frame index and time are that
                # frame's (both: a caller's frame index may repeat, e.g. a live camera's counter
                # restarting, and a re-acquired feature's sample from before its loss must not be
                # taken for it; then the feature has a sample in each of the last j + 1 frames)
                fi = self.slot * self.H + (n - 1 - j) % self.H
                rf, rt, _ = self._refs[nref - 1 - j]
                at = (n - 1 - j >= 0) & (self._h_frame.reshape(-1)[fi] == rf)
                at &= self._h_t.reshape(-1)[fi] == rt
                lag[at] = j
                ref_uv[at] = self._h_uv.reshape(-1, 2).take(fi[at], 0)
                dt_ref[at] = dt_s + (self._t_uv - self._h_t.reshape(-1)[fi[at]])
        # a deferred detection's features, joined this frame (``_merge_pending``): they step from their
        # positions in the detection's frame (kept in _refs for them)
        if self._joined is not None:
            f_det, t_det, jids, juv = self._joined
            self._joined = None
            j = next(j for j in range(nref) if self._refs[nref - 1 - j][:2] == (f_det, t_det))
            at = _isin(self.ids, jids).nonzero()[0]
            by_id = np.argsort(jids)
            k = np.searchsorted(jids, self.ids[at], sorter=by_id)
            lag[at] = j
            ref_uv = ref_uv.copy() if ref_uv is self.uv else ref_uv
            ref_uv[at] = juv[by_id[k]]
            dt_ref[at] = dt_s + (self._t_uv - t_det)
        moving = bool(np.isfinite(dt_s) and dt_s > 0)
        # constant-velocity prediction (px): v (px/s) * dt (s) from the previous frame's position;
        # from the reference position the predicted displacement is (uv - ref_uv) + v dt
        step = (self.vel * np.float32(dt_s)) if moving else np.zeros_like(self.vel)
        disp = (self.uv - ref_uv) + step
        N = len(self.ids)
        p1 = np.empty((N, 2), np.float32)
        st = np.empty(N, np.uint8)
        err = np.empty(N, np.float32)
        st2 = np.empty(N, np.uint8)
        fb = np.empty(N, np.float32)
        groups = [(j, (lag == j).nonzero()[0]) for j in range(nref)] if nref > 1 else [(0, None)]
        for j, g in groups:
            if g is not None and not len(g):
                continue
            sel = slice(None) if g is None else g
            prev = self._refs[nref - 1 - j][2]
            # the group's rows of ref_uv and disp (gathered once, by take: the rows' own values)
            ref_g, disp_g = (ref_uv, disp) if g is None else (ref_uv.take(g, 0), disp.take(g, 0))
            q0 = ref_g - off  # (n, 2) float32 crop px
            p0 = q0.reshape(-1, 1, 2)
            # the features younger than the step (few: densified and re-detected ones, clustered) on
            # the parts of the two images their search reads, the others (about the lens) on the
            # whole crops; every feature at <= 1 / klt_step_s fps
            part = j < nstep - 1
            # forward, starting from the prediction
            guess = (q0 + disp_g).reshape(-1, 1, 2)
            g1, gst, gerr = self._lk(prev, cur, p0, guess, self.levels, cv2.OPTFLOW_USE_INITIAL_FLOW, part)
            # backward: track g1 back into the reference frame, starting from g1 minus the predicted
            # displacement (the prediction reversed, not p0 itself); a good track lands within
            # fb_max_px of where it started. Its residuals are not used: OPTFLOW_LK_GET_MIN_EIGENVALS
            # makes LK report the window's smallest eigenvalue (found anyway) instead of a last pass
            # over the window for the residual (~8 % of the pass). The positions are the same; the
            # status differs only for an end point over half a window beyond the crop's edge, which
            # that pass marks lost and which misses its start (inside the lens) by more than
            # fb_max_px: dropped either way (counted in last_stats as a forward-backward rejection
            # instead of an LK loss).
            back_flags = cv2.OPTFLOW_USE_INITIAL_FLOW | cv2.OPTFLOW_LK_GET_MIN_EIGENVALS
            back_guess = (g1.reshape(-1, 2) - disp_g).reshape(-1, 1, 2)
            back_level = min(self.fb_levels, self.levels)
            p0r, gst2, _ = self._lk(cur, prev, g1, back_guess, back_level, back_flags, part)
            p0r = p0r.reshape(-1, 2)
            # |p0r + off - ref_uv| written out (the same float32 values as np.linalg.norm(.., axis=1),
            # whose call costs more than the arithmetic for a few hundred rows)
            d = p0r + off - ref_g
            gfb = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
            if self.fb_retry and self.fb_levels < self.levels:
                # second chance: a backward pass on the full-resolution level alone converges only
                # within about half a window of its start, so a good track whose motion prediction
                # was off by more (fast rotation, acceleration) fails it; those features (typically a
                # few %) are checked again with one coarser level, as the backward pass did before
                # fb_levels
                again = ((gst.reshape(-1) == 1) & ((gst2 != 1) | ~(gfb <= self.fb_max_px))).nonzero()[0]
                if len(again):
                    q, st3, _ = self._lk(
                        cur,
                        prev,
                        g1[again],
                        (g1[again].reshape(-1, 2) - disp_g[again]).reshape(-1, 1, 2).astype(np.float32),
                        min(self.fb_levels + 1, self.levels),
                        back_flags,
                        part,
                    )
                    p0r[again] = q.reshape(-1, 2)
                    gst2[again] = st3
                    gfb[again] = np.linalg.norm(p0r[again] + off - ref_g[again], axis=1)
            p1[sel] = g1.reshape(-1, 2)
            st[sel] = gst
            err[sel] = gerr
            st2[sel] = gst2
            fb[sel] = gfb
        p1 += off
        u1, v1 = p1[:, 0], p1[:, 1]
        st1 = st == 1
        lk_ok = st1 & (st2 == 1)
        fb_ok = fb <= self.fb_max_px  # (False for a NaN distance, as for an infinite one)
        ok = lk_ok & fb_ok
        n_fb = int(np.count_nonzero(ok))
        # appearance: LK's residual (mean absolute grey difference over the window) must be ordinary
        # for this frame, which tolerates global exposure changes but not a patch that changed
        if n_fb:
            # a textured patch has a larger residual for the same (sub-pixel, noise, shading) mismatch:
            # the bound also scales with the patch's own contrast (texture_k x its mean absolute
            # deviation in the reference frame), so good features on textured obstacles are kept:
            # bound = max(max_residual, 3 median(err), texture_k MAD(patch)); the patch term is only
            # needed (and computed) where err exceeds the first two
            base = max(self.max_residual, 3.0 * _median(err[ok]))
            over = (ok & (err > base)).nonzero()[0]
            if len(over):
                tex = np.zeros(len(over), np.float32)
                if self.texture_k > 0:
                    for j in np.unique(lag[over]):
                        k = lag[over] == j
                        tex[k] = self._texture(self._refs[nref - 1 - j][2], ref_uv[over[k]] - off)
                ok[over] = err[over] <= self.texture_k * tex
        n_res = int(np.count_nonzero(ok))
        h, w = self.shape_hw
        # inside the frame (a NaN position compares false, so this also asks for finite ones) and
        # inside the lens mask
        ok &= (u1 >= 0) & (u1 <= w - 1) & (v1 >= 0) & (v1 <= h - 1)
        # (np.rint: np.round's numbers (half to even) without its wrapper; clipped by two ufuncs, as
        # np.clip's integers)
        ui = np.minimum(np.maximum(np.rint(u1).astype(np.intp), 0), w - 1)
        vi = np.minimum(np.maximum(np.rint(v1).astype(np.intp), 0), h - 1)
        ok &= self.mask.take(vi * w + ui) > 0  # (the mask at (vi, ui), by one flat index)
        n_ok = int(np.count_nonzero(ok))
        n_lk = int(np.count_nonzero(lk_ok))
        # why features were dropped this frame (counts): LK lost them (status 0 either way), the
        # forward-backward check, the residual check, or they left the lens mask
        self.last_stats = {
            "klt_in": float(len(ok)),
            "klt_ok": float(n_ok),
            "lk_lost": float(len(ok) - n_lk),
            "fb_rejected": float(np.count_nonzero(st1 & ~fb_ok)),
            "fb_rejected_lk_ok": float(n_lk - n_fb),
            "residual_rejected": float(n_fb - n_res),
            "left_mask": float(n_res - n_ok),
        }
        # the kept rows updated in place: element-wise over all rows, written where ok (the kept rows'
        # numbers without gathering them, ~60 -> ~20 us; the dropped rows keep theirs for the lost pool)
        okc = ok[:, None]
        if moving:
            # v <- (v + (p1 - p_ref) / dt_ref) / 2, px/s: the displacement of the step taken, from
            # the reference frame (at <= 1 / klt_step_s fps the previous one: (p1 - p0) / dt). Not
            # p1 minus the previous frame's position: above that rate consecutive positions come
            # from different step chains (frame k from k - N, k - 1 from k - 1 - N), whose drifts
            # differ, and that difference over one frame's dt doubled the velocity's noise at 100
            # fps (fps100_mono_straight, |v - the 0.2-s central difference| p90 16.6 -> 34.5 px/s)
            # and so the lost features' predicted positions (reacquire_s ahead)
            dtr = dt_ref.astype(np.float32)[:, None]
            np.copyto(self.vel, 0.5 * self.vel + 0.5 * (p1 - ref_uv) / dtr, where=okc & (dtr > 0))
        np.copyto(self.uv, p1, where=okc)
        self.age += ok
        if n_ok < len(ok):
            self._drop((~ok).nonzero()[0], remember=True)

    def _lk(self, prev, nxt, p, start, level: int, flags: int, part: bool):
        """One KLT call from points ``p`` (K, 1, 2) float32 crop px of ``prev`` starting at ``start``
        in ``nxt`` (two ``roi`` crops), at most ``level`` (OpenCV's maxLevel): on the parts of the
        crops the search reads (``_lk_part``) when ``part``, else on the whole crops. Returns (result
        (K, 1, 2), status (K,), err (K,))."""
        k = self.win[0]
        if part:
            return _lk_part(prev, nxt, p, start, k, level, self._criteria, flags=flags)
        top = _lk_top_level(prev.shape, k, level)
        pyr_prev, pyr_next = self._pyramid(prev, top), self._pyramid(nxt, top)
        return _lk_pyramids(pyr_prev, pyr_next, p, start, k, level, self._criteria, flags)

    def _pyramid(self, crop: np.ndarray, level: int) -> list[np.ndarray]:
        """``crop``'s pyramid ([crop, cv2.pyrDown(crop), ...], levels 0..level at least), kept while
        the crop is a reference frame (``_refs``, pruned in ``track``): a frame's levels are built
        once, though the whole-crop KLT calls of this frame and the next steps read them up to four
        times (this frame's forward and backward passes, and again as a reference)."""
        pyr = self._pyrs.get(id(crop))
        if pyr is None or pyr[0] is not crop:
            pyr = self._pyrs[id(crop)] = [crop]
        while len(pyr) <= level:
            pyr.append(cv2.pyrDown(pyr[-1]))
        return pyr

    def _texture(self, image: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Mean absolute deviation of the grey values (N,) over the KLT window centred on each of the
        points ``p`` ((N,1,2) or (N,2) pixels of ``image``), the window clipped to the image."""
        p = p.reshape(-1, 2)
        hw = self.win[0] // 2
        d = np.arange(-hw, hw + 1)
        h, w = image.shape[:2]
        ui = np.minimum(np.maximum(np.rint(p[:, 0]).astype(np.intp)[:, None] + d[None, :], 0), w - 1)
        vi = np.minimum(np.maximum(np.rint(p[:, 1]).astype(np.intp)[:, None] + d[None, :], 0), h - 1)
        # (the image at (vi, ui) for every window pixel, by one flat index)
        patch = image.take(vi[:, :, None] * w + ui[:, None, :]).reshape(len(p), -1).astype(np.float32)
        return np.mean(np.abs(patch - patch.mean(axis=1, keepdims=True)), axis=1)

    def _cell_counts(self) -> np.ndarray:
        gx, gy = self.grid
        h, w = self.shape_hw
        if not len(self.uv):
            return np.zeros(gx * gy, np.int64)
        cx = np.clip((self.uv[:, 0] * gx / w).astype(np.intp), 0, gx - 1)
        cy = np.clip((self.uv[:, 1] * gy / h).astype(np.intp), 0, gy - 1)
        return np.bincount(cy * gx + cx, minlength=gx * gy)

    def _need_detection(self) -> bool:
        """Whether to detect this frame: coverage thins (fewer than 60 % of the budget live and a
        live cell below ``min_per_cell``), or periodically (every ``redetect_s`` as a frame count at
        the rate seen; a full tracker every twice that long)."""
        if len(self.ids) < 0.6 * self.max_features:
            counts = self._cell_counts()
            if np.any(counts[self._live_cells] < self.min_per_cell):
                return True
        # full (no room for new features): a detection can only re-acquire lost features (0.7 per
        # detection on the 640x480 and 1280x720 bench clips, at 6-10 ms each), so more rarely
        full = len(self.ids) >= self.max_features
        period = self.clock.frames(self.redetect_s * (2 if full else 1))
        return self._frames_since_detect >= period

    def _detect(self, image: np.ndarray, frame: int, t_s: float) -> None:
        """Detect new features (and re-acquire lost ones) in the lens: ``_Finder.find`` on this frame's
        state, then ``_merge``, now (the synchronous schedule), or submitted to the deferred schedule's
        executor (``defer_detection``; merged by ``_merge_pending``)."""
        job = self._detect_job(t_s)
        if job is None:
            return
        if self._executor is None:
            self._merge(self._finder.find(job, self._finder.part(image)))
            return
        # the part of the frame the finder reads, copied now: the frame's array may be the reader's
        # buffer, filled with a later frame before the worker reads it
        part = self._finder.part(image).copy()
        fut = self._executor.submit(_Finder.find_loaded, self._finder_key, job, part)
        self._pending = (fut, frame, t_s, self.n_frames)

    def _detect_job(self, t_s: float) -> _DetectJob | None:
        """What a detection at time ``t_s`` reads of the tracker's state, copied (so ``_Finder.find`` may run
        while the tracker moves on): None when there is nothing to detect for (full, no lost feature)."""
        free = self.max_features - len(self.ids)
        if free <= 0 and not len(self.lost_ids):
            return None
        return _DetectJob(
            free, self.uv.copy(), self._lost_predictions(t_s), self.lost_ids.copy(), self.lost_desc.copy()
        )

    def _merge(self, found: _Found) -> np.ndarray:
        """Add a detection's keypoints as live features (``_Finder.find``'s result; the re-acquired ones by
        their lost feature's id); returns the rows added. Run later than the state ``_Finder.find`` read (the
        deferred schedule), a keypoint whose lost feature has been forgotten since is dropped, and new
        features take only the room left now (the first ones in ``_Finder.find``'s order)."""
        n0 = len(self.ids)
        if not len(found.uv):
            return np.zeros(0, np.intp)
        reacq = np.full(len(found.uv), -1, np.intp)
        keep = np.ones(len(found.uv), bool)
        back = (found.lost_id >= 0).nonzero()[0]
        if len(back):
            row = {int(i): k for k, i in enumerate(self.lost_ids.tolist())}
            for k in back.tolist():
                reacq[k] = row.get(int(found.lost_id[k]), -1)
                keep[k] = reacq[k] >= 0
        fresh = (found.lost_id < 0).nonzero()[0]
        keep[fresh[max(self.max_features - n0, 0) :]] = False
        self._append(found.uv[keep], None if found.desc is None else found.desc[keep], reacq[keep])
        return np.arange(n0, len(self.ids))

    def _append(self, uv: np.ndarray, desc: np.ndarray | None, reacq: np.ndarray) -> int:
        """Add keypoints uv (n,2) as live features (re-acquired ones, ``reacq >= 0``, keep the lost
        feature's id, slot and history); returns how many were added."""
        n = len(uv)
        new_ids = np.empty(n, np.int64)
        new_slot = np.empty(n, np.intp)
        new_age = np.ones(n, np.int64)
        new_vel = np.zeros((n, 2), np.float32)
        fresh = reacq < 0
        # (all rows at once, not a Python iteration per row: fresh rows take the next ids and free
        # slots in row order; an id is used up even when no slot is left for it, as before)
        rf = fresh.nonzero()[0]
        if len(rf):
            new_vel[rf] = self._neighbour_velocity(np.asarray(uv, np.float32).take(rf, 0))
            new_ids[rf] = [next(self._ids) for _ in range(len(rf))]
            free = self._free
            k = min(len(rf), len(free))
            slots = [free.pop() for _ in range(k)]
            if k < len(rf):  # out of slots: those rows are not added
                new_ids[rf[k:]] = -1
            if k:
                new_slot[rf[:k]] = slots
                self._h_n[slots] = 0
        if len(rf) < n:  # re-acquired: the lost feature's id, slot, age and velocity
            rr = (~fresh).nonzero()[0]
            j = reacq[rr]
            new_ids[rr] = self.lost_ids[j]
            new_slot[rr] = self.lost_slot[j]
            new_age[rr] = self.lost_age[j] + 1
            new_vel[rr] = self.lost_vel[j]
            gone = np.zeros(len(self.lost_ids), bool)
            gone[j] = True
            self._remove_lost(gone)
        ok = new_ids >= 0
        m = int(np.count_nonzero(ok))
        if m < n:
            new_ids, uv, new_vel = new_ids[ok], uv[ok], new_vel[ok]
            new_age, new_slot = new_age[ok], new_slot[ok]
            if desc is not None:
                desc = desc[ok]
        self.ids = np.concatenate([self.ids, new_ids])
        self.uv = np.concatenate([self.uv, np.asarray(uv).astype(np.float32)])
        self.vel = np.concatenate([self.vel, new_vel])
        self.desc = np.concatenate([self.desc, desc if desc is not None else np.zeros((m, 32), np.uint8)])
        self.has_desc = np.concatenate([self.has_desc, np.full(m, desc is not None)])
        self.age = np.concatenate([self.age, new_age])
        self.slot = np.concatenate([self.slot, new_slot])
        self.b_C = np.concatenate([self.b_C, np.zeros((m, 3))])
        return m

    def _neighbour_velocity(self, uv: np.ndarray, radius_px: float = 40.0) -> np.ndarray:
        """(n, 2) px/s: the mean velocity of the live features at least 3 frames old within
        ``radius_px`` of each point uv (n, 2) px (zero with fewer than 2 such neighbours): the KLT
        prediction of a new feature, so it starts where its neighbourhood moves (new features
        started from zero motion failed the forward-backward check twice as often on a forward
        flight, mono_straight: 12% -> 6% of those away from the rim)."""
        out = np.zeros((len(uv), 2), np.float32)
        old = (self.age >= 3).nonzero()[0]
        if not len(uv) or len(old) < 2:
            return out
        # (n, m) squared px, du^2 + dv^2 written out: the same numbers as ((a - b) ** 2).sum(-1),
        # whose reduction over a length-2 axis takes ~10x as long
        du = uv[:, 0, None] - self.uv[None, old, 0]
        dv = uv[:, 1, None] - self.uv[None, old, 1]
        d2 = du * du + dv * dv
        near = (d2 <= radius_px**2).astype(np.float32)
        cnt = near.sum(1)
        got = cnt >= 2
        out[got] = (near.compress(got, 0) @ self.vel.take(old, 0)) / cnt[got, None]
        return out

    def _lost_predictions(self, t_s: float) -> np.ndarray:
        """(L, 2) px: where each lost feature is expected at time t_s (s), last seen + v (px/s) *
        time since (s)."""
        dt = np.maximum(float(t_s) - self.lost_t, 0.0).astype(np.float32)
        return self.lost_uv + self.lost_vel * dt[:, None]

    def _drop(self, idx: np.ndarray, remember: bool) -> None:
        """Remove live features ``idx``; remember those with descriptors for re-acquisition."""
        if not len(idx):
            return
        keep = np.ones(len(self.ids), bool)
        keep[idx] = False
        gone = ~keep
        # the kept and remembered rows as index arrays, found once (a boolean mask per array would
        # count its rows again for each of the eight arrays); the same rows in the same order
        if remember and self.reacquire_s > 0:
            r = (gone & self.has_desc).nonzero()[0]
            nr = len(r)
            self.lost_ids = np.concatenate([self.lost_ids, self.ids[r]])
            self.lost_uv = np.concatenate([self.lost_uv, self.uv[r]])
            self.lost_vel = np.concatenate([self.lost_vel, self.vel[r]])
            self.lost_t = np.concatenate([self.lost_t, np.full(nr, self._t_uv)])
            self.lost_desc = np.concatenate([self.lost_desc, self.desc[r]])
            self.lost_age = np.concatenate([self.lost_age, self.age[r]])
            self.lost_slot = np.concatenate([self.lost_slot, self.slot[r]])
            self.lost_for = np.concatenate([self.lost_for, np.zeros(nr, np.int64)])
            free = gone & ~self.has_desc
            excess = len(self.lost_ids) - self.max_features  # bound the pool: forget the oldest
            if excess > 0:
                old = np.zeros(len(self.lost_ids), bool)
                old[np.argsort(-self.lost_for, kind="stable")[:excess]] = True
                self._forget_lost(old)
        else:
            free = gone
        self._free.extend(self.slot[free].tolist())
        ki = keep.nonzero()[0]
        for name in ("ids", "uv", "vel", "desc", "has_desc", "age", "slot", "b_C"):
            setattr(self, name, getattr(self, name).take(ki, 0))

    def _remove_lost(self, gone: np.ndarray) -> None:
        keep = (~gone).nonzero()[0]  # (the kept rows found once for the eight arrays)
        names = ("lost_ids", "lost_uv", "lost_vel", "lost_t", "lost_desc", "lost_age", "lost_slot")
        names += ("lost_for",)
        for name in names:
            setattr(self, name, getattr(self, name).take(keep, 0))

    def _forget_lost(self, gone: np.ndarray) -> None:
        if not np.any(gone):
            return
        self._free.extend(self.lost_slot[gone].tolist())
        self._remove_lost(gone)

    def _bearings_and_history(self, frame: int, t_s: float) -> None:
        if not len(self.ids):
            return
        b, valid = self.model.pixel_to_bearing(self.uv.astype(np.float64))
        if not np.all(valid):
            self._drop((~valid).nonzero()[0], remember=False)
            b = b[valid]
        self.b_C = b
        self._write_history(self.slot, self.uv, b, frame, t_s)

    def _write_history(self, s: np.ndarray, uv: np.ndarray, b: np.ndarray, frame: int, t_s: float) -> None:
        """Append one sample to the ring buffers of slots ``s`` (K,): pixels uv (K, 2), bearings b (K, 3)
        in C (and in B), time t_s (s), frame index."""
        H = self.H
        fi = s * H + self._h_n[s] % H  # flat (slot, ring position) index: one index array, not two
        self._h_uv.reshape(-1, 2)[fi] = uv
        self._h_bC.reshape(-1, 3)[fi] = b
        self._h_bB.reshape(-1, 3)[fi] = b @ self.R_C_B  # b_B = R_C_B^T b_C
        self._h_t.reshape(-1)[fi] = t_s
        self._h_frame.reshape(-1)[fi] = frame
        self._h_n[s] += 1
