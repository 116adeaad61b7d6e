"""Typed records passed between the stages: front end -> fusion -> sinks.

They live in ``estimators`` (the bottom layer) because ``trackers`` produces them and ``estimators``
consumes them, and ``estimators`` may import nothing from ``trackers``.

Frames: ``b_C`` is a unit bearing in the optical frame of the named camera; ``b_B`` in the body frame
B (FLU); ``p_W`` / ``v_W`` in the world frame W. Units SI.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from estimators.errors import InputError, as_numbers, check_rows

TrackStatus = Literal["tentative", "confirmed", "lost"]
TRACK_STATUSES: tuple[str, ...] = ("tentative", "confirmed", "lost")

# numpy's dtype singletons for native float64 / int64: ``a.dtype is _F64`` is a pointer compare (a
# non-native byte order is another dtype object and takes the converting path, which is also right)
_F64 = np.dtype(np.float64)
_I64 = np.dtype(np.int64)


@dataclass(frozen=True)
class CameraView:
    """An obstacle as one camera sees it in one frame.

    Attributes:
        camera: camera name in the rig (e.g. ``"cam0"``).
        b_C: (3,) unit bearing of the obstacle's representative point, camera optical frame.
        uv: (2,) pixel position of the representative point (OpenCV convention), for drawing, or
            None when it has none: ``b_C`` does not project into the image (a representative carried
            beyond the lens's field as the obstacle leaves it). Never a made-up pixel, never NaN.
        sigma_rad: 1-sigma angular uncertainty of ``b_C`` (radians, isotropic about the ray).
        feature_ids: (M,) int64 ids of the member features (stable over their lives).
        feature_b_C: (M, 3) unit bearings of the member features in this camera's frame.
    """

    camera: str
    b_C: np.ndarray
    uv: np.ndarray | None
    sigma_rad: float
    feature_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    feature_b_C: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __init__(
        self,
        camera: str,
        b_C: np.ndarray,
        uv: np.ndarray | None,
        sigma_rad: float,
        feature_ids: np.ndarray | None = None,
        feature_b_C: np.ndarray | None = None,
    ) -> None:
        # The front end builds ~60-100 of these a frame, so the dataclass's generated __init__ (each
        # field through the frozen object.__setattr__, then __post_init__ setting four of them again)
        # is replaced by this one: checks in plain floats, arrays converted only when they are not
        # already float64/int64 of the right shape, the fields written once into __dict__ (7.2 -> ~4 us).
        b = b_C
        if type(b) is not np.ndarray or b.dtype is not _F64 or b.shape != (3,):
            b = as_numbers("CameraView.b_C", b, float, "a finite unit 3-vector").reshape(-1)
        if b.shape != (3,):
            raise InputError(f"CameraView.b_C: expected a finite unit 3-vector, got {b_C!r}")
        x, y, z = b.tolist()
        n2 = x * x + y * y + z * z  # NaN or inf in any component -> n2 not finite
        if not (math.isfinite(n2) and abs(math.sqrt(n2) - 1.0) <= 1e-6):
            raise InputError(f"CameraView.b_C: expected a finite unit 3-vector, got {b_C!r}")
        try:
            sig = float(sigma_rad)
        except (TypeError, ValueError, OverflowError):
            sig = math.nan
        if not (math.isfinite(sig) and sig > 0):
            raise InputError(f"CameraView.sigma_rad: expected a positive angle, got {sigma_rad!r}")
        ids = feature_ids
        if ids is None:
            ids = np.zeros(0, dtype=np.int64)
        elif type(ids) is not np.ndarray or ids.dtype is not _I64 or ids.ndim != 1:
            ids = as_numbers("CameraView.feature_ids", ids, np.int64, "integer ids (N,)").reshape(-1)
        fb = feature_b_C
        if fb is None:
            fb = np.zeros((0, 3))
        elif type(fb) is np.ndarray and fb.dtype is _F64 and fb.ndim == 2 and fb.shape[1] == 3:
            # one BLAS call: the sum of squares is finite exactly when every value is (squares are >= 0,
            # so inf cannot cancel; NaN propagates), unless huge finite values overflow it: then the
            # element-wise check decides (numpy warns of the overflow: |x| > 1e154, never a bearing).
            # 1.3 us against 4 us for isfinite().all() on ~12 features.
            if fb.size:
                r = fb.ravel()
                if not math.isfinite(r.dot(r)) and not np.isfinite(fb).all():
                    raise InputError("CameraView.feature_b_C: contains NaN or infinite values")
        else:
            fb = check_rows("CameraView.feature_b_C", fb, 3)
        if len(ids) != len(fb):
            raise InputError(
                f"CameraView: feature_ids ({len(ids)}) and feature_b_C ({len(fb)}) differ in length"
            )
        if uv is not None:
            if type(uv) is not np.ndarray or uv.dtype is not _F64 or uv.shape != (2,):
                uv = as_numbers("CameraView.uv", uv, float, "a finite pixel (2,) or None").reshape(-1)
                if uv.shape != (2,):
                    raise InputError(f"CameraView.uv: expected a finite pixel (2,) or None, got {uv!r}")
            u, v = uv.tolist()
            if not (math.isfinite(u) and math.isfinite(v)):
                raise InputError(f"CameraView.uv: expected a finite pixel (2,) or None, got {uv!r}")
        d = self.__dict__  # frozen: no attribute assignment, but the instance dict is writable once here
        d["camera"] = camera
        d["b_C"] = b
        d["uv"] = uv
        d["sigma_rad"] = sig  # (a float: not the input, which may be a string float() reads)
        d["feature_ids"] = ids
        d["feature_b_C"] = fb


@dataclass(frozen=True)
class ObstacleObservation:
    """One obstacle track in one frame, as the front end (trackers) reports it.

    Attributes:
        track_id: stable id over the track's life.
        frame: frame index; t_s: frame time in seconds (the filter takes dt from t_s).
        status: ``tentative`` | ``confirmed`` | ``lost`` (a lost track is reported once, then dropped).
        views: one CameraView per camera that sees the obstacle in this frame (empty when lost).
        label: what found it (``"orb"``, ``"navlights"``, a plug-in's name).
        attributes: detector-specific extras, JSON-serialisable (e.g. navlights' ``heading``); a
            ``lost`` observation of an id the front end merged into another has ``merged_into``
            (that id: the fusion may continue the lost id's filter there).
    """

    track_id: int
    frame: int
    t_s: float
    status: TrackStatus
    views: tuple[CameraView, ...]
    label: str = "orb"
    attributes: dict[str, Any] = field(default_factory=dict)

    def __init__(
        self,
        track_id: int,
        frame: int,
        t_s: float,
        status: TrackStatus,
        views: tuple[CameraView, ...],
        label: str = "orb",
        attributes: dict[str, Any] | None = None,
    ) -> None:
        # written by hand, fields set once into __dict__, like CameraView's (4.7 -> ~1.5 us)
        if status not in TRACK_STATUSES:
            raise InputError(f"ObstacleObservation.status: expected one of {TRACK_STATUSES}, got {status!r}")
        try:
            finite = math.isfinite(t_s)  # a float (or numpy float); 0.05 us against np.isfinite's 1.5
        except (TypeError, OverflowError):
            finite = False
        if not finite:
            raise InputError(f"ObstacleObservation.t_s: expected a finite time, got {t_s!r}")
        # (the track id: a dict key in the fusion, int() in the output)
        if type(track_id) is not int and not isinstance(track_id, np.integer):  # (bool: not int's type)
            raise InputError(f"ObstacleObservation.track_id: expected an integer id, got {track_id!r}")
        if type(views) is not tuple and type(views) is not list:
            raise InputError(f"ObstacleObservation.views: expected a tuple of CameraView, got {views!r}")
        for v in views:
            if type(v) is not CameraView:
                raise InputError(f"ObstacleObservation.views: expected a tuple of CameraView, got {views!r}")
        if len(views) > 1:
            names = [v.camera for v in views]
            if len(set(names)) != len(names):
                raise InputError(f"ObstacleObservation.views: one view per camera expected, got {names}")
        d = self.__dict__
        d["track_id"] = track_id
        d["frame"] = frame
        d["t_s"] = t_s
        d["status"] = status
        d["views"] = views
        d["label"] = label
        d["attributes"] = {} if attributes is None else attributes

    @property
    def cameras(self) -> tuple[str, ...]:
        return tuple(v.camera for v in self.views)


def _opt_list(a: np.ndarray | None) -> list[float] | None:
    if a is None:
        return None
    if type(a) is np.ndarray and a.dtype == np.float64:
        return (a if a.ndim == 1 else a.reshape(-1)).tolist()  # plain floats, one C call
    return [float(v) for v in np.asarray(a).reshape(-1)]


@dataclass(frozen=True)
class TrackReport:
    """The estimate for one obstacle track in one frame: one entry of ``tracks.jsonl``'s ``tracks``.

    Field names and meanings follow CONVENTIONS.md "Outputs". Ranges and positions are measured from
    the body origin at this frame's time; ``None`` means unobservable / not available, and
    ``unobservable_reason`` then says why. ``nis`` / ``innovation`` are the last fused update's, for
    diagnostics; ``gated`` counts measurements rejected by the chi-square gate so far.
    ``speed_sigma_mps`` is the 1-sigma of ``speed_mps`` (first order along the reported velocity,
    sqrt(u^T P_vv u) with u = v / |v|, m/s), null when no velocity is reported.
    ``miss_distance_m`` is the distance at the closest approach ``ttc_s`` is the time of,
    |r + t* w|, and ``miss_distance_sigma_m`` its 1-sigma (``estimators.fusion._miss_distances``);
    both null exactly when ``ttc_s`` is.
    """

    id: int
    status: TrackStatus
    camera: str | list[str]
    bearing_body: np.ndarray
    range_m: float | None = None
    range_sigma_m: float | None = None
    range_min_m: float | None = None
    range_max_m: float | None = None
    position_body_m: np.ndarray | None = None
    velocity_world_mps: np.ndarray | None = None
    speed_mps: float | None = None
    speed_sigma_mps: float | None = None
    ttc_s: float | None = None
    miss_distance_m: float | None = None
    miss_distance_sigma_m: float | None = None
    source: str = ""
    label: str = "orb"
    nis: float | None = None
    innovation: np.ndarray | None = None
    gated: int = 0
    unobservable_reason: str | None = None
    attributes: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The JSON object of CONVENTIONS.md, all values plain Python (finite floats or null)."""
        return reports_to_json([self])[0]


def _null_nonfinite(d: dict[str, Any]) -> dict[str, Any]:
    """Replace non-finite floats (and lists holding one) by None in place: JSON has no NaN/inf."""
    for k, v in d.items():
        if isinstance(v, float) and not math.isfinite(v):
            d[k] = None
        elif isinstance(v, list) and any(isinstance(x, float) and not math.isfinite(x) for x in v):
            d[k] = None
    return d


def reports_to_json(reports: Sequence[TrackReport], null_nonfinite: bool = True) -> list[dict[str, Any]]:
    """The JSON objects of CONVENTIONS.md for several reports at once (one frame's ``tracks``).

    The (N, 3) body bearings go through numpy together: azimuth = atan2(y, x) (FLU: 0 straight
    ahead, +90 to the left, +-180 behind), elevation = asin(z / |b|) (+90 straight up), in degrees.
    Values are plain Python.

    Args:
        reports: N ``TrackReport``s.
        null_nonfinite: replace NaN/inf values by None (True). A writer whose JSON encoder refuses
            non-finite numbers may pass False and call again with True only when the encoder refuses.
    """
    n = len(reports)
    if n == 0:
        return []
    B = np.array([r.bearing_body for r in reports], dtype=float).reshape(n, 3)
    x, y, z = B[:, 0], B[:, 1], B[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        az = np.degrees(np.arctan2(y, x))  # azimuth = atan2(y, x): 0 = nose, +90 = left
        el = np.degrees(np.arcsin(np.clip(z / np.sqrt(x * x + y * y + z * z), -1.0, 1.0)))  # asin(z/|b|)
    out = []
    F, opt_list = float, _opt_list
    for r, b, a, e in zip(reports, B.tolist(), az.tolist(), el.tolist(), strict=True):
        # optional floats inline: None or a Python float as they are, anything else (numpy scalars,
        # ints) through float(); no function call per field (~50 reports x 9 fields a frame)
        d: dict[str, Any] = {
            "id": int(r.id),
            "status": r.status,
            "camera": r.camera,
            "bearing_body": b,
            "azimuth_deg": a,
            "elevation_deg": e,
            "range_m": v if (v := r.range_m) is None or type(v) is F else F(v),
            "range_sigma_m": v if (v := r.range_sigma_m) is None or type(v) is F else F(v),
            "range_min_m": v if (v := r.range_min_m) is None or type(v) is F else F(v),
            "range_max_m": v if (v := r.range_max_m) is None or type(v) is F else F(v),
            "position_body_m": opt_list(r.position_body_m),
            "velocity_world_mps": opt_list(r.velocity_world_mps),
            "speed_mps": v if (v := r.speed_mps) is None or type(v) is F else F(v),
            "speed_sigma_mps": v if (v := r.speed_sigma_mps) is None or type(v) is F else F(v),
            "ttc_s": v if (v := r.ttc_s) is None or type(v) is F else F(v),
            "miss_distance_m": v if (v := r.miss_distance_m) is None or type(v) is F else F(v),
            "miss_distance_sigma_m": v if (v := r.miss_distance_sigma_m) is None or type(v) is F else F(v),
            "source": r.source,
            "label": r.label,
            "nis": v if (v := r.nis) is None or type(v) is F else F(v),
            "innovation": opt_list(r.innovation),
            "gated": int(r.gated),
            "unobservable_reason": r.unobservable_reason,
        }
        if r.attributes:
            d["attributes"] = r.attributes
        out.append(_null_nonfinite(d) if null_nonfinite else d)
    return out
