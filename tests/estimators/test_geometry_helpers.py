"""geometry's small-array helpers (_cross, _norm, _norm_rows, _isin, _einsum) are bit-identical to numpy's
np.cross, np.linalg.norm, np.isin and np.einsum, which they replace in the hot path: the triangulations and
bounds must not change by one ulp (tracks.jsonl is compared byte for byte across speed changes)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.geometry import _cross, _einsum, _isin, _norm, _norm_rows

SHAPES = [((3,), (3,)), ((7, 3), (7, 3)), ((1, 3), (9, 3)), ((3,), (5, 3)), ((6, 1, 3), (1, 4, 3))]


@pytest.mark.parametrize("shape_a, shape_b", SHAPES)
def test_cross_is_bit_identical_to_numpy(shape_a, shape_b):
    rng = np.random.default_rng(3)
    for _ in range(50):
        a = rng.normal(size=shape_a) * 10.0 ** rng.uniform(-9, 9)
        b = rng.normal(size=shape_b) * 10.0 ** rng.uniform(-9, 9)
        want = np.cross(a, b)
        got = _cross(a, b)
        assert got.shape == want.shape and np.array_equal(got, want)


def test_cross_of_parallel_and_axis_vectors():
    x, y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    assert _cross(x, y).tolist() == [0.0, 0.0, 1.0]  # x cross y = z
    assert _cross(x, 2.0 * x).tolist() == [0.0, 0.0, 0.0]


def test_norms_are_bit_identical_to_numpy():
    rng = np.random.default_rng(4)
    for n in (1, 3, 4, 50):
        for _ in range(50):
            v = rng.normal(size=n) * 10.0 ** rng.uniform(-9, 9)
            assert _norm(v) == np.linalg.norm(v)
            for k in (3, 4):  # rows of bearings, and the (M, 4) Jacobians of the range sigma
                m = rng.normal(size=(n, k)) * 10.0 ** rng.uniform(-9, 9)
                assert np.array_equal(_norm_rows(m), np.linalg.norm(m, axis=1))
                assert np.array_equal(_norm_rows(m, keepdims=True), np.linalg.norm(m, axis=1, keepdims=True))
            c = rng.normal(size=(n, 5, 3)) * 10.0 ** rng.uniform(-9, 9)  # match_bearings' (N0, N1, 3)
            assert np.array_equal(_norm_rows(c), np.linalg.norm(c, axis=2))
    assert _norm(np.array([3.0, 4.0, 0.0])) == 5.0


def test_isin_equals_numpy_on_integer_ids():
    rng = np.random.default_rng(5)
    key = np.int64(1) << 40
    for _ in range(400):
        na, nb = (int(n) for n in rng.integers(0, 40, 2))
        hi = int(rng.choice([3, 50, 10**6]))  # tie-heavy to sparse
        a = rng.integers(-hi, hi, na) + rng.integers(0, 3, na) * key
        b = rng.integers(-hi, hi, nb) + rng.integers(0, 3, nb) * key
        want = np.isin(a, b)
        got = _isin(a, b)
        assert got.dtype == bool and got.shape == want.shape and np.array_equal(got, want)
    # every value of b present, the largest and smallest beyond b's ends, empty either side
    b = np.array([7, 3, 3, 11], np.int64)
    assert _isin(np.array([3, 11, 7, 12, 2], np.int64), b).tolist() == [True, True, True, False, False]
    assert _isin(np.zeros(0, np.int64), b).shape == (0,)
    assert _isin(np.array([1, 2], np.int64), np.zeros(0, np.int64)).tolist() == [False, False]


# every subscript form the grouping and the fusion use, with operands of their shapes
EINSUM_FORMS = [
    ("ij,ij->i", [(40, 3), (40, 3)]),
    ("kij,kj->ki", [(40, 3, 3), (40, 3)]),
    ("ki,kij,kj->k", [(40, 3), (40, 3, 3), (40, 3)]),
    ("ki,kij->kj", [(40, 3), (40, 3, 3)]),
    ("gij,gj->gi", [(40, 3, 3), (40, 3)]),
    ("ki,ki->k", [(40, 6), (40, 6)]),
    ("nij,nj->ni", [(40, 3, 3), (40, 3)]),
    ("kij,nj->nki", [(8, 3, 3), (40, 3)]),
    ("nki,ni->nk", [(40, 8, 3), (40, 3)]),
    ("nai,naj->nij", [(40, 2, 8), (40, 2, 8)]),
    ("nai,na->ni", [(40, 2, 8), (40, 2)]),
    ("kai,ki->ka", [(40, 2, 8), (40, 8)]),
    ("kai,kij,kbj->kab", [(40, 2, 8), (40, 8, 8), (40, 2, 8)]),
    ("na,na->n", [(40, 2), (40, 2)]),
]


@pytest.mark.parametrize("subscripts, shapes", EINSUM_FORMS)
def test_einsum_is_numpys_own_numbers(subscripts, shapes):
    rng = np.random.default_rng(5)
    ops = [rng.normal(size=s) * 10.0 ** rng.uniform(-6, 6) for s in shapes]
    assert np.array_equal(_einsum(subscripts, *ops), np.einsum(subscripts, *ops))


def test_hot_modules_call_einsum_without_numpys_wrapper():
    """The grouping and the fusion (~340 einsum calls a 720p stereo frame) take ``_einsum``: np.einsum's
    wrapper costs ~0.7 us a call on top of the same C function."""
    import inspect

    from estimators import fusion, geometry
    from trackers import grouping

    for mod in (fusion, geometry, grouping):
        assert "np.einsum(" not in inspect.getsource(mod), mod.__name__
