"""Step 3f (ObstacleGrouper._plane_parts): an upright obstacle at one depth standing on the ground,
grouped with it, leaves the ground's planar flow field.

The flows are built from the closed form of a plane's translational flow on the unit sphere
(camera moving with velocity v over a plane n . X = h, derotated): ``f(b) = (n . b / h) (-(v -
(v . b) b))`` (inverse depth ``n . b / h`` along the ray b, times the tangent part of -v), not
from the code under test. The obstacle's members all move with the flow of the ground at its
base (one depth: the same inverse depth as the ground point it stands on), so its nearest
ground neighbours move as it does and step 3c has no step to cut at.
"""

import numpy as np
import pytest

from estimators.errors import ConfigError
from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.trackers.conftest import equidistant
from tests.trackers.test_grouping import PointFeatures, unit
from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleGrouper, ObstacleTrack, _tangent_basis

RAD_PX = 1.0 / 600.0  # rad per pixel
DT = 10 / 30.0  # a 10-frame window at 30 fps (s)
H_M = 1.5  # camera height over the ground (m)
N_C = np.array([0.0, 1.0, 0.0])  # ground normal in C (y down, towards the ground)
V_C = np.array([0.0, 0.0, 5.0])  # camera velocity in C (m/s, forward)


def _bearing(az, el):
    """Unit bearing (3,) in C at azimuth az (rad, +x right) and depression el (rad, +y down)."""
    b = np.array([np.tan(az), np.tan(el), 1.0])
    return b / np.linalg.norm(b)


def _ground_flow(b, v=V_C):
    """Flow (rad/s) (3,) of the ground point seen along unit bearing b (3,) (closed form above)."""
    inv_d = float(N_C @ b) / H_M
    return inv_d * -(v - float(v @ b) * b)


def _scene(blob: bool, seed: int = 0, speed: float = 1.0, noise_px: float = 0.2):
    """Members of one track: a grid of ground bearings 15 +- 5 deg below the horizon, the upper
    middle of which (azimuth within 1.6 deg, depression 10-12.5 deg) is an obstacle standing
    at depression 13.5 deg (blob=True: its members move with the ground at that point) or more
    ground (blob=False); the camera at ``speed`` times V_C, KLT noise ``noise_px`` over the
    window. Returns bearings (S,3), window flows in the track's tangent basis
    (S,2) rad/s, the blob's row mask (S,), e1, e2 (1,3)."""
    rng = np.random.default_rng(seed)
    b, on_blob = [], []
    for el_deg in np.arange(10.0, 20.01, 1.25):
        for az_deg in np.arange(-4.0, 4.01, 1.6):
            b.append(_bearing(np.radians(az_deg), np.radians(el_deg)))
            on_blob.append(abs(az_deg) < 1.7 and el_deg < 13.6)
    b, on_blob = np.array(b), np.array(on_blob)
    v = speed * V_C
    f = np.array([_ground_flow(bi, v) for bi in b])
    if blob:
        # one range for all its members: the inverse range of the ground point at its foot
        inv_d = float(N_C @ _bearing(0.0, np.radians(13.75))) / H_M
        f[on_blob] = [inv_d * -(v - float(v @ bi) * bi) for bi in b[on_blob]]
    rep = b.mean(0)
    rep /= np.linalg.norm(rep)
    e1, e2 = _tangent_basis(rep[None])
    xy = np.stack([f @ e1[0], f @ e2[0]], 1)
    xy += rng.normal(0.0, noise_px * RAD_PX / DT, xy.shape)  # KLT noise over the window
    return b, xy, on_blob, e1, e2


def _grouper():
    g = ObstacleGrouper(iter(range(1000)), plane_min=12)
    g.link_rad = g.max_radius_rad = np.radians(2.2)  # as set from the lens's scale on an update
    return g


def _parts(g, b, xy):
    n = len(b)
    rep = b.mean(0) / np.linalg.norm(b.mean(0))
    e1, e2 = _tangent_basis(rep[None])
    o, due = np.zeros(n, np.intp), np.ones(1, bool)
    return g._plane_parts(o, np.arange(n) + 100, b, e1, e2, xy, np.full(n, DT), 1, RAD_PX, due)


def test_flows_as_built():
    """The scene is what the test needs: the blob's members and their nearest ground neighbours
    below it differ by less than step 3c's link tolerance (so 3c cannot cut), while the ground's
    flow over the blob's extent changes by several pixels over the window."""
    b, xy, on_blob, *_ = _scene(blob=True)
    _, xy_g, *_ = _scene(blob=False)
    to_px = DT / RAD_PX
    px = np.hypot(*(xy - xy_g).T) * to_px  # blob flow minus the ground's at the same place
    assert on_blob.sum() == 6
    assert px[on_blob].max() > 7.0  # the top of the obstacle: far from the ground's flow
    # the obstacle's bottom row against the ground members just below it (the next row, 6 on)
    low = np.flatnonzero(on_blob)[-2:]
    d = np.hypot(*(xy[low] - xy[low + 6]).T) * to_px
    tol = 1.5 + 0.1 * np.hypot(*xy[low].T) * to_px  # step 3c's link tolerance (px)
    assert np.all(d < tol)


def test_blob_on_a_plane_leaves():
    b, xy, on_blob, *_ = _scene(blob=True)
    out = _parts(_grouper(), b, xy)
    assert list(out) == [0]
    part = out[0] - 100
    assert set(np.flatnonzero(on_blob)) <= set(part.tolist())  # the whole obstacle leaves
    assert len(part) <= on_blob.sum() + 2  # with at most two ground members at its foot


def test_plane_alone_stays():
    """Ground only (the same bearings, all on the plane): no part, over several noise draws."""
    g = _grouper()
    for seed in range(5):
        b, xy, *_ = _scene(blob=False, seed=seed)
        assert _parts(g, b, xy) == {}


def test_blob_within_noise_stays():
    """The same obstacle under 3 px of noise per member: its 3-7 px are not plane_z sigmas."""
    g = _grouper()
    for seed in range(3):
        b, xy, *_ = _scene(blob=True, seed=seed, noise_px=3.0)
        assert _parts(g, b, xy) == {}


def test_blob_under_link_tolerance_stays():
    """A slow camera (speed 0.2: flows ~5 px, the obstacle 0.6-1.5 px off the plane) and almost
    no noise: significant, but under step 3c's link tolerance (1.5 px + 0.1 |flow|)."""
    b, xy, *_ = _scene(blob=True, speed=0.2, noise_px=0.01)
    assert _parts(_grouper(), b, xy) == {}
    b, xy, *_ = _scene(blob=True, speed=1.0, noise_px=0.01)  # (the same at full speed leaves)
    assert list(_parts(_grouper(), b, xy)) == [0]


def test_on_by_default_and_off_at_zero():
    assert ObstacleGrouper(iter(range(10))).plane_min == 12
    assert ObstacleGrouper(iter(range(10)), plane_min=0).plane_min == 0


def test_bad_settings_named():
    with pytest.raises(ConfigError, match="plane_min"):
        ObstacleGrouper(iter(range(10)), plane_min=-1)
    with pytest.raises(ConfigError, match="plane_z"):
        ObstacleGrouper(iter(range(10)), plane_z=float("nan"))
    with pytest.raises(ConfigError, match="plane_every_s"):
        ObstacleGrouper(iter(range(10)), plane_every_s=-1.0)
    with pytest.raises(ConfigError, match="plane_ratio"):
        ObstacleGrouper(iter(range(10)), plane_ratio=-1.0)
    with pytest.raises(ConfigError, match="plane_z"):  # a string from a config file: named, not a TypeError
        ObstacleGrouper(iter(range(10)), plane_z="6")
    with pytest.raises(ConfigError, match="plane_ratio"):
        ObstacleGrouper(iter(range(10)), plane_ratio=None)


class _FixedPart(ObstacleGrouper):
    """Step 3f's model replaced by a stand-in that finds the part {rows 0-3} in a track holding
    them whenever that track is due from the grouper's frame ``found_from`` on, and logs the
    frames the big track was due: the persistence, the cameras' agreement and the frames a
    track is looked at are then the grouper's alone."""

    found_from = 0

    def _plane_parts(self, o, rows, b, e1, e2, xy, dt, T, rad_px, due):
        cnt = np.bincount(o, minlength=T)
        if np.any(due & (cnt >= 12)):
            self.due_log.append(self._frame)
        out = {}
        for t in np.flatnonzero(due & (cnt >= 12)).tolist():
            part = rows[(o == t) & (rows < 4)]
            if len(part) == 4 and self._frame >= self.found_from:
                out[t] = part
        return out


def _still_grid(g, frames: int):
    """A still 5 x 5 grid of points 4 px apart (one track of 25 members; ids 1..25 in row order)
    over ``frames`` frames at 30 fps. Returns per frame the member-id sets of the tracks seen."""
    model = equidistant()
    rad_px = model.max_angle_rad / model.image_circle()[2]
    g.due_log = []
    ft = PointFeatures(model)
    dirs = [unit([x * 4 * rad_px, y * 4 * rad_px, 1.0]) for x in range(-2, 3) for y in range(-2, 3)]
    ids = list(range(1, len(dirs) + 1))
    held = []
    for k in range(frames):
        ft.set(ids, np.array(dirs), k / 30.0)
        seen, _ = g.update(ft, k / 30.0)
        held.append(sorted(sorted(t.members.tolist()) for t in seen))
    return held


def test_a_part_found_split_persist_frames_in_a_row_leaves():
    g = _FixedPart(iter(range(1, 1000)), plane_min=12, plane_every_s=1 / 30)
    g.found_from = 12
    held = _still_grid(g, 20)
    assert held[10] == [list(range(1, 26))]  # one track before the part is found
    # found on frames 12, 13, 14 (the grouper's frame count is one ahead of the index): gone at 14
    first = next(i for i, h in enumerate(held) if len(h) == 2)
    assert first == 13
    assert held[-1] == [[1, 2, 3, 4], list(range(5, 26))]


def test_the_other_camera_must_find_a_part_too():
    """plane_confirm (set by the front end on a rig of several cameras) refuses: no split, the
    count goes on; once it agrees, the part leaves on that frame."""
    asked = []
    g = _FixedPart(iter(range(1, 1000)), plane_min=12, plane_every_s=1 / 30)
    g.plane_confirm = lambda tr: asked.append(tr.plane_n) or len(asked) >= 4
    g.found_from = 12
    held = _still_grid(g, 20)
    assert asked[:4] == [3, 4, 5, 6]  # asked from the third frame in a row on, every frame
    first = next(i for i, h in enumerate(held) if len(h) == 2)
    assert first == 13 + 3
    g = _FixedPart(iter(range(1, 1000)), plane_min=12, plane_every_s=1 / 30)
    g.plane_confirm = lambda tr: False
    held = _still_grid(g, 20)
    assert all(len(h) <= 1 for h in held) and held[-1] == [list(range(1, 26))]
    (tr,) = g.tracks.values()
    assert g.plane_recent(tr) and tr.plane_n >= 10


def test_a_track_is_looked_at_every_plane_every_frames_until_a_part_is_found():
    g = _FixedPart(iter(range(1, 1000)), plane_min=12, plane_every_s=0.1)
    g.found_from = 10**9  # never found
    _still_grid(g, 30)
    assert len(g.due_log) >= 6 and np.all(np.diff(g.due_log) == 3)
    g = _FixedPart(iter(range(1, 1000)), plane_min=12, plane_every_s=0.1)
    g.found_from = 12
    held = _still_grid(g, 30)
    f = next(k for k in g.due_log if k >= 12)  # found on its first look from frame 12 on
    assert f <= 14 and [k for k in g.due_log if f <= k <= f + 2] == [f, f + 1, f + 2]
    # gone on the third frame in a row (the held list's index is the grouper's frame - 1)
    assert next(i for i, h in enumerate(held) if len(h) == 2) == f + 1


def test_the_front_end_asks_the_other_camera_on_a_stereo_rig():
    assert FrontEnd(mono_forward_rig(equidistant())).groupers["cam0"].plane_confirm is None
    fe = FrontEnd(stereo_forward_rig(equidistant(), baseline_m=0.3))
    g0, g1 = fe.groupers["cam0"], fe.groupers["cam1"]
    assert g0.plane_confirm is not None and g1.plane_confirm is not None
    t0 = ObstacleTrack(3, "cam0", np.zeros(0, np.int64), np.array([0.0, 0.0, 1.0]))
    t1 = ObstacleTrack(7, "cam1", np.zeros(0, np.int64), np.array([0.0, 0.0, 1.0]))
    g0.tracks[3], g1.tracks[7] = t0, t1
    g1._frame = 5
    t1.plane_seen = 5  # cam1's view found a part in its latest update
    assert not g0.plane_confirm(t0)  # not the same obstacle (no association yet)
    fe._gid[7] = 3  # associated: cam1's track 7 is global track 3
    assert g0.plane_confirm(t0)
    g1._frame = 7  # its part was found two updates ago: no longer
    assert not g0.plane_confirm(t0)
    t0.plane_seen = g0._frame
    assert not g0.plane_confirm(t0)  # a camera's own part does not confirm itself
    assert g1.plane_confirm(t1)


def _sphere(seed: int):
    """One curved obstacle alone in a track: a sphere of radius 0.5 m centred 1.2 m ahead, the
    camera moving at (3, 0, 1) m/s; members on a 2-degree grid over its face (+-20 deg), each
    with the flow of the sphere point it sees (ray-sphere intersection, nearer root) plus 0.2 px
    of noise over the window. Returns bearings (S,3), window flows in the tangent basis (S,2)."""
    rng = np.random.default_rng(seed)
    c, r, v = np.array([0.0, 0.0, 1.2]), 0.5, np.array([3.0, 0.0, 1.0])
    b, f = [], []
    for az in np.arange(-20.0, 20.01, 2.0):
        for el in np.arange(-20.0, 20.01, 2.0):
            bi = _bearing(np.radians(az), np.radians(el))
            bc = float(bi @ c)
            disc = bc * bc - (float(c @ c) - r * r)  # t^2 - 2 t (b.c) + |c|^2 - r^2 = 0
            if disc > 0:
                b.append(bi)
                f.append(-(v - float(v @ bi) * bi) / (bc - np.sqrt(disc)))
    b, f = np.array(b), np.array(f)
    rep = b.mean(0) / np.linalg.norm(b.mean(0))
    e1, e2 = _tangent_basis(rep[None])
    xy = np.stack([f @ e1[0], f @ e2[0]], 1) + rng.normal(0.0, 0.2 * RAD_PX / DT, (len(b), 2))
    return b, xy


@pytest.mark.parametrize("seed", range(3))
def test_a_part_of_one_curved_obstacle_stays(seed):
    """No plane fits a near sphere's flow, so a disk of it is many sigmas off the plane of the
    rest (without plane_ratio it leaves), but the rest is as far from planar: rbar is a few of
    its own residuals, under plane_ratio (12)."""
    b, xy = _sphere(seed)
    g = _grouper()
    g.link_rad = g.max_radius_rad = np.radians(3.0)
    assert _parts(g, b, xy) == {}
    g.plane_ratio = 0.0
    assert list(_parts(g, b, xy)) == [0]
