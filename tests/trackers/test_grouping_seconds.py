"""The grouper's durations are seconds, applied as frame counts at the frame rate seen (the median
interval of the frame times it is given, ``FrameClock``): the same scene fed at 30 and at 100 Hz
is confirmed, lost and split after the same time, within a frame or two of the slower rate.
Synthetic bearings (the test chooses every feature's direction), so the expected times follow from
the construction: the defaults' counts at 30 fps (min_age 3, confirm 5, max_missed 10, split
window 10, split_persist 3 frames) over the frame interval."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from tests.trackers.conftest import rot_axis
from tests.trackers.test_grouping import PointFeatures, unit
from tests.trackers.test_grouping_split import FLOW_ABS, grid
from trackers.clock import FrameClock
from trackers.grouping import BoxTracker, ObstacleGrouper


def test_the_clock_counts_a_duration_in_frames_at_the_rate_seen():
    c = FrameClock()
    assert c.frames(0.1) == FrameClock.UNKNOWN  # no interval yet: no count is reached
    assert c.frames(0.0, 0) == 0 and c.frames(0.0) == 1  # 0 s is lo frames at any rate: no rate needed
    assert c.tick(0.0) == 0.0  # tick gives the time since the frame before (none: 0)
    assert c.frames(0.1) == FrameClock.UNKNOWN
    for k in range(1, 20):  # 30 fps, times as a timestamps file gives them (microseconds)
        c.tick(round(k / 30, 6))
    assert [c.frames(d) for d in (0.1, 5 / 30, 1 / 3, 0.4, 0.5, 1 / 15)] == [3, 5, 10, 12, 15, 2]
    assert c.tick(round(21 / 30, 6)) == pytest.approx(2 / 30, abs=1e-6)  # a dropped frame: one long
    # interval, the median keeps the rate
    assert c.frames(1 / 3) == 10
    c = FrameClock()
    for k in range(20):
        c.tick(k / 100)
    assert [c.frames(d) for d in (0.1, 5 / 30, 1 / 3, 0.4, 0.5, 1 / 15)] == [10, 17, 33, 40, 50, 7]
    assert c.frames(0.0, 0) == 0 and c.frames(0.0) == 1  # at least lo
    assert c.tick(0.19) == 0.0  # a repeated time is no interval (and no time since the last)
    assert c.period_s == pytest.approx(0.01)


def _blob(model, fps: float, t_end: float = 1.0, t_total: float = 1.6):
    """A 4 x 4 grid of points 6 px apart drifting at 0.1 rad/s about y, alone in the image, shown
    until t_end and gone after: per track id, (time first seen, time first confirmed, time lost)."""
    gr = ObstacleGrouper(iter(range(1, 1000)))
    ft = PointFeatures(model)
    rad_px = model.max_angle_rad / model.image_circle()[2]
    offs = grid(4, 4, -2 * 6.0 * rad_px, 6.0 * rad_px)
    dirs = [unit([x, y, 1.0]) for x, y in offs]
    ids = list(range(1, len(dirs) + 1))
    times: dict[int, list[float | None]] = {}
    for k in range(int(round(t_total * fps))):
        t_s = k / fps
        if t_s < t_end:
            R = rot_axis([0, 1, 0], 0.1 * t_s)
            ft.set(ids, np.array([R @ d for d in dirs]), t_s)
        else:
            ft.set([], np.zeros((0, 3)), t_s)
        seen, lost = gr.update(ft, t_s)
        for t in seen:
            rec = times.setdefault(t.id, [t_s, None, None])
            if t.status == "confirmed" and rec[1] is None:
                rec[1] = t_s
        for t in lost:
            times.setdefault(t.id, [None, None, None])[2] = t_s
    return gr, times


def test_a_track_is_confirmed_and_lost_after_the_same_seconds_at_30_and_100_hz(model):
    """At 30 fps the features are old enough on frame 2 (0.067 s), the track confirmed on its
    5th frame (0.2 s) and lost 11 frames after the last sighting (0.967 + 0.367 s); at 100 fps on
    frames 9, 25 and 33 + 1 after 0.99 s: the same times within 1/30 s and a half (with counts in
    frames, 100 fps confirmed it at 0.06 s and lost it at 1.10 s)."""
    out = {}
    for fps in (30.0, 100.0):
        gr, times = _blob(model, fps)
        assert len(times) == 1, times  # one track, born once
        ((born, conf, lost),) = times.values()
        assert None not in (born, conf, lost)
        out[fps] = (born, conf, lost)
    assert out[30.0] == pytest.approx((2 / 30, 6 / 30, 40 / 30))
    assert out[100.0] == pytest.approx((0.09, 0.25, 1.33))
    for a, b in zip(out[30.0], out[100.0], strict=True):
        assert abs(a - b) < 1.5 / 30


def _split_scene(model, fps: float, seconds: float, history: int = 64):
    """test_grouping_split's obstacle drifting off a still background (0.1 rad/s against 0),
    at ``fps``; per frame the member-id sets of the tracks seen."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    step = 6.0 * rad_px
    parts = [(grid(9, 9, -8 * step, step), 0.0), (grid(3, 3, 1 * step, step), 0.1)]
    gr = ObstacleGrouper(iter(range(1, 10_000)), flow_abs_rad_s=FLOW_ABS)
    ft = PointFeatures(model)
    ft.H = history
    ids, dirs, rates, part_ids = [], [], [], []
    for offs, rate in parts:
        part_ids.append(set(range(len(ids) + 1, len(ids) + 1 + len(offs))))
        for x, y in offs:
            ids.append(len(ids) + 1)
            dirs.append(unit([x, y, 1.0]))
            rates.append(rate)
    held = []
    for k in range(int(round(seconds * fps))):
        t_s = k / fps
        b = [rot_axis([0, 1, 0], w * t_s) @ d for d, w in zip(dirs, rates, strict=True)]
        ft.set(ids, np.array(b), t_s)
        seen, _ = gr.update(ft, t_s)
        held.append([set(t.members.tolist()) for t in seen])
    return gr, part_ids, held


def test_the_split_by_motion_takes_the_same_seconds_at_100_hz(model):
    """Step 3c's window is 1/3 s at every rate: at 100 fps it is 33 frames and the obstacle
    drifts 2.2 px over it, as over 10 frames at 30 fps, so it splits off by about the same time
    (30 fps: held apart from frame 14, 0.47 s). With a 10-frame window at 100 fps (0.1 s: 0.7 px,
    under split_min_px) it never split."""
    gr, (bg_ids, ob_ids), held = _split_scene(model, 100.0, 1.0)
    assert gr.split_frames == 33 and gr.split_persist == 10
    for k in range(50, 100):
        assert ob_ids in held[k], (k, held[k])
        assert bg_ids in held[k], (k, held[k])


def test_windows_into_the_history_are_capped_at_its_length(model):
    """The windows reach at most history - 1 frames back (a ring of 32 samples holds 1/3 s only
    up to 93 fps): a shorter window, never a wrapped one."""
    gr, _, held = _split_scene(model, 100.0, 0.2, history=32)
    assert gr.split_frames == 31 and gr.flow_frames == 17
    gr, _, held = _split_scene(model, 100.0, 0.2, history=8)
    assert gr.split_frames == 7 and gr.flow_frames == 7


def test_flows_at_100_hz_are_derotated_beyond_the_front_end_s_rotations(model):
    """A camera only turning (yaw 0.5 rad/s) over a still 4 x 4 grid at 100 fps, given the
    rotations 7 frames back as the front end gives them: the 1/6-s flow (17 frames) is derotated by
    the chained frame-to-frame rotations, so every flow is ~0 and one track holds the grid. (With
    the identity for the samples 8-17 frames back, each flow kept most of the turn's 0.5 rad/s
    while younger features' did not.)"""
    fps = 100.0
    rad_px = model.max_angle_rad / model.image_circle()[2]
    pts = [unit([x, y, 1.0]) for x, y in grid(4, 4, -1.5 * 6 * rad_px, 6 * rad_px)]
    gr = ObstacleGrouper(iter(range(1, 1000)))

    class F(PointFeatures):
        @property
        def slot(self):
            return np.arange(len(self.ids))

        @property
        def _h_n(self):
            return self.age

    ft = F(model)
    ids = list(range(1, 17))

    def R_C_W(t_s: float) -> np.ndarray:
        return rot_axis([0, 1, 0], 0.5 * t_s).T

    for k in range(60):
        t_s = k / fps
        ft.set(ids, np.array([R_C_W(t_s) @ p for p in pts]), t_s)
        R = {j: R_C_W(t_s) @ R_C_W(t_s - j / fps).T for j in range(1, 8)} if k else None
        seen, _ = gr.update(ft, t_s, R)
    flow, valid = gr._flows(ft, t_s, {j: R_C_W(t_s) @ R_C_W(t_s - j / fps).T for j in range(1, 8)})
    assert gr.flow_frames == 17 and valid.all()
    assert np.abs(flow).max() < 1e-9
    assert len(seen) == 1 and set(seen[0].members.tolist()) == set(ids)


@pytest.mark.parametrize("old", sorted(ObstacleGrouper.RENAMED))
def test_an_old_frame_count_key_is_an_error_naming_its_replacement(old):
    new = ObstacleGrouper.RENAMED[old][0]
    with pytest.raises(ConfigError, match=f"'{old}' \\(frames\\) was replaced by '{new}' \\(seconds"):
        ObstacleGrouper(iter(range(10)), **{old: 3})


def test_the_front_end_names_the_replacement_and_bad_durations(rig):
    from trackers.frontend import FrontEnd

    # one prefix, the front end's (was "FrontEnd: ObstacleGrouper: 'min_age' ...")
    with pytest.raises(ConfigError, match=r"^FrontEnd: 'min_age' in grouping \(frames\) was replaced by "
                                          r"'min_age_s'"):
        FrontEnd(rig, "orb", grouping={"min_age": 3})
    with pytest.raises(ConfigError, match="unknown key 'min_agee' in grouping; did you mean 'min_age_s'"):
        FrontEnd(rig, "orb", grouping={"min_agee": 3})  # a misspelling: the accepted names listed
    for bad in (-0.1, float("nan"), float("inf"), "0.1", True):
        with pytest.raises(ConfigError, match="confirm_s"):
            ObstacleGrouper(iter(range(10)), confirm_s=bad)


def _box_times(fps: float, t_end: float = 0.5, t_total: float = 1.0):
    """One drone box drifting 60 px/s, seen until t_end: (time first confirmed, time lost)."""
    from estimators.rig import mono_forward_rig
    from tests.trackers.conftest import equidistant
    from trackers.detectors.base import Detections

    cam = mono_forward_rig(equidistant()).cameras[0]
    bt = BoxTracker(iter(range(1, 100)))
    conf = lost = None
    for k in range(int(round(t_total * fps))):
        t_s = k / fps
        u0 = 160.0 + 60.0 * t_s
        box = np.array([[u0 - 4, 116.0, u0 + 4, 124.0]])
        det = Detections(boxes=box, labels=("drone",), attributes=({},))
        seen, gone = bt.update(cam, det if t_s < t_end else Detections(), t_s=t_s)
        if conf is None and any(t.status == "confirmed" for t in seen):
            conf = t_s
        if gone:
            lost = t_s
    return conf, lost


def test_a_box_track_is_confirmed_and_lost_after_the_same_seconds_at_30_and_100_hz():
    """confirm_s 0.1 and max_missed_s 1/3: at 30 fps confirmed on its 3rd frame (0.067 s), lost
    11 frames after its last (0.467 + 0.367 s); at 100 fps on its 10th (0.09 s) and 34 frames after
    0.49 s (with counts in frames: 0.02 s and 0.60 s)."""
    assert _box_times(30.0) == pytest.approx((2 / 30, 25 / 30))
    assert _box_times(100.0) == pytest.approx((0.09, 0.83))


@pytest.mark.parametrize("old", sorted(BoxTracker.RENAMED))
def test_an_old_box_frame_count_key_is_an_error_naming_its_replacement(old):
    new = BoxTracker.RENAMED[old][0]
    with pytest.raises(ConfigError, match=f"BoxTracker: '{old}' \\(frames\\) was replaced by '{new}'"):
        BoxTracker(iter(range(10)), **{old: 3})


def test_a_duration_beyond_any_run_is_no_crash():
    """A finite but huge duration (accepted: a finite number >= 0) is a count no track reaches, not
    an OverflowError (1e308 s over a 0.01 s frame is inf frames) once the rate is known."""
    c = FrameClock()
    for k in range(3):
        c.tick(k / 100)
    assert c.frames(1e308) == FrameClock.UNKNOWN and c.frames(1e300) == FrameClock.UNKNOWN
    assert c.frames(0.1) == 10
    gr = ObstacleGrouper(iter(range(10)), max_missed_s=1e308, split_window_s=1e308)
    for k in range(3):
        gr.coast(k / 100)
    assert gr.max_missed == FrameClock.UNKNOWN and gr.split_frames == gr._history_cap
    bt = BoxTracker(iter(range(10)), max_missed_s=1e308, link_s=1e308)
    for k in range(3):
        bt.coast(k / 100)
    assert bt.max_missed == FrameClock.UNKNOWN == bt.link_frames


def test_a_slow_first_interval_decides_nothing_early():
    """A live camera's first interval is often its start-up's (here 0.5 s, then 30 fps). One interval
    is no rate yet, and of two the shorter is taken (the lower median: a long first interval read as
    the rate made every count 1 for two frames: a box confirmed on its 2nd frame and lost after 2
    unseen frames); a too short one only delays decisions."""
    c = FrameClock()
    c.tick(0.0)
    c.tick(0.5)
    assert c.frames(0.1) == FrameClock.UNKNOWN  # one interval
    c.tick(0.5 + 1 / 30)
    assert c.frames(0.1) == 3 and c.frames(1 / 3, 0) == 10
    for k in range(2, 6):  # then the median as before
        c.tick(0.5 + k / 30)
    assert c.frames(0.1) == 3

    from estimators.rig import mono_forward_rig
    from tests.trackers.conftest import equidistant
    from trackers.detectors.base import Detections

    cam = mono_forward_rig(equidistant()).cameras[0]
    bt = BoxTracker(iter(range(1, 100)))
    times = [0.0] + [0.5 + k / 30 for k in range(20)]
    box = Detections(boxes=np.array([[156.0, 116.0, 164.0, 124.0]]), labels=("drone",), attributes=({},))
    conf = lost = None
    for i, t_s in enumerate(times):
        seen, gone = bt.update(cam, box if i < 4 else Detections(), t_s=t_s)
        if conf is None and any(t.status == "confirmed" for t in seen):
            conf = i
        if gone and lost is None:
            lost = i
    assert conf == 2  # its 3rd frame, as at 30 fps throughout
    assert lost == 3 + 11  # 11 frames after its last (max_missed_s 1/3: 10 frames at 30 fps)
    bt = BoxTracker(iter(range(1, 100)))
    lost = [i for i, t_s in enumerate(times) if bt.update(cam, box if i == 0 else Detections(), t_s=t_s)[1]]
    assert lost == [11]  # seen on the first frame only: lost 11 frames on (2 when 0.5 s was the rate)
