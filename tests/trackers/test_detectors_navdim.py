"""navlights on dimmed lights (a camera's exposure gain, tuned scene noisy_1080p): a lone red light on a
blue sky is judged by its own hue, and ``grow_value`` grows a light whose pixels scatter about
``min_value`` into one blob. Expected values come from the drawn frames (where and how bright the
lights are put), not from the code under test."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from estimators.errors import ConfigError
from trackers.detectors import make_detector

SKY = (165, 140, 125)  # BGR: a dim blue sky, HSV (109, 62, 165), as noisy_1080p's


def sky() -> np.ndarray:
    return np.full((240, 320, 3), SKY, np.uint8)


def test_the_sky_is_what_the_tests_assume():
    h, s, v = cv2.cvtColor(sky()[:1, :1], cv2.COLOR_BGR2HSV)[0, 0]
    assert 100 <= h <= 115 and s >= 60 and v == 165  # blue, saturated enough to count as "alike"


def test_a_lone_red_light_on_a_blue_sky_is_judged_by_its_own_hue():
    """A plus-shaped red light (5 px in its 3x3 box, hues 0 and 178: red wraps round 180) on the sky.
    Its box's median hue is the sky's (4 sky corners, 0 0 178 178 178 in the middle of the sort), so
    the old rule found the ring "of its colour" and dropped it as a piece of a blue surface."""
    img = sky()
    offsets = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))
    colours = ((0, 0, 255), (0, 0, 255), (40, 0, 255), (40, 0, 255), (40, 0, 255))  # hue 0, 0, ~175 ...
    for (du, dv), bgr in zip(offsets, colours, strict=True):
        img[120 + dv, 160 + du] = bgr
    hues = cv2.cvtColor(img[119:122, 159:162], cv2.COLOR_BGR2HSV)[:, :, 0]
    assert sorted(hues.ravel().tolist())[4] > 100  # the box's median hue is the sky's
    d = make_detector("navlights").detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["red_uv"] == [160.0, 120.0]
    assert d.attributes[0]["heading"] is None


def dimmed_light(img: np.ndarray, u: int, v: int, bgr_dim, bgr_peak) -> np.ndarray:
    """A 5x5 light of V 172 (under min_value 180) with its diagonal at V 186: the pixels that pass
    min_value alone are a thin diagonal, 5 px in a 5x5 box (not compact)."""
    img[v - 2:v + 3, u - 2:u + 3] = bgr_dim
    for k in range(-2, 3):
        img[v + k, u + k] = bgr_peak
    return img


def test_grow_value_finds_a_dimmed_lone_light_as_one_compact_blob():
    img = dimmed_light(sky(), 160, 120, (20, 20, 172), (20, 20, 186))
    # its pixels passing min_value alone: a thin diagonal, not compact
    assert len(make_detector("navlights", grow_value=None).detect(img).boxes) == 0
    d = make_detector("navlights", grow_value=150).detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["red_uv"] == [160.0, 120.0]
    x1, y1, x2, y2 = d.boxes[0]
    assert (x1, y1, x2, y2) == (158 - 3, 118 - 3, 162 + 3, 122 + 3)  # the whole 5x5 light + margin


def test_grow_value_makes_no_light_of_its_own():
    """Growing starts only from pixels that pass min_value: a saturated red surface of V 170 and a
    dim red spot beside a bright green one give nothing new."""
    img = sky()
    img[100:140, 60:160] = (20, 20, 170)  # a red wall in shade
    assert len(make_detector("navlights", grow_value=150).detect(img).boxes) == 0
    img = sky()
    img[118:123, 198:203] = (20, 20, 170)  # a dim red spot (V 170) ...
    img[120, 230] = (0, 255, 0)  # ... 30 px from a green light: no pair, only the green lone light
    d = make_detector("navlights", grow_value=150).detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["green_uv"] == [230.0, 120.0]


@pytest.mark.parametrize("bad", [-1, 181, 1.5, True, "150"])
def test_grow_value_must_be_a_level_up_to_min_value(bad):
    with pytest.raises(ConfigError, match="grow_value"):
        make_detector("navlights", grow_value=bad)
