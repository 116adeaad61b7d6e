"""Reverse views held between association frames (FrontEnd._follow_only, association.unheld):
a second camera's track keeps its reference view while its members are followed, and one whose
members last frame's matches cannot hold is searched in full. Hand-built geometry: two cameras on
one point, cam1 turned 3 degrees about y, over a textured world at infinity (pure rotation), so a
feature seen along b1 from cam1 is seen along R_0_1 b1 from cam0."""

from __future__ import annotations

import numpy as np
import pytest

from tests.trackers.conftest import equidistant, rot_axis, turned_pair_rig
from trackers.association import unheld


def test_unheld_counts_members_among_last_frames_matches():
    """A track with fewer than 3 of its members among the held ids is unheld; order and
    duplicates in the held ids do not matter; an empty track is unheld."""
    members = [np.array([1, 2, 3, 4]), np.array([5, 6, 7]), np.array([8, 9]), np.zeros(0, np.int64)]
    held = np.array([9, 7, 6, 4, 3, 2, 8, 8])
    np.testing.assert_array_equal(unheld(members, held, 3), [False, True, True, True])
    np.testing.assert_array_equal(unheld(members, held, 2), [False, False, False, True])
    np.testing.assert_array_equal(unheld(members, np.zeros(0, np.int64)), [True] * 4)
    assert unheld([], held).shape == (0,)


def _rotation_rig():
    """(rig, R_1_0, frames(k) -> (cam0 frame, cam1 frame)): cam1 = cam0 turned 3 degrees about y,
    same centre; a blank sky with a textured disc (14 deg radius) moving 0.5 deg per frame."""
    from tests.trackers.conftest import Patch, SphereScene

    model = equidistant(640, 480)
    rig, R_1_0 = turned_pair_rig(model)
    scene = SphereScene(model, blank_env=True)
    d0 = np.array([0.2, 0.0, 1.0]) / np.hypot(0.2, 1.0)

    def frames(k):
        p = [Patch(rot_axis([1, 0, 0], np.radians(0.5) * k) @ d0, np.radians(14), seed=8)]
        return scene.render(None, p), scene.render(R_1_0.T, p)

    return rig, R_1_0, frames


def _cam0_view_error_px(obs, R_1_0, rad_px):
    """Per two-camera report: (its cam0 view's shared features' bearing error against R_0_1 b1,
    px of angle, median); and the count of reports with a cam1 view."""
    errs, with_cam1 = [], 0
    for o in obs:
        views = {w.camera: w for w in o.views}
        if "cam1" not in views:
            continue
        with_cam1 += 1
        if "cam0" not in views:
            continue
        w0, w1 = views["cam0"], views["cam1"]
        row1 = {int(i): k for k, i in enumerate(w1.feature_ids)}
        ks = [(k0, row1[int(i)]) for k0, i in enumerate(w0.feature_ids) if int(i) in row1]
        assert len(ks) >= 3
        e0 = w1.feature_b_C[[k1 for _, k1 in ks]] @ R_1_0  # R_0_1 b1 (rows)
        b0 = w0.feature_b_C[[k0 for k0, _ in ks]]
        errs.append(np.median(np.arccos(np.clip(np.sum(e0 * b0, axis=1), -1, 1))) / rad_px)
    return errs, with_cam1


@pytest.mark.parametrize("upset", ["forgotten", "moved"])
def test_reverse_view_is_held_between_association_frames(upset):
    """cam0 groups nothing, so cam1's tracks get cam0 views only the other way round. On a frame
    between association frames, last frame's cam1 -> cam0 matches are either forgotten (as for a
    track confirmed, or left by its reference track, since the last association frame) or moved
    3 px off (followed matches that land over recheck_px from their start): every cam1 track
    that had a cam0 view keeps one (searched in full; forward-backward checked instead of
    dropped), its features where the rotation puts them (median under 0.3 px)."""
    import cv2

    from trackers.frontend import FrontEnd

    cv2.setNumThreads(1)
    rig, R_1_0, frames = _rotation_rig()
    fe = FrontEnd(rig, association={"reverse_views": True, "every": 5})
    fe.groupers["cam0"].update = lambda *a, **k: ([], [])  # cam0 groups nothing
    rad_px = fe._rad_px["cam0"]
    before = None
    for f in range(13):
        if f == 11:  # between association frames 10 and 15
            m = fe._stereo_mem[("cam1", "cam0")]
            if upset == "forgotten":
                del fe._stereo_mem[("cam1", "cam0")]
            else:
                fe._stereo_mem[("cam1", "cam0")] = (m[0], m[1], m[2], m[3] + 3.0, m[4])
        img0, img1 = frames(f)
        obs = fe.process({"cam0": img0, "cam1": img1}, f, f / 30.0)
        errs, with_cam1 = _cam0_view_error_px(obs, R_1_0, rad_px)
        if f == 10:
            before = len(errs)
            assert before >= 1 and before == with_cam1  # every cam1 track viewed on the full search
        if f in (11, 12):
            assert len(errs) == before, f"frame {f}: {len(errs)} of {before} cam0 views held"
            assert np.median(errs) < 0.3
