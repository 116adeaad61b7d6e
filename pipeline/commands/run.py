"""``fisheye-des run [CONFIG] [--video PATH]... [--calibration PATH] [--trajectory PATH] [--out DIR]``
(``[--set k=v]...``)

Runs the pipeline over recorded videos (or image folders) and writes ``DIR/tracks.jsonl``,
``summary.json`` and ``config.resolved.yaml`` (CONVENTIONS.md "Command line contract"). Flags override
the config; without CONFIG the defaults apply and the rig follows from the calibration file (one
camera: monocular; two: stereo; the first ``--video`` is cam0). ``--batch`` runs several recordings
in parallel worker processes, one result folder each.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command("run")
    def run_command(
        config: Annotated[Path | None, typer.Argument(help="YAML config (see configs/); optional.")] = None,
        video: Annotated[
            list[str] | None, typer.Option("--video", help="Video per camera (repeat; the first is cam0).")
        ] = None,
        images: Annotated[
            list[Path] | None, typer.Option("--images", help="Image folder per camera instead of videos.")
        ] = None,
        calibration: Annotated[
            Path | None, typer.Option("--calibration", help="Calibration file (Kalibr, OpenCV, ROS).")
        ] = None,
        trajectory: Annotated[
            Path | None, typer.Option("--trajectory", help="TUM trajectory (T_W_B) of the body.")
        ] = None,
        speed: Annotated[
            float | None, typer.Option("--speed-mps", help="Constant forward speed, m/s.")
        ] = None,
        out: Annotated[
            Path | None, typer.Option("--out", help="Output folder (default: outputs.dir, else runs/run).")
        ] = None,
        set_: Annotated[
            list[str] | None, typer.Option("--set", help="Override a config key: section.key=value (repeat).")
        ] = None,
        annotate: Annotated[bool, typer.Option("--annotate", help="Also write annotated.mp4.")] = False,
        plots: Annotated[bool, typer.Option("--plots", help="Also write PNG plots.")] = False,
        batch: Annotated[
            list[Path] | None,
            typer.Option("--batch", help="Recordings to run in parallel (videos or folders; repeat the flag "
                         "for each: --batch A --batch B); a result folder each."),
        ] = None,
        jobs: Annotated[
            int | None,
            typer.Option("--jobs", help="Worker processes for --batch (only with it; default one per CPU, "
                         "at most one per recording)."),
        ] = None,
        no_progress: Annotated[bool, typer.Option("--no-progress", help="No progress bar.")] = False,
        describe: Annotated[
            bool, typer.Option("--describe-config", help="Print every config key and exit.")
        ] = False,
    ) -> None:
        """Range obstacles in recorded fisheye videos: tracks.jsonl, summary.json, config.resolved.yaml."""
        import sys

        from pipeline.commands._overrides import check_config_argument, rig_and_motion_overrides
        from pipeline.config import describe_config, load_config
        from pipeline.run import run, run_batch

        if describe:
            print(describe_config())
            return
        check_config_argument(config, {"--video": video, "--images": images, "--batch": batch})
        if jobs is not None and not batch:
            from estimators.errors import ConfigError

            raise ConfigError(f"--jobs {jobs} needs --batch: it is the number of worker processes that run "
                              "the --batch recordings in parallel; a single run uses one process")

        cli: dict = {}
        if video:
            cli["inputs.videos"] = list(video)
        if images:
            cli["inputs.images"] = [str(p) for p in images]
        cli.update(rig_and_motion_overrides(calibration, trajectory, speed, out, list(set_ or [])))
        if annotate:
            cli["outputs.annotated_video"] = True
        if plots:
            cli["outputs.plots"] = True
        if no_progress:
            cli["outputs.progress"] = False
        overrides = list(set_ or [])
        cfg = load_config(config, overrides, cli)
        if batch:
            names = None  # each recording folder's own camchain.yaml, else cam0
            if cfg.rig.calibration is not None or cfg.rig.cameras:
                from pipeline.run import build_rig

                names = list(build_rig(cfg).names)
            out_root = cfg.outputs.dir or Path("runs") / "batch"
            results = run_batch(  # refuses --jobs below 1 before anything is written
                cfg,
                list(batch),
                Path(out_root),
                workers=jobs,
                camera_names=names,
                config_source=config,
                on_done=lambda r: print(_batch_line(r), file=sys.stderr),
            )
            stopped = sum(1 for r in results if r.get("interrupted") or r.get("not_run"))
            if stopped:  # a signal to one worker alone (the batch's own stop raises KeyboardInterrupt)
                from pipeline.cli import interrupted

                bad = sum(1 for r in results if r.get("error"))
                raise interrupted(f"{stopped} of {len(results)} batch runs were interrupted or not run (a "
                                  "signal reached a worker process); the others ran to their end"
                                  + (f", {bad} of them with an error" if bad else "") + " (see above)")
            if any(r.get("error") for r in results):
                from estimators.errors import SourceError

                bad = sum(1 for r in results if r.get("error"))
                raise SourceError(f"{bad} of {len(results)} batch runs reported an error (see above)")
            return
        out_dir = cfg.outputs.dir or Path("runs") / "run"
        try:
            r = run(cfg, out_dir, config_source=config, overrides=overrides)
        except KeyboardInterrupt:
            from pipeline.cli import interrupted

            raise interrupted(f"interrupted; everything up to the last frame is in {out_dir}") from None
        print(
            f"{r.frames} frames, {r.tracks} tracks, {r.frames_per_s:.1f} frames/s"
            f" -> {r.out_dir / 'tracks.jsonl'}",
            file=sys.stderr,
        )


def _batch_line(r: dict) -> str:
    """The line ``run --batch`` prints for one recording's result (``run_batch``'s dict)."""
    if r.get("not_run") or (r.get("interrupted") and not Path(r["out_dir"]).is_dir()):
        return f"{r['out_dir']}: not run ({r.get('why', 'the batch was stopped')})"
    if r.get("interrupted"):
        return f"{r['out_dir']}: interrupted; what it did is in the folder"
    if r.get("error") and not Path(r["out_dir"]).is_dir():  # refused before its first frame
        return f"{r['out_dir']}: not run, no folder  ERROR {r['error']}"
    return (f"{r['out_dir']}: {r.get('frames', 0)} frames"
            + (f", {r['frames_per_s']:.1f} frames/s" if r.get("frames_per_s") else "")
            + (f"  ERROR {r['error']}" if r.get("error") else ""))
