"""FrontEnd._one_track_per_id on hand-built member lists (review of 4f994d8): which view keeps an
id that two reported views of one camera list, worked by hand from its docstring.

The rig: reference camera cam0 with grouper tracks A0 (local id 1, global 100, features 10, 11,
12) and B0 (local 2, global 200, features 20, 21); cam1 with grouper tracks A1 (local 5, global
100) and B1 (local 6, global 200) whose feature ids are cam1's own and reach the reference ids
through ``_pid['cam1']`` = {50: 10, 60: 20} (other ids name themselves)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from trackers.frontend import FrontEnd
from trackers.grouping import ObstacleTrack


def _track(tid: int, camera: str, members: list[int], with_b: bool = True) -> ObstacleTrack:
    m = np.array(members, np.int64)
    # row k's bearing is tagged by k + 1 in x (so a kept row can be told by its bearing)
    b = np.array([[k + 1.0, 0.0, 1.0] for k in range(len(m))]) if with_b else np.zeros((0, 3))
    return ObstacleTrack(tid, camera, m, np.array([0.0, 0.0, 1.0]), member_b_C=b)


def _front_end(seen_cam1_extra=()):
    fe = object.__new__(FrontEnd)  # only the state _one_track_per_id reads
    fe.rig = SimpleNamespace(cameras=(SimpleNamespace(name="cam0"), SimpleNamespace(name="cam1")))
    a0, b0 = _track(1, "cam0", [10, 11, 12]), _track(2, "cam0", [20, 21])
    # B1 is the grouper's own object: cam1 ids 50 (-> 10, owned by A), 60 (-> 20) and 77 (no
    # reference feature); A1's reported view is a modified copy (as _add_found_members leaves
    # it): reference ids already, 10 found by stereo KLT, and 77
    b1 = _track(6, "cam1", [50, 60, 77])
    a1_own = _track(5, "cam1", [51])
    a1_view = _track(5, "cam1", [10, 11, 77])
    fe.groupers = {"cam0": SimpleNamespace(tracks={1: a0, 2: b0}),
                   "cam1": SimpleNamespace(tracks={5: a1_own, 6: b1})}
    fe._gid = {1: 100, 2: 200, 5: 100, 6: 200}
    fe._pid = {"cam1": {50: 10, 60: 20}}
    seen = {"cam0": [a0, b0], "cam1": [b1, a1_view, *seen_cam1_extra]}
    return fe, seen, (a0, b0, b1, a1_own, a1_view)


def test_an_id_stays_in_its_owners_view_else_in_the_first_listed():
    fe, seen, (a0, b0, b1, a1_own, a1_view) = _front_end()
    fe._one_track_per_id(seen)
    # the reference camera lists no id twice: its views are the same objects
    assert seen["cam0"][0] is a0 and seen["cam0"][1] is b0
    new_b1, new_a1 = seen["cam1"]
    # 10 (B1's own 50 under its reference id) belongs to A0's obstacle (global 100): A1's view
    # keeps it although B1 is listed first; 77 has no owner: the first listed view (B1) keeps it
    assert new_a1.members.tolist() == [10, 11]
    assert new_a1.member_b_C[:, 0].tolist() == [1.0, 2.0]
    # B1's view: 20 (its 60) and 77, under reference ids as _observations reports them, rows kept
    assert new_b1.members.tolist() == [20, 77]
    assert new_b1.member_b_C[:, 0].tolist() == [2.0, 3.0]
    # copies: the groupers' tracks are untouched
    assert new_b1 is not b1 and b1.members.tolist() == [50, 60, 77]
    assert new_a1 is not a1_view and a1_view.members.tolist() == [10, 11, 77]
    assert fe.groupers["cam1"].tracks[6] is b1


def test_only_reported_views_take_part():
    # a second track of global 100 (not reported: _observations takes each camera's first track per
    # global id) and a view without per-feature bearings (reported without ids) list 11 and 10: they
    # neither lose nor take ids
    late = _track(7, "cam1", [11])
    no_b = _track(8, "cam1", [10], with_b=False)
    fe, seen, _ = _front_end((late, no_b))
    fe._gid[7] = 100
    fe._one_track_per_id(seen)
    assert seen["cam1"][2] is late and seen["cam1"][3] is no_b
    assert seen["cam1"][1].members.tolist() == [10, 11]
    assert seen["cam1"][0].members.tolist() == [20, 77]


def test_nothing_listed_twice_changes_nothing():
    fe, seen, (a0, b0, b1, a1_own, a1_view) = _front_end()
    seen["cam1"] = [a1_own, b1]  # 51 and 10, 20, 77: distinct
    fe._one_track_per_id(seen)
    assert seen["cam1"][0] is a1_own and seen["cam1"][1] is b1
