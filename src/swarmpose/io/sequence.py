"""Multi-view sequences: the in-memory type :class:`MultiViewSequence` and its on-disk format.

:class:`MultiViewSequence` is what the tracker consumes and what every source produces: the
synthesiser (:mod:`swarmpose.synth`), and later the HumanEva loaders. It holds metadata and
small arrays (cameras, frame times, backgrounds, ground truth, marker detections) in memory and
reads frames (images, masks, silhouettes) on demand through a :class:`FrameReader`, so memory
stays bounded however long the sequence is.

The on-disk format (``"format": "swarmpose-sequence"``, ``"version": 1``) is specified in
``docs/sequence-format.md``: a folder with ``sequence.json`` (metadata, written last),
``cameras.json`` (a :func:`swarmpose.camera.save_rig` file), ``frames.npz`` (frame times),
optional ``backgrounds.npz``, ``ground_truth.npz`` and ``markers.npz``, and one ZIP archive per
view (``views/<VIEW>.zip``) holding one lossless PNG per frame and stream
(``image/000123.png``, ``mask/000123.png``, ``silhouette/000123.png``). Every ``.npz`` is read with
``allow_pickle=False``. Errors name the file (and the field or archive entry) that is missing or bad.

Shape letters: ``T`` frames, ``C`` views, ``H, W`` pixels, ``M`` marker names, ``Q`` detections.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import zipfile
from collections import Counter, deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import cv2
import numpy as np

from swarmpose.body.measurements import SubjectMeasurements
from swarmpose.camera import Camera, load_rig, save_rig
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.files import load_npz

__all__ = [
    "SEQUENCE_FORMAT",
    "SEQUENCE_VERSION",
    "STREAMS",
    "Frame",
    "MarkerData",
    "FrameReader",
    "InMemoryFrames",
    "MultiViewSequence",
    "SequenceWriter",
    "open_sequence",
    "register_source_scheme",
    "write_sequence",
]

SEQUENCE_FORMAT = "swarmpose-sequence"
SEQUENCE_VERSION = 1
#: Per-view image streams a sequence may store: camera images, exact foreground masks (ground
#: truth), observed silhouettes (e.g. precomputed from real video). All (H, W) uint8.
STREAMS: tuple[str, ...] = ("image", "mask", "silhouette")

_META = "sequence.json"
_CAMERAS = "cameras.json"
_FRAMES = "frames.npz"
_BACKGROUNDS = "backgrounds.npz"
_GROUND_TRUTH = "ground_truth.npz"
_MARKERS = "markers.npz"


def _entry(stream: str, k: int) -> str:
    return f"{stream}/{k:06d}.png"


# ---------------------------------------------------------------------- records
@dataclass(frozen=True, eq=False)
class Frame:
    """One frame of a :class:`MultiViewSequence` (what iteration yields).

    Attributes
    ----------
    index : int
    time : float
        Seconds from the first frame.
    images : numpy.ndarray of shape (C, H, W) uint8, or None
    masks : numpy.ndarray of shape (C, H, W) uint8 in {0, 1}, or None
        Exact foreground masks (synthetic ground truth) when stored.
    markers : list of C numpy.ndarray of shape (Q_c, 2), or None
        2D marker detections per view, pixels.
    silhouettes : numpy.ndarray of shape (C, H, W) uint8 in {0, 1}, or None
        Stored observed silhouettes, if any.
    """

    index: int
    time: float
    images: np.ndarray | None
    masks: np.ndarray | None
    markers: list[np.ndarray] | None
    silhouettes: np.ndarray | None = None


@dataclass(eq=False)
class MarkerData:
    """2D marker detections of a whole sequence, flattened (small; kept in memory).

    Attributes
    ----------
    names : tuple of str
        ``M`` marker names (detection ids index into it).
    counts : numpy.ndarray, shape (T, C), int64
        Number of detections per frame and view.
    uv : numpy.ndarray, shape (Q_total, 2), float64
        Detections, frame-major then view, pixels.
    ids : numpy.ndarray, shape (Q_total,), int16
        Marker index of each detection; ``-1`` = false detection. For evaluation only.
    projections : numpy.ndarray of shape (T, C, M, 2) float64, or None
        Noise-free projections of every marker.
    visible : numpy.ndarray of shape (T, C, M) bool, or None
        Visibility before drop-outs (inside the image and not occluded).
    confidence : numpy.ndarray of shape (Q_total,) float64 in [0, 1], or None
        The detector's confidence in each detection (body keypoints from a person detector, whose ids
        are then the keypoints' labels, not an evaluation-only identity).
    """

    names: tuple[str, ...]
    counts: np.ndarray
    uv: np.ndarray
    ids: np.ndarray
    projections: np.ndarray | None = None
    visible: np.ndarray | None = None
    confidence: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.names = tuple(str(n) for n in self.names)
        self.counts = np.asarray(self.counts, dtype=np.int64)
        self.uv = np.asarray(self.uv, dtype=np.float64).reshape(-1, 2)
        self.ids = np.asarray(self.ids, dtype=np.int16).reshape(-1)
        if self.counts.ndim != 2 or np.any(self.counts < 0):
            raise ShapeError(f"marker counts must be a non-negative (T, C) array, got shape {self.counts.shape}")
        total = int(self.counts.sum())
        if self.uv.shape[0] != total or self.ids.shape[0] != total:
            raise ShapeError(f"marker counts sum to {total} but uv has {self.uv.shape[0]} rows and ids "
                             f"{self.ids.shape[0]}")
        T, C = self.counts.shape
        M = len(self.names)
        if self.projections is not None:
            self.projections = np.asarray(self.projections, dtype=np.float64)
            if self.projections.shape != (T, C, M, 2):
                raise ShapeError(f"marker projections must have shape {(T, C, M, 2)}, got {self.projections.shape}")
        if self.visible is not None:
            self.visible = np.asarray(self.visible, dtype=bool)
            if self.visible.shape != (T, C, M):
                raise ShapeError(f"marker visibility must have shape {(T, C, M)}, got {self.visible.shape}")
        if self.confidence is not None:
            self.confidence = np.asarray(self.confidence, dtype=np.float64).reshape(-1)
            if self.confidence.shape != (total,):
                raise ShapeError(f"marker confidence must have shape {(total,)}, got {self.confidence.shape}")
            if not np.all((self.confidence >= 0) & (self.confidence <= 1)):
                raise ShapeError("marker confidence must lie in [0, 1]")
        self._offsets = np.concatenate([[0], np.cumsum(self.counts.ravel())])

    @classmethod
    def from_lists(cls, names: Sequence[str], positions: Sequence[Sequence[np.ndarray]],
                   ids: Sequence[Sequence[np.ndarray]], projections: np.ndarray | None = None,
                   visible: np.ndarray | None = None) -> MarkerData:
        """Build from per-frame lists of per-view ``(Q, 2)`` positions and ``(Q,)`` ids."""
        counts = np.array([[len(p) for p in frame] for frame in positions], dtype=np.int64).reshape(len(positions), -1)
        flat_uv = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for frame in positions for p in frame]
        flat_ids = [np.asarray(i, dtype=np.int16).reshape(-1) for frame in ids for i in frame]
        uv = np.concatenate(flat_uv) if flat_uv else np.zeros((0, 2))
        idv = np.concatenate(flat_ids) if flat_ids else np.zeros(0, np.int16)
        return cls(tuple(names), counts, uv, idv, projections, visible)

    @classmethod
    def from_dense(cls, names: Sequence[str], uv: np.ndarray, confidence: np.ndarray | None = None) -> MarkerData:
        """Build from labelled keypoints ``uv`` of shape (T, C, M, 2), NaN where a keypoint is absent.

        Each present keypoint becomes one detection whose id is its label; ``confidence`` (T, C, M)
        goes with it. :meth:`to_dense` is the inverse.
        """
        uv = np.asarray(uv, dtype=np.float64)
        if uv.ndim != 4 or uv.shape[2:] != (len(names), 2):
            raise ShapeError(f"keypoints must have shape (T, C, {len(names)}, 2), got {uv.shape}")
        present = np.isfinite(uv).all(axis=-1)
        counts = present.sum(axis=2).astype(np.int64)
        ids = np.broadcast_to(np.arange(len(names), dtype=np.int16), present.shape)[present]
        conf = None
        if confidence is not None:
            confidence = np.asarray(confidence, dtype=np.float64)
            if confidence.shape != present.shape:
                raise ShapeError(f"confidence must have shape {present.shape}, got {confidence.shape}")
            conf = np.clip(confidence[present], 0.0, 1.0)
        return cls(tuple(names), counts, uv[present], ids, confidence=conf)

    def to_dense(self) -> tuple[np.ndarray, np.ndarray | None]:
        """Labelled keypoints ``(T, C, M, 2)`` (NaN where absent) and confidences ``(T, C, M)`` or None.

        Needs detections whose ids are labels (at most one per label and view); false detections
        (id -1) are dropped.
        """
        T, C = self.counts.shape
        M = len(self.names)
        uv = np.full((T, C, M, 2), np.nan)
        conf = None if self.confidence is None else np.zeros((T, C, M))
        rows = np.repeat(np.arange(T * C), self.counts.ravel())
        keep = self.ids >= 0
        flat_uv = uv.reshape(T * C, M, 2)
        flat_uv[rows[keep], self.ids[keep]] = self.uv[keep]
        if conf is not None:
            conf.reshape(T * C, M)[rows[keep], self.ids[keep]] = self.confidence[keep]
        return uv, conf

    @property
    def n_frames(self) -> int:
        """``T``."""
        return int(self.counts.shape[0])

    def frame_confidence(self, k: int) -> list[np.ndarray] | None:
        """Confidences ``[(Q_c,)]`` of frame ``k``'s detections, one entry per view, or None."""
        if self.confidence is None:
            return None
        C = self.counts.shape[1]
        return [self.confidence[self._offsets[k * C + c]:self._offsets[k * C + c + 1]].copy() for c in range(C)]

    def frame(self, k: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Detections ``[(Q_c, 2)]`` and ids ``[(Q_c,)]`` of frame ``k``, one entry per view."""
        C = self.counts.shape[1]
        pos, ids = [], []
        for c in range(C):
            a, b = self._offsets[k * C + c], self._offsets[k * C + c + 1]
            pos.append(self.uv[a:b].copy())
            ids.append(self.ids[a:b].copy())
        return pos, ids


# ---------------------------------------------------------------------- frame readers
class FrameReader(Protocol):
    """Where a :class:`MultiViewSequence` gets its frames from (disk, memory, video, ...).

    ``read(stream, k)`` returns the ``(C, H, W)`` uint8 array of ``stream`` (one of
    :data:`STREAMS`) at frame ``k``; ``streams`` says which streams exist.
    """

    streams: tuple[str, ...]

    def read(self, stream: str, k: int) -> np.ndarray: ...

    def close(self) -> None: ...


class InMemoryFrames:
    """A :class:`FrameReader` over arrays already in memory (tests, small sequences, converters).

    Parameters
    ----------
    **streams : numpy.ndarray, shape (T, C, H, W), uint8
        Any of ``image``, ``mask``, ``silhouette``.
    """

    def __init__(self, **streams: np.ndarray):
        unknown = set(streams) - set(STREAMS)
        if unknown:
            raise ConfigError(f"unknown stream(s) {sorted(unknown)}; known: {STREAMS}")
        self._data = {}
        shape = None
        for name, arr in streams.items():
            if arr is None:
                continue
            a = np.asarray(arr)
            if a.ndim != 4 or a.dtype != np.uint8:
                raise ShapeError(f"stream {name!r} must be a (T, C, H, W) uint8 array, got {a.dtype} {a.shape}")
            if shape is not None and a.shape != shape:
                raise ShapeError(f"stream {name!r} has shape {a.shape}, others {shape}")
            shape = a.shape
            self._data[name] = a
        self.streams = tuple(s for s in STREAMS if s in self._data)

    def read(self, stream: str, k: int) -> np.ndarray:
        """``(C, H, W)`` uint8 array of ``stream`` at frame ``k``."""
        return self._data[stream][k].copy()

    def close(self) -> None:
        """Nothing to release."""


class _ZipFrames:
    """Frames from ``views/<VIEW>.zip`` archives of PNGs (one archive per view, opened once)."""

    def __init__(self, root: Path, view_files: Sequence[str], streams: Sequence[str], n_frames: int,
                 size: tuple[int, int]):
        self.root = root
        self.streams = tuple(streams)
        self.size = size
        self._paths = [root / f for f in view_files]
        self._zips: list[zipfile.ZipFile] = []
        try:
            for p in self._paths:
                if not p.is_file():
                    raise DataError(f"{p}: missing view archive (listed in {root / _META})")
                try:
                    z = zipfile.ZipFile(p, "r")
                except (zipfile.BadZipFile, OSError, EOFError) as exc:
                    raise FormatError(f"not a readable ZIP archive (truncated?): {exc}", path=p) from None
                self._zips.append(z)
                names = set(z.namelist())
                for s in self.streams:
                    for k in range(n_frames):
                        if _entry(s, k) not in names:
                            raise FormatError(f"missing entry {_entry(s, k)!r} ({n_frames} frames expected)",
                                              path=p, field=s)
        except Exception:
            self.close()
            raise

    def read(self, stream: str, k: int) -> np.ndarray:
        W, H = self.size
        out = np.empty((len(self._zips), H, W), dtype=np.uint8)
        for c, (z, p) in enumerate(zip(self._zips, self._paths, strict=True)):
            name = _entry(stream, k)
            try:
                data = z.read(name)
            except (zipfile.BadZipFile, KeyError, OSError, EOFError) as exc:
                raise FormatError(f"cannot read entry {name!r}: {exc}", path=p, field=stream) from None
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
            if img is None or img.dtype != np.uint8 or img.shape != (H, W):
                got = None if img is None else f"{img.dtype} {img.shape}"
                raise FormatError(f"entry {name!r} is not a {W}x{H} 8-bit grey PNG (got {got})", path=p, field=stream)
            out[c] = img
        return out

    def close(self) -> None:
        for z in self._zips:
            z.close()
        self._zips = []


# ---------------------------------------------------------------------- the sequence
class MultiViewSequence:
    """A calibrated multi-view sequence, read lazily frame by frame.

    Parameters
    ----------
    cameras : list of Camera
        ``C`` cameras of equal image size; their names are the view names.
    frame_rate : float
        Frames per second.
    n_frames : int
        ``T``.
    reader : FrameReader, optional
        Source of the per-frame image streams (``None``: a sequence without images, e.g. markers only).
    frame_times : numpy.ndarray of shape (T,), optional
        Seconds from the first frame; default ``k / frame_rate``.
    backgrounds : numpy.ndarray of shape (C, H, W) uint8, optional
        Empty-scene image per view.
    gt_joints : numpy.ndarray of shape (T, 15, 3), optional
        Ground-truth HumanEva joints (:data:`swarmpose.joints.JOINTS15`), world mm.
    markers : MarkerData, optional
    world_from_source : numpy.ndarray of shape (4, 4), optional
        Transform from the source data's coordinates to the world (identity by default).
    provenance : dict, optional
        Where the sequence came from (clip, seed, settings, versions).
    source_clip : str or path-like, optional
        The motion-capture clip behind the ground truth.
    subject_measurements : SubjectMeasurements, optional
        The subject's widths, offsets and marker distances (HumanEva ``.mp`` + static trial); the
        tracker sizes its cones from them (:func:`swarmpose.body.measurements.measured_cones`).
    path : path-like, optional
        Folder the sequence was read from.

    Raises
    ------
    ShapeError, ConfigError
        Inconsistent sizes or values.
    """

    def __init__(
        self,
        *,
        cameras: Sequence[Camera],
        frame_rate: float,
        n_frames: int,
        reader: FrameReader | None = None,
        frame_times: np.ndarray | None = None,
        backgrounds: np.ndarray | None = None,
        gt_joints: np.ndarray | None = None,
        markers: MarkerData | None = None,
        world_from_source: np.ndarray | None = None,
        provenance: Mapping[str, Any] | None = None,
        source_clip: str | os.PathLike[str] | None = None,
        subject_measurements: SubjectMeasurements | None = None,
        path: str | os.PathLike[str] | None = None,
    ):
        cams = list(cameras)
        if not cams:
            raise ConfigError("a sequence needs at least one camera")
        if any(not isinstance(c, Camera) for c in cams):
            raise ConfigError("cameras must be Camera objects")
        sizes = {(c.width, c.height) for c in cams}
        if len(sizes) != 1:
            raise ShapeError(f"all cameras must have one image size, got {sorted(sizes)}")
        names = [c.name for c in cams]
        if len(set(names)) != len(names):
            raise ConfigError(f"camera names must be unique, got {names}")
        fr = float(frame_rate)
        if not (math.isfinite(fr) and fr > 0):
            raise ConfigError(f"frame_rate must be finite and > 0, got {frame_rate!r}")
        T = int(n_frames)
        if T < 0 or T != n_frames:
            raise ConfigError(f"n_frames must be a non-negative integer, got {n_frames!r}")
        self.cameras = cams
        self.frame_rate = fr
        self.n_frames = T
        self._reader = reader
        W, H = sizes.pop()
        self.image_size = (W, H)
        C = len(cams)
        if frame_times is None:
            frame_times = np.arange(T) / fr
        self.frame_times = _ro(np.asarray(frame_times, dtype=np.float64))
        if self.frame_times.shape != (T,):
            raise ShapeError(f"frame_times must have shape {(T,)}, got {self.frame_times.shape}")
        problem = frame_times_problem(self.frame_times, fr)
        if problem:
            raise ConfigError(problem)
        if backgrounds is not None:
            backgrounds = np.asarray(backgrounds)
            if backgrounds.shape != (C, H, W) or backgrounds.dtype != np.uint8:
                raise ShapeError(f"backgrounds must be ({C}, {H}, {W}) uint8, got {backgrounds.dtype} {backgrounds.shape}")
            backgrounds = _ro(backgrounds.copy())
        self._backgrounds = backgrounds
        if gt_joints is not None:
            gt_joints = np.asarray(gt_joints, dtype=np.float64)
            if gt_joints.shape != (T, 15, 3):
                raise ShapeError(f"gt_joints must have shape {(T, 15, 3)}, got {gt_joints.shape}")
            gt_joints = _ro(gt_joints)
        self.gt_joints = gt_joints
        if markers is not None and markers.counts.shape != (T, C):
            raise ShapeError(f"marker counts must have shape {(T, C)}, got {markers.counts.shape}")
        self.marker_data = markers
        wfs = np.eye(4) if world_from_source is None else np.asarray(world_from_source, dtype=np.float64)
        if wfs.shape != (4, 4):
            raise ShapeError(f"world_from_source must have shape (4, 4), got {wfs.shape}")
        self.world_from_source = _ro(wfs)
        self.provenance = dict(provenance or {})
        self.source_clip = None if source_clip is None else str(source_clip)
        if subject_measurements is not None and not isinstance(subject_measurements, SubjectMeasurements):
            raise ConfigError("subject_measurements must be a SubjectMeasurements")
        self.subject_measurements = subject_measurements
        self.path = None if path is None else Path(path)

    # ------------------------------------------------------------------ metadata
    @property
    def view_names(self) -> list[str]:
        """Camera names, in view order."""
        return [c.name for c in self.cameras]

    @property
    def n_views(self) -> int:
        """Number of views ``C``."""
        return len(self.cameras)

    @property
    def streams(self) -> tuple[str, ...]:
        """Stored per-frame image streams (subset of :data:`STREAMS`)."""
        return tuple(self._reader.streams) if self._reader is not None else ()

    @property
    def marker_names(self) -> tuple[str, ...] | None:
        """Names of the markers that detection ids refer to, or None without markers."""
        return None if self.marker_data is None else self.marker_data.names

    def backgrounds(self) -> np.ndarray | None:
        """Empty-scene images ``(C, H, W)`` uint8 (read-only), or None when not stored."""
        return self._backgrounds

    def _check_k(self, k: int) -> int:
        kk = int(k)
        if kk != k or not 0 <= kk < self.n_frames:
            raise IndexError(f"frame {k!r} outside [0, {self.n_frames})")
        return kk

    def _read(self, stream: str, k: int) -> np.ndarray | None:
        k = self._check_k(k)
        if stream not in self.streams:
            return None
        return self._reader.read(stream, k)  # type: ignore[union-attr]

    # ------------------------------------------------------------------ frames
    def images(self, k: int) -> np.ndarray | None:
        """Camera images of frame ``k``, ``(C, H, W)`` uint8, or None when the sequence has none."""
        return self._read("image", k)

    def masks(self, k: int) -> np.ndarray | None:
        """Exact foreground masks of frame ``k``, ``(C, H, W)`` uint8 in {0, 1}, or None if not stored."""
        return self._read("mask", k)

    def silhouettes(self, k: int) -> np.ndarray | None:
        """Stored observed silhouettes of frame ``k`` ``(C, H, W)``, or None (compute them from images)."""
        return self._read("silhouette", k)

    def markers(self, k: int) -> list[np.ndarray] | None:
        """2D marker detections of frame ``k``: one ``(Q_c, 2)`` float64 array per view, or None."""
        k = self._check_k(k)
        return None if self.marker_data is None else self.marker_data.frame(k)[0]

    def marker_ids(self, k: int) -> list[np.ndarray] | None:
        """Identity of each detection of frame ``k`` (marker index, -1 = false); for evaluation only."""
        k = self._check_k(k)
        return None if self.marker_data is None else self.marker_data.frame(k)[1]

    def frame(self, k: int) -> Frame:
        """All stored data of frame ``k``."""
        k = self._check_k(k)
        return Frame(index=k, time=float(self.frame_times[k]), images=self.images(k), masks=self.masks(k),
                     markers=self.markers(k), silhouettes=self.silhouettes(k))

    def subsample(self, fps: float) -> np.ndarray:
        """Frame indices for tracking at a lower rate ``fps``.

        An integer ratio ``frame_rate / fps`` gives every ratio-th frame from 0; otherwise the frame
        nearest to each time ``j / fps`` (first frame = time of frame 0).

        Parameters
        ----------
        fps : float
            ``0 < fps <= frame_rate``.

        Returns
        -------
        numpy.ndarray, shape (n,), int64
        """
        fps = float(fps)
        if not (math.isfinite(fps) and 0 < fps <= self.frame_rate * (1 + 1e-9)):
            raise ConfigError(f"fps must be in (0, {self.frame_rate}], got {fps!r}")
        ratio = self.frame_rate / fps
        if abs(ratio - round(ratio)) < 1e-9:
            return np.arange(0, self.n_frames, int(round(ratio)), dtype=np.int64)
        t = self.frame_times - self.frame_times[0]
        targets = np.arange(0.0, t[-1] + 0.5 / self.frame_rate, 1.0 / fps)
        idx = np.clip(np.searchsorted(t, targets), 1, max(self.n_frames - 1, 1))
        left = idx - 1
        nearest = np.where(np.abs(t[left] - targets) <= np.abs(t[np.minimum(idx, self.n_frames - 1)] - targets),
                           left, idx)
        return np.unique(np.minimum(nearest, self.n_frames - 1)).astype(np.int64)

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[Frame]:
        for k in range(self.n_frames):
            yield self.frame(k)

    def close(self) -> None:
        """Release open files."""
        if self._reader is not None:
            self._reader.close()

    def __enter__(self) -> MultiViewSequence:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        W, H = self.image_size
        return (f"MultiViewSequence({self.n_frames} frames at {self.frame_rate:g} fps, views {self.view_names}, "
                f"{W}x{H}, streams {list(self.streams)}, markers={self.marker_data is not None}, "
                f"gt={self.gt_joints is not None}, path={str(self.path) if self.path else None})")


def frame_times_problem(times: np.ndarray, frame_rate: float) -> str | None:
    """What is wrong with a sequence's frame times (seconds) for ``frame_rate``, or ``None``.

    They must be finite and strictly increasing, and their median step within 1 % of ``1 / frame_rate``
    (single dropped frames are allowed; times in milliseconds or at another rate are not).
    """
    t = np.asarray(times, dtype=np.float64)
    if not np.isfinite(t).all():
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        return f"frame_times must be finite, frame {k} is {t[k]!r}"
    if t.size < 2:
        return None
    steps = np.diff(t)
    if (steps <= 0).any():
        k = int(np.flatnonzero(steps <= 0)[0]) + 1
        return f"frame_times must increase strictly, frame {k} is at {t[k]:g} s after {t[k - 1]:g} s"
    step = float(np.median(steps))
    if abs(step * frame_rate - 1.0) > 0.01:
        return (f"frame_times step {step:g} s (median) does not match the frame rate {frame_rate:g} fps "
                f"(expected {1.0 / frame_rate:g} s; times are in seconds)")
    return None


def _ro(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


# ---------------------------------------------------------------------- writing
def _prepare_dir(path: Path, overwrite: bool) -> None:
    if path.exists():
        if not path.is_dir():
            raise DataError(f"{path}: exists and is not a folder")
        if any(path.iterdir()):
            if not overwrite:
                raise DataError(f"{path}: folder is not empty (`swarmpose synth --force`, or overwrite=True, replaces a sequence)")
            if not (path / _META).is_file() and not (path / _CAMERAS).is_file():
                raise DataError(f"{path}: refusing to overwrite a non-empty folder that holds no sequence")
            shutil.rmtree(path)
    (path / "views").mkdir(parents=True, exist_ok=True)


def _encode_png(img: np.ndarray, level: int) -> bytes:
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img), [cv2.IMWRITE_PNG_COMPRESSION, int(level)])
    if not ok:  # pragma: no cover - cv2 only fails on unsupported arrays, which we never pass
        raise DataError("PNG encoding failed")
    return buf.tobytes()


class SequenceWriter:
    """Write a sequence folder frame by frame (streams into the per-view archives as it goes).

    Frames must be written in order ``0, 1, ..., T-1``; :meth:`finish` writes the small files and
    ``sequence.json`` last, so an interrupted write leaves a folder that :func:`open_sequence`
    rejects. PNG encoding runs on a small thread pool.

    Parameters
    ----------
    path : path-like
        Output folder (created; must be empty unless ``overwrite`` and it holds a sequence).
    cameras : list of Camera
    frame_rate : float
    n_frames : int
    streams : sequence of str, default ("image", "mask")
    overwrite : bool, default False
    png_level : int, default 1
        zlib level of the PNGs (1 is fast; higher levels save only a few percent on noisy images).
    workers : int, default 2
        Encoding threads.
    """

    def __init__(self, path: str | os.PathLike[str], cameras: Sequence[Camera], frame_rate: float, n_frames: int,
                 *, streams: Sequence[str] = ("image", "mask"), overwrite: bool = False, png_level: int = 1,
                 workers: int = 2):
        unknown = set(streams) - set(STREAMS)
        if unknown:
            raise ConfigError(f"unknown stream(s) {sorted(unknown)}; known: {STREAMS}")
        self.path = Path(path)
        self.cameras = list(cameras)
        self.frame_rate = float(frame_rate)
        self.n_frames = int(n_frames)
        self.streams = tuple(s for s in STREAMS if s in streams)
        self.png_level = int(png_level)
        W, H = self.cameras[0].width, self.cameras[0].height
        self.size = (W, H)
        _prepare_dir(self.path, overwrite)
        self._view_files = [f"views/{c.name}.zip" for c in self.cameras]
        self._zips = [zipfile.ZipFile(self.path / f, "w", compression=zipfile.ZIP_STORED) for f in self._view_files]
        self._pool = ThreadPoolExecutor(max_workers=max(1, int(workers)))
        self._pending: deque[tuple[int, dict[str, list[Future]]]] = deque()
        self._next = 0
        self._closed = False

    def write_frame(self, k: int, **streams: np.ndarray) -> None:
        """Queue frame ``k``: one ``(C, H, W)`` uint8 array per stream of the writer."""
        if k != self._next:
            raise ConfigError(f"frames must be written in order: expected frame {self._next}, got {k}")
        if set(streams) != set(self.streams):
            raise ConfigError(f"frame {k}: expected streams {list(self.streams)}, got {sorted(streams)}")
        W, H = self.size
        futs: dict[str, list[Future]] = {}
        for name, arr in streams.items():
            a = np.asarray(arr)
            if a.shape != (len(self.cameras), H, W) or a.dtype != np.uint8:
                raise ShapeError(f"frame {k} stream {name!r}: expected ({len(self.cameras)}, {H}, {W}) uint8, "
                                 f"got {a.dtype} {a.shape}")
            futs[name] = [self._pool.submit(_encode_png, a[c].copy(), self.png_level) for c in range(a.shape[0])]
        self._pending.append((k, futs))
        self._next += 1
        while len(self._pending) > 4:  # bounded memory: at most a few frames in flight
            self._flush_one()

    def _flush_one(self) -> None:
        k, futs = self._pending.popleft()
        for name in self.streams:
            for c, fut in enumerate(futs[name]):
                self._zips[c].writestr(_entry(name, k), fut.result())

    def finish(
        self,
        *,
        backgrounds: np.ndarray | None = None,
        frame_times: np.ndarray | None = None,
        gt_joints: np.ndarray | None = None,
        markers: MarkerData | None = None,
        world_from_source: np.ndarray | None = None,
        source_clip: str | os.PathLike[str] | None = None,
        provenance: Mapping[str, Any] | None = None,
        subject_measurements: SubjectMeasurements | None = None,
    ) -> Path:
        """Close the archives and write the metadata files (``sequence.json`` last).

        Returns
        -------
        pathlib.Path
            The sequence folder.
        """
        while self._pending:
            self._flush_one()
        for z in self._zips:
            z.close()
        self._pool.shutdown()
        self._closed = True
        if self._next != self.n_frames:
            raise DataError(f"{self.path}: {self._next} frames written, {self.n_frames} announced")
        T, C = self.n_frames, len(self.cameras)
        W, H = self.size
        # validate through the in-memory type (same checks as reading)
        seq = MultiViewSequence(cameras=self.cameras, frame_rate=self.frame_rate, n_frames=T,
                                frame_times=frame_times, backgrounds=backgrounds, gt_joints=gt_joints,
                                markers=markers, world_from_source=world_from_source,
                                provenance=provenance, source_clip=source_clip,
                                subject_measurements=subject_measurements)
        save_rig(self.path / _CAMERAS, self.cameras)
        np.savez(self.path / _FRAMES, frame_times=np.asarray(seq.frame_times))
        files: dict[str, Any] = {"cameras": _CAMERAS, "frames": _FRAMES, "backgrounds": None,
                                 "ground_truth": None, "markers": None,
                                 "views": dict(zip([c.name for c in self.cameras], self._view_files, strict=True))}
        if backgrounds is not None:
            np.savez_compressed(self.path / _BACKGROUNDS, backgrounds=np.asarray(seq.backgrounds()))
            files["backgrounds"] = _BACKGROUNDS
        if gt_joints is not None:
            np.savez_compressed(self.path / _GROUND_TRUTH, joints=np.asarray(seq.gt_joints))
            files["ground_truth"] = _GROUND_TRUTH
        marker_meta = None
        if markers is not None:
            arrays = {"counts": markers.counts, "uv": markers.uv, "ids": markers.ids}
            if markers.projections is not None:
                arrays["projections"] = markers.projections
            if markers.visible is not None:
                arrays["visible"] = markers.visible
            if markers.confidence is not None:
                arrays["confidence"] = markers.confidence
            np.savez_compressed(self.path / _MARKERS, **arrays)
            files["markers"] = _MARKERS
            marker_meta = {"names": list(markers.names)}
        meta = {
            "format": SEQUENCE_FORMAT,
            "version": SEQUENCE_VERSION,
            "n_frames": T,
            "n_views": C,
            "frame_rate": self.frame_rate,
            "image_size": [W, H],
            "views": [c.name for c in self.cameras],
            "streams": list(self.streams),
            "files": files,
            "markers": marker_meta,
            "ground_truth_joints": "JOINTS15" if gt_joints is not None else None,
            "world_from_source": np.asarray(seq.world_from_source).tolist(),
            "source_clip": seq.source_clip,
            "subject_measurements": (None if subject_measurements is None
                                     else subject_measurements.to_dict()),
            "provenance": _json_safe(seq.provenance),
        }
        tmp = self.path / (_META + ".tmp")
        tmp.write_text(json.dumps(meta, indent=1, allow_nan=False) + "\n", encoding="utf-8")
        tmp.replace(self.path / _META)
        return self.path

    def abort(self) -> None:
        """Stop writing (closes files; the folder stays incomplete and unreadable)."""
        if not self._closed:
            self._pool.shutdown(cancel_futures=True)
            for z in self._zips:
                z.close()
            self._closed = True


def _json_safe(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _json_safe(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_sequence(path: str | os.PathLike[str], seq: MultiViewSequence, *, overwrite: bool = False,
                   png_level: int = 1) -> Path:
    """Write any :class:`MultiViewSequence` in the on-disk format (frame by frame).

    Parameters
    ----------
    path : path-like
        Output folder.
    seq : MultiViewSequence
    overwrite : bool, default False
    png_level : int, default 1

    Returns
    -------
    pathlib.Path
    """
    w = SequenceWriter(path, seq.cameras, seq.frame_rate, seq.n_frames, streams=seq.streams,
                       overwrite=overwrite, png_level=png_level)
    try:
        for k in range(seq.n_frames):
            w.write_frame(k, **{s: seq._read(s, k) for s in seq.streams})
        return w.finish(backgrounds=seq.backgrounds(), frame_times=np.asarray(seq.frame_times),
                        gt_joints=None if seq.gt_joints is None else np.asarray(seq.gt_joints),
                        markers=seq.marker_data, world_from_source=np.asarray(seq.world_from_source),
                        source_clip=seq.source_clip, provenance=seq.provenance,
                        subject_measurements=seq.subject_measurements)
    except BaseException:
        w.abort()
        raise


# ---------------------------------------------------------------------- reading
def _load_npz(path: Path, keys: Sequence[str], optional: Sequence[str] = ()) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise DataError(f"{path}: missing file (listed in {path.parent / _META})")
    arrays = load_npz(path)
    for k in keys:
        if k not in arrays:
            raise FormatError(f"missing array {k!r}", path=path, field=k)
    return {k: arrays[k] for k in [*keys, *(o for o in optional if o in arrays)]}


def _field(meta: Mapping[str, Any], name: str, path: Path, kinds: tuple[type, ...]) -> Any:
    if name not in meta:
        raise FormatError(f"missing field {name!r}", path=path, field=name)
    v = meta[name]
    if isinstance(v, bool) and bool not in kinds:
        raise FormatError(f"field {name!r} has the wrong type (bool)", path=path, field=name)
    if not isinstance(v, kinds):
        raise FormatError(f"field {name!r} must be {' or '.join(k.__name__ for k in kinds)}, "
                          f"got {type(v).__name__}", path=path, field=name)
    return v


def _check_shape(arr: np.ndarray, shape: tuple[int, ...], dtype: Any, path: Path, field: str) -> np.ndarray:
    if arr.shape != shape:
        raise FormatError(f"array {field!r} has shape {arr.shape}, expected {shape}", path=path, field=field)
    if dtype is not None and arr.dtype != np.dtype(dtype):
        raise FormatError(f"array {field!r} has dtype {arr.dtype}, expected {np.dtype(dtype)}", path=path, field=field)
    return arr


#: Openers of sources that are not folders, by prefix (``"humaneva:"``): see :func:`register_source_scheme`.
_SOURCE_OPENERS: dict[str, Callable[[str], MultiViewSequence]] = {}


def register_source_scheme(prefix: str, opener: Callable[[str], MultiViewSequence]) -> None:
    """Let :func:`open_sequence` open every source that begins with ``prefix`` as ``opener(source)``.

    The dataset readers (:mod:`swarmpose.datasets`) register ``humaneva:`` and ``leewalk:`` when imported.
    """
    if not (isinstance(prefix, str) and len(prefix) > 2 and prefix.endswith(":")):
        raise ConfigError(f"a source prefix is a name and a colon, such as 'humaneva:'; got {prefix!r}")
    _SOURCE_OPENERS[prefix] = opener


def open_sequence(path: str | os.PathLike[str]) -> MultiViewSequence:
    """Open a sequence folder written by :class:`SequenceWriter` / :func:`write_sequence`.

    Reads the metadata and small arrays, checks that every listed file exists and that each view
    archive holds every frame of every stream; images are decoded only when asked for.

    Parameters
    ----------
    path : path-like
        The sequence folder.

    Returns
    -------
    MultiViewSequence
        Close it (or use ``with``) to release the archives.

    Raises
    ------
    DataError
        The folder, ``sequence.json`` or a listed file is missing.
    FormatError
        A file is malformed or truncated, a field is missing or wrong, arrays have the wrong
        shape, or an archive misses frames (the message names the file and the field or entry).

    Notes
    -----
    A source with a registered prefix (:func:`register_source_scheme`; ``humaneva:...`` and
    ``leewalk:...`` once :mod:`swarmpose.datasets` is imported) is opened by its reader into the same
    type, read lazily.
    """
    source = os.fspath(path)
    for prefix, opener in _SOURCE_OPENERS.items():
        if source.startswith(prefix):
            return opener(source)
    root = Path(path)
    if not root.is_dir():
        scheme = source.partition(":")[0]
        if ":" in source and len(scheme) > 1 and scheme.isalnum():
            raise DataError(f"{root}: no such sequence folder, and no reader is registered for {scheme + ':'!r} "
                            "sources (the dataset readers register theirs when swarmpose.datasets is imported)")
        raise DataError(f"{root}: no such sequence folder")
    meta_path = root / _META
    if not meta_path.is_file():
        raise DataError(f"{meta_path}: missing (not a sequence folder, or an interrupted write)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise FormatError(f"invalid JSON: {exc.msg}", path=meta_path, line=exc.lineno) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{meta_path}: cannot read: {exc}") from exc
    if not isinstance(meta, dict):
        raise FormatError("expected a JSON object at the top level", path=meta_path)
    fmt = _field(meta, "format", meta_path, (str,))
    if fmt != SEQUENCE_FORMAT:
        raise FormatError(f"format must be {SEQUENCE_FORMAT!r}, got {fmt!r}", path=meta_path, field="format")
    version = _field(meta, "version", meta_path, (int,))
    if version != SEQUENCE_VERSION:
        raise FormatError(f"unsupported version {version!r} (this reader knows {SEQUENCE_VERSION})",
                          path=meta_path, field="version")
    T = _field(meta, "n_frames", meta_path, (int,))
    if T < 0:
        raise FormatError(f"n_frames must be >= 0, got {T}", path=meta_path, field="n_frames")
    fr = float(_field(meta, "frame_rate", meta_path, (int, float)))
    if not (math.isfinite(fr) and fr > 0):
        raise FormatError(f"frame_rate must be finite and > 0, got {fr!r}", path=meta_path, field="frame_rate")
    size = _field(meta, "image_size", meta_path, (list,))
    if len(size) != 2 or not all(isinstance(x, int) and not isinstance(x, bool) and x > 0 for x in size):
        raise FormatError(f"image_size must be [width, height] positive integers, got {size!r}",
                          path=meta_path, field="image_size")
    W, H = size
    views = _field(meta, "views", meta_path, (list,))
    streams = _field(meta, "streams", meta_path, (list,))
    bad = [s for s in streams if s not in STREAMS]
    if bad:
        raise FormatError(f"unknown stream(s) {bad}; known: {list(STREAMS)}", path=meta_path, field="streams")
    files = _field(meta, "files", meta_path, (dict,))
    for key in ("cameras", "frames", "views"):
        if key not in files:
            raise FormatError(f"missing field 'files.{key}'", path=meta_path, field=f"files.{key}")
    view_files = files["views"]
    if not isinstance(view_files, dict) or sorted(view_files) != sorted(views):
        raise FormatError(f"'files.views' must map every view {views} to its archive", path=meta_path,
                          field="files.views")
    shared = sorted(f for f, n in Counter(map(str, view_files.values())).items() if n > 1)
    if shared:
        raise FormatError(f"'files.views' gives two views the same archive {shared} (each view has its own images)",
                          path=meta_path, field="files.views")

    cam_path = root / files["cameras"]
    if not cam_path.is_file():
        raise DataError(f"{cam_path}: missing camera file (listed in {meta_path})")
    cameras = load_rig(cam_path)
    if [c.name for c in cameras] != list(views):
        raise FormatError(f"camera names {[c.name for c in cameras]} differ from the views {views} of {meta_path}",
                          path=cam_path, field="name")
    for c in cameras:
        if (c.width, c.height) != (W, H):
            raise FormatError(f"camera {c.name!r} is {c.width}x{c.height}, the sequence {W}x{H}",
                              path=cam_path, field="width")
    C = len(cameras)
    fpath = root / files["frames"]
    frame_times = _check_shape(_load_npz(fpath, ["frame_times"])["frame_times"], (T,), np.float64, fpath,
                               "frame_times")
    problem = frame_times_problem(frame_times, fr)
    if problem:
        raise FormatError(problem, path=fpath, field="frame_times")
    backgrounds = None
    if files.get("backgrounds"):
        bpath = root / files["backgrounds"]
        backgrounds = _check_shape(_load_npz(bpath, ["backgrounds"])["backgrounds"], (C, H, W), np.uint8, bpath,
                                   "backgrounds")
    gt = None
    if files.get("ground_truth"):
        gpath = root / files["ground_truth"]
        gt = _check_shape(_load_npz(gpath, ["joints"])["joints"], (T, 15, 3), np.float64, gpath, "joints")
    markers = None
    if files.get("markers"):
        mpath = root / files["markers"]
        mm = meta.get("markers")
        if not isinstance(mm, dict) or not isinstance(mm.get("names"), list):
            raise FormatError("field 'markers.names' must list the marker names", path=meta_path, field="markers")
        names = tuple(str(n) for n in mm["names"])
        arr = _load_npz(mpath, ["counts", "uv", "ids"], optional=["projections", "visible", "confidence"])
        counts = _check_shape(arr["counts"], (T, C), np.int64, mpath, "counts")
        total = int(counts.sum())
        uv = _check_shape(arr["uv"], (total, 2), np.float64, mpath, "uv")
        ids = _check_shape(arr["ids"], (total,), np.int16, mpath, "ids")
        M = len(names)
        proj = arr.get("projections")
        if proj is not None:
            _check_shape(proj, (T, C, M, 2), np.float64, mpath, "projections")
        vis = arr.get("visible")
        if vis is not None:
            _check_shape(vis, (T, C, M), np.bool_, mpath, "visible")
        if np.any(ids >= M) or np.any(ids < -1):
            raise FormatError(f"ids must be in [-1, {M}), got {int(ids.min())}..{int(ids.max())}", path=mpath,
                              field="ids")
        conf = arr.get("confidence")
        if conf is not None:
            conf = _check_shape(conf, (total,), np.float64, mpath, "confidence")
            if not np.all((conf >= 0) & (conf <= 1)):
                raise FormatError("confidences must lie in [0, 1]", path=mpath, field="confidence")
        markers = MarkerData(names, counts, uv, ids, proj, vis, conf)
    wfs = meta.get("world_from_source")
    try:
        wfs_arr = None if wfs is None else np.asarray(wfs, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError("world_from_source must be a 4x4 list of numbers", path=meta_path,
                          field="world_from_source") from None
    if wfs_arr is not None and wfs_arr.shape != (4, 4):
        raise FormatError(f"world_from_source must be 4x4, got shape {wfs_arr.shape}", path=meta_path,
                          field="world_from_source")
    prov = meta.get("provenance") or {}
    if not isinstance(prov, dict):
        raise FormatError("provenance must be an object", path=meta_path, field="provenance")
    sm = meta.get("subject_measurements")
    measurements = None if sm is None else SubjectMeasurements.from_dict(sm, path=meta_path)
    reader = None
    if streams:
        reader = _ZipFrames(root, [view_files[v] for v in views], streams, T, (W, H))
    try:
        return MultiViewSequence(cameras=cameras, frame_rate=fr, n_frames=T, reader=reader,
                                 frame_times=frame_times, backgrounds=backgrounds, gt_joints=gt,
                                 markers=markers, world_from_source=wfs_arr, provenance=prov,
                                 source_clip=meta.get("source_clip"), subject_measurements=measurements,
                                 path=root)
    except (ShapeError, ConfigError) as exc:
        if reader is not None:
            reader.close()
        raise FormatError(str(exc), path=meta_path) from None
