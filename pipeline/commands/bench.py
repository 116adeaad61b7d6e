"""``fisheye-des bench``: throughput, per-stage time, live latency, memory and scaling, side by side."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

PARTS = ("throughput", "live", "scaling", "memory", "detectors", "profile")


def register(app: typer.Typer) -> None:
    @app.command("bench")
    def bench_cmd(
        quick: Annotated[bool, typer.Option(
            "--quick", help="Smoke test: one tiny resolution, a few frames (about a minute); for CI. "
            "Its live part adds one 20-frame all-cores run with live.deferred_detection.",
        )] = False,
        out: Annotated[Path, typer.Option(
            "--out", "-o", help="Folder for bench.json and the measured runs.")] = Path("runs/bench"),
        cache: Annotated[Path | None, typer.Option(
            "--cache", help="Folder of rendered clips, reused across runs "
            "(default ~/.cache/fisheye-des/bench).")] = None,
        only: Annotated[list[str] | None, typer.Option(
            "--only", help=f"Measure only this part (repeatable): {', '.join(PARTS)}.")] = None,
        repeat: Annotated[int | None, typer.Option(
            "--repeat", help="Take the one-core throughput (pipeline and decode-only) and the live "
            "latency (one core, and the informational all-cores runs) N times, in interleaved rounds; "
            "rows give the median (the verdict), min-max and the values per round (default 3; 1 with "
            "--quick, where the all-cores live runs are taken once whatever N is).")] = None,
    ) -> None:
        """Measure the pipeline's frames/s, per-stage time, live latency, memory and scaling.

        Renders (or reuses) simulator clips and measures: frames/s at 640x480, 1280x720 and
        1920x1080, mono and stereo, on one pinned core and on all cores, beside decode-only; time per
        stage (median, p99); live latency at the camera's rate on one pinned core, and, informational
        (the budget and the rounds under it, no met/missed: the target is defined on one core), on all
        cores synchronous and with live.deferred_detection (plus the detection worker's CPU share, the
        detections joined and their mean join lag in frames); frames/s against obstacles and
        features; memory over 10,000 frames; kornia beside ORB. Prints a table and writes
        OUT/bench.json. Targets are shown as met/missed on the median of --repeat rounds ("met (2/3 met:
        marginal)" when the rounds straddle the target); nothing fails on time."""
        import sys
        import time

        from estimators.errors import ConfigError
        from pipeline.bench import BenchRun, default_cache_dir, make_plan

        t0 = time.perf_counter()
        try:
            plan = make_plan(quick, repeat)
        except ConfigError as e:
            raise typer.BadParameter(str(e), param_hint="--repeat") from e
        run = BenchRun(plan, out, cache or default_cache_dir(),
                       log=lambda m: print(m, file=sys.stderr, flush=True))
        run.run_all(only or None)
        text, _ = run.report()
        typer.echo(text)
        typer.echo(f"bench wall time: {time.perf_counter() - t0:.1f} s")
