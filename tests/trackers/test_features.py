"""FeatureTracker: KLT on raw fisheye frames, forward-backward rejection, rim, re-acquisition, memory."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.errors import ConfigError, InputError
from estimators.rig import Camera, forward_T_C_B
from tests.trackers.conftest import Patch, SphereScene, blocky_texture, equidistant, rot_axis
from trackers.detectors import make_detector
from trackers.features import FeatureTracker, lens_mask


def make_tracker(model, **kw) -> FeatureTracker:
    cam = Camera("cam0", model, forward_T_C_B())
    return FeatureTracker(
        cam, make_detector("orb", max_features=kw.pop("det_max", 400)), ids=itertools.count(1), **kw
    )


def test_rotation_tracked_everywhere_including_beyond_90_degrees(model):
    """Camera turning about its y axis in a static world at infinity: every surviving feature's
    bearing must follow b_C(k) = R_W_Ck^T R_W_C0 b_C(0) (the rotation, not the code, gives the truth),
    also for features more than 90 degrees off the optical axis."""
    scene = SphereScene(model)
    ft = make_tracker(model, max_features=300)
    step = np.radians(0.6)
    first: dict[int, np.ndarray] = {}
    for k in range(16):
        R = rot_axis([0, 1, 0], k * step)
        feats, _ = ft.track(scene.render(R), k, k / 30)
        if k == 0:
            first = {int(i): b for i, b in zip(feats.ids, feats.b_C, strict=True)}
            continue
    alive = [i for i in feats.ids if int(i) in first]
    assert len(alive) > 50
    R_rel = rot_axis([0, 1, 0], 15 * step).T  # b_C15 = R_W_C15^T R_W_C0 b_C0, R_W_C0 = I
    rad_px = model.max_angle_rad / model.image_circle()[2]
    errs, off = [], []
    for i, b in zip(feats.ids, feats.b_C, strict=True):
        if int(i) in first:
            exp = R_rel @ first[int(i)]
            errs.append(np.arccos(np.clip(exp @ b, -1, 1)) / rad_px)  # pixels
            off.append(np.degrees(np.arccos(np.clip(b[2], -1, 1))))
    errs, off = np.array(errs), np.array(off)
    assert np.median(errs) < 0.3
    assert np.percentile(errs, 95) < 1.5
    rim = off > 90
    assert rim.sum() >= 5, f"only {rim.sum()} features beyond 90 degrees survived 15 frames"
    # at theta > 90 deg one pixel along the circle spans theta / sin(theta) ~ 1.6x the radial angle
    assert np.median(errs[rim]) < 1.0


def test_forward_backward_check_rejects_changing_texture(model):
    """A patch whose texture is replaced every frame cannot be tracked consistently: its features
    must be dropped (forward-backward, LK status or residual), the static world's kept.
    (Re-acquisition is off here: this is about KLT's own checks.)"""
    scene = SphereScene(model)
    ft = make_tracker(model, max_features=300, redetect_s=1 / 30, reacquire_s=0)
    d = np.array([0.0, 0.0, 1.0])
    fb_total = 0
    rng = np.random.default_rng(3)
    for k in range(6):
        p = Patch(d, np.radians(30))
        # a new texture with its block edges in new places (not just new block values)
        p.texture = np.roll(
            blocky_texture(256, int(rng.integers(7, 12)), 100 + k), int(rng.integers(0, 40)), axis=1
        )
        img = scene.render(None, [p])
        feats, _ = ft.track(img, k, k / 30)
        fb_total += int(ft.last_stats.get("fb_rejected", 0))
    # features that survived at least 2 frames inside the flickering patch: none
    inside = (feats.b_C @ d) > np.cos(np.radians(27))
    assert not np.any(inside & (feats.age >= 2))
    outside_old = (~inside) & (feats.age >= 5)
    assert outside_old.sum() > 50
    assert fb_total > 0


def test_reacquisition_after_short_occlusion(model):
    """Features hidden for two frames (flat grey disc) come back with their old ids (ORB
    descriptors near the predicted position)."""
    scene = SphereScene(model)
    ft = make_tracker(model, max_features=300, redetect_s=1 / 30, reacquire_s=5 / 30)
    d = np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0])
    flat = Patch(d, np.radians(25))
    flat.texture = np.full((256, 256), 128, np.uint8)
    before: set[int] = set()
    for k in range(8):
        occl = k in (4, 5)
        feats, _ = ft.track(scene.render(None, [flat] if occl else []), k, k / 30)
        if k == 3:
            inside = (feats.b_C @ d) > np.cos(np.radians(20))
            before = {int(i) for i in feats.ids[inside]}
    assert len(before) >= 5
    back = before & {int(i) for i in feats.ids}
    assert len(back) >= 0.5 * len(before), f"re-acquired {len(back)} of {len(before)}"


def test_history_ring_buffer_and_memory_stay_bounded(model):
    """Constant churn (a flickering patch) for 120 frames: slots are recycled, the lost pool is
    bounded and each history holds at most ``history`` samples, oldest first."""
    scene = SphereScene(model)
    ft = make_tracker(model, max_features=150, history=8, redetect_s=1 / 30)
    cap = ft._h_uv.shape[0]
    imgs = [
        scene.render(rot_axis([0, 1, 0], np.radians(0.2) * k), [Patch([0, 0, 1], np.radians(20), seed=k)])
        for k in range(10)
    ]
    for k in range(80):  # the world swings back and forth; the patch flickers
        j = k % 20
        feats, _ = ft.track(imgs[j if j < 10 else 19 - j], k, k / 30)
    assert ft._h_uv.shape[0] == cap
    assert len(ft._free) + ft.n_live + len(ft.lost_ids) == cap  # no slot leaks
    assert len(ft.lost_ids) <= ft.max_features
    old = feats.ids[feats.age >= 20][0]
    h = ft.history(int(old))
    assert len(h.t_s) == 8 and np.all(np.diff(h.t_s) > 0) and h.frame[-1] == 79
    np.testing.assert_allclose(np.linalg.norm(h.b_C, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(h.b_B, h.b_C @ ft.R_C_B, atol=1e-12)


@pytest.mark.heavy
def test_memory_flat_over_10000_frames(model):
    """10,000 frames with churn: traced Python memory does not grow after the warm-up."""
    import tracemalloc

    scene = SphereScene(model)
    ft = make_tracker(model, max_features=150, redetect_s=2 / 30)
    imgs = [
        scene.render(rot_axis([0, 1, 0], np.radians(0.3) * k), [Patch([0, 0, 1], np.radians(20), seed=k)])
        for k in range(50)
    ]
    tracemalloc.start()
    for k in range(10000):
        ft.track(imgs[k % 50], k, k / 30)
        if k == 1000:
            base = tracemalloc.get_traced_memory()[0]
    now = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    assert now < base * 1.2 + 1e6


def test_lens_mask_matches_circle_and_rejects_misfit():
    m = equidistant(320, 240)
    mask = lens_mask(m, margin_px=0)
    cx, cy, r = m.image_circle()
    assert abs((mask > 0).sum() - np.pi * r * r) < 2 * np.pi * r * 1.5  # area within a rim pixel
    bad = Equidistant(fx=60, fy=60, cx=500, cy=120, width=320, height=240, max_angle_rad=1.7)
    with pytest.raises(InputError, match="does not fit"):
        lens_mask(bad)


@pytest.mark.parametrize(
    "kw",
    [
        {"max_features": 0},
        {"history": 1},
        {"redetect_s": -0.1},
        {"redetect_s": float("nan")},
        {"redetect_s": True},
        {"reacquire_s": -1},
        {"reacquire_s": float("inf")},
        {"fb_max_px": 0.0},
        {"fb_levels": -1},
    ],
)
def test_bad_tracker_options(model, kw):
    with pytest.raises(ConfigError):
        make_tracker(model, **kw)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("max_features", 1.5),
        ("max_features", True),
        ("history", 8.0),
        ("win_px", 11.5),
        ("levels", "2"),
        ("fb_levels", False),
        ("min_per_cell", 1.5),
        ("reacquire_max_hamming", np.float64(40.0)),
        ("grid", (16.5, 9)),
        ("grid", (16, True)),
        ("grid", (16,)),
    ],
)
def test_integer_options_refuse_non_integers(model, name, value):
    """An integer option given a float or a bool is refused (int() would truncate 1.5 to 1 and take
    True as 1), and the message names the option and says an integer was expected."""
    with pytest.raises(ConfigError, match=name.split("[")[0]) as e:
        make_tracker(model, **{name: value})
    assert "integer" in str(e.value)


def test_integer_options_take_numpy_integers(model):
    ft = make_tracker(model, max_features=np.int64(120), history=np.int32(8), grid=[8, 6])
    assert (ft.max_features, ft.H, ft.grid) == (120, 8, (8, 6))
    assert type(ft.max_features) is int and type(ft.H) is int


def test_texture_is_the_window_mean_absolute_deviation(model):
    """A 0/200 checkerboard deviates 100 grey levels from its mean everywhere (worked by hand); a
    flat patch 0: the texture term of the residual bound (issue 4)."""
    ft = make_tracker(model)
    img = np.zeros((100, 100), np.uint8)
    img[:50] = ((np.add.outer(np.arange(50), np.arange(100)) % 2) * 200).astype(np.uint8)
    tex = ft._texture(img, np.array([[50.0, 20.0], [50.0, 80.0]], np.float32))
    # an 11x11 window of a checkerboard: 61 of one value, 60 of the other -> MAD = 2*61*60/121^2*200
    assert tex[0] == pytest.approx(2 * 61 * 60 / 121**2 * 200, rel=1e-5)
    assert tex[1] == 0.0


def test_velocity_is_per_second_so_dropped_frames_keep_tracks(model):
    """Camera turning 3 px per frame at the centre (the equidistant model: f * angle, by hand),
    single-level KLT (no pyramid to absorb a bad prediction): after 8 frames the central features'
    velocity is 3 px * 30 frames/s = 90 px/s, and when frames 8-10 are dropped (9 px of motion in
    one step, predicted from v * dt) most features survive; a per-frame velocity would predict 3 px
    and lose most of them (measured: 44% kept)."""
    scene = SphereScene(model)
    f_px = model.image_circle()[2] / model.max_angle_rad  # px per radian
    step = 3.0 / f_px
    ft = make_tracker(model, max_features=300, levels=0, redetect_s=100 / 30)
    for k in [*range(8), 11]:  # frames 8, 9, 10 dropped
        feats, _ = ft.track(scene.render(rot_axis([0, 1, 0], k * step)), k, k / 30)
        if k == 7:
            before = set(feats.ids.tolist())
            central = np.linalg.norm(ft.uv - [model.cx, model.cy], axis=1) < 30
            v = np.median(ft.vel[central], axis=0)
            assert abs(v[0]) == pytest.approx(90.0, rel=0.1)
            assert abs(v[1]) < 5.0
    kept = len(before & set(feats.ids.tolist())) / len(before)
    assert kept > 0.8, f"kept {kept:.2f} of the features over the dropped frames"


def test_detection_on_the_lens_box_lands_on_whole_frame_orb_corners():
    """ORB runs on the lens circle's bounding box (origin > 0 here), not the frame: the new features
    must be where cv2.ORB finds corners on the whole frame (frame pixels, not box pixels), inside
    the lens mask, and they carry the descriptors cv2.ORB computes for those keypoints."""
    import cv2

    model = equidistant(640, 360)
    ft = make_tracker(model, max_features=200)
    assert ft._det_box[0] > 0 and ft._det_box[2] < 640  # a box, not the frame
    grey = SphereScene(model).render()
    feats, _ = ft.track(grey, 0, 0.0)
    assert len(feats) > 50
    orb = cv2.ORB_create(
        nfeatures=20000, scaleFactor=1.3, nlevels=3, edgeThreshold=15, patchSize=15, fastThreshold=10
    )
    kps, des = orb.detectAndCompute(grey, None)
    ref = cv2.KeyPoint_convert(kps).reshape(-1, 2)
    d2 = ((feats.uv[:, None, :] - ref[None, :, :]) ** 2).sum(-1)
    d = np.sqrt(d2.min(axis=1))
    # level-0 corners coincide exactly; coarser levels (the box's pyramid grid is not the frame's at
    # scale 1.3) within a few pixels; a box-offset mix-up would be ~100 px off
    assert np.median(d) < 0.5, np.percentile(d, [10, 50, 90])
    assert np.percentile(d, 95) < 4.0
    m = lens_mask(model, 4.0)
    assert np.all(m[np.rint(feats.uv[:, 1]).astype(int), np.rint(feats.uv[:, 0]).astype(int)] > 0)
    # descriptors of the exact (level-0) matches: most bits equal to cv2's on the whole frame
    exact = np.flatnonzero(d < 0.01)
    j = np.argmin(d2[exact], axis=1)
    bits = np.unpackbits(np.bitwise_xor(ft.desc[exact], des[j]), axis=1).sum(1)
    assert np.median(bits) <= 8, np.percentile(bits, [50, 90])


def test_only_keepable_keypoints_are_described():
    """With 150 live features and a budget of 160, one detection adds 10 (the budget) and asks ORB
    for descriptors of those 10 only (nothing was lost, so no re-acquisition candidates), not of
    its whole bucketed list (up to 400)."""
    from trackers.detectors.orb import OrbDetector

    model = equidistant(320, 240)
    det = OrbDetector(max_features=400)
    described: list[int] = []
    orig = det._orb.compute

    class Spy:
        def __getattr__(self, name):
            return getattr(orig.__self__, name)

        def compute(self, image, kps):
            described.append(len(kps))
            return orig(image, kps)

    det._orb = Spy()
    cam = Camera("cam0", model, forward_T_C_B())
    ft = FeatureTracker(cam, det, ids=itertools.count(1), max_features=160, redetect_s=1 / 30)
    grey = SphereScene(model).render()
    for k in range(3):  # (the periodic detection needs the rate: two frame intervals)
        ft.track(grey, k, k / 30)
    n0 = ft.n_live
    assert n0 == 160 and described == [160]
    ft._drop(np.arange(150, 160), remember=False)  # 150 left: 10 free
    ft.track(grey, 3, 3 / 30)
    assert described[-1] == 10 and ft.n_live == 160


def _detection_times(ft, grey: np.ndarray, fps: float, t_end: float) -> list[float]:
    """The times (s) at which ``ft``, fed copies of ``grey`` at ``fps`` until ``t_end``, ran a detection."""
    times: list[float] = []
    orig = ft._detect

    def counting(image, frame, t_s):
        times.append(t_s)
        return orig(image, frame, t_s)

    ft._detect = counting
    for k in range(int(round(t_end * fps))):
        ft.track(grey, k, k / fps)
    return times


def test_a_full_tracker_detects_half_as_often(model):
    """A static scene at 30 fps: with room for new features the tracker detects every redetect_s
    (default 4/30 s: every 4th frame, the count it was fitted as); once full (max_features live) a
    detection could only re-acquire lost features, so it runs every 8/30 s (counted: frames 0, 8, 16
    of 20 for a full tracker; 0, 4, ..., 16 with room)."""
    grey = SphereScene(model).render()

    def detect_frames(max_features: int) -> list[int]:
        times = _detection_times(make_tracker(model, max_features=max_features), grey, 30.0, 20 / 30)
        return [round(t * 30) for t in times]

    assert detect_frames(40) == [0, 8, 16]  # full after the first detection
    assert detect_frames(5000) == [0, 4, 8, 12, 16]  # never full


def test_redetect_s_0_detects_every_frame_from_the_first(model):
    """redetect_s 0 is every frame (0 frames at any rate): also on the second frame, before the
    clock has seen the two intervals it needs for a rate (it skipped that frame: [0, 2, 3, 4]); a
    full tracker too (twice 0 s)."""
    grey = SphereScene(model).render()
    for max_features in (40, 5000):
        ft = make_tracker(model, max_features=max_features, redetect_s=0)
        times = _detection_times(ft, grey, 30.0, 5 / 30)
        assert [round(t * 30) for t in times] == [0, 1, 2, 3, 4], max_features


@pytest.mark.parametrize("max_features", [40, 5000], ids=["full", "room"])
def test_the_redetection_cadence_is_in_seconds(model, max_features):
    """The same static scene fed at 30 and at 100 Hz for 1 s: the tracker re-detects at the same
    times within a frame. redetect_s 4/30 s (8/30 s once full) is 4 (8) frames at 30 fps and, at
    the 100-Hz rate seen, 13 (27) frames: every 0.13 (0.27) s, where a count of 4 (8) frames
    detected every 0.04 (0.08) s. Each interval between detections is within one 100-Hz frame of
    the 30-fps one, and as many detections are made."""
    grey = SphereScene(model).render()
    at30 = _detection_times(make_tracker(model, max_features=max_features), grey, 30.0, 1.0)
    at100 = _detection_times(make_tracker(model, max_features=max_features), grey, 100.0, 1.0)
    period = (8 if max_features == 40 else 4) / 30
    assert np.diff(at30) == pytest.approx(np.full(len(at30) - 1, period))
    assert len(at100) == len(at30)
    assert np.all(np.abs(np.diff(at100) - period) <= 0.01 + 1e-9), np.diff(at100)


@pytest.mark.parametrize(
    ("old", "new"), [("redetect_every", "redetect_s"), ("reacquire_frames", "reacquire_s")]
)
def test_the_old_frame_count_keys_are_errors_naming_their_replacement(model, rig, old, new):
    """redetect_every and reacquire_frames (frames) are now redetect_s and reacquire_s (seconds):
    given to the tracker, or through the front end's features options, each is a ConfigError naming
    the new key; a misspelt key is still the usual TypeError."""
    from trackers.frontend import FrontEnd

    msg = f"'{old}' \\(frames\\) was replaced by '{new}' \\(seconds"
    with pytest.raises(ConfigError, match=f"^FeatureTracker: {msg}"):
        make_tracker(model, **{old: 4})
    with pytest.raises(ConfigError, match=f"^FrontEnd: '{old}' in features \\(frames\\) was replaced by "
                                          f"'{new}'"):
        FrontEnd(rig, "orb", features={old: 4})
    with pytest.raises(TypeError, match="redetect_ss"):
        make_tracker(model, redetect_ss=0.1)


def _remembered_for(model, fps: float) -> float:
    """How long (s) after their loss 10 lost features are still remembered for re-acquisition: a
    static scene at ``fps``, no periodic detection (redetect_s 100 s) and a full budget (no coverage
    trigger), so nothing re-acquires them."""
    ft = make_tracker(model, max_features=160, redetect_s=100.0)
    grey = SphereScene(model).render()
    for k in range(3):  # (the rate is known after two intervals)
        ft.track(grey, k, k / fps)
    ft._drop(np.arange(10), remember=True)
    assert len(ft.lost_ids) == 10
    last = 2 / fps
    for k in range(3, int(fps)):
        ft.track(grey, k, k / fps)
        if not len(ft.lost_ids):
            break
        last = k / fps
    return last - 2 / fps


def test_lost_features_are_remembered_for_the_same_seconds_at_30_and_100_hz(model):
    """reacquire_s 8/30 s: 8 frames at 30 fps (as reacquire_frames 8 was), 27 at 100 Hz (0.27 s;
    in frames, 8 at 100 Hz, 0.08 s: shorter than the 0.13-s re-detection cadence there)."""
    assert _remembered_for(model, 30.0) == pytest.approx(8 / 30)
    assert _remembered_for(model, 100.0) == pytest.approx(0.27)


def test_a_full_tracker_describes_only_reacquisition_candidates():
    """A full tracker (no room for new features) keeps no new keypoint, so a detection asks ORB for
    descriptors of the re-acquisition candidates only: keypoints in the 3x3 cells (of the 15 px
    re-acquisition radius) around a lost feature's predicted position, i.e. within 2 sqrt(2) 15 px
    of one (the 10 leftmost features were lost, standing still: predicted where they were). It
    described as many again, anywhere, before. The lost features come back with their ids."""
    from trackers.detectors.orb import OrbDetector

    model = equidistant(320, 240)
    det = OrbDetector(max_features=400)
    described: list[np.ndarray] = []
    orig = det._orb.compute

    class Spy:
        def __getattr__(self, name):
            return getattr(orig.__self__, name)

        def compute(self, image, kps):
            described.append(np.array([k.pt for k in kps], float).reshape(-1, 2))
            return orig(image, kps)

    det._orb = Spy()
    cam = Camera("cam0", model, forward_T_C_B())
    ft = FeatureTracker(cam, det, ids=itertools.count(1), max_features=160, redetect_s=1 / 30)
    grey = SphereScene(model).render()
    ft.track(grey, 0, 0.0)
    left = np.argsort(ft.uv[:, 0])[:10]
    lost_uv, lost_ids = ft.uv[left].copy(), set(ft.ids[left].tolist())
    ft._drop(left, remember=True)
    ft.max_features = ft.n_live  # full: 150 of 150
    n_calls = len(described)
    for k in (1, 2):  # a full tracker detects every 2 redetect_s (1/30 s): frame 2
        feats, _ = ft.track(grey, k, k / 30)
    assert len(described) == n_calls + 1
    x0, y0 = ft.frame_box[:2]
    uv = described[-1] + [x0, y0]  # ORB's crop px -> frame px
    d = np.sqrt(((uv[:, None, :] - lost_uv[None, :, :]) ** 2).sum(-1)).min(axis=1)
    assert len(uv) >= 5 and np.all(d <= 2 * np.sqrt(2) * 15.0), np.sort(d)[-5:]
    assert len(lost_ids & set(feats.ids.tolist())) >= 5


@pytest.mark.parametrize("opts", [{}, {"fb_levels": 0, "fb_retry": True}], ids=["default", "fb0_retry"])
def test_sudden_turn_survives_the_backward_check(model, opts):
    """A camera still for 6 frames that suddenly turns 8 px (at the centre; equidistant: f * angle,
    by hand) in one frame: the motion prediction (0 px) is 8 px off. The forward KLT's pyramid
    absorbs that, but a backward pass on the full-resolution level alone (fb_levels=0) converges only
    within about half its 11 px window of its start, so without a coarser backward pass (the default
    fb_levels=1, or fb_retry after a level-0 pass) the good features fail the forward-backward
    check (measured: 0.56 kept with fb_levels=0 alone, 0.81 with fb_retry, 0.82 with fb_levels=1;
    the rest are outer features lost either way). Kept at the rotated positions (bearing error
    < 1.5 px)."""
    scene = SphereScene(model)
    f_px = model.image_circle()[2] / model.max_angle_rad  # px per radian
    R1 = rot_axis([0, 1, 0], 8.0 / f_px)
    ft = make_tracker(model, max_features=300, redetect_s=100 / 30, **opts)
    for k in range(6):
        feats, _ = ft.track(scene.render(), k, k / 30)
    before = {int(i): b for i, b in zip(feats.ids, feats.b_C, strict=True)}
    feats, _ = ft.track(scene.render(R1), 6, 6 / 30)
    kept = [int(i) for i in feats.ids if int(i) in before]
    assert len(kept) / len(before) > 0.75, f"kept {len(kept) / len(before):.2f} of the features"
    b_now = dict(zip(feats.ids.tolist(), feats.b_C, strict=True))
    rad_px = model.max_angle_rad / model.image_circle()[2]
    errs = [np.arccos(np.clip((R1.T @ before[i]) @ b_now[i], -1, 1)) / rad_px for i in kept]
    assert np.percentile(errs, 95) < 1.5


def test_feature_budget_is_500_by_default_and_follows_the_lens_size_when_asked():
    """The default budget is 500 whatever the lens; max_features=None (opt-in): one feature per
    px_per_feature px^2 of the lens circle (radius r minus the 4 px margin, so pi (r - 4)^2 px^2
    by hand), clipped to [250, 500]; a given count is kept."""
    det = {"det_max": 100}
    assert make_tracker(equidistant(640, 480), **det).max_features == 500
    assert make_tracker(equidistant(720, 720, fill=0.4), **det).max_features == 500
    lens = {"max_features": None, **det}
    # a 720x720 frame, lens radius 0.47 * 720 = 338.4 px: pi 334.4^2 / 700 = 501.8 -> 500 (cap)
    assert make_tracker(equidistant(720, 720), **lens).max_features == 500
    # radius 0.4 * 720 = 288 px: pi 284^2 / 700 = 362.0
    assert abs(make_tracker(equidistant(720, 720, fill=0.4), **lens).max_features - 362) <= 2
    # a 640x480 frame, radius 225.6 px: pi 221.6^2 / 700 = 220.4 -> 250 (floor)
    assert make_tracker(equidistant(640, 480), **lens).max_features == 250
    # twice the area per feature: radius 288 px -> 181 -> 250
    assert make_tracker(equidistant(720, 720, fill=0.4), px_per_feature=1400.0, **lens).max_features == 250
    assert make_tracker(equidistant(640, 480), max_features=123, **det).max_features == 123
    with pytest.raises(ConfigError):
        make_tracker(equidistant(640, 480), px_per_feature=0.0, **det)


def test_describe_on_the_lens_crop_equals_cv2_on_the_whole_frame():
    """describe() computes ORB descriptors on the lens's crop; cv2's ORB on the whole frame, for
    keypoints at the same pixels, gives the same bytes and keeps the same rows."""
    import cv2

    model = equidistant(640, 360)  # lens radius 169 px: the crop is ~370 of 640 px wide
    ft = make_tracker(model, max_features=300)
    grey = SphereScene(model).render()
    ft.track(grey, 0, 0.0)
    x0, y0, x1, y1 = ft.roi
    assert (x1 - x0) < 0.7 * 640 and ft.n_live > 100
    des, rows = ft.describe(grey)
    kps = [cv2.KeyPoint(float(u), float(v), 15.0, -1, 0, 0, i) for i, (u, v) in enumerate(ft.uv)]
    kps, ref = cv2.ORB_create(edgeThreshold=15, patchSize=15).compute(grey, kps)
    np.testing.assert_array_equal(rows, [k.class_id for k in kps])
    np.testing.assert_array_equal(des, ref)


def test_append_without_enough_free_slots_keeps_the_first_rows(model):
    """Four new keypoints with two free ring-buffer slots: the first two rows are added, with the
    next two ids and the slots in pop order; the other two rows use up their ids (as one row at a
    time did) and are not added."""
    ft = make_tracker(model, max_features=50)
    ft._free = [7, 3]  # pop order: 3, then 7
    ft._h_n[[3, 7]] = 5
    start = next(ft._ids)
    uv = np.array([[300.0, 200.0], [310.0, 200.0], [320.0, 200.0], [330.0, 200.0]], np.float32)
    added = ft._append(uv, None, np.full(4, -1, np.intp))
    assert added == 2
    assert ft.ids.tolist() == [start + 1, start + 2]
    assert ft.slot.tolist() == [3, 7]
    assert ft._h_n[[3, 7]].tolist() == [0, 0]
    np.testing.assert_array_equal(ft.uv, uv[:2])
    assert next(ft._ids) == start + 5 and ft._free == []


def test_median_is_np_median_bit_for_bit():
    """_median (the residual test's frame median, without np.median's call overhead) must give
    exactly float(np.median(x)) (numpy is the independent reference): odd and even lengths, ties,
    float32 and float64, infinities, a NaN (np.median's answer is then NaN)."""
    from trackers.features import _median

    rng = np.random.default_rng(7)
    for t in range(3000):
        n = int(rng.integers(1, 400))
        x = (rng.random(n) * rng.choice([1.0, 1e3, 1e30])).astype([np.float32, np.float64][t % 2])
        if t % 3 == 0:
            x = np.round(x * 4) / 4  # ties between the two middle values
        if t % 11 == 0:
            x[rng.integers(0, n)] = np.inf
        if t % 13 == 0:
            x[rng.integers(0, n)] = np.nan
        want = float(np.median(x))
        got = _median(x)
        assert got == want or (np.isnan(got) and np.isnan(want)), (n, x.dtype, got, want)
    assert _median(np.array([1.0, 2.0], np.float32)) == 1.5
    assert _median(np.array([5.0, 1.0, 3.0])) == 3.0


def _part_of(img: np.ndarray, crops) -> tuple[int, np.ndarray]:
    """(the index in ``crops`` of the array a KLT call's image is, or is a part of (a view:
    FeatureTracker._lk_part), the part's origin (2,) float32 px (x, y) in it)."""
    (i,) = [i for i, c in enumerate(crops) if np.shares_memory(img, c)]
    c = crops[i]
    off = img.__array_interface__["data"][0] - c.__array_interface__["data"][0]
    return i, np.array([off % c.strides[0], off // c.strides[0]], np.float32)


def _lk_reference_frames(monkeypatch, model, fps: float, n: int, **kw):
    """Track n frames of a slow turn at ``fps``; for each frame, the frame indices of the images
    the forward LK calls started from (found by content: every rendered frame differs) and how many
    features each call carried."""
    import cv2

    scene = SphereScene(model)
    ft = make_tracker(model, **{"max_features": 300, "redetect_s": 1e6, **kw})
    frames: list[np.ndarray] = []
    calls: list[tuple[np.ndarray, int]] = []
    # (OpenCV's own function, not an earlier call's spy: that one would look in its own tracker)
    real = getattr(cv2.calcOpticalFlowPyrLK, "__wrapped__", cv2.calcOpticalFlowPyrLK)

    def spy(prev, nxt, p0, p1, **a):
        if not a["flags"] & cv2.OPTFLOW_LK_GET_MIN_EIGENVALS:  # the forward pass
            i, _ = _part_of(prev, [r[2] for r in ft._refs])
            calls.append((ft._refs[i][2], len(p0)))
        return real(prev, nxt, p0, p1, **a)

    spy.__wrapped__ = real
    monkeypatch.setattr(cv2, "calcOpticalFlowPyrLK", spy)
    out = []
    for k in range(n):
        grey = scene.render(rot_axis([0, 1, 0], np.radians(3.0) * k / fps))
        frames.append(ft._crop(grey))
        calls.clear()
        ft.track(grey, k, k / fps)
        refs = [[j for j, f in enumerate(frames) if np.array_equal(f, prev)] for prev, _ in calls]
        out.append([(r[-1], m) for r, m in zip(refs, [m for _, m in calls], strict=True)])
    return out, ft


def test_klt_steps_from_the_frame_a_thirtieth_of_a_second_back_at_100_fps(model, monkeypatch):
    """KLT's step is klt_step_s (1/30 s), not a frame: at 100 fps (3 frames per step once the rate
    is known, from the third frame on) a feature is tracked from its position 3 frames back, in
    that frame's image, so its position chain takes 33 steps a second, as at 30 fps, not 100 (each
    step adds a small random error: docs ARCHITECTURE "KLT steps in seconds"). Features younger than
    3 frames step from their first frame; at 30 fps every feature steps from the previous frame."""
    out, ft = _lk_reference_frames(monkeypatch, model, 100.0, 9)
    assert out[0] == [] and [r for r, _ in out[1]] == [0] and [r for r, _ in out[2]] == [1]
    # frame 3: the rate is known (two intervals), the references frames 1 and 2 (the features,
    # all detected at frame 0, have samples there); from frame 4 on, 3 frames back
    assert [r for r, _ in out[3]] == [1]
    for k in range(4, 9):
        assert [r for r, _ in out[k]] == [k - 3], (k, out[k])
        assert out[k][0][1] > 100
    out30, _ = _lk_reference_frames(monkeypatch, model, 30.0, 6)
    for k in range(1, 6):
        assert [r for r, _ in out30[k]] == [k - 1], (k, out30[k])


def test_klt_step_young_features_step_from_their_first_frame(monkeypatch):
    """At 100 fps with detection every frame: a feature detected 1 or 2 frames ago steps from the
    frame it was detected in (one LK call per reference frame in use), older ones from 3 frames
    back; none is lost to the longer step on a slow turn."""
    out, ft = _lk_reference_frames(
        monkeypatch, equidistant(640, 480), 100.0, 12, redetect_s=0.0, max_features=2000, det_max=2000
    )
    young = 0
    for k in range(6, 12):  # (after the start-up detections: none periodic before two intervals)
        refs = dict(out[k])
        assert set(refs) <= {k - 3, k - 2, k - 1} and refs[k - 3] > 0.9 * sum(refs.values()), (k, out[k])
        young += sum(m for r, m in refs.items() if r > k - 3)
    assert young > 10
    assert ft.last_stats["klt_ok"] >= 0.95 * ft.last_stats["klt_in"]


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf"), True, "1/30"])
def test_klt_step_s_must_be_a_duration(model, bad):
    with pytest.raises(ConfigError, match="klt_step_s"):
        make_tracker(model, klt_step_s=bad)


def test_klt_step_velocity_is_the_steps_own_displacement_at_100_fps(model, monkeypatch):
    """At 100 fps (a step of 3 frames) frame k's position comes from k - 3's and k - 1's from k - 4's:
    three interleaved chains, each with its own accumulated step error. The velocity (the KLT
    prediction's and the lost features' predicted positions') must be a chain's own displacement
    over its step, not the difference of two chains over one frame. A static scene (the same image
    every frame: true velocity 0) with each forward LK result shifted by an error that depends on
    the reference frame (frame mod 3: chains drifting 0, +0.2, -0.2 px a step): the velocity stays
    within the step error over the step time (0.2 px / 0.03 s = 6.7 px/s); from consecutive
    positions it grew with the chains' separation (~0.4 px more every 3 frames, / 0.01 s)."""
    import cv2

    scene = SphereScene(model)
    grey = scene.render(np.eye(3))
    ft = make_tracker(model, max_features=300, redetect_s=1e6)
    shift = {0: 0.0, 1: 0.2, 2: -0.2}
    real = cv2.calcOpticalFlowPyrLK

    def biased(prev, nxt, p0, p1, **a):
        out = real(prev, nxt, p0, p1, **a)
        if a["flags"] & cv2.OPTFLOW_LK_GET_MIN_EIGENVALS:  # the backward pass: as is
            return out
        frame = ft._refs[_part_of(prev, [r[-1] for r in ft._refs])[0]][0]
        q = out[0].copy()
        q[..., 0] += np.float32(shift[frame % 3])
        return (q, *out[1:])

    monkeypatch.setattr(cv2, "calcOpticalFlowPyrLK", biased)
    for k in range(40):
        ft.track(grey, k, k / 100.0)
    assert len(ft._refs) == 3
    assert ft.n_live > 100
    speed = np.linalg.norm(ft.vel, axis=1)
    assert np.max(speed) < 7.0, np.percentile(speed, [50, 90, 100])


def test_klt_step_reference_position_is_the_reference_frames_with_a_repeated_frame_index(monkeypatch):
    """At 100 fps (a step of 3 frames) each feature starts LK in a reference image from its own
    position in that frame. The frame index a caller passes may repeat (a live camera's counter
    restarting; here always 0): a re-acquired feature's sample from before its loss must not be taken
    for the reference frame's position. Every forward LK call's start points are checked against the
    features' positions after the frame whose crop the call starts in (the truth is the tracker's own
    earlier output, frame by frame; the pairing is what is tested). Jittered times and dropped frames
    make features lost and re-acquired within the step."""
    import cv2

    model = equidistant(640, 480)
    scene = SphereScene(model)
    ft = make_tracker(model, max_features=300)
    rng = np.random.default_rng(0)
    after: list[tuple[np.ndarray, dict[int, np.ndarray]]] = []  # (crop, {id: uv}) after each call
    starts: list[tuple[int, np.ndarray]] = []
    real = cv2.calcOpticalFlowPyrLK

    def spy(prev, nxt, p0, p1, **a):
        if not a["flags"] & cv2.OPTFLOW_LK_GET_MIN_EIGENVALS:
            c, o = _part_of(prev, [crop for crop, _ in after])
            starts.append((c, p0.reshape(-1, 2) + o))
        return real(prev, nxt, p0, p1, **a)

    monkeypatch.setattr(cv2, "calcOpticalFlowPyrLK", spy)
    bad = total = 0
    for k in range(40):
        if k in (10, 11, 20):
            continue
        t = (k + rng.uniform(-0.3, 0.3)) / 100.0
        starts.clear()
        ft.track(scene.render(rot_axis([0, 1, 0], np.radians(20.0) * t)), 0, t)
        for c, p in starts:
            known = np.array(list(after[c][1].values())) - ft._off
            total += len(p)
            bad += sum(not np.any(np.all(known == q, axis=1)) for q in p)
        after.append((ft._refs[-1][-1], {int(i): uv.copy() for i, uv in zip(ft.ids, ft.uv, strict=True)}))
    assert len(ft._refs) == 3
    assert total > 5000
    assert bad == 0


def _shifted_texture_run(monkeypatch, whole: bool):
    """A 640x480 lens over a textured plane translated by a known (0.7, -0.4) px a frame at 100 fps
    (klt_step_s 1/30 s: a 3-frame step once the rate is known), features detected at frame 0 and
    densified around one point at frame 6 (young: they step from their own frame at frames 7 and
    8, from 3 frames back after). Returns (the tracker; {id: (frame, uv)} of every young
    feature's position after frames 7 and 8; the crop shapes and point counts of every forward
    LK call at frames 7 and 8). ``whole``: every LK call on the whole crops (the calls before the
    young features' went on parts)."""
    import cv2

    from tests.trackers.conftest import blocky_texture

    model = equidistant(640, 480)
    tex = blocky_texture(1024, 160, seed=3)
    v = np.array([0.7, -0.4])

    def frame(k: int) -> np.ndarray:
        M = np.array([[1.0, 0.0, -150.0 + v[0] * k], [0.0, 1.0, -200.0 + v[1] * k]])
        return cv2.warpAffine(tex, M, (640, 480), flags=cv2.INTER_LINEAR)

    if whole:
        real_lk = FeatureTracker._lk
        monkeypatch.setattr(FeatureTracker, "_lk", lambda self, *a: real_lk(self, *a[:-1], False))
    calls: list[tuple[tuple[int, int], int]] = []
    real = cv2.calcOpticalFlowPyrLK

    def spy(prev, nxt, p0, p1, **a):
        if not a["flags"] & cv2.OPTFLOW_LK_GET_MIN_EIGENVALS:
            calls.append((prev.shape, len(p0)))
        return real(prev, nxt, p0, p1, **a)

    monkeypatch.setattr(cv2, "calcOpticalFlowPyrLK", spy)
    ft = make_tracker(model, max_features=300, redetect_s=1e6)
    young: dict[int, list[tuple[int, np.ndarray]]] = {}
    seen: list[tuple[tuple[int, int], int]] = []
    for k in range(10):
        calls.clear()
        ft.track(frame(k), k, k / 100.0)
        if k in (7, 8):
            seen += calls
            for i, uv in zip(ft.ids, ft.uv, strict=True):
                if int(i) in young:
                    young[int(i)].append((k, uv.astype(float)))
        if k == 6:
            n0 = ft.n_live
            ft.densify(frame(k), np.array([[330.0, 250.0]]), np.array([40.0]), k, k / 100.0, per_roi=12)
            young = {int(i): [(6, uv.astype(float))] for i, uv in zip(ft.ids[n0:], ft.uv[n0:], strict=True)}
    return ft, young, seen


def test_klt_step_young_features_are_tracked_on_parts_of_the_crops(monkeypatch):
    """Features younger than the KLT step (at 100 fps: detected or densified 1 or 2 frames ago) are
    few and clustered; their LK calls run on the parts of the two crops their search reads
    (``_lk_part``), each call's pyramids built on that part, not on the whole lens crop (the
    bench's 1280x720 60-Hz clip: the young call pair 1.06 -> ~0.3 ms). The older features' calls
    still take the whole crops. Before, every call took the whole crops."""
    ft, young, calls = _shifted_texture_run(monkeypatch, whole=False)
    crop = ft._refs[-1][2].shape
    assert len(young) >= 6
    few = [(s, m) for s, m in calls if m <= len(young)]
    many = [(s, m) for s, m in calls if m > len(young)]
    assert len(few) == 2 and len(many) == 2  # frames 7 and 8: one young and one old group each
    assert all(s == crop for s, _ in many)
    for s, _ in few:
        assert s[0] * s[1] < crop[0] * crop[1] / 3, (s, crop)  # (243x235 of 480x498)


def test_klt_step_young_features_on_parts_track_as_on_the_whole_crops(monkeypatch):
    """The young features' positions on the parts equal those of calls on the whole crops to 0.01
    px (the same pixels; LK works in the part's float32 coordinates, so the last bits differ), with
    the same ids and verdicts, and follow the plane's known shift (0.7, -0.4) px a frame to 0.1 px."""
    _, part, _ = _shifted_texture_run(monkeypatch, whole=False)
    monkeypatch.undo()
    _, whole, _ = _shifted_texture_run(monkeypatch, whole=True)
    assert len(part) >= 6 and part.keys() == whole.keys()
    v = np.array([0.7, -0.4])
    for i, track in part.items():
        assert [k for k, _ in track] == [k for k, _ in whole[i]] == [6, 7, 8]
        for (k, uv), (_, uw) in zip(track[1:], whole[i][1:], strict=True):
            assert np.abs(uv - uw).max() < 0.01, (i, k, uv, uw)
            np.testing.assert_allclose(uv, track[0][1] + v * (k - 6), atol=0.1)


def test_lk_part_with_every_point_beyond_an_edge_answers_as_the_whole_images():
    """Points and starts all beyond one edge of the images leave no part to search (the boxes'
    union is empty); OpenCV's LK never returns on an empty image, so such a call takes the whole
    images and reports what LK reports there. Run in a child process: before, it hung."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = """
import cv2, numpy as np
from trackers.features import _lk_part, _lk_whole
cv2.setNumThreads(1)
img = np.random.default_rng(0).integers(0, 255, (100, 120), np.uint8)
crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)
p = np.array([[[-500.0, -400.0]], [[-450.0, -420.0]]], np.float32)
q, st, err = _lk_part(img, img, p, p.copy(), 11, 2, crit)
qw, stw, errw = _lk_whole(img, img, p, p.copy(), 11, 2, crit)
assert st.tolist() == stw.tolist() == [0, 0], (st, stw)
assert np.array_equal(q, qw)
print("ok")
"""
    root = str(Path(__file__).resolve().parents[2])  # (this checkout's trackers, not an installed one)
    env = {**os.environ, "PYTHONPATH": root}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env,
                       cwd=root)
    assert r.returncode == 0 and r.stdout.strip() == "ok", r.stderr[-2000:]
