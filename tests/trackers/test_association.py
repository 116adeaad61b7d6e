"""Cross-camera association: the spherical epipolar constraint (closed form), descriptor matching
under it, and a simulated stereo flight where an obstacle seen by both cameras is one track."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.rig import stereo_forward_rig
from tests.trackers.conftest import equidistant, rot_axis
from trackers.association import consistent_pairs, epipolar_residual, match_features


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _render(tmp_path_factory, preset: str, frames: int, resolution: tuple[int, int]):
    """A shipped scenario preset rendered by the simulator into a temporary folder."""
    from pipeline.config import scenarios_dir
    from pipeline.sim.scene import load_scenario
    from pipeline.sim.writer import simulate

    out = tmp_path_factory.mktemp(preset)
    simulate(load_scenario(scenarios_dir() / f"{preset}.yaml"), out, frames=frames, resolution=resolution)
    return out


@pytest.fixture
def stereo():
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    c0, c1 = rig.cameras
    T = c1.T_C_B @ c0.T_C_B.inverse()  # T_C1_C0
    return rig, c0, c1, T


def test_epipolar_residual_zero_for_true_pairs_and_sine_of_offset(stereo):
    rig, c0, c1, T = stereo
    rng = np.random.default_rng(0)
    p_B = rng.uniform([-8, -8, -3], [8, 8, 3], (50, 3))  # includes points behind and beside
    p_B = p_B[np.linalg.norm(p_B, axis=1) > 1.0]
    b0 = unit(c0.T_C_B.apply(p_B))
    b1 = unit(c1.T_C_B.apply(p_B))
    np.testing.assert_array_less(epipolar_residual(b0, b1, T.R, T.t), 1e-12)
    # tilt b1 out of its epipolar plane by 1 degree: the residual is sin(1 deg)
    n = unit(np.cross(T.t, b0 @ T.R.T))
    tilted = np.array(
        [rot_axis(np.cross(n_i, b_i), np.radians(1.0)) @ b_i for n_i, b_i in zip(n, b1, strict=True)]
    )
    np.testing.assert_allclose(epipolar_residual(b0, tilted, T.R, T.t), np.sin(np.radians(1.0)), rtol=1e-6)


def test_matching_keeps_epipolar_pairs_and_rejects_a_lookalike_off_the_plane(stereo):
    rig, c0, c1, T = stereo
    rng = np.random.default_rng(1)
    p_B = np.column_stack([rng.uniform(3, 10, 30), rng.uniform(-3, 3, 30), rng.uniform(-1, 1, 30)])
    b0 = unit(c0.T_C_B.apply(p_B))
    b1 = unit(c1.T_C_B.apply(p_B))
    d = rng.integers(0, 256, (30, 32), dtype=np.uint8)
    # camera 1 sees the same points in another order, plus a lookalike of point 0 off its plane
    perm = rng.permutation(30)
    decoy_b = rot_axis([1, 0, 0], np.radians(8)) @ b1[0]
    b1x = np.vstack([b1[perm], decoy_b])
    d1x = np.vstack([d[perm], d[0]])
    m = match_features(b0, d, b1x, d1x, T.R, T.t, epipolar_rad=np.radians(1.0))
    got = {int(i): int(j) for i, j in m}
    inv = {int(p): k for k, p in enumerate(perm)}
    assert len(got) >= 28
    assert all(j == inv[i] for i, j in got.items())
    assert 30 not in got.values()


def _reference_matches(b0, d0, b1, d1, R, t, epipolar_rad, max_hamming, ratio=0.9):
    """match_features by its definition, pair by pair: the epipolar residual |b1 . n| / |n| with
    n = t_hat x R b0 (1 where |n| <= 1e-9), rays ahead, b1 on the epipolar plane's arc from R b0 to
    t_hat (its components along the in-plane unit vectors square to R b0 and to t_hat, pointing
    into the arc, Gram-Schmidt, >= -sin(epipolar_rad)), Hamming distance by counting set bits;
    each row's best column (least distance, the first on ties), mutual, with Lowe's ratio."""
    n0, n1 = len(b0), len(b1)
    t_hat = np.asarray(t, float) / np.linalg.norm(t)
    H = np.full((n0, n1), np.inf)
    for i in range(n0):
        d = R @ b0[i]
        n = np.cross(t_hat, d)
        e = t_hat - (t_hat @ d) * d  # in the plane, square to d, towards t_hat
        f = d - (d @ t_hat) * t_hat  # in the plane, square to t_hat, towards d
        for j in range(n1):
            nn = float(np.sqrt(n @ n))
            res = abs(float(b1[j] @ n)) / nn if nn > 1e-9 else 1.0
            in_arc = nn > 1e-9 and min(b1[j] @ unit(e), b1[j] @ unit(f)) >= -np.sin(epipolar_rad)
            if res < np.sin(epipolar_rad) and float(d @ b1[j]) > 0 and in_arc:
                h = sum(bin(int(x)).count("1") for x in np.bitwise_xor(d0[i], d1[j]))
                if h <= max_hamming:
                    H[i, j] = h
    out = []
    for i in range(n0):
        if not np.isfinite(H[i]).any():
            continue
        j = int(np.argmin(H[i]))
        second = np.sort(H[i])[1] if n1 > 1 else np.inf
        if int(np.argmin(H[:, j])) == i and H[i, j] <= ratio * second + 1e-9:
            out.append((i, j))
    return np.array(out, np.intp).reshape(-1, 2)


@pytest.mark.parametrize("seed", range(6))
def test_matching_equals_the_pairwise_definition_with_ties(stereo, seed):
    """Near-identical descriptors (a few flipped bits: many equal distances) on bearings of
    which a good share are epipolar candidates: the matches (mutual best, first on ties, ratio)
    equal the definition worked pair by pair."""
    rig, c0, c1, T = stereo
    rng = np.random.default_rng(seed)
    n0, n1 = rng.integers(1, 30, 2)
    b0 = unit(rng.normal(size=(n0, 3)) + [0, 0, 2])
    b1 = unit(rng.normal(size=(n1, 3)) + [0, 0, 2])
    base = rng.integers(0, 256, 32, dtype=np.uint8)
    d0 = np.tile(base, (n0, 1))
    d1 = np.tile(base, (n1, 1))
    for d in (d0, d1):
        for r in range(len(d)):
            for _ in range(rng.integers(0, 5)):
                d[r, rng.integers(0, 32)] ^= np.uint8(1 << int(rng.integers(0, 8)))
    for epi_deg, max_h in ((1.0, 64), (20.0, 64), (20.0, 3), (90.0, 8)):
        got = match_features(b0, d0, b1, d1, T.R, T.t, np.radians(epi_deg), max_h)
        want = _reference_matches(b0, d0, b1, d1, T.R, T.t, np.radians(epi_deg), max_h)
        np.testing.assert_array_equal(got, want)


def test_top_bottom_matching_refuses_rays_that_diverge():
    """The top/bottom rig (baseline along the optical axes): every elevation at one azimuth lies in
    one epipolar plane, so a lookalike 18 deg below the horizon in the down camera passes the
    epipolar and same-side tests for a feature 60 deg above it in the up camera, yet the two rays
    diverge (top_bottom_climb: the box's up-camera track linked to the ground's down-camera track).
    The same point seen by both (5 deg above the horizon, 4 m away) still matches."""
    from estimators.rig import top_bottom_rig

    rig = top_bottom_rig(equidistant(), separation_m=0.10)
    up, down = rig.cameras
    T = down.T_C_B @ up.T_C_B.inverse()  # T_Cdown_Cup

    def el(deg, r):  # a body point at azimuth 30 deg, elevation deg, range r from the body origin
        a, e = np.radians(30.0), np.radians(deg)
        return r * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])

    d = np.random.default_rng(0).integers(0, 256, (1, 32), dtype=np.uint8)
    b_up = unit(up.T_C_B.apply(el(60.0, 4.0)))
    b_down = unit(down.T_C_B.apply(el(-18.0, 15.0)))
    assert epipolar_residual(b_up[None], b_down[None], T.R, T.t)[0] < 1e-12  # one epipolar plane
    assert float((T.R @ b_up) @ b_down) > 0  # and on the same side
    assert match_features(b_up[None], d, b_down[None], d, T.R, T.t).shape == (0, 2)
    p = el(5.0, 4.0)  # seen by both (the down camera reaches 7.5 deg above the horizon)
    got = match_features(unit(up.T_C_B.apply(p))[None], d, unit(down.T_C_B.apply(p))[None], d, T.R, T.t)
    assert got.tolist() == [[0, 0]]


def test_a_ray_along_the_baseline_is_no_candidate(stereo):
    """(review of a7c4650) b0 along the baseline has no epipolar plane (t_hat x R b0 = 0, residual 1
    by definition): it matches nothing, not even an identical descriptor along the baseline in
    camera 1 (whose raw product |b1 . n| is 0 there)."""
    rig, c0, c1, T = stereo
    t_hat = np.asarray(T.t, float) / np.linalg.norm(T.t)
    b0 = np.asarray(T.R).T @ t_hat  # R b0 = t_hat
    b1 = np.array([t_hat, unit([0.0, 0.0, 1.0])])
    d = np.full((1, 32), 7, np.uint8)
    assert epipolar_residual(b0[None], b1[:1], T.R, T.t).tolist() == [1.0]
    got = match_features(b0[None], d, b1, np.vstack([d, d ^ 0xFF]), T.R, T.t)
    assert got.shape == (0, 2)


def test_consistent_pairs_by_hand_and_by_definition():
    """Repeated pairs count once; an id with two partners links nothing (worked by hand), and on
    random ids the result is the definition's: the distinct pairs, sorted, whose a and b ids
    each appear in one distinct pair only."""
    a, b = consistent_pairs(np.array([1, 1, 2, 3, 3, 4]), np.array([10, 10, 20, 30, 31, 20]))
    # (3, 30) and (3, 31): a = 3 has two partners; (2, 20) and (4, 20): b = 20 has two
    assert a.tolist() == [1] and b.tolist() == [10]
    a, b = consistent_pairs(np.zeros(0, np.int64), np.zeros(0, np.int64))
    assert len(a) == len(b) == 0
    rng = np.random.default_rng(3)
    for _ in range(200):
        n = int(rng.integers(1, 30))
        ia = rng.integers(0, 12, n)
        ib = rng.integers(0, 12, n) + (2**40 if rng.random() < 0.5 else 0)
        pairs = sorted(set(zip(ia.tolist(), ib.tolist(), strict=True)))
        n_a = {x: sum(p[0] == x for p in pairs) for x, _ in pairs}
        n_b = {y: sum(p[1] == y for p in pairs) for _, y in pairs}
        want = [p for p in pairs if n_a[p[0]] == 1 and n_b[p[1]] == 1]
        a, b = consistent_pairs(ia, ib)
        assert list(zip(a.tolist(), b.tolist(), strict=True)) == want


@pytest.fixture(scope="module")
def stereo_scene(tmp_path_factory):
    """The stereo_flying preset rendered at 384x216 for 24 frames by the simulator."""
    return _render(tmp_path_factory, "stereo_flying", 24, (384, 216))


def test_stereo_obstacle_is_one_track_with_two_views(stereo_scene):
    """Every simulated camera pair frame goes through the FrontEnd; by the end most confirmed
    tracks carry a view from each camera, and both views of a track point at the same obstacle
    (the simulator's shapes; ground counts as 'no obstacle')."""
    from trackers.benchmark import open_scene, ray_hit_distance, shapes_for_frame
    from trackers.frontend import FrontEnd

    rig, caps, stamps, gt, specs = open_scene(stereo_scene)
    fe = FrontEnd(rig)
    out = []
    for f in sorted(stamps["cam0"]):
        imgs = {n: caps[n].read()[1] for n in ("cam0", "cam1")}
        out = fe.process(imgs, f, stamps["cam0"][f])
    conf = [o for o in out if o.status == "confirmed"]
    two = [o for o in conf if len(o.views) == 2]
    assert len(conf) >= 5
    assert len(two) >= 0.4 * len(conf), f"{len(two)} of {len(conf)} confirmed tracks have both views"
    # both views on the same obstacle (or both on none)
    line = gt[max(gt)]
    v = line["T_W_B"]
    from estimators.se3 import Pose, quat_to_rot

    T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
    shapes = shapes_for_frame(specs, line["obstacles"])
    agree = 0
    for o in two:
        hits = []
        for view in o.views:
            cam = rig[view.camera]
            oW = T_W_B.apply(cam.centre_B)
            dW = T_W_B.rotate(cam.T_C_B.R.T @ view.b_C)
            best = min(
                ((ray_hit_distance(oW, dW, s, 0.05) or np.inf, k) for k, s in shapes.items()),
                default=(np.inf, None),
            )
            hits.append(best[1] if np.isfinite(best[0]) else None)
        agree += hits[0] == hits[1]
    assert agree >= 0.8 * len(two)


def test_link_features_gives_the_reference_id_and_a_fresh_one_when_the_partner_would_change(stereo):
    """The physical-point id rule's bookkeeping: a cam1 feature matched to a cam0 feature is
    reported under the cam0 id; a cam0 feature is held by one cam1 feature at a time; a cam1 feature
    whose match would move to another cam0 feature gets a new id never used before."""
    from trackers.frontend import FrontEnd

    rig = stereo[0]
    fe = FrontEnd(rig)
    pid = fe._pid["cam1"]
    fe.link_features("cam1", np.array([10, 11]), np.array([100, 101]))
    assert pid == {100: 10, 101: 11}
    fe.link_features("cam1", np.array([10]), np.array([102]))  # cam0's 10 is held by 100
    assert 102 not in pid
    fe.link_features("cam1", np.array([10]), np.array([100]))  # the same link again: unchanged
    assert pid[100] == 10
    fe.link_features("cam1", np.array([12]), np.array([101]))  # 101 would change partner
    fresh = pid[101]
    assert fresh not in (10, 11, 12, 100, 101, 102)
    fe.link_features("cam1", np.array([11]), np.array([102]))  # 11 is free again, 102 takes it
    assert pid[102] == 11
    fe.link_features("cam1", np.array([13]), np.array([101]))  # once fresh, 101 stays fresh
    assert pid[101] == fresh


def test_stereo_feature_ids_name_one_physical_point_in_both_views(stereo_scene):
    """Feature ids shared by the cam0 and cam1 views of a track are one physical point: the
    renderer's ray cast (pipeline.sim.raycast) along the cam0 ray and along the cam1 ray of each
    shared id hits the same object at nearly the same place."""
    from estimators.se3 import Pose, quat_to_rot
    from pipeline.sim import World, load_scenario, raycast
    from trackers.benchmark import open_scene
    from trackers.frontend import FrontEnd

    rig, caps, stamps, gt, specs = open_scene(stereo_scene)
    world = World(load_scenario(stereo_scene / "scene.yaml"))
    fe = FrontEnd(rig)
    # tolerance: 3 pixels of angle (a surface point moves by about angle x range, more on grazing
    # surfaces such as the ground, hence the median)
    tol = 3.0 * rig["cam0"].model.max_angle_rad / rig["cam0"].model.image_circle()[2]
    gaps, same_obj, shared_total = [], 0, 0
    for f in sorted(stamps["cam0"]):
        obs = fe.process({n: caps[n].read()[1] for n in ("cam0", "cam1")}, f, stamps["cam0"][f])
        if f not in gt:
            continue
        v = gt[f]["T_W_B"]
        T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
        for o in obs:
            views = {w.camera: w for w in o.views}
            if len(views) < 2:
                continue
            ids0 = {int(i): k for k, i in enumerate(views["cam0"].feature_ids)}
            ids1 = {int(i): k for k, i in enumerate(views["cam1"].feature_ids)}
            assert len(ids1) == len(views["cam1"].feature_ids)  # no id twice in one view
            shared = sorted(set(ids0) & set(ids1))
            hits = []
            for cam, ids in (("cam0", ids0), ("cam1", ids1)):
                c = rig[cam]
                b_W = T_W_B.rotate((c.T_C_B.R.T @ views[cam].feature_b_C[[ids[i] for i in shared]].T).T)
                o_W = np.repeat(T_W_B.apply(c.centre_B)[None], len(shared), 0)
                depth, obj = raycast(world, stamps["cam0"][f], o_W, b_W)
                hits.append((o_W + depth[:, None] * b_W, obj, depth))
            for k in range(len(shared)):
                if not (np.isfinite(hits[0][2][k]) and np.isfinite(hits[1][2][k])):
                    continue
                shared_total += 1
                same_obj += hits[0][1][k] == hits[1][1][k]
                # distance between the two rays' surface points, relative to the range
                gaps.append(np.linalg.norm(hits[0][0][k] - hits[1][0][k]) / hits[0][2][k])
    assert shared_total >= 20, f"only {shared_total} shared feature ids with a surface behind them"
    assert same_obj >= 0.9 * shared_total
    assert np.median(gaps) < tol
    # the links themselves (cam1 features tracked by cam1, reported under a cam0 id), last frame
    ft0, ft1 = fe.trackers["cam0"], fe.trackers["cam1"]
    row0 = {int(i): k for k, i in enumerate(ft0.ids)}
    row1 = {int(i): k for k, i in enumerate(ft1.ids)}
    links = [(row0[r], row1[f1]) for f1, r in fe._pid["cam1"].items() if r in row0 and f1 in row1]
    assert len(links) >= 10, f"only {len(links)} live cam1 features linked to cam0 ones"
    pts = []
    for cam, ft, rows in (("cam0", ft0, [a for a, _ in links]), ("cam1", ft1, [b for _, b in links])):
        c = rig[cam]
        b_W = T_W_B.rotate((c.T_C_B.R.T @ ft.b_C[rows].T).T)
        o_W = np.repeat(T_W_B.apply(c.centre_B)[None], len(rows), 0)
        depth, obj = raycast(world, stamps["cam0"][f], o_W, b_W)
        pts.append((o_W + np.where(np.isfinite(depth), depth, 0.0)[:, None] * b_W, obj, depth))
    ok = np.isfinite(pts[0][2]) & np.isfinite(pts[1][2])
    assert ok.sum() >= 10
    assert np.mean(pts[0][1][ok] == pts[1][1][ok]) >= 0.9
    assert np.median(np.linalg.norm(pts[0][0][ok] - pts[1][0][ok], axis=1) / pts[0][2][ok]) < tol


def _rotated_sphere_pair():
    """Cameras a and b on one point, b turned 3 degrees about y, over a textured world at infinity
    (pure rotation): every feature of a sits in b where the model projects R_b_a b_a. Returns the
    model, R_b_a, both frames and a FeatureTracker that has run on a's frame."""
    import itertools

    from estimators.rig import Camera, forward_T_C_B
    from tests.trackers.conftest import SphereScene
    from trackers.detectors import make_detector
    from trackers.features import FeatureTracker

    model = equidistant(640, 480)
    scene = SphereScene(model)
    R_b_a = rot_axis([0, 1, 0], np.radians(3.0)).T  # b_b = R_b_a b_a
    img_a, img_b = scene.render(None), scene.render(R_b_a.T)
    ft = FeatureTracker(Camera("a", model, forward_T_C_B()), make_detector("orb"), ids=itertools.count(1))
    ft.track(img_a, 0, 0.0)
    return model, R_b_a, img_a, img_b, ft


def test_stereo_klt_on_lens_crops_equals_full_frames():
    """stereo_klt on the lens crops (as the front end runs it, FeatureTracker.roi with origins on
    multiples of 16 px) finds the same features at the same pixels as on the full frames: a camera
    turned 3 degrees about y sees a world at infinity (pure rotation), so every match must also sit
    where the model projects R b_a (checked to 0.3 px)."""
    import cv2

    from trackers.association import stereo_klt

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    assert ft.roi[0] % 16 == 0 and ft.roi[1] % 16 == 0 and ft.roi != (0, 0, 640, 480)
    x0, y0, x1, y1 = ft.roi
    crop = lambda im: np.ascontiguousarray(im[y0:y1, x0:x1])  # noqa: E731
    off = np.array([x0, y0], float)
    cv2.setNumThreads(1)
    uv_a, b_a, t = ft.uv.astype(float), ft.b_C, np.zeros(3)
    full = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t)
    cropped = stereo_klt(crop(img_a), crop(img_b), b_a, uv_a, model, R_b_a, t, off_a=off, off_b=off)
    assert len(full[0]) > 100
    np.testing.assert_array_equal(full[0], cropped[0])
    np.testing.assert_allclose(full[1], cropped[1], atol=1e-3)
    expected, _ = model.bearing_to_pixel(b_a[cropped[0]] @ R_b_a.T)
    assert np.median(np.linalg.norm(cropped[1] - expected, axis=1)) < 0.3


@pytest.fixture(scope="module")
def hover_scene(tmp_path_factory):
    """The stereo_hover preset (sphere 1: radius 0.3 m, centre 1.55 m ahead, so its surface is
    ~1.25-1.5 m away: ~12 degrees of disparity on the 0.30 m baseline) rendered at 960x540."""
    return _render(tmp_path_factory, "stereo_hover", 16, (960, 540))


def test_close_obstacle_features_get_shared_ids_that_name_one_physical_point(hover_scene):
    """A sphere ~1.4 m away (large disparity: the two cameras' independently detected corners on it
    rarely coincide): most of the cam0 view's features on it also appear in the cam1 view under the
    same id, and each shared id names one physical point. Expected match from the scene geometry:
    the renderer's ray cast along the cam0 ray gives the point, its direction from cam1 (when cam1
    sees it: the cast from cam1 reaches it) is where the cam1 bearing of that id must point."""
    from estimators.se3 import Pose, quat_to_rot
    from pipeline.sim import World, load_scenario, raycast
    from trackers.benchmark import open_scene
    from trackers.frontend import FrontEnd

    rig, caps, stamps, gt, specs = open_scene(hover_scene)
    world = World(load_scenario(hover_scene / "scene.yaml"))
    fe = FrontEnd(rig)
    c0, c1 = rig["cam0"], rig["cam1"]
    px_rad = c1.model.max_angle_rad / c1.model.image_circle()[2]  # angle of one pixel
    on_sphere, shared, err_px = 0, 0, []
    frames = sorted(stamps["cam0"])
    for f in frames:
        obs = fe.process({n: caps[n].read()[1] for n in ("cam0", "cam1")}, f, stamps["cam0"][f])
        if f < frames[len(frames) // 2] or f not in gt:  # let tracks confirm and associate first
            continue
        v = gt[f]["T_W_B"]
        T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
        t_s = stamps["cam0"][f]
        for o in obs:
            views = {w.camera: w for w in o.views}
            if len(views) < 2:
                continue
            w0, w1 = views["cam0"], views["cam1"]
            assert len(set(w1.feature_ids.tolist())) == len(w1.feature_ids)  # no id twice in one view
            b_W = T_W_B.rotate((c0.T_C_B.R.T @ w0.feature_b_C.T).T)
            o_W = np.repeat(T_W_B.apply(c0.centre_B)[None], len(b_W), 0)
            depth, obj = raycast(world, t_s, o_W, b_W)
            row1 = {int(i): k for k, i in enumerate(w1.feature_ids)}
            for k in np.flatnonzero(obj == 1):  # sphere 1
                p_W = o_W[k] + depth[k] * b_W[k]
                c1_W = T_W_B.apply(c1.centre_B)
                d1, _ = raycast(world, t_s, c1_W[None], (p_W - c1_W)[None])
                if abs(d1[0] - np.linalg.norm(p_W - c1_W)) > 0.01:  # hidden from cam1
                    continue
                on_sphere += 1
                i = int(w0.feature_ids[k])
                if i not in row1:
                    continue
                shared += 1
                e_C1 = c1.T_C_B.apply(T_W_B.inverse().apply(p_W[None]))[0]
                e_C1 /= np.linalg.norm(e_C1)
                err_px.append(np.arccos(np.clip(e_C1 @ w1.feature_b_C[row1[i]], -1.0, 1.0)) / px_rad)
    err_px = np.asarray(err_px)
    assert on_sphere >= 40, f"only {on_sphere} cam0 feature-frames on the near sphere in two-view tracks"
    assert shared >= 0.5 * on_sphere, f"{shared} of {on_sphere} near-sphere features have a shared id"
    assert np.median(err_px) < 2.0
    assert np.mean(err_px > 5.0) < 0.05, f"{np.mean(err_px > 5.0):.0%} of shared ids > 5 px from their point"


def test_followed_stereo_klt_starts_from_its_guess_and_checks_only_what_moved():
    """stereo_klt on a pure rotation (a camera turned 3 degrees about y over a world at
    infinity: every feature of a sits in b where the model projects R b_a, the expected pixel).
    Started 0.3 px off that pixel with no check asked, a feature lands within 0.3 px of it with no
    backward check; started 4 px off (more than recheck_px from where it lands), it is checked;
    rows with no guess (NaN) start from the infinite-depth projection and are always checked."""
    import cv2

    from trackers.association import stereo_klt

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    cv2.setNumThreads(1)
    uv_a, b_a, t = ft.uv.astype(float), ft.b_C, np.zeros(3)
    expected, ok = model.bearing_to_pixel(b_a @ R_b_a.T)
    uv_a, b_a, expected = uv_a[ok], b_a[ok], expected[ok]  # those seen by b
    n = len(b_a)
    assert n > 100
    guess = expected + np.array([0.3, 0.0])
    far = np.arange(n) % 3 == 1
    guess[far] += np.array([0.0, 4.0])
    none = np.arange(n) % 3 == 2
    guess[none] = np.nan
    r = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t, guess_b=guess, check=np.zeros(n, bool))
    assert len(r.idx) > 0.8 * n
    assert np.median(np.linalg.norm(r.uv_b - expected[r.idx], axis=1)) < 0.3
    near = ~far[r.idx] & ~none[r.idx]
    assert near.sum() > 20 and not r.checked[near].any()
    assert r.checked[far[r.idx]].all() and r.checked[none[r.idx]].all()
    # check asked for every row: all checked, the same rows found at the same pixels (to 0.05 px)
    full = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t, guess_b=guess)
    assert full.checked.all()
    common, i, j = np.intersect1d(r.idx, full.idx, return_indices=True)
    assert len(common) > 0.95 * len(full.idx)
    np.testing.assert_allclose(r.uv_b[i], full.uv_b[j], atol=0.05)


def test_followed_stereo_klt_on_fewer_levels_lands_where_the_full_search_does():
    """follow_levels: rows with a guess (0.3 or 4.3 px off the pixel where the model projects
    R b_a, the expected answer of a pure rotation) searched on 2 pyramid levels instead of 5 are
    found at that pixel as with the full search; rows without a guess still use all levels."""
    import cv2

    from trackers.association import stereo_klt

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    cv2.setNumThreads(1)
    uv_a, b_a, t = ft.uv.astype(float), ft.b_C, np.zeros(3)
    expected, ok = model.bearing_to_pixel(b_a @ R_b_a.T)
    uv_a, b_a, expected = uv_a[ok], b_a[ok], expected[ok]
    n = len(b_a)
    guess = expected + np.array([0.3, 0.0])
    guess[np.arange(n) % 3 == 1] += np.array([0.0, 4.0])
    none = np.arange(n) % 3 == 2
    guess[none] = np.nan
    full = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t, guess_b=guess)
    few = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t, guess_b=guess, follow_levels=1)
    assert len(few.idx) >= 0.97 * len(full.idx) and none[few.idx].sum() == none[full.idx].sum()
    assert np.median(np.linalg.norm(few.uv_b - expected[few.idx], axis=1)) < 0.3
    common, i, j = np.intersect1d(few.idx, full.idx, return_indices=True)
    np.testing.assert_allclose(few.uv_b[i], full.uv_b[j], atol=0.05)


def test_track_grouped_only_by_the_second_camera_gets_a_reference_view_on_its_own_points(stereo_scene):
    """With ``association.reverse_views`` and the reference camera's grouping switched off (its
    features are tracked, none grouped: as when an obstacle's reference features are ungrouped or
    in a track on another obstacle), the second camera's confirmed tracks still get a cam0 view
    (``_derive_views``, the other way round). Expected from the renderer and the rig: the ray
    cast along each shared id's cam1 bearing gives the physical point; its direction from cam0's
    centre is where the cam0 bearing of that id must point (median within 1 px of angle), and
    both views lie on the same object."""
    from estimators.se3 import Pose, quat_to_rot
    from pipeline.sim import World, load_scenario, raycast
    from trackers.benchmark import open_scene
    from trackers.frontend import FrontEnd

    rig, caps, stamps, gt, specs = open_scene(stereo_scene)
    world = World(load_scenario(stereo_scene / "scene.yaml"))
    fe = FrontEnd(rig, association={"reverse_views": True})
    fe.groupers["cam0"].update = lambda *a, **k: ([], [])  # cam0 groups nothing
    c0, c1 = rig["cam0"], rig["cam1"]
    px_rad = c0.model.max_angle_rad / c0.model.image_circle()[2]
    two_view, err_px, same = 0, [], []
    for f in sorted(stamps["cam0"]):
        obs = fe.process({n: caps[n].read()[1] for n in ("cam0", "cam1")}, f, stamps["cam0"][f])
        if f not in gt:
            continue
        v = gt[f]["T_W_B"]
        T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
        t_s = stamps["cam0"][f]
        for o in obs:
            views = {w.camera: w for w in o.views}
            if len(views) < 2:
                continue
            two_view += 1
            w0, w1 = views["cam0"], views["cam1"]
            row1 = {int(i): k for k, i in enumerate(w1.feature_ids)}
            ks = [(k0, row1[int(i)]) for k0, i in enumerate(w0.feature_ids) if int(i) in row1]
            assert len(ks) >= 3  # the view is made of cam1's members found in cam0's image
            b1_W = T_W_B.rotate((c1.T_C_B.R.T @ w1.feature_b_C[[k1 for _, k1 in ks]].T).T)
            o1_W = np.repeat(T_W_B.apply(c1.centre_B)[None], len(ks), 0)
            depth, obj = raycast(world, t_s, o1_W, b1_W)
            ok = np.isfinite(depth)
            p_W = o1_W[ok] + depth[ok, None] * b1_W[ok]
            e_C0 = c0.T_C_B.apply(T_W_B.inverse().apply(p_W))
            e_C0 /= np.linalg.norm(e_C0, axis=1, keepdims=True)
            b0 = w0.feature_b_C[[k0 for k0, _ in ks]][ok]
            err_px.extend(np.arccos(np.clip(np.sum(e_C0 * b0, axis=1), -1.0, 1.0)) / px_rad)
            # the two representative rays hit the same object (or both none)
            hit = []
            for cam, w in (("cam0", w0), ("cam1", w1)):
                c = rig[cam]
                o_W, d_W = T_W_B.apply(c.centre_B)[None], T_W_B.rotate(c.T_C_B.R.T @ w.b_C)[None]
                hit.append(int(raycast(world, t_s, o_W, d_W)[1][0]))
            same.append(hit[0] == hit[1])
    assert two_view >= 20, f"only {two_view} two-view reports with cam0's grouping off"
    assert len(err_px) >= 60
    assert np.median(err_px) < 1.0
    assert np.mean(same) >= 0.9


def test_reverse_views_is_a_checked_option_on_by_default(stereo):
    """On by default (the measured trade in FrontEnd.__init__); false turns it off; a non-boolean
    is refused."""
    from estimators.errors import ConfigError
    from trackers.frontend import FrontEnd

    rig = stereo[0]
    assert FrontEnd(rig).reverse_views is True
    assert FrontEnd(rig, association={"reverse_views": False}).reverse_views is False
    with pytest.raises(ConfigError, match="reverse_views"):
        FrontEnd(rig, association={"reverse_views": "yes"})


def test_stereo_klt_on_the_parts_it_reads_equals_the_whole_images():
    """stereo_klt's KLT calls run on the box of their points (``crop=True``, the default: origins on
    multiples of 2^level, margins for the window, the pyramid filter and the search's reach): on a
    camera turned 3 degrees about y over a world at infinity, every match sits where the model
    projects R b_a (0.3 px), and all, near (one cluster) or spread, followed or new, are the same
    rows at the same pixels as on the whole images."""
    import cv2

    from trackers.association import stereo_klt

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    cv2.setNumThreads(1)
    uv_a, b_a, t = ft.uv.astype(float), ft.b_C, np.zeros(3)
    expected, _ = model.bearing_to_pixel(b_a @ R_b_a.T)
    guess = np.full((len(b_a), 2), np.nan)
    guess[::2] = expected[::2] + 0.7  # half the rows followed from a guess 1 px off
    cluster = np.flatnonzero(np.linalg.norm(uv_a - uv_a[0], axis=1) < 60)
    cases = [(slice(None), {}), (slice(None), {"guess_b": guess, "follow_levels": 1}),
             (cluster, {}), (cluster, {"guess_b": guess[cluster], "follow_levels": 1})]
    for rows, kw in cases:
        whole = stereo_klt(img_a, img_b, b_a[rows], uv_a[rows], model, R_b_a, t, crop=False, **kw)
        part = stereo_klt(img_a, img_b, b_a[rows], uv_a[rows], model, R_b_a, t, **kw)
        assert len(part.idx) >= 0.9 * len(b_a[rows])
        np.testing.assert_array_equal(whole.idx, part.idx)
        np.testing.assert_allclose(whole.uv_b, part.uv_b, atol=1e-3)
        np.testing.assert_array_equal(whole.checked, part.checked)
        err = np.linalg.norm(part.uv_b - expected[rows][part.idx], axis=1)
        assert np.median(err) < 0.3


def test_stereo_klt_searches_new_rows_on_a_part_around_their_epipolar_curves(monkeypatch):
    """A new row's search (from its infinite-depth projection, at ``levels``) and the backward check
    run on a part around where they can end up: the epipolar curves (``EPIPOLAR_STEPS``), and the
    straight paths back to the rows' own pixels, with the windows' margin and ``BAND_SLACK``
    coarsest-level px, not the search's whole reach in every direction. On a horizontal baseline
    over a world at infinity (the answers are the starts) the parts are less tall and less wide than
    the reach's box, and the matches are the whole images' rows at the same pixels."""
    import cv2

    from trackers.association import stereo_klt
    from trackers.features import BAND_SLACK

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    cv2.setNumThreads(1)
    uv_a, b_a = ft.uv.astype(float), ft.b_C
    t = np.array([-0.3, 0.0, 0.0])
    rows = np.flatnonzero(np.linalg.norm(uv_a - [320.0, 240.0], axis=1) < 40)
    assert len(rows) >= 5
    shapes = []
    lk = cv2.calcOpticalFlowPyrLK

    def spy(prev, nxt, *a, **k):
        shapes.append((prev.shape, k["maxLevel"]))
        return lk(prev, nxt, *a, **k)

    levels = 2
    whole = stereo_klt(img_a, img_b, b_a[rows], uv_a[rows], model, R_b_a, t, levels=levels, crop=False)
    monkeypatch.setattr(cv2, "calcOpticalFlowPyrLK", spy)
    part = stereo_klt(img_a, img_b, b_a[rows], uv_a[rows], model, R_b_a, t, levels=levels)
    assert len(part.idx) >= 0.9 * len(rows)
    np.testing.assert_array_equal(whole.idx, part.idx)
    np.testing.assert_allclose(whole.uv_b, part.uv_b, atol=1e-3)
    assert [lv for _, lv in shapes] == [levels, levels]  # forward, backward
    m, reach = (11 // 2 + 6) * 2**levels, (11 // 2) * 2 ** (levels + 1)
    spread = np.ptp(uv_a[rows, 1]) + 4
    for (h, w), _ in shapes:
        assert h <= spread + 2 * (m + BAND_SLACK * 2**levels) + 2**levels  # around the curves
        assert h < spread + 2 * (m + reach) - 2**levels  # (the reach box's height)
        # (and narrower: a nearer point is seen on one side of its infinite-depth projection only)
        assert w < np.ptp(uv_a[rows, 0]) + 2 * (m + reach) - 2**levels


def test_stereo_klt_part_holds_near_matches_far_along_their_epipolar_curves():
    """A new row's part holds its epipolar curve, not only its start: matches 180-200 px from their
    infinite-depth starts (0.93-1.03 rad at this lens's 194 px/rad; w |t| ~ 1.3-1.7) are found on the
    part where the whole images find them. A box of the starts alone with the same margin (window
    margin + BAND_SLACK: 208 px at maxLevel 4) holds those points but not their coarse windows
    (~126 px around them), and loses most of them. Camera b sees a's image moved d px left along
    the row through the centre (the epipolar line of a horizontal baseline there); a broad blob
    (sigma 75 px) with fine texture, so LK converges from that far."""
    import cv2

    from trackers.association import stereo_klt

    cv2.setNumThreads(1)
    model = equidistant(1280, 720)
    rng = np.random.default_rng(0)
    fine = cv2.GaussianBlur(rng.random((720, 1280 + 200)).astype(np.float32), (0, 0), 1.5)
    fine = (fine - fine.mean()) / fine.std()
    yy, xx = np.mgrid[0:720, 0:1280].astype(np.float32)

    def scene(cx, dx):
        blob = np.exp(-((xx - cx) ** 2 + (yy - model.cy) ** 2) / (2 * 75.0**2))
        return np.clip(60 + 150 * blob + 12 * fine[:, dx : dx + 1280], 0, 255).astype(np.uint8)

    t = np.array([-0.1, 0.0, 0.0])
    for xa in (620.0, 650.0, 680.0):
        uv_a = np.array([[xa, model.cy]])
        b_a, _ = model.pixel_to_bearing(uv_a)
        for d in (180, 190, 200):
            img_a, img_b = scene(xa, 0), scene(xa - d, d)  # b sees a's pixel x at x - d
            whole = stereo_klt(img_a, img_b, b_a, uv_a, model, np.eye(3), t, crop=False)
            part = stereo_klt(img_a, img_b, b_a, uv_a, model, np.eye(3), t)
            np.testing.assert_array_equal(whole.idx, [0])
            np.testing.assert_allclose(whole.uv_b, uv_a - [d, 0.0], atol=0.05)
            np.testing.assert_array_equal(part.idx, whole.idx)
            np.testing.assert_allclose(part.uv_b, whole.uv_b, atol=1e-3)


def test_stereo_klt_checks_a_followed_match_that_lands_off_its_guess():
    """A followed row whose forward result lands more than recheck_px from its guess gets the
    backward check (and most such rows pass it); one that lands on its guess is kept unchecked.
    Pure rotation as above: the true match of each row is the projection of R b_a."""
    from trackers.association import stereo_klt

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    uv_a, b_a, t = ft.uv.astype(float), ft.b_C, np.zeros(3)
    expected, _ = model.bearing_to_pixel(b_a @ R_b_a.T)
    guess = expected.copy()
    guess[1::2] += 3.0  # odd rows start 4.2 px off their true match: KLT lands > 1 px from the guess
    none = np.zeros(len(b_a), bool)
    r = stereo_klt(img_a, img_b, b_a, uv_a, model, R_b_a, t, guess_b=guess, check=none, follow_levels=1)
    odd = r.idx % 2 == 1
    assert np.sum(~odd) >= 0.4 * len(b_a) / 2 and not r.checked[~odd].any()
    assert np.sum(odd) >= 0.4 * len(b_a) / 2 and r.checked[odd].all()


def test_lk_part_on_fewer_points_keeps_the_numbers_of_all_with_their_box():
    """LK works in the float32 pixels of the part it is given, so a point's answer depends on the
    part's origin: a backward-check call (from b's pixels, starting at the same pixels in a) on a
    few points far from the others lands them (bit for bit) where the call on all points does when
    given all points' box (``box_prev``, as stereo_klt's backward check does after the epipolar
    test), and only to 1e-3 px (not bit for bit) on its own smaller box. Camera turned 3 degrees
    about y over a world at infinity: the answers sit on a's features."""
    import cv2

    from trackers.features import _lk_part

    model, R_b_a, img_a, img_b, ft = _rotated_sphere_pair()
    cv2.setNumThreads(1)
    in_b, _ = model.bearing_to_pixel(ft.b_C @ R_b_a.T)
    p = in_b.reshape(-1, 1, 2).astype(np.float32)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)
    q_all, st_all, _ = _lk_part(img_b, img_a, p, p, 11, 2, crit)
    # the rows farthest from the points' top-left corner: their own box starts elsewhere
    far = np.argsort(-in_b.sum(axis=1))[:5]
    q_box, st_box, _ = _lk_part(img_b, img_a, p[far], p[far], 11, 2, crit, box_prev=p)
    q_own, _, _ = _lk_part(img_b, img_a, p[far], p[far], 11, 2, crit)
    ok = st_all[far] == 1
    assert ok.sum() >= 4
    np.testing.assert_array_equal(st_box, st_all[far])
    np.testing.assert_array_equal(q_box[ok], q_all[far][ok])
    np.testing.assert_allclose(q_own[ok], q_all[far][ok], atol=1e-3)
    assert not np.array_equal(q_own[ok], q_all[far][ok])  # the origin matters (why box_prev exists)
    assert np.median(np.linalg.norm(q_box[ok].reshape(-1, 2) - ft.uv[far][ok], axis=1)) < 0.3


def _rays(p_a: np.ndarray, t_b_a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit bearings of points p_a (K, 3) m in C_a from camera a and from camera b (p_Cb = p_Ca + t,
    R = I)."""
    b_a = p_a / np.linalg.norm(p_a, axis=1, keepdims=True)
    p_b = p_a + t_b_a
    return b_a, p_b / np.linalg.norm(p_b, axis=1, keepdims=True)


def test_depth_consistent_drops_a_lone_match_off_the_obstacle_and_keeps_a_nearer_surface():
    """depth_consistent on a 0.30 m baseline (R = I): 12 points on a sphere of radius 0.5 m whose
    centre is 3.5 m ahead are all kept; a 13th match whose ray in b was moved onto the point 1.4 m
    along a's ray (a repeated texture's other period) is dropped (it lies 2 m in front of a 0.5 m
    sphere, alone in depth); three points of a box 1.45 m ahead grouped with the sphere's points
    (a nearer obstacle in one group) agree with each other and are kept; a group of two is not
    judged."""
    from trackers.association import depth_consistent

    rng = np.random.default_rng(5)
    t = np.array([-0.3, 0.0, 0.0])
    c = np.array([0.2, -0.1, 3.5])
    n = rng.normal(size=(12, 3))
    n[:, 2] = -np.abs(n[:, 2])  # the half facing the cameras
    sphere = c + 0.5 * n / np.linalg.norm(n, axis=1, keepdims=True)
    b_a, b_b = _rays(sphere, t)
    spread = np.max(np.arccos(np.clip(b_a @ (c / np.linalg.norm(c)), -1, 1)))
    wrong_a = b_a[:1]
    _, wrong_b = _rays(wrong_a * 1.4, t)  # b's ray through the point 1.4 m along a's first ray
    ba, bb = np.concatenate([b_a, wrong_a]), np.concatenate([b_b, wrong_b])
    keep = depth_consistent(ba, bb, np.zeros(13, np.intp), np.eye(3), t, np.array([spread]), 0.0075)
    np.testing.assert_array_equal(keep, [True] * 12 + [False])
    # a nearer surface: three points 1.45-1.47 m ahead in the same group
    box = np.array([[0.1, 0.0, 1.45], [0.15, 0.05, 1.46], [0.12, -0.04, 1.47]])
    bx_a, bx_b = _rays(box, t)
    keep = depth_consistent(
        np.concatenate([b_a, bx_a]), np.concatenate([b_b, bx_b]), np.zeros(15, np.intp), np.eye(3), t,
        np.array([spread]), 0.0075,
    )
    assert keep.all()
    # two groups, the second of two matches (one of them the lone one): not judged
    keep = depth_consistent(
        np.concatenate([b_a, b_a[:1], wrong_a]), np.concatenate([b_b, b_b[:1], wrong_b]),
        np.r_[np.zeros(12), np.ones(2)].astype(np.intp), np.eye(3), t, np.array([spread, spread]), 0.0075,
    )
    assert keep.all()


def test_depth_consistent_bound_follows_the_obstacle_width():
    """The median bound is the width's: a match 30 % nearer than the median of a group whose members
    reach 0.01 rad from their mean is dropped, of one reaching 0.2 rad (2 rho / (1 - 2 rho) = 0.67)
    kept, and with no noise allowance a match just inside the bound's edge (inverse range
    w_med / (1 - 2 rho)) is kept, one 1 % past it dropped (the others all at the median)."""
    from trackers.association import depth_consistent

    t = np.array([-0.3, 0.0, 0.0])
    d = np.array([0.0, 0.0, 1.0])
    pts = np.stack([d * 4.0] * 5 + [d * 2.8])  # five at 4 m, one 30 % nearer
    b_a, b_b = _rays(pts + [[0.01, 0.0, 0.0]], t)
    own = np.zeros(6, np.intp)
    assert not depth_consistent(b_a, b_b, own, np.eye(3), t, np.array([0.01]), 0.0)[5]
    assert depth_consistent(b_a, b_b, own, np.eye(3), t, np.array([0.2]), 0.0)[5]
    rho = 0.1
    for r, kept in ((4.0 * (1 - 2 * rho) * 1.0001, True), (4.0 * (1 - 2 * rho) * 0.99, False)):
        p = np.stack([d * 4.0] * 5 + [d * r]) + [[0.01, 0.0, 0.0]]
        a, b = _rays(p, t)
        assert depth_consistent(a, b, own, np.eye(3), t, np.array([rho]), 0.0)[5] == kept



def _horizon_plane_pair():
    """A top/bottom rig (equidistant 195 deg, 480x480, 0.10 m apart) facing a textured plane 3 m
    ahead (x_B = 3, |y| < 3 m, |z| < 1 m), each camera's frame ray-cast through its model. Returns
    the rig, both frames and ``truth(b_up)``: for up-camera bearings (N, 3), where the down camera
    sees their plane points (by projection) and whether they lie on the plane within 0.15 m of the
    horizon and 0.3 m of its sides (both cameras see them, their windows on the texture)."""
    import cv2

    from estimators.rig import top_bottom_rig
    from tests.trackers.conftest import blocky_texture

    model = equidistant(480, 480, fov_deg=195.0)
    rig = top_bottom_rig(model, separation_m=0.10)
    up, down = rig.cameras
    tex = blocky_texture(1024, 48, 3)
    x_p, half_y, half_z = 3.0, 3.0, 1.0

    def on_plane(cam, b_C):  # the plane point along each bearing, and whether the ray meets it
        d = b_C @ cam.T_C_B.R  # b_B = R_C_B^T b_C
        o = cam.centre_B
        with np.errstate(divide="ignore", invalid="ignore"):
            p = o + ((x_p - o[0]) / d[:, 0])[:, None] * d
        return p, (d[:, 0] > 0) & (np.abs(p[:, 1]) < half_y) & (np.abs(p[:, 2]) < half_z)

    def render(cam):
        v, u = np.mgrid[0 : model.height, 0 : model.width]
        b, ok = cam.model.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1).astype(float))
        p, hit = on_plane(cam, b)
        hit &= ok
        mx = np.where(hit, (p[:, 1] + half_y) / (2 * half_y) * 1023, 0).astype(np.float32)
        my = np.where(hit, (half_z - p[:, 2]) / (2 * half_z) * 1023, 0).astype(np.float32)
        val = cv2.remap(tex, mx.reshape(model.height, -1), my.reshape(model.height, -1), cv2.INTER_LINEAR)
        return np.where(hit, val.ravel(), 128).astype(np.uint8).reshape(model.height, model.width)

    def truth(b_up):
        p, hit = on_plane(up, b_up)
        band = hit & (np.abs(p[:, 1]) < half_y - 0.3) & (np.abs(p[:, 2]) < 0.15)
        p_down = np.where(band[:, None], p, 1.0) @ down.T_C_B.R.T + down.T_C_B.t
        uv, seen = down.model.bearing_to_pixel(p_down)
        return uv, band & seen

    return rig, render(up), render(down), truth


def test_patch_turn_on_the_top_bottom_horizon_is_180_minus_twice_the_azimuth():
    """The down camera's image is the up camera's mirrored about the nose's image axis with its
    radius reflected about the horizon's circle (r -> f pi - r): at azimuth psi on the horizon a
    patch turns by 180 - 2 psi degrees (worked by hand: the radial and the tangential directions
    both flip, about image axes 2 psi apart). A forward pair with parallel axes and one model turns
    by 0; the front end takes the top/bottom pairs (both ways) and no forward pair for turned."""
    from estimators.rig import top_bottom_rig
    from trackers.association import pair_turns, patch_jacobian, patch_turn_deg
    from trackers.frontend import FrontEnd

    model = equidistant(480, 480, fov_deg=195.0)
    rig = top_bottom_rig(model, separation_m=0.10)
    up, down = rig.cameras
    T = down.T_C_B @ up.T_C_B.inverse()
    psi = np.array([0.0, 10.0, 30.0, 45.0, 60.0, 90.0, 120.0, -30.0, -75.0, 170.0])
    r = np.radians(psi)
    b_B = np.stack([np.cos(r), np.sin(r), np.zeros_like(r)], axis=1)  # on the horizon (far)
    turn = patch_turn_deg(patch_jacobian(up.model, down.model, b_B @ up.T_C_B.R.T, T.R))
    expected = (180.0 - 2.0 * psi + 180.0) % 360.0 - 180.0  # wrapped to [-180, 180)
    np.testing.assert_allclose(np.cos(np.radians(turn)), np.cos(np.radians(expected)), atol=1e-9)
    np.testing.assert_allclose(np.sin(np.radians(turn)), np.sin(np.radians(expected)), atol=1e-9)
    fwd = stereo_forward_rig(model, 0.30)
    Tf = fwd.cameras[1].T_C_B @ fwd.cameras[0].T_C_B.inverse()
    v, u = np.mgrid[0:480:16, 0:480:16]
    b, ok = model.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1).astype(float))
    np.testing.assert_allclose(patch_turn_deg(patch_jacobian(model, model, b[ok], Tf.R)), 0.0, atol=1e-9)
    assert pair_turns(up.model, down.model, T.R) and not pair_turns(model, model, Tf.R)
    assert set(FrontEnd(rig, detector="orb")._turned) == {("cam0", "cam1"), ("cam1", "cam0")}
    assert not FrontEnd(fwd, detector="orb")._turned


def test_stereo_klt_finds_a_feature_turned_between_the_top_and_bottom_images():
    """top_bottom_turn's sphere at the rig's height was never one two-view track: stereo KLT
    follows translation only and none of its up-camera members was found in the down camera,
    whose image turns them by 180 - 2 psi. In the down image resampled into the up camera's
    geometry (TurnedPair) the corners of a plane 3 m ahead at the horizon are found where the
    down camera's model projects their plane points (ray-cast; 4-5 px of parallax), each within
    1 px and 90 % within 0.4 px, new or followed from a start 1.5 px off (given in the resampled
    image, where a far point sits at its up-camera pixel); on the images as they are, none is."""
    import cv2

    from trackers.association import TurnedPair, stereo_klt

    cv2.setNumThreads(1)
    rig, img_up, img_down, truth = _horizon_plane_pair()
    up, down = rig.cameras
    uv = cv2.goodFeaturesToTrack(img_up, 400, 0.01, 6).reshape(-1, 2).astype(float)
    b_up, _ = up.model.pixel_to_bearing(uv)
    uv_t, band = truth(b_up)
    uv, b_up, uv_t = uv[band], b_up[band], uv_t[band]
    assert len(uv) >= 30
    T = down.T_C_B @ up.T_C_B.inverse()
    tp = TurnedPair(up.model, down.model, T.R, T.t, img_up.shape, (0, 0), (0, 0))
    far, _ = down.model.bearing_to_pixel(b_up @ T.R.T)
    np.testing.assert_allclose(tp.to_virtual(far), uv, atol=1e-6)
    b_in_up = tp.resample(img_up, img_down)
    guess = tp.to_virtual(uv_t) + np.array([1.2, -0.9])
    for kw in ({}, {"guess_v": guess, "follow_levels": 1}):
        r = tp.stereo_klt(img_up, b_in_up, b_up, uv, **kw)
        assert len(r.idx) >= 0.9 * len(uv)
        err = np.linalg.norm(r.uv_b - uv_t[r.idx], axis=1)
        assert err.max() < 1.0 and np.percentile(err, 90) < 0.4
        expected_b, _ = down.model.pixel_to_bearing(r.uv_b)
        np.testing.assert_allclose(r.b_b, expected_b, atol=1e-9)
    plain = stereo_klt(img_up, img_down, b_up, uv, down.model, T.R, T.t)
    assert not np.any(np.linalg.norm(plain.uv_b - uv_t[plain.idx], axis=1) < 1.0)


def test_front_end_finds_the_up_cameras_horizon_features_in_the_down_image():
    """The front end's stereo search (FrontEnd._stereo) on the top/bottom rig: the up camera's ORB
    features on the plane at the horizon are found in the down image where the down camera's model
    projects their plane points (ray-cast), 80 % of them, within 1 px (none without TurnedPair)."""
    import cv2

    from trackers.frontend import FrontEnd

    cv2.setNumThreads(1)
    rig, img_up, img_down, truth = _horizon_plane_pair()
    fe = FrontEnd(rig, detector="orb")
    fe.process({"cam0": img_up, "cam1": img_down}, 0, 0.0)
    ft = fe.trackers["cam0"]
    uv_t, band = truth(ft.b_C)
    rows = band.nonzero()[0]
    assert len(rows) >= 15
    idx, uv_b, b_b = fe._stereo("cam0", "cam1", rows)
    assert len(idx) >= 0.8 * len(rows)
    assert np.linalg.norm(uv_b - uv_t[rows[idx]], axis=1).max() < 1.0
