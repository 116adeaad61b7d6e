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
    from test_conventions import camchain_names, check_run_folder

    check_run_folder(out / "run", camchain_names(out / "sim" / "camchain.yaml"))
    lines = (out / "run" / "tracks.jsonl").read_text().splitlines()
    assert len(lines) == 15  # 0.5 s at 30 frames/s
    rep = json.loads((out / "report.json").read_text())
    assert rep["frames"] == 15 and rep["scenario"] == "ci_small" and rep["pipeline_frames_per_s"] > 0
    tracks = [t for x in lines for t in json.loads(x)["tracks"]]
    c = rep["counts"]
    # what is scored: confirmed tracks only (counted here straight from tracks.jsonl)
    assert c["confirmed"] == sum(1 for t in tracks if t["status"] == "confirmed")
    assert c["tentative"] == sum(1 for t in tracks if t["status"] == "tentative")
    on = ("confirmed_on_obstacles", "confirmed_near_miss", "confirmed_on_ground", "confirmed_on_sky")
    assert sum(c[k] for k in on) == c["confirmed"]
    assert rep["confirmed"]["reports"] == c["confirmed_on_obstacles"]
    assert rep["confirmed"]["reports"] == rep["stationary"]["reports"] + rep["moving"]["reports"]
    assert set(rep["by_obstacle"]) == {"1", "2", "3"} and rep["by_obstacle"]["3"]["moving"] is True
    text = (out / "report.md").read_text()
    for words in ("range error, median", "within 5 %", "bound coverage", "speed error", "frames/s",
                  "Scored: the reports of confirmed tracks", "run/annotated.mp4"):
        assert words in text
    printed = capsys.readouterr().out
    assert "fisheye-des demo: ci_small" in printed and "Full evaluation table" not in printed
    assert str(out / "report.md") in printed


def test_demo_unknown_scenario_is_one_line_error(tmp_path, capsys):
    from pipeline.cli import main

    rc = main(["demo", "--out", str(tmp_path), "--scenario", "no_such_scenario"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "no_such_scenario: scenario not found" in err[0]
