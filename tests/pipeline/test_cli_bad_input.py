"""Bad input on the command line: one line naming what was wrong and what was expected, exit code 2,
nothing already written lost (run, live, evaluate)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from test_run_support import FakeFrontEnd, FakeFusion, mono_rig, write_video

from pipeline import live as live_mod
from pipeline import run as run_mod
from pipeline.cli import main


def _fake_stages(monkeypatch, front=None):
    for mod in (run_mod, live_mod):
        monkeypatch.setattr(mod, "build_rig", lambda cfg: mono_rig())
        monkeypatch.setattr(mod, "build_frontend", front or (lambda cfg, rig: FakeFrontEnd(rig)))
        monkeypatch.setattr(mod, "build_fusion", lambda cfg, rig, ego: FakeFusion())


def _err_lines(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("command", ["run", "live"])
def test_trajectory_and_speed_together_are_an_error_naming_both(tmp_path, monkeypatch, capsys, command):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    traj = tmp_path / "traj.tum"
    traj.write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    src = ["--video", str(v)] if command == "run" else ["--camera", str(v)]
    rc = main([command, *src, "--trajectory", str(traj), "--speed-mps", "3", "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert "--trajectory" in err[0] and "--speed-mps" in err[0] and "alternatives" in err[0]
    assert not (tmp_path / "o").exists()  # refused before anything is written


class RefusingFrontEnd(FakeFrontEnd):
    """Refuses its frame number ``at`` (counted from 0) as the real front end refuses a bad frame."""

    def __init__(self, rig, at: int):
        super().__init__(rig)
        self.at = at

    def process(self, images, frame, t_s, T_W_B=None):
        if len(self.calls) == self.at:
            from estimators.errors import InputError, frame_at

            raise InputError(f"{frame_at(frame, t_s)}: camera 'cam0': frame is 1x1 px")
        return super().process(images, frame, t_s, T_W_B)


@pytest.mark.parametrize("command", ["run", "live"])
def test_an_error_mid_run_is_recorded_and_says_what_was_kept(tmp_path, monkeypatch, capsys, command):
    _fake_stages(monkeypatch, front=lambda cfg, rig: RefusingFrontEnd(rig, at=3))
    v = write_video(tmp_path / "cam0.mkv", 8, times=[k / 10 for k in range(8)])
    out = tmp_path / "o"
    src = ["--video", str(v), "--no-progress"] if command == "run" else ["--camera", str(v)]
    rc = main([command, *src, "--speed-mps", "3", "--out", str(out)])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1 and "Traceback" not in err[0], err
    # (live: a replayed frame may be dropped as stale on a loaded machine, so the refused frame's
    # index and time may come later; three frames were processed before it either way)
    refused = "frame 3 (t_s=0.300000 s)" if command == "run" else "frame "
    assert err[0].startswith(f"fisheye-des: error: {refused}") and "camera 'cam0'" in err[0]
    assert err[0].endswith(f"(outputs up to frame set 3 are in {out})")
    assert len((out / "tracks.jsonl").read_text().splitlines()) == 3  # nothing already written lost
    s = json.loads((out / "summary.json").read_text())
    assert s["frames"] == 3 and s["error"].startswith(refused) and s["error"].endswith("frame is 1x1 px")


def test_a_timestamps_file_whose_frame_numbers_repeat_is_one_line(tmp_path, monkeypatch, capsys):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 4, times=[0, 0.1, 0.2, 0.3], frames=[0, 1, 1, 3])
    rc = main(["run", "--video", str(v), "--speed-mps", "3", "--out", str(tmp_path / "o"), "--no-progress"])
    err = _err_lines(capsys)
    assert rc == 2 and err == [
        f"fisheye-des: error: {tmp_path / 'cam0.timestamps.txt'}:3: frame numbers must increase; "
        "frame 1 follows frame 1 (line '1 0.200000')"
    ]


@pytest.mark.parametrize("command", ["run", "live", "batch"])
@pytest.mark.parametrize("out", ["file", "file/sub"])
def test_an_out_that_is_a_file_is_one_line(tmp_path, monkeypatch, capsys, command, out):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    (tmp_path / "file").write_text("keep me")
    src = {"run": ["--video", str(v), "--no-progress"], "live": ["--camera", str(v)],
           "batch": ["--batch", str(v), "--no-progress"]}[command]
    name = "live" if command == "live" else "run"
    rc = main([name, *src, "--speed-mps", "3", "--out", str(tmp_path / out)])
    err = _err_lines(capsys)
    blocker = "it" if out == "file" else str(tmp_path / "file")
    assert rc == 2 and err == [
        f"fisheye-des: error: {tmp_path / out}: cannot create the output folder ({blocker} is a file); "
        "expected a folder path that can be created and written"
    ]
    assert (tmp_path / "file").read_text() == "keep me"


def test_make_output_dir_creates_parents_and_accepts_an_existing_folder(tmp_path):
    from pipeline.sinks import make_output_dir

    assert make_output_dir(tmp_path / "a" / "b") == tmp_path / "a" / "b" and (tmp_path / "a" / "b").is_dir()
    assert make_output_dir(str(tmp_path / "a")) == tmp_path / "a"


@pytest.mark.parametrize("command", ["run", "live"])
@pytest.mark.parametrize(
    ("flag", "item"),
    [
        ("--trajectory", "ego_motion.speed_mps=3"),
        ("--trajectory", "ego_motion={speed_mps: 3}"),
        ("--trajectory", "ego_motion.t0_s=2"),  # belongs to the constant speed (was silently ignored)
        ("--speed-mps", "ego_motion.trajectory=TRAJ"),
        ("--calibration", "rig.cameras=[{name: cam0}]"),
    ],
)
def test_a_flag_and_a_set_it_would_replace_are_an_error(
    tmp_path, monkeypatch, capsys, command, flag, item
):
    """A --set the flag would silently replace (the flag clears the other key) is refused like the
    two flags together."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    traj = tmp_path / "traj.tum"
    traj.write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    src = ["--video", str(v)] if command == "run" else ["--camera", str(v)]
    calib = tmp_path / "camchain.yaml"
    calib.write_text("cam0: {}\n")  # never read: the clash is refused first
    value = {"--trajectory": str(traj), "--calibration": str(calib)}.get(flag, "3")
    item = item.replace("TRAJ", str(traj))
    rc = main([command, *src, flag, value, "--set", item, "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert f"{flag} " in err[0] and f"--set {item}" in err[0] and "alternatives" in err[0]
    assert not (tmp_path / "o").exists()  # refused before anything is written


def test_motion_flag_with_the_other_key_set_back_to_null_runs(tmp_path, monkeypatch, capsys):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    traj = tmp_path / "traj.tum"
    traj.write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    rc = main(["run", "--video", str(v), "--trajectory", str(traj), "--set", "ego_motion.speed_mps=3",
               "--set", "ego_motion.speed_mps=null", "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "o" / "tracks.jsonl").is_file()


@pytest.mark.parametrize("command", ["run", "live"])
def test_t0_s_beside_a_trajectory_is_refused_naming_both_keys(tmp_path, monkeypatch, capsys, command):
    """ego_motion.t0_s places the constant-velocity body; a trajectory ignored it without a word.
    --trajectory clears a config's t0_s (it replaces the constant speed, as it clears speed_mps)."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    (tmp_path / "traj.tum").write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text("ego_motion:\n  trajectory: traj.tum\n  t0_s: 2.0\n")
    src = ["--video", str(v)] if command == "run" else ["--camera", str(v)]
    rc = main([command, str(cfg), *src, "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0] == (f"fisheye-des: error: {cfg}:3: ego_motion.t0_s (2 s) belongs to the constant-velocity "
                      "motion (ego_motion.speed_mps) and is not used with a trajectory (its "
                      "timestamps place the body in time); expected no ego_motion.t0_s beside "
                      "a trajectory")
    assert not (tmp_path / "o").exists()
    cfg.write_text("ego_motion:\n  speed_mps: 3.0\n  t0_s: 2.0\n")
    rc = main(["run", str(cfg), "--video", str(v), "--trajectory", str(tmp_path / "traj.tum"),
               "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    assert "t0_s: 0.0" in (tmp_path / "o" / "config.resolved.yaml").read_text()


def test_a_trajectory_clock_offset_beside_a_constant_speed_is_refused(tmp_path, monkeypatch, capsys):
    """ego_motion.time_offset_s shifts a trajectory's clock; beside speed_mps it would be ignored: refused
    where it was set. --speed-mps clears a config's offset (it replaces the trajectory), a --set of it beside
    --speed-mps is refused, and a non-finite offset is refused at load."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    (tmp_path / "traj.tum").write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    cfg = tmp_path / "c.yaml"
    cfg.write_text("ego_motion:\n  speed_mps: 3.0\n  time_offset_s: 0.2\n")
    rc = main(["run", str(cfg), "--video", str(v), "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0] == (f"fisheye-des: error: {cfg}:3: ego_motion.time_offset_s (0.2 s) shifts a trajectory's "
                      "clock and is not used with the constant-velocity motion (ego_motion.speed_mps; its "
                      "ego_motion.t0_s places the body in time); expected ego_motion.trajectory beside it, "
                      "or no ego_motion.time_offset_s")
    assert not (tmp_path / "o").exists()
    cfg.write_text("ego_motion:\n  trajectory: traj.tum\n  time_offset_s: 0.05\n")
    rc = main(["run", str(cfg), "--video", str(v), "--speed-mps", "3", "--out", str(tmp_path / "o"),
               "--no-progress"])
    done = capsys.readouterr().err
    assert rc == 0, done
    resolved = (tmp_path / "o" / "config.resolved.yaml").read_text()
    assert "time_offset_s: 0.0" in resolved and "trajectory: null" in resolved
    rc = main(["run", "--video", str(v), "--speed-mps", "3", "--set", "ego_motion.time_offset_s=0.05",
               "--out", str(tmp_path / "o2")])
    err = _err_lines(capsys)
    assert rc == 2 and err == ["fisheye-des: error: --set ego_motion.time_offset_s=0.05 shifts a "
                               "trajectory's clock, and --speed-mps 3 replaces the trajectory by a constant "
                               "speed, which has no clock to shift; give --trajectory with it, or drop it"]
    rc = main(["run", "--video", str(v), "--trajectory", str(tmp_path / "traj.tum"), "--set",
               "ego_motion.time_offset_s=nan", "--out", str(tmp_path / "o3")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1 and "time_offset_s must be a finite number of seconds, got nan" in err[0]
    assert not (tmp_path / "o3").exists()


@pytest.mark.parametrize("command", ["run", "live"])
def test_a_bad_trajectory_line_is_one_line_naming_it_and_leaves_no_folder(
    tmp_path, monkeypatch, capsys, command
):
    """live as run: the trajectory (and the other stages) are built before the output folder is made."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    zq = tmp_path / "zq.tum"
    zq.write_text("# h\n0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 0\n")
    src = ["--video", str(v)] if command == "run" else ["--camera", str(v)]
    rc = main([command, *src, "--trajectory", str(zq), "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"fisheye-des: error: {zq}:3: has a zero quaternion")
    assert not (tmp_path / "o").exists()


def test_live_whose_fusion_cannot_be_built_leaves_no_folder(tmp_path, monkeypatch, capsys):
    from estimators.errors import ConfigError

    _fake_stages(monkeypatch)

    def refuse(cfg, rig, ego):
        raise ConfigError("fusion: refused (test)")

    monkeypatch.setattr(live_mod, "build_fusion", refuse)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    rc = main(["live", "--camera", str(v), "--speed-mps", "3", "--out", str(tmp_path / "o")])
    assert rc == 2 and _err_lines(capsys) == ["fisheye-des: error: fusion: refused (test)"]
    assert not (tmp_path / "o").exists()


def test_a_batch_run_stopped_mid_way_reports_the_frames_it_kept(tmp_path, monkeypatch, capsys):
    _fake_stages(monkeypatch, front=lambda cfg, rig: RefusingFrontEnd(rig, at=3))
    v = write_video(tmp_path / "cam0.mkv", 8, times=[k / 10 for k in range(8)])
    out = tmp_path / "o"
    rc = main(["run", "--batch", str(v), "--speed-mps", "3", "--out", str(out), "--no-progress"])
    err = _err_lines(capsys)
    assert rc == 2 and err[-1] == "fisheye-des: error: 1 of 1 batch runs reported an error (see above)"
    assert err[0].startswith(f"{out / 'cam0'}: 3 frames  ERROR frame 3 (t_s=0.300000 s)"), err
    assert json.loads((out / "cam0" / "summary.json").read_text())["frames"] == 3


@pytest.mark.parametrize("jobs", ["0", "-2"])
def test_jobs_below_one_is_an_error(tmp_path, monkeypatch, capsys, jobs):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    rc = main(["run", "--batch", str(v), "--jobs", jobs, "--speed-mps", "3", "--out", str(tmp_path / "o"),
               "--no-progress"])
    assert rc == 2 and _err_lines(capsys) == [
        f"fisheye-des: error: --jobs {jobs} (run_batch workers): expected an integer of at least 1 worker "
        "process (or none: one per CPU, at most one per run)"
    ]
    assert not (tmp_path / "o").exists()


def test_jobs_without_batch_is_an_error(tmp_path, monkeypatch, capsys):
    """``--jobs`` sets the --batch worker processes: without --batch it would be ignored silently."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    rc = main(["run", "--video", str(v), "--jobs", "4", "--speed-mps", "3", "--out", str(tmp_path / "o"),
               "--no-progress"])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("fisheye-des: error: --jobs 4 needs --batch: it is the number of worker")
    assert not (tmp_path / "o").exists()


def test_a_preview_port_in_use_is_an_error_naming_it(tmp_path, monkeypatch, capsys):
    """live's MJPEG preview on a port something else listens on (the shipped webcam config's 8080): one
    line naming the port and the way out, exit 2 (was OSError's traceback, exit 1)."""
    import socket

    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        rc = main(["live", "--camera", str(v), "--speed-mps", "3", "--preview", "mjpeg", "--port", str(port),
                   "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"fisheye-des: error: live.preview_port {port}: the MJPEG preview cannot listen "
                             f"on 127.0.0.1:{port} (")
    assert err[0].endswith("give another --port (0: any free one), or --preview file / none")
    assert not (tmp_path / "o").exists()  # the port is tried before the output folder is made


def test_a_failed_live_start_keeps_an_earlier_runs_outputs(tmp_path, monkeypatch, capsys):
    """--out holding a finished run: a preview port in use or a camera that does not open stops the
    start before anything there is written (tracks.jsonl was truncated, config.resolved.yaml replaced)."""
    import socket

    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    out = tmp_path / "keep"
    out.mkdir()
    kept = {"tracks.jsonl": '{"frame": 0, "t_s": 0.0, "tracks": []}\n' * 30, "config.resolved.yaml": "x: 1\n"}
    for name, text in kept.items():
        (out / name).write_text(text)
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        rc = main(["live", "--camera", str(v), "--speed-mps", "3", "--preview", "mjpeg", "--port", str(port),
                   "--out", str(out)])
    assert rc == 2 and "live.preview_port" in capsys.readouterr().err
    rc = main(["live", "--camera", str(tmp_path / "missing.mkv"), "--speed-mps", "3", "--out", str(out)])
    assert rc == 2 and "missing.mkv" in capsys.readouterr().err
    assert {p.name: p.read_text() for p in out.iterdir()} == kept


def test_a_camera_that_does_not_open_leaves_no_output_folder(tmp_path, monkeypatch, capsys):
    _fake_stages(monkeypatch)
    rc = main(["live", "--camera", str(tmp_path / "missing.mkv"), "--speed-mps", "3",
               "--out", str(tmp_path / "o")])
    assert rc == 2 and "missing.mkv" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_preview_port_without_the_mjpeg_preview_is_an_error(tmp_path, monkeypatch, capsys):
    """--port is the MJPEG preview's: with live.preview none (the default) or file it was ignored."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    for preview in ([], ["--preview", "file"]):
        rc = main(["live", "--camera", str(v), "--speed-mps", "3", "--port", "9123", *preview,
                   "--out", str(tmp_path / "o")])
        shown = preview[1] if preview else "none"
        assert rc == 2 and _err_lines(capsys) == [
            f"fisheye-des: error: --port 9123 is the MJPEG preview's port, but live.preview is '{shown}'; "
            "give --preview mjpeg too, or drop --port"]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("flag", ["--video", "--images", "--batch", "--camera"])
def test_a_second_value_after_a_repeatable_flag_is_named_as_such_not_as_a_config(tmp_path, monkeypatch,
                                                                                  capsys, flag):
    """`--video a.mkv b.mkv` (or --images, --batch; live's `--camera 0 1`) makes the second value the
    CONFIG argument: the error says to repeat the flag (was 'config file not found', or for a video a
    UnicodeDecodeError traceback, exit 1)."""
    _fake_stages(monkeypatch)
    a = write_video(tmp_path / "a.mkv", 3, times=[0, 0.1, 0.2])
    b = write_video(tmp_path / "b.mkv", 3, times=[0, 0.1, 0.2])
    values = {"--video": [a, b], "--images": [tmp_path, tmp_path], "--batch": [a, tmp_path],
              "--camera": ["0", "1"]}[flag]
    command = "live" if flag == "--camera" else "run"
    rc = main([command, flag, *map(str, values), "--speed-mps", "3", "--out", str(tmp_path / "o")])
    assert rc == 2 and _err_lines(capsys) == [
        f"fisheye-des: error: {values[1]}: not a YAML config (the first argument); {flag} takes one value "
        f"per flag: {flag} {values[0]} {flag} {values[1]}"]
    assert not (tmp_path / "o").exists()


def test_a_second_camera_url_or_device_after_one_flag_gets_the_repeat_hint_unfolded(tmp_path, capsys):
    """A URL (its '//' folded to '/' on the way in as a path) or a device node as the stray second value
    of --camera / --video: the repeat-the-flag hint, with the URL as typed (it was 'config file not
    found' with the URL garbled)."""
    for command, flag, first, second in (
        ("live", "--camera", "rtsp://cam/a", "rtsp://cam/b"),
        ("run", "--video", str(tmp_path / "a.mkv"), "http://host/b.mkv?s=1"),
        ("live", "--camera", "/dev/null", "/dev/zero"),
    ):
        rc = main([command, flag, first, second, "--speed-mps", "3", "--out", str(tmp_path / "o")])
        assert rc == 2 and _err_lines(capsys) == [
            f"fisheye-des: error: {second}: not a YAML config (the first argument); {flag} takes one value "
            f"per flag: {flag} {first} {flag} {second}"], (command, second)
    assert not (tmp_path / "o").exists()


def test_a_missing_yaml_config_beside_a_repeatable_flag_is_named_missing(tmp_path, capsys):
    v = write_video(tmp_path / "a.mkv", 3, times=[0, 0.1, 0.2])
    assert main(["run", str(tmp_path / "my.yaml"), "--video", str(v), "--speed-mps", "3"]) == 2
    missing = tmp_path / "my.yaml"
    assert _err_lines(capsys)[0].startswith(f"fisheye-des: error: {missing}: config file not found")


def test_a_yaml_config_of_any_name_beside_a_repeatable_flag_loads(tmp_path, monkeypatch):
    """CONFIG need not be named .yaml: `run my.cfg --video a.mkv` loads my.cfg (it was refused with the
    repeat-the-flag hint)."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "a.mkv", 3, times=[0, 0.1, 0.2])
    cfg = tmp_path / "my.cfg"
    cfg.write_text("ego_motion:\n  speed_mps: 3\n")
    assert main(["run", str(cfg), "--video", str(v), "--out", str(tmp_path / "o"), "--no-progress"]) == 0
    assert len((tmp_path / "o" / "tracks.jsonl").read_text().splitlines()) == 3


def test_a_config_argument_that_is_no_media_is_left_to_the_config_loader(tmp_path, monkeypatch, capsys):
    """Only a folder, a video or image name, or (live) a device index gets the repeat-the-flag hint; a
    preset's typo is 'config file not found' with the presets, a text file that is no config 'not a
    YAML config', a number after --video not found (it is no camera there)."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "a.mkv", 3, times=[0, 0.1, 0.2])
    notes = tmp_path / "notes.txt"
    notes.write_text("0.0\n0.1\n")
    for config, expected in (
        ("mono_forwad", "mono_forwad: config file not found (neither a file nor a preset"),
        ("1", "1: config file not found"),
        (str(notes), f"{notes}: not a YAML config (it reads as a str, not a mapping)"),
    ):
        assert main(["run", config, "--video", str(v), "--speed-mps", "3", "--out", str(tmp_path / "o")]) == 2
        err = _err_lines(capsys)
        assert len(err) == 1 and err[0].startswith(f"fisheye-des: error: {expected}"), err
        assert ("presets: " in err[0]) == (config != str(notes)), err
    assert not (tmp_path / "o").exists()


def test_a_config_that_is_no_text_is_an_error_not_a_traceback(tmp_path, capsys):
    v = write_video(tmp_path / "a.mkv", 3, times=[0, 0.1, 0.2])
    assert main(["run", str(v), "--speed-mps", "3", "--out", str(tmp_path / "o")]) == 2
    assert _err_lines(capsys) == [
        f"fisheye-des: error: {v}: not a YAML config (not UTF-8 text); expected a YAML file of sections "
        "(rig, ego_motion, ...), e.g. configs/mono_forward.yaml"]


def _live_over(tmp_path, monkeypatch, capsys, frames, tum):
    """``live`` (fake stages, no trajectory wait) replaying a video of ``frames`` frames at 10 Hz against
    the trajectory text ``tum``: (exit code, stderr lines, summary.json)."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", frames, times=[k / 10 for k in range(frames)])
    traj = tmp_path / "traj.tum"
    traj.write_text(tum)
    rc = main(["live", "--camera", str(v), "--trajectory", str(traj), "--set", "live.trajectory_wait_s=0",
               "--out", str(tmp_path / "o")])
    return rc, _err_lines(capsys), json.loads((tmp_path / "o" / "summary.json").read_text())


def test_live_says_how_many_frames_it_skipped_for_want_of_a_pose(tmp_path, monkeypatch, capsys):
    """A trajectory that stops short of the frames: the frames past its end are skipped (counted in
    summary.json's frames_without_pose); the closing line says so too (was silent there)."""
    rc, err, sm = _live_over(tmp_path, monkeypatch, capsys, 8, "0.0 0 0 0 0 0 0 1\n0.35 1 0 0 0 0 0 1\n")
    skipped, gap = sm["frames_without_pose"], sm["pose_gap_after_s"]
    assert rc == 0 and skipped >= 1  # (4 unless the loaded machine dropped some as stale)
    assert 0.05 <= gap <= 0.35 + 1e-9 and sm["frames_before_trajectory"] == 0  # (0.4-0.7 s past 0.35 s)
    assert f" stale frames dropped, {skipped} skipped without a pose (the trajectory did not reach their " \
        f"time within live.trajectory_wait_s; the farthest was {gap:.3f} s past its last pose), latency " \
        "median " in err[-1], err  # (a writer's lag: no clock hint)


def test_live_names_the_clock_when_frames_lie_far_past_a_trajectorys_last_pose(tmp_path, monkeypatch, capsys):
    """Frames on the unix clock against a trajectory on a flight controller's boot clock (poses at
    -500..-499 s): every frame lies ~500 s past the last pose; the closing line gives that gap and names
    ego_motion.time_offset_s / live.clock, which a writer's usual lag (above) does not get."""
    rc, err, sm = _live_over(tmp_path, monkeypatch, capsys, 4, "-500.0 0 0 0 0 0 0 1\n-499.0 1 0 0 0 0 0 1\n")
    assert rc == 0 and sm["frames_without_pose"] >= 1 and 499.0 <= sm["pose_gap_after_s"] <= 499.3 + 1e-9
    assert (f"the farthest was {sm['pose_gap_after_s']:.3f} s past its last pose: a trajectory on another "
            "clock needs ego_motion.time_offset_s, its time minus the frame's, or live.clock), latency "
            "median ") in err[-1], err


def test_live_skips_frames_before_a_trajectorys_first_pose_without_waiting_and_names_the_offset(
    tmp_path, monkeypatch, capsys
):
    """A trajectory stamped on another clock (its first pose after every frame): no frame can ever get a
    pose, since a growing file adds poses at its end. They are skipped at once (they waited
    live.trajectory_wait_s each), counted as frames_before_trajectory, and the closing line names
    ego_motion.time_offset_s (it said the trajectory 'did not reach their time')."""
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 6, times=[k / 10 for k in range(6)])
    traj = tmp_path / "later.tum"
    traj.write_text("500.0 0 0 0 0 0 0 1\n501.0 1 0 0 0 0 0 1\n")
    t0 = time.monotonic()
    rc = main(["live", "--camera", str(v), "--trajectory", str(traj), "--set", "live.trajectory_wait_s=5",
               "--out", str(tmp_path / "o")])
    took = time.monotonic() - t0
    err = _err_lines(capsys)
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert rc == 0 and s["frames"] == 0 and took < 5, (took, err)  # (6 frames x 5 s before)
    before = s["frames_before_trajectory"]
    assert before >= 1 and s["frames_without_pose"] == before  # (6 unless dropped as stale)
    gap = s["pose_gap_before_s"]
    assert 499.5 <= gap <= 500.0 and s["pose_gap_after_s"] is None  # (the first frame kept is 0 s: 500 s)
    assert (f" stale frames dropped, {before} skipped before the trajectory's first pose (up to {gap:.3f} s "
            "before it: its writer started after the camera, or it runs on another clock, which needs "
            "ego_motion.time_offset_s, its time minus the frame's, or live.clock), latency median ") \
        in err[-1], err
    rc = main(["live", "--camera", str(v), "--trajectory", str(traj), "--set", "live.trajectory_wait_s=5",
               "--set", "ego_motion.time_offset_s=500", "--out", str(tmp_path / "o2")])
    s = json.loads((tmp_path / "o2" / "summary.json").read_text())
    assert rc == 0 and s["frames_without_pose"] == 0 and s["frames"] >= 1, _err_lines(capsys)


def test_run_batch_refuses_zero_workers(tmp_path):
    from estimators.errors import ConfigError
    from pipeline.config import load_config
    from pipeline.run import run_batch

    with pytest.raises(ConfigError, match=r"run_batch workers\): expected an integer of at least 1"):
        run_batch(load_config(None, ["ego_motion.speed_mps=3"]), [], tmp_path / "o", workers=0)


_SIGTERM_RUN = """
import os, signal, sys
sys.path.insert(0, {tests!r})
from test_run_support import FakeFrontEnd, FakeFusion, mono_rig
from pipeline import live as live_mod, run as run_mod
from pipeline.cli import main

class Stopped(FakeFrontEnd):  # a supervisor's SIGTERM arrives while the 4th frame set is processed
    def process(self, images, frame, t_s, T_W_B=None):
        if len(self.calls) == 3:
            os.kill(os.getpid(), signal.SIGTERM)
        return super().process(images, frame, t_s, T_W_B)

for mod in (run_mod, live_mod):
    mod.build_rig = lambda cfg: mono_rig()
    mod.build_frontend = lambda cfg, rig: Stopped(rig)
    mod.build_fusion = lambda cfg, rig, ego: FakeFusion()
sys.exit(main({args!r}))
"""


@pytest.mark.parametrize("command", ["run", "live"])
def test_sigterm_stops_like_ctrl_c_with_summary_json_written(tmp_path, command):
    """systemd, a launch file or `docker stop` end a process with SIGTERM: the run stops as on a Ctrl-C
    (summary.json written, interrupted true, exit 130), not killed without its summary (was: exit -15,
    no summary.json)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    import pipeline

    v = write_video(tmp_path / "cam0.mkv", 10, times=[k / 10 for k in range(10)])
    src = "--video" if command == "run" else "--camera"
    args = [command, src, str(v), "--speed-mps", "3", "--out", str(tmp_path / "o")]
    code = _SIGTERM_RUN.format(tests=str(Path(__file__).parent), args=args)
    env = {**os.environ, "PYTHONPATH": str(Path(pipeline.__file__).parents[1])}
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 130, p.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    lines = (tmp_path / "o" / "tracks.jsonl").read_text().splitlines()
    assert s["interrupted"] is True and s["error"] is None and s["frames"] == len(lines) == 3


_BATCH_MAIN = """
import os, sys, time
sys.path.insert(0, {tests!r})
from test_run_support import FakeFrontEnd, FakeFusion, mono_rig
from pipeline import run as run_mod

class Stalled(FakeFrontEnd):
    def process(self, images, frame, t_s, T_W_B=None):
{body}
        return super().process(images, frame, t_s, T_W_B)

# (module level: the spawned batch workers import this file as __mp_main__ and get the stand-ins too)
run_mod.build_rig = lambda cfg: mono_rig()
run_mod.build_frontend = lambda cfg, rig: Stalled(rig)
run_mod.build_fusion = lambda cfg, rig, ego: FakeFusion()

if __name__ == "__main__":
    from pipeline.cli import main
    sys.exit(main({args!r}))
"""
# a recording stops at its third frame until the test creates the file `release` (or a signal stops
# it): what the test acts on is under way however slow the machine (no race with a recording's end)
_STALL = """\
        if len(self.calls) == 2:
            t_end = time.monotonic() + 60
            while not os.path.exists({release!r}) and time.monotonic() < t_end:
                time.sleep(0.02)"""


def _batch(tmp_path, n_frames: int, body: str = _STALL):
    """``run --batch`` of three recordings of ``n_frames`` frames (v1, v2, v3) with 2 workers, in a
    child process whose front end runs ``body`` before each frame: its Popen arguments, the output
    folder and the release file (``_STALL``)."""
    import os
    import sys

    import pipeline

    vids = [write_video(tmp_path / f"v{k}.mkv", n_frames, times=[i / 10 for i in range(n_frames)])
            for k in (1, 2, 3)]
    out, release = tmp_path / "o", tmp_path / "release"
    args = ["run", *(a for v in vids for a in ("--batch", str(v))), "--jobs", "2", "--speed-mps", "3",
            "--out", str(out), "--no-progress"]
    script = tmp_path / "batch_main.py"
    script.write_text(_BATCH_MAIN.format(tests=str(Path(__file__).parent), args=args,
                                         body=body.format(release=str(release))))
    env = {**os.environ, "PYTHONPATH": str(Path(pipeline.__file__).parents[1])}
    return [sys.executable, str(script)], env, out, release


def _wait_for(cond, timeout_s: float = 90.0) -> None:
    t_end = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < t_end, "timed out"
        time.sleep(0.05)


def _lines_in(path) -> int:
    return len(path.read_text().splitlines()) if path.is_file() else 0


def test_sigterm_stops_a_batch_its_recordings_under_way_and_starts_no_other(tmp_path):
    """A SIGTERM to `run --batch` (which reaches its process alone, not the workers) stops the
    recordings under way, each with its summary.json (interrupted), and starts none of the rest: was
    every recording run to its end, the queued ones too, before the batch exited."""
    import signal
    import subprocess

    cmd, env, out, _release = _batch(tmp_path, 20)
    with subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env) as p:
        try:  # v1 and v2 under way, each held at its third frame
            _wait_for(lambda: all(_lines_in(out / n / "tracks.jsonl") >= 2 for n in ("v1", "v2")))
            p.send_signal(signal.SIGTERM)
            err = p.communicate(timeout=60)[1]
        finally:
            if p.poll() is None:
                p.kill()
    assert p.returncode == 130, err
    for n in ("v1", "v2"):
        s = json.loads((out / n / "summary.json").read_text())
        assert s["interrupted"] is True and s["frames"] == 2, (n, s["frames"])
        assert f"{out / n}: interrupted; what it did is in the folder" in err
    assert not (out / "v3").exists() and f"{out / 'v3'}: not run (the batch was stopped)" in err


def test_a_batch_recording_refused_at_its_start_is_named_without_a_folder(tmp_path, monkeypatch, capsys):
    """A file of the batch that is no video gets no result folder: its line says so (was "DIR: 0
    frames", naming a folder that does not exist), and the other recordings run."""
    _fake_stages(monkeypatch)
    good = write_video(tmp_path / "good.mkv", 3, times=[0.0, 0.1, 0.2])
    bad = tmp_path / "bad.mkv"
    bad.write_text("not a video")
    out = tmp_path / "o"
    rc = main(["run", "--batch", str(bad), "--batch", str(good), "--jobs", "1", "--speed-mps", "3",
               "--out", str(out), "--no-progress"])
    err = _err_lines(capsys)
    assert rc == 2 and not (out / "bad").exists() and (out / "good" / "summary.json").is_file()
    assert err[0].startswith(f"{out / 'bad'}: not run, no folder  ERROR {bad}: cannot be opened"), err
    assert err[1].startswith(f"{out / 'good'}: 3 frames, "), err


def _writer_of(path) -> int | None:
    """The pid of a process holding ``path`` open for writing (Linux /proc), or None."""
    import os

    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            for fd in os.listdir(f"/proc/{pid}/fd"):
                if os.readlink(f"/proc/{pid}/fd/{fd}") == str(path):
                    return int(pid)
        except OSError:
            continue
    return None


def _signal_v1s_worker(tmp_path, sig: int, wait_for: str | None = None) -> tuple[int, str, Path]:
    """``_batch`` of three 20-frame recordings; the worker process of v1, held at its third frame with
    its tracks.jsonl open (found through /proc), gets ``sig``; once v1's folder holds ``wait_for`` (if
    given) the other recordings are released. Returns the batch's exit code, its stderr and the
    output folder."""
    import os
    import subprocess

    cmd, env, out, release = _batch(tmp_path, 20)
    f = out / "v1" / "tracks.jsonl"
    with subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env) as p:
        try:
            _wait_for(lambda: _lines_in(f) >= 2)
            pid = _writer_of(f)
            assert pid is not None and pid != p.pid
            os.kill(pid, sig)
            if wait_for:
                _wait_for(lambda: (out / "v1" / wait_for).is_file())
            release.touch()  # (the other recordings, if their workers still run)
            err = p.communicate(timeout=90)[1]
        finally:
            if p.poll() is None:
                p.kill()
    return p.returncode, err, out


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux /proc")
def test_a_batch_worker_killed_by_the_system_is_named_and_the_batch_exits_2(tmp_path):
    """A batch worker killed mid-recording (SIGKILL, as the kernel's out-of-memory killer does) broke the
    pool: the batch died with BrokenProcessPool's traceback naming no recording. Now each recording left
    unfinished gets its line (started: what it wrote is in its folder; not started: not run) and the
    batch exits 2."""
    import signal

    rc, err, out = _signal_v1s_worker(tmp_path, signal.SIGKILL)
    f = out / "v1" / "tracks.jsonl"
    assert rc == 2, err
    assert "Traceback" not in err and "BrokenProcessPool" not in err, err
    assert f"{out / 'v1'}: 0 frames  ERROR its worker process died" in err
    assert _lines_in(f) == 2  # what it wrote is kept
    assert str(out / "v3") in err


def test_a_bug_in_a_batch_recording_names_the_recording(tmp_path):
    """A bug (not a refused input) in a batch worker is raised on, as in a single run (traceback, exit 1),
    now with the recording named: the traceback came from the worker process and named none."""
    import subprocess

    cmd, env, out, _release = _batch(tmp_path, 3, body="        raise RuntimeError('a bug')")
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 1 and "RuntimeError: a bug" in p.stderr, p.stderr
    assert f"(in the batch's recording {out / 'v1'})" in p.stderr, p.stderr


def test_a_batch_worker_signalled_as_it_reads_the_stop_event_runs_no_recording(tmp_path, monkeypatch):
    """The batch's parent sets the stop event, then signals its workers: a worker that read the event
    (not set yet) and got the signal before it marked its recording under way ignored the signal (as
    between recordings) and ran the recording to its end. The signal is delivered here at that read."""
    import signal

    from pipeline.run import _BATCH_WORKER, _batch_pool_job, _batch_worker_init

    ran = []
    monkeypatch.setattr(run_mod, "_batch_worker", lambda args: ran.append(args) or {"out_dir": args[1]})

    class Event:  # the stop event: not set when first read, and the parent, which has just set it,
        read = False  # sends its SIGTERM right then

        def is_set(self):
            if self.read:
                return True
            self.read = True
            signal.getsignal(signal.SIGTERM)(signal.SIGTERM, None)
            return False

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(run_mod, "_BATCH_WORKER", dict(_BATCH_WORKER))
    try:
        _batch_worker_init(Event())
        r = _batch_pool_job(({}, str(tmp_path / "v1"), None))
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
    assert ran == [] and r == {"out_dir": str(tmp_path / "v1"), "interrupted": True}


def test_a_stopped_batch_signals_its_own_workers_and_no_other_child_of_its_caller(tmp_path):
    """run_batch as a library: stopped (a KeyboardInterrupt, here from on_done), it sent SIGTERM to every
    multiprocessing child of the calling process (multiprocessing.active_children), a caller's own
    worker too, which died of it; now only to the pool's processes."""
    import multiprocessing

    from pipeline.config import load_config
    from pipeline.run import run_batch

    bystander = multiprocessing.get_context("spawn").Process(target=time.sleep, args=(60,), daemon=True)
    bystander.start()
    try:
        bad = []
        for k in (1, 2, 3):
            bad.append(tmp_path / f"v{k}.mkv")
            bad[-1].write_text("not a video")
        done = []

        def on_done(r):
            done.append(r)
            if len(done) == 1:
                raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            run_batch(load_config(None, ["ego_motion.speed_mps=3"]), bad, tmp_path / "o", workers=2,
                      on_done=on_done)
        assert len(done) == 3
        bystander.join(0.5)
        assert bystander.is_alive(), bystander.exitcode
    finally:
        bystander.kill()
        bystander.join()


def test_a_batch_worker_once_interrupted_runs_no_other_recording(tmp_path, monkeypatch):
    """systemd's stop sends SIGTERM to every process of the unit: a worker interrupted directly, its
    recording's outputs written, could take the next recording before the parent had set the stop
    event, and, taking no second signal, ran it to its end while the batch waited."""
    import signal

    from pipeline.run import _BATCH_WORKER, _batch_pool_job, _batch_worker_init

    ran = []
    monkeypatch.setattr(run_mod, "_batch_worker", lambda args: ran.append(args) or {"out_dir": args[1]})

    class Event:  # the parent's stop: not set yet
        def is_set(self):
            return False

    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(run_mod, "_BATCH_WORKER", dict(_BATCH_WORKER))
    try:
        _batch_worker_init(Event())
        run_mod._BATCH_WORKER.update(interrupted=True)  # (its first recording was stopped)
        r = _batch_pool_job(({}, str(tmp_path / "v3"), None))
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
    assert ran == [] and r == {"out_dir": str(tmp_path / "v3"), "frames": 0, "not_run": True,
                               "why": "its worker process was interrupted"}


def test_a_ctrl_c_in_a_one_worker_batch_names_the_recording_stopped_and_those_not_run(tmp_path, monkeypatch,
                                                                                     capsys):
    """`run --batch ... --jobs 1` runs its recordings in this process: a Ctrl-C (or SIGTERM) printed no
    line for the recording it stopped nor for those it left, as a batch of worker processes does."""

    class Stopped(FakeFrontEnd):  # the Ctrl-C during v1's third frame
        def process(self, images, frame, t_s, T_W_B=None):
            if len(self.calls) == 2:
                raise KeyboardInterrupt
            return super().process(images, frame, t_s, T_W_B)

    _fake_stages(monkeypatch, front=lambda cfg, rig: Stopped(rig))
    vids = [write_video(tmp_path / f"v{k}.mkv", 5, times=[i / 10 for i in range(5)]) for k in (1, 2)]
    out = tmp_path / "o"
    rc = main(["run", *(a for v in vids for a in ("--batch", str(v))), "--jobs", "1", "--speed-mps", "3",
               "--out", str(out), "--no-progress"])
    err = _err_lines(capsys)
    assert rc == 130
    assert json.loads((out / "v1" / "summary.json").read_text())["interrupted"] is True
    assert f"{out / 'v1'}: interrupted; what it did is in the folder" in err, err
    assert f"{out / 'v2'}: not run (the batch was stopped)" in err and not (out / "v2").exists(), err


def test_a_stopped_batch_names_a_recording_whose_worker_died_not_as_not_run(tmp_path):
    """After a Ctrl-C or SIGTERM, each unfinished recording's line comes from its future: cancelled, not
    run; its worker died (BrokenProcessPool) with its folder there, the worker-died error (was "not
    run" for every future that ended with an exception); a bug, its error."""
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool

    def done(exc=None, value=None):
        f = Future()
        f.set_exception(exc) if exc is not None else f.set_result(value)
        return f

    (tmp_path / "started").mkdir()
    cancelled = Future()
    cancelled.cancel()
    assert run_mod._stopped_result(cancelled, str(tmp_path / "queued"))["not_run"] is True
    r = run_mod._stopped_result(done(BrokenProcessPool("x")), str(tmp_path / "started"))
    assert "not_run" not in r and r["error"].startswith("its worker process died")
    r = run_mod._stopped_result(done(RuntimeError("a bug")), str(tmp_path / "started"))
    assert r["error"] == "RuntimeError: a bug"
    ok = {"out_dir": str(tmp_path / "started"), "frames": 3, "interrupted": True}
    assert run_mod._stopped_result(done(value=ok), ok["out_dir"]) == ok


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux /proc")
def test_a_batch_worker_signalled_by_hand_makes_the_batch_exit_130(tmp_path):
    """A SIGINT to one batch worker alone (`kill -INT <its pid>`) interrupts its recording; the batch
    carried on and exited 0, as if every recording had run to its end. Now the other recordings still
    run, and the batch exits 130 naming how many were interrupted or not run."""
    import signal

    rc, err, out = _signal_v1s_worker(tmp_path, signal.SIGINT, wait_for="summary.json")
    assert rc == 130, err
    s = json.loads((out / "v1" / "summary.json").read_text())
    assert s["interrupted"] is True and s["frames"] == 2, s
    assert f"{out / 'v1'}: interrupted; what it did is in the folder" in err
    # the signalled worker starts no other recording (it may take v2 or v3 first: "not run"); a recording
    # the other worker took runs to its end
    ran = [n for n in ("v2", "v3") if (out / n / "summary.json").is_file()]
    for n in ran:
        assert json.loads((out / n / "summary.json").read_text())["frames"] == 20, n
    for n in {"v2", "v3"} - set(ran):
        assert f"{out / n}: not run (its worker process was interrupted)" in err, err
    assert (f"{3 - len(ran)} of 3 batch runs were interrupted or not run (a signal reached a worker "
            "process)") in err, err



@pytest.mark.parametrize("stopped", [False, True])
def test_a_batch_recording_interrupted_before_its_folder_names_who_stopped_it(tmp_path, monkeypatch, stopped):
    """A recording interrupted before its folder existed is printed as not run; its line said "the
    batch was stopped" also when the signal had reached its worker alone (and the batch ran on). Now
    it says which: the batch's stop event set by the time the worker took the signal, or not."""
    import signal

    from pipeline.commands.run import _batch_line
    from pipeline.run import _BATCH_WORKER, _batch_pool_job, _batch_worker_init

    class Event:  # the parent's stop: not set when the recording starts
        flag = False

        def is_set(self):
            return self.flag

    stop = Event()

    def interrupted(args):  # the signal, after the batch's stop event was set (or not)
        stop.flag = stopped
        raise KeyboardInterrupt

    monkeypatch.setattr(run_mod, "_batch_worker", interrupted)
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(run_mod, "_BATCH_WORKER", dict(_BATCH_WORKER))
    try:
        _batch_worker_init(stop)
        r = _batch_pool_job(({}, str(tmp_path / "v1"), None))
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
    assert r["interrupted"] is True and not (tmp_path / "v1").exists()
    why = "the batch was stopped" if stopped else "its worker process was interrupted"
    assert _batch_line(r) == f"{tmp_path / 'v1'}: not run ({why})"
