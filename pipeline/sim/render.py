"""Per-pixel ray-casting renderer through the project's camera models (no dewarping).

Each camera's unit bearings ``b_C`` are computed once for every pixel centre with
``model.pixel_to_bearing``; pixels outside the lens circle stay black. Per frame the bearings are
rotated to W with ``T_W_C = T_W_B @ T_C_B.inverse()`` and cast into the ``World`` (float32 rays,
bounding-sphere culling per object), shaded by texture x Lambert, sky gradient elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.se3 import Pose
from pipeline.sim.world import Hits, World


@dataclass
class _CamRays:
    name: str
    width: int
    height: int
    T_C_B: Pose
    valid_idx: np.ndarray  # (M,) flat pixel indices inside the lens circle
    b_C: np.ndarray  # (M,3) float32 unit bearings of those pixels, C
    pix_rad: float  # angular size of a pixel near the image centre, rad
    sub_b_C: list[np.ndarray]  # supersampling: (M,3) bearings at s x s sub-pixel offsets (empty: s = 1)
    tile_start: np.ndarray  # (T,) first ray of each pixel tile (rays are ordered by tile)
    tile_len: np.ndarray  # (T,) rays per tile
    tile_axis_C: np.ndarray  # (T,3) unit mean bearing of each tile, C
    tile_half_rad: np.ndarray  # (T,) largest angle between a tile's axis and its rays (+ a pixel)


def _camera_rays(cam, supersample: int = 1) -> _CamRays:
    """Precompute the bearings of every pixel centre of ``cam`` (``Camera``: name, model, T_C_B),
    and with ``supersample`` s > 1 those of an s x s grid inside each pixel (a sub-sample outside
    the lens falls back to the pixel centre)."""
    m = cam.model
    W, H = int(m.width), int(m.height)
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    b, ok = m.pixel_to_bearing(uv)
    idx = np.nonzero(ok)[0]
    b_C = b[idx].astype(np.float32)
    cx, cy, _ = m.image_circle()
    bb, okc = m.pixel_to_bearing(np.array([[cx, cy], [cx + 1.0, cy]]))
    pix = float(np.arccos(np.clip(bb[0] @ bb[1], -1, 1))) if okc.all() else 1.0 / max(W, H)
    # pixel tiles for culling: order the rays tile by tile so that each tile is a contiguous range
    T = TILE_PX
    ntx = (W + T - 1) // T
    tile = (idx // W) // T * ntx + (idx % W) // T
    order = np.argsort(tile, kind="stable")
    idx, b_C, tile = idx[order], b_C[order], tile[order]
    _, start, count = np.unique(tile, return_index=True, return_counts=True)
    axis = np.add.reduceat(b_C.astype(np.float64), start, axis=0)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    cosang = np.einsum("ij,ij->i", b_C, np.repeat(axis, count, axis=0).astype(np.float32))
    half = np.arccos(np.clip(np.minimum.reduceat(cosang, start), -1.0, 1.0)) + 2.0 * pix
    subs = []
    if supersample > 1:
        offs = (np.arange(supersample) + 0.5) / supersample - 0.5  # sub-pixel centres in (-0.5, 0.5)
        for dv in offs:
            for du in offs:
                bs, oks = m.pixel_to_bearing(uv[idx] + [du, dv], within_image=False)
                bs = bs.astype(np.float32)
                bs[~oks] = b_C[~oks]
                subs.append(bs)
    return _CamRays(cam.name, W, H, cam.T_C_B, idx, b_C, pix, subs, start, count, axis, half)


TILE_PX = 16  # side of the pixel tiles used to cull objects


def _tile_culler(cr: _CamRays, T_W_C: Pose):
    """``cull(c_W, r)`` for World.cast: the rays of the tiles whose cone (axis, half angle) meets
    the cone of the sphere seen from the camera centre: angle(axis, c - o) <= half + asin(r/|c - o|)."""
    axes_W = cr.tile_axis_C @ T_W_C.R.T
    o = T_W_C.t

    def cull(c_W: np.ndarray, r: float):
        v = np.asarray(c_W, float) - o
        dist = float(np.linalg.norm(v))
        if dist <= r * 1.0001:
            return None  # the camera is inside the bounding sphere: every ray
        lim = cr.tile_half_rad + np.arcsin(r / dist)
        ok = axes_W @ (v / dist) >= np.cos(np.minimum(lim, np.pi))
        sel = np.nonzero(ok)[0]
        if len(sel) == 0:
            return np.zeros(0, np.int64)
        lens = cr.tile_len[sel]
        # concatenated ranges [start, start + len) of the selected tiles
        offs = np.repeat(cr.tile_start[sel] - np.concatenate([[0], np.cumsum(lens)[:-1]]), lens)
        return offs + np.arange(int(lens.sum()))

    return cull


class Renderer:
    """Renders the cameras of a rig in a ``World``.

    Args:
        world: the scene.
        cameras: iterable of cameras with ``name``, ``model`` (a ``CameraModel``) and ``T_C_B``.
        supersample: s x s rays per pixel, averaged (anti-aliasing; s^2 times the cost).
    """

    def __init__(self, world: World, cameras, supersample: int = 1):
        self.world = world
        self.cams = {c.name: _camera_rays(c, supersample) for c in cameras}

    def cast_camera(self, name: str, T_W_B: Pose, t_s: float,
                    halo: bool = False) -> tuple[Hits, np.ndarray, np.ndarray, list]:
        """Cast the valid pixels' rays of camera ``name`` at body pose ``T_W_B``, time ``t_s``.

        halo: give navigation lights a radius of at least one pixel (images only; see World.cast).
        Returns (hits, o_W (3,) camera centre, d_W (M,3) float32 ray directions, flat parts)."""
        cr = self.cams[name]
        T_W_C = T_W_B @ cr.T_C_B.inverse()
        d_W = cr.b_C @ T_W_C.R.T.astype(np.float32)  # d_W = R_W_C b_C for each row
        o_W = T_W_C.t
        hits, flat = self.world.cast(t_s, o_W, d_W, light_halo_rad=cr.pix_rad if halo else 0.0,
                                     cull=_tile_culler(cr, T_W_C))
        return hits, o_W, d_W, flat

    def render_float(self, name: str, T_W_B: Pose, t_s: float) -> np.ndarray:
        """Linear BGR image (H, W, 3) float32 in [0, 1]; black outside the lens circle."""
        cr = self.cams[name]
        if cr.sub_b_C:
            T_W_C = T_W_B @ cr.T_C_B.inverse()
            R = T_W_C.R.T.astype(np.float32)
            placed = self.world.place(t_s)
            cull = _tile_culler(cr, T_W_C)
            col = None
            sub_pix = cr.pix_rad / len(cr.sub_b_C) ** 0.5  # a sub-sample's angular size
            for b_C in cr.sub_b_C:
                d_W = b_C @ R
                hits, flat = self.world.cast(t_s, T_W_C.t, d_W, placed=placed, light_halo_rad=cr.pix_rad,
                                             cull=cull)
                c = self.world.shade(t_s, T_W_C.t, d_W, hits, flat, pix_rad=sub_pix)
                col = c if col is None else col + c
            col /= np.float32(len(cr.sub_b_C))
        else:
            hits, o_W, d_W, flat = self.cast_camera(name, T_W_B, t_s, halo=True)
            col = self.world.shade(t_s, o_W, d_W, hits, flat, pix_rad=cr.pix_rad)
        img = np.zeros((cr.height * cr.width, 3), np.float32)
        img[cr.valid_idx] = col
        return img.reshape(cr.height, cr.width, 3)

    def depth(self, name: str, T_W_B: Pose, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-pixel range from the camera centre (H, W) metres (inf on sky or outside the lens)
        and object id (H, W) (-1 sky, -2 outside the lens)."""
        cr = self.cams[name]
        hits, _, _, _ = self.cast_camera(name, T_W_B, t_s)
        depth = np.full(cr.height * cr.width, np.inf, np.float32)
        ids = np.full(cr.height * cr.width, -2, np.int64)
        depth[cr.valid_idx] = hits.t_m
        ids[cr.valid_idx] = hits.object_id
        return depth.reshape(cr.height, cr.width), ids.reshape(cr.height, cr.width)


def to_uint8(img: np.ndarray, gain: float = 1.0, noise_sigma: float = 0.0,
             rng: np.random.Generator | None = None, mask: np.ndarray | None = None) -> np.ndarray:
    """Float image in [0, 1] -> uint8 with ``gain`` and Gaussian noise of ``noise_sigma`` grey levels.

    mask: (H, W) bool of the lens circle; noise is added inside it only (outside stays black)."""
    import cv2

    x = img * np.float32(255.0 * gain)
    if noise_sigma > 0:
        rng = rng or np.random.default_rng(0)
        n = rng.standard_normal(size=x.shape, dtype=np.float32)
        n *= np.float32(noise_sigma)
        if mask is not None:
            n *= mask[..., None] if x.ndim == 3 else mask
        x += n
        np.maximum(x, np.float32(0), out=x)
    return cv2.convertScaleAbs(x)  # round half to even-free, saturating to [0, 255]


def lens_mask(renderer: Renderer, name: str) -> np.ndarray:
    """(H, W) bool: True at pixels inside the lens circle of camera ``name``."""
    cr = renderer.cams[name]
    m = np.zeros(cr.height * cr.width, bool)
    m[cr.valid_idx] = True
    return m.reshape(cr.height, cr.width)
