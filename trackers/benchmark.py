"""Benchmark of the front end on a simulated scene: frame rate (with decoding), per-stage timings,
coverage of the visible obstacles, id switches, features tracked beyond 90 degrees off-axis.

    python -m trackers.benchmark SCENE_DIR [--detector orb+navlights] [--threads 1] [--frames N] [--no-poses]
                                 [--mjpeg QUALITY]

The front end gets the scene's true body poses (``T_W_B`` in ``gt.jsonl``) for its rotation
compensation, as the pipeline gets the trajectory's: ``--no-poses`` (``use_poses=False``) measures
it without them. ``poses`` in the result says whether any frame had one.

``SCENE_DIR`` is the output of ``fisheye-des simulate`` (``<cam>.mkv``, ``<cam>.timestamps.txt``,
``camchain.yaml``, ``gt.jsonl``, ``scene.yaml``). Reads files only (``--mjpeg`` writes its MJPEG copies beside
the videos); imports nothing from ``pipeline``.

The scene's videos are lossless colour FFV1, which no camera delivers and which cost far more to
decode (9-10 ms CPU a 1280x720 frame, 42-48 ms at 1920x1080) than the front end's own work. ``--mjpeg Q``
decodes the frames as a USB camera delivers them instead: each camera's video re-encoded once as
MJPEG (JPEG quality ``Q``, 4:2:2 chroma as a UVC camera's MJPEG; ``mjpeg_copy``), every packet
decoded by libjpeg-turbo (``cv2.imdecode``) straight to grey for a grey detector (``GREY_DETECTORS``,
the pipeline's rule), else to BGR. Decoding, the front end and the scoring then all run on those decoded
frames (their JPEG artefacts included); ``video`` in the result says what was decoded.

Mapping tracks to ground truth: a reported track's view in camera c is on obstacle k when the ray
from the camera centre along the view's bearing passes through obstacle k's shape (sphere, pole as
a capsule, box/wall, a drone as the box holding its body and lights, ``drone_shape``; shapes from
``scene.yaml``, positions from ``gt.jsonl``) inflated by ``margin_px`` pixels at that range; the
nearest such obstacle along the ray wins (occlusion). An obstacle is *covered* in a frame when
some reported track is on it; it counts from half a second after it first became visible
(``visible`` in any camera). The id of an obstacle's track is sticky (kept while it stays on the
obstacle); a change to another id while the obstacle is covered is an id switch; the id stays
while its track lives and is not on another obstacle, even if its representative point strays off
for a frame (CLEAR-MOT style). A track that lives unreported (coasting: unseen, not yet lost) is
paused, not ended: the switch is decided when the pause ends, none if it is reported on the
obstacle again, else one at the frame the pause began (``StickyIds``).
An id is one obstacle's in a frame (CLEAR-MOT's one-to-one matching): a track kept as one
obstacle's id that also lies on a second covers the second but does not become its id; such frames
are counted per obstacle as ``shared_id_frames``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from estimators.errors import FisheyeDesError, InputError, SourceError
from estimators.se3 import Pose, quat_to_rot
from trackers.detectors import GREY_DETECTORS


@dataclass
class Shape:
    """An obstacle's shape in W at one frame (kind: sphere | capsule | box)."""

    kind: str
    c_W: np.ndarray
    r_m: float = 0.0
    half_h_m: float = 0.0  # capsule: half length of the vertical axis
    half_size_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    yaw_rad: float = 0.0


def ray_hit_distance(o: np.ndarray, d: np.ndarray, s: Shape, margin_m: float) -> float | None:
    """Distance along the unit ray (o, d) (W, metres) to where it meets the inflated shape, or None."""
    if s.kind == "sphere" or s.kind == "capsule":
        if s.kind == "sphere":
            p = s.c_W
        else:  # closest point on the vertical axis segment to the ray: sample the axis
            zs = np.linspace(-s.half_h_m, s.half_h_m, 41)
            pts = s.c_W + np.outer(zs, [0.0, 0.0, 1.0])
            t = np.maximum((pts - o) @ d, 0.0)
            dist = np.linalg.norm(o + t[:, None] * d - pts, axis=1)
            p = pts[int(np.argmin(dist))]
        t = float((p - o) @ d)
        if t <= 0:
            return None
        dist = float(np.linalg.norm(o + t * d - p))
        return t if dist <= s.r_m + margin_m else None
    # box: slab test in the box frame (yaw about W z)
    c, sn = np.cos(-s.yaw_rad), np.sin(-s.yaw_rad)
    R = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
    ol, dl = R @ (o - s.c_W), R @ d
    h = s.half_size_m + margin_m
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-h - ol) / dl, (h - ol) / dl
    tmin = np.nanmax(np.minimum(t1, t2))
    tmax = np.nanmin(np.maximum(t1, t2))
    if tmax >= max(tmin, 0.0):
        return float(max(tmin, 0.0))
    return None


def ray_hits(o: np.ndarray, d: np.ndarray, s: Shape, margin_m: np.ndarray | float) -> np.ndarray:
    """Vectorised ``ray_hit_distance``: distances (N,) along unit rays d (N,3) from o (3,) (W, metres)
    to the inflated shape, ``inf`` where a ray misses. The capsule uses the closest approach of the
    ray's line to the axis segment (exact, where ``ray_hit_distance`` samples the axis)."""
    d = np.asarray(d, float).reshape(-1, 3)
    n = len(d)
    m = np.broadcast_to(np.asarray(margin_m, float), (n,))
    out = np.full(n, np.inf)
    if s.kind in ("sphere", "capsule"):
        if s.kind == "sphere":
            p = np.broadcast_to(s.c_W, (n, 3))
        else:
            # closest points of the line o + t d and the segment c + z e_z, z in [-h, h]:
            # w = o - c; z = (w_z - (d.w) d_z) / (1 - d_z^2) (clipped), then t = (c + z e_z - o) . d
            w = o - s.c_W
            dz = d[:, 2]
            den = np.maximum(1.0 - dz * dz, 1e-12)
            z = np.clip((w[2] - (d @ w) * dz) / den, -s.half_h_m, s.half_h_m)
            p = s.c_W[None, :] + z[:, None] * np.array([0.0, 0.0, 1.0])
        t = np.einsum("ij,ij->i", p - o, d)
        dist = np.linalg.norm(o + t[:, None] * d - p, axis=1)
        ok = (t > 0) & (dist <= s.r_m + m)
        out[ok] = t[ok]
        return out
    c, sn = np.cos(-s.yaw_rad), np.sin(-s.yaw_rad)
    R = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
    ol, dl = R @ (o - s.c_W), d @ R.T
    h = s.half_size_m[None, :] + m[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (-h - ol) / dl, (h - ol) / dl
    tmin = np.nanmax(np.minimum(t1, t2), axis=1)
    tmax = np.nanmin(np.maximum(t1, t2), axis=1)
    ok = tmax >= np.maximum(tmin, 0.0)
    out[ok] = np.maximum(tmin[ok], 0.0)
    return out


def shapes_for_frame(specs: dict[int, dict], gt_obstacles: list[dict]) -> dict[int, Shape]:
    """Shapes (W) of the obstacles of one gt.jsonl line, sizes from scene.yaml's obstacle specs."""
    out = {}
    for o in gt_obstacles:
        sp = specs.get(int(o["id"]), {})
        kind = o.get("kind", sp.get("kind"))
        c = np.asarray(o["p_W"], float)
        if kind == "sphere":
            out[o["id"]] = Shape("sphere", c, r_m=float(sp["radius_m"]))
        elif kind == "pole":
            out[o["id"]] = Shape("capsule", c, r_m=float(sp["radius_m"]), half_h_m=float(sp["height_m"]) / 2)
        elif kind in ("box", "wall"):
            size = sp.get("size_m") or ([0.2, 6.0, 4.0] if kind == "wall" else [1.0, 1.0, 1.0])
            out[o["id"]] = Shape(
                "box",
                c,
                half_size_m=np.asarray(size, float) / 2,
                yaw_rad=float(np.radians(sp.get("yaw_deg", 0.0))),
            )
        elif kind == "drone":
            out[o["id"]] = drone_shape(sp, c, np.asarray(o.get("v_W", (0.0, 0.0, 0.0)), float))
        else:  # anything else: bounding sphere
            out[o["id"]] = Shape("sphere", c, r_m=float(o.get("radius_m", 0.5)))
    return out


def drone_shape(spec: dict, bound_c_W: np.ndarray, v_W: np.ndarray) -> Shape:
    """A drone's shape in W: the simulator's flat body (``size_m``, default 0.5 x 0.5 x 0.12) with
    its three nav lights (spheres of ``light_radius_m``, default 0.05, their centres half a radius
    beyond the body's left, right and tail edges) as the one box that holds them all, turned by
    the drone's yaw (its heading when it moves faster than 0.1 m/s horizontally, else ``yaw_deg``).

    Not its bounding sphere: that sphere is as tall as the body is wide (a 0.5 x 0.12 m body seen
    from the side fills a fifth of it), so a ray past the drone onto what lies behind it was put
    on the drone. ``bound_c_W`` is gt.jsonl's ``p_W``, the centre of the bounding box of the parts'
    bounding spheres' centres: the body's centre sits ``(sx / 2 + lr / 2) / 2`` ahead of it."""
    sx, sy, sz = (float(s) for s in (spec.get("size_m") or (0.5, 0.5, 0.12)))
    lr = float(spec.get("light_radius_m", 0.05))
    yaw = float(np.radians(spec.get("yaw_deg", 0.0)))
    if np.hypot(v_W[0], v_W[1]) > 0.1:
        yaw = float(np.arctan2(v_W[1], v_W[0]))
    fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    c_W = bound_c_W + fwd * (sx / 2 + lr / 2) / 2
    half = np.array([sx / 2 + 1.5 * lr, sy / 2 + 1.5 * lr, max(sz / 2, lr)])
    return Shape("box", c_W, half_size_m=half, yaw_rad=yaw)


def merged_depth_kind(
    range_m: float, other_ranges_m: list[float], ratio: float = 1.5
) -> tuple[str, list[float]]:
    """How an obstacle merged into a track lying on other obstacles sits against them in depth.

    Args:
        range_m: the obstacle's surface range (m, ground truth) from the camera.
        other_ranges_m: the surface ranges (m) of the obstacles the holding track lies on.
        ratio: the depth factor that makes two obstacles "lined up" (1.5: 10 m and 15 m).
    Returns:
        (``lined_up`` when some other range differs from ``range_m`` by ``ratio`` or more either
        way, ``other / range_m >= ratio`` or ``<= 1 / ratio`` (one behind the other: a depth cue
        could part them), else ``side_by_side``; the ratios ``other / range_m``).
    """
    ratios = [float(r) / float(range_m) for r in other_ranges_m]
    lined = any(max(q, 1.0 / q) >= ratio for q in ratios if q > 0)
    return ("lined_up" if lined else "side_by_side"), ratios


class _Explainer:
    """What every coverage gap and id switch of a benchmark run is (``run_benchmark(explain=True)``).

    Per due frame an obstacle is not covered, the first cause that applies (features are put on an
    obstacle by casting their current rays against the scene's shapes, margin 1 px):
    ``no_features`` (none of any camera's live features is on it; split by ``rim``: its centre more
    than 90 deg off every seeing camera's axis, ``tiny``: angular radius under 4 px), ``young`` (its
    features are all younger than the grouper's ``min_age`` + ``flow_frames``, frame counts at the
    rate seen), ``ungrouped`` (old enough but in no seen track), ``coasting`` (a track that covered it
    last frame is unseen now),
    ``in_track_elsewhere`` (its features are members of a seen track whose representative bearing
    lies on another obstacle: ``merged_other``, or on none: ``rep_off``; per holding track ``rep_px``,
    per camera: the representative's angle from its members' mean and their RMS angle about it, px;
    ``in_track_rep_beside_members`` counts those gaps where it lies beyond that RMS in some camera:
    a representative left where the members it was set on were). ``merged_by_depth`` splits
    the ``merged_other`` gaps by the obstacles' ground-truth surface ranges: ``lined_up`` when the
    other obstacle's range differs from this one's by ``DEPTH_RATIO`` (1.5) or more (one behind the
    other: a depth cue could part them), else ``side_by_side``; each such event has ``range_ratio``.

    Per id switch: ``moved_to_other_obstacle`` (the old track now lies on another obstacle), else
    the old track is ``coasting`` (unseen but alive), ``absorbed`` (merged into another camera's
    track) or ``lost``; each with ``parallel`` when the new id had been on the obstacle while the old
    one was still reported (a split: two tracks on one obstacle) or ``new_after_gap`` otherwise.
    """

    DEPTH_RATIO = 1.5  # merged obstacles whose ranges differ by this factor are "lined up"

    def __init__(self, fe) -> None:
        self.fe = fe
        self.gaps: dict[str, int] = {}
        self.merged_depth: dict[str, int] = {}  # merged_other gaps: lined_up | side_by_side
        self.gap_by_obstacle: dict[int, dict[str, int]] = {}
        self.switches: dict[str, int] = {}
        self.events: list[dict] = []
        self.first_on: dict[tuple[int, int], int] = {}  # (gid, obstacle) -> first frame on it
        self.last_rep: dict[int, int] = {}  # gid -> last frame reported
        self.prev_cover: dict[int, set[int]] = {}  # obstacle -> gids covering it last frame

    def _local_tracks(self):
        fe = self.fe
        for cam, gr in fe.groupers.items():
            for tr in gr.tracks.values():
                yield cam, tr, fe._global(tr.id)

    def reported(self, f, alive_on) -> None:
        """This frame's reported tracks (gid -> obstacles they lie on), before its switches."""
        for gid in alive_on:
            for oid in alive_on[gid]:
                self.first_on.setdefault((gid, oid), f)

    def frame(self, f, T_W_B, shapes, line, on, alive_on, due_ids, c_B, R_B_C, rad_px) -> None:
        fe = self.fe
        for gid in alive_on:
            self.last_rep[gid] = f
        # every live feature: the obstacle it sits on, its age, its track (gid, seen) if any
        feat_on, feat_age, feat_gid, feat_seen = [], [], [], []
        for cam, feats in fe.last_features.items():
            if not len(feats) or cam not in fe.groupers:
                continue
            oW = T_W_B.apply(c_B[cam])
            dW = feats.b_C @ (T_W_B.R @ R_B_C[cam]).T  # b_W = R_W_B R_B_C b_C
            best = np.full(len(dW), np.inf)
            which = np.full(len(dW), -1)
            for oid, sh in shapes.items():
                rng = float(np.linalg.norm(sh.c_W - oW))
                t = ray_hits(oW, dW, sh, rad_px[cam] * rng)
                closer = t < best
                best[closer], which[closer] = t[closer], oid
            gid = np.full(len(dW), -1)
            seen = np.zeros(len(dW), bool)
            pos = {int(i): k for k, i in enumerate(feats.ids.tolist())}
            for tr in fe.groupers[cam].tracks.values():
                for m in tr.members.tolist():
                    k = pos.get(int(m))
                    if k is not None:
                        gid[k], seen[k] = fe._global(tr.id), tr.seen
            feat_on.append(which)
            feat_age.append(feats.age)
            feat_gid.append(gid)
            feat_seen.append(seen)
        if feat_on:
            fo, fa, fg, fs = (np.concatenate(x) for x in (feat_on, feat_age, feat_gid, feat_seen))
        else:
            fo = fa = fg = np.zeros(0, np.int64)
            fs = np.zeros(0, bool)
        gr0 = next(iter(fe.groupers.values()), None)
        min_age = (gr0.min_age + gr0.flow_frames) if gr0 is not None else 0
        alive_local = {g for _c, tr, g in self._local_tracks() if not tr.seen}
        for o in line["obstacles"]:
            oid = int(o["id"])
            if oid not in due_ids or on.get(oid):
                continue
            mine = fo == oid
            if not np.any(mine):
                cause = "no_features"
                # rim / tiny: where the obstacle is in the cameras that see it
                sub = "other"
                offs, sizes = [], []
                for cam, vis in o.get("visible", {}).items():
                    if not vis or cam not in c_B:
                        continue
                    p = np.asarray(o["p_W"], float) - T_W_B.apply(c_B[cam])
                    b = (T_W_B.R @ R_B_C[cam]).T @ p
                    offs.append(np.degrees(np.arccos(np.clip(b[2] / np.linalg.norm(b), -1, 1))))
                    sh = shapes.get(oid)
                    r_m = (
                        sh.r_m
                        if sh is not None and sh.kind != "box"
                        else float(np.min(sh.half_size_m) if sh is not None else 0.5)
                    )
                    sizes.append(r_m / max(np.linalg.norm(p), 1e-6) / rad_px[cam])
                if offs and min(offs) > 90:
                    sub = "rim"
                elif sizes and max(sizes) < 4:
                    sub = "tiny"
                cause += "/" + sub
            elif not np.any(fs[mine] & (fg[mine] >= 0)):
                if any(g in alive_local for g in self.prev_cover.get(oid, ())):
                    cause = "coasting"
                elif np.all(fa[mine] < min_age):
                    cause = "young"
                else:
                    cause = "ungrouped"
            else:
                gs = set(fg[mine & fs & (fg >= 0)].tolist())
                if any(alive_on.get(g) for g in gs):
                    cause = "in_track_elsewhere/merged_other"
                else:
                    cause = "in_track_elsewhere/rep_off"
            self.gaps[cause] = self.gaps.get(cause, 0) + 1
            per = self.gap_by_obstacle.setdefault(oid, {})
            per[cause] = per.get(cause, 0) + 1
            ev = {"frame": f, "obstacle": oid, "gap": cause, "features_on": int(np.sum(mine))}
            if cause.startswith("in_track"):
                # the tracks holding its features: where they lie and what their members are on
                rng = {int(x["id"]): x.get("surface_range_m") for x in line["obstacles"]}
                if cause.endswith("merged_other") and rng.get(oid):
                    # merged with an obstacle at a clearly other depth (lined up along the line of
                    # sight) or at about the same depth (side by side): what a depth cue could part
                    others = [rng[k] for g in gs for k in alive_on.get(g, ()) if k != oid and rng.get(k)]
                    kind, ratios = merged_depth_kind(rng[oid], others, self.DEPTH_RATIO)
                    self.merged_depth[kind] = self.merged_depth.get(kind, 0) + 1
                    ev["range_ratio"] = [round(r, 3) for r in ratios]
                ev["tracks"] = {
                    int(g): {
                        "on": sorted(alive_on.get(g, ())),
                        "members_on": {
                            int(k): int(v)
                            for k, v in zip(*np.unique(fo[fs & (fg == g)], return_counts=True), strict=True)
                        },
                        "rep_px": self._rep_px(g, rad_px),
                    }
                    for g in sorted(gs)
                }
            self.events.append(ev)
        self.prev_cover = {oid: set(g) for oid, g in on.items()}

    def _rep_px(self, gid: int, rad_px: dict[str, float]) -> dict[str, list[float]]:
        """Per camera seeing track ``gid``: [the representative bearing's angle from its members'
        normalised mean, the members' RMS angle about that mean] in px at the camera's scale (a
        representative farther off than its members spread lies beside them: it moves with them
        and is pulled only slowly to their mean, so it stays where the members it was set on were)."""
        out = {}
        for cam, tr, g in self._local_tracks():
            if g != gid or not tr.seen or not len(tr.member_b_C):
                continue
            m = tr.member_b_C.sum(0)
            m = m / np.linalg.norm(m)
            a = np.arccos(np.clip(tr.member_b_C @ m, -1.0, 1.0))
            d = float(np.arccos(np.clip(tr.b_C @ m, -1.0, 1.0)))
            out[cam] = [round(d / rad_px[cam], 2), round(float(np.sqrt(np.mean(a * a))) / rad_px[cam], 2)]
        return out

    def switch(self, f, oid, old, new, alive_on) -> None:
        fe = self.fe
        if old in alive_on:
            cause = "moved_to_other_obstacle"
        else:
            local = {tr.id for _c, tr, _g in self._local_tracks()}
            live = {g for _c, _t, g in self._local_tracks()}
            if old in local and fe._global(old) != old:
                cause = "absorbed"
            elif old in live:
                cause = "coasting"
            else:
                cause = "lost"
            fo = self.first_on.get((new, oid))
            par = fo is not None and fo <= self.last_rep.get(old, -1)
            cause += "/parallel" if par else "/new_after_gap"
        self.switches[cause] = self.switches.get(cause, 0) + 1
        self.events.append(
            {
                "frame": f,
                "obstacle": oid,
                "switch": cause,
                "from": old,
                "to": new,
                "old_last_reported": self.last_rep.get(old),
                "new_first_on": self.first_on.get((new, oid)),
            }
        )

    def summary(self) -> dict:
        return {
            "gap_causes": dict(sorted(self.gaps.items(), key=lambda kv: -kv[1])),
            "gap_causes_by_obstacle": {k: self.gap_by_obstacle[k] for k in sorted(self.gap_by_obstacle)},
            "merged_by_depth": self.merged_depth,
            # in_track_elsewhere gaps where a track holding the obstacle's features has its
            # representative beside its members (farther from their mean than their RMS angle)
            "in_track_rep_beside_members": sum(
                any(d > rms for v in e["tracks"].values() for d, rms in v["rep_px"].values())
                for e in self.events
                if str(e.get("gap", "")).startswith("in_track")
            ),
            "switch_causes": dict(sorted(self.switches.items(), key=lambda kv: -kv[1])),
            "events": self.events,
        }


class StickyIds:
    """Each obstacle's track id and its id switches (``run_benchmark``'s scoring, CLEAR-MOT style).

    An obstacle's id is sticky: it stays while its track is reported and on no other obstacle (a
    reported track on no obstacle keeps it: its representative point strayed off for a frame). When
    it does not stay and other tracks are on the obstacle, the lowest of their ids takes over: an id
    switch. One exception, a pause: the id's track is unreported but alive (coasting: unseen, not
    yet lost). Then the switch is decided when the pause ends: none if the track is reported again
    and stays (the id never changed for a reader of the reports), else (lost, or back on another
    obstacle, or still coasting at the end of the run) the switch counts, at the frame the pause
    began, to the id that took over then.

    An id is one obstacle's in a frame (CLEAR-MOT's one-to-one matching; ``begin_frame``): an id
    kept by one obstacle is not free to become another's, so a track lying on two obstacles at once
    (one camera's view on each) stays the first one's id, and the second is covered but not under an
    id of its own (counted in ``shared``: frames covered only under other obstacles' ids) instead of
    switching to that id and later away from it.
    """

    def __init__(self) -> None:
        self.sticky: dict[int, int] = {}
        self.pending: dict[int, tuple[int, int, int]] = {}  # obstacle -> (frame, paused id, next id)
        self.owner: dict[int, int] = {}  # id -> the obstacle it is this frame's id of
        self.shared: dict[int, int] = {}  # obstacle -> frames covered only under others' ids

    def begin_frame(self, alive_on: dict[int, set[int]]) -> None:
        """A new frame: every obstacle whose id stays (reported, on it or on no obstacle) owns it,
        when two could the one that first got an id (``sticky``'s insertion order). A paused
        obstacle whose id is reported again and stays owns it too (its pause ends in ``update``
        with no switch): else another obstacle under that track could take the id in this frame."""
        self.owner = {}
        for oid, st in self.sticky.items():
            if self._stays(st, oid, alive_on):
                self.owner.setdefault(st, oid)

    @staticmethod
    def _stays(st: int, oid: int, alive_on: dict[int, set[int]]) -> bool:
        return st in alive_on and (not alive_on[st] or oid in alive_on[st])

    def update(
        self, f: int, oid: int, ids: set[int], alive_on: dict[int, set[int]], coasting: set[int]
    ) -> list[dict]:
        """Obstacle ``oid`` in due frame ``f``: ``ids`` the reported tracks on it, ``alive_on`` every
        reported track -> the obstacles it is on, ``coasting`` the live tracks not reported. Returns
        the switches decided now (frame, obstacle, from, to, why)."""
        out = []
        st = self.sticky.get(oid)
        p = self.pending.get(oid)
        if p is not None and (st in alive_on or st not in coasting):  # the pause ended
            del self.pending[oid]
            if not self._stays(st, oid, alive_on):  # lost, or back on another obstacle
                why = "gone" if st not in alive_on else f"on obstacles {sorted(alive_on[st])}"
                out.append({"frame": p[0], "obstacle": oid, "from": st, "to": p[2], "why": why})
                self.sticky[oid] = st = p[2]
        if oid in self.pending:
            return out
        if not (st is not None and self._stays(st, oid, alive_on) and self.owner.get(st, oid) == oid) and ids:
            free = [i for i in ids if self.owner.get(i, oid) == oid]
            if not free:  # covered only by ids other obstacles hold this frame
                self.shared[oid] = self.shared.get(oid, 0) + 1
                return out
            new = min(free)
            if st is not None and new != st:
                if st not in alive_on and st in coasting:
                    self.pending[oid] = (f, st, new)
                    return out
                why = "gone" if st not in alive_on else f"on obstacles {sorted(alive_on[st])}"
                out.append({"frame": f, "obstacle": oid, "from": st, "to": new, "why": why})
            self.sticky[oid] = new
            self.owner[new] = oid
        return out

    def finish(self) -> list[dict]:
        """The pauses not ended while their obstacle was due (it left the view first, or the run
        ended): each a switch (the obstacle was last reported under the other id)."""
        out = [
            {"frame": fr, "obstacle": oid, "from": st, "to": new, "why": "not reported on it again"}
            for oid, (fr, st, new) in sorted(self.pending.items())
        ]
        self.pending.clear()
        return out


def mjpeg_copy(video: Path, quality: int) -> Path:
    """``video`` re-encoded as a camera's MJPEG: ``<stem>.q<quality>.mjpeg`` beside it, each frame one
    baseline JPEG (``quality`` 1-100, 4:2:2 chroma), the JPEGs back to back (FFmpeg's raw ``mjpeg``
    format: a VideoCapture with ``CAP_PROP_FORMAT`` -1 reads them back one packet a frame).

    Made once and reused while it is newer than ``video`` (written to a temporary file, then renamed:
    a killed run leaves no partial copy). Raises InputError for a quality outside 1..100, SourceError
    when ``video`` cannot be read."""
    if not 1 <= int(quality) <= 100:
        raise InputError(f"benchmark: expected a JPEG quality in 1..100, got {quality}")
    out = video.with_name(f"{video.stem}.q{int(quality)}.mjpeg")
    if out.exists() and out.stat().st_mtime_ns >= video.stat().st_mtime_ns:
        return out
    cap = cv2.VideoCapture(str(video), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        raise SourceError(f"benchmark: cannot open video {video}")
    params = [
        cv2.IMWRITE_JPEG_QUALITY,
        int(quality),
        cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
        cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422,
    ]
    tmp = out.with_name(f".{out.name}.{os.getpid()}.part")
    try:
        with tmp.open("wb") as f:
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                f.write(cv2.imencode(".jpg", img, params)[1].tobytes())
        os.replace(tmp, out)
    finally:
        cap.release()
        tmp.unlink(missing_ok=True)
    return out


def open_scene(scene_dir: Path, threads: int | None = None, mjpeg_quality: int | None = None):
    """(rig, captures {cam: VideoCapture}, timestamps {cam: {frame: t_s}}, gt {frame: line}, specs).

    ``threads``: the video decoder's threads (None: FFmpeg's default, one per core). Decoding with
    its own threads runs ahead of the reads, so its CPU time would be booked to whatever runs then.
    ``mjpeg_quality``: read each camera's ``mjpeg_copy`` at that quality instead, as undecoded JPEG
    packets (``CAP_PROP_FORMAT`` -1; the caller decodes them)."""
    from estimators.calibration import load_kalibr

    scene_dir = Path(scene_dir)
    rig = load_kalibr(scene_dir / "camchain.yaml")
    caps, stamps = {}, {}
    for cam in rig.cameras:
        p = scene_dir / f"{cam.name}.mkv"
        if mjpeg_quality is not None:
            p = mjpeg_copy(p, mjpeg_quality)
        params = [] if threads is None else [cv2.CAP_PROP_N_THREADS, int(threads)]
        cap = cv2.VideoCapture(str(p), cv2.CAP_FFMPEG, params)
        if not cap.isOpened():
            raise SourceError(f"benchmark: cannot open video {p}")
        if mjpeg_quality is not None and not cap.set(cv2.CAP_PROP_FORMAT, -1):
            raise SourceError(f"benchmark: cannot read {p}'s packets undecoded")
        caps[cam.name] = cap
        st = {}
        for line in (scene_dir / f"{cam.name}.timestamps.txt").read_text().splitlines():
            if line.strip():
                f, t = line.split()[:2]
                st[int(f)] = float(t)
        stamps[cam.name] = st
    gt = {}
    gp = scene_dir / "gt.jsonl"
    if gp.exists():
        for line in gp.read_text().splitlines():
            if line.strip():
                d = json.loads(line)
                gt[int(d["frame"])] = d
    specs = {}
    sp = scene_dir / "scene.yaml"
    if sp.exists():
        for o in (yaml.safe_load(sp.read_text()) or {}).get("obstacles", []) or []:
            specs[int(o["id"])] = o
    return rig, caps, stamps, gt, specs


def run_benchmark(
    scene_dir: str | Path,
    detector: str = "orb+navlights",
    threads: int = 1,
    max_frames: int | None = None,
    margin_px: float = 2.0,
    use_poses: bool = True,
    explain: bool = False,
    mjpeg_quality: int | None = None,
    **frontend_options: Any,
) -> dict[str, Any]:
    """Run the FrontEnd over a simulated scene and measure it (see the module docstring).

    Wall-clock rates (``fps``) suffer from other processes on a shared machine; ``fps_cpu`` uses
    this process's CPU time (``time.process_time``), which with one OpenCV thread and the decoder
    on ``threads`` threads too is the work done (decode and front end booked apart).

    Returns a dict: frames, fps (decode + front end), fps_frontend, their CPU-time versions, ms per
    stage, coverage per obstacle (and overall), id switches per obstacle and per obstacle-minute,
    distinct track ids seen on each obstacle, reported tracks on no obstacle per frame (the ground,
    false groups: ``off_obstacle_tracks_per_frame``; of them confirmed:
    ``off_obstacle_confirmed_per_frame``), tracks the groupers split by motion
    (``track_splits``, step 3c) (``switch_log``: frame, obstacle, old and new id, why the old one no
    longer counts), rim features.
    ``use_poses``: pass the scene's true ``T_W_B`` per frame (when ``gt.jsonl`` has it) to the
    front end, as the pipeline passes its trajectory's poses; False: none (no rotation compensation).
    ``explain``: also ``explain``, the cause of every coverage gap and id switch (``_Explainer``;
    CPU time per frame then includes the analysis, so rates are not comparable).
    ``mjpeg_quality``: decode and score the frames of the scene's MJPEG copy at that JPEG quality
    (``mjpeg_copy``; see the module docstring) instead of its lossless videos. ``video`` in the
    result says what was decoded: ``format`` (the stream's codec tag: ``ffv1``, ``mjpg``), to what
    (``decoded_to``: ``bgr``, or ``grey`` from MJPEG for a grey detector, ``GREY_DETECTORS``) and
    the JPEG ``quality``.
    """
    from trackers.frontend import STAGES, FrontEnd

    cv2.setNumThreads(int(threads))
    rig, caps, stamps, gt, specs = open_scene(
        Path(scene_dir), threads=int(threads), mjpeg_quality=mjpeg_quality
    )
    fe = FrontEnd(rig, detector=detector, **frontend_options)
    colour = str(detector).lower() not in GREY_DETECTORS  # the pipeline's rule
    jpeg_flag = cv2.IMREAD_COLOR if colour else cv2.IMREAD_GRAYSCALE
    names = [c.name for c in rig.cameras]
    fourcc = int(caps[names[0]].get(cv2.CAP_PROP_FOURCC))
    video: dict[str, Any] = {
        "format": "".join(chr((fourcc >> 8 * i) & 0xFF) for i in range(4)).strip().lower()
    }
    if mjpeg_quality is None:
        video["decoded_to"] = "bgr"
    else:
        video.update(quality=int(mjpeg_quality), decoded_to="bgr" if colour else "grey")
    ex = _Explainer(fe) if explain else None
    frames = sorted(stamps[names[0]])
    if max_frames:
        frames = frames[:max_frames]
    R_B_C = {c.name: c.T_C_B.R.T for c in rig.cameras}
    c_B = {c.name: c.centre_B for c in rig.cameras}
    rad_px = {c.name: c.model.rad_per_px for c in rig.cameras}
    t_decode = t_front = c_decode = c_front = 0.0
    stage = dict.fromkeys(STAGES, 0.0)
    first_seen: dict[int, float] = {}
    due: dict[int, int] = {}
    covered: dict[int, int] = {}
    sticky = StickyIds()
    switches: dict[int, int] = {}
    switch_log: list[dict] = []
    ids_on: dict[int, set[int]] = {}  # obstacle -> every track id seen on it (due frames)
    rim_feats, rim_old = 0, 0
    n_obs = 0
    n_off = n_gt = 0  # tracks on no obstacle, frames with ground truth
    n_off_conf = 0  # ... of them confirmed
    confirmed_ids: set[int] = set()  # this frame's confirmed track ids
    posed = False  # some frame was given its pose
    for f in frames:
        c0 = time.process_time()
        t0 = time.perf_counter()
        imgs = {}
        for n in names:
            ok, img = caps[n].read()
            if not ok:
                raise SourceError(f"benchmark: {n}'s video ended before frame {f}")
            if mjpeg_quality is not None:
                img = cv2.imdecode(img, jpeg_flag)
                if img is None:
                    raise SourceError(f"benchmark: {n}'s MJPEG frame {f} does not decode as a JPEG")
            imgs[n] = img
        t1 = time.perf_counter()
        c1 = time.process_time()
        t_s = stamps[names[0]][f]
        line = gt.get(f)
        T_W_B = None
        if line is not None and "T_W_B" in line:
            v = line["T_W_B"]
            T_W_B = Pose(quat_to_rot(np.asarray(v[3:7])), np.asarray(v[:3]))
        obs = fe.process(imgs, f, t_s, T_W_B=T_W_B if use_poses else None)
        posed |= use_poses and T_W_B is not None
        t2 = time.perf_counter()
        c2 = time.process_time()
        c_decode += c1 - c0
        c_front += c2 - c1
        t_decode += t1 - t0
        t_front += t2 - t1
        for k in stage:
            stage[k] += fe.timings.get(k, 0.0)
        n_obs += len(obs)
        for feats in fe.last_features.values():
            if len(feats):
                off = np.arccos(np.clip(feats.b_C[:, 2], -1, 1))
                rim_feats += int(np.sum(off > np.pi / 2))
                rim_old += int(np.sum((off > np.pi / 2) & (feats.age >= 10)))
        if line is None or T_W_B is None:
            continue
        shapes = shapes_for_frame(specs, line["obstacles"])
        # which obstacle is each reported track on?
        on: dict[int, set[int]] = {}
        alive_on: dict[int, set[int]] = {}  # every live track id -> the obstacles its views are on
        confirmed_ids.clear()
        for o in obs:
            if o.status == "lost":
                continue
            alive_on.setdefault(o.track_id, set())
            if o.status == "confirmed":
                confirmed_ids.add(o.track_id)
            for v in o.views:
                oW = T_W_B.apply(c_B[v.camera])
                dW = T_W_B.rotate(R_B_C[v.camera] @ v.b_C)
                best, best_t = None, np.inf
                for oid, s in shapes.items():
                    rng = float(np.linalg.norm(s.c_W - oW))
                    hit = ray_hit_distance(oW, dW, s, margin_px * rad_px[v.camera] * rng)
                    if hit is not None and hit < best_t:
                        best, best_t = oid, hit
                if best is not None:
                    on.setdefault(best, set()).add(o.track_id)
                    alive_on[o.track_id].add(best)
        # reported tracks none of whose views is on an obstacle (the ground, a false group)
        n_off += sum(1 for obst in alive_on.values() if not obst)
        n_off_conf += sum(1 for tid, obst in alive_on.items() if not obst and tid in confirmed_ids)
        n_gt += 1
        if ex is not None:
            ex.reported(f, alive_on)
        # live tracks not reported this frame (unseen, not yet lost): a pause, not an end (StickyIds)
        coasting = {
            fe._global(tr.id)
            for trs in (*(g.tracks for g in fe.groupers.values()), *(b.tracks for b in fe.boxers.values()))
            for tr in trs.values()
            if not tr.seen
        } - alive_on.keys()
        due_now = set()
        sticky.begin_frame(alive_on)
        for o in line["obstacles"]:
            oid = int(o["id"])
            if not any(o.get("visible", {}).values()):
                continue
            first_seen.setdefault(oid, t_s)
            if t_s - first_seen[oid] < 0.5:
                continue
            due_now.add(oid)
            due[oid] = due.get(oid, 0) + 1
            ids = on.get(oid, set())
            ids_on.setdefault(oid, set()).update(ids)
            if ids:
                covered[oid] = covered.get(oid, 0) + 1
            # the obstacle's track id is sticky (StickyIds); changing it to another track is an id switch
            for sw in sticky.update(f, oid, ids, alive_on, coasting):
                switches[oid] = switches.get(oid, 0) + 1
                switch_log.append(sw)
                if ex is not None:
                    ex.switch(sw["frame"], oid, sw["from"], sw["to"], alive_on)
        if ex is not None:
            ex.frame(f, T_W_B, shapes, line, on, alive_on, due_now, c_B, R_B_C, rad_px)
    for sw in sticky.finish():
        switches[sw["obstacle"]] = switches.get(sw["obstacle"], 0) + 1
        switch_log.append(sw)
        if ex is not None:
            ex.switch(sw["frame"], sw["obstacle"], sw["from"], sw["to"], {})
    switch_log.sort(key=lambda e: (e["frame"], e["obstacle"]))  # (a pause's switch is decided later)
    nf = len(frames)
    fps_dt = (
        frames and (stamps[names[0]][frames[-1]] - stamps[names[0]][frames[0]]) / max(nf - 1, 1)
    ) or 1 / 30
    per = {}
    for oid in sorted(due):
        minutes = covered.get(oid, 0) * fps_dt / 60.0
        per[oid] = {
            "frames_due": due[oid],
            "coverage": covered.get(oid, 0) / due[oid],
            "id_switches": switches.get(oid, 0),
            "switches_per_min": switches.get(oid, 0) / minutes if minutes > 0 else 0.0,
            "track_ids": len(ids_on.get(oid, ())),  # distinct ids on it (pieces, parallel tracks)
            # covered frames in which its only tracks were other obstacles' ids (StickyIds.begin_frame)
            "shared_id_frames": sticky.shared.get(oid, 0),
        }
    tot_due = sum(due.values())
    h, w = rig.cameras[0].model.height, rig.cameras[0].model.width
    return {
        "scene": str(scene_dir),
        "resolution": f"{w}x{h}",
        "cameras": len(names),
        "detector": detector,
        "video": video,
        "threads": threads,
        "poses": posed,
        "frames": nf,
        "fps": nf / (t_decode + t_front),
        "fps_frontend": nf / t_front,
        "fps_cpu": nf / (c_decode + c_front),
        "fps_frontend_cpu": nf / c_front,
        "ms_per_frame": {
            "decode": 1e3 * t_decode / nf,
            "frontend": 1e3 * t_front / nf,
            "decode_cpu": 1e3 * c_decode / nf,
            "frontend_cpu": 1e3 * c_front / nf,
            **{k: 1e3 * v / nf for k, v in stage.items()},
        },
        "coverage": sum(covered.values()) / tot_due if tot_due else None,
        "min_coverage": min((p["coverage"] for p in per.values()), default=None),
        "max_switches_per_min": max((p["switches_per_min"] for p in per.values()), default=None),
        # all switches over all covered obstacle-minutes (stable on short scenes)
        "switches_per_obstacle_minute": sum(switches.values())
        / max(sum(covered.values()) * fps_dt / 60.0, 1e-9),
        # the counts behind the rates (one switch in a 3-4 s scene is 5-15 per obstacle-minute)
        "id_switches": sum(switches.values()),
        "covered_obstacle_minutes": sum(covered.values()) * fps_dt / 60.0,
        "obstacles": per,
        "switch_log": switch_log,
        "shared_id_frames": sum(sticky.shared.values()),
        "observations_per_frame": n_obs / nf,
        "off_obstacle_tracks_per_frame": n_off / max(n_gt, 1),
        "off_obstacle_confirmed_per_frame": n_off_conf / max(n_gt, 1),
        "track_splits": sum(getattr(g, "splits", 0) for g in fe.groupers.values()),
        "rim_features_per_frame": rim_feats / nf,
        "rim_features_age10_per_frame": rim_old / nf,
        **({"explain": ex.summary()} if ex is not None else {}),
    }


def main(argv: list[str] | None = None) -> None:
    """Command-line entry: print the benchmark of one scene as JSON."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene_dir")
    ap.add_argument("--detector", default="orb+navlights")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--frames", type=int, default=None)
    ap.add_argument(
        "--poses",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="pass the scene's true T_W_B (rotation compensation), as the pipeline does (default); "
        "--no-poses: without",
    )
    ap.add_argument("--explain", action="store_true", help="the cause of every coverage gap and id switch")
    ap.add_argument(
        "--mjpeg",
        type=int,
        default=None,
        metavar="QUALITY",
        help="decode (and score) the frames as a USB camera delivers them: the scene's videos re-encoded "
        "once as MJPEG at this JPEG quality (e.g. 90), decoded to grey for a grey detector (orb, kornia)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="GROUP.KEY=VALUE",
        help="a FrontEnd option, e.g. grouping.max_radius_px=30 or max_width=960 (repeatable)",
    )
    a = ap.parse_args(argv)
    opts: dict[str, Any] = {}
    for item in a.set:
        key, _, val = item.partition("=")
        group, _, name = key.partition(".")
        if name:
            opts.setdefault(group, {})[name] = yaml.safe_load(val)
        else:  # a top-level FrontEnd option, e.g. max_width=960
            opts[group] = yaml.safe_load(val)
    try:
        res = run_benchmark(
            a.scene_dir,
            detector=a.detector,
            threads=a.threads,
            max_frames=a.frames,
            use_poses=a.poses,
            explain=a.explain,
            mjpeg_quality=a.mjpeg,
            **opts,
        )
    except FisheyeDesError as e:  # bad input: its message, not a traceback
        ap.exit(2, f"error: {e}\n")
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
