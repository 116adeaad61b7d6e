"""Two-ray geometry: triangulation, moving-obstacle range bounds, velocity from two fixes.

These are the thesis's planar law-of-sines formulas (eq. 3.1-3.13, see ``estimators/thesis.py``)
generalised to 3-D rays: a ray is a centre ``c`` (3,) in metres and a unit direction ``b`` (3,), both
in one common frame (world W, or body B when both poses are expressed in the current body frame).
Mono parallax is one camera at two poses (ray a = earlier pose, ray b = the current pose); stereo is
two cameras at one instant. Bearings may point anywhere (also beyond 90 degrees off an optical axis):
only their direction matters here.

Every estimator returns a frozen result record or ``Unobservable(reason)``: degenerate geometry
(parallel rays, zero baseline, a point behind a camera, planar angles summing to >= 180 degrees,
motion inconsistent with the speed limit) is an answer, never NaN and never an exception. Malformed
input (wrong shape, NaN/inf, a zero direction, negative speed limit) raises ``InputError``.

Planar helpers (``planar_rays``, ``planar_triangulate``) build the thesis's configuration: baseline
A -> B of length d along +x, the obstacle C at y > 0, ``theta1`` the interior angle at A (between
A->B and A->C), ``theta2`` the interior angle at B (between B->A and B->C). Then
``triangulate(...).range_m`` (from B) is eq. 3.8 ``Y = d sin th1 / cos(th1 + th2 - 90 deg)``,
``p[1]`` is eq. 3.1's perpendicular ``Z`` and the range from the baseline's midpoint is eq. 3.2's CF,
for any interior angles in (0, 180 deg) with th1 + th2 < 180 deg (so also eq. 3.9, 3.10 with an
angle over 90 degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# np.einsum's own C function, called without its Python-level wrapper (the array-function dispatch
# and the keyword handling of its optimize path, which is off by default: ~0.7 us a call; the 720p
# stereo frame makes ~340 calls in the grouping and the fusion): the same function on the same
# operands, so the same numbers. It is numpy's private name: a numpy without it gets np.einsum itself.
try:
    from numpy._core.multiarray import c_einsum as _einsum
except ImportError:  # pragma: no cover (numpy 2.0-2.4 have it)
    _einsum = np.einsum

from estimators.errors import InputError

__all__ = [
    "Unobservable",
    "Triangulation",
    "RangeBounds",
    "Velocity",
    "triangulate",
    "TriangulationBatch",
    "triangulate_batch",
    "moving_obstacle_bounds",
    "moving_obstacle_bounds_unchecked",
    "moving_obstacle_bounds_batch",
    "velocity_from_fixes",
    "planar_rays",
    "planar_triangulate",
    "planar_moving_obstacle_bounds",
]

# Below this squared sine of the angle between two rays they are treated as exactly parallel
# in the closed forms (the user-facing threshold is ``min_parallax_rad``).
_PARALLEL_SIN2 = 1e-24


@dataclass(frozen=True)
class Unobservable:
    """A degenerate-geometry answer: the quantity cannot be estimated from these inputs.

    ``reason`` says why, e.g. "parallel rays", "zero baseline", "point behind camera a",
    "angles sum to >= 180 deg", "inconsistent with max speed", "zero time interval".
    """

    reason: str

    def __bool__(self) -> bool:  # so that ``if result:`` reads "if observable"
        return False


@dataclass(frozen=True)
class Triangulation:
    """Two-ray triangulation result; every length in metres, in the common frame of the inputs.

    p: (3,) the point (midpoint of the rays' common perpendicular).
    range_m: |p - origin| (origin defaults to ray b's centre, i.e. where the drone is now).
    range_sigma_m: first-order standard deviation of ``range_m`` from isotropic bearing noise of
        ``bearing_sigma_rad`` on each of the two rays (0.0 when that sigma is 0).
    depth_a_m, depth_b_m: distance from each ray's centre to the closest point on that ray.
    parallax_rad: angle between the two ray directions, in [0, pi].
    miss_m: closest-approach distance between the two rays (0 for consistent, noise-free rays).
    """

    p: np.ndarray
    range_m: float
    range_sigma_m: float
    depth_a_m: float
    depth_b_m: float
    parallax_rad: float
    miss_m: float


@dataclass(frozen=True)
class RangeBounds:
    """Interval that must contain a moving obstacle's range (metres).

    range_min_m, range_max_m: range from the origin (default ray b's centre); ``range_max_m`` is
        None when unbounded (the obstacle could be anywhere beyond ``range_min_m``).
    depth_min_m, depth_max_m: the same interval as depths along ray b (None = unbounded).
    """

    range_min_m: float
    range_max_m: float | None
    depth_min_m: float
    depth_max_m: float | None


@dataclass(frozen=True)
class Velocity:
    """Velocity from two position fixes, in the frame of the inputs.

    v: (3,) m/s. speed_mps: |v|. heading_rad: atan2(v_y, v_x) in that frame (0 when v_x = v_y = 0).
    speed_sigma_mps: first-order standard deviation of the speed, None when the fixes carry no sigma.
    """

    v: np.ndarray
    speed_mps: float
    heading_rad: float
    speed_sigma_mps: float | None


# --------------------------------------------------------------------------- input checks


def _vec3(name: str, x) -> np.ndarray:
    """Return ``x`` as a finite float64 (3,) array or raise InputError naming ``name``."""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}: expected a (3,) array of finite numbers, got {x!r}") from e
    if a.shape != (3,):
        raise InputError(f"{name}: expected an array of shape (3), got {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"{name}: expected finite values, got {a.tolist()}")
    return a


def _unit3(name: str, x) -> np.ndarray:
    """Return ``x`` normalised to a unit (3,) vector; a zero or non-finite vector is an InputError."""
    a = _vec3(name, x)
    n = float(_norm(a))
    if not n > 1e-12:
        raise InputError(f"{name}: expected a non-zero direction (unit bearing), got {a.tolist()}")
    return a / n


def _scalar(name: str, x, *, min_value: float | None = None, allow_inf: bool = False) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}: expected a number, got {x!r}") from e
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise InputError(f"{name}: expected a finite number, got {v}")
    if min_value is not None and v < min_value:
        raise InputError(f"{name}: expected a value >= {min_value}, got {v}")
    return v


# --------------------------------------------------------------------------- triangulation


def _norm(x: np.ndarray) -> float:
    """|x| of a float 1-D array: ``np.linalg.norm``'s own formula for it, sqrt(x . x), without its
    dispatch (~7 us a call on a 3-vector); the same value."""
    return math.sqrt(x.dot(x))


def _norm_rows(x: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Norms (...) of the vectors x (..., K) (float): ``np.linalg.norm(x, axis=-1)``'s own formula,
    sqrt(add.reduce(x * x, axis=-1)), without its axis handling (~10 us a call); the same values.
    For K = 2 or 3 the squares are summed column by column, left to right (add.reduce's own order
    on so short an axis, bit for bit; ~3x faster). keepdims: (..., 1)."""
    s = x * x
    if s.shape[-1] == 3:
        n = np.sqrt(s[..., 0] + s[..., 1] + s[..., 2])
    elif s.shape[-1] == 2:
        n = np.sqrt(s[..., 0] + s[..., 1])
    else:
        n = np.sqrt(np.add.reduce(s, axis=-1))
    return n[..., None] if keepdims else n


def _isin(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.isin(a, b)`` of integer arrays a (N,) and b (M,): the same (N,) bool answer, by a binary
    search of a's values in sorted b (~15 us a call on a few hundred ids, against np.isin's ~80-100:
    its dtype and range checks and one sort of both arrays together)."""
    if not len(b) or not len(a):
        return np.zeros(len(a), bool)
    s = np.sort(b)
    i = np.minimum(s.searchsorted(a), len(s) - 1)
    return s[i] == a


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of float (3,) or (N, 3) arrays (broadcast like ``np.cross``), bit-identical to it.

    The same products and differences as ``np.cross`` (c0 = a1 b2 - a2 b1, c1 = a2 b0 - a0 b2,
    c2 = a0 b1 - a1 b0, each an IEEE multiply then subtract), without its axis handling, which
    costs ~30 us a call on small arrays (triangulate made 7 calls: ~2/3 of its time). A (3,) pair
    is done in Python floats (the same IEEE operations).
    """
    if a.ndim == 1 and b.ndim == 1:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(a.shape if a.shape == b.shape else np.broadcast_shapes(a.shape, b.shape))
    np.subtract(a1 * b2, a2 * b1, out=out[..., 0])
    np.subtract(a2 * b0, a0 * b2, out=out[..., 1])
    np.subtract(a0 * b1, a1 * b0, out=out[..., 2])
    return out


def _closest_depths(c_a, b_a, c_b, b_b):
    """Depths (s, t) of the closest points c_a + s b_a, c_b + t b_b of two lines (vectorised).

    Arrays (..., 3), unit directions. Minimising |w0 + s b_a - t b_b|^2 with w0 = c_a - c_b:
        s = (k e - d) / (1 - k^2),   t = (e - k d) / (1 - k^2)
    with k = b_a.b_b, d = b_a.w0, e = b_b.w0 and 1 - k^2 = |b_a x b_b|^2 = sin^2(parallax).
    """
    w0 = c_a - c_b
    add = np.add.reduce  # np.sum's own reduction, without its dispatch
    k = add(b_a * b_b, axis=-1)
    d = add(b_a * w0, axis=-1)
    e = add(b_b * w0, axis=-1)
    den = add(_cross(b_a, b_b) ** 2, axis=-1)
    s = (k * e - d) / den
    t = (e - k * d) / den
    return s, t


def _tangent_basis(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit ``b`` (3,) and to each other."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(b)))] = 1.0
    u1 = _cross(b, e)
    u1 /= _norm(u1)
    return u1, _cross(b, u1)


def _sigma_step(sin_par):
    """Central-difference step (rad) of the range sigma for rays at sin(parallax) ``sin_par``
    (a float or an array): 1e-6 rad, or an 80th of sin(parallax) when that is smaller (parallax
    under 8e-5 rad or within it of 180 deg). The range is singular where the rays are parallel, so a
    step must stay well inside the parallax: a fixed 1e-6 was +12 % at a parallax of 3e-6 rad and
    reached across the singularity below it (x1.9e9 at 1e-6, x1e-3 at 1e-7 against the closed form)."""
    return np.minimum(1e-6, sin_par / 80.0)


def _range_sigma(c_a, b_a, c_b, b_b, origin, sigma_rad: float, sin_par: float) -> float:
    """First-order std of the midpoint range under isotropic bearing noise ``sigma_rad`` per ray.

    sigma_range = sigma_rad * |J|, J = d range / d(phi_a1, phi_a2, phi_b1, phi_b2), the four small
    rotations of the two bearings in their tangent planes; J by central differences (step
    ``_sigma_step(sin_par)``, sin_par = |b_a x b_b|), evaluated in one vectorised call.
    """
    if sigma_rad == 0.0:
        return 0.0
    h = float(_sigma_step(sin_par))
    ua = _tangent_basis(b_a)
    ub = _tangent_basis(b_b)
    rows_ba, rows_bb = [], []
    for u in ua:  # perturb ray a
        for sgn in (1.0, -1.0):
            v = b_a + sgn * h * u
            rows_ba.append(v / _norm(v))
            rows_bb.append(b_b)
    for u in ub:  # perturb ray b
        for sgn in (1.0, -1.0):
            v = b_b + sgn * h * u
            rows_ba.append(b_a)
            rows_bb.append(v / _norm(v))
    BA = np.array(rows_ba)
    BB = np.array(rows_bb)
    s, t = _closest_depths(c_a[None], BA, c_b[None], BB)
    P = 0.5 * ((c_a + s[:, None] * BA) + (c_b + t[:, None] * BB))
    r = _norm_rows(P - origin)
    J = (r[0::2] - r[1::2]) / (2 * h)  # (4,)
    return float(sigma_rad * _norm(J))


def triangulate(
    c_a,
    b_a,
    c_b,
    b_b,
    *,
    origin=None,
    bearing_sigma_rad: float = 0.0,
    min_parallax_rad: float = 1e-4,
) -> Triangulation | Unobservable:
    """Triangulate a static point seen along two rays (mono parallax or stereo).

    c_a, c_b: (3,) ray origins (camera centres) in metres; b_a, b_b: (3,) directions (normalised
    here; unit bearings expected), all in one common frame (W or B). origin: (3,) point the range is
    measured from, default ``c_b`` (the second pose / where the drone is now). bearing_sigma_rad:
    isotropic 1-sigma bearing noise of each ray (radians) for ``range_sigma_m``. min_parallax_rad:
    smaller angles between the rays are "parallel rays".

    Method: midpoint of the common perpendicular. For noise-free rays it is exact; with equal angular
    noise on rays of similar depth it is within first order of the optimal (L2-angular) estimate, and
    it is closed form, which the fusion filter and the property tests rely on.

    Returns Triangulation, or Unobservable for: zero baseline, parallel rays, a closest point at zero
    or negative depth on either ray ("point behind camera a/b", or both when the rays diverge).
    Raises InputError on malformed input (shapes, NaN, zero directions, negative sigma).
    """
    c_a = _vec3("c_a", c_a)
    c_b = _vec3("c_b", c_b)
    b_a = _unit3("b_a", b_a)
    b_b = _unit3("b_b", b_b)
    o = c_b if origin is None else _vec3("origin", origin)
    sigma = _scalar("bearing_sigma_rad", bearing_sigma_rad, min_value=0.0)
    min_par = _scalar("min_parallax_rad", min_parallax_rad, min_value=0.0)

    baseline = float(_norm(c_b - c_a))
    scale = max(1.0, float(_norm(c_a)), float(_norm(c_b)))
    if baseline <= 1e-12 * scale:
        return Unobservable("zero baseline")
    # parallax = atan2(|b_a x b_b|, b_a . b_b): accurate at small and large angles
    sin_par = float(_norm(_cross(b_a, b_b)))
    parallax = math.atan2(sin_par, float(b_a @ b_b))
    if parallax < min_par or sin_par**2 <= _PARALLEL_SIN2:
        return Unobservable("parallel rays")
    if math.pi - parallax < min_par:
        # anti-parallel rays: they can only meet between the centres if collinear with the baseline
        return Unobservable("parallel rays (opposite directions)")

    s, t = _closest_depths(c_a, b_a, c_b, b_b)
    s, t = float(s), float(t)
    tol = 1e-12 * scale
    if s <= tol and t <= tol:
        return Unobservable("point behind both cameras (rays diverge)")
    if s <= tol:
        return Unobservable("point behind camera a")
    if t <= tol:
        return Unobservable("point behind camera b")

    q_a = c_a + s * b_a
    q_b = c_b + t * b_b
    p = 0.5 * (q_a + q_b)  # midpoint of the common perpendicular
    rng = float(_norm(p - o))
    return Triangulation(
        p=p,
        range_m=rng,
        range_sigma_m=_range_sigma(c_a, b_a, c_b, b_b, o, sigma, sin_par),
        depth_a_m=s,
        depth_b_m=t,
        parallax_rad=parallax,
        miss_m=float(_norm(q_a - q_b)),
    )


@dataclass(frozen=True)
class TriangulationBatch:
    """``triangulate`` over N ray pairs; row i equals ``triangulate`` of the i-th inputs.

    p: (N, 3); range_m, range_sigma_m, depth_a_m, depth_b_m, parallax_rad, miss_m: (N,) as in
    ``Triangulation``. valid: (N,) bool; rows that are not valid are zeros (never NaN) and
    ``reason[i]`` says why (the ``Unobservable`` reason; "" for valid rows).
    """

    p: np.ndarray
    range_m: np.ndarray
    range_sigma_m: np.ndarray
    depth_a_m: np.ndarray
    depth_b_m: np.ndarray
    parallax_rad: np.ndarray
    miss_m: np.ndarray
    valid: np.ndarray
    reason: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.valid.shape[0])

    def row(self, i: int) -> Triangulation | Unobservable:
        """Row ``i`` as the scalar API's result."""
        if not self.valid[i]:
            return Unobservable(self.reason[i])
        return Triangulation(
            p=self.p[i].copy(),
            range_m=float(self.range_m[i]),
            range_sigma_m=float(self.range_sigma_m[i]),
            depth_a_m=float(self.depth_a_m[i]),
            depth_b_m=float(self.depth_b_m[i]),
            parallax_rad=float(self.parallax_rad[i]),
            miss_m=float(self.miss_m[i]),
        )


def _rows3(name: str, x, n: int | None) -> np.ndarray:
    """(N, 3) or (3,) finite float64 -> (N, 3) (a (3,) input is repeated); InputError otherwise."""
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}: expected an (N, 3) or (3,) array of finite numbers") from e
    if a.shape == (3,):
        a = np.broadcast_to(a, (1 if n is None else n, 3))
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and a.shape[0] != n):
        want = "(N, 3) or (3,)" if n is None else f"({n}, 3) or (3,)"
        raise InputError(f"{name}: expected an array of shape {want}, got {np.shape(x)}")
    if not np.isfinite(a).all():
        raise InputError(f"{name}: expected finite values (no NaN/inf)")
    return a


def triangulate_batch(
    c_a,
    b_a,
    c_b,
    b_b,
    *,
    origin=None,
    bearing_sigma_rad: float = 0.0,
    min_parallax_rad: float = 1e-4,
) -> TriangulationBatch:
    """Vectorised ``triangulate`` over N ray pairs (same method, same degenerate cases).

    c_a, b_a, c_b, b_b, origin: (N, 3) arrays, or (3,) shared by all rows, in one common frame
    (metres, directions normalised here); origin defaults to c_b. A zero direction or NaN anywhere
    is an InputError (as in the scalar API); degenerate rows are ``valid = False`` with a reason.
    """
    n = None
    for x in (c_a, b_a, c_b, b_b, origin):
        if x is not None and np.ndim(x) == 2:
            n = int(np.shape(x)[0])
            break
    c_a = _rows3("c_a", c_a, n)
    n = c_a.shape[0]
    c_b = _rows3("c_b", c_b, n)
    b_a = _rows3("b_a", b_a, n)
    b_b = _rows3("b_b", b_b, n)
    o = c_b if origin is None else _rows3("origin", origin, n)
    sigma = _scalar("bearing_sigma_rad", bearing_sigma_rad, min_value=0.0)
    min_par = _scalar("min_parallax_rad", min_parallax_rad, min_value=0.0)
    na, nb = _norm_rows(b_a), _norm_rows(b_b)
    if (na <= 1e-12).any() or (nb <= 1e-12).any():
        raise InputError("b_a, b_b: expected non-zero directions (unit bearings) in every row")
    b_a, b_b = b_a / na[:, None], b_b / nb[:, None]

    scale = np.maximum(1.0, np.maximum(_norm_rows(c_a), _norm_rows(c_b)))
    baseline = _norm_rows(c_b - c_a)
    sin_par = _norm_rows(_cross(b_a, b_b))
    parallax = np.arctan2(sin_par, np.sum(b_a * b_b, axis=1))
    reasons = np.full(n, "", dtype=object)
    zero_base = baseline <= 1e-12 * scale
    parallel = ~zero_base & ((parallax < min_par) | (sin_par**2 <= _PARALLEL_SIN2))
    anti = ~zero_base & ~parallel & (np.pi - parallax < min_par)
    reasons[zero_base] = "zero baseline"
    reasons[parallel] = "parallel rays"
    reasons[anti] = "parallel rays (opposite directions)"
    ok = ~(zero_base | parallel | anti)
    with np.errstate(divide="ignore", invalid="ignore"):
        s, t = _closest_depths(c_a, b_a, c_b, b_b)
    s = np.where(ok, s, 0.0)
    t = np.where(ok, t, 0.0)
    tol = 1e-12 * scale
    behind_a, behind_b = ok & (s <= tol), ok & (t <= tol)
    reasons[behind_a & behind_b] = "point behind both cameras (rays diverge)"
    reasons[behind_a & ~behind_b] = "point behind camera a"
    reasons[behind_b & ~behind_a] = "point behind camera b"
    ok &= ~(behind_a | behind_b)

    q_a = c_a + s[:, None] * b_a
    q_b = c_b + t[:, None] * b_b
    p = 0.5 * (q_a + q_b)  # midpoint of the common perpendicular
    rng = _norm_rows(p - o)
    sig = np.zeros(n)
    if sigma > 0.0 and ok.any():
        sig[ok] = _range_sigma_batch(c_a[ok], b_a[ok], c_b[ok], b_b[ok], o[ok], sigma, sin_par[ok])
    z = ~ok
    p[z] = 0.0
    for arr in (rng, s, t, parallax, sig):
        arr[z] = 0.0
    miss = np.where(ok, _norm_rows(q_a - q_b), 0.0)
    return TriangulationBatch(
        p=p,
        range_m=rng,
        range_sigma_m=sig,
        depth_a_m=s,
        depth_b_m=t,
        parallax_rad=parallax,
        miss_m=miss,
        valid=ok,
        reason=tuple(str(r) for r in reasons),
    )


def _range_sigma_batch(c_a, b_a, c_b, b_b, origin, sigma_rad: float, sin_par: np.ndarray) -> np.ndarray:
    """Vectorised ``_range_sigma`` for (M, 3) inputs and sin(parallax) (M,) -> (M,).

    The 8 perturbed ray pairs of every row (+-h about each of the two tangent directions of ray a,
    then of ray b; h = ``_sigma_step`` of the row) are stacked into one (8M, 3) batch for a single
    ``_closest_depths`` call; the arithmetic is row-wise, so each row's value is the one a separate
    call would give.
    """
    h = _sigma_step(sin_par)  # (M,)
    m = c_a.shape[0]
    rows_ba, rows_bb = [], []
    for which in ("a", "b"):
        b = b_a if which == "a" else b_b
        e = np.zeros_like(b)
        e[np.arange(m), np.argmin(np.abs(b), axis=1)] = 1.0
        u1 = _cross(b, e)
        u1 /= _norm_rows(u1, keepdims=True)
        for u in (u1, _cross(b, u1)):  # the two tangent directions of this ray
            for sgn in (1.0, -1.0):
                v = b + sgn * h[:, None] * u
                v /= _norm_rows(v, keepdims=True)
                rows_ba.append(v if which == "a" else b_a)
                rows_bb.append(b_b if which == "a" else v)
    BA, BB = np.concatenate(rows_ba), np.concatenate(rows_bb)  # (8M, 3), block j = perturbation j
    CA, CB, O = np.tile(c_a, (8, 1)), np.tile(c_b, (8, 1)), np.tile(origin, (8, 1))
    s, t = _closest_depths(CA, BA, CB, BB)
    P = 0.5 * ((CA + s[:, None] * BA) + (CB + t[:, None] * BB))
    r = _norm_rows(P - O).reshape(8, m)
    J = np.ascontiguousarray(((r[0::2] - r[1::2]) / (2 * h)).T)  # (M, 4): d range / d phi, central
    return sigma_rad * _norm_rows(J)


# --------------------------------------------------------------------------- moving obstacle bounds


def _dot(a, b) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _within(w, u, D: float, tol: float) -> tuple[float, float] | None:
    """Solution set {r : |w + r u| <= D} as (lo, hi) (may be +-inf), or None if empty.

    w, u: 3-sequences of floats. The quadratic A r^2 + 2 beta r + (|w|^2 - D^2) <= 0 with A = |u|^2,
    beta = w.u has the reduced discriminant beta^2 - A(|w|^2 - D^2) = A D^2 - |w x u|^2 (Lagrange's
    identity), computed from the cross product so that tangent cases (D = the closest distance
    |w x u| / |u|) keep full precision; a closest distance within ``tol`` of D counts as touching.
    Plain float math: numpy costs ~10x more on 3-vectors.
    """
    A = _dot(u, u)
    ww = _dot(w, w)
    if A <= 1e-30:  # u = 0: constant distance |w|
        return (-math.inf, math.inf) if math.sqrt(ww) <= D + tol else None
    beta = _dot(w, u)
    x0 = w[1] * u[2] - w[2] * u[1]  # w x u
    x1 = w[2] * u[0] - w[0] * u[2]
    x2 = w[0] * u[1] - w[1] * u[0]
    miss = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / math.sqrt(A)  # closest distance of the line to 0
    if miss > D + tol:
        return None
    disc = max(A * (D * D - miss * miss), 0.0)
    sq = math.sqrt(disc)
    q = -(beta + math.copysign(sq, beta))  # stable roots q / A and c / q
    c = ww - D * D
    r1 = q / A
    r2 = c / q if q != 0.0 else r1
    return (min(r1, r2), max(r1, r2))


def _intersect(a: tuple[float, float] | None, lo: float, hi: float) -> tuple[float, float] | None:
    if a is None:
        return None
    lo2, hi2 = max(a[0], lo), min(a[1], hi)
    return (lo2, hi2) if lo2 <= hi2 else None


def moving_obstacle_bounds(
    c_a, b_a, c_b, b_b, max_displacement_m: float | None = None, *, origin=None
) -> RangeBounds | Unobservable:
    """Range interval of an obstacle that moved at most ``max_displacement_m`` between two sightings.

    Generalises the thesis's eq. 3.11-3.13 to 3-D and any direction of motion. The obstacle was on
    ray a (half-line c_a + s b_a, s >= 0) at time a and is on ray b at time b; it moved at most
    D = max_displacement_m (= max speed * dt) in between. The feasible depths along ray b are
        R = {r >= 0 : dist(c_b + r b_b, ray a) <= D},
    an interval (distance to a convex set is convex along a line). Closed form, piecewise:
    with w(r) = c_b - c_a + r b_b and the foot depth s(r) = b_a.w(r) = s0 + r k on line a,
      where s(r) >= 0:  |w|^2 - s^2 <= D^2   (distance to the line)
      where s(r) <  0:  |w|^2       <= D^2   (distance to c_a)
    each a quadratic inequality in r. The range from ``origin`` is convex along ray b, so its
    minimum over R is at the clamped foot of the perpendicular from origin (an interior minimum is
    possible) and its maximum at an end point (None when R is unbounded).

    c_a, c_b: (3,) centres in metres; b_a, b_b: (3,) directions (normalised here); origin: (3,),
    default c_b; all in one common frame. max_displacement_m >= 0 (may be +inf: then only the
    half-line constraint remains); None (default) = the baseline |c_b - c_a|, i.e. the obstacle
    moves no farther than the camera did (the thesis's assumption, eq. 3.11-3.13: as fast as the
    drone in straight flight; on a curved path the chord is shorter than speed * dt, so pass
    max speed * dt there, as the fusion does). Returns RangeBounds, or
    Unobservable("inconsistent with max speed") when R is empty. Raises InputError on malformed input.
    See ``moving_obstacle_bounds_unchecked`` for the same without the input checks (hot loops).
    """
    c_a = _vec3("c_a", c_a)
    c_b = _vec3("c_b", c_b)
    b_a = _unit3("b_a", b_a)
    b_b = _unit3("b_b", b_b)
    o = c_b if origin is None else _vec3("origin", origin)
    if max_displacement_m is None:  # the obstacle moves at most as fast as the drone: D = |c_b - c_a|
        max_displacement_m = float(_norm(c_b - c_a))
    D = _scalar("max_displacement_m", max_displacement_m, min_value=0.0, allow_inf=True)
    return moving_obstacle_bounds_unchecked(
        c_a.tolist(), b_a.tolist(), c_b.tolist(), b_b.tolist(), D, o.tolist()
    )


def moving_obstacle_bounds_unchecked(c_a, b_a, c_b, b_b, D: float, origin) -> RangeBounds | Unobservable:
    """``moving_obstacle_bounds`` without input checks, in plain float math (~10x faster).

    c_a, b_a, c_b, b_b, origin: 3-sequences of finite floats (tuples, lists or (3,) arrays) in one
    frame, metres; b_a, b_b unit directions (not normalised here); D >= 0 metres (may be +inf).
    The caller guarantees all that (e.g. the fusion filter's own world-frame rays).
    """
    if math.isinf(D):
        lo, hi = 0.0, math.inf
    else:
        w0 = (c_b[0] - c_a[0], c_b[1] - c_a[1], c_b[2] - c_a[2])
        k = _dot(b_a, b_b)
        s0 = _dot(b_a, w0)
        tol = 1e-9 * max(1.0, math.sqrt(_dot(c_a, c_a)), math.sqrt(_dot(c_b, c_b)))
        # region where the foot on line a has s(r) = s0 + k r >= 0
        if abs(k) <= 1e-15:
            reg_line = (-math.inf, math.inf) if s0 >= 0 else None
        elif k > 0:
            reg_line = (-s0 / k, math.inf)
        else:
            reg_line = (-math.inf, -s0 / k)
        # distance to the line a: |w_perp + r b_perp| <= D, the components orthogonal to b_a of
        # w(r) = w0 + r b_b (w_perp = w0 - s0 b_a, b_perp = b_b - k b_a)
        w_perp = (w0[0] - s0 * b_a[0], w0[1] - s0 * b_a[1], w0[2] - s0 * b_a[2])
        b_perp = (b_b[0] - k * b_a[0], b_b[1] - k * b_a[1], b_b[2] - k * b_a[2])
        sol_line = _within(w_perp, b_perp, D, tol)
        # distance to the centre c_a: |w0 + r b_b| <= D
        sol_pt = _within(w0, b_b, D, tol)
        pieces = []
        if reg_line is not None:
            pieces.append(_intersect(sol_line, max(0.0, reg_line[0]), reg_line[1]))
            # complement of the line region (s < 0) uses the distance to c_a
            if math.isinf(reg_line[0]) and not math.isinf(reg_line[1]):
                pieces.append(_intersect(sol_pt, max(0.0, reg_line[1]), math.inf))
            elif not math.isinf(reg_line[0]):
                pieces.append(_intersect(sol_pt, 0.0, reg_line[0]))
        else:
            pieces.append(_intersect(sol_pt, 0.0, math.inf))
        pieces = [p for p in pieces if p is not None]
        if not pieces:
            return Unobservable("inconsistent with max speed")
        lo = min(p[0] for p in pieces)
        hi = max(p[1] for p in pieces)

    # range from the origin along ray b: |c_b + r b_b - o| is convex in r
    e = (c_b[0] - origin[0], c_b[1] - origin[1], c_b[2] - origin[2])
    be = _dot(b_b, e)
    ee = _dot(e, e)

    def rng(r: float) -> float:
        return math.sqrt(max(ee + 2.0 * r * be + r * r, 0.0))  # |e + r b|, |b| = 1

    r_star = min(max(-be, lo), hi)
    range_min = rng(r_star)
    if math.isinf(hi):
        range_max = None
        depth_max = None
    else:
        range_max = max(rng(lo), rng(hi))
        depth_max = hi
    return RangeBounds(range_min_m=range_min, range_max_m=range_max, depth_min_m=lo, depth_max_m=depth_max)


def _within_batch(w: np.ndarray, u: np.ndarray, D: np.ndarray, tol: np.ndarray):
    """Row-wise ``_within``: w, u (N, 3), D, tol (N,) -> (lo, hi, ok) (N,) each."""
    A = _einsum("ij,ij->i", u, u)
    ww = _einsum("ij,ij->i", w, w)
    beta = _einsum("ij,ij->i", w, u)
    zero = A <= 1e-30
    As = np.where(zero, 1.0, A)
    miss = _norm_rows(_cross(w, u)) / np.sqrt(As)
    ok = np.where(zero, np.sqrt(ww) <= D + tol, miss <= D + tol)
    sq = np.sqrt(np.maximum(As * (D * D - miss * miss), 0.0))
    q = -(beta + np.copysign(sq, beta))  # stable roots q / A and c / q
    r1 = q / As
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(q != 0.0, (ww - D * D) / np.where(q != 0.0, q, 1.0), r1)
    lo = np.where(zero, -np.inf, np.minimum(r1, r2))
    hi = np.where(zero, np.inf, np.maximum(r1, r2))
    return lo, hi, ok


def moving_obstacle_bounds_batch(c_a, b_a, c_b, b_b, D, origin):
    """``moving_obstacle_bounds_unchecked`` over N rows at once (same closed form, same cases).

    c_a, b_a, c_b, b_b, origin: (N, 3) float arrays in one frame (m; b_a, b_b unit directions, not
    normalised here); D: (N,) max displacements (m, >= 0, may be +inf). No input checks (hot
    loops: the caller's own finite rays). Returns (range_min_m, range_max_m, depth_min_m,
    depth_max_m, valid), each (N,): rows that are not valid ("inconsistent with max speed") are 0;
    an unbounded interval has range_max_m = depth_max_m = +inf.
    """
    c_a, b_a, c_b, b_b, o = (np.asarray(x, dtype=float) for x in (c_a, b_a, c_b, b_b, origin))
    D = np.asarray(D, dtype=float)
    n = len(D)
    inf = np.inf
    w0 = c_b - c_a
    k = _einsum("ij,ij->i", b_a, b_b)
    s0 = _einsum("ij,ij->i", b_a, w0)
    tol = 1e-9 * np.maximum(1.0, np.maximum(_norm_rows(c_a), _norm_rows(c_b)))
    Df = np.where(np.isinf(D), 0.0, D)
    # region of line a's foot s(r) = s0 + k r >= 0: (reg_lo, reg_hi), reg_ok
    flat = np.abs(k) <= 1e-15
    ks = np.where(flat, 1.0, k)
    reg_ok = ~flat | (s0 >= 0)
    reg_lo = np.where(flat, -inf, np.where(k > 0, -s0 / ks, -inf))
    reg_hi = np.where(flat, inf, np.where(k > 0, inf, -s0 / ks))
    # both constraints in one _within_batch call over 2N rows (row-wise arithmetic: the same values)
    lo_w, hi_w, ok_w = _within_batch(np.concatenate((w0 - s0[:, None] * b_a, w0)),
                                     np.concatenate((b_b - k[:, None] * b_a, b_b)),
                                     np.concatenate((Df, Df)), np.concatenate((tol, tol)))
    ln_lo, ln_hi, ln_ok = lo_w[:n], hi_w[:n], ok_w[:n]
    pt_lo, pt_hi, pt_ok = lo_w[n:], hi_w[n:], ok_w[n:]

    def cut(lo, hi, ok, a, b):  # _intersect, row-wise
        lo2, hi2 = np.maximum(lo, a), np.minimum(hi, b)
        return lo2, hi2, ok & (lo2 <= hi2)

    # piece 1: the line region (or, without one, the whole half-line against the centre c_a)
    l1 = np.where(reg_ok, ln_lo, pt_lo)
    h1 = np.where(reg_ok, ln_hi, pt_hi)
    o1 = np.where(reg_ok, ln_ok, pt_ok)
    p1 = cut(l1, h1, o1, np.where(reg_ok, np.maximum(0.0, reg_lo), 0.0), np.where(reg_ok, reg_hi, inf))
    # piece 2: the complement of the line region against the centre c_a
    lo_inf, hi_inf = np.isinf(reg_lo), np.isinf(reg_hi)
    case_a = reg_ok & lo_inf & ~hi_inf  # region (-inf, reg_hi): complement beyond reg_hi
    case_b = reg_ok & ~lo_inf  # region (reg_lo, inf): complement [0, reg_lo]
    a2 = np.where(case_a, np.maximum(0.0, np.where(hi_inf, 0.0, reg_hi)), 0.0)
    b2 = np.where(case_a, inf, np.where(case_b, np.where(lo_inf, 0.0, reg_lo), inf))
    p2 = cut(pt_lo, pt_hi, pt_ok & (case_a | case_b), a2, b2)
    valid = p1[2] | p2[2]
    lo = np.minimum(np.where(p1[2], p1[0], inf), np.where(p2[2], p2[0], inf))
    hi = np.maximum(np.where(p1[2], p1[1], -inf), np.where(p2[2], p2[1], -inf))
    dinf = np.isinf(D)
    lo = np.where(dinf, 0.0, lo)
    hi = np.where(dinf, inf, hi)
    valid |= dinf
    lo = np.where(valid, lo, 0.0)
    hi = np.where(valid, hi, 0.0)
    # range from the origin along ray b: |e + r b|, e = c_b - o, convex in r
    e = c_b - o
    be = _einsum("ij,ij->i", b_b, e)
    ee = _einsum("ij,ij->i", e, e)
    fin = np.isfinite(hi)
    hi_f = np.where(fin, hi, 0.0)

    def rng(r):
        return np.sqrt(np.maximum(ee + 2.0 * r * be + r * r, 0.0))

    r_star = np.minimum(np.maximum(-be, lo), np.where(fin, hi, inf))
    r_min = np.where(valid, rng(r_star), 0.0)
    r_max = np.where(valid, np.where(fin, np.maximum(rng(lo), rng(hi_f)), inf), 0.0)
    if n == 0:
        valid = np.zeros(0, dtype=bool)
    return r_min, r_max, lo, hi, valid


# --------------------------------------------------------------------------- velocity


def _cov(name: str, sigma) -> np.ndarray | None:
    """Position uncertainty as a (3,3) covariance: None, a scalar per-axis std (m), or (3,3) cov (m^2)."""
    if sigma is None:
        return None
    a = np.asarray(sigma, dtype=float)
    if a.shape == ():
        s = _scalar(name, float(a), min_value=0.0)
        return np.eye(3) * s * s
    if a.shape != (3, 3) or not np.isfinite(a).all():
        raise InputError(
            f"{name}: expected a per-axis std (m) or a finite (3, 3) covariance (m^2), got shape {a.shape}"
        )
    return a


def velocity_from_fixes(p_1, t1_s, p_2, t2_s, *, sigma_1=None, sigma_2=None) -> Velocity | Unobservable:
    """Velocity of an obstacle from two position fixes (generalises the thesis's eq. 3.3-3.6).

    p_1, p_2: (3,) positions in metres at times t1_s < t2_s (seconds), in one frame that does not
    move between the two times (W; a body frame only when the drone's motion was removed).
    sigma_1, sigma_2: position uncertainty of each fix, a per-axis std in metres or a (3,3)
    covariance in m^2 (None: no sigma).

    v = (p_2 - p_1) / (t2 - t1); speed sigma to first order: sqrt(u^T (S1 + S2) u) / dt with u = v/|v|
    (for v = 0: sqrt(trace(S1 + S2) / 3) / dt). Returns Unobservable("zero time interval") for
    t2 == t1; raises InputError for t2 < t1 or non-finite inputs.
    """
    p_1 = _vec3("p_1", p_1)
    p_2 = _vec3("p_2", p_2)
    t1 = _scalar("t1_s", t1_s)
    t2 = _scalar("t2_s", t2_s)
    S1 = _cov("sigma_1", sigma_1)
    S2 = _cov("sigma_2", sigma_2)
    dt = t2 - t1
    if dt < 0:
        raise InputError(f"t2_s: expected a time after t1_s = {t1}, got {t2}")
    if dt == 0:
        return Unobservable("zero time interval")
    v = (p_2 - p_1) / dt  # eq. 3.3-3.6: CD / 0.1 s, CD = |p_2 - p_1|
    speed = float(_norm(v))
    heading = math.atan2(float(v[1]), float(v[0]))
    sig = None
    if S1 is not None or S2 is not None:
        S = (S1 if S1 is not None else 0.0) + (S2 if S2 is not None else 0.0)
        if speed > 0:
            u = v / speed
            var = float(u @ S @ u)
        else:
            var = float(np.trace(S)) / 3.0
        sig = math.sqrt(max(var, 0.0)) / dt
    return Velocity(v=v, speed_mps=speed, heading_rad=heading, speed_sigma_mps=sig)


# --------------------------------------------------------------------------- planar (thesis) helpers


def planar_rays(d_m: float, theta1_rad: float, theta2_rad: float):
    """The thesis's planar two-ray configuration from a baseline and two interior angles.

    A = (0, 0, 0), B = (d, 0, 0) (A -> B is the drone's motion for mono, camera 1 -> camera 2 for
    stereo); the obstacle C is at y > 0. theta1_rad: interior angle at A between A->B and A->C;
    theta2_rad: interior angle at B between B->A and B->C; both in (0, pi), may exceed pi/2.
    Returns (c_a, b_a, c_b, b_b), each (3,) in metres / unit directions:
        b_a = (cos th1, sin th1, 0),  b_b = (-cos th2, sin th2, 0).
    """
    d = _scalar("d_m", d_m)
    t1 = _scalar("theta1_rad", theta1_rad)
    t2 = _scalar("theta2_rad", theta2_rad)
    c_a = np.zeros(3)
    c_b = np.array([d, 0.0, 0.0])
    b_a = np.array([math.cos(t1), math.sin(t1), 0.0])
    b_b = np.array([-math.cos(t2), math.sin(t2), 0.0])
    return c_a, b_a, c_b, b_b


def _planar_check(d_m: float, theta1_rad: float, theta2_rad: float) -> Unobservable | None:
    if d_m <= 0:
        return Unobservable("zero baseline")
    if not (0 < theta1_rad < math.pi and 0 < theta2_rad < math.pi):
        return Unobservable("interior angle outside (0, 180) deg")
    if theta1_rad + theta2_rad >= math.pi:
        return Unobservable("angles sum to >= 180 deg")
    return None


def planar_triangulate(
    d_m: float, theta1_rad: float, theta2_rad: float, *, origin: str = "b", bearing_sigma_rad: float = 0.0
) -> Triangulation | Unobservable:
    """Triangulate the thesis's planar configuration (see ``planar_rays``) with ``triangulate``.

    origin: "b" (range from B: eq. 3.8, 3.9, 3.10, the mono range and the stereo "Y"),
    "a" (range from A), or "mid" (from the baseline's midpoint: eq. 3.2's CF). ``p[1]`` is the
    perpendicular distance to the baseline (eq. 3.1's Z). Angles summing to >= 180 deg, or outside
    (0, 180) deg, or d = 0 give Unobservable; NaN or a negative d raise InputError.
    """
    bad = _planar_check(
        _scalar("d_m", d_m, min_value=0.0),
        _scalar("theta1_rad", theta1_rad),
        _scalar("theta2_rad", theta2_rad),
    )
    if bad is not None:
        return bad
    c_a, b_a, c_b, b_b = planar_rays(d_m, theta1_rad, theta2_rad)
    o = {"b": c_b, "a": c_a, "mid": 0.5 * (c_a + c_b)}.get(origin)
    if o is None:
        raise InputError(f"origin: expected one of 'a', 'b', 'mid', got {origin!r}")
    return triangulate(
        c_a, b_a, c_b, b_b, origin=o, bearing_sigma_rad=bearing_sigma_rad, min_parallax_rad=0.0
    )


def planar_moving_obstacle_bounds(
    d_m: float, theta1_rad: float, theta2_rad: float, max_displacement_m: float | None = None
) -> RangeBounds | Unobservable:
    """``moving_obstacle_bounds`` for the thesis's planar configuration (range from B); the
    displacement defaults to the baseline ``d_m`` (obstacle at most as fast as the drone)."""
    if _scalar("d_m", d_m, min_value=0.0) == 0.0:
        return Unobservable("zero baseline")
    if not (
        0 < _scalar("theta1_rad", theta1_rad) < math.pi and 0 < _scalar("theta2_rad", theta2_rad) < math.pi
    ):
        return Unobservable("interior angle outside (0, 180) deg")
    c_a, b_a, c_b, b_b = planar_rays(d_m, theta1_rad, theta2_rad)
    return moving_obstacle_bounds(c_a, b_a, c_b, b_b, max_displacement_m)
