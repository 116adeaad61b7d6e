"""Writer round trip (videos read back pixel-exact, timestamps, gt.jsonl) and every preset renders."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from estimators.calibration import load_rig
from estimators.egomotion import TumTrajectory
from pipeline.sim.scene import load_scenario, scenario_from_dict
from pipeline.sim.writer import Simulation, exposure_gain, simulate

SCENARIOS = Path(__file__).resolve().parents[2] / "configs" / "scenarios"
GT_KEYS = {"id", "kind", "moving", "p_W", "v_W", "p_B", "v_B_rel", "range_m", "surface_range_m",
           "bearing_body", "azimuth_deg", "elevation_deg", "radius_m", "visible", "pixel"}


def _read_video(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        frames.append(f)
    cap.release()
    return frames


def _small(**realism):
    return scenario_from_dict({
        "name": "small", "seed": 3, "fps": 20, "duration_s": 0.3,
        "rig": {"kind": "stereo", "resolution": [160, 120], "baseline_m": 0.3},
        "observer": {"kind": "straight", "speed_mps": 5.0},
        "obstacles": [
            {"id": 1, "kind": "sphere", "radius_m": 0.8, "position_m": [8, 1, 2]},
            {"id": 2, "kind": "drone", "position_m": [6, -2, 2.2],
             "motion": {"kind": "constant_velocity", "velocity_mps": [0, 2, 0]}},
        ],
        "realism": realism,
    })


def test_simulate_round_trip(tmp_path):
    scn = _small()
    res = simulate(scn, tmp_path)
    assert res.frames_written == 6 and res.frames_dropped == 0 and res.cameras == ("cam0", "cam1")
    sim = Simulation(scn)
    for cam in ("cam0", "cam1"):
        frames = _read_video(tmp_path / f"{cam}.mkv")
        assert len(frames) == 6
        for k, f in enumerate(frames):
            np.testing.assert_array_equal(f, sim.render_clean(cam, k / 20))  # lossless, frame-exact
        lines = (tmp_path / f"{cam}.timestamps.txt").read_text().split("\n")
        pairs = [ln.split() for ln in lines if ln.strip()]
        assert [int(a) for a, _ in pairs] == list(range(6))
        np.testing.assert_allclose([float(b) for _, b in pairs], np.arange(6) / 20, atol=1e-9)
    gt = [json.loads(ln) for ln in (tmp_path / "gt.jsonl").read_text().splitlines()]
    assert [g["frame"] for g in gt] == list(range(6))
    for g in gt:
        assert len(g["T_W_B"]) == 7
        assert {o["id"] for o in g["obstacles"]} == {1, 2}
        for o in g["obstacles"]:
            assert GT_KEYS <= set(o)
            assert set(o["visible"]) == {"cam0", "cam1"}
    # sphere at t = 0.1 s: body at x = 0.5, z = 2 -> p_B = (7.5, 1, 0); range and surface range
    o = next(o for o in gt[2]["obstacles"] if o["id"] == 1)
    np.testing.assert_allclose(o["p_B"], [7.5, 1.0, 0.0], atol=1e-5)
    np.testing.assert_allclose(o["range_m"], np.hypot(7.5, 1.0), atol=1e-5)
    np.testing.assert_allclose(o["surface_range_m"], np.hypot(7.5, 1.0) - 0.8, atol=1e-5)
    np.testing.assert_allclose(o["v_B_rel"], [-5.0, 0.0, 0.0], atol=1e-3)
    np.testing.assert_allclose(o["azimuth_deg"], np.degrees(np.arctan2(1.0, 7.5)), atol=1e-4)
    assert o["visible"] == {"cam0": True, "cam1": True} and not o["moving"]
    d = next(o for o in gt[2]["obstacles"] if o["id"] == 2)
    assert d["moving"] and np.allclose(d["v_W"], [0, 2, 0])
    np.testing.assert_allclose(d["v_B_rel"], [-5, 2, 0], atol=1e-3)
    # side files
    rig = load_rig(tmp_path / "camchain.yaml")
    assert rig.names == ("cam0", "cam1") and rig[0].model.width == 160
    traj = TumTrajectory.load(tmp_path / "trajectory.tum")
    np.testing.assert_allclose(traj.pose_at(0.25).t, [1.25, 0.0, 2.0], atol=1e-9)
    assert load_scenario(tmp_path / "scene.yaml") == scn.model_copy(update={"duration_s": 0.3})


def test_grey_videos_round_trip(tmp_path):
    scn = _small()
    simulate(scn, tmp_path, frames=3, grey=True)
    sim = Simulation(scn)
    frames = _read_video(tmp_path / "cam1.mkv")
    assert len(frames) == 3
    for k, f in enumerate(frames):
        expect = cv2.cvtColor(sim.render_clean("cam1", k / 20), cv2.COLOR_BGR2GRAY)
        for c in range(3):
            np.testing.assert_array_equal(f[..., c], expect)


def test_frame_drops_skip_timestamps_and_truth(tmp_path):
    scn = _small(frame_drop_prob=0.4).model_copy(update={"duration_s": 1.0})
    res = simulate(scn, tmp_path, frames=20)
    assert res.frames_dropped > 0 and res.frames_written + res.frames_dropped == 20
    frames = _read_video(tmp_path / "cam1.mkv")
    pairs = [ln.split() for ln in (tmp_path / "cam1.timestamps.txt").read_text().splitlines()]
    gt = [json.loads(ln) for ln in (tmp_path / "gt.jsonl").read_text().splitlines()]
    assert len(frames) == len(pairs) == len(gt) == res.frames_written
    ts = np.array([float(b) for _, b in pairs])
    assert np.all(np.diff(ts) > 0) and np.any(np.diff(ts) > 1.5 / 20)  # gaps where frames dropped
    np.testing.assert_allclose(ts, [g["t_s"] for g in gt])
    k = np.array([int(a) for a, _ in pairs])  # the frame counter skips the dropped frames
    np.testing.assert_allclose(ts * 20, k, atol=1e-6)
    assert np.any(np.diff(k) > 1) and [g["frame"] for g in gt] == k.tolist()
    assert [g["video_frame"] for g in gt] == list(range(res.frames_written))


def test_noise_blur_and_gain_change_the_image_as_specified():
    clean = Simulation(_small())
    noisy = Simulation(_small(noise_sigma=5.0))
    a = clean.render("cam0", 0.1).astype(float)
    b = noisy.render("cam0", 0.1, np.random.default_rng(1)).astype(float)
    inside = a.sum(axis=2) > 0
    diff = (b - a)[inside & (a.min(axis=2) > 30) & (a.max(axis=2) < 220)]
    assert abs(diff.std() - 5.0) < 0.3  # the requested sigma (away from clipping)
    assert np.all(b[~inside] == 0)  # outside the lens circle stays black
    blurred = Simulation(_small(motion_blur={"subframes": 4, "exposure_s": 0.04}))
    c = blurred.render("cam0", 0.1).astype(float)
    assert 0 < np.abs(c - a).mean() < 20
    spec = _small(exposure={"amplitude": 0.2, "period_s": 1.0, "steps": [[0.5, 0.5]]}).realism.exposure
    assert exposure_gain(spec, 0.25) == pytest.approx(1.2)
    assert exposure_gain(spec, 0.75) == pytest.approx(0.8 * 0.5)


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.stem)
def test_preset_loads_and_renders(path):
    scn = load_scenario(path)
    assert scn.n_frames >= 30
    W, H = scn.rig.resolution
    f = 160 / W
    sim = Simulation(scn, (160, round(H * f)), n_frames=1)
    for cam in sim.rig:
        img = sim.render(cam.name, 0.0, np.random.default_rng(0))
        assert img.shape == (round(H * f), 160, 3) and img.max() > 0
    _, obs = sim.truth(0.0)
    assert len(obs) == len(scn.obstacles) and any(any(o["visible"].values()) for o in obs)


def test_cli_simulate_and_errors(tmp_path, capsys):
    from pipeline.cli import main

    rc = main(["simulate", str(SCENARIOS / "ci_small.yaml"), "--out", str(tmp_path / "s"), "--frames", "3",
               "--resolution", "160x120", "--no-progress"])
    assert rc == 0 and "wrote 3 frames" in capsys.readouterr().out
    assert len(_read_video(tmp_path / "s" / "cam0.mkv")) == 3
    assert main(["simulate", str(SCENARIOS / "ci_small.yaml"), "--out", str(tmp_path / "x"),
                 "--resolution", "160by120"]) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: b\nobstacles:\n  - {id: 1, kind: cone}\n")
    assert main(["simulate", str(bad), "--out", str(tmp_path / "y")]) == 2
    assert "obstacles.0.kind" in capsys.readouterr().err
    # every error is one line: garbage YAML, a misspelt key (with a suggestion), --out on a file
    bad.write_text("a: [1, 2\n b: ::\n")
    assert main(["simulate", str(bad), "--out", str(tmp_path / "y")]) == 2
    bad.write_text("name: b\nduraton_s: 1.0\n")
    assert main(["simulate", str(bad), "--out", str(tmp_path / "y")]) == 2
    assert main(["simulate", str(SCENARIOS / "ci_small.yaml"), "--out", str(bad)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and all(e.startswith("fisheye-des: error: ") for e in err), err
    assert "line 2, column 3" in err[0] and "did you mean 'duration_s'" in err[1]
    assert "cannot create the output folder" in err[2]
    # an unknown key is judged against the keys of the mapping that holds it
    bad.write_text("name: b\nrig: {model: {kind: ds}}\n")
    assert main(["simulate", str(bad), "--out", str(tmp_path / "y")]) == 2
    assert "rig.model.kind: unknown key; expected: fov_deg, name, params" in capsys.readouterr().err


@pytest.mark.heavy
@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.stem)
def test_preset_full_resolution_benchmark(path, tmp_path):
    """Renders 5 frames of each preset at its own resolution and prints the time per frame."""
    scn = load_scenario(path)
    res = simulate(scn, tmp_path, frames=5)
    print(f"{scn.name}: {res.resolution[0]}x{res.resolution[1]} x{len(res.cameras)} "
          f"{res.render_s_per_frame * 1000:.0f} ms/frame wall, "
          f"{res.render_cpu_s_per_frame * 1000:.0f} ms CPU")
    assert res.frames_written + res.frames_dropped == 5


def test_supersampling_averages_sub_pixel_rays():
    # a sphere edge: supersampled pixels take intermediate values; the mean over the image stays
    # close to the point-sampled one (same scene), and area-weighted coverage matches
    base = _small()
    ss = base.model_copy(update={"realism": base.realism.model_copy(update={"supersample": 3})})
    a = Simulation(base).render("cam0", 0.0).astype(float)
    b = Simulation(ss).render("cam0", 0.0).astype(float)
    assert abs(a.mean() - b.mean()) < 2.0
    levels_a = len(np.unique(a[..., 1]))
    levels_b = len(np.unique(b[..., 1]))
    assert levels_b > levels_a  # mixed edge pixels
