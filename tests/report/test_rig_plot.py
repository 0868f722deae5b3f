"""The rig picture: a PNG of the expected size showing every camera's colour and the floor grid."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError
from swarmpose.report.rig import frustum_corners, plot_rig

BLUE, VERMILLION, GREEN = (0, 114, 178), (213, 94, 0), (0, 158, 115)


def _rgb(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def _count(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 12) -> int:
    return int((np.abs(img.astype(int) - np.array(rgb)).max(axis=-1) <= tol).sum())


def _ring(n: int) -> list[Camera]:
    return [Camera.look_at(f"cam{i}", eye=(3000 * math.cos(2 * math.pi * i / n), 3000 * math.sin(2 * math.pi * i / n),
                                          2000.0), target=(0.0, 0.0, 1000.0), f=800.0, width=640, height=480)
            for i in range(n)]


def test_plot_rig_png(tmp_path: Path):
    out = plot_rig(_ring(3), tmp_path / "sub" / "rig.png", title="three cameras", figsize=(8.0, 6.0), dpi=100)
    assert out == tmp_path / "sub" / "rig.png"
    img = _rgb(out)
    assert img.shape == (600, 800, 3)
    assert img.std() > 10  # not blank
    for colour in (BLUE, VERMILLION, GREEN):  # one colour per camera, in the palette's order
        assert _count(img, colour) > 50, colour
    assert _count(img, (166, 166, 166), tol=20) > 200  # the floor grid


def test_plot_rig_takes_a_calibration_and_an_odd_floor(tmp_path: Path):
    class Cal:  # anything with .cameras, as swarmpose.io.calibration.Calibration
        cameras = _ring(1)

    out = plot_rig(Cal(), tmp_path / "one.png", floor_z=-500.0)
    img = _rgb(out)
    assert img.shape == (715, 990, 3) and img.std() > 10
    assert _count(img, BLUE) > 50


def test_frustum_corners_project_to_the_image_corners():
    cam = _ring(2)[1]
    corners = frustum_corners(cam, 400.0)
    uv, z = cam.project_with_depth(corners)
    np.testing.assert_allclose(uv, [[-0.5, -0.5], [639.5, -0.5], [639.5, 479.5], [-0.5, 479.5]], atol=1e-9)
    np.testing.assert_allclose(z, 400.0)


def test_plot_rig_needs_cameras(tmp_path: Path):
    with pytest.raises(ConfigError):
        plot_rig([], tmp_path / "none.png")
