"""`fisheye-des --help`: every command has a one-line summary in the command list."""

from __future__ import annotations

import inspect

import pytest
import typer

from pipeline.cli import COMMANDS, app


@pytest.mark.parametrize("name", COMMANDS)
def test_every_command_has_a_one_line_summary(name):
    cmd = typer.main.get_command(app).commands[name]
    summary = cmd.short_help or inspect.cleandoc(cmd.help or "").split("\n\n")[0]
    assert summary.strip() and "\n" not in summary, summary  # the list shows the first paragraph as is


def test_top_level_help_lists_each_command_on_its_own_summary(capsys):
    from pipeline.cli import main

    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert f" {name} " in out
    assert "frames/s at 640x480, 1280x720 and" not in out  # bench's details stay in `bench --help`
    assert "scene.yaml and gt.jsonl into OUT" not in out  # simulate's too


@pytest.mark.parametrize("name", COMMANDS)
def test_a_command_s_help_paragraphs_are_not_broken_at_the_source_s_line_ends(name):
    """typer keeps single line breaks in a docstring's later paragraphs: `bench --help` showed its
    description broken mid-sentence at the source's line ends; each paragraph is one line now."""
    cmd = typer.main.get_command(app).commands[name]
    for par in (cmd.help or "").split("\n\n"):
        assert "\n" not in par, par


REPO = __import__("pathlib").Path(__file__).resolve().parents[2]


def _options(name: str) -> set[str]:
    cmd = typer.main.get_command(app).commands[name]
    return {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}


@pytest.mark.parametrize("name", ["run", "live"])
def test_readme_rows_of_run_and_live_show_the_motion_input_with_real_options(name):
    """The README's usage row names the body's motion (--trajectory or --speed-mps) and only options the
    command has."""
    import re

    row = next(ln for ln in (REPO / "README.md").read_text().splitlines()
               if ln.startswith(f"| `fisheye-des {name} "))
    usage = row.split("`")[1]
    assert "(--trajectory traj.tum \\| --speed-mps V)" in usage
    assert set(re.findall(r"--[a-z][a-z-]*", usage)) <= _options(name)


def test_shipped_config_points_to_describe_config():
    head = (REPO / "configs" / "mono_forward.yaml").read_text().splitlines()[:5]
    assert any("fisheye-des run --describe-config" in ln for ln in head)
    assert "--describe-config" in _options("run")


def test_exit_code_1_is_an_unexpected_error_with_its_traceback_as_the_readme_says(tmp_path):
    """main() re-raises what is no fisheye-des error (a bug), and a fisheye-des error under --debug:
    Python prints the traceback and exits with 1; the README's list of exit codes says so."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(REPO)}
    bug = ("import sys, pipeline.cli as c\n"
           "def app(**kw): raise ZeroDivisionError('a bug')\n"
           "c.app = app\nsys.exit(c.main(['run']))\n")
    r = subprocess.run([sys.executable, "-c", bug], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" in r.stderr and "ZeroDivisionError: a bug" in r.stderr
    args = ["--debug", "run", "--video", str(tmp_path / "none.mkv"), "--speed-mps", "1",
            "--out", str(tmp_path / "o")]
    r = subprocess.run([sys.executable, "-m", "pipeline.cli", *args], capture_output=True, text=True, env=env,
                       cwd=tmp_path)
    assert r.returncode == 1 and "Traceback" in r.stderr, r.stderr
    readme = " ".join((REPO / "README.md").read_text().split())
    assert ("130 interrupted (Ctrl-C, or SIGTERM as systemd, a launch file or `docker stop` send it; "
            "outputs written so far are kept, `summary.json` with `interrupted` true), 1 an unexpected "
            "internal error (a bug: Python's traceback on stderr; also bad input under `--debug`") in readme


def test_ctrl_c_in_a_command_without_its_own_note_says_it_was_interrupted(tmp_path, monkeypatch, capsys):
    """click turns a KeyboardInterrupt into Abort: simulate, demo, calibrate ... exited 130 silently (run
    and live print their own note); the note is the one the README's exit codes describe."""
    import pipeline.sim.writer as writer
    from pipeline.cli import main

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(writer, "simulate", interrupted)
    assert main(["simulate", "ci_small", "--out", str(tmp_path / "s"), "--no-progress"]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "fisheye-des: interrupted; outputs written so far are kept")
