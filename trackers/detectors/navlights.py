"""``navlights``: a drone target from its navigation lights (thesis section 5.2).

The thesis puts, as on aircraft, a red light on the drone's own LEFT wingtip, a green light on its
RIGHT wingtip and a white light in the middle. Seen from the front (the target flies towards the
camera) its left is on our right, so the image shows GREEN on the LEFT of RED; seen from behind
(it flies away) the image shows RED on the LEFT of GREEN. "Left" here is smaller image u (column)
in the raw frame, which for a camera mounted upright is the observer's left. The thesis (Fig.
5.4/5.5): "green navigation light on the left and red light on the right, that means the drone is
flying towards" us.

A target is a red blob and a green blob whose separation is at most ``max_pair_px`` with a white
blob between them (its projection on the red-green segment in the middle 80 %, its distance from the
segment under half the separation), unless ``require_white=False``. Its box covers the three lights;
attributes: ``heading`` (``"towards"`` | ``"away"``), ``red_uv``, ``green_uv``, ``white_uv``.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from estimators.errors import InputError
from trackers.detectors.base import Detections, Detector, register_detector


def heading_from_lights(red_u: float, green_u: float) -> str:
    """``"towards"`` when the green light is on the image-left of the red one, else ``"away"``.

    Red is on the target's own left wingtip, green on its right (thesis 5.2): a target facing us
    shows its right (green) on our left.
    """
    return "towards" if green_u < red_u else "away"


def _blobs(binary: np.ndarray, min_area: int, max_area: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Connected blobs of a 0/255 mask -> (centroids (K,2) px, boxes (K,4) xyxy, areas (K,))."""
    n, _, stats, cents = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if n <= 1:
        return np.zeros((0, 2)), np.zeros((0, 4)), np.zeros(0)
    st = stats[1:]
    area = st[:, cv2.CC_STAT_AREA]
    ok = (area >= min_area) & (area <= max_area)
    st, c = st[ok], cents[1:][ok]
    x, y, w, h = (st[:, i].astype(float) for i in range(4))
    return c, np.stack([x, y, x + w - 1, y + h - 1], axis=1), area[ok].astype(float)


@register_detector("navlights")
class NavLightsDetector(Detector):
    """Red / green / white navigation lights by colour and brightness; pairs make drone targets.

    Args:
        min_value: minimum brightness (HSV V, 0-255) of a light.
        min_saturation: minimum saturation (0-255) of a red or green light.
        max_white_saturation: maximum saturation of a white light.
        min_area_px, max_area_px: blob size limits (pixels).
        max_pair_px: largest red-green separation (pixels) of one target.
        require_white: a target needs the white light between red and green.
        box_margin_px: margin added around the lights' box.
    """

    produces_keypoints = False
    produces_boxes = True

    def __init__(
        self,
        min_value: int = 180,
        min_saturation: int = 120,
        max_white_saturation: int = 50,
        min_area_px: int = 2,
        max_area_px: int = 2000,
        max_pair_px: float = 300.0,
        require_white: bool = True,
        box_margin_px: float = 3.0,
    ) -> None:
        self.min_value = int(min_value)
        self.min_saturation = int(min_saturation)
        self.max_white_saturation = int(max_white_saturation)
        self.min_area_px, self.max_area_px = int(min_area_px), int(max_area_px)
        self.max_pair_px = float(max_pair_px)
        self.require_white = bool(require_white)
        self.box_margin_px = float(box_margin_px)

    def colour_masks(self, bgr: np.ndarray, mask: np.ndarray | None) -> dict[str, np.ndarray]:
        """0/255 (H, W) masks of the red, green and white light pixels of a BGR frame."""
        hsv = cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)  # H in [0, 180), S, V in [0, 255]
        h, s, v = hsv[:, :, 0], hsv[:, :, 1], hsv[:, :, 2]
        bright = v >= self.min_value
        sat = s >= self.min_saturation
        out = {
            "red": bright & sat & ((h <= 10) | (h >= 170)),
            "green": bright & sat & (h >= 45) & (h <= 90),
            "white": bright & (s <= self.max_white_saturation),
        }
        res = {}
        for k, m in out.items():
            m = m.astype(np.uint8) * 255
            if mask is not None:
                m &= (mask > 0).astype(np.uint8) * 255
            res[k] = m
        return res

    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """See Detector.detect. ``image`` must be (H, W, 3) BGR: grey frames carry no colour."""
        if image.ndim != 3 or image.shape[2] != 3:
            raise InputError(
                f"navlights: expected a (H, W, 3) BGR frame (colour is needed), got {image.shape}"
            )
        masks = self.colour_masks(image, mask)
        red = _blobs(masks["red"], self.min_area_px, self.max_area_px)
        green = _blobs(masks["green"], self.min_area_px, self.max_area_px)
        white = _blobs(masks["white"], self.min_area_px, self.max_area_px)
        boxes, scores, attrs = [], [], []
        used_g: set[int] = set()
        for i in np.argsort(-red[2]):  # biggest red first
            r = red[0][i]
            best: tuple[float, int, int] | None = None
            for j in range(len(green[0])):
                if j in used_g:
                    continue
                g = green[0][j]
                d = float(np.hypot(*(g - r)))
                if d > self.max_pair_px or d < 1.0:
                    continue
                k_white = self._white_between(r, g, white[0])
                if k_white < 0 and self.require_white:
                    continue
                if best is None or d < best[0]:
                    best = (d, j, k_white)
            if best is None:
                continue
            d, j, k = best
            used_g.add(j)
            parts = [red[1][i], green[1][j]] + ([white[1][k]] if k >= 0 else [])
            pb = np.array(parts)
            m = self.box_margin_px
            boxes.append([pb[:, 0].min() - m, pb[:, 1].min() - m, pb[:, 2].max() + m, pb[:, 3].max() + m])
            scores.append(1.0 if k >= 0 else 0.5)
            a: dict[str, Any] = {
                "heading": heading_from_lights(float(r[0]), float(green[0][j][0])),
                "red_uv": [float(r[0]), float(r[1])],
                "green_uv": [float(green[0][j][0]), float(green[0][j][1])],
                "white_uv": None if k < 0 else [float(white[0][k][0]), float(white[0][k][1])],
            }
            attrs.append(a)
        if not boxes:
            return Detections.empty()
        return Detections(
            boxes=np.array(boxes),
            box_scores=np.array(scores),
            labels=("drone",) * len(boxes),
            attributes=tuple(attrs),
        )

    @staticmethod
    def _white_between(r: np.ndarray, g: np.ndarray, whites: np.ndarray) -> int:
        """Index of the white blob nearest the red-green midpoint that lies between them, or -1."""
        if len(whites) == 0:
            return -1
        seg = g - r
        L2 = float(seg @ seg)
        u = (whites - r) @ seg / L2  # position along the segment, 0 at red, 1 at green
        perp = np.abs((whites - r) @ np.array([-seg[1], seg[0]])) / np.sqrt(L2)
        ok = (u > 0.1) & (u < 0.9) & (perp < 0.5 * np.sqrt(L2))
        if not np.any(ok):
            return -1
        dmid = np.hypot(*(whites - (r + g) / 2).T)
        dmid[~ok] = np.inf
        return int(np.argmin(dmid))
