"""The simulator's geometry against closed forms (ray-sphere, ray-plane, slabs, a pole's azimuth)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from estimators.errors import ConfigError, InputError
from estimators.se3 import Pose, rot_z
from pipeline.sim.rigs import build_rig, default_model
from pipeline.sim.scene import scenario_from_dict
from pipeline.sim.world import SKY_ID, World, raycast
from pipeline.sim.writer import Simulation

R_C_B_FWD = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])  # forward mount, by hand


def _scn(obstacles, ground=None, **kw):
    d = {"name": "t", "obstacles": obstacles, "ground": ground or {"enabled": False}}
    d.update(kw)
    return scenario_from_dict(d)


# ------------------------------------------------------------------------------------- raycast
def test_raycast_sphere_closed_form():
    c, R = np.array([7.0, -1.0, 2.5]), 1.3
    w = World(_scn([{"id": 3, "kind": "sphere", "radius_m": R, "position_m": c.tolist()}]))
    rng = np.random.default_rng(0)
    o = np.array([0.5, 0.2, 2.0])
    # rays towards random points of the sphere's disc, plus some that miss
    aim = c + rng.normal(size=(200, 3)) * 0.9
    d = aim - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    depth, ids = raycast(w, 0.0, o, d)
    # closed form: |o + t d - c| = R  ->  t = (d.(c-o)) - sqrt((d.(c-o))^2 - |c-o|^2 + R^2)
    b = d @ (c - o)
    disc = b * b - np.sum((c - o) ** 2) + R * R
    hit = disc >= 0
    assert hit.sum() > 50 and (~hit).sum() > 5
    np.testing.assert_allclose(depth[hit], b[hit] - np.sqrt(disc[hit]), rtol=0, atol=1e-9)
    assert np.all(ids[hit] == 3) and np.all(ids[~hit] == SKY_ID) and np.all(np.isinf(depth[~hit]))


def test_raycast_ground_plane_and_sky():
    w = World(_scn([], ground={"z_m": -0.5, "id": 0}))
    o = np.array([1.0, 2.0, 3.0])
    d = np.array([[0.3, 0.1, -1.0], [0.0, 1.0, -0.2], [1.0, 0.0, 0.1], [0.0, 0.0, 1.0]])
    depth, ids = raycast(w, 0.0, np.tile(o, (4, 1)), d)
    dn = d / np.linalg.norm(d, axis=1, keepdims=True)
    t_expect = (-0.5 - 3.0) / dn[:2, 2]  # z_o + t d_z = z_ground
    np.testing.assert_allclose(depth[:2], t_expect, atol=1e-9)
    assert ids.tolist() == [0, 0, SKY_ID, SKY_ID]


def test_raycast_rotated_box_face():
    yaw = np.deg2rad(30.0)
    c = np.array([10.0, 4.0, 1.0])
    size = [2.0, 3.0, 1.0]
    w = World(_scn([{"id": 9, "kind": "box", "size_m": size, "position_m": c.tolist(), "yaw_deg": 30.0}]))
    n_W = rot_z(yaw) @ np.array([-1.0, 0.0, 0.0])  # outward normal of the box's -x face
    # from 5 m in front of that face, straight at it, with offsets inside the face
    R = rot_z(yaw)
    offs = np.array([[0, 0, 0], [0, 1.2, 0.3], [0, -1.4, -0.45]], float)
    o = c + 1.0 * n_W + 5.0 * n_W + offs @ R.T
    depth, ids = raycast(w, 0.0, o, np.tile(-n_W, (3, 1)))
    np.testing.assert_allclose(depth, 5.0, atol=1e-9)  # the face lies 1 m (half of 2 m) from c
    assert np.all(ids == 9)
    # an oblique ray: t = (distance to the face plane) / cos(angle to the normal)
    d = -n_W * np.cos(0.2) + R @ np.array([0, 1.0, 0]) * np.sin(0.2)
    depth, _ = raycast(w, 0.0, c + 6.0 * n_W, d[None])
    np.testing.assert_allclose(depth, 5.0 / np.cos(0.2), atol=1e-9)


def test_raycast_pole_side_and_top():
    w = World(_scn([{"id": 4, "kind": "pole", "radius_m": 0.25, "height_m": 5.0, "position_m": [6, 0, 0]}]))
    o = np.array([0.0, 0.0, 2.0])
    depth, ids = raycast(w, 0.0, o, np.array([[1.0, 0, 0]]))
    np.testing.assert_allclose(depth, 6.0 - 0.25, atol=1e-9)
    # looking down onto the top cap from above it
    depth, ids = raycast(w, 0.0, np.array([6.1, 0.0, 9.0]), np.array([[0, 0, -1.0]]))
    np.testing.assert_allclose(depth, 4.0, atol=1e-9)
    assert ids.tolist() == [4]


def test_raycast_moving_sphere_follows_its_velocity():
    w = World(
        _scn(
            [
                {
                    "id": 2,
                    "kind": "sphere",
                    "radius_m": 0.5,
                    "position_m": [10, 0, 0],
                    "motion": {"kind": "constant_velocity", "velocity_mps": [-2.0, 1.0, 0.0]},
                }
            ]
        )
    )
    for t in (0.0, 1.0, 2.5):
        c = np.array([10 - 2 * t, t, 0.0])
        depth, ids = raycast(w, t, np.zeros(3), (c / np.linalg.norm(c))[None])
        np.testing.assert_allclose(depth, np.linalg.norm(c) - 0.5, atol=1e-9)


def test_raycast_rejects_bad_input():
    w = World(_scn([]))
    with pytest.raises(InputError, match="dirs_W"):
        raycast(w, 0.0, np.zeros(3), np.zeros((2, 2)))
    with pytest.raises(InputError, match="non-zero"):
        raycast(w, 0.0, np.zeros(3), np.zeros((1, 3)))


def test_scenario_errors_are_clear():
    with pytest.raises(ConfigError, match="radius_m"):
        _scn([{"id": 1, "kind": "sphere"}])
    with pytest.raises(ConfigError, match="unique"):
        _scn([{"id": 1, "kind": "sphere", "radius_m": 1}, {"id": 1, "kind": "sphere", "radius_m": 1}])
    with pytest.raises(ConfigError, match="colour_typo"):
        _scn([{"id": 1, "kind": "sphere", "radius_m": 1, "colour_typo": 3}])


# ---------------------------------------------------------------------------- rendered geometry
def _mono_sim(obstacles, res=(320, 240), observer=None, model="kannala_brandt"):
    d = {
        "name": "g",
        "obstacles": obstacles,
        "ground": {"enabled": False},
        "rig": {"kind": "mono", "resolution": list(res), "model": {"name": model}},
    }
    if observer:
        d["observer"] = observer
    return Simulation(scenario_from_dict(d), n_frames=61)


@pytest.mark.parametrize(
    "c_B,model",
    [
        ((8.0, 0.0, 0.0), "kannala_brandt"),
        ((5.0, 2.0, -1.0), "kannala_brandt"),
        ((-0.4, 4.0, 0.3), "kannala_brandt"),  # ~96 deg off the optical axis
        ((4.0, -3.0, 1.0), "double_sphere"),
    ],
)
def test_sphere_mask_is_the_cone_of_half_angle_asin_R_over_d(c_B, model):
    R = 0.6
    start = np.array([0.0, 0.0, 2.0])
    c_W = start + np.asarray(c_B)
    sim = _mono_sim([{"id": 1, "kind": "sphere", "radius_m": R, "position_m": c_W.tolist()}], model=model)
    cam = sim.rig[0]
    depth, ids = sim.renderer.depth(cam.name, sim.traj.pose_at(0.0), 0.0)
    mask = ids == 1
    H, W = mask.shape
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    b_C, ok = cam.model.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1))
    cen_C = R_C_B_FWD @ np.asarray(c_B)  # camera at the body origin
    d = np.linalg.norm(cen_C)
    ang = np.arccos(np.clip(b_C @ (cen_C / d), -1, 1)).reshape(H, W)
    half = np.arcsin(R / d)  # apparent angular radius of a sphere
    pix = 2.0 * np.max(_pixel_angle(cam.model))  # angular pixel size (generous: edge of the lens)
    okm = ok.reshape(H, W)
    assert mask.sum() > 20
    assert np.all(ang[mask] <= half + 1e-9)  # every sphere pixel's ray is inside the cone
    inner = okm & (ang < half - pix)
    assert inner.sum() > 5 and np.all(mask[inner])  # every pixel well inside the cone sees it
    # measured apparent radius: the largest angle among the sphere's pixels
    assert abs(ang[mask].max() - half) < pix


def _pixel_angle(model):
    cx, cy, r = model.image_circle()
    uv = np.array([[cx + 0.9 * r, cy], [cx + 0.9 * r + 1, cy]])
    b, _ = model.pixel_to_bearing(uv)
    return np.array([np.arccos(np.clip(b[0] @ b[1], -1, 1))])


def test_sphere_centre_pixel_matches_cv2_fisheye():
    # cv2.fisheye projects the sphere's centre; the mask's centroid agrees within ~1 px near the axis
    R, c_B = 0.8, np.array([10.0, 1.5, 1.0])
    sim = _mono_sim(
        [{"id": 1, "kind": "sphere", "radius_m": R, "position_m": (c_B + [0, 0, 2]).tolist()}], res=(640, 480)
    )
    m = sim.rig[0].model
    _, ids = sim.renderer.depth("cam0", sim.traj.pose_at(0.0), 0.0)
    vv, uu = np.nonzero(ids == 1)
    K = np.array([[m.fx, 0, m.cx], [0, m.fy, m.cy], [0, 0, 1.0]])
    D = np.array([m.k1, m.k2, m.k3, m.k4])
    p_C = (R_C_B_FWD @ c_B).reshape(1, 1, 3)
    uv, _ = cv2.fisheye.projectPoints(p_C, np.zeros(3), np.zeros(3), K, D)
    np.testing.assert_allclose([uu.mean(), vv.mean()], uv.reshape(2), atol=1.0)


def test_pole_azimuth_over_a_straight_flight():
    x0, y0, v = 12.0, 3.0, 4.0
    pole = {"id": 7, "kind": "pole", "radius_m": 0.2, "height_m": 6.0, "position_m": [x0, y0, 0.0]}
    sim = _mono_sim(
        [pole],
        res=(640, 480),
        observer={"kind": "straight", "speed_mps": v, "start": {"position_m": [0.0, 0.0, 2.0]}},
    )
    cam = sim.rig[0]
    m = cam.model
    row = int(round(m.cy))  # the image row of elevation 0 (cy is on a pixel centre here)
    pix = _pixel_angle(m)[0]
    for t in (0.0, 0.5, 1.0, 1.5):
        _, ids = sim.renderer.depth("cam0", sim.traj.pose_at(t), t)
        cols = np.nonzero(ids[row] == 7)[0]
        assert len(cols) >= 2
        b, _ = m.pixel_to_bearing(np.stack([cols.astype(float), np.full(len(cols), float(row))], 1))
        b_B = b @ R_C_B_FWD  # C -> B
        az = np.arctan2(b_B[:, 1], b_B[:, 0])
        # the pole's tangent rays are symmetric about its centre: the midpoint of the extremes
        measured = 0.5 * (az.min() + az.max())
        expected = np.arctan2(y0, x0 - v * t)  # closed form for a straight, level flight
        assert abs(measured - expected) < 1.5 * pix, (t, measured, expected)
        _, obs = sim.truth(t)
        assert abs(np.deg2rad(obs[0]["azimuth_deg"]) - expected) < 1e-6


def test_default_lens_fits_inside_the_frame():
    for name in ("kannala_brandt", "double_sphere", "eucm", "equidistant"):
        m = default_model(name, 1280, 720)
        cx, cy, r = m.image_circle()
        assert r < 360 and r > 300 and abs(np.rad2deg(m.max_angle_rad) - 97.5) < 1e-6


def test_rig_resolution_override_scales_the_lens():
    scn = scenario_from_dict({"name": "r", "rig": {"kind": "stereo", "resolution": [1280, 720]}})
    big = build_rig(scn.rig)
    small = build_rig(scn.rig, (640, 360))
    assert (small[1].model.width, small[1].model.height) == (640, 360)
    assert abs(small[0].model.fx - big[0].model.fx / 2) < 1e-9
    assert np.allclose(small[1].T_C_B.inverse().t, [0, -0.15, 0])
    with pytest.raises(ConfigError, match="aspect"):
        build_rig(scn.rig, (640, 480))


def test_forward_mount_by_hand():
    # the rig's forward mount equals the hand-written rotation (optical z = body x, image x = -y)
    scn = scenario_from_dict({"name": "r"})
    np.testing.assert_allclose(build_rig(scn.rig)[0].T_C_B.R, R_C_B_FWD)
    assert Pose(R_C_B_FWD, np.zeros(3)).apply([1.0, 0, 0])[2] == 1.0


def test_drone_lights_red_left_green_right_white_tail():
    # a drone flying away along +x, 4 m ahead: we see its tail (white) in the middle, its left
    # (red, +y) on the image's left and its right (green) on the image's right
    drone = {
        "id": 1,
        "kind": "drone",
        "position_m": [4.0, 0.0, 2.3],
        "light_radius_m": 0.06,
        "motion": {"kind": "constant_velocity", "velocity_mps": [2.0, 0.0, 0.0]},
    }
    sim = _mono_sim([drone], res=(640, 480))
    img = sim.render("cam0", 0.0).astype(int)
    b, g, r = img[..., 0], img[..., 1], img[..., 2]
    red = np.argwhere((r > 200) & (g < 80) & (b < 80))
    green = np.argwhere((g > 200) & (r < 100) & (b < 80))
    white = np.argwhere((r > 240) & (g > 240) & (b > 240))
    assert len(red) and len(green) and len(white)
    cx = sim.rig[0].model.cx
    assert red[:, 1].mean() < cx - 3 < cx + 3 < green[:, 1].mean()
    assert abs(white[:, 1].mean() - cx) < 3


def test_stereo_right_camera_sees_from_its_own_centre():
    # cam1 of a 0.30 m forward pair sits at body y = -0.15: a sphere's pixels in cam1 are exactly
    # the rays from (0, -0.15, 0) within asin(R/d) of the direction to the centre
    R, c_B = 0.4, np.array([3.0, 0.5, 0.2])
    scn = scenario_from_dict(
        {
            "name": "s",
            "ground": {"enabled": False},
            "rig": {"kind": "stereo", "baseline_m": 0.3, "resolution": [320, 240]},
            "obstacles": [
                {"id": 1, "kind": "sphere", "radius_m": R, "position_m": (c_B + [0, 0, 2.0]).tolist()}
            ],
        }
    )
    sim = Simulation(scn, n_frames=2)
    cam = sim.rig[1]
    _, ids = sim.renderer.depth(cam.name, sim.traj.pose_at(0.0), 0.0)
    H, W = ids.shape
    u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    b_C, _ = cam.model.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1))
    rel_C = R_C_B_FWD @ (c_B - np.array([0.0, -0.15, 0.0]))
    d = np.linalg.norm(rel_C)
    ang = np.arccos(np.clip(b_C @ (rel_C / d), -1, 1)).reshape(H, W)
    half = np.arcsin(R / d)
    mask = ids == 1
    assert mask.sum() > 20 and np.all(ang[mask] <= half + 1e-9)
    assert np.all(mask[ang < half - 2 * _pixel_angle(cam.model)[0]])


def test_tile_culling_loses_no_hit():
    # the renderer culls objects per pixel tile; its ids and depths must equal uncut ray casting
    rng = np.random.default_rng(3)
    obs = [
        {
            "id": i + 1,
            "kind": "sphere",
            "radius_m": float(rng.uniform(0.05, 1.0)),
            "position_m": [float(rng.uniform(-6, 12)), float(rng.uniform(-8, 8)), float(rng.uniform(0.5, 5))],
        }
        for i in range(25)
    ]
    obs += [
        {"id": 40, "kind": "pole", "radius_m": 0.1, "height_m": 9.0, "position_m": [0.8, 0.6, 0.0]},
        {"id": 41, "kind": "wall", "position_m": [-0.5, -3.0, 2.0]},
        {"id": 42, "kind": "drone", "position_m": [3.0, -0.4, 2.1], "light_radius_m": 0.01},
    ]
    scn = scenario_from_dict(
        {
            "name": "c",
            "obstacles": obs,
            "rig": {"resolution": [200, 150]},
            "observer": {"kind": "turning", "speed_mps": 2, "yaw_rate_deg_s": 40},
        }
    )
    sim = Simulation(scn, n_frames=20)
    cam = sim.rig[0]
    for t in (0.0, 0.4):
        T_W_B = sim.traj.pose_at(t)
        depth, ids = sim.renderer.depth("cam0", T_W_B, t)
        T_W_C = T_W_B @ cam.T_C_B.inverse()
        H, W = ids.shape
        u, v = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
        b_C, ok = cam.model.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1))
        d_ref, id_ref = raycast(sim.world, t, T_W_C.t, T_W_C.rotate(b_C[ok]))
        assert len(np.unique(id_ref)) > 10
        np.testing.assert_array_equal(ids.ravel()[ok], id_ref)
        fin = np.isfinite(d_ref)
        np.testing.assert_allclose(depth.ravel()[ok][fin], d_ref[fin], rtol=1e-4)
