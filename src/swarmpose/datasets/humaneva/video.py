"""Video and background: :class:`VideoSource`, HumanEva's background model and silhouettes (facts
section 6), the frame reader of a trial and the cached background of a camera."""

from __future__ import annotations

import hashlib
import math
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from swarmpose.datasets.humaneva.files import _loadmat
from swarmpose.datasets.humaneva.layout import IMAGE_EXTENSIONS, _background_sessions
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError


# ---------------------------------------------------------------------- background model
@dataclass(frozen=True, eq=False)
class BackgroundModel:
    """HumanEva's per-pixel background model: one diagonal Gaussian per recording session.

    Attributes
    ----------
    means, variances : numpy.ndarray, shape (M, H, W, 3), float32
        Per-session, per-pixel, per-channel mean and variance of colour values scaled to [0, 1].
    """

    means: np.ndarray
    variances: np.ndarray

    def __post_init__(self) -> None:
        if self.means.ndim != 4 or self.means.shape[-1] != 3 or self.means.shape != self.variances.shape:
            raise ShapeError(f"background means/variances must both be (M, H, W, 3), got {self.means.shape} and "
                             f"{self.variances.shape}")

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)``."""
        return int(self.means.shape[2]), int(self.means.shape[1])

    def log_likelihood(self, frame: np.ndarray) -> np.ndarray:
        """``log p_bg(v)`` per pixel, ``(H, W)`` float64: log of the mean over sessions of the Gaussians."""
        v = _as_rgb01(frame)
        if v.shape != self.means.shape[1:]:
            raise ShapeError(f"frame {v.shape[:2]} does not match the background model {self.means.shape[1:3]}")
        M = self.means.shape[0]
        logs = np.empty((M,) + v.shape[:2])
        for k in range(M):
            var = self.variances[k].astype(np.float64)
            d = v - self.means[k]
            # log prod_c N(v_c; mu_c, var_c) = sum_c -0.5 log(2 pi var_c) - (v_c - mu_c)^2 / (2 var_c)
            logs[k] = (-0.5 * np.log(2.0 * np.pi * var) - d * d / (2.0 * var)).sum(-1)
        top = logs.max(axis=0)
        return top + np.log(np.exp(logs - top).sum(axis=0)) - math.log(M)  # log (1/M sum_m ...)

    def mean_image(self, session: int = 0) -> np.ndarray:
        """Grey ``(H, W)`` uint8 image of one session's mean."""
        rgb = np.clip(np.rint(self.means[session] * 255.0), 0, 255).astype(np.uint8)
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


def _as_rgb01(frame: np.ndarray) -> np.ndarray:
    a = np.asarray(frame)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)  # grey footage: three equal channels, as HumanEva decodes it
    if a.ndim != 3 or a.shape[2] != 3:
        raise ShapeError(f"frame must be (H, W) or (H, W, 3), got {a.shape}")
    if a.dtype == np.uint8:
        return a.astype(np.float64) / 255.0
    return a.astype(np.float64)


def humaneva_background_model(sessions: Iterable[Iterable[np.ndarray]]) -> BackgroundModel:
    """Fit the background model from footage of the empty scene (``BackgroundSubtraction.m``).

    Parameters
    ----------
    sessions : iterable of iterables of numpy.ndarray
        One iterable of frames per recording session; frames ``(H, W, 3)`` or ``(H, W)`` uint8
        (scaled to [0, 1]) or float already in [0, 1].

    Returns
    -------
    BackgroundModel
        Per session: mean and variance ``E[v^2] - E[v]^2``; a variance <= 0 becomes 1e-3 (as the
        support code, which replaces exact zeros).

    Raises
    ------
    ShapeError
        Frames of different sizes, or a session without frames.
    """
    means, variances = [], []
    shape = None
    for s, frames in enumerate(sessions):
        acc = acc2 = None
        n = 0
        for fr in frames:
            v = _as_rgb01(fr)
            if shape is None:
                shape = v.shape
            if v.shape != shape:
                raise ShapeError(f"background frame of shape {v.shape} in session {s}, expected {shape}")
            if acc is None:
                acc, acc2 = v.copy(), v * v
            else:
                acc += v
                acc2 += v * v
            n += 1
        if n == 0:
            raise ShapeError(f"background session {s} has no frames")
        mu = acc / n
        var = acc2 / n - mu * mu
        var[var <= 0.0] = 1e-3
        means.append(mu.astype(np.float32))
        variances.append(var.astype(np.float32))
    if not means:
        raise ShapeError("no background sessions")
    return BackgroundModel(np.stack(means), np.stack(variances))


def humaneva_silhouette(frame: np.ndarray, model: BackgroundModel, *, risk: float = 1.0, min_area: int = 10,
                        largest_only: bool = False) -> np.ndarray:
    """HumanEva's background subtraction of one frame (facts section 6).

    A pixel is foreground when ``p_bg(v) < 1 / (256^3 * risk)`` (a uniform foreground over 8-bit
    colours, with a misclassification-risk factor). Then, optionally, all but the largest
    8-connected component are removed, and 4-connected components smaller than ``min_area`` pixels.

    Parameters
    ----------
    frame : numpy.ndarray, shape (H, W, 3) or (H, W), uint8
    model : BackgroundModel
    risk : float, default 1.0
        HumanEva-I uses 1; HumanEva-II defaults are 1e80, 1e60, 1e30, 1e80 for C1..C4.
    min_area : int, default 10
    largest_only : bool, default False

    Returns
    -------
    numpy.ndarray, shape (H, W), uint8 in {0, 1}
    """
    if not (risk > 0 and math.isfinite(risk)):
        raise ConfigError(f"risk must be finite and > 0, got {risk!r}")
    log_thr = -3.0 * math.log(256.0) - math.log(risk)
    mask = (model.log_likelihood(frame) < log_thr).astype(np.uint8)
    if largest_only and mask.any():
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if n > 1:
            keep = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
            mask = (labels == keep).astype(np.uint8)
    if min_area > 0 and mask.any():
        n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=4)
        small = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] < min_area)
        small = small[small > 0]
        if small.size:
            mask[np.isin(labels, small)] = 0
    return mask


def read_background_mat(path: str | os.PathLike[str]) -> BackgroundModel:
    """Read the support code's precomputed ``Background_(<CAM>).mat`` (``bg_means``, ``bg_vars`` cells)."""

    p = Path(path)
    data = _loadmat(p, "background statistics (.mat)")
    arrays = {}
    for key in ("bg_means", "bg_vars"):
        if key not in data:
            raise FormatError(f"missing variable {key!r}", path=p, field=key)
        items = data[key]
        items = list(items.ravel()) if isinstance(items, np.ndarray) and items.dtype == object else [items]
        try:
            arr = np.stack([np.asarray(x, dtype=np.float64) for x in items])
        except (TypeError, ValueError):
            raise FormatError(f"{key!r} must hold equally sized H x W x 3 numeric arrays", path=p, field=key) from None
        if arr.ndim != 4 or arr.shape[-1] != 3:
            raise FormatError(f"{key!r} must hold H x W x 3 arrays, got shape {arr.shape[1:]}", path=p, field=key)
        arrays[key] = arr
    if arrays["bg_means"].shape != arrays["bg_vars"].shape:
        raise FormatError("bg_means and bg_vars differ in shape", path=p, field="bg_vars")
    var = arrays["bg_vars"].copy()
    var[var <= 0] = 1e-3
    return BackgroundModel(arrays["bg_means"].astype(np.float32), var.astype(np.float32))


# ---------------------------------------------------------------------- video
def _numbered_images(folder: Path) -> list[tuple[int, Path]]:
    out = []
    for f in folder.iterdir():
        if f.is_file() and f.suffix.lower() in IMAGE_EXTENSIONS:
            m = re.search(r"(\d+)$", f.stem)
            if m:
                out.append((int(m.group(1)), f))
    out.sort()
    return out


class VideoSource:
    """Frames of one camera, 0-based, decoded on demand and returned as RGB ``(H, W, 3)`` uint8.

    A video file is read with OpenCV (``cv2.VideoCapture``; sequential reads are not re-seeked) and,
    when OpenCV cannot open it, with ``imageio`` (needs ``imageio-ffmpeg``: ``swarmpose[video]``).
    A folder is read as numbered images (BMP/PNG/TIFF/PGM/JPEG; frame ``i`` = the file with the
    ``i``-th counter after the smallest, as the support code's ``image_stream``).

    Parameters
    ----------
    path : path-like
        ``.avi`` (or any video OpenCV/imageio reads) or an image folder.

    Raises
    ------
    DataError
        Missing path or a folder without numbered images, or no decoder could open the video.
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = Path(path)
        self._cap: Any = None
        self._imageio: Any = None
        self._files: dict[int, Path] | None = None
        self._next = 0
        self._last: tuple[int, np.ndarray] | None = None
        if self.path.is_dir():
            items = _numbered_images(self.path)
            if not items:
                raise DataError(f"{self.path}: no numbered image files ({', '.join(IMAGE_EXTENSIONS)})")
            self._first = items[0][0]
            self._files = dict(items)
            self.n_frames = items[-1][0] - self._first + 1
            img = self._read_file(self._first)
            self.size = (int(img.shape[1]), int(img.shape[0]))
            self._last = (0, img)
            return
        if not self.path.is_file():
            raise DataError(f"{self.path}: missing video (or image folder)")
        cap = cv2.VideoCapture(str(self.path))
        if cap.isOpened():
            n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
            w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            if w > 0 and h > 0:
                self._cap = cap
                self.size = (w, h)
                self.n_frames = n if n > 0 else self._count_frames()
                return
            cap.release()
        try:
            import imageio.v2 as iio

            # FFmpeg only: letting imageio try every plugin on an unreadable file reaches its
            # deprecated TIFF and DICOM readers
            self._imageio = iio.get_reader(str(self.path), format="FFMPEG")
            n = self._imageio.count_frames()
            first = self._imageio.get_data(0)
        except Exception as exc:  # imageio raises plugin-specific errors
            self._imageio = None
            raise DataError(f"{self.path}: cannot decode the video: OpenCV could not open it and imageio failed "
                            f"({type(exc).__name__}: {exc}); install an FFmpeg backend: pip install "
                            f"'swarmpose[video]'") from None
        self.n_frames = int(n)
        self.size = (int(first.shape[1]), int(first.shape[0]))

    def _count_frames(self) -> int:
        n = 0
        while self._cap.grab():
            n += 1
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
        self._next = 0
        return n

    def _read_file(self, counter: int) -> np.ndarray:
        assert self._files is not None
        f = self._files.get(counter)
        if f is None:
            raise DataError(f"{self.path}: image number {counter} is missing (frames are numbered from "
                            f"{self._first})")
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise FormatError("cannot decode image (truncated or not an image)", path=f)
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)

    def read(self, i: int) -> np.ndarray:
        """RGB frame ``i`` (0-based), ``(H, W, 3)`` uint8.

        Raises
        ------
        IndexError
            ``i`` outside ``[0, n_frames)``.
        FormatError
            The frame cannot be decoded (truncated video, bad image); the message names the file.
        """
        i = int(i)
        if not 0 <= i < self.n_frames:
            raise IndexError(f"{self.path}: frame {i} outside [0, {self.n_frames})")
        if self._last is not None and self._last[0] == i:
            return self._last[1]
        if self._files is not None:
            img = self._read_file(self._first + i)
        elif self._cap is not None:
            if i != self._next:
                self._cap.set(cv2.CAP_PROP_POS_FRAMES, i)
            ok, bgr = self._cap.read()
            self._next = i + 1
            if not ok or bgr is None:
                self._next = -1
                raise FormatError(f"cannot decode frame {i} of {self.n_frames} (truncated video?)", path=self.path)
            img = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB) if bgr.ndim == 3 else cv2.cvtColor(bgr, cv2.COLOR_GRAY2RGB)
        else:
            try:
                img = np.asarray(self._imageio.get_data(i))
            except Exception as exc:
                raise FormatError(f"cannot decode frame {i} ({type(exc).__name__}: {exc})", path=self.path) from None
            if img.ndim == 2:
                img = np.repeat(img[..., None], 3, axis=2)
            img = np.ascontiguousarray(img[..., :3]).astype(np.uint8)
        if img.shape[:2] != (self.size[1], self.size[0]):
            raise FormatError(f"frame {i} is {img.shape[1]}x{img.shape[0]}, the stream {self.size[0]}x{self.size[1]}",
                              path=self.path)
        self._last = (i, img)
        return img

    def close(self) -> None:
        """Release the decoder."""
        if self._cap is not None:
            self._cap.release()
            self._cap = None
        if self._imageio is not None:
            self._imageio.close()
            self._imageio = None
        self._last = None

    def __enter__(self) -> VideoSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _grey(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)


class HumanEvaFrames:
    """:class:`~swarmpose.io.sequence.FrameReader` over HumanEva videos (decoded on demand).

    Parameters
    ----------
    sources : list of VideoSource
        One per view.
    video_index : numpy.ndarray, shape (T, C), int
        0-based video frame of each view at each sequence frame.
    models : list of BackgroundModel, optional
        Background model per view; enables the ``silhouette`` stream.
    risks : sequence of float, optional
        Per-view risk for :func:`humaneva_silhouette` (default 1).
    min_area, largest_only
        Passed to :func:`humaneva_silhouette`.
    """

    def __init__(self, sources: Sequence[VideoSource], video_index: np.ndarray,
                 models: Sequence[BackgroundModel] | None = None, risks: Sequence[float] | None = None,
                 min_area: int = 10, largest_only: bool = False):
        self.sources = list(sources)
        self.video_index = np.asarray(video_index, dtype=np.int64)
        if self.video_index.ndim != 2 or self.video_index.shape[1] != len(self.sources):
            raise ShapeError(f"video_index must be (T, {len(self.sources)}), got {self.video_index.shape}")
        self.models = None if models is None else list(models)
        self.risks = [1.0] * len(self.sources) if risks is None else [float(r) for r in risks]
        self.min_area = int(min_area)
        self.largest_only = bool(largest_only)
        self.streams = ("image", "silhouette") if self.models is not None else ("image",)

    def colour(self, k: int) -> np.ndarray:
        """RGB frames of sequence frame ``k``, ``(C, H, W, 3)`` uint8."""
        return np.stack([s.read(int(self.video_index[k, c])) for c, s in enumerate(self.sources)])

    def read(self, stream: str, k: int) -> np.ndarray:
        """``(C, H, W)`` uint8 grey images (``image``) or {0, 1} masks (``silhouette``) of frame ``k``."""
        frames = [s.read(int(self.video_index[k, c])) for c, s in enumerate(self.sources)]
        if stream == "image":
            return np.stack([_grey(f) for f in frames])
        if stream == "silhouette" and self.models is not None:
            return np.stack([humaneva_silhouette(f, m, risk=r, min_area=self.min_area, largest_only=self.largest_only)
                             for f, m, r in zip(frames, self.models, self.risks, strict=True)])
        raise ConfigError(f"unknown stream {stream!r}; this reader has {self.streams}")

    def close(self) -> None:
        """Release the video decoders."""
        for s in self.sources:
            s.close()


# ---------------------------------------------------------------------- background loading / cache
def _footage_frames(path: Path, max_frames: int | None) -> Iterable[np.ndarray]:
    src = VideoSource(path)
    try:
        n = src.n_frames
        if max_frames is None or n <= max_frames:
            idx = range(n)
        else:
            idx = np.unique(np.linspace(0, n - 1, int(max_frames)).round().astype(int))
        for i in idx:
            yield src.read(int(i))
    finally:
        src.close()


def load_background_model(subject_dir: str | os.PathLike[str], camera: str, *, max_frames: int | None = 100,
                          cache_dir: str | os.PathLike[str] | None = "cache/humaneva") -> BackgroundModel | None:
    """The background model of one camera, or None when no background footage is found.

    Looks in ``<S>/Background/`` (HumanEva-II) and ``<root>/Background/`` (HumanEva-I) for the support
    code's ``Background_(<CAM>).mat`` (used as is) or the footage ``Background_*_(<CAM>).avi`` / image
    folders (one recording session each), summarised by :func:`humaneva_background_model` from at
    most ``max_frames`` evenly spaced frames per session, and cached in ``cache_dir`` (None: no cache).
    """
    sd = Path(subject_dir)
    mat, sessions = _background_sessions(sd, camera)
    if mat is not None:
        return read_background_mat(mat)
    if not sessions:
        return None
    key_src = repr([(str(p.resolve()), *(_stat_key(p))) for p in sessions]) + repr(max_frames)
    key = hashlib.sha1(key_src.encode()).hexdigest()[:16]
    cache = None if cache_dir is None else Path(cache_dir) / f"background-{camera}-{key}.npz"
    if cache is not None and cache.is_file():
        try:
            with np.load(cache, allow_pickle=False) as z:
                return BackgroundModel(z["means"], z["variances"])
        except (OSError, ValueError, KeyError, ShapeError):
            pass  # damaged cache entry: recompute
    model = humaneva_background_model(_footage_frames(p, max_frames) for p in sessions)
    if cache is not None:
        cache.parent.mkdir(parents=True, exist_ok=True)
        tmp = cache.with_name(cache.name + ".tmp.npz")
        np.savez(tmp, means=model.means, variances=model.variances)
        os.replace(tmp, cache)
    return model


def _stat_key(p: Path) -> tuple[int, int]:
    if p.is_dir():
        files = _numbered_images(p)
        return len(files), int(max((f.stat().st_mtime_ns for _, f in files), default=0))
    st = p.stat()
    return int(st.st_size), int(st.st_mtime_ns)


def _nearest_session(model: BackgroundModel, grey: np.ndarray) -> np.ndarray:
    """Grey mean image of the session closest (mean absolute difference) to a frame."""
    best = None
    for k in range(model.means.shape[0]):
        img = model.mean_image(k)
        d = float(np.mean(cv2.absdiff(img, grey)))
        if best is None or d < best[0]:
            best = (d, img)
    assert best is not None
    return best[1]
