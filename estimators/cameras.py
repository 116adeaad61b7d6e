"""Fisheye camera models: pixels <-> unit bearings, vectorised in numpy (float64).

Every model implements :class:`CameraModel`. Bearings ``b_C`` are unit 3-vectors in the camera
optical frame C (x right, y down, z forward, CONVENTIONS.md), valid beyond 90 degrees off the
optical axis; pixels ``uv`` follow OpenCV (integer coordinates are pixel centres, origin at the
top-left pixel, so the image spans ``[-0.5, width - 0.5] x [-0.5, height - 0.5]``).

Rows that are invalid (non-finite input, outside the lens's field, outside the model's domain,
outside the image when ``within_image=True``) come back as zeros with ``valid=False``, never NaN.

Models (registry :data:`CAMERA_MODELS`, factory :func:`make_camera_model`):

- ``equidistant``: ``r = f * theta`` (the thesis's linear "degrees per pixel" model, sec. 4.1.3).
- ``kannala_brandt``: OpenCV fisheye / Kalibr ``pinhole`` + ``equidistant``, 4 coefficients,
  with ``theta = atan2(sqrt(x^2 + y^2), z)`` so that rays beyond 90 degrees work.
- ``double_sphere``: Usenko, Demmel, Cremers, "The Double Sphere Camera Model", 3DV 2018.
- ``eucm``: the enhanced unified camera model (Khomutenko et al. 2016), as in Kalibr and basalt.
"""

from __future__ import annotations

import dataclasses
import functools
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from estimators.errors import CalibrationError, InputError, check_shape

__all__ = [
    "CAMERA_MODELS",
    "CameraModel",
    "DoubleSphere",
    "Equidistant",
    "Eucm",
    "KannalaBrandt",
    "make_camera_model",
    "register_camera_model",
]

# No model images the exact backward ray (theta = pi maps to a whole circle for the theta models):
# every max_angle_rad is capped just below pi.
MAX_ANGLE_CAP_RAD = np.pi - 1e-6
# Slack on angle comparisons so that a bearing exactly at the lens limit (and its round trip) is valid.
_ANGLE_TOL_RAD = 1e-9

CAMERA_MODELS: dict[str, type[CameraModel]] = {}


def register_camera_model(cls: type[CameraModel]) -> type[CameraModel]:
    """Class decorator: add a :class:`CameraModel` subclass to :data:`CAMERA_MODELS` under ``cls.name``."""
    if cls.name in CAMERA_MODELS and CAMERA_MODELS[cls.name] is not cls:
        raise CalibrationError(f"camera model name {cls.name!r} is already registered")
    CAMERA_MODELS[cls.name] = cls
    return cls


def make_camera_model(name: str, **params) -> CameraModel:
    """Build a registered camera model by name, e.g. ``make_camera_model("kannala_brandt", fx=..., ...)``.

    ``params`` are the model's keyword fields (those returned by ``model.params()``). An unknown
    name or parameter is a CalibrationError that lists the valid ones.
    """
    cls = CAMERA_MODELS.get(name)
    if cls is None:
        raise CalibrationError(
            f"unknown camera model {name!r}; expected one of: {', '.join(sorted(CAMERA_MODELS))}"
        )
    fields = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(params) - set(fields))
    if unknown:
        raise CalibrationError(
            f"camera model {name!r}: unknown parameter(s) {', '.join(unknown)}; "
            f"expected: {', '.join(fields)}"
        )
    try:
        return cls(**params)
    except TypeError as e:  # a missing required field
        raise CalibrationError(f"camera model {name!r}: {e}; expected: {', '.join(fields)}") from e


def _float(model, field: str) -> float:
    """A model field as a finite Python float, else a CalibrationError naming the model and field."""
    v = getattr(model, field)
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise CalibrationError(f"{model.name}: expected {field} a number, got {v!r}") from None
    if not np.isfinite(f):
        raise CalibrationError(f"{model.name}: expected {field} finite, got {f}")
    return f


def _tangent_basis(b: np.ndarray) -> np.ndarray:
    """Orthonormal tangent basis of the unit sphere at unit bearings ``b`` (N,3) -> (N,3,2)."""
    a = np.zeros_like(b)
    use_x = np.abs(b[:, 0]) < 0.9
    a[use_x, 0] = 1.0
    a[~use_x, 1] = 1.0
    t1 = np.cross(a, b)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(b, t1)
    return np.stack([t1, t2], axis=2)


class CameraModel(ABC):
    """A central camera model mapping pixels to unit bearings in the optical frame C and back.

    Subclasses are frozen, keyword-only dataclasses whose fields are the model's parameters
    (``params()`` returns them; ``make_camera_model(name, **params)`` rebuilds the model).
    They implement three hooks on finite, unit-norm rows: ``_project``, ``_project_jacobian``
    and ``_unproject``; the public methods here add input checks, the angle limit, the image
    bounds and the zero/valid convention.

    Attributes:
        name: registry name.
        width, height: image size in pixels.
        max_angle_rad: largest angle off the optical axis (+z of C) the lens images (half FOV), rad.
    """

    name: ClassVar[str]
    width: int
    height: int
    max_angle_rad: float

    # ----------------------------------------------------------------------------- model hooks
    @abstractmethod
    def _project(self, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit bearings (M,3), finite -> (uv (M,2), valid (M,)) ignoring the angle limit and image."""

    @abstractmethod
    def _project_jacobian(self, b: np.ndarray) -> np.ndarray:
        """d uv / d b at unit bearings (M,3) -> (M,2,3) (the derivative for an unnormalised input)."""

    @abstractmethod
    def _unproject(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Finite pixels (M,2) -> (unit bearings (M,3), valid (M,)) ignoring the angle limit and image."""

    # ------------------------------------------------------------------------------ public API
    def in_image(self, uv: np.ndarray) -> np.ndarray:
        """Pixels ``uv`` (N,2) -> (N,) bool, True inside ``[-0.5, w-0.5] x [-0.5, h-0.5]``."""
        uv = np.asarray(uv, dtype=np.float64)
        with np.errstate(invalid="ignore"):
            return (
                (uv[:, 0] >= -0.5)
                & (uv[:, 0] <= self.width - 0.5)
                & (uv[:, 1] >= -0.5)
                & (uv[:, 1] <= self.height - 0.5)
            )

    def pixel_to_bearing(self, uv: np.ndarray, within_image: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Unproject pixels to unit bearings.

        Args:
            uv: (N,2) pixel coordinates (OpenCV convention), float.
            within_image: when True (default) pixels outside the image are invalid.

        Returns:
            b_C: (N,3) unit bearings in the camera optical frame C; zeros where invalid.
            valid: (N,) bool.
        """
        uv = self._as_points("uv", uv, 2)
        u, v = uv[:, 0], uv[:, 1]
        if within_image:
            # inside [-0.5, w-0.5] x [-0.5, h-0.5] (in_image's test); NaN and +-inf compare False, so
            # this is also the finiteness test
            valid = (u >= -0.5) & (u <= self.width - 0.5) & (v >= -0.5) & (v <= self.height - 0.5)
        else:
            valid = np.isfinite(u) & np.isfinite(v)
        if valid.all():  # the common case (whole images): no gathering and scattering
            b, vi = self._unproject(uv)
            valid = vi & self._within_angle(b)
            if not valid.all():
                b[~valid] = 0.0
            return b, valid
        b = np.zeros((uv.shape[0], 3))
        idx = np.flatnonzero(valid)
        if idx.size:
            bi, vi = self._unproject(uv[idx])
            vi &= self._within_angle(bi)
            b[idx[vi]] = bi[vi]
            valid[idx[~vi]] = False
        return b, valid

    def bearing_to_pixel(self, b_C: np.ndarray, within_image: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Project directions to pixels.

        Args:
            b_C: (N,3) directions in the camera optical frame C (any non-zero length).
            within_image: when True (default) projections outside the image are invalid.

        Returns:
            uv: (N,2) pixels (OpenCV convention); zeros where invalid.
            valid: (N,) bool: finite, non-zero, within ``max_angle_rad`` of +z, in the model's
            domain and (if ``within_image``) inside the image.
        """
        bu, valid, _ = self._unit_rows(b_C)
        if valid.all():  # the common case (every direction in the field): no gathering and scattering
            uv, vi = self._project(bu)
            if within_image:
                vi &= self.in_image(uv)
            if not vi.all():
                uv[~vi] = 0.0
                valid &= vi
            return uv, valid
        uv = np.zeros((bu.shape[0], 2))
        idx = np.flatnonzero(valid)
        if idx.size:
            ui, vi = self._project(bu[idx])
            if within_image:
                vi &= self.in_image(ui)
            uv[idx[vi]] = ui[vi]
            valid[idx[~vi]] = False
        return uv, valid

    def bearing_to_pixel_jacobian(self, b_C: np.ndarray, within_image: bool = True) -> np.ndarray:
        """Jacobian d uv / d b_C of :meth:`bearing_to_pixel`.

        Args:
            b_C: (N,3) directions in C (any non-zero length; the Jacobian is for that vector,
                so it scales with 1/|b_C| and is orthogonal to b_C).
            within_image: as in :meth:`bearing_to_pixel`.

        Returns:
            (N,2,3) in px per unit of b_C; zeros on rows :meth:`bearing_to_pixel` marks invalid.
        """
        bu, _, norm = self._unit_rows(b_C)
        _, valid = self.bearing_to_pixel(b_C, within_image=within_image)
        J = np.zeros((bu.shape[0], 2, 3))
        idx = np.flatnonzero(valid)
        if idx.size:
            # uv(s b) = uv(b) for s > 0, so d uv/d b = J_unit(b/|b|) / |b|.
            J[idx] = self._project_jacobian(bu[idx]) / norm[idx, None, None]
        return J

    def pixel_to_bearing_jacobian(self, uv: np.ndarray, within_image: bool = True) -> np.ndarray:
        """Jacobian d b_C / d uv of :meth:`pixel_to_bearing`.

        Args:
            uv: (N,2) pixels.
            within_image: as in :meth:`pixel_to_bearing`.

        Returns:
            (N,3,2) in unit-bearing per px; zeros on invalid rows. Columns are tangent to the
            unit sphere at b_C.
        """
        b, valid = self.pixel_to_bearing(uv, within_image=within_image)
        J = np.zeros((b.shape[0], 3, 2))
        idx = np.flatnonzero(valid)
        if idx.size:
            # The unprojection is the inverse of the projection restricted to the unit sphere:
            # with T (3x2) a tangent basis at b and P = d uv/d b (2x3), d b/d uv = T (P T)^-1.
            bi = b[idx]
            T = _tangent_basis(bi)
            PT = self._project_jacobian(bi) @ T  # (M,2,2)
            det = PT[:, 0, 0] * PT[:, 1, 1] - PT[:, 0, 1] * PT[:, 1, 0]
            ok = np.abs(det) > 1e-300
            inv = np.empty_like(PT)
            d = np.where(ok, det, 1.0)
            inv[:, 0, 0] = PT[:, 1, 1] / d
            inv[:, 1, 1] = PT[:, 0, 0] / d
            inv[:, 0, 1] = -PT[:, 0, 1] / d
            inv[:, 1, 0] = -PT[:, 1, 0] / d
            Ji = T @ inv
            Ji[~ok] = 0.0
            J[idx] = Ji
        return J

    def image_circle(self) -> tuple[float, float, float]:
        """The lens circle: ``(cx, cy, radius_px)``.

        ``radius_px`` is the smallest distance from the principal point to the projection of a
        ray at ``max_angle_rad`` along the image's +-x and +-y directions (the inscribed circle
        when fx != fy); it may extend beyond the image.
        """
        th = self.max_angle_rad - 2 * _ANGLE_TOL_RAD
        s, c = np.sin(th), np.cos(th)
        b = np.array([[s, 0, c], [-s, 0, c], [0, s, c], [0, -s, c]])
        uv, valid = self._project(b)
        cx, cy = self._principal_point()
        r = np.hypot(uv[:, 0] - cx, uv[:, 1] - cy)
        return float(cx), float(cy), float(np.min(np.where(valid, r, np.inf)))

    @functools.cached_property
    def rad_per_px(self) -> float:
        """Radians per pixel at the lens's mean scale: ``max_angle_rad`` over the image circle's
        radius (at least 1 px); computed once per model object (``image_circle`` projects four rays)."""
        return float(self.max_angle_rad / max(self.image_circle()[2], 1.0))

    def params(self) -> dict:
        """The model's parameters as a dict of plain Python numbers (keyword fields of the class)."""
        return dataclasses.asdict(self)  # type: ignore[call-overload]

    def scaled(self, factor: float) -> CameraModel:
        """The same lens on an image resized by ``factor`` (e.g. 0.5 for half resolution).

        Focal lengths scale by ``factor``; the principal point follows the pixel-centre convention,
        ``c' = (c + 0.5) * factor - 0.5``; width and height are rounded.
        """
        f = float(factor)
        if not np.isfinite(f) or f <= 0:
            raise InputError(f"scaled: expected a finite factor > 0, got {factor!r}")
        p = self.params()
        p.update(
            fx=p["fx"] * f,
            fy=p["fy"] * f,
            cx=(p["cx"] + 0.5) * f - 0.5,
            cy=(p["cy"] + 0.5) * f - 0.5,
            width=max(1, round(p["width"] * f)),
            height=max(1, round(p["height"] * f)),
        )
        return type(self)(**p)

    # ------------------------------------------------------------------------------- helpers
    def _principal_point(self) -> tuple[float, float]:
        return self.cx, self.cy  # type: ignore[attr-defined]

    @staticmethod
    def _as_points(name: str, a, dim: int) -> np.ndarray:
        arr = np.asarray(a, dtype=np.float64)
        check_shape(name, arr, (None, dim))
        return arr

    def _unit_rows(self, b_C) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """-> (unit rows (N,3) with zeros where invalid, valid (N,), norms (N,)) incl. the angle limit."""
        b = self._as_points("b_C", b_C, 3)
        with np.errstate(invalid="ignore", over="ignore"):
            norm = np.linalg.norm(b, axis=1)
            valid = np.isfinite(norm) & (norm > 0)
        if valid.all():  # (the common case: no masked gather and scatter)
            bu = b / norm[:, None]
        else:
            bu = np.zeros_like(b)
            bu[valid] = b[valid] / norm[valid, None]
        valid &= self._within_angle(bu)
        if valid.all():
            return bu, valid, norm
        bu[~valid] = 0.0
        return bu, valid, np.where(valid, norm, 1.0)

    def _within_angle(self, b: np.ndarray) -> np.ndarray:
        """Unit bearings (N,3) -> (N,) bool: angle off +z <= max_angle_rad (+ tolerance).

        theta <= theta_max  <=>  b_z = cos(theta) >= cos(theta_max) for unit b (cos falls on [0, pi]).
        """
        c = self.__dict__.get("_cos_max")  # cos(theta_max), computed once per model
        if c is None:
            c = np.cos(min(self.max_angle_rad + _ANGLE_TOL_RAD, np.pi))
            object.__setattr__(self, "_cos_max", c)
        return b[:, 2] >= c

    def _check_common(self) -> None:
        """Validate and normalise the shared fields (fx, fy, cx, cy, width, height)."""
        for k in ("fx", "fy", "cx", "cy"):
            object.__setattr__(self, k, _float(self, k))
        if self.fx <= 0 or self.fy <= 0:  # type: ignore[attr-defined]
            raise CalibrationError(
                f"{self.name}: expected focal lengths fx, fy > 0 px, "
                f"got {self.fx}, {self.fy}"  # type: ignore[attr-defined]
            )
        for k in ("width", "height"):
            v = getattr(self, k)
            try:
                ok = not isinstance(v, bool | str) and int(v) == v and int(v) > 0
            except (TypeError, ValueError, OverflowError):
                ok = False
            if not ok:
                raise CalibrationError(f"{self.name}: expected {k} a positive integer (px), got {v!r}")
            object.__setattr__(self, k, int(v))

    def _set_max_angle(self, natural_rad: float) -> None:
        """Effective limit = min(natural lens/model limit, user value, just below pi)."""
        user = self.max_angle_rad
        eff = min(float(natural_rad), MAX_ANGLE_CAP_RAD)
        if user is not None:
            u = _float(self, "max_angle_rad")
            if u <= 0:
                raise CalibrationError(f"{self.name}: expected max_angle_rad > 0, got {u}")
            eff = min(eff, u)
        object.__setattr__(self, "max_angle_rad", eff)


# --------------------------------------------------------------------------- theta models
class _ThetaModel(CameraModel):
    """Models of the form ``(u, v) = (fx, fy) * theta_d(theta) * (x, y) / rho + (cx, cy)``,
    ``rho = sqrt(x^2 + y^2)``, ``theta = atan2(rho, z)`` (angle off the optical axis, in [0, pi])."""

    @abstractmethod
    def _theta_d(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """theta (rad) -> (theta_d, d theta_d / d theta)."""

    @abstractmethod
    def _theta_from_theta_d(self, theta_d: np.ndarray) -> np.ndarray:
        """Inverse of theta_d on [0, max_angle_rad]; inputs within [0, theta_d(max_angle_rad)]."""

    def _finish_theta_model(self, natural_rad: float) -> None:
        self._set_max_angle(natural_rad)
        td_max, _ = self._theta_d(np.array([self.max_angle_rad]))
        object.__setattr__(self, "_theta_d_max", float(td_max[0]))

    def _theta_d_value(self, theta: np.ndarray) -> np.ndarray:
        """theta (rad) -> theta_d alone (``_theta_d``'s first value, the same numbers)."""
        return self._theta_d(theta)[0]

    def _project(self, b):
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        rho = np.hypot(x, y)
        theta = np.arctan2(rho, z)  # theta = atan2(sqrt(x^2+y^2), z), in [0, pi]
        td = self._theta_d_value(theta)
        # m = theta_d * (x, y) / rho; on the axis (rho = 0) m = 0.
        off = rho > 0
        s = td / rho if off.all() else np.where(off, td / np.where(off, rho, 1.0), 0.0)
        # (u, v) = (fx s x + cx, fy s y + cy), each column written in place in that order
        uv = np.empty((len(s), 2))
        u, v = uv[:, 0], uv[:, 1]
        np.multiply(s, self.fx, out=u)
        u *= x
        u += self.cx
        np.multiply(s, self.fy, out=v)
        v *= y
        v += self.cy
        return uv, np.ones(b.shape[0], dtype=bool)

    def _project_jacobian(self, b):
        # Unit b: theta = atan2(rho, z), d theta/d(x,y,z) = (z x/rho, z y/rho, -rho).
        # m = s (x, y), s = theta_d/rho; d s/d(x,y) = c (x, y), c = (theta_d' z - s)/rho^2,
        # d s/d z = -theta_d' (for |b| = 1). So
        #   d m/d b = [[s + c x^2, c x y, -x theta_d'], [c x y, s + c y^2, -y theta_d']].
        # The cancellation in c near the axis costs ~eps/rho^2, multiplied by x^2, y^2 <= rho^2.
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        rho = np.hypot(x, y)
        theta = np.arctan2(rho, z)
        td, dtd = self._theta_d(theta)
        off = rho > 1e-150
        r_safe = np.where(off, rho, 1.0)
        s = np.where(off, td / r_safe, dtd)  # on the axis (z = 1): s -> theta_d'(0)
        c = np.where(off, (dtd * z - s) / r_safe**2, 0.0)
        J = np.empty((b.shape[0], 2, 3))
        J[:, 0, 0] = self.fx * (s + c * x * x)
        J[:, 0, 1] = self.fx * c * x * y
        J[:, 0, 2] = -self.fx * x * dtd
        J[:, 1, 0] = self.fy * c * x * y
        J[:, 1, 1] = self.fy * (s + c * y * y)
        J[:, 1, 2] = -self.fy * y * dtd
        return J

    def _unproject(self, uv):
        mx = (uv[:, 0] - self.cx) / self.fx
        my = (uv[:, 1] - self.cy) / self.fy
        td = np.hypot(mx, my)
        valid = td <= self._theta_d_max * (1 + 1e-12) + 1e-15
        if valid.all():
            theta = self._theta_from_theta_d(np.minimum(td, self._theta_d_max))
        else:  # solve only inside the lens circle
            theta = np.zeros_like(td)
            theta[valid] = self._theta_from_theta_d(np.minimum(td[valid], self._theta_d_max))
        # b = (sin(theta) m / theta_d, cos(theta)); on the axis sin(theta)/theta_d -> 1/theta_d'(0) = 1.
        off = td > 0
        if off.all():  # no pixel on the axis (the usual case): the same numbers without the two wheres
            q = np.sin(theta)
            q /= td
        else:
            q = np.where(off, np.sin(theta) / np.where(off, td, 1.0), 1.0)
        b = np.empty((len(td), 3))
        np.multiply(q, mx, out=b[:, 0])
        np.multiply(q, my, out=b[:, 1])
        b[:, 2] = np.cos(theta)  # (into a contiguous temporary: numpy's strided cos may round differently)
        if not valid.all():
            b[~valid] = 0.0
        return b, valid


@register_camera_model
@dataclass(frozen=True, kw_only=True)
class Equidistant(_ThetaModel):
    """Equidistant (linear) fisheye: ``r = f * theta``.

    ``(u, v) = (fx, fy) * theta * (x, y)/rho + (cx, cy)``, ``theta = atan2(rho, z)``.

    The thesis's "degrees per pixel about the image centre" model (sec. 4.1.3); see
    :meth:`from_deg_per_px`. Fields: ``fx, fy`` (px/rad), ``cx, cy`` (px), ``width, height`` (px),
    ``max_angle_rad`` (optional lens limit; default: just below pi).
    """

    name: ClassVar[str] = "equidistant"
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    max_angle_rad: float | None = None

    def __post_init__(self) -> None:
        self._check_common()
        self._finish_theta_model(np.pi)

    @classmethod
    def from_deg_per_px(
        cls,
        deg_per_px: float,
        width: int,
        height: int,
        cx: float | None = None,
        cy: float | None = None,
        max_angle_rad: float | None = None,
    ) -> Equidistant:
        """The thesis's linear model: each pixel away from the image centre adds ``deg_per_px`` degrees.

        ``f = 1 / radians(deg_per_px)`` px/rad, so ``r_px = theta_deg / deg_per_px``. ``cx, cy``
        default to the image centre ``((width - 1)/2, (height - 1)/2)``.
        """
        d = float(deg_per_px)
        if not np.isfinite(d) or d <= 0:
            raise CalibrationError(f"equidistant: expected deg_per_px > 0, got {deg_per_px!r}")
        f = 1.0 / np.radians(d)
        return cls(
            fx=f,
            fy=f,
            cx=(width - 1) / 2.0 if cx is None else cx,
            cy=(height - 1) / 2.0 if cy is None else cy,
            width=width,
            height=height,
            max_angle_rad=max_angle_rad,
        )

    def _theta_d(self, theta):
        return theta, np.ones_like(theta)

    def _theta_from_theta_d(self, theta_d):
        return theta_d


@register_camera_model
@dataclass(frozen=True, kw_only=True)
class KannalaBrandt(_ThetaModel):
    """Kannala-Brandt with 4 coefficients (OpenCV ``cv2.fisheye``, Kalibr ``pinhole`` + ``equidistant``).

    ``theta = atan2(sqrt(x^2+y^2), z)``,
    ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``,
    ``(u, v) = (fx, fy) * theta_d * (x, y)/rho + (cx, cy)`` (no skew). Equals OpenCV for z > 0 and
    continues it beyond 90 degrees. ``max_angle_rad``: the lens limit; by default the largest
    theta <= pi up to which theta_d is still increasing (so that it can be inverted), capped by
    the user's value if given.
    """

    name: ClassVar[str] = "kannala_brandt"
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    k4: float = 0.0
    max_angle_rad: float | None = None

    def __post_init__(self) -> None:
        self._check_common()
        for k in ("k1", "k2", "k3", "k4"):
            object.__setattr__(self, k, _float(self, k))
        self._finish_theta_model(self._monotonic_limit())

    def _monotonic_limit(self) -> float:
        # First zero of theta_d'(theta) = 1 + 3 k1 t + 5 k2 t^2 + 7 k3 t^3 + 9 k4 t^4 (t = theta^2)
        # in (0, pi]: scan a fine grid for the first sign change, then bisect (robust to tiny
        # leading coefficients, where polynomial root finders lose the relevant root).
        th = np.linspace(0.0, np.pi, 8193)
        _, d = self._theta_d(th)
        bad = np.flatnonzero(d <= 0)
        if bad.size == 0:
            return np.pi
        lo, hi = th[bad[0] - 1], th[bad[0]]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if self._theta_d(np.array([mid]))[1][0] > 0:
                lo = mid
            else:
                hi = mid
        return float(lo)

    def _theta_d(self, theta):
        t2 = theta * theta
        # theta_d = theta (1 + k1 t2 + k2 t2^2 + k3 t2^3 + k4 t2^4)
        poly = 1 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4)))
        # d theta_d / d theta = 1 + 3 k1 t2 + 5 k2 t2^2 + 7 k3 t2^3 + 9 k4 t2^4
        dpoly = 1 + t2 * (3 * self.k1 + t2 * (5 * self.k2 + t2 * (7 * self.k3 + t2 * 9 * self.k4)))
        return theta * poly, dpoly

    def _theta_from_theta_d(self, theta_d):
        # Start from a table of theta_d over the monotonic range [0, max_angle_rad] (linear
        # interpolation, error ~1e-7 rad), then two Newton steps theta -= (theta_d(theta) - target)
        # / theta_d'(theta) (quadratic convergence: ~1e-14 rad). Rows that still miss (near the
        # turning point, where theta_d' -> 0) go to the safeguarded solver.
        target = theta_d
        grid = getattr(self, "_theta_grid", None)
        if grid is None:
            th = np.linspace(0.0, self.max_angle_rad, 4097)
            grid = (th, self._theta_d(th)[0])
            object.__setattr__(self, "_theta_grid", grid)
        theta = np.interp(target, grid[1], grid[0])
        # _theta_d written out with the same operations in the same order (so the same numbers),
        # in place: its 20-odd temporaries cost more than the arithmetic on a few hundred rows
        k1, k2, k3, k4 = self.k1, self.k2, self.k3, self.k4
        c1, c2, c3 = 3 * k1, 5 * k2, 7 * k3
        with np.errstate(divide="ignore", invalid="ignore"):
            for _ in range(2):
                t2 = theta * theta
                f = self._theta_d_in_place(theta, t2)
                # df = 1 + t2 (3 k1 + t2 (5 k2 + t2 (7 k3 + t2 9 k4)))
                df = t2 * 9
                df *= k4
                df += c3
                df *= t2
                df += c2
                df *= t2
                df += c1
                df *= t2
                df += 1
                # theta <- theta - (theta_d(theta) - target) / theta_d'(theta)
                f -= target
                f /= df
                theta = theta - f
        # clip to [0, max_angle_rad], NaN -> 0 (as clip(nan_to_num(theta, nan=0))); +-inf clip to the ends
        theta = np.minimum(np.maximum(theta, 0.0), self.max_angle_rad)
        nan = np.isnan(theta)
        if nan.any():
            theta[nan] = 0.0
        f = self._theta_d_in_place(theta, theta * theta)
        f -= target
        np.abs(f, out=f)
        miss = np.flatnonzero(f > 1e-13 * np.maximum(1.0, target))
        if miss.size:
            theta[miss] = self._theta_safeguarded(target[miss])
        return theta

    def _theta_d_value(self, theta):
        return self._theta_d_in_place(theta, theta * theta)

    def _theta_d_in_place(self, theta, t2):
        """theta_d(theta) = theta (1 + t2 (k1 + t2 (k2 + t2 (k3 + t2 k4)))) for theta (N,) rad with
        t2 = theta^2 (N,): _theta_d's value with the same operations in the same order (so the same
        numbers), in place on one new array."""
        f = t2 * self.k4
        f += self.k3
        f *= t2
        f += self.k2
        f *= t2
        f += self.k1
        f *= t2
        f += 1
        f *= theta
        return f

    def _theta_safeguarded(self, target):
        # Safeguarded Newton on f(theta) = theta_d(theta) - target over the monotonic range
        # [0, max_angle_rad]: a Newton step that leaves the bracket [lo, hi] becomes a bisection.
        lo = np.zeros_like(target)
        hi = np.full_like(target, self.max_angle_rad)
        theta = np.clip(target, 0.0, self.max_angle_rad)
        active = np.arange(target.size)
        for _ in range(200):
            if active.size == 0:
                break
            th = theta[active]
            f, df = self._theta_d(th)
            f = f - target[active]
            pos = f > 0
            hi[active] = np.where(pos, th, hi[active])
            lo[active] = np.where(pos, lo[active], th)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = f / df
            new = th - step
            bad = ~np.isfinite(new) | (new < lo[active]) | (new > hi[active])
            new = np.where(bad, 0.5 * (lo[active] + hi[active]), new)
            theta[active] = new
            done = (np.abs(new - th) <= 1e-15 * np.maximum(1.0, th)) | (f == 0)
            active = active[~done]
        return theta


# ------------------------------------------------------------------ models u = f (x, y) / D + c
def _over_denominator(m: CameraModel, b: np.ndarray, den: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """``(u, v) = (fx x / den + cx, fy y / den + cy)`` for rows of b (M,3); den replaced by 1 where
    not valid (those rows are discarded by the caller)."""
    den = np.where(valid, den, 1.0)
    return np.stack([m.fx * b[:, 0] / den + m.cx, m.fy * b[:, 1] / den + m.cy], axis=1)  # type: ignore[attr-defined]


def _over_denominator_jacobian(m: CameraModel, b: np.ndarray, D: np.ndarray, dD: np.ndarray) -> np.ndarray:
    """d uv / d b (M,2,3) of ``u = fx x / D + cx``, ``v = fy y / D + cy`` given D (M,) and dD/db (M,3):
    du/db = fx (e_x / D - x dD/db / D^2), dv/db = fy (e_y / D - y dD/db / D^2)."""
    fx, fy = m.fx, m.fy  # type: ignore[attr-defined]
    J = np.empty((b.shape[0], 2, 3))
    J[:, 0, :] = -fx * (b[:, 0] / D**2)[:, None] * dD
    J[:, 1, :] = -fy * (b[:, 1] / D**2)[:, None] * dD
    J[:, 0, 0] += fx / D
    J[:, 1, 1] += fy / D
    return J


# ----------------------------------------------------------------------------- double sphere
@register_camera_model
@dataclass(frozen=True, kw_only=True)
class DoubleSphere(CameraModel):
    """Double sphere model (Usenko et al. 2018), Kalibr ``ds``: lenses wider than 180 degrees.

    Projection: ``d1 = |b|``, ``d2 = sqrt(x^2 + y^2 + (xi d1 + z)^2)``,
    ``(u, v) = (fx, fy) * (x, y) / (alpha d2 + (1 - alpha)(xi d1 + z)) + (cx, cy)``, valid for
    ``z > -w2 d1`` with ``w1 = alpha/(1-alpha)`` (alpha <= 0.5) or ``(1-alpha)/alpha``,
    ``w2 = (w1 + xi)/sqrt(2 w1 xi + xi^2 + 1)``, i.e. up to ``theta = acos(-w2)`` off the axis.
    Fields: ``xi`` in [-1, 1], ``alpha`` in [0, 1]; ``max_angle_rad`` optionally caps acos(-w2).
    """

    name: ClassVar[str] = "double_sphere"
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    xi: float
    alpha: float
    max_angle_rad: float | None = None

    def __post_init__(self) -> None:
        self._check_common()
        xi, al = _float(self, "xi"), _float(self, "alpha")
        if not -1.0 <= xi <= 1.0:
            raise CalibrationError(f"double_sphere: expected xi in [-1, 1], got {xi}")
        if not 0.0 <= al <= 1.0:
            raise CalibrationError(f"double_sphere: expected alpha in [0, 1], got {al}")
        object.__setattr__(self, "xi", xi)
        object.__setattr__(self, "alpha", al)
        w1 = al / (1 - al) if al <= 0.5 else (1 - al) / al
        w2 = (w1 + xi) / np.sqrt(2 * w1 * xi + xi * xi + 1)
        object.__setattr__(self, "_w2", float(w2))
        self._set_max_angle(float(np.arccos(np.clip(-w2, -1.0, 1.0))))

    def _project(self, b):
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        d1 = np.linalg.norm(b, axis=1)
        w = self.xi * d1 + z
        d2 = np.sqrt(x * x + y * y + w * w)
        den = self.alpha * d2 + (1 - self.alpha) * w
        valid = (z > -self._w2 * d1 - 1e-12) & (den > 0)
        return _over_denominator(self, b, den, valid), valid

    def _project_jacobian(self, b):
        # D = alpha d2 + (1-alpha) w, w = xi d1 + z: dd1/db = b/d1, dw/db = xi b/d1 + e_z,
        # dd2/db = ((x, y, 0) + w dw/db)/d2, dD/db = alpha dd2/db + (1-alpha) dw/db,
        # du/db = fx (e_x/D - x dD/db / D^2), dv/db = fy (e_y/D - y dD/db / D^2).
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        d1 = np.linalg.norm(b, axis=1)
        w = self.xi * d1 + z
        d2 = np.sqrt(x * x + y * y + w * w)
        D = self.alpha * d2 + (1 - self.alpha) * w
        dw = self.xi * b / d1[:, None]
        dw[:, 2] += 1.0
        dd2 = (np.stack([x, y, np.zeros_like(z)], axis=1) + w[:, None] * dw) / d2[:, None]
        dD = self.alpha * dd2 + (1 - self.alpha) * dw
        return _over_denominator_jacobian(self, b, D, dD)

    def _unproject(self, uv):
        # m = ((u-cx)/fx, (v-cy)/fy), r^2 = mx^2 + my^2,
        # mz = (1 - alpha^2 r^2) / (alpha sqrt(1 - (2 alpha - 1) r^2) + 1 - alpha),
        # b = (mz xi + sqrt(mz^2 + (1 - xi^2) r^2)) / (mz^2 + r^2) * (mx, my, mz) - (0, 0, xi).
        al, xi = self.alpha, self.xi
        mx = (uv[:, 0] - self.cx) / self.fx
        my = (uv[:, 1] - self.cy) / self.fy
        r2 = mx * mx + my * my
        arg1 = 1 - (2 * al - 1) * r2
        valid = arg1 >= 0  # r^2 <= 1/(2 alpha - 1) when alpha > 0.5
        s1 = np.sqrt(np.where(valid, arg1, 0.0))
        mz = (1 - al * al * r2) / (al * s1 + 1 - al)
        arg2 = mz * mz + (1 - xi * xi) * r2
        valid &= arg2 >= 0
        k = (mz * xi + np.sqrt(np.where(valid, arg2, 0.0))) / (mz * mz + r2)
        b = np.stack([k * mx, k * my, k * mz - xi], axis=1)
        n = np.linalg.norm(b, axis=1)
        valid &= np.isfinite(n) & (n > 0)
        b = np.where(valid[:, None], b / np.where(valid, n, 1.0)[:, None], 0.0)
        # The inverse is only the projection's inverse inside its domain z > -w2 |b|.
        valid &= b[:, 2] > -self._w2 - 1e-12
        b[~valid] = 0.0
        return b, valid


# ------------------------------------------------------------------------------------- eucm
@register_camera_model
@dataclass(frozen=True, kw_only=True)
class Eucm(CameraModel):
    """Enhanced unified camera model (Khomutenko et al. 2016), Kalibr ``eucm``.

    Projection: ``d = sqrt(beta (x^2 + y^2) + z^2)``,
    ``(u, v) = (fx, fy) * (x, y) / (alpha d + (1 - alpha) z) + (cx, cy)``, valid for ``z > -w d``
    with ``w = alpha/(1-alpha)`` (alpha <= 0.5) or ``(1-alpha)/alpha`` (alpha > 0.5). Off-axis
    limit: ``theta_max = pi/2 + atan(w sqrt(beta) / sqrt(1 - w^2))``. Fields: ``alpha`` in [0, 1],
    ``beta > 0``; ``max_angle_rad`` optionally caps theta_max.
    """

    name: ClassVar[str] = "eucm"
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    alpha: float
    beta: float
    max_angle_rad: float | None = None

    def __post_init__(self) -> None:
        self._check_common()
        al, be = _float(self, "alpha"), _float(self, "beta")
        if not 0.0 <= al <= 1.0:
            raise CalibrationError(f"eucm: expected alpha in [0, 1], got {al}")
        if not be > 0.0:
            raise CalibrationError(f"eucm: expected beta > 0, got {be}")
        object.__setattr__(self, "alpha", al)
        object.__setattr__(self, "beta", be)
        w = al / (1 - al) if al <= 0.5 else (1 - al) / al
        object.__setattr__(self, "_w", float(w))
        # z = -w d on the unit sphere: cos = -w sqrt(beta sin^2 + cos^2) -> tan^2 = (1 - w^2)/(w^2 beta)
        natural = np.pi if w >= 1.0 else np.pi / 2 + np.arctan(w * np.sqrt(be) / np.sqrt(1 - w * w))
        self._set_max_angle(float(natural))

    def _project(self, b):
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        d = np.sqrt(self.beta * (x * x + y * y) + z * z)
        den = self.alpha * d + (1 - self.alpha) * z
        valid = (z > -self._w * d - 1e-12) & (den > 0)
        return _over_denominator(self, b, den, valid), valid

    def _project_jacobian(self, b):
        # D = alpha d + (1-alpha) z, dd/db = (beta x, beta y, z)/d,
        # dD/db = alpha dd/db + (1-alpha) e_z; du/db = fx (e_x/D - x dD/db / D^2), same for v.
        x, y, z = b[:, 0], b[:, 1], b[:, 2]
        d = np.sqrt(self.beta * (x * x + y * y) + z * z)
        D = self.alpha * d + (1 - self.alpha) * z
        dD = self.alpha * np.stack([self.beta * x, self.beta * y, z], axis=1) / d[:, None]
        dD[:, 2] += 1 - self.alpha
        return _over_denominator_jacobian(self, b, D, dD)

    def _unproject(self, uv):
        # m = ((u-cx)/fx, (v-cy)/fy), r^2 = mx^2 + my^2,
        # mz = (1 - beta alpha^2 r^2) / (alpha sqrt(1 - (2 alpha - 1) beta r^2) + 1 - alpha),
        # b = (mx, my, mz) / |(mx, my, mz)|; valid for r^2 <= 1/(beta (2 alpha - 1)) when alpha > 0.5.
        al, be = self.alpha, self.beta
        mx = (uv[:, 0] - self.cx) / self.fx
        my = (uv[:, 1] - self.cy) / self.fy
        r2 = mx * mx + my * my
        arg = 1 - (2 * al - 1) * be * r2
        valid = arg >= 0
        mz = (1 - be * al * al * r2) / (al * np.sqrt(np.where(valid, arg, 0.0)) + 1 - al)
        b = np.stack([mx, my, mz], axis=1)
        n = np.linalg.norm(b, axis=1)
        valid &= np.isfinite(n) & (n > 0)
        b = np.where(valid[:, None], b / np.where(valid, n, 1.0)[:, None], 0.0)
        d = np.sqrt(be * (b[:, 0] ** 2 + b[:, 1] ** 2) + b[:, 2] ** 2)
        valid &= b[:, 2] > -self._w * d - 1e-12
        b[~valid] = 0.0
        return b, valid
