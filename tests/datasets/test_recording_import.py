"""Importing a recording: cameras matched by name, sizes fitted, offsets found, the subject kept, files written."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from recording_fixtures import FakeDetector, motion, rig, write_image_folders

from swarmpose.datasets.recording import ImportOptions, import_recording
from swarmpose.datasets.recording.match import fit_camera, frame_plan, match_cameras
from swarmpose.datasets.recording.subject import consistent_views
from swarmpose.detection.joints import SWAP15
from swarmpose.errors import DataError, FormatError
from swarmpose.io.calibration import write_calibration
from swarmpose.io.sequence import open_sequence
from swarmpose.triangulation import reproject

T = 24


def same_camera(a, b, tol: float = 1e-6) -> bool:
    """Equal to ``tol`` (intrinsics px, distortion, R, t mm), names and sizes exactly."""
    return (a.name, a.width, a.height) == (b.name, b.width, b.height) and all(
        np.allclose(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)), rtol=0, atol=tol)
        for f in ("fx", "fy", "cx", "cy", "skew", "dist", "R", "t"))


# ---------------------------------------------------------------------- matching and sizes
def test_cameras_are_matched_by_name_word_and_number():
    cams = ["int_cam01_img", "int_cam02_img", "side"]
    assert match_cameras(cams, ["cam02", "cam01"]) == [1, 0]
    assert match_cameras(["camera_1", "camera_2"], ["cam2", "c1"]) == [1, 0]
    assert match_cameras(["side", "front"], ["FRONT"]) == [1]


def test_an_unmatched_or_ambiguous_video_is_named():
    with pytest.raises(DataError, match=r"cam05.mp4: no camera named like 'cam05' in calib.toml \(its cameras: a1, b2"):
        match_cameras(["a1", "b2"], ["cam05"], calibration="calib.toml", sources=["cam05.mp4"])
    with pytest.raises(DataError, match="matches several cameras"):
        match_cameras(["cam_1_a", "cam_1_b"], ["cam1"])
    with pytest.raises(DataError, match="is matched by 'cam01' already"):
        match_cameras(["cam01"], ["cam01", "cam1"])


def test_a_frame_size_is_kept_scaled_padded_or_refused():
    cam = rig(1)[0]
    assert fit_camera(cam, (320, 240)) == (cam, None)
    half, note = fit_camera(cam, (160, 120), source="v.mp4")
    assert half == cam.scaled(0.5) and "0.5 times the size" in note
    X = np.array([[100.0, 200.0, 1000.0]])
    assert np.allclose(half.project(X), (cam.project(X) + 0.5) * 0.5 - 0.5)
    same, note = fit_camera(cam, (312, 240), source="v.mp4")
    assert same is cam and "padded by 8 px on the right" in note
    with pytest.raises(FormatError, match=r"v.mp4: .*frames are 300x240 but camera 'cam01' in c.toml is 320x240"):
        fit_camera(cam, (300, 240), source="v.mp4", calibration="c.toml")


def test_frame_plan_offsets_ranges_and_different_lengths():
    plan, notes = frame_plan([10, 10, 10], [0, 2, -1], step=2)
    assert plan[:, 0].tolist() == [1, 3, 5, 7] and (plan[:, 1] - plan[:, 0] == 2).all() and plan[0, 2] == 0
    with pytest.raises(DataError, match=r"b.mp4 has 8 \(2 fewer than a.mp4\).*--common-range"):
        frame_plan([10, 8], [0, 0], names=["a.mp4", "b.mp4"])
    plan, _ = frame_plan([10, 8], [0, 0], common_range=True)
    assert len(plan) == 8
    plan, notes = frame_plan([10, 10], [0, 0], start=2, stop=40)
    assert plan[:, 0].tolist() == list(range(2, 10)) and "stop at 10" in notes[0]


# ---------------------------------------------------------------------- the subject across views
def test_consistent_views_resolves_swaps_and_finds_somebody_else():
    cams = rig(4)
    pts = motion(T)
    kp = reproject(cams, pts)  # (T, C, 15, 2)
    cf = np.full(kp.shape[:-1], 0.9)
    kp[3:9, 1] = kp[3:9, 1][:, SWAP15]  # view 1 has left and right exchanged on frames 3-8
    other = reproject(cams, pts + [0, 1500, 0])
    kp[5, 2] = other[5, 2]  # view 2 sees somebody else on frame 5
    sel = consistent_views(cams, kp, cf, SWAP15, threshold=10.0)
    assert sel.swapped[3:9, 1].all() and sel.swapped.sum() == 6
    assert not sel.inlier[5, 2] and sel.inlier.sum() == T * 4 - 1
    assert np.allclose(sel.points, pts, atol=1e-6)
    fixed, _ = sel.apply(kp, cf, SWAP15)
    assert np.allclose(fixed[3:9, 1], reproject(cams, pts)[3:9, 1])


def test_a_mirrored_majority_keeps_the_detectors_labels():
    """Three of four views swapped is the same person mirrored: the three keep their labels, the one flips."""
    cams = rig(4)
    pts = motion(4)
    kp = reproject(cams, pts)
    kp[:, 1:] = kp[:, 1:][:, :, SWAP15]
    sel = consistent_views(cams, kp, np.full(kp.shape[:-1], 0.9), SWAP15, threshold=10.0)
    assert sel.swapped[:, 0].all() and not sel.swapped[:, 1:].any()


# ---------------------------------------------------------------------- the whole import, with a fake detector
@pytest.fixture()
def recording(tmp_path: Path):
    cams = rig(4)
    pts = motion(T)
    lag = {2: 2}  # camera 3 started 2 frames early: its frame k + 2 shows reference frame k
    folders = write_image_folders(tmp_path / "videos", cams, pts, lag=lag)
    write_calibration(tmp_path / "calib.toml", cams, "toml")
    return tmp_path, cams, pts, lag, folders


def test_import_finds_offsets_resolves_swaps_and_redetects_the_subject(recording):
    root, cams, pts, lag, folders = recording
    det = FakeDetector(cams, pts, lag=lag, swapped={(1, 4), (1, 5), (3, 10)}, other={(0, 7)})
    out = root / "seq"
    res = import_recording(folders, root / "calib.toml", out, detector=det, progress=False,
                           options=ImportOptions(fps=30, auto_offsets=True, max_offset=3, scale=0.5,
                                                 cache_dir=root / "cache"))
    assert res.offsets == [0, 0, 2, 0]
    assert res.offset_search["cost_after_px"] < res.offset_search["cost_before_px"]
    assert res.swapped_view_frames == 3 and res.redetected_view_frames == 1 and res.dropped_view_frames == 0
    assert max(res.residual_px.values()) < 0.05 and res.frame_residual_max_px < 0.05
    assert not any(p.name.startswith(".seq") for p in root.iterdir())  # no temporary folder left
    with open_sequence(out) as seq:
        assert seq.n_frames == T - 2 and seq.image_size == (160, 120) and seq.gt_joints is None
        assert seq.streams == ("image", "silhouette")
        for got, cam in zip(seq.cameras, cams, strict=True):
            assert same_camera(got, cam.scaled(0.5))
        dense, conf = seq.marker_data.to_dense()
        truth = reproject(seq.cameras, pts[:T - 2])
        assert np.allclose(dense, truth, atol=1e-6) and np.allclose(conf, 0.9)
        assert seq.silhouettes(0).max() == 1
    info = json.loads((out / "import" / "import.json").read_text())
    assert info["offsets"] == [0, 0, 2, 0] and info["cameras"] == ["cam01", "cam02", "cam03", "cam04"]
    # the detections are cached: a second import with other options detects nothing again
    det.calls = 0
    import_recording(folders, root / "calib.toml", root / "seq2", detector=det, progress=False,
                     options=ImportOptions(fps=30, offsets={"cam03": 2}, silhouettes="median", cache_dir=root / "cache"))
    assert det.calls == 1  # the one view-frame that needs the subject's region
    with open_sequence(root / "seq2") as seq:
        assert seq.streams == ("image",) and seq.backgrounds().shape == (4, 240, 320)
        images = seq.images(3)
        assert images[0][0, 1] == 3 and images[2][0, 1] == 5  # camera 3's own frame 3 + 2


def test_a_view_that_never_shows_the_subject_is_dropped_not_believed(recording):
    root, cams, pts, lag, folders = recording

    class Stubborn(FakeDetector):
        def detect(self, image, roi=None):
            return super().detect(image, None)  # the region does not help: still somebody else

    det = Stubborn(cams, pts, lag=lag, other={(0, 7)})
    res = import_recording(folders, root / "calib.toml", root / "seq", detector=det, progress=False,
                           options=ImportOptions(fps=30, offsets={"cam03": 2}, cache_dir=root / "cache"))
    assert res.dropped_view_frames == 1 and res.frame_residual_max_px < 0.05
    with open_sequence(root / "seq") as seq:
        dense, conf = seq.marker_data.to_dense()
        assert np.isnan(dense[7, 0]).all() and (conf[7, 0] == 0).all() and np.isfinite(dense[6, 0]).all()
