"""Overlays: cones drawn where they project, in the side's colour; files, frame choice and videos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from swarmpose.errors import ConfigError
from swarmpose.report import load_results, overlay_video, overlays, render_overlay
from swarmpose.report._style import SIDE_RGB
from swarmpose.report.overlay import CROP_ASPECT, choose_frames, crop_boxes, video_backends


def _dominant(px: np.ndarray, grey: int = 128, alpha: float = 0.35) -> str:
    """The side whose cone colour, blended over ``grey``, is nearest to the pixel (or "none")."""
    cands = {"none": np.array([grey] * 3, float)}
    for side, rgb in SIDE_RGB.items():
        cands[side] = (1 - alpha) * grey + alpha * np.array(rgb, float)
    dist = {k: float(np.abs(px.astype(float) - v).max()) for k, v in cands.items()}
    best = min(dist, key=dist.get)
    return best if dist[best] < 12 else "unclear"


def _views(res) -> tuple[list, np.ndarray]:
    """The results' cameras and a mid-grey image per view."""
    with res.open_sequence() as seq:
        cams = list(seq.cameras)
    return cams, np.full((len(cams), cams[0].height, cams[0].width), 128, np.uint8)


def test_cones_drawn_where_they_project(fake_results):
    res = load_results(fake_results[0])
    model = res.model
    pose = res.runs[0].params[2]
    cams, grey = _views(res)
    C, H, W = grey.shape
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


def test_ground_truth_skeleton_drawn_in_whole_and_cut_views(fake_results):
    """The head top lands where its view shows it; each view cut to the person is drawn at the views'
    height, with the joint where the cut maps it."""
    res = load_results(fake_results[0])
    r = res.runs[0]
    cams, grey = _views(res)
    C, H, W = grey.shape
    gt = r.gt_joints[1]
    boxes = crop_boxes(cams, np.vstack([r.joints[1], gt]))
    TW = round(H * CROP_ASPECT)
    for crop, x0, y0, zoom, left in ((None, 0.0, 0.0, 1.0, W + 4),
                                     (boxes, boxes[1][0], boxes[1][1], H / (boxes[1][3] - boxes[1][1]), TW + 4)):
        img = render_overlay(res.model, r.params[1] + 5.0, cams, grey, gt, legend=False, crop=crop)  # pose far off
        u, v = np.round((cams[1].project(gt[14]) - [x0, y0]) * zoom).astype(int)  # head top in view 2
        px = img[v, left + u].astype(int)
        assert px[0] > 180 and px[1] > 180 and px[2] < 120, px  # yellow
    assert img.shape == (H, C * TW + (C - 1) * 4, 3)
    for cam, (x0, y0, x1, y1) in zip(cams, boxes, strict=True):
        uv = cam.project(np.vstack([r.joints[1], gt]))
        assert x0 < uv[:, 0].min() and uv[:, 0].max() < x1 and y0 < uv[:, 1].min() and uv[:, 1].max() < y1
        assert (x1 - x0) / (y1 - y0) == pytest.approx(CROP_ASPECT)
        assert 0.3 * H - 1e-9 <= y1 - y0 < H  # the person is drawn larger than in the whole view
    with pytest.raises(ConfigError, match="one box"):
        render_overlay(res.model, r.params[1], cams, grey, gt, crop=boxes[:2])
    # no point in sight: the whole image, padded above and below to the aspect
    h = W / CROP_ASPECT
    assert crop_boxes(cams[:1], np.full((2, 3), np.nan)) == [pytest.approx((0.0, H / 2 - h / 2, W, H / 2 + h / 2))]


def test_marker_detections_drawn_as_rings(fake_results):
    """A marker tracker's input is shown: a sky-blue ring around each detection, none elsewhere."""
    from swarmpose.report._style import DETECTION_RGB

    res = load_results(fake_results[0])
    cams, grey = _views(res)
    C, H, W = grey.shape
    far = res.runs[0].params[0] + 50.0  # the body out of sight: only the rings are drawn
    dets = [np.array([[40.0, 30.0], [200.0, 150.0]]), np.zeros((0, 2)), np.array([[60.0, 90.0]])]
    img = render_overlay(res.model, far, cams, grey, None, legend=False, detections=dets)
    plain = render_overlay(res.model, far, cams, grey, None, legend=False)
    sky = np.array(DETECTION_RGB, float)

    def ring_near(view: int, u: float, v: float) -> bool:
        x0 = view * (W + 4)
        patch = img[int(v) - 9:int(v) + 10, x0 + int(u) - 9:x0 + int(u) + 10].reshape(-1, 3).astype(float)
        return bool(np.any(np.abs(patch - sky).max(axis=1) < 40))

    assert ring_near(0, 40, 30) and ring_near(0, 200, 150) and ring_near(2, 60, 90)
    assert not ring_near(1, 40, 30) and not ring_near(0, 120, 100)
    assert tuple(img[30, 40]) == (128, 128, 128)  # a ring, not a disc: the detection itself stays visible
    changed = np.any(img != plain, axis=2)
    assert changed[:, W + 4:2 * W + 4].sum() == 0  # the view without detections is untouched
    with pytest.raises(ConfigError, match="one array per view"):
        render_overlay(res.model, far, cams, grey, None, detections=dets[:2])


def test_overlay_files(fake_results, tmp_path: Path):
    res = load_results(fake_results[0])
    paths = overlays(res, 3, run=1, out_dir=tmp_path, crop=False)
    worst = int(res.frame_indices[np.argmax(res.run(1).d_per_frame)])
    assert [p.name for p in paths] == sorted(p.name for p in paths)
    assert any(p.name == f"overlay_run001_frame{worst:06d}.png" for p in paths)
    assert len(paths) == 3
    with Image.open(paths[0]) as im:
        assert im.size[0] == 3 * 240 + 2 * 4
        assert im.size[1] > 180
        arr = np.asarray(im.convert("RGB"))
    assert arr.std() > 20
    explicit = overlays(res, [6, 15], out_dir=tmp_path / "x", scale=0.5, crop=False)
    assert [p.name for p in explicit] == ["overlay_run000_frame000006.png", "overlay_run000_frame000015.png"]
    with Image.open(explicit[0]) as im:
        assert im.size[0] == round((3 * 240 + 2 * 4) * 0.5)
    # by default every view is cut to the person: tiles as tall as the views, 3 wide to 4 high
    cut = overlays(res, [6], out_dir=tmp_path / "cut")
    with Image.open(cut[0]) as im:
        assert im.size[0] == 3 * round(180 * CROP_ASPECT) + 2 * 4
    with pytest.raises(ConfigError, match="frame 7 was not tracked"):
        overlays(res, [7], out_dir=tmp_path / "y")


def test_choose_frames_includes_worst(fake_results):
    res = load_results(fake_results[0])
    assert choose_frames(res, 100).tolist() == list(range(6))
    pos = choose_frames(res, 2, run=1)
    assert len(pos) == 2 and int(np.argmax(res.run(1).d_per_frame)) in pos.tolist()
    with pytest.raises(ConfigError):
        choose_frames(res, 0)


def test_gif_video(fake_results, tmp_path: Path, monkeypatch):
    from swarmpose.report import overlay as overlay_module

    boxes = []
    draw = overlay_module.render_overlay
    monkeypatch.setattr(overlay_module, "render_overlay", lambda *a, **k: (boxes.append(k["crop"]), draw(*a, **k))[1])
    out = overlay_video(fake_results[0], tmp_path / "v.gif", every=2, scale=0.5)
    with Image.open(out) as im:
        assert im.n_frames == 3  # frames 0, 6, 12 of the 6 processed
        assert im.info["duration"] == 100  # 20 fps / every 2 = 10 fps
        assert im.size[0] == round((3 * round(180 * CROP_ASPECT) + 2 * 4) * 0.5)  # views cut to the person
    assert len(boxes) == 3 and boxes[0] is not None
    sizes = {(round(x1 - x0, 6), round(y1 - y0, 6)) for frame in boxes for x0, y0, x1, y1 in frame[:1]}
    assert len(sizes) == 1  # one size per view for the whole video: the zoom does not change
    whole = overlay_video(fake_results[0], tmp_path / "w.gif", every=2, scale=0.5, crop=False)
    with Image.open(whole) as im:
        assert im.size[0] == round((3 * 240 + 2 * 4) * 0.5)


def test_video_boxes_follow_the_person_smoothly(fake_results):
    from swarmpose.report.overlay import follow_boxes

    res = load_results(fake_results[0])
    r = res.runs[0]
    cams, _ = _views(res)
    pts = np.concatenate([r.joints, r.gt_joints], axis=1)
    pts[2, :, :] = np.nan  # a frame in which no view sees the person takes its neighbours' centre
    boxes = follow_boxes(cams, pts, window=3)
    assert len(boxes) == len(pts) and all(len(b) == len(cams) for b in boxes)
    for c, cam in enumerate(cams):
        view = np.array([b[c] for b in boxes])
        assert np.ptp(view[:, 2] - view[:, 0]) < 1e-9 and np.ptp(view[:, 3] - view[:, 1]) < 1e-9
        assert (view[:, 2] - view[:, 0]) / (view[:, 3] - view[:, 1]) == pytest.approx(CROP_ASPECT)
        for t in (0, 1, 3, len(pts) - 1):  # the person stays inside the box that follows it
            uv = cam.project(pts[t])
            x0, y0, x1, y1 = view[t]
            assert x0 < uv[:, 0].min() and uv[:, 0].max() < x1 and y0 < uv[:, 1].min() and uv[:, 1].max() < y1
        assert np.all(np.isfinite(view))
        # no wider than one frame's box needs: the size is the person's, not the path's
        assert view[0, 3] - view[0, 1] == pytest.approx(max(b[3] - b[1] for b in (crop_boxes([cam], p)[0] for p in pts
                                                                                   if np.isfinite(p).all())))


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


def test_gif_pictures_keep_uneven_frame_times():
    """25 fps from a 60 fps sequence tracks frames 33 and 50 ms apart: each GIF picture lasts until the next one,
    on GIF's 10-ms grid without drifting; even frames keep one duration."""
    from swarmpose.report.overlay import gif_durations_ms

    t = np.array([0, 2, 5, 7, 10, 12, 15, 17, 20, 22, 25]) / 60.0  # nearest 60-fps frames of a 25-fps clock
    d = gif_durations_ms(t, default_ms=40)
    assert d[:5] == [30, 50, 40, 50, 30] and d[-1] == 40
    assert abs(sum(d[:-1]) - 1000 * t[-1]) <= 5  # the clock, not the sum of rounded steps
    long = np.round(np.arange(0, 3000) / 25.0 * 60.0) / 60.0
    assert abs(sum(gif_durations_ms(long, default_ms=40)[:-1]) - 1000 * long[-1]) <= 5
    assert gif_durations_ms(np.arange(10) / 20.0, default_ms=50) == 50
    assert gif_durations_ms(np.array([0.0]), default_ms=50) == 50
    thirty = gif_durations_ms(np.arange(301) / 30.0, default_ms=33)  # 33.3 ms: GIF has 30 or 40
    assert set(thirty) == {30, 40} and abs(sum(thirty[:-1]) - 10_000) <= 5
