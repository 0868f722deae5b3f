"""Detections of one view's video, kept in a resumable cache file.

One ``.npz`` per view (never pickled) holds

* ``keypoints (T, K, 2)`` float32 pixels (NaN where absent), ``confidence (T, K)`` float32,
  ``found (T,)`` bool, ``done (T,)`` bool (which frames have been detected);
* the masks, each PNG-encoded (1 bit per pixel), concatenated into ``mask_png`` (uint8) with
  ``mask_offsets (T + 1,)`` (frame ``t`` is ``mask_png[offsets[t]:offsets[t + 1]]``, empty when it
  has no mask) and ``image_size (2,) = (H, W)``;
* ``meta``: a JSON string with the cache format, the detector's name, version, settings and
  keypoint names, the video's identity (path, size, mtime) and the frame count.

It is rewritten atomically (temporary file, then ``os.replace``) every ``save_every`` detected frames
and when the run stops for any reason, so an interrupted run resumes where it stopped, and a finished
one is read back without detecting again. A cache whose ``meta`` differs from the current run (another
detector, setting, version or video) is ignored and redone from the start.

Public API
----------
``detect_video_frames(frames, detector, cache_path, *, n_frames, video=None, save_every=10, progress=True)
-> VideoDetections``; ``detect_video_file(video_path, detector, cache_path, **kw)`` the same on a video
file; ``load_detections(cache_path) -> VideoDetections``; ``iter_video_frames(path)``;
``video_identity(path) -> dict``.
"""

from __future__ import annotations

import json
import os
import sys
import warnings
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from swarmpose.detection.base import PersonDetector
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.files import load_npz
from swarmpose.io.video import open_frames

__all__ = ["VideoDetections", "detect_video_frames", "detect_video_file", "load_detections", "iter_video_frames",
           "video_identity", "CACHE_FORMAT"]

CACHE_FORMAT = 1
_ARRAYS = ("keypoints", "confidence", "found", "done", "mask_png", "mask_offsets", "image_size", "meta")


@dataclass
class VideoDetections:
    """One view's detections over ``T`` frames (see the module docstring for the arrays)."""

    keypoints: np.ndarray
    confidence: np.ndarray
    found: np.ndarray
    done: np.ndarray
    image_size: tuple[int, int] | None
    meta: dict[str, Any]
    mask_png: list[bytes] = field(repr=False, default_factory=list)

    @classmethod
    def empty(cls, n_frames: int, n_keypoints: int, meta: dict[str, Any]) -> VideoDetections:
        """Nothing detected yet."""
        return cls(np.full((n_frames, n_keypoints, 2), np.nan, np.float32), np.zeros((n_frames, n_keypoints),
                   np.float32), np.zeros(n_frames, bool), np.zeros(n_frames, bool), None, meta, [b""] * n_frames)

    @property
    def n_frames(self) -> int:
        return int(self.done.shape[0])

    @property
    def complete(self) -> bool:
        """Whether every frame has been detected."""
        return bool(self.done.all())

    def mask(self, t: int) -> np.ndarray | None:
        """Frame ``t``'s ``(H, W)`` uint8 ``{0, 1}`` mask, or None (not detected, or no mask)."""
        data = self.mask_png[t]
        if not data:
            return None
        mask = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE)
        if mask is None:
            raise FormatError(f"the mask of frame {t} is not a readable PNG")
        return (mask > 0).astype(np.uint8)

    def masks(self) -> np.ndarray:
        """All masks, ``(T, H, W)`` uint8 (zeros where a frame has none)."""
        if self.image_size is None:
            raise DataError("these detections hold no mask")
        out = np.zeros((self.n_frames, *self.image_size), np.uint8)
        for t in range(self.n_frames):
            m = self.mask(t)
            if m is not None:
                out[t] = m
        return out

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write atomically to ``path`` (a temporary file beside it, then ``os.replace``)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        offsets = np.zeros(self.n_frames + 1, np.int64)
        offsets[1:] = np.cumsum([len(b) for b in self.mask_png])
        blob = np.frombuffer(b"".join(self.mask_png), np.uint8)
        tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
        try:
            with open(tmp, "wb") as fh:
                np.savez(fh, keypoints=self.keypoints.astype(np.float32), confidence=self.confidence.astype(np.float32),
                         found=self.found.astype(bool), done=self.done.astype(bool), mask_png=blob,
                         mask_offsets=offsets, image_size=np.array(self.image_size or (0, 0), np.int64),
                         meta=np.array(json.dumps(self.meta, sort_keys=True)))
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)


def load_detections(cache_path: str | os.PathLike[str]) -> VideoDetections:
    """The detections cached in ``cache_path``.

    Raises
    ------
    FormatError
        Not a detection cache of this format (truncated, other arrays, inconsistent shapes).
    """
    z = load_npz(Path(cache_path), _ARRAYS)
    try:
        meta = json.loads(str(z["meta"]))
    except json.JSONDecodeError:
        raise FormatError("field meta is not JSON", path=cache_path) from None
    if not isinstance(meta, dict) or meta.get("format") != CACHE_FORMAT:
        raise FormatError(f"not a detection cache of format {CACHE_FORMAT}", path=cache_path)
    kp, conf, found, done, offsets = (z[k] for k in ("keypoints", "confidence", "found", "done", "mask_offsets"))
    t = done.shape[0] if done.ndim == 1 else -1
    if (kp.ndim != 3 or kp.shape[0] != t or kp.shape[2] != 2 or conf.shape != kp.shape[:2]
            or found.shape != (t,) or offsets.shape != (t + 1,) or z["image_size"].shape != (2,)
            or np.any(np.diff(offsets) < 0) or offsets[0] != 0 or offsets[-1] != z["mask_png"].size):
        raise FormatError("inconsistent array shapes", path=cache_path)
    blob = z["mask_png"].tobytes()
    h, w = (int(v) for v in z["image_size"])
    return VideoDetections(kp, conf, found.astype(bool), done.astype(bool), (h, w) if h > 0 else None, meta,
                           [blob[a:b] for a, b in zip(offsets[:-1], offsets[1:], strict=True)])


def video_identity(path: str | os.PathLike[str]) -> dict[str, Any]:
    """``{"path", "size", "mtime_ns"}`` of a video file (what makes its cached detections stale)."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise DataError(f"video not found: {p}") from None
    return {"path": str(p.resolve()), "size": int(st.st_size), "mtime_ns": int(st.st_mtime_ns)}


def iter_video_frames(path: str | os.PathLike[str], n_frames: int | None = None) -> Iterator[np.ndarray]:
    """The BGR frames of a video file (or image folder), in order (the first ``n_frames`` when given):
    :func:`swarmpose.io.video.open_frames`'s, which names the file when it cannot be read."""
    src = open_frames(path)
    n = src.n_frames if n_frames is None else min(int(n_frames), src.n_frames)
    for _, frame in src.frames(range(n)):
        yield frame


def _run_meta(detector: PersonDetector, n_frames: int, video: Mapping[str, Any] | str | os.PathLike[str] | None
              ) -> dict[str, Any]:
    if video is not None and not isinstance(video, Mapping):
        video = video_identity(video)
    meta = {"format": CACHE_FORMAT, "n_frames": int(n_frames), "video": None if video is None else dict(video),
            "detector": {"name": str(detector.name), "version": str(detector.version),
                         "settings": dict(detector.settings), "keypoint_names": list(detector.keypoint_names)}}
    return json.loads(json.dumps(meta, sort_keys=True))  # as it reads back (tuples as lists)


def _resume(cache_path: Path, meta: dict[str, Any]) -> VideoDetections | None:
    """The cached detections when they belong to this run, else None (a damaged file is warned about)."""
    if not cache_path.is_file():
        return None
    try:
        cached = load_detections(cache_path)
    except (FormatError, OSError) as exc:
        warnings.warn(f"detection cache {cache_path} is unreadable and is redone: {exc}", stacklevel=3)
        return None
    return cached if cached.meta == meta else None


def detect_video_frames(frames: Iterable[np.ndarray], detector: PersonDetector, cache_path: str | os.PathLike[str],
                        *, n_frames: int, video: Mapping[str, Any] | str | os.PathLike[str] | None = None,
                        save_every: int = 10, progress: bool = True) -> VideoDetections:
    """Detect the person in each of one view's ``n_frames`` frames, through the cache ``cache_path``.

    Parameters
    ----------
    frames : iterable of (H, W) or (H, W, 3) uint8
        The view's frames from the first, in order (frames already in the cache are read and skipped;
        the iterable is not consumed at all when the cache is complete).
    detector : PersonDetector
        Reset before the first frame detected and after every frame skipped.
    cache_path : path
        The ``.npz`` file (its folder is created).
    n_frames : int
        Frames expected; more are ignored, fewer leave ``done`` False for the rest (with a warning).
    video : path or mapping, optional
        The video file (its :func:`video_identity` is recorded) or an identity mapping of your own.
    save_every : int
        Detected frames between two cache writes.
    progress : bool
        Show a tqdm bar on stderr.

    Raises
    ------
    ShapeError
        A frame's size differs from the earlier frames'.
    """
    from tqdm import tqdm

    if int(n_frames) < 0 or int(save_every) < 1:
        raise ConfigError(f"n_frames must be >= 0 and save_every >= 1, got {n_frames} and {save_every}")
    cache_path = Path(cache_path)
    meta = _run_meta(detector, n_frames, video)
    result = _resume(cache_path, meta) or VideoDetections.empty(int(n_frames), len(detector.keypoint_names), meta)
    if result.complete:
        return result
    unsaved, last, seen = 0, -2, 0
    bar = tqdm(total=result.n_frames, initial=int(result.done.sum()), desc=f"detect {cache_path.stem}",
               unit="frame", file=sys.stderr, disable=not progress)
    try:
        for t, frame in enumerate(frames):
            if t >= result.n_frames:
                break
            seen = t + 1
            if result.done[t]:
                continue
            shape = tuple(np.shape(frame)[:2])
            if result.image_size is not None and shape != result.image_size:
                raise ShapeError(f"frame {t} is {shape}, the earlier frames {result.image_size}")
            if last != t - 1:
                detector.reset()  # the first frame, or frames skipped since the last one detected
            det = detector.detect(frame)
            result.keypoints[t] = det.keypoints
            result.confidence[t] = det.confidence
            result.found[t] = det.found
            if result.image_size is None:
                result.image_size = shape  # type: ignore[assignment]
            if det.mask is not None:
                ok, png = cv2.imencode(".png", det.mask * np.uint8(255), [cv2.IMWRITE_PNG_BILEVEL, 1])
                result.mask_png[t] = png.tobytes() if ok else b""
            result.done[t] = True
            last, unsaved = t, unsaved + 1
            bar.update(1)
            if unsaved >= save_every:
                result.save(cache_path)
                unsaved = 0
    finally:
        if unsaved:
            result.save(cache_path)
        bar.close()
    if not result.complete and seen < result.n_frames:
        warnings.warn(f"{cache_path.stem}: the frames ended after {seen} of {result.n_frames}", stacklevel=2)
    return result


def detect_video_file(video_path: str | os.PathLike[str], detector: PersonDetector,
                      cache_path: str | os.PathLike[str], *, n_frames: int | None = None, save_every: int = 10,
                      progress: bool = True) -> VideoDetections:
    """:func:`detect_video_frames` on a video file (``n_frames``: OpenCV's frame count when None)."""
    identity = video_identity(video_path)
    if n_frames is None:
        n_frames = open_frames(video_path).n_frames
    return detect_video_frames(iter_video_frames(video_path, n_frames), detector, cache_path, n_frames=n_frames,
                               video=identity, save_every=save_every, progress=progress)
