"""A box track's id carried on by the feature track that lay on the box (issue 4: track id switches;
FrontEnd._box_hands_id). A drone found first by its lights, with an ORB track on its body that never
linked to the box, keeps the box's id when the lights go unseen: the feature track takes it.

Frames are drawn by hand (a textured patch moving on a blank sky, lights drawn on it); the expected
ids are the ids of the first reports, not values computed by the code under test."""

from __future__ import annotations

import cv2
import numpy as np

from estimators.rig import mono_forward_rig, stereo_forward_rig
from tests.trackers.conftest import Patch, SphereScene, equidistant, rot_axis
from tests.trackers.test_detectors_composite import draw_lights
from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleTrack

PATCH_RAD = np.radians(9)


def _run(n: int, lit) -> list[dict[str, int]]:
    """A drone on a mono rig: its textured body (9 deg radius) from frame 4 on, moving 0.6 deg a
    frame; lights 24 px apart on it in the frames k where ``lit(k)``, jumping 4 px up and down every
    frame (the box centre's motion over 3 frames is then 8 px off the body's: the box never links to
    the body's feature track, whose members all lie in the box). Returns per frame {label: id} of
    the reports on the drone (label ``drone``: the box; ``orb``: a feature track)."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    scene = SphereScene(model, blank_env=True)
    out = []
    for k in range(n):
        d = rot_axis([0, 1, 0], np.radians(0.6) * k) @ np.array([0.25, 0.05, 1.0])
        d = d / np.linalg.norm(d)
        patches = [Patch(d, PATCH_RAD, seed=3)] if k >= 4 else []
        img = cv2.cvtColor(scene.render(np.eye(3), patches), cv2.COLOR_GRAY2BGR)
        (u, v), = model.bearing_to_pixel(d[None])[0]
        if lit(k):
            dv = 4.0 * (-1) ** k
            draw_lights(img, (u + 12.0, v + dv), (u - 12.0, v + dv), radius=1)
        obs = fe.process({"cam0": img}, k, k / 30)
        assert not fe.boxers["cam0"].links  # (the premise: never linked)
        out.append({
            o.label: o.track_id for o in obs
            if o.status != "lost" and np.arccos(np.clip(o.views[0].b_C @ d, -1, 1)) < PATCH_RAD
        })
    return out


def test_when_the_lights_go_unseen_the_body_track_carries_the_box_id():
    """Lights from frame 0 to 15, the body from frame 4: two reports on the drone from frame 10 (the
    box under its first id, the body's feature track under its own). From frame 16 the lights are
    gone: the body's track is reported under the box's id in every frame after (before, under its
    own id: an id switch on the drone)."""
    out = _run(24, lambda k: k < 16)
    box_id, body_id = out[0]["drone"], out[10]["orb"]
    assert box_id < body_id
    assert all(on == {"drone": box_id, "orb": body_id} for on in out[10:16]), out[10:16]
    assert all(on == {"orb": box_id} for on in out[16:]), out[16:]


def test_when_the_lights_come_back_each_track_reports_on_its_own():
    """As above, the lights gone in frames 16-19 only (the box track coasts) and back from frame 20:
    the box reports under its id again and the body's track on its own again, under a fresh id (the
    id it had was reported lost when the box's id took it over: an id never comes back after its
    lost report), one id from then on."""
    out = _run(26, lambda k: k < 16 or k >= 20)
    box_id, body_id = out[0]["drone"], out[10]["orb"]
    assert all(on == {"orb": box_id} for on in out[16:20]), out[16:20]
    fresh = out[20].get("orb")
    assert fresh not in (None, box_id, body_id), out[20]
    assert all(on == {"drone": box_id, "orb": fresh} for on in out[20:]), out[20:]


def test_an_id_reported_lost_is_never_reported_again(monkeypatch):
    """A feature track (local id 5) merged into an id 3 (as when a box lends its id) is reported lost
    under 5 with ``merged_into`` 3; when it is given its own id back (``_box_keeps_id`` /
    ``_box_hands_id`` give-backs set ``_gid[5] = 5``) it is reported under a fresh id, not 5 again and
    not 3, keeps that id, and is reported lost once under it when it ends."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    b = np.array([0.0, 0.0, 1.0])
    tr = ObstacleTrack(5, "cam0", np.zeros(0, np.int64), b, sigma_rad=0.005, status="confirmed", hits=9)
    gr = fe.groupers["cam0"]
    gr.tracks[5] = tr
    step = {"seen": [tr], "lost": [], "ids": lambda absorbed: None}
    monkeypatch.setattr(fe, "_has_texture", lambda *a: True)
    monkeypatch.setattr(gr, "update", lambda *a, **k: (step["seen"], step["lost"]))
    monkeypatch.setattr(fe, "_box_keeps_id", lambda absorbed: step["ids"](absorbed))
    img = np.zeros((model.height, model.width, 3), np.uint8)

    def frame(k):
        return [(o.track_id, o.status, o.attributes) for o in fe.process({"cam0": img}, k, k / 30)]

    assert frame(0) == [(5, "confirmed", {})]
    step["ids"] = lambda absorbed: fe._merge_gids(3, 5, (5,), absorbed)
    assert frame(1) == [(3, "confirmed", {}), (5, "lost", {"merged_into": 3})]
    step["ids"] = lambda absorbed: fe._gid.__setitem__(5, 5)  # the give-back
    (fresh, status, _), = frame(2)
    assert fresh not in (3, 5) and status == "confirmed"
    step["ids"] = lambda absorbed: None
    assert frame(3) == [(fresh, "confirmed", {})]
    del gr.tracks[5]
    step["seen"], step["lost"] = [], [tr]
    assert frame(4) == [(fresh, "lost", {})]
    assert frame(5) == []


def _stereo_drone(run0: int = 3, run1: int = 3, feature_hits: int = 14):
    """stereo_flying frame 68 by hand: a drone's boxes in both cameras (cam0 box 10, cam1 box 11:
    one obstacle, global 10, seen 40 frames), both unseen this frame (coasting); an ORB track on it
    in each camera (cam1 20, cam0 21: global 20), seen now, that lay on the boxes (``placed``) in
    their last ``run0`` | ``run1`` updates and never linked."""
    rig = stereo_forward_rig(equidistant(), baseline_m=0.3)
    fe = FrontEnd(rig, detector="orb+navlights")
    b = np.array([0.0, 0.0, 1.0])
    none = np.zeros(0, np.int64)

    def track(tid, cam, hits, label="orb"):
        return ObstacleTrack(tid, cam, none, b, sigma_rad=0.005, status="confirmed", hits=hits, label=label)

    fe.boxers["cam0"].tracks[10], fe.boxers["cam1"].tracks[11] = track(10, "cam0", 40, "drone"), track(
        11, "cam1", 38, "drone")
    for t in (fe.boxers["cam0"].tracks[10], fe.boxers["cam1"].tracks[11]):
        t.seen = False
    fe.groupers["cam1"].tracks[20], fe.groupers["cam0"].tracks[21] = track(20, "cam1", feature_hits), track(
        21, "cam0", feature_hits - 6)
    fe.boxers["cam0"].placed = {10: {21: run0}}
    fe.boxers["cam1"].placed = {11: {20: run1}}
    for bx in fe.boxers.values():  # the box trackers have seen frames 1/30 s apart: link_s is 3 frames
        for k in range(3):
            bx.clock.tick(k / 30)
        bx._count()
    fe._gid.update({11: 10, 21: 20})
    fe._reported.update({10, 20})
    return fe


def test_a_coasting_stereo_box_hands_its_id_to_the_feature_tracks_in_both_cameras():
    """The box pair unseen: the feature tracks' obstacle (global 20, both cameras) takes the box's
    id 10 (the one seen longer), 20 reported lost once; while the boxes coast it stays; when a box
    of 10 is seen again each feature track takes back global id 20."""
    fe = _stereo_drone()
    absorbed: list[int] = []
    fe._box_hands_id(absorbed)
    assert {fe._global(t) for t in (10, 11, 20, 21)} == {10} and absorbed == [20]
    absorbed = []
    fe._box_hands_id(absorbed)
    assert fe._global(20) == fe._global(21) == 10 and absorbed == []
    fe.boxers["cam1"].tracks[11].seen = True
    fe._box_hands_id(absorbed)
    assert fe._global(20) == fe._global(21) == 20 and fe._global(11) == 10 and absorbed == []


def test_no_id_is_handed_without_a_track_that_lay_on_the_box_long_enough_or_to_an_older_track():
    """No hand-over: a track on the box in fewer than ``link_frames`` (3) updates in a row before it
    went unseen; the boxes seen; the feature track seen for more frames than the box (it keeps its
    own id: the id seen longer); the feature track unseen too."""
    fe = _stereo_drone(run0=2, run1=2)
    fe._box_hands_id([])
    assert fe._global(20) == 20
    fe = _stereo_drone()
    fe.boxers["cam0"].tracks[10].seen = True
    fe._box_hands_id([])
    assert fe._global(20) == 20
    fe = _stereo_drone(feature_hits=60)
    fe._box_hands_id([])
    assert fe._global(20) == 20 and fe._global(11) == 10
    fe = _stereo_drone()
    for gr in fe.groupers.values():
        for t in gr.tracks.values():
            t.seen = False
    fe._box_hands_id([])
    assert fe._global(20) == 20


def test_a_merged_id_is_reported_lost_with_the_id_it_was_merged_into(monkeypatch):
    """An id absorbed by a merge (``_merge_gids``: here a box lending its id) is reported lost once
    with ``attributes["merged_into"]``, the id that carries on (the fusion then continues its filter
    there when it was ranged more recently, ``ObstacleFusion._continued``); an id merged twice in a
    frame names the last one."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    fe._reported.update({9, 5})

    def merges(absorbed):
        fe._merge_gids(5, 9, (9,), absorbed)
        fe._merge_gids(3, 5, (5,), absorbed)

    monkeypatch.setattr(fe, "_box_keeps_id", merges)
    img = np.zeros((model.height, model.width, 3), np.uint8)
    obs = fe.process({"cam0": img}, 0, 0.0)
    assert [(o.track_id, o.status, o.attributes) for o in obs] == [
        (5, "lost", {"merged_into": 3}), (9, "lost", {"merged_into": 3})]


def test_an_id_is_handed_once_and_given_back_only_to_the_tracks_the_box_does_not_link():
    """The box pair's id 10 handed to global 20 (cam1 20, cam0 21). While it is handed and 20's tracks
    go unseen, another track on the box (cam0 30, placed long enough, seen) does not take 10 too (it
    would overwrite what 20's tracks are to take back); a box track under the feature track's global
    id (cam1 box 12 under 20) stops a hand-over; when the box is seen again linked to cam0's 21, 21
    stays under 10 (``_box_keeps_id``'s link) and only cam1's 20 takes back 20."""
    fe = _stereo_drone()
    fe._box_hands_id([])
    assert fe._box_handed == {10: {20: 20, 21: 20}}
    for gr in fe.groupers.values():
        for t in gr.tracks.values():
            t.seen = False
    b = np.array([0.0, 0.0, 1.0])
    fe.groupers["cam0"].tracks[30] = ObstacleTrack(30, "cam0", np.zeros(0, np.int64), b, sigma_rad=0.005,
                                                   status="confirmed", hits=5)
    fe.boxers["cam0"].placed = {10: {21: 3, 30: 3}}
    fe._reported.add(30)
    fe._box_hands_id([])
    assert fe._global(30) == 30 and fe._box_handed == {10: {20: 20, 21: 20}}
    fe.boxers["cam0"].tracks[10].seen = True
    fe.boxers["cam0"].links = {10: 21}
    fe._box_hands_id([])
    assert fe._global(21) == 10 and fe._global(20) == 20 and not fe._box_handed

    fe = _stereo_drone()
    fe.boxers["cam1"].tracks[12] = ObstacleTrack(12, "cam1", np.zeros(0, np.int64), b, sigma_rad=0.005,
                                                 status="confirmed", hits=3, label="drone")
    fe.boxers["cam1"].tracks[12].seen = False
    fe._gid[12] = 20
    fe._box_hands_id([])
    assert fe._global(20) == fe._global(21) == 20 and not fe._box_handed


def test_ended_ids_no_track_can_come_back_under_are_forgotten():
    """Past 4096 ended ids the front end keeps only those a track may still be reported under (a
    local track's id or global id, an id ``_box_handed`` saved): a long live run's memory stays
    bounded."""
    model = equidistant()
    fe = FrontEnd(mono_forward_rig(model), detector="orb+navlights")
    fe._ended = set(range(100, 5100))
    fe._gid[7] = 150
    fe.process({"cam0": np.zeros((model.height, model.width, 3), np.uint8)}, 0, 0.0)
    assert fe._ended == {150}
