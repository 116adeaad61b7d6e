"""The observer's (body B) trajectory as a ``TumTrajectory`` sampled densely from closed forms."""

from __future__ import annotations

import numpy as np

from estimators.egomotion import TumTrajectory
from estimators.errors import ConfigError
from estimators.se3 import Pose, rot_x, rot_y, rot_z
from pipeline.sim.scene import ObserverSpec


def observer_pose(obs: ObserverSpec, t_s: float) -> Pose:
    """Closed-form ``T_W_B`` at ``t_s`` for the parametric observer kinds (not ``tum``).

    Heading psi(t) = psi0 + omega t (omega = yaw rate); the body flies along its heading at
    ``speed_mps`` and climbs at ``climb_rate_mps``:
      omega != 0: x = x0 + v/omega (sin psi - sin psi0), y = y0 - v/omega (cos psi - cos psi0)
      omega == 0: x = x0 + v t cos psi0,                  y = y0 + v t sin psi0
      z = z0 + climb t.
    Attitude R_W_B = Rz(psi) Ry(pitch0) Rx(roll0) (ZYX, FLU body).
    """
    s = obs.start
    psi0 = np.deg2rad(s.yaw_deg)
    w = np.deg2rad(obs.yaw_rate_deg_s)
    v = obs.speed_mps
    psi = psi0 + w * t_s
    if abs(w) > 1e-12:
        dx = v / w * (np.sin(psi) - np.sin(psi0))
        dy = -v / w * (np.cos(psi) - np.cos(psi0))
    else:
        dx = v * t_s * np.cos(psi0)
        dy = v * t_s * np.sin(psi0)
    p = np.asarray(s.position_m, float) + [dx, dy, obs.climb_rate_mps * t_s]
    R = rot_z(psi) @ rot_y(np.deg2rad(s.pitch_deg)) @ rot_x(np.deg2rad(s.roll_deg))
    return Pose(R, p)


def observer_trajectory(obs: ObserverSpec, t_end_s: float, rate_hz: float = 400.0,
                        t_start_s: float = 0.0) -> TumTrajectory:
    """``T_W_B`` samples on [t_start_s, t_end_s] (at ``rate_hz``, at least 2) as a TumTrajectory.

    Dense sampling keeps the linear/slerp interpolation of the TUM file within ~1e-5 m of the
    closed form for the turning kind (chord error v omega dt^2 / 8). For ``kind: tum`` the file is
    loaded and must cover [0, t_end_s]."""
    if obs.kind == "tum":
        traj = TumTrajectory.load(obs.tum_path)
        if not (traj.covers(t_start_s) and traj.covers(t_end_s)):
            raise ConfigError(
                f"observer.tum_path {obs.tum_path}: covers [{traj.t_s[0]:.3f}, {traj.t_s[-1]:.3f}] s; "
                f"the scenario needs [{t_start_s:.3f}, {t_end_s:.3f}] s"
            )
        return traj
    n = max(2, int(np.ceil((t_end_s - t_start_s) * rate_hz)) + 1)
    t = np.linspace(t_start_s, t_end_s, n)
    return TumTrajectory.from_poses(t, [observer_pose(obs, float(ti)) for ti in t], source="observer")
