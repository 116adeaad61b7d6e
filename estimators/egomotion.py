"""Ego-motion of the body: the pose ``T_W_B(t_s)`` from a TUM trajectory or a constant velocity.

TUM format (CONVENTIONS.md): one pose per line, ``timestamp tx ty tz qx qy qz qw``, the pose
``T_W_B`` (p_W = T_W_B p_B); ``#`` starts a comment. Poses between samples are interpolated
linearly in position and by slerp in rotation. Times outside the file's span are an error, never
an extrapolation.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from estimators.errors import InputError
from estimators.se3 import Pose, quat_to_rot, rot_to_quat, slerp


class EgoMotion(ABC):
    """Source of the body pose in the world frame as a function of time."""

    @abstractmethod
    def pose_at(self, t_s: float) -> Pose:
        """``T_W_B`` at time ``t_s`` (seconds). Raises InputError outside the covered span."""

    @abstractmethod
    def velocity_at(self, t_s: float) -> np.ndarray:
        """Body velocity in the world frame, ``v_W`` (3,), m/s."""

    def covers(self, t_s: float) -> bool:
        """Whether ``t_s`` lies within the span this source can answer for."""
        return True


@dataclass(frozen=True)
class ConstantVelocity(EgoMotion):
    """The thesis's case: the body flies at ``speed_mps`` along its own x axis (forward), level.

    ``T_W_B(t) = (R0, p0 + R0 @ [speed_mps * (t - t0_s), 0, 0])``.
    """

    speed_mps: float
    t0_s: float = 0.0
    start: Pose = Pose(np.eye(3), np.zeros(3))

    def __post_init__(self) -> None:
        if not np.isfinite(self.speed_mps):
            raise InputError(f"ConstantVelocity: speed_mps must be finite, got {self.speed_mps}")

    def pose_at(self, t_s: float) -> Pose:
        dx = self.speed_mps * (float(t_s) - self.t0_s)
        return Pose(self.start.R, self.start.t + self.start.R @ np.array([dx, 0.0, 0.0]))

    def velocity_at(self, t_s: float) -> np.ndarray:
        return self.start.R @ np.array([self.speed_mps, 0.0, 0.0])


def _quaternion_norms(q: np.ndarray) -> np.ndarray:
    """Norms of the quaternions ``q`` (N, 4); where the squares overflow, ``math.hypot``'s
    (overflow-safe), so only a norm beyond the float range is infinite."""
    with np.errstate(over="ignore"):
        norms = np.linalg.norm(q, axis=1)
    for i in np.flatnonzero(~np.isfinite(norms)):
        norms[i] = math.hypot(*q[i])
    return norms


def _quaternion_problem(norm: float) -> str:
    kind = "a zero quaternion" if norm < 1e-9 else "a quaternion too large to normalise"
    return f"has {kind} (norm {norm:.3g}; expected a rotation [qx qy qz qw], any non-zero finite scale)"


def parse_tum_line(line: str, where: str) -> list[float] | None:
    """One line of a TUM file as its 8 numbers ``[t, tx, ty, tz, qx, qy, qz, qw]``, or None for a blank
    or ``#`` comment line; commas count as spaces. The per-line check of :meth:`TumTrajectory.load` and
    of readers of growing files (``pipeline.live.GrowingTrajectory``).

    Args:
        where: how errors name the line, e.g. ``"traj.tum:3"``.

    Raises:
        InputError: ``"<where>: ..."``: not 8 numbers, a NaN or infinite value, or a zero quaternion (or
            one too large to normalise).
    """
    s = line.strip()
    if not s or s.startswith("#"):
        return None
    parts = s.replace(",", " ").split()
    if len(parts) != 8:
        raise InputError(f"{where}: expected 8 numbers 'timestamp tx ty tz qx qy qz qw', got {len(parts)}")
    try:
        vals = [float(x) for x in parts]
    except ValueError:
        raise InputError(f"{where}: not a number in {s!r}") from None
    if not all(np.isfinite(vals)):
        raise InputError(f"{where}: NaN or infinite value in {s!r}")
    qn = float(_quaternion_norms(np.array([vals[4:8]]))[0])
    if not (qn >= 1e-9 and np.isfinite(qn)):
        raise InputError(f"{where}: {_quaternion_problem(qn)} in {s!r}")
    return vals


class TumTrajectory(EgoMotion):
    """A trajectory of timestamped poses ``T_W_B``, interpolated to any time inside its span.

    Args:
        t_s: timestamps, shape (N,), seconds, strictly increasing, N >= 2.
        p_W: positions of the body origin in W, shape (N, 3), metres.
        q_W_B: orientations as unit quaternions [qx, qy, qz, qw], shape (N, 4).
        source: name used in error messages (the file path).
    """

    def __init__(self, t_s: np.ndarray, p_W: np.ndarray, q_W_B: np.ndarray, source: str = "trajectory"):
        t_s = np.asarray(t_s, dtype=float).reshape(-1)
        p_W = np.asarray(p_W, dtype=float).reshape(-1, 3)
        q_W_B = np.asarray(q_W_B, dtype=float).reshape(-1, 4)
        if not (len(t_s) == len(p_W) == len(q_W_B)):
            raise InputError(f"{source}: t_s, p_W and q_W_B must have the same length")
        if len(t_s) < 2:
            raise InputError(f"{source}: expected at least 2 poses, got {len(t_s)}")
        for i in range(len(t_s)):
            if not (np.isfinite(t_s[i]) and np.all(np.isfinite(p_W[i])) and np.all(np.isfinite(q_W_B[i]))):
                raise InputError(f"{source}: pose {i} (t={t_s[i]}) has a NaN or infinite value")
        bad = np.nonzero(np.diff(t_s) <= 0)[0]
        if len(bad):
            i = int(bad[0]) + 1
            raise InputError(
                f"{source}: timestamps must increase strictly; pose {i} has t={t_s[i]!r} "
                f"after t={t_s[i - 1]!r}"
            )
        norms = _quaternion_norms(q_W_B)
        bad = ~((norms >= 1e-9) & np.isfinite(norms))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise InputError(f"{source}: pose {i} {_quaternion_problem(norms[i])}")
        self.t_s = t_s
        self.p_W = p_W
        self.q_W_B = q_W_B / norms[:, None]
        self.source = source

    @classmethod
    def load(cls, path: str | Path) -> TumTrajectory:
        """Read a TUM file; a malformed line is an InputError naming the file and line number."""
        path = Path(path)
        if not path.is_file():
            raise InputError(f"{path}: trajectory file not found")
        rows = []
        with path.open() as f:
            for lineno, line in enumerate(f, start=1):
                vals = parse_tum_line(line, f"{path}:{lineno}")
                if vals is not None:
                    rows.append((lineno, vals))
        if len(rows) < 2:
            raise InputError(f"{path}: expected at least 2 poses, found {len(rows)}")
        for (l0, v0), (l1, v1) in zip(rows, rows[1:], strict=False):
            if v1[0] <= v0[0]:
                raise InputError(
                    f"{path}:{l1}: timestamps must increase strictly; {v1[0]!r} follows {v0[0]!r} "
                    f"(line {l0})"
                )
        a = np.array([v for _, v in rows])
        return cls(a[:, 0], a[:, 1:4], a[:, 4:8], source=str(path))

    def save(self, path: str | Path) -> None:
        """Write as TUM text with full precision."""
        with Path(path).open("w") as f:
            f.write("# timestamp tx ty tz qx qy qz qw  (T_W_B)\n")
            for t, p, q in zip(self.t_s, self.p_W, self.q_W_B, strict=True):
                f.write(f"{t:.9f} " + " ".join(f"{v:.9f}" for v in (*p, *q)) + "\n")

    @classmethod
    def from_poses(cls, t_s: np.ndarray, poses: list[Pose], source: str = "trajectory") -> TumTrajectory:
        return cls(t_s, np.array([p.t for p in poses]), np.array([rot_to_quat(p.R) for p in poses]), source)

    def covers(self, t_s: float) -> bool:
        return bool(self.t_s[0] - 1e-9 <= t_s <= self.t_s[-1] + 1e-9)

    def _segment(self, t_s: float) -> tuple[int, float]:
        if not self.covers(t_s):
            raise InputError(
                f"{self.source}: time {t_s:.6f} s is outside the trajectory's span "
                f"[{self.t_s[0]:.6f}, {self.t_s[-1]:.6f}] s"
            )
        i = min(max(int(np.searchsorted(self.t_s, t_s, side="right")) - 1, 0), len(self.t_s) - 2)
        t0, t1 = float(self.t_s[i]), float(self.t_s[i + 1])
        return i, min(max((t_s - t0) / (t1 - t0), 0.0), 1.0)

    def pose_at(self, t_s: float) -> Pose:
        i, u = self._segment(float(t_s))
        p = (1 - u) * self.p_W[i] + u * self.p_W[i + 1]
        q = slerp(self.q_W_B[i], self.q_W_B[i + 1], u)
        return Pose(quat_to_rot(q), p)

    def velocity_at(self, t_s: float) -> np.ndarray:
        i, _ = self._segment(float(t_s))
        return (self.p_W[i + 1] - self.p_W[i]) / (self.t_s[i + 1] - self.t_s[i])
