"""Config loading: unknown keys (line, suggestion), wrong types, relative paths, --set, resolved file."""

from __future__ import annotations

import typing
from pathlib import Path

import numpy as np
import pytest
import yaml
from pydantic import BaseModel

from estimators.errors import ConfigError
from pipeline.config import RESOLVED_NAME, PipelineConfig, describe_config, load_config, write_resolved

REPO = Path(__file__).resolve().parents[2]


def _write(tmp_path: Path, text: str, name: str = "c.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_unknown_key_names_file_line_and_closest_key(tmp_path):
    p = _write(tmp_path, "rig:\n  calibration: cam.yaml\nego_motion:\n  sped_mps: 5\n")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    msg = str(e.value)
    assert f"{p}:4:" in msg
    assert "'sped_mps'" in msg and "did you mean 'speed_mps'" in msg


@pytest.mark.parametrize(
    ("where", "key", "tail"),
    [
        ("file", "qqqq", "in tracker; valid keys: features, grouping, boxes"),
        ("file", "boxs", "in tracker; did you mean 'boxes'? Valid keys: features, grouping, boxes"),
        ("--set", "qqqq", "in tracker; valid keys: features, grouping, boxes"),
        ("--set", "boxs", "in tracker; did you mean 'boxes'? Valid keys: features, grouping, boxes"),
    ],
)
def test_unknown_key_message_separates_the_key_from_the_valid_ones(tmp_path, where, key, tail):
    """With or without a close match, the list of valid keys is set off from the key's own text."""
    with pytest.raises(ConfigError) as e:
        if where == "file":
            load_config(_write(tmp_path, f"tracker:\n  {key}: 1\n"))
        else:
            load_config(None, [f"tracker.{key}=1"])
    assert f"unknown key '{key}' {tail}" in str(e.value)


def test_no_valid_keys_and_the_count_of_further_errors_are_not_read_as_part_of_a_key_list(tmp_path):
    """With no valid keys the message says so (was "; valid keys: " and nothing); the count of further
    errors is a clause of its own after the list (was " (and N more errors)", read as a key)."""
    from estimators.errors import did_you_mean

    assert did_you_mean("x", []) == "; no key is valid there"
    assert did_you_mean("boxs", ["boxes"]) == "; did you mean 'boxes'? Valid keys: boxes"
    with pytest.raises(ConfigError) as e:
        load_config(_write(tmp_path, "tracker:\n  qqqq: 1\nfusion:\n  max_speed_mps: abc\n  zz: 2\n"))
    msg = str(e.value)
    assert msg.endswith(", densify_s; 2 more errors besides this one") and "(and " not in msg, msg
    with pytest.raises(ConfigError) as e:
        load_config(_write(tmp_path, "fusion:\n  max_speed_mps: abc\n  lost_after_s: xyz\n"))
    assert str(e.value).endswith("; 1 more error besides this one"), str(e.value)


@pytest.mark.parametrize(
    ("group", "key", "close"),
    [("features", "max_featurs", "max_features"), ("grouping", "lnk_px", "link_px"),
     ("boxes", "gate_rd", "gate_rad"), ("association", "evry", "every")],
)
def test_a_tracker_option_key_is_checked_when_the_config_loads(tmp_path, monkeypatch, group, key, close):
    """tracker.<group>.<key> is checked by load_config, not first when the front end is built, with the
    file's line (or the --set item) and the closest valid key, as unknown config keys are; boxes too
    when the detector (orb) builds no box tracker, where it was ignored."""
    import trackers.frontend as fe

    monkeypatch.setattr(fe.FrontEnd, "__init__", lambda *a, **k: pytest.fail("front end built"))
    p = _write(tmp_path, f"detector: {{name: orb}}\ntracker:\n  {group}:\n    {key}: 1\n")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert str(e.value).startswith(f"{p}:4: unknown key '{key}' in tracker.{group}; did you mean '{close}'? "
                                   "Valid keys: "), str(e.value)
    assert close in str(e.value).split("Valid keys: ")[1].split(", ")
    with pytest.raises(ConfigError) as e:
        load_config(None, [f"tracker.{group}.{key}=1"])
    assert str(e.value).startswith(f"--set tracker.{group}.{key}=1: unknown key '{key}' in tracker.{group}; "
                                   f"did you mean '{close}'?"), str(e.value)


@pytest.mark.parametrize("detector", ["orb", "kornia"])
def test_box_settings_beside_a_detector_without_boxes_are_refused(tmp_path, detector):
    """tracker.boxes with a detector that gives no boxes (no BoxTracker is built) was silently ignored:
    refused when the config loads, where it was set, naming the detectors that give boxes."""
    p = _write(tmp_path, f"detector: {{name: {detector}}}\ntracker:\n  boxes:\n    gate_rad: 0.1\n")
    tail = (f"tracker.boxes (gate_rad) set, and detector {detector!r} gives no boxes (no box tracker is "
            "built: they would be ignored); expected a detector that gives boxes (navlights, orb+navlights, "
            "torch or another '<keypoint detector>+<box detector>' composite), or no boxes options")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert str(e.value) == f"{p}:4: {tail}"
    with pytest.raises(ConfigError) as e:
        load_config(None, [f"detector.name={detector}", "tracker.boxes.gate_rad=0.1"])
    assert str(e.value) == f"--set tracker.boxes.gate_rad=0.1: {tail}"
    for name in ("navlights", "orb+navlights", "orb+torch", "torch"):  # these build a BoxTracker
        assert load_config(None, [f"detector.name={name}", "tracker.boxes.gate_rad=0.1"]).tracker.boxes


def test_an_old_tracker_frame_count_key_names_its_replacement_when_the_config_loads(tmp_path):
    p = _write(tmp_path, "tracker:\n  features: {win_px: 11}\n  grouping:\n    min_age: 3\n")
    with pytest.raises(ConfigError, match=rf"^{p}:4: 'min_age' in tracker\.grouping \(frames\) was replaced "
                                          r"by 'min_age_s' \(seconds"):
        load_config(p)


def test_unknown_key_in_list_item(tmp_path):
    p = _write(tmp_path, "rig:\n  cameras:\n    - name: cam0\n      model: eucm\n      mout: up\n")
    with pytest.raises(ConfigError, match=r":5: unknown key 'mout' in rig\.cameras\.0; did you mean 'mount'"):
        load_config(p)


def test_unknown_section(tmp_path):
    p = _write(tmp_path, "# comment\n\noutput:\n  plots: true\n")
    with pytest.raises(ConfigError, match=r":3: unknown key 'output' in top level; did you mean 'outputs'"):
        load_config(p)


def test_wrong_type_names_line_and_expected(tmp_path):
    p = _write(tmp_path, "ego_motion:\n  speed_mps: fast\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:2: ego_motion\.speed_mps: .*'fast'.*expected float, m/s"):
        load_config(p)


def test_invalid_yaml_and_missing_file(tmp_path):
    p = _write(tmp_path, "rig:\n  calibration: [a, b\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(p)
    with pytest.raises(ConfigError, match="config file not found"):
        load_config(tmp_path / "nope.yaml")


def test_paths_relative_to_config_file(tmp_path, monkeypatch):
    sub = tmp_path / "configs"
    sub.mkdir()
    p = _write(sub, "rig: {calibration: calib/cam.yaml}\ninputs: {videos: [../v/a.mkv, 'rtsp://host/s']}\n")
    monkeypatch.chdir(tmp_path)
    cfg = load_config(p)
    assert cfg.rig.calibration == sub / "calib" / "cam.yaml"
    assert cfg.inputs.videos == [str(tmp_path / "v" / "a.mkv"), "rtsp://host/s"]


def test_a_detector_model_path_is_relative_to_the_config_file_or_on_the_command_line_to_cwd(
        tmp_path, monkeypatch):
    """detector.options.model_path (torch's model, also inside a composite's part) is a path like the
    config's others: relative to the config file (was: to the current directory, so a config next to
    its model failed when run from elsewhere); given by --set, relative to the current directory."""
    sub = tmp_path / "configs"
    sub.mkdir()
    monkeypatch.chdir(tmp_path)
    p = _write(sub, "detector: {name: torch, options: {model_path: m/boxes.pt, min_score: 0.3}}\n")
    assert load_config(p).detector.options == {"model_path": str(sub / "m" / "boxes.pt"), "min_score": 0.3}
    p = _write(sub, "detector: {name: orb+torch, options: {torch: {model_path: boxes.pt}}}\n", "c2.yaml")
    assert load_config(p).detector.options == {"torch": {"model_path": str(sub / "boxes.pt")}}
    assert load_config(p, ["detector.options.torch.model_path=here.pt"]).detector.options == {
        "torch": {"model_path": str(tmp_path / "here.pt")}}
    assert load_config(p, ["detector.options={torch: {model_path: here.pt}}"]).detector.options == {
        "torch": {"model_path": str(tmp_path / "here.pt")}}
    assert load_config(p, ["detector.options.torch.model_path=/abs/x.pt"]).detector.options == {
        "torch": {"model_path": "/abs/x.pt"}}
    sets = ["detector.options.model_path=x.pt", "detector.name=torch"]
    assert load_config(None, sets).detector.options == {"model_path": str(tmp_path / "x.pt")}
    p = _write(sub, "detector: {options: {torch: {model_path: boxes.pt}}}\n", "c3.yaml")  # torch by --set
    assert load_config(p, ["detector.name=orb+torch"]).detector.options == {
        "torch": {"model_path": str(sub / "boxes.pt")}}


def test_a_plug_in_detectors_model_path_option_is_passed_as_written(tmp_path, monkeypatch):
    """Only torch's model_path (and a composite's torch part's) is a path the config resolves: a plug-in's
    option of that name may be a model id (org/model), not a file here (was made /cwd/org/model)."""
    monkeypatch.chdir(tmp_path)
    p = _write(tmp_path, "detector: {name: my_plugin, options: {model_path: org/model}}\n")
    assert load_config(p).detector.options == {"model_path": "org/model"}
    sets = ["detector.name=my_plugin", "detector.options.model_path=org/model"]
    assert load_config(None, sets).detector.options == {"model_path": "org/model"}
    sets = ["detector.name=orb+my_boxes", "detector.options={my_boxes: {model_path: org/model}}"]
    assert load_config(None, sets).detector.options == {"my_boxes": {"model_path": "org/model"}}


def test_set_overrides_are_typed_and_cli_paths_relative_to_cwd(tmp_path, monkeypatch):
    (tmp_path / "cfgdir").mkdir()
    p = _write(tmp_path / "cfgdir", "ego_motion: {speed_mps: 2}\n")
    monkeypatch.chdir(tmp_path)
    cfg = load_config(
        p,
        [
            "ego_motion.speed_mps=7.5",
            "outputs.plots=true",
            "detector.options.n_features=300",
            "inputs.videos=[x.mkv]",
        ],
    )
    assert cfg.ego_motion.speed_mps == 7.5
    assert cfg.outputs.plots is True
    assert cfg.detector.options == {"n_features": 300}
    assert cfg.inputs.videos == [str(tmp_path / "x.mkv")]  # --set paths: relative to the current directory


def test_set_unknown_key_and_wrong_type(tmp_path):
    with pytest.raises(
        ConfigError, match=r"--set ego_motion.sped=3: unknown key 'sped'.*did you mean 'speed_mps'"
    ):
        load_config(None, ["ego_motion.sped=3"])
    with pytest.raises(ConfigError, match=r"--set outputs.every_n=often: outputs\.every_n: .*integer"):
        load_config(None, ["outputs.every_n=often"])
    with pytest.raises(ConfigError, match="expected section.key=value"):
        load_config(None, ["ego_motion.speed_mps"])


def test_mutually_exclusive_keys(tmp_path):
    p = _write(tmp_path, "ego_motion: {speed_mps: 2, trajectory: t.tum}\n")
    with pytest.raises(ConfigError, match=r":1: .*either 'speed_mps' or 'trajectory'"):
        load_config(p)


def test_resolved_config_written_and_reloads(tmp_path):
    p = _write(tmp_path, "rig: {calibration: cam.yaml}\nego_motion: {speed_mps: 3}\n")
    cfg = load_config(p, ["outputs.every_n=2"])
    out = write_resolved(cfg, tmp_path / "out", source=p, overrides=["outputs.every_n=2"])
    assert out == tmp_path / "out" / RESOLVED_NAME
    text = out.read_text()
    assert "--set outputs.every_n=2" in text
    data = yaml.safe_load(text)
    assert data["rig"]["calibration"] == str(tmp_path / "cam.yaml")
    assert data["outputs"]["every_n"] == 2
    assert "lost_after_s" in data["fusion"] and data["tracker"]["features"] == {}  # every key present
    assert load_config(out) == cfg  # absolute paths: the resolved file reproduces the run anywhere


def test_every_key_is_documented():
    seen = set()

    def walk(model):
        seen.add(model)
        for name, f in model.model_fields.items():
            assert f.description and ":" in f.description, f"{model.__name__}.{name} lacks a description"
            stack = [f.annotation]
            while stack:
                a = stack.pop()
                stack.extend(typing.get_args(a))
                if isinstance(a, type) and issubclass(a, BaseModel) and a not in seen:
                    walk(a)

    walk(PipelineConfig)
    assert len(seen) >= 9  # every section and the inline camera
    assert "ego_motion.speed_mps: float, m/s" in describe_config()


@pytest.mark.parametrize(
    ("name", "kind", "baseline_m"),
    [
        ("mono_forward.yaml", "mono", None),
        ("stereo_030.yaml", "stereo", 0.30),
        ("top_bottom_360.yaml", "stereo", 0.10),
        ("live_webcam.yaml", "mono", None),
    ],
)
def test_shipped_configs_load_and_build_their_rig(name, kind, baseline_m):
    from pipeline.run import build_rig

    cfg = load_config(REPO / "configs" / name)
    rig = build_rig(cfg)
    assert rig.kind == kind
    if baseline_m is not None:
        c0, c1 = rig.cameras[0].T_C_B.inverse().t, rig.cameras[1].T_C_B.inverse().t
        assert abs(float(np.linalg.norm(c0 - c1)) - baseline_m) < 1e-12


@pytest.mark.parametrize(
    ("yaml_text", "sets", "expected"),
    [
        (None, ["fusion.max_speed_mps=-3"],
         "--set fusion.max_speed_mps=-3: fusion.max_speed_mps: expected a value >= 0, got -3.0"),
        ("fusion:\n  lost_after_s: 0.5\n  gate_probability: 2\n", [],
         "{path}:3: fusion.gate_probability: expected a probability in (0, 1), got 2.0"),
    ],
)
def test_a_bad_fusion_value_is_named_as_the_config_key(tmp_path, yaml_text, sets, expected):
    """Checked on load, named as the user wrote it (fusion.key, where it was set), not FusionSettings."""
    path = _write(tmp_path, yaml_text) if yaml_text is not None else None
    with pytest.raises(ConfigError) as e:
        load_config(path, sets)
    assert str(e.value) == expected.format(path=path)


def test_fusion_section_mirrors_fusion_settings():
    import dataclasses

    from estimators import fusion
    from pipeline.config import FusionConfig

    names = [f.name for f in dataclasses.fields(fusion.FusionSettings)]
    assert list(FusionConfig.model_fields) == names
    for name, f in FusionConfig.model_fields.items():  # FusionSettings' docstring documents every field
        assert len(f.description.split(":", 1)[1].strip()) > 10, f"fusion.{name} is undocumented"
    cfg = load_config(None, ["fusion.max_speed_mps=12", "fusion.lost_after_s=0.8"])
    s = fusion.FusionSettings(**cfg.fusion.settings_kwargs())
    assert s == fusion.FusionSettings(max_speed_mps=12.0, lost_after_s=0.8)  # the rest: fusion's defaults
    with pytest.raises(ConfigError, match=r"unknown key 'lost_after' in fusion; did you mean 'lost_after_s'"):
        load_config(None, ["fusion.lost_after=1"])


def test_the_removed_fusion_window_setting_names_the_tracker_window(tmp_path):
    """fusion.feature_window_px (5.5, set by hand to half the tracker's window) was removed: the
    fusion takes the front end's window; a config or --set giving it is told where the window is."""
    p = tmp_path / "old.yaml"
    p.write_text("fusion:\n  feature_window_px: 5.5\n")
    gone = r"'fusion\.feature_window_px' was removed.*set tracker\.features\.win_px"
    with pytest.raises(ConfigError, match=r"old\.yaml:2: " + gone):
        load_config(p)
    with pytest.raises(ConfigError, match=r"--set fusion\.feature_window_px=4: " + gone):
        load_config(None, ["fusion.feature_window_px=4"])


def test_grouping_help_names_the_grouper_s_pixel_keys():
    """The help text of tracker.grouping names ObstacleGrouper's own keywords (link_px, max_radius_px)."""
    import inspect

    from pipeline.config import describe_config
    from trackers.grouping import ObstacleGrouper

    text = describe_config()
    params = inspect.signature(ObstacleGrouper.__init__).parameters
    for key in ("link_px", "max_radius_px", "min_features", "confirm_s", "max_missed_s"):
        assert key in params and key in text
    assert "link_rad" not in text and "max_radius_rad" not in text


def test_inputs_grey_defaults_to_the_detector_s_needs():
    from pipeline.config import load_config
    from pipeline.run import wants_grey

    assert wants_grey(load_config(None)) is False  # orb+navlights: navlights needs colour
    assert wants_grey(load_config(None, cli={"detector.name": "orb"})) is True  # orb works on grey
    assert wants_grey(load_config(None, cli={"detector.name": "navlights"})) is False  # needs colour
    assert wants_grey(load_config(None, cli={"detector.name": "navlights", "inputs.grey": True})) is True
    assert wants_grey(load_config(None, cli={"inputs.grey": False})) is False


def test_front_end_scalar_options_reach_the_front_end():
    from test_run_support import mono_rig

    from pipeline.config import load_config
    from pipeline.run import build_frontend

    cfg = load_config(None, ["tracker.max_width=640", "tracker.densify_s=0.1"])
    assert cfg.tracker.frontend_options() == {"max_width": 640, "densify_s": 0.1}
    fe = build_frontend(cfg, mono_rig())
    assert fe.densify_s == 0.1 and fe.densify_below == 8  # the front end's own default kept
    assert load_config(None).tracker.frontend_options() == {}
    # the old frame count names its replacement
    with pytest.raises(ConfigError, match=r"tracker\.densify_every' was removed.*tracker\.densify_s"):
        load_config(None, ["tracker.densify_every=2"])


def test_shipped_presets_are_package_data_and_found_by_name(tmp_path, monkeypatch):
    """configs/ ships inside the package (pipeline/_configs links to it; pyproject's package-data takes
    every YAML there), so `demo` and preset names work without the repository (a `pip install .`)."""
    import fnmatch
    import tomllib

    from pipeline.config import configs_dir, find_preset, scenarios_dir

    link = REPO / "pipeline" / "_configs"
    assert link.is_symlink() and link.resolve() == (REPO / "configs").resolve()
    assert configs_dir().resolve() == (REPO / "configs").resolve()
    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    shipped = patterns.get("pipeline", [])
    files = [p.relative_to(REPO / "configs").as_posix() for p in (REPO / "configs").rglob("*.yaml")]
    assert len(files) >= 16  # 4 configs + 12 scenarios
    missing = [f for f in files if not any(fnmatch.fnmatch(f"_configs/{f}", pat) for pat in shipped)]
    assert not missing, f"not shipped by pyproject package-data: {missing}"
    # names resolve from any working directory
    monkeypatch.chdir(tmp_path)
    assert find_preset("mono_forward") == configs_dir() / "mono_forward.yaml"
    assert find_preset("demo", scenarios_dir()) == scenarios_dir() / "demo.yaml"
    assert load_config("stereo_030").rig.cameras  # a preset name as CONFIG
    with pytest.raises(ConfigError, match="mono_forward") as e:  # the message lists the presets
        find_preset("mono_forwad")
    assert "not found" in str(e.value)


def test_a_grey_video_is_read_grey_even_for_a_colour_detector(tmp_path):
    """orb+navlights (the default) needs colour, but a grey video has none: it is decoded grey (no
    colour conversion, ORB alone's cost); a colour video stays BGR; inputs.grey set wins."""
    import cv2

    from pipeline.config import load_config
    from pipeline.run import reads_grey

    def video(path, is_colour):
        fourcc = cv2.VideoWriter_fourcc(*"FFV1")
        w = cv2.VideoWriter(str(path), cv2.CAP_FFMPEG, fourcc, 30.0, (64, 48), is_colour)
        if not w.isOpened():
            pytest.skip("OpenCV cannot write FFV1 here")
        img = np.tile(np.arange(64, dtype=np.uint8), (48, 1))
        w.write(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR) if is_colour else img)
        w.release()
        return path

    g, c = video(tmp_path / "g.mkv", False), video(tmp_path / "c.mkv", True)
    cfg = load_config(None)
    assert reads_grey(cfg, [g]) is True and reads_grey(cfg, [c]) is False
    assert reads_grey(load_config(None, cli={"inputs.grey": False}), [g]) is False
    assert reads_grey(load_config(None, cli={"detector.name": "orb"}), c) is True


@pytest.mark.parametrize("key", ["ego_motion.speed_mps", "ego_motion.t0_s", "inputs.max_frames", "inputs.fps",
                                 "live.duration_s", "outputs.every_n"])
def test_a_boolean_for_a_number_of_any_section_is_refused(key):
    """ego_motion.speed_mps: true was read as 1 m/s (pydantic's lax mode); every section's number
    refuses a boolean, naming the key; a key that takes a boolean still does."""
    with pytest.raises(ConfigError, match=f"{key}: expected a number, not the boolean true"):
        load_config(overrides=[f"{key}=true"])
    assert load_config(overrides=["outputs.plots=true", "live.paced=false"]).outputs.plots is True


@pytest.mark.parametrize("key", ["measurement_correlation_s", "feature_velocity_lag_s", "max_speed_mps",
                                 "reinit_after_gated"])
@pytest.mark.parametrize("value", ["true", "false"])
def test_a_boolean_for_a_fusion_number_is_refused(key, value):
    """pydantic's lax mode read true as 1.0 and false as 0.0 (FusionSettings itself refuses booleans):
    the key and what is expected are named; null stays allowed where the field takes None."""
    with pytest.raises(ConfigError, match=f"fusion.{key}: expected a number, not the boolean {value}"):
        load_config(overrides=[f"fusion.{key}={value}"])
    assert load_config(overrides=["fusion.max_speed_mps=null"]).fusion.max_speed_mps is None
    assert load_config(overrides=[f"fusion.{key}=2"]).fusion.settings_kwargs()[key] == 2


def test_the_removed_stereo_update_key_says_it_was_removed(tmp_path):
    """fusion.stereo_update (removed in session 29) is in every config.resolved.yaml written before: such a
    file names the removal, not 'did you mean stereo_jump_check'."""
    p = _write(tmp_path, "fusion:\n  stereo_update: bearings\n")
    with pytest.raises(ConfigError) as e:
        load_config(p)
    assert str(e.value) == (f"{p}:2: 'fusion.stereo_update' was removed: a stereo frame always updates a "
                            "track with the two cameras' bearings (the 'point' update lost on the accuracy "
                            "harness and was removed in session 29); drop the key")
