"""Overlays: cones drawn where they project, in the side's colour; files, frame choice and videos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarmpose.errors import ConfigError
from swarmpose.report import load_results, overlay_video, overlays, render_overlay
from swarmpose.report._style import SIDE_RGB
from swarmpose.report.overlay import choose_frames, video_backends


def _dominant(px: np.ndarray, grey: int = 128, alpha: float = 0.35) -> str:
    """The side whose cone colour, blended over ``grey``, is nearest to the pixel (or "none")."""
    cands = {"none": np.array([grey] * 3, float)}
    for side, rgb in SIDE_RGB.items():
        cands[side] = (1 - alpha) * grey + alpha * np.array(rgb, float)
    dist = {k: float(np.abs(px.astype(float) - v).max()) for k, v in cands.items()}
    best = min(dist, key=dist.get)
    return best if dist[best] < 12 else "unclear"


def test_cones_drawn_where_they_project(fake_results):
    res = load_results(fake_results[0])
    model = res.model
    pose = res.runs[0].params[2]
    with res.open_sequence() as seq:
        cams = list(seq.cameras)
    C, W, H = len(cams), cams[0].width, cams[0].height
    grey = np.full((C, H, W), 128, np.uint8)
    img = render_overlay(model, pose, cams, grey, None, title="", legend=False)
    assert img.shape == (H, C * W + (C - 1) * 4, 3)
    placed = model.cones(pose)
    names = model.cone_arrays.names
    cam = cams[0]  # frontal view
    for cone, side in (("torso", "center"), ("l_thigh", "left"), ("r_thigh", "right"), ("head", "center")):
        k = names.index(cone)
        mid = 0.5 * (placed.start[0, k] + placed.end[0, k])
        u, v = np.round(cam.project(mid)).astype(int)
        assert 0 <= u < W and 0 <= v < H
        assert _dominant(img[v, u]) == side, (cone, img[v, u])
    # far from the body the image stays grey
    assert tuple(img[3, 3]) == (128, 128, 128)


def test_ground_truth_skeleton_drawn(fake_results):
    res = load_results(fake_results[0])
    r = res.runs[0]
    with res.open_sequence() as seq:
        cams = list(seq.cameras)
    C, W, H = len(cams), cams[0].width, cams[0].height
    grey = np.full((C, H, W), 128, np.uint8)
    gt = r.gt_joints[1]
    img = render_overlay(res.model, r.params[1] + 5.0, cams, grey, gt, legend=False)  # pose far off
    u, v = np.round(cams[1].project(gt[14])).astype(int)  # head top in view 2
    px = img[v, W + 4 + u].astype(int)
    assert px[0] > 180 and px[1] > 180 and px[2] < 120, px  # yellow


def test_overlay_files(fake_results, tmp_path: Path):
    res = load_results(fake_results[0])
    paths = overlays(res, 3, run=1, out_dir=tmp_path)
    worst = int(res.frame_indices[np.argmax(res.run(1).d_per_frame)])
    assert [p.name for p in paths] == sorted(p.name for p in paths)
    assert any(p.name == f"overlay_run001_frame{worst:06d}.png" for p in paths)
    assert len(paths) == 3
    with Image.open(paths[0]) as im:
        assert im.size[0] == 3 * 240 + 2 * 4
        assert im.size[1] > 180
        arr = np.asarray(im.convert("RGB"))
    assert arr.std() > 20
    explicit = overlays(res, [6, 15], out_dir=tmp_path / "x", scale=0.5)
    assert [p.name for p in explicit] == ["overlay_run000_frame000006.png", "overlay_run000_frame000015.png"]
    with Image.open(explicit[0]) as im:
        assert im.size[0] == round((3 * 240 + 2 * 4) * 0.5)
    with pytest.raises(ConfigError, match="frame 7 was not tracked"):
        overlays(res, [7], out_dir=tmp_path / "y")


def test_choose_frames_includes_worst(fake_results):
    res = load_results(fake_results[0])
    assert choose_frames(res, 100).tolist() == list(range(6))
    pos = choose_frames(res, 2, run=1)
    assert len(pos) == 2 and int(np.argmax(res.run(1).d_per_frame)) in pos.tolist()
    with pytest.raises(ConfigError):
        choose_frames(res, 0)


def test_gif_video(fake_results, tmp_path: Path):
    out = overlay_video(fake_results[0], tmp_path / "v.gif", every=2, scale=0.5)
    with Image.open(out) as im:
        assert im.n_frames == 3  # frames 0, 6, 12 of the 6 processed
        assert im.info["duration"] == 100  # 20 fps / every 2 = 10 fps
        assert im.size[0] == round((3 * 240 + 2 * 4) * 0.5)


@pytest.mark.skipif(not any(v for k, v in video_backends().items() if k.startswith("mp4")),
                    reason="no FFmpeg here (imageio-ffmpeg or OpenCV's)")
def test_mp4_video(fake_results, tmp_path: Path):
    import cv2

    out = overlay_video(fake_results[0], tmp_path / "v.mp4", fps=5.0)
    cap = cv2.VideoCapture(str(out))
    try:
        assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 6
        assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(5.0)
        assert int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)) % 16 == 0
    finally:
        cap.release()


def test_bad_video_format(fake_results, tmp_path: Path):
    with pytest.raises(ConfigError, match="unknown video format"):
        overlay_video(fake_results[0], tmp_path / "v.avi")
