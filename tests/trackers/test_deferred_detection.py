"""FeatureTracker's deferred re-detection (live mode, ``defer_detection``): a frame's detection runs off its
path and its features join at a later frame, tracked from the detection's frame; executors stand in for
the worker process so each schedule is deterministic."""

from __future__ import annotations

import itertools
from concurrent.futures import Future

import numpy as np
import pytest

from estimators.errors import InputError
from estimators.rig import Camera, forward_T_C_B
from tests.trackers.conftest import SphereScene, rot_axis
from trackers.clock import FrameClock
from trackers.detectors import make_detector
from trackers.features import _FINDERS, FeatureTracker


class NowExecutor:
    """Runs each job when it is submitted (a synchronous stand-in for the worker process)."""

    def __init__(self) -> None:
        self.jobs = 0

    def submit(self, fn, *args):
        self.jobs += fn.__name__ != "ready"  # detections (not the set-up's check)
        fut: Future = Future()
        try:
            fut.set_result(fn(*args))
        except Exception as e:  # the worker's error travels in the future, as in a thread pool
            fut.set_exception(e)
        return fut


class HeldExecutor:
    """Holds each detection until ``release()`` runs it (a detection that takes several frames)."""

    def __init__(self) -> None:
        self.held: list[tuple[Future, object, tuple]] = []

    def submit(self, fn, *args):
        fut: Future = Future()
        if fn.__name__ == "ready":  # (the set-up's check, answered at once)
            fut.set_result(fn(*args))
        else:
            self.held.append((fut, fn, args))
        return fut

    def release(self) -> None:
        for fut, fn, args in self.held:
            fut.set_result(fn(*args))
        self.held = []


def make_tracker(model, **kw) -> FeatureTracker:
    cam = Camera("cam0", model, forward_T_C_B())
    return FeatureTracker(cam, make_detector("orb", max_features=400), ids=itertools.count(1), **kw)


def _turning(model, n: int, step_deg: float = 1.0):
    scene = SphereScene(model)
    return [scene.render(rot_axis([0, 1, 0], k * np.radians(step_deg))) for k in range(n)]


def test_a_deferred_detection_joins_at_the_next_frame_as_the_synchronous_one_tracked():
    """With the detection done by the next frame, its features join there, tracked from the detection's
    frame: frame 0 publishes no feature (its detection is under way), frame 1 the same features, ids and
    float32 positions as the synchronous schedule's frame 1 (the same ORB result, the same KLT step from
    frame 0), as features first seen in frame 1: one history sample, age 1 (the grouper reads a
    feature's samples as one per frame)."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    frames = _turning(model, 6)
    sync, dfr = make_tracker(model, max_features=300), make_tracker(model, max_features=300)
    ex = NowExecutor()
    dfr.defer_detection(ex)
    out_s, out_d = [], []
    for k, img in enumerate(frames):
        out_s.append(sync.track(img, k, k / 30)[0])
        out_d.append(dfr.track(img, k, k / 30)[0])
    assert len(out_s[0]) > 100 and len(out_d[0]) == 0
    assert ex.jobs >= 1
    np.testing.assert_array_equal(out_d[1].ids, out_s[1].ids)
    np.testing.assert_array_equal(out_d[1].uv, out_s[1].uv)
    assert np.all(out_d[1].age == 1) and np.all(out_s[1].age == 2)
    assert dfr.deferred == {"joined": ex.jobs, "frames_late": ex.jobs}  # each joined one frame after its own
    i = int(out_d[1].ids[0])
    assert dfr.history(i).frame.tolist()[:1] == [1] and sync.history(i).frame.tolist()[:2] == [0, 1]


def test_a_detection_that_joins_frames_later_steps_from_its_own_frame(monkeypatch):
    """A detection of frame 2 done only after frame 4: its features are not published in frames 2-4, join
    at frame 5 (their history from there), and KLT takes them from their positions in frame 2's image
    (kept for them) into frame 5's; their bearings follow the camera's rotation from frame 2 to 5 (b_5 =
    R(3 steps)^T b_2 for a static world at infinity), within the KLT's error (a step from another frame's
    image at the frame-2 position would be off by 1 deg, 1.1 px, per frame)."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    step = np.radians(1.0)
    frames = _turning(model, 8)
    ft = make_tracker(model, max_features=300, redetect_s=2 / 30)
    ex = HeldExecutor()
    ft.defer_detection(ex)
    calls = []
    orig = ft._lk

    def spy(prev, nxt, p, start, level, flags, part):
        calls.append((prev, len(p)))
        return orig(prev, nxt, p, start, level, flags, part)

    monkeypatch.setattr(ft, "_lk", spy)
    merged = []  # (ids given, the detection's keypoints) per join
    orig_merge = ft._merge

    def merge_spy(found):
        rows = orig_merge(found)
        merged.append((ft.ids[rows].copy(), found))
        return rows

    monkeypatch.setattr(ft, "_merge", merge_spy)
    ids_at: dict[int, set[int]] = {}
    for k in range(8):
        if k in (1, 5):  # frame 0's detection joins at frame 1; frame 2's at frame 5
            ex.release()
        calls.clear()
        feats, _ = ft.track(frames[k], k, k / 30)
        ids_at[k] = set(feats.ids.tolist())
        if k == 2:
            assert len(ex.held) == 1  # frame 2's detection is under way
            crop2 = ft._refs[-1][2]
        if k == 5:
            first5 = [c for c in calls if c[0] is crop2]
            assert len(ft._refs) == 1  # frame 2's crop released once its features joined
            feats5 = feats
    new = ids_at[5] - ids_at[4]
    assert len(new) >= 10, f"{len(new)} features joined at frame 5"
    # stepped from frame 2's crop: the joined features, and only they (the others step from the KLT
    # step's references, not from the frame kept for the detection)
    assert first5 and sum(n for _, n in first5) == len(merged[-1][0]) >= len(new)
    R = rot_axis([0, 1, 0], 3 * step).T  # b_C5 = R_W_C5^T R_W_C2 b_C2 for a static world at infinity
    rad_px = model.max_angle_rad / model.image_circle()[2]
    errs = []
    ids_j, found = merged[-1]  # frame 2's detection, joined at frame 5: its kept rows in order
    assert np.all(found.lost_id == -1) and new <= set(ids_j.tolist())
    b2 = model.pixel_to_bearing(found.uv[: len(ids_j)].astype(np.float64))[0]
    first = dict(zip(ids_j.tolist(), b2, strict=True))
    for i in new:
        assert ft.history(i).frame.tolist()[:1] == [5]  # first seen at the join
        b5 = feats5.b_C[feats5.ids == i][0]
        errs.append(np.arccos(np.clip((R @ first[i]) @ b5, -1, 1)) / rad_px)
    assert np.median(errs) < 0.3, f"median {np.median(errs):.2f} px from the rotation"
    assert ft.deferred["joined"] >= 2


def test_a_detection_joins_into_the_room_left_and_drops_forgotten_reacquisitions():
    """The merge after the state moved on: new features take only the room left now (the first ones of
    the detection's order), and a keypoint that re-acquired a lost feature forgotten since is dropped."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    ft = make_tracker(model, max_features=50)
    job = ft._detect_job(0.0)
    found = ft._finder.find(job, ft._finder.part(SphereScene(model).render()))
    assert len(found.uv) == 50 and np.all(found.lost_id == -1)
    ft._append(np.array([[160.0, 120.0]] * 45, np.float32), None, np.full(45, -1, np.intp))
    rows = ft._merge(found)
    assert len(rows) == 5
    np.testing.assert_array_equal(ft.uv[rows], found.uv[:5])
    # a re-acquisition of a lost feature the tracker no longer remembers
    gone = type(found)(found.uv[:1], found.desc[:1], np.array([10**6], np.int64))
    assert len(ft._merge(gone)) == 0


def test_a_failing_deferred_detection_is_a_clear_error_at_its_join():
    """The worker's error reaches the frame that would take the detection's features: a RuntimeError
    naming the camera, the detection's frame and the cause (not a silent loss of re-detection)."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    ft = make_tracker(model)
    ft.defer_detection(NowExecutor())
    grey = SphereScene(model).render()

    def bad(*a, **k):
        raise InputError("orb: the frame is not an image")

    _FINDERS[ft._finder_key].detector.detect = bad  # (the worker's copy: an executor in this process)
    ft.track(grey, 7, 0.0)  # submitted: the frame goes on
    with pytest.raises(RuntimeError, match=r"'cam0'.*frame 7.*InputError: orb: the frame is not an image"):
        ft.track(grey, 8, 1 / 30)


def test_setting_the_synchronous_schedule_drops_a_detection_under_way():
    """defer_detection(None) (the end of a live run) drops the detection under way: the tracker keeps no
    crop for it and detects in its frames again."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    grey = SphereScene(model).render()
    ft = make_tracker(model, max_features=200)
    ex = HeldExecutor()
    ft.defer_detection(ex)
    assert len(ft.track(grey, 0, 0.0)[0]) == 0 and ft._pending is not None
    ft.defer_detection(None)
    assert ft._pending is None
    assert len(ft.track(grey, 1, 1 / 30)[0]) > 50  # the coverage trigger, in its own frame
    assert len(ft._refs) == 1


def test_a_worker_that_cannot_take_the_detector_fails_when_the_schedule_is_set():
    """The executor is given the tracker's finder (detector included) when the deferred schedule is set:
    one that cannot take it (here: it cannot pickle the detector) fails there, naming the detector and
    the way out, not at the first detection's join mid-run; the tracker stays synchronous."""
    import pickle

    from tests.trackers.conftest import equidistant

    class PicklingExecutor(NowExecutor):
        def submit(self, fn, *args):
            return super().submit(lambda: pickle.loads(pickle.dumps(fn))(*args))

    model = equidistant()
    ft = make_tracker(model)
    ft.detector.unpicklable = lambda: None  # an attribute pickle refuses
    with pytest.raises(RuntimeError, match=r"'cam0'.*cannot take.*OrbDetector.*deferred_detection false"):
        ft.defer_detection(PicklingExecutor())
    assert ft._executor is None
    assert len(ft.track(SphereScene(model).render(), 0, 0.0)[0]) > 50


@pytest.mark.parametrize("deferred", [False, True])
def test_a_deferred_reacquisition_keeps_the_lost_features_age_as_the_synchronous_one(deferred):
    """A lost feature re-acquired by a detection keeps its age (``_append``: the lost age + 1 in the
    detection's frame, one more a frame after). Joined a frame late, it has the age it would have had
    re-acquired in the join's frame (the lost age + 1), as a new feature has a new one's (1): the
    join restarted re-acquired ones at 1 too, so the grouper took them for new features (fails at
    a451afe: age 1). Static scene: the dropped features are re-detected where they were."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    grey = SphereScene(model).render()
    ft = make_tracker(model, max_features=300)
    for k in range(6):
        ft.track(grey, k, k / 30)
    if deferred:
        ft.defer_detection(NowExecutor())
    drop = np.flatnonzero(ft.has_desc)[:40]
    # the age each has when re-acquired in a detection's own frame (``_append``: its age when lost + 1)
    again = dict(zip(ft.ids[drop].tolist(), (ft.age[drop] + 1).tolist(), strict=True))
    ft._drop(drop, remember=True)
    ft._frames_since_detect = FrameClock.UNKNOWN  # a detection in frame 6
    ft.track(grey, 6, 6 / 30)
    feats, _ = ft.track(grey, 7, 7 / 30)  # the deferred one joins here
    back = [i for i in feats.ids.tolist() if i in again]
    assert len(back) >= 10, f"{len(back)} re-acquired"
    age = dict(zip(feats.ids.tolist(), feats.age.tolist(), strict=True))
    want = {i: again[i] + (0 if deferred else 1) for i in back}  # (synchronous: re-acquired in frame 6)
    assert {i: age[i] for i in back} == want


class NeverDoneExecutor:
    """A detection that never reports done: its result is made only when it is waited for."""

    def submit(self, fn, *args):
        class Lazy(Future):
            def done(self):
                return False

            def result(self, timeout=None):
                return fn(*args)

        return Lazy()


def test_a_detection_still_under_way_at_the_historys_reach_is_waited_for():
    """The frames kept for a detection under way stop at ``history`` (the reach of a feature's samples):
    the detection still not done then is waited for in that frame, ``history`` frames after its own, so
    the crops kept never pass ``history`` (without the wait they grew by one a frame)."""
    from tests.trackers.conftest import equidistant

    model = equidistant()
    grey = SphereScene(model).render()
    ft = make_tracker(model, max_features=300)
    ft.defer_detection(NeverDoneExecutor())
    kept = []
    for k in range(3 * ft.H):
        ft.track(grey, k, k / 30)
        kept.append(len(ft._refs))
    assert max(kept) == ft.H, kept
    assert ft.deferred["joined"] >= 2 and ft.deferred["frames_late"] == ft.H * ft.deferred["joined"]


class PicklingExecutor:
    """Runs each job at once across pickle, as a worker process takes it (the function and its arguments
    pickled at submission, loaded and run), and keeps each detection's arguments and result."""

    def __init__(self) -> None:
        self.done: list[tuple[tuple, object]] = []  # (the detection's arguments as sent, its result)
        self.sent_bytes: list[int] = []

    def submit(self, fn, *args):
        import pickle

        blob = pickle.dumps((fn, args))
        fn2, args2 = pickle.loads(blob)
        fut: Future = Future()
        fut.set_result(fn2(*args2))
        if fn.__name__ != "ready":
            self.done.append((args2, fut.result()))
            self.sent_bytes.append(len(blob))
        return fut


@pytest.mark.parametrize("width", [320, 640])  # ORB's box: the whole frame | the lens's box, a crop
def test_a_deferred_detection_finds_what_the_synchronous_one_finds_on_the_same_frame_and_job(width):
    """The worker's detection (the finder loaded once there, a job with only the part of the frame it
    reads) and the synchronous one (``_detect``) give the same keypoints, descriptors and re-acquired ids
    on the same frame and state: here a detection with live features and a lost pool (some re-acquired).
    What a job carries is the box, not the frame, and not the finder (its lens mask alone is a frame's
    size)."""
    from tests.trackers.conftest import equidistant

    model = equidistant(width=width)
    frames = _turning(model, 8)
    ft = make_tracker(model, max_features=300)
    for k in range(4):
        ft.track(frames[k], k, k / 30)
    ex = PicklingExecutor()
    ft.defer_detection(ex)
    ft._drop(np.flatnonzero(ft.has_desc)[:40], remember=True)
    ft._frames_since_detect = FrameClock.UNKNOWN  # a detection in frame 4
    ft.track(frames[4], 4, 4 / 30)
    ((key, job, part), found), *_ = ex.done
    assert len(job.uv) > 50 and len(job.lost_ids) >= 40
    x0, y0, x1, y1 = ft.frame_box
    assert part.shape == (y1 - y0, x1 - x0) and ((x1 - x0) < width) == (width == 640)
    assert ex.sent_bytes[0] < part.nbytes + 20 * (job.uv.nbytes + job.lost_desc.nbytes) + 4096
    want = ft._finder.find(job, ft._finder.part(frames[4]))  # the synchronous schedule's call (_detect)
    assert len(want.uv) > 20 and np.sum(want.lost_id >= 0) >= 5
    np.testing.assert_array_equal(found.uv, want.uv)
    np.testing.assert_array_equal(found.desc, want.desc)
    np.testing.assert_array_equal(found.lost_id, want.lost_id)


@pytest.mark.parametrize("width", [320, 640])  # the whole frame (a copy, not the frame itself) | a crop
def test_the_frame_a_deferred_detection_reads_is_copied_when_it_is_submitted(width):
    """The caller's frame may be a reader's buffer, refilled with a later frame before the worker reads
    it: the detection reads the frame as it was at submission. Here the caller's array is blanked after
    the frame returns and before the held detection runs: its features are those of an untouched
    frame's (fails at 61b58d6: it read the blank frame, no feature joined)."""
    from tests.trackers.conftest import equidistant

    model = equidistant(width=width)
    frames = _turning(model, 2)
    got = []
    for blank in (False, True):
        ft = make_tracker(model, max_features=300)
        ex = HeldExecutor()
        ft.defer_detection(ex)
        bgr = np.repeat(frames[0][:, :, None], 3, axis=2)  # the reader's frame (the detector's image)
        ft.track(frames[0], 0, 0.0, image=bgr)
        if blank:
            bgr[:] = 0
        ex.release()
        got.append(ft.track(frames[1], 1, 1 / 30)[0])
    assert len(got[0]) > 100
    np.testing.assert_array_equal(got[1].ids, got[0].ids)
    np.testing.assert_array_equal(got[1].uv, got[0].uv)
