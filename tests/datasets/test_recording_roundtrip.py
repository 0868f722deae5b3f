"""A synthesised clip out as per-camera videos + a calibration file, and imported again: the same cameras and images."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmpose.datasets.recording import ImportOptions, import_recording
from swarmpose.export.recording import export_recording
from swarmpose.io.sequence import open_sequence
from swarmpose.synth import synthesize

FRAMES = 4


@pytest.fixture(scope="module")
def synthetic(mocap_dir: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("synth") / "walk"
    synthesize(mocap_dir / "cmu_16_16_walk.bvh", out, fps=60, seed=0, max_frames=FRAMES, measure=False,
               progress=False)
    return out


def same_camera(a, b, tol: float = 1e-6) -> bool:
    return (a.name, a.width, a.height) == (b.name, b.width, b.height) and all(
        np.allclose(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), rtol=0, atol=tol)
        for f in ("fx", "fy", "cx", "cy", "skew", "dist", "R", "t"))


@pytest.mark.parametrize("fmt", ["toml", "opencv", "easymocap"])
@pytest.mark.parametrize("video", [True, False], ids=["mp4", "png"])
def test_export_then_import_gives_the_same_cameras_and_images(synthetic, tmp_path, fmt, video):
    with open_sequence(synthetic) as seq:
        exported = export_recording(seq, tmp_path / "rec", calibration_format=fmt, video=video)
        res = import_recording(exported["sources"], exported["calibration"], tmp_path / "back", progress=False,
                               options=ImportOptions(detect=False, silhouettes="none", fps=seq.frame_rate))
        assert res.notes and not any("padded" in n or "scaled" in n for n in res.notes)
        with open_sequence(tmp_path / "back") as back:
            assert back.n_frames == FRAMES and back.frame_rate == seq.frame_rate
            for a, b in zip(back.cameras, seq.cameras, strict=True):
                assert same_camera(a, b)
            for k in range(FRAMES):
                diff = np.abs(back.images(k).astype(int) - seq.images(k).astype(int))
                if video:  # MPEG-4 Part 2 at OpenCV's default quality: small, noise-like differences
                    assert diff.mean() < 3.0 and np.percentile(diff, 99) < 25
                else:
                    assert diff.max() == 0
