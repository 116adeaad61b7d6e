"""Per-frame ground truth of the obstacles (the lines of ``gt.jsonl``)."""

from __future__ import annotations

import numpy as np

from estimators.egomotion import EgoMotion
from estimators.rig import Rig
from estimators.se3 import Pose
from pipeline.sim.world import World, object_velocity, surface_distance


def body_velocity_W(traj: EgoMotion, t_s: float, h_s: float = 1e-3) -> np.ndarray:
    """Velocity of the body origin in W (3,) m/s by a central difference of ``traj.pose_at``
    (one-sided at the ends of the trajectory's span)."""
    t0, t1 = t_s - h_s, t_s + h_s
    if not traj.covers(t0):
        t0 = t_s
    if not traj.covers(t1):
        t1 = t_s
    if t1 <= t0:
        return traj.velocity_at(t_s)
    return (traj.pose_at(t1).t - traj.pose_at(t0).t) / (t1 - t0)


def obstacle_truth(world: World, rig: Rig, T_W_B: Pose, v_body_W: np.ndarray, t_s: float) -> list[dict]:
    """Truth of every obstacle at ``t_s`` seen from the body at ``T_W_B`` moving at ``v_body_W``.

    Per obstacle (the ``gt.jsonl`` schema): ``p_W`` centre of its bounding sphere in W (a pole: the
    middle of its axis), ``v_W`` its velocity; ``p_B`` the centre in B; ``v_B_rel`` = R_W_B^T (v_W -
    v_body_W), the velocity relative to the body expressed in B (no rotation term); ``range_m`` =
    |p_B|; ``surface_range_m`` body origin to the nearest surface point; ``bearing_body`` p_B/|p_B|;
    ``azimuth_deg`` atan2(y, x) (left positive) and ``elevation_deg`` asin(z) of that bearing;
    ``radius_m`` bounding radius; per camera ``visible`` (the centre lies in the lens's image and the
    ray from the camera centre to it hits this obstacle first) and ``pixel`` [u, v] of the centre
    (null when outside the image).
    """
    placed = world.place(t_s)
    T_B_W = T_W_B.inverse()
    o_B_W = T_W_B.t
    cams = []
    for cam in rig:
        T_W_C = T_W_B @ cam.T_C_B.inverse()
        cams.append((cam, T_W_C))
    out = []
    for pl in placed:
        c_W = pl.bound_c_W
        v_W = object_velocity(pl.spec, t_s)
        p_B = T_B_W.apply(c_W)
        rng = float(np.linalg.norm(p_B))
        b_B = p_B / rng if rng > 0 else np.array([1.0, 0.0, 0.0])
        surf = min(surface_distance(part, pl, o_B_W) for part in pl.parts)
        vis, pix = {}, {}
        for cam, T_W_C in cams:
            p_C = T_W_C.inverse().apply(c_W)
            uv, ok = cam.model.bearing_to_pixel(p_C[None])
            seen = False
            if ok[0]:
                d = c_W - T_W_C.t
                dist = float(np.linalg.norm(d))
                hits, _ = world.cast(t_s, T_W_C.t, (d / dist)[None], placed=placed)
                seen = bool(hits.object_id[0] == pl.spec.id)
            vis[cam.name] = seen
            pix[cam.name] = [float(uv[0, 0]), float(uv[0, 1])] if ok[0] else None
        out.append(
            {
                "id": int(pl.spec.id),
                "kind": pl.spec.kind,
                "moving": bool(pl.spec.moving),
                "p_W": _r(c_W),
                "v_W": _r(v_W),
                "p_B": _r(p_B),
                "v_B_rel": _r(T_W_B.R.T @ (v_W - v_body_W)),
                "range_m": round(rng, 6),
                "surface_range_m": round(surf, 6),
                "bearing_body": _r(b_B, 9),
                "azimuth_deg": round(float(np.degrees(np.arctan2(b_B[1], b_B[0]))), 6),
                "elevation_deg": round(float(np.degrees(np.arcsin(np.clip(b_B[2], -1, 1)))), 6),
                "radius_m": round(float(pl.bound_r), 6),
                "visible": vis,
                "pixel": pix,
            }
        )
    return out


def pose_record(T_W_B: Pose) -> list[float]:
    """``[tx, ty, tz, qx, qy, qz, qw]`` of a pose (TUM order)."""
    return _r(np.concatenate([T_W_B.t, T_W_B.quat_xyzw()]), 9)


def _r(a: np.ndarray, nd: int = 6) -> list[float]:
    return [round(float(x), nd) for x in np.asarray(a).ravel()]
