"""FrontEnd: bad input (table-driven), grey and BGR frames, timings, options."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.errors import ConfigError, InputError
from estimators.records import ObstacleObservation
from estimators.rig import mono_forward_rig
from estimators.se3 import Pose
from tests.trackers.conftest import SphereScene
from trackers.frontend import STAGES, FrontEnd

H, W = 240, 320


def good_grey(model) -> np.ndarray:
    return SphereScene(model).render()


BAD = [
    # (case, images builder, expected exception or None for "empty result, no crash")
    ("empty array", lambda g: {"cam0": np.zeros((0, 0), np.uint8)}, InputError),
    ("tiny frame", lambda g: {"cam0": np.zeros((8, 8), np.uint8)}, InputError),
    ("wrong size", lambda g: {"cam0": np.zeros((H, W + 2), np.uint8)}, InputError),
    ("transposed", lambda g: {"cam0": np.ascontiguousarray(g.T)}, InputError),
    ("four channels", lambda g: {"cam0": np.zeros((H, W, 4), np.uint8)}, InputError),
    ("two channels", lambda g: {"cam0": np.zeros((H, W, 2), np.uint8)}, InputError),
    ("float image", lambda g: {"cam0": g.astype(np.float32)}, InputError),
    ("not an array", lambda g: {"cam0": [[0, 1], [2, 3]]}, InputError),
    ("unknown camera", lambda g: {"cam9": g}, InputError),
    ("not a mapping", lambda g: [g], InputError),
    ("black", lambda g: {"cam0": np.zeros((H, W), np.uint8)}, None),
    ("saturated", lambda g: {"cam0": np.full((H, W), 255, np.uint8)}, None),
    ("saturated BGR", lambda g: {"cam0": np.full((H, W, 3), 255, np.uint8)}, None),
    ("flat grey", lambda g: {"cam0": np.full((H, W), 90, np.uint8)}, None),
    ("camera missing (dropped)", lambda g: {}, None),
    ("one-channel 3-D", lambda g: {"cam0": g[:, :, None]}, None),
]


@pytest.mark.parametrize("with_pose", [False, True], ids=["no pose", "pose"])
@pytest.mark.parametrize("case,build,exc", BAD, ids=[b[0] for b in BAD])
def test_bad_input(model, rig, case, build, exc, with_pose):
    """Each bad frame either raises the expected error with a message naming the problem, or gives
    an empty/non-crashing result; after it the front end keeps working on good frames. With a body
    pose given (as run/live do), tracks coast through the bad frame with the camera's rotation."""
    fe = FrontEnd(rig)
    g = good_grey(model)
    pose = {"T_W_B": Pose.identity()} if with_pose else {}
    for k in range(3):
        fe.process({"cam0": g}, k, k / 30, **pose)
    if exc is not None:
        with pytest.raises(exc) as ei:
            fe.process(build(g), 3, 0.1, **pose)
        assert "cam" in str(ei.value) or "mapping" in str(ei.value)
    else:
        out = fe.process(build(g), 3, 0.1, **pose)
        assert all(isinstance(o, ObstacleObservation) for o in out)
        if case in ("black", "saturated", "saturated BGR", "flat grey", "camera missing (dropped)"):
            assert [o for o in out if o.status != "lost"] == []
    out = fe.process({"cam0": g}, 4, 4 / 30, **pose)  # recovers
    assert isinstance(out, list)


REFUSED = [b[:2] for b in BAD if b[2] is not None]


@pytest.mark.parametrize("case,build", REFUSED, ids=[b[0] for b in REFUSED])
def test_a_refused_frame_is_named_by_its_index_and_time(model, rig, case, build):
    """A video's bad frame is found again by the index and t_s the message gives, named as the fusion
    names a frame it refuses ("frame 17 (t_s=0.567000 s): ..."): one form for every refusal."""
    fe = FrontEnd(rig)
    with pytest.raises(InputError, match=r"^frame 17 \(t_s=0\.567000 s\): \S"):
        fe.process(build(good_grey(model)), 17, 0.567)


def test_the_front_end_and_the_fusion_name_a_refused_frame_alike(model, rig):
    """Unknown camera, not a mapping, a bad image: the message starts as the fusion's ego-motion
    refusal does, "frame N (t_s=... s): "; a t_s that is no number is shown as given."""
    from estimators.errors import frame_at

    fe = FrontEnd(rig)
    assert frame_at(6, 0.2) == "frame 6 (t_s=0.200000 s)" and frame_at(6, "x") == "frame 6 (t_s='x')"
    with pytest.raises(InputError) as e:
        fe.process({"cam9": good_grey(model)}, 6, 0.2)
    assert str(e.value).startswith("frame 6 (t_s=0.200000 s): FrontEnd.process: unknown cameras ['cam9']")
    with pytest.raises(InputError) as e:
        fe.process([good_grey(model)], 6, "soon")
    assert str(e.value).startswith("frame 6 (t_s='soon'): FrontEnd.process: expected a mapping")
    with pytest.raises(InputError) as e:
        fe.process({"cam0": np.zeros((8, 8), np.uint8)}, 6, 0.2)
    assert str(e.value).startswith("frame 6 (t_s=0.200000 s): camera 'cam0': ")


def test_wrong_size_message_names_both_sizes(rig):
    fe = FrontEnd(rig)
    with pytest.raises(InputError, match=r"640x480.*320x240"):
        fe.process({"cam0": np.zeros((480, 640), np.uint8)}, 0, 0.0)


def test_lens_circle_that_does_not_fit_is_an_error():
    bad = Equidistant(fx=60, fy=60, cx=-40.0, cy=120, width=W, height=H, max_angle_rad=1.7)
    with pytest.raises(InputError, match="lens circle"):
        FrontEnd(mono_forward_rig(bad))


def test_grey_and_bgr_give_the_same_tracks(model, rig):
    scene = SphereScene(model)
    frames = [scene.render(np.eye(3)) for _ in range(6)]
    a, b = FrontEnd(rig), FrontEnd(rig)
    for k, g in enumerate(frames):
        oa = a.process({"cam0": g}, k, k / 30)
        ob = b.process({"cam0": np.repeat(g[:, :, None], 3, axis=2)}, k, k / 30)
    assert [o.track_id for o in oa] == [o.track_id for o in ob]
    assert set(a.timings) == set(STAGES)
    assert all(v >= 0 for v in a.timings.values())


@pytest.mark.parametrize(
    "opts",
    [
        {"bogus": 1},
        {"features": {"nope": 1}},
        {"grouping": {"link_px": -1}},
        {"association": {"x": 1}},
        {"association": {"recheck_every": 0}},
        {"association": {"recheck_px": -1.0}},
        {"detector_options": {"max_features": 0}},
    ],
)
def test_bad_options_are_config_errors(rig, opts):
    with pytest.raises(ConfigError):
        FrontEnd(rig, **opts)


@pytest.mark.parametrize(
    "group,name,detector,accepted",
    [
        ("features", "max_featurs", "orb", ["max_features", "grid", "redetect_s", "win_px", "klt_step_s"]),
        ("grouping", "link_pix", "orb", ["link_px", "min_age_s", "confirm_s", "plane_every_s"]),
        ("boxes", "gate", "navlights", ["gate_rad", "confirm_s", "link_share", "link_older_only"]),
        ("association", "epipolar", "orb", ["every", "epipolar_deg", "reverse_views"]),
    ],
)
def test_an_unknown_option_lists_the_accepted_ones(rig, group, name, detector, accepted):
    with pytest.raises(ConfigError) as ei:
        FrontEnd(rig, detector, **{group: {name: 1}})
    msg = str(ei.value)
    assert msg.startswith(f"FrontEnd: unknown key '{name}' in {group}; did you mean "), msg
    listed = msg.split("Valid keys: ")[1].split(", ")
    assert set(accepted) <= set(listed)
    assert not {"ids", "camera", "detector", "label", "old"} & set(listed)  # set by the front end itself


def test_every_option_group_is_checked_also_one_the_detector_does_not_build(rig):
    """A misspelt boxes key beside orb (no box tracker) is refused, not ignored; the first unknown name
    of a group is named (option_problem), a group whose names are all taken passes."""
    import trackers.frontend as fe

    with pytest.raises(ConfigError, match=r"^FrontEnd: unknown key 'gate_rd' in boxes; did you mean "):
        FrontEnd(rig, "orb", boxes={"gate_rd": 1.0})
    with pytest.raises(ConfigError, match=r"^FrontEnd: unknown key 'b' in association; valid keys: every, "):
        FrontEnd(rig, "orb", association={"every": 5, "b": 1, "a": 2})
    assert fe.option_problem("association", {"every": 5, "epipolar_deg": 1.0}) is None


def test_box_options_beside_a_detector_without_boxes_are_refused_from_code_too(rig):
    """FrontEnd(rig, "orb", boxes=...) built no BoxTracker and dropped the options without a word (a config
    was already refused at load); now the same refusal; a detector that gives boxes takes them."""
    with pytest.raises(ConfigError) as e:
        FrontEnd(rig, "orb", boxes={"gate_rad": 0.1})
    assert str(e.value) == (
        "FrontEnd: boxes (gate_rad) set, and detector 'orb' gives no boxes (no box tracker is built: they "
        "would be ignored); expected a detector that gives boxes (navlights, orb+navlights, torch or another "
        "'<keypoint detector>+<box detector>' composite), or no boxes options")
    assert FrontEnd(rig, "navlights", boxes={"gate_rad": 0.1}).boxers
    assert not FrontEnd(rig, "orb", boxes={}).boxers


def test_an_unknown_front_end_option_is_worded_as_an_unknown_key(rig):
    """The front end's own options in the words of every other unknown key (was "unknown options
    ['groupin']; expected any of [...]"); a group it has none of is a ConfigError (was a KeyError)."""
    import trackers.frontend as fe

    with pytest.raises(ConfigError, match=r"^FrontEnd: unknown key 'groupin' in its options; did you mean "
                                          r"'grouping'\? Valid keys: detector_options, features, grouping, "):
        FrontEnd(rig, "orb", groupin={})
    with pytest.raises(ConfigError, match=r"^FrontEnd: no option group 'tracks'; expected one of features, "
                                          r"grouping, boxes, association$"):
        fe.option_problem("tracks", {"a": 1})


def test_the_configs_tracker_groups_are_the_front_ends_option_groups():
    """The config checks (and passes on) one dict field of its tracker section per front-end option
    group: the two lists are one set, so the config's check never asks the front end for a group it
    has not got."""
    import trackers.frontend as fe
    from pipeline.config import TrackerConfig

    groups = {g for g, v in TrackerConfig().model_dump().items() if isinstance(v, dict)}  # as _check_tracker
    assert groups == set(fe._OPTION_DICTS)


@pytest.mark.parametrize("bad", ["x", 2.7, -1, True, "2"])
def test_follow_levels_must_be_a_non_negative_integer_or_null(rig, bad):
    """association.follow_levels is OpenCV's maxLevel: a string, a float (2.7 would be truncated
    to 2) or a negative value is a ConfigError naming the setting, the value and what is expected."""
    with pytest.raises(ConfigError) as e:
        FrontEnd(rig, association={"follow_levels": bad})
    msg = str(e.value)
    assert "follow_levels" in msg and repr(bad) in msg and "integer >= 0 or null" in msg


@pytest.mark.parametrize("good", [None, 0, 1, 3])
def test_follow_levels_accepts_integers_and_null(rig, good):
    assert FrontEnd(rig, association={"follow_levels": good}).follow_levels == good


def test_non_finite_time_is_an_error(model, rig):
    with pytest.raises(InputError, match=r"^frame 0: FrontEnd.process: expected a finite t_s, got nan"):
        FrontEnd(rig).process({"cam0": good_grey(model)}, 0, float("nan"))


def test_wide_frames_are_tracked_downscaled_with_consistent_bearings_and_pixels():
    """A 640x480 camera with max_width=320: tracking runs at 320x240 on the scaled model, the
    reported bearings and full-frame pixels agree through the full-size model (within 1 px)."""
    from tests.trackers.conftest import equidistant, rot_axis

    big = equidistant(640, 480)
    rig = mono_forward_rig(big)
    scene = SphereScene(big)
    fe = FrontEnd(rig, max_width=320)
    assert fe.cams["cam0"].model.width == 320
    out = []
    for k in range(8):
        out = fe.process({"cam0": scene.render(rot_axis([0, 1, 0], np.radians(0.5) * k))}, k, k / 30)
    views = [v for o in out if o.status != "lost" for v in o.views]
    assert views
    uv, ok = big.bearing_to_pixel(np.array([v.b_C for v in views]))
    assert ok.all()
    np.testing.assert_allclose(uv, np.array([v.uv for v in views]), atol=1.0)
    with pytest.raises(ConfigError, match="max_width"):
        FrontEnd(rig, max_width=10)


def test_texture_sample_index_is_the_strided_masked_sample():
    """_has_texture's precomputed flat indices pick the same pixels, in the same order, as numpy's
    strided boolean indexing grey[::8, ::8][mask[::8, ::8] > 0] (also for sizes not a multiple of 8)."""
    from trackers.features import lens_mask
    from trackers.frontend import _sample_index

    rng = np.random.default_rng(3)
    for w, h in ((640, 480), (1277, 719)):
        m = Equidistant(fx=w / 4, fy=w / 4, cx=(w - 1) / 2, cy=(h - 1) / 2, width=w, height=h)
        mask = lens_mask(m)
        grey = rng.integers(0, 256, (h, w), dtype=np.uint8)
        want = grey[::8, ::8][mask[::8, ::8] > 0]
        got = np.take(grey, _sample_index(mask))
        assert len(want) > 100
        np.testing.assert_array_equal(got, want)


def test_the_stereo_klt_takes_the_trackers_window(monkeypatch):
    """One window setting: features.win_px (7 here) is the temporal KLT's window and the stereo
    KLT's (it was 11 whatever win_px said); tracked_window gives every camera that window."""
    import trackers.frontend as fe_mod
    from estimators.rig import stereo_forward_rig
    from tests.trackers.conftest import equidistant, rot_axis

    model = equidistant(320, 240)
    rig = stereo_forward_rig(model, 0.30)
    scene = SphereScene(model)  # the environment at infinity: both cameras see one image
    seen = []
    real = fe_mod.stereo_klt

    def recording(*a, **kw):
        seen.append(kw.get("win_px"))
        return real(*a, **kw)

    monkeypatch.setattr(fe_mod, "stereo_klt", recording)
    fe = FrontEnd(rig, features={"win_px": 7})
    assert fe.trackers["cam0"].win == fe.trackers["cam1"].win == (7, 7)
    for k in range(6):
        img = scene.render(rot_axis([0, 1, 0], np.radians(0.5) * k))
        fe.process({"cam0": img, "cam1": img}, k, k / 30)
    assert seen and set(seen) == {7}
    assert fe_mod.tracked_window(rig, {"win_px": 7}) == {"cam0": 7, "cam1": 7}
    assert fe_mod.tracked_window(rig) == fe_mod.tracked_window(rig, {}) == {"cam0": 11, "cam1": 11}


@pytest.mark.parametrize("bad", [2, 0, -11, 11.5, True, "11", None])
def test_a_window_that_is_not_an_integer_of_3_px_or_more_is_refused(rig, bad):
    from trackers.frontend import tracked_window

    with pytest.raises(ConfigError, match=r"win_px"):
        tracked_window(rig, {"win_px": bad})
    with pytest.raises(ConfigError, match=r"win_px"):
        FrontEnd(rig, features={"win_px": bad})
