"""Scenario description of the simulator: objects, their motions, the observer, the rig, realism.

A scenario is a YAML file validated by the pydantic models below (unknown keys are errors). All
lengths in metres, times in seconds, angles in degrees only where the key says ``_deg``.
World frame W: z up. Object positions are the object's reference point in W at ``t_s``:
the centre for spheres, boxes, walls and drones; the centre of the *base* for poles.

Example::

    name: mono_straight
    duration_s: 3.0
    fps: 30
    rig: {kind: mono, resolution: [1280, 720]}
    observer: {kind: straight, speed_mps: 5.0, start: {position_m: [0, 0, 2]}}
    ground: {z_m: 0.0}
    obstacles:
      - {id: 1, kind: sphere, radius_m: 1.0, position_m: [20, 2, 2]}
      - {id: 2, kind: pole, radius_m: 0.15, height_m: 6, position_m: [15, -3, 0]}
      - {id: 3, kind: drone, position_m: [25, 10, 3],
         motion: {kind: constant_velocity, velocity_mps: [0, -4, 0]}}
"""

from __future__ import annotations

import difflib
import typing
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from estimators.errors import ConfigError

Vec3 = tuple[float, float, float]
Colour = tuple[float, float, float]  # BGR in [0, 1]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# ----------------------------------------------------------------------------------------- motions
class StaticMotion(_Model):
    """The object stays at its ``position_m``."""

    kind: Literal["static"] = "static"


class ConstantVelocityMotion(_Model):
    """``p_W(t) = position_m + velocity_mps * (t - t0_s)``."""

    kind: Literal["constant_velocity"] = "constant_velocity"
    velocity_mps: Vec3
    t0_s: float = 0.0


class WaypointMotion(_Model):
    """Piecewise-linear path through ``positions_m`` at ``times_s``; held at the ends.

    The object's ``position_m`` is ignored (the first waypoint is the start)."""

    kind: Literal["waypoints"] = "waypoints"
    times_s: list[float]
    positions_m: list[Vec3]

    @model_validator(mode="after")
    def _check(self) -> WaypointMotion:
        if len(self.times_s) < 2 or len(self.times_s) != len(self.positions_m):
            raise ValueError(
                f"waypoints: expected >= 2 times_s and as many positions_m, got {len(self.times_s)} "
                f"and {len(self.positions_m)}"
            )
        if np.any(np.diff(self.times_s) <= 0):
            raise ValueError(f"waypoints: times_s must increase strictly, got {self.times_s}")
        return self


Motion = Annotated[StaticMotion | ConstantVelocityMotion | WaypointMotion, Field(discriminator="kind")]


# ----------------------------------------------------------------------------------------- objects
class TextureSpec(_Model):
    """Hashed random checker texture fixed to the object (solid texture in object coordinates).

    ``cell_m``: coarse cell size (default: from the object's size); fine cells are ``cell_m / 3``.
    ``colour``: BGR tint in [0, 1] of the bright cells; ``contrast`` in (0, 1].
    """

    seed: int | None = None
    cell_m: float | None = Field(default=None, gt=0)
    colour: Colour = (1.0, 1.0, 1.0)
    contrast: float = Field(default=0.85, gt=0, le=1)


class ObstacleSpec(_Model):
    """One obstacle. Sizes by kind:

    - ``sphere``: ``radius_m``.
    - ``box`` / ``wall``: ``size_m`` [x, y, z] full extents in the object frame; ``yaw_deg`` turns it
      about W's z. A wall is a box (default 0.2 x 6 x 4 m: facing +x).
    - ``pole``: vertical cylinder, ``radius_m`` and ``height_m``; ``position_m`` is the base centre.
    - ``drone``: a small quadcopter body (``size_m``, default 0.5 x 0.5 x 0.12) with red (its left),
      green (its right) and white (tail) navigation lights; heads along its velocity when it moves,
      else along ``yaw_deg``.
    """

    id: int = Field(ge=0)
    kind: Literal["sphere", "box", "pole", "wall", "drone"]
    position_m: Vec3 = (0.0, 0.0, 0.0)
    radius_m: float | None = Field(default=None, gt=0)
    size_m: Vec3 | None = None
    height_m: float | None = Field(default=None, gt=0)
    yaw_deg: float = 0.0
    motion: Motion = StaticMotion()
    texture: TextureSpec = TextureSpec()
    light_radius_m: float = Field(default=0.05, gt=0)

    @model_validator(mode="after")
    def _check(self) -> ObstacleSpec:
        k = self.kind
        if k == "sphere" and self.radius_m is None:
            raise ValueError(f"obstacle {self.id}: a sphere needs radius_m")
        if k == "box" and self.size_m is None:
            raise ValueError(f"obstacle {self.id}: a box needs size_m [x, y, z]")
        if k == "pole" and (self.radius_m is None or self.height_m is None):
            raise ValueError(f"obstacle {self.id}: a pole needs radius_m and height_m")
        if self.size_m is not None and min(self.size_m) <= 0:
            raise ValueError(f"obstacle {self.id}: size_m must be positive, got {self.size_m}")
        return self

    @property
    def moving(self) -> bool:
        m = self.motion
        if isinstance(m, ConstantVelocityMotion):
            return bool(np.any(np.asarray(m.velocity_mps) != 0))
        if isinstance(m, WaypointMotion):
            return bool(np.ptp(np.asarray(m.positions_m), axis=0).max() > 0)
        return False


class GroundSpec(_Model):
    """Textured horizontal ground plane ``z = z_m`` (W). Its object id is ``id`` (default 0)."""

    enabled: bool = True
    z_m: float = 0.0
    id: int = 0
    cell_m: float = Field(default=1.0, gt=0)
    seed: int = 7
    colour: Colour = (0.55, 0.65, 0.6)
    contrast: float = Field(default=0.45, gt=0, le=1)


class SkySpec(_Model):
    """Sky gradient (BGR in [0, 1]) from the horizon to the zenith; below the horizon ``nadir``."""

    zenith: Colour = (0.85, 0.55, 0.35)
    horizon: Colour = (0.95, 0.85, 0.8)
    nadir: Colour = (0.35, 0.35, 0.35)


# ------------------------------------------------------------------------------------ observer, rig
class StartSpec(_Model):
    position_m: Vec3 = (0.0, 0.0, 2.0)
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0


class ObserverSpec(_Model):
    """The drone's (body B) trajectory.

    ``straight``: along its heading at ``speed_mps``; ``turning``: constant ``yaw_rate_deg_s`` (the
    body heads along its velocity); ``climbing``: ``climb_rate_mps`` up while flying forward (level
    body); ``hover``: speed 0. Fields combine (a turning climb is allowed). ``tum``: the poses of
    the TUM file ``tum_path`` (relative to the scenario file), which must cover the scenario's span.
    """

    kind: Literal["straight", "turning", "climbing", "hover", "tum"] = "straight"
    tum_path: str | None = None
    speed_mps: float = Field(default=0.0, ge=0.0, le=40.0)
    yaw_rate_deg_s: float = 0.0
    climb_rate_mps: float = 0.0
    start: StartSpec = StartSpec()

    @model_validator(mode="after")
    def _check(self) -> ObserverSpec:
        if self.kind == "turning" and self.yaw_rate_deg_s == 0:
            raise ValueError("observer: kind 'turning' needs a non-zero yaw_rate_deg_s")
        if self.kind == "climbing" and self.climb_rate_mps == 0:
            raise ValueError("observer: kind 'climbing' needs a non-zero climb_rate_mps")
        if self.kind == "hover" and (self.speed_mps != 0 or self.climb_rate_mps != 0):
            raise ValueError("observer: kind 'hover' must have speed_mps 0 and climb_rate_mps 0")
        if (self.kind == "tum") != (self.tum_path is not None):
            raise ValueError("observer: tum_path is required with kind 'tum' and only allowed with it")
        return self


class CameraModelSpec(_Model):
    """A camera model by registry name with its parameters (``estimators.cameras``).

    Without ``params`` a default lens is used: a 195-degree fisheye whose image circle fits inside
    the frame (see ``pipeline.sim.rigs.default_model``)."""

    name: Literal["kannala_brandt", "double_sphere", "equidistant", "eucm"] = "kannala_brandt"
    params: dict[str, Any] | None = None
    fov_deg: float = Field(default=195.0, gt=60, le=240)


class CustomCameraSpec(_Model):
    """A camera of a ``custom`` rig: ``T_C_B`` as a 4x4 row-major matrix (p_C = T_C_B p_B)."""

    name: str
    model: CameraModelSpec = CameraModelSpec()
    T_C_B: list[list[float]]


class RigSpec(_Model):
    """``mono``: one forward camera; ``stereo``: forward pair, ``baseline_m`` along body y;
    ``top_bottom``: optical axes along body +z and -z, ``separation_m`` apart on body z;
    ``custom``: ``cameras`` listed. ``offset_m``: the mono camera's centre in B."""

    kind: Literal["mono", "stereo", "top_bottom", "custom"] = "mono"
    resolution: tuple[int, int] = (1280, 720)
    model: CameraModelSpec = CameraModelSpec()
    baseline_m: float = Field(default=0.30, gt=0)
    separation_m: float = Field(default=0.10, ge=0)
    offset_m: Vec3 = (0.0, 0.0, 0.0)
    cameras: list[CustomCameraSpec] | None = None

    @field_validator("resolution")
    @classmethod
    def _res(cls, v: tuple[int, int]) -> tuple[int, int]:
        if v[0] < 16 or v[1] < 16:
            raise ValueError(f"resolution: expected [width, height] >= 16 pixels, got {list(v)}")
        return v

    @model_validator(mode="after")
    def _check(self) -> RigSpec:
        if self.kind == "custom" and not self.cameras:
            raise ValueError("rig: kind 'custom' needs a list of cameras")
        return self


# ------------------------------------------------------------------------------------------ realism
class MotionBlurSpec(_Model):
    """Average of ``subframes`` renders spread over ``exposure_s`` ending at the frame time."""

    subframes: int = Field(default=1, ge=1, le=32)
    exposure_s: float = Field(default=0.0, ge=0)


class ExposureSpec(_Model):
    """Gain over time: ``gain(t) = base_gain * (1 + amplitude * sin(2 pi t / period_s))`` times the
    factor of the last ``steps`` entry ``[t_s, factor]`` whose time has passed."""

    base_gain: float = Field(default=1.0, gt=0)
    amplitude: float = Field(default=0.0, ge=0, lt=1)
    period_s: float = Field(default=2.0, gt=0)
    steps: list[tuple[float, float]] = []


class RealismSpec(_Model):
    """Image effects. ``supersample``: s x s rays per pixel averaged (anti-aliased edges and
    textures, s^2 times the render cost)."""

    supersample: int = Field(default=1, ge=1, le=4)
    noise_sigma: float = Field(default=0.0, ge=0, description="Gaussian pixel noise, grey levels (0-255)")
    motion_blur: MotionBlurSpec = MotionBlurSpec()
    exposure: ExposureSpec = ExposureSpec()
    frame_drop_prob: float = Field(default=0.0, ge=0, lt=1)


class Scenario(_Model):
    """A complete simulated flight. ``seed`` drives textures, noise and frame drops."""

    name: str
    description: str = ""
    seed: int = 0
    duration_s: float = Field(default=3.0, gt=0)
    fps: float = Field(default=30.0, gt=0, le=1000)
    rig: RigSpec = RigSpec()
    observer: ObserverSpec = ObserverSpec()
    ground: GroundSpec = GroundSpec()
    sky: SkySpec = SkySpec()
    obstacles: list[ObstacleSpec] = []
    realism: RealismSpec = RealismSpec()

    @model_validator(mode="after")
    def _ids(self) -> Scenario:
        ids = [o.id for o in self.obstacles]
        dup = sorted({i for i in ids if ids.count(i) > 1})
        if dup:
            raise ValueError(f"obstacle ids must be unique; repeated: {dup}")
        if self.ground.enabled and self.ground.id in ids:
            raise ValueError(f"ground id {self.ground.id} is also an obstacle id; give ground.id another")
        return self

    @property
    def n_frames(self) -> int:
        return int(np.floor(self.duration_s * self.fps + 1e-9))

    def obstacle(self, obstacle_id: int) -> ObstacleSpec:
        for o in self.obstacles:
            if o.id == obstacle_id:
                return o
        raise ConfigError(f"scenario {self.name!r}: no obstacle with id {obstacle_id}")


def _models_in(annotation) -> list[type[BaseModel]]:
    """The pydantic models an annotation refers to (through Optional, unions, lists, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for a in typing.get_args(annotation) for m in _models_in(a)]


def _keys_at(loc: tuple) -> list[str]:
    """The keys accepted beside the last element of a validation error's ``loc`` (the fields of
    the model that holds it), for the message on an unknown key."""
    cands: list[type[BaseModel]] = [Scenario]
    for part in loc[:-1]:
        if isinstance(part, int):  # a list index
            continue
        nxt = [m for c in cands if part in c.model_fields
               for m in _models_in(c.model_fields[part].annotation)]
        if not nxt:  # the tag of a discriminated union, e.g. motion.constant_velocity
            nxt = [c for c in cands if "kind" in c.model_fields and c.model_fields["kind"].default == part]
        cands = nxt or cands
    return sorted({f for c in cands for f in c.model_fields})


def _format_errors(e: ValidationError, source: str) -> str:
    """One line: ``SOURCE: invalid scenario: loc: message; loc: message`` (unknown keys with a
    close-match suggestion)."""
    parts = []
    for err in e.errors():
        loc = ".".join(str(p) for p in err["loc"])
        msg = err["msg"]
        if err["type"] == "extra_forbidden" and err["loc"]:
            keys = _keys_at(err["loc"])
            close = difflib.get_close_matches(str(err["loc"][-1]), keys, n=1)
            msg = (f"unknown key (did you mean {close[0]!r}?)" if close
                   else f"unknown key; expected: {', '.join(keys)}")
        parts.append(f"{loc or '<top>'}: {msg}")
    return f"{source}: invalid scenario: " + "; ".join(parts)


def _yaml_problem(e: yaml.YAMLError) -> str:
    """A YAML parse error as one line: ``line L, column C: problem``."""
    mark = getattr(e, "problem_mark", None)
    problem = getattr(e, "problem", None) or str(e).splitlines()[0]
    return (f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else "") + problem


def scenario_from_dict(data: dict, source: str = "scenario") -> Scenario:
    """Validate a scenario mapping; a ConfigError lists every invalid key with its location."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping at the top level, got {type(data).__name__}")
    try:
        return Scenario.model_validate(data)
    except ValidationError as e:
        raise ConfigError(_format_errors(e, source)) from None


def load_scenario(path: str | Path, overrides: dict | None = None) -> Scenario:
    """Read a scenario YAML file. ``overrides`` (a mapping) is merged on top at the top level
    (nested mappings merge recursively). Errors name the file and the offending key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: scenario file not found")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML: {_yaml_problem(e)}") from None
    if overrides:
        data = _merge(data or {}, overrides)
    scn = scenario_from_dict(data, source=str(path))
    tum = scn.observer.tum_path
    if tum is not None and not Path(tum).is_absolute():  # paths are relative to the scenario file
        obs = scn.observer.model_copy(update={"tum_path": str((path.parent / tum).resolve())})
        scn = scn.model_copy(update={"observer": obs})
    return scn


def _merge(a: dict, b: dict) -> dict:
    out = dict(a)
    for k, v in b.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def dump_scenario(scn: Scenario, path: str | Path) -> None:
    """Write the resolved scenario (every default filled in) as YAML."""
    Path(path).write_text(yaml.safe_dump(scn.model_dump(mode="json"), sort_keys=False))
