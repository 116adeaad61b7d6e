"""The grouper's fast helpers give numpy's own reference formulas' values bit for bit (speed cuts
that must not move any output)."""

import numpy as np
import pytest

from estimators.geometry import _norm_rows
from trackers.grouping import _bincount3, _normalise, _well_conditioned


def _ref_norm(v):
    return np.linalg.norm(v, axis=-1)


def _ref_normalise(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


@pytest.mark.parametrize("shape", [(3,), (1, 3), (7, 3), (500, 3), (4, 9, 3), (0, 3), (6, 2), (3, 5, 2)])
def test_norm_rows_and_normalise_equal_numpy_bit_for_bit(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(20):
        v = rng.normal(size=shape) * 10.0 ** rng.integers(-30, 30, size=shape)
        assert np.array_equal(_norm_rows(v), _ref_norm(v))
        if shape[-1] == 3:
            out = _normalise(v)
            assert out.shape == v.shape
            assert np.array_equal(out, _ref_normalise(v))
    if shape[-1] == 3:  # zero vectors stay zero (no division by 0); a NaN norm divides by 1, as numpy's
        z = np.zeros(shape)
        assert np.array_equal(_normalise(z), z)
        if len(shape) == 1:
            w = np.array([np.nan, 1.0, 0.0])
            assert np.array_equal(_normalise(w), _ref_normalise(w), equal_nan=True)


def test_norm_rows_strided_input():
    v = np.random.default_rng(1).normal(size=(40, 6))[::3, 1:4]  # not contiguous
    assert np.array_equal(_norm_rows(v), _ref_norm(v))


def test_bincount3_equals_stacked_bincounts():
    rng = np.random.default_rng(2)
    keys = rng.integers(0, 30, 400)
    v = rng.normal(size=(400, 3))
    ref = np.stack([np.bincount(keys, v[:, k], 35) for k in range(3)], 1)
    out = _bincount3(keys, v, 35)
    assert out.shape == (35, 3) and out.flags.c_contiguous
    assert np.array_equal(out, ref)
    assert _bincount3(np.zeros(0, np.int64), np.zeros((0, 3)), 4).shape == (4, 3)


def test_well_conditioned_agrees_with_the_eigenvalue_rule():
    rng = np.random.default_rng(3)
    mats = []
    for scale in (1.0, 1e-4, 1e-9, 1e-12, 0.0):  # well conditioned ... singular (8 x 8, symmetric)
        for _ in range(10):
            X = rng.normal(size=(30, 8))
            X[:, 7] = X[:, 6] + scale * rng.normal(size=30)  # two near-equal columns
            mats.append(X.T @ X)
    A = np.array(mats)
    ev = np.abs(np.linalg.eigvalsh(A))
    expect = ev[:, -1] < 1e10 * ev[:, 0]
    assert expect.any() and not expect.all()
    ok, Ai = _well_conditioned(A)
    assert np.array_equal(ok, expect)
    if Ai is not None:
        assert np.array_equal(Ai[ok], np.linalg.inv(A[ok]))
    # an exactly singular matrix (inv raises): the eigenvalues decide, no inverse
    S = np.array([np.eye(8), np.diag([1.0] * 7 + [0.0])])
    ok, Ai = _well_conditioned(S)
    assert ok.tolist() == [True, False] and Ai is None


@pytest.mark.parametrize("cond", [1e8, 8e9, 1.2e10, 3e10])
def test_well_conditioned_near_the_threshold(cond):
    """Condition numbers on both sides of 1e10 (an 8 x 8 rotated diag(1, ..., 1, 1 / cond)): 1e8 passes
    by the Frobenius bound, 8e9 only by the eigenvalues, 1.2e10 and 3e10 fail though their bound
    |A|_F |A^-1|_F ~ 2.65 cond is below 1e11 (a shortcut bound above 1e10 would pass them)."""
    Q, _ = np.linalg.qr(np.random.default_rng(4).normal(size=(8, 8)))
    A = (Q * np.r_[np.ones(7), 1.0 / cond]) @ Q.T
    A = 0.5 * (A + A.T)[None]
    ok, Ai = _well_conditioned(A)
    assert ok.tolist() == [cond < 1e10]
    assert Ai is not None and np.array_equal(Ai, np.linalg.inv(A))


def test_norm_rows_and_normalise_sum_in_numpys_order():
    """Components of one magnitude, where the order of the sum of squares shows in the last bit of
    some norms (x^2 + z^2 + y^2 differs from numpy's x^2 + y^2 + z^2 in ~12 % of these draws)."""
    rng = np.random.default_rng(7)
    V = rng.uniform(0.5, 2.0, size=(2000, 3))
    assert np.array_equal(_norm_rows(V), _ref_norm(V))
    assert np.array_equal(_normalise(V), _ref_normalise(V))
    for v in V[:300]:  # the one-vector path (Python floats)
        assert np.array_equal(_normalise(v), _ref_normalise(v))
    W = rng.uniform(0.5, 2.0, size=(2000, 2))
    assert np.array_equal(_norm_rows(W), _ref_norm(W))
