"""Camera calibration files -> :class:`~estimators.rig.Rig`, and a Kalibr camchain writer.

Formats read (CONVENTIONS.md "Inputs"); :func:`load_rig` detects which one a file is:

- Kalibr ``camchain.yaml`` (``cam0``, ``cam1``, ...): ``camera_model: pinhole`` with
  ``distortion_model: equidistant`` (Kannala-Brandt, 4 coefficients), ``camera_model: ds`` and
  ``camera_model: eucm`` (``distortion_model: none``); ``intrinsics``, ``distortion_coeffs``,
  ``resolution``, ``T_cam_imu`` (= ``T_C_B``), ``T_cn_cnm1`` for further cameras.
- OpenCV FileStorage YAML/JSON/XML (``cv2.fisheye`` result): ``K`` or ``camera_matrix``, ``D``
  (4 fisheye coefficients), the image size.
- ROS ``camera_info`` YAML with ``distortion_model: equidistant`` (the ``camera_calibration``
  file layout, or the message layout with ``K``/``D`` or ``k``/``d``).
- The thesis's linear model: ``model: thesis_linear``, ``deg_per_px``, image size.

Body frame when a file has no extrinsics: the first camera is assumed to look forward along body
+x at the body origin (``rig.forward_T_C_B()``); further cameras follow from ``T_cn_cnm1``.
Extra keys written by :func:`save_kalibr` and ignored by Kalibr: ``max_angle_rad`` (lens limit),
``fisheye_des_model: equidistant`` (the linear model, stored as pinhole-equi with zero
coefficients) and ``camera_name`` (when a camera's name is not its ``camN`` key).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from estimators.cameras import CameraModel, DoubleSphere, Equidistant, Eucm, KannalaBrandt
from estimators.errors import CalibrationError, FisheyeDesError, InputError
from estimators.rig import Camera, Rig, forward_T_C_B
from estimators.se3 import Pose

__all__ = [
    "FORMATS",
    "load_kalibr",
    "load_opencv",
    "load_rig",
    "load_ros_camera_info",
    "load_thesis_linear",
    "rig_from_dict",
    "save_kalibr",
]

FORMATS = ("kalibr", "opencv", "ros", "thesis_linear")
_KALIBR_ACCEPTED = "pinhole + equidistant (Kannala-Brandt, 4 coeffs), ds + none, eucm + none"
_OPENCV_K_KEYS = ("K", "camera_matrix", "cameraMatrix")
_OPENCV_D_KEYS = ("D", "dist_coeffs", "distortion_coefficients", "distortion_coeffs", "distCoeffs")


# ------------------------------------------------------------------------------------ helpers
def _err(src: str, cam: str | None, msg: str) -> CalibrationError:
    where = f"{src}: camera {cam!r}: " if cam else f"{src}: "
    return CalibrationError(where + msg)


def _floats(src: str, cam: str | None, key: str, value: Any, n: int | None = None) -> np.ndarray:
    """A flat list of finite floats (``n`` of them if given), else a CalibrationError."""
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise _err(src, cam, f"{key} must be a list of numbers, got {value!r}") from None
    if n is not None and arr.size != n:
        raise _err(src, cam, f"{key}: expected {n} values, found {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise _err(src, cam, f"{key} must be finite, got {arr.tolist()}")
    return arr


def _size(src: str, cam: str | None, w: Any, h: Any) -> tuple[int, int]:
    try:
        wf, hf = float(w), float(h)
    except (TypeError, ValueError):
        raise _err(src, cam, f"image size must be two positive integers, got {w!r} x {h!r}") from None
    if wf != int(wf) or hf != int(hf) or wf <= 0 or hf <= 0:
        raise _err(src, cam, f"image size must be two positive integers, got {w!r} x {h!r}")
    return int(wf), int(hf)


def _pose(src: str, cam: str, key: str, value: Any) -> Pose:
    T = _floats(src, cam, key, value, 16).reshape(4, 4)
    try:
        return Pose.from_matrix(T)
    except FisheyeDesError as e:
        raise _err(src, cam, f"{key}: {e}") from None


def _model(src: str, cam: str | None, build) -> CameraModel:
    """Run a model constructor, re-raising its parameter errors with the file and camera."""
    try:
        return build()
    except CalibrationError as e:
        raise _err(src, cam, str(e)) from None


def _kb_from_K_D(src: str, cam: str | None, K: np.ndarray, D: np.ndarray, w: int, h: int,
                 where: str) -> KannalaBrandt:
    K = np.asarray(K, dtype=float).reshape(-1)
    if K.size != 9:
        raise _err(src, cam, f"{where}: camera matrix: expected 3x3 (9 values), found {K.size}")
    K = K.reshape(3, 3)
    if abs(K[0, 1]) > 1e-9 * abs(K[0, 0]):
        raise _err(src, cam, f"{where}: camera matrix has skew K[0,1] = {K[0, 1]}; expected 0")
    D = np.asarray(D, dtype=float).reshape(-1)
    if D.size != 4:
        raise _err(
            src,
            cam,
            f"{where}: expected 4 fisheye distortion coefficients (k1..k4, Kannala-Brandt), found {D.size}"
            + (" (that looks like OpenCV's pinhole radtan model, which is not supported)" if D.size in
               (5, 8, 12, 14) else ""),
        )
    return _model(src, cam, lambda: KannalaBrandt(
        fx=K[0, 0], fy=K[1, 1], cx=K[0, 2], cy=K[1, 2], width=w, height=h,
        k1=D[0], k2=D[1], k3=D[2], k4=D[3],
    ))


# ------------------------------------------------------------------------------------- Kalibr
def _kalibr_model(src: str, cam: str, d: dict) -> CameraModel:
    cm = str(d.get("camera_model", "")).strip().lower()
    dm = str(d.get("distortion_model", "none")).strip().lower()
    if "intrinsics" not in d:
        raise _err(src, cam, "missing 'intrinsics'")
    if "resolution" not in d:
        raise _err(src, cam, "missing 'resolution' ([width, height] in px)")
    res = _floats(src, cam, "resolution", d["resolution"], 2)
    w, h = _size(src, cam, res[0], res[1])
    coeffs = d.get("distortion_coeffs") or []
    max_angle = d.get("max_angle_rad")
    max_angle = None if max_angle is None else float(_floats(src, cam, "max_angle_rad", max_angle, 1)[0])
    if cm == "pinhole" and dm in ("equidistant", "equi"):
        fu, fv, pu, pv = _floats(src, cam, "intrinsics", d["intrinsics"], 4)
        k = np.asarray(coeffs, dtype=float).reshape(-1) if coeffs else np.zeros(0)
        if k.size != 4:
            raise _err(
                src, cam,
                f"distortion_model 'equidistant' expects 4 distortion_coeffs (k1..k4), found {k.size}",
            )
        k = _floats(src, cam, "distortion_coeffs", k, 4)
        if str(d.get("fisheye_des_model", "")).lower() == "equidistant":
            if np.any(k != 0):
                raise _err(src, cam, f"fisheye_des_model 'equidistant' needs zero distortion_coeffs, "
                                     f"found {k.tolist()}")
            return _model(src, cam, lambda: Equidistant(
                fx=fu, fy=fv, cx=pu, cy=pv, width=w, height=h, max_angle_rad=max_angle))
        return _model(src, cam, lambda: KannalaBrandt(
            fx=fu, fy=fv, cx=pu, cy=pv, width=w, height=h, k1=k[0], k2=k[1], k3=k[2], k4=k[3],
            max_angle_rad=max_angle))
    if cm in ("ds", "eucm") and dm == "none":
        if len(coeffs):
            raise _err(src, cam, f"camera_model '{cm}' with distortion_model 'none' expects no "
                                 f"distortion_coeffs, found {len(coeffs)}")
        a, b, fu, fv, pu, pv = _floats(src, cam, "intrinsics", d["intrinsics"], 6)
        if cm == "ds":
            return _model(src, cam, lambda: DoubleSphere(
                fx=fu, fy=fv, cx=pu, cy=pv, width=w, height=h, xi=a, alpha=b, max_angle_rad=max_angle))
        return _model(src, cam, lambda: Eucm(
            fx=fu, fy=fv, cx=pu, cy=pv, width=w, height=h, alpha=a, beta=b, max_angle_rad=max_angle))
    raise _err(src, cam, f"camera_model '{cm}' with distortion_model '{dm}' is not supported; "
                         f"accepted: {_KALIBR_ACCEPTED}")


def _load_kalibr_dict(data: dict, src: str) -> Rig:
    keys = [k for k in data if isinstance(k, str) and re.fullmatch(r"cam\d+", k)]
    if not keys:
        raise _err(src, None, "no 'cam0', 'cam1', ... entries found (Kalibr camchain)")
    keys.sort(key=lambda k: int(k[3:]))
    expected = [f"cam{i}" for i in range(len(keys))]
    if keys != expected:
        raise _err(src, None, f"camera keys must be cam0, cam1, ... without gaps; found {', '.join(keys)}")
    cams: list[Camera] = []
    prev: Pose | None = None
    for key in keys:
        d = data[key]
        if not isinstance(d, dict):
            raise _err(src, key, f"expected a mapping of calibration keys, got {type(d).__name__}")
        model = _kalibr_model(src, key, d)
        if "T_cam_imu" in d:
            T_C_B = _pose(src, key, "T_cam_imu", d["T_cam_imu"])
        elif prev is None:
            T_C_B = forward_T_C_B()  # no body frame given: cam0 looks forward from the body origin
        elif "T_cn_cnm1" in d:
            T_C_B = _pose(src, key, "T_cn_cnm1", d["T_cn_cnm1"]) @ prev
        else:
            raise _err(src, key, "needs T_cam_imu or T_cn_cnm1 (its pose relative to the previous camera)")
        name = str(d.get("camera_name", key))
        cams.append(Camera(name, model, T_C_B))
        prev = T_C_B
    try:
        return Rig(tuple(cams))
    except FisheyeDesError as e:
        raise _err(src, None, str(e)) from None


def load_kalibr(path: str | Path) -> Rig:
    """Read a Kalibr ``camchain.yaml`` (or ``camchain-imucam.yaml``) into a Rig (cameras in cam0.. order)."""
    return _load_kalibr_dict(_read_yaml(Path(path)), str(path))


def save_kalibr(rig: Rig, path: str | Path) -> Path:
    """Write ``rig`` as a Kalibr camchain that :func:`load_rig` reads back to an equal Rig.

    Kannala-Brandt -> ``pinhole`` + ``equidistant``; the linear model -> the same with zero
    coefficients and ``fisheye_des_model: equidistant``; double sphere -> ``ds``; EUCM -> ``eucm``.
    Every camera gets ``T_cam_imu`` (= T_C_B) and, from cam1 on, ``T_cn_cnm1``.
    """
    out: dict[str, dict] = {}
    prev: Pose | None = None
    for i, cam in enumerate(rig.cameras):
        m = cam.model
        e: dict[str, Any] = {}
        if isinstance(m, KannalaBrandt | Equidistant):
            e["camera_model"] = "pinhole"
            e["intrinsics"] = [float(m.fx), float(m.fy), float(m.cx), float(m.cy)]
            e["distortion_model"] = "equidistant"
            if isinstance(m, KannalaBrandt):
                e["distortion_coeffs"] = [float(m.k1), float(m.k2), float(m.k3), float(m.k4)]
            else:
                e["distortion_coeffs"] = [0.0, 0.0, 0.0, 0.0]
                e["fisheye_des_model"] = "equidistant"
        elif isinstance(m, DoubleSphere):
            e["camera_model"] = "ds"
            e["intrinsics"] = [float(v) for v in (m.xi, m.alpha, m.fx, m.fy, m.cx, m.cy)]
            e["distortion_model"] = "none"
            e["distortion_coeffs"] = []
        elif isinstance(m, Eucm):
            e["camera_model"] = "eucm"
            e["intrinsics"] = [float(v) for v in (m.alpha, m.beta, m.fx, m.fy, m.cx, m.cy)]
            e["distortion_model"] = "none"
            e["distortion_coeffs"] = []
        else:
            raise CalibrationError(
                f"save_kalibr: camera {cam.name!r} has model {m.name!r}, which Kalibr cannot store; "
                "expected one of: kannala_brandt, equidistant, double_sphere, eucm"
            )
        e["resolution"] = [int(m.width), int(m.height)]
        e["max_angle_rad"] = float(m.max_angle_rad)
        e["T_cam_imu"] = [[float(v) for v in row] for row in cam.T_C_B.matrix()]
        if prev is not None:
            e["T_cn_cnm1"] = [[float(v) for v in row] for row in (cam.T_C_B @ prev.inverse()).matrix()]
        if cam.name != f"cam{i}":
            e["camera_name"] = cam.name
        e["rostopic"] = f"/{cam.name}/image_raw"
        out[f"cam{i}"] = e
        prev = cam.T_C_B
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        with p.open("w") as f:
            yaml.safe_dump(out, f, default_flow_style=None, sort_keys=False)
    except OSError as e:
        raise InputError(
            f"{p}: cannot write the calibration ({e.strerror}); expected a writable file path"
        ) from None
    return p


# ------------------------------------------------------------------------------------- OpenCV
def _read_filestorage(path: Path) -> dict:
    """All top-level nodes of an OpenCV FileStorage file as numbers, strings, lists or arrays."""
    import cv2

    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as e:
        raise _err(str(path), None, f"not a readable OpenCV FileStorage file ({str(e).strip()})") from None
    if not fs.isOpened():
        raise _err(str(path), None, "not a readable OpenCV FileStorage file")
    out: dict[str, Any] = {}
    try:
        for key in fs.root().keys():
            n = fs.getNode(key)
            if n.isMap():
                m = n.mat()
                if m is not None:
                    out[key] = np.asarray(m, dtype=float)
            elif n.isSeq():
                out[key] = [n.at(i).real() for i in range(n.size())]
            elif n.isInt() or n.isReal():
                out[key] = n.real()
            elif n.isString():
                out[key] = n.string()
    finally:
        fs.release()
    return out


def _image_size_from(d: dict, src: str, cam: str | None) -> tuple[int, int]:
    for wk, hk in (("image_width", "image_height"), ("width", "height"), ("imageWidth", "imageHeight")):
        if wk in d and hk in d:
            return _size(src, cam, d[wk], d[hk])
    for k in ("image_size", "imageSize", "img_size", "resolution", "size"):
        if k in d:
            v = _floats(src, cam, k, d[k], 2)
            return _size(src, cam, v[0], v[1])
    raise _err(src, cam, "no image size found; expected image_width + image_height, width + height, "
                         "or image_size / resolution [width, height]")


def _opencv_from_dict(d: dict, src: str) -> Rig:
    K = next((d[k] for k in _OPENCV_K_KEYS if k in d), None)
    D = next((d[k] for k in _OPENCV_D_KEYS if k in d), None)
    if K is None or D is None:
        raise _err(src, None, f"expected a camera matrix ({' or '.join(_OPENCV_K_KEYS)}) and fisheye "
                              f"distortion ({' or '.join(_OPENCV_D_KEYS)})")
    K = _floats(src, None, "camera matrix", K)
    D = _floats(src, None, "D", D)
    w, h = _image_size_from(d, src, None)
    model = _kb_from_K_D(src, None, K, D, w, h, "OpenCV fisheye")
    name = str(d.get("camera_name", "cam0"))
    return Rig((Camera(name, model, forward_T_C_B()),))


def load_opencv(path: str | Path) -> Rig:
    """Read a ``cv2.fisheye`` calibration saved with ``cv2.FileStorage`` (YAML, JSON or XML).

    Keys: ``K`` or ``camera_matrix`` (3x3), ``D`` (4 coefficients), the image size
    (``image_width``/``image_height``, ``width``/``height`` or ``image_size`` [w, h]). One camera,
    ``cam0``, looking forward from the body origin.
    """
    p = Path(path)
    _check_file(p)
    return _opencv_from_dict(_read_filestorage(p), str(p))


# ---------------------------------------------------------------------------------------- ROS
def _ros_from_dict(d: dict, src: str) -> Rig:
    cam = str(d.get("camera_name") or "cam0")
    dm = str(d.get("distortion_model", "")).strip().lower()
    if dm != "equidistant":
        raise _err(src, cam, f"distortion_model '{dm}' is not supported; accepted: equidistant "
                             "(Kannala-Brandt, 4 coefficients)")

    def data(v):
        return v.get("data") if isinstance(v, dict) else v

    K = next((data(d[k]) for k in ("camera_matrix", "K", "k") if k in d), None)
    D = next((data(d[k]) for k in ("distortion_coefficients", "D", "d") if k in d), None)
    if K is None or D is None:
        raise _err(src, cam, "expected camera_matrix (or K/k) and distortion_coefficients (or D/d)")
    K = _floats(src, cam, "camera_matrix", K)
    D = _floats(src, cam, "distortion_coefficients", D)
    w, h = _image_size_from(d, src, cam)
    model = _kb_from_K_D(src, cam, K, D, w, h, "distortion_model 'equidistant'")
    return Rig((Camera(cam, model, forward_T_C_B()),))


def load_ros_camera_info(path: str | Path) -> Rig:
    """Read a ROS ``camera_info`` YAML (``distortion_model: equidistant``) into a one-camera Rig.

    Accepts the ``camera_calibration`` file layout (``image_width``, ``camera_matrix: {data}``,
    ``distortion_coefficients: {data}``) and the message layout (``width``, ``K``/``k``, ``D``/``d``).
    The camera is named by ``camera_name`` (default ``cam0``) and looks forward from the body origin.
    """
    p = Path(path)
    return _ros_from_dict(_read_yaml(p), str(p))


# ------------------------------------------------------------------------------ thesis linear
def _thesis_from_dict(d: dict, src: str) -> Rig:
    cam = str(d.get("camera_name", "cam0"))
    if "deg_per_px" not in d:
        raise _err(src, cam, "model 'thesis_linear' needs deg_per_px (degrees per pixel about the centre)")
    w, h = _image_size_from(d, src, cam)
    deg = _floats(src, cam, "deg_per_px", d["deg_per_px"], 1)[0]
    # Default lens limit: the thesis measured a 180-degree horizontal field of view (sec. 4.1.3).
    max_deg = d.get("max_angle_deg", 90.0)
    max_rad = float(np.radians(_floats(src, cam, "max_angle_deg", max_deg, 1)[0]))
    model = _model(src, cam, lambda: Equidistant.from_deg_per_px(
        deg, w, h, cx=d.get("cx"), cy=d.get("cy"), max_angle_rad=max_rad))
    return Rig((Camera(cam, model, forward_T_C_B()),))


def load_thesis_linear(path: str | Path) -> Rig:
    """Read the thesis's linear model: ``model: thesis_linear``, ``deg_per_px``, image size.

    Optional: ``cx``, ``cy`` (default: the image centre), ``max_angle_deg`` (lens half-FOV;
    default 90, the thesis's measured 180-degree field of view), ``camera_name``. One
    forward-looking camera.
    """
    p = Path(path)
    return _thesis_from_dict(_read_yaml(p), str(p))


# ---------------------------------------------------------------------------------- detection
def _check_file(p: Path) -> None:
    if not p.is_file():
        raise CalibrationError(f"{p}: calibration file not found")


def _read_yaml(p: Path) -> dict:
    _check_file(p)
    text = p.read_text(errors="replace")
    try:
        data = json.loads(text) if p.suffix.lower() == ".json" else yaml.safe_load(text)
    except json.JSONDecodeError as e:
        raise CalibrationError(
            f"{p}: does not parse as JSON: line {e.lineno}, column {e.colno}: {e.msg}"
        ) from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise CalibrationError(f"{p}: does not parse as YAML: {where}{problem}") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{p}: expected a mapping of calibration keys, got {type(data).__name__}")
    return data


def _is_opencv_filestorage(p: Path) -> bool:
    head = p.read_bytes()[:4096].decode("utf-8", errors="replace")
    return head.lstrip().startswith("%YAML") or "opencv-matrix" in head or p.suffix.lower() == ".xml"


def rig_from_dict(data: dict, src: str = "<dict>") -> Rig:
    """Detect the format of an already-parsed calibration mapping and build the Rig."""
    if any(isinstance(v, dict) and "camera_model" in v for v in data.values()):
        return _load_kalibr_dict(data, src)
    if str(data.get("model", "")).lower() == "thesis_linear":
        return _thesis_from_dict(data, src)
    has_k = any(k in data for k in _OPENCV_K_KEYS + ("k",))
    if "distortion_model" in data and has_k:
        return _ros_from_dict(data, src)
    if has_k and any(k in data for k in _OPENCV_D_KEYS):
        return _opencv_from_dict(data, src)
    raise CalibrationError(
        f"{src}: unrecognised calibration format (top-level keys: {', '.join(map(str, list(data)[:8]))}); "
        "expected a Kalibr camchain (cam0: camera_model, intrinsics, ...), an OpenCV FileStorage file "
        "(K, D, image size), a ROS camera_info YAML (distortion_model: equidistant, camera_matrix, ...) "
        "or the thesis's linear model (model: thesis_linear, deg_per_px, width, height)"
    )


def load_rig(path: str | Path) -> Rig:
    """Load any supported calibration file into a :class:`Rig`, detecting its format.

    See the module docstring for the formats. Errors (missing file, unknown format, unsupported or
    mismatched model) are CalibrationError naming the file, the camera, what was found and what
    is accepted.
    """
    p = Path(path)
    _check_file(p)
    if _is_opencv_filestorage(p):
        return load_opencv(p)
    return rig_from_dict(_read_yaml(p), str(p))
