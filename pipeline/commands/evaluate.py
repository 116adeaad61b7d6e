"""``fisheye-des evaluate RUN_DIR SCENARIO_DIR [RUN_DIR SCENARIO_DIR ...] [--out DIR]``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    @app.command("evaluate")
    def evaluate_cmd(
        paths: Annotated[
            list[Path],
            typer.Argument(
                help="RUN_DIR SCENARIO_DIR pairs: a run's folder (tracks.jsonl) and the "
                "simulated scenario's folder (gt.jsonl, scene.yaml, trajectory.tum)."
            ),
        ],
        out: Annotated[
            Path | None, typer.Option("--out", "-o", help="Output folder (default RUN_DIR/eval).")
        ] = None,
        assoc_tol_deg: Annotated[
            float, typer.Option("--assoc-tol-deg", help="Angular tolerance for narrow misses.")
        ] = 2.0,
        plots: Annotated[bool, typer.Option("--plots/--no-plots", help="Range-vs-time PNGs.")] = True,
    ) -> None:
        """Range, bounds, velocity, consistency and detection metrics of runs against simulator truth.

        Writes metrics.json, metrics.txt, reports.jsonl and plots/ into OUT and prints the table. A run
        whose videos (its config.resolved.yaml) are not the scenario's is refused; inputs that cannot be
        checked (an image folder, a camera) are scored with a note."""
        from estimators.errors import InputError
        from pipeline.evaluate import evaluate, format_table, write_outputs

        if len(paths) % 2:
            raise InputError(f"evaluate: expected RUN_DIR SCENARIO_DIR pairs, got {len(paths)} paths")
        pairs = [(paths[i], paths[i + 1]) for i in range(0, len(paths), 2)]
        ev = evaluate(pairs, assoc_tol_deg=assoc_tol_deg)  # refuses a run of another scenario's videos
        out_dir = out if out is not None else Path(pairs[0][0]) / "eval"
        write_outputs(ev, out_dir, plots=plots)
        typer.echo(format_table(ev.metrics))
        typer.echo(f"\nwrote {out_dir / 'metrics.json'}")
        for note in ev.notes:  # inputs that could not be checked against the scenario's videos
            typer.echo(f"note: {note}", err=True)
