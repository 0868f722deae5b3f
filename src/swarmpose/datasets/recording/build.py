"""Import a recording: one video or image folder per camera plus a calibration file become a sequence folder.

The steps (``docs/recordings.md``):

1. the calibration is read (:func:`swarmpose.io.calibration.read_calibration`: mm, z up), each video is
   matched to its camera by name and its frame size to the calibration's (scaled or padded, said so);
2. the person is detected in every frame of every view once (MediaPipe Pose: 2D keypoints with confidences
   and a segmentation mask), through a resumable cache;
3. optionally, per-camera frame offsets are estimated from the keypoints (:mod:`.sync`);
4. per frame, the views that show the subject consistently with the calibration are found and left and right
   resolved (:mod:`.subject`); a view that shows somebody else is detected again inside the region where the
   others put the subject, and dropped for that frame if it still disagrees;
5. the sequence is written to a temporary folder (grey images, the learned silhouettes restricted to the
   subject's region, the keypoints as the marker stream with their confidences, or backgrounds for
   background subtraction) with ``import/`` beside it (triangulated joints, residuals, settings), then moved
   into place: an error leaves nothing behind.

Residuals are in pixels of the videos (the calibration's resolution), whatever the import's scale.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import sys
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from swarmpose.camera import Camera
from swarmpose.datasets.recording.match import fit_camera, frame_plan, match_cameras, pad_to, with_size
from swarmpose.datasets.recording.subject import ViewSelection, consistent_views
from swarmpose.datasets.recording.sync import OffsetSearch, estimate_offsets
from swarmpose.detection.joints import MIN_CONFIDENCE
from swarmpose.errors import ConfigError, DataError
from swarmpose.io.sequence import MarkerData, SequenceWriter
from swarmpose.io.video import FrameSource, open_frames
from swarmpose.joints import JOINTS15
from swarmpose.triangulation import reproject, residuals

__all__ = ["ImportOptions", "RecordingImport", "import_recording", "SILHOUETTE_MODES", "IMPORT_DIR"]

SILHOUETTE_MODES = ("learned", "median", "background", "none")
#: The import's own files inside the sequence folder.
IMPORT_DIR = "import"
#: Frames sampled for a temporal-median background.
MEDIAN_FRAMES = 60


@dataclass
class ImportOptions:
    """How :func:`import_recording` builds the sequence (the CLI's ``swarmpose import`` options).

    Attributes
    ----------
    start, stop, step : int
        Reference frames ``start, start + step, ... < stop`` (stop None: to the end).
    scale : float
        Resize factor of the stored images (0.5: half size); the cameras are scaled with them.
    offsets : mapping of str to int, optional
        Frame offset per video or camera name (camera ``c`` shows reference frame ``k`` in its frame
        ``k + offset``); unnamed cameras 0.
    auto_offsets : bool
        Estimate the offsets from the keypoints (starting from ``offsets``).
    max_offset : int
        Largest offset the estimate tries, frames.
    common_range : bool
        Accept videos of different lengths (the frames all of them have).
    silhouettes : {"learned", "median", "background", "none"}
        The person segmentation of the detector; background subtraction against the temporal median of
        the frames or against ``background`` (the tracker computes the silhouettes); or none.
    background : sequence of path, optional
        Empty-scene videos, images or image folders, one per camera in the order of the videos.
    detect : bool
        Run the detector (keypoints; needed by ``learned``, ``auto_offsets``).
    threshold : float, optional
        Largest median residual (px) of a view that shows the subject; default 2.5 % of the image diagonal.
    fps : float, optional
        Frame rate of image folders (videos state theirs).
    units, up : str, optional
        The calibration's length unit and up axis, when its format does not state them.
    extrinsics : path, optional
        The EasyMocap ``extri.yml`` beside an ``intri.yml``.
    cache_dir : path
        Where detections are kept between imports.
    """

    start: int = 0
    stop: int | None = None
    step: int = 1
    scale: float = 1.0
    offsets: Mapping[str, int] | None = None
    auto_offsets: bool = False
    max_offset: int = 5
    common_range: bool = False
    silhouettes: str = "learned"
    background: Sequence[str | os.PathLike[str]] | None = None
    detect: bool = True
    threshold: float | None = None
    fps: float | None = None
    units: str | None = None
    up: str | None = None
    extrinsics: str | os.PathLike[str] | None = None
    cache_dir: str | os.PathLike[str] = "cache/detections"


@dataclass
class RecordingImport:
    """What :func:`import_recording` did (also written to ``import/import.json``)."""

    path: Path
    n_frames: int
    frame_rate: float
    cameras: list[str]
    videos: list[str]
    image_size: tuple[int, int]
    offsets: list[int]
    offset_search: dict[str, Any] | None
    residual_px: dict[str, float] = field(default_factory=dict)
    frame_residual_max_px: float | None = None
    worst_frame: int | None = None
    swapped_view_frames: int = 0
    redetected_view_frames: int = 0
    dropped_view_frames: int = 0
    found_rate: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["path"] = str(self.path)
        return d


def _say(progress: bool, text: str) -> None:
    if progress:
        print(text, file=sys.stderr, flush=True)


def _offset_list(names: Sequence[str], cam_names: Sequence[str], offsets: Mapping[str, int] | None) -> list[int]:
    out = [0] * len(names)
    for key, value in (offsets or {}).items():
        hits = [c for c in range(len(names)) if key in (names[c], cam_names[c])]
        if not hits:
            raise ConfigError(f"--offset {key}={value}: no video or camera named {key!r} (videos: {', '.join(names)})")
        out[hits[0]] = int(value)
    return out


def _cache_file(cache_dir: Path, src: FrameSource, detector: Any) -> Path:
    st = src.path.stat()
    key = hashlib.sha1(json.dumps([str(src.path.resolve()), st.st_size, int(st.st_mtime), detector.name,
                                   detector.version, detector.settings], sort_keys=True).encode()).hexdigest()[:12]
    return cache_dir / f"{src.name}-{key}.npz"


def _detect_all(sources: Sequence[FrameSource], n_needed: Sequence[int], detector: Any, cache_dir: Path,
                progress: bool):
    from swarmpose.detection.cache import detect_video_frames

    out = []
    for src, n in zip(sources, n_needed, strict=True):
        frames = (img for _, img in src.frames(range(n)))
        st = src.path.stat()
        identity = {"path": str(src.path.resolve()), "bytes": st.st_size, "mtime": int(st.st_mtime),
                    "size": list(src.size), "frames": src.n_frames}
        detector.reset()
        out.append(detect_video_frames(frames, detector, _cache_file(cache_dir, src, detector), n_frames=n,
                                       video=identity, progress=progress))
    return out


def _joints15(detector: Any, keypoints: np.ndarray, confidence: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A detector's keypoints (..., K, 2) as the body model's 15 joints (the detector's mapping is data)."""
    from swarmpose.detection.joints import BLAZEPOSE33, to_joints15

    names = tuple(detector.keypoint_names)
    kp, cf = np.asarray(keypoints, np.float64), np.asarray(confidence, np.float64)
    if names == JOINTS15:
        return kp, cf
    if names == BLAZEPOSE33:
        return to_joints15(kp, cf)
    raise ConfigError(f"detector {detector.name!r}: no mapping from its keypoints ({', '.join(names[:4])}, ...) to the "
                      "body model's joints")


def _subject_box(uv: np.ndarray, size: tuple[int, int], margin: float = 0.25) -> tuple[int, int, int, int] | None:
    """The box around projected joints ``uv`` (J, 2), grown by ``margin`` of its height, or None."""
    ok = np.isfinite(uv).all(axis=1)
    if ok.sum() < 3:
        return None
    lo, hi = uv[ok].min(axis=0), uv[ok].max(axis=0)
    pad = margin * max(hi[1] - lo[1], hi[0] - lo[0], 1.0)
    x0, y0 = int(np.floor(lo[0] - pad)), int(np.floor(lo[1] - pad))
    x1, y1 = int(np.ceil(hi[0] + pad)) + 1, int(np.ceil(hi[1] + 0.5 * pad)) + 1  # feet: less below
    W, H = size
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    return None if x1 <= x0 or y1 <= y0 else (x0, y0, x1, y1)


def _median_background(src: FrameSource, indices: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    take = indices if len(indices) <= MEDIAN_FRAMES else indices[np.linspace(0, len(indices) - 1, MEDIAN_FRAMES).astype(int)]
    frames = [pad_to(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), size) for _, img in src.frames(np.unique(take))]
    return np.median(np.stack(frames), axis=0).astype(np.uint8)


def _resize(img: np.ndarray, size: tuple[int, int], nearest: bool = False) -> np.ndarray:
    if (img.shape[1], img.shape[0]) == size:
        return img
    return cv2.resize(img, size, interpolation=cv2.INTER_NEAREST if nearest else cv2.INTER_AREA)


def import_recording(
    sources: Sequence[str | os.PathLike[str]],
    calibration: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    options: ImportOptions | None = None,
    detector: Any = None,
    force: bool = False,
    progress: bool = True,
    on_selection: Callable[[ViewSelection], None] | None = None,
) -> RecordingImport:
    """Build a sequence folder from one video or image folder per camera and a calibration file.

    Parameters
    ----------
    sources : sequence of path
        One video file or image folder per camera, named after its camera.
    calibration : path
        A calibration file (TOML, OpenCV YAML/XML, EasyMocap ``intri.yml``, Qualisys ``.qca.txt``).
    out : path
        The sequence folder to write (must not exist, or ``force`` and hold a sequence).
    options : ImportOptions, optional
    detector : PersonDetector, optional
        Default: MediaPipe Pose (the ``detect`` extra).
    force : bool
        Replace an existing sequence folder.
    progress : bool
        Progress bars and steps on stderr.

    Returns
    -------
    RecordingImport

    Raises
    ------
    DataError, FormatError, ConfigError
        Bad input, named; nothing is written then.
    """
    opt = options or ImportOptions()
    owned = None
    if detector is None and opt.detect:
        from swarmpose.detection.mediapipe_pose import MediaPipePose

        detector = owned = MediaPipePose()  # a clear error, before anything else, when the extra is missing
    try:
        return _import(sources, calibration, out, opt, detector, force, progress, on_selection)
    finally:
        if owned is not None:
            owned.close()  # MediaPipe's graphs, before the interpreter's shutdown (which can hang on them)


def _import(sources, calibration, out, opt: ImportOptions, detector, force: bool, progress: bool,
            on_selection) -> RecordingImport:
    from swarmpose.io.calibration import read_calibration

    t_start = time.perf_counter()
    seconds: dict[str, float] = {}
    out = Path(out)
    if opt.silhouettes not in SILHOUETTE_MODES:
        raise ConfigError(f"--silhouettes {opt.silhouettes!r}: expected one of {', '.join(SILHOUETTE_MODES)}")
    if opt.silhouettes == "background" and not opt.background:
        raise ConfigError("--silhouettes background needs --background, one empty-scene video or image per camera")
    if opt.silhouettes == "learned" and not opt.detect:
        raise ConfigError("--silhouettes learned needs the detector (drop --no-detect)")
    if opt.auto_offsets and not opt.detect:
        raise ConfigError("--auto-offsets needs the detector's keypoints (drop --no-detect)")
    if not (np.isfinite(opt.scale) and 0 < opt.scale <= 1):
        raise ConfigError(f"--scale must be in (0, 1], got {opt.scale}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        if not force:
            raise DataError(f"{out}: exists and is not empty (--force replaces a sequence folder)")
        if not (out / "sequence.json").is_file():
            raise DataError(f"{out}: refusing to replace a folder that holds no sequence")
    if not sources:
        raise ConfigError("no video or image folder given")
    calib = read_calibration(calibration, extrinsics=opt.extrinsics, units=opt.units, up=opt.up)
    notes = list(calib.notes)
    srcs = [open_frames(p) for p in sources]
    names = [s.name for s in srcs]
    if len(set(names)) != len(names):
        raise ConfigError(f"two videos have one name: {', '.join(names)} (each is matched to its camera by name)")
    idx = match_cameras([c.name for c in calib.cameras], names, calibration=calibration, sources=[s.path for s in srcs])
    fitted = []
    for src, i in zip(srcs, idx, strict=True):
        cam, note = fit_camera(calib.cameras[i], src.size, source=src.path, calibration=calibration)
        fitted.append(cam)
        if note:
            notes.append(note)
    common = (max(c.width for c in fitted), max(c.height for c in fitted))
    if any((c.width, c.height) != common for c in fitted):
        notes.append(f"the cameras' images differ in size: every view is padded on the right and bottom to "
                     f"{common[0]}x{common[1]}")
    # the views are named after their videos (cam01), the calibration's names kept in the provenance
    cams = [dataclasses.replace(with_size(c, common), name=n) for c, n in zip(fitted, names, strict=True)]
    rates = {s.fps for s in srcs if s.fps is not None}
    if opt.fps is not None:
        fps = float(opt.fps)
    elif not rates:
        raise ConfigError("image folders state no frame rate: pass --fps")
    else:
        fps = max(rates)
        if max(rates) > min(rates) * 1.01:
            raise DataError("the videos have different frame rates: " + ", ".join(
                f"{s.path.name} {s.fps:g} fps" for s in srcs if s.fps is not None))
    backgrounds_src = None
    if opt.silhouettes == "background":
        if len(opt.background or ()) != len(srcs):
            raise ConfigError(f"--background: {len(opt.background or ())} given, one per video expected ({len(srcs)})")
        backgrounds_src = [open_frames(p) for p in opt.background or ()]
        for b, src in zip(backgrounds_src, srcs, strict=True):
            if b.size != src.size:
                raise DataError(f"{b.path}: the background is {b.size[0]}x{b.size[1]}, the video {src.path.name} "
                                f"{src.size[0]}x{src.size[1]}")
    offsets = _offset_list(names, [calib.cameras[i].name for i in idx], opt.offsets)
    plan, plan_notes = frame_plan([s.n_frames for s in srcs], offsets, start=opt.start, stop=opt.stop, step=opt.step,
                                  common_range=opt.common_range, names=[s.path.name for s in srcs])
    diag = float(np.hypot(*common))
    threshold = float(opt.threshold) if opt.threshold is not None else 0.025 * diag
    seconds["checks"] = time.perf_counter() - t_start

    # ---------------------------------------------------------------- detection
    dets = None
    search: OffsetSearch | None = None
    if opt.detect:
        from swarmpose.detection.joints import SWAP15

        # whole videos (a cache that serves any later range), or up to --stop (+ the offsets' margin)
        margin = opt.max_offset if opt.auto_offsets else 0
        n_needed = [s.n_frames if opt.stop is None else min(s.n_frames, int(plan[:, c].max()) + margin + 1)
                    for c, s in enumerate(srcs)]
        t0 = time.perf_counter()
        _say(progress, f"detecting the person in {len(srcs)} views ({detector.name}; cached in {opt.cache_dir})")
        dets = _detect_all(srcs, n_needed, detector, Path(opt.cache_dir), progress)
        seconds["detection"] = time.perf_counter() - t0
        kp15, cf15 = zip(*(_joints15(detector, d.keypoints, d.confidence) for d in dets), strict=True)
        if opt.auto_offsets:
            t0 = time.perf_counter()
            search = estimate_offsets(cams, kp15, cf15, SWAP15, threshold, start=offsets, max_offset=opt.max_offset)
            offsets = search.offsets
            plan, plan_notes = frame_plan([s.n_frames for s in srcs], offsets, start=opt.start, stop=opt.stop,
                                          step=opt.step, common_range=opt.common_range, names=[s.path.name for s in srcs])
            seconds["offsets"] = time.perf_counter() - t0
    notes.extend(plan_notes)
    T, C = plan.shape
    found_rate = {}
    sel = None
    kp = cf = None
    redetected = dropped = 0
    masks_override: dict[tuple[int, int], np.ndarray] = {}
    if dets is not None:
        kp = np.stack([kp15[c][plan[:, c]] for c in range(C)], axis=1)  # (T, C, 15, 2)
        cf = np.stack([cf15[c][plan[:, c]] for c in range(C)], axis=1)
        found_rate = {cams[c].name: float(dets[c].found[plan[:, c]].mean()) for c in range(C)}
        t0 = time.perf_counter()
        sel = consistent_views(cams, kp, cf, SWAP15, threshold)
        redo = np.argwhere(~sel.inlier & np.isfinite(sel.points).all(axis=(1, 2))[:, None])
        if redo.size:
            redetected, masks_override = _redetect(srcs, cams, plan, redo, sel, kp, cf, detector, common)
            sel = consistent_views(cams, kp, cf, SWAP15, threshold)
        kp, cf = sel.apply(kp, cf, SWAP15)
        bad = ~sel.inlier
        dropped = int((bad & np.isfinite(kp).all(axis=-1).any(axis=-1)).sum())
        kp = np.where(bad[..., None, None], np.nan, kp)
        cf = np.where(bad[..., None], 0.0, cf)
        seconds["subject"] = time.perf_counter() - t0
        if on_selection is not None:
            on_selection(sel)

    # ---------------------------------------------------------------- write
    t0 = time.perf_counter()
    size_out = cams[0].scaled(opt.scale).size if opt.scale != 1 else common
    cams_out = [c.scaled(opt.scale) if opt.scale != 1 else c for c in cams]
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    streams = ("image", "silhouette") if opt.silhouettes == "learned" else ("image",)
    try:
        backgrounds = None
        if opt.silhouettes in ("median", "background"):
            bg_from = backgrounds_src if backgrounds_src is not None else srcs
            bgs = []
            for c, b in enumerate(bg_from):
                ind = np.arange(b.n_frames) if backgrounds_src is not None else plan[:, c]
                bgs.append(_resize(_median_background(b, ind, common), size_out))
            backgrounds = np.stack(bgs)
            if backgrounds_src is None:
                notes.append(f"background subtraction against the temporal median of {min(T, MEDIAN_FRAMES)} frames "
                             "per camera (no empty-scene frame given): whoever stands still stays in the background")
        writer = SequenceWriter(tmp, cams_out, fps / opt.step, T, streams=streams)
        uv_subject = None if sel is None else reproject(cams, sel.points)  # (T, C, 15, 2) video px
        from tqdm import tqdm

        iters = [src.frames(plan[:, c]) for c, src in enumerate(srcs)]
        with tqdm(total=T, desc="write sequence", unit="frame", file=sys.stderr, disable=not progress) as bar:
            for t in range(T):
                images = np.empty((C, size_out[1], size_out[0]), np.uint8)
                sil = np.empty_like(images) if "silhouette" in streams else None
                for c in range(C):
                    _, img = next(iters[c])
                    images[c] = _resize(pad_to(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), common), size_out)
                    if sil is not None:
                        m = masks_override.get((t, c))
                        if m is None:
                            m = dets[c].mask(int(plan[t, c]))
                        m = np.zeros(srcs[c].size[::-1], np.uint8) if m is None else m
                        m = pad_to(m, common)
                        box = _subject_box(uv_subject[t, c], common)
                        if box is not None:
                            keep = np.zeros_like(m)
                            x0, y0, x1, y1 = box
                            keep[y0:y1, x0:x1] = m[y0:y1, x0:x1]
                            m = keep
                        sil[c] = _resize(m, size_out, nearest=True)
                frame = {"image": images}
                if sil is not None:
                    frame["silhouette"] = sil
                writer.write_frame(t, **frame)
                bar.update(1)
        markers = None
        if kp is not None:
            s = opt.scale
            markers = MarkerData.from_dense(JOINTS15, (kp + 0.5) * s - 0.5, np.clip(cf, 0, 1))
        provenance = {
            "kind": "recording",
            "videos": [str(s.path) for s in srcs],
            "calibration": [str(p) for p in calib.paths],
            "calibration_format": calib.format,
            "camera_of_video": {n: calib.cameras[i].name for n, i in zip(names, idx, strict=True)},
            "units": calib.units, "up": calib.up,
            "world_from_calibration": np.asarray(calib.world_from_file).tolist(),
            "frames": {"start": int(plan[0, 0] - offsets[0]), "step": opt.step, "video_frames": plan.tolist()},
            "offsets": dict(zip(names, offsets, strict=True)),
            "scale": opt.scale,
            "silhouettes": opt.silhouettes,
            "detector": None if detector is None or not opt.detect else
            {"name": detector.name, "version": detector.version, "settings": detector.settings},
        }
        writer.finish(backgrounds=backgrounds, frame_times=np.arange(T) * opt.step / fps, markers=markers,
                      provenance=provenance)
        result = RecordingImport(path=out, n_frames=T, frame_rate=fps / opt.step, cameras=[c.name for c in cams],
                                 videos=[str(s.path) for s in srcs], image_size=size_out, offsets=offsets,
                                 offset_search=None, found_rate=found_rate, notes=notes,
                                 redetected_view_frames=redetected, dropped_view_frames=dropped)
        if search is not None:
            result.offset_search = {"offsets": search.offsets, "cost_before_px": search.cost_before,
                                    "cost_after_px": search.cost_after, "frames": search.frames,
                                    "table": {cams[c].name: row for c, row in search.table.items()}}
        if sel is not None:
            residual = residuals(cams, sel.points, kp)  # (T, C, 15) px of the videos
            _summarise(result, cams, sel, residual, cf)
            (tmp / IMPORT_DIR).mkdir(exist_ok=True)
            np.savez_compressed(tmp / IMPORT_DIR / "keypoints3d.npz", points=sel.points, residual=residual,
                                confidence=cf, keypoints=kp, inlier=sel.inlier, swapped=sel.swapped,
                                video_frames=plan, threshold=np.float64(threshold))
        seconds["write"] = time.perf_counter() - t0
        seconds["total"] = time.perf_counter() - t_start
        result.seconds = seconds
        (tmp / IMPORT_DIR).mkdir(exist_ok=True)
        (tmp / IMPORT_DIR / "import.json").write_text(json.dumps(result.to_dict(), indent=1, default=_jsonable) + "\n")
        if out.exists():
            shutil.rmtree(out)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return result


def _jsonable(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON-able: {type(o)}")


def _summarise(result: RecordingImport, cams: Sequence[Camera], sel: ViewSelection, residual: np.ndarray,
               cf: np.ndarray) -> None:
    """Residual figures from ``residual`` (T, C, J): per camera the median over its confident joints, per frame
    the median over all views' confident joints."""
    r = np.where(cf >= MIN_CONFIDENCE, residual, np.nan)
    with warnings.catch_warnings():  # a camera or frame without confident joints: NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        per_cam = np.nanmedian(r.transpose(1, 0, 2).reshape(len(cams), -1), axis=1)
        per_frame = np.nanmedian(r.reshape(r.shape[0], -1), axis=1)
    result.residual_px = {cam.name: float(v) for cam, v in zip(cams, per_cam, strict=True)}
    if np.isfinite(per_frame).any():
        result.frame_residual_max_px = float(np.nanmax(per_frame))
        result.worst_frame = int(np.nanargmax(per_frame))
    result.swapped_view_frames = int(sel.swapped.sum())


def _redetect(srcs, cams, plan, redo, sel, kp, cf, detector, common):
    """Detect again, inside the region where the other views put the subject, every view that disagrees."""
    uv = reproject(cams, sel.points)
    masks: dict[tuple[int, int], np.ndarray] = {}
    n = 0
    for c in np.unique(redo[:, 1]):
        rows = redo[redo[:, 1] == c][:, 0]
        frames = {int(plan[t, c]): int(t) for t in rows}
        for k, img in srcs[c].frames(sorted(frames)):
            t = frames[k]
            box = _subject_box(uv[t, c], srcs[c].size, margin=0.3)
            if box is None:
                continue
            det = detector.detect(img, roi=box)
            n += 1
            if not det.found:
                continue
            k15, c15 = _joints15(detector, det.keypoints[None], det.confidence[None])
            kp[t, c], cf[t, c] = k15[0], c15[0]
            if det.mask is not None:
                masks[(t, int(c))] = det.mask
    return n, masks
