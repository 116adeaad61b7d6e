"""navlights over a sequence (``detect_boxes`` with ``scan_every``: the whole lens every N-th frame,
around the drones already found in between) and its white-light window (the same square whatever part
of the frame was searched). Expected values come from where the lights are drawn."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from trackers.detectors import make_detector

RED, GREEN = (0, 0, 255), (0, 255, 0)


def frame(pairs, size=(240, 320)) -> np.ndarray:
    """A dark frame with one-pixel red-green pairs ((red u, v), (green u, v)) drawn."""
    img = np.full(size + (3,), 60, np.uint8)
    for r, g in pairs:
        img[r[1], r[0]] = RED
        img[g[1], g[0]] = GREEN
    return img


def centres(det) -> list[tuple[float, float]]:
    return [(round(float(c[0]), 1), round(float(c[1]), 1)) for c in det.box_centres]


def test_scan_every_finds_a_new_drone_at_the_next_full_scan_and_follows_a_found_one_every_frame():
    nav = make_detector("navlights", scan_every=3)
    mask = np.full((240, 320), 255, np.uint8)
    a = lambda k: ((100 + 2 * k, 60), (92 + 2 * k, 60))  # noqa: E731  (moves 2 px a frame)
    b = ((250, 200), (242, 200))  # appears at frame 1, far from a
    got = []
    for k in range(5):
        pairs = [a(k)] + ([b] if k >= 1 else [])
        got.append(centres(nav.detect_boxes(frame(pairs), mask)))
    # frame 0: full scan; 1, 2: only around a; 3: full scan; 4: around a and b
    assert got[0] == [(96.0, 60.0)]
    assert got[1] == [(98.0, 60.0)] and got[2] == [(100.0, 60.0)]
    assert sorted(got[3]) == [(102.0, 60.0), (246.0, 200.0)]
    assert sorted(got[4]) == [(104.0, 60.0), (246.0, 200.0)]
    # detect (one frame, no sequence) always searches the whole lens
    assert sorted(centres(nav.detect(frame([a(1), b]), mask))) == [(98.0, 60.0), (246.0, 200.0)]


def test_scan_every_keeps_one_sequence_per_camera_mask():
    nav = make_detector("navlights", scan_every=2)
    m0, m1 = np.full((240, 320), 255, np.uint8), np.full((240, 320), 255, np.uint8)
    p = ((100, 60), (92, 60))
    assert len(nav.detect_boxes(frame([p]), m0).boxes) == 1  # cam0: full scan
    assert len(nav.detect_boxes(frame([]), m1).boxes) == 0  # cam1: full scan, nothing
    assert len(nav.detect_boxes(frame([p]), m1).boxes) == 0  # cam1: nothing found before: no search
    assert len(nav.detect_boxes(frame([p]), m0).boxes) == 1  # cam0: around its drone
    assert len(nav.detect_boxes(frame([p]), m1).boxes) == 1  # cam1: its full scan


def test_scan_every_without_masks_keeps_one_sequence_per_camera_name():
    """mask None for both cameras: the camera name tells their sequences apart (keyed by the mask
    object alone, cam1's first call would continue cam0's sequence and skip its full scan)."""
    nav = make_detector("navlights", scan_every=2)
    p = ((100, 60), (92, 60))
    assert len(nav.detect_boxes(frame([]), None, camera="cam0").boxes) == 0  # cam0: full scan, nothing
    assert len(nav.detect_boxes(frame([p]), None, camera="cam1").boxes) == 1  # cam1: its full scan
    assert len(nav.detect_boxes(frame([p]), None, camera="cam0").boxes) == 0  # cam0: nothing to follow
    assert len(nav.detect_boxes(frame([p]), None, camera="cam1").boxes) == 1  # cam1: around its drone
    assert len(nav.detect_boxes(frame([p]), None, camera="cam0").boxes) == 1  # cam0: its full scan


def test_composite_passes_the_camera_name_to_its_box_part():
    det = make_detector("orb+navlights", navlights={"scan_every": 2})
    p = ((100, 60), (92, 60))
    assert len(det.detect_boxes(frame([]), None, camera="cam0").boxes) == 0
    assert len(det.detect_boxes(frame([p]), None, camera="cam1").boxes) == 1  # its own full scan


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "3"])
def test_scan_every_must_be_a_whole_number_of_frames(bad):
    with pytest.raises(ConfigError, match="scan_every"):
        make_detector("navlights", scan_every=bad)


def test_white_light_off_the_lights_rows_is_found_in_its_whole_window():
    """A bluish-white light (B above G and R: not a red/green candidate itself) 10 px below the middle
    of a pair 40 px apart lies inside the documented window (half-size 40 / 2 + 2 px)."""
    img = frame([((180, 120), (140, 120))])
    img[130, 160] = (255, 235, 235)  # S 20, V 255
    d = make_detector("navlights").detect(img)
    assert len(d.boxes) == 1 and d.attributes[0]["white_uv"] == [160.0, 130.0]
    assert d.box_scores[0] == 1.0
