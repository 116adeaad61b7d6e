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
