"""``fisheye-des demo [--out DIR]``: the whole system in about a minute, with nothing but this package.

1. simulates a short flight with stationary and moving obstacles (``configs/scenarios/demo.yaml``,
   a 0.30 m forward stereo pair at 640x360 by default; ``--scenario`` picks another) -> ``DIR/sim/``
   (videos, grey when the detector works on grey, timestamps, camchain.yaml, trajectory.tum, gt.jsonl);
2. runs the full pipeline on the rendered video -> ``DIR/run/`` (tracks.jsonl, summary.json,
   config.resolved.yaml, annotated.mp4, range/polar plots);
3. evaluates it against the ground truth -> ``DIR/eval/`` (metrics.json, metrics.txt, plots);
4. writes ``DIR/report.md`` / ``report.json``: range errors (median, p90, share within 5 % and 10 %),
   bound coverage, speed errors, per-obstacle figures, frames/s, wall times; scored on the confirmed
   tracks' reports on obstacles (see :func:`run_demo`).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Annotated, Any

import typer

DEFAULT_SCENARIO = "demo.yaml"  # stereo: ranges, bounds and obstacle velocity; stationary and moving
DEFAULT_RESOLUTION = (640, 360)


def _pct(v: Any) -> str:
    return "-" if v is None else f"{100 * v:.1f}%"


def _num(v: Any, fmt: str = "{:.2f}") -> str:
    return "-" if v is None else fmt.format(v)


def run_demo(
    out: str | Path,
    scenario: str | Path | None = None,
    resolution: tuple[int, int] | None = DEFAULT_RESOLUTION,
    seconds: float | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Simulate, run, evaluate and report; returns the report's figures (also in ``report.json``).

    Args:
        out: output folder (sim/, run/, eval/, report.md, report.json).
        scenario: scenario YAML (default ``configs/scenarios/demo.yaml``); a bare name is looked up in
            ``configs/scenarios``.
        resolution: (width, height) to render at (the lens scaled), None = the scenario's own.
        seconds: shorten the flight (None = the scenario's duration).

    What is scored (the figures of the report): the **confirmed** tracks' reports whose bearing hits
    an obstacle (the renderer's ray cast along the reported bearing hits it first); their truth is
    the depth of that hit. Counted, not scored: tentative tracks (not yet reported to a user as
    obstacles), and confirmed reports whose bearing hits the ground or the sky, among them the
    "near misses" the evaluator associates with an obstacle because the ray passes within its
    tolerance of the obstacle's bounding sphere (mostly ground features around a tall obstacle: a
    pole's bounding sphere is as wide as the pole is tall); their range error is given separately.
    """
    from estimators.errors import ConfigError
    from pipeline.config import find_preset, load_config, scenarios_dir
    from pipeline.evaluate import (
        evaluate,
        format_table,
        range_metrics,
        scored_range_metrics,
        scored_reports,
        write_outputs,
    )
    from pipeline.run import run, wants_grey
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.writer import VIDEO_EXT, simulate
    from pipeline.sinks import make_output_dir, write_json

    out = make_output_dir(out)
    scn_path = find_preset(DEFAULT_SCENARIO if scenario is None else scenario, scenarios_dir(), "scenario")
    wall: dict[str, float] = {}
    cli: dict[str, Any] = {
        "outputs.annotated_video": True,
        "outputs.plots": True,
        "outputs.progress": progress,
    }
    grey = wants_grey(load_config(None, cli=cli))  # a grey-only detector: render grey, decode as it is

    t0 = time.perf_counter()
    scn = load_scenario(scn_path)
    sim = simulate(scn, out / "sim", seconds=seconds, resolution=resolution, progress=progress, grey=grey)
    wall["simulate_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    videos = [str(out / "sim" / f"{cam}{VIDEO_EXT}") for cam in sim.cameras]
    for v in videos:
        if not Path(v).is_file():
            raise ConfigError(f"{v}: the simulator did not write the expected video")
    cli.update(
        {
            "inputs.videos": videos,
            "rig.calibration": str(out / "sim" / "camchain.yaml"),
            "ego_motion.trajectory": str(out / "sim" / "trajectory.tum"),
        }
    )
    cfg = load_config(None, cli=cli)
    res = run(cfg, out / "run")
    wall["run_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ev = evaluate([(out / "run", out / "sim")])
    with warnings.catch_warnings():  # matplotlib's layout notes are not for a new user's first screen
        warnings.simplefilter("ignore", UserWarning)
        write_outputs(ev, out / "eval", plots=True)
    wall["evaluate_s"] = time.perf_counter() - t0
    wall["total_s"] = sum(wall.values())

    m = ev.metrics
    rows = ev.rows  # every non-lost report inside the scenario's time span
    conf = [r for r in rows if r.status == "confirmed"]
    on_obstacle = scored_reports(rows)
    near = [r for r in conf if r.obstacle_id is not None and r.hit == "near"]
    counts = {
        "reports": len(rows),
        "tentative": sum(1 for r in rows if r.status == "tentative"),
        "confirmed": len(conf),
        "confirmed_on_obstacles": len(on_obstacle),
        "confirmed_near_miss": len(near),
        "confirmed_on_ground": sum(1 for r in conf if r.hit == "ground" and r.obstacle_id is None),
        "confirmed_on_sky": sum(1 for r in conf if r.hit == "sky" and r.obstacle_id is None),
    }
    obstacles = {}
    for key, om in m.get("by_obstacle", {}).items():
        oid = int(key.rsplit("/", 1)[1])
        sel = [r for r in on_obstacle if r.obstacle_id == oid]
        obstacles[str(oid)] = {
            "kind": om["kind"],
            "moving": om["moving"],
            "detection_coverage": om["detection_coverage"],
            "track_ids": len(om["track_ids"]),
            **range_metrics(sel),
        }
    summary = res.summary
    figures = {
        "scenario": scn.name,
        "scenario_file": str(scn_path),
        "cameras": list(sim.cameras),
        "resolution": list(sim.resolution),
        "frames": res.frames,
        "tracks": res.tracks,
        "pipeline_frames_per_s": res.frames_per_s,
        "pipeline_cpu_ms_per_frame": (
            1e3 * summary["cpu_s_per_frame"] if summary.get("cpu_s_per_frame") is not None else None
        ),
        "wall": wall,
        "scored": "confirmed tracks' reports whose bearing hits an obstacle (renderer ray cast)",
        "counts": counts,
        **scored_range_metrics(rows),  # "confirmed", "stationary", "moving"
        "near_miss": range_metrics(near),
        "by_obstacle": obstacles,
        "ground": m.get("ground", {}),
        "all_reports": m.get("overall", {}),  # tentative ones too: the evaluator's own overall row
        "detection_coverage": m.get("overall", {}).get("detection_coverage"),
    }
    write_json(out / "report.json", figures)
    (out / "report.md").write_text(_report_md(figures, format_table(m), out))
    return figures


def _report_md(f: dict[str, Any], table: str, out: Path) -> str:
    groups = (f["confirmed"], f["stationary"], f["moving"])
    w = f["wall"]
    c = f["counts"]

    def row(label: str, key: str, fmt) -> str:
        return f"| {label} | " + " | ".join(fmt(g.get(key)) for g in groups) + " |"

    width, height = f["resolution"]
    n_stat = sum(1 for o in f["by_obstacle"].values() if not o["moving"])
    n_mov = len(f["by_obstacle"]) - n_stat
    lines = [
        f"# fisheye-des demo: {f['scenario']}",
        "",
        f"{len(f['cameras'])} camera(s) ({', '.join(f['cameras'])}) at {width}x{height}, "
        f"{f['frames']} frames; {n_stat} stationary and {n_mov} moving obstacles.",
        "",
        "Scored: the reports of confirmed tracks whose bearing hits an obstacle "
        f"({c['confirmed_on_obstacles']} of {c['confirmed']} confirmed reports; the renderer's ray along "
        f"the reported bearing gives the true range). Not scored: {c['tentative']} tentative reports; "
        f"confirmed ones on the ground ({c['confirmed_on_ground']}) or the sky ({c['confirmed_on_sky']}); "
        f"{c['confirmed_near_miss']} near misses (ray within 2 deg of an obstacle's bounding sphere but "
        f"hitting what is behind it; median range error {_pct(f['near_miss'].get('rel_err_median'))} "
        "against the obstacle).",
        "",
        "| | all | stationary | moving |",
        "| --- | --- | --- | --- |",
        row("reports with a range", "ranged", lambda v: _num(v, "{:d}")),
        row("range error, median (relative)", "rel_err_median", _pct),
        row("range error, 90th percentile", "rel_err_p90", _pct),
        row("within 5 %", "within_5pct", _pct),
        row("within 10 %", "within_10pct", _pct),
        row("bound coverage (truth inside [min, max])", "bounds_coverage", _pct),
        row("bounds without an upper end", "bounds_unbounded_share", _pct),
        row("speed error, median (m/s)", "speed_err_median_mps", _num),
        row("speed error, 90th percentile (m/s)", "speed_err_p90_mps", _num),
        "",
        "| obstacle | found in frames | track ids | ranged | median error | within 10 % |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for oid, o in f["by_obstacle"].items():
        lines.append(
            f"| {oid} {o['kind']}{' (moving)' if o['moving'] else ''} | {_pct(o['detection_coverage'])} | "
            f"{o['track_ids']} | {o.get('ranged', 0)} | {_pct(o.get('rel_err_median'))} | "
            f"{_pct(o.get('within_10pct'))} |"
        )
    cpu = f.get("pipeline_cpu_ms_per_frame")
    lines += [
        "",
        f"Pipeline speed: {f['pipeline_frames_per_s']:.1f} frames/s"
        + (f" ({cpu:.0f} ms CPU per frame set)" if cpu is not None else "")
        + f". Wall time: simulate {w['simulate_s']:.1f} s, run {w['run_s']:.1f} s, "
        f"evaluate {w['evaluate_s']:.1f} s, total {w['total_s']:.1f} s.",
        "",
        f"Files (in `{out}`):",
        "- annotated video: `run/annotated.mp4`; plots: `run/range_over_time.png`, `run/polar_map.png`, "
        "`eval/plots/`",
        "- tracks: `run/tracks.jsonl` (one line per frame), `run/summary.json`; metrics: `eval/metrics.txt`, "
        "`eval/metrics.json`; this report: `report.md`, `report.json`",
        "",
        "## Full evaluation table (every non-lost report, tentative ones too)",
        "",
        "```",
        table,
        "```",
        "",
    ]
    return "\n".join(lines)


def register(app: typer.Typer) -> None:
    @app.command("demo")
    def demo_command(
        out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("runs/demo"),
        scenario: Annotated[
            Path | None, typer.Option("--scenario", help="Scenario YAML or name in configs/scenarios/.")
        ] = None,
        resolution: Annotated[
            str, typer.Option("--resolution", help="WIDTHxHEIGHT to render at, or 'native'.")
        ] = f"{DEFAULT_RESOLUTION[0]}x{DEFAULT_RESOLUTION[1]}",
        seconds: Annotated[
            float | None, typer.Option("--seconds", help="Shorten the flight to S seconds.")
        ] = None,
        no_progress: Annotated[bool, typer.Option("--no-progress", help="No progress bars.")] = False,
    ) -> None:
        """Simulate a flight, range its obstacles, evaluate against the truth, and write a report."""
        import sys

        from estimators.errors import ConfigError

        res: tuple[int, int] | None = None
        if resolution.lower() != "native":
            try:
                w, h = (int(x) for x in resolution.lower().split("x"))
            except ValueError:
                raise ConfigError(
                    f"--resolution: expected WIDTHxHEIGHT or 'native', got {resolution!r}"
                ) from None
            res = (w, h)
        f = run_demo(out, scenario, res, seconds, progress=not no_progress)
        print((out / "report.md").read_text().split("## Full evaluation table")[0].rstrip(), file=sys.stdout)
        print(f"\nfull report: {out / 'report.md'}", file=sys.stdout)
        _ = f
