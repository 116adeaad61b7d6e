"""Bad input on the command line: one line naming what was wrong and what was expected, exit code 2,
nothing already written lost (run, live, evaluate)."""

from __future__ import annotations

import json

import pytest
from test_run_support import FakeFrontEnd, FakeFusion, mono_rig, write_video

from pipeline import live as live_mod
from pipeline import run as run_mod
from pipeline.cli import main


def _fake_stages(monkeypatch, front=None):
    for mod in (run_mod, live_mod):
        monkeypatch.setattr(mod, "build_rig", lambda cfg: mono_rig())
        monkeypatch.setattr(mod, "build_frontend", front or (lambda cfg, rig: FakeFrontEnd(rig)))
        monkeypatch.setattr(mod, "build_fusion", lambda cfg, rig, ego: FakeFusion())


def _err_lines(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("command", ["run", "live"])
def test_trajectory_and_speed_together_are_an_error_naming_both(tmp_path, monkeypatch, capsys, command):
    _fake_stages(monkeypatch)
    v = write_video(tmp_path / "cam0.mkv", 3, times=[0, 0.1, 0.2])
    traj = tmp_path / "traj.tum"
    traj.write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    src = ["--video", str(v)] if command == "run" else ["--camera", str(v)]
    rc = main([command, *src, "--trajectory", str(traj), "--speed-mps", "3", "--out", str(tmp_path / "o")])
    err = _err_lines(capsys)
    assert rc == 2 and len(err) == 1, err
    assert "--trajectory" in err[0] and "--speed-mps" in err[0] and "alternatives" in err[0]
    assert not (tmp_path / "o").exists()  # refused before anything is written
