"""Step 3e of the grouper: a track whose members lie in two clusters with a gap between them that
is wide for the clusters' own spacing splits in two; a sparse stretch of one surface, a uniform
sparse surface and a part too small do not. Hand-built layouts: points on the lens's equidistant
fisheye placed by their pixel offsets from the axis along the image's x axis (where an
equidistant lens's pixel distances are angles: ``rad_px`` per pixel), all turning together about
the camera's y axis (one motion: only position can part them). The expected tracks follow from
the layouts' spacings and gaps, not from the code under test."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.errors import ConfigError
from tests.trackers.conftest import equidistant, rot_axis
from tests.trackers.test_grouping import PointFeatures
from trackers.grouping import ObstacleGrouper

RATE = np.radians(0.3)  # rad per frame about the camera's y axis, the same for every point


@pytest.fixture
def model():
    """A 1280 x 720 lens (0.0052 rad per pixel, as the scenes' 720p lenses): the layouts below
    span 50 px, 0.26 rad, over which a rotation's flow field stays within the grouper's flow
    tolerance (on the 320 x 240 test lens 50 px are 0.77 rad and the flows differ by more)."""
    return equidistant(1280, 720)


def at(model, x_px: float, y_px: float) -> np.ndarray:
    """Unit bearing (3,) of the pixel (x_px, y_px) from the principal point of the equidistant
    ``model``: angle off-axis ``rad_px * hypot(x, y)`` in the direction (x, y)."""
    rad_px = model.max_angle_rad / model.image_circle()[2]
    th, ph = rad_px * np.hypot(x_px, y_px), np.arctan2(y_px, x_px)
    return np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])


def grid(x0: float, nx: int, ny: int, step: float) -> list[tuple[float, float]]:
    """Pixel offsets of an nx x ny grid ``step`` px apart, left edge at x0, centred on y = 0."""
    return [(x0 + i * step, (j - (ny - 1) / 2) * step) for i in range(nx) for j in range(ny)]


def run(model, parts, frames: int = 24, **opts):
    """parts: lists of pixel offsets. Returns the grouper, the feature ids per part and per frame
    {track id: member-id set} of the tracks seen."""
    gr = ObstacleGrouper(iter(range(1, 1000)), **opts)
    ft = PointFeatures(model)
    ids, pts, part_ids = [], [], []
    for p in parts:
        part_ids.append(set(range(len(ids) + 1, len(ids) + 1 + len(p))))
        ids += list(range(len(ids) + 1, len(ids) + 1 + len(p)))
        pts += [at(model, x, y) for x, y in p]
    pts = np.array(pts)
    held = []
    for k in range(frames):
        R = rot_axis([0, 1, 0], RATE * k)
        ft.set(ids, pts @ R.T, k / 30.0)
        seen, _ = gr.update(ft, k / 30.0)
        held.append({t.id: set(t.members.tolist()) for t in seen})
    return gr, part_ids, held


# a 1 m sphere's few features beside a strip of ground that moves as it does: a 3 x 3 cluster and a
# 5 x 4 cluster, both 5 px apart inside, the gap between them 20 px (4 times their spacing, inside
# link_px 35, so they start as one track)
# (step 3e's numbers below: gap_min_part 3 and gap_persist 3, so that a small part is 2 points)
OPTS = {"gap_factor": 3.0, "gap_min_px": 12.0, "gap_min_part": 3, "gap_persist": 3}
SPHERE = grid(-40.0, 3, 3, 5.0)  # x from -40 to -30
GROUND = grid(-10.0, 5, 4, 5.0)  # x from -10 to 10: 20 px from the sphere's right column


def test_two_clusters_with_a_gap_split_into_two_tracks(model):
    """gap_factor 3: the gap (20 px) exceeds 3 x the spacing (5 px) and 12 px, both parts have at
    least 3 members: after gap_persist (3) frames as a candidate the 9 sphere points leave and
    start their own track; the ground keeps the old id (the larger part stays)."""
    gr, (a, b), held = run(model, [SPHERE, GROUND], **OPTS)
    first = next(k for k, h in enumerate(held) if h)
    (tid,) = held[first]
    assert held[first][tid] == a | b  # one track on both at first (they are within link_px)
    # the candidate is found on the track's next 3 updates; it leaves on the third
    for k in (first + 1, first + 2):
        assert held[k] == {tid: a | b}, k
    split = first + 3
    assert held[split][tid] == b
    others = [m for t, m in held[split].items() if t != tid]
    assert others == [a]
    for h in held[split:]:  # and they stay apart
        assert sorted(map(sorted, h.values())) == sorted([sorted(a), sorted(b)])
    assert gr.gap_splits == 1


def test_step_3e_is_off_by_default_and_its_other_defaults(model):
    """The same layout with the defaults: one track holds both clusters throughout (step 3e is
    opt-in). With gap_factor 3 and the other defaults (gap_persist 5, gap_min_part 4 <= 9) the
    sphere leaves on the track's fifth update."""
    gr, (a, b), held = run(model, [SPHERE, GROUND])
    assert all(list(h.values()) == [a | b] for h in held if h)
    assert gr.gap_splits == 0
    gr, (a, b), held = run(model, [SPHERE, GROUND], gap_factor=3.0)
    first = next(k for k, h in enumerate(held) if h)
    assert [len(h) for h in held[first : first + 6]] == [1, 1, 1, 1, 1, 2]
    assert sorted(map(sorted, held[-1].values())) == sorted([sorted(a), sorted(b)])


@pytest.mark.parametrize(
    "parts, why",
    [
        # the same clusters 12 px apart: 2.4 x their spacing, less than gap_factor 3 (and the
        # 12 px floor): a sparse stretch of one surface
        ([grid(-32.0, 3, 3, 5.0), GROUND], "sparse stretch"),
        # a uniform sparse surface: 6 x 6 points 10 px apart (no gap anywhere)
        ([grid(-25.0, 6, 6, 10.0)], "uniform"),
        # two sphere points 20 px from the ground: a part of 2 < gap_min_part 3 stays
        ([[(-30.0, 0.0), (-30.0, 5.0)], GROUND], "small part"),
        # a 6-px gap in a 5-px grid is 1.2 x the spacing (a missing feature, not a gap)
        ([grid(-31.0, 3, 3, 5.0), GROUND], "missing column"),
    ],
)
def test_what_is_not_a_gap_stays_one_track(model, parts, why):
    """gap_factor 3: every layout stays one track holding every point."""
    gr, ids, held = run(model, parts, **OPTS)
    every = set().union(*ids)
    assert any(held), why
    assert all(list(h.values()) == [every] for h in held if h), why
    assert gr.gap_splits == 0, why


def test_a_gap_wider_than_its_parts_spacing_but_under_the_floor_stays(model):
    """Clusters 2 px apart inside, 10 px apart: 5 x their spacing but under gap_min_px 12: no
    split; with gap_min_px 8 it splits (10 px > max(8, 3 x 2))."""
    parts = [grid(-24.0, 3, 3, 2.0), grid(-10.0, 5, 4, 2.0)]  # x -24..-20 and -10..-2
    gr, ids, held = run(model, parts, **OPTS)
    assert gr.gap_splits == 0
    gr, (a, b), held = run(model, parts, **{**OPTS, "gap_min_px": 8.0})
    assert gr.gap_splits == 1
    assert sorted(map(sorted, held[-1].values())) == sorted([sorted(a), sorted(b)])


@pytest.mark.parametrize(
    "opts",
    [
        {"gap_factor": 0.5},
        {"gap_factor": 1.0},
        {"gap_factor": float("nan")},
        {"gap_factor": True},
        {"gap_min_px": -1.0},
        {"gap_min_part": 1},
        {"gap_min_part": 2.5},
        {"gap_persist": 0},
    ],
)
def test_bad_step_3e_options_are_refused(opts):
    """Each bad option raises a ConfigError naming it."""
    with pytest.raises(ConfigError, match=next(iter(opts))):
        ObstacleGrouper(iter(range(1, 10)), **opts)
