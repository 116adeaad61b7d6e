"""``fisheye-des simulate SCENARIO.yaml --out DIR``: render a synthetic fisheye flight with ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def _parse_resolution(text: str | None) -> tuple[int, int] | None:
    from estimators.errors import ConfigError

    if text is None:
        return None
    parts = text.lower().replace("×", "x").split("x")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise ConfigError(f"--resolution: expected WIDTHxHEIGHT such as 1280x720, got {text!r}") from None
    if w < 16 or h < 16:
        raise ConfigError(f"--resolution: expected at least 16x16 pixels, got {text!r}")
    return w, h


def register(app: typer.Typer) -> None:
    @app.command("simulate")
    def simulate_cmd(
        scenario: Annotated[
            Path, typer.Argument(help="Scenario YAML, or a shipped preset's name (e.g. demo, mono_straight).")
        ],
        out: Annotated[Path, typer.Option("--out", "-o", help="Output folder (created).")],
        frames: Annotated[
            int | None, typer.Option("--frames", help="Number of frames (default: duration x fps).")
        ] = None,
        seconds: Annotated[
            float | None, typer.Option("--seconds", help="Duration in seconds instead of --frames.")
        ] = None,
        resolution: Annotated[
            str | None,
            typer.Option("--resolution", help="WIDTHxHEIGHT; the lens is scaled to it (same aspect)."),
        ] = None,
        progress: Annotated[bool, typer.Option("--progress/--no-progress", help="Progress bar.")] = True,
        grey: Annotated[bool, typer.Option("--grey", help="Write greyscale videos instead of BGR.")] = False,
    ) -> None:
        """Render raw fisheye video of a scenario, with its exact ground truth.

        Writes the videos, camchain.yaml, trajectory.tum, scene.yaml and gt.jsonl into OUT."""
        from pipeline.config import find_preset, scenarios_dir
        from pipeline.sim.scene import load_scenario
        from pipeline.sim.writer import simulate

        scn = load_scenario(find_preset(scenario, scenarios_dir(), "scenario"))
        res = simulate(scn, out, frames=frames, seconds=seconds, resolution=_parse_resolution(resolution),
                       progress=progress, grey=grey)
        w, h = res.resolution
        typer.echo(
            f"{scn.name}: wrote {res.frames_written} frames ({res.frames_dropped} dropped) of "
            f"{', '.join(res.cameras)} at {w}x{h} to {res.out_dir}; "
            f"render {res.render_s_per_frame * 1000:.0f} ms per frame "
            f"({res.render_cpu_s_per_frame * 1000:.0f} ms CPU)"
        )
