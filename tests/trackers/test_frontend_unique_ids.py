"""One feature id, one obstacle per camera and frame (FrontEnd._release_found): a wrong link of
camera b's feature to a reference feature of ANOTHER obstacle (as descriptor links can pair
neighbouring corners along the epipolar line) must not make b list that reference id in two
tracks (at the linked feature and where stereo KLT found the reference feature): the id stays in
its own obstacle's view, at the bearing the rig's rotation puts it (an independent source)."""

from __future__ import annotations

import numpy as np

from tests.trackers.conftest import Patch, SphereScene, equidistant, rot_axis, turned_pair_rig


def _two_patch_rig():
    """(rig, R_1_0, frames(k)): cam1 = cam0 turned 3 degrees about y, same centre; a blank sky with
    two textured discs (12 deg radius) 50 deg apart, drifting 0.4 deg per frame."""
    model = equidistant(480, 360)
    rig, R_1_0 = turned_pair_rig(model)
    scene = SphereScene(model, blank_env=True)
    dA = np.array([0.45, 0.0, 1.0]) / np.hypot(0.45, 1.0)
    dB = np.array([-0.45, 0.0, 1.0]) / np.hypot(0.45, 1.0)

    def frames(k):
        R = rot_axis([1, 0, 0], np.radians(0.4) * k)
        p = [Patch(R @ dA, np.radians(12), seed=8), Patch(R @ dB, np.radians(12), seed=9)]
        return scene.render(None, p), scene.render(R_1_0.T, p)

    return rig, R_1_0, frames


def _listed(obs):
    """{(camera, feature id): [(track id, b_C (3,)), ...]} over one frame's observations."""
    out: dict = {}
    for o in obs:
        for v in o.views:
            for i, b in zip(v.feature_ids.tolist(), v.feature_b_C, strict=True):
                out.setdefault((v.camera, i), []).append((o.track_id, b))
    return out


def test_a_wrong_link_does_not_list_an_id_in_two_tracks():
    import cv2

    from trackers.frontend import FrontEnd

    cv2.setNumThreads(1)
    rig, R_1_0, frames = _two_patch_rig()
    fe = FrontEnd(rig, association={"every": 5})
    rad_px = fe._rad_px["cam1"]
    for f in range(11):  # association frame 10 last
        img0, img1 = frames(f)
        obs = fe.process({"cam0": img0, "cam1": img1}, f, f / 30.0)
    two = [o for o in obs if o.status == "confirmed" and {v.camera for v in o.views} == {"cam0", "cam1"}]
    assert len(two) == 2, "both discs are stereo tracks"
    # a reference member r of track A found in cam1, and a cam1 member f of track B (its own id)
    a, b = two
    va = {v.camera: v for v in a.views}
    shared = sorted(set(va["cam0"].feature_ids.tolist()) & set(va["cam1"].feature_ids.tolist()))
    assert shared
    r = shared[0]
    pid = fe._pid["cam1"]
    own_b = [t for t in fe.groupers["cam1"].tracks.values() if fe._global(t.id) == b.track_id]
    assert own_b
    f_b = next(i for i in own_b[0].members.tolist() if i not in pid)
    fe._claim["cam1"].pop(r, None)  # the wrong link: cam1's f_b (on disc B) taken for r (on A)
    for k, v in list(pid.items()):
        if v == r:
            del pid[k]
    pid[f_b] = r
    fe._claim["cam1"][r] = f_b
    img0, img1 = frames(11)  # not an association frame: the link stands
    obs = fe.process({"cam0": img0, "cam1": img1}, 11, 11 / 30.0)
    listed = _listed(obs)
    twice = {k: len(v) for k, v in listed.items() if len({t for t, _ in v}) > 1}
    assert not twice, f"ids listed by two tracks of one camera: {twice}"
    # cam1 lists r once, on its own obstacle A at R_1_0 b_0(r) (within 1 px of angle)
    b0 = {}
    for o in obs:
        for v in o.views:
            if v.camera == "cam0":
                for i, bb in zip(v.feature_ids.tolist(), v.feature_b_C, strict=True):
                    b0[i] = bb
    assert ("cam1", r) in listed
    ((tid, b1),) = listed[("cam1", r)]
    assert tid == a.track_id
    err = np.arccos(np.clip(b1 @ (R_1_0 @ b0[r]), -1.0, 1.0)) / rad_px
    assert err < 1.0
