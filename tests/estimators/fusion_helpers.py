"""Helpers shared by the fusion tests (not a test module)."""

from __future__ import annotations

import numpy as np


def noisy_bearing(rng, sigma):
    """bearing(cam, T_W_B, p_W): the unit bearing (3,) of world point p_W (m) in camera cam at body
    pose T_W_B, turned by isotropic tangent noise of sigma rad drawn from rng."""

    def bearing(cam, T_W_B, p_W):
        p_C = (cam.T_C_B @ T_W_B.inverse()).apply(p_W)
        b = p_C / np.linalg.norm(p_C)
        e = rng.normal(scale=sigma, size=3)
        b = b + e - (e @ b) * b
        return b / np.linalg.norm(b)

    return bearing
