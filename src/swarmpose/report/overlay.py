"""Overlay images of a tracked run: the estimated cones and the ground truth on the camera views.

Every view of a frame is drawn as a tile: the camera image in grey, each truncated cone of the
tracked pose filled semi-transparently and outlined (left limbs blue, right limbs orange, torso
and head green; far cones first), and the ground-truth 15-joint skeleton in yellow with a dark
border. Runs tracked on 2D markers also show the frame's detections (sky-blue rings, false ones
included: what the tracker was given; in a cut-out view, those inside it). The tiles sit side by
side (at most ``columns`` per row) under a title line with the frame index, its time and the 3D
error D, above a legend (thesis Fig. 6.3/6.6 show such views).

The report cuts each view to the person (:func:`crop_boxes`: the estimated and true joints with a
margin; in a video :func:`follow_boxes`, one size per view moving smoothly with the person) and draws
the cut-outs at the views' height, so the body is large enough to judge; ``crop=False`` keeps the
whole views.

Cone outlines come from :func:`swarmpose.render.project_cones` (the same geometry the fitness
uses: exact occluding contours of the truncated cones, with lens distortion).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from swarmpose.errors import ConfigError, DataError
from swarmpose.joints import BONES15
from swarmpose.report._style import DETECTION_RGB, GT_RGB, SIDE_RGB, bgr
from swarmpose.report.results import Results, as_results

__all__ = ["render_overlay", "overlays", "overlay_video", "choose_frames", "crop_boxes", "follow_boxes",
           "gif_durations_ms", "mp4_is_h264", "video_backends"]

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_SHIFT = 4  # sub-pixel bits for cv2 drawing
_ONE = 1 << _SHIFT


def _fixed(pts: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(pts, dtype=np.float64) * _ONE).astype(np.int32)


def _drawable(uv: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
    """Which image points can be drawn: finite, not absurdly far off, and (given depths) in front."""
    ok = np.all(np.isfinite(uv), axis=1) & np.all(np.abs(uv) < 1e5, axis=1)
    return ok if z is None else ok & (z > 1.0)


def _label(img: np.ndarray, text: str, org: tuple[int, int], scale: float = 0.55) -> None:
    (w, h), base = cv2.getTextSize(text, _FONT, scale, 1)
    x, y = org
    cv2.rectangle(img, (x - 3, y - h - 4), (x + w + 3, y + base + 1), (25, 25, 25), -1)
    cv2.putText(img, text, (x, y), _FONT, scale, (235, 235, 235), 1, cv2.LINE_AA)


def _draw_view(tile: np.ndarray, polys: list[np.ndarray], depths: list[float], sides: Sequence[str],
               gt_uv: np.ndarray | None, gt_ok: np.ndarray | None, alpha: float, line: int,
               detections: np.ndarray | None = None) -> None:
    """Draw cones (far first), the 2D detections and the ground-truth skeleton onto one BGR tile, in place."""
    for k in np.argsort(-np.asarray(depths)):
        poly = polys[k]
        if poly is None:
            continue
        colour = bgr(SIDE_RGB.get(sides[k], SIDE_RGB["center"]))
        pts = _fixed(poly)[None]
        layer = tile.copy()
        cv2.fillPoly(layer, pts, colour, cv2.LINE_AA, _SHIFT)
        cv2.addWeighted(layer, alpha, tile, 1.0 - alpha, 0.0, dst=tile)
        cv2.polylines(tile, pts, True, colour, line, cv2.LINE_AA, _SHIFT)
    if detections is not None:
        det = np.asarray(detections, dtype=np.float64).reshape(-1, 2)
        for uv in det[_drawable(det)]:
            c = tuple(_fixed(uv))
            cv2.circle(tile, c, (line + 4) * _ONE, (20, 20, 20), line + 2, cv2.LINE_AA, _SHIFT)
            cv2.circle(tile, c, (line + 4) * _ONE, bgr(DETECTION_RGB), line, cv2.LINE_AA, _SHIFT)
    if gt_uv is None:
        return
    gt_col = bgr(GT_RGB)
    for a, b in BONES15:
        if gt_ok[a] and gt_ok[b]:
            p, q = _fixed(gt_uv[a]), _fixed(gt_uv[b])
            cv2.line(tile, tuple(p), tuple(q), (20, 20, 20), line + 2, cv2.LINE_AA, _SHIFT)
            cv2.line(tile, tuple(p), tuple(q), gt_col, line, cv2.LINE_AA, _SHIFT)
    for j in np.flatnonzero(gt_ok):
        c = tuple(_fixed(gt_uv[j]))
        cv2.circle(tile, c, (line + 2) * _ONE, (20, 20, 20), -1, cv2.LINE_AA, _SHIFT)
        cv2.circle(tile, c, (line + 1) * _ONE, gt_col, -1, cv2.LINE_AA, _SHIFT)


def _legend(width: int, height: int, scale: float, detections: bool = False, truth: bool = True) -> np.ndarray:
    bar = np.full((height, width, 3), 40, np.uint8)
    x = 10
    y = height // 2
    s = 0.5 * scale
    items = [(SIDE_RGB["left"], "left limbs"), (SIDE_RGB["right"], "right limbs"),
             (SIDE_RGB["center"], "torso / head")] + ([(GT_RGB, "ground truth (15 joints)")] if truth else [])
    if detections:
        items.append((DETECTION_RGB, "2D detections"))
    for rgb, text in items:
        sw = max(int(14 * scale), 6)
        cv2.rectangle(bar, (x, y - sw // 2), (x + sw, y + sw // 2), bgr(rgb), -1)
        x += sw + 6
        cv2.putText(bar, text, (x, y + int(5 * scale)), _FONT, s, (230, 230, 230), 1, cv2.LINE_AA)
        (w, _), _ = cv2.getTextSize(text, _FONT, s, 1)
        x += w + 22
    return bar


#: Width / height of a cut-out view (a standing person is taller than wide).
CROP_ASPECT = 0.75


def _person_box(cam, pts: np.ndarray, margin: float, aspect: float,
                min_height_frac: float) -> tuple[float, float, float, float] | None:
    """:func:`crop_boxes`'s box for one view, or None when the view sees none of the points."""
    uv = np.zeros((0, 2))
    if len(pts):
        uv, z = cam.project_with_depth(pts)
        uv = uv[_drawable(uv, z)]
    if len(uv) == 0:
        return None
    (x0, y0), (x1, y1) = uv.min(axis=0), uv.max(axis=0)
    grow = margin * max(y1 - y0, (x1 - x0) / aspect, 1.0)
    return _with_aspect(x0 - grow, y0 - grow, x1 + grow, y1 + grow, aspect, min_height_frac * cam.height)


def _with_aspect(x0: float, y0: float, x1: float, y1: float, aspect: float,
                 min_height: float = 0.0) -> tuple[float, float, float, float]:
    """The box with the same centre grown to ``aspect`` (width / height) and ``min_height``."""
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    h = max(y1 - y0, (x1 - x0) / aspect, min_height)
    w = aspect * h
    return (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)


def _whole_view(cam, aspect: float) -> tuple[float, float, float, float]:
    return _with_aspect(0.0, 0.0, float(cam.width), float(cam.height), aspect)


def _points(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return pts[np.all(np.isfinite(pts), axis=1)]


def crop_boxes(cameras: Sequence, points: np.ndarray, *, margin: float = 0.25, aspect: float = CROP_ASPECT,
               min_height_frac: float = 0.3) -> list[tuple[float, float, float, float]]:
    """Per view, a box ``(x0, y0, x1, y1)`` in pixels around the projections of ``points``.

    The box is the points' bounding box grown by ``margin`` of its height on every side (the cones'
    thickness, the head and the feet lie beyond the joints), widened or heightened to ``aspect``
    (width / height), and at least ``min_height_frac`` of the image tall (a distant view is not
    blown up beyond ~3x). It may reach past the image (drawn dark there). A view that sees none of the
    points gets the whole image, padded to the aspect.

    Parameters
    ----------
    cameras : sequence of Camera
    points : numpy.ndarray, shape (..., 3)
        World points, mm (e.g. the estimated and true joints of one frame).
    """
    pts = _points(points)
    boxes = []
    for cam in cameras:
        box = _person_box(cam, pts, margin, aspect, min_height_frac)
        boxes.append(box if box is not None else _whole_view(cam, aspect))
    return boxes


def follow_boxes(cameras: Sequence, points: np.ndarray, *, window: int = 1, margin: float = 0.25,
                 aspect: float = CROP_ASPECT, min_height_frac: float = 0.3) -> list[list[tuple[float, ...]]]:
    """Boxes that follow the person through a video: ``boxes[t][c]`` for frame ``t`` and view ``c``.

    Each view keeps one size for the whole video (the largest of its :func:`crop_boxes` boxes, so the
    zoom does not change) and moves its centre with the person, averaged over ``window`` frames so
    that it does not jitter. Frames where a view sees no point take the centre of their neighbours.

    Parameters
    ----------
    cameras : sequence of Camera
    points : numpy.ndarray, shape (T, P, 3)
        World points per frame, mm (estimated and true joints).
    window : int, default 1
        Frames of the centred moving average of the box centres.
    """
    from scipy.ndimage import uniform_filter1d

    T = len(points)
    per_view = []
    for cam in cameras:
        boxes = [_person_box(cam, _points(points[t]), margin, aspect, min_height_frac) for t in range(T)]
        seen = np.array([b is not None for b in boxes])
        if not seen.any():
            per_view.append([_whole_view(cam, aspect)] * T)
            continue
        b = np.array([bx for bx in boxes if bx is not None])
        h = float((b[:, 3] - b[:, 1]).max())
        w = aspect * h
        t = np.arange(T)
        centres = np.stack([np.interp(t, t[seen], 0.5 * (b[:, 0] + b[:, 2])),
                            np.interp(t, t[seen], 0.5 * (b[:, 1] + b[:, 3]))], axis=1)
        centres = uniform_filter1d(centres, size=max(1, int(window)), axis=0, mode="nearest")
        per_view.append([(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2) for cx, cy in centres])
    return [[view[t] for view in per_view] for t in range(T)]


def _cut(img: np.ndarray, box: tuple[float, float, float, float],
         size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The part of ``img`` inside ``box`` resized to ``size`` = (width, height), dark beyond the image;
    with the map of image pixels into it, ``uv -> (uv - origin) * zoom``, as ``(cut, origin, zoom)``."""
    x0, y0, x1, y1 = box
    tw, th = size
    origin, zoom = np.array([x0, y0]), np.array([tw / (x1 - x0), th / (y1 - y0)])
    M = np.array([[zoom[0], 0.0, -x0 * zoom[0]], [0.0, zoom[1], -y0 * zoom[1]]])
    interp = cv2.INTER_AREA if zoom[0] < 1 else cv2.INTER_LINEAR
    cut = cv2.warpAffine(img, M, (tw, th), flags=interp, borderMode=cv2.BORDER_CONSTANT, borderValue=(30, 30, 30))
    return cut, origin, zoom


def render_overlay(
    model,
    pose: np.ndarray,
    cameras: Sequence,
    images: np.ndarray | None,
    gt_joints: np.ndarray | None = None,
    *,
    title: str = "",
    alpha: float = 0.35,
    columns: int = 4,
    scale: float = 1.0,
    legend: bool = True,
    detections: Sequence[np.ndarray] | None = None,
    crop: Sequence[tuple[float, float, float, float]] | None = None,
) -> np.ndarray:
    """Draw one frame: every view with the model's cones and the ground-truth skeleton.

    Parameters
    ----------
    model : BodyModel
        The tracked body model (its cones' ``side`` picks the colour).
    pose : numpy.ndarray, shape (D,)
        The estimated pose.
    cameras : sequence of Camera
        ``C`` calibrated cameras (one image size).
    images : numpy.ndarray of shape (C, H, W) uint8, or None
        The camera images (a dark background when None).
    gt_joints : numpy.ndarray of shape (15, 3), optional
        Ground-truth joints, world mm (:data:`swarmpose.joints.JOINTS15` order).
    title : str
        Text of the title line.
    alpha : float, default 0.35
        Opacity of the cone fill.
    columns : int, default 4
        Views per row.
    scale : float, default 1.0
        Resize factor of the whole picture.
    legend : bool, default True
        Add the colour legend below the views.
    detections : sequence of C arrays of shape (Q_c, 2), optional
        2D marker detections per view, pixels (drawn as rings; a marker tracker's input).
    crop : sequence of C boxes (x0, y0, x1, y1), optional
        Cut each view to its box (pixels, e.g. from :func:`crop_boxes`) and draw it at the views'
        height (the boxes share one aspect ratio: the first box's); None draws the whole views.

    Returns
    -------
    numpy.ndarray, shape (H', W', 3), uint8
        RGB picture.
    """
    from swarmpose.render import project_cones

    cams = list(cameras)
    C = len(cams)
    W, H = cams[0].width, cams[0].height
    if images is not None and np.asarray(images).shape != (C, H, W):
        raise ConfigError(f"images must be ({C}, {H}, {W}) for the cameras, got {np.shape(images)}")
    if not 0.0 <= alpha <= 1.0:
        raise ConfigError(f"alpha must be in [0, 1], got {alpha}")
    if not scale > 0:
        raise ConfigError(f"scale must be > 0, got {scale}")
    if detections is not None and len(detections) != C:
        raise ConfigError(f"detections must give one array per view ({C}), got {len(detections)}")
    if crop is not None:
        crop = [tuple(float(v) for v in b) for b in crop]
        if len(crop) != C or any(len(b) != 4 or not (b[2] > b[0] and b[3] > b[1]) for b in crop):
            raise ConfigError(f"crop must give one box (x0, y0, x1, y1) with x1 > x0, y1 > y0 per view ({C})")
    pose = model.check_poses(pose)
    if pose.shape[0] != 1:
        raise ConfigError(f"render_overlay draws one pose, got {pose.shape[0]}")
    pc = project_cones(model, pose, cams)
    sides = model.cone_arrays.sides
    line = 2 if max(W, H) >= 400 else 1
    TW, TH = (W, H) if crop is None else (max(1, round(H * (crop[0][2] - crop[0][0]) / (crop[0][3] - crop[0][1]))), H)
    tiles = []
    for c, cam in enumerate(cams):
        if images is not None:
            tile = cv2.cvtColor(np.ascontiguousarray(images[c]), cv2.COLOR_GRAY2BGR)
        else:
            tile = np.full((H, W, 3), 30, np.uint8)
        # drawn after the cut, in the cut-out's pixels, so that lines stay sharp
        origin, zoom = np.zeros(2), np.ones(2)
        if crop is not None:
            tile, origin, zoom = _cut(tile, crop[c], (TW, TH))

        def to_tile(uv: np.ndarray, origin=origin, zoom=zoom) -> np.ndarray:
            return (np.asarray(uv, dtype=np.float64) - origin) * zoom

        polys: list[np.ndarray | None] = []
        depths: list[float] = []
        for k in range(len(sides)):
            n = int(pc.n_vertices[0, c, k])
            if n < 3:
                polys.append(None)
                depths.append(0.0)
                continue
            polys.append(to_tile(pc.vertices[0, c, k, :n]))
            depths.append(float(np.nanmean(pc.depth[0, c, k, :n])))
        gt_uv = gt_ok = None
        if gt_joints is not None:
            uv, z = cam.project_with_depth(np.asarray(gt_joints, dtype=np.float64))
            gt_ok = _drawable(uv, z)
            gt_uv = to_tile(np.where(gt_ok[:, None], uv, 0.0))
        det = None
        if detections is not None:
            det = to_tile(np.asarray(detections[c], dtype=np.float64).reshape(-1, 2))
        _draw_view(tile, polys, depths, sides, gt_uv, gt_ok, alpha, line, det)
        _label(tile, cam.name, (8, 22))
        tiles.append(tile)
    cols = max(1, min(int(columns), C))
    rows = -(-C // cols)
    gap = 4
    grid = np.full((rows * TH + (rows - 1) * gap, cols * TW + (cols - 1) * gap, 3), 60, np.uint8)
    for i, tile in enumerate(tiles):
        r, q = divmod(i, cols)
        grid[r * (TH + gap):r * (TH + gap) + TH, q * (TW + gap):q * (TW + gap) + TW] = tile
    if scale != 1.0:
        interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
        grid = cv2.resize(grid, (max(1, round(grid.shape[1] * scale)), max(1, round(grid.shape[0] * scale))),
                          interpolation=interp)
    ts = max(0.45, min(1.0, grid.shape[1] / 1800.0))
    parts = [grid]
    if title:
        head = np.full((int(34 * ts) + 6, grid.shape[1], 3), 25, np.uint8)
        cv2.putText(head, title, (10, int(24 * ts) + 2), _FONT, 0.75 * ts, (245, 245, 245), 1, cv2.LINE_AA)
        parts.insert(0, head)
    if legend:
        truth = gt_joints is not None and bool(np.isfinite(np.asarray(gt_joints, dtype=np.float64)).any())
        parts.append(_legend(grid.shape[1], int(30 * ts) + 6, ts * 1.4, detections is not None, truth))
    out = np.vstack(parts)
    return cv2.cvtColor(out, cv2.COLOR_BGR2RGB)


def choose_frames(results: Results, count: int, run: int = 0) -> np.ndarray:
    """Positions (into the processed frames) of ``count`` frames: evenly spread, with the worst one (without
    ground truth, evenly spread only).

    Parameters
    ----------
    results : Results
    count : int
        How many frames (at least 1).
    run : int
        Run whose worst frame (highest D) is included.

    Returns
    -------
    numpy.ndarray, shape (<= count,), int64
        Sorted, unique positions ``0 .. T-1``.
    """
    if count < 1:
        raise ConfigError(f"the number of overlay frames must be at least 1, got {count}")
    T = len(results.frame_indices)
    if count >= T:
        return np.arange(T, dtype=np.int64)
    d = results.run(run).d_per_frame
    if not np.isfinite(d).any():  # no ground truth: no worst frame, the frames evenly spread
        return np.unique(np.round(np.linspace(0, T - 1, count)).astype(np.int64))
    pos = {int(i) for i in np.round(np.linspace(0, T - 1, count - 1))} if count > 1 else set()
    for i in np.argsort(-d, kind="stable"):  # the worst frame, then the next worst until full
        if len(pos) >= count:
            break
        pos.add(int(i))
    return np.array(sorted(pos), dtype=np.int64)


def _positions(res: Results, frames: int | Sequence[int] | None, run: int) -> np.ndarray:
    if frames is None:
        frames = 4
    if isinstance(frames, int | np.integer):
        return choose_frames(res, int(frames), run)
    fi = res.frame_indices
    out = []
    for f in frames:
        i = int(np.searchsorted(fi, int(f)))
        if i >= len(fi) or fi[i] != int(f):
            step = f" every {int(fi[1] - fi[0])}" if len(fi) > 1 else ""
            raise ConfigError(f"frame {f} was not tracked (tracked: sequence frames {int(fi[0])}..{int(fi[-1])}"
                              f"{step})")
        out.append(i)
    return np.array(out, dtype=np.int64)


def _title(res: Results, run: int, i: int) -> str:
    r = res.run(run)
    algo = str(res.config.get("algo", "")).upper()
    fps = f" {res.fps:g} fps" if res.fps else ""
    d = float(r.d_per_frame[i])
    if np.isfinite(d):
        err = f"D = {d:.1f} mm"
    else:
        err = "no ground truth" if res.summary.get("ground_truth", True) is False else "no valid ground truth"
    return (f"frame {int(r.frame_indices[i])}   t = {float(r.frame_times[i]):.3f} s   "
            f"{err}      {algo}{fps}, run {run}")


class _FrameSource:
    """Images per processed frame from the sequence (or none when it cannot be opened)."""

    def __init__(self, res: Results, sequence: str | os.PathLike[str] | None):
        from swarmpose.track.tracker import MARKER_FITNESS

        self.seq = res.open_sequence(sequence)
        self.cameras = list(self.seq.cameras)
        self.backgrounds = self.seq.backgrounds()
        self.on_markers = res.config.get("fitness_kind") in MARKER_FITNESS

    def images(self, k: int) -> np.ndarray | None:
        img = self.seq.images(k)
        return img if img is not None else self.backgrounds

    def detections(self, k: int) -> list[np.ndarray] | None:
        """The 2D detections of frame ``k`` when the run tracked markers, else None."""
        return self.seq.markers(k) if self.on_markers else None

    def close(self) -> None:
        self.seq.close()


def overlays(
    results: str | os.PathLike[str] | Results,
    frames: int | Sequence[int] | None = 4,
    *,
    run: int = 0,
    out_dir: str | os.PathLike[str] | None = None,
    sequence: str | os.PathLike[str] | None = None,
    scale: float = 1.0,
    alpha: float = 0.35,
    crop: bool = True,
) -> list[Path]:
    """Write one overlay PNG per chosen frame (all views side by side; see :func:`render_overlay`).

    Parameters
    ----------
    results : path-like or Results
    frames : int or sequence of int, default 4
        A number: that many frames spread over the sequence, including the run's worst frame. A
        sequence: those sequence frame indices (they must have been tracked).
    run : int, default 0
        The run to draw.
    out_dir : path-like, optional
        Default ``RESULTS_DIR/report/overlays``.
    sequence : path-like, optional
        The sequence folder, when ``config.json``'s path no longer points to it.
    scale, alpha : see :func:`render_overlay`.
    crop : bool, default True
        Cut each view to the person (estimated and true joints, :func:`crop_boxes`); False: whole views.

    Returns
    -------
    list of pathlib.Path
        ``overlay_run000_frame000123.png`` files, in frame order.

    Raises
    ------
    DataError
        The sequence folder or the subject is missing.
    ConfigError
        A requested frame was not tracked, or no such run.
    """
    res = as_results(results)
    r = res.run(run)
    pos = _positions(res, frames, run)
    out = Path(out_dir) if out_dir is not None else res.path / "report" / "overlays"
    out.mkdir(parents=True, exist_ok=True)
    model = res.model
    src = _FrameSource(res, sequence)
    paths = []
    try:
        for i in pos:
            k = int(r.frame_indices[i])
            boxes = crop_boxes(src.cameras, np.vstack([r.joints[i], r.gt_joints[i]])) if crop else None
            rgb = render_overlay(model, r.params[i], src.cameras, src.images(k), r.gt_joints[i],
                                 title=_title(res, run, int(i)), scale=scale, alpha=alpha,
                                 detections=src.detections(k), crop=boxes)
            p = out / f"overlay_run{run:03d}_frame{k:06d}.png"
            if not cv2.imwrite(str(p), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)):
                raise DataError(f"{p}: cannot write the PNG")
            paths.append(p)
    finally:
        src.close()
    return paths


def _pad16(img: np.ndarray) -> np.ndarray:
    H, W = img.shape[:2]
    H2, W2 = -(-H // 16) * 16, -(-W // 16) * 16
    if (H2, W2) == (H, W):
        return img
    out = np.zeros((H2, W2, 3), np.uint8)
    out[:H, :W] = img
    return out


def video_backends() -> dict[str, bool]:
    """Which video writers work here: ``{"gif": ..., "mp4-imageio-ffmpeg": ..., "mp4-opencv": ...}``."""
    try:
        import imageio_ffmpeg  # noqa: F401

        has_ffmpeg = True
    except ImportError:
        has_ffmpeg = False
    return {"gif": True, "mp4-imageio-ffmpeg": has_ffmpeg, "mp4-opencv": _opencv_mp4_ok()}


def mp4_is_h264() -> bool:
    """Whether an MP4 written here is H.264, which browsers play: imageio with imageio-ffmpeg (the ``video``
    extra). Without them OpenCV's bundled FFmpeg writes MPEG-4 Part 2, which most browsers do not play."""
    try:
        import imageio.v2  # noqa: F401
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        return False
    return True


def _opencv_mp4_ok() -> bool:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        w = cv2.VideoWriter(str(Path(d) / "t.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (32, 32))
        ok = w.isOpened()
        w.release()
    return bool(ok)


class _Mp4Writer:
    def __init__(self, path: Path, fps: float):
        self.path, self.fps = path, fps
        self.writer = None
        self.kind = None

    def append(self, rgb: np.ndarray) -> None:
        rgb = _pad16(rgb)
        if self.writer is None:
            try:
                import imageio.v2 as iio2
                import imageio_ffmpeg  # noqa: F401

                self.writer = iio2.get_writer(str(self.path), format="FFMPEG", mode="I", fps=self.fps,
                                              codec="libx264", quality=7, macro_block_size=16)
                self.kind = "imageio"
            except ImportError:
                H, W = rgb.shape[:2]
                w = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"), float(self.fps), (W, H))
                if not w.isOpened():
                    raise ConfigError("MP4 needs ffmpeg: install the 'video' extra (pip install "
                                      "'swarmpose[video]') or write a GIF") from None
                self.writer = w
                self.kind = "opencv"
        if self.kind == "imageio":
            self.writer.append_data(rgb)
        else:
            self.writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))

    def close(self) -> None:
        if self.writer is not None:
            (self.writer.close if self.kind == "imageio" else self.writer.release)()


def overlay_video(
    results: str | os.PathLike[str] | Results,
    path: str | os.PathLike[str] | None = None,
    *,
    run: int = 0,
    fps: float | None = None,
    fmt: str | None = None,
    every: int = 1,
    scale: float = 0.5,
    sequence: str | os.PathLike[str] | None = None,
    alpha: float = 0.35,
    crop: bool = True,
) -> Path:
    """Write the overlays of every processed frame as an animated GIF or an MP4 video.

    Parameters
    ----------
    results : path-like or Results
    path : path-like, optional
        Output file; default ``RESULTS_DIR/report/overlay_run000.gif`` (or ``.mp4``).
    run : int, default 0
    fps : float, optional
        Playback rate; default the tracking rate (real time).
    fmt : {"gif", "mp4"}, optional
        Default from ``path``'s suffix, else ``"gif"``. GIF is written with Pillow (frames are kept in
        memory as 256-colour images: fine for short clips; use ``every``/``scale`` for long ones);
        MP4 (H.264) uses imageio-ffmpeg (the ``video`` extra) when installed, else OpenCV's
        bundled FFmpeg (MPEG-4 part 2).
    every : int, default 1
        Use every ``every``-th processed frame.
    scale : float, default 0.5
        Resize factor of the pictures.
    sequence : path-like, optional
        The sequence folder, when ``config.json``'s path no longer points to it.
    alpha : float
        Cone fill opacity.
    crop : bool, default True
        Cut each view to the person with a box of one size per view that follows the person
        smoothly (:func:`follow_boxes`, half a second of averaging); False: whole views.

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ConfigError
        Unknown format, or MP4 without any FFmpeg.
    """
    from PIL import Image

    res = as_results(results)
    r = res.run(run)
    if path is not None and fmt is None:
        fmt = Path(path).suffix.lower().lstrip(".") or "gif"
    fmt = (fmt or "gif").lower()
    if fmt not in ("gif", "mp4"):
        raise ConfigError(f"unknown video format {fmt!r} (known: gif, mp4)")
    if every < 1:
        raise ConfigError(f"every must be >= 1, got {every}")
    out = Path(path) if path is not None else res.path / "report" / f"overlay_run{run:03d}.{fmt}"
    out.parent.mkdir(parents=True, exist_ok=True)
    rate = float(fps) if fps else (res.fps / every if res.fps else 10.0)
    if not rate > 0:
        raise ConfigError(f"fps must be > 0, got {fps}")
    model = res.model
    src = _FrameSource(res, sequence)
    gif_frames: list = []
    mp4 = _Mp4Writer(out, rate) if fmt == "mp4" else None
    try:
        shown = np.arange(0, len(r.frame_indices), every)
        boxes = None
        if crop:  # half a second of smoothing at the playback rate
            window = max(1, round(0.5 * res.fps / every)) if res.fps else 1
            boxes = follow_boxes(src.cameras, np.concatenate([r.joints[shown], r.gt_joints[shown]], axis=1),
                                 window=window)
        for n, i in enumerate(shown):
            k = int(r.frame_indices[i])
            rgb = render_overlay(model, r.params[i], src.cameras, src.images(k), r.gt_joints[i],
                                 title=_title(res, run, int(i)), scale=scale, alpha=alpha,
                                 detections=src.detections(k), crop=None if boxes is None else boxes[n])
            if mp4 is not None:
                mp4.append(rgb)
            else:
                gif_frames.append(Image.fromarray(rgb).quantize(colors=256, method=Image.Quantize.FASTOCTREE))
    finally:
        src.close()
        if mp4 is not None:
            mp4.close()
    if mp4 is None:
        # real time: each picture lasts until the next tracked frame (25 from 60 fps: 33 or 50 ms); a given
        # rate: even steps. Either on GIF's 10-ms clock, so that 30 fps does not play as 33 (30 ms each).
        times = r.frame_times[shown] if not fps else np.arange(len(shown)) / rate
        durations = gif_durations_ms(times, default_ms=max(20, int(round(1000.0 / rate))))
        gif_frames[0].save(out, save_all=True, append_images=gif_frames[1:], duration=durations, loop=0,
                           optimize=False, disposal=1)
    return out


def gif_durations_ms(times_s: np.ndarray, *, default_ms: int) -> int | list[int]:
    """How long each GIF picture is shown so that the pictures keep their frames' times.

    GIF counts in hundredths of a second, so the frame times are rounded on the cumulative clock (errors do not
    add up over a long clip: 30 fps alternates 30 and 40 ms); the last picture lasts as long as the mean step.
    Fewer than two frames give ``default_ms``. Every duration is at least 20 ms (browsers slow shorter ones
    down), so above 50 pictures per second a GIF plays slower than real time; an MP4 does not.
    """
    t = np.asarray(times_s, dtype=np.float64)
    if t.size < 2 or not np.all(np.isfinite(t)):
        return default_ms
    step = np.diff(t)
    if np.ptp(step) < 1e-6 and abs(step[0] * 100.0 - round(step[0] * 100.0)) < 1e-6:
        return max(20, int(round(step[0] * 1000.0)))  # whole hundredths: one duration for all
    clock = np.round((t - t[0]) * 100.0) * 10.0  # ms, on the GIF's 10-ms grid
    steps = np.append(np.diff(clock), round(float(step.mean()) * 100.0) * 10.0)
    return [max(20, int(v)) for v in steps]
