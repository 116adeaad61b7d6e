"""Two cameras' tracks merged by the association into one obstacle keep the id seen for longer,
whichever camera tracks it (FrontEnd._survivor; issue 4: track id switches). The frame counts are
set by hand."""

from __future__ import annotations

import numpy as np

from estimators.rig import stereo_forward_rig
from tests.trackers.conftest import equidistant
from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleTrack


def test_two_cameras_tracks_merging_keep_the_id_seen_for_longer():
    """demo f30: the right camera's track of 28 frames lost its id to the left (reference) camera's
    track of 18 frames; the longer-seen id survives now, from either camera; equal counts keep the
    older (smaller) id."""
    fe = FrontEnd(stereo_forward_rig(equidistant(), baseline_m=0.3))
    b = np.array([0.0, 0.0, 1.0])
    fe.groupers["cam0"].tracks[31] = ObstacleTrack(31, "cam0", np.zeros(0, np.int64), b, hits=18)
    fe.groupers["cam1"].tracks[16] = ObstacleTrack(16, "cam1", np.zeros(0, np.int64), b, hits=28)
    assert fe._survivor(31, 16) == (16, 31) and fe._survivor(16, 31) == (16, 31)
    fe.groupers["cam0"].tracks[31].hits = 28
    assert fe._survivor(31, 16) == (16, 31)
    fe.groupers["cam0"].tracks[31].hits = 29
    assert fe._survivor(16, 31) == (31, 16)
