"""Triangulation of detections whose left and right labels a detector exchanged in some views."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.fitness.scene import demo_cameras
from swarmpose.triangulation import MAX_EXHAUSTIVE_VIEWS, relabel_pairs, reproject, triangulate

THRESHOLD = 20.0  # px


def _two_wrists(n_views: int, frames: int = 3):
    """Cameras, two points per frame 400 mm apart (a left and a right wrist) and an unrelated third point, their
    pixels ``(T, C, 3, 2)`` and weights."""
    cams = demo_cameras(n_views)
    rng = np.random.default_rng(0)
    pts = np.stack([np.array([[-200.0, 0, 1000], [200.0, 0, 1000], [0.0, 0, 1600]])
                    + rng.normal(0, 50, 3) for _ in range(frames)])
    uv = reproject(cams, pts)
    return cams, pts, uv, np.full(uv.shape[:-1], 0.9)


def _swap(uv: np.ndarray, w: np.ndarray, views: list[int], frame: int = 0):
    uv, w = uv.copy(), w.copy()
    for c in views:
        uv[frame, c, [0, 1]] = uv[frame, c, [1, 0]]
        w[frame, c, [0, 1]] = w[frame, c, [1, 0]]
    return uv, w


@pytest.mark.parametrize("n_views", [4, MAX_EXHAUSTIVE_VIEWS + 1])  # every labelling tried; one view at a time
def test_one_views_swapped_pair_is_put_back(n_views: int):
    cams, pts, uv, w = _two_wrists(n_views)
    w[0, 2, 0] = 0.5  # the weights travel with their detections
    bad_uv, bad_w = _swap(uv, w, [2])
    assert np.abs(triangulate(cams, bad_uv, bad_w)[0, :2] - pts[0, :2]).max() > 20  # as detected: both off
    out_uv, out_w = relabel_pairs(cams, bad_uv, bad_w, [(0, 1)], THRESHOLD)
    np.testing.assert_array_equal(out_uv, uv)
    np.testing.assert_array_equal(out_w, w)
    np.testing.assert_allclose(triangulate(cams, out_uv, out_w), pts, atol=1e-6)


def test_the_labels_most_views_gave_are_kept():
    """Three of four views exchanged: the two points are found either way; they keep the labels of the three."""
    cams, pts, uv, w = _two_wrists(4)
    bad_uv, bad_w = _swap(uv, w, [1, 2, 3])
    out_uv, _ = relabel_pairs(cams, bad_uv, bad_w, [(0, 1)], THRESHOLD)
    np.testing.assert_array_equal(out_uv[0], uv[0][:, [1, 0, 2]])  # view 0 exchanged to join the others
    np.testing.assert_array_equal(out_uv[1:], uv[1:])  # the other frames as they were


def test_with_fewer_views_than_min_views_nothing_moves():
    cams, pts, uv, w = _two_wrists(4)
    bad_uv, bad_w = _swap(uv, w, [2])
    bad_w[0, 3, 1] = 0.0  # view 3 sees one wrist only: three views see both
    out_uv, _ = relabel_pairs(cams, bad_uv, bad_w, [(0, 1)], THRESHOLD)
    np.testing.assert_array_equal(out_uv[0, 2], uv[0, 2])
    bad_w[0, 1, 0] = 0.0  # now two views see both
    out_uv, out_w = relabel_pairs(cams, bad_uv, bad_w, [(0, 1)], THRESHOLD)
    np.testing.assert_array_equal(out_uv, bad_uv)
    np.testing.assert_array_equal(out_w, bad_w)


def test_agreeing_views_and_other_joints_are_left_as_they_are():
    cams, pts, uv, w = _two_wrists(4)
    noisy = uv + np.random.default_rng(1).normal(0, 2.0, uv.shape)
    out_uv, out_w = relabel_pairs(cams, noisy, w, [(0, 1)], THRESHOLD)
    np.testing.assert_array_equal(out_uv, noisy)
    np.testing.assert_array_equal(out_w, w)
    bad_uv, bad_w = _swap(uv, w, [1])
    bad_uv[:, :, 2] = np.nan  # an absent third point is not touched
    out_uv, _ = relabel_pairs(cams, bad_uv, bad_w, [(0, 1)], THRESHOLD)
    assert np.isnan(out_uv[:, :, 2]).all()
    np.testing.assert_array_equal(out_uv[:, :, :2], uv[:, :, :2])
