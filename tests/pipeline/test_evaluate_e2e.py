"""End to end: simulate the CI preset, run the pipeline on its video, evaluate the run (heavy)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

SCENARIOS = Path(__file__).resolve().parents[2] / "configs" / "scenarios"


@pytest.mark.heavy
def test_simulate_run_evaluate(tmp_path):
    from pipeline.cli import main

    sc, run, ev = tmp_path / "sc", tmp_path / "run", tmp_path / "ev"
    assert main(["simulate", str(SCENARIOS / "ci_small.yaml"), "--out", str(sc), "--no-progress"]) == 0
    assert main(["run", "--video", str(sc / "cam0.mkv"), "--calibration", str(sc / "camchain.yaml"),
                 "--trajectory", str(sc / "trajectory.tum"), "--out", str(run), "--no-progress"]) == 0
    assert main(["evaluate", str(run), str(sc), "--out", str(ev)]) == 0
    m = json.loads((ev / "metrics.json").read_text())
    assert m["overall"]["all_reports"] > 0
    assert set(m["by_obstacle"]) == {"ci_small/1", "ci_small/2", "ci_small/3"}
    print(json.dumps(m["overall"], indent=1))
