"""Exception types. Library code raises these; only the CLI turns them into messages and exit codes.

Every message names what was wrong and what was expected (kornia's ``check`` style), e.g.
``"calib.yaml: camera 'cam0' has distortion_model 'radtan'; expected one of: equidistant, ds, eucm"``.
"""

from __future__ import annotations


class FisheyeDesError(Exception):
    """Base of every error fisheye-des raises on purpose."""


class InputError(FisheyeDesError, ValueError):
    """Bad input data: wrong shape, NaN, non-monotonic time, a file that does not parse."""


class CalibrationError(InputError):
    """A calibration file that cannot be loaded, or a model/parameter mismatch."""


class ConfigError(InputError):
    """A configuration that does not validate (unknown key, wrong type, bad value)."""


class SourceError(InputError):
    """A video, image folder or camera that cannot be opened or read."""


def check_shape(name: str, arr, shape: tuple) -> None:
    """Raise InputError unless ``arr.shape`` matches ``shape`` (``None`` entries match any size).

    >>> import numpy as np; check_shape("uv", np.zeros((4, 2)), (None, 2))
    """
    actual = getattr(arr, "shape", None)
    if actual is None or len(actual) != len(shape) or any(
        s is not None and s != a for s, a in zip(shape, actual, strict=True)
    ):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"{name}: expected an array of shape {want}, got {actual}")


def check_rows(name: str, arr, ncols: int, dtype=float):
    """``arr`` as a finite ``(N, ncols)`` array of ``dtype``; an empty input becomes ``(0, ncols)``.

    Raises InputError naming ``name`` on another shape or a NaN/infinite value.
    """
    import numpy as np

    a = np.asarray(arr, dtype=dtype)
    if a.size == 0:
        return a.reshape(0, ncols)
    if a.ndim != 2 or a.shape[1] != ncols:
        raise InputError(f"{name}: expected shape (N, {ncols}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return a
