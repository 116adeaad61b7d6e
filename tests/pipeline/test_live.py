"""Live mode without a camera: paced replay (latency, stale frames), MJPEG on loopback read back as a live
URL, reopening a stream that stops, a growing trajectory, a camera index that does not exist."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from test_conventions import documented_summary_keys
from test_run_support import FakeFrontEnd, FakeFusion, H, W, mono_rig, stereo_rig, write_video

from estimators.egomotion import ConstantVelocity
from estimators.errors import ConfigError, InputError, SourceError
from pipeline.config import load_config
from pipeline.live import (
    Grabber,
    GrowingTrajectory,
    MjpegServer,
    latency_log_stages,
    make_reader_factory,
    run_live,
)
from pipeline.run import FramePoseCache


class SlowFrontEnd(FakeFrontEnd):
    def __init__(self, rig, delay_s):
        super().__init__(rig)
        self.delay_s = delay_s

    def process(self, images, frame, t_s, T_W_B=None):
        time.sleep(self.delay_s)
        return super().process(images, frame, t_s)


def _cfg(*sets):
    return load_config(None, ["ego_motion.speed_mps=5", *sets])


def _live(tmp_path, readers, front=None, cfg=None, **kw):
    rig = mono_rig()
    return run_live(
        cfg or _cfg(),
        tmp_path / "out",
        rig=rig,
        egomotion=ConstantVelocity(5.0),
        frontend=front or FakeFrontEnd(rig),
        fusion=FakeFusion(),
        readers=readers,
        **kw,
    )


def test_paced_replay_latency_and_video_times(tmp_path):
    times = [k / 20 for k in range(10)]  # 20 frames/s, 0.45 s long
    v = write_video(tmp_path / "cam0.mkv", 10, times=times)
    t0 = time.monotonic()
    r = _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)])
    wall = time.monotonic() - t0
    assert wall >= 0.4  # real rate, not as fast as decoding
    assert r.frames + r.stale == 10 and r.frames >= 2  # stale only when this (loaded) machine stalls
    recs = [json.loads(x) for x in (tmp_path / "out" / "tracks.jsonl").read_text().splitlines()]
    for x in recs:  # a replayed file keeps its own frame indices and times
        assert x["t_s"] == pytest.approx(times[x["frame"]])
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["latency"]["n"] == r.frames and 0 <= s["latency"]["median_s"] <= s["latency"]["p99_s"] < 1.0
    undocumented = set(s) - documented_summary_keys()
    assert not undocumented, f"live summary.json keys not in docs/OUTPUTS.md: {sorted(undocumented)}"


def test_slow_pipeline_takes_newest_frame_and_counts_stale(tmp_path):
    v = write_video(tmp_path / "cam0.mkv", 12, times=[k / 30 for k in range(12)])
    rig = mono_rig()
    front = SlowFrontEnd(rig, delay_s=0.1)  # 10 frames/s against a 30 frames/s camera
    r = _live(tmp_path, [make_reader_factory(str(v), "cam0")], front=front)
    s = r.summary
    assert r.stale > 0
    assert r.frames + r.stale == s["frames_grabbed"]["cam0"] == 12  # every frame either used or dropped
    seqs = [c[0] for c in front.calls]
    assert seqs == sorted(seqs) and max(np.diff(seqs)) > 1  # skipped over stale frames


def _publisher(server, stop, period_s=0.02):
    k = 0
    while not stop.is_set():
        server.publish(np.full((H, W, 3), (8 * k) % 256, np.uint8))
        k += 1
        time.sleep(period_s)


def test_mjpeg_served_on_loopback_and_read_back_as_a_live_url(tmp_path):
    server = MjpegServer(port=0)
    stop = threading.Event()
    th = threading.Thread(target=_publisher, args=(server, stop), daemon=True)
    th.start()
    try:
        assert server.url.startswith("http://127.0.0.1:")
        r = _live(tmp_path, [make_reader_factory(server.url, "cam0", timeout_s=3.0)], max_frames=5)
    finally:
        stop.set()
        server.close()
    assert r.frames == 5
    recs = [json.loads(x) for x in (tmp_path / "out" / "tracks.jsonl").read_text().splitlines()]
    assert len(recs) == 5 and all(b["t_s"] > a["t_s"] for a, b in zip(recs, recs[1:], strict=False))


def test_stream_that_stops_is_reopened_and_the_run_goes_on(tmp_path):
    server = MjpegServer(port=0)
    port = server.port
    stop = threading.Event()
    threading.Thread(target=_publisher, args=(server, stop), daemon=True).start()
    state = {}

    def on_frame(n, info):
        if n == 3 and "restarted" not in state:  # the camera goes away for 0.3 s, then comes back
            stop.set()
            server.close()
            time.sleep(0.3)
            state["server"] = MjpegServer(port=port)
            state["stop"] = threading.Event()
            threading.Thread(target=_publisher, args=(state["server"], state["stop"]), daemon=True).start()
            state["restarted"] = True

    cfg = _cfg(
        "live.reconnect_initial_s=0.05",
        "live.reconnect_max_s=0.2",
        "live.stall_timeout_s=0.5",
        "live.duration_s=20",
    )
    try:
        r = _live(
            tmp_path,
            [make_reader_factory(server.url, "cam0", timeout_s=1.0)],
            cfg=cfg,
            max_frames=8,
            on_frame=on_frame,
        )
    finally:
        stop.set()
        if "server" in state:
            state["stop"].set()
            state["server"].close()
    assert r.frames == 8
    assert r.summary["reopened"]["cam0"] >= 1


def test_mjpeg_preview_of_the_annotated_frames(tmp_path):
    import urllib.request

    v = write_video(tmp_path / "cam0.mkv", 20, times=[k / 20 for k in range(20)])
    urls = []
    got = {}

    def on_frame(n, info):
        if n == 3:
            with urllib.request.urlopen(urls[0].replace("/stream.mjpg", "/frame.jpg"), timeout=2) as resp:
                got["type"] = resp.headers["Content-Type"]
                got["jpeg"] = resp.read()

    cfg = _cfg("live.preview=mjpeg", "live.preview_port=0")
    _live(
        tmp_path,
        [make_reader_factory(str(v), "cam0")],
        cfg=cfg,
        on_frame=on_frame,
        on_event=lambda m: urls.append(m.split("MJPEG stream ")[1].rstrip(")")),
    )
    assert urls[0].startswith("http://127.0.0.1:")
    assert got["type"] == "image/jpeg" and got["jpeg"][:2] == b"\xff\xd8"


def test_growing_trajectory_is_reread_when_time_passes_its_end(tmp_path):
    p = tmp_path / "t.tum"
    p.write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    g = GrowingTrajectory(p)
    assert g.covers(0.5) and not g.covers(1.5)
    assert g.pose_at(0.5).t == pytest.approx([0.5, 0, 0])
    with p.open("a") as f:
        f.write("2.0 3 0 0 0 0 0 1\n3.0 4 0")  # the last line is still being written
    assert g.covers(1.5) and not g.covers(2.5)
    assert g.pose_at(1.5).t == pytest.approx([2.0, 0, 0])
    assert g.velocity_at(1.5) == pytest.approx([2.0, 0, 0])


def test_a_growing_trajectory_read_at_frame_times_takes_its_ends_within_half_a_millisecond(tmp_path):
    """As a file trajectory (pipeline.run.ClockOffset): a frame time within EDGE_S of the span's ends
    takes the end's pose (rounded frame times); one with no pose yet in the file is still not covered."""
    from pipeline.run import EDGE_S, ClockOffset

    p = tmp_path / "t.tum"
    p.write_text("10.0 0 0 0 0 0 0 1\n11.0 1 0 0 0 0 0 1\n")
    g = ClockOffset(GrowingTrajectory(p), 10.0)
    assert g.start_s == 0.0 and g.covers(1.0 + 0.8 * EDGE_S) and g.covers(-0.8 * EDGE_S)
    assert g.pose_at(1.0 + 0.8 * EDGE_S).t == pytest.approx([1.0, 0, 0])
    assert not g.covers(1.0 + 1.2 * EDGE_S) and not g.covers(-1.2 * EDGE_S)
    assert ClockOffset(GrowingTrajectory(tmp_path / "none.tum")).start_s is None  # no poses yet


@pytest.mark.parametrize(
    ("bad", "problem"),
    [
        ("1 1 0 0 0 0 0 0", "has a zero quaternion"),
        ("1 1 0 0 nan 0 0 1", "NaN or infinite value"),
        ("1 1 0 0 0 0 1", "expected 8 numbers"),
        ("1 1 0 x 0 0 0 1", "not a number"),
    ],
)
def test_growing_trajectory_errors_name_the_files_line_as_tum_load_does(tmp_path, bad, problem):
    from estimators.egomotion import TumTrajectory

    p = tmp_path / "zq.tum"
    p.write_text(f"# h\n0 0 0 0 0 0 0 1\n{bad}\n")
    with pytest.raises(InputError) as grown:
        GrowingTrajectory(p)
    with pytest.raises(InputError) as loaded:
        TumTrajectory.load(p)
    assert str(grown.value).startswith(f"{p}:3: {problem}")
    assert str(grown.value) == str(loaded.value)


def test_camera_index_that_does_not_exist(tmp_path):
    with pytest.raises(SourceError, match="camera index 97: cannot be opened"):
        _live(tmp_path, [make_reader_factory(97, "cam0")])


def test_cli_live_replays_a_video_with_stub_stages(tmp_path, monkeypatch, capsys):
    from pipeline import live as live_mod
    from pipeline.cli import main

    monkeypatch.setattr(live_mod, "build_rig", lambda cfg: mono_rig())
    monkeypatch.setattr(live_mod, "build_frontend", lambda cfg, rig: FakeFrontEnd(rig))
    monkeypatch.setattr(live_mod, "build_fusion", lambda cfg, rig, ego: FakeFusion())
    v = write_video(tmp_path / "cam0.mkv", 6, times=[k / 30 for k in range(6)])
    rc = main(
        ["live", "--camera", str(v), "--speed-mps", "2", "--out", str(tmp_path / "o"), "--preview", "file"]
    )
    assert rc == 0
    lines = len((tmp_path / "o" / "tracks.jsonl").read_text().splitlines())
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    # every frame of the video is either processed (one line, one latency sample) or dropped as stale
    # (replaced by a newer one while the loop was busy: on a loaded machine that happens to 1-2 of the
    # 6 frames paced at 30 Hz), never lost
    dropped = s["stale_frames_dropped"]["cam0"]
    assert lines >= 1 and lines + dropped == 6
    assert s["mode"] == "live" and s["latency"]["n"] == lines and (tmp_path / "o" / "preview.mp4").is_file()
    assert "latency median" in capsys.readouterr().err


@pytest.mark.parametrize("offset_s", [0.0, 50.0])
def test_live_with_a_trajectory_file_that_grows(tmp_path, monkeypatch, offset_s):
    """Poses arrive while the run goes: frames wait for them (bounded) and fusion sees the right pose;
    also from a file stamped on another clock (ego_motion.time_offset_s: frame time + 50 s)."""
    from pipeline import live as live_mod

    traj = tmp_path / "live.tum"
    traj.write_text(f"{offset_s:.2f} 0 0 0 0 0 0 1\n{0.1 + offset_s:.2f} 0.1 0 0 0 0 0 1\n")  # x = t (1 m/s)

    def writer():
        for k in range(2, 11):
            time.sleep(0.05)
            with traj.open("a") as f:
                f.write(f"{k / 10 + offset_s:.2f} {k / 10:.2f} 0 0 0 0 0 1\n")

    class PoseRecordingFusion(FakeFusion):
        def __init__(self, ego):
            super().__init__()
            self.ego, self.x = ego, []

        def step(self, observations, frame, t_s):
            self.x.append((t_s, float(self.ego.pose_at(t_s).t[0])))
            return super().step(observations, frame, t_s)

    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    cfg = load_config(None, ["live.trajectory_wait_s=1.0", f"ego_motion.time_offset_s={offset_s}"],
                      cli={"ego_motion.trajectory": str(traj)})
    rig = mono_rig()
    made = []
    monkeypatch.setattr(
        live_mod, "build_fusion", lambda cfg, rig, ego: made.append(PoseRecordingFusion(ego)) or made[0]
    )
    th = threading.Thread(target=writer, daemon=True)
    th.start()
    r = run_live(
        cfg,
        tmp_path / "out",
        rig=rig,
        frontend=FakeFrontEnd(rig),
        readers=[make_reader_factory(str(v), "cam0")],
    )
    th.join()
    fusion = made[0]
    ego = fusion.ego
    # live mode re-reads a trajectory file as it grows (behind the one-pose-per-frame cache)
    growing = ego.inner.inner  # (read at frame times: ClockOffset)
    assert isinstance(ego, FramePoseCache) and isinstance(growing, GrowingTrajectory)
    assert r.summary["frames_without_pose"] == 0 and r.frames >= 5
    assert growing.reloads >= 2
    for t_s, x in fusion.x:
        assert x == pytest.approx(t_s)  # x = 1 m/s * t in the file


class ShapeFrontEnd(FakeFrontEnd):
    """Records the shape of every image it is given."""

    def __init__(self, rig):
        super().__init__(rig)
        self.shapes = []

    def process(self, images, frame, t_s, T_W_B=None):
        self.shapes += [v.shape for v in images.values()]
        return super().process(images, frame, t_s)


def test_live_feeds_a_grey_detector_grey_frames_as_run_does(tmp_path):
    """The orb detector works on grey images: live decodes to (H, W) as `run` does (colour for navlights)."""
    v = write_video(tmp_path / "cam0.mkv", 6, times=[k / 30 for k in range(6)])
    rig = mono_rig()
    for name, want in (("orb", (H, W)), ("navlights", (H, W, 3))):
        front = ShapeFrontEnd(rig)
        cfg = _cfg(f"live.cameras=['{v}']", f"detector.name={name}", "live.paced=false")
        run_live(
            cfg,
            tmp_path / name,
            rig=rig,
            egomotion=ConstantVelocity(5.0),
            frontend=front,
            fusion=FakeFusion(),
        )
        assert front.shapes and set(front.shapes) == {want}, name


class LateReader:
    """A replay that publishes each frame 0.3 s after it was due (a camera emulation falling behind)."""

    ends = True

    def __init__(self, n=3):
        self.n = n
        self.arrival_s = None

    def read(self):
        if self.n == 0:
            return None, None
        self.n -= 1
        time.sleep(0.05)
        self.arrival_s = time.monotonic() - 0.3
        return np.zeros((H, W), np.uint8), 1.0 - 0.1 * self.n

    def close(self):
        pass


def test_a_replay_behind_schedule_shows_as_latency_not_as_a_late_arrival(tmp_path):
    r = _live(tmp_path, [LateReader])
    s = r.summary
    assert r.frames >= 1
    assert s["latency"]["median_s"] >= 0.3  # from when the frame was due, not when it was published
    assert s["replay_lag"]["cam0"]["median_s"] >= 0.3
    # the split adds up: waited (arrival -> taken) + processing (taken -> line written)
    assert s["latency_waited"]["median_s"] >= 0.3 and s["latency_processing"]["n"] == r.frames


def _stereo_live(tmp_path, name, readers, front=None):
    rig = stereo_rig()
    front = front or FakeFrontEnd(rig)
    r = run_live(
        _cfg(),
        tmp_path / name,
        rig=rig,
        egomotion=ConstantVelocity(5.0),
        frontend=front,
        fusion=FakeFusion(),
        readers=readers,
    )
    return r, front


def test_stereo_live_pairs_the_cameras_frames_by_time(tmp_path):
    """Each camera's frame of the same instant goes in together (frame k of both videos has grey level
    4k); a camera whose times never come within live.sync_tolerance_s is left out and counted."""
    times = [k / 20 for k in range(12)]
    v0 = write_video(tmp_path / "cam0.mkv", 12, times=times)
    v1 = write_video(tmp_path / "cam1.mkv", 12, times=times)
    v2 = write_video(tmp_path / "far" / "cam1.mkv", 12, times=[t + 0.5 for t in times])
    for other, paired in ((v1, True), (v2, False)):
        readers = [make_reader_factory(str(v0), "cam0"), make_reader_factory(str(other), "cam1")]
        r, front = _stereo_live(tmp_path, f"out_{paired}", readers)
        assert r.frames >= 2 and r.frames + r.summary["stale_frames_dropped"]["cam0"] == 12
        missed = r.summary["frames_without_partner"]["cam1"]
        if paired:
            with_both = [c[2] for c in front.calls if "cam1" in c[2]]
            # the partner is waited for (frame time), so none is missed, however loaded the machine
            assert missed == 0 and len(with_both) == r.frames
            assert all(im["cam0"] == im["cam1"] for im in with_both)  # the same frame index
        else:
            assert missed == r.frames and all(set(c[2]) == {"cam0"} for c in front.calls)


def test_stereo_live_pairs_when_one_camera_opens_late(tmp_path):
    """The second camera takes 0.15 s (3 frame intervals, >> live.sync_tolerance_s) longer to open:
    the replays share one schedule start and pairing is in frame time, so every frame is paired."""
    times = [k / 20 for k in range(12)]
    v0 = write_video(tmp_path / "cam0.mkv", 12, times=times)
    v1 = write_video(tmp_path / "cam1.mkv", 12, times=times)
    open1 = make_reader_factory(str(v1), "cam1")

    def slow_open():
        time.sleep(0.15)
        return open1()

    r, front = _stereo_live(tmp_path, "out", [make_reader_factory(str(v0), "cam0"), slow_open])
    assert r.frames >= 2
    assert r.summary["frames_without_partner"]["cam1"] == 0
    assert all(set(c[2]) == {"cam0", "cam1"} and c[2]["cam0"] == c[2]["cam1"] for c in front.calls)


class FakeClock:
    """A clock that moves only when told (s)."""

    def __init__(self, t=100.0):
        self.t = t

    def __call__(self):
        return self.t


def _grabber(clock, stall_timeout_s=2.0):
    return Grabber(lambda: None, "cam1", stall_timeout_s=stall_timeout_s, clock=clock)  # not started


def _img():
    return np.zeros((H, W), np.uint8)


def test_nearest_waits_on_the_injected_clock_for_the_partner_frame_not_the_tolerance():
    """The partner of frame time 0.05 s arrives 0.3 s (wall) after it is asked for, far beyond the
    0.02 s sync tolerance: the wait is bounded on the grabber's clock (which stands still here), so
    the partner is found; its 0.05 s frame time pairs it."""
    clock = FakeClock()
    g = _grabber(clock)
    g._publish(_img(), 0.0)
    threading.Timer(0.3, lambda: g._publish(_img(), 0.05)).start()
    f = g.nearest(0.05, tolerance_s=0.02)
    assert f is not None and f.t_s == pytest.approx(0.05) and f.seq == 1


def test_nearest_waits_at_most_its_bound_and_pairs_by_frame_time():
    clock = FakeClock()
    g = _grabber(clock)
    for k in range(3):  # frames every 0.05 s: waits at most 2 intervals + slack = 0.2 s on the clock
        g._publish(_img(), 0.05 * k)

    def advance():  # the clock passes the bound; no partner comes
        time.sleep(0.2)
        clock.t += 0.25

    threading.Thread(target=advance, daemon=True).start()
    t0 = time.monotonic()
    assert g.nearest(0.15, tolerance_s=0.02) is None  # nearest is 0.10: 0.05 away in frame time
    assert time.monotonic() - t0 < 5.0  # returned once the injected clock passed the bound
    assert clock.t == pytest.approx(100.25)  # ... and not before
    assert g.nearest(0.09, tolerance_s=0.02).t_s == pytest.approx(0.10)  # a frame after: no wait
    clock.t += 10.0  # nothing published for > stall_timeout_s: a stopped camera is not waited for
    t0 = time.monotonic()
    assert g.nearest(0.5, tolerance_s=0.02) is None and time.monotonic() - t0 < 0.5


def test_latency_parts_add_up_per_frame_and_name_where_the_time_went(tmp_path):
    """A replay 0.3 s behind its schedule (lag) feeding a pipeline that takes 0.1 s a frame (process):
    the per-frame CSV's parts add up to the latency, lag ~0.3 s, process >= 0.1 s, and the summary
    carries the same parts and the drop rate."""
    rig = mono_rig()
    log = tmp_path / "latency.csv"
    r = _live(tmp_path, [lambda: LateReader(4)], front=SlowFrontEnd(rig, delay_s=0.1), latency_log=log)
    rows = log.read_text().splitlines()
    assert rows[0] == ("seq,t_s,latency_s,lag_s,queue_s,process_s,write_s,decode_s,process_cpu_s,gc_s,"
                       "resize_s,detect_s,track_s,group_s,associate_s,report_s,estimate_s,fuse_s")
    assert len(rows) == 1 + r.frames and r.frames >= 1
    for row in rows[1:]:
        lat, lag, queue, proc, write = (float(x) for x in row.split(",")[2:7])
        assert lag + queue + proc + write == pytest.approx(lat, abs=1e-5)
        assert lag >= 0.3 - 1e-3 and proc >= 0.1 and queue >= 0 and write >= 0
        cpu, gc_s = (float(x) for x in row.split(",")[8:10])
        assert 0 <= cpu < 0.05 and 0 <= gc_s <= proc + write  # the 0.1 s of process is a sleep, not CPU
    s = r.summary
    assert s["latency_parts"]["process"]["n"] == r.frames and s["latency_parts"]["lag"]["median_s"] >= 0.299
    assert s["drop_rate"]["cam0"] == pytest.approx(r.stale / s["frames_grabbed"]["cam0"])


class DetectEveryOtherFrame(FakeFrontEnd):
    """A front end that reports a 20 ms detect stage on its odd calls and 1 ms on its even ones, a track
    stage always and no resize or report stage (as a periodic ORB detection shows in the real one)."""

    def process(self, images, frame, t_s, T_W_B=None):
        self.timings = {"detect": 0.020 if len(self.calls) % 2 else 0.001, "track": 0.004,
                        "group": 0.0005, "associate": 0.0}
        return super().process(images, frame, t_s)


def test_latency_log_gives_each_frames_stage_times(tmp_path):
    """The per-frame CSV carries the frame's own stage times beside its latency parts: detect 0.001 s
    on the 1st, 3rd ... processed frame and 0.020 s on the 2nd, 4th ... (as the front end reported
    them for that frame), track 0.004, associate 0 written as 0, fusion's estimate and fuse 1e-4, and
    the stages the front end did not report (resize, report) empty."""
    rig = mono_rig()
    log = tmp_path / "latency.csv"
    r = _live(tmp_path, [lambda: LateReader(4)], front=DetectEveryOtherFrame(rig), latency_log=log)
    assert latency_log_stages() == ("resize", "detect", "track", "group", "associate", "report",
                                    "estimate", "fuse")
    rows = log.read_text().splitlines()
    head = rows[0].split(",")
    assert r.frames >= 2 and len(rows) == 1 + r.frames
    for k, row in enumerate(rows[1:]):
        cell = dict(zip(head, row.split(","), strict=True))
        assert float(cell["detect_s"]) == pytest.approx(0.020 if k % 2 else 0.001)
        assert float(cell["track_s"]) == pytest.approx(0.004)
        assert float(cell["group_s"]) == pytest.approx(5e-4)
        assert cell["associate_s"] == "0.000000" and cell["resize_s"] == "" and cell["report_s"] == ""
        assert float(cell["estimate_s"]) == pytest.approx(1e-4)
        assert float(cell["fuse_s"]) == pytest.approx(1e-4)


def test_the_latency_logs_stages_are_those_the_real_stages_report():
    """The CSV's stage columns are exactly the stages the real front end and fusion give each frame
    (in that order), so no stage's time is left out of a row and no column is always empty."""
    from estimators.fusion import ObstacleFusion
    from trackers.frontend import FrontEnd

    rig = mono_rig()
    front = FrontEnd(rig)
    fusion = ObstacleFusion(rig, ConstantVelocity(5.0))
    fusion.step(front.process({"cam0": np.zeros((H, W, 3), np.uint8)}, 0, 0.0), 0, 0.0)
    assert latency_log_stages() == (*front.timings, *fusion.timings)


def test_replay_reports_each_frames_decode_time(tmp_path):
    v = write_video(tmp_path / "cam0.mkv", 6, times=[k / 30 for k in range(6)])
    r = _live(tmp_path, [make_reader_factory(str(v), "cam0")])
    dec = r.summary["latency_parts"]["decode"]
    assert dec["n"] == r.frames and 0 < dec["median_s"] < 0.5


def test_an_unwritable_latency_log_fails_before_any_camera_is_opened(tmp_path):
    """latency_log in a folder that does not exist: an InputError naming it, raised before a camera
    is opened (before, the grabbers were already reading when the open failed, and nothing stopped
    them or closed the cameras)."""
    opened, closed, stop = [], [], threading.Event()

    class EndlessReader:
        ends = True

        def __init__(self):
            opened.append(self)

        def read(self):
            if stop.is_set():
                return None, None
            time.sleep(0.01)
            return np.zeros((H, W), np.uint8), None

        def close(self):
            closed.append(self)

    bad = tmp_path / "no" / "such" / "dir" / "latency.csv"
    try:
        with pytest.raises(InputError, match="latency_log"):
            _live(tmp_path, [EndlessReader], latency_log=bad)
        assert len(closed) == len(opened)  # no camera left open (none opened at all)
    finally:
        stop.set()  # let a grabber that was left running end


def test_live_loop_runs_with_the_set_up_objects_frozen_for_the_collector(tmp_path):
    import gc

    counts = []

    class Probe(FakeFrontEnd):
        def process(self, images, frame, t_s, T_W_B=None):
            counts.append(gc.get_freeze_count())
            return super().process(images, frame, t_s)

    v = write_video(tmp_path / "cam0.mkv", 6, times=[k / 50 for k in range(6)])
    r = _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)], front=Probe(mono_rig()))
    assert r.frames >= 1 and len(counts) == r.frames
    assert min(counts) > 10_000  # modules, rig, front end: frozen before the first frame
    assert gc.get_freeze_count() == 0


# ------------------------------------------------------------------ frames the loop will not take
def test_wanted_is_false_only_when_the_loop_is_busy_past_the_next_frame():
    clock = FakeClock()
    g = _grabber(clock)
    assert g.wanted()  # nothing known yet
    for _ in range(5):  # grabs every 10 ms
        g._grab_s.append(clock.t)
        clock.t += 0.010
    assert g.wanted()  # the loop has not said when it will be ready
    g.expect_ready(clock.t + 0.030)  # busy for three more frame intervals: a newer frame comes first
    assert not g.wanted()
    g.expect_ready(clock.t + 0.0105)  # ready within 1.1 intervals (arrival jitter): this is its frame
    assert g.wanted()
    g.expect_ready(clock.t - 0.005)  # overdue: wanted
    assert g.wanted()
    g.expect_ready(clock.t + 0.030)
    g.take(timeout_s=0.0)  # the loop waits for a frame: any frame is wanted
    assert g.wanted()


class FakeCam:
    """A camera at ``rate_hz``: ``grab`` waits for the next frame; ``retrieve`` (the decode) is counted."""

    def __init__(self, n, rate_hz):
        self.n, self.period, self.k, self.retrieved = n, 1.0 / rate_hz, 0, []
        self.t0 = time.monotonic()

    def grab(self):
        if self.k >= self.n:
            time.sleep(0.01)
            return False
        wait = self.t0 + self.k * self.period - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        self.k += 1
        return True

    def retrieve(self):
        self.retrieved.append(self.k - 1)
        return True, np.full((H, W), (self.k - 1) % 256, np.uint8)

    def release(self):
        pass


def _fake_camera_reader(cam):
    from pipeline.live import CaptureReader

    r = CaptureReader.__new__(CaptureReader)  # a camera without the device: its capture is the fake
    r.ref, r.grey, r.cap, r.wanted = 0, False, cam, None
    return r


def test_capture_reader_does_not_decode_an_unwanted_frame():
    from pipeline.live import SKIPPED

    cam = FakeCam(3, 1000.0)
    r = _fake_camera_reader(cam)
    img, _ = r.read()
    assert img is not SKIPPED and cam.retrieved == [0]
    r.wanted = lambda: False
    img, _ = r.read()
    assert img is SKIPPED and cam.retrieved == [0] and cam.k == 2  # grabbed (the queue moved), not decoded


def test_camera_frames_the_busy_loop_will_not_take_are_dropped_without_decoding(tmp_path, monkeypatch):
    """A 100 Hz camera and a 40 ms pipeline: most frames arrive while the loop is busy for several more
    intervals; they are grabbed but not decoded, and counted as dropped. Every processed frame was
    decoded, and each was the newest frame when the loop took it: no camera frame that had arrived
    (grabbed, then decoded or dropped by the grabber) before the loop asked for a frame is newer than
    the one it got. The camera's frames carry their index in their pixels; an event log, appended in
    order from both threads, records each arrival and each take."""
    from pipeline.live import Grabber

    cam = FakeCam(60, 100.0)
    events: list[tuple[str, int]] = []  # ("arrived", camera frame) / ("take", -1) / ("taken", frame)
    publish, skip, take = Grabber._publish, Grabber._skip, Grabber.take

    def logged_publish(self, *a, **k):
        publish(self, *a, **k)
        events.append(("arrived", cam.k - 1))  # the grabber thread: cam.k is the frame just grabbed

    def logged_skip(self):
        skip(self)
        events.append(("arrived", cam.k - 1))

    def logged_take(self, timeout_s):
        events.append(("take", -1))
        f = take(self, timeout_s)
        if f is not None:
            events.append(("taken", int(f.image[0, 0])))
        return f

    monkeypatch.setattr(Grabber, "_publish", logged_publish)
    monkeypatch.setattr(Grabber, "_skip", logged_skip)
    monkeypatch.setattr(Grabber, "take", logged_take)
    rig = mono_rig()
    front = SlowFrontEnd(rig, delay_s=0.04)
    r = _live(tmp_path, [lambda: _fake_camera_reader(cam)], front=front, max_frames=8)
    s = r.summary
    assert r.frames == 8
    skipped = s["frames_not_decoded"]["cam0"]
    assert skipped > 0 and skipped <= s["stale_frames_dropped"]["cam0"]
    assert s["frames_grabbed"]["cam0"] == len(cam.retrieved) + skipped  # every grabbed frame: decoded or not
    newest, checked = -1, 0
    for i, (kind, k) in enumerate(events):
        if kind == "arrived":
            newest = max(newest, k)
        elif kind == "take" and i + 1 < len(events):
            got = next((k2 for kind2, k2 in events[i + 1:] if kind2 == "taken"), None)
            if got is not None:
                assert got >= newest, f"took frame {got} when frame {newest} had already arrived"
                assert got in cam.retrieved  # decoded
                checked += 1
    assert checked >= 8
    assert newest > 8  # frames arrived while the loop was busy (the check above was not vacuous)


def test_latency_log_counts_a_garbage_collection_in_the_frame_it_stopped(tmp_path):
    """A front end that forces a full collection on its second frame: that frame's gc_s is the time
    the collection took (> 0), the first frame's is not larger than it."""
    import gc

    class Collecting(FakeFrontEnd):
        n = 0

        def process(self, images, frame, t_s, T_W_B=None):
            Collecting.n += 1
            if Collecting.n == 2:
                gc.collect()
            return super().process(images, frame, t_s)

    log = tmp_path / "latency.csv"
    r = _live(tmp_path, [lambda: LateReader(3)], front=Collecting(mono_rig()), latency_log=log)
    assert r.frames >= 2
    gc_s = [float(row.split(",")[9]) for row in log.read_text().splitlines()[1:]]
    assert gc_s[1] > 0 and gc_s[1] >= gc_s[0]
    assert r.summary["latency_parts"]["gc"]["max_s"] == pytest.approx(max(gc_s), abs=1e-6)


def test_a_paced_replay_decodes_each_frame_just_before_it_is_due_not_right_after_the_last():
    """Frames every 0.1 s, each decode 0.01 s (on a fake clock). From the third frame on (two due times
    give the interval, one decode its time) frame k's decode starts at due_k - (DECODE_LEAD * 0.01 +
    DECODE_LEAD_SLACK_S) = due_k - 0.017 s, not at due_(k-1) when frame k-1 was handed over; every
    frame is still handed over at its due time (arrival = due)."""
    from pipeline.live import DECODE_LEAD, DECODE_LEAD_SLACK_S, SourceReader
    from pipeline.sources import Frame, PacedSource, Source

    now = [100.0]
    starts: list[float] = []

    class Decoding(Source):
        camera = "cam0"

        def __iter__(self):
            for k in range(5):
                starts.append(now[0])
                now[0] += 0.01  # the decode
                yield Frame(k, 0.1 * k, "cam0", np.zeros((2, 2), np.uint8))

    def sleep(dt):
        now[0] += dt

    rd = SourceReader(PacedSource(Decoding(), clock=lambda: now[0], sleep=sleep))
    rd.set_start(100.05)  # the schedule starts 0.05 s after the clock's now
    arrivals = []
    while True:
        img, _t = rd.read()
        if img is None:
            break
        arrivals.append(rd.arrival_s)
        assert now[0] == pytest.approx(rd.arrival_s)  # handed over at its due time, not later
    due = [100.05 + 0.1 * k for k in range(5)]
    assert arrivals == pytest.approx(due)
    lead = DECODE_LEAD * 0.01 + DECODE_LEAD_SLACK_S
    assert lead == pytest.approx(0.017)
    assert starts[:2] == pytest.approx([100.0, 100.05])  # no interval known yet: at once
    assert starts[2:] == pytest.approx([d - 0.017 for d in due[2:]])


class DeferringFrontEnd(FakeFrontEnd):
    """Takes the live run's detection worker and runs a job on it: ``job`` submitted at the first frame,
    its result taken at the third (a job that raises stops the run there)."""

    def __init__(self, rig, job=(abs, -3)):
        super().__init__(rig)
        self.executors: list = []
        self.job = job
        self.result = None

    def defer_detection(self, executor):
        self.executors.append(executor)

    def process(self, images, frame, t_s, T_W_B=None):
        if len(self.calls) == 0:
            self.fut = self.executors[-1].submit(*self.job)
        if len(self.calls) == 2:
            self.result = self.fut.result()
        return super().process(images, frame, t_s)


def _no_worker_left():
    import multiprocessing

    return not multiprocessing.active_children()


def test_the_live_run_detects_in_a_worker_process_at_its_nice_that_ends_with_the_run(tmp_path):
    """live.deferred_detection true (opt-in): the front end gets a worker process (spawned and started
    before the grabbers, at live.detection_nice), which runs jobs beside the frames and is gone when the run
    ends; the front end is set back to detecting in its frames. Off (the default): no worker."""
    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    front = DeferringFrontEnd(mono_rig())
    r = _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)], front=front,
              cfg=_cfg("live.deferred_detection=true"))
    assert r.frames >= 3 and front.result == 3
    worker, reset = front.executors
    assert reset is None and _no_worker_left()
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["deferred_detection"]["worker_nice"] == worker.nice >= 10
    front = FakeFrontEnd(mono_rig())
    front.defer_detection = lambda ex: pytest.fail("no worker by default (live.deferred_detection false)")
    _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=False)], front=front)
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["deferred_detection"] is None


def test_the_live_summary_reports_the_detection_workers_cpu_seconds_over_the_loop(tmp_path):
    """summary.json's deferred_detection.worker_cpu_s: the worker process's CPU seconds (from
    /proc/<pid>/stat) between loop start and end, so a user sees what the second core costs; a job that
    burns CPU in the worker shows in it, the worker's start-up (spawn, imports) does not."""
    if not Path("/proc/self/stat").is_file():
        pytest.skip("needs /proc (Linux)")
    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    front = DeferringFrontEnd(mono_rig(), job=(sum, range(20_000_000)))  # ~0.2-1 s of one core
    _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)], front=front,
          cfg=_cfg("live.deferred_detection=true"))
    assert front.result == sum(range(20_000_000))
    cpu = json.loads((tmp_path / "out" / "summary.json").read_text())["deferred_detection"]["worker_cpu_s"]
    t0 = time.process_time()
    sum(range(20_000_000))
    here = time.process_time() - t0  # the same job in this process
    assert 0.5 * here <= cpu <= 2.0 * here + 0.3


def test_process_cpu_s_reads_a_process_cpu_time_from_proc():
    """process_cpu_s(pid): user + system seconds from /proc/<pid>/stat, as os.times() counts them for this
    process; None for no pid or a process that does not exist."""
    if not Path("/proc/self/stat").is_file():
        pytest.skip("needs /proc (Linux)")
    import os

    from pipeline.live import process_cpu_s

    sum(range(5_000_000))
    t = os.times()
    assert process_cpu_s(os.getpid()) == pytest.approx(t.user + t.system, abs=0.05)
    assert process_cpu_s(None) is None
    assert process_cpu_s(2**22 + 12345) is None  # above Linux's pid_max


def test_a_failing_detection_job_stops_the_live_run_with_its_error_and_no_worker_left(tmp_path):
    """The worker's error reaches the loop (the frame that takes the job's result) and ends the run with
    it, outputs written and the worker process gone, not a hang."""
    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    front = DeferringFrontEnd(mono_rig(), job=(int, "not a number"))
    with pytest.raises(ValueError, match="not a number"):
        _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)], front=front,
              cfg=_cfg("live.deferred_detection=true"))
    assert _no_worker_left() and front.executors[-1] is None
    assert (tmp_path / "out" / "summary.json").is_file()


def test_a_feature_tracker_detects_through_the_worker_process_as_in_its_frame():
    """The worker process (the detector and the tracker's settings pickled to it) finds what the tracker
    finds in its own frame: on a still scene the features that join equal, in number and place, those of
    the synchronous schedule's first frame (ORB is deterministic; KLT on a still scene moves them by far
    less than a pixel)."""
    import itertools

    from estimators.rig import Camera, forward_T_C_B
    from pipeline.live import detection_worker
    from tests.trackers.conftest import SphereScene, equidistant
    from trackers.detectors import make_detector
    from trackers.features import FeatureTracker

    model = equidistant()
    grey = SphereScene(model).render()

    def tracker():
        cam = Camera("cam0", model, forward_T_C_B())
        return FeatureTracker(cam, make_detector("orb", max_features=400), ids=itertools.count(1))

    sync = tracker().track(grey, 0, 0.0)[0]
    ft = tracker()
    ex = detection_worker(None)
    try:
        ft.defer_detection(ex)
        k = 0
        while not len(ft.features()) and k < 400:
            ft.track(grey, k, k / 30)
            k += 1
            time.sleep(0.01)
    finally:
        ft.defer_detection(None)
        ex.shutdown()
    got = ft.features()
    assert ft.deferred["joined"] >= 1 and k >= 2  # (joined from the worker, not detected in frame 0)
    assert len(got) == len(sync) > 100
    np.testing.assert_allclose(got.uv, sync.uv, atol=0.05)


class RefusingFrontEnd(FakeFrontEnd):
    """A front end whose trackers cannot take the worker (``FeatureTracker.defer_detection``'s set-up error:
    a detector that does not pickle)."""

    def defer_detection(self, executor):
        if executor is not None:
            raise RuntimeError("FeatureTracker 'cam0': the detection worker cannot take its detector")


def _grabbing_threads():
    return [t for t in threading.enumerate() if t.name.startswith("grab-") and t.is_alive()]


def test_a_set_up_error_after_the_worker_started_leaves_no_worker_camera_or_thread(tmp_path):
    """A step of the set-up that fails once the worker process runs (a detector the worker cannot take; a
    preview port in use, after the grabbers started) ends the run with its error and stops what the set-up
    had started: no worker process, no camera reader open, no grabber thread."""
    import socket

    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    closed = []

    def factory():
        r = make_reader_factory(str(v), "cam0", paced=True)()
        close = r.close
        r.close = lambda: (closed.append(1), close())[1]
        return r

    with pytest.raises(RuntimeError, match="cannot take"):
        _live(tmp_path, [factory], front=RefusingFrontEnd(mono_rig()),
              cfg=_cfg("live.deferred_detection=true"))
    assert _no_worker_left() and closed == [1]
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        with pytest.raises(ConfigError, match="live.preview_port .*in use"):
            _live(tmp_path, [factory], front=DeferringFrontEnd(mono_rig()),
                  cfg=_cfg("live.deferred_detection=true", "live.preview=mjpeg", f"live.preview_port={port}"))
    assert _no_worker_left() and not _grabbing_threads() and len(closed) == 2


def test_the_detection_worker_ignores_ctrl_c_and_sigterm_and_ends_with_its_run_process():
    """Ctrl-C reaches the whole process group, and so may a supervisor's SIGTERM: the worker ignores both
    (the run ends it with its shutdown; it printed its own KeyboardInterrupt traceback on every Ctrl-C
    before, and a SIGTERM killed it under the run, summary.json's worker_cpu_s null), and a worker whose
    run process is gone without a shutdown (SIGKILL) ends too instead of waiting for jobs for good."""
    import os
    import signal
    import subprocess
    import sys
    from pathlib import Path

    import pipeline
    from pipeline.live import detection_worker

    ex = detection_worker(None)
    try:
        pid = ex.submit(os.getpid).result()
        for sig in (signal.SIGINT, signal.SIGTERM):  # (SIGTERM: systemd's stop reaches the whole group)
            os.kill(pid, sig)
            time.sleep(0.3)
            assert ex.submit(abs, -2).result(timeout=30) == 2, sig
    finally:
        ex.shutdown()
    code = (
        "import os\nfrom pipeline.live import detection_worker\n"
        "ex = detection_worker(None)\nprint(ex.submit(os.getpid).result(), flush=True)\nos._exit(0)\n"
    )
    env = {**os.environ, "PYTHONPATH": str(Path(pipeline.__file__).parents[1])}  # (this checkout's code)
    with subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env) as run:
        pid = int(run.stdout.readline())  # (not read to its end: an orphan worker would hold the pipe)
        run.wait(timeout=60)

    def alive() -> bool:
        try:
            with open(f"/proc/{pid}/stat") as f:
                return f.read().split(") ")[-1][:1] != "Z"  # (a zombie has ended)
        except FileNotFoundError:
            return False

    try:
        t_end = time.monotonic() + 20
        while alive() and time.monotonic() < t_end:
            time.sleep(0.05)
        assert not alive(), "the worker outlived its run's process"
    finally:
        if alive():
            os.kill(pid, signal.SIGKILL)


class _UnloadableOrb:
    """Stands for a detector that pickles but does not load in the worker process (a plug-in whose
    ``__setstate__`` needs what that process lacks)."""

    def __init__(self):
        self.device = "a device only this process has"

    def __setstate__(self, state):
        raise ImportError("this detector's device is not in the worker")


def test_a_detector_the_worker_process_cannot_load_is_a_clear_error_naming_its_cause():
    """The set-up's check sends the tracker's finder to the real worker process: a detector that pickles
    but fails to load there is a RuntimeError naming the camera, the detector and the cause (not the
    worker process dying as it reads the job: BrokenProcessPool, the cause only in its traceback on
    stderr), and the worker process still runs."""
    import itertools

    from estimators.rig import Camera, forward_T_C_B
    from pipeline.live import detection_worker
    from tests.trackers.conftest import equidistant
    from trackers.detectors import make_detector
    from trackers.features import FeatureTracker

    model = equidistant()
    ft = FeatureTracker(Camera("cam0", model, forward_T_C_B()), make_detector("orb"), ids=itertools.count(1))
    ft.detector.part = _UnloadableOrb()
    ex = detection_worker(None)
    try:
        with pytest.raises(RuntimeError, match=r"'cam0'.*OrbDetector.*ImportError: this detector's device"):
            ft.defer_detection(ex)
        assert ft._executor is None
        assert ex.submit(abs, -2).result(timeout=30) == 2
    finally:
        ex.shutdown()


def test_a_ctrl_c_while_the_worker_shuts_down_keeps_the_runs_outputs(tmp_path, monkeypatch):
    """The worker is shut down after the outputs are written: its shutdown waits for a detection under way
    (kornia on a CPU: ~1 s), and a second Ctrl-C there (or an error) left summary.json unwritten and
    tracks.jsonl unclosed when the shutdown came first (fails at a451afe: no summary.json). The shutdown is
    still made."""
    from concurrent.futures import Future

    import pipeline.live as live

    class Worker:
        nice = 10
        shut = 0

        def submit(self, fn, *args):
            fut: Future = Future()
            fut.set_result(fn(*args))
            return fut

        def shutdown(self, wait=True, cancel_futures=False):
            Worker.shut += 1
            raise KeyboardInterrupt  # the user's second Ctrl-C while the detection under way ends

    monkeypatch.setattr(live, "detection_worker", lambda nice: Worker())
    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    with pytest.raises(KeyboardInterrupt):
        _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=True)],
              front=DeferringFrontEnd(mono_rig()), cfg=_cfg("live.deferred_detection=true"))
    assert Worker.shut == 1
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["frames"] >= 1 and s["deferred_detection"]["worker_nice"] == 10
    assert len((tmp_path / "out" / "tracks.jsonl").read_text().splitlines()) == s["frames"]


def test_deferred_detection_with_a_front_end_that_cannot_defer_is_a_clear_error(tmp_path):
    """live.deferred_detection true asks for the detections off the frame's path: a front end without
    ``defer_detection`` is a ConfigError naming the key and the front end, before any camera or worker
    starts (it was silently left undone: summary.json's deferred_detection null)."""
    v = write_video(tmp_path / "cam0.mkv", 4, times=[k / 20 for k in range(4)])
    opened = []

    def factory():
        opened.append(1)
        return make_reader_factory(str(v), "cam0", paced=False)()

    with pytest.raises(ConfigError, match=r"live\.deferred_detection true.*FakeFrontEnd.*defer_detection"):
        _live(tmp_path, [factory], cfg=_cfg("live.deferred_detection=true"))
    assert not opened and _no_worker_left()


def test_a_replayed_file_cut_off_halfway_ends_the_live_run_normally_as_outputs_md_says(tmp_path):
    """live records ``error`` only for a frame a stage refused: a replayed file that breaks halfway ends
    the run normally (``error`` null), unlike ``run``; docs/OUTPUTS.md says which records what."""
    v = write_video(tmp_path / "cam0.mkv", 30, times=[k / 30 for k in range(30)])
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(v.read_bytes()[: v.stat().st_size // 2])
    (tmp_path / "cut.timestamps.txt").write_text((tmp_path / "cam0.timestamps.txt").read_text())
    r = _live(tmp_path, [make_reader_factory(str(cut), "cam0", paced=False)])
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert 0 < r.frames < 30 and s["frames"] == r.frames and s["error"] is None
    doc = " ".join((Path(__file__).resolve().parents[2] / "docs" / "OUTPUTS.md").read_text().split())
    assert "(or `live`)" not in doc
    assert "For `live` it is only a frame a stage refused" in doc
    assert "even one cut off halfway, ends the live run normally (exit 0, `error` null)" in doc


def test_a_second_ctrl_c_while_the_grabbers_stop_keeps_summary_json(tmp_path, monkeypatch):
    """Stopping the grabbers waits up to 5 s a camera; a second Ctrl-C or a repeated SIGTERM there lost
    summary.json (built after them). Now the summary is written (interrupted); the deferred-detection
    worker's shutdown still comes last."""
    import pipeline.live as live

    stop = live.Grabber.stop

    def stop_then_signal(self, *a, **kw):
        stop(self, *a, **kw)
        raise KeyboardInterrupt

    monkeypatch.setattr(live.Grabber, "stop", stop_then_signal)
    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 20 for k in range(10)])
    rig = mono_rig()
    with pytest.raises(KeyboardInterrupt):
        _live(tmp_path, [make_reader_factory(str(v), "cam0", paced=False)],
              front=FakeFrontEnd(rig, interrupt_at=3))
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    # (3 frames, or fewer when the loop took the newest frame past dropped ones and the file ended first:
    # the second signal then interrupts a run that had ended)
    assert s["interrupted"] is True and 1 <= s["frames"] <= 3
    assert len((tmp_path / "out" / "tracks.jsonl").read_text().splitlines()) == s["frames"]
