"""``orb``: cv2.ORB keypoints with descriptors, spread over the frame by grid bucketing."""

from __future__ import annotations

from collections.abc import Callable
from operator import attrgetter

import cv2
import numpy as np

from estimators.errors import ConfigError, InputError
from trackers.detectors.base import Detections, Detector, register_detector, to_grey

_response = attrgetter("response")


def _responses(kps) -> np.ndarray:
    """(N,) float32 responses of N cv2.KeyPoints (one C-level pass; a list comprehension's per-item
    attribute look-up cost ~60 us for the ~2,500 keypoints of a 1280x720 detection)."""
    return np.fromiter(map(_response, kps), np.float32, len(kps))


def bucket(
    uv: np.ndarray, score: np.ndarray, shape_hw: tuple[int, int], grid: tuple[int, int], per_cell: int
) -> np.ndarray:
    """Indices of the strongest ``per_cell`` points in each cell of a ``grid`` = (cols, rows) grid.

    Args:
        uv: (N, 2) pixel positions; score: (N,) responses; shape_hw: image (H, W).
    Returns:
        (K,) int indices into uv, round-robin over the cells: every cell's strongest point first,
        then every cell's second strongest, ... (so truncating the result keeps the spread).
    """
    if len(uv) == 0:
        return np.zeros(0, dtype=np.intp)
    h, w = shape_hw
    gx, gy = grid
    cx = np.clip((uv[:, 0] * gx / w).astype(np.intp), 0, gx - 1)
    cy = np.clip((uv[:, 1] * gy / h).astype(np.intp), 0, gy - 1)
    cell = cy * gx + cx
    order = np.lexsort((-score, cell))  # by cell, then strongest first
    cs = cell[order]
    start = np.searchsorted(cs, cs, side="left")  # first index of each point's cell run
    rank = np.arange(len(cs)) - start
    ok = rank < per_cell
    order, rank = order[ok], rank[ok]
    return order[np.lexsort((-score[order], rank))]


@register_detector("orb")
class OrbDetector(Detector):
    """ORB (FAST corners + Harris score + rBRIEF descriptors) on the raw fisheye frame.

    ORB is asked for many more corners than wanted, then the strongest ``max_features /
    (grid cells)`` are kept per cell, so that the rim of the lens circle (compressed and darker)
    is covered as well as the centre.

    Args:
        max_features: keypoints wanted per frame (upper bound).
        grid: (cols, rows) of the bucketing grid.
        fast_threshold: FAST intensity threshold (grey levels); low values find corners in the
            low-contrast rim.
        n_levels, scale_factor: ORB pyramid.
        descriptors: compute 32-byte ORB descriptors (used to re-acquire and to match cameras).
    """

    def __init__(
        self,
        max_features: int = 600,
        grid: tuple[int, int] = (16, 9),
        fast_threshold: int = 10,
        n_levels: int = 3,
        scale_factor: float = 1.3,
        descriptors: bool = True,
    ) -> None:
        if max_features < 1 or grid[0] < 1 or grid[1] < 1:
            raise ConfigError(
                f"orb: expected max_features >= 1 and grid >= (1, 1), got {max_features}, {grid}"
            )
        self.max_features = int(max_features)
        self.grid = (int(grid[0]), int(grid[1]))
        self.descriptors = bool(descriptors)
        # the mask is applied to the keypoints afterwards, not given to ORB (with a mask ORB took
        # twice as long: 8.6 vs 3.9 ms on a 1280x720 frame with 3 levels), so masked-out corners
        # (e.g. at live features) share the budget: 5x, not 4x, the wanted number; when most of the
        # budget went outside the mask, ORB runs again with it (noisy_1080p: noise outside the lens
        # had left its smallest obstacle covered in 21% of its frames, not 56%)
        self._orb = cv2.ORB_create(
            nfeatures=5 * self.max_features,
            scaleFactor=scale_factor,
            nlevels=n_levels,
            edgeThreshold=15,
            patchSize=15,
            fastThreshold=int(fast_threshold),
        )

    def __getstate__(self) -> dict:
        """Picklable (a live run's detection worker process gets the detector): cv2.ORB is not, so its
        settings travel and it is made again."""
        o = self._orb
        state = {k: v for k, v in self.__dict__.items() if k != "_orb"}
        state["_orb_args"] = {
            "nfeatures": o.getMaxFeatures(),
            "scaleFactor": o.getScaleFactor(),
            "nlevels": o.getNLevels(),
            "edgeThreshold": o.getEdgeThreshold(),
            "patchSize": o.getPatchSize(),
            "fastThreshold": o.getFastThreshold(),
        }
        return state

    def __setstate__(self, state: dict) -> None:
        state = dict(state)
        self._orb = cv2.ORB_create(**state.pop("_orb_args"))
        self.__dict__.update(state)

    def detect(
        self,
        image: np.ndarray,
        mask: np.ndarray | None = None,
        *,
        origin: tuple[int, int] = (0, 0),
        frame_hw: tuple[int, int] | None = None,
        select: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    ) -> Detections:
        """See Detector.detect; keypoints carry ORB descriptors (N, 32) uint8.

        Args:
            image: (H, W) grey or (H, W, 3) BGR uint8 frame, or a crop of one (FeatureTracker
                passes the lens circle's bounding box: ORB's cost is per pixel).
            mask: (H, W) uint8 of ``image``'s size, keypoints only where > 0, or None.
            origin, frame_hw: when ``image`` is a crop, its (x, y) origin in the frame (px) and the
                frame's (H, W): the bucketing grid then covers the frame, not the crop (a grid over
                the crop puts fewer keypoints in each lens cell). Keypoints stay in ``image``'s pixels.
            select: optional ``select(uv (K, 2) frame px, scores (K,)) -> indices`` called with the
                bucketed keypoints (round-robin order); only the selected ones get descriptors and
                are returned (descriptors cost ~1.5 us per keypoint plus the blurred pyramid).
        """
        grey = to_grey(image)
        if mask is not None and np.shape(mask)[:2] != grey.shape[:2]:
            raise InputError(
                f"orb: mask of shape {np.shape(mask)} for a {grey.shape[:2]} image; expected the same size"
            )
        kps = self._orb.detect(grey, None)
        if not kps:
            return Detections.empty()
        uv = cv2.KeyPoint_convert(kps).reshape(-1, 2).astype(np.float32)
        if mask is not None and len(kps) >= 0.9 * self._orb.getMaxFeatures():
            # ORB's budget was used up: when much of it went to corners outside the mask (e.g.
            # sensor noise outside the lens circle), detect again inside the mask (the slow path)
            m = np.asarray(mask)
            ui = np.clip(np.rint(uv[:, 0]).astype(np.intp), 0, m.shape[1] - 1)
            vi = np.clip(np.rint(uv[:, 1]).astype(np.intp), 0, m.shape[0] - 1)
            if np.count_nonzero(m.take(vi * m.shape[1] + ui)) < 0.7 * len(kps):
                kps = self._orb.detect(grey, mask)
                if not kps:
                    return Detections.empty()
                uv = cv2.KeyPoint_convert(kps).reshape(-1, 2).astype(np.float32)
        if mask is not None:
            m = np.asarray(mask)
            ui = np.clip(np.rint(uv[:, 0]).astype(np.intp), 0, m.shape[1] - 1)
            vi = np.clip(np.rint(uv[:, 1]).astype(np.intp), 0, m.shape[0] - 1)
            inside = (m.take(vi * m.shape[1] + ui) > 0).nonzero()[0]
            if not len(inside):
                return Detections.empty()
            kps = [kps[i] for i in inside.tolist()]
            uv = uv.take(inside, 0)
        # (responses of the kept keypoints only: not of a discarded unmasked pass (3000 at 1080p,
        # ~0.14 ms) nor of those outside the mask)
        sc = _responses(kps)
        per_cell = max(1, int(np.ceil(self.max_features / (self.grid[0] * self.grid[1]) * 2)))
        off = np.array(origin, np.float32)
        keep = bucket(uv + off, sc, grey.shape[:2] if frame_hw is None else frame_hw, self.grid, per_cell)
        keep = keep[: self.max_features]
        if select is not None:
            keep = keep[np.asarray(select(uv[keep] + off, sc[keep]), np.intp)]
            if not len(keep):
                return Detections.empty()
        kps = [kps[i] for i in keep.tolist()]
        if not self.descriptors:
            return Detections(keypoints=uv[keep], scores=sc[keep])
        kps, des = self._orb.compute(grey, kps)
        if des is None or not kps:
            return Detections.empty()
        return Detections(
            keypoints=cv2.KeyPoint_convert(kps).reshape(-1, 2).astype(np.float32),
            scores=_responses(kps),
            descriptors=des,
        )
