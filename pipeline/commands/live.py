"""``fisheye-des live [CONFIG] [--camera INDEX|URL]... [--calibration PATH] [--trajectory PATH] [--out DIR]``

Runs the pipeline on live cameras (device index or stream URL), always on the newest frame; writes
``DIR/tracks.jsonl`` (flushed per frame), ``summary.json`` (latency, stale frames, reopens) and the
resolved config. A video file as ``--camera`` is replayed at its real rate (testing without a camera).
``--trajectory`` may be a file that grows during the run.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command("live")
    def live_command(
        config: Annotated[Path | None, typer.Argument(help="YAML config (configs/live_webcam.yaml).")] = None,
        camera: Annotated[
            list[str] | None,
            typer.Option("--camera", help="Device index, URL, or a video file replayed at its real rate "
                         "(testing without a camera); repeat for each camera, cam0 first."),
        ] = None,
        calibration: Annotated[Path | None, typer.Option("--calibration", help="Calibration file.")] = None,
        trajectory: Annotated[
            Path | None, typer.Option("--trajectory", help="TUM trajectory (T_W_B); may grow during the run.")
        ] = None,
        speed: Annotated[float | None, typer.Option("--speed-mps", help="Forward speed, m/s.")] = None,
        out: Annotated[Path | None, typer.Option("--out", help="Output folder (default runs/live).")] = None,
        preview: Annotated[
            str | None,
            typer.Option("--preview", help="none | file (preview.mp4) | mjpeg (http://127.0.0.1:PORT/)."),
        ] = None,
        port: Annotated[
            int | None, typer.Option("--port", help="MJPEG preview port on 127.0.0.1 (with --preview mjpeg).")
        ] = None,
        duration: Annotated[float | None, typer.Option("--duration", help="Stop after S seconds.")] = None,
        set_: Annotated[list[str] | None, typer.Option("--set", help="section.key=value override.")] = None,
    ) -> None:
        """Range obstacles live from cameras; Ctrl-C stops with everything written."""
        import sys

        from pipeline.commands._overrides import check_config_argument, rig_and_motion_overrides
        from pipeline.config import load_config
        from pipeline.live import run_live

        check_config_argument(config, {"--camera": camera})
        cli: dict = {}
        if camera:
            cli["live.cameras"] = [int(c) if c.isdigit() else c for c in camera]
        cli.update(rig_and_motion_overrides(calibration, trajectory, speed, out, list(set_ or [])))
        if preview is not None:
            cli["live.preview"] = preview
        if port is not None:
            cli["live.preview_port"] = port
        if duration is not None:
            cli["live.duration_s"] = duration
        cfg = load_config(config, list(set_ or []), cli)
        if port is not None and cfg.live.preview != "mjpeg":
            from estimators.errors import ConfigError

            raise ConfigError(f"--port {port} is the MJPEG preview's port, but live.preview is "
                              f"'{cfg.live.preview}'; give --preview mjpeg too, or drop --port")
        out_dir = cfg.outputs.dir or Path("runs") / "live"
        try:
            r = run_live(cfg, out_dir, on_event=lambda m: print(m, file=sys.stderr))
        except KeyboardInterrupt:
            from pipeline.cli import interrupted

            raise interrupted(f"stopped; tracks.jsonl and summary.json are in {out_dir}") from None
        lat = r.latency
        sm = r.summary
        before = sm.get("frames_before_trajectory", 0)
        late = sm.get("frames_without_pose", 0) - before
        print(
            f"{r.frames} frames, {r.stale} stale frames dropped"
            + (f", {late} skipped without a pose ({_late_text(sm.get('pose_gap_after_s'), cfg)})"
               if late else "")
            + (f", {before} skipped before the trajectory's first pose (up to "
               f"{sm['pose_gap_before_s']:.3f} s before it: its writer started after the camera, or it runs "
               "on another clock, which needs ego_motion.time_offset_s, its time minus the frame's, or "
               "live.clock)"
               if before else "")
            + f", latency median {1000 * lat.get('median_s', 0):.1f} ms p99 "
            f"{1000 * lat.get('p99_s', 0):.1f} ms -> {r.out_dir / 'tracks.jsonl'}",
            file=sys.stderr,
        )


def _late_text(gap_s: float | None, cfg) -> str:
    """Why frames past the trajectory's last pose were skipped, for the closing line: the farthest one's
    distance past it and, when that is far beyond what a writer lags (over 1 s and 10 waits), the clock."""
    text = "the trajectory did not reach their time within live.trajectory_wait_s"
    if gap_s is None:
        return text
    text += f"; the farthest was {gap_s:.3f} s past its last pose"
    if gap_s > max(1.0, 10 * cfg.live.trajectory_wait_s):
        text += (": a trajectory on another clock needs ego_motion.time_offset_s, its time minus the "
                 "frame's, or live.clock")
    return text
