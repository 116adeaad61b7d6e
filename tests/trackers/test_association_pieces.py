"""Pieces (trackers/association.py): a camera's second track on an obstacle that a two-camera track
covers joins it when its members triangulate at that track's depth. Expected values are worked by
hand on a rig whose second camera sits 0.3 m beside the first (R = I): the rays of a point on the
first camera's optical axis meet there, and the depth's sensitivity to each ray's angle follows
from the triangle's closed form."""

from __future__ import annotations

import numpy as np
import pytest

from trackers.association import (
    informative,
    piece_agrees,
    point_bearings,
    ray_depths,
    surface_agreement,
)

B = 0.3  # m: camera b's centre at (B, 0, 0) in C_a, so p_Cb = p_Ca + t with t = (-B, 0, 0)
R = np.eye(3)
T = np.array([-B, 0.0, 0.0])


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_ray_depths_meet_on_the_axis_with_the_triangles_sensitivity():
    """A point at z = 4 m on a's axis: b sees it along (-B, 0, 4). Ray b's angle theta to the
    axis (tan theta = B / z) gives z = B / tan(theta + delta): dz/ddelta = -B (1 + tan^2) / tan^2;
    ray a tilted by delta towards +x meets ray b (x = B - z B / 4) at s = B / (sin delta +
    (B / 4) cos delta): ds/ddelta = -B / (B / 4)^2. With both rays of sigma 1 mrad, the depth's
    sigma is 1e-3 hypot of the two."""
    z = 4.0
    b_a = np.array([[0.0, 0.0, 1.0]])
    b_b = unit([[-B, 0.0, z]])
    d, s, ok = ray_depths(b_a, b_b, R, T, 1e-3)
    tan = B / z
    expected = 1e-3 * np.hypot(B * (1 + tan**2) / tan**2, B / tan**2)
    assert ok[0]
    assert d[0] == pytest.approx(z, abs=1e-12)
    assert s[0] == pytest.approx(expected, rel=1e-9)
    # the same by finite differences of the closed forms above (independent of ray_depths)
    h = 1e-7
    dz_b = (B / np.tan(np.arctan(tan) + h) - B / np.tan(np.arctan(tan) - h)) / (2 * h)
    ds_a = (B / (np.sin(h) + tan * np.cos(h)) - B / (np.sin(-h) + tan * np.cos(-h))) / (2 * h)
    assert s[0] == pytest.approx(1e-3 * np.hypot(dz_b, ds_a), rel=1e-5)


def test_ray_depths_refuse_rays_that_do_not_meet_ahead():
    b_a = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    b_b = np.array(
        [
            [0.0, 0.0, 1.0],  # parallel: the point at infinity
            unit([B, 0.0, 4.0]),  # diverging: they would meet behind camera a
            unit([-B, 0.0, -4.0]),  # the point behind both
        ]
    )
    d, s, ok = ray_depths(b_a, b_b, R, T, 1e-3)
    assert not ok.any()
    assert np.isinf(d).all() and np.isinf(s).all()


def test_point_bearings_is_where_camera_b_sees_a_point_at_that_depth():
    """At depth 4 m along a's axis camera b (0.3 m to the +x side) sees (-0.3, 0, 4); and depths
    put along rays of a rotated rig come back from ray_depths."""
    got = point_bearings(np.array([[0.0, 0.0, 1.0]]), 4.0, R, T)
    np.testing.assert_allclose(got[0], unit([-B, 0.0, 4.0]), atol=1e-15)
    c, s_ = np.cos(0.2), np.sin(0.2)
    R_y = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]])
    rng = np.random.default_rng(3)
    b_a = unit(rng.normal([0, 0, 1], 0.3, (20, 3)))
    depth = rng.uniform(1.0, 12.0, 20)
    d, _, ok = ray_depths(b_a, point_bearings(b_a, depth, R_y, T), R_y, T, 1e-3)
    assert ok.all()
    np.testing.assert_allclose(d, depth, rtol=1e-9)


def test_informative_means_the_inverse_depth_is_three_sigmas_from_zero():
    got = informative(np.array([3.0, 3.0, np.inf, 3.0]), np.array([0.99, 1.01, 0.1, np.inf]))
    assert got.tolist() == [True, False, False, False]


def test_surface_agreement_uses_the_neighbours_median_and_the_joint_sigma():
    """Six points at 4 m (sigma 0.1 m) near the new one, six at 8 m far from it in the image: the
    surface next to it is 4 m with variance (pi / 2) 0.01 / 6; a new point of sigma 0.05 m agrees
    within 3 sqrt(0.05^2 + that) = 0.2146 m."""
    uv_ref = np.array([[100.0 + 3 * i, 100.0] for i in range(6)] + [[400.0 + 3 * i, 100.0] for i in range(6)])
    d_ref = np.array([4.0] * 6 + [8.0] * 6)
    s_ref = np.full(12, 0.1)
    lim = 3 * np.sqrt(0.05**2 + (np.pi / 2) * 0.01 / 6)
    assert lim == pytest.approx(0.2146, abs=1e-4)
    uv_new = np.array([[110.0, 105.0]] * 3)
    d_new = np.array([4.0 + 0.99 * lim, 4.0 - 1.01 * lim, np.inf])
    got = surface_agreement(uv_new, d_new, np.array([0.05, 0.05, 0.05]), uv_ref, d_ref, s_ref)
    assert got.tolist() == [True, False, False]
    assert not surface_agreement(uv_new, d_new, np.full(3, 0.05), uv_ref[:0], d_ref[:0], s_ref[:0]).any()


def _triangulated(depths, xs_px, sigma_rad=2e-3):
    """Points at ``depths`` along rays of camera a fanned out across the image (pixel x ->
    angle sigma_rad x): their pixels, and depth and sigma as ray_depths triangulates them from the
    exact b rays."""
    ang = np.asarray(xs_px, float) * sigma_rad
    b_a = np.column_stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)])
    d, s, ok = ray_depths(b_a, point_bearings(b_a, np.asarray(depths, float), R, T), R, T, sigma_rad)
    assert ok.all()
    uv = np.column_stack([640 + np.asarray(xs_px, float), np.full(len(ang), 360.0)])
    return uv, d, s


def test_a_piece_beside_the_track_at_its_depth_joins_it():
    """One obstacle 3 m away split into two tracks side by side (2 mrad per px, 1 px sigma): the
    piece's depths equal the track's."""
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([3.0] * 5, np.arange(5, 30, 5))
    assert piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_an_obstacle_beside_the_track_at_another_depth_does_not_join_it():
    """Two obstacles side by side in the image, 3 m and 4 m away: near the axis the depth sigma is
    about sqrt(2) d^2 sigma / B (0.151 m at 4 m with a 0.3 m baseline and 2 mrad rays), so the
    1 m step is over 6 joint sigmas: no join."""
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([4.0] * 5, np.arange(5, 30, 5))
    np.testing.assert_allclose(s_p, np.sqrt(2) * 16 * 2e-3 / B, rtol=0.02)
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_far_pieces_whose_depth_says_nothing_do_not_join():
    """At 40 m the depth sigma (~10 m) holds any depth within 3 sigmas, so it is no evidence."""
    uv_t, d_t, s_t = _triangulated([40.0] * 8, np.arange(-40, 0, 5))
    uv_p, d_p, s_p = _triangulated([40.0] * 5, np.arange(5, 30, 5))
    assert not informative(d_p, s_p).any()
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


def test_a_piece_needs_three_agreeing_members_and_a_majority():
    uv_t, d_t, s_t = _triangulated([3.0] * 8, np.arange(-40, 0, 5))
    # two at the track's depth, two at 4 m: two agree (fewer than 3)
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 4.0, 4.0], np.arange(5, 25, 5))
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)
    # three agree, three do not: no majority
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 3.0, 4.0, 4.0, 4.0], np.arange(5, 35, 5))
    assert not piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)
    # three agree, two do not
    uv_p, d_p, s_p = _triangulated([3.0, 3.0, 3.0, 4.0, 4.0], np.arange(5, 30, 5))
    assert piece_agrees(uv_p, d_p, s_p, uv_t, d_t, s_t)


@pytest.fixture(scope="module")
def flying_640(tmp_path_factory):
    """The stereo_flying preset rendered at 640x360 for 12 frames by the simulator."""
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.writer import simulate

    out = tmp_path_factory.mktemp("stereo_flying_640")
    simulate(load_scenario(scenarios_dir() / "stereo_flying.yaml"), out, frames=12, resolution=(640, 360))
    return out


def test_a_split_off_piece_joins_its_two_camera_track_on_its_own_physical_points(flying_640):
    """On frame 9 the largest confirmed cam0 track is cut in two by image column (as a grouper
    split would), and the half on the right is kept from getting a cam1 view of its own: it is
    reported under its own id with one view; on the association frame 10 it joins the other
    half's two-camera track (same global id, its members in that id's cam0 view, found ones in its
    cam1 view; its own id reported lost once) and stays joined on frame 11. Expected from the
    renderer: the ray cast from cam0 along each of its members' cam0 bearings gives the physical
    point, whose direction from cam1's centre is where the cam1 bearing of that id must point
    (median within 1 px of angle)."""
    from estimators.se3 import Pose, quat_to_rot
    from pipeline.sim import World, load_scenario, raycast
    from trackers.benchmark import open_scene
    from trackers.frontend import FrontEnd
    from trackers.grouping import ObstacleTrack

    rig, caps, stamps, gt, specs = open_scene(flying_640)
    world = World(load_scenario(flying_640 / "scene.yaml"))
    fe = FrontEnd(rig, association={"attach_pieces": True})
    g0, ft0 = fe.groupers["cam0"], fe.trackers["cam0"]
    update, derive = g0.update, fe._derive_views
    cut: dict = {}

    def split_update(*a, **k):
        s1, l1 = update(*a, **k)
        if fe._n == 9:
            big = max((t for t in s1 if t.status == "confirmed"), key=lambda t: len(t.members))
            rows, which = fe._rows(ft0, big.members)
            o = np.argsort(ft0.uv[rows, 0], kind="stable")
            keep, move = which[o[: len(o) // 2]], which[o[len(o) // 2 :]]
            piece = ObstacleTrack(next(fe._track_ids), "cam0", big.members[move].copy(), big.b_C.copy(),
                                  uv=big.uv.copy(), sigma_rad=big.sigma_rad, status="confirmed",
                                  hits=big.hits, member_b_C=big.member_b_C[move].copy())
            big.members, big.member_b_C = big.members[keep].copy(), big.member_b_C[keep].copy()
            g0.tracks[piece.id] = piece
            s1.append(piece)
            cut.update(big=big, piece=piece)
        return s1, l1

    def no_own_view(seen, greys):
        out = derive(seen, greys)
        p = cut.get("piece")
        return {n: [v for v in vs if p is None or v.id != p.id] for n, vs in out.items()}

    g0.update = split_update
    fe._derive_views = no_own_view
    c0, c1 = rig["cam0"], rig["cam1"]
    px_rad = c1.model.max_angle_rad / c1.model.image_circle()[2]
    checked = 0
    for f in sorted(stamps["cam0"]):
        v = gt[f]["T_W_B"]
        T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
        t_s = stamps["cam0"][f]
        obs = fe.process({n: caps[n].read()[1] for n in ("cam0", "cam1")}, f, t_s, T_W_B=T_W_B)
        if "piece" not in cut:
            continue
        big, piece = cut["big"], cut["piece"]
        g = fe._global(big.id)
        mine = [o for o in obs if o.track_id == piece.id]
        if f == 9:  # not attached yet: its own one-camera report
            assert [len(o.views) for o in mine] == [1] and mine[0].status == "confirmed"
            continue
        assert fe._global(piece.id) == g and piece.id in fe._pieces
        assert [o.status for o in mine] == (["lost"] if f == 10 else [])
        (o,) = [o for o in obs if o.track_id == g]
        views = {w.camera: w for w in o.views}
        own = set(piece.members.tolist())
        assert own <= set(views["cam0"].feature_ids.tolist())
        k1 = [k for k, i in enumerate(views["cam1"].feature_ids.tolist()) if i in own]
        assert len(k1) >= 3
        # the cam1 bearings of the piece's ids point at the physical points of their cam0 bearings
        row0 = {int(i): k for k, i in enumerate(views["cam0"].feature_ids)}
        b0 = views["cam0"].feature_b_C[[row0[int(views["cam1"].feature_ids[k])] for k in k1]]
        b0_W = T_W_B.rotate((c0.T_C_B.R.T @ b0.T).T)
        o0_W = np.repeat(T_W_B.apply(c0.centre_B)[None], len(b0), 0)
        depth, _ = raycast(world, t_s, o0_W, b0_W)
        ok = np.isfinite(depth)
        p_C1 = c1.T_C_B.apply(T_W_B.inverse().apply(o0_W[ok] + depth[ok, None] * b0_W[ok]))
        e1 = p_C1 / np.linalg.norm(p_C1, axis=1, keepdims=True)
        b1 = views["cam1"].feature_b_C[k1][ok]
        assert np.median(np.arccos(np.clip(np.sum(e1 * b1, axis=1), -1, 1)) / px_rad) < 1.0
        checked += 1
    assert checked == 2  # frames 10 (attached) and 11 (kept attached)


def test_attach_pieces_is_a_checked_option_off_by_default():
    from estimators.errors import ConfigError
    from estimators.rig import stereo_forward_rig
    from tests.trackers.conftest import equidistant
    from trackers.frontend import FrontEnd

    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    assert FrontEnd(rig).attach_pieces is False
    assert FrontEnd(rig, association={"attach_pieces": True}).attach_pieces is True
    with pytest.raises(ConfigError, match="attach_pieces"):
        FrontEnd(rig, association={"attach_pieces": 1})
