"""The resumable detection cache (swarmpose.detection.cache) with a fake detector that counts its calls."""

from __future__ import annotations

import os

import numpy as np
import pytest

from swarmpose.detection.base import Detection
from swarmpose.detection.cache import detect_video_frames, load_detections, video_identity
from swarmpose.errors import FormatError, ShapeError

T, H, W = 12, 24, 32


class Counting:
    """A detector whose keypoints are read off the frame (its grey level) and whose mask is a box."""

    name = "counting"
    version = "1.0"
    keypoint_names = ("p", "q")

    def __init__(self, offset: float = 0.0):
        self.offset = offset
        self.calls = 0
        self.resets = 0

    @property
    def settings(self):
        return {"offset": self.offset}

    def detect(self, image, roi=None):
        self.calls += 1
        level = int(image[0, 0])
        if level % 5 == 4:  # nobody in these frames
            return Detection.empty(2, (H, W))
        mask = np.zeros((H, W), np.uint8)
        mask[2: 2 + level % 7, 3: 3 + level % 11] = 1
        kp = np.array([[level, level + 0.25], [self.offset, -level]], float)
        return Detection(kp, np.array([0.5, level / 100]), mask, True)

    def reset(self):
        self.resets += 1


def frames(n=T, fail_at=None):
    for t in range(n):
        if t == fail_at:
            raise KeyboardInterrupt
        yield np.full((H, W), t, np.uint8)


def untouchable():
    raise AssertionError("a complete cache must not read the frames")
    yield  # pragma: no cover


def check(result, offset=0.0):
    assert result.complete and result.n_frames == T
    for t in range(T):
        if t % 5 == 4:
            assert not result.found[t] and np.isnan(result.keypoints[t]).all()
            assert result.mask(t).sum() == 0
            continue
        assert result.found[t]
        np.testing.assert_allclose(result.keypoints[t], [[t, t + 0.25], [offset, -t]])
        np.testing.assert_allclose(result.confidence[t], [0.5, t / 100], rtol=1e-6)
        expected = np.zeros((H, W), np.uint8)
        expected[2: 2 + t % 7, 3: 3 + t % 11] = 1
        np.testing.assert_array_equal(result.mask(t), expected)


def test_round_trip_and_no_second_detection(tmp_path):
    path = tmp_path / "views" / "cam1.npz"
    det = Counting()
    check(detect_video_frames(frames(), det, path, n_frames=T, progress=False))
    assert det.calls == T and det.resets == 1
    assert [p.name for p in path.parent.iterdir()] == ["cam1.npz"]  # no temporary file left
    with np.load(path, allow_pickle=False) as z:
        assert z["keypoints"].dtype == np.float32 and z["keypoints"].shape == (T, 2, 2)
        assert z["done"].all()
    loaded = load_detections(path)
    check(loaded)
    assert loaded.masks().shape == (T, H, W)
    again = detect_video_frames(untouchable(), det, path, n_frames=T, progress=False)
    check(again)
    assert det.calls == T


def test_interrupted_run_resumes_without_redetecting(tmp_path):
    path = tmp_path / "cam1.npz"
    det = Counting()
    with pytest.raises(KeyboardInterrupt):
        detect_video_frames(frames(fail_at=7), det, path, n_frames=T, save_every=3, progress=False)
    assert det.calls == 7
    partial = load_detections(path)
    assert partial.done.tolist() == [True] * 7 + [False] * 5  # saved on the way out, not only every 3
    det2 = Counting()
    check(detect_video_frames(frames(), det2, path, n_frames=T, save_every=3, progress=False))
    assert det2.calls == T - 7 and det2.resets == 1


def test_a_hole_in_the_done_frames_resets_the_tracker(tmp_path):
    path = tmp_path / "cam1.npz"
    detect_video_frames(frames(), Counting(), path, n_frames=T, progress=False)
    cached = load_detections(path)
    cached.done[[3, 4, 9]] = False
    cached.save(path)
    det = Counting()
    check(detect_video_frames(frames(), det, path, n_frames=T, progress=False))
    assert det.calls == 3 and det.resets == 2  # before frame 3, and before frame 9 (frames 5-8 skipped)


@pytest.mark.parametrize("change", ["setting", "version", "video", "n_frames"])
def test_a_changed_run_detects_again(tmp_path, change):
    path = tmp_path / "cam1.npz"
    detect_video_frames(frames(), Counting(), path, n_frames=T, video={"path": "a.mp4", "size": 1}, progress=False)
    det = Counting(offset=2.5 if change == "setting" else 0.0)
    if change == "version":
        det.version = "1.1"
    video = {"path": "a.mp4", "size": 2 if change == "video" else 1}
    n = T - 2 if change == "n_frames" else T
    result = detect_video_frames(frames(), det, path, n_frames=n, video=video, progress=False)
    assert det.calls == n
    assert result.meta["detector"]["settings"] == det.settings
    if change == "setting":
        check(result, offset=2.5)


def test_video_identity_follows_the_file(tmp_path):
    video = tmp_path / "v.mp4"
    video.write_bytes(b"x" * 10)
    path = tmp_path / "cam1.npz"
    det = Counting()
    detect_video_frames(frames(), det, path, n_frames=T, video=video, progress=False)
    assert load_detections(path).meta["video"] == video_identity(video)
    detect_video_frames(untouchable(), det, path, n_frames=T, video=video, progress=False)
    st = video.stat()
    os.utime(video, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    detect_video_frames(frames(), det, path, n_frames=T, video=video, progress=False)
    assert det.calls == 2 * T


def test_damaged_cache_is_redone_with_a_warning(tmp_path):
    path = tmp_path / "cam1.npz"
    path.write_bytes(b"PK\x03\x04 not really a zip")
    det = Counting()
    with pytest.warns(UserWarning, match="unreadable"):
        check(detect_video_frames(frames(), det, path, n_frames=T, progress=False))
    assert det.calls == T
    path.write_bytes(b"garbage")
    with pytest.raises(FormatError):
        load_detections(path)


def test_too_few_frames_warns_and_too_many_are_ignored(tmp_path):
    with pytest.warns(UserWarning, match="after 5 of 12"):
        short = detect_video_frames(frames(5), Counting(), tmp_path / "a.npz", n_frames=T, progress=False)
    assert short.done.sum() == 5 and not short.complete
    det = Counting()
    check(detect_video_frames(frames(T + 4), det, tmp_path / "b.npz", n_frames=T, progress=False))
    assert det.calls == T


def test_frames_of_another_size_are_refused(tmp_path):
    def mixed():
        yield np.zeros((H, W), np.uint8)
        yield np.zeros((H + 1, W), np.uint8)

    with pytest.raises(ShapeError):
        detect_video_frames(mixed(), Counting(), tmp_path / "a.npz", n_frames=2, progress=False)
    assert load_detections(tmp_path / "a.npz").done.tolist() == [True, False]
