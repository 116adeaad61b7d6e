"""One feature id, one obstacle per camera and frame, where the duplicates arise
(FrontEnd._release_found, FrontEnd._drop_listed), on hand-built member lists worked by hand from
their docstrings.

The rig: reference camera cam0 with grouper tracks A0 (local id 1, global 100, features 10, 11,
12), B0 (local 2, global 200, features 20, 21) and C0 (local 3, global 300, features 30, 31, 32);
cam1 with grouper tracks A1 (local 5, global 100, its own feature 51) and B1 (local 6, global 200,
features 50, 60, 70, 77) whose feature ids reach the reference ids through ``_pid['cam1']`` =
{50: 10, 60: 20, 70: 30} (other ids name themselves)."""

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


def _front_end():
    fe = object.__new__(FrontEnd)  # only the state the two methods read
    fe.rig = SimpleNamespace(cameras=(SimpleNamespace(name="cam0"), SimpleNamespace(name="cam1")))
    a0, b0, c0 = _track(1, "cam0", [10, 11, 12]), _track(2, "cam0", [20, 21]), _track(3, "cam0", [30, 31, 32])
    a1_own, b1 = _track(5, "cam1", [51]), _track(6, "cam1", [50, 60, 70, 77])
    fe.groupers = {"cam0": SimpleNamespace(tracks={1: a0, 2: b0, 3: c0}),
                   "cam1": SimpleNamespace(tracks={5: a1_own, 6: b1})}
    fe._gid = {1: 100, 2: 200, 3: 300, 5: 100, 6: 200}
    fe._pid = {"cam1": {50: 10, 60: 20, 70: 30}}
    return fe, (a0, b0, c0, a1_own, b1)


def test_a_found_reference_member_takes_its_id_from_cam1s_linked_feature():
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    # A1's reported view as _add_found_members leaves it: its own 51, then 10 and 11 found by
    # stereo KLT (2 found); C0's derived view in cam1 (_views_found): 30, 31, 32, all found
    a1_view = _track(5, "cam1", [51, 10, 11])
    c1 = _track(3, "cam1", [30, 31, 32])
    trs = [b1, a1_view]
    fe._release_found(trs, {1: 2}, [c1], "cam1")
    # B1 lists 50 (-> 10, found for A's view) and 70 (-> 30, found for C's view): both leave B1;
    # 60 and 77 stay, under the ids _observations reports (20, 77), with their own bearings
    new_b1 = trs[0]
    assert new_b1.members.tolist() == [20, 77]
    assert new_b1.member_b_C[:, 0].tolist() == [2.0, 4.0]
    # the views that hold the found points are unchanged; the grouper's track is not modified
    assert trs[1] is a1_view and c1.members.tolist() == [30, 31, 32]
    assert new_b1 is not b1 and b1.members.tolist() == [50, 60, 70, 77]
    assert fe.groupers["cam1"].tracks[6] is b1
    assert np.array_equal(new_b1.b_C, b1.b_C)


def test_a_copys_own_part_loses_an_id_found_for_another_view():
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    # B1's view is itself a copy (its own members already under reported ids, then 21 found);
    # C0's derived view lists 30, which B1's own 70 holds
    b1_view = _track(6, "cam1", [10, 20, 30, 77, 21])
    c1 = _track(3, "cam1", [30, 31, 32])
    trs = [a1_own, b1_view]
    fe._release_found(trs, {1: 1}, [c1], "cam1")
    assert trs[0] is a1_own
    assert trs[1].members.tolist() == [10, 20, 77, 21]  # the found 21 stays, at the end
    assert trs[1].member_b_C[:, 0].tolist() == [1.0, 2.0, 4.0, 5.0]


def test_only_reported_views_take_part():
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    # a second cam1 track of global 100 (not reported: _observations takes each camera's first
    # track per global id) whose copy found 20, and a derived view of global 100 after it: they
    # take no id from B1 (60 -> 20, 50 -> 10 stay)
    late = _track(7, "cam1", [20])
    derived_late = _track(1, "cam1", [10, 11, 12])
    fe._gid[7] = 100
    trs = [a1_own, b1, late]
    fe._release_found(trs, {2: 1}, [derived_late], "cam1")
    assert all(x is y for x, y in zip(trs, [a1_own, b1, late], strict=True))


def test_reverse_views_drop_ids_the_reference_camera_lists():
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    # a second reference track of global 100 (not reported) lists 90; reverse views E (global
    # 800) and F (global 900, as from a third camera), and G (global 800 again: not reported)
    a0_late = _track(4, "cam0", [90])
    fe._gid.update({4: 100, 8: 800, 9: 900, 10: 800})
    e, f, g = _track(8, "cam0", [11, 90, 91]), _track(9, "cam0", [91, 92]), _track(10, "cam0", [12])
    extra = [e, f, g]
    fe._drop_listed([a0, b0, a0_late], extra)
    # E: 11 is A0's (a reference feature is its own obstacle's point); 90 only a non-reported
    # track lists: it stays. F: 91 is listed by E before it. G is not reported: unchanged
    assert extra[0].members.tolist() == [90, 91]
    assert extra[0].member_b_C[:, 0].tolist() == [2.0, 3.0]
    assert extra[1].members.tolist() == [92]
    assert extra[1].member_b_C[:, 0].tolist() == [2.0]
    assert extra[2] is g
    assert e.members.tolist() == [11, 90, 91]  # copies: the views built are not modified


def test_nothing_listed_twice_changes_nothing():
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    trs = [a1_own, b1]
    fe._release_found(trs, {}, [], "cam1")
    assert trs[0] is a1_own and trs[1] is b1
    extra = [_track(8, "cam0", [90, 91])]
    fe._gid[8] = 800
    before = extra[0]
    fe._drop_listed([a0, b0, c0], extra)
    assert extra[0] is before


def test_derive_views_applies_both_rules_to_the_views_it_returns():
    """_derive_views itself, its view builders stubbed (they return hand-built views): the reverse
    view it returns for the reference camera no longer lists the id the reference camera's own
    track lists, and camera b's track gives up the id found for another obstacle's view (without
    the two calls in _derive_views the views come back unchanged; fisheye-des demo's tracks.jsonl
    differs without either)."""
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    fe.cams = {"cam0": None, "cam1": None}
    fe.trackers = {"cam0": None, "cam1": None}
    fe.reverse_views = True
    c1 = _track(3, "cam1", [30, 31, 32])  # C0's view found in cam1 (global 300: B1's 70 -> 30)
    e = _track(8, "cam0", [11, 90, 91])  # a reverse view (global 800) listing A0's 11
    fe._gid[8] = 800
    fe._add_found_members = lambda seen, ref, b: {}
    fe._unviewed_in_ref = lambda seen, b: [b1]
    fe._views_found = lambda a, b, todo, pid: [c1] if (a, b) == ("cam0", "cam1") else [e]
    seen = {"cam0": [a0, b0, c0], "cam1": [a1_own, b1]}
    out = fe._derive_views(seen, {"cam0": None, "cam1": None})
    assert [t.members.tolist() for t in out["cam0"]] == [[90, 91]]
    assert out["cam1"] == [c1]
    assert seen["cam1"][0] is a1_own
    assert seen["cam1"][1].members.tolist() == [10, 20, 77]  # 70 (-> 30) left for C's view
    assert seen["cam0"] == [a0, b0, c0]


def test_views_without_feature_bearings_neither_lose_nor_take_ids():
    """A view whose members have no per-feature bearings is reported without feature ids
    (_observations), so it lists no id twice: it keeps its members, and its members take no id
    from another view."""
    fe, (a0, b0, c0, a1_own, b1) = _front_end()
    fe._gid.update({4: 400, 8: 800, 9: 900})
    # cam1: A1's copy found 10 and 11 (2 found); a view of global 800 lists 10 without bearings
    a1_view = _track(5, "cam1", [51, 10, 11])
    no_b = _track(8, "cam1", [10], with_b=False)
    trs = [a1_view, no_b]
    fe._release_found(trs, {0: 2}, [], "cam1")
    assert trs[0] is a1_view and trs[1] is no_b
    # cam0: a reference track without bearings lists 11 (E keeps it); a reverse view without
    # bearings keeps 12, which A0 lists
    ref_no_b = _track(4, "cam0", [11], with_b=False)
    e, f = _track(8, "cam0", [11, 90]), _track(9, "cam0", [12], with_b=False)
    extra = [e, f]
    a0_12 = _track(1, "cam0", [12])  # A0 listing 12 alone
    fe._drop_listed([a0_12, ref_no_b], extra)
    assert extra[0] is e and extra[1] is f
