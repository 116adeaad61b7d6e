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
    tn = np.linalg.norm(t)
    if tn == 0:
        return np.linalg.norm(np.cross(b1, b0 @ np.asarray(R_C1_C0).T), axis=1)  # pure rotation: rays equal
    n = np.cross(t / tn, b0 @ np.asarray(R_C1_C0).T)
    nn = np.linalg.norm(n, axis=1)
    res = np.abs(np.sum(b1 * n, axis=1)) / np.where(nn > 1e-9, nn, 1.0)
    return np.where(nn > 1e-9, res, 1.0)


_POP8 = np.array([bin(i).count("1") for i in range(256)], np.int64)  # bits set per byte value


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
    """Descriptor matches between two cameras' features that satisfy the epipolar constraint.

    Args:
        b0, b1: (N0, 3), (N1, 3) unit bearings in cameras 0 and 1; d0, d1: their (N, 32) ORB descriptors.
        R_C1_C0, t_C1_C0: camera 0 -> camera 1 transform (p_C1 = R p_C0 + t, metres).
        epipolar_rad: largest angle of b1 out of b0's epipolar plane.
        max_hamming: largest descriptor distance (bits of 256); ratio: Lowe's ratio test.
    Returns:
        (K, 2) int index pairs (i0, i1), mutual best among the epipolar-consistent candidates.
    """
    if not len(b0) or not len(b1):
        return np.zeros((0, 2), np.intp)
    # epipolar residual of every pair: |b1 . n_i| / |n_i|
    t = np.asarray(t_C1_C0, float)
    tn = np.linalg.norm(t)
    Rb0 = b0 @ np.asarray(R_C1_C0).T
    if tn > 0:
        n = np.cross(t / tn, Rb0)
        nn = np.linalg.norm(n, axis=1)
        res = np.abs(n @ b1.T) / np.where(nn > 1e-9, nn, 1.0)[:, None]
        res[nn <= 1e-9] = 1.0
        # both rays on the same side (for baselines much shorter than the range)
        ok = (res < np.sin(epipolar_rad)) & ((Rb0 @ b1.T) > 0)
    else:
        ok = (Rb0 @ b1.T) > np.cos(epipolar_rad)
    # descriptor distances only for the epipolar candidates
    H = np.full(ok.shape, np.inf)
    ii, jj = np.nonzero(ok)
    if len(ii):
        H[ii, jj] = _POP8[np.bitwise_xor(d0[ii], d1[jj])].sum(axis=1)
    H[H > max_hamming] = np.inf
    if not np.isfinite(H).any():
        return np.zeros((0, 2), np.intp)
    j = np.argmin(H, axis=1)
    i_back = np.argmin(H, axis=0)
    best = H[np.arange(len(b0)), j]
    Hs = H.copy()
    Hs[np.arange(len(b0)), j] = np.inf
    second = Hs.min(axis=1)
    good = np.isfinite(best) & (i_back[j] == np.arange(len(b0))) & (best <= ratio * second + 1e-9)
    i = np.flatnonzero(good)
    return np.stack([i, j[i]], axis=1)


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
    win_px: int = 11,
    levels: int = 4,
    fb_max_px: float = 1.0,
    off_a: np.ndarray | None = None,
    off_b: np.ndarray | None = None,
    guess_b: np.ndarray | None = None,
    check: np.ndarray | None = None,
    recheck_px: float = 1.0,
    follow_levels: int | None = None,
) -> StereoKLT:
    """Find camera a's features in camera b's image by KLT, checked by the epipolar constraint and
    (where needed) forward-backward. One forward KLT call per pyramid depth (rows with their own
    guess, a match followed over frames, at ``follow_levels``; the others, from their
    infinite-depth projection, at ``levels``).

    Args:
        grey_a, grey_b: (H, W) uint8 frames of cameras a and b (same time).
        b_a: (N, 3) unit bearings in C_a; uv_a: (N, 2) their pixels in a.
        model_b: camera b's CameraModel; R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
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
    if not own.all():
        inf = np.flatnonzero(~own)
        g, ok_inf = model_b.bearing_to_pixel(b_a[inf] @ np.asarray(R_b_a).T)
        start[inf] = g
        ok[inf] = ok_inf
    idx = np.flatnonzero(ok)
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
    for rows, lv in ((np.flatnonzero(near), follow_levels), (np.flatnonzero(~near), levels)):
        if not len(rows):
            continue
        q, s_q, _ = cv2.calcOpticalFlowPyrLK(
            grey_a,
            grey_b,
            p0[rows],
            p1[rows],
            winSize=(win_px, win_px),
            maxLevel=lv,
            criteria=crit,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        p1[rows] = q
        st[rows] = s_q.reshape(-1)
    good = st == 1
    uv_b = p1.reshape(-1, 2).astype(float) + ob
    # the backward check: rows asked for, and followed rows that did not land where expected
    chk = np.ones(len(idx), bool) if check is None else np.asarray(check, bool)[idx].copy()
    chk |= ~own[idx]
    moved = own[idx] & (np.linalg.norm(uv_b - start[idx], axis=1) > recheck_px)
    chk |= moved
    ci = np.flatnonzero(chk & good)
    if len(ci):
        p0r, st2, _ = cv2.calcOpticalFlowPyrLK(
            grey_b, grey_a, p1[ci], None, winSize=(win_px, win_px), maxLevel=levels, criteria=crit
        )
        good[ci] &= (st2.reshape(-1) == 1) & (
            np.linalg.norm((p0r - p0[ci]).reshape(-1, 2), axis=1) <= fb_max_px
        )
    bb, okb = model_b.pixel_to_bearing(uv_b)
    good &= okb
    good &= epipolar_residual(b_a[idx], bb, R_b_a, t_b_a) < np.sin(epipolar_rad)
    return StereoKLT(idx[good], uv_b[good], bb[good], chk[good])


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
    pairs = np.unique(np.stack([ia, ib], axis=1), axis=0)
    _, inv_a, cnt_a = np.unique(pairs[:, 0], return_inverse=True, return_counts=True)
    _, inv_b, cnt_b = np.unique(pairs[:, 1], return_inverse=True, return_counts=True)
    ok = (cnt_a[inv_a] == 1) & (cnt_b[inv_b] == 1)
    return pairs[ok, 0], pairs[ok, 1]
