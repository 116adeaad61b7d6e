"""Tests of the validation scene set of the accuracy harness (``--set validation``: 18 fresh-seed
copies of nine tuned and held-out scenes, used to fit nothing), of ``--override`` and of the pooled
range z^2 statistics.

The presets are checked from their YAML alone (each is its preset with only the seeds changed);
the statistics against values worked by hand on made-up samples; ``--override`` through the CLI
and the config it builds."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
SCEN = REPO / "configs" / "scenarios"
FAMILIES = ("heldout_fast_18mps", "heldout_mono_straight", "heldout_moving", "heldout_stereo_flying",
            "heldout_stereo_hover", "mono_straight", "moving_crossing", "stereo_flying", "turning")
TUNED = ("mono_straight", "stereo_flying", "moving_crossing", "stereo_hover", "thesis_speed_15mps")


@pytest.fixture(autouse=True)
def _own_render_cache(tmp_path_factory, monkeypatch):
    """Renders go to a cache of this test session, not ~/.cache (accuracy.render_cache_dir)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.getbasetemp() / "xdg_cache"))


def _yaml(name: str) -> dict:
    return yaml.safe_load((SCEN / f"{name}.yaml").read_text())


def _seeds(d: dict) -> set[int]:
    return {d["seed"], *([d["ground"]["seed"]] if "seed" in d.get("ground", {}) else [])}


# ---------------------------------------------------------------------------------------- the set
def test_validation_set_is_exactly_its_18_presets_and_they_load():
    from pipeline.accuracy import PIPELINE_SCENES_VALIDATION, SCENE_SETS
    from pipeline.sim.scene import load_scenario

    files = sorted(p.stem for p in SCEN.glob("val*.yaml"))
    expected = sorted([f"val_{f}" for f in FAMILIES] + [f"val2_{f}" for f in FAMILIES])
    assert files == expected
    assert sorted(PIPELINE_SCENES_VALIDATION) == expected and len(set(PIPELINE_SCENES_VALIDATION)) == 18
    assert SCENE_SETS["validation"][0] == PIPELINE_SCENES_VALIDATION
    for n in expected:
        scn = load_scenario(SCEN / f"{n}.yaml")
        assert scn.name == n and scn.n_frames >= 90


@pytest.mark.parametrize("name", [f"{h}_{f}" for h in ("val", "val2") for f in FAMILIES])
def test_validation_preset_is_its_preset_with_only_the_seeds_changed(name):
    d = _yaml(name)
    preset = _yaml(name.split("_", 1)[1])
    assert d["seed"] != preset["seed"] and d["ground"]["seed"] != preset["ground"].get("seed")
    for x in (d, preset):
        x.pop("name")
        x.pop("seed")
        x["ground"].pop("seed", None)
    assert d == preset
    head = (SCEN / f"{name}.yaml").read_text().splitlines()[0]
    assert head.startswith("# VALIDATION copy of the preset") and "used to fit nothing" in head


def test_no_validation_seed_is_shared_with_a_tuned_or_heldout_scene_or_another_validation_one():
    others = set()
    for n in TUNED + tuple(p.stem for p in SCEN.glob("heldout_*.yaml")):
        others |= _seeds(_yaml(n))
    val = [_seeds(_yaml(p.stem)) for p in sorted(SCEN.glob("val*.yaml"))]
    assert len(val) == 18 and all(len(s) == 2 for s in val)  # a top-level and a ground seed each
    flat = [x for s in val for x in s]
    assert not set(flat) & others
    assert len(flat) == len(set(flat))


def test_session6_seeds_kept():
    """The renders and numbers of session 6's harness (/tmp/val) are comparable only with its seeds."""
    for name, seeds in (("val_heldout_fast_18mps", (301, 401)), ("val_turning", (357, 489)),
                        ("val2_heldout_moving", (815, 923)), ("val2_turning", (857, 989))):
        assert (_yaml(name)["seed"], _yaml(name)["ground"]["seed"]) == seeds


def _canned(monkeypatch, calls):
    """_run_pipeline replaced: one mono report per scene, 10 m away, 2 % long, sigma 0.1 m (z^2 4)."""
    import pipeline.accuracy as acc

    def fake(opts, out_dir, progress, names=None):
        calls.append(names)
        ss, per = [], {}
        for n in names:
            s = acc.Sample(scene=n, rig="mono", track=1, t_s=2.0, in_view_s=1.5, moving=False,
                           speed_true=0.0, max_speed=5.0, off_axis_deg=30.0, range_true=10.0, n_views=1,
                           range_m=10.2, range_sigma_m=0.1, range_min_m=None, range_max_m=None,
                           source="mono", obstacle=1)
            ss.append(s)
            per[n] = acc.summarize([s])
        return ss, per, {}

    monkeypatch.setattr(acc, "_run_pipeline", fake)


def test_set_validation_runs_the_18_and_prints_verdicts_pooled_figures_halves_and_top_reports(
        monkeypatch, tmp_path):
    from pipeline.accuracy import PIPELINE_SCENES_VALIDATION, AccuracyOptions, run_accuracy

    calls = []
    _canned(monkeypatch, calls)
    res = run_accuracy(AccuracyOptions(mode="pipeline", scene_set="validation"), tmp_path)
    assert calls == [PIPELINE_SCENES_VALIDATION]
    t = res["table"]
    assert "validation" in t and "mono 3-20 m, >=10 deg off, >=1 s: median rel err" in t
    assert "pooled range z^2 over 18 reports" in t and "median 4.000" in t and "z^2 > 9 0.00 %" in t
    assert "half val_*" in t and "half val2_*" in t
    assert "top 10 range z^2 reports" in t and t.count("  z2       4.0 val") == 10
    m = res["sets"]["validation"]["metrics"]
    assert m["range_z2_n"] == 18 and m["range_z2_trim1_mean"] == pytest.approx(4.0)
    assert set(res["sets"]["validation"]["halves"]) == {"val", "val2"}
    assert (tmp_path / "accuracy_validation.json").is_file()


def test_set_all_is_tuned_heldout_validation_demo_lowres_highfps_rig360_and_both_is_unchanged(monkeypatch,
                                                                                             tmp_path):
    from pipeline.accuracy import (
        PIPELINE_SCENES_HELDOUT,
        PIPELINE_SCENES_HIGHFPS,
        PIPELINE_SCENES_LOWRES,
        PIPELINE_SCENES_RIG360,
        PIPELINE_SCENES_VALIDATION,
        AccuracyOptions,
        run_accuracy,
    )

    calls = []
    _canned(monkeypatch, calls)
    res = run_accuracy(AccuracyOptions(mode="pipeline", scene_set="all"), tmp_path)
    assert calls == [TUNED, PIPELINE_SCENES_HELDOUT, PIPELINE_SCENES_VALIDATION, ("demo",),
                     PIPELINE_SCENES_LOWRES, PIPELINE_SCENES_HIGHFPS, PIPELINE_SCENES_RIG360]
    assert list(res["sets"]) == ["tuned", "heldout", "validation", "demo", "lowres", "highfps", "rig360"]
    assert "range z^2 mean without the top 1 %" in res["table"]  # side by side
    header = next(line for line in res["table"].splitlines() if line.startswith("metric (side by side)"))
    assert header.split()[4:] == ["tuned", "held-out", "validation", "demo", "lowres", "highfps",
                                   "rig360", "target"]
    calls.clear()
    run_accuracy(AccuracyOptions(mode="pipeline", scene_set="both"), tmp_path)
    assert calls == [TUNED, PIPELINE_SCENES_HELDOUT]


def test_validation_has_no_quick_scenes():
    from estimators.errors import ConfigError
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    with pytest.raises(ConfigError, match="no --quick scenes"):
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="validation", quick=True))


# ---------------------------------------------------------------------------------- z^2 statistics
def test_z2_stats_against_hand_worked_values():
    from pipeline.accuracy import z2_stats

    # n 4: floor(1 % of 4) = 0 dropped; mean (4 + 0.25 + 9 + 16) / 4 = 7.3125; median (4 + 9) / 2;
    # z^2 > 9: only 16 (9 is not beyond 3 sigma)
    m = z2_stats([4.0, 0.25, 9.0, 16.0])
    assert m["range_z2_n"] == 4
    assert m["range_z2_mean"] == pytest.approx(7.3125) and m["range_z2_trim1_mean"] == pytest.approx(7.3125)
    assert m["range_z2_median"] == pytest.approx(6.5) and m["range_z2_gt9_share"] == pytest.approx(0.25)
    # n 200: 196 ones, 0, 10, 50, 400. Mean 656 / 200 = 3.28; the top 1 % = 2 values (400, 50)
    # dropped: (196 + 10 + 0) / 198; median: the 100th and 101st of the sorted values, both 1;
    # z^2 > 9: 10, 50, 400 = 3 of 200
    m = z2_stats([1.0] * 196 + [0.0, 10.0, 50.0, 400.0])
    assert m["range_z2_mean"] == pytest.approx(3.28)
    assert m["range_z2_trim1_mean"] == pytest.approx(206 / 198)
    assert m["range_z2_median"] == pytest.approx(1.0) and m["range_z2_gt9_share"] == pytest.approx(0.015)
    assert z2_stats([])["range_z2_mean"] is None


def test_range_z2_reports_are_summarize_nees_population_largest_first():
    import pipeline.accuracy as acc

    def s(r, sigma=0.5, **kw):
        base = dict(scene="a", rig="mono", track=1, t_s=1.0, in_view_s=1.5, moving=False, speed_true=0.0,
                    max_speed=5.0, off_axis_deg=30.0, range_true=10.0, n_views=1, range_m=r,
                    range_sigma_m=sigma, range_min_m=None, range_max_m=None, source="mono", obstacle=3)
        base.update(kw)
        return acc.Sample(**base)

    samples = [s(10.5), s(12.0, track=2), s(11.0, source="stereo", moving=True, stereo_fed=True, track=3),
               s(20.0, moving=True, track=4),  # moving, not stereo-fed: no motion hypothesis, left out
               s(20.0, hit="near", track=5), s(None, track=6), s(20.0, sigma=None, track=7)]
    rows = acc.range_z2_reports(samples)
    # z^2 = ((r - 10) / 0.5)^2: 16 (track 2), 4 (track 3), 1 (track 1)
    assert [(r["track"], r["z2"]) for r in rows] == [(2, 16.0), (3, 4.0), (1, 1.0)]
    assert rows[0] == {"z2": 16.0, "scene": "a", "t_s": 1.0, "track": 2, "obstacle": 3, "range_m": 12.0,
                       "range_true": 10.0, "sigma": 0.5, "source": "mono"}
    assert acc.summarize(samples)["range_nees_n"] == 3


# ---------------------------------------------------------------------------------------- override
def _scene_folder(tmp_path: Path) -> Path:
    d = tmp_path / "scene"
    d.mkdir()
    for f in ("cam0.mkv", "camchain.yaml", "trajectory.tum"):
        (d / f).write_text("")
    return d


def test_override_reaches_the_scene_config_and_the_recording_key(tmp_path):
    from pipeline.accuracy import frontend_key_parts, scene_config

    d = _scene_folder(tmp_path)
    base = scene_config(d)
    cfg = scene_config(d, ("tracker.grouping.link_px=30", "fusion.feature_point_sigma_k=2.5"))
    assert cfg.tracker.grouping == {"link_px": 30} and "link_px" not in base.tracker.grouping
    assert cfg.fusion.feature_point_sigma_k == 2.5
    assert [str(v) for v in cfg.inputs.videos] == [str(d / "cam0.mkv")]  # the scene's own inputs kept
    parts = {"quick": False, "duration_s": 4.0, "scenario_yaml": "x"}
    k0, k1 = frontend_key_parts(parts, base), frontend_key_parts(parts, cfg)
    assert k0["frontend config"] != k1["frontend config"]  # a front-end override: not replayed
    k2 = frontend_key_parts(parts, scene_config(d, ("fusion.feature_point_sigma_k=2.5",)))
    assert k2 == k0  # a fusion override: the recording still holds


def test_override_cli_reaches_the_fusion_settings_and_the_options(monkeypatch):
    from typer.testing import CliRunner

    import pipeline.accuracy as acc
    from pipeline.cli import app

    seen = {}

    def fake(opts, out_dir=None, progress=None):
        seen["opts"] = opts
        return {"table": "T", "elapsed_s": 0.0}

    monkeypatch.setattr(acc, "run_accuracy", fake)
    r = CliRunner().invoke(app, ["accuracy", "--mode", "pipeline", "--set", "validation",
                                 "--override", "tracker.grouping.link_px=30",
                                 "--override", "fusion.feature_point_sigma_k=2.5", "--max-speed", "4"])
    assert r.exit_code == 0, r.output
    o = seen["opts"]
    assert o.overrides == ("tracker.grouping.link_px=30", "fusion.feature_point_sigma_k=2.5")
    assert o.scene_set == "validation" and o.render_cache
    assert o.settings.feature_point_sigma_k == 2.5 and o.settings.max_speed_mps == 4.0
    from estimators.fusion import FusionSettings

    r = CliRunner().invoke(app, ["accuracy", "--mode", "pipeline"])
    assert seen["opts"].settings == FusionSettings() and seen["opts"].overrides == ()


@pytest.mark.parametrize(
    "item, expect",
    [
        ("tracker.grouping.link_pz=3", ["tracker.grouping.link_pz", "did you mean 'link_px'"]),
        ("tracker.grping.link_px=30", ["--override tracker.grping.link_px=30", "unknown key 'grping'",
                                         "did you mean 'grouping'"]),
        ("fusion.feature_point_sigma_k=abc", ["--override fusion.feature_point_sigma_k=abc",
                                              "expected float"]),
        ("link_px", ["--override 'link_px'", "expected section.key=value"]),
        ("tracker.features.max_features=2.5", ["tracker.features.max_features=2.5", "integer"]),
        ("tracker.boxes.link_tol_px=-1", ["--override tracker.boxes", "link_tol_px"]),
        # keywords the front end sets itself are no options (were accepted, then clashed in FrontEnd)
        ("tracker.features.camera=1", ["--override tracker.features.camera=1:", "unknown key 'camera'"]),
        ("tracker.grouping.old=1", ["--override tracker.grouping.old=1:", "unknown key 'old'"]),
        ("ego_motion.speed_mps=3", ["--override ego_motion.speed_mps=3", "set from each scene's render"]),
        ("rig.calibration=x.yaml", ["--override rig.calibration=x.yaml", "cannot be overridden"]),
        # the render's trajectory and frames share one clock: an offset stopped every scene at an end
        ("ego_motion.time_offset_s=0.01", ["--override ego_motion.time_offset_s=0.01", "frames' clock"]),
        ("ego_motion.t0_s=1", ["--override ego_motion.t0_s=1", "cannot be overridden"]),
    ],
)
def test_bad_override_is_a_clear_error_before_anything_runs(monkeypatch, item, expect):
    from typer.testing import CliRunner

    import pipeline.accuracy as acc
    from pipeline.cli import app

    monkeypatch.setattr(acc, "run_accuracy", lambda *a, **k: pytest.fail("ran despite a bad --override"))
    r = CliRunner().invoke(app, ["accuracy", "--mode", "pipeline", "--override", item])
    assert r.exit_code != 0
    msg = str(r.exception) if r.exception and not isinstance(r.exception, SystemExit) else r.output
    for e in expect:
        assert e in msg, msg


@pytest.mark.parametrize(
    "args, expect",
    [
        (["--mode", "pipeline", "--pixel-sigma", "1.0"],
         "accuracy --pixel-sigma: bearings mode only, no effect in pipeline mode; drop it or give --mode "
         "bearings"),
        (["--mode", "pipeline", "--seed", "3", "--n-random", "2"],
         "accuracy --seed, --n-random: bearings mode only, no effect in pipeline mode; drop them or give "
         "--mode bearings"),
        (["--reuse-frontend"],
         "accuracy --reuse-frontend: pipeline mode only, no effect in bearings mode; drop it or give --mode "
         "pipeline"),
        (["--no-render-cache"], "accuracy --no-render-cache: pipeline mode only, no effect in bearings mode"),
        (["--render-cache", "--reuse-frontend"],
         "accuracy --reuse-frontend, --render-cache: pipeline mode only, no effect in bearings mode; drop "
         "them"),
    ],
)
def test_an_option_of_the_other_mode_is_an_error_not_ignored(monkeypatch, capsys, args, expect):
    """--pixel-sigma / --seed / --n-random shape bearings mode's noise and scenes, --reuse-frontend and
    --render-cache pipeline mode's renders: given in the other mode they did nothing, silently."""
    import pipeline.accuracy as acc
    from pipeline.cli import main

    monkeypatch.setattr(acc, "run_accuracy", lambda *a, **k: pytest.fail("ran despite an ignored option"))
    assert main(["accuracy", *args]) == 2
    assert capsys.readouterr().err.strip().startswith(f"fisheye-des: error: {expect}")


def test_the_table_title_gives_the_pixel_noise_only_in_bearings_mode():
    """Pipeline mode measures rendered frames: its title said 'pixel noise 0.5 px', which it never used."""
    from pipeline.accuracy import AccuracyOptions, _title

    assert _title(AccuracyOptions()) == ("fisheye-des accuracy (bearings mode; pixel noise 0.5 px; thesis "
                                         "interval 0.5 s)")
    assert _title(AccuracyOptions(mode="pipeline", quick=True)) == (
        "fisheye-des accuracy (pipeline mode, quick; thesis interval 0.5 s)")


def test_the_mode_s_own_options_reach_it_with_their_defaults_when_not_given(monkeypatch):
    import pipeline.accuracy as acc
    from pipeline.cli import main

    seen = []
    monkeypatch.setattr(acc, "run_accuracy", lambda opts, *a, **k: seen.append(opts) or {
        "table": "", "elapsed_s": 0.0})
    assert main(["accuracy", "--pixel-sigma", "0.25", "--seed", "4"]) == 0
    assert main(["accuracy", "--mode", "pipeline", "--no-render-cache", "--reuse-frontend"]) == 0
    assert main(["accuracy", "--mode", "pipeline"]) == 0
    b, p, d = seen
    assert (b.pixel_sigma_px, b.seed, b.render_cache) == (0.25, 4, True)
    assert (p.pixel_sigma_px, p.seed, p.render_cache, p.reuse_frontend) == (0.5, 0, False, True)
    assert (d.render_cache, d.reuse_frontend) == (True, False)


# -------------------------------------------------------------------------------------- render cache
def test_render_cache_key_ignores_comments_and_follows_the_scenario(tmp_path):
    from pipeline.accuracy import render_key
    from pipeline.sim.scene import load_scenario

    a = tmp_path / "a.yaml"
    text = (SCEN / "ci_small.yaml").read_text()
    a.write_text("# a comment\n" + text)
    scn = load_scenario(SCEN / "ci_small.yaml")
    assert render_key(load_scenario(a)) == render_key(scn)
    assert render_key(scn.model_copy(update={"duration_s": 2.0})) != render_key(scn)
    assert render_key(scn.model_copy(update={"seed": scn.seed + 1})) != render_key(scn)


def test_render_key_follows_the_camera_code_a_render_goes_through(monkeypatch):
    """The renderer turns pixels into bearings with estimators/cameras.py: a render made before a
    change there must not be reused, so the key hashes it (and rig, se3, egomotion, calibration)."""
    import pipeline.accuracy as acc
    from pipeline.sim.scene import load_scenario

    scn = load_scenario(SCEN / "ci_small.yaml")
    full = acc.render_key(scn)
    assert "cameras.py" in acc._RENDER_ESTIMATORS
    rest = tuple(n for n in acc._RENDER_ESTIMATORS if n != "cameras.py")
    monkeypatch.setattr(acc, "_RENDER_ESTIMATORS", rest)
    assert acc.render_key(scn) != full



def test_two_runs_share_one_cached_render(tmp_path, monkeypatch):
    """A scene rendered for one --out is linked, not rendered again, for another --out."""
    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.sim.scene import load_scenario

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    renders = []

    def fake_simulate(scn, out):
        renders.append(scn.name)
        Path(out).mkdir(parents=True)
        (Path(out) / "gt.jsonl").write_text("{}\n")

    monkeypatch.setattr(writer, "simulate", fake_simulate)
    scn = load_scenario(SCEN / "ci_small.yaml")
    parts = {"quick": False, "duration_s": 1.0, "scenario_yaml": "x"}
    opts = acc.AccuracyOptions(mode="pipeline")
    d1 = acc._scene_dir(opts, tmp_path / "out1", "ci_small", scn, parts, None)
    d2 = acc._scene_dir(opts, tmp_path / "out2", "ci_small", scn, parts, None)
    assert renders == ["ci_small"]
    assert d1.is_symlink() and d2.is_symlink() and d1.resolve() == d2.resolve()
    assert d1.resolve().parent == tmp_path / "cache" / "fisheye-des" / "accuracy"
    assert (d1 / acc.RENDER_DONE_NAME).is_file()
    # --no-render-cache: rendered into --out itself, and reused there while the text is unchanged
    off = acc.AccuracyOptions(mode="pipeline", render_cache=False)
    d3 = acc._scene_dir(off, tmp_path / "out3", "ci_small", scn, parts, None)
    d3b = acc._scene_dir(off, tmp_path / "out3", "ci_small", scn, parts, None)
    assert renders == ["ci_small", "ci_small"] and not d3.is_symlink() and d3 == d3b


# ------------------------------------------------------------------------------ uncovered obstacle-frames
def test_uncovered_obstacle_frames_by_reason_and_obstacle():
    from types import SimpleNamespace as R

    import pipeline.accuracy as acc

    eligible = {(1.0, 4), (1.1, 4), (1.2, 4), (1.3, 4), (1.0, 3)}
    covered = {(1.0, 4), (1.0, 3)}
    rows = [R(t_s=1.1, obstacle_id=4, hit="near"),  # only a near miss at 1.1
            R(t_s=1.2, obstacle_id=4, hit="obstacle"),  # on it (unranged: not covered)
            R(t_s=1.2, obstacle_id=4, hit="near"),
            R(t_s=1.3, obstacle_id=3, hit="obstacle"),  # another obstacle: 1.3 has no report on 4
            R(t_s=1.3, obstacle_id=None, hit="background")]
    u = acc._uncovered(rows, eligible, covered, {3: "pole", 4: "box"})
    assert (u["no_report"], u["near_only"], u["unranged"]) == (1, 1, 1)
    assert u["by_obstacle"] == {"3": {"kind": "pole", "covered": 1, "eligible": 1},
                                "4": {"kind": "box", "covered": 1, "eligible": 4}}
    other = {"no_report": 2, "near_only": 0, "unranged": 0,
             "by_obstacle": {"1": {"kind": "sphere", "covered": 1, "eligible": 2}}}
    pooled = acc.pool_uncovered({"a": {"mono_uncovered": u}, "b": {"mono_uncovered": other}}, "mono")
    assert (pooled["no_report"], pooled["near_only"], pooled["unranged"]) == (3, 1, 1)
    assert pooled["worst"] == [["a", 4, "box", 1, 4], ["b", 1, "sphere", 1, 2]]  # 25 %, then 50 %
    assert acc.pool_uncovered({"a": {}}, "stereo") is None


def test_uncovered_obstacle_frames_by_what_the_front_end_had_on_them():
    """_front_end_state casts the recorded observations' rays against the scene, worked by hand: a
    mono camera at the body origin looking along body +x, at t = 1 s at (5, 0, 5) (5 m/s along +x
    from (0, 0, 5)); spheres of 0.5 m ahead at (12, 0, 5) (#1: b_C = (0, 0, 1), optical frame x
    right, y down, z forward), to the left at (5, 6, 5) (#2: b_C = (-1, 0, 0)) and to the right at
    (5, -6, 5) (#3: b_C = (1, 0, 0)); nothing behind (b_C = (0, 0, -1): sky). Track 7's
    representative ray is on #1 and one member feature on #2; track 8 lies on the sky with a
    member on nothing. #1 is tracked, #2 merged (its feature only in a track lying on #1), #3
    untracked, and so is #1 at 1.2 s, a frame without observations."""
    from types import SimpleNamespace as R

    import numpy as np

    import pipeline.accuracy as acc
    from estimators.records import CameraView, ObstacleObservation
    from pipeline.sim.rigs import build_rig
    from pipeline.sim.scene import scenario_from_dict
    from pipeline.sim.trajectory import observer_trajectory
    from pipeline.sim.world import World

    scn = scenario_from_dict({
        "name": "three", "duration_s": 2.0, "fps": 10,
        "rig": {"kind": "mono", "resolution": [640, 480]},
        "observer": {"kind": "straight", "speed_mps": 5.0, "start": {"position_m": [0, 0, 5]}},
        "ground": {"enabled": False},
        "obstacles": [{"id": 1, "kind": "sphere", "radius_m": 0.5, "position_m": [12.0, 0.0, 5.0]},
                      {"id": 2, "kind": "sphere", "radius_m": 0.5, "position_m": [5.0, 6.0, 5.0]},
                      {"id": 3, "kind": "sphere", "radius_m": 0.5, "position_m": [5.0, -6.0, 5.0]}],
    })
    truth = R(world=World(scn))
    rig = build_rig(scn.rig)
    ego = observer_trajectory(scn.observer, 2.0)
    ahead, left, behind = [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]
    views7 = (CameraView("cam0", np.array(ahead), np.zeros(2), 1e-3, [11, 12],
                         np.array([ahead, left])),)
    views8 = (CameraView("cam0", np.array(behind), np.zeros(2), 1e-3, [13], np.array([behind])),)
    obs = [ObstacleObservation(7, 10, 1.0, "confirmed", views7),
           ObstacleObservation(8, 10, 1.0, "confirmed", views8)]
    keys = {(1.0, 1), (1.0, 2), (1.0, 3), (1.2, 1)}
    fe = acc._front_end_state(truth, [(10, 1.0, obs), (12, 1.2, [])], rig, ego, keys)
    assert fe == {(1.0, 1): "tracked", (1.0, 2): "merged", (1.0, 3): "untracked"}
    u = acc._uncovered([], keys, set(), {1: "sphere", 2: "sphere", 3: "sphere"}, fe)
    assert u["no_report"] == 4 and u["front_end"] == {"untracked": 2, "merged": 1, "tracked": 1}
    assert "front_end" not in acc._uncovered([], keys, set(), {})  # (without the recording: as before)
    other = {"no_report": 1, "near_only": 0, "unranged": 0, "front_end": {"untracked": 0, "merged": 0,
                                                                           "tracked": 1}, "by_obstacle": {}}
    pooled = acc.pool_uncovered({"a": {"mono_uncovered": u}, "b": {"mono_uncovered": other}}, "mono")
    assert pooled["front_end"] == {"untracked": 2, "merged": 1, "tracked": 2}
    # a scene without the front end's counts: no pooled counts (not a part of the frames)
    no_fe = {k: v for k, v in other.items() if k != "front_end"}
    assert "front_end" not in acc.pool_uncovered({"a": {"mono_uncovered": u}, "b": {"mono_uncovered": no_fe}},
                                                 "mono")


def test_front_end_state_casts_each_view_from_its_own_camera_on_a_turned_body():
    """_front_end_state's frames, worked by hand where the camera centres and the body's attitude
    matter: a stereo pair 1 m apart (cam0 at body y = +0.5 m, cam1 at -0.5 m, both looking along
    body +x), the body flying at 5 m/s from (0, 0, 5) at yaw 90 deg (body x = world +y, body y =
    world -x): at t = 1 s it is at (0, 5, 5), cam0 at (-0.5, 5, 5), cam1 at (0.5, 5, 5); at 1.2 s
    1 m further along +y. Spheres of 0.2 m at (-0.5, 12, 5) (#1, straight ahead of cam0) and
    (0.5, 12, 5) (#2, ahead of cam1). At 1 s only cam0 sees a track straight ahead (b_C = (0, 0,
    1)): #1 is tracked, #2 not; at 1.2 s only cam1 does: #2 tracked, #1 not. Cast from the body
    origin the rays pass 0.5 m beside both spheres; without the body's turn they go along world
    +x; with the cameras' poses swapped the two frames swap."""
    from types import SimpleNamespace as R

    import numpy as np

    import pipeline.accuracy as acc
    from estimators.records import CameraView, ObstacleObservation
    from pipeline.sim.rigs import build_rig
    from pipeline.sim.scene import scenario_from_dict
    from pipeline.sim.trajectory import observer_trajectory
    from pipeline.sim.world import World

    scn = scenario_from_dict({
        "name": "pair", "duration_s": 2.0, "fps": 10,
        "rig": {"kind": "stereo", "resolution": [640, 480], "baseline_m": 1.0},
        "observer": {"kind": "straight", "speed_mps": 5.0, "start": {"position_m": [0, 0, 5], "yaw_deg": 90}},
        "ground": {"enabled": False},
        "obstacles": [{"id": 1, "kind": "sphere", "radius_m": 0.2, "position_m": [-0.5, 12.0, 5.0]},
                      {"id": 2, "kind": "sphere", "radius_m": 0.2, "position_m": [0.5, 12.0, 5.0]}],
    })
    ahead = np.array([0.0, 0.0, 1.0])

    def seen_ahead_by(cam, track, frame, t_s):
        view = CameraView(cam, ahead, np.zeros(2), 1e-3)
        return (frame, t_s, [ObstacleObservation(track, frame, t_s, "confirmed", (view,))])

    obs = [seen_ahead_by("cam0", 7, 10, 1.0), seen_ahead_by("cam1", 8, 12, 1.2)]
    keys = {(1.0, 1), (1.0, 2), (1.2, 1), (1.2, 2)}
    ego = observer_trajectory(scn.observer, 2.0)
    fe = acc._front_end_state(R(world=World(scn)), obs, build_rig(scn.rig), ego, keys)
    assert fe == {(1.0, 1): "tracked", (1.0, 2): "untracked", (1.2, 1): "untracked", (1.2, 2): "tracked"}


def test_recording_key_is_relative_to_the_scene_folder_and_old_keys_still_match(tmp_path):
    import pickle

    from pipeline.accuracy import _key, _stale_parts, frontend_key_parts, scene_config

    a, b = tmp_path / "a" / "scenes" / "s", tmp_path / "b" / "scenes" / "s"
    for d in (a, b):
        d.mkdir(parents=True)
        for f in ("cam0.mkv", "camchain.yaml", "trajectory.tum"):
            (d / f).write_text("")
    parts = {"quick": False, "duration_s": 4.0, "scenario_yaml": "x"}
    pa = frontend_key_parts(parts, scene_config(a), a)
    pb = frontend_key_parts(parts, scene_config(b), b)
    assert pa == pb and pa["frontend config"]["inputs"]["videos"] == ["<scene>/cam0.mkv"]
    assert pa["frontend config"]["rig"]["calibration"] == "<scene>/camchain.yaml"
    legacy = frontend_key_parts(parts, scene_config(a))  # absolute paths: a recording made before
    assert legacy != pa
    rec = tmp_path / "obs.pkl"
    rec.write_bytes(pickle.dumps({"key": _key(legacy), "key_parts": {k: _key(v) for k, v in legacy.items()}}))
    assert _stale_parts(rec, pa, legacy) == []  # replayed where it was recorded
    assert _stale_parts(rec, pb, frontend_key_parts(parts, scene_config(b))) == ["frontend config"]


def test_an_override_of_an_unknown_tracker_key_is_the_config_s_check_on_the_front_ends_own_table(monkeypatch):
    """accuracy's check of tracker.<group> keys is load_config's (trackers.frontend.option_problem on
    the front end's one table, _CLASS_OPTIONS), not a copy of it: a class put there is the one whose
    keywords the message lists, and the override is named as --override."""
    import pipeline.accuracy as acc
    import trackers.frontend as fe
    from estimators.errors import ConfigError

    class StubTracker:
        RENAMED: dict = {}

        def __init__(self, camera=None, detector=None, ids=None, win_px=21):
            pass

    monkeypatch.setitem(fe._CLASS_OPTIONS, "features", (StubTracker, ("camera", "detector", "ids")))
    assert not hasattr(acc, "_TRACKER_GROUPS")
    with pytest.raises(ConfigError, match=r"^--override tracker\.features\.max_features=5: unknown key "
                                          r"'max_features' in tracker\.features; valid keys: win_px$"):
        acc.settings_from_overrides(["tracker.features.max_features=5"])
