"""Tests of the accuracy harness (pipeline/accuracy.py): metric definitions on hand-made samples,
the thesis baseline on a hand-worked triangle, a one-scene bearings-mode smoke run, and (heavy) the
quick harness against the issue's targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.accuracy import (
    AccuracyOptions,
    Sample,
    _law_of_sines,
    format_table,
    run_accuracy,
    run_bearings,
    summarize,
)


def _s(**kw) -> Sample:
    base = dict(scene="s", rig="mono", track=1, t_s=2.0, in_view_s=1.5, moving=False, speed_true=0.0,
                max_speed=5.0, off_axis_deg=30.0, range_true=10.0, n_views=1, range_m=10.0,
                range_sigma_m=0.1, range_min_m=None, range_max_m=None, source="mono")
    base.update(kw)
    return Sample(**base)


def test_summarize_mono_selection_and_quantiles():
    samples = [_s(range_m=10.0 + 0.1 * k) for k in range(11)]  # rel errors 0, 1 %, ..., 10 %
    samples += [
        _s(range_true=25.0, range_m=0.0),  # beyond 20 m: excluded
        _s(off_axis_deg=5.0, range_m=0.0),  # < 10 deg off the flight direction: excluded
        _s(in_view_s=0.5, range_m=0.0),  # < 1 s in view: excluded
        _s(moving=True, speed_true=1.0, range_m=0.0),  # moving: excluded
        _s(rig="stereo", range_m=0.0),  # one camera of a stereo rig: not the monocular case
    ]
    m = summarize(samples)
    assert m["mono_n"] == 11
    assert m["mono_median_rel"] == pytest.approx(0.05)
    assert m["mono_p90_rel"] == pytest.approx(0.09)  # numpy linear quantile of 0..0.10 step 0.01


def test_summarize_scores_a_top_bottom_rigs_one_camera_reports_as_monocular():
    """The 360-degree top/bottom rig ranges each obstacle off the horizon band with one camera over
    the drone's motion: its one-camera reports are the mono metric's, its two-camera ones are not."""
    samples = [_s(rig="top_bottom", range_m=10.0 + 0.1 * k) for k in range(5)]  # 0 .. 4 %
    samples += [_s(rig="top_bottom", n_views=2, range_m=0.0)]  # both cameras: not monocular
    m = summarize(samples)
    assert m["mono_n"] == 5
    assert m["mono_median_rel"] == pytest.approx(0.02)


def test_format_table_keeps_only_the_rows_asked_for():
    """A set whose rig has no stereo pair prints only the target rows that apply (``SET_ROWS``)."""
    from pipeline.accuracy import SET_ROWS

    m = summarize([_s(range_m=10.1)])
    full = format_table(m)
    assert "stereo 0.30 m, <=3 m" in full and "median speed err" in full
    t = format_table(m, keys=SET_ROWS["rig360"])
    assert not [line for line in t.splitlines() if line.startswith("stereo")]
    assert "mono 3-20 m, >=10 deg off, >=1 s: median rel err" in t
    assert "moving <= max speed: bounds coverage" in t and "range NEES mean (1 dof" in t


def test_summarize_bounds_coverage_counts_only_obstacles_within_max_speed():
    samples = [
        _s(moving=True, speed_true=3.0, range_min_m=8.0, range_max_m=12.0),  # inside
        _s(moving=True, speed_true=3.0, range_min_m=8.0, range_max_m=None),  # inside, unbounded
        _s(moving=True, speed_true=3.0, range_min_m=11.0, range_max_m=12.0),  # outside
        _s(moving=True, speed_true=9.0, range_min_m=11.0, range_max_m=12.0),  # faster than max: ignored
    ]
    m = summarize(samples)
    assert m["bounds_n"] == 3
    assert m["bounds_coverage"] == pytest.approx(2 / 3)
    assert m["bounds_upper_share"] == pytest.approx(2 / 3)


def test_summarize_stereo_and_velocity_metrics():
    samples = [
        _s(rig="stereo", n_views=2, range_true=2.0, range_m=2.02),  # 1 %
        _s(rig="stereo", n_views=2, range_true=6.0, range_m=6.18),  # 3 %
        _s(rig="stereo", n_views=2, range_true=7.0, range_m=7.35, moving=True, speed_true=2.0,
           speed_mps=2.2, heading_err_deg=4.0, source="stereo", stereo_fed=True),  # 5 %, 10 %
    ]
    m = summarize(samples)
    assert m["stereo_3m_n"] == 1 and m["stereo_3m_median_rel"] == pytest.approx(0.01)
    assert m["stereo_8m_n"] == 3 and m["stereo_8m_median_rel"] == pytest.approx(0.03)
    assert m["stereo_speed_median_rel"] == pytest.approx(0.10)
    assert m["stereo_heading_median_deg"] == pytest.approx(4.0)


def test_summarize_one_sigma_share_and_nees():
    samples = [_s(range_m=10.05, nees3=2.0), _s(range_m=10.2, nees3=4.0, track=2)]  # sigma 0.1
    m = summarize(samples)
    assert m["one_sigma_share"] == pytest.approx(0.5)
    assert m["nees_mean"] == pytest.approx(3.0)
    assert m["nees_n_tracks"] == 2
    lo, hi = m["nees_interval95"]
    assert lo < 3.0 < hi
    table = format_table(m)
    assert "position NEES" in table and "PASS" in table
    # range NEES (the evaluator's 1-D one): (0.05 / 0.1)^2 = 0.25 and (0.2 / 0.1)^2 = 4
    assert m["range_nees_n"] == 2
    assert m["range_nees_mean"] == pytest.approx((0.25 + 4.0) / 2)
    assert "range NEES" in table


def test_true_miss_distance_closed_forms():
    from pipeline.accuracy import _true_miss

    # head-on: 10 m ahead closing at 5 m/s; abeam: 6 m ahead, 2 m left, closing at 3 m/s along x;
    # receding (or relatively still): the closest approach is now, |r|
    assert _true_miss(np.array([10.0, 0.0, 0.0]), np.array([-5.0, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-12)
    assert _true_miss(np.array([6.0, 2.0, 0.0]), np.array([-3.0, 0.0, 0.0])) == pytest.approx(2.0)
    assert _true_miss(np.array([6.0, 2.0, 0.0]), np.array([3.0, 0.0, 0.0])) == pytest.approx(math.sqrt(40.0))
    assert _true_miss(np.array([6.0, 2.0, 0.0]), np.zeros(3)) == pytest.approx(math.sqrt(40.0))


def test_summarize_miss_distance_row_is_informational():
    # errors 0.05, 0.15 and 0.5 m with a 0.1 m sigma: median 0.15, 1 of 3 within 1 sigma, 2 within 2;
    # a report without the truth's miss (ttc_s > 3 s or null) and a near miss are not scored
    samples = [_s(miss_m=2.0, miss_sigma_m=0.1, miss_true_m=2.05),
               _s(miss_m=1.0, miss_sigma_m=0.1, miss_true_m=0.85),
               _s(miss_m=0.0, miss_sigma_m=0.1, miss_true_m=0.5), _s(),
               _s(miss_m=0.0, miss_sigma_m=0.1, miss_true_m=9.0, hit="near")]
    m = summarize(samples)
    assert m["miss_n"] == 3
    assert m["miss_abs_err_median"] == pytest.approx(0.15)
    assert m["miss_within_1sigma"] == pytest.approx(1 / 3)
    assert m["miss_within_2sigma"] == pytest.approx(2 / 3)
    assert "miss distance" not in format_table(m)  # (bearings mode: no such reports)
    m["mono_eligible_n"] = 1  # pipeline mode
    row = next(ln for ln in format_table(m).splitlines() if ln.startswith("miss distance, ttc_s <= 3 s"))
    assert "0.150" in row and "info" in row and "33.33 %" in row and "66.67 %" in row
    assert "PASS" not in row and "FAIL" not in row
    from pipeline.accuracy import format_compare

    rows = [ln for ln in format_compare({"a": m, "b": m}).splitlines() if ln.startswith("miss distance")]
    assert len(rows) == 3 and rows[0].split()[-3:] == ["0.150", "0.150", "info"]


def test_thesis_law_of_sines_hand_worked_triangle():
    # A = (0,0,0), B = (4,0,0), C = (4,3,0): theta1 = atan2(3, 4), theta2 = 90 deg, |BC| = 3
    c_a, c_b = np.zeros(3), np.array([4.0, 0.0, 0.0])
    b_a = np.array([0.8, 0.6, 0.0])
    b_b = np.array([0.0, 1.0, 0.0])
    assert _law_of_sines(c_a, b_a, c_b, b_b, c_b) == pytest.approx(3.0, abs=1e-9)
    assert _law_of_sines(c_a, b_a, c_b, b_b, c_a) == pytest.approx(5.0, abs=1e-9)  # range from A
    assert _law_of_sines(c_a, b_a, c_a, b_b, c_b) is None  # zero baseline


def _tiny_scene():
    from pipeline.sim.scene import scenario_from_dict

    return scenario_from_dict({
        "name": "tiny", "duration_s": 1.4, "fps": 15,
        "rig": {"kind": "mono", "resolution": [640, 480]},
        "observer": {"kind": "straight", "speed_mps": 5.0, "start": {"position_m": [0, 0, 5]}},
        "ground": {"enabled": False},
        "obstacles": [{"id": 1, "kind": "sphere", "radius_m": 0.3, "position_m": [12.0, 4.0, 5.5]}],
    })


def test_bearings_mode_one_scene_matches_truth():
    scn = _tiny_scene()
    ss = run_bearings(scn, AccuracyOptions(pixel_sigma_px=0.3), np.random.default_rng(1))
    assert len(ss) == scn.n_frames  # one report per frame, the sphere is always in view
    last = ss[-1]
    # truth by hand: body at x = 5 * t, obstacle centre (12, 4, 5.5), body at z = 5
    t = (scn.n_frames - 1) / scn.fps
    assert last.range_true == pytest.approx(math.sqrt((12 - 5 * t) ** 2 + 16 + 0.25), abs=1e-5)
    assert last.range_m is not None
    assert abs(last.range_m - last.range_true) / last.range_true < 0.03
    assert last.thesis_range_m is not None  # 0.5 s back is within the run


def test_bearings_mode_labels_a_top_bottom_rig_by_its_kind_not_its_camera_count():
    """Two cameras up and down are not a stereo pair: bearings mode's samples carry the scenario's
    rig kind (as pipeline mode's), so their one-camera reports count as monocular, none as stereo."""
    from pipeline.accuracy import harness_scenario

    _, scn = harness_scenario("top_bottom_climb")
    scn = scn.model_copy(update={"duration_s": 1.5})
    ss = run_bearings(scn, AccuracyOptions(), np.random.default_rng(0))
    assert ss and {s.rig for s in ss} == {"top_bottom"}
    m = summarize(ss)
    assert m["stereo_8m_n"] == 0 and m["mono_n"] > 0


@pytest.mark.heavy
def test_quick_harness_meets_targets_bearings_mode():
    res = run_accuracy(AccuracyOptions(quick=True))
    m = res["metrics"]
    assert m["mono_median_rel"] <= 0.02 and m["mono_p90_rel"] <= 0.05
    assert m["stereo_8m_median_rel"] <= 0.04
    assert m["bounds_coverage"] >= 0.99
    assert res["elapsed_s"] < 120


def test_replayed_fusion_over_recorded_observations_reports_the_same(tmp_path):
    """--reuse-frontend: the fusion replayed over the observations recorded while running gives the
    same tracks.jsonl lines as the run itself (here: five static member features of one obstacle,
    seen from the tiny scene's straight flight)."""
    import pickle

    from estimators.fusion import ObstacleFusion
    from estimators.records import CameraView, ObstacleObservation
    from pipeline.accuracy import _RecordingFusion, _replay_fusion, _trackers_hash
    from pipeline.sim.rigs import build_rig
    from pipeline.sim.trajectory import observer_trajectory

    scn = _tiny_scene()
    rig = build_rig(scn.rig)
    cam = rig[0]
    traj = observer_trajectory(scn.observer, 2.0)
    pts_W = np.array([12.0, 4.0, 5.5]) + 0.2 * np.array(
        [[0, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    rec = _RecordingFusion(ObstacleFusion(rig, traj))
    ran = []
    for k in range(40):
        t = k / 30.0
        T_C_W = cam.T_C_B @ traj.pose_at(t).inverse()
        b_C = np.array([T_C_W.apply(p) for p in pts_W])
        b_C /= np.linalg.norm(b_C, axis=1, keepdims=True)
        rep = b_C.mean(axis=0)
        view = CameraView(cam.name, rep / np.linalg.norm(rep), np.zeros(2), 1e-3,
                          np.arange(5, dtype=np.int64), b_C)
        obs = [ObstacleObservation(7, k, t, "confirmed", (view,))]
        ran.append({"frame": k, "t_s": t, "tracks": [r.to_json() for r in rec.step(obs, k, t)]})
    assert ran[-1]["tracks"][0]["range_m"] is not None  # the features did range the track
    path = tmp_path / "observations.pkl"
    path.write_bytes(pickle.dumps({"trackers_hash": _trackers_hash(), "frames": rec.frames}))
    replayed, note = _replay_fusion(ObstacleFusion(rig, traj), path)
    assert replayed == ran and note == ""
    path.write_bytes(pickle.dumps({"trackers_hash": "older front end", "frames": rec.frames}))
    assert "changed" in _replay_fusion(ObstacleFusion(rig, traj), path)[1]


def test_mono_obstacle_frames_eligible_by_truth_and_covered_by_reports():
    """The coverage line of pipeline mode: obstacle-frames the mono metric could score, from the
    truth alone (hand-made: body at (5 t, 0, 0) flying along +x), and those with a ranged report."""
    from types import SimpleNamespace

    from pipeline.accuracy import _mono_covered, _mono_eligible

    traj = SimpleNamespace(
        covers=lambda t: True,
        pose_at=lambda t: SimpleNamespace(t=np.array([5.0 * t, 0.0, 0.0]), R=np.eye(3)),
        velocity_at=lambda t: np.array([5.0, 0.0, 0.0]),
    )

    def ob(i, p, moving=False, surf=8.0):
        return {"id": i, "p_W": p, "moving": moving, "surface_range_m": surf, "visible": {"cam0": True}}

    gt = [{"t_s": t, "obstacles": [
        ob(1, [10.0, 5.0, 0.0]),  # at t = 1: (5, 5, 0) from the body, 45 deg off the flight direction
        ob(2, [40.0, 0.5, 0.0]),  # < 1 deg off: never eligible
        ob(3, [10.0, -5.0, 0.0], moving=True),  # moving: never
        ob(4, [10.0, 8.0, 0.0], surf=25.0),  # beyond 20 m: never
    ]} for t in (0.0, 0.5, 1.0, 1.5)]
    truth = SimpleNamespace(scn=SimpleNamespace(rig=SimpleNamespace(kind="mono")), gt=gt, traj=traj)
    elig = _mono_eligible(truth)
    assert elig == {(1.0, 1), (1.5, 1)}  # in view since t = 0: eligible from t = 1 s on
    reps = [_s(t_s=1.0, obstacle=1), _s(t_s=1.5, obstacle=1, range_m=None),
            _s(t_s=1.5, obstacle=1, hit="near")]  # unranged / near miss: not covered
    assert _mono_covered(reps, elig) == {(1.0, 1)}
    truth.scn.rig.kind = "stereo"
    assert _mono_eligible(truth) == set()


def test_front_end_rays_for_the_thesis_method_are_the_cameras_rays_in_world():
    """The thesis baseline of pipeline mode takes each view's representative ray in W: the tiny
    scene's forward camera (optical axis = body +x, at the body origin) at t = 1 s sits at
    (5, 0, 5) and its optical axis b_C = (0, 0, 1) points along +x; a ray 90 deg to the left
    (b_C = (-1, 0, 0) in the optical frame x-right, y-down, z-forward) points along +y."""
    from estimators.records import CameraView, ObstacleObservation
    from pipeline.accuracy import _front_end_rays
    from pipeline.sim.rigs import build_rig
    from pipeline.sim.trajectory import observer_trajectory

    scn = _tiny_scene()
    rig = build_rig(scn.rig)
    traj = observer_trajectory(scn.observer, 2.0)
    views = [CameraView("cam0", np.array([0.0, 0.0, 1.0]), np.zeros(2), 1e-3)]
    left = [CameraView("cam0", np.array([-1.0, 0.0, 0.0]), np.zeros(2), 1e-3)]
    obs = [ObstacleObservation(3, 30, 1.0, "confirmed", tuple(views)),
           ObstacleObservation(4, 30, 1.0, "confirmed", tuple(left))]
    rays = _front_end_rays([(30, 1.0, obs)], rig, traj)
    (c3, b3), = rays[(1.0, 3)]
    (_c4, b4), = rays[(1.0, 4)]
    assert np.allclose(c3, [5.0, 0.0, 5.0], atol=1e-9)
    assert np.allclose(b3, [1.0, 0.0, 0.0], atol=1e-9)
    assert np.allclose(b4, [0.0, 1.0, 0.0], atol=1e-9)


def test_format_scenes_lists_only_the_metrics_a_scene_has():
    from pipeline.accuracy import format_scenes

    per = {"mono_a": summarize([_s(range_m=10.2)]),  # 2 % error
           "stereo_b": summarize([_s(rig="stereo", n_views=2, range_true=2.0, range_m=2.02)])}
    lines = format_scenes(per).splitlines()
    assert lines[0] == "per scene:"
    assert "mono 2.00 % / 2.00 % (n 1)" in lines[1] and "stereo" not in lines[1]
    assert "stereo<=3m 1.00 % (n 1)" in lines[2] and "mono " not in lines[2]


def test_the_replay_key_hashes_the_front_ends_sources_not_its_benchmark_tool():
    """A recording replays while the front end's sources are unchanged: the key is the sha1 of every
    trackers/*.py (path, then bytes, sorted by path) except trackers/benchmark.py, the benchmark tool
    nothing of the front end imports (its edits must not force every recording to be tracked again)."""
    import hashlib
    from pathlib import Path

    from pipeline.accuracy import _trackers_hash

    root = Path(__file__).resolve().parents[2] / "trackers"
    files = sorted(root.rglob("*.py"))
    assert (root / "benchmark.py") in files and (root / "frontend.py") in files

    def sha(paths):
        h = hashlib.sha1()
        for p in paths:
            h.update(p.relative_to(root).as_posix().encode())
            h.update(p.read_bytes())
        return h.hexdigest()

    assert _trackers_hash() == sha([p for p in files if p.name != "benchmark.py" or p.parent != root])
    assert _trackers_hash() != sha(files)


def test_bearings_mode_view_pixel_is_the_noisy_pixel_its_bearing_comes_from():
    """The bearings mode's CameraView.uv: with no noise the point's pixel by the equidistant closed
    form (r = f theta about (cx, cy)); with noise the pixel whose closed-form back-projection is
    the noisy bearing (not the noise-free pixel, not a made-up (0, 0)). A point behind the lens's
    field has neither."""
    from estimators.cameras import Equidistant
    from pipeline.accuracy import _noisy_bearing

    m = Equidistant(fx=200.0, fy=200.0, cx=320.0, cy=240.0, width=640, height=480,
                    max_angle_rad=math.radians(100.0))
    p_C = np.array([1.0, -0.5, 3.0])
    theta, phi = math.atan2(math.hypot(1.0, -0.5), 3.0), math.atan2(-0.5, 1.0)
    truth = [320.0 + 200.0 * theta * math.cos(phi), 240.0 + 200.0 * theta * math.sin(phi)]
    b, _, uv = _noisy_bearing(m, p_C, 0.0, np.random.default_rng(0))
    np.testing.assert_allclose(uv, truth, atol=1e-9)
    np.testing.assert_allclose(b, p_C / np.linalg.norm(p_C), atol=1e-12)
    b, _, uv = _noisy_bearing(m, p_C, 2.0, np.random.default_rng(1))
    assert 1e-3 < np.hypot(*(uv - truth)) < 10.0  # moved by the noise (2 px sigma)
    r = np.hypot(uv[0] - 320.0, uv[1] - 240.0)
    th = r / 200.0
    back = [math.sin(th) * (uv[0] - 320.0) / r, math.sin(th) * (uv[1] - 240.0) / r, math.cos(th)]
    np.testing.assert_allclose(b, back, atol=1e-9)
    assert _noisy_bearing(m, np.array([0.1, 0.0, -1.0]), 1.0, np.random.default_rng(2)) is None
