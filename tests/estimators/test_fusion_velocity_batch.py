"""``ObstacleFusion._feature_velocity`` computes every due track's feature velocity in one batch.

Several tracks at once (a mix of the cases: one due with many shared ids in shuffled order, one with
exactly two, one whose first frame lists a single id (no reference), one not yet due, one fresh): each track's
velocity and covariance must equal the per-track formulas of its docstring, written out here with
np.median per track (the reduction in the track's ray frame Q = [a, e1, e2], the fusion's basis
``_ttangent_basis``), to rounding; tracks must not mix (a batching bug that takes another track's
rows fails here).
"""

from __future__ import annotations

import math
import types

import numpy as np

from estimators.cameras import Equidistant
from estimators.egomotion import ConstantVelocity
from estimators.fusion import FusionSettings, ObstacleFusion, _Track, _ttangent_basis
from estimators.fusion_stats import chi2_ppf, median_variance_factor
from estimators.rig import stereo_forward_rig


def _expected(s: FusionSettings, ref, now, dt: float):
    """The docstring's reduction for one track: ref / now = (ids, P, sr, st, U) of its points."""
    f_r, P_r, S_r, T_r, U_r = ref
    f_n, P_n, S_n, T_n, U_n = now
    common = sorted(set(f_r.tolist()) & set(f_n.tolist()))
    ia = [int(np.flatnonzero(f_r == f)[0]) for f in common]
    ib = [int(np.flatnonzero(f_n == f)[0]) for f in common]
    n = len(common)
    a = U_n[ib].sum(axis=0)
    a /= np.linalg.norm(a)
    Q = np.column_stack([a, *_ttangent_basis(tuple(a.tolist()))])
    W = ((P_n[ib] - P_r[ia]) / dt) @ Q
    w = np.median(W, axis=0)
    var = np.zeros((n, 3))
    for U, S, T in ((U_r[ia], S_r[ia], T_r[ia]), (U_n[ib], S_n[ib], T_n[ib])):
        c2 = (U @ Q) ** 2
        var += (S**2)[:, None] * c2 + (T**2)[:, None] * (1.0 - c2)
    var /= dt * dt
    var_k = np.median(var, axis=0)
    chi = np.sum((W - w) ** 2 / var, axis=0)
    gate = chi2_ppf(s.gate_probability, n - 1)
    mad2 = (1.4826 * np.median(np.abs(W - w), axis=0)) ** 2
    var_k = np.where(chi > gate, np.maximum(mad2, var_k), var_k)
    q = s.max_accel_mps2**2 * s.accel_time_s
    rq = var_k * median_variance_factor(n) / n
    return Q @ w, Q @ np.diag(rq + q * dt / 3.0) @ Q.T


def test_batched_feature_velocities_equal_the_per_track_formulas():
    rng = np.random.default_rng(3)
    s = FusionSettings()
    lag = s.feature_velocity_lag_s
    assert lag > 0
    fus = ObstacleFusion(stereo_forward_rig(Equidistant.from_deg_per_px(0.15, 640, 640), 0.3),
                         ConstantVelocity(0.0), s)
    tracks = [_Track(k, "orb") for k in range(5)]
    # (ids at the reference, ids now) per track; track 2's first frame lists a single id, which
    # measures nothing, so it is no reference; track 3 is first seen at the later frame (fresh)
    ids = {0: (np.arange(10, 19), rng.permutation(np.arange(12, 21))),
           1: (np.array([40, 41, 42]), np.array([41, 42, 43])),
           2: (np.array([60]), np.array([60, 61, 62])),
           3: (None, np.array([80, 81, 82]))}
    vel = {0: np.array([1.0, -0.5, 0.2]), 1: np.array([0.0, 2.0, 0.0])}

    def points(k, f, t):
        centre = np.array([4.0 + k, 0.3 * k, 0.1])
        p = centre + 0.05 * np.sin(np.outer(f, [1.0, 2.0, 3.0])) + vel.get(k, np.zeros(3)) * t
        p += rng.normal(scale=2e-3, size=p.shape)
        u = p / np.linalg.norm(p, axis=1)[:, None]
        return p, 0.01 + 0.002 * (f % 3), 1e-3 + 1e-4 * (f % 2), u

    def frame(t, which):
        gg, fid, P, S, T, U = [], [], [], [], [], []
        for k in (0, 1, 2, 3):
            f = ids[k][which]
            if f is None:
                continue
            p, sr, st, u = points(k, f, t)
            gg.append(np.full(len(f), k))
            fid.append(f)
            P.append(p)
            S.append(sr)
            T.append(st)
            U.append(u)
        cat = np.concatenate
        order = rng.permutation(sum(len(g) for g in gg))  # (the batch takes any order)
        return tuple(x[order] for x in (cat(gg), cat(fid), cat(P), cat(S), cat(T), cat(U)))

    sg0 = types.SimpleNamespace(t_s=0.0)
    work0 = [(tr, sg0, "confirmed") for tr in tracks]
    fr0 = frame(0.0, 0)
    fus._feature_velocity(work0, *fr0)
    refs = {}
    for k in (0, 1):  # (one reference per frame: this frame's, the only one yet)
        assert tracks[k].vel_ref is not None and len(tracks[k].vel_ref) == 1
        refs[k] = tracks[k].vel_ref[0]
        assert refs[k][0] == 0.0
        np.testing.assert_array_equal(refs[k][1], np.sort(ids[k][0]))
    assert tracks[2].vel_ref is None
    t1 = lag + 1e-3
    sg1 = types.SimpleNamespace(t_s=t1)
    fr1 = frame(t1, 1)
    fus._feature_velocity([(tr, sg1, "confirmed") for tr in tracks], *fr1)
    for k in (0, 1):
        tr = tracks[k]
        # (measured: the reference used is dropped, this frame's points are the next one)
        assert len(tr.vel_ref) == 1 and tr.vel_ref[0][0] == t1
        m = fr1[0] == k
        o = np.argsort(fr1[1][m])
        now = (fr1[1][m][o], fr1[2][m][o], fr1[3][m][o], fr1[4][m][o], fr1[5][m][o])
        v, R = _expected(s, refs[k][1:], now, t1)
        np.testing.assert_allclose(tr.feature_velocity[0], v, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(tr.feature_velocity[1], R, rtol=1e-10, atol=1e-14 * np.abs(R).max())
        assert tr.vel_acc is not None and math.isclose(tr.vel_acc[2], t1 - 0.5 * t1)
    # the moving track's velocity is the truth to the noise of its displacements
    np.testing.assert_allclose(tracks[0].feature_velocity[0], vel[0], atol=0.1)
    # track 2: this frame's three ids are its first reference, nothing measured
    assert tracks[2].feature_velocity is None and [r[0] for r in tracks[2].vel_ref] == [t1]
    np.testing.assert_array_equal(tracks[2].vel_ref[0][1], [60, 61, 62])
    # track 3: a fresh reference; track 4: not in the batch at all
    assert tracks[3].feature_velocity is None and [r[0] for r in tracks[3].vel_ref] == [t1]
    assert tracks[4].vel_ref is None and tracks[4].feature_velocity is None


def test_velocity_evidence_of_several_tracks_equals_one_kalman_update_each():
    """``ObstacleFusion._velocity_evidence`` updates every due track's evidence in one batch: each
    must equal the docstring's filter for that track alone, written out here (P grown by q (t -
    t_e) I, K = P0 (P0 + R)^-1, x = x0 + K (v - x0), P = (I - K) P0 symmetrised), to 1e-12 (bit for
    bit on this machine; numpy's stacked and single 3x3 inverses may round apart on another CPU); a
    track without evidence starts from its measurement; tracks must not mix."""
    rng = np.random.default_rng(5)
    s = FusionSettings()
    fus = ObstacleFusion(stereo_forward_rig(Equidistant.from_deg_per_px(0.15, 640, 640), 0.3),
                         ConstantVelocity(0.0), s)
    q = s.max_accel_mps2**2 * s.accel_time_s
    tracks = [_Track(k, "orb") for k in range(6)]
    before = {}
    for k, tr in enumerate(tracks):
        if k % 3 != 1:  # tracks 1 and 4 have no evidence yet
            A = rng.normal(size=(3, 3))
            tr.vel_acc = (rng.normal(size=3), A @ A.T + 0.05 * np.eye(3), 0.1 * k)
            before[k] = tr.vel_acc
    V = rng.normal(size=(6, 3))
    B = rng.normal(size=(6, 3, 3))
    R = B @ B.transpose(0, 2, 1) + 0.02 * np.eye(3)
    T = [0.9 + 0.01 * k for k in range(6)]
    T[5] = 0.0  # measured before its evidence's time: no growth (max(t - t_e, 0))
    fus._velocity_evidence(tracks, V, R, T)
    for k, tr in enumerate(tracks):
        x, P, t = tr.vel_acc
        assert t == T[k]
        if k not in before:
            assert np.array_equal(x, V[k]) and np.array_equal(P, R[k])
            continue
        x0, P0, t0 = before[k]
        P0 = P0 + np.eye(3) * (q * max(T[k] - t0, 0.0))
        K = P0 @ np.linalg.inv(P0 + R[k])
        P_want = P0 - K @ P0
        np.testing.assert_allclose(x, x0 + K @ (V[k] - x0), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(P, 0.5 * (P_want + P_want.T), rtol=1e-12, atol=1e-12)
