"""trackers.benchmark's id scoring (StickyIds): a pause of the obstacle's track (unseen for a few
frames, then reported again under its id) is not an id switch; a handover is, at the frame it began.
Hand-built frames; the expected switches are what the definition in StickyIds' docstring gives."""

from __future__ import annotations

from trackers.benchmark import StickyIds


def _run(frames):
    """frames: (ids on obstacle 4, alive_on, coasting) per due frame; returns every switch decided."""
    s = StickyIds()
    out = []
    for f, (ids, alive_on, coasting) in enumerate(frames):
        out += s.update(f, 4, set(ids), alive_on, set(coasting))
    return out + s.finish()


def test_a_pause_that_ends_back_on_the_obstacle_is_no_switch():
    # track 3 holds obstacle 4; it goes unseen for two frames (coasting) while track 1, beside it on
    # the obstacle, is reported; then 3 is reported on obstacle 4 again. No switch (the rule before
    # StickyIds counted 3 -> 1 at frame 1)
    frames = [
        ([3], {3: {4}}, []),
        ([1], {1: {4}}, [3]),
        ([1], {1: {4}}, [3]),
        ([1, 3], {1: {4}, 3: {4}}, []),
        ([1, 3], {1: {4}, 3: {4}}, []),
    ]
    assert _run(frames) == []


def test_pause_then_lost_is_a_switch_at_the_pause():
    frames = [
        ([3], {3: {4}}, []),
        ([1], {1: {4}}, [3]),  # 3 coasts, 1 is on the obstacle
        ([1], {1: {4}}, [3]),
        ([1], {1: {4}}, []),  # 3 lost
        ([1], {1: {4}}, []),
    ]
    sw = _run(frames)
    assert [(e["frame"], e["from"], e["to"], e["why"]) for e in sw] == [(1, 3, 1, "gone")]


def test_pause_then_back_on_another_obstacle_is_a_switch():
    frames = [
        ([3], {3: {4}}, []),
        ([1], {1: {4}}, [3]),
        ([1], {1: {4}, 3: {5}}, []),  # 3 is reported again, on obstacle 5
    ]
    sw = _run(frames)
    assert [(e["frame"], e["from"], e["to"], e["why"]) for e in sw] == [(1, 3, 1, "on obstacles [5]")]


def test_pause_still_open_at_the_end_counts():
    frames = [([3], {3: {4}}, []), ([1], {1: {4}}, [3]), ([1], {1: {4}}, [3])]
    sw = _run(frames)
    assert [(e["frame"], e["from"], e["to"]) for e in sw] == [(1, 3, 1)]


def test_a_track_that_ends_or_moves_is_a_switch_at_once():
    # 3 lost (neither reported nor coasting) while 1 is on the obstacle; then 1 moves to obstacle 5
    # while 2 is on it; a reported track on no obstacle keeps its id
    frames = [
        ([3], {3: {4}}, []),
        ([1], {1: {4}}, []),
        ([], {1: set()}, []),
        ([2], {1: {5}, 2: {4}}, []),
    ]
    sw = _run(frames)
    assert [(e["frame"], e["from"], e["to"]) for e in sw] == [(1, 3, 1), (3, 1, 2)]


def test_no_ids_on_the_obstacle_decides_nothing_and_keeps_the_pause_open():
    frames = [([3], {3: {4}}, []), ([1], {1: {4}}, [3]), ([], {}, [3]), ([3], {3: {4}}, [])]
    assert _run(frames) == []


def _score(frames):
    """One-to-one scoring over hand-built frames, each (ids on each due obstacle, alive_on); nothing
    coasts. Returns (switches as (obstacle, from, to), frames covered only under others' ids)."""
    s = StickyIds()
    out = []
    for f, (ids_on, alive_on) in enumerate(frames):
        s.begin_frame(alive_on)
        for oid, ids in ids_on.items():
            out += [(e["obstacle"], e["from"], e["to"]) for e in s.update(f, oid, set(ids), alive_on, set())]
    return out + [(e["obstacle"], e["from"], e["to"]) for e in s.finish()], s.shared


def test_a_track_on_two_obstacles_is_the_first_ones_id():
    # track 12 holds pole 3; its other camera's view strays onto sphere 5 passing the pole (demo,
    # frames 31-41 at 734926f: one id, two obstacles); then sphere 5 gets its own track 53. Sphere 5
    # never had an id of its own before 53: no switch (the scorer before made 12 the sphere's id
    # too, then 12 -> 53), and its 3 frames covered only under the pole's id are counted
    frames = [({3: {12}}, {12: {3}})] * 3
    frames += [({3: {12}, 5: {12}}, {12: {3, 5}})] * 3
    frames += [({3: {12}, 5: {53}}, {12: {3}, 53: {5}})] * 3
    assert _score(frames) == ([], {5: 3})


def test_real_switches_still_count_under_one_to_one():
    # the obstacle's track ends and another takes over: one switch
    frames = [({1: {7}}, {7: {1}})] * 2 + [({1: {9}}, {9: {1}})] * 2
    assert _score(frames)[0] == [(1, 7, 9)]
    # track 7 leaves obstacle 1 for obstacle 2 (whose own track 8 ends): 1 switches to 9, 2 to 7
    frames = [({1: {7}, 2: {8}}, {7: {1}, 8: {2}}), ({1: {9}, 2: {7}}, {7: {2}, 9: {1}})]
    assert _score(frames)[0] == [(1, 7, 9), (2, 8, 7)]
    # an id straying onto no obstacle for a frame is kept
    frames = [({1: {7}}, {7: {1}}), ({1: {9}}, {7: set(), 9: {1}}), ({1: {7, 9}}, {7: {1}, 9: {1}})]
    assert _score(frames)[0] == []
    # two tracks on one obstacle, the held one lost: a switch to the other
    frames = [({1: {3, 5}}, {3: {1}, 5: {1}}), ({1: {5}}, {5: {1}})]
    assert _score(frames)[0] == [(1, 3, 5)]


def _score_coasting(frames, order):
    """As _score with coasting tracks: frames (ids on each due obstacle, alive_on, coasting), the due
    obstacles updated in ``order``."""
    s = StickyIds()
    out = []
    for f, (ids_on, alive_on, coasting) in enumerate(frames):
        s.begin_frame(alive_on)
        for oid in order:
            if oid in ids_on:
                sw = s.update(f, oid, ids_on[oid], alive_on, coasting)
                out += [(e["obstacle"], e["from"], e["to"]) for e in sw]
    return out + [(e["obstacle"], e["from"], e["to"]) for e in s.finish()], s.shared


def test_a_pause_that_ends_on_two_obstacles_keeps_the_id_one_to_one():
    # track 3 holds obstacle 4, coasts a frame (track 1 on 4), then is reported on obstacles 4 and 5:
    # the pause ends with no switch (3 stays on 4), so 3 is 4's id in those frames and 5 is covered
    # only under it (2 shared frames); 5 then gets its own track 7: no switch (5 never had an id of
    # its own). Whichever obstacle is scored first in a frame. (Before: the pause's obstacle did not
    # own 3 in the frame its pause ended, 5 took 3 and was later scored a switch 3 -> 7.)
    frames = [
        ({4: {3}}, {3: {4}}, set()),
        ({4: {1}}, {1: {4}}, {3}),
        ({4: {3}, 5: {3}}, {3: {4, 5}}, set()),
        ({4: {3}, 5: {3}}, {3: {4, 5}}, set()),
        ({4: {3}, 5: {7}}, {3: {4}, 7: {5}}, set()),
    ]
    for order in ([4, 5], [5, 4]):
        assert _score_coasting(frames, order) == ([], {5: 2}), order


def test_an_id_two_obstacles_hold_is_the_first_ones():
    # track 12 is obstacle 1's id; while 1 is uncovered 12 lies on obstacle 2 only and becomes its id
    # (2 had none); then 12 lies on both: it stays 1's (1 got its id first), 2 is covered only under
    # it (2 shared frames), and neither is scored a switch
    frames = [({1: {12}}, {12: {1}})] * 2
    frames += [({1: set(), 2: {12}}, {12: {2}})] * 2
    frames += [({1: {12}, 2: {12}}, {12: {1, 2}})] * 2
    for order in ([1, 2], [2, 1]):
        assert _score_coasting([(i, a, set()) for i, a in frames], order) == ([], {2: 2}), order
