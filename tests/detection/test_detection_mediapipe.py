"""MediaPipe Pose (swarmpose.detection.mediapipe_pose): the install message without it, and the real model on
three frames of the Pose2Sim demo recording when it is installed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarmpose.detection.base import PersonDetector
from swarmpose.detection.joints import BLAZEPOSE_INDEX
from swarmpose.errors import ConfigError

VIDEOS = Path(__file__).resolve().parents[3] / "shared" / "data" / "recordings" / "pose2sim-demo-single" / "videos"


def test_missing_mediapipe_says_how_to_install(no_mediapipe):
    from swarmpose.detection.mediapipe_pose import MediaPipePose

    with pytest.raises(ConfigError) as info:
        MediaPipePose()
    message = str(info.value)
    assert "pip install 'swarmpose[detect]'" in message
    assert "pip install --no-deps mediapipe==0.10.14" in message and "protobuf>=4.25.3,<5" in message


@pytest.fixture(scope="module")
def cam03_frames():
    pytest.importorskip("mediapipe", reason="MediaPipe is not installed (pip install 'swarmpose[detect]')")
    from swarmpose.detection.cache import iter_video_frames

    path = VIDEOS / "cam03.mp4"
    if not path.is_file():
        pytest.skip(f"the Pose2Sim demo recording is not at {path} (../shared beside the repo)")
    return list(iter_video_frames(path, 3))


def test_settings_are_checked():
    pytest.importorskip("mediapipe", reason="MediaPipe is not installed (pip install 'swarmpose[detect]')")
    from swarmpose.detection.mediapipe_pose import MediaPipePose

    with pytest.raises(ConfigError):
        MediaPipePose(model_complexity=3)
    with pytest.raises(ConfigError):
        MediaPipePose(mask_threshold=1.5)


def test_real_mediapipe_finds_the_person(cam03_frames):
    from swarmpose.detection.mediapipe_pose import MediaPipePose

    with MediaPipePose() as det:
        assert isinstance(det, PersonDetector) and len(det.keypoint_names) == 33
        h, w = cam03_frames[0].shape[:2]
        for frame in cam03_frames:
            d = det.detect(frame)
            assert d.found
            assert np.all((d.keypoints >= -0.5) & (d.keypoints <= [w - 0.5, h - 0.5]))
            assert d.confidence.min() >= 0 and d.confidence.max() <= 1 and np.median(d.confidence) > 0.5
            assert d.mask.shape == (h, w) and 0.02 < d.mask.mean() < 0.30
            for hip in ("left_hip", "right_hip"):
                u, v = np.round(d.keypoints[BLAZEPOSE_INDEX[hip]]).astype(int)
                assert d.mask[v, u] == 1, hip
        # a region of interest around the person gives nearly the same keypoints, in full-image pixels
        lo, hi = d.keypoints.min(axis=0) - 150, d.keypoints.max(axis=0) + 150
        r = det.detect(cam03_frames[-1], roi=(lo[0], lo[1], hi[0], hi[1]))
        assert r.found and np.median(np.linalg.norm(r.keypoints - d.keypoints, axis=1)) < 25
        x0, y0 = np.maximum(lo, 0).round().astype(int)
        assert r.mask[:y0].sum() == 0 and r.mask[:, :x0].sum() == 0
