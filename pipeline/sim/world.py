"""Scene geometry at any time, vectorised ray casting and shading.

``World`` turns a ``Scenario`` into primitives (spheres, boxes, vertical cylinders, a ground plane)
that move rigidly with their owner object. ``raycast`` and the renderer share ``World.cast``:
nearest positive hit along each ray, per-object bounding-sphere culling, numpy throughout.

Object frame O of an obstacle: origin at its reference point (``position_m`` of the scenario: the
centre, or the base centre for a pole), axes of W turned by the object's yaw about z.
Textures are solid textures of the hit point in O, so they move rigidly with the object.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from estimators.errors import InputError
from estimators.se3 import rot_z
from pipeline.sim.scene import (
    ConstantVelocityMotion,
    ObstacleSpec,
    Scenario,
    WaypointMotion,
)

SKY_ID = -1
_EPS_T = 1e-6  # metres: hits closer than this along the ray are ignored (self-hits)
_SUN_W = np.array([0.35, 0.25, 0.90]) / np.linalg.norm([0.35, 0.25, 0.90])  # light direction, W

# Navigation lights (BGR in [0, 1]; emissive, not shaded): aviation red left, green right, white tail.
NAV_RED = (0.15, 0.15, 1.0)
NAV_GREEN = (0.25, 1.0, 0.15)
NAV_WHITE = (1.0, 1.0, 1.0)


# ------------------------------------------------------------------------------------------ texture
def hash01(ix: np.ndarray, iy: np.ndarray, iz: np.ndarray, seed: int) -> np.ndarray:
    """Integer lattice cells -> pseudo-random floats in [0, 1), deterministic in (cell, seed).

    ix, iy, iz: integer arrays of one shape (any sign). Returns float32 of that shape."""
    with np.errstate(over="ignore"):
        h = (
            np.asarray(ix).astype(np.uint32) * np.uint32(73856093)  # two's-complement wrap for < 0
            ^ np.asarray(iy).astype(np.uint32) * np.uint32(19349663)
            ^ np.asarray(iz).astype(np.uint32) * np.uint32(83492791)
            ^ np.uint32((seed * 2654435761) & 0xFFFFFFFF)
        )
        # lowbias32 finaliser (Wellons): avalanche the bits
        h ^= h >> np.uint32(16)
        h *= np.uint32(0x7FEB352D)
        h ^= h >> np.uint32(15)
        h *= np.uint32(0x846CA68B)
        h ^= h >> np.uint32(16)
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(1.0 / (1 << 24))


def checker_value(q: np.ndarray, cell_m: float, seed: int, contrast: float,
                  fade: np.ndarray | None = None) -> np.ndarray:
    """Two-scale hashed checker: grey value in [0, 1] at points ``q`` (N,3) (or (N,2)), metres.

    Coarse cells of ``cell_m`` are dark or bright at random; fine cells of ``cell_m / 3`` flip a
    quarter of them, and a slow random modulation (cells of ``3 cell_m``) varies the brightness, so
    corners exist at two scales. The lattice is offset by an irrational fraction of a cell so that
    no flat face of an object lies on a cell boundary. ``fade`` (N,) in [0, 1] scales the contrast
    (used against aliasing far away).
    """
    q = np.asarray(q, dtype=np.float32)
    off = np.float32(0.3819660)  # (3 - sqrt 5) / 2
    c1 = np.floor(q * np.float32(1.0 / cell_m) + off).astype(np.int32)
    c2 = np.floor(q * np.float32(3.0 / cell_m) + off).astype(np.int32)
    c0 = np.floor(q * np.float32(1.0 / (3.0 * cell_m)) + off).astype(np.int32)

    def h(c: np.ndarray, sd: int) -> np.ndarray:  # planar textures (2 columns): third index 0
        return hash01(c[:, 0], c[:, 1], c[:, 2] if c.shape[1] == 3 else np.int32(0), sd)

    coarse = h(c1, seed) > 0.5
    flip = h(c2, seed + 1) > 0.75
    slow = 0.8 + 0.2 * h(c0, seed + 2)
    bright = coarse ^ flip
    k = np.float32(contrast) if fade is None else np.float32(contrast) * fade.astype(np.float32)
    return (0.5 + np.where(bright, 0.5, -0.5).astype(np.float32) * k) * slow


# ------------------------------------------------------------------------------------------- motion
def object_position(spec: ObstacleSpec, t_s: float) -> np.ndarray:
    """Reference point of the obstacle in W at ``t_s``: (3,) metres."""
    m = spec.motion
    if isinstance(m, ConstantVelocityMotion):
        return np.asarray(spec.position_m, float) + np.asarray(m.velocity_mps, float) * (t_s - m.t0_s)
    if isinstance(m, WaypointMotion):
        P = np.asarray(m.positions_m, float)
        return np.array([np.interp(t_s, m.times_s, P[:, k]) for k in range(3)])
    return np.asarray(spec.position_m, float)


def object_velocity(spec: ObstacleSpec, t_s: float) -> np.ndarray:
    """Velocity of the obstacle in W at ``t_s``: (3,) m/s (a waypoint path: its current segment)."""
    m = spec.motion
    if isinstance(m, ConstantVelocityMotion):
        return np.asarray(m.velocity_mps, float)
    if isinstance(m, WaypointMotion):
        T = np.asarray(m.times_s)
        if t_s < T[0] or t_s >= T[-1]:
            return np.zeros(3)
        i = int(np.searchsorted(T, t_s, side="right") - 1)
        P = np.asarray(m.positions_m, float)
        return (P[i + 1] - P[i]) / (T[i + 1] - T[i])
    return np.zeros(3)


def object_yaw_rad(spec: ObstacleSpec, t_s: float) -> float:
    """Yaw of the object frame O about W's z: fixed, except a moving drone heads along its velocity."""
    if spec.kind == "drone":
        v = object_velocity(spec, t_s)
        if np.hypot(v[0], v[1]) > 0.1:
            return float(np.arctan2(v[1], v[0]))
    return float(np.deg2rad(spec.yaw_deg))


# ------------------------------------------------------------------------------------------- parts
@dataclass(frozen=True)
class Part:
    """A primitive of an object, fixed in the object frame O.

    kind: ``sphere`` (size = (r,)), ``box`` (size = half extents (3,)), ``cyl`` (vertical cylinder,
    size = (r, height), base at ``offset_O``). offset_O: (3,) metres in O. emissive: BGR or None.
    """

    kind: str
    size: tuple[float, ...]
    offset_O: tuple[float, float, float] = (0.0, 0.0, 0.0)
    emissive: tuple[float, float, float] | None = None

    def bound(self) -> tuple[np.ndarray, float]:
        """Bounding sphere in O: centre (3,), radius (m)."""
        o = np.asarray(self.offset_O, float)
        if self.kind == "sphere":
            return o, self.size[0]
        if self.kind == "box":
            return o, float(np.linalg.norm(self.size))
        r, h = self.size
        return o + [0, 0, h / 2], float(np.hypot(r, h / 2))


def parts_of(spec: ObstacleSpec) -> list[Part]:
    """The primitives that make up an obstacle, in its object frame O."""
    if spec.kind == "sphere":
        return [Part("sphere", (spec.radius_m,))]
    if spec.kind == "pole":
        return [Part("cyl", (spec.radius_m, spec.height_m))]
    if spec.kind in ("box", "wall"):
        size = spec.size_m or (0.2, 6.0, 4.0)
        return [Part("box", tuple(0.5 * s for s in size))]
    # drone: flat body, lights at the arm tips (red its left +y, green its right -y, white tail -x)
    sx, sy, sz = spec.size_m or (0.5, 0.5, 0.12)
    lr = spec.light_radius_m
    return [
        Part("box", (sx / 2, sy / 2, sz / 2)),
        Part("sphere", (lr,), (0.0, sy / 2 + lr * 0.5, 0.0), NAV_RED),
        Part("sphere", (lr,), (0.0, -(sy / 2 + lr * 0.5), 0.0), NAV_GREEN),
        Part("sphere", (lr,), (-(sx / 2 + lr * 0.5), 0.0, 0.0), NAV_WHITE),
    ]


@dataclass
class _Placed:
    """An obstacle placed at one time: pose of O in W and its parts."""

    spec: ObstacleSpec
    p_W: np.ndarray  # (3,) reference point
    R_W_O: np.ndarray  # (3, 3)
    parts: list[Part]
    bound_c_W: np.ndarray = field(default=None)  # (3,) centre of the bounding sphere of all parts
    bound_r: float = 0.0


@dataclass
class Hits:
    """Result of casting N rays.

    t_m: (N,) distance along each (unit) ray to the nearest hit, inf for sky.
    object_id: (N,) int, the owner id (-1 sky; the ground has ``GroundSpec.id``).
    part: (N,) int, index into ``World.placed(t)`` flattened parts (-1 sky, -2 ground).
    """

    t_m: np.ndarray
    object_id: np.ndarray
    part: np.ndarray


class World:
    """The scene's geometry as a function of time, built from a ``Scenario``."""

    def __init__(self, scn: Scenario):
        self.scn = scn
        self.specs = list(scn.obstacles)
        self._parts = {s.id: parts_of(s) for s in self.specs}
        self.ground = scn.ground if scn.ground.enabled else None

    # -- placement
    def place(self, t_s: float) -> list[_Placed]:
        """Every obstacle at time ``t_s`` with its bounding sphere in W."""
        out = []
        for s in self.specs:
            p = object_position(s, t_s)
            R = rot_z(object_yaw_rad(s, t_s))
            parts = self._parts[s.id]
            cs, rs = zip(*(pt.bound() for pt in parts), strict=True)
            cs = np.array(cs)
            c_O = 0.5 * (cs.min(axis=0) + cs.max(axis=0))
            r = max(float(np.linalg.norm(c - c_O)) + ri for c, ri in zip(cs, rs, strict=True))
            out.append(_Placed(s, p, R, parts, p + R @ c_O, r))
        return out

    # -- ray casting
    def cast(self, t_s: float, o_W: np.ndarray, d_W: np.ndarray,
             placed: list[_Placed] | None = None, light_halo_rad: float = 0.0,
             cull=None) -> tuple[Hits, list]:
        """Nearest hit along rays ``o_W + t d_W`` (d_W unit, (N,3); o_W (3,) or (N,3)), at ``t_s``.

        light_halo_rad: rendering only (shared origin): emissive parts (navigation lights) are
        enlarged to subtend at least this angle in radius, so that a light smaller than a pixel
        still lights a pixel, like the bloom of a real light. 0 for ground truth.
        cull: optional ``cull(centre_W (3,), radius_m) -> ray indices or None`` (shared origin):
        a superset of the rays that can meet that sphere (None: all rays), e.g. the renderer's
        pixel tiles; the exact per-ray test then runs on those rays only.
        Returns the hits and the flat list of (placed object, part) that ``Hits.part`` indexes."""
        placed = self.place(t_s) if placed is None else placed
        N = len(d_W)
        dt = d_W.dtype
        best = np.full(N, np.inf, dtype=dt)
        part_idx = np.full(N, -1, dtype=np.int32)
        flat = []
        shared_origin = o_W.ndim == 1
        for pl in placed:
            # bounding-sphere culling: |(c - o) x d| <= r and the sphere not wholly behind
            oc = (pl.bound_c_W - o_W).astype(dt)
            halo = light_halo_rad > 0 and shared_origin and any(p.emissive for p in pl.parts)
            if shared_origin:
                dist_c = float(np.linalg.norm(oc))
                r = pl.bound_r + (light_halo_rad * (dist_c + pl.bound_r) if halo else 0.0)
                pre = None if cull is None else cull(pl.bound_c_W, r)
                dd = d_W if pre is None else d_W[pre]
                b = dd @ oc
                perp2 = dist_c * dist_c - b * b
                bb = best if pre is None else best[pre]
                cand = np.nonzero((perp2 <= r * r) & (b + r > 0) & (b - r < bb))[0]
                if pre is not None:
                    cand = pre[cand]
            else:
                b = np.einsum("ij,ij->i", d_W, oc)
                perp2 = np.einsum("ij,ij->i", oc, oc) - b * b
                cand = np.nonzero((perp2 <= pl.bound_r**2) & (b + pl.bound_r > 0))[0]
            for part in pl.parts:
                flat.append((pl, part))
                if len(cand) == 0:
                    continue
                o = o_W if shared_origin else o_W[cand]
                geom = part
                if halo and part.emissive is not None:
                    c_W = pl.p_W + pl.R_W_O @ np.asarray(part.offset_O)
                    r_eff = max(part.size[0], light_halo_rad * float(np.linalg.norm(c_W - o_W)))
                    geom = Part("sphere", (r_eff,), part.offset_O, part.emissive)
                t = _intersect_part(geom, pl, o, d_W[cand])
                closer = t < best[cand]
                idx = cand[closer]
                best[idx] = t[closer]
                part_idx[idx] = len(flat) - 1
        if self.ground is not None:
            oz = o_W[2] if shared_origin else o_W[:, 2]
            dz = d_W[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                tg = (self.ground.z_m - oz) / dz  # plane z = z_g: t = (z_g - o_z) / d_z
            hit = (tg > _EPS_T) & (tg < best)
            best[hit] = tg[hit]
            part_idx[hit] = -2
        ids = np.full(N, SKY_ID, dtype=np.int64)
        obj = part_idx >= 0
        if len(flat):
            owner = np.array([pl.spec.id for pl, _ in flat], dtype=np.int64)
            ids[obj] = owner[part_idx[obj]]
        if self.ground is not None:
            ids[part_idx == -2] = self.ground.id
        return Hits(best, ids, part_idx), flat

    # -- shading
    def shade(self, t_s: float, o_W: np.ndarray, d_W: np.ndarray, hits: Hits, flat: list,
              pix_rad: float = 0.0) -> np.ndarray:
        """BGR colour in [0, 1] (N,3) float32 of each ray: texture x Lambert at hits, sky otherwise.

        pix_rad: angular size of a pixel (rad), used to fade far textures against aliasing."""
        col = np.empty((len(d_W), 3), np.float32)
        sky = np.nonzero(hits.part == -1)[0]
        col[sky] = self._sky(d_W[sky])
        shared_origin = o_W.ndim == 1
        on_obj = np.nonzero(hits.part >= 0)[0]  # objects usually cover a small share of the rays
        part_on = hits.part[on_obj]
        for k, (pl, part) in enumerate(flat):
            idx = on_obj[part_on == k]
            if len(idx) == 0:
                continue
            if part.emissive is not None:
                col[idx] = part.emissive
                continue
            o = o_W if shared_origin else o_W[idx]
            x_W = o + hits.t_m[idx, None] * d_W[idx]
            q_O = (x_W - pl.p_W) @ pl.R_W_O  # R^T (x - p): point in the object frame
            n_O = _normal_O(part, q_O)
            n_W = n_O @ pl.R_W_O.T
            tex = pl.spec.texture
            cell = tex.cell_m or _default_cell(pl.spec)
            seed = tex.seed if tex.seed is not None else self.scn.seed * 1000 + pl.spec.id
            fade = None
            if pix_rad > 0:
                fade = _clamp(2.0 - hits.t_m[idx] * (pix_rad / (cell / 3.0) * 2.0), 0.25, 1.0)
            v = checker_value(q_O, cell, seed, tex.contrast, fade)
            lam = 0.45 + 0.55 * _clamp(n_W @ _SUN_W, 0.0, 1.0)  # Lambert with ambient
            col[idx] = (v * lam).astype(np.float32)[:, None] * np.asarray(tex.colour, np.float32)
        gidx = np.nonzero(hits.part == -2)[0]
        if len(gidx):
            g = self.ground
            o = o_W[:2] if shared_origin else o_W[gidx, :2]
            xy = o + hits.t_m[gidx, None] * d_W[gidx, :2]
            fade = None
            if pix_rad > 0:
                # footprint of a pixel on the plane grows with range and obliquity
                obl = np.maximum(np.abs(d_W[gidx, 2]), np.float32(0.05))
                foot = hits.t_m[gidx] * np.float32(pix_rad) / obl
                fade = _clamp(1.5 - foot * np.float32(1.5 / g.cell_m), 0.0, 1.0)
            v = checker_value(xy, g.cell_m, g.seed, g.contrast, fade)
            lam = 0.45 + 0.55 * float(_SUN_W[2])
            col[gidx] = (v * lam)[:, None] * np.asarray(g.colour, np.float32)
        return col

    def _sky(self, d_W: np.ndarray) -> np.ndarray:
        s = self.scn.sky
        z = d_W[:, 2:3].astype(np.float32)
        zen, hor, nad = (np.asarray(c, np.float32) for c in (s.zenith, s.horizon, s.nadir))
        # gradient horizon -> zenith above (sqrt of the elevation sine), horizon -> nadir below
        up = np.sqrt(np.maximum(z, np.float32(0)))
        down = np.sqrt(np.maximum(-z, np.float32(0)))
        return hor + (zen - hor) * up + (nad - hor) * down


def _clamp(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """np.clip without its overhead (float32 kept)."""
    return np.minimum(np.maximum(x, x.dtype.type(lo)), x.dtype.type(hi))


def _default_cell(spec: ObstacleSpec) -> float:
    """Coarse texture cell: about a quarter of the object's smallest visible extent."""
    if spec.kind == "sphere":
        return max(spec.radius_m / 2.0, 0.02)
    if spec.kind == "pole":
        return max(spec.radius_m * 1.2, 0.02)
    if spec.kind == "drone":
        return 0.1
    size = sorted(spec.size_m or (0.2, 6.0, 4.0))
    return max(min(size[1] / 4.0, 0.5), 0.02)


def _intersect_part(part: Part, pl: _Placed, o_W: np.ndarray, d_W: np.ndarray) -> np.ndarray:
    """Distance along each unit ray to ``part`` (inf on a miss), (M,). o_W (3,) or (M,3)."""
    R = pl.R_W_O
    # rays in the part's local frame (origin at the part's offset, axes of O)
    o = ((o_W - pl.p_W) @ R - np.asarray(part.offset_O)).astype(d_W.dtype)
    d = d_W @ R.astype(d_W.dtype)
    if part.kind == "sphere":
        return _ray_sphere(o, d, part.size[0])
    if part.kind == "box":
        return _ray_box(o, d, np.asarray(part.size, d.dtype))
    return _ray_cyl(o, d, part.size[0], part.size[1])


def _ray_sphere(o: np.ndarray, d: np.ndarray, r: float) -> np.ndarray:
    # |o + t d|^2 = r^2, |d| = 1:  t = -b -+ sqrt(b^2 - c), b = o.d, c = |o|^2 - r^2
    if o.ndim == 1:
        b = d @ o
        c = float(o @ o) - r * r
    else:
        b = np.einsum("ij,ij->i", o, d)
        c = np.einsum("ij,ij->i", o, o) - r * r
    disc = b * b - c
    sq = np.sqrt(np.maximum(disc, 0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > _EPS_T, t0, np.where(t1 > _EPS_T, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def _ray_box(o: np.ndarray, d: np.ndarray, h: np.ndarray) -> np.ndarray:
    # slabs |x_k| <= h_k: t in [max_k min(t1,t2), min_k max(t1,t2)]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(d == 0, 1e-30, d)
        t1 = (-h - o) * inv
        t2 = (h - o) * inv
    tmin = np.minimum(t1, t2).max(axis=1)
    tmax = np.maximum(t1, t2).min(axis=1)
    t = np.where(tmin > _EPS_T, tmin, tmax)
    return np.where((tmax >= tmin) & (tmax > _EPS_T), t, np.inf)


def _ray_cyl(o: np.ndarray, d: np.ndarray, r: float, height: float) -> np.ndarray:
    # side: (ox + t dx)^2 + (oy + t dy)^2 = r^2 with 0 <= z <= height; caps z = 0 and z = height.
    # A ray that meets a cap also meets the infinite cylinder (disc >= 0) unless it is vertical,
    # so only those rays are solved.
    o2 = np.broadcast_to(o, d.shape)
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = o2[:, 0] * d[:, 0] + o2[:, 1] * d[:, 1]
    c = o2[:, 0] ** 2 + o2[:, 1] ** 2 - r * r
    disc = b * b - a * c
    out = np.full(len(d), np.inf, dtype=d.dtype)
    sel = np.nonzero((disc >= 0) | (a < 1e-12))[0]
    if len(sel) == 0:
        return out
    a, b, disc, o2, d = a[sel], b[sel], disc[sel], o2[sel], d[sel]
    sq = np.sqrt(np.maximum(disc, 0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = []
        for tt in ((-b - sq) / a, (-b + sq) / a):
            z = o2[:, 2] + tt * d[:, 2]
            ok = (disc >= 0) & (a > 1e-12) & (tt > _EPS_T) & (z >= 0) & (z <= height)
            ts.append(np.where(ok, tt, np.inf))
        for zc in (0.0, height):
            tt = (zc - o2[:, 2]) / d[:, 2]
            x = o2[:, 0] + tt * d[:, 0]
            y = o2[:, 1] + tt * d[:, 1]
            ok = (tt > _EPS_T) & (x * x + y * y <= r * r)
            ts.append(np.where(ok, tt, np.inf))
    out[sel] = np.minimum.reduce(ts)
    return out


def _normal_O(part: Part, q_O: np.ndarray) -> np.ndarray:
    """Outward unit normals (N,3) in O at surface points ``q_O`` (N,3) of ``part``."""
    q = q_O - np.asarray(part.offset_O, q_O.dtype)
    if part.kind == "sphere":
        return q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-9)
    if part.kind == "box":
        h = np.asarray(part.size, q.dtype)
        k = np.argmax(np.abs(q) / h, axis=1)
        n = np.zeros_like(q)
        n[np.arange(len(q)), k] = np.sign(q[np.arange(len(q)), k])
        return n
    r, height = part.size
    n = np.zeros_like(q)
    rad = np.hypot(q[:, 0], q[:, 1])
    side = (r - rad) < np.minimum(np.abs(q[:, 2]), np.abs(height - q[:, 2]))  # nearer the wall than a cap
    n[side, 0] = q[side, 0] / np.maximum(rad[side], 1e-9)
    n[side, 1] = q[side, 1] / np.maximum(rad[side], 1e-9)
    n[~side, 2] = np.where(q[~side, 2] > height / 2, 1.0, -1.0)
    return n


def surface_distance(part: Part, pl: _Placed, x_W: np.ndarray) -> float:
    """Euclidean distance (m) from point ``x_W`` (3,) to the surface of ``part`` (0 inside)."""
    q = (x_W - pl.p_W) @ pl.R_W_O - np.asarray(part.offset_O)
    if part.kind == "sphere":
        return max(float(np.linalg.norm(q)) - part.size[0], 0.0)
    if part.kind == "box":
        return float(np.linalg.norm(np.maximum(np.abs(q) - np.asarray(part.size), 0.0)))
    r, height = part.size
    dr = max(float(np.hypot(q[0], q[1])) - r, 0.0)
    dz = max(-q[2], q[2] - height, 0.0)
    return float(np.hypot(dr, dz))


def raycast(
    world: World | Scenario, t_s: float, origins_W: np.ndarray, dirs_W: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Ground-truth ray casting, the renderer's own code path.

    Args:
        world: the scene, a ``World`` (reuse it for many calls) or a ``Scenario``.
        t_s: time in seconds (objects are placed at this time).
        origins_W: ray origins in W, (N,3) or (3,) metres.
        dirs_W: ray directions in W, (N,3), any non-zero length (normalised here).
    Returns:
        depth_m (N,): distance from the origin to the nearest surface along the ray, inf on sky.
        object_id (N,) int: the hit object's id, -1 for sky, the ground's id for the ground.
    """
    if isinstance(world, Scenario):
        world = World(world)
    d = np.asarray(dirs_W, dtype=float)
    if d.ndim == 1:
        d = d[None]
    if d.ndim != 2 or d.shape[1] != 3:
        raise InputError(f"raycast: dirs_W must be (N,3), got {np.shape(dirs_W)}")
    n = np.linalg.norm(d, axis=1, keepdims=True)
    if np.any(~np.isfinite(n)) or np.any(n < 1e-12):
        raise InputError("raycast: dirs_W must be finite and non-zero")
    o = np.asarray(origins_W, dtype=float)
    if o.shape not in ((3,), d.shape):
        raise InputError(f"raycast: origins_W must be (3,) or {d.shape}, got {o.shape}")
    hits, _ = world.cast(float(t_s), o, d / n)
    return hits.t_m, hits.object_id
