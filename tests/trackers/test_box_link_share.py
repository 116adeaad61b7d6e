"""BoxTracker: a new box <-> feature track link needs ``link_share`` (3/4) of the feature track's
members on the box; a held link keeps half. Positions drawn by hand (pixels on an 8x8 px box moving
2 px a frame; members "off" lie 14-15 px below its centre or 10 px left of it, outside its
half-diagonal of 5.7 px plus the 3 px margin, and move with it; the feature track's bearing, their
mean, stays within that reach in every case below), not taken from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from estimators.rig import mono_forward_rig
from tests.trackers.conftest import equidistant
from trackers.detectors import Detections
from trackers.grouping import BoxTracker, ObstacleTrack

ON = [(-2.0, -1.0), (2.0, 1.0), (0.0, 0.0), (1.0, -2.0)]  # pixel offsets from the box centre
OFF = [(0.0, 14.0), (1.0, 15.0), (-10.0, 0.0)]


def _run(per_frame: list[tuple[int, int]]):
    """Box track id 5 with feature track 7 on it; per frame (members on the box, members off it)
    taken from ON and OFF; returns the links after each frame."""
    model = equidistant()
    cam = mono_forward_rig(model).cameras[0]
    bt = BoxTracker(iter(range(5, 100)))
    out = []
    for k, (n_on, n_off) in enumerate(per_frame):
        u0, v0 = 160.0 + 2 * k, 120.0
        det = Detections(boxes=np.array([[u0 - 4, v0 - 4, u0 + 4, v0 + 4]]), labels=("drone",),
                         attributes=({},))
        px = np.array([(u0 + du, v0 + dv) for du, dv in ON[:n_on] + OFF[:n_off]])
        mb, _ = model.pixel_to_bearing(px)
        ids = np.array([100 + i for i in range(n_on)] + [200 + i for i in range(n_off)])
        b = mb.mean(axis=0)
        ft = ObstacleTrack(7, "cam0", ids, b / np.linalg.norm(b), member_b_C=mb)
        bt.update(cam, det, [ft], t_s=k / 30)
        out.append(dict(bt.links))
    return out


def test_a_new_link_needs_three_quarters_of_the_members_on_the_box():
    """3 of 4 members on the box: linked once it moved with the box over link_frames (3) updates, the
    4th frame; 2 of 4 (half, which linked before): never linked."""
    assert _run([(3, 1)] * 6) == [{}] * 3 + [{5: 7}] * 3
    assert _run([(2, 2)] * 6) == [{}] * 6


def test_a_held_link_keeps_half_of_the_members_on_the_box():
    """Linked with 4 of 4 on the box, the link holds when two leave it (2 of 4 on the box, half) and
    ends at 2 of 5 (fewer than half) or at 1 of 2 (half, but fewer than link_min_members, 2)."""
    held = [{}] * 3 + [{5: 7}] * 3
    assert _run([(4, 0)] * 4 + [(2, 2)] * 2 + [(2, 3)]) == held + [{}]
    assert _run([(4, 0)] * 4 + [(2, 2)] * 2 + [(1, 1)]) == held + [{}]


@pytest.mark.parametrize("bad", [0.4, 1.5, True, "0.75"])
def test_link_share_must_be_between_half_and_one(bad):
    with pytest.raises(ConfigError, match="link_share"):
        BoxTracker(iter(range(5)), link_share=bad)
