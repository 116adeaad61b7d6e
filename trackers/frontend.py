"""The front end: frames of every camera in, one ObstacleObservation per obstacle track out.

Per camera: a keypoint detector + KLT FeatureTracker + ObstacleGrouper (``orb``, ``kornia``, plug-ins
with keypoints), and/or a BoxTracker for detectors that report boxes (``navlights``, ``torch``).
Several cameras: tracks are linked across cameras by epipolar-constrained descriptor matching
(trackers/association.py) so one obstacle seen by two cameras is one track with two CameraViews.
Feature ids are physical-point ids: a feature of another camera matched (epipolar + descriptor) to a
reference-camera (the rig's first) feature is reported under that feature's id (``link_features``).
"""

from __future__ import annotations

import functools
import inspect
import itertools
import time
from collections import deque
from collections.abc import Mapping
from fractions import Fraction
from typing import Any

import cv2
import numpy as np

from estimators.errors import ConfigError, InputError, did_you_mean, frame_at
from estimators.geometry import _isin, _norm_rows
from estimators.records import CameraView, ObstacleObservation
from estimators.rig import Camera, Rig
from trackers.association import (
    BoxStereo,
    TurnedPair,
    box_pairs,
    boxes_compatible,
    consistent_pairs,
    depth_consistent,
    klt_links,
    match_features,
    pair_turns,
    stereo_klt,
    unheld,
)
from trackers.clock import check_durations, renamed_text
from trackers.detectors import Detector, boxes_unused, make_detector, to_grey
from trackers.features import KLT_WIN_PX, FeatureTracker, klt_window_px, lens_mask
from trackers.grouping import BoxTracker, ObstacleGrouper, ObstacleTrack, _bincount3

STAGES = ("resize", "detect", "track", "group", "associate", "report")
_OPTION_GROUPS = (
    "detector_options",
    "features",
    "grouping",
    "boxes",
    "association",
    "max_width",
    "densify_below",
    "densify_s",
)
_ASSOCIATION_OPTIONS = (
    "every",
    "epipolar_deg",
    "max_hamming",
    "min_votes",
    "klt_link_px",
    "recheck_every",
    "recheck_px",
    "follow_levels",
    "reverse_views",
)
# the option groups built into a class per camera: group -> (class, its parameters the front end sets);
# the class's RENAMED: its old frame-count keys that are durations now
_CLASS_OPTIONS = {
    "features": (FeatureTracker, ("camera", "detector", "ids")),
    "grouping": (ObstacleGrouper, ("ids", "label")),
    "boxes": (BoxTracker, ("ids",)),
}
# the options given as dicts, checked by option_problem; the config's tracker section has one dict
# field for each (pipeline.config.TrackerConfig: a test holds the two equal)
_OPTION_DICTS = ("features", "grouping", "boxes", "association")
_FRONTEND_RENAMED = {"densify_every": ("densify_s", "every 2nd frame at 30 fps = 2/30 s")}
DENSIFY_S = 2 / 30  # the front end's default densify_s: every 2nd frame at 30 fps, the count it was fitted as


MAX_WIDTH_PX = 1280  # the front end's default max_width


def tracked_scale(rig: Rig, max_width: int | None = MAX_WIDTH_PX) -> dict[str, float]:
    """Per camera name, the scale of the images its features are tracked in (1.0: the full frame):
    frames wider than ``max_width`` px are tracked downscaled to that width, the camera model scaled
    alike, so bearings are unchanged but a tracked pixel (the KLT window, a feature's pixel noise)
    spans 1 / scale of the frame's pixels. ``None``: never downscaled.

    Raises ConfigError for a max_width that is not an integer >= 64 px or None.
    """
    if max_width is not None and (not isinstance(max_width, int) or max_width < 64):
        raise ConfigError(f"FrontEnd: max_width expected an integer >= 64 px or None, got {max_width!r}")
    return {
        c.name: (1.0 if max_width is None or c.model.width <= max_width else max_width / c.model.width)
        for c in rig.cameras
    }


def tracked_window(rig: Rig, features: Mapping[str, Any] | None = None) -> dict[str, int]:
    """Per camera name, the side (px of the images its features are tracked in: ``tracked_scale``)
    of the square KLT window its features are tracked by: ``features['win_px']`` (FeatureTracker's
    keyword, default ``KLT_WIN_PX``), the one window setting: the temporal KLT's, the stereo KLT's
    (``stereo_klt`` searching camera a's features in b is given a's tracker's window, for every
    ordered pair of cameras) and the fusion's window angle (``ObstacleFusion(window_px=)``, its
    half-width over the tracked px per rad).

    Raises ConfigError for a win_px that is not an integer >= 3 (``klt_window_px``).
    """
    w = klt_window_px((features or {}).get("win_px", KLT_WIN_PX))
    return {c.name: w for c in rig.cameras}


def accepted_options(group: str) -> list[str]:
    """The option names the front end's ``group`` (features, grouping, boxes, association) accepts:
    the keywords of the class it is built into (``_CLASS_OPTIONS``), or the association's.

    Raises:
        ConfigError: ``group`` is none of them.
    """
    if group == "association":
        return list(_ASSOCIATION_OPTIONS)
    if group not in _CLASS_OPTIONS:
        raise ConfigError(f"FrontEnd: no option group {group!r}; expected one of {', '.join(_OPTION_DICTS)}")
    cls, internal = _CLASS_OPTIONS[group]
    return [
        n for n, p in inspect.signature(cls).parameters.items()
        if p.kind is not p.VAR_KEYWORD and n not in internal
    ]


def option_problem(
    group: str, given: Mapping[str, Any], section: str | None = None
) -> tuple[str, str] | None:
    """The one check of the names of a front-end option group (``_OPTION_DICTS``: features, grouping,
    boxes, association), made by ``FrontEnd`` and, with the config's key and line, when a config
    loads (``pipeline.config.load_config``): the first name in ``given`` that ``group`` does not take,
    and the message, which the caller prefixes with its own name or the config's place: an old frame
    count that is a duration now is "'x' in SECTION (frames) was replaced by 'x_s' ..." (its class's
    ``RENAMED``, ``trackers.clock.renamed_text``); any other name is "unknown key 'x' in SECTION; did
    you mean 'y'? Valid keys: ..." (``did_you_mean``, the config's wording). ``section``: how the
    message names the group (default ``group``). None when every name is taken."""
    accepted = accepted_options(group)
    renamed = _CLASS_OPTIONS[group][0].RENAMED if group in _CLASS_OPTIONS else {}
    where = section or group
    for k in given:
        if k in accepted:
            continue
        if k in renamed:
            return k, renamed_text(renamed, k, f" in {where}")
        return k, f"unknown key '{k}' in {where}" + did_you_mean(str(k), accepted)
    return None


def _bad_options(group: str, e: Exception) -> ConfigError:
    """The error for options of ``group`` whose names its class takes but whose values it refused with a
    TypeError (``e``)."""
    return ConfigError(f"FrontEnd: bad {group} options: {e}")


def check_image(name: str, image: Any, width: int, height: int) -> np.ndarray:
    """Validate one camera's frame against its calibration.

    Args:
        name: camera name (for messages); width, height: the calibration's image size (px).
        image: (H, W) uint8 grey or (H, W, 3) uint8 BGR ((H, W, 1) is taken as grey).
    Returns:
        the image as an ndarray.
    Raises:
        InputError: not an array, empty, wrong dtype, wrong channel count, or a size other than the
            calibration's (the message gives both).
    """
    if not isinstance(image, np.ndarray):
        raise InputError(f"camera {name!r}: expected a numpy image, got {type(image).__name__}")
    if image.size == 0:
        raise InputError(
            f"camera {name!r}: empty frame (shape {image.shape}); expected {height}x{width} pixels"
        )
    if image.dtype != np.uint8:
        raise InputError(f"camera {name!r}: expected a uint8 image, got dtype {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)):
        raise InputError(
            f"camera {name!r}: expected (H, W) grey or (H, W, 3) BGR, got shape {image.shape} "
            f"({image.shape[2] if image.ndim == 3 else image.ndim} channels/dims)"
        )
    if image.shape[:2] != (height, width):
        raise InputError(
            f"camera {name!r}: frame is {image.shape[1]}x{image.shape[0]} px but the calibration is "
            f"{width}x{height}; resize the video or scale the calibration (CameraModel.scaled)"
        )
    return image


def _shrink_box(
    size_wh: tuple[int, int], model, box: tuple[int, int, int, int]
) -> tuple[int, int, int, int, int, int, int, int] | None:
    """Where to shrink only part of a (W, H) = ``size_wh`` frame to ``model``'s (w, h) size.

    ``box`` (x0, y0, x1, y1) px of the small frame is widened to the resize's period: with
    w / W = p / q in lowest terms, a box edge on a multiple of p small pixels is on a multiple of q
    frame pixels, so cv2.resize INTER_AREA of that part of the frame gives the same pixels as the
    whole frame's resize (the same source interval per output pixel).

    Returns:
        (sx0, sy0, sx1, sy1) frame px and (x0, y0, x1, y1) small-frame px of the part, or None when
        the period is long (p > 16) or the part is most of the frame (nothing to save).
    """
    (sw, sh), (dw, dh) = size_wh, (int(model.width), int(model.height))
    fx, fy = Fraction(dw, sw), Fraction(dh, sh)
    px, py = fx.numerator, fy.numerator
    if px > 16 or py > 16:
        return None
    x0, y0 = box[0] // px * px, box[1] // py * py
    x1, y1 = min(dw, -(-box[2] // px) * px), min(dh, -(-box[3] // py) * py)
    if (x1 - x0) * (y1 - y0) > 0.8 * dw * dh:
        return None
    # small px x -> frame px x q / p (exact: x is a multiple of p, and dw q / p = sw)
    qx, qy = fx.denominator, fy.denominator
    return (x0 * qx // px, y0 * qy // py, x1 * qx // px, y1 * qy // py, x0, y0, x1, y1)


def _sample_index(mask: np.ndarray) -> np.ndarray:
    """(K,) flat indices into an (H, W) frame of the pixels of every 8th row and column where
    ``mask`` (H, W) is > 0, row by row: ``np.take(grey, idx)`` equals
    ``grey[::8, ::8][mask[::8, ::8] > 0]``."""
    w = mask.shape[1]
    ys, xs = np.nonzero(mask[::8, ::8] > 0)
    return (ys * 8 * w + xs * 8).astype(np.intp)


def _shallow_copy(obj):
    """``copy.copy`` of a plain (dict-based) object such as ObstacleTrack: a new instance sharing
    the attribute values, without the reduce protocol's overhead."""
    new = object.__new__(type(obj))
    new.__dict__.update(obj.__dict__)
    return new


def _physical_ids(pid: dict[int, int], ids: np.ndarray) -> np.ndarray:
    """Feature ids (N,) of one camera under their physical-point ids: through ``pid`` (that
    camera's feature id -> the reference camera's id of the same point, ``FrontEnd._pid``), an id
    without an entry unchanged."""
    il = ids.tolist()
    return np.fromiter(map(pid.get, il, il), np.int64, len(il))


def _count_pairs(ids_a: np.ndarray, ids_b: np.ndarray) -> dict[tuple[int, int], int]:
    """Votes per (a's track id, b's track id) pair: {pair: count}, pairs in the order of their
    first vote (the order ``_associate``'s best-partner choice breaks ties by).

    Args:
        ids_a, ids_b: (K,) int track ids (>= 0, < 2^31), row-paired, one vote per row.
    """
    ia = np.asarray(ids_a, np.int64)
    if not len(ia):
        return {}
    key = (ia << 32) | np.asarray(ids_b, np.int64)
    uk, first, cnt = np.unique(key, return_index=True, return_counts=True)
    o = np.argsort(first, kind="stable")
    uk, cnt = uk[o], cnt[o]
    pairs = zip((uk >> 32).tolist(), (uk & 0xFFFFFFFF).tolist(), strict=True)
    return dict(zip(pairs, cnt.tolist(), strict=True))


class FrontEnd:
    """Detectors, feature tracking and obstacle grouping for every camera of a rig.

    Args:
        rig: an ``estimators.rig.Rig``.
        detector: registered detector name (``orb``, ``navlights``, ``kornia``, ``torch``, a plug-in)
            or a Detector instance.
        **options: ``detector_options`` (dict, the detector's keywords), ``features`` (dict,
            FeatureTracker keywords), ``grouping`` (dict, ObstacleGrouper keywords), ``boxes``
            (dict, BoxTracker keywords), ``association`` (dict: ``every`` frames (default 5),
            ``epipolar_deg`` (1.0), ``max_hamming`` (64), ``min_votes`` (3)), ``max_width`` (int px,
            default 1280, or None): wider frames are tracked downscaled to this width with the
            camera model scaled alike (``CameraModel.scaled``), so bearings keep their meaning;
            ``CameraView.uv`` is reported in the full frame's pixels; ``densify_below`` (int, default
            8, 0 = off): tracks with fewer members get extra features detected around them
            (``FeatureTracker.densify``), so small obstacles keep enough features; ``densify_s`` (s,
            default 2/30): each track at most this often, applied as a frame count at the frame rate
            seen (the camera's feature tracker's ``FrameClock``, as the grouping's durations): every
            2nd frame at 30 fps, the count it was fitted as (``densify_every`` 2 before; the old key is
            an error naming this one), every 7th at 100 fps, where every 2nd ran densify 3.3x as often
            a second as at 30 fps (docs/ARCHITECTURE.md "... densify's cadence in seconds").

    Attributes:
        timings: seconds of the last frame per stage (resize: frames wider than max_width shrunk,
            detect, track, group, associate, report: the observations built from the tracks), summed
            over the cameras.
    """

    def __init__(self, rig, detector: str | Detector = "orb", **options: Any) -> None:
        old = {k: options[k] for k in _FRONTEND_RENAMED if k in options}
        self.densify_s = check_durations(
            "FrontEnd", _FRONTEND_RENAMED, old, {"densify_s": options.get("densify_s", DENSIFY_S)}
        )["densify_s"]
        unknown = [k for k in options if k not in _OPTION_GROUPS]
        if unknown:
            raise ConfigError(f"FrontEnd: unknown key '{unknown[0]}' in its options"
                              + did_you_mean(str(unknown[0]), list(_OPTION_GROUPS)))
        for group in _OPTION_DICTS:  # every group, also one this detector does not build (boxes for orb)
            problem = option_problem(group, options.get(group, {}))
            if problem is not None:
                raise ConfigError(f"FrontEnd: {problem[1]}")
        self.rig = rig
        self.detector = (
            detector
            if isinstance(detector, Detector)
            else make_detector(detector, **options.get("detector_options", {}))
        )
        if options.get("boxes") and not self.detector.produces_boxes:
            raise ConfigError(f"FrontEnd: {boxes_unused(self.detector.name, options['boxes'])}")
        # feature tracks are labelled by the keypoint detector (``orb`` also inside ``orb+navlights``)
        self.label = self.detector.keypoint_part.name or self.detector.name or "detector"
        self._feature_ids = itertools.count(1)
        self._track_ids = itertools.count(1)
        a = dict(options.get("association", {}))
        self.assoc_every = int(a.get("every", 5))
        self.epipolar_rad = float(np.radians(a.get("epipolar_deg", 1.0)))
        self.max_hamming = int(a.get("max_hamming", 64))
        self.min_votes = int(a.get("min_votes", 3))
        # a reference feature found by stereo KLT within this distance of exactly one of the other
        # camera's features (and nothing else within twice it) is the same physical point
        self.klt_link_px = float(a.get("klt_link_px", 1.5))
        # stereo KLT of a feature matched last frame: forward-backward re-checked every this many
        # frames, or when it lands more than recheck_px from where last frame's match predicts
        self.recheck_every = int(a.get("recheck_every", 4))
        self.recheck_px = float(a.get("recheck_px", 1.0))
        # OpenCV maxLevel of the stereo KLT for a match followed from last frame (it starts within a
        # pixel or two of its answer): 1 searches 2 pyramid levels (full size and half), 0 only the
        # full-size image; new matches use maxLevel 4 (5 levels); null: maxLevel 4 for all
        fl = a.get("follow_levels", 1)
        if fl is not None and (isinstance(fl, bool) or not isinstance(fl, (int, np.integer)) or fl < 0):
            raise ConfigError(
                "FrontEnd association: follow_levels (OpenCV maxLevel of a followed stereo match's "
                f"KLT) expected an integer >= 0 or null, got {fl!r}"
            )
        self.follow_levels = None if fl is None else int(fl)
        # views the other way round (_derive_views): another camera's confirmed track with no
        # reference-camera track gets a reference view from its members found there by stereo KLT
        # (a full search every `every` frames, last frame's matches followed in between).
        # On by default: it costs ~2 ms of CPU per 720p stereo frame (associate median 5.4 -> 7.3
        # ms, one pinned core, against the 30 fps stereo target), for these gains on the accuracy
        # scenes (accuracy --mode pipeline --set both at 9edeb56, false -> true, tuned | held-out):
        # range NEES 1.104 -> 1.006 | 2.034 -> 1.954, stereo <= 3 m 0.80 -> 0.80 | 0.71 -> 0.67 %,
        # <= 8 m 1.09 -> 1.04 | 0.97 -> 1.00 %, stereo <= 8 m obstacle-frame coverage
        # 76.1 -> 76.1 | 70.2 -> 74.0 %; mono, bounds and speed identical
        rv = a.get("reverse_views", True)
        if not isinstance(rv, bool):
            raise ConfigError(f"FrontEnd association: reverse_views expected true or false, got {rv!r}")
        self.reverse_views = rv
        if self.recheck_every < 1 or not self.recheck_px >= 0:
            raise ConfigError(
                "FrontEnd association: recheck_every expected an integer >= 1 and recheck_px a "
                f"distance >= 0 px, got {self.recheck_every!r} and {self.recheck_px!r}"
            )
        # frames wider than max_width are tracked downscaled (the camera model scaled alike, so
        # bearings are unchanged); pixel outputs (CameraView.uv) are given in the full frame
        self.scale = tracked_scale(rig, options.get("max_width", MAX_WIDTH_PX))
        self.densify_below = int(options.get("densify_below", 8))
        # track id -> its camera's feature tracker's frame count (FeatureTracker.n_frames) at its last
        # densify: frames processed, the unit of the clock's counts (a caller's frame index counts a live
        # camera's dropped frames too)
        self._densified: dict[int, int] = {}
        self.calib_size = {c.name: (c.model.width, c.model.height) for c in rig.cameras}
        self.cams = {
            c.name: c
            if self.scale[c.name] == 1.0
            else Camera(c.name, c.model.scaled(self.scale[c.name]), c.T_C_B)
            for c in rig.cameras
        }
        self.masks = {
            c.name: lens_mask(c.model) for c in self.cams.values()
        }  # InputError if the circle does not fit
        # _has_texture's sample (every 8th pixel of every 8th row, inside the lens) as flat indices
        # into the frame, in the order boolean indexing gives them
        self._texture_idx = {n: _sample_index(m) for n, m in self.masks.items()}
        self.trackers: dict[str, FeatureTracker] = {}
        self.groupers: dict[str, ObstacleGrouper] = {}
        self.boxers: dict[str, BoxTracker] = {}
        for c in self.cams.values():
            if self.detector.produces_keypoints:
                fo, go = options.get("features", {}), options.get("grouping", {})
                try:
                    self.trackers[c.name] = FeatureTracker(
                        c, self.detector.keypoint_part, ids=self._feature_ids, **fo
                    )
                except TypeError as e:
                    raise _bad_options("features", e) from e
                try:
                    self.groupers[c.name] = ObstacleGrouper(self._track_ids, label=self.label, **go)
                except TypeError as e:
                    raise _bad_options("grouping", e) from e
            if self.detector.produces_boxes:
                bo = options.get("boxes", {})
                try:
                    self.boxers[c.name] = BoxTracker(self._track_ids, **bo)
                except TypeError as e:
                    raise _bad_options("boxes", e) from e
        if len(self.groupers) > 1:  # grouping step 3f: a split both cameras' flows support
            for n, g in self.groupers.items():
                g.plane_confirm = functools.partial(self._plane_confirm, n)
        # frames wider than max_width, keypoint cameras: only the part the tracker reads (its lens
        # box, FeatureTracker.frame_box) is shrunk, the rest of the small frame left black
        self._shrink = {
            n: _shrink_box(self.calib_size[n], self.cams[n].model, ft.frame_box)
            for n, ft in self.trackers.items()
            if self.scale[n] != 1.0
        }
        # box detectors read the full-size frame (its colour, its lens mask), not the shrunk one:
        # the keypoints then see the same small grey frame as with the keypoint detector alone, and
        # no colour frame is shrunk (1920x1080 orb+navlights: +9 -> +2 ms a frame); their boxes are
        # mapped to the small frame (Detections.scaled)
        self._box_masks = {
            c.name: lens_mask(c.model, margin_px=3.0 / self.scale[c.name])  # the small mask's margin
            for c in rig.cameras
            if c.name in self.boxers and self.scale[c.name] != 1.0
        }
        self.timings: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        # per camera and camera pair, computed once: radians per pixel at the lens's mean scale,
        # R_C_B, and T_Cb_Ca = T_Cb_B T_B_Ca (p_Cb = R p_Ca + t)
        self._rad_px = {n: c.model.rad_per_px for n, c in self.cams.items()}
        self._R_C_B = {n: np.asarray(c.T_C_B.R, float) for n, c in self.cams.items()}
        self._T_b_a = {
            (a, b): self.cams[b].T_C_B @ self.cams[a].T_C_B.inverse()
            for a in self.cams
            for b in self.cams
            if a != b
        }
        # camera pairs (a, b) whose images turn a feature's patch (the top/bottom rig's): stereo KLT
        # searches b's crop resampled into a's geometry (TurnedPair; none for parallel axes)
        self._turned: dict[tuple[str, str], TurnedPair] = {}
        for (a, b), T in self._T_b_a.items():
            ma, mb = self.cams[a].model, self.cams[b].model
            if a in self.trackers and b in self.trackers and pair_turns(ma, mb, T.R):
                (x0, y0, x1, y1), rb = self.trackers[a].roi, self.trackers[b].roi
                self._turned[(a, b)] = TurnedPair(ma, mb, T.R, T.t, (y1 - y0, x1 - x0), (x0, y0), rb[:2])
        self._b_in_a: dict[tuple[str, str], np.ndarray] = {}  # this frame's resampled crops, per pair
        # this frame's stereo KLT results per camera pair (shared by _associate and _derive_views)
        self._stereo_cache: dict[tuple[str, str], tuple] = {}
        # last frame's stereo KLT matches per camera pair (_remember_stereo), where this frame's start
        self._stereo_mem: dict[tuple[str, str], tuple] = {}
        # camera pairs whose stereo KLT this frame only follows last frame's matches (at
        # follow_levels; backward-checked only when it lands off its guess): the reverse views'
        # pairs between their retries (_derive_views); _retry_rows: per such pair, the rows of
        # a's features searched in full all the same (_unheld_rows)
        self._follow_only: set[tuple[str, str]] = set()
        self._retry_rows: dict[tuple[str, str], np.ndarray] = {}
        self._gid: dict[int, int] = {}  # local (per-camera) track id -> global track id
        # global ids of box tracks that a younger feature track linked to the box reports under
        # (_box_keeps_id), so that it gives them back when the link ends: the box's camera and the
        # frames in a row it was seen and not linked
        self._box_lent: dict[int, tuple[str, int]] = {}
        # global ids of box tracks handed to a feature track that lay on the box while the box coasts
        # (_box_hands_id): per id, its local feature track ids -> the global id each had before
        self._box_handed: dict[int, dict[int, int]] = {}
        self._merged_into: dict[int, int] = {}  # this frame's merges: dropped global id -> kept one
        # _merge_gids' count (a merge re-maps global ids) and this frame's _unviewed_in_ref lists
        # per (camera, that count), reset each frame by _prefetch_stereo
        self._gid_version = 0
        self._unviewed: dict[tuple[str, int], tuple] = {}
        # per camera, this frame's (live feature ids, their stable argsort, the sorted ids) (_rows)
        self._id_order: dict[str, tuple] = {}
        # box tracks of the reference camera and another linked as one obstacle (_associate_boxes)
        self._box_stereo = {(rig.cameras[0].name, c.name): BoxStereo(2) for c in rig.cameras[1:]}
        # physical-point feature ids (ARCHITECTURE "Stage interfaces"): per other camera, its
        # feature id -> the id it is reported under (the reference camera's matched feature, or a
        # fresh id once its link would have changed), and which of its features holds each ref id
        self._pid: dict[str, dict[int, int]] = {c.name: {} for c in rig.cameras[1:]}
        self._claim: dict[str, dict[int, int]] = {c.name: {} for c in rig.cameras[1:]}
        self._reported: set[int] = set()  # global ids reported at least once
        # global ids reported lost: none is reported again (CONVENTIONS: an id is stable over the
        # track's life, lost reported once when it ends); _observations gives a track under one a fresh id
        self._ended: set[int] = set()
        self._R_W_B: deque[np.ndarray] = deque(maxlen=8)
        self._n = 0
        self.last_features: dict[str, Any] = {}

    # --------------------------------------------------------------------------------- api
    def process(
        self, images: Mapping[str, np.ndarray], frame: int, t_s: float, T_W_B=None
    ) -> list[ObstacleObservation]:
        """Run detection, tracking, grouping and association on one frame set.

        Args:
            images: camera name -> (H, W) uint8 grey or (H, W, 3) uint8 BGR frame of the calibration's
                size. A camera left out this frame (dropped frame) coasts.
            frame: frame index; t_s: frame time (s).
            T_W_B: optional body pose at t_s (``estimators.se3.Pose``); its rotation compensates the
                camera's own rotation when comparing feature motions.
        Returns:
            one ObstacleObservation per obstacle track seen this frame (tentative or confirmed), plus
            one ``lost`` observation for each track lost this frame. A black or saturated frame gives
            no detections (tracks coast).
        Raises:
            InputError: an unknown camera, a frame of the wrong size, dtype or channel count (the
                message names the frame index and its t_s).
        """
        if not isinstance(images, Mapping):
            raise InputError(
                f"{frame_at(frame, t_s)}: FrontEnd.process: expected a mapping camera name -> image, "
                f"got {type(images).__name__}"
            )
        extra = sorted(set(images) - set(self.cams))
        if extra:
            raise InputError(
                f"{frame_at(frame, t_s)}: FrontEnd.process: unknown cameras {extra}; the rig has "
                f"{list(self.cams)}"
            )
        if not np.isfinite(t_s):
            raise InputError(f"frame {frame}: FrontEnd.process: expected a finite t_s, got {t_s!r}")
        tm = dict.fromkeys(STAGES, 0.0)
        checked = {}
        full: dict[str, np.ndarray] = {}  # the full-size frames of box cameras wider than max_width
        for name, img in images.items():
            w, h = self.calib_size[name]
            try:
                img = check_image(name, img, w, h)
            except InputError as e:  # which frame was refused: a video's bad frame is found by index / time
                raise InputError(f"{frame_at(frame, t_s)}: {e}") from None
            if self.scale[name] != 1.0:
                m = self.cams[name].model
                t0 = time.perf_counter()
                if name in self.boxers:
                    full[name] = img
                img = to_grey(img)  # shrink the grey frame (a third the work)
                box = self._shrink.get(name)
                if box is not None:  # the lens box only (1920x1080: 4.2 -> ~2.5 ms)
                    sx0, sy0, sx1, sy1, x0, y0, x1, y1 = box
                    small = np.zeros((m.height, m.width), np.uint8)
                    small[y0:y1, x0:x1] = cv2.resize(
                        img[sy0:sy1, sx0:sx1], (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA
                    )
                    img = small
                else:
                    img = cv2.resize(img, (m.width, m.height), interpolation=cv2.INTER_AREA)
                tm["resize"] += time.perf_counter() - t0
            checked[name] = img
        rot = self._rotations(T_W_B)
        seen: dict[str, list[ObstacleTrack]] = {}
        lost: list[ObstacleTrack] = []
        greys: dict[str, np.ndarray] = {}
        for name, cam in self.cams.items():
            img = checked.get(name)
            grey = None if img is None else to_grey(img)
            usable = grey is not None and self._has_texture(grey, self.masks[name], self._texture_idx[name])
            s: list[ObstacleTrack] = []
            if name in self.trackers:
                ft = self.trackers[name]
                gr = self.groupers[name]
                if usable:
                    greys[name] = grey
                    feats, t = ft.track(grey, frame, t_s, image=img)
                    tm["track"] += t["track"]
                    tm["detect"] += t["detect"]
                    self.last_features[name] = feats
                    t0 = time.perf_counter()
                    R_C = self._camera_rotations(self._R_C_B[name], rot)
                    s1, l1 = gr.update(ft, t_s, R_C)
                    tm["group"] += time.perf_counter() - t0
                    t0 = time.perf_counter()
                    # tracks with few members, each at most every densify_s (as frames at the rate seen:
                    # none before the feature tracker's clock knows the rate, as no track exists then),
                    # 8 per frame
                    every, n = ft.clock.frames(self.densify_s), ft.n_frames
                    small = [
                        t
                        for t in s1
                        if len(t.members) < self.densify_below
                        and n - self._densified.get(t.id, -(10**9)) >= every
                    ]
                    small = sorted(small, key=lambda t: len(t.members))[:8]
                    for t in small:
                        self._densified[t.id] = n
                    if len(self._densified) > 4096:  # forget long-gone tracks
                        self._densified = {k: v for k, v in self._densified.items() if n - v < 300}
                    # one whose representative has no pixel (beyond the lens's field, uv None) is not
                    # searched, but keeps its turn among the 8 and its densify_s wait (handing the
                    # turn to another track was measured worse: docs/ARCHITECTURE.md, "no pixel")
                    small = [t for t in small if t.uv is not None]
                    if small:
                        rad_px = self._rad_px[name]
                        radii = [
                            2.0 * np.sqrt(max(t.sigma_rad**2 * len(t.members), 0.0)) / rad_px for t in small
                        ]
                        ft.densify(grey, np.array([t.uv for t in small]), np.array(radii), frame, t_s)
                    tm["detect"] += time.perf_counter() - t0
                else:
                    s1, l1 = [], gr.coast(t_s, self._camera_rotations(self._R_C_B[name], rot))
                s += s1
                lost += l1
            if name in self.boxers:
                t0 = time.perf_counter()
                if usable:
                    if name in full:  # found on the full-size frame, mapped to the small one
                        det = self.detector.detect_boxes(full[name], self._box_masks[name])
                        det = det.scaled(self.scale[name])
                    else:
                        det = self.detector.detect_boxes(img, self.masks[name])
                    tm["detect"] += time.perf_counter() - t0
                    t0 = time.perf_counter()
                    # (given this frame's feature tracks: one obstacle found by both is reported once)
                    s2, l2 = self.boxers[name].update(cam, det, s, t_s=t_s)
                else:
                    s2, l2 = [], self.boxers[name].coast(t_s)
                tm["group"] += time.perf_counter() - t0
                s += s2
                lost += l2
            seen[name] = s
        t0 = time.perf_counter()
        absorbed: list[int] = []
        self._merged_into = {}
        if self.boxers and self.groupers:
            self._box_keeps_id(absorbed)
            self._box_hands_id(absorbed)
        assoc_now = len(self.cams) > 1 and self._n % self.assoc_every == 0
        if len(self.cams) > 1:
            self._prefetch_stereo(seen, greys, assoc_now)
        if assoc_now:
            absorbed += self._associate(seen, greys)
        if len(self.cams) > 1 and self.boxers:  # box tracks: every frame (no features to match)
            absorbed += self._associate_boxes(seen)
        if len(self.cams) > 1:
            for name, extra in self._derive_views(seen, greys).items():
                seen[name] = seen.get(name, []) + extra
        self._remember_stereo()
        tm["associate"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        self._n += 1
        out = self._observations(seen, lost, absorbed, frame, t_s)
        tm["report"] = time.perf_counter() - t0
        self.timings = tm
        return out

    def defer_detection(self, executor: Any) -> None:
        """The feature trackers' re-detections run on ``executor`` off the frame's path (live mode:
        ``FeatureTracker.defer_detection``); None: in their frames (the default)."""
        for ft in self.trackers.values():
            ft.defer_detection(executor)

    @property
    def deferred(self) -> dict[str, dict[str, int]]:
        """Per feature tracker: deferred detections joined and the frames between their own and their
        joins, in all (``FeatureTracker.deferred``)."""
        return {name: dict(ft.deferred) for name, ft in self.trackers.items()}

    # ------------------------------------------------------------------------------ helpers
    @staticmethod
    def _has_texture(grey: np.ndarray, mask: np.ndarray, sample: np.ndarray | None = None) -> bool:
        """False for black, saturated or flat frames: the std of the lens area (sampled every 8 px)
        below 2 grey levels and, at full resolution, no two pixels 24 grey levels apart (so a
        small obstacle against a flat sky still counts). ``sample``: ``_sample_index(mask)``
        (flat indices of that sample; computed from ``mask`` when None)."""
        sub = np.take(grey, _sample_index(mask) if sample is None else sample)
        if sub.size <= 16:
            return False
        if float(sub.std()) >= 2.0:
            return True
        lo, hi, _, _ = cv2.minMaxLoc(grey, mask)
        return bool(hi - lo >= 24)

    def _rotations(self, T_W_B) -> dict[int, np.ndarray] | None:
        """{k: R_Bnow_Bk} for the last frames, from the given poses (None without poses)."""
        if T_W_B is None:
            self._R_W_B.clear()
            return None
        R_now = np.asarray(T_W_B.R, float)
        self._R_W_B.appendleft(R_now)
        return {k: R_now.T @ self._R_W_B[k] for k in range(1, len(self._R_W_B))}

    @staticmethod
    def _camera_rotations(
        R_C_B: np.ndarray, rot: dict[int, np.ndarray] | None
    ) -> dict[int, np.ndarray] | None:
        if not rot:
            return None
        # R_Cnow_Ck = R_C_B R_Bnow_Bk R_C_B^T
        return {k: R_C_B @ R @ R_C_B.T for k, R in rot.items()}

    def _plane_confirm(self, name: str, tr: ObstacleTrack) -> bool:
        """Whether the track of camera ``name``'s grouper whose part is due to leave by its motion
        off a plane (grouping step 3f) has a view in another camera (the same global id) where
        step 3f found a part too (``ObstacleGrouper.plane_recent``)."""
        g = self._global(tr.id)
        for n, gr in self.groupers.items():
            if n != name and any(self._global(t.id) == g and gr.plane_recent(t) for t in gr.tracks.values()):
                return True
        return False

    def _global(self, tid: int) -> int:
        return self._gid.get(tid, tid)

    def _rows(self, ft: FeatureTracker, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(rows (K,) into ft's live features, which (K,) indices into ``ids``) of the live ones
        among feature ids ``ids`` (N,). The sort of ft's ids is kept for the frame (``_id_order``,
        while ``ft.ids`` is the same array)."""
        ids = np.asarray(ids, np.int64)
        if not len(ids) or not len(ft.ids):
            return np.zeros(0, np.intp), np.zeros(0, np.intp)
        c = self._id_order.get(id(ft))
        if c is None or c[0] is not ft.ids:
            order = np.argsort(ft.ids, kind="stable")
            c = self._id_order[id(ft)] = (ft.ids, order, ft.ids[order])
        _, order, sids = c
        k = np.minimum(np.searchsorted(sids, ids), len(sids) - 1)
        which = (sids[k] == ids).nonzero()[0]
        return order[k[which]], which

    def _stereo(self, a: str, b: str, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Camera a's live features ``rows`` (K,) found in camera b's frame by stereo KLT
        (trackers/association.py ``stereo_klt``, on the trackers' lens crops), each feature
        at most once per frame: (idx (J,) into rows, uv_b (J, 2) full-frame px in b, b_b (J, 3)
        unit bearings in C_b).

        A feature found last frame starts from there, moved by its own motion in a, and skips the
        forward-backward check unless its last check is ``recheck_every`` frames old or it did not
        land within ``recheck_px`` of that start (new features are always checked). A pair whose
        images turn a patch (``self._turned``) is searched in b's crop resampled into a's geometry
        (``TurnedPair``), where that start is last frame's match seen there moved alike."""
        fa, fb = self.trackers[a], self.trackers[b]
        turned = self._turned.get((a, b))
        n = len(fa.ids)
        c = self._stereo_cache.get((a, b))
        if c is None or len(c[0]) != n:
            nan = np.nan
            c = (np.zeros(n, bool), np.full((n, 2), nan), np.full((n, 3), nan), np.full(n, -1, np.int64))
            self._stereo_cache[(a, b)] = c
        tried, uvb, bb, chk = c
        rows = np.asarray(rows, np.intp)
        todo = np.unique(rows[~tried[rows]])
        follow_only = (a, b) in self._follow_only
        if len(todo):
            guess = np.full((len(todo), 2), np.nan)
            last = np.full(len(todo), -1, np.int64)
            m = self._stereo_mem.get((a, b))
            if m is not None and m[0] == self._n - 1 and len(m[1]):
                m_ids = m[1]
                ids = fa.ids[todo]
                k = np.minimum(np.searchsorted(m_ids, ids), len(m_ids) - 1)
                hit = (m_ids[k] == ids).nonzero()[0]
                kk = k[hit]
                # last frame's match moved as the feature moved in a: uv_b + (uv_a now - uv_a then)
                # (in b' for a turned pair: b's image there has a's orientation)
                last_b = m[3].take(kk, 0) if turned is None else turned.to_virtual(m[3].take(kk, 0))
                guess[hit] = last_b + (fa.uv.take(todo[hit], 0) - m[2].take(kk, 0))
                last[hit] = m[4][kk]
            if follow_only:  # last frame's matches followed, plus the retry rows (see _follow_only)
                tried[todo] = True
                held = last >= 0
                retry = self._retry_rows.get((a, b))
                if retry is not None and len(retry):
                    held |= _isin(todo, retry)
                keep = held.nonzero()[0]
                todo, guess, last = todo[keep], guess[keep], last[keep]
        if len(todo):
            (ca, oa), (cb, ob) = fa.crop, fb.crop
            kw = dict(
                win_px=fa.win[0],  # the temporal KLT's window (tracked_window)
                off_a=oa,
                check=np.zeros(len(todo), bool)
                if follow_only
                else (last < 0) | (self._n - last >= self.recheck_every),
                recheck_px=self.recheck_px,
                follow_levels=self.follow_levels,
                epipolar_rad=self.epipolar_rad,
            )
            if turned is None:
                T = self._T_b_a[(a, b)]
                r = stereo_klt(
                    ca, cb, fa.b_C[todo], fa.uv[todo].astype(float), self.cams[b].model, T.R, T.t,
                    off_b=ob, guess_b=guess, **kw,
                )
            else:
                b_in_a = self._b_in_a.get((a, b))
                if b_in_a is None:
                    b_in_a = self._b_in_a[(a, b)] = turned.resample(ca, cb)
                uv_a = fa.uv[todo].astype(float)
                r = turned.stereo_klt(ca, b_in_a, fa.b_C[todo], uv_a, guess, off_b=oa, **kw)
            tried[todo] = True
            found = todo[r.idx]
            uvb[found] = r.uv_b
            bb[found] = r.b_b
            chk[found] = np.where(r.checked, self._n, last[r.idx])
        sel = np.isfinite(uvb[rows, 0]).nonzero()[0]
        rs = rows[sel]
        return sel, uvb.take(rs, 0), bb.take(rs, 0)

    def _remember_stereo(self) -> None:
        """Keep this frame's stereo KLT matches (per camera pair, sorted by a's feature id: the
        frame, ids, uv_a, uv_b (full-frame px), frame of the last forward-backward check) as the
        next frame's starting points, and clear the per-frame cache."""
        mem = {}
        for (a, b), (_, uvb, _, chk) in self._stereo_cache.items():
            ft = self.trackers[a]
            f = np.isfinite(uvb[:, 0]).nonzero()[0]
            o = np.argsort(ft.ids[f], kind="stable")
            f = f[o]
            mem[(a, b)] = (self._n, ft.ids[f], ft.uv[f].astype(float), uvb[f], chk[f])
        self._stereo_mem = mem
        self._stereo_cache.clear()
        self._b_in_a.clear()

    def _prefetch_stereo(
        self, seen: dict[str, list[ObstacleTrack]], greys: dict[str, np.ndarray], assoc_now: bool
    ) -> None:
        """Run this frame's stereo KLT once per camera pair, for every feature that ``_associate``
        (when ``assoc_now``: all members of the detector's tracks) and ``_derive_views`` /
        ``_add_found_members`` (members of confirmed reference tracks with >= 3 members) will ask
        ``_stereo`` for: LK rebuilds both images' pyramids on every call (the Python binding takes
        no prebuilt pyramids), so one call per pair and frame instead of up to three."""
        self._unviewed.clear()  # this frame's lists (_unviewed_in_ref) and sorts (_rows)
        self._id_order.clear()
        ref = self.rig.cameras[0].name
        names = [n for n in self.cams if n in greys and n in self.trackers and seen.get(n)]
        # reverse views: a full search (a retry) on association frames, else last frame's matches
        # followed only (_follow_only)
        rev = self.reverse_views and not assoc_now
        self._follow_only = {(n, ref) for n in self.cams if n != ref} if rev else set()
        # ... except the members of tracks that last frame's matches cannot hold a view for
        # (_unheld_rows): searched in full, so a view is not lost until the next association frame
        self._retry_rows = {
            (a, b): self._unheld_rows(a, b, self._unviewed_in_ref(seen, a)) for a, b in self._follow_only
        }
        for a, b in itertools.permutations(names, 2):
            a_first = names.index(a) < names.index(b)
            trs = []
            if assoc_now and a_first:
                trs += [t for t in seen[a] if t.label == self.label and len(t.members)]
            if a == ref:
                trs += [t for t in seen[a] if t.status == "confirmed" and len(t.members) >= 3]
            elif b == ref and self.reverse_views:  # _derive_views: a's tracks with no reference view
                trs += self._unviewed_in_ref(seen, a)
            if not trs:
                continue
            rows, _ = self._rows(self.trackers[a], np.concatenate([t.members for t in trs]))
            if len(rows):
                self._stereo(a, b, rows)

    def _unheld_rows(self, a: str, b: str, tracks: list[ObstacleTrack]) -> np.ndarray:
        """Rows (K,) into camera a's live features: the members of ``tracks`` (a's tracks with no
        view in camera b) whose track has fewer than 3 members among last frame's a -> b stereo
        matches (``unheld``): following those cannot give a view, so between association frames
        they are searched in full (``_follow_only``'s retry rows) instead of waiting for the next
        association frame (a track confirmed, or whose linked reference track left, since the last
        one; one whose followed matches were lost)."""
        m = self._stereo_mem.get((a, b))
        held_ids = m[1] if m is not None and m[0] == self._n - 1 else np.zeros(0, np.int64)
        todo = [t.members for t in tracks]
        out = [t for t, u in zip(todo, unheld(todo, held_ids, 3), strict=True) if u]
        if not out:
            return np.zeros(0, np.intp)
        return self._rows(self.trackers[a], np.concatenate(out))[0]

    def _associate(self, seen: dict[str, list[ObstacleTrack]], greys: dict[str, np.ndarray]) -> list[int]:
        """Link tracks of different cameras that share epipolar-consistent feature correspondences
        (ORB descriptor matches, and members found by KLT in the other camera's image).

        Returns the global ids absorbed into another this frame (to be reported lost once)."""
        names = [n for n in self.cams if n in greys and n in self.trackers and seen.get(n)]
        data = {}
        members: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}  # rows, uv, owner track id
        for n in names:
            ft = self.trackers[n]
            trs = [tr for tr in seen[n] if tr.label == self.label and len(tr.members)]
            if not trs:
                continue
            mem = np.concatenate([tr.members for tr in trs])
            own_all = np.repeat(np.array([tr.id for tr in trs], np.int64), [len(tr.members) for tr in trs])
            rows_a, which = self._rows(ft, mem)
            if not len(rows_a):
                continue
            owner = own_all[which]
            members[n] = (rows_a, ft.uv[rows_a].astype(float), owner)
            des, got = ft.describe(greys[n], rows_a)
            # describe returns rows of the live features; their owners via the row -> owner map
            row_owner = np.full(len(ft.ids), -1, np.int64)
            row_owner[rows_a] = owner
            data[n] = (ft.b_C[got], des, row_owner[got], ft.ids[got])
        absorbed: list[int] = []
        for a, b in itertools.combinations([n for n in names if n in data], 2):
            T_b_a = self._T_b_a[(a, b)]  # T_Cb_Ca = T_Cb_B T_B_Ca
            ba, da, oa, fa = data[a]
            bb, db, ob, fb = data[b]
            # votes 1: ORB descriptors of members matched under the epipolar constraint (one vote
            # per match to the pair (a's owner track, b's owner track))
            m = match_features(ba, da, bb, db, T_b_a.R, T_b_a.t, self.epipolar_rad, self.max_hamming)
            ref_a = a == self.rig.cameras[0].name
            link_a, link_b = [fa[m[:, 0]]], [fb[m[:, 1]]]  # physical-point links (ref id, b's id)
            vote_a, vote_b = [oa[m[:, 0]]], [ob[m[:, 1]]]
            # votes 2: a's members found in b's image by KLT from their infinite-depth projection;
            # the vote goes to b's track whose member is nearest (within the grouping link distance)
            ua, ub = members[a], members[b]
            idx, uv_b, _ = self._stereo(a, b, ua[0])
            if len(idx) and len(ub[1]):
                # squared px, du^2 + dv^2 written out (the same numbers as ((a - b) ** 2).sum(-1),
                # whose reduction over a length-2 axis took 10x as long: 3.7 vs 0.35 ms at 260 x 450)
                du = uv_b[:, 0, None] - ub[1][None, :, 0]
                dv = uv_b[:, 1, None] - ub[1][None, :, 1]
                d2 = du * du + dv * dv
                j = np.argmin(d2, axis=1)
                near = d2[np.arange(len(idx)), j] <= self.groupers[b].link_px ** 2
                vote_a.append(ua[2][idx[near]])
                vote_b.append(ub[2][j[near]])
                if ref_a:
                    ia, ib = klt_links(d2, self.klt_link_px)
                    link_a.append(self.trackers[a].ids[ua[0][idx[ia]]])
                    link_b.append(self.trackers[b].ids[ub[0][ib]])
            if ref_a:
                self.link_features(b, *consistent_pairs(np.concatenate(link_a), np.concatenate(link_b)))
            pairs = _count_pairs(np.concatenate(vote_a), np.concatenate(vote_b))
            if not pairs:
                continue
            best_a: dict[int, tuple[int, int]] = {}
            best_b: dict[int, tuple[int, int]] = {}
            for (ta, tb), v in pairs.items():
                if v > best_a.get(ta, (0, -1))[0]:
                    best_a[ta] = (v, tb)
                if v > best_b.get(tb, (0, -1))[0]:
                    best_b[tb] = (v, ta)
            held: dict[str, set[int]] = {}  # camera -> global ids of its live local tracks
            for ta, (v, tb) in best_a.items():
                if v < self.min_votes or best_b[tb][1] != ta:
                    continue
                ga, gb = self._global(ta), self._global(tb)
                if ga == gb:
                    continue
                for cam in (a, b):
                    if cam not in held:
                        held[cam] = self._gids_in(cam)
                if ga in held[b] or gb in held[a]:
                    continue  # already linked to another track in that camera
                held.clear()  # the merge below re-maps global ids
                # the surviving id: the one seen for longer, so the id downstream filters know carries on
                keep, drop = self._survivor(ga, gb)
                self._merge_gids(keep, drop, (ta, tb), absorbed)
        return absorbed

    def _box_keeps_id(self, absorbed: list[int]) -> None:
        """An obstacle found first by its box keeps the box's id (issue 4: track id switches).

        A box track linked to a feature track of its camera (``BoxTracker.links``) is not reported;
        the feature track is. When the box track is the older one (a smaller global id: box and
        feature tracks draw ids from one counter) and no other camera has a track of its global id,
        the feature track's global id (with every local track sharing it) is merged into the box's
        (``_merge_gids``; its own id is reported lost once if it was reported), so the obstacle's
        reported id does not change at the link. While the box is seen, a feature track of its
        camera under its id that is not linked to it (the link moved to another track, or ended
        ``link_frames`` frames in a row: a link re-forms only after as many, so a shorter break
        keeps the id) takes its own id back (reported under a fresh id when that one was reported lost
        at the merge: ``_observations``); with none linked the box reports under its id again
        (other cameras' tracks under it follow the track they were associated with). A box unseen
        (coasting) keeps lending its id; one that ends while lending it leaves its id with the
        feature track. A box another camera sees too lends no id: its obstacle is ranged from the
        two box views, and the feature track's view beside the other camera's box view under one id
        gave wrong, narrow ranges (accuracy, stereo_flying's drone: tuned range NEES 0.999 -> 1.477).

        Args: absorbed: global ids absorbed this frame (to be reported lost once), appended to."""
        gid = self._global
        held: dict[int, int] = {}  # a lent global id -> the feature track linked to its box now
        for name, bx in self.boxers.items():
            for bid, fid in bx.links.items():
                gb, gf = gid(bid), gid(fid)
                if gb < gf and not any(gb in self._gids_in(n) for n in self.cams if n != name):
                    self._merge_gids(gb, gf, (fid,), absorbed)
                    self._box_lent[gb] = (name, 0)
                if gid(fid) == gb:
                    held[gb] = fid
        if not self._box_lent:
            return
        # boxes seen this frame (a coasting box keeps lending its id: it may be found, and linked, again)
        seen = {gid(t.id) for bx in self.boxers.values() for t in bx.tracks.values() if t.seen}
        for g, (cam, n) in sorted(self._box_lent.items()):
            lids = [t for gr in self.groupers.values() for t in gr.tracks if gid(t) == g]
            if not lids:
                del self._box_lent[g]
                continue
            h = held.get(g)
            n = 0 if g not in seen or h is not None else n + 1  # frames in a row seen, not linked
            self._box_lent[g] = (cam, n)
            if g not in seen or 0 < n < self.boxers[cam].link_frames:
                continue  # (a link re-forms only after link_frames: a shorter break keeps the id)
            # in the box's camera, the feature tracks under its id not linked to it now take their own
            off = [t for t in self.groupers[cam].tracks if gid(t) == g and t != h]
            for lid in off:
                self._gid[lid] = lid
            if h is None:  # the box reports under its id again; other cameras' views follow
                for lid in [t for t in lids if t not in off] if off else ():
                    self._gid[lid] = min(off)
                del self._box_lent[g]
            if off:
                self._gid_version += 1

    def _box_hands_id(self, absorbed: list[int]) -> None:
        """A box track's id carried on by the feature track that lay on the box (issue 4: id switches).

        A box track and a feature track of its camera on the same obstacle that never linked
        (``BoxTracker.links``: the nearest members did not move with the box centre, or another
        camera sees the box too, so it lends no id) are two reports, each under its own id. When
        no track under the box's global id is seen this frame (every box track of it coasting, a
        feature track it lent its id to unseen too), the feature track that lay on the box as a new
        link needs (bearing and ``link_share`` of its members within the box) in the box's last
        ``link_frames`` updates seen in a row (``BoxTracker.placed``; the most such updates, then the
        smaller id) and is seen now takes the box's id, with every local track under its global id
        (``_merge_gids``: its own id is reported lost once), if the box's id is the one seen longer
        (``_survivor``) and no box track is under the feature track's id. The obstacle's report then
        keeps the id it had while the box, the track that carried it, coasts and after it ends
        (stereo_flying's near drone, noisy_1080p's drone: the box went unseen for good in the drone's
        last frames in view, the ORB tracks on it since 13 and 3 frames carried on under their own
        ids). When a box track of that id is seen again, the handed tracks take back the ids they had
        (reported under a fresh id when that one was reported lost: ``_observations``).
        The feature track's id is reported lost with ``merged_into`` the box's id: the fusion continues
        the feature track's filter under the box's id when it was ranged more recently than the box's
        (``ObstacleFusion._continued``; stereo_flying's drone: the box's filter bounds only since
        frame 39, the feature track's ranged to the last frame), else the box's filter goes on with
        the feature track's views and the feature track's filter ends.

        Args: absorbed: global ids absorbed this frame (to be reported lost once), appended to."""
        gid = self._global
        boxes: dict[int, list[tuple[str, ObstacleTrack]]] = {}
        for name, bx in self.boxers.items():
            for t in bx.tracks.values():
                boxes.setdefault(gid(t.id), []).append((name, t))
        for g, prev in list(self._box_handed.items()):
            if g in boxes and not any(t.seen for _n, t in boxes[g]):
                continue  # the box coasts: the id stays handed
            if g in boxes:  # a box of that id seen again: the handed tracks take back their ids
                linked = {self.boxers[n].links.get(t.id) for n, t in boxes[g]}  # (not one it links to)
                for lid, f in prev.items():
                    if gid(lid) == g and lid not in linked:
                        self._gid[lid] = f
                self._gid_version += 1
            del self._box_handed[g]
        seen = {gid(t.id) for gr in self.groupers.values() for t in gr.tracks.values() if t.seen}
        for g, bs in sorted(boxes.items()):
            if g in seen or g in self._box_handed or any(t.seen for _n, t in bs):
                continue
            runs: dict[int, int] = {}
            for name, t in bs:
                need = self.boxers[name].link_frames
                for fid, n in self.boxers[name].placed.get(t.id, {}).items():
                    f = gid(fid)
                    if n >= need and f != g and f in seen and f not in boxes:
                        runs[f] = max(runs.get(f, 0), n)
            if not runs:
                continue
            f = min(runs, key=lambda k: (-runs[k], k))
            if self._survivor(g, f)[0] != g:
                continue
            lids = [lid for gr in self.groupers.values() for lid in gr.tracks if gid(lid) == f]
            self._box_handed[g] = dict.fromkeys(lids, f)
            self._merge_gids(g, f, tuple(lids), absorbed)
            seen.add(g)

    def _box_fold(self, seen, a: tuple, b: tuple) -> bool:
        """Whether one side of a linked box pair is a box linked to a feature track
        (``BoxTracker.links``) and the other a visible box whose camera already has a track of that
        feature track's obstacle lying on the box (its bearing within the box's 3 sigma_rad + the
        BoxTracker's gate_rad): the box is then folded into that obstacle (reported once; the track
        listed first in that camera gives the view; the merged obstacle keeps the id seen longer,
        ``_survivor``, as the other stereo merges do).
        a, b: (camera, box track id, standing-for track id, global id)."""
        for (_, tf_, lf, gf), (cv, tv, lv, _) in ((a, b), (b, a)):
            if lf == tf_ or lv != tv:
                continue  # not (a box on a feature track, a visible box)
            box = self.boxers[cv].tracks.get(tv)
            if box is None:
                continue
            reach = 3.0 * box.sigma_rad + self.boxers[cv].gate_rad
            for tr in seen.get(cv, ()):
                if tr.id != tv and self._global(tr.id) == gf and float(tr.b_C @ box.b_C) >= np.cos(reach):
                    return True
        return False

    def _associate_boxes(self, seen: dict[str, list[ObstacleTrack]]) -> list[int]:
        """Link box tracks (BoxTracker) of another camera to the reference camera's (the rig's
        first) that are one obstacle: box centres epipolar-consistent within the larger box's
        angular half-diagonal (3 sigma_rad) plus ``association.epipolar_deg``, rays meeting ahead
        of both cameras, the same label and compatible attributes (``boxes_compatible``), each box
        the other's only candidate, in 2 consecutive frames (trackers/association.py ``box_pairs``,
        ``BoxStereo``). A box linked to a feature track of its camera (``BoxTracker.links``) stands
        for that track; a pair whose boxes are both so linked is left to ``_associate``; a visible
        box whose partner stands for a feature track already seen in the box's camera is folded
        into that obstacle when that track lies on the box (``_box_fold``). Box tracks
        have no member features, so the two views carry no shared feature ids.

        Returns the global ids absorbed into another this frame (to be reported lost once)."""
        ref = self.rig.cameras[0].name
        absorbed: list[int] = []
        if ref not in self.boxers:
            return absorbed
        box_a = self.boxers[ref]
        A = [t for t in box_a.tracks.values() if t.seen]
        for b, box_b in self.boxers.items():
            if b == ref:
                continue
            B = [t for t in box_b.tracks.values() if t.seen]
            pairs: list[tuple[int, int]] = []
            if A and B:
                T = self._T_b_a[(ref, b)]  # T_Cb_Ca
                comp = np.array(
                    [[ta.label == tb.label and boxes_compatible(ta.attributes, tb.attributes) for tb in B]
                     for ta in A]
                )
                i0, i1 = box_pairs(
                    np.array([t.b_C for t in A]), np.array([3.0 * t.sigma_rad for t in A]),
                    np.array([t.b_C for t in B]), np.array([3.0 * t.sigma_rad for t in B]),
                    T.R, T.t, self.epipolar_rad, comp,
                )
                pairs = [(A[i].id, B[j].id) for i, j in zip(i0.tolist(), i1.tolist(), strict=True)]
            for ta, tb in self._box_stereo[(ref, b)].update(pairs):
                la, lb = box_a.links.get(ta, ta), box_b.links.get(tb, tb)
                if la != ta and lb != tb:
                    continue
                ga, gb = self._global(la), self._global(lb)
                if ga == gb:
                    continue
                keep, drop = self._survivor(ga, gb)
                if ga in self._gids_in(b) or gb in self._gids_in(ref):
                    # one box stands for a feature track whose obstacle already has a track in the
                    # other box's camera: that box is a second report of it there when that track
                    # lies on the box (within 3 sigma + the BoxTracker's gate): folded into it
                    if not self._box_fold(seen, (ref, ta, la, ga), (b, tb, lb, gb)):
                        continue  # linked to another track in that camera
                self._merge_gids(keep, drop, (la, lb), absorbed)
        return absorbed

    def link_features(self, camera: str, ref_ids: np.ndarray, ids: np.ndarray) -> None:
        """Record verified matches of ``camera``'s features to the reference camera's (rig's first).

        A matched feature of ``camera`` is then reported under the reference feature's id (one
        physical point, one id in every view). Links are kept stable: a reference feature is held by
        at most one live feature of ``camera``; a feature whose match would now be another reference
        feature gets a fresh id for good instead (never re-using an id for another point).

        Args:
            camera: a non-reference camera's name.
            ref_ids: (K,) int reference-camera feature ids; ids: (K,) int ``camera``'s feature ids,
                row-paired, each pair verified by the epipolar constraint and the ORB descriptor.
        """
        pid, claim = self._pid[camera], self._claim[camera]
        ft = self.trackers[camera]
        if len(pid) > 4 * ft.max_features:  # forget features no longer tracked in that camera
            keep = set(ft.ids.tolist()) | set(ft.lost_ids.tolist())
            for f in [f for f in pid if f not in keep]:
                r = pid.pop(f)
                if claim.get(r) == f:
                    del claim[r]
        for r, f in zip(np.asarray(ref_ids).tolist(), np.asarray(ids).tolist(), strict=True):
            cur = pid.get(f)
            if cur == r:
                continue
            if cur is None:
                if r in claim:  # another feature of this camera holds that point
                    continue
                pid[f] = r
                claim[r] = f
            elif claim.get(cur) == f:  # the link would change partner: a fresh id instead
                del claim[cur]
                pid[f] = next(self._feature_ids)

    def _merge_gids(self, keep: int, drop: int, lids: tuple, absorbed: list[int]) -> None:
        """One obstacle from two: every local track id mapped to global id ``drop`` and the pair's
        local ids ``lids`` map to ``keep``; ``drop`` goes to ``absorbed`` when it was reported (its
        lost report names ``keep`` as ``merged_into``, this frame's ``_merged_into``)."""
        self._gid_version += 1
        self._merged_into[drop] = keep
        for lid, g in list(self._gid.items()):
            if g == drop:
                self._gid[lid] = keep
        for lid in lids:
            self._gid[lid] = keep
        if drop in self._reported:
            absorbed.append(drop)

    def _survivor(self, ga: int, gb: int) -> tuple[int, int]:
        """(kept, dropped) of two global ids being merged (see _associate): the one seen for more
        frames (in any camera), so the id downstream filters know carries on."""

        def hits(g: int) -> int:
            n = 0
            for d in list(self.groupers.values()) + list(self.boxers.values()):
                n = max([n] + [t.hits for t in d.tracks.values() if self._global(t.id) == g])
            return n

        ha, hb = hits(ga), hits(gb)
        return (ga, gb) if (ha, -ga) >= (hb, -gb) else (gb, ga)

    def _derive_views(
        self, seen: dict[str, list[ObstacleTrack]], greys: dict[str, np.ndarray]
    ) -> dict[str, list[ObstacleTrack]]:
        """Views in the other cameras of confirmed reference-camera tracks that have none there yet.

        The reference camera (the rig's first) tracks' members are found in each other camera's
        image by KLT from their infinite-depth projection (epipolar-checked, trackers/association.py);
        with >= 3 found, the track gets a view there: bearing = mean of the found members' bearings
        plus the reference offset of the representative point from its members' mean, rotated into
        that camera (R_b_a). These views carry the same feature ids as the reference members.

        A track that already has a view in camera b (its own grouper's track, linked by
        ``_associate``) gets the reference members found there the same way added to that view
        under their reference ids (``_add_found_members``; ``seen[b]`` then holds a copy, the
        grouper's track is not changed), so close obstacles, whose two cameras' independently
        detected corners rarely coincide, still have physical-point ids in both views.

        With ``association.reverse_views`` (on by default), the other way round: another camera's confirmed
        track whose global id has no reference track this frame (``_unviewed_in_ref``) gets a
        reference view from its members found in the reference image alike (members under their
        physical-point ids, ``_pid``). That search is a retry every ``association.every`` frames
        (new and re-checked matches, forward-backward); in between last frame's matches are
        followed (``_follow_only``: 2 pyramid levels, the backward check only for a match that
        lands off its start), so the extra KLT pair costs little per frame, and a track that
        those matches cannot hold a view for (fewer than 3: confirmed, or left by its linked
        reference track, since the last retry, or its matches lost) is searched in full
        (``_unheld_rows``), so a view persists while >= 3 of its features are found.

        One feature id, one obstacle per camera and frame: where found members meet an id already
        listed, once all views are built, camera b's feature linked to a reference member found
        for another view leaves its view (``_release_found``) and a reverse view drops the ids the
        reference camera's tracks list (``_drop_listed``). Two rays under one id would be fused as
        one point. Only the reported member lists change: the trackers', groupers' and links'
        states do not.
        """
        ref = self.rig.cameras[0].name
        out: dict[str, list[ObstacleTrack]] = {}
        if ref not in greys or ref not in self.trackers:
            return out
        to_release: dict[str, tuple[dict[int, int], list[ObstacleTrack]]] = {}  # _release_found's, per b
        for b in self.cams:
            if b == ref or b not in greys or not seen.get(ref):
                continue
            n_found = self._add_found_members(seen, ref, b)
            gid = self._gid.get
            have = {gid(t.id, t.id) for t in seen.get(b, [])}
            todo = [
                t
                for t in seen[ref]
                if t.status == "confirmed" and gid(t.id, t.id) not in have and len(t.members) >= 3
            ]
            views = self._views_found(ref, b, todo, None)
            to_release[b] = (n_found, views)
            if views:
                out[b] = views
        # reverse_views, the other way round: another camera's confirmed track whose global id has
        # no view in the reference camera this frame (the obstacle's reference features are
        # ungrouped, or in a reference track on another obstacle) gets a reference view from its
        # members found there (an obstacle both cameras see is stereo whichever camera grouped it)
        for b in self.cams:
            if b == ref or b not in greys or b not in self.trackers or not self.reverse_views:
                continue
            todo = self._unviewed_in_ref(seen, b)
            for v in self._views_found(b, ref, todo, self._pid.get(b)):
                out.setdefault(ref, []).append(v)
        # one feature id, one obstacle per camera: b's reported tracks change only now (the
        # reverse views take b's own grouper tracks, _unviewed_in_ref)
        for b, (n_found, views) in to_release.items():
            self._release_found(seen[b], n_found, views, b)
        if ref in out:
            self._drop_listed(seen[ref], out[ref])
        return out

    def _unviewed_in_ref(self, seen: dict[str, list[ObstacleTrack]], b: str) -> list[ObstacleTrack]:
        """Camera b's own confirmed grouper tracks (>= 3 members) whose global id has no track in
        the reference camera's ``seen`` list this frame."""
        key = (b, self._gid_version)
        hit = self._unviewed.get(key)
        if hit is not None and hit[0] is seen:
            return hit[1]
        ref = self.rig.cameras[0].name
        grouper = self.groupers.get(b)
        if grouper is None or not seen.get(b):
            return []
        gid = self._gid.get
        label = self.label
        own_tracks = grouper.tracks
        have_ref = {gid(t.id, t.id) for t in seen.get(ref, [])}
        out = [
            t
            for t in seen[b]
            if t.status == "confirmed"
            and t.label == label
            and len(t.members) >= 3
            and own_tracks.get(t.id) is t
            and gid(t.id, t.id) not in have_ref
        ]
        self._unviewed[key] = (seen, out)
        return out

    def _views_found(
        self, a: str, b: str, todo: list[ObstacleTrack], pid: dict[int, int] | None
    ) -> list[ObstacleTrack]:
        """Views in camera b of camera a's tracks ``todo`` from their members found in b's image by
        stereo KLT (``_stereo``) whose two rays agree with their track's depth (``_depth_consistent``):
        a track with >= 3 found gets one, bearing = mean of the found
        members' bearings plus a's offset of the representative point from its found members'
        mean, rotated into b (R_b_a); members: the found ones under their physical-point ids (a's
        ids through ``pid`` when a is not the reference camera)."""
        if not todo:
            return []
        ft = self.trackers[a]
        mem = np.concatenate([t.members for t in todo])
        own = np.repeat(np.arange(len(todo)), [len(t.members) for t in todo])
        rows, which = self._rows(ft, mem)
        own, mem = own[which], mem[which]
        idx, _, bb = self._stereo(a, b, rows)
        keep = self._depth_consistent(a, b, rows, own, idx, bb, len(todo))
        idx, bb = idx[keep], bb.compress(keep, 0)
        # idx is increasing and own non-decreasing along rows: each track's found members are
        # one run of idx; tracks with >= 3 found get a view
        cnt = np.bincount(own[idx], minlength=len(todo))
        ends = np.cumsum(cnt)
        good = (cnt >= 3).nonzero()[0]
        if not len(good):
            return []
        R_b_a = self._T_b_a[(a, b)].R
        gl, los, his = good.tolist(), (ends - cnt)[good].tolist(), ends[good].tolist()
        # rep_b = normalise(mean(b_b) + R_b_a (rep_a - mean(b_a))) for all good tracks at once: a mean is
        # the sum / n, the sums by bincount (row by row from 0.0: a slice's np.add.reduce's sums, where
        # np.add.reduceat's pairwise ones are not), R_b_a on each row by one broadcast matmul (a
        # matrix-vector product per row, as R_b_a @ v)
        own_f = own[idx]
        n_f = cnt[good][:, None]
        rep_a = np.array([todo[ti].b_C for ti in gl], float).reshape(-1, 3)
        mean_a = _bincount3(own_f, ft.b_C[rows[idx]], len(todo))[good] / n_f
        mean_b = _bincount3(own_f, bb, len(todo))[good] / n_f
        reps = mean_b + np.matmul(R_b_a, (rep_a - mean_a)[:, :, None])[:, :, 0]
        reps /= _norm_rows(reps, keepdims=True)
        uv, okp = self.cams[b].model.bearing_to_pixel(reps)
        found = mem[idx]
        if pid:  # under their physical-point ids
            found = _physical_ids(pid, found)
        out = []
        for k, (ti, lo, hi) in enumerate(zip(gl, los, his, strict=True)):
            if not okp[k]:
                continue
            tr = todo[ti]
            ids = found[lo:hi]
            v = ObstacleTrack(
                tr.id,
                b,
                ids,
                reps[k],
                uv=uv[k],
                sigma_rad=tr.sigma_rad,
                status=tr.status,
                label=tr.label,
                attributes=dict(tr.attributes),
                member_b_C=bb[lo:hi],
            )
            out.append(v)
        return out

    def _depth_consistent(
        self, a: str, b: str, rows: np.ndarray, own: np.ndarray, idx: np.ndarray, bb: np.ndarray, n: int
    ) -> np.ndarray:
        """Which of camera a's members ``rows[idx]`` found in camera b's image by stereo KLT (at
        bearings ``bb`` (J, 3) in C_b) are points of their track's obstacle by their two rays
        (trackers/association.py ``depth_consistent``): the depth extent allowed is the track's
        width, from its live members' angular radius in a (``own`` (K,): each row's track index
        of ``n``, non-decreasing), plus 3 px of bearing noise in b.

        Returns:
            (J,) bool, the found members kept.
        """
        keep = np.ones(len(idx), bool)
        if len(idx) < 3 or np.bincount(own[idx]).max() < 3:
            return keep  # no track has 3 found: none is judged
        b_a = self.trackers[a].b_C.take(rows, 0)
        # each track's angular radius: the largest angle of its members from their mean bearing
        sums = np.stack([np.bincount(own, b_a[:, k], minlength=n) for k in range(3)], axis=1)
        nrm = _norm_rows(sums, keepdims=True)
        mean = sums / np.where(nrm > 0, nrm, 1.0)
        ang = np.arccos(np.clip(np.sum(b_a * mean[own], axis=1), -1.0, 1.0))
        # own is non-decreasing: each track's rows are one run
        starts = np.concatenate(([True], own[1:] != own[:-1])).nonzero()[0]
        spread = np.zeros(n)
        spread[own[starts]] = np.maximum.reduceat(ang, starts)
        T = self._T_b_a[(a, b)]
        return depth_consistent(b_a[idx], bb, own[idx], T.R, T.t, spread, 3.0 * self._rad_px[b])

    def _add_found_members(self, seen: dict[str, list[ObstacleTrack]], ref: str, b: str) -> dict[int, int]:
        """Replace, in ``seen[b]``, camera b's grouper tracks that share a global id with a confirmed
        reference track by copies whose members also hold the reference members found in b's image
        by stereo KLT (ids: the reference ids; bearings: where KLT found them, (K, 3) unit in C_b).
        b's own members keep their ids mapped to the reference ones (``link_features``); a reference
        id already among them is not added twice.

        Returns:
            {index in ``seen[b]`` of a copy: how many found members end its member list}."""
        ft = self.trackers[ref]
        grouper = self.groupers.get(b)
        if grouper is None or not seen.get(b):
            return {}
        gid = self._gid.get
        label = self.label
        refs: dict[int, ObstacleTrack] = {}
        for t in seen[ref]:
            if t.status == "confirmed" and t.label == label and len(t.members) >= 3:
                refs.setdefault(gid(t.id, t.id), t)
        own_tracks = grouper.tracks
        slots = [
            (k, tb, refs[g])
            for k, tb in enumerate(seen[b])
            if (g := gid(tb.id, tb.id)) in refs
            and own_tracks.get(tb.id) is tb
            and len(tb.member_b_C) == len(tb.members)
        ]
        if not slots:
            return {}
        mem = np.concatenate([tr.members for _, _, tr in slots])
        own = np.repeat(np.arange(len(slots)), [len(tr.members) for _, _, tr in slots])
        rows, which = self._rows(ft, mem)
        own, mem = own[which], mem[which]
        idx, _, bb = self._stereo(ref, b, rows)
        if not len(idx):
            return {}
        pid = self._pid.get(b, {})
        # b's own members under their reference ids, all slots at once (run of slot si: lo..hi)
        tb_mem = [tb.members for _, tb, _ in slots]
        n_b = np.array([len(m) for m in tb_mem])
        allm = np.concatenate(tb_mem)
        if pid:
            allm = _physical_ids(pid, allm)
        slot_b = np.repeat(np.arange(len(slots)), n_b)
        # a reference id found by KLT is placed where KLT found it, also when one of b's members
        # is linked to it (descriptor links on a near object can pair neighbouring corners along
        # the epipolar line; KLT starts from the reference feature's own patch): b's member with a
        # (slot, id) among the found ones is dropped
        own_f = own[idx]  # non-decreasing: each slot's found members are one run
        found = mem[idx]
        key = np.int64(1) << 40
        keep_all = ~_isin(slot_b * key + allm, own_f * key + found)
        cnt_f = np.bincount(own_f, minlength=len(slots))
        end_f = np.cumsum(cnt_f)
        end_b = np.cumsum(n_b)
        n_found: dict[int, int] = {}
        for si, (k, tb, _) in enumerate(slots):
            if not cnt_f[si]:
                continue
            lo, hi = end_b[si] - n_b[si], end_b[si]
            flo, fhi = end_f[si] - cnt_f[si], end_f[si]
            keep = keep_all[lo:hi]
            v = _shallow_copy(tb)
            v.members = np.concatenate([allm[lo:hi][keep], found[flo:fhi]])
            v.member_b_C = np.concatenate([tb.member_b_C.compress(keep, 0), bb[flo:fhi]])
            seen[b][k] = v
            n_found[k] = int(fhi - flo)
        return n_found

    def _reported_views(self, trs: list[ObstacleTrack], done: set[int]) -> list[int]:
        """Indices into ``trs`` (one camera's tracks, in order) of the views ``_observations`` reports
        with feature ids: each global id's first track (``done``: the global ids already taken,
        updated), when it lists members with per-feature bearings."""
        gid = self._gid.get
        out = []
        for k, t in enumerate(trs):
            g = gid(t.id, t.id)
            if g in done:
                continue
            done.add(g)
            n = len(t.members)
            if n and len(t.member_b_C) == n:
                out.append(k)
        return out

    def _release_found(
        self, trs: list[ObstacleTrack], n_found: dict[int, int], derived: list[ObstacleTrack], b: str
    ) -> None:
        """One feature id, one obstacle per camera and frame, camera b's side: a reference member
        found in b's image by stereo KLT for its own obstacle's view (``_add_found_members``'
        copies, whose members at index k of ``trs`` = ``seen[b]`` end with ``n_found[k]`` found
        ones; ``derived``: ``_views_found``'s new views, all found) is that physical point in b, so
        b's own feature linked to the same reference id (``link_features``: a link between
        neighbouring corners along the epipolar line, or b grouped that point with another
        obstacle) leaves the other view it sits in. Only reported views (``_reported_views``) take
        part; a view that loses members is replaced in ``trs`` by a copy listing the rest under
        their reported ids, with their bearings (its own bearing unchanged). Two rays under one id
        would be fused as one point (docs/ARCHITECTURE.md). A reference id is found for one
        obstacle only (its reference track's), and b's features hold distinct reference ids, so
        nothing else lists an id twice in b."""
        done: set[int] = set()
        views = self._reported_views(trs, done)
        found = [derived[k].members for k in self._reported_views(derived, done)]
        parts = []  # (index in trs, own-part length): reported views with members of b's own
        for k in views:
            t = trs[k]
            n, nf = len(t.members), n_found.get(k, 0)
            if nf:
                found.append(t.members[n - nf :])
            if nf < n:
                parts.append((k, n - nf))
        if not found or not parts:
            return
        own = self.groupers[b].tracks
        pid = self._pid.get(b)
        # own parts under their reported ids (a grouper's own track through _pid, as _observations)
        ids = np.concatenate([trs[k].members[:m] for k, m in parts])
        if pid:
            mapped = [own.get(trs[k].id) is trs[k] for k, _ in parts]
            if any(mapped):
                need = np.repeat(mapped, [m for _, m in parts])
                ids[need] = _physical_ids(pid, ids[need])
        drop = _isin(ids, np.concatenate(found))
        if not drop.any():
            return
        ends = np.cumsum([m for _, m in parts])
        for pi in np.unique(np.searchsorted(ends, drop.nonzero()[0], side="right")).tolist():
            k, m = parts[pi]
            t = trs[k]
            lo, hi = int(ends[pi]) - m, int(ends[pi])
            keep = ~drop[lo:hi]
            v = _shallow_copy(t)
            v.members = np.concatenate([ids[lo:hi][keep], t.members[m:]])
            v.member_b_C = np.concatenate([t.member_b_C[:m].compress(keep, 0), t.member_b_C[m:]])
            trs[k] = v

    def _drop_listed(self, trs: list[ObstacleTrack], extra: list[ObstacleTrack]) -> None:
        """One feature id, one obstacle per camera and frame, the reference camera's side: the
        reverse views ``extra`` (``_views_found`` into the reference camera, members under their
        physical-point ids) drop the ids that the reference camera's reported views ``trs`` (its
        own tracks: a reference feature is its own obstacle's point) or an earlier reverse view
        already list. Only reported views take part (``_reported_views``); a view that loses
        members is replaced in ``extra`` by a copy without them (its bearing unchanged)."""
        done: set[int] = set()
        listed = [trs[k].members for k in self._reported_views(trs, done)]
        rev = self._reported_views(extra, done)
        if not rev:
            return
        ids = np.concatenate([extra[k].members for k in rev])
        drop = _isin(ids, np.concatenate(listed)) if listed else np.zeros(len(ids), bool)
        _, first = np.unique(ids, return_index=True)  # an id an earlier reverse view lists
        if len(first) < len(ids):
            later = np.ones(len(ids), bool)
            later[first] = False
            drop |= later
        if not drop.any():
            return
        ends = np.cumsum([len(extra[k].members) for k in rev])
        for ri in np.unique(np.searchsorted(ends, drop.nonzero()[0], side="right")).tolist():
            t = extra[rev[ri]]
            m = ~drop[int(ends[ri]) - len(t.members) : int(ends[ri])]
            v = _shallow_copy(t)
            v.members = t.members[m]
            v.member_b_C = t.member_b_C[m]
            extra[rev[ri]] = v

    def _gids_in(self, camera: str) -> set[int]:
        """The global ids of ``camera``'s live local tracks (grouped and box tracks)."""
        tracks = list(self.groupers[camera].tracks) if camera in self.groupers else []
        if camera in self.boxers:
            tracks += list(self.boxers[camera].tracks)
        return set(map(self._global, tracks))

    def _observations(
        self,
        seen: dict[str, list[ObstacleTrack]],
        lost: list[ObstacleTrack],
        absorbed: list[int],
        frame: int,
        t_s: float,
    ) -> list[ObstacleObservation]:
        gid_of = self._gid.get
        # an id once reported lost is never reported again: tracks that would be reported under one (a
        # give-back of _box_keeps_id / _box_hands_id: an id lent or handed, and merged away, comes back
        # to its own tracks) take a fresh id together; the fusion sees a new track (a new filter)
        back = {gid_of(tr.id, tr.id) for trs in seen.values() for tr in trs} & self._ended
        for g in sorted(back):
            lids = {tr.id for trs in seen.values() for tr in trs if gid_of(tr.id, tr.id) == g}
            for d in (*self.groupers.values(), *self.boxers.values()):
                lids.update(lid for lid in d.tracks if gid_of(lid, lid) == g)
            self._merge_gids(next(self._track_ids), g, tuple(sorted(lids)), absorbed)
        groups: dict[int, list[ObstacleTrack]] = {}
        for name in self.cams:
            for tr in seen.get(name, ()):
                g = gid_of(tr.id, tr.id)
                if g in groups:
                    groups[g].append(tr)
                else:
                    groups[g] = [tr]
        no_b, no_ids = np.zeros((0, 3)), np.zeros(0, np.int64)
        own_tracks = {n: g.tracks for n, g in self.groupers.items()}
        out: list[ObstacleObservation] = []
        for gid in sorted(groups):
            trs = groups[gid]
            views, done = [], set()
            confirmed = False
            attrs: dict[str, Any] = {}
            for tr in trs:
                confirmed = confirmed or tr.status == "confirmed"
                attrs.update(tr.attributes)
                cam = tr.camera
                if cam in done:
                    continue
                done.add(cam)
                n_m = len(tr.members)
                if len(tr.member_b_C) == n_m:
                    fb, fi = tr.member_b_C, tr.members
                else:
                    fb, fi = no_b, no_ids
                pid = self._pid.get(cam)
                if pid and len(fi) and cam in own_tracks and own_tracks[cam].get(tr.id) is tr:
                    fi = _physical_ids(pid, fi)
                f = self.scale[cam]
                views.append(
                    CameraView(
                        camera=cam,
                        b_C=tr.b_C,
                        uv=tr.uv if f == 1.0 or tr.uv is None else (tr.uv + 0.5) / f - 0.5,
                        sigma_rad=tr.sigma_rad,
                        feature_ids=fi,
                        feature_b_C=fb,
                    )
                )
            out.append(
                ObstacleObservation(
                    gid,
                    frame,
                    t_s,
                    "confirmed" if confirmed else "tentative",
                    tuple(views),
                    label=trs[0].label,
                    attributes=attrs,
                )
            )
        self._reported.update(groups)
        live = set(groups)
        for name in self.cams:  # global ids with a coasting local track are not lost yet
            for d in (self.groupers.get(name), self.boxers.get(name)):
                if d is not None:
                    live.update(map(gid_of, d.tracks, d.tracks))
        gone = {self._global(tr.id): tr for tr in lost}
        for tr in lost:
            self._gid.pop(tr.id, None)
        for gid in sorted(set(gone) | set(absorbed)):
            if gid in live and gid not in absorbed:
                continue
            if gid in self._reported:
                lbl = gone[gid].label if gid in gone else self.label
                into = gid
                while into in self._merged_into:
                    into = self._merged_into[into]
                extra = {"merged_into": into} if gid in absorbed and into != gid else {}
                out.append(ObstacleObservation(gid, frame, t_s, "lost", (), label=lbl, attributes=extra))
                self._reported.discard(gid)
                self._ended.add(gid)
        if len(self._ended) > 4096:  # keep the ended ids a track may still come back under
            refs = set(self._gid.values()).union(*(h.values() for h in self._box_handed.values()))
            for d in (*self.groupers.values(), *self.boxers.values()):
                refs.update(d.tracks)
            self._ended &= refs
        return out
