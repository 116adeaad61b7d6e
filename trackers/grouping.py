"""Features -> obstacle tracks in one camera: proximity on the unit sphere plus consistent motion.

Per frame:

1. Each track keeps its member features that are still alive and still move with it: a member
   whose rotation-compensated flow differs from the track's median flow by more than
   ``flow_abs_rad_s + flow_rel * |median|`` leaves, and so does one farther than ``max_radius_rad``
   from the track's representative bearing.
2. Unassigned features old enough to have a flow join the track of their nearest member within
   ``link_rad`` when their flow agrees.
3. The rest are grouped by connected components of the graph "angular distance < link_rad and flow
   agrees"; a component wider than ``max_radius_rad`` is cut into pieces of that radius; a piece
   of at least ``min_features`` features revives a coasting track near it, or starts a tentative
   track.
4. Life cycle: tentative -> confirmed after ``confirm_frames`` frames with members; unseen for more
   than ``max_missed`` frames -> lost (reported once, then dropped).
5. Optional (``hand_on``) hysteresis on splits: a confirmed track that lost its members this
   frame takes over a younger track now covering its place (within half ``link_rad``, flows
   agreeing), so the id follows the obstacle when its features are replaced; the younger one is
   lost.

The representative bearing ``b_C`` moves with the mean frame-to-frame motion of the members present
in both frames (so members joining or leaving do not make it jump), pulled gently (gain
``centre_gain``) towards the normalised mean of the members so that it cannot drift off the object.
Its sigma is ``sqrt(spread^2 / n + floor^2)``, spread = RMS angle of the members about it, floor =
``sigma_floor_px`` pixels at that point.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from estimators.errors import ConfigError
from trackers.features import FeatureTracker


def _normalise(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit vectors a (..., 3) and b (..., 3), stable at 0 and pi:
    ``atan2(|a x b|, a . b)``."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


@dataclass
class ObstacleTrack:
    """One obstacle as one camera tracks it (mutable state of the grouper).

    Attributes:
        id: track id (unique over all cameras of the front end).
        camera: camera name.
        members: (M,) int64 ids of the member features.
        b_C: (3,) unit representative bearing in C.
        uv: (2,) its pixel position.
        sigma_rad: 1-sigma uncertainty of b_C (rad).
        flow_rad_s: (3,) median rotation-compensated member flow in C (rad/s, tangent vector).
        status: tentative | confirmed | lost.
        hits: frames seen; missed: consecutive frames unseen; seen: seen this frame.
        label / attributes: what made it (``orb`` ... or a box detector's label) and its extras.
    """

    id: int
    camera: str
    members: np.ndarray
    b_C: np.ndarray
    uv: np.ndarray = field(default_factory=lambda: np.zeros(2))
    sigma_rad: float = 0.01
    flow_rad_s: np.ndarray = field(default_factory=lambda: np.zeros(3))
    status: str = "tentative"
    hits: int = 1
    missed: int = 0
    seen: bool = True
    label: str = "orb"
    attributes: dict = field(default_factory=dict)
    member_b_C: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    keep_min: int = 0  # members it needs to stay seen (0: the grouper's default)


class ObstacleGrouper:
    """Groups the features of one camera into obstacle tracks (see the module docstring).

    Args:
        ids: shared id counter for track ids.
        link_px: largest distance between neighbouring features of one obstacle, in pixels at the
            lens's mean scale (turned into an angle, ``link_rad``, on the first update).
        max_radius_px: largest distance of a member from its track's representative point (pixels,
            turned into ``max_radius_rad`` likewise).
        flow_abs_rad_s, flow_rel: flows agree when ``|f_i - f_j| < flow_abs + flow_rel * max(|f_i|, |f_j|)``.
        flow_frames: flow measured over this many frames (less for younger features).
        min_features: features needed to start a track.
        min_features_isolated: features enough to start a track when they are isolated (no other
            live feature within ``link_rad``) and all at least ``isolated_min_age`` frames old: a
            small obstacle against the sky has one or two corners.
        hand_on: hysteresis on splits (step 5), off by default: it lowered the switches on some
            renders of mono_straight and raised them on others.
        min_age: frames a feature must have been tracked before it can join or start a track.
        confirm_frames: frames with members before a track is confirmed.
        max_missed: frames a track may go unseen (occlusion, frame drops) before it is lost.
        coast_predict: an unseen track's bearing moves on with its last flow (and the camera's
            rotation when given), so features found where the obstacle went revive it (issue 4).
        centre_gain: pull of the representative bearing towards the member mean per frame.
        sigma_floor_px: floor of sigma_rad, in pixels at the representative point.
        label: label of the tracks (the detector's name).
    """

    def __init__(
        self,
        ids: Iterator[int],
        link_px: float = 35.0,
        max_radius_px: float = 50.0,
        flow_abs_rad_s: float = 0.03,
        flow_rel: float = 0.2,
        flow_frames: int = 5,
        min_features: int = 3,
        min_features_isolated: int = 1,
        isolated_min_age: int = 12,
        min_age: int = 3,
        confirm_frames: int = 5,
        hand_on: bool = False,
        max_missed: int = 10,
        coast_predict: bool = True,
        centre_gain: float = 0.02,
        sigma_floor_px: float = 0.5,
        label: str = "orb",
    ) -> None:
        if link_px <= 0 or max_radius_px <= 0 or min_features < 1 or confirm_frames < 1 or max_missed < 0:
            raise ConfigError(
                "ObstacleGrouper: expected link_px > 0, max_radius_px > 0, min_features >= 1, "
                "confirm_frames >= 1, max_missed >= 0; got "
                f"{link_px}, {max_radius_px}, {min_features}, {confirm_frames}, {max_missed}"
            )
        self._ids = ids
        self.link_px = float(link_px)
        self.max_radius_px = float(max_radius_px)
        self.link_rad = self.max_radius_rad = 0.0  # set from the camera's scale on the first update
        self.flow_abs = float(flow_abs_rad_s)
        self.flow_rel = float(flow_rel)
        self.flow_frames = int(flow_frames)
        self.min_features = int(min_features)
        self.min_features_isolated = int(min_features_isolated)
        self.hand_on = bool(hand_on)
        self.isolated_min_age = int(isolated_min_age)
        self.min_age = int(min_age)
        self.confirm_frames = int(confirm_frames)
        self.max_missed = int(max_missed)
        self.centre_gain = float(centre_gain)
        self.sigma_floor_px = float(sigma_floor_px)
        self.label = label
        self.tracks: dict[int, ObstacleTrack] = {}
        self.coast_predict = bool(coast_predict)
        self._last_t_s: float | None = None

    # ---------------------------------------------------------------------------------- api
    def update(
        self, ft: FeatureTracker, t_s: float, R_C_Cprev: dict[int, np.ndarray] | None = None
    ) -> tuple[list[ObstacleTrack], list[ObstacleTrack]]:
        """Group the live features of ``ft`` after its ``track()`` call for this frame.

        Args:
            ft: the camera's FeatureTracker (live features, their bearings and history).
            t_s: frame time (s).
            R_C_Cprev: optional rotations ``{k: R (3,3)}`` taking a direction in this camera's frame
                k frames ago into the frame now (from the ego-motion), for k = 1..flow_frames; flows
                are then compensated for the camera's own rotation. Missing k: no compensation.
        Returns:
            (tracks seen this frame, tracks lost this frame).
        """
        ids, b = ft.ids, ft.b_C
        n = len(ids)
        dt_s = t_s - self._last_t_s if self._last_t_s is not None else 0.0
        self._last_t_s = t_s
        rad_px = self._rad_per_px(ft)
        self.link_rad = self.link_px * rad_px
        self.max_radius_rad = self.max_radius_px * rad_px
        cos_link, cos_r = np.cos(self.link_rad), np.cos(self.max_radius_rad)
        flow, fvalid = self._flows(ft, t_s, R_C_Cprev)
        fvalid &= ft.age >= self.min_age
        fnorm = np.sqrt(np.einsum("ij,ij->i", flow, flow))
        b_prev, pvalid = ft.previous_bearing()
        tracks = list(self.tracks.values())
        T = len(tracks)
        rep = np.array([t.b_C for t in tracks]).reshape(T, 3)
        tflow = np.array([t.flow_rad_s for t in tracks]).reshape(T, 3)
        # owner[i]: index (into tracks) of the track feature i belonged to last frame, or -1
        owner = np.full(n, -1, np.intp)
        if T and n:
            order = np.argsort(ids, kind="stable")
            sids = ids[order]
            lens = [len(t.members) for t in tracks]
            if sum(lens):
                mem = np.concatenate([t.members for t in tracks])
                mem_t = np.repeat(np.arange(T), lens)
                k = np.minimum(np.searchsorted(sids, mem), n - 1)
                ok = sids[k] == mem
                owner[order[k[ok]]] = mem_t[ok]
        for t in tracks:
            t.seen = False
        # 1. members stay within max_radius of the representative bearing and move with the track
        r = np.flatnonzero(owner >= 0)
        if len(r):
            far = np.einsum("ij,ij->i", b[r], rep[owner[r]]) < cos_r
            owner[r[far]] = -1
        for loose in (2.0, 1.0):  # robust mean flow: a loose cut, then the strict one
            tflow, has_flow = self._track_flow(owner, flow, fvalid, tflow, T)
            sel = np.flatnonzero((owner >= 0) & fvalid)
            if len(sel):
                o = owner[sel]
                d = np.linalg.norm(flow[sel] - tflow[o], axis=1)
                thr = self.flow_abs + self.flow_rel * np.maximum(fnorm[sel], np.linalg.norm(tflow[o], axis=1))
                owner[sel[(d >= loose * thr) & has_flow[o]]] = -1
        tflow, has_flow = self._track_flow(owner, flow, fvalid, tflow, T)
        # 2. unassigned features with a flow join the track of their nearest member
        free = np.flatnonzero((owner < 0) & fvalid)
        memb = np.flatnonzero(owner >= 0)
        if len(free) and len(memb):
            cosd = b[free] @ b[memb].T
            j = np.argmax(cosd, axis=1)
            t_of = owner[memb[j]]
            ok = cosd[np.arange(len(free)), j] > cos_link
            ok &= np.einsum("ij,ij->i", b[free], rep[t_of]) > cos_r
            fd = np.linalg.norm(flow[free] - tflow[t_of], axis=1)
            thr = self.flow_abs + self.flow_rel * np.maximum(fnorm[free], np.linalg.norm(tflow[t_of], axis=1))
            ok &= (fd < thr) | ~has_flow[t_of]
            owner[free[ok]] = t_of[ok]
        # 3. new groups from the rest
        free = np.flatnonzero((owner < 0) & fvalid)
        fresh = np.zeros(T, bool)
        new_rep, new_flow = [], []
        n_near: np.ndarray | None = None  # per feature: live features within link_rad, itself included
        for rows in self._components(free, b, flow):
            small = len(rows) < self.min_features
            if small:
                if len(rows) < self.min_features_isolated or np.any(ft.age[rows] < self.isolated_min_age):
                    continue
                if n_near is None:
                    n_near = np.zeros(n, np.int64)
                    n_near[free] = (b[free] @ b.T > cos_link).sum(axis=1)
                # isolated: every member's neighbours are members (the component is a connected one)
                if np.any(n_near[rows] > len(rows)):
                    continue
            c = _normalise(b[rows].mean(0))
            ti = self._revive(tracks, c, owner)
            if ti is None:
                tid = next(self._ids)
                tr = ObstacleTrack(tid, ft.name, ids[rows], c, hits=0, label=self.label)
                if small:
                    tr.keep_min = 1
                self.tracks[tid] = tr
                tracks.append(tr)
                ti = len(tracks) - 1
                fresh = np.append(fresh, True)
                new_rep.append(c)
                new_flow.append(flow[rows].mean(0))
            else:
                fresh[ti] = True
                rep[ti] = c
            owner[rows] = ti
        if new_rep:
            rep = np.concatenate([rep, np.array(new_rep)])
            tflow = np.concatenate([tflow, np.array(new_flow)])
        T = len(tracks)
        tflow, _ = self._track_flow(owner, flow, fvalid, tflow, T)
        # 4. representative bearing, sigma, members, life cycle
        own = np.flatnonzero(owner >= 0)
        o = owner[own]
        cnt = np.bincount(o, minlength=T)
        bsum = np.stack([np.bincount(o, b[own, k], T) for k in range(3)], 1)
        mean_c = _normalise(bsum)
        per = own[pvalid[own] & ~fresh[o]]
        po = owner[per]
        pcnt = np.bincount(po, minlength=T)
        dsum = np.stack([np.bincount(po, b[per, k] - b_prev[per, k], T) for k in range(3)], 1)
        # move with the members present in both frames: b_rep += mean(b_now - b_prev), then a
        # gentle pull towards the member mean (gain centre_gain)
        moved = _normalise(rep + dsum / np.maximum(pcnt, 1)[:, None])
        moved = _normalise(moved + self.centre_gain * (mean_c - moved))
        use_moved = (pcnt > 0) & (np.einsum("ij,ij->i", moved, mean_c) > cos_r)
        new_rep_all = np.where(use_moved[:, None], moved, mean_c)
        ang = np.arccos(np.clip(np.einsum("ij,ij->i", b[own], new_rep_all[o]), -1.0, 1.0))
        spread2 = np.bincount(o, ang * ang, T) / np.maximum(cnt, 1)
        # sigma^2 = spread^2 / n + floor^2
        sigma = np.sqrt(spread2 / np.maximum(cnt, 1) + (self.sigma_floor_px * rad_px) ** 2)
        srt = own[np.argsort(o, kind="stable")]
        groups = np.split(srt, np.cumsum(cnt)[:-1]) if T else []
        keep_min = max(2, self.min_features // 2)
        seen, lost = [], []
        for ti, tr in enumerate(tracks):
            if cnt[ti] >= (tr.keep_min or keep_min):
                rows = groups[ti]
                tr.members = ids[rows]
                tr.member_b_C = b[rows]
                tr.b_C = new_rep_all[ti]
                tr.flow_rad_s = tflow[ti]
                tr.sigma_rad = float(sigma[ti])
                tr.hits += 1
                tr.missed = 0
                tr.seen = True
                if tr.status == "tentative" and tr.hits >= self.confirm_frames:
                    tr.status = "confirmed"
                seen.append(tr)
            else:
                tr.members = np.zeros(0, np.int64)
                tr.member_b_C = np.zeros((0, 3))
                tr.missed += 1
                # coast on the predicted bearing: b <- normalise(R_C_Cprev b + flow dt) (flow: tangent,
                # rad/s, rotation-compensated when R_C_Cprev is given), so new features found where
                # the obstacle went revive it under its old id
                if self.coast_predict and dt_s > 0:
                    R1 = R_C_Cprev.get(1) if R_C_Cprev else None
                    b_pred = R1 @ tr.b_C if R1 is not None else tr.b_C
                    tr.b_C = _normalise(b_pred + tr.flow_rad_s * dt_s)
                if tr.missed > self.max_missed:
                    tr.status = "lost"
                    lost.append(tr)
                    del self.tracks[tr.id]
        if self.hand_on:
            seen, lost = self._hand_on(seen, lost, cos_r)
        if seen:
            uv, ok = ft.model.bearing_to_pixel(np.array([t.b_C for t in seen]))
            for t, u, v in zip(seen, uv, ok, strict=True):
                if v:
                    t.uv = u
        return seen, lost

    def _hand_on(
        self, seen: list[ObstacleTrack], lost: list[ObstacleTrack], cos_r: float
    ) -> tuple[list[ObstacleTrack], list[ObstacleTrack]]:
        """Hysteresis on splits: a confirmed track that lost its members this frame takes over the
        younger track (higher id) that now covers its place (representative bearings within half
        ``link_rad``, flows agreeing), so the id follows the obstacle; the younger one is lost.

        Returns the updated (seen, lost)."""
        just_lost = [
            t for t in self.tracks.values() if not t.seen and t.missed == 1 and t.status == "confirmed"
        ]
        if not just_lost or not seen:
            return seen, lost
        for old in sorted(just_lost, key=lambda t: t.id):
            best, best_cos = None, max(cos_r, float(np.cos(0.5 * self.link_rad)))
            for y in seen:
                if y.id <= old.id or y.label != old.label:
                    continue
                cs = float(y.b_C @ old.b_C)
                d = float(np.linalg.norm(y.flow_rad_s - old.flow_rad_s))
                thr = self.flow_abs + self.flow_rel * max(
                    float(np.linalg.norm(y.flow_rad_s)), float(np.linalg.norm(old.flow_rad_s))
                )
                if cs > best_cos and d < thr:
                    best, best_cos = y, cs
            if best is None:
                continue
            y = best
            old.members, old.member_b_C, old.b_C = y.members, y.member_b_C, y.b_C
            old.flow_rad_s, old.sigma_rad = y.flow_rad_s, y.sigma_rad
            old.hits += 1
            old.missed = 0
            old.seen = True
            y.status = "lost"
            y.seen = False
            del self.tracks[y.id]
            seen = [old if t is y else t for t in seen]
            lost.append(y)
        return seen, lost

    @staticmethod
    def _track_flow(
        owner: np.ndarray, flow: np.ndarray, fvalid: np.ndarray, old: np.ndarray, T: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Mean member flow per track (T,3) where >= 3 members have a flow (else ``old``), and that mask."""
        sel = np.flatnonzero((owner >= 0) & fvalid)
        o = owner[sel]
        cnt = np.bincount(o, minlength=T)
        sums = np.stack([np.bincount(o, flow[sel, k], T) for k in range(3)], 1) if T else np.zeros((0, 3))
        has = cnt >= 3
        return np.where(has[:, None], sums / np.maximum(cnt, 1)[:, None], old), has

    # ----------------------------------------------------------------------------- helpers
    def _flows(
        self, ft: FeatureTracker, t_s: float, R: dict[int, np.ndarray] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per feature: flow (N,3) in rad/s = (b_now - R b_then) / dt over up to flow_frames frames."""
        n = len(ft.ids)
        if not n:
            return np.zeros((0, 3)), np.zeros(0, bool)
        b_then, t_then, valid = ft.bearing_ago(self.flow_frames)
        if R:
            n_back = np.minimum(ft._h_n[ft.slot] - 1, self.flow_frames)
            for k, Rk in R.items():
                sel = n_back == k
                if np.any(sel):
                    b_then = b_then.copy()
                    b_then[sel] = b_then[sel] @ np.asarray(Rk).T
        dt = t_s - t_then
        valid &= dt > 0
        flow = np.zeros((n, 3))
        flow[valid] = (ft.b_C[valid] - b_then[valid]) / dt[valid, None]
        return flow, valid

    def _components(self, free: np.ndarray, b: np.ndarray, flow: np.ndarray) -> list[np.ndarray]:
        """Connected components (union-find) of the free features, cut to max_radius_rad pieces."""
        m = len(free)
        if m == 0:
            return []
        bf, ff = b[free], flow[free]
        close = (bf @ bf.T) > np.cos(self.link_rad)
        fn = np.linalg.norm(ff, axis=1)
        d = np.linalg.norm(ff[:, None, :] - ff[None, :, :], axis=2)
        agree = d < self.flow_abs + self.flow_rel * np.maximum(fn[:, None], fn[None, :])
        adj = close & agree
        # connected components by min-label propagation: each feature takes the smallest label
        # among its neighbours until nothing changes (at most the graph's diameter rounds)
        labels = np.arange(m)
        big = m + 1
        for _ in range(m):
            nxt = np.where(adj, labels[None, :], big).min(axis=1)
            nxt = np.minimum(nxt, labels)
            nxt = nxt[nxt]  # pointer jumping speeds it up
            if np.array_equal(nxt, labels):
                break
            labels = nxt
        roots = labels
        out: list[np.ndarray] = []
        cos_r = np.cos(self.max_radius_rad)
        for r in np.unique(roots):
            comp = np.flatnonzero(roots == r)
            if len(comp) < min(self.min_features, self.min_features_isolated):
                continue
            if len(comp) < self.min_features:  # judged by the caller (isolated or not)
                out.append(free[comp])
                continue
            while len(comp):
                c = _normalise(bf[comp].mean(0))
                if np.all(bf[comp] @ c > cos_r):
                    out.append(free[comp])
                    break
                # cut: a piece around the member farthest from the centre, so the rest stays compact
                far = comp[np.argmin(bf[comp] @ c)]
                piece = comp[bf[comp] @ bf[far] > np.cos(self.max_radius_rad)]
                c2 = _normalise(bf[piece].mean(0))
                piece = comp[bf[comp] @ c2 > cos_r]
                if not len(piece):
                    piece = np.array([far])
                out.append(free[piece])
                comp = np.setdiff1d(comp, piece)
        return out

    def _revive(self, tracks: list[ObstacleTrack], c: np.ndarray, owner: np.ndarray) -> int | None:
        """Index of a coasting track (unseen last frame, no members now) whose bearing is within
        max_radius of the group centre ``c`` (3,), or None."""
        taken = set(np.unique(owner[owner >= 0]).tolist())
        best, best_cos = None, np.cos(self.max_radius_rad)
        for ti, tr in enumerate(tracks):
            if tr.missed == 0 or ti in taken or tr.hits == 0:
                continue
            cs = float(c @ tr.b_C)
            if cs > best_cos:
                best, best_cos = ti, cs
        return best

    def _rad_per_px(self, ft: FeatureTracker) -> float:
        cx, cy, r = ft.model.image_circle()
        return float(ft.model.max_angle_rad / max(r, 1.0))


class BoxTracker:
    """Tracks box detections (navlights, torch models, plug-ins) of one camera as obstacles.

    A box's representative bearing is its centre's bearing; boxes are matched to tracks of the same
    label greedily by angle, within ``gate_rad`` plus the box's own angular half-size. Life cycle as
    ObstacleGrouper's. sigma_rad = half the box's angular diagonal / 3, floored at ``sigma_floor_rad``.
    """

    def __init__(
        self,
        ids: Iterator[int],
        gate_rad: float = np.radians(3.0),
        confirm_frames: int = 3,
        max_missed: int = 10,
        sigma_floor_rad: float = np.radians(0.2),
    ) -> None:
        self._ids = ids
        self.gate_rad = float(gate_rad)
        self.confirm_frames = int(confirm_frames)
        self.max_missed = int(max_missed)
        self.sigma_floor_rad = float(sigma_floor_rad)
        self.tracks: dict[int, ObstacleTrack] = {}

    def update(self, camera, det) -> tuple[list[ObstacleTrack], list[ObstacleTrack]]:
        """Match this frame's boxes (``det``: Detections) of ``camera`` (an ``estimators.rig.Camera``).

        Returns:
            (tracks seen this frame, tracks lost this frame).
        """
        model = camera.model
        seen: list[ObstacleTrack] = []
        for tr in self.tracks.values():
            tr.seen = False
        if len(det.boxes):
            c = det.box_centres
            corners = np.concatenate([det.boxes[:, :2], det.boxes[:, 2:]])
            bc, okc = model.pixel_to_bearing(c)
            bk, okk = model.pixel_to_bearing(corners)
            m = len(c)
            half = np.where(okk[:m] & okk[m:], angle_between(bk[:m], bk[m:]) / 2, 0.0)
            cand = []
            for i in range(m):
                if not okc[i]:
                    continue
                for tr in self.tracks.values():
                    if tr.label != det.labels[i]:
                        continue
                    a = float(angle_between(bc[i], tr.b_C))
                    if a < self.gate_rad + half[i]:
                        cand.append((a, i, tr.id))
            cand.sort()
            used_b: set[int] = set()
            used_t: set[int] = set()
            match: dict[int, int] = {}
            for _a, i, tid in cand:
                if i in used_b or tid in used_t:
                    continue
                used_b.add(i)
                used_t.add(tid)
                match[i] = tid
            for i in range(m):
                if not okc[i]:
                    continue
                if i in match:
                    tr = self.tracks[match[i]]
                    tr.hits += 1
                else:
                    tid = next(self._ids)
                    tr = ObstacleTrack(tid, camera.name, np.zeros(0, np.int64), bc[i], label=det.labels[i])
                    self.tracks[tid] = tr
                tr.b_C = bc[i]
                tr.uv = c[i].astype(float)
                tr.sigma_rad = float(max(half[i] / 3.0, self.sigma_floor_rad))
                tr.attributes = dict(det.attributes[i])
                tr.missed = 0
                tr.seen = True
                if tr.status == "tentative" and tr.hits >= self.confirm_frames:
                    tr.status = "confirmed"
                seen.append(tr)
        lost = []
        for tid in list(self.tracks):
            tr = self.tracks[tid]
            if not tr.seen:
                tr.missed += 1
                if tr.missed > self.max_missed:
                    tr.status = "lost"
                    lost.append(tr)
                    del self.tracks[tid]
        return seen, lost
