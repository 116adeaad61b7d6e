"""Cameras mounted on the body, and rigs of them (mono, stereo, N cameras).

Frames (CONVENTIONS.md): body B is FLU (x forward, y left, z up); camera optical frame C is
x right, y down, z forward along the optical axis. ``T_C_B`` maps body points into the camera,
``p_C = T_C_B p_B``; the camera centre in B is ``T_C_B.inverse().t``.

Standard mounts (rotation ``R_C_B`` written out; its rows are the C axes expressed in B):

- forward: optical z = body +x, image x (right) = body -y, image y (down) = body -z;
- up: optical z = body +z, image y (down) = body -x (the top of the image points forward),
  image x = body +y;
- down: optical z = body -z, image y (down) = body -x (top of the image forward), image x = body -y.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from estimators.cameras import CameraModel
from estimators.errors import ConfigError, InputError
from estimators.se3 import Pose

__all__ = [
    "R_C_B_DOWN",
    "R_C_B_FORWARD",
    "R_C_B_UP",
    "Camera",
    "Rig",
    "down_T_C_B",
    "forward_T_C_B",
    "mono_forward_rig",
    "stereo_forward_rig",
    "top_bottom_rig",
    "up_T_C_B",
]

# Forward camera. Rows = x_C, y_C, z_C in body coordinates:
#   x_C (image right) = -y_B, y_C (image down) = -z_B, z_C (optical axis) = +x_B.
R_C_B_FORWARD = np.array(
    [
        [0.0, -1.0, 0.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
    ]
)
# Camera looking up (thesis ch. 5 top camera). Rows = x_C, y_C, z_C in body coordinates:
#   x_C = +y_B, y_C = -x_B (top of the image towards the nose), z_C = +z_B.
R_C_B_UP = np.array(
    [
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
    ]
)
# Camera looking down (thesis ch. 5 bottom camera). Rows = x_C, y_C, z_C in body coordinates:
#   x_C = -y_B, y_C = -x_B (top of the image towards the nose), z_C = -z_B.
R_C_B_DOWN = np.array(
    [
        [0.0, -1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
    ]
)


def _mount(R_C_B: np.ndarray, offset_B) -> Pose:
    """Camera at ``offset_B`` (its centre in B, metres) with rotation R_C_B: p_C = R_C_B (p_B - c_B)."""
    c_B = np.asarray(offset_B, dtype=float).reshape(-1)
    if c_B.shape != (3,) or not np.all(np.isfinite(c_B)):
        raise InputError(f"camera offset: expected a finite (3,) position in B (m), got {offset_B!r}")
    return Pose(R_C_B, -R_C_B @ c_B)


def forward_T_C_B(offset_B=(0.0, 0.0, 0.0)) -> Pose:
    """``T_C_B`` of a camera looking along body +x, centred at ``offset_B`` (3,) metres in B."""
    return _mount(R_C_B_FORWARD, offset_B)


def up_T_C_B(offset_B=(0.0, 0.0, 0.0)) -> Pose:
    """``T_C_B`` of a camera looking along body +z (up), image top towards the nose, at ``offset_B`` (m)."""
    return _mount(R_C_B_UP, offset_B)


def down_T_C_B(offset_B=(0.0, 0.0, 0.0)) -> Pose:
    """``T_C_B`` of a camera looking along body -z (down), image top towards the nose, at ``offset_B`` (m)."""
    return _mount(R_C_B_DOWN, offset_B)


@dataclass(frozen=True, eq=False)
class Camera:
    """One camera of a rig.

    Attributes:
        name: unique name in the rig (e.g. ``cam0``; Kalibr's key).
        model: the intrinsic :class:`~estimators.cameras.CameraModel`.
        T_C_B: body-to-camera transform, ``p_C = T_C_B p_B`` (Kalibr's ``T_cam_imu``).
    """

    name: str
    model: CameraModel
    T_C_B: Pose

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"Camera: expected a non-empty name, got {self.name!r}")
        if not isinstance(self.model, CameraModel):
            raise InputError(f"Camera {self.name!r}: expected a CameraModel, got {type(self.model).__name__}")
        if not isinstance(self.T_C_B, Pose):
            raise InputError(f"Camera {self.name!r}: expected T_C_B a Pose, got {type(self.T_C_B).__name__}")

    @property
    def centre_B(self) -> np.ndarray:
        """Camera centre in B (3,), metres."""
        return self.T_C_B.inverse().t

    @property
    def T_B_C(self) -> Pose:
        """Camera-to-body transform, ``p_B = T_B_C p_C``."""
        return self.T_C_B.inverse()

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Camera):
            return NotImplemented
        return (
            self.name == other.name
            and self.model == other.model
            and np.array_equal(self.T_C_B.R, other.T_C_B.R)
            and np.array_equal(self.T_C_B.t, other.T_C_B.t)
        )


@dataclass(frozen=True)
class Rig:
    """The cameras on the body.

    Attributes:
        cameras: tuple of :class:`Camera`, at least one, unique names; the order is meaningful
            (cam0 first; in a stereo rig cameras[0] is the left/reference camera).
    """

    cameras: tuple[Camera, ...]

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        if not cams:
            raise ConfigError("Rig: expected at least one camera, got none")
        for c in cams:
            if not isinstance(c, Camera):
                raise ConfigError(f"Rig: expected Camera objects, got {type(c).__name__}")
        names = [c.name for c in cams]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ConfigError(f"Rig: camera names must be unique; duplicated: {', '.join(dup)}")
        object.__setattr__(self, "cameras", cams)

    @property
    def kind(self) -> str:
        """``"mono"`` (1 camera), ``"stereo"`` (2) or ``"multi"`` (3 or more)."""
        return {1: "mono", 2: "stereo"}.get(len(self.cameras), "multi")

    @property
    def names(self) -> tuple[str, ...]:
        """Camera names in rig order."""
        return tuple(c.name for c in self.cameras)

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __getitem__(self, key: str | int) -> Camera:
        """A camera by name (``rig["cam0"]``) or index (``rig[0]``)."""
        if isinstance(key, int):
            if not -len(self.cameras) <= key < len(self.cameras):
                raise InputError(f"Rig: camera index {key} out of range; the rig has {len(self.cameras)}")
            return self.cameras[key]
        for c in self.cameras:
            if c.name == key:
                return c
        raise InputError(f"Rig: no camera named {key!r}; cameras: {', '.join(self.names)}")


def mono_forward_rig(model: CameraModel, name: str = "cam0", offset_B=(0.0, 0.0, 0.0)) -> Rig:
    """One forward-looking camera (the thesis's DES-MFLC set-up) at ``offset_B`` (3,) metres in B."""
    return Rig((Camera(name, model, forward_T_C_B(offset_B)),))


def stereo_forward_rig(model: CameraModel, baseline_m: float, model_right: CameraModel | None = None) -> Rig:
    """Two forward-looking cameras with a baseline along body y (the thesis's DES-BFLC set-up).

    ``cam0`` (left) is at ``y = +baseline_m/2``, ``cam1`` (right) at ``y = -baseline_m/2``.
    ``model_right`` defaults to ``model``.
    """
    b = float(baseline_m)
    if not np.isfinite(b) or b <= 0:
        raise ConfigError(f"stereo_forward_rig: expected baseline_m > 0, got {baseline_m!r}")
    return Rig(
        (
            Camera("cam0", model, forward_T_C_B((0.0, b / 2, 0.0))),
            Camera("cam1", model if model_right is None else model_right, forward_T_C_B((0.0, -b / 2, 0.0))),
        )
    )


def top_bottom_rig(
    model: CameraModel, separation_m: float = 0.0, model_bottom: CameraModel | None = None
) -> Rig:
    """The thesis's chapter-5 360-degree rig: ``cam0`` looks up (+z_B), ``cam1`` down (-z_B).

    The centres are at ``z = +separation_m/2`` and ``-separation_m/2`` on the body z axis.
    """
    h = float(separation_m)
    if not np.isfinite(h) or h < 0:
        raise ConfigError(f"top_bottom_rig: expected separation_m >= 0, got {separation_m!r}")
    return Rig(
        (
            Camera("cam0", model, up_T_C_B((0.0, 0.0, h / 2))),
            Camera("cam1", model if model_bottom is None else model_bottom, down_T_C_B((0.0, 0.0, -h / 2))),
        )
    )
