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

from estimators.errors import InputError


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


def _lk_box(pts: np.ndarray, margin: float, shape: tuple[int, ...], align: int) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) px of an image of ``shape`` (H, W, ...) holding every point of ``pts`` (K, 2)
    px with ``margin`` px around, its origin on a multiple of ``align`` px (so the part's pyramid
    levels sample the image's own grid), clipped to the image."""
    lo = np.floor(pts.min(axis=0) - margin)
    hi = np.ceil(pts.max(axis=0) + margin) + 1
    x0 = max(int(lo[0]) // align * align, 0)
    y0 = max(int(lo[1]) // align * align, 0)
    return x0, y0, min(int(hi[0]), shape[1]), min(int(hi[1]), shape[0])


def _lk_part(
    grey_prev: np.ndarray,
    grey_next: np.ndarray,
    p_prev: np.ndarray,
    p_next: np.ndarray,
    win_px: int,
    level: int,
    crit: tuple,
    reach_px: float,
) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.calcOpticalFlowPyrLK`` from ``p_prev`` (K, 1, 2) float32 in grey_prev, starting at
    ``p_next`` (K, 1, 2) float32 in grey_next, on the parts of the two images the search can read.

    LK's cost per call is mostly building both images' pyramids (and the previous image's
    derivatives), so it runs on the box of the points instead of the whole image: the previous
    image's box holds every window at every level with the reach of the pyramid's 5-tap filter
    (``(win_px // 2 + 6) 2^level`` px around the points), the next image's box that plus
    ``reach_px`` around the starts (how far a point may travel); LK runs on their union in both
    images (its two images have one size), its origin on a multiple of ``2^level`` px, so each
    level samples the full image's own grid: inside the box every pixel LK reads equals the whole
    image's. A point that would travel farther than ``reach_px`` may be lost (status 0).

    Returns:
        (p_next (K, 1, 2) float32 result in grey_next, status (K,) uint8).
    """
    import cv2

    if grey_prev.shape != grey_next.shape:  # LK takes two images of one size
        return _lk_whole(grey_prev, grey_next, p_prev, p_next, win_px, level, crit)
    m = (win_px // 2 + 6) * 2.0**level
    al = 2**level
    a = _lk_box(p_prev.reshape(-1, 2), m, grey_prev.shape, al)
    b = _lk_box(p_next.reshape(-1, 2), m + reach_px, grey_next.shape, al)
    # one box for both (LK's two images have one size): the union
    x0, y0, x1, y1 = min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3])
    o = np.array([x0, y0], np.float32)
    q, st, _ = cv2.calcOpticalFlowPyrLK(
        grey_prev[y0:y1, x0:x1],
        grey_next[y0:y1, x0:x1],
        p_prev - o,
        p_next - o,
        winSize=(win_px, win_px),
        maxLevel=level,
        criteria=crit,
        flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return q + o, st.reshape(-1)


def _lk_whole(grey_prev, grey_next, p_prev, p_next, win_px, level, crit):
    """``_lk_part`` on the whole images (the reference it must agree with)."""
    import cv2

    q, st, _ = cv2.calcOpticalFlowPyrLK(
        grey_prev,
        grey_next,
        p_prev,
        p_next.copy(),
        winSize=(win_px, win_px),
        maxLevel=level,
        criteria=crit,
        flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
    )
    return q, st.reshape(-1)


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
    crop: bool = True,
    moved: str = "check",
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
        moved: what happens to a row with a finite guess that lands more than ``recheck_px``
            from it: "check" (the backward check) or "drop" (not found this call: no backward
            pass at all unless ``check`` asks for one).
        crop: run each KLT call on the parts of the two images its search reads (``_lk_part``:
            the same answers for any point that travels less than the coarsest window's reach,
            for a fraction of the pyramid-building cost); False: on the whole images.
    Returns:
        ``StereoKLT`` (idx, uv_b, b_b, checked).
    """
    import cv2

    if moved not in ("check", "drop"):
        raise InputError(f"stereo_klt: moved expected 'check' or 'drop', got {moved!r}")
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
        # on the parts of the images the search reads (_lk_part); reach: a followed row starts
        # within a pixel or two of its answer, a new one anywhere along its epipolar curve within
        # what the coarsest level's window covers
        reach = (win_px // 2) * 2.0 ** (lv + 1)
        q, s_q = _lk_part(grey_a, grey_b, p0[rows], p1[rows], win_px, lv, crit, reach) if crop else (
            _lk_whole(grey_a, grey_b, p0[rows], p1[rows], win_px, lv, crit)
        )
        p1[rows] = q
        st[rows] = s_q
    good = st == 1
    uv_b = p1.reshape(-1, 2).astype(float) + ob
    # the backward check: rows asked for, and followed rows that did not land where expected
    chk = np.ones(len(idx), bool) if check is None else np.asarray(check, bool)[idx].copy()
    chk |= ~own[idx]
    far = own[idx] & (np.linalg.norm(uv_b - start[idx], axis=1) > recheck_px)
    if moved == "drop":
        good &= ~far
    else:
        chk |= far
    ci = np.flatnonzero(chk & good)
    if len(ci):
        # backward: from the forward result in b, starting at the same pixel in a
        reach = (win_px // 2) * 2.0 ** (levels + 1)
        p0r, st2 = _lk_part(grey_b, grey_a, p1[ci], p1[ci], win_px, levels, crit, reach) if crop else (
            _lk_whole(grey_b, grey_a, p1[ci], p1[ci], win_px, levels, crit)
        )
        good[ci] &= (st2 == 1) & (
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


# ------------------------------------------------------------------------------------------------
# Pieces: a camera's second track on an obstacle that a two-camera track already covers
# ------------------------------------------------------------------------------------------------
# The groupers sometimes split one obstacle into two tracks in one camera; a piece that gets no
# view in the other camera (its members are not found there from their infinite-depth projection,
# nor linked to a track there) is reported as a one-camera obstacle: no stereo range and no stereo
# velocity, beside the two-camera track of the same obstacle. A confirmed piece within the
# grouper's link_px of a two-camera track's member in the image is attached to that track (same
# global id, for as long as the piece lives; its members join the track's views, ``attach_pieces``)
# when the geometry says it is the same surface: its members, searched in the other camera by
# stereo KLT from where they would be at that track's depth, triangulate at the depth of the
# track's members next to them in the image, within their joint noise (``piece_agrees``). Opt-in
# (``association.attach_pieces``): see FrontEnd.__init__ for what it was measured to do.

# angular noise of one stereo KLT ray, in pixels of the image it was measured in: the stereo KLT's
# forward-backward bound (stereo_klt fb_max_px = 1 px) taken as one sigma
PIECE_SIGMA_PX = 1.0
# members of the two-camera track whose depths stand for the surface next to a piece member (the
# same count as the fusion's member-spread model)
PIECE_NEIGHBOURS = 6
# a piece member agrees with that surface when its depth is within this many joint sigmas
PIECE_GATE_SIGMA = 3.0


def ray_depths(
    b_a: np.ndarray, b_b: np.ndarray, R_b_a: np.ndarray, t_b_a: np.ndarray, sigma_rad: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Depth along camera a's rays of the points two row-paired rays of cameras a and b meet at,
    with its first-order sigma.

    Ray a: ``s b_a`` (in C_a, from a's centre); ray b in C_a: ``c + u e`` with ``c = -R^T t`` (b's
    centre) and ``e = R^T b_b``. The closest approach of the two lines (least squares in s, u):
    ``s = (b.c - (b.e)(e.c)) / (1 - (b.e)^2)``, ``u = s (b.e) - e.c``. An angular error delta of ray
    b moves the meeting point along ray a by ``u delta / sin g`` (g the angle between the rays), one
    of ray a by ``s delta cos g / sin g``; both of one sigma:
    ``sigma_s = sigma sqrt(u^2 + s^2 cos^2 g) / sin g``.

    Args:
        b_a: (N, 3) unit bearings in C_a; b_b: (N, 3) unit bearings in C_b (row-paired).
        R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
        sigma_rad: angular sigma of each ray (rad), scalar or (N,).
    Returns:
        (depth_m (N,) along b_a, sigma_m (N,), ok (N,) bool): ok where both rays point at the
        meeting point (s > 0, u > 0) and they are not parallel (sin g > 1e-6); depth and sigma are
        inf elsewhere.
    """
    b_a = np.asarray(b_a, float).reshape(-1, 3)
    R = np.asarray(R_b_a, float)
    t = np.asarray(t_b_a, float).reshape(3)
    e = np.asarray(b_b, float).reshape(-1, 3) @ R  # R^T b_b, rows
    c = -(R.T @ t)
    be = np.sum(b_a * e, axis=1)
    bc = b_a @ c
    ec = e @ c
    sin2 = 1.0 - be * be
    ok = sin2 > 1e-12
    s = np.where(ok, (bc - be * ec) / np.where(ok, sin2, 1.0), np.inf)  # along ray a
    u = np.where(ok, s * be - ec, np.inf)  # along ray b
    ok &= (s > 0) & (u > 0) & np.isfinite(s)
    sin_g = np.sqrt(np.maximum(sin2, 0.0))
    sig = np.asarray(sigma_rad, float) * np.sqrt(u * u + s * s * be * be) / np.where(ok, sin_g, 1.0)
    return np.where(ok, s, np.inf), np.where(ok, sig, np.inf), ok


def informative(depth_m: np.ndarray, sigma_m: np.ndarray, gate: float = PIECE_GATE_SIGMA) -> np.ndarray:
    """Whether a triangulated depth tells anything: its inverse depth is more than ``gate`` sigmas
    from zero (infinity), ``1/d > gate sigma_d / d^2``, i.e. ``sigma_d < d / gate``. A depth test
    on a point that is not is always passed (a wide sigma holds any depth), so it is no evidence.

    Args:
        depth_m, sigma_m: (N,) metres (inf where not triangulated).
    Returns:
        (N,) bool.
    """
    d = np.asarray(depth_m, float)
    s = np.asarray(sigma_m, float)
    fin = np.isfinite(d) & np.isfinite(s) & (d > 0)
    return fin & (np.where(fin, s, np.inf) * gate < np.where(fin, d, 0.0))


def point_bearings(b_a: np.ndarray, depth_m: np.ndarray, R_b_a: np.ndarray, t_b_a: np.ndarray) -> np.ndarray:
    """Unit bearings in C_b of the points at ``depth_m`` along camera a's rays ``b_a``.

    ``p_b = R (d b_a) + t``, normalised (a point at b's centre gives a zero row).

    Args:
        b_a: (N, 3) unit bearings in C_a; depth_m: (N,) or scalar metres along them.
        R_b_a (3, 3), t_b_a (3,) m: p_Cb = R p_Ca + t.
    Returns:
        (N, 3) unit bearings in C_b.
    """
    p = (np.asarray(b_a, float).reshape(-1, 3) * np.asarray(depth_m, float).reshape(-1, 1)) @ np.asarray(
        R_b_a, float
    ).T + np.asarray(t_b_a, float).reshape(3)
    n = np.linalg.norm(p, axis=1, keepdims=True)
    return p / np.where(n > 0, n, 1.0)


def surface_agreement(
    uv_new: np.ndarray,
    d_new: np.ndarray,
    s_new: np.ndarray,
    uv_ref: np.ndarray,
    d_ref: np.ndarray,
    s_ref: np.ndarray,
    k: int = PIECE_NEIGHBOURS,
    gate: float = PIECE_GATE_SIGMA,
) -> np.ndarray:
    """Whether each new point lies at the depth of the reference surface next to it in the image.

    The surface next to new point i is the median depth m_i of the k reference points nearest it
    in the image, whose sigma is that of a median of k values, ``(pi / 2) median(s_j^2) / k``
    (as in the fusion's member-spread model); the point agrees when
    ``|d_i - m_i| <= gate sqrt(s_i^2 + sigma_m,i^2)``.

    Args:
        uv_new: (N, 2) px, d_new, s_new: (N,) m depth and sigma of the new points (one camera's
            pixels and depths along its rays); uv_ref (M, 2), d_ref (M,), s_ref (M,): the same of
            the reference points (finite).
        k: neighbours (min(k, M) are used); gate: sigmas.
    Returns:
        (N,) bool (all False when M == 0; False for a non-finite new depth).
    """
    uv_new = np.asarray(uv_new, float).reshape(-1, 2)
    n, m = len(uv_new), len(d_ref)
    if not n or not m:
        return np.zeros(n, bool)
    kk = min(int(k), m)
    du = uv_new[:, None, 0] - np.asarray(uv_ref, float)[None, :, 0]
    dv = uv_new[:, None, 1] - np.asarray(uv_ref, float)[None, :, 1]
    near = np.argsort(du * du + dv * dv, axis=1, kind="stable")[:, :kk]  # (N, kk)
    med = np.median(np.asarray(d_ref, float)[near], axis=1)
    var_m = (np.pi / 2) * np.median(np.asarray(s_ref, float)[near] ** 2, axis=1) / kk
    d_new = np.asarray(d_new, float)
    s_new = np.asarray(s_new, float)
    fin = np.isfinite(d_new) & np.isfinite(s_new)
    lim = gate * np.sqrt(np.where(fin, s_new, 0.0) ** 2 + var_m)
    return fin & (np.abs(np.where(fin, d_new, 0.0) - med) <= lim)


def piece_agrees(
    uv_piece: np.ndarray,
    d_piece: np.ndarray,
    s_piece: np.ndarray,
    uv_pair: np.ndarray,
    d_pair: np.ndarray,
    s_pair: np.ndarray,
) -> bool:
    """Whether a piece's members lie on the surface of a two-camera track's members (same camera).

    Only members whose depth is informative count (``informative``: both the piece's and the
    track's); the piece agrees when at least 3 of its informative members, and more than half of
    them, are at the depth of the track's surface next to them (``surface_agreement``).

    Args:
        uv_piece (N, 2) px, d_piece, s_piece (N,) m: the piece's members found in the other camera
            (pixels, triangulated depth along this camera's rays and its sigma; inf where none);
        uv_pair (M, 2), d_pair, s_pair (M,): the same of the two-camera track's members.
    Returns:
        bool.
    """
    inf = informative(d_piece, s_piece)
    ref = informative(d_pair, s_pair)
    if inf.sum() < 3 or ref.sum() < 3:
        return False
    ok = surface_agreement(
        np.asarray(uv_piece, float).reshape(-1, 2)[inf],
        np.asarray(d_piece, float)[inf],
        np.asarray(s_piece, float)[inf],
        np.asarray(uv_pair, float).reshape(-1, 2)[ref],
        np.asarray(d_pair, float)[ref],
        np.asarray(s_pair, float)[ref],
    )
    n_ok = int(ok.sum())
    return n_ok >= 3 and 2 * n_ok > int(inf.sum())


def _final_ids(fe, cam: str, tr) -> tuple[np.ndarray, np.ndarray]:
    """(ids (M,), bearings (M, 3) in C_cam) of a track's members as they are reported: a camera's
    own grouper track holds its local feature ids, mapped here to physical-point ids (``fe._pid``)
    as ``FrontEnd._observations`` maps them; a copy or a derived view holds reported ids already.
    Bearings: the track's member_b_C, else the live features' (members not live are left out)."""
    ids = np.asarray(tr.members, np.int64)
    b = np.asarray(tr.member_b_C, float).reshape(-1, 3)
    own = cam in fe.groupers and fe.groupers[cam].tracks.get(tr.id) is tr
    if len(b) != len(ids):
        rows, which = fe._rows(fe.trackers[cam], ids)
        ids, b = ids[which], fe.trackers[cam].b_C[rows]
    pid = fe._pid.get(cam)
    if own and pid and len(ids):
        ids = np.fromiter(map(pid.get, ids.tolist(), ids.tolist()), np.int64, len(ids))
    return ids, b


def _joined(tr, ids: np.ndarray, b: np.ndarray, add_ids: np.ndarray, add_b: np.ndarray):
    """A copy of track ``tr`` whose members are ``ids`` (bearings ``b``) plus those of ``add_ids``
    (bearings ``add_b``) not among them."""
    import copy

    new = ~np.isin(add_ids, ids)
    v = copy.copy(tr)
    v.members = np.concatenate([ids, np.asarray(add_ids, np.int64)[new]])
    v.member_b_C = np.concatenate([b, np.asarray(add_b, float).reshape(-1, 3)[new]])
    return v


def pieces_aside(fe, seen: dict) -> list:
    """Take out of ``seen`` (camera -> list of ObstacleTrack, changed in place) the attached pieces
    (``fe._pieces``: local track ids) whose global id has another track in that camera's list, and
    return them (``attach_pieces`` joins them to that track's views after the views are derived).
    A piece whose global id has no other track there stays: it is then that obstacle's view.
    Pieces no grouper tracks any more are forgotten."""
    if not fe._pieces:
        return []
    live = set()
    for g in fe.groupers.values():
        live.update(g.tracks)
    fe._pieces &= live
    out = []
    for cam, trs in seen.items():
        if not any(t.id in fe._pieces for t in trs):
            continue
        main = {fe._global(t.id) for t in trs if t.id not in fe._pieces}
        keep = []
        for t in trs:
            (out if t.id in fe._pieces and fe._global(t.id) in main else keep).append(t)
        seen[cam] = keep
    return out


def _search_pieces(fe, seen: dict, x: str, y: str) -> list:
    """Camera x's confirmed one-camera tracks attached this frame to a two-camera track of x and y
    (see the section's comment): changes ``fe._gid`` and ``fe._pieces``, stores the pieces'
    matches found in y in the frame's stereo cache (followed from next frame on), and returns the
    attached tracks (taken out of ``seen[x]``), each with the global id it had before."""
    grouper, ft = fe.groupers[x], fe.trackers[x]
    g_y = {fe._global(t.id) for t in seen.get(y, [])}
    g_other = set()
    for cam, trs in seen.items():
        if cam != x:
            g_other.update(fe._global(t.id) for t in trs)
    pairs, pieces = [], []
    for t in seen.get(x, []):
        own = grouper.tracks.get(t.id)
        if own is None or own.label != fe.label or len(own.members) < 3:
            continue
        g = fe._global(t.id)
        if g in g_y:
            pairs.append(own)
        elif own.status == "confirmed" and g not in g_other and t is own and t.id not in fe._pieces:
            pieces.append(own)
    if not pairs or not pieces:
        return []
    # beside: a piece within the grouper's own neighbour distance (link_px) of a two-camera
    # track's member in x's image; its partner is the track of the nearest such member
    rows_p, which = fe._rows(ft, np.concatenate([p.members for p in pairs]))
    owner = np.repeat(np.arange(len(pairs)), [len(p.members) for p in pairs])[which]
    uv_p = ft.uv[rows_p].astype(float)
    cand = []
    for pc in pieces:
        rows, _ = fe._rows(ft, pc.members)
        if len(rows) < 3 or not len(rows_p):
            continue
        du = ft.uv[rows, None, 0] - uv_p[None, :, 0]
        dv = ft.uv[rows, None, 1] - uv_p[None, :, 1]
        d2 = (du * du + dv * dv).min(axis=0)
        j = int(np.argmin(d2))
        if d2[j] <= grouper.link_px**2:
            cand.append((pc, rows, int(owner[j])))
    if not cand:
        return []
    T = fe._T_b_a[(x, y)]
    sig = PIECE_SIGMA_PX * max(fe._rad_px[x], fe._rad_px[y])
    # the partners' members at their stereo depth (x's pixels, depth along x's rays)
    use = np.isin(owner, [k for _, _, k in cand])
    rows_u, own_u = rows_p[use], owner[use]
    idx, _, bb = fe._stereo(x, y, rows_u)
    d, s, ok = ray_depths(ft.b_C[rows_u[idx]], bb, T.R, T.t, sig)
    ok &= informative(d, s)
    r_ref, o_ref, d_ref, s_ref = rows_u[idx][ok], own_u[idx][ok], d[ok], s[ok]
    uv_ref = ft.uv[r_ref].astype(float)
    tried, uvb, bbc, chk = fe._stereo_cache[(x, y)]
    out = []
    for pc, rows, k in cand:
        sel = o_ref == k
        if sel.sum() < 3:
            continue
        fe._stereo(x, y, rows)  # found from infinity or followed (cached)
        miss = rows[~np.isfinite(uvb[rows, 0])]
        if len(miss):
            # search the others from where they would be at the depth of the partner's surface
            # next to them (the median of its PIECE_NEIGHBOURS members nearest in x's image)
            du = ft.uv[miss, None, 0] - uv_ref[None, sel, 0]
            dv = ft.uv[miss, None, 1] - uv_ref[None, sel, 1]
            near = np.argsort(du * du + dv * dv, axis=1, kind="stable")[:, :PIECE_NEIGHBOURS]
            d_guess = np.median(d_ref[sel][near], axis=1)
            g, okg = fe.cams[y].model.bearing_to_pixel(point_bearings(ft.b_C[miss], d_guess, T.R, T.t))
            (ca, oa), (cb, ob) = ft.crop, fe.trackers[y].crop
            r = stereo_klt(ca, cb, ft.b_C[miss], ft.uv[miss].astype(float), fe.cams[y].model, T.R, T.t,
                           fe.epipolar_rad, off_a=oa, off_b=ob,
                           guess_b=np.where(okg[:, None], g, np.nan), check=np.ones(len(miss), bool))
            f = miss[r.idx]
            uvb[f], bbc[f], chk[f], tried[f] = r.uv_b, r.b_b, fe._n, True
        got = rows[np.isfinite(uvb[rows, 0])]
        if len(got) < 3:
            continue
        dp, sp, _ = ray_depths(ft.b_C[got], bbc[got], T.R, T.t, sig)
        if piece_agrees(ft.uv[got].astype(float), dp, sp, uv_ref[sel], d_ref[sel], s_ref[sel]):
            out.append((pc, fe._global(pc.id)))
            fe._gid[pc.id] = fe._global(pairs[k].id)
            fe._pieces.add(pc.id)
    if out:
        ids = {id(t) for t, _ in out}
        seen[x] = [t for t in seen[x] if id(t) not in ids]
    return out


def attach_pieces(fe, seen: dict, greys: dict, aside: list, search: bool) -> list[int]:
    """Join a camera's pieces to the views of the two-camera track they belong to.

    ``aside``: pieces attached earlier (``pieces_aside``); with ``search`` (association frames),
    camera x's confirmed tracks with no view in another camera are tested against the two-camera
    tracks of x (``_search_pieces``). Each piece's members join, in ``seen[x]``, a copy of the view
    of its global id, and the piece's members found by stereo KLT in the other camera join a copy
    of the view there (under the same physical-point ids: the reference camera's feature ids, a
    non-reference camera's mapped through ``fe._pid``).

    Args:
        fe: the ``FrontEnd``; seen: camera -> list of ObstacleTrack of this frame (after
            ``_derive_views``), changed in place; greys: camera -> this frame's grey image.
    Returns:
        the global ids the newly attached pieces were reported under (to be reported lost once).
    """
    pieces = [(t.camera, t) for t in aside]
    absorbed: list[int] = []
    if search:
        for x in fe.groupers:
            for y in fe.groupers:
                if x == y or x not in greys or y not in greys or x not in fe.trackers or y not in fe.trackers:
                    continue
                for t, g_old in _search_pieces(fe, seen, x, y):
                    pieces.append((x, t))
                    absorbed.append(g_old)
    absorbed = [g for g in absorbed if g in fe._reported]
    for x, pc in pieces:
        g = fe._global(pc.id)
        k_main = next((k for k, t in enumerate(seen.get(x, [])) if fe._global(t.id) == g), None)
        if k_main is None:  # no other view of it here: the piece is the view
            seen.setdefault(x, []).append(pc)
            continue
        ids_p, b_p = _final_ids(fe, x, pc)
        main = seen[x][k_main]
        seen[x][k_main] = _joined(main, *_final_ids(fe, x, main), ids_p, b_p)
        for y in fe.trackers:
            if y == x or y not in greys:
                continue
            k_y = next((k for k, t in enumerate(seen.get(y, [])) if fe._global(t.id) == g), None)
            if k_y is None or (x, y) not in fe._stereo_cache:
                continue
            rows, which = fe._rows(fe.trackers[x], pc.members)
            # rows of the piece's members in x: their reported ids are ids_p in the same order
            # when no member was dropped for not being live
            if len(which) != len(ids_p):
                continue
            idx, _, bb = fe._stereo(x, y, rows)
            if not len(idx):
                continue
            vy = seen[y][k_y]
            seen[y][k_y] = _joined(vy, *_final_ids(fe, y, vy), ids_p[idx], bb)
    return absorbed

