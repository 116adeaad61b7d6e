"""Step 3d of the grouper: a track whose members lie at two clearly different depths splits by their
parallax rates; one surface whose depth changes smoothly, two depths closer than ``depth_ratio``
and parallax below the noise gate do not. Synthetic 3-D points seen from a camera translating
along x at v (m/s): a point at depth d straight ahead moves across the image at v / d rad/s (the
closed form the expected tracks follow from), and nothing here comes from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from tests.trackers.conftest import rot_axis
from tests.trackers.test_grouping import PointFeatures, unit
from trackers.grouping import ObstacleGrouper

FPS = 30.0
# a wide flow tolerance (0.3 + 0.2 |f| rad/s) so that surfaces at different depths join one track
# frame to frame (what step 3d is there to undo); step 3c is off to test step 3d alone
# (and the numbers below are for a 5-frame window, the flow's own, unless a test says otherwise)
# (step 3d is opt-in: depth_ratio 1.5 turns it on)
# (step 3e is off too: the walls drift apart, and a gap that opens between them is its to cut)
OPTS = {"flow_abs_rad_s": 0.3, "split_min_px": 0.0, "depth_frames": 5, "depth_ratio": 1.5, "gap_factor": 0.0}


def wall(nx: int, ny: int, x0: float, step: float, depth_m) -> list[np.ndarray]:
    """3-D points (m, camera frame at t = 0) of an nx x ny grid whose bearings are ``step`` rad
    apart starting at tangent offset x0 (rad); depth_m: a number, or a function of the column
    index giving each column's depth (a slanted surface)."""
    pts = []
    for i in range(nx):
        d = depth_m(i) if callable(depth_m) else depth_m
        for j in range(ny):
            pts.append(d * np.array([x0 + i * step, (j - (ny - 1) / 2) * step, 1.0]))
    return pts


class Features(PointFeatures):
    """The test's stand-in FeatureTracker, with the history counts the grouper reads when it is
    given the camera's rotations (one sample per frame since a feature was born)."""

    @property
    def slot(self) -> np.ndarray:
        return np.arange(len(self.ids))

    @property
    def _h_n(self) -> np.ndarray:
        return self.age


def simulate(model, parts, v_mps: float, frames: int = 30, yaw_rad_s: float = 0.0, rotations=True, **opts):
    """parts: lists of 3-D points; the camera moves along +x at v_mps and turns about its y axis at
    yaw_rad_s (R_C_W(t) = rot_y(yaw t)^T). The grouper gets R_C_Cprev[k] = R_C_W(t) R_C_W(t - k /
    FPS)^T for k = 1..31 (``rotations``; else None). Returns the grouper, the feature ids per part
    and per frame the member-id sets of the tracks seen."""
    gr = ObstacleGrouper(iter(range(1, 10_000)), **{**OPTS, **opts})
    ft = Features(model)
    ids, pts, part_ids = [], [], []
    for p in parts:
        part_ids.append(set(range(len(ids) + 1, len(ids) + 1 + len(p))))
        ids += list(range(len(ids) + 1, len(ids) + 1 + len(p)))
        pts += p
    pts = np.array(pts)
    held = []

    def R_C_W(t_s: float) -> np.ndarray:
        return rot_axis([0, 1, 0], yaw_rad_s * t_s).T

    for k in range(frames):
        t_s = k / FPS
        c = np.array([v_mps * t_s, 0.0, 0.0])
        ft.set(ids, np.array([R_C_W(t_s) @ unit(p - c) for p in pts]), t_s)
        R = {j: R_C_W(t_s) @ R_C_W(t_s - j / FPS).T for j in range(1, 32)} if rotations else None
        seen, _ = gr.update(ft, t_s, R)
        held.append([set(t.members.tolist()) for t in seen])
    return gr, part_ids, held


def two_walls(model, near_rate: float, far_rate: float, v_mps: float = 1.0):
    """A 4 x 4 wall at depth v / near_rate beside (on the -x side, touching: 3 px apart) a 4 x 4
    wall at depth v / far_rate: their bearings drift at near_rate and far_rate rad/s, times
    cos^2 of the angle off the axis (at most 0.19 rad here: a factor 0.965 at the edge)."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 3.0 * rad_px
    return [wall(4, 4, -4 * step, step, v_mps / near_rate), wall(4, 4, 0.0, step, v_mps / far_rate)]


def test_two_walls_at_depths_1_8_apart_split(model):
    """Near wall at 1.25 m, far wall at 2.22 m (inverse depths 0.8 and 0.45 /m, ratio 1.78),
    camera at 1 m/s: flows 0.8 and 0.45 rad/s agree frame to frame (0.35 < 0.3 + 0.2 x 0.8), so
    one track holds both at first. Between the walls' sorted rates the gap is at least
    0.8 x 0.965 - 0.45 = 0.32 rad/s, a ratio of 1.7 >= 1.5; over the 5-frame flow (1/6 s) the
    noise model gives sigma_s = sqrt(2) 0.25 px x 0.0155 rad/px / (1/6 s) = 0.033 rad/s per
    member, 0.047 for a pair: 6.9 sigma > 4 (a 4-frame flow at frame 4: 5.5 sigma), so it is
    found from frame 4 and split after depth_persist = 2 frames. From frame 8 on each wall is
    exactly one track."""
    gr, (near, far), held = simulate(model, two_walls(model, 0.8, 0.45), 1.0)
    assert any((m & near) and (m & far) for m in held[3]), held[3]
    for k in range(8, 30):
        assert near in held[k] and far in held[k], (k, held[k])
    assert gr.depth_splits >= 1 and gr.splits == 0


def test_without_step_3d_the_two_walls_stay_one_track(model):
    """The same scene with step 3d off (depth_ratio = 1): some track mixes the walls to the end
    (what the test above checks is step 3d's doing)."""
    gr, (near, far), held = simulate(model, two_walls(model, 0.8, 0.45), 1.0, depth_ratio=1.0)
    assert any((m & near) and (m & far) for m in held[-1]), held[-1]
    assert gr.depth_splits == 0


def test_a_turning_camera_splits_them_too_and_needs_its_rotation(model):
    """The same two walls while the camera also turns at 0.5 rad/s about y (its rotation adds
    0.5 rad/s to every flow, more than the depth gap): with the rotation given the split is
    the same as without turning; without it (R_C_Cprev None) flows are not proportional to
    inverse depth and step 3d does nothing."""
    gr, (near, far), held = simulate(model, two_walls(model, 0.8, 0.45), 1.0, yaw_rad_s=0.5)
    assert gr.depth_splits >= 1
    for k in range(8, 30):
        assert near in held[k] and far in held[k], (k, held[k])
    gr, _, _ = simulate(model, two_walls(model, 0.8, 0.45), 1.0, yaw_rad_s=0.5, rotations=False)
    assert gr.depth_splits == 0


def test_depths_closer_than_the_ratio_do_not_split(model):
    """Inverse depths 2.0 and 1.54 /m (ratio 1.3 < 1.5), 1 m/s: the gap between the walls' rates
    (about 2.0 x 0.965 - 1.54 = 0.39 rad/s, less as the near wall turns off the axis) is above
    the noise gate (it splits with depth_ratio 1.01: checked below), but the depths are too close
    to call two obstacles: no split."""
    gr, (near, far), held = simulate(model, two_walls(model, 2.0, 1.54), 1.0)
    assert gr.depth_splits == 0
    assert any(m >= near | far for m in held[-1]), held[-1]
    gr, _, _ = simulate(model, two_walls(model, 2.0, 1.54), 1.0, depth_ratio=1.01)
    assert gr.depth_splits >= 1


def test_parallax_below_the_noise_gate_waits_for_a_longer_window(model):
    """Inverse depths 0.16 and 0.08 /m (ratio 2) at 1 m/s: over a 5-frame window the gap (about
    0.16 x 0.965 - 0.08 = 0.074 rad/s) is 1.6 sigma of a pair (0.047 rad/s): depth is not
    observable there, no split (with a gate of 0.5 sigma instead of 4 it splits: checked). Over
    the default 20-frame window (2/3 s) sigma_s = sqrt(2) 0.25 x 0.0155 / (2/3) = 0.0082 rad/s,
    0.0116 for a pair, so the gap is 6.4 sigma: judged once the features are 10 frames old (half
    the window; 3.2 sigma then, 4 sigma from about 13 frames), split after 2 frames in a row:
    each wall is one track from frame 20 on."""
    gr, (near, far), held = simulate(model, two_walls(model, 0.16, 0.08), 1.0)
    assert gr.depth_splits == 0
    assert any(m >= near | far for m in held[-1]), held[-1]
    gr, _, _ = simulate(model, two_walls(model, 0.16, 0.08), 1.0, depth_gate=0.5)
    assert gr.depth_splits >= 1
    gr, (near, far), held = simulate(model, two_walls(model, 0.16, 0.08), 1.0, depth_frames=20)
    assert gr.depth_splits >= 1
    for k in range(20, 30):
        assert near in held[k] and far in held[k], (k, held[k])


def test_a_slanted_surface_does_not_split(model):
    """One 9 x 4 surface whose column depths go from 1.25 m to 2.22 m (the two walls' depths, but
    in 9 steps: neighbouring columns' inverse depths differ by 1.78^(1/8) = 1.075): no gap in the
    sorted parallax rates reaches the ratio, so it stays one track."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 3.0 * rad_px
    pts = wall(9, 4, -4 * step, step, lambda i: 1.25 * 1.78 ** (i / 8))
    gr, (ids,), held = simulate(model, [pts], 1.0)
    assert gr.depth_splits == 0
    for k in range(6, 30):
        assert ids in held[k], (k, held[k])


def test_a_sparsely_sampled_depth_gradient_does_not_split(model):
    """Five columns of 4 points whose inverse depths fall by 1.6x from column to column (0.8,
    0.5, 0.31, 0.2, 0.12 /m): every gap between neighbouring columns passes the ratio (1.6 >=
    1.5), but wherever the track would be cut one side spans at least as large a ratio itself
    (1.6^k, k >= 1): a gradient, not a step, so it stays one track (without that rule, the
    ratio and the noise gate alone split it: checked against the previous version)."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 3.0 * rad_px
    pts = wall(5, 4, -2 * step, step, lambda i: 1.25 * 1.6**i)
    gr, (ids,), held = simulate(model, [pts], 1.0)
    assert gr.depth_splits == 0
    for k in range(6, 30):
        assert ids in held[k], (k, held[k])


def test_step_3d_is_off_by_default():
    """Opt-in: the default depth_ratio is 1 (step 3d off)."""
    assert ObstacleGrouper(iter(range(1, 10))).depth_ratio == 1.0


@pytest.mark.parametrize(
    "bad",
    [
        {"depth_ratio": 0.9},
        {"depth_ratio": float("nan")},
        {"depth_ratio": float("inf")},
        {"depth_ratio": "x"},
        {"depth_sigma_px": 0.0},
        {"depth_sigma_px": -1.0},
        {"depth_gate": float("nan")},
        {"depth_gate": 0},
        {"depth_persist": 0},
        {"depth_persist": 1.5},
        {"depth_persist": True},
        {"depth_frames": 0},
        {"depth_frames": 2.5},
    ],
)
def test_bad_depth_settings_are_config_errors(bad):
    """Each bad step 3d setting is a ConfigError naming it (none silently turns the step off)."""
    with pytest.raises(ConfigError, match=next(iter(bad))):
        ObstacleGrouper(iter(range(1, 10)), **bad)
