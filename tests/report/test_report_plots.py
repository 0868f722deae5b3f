"""The error plots: files of the expected size that show the runs, the mean and the IK floor."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from swarmpose.report import error_over_time, load_results, per_joint_errors
from swarmpose.report._style import SIDE_RGB


def _rgb(path: Path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def _has_colour(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 12, min_pixels: int = 30) -> bool:
    d = np.abs(img.astype(int) - np.array(rgb)).max(axis=-1)
    return int((d <= tol).sum()) >= min_pixels


def test_error_over_time_png(fake_results, tmp_path: Path):
    res = load_results(fake_results[0])
    out = error_over_time(res, out=tmp_path / "d.png", figsize=(8.0, 4.0), dpi=100)
    assert out == tmp_path / "d.png"
    img = _rgb(out)
    assert img.shape == (400, 800, 3)
    assert img.std() > 10  # not blank
    assert _has_colour(img, (0, 0, 0), tol=30, min_pixels=300)  # the thick mean line (and text)
    assert _has_colour(img, (120, 120, 120), tol=20)  # the dashed IK floor


def test_error_over_time_default_location(fake_results, tmp_path: Path):
    import shutil

    dst = tmp_path / "res"
    shutil.copytree(fake_results[0], dst, ignore=shutil.ignore_patterns("report"))
    out = error_over_time(dst)
    assert out == dst / "report" / "error_over_time.png"
    with Image.open(out) as im:
        assert im.size == (990, 462)


def test_per_joint_png(fake_results, tmp_path: Path):
    out = per_joint_errors(fake_results[0], out=tmp_path / "j.png", figsize=(10.0, 4.0), dpi=80)
    img = _rgb(out)
    assert img.shape == (320, 800, 3)
    for side in ("left", "right", "center"):  # bars coloured by body side
        assert _has_colour(img, SIDE_RGB[side], tol=8, min_pixels=100), side
