"""``estimators.fusion._unique_first``: the sorted distinct integer keys and the index of each one's
first occurrence. Truth by hand, and np.unique(keys, return_index=True)'s own arrays (the function
stands in for it on the per-frame path)."""

from __future__ import annotations

import numpy as np
import pytest

from estimators.fusion import _unique_first


def test_by_hand():
    keys = np.array([7, 3, 7, 3, 9, 3, -2, 9])
    uniq, first = _unique_first(keys)
    assert uniq.tolist() == [-2, 3, 7, 9]
    assert first.tolist() == [6, 1, 0, 4]  # the first of each key's repeats, in key order


@pytest.mark.parametrize(
    "keys",
    [
        [],  # empty
        [5],  # one key
        [4, 4, 4, 4],  # all equal: index 0
        [0, 1, 2, 3, 4],  # sorted, distinct
        [4, 3, 2, 1, 0],  # reversed
        [2, 1, 2, 1, 2, 1],  # ties throughout
        [-(2**62), 2**62, 0, -(2**62)],  # int64's range
    ],
)
def test_edge_cases_match_numpy(keys):
    k = np.array(keys, dtype=np.int64)
    uniq, first = _unique_first(k)
    want_u, want_i = np.unique(k, return_index=True)
    assert uniq.dtype == want_u.dtype and first.dtype == want_i.dtype
    assert np.array_equal(uniq, want_u) and np.array_equal(first, want_i)


def test_random_keys_match_numpy():
    rng = np.random.default_rng(20)
    for n, hi in ((3, 2), (40, 10), (300, 5000), (2000, 50)):
        k = rng.integers(-hi, hi, n)
        uniq, first = _unique_first(k)
        want_u, want_i = np.unique(k, return_index=True)
        assert np.array_equal(uniq, want_u) and np.array_equal(first, want_i)
