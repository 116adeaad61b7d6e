"""Camera models and rigs of a scenario, built with ``estimators.cameras`` / ``estimators.rig``."""

from __future__ import annotations

import numpy as np

from estimators.cameras import CameraModel, make_camera_model
from estimators.errors import CalibrationError, ConfigError
from estimators.rig import Camera, Rig, mono_forward_rig, stereo_forward_rig, top_bottom_rig
from estimators.se3 import Pose
from pipeline.sim.scene import CameraModelSpec, RigSpec

# Shape parameters of the default lenses (plausible values of real 190-200 degree fisheyes);
# the focal length is then chosen so that the image circle fits inside the frame.
_DEFAULT_SHAPE = {
    "kannala_brandt": {"k1": -0.012, "k2": 0.002, "k3": -0.0004, "k4": 0.0},
    "double_sphere": {"xi": -0.2, "alpha": 0.6},
    "eucm": {"alpha": 0.6, "beta": 1.1},
    "equidistant": {},
}
CIRCLE_FILL = 0.47  # image-circle radius as a share of min(width, height)


def default_model(name: str, width: int, height: int, fov_deg: float = 195.0) -> CameraModel:
    """A ``fov_deg`` fisheye of model ``name`` whose image circle (radius ``CIRCLE_FILL *
    min(width, height)``) is centred in a ``width x height`` image."""
    half = float(np.deg2rad(fov_deg / 2.0))
    shape = _DEFAULT_SHAPE[name]
    unit = make_camera_model(name, fx=1.0, fy=1.0, cx=0.0, cy=0.0, width=width, height=height,
                             max_angle_rad=half, **shape)
    if unit.max_angle_rad < half - 1e-6:
        raise ConfigError(
            f"camera model {name!r} with default shape {shape} images at most "
            f"{np.rad2deg(unit.max_angle_rad) * 2:.1f} deg; asked for fov_deg {fov_deg}"
        )
    _, _, r1 = unit.image_circle()  # radius of the circle at f = 1
    f = CIRCLE_FILL * min(width, height) / r1
    return make_camera_model(name, fx=f, fy=f, cx=(width - 1) / 2.0, cy=(height - 1) / 2.0,
                             width=width, height=height, max_angle_rad=half, **shape)


def build_model(spec: CameraModelSpec, resolution: tuple[int, int]) -> CameraModel:
    """The model of ``spec`` at ``resolution`` (W, H): explicit ``params`` or the default lens.

    Explicit params without width/height get them from ``resolution``."""
    W, H = resolution
    if spec.params is None:
        return default_model(spec.name, W, H, spec.fov_deg)
    p = dict(spec.params)
    p.setdefault("width", W)
    p.setdefault("height", H)
    try:
        return make_camera_model(spec.name, **p)
    except CalibrationError as e:
        raise ConfigError(f"rig.model: {e}") from None


def build_rig(spec: RigSpec, resolution: tuple[int, int] | None = None) -> Rig:
    """The ``Rig`` of a scenario. ``resolution`` overrides ``spec.resolution`` (the lens is then
    the same lens scaled, so a resized run sees the same field of view)."""
    res = tuple(spec.resolution)
    if spec.kind == "custom":
        cams = []
        for c in spec.cameras or []:
            m = build_model(c.model, res)
            T = np.asarray(c.T_C_B, float)
            if T.shape != (4, 4):
                raise ConfigError(f"rig.cameras[{c.name}].T_C_B: expected a 4x4 matrix, got shape {T.shape}")
            cams.append(Camera(c.name, _rescale(m, resolution), Pose.from_matrix(T)))
        return Rig(tuple(cams))
    model = _rescale(build_model(spec.model, res), resolution)
    if spec.kind == "mono":
        return mono_forward_rig(model, offset_B=spec.offset_m)
    if spec.kind == "stereo":
        return stereo_forward_rig(model, spec.baseline_m)
    return top_bottom_rig(model, spec.separation_m)


def _rescale(model: CameraModel, resolution: tuple[int, int] | None) -> CameraModel:
    if resolution is None or tuple(resolution) == (model.width, model.height):
        return model
    W, H = resolution
    f = W / model.width
    if abs(H / model.height - f) > 0.02:
        raise ConfigError(
            f"--resolution {W}x{H}: expected the aspect ratio of the scenario's "
            f"{model.width}x{model.height} (scaling the lens needs one factor)"
        )
    m = model.scaled(f)
    if (m.width, m.height) != (W, H):
        p = m.params()
        p.update(width=W, height=H)
        m = type(m)(**p)
    return m
