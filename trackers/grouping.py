"""Features -> obstacle tracks in one camera: proximity on the unit sphere plus consistent motion.

Per frame (array operations over the features and tracks; Python loops only over the tracks to
write their new state and over components wide enough to be cut):

1. Each track keeps its member features that are still alive and still move with it: a member
   whose rotation-compensated flow differs from the track's mean flow by more than
   ``flow_abs_rad_s + flow_rel * |flow|`` leaves, and so does one farther than ``max_radius_rad``
   from the track's representative bearing.
2. Unassigned features old enough to have a flow join the track of their nearest member within
   ``link_rad`` when their flow agrees; a track short of members (coasting, or its features
   replaced) takes the free features within ``link_rad`` of where it was predicted to be that
   move like it.
3. The rest are grouped by connected components of the graph "angular distance < link_rad and flow
   agrees"; a component wider than ``max_radius_rad`` is cut into pieces of that radius. A piece of
   at least ``min_features`` features (or a small isolated one, see ``min_features_isolated``)
   revives a track that has no members now (coasting, or whose features were all replaced this
   frame) when it lies within ``max_radius_rad`` of where that track was predicted to be and moves
   like it (closest pairs first); otherwise it starts a tentative track.
3b. One obstacle tracked as two pieces (a near obstacle grows beyond ``max_radius`` and is cut):
   when the older, confirmed piece loses its members (it left the image or was hidden), it takes
   over the younger piece that lies where its members went and moves like it, so the obstacle
   keeps the id downstream filters know (the younger id is reported lost).
3c. Two surfaces in one track (an obstacle and what lies behind or beside it, whose
   frame-to-frame flows agree within the tolerance): the members' flows over ``split_window_s``
   are compared between neighbours; where they jump (a parallax step at an occluding edge,
   or an independently moving obstacle), not merely change smoothly, and the same part is found
   in every frame over ``split_persist_s``, that part leaves: it revives a memberless track predicted
   there or starts a new one (see ``_split``). Measured (2026-11-22, six presets): over 1/3 s the
   presets' mixed tracks are not separable by motion (after an affine fit the minority's leftover
   flow is 0-1.6 px/s, inside the spread); of 69 splits ~59 cut ground from ground and 2-4
   separated two surfaces. Its coverage gain on moving_crossing (worst obstacle 0.21 -> 0.63)
   comes from step 4 exempting a split-off part, which the crossing box's features then joined;
   the cause there is step 4's least-squares fit pulled by a mover nearby. Kept until a fix of
   step 4 that does not cost stereo accuracy replaces it.
3f. An upright obstacle standing on the ground it is grouped with (``plane_min``, on by default): at its
   foot the two flows are equal, so 3c finds no step, but a plane's flow on the sphere is an exact
   8-parameter function of the bearing and an obstacle at one range breaks it. Each disk of
   members (``link_rad``) is tested against the plane fitted to the rest; the most significant
   part that is displaced one way, by more than 3c's link tolerance, ``plane_z`` sigmas of the
   fit's prediction and ``plane_ratio`` times the rest's own scatter about its plane (a part of
   one curved obstacle is off the plane by about as much as its rest is), leaves when found
   in every frame over ``split_persist_s`` (see ``_plane_parts``).
   A track is tested every ``plane_every_s`` (staggered by id), every frame once a part is
   found in it. On a rig of several cameras the front end sets ``plane_confirm``: the part leaves
   only when the same obstacle's view in another camera found a part too (one camera's flow
   alone, e.g. a stereo view mixing two obstacles, does not split it).
4. Extended texture (the ground, a large wall): a track is *embedded* when non-member features
   surround it (they lie in at least ``extended_sectors`` of 8 angular sectors around it; sectors
   outside the lens do not count against it) and the flow field they span (an affine fit in the
   tangent plane) agrees with the track's flow at the track. A bounded obstacle has a motion
   boundary or empty space around most of it; a piece of a textured surface does not. An embedded
   piece starts no track and a tentative track embedded in every frame over ``extended_s`` is
   dropped (lost); their features start no new group for ``BG_S`` (they may still join a track
   they move with).
5. Life cycle: tentative -> confirmed after ``confirm_s`` of frames with members; unseen for more
   than ``max_missed_s`` -> lost (reported once, then dropped). An unseen track coasts: its
   bearing moves on with its last flow (and the camera's rotation when given).

Durations are settings in seconds (keys ``*_s``), applied as frame counts at the frame rate seen
(``FrameClock``: the median interval of the frame times ``t_s`` given, never a configured rate): the
counts fitted at 30 fps (every scene of the harness) are the defaults' counts at 30 fps, and a rule
keeps its meaning in time at another rate (at 100 fps a flow is still measured over 1/6 s, so the
flow tolerance ``flow_abs_rad_s`` is still the same displacement). Windows reaching into a
feature's history are capped at the tracker's ``history`` samples.

The representative bearing ``b_C`` moves with the mean frame-to-frame motion of the members present
in both frames (so members joining or leaving do not make it jump), pulled gently (gain
``centre_gain``) towards the normalised mean of the members so that it cannot drift off the object.
Its sigma is ``sqrt(spread^2 / n + floor^2)``, spread = RMS angle of the members about it, floor =
``sigma_floor_px`` pixels at that point.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from estimators.errors import ConfigError
from estimators.geometry import _cross, _einsum, _norm_rows
from trackers.clock import FrameClock, check_durations
from trackers.features import FeatureTracker

# an unseen track's members: shared, read-only
_NO_IDS = np.zeros(0, np.int64)
_NO_IDS.flags.writeable = False
_NO_BEARINGS = np.zeros((0, 3))
_NO_BEARINGS.flags.writeable = False


def _normalise(v: np.ndarray) -> np.ndarray:
    if v.ndim == 1 and len(v) == 3:  # one vector: the same IEEE operations in Python floats (~3x faster)
        x, y, z = v.tolist()
        n = math.sqrt(x * x + y * y + z * z)
        return v / (n if n > 0 else 1.0)
    n = _norm_rows(v, keepdims=True)  # np.linalg.norm's own formula
    return v / np.where(n > 0, n, 1.0)


_SECTOR_MID = -np.pi + (np.arange(8) + 0.5) * (np.pi / 4.0)  # middle directions of 8 sectors (rad)
_SECTOR_COS, _SECTOR_SIN = np.cos(_SECTOR_MID), np.sin(_SECTOR_MID)
_ARANGE12 = np.arange(12)
_EZ, _EX = np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]])
_EYE3 = np.eye(3)[None]  # (1, 3, 3)
_RIDGE = np.diag([1e-9, 1e-3, 1e-3])  # step 4's ridge on the affine fit's normal equations
_N_OF_SUMS = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])  # N = [[n, x, y], [x, xx, xy], [y, xy, yy]] sums


def _bincount3(keys: np.ndarray, v: np.ndarray, n: int) -> np.ndarray:
    """Per key 0..n-1 the sums (n, 3) of the rows of v (K, 3) with that key (K,) int:
    ``np.stack([np.bincount(keys, v[:, k], n) for k in range(3)], 1)``, the same sums, without np.stack's
    overhead (a C-ordered copy of the three rows)."""
    sums = [np.bincount(keys, v[:, 0], n), np.bincount(keys, v[:, 1], n), np.bincount(keys, v[:, 2], n)]
    return np.array(sums).T.copy()


def _well_conditioned(A: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Which symmetric matrices A (K, n, n) have a condition number below 1e10, and their inverses
    (K, n, n) (``np.linalg.inv``'s; None when one is exactly singular). The rule is step 3f's:
    |last| < 1e10 |first| of ``np.linalg.eigvalsh``'s ascending eigenvalues, i.e. the largest over
    the smallest eigenvalue for a positive semi-definite A such as step 3f's N_R (for an indefinite
    A, the magnitudes of its two extreme eigenvalues, which the bound below also covers).

    ``cond <= |A|_F |A^-1|_F``, so where that bound is below 1e9 the test passes without the
    eigenvalues (an eighth of the cost on step 3f's 8x8 matrices); the others are decided by them."""
    try:
        Ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:  # an exactly singular one: the eigenvalues decide
        Ai = None
    ok = np.zeros(len(A), bool)
    if Ai is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            m = A.shape[-1] ** 2
            ok = np.sqrt((A * A).reshape(-1, m).sum(1) * (Ai * Ai).reshape(-1, m).sum(1)) < 1e9
    if not ok.all():
        ev = np.abs(np.linalg.eigvalsh(A[~ok]))
        ok[~ok] = ev[:, -1] < 1e10 * ev[:, 0]
    return ok, Ai


def _found_again(fids: np.ndarray, prev: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """A candidate part (feature ids fids (K,)) found in a track this frame (steps 3c and 3f): its
    sorted ids and the frames in a row it has been found, ``n + 1`` when it has at least half of its
    features (or of the last candidate's) in common with the last frame's candidate (sorted ids prev
    (P,)), else 1."""
    mids = np.sort(fids)
    common = np.intersect1d(mids, prev, assume_unique=True).size if len(prev) else 0
    return mids, (n + 1 if 2 * common >= min(len(mids), len(prev)) > 0 else 1)


def _tangent_basis(rep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal tangent vectors (e1, e2), each (T, 3), at unit bearings rep (T, 3): e1 = ref x rep
    normalised (ref the z axis, or x near it), e2 = rep x e1."""
    ref = np.where(np.abs(rep[:, 2:3]) < 0.9, _EZ, _EX)
    e1 = _normalise(_cross(ref, rep))
    return e1, _cross(rep, e1)


def _traceless_basis() -> np.ndarray:
    """(8,3,3): a basis of the 3x3 matrices modulo the identity (the 8 unit matrices E_ij but E_22,
    with E_00 - E_22 and E_11 - E_22 for the diagonal): ``P_b G b`` does not see G's identity part."""
    out = []
    for i in range(3):
        for j in range(3):
            if i == j == 2:
                continue
            m = np.zeros((3, 3))
            m[i, j] = 1.0
            if i == j:
                m[2, 2] = -1.0
            out.append(m)
    return np.array(out)


_TRACELESS = _traceless_basis()


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
        uv: (2,) pixel of ``b_C`` in this camera's image, or None when there is none: ``b_C`` does
            not project into the image (a representative carried beyond the lens's field or the
            picture by its members' motion as the obstacle leaves them) or the track is unseen
            this frame (coasting on a predicted bearing, or lost: :meth:`unseen`).
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
    uv: np.ndarray | None = None
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
    extended: int = 0  # frames in a row on extended texture (the grouper's step 4)
    split_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # step 3c candidate
    split_n: int = 0  # frames in a row the step 3c candidate split was found
    split: bool = False  # split off another track by its motion (step 3c): not judged as texture
    plane_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # step 3f candidate
    plane_n: int = 0  # frames in a row the step 3f candidate split was found
    plane_seen: int = -(10**9)  # the grouper's frame count when step 3f last found a part in it

    def unseen(self) -> None:
        """No view of it this frame (coasting or lost): not seen, no members, no pixel."""
        self.seen = False
        self.members, self.member_b_C = _NO_IDS, _NO_BEARINGS
        self.uv = None


class ObstacleGrouper:
    """Groups the features of one camera into obstacle tracks (see the module docstring).

    Args:
        ids: shared id counter for track ids.
        link_px: largest distance between neighbouring features of one obstacle, in pixels at the
            lens's mean scale (turned into an angle, ``link_rad``, on the first update).
        max_radius_px: largest distance of a member from its track's representative point (pixels,
            turned into ``max_radius_rad`` likewise).
        flow_abs_rad_s, flow_rel: flows agree when ``|f_i - f_j| < flow_abs + flow_rel * max(|f_i|, |f_j|)``.
        flow_window_s: flow measured over this time (s; 1/6: 5 frames at 30 fps), less for younger
            features, at most ``history - 1`` frames back.
        min_features: features needed to start a track.
        min_features_isolated: features enough to start a track when they are isolated (no other
            live feature within ``link_rad``) and all tracked for at least ``isolated_min_age_s``
            (0.4 s: 12 frames at 30 fps): a small obstacle against the sky has one or two corners.
        min_age_s: time (s; 0.1: 3 frames at 30 fps) a feature must have been tracked before it can
            join or start a track.
        confirm_s: time (s; 1/6: 5 frames at 30 fps) of frames with members before a track is
            confirmed.
        max_missed_s: time (s; 1/3: 10 frames at 30 fps) a track may go unseen (occlusion, frame
            drops) before it is lost.
        coast_predict: an unseen track's bearing moves on with its last flow (and the camera's
            rotation when given), so features found where the obstacle went revive it (issue 4).
        extended_sectors: a track is on extended texture when features moving with it lie in at
            least this many of the 8 sectors around it (empty sectors outside the lens excepted,
            at least 4 occupied); 0 turns the rule off.
        extended_s: time (s; 0.1: 3 frames at 30 fps) a tentative track may be on extended texture
            in every frame before it is dropped (confirmed tracks are kept).
        centre_gain: pull of the representative bearing towards the member mean per frame.
        sigma_floor_px: floor of sigma_rad, in pixels at the representative point.
        split_window_s: window (s) over which step 3c compares its members' motions. 1/3 s (10
            frames at 30 fps): long enough that the relative motion of two surfaces whose
            frame-to-frame flows agree within the grouping tolerance (``flow_abs`` is the noise
            floor of a ``flow_window_s`` flow) adds up to a few pixels, short enough to be judged
            while the features of a crossing obstacle live; at most ``history - 1`` frames (the
            feature tracker's; 63 by default: 1/3 s up to 189 fps).
        split_min_px: step 3c links two neighbouring members when their window flows differ by
            less than this many pixels over the window plus ``split_rel`` of the larger flow.
            KLT follows a corner to 0.1-0.3 px per frame, so 1.5 px over the window is several
            times what noise alone gives; 0 turns step 3c off.
        split_rel: the relative part: a smooth surface's flow changes between neighbours
            ``link_px`` apart (~0.1 rad at 720p) by about that fraction of itself (flow ~ 1/depth,
            and depth changes across a fronto-parallel patch of 0.1 rad by ~0.1 at 45 degrees
            off its normal), a depth step (an obstacle in front of what lies behind it) by more.
        split_step: ... and a part leaves only when the flow jumps across its boundary (median over
            the near pairs across it) by this many times what it changes between neighbours
            within the parts (median over their near pairs), and by ``split_min_px``: a step, not
            a gradient. On a smooth surface neighbouring pairs across any line differ about as
            much as pairs beside it; 3 leaves room for noise in the medians.
        split_persist_s: time (s; 0.1: 3 frames at 30 fps) over which the same split (half its
            features in common) must be found in every frame before the track splits: evidence
            over several frames, not one.
        plane_min: step 3f (in ``_split``): tracks of at least this many members judged over the
            window (and at least 12: 8 plane parameters, a part of 3 and a rest of 8) are tested
            for a compact part off the planar flow field of the others (``_plane_parts``); default
            12; 0 turns step 3f off.
        plane_z: ... and a part leaves only when its mean displacement from the others' plane is
            this many sigmas of the fit's prediction (``z`` in ``_plane_parts``).
        plane_ratio: ... and its mean displacement is at least this many times the rest's RMS
            residual about its plane (per axis): one surface off a plane, not a part of a curved
            obstacle, whose rest is as far from planar (tuned scenes: parts of one obstacle 4-9,
            obstacles off the ground 17-84).
        plane_every_s: step 3f tests a track every this long (s; 1/15: every 2nd frame at 30 fps;
            staggered by track id: the cost spread over frames), and every frame once it found a
            part in it (the split still needs it found over ``split_persist_s``).
        label: label of the tracks (the detector's name).

    Attributes: ``durations`` (the settings above in s, by key) and their frame counts at the rate
    seen, set each frame (``_count``): flow_frames, min_age, isolated_min_age, confirm_frames,
    max_missed, extended_frames, split_frames, split_persist, plane_every, bg_frames.
    """

    # its frame counts that are durations now: old key -> (new key, the old default in time); the front
    # end's option check (trackers.frontend.option_problem) names the replacement from it
    RENAMED: ClassVar[dict[str, tuple[str, str]]] = {
        "flow_frames": ("flow_window_s", "5 frames at 30 fps = 1/6 s"),
        "min_age": ("min_age_s", "3 frames at 30 fps = 0.1 s"),
        "isolated_min_age": ("isolated_min_age_s", "12 frames at 30 fps = 0.4 s"),
        "confirm_frames": ("confirm_s", "5 frames at 30 fps = 1/6 s"),
        "max_missed": ("max_missed_s", "10 frames at 30 fps = 1/3 s"),
        "extended_frames": ("extended_s", "3 frames at 30 fps = 0.1 s"),
        "split_frames": ("split_window_s", "10 frames at 30 fps = 1/3 s"),
        "split_persist": ("split_persist_s", "3 frames at 30 fps = 0.1 s"),
        "plane_every": ("plane_every_s", "every 2nd frame at 30 fps = 1/15 s"),
    }

    BG_S = 0.5  # time (s) a feature stays marked as extended texture (15 frames at 30 fps)

    def __init__(
        self,
        ids: Iterator[int],
        link_px: float = 35.0,
        max_radius_px: float = 50.0,
        flow_abs_rad_s: float = 0.03,
        flow_rel: float = 0.2,
        flow_window_s: float = 5 / 30,
        min_features: int = 3,
        min_features_isolated: int = 1,
        isolated_min_age_s: float = 0.4,
        min_age_s: float = 0.1,
        confirm_s: float = 5 / 30,
        max_missed_s: float = 1 / 3,
        coast_predict: bool = True,
        extended_sectors: int = 6,
        extended_s: float = 0.1,
        centre_gain: float = 0.02,
        sigma_floor_px: float = 0.5,
        split_window_s: float = 1 / 3,
        split_min_px: float = 1.5,
        split_rel: float = 0.1,
        split_step: float = 3.0,
        split_persist_s: float = 0.1,
        plane_min: int = 12,
        plane_z: float = 6.0,
        plane_every_s: float = 1 / 15,
        plane_ratio: float = 12.0,
        label: str = "orb",
        **old: Any,
    ) -> None:
        self.durations = check_durations(
            "ObstacleGrouper",
            ObstacleGrouper.RENAMED,
            old,
            {
                "flow_window_s": flow_window_s, "isolated_min_age_s": isolated_min_age_s,
                "min_age_s": min_age_s, "confirm_s": confirm_s, "max_missed_s": max_missed_s,
                "extended_s": extended_s, "split_window_s": split_window_s,
                "split_persist_s": split_persist_s, "plane_every_s": plane_every_s,
            },
        )
        if (
            link_px <= 0
            or max_radius_px <= 0
            or min_features < 1
            or not 0 <= extended_sectors <= 8
            or not 0 <= split_min_px < float("inf")  # (also NaN)
            or not 0 <= split_rel < float("inf")
            or not 1 <= split_step < float("inf")
        ):
            raise ConfigError(
                "ObstacleGrouper: expected link_px > 0, max_radius_px > 0, min_features >= 1, "
                "0 <= extended_sectors <= 8, finite split_min_px >= 0 (0: step 3c off), "
                "split_rel >= 0, split_step >= 1; got "
                f"{link_px}, {max_radius_px}, {min_features}, "
                f"{extended_sectors}, {split_min_px}, {split_rel}, {split_step}"
            )
        self._ids = ids
        self.link_px = float(link_px)
        self.max_radius_px = float(max_radius_px)
        self.link_rad = self.max_radius_rad = 0.0  # set from the camera's scale on each update
        self.flow_abs = float(flow_abs_rad_s)
        self.flow_rel = float(flow_rel)
        self.min_features = int(min_features)
        self.min_features_isolated = int(min_features_isolated)
        self.coast_predict = bool(coast_predict)
        self.extended_sectors = int(extended_sectors)
        self.centre_gain = float(centre_gain)
        self.sigma_floor_px = float(sigma_floor_px)
        self.split_min_px = float(split_min_px)
        self.split_rel = float(split_rel)
        self.split_step = float(split_step)
        # the durations as frame counts at the rate seen (``_count``, each frame)
        self.clock = FrameClock()
        self._history_cap = 10**9  # the feature tracker's history - 1 (known at the first update)
        self._count()
        if isinstance(plane_min, bool) or not isinstance(plane_min, (int, np.integer)) or plane_min < 0:
            raise ConfigError(
                f"ObstacleGrouper: expected plane_min an integer >= 0 (0: step 3f off); got {plane_min!r}"
            )
        self.plane_min = int(plane_min)
        real = (int, float, np.integer, np.floating)
        if not isinstance(plane_z, real) or not 0 < plane_z < float("inf"):  # (also NaN)
            raise ConfigError(f"ObstacleGrouper: expected a finite plane_z > 0 (sigmas); got {plane_z!r}")
        self.plane_z = float(plane_z)
        if not isinstance(plane_ratio, real) or not 0 <= plane_ratio < float("inf"):  # (also NaN)
            raise ConfigError(f"ObstacleGrouper: expected a finite plane_ratio >= 0; got {plane_ratio!r}")
        self.plane_ratio = float(plane_ratio)
        # step 3f on a rig of several cameras (set by the front end): given a track whose part is
        # due to leave, whether the same obstacle's track in another camera found a part of its
        # own in its latest update (``plane_recent``); a split one camera's flow alone supports is
        # not made. None (one camera): no such check.
        self.plane_confirm: Callable[[ObstacleTrack], bool] | None = None
        # the frame-to-frame rotations, as far back as step 3c's window and the flow's reach (their
        # cap, the feature history's; set at the first update)
        self._R1_hist: deque[np.ndarray] = deque(maxlen=1)
        # their products R_C(t)_C(t-k), k = 1, 2, ..., as far as this frame's windows asked for
        # (``_window_rotations``: the flow's and step 3c's windows share the chain's start)
        self._R1_chain: list[np.ndarray] = []
        self.label = label
        self.tracks: dict[int, ObstacleTrack] = {}
        # features judged to be on extended texture: ids (sorted) and the frame their mark expires
        self._bg_ids = np.zeros(0, np.int64)
        self._bg_until = np.zeros(0, np.int64)
        self._frame = 0
        self.splits = 0  # tracks split by step 3c so far (a diagnostic count)
        self._need_t = np.zeros(0, np.int64)  # this frame's members each track needs to stay seen

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
        dt_s = self.clock.tick(t_s)  # (the time since the last frame)
        if self._history_cap != ft.H - 1:  # windows into the history reach at most its length back
            self._history_cap = ft.H - 1
            self._R1_hist = deque(self._R1_hist, maxlen=self._history_cap)
        self._count()
        rad_px = ft.model.rad_per_px
        self.link_rad = self.link_px * rad_px
        self.max_radius_rad = self.max_radius_px * rad_px
        cos_link, cos_r = np.cos(self.link_rad), np.cos(self.max_radius_rad)
        R1 = R_C_Cprev.get(1) if R_C_Cprev else None
        self._remember_rotation(R1)
        flow, fvalid = self._flows(ft, t_s, R_C_Cprev)
        fvalid &= ft.age >= self.min_age
        f2 = _einsum("ij,ij->i", flow, flow)
        fnorm = np.sqrt(f2)
        b_prev, pvalid = ft.previous_bearing()
        tracks = list(self.tracks.values())
        T = len(tracks)
        rep = np.array([t.b_C for t in tracks], float).reshape(T, 3)
        tflow = np.array([t.flow_rad_s for t in tracks], float).reshape(T, 3)
        hits = np.array([t.hits for t in tracks], np.int64)
        conf = np.array([t.status == "confirmed" for t in tracks], bool).reshape(T)
        km = self._keep_min()
        need_t = np.array([t.keep_min or km for t in tracks], np.int64).reshape(T)  # members to stay seen
        self._need_t = need_t  # (for _inherit and _revive this frame)
        owner = self._owners(ids, tracks)
        self._frame += 1
        bg = self._background(ids)
        # 1. members stay within max_radius of the representative bearing and move with the track
        r = (owner >= 0).nonzero()[0]
        if len(r):
            far = _einsum("ij,ij->i", b.take(r, 0), rep.take(owner[r], 0)) < cos_r
            owner[r[far]] = -1
        sel = ((owner >= 0) & fvalid).nonzero()[0]  # members with a flow
        o, f_sel, fn_sel = owner[sel], flow.take(sel, 0), fnorm[sel]
        tflow, has_flow = self._mean_flow(o, f_sel, tflow, T)
        for loose in (2.0, 1.0):  # robust mean flow: a loose cut, then the strict one
            if len(sel):
                t_o = tflow.take(o, 0)
                good = self._agree(f_sel, fn_sel, t_o, loose, _norm_rows(tflow)[o]) | ~has_flow[o]
                if not good.all():  # (else the mean over the same members is the same)
                    owner[sel[~good]] = -1
                    sel, o, f_sel, fn_sel = sel[good], o[good], f_sel.compress(good, 0), fn_sel[good]
                    tflow, has_flow = self._mean_flow(o, f_sel, tflow, T)
        # 2. unassigned features with a flow join the track of their nearest member (features
        # marked as extended texture too: they start no new group, but may move with a track)
        free = ((owner < 0) & fvalid).nonzero()[0]
        memb = (owner >= 0).nonzero()[0]
        if len(free) and len(memb):
            cosd = b.take(free, 0) @ b.take(memb, 0).T
            j = np.argmax(cosd, axis=1)
            k = (cosd[np.arange(len(free)), j] > cos_link).nonzero()[0]
            fk, t_of = free[k], owner[memb[j[k]]]
            ok = _einsum("ij,ij->i", b.take(fk, 0), rep.take(t_of, 0)) > cos_r
            # (the last known flow if < 3 members)
            ok &= self._agree(flow.take(fk, 0), fnorm[fk], tflow.take(t_of, 0), 1.0, _norm_rows(tflow)[t_of])
            owner[fk[ok]] = t_of[ok]
        # 2b. a track short of members (coasting, or its features replaced) takes the free features
        # within link_rad of where it was predicted to be that move like it
        cnt_now = np.bincount(owner[owner >= 0], minlength=T) if T else np.zeros(0, np.int64)
        short = ((cnt_now < need_t) & (hits > 0)).nonzero()[0]
        free = ((owner < 0) & fvalid).nonzero()[0]
        pred = rep.take(short, 0)
        pred = pred @ R1.T if R1 is not None else pred
        pred = _normalise(pred + tflow.take(short, 0) * dt_s) if self.coast_predict else pred
        if len(short) and len(free):
            cs = b.take(free, 0) @ pred.T  # (F, S)
            ok = (cs > cos_link) & self._agree(
                flow.take(free, 0)[:, None, :], fnorm[free][:, None], tflow.take(short, 0)[None, :, :]
            )
            cs = np.where(ok, cs, -2.0)
            j = np.argmax(cs, axis=1)
            hit = cs[np.arange(len(free)), j] > -2.0
            owner[free[hit]] = short[j[hit]]
            got = np.bincount(j[hit], minlength=len(short)) > 0
            fresh_short = short[got & (cnt_now[short] == 0)]
        else:
            fresh_short = np.zeros(0, np.intp)
        # 3. new groups from the rest: revive a memberless track where it was predicted, else new
        free = ((owner < 0) & fvalid & ~bg).nonzero()[0]
        pieces, small = self._pieces(free, b, flow, fvalid, ft.age, cos_link, f2)
        K = len(pieces)
        fresh = np.zeros(T + K, bool)  # its members are all new this frame (no motion to follow)
        keep1 = np.zeros(T + K, bool)  # a small isolated obstacle: one member keeps it seen
        fresh[fresh_short] = True
        if K:
            rows_all = np.concatenate(pieces)
            piece_of = np.arange(K).repeat([len(p) for p in pieces])
            cnt_p = np.bincount(piece_of, minlength=K)
            b_p, f_p = b.take(rows_all, 0), flow.take(rows_all, 0)
            pc = _normalise(_bincount3(piece_of, b_p, K))
            pf = _bincount3(piece_of, f_p, K) / cnt_p[:, None]
            tgt = T + np.arange(K)  # index of each piece's track: a new one unless revived
            cnt_now = np.bincount(owner[owner >= 0], minlength=T) if T else np.zeros(0, np.int64)
            cand = ((cnt_now < need_t) & (hits > 0)).nonzero()[0]
            if len(cand):
                # where each candidate is now: b <- normalise(R_C_Cprev b + flow dt)
                pred = rep.take(cand, 0)
                pred = pred @ R1.T if R1 is not None else pred
                pred = _normalise(pred + tflow.take(cand, 0) * dt_s) if self.coast_predict else pred
                cs = pc @ pred.T  # (K, C)
                pi, ci = np.nonzero(cs > cos_r)
                agree = self._agree(pf.take(pi, 0), _norm_rows(pf)[pi], tflow.take(cand[ci], 0))
                pi, ci = pi[agree], ci[agree]
                used_p, used_c = set(), set()
                order = (-cs[pi, ci]).argsort(kind="stable")  # closest pairs first
                for p, c in zip(pi[order].tolist(), ci[order].tolist(), strict=True):
                    if p not in used_p and c not in used_c:
                        used_p.add(p)
                        used_c.add(c)
                        tc = int(cand[c])
                        tgt[p] = tc
                        rep[tc] = pc[p]
                        fresh[tc] = cnt_now[tc] == 0
            fresh[T:] = True
            keep1[tgt] = small
            owner[rows_all] = tgt[piece_of]
            rep = np.concatenate([rep, pc])
            tflow = np.concatenate([tflow, pf])
        TK = T + K
        tflow, has_flow = self._track_flow(owner, flow, fvalid, tflow, TK)
        # 3b. one obstacle tracked as two pieces (cut to max_radius as it grew in the image) whose
        # older piece lost its members (out of the image, occluded): it takes over the younger one
        conf_k = np.concatenate([conf, np.zeros(TK - T, bool)])
        hits_k = np.concatenate([hits, np.zeros(TK - T, np.int64)])
        taken = self._inherit(owner, b, tflow, has_flow, conf_k, hits_k, cos_link, tracks, R1, dt_s)
        if (taken >= 0).any():
            hj = (taken >= 0).nonzero()[0]
            rep[taken[hj]] = rep[hj]  # the heir's representative bearing carries on
            tflow, _ = self._track_flow(owner, flow, fvalid, tflow, TK)
        # 3c. two surfaces in one track (an occluding edge, an obstacle crossing the background):
        # split by the members' motion over split_frames frames, found split_persist frames in a row
        split_born = np.zeros(TK, bool)
        if T and self.split_min_px > 0:
            sp_rows, sp_tgt = self._split(
                ft, t_s, R_C_Cprev, owner, rep, tracks, taken, rad_px, flow, fvalid, tflow, R1, dt_s
            )
            self.splits += len(sp_rows)
            for rows_s, (src, dst) in zip(sp_rows, sp_tgt, strict=True):
                fresh[src] = True  # its representative restarts at its remaining members' mean
                if dst < 0:  # a new track
                    dst = TK
                    TK += 1
                    K += 1
                    rep = np.concatenate([rep, _normalise(b[rows_s].mean(0))[None]])
                    tflow = np.concatenate([tflow, tflow[src][None]])
                    fresh = np.concatenate([fresh, [True]])
                    keep1 = np.concatenate([keep1, [False]])
                    taken = np.concatenate([taken, [-1]])
                    split_born = np.concatenate([split_born, [True]])  # (exempt from step 4)
                else:  # a memberless track revived by it
                    tracks[dst].split = True
                    fresh[dst] = True
                    rep[dst] = _normalise(b[rows_s].mean(0))
                owner[rows_s] = dst
            if sp_rows:
                tflow, _ = self._track_flow(owner, flow, fvalid, tflow, TK)
        # 4. representative bearing, sigma, reach
        own = (owner >= 0).nonzero()[0]
        o = owner[own]
        cnt = np.bincount(o, minlength=TK)
        b_own = b.take(own, 0)
        mean_c = _normalise(_bincount3(o, b_own, TK))
        m_per = pvalid[own] & ~fresh[o]
        po = o[m_per]
        pcnt = np.bincount(po, minlength=TK)
        d_per = b_own.compress(m_per, 0) - b_prev.take(own[m_per], 0)
        dsum = _bincount3(po, d_per, TK)
        # move with the members present in both frames: b_rep += mean(b_now - b_prev), then a
        # gentle pull towards the member mean (gain centre_gain)
        moved = _normalise(rep + dsum / np.maximum(pcnt, 1)[:, None])
        moved = _normalise(moved + self.centre_gain * (mean_c - moved))
        use_moved = (pcnt > 0) & (_einsum("ij,ij->i", moved, mean_c) > cos_r)
        new_rep = np.where(use_moved[:, None], moved, mean_c)
        ang = np.arccos(_einsum("ij,ij->i", b_own, new_rep.take(o, 0)).clip(-1.0, 1.0))
        order_o = o.argsort(kind="stable")
        srt = own[order_o]  # member rows grouped by track
        starts = np.concatenate([[0], cnt.cumsum()])
        ne = (cnt > 0).nonzero()[0]
        spread2 = np.bincount(o, ang * ang, TK) / np.maximum(cnt, 1)
        # sigma^2 = spread^2 / n + floor^2
        sigma = np.sqrt(spread2 / np.maximum(cnt, 1) + (self.sigma_floor_px * rad_px) ** 2)
        reach = np.zeros(TK)  # farthest member's angle from the representative bearing
        if len(ne):
            reach[ne] = np.maximum.reduceat(ang[order_o], starts[ne])
        need = np.full(TK, km)
        need[:T] = need_t
        need[keep1] = 1
        alive = cnt >= need
        # 5. extended texture
        ext = np.zeros(TK, bool)
        # (confirmed tracks are not judged: an established obstacle keeps its track)
        tent = np.ones(TK, bool)
        tent[:T] = [t.status == "tentative" and not t.split for t in tracks]
        tent &= ~split_born  # (split off by its motion against what surrounds it)
        if self.extended_sectors and (alive & tent).any():
            a_idx = (alive & tent).nonzero()[0]
            ext[a_idx] = self._embedded(
                new_rep.take(a_idx, 0), reach[a_idx], tflow.take(a_idx, 0), a_idx, b, flow, fvalid, owner,
                ft.model,
            )
        # 6. the tracks' new state, the life cycle (array work first, then one pass over tracks)
        # (python lists: the loop below reads them one element at a time)
        alive_l, ext_l, taken_l = alive.tolist(), ext.tolist(), taken.tolist()
        new_ids = [next(self._ids) if alive_l[ti] and not ext_l[ti] else -1 for ti in range(T, TK)]
        show = alive.nonzero()[0]
        # a representative that does not project (moved on with its members beyond the lens's
        # field as the obstacle leaves it) has no pixel: uv None, never a made-up one
        uv_all: list[np.ndarray | None] = [None] * TK
        if len(show):
            uv, ok = ft.model.bearing_to_pixel(new_rep.take(show, 0))
            for ti, u in zip(show[ok].tolist(), uv[ok], strict=True):
                uv_all[ti] = u
        coast_b = rep[:T] @ R1.T if R1 is not None else rep[:T]
        if self.coast_predict and dt_s > 0:  # b <- normalise(R_C_Cprev b + flow dt): see _coast_one
            coast_b = _normalise(coast_b + tflow[:T] * dt_s)
        ids_s, b_s = ids[srt], b.take(srt, 0)  # members grouped by track (slices below are views)
        st = starts.tolist()
        sig = sigma.tolist()
        seen, lost, to_bg = [], [], []
        for ti in range(TK):
            if ti < T:
                tr = tracks[ti]
                if taken_l[ti] >= 0:  # taken over by an older track of the same obstacle
                    tr.unseen()
                    tr.status = "lost"
                    del self.tracks[tr.id]
                    lost.append(tr)
                    continue
                if not alive_l[ti]:  # unseen: coast on the predicted bearing
                    tr.unseen()
                    tr.b_C = coast_b[ti]
                    tr.missed += 1
                    if tr.missed > self.max_missed:
                        tr.status = "lost"
                        del self.tracks[tr.id]
                        lost.append(tr)
                    continue
                tr.extended = tr.extended + 1 if ext_l[ti] else 0
                if tr.extended >= self.extended_frames and tr.status == "tentative":
                    tr.unseen()
                    tr.status = "lost"
                    to_bg.append(srt[st[ti] : st[ti + 1]])
                    del self.tracks[tr.id]
                    lost.append(tr)
                    continue
            else:
                if not alive_l[ti]:
                    continue
                if ext_l[ti]:  # a piece of extended texture: no track
                    to_bg.append(srt[st[ti] : st[ti + 1]])
                    continue
                tid = new_ids[ti - T]
                tr = ObstacleTrack(tid, ft.name, _NO_IDS, new_rep[ti], hits=0, label=self.label)
                tr.keep_min = 1 if keep1[ti] else 0
                tr.split = bool(split_born[ti])
                self.tracks[tid] = tr
            tr.members, tr.member_b_C = ids_s[st[ti] : st[ti + 1]], b_s[st[ti] : st[ti + 1]]
            tr.b_C, tr.flow_rad_s, tr.sigma_rad, tr.uv = new_rep[ti], tflow[ti], sig[ti], uv_all[ti]
            tr.hits += 1
            tr.missed = 0
            tr.seen = True
            if tr.status == "tentative" and tr.hits >= self.confirm_frames:
                tr.status = "confirmed"
            seen.append(tr)
        if to_bg:
            self._mark_background(ids[np.concatenate(to_bg)])
        return seen, lost

    def coast(self, t_s: float, R_C_Cprev: dict[int, np.ndarray] | None = None) -> list[ObstacleTrack]:
        """A frame without usable features (dropped, black or flat): every track coasts (its
        bearing moves on with its flow and the camera's rotation ``R_C_Cprev[1]`` (3,3) when given).

        Args:
            t_s: frame time (s); R_C_Cprev: as in ``update``.
        Returns:
            the tracks lost this frame (unseen for more than ``max_missed_s``)."""
        dt_s = self.clock.tick(t_s)
        self._count()
        R1 = R_C_Cprev.get(1) if R_C_Cprev else None
        self._remember_rotation(R1)
        lost = []
        for tr in list(self.tracks.values()):
            if self._coast_one(tr, dt_s, R1):
                lost.append(tr)
        return lost

    # ----------------------------------------------------------------------------- helpers
    def _count(self) -> None:
        """This frame's frame counts of the durations (``FrameClock.frames`` at the rate seen; the
        windows into the feature history capped at its length, ``history - 1`` frames back)."""
        d, f, cap = self.durations, self.clock.frames, self._history_cap
        self.flow_frames = min(f(d["flow_window_s"]), cap)
        self.min_age = f(d["min_age_s"])
        self.isolated_min_age = f(d["isolated_min_age_s"])
        self.confirm_frames = f(d["confirm_s"])
        self.max_missed = f(d["max_missed_s"], 0)
        self.extended_frames = f(d["extended_s"])
        self.split_frames = min(f(d["split_window_s"], 2), cap)
        self.split_persist = f(d["split_persist_s"])
        self.plane_every = f(d["plane_every_s"])
        self.bg_frames = f(self.BG_S)

    def _background(self, ids: np.ndarray) -> np.ndarray:
        """(N,) bool: live feature ids (N,) marked as extended texture (marks expire after
        ``BG_S``, so an obstacle taken for texture gets another chance)."""
        keep = self._bg_until > self._frame
        if not keep.all():
            self._bg_ids, self._bg_until = self._bg_ids[keep], self._bg_until[keep]
        if not len(self._bg_ids) or not len(ids):
            return np.zeros(len(ids), bool)
        k = np.minimum(self._bg_ids.searchsorted(ids), len(self._bg_ids) - 1)
        return self._bg_ids[k] == ids

    def _mark_background(self, fids: np.ndarray) -> None:
        """Mark feature ids (K,) as extended texture for the next ``BG_S`` (``bg_frames`` frames)."""
        allid = np.concatenate([self._bg_ids, fids])
        until = np.concatenate([self._bg_until, np.full(len(fids), self._frame + self.bg_frames)])
        order = allid.argsort(kind="stable")
        self._bg_ids, self._bg_until = allid[order], until[order]

    def _keep_min(self) -> int:
        """Members a track needs to stay seen: half of min_features, at least 2."""
        return max(2, self.min_features // 2)

    def _coast_one(self, tr: ObstacleTrack, dt_s: float, R1: np.ndarray | None) -> bool:
        """One unseen frame of ``tr``; True when it is lost now (and dropped from ``tracks``)."""
        tr.unseen()
        tr.missed += 1
        # coast on the predicted bearing: b <- normalise(R_C_Cprev b + flow dt) (flow: tangent,
        # rad/s, rotation-compensated when R_C_Cprev is given), so new features found where
        # the obstacle went revive it under its old id
        if self.coast_predict and dt_s > 0:
            b_pred = R1 @ tr.b_C if R1 is not None else tr.b_C
            tr.b_C = _normalise(b_pred + tr.flow_rad_s * dt_s)
        if tr.missed > self.max_missed:
            tr.status = "lost"
            del self.tracks[tr.id]
            return True
        return False

    def _inherit(
        self,
        owner: np.ndarray,
        b: np.ndarray,
        tflow: np.ndarray,
        has_flow: np.ndarray,
        conf: np.ndarray,
        hits: np.ndarray,
        cos_link: float,
        tracks: list[ObstacleTrack],
        R1: np.ndarray | None,
        dt_s: float,
    ) -> np.ndarray:
        """A confirmed track that has lost its members this frame takes over a younger track seen
        this frame that lies where its members went (one of its members within ``link_rad`` of
        one of the old track's last members, moved on by the old track's flow and the camera's
        rotation R1 (3,3)) and moves like it: one obstacle tracked as two pieces whose older piece
        left the image or was hidden. The old id carries on (downstream filters know it).

        Args: owner (N,) track index per live feature, -1 none (changed in place); b (N,3) unit
        bearings in C; per track index (TK): tflow (TK,3) mean member flow (rad/s), has_flow
        (from >= 3 members), conf (confirmed), hits; tracks: the T existing tracks (indices < T).
        Returns taken (TK,) int: the index of the track that took over each one, -1 for none."""
        TK = len(tflow)
        T = len(tracks)
        out = np.full(TK, -1, np.intp)
        if T == 0:
            return out
        cnt = np.bincount(owner[owner >= 0], minlength=TK)
        dying = [i for i in ((cnt[:T] < self._need_t) & conf[:T]).nonzero()[0] if len(tracks[i].member_b_C)]
        if not dying:
            return out
        alive = cnt >= np.concatenate([self._need_t, np.full(TK - T, self._keep_min())])
        used = np.zeros(TK, bool)
        fn = _norm_rows(tflow)
        for i in dying:
            mb = tracks[i].member_b_C
            mb = mb @ R1.T if R1 is not None else mb
            mb = _normalise(mb + tflow[i] * dt_s) if self.coast_predict else mb
            cand = (alive & ~used & (hits < hits[i]) & has_flow).nonzero()[0]
            cand = cand[self._agree(tflow[cand], fn[cand], tflow[i][None, :])]
            best, best_c = -1, cos_link
            for j in cand:
                rj = (owner == j).nonzero()[0]
                c = float(np.max(b[rj] @ mb.T))
                if c > best_c:
                    best, best_c = j, c
            if best >= 0:
                owner[owner == best] = i
                out[best] = i
                used[best] = used[i] = True
        return out

    def _split(
        self,
        ft: FeatureTracker,
        t_s: float,
        R: dict[int, np.ndarray] | None,
        owner: np.ndarray,
        rep: np.ndarray,
        tracks: list[ObstacleTrack],
        taken: np.ndarray,
        rad_px: float,
        flow: np.ndarray,
        fvalid: np.ndarray,
        tflow: np.ndarray,
        R1: np.ndarray | None,
        dt_s: float,
    ) -> tuple[list[np.ndarray], list[tuple[int, int]]]:
        """Step 3c: tracks whose members form two surfaces by their motion over the last
        ``split_frames`` frames (``split_window_s``; an obstacle and what lies behind or beside it:
        a parallax step at the occluding edge, or one of them moving), grouped together because their
        frame-to-frame flows differ less than the grouping tolerance.

        Per existing track (``tracks``, indices < T), each member tracked over at least half the
        window gets a window flow ``(b_now - R_C_Cprev[k] b_k_ago) / dt`` (rad/s, k <=
        split_frames frames back; rotation-compensated when that rotation is given, with
        ``_window_rotations`` over the whole window), expressed
        in the tangent plane at the track's representative bearing ``rep`` (TK,3) (there a camera
        rotation's flow field is the same to second order in the track's size). The members are
        re-linked: two members within ``link_rad`` link when their window flows differ by less
        than ``split_min_px`` pixels over the shorter of their windows plus ``split_rel`` of the
        larger flow (a smooth surface's flow changes little between neighbours; a depth step
        or an independently moving obstacle makes a jump). A track whose linked members fall
        into two components of 2 or more has a candidate split: the second largest component.
        The track splits when a candidate was found ``split_persist`` frames in a row
        (``split_persist_s``) with half of its features in common; the candidate's members leave:
        they revive a memberless track predicted within ``max_radius`` of them whose flow agrees,
        else they start a new track.

        Args: ft, t_s, R as in ``update``; owner (N,) track index per live feature (not changed);
        rep (TK,3) unit bearings in C; tracks: the T existing tracks (their split state is
        updated); taken (TK,) from ``_inherit``; rad_px: radians per pixel; flow (N,3), fvalid
        (N,) the features' flows (rad/s) as in ``update``; tflow (TK,3) the tracks' mean flows;
        R1 (3,3) or None, dt_s: the camera's rotation and the time since the last frame.
        Returns (rows (K_i,) into the live features per split-off part, (source track index,
        target track index or -1 for a new track) per part)."""
        T = len(tracks)
        # the camera's rotation over the whole window (chained past the front end's few frames);
        # with rotations, the window reaches only as far back as they are known
        R = self._window_rotations(R, self.split_frames)
        L = min(self.split_frames, max(R)) if R else self.split_frames
        out_rows: list[np.ndarray] = []
        out_tgt: list[tuple[int, int]] = []
        back = np.minimum(ft.age - 1, L)  # samples back in the window (a feature has one per frame)
        rows = ((owner >= 0) & (owner < T) & (2 * back >= L)).nonzero()[0]
        o = owner[rows]
        cnt = np.bincount(o, minlength=T)
        judged = (cnt >= 4) & (taken[:T] < 0)
        sel = judged[o]
        rows, o = rows[sel], o[sel]
        srt = o.argsort(kind="stable")  # rows grouped by track (blocks), in row order within
        rows, o = rows[srt], o[srt]
        found = np.zeros(T, bool)
        plane: dict[int, np.ndarray] = {}  # step 3f: track index -> rows of its part off the plane
        if len(rows):
            b_then, t_then, _ = ft.bearing_ago(L)
            b_then, bk = b_then.take(rows, 0), back[rows]
            if R:
                Rs = _EYE3.repeat(L + 1, 0)
                for kk, Rk in R.items():
                    if 0 < kk <= L:
                        Rs[kk] = Rk
                b_then = _einsum("nij,nj->ni", Rs.take(bk, 0), b_then)
            dt = np.maximum(t_s - t_then[rows], 1e-9)
            f = (ft.b_C.take(rows, 0) - b_then) / dt[:, None]  # window flow (rad/s)
            e1, e2 = _tangent_basis(rep[:T])
            e1o, e2o = e1.take(o, 0), e2.take(o, 0)
            xy = np.stack([_einsum("ij,ij->i", f, e1o), _einsum("ij,ij->i", f, e2o)], 1)
            fn = np.hypot(xy[:, 0], xy[:, 1])
            if self.plane_min:  # step 3f: a part off the members' planar flow field
                # (each track every plane_every-th frame, staggered by id; every frame while a
                # candidate of it is being confirmed)
                due = np.array(
                    [t.plane_n > 0 or (self._frame + t.id) % self.plane_every == 0 for t in tracks], bool
                ).reshape(T)
                plane = self._plane_parts(o, rows, ft.b_C.take(rows, 0), e1, e2, xy, dt, T, rad_px, due)
            # tracks whose members' window flows all lie within half the smallest link tolerance
            # of their mean cannot be cut (every pair links): only the others are looked at
            nn = np.maximum(np.bincount(o, minlength=T), 1)
            dev = np.hypot(
                xy[:, 0] - (np.bincount(o, xy[:, 0], T) / nn)[o],
                xy[:, 1] - (np.bincount(o, xy[:, 1], T) / nn)[o],
            )
            maxdev, maxdt = np.zeros(T), np.zeros(T)
            np.maximum.at(maxdev, o, dev)
            np.maximum.at(maxdt, o, dt)
            cut_ok = 2.0 * maxdev >= self.split_min_px * rad_px / np.maximum(maxdt, 1e-9)
            sel = cut_ok[o]
            rows, o, xy, fn, dt = rows[sel], o[sel], xy.compress(sel, 0), fn[sel], dt[sel]
            bj = ft.b_C.take(rows, 0)
            m = len(rows)
            # member pairs (i < j) of one track (rows sorted by track: blocks), within link_rad;
            # every test below is symmetric in i and j, so one direction of each pair is enough
            cnt_o = np.bincount(o, minlength=T)
            reps_n = cnt_o.cumsum()[o] - np.arange(1, m + 1)  # rows after i in its block
            ei = np.arange(m).repeat(reps_n)
            ej = ei + 1 + (np.arange(len(ei)) - (reps_n.cumsum() - reps_n).repeat(reps_n))
            keep = _einsum("ij,ij->i", bj.take(ei, 0), bj.take(ej, 0)) > np.cos(self.link_rad)
            ei, ej = ei[keep], ej[keep]
            dd = np.hypot(*(xy.take(ei, 0) - xy.take(ej, 0)).T)  # |window flow difference| (rad/s)
            thr = self.split_min_px * rad_px / np.minimum(dt[ei], dt[ej])
            thr = thr + self.split_rel * np.maximum(fn[ei], fn[ej])
            linked = dd < thr
            # only tracks with a near pair that does not link can fall apart
            loose = np.bincount(o[ei[~linked]], minlength=T) > 0
            if not loose.any() and not plane:
                for t in range(T):  # no candidate this frame: the count restarts
                    tracks[t].split_n = tracks[t].plane_n = 0
                return out_rows, out_tgt
            li, lj = ei[linked], ej[linked]  # links (one direction each)
            # connected components: each end of a link takes the smaller label of the two, then
            # labels jump to their label's label, until nothing changes (the component's least row)
            labels = np.arange(m)
            while len(li):
                lo = np.minimum(labels[li], labels[lj])
                nxt = labels.copy()
                np.minimum.at(nxt, li, lo)
                np.minimum.at(nxt, lj, lo)
                nxt = nxt[nxt]
                if np.array_equal(nxt, labels):
                    break
                labels = nxt
            size = np.bincount(labels, minlength=m)
            ids = ft.ids
            # tracks with two parts of 2 or more members (a part lies in one track: links do)
            root = ((labels == np.arange(m)) & (size >= 2)).nonzero()[0]
            is_multi = judged & loose & (np.bincount(o[root], minlength=T) >= 2)
            # per such track its second largest part (ties: the lower label): part A
            root = root[is_multi[o[root]]]
            rk = np.lexsort((root, -size[root], o[root]))  # by track, then size descending
            root, ro = root[rk], o[root[rk]]
            a_lab = np.full(T, -1)
            rank = np.arange(len(ro)) - ro.searchsorted(ro)  # position within its track
            a_lab[ro[rank == 1]] = root[rank == 1]
            in_a = labels == a_lab[o]
            # a step, not a gradient: the flow jumps across part A's boundary by split_step times
            # what it changes between neighbours within the parts, and by the floor (per track:
            # lower medians over its near pairs; each pair once, which leaves a lower median as
            # over both directions)
            pe = is_multi[o[ei]]
            cross = pe & (in_a[ei] != in_a[ej])
            inner = pe & ~cross
            med_c = self._group_lower_median(o[ei[cross]], dd[cross], T)
            med_i = self._group_lower_median(o[ei[inner]], dd[inner], T)
            mdt = np.bincount(o, dt, T) / np.maximum(np.bincount(o, minlength=T), 1)
            floor_t = self.split_min_px * rad_px / np.maximum(mdt, 1e-9)
            step = is_multi & (med_c >= np.maximum(self.split_step * np.nan_to_num(med_i), floor_t))
            for t in step.nonzero()[0]:
                ia = (in_a & (o == t)).nonzero()[0]
                move = rows[ia]
                found[t] = True
                tr = tracks[t]
                tr.split_ids, tr.split_n = _found_again(ids[move], tr.split_ids, tr.split_n)
                if tr.split_n >= self.split_persist:
                    tr.split_n, tr.split_ids = 0, np.zeros(0, np.int64)
                    out_rows.append(move)
                    out_tgt.append((int(t), -1))
        for t in (~found).nonzero()[0].tolist():  # no candidate this frame: the count restarts
            tracks[t].split_n = 0
        # step 3f: the same persistence rule, for tracks step 3c did not split this frame
        found_l = found.tolist()
        for t, tr in enumerate(tracks):
            move = plane.get(t)
            if move is None or found_l[t]:
                if tr.plane_n or len(tr.plane_ids):  # (else it is reset already)
                    tr.plane_n, tr.plane_ids = 0, np.zeros(0, np.int64)
                continue
            tr.plane_ids, tr.plane_n = _found_again(ft.ids[move], tr.plane_ids, tr.plane_n)
            tr.plane_seen = self._frame
            # (refused by the other camera: the count goes on, the split waits for its support)
            if tr.plane_n >= self.split_persist and (self.plane_confirm is None or self.plane_confirm(tr)):
                tr.plane_n, tr.plane_ids = 0, np.zeros(0, np.int64)
                out_rows.append(move)
                out_tgt.append((int(t), -1))
        self._revive(ft.b_C, out_rows, out_tgt, owner, rep, tracks, taken, flow, fvalid, tflow, R1, dt_s)
        return out_rows, out_tgt

    def plane_recent(self, tr: ObstacleTrack) -> bool:
        """Whether step 3f found a part in this grouper's track ``tr`` in its latest update or the
        one before (a rig's cameras are grouped one after the other in a frame)."""
        return self._frame - tr.plane_seen <= 1

    def _plane_parts(
        self,
        o: np.ndarray,
        rows: np.ndarray,
        b: np.ndarray,
        e1: np.ndarray,
        e2: np.ndarray,
        xy: np.ndarray,
        dt: np.ndarray,
        T: int,
        rad_px: float,
        due: np.ndarray,
    ) -> dict[int, np.ndarray]:
        """Step 3f: per track (index < T) of at least ``plane_min`` judged members, a compact part
        whose window flows the planar flow field of the other members does not predict (an
        upright obstacle at one depth standing on the ground it is grouped with: at its base the
        flows are equal, so no link between neighbours parts them, but away from its base the
        ground's flow goes on changing with position and the obstacle's does not).

        The derotated flow of a plane ``n . X = h`` seen by a camera moving with velocity v is
        ``f(b) = -(n . b / h) P_b v`` (inverse range ``n . b / h`` along the unit bearing b,
        ``P_b = I - b b^T``), i.e. ``f = -P_b G b`` with ``G = v n^T / h``: linear in G, and G's
        identity part is invisible (``P_b b = 0``), so 8 parameters g over the basis
        ``_TRACELESS``: ``f = D(b) g``, D (2,8) the tangent components (e1, e2 at the track's
        representative bearing) of ``P_b B_k b``. Exact for any plane and lens (bearings, not
        pixels); the ground near the horizon is far from affine in the image. Each candidate
        part C is the disk of members within ``link_rad`` of one member; g is fitted to the rest
        R by least squares (normal equations ``N_R = N - N_C``, ``B_R = B - B_C``: one 8x8
        solve per candidate), with per-axis noise ``s^2 = SSE_R / (2 |R| - 8)``. C's mean
        residual ``rbar = mean_C f - Dbar_C g`` has covariance ``V = s^2 (I / |C| + Dbar_C N_R^-1
        Dbar_C^T)`` (its own noise and the fit's, extrapolated to it); C is off the plane when
        ``z = sqrt(rbar^T V^-1 rbar) >= plane_z``, at least 2/3 of its members' residuals
        point rbar's way (one surface displaced, not noise), and the part that leaves, its
        members displaced along rbar by at least half |rbar| (a disk about an obstacle's edge
        holds a few ground members too), has ``min_features`` members or more whose mean
        displacement clears step 3c's link tolerance (``split_min_px`` over the window plus
        ``split_rel`` of C's mean flow). The rest needs 8 members and more than C. Of a track's
        candidates, the most significant (largest z).

        Args: o (S,) track index per judged row, rows (S,) those rows into the live features,
        b (S,3) their unit bearings in C, e1, e2 (T,3) the tangent basis at each track's
        representative bearing, xy (S,2) window flows in that basis (rad/s), dt (S,) each row's
        window (s), T tracks, rad_px radians per pixel. Returns {track index: rows of the part}."""
        out: dict[int, np.ndarray] = {}
        cnt = np.bincount(o, minlength=T)
        # all eligible tracks at once (rows come sorted by track: blocks); a candidate disk and
        # its rest lie in one track
        idx = ((cnt[o] >= max(self.plane_min, 12)) & due[o]).nonzero()[0]
        if not len(idx):
            return out
        os_, bt, F, dts = o[idx], b.take(idx, 0), xy.take(idx, 0), dt[idx]
        S = len(idx)
        # D_i (2,8): the tangent components (e1, e2 at rep) of P_b B_k b, P_b = I - b b^T
        u = _einsum("kij,nj->nki", _TRACELESS, bt)  # (S,8,3) B_k b
        u = u - _einsum("nki,ni->nk", u, bt)[:, :, None] * bt[:, None, :]
        e1o, e2o = e1.take(os_, 0), e2.take(os_, 0)
        D = np.stack([_einsum("nki,ni->nk", u, e1o), _einsum("nki,ni->nk", u, e2o)], 1)
        M = ((bt @ bt.T) > np.cos(self.link_rad)) & (os_[:, None] == os_[None, :])  # disks (S,S)
        Mf = M.astype(float)
        nC = Mf.sum(1)
        DD = _einsum("nai,naj->nij", D, D).reshape(S, 64)
        DF = _einsum("nai,na->ni", D, F)  # (S,8)
        FF = _einsum("ij,ij->i", F, F)
        starts = np.concatenate(([True], os_[1:] != os_[:-1])).nonzero()[0]
        blk = np.arange(len(starts)).repeat(np.diff(np.append(starts, S)))  # block of each row
        nR = cnt[os_] - nC
        k = ((nC >= self.min_features) & (nR >= 8) & (nR > nC)).nonzero()[0]
        if not len(k):
            return out
        kb = blk[k]
        NR = (np.add.reduceat(DD, starts, 0)[kb] - Mf[k] @ DD).reshape(-1, 8, 8)
        BR = np.add.reduceat(DF, starts, 0)[kb] - Mf[k] @ DF  # (K,8)
        wc, NRi = _well_conditioned(NR)
        if not wc.any():
            return out
        k, kb, NR, BR = k[wc], kb[wc], NR[wc], BR[wc]
        Mk = Mf[k]  # (K,S)
        NRi = NRi[wc] if NRi is not None else np.linalg.inv(NR)
        g = _einsum("kij,kj->ki", NRi, BR)  # (K,8) g_R = N_R^-1 B_R
        sse = (np.add.reduceat(FF, starts)[kb] - Mk @ FF) - _einsum("ki,ki->k", g, BR)
        s2 = np.maximum(sse, 0.0) / (2.0 * nR[k] - 8.0)
        mC = Mk / nC[k][:, None]
        Dbar = (mC @ D.reshape(S, 16)).reshape(-1, 2, 8)  # (K,2,8)
        fC = mC @ F
        rbar = fC - _einsum("kai,ki->ka", Dbar, g)  # (K,2)
        V = _einsum("kai,kij,kbj->kab", Dbar, NRi, Dbar) + np.eye(2)[None] / nC[k][:, None, None]
        V = V * s2[:, None, None]
        det = V[:, 0, 0] * V[:, 1, 1] - V[:, 0, 1] ** 2
        # z^2 = rbar^T V^-1 rbar (chi2 with 2 degrees of freedom for a part on the plane)
        x0, x1 = rbar[:, 0], rbar[:, 1]
        z2 = V[:, 1, 1] * x0**2 - 2 * V[:, 0, 1] * x0 * x1 + V[:, 0, 0] * x1**2
        z = np.sqrt(np.maximum(z2, 0.0) / np.maximum(det, 1e-300))
        rn = np.hypot(x0, x1)
        # step 3c's link tolerance: split_min_px over the window and split_rel of the flow
        floor = self.split_min_px * rad_px / np.maximum(mC @ dts, 1e-9)
        floor = floor + self.split_rel * np.hypot(fC[:, 0], fC[:, 1])
        # the disks' members' residuals against the rest's fit along rbar's direction (rad/s),
        # over the (candidate, member) pairs, candidate major, members in row order
        K = len(k)
        pk, pn = np.nonzero(M[k])
        rm = F[pn] - _einsum("nai,ni->na", D[pn], g[pk])
        proj = _einsum("na,na->n", rm, rbar[pk]) / np.maximum(rn, 1e-30)[pk]
        way = np.bincount(pk, proj > 0, K) * 3 >= 2 * nC[k]
        # the part: the disk's members displaced at least half as far as its mean (a disk
        # about an obstacle's edge holds a few ground members too); their mean clears the floor
        inp = proj >= 0.5 * rn[pk]
        n_in = np.bincount(pk, inp, K)
        mean_in = np.bincount(pk, proj * inp, K) / np.maximum(n_in, 1)
        # and it stands out of the rest's own scatter about its plane (rbar >= plane_ratio s): a
        # part of one curved surface is off the plane by about as much as the rest is
        good = (z >= self.plane_z) & way & (n_in >= self.min_features) & (mean_in >= floor)
        good = (good & (rn >= self.plane_ratio * np.sqrt(s2))).nonzero()[0]
        if not len(good):
            return out
        # per track its most significant candidate (ties: the first)
        order = good[np.lexsort((good, -z[good], kb[good]))]
        first = order[np.concatenate(([True], kb[order][1:] != kb[order][:-1]))]
        for bi in first.tolist():
            out[int(os_[k[bi]])] = rows[idx[pn[(pk == bi) & inp]]]
        return out

    def _revive(
        self,
        b: np.ndarray,
        out_rows: list[np.ndarray],
        out_tgt: list[tuple[int, int]],
        owner: np.ndarray,
        rep: np.ndarray,
        tracks: list[ObstacleTrack],
        taken: np.ndarray,
        flow: np.ndarray,
        fvalid: np.ndarray,
        tflow: np.ndarray,
        R1: np.ndarray | None,
        dt_s: float,
    ) -> None:
        """Parts split off tracks (rows ``out_rows`` into the live features, bearings b (N,3) in C)
        revive a memberless track predicted within ``max_radius`` of their mean bearing whose flow
        agrees with theirs (closest first, each at most once): ``out_tgt[i]`` becomes (source,
        revived index); the others keep -1 (a new track). Arguments otherwise as in ``_split``."""
        if not out_rows:
            return
        T = len(tracks)
        cnt_all = np.bincount(owner[owner >= 0], minlength=T)[:T]
        need = self._need_t
        hits = np.array([tr.hits for tr in tracks])
        cand = ((cnt_all < need) & (taken[:T] < 0) & (hits > 0)).nonzero()[0]
        if not len(cand):
            return
        cos_r = np.cos(self.max_radius_rad)
        used: set[int] = set()
        pred = rep[cand] @ R1.T if R1 is not None else rep[cand]  # b <- R_C_Cprev b + flow dt
        pred = _normalise(pred + tflow[cand] * dt_s) if self.coast_predict else pred
        for i, mv in enumerate(out_rows):
            c_mv = _normalise(b[mv].mean(0))
            fv = mv[fvalid[mv]]
            if not len(fv):
                continue
            f_mv = flow[fv].mean(0)
            agree = self._agree(f_mv[None], np.linalg.norm(f_mv)[None], tflow[cand])
            cc = np.where(agree, pred @ c_mv, -2.0)
            for j in (-cc).argsort():  # the closest unused one within max_radius
                if cc[j] <= cos_r:
                    break
                if int(cand[j]) not in used:
                    used.add(int(cand[j]))
                    out_tgt[i] = (out_tgt[i][0], int(cand[j]))
                    break

    def _remember_rotation(self, R1: np.ndarray | None) -> None:
        """Keep this frame's R_C_Cprev[1] (3,3) (the rotation from the previous frame's camera
        frame into this one's) for step 3c's window and the flow's (``_window_rotations``); a
        frame without it breaks the chain."""
        self._R1_chain = []
        if R1 is None:
            self._R1_hist.clear()
        else:
            self._R1_hist.appendleft(np.asarray(R1, float))

    def _window_rotations(self, R: dict[int, np.ndarray] | None, frames: int) -> dict[int, np.ndarray]:
        """{k: R_C_Cprev[k]} (3,3) for k = 1..frames as far as known: the given ones (the front
        end's, a few frames back), and beyond them the product of the remembered frame-to-frame
        rotations, ``R_C(t)_C(t-k) = R_C(t)_C(t-1) R_C(t-1)_C(t-2) ... R_C(t-k+1)_C(t-k)``.
        Used by step 3c and the flow (``_flows``: at 100 fps its 17 frames reach past the front
        end's): a window sample older than the rotation known is not derotated by the identity (it
        would read the camera's turn as the member's motion)."""
        if not R or not self._R1_hist:
            return {}
        out = {k: v for k, v in R.items() if 0 < k <= frames}
        n = min(frames, len(self._R1_hist))
        chain = self._R1_chain  # (this frame's products so far: the same numbers, each made once)
        if len(chain) < n:
            acc = chain[-1] if chain else np.eye(3)
            for R1 in itertools.islice(self._R1_hist, len(chain), n):
                acc = acc @ R1
                chain.append(acc)
        for k in range(1, n + 1):
            out.setdefault(k, chain[k - 1])
        return out

    @staticmethod
    def _group_lower_median(keys: np.ndarray, vals: np.ndarray, T: int) -> np.ndarray:
        """Per key 0..T-1 the lower median of ``vals`` (K,) with that key (K,) int; NaN for none."""
        out = np.full(T, np.nan)
        if not len(keys):
            return out
        order = np.lexsort((vals, keys))
        cnt = np.bincount(keys, minlength=T)
        start = np.concatenate([[0], cnt.cumsum()[:-1]])
        has = (cnt > 0).nonzero()[0]
        out[has] = vals[order][start[has] + (cnt[has] - 1) // 2]
        return out

    def _agree(
        self, f: np.ndarray, fn: np.ndarray, g: np.ndarray, loose: float = 1.0, gn: np.ndarray | None = None
    ) -> np.ndarray:
        """Flows f (..., 3) (norms fn (...)) and g (..., 3) (norms gn (...), computed when None)
        agree (rad/s): ``|f - g| < loose (flow_abs + flow_rel max(|f|, |g|))``."""
        gn = _norm_rows(g) if gn is None else gn
        return _norm_rows(f - g) < loose * (self.flow_abs + self.flow_rel * np.maximum(fn, gn))

    @staticmethod
    def _owners(ids: np.ndarray, tracks: list[ObstacleTrack]) -> np.ndarray:
        """owner[i]: index (into ``tracks``) of the track live feature i belonged to, or -1."""
        n, T = len(ids), len(tracks)
        owner = np.full(n, -1, np.intp)
        if not (T and n):
            return owner
        lens = [len(t.members) for t in tracks]
        if not sum(lens):
            return owner
        order = ids.argsort(kind="stable")
        sids = ids[order]
        mem = np.concatenate([t.members for t in tracks])
        mem_t = np.arange(T).repeat(lens)
        k = np.minimum(sids.searchsorted(mem), n - 1)
        ok = sids[k] == mem
        owner[order[k[ok]]] = mem_t[ok]
        return owner

    @staticmethod
    def _mean_flow(o: np.ndarray, f: np.ndarray, old: np.ndarray, T: int) -> tuple[np.ndarray, np.ndarray]:
        """Mean flow per track (T,3) of the members with a flow (track index o (S,), flow f (S,3))
        where >= 3 members have one (else ``old`` (T,3)), and that mask (T,): as ``_track_flow``."""
        cnt = np.bincount(o, minlength=T)
        sums = _bincount3(o, f, T) if T else np.zeros((0, 3))
        has = cnt >= 3
        return np.where(has[:, None], sums / np.maximum(cnt, 1)[:, None], old), has

    @staticmethod
    def _track_flow(
        owner: np.ndarray, flow: np.ndarray, fvalid: np.ndarray, old: np.ndarray, T: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Mean member flow per track (T,3) where >= 3 members have a flow (else ``old``), and that mask."""
        sel = ((owner >= 0) & fvalid).nonzero()[0]
        return ObstacleGrouper._mean_flow(owner[sel], flow.take(sel, 0), old, T)

    def _flows(
        self, ft: FeatureTracker, t_s: float, R: dict[int, np.ndarray] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per feature: flow (N,3) in rad/s = (b_now - R b_then) / dt over up to flow_frames frames,
        and whether it has one (N,)."""
        n = len(ft.ids)
        if not n:
            return np.zeros((0, 3)), np.zeros(0, bool)
        b_then, t_then, valid = ft.bearing_ago(self.flow_frames)
        R = self._window_rotations(R, self.flow_frames)  # (the front end's reach fewer frames back)
        if R:
            # b_then <- R_C_Cprev[k] b_then, k = frames back of each feature's sample (identity if absent)
            n_back = np.minimum(ft._h_n[ft.slot] - 1, self.flow_frames)
            Rs = _EYE3.repeat(self.flow_frames + 1, 0)
            for k, Rk in R.items():
                if 0 < k <= self.flow_frames:
                    Rs[k] = Rk
            b_then = _einsum("nij,nj->ni", Rs.take(np.maximum(n_back, 0), 0), b_then)
        dt = t_s - t_then
        valid &= dt > 0
        flow = (ft.b_C - b_then) / np.where(valid, dt, 1.0)[:, None]
        flow[~valid] = 0.0
        return flow, valid

    def _pieces(
        self,
        free: np.ndarray,
        b: np.ndarray,
        flow: np.ndarray,
        fvalid: np.ndarray,
        age: np.ndarray,
        cos_link: float,
        f2_all: np.ndarray,
    ) -> tuple[list[np.ndarray], np.ndarray]:
        """Connected components of the free features (rows (m,) into the live features; graph:
        within link_rad and flows agreeing), cut to max_radius_rad pieces: the pieces (rows) that
        may start or revive a track, and per piece whether it is a small isolated one: fewer than
        min_features features, at least min_features_isolated, all isolated_min_age frames old,
        and no other live feature within link_rad of any of them unless it has a flow (fvalid
        (N,)) that disagrees with theirs (a small obstacle moving against the background; a
        component set apart by its motion only needs two features at least). f2_all (N,): the
        squared norms of ``flow`` (rad^2/s^2)."""
        m = len(free)
        if m == 0:
            return [], np.zeros(0, bool)
        bf, ff = b.take(free, 0), flow.take(free, 0)
        f2 = f2_all[free]
        fn = np.sqrt(f2)
        # |f_i - f_j|^2 = |f_i|^2 + |f_j|^2 - 2 f_i.f_j;  agree: |f_i - f_j| < abs + rel max(|f_i|, |f_j|)
        d2 = f2[:, None] + f2[None, :] - 2.0 * (ff @ ff.T)
        thr = self.flow_abs + self.flow_rel * np.maximum(fn[:, None], fn[None, :])
        adj = ((bf @ bf.T) > cos_link) & (d2 < thr * thr)
        # connected components by min-label propagation: each feature takes the smallest label
        # among its neighbours until nothing changes (at most the graph's diameter rounds)
        labels = np.arange(m)
        big = m + 1
        for _ in range(m):
            nxt = np.minimum(np.where(adj, labels[None, :], big).min(axis=1), labels)
            nxt = nxt[nxt]  # pointer jumping speeds it up
            if np.array_equal(nxt, labels):
                break
            labels = nxt
        size = np.bincount(labels, minlength=m)
        sz = size[labels]
        out: list[np.ndarray] = []
        small: list[bool] = []
        # small components: judged as a whole (isolated, old enough)
        cand = ((sz < self.min_features) & (sz >= self.min_features_isolated)).nonzero()[0]
        if len(cand):
            ok_f = age[free] >= self.isolated_min_age
            # isolated: a member's live neighbours (itself included) are all members, or move
            # unlike it (a small obstacle crossing the background: its motion sets it apart)
            ci, nj = np.nonzero(bf.take(cand, 0) @ b.T > cos_link)  # (candidate, live feature) pairs near
            fc = ff.take(cand, 0)
            g2 = f2_all[nj]
            dd = (f2[cand][ci] + g2) - 2.0 * (fc @ flow.T)[ci, nj]
            th = self.flow_abs + self.flow_rel * np.maximum(fn[cand][ci], np.sqrt(g2))
            unlike = fvalid[nj] & (dd > 4.0 * th * th)  # twice the grouping tolerance
            n_near = np.bincount(ci[~unlike], minlength=len(cand))
            n_any = np.bincount(ci, minlength=len(cand))
            # set apart by motion only (live neighbours that move unlike it): two features at least
            szc = sz[cand]
            ok_f[cand] &= (n_near <= szc) & ((n_any <= szc) | (szc >= 2))
            bad = np.bincount(labels[cand[~ok_f[cand]]], minlength=m) > 0
            lab_c = labels[cand]
            keep = ~bad[lab_c]
            if keep.any():
                # the kept components' features, grouped by label (ascending), in row order
                rows_k, lab_k = cand[keep], lab_c[keep]
                o_k = lab_k.argsort(kind="stable")
                rows_k, lab_k = rows_k[o_k], lab_k[o_k]
                cut = (lab_k[1:] != lab_k[:-1]).nonzero()[0] + 1
                out.extend(np.split(free[rows_k], cut))
                small.extend([True] * (len(cut) + 1))
        # components of min_features or more: cut to max_radius pieces
        cos_r = np.cos(self.max_radius_rad)
        by_label = labels.argsort(kind="stable")  # rows grouped by label, in row order within
        first = size.cumsum() - size
        for r in (size >= self.min_features).nonzero()[0].tolist():
            comp = by_label[first[r] : first[r] + size[r]]  # (= (labels == r).nonzero()[0])
            while len(comp):
                bc = bf.take(comp, 0)
                cen = _normalise(np.add.reduce(bc, 0) / len(comp))  # (bc.mean(0)'s own sums)
                cc = bc @ cen
                if (cc > cos_r).all():
                    out.append(free[comp])
                    small.append(False)
                    break
                # cut: a piece around the member farthest from the centre, so the rest stays compact
                far = comp[np.argmin(cc)]
                piece = comp[bc @ bf[far] > cos_r]
                c2 = _normalise(np.add.reduce(bf.take(piece, 0), 0) / len(piece))
                inside = bc @ c2 > cos_r
                piece = comp[inside] if inside.any() else np.array([far])
                if len(piece) >= self.min_features:
                    out.append(free[piece])
                    small.append(False)
                comp = comp[~inside] if inside.any() else comp[comp != far]
        return out, np.array(small, bool)
    def _embedded(
        self,
        rep: np.ndarray,
        reach: np.ndarray,
        tflow: np.ndarray,
        tidx: np.ndarray,
        b: np.ndarray,
        flow: np.ndarray,
        fvalid: np.ndarray,
        owner: np.ndarray,
        model,
    ) -> np.ndarray:
        """Per track (rep (A,3) unit bearings in C, reach (A,) rad = farthest member's angle,
        tflow (A,3) rad/s, tidx (A,) its index in ``owner``): True when it lies on extended
        texture: the non-member features within ``reach + link_rad`` surround it (they lie in at
        least ``extended_sectors`` of the 8 sectors around it, sectors whose outer edge is outside
        the lens (``model.max_angle_rad`` off +z) not held against it, and in at least 4), and the
        flow field they span, fitted as an affine function of the position and taken at the
        track, agrees with the track's flow (no motion boundary around it)."""
        A = len(rep)
        out = np.zeros(A, bool)
        cand = fvalid.nonzero()[0]
        if not len(cand):
            return out
        outer = np.minimum(reach + self.link_rad, np.pi)
        ti, j = np.nonzero(rep @ b.take(cand, 0).T > np.cos(outer)[:, None])
        i = cand[j]
        ok = owner[i] != tidx[ti]
        ti, i = ti[ok], i[ok]
        # tangent basis (e1, e2) at each rep; position (x, y) and sector of each neighbour
        e1, e2 = _tangent_basis(rep)
        d = b.take(i, 0) - rep.take(ti, 0)
        x = _einsum("ij,ij->i", d, e1.take(ti, 0))
        y = _einsum("ij,ij->i", d, e2.take(ti, 0))
        sec = np.floor((np.arctan2(y, x) + np.pi) * (4.0 / np.pi)).astype(np.intp) % 8
        occ = np.zeros((A, 8), bool)
        occ[ti, sec] = True
        # a sector is visible when the point at `outer` in its middle direction is inside the lens
        z = np.cos(outer)[:, None] * rep[:, 2:3] + np.sin(outer)[:, None] * (
            _SECTOR_COS[None, :] * e1[:, 2:3] + _SECTOR_SIN[None, :] * e2[:, 2:3]
        )
        vis = z > np.cos(model.max_angle_rad)
        surrounded = ((occ & vis).sum(1) >= 4) & ((vis & ~occ).sum(1) <= 8 - self.extended_sectors)
        if not surrounded.any():
            return out
        keep = surrounded[ti]  # (the fit is needed for the surrounded tracks only)
        ti, i, x, y = ti[keep], i[keep], x[keep], y[keep]
        # affine flow field of the neighbours: f(x, y) = c0 + c1 x + c2 y per tangent component,
        # least squares (normal equations, a small ridge on the slopes); at the track: c0
        s = self.link_rad
        xs, ys = x / s, y / s  # slopes per link_rad
        fi = flow.take(i, 0)
        fx, fy = _einsum("ij,ij->i", fi, e1.take(ti, 0)), _einsum("ij,ij->i", fi, e2.take(ti, 0))
        # N = sum r r^T, rhs = sum r f^T with r = (1, x, y): per track sums of these 12 products
        # by one bincount over (track, product) (a ufunc.at is ten times slower)
        w = np.stack(
            [np.ones_like(x), xs, ys, xs * xs, xs * ys, ys * ys, fx, fy, xs * fx, xs * fy, ys * fx, ys * fy],
            1,
        )
        sums = np.bincount((ti[:, None] * 12 + _ARANGE12).ravel(), w.ravel(), A * 12).reshape(A, 12)
        N = sums[:, _N_OF_SUMS].reshape(A, 3, 3)
        rhs = sums[:, 6:].reshape(A, 3, 2)
        N += _RIDGE * np.maximum(N[:, 0, 0], 1.0)[:, None, None]
        c0 = np.linalg.solve(N[surrounded], rhs[surrounded])[:, 0, :]  # (S, 2)
        tf = np.stack([_einsum("ij,ij->i", tflow, e1), _einsum("ij,ij->i", tflow, e2)], 1)[surrounded]
        gap = _norm_rows(c0 - tf)
        thr = self.flow_abs + self.flow_rel * np.maximum(_norm_rows(c0), _norm_rows(tf))
        out[surrounded] = gap < thr
        return out


class BoxTracker:
    """Tracks box detections (navlights, torch models, plug-ins) of one camera as obstacles.

    A box's representative bearing is its centre's bearing; boxes are matched to tracks of the same
    label greedily by angle, within ``gate_rad`` plus the box's own angular half-size. Life cycle as
    ObstacleGrouper's. sigma_rad = half the box's angular diagonal / 3, floored at ``sigma_floor_rad``.

    One obstacle, two tracks (a composite detector such as ``orb+navlights``: a drone textured enough
    for ORB, a textured obstacle with a light-like spot): ``update`` is given the camera's feature
    tracks seen this frame (``others``). A box track and a feature track are LINKED when the feature
    track lies on the box (its representative bearing and at least ``link_share`` (3/4) of its members,
    and at least ``min(link_min_members, its members)``, within the box's angular half-diagonal plus
    ``link_margin_px`` of the box centre) AND its members nearest the box moved with the box centre
    over the last ``link_frames`` frames: their mean displacement and the box centre's, raw (the camera's own
    rotation moves both alike, so it cancels in the difference), differ by at most ``link_tol_px``
    (in the lens's mean rad/px). A link holds while the pair stays so placed (half of the members on
    the box then suffice: features join and leave). A new link needs most members on the box, not
    half: a feature track with half its members on a pole beside a drone moved with the drone for a
    few frames and was linked, and the drone's id then went with it when the two parted (tuned
    stereo_flying: links formed at 7 of 10 and 4 of 8 members; the drones' own links at 3 of 4 to
    all). A linked box track is
    not reported (it is tracked on, and comes back under its own id if the feature track goes); the
    feature track is reported with the box's attributes added and ``box_label`` (e.g. ``drone``),
    under the box's id when the box is the older track and no other camera sees it
    (``FrontEnd._box_keeps_id``: the drone keeps the id it was first reported under).
    The feature track is the one kept: its member features give it ranges and stereo association,
    and they lie on the box, so its bearing does too.

    Not linked, so reported twice: a box well inside a larger feature track, off its representative
    bearing (a light near the edge of a big textured obstacle). A rule "members all around the box"
    was tried and dropped: on tuned scene moving_headon it linked the approaching drone, at 14 m
    near the focus of expansion where everything hardly moves, to a background track whose features
    surround it (one on the drone, ten off it) and hid the drone for 7 frames; so did "the bearing
    and two members in the box" (that track's bearing was 10 px from the box centre, inside its
    12 px radius). Hiding a drone is worse than a second report of an obstacle.

    ``link_older_only`` (opt-in, default False): a box track is linked only to a feature track made before
    it (a smaller id: box and feature tracks draw ids from the front end's one counter). A drone found
    first by its lights then keeps its own report and id beside the feature track ORB finds on it later;
    by default the link hides the box and the feature track carries on under the box's id (above), but
    where another camera sees the box too the drone's reported id changes from the box's to the feature
    track's (an id switch). The drone id switches of the tuned scenes were such handovers, not links to
    the wrong track (session 9: moving_crossing, wide_angle_beyond90, noisy_1080p).

    Durations in seconds, applied as frame counts at the frame rate seen (``FrameClock``, as
    ObstacleGrouper's): ``confirm_s`` (0.1: 3 frames at 30 fps), ``max_missed_s`` (1/3: 10 frames),
    ``link_s`` (0.1: 3 frames; ``link_tol_px`` is the displacement allowed over it); attributes
    confirm_frames, max_missed, link_frames hold the counts in effect.
    """

    # its frame counts that are durations now (as ObstacleGrouper.RENAMED)
    RENAMED: ClassVar[dict[str, tuple[str, str]]] = {
        "confirm_frames": ("confirm_s", "3 frames at 30 fps = 0.1 s"),
        "max_missed": ("max_missed_s", "10 frames at 30 fps = 1/3 s"),
        "link_frames": ("link_s", "3 frames at 30 fps = 0.1 s"),
    }

    def __init__(
        self,
        ids: Iterator[int],
        gate_rad: float = np.radians(3.0),
        confirm_s: float = 0.1,
        max_missed_s: float = 1 / 3,
        sigma_floor_rad: float = np.radians(0.2),
        link_margin_px: float = 3.0,
        link_min_members: int = 2,
        link_s: float = 0.1,
        link_tol_px: float = 2.0,
        link_share: float = 0.75,
        link_older_only: bool = False,
        **old: Any,
    ) -> None:
        self.durations = check_durations(
            "BoxTracker", BoxTracker.RENAMED, old,
            {"confirm_s": confirm_s, "max_missed_s": max_missed_s, "link_s": link_s},
        )
        v = link_min_members
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ConfigError(f"BoxTracker: link_min_members expected an integer >= 1, got {v!r}")
        for nm, v in (("gate_rad", gate_rad), ("sigma_floor_rad", sigma_floor_rad),
                      ("link_margin_px", link_margin_px), ("link_tol_px", link_tol_px)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)) or not v >= 0:
                raise ConfigError(f"BoxTracker: {nm} expected a number >= 0, got {v!r}")
        if isinstance(link_share, bool) or not isinstance(link_share, (int, float, np.number)) or not (
            0.5 <= link_share <= 1
        ):
            raise ConfigError(f"BoxTracker: link_share expected a number in [0.5, 1], got {link_share!r}")
        self._ids = ids
        self.gate_rad = float(gate_rad)
        self.sigma_floor_rad = float(sigma_floor_rad)
        self.link_margin_px = float(link_margin_px)
        self.link_min_members = int(link_min_members)
        self.clock = FrameClock()
        self._count()
        self.link_tol_px = float(link_tol_px)
        self.link_share = float(link_share)
        if not isinstance(link_older_only, bool):
            raise ConfigError(f"BoxTracker: link_older_only expected true or false, got {link_older_only!r}")
        self.link_older_only = link_older_only
        self.tracks: dict[int, ObstacleTrack] = {}
        self.links: dict[int, int] = {}  # box track id -> linked feature track id
        self._half: dict[int, float] = {}  # box track id -> its box's angular half-diagonal (rad)
        # (box id, feature track id) -> recent (update count, near members' mean bearing, box bearing)
        self._hist: dict[tuple[int, int], deque] = {}
        self._decorated: dict[int, tuple[ObstacleTrack, tuple[str, ...]]] = {}  # keys added to others
        # box track id -> {feature track id: updates in a row it lay on the box as a new link needs
        # (bearing and link_share of its members; half for the held link), at most link_frames + 1},
        # as of the box's last update seen; kept while the box coasts (FrontEnd._box_hands_id)
        self.placed: dict[int, dict[int, int]] = {}
        self._n = 0

    def _count(self) -> None:
        """This frame's frame counts of the durations at the rate seen (``FrameClock.frames``)."""
        d, f = self.durations, self.clock.frames
        self.confirm_frames = f(d["confirm_s"])
        self.max_missed = f(d["max_missed_s"], 0)
        self.link_frames = f(d["link_s"])

    def update(
        self, camera, det, others=(), *, t_s: float
    ) -> tuple[list[ObstacleTrack], list[ObstacleTrack]]:
        """Match this frame's boxes (``det``: Detections) of ``camera`` (an ``estimators.rig.Camera``).

        Args:
            others: the camera's feature tracks seen this frame (ObstacleTrack with ``member_b_C``),
                for the links described in the class docstring; empty: no links.
            t_s: frame time (s).
        Returns:
            (box tracks seen this frame and not linked to a feature track, tracks lost this frame).
        """
        model = camera.model
        self._n += 1
        self.clock.tick(t_s)
        self._count()
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
                self._half[tr.id] = float(half[i])
                if tr.status == "tentative" and tr.hits >= self.confirm_frames:
                    tr.status = "confirmed"
                seen.append(tr)
        lost = []
        for tid in list(self.tracks):
            tr = self.tracks[tid]
            if not tr.seen:
                tr.unseen()
                tr.missed += 1
                if tr.missed > self.max_missed:
                    tr.status = "lost"
                    lost.append(tr)
                    del self.tracks[tid]
        hidden = self._link(model, seen, others)
        return [tr for tr in seen if tr.id not in hidden], lost

    def _link(self, model, seen: list[ObstacleTrack], others) -> set[int]:
        """Update the box <-> feature track links (class docstring); decorate the linked feature
        tracks; return the ids of the box tracks not to report."""
        rad_px = model.rad_per_px
        feats = [t for t in others if len(t.member_b_C) == len(t.members) and len(t.members)]
        by_id = {t.id: t for t in feats}
        links: dict[int, int] = {}
        now: set[tuple[int, int]] = set()
        if seen and feats:
            # all members at once: cosines against each box, compared with cos(radius) (no arccos)
            n_mem = np.array([len(f.members) for f in feats])
            start = np.concatenate([[0], n_mem.cumsum()])
            owner = np.arange(len(feats)).repeat(n_mem)
            mem_b = np.concatenate([f.member_b_C for f in feats])  # (M, 3)
            rep_b = np.array([f.b_C for f in feats])  # (T, 3)
            n_low = np.minimum(self.link_min_members, n_mem)
            n_hold = np.maximum(n_low, (n_mem + 1) // 2)  # a held link: half its members on the box
            n_new = np.maximum(n_low, np.ceil(self.link_share * n_mem - 1e-9))  # a new one: link_share
        for b in seen if feats else ():
            radius = self._half.get(b.id, 0.0) + self.link_margin_px * rad_px
            cos_r = np.cos(radius)
            cos_c = rep_b @ b.b_C
            cand = (cos_c >= cos_r).nonzero()[0]  # its bearing in the box ...
            if self.link_older_only:  # ... made before the box (ids come from one counter; a held
                # link was made under this rule, so its feature track is older too)
                cand = cand[[feats[ti].id < b.id for ti in cand]]
            if not len(cand):
                continue
            cos_m = mem_b @ b.b_C
            n_in = np.bincount(owner[cos_m >= cos_r], minlength=len(feats))
            best: tuple[float, int] | None = None  # (-cos to the feature track's bearing, its id)
            held_id = self.links.get(b.id)
            n_min = np.array([n_hold[ti] if feats[ti].id == held_id else n_new[ti] for ti in cand])
            for ti in cand[n_in[cand] >= n_min]:  # ... and most of its members too
                f = feats[ti]
                seg = cos_m[start[ti]:start[ti + 1]]
                k = (-seg).argsort(kind="stable")[:8]  # the members nearest the box: does it move with them
                key = (b.id, f.id)
                h = self._hist.setdefault(key, deque())
                near = dict(zip(f.members[k].tolist(), f.member_b_C[k], strict=True))
                h.append((self._n, near, b.b_C.copy()))
                while len(h) > self.link_frames + 1:  # (the count follows the rate seen)
                    h.popleft()
                now.add(key)
                held = f.id == held_id  # a link holds while the pair stays so placed
                if (held or self._moves_with(h, rad_px)) and (best is None or -cos_c[ti] < best[0]):
                    best = (-float(cos_c[ti]), f.id)
            if best is not None:
                links[b.id] = best[1]
        for key in [k for k in self._hist if k not in now]:
            del self._hist[key]  # the pair was not seen so placed this update: its history restarts
        for b in seen:
            self.placed[b.id] = {}
        for (bid, fid), h in self._hist.items():
            self.placed[bid][fid] = len(h)
        # one box per feature track (the lowest box id kept)
        taken: dict[int, int] = {}
        for bid, fid in sorted(links.items()):
            taken.setdefault(fid, bid)
        self.links = {bid: fid for fid, bid in taken.items()}
        for fid, (tr, keys) in list(self._decorated.items()):  # undo last update's additions
            for key in keys:
                tr.attributes.pop(key, None)
            del self._decorated[fid]
        for bid, fid in self.links.items():
            b, f = self.tracks[bid], by_id[fid]
            add = {**b.attributes, "box_label": b.label}
            add = {key: v for key, v in add.items() if key not in f.attributes}
            f.attributes.update(add)
            self._decorated[fid] = (f, tuple(add))
        for tid in [t for t in self._half if t not in self.tracks]:
            del self._half[tid]
        for tid in [t for t in self.placed if t not in self.tracks]:
            del self.placed[tid]
        return set(self.links)

    def _moves_with(self, h: deque, rad_px: float) -> bool:
        """Whether a (box, feature track) pair's history ``h`` covers ``link_frames`` consecutive
        updates and the feature track's members nearest the box (those in both the first and the
        last entry) moved on average as the box centre did over them."""
        if len(h) < self.link_frames + 1 or h[-1][0] - h[0][0] != self.link_frames:
            return False
        common = [i for i in h[-1][1] if i in h[0][1]]
        if not common:
            return False
        d_f = np.mean([h[-1][1][i] - h[0][1][i] for i in common], axis=0)  # (3,) rad, tangent
        d_b = h[-1][2] - h[0][2]
        return float(np.linalg.norm(d_f - d_b)) <= self.link_tol_px * rad_px

    def coast(self, t_s: float) -> list[ObstacleTrack]:
        """A frame (time t_s, s) without a usable image: every track goes unseen; returns those
        lost now (unseen for more than ``max_missed_s``)."""
        self._n += 1
        self.clock.tick(t_s)
        self._count()
        lost = []
        for tid in list(self.tracks):
            tr = self.tracks[tid]
            tr.seen = False
            tr.missed += 1
            if tr.missed > self.max_missed:
                tr.status = "lost"
                lost.append(tr)
                del self.tracks[tid]
        return lost
