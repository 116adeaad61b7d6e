"""`fisheye-des thesis`: runs, prints every table with a verdict, writes --json."""

from __future__ import annotations

import json
import math

from pipeline.cli import main


def test_thesis_command_prints_and_writes_json(tmp_path, capsys):
    out = tmp_path / "sub" / "thesis.json"
    rc = main(["thesis", "--json", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    for table in (
        "4.2",
        "4.3",
        "4.4",
        "4.5",
        "4.6",
        "4.7",
        "4.8",
        "4.9",
        "4.10",
        "4.11",
        "4.12",
        "4.13",
        "4.14",
        "4.15",
        "A.1",
        "A.2",
        "A.3",
    ):
        assert f"Table {table}: " in text, table
    assert "Table 4.2: reproduces" in text
    assert "Table 4.14: does not reproduce" in text
    assert "Where the thesis is not self-consistent" in text
    data = json.loads(out.read_text())
    assert set(data) == {"rows", "tables", "inconsistencies"}
    r42 = next(r for r in data["rows"] if r["table"] == "4.2" and r["quantity"] == "experimental distance")
    # 165.1 sin 72.5 / sin 152.5, by the law of sines
    expect = 165.1 * math.sin(math.radians(72.5)) / math.sin(math.radians(152.5))
    assert math.isclose(r42["ours"], expect, rel_tol=1e-9)
    assert r42["thesis"] == 341.1 and r42["verdict"] == "reproduces"
    assert data["tables"]["4.5"].startswith("does not reproduce")


def test_thesis_command_help():
    assert main(["thesis", "--help"]) == 0


def test_usage_errors_are_a_message_and_exit_code_2(capsys):
    # typer raises its vendored click's exceptions; they must not escape as a traceback
    assert main(["thesis", "--bogus"]) == 2
    assert "No such option: --bogus" in capsys.readouterr().err


def test_unwritable_json_path_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["thesis", "--json", str(blocker / "t.json")]) == 2
    assert capsys.readouterr().err.startswith("fisheye-des: error: --json")
