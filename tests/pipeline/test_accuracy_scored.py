"""The accuracy harness's informational rows on every report ``fisheye-des demo`` scores
(``scored_ranges``, ``format_scored``, and their place in ``run_accuracy``'s output), and the
evaluator's ``scored_reports`` / ``scored_range_metrics`` the demo and the harness share.

Expected values are worked by hand from made-up evaluator rows (relative errors chosen to be exact
in binary-free terms: 2 %, 5 %, 20 %; percentiles by linear interpolation, numpy's default)."""

from __future__ import annotations

from pathlib import Path

import pytest


def _row(scene="s", t=1.0, track=1, status="confirmed", hit="obstacle", oid=1, moving=False,
         true=10.0, rng=None):
    from pipeline.evaluate import Row

    return Row(scenario=scene, frame=0, t_s=t, track_id=track, status=status, hit=hit,
               obstacle_id=oid, moving=moving, range_true_m=true, range_m=rng, range_sigma_m=None,
               range_min_m=None, range_max_m=None, v_est_W=None, v_true_W=None, nis=None, nis_dim=None)


def _rows(scene="s"):
    """Three scored ranged reports (stationary 5 % and 2 % off, moving 20 % off), one scored report
    without a range, and four the demo does not score (tentative, near miss, ground, sky)."""
    return [
        _row(scene, rng=10.5),                       # stationary, +5 %
        _row(scene, track=2, rng=9.8),               # stationary, -2 %
        _row(scene, track=3, oid=2, moving=True, true=5.0, rng=6.0),  # moving, +20 %
        _row(scene, track=4, oid=2, moving=True, true=5.0, rng=None),  # moving, unranged
        _row(scene, track=5, status="tentative", oid=2, moving=True, true=5.0, rng=10.0),
        _row(scene, track=6, hit="near", oid=2, moving=True, true=5.0, rng=10.0),
        _row(scene, track=7, hit="ground", oid=None, moving=None, true=3.0, rng=9.0),
        _row(scene, track=8, hit="sky", oid=None, moving=None, true=None, rng=9.0),
    ]


def test_scored_reports_are_confirmed_reports_hitting_an_obstacle():
    from pipeline.evaluate import scored_reports

    assert [r.track_id for r in scored_reports(_rows())] == [1, 2, 3, 4]


def test_scored_range_metrics_by_hand():
    from pipeline.evaluate import scored_range_metrics

    g = scored_range_metrics(_rows())
    a = g["confirmed"]
    assert (a["reports"], a["ranged"]) == (4, 3)
    # |errors| 0.05, 0.02, 0.20: median 0.05; p90 at rank 0.9 * 2 = 1.8: 0.05 + 0.8 * 0.15 = 0.17
    assert a["rel_err_median"] == pytest.approx(0.05)
    assert a["rel_err_p90"] == pytest.approx(0.17)
    assert a["within_10pct"] == pytest.approx(2 / 3)
    assert g["stationary"]["rel_err_median"] == pytest.approx(0.035)
    assert (g["moving"]["reports"], g["moving"]["ranged"]) == (2, 1)
    assert g["moving"]["rel_err_p90"] == pytest.approx(0.20)


def test_scored_ranges_pools_scenes_and_splits_moving_by_rig():
    from pipeline.accuracy import scored_ranges

    mono = _rows("m")
    stereo = [_row("st", oid=3, moving=True, true=4.0, rng=4.32),  # +8 %
              _row("st", track=2, oid=3, moving=True, true=4.0, rng=3.8),  # -5 %
              _row("st", track=3, oid=1, rng=12.0)]                # stationary, +20 %
    sr = scored_ranges({"m": ("mono", mono), "st": ("stereo", stereo)})
    # all: 0.05 0.02 0.20 | 0.08 0.05 0.20 -> sorted 0.02 0.05 0.05 0.08 0.20 0.20: median 0.065,
    # p90 at rank 4.5: 0.20; within 10 %: 4 of 6
    assert sr["all"]["ranged"] == 6
    assert sr["all"]["rel_err_median"] == pytest.approx(0.065)
    assert sr["all"]["rel_err_p90"] == pytest.approx(0.20)
    assert sr["all"]["within_10pct"] == pytest.approx(4 / 6)
    assert sr["moving_mono_rig"]["ranged"] == 1
    assert sr["moving_mono_rig"]["rel_err_median"] == pytest.approx(0.2)
    # stereo moving: 0.08, 0.05 -> median 0.065, p90 0.05 + 0.9 * 0.03 = 0.077
    assert sr["moving_stereo_rig"]["ranged"] == 2
    assert sr["moving_stereo_rig"]["rel_err_median"] == pytest.approx(0.065)
    assert sr["moving_stereo_rig"]["rel_err_p90"] == pytest.approx(0.077)
    assert sr["moving"]["ranged"] == 3 and sr["stationary"]["ranged"] == 3
    empty = scored_ranges({})
    assert empty["all"] == {"reports": 0, "ranged": 0}


def test_scored_ranges_counts_a_top_bottom_rigs_movers_with_the_mono_rigs():
    """The top/bottom rig's scenes (``--set rig360``) are scored as monocular (``MONO_RIGS``): their
    moving obstacles' reports are the mono-rig group's too (they were in neither rig group: rig360's
    "moving obstacles, mono rig" and "stereo rig" rows both read ranged 0 beside 6 moving ranged)."""
    from pipeline.accuracy import scored_ranges

    tb = [_row("tb", oid=5, moving=True, true=5.0, rng=6.0),  # moving, +20 %
          _row("tb", track=2, oid=1, rng=10.5)]               # stationary
    sr = scored_ranges({"tb": ("top_bottom", tb)})
    assert sr["moving"]["ranged"] == 1
    assert sr["moving_mono_rig"]["ranged"] == 1
    assert sr["moving_mono_rig"]["rel_err_median"] == pytest.approx(0.2)
    assert sr["moving_stereo_rig"]["ranged"] == 0


def test_scored_ranges_are_strict_json():
    """Bounds without an upper end have an infinite median width: written null, as metrics.json does."""
    import json

    from pipeline.accuracy import scored_ranges

    r = _row(rng=10.5)
    r.range_min_m = 2.0
    sr = scored_ranges({"s": ("mono", [r])})
    assert sr["all"]["bounds_coverage"] == 1.0 and sr["all"]["bounds_width_median_m"] is None
    json.dumps(sr, allow_nan=False)


def test_format_scored_lines():
    from pipeline.accuracy import format_scored, scored_ranges

    m = {"scored_ranges": scored_ranges({"m": ("mono", _rows("m"))})}
    lines = format_scored(m).splitlines()
    assert lines[0].startswith("range error of every confirmed report on an obstacle, any age")
    assert "informational, no target" in lines[0]
    all_line = next(ln for ln in lines if ln.strip().startswith("all obstacles"))
    assert "ranged      3" in all_line and "median   5.00 %" in all_line and "p90  17.00 %" in all_line
    assert "within 10 %  66.67 %" in all_line
    stereo = next(ln for ln in lines if "moving obstacles, stereo rig" in ln)
    assert "ranged      0" in stereo and stereo.count("n/a") == 3
    assert not any("PASS" in ln or "FAIL" in ln for ln in lines)


def _canned(monkeypatch, calls):
    """_run_pipeline replaced: one verdict sample per scene and the evaluator rows of _rows(), the
    held-out scenes' moving report 40 % off instead of 20 %; every scene a stereo rig."""
    import pipeline.accuracy as acc

    def fake(opts, out_dir, progress, names=None):
        calls.append(names)
        ss, per, rows = [], {}, {}
        for n in names:
            s = acc.Sample(scene=n, rig="mono", track=1, t_s=2.0, in_view_s=1.5, moving=False,
                           speed_true=0.0, max_speed=5.0, off_axis_deg=30.0, range_true=10.0, n_views=1,
                           range_m=10.1, range_sigma_m=0.2, range_min_m=None, range_max_m=None,
                           source="mono", obstacle=1)
            ss.append(s)
            per[n] = acc.summarize([s])
            r = _rows(n)
            if n.startswith("heldout_"):
                r[2].range_m = 7.0
            rows[n] = ("stereo", r)
            per[n]["scored_ranges"] = acc.scored_ranges({n: rows[n]})
        return ss, per, rows

    monkeypatch.setattr(acc, "_run_pipeline", fake)


def test_every_pipeline_set_prints_and_writes_the_scored_rows(monkeypatch, tmp_path):
    import json

    from pipeline.accuracy import AccuracyOptions, run_accuracy

    calls = []
    _canned(monkeypatch, calls)
    res = run_accuracy(AccuracyOptions(mode="pipeline", scene_set="both"), tmp_path)
    t = res["table"]
    assert t.count("range error of every confirmed report on an obstacle, any age") == 2  # each set
    # 5 scenes pooled: the moving stereo rig group is 5 reports 20 % (tuned) or 40 % (held-out) off
    m = res["sets"]["heldout"]["metrics"]["scored_ranges"]
    assert m["moving_stereo_rig"]["ranged"] == 5
    assert m["moving_stereo_rig"]["rel_err_p90"] == pytest.approx(0.4)
    assert m["moving_mono_rig"] == {"reports": 0, "ranged": 0}
    side = [ln for ln in t.splitlines() if ln.startswith("confirmed, any age, moving stereo rig: p90")]
    assert len(side) == 1 and "20.00 %" in side[0] and "40.00 %" in side[0] and "info" in side[0]
    saved = json.loads((tmp_path / "accuracy_both.json").read_text())
    # tuned, 5 scenes: 5 x (0.02, 0.05, 0.20): p90 at rank 12.6 of 0..14 is 0.20; median 0.05
    tuned = saved["sets"]["tuned"]["metrics"]["scored_ranges"]["all"]
    assert tuned["rel_err_p90"] == pytest.approx(0.20) and tuned["rel_err_median"] == pytest.approx(0.05)
    assert saved["sets"]["tuned"]["per_scene"]["mono_straight"]["scored_ranges"]["all"]["ranged"] == 3


def test_validation_halves_get_the_scored_rows(monkeypatch, tmp_path):
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    _canned(monkeypatch, [])
    res = run_accuracy(AccuracyOptions(mode="pipeline", scene_set="validation"), tmp_path)
    halves = res["sets"]["validation"]["halves"]
    assert halves["val"]["scored_ranges"]["all"]["ranged"] == 27  # 9 scenes x 3
    assert "  half val2_*: all obstacles p90 20.00 %" in res["table"]


# ------------------------------------------------------------------------- the demo's scene (--set demo)
def test_set_demo_is_the_demo_scenario_and_all_holds_it():
    from pipeline.accuracy import SCENE_SETS, SET_GROUPS
    from pipeline.commands.demo import DEFAULT_SCENARIO

    assert SCENE_SETS["demo"] == ((DEFAULT_SCENARIO.removesuffix(".yaml"),), ())
    assert "demo" in SET_GROUPS["all"] and "demo" not in SET_GROUPS["both"]


def test_demo_scene_is_rendered_as_the_demo_renders_it(tmp_path, monkeypatch):
    """The demo renders at 640x360 (its --resolution default) and grey for ORB (a grey detector),
    colour for navlights and orb+navlights, the default (colour ones); every other scene as before
    (no keywords, same key)."""
    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario

    assert acc.scene_render("demo") == {"resolution": [640, 360], "grey": False}
    assert acc.scene_render("demo", ("detector.name=orb",)) == {"resolution": [640, 360], "grey": True}
    assert acc.scene_render("demo", ("detector.name=navlights",)) == {"resolution": [640, 360], "grey": False}
    assert acc.scene_render("mono_straight") == {}
    scn = load_scenario(scenarios_dir() / "demo.yaml")
    assert acc.render_key(scn, {}) == acc.render_key(scn)
    keys = {acc.render_key(scn), acc.render_key(scn, acc.scene_render("demo", ("detector.name=orb",))),
            acc.render_key(scn, {"resolution": [640, 360], "grey": False})}
    assert len(keys) == 3
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    calls = []

    def fake_simulate(scn, out, **kw):
        calls.append(kw)
        Path(out).mkdir(parents=True)
        (Path(out) / "gt.jsonl").write_text("{}\n")

    monkeypatch.setattr(writer, "simulate", fake_simulate)
    how = acc.scene_render("demo", ("detector.name=orb",))
    on = acc.AccuracyOptions(mode="pipeline")
    d = acc._scene_dir(on, tmp_path / "out", "demo", scn, {"x": 1}, None, how)
    assert calls == [{"resolution": (640, 360), "grey": True}]
    assert d.resolve().name == f"demo-{acc.render_key(scn, how)}"
    off = acc.AccuracyOptions(mode="pipeline", render_cache=False)
    acc._scene_dir(off, tmp_path / "out2", "demo", scn, {"x": 1}, None, how)
    assert calls[-1] == {"resolution": (640, 360), "grey": True}


# ------------------------------------------------------------ the low-resolution set (--set lowres)
_LOWRES = ("lowres_mono_straight", "lowres_moving_crossing", "lowres_stereo_flying",
           "lowres_heldout_stereo_flying", "lowres_val_stereo_flying", "lowres_val2_stereo_flying")


def test_set_lowres_lists_its_scenes_and_all_holds_it():
    from estimators.errors import ConfigError
    from pipeline.accuracy import SCENE_SETS, SET_GROUPS, AccuracyOptions, run_accuracy
    from pipeline.config import scenarios_dir

    assert SCENE_SETS["lowres"] == (_LOWRES, ())
    assert SET_GROUPS["all"][:5] == ("tuned", "heldout", "validation", "demo", "lowres")
    assert "lowres" not in SET_GROUPS["both"]
    for n in _LOWRES:  # copies of presets (the originals stay in their own sets)
        assert (scenarios_dir() / f"{n.removeprefix('lowres_')}.yaml").is_file()
    with pytest.raises(ConfigError, match="lowres, highfps, rig360, both, all"):
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="lowers"))
    with pytest.raises(ConfigError, match="the validation, demo, lowres, highfps and rig360 sets have none"):
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="lowres", quick=True))


def _kb_pixel(f, c, k, theta, phi):
    """Kannala-Brandt by hand: r = f theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)."""
    import math

    r = f * theta * (1 + k[0] * theta**2 + k[1] * theta**4 + k[2] * theta**6 + k[3] * theta**8)
    return c[0] + r * math.cos(phi), c[1] + r * math.sin(phi)


def test_lowres_copy_is_its_original_rendered_at_640x360_with_the_lens_scaled(tmp_path, monkeypatch):
    """lowres_<scene> is <scene>.yaml renamed, rendered at 640x360 with the same lens scaled: half the
    focal length, the principal point at the centre of a 640x360 image, the same distortion and
    field of view, so every bearing lands half as far from the centre (checked by hand)."""
    import math

    import numpy as np

    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario

    for name in _LOWRES:
        path, scn = acc.harness_scenario(name)
        orig = load_scenario(scenarios_dir() / f"{name.removeprefix('lowres_')}.yaml")
        assert path == scenarios_dir() / f"{orig.name}.yaml"
        assert scn.name == name and scn.model_dump(exclude={"name"}) == orig.model_dump(exclude={"name"})
        assert acc.scene_render(name) == {"resolution": [640, 360]}
        assert acc.scene_render(name, ("detector.name=orb",)) == {"resolution": [640, 360]}  # colour
    assert acc.harness_scenario("mono_straight")[1] == load_scenario(scenarios_dir() / "mono_straight.yaml")
    assert acc.scene_render("mono_straight") == {}
    # the rig the render is made with (the writer's), against the original's 1280x720 lens
    _, scn = acc.harness_scenario("lowres_stereo_flying")
    lo = writer.Simulation(scn, (640, 360), 1).rig
    hi = writer.Simulation(acc.harness_scenario("stereo_flying")[1], None, 1).rig
    assert [c.name for c in lo] == [c.name for c in hi] == ["cam0", "cam1"]
    for a, b in zip(lo, hi, strict=True):
        pa, pb = a.model.params(), b.model.params()
        assert (pa["width"], pa["height"], pb["width"], pb["height"]) == (640, 360, 1280, 720)
        assert pb["fx"] == pytest.approx(204.524, abs=1e-3) and pa["fx"] == pytest.approx(pb["fx"] / 2)
        assert (pa["cx"], pa["cy"]) == (319.5, 179.5)  # (639.5 + 0.5) / 2 - 0.5: the centre
        assert pa["max_angle_rad"] == pb["max_angle_rad"]
        k = [pa[f"k{i}"] for i in range(1, 5)]
        assert k == [pb[f"k{i}"] for i in range(1, 5)]
        np.testing.assert_allclose(a.T_C_B.t, b.T_C_B.t)  # the same 0.30 m baseline
        for theta, phi in ((0.3, 0.7), (1.0, -2.0), (1.5, 2.9)):
            st = math.sin(theta)
            b_C = np.array([st * math.cos(phi), st * math.sin(phi), math.cos(theta)])
            uv, ok = a.model.bearing_to_pixel(b_C[None])
            assert ok[0]
            np.testing.assert_allclose(uv[0], _kb_pixel(102.262, (319.5, 179.5), k, theta, phi), atol=2e-3)
    # pipeline mode renders the copy at 640x360 from its original's YAML; bearings mode uses that rig
    seen = []

    def stop(opts, root, name, scn, scene_parts, progress, how=None):
        seen.append((name, scn.name, how, scene_parts["scenario_yaml"]))
        raise KeyboardInterrupt

    monkeypatch.setattr(acc, "_scene_dir", stop)
    with pytest.raises(KeyboardInterrupt):
        acc.run_accuracy(acc.AccuracyOptions(mode="pipeline", scene_set="lowres"), tmp_path)
    assert seen == [("lowres_mono_straight", "lowres_mono_straight", {"resolution": [640, 360]},
                     (scenarios_dir() / "mono_straight.yaml").read_text())]

    def no_fusion(rig, traj, settings):
        seen.append([(c.model.width, c.model.height) for c in rig])
        raise KeyboardInterrupt

    monkeypatch.setattr(acc, "ObstacleFusion", no_fusion)
    with pytest.raises(KeyboardInterrupt):
        acc.run_accuracy(acc.AccuracyOptions(scene_set="lowres"))
    assert seen[-1] == [(640, 360)]


# ------------------------------------------------------------ the high-frame-rate set (--set highfps)
_HIGHFPS = ("fps100_mono_straight", "fps100_moving_crossing", "fps100_stereo_flying",
            "fps100_heldout_stereo_flying")


def test_set_highfps_lists_its_scenes_and_all_holds_it():
    from estimators.errors import ConfigError
    from pipeline.accuracy import SCENE_SETS, SET_GROUPS, AccuracyOptions, run_accuracy
    from pipeline.config import scenarios_dir

    assert SCENE_SETS["highfps"] == (_HIGHFPS, ())
    assert SET_GROUPS["all"][:6] == ("tuned", "heldout", "validation", "demo", "lowres", "highfps")
    assert "highfps" not in SET_GROUPS["both"]
    for n in _HIGHFPS:  # copies of presets (the originals stay in their own sets)
        assert (scenarios_dir() / f"{n.removeprefix('fps100_')}.yaml").is_file()
    with pytest.raises(ConfigError, match="lowres, highfps and rig360 sets have none"):
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="highfps", quick=True))


def test_highfps_copy_is_its_original_at_100_fps_and_the_run_reads_its_frame_times(tmp_path, monkeypatch):
    """fps100_<scene> is <scene>.yaml renamed with fps 100 and nothing else changed (same length,
    trajectory, world, resolution): 100 / 30 as many frames, each at k / 100 s; the render's
    timestamps files carry those times and the run config of the render reads them back."""
    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.config import scenarios_dir
    from pipeline.run import build_rig, open_inputs
    from pipeline.sim.scene import load_scenario

    for name in _HIGHFPS:
        path, scn = acc.harness_scenario(name)
        orig = load_scenario(scenarios_dir() / f"{name.removeprefix('fps100_')}.yaml")
        assert path == scenarios_dir() / f"{orig.name}.yaml"
        assert orig.fps == 30 and scn.fps == 100
        assert scn.name == name
        assert scn.model_dump(exclude={"name", "fps"}) == orig.model_dump(exclude={"name", "fps"})
        assert scn.n_frames == round(orig.duration_s * 100) and orig.n_frames == round(orig.duration_s * 30)
        assert acc.scene_render(name) == {} and acc.scene_render(name, ("detector.name=orb",)) == {}
        assert acc.render_key(scn) != acc.render_key(orig)  # its own cached render
    sim = writer.Simulation(acc.harness_scenario("fps100_stereo_flying")[1], None, 3)
    assert [sim.frame_time(k) for k in range(3)] == [0.0, 0.01, 0.02]
    assert [(c.model.width, c.model.height) for c in sim.rig] == [(1280, 720)] * 2
    # a tiny render of the copy (3 frames at 96x54): the run's frame sets are at k / 100 s
    _, scn = acc.harness_scenario("fps100_stereo_flying")
    writer.simulate(scn, tmp_path / "r", frames=3, resolution=(96, 54))
    cfg = acc.scene_config(tmp_path / "r")
    src = open_inputs(cfg, build_rig(cfg))
    try:
        got = [(fs.frame, fs.t_s) for fs in src]
    finally:
        src.close()
    assert got == [(0, 0.0), (1, 0.01), (2, 0.02)]
    # pipeline mode renders the copy (the 100-fps scenario) from its original's YAML
    seen = []

    def stop(opts, root, name, scn, scene_parts, progress, how=None):
        seen.append((name, scn.name, scn.fps, how, scene_parts["scenario_yaml"]))
        raise KeyboardInterrupt

    monkeypatch.setattr(acc, "_scene_dir", stop)
    with pytest.raises(KeyboardInterrupt):
        acc.run_accuracy(acc.AccuracyOptions(mode="pipeline", scene_set="highfps"), tmp_path)
    assert seen == [("fps100_mono_straight", "fps100_mono_straight", 100.0, {},
                     (scenarios_dir() / "mono_straight.yaml").read_text())]


# ------------------------------------------------------------ the 360-degree set (--set rig360)
_RIG360 = ("top_bottom_climb", "top_bottom_turn")


def test_set_rig360_lists_its_top_bottom_scenes_and_all_ends_with_it():
    from estimators.errors import ConfigError
    from pipeline.accuracy import (
        SCENE_SETS,
        SET_GROUPS,
        SET_ROWS,
        AccuracyOptions,
        harness_scenario,
        run_accuracy,
        scene_render,
    )

    assert SCENE_SETS["rig360"] == (_RIG360, ())
    assert SET_GROUPS["all"] == ("tuned", "heldout", "validation", "demo", "lowres", "highfps", "rig360")
    assert "rig360" not in SET_GROUPS["both"]
    assert not any(k.startswith("stereo") for k in SET_ROWS["rig360"])
    for n in _RIG360:  # presets of their own, rendered as they are
        _, scn = harness_scenario(n)
        assert scn.name == n and scn.rig.kind == "top_bottom" and scene_render(n) == {}
    with pytest.raises(ConfigError, match="rig360 sets have none"):
        run_accuracy(AccuracyOptions(mode="pipeline", scene_set="rig360", quick=True))


@pytest.mark.parametrize("name", _RIG360)
def test_rig360_scenes_render_and_load_as_an_up_and_a_down_camera(tmp_path, name):
    """A tiny render (2 frames at 96x96) of each scene loads as the run config the harness builds:
    two cameras, cam0's optical axis along body +z and cam1's along -z, 0.10 m apart (the
    scenarios' rig), the image tops towards the nose; every obstacle in the truth."""
    import numpy as np

    import pipeline.accuracy as acc
    import pipeline.sim.writer as writer
    from pipeline.evaluate import ScenarioTruth
    from pipeline.run import build_rig

    _, scn = acc.harness_scenario(name)
    writer.simulate(scn, tmp_path / "r", frames=2, resolution=(96, 96))
    rig = build_rig(acc.scene_config(tmp_path / "r"))
    assert rig.names == ("cam0", "cam1")
    up, down = rig.cameras
    # rows of R_C_B are the camera axes in B: z_C (optical axis) and y_C (image down = towards the tail)
    np.testing.assert_allclose(up.T_C_B.R[2], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(down.T_C_B.R[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(up.T_C_B.R[1], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(down.T_C_B.R[1], [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(up.T_C_B.inverse().t - down.T_C_B.inverse().t, [0, 0, 0.10], atol=1e-12)
    truth = ScenarioTruth.load(tmp_path / "r")
    assert len(truth.gt) == 2
    assert {o["id"] for o in truth.gt[0]["obstacles"]} == {o.id for o in scn.obstacles}


@pytest.mark.heavy
def test_rig360_meets_the_monocular_and_bounds_targets(tmp_path):
    """``accuracy --mode pipeline --set rig360`` (renders cached; ~4 min on a fresh cache): the
    one-camera reports meet the monocular targets, the moving drone's bounds hold the truth."""
    from pipeline.accuracy import AccuracyOptions, run_accuracy

    m = run_accuracy(AccuracyOptions(mode="pipeline", scene_set="rig360"), tmp_path)["metrics"]
    assert m["mono_n"] > 500 and m["mono_median_rel"] <= 0.02 and m["mono_p90_rel"] <= 0.05
    assert m["bounds_n"] > 100 and m["bounds_coverage"] >= 0.99
    assert m["mono_obstacle_coverage"] >= 0.95
