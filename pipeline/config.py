"""Run configuration: pydantic models for every key, YAML loading with line numbers, ``--set`` overrides.

A config is a YAML file with the sections below (all optional; every key has a default or is filled
in from the command line). Unknown keys and wrong types are ``ConfigError``s that name the file, the
line and the closest valid key. Relative paths are relative to the config file (paths given on the
command line or through ``--set`` are relative to the current directory). The config as run, with
every default filled in and every path absolute, is written beside the outputs as
``config.resolved.yaml`` (:func:`write_resolved`).

Example (``configs/mono_forward.yaml``)::

    rig: {calibration: calib/mono_camchain.yaml}
    ego_motion: {speed_mps: 5.0}
    detector: {name: orb, options: {n_features: 800}}
    inputs: {videos: [flight.mkv]}
    outputs: {annotated_video: true, plots: true}

Units: SI everywhere (metres, seconds, m/s, m/s^2); degrees only where the key says ``_deg``.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import os
import re
import types
import typing
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)

from estimators.errors import ConfigError, did_you_mean

__all__ = [
    "PipelineConfig",
    "RigConfig",
    "CameraConfig",
    "EgoMotionConfig",
    "DetectorConfig",
    "TrackerConfig",
    "FusionConfig",
    "InputsConfig",
    "LiveConfig",
    "OutputsConfig",
    "load_config",
    "write_resolved",
    "describe_config",
    "RESOLVED_NAME",
]

RESOLVED_NAME = "config.resolved.yaml"


def _is_url(s: str) -> bool:
    return "://" in s


def _resolve_path(v: Path | str | None, info: ValidationInfo) -> Any:
    """Make a relative path absolute against ``context['base_dir']`` (the config file's folder)."""
    if v is None:
        return None
    if isinstance(v, str) and _is_url(v):
        return v
    p = Path(os.path.expanduser(str(v)))
    if not p.is_absolute():
        base = (info.context or {}).get("base_dir") or Path.cwd()
        p = Path(base) / p
    p = Path(os.path.normpath(p))
    return p if not isinstance(v, str) else str(p)


# A path relative to the config file.
RelPath = Annotated[Path, AfterValidator(_resolve_path)]
# A video: a path relative to the config file, or a URL (``rtsp://...``, ``http://...``) kept as is.
VideoRef = Annotated[str, AfterValidator(_resolve_path)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_a_number(cls, v: Any, info: ValidationInfo) -> Any:
        """true/false is no number: pydantic's lax mode would read it as 1 or 0 (``ego_motion.speed_mps:
        true`` flying at 1 m/s), so a number's key refuses it, naming the key (a key that takes a
        bool as well, and every other value, is left to the field's own validation)."""
        if isinstance(v, bool):
            kinds = typing.get_args(cls.model_fields[info.field_name].annotation)
            kinds = kinds or (cls.model_fields[info.field_name].annotation,)
            if bool not in kinds and (int in kinds or float in kinds):
                raise ValueError(f"expected a number, not the boolean {str(v).lower()}")
        return v


# ----------------------------------------------------------------------------------------------- rig
class CameraConfig(_Section):
    """One camera given inline (instead of a calibration file)."""

    name: str = Field(description="str: camera name in the rig, e.g. 'cam0'; also the name of its video.")
    model: str = Field(
        description="str: camera model registry name: 'equidistant', 'kannala_brandt', 'double_sphere', "
        "'eucm'."
    )
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: the model's fields as estimators.cameras.make_camera_model takes them, e.g. "
        "fx, fy (px/rad), cx, cy (px), width, height (px), k1..k4 for kannala_brandt.",
    )
    mount: Literal["forward", "up", "down"] = Field(
        "forward",
        description="str: standard mount of estimators.rig: 'forward' (optical axis = body +x, image x = "
        "body -y), 'up' (+z, image top towards the nose), 'down' (-z, image top towards the nose).",
    )
    position_m: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="[x, y, z] metres: the camera centre in the body frame B."
    )


class RigConfig(_Section):
    """The cameras: a calibration file (Kalibr, OpenCV, ROS camera_info) or inline cameras."""

    calibration: RelPath | None = Field(
        None,
        description="path: calibration file (Kalibr camchain.yaml, OpenCV FileStorage YAML/JSON, ROS "
        "camera_info YAML); one camera -> monocular, two -> stereo. Relative to the config file.",
    )
    cameras: list[CameraConfig] | None = Field(
        None, description="list: cameras given inline instead of `calibration` (see CameraConfig)."
    )

    @model_validator(mode="after")
    def _one_of(self) -> RigConfig:
        if self.calibration is not None and self.cameras:
            raise ValueError("give either 'calibration' or 'cameras', not both")
        return self


# ---------------------------------------------------------------------------------------- ego-motion
class EgoMotionConfig(_Section):
    """How the body moves: a constant forward speed (the thesis's case) or a TUM trajectory T_W_B."""

    speed_mps: float | None = Field(
        None,
        description="float, m/s: constant speed along the body's x axis (forward), level flight. "
        "Mutually exclusive with `trajectory`.",
    )
    trajectory: RelPath | None = Field(
        None,
        description="path: TUM trajectory file ('timestamp tx ty tz qx qy qz qw', pose T_W_B, seconds and "
        "metres) interpolated to frame times. Relative to the config file.",
    )
    t0_s: float = Field(
        0.0,
        description="float, s: time at which the constant-velocity body is at the origin (with `speed_mps`; "
        "with `trajectory` an error: the trajectory's own timestamps place the body).",
    )

    time_offset_s: float = Field(
        0.0,
        description="float, s: the trajectory's clock minus the frames' clock: frame time t_s is looked up "
        "in the trajectory at t_s + time_offset_s (e.g. 0.015 when the flight log stamps an instant 15 ms "
        "later than the camera; the sign of Kalibr's timeshift_cam_imu). With `trajectory` only: the "
        "constant-velocity motion has `t0_s`.",
    )

    @model_validator(mode="after")
    def _one_of(self) -> EgoMotionConfig:
        if self.speed_mps is not None and self.trajectory is not None:
            raise ValueError("give either 'speed_mps' or 'trajectory', not both")
        if not math.isfinite(self.time_offset_s):
            raise ValueError(f"time_offset_s must be a finite number of seconds, got {self.time_offset_s}")
        return self


# ---------------------------------------------------------------------------------- detector/tracker
class DetectorConfig(_Section):
    """Which obstacle/feature detector the front end uses."""

    name: str = Field(
        "orb+navlights",
        description="str: detector registry name: 'orb', 'navlights', 'kornia', 'torch' or a plug-in's name "
        "(entry-point group fisheye_des.detectors); '<keypoint detector>+<box detector>' runs both in one "
        "front end, e.g. 'orb+navlights' (the default: ORB's feature tracks plus drones found by their "
        "navigation lights; options per part: {orb: {...}, navlights: {...}}; on a grey video it is ORB "
        "alone, at ORB's cost).",
    )
    options: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: keyword options passed to the detector's constructor; torch's model file "
        "(model_path, also as a composite's part: {torch: {model_path: ...}}) is relative to the config "
        "file, as the config's other paths; any other detector's options (a plug-in's too) are passed as "
        "written.",
    )

    @field_validator("options")
    @classmethod
    def _model_path_relative_to_the_config(cls, v: dict[str, Any], info: ValidationInfo) -> dict[str, Any]:
        key = _model_path_key(info.data.get("name"))
        return v if key is None else _with_model_path(v, key, lambda p: _resolve_path(p, info))


class TrackerConfig(_Section):
    """Front-end settings (feature tracking, obstacle grouping, cross-camera association), passed to
    ``trackers.frontend.FrontEnd(rig, detector, **options)``; a key of features, grouping, boxes or
    association that the front end does not take is an error when the config loads, naming the closest
    valid key (``trackers.frontend.option_problem``)."""

    features: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: trackers.features.FeatureTracker keywords, e.g. max_features (int; default 500; "
        "null, opt-in: one per px_per_feature (700) px^2 of the lens mask, clipped to [250, 500], picked "
        "for CPU, not fitted: it costs worst-obstacle coverage at 640x480), "
        "grid ([cols, rows]), "
        "redetect_s (s, default 4/30: periodic re-detection, every 4th frame at 30 fps, twice as long once "
        "the tracker is full; applied as a frame count at the frame rate seen, as the grouping's durations; "
        "the old redetect_every (frames) is an error naming it), reacquire_s (s, default 8/30: lost features "
        "are remembered this long for re-acquisition, at the frame rate seen; was reacquire_frames), "
        "win_px (px, default 11: the KLT window's side, the temporal and the stereo "
        "KLT's; the fusion's window angle is its half-width over each camera's tracked px per rad), "
        "levels (int), fb_max_px (px, forward-backward check), "
        "fb_levels (int, pyramid levels of the backward pass, default 1; 0: full resolution only), "
        "fb_retry (bool, a level-0 failure is checked again one level up), "
        "min_distance_px (px), history (samples per feature, 64: the grouping's windows reach at most "
        "history - 1 frames back), klt_step_s (s, 1/30: KLT tracks a feature from its position this long "
        "back, as frames at the rate seen, so its position takes one KLT step per klt_step_s at any frame "
        "rate; 1 frame at <= 30 fps).",
    )
    grouping: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: trackers.grouping.ObstacleGrouper keywords, e.g. link_px (px, largest "
        "distance between neighbouring features of one obstacle, at the lens's mean scale), "
        "max_radius_px (px, largest distance of a member from its track's representative point), "
        "flow_abs_rad_s (rad/s), flow_rel, flow_window_s (s, 1/6: the flow's time base), min_features "
        "(int), min_age_s (s, 0.1), isolated_min_age_s (s, 0.4), confirm_s (s, 1/6), max_missed_s (s, 1/3), "
        "extended_sectors (int, 0-8: a new piece of features surrounded in this "
        "many of 8 sectors by features moving with it is part of a large textured surface and starts no "
        "track; 0 turns the rule off), extended_s (s, 0.1: how long a tentative track may be judged so "
        "before it is dropped), split_window_s (s, 1/3: window over which step 3c compares members' "
        "motions), split_min_px (px, 1.5; 0 turns the split by motion off), split_rel (0.1), split_step "
        "(3.0), split_persist_s (s, 0.1: a split must be found in every frame this long), plane_min (12: "
        "step 3f, an obstacle standing on the ground it is grouped with leaves the ground's planar flow; "
        "tracks of at least this many members are tested, 0 turns it off), plane_z (sigmas, 6.0), "
        "plane_ratio (12.0), plane_every_s (s, 1/15). Durations are applied as frame counts at the frame "
        "rate seen (the median interval of the frame times; the defaults are the counts fitted at 30 fps: "
        "5, 3, 12, 5, 10, 3, 10, 3 and every 2nd frame, in the order above); the old frame-count keys "
        "(min_age, confirm_frames, ...) are an error naming their replacement.",
    )
    boxes: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: BoxTracker keywords (detectors that give boxes: navlights, torch, composites "
        "such as orb+navlights; an error beside one that gives none, e.g. orb): gate_rad (rad, 3 deg), "
        "confirm_s (s, 0.1), max_missed_s (s, 1/3), sigma_floor_rad (rad, 0.2 deg); durations at the frame "
        "rate seen, as the grouping's; with a keypoint detector beside the boxes, a box is folded into a "
        "feature track on it: link_margin_px (px, 3), link_min_members (2), link_s (s, 0.1), link_tol_px "
        "(px, 2), link_share (0.75: the share of its members on the box a new link needs; a held link "
        "keeps half), link_older_only (false; true: only to a feature track made before the box, so a "
        "drone found first by its lights keeps its own id and report).",
    )
    association: dict[str, Any] = Field(
        default_factory=dict,
        description="dict: cross-camera association: every (frames, default 5), epipolar_deg (deg, 1.0), "
        "max_hamming (int, 64), min_votes (int, 3), klt_link_px (px, 1.5), recheck_every (frames, 4: "
        "a followed stereo match's forward-backward re-check), recheck_px (px, 1.0), follow_levels (int, 1: "
        "OpenCV maxLevel of the stereo KLT for a match followed from the last frame, i.e. 1 searches 2 "
        "pyramid levels (full size and half) and 0 only the full-size image; new matches use maxLevel 4, "
        "5 levels; null: maxLevel 4 for all), reverse_views (bool, true: a second camera's confirmed "
        "track with no reference-camera track gets a reference view from its members found there by "
        "stereo KLT).",
    )
    max_width: int | None = Field(
        None,
        ge=64,
        description="int, px: frames wider than this are tracked downscaled (camera model scaled alike, so "
        "bearings are unchanged). Null: the front end's default (1280).",
    )
    densify_below: int | None = Field(
        None,
        ge=0,
        description="int: tracks with fewer member features get extra features detected around them. "
        "Null: the front end's default (8).",
    )
    densify_s: float | None = Field(
        None,
        ge=0,
        description="float, s: a small track is densified at most this often, applied as a frame count at "
        "the frame rate seen, as the grouping's durations (2/30: every 2nd frame at 30 fps, the count it "
        "was fitted as; 7 at 100 fps; 0 = every frame). Null: the front end's default (2/30). Was "
        "densify_every (frames).",
    )

    def frontend_options(self) -> dict[str, Any]:
        """The non-empty groups and the set scalars as FrontEnd keyword arguments."""
        return {
            k: (dict(v) if isinstance(v, dict) else v)
            for k, v in self.model_dump().items()
            if v is not None and v != {}
        }


def _attribute_docs(cls: type) -> dict[str, str]:
    """``name -> text`` from the ``Attributes:`` section of a class docstring (Google style)."""
    doc = inspect.getdoc(cls) or ""
    out: dict[str, str] = {}
    in_attrs = False
    current = None
    for line in doc.splitlines():
        if line.strip() == "Attributes:":
            in_attrs = True
            continue
        if not in_attrs:
            continue
        if line and not line.startswith(" "):
            break  # the next section
        m = re.match(r"^ {4}(\w+):\s*(.*)$", line)
        if m:
            current = m.group(1)
            out[current] = m.group(2).strip()
        elif current and line.strip():
            out[current] += " " + line.strip()
    return out


def _type_name(t: Any) -> str:
    return getattr(t, "__name__", None) or str(t).replace("typing.", "")


def _make_fusion_config() -> type[BaseModel]:
    """``FusionConfig``: one key per field of ``estimators.fusion.FusionSettings``, generated from it so the
    two never drift: same names, types and defaults; each key's description is the field's entry in
    FusionSettings' docstring (units there)."""
    from estimators.fusion import FusionSettings

    hints = typing.get_type_hints(FusionSettings)
    docs = _attribute_docs(FusionSettings)
    fields: dict[str, Any] = {}
    for f in dataclasses.fields(FusionSettings):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()  # type: ignore[misc]
        text = docs.get(f.name, "")
        fields[f.name] = (hints[f.name], Field(default, description=f"{_type_name(hints[f.name])}: {text}"))
    model = create_model("FusionConfig", __base__=_Section, **fields)
    model.__doc__ = (
        "Per-obstacle filter settings: the fields of ``estimators.fusion.FusionSettings`` "
        "(SI units, radians), with its defaults."
    )

    def settings_kwargs(self) -> dict[str, Any]:
        """All keys as FusionSettings keywords."""
        return {k: getattr(self, k) for k in type(self).model_fields}

    model.settings_kwargs = settings_kwargs
    return model


FusionConfig = _make_fusion_config()


# -------------------------------------------------------------------------------------------- inputs
class InputsConfig(_Section):
    """Recorded inputs for `fisheye-des run`: one video (or image folder) per camera, in the rig's order."""

    videos: list[VideoRef] = Field(
        default_factory=list,
        description="list of paths/URLs: one video per camera, in the rig's camera order (first = cam0). "
        "Frame times come from '<video stem>.timestamps.txt' beside it when present.",
    )
    images: list[RelPath] = Field(
        default_factory=list,
        description="list of paths: one image folder per camera (instead of videos), files in natural name "
        "order (frame_2 before frame_10; the k-th image gets the k-th line of its timestamps file).",
    )
    fps: float | None = Field(
        None,
        gt=0,
        description="float, Hz: frame rate of image folders that have no timestamps file "
        "(also overrides a video's own rate when set).",
    )
    sync_tolerance_s: float = Field(
        0.005,
        ge=0,
        description="float, s: frames of different cameras within this time of each other are one stereo "
        "set; a frame without a partner within it is dropped and counted.",
    )
    max_frames: int | None = Field(None, gt=0, description="int: stop after this many frame sets.")
    prefetch: int = Field(
        2,
        ge=0,
        description="int, frames: decode each video this many frames ahead in a background thread "
        "(0 = decode in the run loop). Used only when the process may run on more than one CPU: on one "
        "core the thread overlaps nothing.",
    )
    grey: bool | None = Field(
        None,
        description="bool: decode videos to (H, W) grey frames (a grey video is then read without any "
        "colour conversion). Default (null): grey when the detector works on grey images ('orb', "
        "'kornia') or the video itself is grey (nothing to find by colour), BGR for the others "
        "('navlights', 'orb+navlights' need colour). The annotated video is drawn either way.",
    )


class LiveConfig(_Section):
    """Live camera settings for `fisheye-des live`."""

    cameras: list[int | str] = Field(
        default_factory=lambda: [0],
        description="list: per rig camera, a device index (int) or a stream URL (str) OpenCV/FFmpeg opens.",
    )
    clock: Literal["run", "unix"] = Field(
        "run",
        description="str: t_s of a live frame: 'run' = seconds since the run started, 'unix' = seconds since "
        "1970 (use it when a trajectory file written by another program is in unix time).",
    )
    reconnect_initial_s: float = Field(
        0.2, gt=0, description="float, s: first wait before reopening a camera that stopped delivering."
    )
    reconnect_max_s: float = Field(
        5.0, gt=0, description="float, s: longest wait between reopen attempts (the wait doubles each try)."
    )
    stall_timeout_s: float = Field(
        2.0, gt=0, description="float, s: a camera with no new frame for this long is treated as stopped."
    )
    duration_s: float | None = Field(
        None, gt=0, description="float, s: stop after this long (None: until Ctrl-C)."
    )
    trajectory_wait_s: float = Field(
        0.2,
        ge=0,
        description="float, s: how long to wait for a growing trajectory file to reach a frame's t_s before "
        "the frame is skipped (counted in summary.json's frames_without_pose); a frame before the file's "
        "first pose is skipped at once (also counted as frames_before_trajectory): poses are only added at "
        "the end.",
    )
    preview: Literal["none", "file", "mjpeg"] = Field(
        "none",
        description="str: annotated preview: 'file' (preview.mp4 in the output folder), 'mjpeg' (HTTP).",
    )
    preview_port: int = Field(
        8080,
        ge=0,
        le=65535,
        description="int: TCP port of the MJPEG preview on 127.0.0.1 (0 = any free port).",
    )
    paced: bool = Field(
        True,
        description="bool: when a camera entry is a video file, replay it at its real frame rate "
        "(testing without a camera).",
    )
    sync_tolerance_s: float = Field(
        0.02,
        ge=0,
        description="float, s: several cameras: the frame of each other camera nearest in time to the "
        "first camera's (video t_s for replays, else arrival time) joins it when within this; otherwise "
        "the first camera's frame is processed alone and counted (summary: frames_without_partner).",
    )
    grabber_nice: int | None = Field(
        -5,
        ge=-20,
        le=19,
        description="int: Linux nice value of the camera-reading threads (lower = sooner; the pipeline's "
        "thread keeps the process's own), so that frames are read on time while the pipeline is busy on "
        "the same core. Below the process's own value it needs CAP_SYS_NICE; without it the threads keep "
        "the process's value (summary.json says which applied). null: leave them as they are.",
    )
    deferred_detection: bool = Field(
        False,
        description="bool: opt-in: the feature trackers' periodic ORB re-detection runs in a worker process "
        "at ``detection_nice``, off the frame's path: a frame's reports do not wait for its detection, whose "
        "features join at the first frame after it is done (tracked from the detection's frame). A measured "
        "trade: a lower latency p99 where the loop has idle time (1080p at 30 Hz), for fewer features and a "
        "lower obstacle coverage (a detection's features join frames late; more so on a loop with no idle "
        "time): docs/ARCHITECTURE.md 'The re-detection off the frame's path in live mode'. false (default): "
        "each detection in its own frame, as `run` does (the offline modes always do).",
    )
    detection_nice: int | None = Field(
        10,
        ge=-20,
        le=19,
        description="int: with deferred_detection, Linux nice value of the detection's worker process "
        "(higher = later: it runs in the loop's idle time, and gets a share of a busy core by its weight). "
        "null: the run's own.",
    )


# ------------------------------------------------------------------------------------------- outputs
class OutputsConfig(_Section):
    """What a run writes besides tracks.jsonl, summary.json and config.resolved.yaml."""

    dir: RelPath | None = Field(
        None, description="path: output folder (created). Relative to the config file; --out overrides."
    )
    annotated_video: bool = Field(
        False,
        description="bool: write annotated.mp4 (raw fisheye frames with track id, range, bounds, velocity "
        "arrow and the lens circle).",
    )
    plots: bool = Field(
        False, description="bool: write PNG plots (range over time per track; polar map around the drone)."
    )
    every_n: int = Field(
        1, ge=1, description="int: annotate every n-th frame only (annotated video/preview)."
    )
    max_plot_tracks: int = Field(12, ge=1, description="int: the longest this many tracks get a range plot.")
    progress: bool = Field(True, description="bool: show a progress bar on stderr.")


class PipelineConfig(_Section):
    """The whole configuration of a run (``fisheye-des run`` / ``live`` / ``demo``)."""

    rig: RigConfig = Field(default_factory=RigConfig, description="section: the cameras.")
    ego_motion: EgoMotionConfig = Field(default_factory=EgoMotionConfig, description="section: body motion.")
    detector: DetectorConfig = Field(default_factory=DetectorConfig, description="section: the detector.")
    tracker: TrackerConfig = Field(default_factory=TrackerConfig, description="section: front-end settings.")
    fusion: FusionConfig = Field(default_factory=FusionConfig, description="section: filter settings.")
    inputs: InputsConfig = Field(default_factory=InputsConfig, description="section: recorded inputs.")
    live: LiveConfig = Field(default_factory=LiveConfig, description="section: live cameras.")
    outputs: OutputsConfig = Field(default_factory=OutputsConfig, description="section: outputs.")


# ------------------------------------------------------------------------------ model introspection
def _unwrap(annotation: Any) -> list[Any]:
    """The concrete types inside Optional / Union / Annotated / list / dict / tuple annotations."""
    origin = typing.get_origin(annotation)
    if origin is Annotated:
        return _unwrap(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        out: list[Any] = []
        for a in typing.get_args(annotation):
            out += _unwrap(a)
        return out
    return [annotation]


def _sub_model(annotation: Any, step: str | int) -> tuple[type[BaseModel] | None, bool]:
    """Follow one location step from a field annotation: (model class there or None, step consumed)."""
    for a in _unwrap(annotation):
        origin = typing.get_origin(a)
        if isinstance(a, type) and issubclass(a, BaseModel):
            return a, False
        if origin in (list, tuple) and isinstance(step, int):
            for inner in typing.get_args(a):
                for t in _unwrap(inner):
                    if isinstance(t, type) and issubclass(t, BaseModel):
                        return t, True
            return None, True
    return None, False


def _descend(loc: tuple[str | int, ...]) -> type[BaseModel] | None:
    """The model class reached by following ``loc`` from the top (None when it leads out of the models)."""
    model: type[BaseModel] | None = PipelineConfig
    i = 0
    while i < len(loc):
        key = loc[i]
        if model is None or not isinstance(key, str) or key not in model.model_fields:
            return None
        ann = model.model_fields[key].annotation
        i += 1
        nxt = loc[i] if i < len(loc) else ""
        sub, consumed = _sub_model(ann, nxt)
        if consumed:
            i += 1
        model = sub
    return model


def _model_at(loc: tuple[str | int, ...]) -> type[BaseModel] | None:
    """The model class that owns the last string key of ``loc``."""
    keys = [i for i, p in enumerate(loc) if isinstance(p, str)]
    if not keys:
        return None
    last = keys[-1]
    owner = _descend(loc[:last])
    if owner is None or loc[last] not in owner.model_fields:
        return None
    return owner


def _field_annotation(loc: tuple[str | int, ...]) -> Any:
    owner = _model_at(loc)
    if owner is None or not loc or not isinstance(loc[-1], str) or loc[-1] not in owner.model_fields:
        return None
    return owner.model_fields[loc[-1]].annotation


def _is_path_field(loc: tuple[str | int, ...]) -> bool:
    ann = _field_annotation(loc)
    if ann is None:
        return False
    text = repr(ann)
    return "_resolve_path" in text


# Keys that were removed or renamed: key path -> what to set instead (an error names it).
_REMOVED_KEYS: dict[tuple[str, ...], str] = {
    ("fusion", "feature_window_px"): "the fusion's window angle follows the front end's KLT window: set "
    "tracker.features.win_px (the window's side in tracked px; the fusion takes its half-width over each "
    "camera's tracked px per rad)",
    ("fusion", "stereo_update"): "a stereo frame always updates a track with the two cameras' bearings (the "
    "'point' update lost on the accuracy harness and was removed in session 29); drop the key",
    ("tracker", "densify_every"): "densify's cadence is a duration now: set tracker.densify_s (seconds, "
    "applied at the frame rate seen; every 2nd frame at 30 fps = 2/30)",
}


def _removed(loc: tuple) -> str | None:
    """The message for a removed key at ``loc``, or None."""
    key = tuple(str(p) for p in loc)
    return f"'{'.'.join(key)}' was removed: {_REMOVED_KEYS[key]}" if key in _REMOVED_KEYS else None


# ------------------------------------------------------------------------------------ YAML handling
def _line_map(node: yaml.Node, path: tuple = (), out: dict | None = None) -> dict[tuple, int]:
    """Map every key path of a composed YAML document to its 1-based line number."""
    out = {} if out is None else out
    out.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            key = k.value
            out[path + (key,)] = k.start_mark.line + 1
            _line_map(v, path + (key,), out)
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            out[path + (i,)] = v.start_mark.line + 1
            _line_map(v, path + (i,), out)
    return out


def _read_yaml(path: Path) -> tuple[dict, dict[tuple, int]]:
    if not path.is_file():
        raise ConfigError(f"{path}: config file not found")
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise ConfigError(f"{path}: not a YAML config (not UTF-8 text); expected a YAML file of sections "
                          "(rig, ego_motion, ...), e.g. configs/mono_forward.yaml") from None
    try:
        loader = yaml.SafeLoader(text)
        try:
            node = loader.get_single_node()
            data = loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f":{mark.line + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ConfigError(f"{path}{where}: not valid YAML ({problem})") from None
    if data is None:
        return {}, {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: not a YAML config (it reads as a {type(data).__name__}, not a mapping); "
                          "expected a YAML file of sections (rig, ego_motion, ...), e.g. "
                          "configs/mono_forward.yaml")
    return data, _line_map(node)


def _parse_override(item: str) -> tuple[tuple[str, ...], Any]:
    if "=" not in item:
        raise ConfigError(f"--set {item!r}: expected section.key=value")
    key, raw = item.split("=", 1)
    parts = tuple(p for p in key.strip().split(".") if p)
    if not parts:
        raise ConfigError(f"--set {item!r}: expected section.key=value")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError:
        value = raw
    return parts, value


def _set_in(data: dict, parts: tuple[str, ...], value: Any, origin: str) -> None:
    cur = data
    for i, p in enumerate(parts[:-1]):
        nxt = cur.get(p)
        if nxt is None:
            nxt = cur[p] = {}
        if not isinstance(nxt, dict):
            raise ConfigError(f"{origin}: '{'.'.join(parts[: i + 1])}' is not a section")
        cur = nxt
    cur[parts[-1]] = value


def _check_override_key(parts: tuple[str, ...], origin: str) -> None:
    """An override of an unknown key: error with the closest valid key (dict-valued keys accept anything)."""
    model: type[BaseModel] | None = PipelineConfig
    for i, p in enumerate(parts):
        if model is None:
            return  # inside a free-form dict (options/settings)
        if p not in model.model_fields:
            gone = _removed(parts[: i + 1])
            if gone:
                raise ConfigError(f"{origin}: {gone}")
            where = ".".join(parts[:i]) or "top level"
            raise ConfigError(
                f"{origin}: unknown key '{p}' in {where}" + did_you_mean(p, list(model.model_fields))
            )
        ann = model.model_fields[p].annotation
        nxt = None
        for a in _unwrap(ann):
            if isinstance(a, type) and issubclass(a, BaseModel):
                nxt = a
        if nxt is None and i < len(parts) - 1:
            if not any(typing.get_origin(a) is dict for a in _unwrap(ann)):
                raise ConfigError(f"{origin}: '{'.'.join(parts[: i + 1])}' is a value, not a section")
        model = nxt


def _model_path_key(name: Any) -> tuple[str, ...] | None:
    """Where detector ``name``'s model file is in its options, the one detector option that is a path:
    ``("model_path",)`` for ``torch``, ``("torch", "model_path")`` for a composite with a torch part
    (``orb+torch``); None for any other detector (a plug-in's options are its own, passed as written)."""
    parts = [p.strip() for p in name.split("+")] if isinstance(name, str) else []
    if parts == ["torch"]:
        return ("model_path",)
    return ("torch", "model_path") if len(parts) == 2 and "torch" in parts else None


def _with_model_path(options: Any, key: tuple[str, ...], resolve) -> Any:
    """``options`` with the non-empty string at ``key`` (if any) passed through ``resolve``."""
    if not isinstance(options, dict) or key[0] not in options:
        return options
    v = options[key[0]]
    if len(key) > 1:
        return {**options, key[0]: _with_model_path(v, key[1:], resolve)}
    return {**options, key[0]: resolve(v)} if isinstance(v, str) and v else options


def _absolutize(value: Any) -> Any:
    """Command-line paths are relative to the current directory."""
    if isinstance(value, list):
        return [_absolutize(v) for v in value]
    if isinstance(value, (str, Path)) and not _is_url(str(value)):
        p = Path(os.path.expanduser(str(value)))
        return str(p if p.is_absolute() else Path.cwd() / p)
    return value


# ---------------------------------------------------------------------------------- shipped presets
def configs_dir() -> Path:
    """The folder of the shipped configs (``configs/*.yaml``) and scenario presets (``scenarios/``).

    ``pipeline/_configs`` is a link to the repository's ``configs/`` and ships as package data, so the
    same path works from a source checkout, an editable install and a ``pip install .`` (where the
    wheel holds copies of the files). A checkout without symbolic links falls back to the repository
    folder beside the package.
    """
    here = Path(__file__).resolve().parent
    for d in (here / "_configs", here.parent / "configs"):
        if d.is_dir():
            return d
    raise ConfigError(
        f"the shipped configs are missing: neither {here / '_configs'} nor {here.parent / 'configs'} "
        "is a folder (reinstall fisheye-des)"
    )


def scenarios_dir() -> Path:
    """The folder of the simulator's scenario presets (``configs/scenarios/*.yaml``)."""
    return configs_dir() / "scenarios"


def find_preset(ref: str | Path, folder: Path | None = None, what: str = "config file") -> Path:
    """A YAML file: ``ref`` itself when it exists, else a shipped preset of that name (``.yaml`` optional)
    in ``folder`` (default :func:`configs_dir`), e.g. ``mono_forward`` or ``scenarios/demo``.

    Raises:
        ConfigError: neither a file nor a preset; the message lists the presets there are.
    """
    p = Path(ref).expanduser()
    if p.is_file():
        return p
    folder = configs_dir() if folder is None else folder
    for cand in (folder / p, folder / f"{p}.yaml"):
        if cand.is_file():
            return cand
    names = sorted(q.stem for q in folder.glob("*.yaml"))
    raise ConfigError(
        f"{ref}: {what} not found (neither a file nor a preset in {folder}; "
        f"presets: {', '.join(names) or 'none'})"
    )


def load_config(
    path: str | Path | None = None,
    overrides: list[str] | tuple[str, ...] = (),
    cli: dict[str, Any] | None = None,
) -> PipelineConfig:
    """Load and validate a config.

    Args:
        path: YAML file (or the name of a shipped preset, see :func:`find_preset`), or None for the
            defaults.
        overrides: ``section.key=value`` strings (``--set``); values are parsed as YAML scalars/lists and
            typed by the model; relative paths in them are relative to the current directory.
        cli: dotted keys set by dedicated command-line flags (e.g. ``{"inputs.videos": [...]}``), applied
            after ``overrides``; relative paths relative to the current directory.

    Raises:
        ConfigError: naming the file and line (or the ``--set`` item) and the closest valid key.
    """
    cfg_path = find_preset(path).resolve() if path is not None else None
    if cfg_path is not None:
        data, lines = _read_yaml(cfg_path)
        base_dir = cfg_path.parent
    else:
        data, lines, base_dir = {}, {}, Path.cwd()
    origins: dict[tuple, str] = {}
    items: list[tuple[str, tuple[str, ...], Any]] = []
    for item in overrides:
        parts, value = _parse_override(item)
        items.append((f"--set {item}", parts, value))
    for key, value in (cli or {}).items():
        items.append((f"--{key.split('.')[-1]}", tuple(key.split(".")), value))
    for origin, parts, value in items:
        _check_override_key(parts, origin)
        if _is_path_field(parts):
            value = _absolutize(value)
        _set_in(data, parts, value, origin)
        origins[parts] = origin
    # torch's model file, when the command line gives it, is relative to the current directory (one in
    # the config file is relative to that file: DetectorConfig); its key is known once the name is final
    det = data.get("detector")
    if isinstance(det, dict) and isinstance(det.get("options"), dict):
        key = _model_path_key(det.get("name", DetectorConfig.model_fields["name"].default))
        full = ("detector", "options", *key) if key is not None else None
        # an item setting it or a section holding it: the value is the command line's, not the file's
        if full is not None and any(full[: len(parts)] == parts for _, parts, _ in items):
            det["options"] = _with_model_path(det["options"], key, _absolutize)
    try:
        cfg = PipelineConfig.model_validate(data, context={"base_dir": base_dir})
    except ValidationError as e:
        raise ConfigError(_format_error(e, cfg_path, lines, origins)) from None
    _check_fusion(cfg, cfg_path, lines, origins)
    _check_tracker(cfg, cfg_path, lines, origins)
    _check_ego_motion(cfg, cfg_path, lines, origins)
    return cfg


def t0_beside_trajectory(where: str, t0_s: float) -> ConfigError:
    """The one error for ``ego_motion.t0_s`` beside a trajectory (the config's, a flag's or a batch
    recording's ``trajectory.tum``), ``where``: the place it was set or found."""
    return ConfigError(
        f"{where}: ego_motion.t0_s ({t0_s:g} s) belongs to the constant-velocity motion "
        "(ego_motion.speed_mps) and is not used with a trajectory (its timestamps place the body in time); "
        "expected no ego_motion.t0_s beside a trajectory"
    )


def _check_ego_motion(cfg: PipelineConfig, path: Path | None, lines: dict, origins: dict) -> None:
    """Refuse ``ego_motion.t0_s`` beside ``ego_motion.trajectory`` (it belongs to the constant-velocity
    motion, ``speed_mps``) and ``ego_motion.time_offset_s`` beside ``speed_mps`` (it belongs to a
    trajectory's clock): either would be silently ignored; named where it was set."""
    em = cfg.ego_motion
    if em.trajectory is not None and em.t0_s != 0.0:
        raise t0_beside_trajectory(_where(("ego_motion", "t0_s"), path, lines, origins), em.t0_s)
    if em.speed_mps is not None and em.time_offset_s != 0.0:
        raise ConfigError(
            f"{_where(('ego_motion', 'time_offset_s'), path, lines, origins)}: ego_motion.time_offset_s "
            f"({em.time_offset_s!r} s) shifts a trajectory's clock and is not used with the "
            "constant-velocity motion (ego_motion.speed_mps; its ego_motion.t0_s places the body in time); "
            "expected ego_motion.trajectory beside it, or no ego_motion.time_offset_s"
        )


def _check_tracker(cfg: PipelineConfig, path: Path | None, lines: dict, origins: dict) -> None:
    """Check the names in the free-form tracker groups (``tracker.features`` / ``grouping`` / ``boxes`` /
    ``association``) as the front end will take them (``trackers.frontend.option_problem``, the one
    check), at load time and where they were set, as unknown config keys are: with the closest valid
    name. Then ``tracker.boxes`` beside a detector that gives no boxes (``orb``: no BoxTracker is built,
    so it would be ignored) is refused, naming the detectors that give boxes."""
    groups = {g: v for g, v in cfg.tracker.model_dump().items() if isinstance(v, dict)}  # the free-form ones
    if not any(groups.values()):
        return  # (the front end's import, cv2, only when there is something to check)
    from trackers.detectors import boxes_unused, gives_boxes
    from trackers.frontend import option_problem

    for group, given in groups.items():
        problem = option_problem(group, given, section=f"tracker.{group}")
        if problem is not None:
            key, msg = problem
            raise ConfigError(f"{_where(('tracker', group, key), path, lines, origins)}: {msg}")
    boxes = cfg.tracker.boxes
    if boxes and gives_boxes(cfg.detector.name) is False:
        raise ConfigError(
            f"{_where(('tracker', 'boxes', next(iter(boxes))), path, lines, origins)}: tracker."
            + boxes_unused(cfg.detector.name, boxes)
        )


def _check_fusion(cfg: PipelineConfig, path: Path | None, lines: dict, origins: dict) -> None:
    """Check the fusion section as ``estimators.fusion.FusionSettings`` will take it (its value checks:
    >= 0, a probability, ...), at load time and in the config's words: the key as written
    (``fusion.max_speed_mps``) and where it was set, not the settings class's field name."""
    from estimators.fusion import FusionSettings

    try:
        FusionSettings(**cfg.fusion.settings_kwargs())
    except ConfigError as e:
        m = re.match(r"FusionSettings\.(\w+): (.*)", str(e), re.S)
        if m is None:
            raise ConfigError(f"{_where(('fusion',), path, lines, origins)}: fusion: {e}") from None
        key, problem = m.groups()
        loc = ("fusion", key)
        raise ConfigError(f"{_where(loc, path, lines, origins)}: fusion.{key}: {problem}") from None


def _where(loc: tuple, path: Path | None, lines: dict, origins: dict) -> str:
    """Where the value at ``loc`` was set: the --set item, or file:line of the longest known prefix of
    loc (the file alone, or "config" for the defaults, when no line is known)."""
    for n in range(len(loc), 0, -1):
        if loc[:n] in origins:
            return origins[loc[:n]]
    line = None
    for n in range(len(loc), -1, -1):
        if loc[:n] in lines:
            line = lines[loc[:n]]
            break
    name = str(path) if path is not None else "config"
    return f"{name}:{line}" if line is not None else name


def _format_error(e: ValidationError, path: Path | None, lines: dict, origins: dict) -> str:
    errors = sorted(e.errors(), key=lambda x: x["type"] != "extra_forbidden")  # a typo explains 'missing'
    err = errors[0]
    loc = tuple(err["loc"])
    where = _where(loc, path, lines, origins)
    dotted = ".".join(str(p) for p in loc) or "(top level)"
    # its own clause, after the message (whose tail may be a list of valid keys or an expectation)
    more = (f"; {len(errors) - 1} more error{'s' if len(errors) > 2 else ''} besides this one"
            if len(errors) > 1 else "")
    if err["type"] == "extra_forbidden":
        gone = _removed(loc)
        if gone:
            return f"{where}: {gone}{more}"
        owner = _descend(loc[:-1])
        valid = list(owner.model_fields) if owner is not None else []
        parent = ".".join(str(p) for p in loc[:-1]) or "top level"
        return f"{where}: unknown key '{loc[-1]}' in {parent}" + did_you_mean(str(loc[-1]), valid) + more
    # wrong type / value: say what is expected from the field's description
    owner = _model_at(loc)
    desc = ""
    key = next(
        (p for p in reversed(loc) if isinstance(p, str) and owner is not None and p in owner.model_fields),
        None,
    )
    if owner is not None and key is not None:
        desc = owner.model_fields[key].description or ""
        desc = f"; expected {desc.split(':', 1)[0]}" if desc else ""
    got = err.get("input")
    got_txt = "" if isinstance(got, dict) else f" (got {got!r})"
    msg = err["msg"].replace("Value error, ", "")
    return f"{where}: {dotted}: {msg}{got_txt}{desc}{more}"


def write_resolved(
    cfg: PipelineConfig,
    out_dir: str | Path,
    source: str | Path | None = None,
    overrides: list[str] | tuple[str, ...] = (),
) -> Path:
    """Write the config as run (defaults filled in, absolute paths) to ``out_dir/config.resolved.yaml``."""
    out = Path(out_dir) / RESOLVED_NAME
    out.parent.mkdir(parents=True, exist_ok=True)
    header = "# fisheye-des: the configuration as run (defaults filled in, paths absolute)\n"
    if source is not None:
        header += f"# from: {source}\n"
    for o in overrides:
        header += f"# --set {o}\n"
    body = yaml.safe_dump(cfg.model_dump(mode="json"), sort_keys=False, default_flow_style=None)
    out.write_text(header + body)
    return out


def describe_config(model: type[BaseModel] = PipelineConfig, prefix: str = "") -> str:
    """Every key as ``section.key: type, unit: meaning [default]`` lines (docs, ``--describe-config``)."""
    rows = []
    for name, f in model.model_fields.items():
        key = f"{prefix}{name}"
        subs: list[tuple[type[BaseModel], str]] = []
        for a in _unwrap(f.annotation):
            if isinstance(a, type) and issubclass(a, BaseModel):
                subs.append((a, key + "."))
            elif typing.get_origin(a) in (list, tuple):
                subs += [
                    (t, key + "[].")
                    for inner in typing.get_args(a)
                    for t in _unwrap(inner)
                    if isinstance(t, type) and issubclass(t, BaseModel)
                ]
        if subs and typing.get_origin(f.annotation) is None and not f.is_required() and f.default_factory:
            rows.append(f"{key}: {f.description}")
            rows.append(describe_config(subs[0][0], prefix=subs[0][1]))
            continue
        default = "" if f.is_required() else f" [default: {f.get_default(call_default_factory=True)!r}]"
        rows.append(f"  {key}: {f.description}{default}")
        for sub, pre in subs:
            rows.append(describe_config(sub, prefix=pre))
    return "\n".join(r for r in rows if r)
