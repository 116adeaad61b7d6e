"""``navlights``: a drone target from its navigation lights (thesis section 5.2).

The thesis puts, as on aircraft, a red light on the drone's own LEFT wingtip, a green light on its
RIGHT wingtip and a white light in the middle. Seen from the front (the target flies towards the
camera) its left is on our right, so the image shows GREEN on the LEFT of RED; seen from behind
(it flies away) the image shows RED on the LEFT of GREEN. "Left" here is smaller image u (column)
in the raw frame, which for a camera mounted upright is the observer's left. The thesis (Fig.
5.4/5.5): "green navigation light on the left and red light on the right, that means the drone is
flying towards" us.

What a light looks like (and what this detector tests): an emissive, saturated-colour spot, as bright
as the sensor gets (HSV V >= ``min_value``, S >= ``min_saturation``, red or green hue), from ONE
pixel (a far drone: 40 m away a 0.16 m light is a third of a pixel, the optics spread it over one or
two) to a few hundred. A target is a red blob and a green blob (each at most ``max_area_px``) at most
``max_pair_px`` apart, paired greedily nearest first (each light in one target). The white light is
looked for between them (an unsaturated pixel brighter than the pair's surroundings: against a
bright sky a white light is only 10-20 grey levels above it) and raises the box's score (1.0, else
0.6); it is required only with ``require_white=True``. Default False: on the tuned scene
moving_headon (a drone approaching head-on from 40 m) the white light is found in 95 of the 120
frames whose red and green lights are found; in the other 25 (the nearest) it is not in the image.
Why the earlier defaults found that drone in 24 of 120 frames: its lights are ONE pixel each at
40-25 m (``min_area_px`` was 2), and the white light was a blob of a frame-wide mask (S <= 50,
V >= 180) that also holds the bright sky near the horizon (S 45-58, V 236-241), so it merged into
a sky blob far above ``max_area_px``.

Its box covers the lights; attributes: ``heading`` (``"towards"`` | ``"away"``), ``red_uv``,
``green_uv``, ``white_uv`` (None when not seen).

Cost: a cheap test on the mask's bounding box (a fisheye lens circle is about half of a 16:9 frame)
keeps the pixels that may be red or green lights (max(G, R) >= B and >= ``min_value``; a
saturation test there cost as much as the HSV conversion it saves); the HSV test runs only in
their box, and the blob labelling only around the bright saturated red-to-green pixels found. A
frame without candidates costs three elementwise passes over the lens box.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import cv2
import numpy as np

from estimators.errors import ConfigError, InputError
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


def _u8(mask: np.ndarray) -> np.ndarray:
    """A (H, W) mask as OpenCV's operation masks want it: uint8 as it is, any other dtype (bool, a 0/1
    float) as uint8 of mask > 0."""
    return mask if mask.dtype == np.uint8 else (mask > 0).astype(np.uint8)


def _mask_box(mask: np.ndarray | None, shape_hw: tuple[int, int]) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) px, the bounding box of ``mask`` > 0 (the whole frame when None)."""
    if mask is None:
        return 0, 0, shape_hw[1], shape_hw[0]
    x, y, w, h = cv2.boundingRect((mask > 0).astype(np.uint8))
    return x, y, x + w, y + h


@register_detector("navlights")
class NavLightsDetector(Detector):
    """Red / green / white navigation lights by colour and brightness; pairs make drone targets.

    Args:
        min_value: minimum brightness (HSV V, 0-255) of a red or green light.
        min_saturation: minimum saturation (0-255) of a red or green light.
        max_white_saturation: maximum saturation of a white light.
        white_contrast: a white light is at least this many grey levels (V) above the median of the
            pair's surroundings and at least ``min_value``.
        min_area_px, max_area_px: blob size limits (pixels).
        max_pair_px: largest red-green separation (pixels) of one target.
        require_white: a target needs the white light between red and green (the thesis's strict
            test; no lone lights then).
        box_margin_px: margin added around the lights' box.
        single_lights: also report a lone red or green light (no partner within ``max_pair_px``,
            or its partner taken by a nearer pair) that looks like a light: at most
            ``single_max_area_px``, compact (filling half its box), brighter than the ring 2-4 px
            around it by ``white_contrast``, and not a piece of a surface of its colour (under a
            quarter of that ring has its hue, saturated). A drone seen from the side shows one
            wingtip light (tuned scenes wide_angle_beyond90, stereo_hover: the other is behind the
            body). Score 0.3, ``heading`` None.
        scan_every: ``detect_boxes`` (the front end's per-frame call) searches the whole lens every
            this many frames of a camera and, in between, only around the boxes it found in the last
            ``scan_every`` frames; 1: the whole lens every frame. ``detect`` always searches it all.
            With 3 a drone that comes into view is found at most 2 frames (67 ms at 30 fps) later,
            inside the half second the coverage target allows, and one already found is looked for in
            every frame; at 720p navlights' CPU goes from ~1.6 to ~0.6 ms a frame (bench clip), but a
            dim, flickering drone is lost for longer (noisy_1080p's drone 1.000 -> 0.979 of frames).
        grow_value: a light's blob is grown (hysteresis) from its pixels that pass ``min_value`` into
            the connected pixels of a light's colour (``min_saturation``, red or green hue) of HSV V
            >= this (``min_value`` or None: no growing; default 150: a red or green as saturated as
            a light is no sky or ground even that dark). A light dimmed by the camera's exposure has
            its pixels scattered about ``min_value`` (noisy_1080p's drone: V 170-184), so the pixels
            that pass are a sparse, broken blob: a lone light then fails the compactness test and a
            pair's light splits into several boxes. Only pixels joined to one passing ``min_value``
            join, so growing makes no blob of its own.
    """

    produces_keypoints = False
    produces_boxes = True
    needs_colour = True

    def __init__(
        self,
        min_value: int = 180,
        min_saturation: int = 120,
        max_white_saturation: int = 50,
        white_contrast: int = 8,
        min_area_px: int = 1,
        max_area_px: int = 2000,
        max_pair_px: float = 300.0,
        require_white: bool = False,
        box_margin_px: float = 3.0,
        single_lights: bool = True,
        single_max_area_px: int = 200,
        scan_every: int = 1,
        grow_value: int | None = 150,
    ) -> None:
        for nm, v, lo, hi in (
            ("min_value", min_value, 0, 255),
            ("min_saturation", min_saturation, 0, 255),
            ("max_white_saturation", max_white_saturation, 0, 255),
            ("white_contrast", white_contrast, 0, 255),
        ):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"navlights: {nm} expected an integer in [{lo}, {hi}], got {v!r}")
        if isinstance(scan_every, bool) or not isinstance(scan_every, (int, np.integer)) or scan_every < 1:
            raise ConfigError(f"navlights: scan_every expected an integer >= 1 (frames), got {scan_every!r}")
        for nm, v in (("min_area_px", min_area_px), ("max_area_px", max_area_px),
                      ("single_max_area_px", single_max_area_px)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"navlights: {nm} expected an integer >= 1 px, got {v!r}")
        if max_area_px < min_area_px:
            raise ConfigError(
                f"navlights: expected min_area_px <= max_area_px, got {min_area_px} > {max_area_px}"
            )
        for nm, v in (("max_pair_px", max_pair_px), ("box_margin_px", box_margin_px)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not v >= 0:
                raise ConfigError(f"navlights: {nm} expected a distance >= 0 px, got {v!r}")
        for nm, v in (("require_white", require_white), ("single_lights", single_lights)):
            if not isinstance(v, bool):
                raise ConfigError(f"navlights: {nm} expected true or false, got {v!r}")
        self.min_value = int(min_value)
        self.min_saturation = int(min_saturation)
        self.max_white_saturation = int(max_white_saturation)
        self.white_contrast = int(white_contrast)
        self.min_area_px, self.max_area_px = int(min_area_px), int(max_area_px)
        self.max_pair_px = float(max_pair_px)
        self.require_white = bool(require_white)
        self.box_margin_px = float(box_margin_px)
        self.single_lights = bool(single_lights)
        self.single_max_area_px = int(single_max_area_px)
        self.scan_every = int(scan_every)
        gv = self.min_value if grow_value is None else grow_value
        if isinstance(gv, bool) or not isinstance(gv, (int, np.integer)) or not 0 <= gv <= self.min_value:
            raise ConfigError(
                f"navlights: grow_value expected an integer in [0, min_value={self.min_value}] or None, "
                f"got {grow_value!r}"
            )
        self.grow_value = int(gv)
        # detect_boxes' sequences, one per camera name or (without one) per mask object: (the mask,
        # kept referenced so that its id is not reused; calls so far; the boxes of the last
        # scan_every calls)
        self._seq: dict[tuple, tuple[np.ndarray | None, list[int], deque]] = {}
        self._box_cache: dict[int, tuple[np.ndarray, tuple[int, ...], tuple[int, int, int, int]]] = {}

    # ------------------------------------------------------------------------------ colour
    def _colour(self, hsv: np.ndarray, v: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """0/255 masks (red, green) of an HSV image (H in [0, 180), S, V in [0, 255]); ``v``: the
        least V (default ``min_value``)."""
        s, v = self.min_saturation, self.min_value if v is None else v
        red = cv2.inRange(hsv, (0, s, v), (10, 255, 255))
        red |= cv2.inRange(hsv, (170, s, v), (179, 255, 255))
        green = cv2.inRange(hsv, (45, s, v), (90, 255, 255))
        return red, green

    def _crop_box(self, mask: np.ndarray | None, shape_hw: tuple[int, int]) -> tuple[int, int, int, int]:
        """The mask's bounding box, remembered per mask object (the front end passes one fixed lens
        mask per camera; the mask is kept referenced so that its id is not reused)."""
        if mask is None:
            return _mask_box(None, shape_hw)
        hit = self._box_cache.get(id(mask))
        if hit is None or hit[0] is not mask or hit[1] != mask.shape:
            if len(self._box_cache) > 16:
                self._box_cache.clear()
            hit = (mask, mask.shape, _mask_box(mask, shape_hw))
            self._box_cache[id(mask)] = hit
        return hit[2]

    # ------------------------------------------------------------------------------ detect
    def _check(self, image: np.ndarray, mask: np.ndarray | None) -> None:
        if image.ndim != 3 or image.shape[2] != 3:
            raise InputError(
                f"navlights: expected a (H, W, 3) BGR frame (colour is needed), got {image.shape}"
            )
        if mask is not None and mask.shape != image.shape[:2]:
            raise InputError(f"navlights: mask shape {mask.shape} != frame shape {image.shape[:2]}")

    def detect(self, image: np.ndarray, mask: np.ndarray | None = None) -> Detections:
        """See Detector.detect. ``image`` must be (H, W, 3) BGR: grey frames carry no colour."""
        self._check(image, mask)
        return self._find(image, mask, self._crop_box(mask, image.shape[:2]))

    def detect_boxes(
        self, image: np.ndarray, mask: np.ndarray | None = None, camera: str | None = None
    ) -> Detections:
        """The front end's call, once per frame of a camera's sequence: ``detect`` on the whole lens
        every ``scan_every``-th call, and in between only around the boxes found in the last
        ``scan_every`` calls (each grown by its own size + 16 px: a drone's lights, its white light's
        window and the lone-light ring stay inside). A drone that appears is found up to
        ``scan_every - 1`` frames later; one already found is looked for in every frame.
        ``scan_every`` 1: ``detect`` every frame.

        Cameras are told apart by ``camera`` (a name) when given, else by their mask objects (the
        front end passes one lens mask per camera); several cameras without masks (``mask`` None)
        need ``camera``, or they share one sequence."""
        self._check(image, mask)
        lens = self._crop_box(mask, image.shape[:2])
        if self.scan_every == 1:
            return self._find(image, mask, lens)
        key: tuple = ("mask", id(mask)) if camera is None else ("camera", camera)
        st = self._seq.get(key)
        if st is None or (camera is None and st[0] is not mask):
            if len(self._seq) > 16:  # bounded: a rig has a few masks; ones no longer passed are dropped
                self._seq.clear()
            st = (mask, [0], deque(maxlen=self.scan_every))
            self._seq[key] = st
        n = st[1][0]
        st[1][0] += 1
        recent = [b for boxes in st[2] for b in boxes]
        if n % self.scan_every == 0:
            region = lens
        elif not recent:
            st[2].append([])
            return Detections.empty()
        else:
            bx = np.array(recent, float)
            grow = 16.0 + np.maximum(bx[:, 2] - bx[:, 0], bx[:, 3] - bx[:, 1])
            region = (
                max(lens[0], int(np.floor((bx[:, 0] - grow).min()))),
                max(lens[1], int(np.floor((bx[:, 1] - grow).min()))),
                min(lens[2], int(np.ceil((bx[:, 2] + grow).max())) + 1),
                min(lens[3], int(np.ceil((bx[:, 3] + grow).max())) + 1),
            )
        det = self._find(image, mask, region)
        st[2].append(det.boxes.tolist())
        return det

    def _find(
        self, image: np.ndarray, mask: np.ndarray | None, region: tuple[int, int, int, int]
    ) -> Detections:
        """The lights in ``region`` (x0, y0, x1, y1) px of ``image`` (inside ``mask``)."""
        x0, y0, x1, y1 = region
        if x1 <= x0 or y1 <= y0:
            return Detections.empty()
        # a red, green or white light's HSV V is max(G, R) >= B: pixels that fail this or V >=
        # min_value (a blue sky, the dark ground) cannot be lights; most frames have none and stop
        # here, at a third of the HSV conversion's cost
        crop = image[y0:y1, x0:x1]
        v_rg = cv2.max(crop[:, :, 1], crop[:, :, 2])
        cand = cv2.compare(v_rg, crop[:, :, 0], cv2.CMP_GE)
        cand &= cv2.compare(v_rg, self.min_value, cv2.CMP_GE)
        if mask is not None:
            cand = cv2.bitwise_and(cand, cand, mask=_u8(mask[y0:y1, x0:x1]))
        if cv2.countNonZero(cand) == 0:
            return Detections.empty()
        # the HSV test only in their box, grown by 8 px (the lone-light ring, the white light's window)
        cx, cy, cw, ch = cv2.boundingRect(cand)
        x0, y0, x1, y1 = (max(x0, x0 + cx - 8), max(y0, y0 + cy - 8),
                          min(x1, x0 + cx + cw + 8), min(y1, y0 + cy + ch + 8))
        hsv = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_BGR2HSV)
        # bright, saturated pixels of a red to green hue (two inRange: red wraps round 180)
        lo, hi = (self.min_saturation, self.min_value), (255, 255)
        lit = cv2.inRange(hsv, (0, *lo), (90, *hi))
        lit |= cv2.inRange(hsv, (170, *lo), (179, *hi))
        if mask is not None:
            lit = cv2.bitwise_and(lit, lit, mask=_u8(mask[y0:y1, x0:x1]))
        if cv2.countNonZero(lit) == 0:
            return Detections.empty()
        if self.grow_value < self.min_value:
            lit = self._grow(hsv, lit, mask, (x0, y0, x1, y1))
        # red and green, labelled into blobs, only in the box around the lit pixels
        bx0, by0, bw, bh = cv2.boundingRect(lit)
        sub = (slice(by0, by0 + bh), slice(bx0, bx0 + bw))
        red, green = self._colour(hsv[sub], self.grow_value)
        red = cv2.bitwise_and(red, lit[sub])
        green = cv2.bitwise_and(green, lit[sub])
        if not self.single_lights and (cv2.countNonZero(red) == 0 or cv2.countNonZero(green) == 0):
            return Detections.empty()  # a pair needs both
        off = np.array([x0 + bx0, y0 + by0], float)
        R = _blobs(red, self.min_area_px, self.max_area_px)
        G = _blobs(green, self.min_area_px, self.max_area_px)
        if not len(R[0]) and not len(G[0]):
            return Detections.empty()
        rc, gc = R[0] + off, G[0] + off
        rb, gb = R[1] + np.tile(off, 2), G[1] + np.tile(off, 2)
        # candidate pairs nearest first, each light in at most one target
        d = np.hypot(rc[:, None, 0] - gc[None, :, 0], rc[:, None, 1] - gc[None, :, 1])  # (NR, NG)
        ii, jj = np.nonzero((d <= self.max_pair_px) & (d >= 1.0))
        order = np.argsort(d[ii, jj], kind="stable")
        used_r: set[int] = set()
        used_g: set[int] = set()
        boxes, scores, attrs = [], [], []
        for k in order:
            i, j = int(ii[k]), int(jj[k])
            if i in used_r or j in used_g:
                continue
            w_uv = self._white_between(image, rc[i], gc[j])
            if w_uv is None and self.require_white:
                continue
            used_r.add(i)
            used_g.add(j)
            pb = np.array([rb[i], gb[j]])
            m = self.box_margin_px
            x_lo, y_lo = min(pb[:, 0].min(), rc[i][0], gc[j][0]), pb[:, 1].min()
            x_hi, y_hi = pb[:, 2].max(), pb[:, 3].max()
            if w_uv is not None:
                x_lo, x_hi = min(x_lo, w_uv[0]), max(x_hi, w_uv[0])
                y_lo, y_hi = min(y_lo, w_uv[1]), max(y_hi, w_uv[1])
            boxes.append([x_lo - m, y_lo - m, x_hi + m, y_hi + m])
            scores.append(1.0 if w_uv is not None else 0.6)
            a: dict[str, Any] = {
                "heading": heading_from_lights(float(rc[i][0]), float(gc[j][0])),
                "red_uv": [float(rc[i][0]), float(rc[i][1])],
                "green_uv": [float(gc[j][0]), float(gc[j][1])],
                "white_uv": None if w_uv is None else [float(w_uv[0]), float(w_uv[1])],
            }
            attrs.append(a)
        if self.single_lights and not self.require_white:  # a lone light: a drone seen from the side
            m = self.box_margin_px
            parts = (("red", (rc, rb, R[2]), used_r), ("green", (gc, gb, G[2]), used_g))
            for colour, (cs, bs, areas), used in parts:
                for i in range(len(cs)):
                    if i in used or not self._lone_light(hsv, x0, y0, bs[i], areas[i], colour):
                        continue
                    boxes.append([bs[i][0] - m, bs[i][1] - m, bs[i][2] + m, bs[i][3] + m])
                    scores.append(0.3)
                    attrs.append({
                        "heading": None,
                        "red_uv": [float(cs[i][0]), float(cs[i][1])] if colour == "red" else None,
                        "green_uv": [float(cs[i][0]), float(cs[i][1])] if colour == "green" else None,
                        "white_uv": None,
                    })
        if not boxes:
            return Detections.empty()
        return Detections(
            boxes=np.array(boxes, float),
            box_scores=np.array(scores),
            labels=("drone",) * len(boxes),
            attributes=tuple(attrs),
        )

    def _grow(self, hsv: np.ndarray, lit: np.ndarray, mask: np.ndarray | None,
              region: tuple[int, int, int, int]) -> np.ndarray:
        """``lit`` (0/255, the pixels passing the light test in ``hsv``, the HSV of ``region`` (x0, y0,
        x1, y1) frame px) grown into the connected saturated red-to-green pixels of V >=
        ``grow_value`` (hysteresis): a dimmed light's pixels scatter about ``min_value`` and only some
        pass it; grown from them, the light is one compact blob again. No new blob: only pixels
        connected to one that passes the strict test join."""
        lo, hi = (self.min_saturation, self.grow_value), (255, 255)
        weak = cv2.inRange(hsv, (0, *lo), (90, *hi))
        weak |= cv2.inRange(hsv, (170, *lo), (179, *hi))
        if mask is not None:
            x0, y0, x1, y1 = region
            weak = cv2.bitwise_and(weak, weak, mask=_u8(mask[y0:y1, x0:x1]))
        n, lab = cv2.connectedComponents(weak, connectivity=8)
        keep = np.zeros(n, bool)
        keep[lab[lit > 0]] = True
        keep[0] = False
        return np.where(keep[lab], 255, 0).astype(np.uint8)

    def _lone_light(
        self, hsv: np.ndarray, x0: int, y0: int, box: np.ndarray, area: float, colour: str = "red"
    ) -> bool:
        """Whether a red or green blob (``box`` (4,) frame px xyxy, ``area`` px) looks like a light on
        its own: small (``single_max_area_px``), compact (it fills at least half its box) and brighter
        than the ring 2-4 px around its box by ``white_contrast`` (median V)."""
        if area > self.single_max_area_px:
            return False
        bw, bh = box[2] - box[0] + 1, box[3] - box[1] + 1
        if area < 0.5 * bw * bh:
            return False
        xa, ya = int(box[0]) - x0, int(box[1]) - y0
        xb, yb = int(box[2]) - x0 + 1, int(box[3]) - y0 + 1
        H, W = hsv.shape[:2]
        v = hsv[:, :, 2]
        ring = v[max(ya - 4, 0):min(yb + 4, H), max(xa - 4, 0):min(xb + 4, W)].astype(np.int32)
        inner = np.zeros(ring.shape, bool)
        iy, ix = max(ya - 4, 0), max(xa - 4, 0)
        inner[max(ya - 2, 0) - iy:min(yb + 2, H) - iy, max(xa - 2, 0) - ix:min(xb + 2, W) - ix] = True
        if inner.all():
            return False
        peak = int(v[ya:yb, xa:xb].max())
        if peak < int(np.median(ring[~inner])) + self.white_contrast:
            return False
        # a light is a colour spot on a surface of another colour; a piece of a coloured surface
        # (a bright green texture cut up by noise) has its hue, well saturated, all around it
        hr = hsv[max(ya - 4, 0):min(yb + 4, H), max(xa - 4, 0):min(xb + 4, W)][~inner]
        # the light's own hue: red is 0 (its hues wrap round 180: 178 and 2 are both red, and a
        # median over them, or over the box's other pixels, is some other colour: a red light on a
        # blue sky (hue ~107) got a median of 111 and was judged a piece of the sky); green the
        # median over the box's pixels of green hue (45-90, no wrap)
        if colour == "red":
            hue = 0
        else:
            hb = hsv[ya:yb, xa:xb, 0]
            g = hb[(hb >= 45) & (hb <= 90)]
            hue = int(np.median(g)) if g.size else 60
        dh = np.abs(hr[:, 0].astype(np.int32) - hue)
        dh = np.minimum(dh, 180 - dh)
        alike = (dh <= 15) & (hr[:, 1] >= self.min_saturation // 2)
        return float(np.mean(alike)) < 0.25

    def _white_between(self, image: np.ndarray, r: np.ndarray, g: np.ndarray) -> np.ndarray | None:
        """Frame pixel (2,) of the white light between the red light ``r`` and the green ``g``
        (frame px), or None.

        Looked for in the square around the pair's midpoint of half-size half the separation + 2 px
        (of ``image``, the (H, W, 3) BGR frame, converted to HSV here: the square is the same whatever
        part of the frame was searched for the lights): the brightest unsaturated pixel
        (S <= max_white_saturation) that is at least ``white_contrast`` above the square's median V
        and at least ``min_value``, whose projection on the red-green segment lies in its middle 80 %.
        """
        mid = (r + g) / 2
        seg = g - r
        L = float(np.hypot(*seg))
        h = int(np.ceil(L / 2)) + 2
        cx, cy = int(round(mid[0])), int(round(mid[1]))
        ya, yb = max(cy - h, 0), min(cy + h + 1, image.shape[0])
        xa, xb = max(cx - h, 0), min(cx + h + 1, image.shape[1])
        if yb <= ya or xb <= xa:
            return None
        win = cv2.cvtColor(image[ya:yb, xa:xb], cv2.COLOR_BGR2HSV)
        s, v = win[:, :, 1].astype(np.int32), win[:, :, 2].astype(np.int32)
        need = max(self.min_value, int(np.median(v)) + self.white_contrast)
        ok = (s <= self.max_white_saturation) & (v >= need)
        if not np.any(ok):
            return None
        vy, vx = np.nonzero(ok)
        p = np.stack([vx + xa, vy + ya], axis=1).astype(float)  # frame pixels
        u = (p - r) @ seg / (L * L)  # 0 at red, 1 at green
        inside = (u > 0.1) & (u < 0.9)
        if not np.any(inside):
            return None
        p, vals = p[inside], v[vy[inside], vx[inside]]
        return p[int(np.argmax(vals))]
