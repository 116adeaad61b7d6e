"""Cross-camera association: one obstacle seen by several cameras becomes one track.

Member features of the cameras' tracks are matched by ORB descriptor (Hamming distance, mutual best,
Lowe ratio) and a match must satisfy the rig's epipolar constraint on the sphere: with
``T_C1_C0 = T_C1_B T_C0_B^-1 = (R, t)``, a point seen along b0 from camera 0 and along b1 from
camera 1 satisfies ``b1 . (t x R b0) = 0`` (coplanarity); we accept
``|b1 . (t_hat x R b0)| / |t_hat x R b0| < sin(epipolar_rad)`` and ahead-of-both-cameras geometry.
Two tracks are linked when at least ``min_votes`` such matches join them and each is the other's
best partner.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# np.cross and np.linalg.norm (of a vector or of rows) bit for bit, without their axis handling
from estimators.cameras import _tangent_basis
from estimators.geometry import _cross, _isin, _norm, _norm_rows
from trackers.features import KLT_WIN_PX, _lk_part, _lk_whole


def epipolar_residual(b0: np.ndarray, b1: np.ndarray, R_C1_C0: np.ndarray, t_C1_C0: np.ndarray) -> np.ndarray:
    """Sine of the angle of b1 out of the epipolar plane of b0.

    Args:
        b0: (N, 3) unit bearings in camera 0; b1: (N, 3) unit bearings in camera 1 (row-paired).
        R_C1_C0: (3, 3), t_C1_C0: (3,) metres, with p_C1 = R p_C0 + t.
    Returns:
        (N,) ``|b1 . n| / |n|`` with ``n = t_hat x R b0`` the epipolar plane's normal in camera 1
        (1 where the plane is undefined: b0 along the baseline).
    """
    t = np.asarray(t_C1_C0, float)
    tn = _norm(t)
    if tn == 0:
        return _norm_rows(_cross(b1, b0 @ np.asarray(R_C1_C0).T))  # pure rotation: rays equal
    n = _cross(t / tn, b0 @ np.asarray(R_C1_C0).T)
    nn = _norm_rows(n)
    res = np.abs(np.add.reduce(b1 * n, axis=1)) / np.where(nn > 1e-9, nn, 1.0)
    return np.where(nn > 1e-9, res, 1.0)


def match_features(
    b0: np.ndarray,
    d0: np.ndarray,
    b1: np.ndarray,
    d1: np.ndarray,
    R_C1_C0: np.ndarray,
    t_C1_C0: np.ndarray,
    epipolar_rad: float = np.radians(1.0),
    max_hamming: int = 64,
    ratio: float = 0.9,
) -> np.ndarray:
    """Descriptor matches between two cameras' features that satisfy the epipolar constraint and
    whose rays meet ahead of both cameras (within ``epipolar_rad``).

    Args:
        b0, b1: (N0, 3), (N1, 3) unit bearings in cameras 0 and 1; d0, d1: their (N, 32) uint8 ORB
            descriptors (any uint8 width; read 64 bits at a time when it is a multiple of 8 bytes).
        R_C1_C0, t_C1_C0: camera 0 -> camera 1 transform (p_C1 = R p_C0 + t, metres).
        epipolar_rad: largest angle of b1 out of b0's epipolar plane.
        max_hamming: largest descriptor distance, a whole number of bits (of 256: it is one digit
            of the integer sort keys); ratio: Lowe's ratio test.
    Returns:
        (K, 2) int index pairs (i0, i1), mutual best among the epipolar-consistent candidates.
    """
    n0, n1 = len(b0), len(b1)
    if not n0 or not n1:
        return np.zeros((0, 2), np.intp)
    # epipolar residual of every pair: |b1 . n_i| / |n_i| (in place on the (N0, N1) products)
    t = np.asarray(t_C1_C0, float)
    tn = _norm(t)
    Rb0 = b0 @ np.asarray(R_C1_C0).T
    if tn > 0:
        n = _cross(t / tn, Rb0)
        nn = _norm_rows(n)
        res = n @ b1.T
        np.abs(res, out=res)
        res /= np.where(nn > 1e-9, nn, 1.0)[:, None]
        sin_eps = np.sin(epipolar_rad)
        ok = res < sin_eps
        # both rays on the same side (for baselines much shorter than the range)
        c = Rb0 @ b1.T
        ok &= c > 0
        ok[nn <= 1e-9] = False  # b0 along the baseline: residual 1, never below sin(epipolar_rad)
        # the rays meet ahead of both cameras (t + s R b0 = u b1 with s, u > 0): camera 1 sees the
        # point on the arc of the epipolar plane from R b0 (infinite depth) to t_hat (the epipole),
        # so b1 . e >= 0 and b1 . f >= 0 with e, f the plane's unit vectors square to R b0 and to
        # t_hat that point into the arc (e = (t_hat - g R b0) / |n|, f = (R b0 - g t_hat) / |n|,
        # g = t_hat . R b0), each within the epipolar angle (noise at infinite depth). The same-side
        # test alone lets diverging rays through where the baseline lies along the rays: on a
        # top/bottom rig a feature 60 deg above the horizon in the up camera and one 18 deg below it
        # in the down camera share an epipolar plane (docs/ARCHITECTURE.md "The 360-degree rig")
        t_hat = t / tn
        g = (Rb0 @ t_hat)[:, None]
        tb1 = t_hat @ b1.T
        inv_n = 1.0 / np.where(nn > 1e-9, nn, 1.0)[:, None]
        ok &= (tb1 - g * c) * inv_n >= -sin_eps
        ok &= (c - g * tb1) * inv_n >= -sin_eps
    else:
        ok = (Rb0 @ b1.T) > np.cos(epipolar_rad)
    # descriptor distances only for the epipolar candidates (i0, i1), row-major
    f = np.flatnonzero(ok)  # (ok is (n0, n1): flat, row-major indices)
    ii = f // n1
    jj = f - ii * n1
    # Hamming distance = popcount(d0 XOR d1), 64 bits at a time (ORB's 32 bytes: 4 words)
    w0, w1 = np.ascontiguousarray(d0, np.uint8), np.ascontiguousarray(d1, np.uint8)
    if w0.shape[1] % 8 == 0:
        w0, w1 = w0.view(np.uint64), w1.view(np.uint64)
    h = np.bitwise_count(w0.take(ii, 0) ^ w1.take(jj, 0)).sum(axis=1, dtype=np.int64)
    k = (h <= max_hamming).nonzero()[0]
    if not len(k):
        return np.zeros((0, 2), np.intp)
    ii, jj, h = ii[k], jj[k], h[k]
    hb = np.int64(max_hamming + 1)  # distances are 0..max_hamming: one digit of a sort key
    # per i0: its best i1 (least distance, ties: least i1) and its second least distance, from the
    # candidates sorted by the key (i0, distance, i1)
    key = np.sort((ii * hb + h) * n1 + jj)
    ri = key // (hb * n1)
    rh = key // n1 - ri * hb
    first = np.concatenate(([True], ri[1:] != ri[:-1])).nonzero()[0]
    i = ri[first]
    j = key[first] % n1
    best = rh[first]
    nxt = first + 1
    has2 = np.concatenate((first[1:], [len(ri)])) > nxt
    second = np.where(has2, rh[np.minimum(nxt, len(ri) - 1)], np.inf)
    # per i1: its best i0 (least distance, ties: least i0), keys (i1, distance, i0)
    ck = np.sort((jj * hb + h) * n0 + ii)
    cf = np.concatenate(([True], ck[1:] // (hb * n0) != ck[:-1] // (hb * n0))).nonzero()[0]
    i_back = np.full(n1, -1, np.int64)
    i_back[ck[cf] // (hb * n0)] = ck[cf] % n0
    # mutual best, and Lowe's ratio test: best <= ratio * second
    good = (i_back[j] == i) & (best <= ratio * second + 1e-9)
    return np.stack([i[good], j[good]], axis=1)


#: Inverse ranges times the baseline (w |t|) at which a new stereo row's epipolar curve (R b_a + w t
#: projected) is sampled for the part its search runs on (``stereo_klt``). A sample lies atan(w |t|)
#: off the infinite-depth start for a ray square to the baseline (the last: 1.01 rad, 130 px at 129
#: px/rad, 196 px at 194), nearer for a ray toward the baseline's direction (0.51 rad at 47 deg), whose
#: curve goes on to the epipole: up to ~60 px of a 160-px reach's curve lie past the last sample. They
#: are inside the part's margin (window + BAND_SLACK, 208 px at maxLevel 4), and the coarsest windows
#: there (~126 px around a point: 96 of window, 30 of pyramid filter) read the whole image's pixels
#: up to ~80 px past a sample.
EPIPOLAR_STEPS = (0.0, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6)


class StereoKLT(NamedTuple):
    """Result of ``stereo_klt``: the rows found and where.

    Attributes:
        idx: (K,) int rows of the input bearings found in camera b.
        uv_b: (K, 2) float px, full-frame pixels in b; b_b: (K, 3) unit bearings in C_b.
        checked: (K,) bool, whether the forward-backward check ran on that row this call.
    """

    idx: np.ndarray
    uv_b: np.ndarray
    b_b: np.ndarray
    checked: np.ndarray


def stereo_klt(
    grey_a: np.ndarray,
    grey_b: np.ndarray,
    b_a: np.ndarray,
    uv_a: np.ndarray,
    model_b,
    R_b_a: np.ndarray,
    t_b_a: np.ndarray,
    epipolar_rad: float = np.radians(1.0),
    win_px: int = KLT_WIN_PX,
    levels: int = 4,
    fb_max_px: float = 1.0,
    off_a: np.ndarray | None = None,
    off_b: np.ndarray | None = None,
    guess_b: np.ndarray | None = None,
    check: np.ndarray | None = None,
    recheck_px: float = 1.0,
    follow_levels: int | None = None,
    crop: bool = True,
) -> StereoKLT:
    """Find camera a's features in camera b's image by KLT, checked by the epipolar constraint and
    (where needed) forward-backward. One forward KLT call per pyramid depth (rows with their own
    guess, a match followed over frames, at ``follow_levels``; the others, from their
    infinite-depth projection, at ``levels``).

    Args:
        grey_a, grey_b: (H, W) uint8 frames of cameras a and b (same time).
        b_a: (N, 3) unit bearings in C_a; uv_a: (N, 2) their pixels in a.
        model_b: camera b's CameraModel; R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
        win_px: the KLT window (px): the front end passes camera a's FeatureTracker window, so the
            stereo match is the temporal track's window (``trackers.frontend.tracked_window``).
        off_a, off_b: (2,) px, when grey_a / grey_b are crops of the full frames: the crops'
            origins in the full frames (full-frame pixel = crop pixel + origin); uv_a and the
            returned uv_b are full-frame pixels either way.
        guess_b: (N, 2) full-frame px in b where each row is expected (e.g. last frame's match
            moved by the feature's motion in a); NaN rows (or None: all) start from the
            infinite-depth projection of b_a.
        check: (N,) bool, rows that get the backward check whatever happens (None: all). A row
            with a finite guess whose forward result lands more than ``recheck_px`` from it is
            checked too; every other row is kept on the forward result and the epipolar test.
        follow_levels: OpenCV maxLevel of the forward pass for rows with a finite guess (maxLevel
            n searches n + 1 pyramid levels; a followed match starts within a pixel or two of its
            answer, so it needs no coarse levels); the other rows use ``levels`` (also a maxLevel).
            None: ``levels`` for all rows (one call).
        crop: run each KLT call on a part of the two images (``_lk_part``: the box of the points
            with the windows' margin and the search's reach; a call of new rows only and the
            backward check on a part around their epipolar curves and paths back, ``band``), for a
            fraction of the pyramid-building cost. The answers are the whole images' but for LK's
            last float32 bits (it works relative to the part's origin) and a search that strays
            from where it is expected (it reads the part's edge); False: on the whole images.
    Returns:
        ``StereoKLT`` (idx, uv_b, b_b, checked).
    """
    import cv2

    n = len(b_a)
    empty = StereoKLT(np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0, bool))
    if not n:
        return empty
    # a point far away is seen along R b_a from camera b: the start of the search
    start = np.zeros((n, 2))
    ok = np.ones(n, bool)
    own = np.zeros(n, bool) if guess_b is None else np.isfinite(np.asarray(guess_b, float)).all(axis=1)
    if own.any():
        start[own] = np.asarray(guess_b, float)[own]
    curve = np.full((n, len(EPIPOLAR_STEPS), 2), np.nan)  # each new row's epipolar curve in b
    if not own.all():
        inf = (~own).nonzero()[0]
        d = b_a[inf] @ np.asarray(R_b_a).T
        t = np.asarray(t_b_a, float).reshape(3)
        base = _norm(t)
        if crop and base > 0:
            # the start and where the point projects nearer than infinity, in one call (each row is
            # projected on its own): R b_a + w t at the inverse ranges w (1/m) of EPIPOLAR_STEPS
            k = len(EPIPOLAR_STEPS)
            X = np.empty((len(inf), k, 3))
            X[:, 0] = d  # (w = 0: the start, R b_a itself)
            X[:, 1:] = d[:, None, :] + (np.asarray(EPIPOLAR_STEPS[1:]) / base)[:, None] * t
            c, ok_c = model_b.bearing_to_pixel(X.reshape(-1, 3))
            g, ok_inf = c[::k].copy(), ok_c[::k].copy()
            c[~ok_c] = np.nan
            curve[inf] = c.reshape(len(inf), k, 2)
        else:
            g, ok_inf = model_b.bearing_to_pixel(d)
        start[inf] = g
        ok[inf] = ok_inf
    idx = ok.nonzero()[0]
    if not len(idx):
        return empty
    oa = np.zeros(2) if off_a is None else np.asarray(off_a, float).reshape(2)
    ob = np.zeros(2) if off_b is None else np.asarray(off_b, float).reshape(2)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)
    p0 = (uv_a[idx] - oa).reshape(-1, 1, 2).astype(np.float32)
    p1 = (start[idx] - ob).reshape(-1, 1, 2).astype(np.float32)
    st = np.zeros(len(idx), np.uint8)
    # one forward call per pyramid depth: followed rows (own guess) at follow_levels, others at levels
    near = own[idx] if follow_levels is not None and follow_levels < levels else np.zeros(len(idx), bool)
    for rows, lv in ((near.nonzero()[0], follow_levels), ((~near).nonzero()[0], levels)):
        if not len(rows):
            continue
        # on the parts of the images the search reads (_lk_part, its reach what the coarsest
        # level's window covers): a followed row starts within a pixel or two of its answer, a new
        # one anywhere along its epipolar curve within that reach (the part: around the curves,
        # ``band``, when the call holds new rows only)
        band = None
        if crop and not own[idx[rows]].any():
            band = np.concatenate([p1[rows].reshape(-1, 2), curve[idx[rows]].reshape(-1, 2) - ob])
        q, s_q, _ = _lk_part(grey_a, grey_b, p0[rows], p1[rows], win_px, lv, crit, band=band) if crop else (
            _lk_whole(grey_a, grey_b, p0[rows], p1[rows], win_px, lv, crit)
        )
        p1[rows] = q
        st[rows] = s_q
    good = st == 1
    uv_b = p1.reshape(-1, 2).astype(float) + ob
    # the backward check: rows asked for, and followed rows that did not land where expected
    chk = np.ones(len(idx), bool) if check is None else np.asarray(check, bool)[idx].copy()
    chk |= ~own[idx]
    chk |= own[idx] & (_norm_rows(uv_b - start[idx]) > recheck_px)
    # the lens and epipolar tests of the forward results first (row by row: the same numbers on
    # the rows KLT found as on all), so the backward check runs only on rows that can pass them
    box = chk & good  # the rows to check: their box makes the backward call's parts
    g = good.nonzero()[0]
    bb = np.zeros((len(idx), 3))
    bb_g, okb = model_b.pixel_to_bearing(uv_b[g])
    bb[g] = bb_g
    good[g] = okb & (epipolar_residual(b_a[idx[g]], bb_g, R_b_a, t_b_a) < np.sin(epipolar_rad))
    ci = (chk & good).nonzero()[0]
    if len(ci):
        p1c, p1b = p1.take(ci, 0), p1.compress(box, 0)
        # backward: from the forward result in b, starting at the same pixel in a (in the parts of
        # the images all rows to check would read: the same numbers as a call on all of them)
        # (its part: around the straight paths from those starts to the rows' own pixels in a, where
        # a good match returns)
        p0r, st2, _ = _lk_part(
            grey_b, grey_a, p1c, p1c, win_px, levels, crit, box_prev=p1b,
            band=np.concatenate([p1b, p0.compress(box, 0)]).reshape(-1, 2),
        ) if crop else _lk_whole(grey_b, grey_a, p1c, p1c, win_px, levels, crit)
        good[ci] &= (st2 == 1) & (
            _norm_rows((p0r - p0.take(ci, 0)).reshape(-1, 2)) <= fb_max_px
        )
    return StereoKLT(idx[good], uv_b.compress(good, 0), bb.compress(good, 0), chk[good])


#: Stereo KLT follows translation only: a camera pair where some feature's patch turns by more than
#: this (degrees, ``patch_turn_deg``) from camera a's image to camera b's is searched in b's image
#: resampled into a's geometry (``TurnedPair``). On the top/bottom rig a point on the horizon at
#: azimuth psi from the nose turns by 180 - 2 psi (the down camera's image is the up camera's
#: mirrored, its radius reflected about the horizon's circle): only abeam does it keep its
#: orientation, and plain KLT found none of top_bottom_turn's sphere members in the other camera
#: (docs/ARCHITECTURE.md "The 360-degree rig"). A pair with parallel axes and one model turns by 0.
TURNED_DEG = 30.0


def patch_jacobian(model_a, model_b, b_a: np.ndarray, R_b_a: np.ndarray) -> np.ndarray:
    """The local map of camera a's image onto camera b's at each feature, d uv_b / d uv_a, for a
    point far away (seen along R_b_a b_a from b; the baseline moves a near one, not its patch's shape).

    Args:
        model_a, model_b: the cameras' CameraModels; b_a: (N, 3) unit bearings in C_a; R_b_a (3, 3).
    Returns:
        (N, 2, 2) px per px; NaN rows where either camera does not see the direction.
    """
    b_a = np.asarray(b_a, float).reshape(-1, 3)
    R = np.asarray(R_b_a, float)
    # a tangent basis E (3, 2) at b_a: a step E c moves uv_a by P_a E c and uv_b by P_b R E c
    E = _tangent_basis(b_a)
    A = model_a.bearing_to_pixel_jacobian(b_a) @ E
    B = model_b.bearing_to_pixel_jacobian(b_a @ R.T) @ (R @ E)
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    ok = (np.abs(det) > 1e-12) & np.any(B != 0, axis=(1, 2))
    J = np.full((len(b_a), 2, 2), np.nan)
    if ok.any():
        J[ok] = B[ok] @ np.linalg.inv(A[ok])
    return J


def patch_turn_deg(J: np.ndarray) -> np.ndarray:
    """(N,) degrees in [-180, 180]: the rotation of the local maps J (N, 2, 2) (their polar
    decomposition's, atan2(J10 - J01, J00 + J11)); NaN where J is."""
    J = np.asarray(J, float).reshape(-1, 2, 2)
    return np.degrees(np.arctan2(J[:, 1, 0] - J[:, 0, 1], J[:, 0, 0] + J[:, 1, 1]))


def pair_turns(model_a, model_b, R_b_a: np.ndarray, step_px: int = 16) -> bool:
    """Whether some feature's patch turns by more than ``TURNED_DEG`` from camera a's image to camera
    b's (``patch_turn_deg`` at a's pixels every ``step_px`` px whose direction b sees)."""
    v, u = np.mgrid[0 : model_a.height : step_px, 0 : model_a.width : step_px]
    b, ok = model_a.pixel_to_bearing(np.stack([u.ravel(), v.ravel()], 1).astype(float))
    if not ok.any():
        return False
    turn = patch_turn_deg(patch_jacobian(model_a, model_b, b[ok], R_b_a))
    return bool(np.any(np.abs(turn) > TURNED_DEG))  # (NaN where b does not see it: False)


class TurnedPair:
    """Stereo KLT of camera a's features in camera b's image for a pair whose images turn a patch
    (``pair_turns``): b's lens crop is resampled into a's crop geometry, the view of a virtual camera
    b' at b's centre with a's orientation and a's model, in which a far point sits at its pixel in a
    and a near one moves along its epipolar curve by the parallax only, as between parallel cameras:
    there ``stereo_klt`` (translation only) holds. Its matches are mapped back to b's pixels and
    bearings through the models (not through the resampled image).

    Args:
        model_a, model_b: the cameras' CameraModels; R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
        shape_a: (h, w) of a's crop, off_a: its origin in a's frame; off_b: b's crop's origin in b's.
    """

    def __init__(self, model_a, model_b, R_b_a, t_b_a, shape_a, off_a, off_b) -> None:
        import cv2

        self.model_a, self.model_b = model_a, model_b
        self.R = np.asarray(R_b_a, float)
        self.t_v = self.R.T @ np.asarray(t_b_a, float).reshape(3)  # p_Cb' = p_Ca + R^T t
        h, w = shape_a
        v, u = np.mgrid[0:h, 0:w]
        uv = np.stack([u.ravel(), v.ravel()], 1).astype(float) + np.asarray(off_a, float).reshape(2)
        b, ok = model_a.pixel_to_bearing(uv)
        uv_b, ok_b = model_b.bearing_to_pixel(b[ok] @ self.R.T)
        # only a's pixels whose direction b sees are resampled (top_bottom_turn: 19 % of the crop),
        # their maps laid out in rows of 1024 (fixed point: 16SC2)
        self._idx = ok.nonzero()[0][ok_b]
        n = len(self._idx)
        m = np.zeros((-(-n // 1024) * 1024, 2), np.float32)
        m[:n] = uv_b[ok_b] - np.asarray(off_b, float).reshape(2)
        m = m.reshape(-1, 1024, 2)
        self._maps = cv2.convertMaps(m[..., 0], m[..., 1], cv2.CV_16SC2)

    def resample(self, grey_a: np.ndarray, grey_b: np.ndarray) -> np.ndarray:
        """b's crop (uint8) seen by b', an image of a's crop's size, and a's crop ``grey_a`` where b
        does not see: b's black beyond its field would be an edge in the coarse pyramid levels that
        draws KLT's search off (top_bottom_turn: maxLevel 4 sent the sphere's members 200-700 px
        away). ~1 ms a frame and pair at 948x948 px (a remap of the whole crop: ~2.7)."""
        import cv2

        seen = cv2.remap(grey_b, *self._maps, cv2.INTER_LINEAR).reshape(-1)
        out = grey_a.copy()
        out.reshape(-1)[self._idx] = seen[: len(self._idx)]
        return out

    def to_virtual(self, uv_b: np.ndarray) -> np.ndarray:
        """(N, 2) full-frame px in b -> in b' (the same directions); NaN where either does not see."""
        bb, ok = self.model_b.pixel_to_bearing(np.asarray(uv_b, float).reshape(-1, 2))
        uv, okv = self.model_a.bearing_to_pixel(bb @ self.R)
        return np.where((ok & okv)[:, None], uv, np.nan)

    def stereo_klt(self, grey_a, b_in_a, b_a, uv_a, guess_v=None, **kw) -> StereoKLT:
        """``stereo_klt`` of a's features b_a (N, 3) at uv_a (N, 2) in b' (``b_in_a``: ``resample`` of
        b's crop; ``guess_v``: (N, 2) full-frame px in b', NaN rows: none), other keywords as
        ``stereo_klt``'s (its off_b is a's crop's origin here). Rows whose direction b does not see
        are not searched. Returns its ``StereoKLT`` in b: idx into the N rows, uv_b full-frame px in
        b, b_b unit bearings in C_b, checked."""
        _, seen = self.model_b.bearing_to_pixel(np.asarray(b_a, float) @ self.R.T)
        rows = seen.nonzero()[0]
        g = None if guess_v is None else np.asarray(guess_v, float)[rows]
        r = stereo_klt(
            grey_a, b_in_a, b_a[rows], uv_a[rows], self.model_a, np.eye(3), self.t_v, guess_b=g,
            **{k: (v[rows] if k == "check" and v is not None else v) for k, v in kw.items()},
        )
        b_b = r.b_b @ self.R.T
        uv_b, ok = self.model_b.bearing_to_pixel(b_b)
        return StereoKLT(rows[r.idx[ok]], uv_b[ok], b_b[ok], r.checked[ok])


def depth_consistent(
    b_a: np.ndarray,
    b_b: np.ndarray,
    owner: np.ndarray,
    R_b_a: np.ndarray,
    t_b_a: np.ndarray,
    spread_rad: np.ndarray,
    noise_rad: float,
    min_found: int = 3,
) -> np.ndarray:
    """Which stereo-KLT matches of one obstacle's features can be points of that one obstacle,
    judged from this frame's two rays of each (valid for a moving obstacle too).

    Each match's range along camera a's ray is where it passes closest to camera b's ray (in C_b:
    t + s d and u b_b with d = R b_a, c = d . b_b, e = b_b . t):
        s = (c e - d . t) / (1 - c^2),   inverse range w = 1 / s = (1 - c^2) / (c e - d . t).
    The points of an obstacle about as deep as it is wide lie within D = 2 rho r of the median
    member's range r (rho: the members' angular radius seen from a, so 2 rho r its width), so
    their inverse ranges lie within
        |w - w_med| <= w_med 2 rho / (1 - 2 rho)                (no bound once 2 rho >= 1)
    of the median's (D / r^2 for D << r), plus the bearing noise: an error of noise_rad on one
    ray moves w by noise_rad / (|t| sin gamma), gamma the angle between a's ray and the baseline.
    A match outside that is kept when another match of the group agrees with it within the two
    rays' noise: a surface of its own (a group holding a nearer obstacle's features beside a
    farther one's, or the background's). A match on another point of a repeated texture meets b's
    ray far off and alone (1.4 m beside 3.8 m on a sphere at 3.5 m) and is dropped. Groups with
    fewer than ``min_found`` matches are kept as they are (no median).

    Args:
        b_a: (K, 3) unit bearings of the matched features in C_a; b_b: (K, 3) unit bearings where
            stereo KLT found them in C_b (row-paired).
        owner: (K,) int, non-decreasing: each match's obstacle (group) index into ``spread_rad``.
        R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
        spread_rad: (G,) rad, each obstacle's members' largest angle from their mean bearing in C_a.
        noise_rad: bearing noise allowed on a ray (rad), e.g. a few pixels' angle.
        min_found: smallest group judged.
    Returns:
        (K,) bool, the matches kept.
    """
    b_a = np.asarray(b_a, float).reshape(-1, 3)
    b_b = np.asarray(b_b, float).reshape(-1, 3)
    owner = np.asarray(owner, np.intp).reshape(-1)
    keep = np.ones(len(b_a), bool)
    t = np.asarray(t_b_a, float).reshape(3)
    base = _norm(t)
    if len(b_a) < min_found or base <= 0:
        return keep
    d = b_a @ np.asarray(R_b_a, float).T
    c = np.add.reduce(d * b_b, axis=1)
    den = c * (b_b @ t) - d @ t  # s (1 - c^2)
    # w = (1 - c^2) / den; parallel rays (den ~ 0): a point at infinity, w = 0
    w = np.divide(1.0 - c * c, den, out=np.zeros_like(den), where=np.abs(den) > 1e-12)
    # noise: noise_rad / (|t| sin gamma), sin gamma = |t_hat x d| (at least 0.1: rays along the
    # baseline range nothing)
    sin_g = np.maximum(_norm_rows(_cross(t / base, d)), 0.1)
    noise = noise_rad / (base * sin_g)
    ext = 2.0 * np.asarray(spread_rad, float)
    starts = np.concatenate(([True], owner[1:] != owner[:-1])).nonzero()[0]
    cnt = np.diff(np.append(starts, len(owner)))
    x = ext[owner[starts]]
    judged = (cnt >= min_found) & (x < 1.0)  # x >= 1: as deep as its range, any range in front
    if not judged.any():
        return keep
    # the judged groups' rows, each group one run (owner is non-decreasing)
    g_start, g_cnt, g_x = starts[judged], cnt[judged], x[judged]
    run = np.repeat(np.arange(len(g_cnt)), g_cnt)  # each judged row's group
    off = np.cumsum(g_cnt) - g_cnt
    rows = np.repeat(g_start, g_cnt) + np.arange(len(run)) - off[run]
    wg, ng = w[rows], noise[rows]
    # each group's median (np.median's: the middle value, or the mean of the two middle ones)
    srt = wg[np.lexsort((wg, run))]
    w_med = (srt[off + (g_cnt - 1) // 2] + srt[off + g_cnt // 2]) / 2
    xr = g_x[run]
    near_med = np.abs(wg - w_med[run]) <= np.abs(w_med[run]) * xr / (1.0 - xr) + ng
    keep[rows] = near_med
    # off the median's bound, a surface of its own (a nearer obstacle grouped with a farther one,
    # the background): another match of its group agrees with it within the two rays' noise
    out = (~near_med).nonzero()[0]
    if len(out):
        c = g_cnt[run[out]]
        pi = np.repeat(out, c)  # each such match against every match of its group
        pj = np.repeat(off[run[out]], c) + np.arange(len(pi)) - np.repeat(np.cumsum(c) - c, c)
        agree = np.abs(wg[pi] - wg[pj]) <= ng[pi] + ng[pj]
        support = np.bincount(pi, agree, minlength=len(run))[out]  # itself included
        keep[rows[out]] = support >= 2
    return keep


def klt_links(d2_px2: np.ndarray, link_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (KLT-found point, other camera's feature) that name one physical point.

    A feature of camera a found in camera b's image by stereo KLT (``stereo_klt``: forward-backward
    and epipolar checked) lands on camera b's own feature of that point when b tracks it. A pair is
    kept when each is the other's nearest, their distance is at most ``link_px`` and no other of
    b's features (nor another found point) lies within ``2 link_px`` (unambiguous).

    Args:
        d2_px2: (K, M) squared pixel distances between K found points in b and b's M features.
        link_px: largest distance, pixels of b's tracked image.
    Returns:
        (i (J,) rows of the found points, j (J,) columns of b's features), row-paired.
    """
    d2 = np.asarray(d2_px2, float)
    if not d2.size:
        return np.zeros(0, np.intp), np.zeros(0, np.intp)
    r2 = link_px**2
    j = np.argmin(d2, axis=1)
    i = np.arange(len(d2))
    best = d2[i, j]
    mutual = np.argmin(d2, axis=0)[j] == i
    # ambiguity: a second candidate within 2 link_px on either side
    near = d2 <= 4 * r2
    unique = (near.sum(axis=1) == 1) & (near.sum(axis=0)[j] == 1)
    keep = (best <= r2) & mutual & unique
    return i[keep], j[keep]


def consistent_pairs(ids_a: np.ndarray, ids_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct id pairs in which every id has one partner only.

    Args:
        ids_a, ids_b: (K,) int feature ids of cameras a and b, row-paired (possibly repeated pairs
            from several matchers).
    Returns:
        (ids_a (J,), ids_b (J,)): the unique pairs, minus those whose a id or b id is paired with
        another partner too (conflicting evidence links nothing).
    """
    ia = np.asarray(ids_a, np.int64).reshape(-1)
    ib = np.asarray(ids_b, np.int64).reshape(-1)
    if not len(ia):
        return ia, ib
    # the distinct pairs, sorted by (a, b) (np.unique of the (K, 2) rows, without its axis path)
    o = np.lexsort((ib, ia))
    a, b = ia[o], ib[o]
    first = np.empty(len(a), bool)
    first[0] = True
    np.not_equal(a[1:], a[:-1], out=first[1:])
    first[1:] |= b[1:] != b[:-1]
    a, b = a[first], b[first]
    # each a id's partners: its run's length (a is sorted); each b id's: its count in sorted b
    sa = np.concatenate(([True], a[1:] != a[:-1])).nonzero()[0]
    cnt_a = np.diff(np.append(sa, len(a)))
    bs = np.sort(b)
    one_b = np.searchsorted(bs, b, "right") - np.searchsorted(bs, b, "left") == 1
    ok = np.repeat(cnt_a == 1, cnt_a) & one_b
    return a[ok], b[ok]


def unheld(members: list[np.ndarray], held_ids: np.ndarray, min_held: int = 3) -> np.ndarray:
    """Which tracks last frame's stereo matches cannot give a view in the other camera.

    A view is made of >= ``min_held`` members found in the other camera's image; between
    association frames a match is only followed from last frame (``FrontEnd._follow_only``), so a
    track with fewer than ``min_held`` members among last frame's matches would have no view until
    the next full search. Those tracks' members are searched in full instead.

    Args:
        members: per track, (M_i,) int feature ids of its members.
        held_ids: (K,) int feature ids matched in the other camera last frame (any order).
        min_held: the members a view needs.
    Returns:
        (len(members),) bool, True where fewer than ``min_held`` members are in ``held_ids``.
    """
    n = len(members)
    if not n:
        return np.zeros(0, bool)
    held = np.asarray(held_ids, np.int64).reshape(-1)
    ids = [np.asarray(m, np.int64).reshape(-1) for m in members]
    # one membership test for all tracks' members; count each track's held ones (run of its members)
    owner = np.repeat(np.arange(n), [len(m) for m in ids])
    hit = _isin(np.concatenate(ids), held)
    return np.bincount(owner[hit], minlength=n) < min_held


def box_pairs(
    b0: np.ndarray,
    half0: np.ndarray,
    b1: np.ndarray,
    half1: np.ndarray,
    R_C1_C0: np.ndarray,
    t_C1_C0: np.ndarray,
    margin_rad: float = 0.0,
    compatible: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Box detections of two cameras that can be one obstacle: their centres' bearings satisfy the
    epipolar constraint within the boxes' angular size, and their rays meet ahead of both cameras.

    A box centre is not one physical point (each camera sees the lights, or the object, from its
    own side), so the tolerance is the larger box's angular half-diagonal plus ``margin_rad``:
        |b1 . n| / |n| < sin(max(half0, half1) + margin),  n = t_hat x R b0   (coplanarity)
    Ahead: the closest points of the rays c0 + s R b0 and c1 + u b1 (in C1: c0 = t, c1 = 0) have
    s >= 0 and u >= 0, with (d = R b0, c = d . b1)
        s = (c (b1 . t) - d . t) / (1 - c^2),   u = b1 . t + s c;
    near-parallel rays (1 - c^2 < 1e-12, an obstacle far beyond the baseline) count as ahead when
    c > 0. A pair is kept when each box is the other's only candidate (an ambiguous pair links
    nothing: two reports are better than one wrong merge).

    Args:
        b0: (N0, 3) unit centre bearings in C0; half0: (N0,) rad their boxes' angular half-diagonals.
        b1: (N1, 3) unit centre bearings in C1; half1: (N1,) rad.
        R_C1_C0 (3, 3), t_C1_C0 (3,) m: p_C1 = R p_C0 + t.
        margin_rad: added to the tolerance (rad).
        compatible: (N0, N1) bool, pairs whose labels / attributes agree (None: all).
    Returns:
        (i0 (K,), i1 (K,)) int row pairs.
    """
    b0 = np.asarray(b0, float).reshape(-1, 3)
    b1 = np.asarray(b1, float).reshape(-1, 3)
    e = np.zeros(0, np.intp)
    if not len(b0) or not len(b1):
        return e, e
    R = np.asarray(R_C1_C0, float)
    t = np.asarray(t_C1_C0, float).reshape(3)
    d = b0 @ R.T  # (N0, 3) camera 0's rays in C1
    tol = np.maximum(np.asarray(half0, float)[:, None], np.asarray(half1, float)[None, :]) + margin_rad
    tn = _norm(t)
    if tn > 0:
        n = _cross(t / tn, d)
        nn = _norm_rows(n)
        res = np.abs(n @ b1.T) / np.where(nn > 1e-9, nn, 1.0)[:, None]
        res[nn <= 1e-9] = 0.0  # along the baseline: every plane holds it (the angle test decides)
    else:
        res = _norm_rows(_cross(d[:, None, :], b1[None, :, :]))  # rays equal
    ok = res < np.sin(np.minimum(tol, np.pi / 2))
    c = d @ b1.T  # (N0, N1) cosines between the rays
    dt = d @ t  # (N0,)
    bt = b1 @ t  # (N1,)
    den = 1.0 - c * c
    par = den < 1e-12
    s = (c * bt[None, :] - dt[:, None]) / np.where(par, 1.0, den)
    u = bt[None, :] + s * c
    ok &= np.where(par, c > 0, (s >= 0) & (u >= 0))
    if compatible is not None:
        ok &= np.asarray(compatible, bool)
    one0 = ok.sum(axis=1) == 1
    one1 = ok.sum(axis=0) == 1
    i0, i1 = np.nonzero(ok)
    keep = one0[i0] & one1[i1]
    return i0[keep], i1[keep]


def boxes_compatible(attrs0: dict, attrs1: dict) -> bool:
    """Whether two box detections' attributes can describe one obstacle: a ``heading`` (or
    ``colour``) both give must agree, and lights (``red_uv`` / ``green_uv`` not None, navlights)
    seen by both must share a colour (a lone red light is not a lone green one)."""
    for key in ("heading", "colour"):
        v0, v1 = attrs0.get(key), attrs1.get(key)
        if v0 is not None and v1 is not None and v0 != v1:
            return False
    c0 = {k for k in ("red_uv", "green_uv") if attrs0.get(k) is not None}
    c1 = {k for k in ("red_uv", "green_uv") if attrs1.get(k) is not None}
    return not (c0 and c1 and not c0 & c1)


class BoxStereo:
    """Which box tracks of two cameras are one obstacle: a (track of camera 0, track of camera 1)
    pair ``box_pairs`` keeps in ``frames`` consecutive updates is linked (a chance alignment of two
    obstacles on one epipolar curve rarely lasts while they move).

    Args:
        frames: consecutive updates a pair must be kept in before it is linked (>= 1).
    """

    def __init__(self, frames: int = 2) -> None:
        self.frames = int(frames)
        self._run: dict[tuple[int, int], tuple[int, int]] = {}  # pair -> (last update, run length)
        self._n = 0

    def update(self, pairs: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Record this update's kept pairs (track ids, camera 0's first); returns those linked now
        (kept in ``frames`` consecutive updates, this one included)."""
        self._n += 1
        run = {}
        for p in pairs:
            last, k = self._run.get(p, (0, 0))
            run[p] = (self._n, k + 1 if last == self._n - 1 else 1)
        self._run = run  # a pair not kept this update starts again
        return [p for p, (_, k) in run.items() if k >= self.frames]
