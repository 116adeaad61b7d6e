"""``fisheye-des thesis``: reproduce the thesis's chapter-4 and appendix-A tables.

Every table is recomputed from its own printed inputs with the general estimators
(``estimators.geometry`` through ``estimators.thesis``); for each quantity the command prints the
thesis's value, ours, the difference and a verdict, then one line per inconsistency of the thesis.
``--json PATH`` also writes everything as JSON.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def _fmt(x: float | None, nd: int = 2) -> str:
    return "-" if x is None else f"{x:.{nd}f}"


def run(json_path: Path | None = None, echo=print) -> dict:
    """Compute the reproduction, print it with ``echo`` and return it as a JSON-ready dict."""
    from estimators import thesis

    rows = thesis.reproduce()
    notes = thesis.inconsistencies()
    summary = thesis.table_summary(rows)
    echo("Reproduction of the thesis's chapter 4 and appendix A tables (lengths in cm, as printed)")
    echo(
        "conventions: theta1/theta2 = interior angles at the first/second camera (pose); distance = "
        "range from the second (eq. 3.8 law of sines, via geometry.planar_triangulate) from the "
        "'Experimental' angles; error = |est - measured| / measured, measured of the second figure."
    )
    echo(
        "verdict 'reproduces': equal to the printed digits, or within the spread caused by rounding "
        "the printed inputs (angles to 0.1 deg or their printed digits, lengths to 0.1 cm)."
    )
    echo("")
    header = f"{'table':<6} {'quantity':<46} {'thesis':>9} {'ours':>9} {'diff':>8} {'tol':>7}  verdict"
    echo(header)
    echo("-" * len(header))
    for r in rows:
        echo(
            f"{r.table:<6} {(r.quantity + ' [' + r.unit + ']'):<46} {_fmt(r.thesis):>9} {_fmt(r.ours):>9} "
            f"{_fmt(r.diff):>8} {_fmt(r.tolerance):>7}  {r.verdict}" + (f"  ({r.note})" if r.note else "")
        )
    echo("")
    echo("Per table:")
    for k, v in summary.items():
        label = f"Section {k[4:]}" if k.startswith("sec ") else f"Table {k}"
        echo(f"  {label}: {v}")
    echo("")
    echo(f"Where the thesis is not self-consistent ({len(notes)}):")
    for line in notes:
        echo(f"  - {line}")
    result = {
        "rows": thesis.rows_as_dicts(rows),
        "tables": summary,
        "inconsistencies": notes,
    }
    if json_path is not None:
        import json

        from estimators.errors import InputError

        try:
            json_path.parent.mkdir(parents=True, exist_ok=True)
            json_path.write_text(json.dumps(result, indent=2) + "\n")
        except OSError as e:
            raise InputError(
                f"--json {json_path}: cannot write ({e.strerror}); expected a writable file path"
            ) from None
        echo(f"\nwrote {json_path}")
    return result


def register(app: typer.Typer) -> None:
    """Add the ``thesis`` sub-command to ``app``."""

    @app.command("thesis")
    def thesis_cmd(
        json_path: Annotated[
            Path | None, typer.Option("--json", help="Also write the results as JSON here.")
        ] = None,
    ) -> None:
        """Reproduce the thesis's tables (chapter 4, appendix A) with the general estimators."""
        run(json_path, echo=typer.echo)
