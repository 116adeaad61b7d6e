"""`fisheye-des demo` on a tiny scenario: simulate -> run -> evaluate -> report, every file present."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("pipeline.sim.writer")
pytest.importorskip("pipeline.evaluate")
pytest.importorskip("trackers.frontend")


def test_demo_on_a_tiny_scenario(tmp_path, capsys):
    from pipeline.cli import main

    out = tmp_path / "demo"
    rc = main(
        [
            "demo",
            "--out",
            str(out),
            "--scenario",
            "ci_small",
            "--resolution",
            "native",
            "--seconds",
            "0.5",
            "--no-progress",
        ]
    )
    assert rc == 0
    for f in (
        "sim/cam0.mkv",
        "sim/gt.jsonl",
        "run/tracks.jsonl",
        "run/summary.json",
        "run/config.resolved.yaml",
        "run/annotated.mp4",
        "run/range_over_time.png",
        "run/polar_map.png",
        "eval/metrics.json",
        "report.md",
        "report.json",
    ):
        assert (out / f).is_file(), f
    lines = (out / "run" / "tracks.jsonl").read_text().splitlines()
    assert len(lines) == 15  # 0.5 s at 30 frames/s
    rep = json.loads((out / "report.json").read_text())
    assert rep["frames"] == 15 and rep["scenario"] == "ci_small" and rep["pipeline_frames_per_s"] > 0
    n_reports = sum(len(json.loads(x)["tracks"]) for x in lines)
    assert 0 < rep["overall"]["reports"] <= n_reports  # the evaluator scored reports of this run
    text = (out / "report.md").read_text()
    assert "range error, median" in text and "bound coverage" in text and "frames/s" in text
    assert "fisheye-des demo: ci_small" in capsys.readouterr().out


def test_demo_unknown_scenario_is_one_line_error(tmp_path, capsys):
    from pipeline.cli import main

    rc = main(["demo", "--out", str(tmp_path), "--scenario", "no_such_scenario"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no_such_scenario: scenario not found" in err[0]
