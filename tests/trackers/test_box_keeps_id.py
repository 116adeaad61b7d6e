"""Ids that carry on (issue 4: track id switches). A drone found first by its lights keeps the box
track's id when ORB later finds a feature track on it (FrontEnd._box_keeps_id; one camera sees the
box), and the two get their own ids back when the link ends.

Frames are drawn by hand (a textured patch moving on a blank sky, lights drawn on it or drifting off
it); the expected ids are the ids of the first reports, not values computed by the code under test."""

from __future__ import annotations

import cv2
import numpy as np

from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.trackers.conftest import Patch, SphereScene, equidistant, rot_axis
from tests.trackers.test_detectors_composite import draw_lights
from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleTrack

PATCH_RAD = np.radians(9)


def _frames(model, n: int, patch_from: int, drift_from: int | None = None, drift_deg: float = 2.0):
    """BGR frames of a drone: lights 18 px apart from frame 0 on, its textured body (a patch of 9 deg
    radius) from frame ``patch_from`` on, both moving 0.6 deg a frame; from ``drift_from`` on the
    lights move off the body by ``drift_deg`` more each frame. Yields (frame, body centre, lights'
    centre) directions."""
    scene = SphereScene(model, blank_env=True)
    for k in range(n):
        d = rot_axis([0, 1, 0], np.radians(0.6) * k) @ np.array([0.25, 0.05, 1.0])
        d = d / np.linalg.norm(d)
        patches = [Patch(d, PATCH_RAD, seed=3)] if k >= patch_from else []
        img = cv2.cvtColor(scene.render(np.eye(3), patches), cv2.COLOR_GRAY2BGR)
        off = 0.0 if drift_from is None or k < drift_from else np.radians(drift_deg) * (k - drift_from + 1)
        dl = rot_axis([1, 0, 0], off) @ d
        (u, v), = model.bearing_to_pixel(dl[None])[0]
        draw_lights(img, (u + 9.0, v), (u - 9.0, v), radius=1)
        yield img, d, dl


def _on(obs, d: np.ndarray, radius: float):
    return [
        o for o in obs
        if o.status != "lost" and any(np.arccos(np.clip(v.b_C @ d, -1, 1)) < radius for v in o.views)
    ]


def _drone(o) -> bool:
    return o.label == "drone" or o.attributes.get("box_label") == "drone"


def test_a_drone_found_first_by_its_lights_keeps_the_box_id_when_a_feature_track_takes_over():
    """The lights are seen from frame 0, the body's texture from frame 4: the feature track ORB makes
    on it is younger than the box track. Every frame the drone's report (the box's, then the feature
    track's once linked: box label and attributes) has the id of its first report, and at the end
    the drone has one report, the feature track's view (its member features)."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    ids = []
    for k, (img, d, _dl) in enumerate(_frames(model, 20, patch_from=4)):
        on = _on(fe.process({"cam0": img}, k, k / 30), d, PATCH_RAD)
        ids.append([o.track_id for o in on if _drone(o)])
    assert all(len(i) == 1 for i in ids) and {i[0] for i in ids} == {ids[0][0]}, ids
    assert len(on) == 1 and on[0].label == "orb" and len(on[0].views[0].feature_ids) >= 3


def test_when_the_lights_leave_the_body_each_track_reports_under_its_own_id():
    """As above, then from frame 20 the lights drift off the body (2 deg a frame, across its 9 deg
    radius): the link ends; the box is reported again under the drone's first id (label drone) and
    the body under an id of its own (label orb, no box label): two obstacles, two ids, not one
    report hiding the other."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    first = None
    for k, (img, d_k, dl) in enumerate(_frames(model, 34, patch_from=4, drift_from=20)):
        obs, d = fe.process({"cam0": img}, k, k / 30), d_k
        if first is None and _on(obs, dl, np.radians(3)):
            first = _on(obs, dl, np.radians(3))[0].track_id
    drone = [o for o in _on(obs, dl, np.radians(3)) if o.label == "drone"]
    body = [o for o in _on(obs, d, PATCH_RAD) if o.label == "orb"]
    assert [o.track_id for o in drone] == [first], [(o.track_id, o.label) for o in obs]
    assert len(body) == 1 and body[0].track_id != first and "box_label" not in body[0].attributes


def _linked_pair(fe: FrontEnd, box_id: int, feature_id: int) -> None:
    b = np.array([0.0, 0.0, 1.0])
    fe.boxers["cam0"].tracks[box_id] = ObstacleTrack(box_id, "cam0", np.zeros(0, np.int64), b, label="drone")
    fe.groupers["cam0"].tracks[feature_id] = ObstacleTrack(feature_id, "cam0", np.zeros(0, np.int64), b)
    fe.boxers["cam0"].links = {box_id: feature_id}
    for k in range(3):  # the box tracker has seen frames 1/30 s apart: link_s 0.1 s is 3 frames
        fe.boxers["cam0"].clock.tick(k / 30)
    fe.boxers["cam0"]._count()


def test_a_box_that_another_camera_sees_too_lends_no_id():
    """On a stereo rig a box seen by one camera only lends its id to the younger feature track
    linked to it, keeps lending it while it coasts, moves it to the track the link moved to (the
    first takes its own id back), and gets it back when seen unlinked 3 frames in a row; a box the
    other camera sees too (associated: one global id, ranged from its two views) lends none
    (accuracy: the feature track's view beside the other camera's box view under one id gave
    wrong, narrow ranges)."""
    fe = FrontEnd(stereo_forward_rig(equidistant(), baseline_m=0.3), detector="orb+navlights")
    _linked_pair(fe, 5, 9)
    absorbed: list[int] = []
    fe._box_keeps_id(absorbed)
    assert fe._global(9) == 5 and fe._global(5) == 5
    fe.boxers["cam0"].links = {}
    fe.boxers["cam0"].tracks[5].seen = False  # the box coasts (unseen, so unlinked): it keeps lending
    for _ in range(4):
        fe._box_keeps_id(absorbed)
        assert fe._global(9) == 5
    fe.boxers["cam0"].tracks[5].seen = True  # seen again, linked to a newer feature track 11 on it
    fe.groupers["cam0"].tracks[11] = ObstacleTrack(11, "cam0", np.zeros(0, np.int64), np.array([0.0, 0, 1]))
    fe.boxers["cam0"].links = {5: 11}
    fe._box_keeps_id(absorbed)
    assert fe._global(11) == 5 and fe._global(9) == 9  # 11 holds the box's id, 9 takes its own
    fe.boxers["cam0"].links = {}  # seen, not linked: each its own id after link_s (3 frames at 30 fps)
    for _ in range(2):
        fe._box_keeps_id(absorbed)
        assert fe._global(11) == 5
    fe._box_keeps_id(absorbed)
    assert fe._global(11) == 11 and fe._global(9) == 9 and fe._global(5) == 5
    fe = FrontEnd(stereo_forward_rig(equidistant(), baseline_m=0.3), detector="orb+navlights")
    _linked_pair(fe, 5, 9)
    fe.boxers["cam1"].tracks[6] = ObstacleTrack(6, "cam1", np.zeros(0, np.int64), np.array([0.0, 0.0, 1.0]))
    fe._gid[6] = 5  # cam1's box track 6 is the same obstacle: global track 5
    fe._box_keeps_id(absorbed)
    assert fe._global(9) == 9


def test_an_id_lent_on_a_stereo_association_frame_is_reported_lost(monkeypatch):
    """The feature track's own id, absorbed when a box lends it its id (before the association), is
    reported lost once also on a frame where the stereo association runs (every ``assoc_every``
    frames, the first one included): the association's absorbed ids are added to it, not put in
    its place (before, that frame's report had no lost id 9: fusion kept its track open)."""
    model = equidistant()
    fe = FrontEnd(stereo_forward_rig(model, baseline_m=0.3), detector="orb+navlights")
    fe._reported.add(9)  # feature track 9 was reported; this frame box track 5 lends it its id
    monkeypatch.setattr(fe, "_box_keeps_id", lambda absorbed: fe._merge_gids(5, 9, (9,), absorbed))
    img = np.zeros((model.height, model.width, 3), np.uint8)
    assert fe._n % fe.assoc_every == 0  # an association frame
    obs = fe.process({"cam0": img, "cam1": img}, 0, 0.0)
    assert [(o.track_id, o.status) for o in obs] == [(9, "lost")]


def test_a_box_folded_into_a_younger_feature_tracks_obstacle_keeps_its_older_id():
    """heldout_stereo_flying frame 79 by hand: a drone's boxes in both cameras (cam0 box 10, cam1
    box 11: one obstacle, global 10, seen 40 frames) and a younger ORB track on it in each camera
    (cam1 track 20, linked to cam1's box, and cam0 track 21, global 20, seen 29 frames). The box
    pair is folded into the feature tracks' obstacle (cam0's box lies on track 21: one report);
    the merged obstacle keeps the id seen longer, 10, as the other stereo merges (``_survivor``), and 20 is
    reported lost once. Before, the fold always kept the feature track's id: the drone's reported
    id changed 10 -> 20 (an id switch)."""
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    fe = FrontEnd(rig, detector="orb+navlights")
    p_B = np.array([4.0, 0.5, -0.3])  # the drone, 4 m ahead
    b0, b1 = (c.T_C_B.apply(p_B) / np.linalg.norm(c.T_C_B.apply(p_B)) for c in rig.cameras)
    none = np.zeros(0, np.int64)

    def track(tid, cam, b, hits, label="orb"):
        return ObstacleTrack(tid, cam, none, b, sigma_rad=0.005, status="confirmed", hits=hits, label=label)

    box0, box1 = track(10, "cam0", b0, 40, "drone"), track(11, "cam1", b1, 38, "drone")
    f1, f0 = track(20, "cam1", b1, 29), track(21, "cam0", b0, 25)
    fe.boxers["cam0"].tracks[10], fe.boxers["cam1"].tracks[11] = box0, box1
    fe.groupers["cam1"].tracks[20], fe.groupers["cam0"].tracks[21] = f1, f0
    fe.boxers["cam1"].links = {11: 20}
    fe._gid.update({11: 10, 21: 20})
    fe._reported.update({10, 20})
    seen = {"cam0": [f0, box0], "cam1": [f1, box1]}
    absorbed = fe._associate_boxes(seen)  # (a pair needs 2 frames in a row)
    assert absorbed == [] and fe._global(21) == 20
    absorbed = fe._associate_boxes(seen)
    assert absorbed == [20]
    assert {fe._global(t) for t in (10, 11, 20, 21)} == {10}
