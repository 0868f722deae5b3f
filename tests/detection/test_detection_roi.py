"""The detector base class (swarmpose.detection.base): colour conversion, the region of interest and the
mapping of normalised landmarks back to full-image pixels, with a fake model."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.detection.base import Detection, LandmarkDetector, PersonDetector, RawLandmarks, clip_roi
from swarmpose.errors import ConfigError, ShapeError

XY = np.array([[0.0, 0.0], [1.0, 1.0], [0.5, 0.25]])


class FixedPoints(LandmarkDetector):
    """Always the same normalised points; the mask is the crop's central half (optionally at another size)."""

    name = "fixed"
    keypoint_names = ("a", "b", "c")

    def __init__(self, mask_size: tuple[int, int] | None = None, found: bool = True):
        self.mask_size, self.found = mask_size, found
        self.calls: list[tuple[tuple[int, ...], bool, np.ndarray]] = []

    def _infer(self, rgb, *, static):
        self.calls.append((rgb.shape, static, rgb[0, 0].copy()))
        if not self.found:
            return None
        h, w = self.mask_size or rgb.shape[:2]
        prob = np.zeros((h, w), np.float32)
        prob[h // 4: h - h // 4, w // 4: w - w // 4] = 0.9
        return RawLandmarks(XY, np.array([0.9, 1.2, -0.1]), prob)


def test_fake_detector_follows_the_protocol():
    assert isinstance(FixedPoints(), PersonDetector)


def test_full_image_pixels_use_the_pixel_centre_convention():
    det = FixedPoints()
    d = det.detect(np.zeros((60, 80, 3), np.uint8))
    assert d.found and d.keypoints.dtype == np.float64
    np.testing.assert_allclose(d.keypoints, [[-0.5, -0.5], [79.5, 59.5], [39.5, 14.5]])
    np.testing.assert_allclose(d.confidence, [0.9, 1.0, 0.0])  # clipped into [0, 1]
    assert d.mask.shape == (60, 80) and d.mask.dtype == np.uint8 and set(np.unique(d.mask)) == {0, 1}
    assert det.calls[0][1] is False  # the whole image: video mode


def test_roi_maps_back_to_the_full_image():
    det = FixedPoints()
    x0, y0, x1, y1 = 20, 10, 60, 50
    d = det.detect(np.zeros((60, 80), np.uint8), roi=(x0, y0, x1, y1))
    assert det.calls[0][0] == (40, 40, 3) and det.calls[0][1] is True  # the crop only, as a still image
    np.testing.assert_allclose(d.keypoints, [[x0 - 0.5, y0 - 0.5], [x1 - 0.5, y1 - 0.5], [39.5, 19.5]])
    assert d.mask.shape == (60, 80)
    assert d.mask[:y0].sum() == 0 and d.mask[y1:].sum() == 0 and d.mask[:, :x0].sum() == 0 and d.mask[:, x1:].sum() == 0
    expected = np.zeros((60, 80), np.uint8)
    expected[y0 + 10: y1 - 10, x0 + 10: x1 - 10] = 1
    np.testing.assert_array_equal(d.mask, expected)


def test_roi_is_clipped_to_the_image_and_an_empty_one_refused():
    det = FixedPoints()
    d = det.detect(np.zeros((60, 80), np.uint8), roi=(-10, 50, 200, 90))
    assert det.calls[0][0][:2] == (10, 80)
    np.testing.assert_allclose(d.keypoints[1], [79.5, 59.5])
    assert clip_roi((1.4, 2.6, 10, 20), (60, 80)) == (1, 3, 10, 20)
    with pytest.raises(ConfigError):
        det.detect(np.zeros((60, 80), np.uint8), roi=(90, 0, 100, 10))
    with pytest.raises(ConfigError):
        det.detect(np.zeros((60, 80), np.uint8), roi=(0, 0, 10))


def test_mask_of_another_size_is_resized_to_the_crop():
    d = FixedPoints(mask_size=(20, 20)).detect(np.zeros((60, 80), np.uint8), roi=(0, 0, 40, 40))
    assert d.mask.shape == (60, 80)
    assert d.mask[20, 20] == 1 and d.mask[2, 2] == 0 and d.mask[:, 40:].sum() == 0


def test_bgr_and_grey_become_rgb():
    det = FixedPoints()
    bgr = np.zeros((6, 8, 3), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 10, 20, 30
    det.detect(bgr)
    np.testing.assert_array_equal(det.calls[-1][2], [30, 20, 10])
    det.detect(np.full((6, 8), 7, np.uint8))
    np.testing.assert_array_equal(det.calls[-1][2], [7, 7, 7])
    det.detect(np.full((6, 8, 1), 9, np.uint8))
    np.testing.assert_array_equal(det.calls[-1][2], [9, 9, 9])
    with pytest.raises(ConfigError):
        det.detect(np.zeros((6, 8, 3), np.float32))
    with pytest.raises(ShapeError):
        det.detect(np.zeros((6, 8, 4), np.uint8))


def test_nobody_found():
    d = FixedPoints(found=False).detect(np.zeros((60, 80), np.uint8), roi=(0, 0, 30, 30))
    assert not d.found and np.isnan(d.keypoints).all() and (d.confidence == 0).all()
    assert d.mask.shape == (60, 80) and d.mask.sum() == 0


def test_detection_checks_shapes():
    with pytest.raises(ShapeError):
        Detection(np.zeros((3, 2)), np.zeros(2), None, True)
    with pytest.raises(ShapeError):
        Detection(np.zeros((3, 2)), np.zeros(3), np.zeros((4, 4), bool), True)
