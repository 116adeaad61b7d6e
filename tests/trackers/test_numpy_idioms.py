"""The trackers' hot paths take numpy's row indices by the array method ``m.nonzero()[0]``, not
``np.flatnonzero(m)`` (its ravel and nonzero wrappers cost ~0.8 us a call, ~50 calls a 720p stereo
frame): the same indices for a 1-D mask. Where the mask is 2-D the flat indices are what is meant,
and ``np.flatnonzero`` stays (``match_features``' (n0, n1) epipolar candidates)."""

import inspect

import numpy as np

from trackers import association, features, frontend, grouping
from trackers.detectors import orb


def test_row_indices_by_the_method_flat_indices_only_for_the_2d_mask():
    mods = (association, features, frontend, grouping, orb)
    uses = {m.__name__: inspect.getsource(m).count("np.flatnonzero(") for m in mods}
    assert uses == {
        "trackers.association": 1,  # match_features: ok (n0, n1), flat row-major indices
        "trackers.features": 0,
        "trackers.frontend": 0,
        "trackers.grouping": 0,
        "trackers.detectors.orb": 0,
    }


def test_the_method_is_flatnonzero_on_1d_masks_and_not_on_2d_ones():
    rng = np.random.default_rng(0)
    m = rng.random(300) < 0.4
    assert np.array_equal(m.nonzero()[0], np.flatnonzero(m))
    m2 = rng.random((7, 9)) < 0.4
    assert not np.array_equal(m2.nonzero()[0], np.flatnonzero(m2))


def test_klt_gathers_rows_by_take_not_by_fancy_indexing():
    """The KLT's per-frame gathers of (N, k) rows and of pixels at (v, u) are ``take``s (a row list or one
    flat index: numpy's chunked copy, the same values), not 2-D fancy indexing (a general iterator, one
    element or row at a time: ~1.6 M instructions a 720p stereo frame more)."""
    ft = features.FeatureTracker
    for fn in (ft._klt, ft._texture, ft.densify, features._Finder.find, orb.OrbDetector.detect,
               features._lk_box):
        src = inspect.getsource(fn)
        assert "[vi, ui]" not in src and "[vi[" not in src, fn.__name__
        assert "ref_uv[sel]" not in src and "disp[sel]" not in src, fn.__name__
        assert "uv = uv[inside]" not in src and "pts = pts[" not in src, fn.__name__


def test_flat_take_is_the_two_index_gather():
    rng = np.random.default_rng(1)
    img = rng.integers(0, 255, (37, 53), dtype=np.uint8)
    vi, ui = rng.integers(0, 37, (20, 5)), rng.integers(0, 53, (20, 5))
    assert np.array_equal(img.take(vi * img.shape[1] + ui), img[vi, ui])
    view = img[3:30, 7:40]  # a part of a frame (not contiguous): take's index is the logical one
    vi, ui = vi % view.shape[0], ui % view.shape[1]
    assert np.array_equal(view.take(vi * view.shape[1] + ui), view[vi, ui])


def test_stereo_association_norms_and_crosses_by_geometrys_helpers():
    """The stereo association and the front end's per-frame norms and cross products are geometry's
    ``_norm`` / ``_norm_rows`` / ``_cross`` (the same values; np.linalg.norm's and np.cross's argument
    handling costs ~5-30 us a call, ~10 calls a 720p stereo frame)."""
    for mod in (association, frontend):
        src = inspect.getsource(mod)
        assert "np.linalg.norm(" not in src and "np.cross(" not in src, mod.__name__
