"""``fisheye-des accuracy``: measure the fusion filter against the issue's numbers on simulated scenes.

Prints one table (ours, the thesis's two-frame law-of-sines method, the target, a verdict) and, with
``--out DIR``, writes ``DIR/accuracy.json`` (every metric, per scene) and ``DIR/accuracy.txt``.
``--set heldout`` scores the held-out scenes instead (``accuracy_heldout.*``), ``--set both`` both
sets side by side (``accuracy_both.*``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add the ``accuracy`` sub-command to ``app``."""

    @app.command("accuracy")
    def accuracy_cmd(
        quick: Annotated[
            bool, typer.Option("--quick", help="Few short scenes (CI smoke test, < 1 min).")
        ] = False,
        mode: Annotated[
            str,
            typer.Option("--mode", help="bearings (true bearings + noise) or pipeline (render, track)."),
        ] = "bearings",
        out: Annotated[
            Path | None, typer.Option("--out", help="Write accuracy.json / accuracy.txt here.")
        ] = None,
        pixel_sigma: Annotated[
            float, typer.Option("--pixel-sigma", help="Pixel noise (px, 1-sigma) of bearings mode.")
        ] = 0.5,
        seed: Annotated[int, typer.Option("--seed", help="Seed of the noise and of the random scenes.")] = 0,
        n_random: Annotated[
            int | None, typer.Option("--n-random", help="Random scenes per family (default 1 quick, 6 full).")
        ] = None,
        thesis_interval: Annotated[
            float,
            typer.Option("--thesis-interval", help="Frame interval (s) of the thesis's two-frame method."),
        ] = 0.5,
        max_speed: Annotated[
            float | None,
            typer.Option(
                "--max-speed", help="Max obstacle speed (m/s) for the bounds; default: the drone's speed."
            ),
        ] = None,
        scene: Annotated[
            list[str] | None,
            typer.Option("--scene", help="Only this scene of the chosen --set (repeat); default: all of it."),
        ] = None,
        scene_set: Annotated[
            str,
            typer.Option(
                "--set",
                help="Scene set: tuned (default: the scenes the fusion and grouping settings were "
                "fitted on), heldout (configs/scenarios/heldout_*.yaml, used to fit nothing) or both "
                "(each table, then side by side and per scene). With --out, heldout / both write "
                "accuracy_<set>.json / .txt.",
            ),
        ] = "tuned",
        reuse_frontend: Annotated[
            bool,
            typer.Option(
                "--reuse-frontend",
                help="Pipeline mode: replay the fusion over the front end's observations recorded by an "
                "earlier run into the same --out (runs/<scene>/observations.pkl) instead of tracking again; "
                "a recording made with other trackers/ sources, --quick, scenario text or front-end "
                "config is recorded again, not replayed.",
            ),
        ] = False,
    ) -> None:
        """Measure range, bounds, velocity and consistency of the fusion filter (and the thesis's method)."""
        from estimators.errors import ConfigError
        from estimators.fusion import FusionSettings
        from pipeline.accuracy import AccuracyOptions, run_accuracy

        if mode not in ("bearings", "pipeline"):
            raise ConfigError(f"accuracy --mode: expected 'bearings' or 'pipeline', got {mode!r}")
        opts = AccuracyOptions(
            mode=mode, quick=quick, pixel_sigma_px=pixel_sigma, seed=seed, n_random=n_random,
            thesis_interval_s=thesis_interval, scenes=tuple(scene) if scene else None,
            settings=FusionSettings(max_speed_mps=max_speed), reuse_frontend=reuse_frontend,
            scene_set=scene_set,
        )
        res = run_accuracy(opts, out, progress=lambda s: typer.echo(s, err=True))
        typer.echo(res["table"])
        typer.echo(f"elapsed {res['elapsed_s']:.1f} s" + (f"; wrote {res['written']}" if out else ""))
