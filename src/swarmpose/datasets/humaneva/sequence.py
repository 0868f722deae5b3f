"""One trial assembled into a :class:`~swarmpose.io.sequence.MultiViewSequence`, and ``humaneva:`` sources."""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

import numpy as np

from swarmpose.body.measurements import limb_table
from swarmpose.camera import Camera
from swarmpose.datasets.humaneva.calibration import (
    StreamOffset,
    read_calibration,
    read_mp,
    read_offsets,
    synchronize,
)
from swarmpose.datasets.humaneva.layout import (
    DATASET_CAMERAS,
    DEFAULT_CAMERAS,
    DEFAULT_RISK,
    FIRST_FRAME_I,
    VIDEO_RATE,
    humaneva_frame_range,
    trial_files,
)
from swarmpose.datasets.humaneva.mocap import (
    GroundTruth,
    MocapMarkers,
    humaneva_ground_truth,
    limb_lengths,
    read_mocap,
    subject_measurements,
)
from swarmpose.datasets.humaneva.video import (
    HumanEvaFrames,
    VideoSource,
    _grey,
    _nearest_session,
    load_background_model,
)
from swarmpose.errors import ConfigError, DataError, ShapeError
from swarmpose.io.sequence import MultiViewSequence


# ---------------------------------------------------------------------- trials and sequences
def _split_action_trial(name: str) -> tuple[str, str]:
    m = re.fullmatch(r"(.+)_(\d+)", name)
    if not m:
        raise ConfigError(f"expected <Action>_<Trial> (e.g. Walking_1), got {name!r}")
    return m.group(1), m.group(2)


class HumanEvaTrial:
    """One HumanEva trial (subject, action, trial number) with its calibration, sync and mocap.

    Parameters
    ----------
    subject_dir : path-like
        ``<root>/<S>`` (e.g. ``/data/HumanEva/S1``).
    action : str
        ``Walking``, ``Jog``, ``ThrowCatch``, ``Gestures``, ``Box`` or ``Combo``.
    trial : str or int
    dataset : {"HumanEva-I", "HumanEva-II"}, optional
        Detected from the camera names when omitted.

    Attributes
    ----------
    offsets : dict of str to StreamOffset or None
    sync : SyncInfo
        Over every camera of the dataset with an ``.ofs`` (reproduces the official frame numbers).
    files : dict
        Paths used (see :func:`trial_files`).

    Raises
    ------
    DataError
        The subject folder or every ``.ofs`` of the trial is missing.
    FormatError
        A malformed ``.ofs``.
    """

    def __init__(self, subject_dir: str | os.PathLike[str], action: str, trial: str | int,
                 dataset: str | None = None):
        self.subject_dir = Path(subject_dir)
        if not self.subject_dir.is_dir():
            raise DataError(f"{self.subject_dir}: no such HumanEva subject folder")
        self.subject = self.subject_dir.name
        self.action = action
        self.trial = str(trial)
        if dataset is not None and dataset not in DATASET_CAMERAS:
            raise ConfigError(f"dataset must be one of {sorted(DATASET_CAMERAS)}, got {dataset!r}")
        self.files = trial_files(self.subject_dir, action, self.trial, dataset)
        self.dataset: str = self.files["dataset"]
        self.all_cameras: tuple[str, ...] = self.files["cameras"]
        self.offsets: dict[str, StreamOffset | None] = {
            c: (read_offsets(p) if p.is_file() else None) for c, p in self.files["offsets"].items()}
        if not any(self.offsets.values()):
            expected = ", ".join(str(p) for p in self.files["offsets"].values())
            raise DataError(f"{self.subject_dir}: no sync file for {action}_{self.trial}; expected {expected}")
        self.sync = synchronize(self.offsets, self.all_cameras)
        self._mocap: MocapMarkers | None = None

    @property
    def name(self) -> str:
        """``S1_Walking_1``."""
        return f"{self.subject}_{self.action}_{self.trial}"

    @property
    def has_mocap(self) -> bool:
        """Whether a mocap file (``.mat`` cache or ``.c3d``) exists for the trial."""
        p: Path = self.files["mocap"]
        return p.is_file() or p.with_suffix(".c3d").is_file()

    def mocap(self) -> MocapMarkers:
        """The trial's markers (read once)."""
        if self._mocap is None:
            self._mocap = read_mocap(self.files["mocap"])
        return self._mocap

    def camera(self, cam: str, size: tuple[int, int]) -> Camera:
        """Calibration of ``cam`` as a :class:`Camera` of image size ``(width, height)``."""
        return read_calibration(self.files["calibration"][cam], width=size[0], height=size[1], name=cam)

    def available_frames(self, cameras: Sequence[str], sources: Mapping[str, VideoSource] | None = None) -> int:
        """Last synchronized frame with video for every camera in ``cameras`` and mocap (if any)."""
        last = None
        for c in cameras:
            if c not in self.sync.video_start:
                raise DataError(f"{self.files['offsets'][c]}: missing sync file for camera {c}")
            if sources is not None:
                n = sources[c].n_frames
                lc = n - self.sync.video_start[c] + 1
                last = lc if last is None else min(last, lc)
        if self.has_mocap:
            lm = self.sync.mocap_frames(self.mocap().n_frames)
            last = lm if last is None else min(last, lm)
        return int(last if last is not None else 0)

    def frame_range(self, split: str = "auto", frames: tuple[int, int] | None = None) -> tuple[int, int]:
        """Requested synchronized frames ``(first, last)`` before checking availability."""
        if frames is not None:
            a, b = int(frames[0]), int(frames[1])
            if not 1 <= a <= b:
                raise ConfigError(f"frames must be 1 <= first <= last, got {a}-{b}")
            return a, b
        if split == "all":
            return (FIRST_FRAME_I if self.dataset == "HumanEva-I" else 1), 10**9
        if split not in ("auto", "validate", "train", "test"):
            raise ConfigError(f"split must be auto, all, validate, train or test; got {split!r}")
        r = humaneva_frame_range(self.dataset, self.subject, self.action, self.trial, split)
        if r is None:
            if split != "auto":
                raise ConfigError(f"{self.dataset} has no {split!r} partition for {self.subject} {self.action} "
                                  f"trial {self.trial}")
            return (FIRST_FRAME_I if self.dataset == "HumanEva-I" else 1), 10**9
        return r

    def ground_truth(self, frames: np.ndarray, static: MocapMarkers | None = None) -> tuple[GroundTruth, dict]:
        """Ground truth at synchronized frames ``frames`` and the subject measurements used."""
        mocap = self.mocap()
        notes: dict[str, Any] = {}
        mp_path = self.files["mp"]
        mp = read_mp(mp_path)
        if static is None:
            sp: Path = self.files["static"]
            if sp.is_file() or sp.with_suffix(".c3d").is_file():
                static = read_mocap(sp)
                notes["torso_radius_from"] = str(static.path)
            else:
                static = mocap
                notes["torso_radius_from"] = f"{mocap.path} (no Static trial found)"
        measurements = subject_measurements(static, mp, mp_path)
        params = limb_table(measurements)
        gt = humaneva_ground_truth(mocap, self.sync.mocap_position(frames), torso_radius=float(params[0, 0]),
                                   l_shoulder_offset=float(params[5, 0]), r_shoulder_offset=float(params[7, 0]))
        notes["limb_params"] = params
        notes["measurements"] = measurements
        notes["limb_lengths_mm"] = limb_lengths(mocap)
        return gt, notes

    def sequence(self, cameras: Sequence[str] | None = None, *, split: str = "auto",
                 frames: tuple[int, int] | None = None, silhouettes: bool = True,
                 background_frames: int | None = 100, cache_dir: str | os.PathLike[str] | None = "cache/humaneva",
                 risk: Mapping[str, float] | None = None, min_area: int = 10,
                 largest_only: bool = False) -> MultiViewSequence:
        """The trial as a lazily read :class:`~swarmpose.io.sequence.MultiViewSequence`.

        Parameters
        ----------
        cameras : sequence of str, optional
            Views (one image size; HumanEva-I cannot mix C* and BW*). Default C1-C3 (HumanEva-I) or
            C1-C4 (HumanEva-II).
        split : str, default "auto"
            Partition (see :func:`humaneva_frame_range`) or ``"all"``.
        frames : (int, int), optional
            Explicit synchronized frames ``(first, last)``, inclusive; overrides ``split``.
        silhouettes : bool, default True
            Offer a ``silhouette`` stream (HumanEva background model) when background footage exists.
        background_frames, cache_dir
            See :func:`load_background_model`.
        risk : mapping of camera to float, optional
            Background-model risk per camera (defaults of the support code).
        min_area, largest_only
            Silhouette post-processing.

        Returns
        -------
        MultiViewSequence
            Frame ``k`` is synchronized frame ``first + k``; ``gt_joints`` are NaN rows on invalid
            mocap frames (None without mocap, e.g. HumanEva-I trial 2); ``backgrounds`` are the grey
            session means nearest to the first frame; ``provenance`` records files, sync and the
            subject measurements (18 limb lengths, 10 x 5 cone parameters). Close it when done.

        Raises
        ------
        DataError
            A missing file (named), or the requested frames are not all available.
        FormatError
            A malformed file (named, with line or field).
        ConfigError, ShapeError
            Bad options, or cameras of different image sizes.
        """
        cams = tuple(cameras) if cameras else DEFAULT_CAMERAS[self.dataset]
        unknown = [c for c in cams if c not in self.all_cameras]
        if unknown:
            raise ConfigError(f"unknown camera(s) {unknown} for {self.dataset}; known: {list(self.all_cameras)}")
        if len(set(cams)) != len(cams):
            raise ConfigError(f"cameras must be distinct, got {list(cams)}")
        sources: dict[str, VideoSource] = {}
        try:
            for c in cams:
                sources[c] = VideoSource(self.files["video"][c])
            sizes = {c: s.size for c, s in sources.items()}
            if len(set(sizes.values())) != 1:
                raise ShapeError(f"the cameras {list(cams)} have different image sizes {sizes}; choose cameras of one "
                                 "kind (HumanEva-I: C1-C3 colour or BW1-BW4 greyscale)")
            size = next(iter(sizes.values()))
            camera_objs = [self.camera(c, size) for c in cams]
            first, last = self.frame_range(split, frames)
            avail = self.available_frames(cams, sources)
            open_ended = last >= 10**9
            if open_ended:
                last = avail
            if first > last or last > avail:
                what = "the videos" + (" and mocap" if self.has_mocap else "")
                raise DataError(f"{self.subject_dir}: {self.action}_{self.trial} frames {first}-"
                                f"{'end' if open_ended else last} requested, but {what} cover synchronized frames "
                                f"1-{avail} for cameras {list(cams)}")
            F = np.arange(first, last + 1)
            video_index = np.stack([self.sync.video_frame(c, F) - 1 for c in cams], axis=1)
            if video_index.min() < 0:
                raise DataError(f"{self.subject_dir}: synchronized frame {first} precedes the start of a video")
            gt = notes = None
            if self.has_mocap:
                gt, notes = self.ground_truth(F)
            models = None
            backgrounds = None
            bg_models = [load_background_model(self.subject_dir, c, max_frames=background_frames, cache_dir=cache_dir)
                         for c in cams]
            if all(m is not None for m in bg_models):
                for c, m in zip(cams, bg_models, strict=True):
                    if m.size != size:
                        raise ShapeError(f"background model of {c} is {m.size[0]}x{m.size[1]}, the video "
                                         f"{size[0]}x{size[1]}")
                backgrounds = np.stack([_nearest_session(m, _grey(sources[c].read(int(video_index[0, i]))))
                                        for i, (c, m) in enumerate(zip(cams, bg_models, strict=True))])
                if silhouettes:
                    models = bg_models
            risks = dict(DEFAULT_RISK[self.dataset])
            if risk:
                risks.update({str(k): float(v) for k, v in risk.items()})
            reader = HumanEvaFrames([sources[c] for c in cams], video_index, models,
                                    [risks.get(c, 1.0) for c in cams], min_area=min_area, largest_only=largest_only)
            provenance: dict[str, Any] = {
                "source": "humaneva", "dataset": self.dataset, "subject": self.subject, "action": self.action,
                "trial": self.trial, "split": "frames" if frames is not None else split,
                "sync_frames": [int(first), int(last)], "video_start": {c: self.sync.video_start[c] for c in cams},
                "mocap_start": self.sync.mocap_start, "mocap_scale": self.sync.mocap_scale,
                "files": {"calibration": {c: str(self.files["calibration"][c]) for c in cams},
                          "offsets": {c: str(self.files["offsets"][c]) for c in self.all_cameras if self.offsets[c]},
                          "video": {c: str(sources[c].path) for c in cams},
                          "mocap": str(self.files["mocap"]) if self.has_mocap else None},
                "background_model": models is not None or backgrounds is not None,
                "risk": {c: risks.get(c, 1.0) for c in cams},
            }
            if gt is not None:
                provenance.update({
                    "invalid_frames": int((~gt.valid).sum()),
                    "limb_lengths_mm": notes["limb_lengths_mm"].tolist(),
                    "limb_params": notes["limb_params"].tolist(),
                    "torso_radius_from": notes["torso_radius_from"],
                    "ground_truth": "HumanEva cur_frame 20 points; JOINTS15 double joints = midpoints",
                })
            return MultiViewSequence(cameras=camera_objs, frame_rate=VIDEO_RATE, n_frames=len(F), reader=reader,
                                     frame_times=(F - first) / VIDEO_RATE, backgrounds=backgrounds,
                                     gt_joints=None if gt is None else gt.joints15, provenance=provenance,
                                     subject_measurements=None if gt is None else notes["measurements"],
                                     path=self.subject_dir)
        except BaseException:
            for s in sources.values():
                s.close()
            raise


def open_humaneva(subject_dir: str | os.PathLike[str], action: str, trial: str | int,
                  dataset: str | None = None) -> HumanEvaTrial:
    """Open one trial; see :class:`HumanEvaTrial`."""
    return HumanEvaTrial(subject_dir, action, trial, dataset)


@dataclass(frozen=True)
class HumanEvaSpec:
    """A parsed ``humaneva:`` source: ``humaneva:<root>/<S>/<Action>_<Trial>[?key=value&...]``.

    Keys: ``cams`` (comma list, e.g. ``BW1,BW2,BW3,BW4``), ``split`` (auto, all, validate, train,
    test), ``frames`` (``first-last``, synchronized frames), ``silhouettes`` (0/1), ``bgframes``
    (frames per background session; 0 = all), ``dataset`` (``I``/``II``).
    """

    subject_dir: Path
    action: str
    trial: str
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """A short name for result folders: ``S1_Walking_1`` (plus the cameras when given)."""
        cams = self.options.get("cameras")
        return f"{self.subject_dir.name}_{self.action}_{self.trial}" + (f"-{'-'.join(cams)}" if cams else "")


_SPEC_KEYS = ("cams", "split", "frames", "silhouettes", "bgframes", "dataset")


def parse_humaneva_spec(spec: str | os.PathLike[str]) -> HumanEvaSpec:
    """Parse ``humaneva:<root>/<S>/<Action>_<Trial>[?cams=C1,C2&split=all&frames=6-100]``.

    The ``humaneva:`` prefix is optional. Raises :class:`ConfigError` for a malformed spec.
    """
    s = os.fspath(spec)
    if s.startswith("humaneva:"):
        s = s[len("humaneva:"):]
    path_part, _, query = s.partition("?")
    if not path_part:
        raise ConfigError("humaneva: source needs a path, e.g. humaneva:/data/HumanEva/S1/Walking_1")
    p = Path(path_part)
    action, trial = _split_action_trial(p.name)
    opts: dict[str, Any] = {}
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise ConfigError(f"malformed options {query!r}; expected key=value pairs joined by '&'") from None
    for k, v in pairs:
        if k not in _SPEC_KEYS:
            raise ConfigError(f"unknown humaneva option {k!r}; known: {', '.join(_SPEC_KEYS)}")
        if k == "cams":
            opts["cameras"] = tuple(c.strip() for c in v.split(",") if c.strip())
            if not opts["cameras"]:
                raise ConfigError("cams names no camera; give a comma-separated list such as cams=C1,C2,C3 "
                                  "(or leave it out for every camera)")
        elif k == "split":
            opts["split"] = v
        elif k == "frames":
            m = re.fullmatch(r"\s*(\d+)\s*[-:]\s*(\d+)\s*", v)
            if not m:
                raise ConfigError(f"frames must look like 6-590, got {v!r}")
            opts["frames"] = (int(m.group(1)), int(m.group(2)))
        elif k == "silhouettes":
            if v not in ("0", "1", "true", "false"):
                raise ConfigError(f"silhouettes must be 0 or 1, got {v!r}")
            opts["silhouettes"] = v in ("1", "true")
        elif k == "bgframes":
            if not v.isdigit():
                raise ConfigError(f"bgframes must be a non-negative integer, got {v!r}")
            opts["background_frames"] = int(v) or None
        elif k == "dataset":
            if v not in ("I", "II"):
                raise ConfigError(f"dataset must be I or II, got {v!r}")
            opts["dataset"] = f"HumanEva-{v}"
    return HumanEvaSpec(p.parent, action, trial, opts)


def humaneva_sequence(spec: str | os.PathLike[str], **overrides: Any) -> MultiViewSequence:
    """Open a ``humaneva:`` source as a lazily read :class:`~swarmpose.io.sequence.MultiViewSequence`.

    Parameters
    ----------
    spec : str or path-like
        ``humaneva:<root>/<S>/<Action>_<Trial>[?options]`` (see :class:`HumanEvaSpec`); the prefix is
        optional.
    **overrides
        Keyword arguments of :meth:`HumanEvaTrial.sequence` (``cameras``, ``split``, ``frames``,
        ``cache_dir``, ...), taking precedence over the spec's options.

    Returns
    -------
    MultiViewSequence

    Examples
    --------
    >>> seq = humaneva_sequence("humaneva:/data/HumanEva/S1/Walking_1?cams=C1,C2,C3")  # doctest: +SKIP
    """
    parsed = parse_humaneva_spec(spec)
    opts = dict(parsed.options)
    dataset = overrides.pop("dataset", opts.pop("dataset", None))
    opts.update(overrides)
    trial = HumanEvaTrial(parsed.subject_dir, parsed.action, parsed.trial, dataset)
    return trial.sequence(**opts)
