"""Frames of one camera from a video file or a folder of images, read in order.

:func:`open_frames` opens either; :class:`FrameSource` tells the frame count, rate and size before any
frame is decoded and yields BGR ``uint8`` frames in order. Videos are decoded by OpenCV (its FFmpeg
build reads H.264/H.265 MP4, AVI, MOV, MKV); an image folder holds one image per frame, ordered by the
numbers in the file names (``frame_2.png`` before ``frame_10.png``).

Errors name the file: a video OpenCV cannot open or that ends before its announced frame count, an
image folder without images, an image that does not decode, images of different sizes.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from swarmpose.errors import DataError, FormatError

__all__ = ["FrameSource", "open_frames", "IMAGE_SUFFIXES", "VIDEO_SUFFIXES"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")


def _natural_key(name: str) -> list:
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


@dataclass
class FrameSource:
    """One camera's frames: a video file or an image folder.

    Attributes
    ----------
    path : pathlib.Path
    n_frames : int
        Frames available.
    fps : float or None
        The video's frame rate (None for an image folder).
    size : (int, int)
        ``(width, height)`` in pixels.
    kind : {"video", "images"}
    """

    path: Path
    n_frames: int
    fps: float | None
    size: tuple[int, int]
    kind: str
    _files: list[Path] = field(default_factory=list, repr=False)

    @property
    def name(self) -> str:
        """The file or folder name without its suffix (``cam01`` for ``cam01.mp4``)."""
        return self.path.name if self.path.is_dir() else self.path.stem

    def frames(self, indices: np.ndarray | list[int]) -> Iterator[tuple[int, np.ndarray]]:
        """Yield ``(k, frame)`` for each requested frame index, in increasing order, as BGR uint8 (H, W, 3).

        Indices outside ``[0, n_frames)`` raise :class:`~swarmpose.errors.DataError` before decoding.
        """
        idx = np.asarray(indices, dtype=np.int64).ravel()
        if idx.size == 0:
            return
        if np.any(np.diff(idx) <= 0):
            raise ValueError("frame indices must increase strictly")
        if idx[0] < 0 or idx[-1] >= self.n_frames:
            raise DataError(f"{self.path}: frames {int(idx[0])}..{int(idx[-1])} requested, it has {self.n_frames} "
                            f"(0..{self.n_frames - 1})")
        if self.kind == "images":
            for k in idx:
                yield int(k), self._read_image(self._files[k])
            return
        yield from self._video_frames(idx)

    def _read_image(self, p: Path) -> np.ndarray:
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise FormatError("cannot be decoded as an image", path=p)
        if (img.shape[1], img.shape[0]) != self.size:
            raise FormatError(f"image is {img.shape[1]}x{img.shape[0]}, the folder's first image is "
                              f"{self.size[0]}x{self.size[1]}", path=p)
        return img

    def _video_frames(self, idx: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
        cap = cv2.VideoCapture(str(self.path))
        try:
            if not cap.isOpened():
                raise DataError(f"{self.path}: cannot be opened as a video")
            want = iter(idx.tolist())
            target = next(want)
            k = 0  # decoded from the start: OpenCV's seeks are not frame-exact for every codec
            while True:
                if k < target:
                    if not cap.grab():
                        break
                    k += 1
                    continue
                ok, img = cap.read()
                if not ok or img is None:
                    break
                if img.ndim == 2:
                    img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
                yield k, img
                k += 1
                target = next(want, None)
                if target is None:
                    return
            raise DataError(f"{self.path}: the video ends at frame {k}, before frame {target} "
                            f"({self.n_frames} frames announced; the file may be truncated)")
        finally:
            cap.release()


def _open_video(path: Path) -> FrameSource:
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise DataError(f"{path}: cannot be opened as a video (OpenCV's FFmpeg could not read it: not a video, "
                            "truncated, or a codec it lacks)")
        n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        ok, img = cap.read()
        if not ok or img is None:
            raise DataError(f"{path}: cannot be read as a video (no frame decodes)")
        if (img.shape[1], img.shape[0]) != (w, h):  # rotation metadata applied by the decoder
            w, h = img.shape[1], img.shape[0]
    finally:
        cap.release()
    if n <= 0:
        raise DataError(f"{path}: the video announces no frame count; convert it to MP4 (ffmpeg -i IN OUT.mp4)")
    if not (np.isfinite(fps) and fps > 0):
        fps = None
    return FrameSource(path=path, n_frames=n, fps=fps, size=(w, h), kind="video")


def _open_images(path: Path) -> FrameSource:
    files = sorted((p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
                   key=lambda p: _natural_key(p.name))
    if not files:
        raise DataError(f"{path}: the folder holds no images ({', '.join(IMAGE_SUFFIXES)})")
    first = cv2.imread(str(files[0]), cv2.IMREAD_COLOR)
    if first is None:
        raise FormatError("cannot be decoded as an image", path=files[0])
    return FrameSource(path=path, n_frames=len(files), fps=None, size=(first.shape[1], first.shape[0]),
                       kind="images", _files=files)


def open_frames(path: str | os.PathLike[str]) -> FrameSource:
    """Open a video file, an image folder or a single image as a :class:`FrameSource` (no frame decoded but
    the first)."""
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: no such video file or image folder")
    if p.is_dir():
        return _open_images(p)
    if p.suffix.lower() in IMAGE_SUFFIXES:  # one picture: a one-frame source (an empty-scene background)
        img = cv2.imread(str(p), cv2.IMREAD_COLOR)
        if img is None:
            raise FormatError("cannot be decoded as an image", path=p)
        return FrameSource(path=p, n_frames=1, fps=None, size=(img.shape[1], img.shape[0]), kind="images", _files=[p])
    return _open_video(p)
