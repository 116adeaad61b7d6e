"""Front-end accuracy on simulated scenes (trackers/benchmark.py): the mapping of tracks to the
simulator's obstacles (closed-form ray/shape tests), a fast regression test on the small CI scene,
and heavy runs of the presets with the issue's numbers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from estimators.errors import InputError
from trackers.benchmark import (
    Shape,
    merged_depth_kind,
    mjpeg_copy,
    ray_hit_distance,
    ray_hits,
    run_benchmark,
)
from trackers.detectors import register_detector
from trackers.detectors.orb import OrbDetector

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "configs" / "scenarios"


def simulate(name: str, out: Path, **kw) -> Path:
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.writer import simulate as sim

    sim(load_scenario(SCENARIOS / f"{name}.yaml"), out, **kw)
    return out


def test_ray_hits_closed_forms():
    o = np.zeros(3)
    x = np.array([1.0, 0.0, 0.0])
    # sphere of radius 1 at 10 m ahead: a hit, reported at the centre's projection on the ray
    assert ray_hit_distance(o, x, Shape("sphere", np.array([10.0, 0, 0]), r_m=1.0), 0.0) == pytest.approx(
        10.0
    )
    # passes 1.5 m beside it: miss, unless the margin is 0.6 m
    d = np.array([10.0, 1.5, 0.0]) / np.hypot(10, 1.5)
    s = Shape("sphere", np.array([10.0, 0, 0]), r_m=1.0)
    # the centre is |c x d| = 10 * 1.5 / hypot(10, 1.5) = 1.483 m from that ray
    assert ray_hit_distance(o, d, s, 0.0) is None
    assert ray_hit_distance(o, d, s, 0.45) is None
    assert ray_hit_distance(o, d, s, 0.5) is not None
    # pole: capsule along z from z=-3 to 3 at x=5, radius 0.1; a ray up at 30 deg hits it
    pole = Shape("capsule", np.array([5.0, 0, 0]), r_m=0.1, half_h_m=3.0)
    up = np.array([np.cos(np.radians(30)), 0, np.sin(np.radians(30))])
    assert ray_hit_distance(o, up, pole, 0.0) == pytest.approx(5 / np.cos(np.radians(30)), rel=0.02)
    assert ray_hit_distance(o, -up, pole, 0.0) is None  # behind
    # box 2x2x2 at x=10 turned 45 deg: the ray along x enters at 10 - sqrt(2)
    box = Shape("box", np.array([10.0, 0, 0]), half_size_m=np.ones(3), yaw_rad=np.radians(45))
    assert ray_hit_distance(o, x, box, 0.0) == pytest.approx(10 - np.sqrt(2))
    assert ray_hit_distance(o, np.array([0.0, 1.0, 0.0]), box, 0.0) is None


def test_vectorised_ray_hits_closed_forms():
    """ray_hits (the explain mode's per-feature test) on the same closed forms, several rays at once."""
    o = np.zeros(3)
    s = Shape("sphere", np.array([10.0, 0, 0]), r_m=1.0)
    d = np.array([[1.0, 0, 0], [10.0, 1.5, 0.0], [-1.0, 0, 0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    t = ray_hits(o, d, s, 0.0)
    assert t[0] == pytest.approx(10.0) and np.isinf(t[1]) and np.isinf(t[2])  # ahead, 1.483 m off, behind
    assert np.isfinite(ray_hits(o, d, s, 0.5)[1])
    # pole along z from z=-3 to 3 at x=5, r 0.1: up at 30 deg it hits at 5 / cos 30 (the line's
    # closest approach to the axis, exactly); over the top (up at 45 deg passes z=5 > 3 + 0.1): miss
    pole = Shape("capsule", np.array([5.0, 0, 0]), r_m=0.1, half_h_m=3.0)
    up = np.array([[np.cos(np.radians(a)), 0, np.sin(np.radians(a))] for a in (30.0, 45.0)])
    t = ray_hits(o, up, pole, 0.0)
    assert t[0] == pytest.approx(5 / np.cos(np.radians(30))) and np.isinf(t[1])
    box = Shape("box", np.array([10.0, 0, 0]), half_size_m=np.ones(3), yaw_rad=np.radians(45))
    t = ray_hits(o, np.array([[1.0, 0, 0], [0, 1.0, 0]]), box, 0.0)
    assert t[0] == pytest.approx(10 - np.sqrt(2)) and np.isinf(t[1])


@pytest.fixture(scope="module")
def ci_scene(tmp_path_factory) -> Path:
    # at 640x480: at the preset's 320x240 the sphere is ~10 px wide and its handful of corners
    # comes and goes with the renderer's texture details
    return simulate("ci_small", tmp_path_factory.mktemp("ci_small"), resolution=(640, 480))


def test_ci_small_coverage_and_ids(ci_scene):
    """ci_small (at 640x480, 1 s): the pole and the sphere are tracked in every due frame without an
    id switch (measured: 1.00 / 1.00, 0 switches; overall 0.88: the drone, ~6 px and due in only 4
    frames, has no ORB track).
    Thresholds sit below the measured values so that a regression fails."""
    res = run_benchmark(ci_scene)
    per = res["obstacles"]
    assert per[1]["coverage"] >= 0.9 and per[2]["coverage"] >= 0.9
    assert per[1]["id_switches"] == 0 and per[2]["id_switches"] == 0
    assert res["coverage"] >= 0.8
    assert res["rim_features_per_frame"] > 0
    # tracks on no obstacle are some of the reported ones (the pole and sphere tracks are not)
    assert 0 <= res["off_obstacle_tracks_per_frame"] < res["observations_per_frame"]
    # ... and the confirmed ones among them (a tentative track is counted only in the first;
    # measured at 804cf02..16d9020: 3.03 confirmed of 5.90 a frame, so counting tentative ones too fails)
    assert 0 < res["off_obstacle_confirmed_per_frame"] < res["off_obstacle_tracks_per_frame"]
    assert set(res["ms_per_frame"]) >= {"decode", "frontend", "detect", "track", "group", "associate"}


def test_explain_gives_a_cause_for_every_gap_and_switch(ci_scene):
    """--explain: each uncovered due frame and each id switch gets exactly one cause, and the
    coverage figures are the plain run's (ci_small has gaps under ORB alone: its ~6 px drone, which only
    the default orb+navlights finds; 4 frames measured)."""
    plain = run_benchmark(ci_scene, detector="orb")
    res = run_benchmark(ci_scene, detector="orb", explain=True)
    assert res["coverage"] == plain["coverage"] and res["id_switches"] == plain["id_switches"]
    ex = res["explain"]
    gaps = sum(p["frames_due"] - round(p["coverage"] * p["frames_due"]) for p in res["obstacles"].values())
    assert gaps > 0 and sum(ex["gap_causes"].values()) == gaps
    assert sum(ex["switch_causes"].values()) == res["id_switches"]
    assert len([e for e in ex["events"] if "gap" in e]) == gaps
    # every merged_other gap is either lined up in depth or side by side, none twice
    merged = [e for e in ex["events"] if e.get("gap") == "in_track_elsewhere/merged_other"]
    assert sum(ex["merged_by_depth"].values()) == len(merged)
    for e in merged:  # lined up: some other obstacle's range differs by DEPTH_RATIO (1.5) or more
        assert all(r > 0 for r in e["range_ratio"])
    # (ci_small under ORB has no in_track_elsewhere gap (measured: 2 no_features/tiny, 2 young), so
    # where a holding track's representative lies is tested on its own: _rep_px and the summary's
    # in_track_rep_beside_members below)
    assert ex["in_track_rep_beside_members"] == 0
    # distinct ids on an obstacle: at least one per switch more than the first; none if never covered
    for p in res["obstacles"].values():
        if p["coverage"] > 0:
            assert p["track_ids"] >= 1 + p["id_switches"]
        else:
            assert p["track_ids"] == 0


# The presets at full size. Measured 02:05 UTC on renders of 01:55 (previous front end on the same
# renders in brackets): mono_straight coverage 0.94, min 0.86, 20 switches per obstacle-minute
# (0.96, 0.86, 20); moving_crossing 0.61, min 0.32, 8 (0.56, 0.32, 8.5: a 6-px drone, a 16-px box);
# wide_angle_beyond90 0.78, min 0.47, 12 (0.77, 0.43, 12.5: slivers at 93-97 deg against the rim);
# noisy_1080p 0.86, min 0.52, 39; stereo_flying 0.95, min 0.74, 14 (0.95, 0.76). One switch in
# these 3-4 s scenes is 4-20 per obstacle-minute, so the switch bounds are loose. The thresholds sit
# below those; the targets (>= 0.95 everywhere, < 1 switch per obstacle-minute) are not met.
# 2026-11-22 (third session): with the backward KLT check on the full-resolution level only
# (fb_levels=0, a speed change) noisy_1080p's worst obstacle fell 0.52 -> 0.29 and turning's to 0.19;
# fb_levels=1 is the default again (noisy_1080p 0.934 / worst 0.708, turning 1.000, stereo_flying
# 0.926 / 0.623), but moving_crossing's worst obstacle is 0.21 with it (0.71 with fb_levels=0): its
# features are grouped with the background (trackers.benchmark --explain), so that guard is 0.18.
# 2026-11-22 (fourth session): with the grouper's split by motion (step 3c) moving_crossing is
# 0.846 / worst 0.629 (its box is no longer dropped as ground texture), so that guard is 0.75 / 0.5;
# the others measured stereo_flying 0.933 / 0.660, noisy_1080p 0.934 / 0.708, wide_angle 0.851 /
# 0.587, mono_straight 1.000 / 1.000 (guards unchanged).
HEAVY = [
    # (scenario, min overall coverage, min per-obstacle coverage, max switches per obstacle-minute
    # over all obstacles)
    ("mono_straight", 0.9, 0.75, 35.0),
    ("moving_crossing", 0.75, 0.5, 25.0),
    ("wide_angle_beyond90", 0.7, 0.35, 30.0),
    ("noisy_1080p", 0.78, 0.4, 50.0),
    ("stereo_flying", 0.9, 0.62, 40.0),
]


@pytest.mark.heavy
@pytest.mark.parametrize("name,cov,cov_min,sw", HEAVY, ids=[h[0] for h in HEAVY])
def test_presets_full(tmp_path, name, cov, cov_min, sw):
    res = run_benchmark(simulate(name, tmp_path / name))
    print(json.dumps({k: v for k, v in res.items() if k != "obstacles"}, indent=1))
    print(json.dumps(res["obstacles"], indent=1))
    assert res["coverage"] >= cov
    assert res["min_coverage"] >= cov_min
    assert res["switches_per_obstacle_minute"] <= sw
    if name == "wide_angle_beyond90":
        assert res["rim_features_age10_per_frame"] >= 30  # features > 90 deg off-axis, tracked >= 10 frames


def test_poses_are_passed_by_default_as_the_pipeline_does(ci_scene):
    """The benchmark measures what the pipeline runs: the front end gets the scene's true poses
    (gt.jsonl has T_W_B on every frame) unless told not to; the result says which it was."""
    with_poses = run_benchmark(ci_scene, max_frames=3)
    without = run_benchmark(ci_scene, max_frames=3, use_poses=False)
    assert with_poses["poses"] is True and without["poses"] is False


def test_cli_no_poses_flag(ci_scene, capsys):
    """``--no-poses`` turns them off; the default and ``--poses`` pass them."""
    from trackers.benchmark import main

    for argv, expect in (([], True), (["--poses"], True), (["--no-poses"], False)):
        main([str(ci_scene), "--frames", "3", *argv])
        assert json.loads(capsys.readouterr().out)["poses"] is expect


def _lossless_frames(video: Path, n: int) -> list[np.ndarray]:
    import cv2

    cap = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
    frames = [cap.read()[1] for _ in range(n)]
    cap.release()
    return frames


def _psnr_db(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(255.0**2 / np.mean((a.astype(float) - b.astype(float)) ** 2)))


def test_mjpeg_copy_is_a_cameras_mjpeg(ci_scene):
    """The copy is one baseline JPEG per frame of the video (4:2:2 chroma, as a UVC camera's MJPEG),
    back to back; FFmpeg's own MJPEG decoder reads it as a video of as many frames, each close to
    the lossless frame (JPEG quality 90: well above 35 dB) but not equal to it; made once."""
    import cv2

    video = ci_scene / "cam0.mkv"
    out = mjpeg_copy(video, 90)
    assert out == ci_scene / "cam0.q90.mjpeg"
    n = sum(1 for ln in (ci_scene / "cam0.timestamps.txt").read_text().splitlines() if ln.strip())
    data = out.read_bytes()
    # SOI markers (0xFFD8 never occurs inside entropy-coded data: 0xFF there is followed by 0x00)
    assert data.count(b"\xff\xd8\xff") == n
    sof = data.index(b"\xff\xc0")  # baseline DCT frame header: Nf, then (id, HV sampling, table) each
    assert data[sof + 9] == 3
    assert [data[sof + 11 + 3 * k] for k in range(3)] == [0x21, 0x11, 0x11]  # Y 2x1: 4:2:2
    cap = cv2.VideoCapture(str(out), cv2.CAP_FFMPEG)
    decoded = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        decoded.append(img)
    assert len(decoded) == n
    lossless = _lossless_frames(video, n)
    psnr = [_psnr_db(a, b) for a, b in zip(decoded, lossless, strict=True)]
    assert min(psnr) > 35.0 and max(psnr) < 80.0
    stamp = out.stat().st_mtime_ns
    assert mjpeg_copy(video, 90) == out and out.stat().st_mtime_ns == stamp
    with pytest.raises(InputError, match="quality"):
        mjpeg_copy(video, 0)


class _PluginOrb(OrbDetector):
    """A plug-in detector (not in GREY_DETECTORS) that itself needs no colour: like torch's user
    models, the pipeline gives it colour frames, so the benchmark does too."""


register_detector("test_plugin_orb")(_PluginOrb)


@pytest.mark.parametrize(
    "detector, decoded_to", [("orb", "grey"), ("orb+navlights", "bgr"), ("test_plugin_orb", "bgr")]
)
def test_mjpeg_frames_are_what_the_front_end_sees(ci_scene, monkeypatch, detector, decoded_to):
    """``mjpeg_quality``: the front end (and so the coverage scoring) gets the decoded JPEG frames,
    grey for a grey detector (orb), BGR for any other (orb+navlights, a plug-in), as the pipeline
    decodes them; the result says so."""
    import cv2

    from trackers.frontend import FrontEnd

    seen: list[np.ndarray] = []
    process = FrontEnd.process

    def spy(self, images, *a, **kw):
        seen.append(images["cam0"].copy())
        return process(self, images, *a, **kw)

    monkeypatch.setattr(FrontEnd, "process", spy)
    res = run_benchmark(ci_scene, detector=detector, max_frames=4, mjpeg_quality=90)
    assert res["video"] == {"format": "mjpg", "quality": 90, "decoded_to": decoded_to}
    lossless = _lossless_frames(ci_scene / "cam0.mkv", 4)
    if decoded_to == "grey":
        lossless = [cv2.cvtColor(b, cv2.COLOR_BGR2GRAY) for b in lossless]
    assert len(seen) == 4
    for img, ref in zip(seen, lossless, strict=True):
        assert img.shape == ref.shape and img.dtype == np.uint8
        assert 35.0 < _psnr_db(img, ref) < 80.0  # the JPEG's frame, not the lossless one
    assert run_benchmark(ci_scene, max_frames=1)["video"] == {"format": "ffv1", "decoded_to": "bgr"}


@pytest.mark.parametrize(
    "range_m, others, kind",
    [
        (10.0, [14.0], "side_by_side"),  # 1.4 < 1.5
        (10.0, [15.0], "lined_up"),  # 1.5: the boundary counts as lined up
        (10.0, [7.0], "side_by_side"),  # 10 / 7 = 1.43 in front
        (10.0, [6.0], "lined_up"),  # 10 / 6 = 1.67 in front
        (10.0, [11.0, 20.0], "lined_up"),  # one of them behind
        (10.0, [9.0, 11.0], "side_by_side"),
        (10.0, [], "side_by_side"),  # no other obstacle's range known
    ],
)
def test_merged_by_depth_classification(range_m, others, kind):
    """An obstacle merged with others: lined up when another's range differs by 1.5x either way
    (ratios worked by hand), else side by side; the ratios are other / own."""
    got, ratios = merged_depth_kind(range_m, others, 1.5)
    assert got == kind
    assert ratios == pytest.approx([o / range_m for o in others])


@pytest.mark.parametrize(
    "drone",
    [
        # crossing (heading along its velocity), climbing too; seen from the side
        "{id: 4, kind: drone, position_m: [0.5, -5.0, 3.0], light_radius_m: 0.06,"
        " motion: {kind: constant_velocity, velocity_mps: [0.6, 0.4, 0.5]}}",
        # hovering, turned by yaw_deg, another body size
        "{id: 4, kind: drone, position_m: [6.0, 1.0, 2.6], yaw_deg: 30, size_m: [0.6, 0.4, 0.1]}",
    ],
)
def test_drone_shape_holds_the_simulators_drone_not_its_bounding_sphere(tmp_path, drone):
    """A drone is the box that holds the simulator's drone (body and lights), not its bounding
    sphere: every ray pipeline.sim.raycast puts on the drone hits the shape (margin 0), and of the
    rays through the bounding sphere that miss the drone (what lies behind it) most miss the shape
    (the box's corners beyond the round lights are all it adds)."""
    import yaml

    from estimators.se3 import Pose
    from pipeline.sim.groundtruth import obstacle_truth
    from pipeline.sim.rigs import build_rig
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.world import World, raycast
    from trackers.benchmark import shapes_for_frame

    p = tmp_path / "drone.yaml"
    p.write_text(
        "name: drone\nseed: 1\nduration_s: 1.0\nfps: 30\nrig: {kind: mono, resolution: [320, 240]}\n"
        "observer: {kind: hover, start: {position_m: [0, 0, 2.5]}}\nground: {z_m: 0.0}\n"
        f"obstacles:\n  - {drone}\n"
    )
    scn = load_scenario(p)
    world = World(scn)
    t_s = 0.5
    rig = build_rig(scn.rig)
    line = obstacle_truth(world, rig, Pose(np.eye(3), np.array([0.0, 0.0, 2.5])), np.zeros(3), t_s)
    (gt,) = line
    specs = {4: yaml.safe_load(drone)}
    shape = shapes_for_frame(specs, [gt])[4]
    o = np.array([0.0, 0.0, 2.5])
    c = np.asarray(gt["p_W"], float)
    r = float(gt["radius_m"])
    rng = np.random.default_rng(7)
    pts = c + rng.uniform(-r, r, (20000, 3))  # rays towards points of the bounding sphere's cube
    d = (pts - o) / np.linalg.norm(pts - o, axis=1, keepdims=True)
    _, who = raycast(world, t_s, o, d)
    on_shape = np.isfinite(ray_hits(o, d, shape, 0.0))
    in_sphere = np.isfinite(ray_hits(o, d, Shape("sphere", c, r_m=r), 0.0))
    on_drone = who == 4
    assert on_drone.sum() > 500
    assert np.all(on_shape[on_drone])
    past = in_sphere & ~on_drone
    assert past.sum() > 2000 and on_shape[past].mean() < 0.25


def test_the_command_reports_bad_input_without_a_traceback(ci_scene, tmp_path, capsys):
    """python -m trackers.benchmark: a JPEG quality outside 1..100 or a folder that is no scene ends
    with exit status 2 and the message naming what was wrong, not a traceback."""
    from trackers.benchmark import main

    with pytest.raises(SystemExit) as e:
        main([str(ci_scene), "--mjpeg", "0"])
    assert e.value.code == 2
    assert "expected a JPEG quality in 1..100, got 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main([str(tmp_path)])
    assert e.value.code == 2
    assert "camchain.yaml" in capsys.readouterr().err


def test_explain_measures_where_a_holding_track_s_representative_lies():
    """``_Explainer._rep_px``: the representative's angle from its members' normalised mean and the
    members' RMS angle about that mean, in px at the camera's scale. Closed form: two members
    +-a about the z axis in the x-z plane (mean z, RMS a) and the representative at angle 3a on the
    other axis; an unseen track and another id give nothing."""
    from types import SimpleNamespace

    from trackers.benchmark import _Explainer

    a, rad_px = 0.01, 0.002
    members = np.array([[np.sin(a), 0.0, np.cos(a)], [-np.sin(a), 0.0, np.cos(a)]])
    rep = np.array([0.0, np.sin(3 * a), np.cos(3 * a)])
    seen = SimpleNamespace(id=7, seen=True, member_b_C=members, b_C=rep)
    unseen = SimpleNamespace(id=8, seen=False, member_b_C=members, b_C=rep)
    fe = SimpleNamespace(groupers={"cam0": SimpleNamespace(tracks={7: seen, 8: unseen})}, _global=lambda i: i)
    ex = _Explainer(fe)
    d, rms = ex._rep_px(7, {"cam0": rad_px})["cam0"]
    assert d == pytest.approx(3 * a / rad_px, abs=0.01) and rms == pytest.approx(a / rad_px, abs=0.01)
    assert ex._rep_px(8, {"cam0": rad_px}) == {} and ex._rep_px(9, {"cam0": rad_px}) == {}


def test_the_summary_counts_the_gaps_whose_holding_track_lies_beside_its_members():
    """``in_track_rep_beside_members``: the in_track_elsewhere gaps where some holding track's
    representative lies farther from its members' mean than their RMS angle in some camera (any
    camera, any holding track); other gaps, switches and a track seen in no camera count nothing."""
    from types import SimpleNamespace

    from trackers.benchmark import _Explainer

    ex = _Explainer(SimpleNamespace(groupers={}))
    ex.events = [
        {"gap": "in_track_elsewhere/merged_other", "tracks": {3: {"rep_px": {"cam0": [5.0, 2.0]}}}},  # 1
        {"gap": "in_track_elsewhere/rep_off",  # beside in cam1 only: 1
         "tracks": {4: {"rep_px": {"cam0": [1.0, 2.0], "cam1": [3.0, 2.5]}}}},
        {"gap": "in_track_elsewhere/merged_other",  # one of two tracks beside: 1
         "tracks": {5: {"rep_px": {"cam0": [1.0, 2.0]}}, 6: {"rep_px": {"cam0": [4.0, 1.0]}}}},
        {"gap": "in_track_elsewhere/rep_off", "tracks": {7: {"rep_px": {"cam0": [2.0, 2.0]}}}},  # on: 0
        {"gap": "in_track_elsewhere/rep_off", "tracks": {8: {"rep_px": {}}}},  # unseen: 0
        {"gap": "young"},
        {"switch": "lost", "from": 1, "to": 2},
    ]
    assert ex.summary()["in_track_rep_beside_members"] == 3
