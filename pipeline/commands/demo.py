"""``fisheye-des demo [--out DIR]``: the whole system in about a minute, with nothing but this package.

1. simulates a short flight with stationary and moving obstacles (``configs/scenarios/stereo_flying.yaml``,
   a 0.30 m forward stereo pair, 3 s at 640x360 by default; ``--scenario`` picks another) -> ``DIR/sim/``
   (videos, timestamps, camchain.yaml, trajectory.tum, gt.jsonl);
2. runs the full pipeline on the rendered video -> ``DIR/run/`` (tracks.jsonl, summary.json,
   config.resolved.yaml, annotated.mp4, range/polar plots);
3. evaluates it against the ground truth -> ``DIR/eval/`` (metrics.json, metrics.txt, plots);
4. writes ``DIR/report.md``: range errors, bound coverage, speed errors, frames/s, wall times.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Any

import typer

DEFAULT_SCENARIO = "stereo_flying.yaml"  # stereo: ranges, bounds and obstacle velocity
DEFAULT_RESOLUTION = (640, 360)


def scenarios_dir() -> Path:
    """``configs/scenarios`` of the repository this package runs from."""
    return Path(__file__).resolve().parents[2] / "configs" / "scenarios"


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
    detector: str | None = None,
) -> dict[str, Any]:
    """Simulate, run, evaluate and report; returns the report's figures (also in ``report.json``).

    Args:
        out: output folder (sim/, run/, eval/, report.md).
        scenario: scenario YAML (default ``configs/scenarios/stereo_flying.yaml``); a bare name is
            looked up in ``configs/scenarios``.
        resolution: (width, height) to render at (the lens scaled), None = the scenario's own.
        seconds: shorten the flight (None = the scenario's duration).
        detector: detector name for the run (default: the config default, ``orb``).
    """
    from estimators.errors import ConfigError
    from pipeline.config import load_config
    from pipeline.evaluate import evaluate, format_table, write_outputs
    from pipeline.run import run
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.writer import VIDEO_EXT, simulate
    from pipeline.sinks import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scn_path = Path(scenario) if scenario is not None else scenarios_dir() / DEFAULT_SCENARIO
    if not scn_path.is_file() and (scenarios_dir() / scn_path).is_file():
        scn_path = scenarios_dir() / scn_path
    if not scn_path.is_file() and (scenarios_dir() / f"{scn_path}.yaml").is_file():
        scn_path = scenarios_dir() / f"{scn_path}.yaml"
    if not scn_path.is_file():
        raise ConfigError(f"{scenario}: scenario not found (neither a file nor a name in {scenarios_dir()})")
    wall: dict[str, float] = {}

    t0 = time.perf_counter()
    scn = load_scenario(scn_path)
    sim = simulate(scn, out / "sim", seconds=seconds, resolution=resolution, progress=progress)
    wall["simulate_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    videos = [str(out / "sim" / f"{cam}{VIDEO_EXT}") for cam in sim.cameras]
    for v in videos:
        if not Path(v).is_file():
            raise ConfigError(f"{v}: the simulator did not write the expected video")
    cli: dict[str, Any] = {
        "inputs.videos": videos,
        "rig.calibration": str(out / "sim" / "camchain.yaml"),
        "ego_motion.trajectory": str(out / "sim" / "trajectory.tum"),
        "outputs.annotated_video": True,
        "outputs.plots": True,
        "outputs.progress": progress,
    }
    if detector:
        cli["detector.name"] = detector
    cfg = load_config(None, cli=cli)
    res = run(cfg, out / "run")
    wall["run_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ev = evaluate([(out / "run", out / "sim")])
    write_outputs(ev, out / "eval", plots=True)
    wall["evaluate_s"] = time.perf_counter() - t0
    wall["total_s"] = sum(wall.values())

    m = ev.metrics
    ov = m.get("overall", {})
    figures = {
        "scenario": scn.name,
        "cameras": list(sim.cameras),
        "resolution": list(sim.resolution),
        "frames": res.frames,
        "tracks": res.tracks,
        "pipeline_frames_per_s": res.frames_per_s,
        "wall": wall,
        "overall": ov,
        "stationary": m.get("by_motion", {}).get("stationary", {}),
        "moving": m.get("by_motion", {}).get("moving", {}),
        "by_obstacle": m.get("by_obstacle", {}),
    }
    write_json(out / "report.json", figures)
    (out / "report.md").write_text(_report_md(figures, format_table(m), out))
    return figures


def _report_md(f: dict[str, Any], table: str, out: Path) -> str:
    groups = (f["overall"], f["stationary"], f["moving"])
    w = f["wall"]

    def row(label: str, key: str, fmt) -> str:
        return f"| {label} | " + " | ".join(fmt(g.get(key)) for g in groups) + " |"

    width, height = f["resolution"]
    lines = [
        f"# fisheye-des demo: {f['scenario']}",
        "",
        f"{len(f['cameras'])} camera(s) ({', '.join(f['cameras'])}) at {width}x{height}, "
        f"{f['frames']} frames, {f['tracks']} obstacle tracks. Files are relative to `{out}`.",
        "",
        "| | all | stationary | moving |",
        "| --- | --- | --- | --- |",
        row("reports ranged", "ranged", lambda v: _num(v, "{:d}")),
        row("range error, median (relative)", "rel_err_median", _pct),
        row("range error, 90th percentile", "rel_err_p90", _pct),
        row("within 10 %", "within_10pct", _pct),
        row("bound coverage (truth inside [min, max])", "bounds_coverage", _pct),
        row("speed error, median (m/s; stereo-fed tracks)", "speed_err_median_mps", _num),
        f"| detection coverage (mean over obstacles) | {_pct(f['overall'].get('detection_coverage_mean'))}"
        " | | |",
        "",
        f"Pipeline speed: {f['pipeline_frames_per_s']:.1f} frames/s. Wall time: simulate "
        f"{w['simulate_s']:.1f} s, run {w['run_s']:.1f} s, evaluate {w['evaluate_s']:.1f} s, "
        f"total {w['total_s']:.1f} s.",
        "",
        "Files:",
        "- annotated video: `run/annotated.mp4`",
        "- tracks: `run/tracks.jsonl` (one line per frame), summary: `run/summary.json`",
        "- plots: `run/range_over_time.png`, `run/polar_map.png`, `eval/plots/`",
        "- metrics: `eval/metrics.json`, `eval/metrics.txt`",
        "",
        "## Full evaluation table",
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
        print(f"\nreport: {out / 'report.md'}", file=sys.stderr)
        _ = f
