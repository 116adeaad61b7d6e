"""Synthetic fisheye scenes for the front-end tests, rendered through a camera model.

The world is a textured sphere at infinity (a random blocky texture indexed by direction); optional
textured discs (patches) sit on it at directions that can move. Every pixel's colour is the texture
at its bearing (camera model ``pixel_to_bearing``), rotated into the world, so features at any angle
off-axis (beyond 90 degrees too) appear where the model says. Expected motions in the tests come
from the rotations and patch directions given here, not from the code under test.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
import pytest

from estimators.cameras import Equidistant
from estimators.rig import mono_forward_rig


def equidistant(
    width: int = 320, height: int = 240, fov_deg: float = 200.0, fill: float = 0.47
) -> Equidistant:
    """An equidistant fisheye whose lens circle (radius ``fill * height``) holds ``fov_deg``."""
    half = np.radians(fov_deg / 2)
    f = fill * height / half
    return Equidistant(
        fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height, max_angle_rad=half
    )


def blocky_texture(size: int, cells: int, seed: int) -> np.ndarray:
    """(size, size) uint8 random blocks with some blur: corners everywhere, no periodicity."""
    rng = np.random.default_rng(seed)
    small = (rng.random((cells, cells)) * 200 + 30).astype(np.uint8)
    img = cv2.resize(small, (size, size), interpolation=cv2.INTER_NEAREST)
    return cv2.GaussianBlur(img, (0, 0), 1.0)


def tangent_basis(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to unit d (3,) and to each other."""
    a = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(a, d)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(d, e1)


@dataclass
class Patch:
    """A textured disc on the sky sphere: centre direction d_W (3,), angular radius, own texture."""

    d_W: np.ndarray
    radius_rad: float
    seed: int = 5
    texture: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        self.d_W = np.asarray(self.d_W, float) / np.linalg.norm(self.d_W)
        if self.texture is None:
            self.texture = blocky_texture(256, 8, self.seed)


class SphereScene:
    """Renders grey fisheye frames of a textured environment sphere plus patches.

    Args:
        model: camera model; seed: environment texture seed; blank_env: a flat grey environment
            (so only the patches have texture).
    """

    def __init__(self, model, seed: int = 1, blank_env: bool = False) -> None:
        self.model = model
        h, w = model.height, model.width
        v, u = np.mgrid[0:h, 0:w]
        uv = np.stack([u.ravel(), v.ravel()], 1).astype(float)
        b, ok = model.pixel_to_bearing(uv)
        self.b_C = b
        self.ok = ok
        self.env = None if blank_env else blocky_texture(1024, 64, seed)

    def render(self, R_W_C: np.ndarray | None = None, patches: list[Patch] = ()) -> np.ndarray:
        """(H, W) uint8 frame of the camera with orientation R_W_C (b_W = R_W_C b_C)."""
        R = np.eye(3) if R_W_C is None else np.asarray(R_W_C)
        h, w = self.model.height, self.model.width
        bW = self.b_C @ R.T
        out = np.full(h * w, 128, np.float32)
        if self.env is not None:
            az = np.arctan2(bW[:, 0], bW[:, 2])  # [-pi, pi]
            el = np.arcsin(np.clip(bW[:, 1], -1, 1))  # [-pi/2, pi/2]
            mx = ((az + np.pi) / (2 * np.pi) * 1023).astype(np.float32)
            my = ((el + np.pi / 2) / np.pi * 1023).astype(np.float32)
            out = (
                cv2.remap(self.env, mx.reshape(h, w), my.reshape(h, w), cv2.INTER_LINEAR)
                .reshape(-1)
                .astype(np.float32)
            )
        for p in patches:
            e1, e2 = tangent_basis(p.d_W)
            inside = (bW @ p.d_W) > np.cos(p.radius_rad)
            x = (bW[inside] @ e1) / np.sin(p.radius_rad)  # in [-1, 1] over the disc
            y = (bW[inside] @ e2) / np.sin(p.radius_rad)
            s = p.texture.shape[0] - 1
            mx = np.zeros(h * w, np.float32)
            my = np.zeros(h * w, np.float32)
            mx[inside] = (x + 1) / 2 * s
            my[inside] = (y + 1) / 2 * s
            val = cv2.remap(p.texture, mx.reshape(h, w), my.reshape(h, w), cv2.INTER_LINEAR).reshape(-1)
            out[inside] = val[inside]
        out[~self.ok] = 0
        return out.reshape(h, w).astype(np.uint8)


def rot_axis(axis, angle_rad: float) -> np.ndarray:
    """Rotation matrix about a unit axis (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


def turned_pair_rig(model, turn_deg: float = 3.0):
    """(rig, R_1_0): two cameras with one centre, cam1 = cam0 (forward) turned turn_deg about the
    camera y axis, so a world point at infinity seen along b_0 by cam0 is seen along
    b_1 = R_1_0 b_0 by cam1 (render cam1's frame with ``SphereScene.render(R_1_0.T, ...)``)."""
    from estimators.rig import Camera, Rig, forward_T_C_B
    from estimators.se3 import Pose

    R_1_0 = rot_axis([0, 1, 0], np.radians(turn_deg)).T  # b_1 = R_1_0 b_0
    T0 = forward_T_C_B()
    T1 = Pose(R_1_0 @ np.asarray(T0.R), R_1_0 @ np.asarray(T0.t))  # T_C1_B = R_1_0 T_C0_B
    return Rig((Camera("cam0", model, T0), Camera("cam1", model, T1))), R_1_0


def assert_same_feature_tracks(oa, ob) -> None:
    """Two front ends' observations of one frame are the same feature tracks: ids, statuses, labels,
    and every view's bearings and feature ids, bit for bit."""
    assert [(o.track_id, o.status, o.label) for o in oa] == [(o.track_id, o.status, o.label) for o in ob]
    for x, y in zip(oa, ob, strict=True):
        for vx, vy in zip(x.views, y.views, strict=True):
            np.testing.assert_array_equal(vx.b_C, vy.b_C)
            np.testing.assert_array_equal(vx.feature_ids, vy.feature_ids)


@pytest.fixture
def model():
    return equidistant()


@pytest.fixture
def rig(model):
    return mono_forward_rig(model)
