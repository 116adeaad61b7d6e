"""Step 3c of the grouper: a track whose members form two surfaces by their motion over several
frames splits, a smooth flow field does not. Synthetic bearings (the test chooses every feature's
direction), so the expected tracks follow from the construction."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from tests.trackers.conftest import rot_axis
from tests.trackers.test_grouping import PointFeatures, unit
from trackers.grouping import ObstacleGrouper, _found_again

FPS = 30.0
# frame to frame, flows agree within flow_abs + flow_rel |f| = 0.1 + 0.2 |f| rad/s, so the moving
# parts below (0.1 rad/s against 0, or 0.24 against 0.12) join one track on their first frames
FLOW_ABS = 0.1


def grid(nx: int, ny: int, x0: float, step: float) -> list[tuple[float, float]]:
    """Tangent-plane offsets (rad) of an nx x ny grid of points ``step`` apart, starting at x0."""
    return [(x0 + i * step, (j - (ny - 1) / 2) * step) for i in range(nx) for j in range(ny)]


def simulate(model, parts, frames: int, **opts):
    """parts: list of (offsets [(x, y)] rad about +z, angular rate (rad/s) about the y axis, or a
    function of x giving it); every point turns about y at its rate. Returns the grouper, the
    feature ids per part, and per frame the member-id sets of the tracks seen."""
    gr = ObstacleGrouper(iter(range(1, 10_000)), flow_abs_rad_s=FLOW_ABS, **opts)
    ft = PointFeatures(model)
    ids, dirs, rates = [], [], []
    part_ids = []
    for offs, rate in parts:
        pid = []
        for x, y in offs:
            ids.append(len(ids) + 1)
            pid.append(ids[-1])
            dirs.append(unit([x, y, 1.0]))
            rates.append(rate(x) if callable(rate) else rate)
        part_ids.append(set(pid))
    held = []
    for k in range(frames):
        t_s = k / FPS
        b = np.array([rot_axis([0, 1, 0], w * t_s) @ d for d, w in zip(dirs, rates, strict=True)])
        ft.set(ids, b, t_s)
        seen, _ = gr.update(ft, t_s)
        held.append([set(t.members.tolist()) for t in seen])
    return gr, part_ids, held


def test_an_obstacle_drifting_across_a_still_background_splits_off(model):
    """A 9 x 9 grid of still background points 6 px apart and a 3 x 3 obstacle beside its
    middle, touching it (6 px), drifting at 0.1 rad/s: frame to frame its flow agrees with the
    background's (0.1 < 0.1 + 0.2 x 0.1), so one track holds both. Over the 10-frame window
    it moves 0.1 / 3 rad = 2.2 px (this lens: 0.0155 rad/px) away from its neighbours: more than
    split_min_px (1.5 px) plus split_rel of its flow, and the background has no flow step of its
    own, so after split_persist frames in a row it leaves: one track holds exactly the obstacle,
    another exactly the background, from then on."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 6.0 * rad_px
    bg = grid(9, 9, -8 * step, step)
    obst = grid(3, 3, 1 * step, step)
    gr, (bg_ids, ob_ids), held = simulate(model, [(bg, 0.0), (obst, 0.1)], 30)
    # at first (old enough, min_age 3): one track mixes them
    assert any((m & ob_ids) and (m & bg_ids) for m in held[4]), held[4]
    # the window flow is judged once a feature has half the window (5 frames); a cut needs the
    # 2.2 px x (back / 10) drift over `back` frames to beat 1.5 px + 10 %: back >= 8, then
    # split_persist = 3 frames in a row: split by frame 11 (checked from 14 on, some margin)
    for k in range(14, 30):
        assert ob_ids in held[k], (k, held[k])
        assert bg_ids in held[k], (k, held[k])
    assert gr.split_persist == 3 and gr.split_frames == 10


def test_two_touching_surfaces_at_different_depths_stay_apart(model):
    """Parallax of a translating camera: two 4 x 4 grids side by side and touching, the near one
    turning at 0.24 rad/s, the far one (twice as far) at 0.12 rad/s. Frame to frame they agree
    (0.12 < 0.1 + 0.2 x 0.24); over the 10-frame window the near one moves 5.2 px against 2.6 px:
    2.6 px apart, more than 1.5 px + 10 % of the flow (2.3 px). They end as two tracks, each
    holding exactly one grid, and stay apart."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 6.0 * rad_px
    near = grid(4, 4, -4 * step, step)
    far = grid(4, 4, 0.0, step)
    gr, (near_ids, far_ids), held = simulate(model, [(near, 0.24), (far, 0.12)], 30)
    assert any((m & near_ids) and (m & far_ids) for m in held[4]), held[4]
    for k in range(14, 30):
        assert near_ids in held[k] and far_ids in held[k], (k, held[k])


def test_a_smooth_flow_field_does_not_split(model):
    """One slanted surface: a 9 x 5 grid whose rate grows linearly across it from 0.05 to
    0.15 rad/s (flow ~ 1 / depth of a tilted plane). Neighbours 6 px apart differ by
    0.1 / 8 = 0.0125 rad/s, well inside the link tolerance (1.5 px over the window = 0.07 rad/s
    here), so it never splits: one track holds every point on every frame from the fifth."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 6.0 * rad_px
    pts = grid(9, 5, -4 * step, step)
    xs = [x for x, _ in pts]
    lo, hi = min(xs), max(xs)
    gr, (all_ids,), held = simulate(model, [(pts, lambda x: 0.05 + 0.1 * (x - lo) / (hi - lo))], 30)
    for k in range(4, 30):
        assert all_ids in held[k], (k, held[k])


@pytest.mark.parametrize("bad", [{"split_min_px": -1.0}, {"split_min_px": float("nan")},
                                 {"split_rel": -0.1}, {"split_step": 0.5}])
def test_bad_split_settings_are_config_errors(bad):
    """A negative or NaN split_min_px used to switch step 3c off silently (review); now each bad
    step 3c setting is a ConfigError naming what was expected."""
    (key, value), = bad.items()
    with pytest.raises(ConfigError, match=key):
        ObstacleGrouper(iter(range(1, 10)), **bad)


def test_found_again_counts_a_candidate_found_with_half_its_features_in_common():
    ids, n = _found_again(np.array([9, 3, 5, 7]), np.zeros(0, np.int64), 0)  # first time: 1
    assert ids.tolist() == [3, 5, 7, 9] and n == 1
    ids, n = _found_again(np.array([7, 9, 11, 13]), ids, n)  # 2 of 4 in common (half): 2
    assert ids.tolist() == [7, 9, 11, 13] and n == 2
    ids, n = _found_again(np.array([13, 20, 21]), ids, n)  # 1 of min(3, 4) = 3 in common: restart
    assert ids.tolist() == [13, 20, 21] and n == 1
    ids, n = _found_again(np.array([20]), ids, 4)  # all of the smaller one in common: 5
    assert n == 5
