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


def did_you_mean(key: str, valid: list[str]) -> str:
    """The tail of an unknown-key message, the one wording of every layer (config keys, the front end's
    option groups): the closest valid key if any, then all of them ("...in tracker; did you mean
    'boxes'? Valid keys: features, ..." or "...in tracker; valid keys: ..."), or "; no key is valid
    there" when there are none.

    >>> did_you_mean("boxs", ["boxes"])
    "; did you mean 'boxes'? Valid keys: boxes"
    """
    import difflib

    if not valid:
        return "; no key is valid there"
    close = difflib.get_close_matches(key, valid, n=1, cutoff=0.5)
    if close:
        return f"; did you mean '{close[0]}'? Valid keys: {', '.join(valid)}"
    return f"; valid keys: {', '.join(valid)}"


def frame_at(frame, t_s) -> str:
    """How a message names the frame it refuses, in every stage (front end, fusion):
    ``"frame 6 (t_s=0.200000 s)"``; a ``t_s`` that is not a number is shown as given.

    >>> frame_at(6, 0.2), frame_at(6, "x")
    ('frame 6 (t_s=0.200000 s)', "frame 6 (t_s='x')")
    """
    import numbers

    if isinstance(t_s, numbers.Real) and not isinstance(t_s, bool):
        return f"frame {frame} (t_s={float(t_s):.6f} s)"
    return f"frame {frame} (t_s={t_s!r})"


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


def as_numbers(name: str, value, dtype, expected: str):
    """``value`` as a numpy array of ``dtype``; InputError naming ``name`` and ``expected`` when
    its entries are not numbers (numpy's own ValueError or TypeError says neither), lie outside
    ``dtype``'s range (numpy's or Python's OverflowError), or, for an integer ``dtype``, are not
    whole numbers (numpy would cut 1.5 to 1 and NaN to -2**63 without a word).

    >>> as_numbers("uv", ["x", 1], float, "a pixel (2,)")
    Traceback (most recent call last):
    ...
    estimators.errors.InputError: uv: expected a pixel (2,), got ['x', 1] (not numbers)
    >>> as_numbers("ids", [3, 1.5], int, "integer ids (N,)")
    Traceback (most recent call last):
    ...
    estimators.errors.InputError: ids: expected integer ids (N,), got [3, 1.5] (not whole numbers)
    """
    import numpy as np

    try:
        with np.errstate(invalid="ignore"):  # (a float NaN cast to an integer: refused below)
            a = np.asarray(value, dtype=dtype)
        if a.dtype.kind in "iu" and np.asarray(value).dtype.kind not in "iu":
            # (float, bool, str or object entries: whole numbers only, compared as floats)
            if not np.array_equal(a, np.asarray(value, dtype=float)):
                raise InputError(f"{name}: expected {expected}, got {value!r} (not whole numbers)")
    except (TypeError, ValueError) as e:
        if isinstance(e, InputError):
            raise
        raise InputError(f"{name}: expected {expected}, got {value!r} (not numbers)") from None
    except OverflowError:
        raise InputError(f"{name}: expected {expected}, got {value!r} (out of range)") from None
    return a


def check_rows(name: str, arr, ncols: int, dtype=float):
    """``arr`` as a finite ``(N, ncols)`` array of ``dtype``; an empty input becomes ``(0, ncols)``.

    Raises InputError naming ``name`` on another shape, a NaN/infinite value or entries that are not
    numbers.
    """
    import numpy as np

    a = as_numbers(name, arr, dtype, f"numbers of shape (N, {ncols})")
    if a.size == 0:
        return a.reshape(0, ncols)
    if a.ndim != 2 or a.shape[1] != ncols:
        raise InputError(f"{name}: expected shape (N, {ncols}), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return a
