"""Rough edges of the accuracy harness: error messages for a mistyped --set / --scene or a scene of
another set, a front-end recording cut short by an interrupted run, and the folders an interrupted
render leaves in the render cache."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.fixture(autouse=True)
def _own_render_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg_cache"))


def test_mistyped_set_suggests_the_set():
    from estimators.errors import ConfigError
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    with pytest.raises(ConfigError, match="got 'validaton'; did you mean 'validation'") as e:
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="validaton"))
    assert "demo" in str(e.value)  # listed among the valid ones
    with pytest.raises(ConfigError) as e:
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="zzz"))
    assert "did you mean" not in str(e.value)


@pytest.mark.parametrize(
    "scene_set, scene, expect",
    [
        ("tuned", "heldout_moving", "'heldout_moving' is in the heldout set (--set heldout or a group "
                                    "holding it: both, all)"),
        ("heldout", "demo", "'demo' is in the demo set (--set demo or a group holding it: all)"),
        ("all", "val_turnin", "'val_turnin': did you mean 'val_turning'?"),
        ("heldout", "mono_straigt", "'mono_straigt': did you mean 'mono_straight' (the tuned set)?"),
    ],
)
def test_scene_of_another_set_or_mistyped_says_so(scene_set, scene, expect):
    from estimators.errors import ConfigError
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    with pytest.raises(ConfigError) as e:
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set=scene_set, scenes=(scene,)))
    msg = str(e.value)
    assert expect in msg and "is in no chosen scene set" in msg and "expected one of" in msg


def test_unknown_scene_without_a_near_name_has_no_hint():
    from estimators.errors import ConfigError
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    with pytest.raises(ConfigError) as e:
        run_accuracy(AccuracyOptions(mode="pipeline", scenes=("qqqq", "zzzz")))
    assert "'qqqq', 'zzzz' are in no chosen scene set" in str(e.value) and "did you mean" not in str(e.value)


def test_a_cut_short_recording_is_recorded_again_not_a_crash(tmp_path):
    import pipeline.accuracy as acc

    parts = {"trackers": "t", "scene": {"a": 1}, "frontend config": {"b": 2}}
    rec = pickle.dumps({"trackers_hash": "t", "key": acc._key(parts),
                        "key_parts": {k: acc._key(v) for k, v in parts.items()}, "frames": [(0, 0.0, [])]})
    p = tmp_path / "observations.pkl"
    acc._write_atomic(p, rec)
    assert acc._stale_parts(p, parts) == []
    assert [f.name for f in tmp_path.iterdir()] == ["observations.pkl"]  # no temporary left behind
    p.write_bytes(rec[: len(rec) // 2])  # what an interrupted write used to leave
    assert acc._stale_parts(p, parts) == [acc.UNREADABLE]
    p.write_bytes(pickle.dumps([1, 2]))  # a pickle, not a recording
    assert acc._stale_parts(p, parts) == [acc.UNREADABLE]


def test_an_interrupted_renders_folder_is_removed_by_the_next_render(tmp_path, monkeypatch):
    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario

    def fake_simulate(scn, out, **kw):
        Path(out).mkdir(parents=True)
        (Path(out) / "gt.jsonl").write_text("{}\n")

    monkeypatch.setattr(writer, "simulate", fake_simulate)
    scn = load_scenario(scenarios_dir() / "ci_small.yaml")
    cache = acc.render_cache_dir()
    name = f"ci_small-{acc.render_key(scn)}"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True).stdout.strip()  # a pid that has exited
    (cache / f".{name}.part-{dead}").mkdir(parents=True)
    (cache / f".{name}.part-{dead}" / "cam0.mkv").write_bytes(b"half")
    live = cache / f".{name}.part-{os.getppid()}"  # a render still running (this test's parent)
    live.mkdir()
    other = cache / f".other-0123456789abcdef.part-{dead}"  # another key's: not this render's business
    other.mkdir()
    d = acc._cached_render(scn, None)
    assert (d / acc.RENDER_DONE_NAME).is_file()
    assert sorted(p.name for p in cache.iterdir()) == sorted([name, live.name, other.name])


def test_no_render_cache_rerender_leaves_no_file_of_the_old_render(tmp_path, monkeypatch):
    """--no-render-cache: a stale render in --out/scenes (another scenario text, or cut short before
    its key was written) is replaced whole; a stale cam1.mkv would be read as a second camera."""
    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario

    def fake_simulate(scn, out, **kw):
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "gt.jsonl").write_text("{}\n")
        (Path(out) / "cam0.mkv").write_bytes(b"new")

    monkeypatch.setattr(writer, "simulate", fake_simulate)
    scn = load_scenario(scenarios_dir() / "ci_small.yaml")
    sdir = tmp_path / "out" / "scenes" / "ci_small"
    sdir.mkdir(parents=True)
    for f in ("gt.jsonl", "cam0.mkv", "cam1.mkv"):
        (sdir / f).write_text("old")
    (sdir / acc.SCENE_KEY_NAME).write_text("another key\n")
    off = acc.AccuracyOptions(mode="pipeline", render_cache=False)
    assert acc._scene_dir(off, tmp_path / "out", "ci_small", scn, {"x": 1}, None) == sdir
    assert sorted(p.name for p in sdir.iterdir()) == ["cam0.mkv", "gt.jsonl", acc.SCENE_KEY_NAME]
    assert (sdir / "cam0.mkv").read_bytes() == b"new"
