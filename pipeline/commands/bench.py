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
            "--quick", help="Smoke test: one tiny resolution, a few frames (about a minute); for CI.",
        )] = False,
        out: Annotated[Path, typer.Option(
            "--out", "-o", help="Folder for bench.json and the measured runs.")] = Path("runs/bench"),
        cache: Annotated[Path | None, typer.Option(
            "--cache", help="Folder of rendered clips, reused across runs "
            "(default ~/.cache/fisheye-des/bench).")] = None,
        only: Annotated[list[str] | None, typer.Option(
            "--only", help=f"Measure only this part (repeatable): {', '.join(PARTS)}.")] = None,
    ) -> None:
        """Render (or reuse) simulator clips and measure the pipeline: frames/s at 640x480, 1280x720 and
        1920x1080, mono and stereo, on one pinned core and on all cores, beside decode-only; time per
        stage (median, p99); live latency at the camera's rate; frames/s against obstacles and
        features; memory over 10,000 frames; kornia beside ORB. Prints a table and writes
        OUT/bench.json. Targets are shown as met/missed; nothing fails on time."""
        import sys
        import time

        from pipeline.bench import BenchRun, default_cache_dir, make_plan

        t0 = time.perf_counter()
        run = BenchRun(make_plan(quick), out, cache or default_cache_dir(),
                       log=lambda m: print(m, file=sys.stderr, flush=True))
        run.run_all(only or None)
        text, _ = run.report()
        typer.echo(text)
        typer.echo(f"bench wall time: {time.perf_counter() - t0:.1f} s")
