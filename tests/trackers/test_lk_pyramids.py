"""KLT level by level on pyramids built once (trackers/features.py ``_lk_pyramids``,
``FeatureTracker._pyramid``).

The reference is OpenCV's own one-call search (``cv2.calcOpticalFlowPyrLK`` at maxLevel n) and its
own pyramid depth (``cv2.buildOpticalFlowPyramid``'s returned level): the level-by-level search must
give its positions and statuses bit for bit, and its err wherever a point is found."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

from estimators.rig import Camera, forward_T_C_B
from tests.trackers.conftest import SphereScene, blocky_texture, equidistant, rot_axis
from trackers.detectors import make_detector
from trackers.features import FeatureTracker, _lk_pyramids, _lk_top_level

CRIT = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)


def _pair(h: int, w: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A blocky texture and the same texture moved by (3.4, -2.1) px and turned 1 degree."""
    img = blocky_texture(max(h, w), max(h, w) // 6, seed)[:h, :w].copy()
    M = cv2.getRotationMatrix2D((w / 2, h / 2), 1.0, 1.0)
    M[:, 2] += (3.4, -2.1)
    return img, cv2.warpAffine(img, M, (w, h), borderMode=cv2.BORDER_REFLECT_101)


def _levels(img: np.ndarray, n: int) -> list[np.ndarray]:
    out = [img]
    for _ in range(n):
        out.append(cv2.pyrDown(out[-1]))
    return out


@pytest.mark.parametrize(
    "h, w, win, level", [(300, 340, 13, 2), (300, 340, 11, 3), (90, 70, 13, 4), (300, 340, 9, 0)]
)
def test_top_level_is_opencvs_pyramid_depth(h, w, win, level):
    img = np.zeros((h, w), np.uint8)
    got, _ = cv2.buildOpticalFlowPyramid(img, (win, win), level, withDerivatives=False)
    assert _lk_top_level(img.shape, win, level) == got


@pytest.mark.parametrize(
    "h, w, win, level, flags",
    [
        (300, 340, 13, 2, cv2.OPTFLOW_USE_INITIAL_FLOW),
        (300, 340, 13, 1, cv2.OPTFLOW_USE_INITIAL_FLOW | cv2.OPTFLOW_LK_GET_MIN_EIGENVALS),
        (300, 340, 11, 3, cv2.OPTFLOW_USE_INITIAL_FLOW),
        (90, 70, 13, 4, cv2.OPTFLOW_USE_INITIAL_FLOW),  # (OpenCV stops at level 1 here)
        (300, 340, 13, 2, 0),  # no initial flow: the search starts at the points, the guess unread
    ],
)
def test_level_by_level_equals_one_call_bit_for_bit(h, w, win, level, flags):
    rng = np.random.default_rng(7)
    for seed in range(3):
        a, b = _pair(h, w, seed)
        good = cv2.goodFeaturesToTrack(a, 300, 0.01, 5).astype(np.float32)
        # points near and beyond the edges too (lost at some level or at the end)
        edge = rng.uniform(-25, max(h, w) + 25, (40, 1, 2)).astype(np.float32)
        p = np.concatenate([good, edge])
        guess = (p + rng.normal(0.0, 3.0, p.shape)).astype(np.float32)
        q, st, err = cv2.calcOpticalFlowPyrLK(
            a, b, p, guess.copy(), winSize=(win, win), maxLevel=level, criteria=CRIT, flags=flags
        )
        top = _lk_top_level(a.shape, win, level)
        q2, st2, err2 = _lk_pyramids(_levels(a, top), _levels(b, top), p, guess, win, level, CRIT, flags)
        assert q2.tobytes() == q.tobytes()
        np.testing.assert_array_equal(st2, st.reshape(-1))
        found = st.reshape(-1) == 1
        assert found.sum() > 100 and (~found).sum() > 5
        assert err2[found].tobytes() == err.reshape(-1)[found].tobytes()


def test_tracker_builds_each_frames_levels_once(monkeypatch):
    """The whole-crop KLT passes read a frame's pyramid as this frame's target, its backward pass's
    source and later as a reference: cv2.pyrDown runs once a level and frame (2 levels at the
    default maxLevel 2), the cache holding only the reference frames' pyramids."""
    model = equidistant(320, 240)
    scene = SphereScene(model)
    ft = FeatureTracker(
        Camera("cam0", model, forward_T_C_B()),
        make_detector("orb", max_features=300),
        ids=itertools.count(1),
        max_features=300,
        redetect_s=1e6,
    )
    calls = []
    real = cv2.pyrDown
    monkeypatch.setattr(cv2, "pyrDown", lambda img, *a, **k: calls.append(img.shape) or real(img, *a, **k))
    n = 8
    for k in range(n):
        ft.track(scene.render(rot_axis([0, 1, 0], np.radians(2.0) * k / 30.0)), k, k / 30.0)
    assert ft.last_stats["klt_ok"] > 100
    # (frame 0's levels built at frame 1, as its source; without the cache six a frame: each
    # frame's two levels in the forward pass, level 1 again in the backward, all again two frames on)
    assert len(calls) == 2 * n
    assert set(ft._pyrs) == {id(r[2]) for r in ft._refs}


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_lk_box_is_the_finite_points_box(bad):
    """``_lk_box`` (the part of an image a KLT call reads): the finite points' extremes with the
    margin around, the origin down to a multiple of ``align``, clipped to the image; a non-finite
    coordinate drops its point, none finite gives the whole image. Worked by hand: x in [100.25,
    300.5], y in [50.75, 201.0], margin 22: x0 = floor(78.25) = 78 -> 72 (align 8), y0 = 28 -> 24,
    x1 = ceil(322.5) + 1 = 324, y1 = ceil(223.0) + 1 = 224."""
    from trackers.features import _lk_box

    pts = np.array([[100.25, 120.0], [300.5, 50.75], [180.0, 201.0]], np.float32)
    assert _lk_box(pts, 22.0, (480, 640), 8) == (72, 24, 324, 224)
    odd = np.array([[bad, 5.0], [600.0, bad]], np.float32)
    assert _lk_box(np.concatenate([pts, odd]), 22.0, (480, 640), 8) == (72, 24, 324, 224)
    assert _lk_box(odd, 22.0, (480, 640), 8) == (0, 0, 640, 480)
    assert _lk_box(pts[:0], 22.0, (480, 640), 8) == (0, 0, 640, 480)
    # clipped to the image
    assert _lk_box(pts, 200.0, (300, 400), 16) == (0, 0, 400, 300)
