"""The benchmark harness on tiny synthetic inputs: statistics, memory sampler, decode-only, thread
pinning in a subprocess, render cache, table and JSON report. No wall-clock thresholds."""

from __future__ import annotations

import inspect
import json
import os
import statistics
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from estimators.errors import ConfigError, InputError, SourceError
from pipeline import bench
from trackers.grouping import ObstacleGrouper


def write_video(path: Path, values: list[int], size: tuple[int, int] = (64, 48), fps: float = 30.0) -> Path:
    """FFV1 (lossless) video whose frame i is uniformly grey ``values[i]``."""
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, size)
    if not w.isOpened():
        pytest.skip("OpenCV cannot write FFV1 here")
    for v in values:
        w.write(np.full((size[1], size[0], 3), v, np.uint8))
    w.release()
    return path


@pytest.fixture()
def video(tmp_path: Path) -> Path:
    return write_video(tmp_path / "cam0.mkv", [10 * i for i in range(10)])


# ------------------------------------------------------------------------------------- statistics
@pytest.mark.parametrize(
    "samples",
    [[1.0, 2.0, 3.0, 4.0], list(range(101)), [5.0], [0.003, 0.001, 0.002, 0.010, 0.004, 0.002, 0.0015]],
)
def test_percentile_matches_statistics_inclusive_quantiles(samples):
    # statistics.quantiles(method="inclusive") interpolates linearly between order statistics:
    # an independent implementation of the same definition.
    if len(samples) == 1:
        assert bench.percentile(samples, 99) == samples[0]
        return
    q = statistics.quantiles(samples, n=100, method="inclusive")
    assert bench.percentile(samples, 50) == pytest.approx(statistics.median(samples))
    assert bench.percentile(samples, 99) == pytest.approx(q[98])
    assert bench.percentile(samples, 25) == pytest.approx(q[24])


def test_percentile_hand_worked():
    # rank r = 0.99 * (2 - 1) = 0.99 -> 0 + 0.99 * (10 - 0)
    assert bench.percentile([10.0, 0.0], 99) == pytest.approx(9.9)
    assert bench.percentile([10.0, 0.0], 0) == 0.0 and bench.percentile([10.0, 0.0], 100) == 10.0


@pytest.mark.parametrize("samples,q", [([], 50), ([1.0], -1), ([1.0], 101)])
def test_percentile_rejects_bad_input(samples, q):
    with pytest.raises(InputError):
        bench.percentile(samples, q)


def test_stats_from_samples():
    s = bench.Stats.from_samples([0.004, 0.001, 0.002, 0.003])
    assert (s.n, s.median_s, s.max_s) == (4, pytest.approx(0.0025), 0.004)
    assert s.mean_s == pytest.approx(0.0025) and s.total_s == pytest.approx(0.010)
    assert s.p99_s == pytest.approx(0.003 + 0.97 * 0.001)  # r = 2.97
    assert set(s.to_json()) == {"n", "median_s", "p99_s", "mean_s", "max_s", "total_s"}
    with pytest.raises(InputError):
        bench.Stats.from_samples([])


# ------------------------------------------------------------------------------------------ memory
def test_rss_sees_a_touched_allocation():
    before = bench.rss_bytes()
    block = np.ones(64 * 2**20, dtype=np.uint8)  # 64 MiB, every page written
    after = bench.rss_bytes()
    assert after - before > 48 * 2**20
    assert bench.peak_rss_bytes() >= after
    del block


def test_memory_sampler_checkpoints_and_growth():
    m = bench.MemorySampler([3, 5])
    fake = iter([100 * 2**20, 200 * 2**20])
    m._rss_fn = lambda: next(fake)
    for n in range(1, 7):
        m.after_frame(n)
    assert m.samples == {3: 100 * 2**20, 5: 200 * 2**20}
    g = m.growth(3, 5)
    assert g["growth_bytes"] == 100 * 2**20 and g["ratio"] == pytest.approx(2.0)
    assert bench.memory_grew(g) is True
    assert m.growth(3, 7) is None and bench.memory_grew(None) is None
    flat = {"growth_bytes": 2 * 2**20, "rss_from_bytes": 100 * 2**20}
    assert bench.memory_grew(flat) is False
    assert set(m.to_json()) == {"rss_bytes_at_frames", "peak_rss_bytes"}


# ------------------------------------------------------------------------------------------- video
def test_looped_frames_replays_the_clip_in_order_and_in_grey(video):
    frames = list(bench.looped_frames({"cam0": video}, 25, fps=100.0))
    assert [f.frame for f in frames] == list(range(25))
    assert frames[24].t_s == pytest.approx(0.24)  # time keeps running across loops
    for f in frames:
        img = f.images["cam0"]
        assert img.shape == (48, 64) and img.dtype == np.uint8
        assert int(img[0, 0]) == 10 * (f.frame % 10)  # FFV1 is lossless: the value written
        assert f.decode_s > 0


def test_looped_frames_keeps_cameras_in_step(tmp_path):
    a = write_video(tmp_path / "cam0.mkv", [0, 50, 100])
    b = write_video(tmp_path / "cam1.mkv", [200, 150, 100])
    got = [(int(f.images["cam0"][0, 0]), int(f.images["cam1"][0, 0]))
           for f in bench.looped_frames({"cam0": a, "cam1": b}, 4)]
    assert got == [(0, 200), (50, 150), (100, 100), (0, 200)]


def test_decode_only_counts_frames(video):
    r = bench.decode_only({"cam0": video}, 15)
    assert r["frames"] == 15 and r["per_frame"]["n"] == 15 and r["fps"] > 0


def test_missing_video_is_a_source_error(tmp_path):
    with pytest.raises(SourceError, match=r"nope\.mkv: cannot (be opened|open)"):
        list(bench.looped_frames({"cam0": tmp_path / "nope.mkv"}, 1))


# ------------------------------------------------------------------------------ pinning subprocess
@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="CPU affinity is Linux-only")
def test_worker_pins_to_one_core_in_a_subprocess(video):
    r = bench.run_task({"kind": "decode", "videos": {"cam0": str(video)}, "frames": 5}, 1)
    assert "error" not in r, r
    p = r["pinning"]
    assert len(p["affinity"]) == 1 and p["cv2_threads"] == 1
    assert all(v == "1" for v in p["env"].values())
    assert r["frames"] == 5
    free = bench.run_task({"kind": "decode", "videos": {"cam0": str(video)}, "frames": 5}, None)
    assert len(free["pinning"]["affinity"]) == len(os.sched_getaffinity(0))


def test_worker_errors_come_back_as_data(video):
    r = bench.run_task({"kind": "no-such-task"}, 1)
    assert "unknown task kind" in r["error"]


# ------------------------------------------------------------------------------------ render cache
def test_cached_render_renders_once_and_redoes_an_unfinished_one(tmp_path):
    calls = []

    def fake_render(scn: Path, out: Path) -> None:
        calls.append(scn)
        assert scn.is_file()
        write_video(out / "cam0.mkv", [1, 2])

    scn = {"name": "s", "obstacles": [{"id": 1, "kind": "sphere", "radius_m": 1.0}]}
    d1 = bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=2, render=fake_render)
    d2 = bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=2, render=fake_render)
    assert d1 == d2 and len(calls) == 1
    assert list(bench.render_videos(d1)) == ["cam0"]
    d3 = bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=3, render=fake_render)
    assert d3 != d1 and len(calls) == 2
    (d3 / ".complete").unlink()  # as if killed mid-render
    bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=3, render=fake_render)
    assert len(calls) == 3


# ------------------------------------------------------------------------------------------ report
def test_row_ratios():
    r = bench.Row("t", "fps", 50.0, "fps", "decode-only", 200.0, inverse=True)
    assert r.ratio == pytest.approx(4.0)  # takes 4x the decode time per frame
    r = bench.Row("t", "latency", 0.02, "s", "frame interval", 0.01)
    assert r.ratio == pytest.approx(2.0)
    assert bench.Row("t", "x", None, "s", "b", 1.0).ratio is None


def test_table_and_json_report(tmp_path):
    rows = [
        bench.Row("throughput", "640x480 mono, 1 core", 120.0, "fps", "decode-only", 480.0,
                  target=">= 100 fps", met=True, inverse=True),
        bench.Row("throughput", "1920x1080 mono, 1 core", 12.0, "fps", target=">= 30 fps", met=False),
        bench.Row("detectors", "kornia on CUDA", None, "fps", note="no GPU"),
    ]
    text = bench.format_table(rows)
    assert "met" in text and "MISSED" in text and "x4.00 time of decode-only" in text
    assert "no GPU" in text and "## detectors" in text
    sections = bench.sanitize({"decode": {"fps": float("nan"), "frames": 3}})
    doc = bench.write_report(tmp_path / "bench.json", rows, sections, {"quick": True})
    back = json.loads((tmp_path / "bench.json").read_text())
    assert back == json.loads(json.dumps(doc))
    assert back["schema"] == bench.SCHEMA and back["sections"]["decode"] == {"fps": None, "frames": 3}
    assert back["rows"][0]["ratio"] == pytest.approx(4.0) and back["rows"][1]["met"] is False
    assert bench.sanitize({"a": [1.0, float("inf")], "b": float("nan")}) == {"a": [1.0, None], "b": None}


def test_machine_info_names_the_software():
    info = bench.machine_info(probe_torch=False)
    assert info["opencv"] == cv2.__version__ and info["python"] == sys.version.split()[0]


# ------------------------------------------------------------------------------------ plan, scenes
def test_quick_plan_is_small_and_full_plan_covers_the_issue():
    q, f = bench.make_plan(True), bench.make_plan(False)
    assert q.quick and q.memory_frames < 1000 and len(q.resolutions) == 1
    # the quick scaling runs outlast a track's confirmation at the clip's rate (the grouping counts in
    # seconds), so their obstacle and feature-in-obstacle rows exercise the grouping
    grouper = inspect.signature(ObstacleGrouper.__init__).parameters
    confirm_s = grouper["min_age_s"].default + grouper["confirm_s"].default
    assert q.scaling_frames / bench.camera_rate_hz(q.scaling_resolution) > confirm_s
    assert f.resolutions == ((640, 480), (1280, 720), (1920, 1080))
    assert f.rigs == ("mono", "stereo") and f.threads == (1, None)
    assert f.obstacle_counts == (1, 10, 50) and f.feature_counts == (100, 500, 2000)
    assert f.memory_frames == 10_000 and f.memory_checkpoints[0] == 1_000
    # thesis Table 4.1: 30 fps at 1080p, 60 at 720p, 100 at 480p
    assert [bench.camera_rate_hz(r) for r in f.resolutions] == [100.0, 60.0, 30.0]


@pytest.mark.parametrize("n", [1, 10, 50])
def test_bench_scenario_validates_and_keeps_the_corridor_clear(n):
    from pipeline.sim.scene import scenario_from_dict

    d = bench.bench_scenario("s", (640, 480), "stereo", 100.0, 300, n)
    scn = scenario_from_dict(d)
    assert len(scn.obstacles) == n and scn.n_frames == 300 and scn.rig.kind == "stereo"
    for o in scn.obstacles:  # the observer flies along x at y = 0: nothing may sit in its way
        assert abs(o.position_m[1]) >= 2.5 and o.position_m[0] >= 12.0


# -------------------------------------------------------------------------------- end to end (CLI)
def _have_pipeline() -> bool:
    try:
        import pipeline.live  # noqa: F401
        import pipeline.run  # noqa: F401
        import pipeline.sim.writer  # noqa: F401
        import trackers.frontend  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(not _have_pipeline(), reason="simulator / front end / run loop not importable")
def test_bench_quick_throughput_end_to_end(tmp_path):
    from typer.testing import CliRunner

    from pipeline.cli import app

    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "throughput", "--out", str(tmp_path / "o"),
                                 "--cache", str(tmp_path / "c")])
    assert r.exit_code == 0, r.output
    assert "pipeline throughput" in r.output and "decode-only" in r.output and "stage (ms/frame)" in r.output
    doc = json.loads((tmp_path / "o" / "bench.json").read_text())
    assert doc["schema"] == bench.SCHEMA and doc["meta"]["quick"] is True
    assert doc["meta"]["plan"]["repeat"] == 1 and "repeats: 1 (each measurement taken once" in r.output
    tp = doc["sections"]["throughput"]
    assert {(t["rig"], t["threads"]) for t in tp} == {("mono", 1), ("stereo", 1)}
    for t in tp:
        assert "error" not in t["pipeline"], t["pipeline"]
        assert t["pipeline"]["frames"] == bench.make_plan(True).measure_frames
        assert {"decode", "detect", "track", "estimate", "fuse", "write"} <= set(t["pipeline"]["stages"])
        assert len(t["pipeline"]["pinning"]["affinity"]) == 1
        # the run wrote one tracks.jsonl line per frame
        lines = (Path(t["pipeline"]["out"]) / "tracks.jsonl").read_text().splitlines()
        assert len(lines) == t["pipeline"]["frames"]
    rows = {(row["section"].split(" (")[0], row["name"]): row for row in doc["rows"]}
    assert any(k[0] == "pipeline throughput" and v["ratio"] is not None for k, v in rows.items())
    # the clips were rendered into the cache, complete
    clips = sorted((tmp_path / "c").iterdir())
    assert len(clips) == 2
    assert all((c / ".complete").is_file() and (c / "camchain.yaml").is_file() for c in clips)


@pytest.mark.heavy
@pytest.mark.skipif(not _have_pipeline(), reason="simulator / front end / run loop not importable")
def test_bench_quick_everything_end_to_end(tmp_path):
    import subprocess

    cmd = [sys.executable, "-m", "pipeline.cli", "bench", "--quick", "--out", str(tmp_path / "o"),
           "--cache", str(tmp_path / "c")]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    for part in ("live latency", "cost vs obstacles", "cost vs features", "memory", "detectors"):
        assert part in r.stdout
    doc = json.loads((tmp_path / "o" / "bench.json").read_text())
    assert set(doc["sections"]) >= {"throughput", "live", "scaling", "memory", "detectors"}
    assert doc["sections"]["live"][0]["result"].get("latency", {}).get("n", 0) > 0

    def errors(x, path=""):  # every measurement that failed (a row printed with "-" and a note)
        if isinstance(x, dict):
            return [f"{path}: {v}" for k, v in x.items() if k == "error" and v] + [
                e for k, v in x.items() for e in errors(v, f"{path}/{k}")]
        if isinstance(x, list):
            return [e for i, v in enumerate(x) for e in errors(v, f"{path}[{i}]")]
        return []

    assert errors(doc["sections"]) == []


def test_memory_sampler_streams_its_samples_to_disk(tmp_path):
    m = bench.MemorySampler([1, 2], path=tmp_path / "memory.json")
    m.after_frame(1)
    first = json.loads((tmp_path / "memory.json").read_text())
    assert list(first["rss_bytes_at_frames"]) == ["1"]
    m.after_frame(2)
    assert list(json.loads((tmp_path / "memory.json").read_text())["rss_bytes_at_frames"]) == ["1", "2"]


def test_looping_source_feeds_the_run_loop_with_bgr_frame_sets(tmp_path):
    a = write_video(tmp_path / "cam0.mkv", [0, 50, 100])
    b = write_video(tmp_path / "cam1.mkv", [200, 150, 100])
    src = bench.LoopingSource({"cam0": a, "cam1": b}, 7, fps=10.0, checkpoints=[2, 7], warmup=2)
    sets = list(src)
    assert [s.frame for s in sets] == list(range(7)) and sets[6].t_s == pytest.approx(0.6)
    assert list(sets[0].frames) == ["cam0", "cam1"]
    assert sets[4].images["cam1"].shape == (48, 64, 3)  # BGR, as VideoSource yields it
    assert int(sets[4].images["cam1"][0, 0, 0]) == 150  # frame 4 = clip frame 1
    assert sorted(src.memory.samples) == [2, 7]
    assert src.steady_fps() > 0 and src.steady_cpu_fps() > 0
    assert [s.camera for s in src.sources] == ["cam0", "cam1"] and src.error is None


def test_looping_source_reading_ahead_yields_the_same_frame_sets(tmp_path):
    """With more than one CPU `run` reads ahead in a thread (inputs.prefetch); the bench's source does
    the same then, and yields the same frames in the same order."""
    a = write_video(tmp_path / "cam0.mkv", [0, 50, 100])
    b = write_video(tmp_path / "cam1.mkv", [200, 150, 100])
    videos = {"cam0": a, "cam1": b}
    plain = bench.LoopingSource(videos, 7, fps=10.0, checkpoints=[7])
    ahead = bench.LoopingSource(videos, 7, fps=10.0, checkpoints=[7], prefetch=2)
    want = [(s.frame, s.t_s, [int(im[0, 0, 0]) for im in s.images.values()]) for s in plain]
    got = [(s.frame, s.t_s, [int(im[0, 0, 0]) for im in s.images.values()]) for s in ahead]
    assert got == want and [v for _, _, v in got][3] == [0, 200]  # frame 3 = clip frame 0 again
    assert sorted(ahead.memory.samples) == [7] and ahead.sets == 7


def write_grey_video(path: Path, values: list[int], size: tuple[int, int] = (64, 48)) -> Path:
    """One-plane grey FFV1 video (isColor=False, as ``simulate --grey`` writes) whose frame i is a
    horizontal ramp ``values[i] + column``."""
    w = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*"FFV1"), 30.0, size, False)
    if not w.isOpened():
        pytest.skip("OpenCV cannot write grey FFV1 here")
    ramp = np.arange(size[0], dtype=np.uint8)[None, :]
    for v in values:
        w.write(np.broadcast_to(ramp + np.uint8(v), (size[1], size[0])).copy())
    w.release()
    return path


@pytest.mark.parametrize("fourcc, ext", [("MJPG", "avi"), ("mp4v", "mp4")])
def test_a_colour_yuv_video_is_not_grey(tmp_path, fourcc, ext):
    """A colour MJPEG or MPEG-4 video (what a USB camera records) decodes without conversion to one
    plane too, its luma; it is still colour: the default detector (orb+navlights) needs it in colour."""
    from pipeline.config import PipelineConfig
    from pipeline.run import reads_grey

    p = tmp_path / f"cam0.{ext}"
    w = cv2.VideoWriter(str(p), cv2.CAP_FFMPEG, cv2.VideoWriter_fourcc(*fourcc), 30.0, (64, 48), True)
    if not w.isOpened():
        pytest.skip(f"OpenCV cannot write {fourcc} here")
    frame = np.zeros((48, 64, 3), np.uint8)
    frame[:, :32] = (0, 0, 255)  # red | green halves
    frame[:, 32:] = (0, 255, 0)
    for _ in range(3):
        w.write(frame)
    w.release()
    cap = cv2.VideoCapture(str(p), cv2.CAP_FFMPEG)
    cap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
    assert cap.read()[1].shape == (48, 64)  # the decoder's luma plane
    cap.release()
    assert bench.is_grey_video(p) is False
    cfg = PipelineConfig()
    assert cfg.detector.name == "orb+navlights" and reads_grey(cfg, [p]) is False


def test_grey_video_is_read_without_conversion_and_colour_one_is_converted(tmp_path):
    g = write_grey_video(tmp_path / "cam0.mkv", [0, 100])
    c = write_video(tmp_path / "cam1.mkv", [30, 60])
    assert bench.is_grey_video(g) is True and bench.is_grey_video(c) is False
    frames = list(bench.looped_frames({"cam0": g, "cam1": c}, 3))
    for f, v, u in zip(frames, [0, 100, 0], [30, 60, 30], strict=True):
        assert f.images["cam0"].shape == (48, 64) and f.images["cam1"].shape == (48, 64)
        assert int(f.images["cam0"][5, 0]) == v and int(f.images["cam0"][5, 63]) == v + 63  # lossless ramp
        assert int(f.images["cam1"][0, 0]) == u
    src = bench.LoopingSource({"cam0": g}, 2, fps=10.0, grey=True)
    assert [s.images["cam0"].shape for s in src] == [(48, 64), (48, 64)]


def test_cached_render_keys_grey_clips_apart(tmp_path):
    calls = []

    def fake_render(scn: Path, out: Path) -> None:
        calls.append(out)

    scn = {"name": "s"}
    d0 = bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=2, render=fake_render)
    d1 = bench.cached_render(scn, tmp_path, resolution=(64, 48), frames=2, render=fake_render, grey=True)
    assert d0 != d1 and "grey" in d1.name and len(calls) == 2


def test_live_and_scaling_rows_keep_measured_values_out_of_their_names(tmp_path):
    """Row names are fixed text (comparable across runs); every measured value sits in a column."""
    plan = bench.make_plan(quick=True)
    b = bench.BenchRun(plan, tmp_path / "o", tmp_path / "c")
    clip = bench.Clip(tmp_path, {"cam0": tmp_path / "cam0.mkv"}, {"observer": {}}, (160, 120), 100.0, 10)
    b.clip = lambda res, rig, n=None: clip
    part = {"median_s": 0.0123, "p99_s": 0.0456}  # 12.3 ms / 45.6 ms: distinctive, and nowhere in a name
    live = {"latency": part, "decode_median_s": 0.0017, "dropped": 7, "offered": 31, "cpu_busy": 0.987,
            "loadavg_1min": [3.21, 4.56],
            "parts": {k: part for k in ("lag", "queue", "process", "write", "decode", "process_cpu", "gc")}}
    pipe = {"fps": 55.5, "observations_mean": 7.77, "tracked_features_mean": 333.3,
            "grouped_features_mean": 222.2}
    b.run = lambda task, threads, timeout_s=0: dict(live if task["kind"] == "live" else pipe)
    b.live()
    b.scaling()
    names = " | ".join(r.name for r in b.rows)
    for v in ("12.3", "45.6", "98.7", "4.56", "7.77", "7.8", "333", "222", "55.5"):
        assert v not in names
    rows = {r.name: r for r in b.rows}
    load = next(r for n, r in rows.items() if n.endswith(
        "machine load average (1 min, larger of start and end)"))
    assert load.value == pytest.approx(4.56)
    split = [r for r in b.rows if r.section.startswith("live latency split")]
    assert len(split) == 9 and all(r.extra.get("p99_ms") == pytest.approx(45.6) for r in split[:7])
    assert any(r.value == pytest.approx(7.77) for r in b.rows)  # obstacles per frame: a value, not a name
    table = bench.format_table(b.rows)
    line = next(ln for ln in table.split("\n") if "taken -> reports" in ln)
    assert "12.3 ms" in line and "45.6 ms" in line  # median and p99 in their columns


def test_live_latency_without_the_looped_clips_restarts(tmp_path):
    """A 10-frame clip looped: seq 0..29 delivered, every 3rd processed, clip positions 0 3 6 9 2 5 8 1 4 7.
    The position decreases at seq 12 (9 -> 2) and seq 21 (8 -> 1): the clip restarted there, and those
    frames and the one after each are left out."""
    csv_path = tmp_path / "latency.csv"
    seqs = list(range(0, 30, 3))  # positions 0 3 6 9 2 5 8 1 4 7: restarts before seq 12 and seq 21
    lat = {s: 0.010 for s in seqs}
    lat[12], lat[15], lat[21], lat[24] = 0.5, 0.4, 0.6, 0.3  # the cold starts after each restart
    csv_path.write_text("seq,latency_s\n" + "".join(f"{s},{lat[s]}\n" for s in seqs))
    out = bench.live_without_cuts(csv_path, 10, after=2)
    assert out["cuts"] == 2 and out["frames_left_out"] == 4
    assert out["latency"]["n"] == 6 and out["latency"]["max_s"] == pytest.approx(0.010)
    assert bench.live_without_cuts(csv_path, 10, after=0)["latency"]["max_s"] == pytest.approx(0.6)


# ------------------------------------------------------------------ --repeat: medians, spread, rounds
def test_repeat_summary_hand_worked():
    """Values 113, 93, 101 against >= 100: sorted 93 101 113, median 101, range 93-113, 2 of 3 met;
    an even count takes the mean of the two middle values; a failed repeat (None) is left out."""
    s = bench.repeat_summary([113.0, 93.0, 101.0], lambda v, i: v >= 100.0)
    assert s["median"] == 101.0 and (s["min"], s["max"]) == (93.0, 113.0) and s["n"] == 3
    assert s["values"] == [113.0, 93.0, 101.0] and s["met_each"] == [True, False, True] and s["n_met"] == 2
    s = bench.repeat_summary([4.0, None, 1.0, 3.0, 2.0])
    assert s["median"] == 2.5 and s["n"] == 4 and s["values"][1] is None and "n_met" not in s
    assert bench.repeat_summary([None])["median"] is None


def test_repeated_row_shows_median_range_and_a_marginal_verdict():
    s = bench.repeat_summary([113.0, 93.0, 101.0], lambda v, i: v >= 100.0)
    straddle = bench.Row("t", "640x480 mono, 1 core", s["median"], "fps", target=">= 100 fps", met=True,
                         extra=bench.repeat_extra(s))
    s2 = bench.repeat_summary([120.0, 125.0, 130.0], lambda v, i: v >= 100.0)
    clear = bench.Row("t", "1280x720 mono, 1 core", s2["median"], "fps", target=">= 100 fps", met=True,
                      extra=bench.repeat_extra(s2))
    text = bench.format_table([straddle, clear])
    line = next(ln for ln in text.split("\n") if "640x480" in ln)
    assert "101.0 fps" in line and "93.0-113" in line and line.rstrip().endswith("met (2/3 met: marginal)")
    line = next(ln for ln in text.split("\n") if "1280x720" in ln)
    assert "125.0 fps" in line and "120.0-130.0" in line and line.rstrip().endswith("met")
    assert "marginal" not in line


def test_a_clear_verdict_is_not_marginal_and_a_nan_round_is_a_failed_one():
    """0 of 3 rounds met: a plain MISSED (not 'marginal'); a nan round counts as failed, not as a
    round that missed: 120, nan, 125 against >= 100 is 2/2 met, median 122.5."""
    s = bench.repeat_summary([80.0, 90.0, 95.0], lambda v, i: v >= 100.0)
    miss = bench.Row("t", "640x480 mono, 1 core", s["median"], "fps", target=">= 100 fps", met=False,
                     extra=bench.repeat_extra(s))
    s2 = bench.repeat_summary([120.0, float("nan"), 125.0], lambda v, i: v >= 100.0)
    assert s2["median"] == 122.5 and s2["n_met"] == 2 and s2["values"][1] is None
    nan = bench.Row("t", "1280x720 mono, 1 core", s2["median"], "fps", target=">= 100 fps", met=True,
                    extra=bench.repeat_extra(s2))
    text = bench.format_table([miss, nan])
    line = next(ln for ln in text.split("\n") if "640x480" in ln)
    assert line.rstrip().endswith("MISSED") and "marginal" not in line
    line = next(ln for ln in text.split("\n") if "1280x720" in ln)
    assert line.rstrip().endswith("met") and "marginal" not in line


def _fake_bench(tmp_path, plan, pipe_fps, dec_fps, live_p99=None, live_dec=None):
    """A BenchRun whose measurements are scripted per (clip, round); returns it and the call log."""
    b = bench.BenchRun(plan, tmp_path / "o", tmp_path / "c")
    clips = {}

    def clip(res, rig, n=None):
        return clips.setdefault((res, rig), bench.Clip(tmp_path / f"{res[0]}{rig}",
                                                       {"cam0": tmp_path / "v.mkv"}, {"observer": {}}, res,
                                                       100.0, 10))
    b.clip = clip
    calls = []
    seen: dict = {}

    def run(task, threads, timeout_s=0):
        key = (task["kind"], task["_res"], threads)
        k = seen.get(key, 0)
        seen[key] = k + 1
        calls.append((task["kind"], task["_res"], threads, k))
        if task["kind"] == "decode":
            return {"fps": dec_fps[task["_res"]][k], "cpu_fps": dec_fps[task["_res"]][k]}
        if task["kind"] == "pipeline":
            return {"fps": pipe_fps[task["_res"]][k], "cpu_fps": pipe_fps[task["_res"]][k]}
        lat = {"median_s": 0.005, "p99_s": live_p99[task["_res"]][k]}
        return {"latency": lat, "decode_median_s": live_dec[task["_res"]][k],
                "without_cuts": {"latency": lat}}
    b.run = run
    orig_task = bench.Clip.task

    def task(self, kind, frames, **extra):
        t = orig_task(self, kind, frames, **extra)
        t["_res"] = tuple(self.resolution)
        return t
    return b, calls, task


def test_throughput_rounds_are_interleaved_and_rows_give_the_median(tmp_path, monkeypatch):
    plan = bench.BenchPlan(quick=False, resolutions=((640, 480), (1280, 720)), rigs=("mono",), threads=(1,),
                           repeat=3)
    # per round: 640 mono 113, 93, 101 fps (target 100: median 101 met, 2/3 rounds);
    # 720 mono 70, 60, 50 fps (target 60: median 60 met, 2/3) with decode 300, 240, 200 ->
    # per-round ratios 300/70 = 4.286, 240/60 = 4.0, 200/50 = 4.0: median 4.0 (target <= 2: MISSED, 0/3)
    pipe = {(640, 480): [113.0, 93.0, 101.0], (1280, 720): [70.0, 60.0, 50.0]}
    dec = {(640, 480): [500.0, 400.0, 450.0], (1280, 720): [300.0, 240.0, 200.0]}
    b, calls, task = _fake_bench(tmp_path, plan, pipe, dec)
    monkeypatch.setattr(bench.Clip, "task", task)
    b.throughput()
    # round 1 all clips, then round 2 all clips, ...; decode-only then pipeline on the same clip
    assert calls == [(kind, r, 1, k) for k in range(3) for r in ((640, 480), (1280, 720))
                     for kind in ("decode", "pipeline")]
    rows = {(r.section.split(" (")[0], r.name): r for r in b.rows}
    r = rows[("pipeline throughput", "640x480 mono, 1 core")]
    assert r.value == 101.0 and r.met is True and r.extra["repeats"] == [113.0, 93.0, 101.0]
    assert (r.extra["min"], r.extra["max"], r.extra["repeats_met"]) == (93.0, 113.0, 2)
    assert r.baseline_value == 450.0  # the decode-only median
    r = rows[("pipeline throughput", "1280x720 mono, 1 core")]
    assert r.value == 60.0 and r.met is True and r.extra["repeats_met"] == 2
    r = rows[("pipeline / decode-only", "1280x720 mono, 1 core: time per frame ratio")]
    assert r.value == pytest.approx(4.0) and r.met is False and r.extra["repeats_met"] == 0
    assert r.extra["repeats"] == pytest.approx([300 / 70, 4.0, 4.0])
    sec = b.sections["throughput"]
    # the section's representative run is the median round (101 fps: round 3); every round is kept
    assert sec[0]["median_round"] == 2 and sec[0]["pipeline"]["fps"] == 101.0 and len(sec[0]["rounds"]) == 3


def test_even_repeats_give_the_mean_value_and_the_lower_middle_round(tmp_path, monkeypatch):
    # 2 rounds 110, 90 fps: the row's value is the mean of the two, 100 (>= 100: met, 1/2 met:
    # marginal); the representative round (stage table) is the lower middle one, 90 fps: round 2
    plan = bench.BenchPlan(quick=False, resolutions=((640, 480),), rigs=("mono",), threads=(1,), repeat=2)
    b, calls, task = _fake_bench(tmp_path, plan, {(640, 480): [110.0, 90.0]}, {(640, 480): [400.0, 400.0]})
    monkeypatch.setattr(bench.Clip, "task", task)
    b.throughput()
    r = next(r for r in b.rows if r.section.startswith("pipeline throughput"))
    assert r.value == 100.0 and r.met is True and r.extra["repeats_met"] == 1
    sec = b.sections["throughput"][0]
    assert sec["median_round"] == 1 and sec["pipeline"]["fps"] == 90.0


def test_all_cores_throughput_is_taken_once(tmp_path, monkeypatch):
    plan = bench.BenchPlan(quick=False, resolutions=((640, 480),), rigs=("mono",), threads=(1, None),
                           repeat=2)
    v = {(640, 480): [100.0, 110.0]}
    b, calls, task = _fake_bench(tmp_path, plan, v, v)
    monkeypatch.setattr(bench.Clip, "task", task)
    b.throughput()
    assert [(c[0], c[2]) for c in calls] == [("decode", 1), ("pipeline", 1), ("decode", None),
                                              ("pipeline", None), ("decode", 1), ("pipeline", 1)]


def test_live_rounds_are_interleaved_and_each_p99_meets_its_own_budget(tmp_path, monkeypatch):
    plan = bench.BenchPlan(quick=False, resolutions=((640, 480), (1280, 720)), rigs=("mono",), threads=(1,),
                           repeat=3, live_all_cores=())  # the one-core rounds alone (all cores: below)
    # 720p at 60 Hz: interval 16.67 ms; decode 2, 2, 3 ms -> budgets 18.67, 18.67, 19.67 ms (median 18.67);
    # p99 17.7, 19.1, 19.0 ms: median 19.0 -> MISSED; round 1 (17.7 < 18.67) and round 3 (19.0 < 19.67)
    # met on their own budget, round 2 did not: 2/3
    p99 = {(640, 480): [0.022, 0.024, 0.023], (1280, 720): [0.0177, 0.0191, 0.0190]}
    dec = {(640, 480): [0.001] * 3, (1280, 720): [0.002, 0.002, 0.003]}
    b, calls, task = _fake_bench(tmp_path, plan, {}, {}, p99, dec)
    monkeypatch.setattr(bench.Clip, "task", task)
    b.live()
    assert calls == [("live", r, 1, k) for k in range(3) for r in ((640, 480), (1280, 720))]
    r = next(r for r in b.rows if r.name == "1280x720 mono at 60 Hz, 1 core: p99")
    assert r.value == pytest.approx(19.0) and r.met is False
    assert r.baseline_value == pytest.approx(1000 / 60 + 2.0) and r.target == "< 18.7 ms"
    assert r.extra["repeats"] == pytest.approx([17.7, 19.1, 19.0]) and r.extra["repeats_met"] == 2
    assert (r.extra["min"], r.extra["max"]) == pytest.approx((17.7, 19.1))
    assert "MISSED (2/3 met: marginal)" in bench.format_table(b.rows)
    r = next(r for r in b.rows if r.name == "640x480 mono at 100 Hz, 1 core: p99")
    assert r.value == pytest.approx(23.0) and r.met is False and r.extra["repeats_met"] == 0
    assert b.sections["live"][1]["median_round"] == 2 and len(b.sections["live"][1]["rounds"]) == 3


def test_live_all_cores_rows_are_informational_synchronous_and_deferred(tmp_path, monkeypatch):
    """Beside the one-core live rows, the full plan runs live on all cores (threads None) synchronous and
    with live.deferred_detection, in the same interleaved rounds; their rows show the budget (interval +
    decode) with the rounds under it and never met/missed (the target is defined on one core), with a
    note saying so in bench.json and the printed table; the deferred rows add the worker's CPU share, the
    detections joined and the mean join lag. The one-core rows and section are as before."""
    plan = bench.BenchPlan(quick=False, resolutions=((1280, 720),), rigs=("mono",), threads=(1,), repeat=3)
    assert plan.live_all_cores == (False, True) and bench.make_plan(False).live_all_cores == (False, True)
    b = bench.BenchRun(plan, tmp_path / "o", tmp_path / "c")
    clip = bench.Clip(tmp_path, {"cam0": tmp_path / "v.mkv"}, {"observer": {}}, (1280, 720), 60.0, 10)
    b.clip = lambda res, rig, n=None: clip
    # 60 Hz: interval 16.67 ms, decode 2 ms -> budget 18.67 ms a round; all cores p99 17, 19, 18 ms
    # (2/3 rounds under, median 18 ms under the budget: still no verdict); one core 25 ms (MISSED)
    p99 = {(1, False): [0.025] * 3, (None, False): [0.017, 0.019, 0.018], (None, True): [0.012, 0.014, 0.013]}
    calls, seen = [], {}

    def run(task, threads, timeout_s=0):
        key = (threads, bool(task.get("deferred")))
        k = seen.get(key, 0)
        seen[key] = k + 1
        calls.append(key)
        out = {"latency": {"median_s": 0.008, "p99_s": p99[key][k]}, "decode_median_s": 0.002,
               "dropped": 3, "offered": 300, "wall_s": 5.0}
        if key[1]:  # worker 1.5 s of CPU over 5 s: 30 % of a core; 12 joined, 30 frames late in all
            out["deferred"] = bench.deferred_stats(
                {"worker_nice": 10, "worker_cpu_s": 1.5, "joined": {"cam0": 12}, "frames_late": {"cam0": 30}},
                5.0)
        return out
    b.run = run
    b.live()
    assert calls == [(1, False), (None, False), (None, True)] * 3
    assert len(b.sections["live"]) == 1 and len(b.sections["live"][0]["rounds"]) == 3  # one core only
    rows = {r.name: r for r in b.rows}
    assert rows["1280x720 mono at 60 Hz, 1 core: p99"].met is False
    sync = rows["1280x720 mono at 60 Hz, all cores: p99"]
    dfr = rows["1280x720 mono at 60 Hz, all cores, deferred detection: p99"]
    assert sync.value == pytest.approx(18.0) and dfr.value == pytest.approx(13.0)
    assert sync.baseline_value == pytest.approx(1000 / 60 + 2.0)
    assert sync.target == "budget 18.7 ms: 2/3 rounds under"
    assert dfr.target == "budget 18.7 ms: 3/3 rounds under"
    assert sync.extra["rounds_under_budget"] == 2
    assert sync.extra["repeats"] == pytest.approx([17.0, 19.0, 18.0])
    info = [r for r in b.rows if r.section.startswith("live latency, all cores")]
    assert {r.name.split(": ")[1] for r in info} >= {"median", "p99", "frames dropped"}
    assert all(r.met is None and r.extra.get("informational") is True for r in info)
    assert "informational" in info[0].section and "one core" in info[0].section
    d = "1280x720 mono at 60 Hz, all cores, deferred detection: "
    assert rows[d + "detection worker's CPU share of one core"].value == pytest.approx(30.0)
    assert rows[d + "detections joined"].value == 12
    assert rows[d + "mean join lag"].value == pytest.approx(2.5)
    sync_names = [r.name for r in info if r.name.startswith("1280x720 mono at 60 Hz, all cores: ")]
    assert len(sync_names) == 3 and not any("worker" in n or "join" in n for n in sync_names)
    sec = b.sections["live_all_cores"]
    assert "one core" in sec["note"] and "met/missed" in sec["note"]
    assert [(x["deferred"], x["threads"], len(x["rounds"])) for x in sec["results"]] == [
        (False, None, 3), (True, None, 3)]
    table = bench.format_table(b.rows)
    for ln in table.split("\n"):
        if "all cores" in ln:
            assert not ln.rstrip().endswith(("met", "MISSED")) and "marginal" not in ln
    monkeypatch.setattr(bench, "machine_info", lambda probe_torch=True: {})
    text, doc = b.report()
    assert f"note: {bench.LIVE_ALL_CORES_NOTE}" in text
    assert doc["sections"]["live_all_cores"]["note"] == bench.LIVE_ALL_CORES_NOTE
    assert all(r["met"] is None for r in doc["rows"] if r["extra"].get("informational"))


def test_quick_live_adds_one_short_all_cores_deferred_run(tmp_path):
    """--quick (CI) exercises the deferred path once: one all-cores run with live.deferred_detection of
    live_frames frames beside the one-core run, whatever --repeat says."""
    plan = bench.make_plan(True, 3)
    assert plan.live_all_cores == (True,) and plan.live_frames == 20
    b = bench.BenchRun(plan, tmp_path / "o", tmp_path / "c")
    clip = bench.Clip(tmp_path, {"cam0": tmp_path / "v.mkv"}, {"observer": {}}, (160, 120), 100.0, 10)
    b.clip = lambda res, rig, n=None: clip
    calls = []

    def run(task, threads, timeout_s=0):
        calls.append((threads, task.get("deferred"), task["frames"]))
        return {"latency": {"median_s": 0.005, "p99_s": 0.009}, "decode_median_s": 0.001}
    b.run = run
    b.live()
    assert calls == [(1, None, 20), (None, True, 20), (1, None, 20), (1, None, 20)]



def test_repeat_help_says_the_quick_all_cores_live_runs_are_taken_once():
    """bench --help's --repeat: under --quick the all-cores live runs are taken once whatever N is
    (``info_rounds`` in BenchRun.live), as the test above measures."""
    import typer

    from pipeline.cli import app

    cmd = typer.main.get_command(app).commands["bench"]
    (opt,) = [p for p in cmd.params if "--repeat" in p.opts]
    text = " ".join(opt.help.split())
    assert "1 with --quick, where the all-cores live runs are taken once whatever N is" in text

def test_deferred_stats_hand_worked():
    dd = {"worker_nice": 10, "worker_cpu_s": 0.5, "joined": {"cam0": 3, "cam1": 1},
          "frames_late": {"cam0": 4, "cam1": 2}}
    s = bench.deferred_stats(dd, 2.0)
    assert s["worker_cpu_share"] == pytest.approx(0.25) and s["joined_total"] == 4
    assert s["join_lag_frames_mean"] == pytest.approx(1.5) and s["worker_nice"] == 10
    assert bench.deferred_stats(None, 2.0) is None
    s = bench.deferred_stats({"worker_cpu_s": None, "joined": {"cam0": 0}, "frames_late": {"cam0": 0}}, 2.0)
    assert s["worker_cpu_share"] is None and s["join_lag_frames_mean"] is None


@pytest.mark.skipif(not _have_pipeline(), reason="simulator / front end / run loop not importable")
def test_bench_quick_live_runs_the_deferred_schedule_on_all_cores_end_to_end(tmp_path):
    """The quick live part for real: the one-core run and the all-cores run with the detection worker
    process, whose summary gives the worker's CPU seconds."""
    from typer.testing import CliRunner

    from pipeline.cli import app

    r = CliRunner().invoke(app, ["bench", "--quick", "--only", "live", "--out", str(tmp_path / "o"),
                                 "--cache", str(tmp_path / "c")])
    assert r.exit_code == 0, r.output
    assert "all cores, deferred detection: p99" in r.output and "note: live latency on all cores" in r.output
    doc = json.loads((tmp_path / "o" / "bench.json").read_text())
    (res,) = doc["sections"]["live_all_cores"]["results"]
    x = res["result"]
    assert "error" not in x, x["error"]
    assert res["deferred"] is True and x["frames"] == 20 and x["pinning"]["requested"] is None
    d = x["deferred"]
    assert d["worker_nice"] is not None and d["worker_cpu_s"] is not None and d["worker_cpu_s"] >= 0
    s = json.loads((Path(x["latency_csv"]).parent / "summary.json").read_text())
    assert s["parameters"]["live"]["deferred_detection"] is True
    assert doc["sections"]["live"][0]["result"]["pinning"]["requested"] == 1


def test_repeat_defaults_and_bad_values():
    assert bench.make_plan(False).repeat == 3 and bench.make_plan(True).repeat == 1
    assert bench.make_plan(True, 4).repeat == 4
    for bad in (0, -1):
        with pytest.raises(ConfigError, match="repeat"):
            bench.make_plan(False, bad)
    from typer.testing import CliRunner

    from pipeline.cli import app

    r = CliRunner().invoke(app, ["bench", "--quick", "--repeat", "0", "--out", "/nonexistent/x"])
    assert r.exit_code != 0 and "repeat" in r.output
