"""Step 3c's window flows are derotated over the whole window: the grouper chains the
frame-to-frame rotations it is given (``R_C_Cprev[1]``) past the few frames back the front end
gives (``R_C_Cprev[k]`` for k = 1..7: its pose history holds 8 poses), so a member seen 10 frames
ago is not compared with one seen 6 frames ago as if the camera had not turned in between.

Closed form: a camera that only turns (no translation) sees every static point move by the
rotation alone, so after derotation every member's window flow is exactly 0 and nothing can be
split by motion. Without the rotation for the older samples, a member tracked over the whole
10-frame window keeps the turn's flow (yaw 0.5 rad/s: ~0.5 rad/s, ~60 px/s here) and one tracked
over 5-7 frames has none: a jump step 3c would cut (the code before this test did)."""

from __future__ import annotations

from collections import deque

import numpy as np

from tests.trackers.conftest import rot_axis
from tests.trackers.test_grouping import PointFeatures, unit
from trackers.grouping import ObstacleGrouper

FPS = 30.0
YAW_RAD_S = 0.5
FRONT_END_K = 7  # the front end's rotations reach this many frames back (deque of 8 poses)


class Features(PointFeatures):
    """The test's stand-in FeatureTracker, with the history counts the grouper reads when it is
    given the camera's rotations (one sample per frame since a feature was born)."""

    @property
    def slot(self) -> np.ndarray:
        return np.arange(len(self.ids))

    @property
    def _h_n(self) -> np.ndarray:
        return self.age


def _turning_wall(model, rotations_back: int, frames: int = 30):
    """A 4 x 4 grid of points (6 px apart) at 5 m, seen from a camera turning about its y axis at
    YAW_RAD_S; a second 4 x 4 grid interleaved with it (half a step off) appears at frame 12. The
    grouper gets R_C_Cprev[k] for k = 1..rotations_back. Returns (grouper, ids of the grid, of the
    late grid, per frame the member-id sets of the tracks seen)."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 6.0 * rad_px
    old = [5.0 * unit([(x - 1.5) * step, (y - 1.5) * step, 1.0]) for x in range(4) for y in range(4)]
    late = [5.0 * unit([(x - 1.0) * step, (y - 1.0) * step, 1.0]) for x in range(4) for y in range(4)]
    pts = np.array(old + late)
    ids_old, ids_late = list(range(1, 17)), list(range(17, 33))
    gr = ObstacleGrouper(iter(range(1, 1000)))
    ft = Features(model)

    def R_C_W(t_s: float) -> np.ndarray:
        return rot_axis([0, 1, 0], YAW_RAD_S * t_s).T

    held = []
    for k in range(frames):
        t_s = k / FPS
        ids = ids_old + (ids_late if k >= 12 else [])
        ft.set(ids, np.array([R_C_W(t_s) @ unit(pts[i - 1]) for i in ids]), t_s)
        R = {j: R_C_W(t_s) @ R_C_W(t_s - j / FPS).T for j in range(1, rotations_back + 1)} if k else None
        seen, _ = gr.update(ft, t_s, R)
        held.append([set(t.members.tolist()) for t in seen])
    return gr, set(ids_old), set(ids_late), held


def test_a_turn_known_only_7_frames_back_does_not_split_old_from_young_members(model):
    """With the front end's 7 frames of rotations, the 10-frame window is derotated by the
    chained frame-to-frame rotations: no split, and at the end one track holds both grids."""
    gr, ids_old, ids_late, held = _turning_wall(model, FRONT_END_K)
    assert gr.splits == 0
    assert len(held[-1]) == 1 and held[-1][0] == ids_old | ids_late


def test_the_same_with_every_rotation_given(model):
    """The reference: the rotations given for the whole window (k = 1..31) give the same answer."""
    gr, ids_old, ids_late, held = _turning_wall(model, 31)
    assert gr.splits == 0
    assert len(held[-1]) == 1 and held[-1][0] == ids_old | ids_late


def test_window_rotations_are_the_chained_products_whatever_the_window_order():
    """``_window_rotations`` keeps one frame's chain of products for both windows (the flow's and
    step 3c's): each window gets the products ``R1[1] R1[2] ... R1[k]`` made in that order (the
    same numbers as multiplying them out for that window alone), the given rotations where they
    exist, and a new frame's rotation starts a new chain."""
    rng = np.random.default_rng(3)
    gr = ObstacleGrouper(iter(range(1, 1000)))
    gr._R1_hist = deque(maxlen=30)
    given = {1: rng.standard_normal((3, 3)), 2: rng.standard_normal((3, 3))}

    def expected(frames):
        out = {k: v for k, v in given.items() if k <= frames}
        acc = np.eye(3)
        for k, R1 in enumerate(list(gr._R1_hist)[:frames], start=1):
            acc = acc @ R1
            out.setdefault(k, acc)
        return out

    for _ in range(25):
        gr._remember_rotation(rng.standard_normal((3, 3)))
        for frames in (rng.integers(1, 30), rng.integers(1, 30), 20, 10):
            got, want = gr._window_rotations(given, int(frames)), expected(int(frames))
            assert sorted(got) == sorted(want)
            assert all(np.array_equal(got[k], want[k]) for k in want)
    gr._remember_rotation(None)  # a frame without a rotation breaks the chain
    assert gr._window_rotations(given, 10) == {}
