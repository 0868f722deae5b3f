"""The Lee walk release of Balan, Sigal & Black (2005), as far as its format is documented.

What is known (``shared/reference/humaneva-facts.md`` section 7.1, thesis [FL12] l.541): one subject
walking in a circle, **4 greyscale cameras, 644 x 484 pixels, 60 fps, 532 frames per camera**,
precomputed background-subtracted images, camera calibration, and ground-truth parameters of
Balan's 31-parameter body model computed from motion capture; distributed with Balan's MATLAB
code at ``http://www.cs.brown.edu/~alb/download.htm``. **The file names and formats inside that
release are not publicly documented** (no copy was found), so this module reads a documented
*adapter layout* -- :class:`LeeWalkLayout` -- whose patterns can be changed to match the files
you have. Every missing piece raises an error that lists the files that were looked for.

Default layout (``{cam}`` is 1..4; the first existing candidate wins)::

    calibration/cam{cam}.cal | Calibration/cam{cam}.cal | calib/cam{cam}.cal | cam{cam}.cal | Spica{cam}Calib.cal
        22 numbers, the HumanEva .cal format (fc cc alpha_c kc R T); the HumanEva support code's
        calibration reader names its example "Spica1Calib.cal", and the Lee walk was filmed with
        the Spica-grabbed greyscale cameras, so that format is assumed.
    images/cam{cam}/ | Images/cam{cam}/ | cam{cam}/ | cam{cam}.avi         numbered images or a video
    silhouettes/cam{cam}/ | bgsub/cam{cam}/ | foreground/cam{cam}/        numbered images, non-zero = foreground
    background/cam{cam}.{png,bmp,pgm,tif} (optional)                      empty-scene image
    groundtruth/params.txt | gt_params.txt (optional)                     T lines x 31 numbers (thesis Table 5.1
                                                                          order: x1..x31, radians and mm)
    groundtruth/joints15.txt | gt_joints15.txt (optional)                 T lines x 45 numbers: JOINTS15 x, y, z (mm)

At least one of images and silhouettes is required per camera. Frame ``k`` of the sequence is the
``k``-th file (by its trailing number) in each folder. The 31 parameters cannot be turned into the
15 joints without the subject's limb lengths (not published, facts section 10), so ground-truth
joints come from ``joints15.txt`` when present; the parameters are exposed as
:attr:`LeeWalkRelease.gt_params` (convert them with ``swarmpose.body`` once the subject is known).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

import cv2
import numpy as np

from swarmpose.camera import Camera
from swarmpose.datasets.humaneva import VideoSource, parse_calibration
from swarmpose.datasets.humaneva.files import _number, _read_text
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.sequence import MultiViewSequence
from swarmpose.joints import JOINT_INDEX

__all__ = ["LeeWalkLayout", "LeeWalkRelease", "open_leewalk", "leewalk_sequence", "read_number_table",
           "LEEWALK_FRAMES", "LEEWALK_SIZE", "LEEWALK_RATE", "N_PARAMS"]

LEEWALK_FRAMES = 532
LEEWALK_SIZE = (644, 484)
LEEWALK_RATE = 60.0
N_PARAMS = 31


@dataclass(frozen=True)
class LeeWalkLayout:
    """Where the Lee walk files are -- the adapter point for the undocumented release layout.

    Each field is a tuple of candidate paths relative to the release folder, with ``{cam}``
    replaced by each entry of ``cameras``; the first that exists is used. Pass your own instance to
    :func:`open_leewalk` when your copy names its files differently.
    """

    cameras: tuple[str, ...] = ("1", "2", "3", "4")
    frame_rate: float = LEEWALK_RATE
    calibration: tuple[str, ...] = ("calibration/cam{cam}.cal", "Calibration/cam{cam}.cal", "calib/cam{cam}.cal",
                                    "cam{cam}.cal", "Spica{cam}Calib.cal")
    images: tuple[str, ...] = ("images/cam{cam}", "Images/cam{cam}", "cam{cam}", "cam{cam}.avi", "images/cam{cam}.avi")
    silhouettes: tuple[str, ...] = ("silhouettes/cam{cam}", "Silhouettes/cam{cam}", "bgsub/cam{cam}",
                                    "foreground/cam{cam}")
    backgrounds: tuple[str, ...] = tuple(f"{d}/cam{{cam}}.{e}" for d in ("background", "Background")
                                         for e in ("png", "bmp", "pgm", "tif"))
    gt_params: tuple[str, ...] = ("groundtruth/params.txt", "GroundTruth/params.txt", "gt_params.txt")
    gt_joints: tuple[str, ...] = ("groundtruth/joints15.txt", "GroundTruth/joints15.txt", "gt_joints15.txt")

    def find(self, root: Path, kind: str, cam: str | None = None) -> Path | None:
        """First existing candidate of ``kind`` (a field name) for ``cam``, or None."""
        for pattern in getattr(self, kind):
            p = root / pattern.format(cam=cam)
            if p.exists():
                return p
        return None

    def expected(self, root: Path, kind: str, cam: str | None = None) -> str:
        """The candidates of ``kind`` as one string, for error messages."""
        return ", ".join(str(root / pat.format(cam=cam)) for pat in getattr(self, kind))


def _missing(root: Path, layout: LeeWalkLayout, kind: str, what: str, cam: str | None = None) -> DataError:
    who = f" for camera {cam}" if cam is not None else ""
    return DataError(f"Lee walk release {root}: no {what}{who}; expected one of: {layout.expected(root, kind, cam)} "
                     "(the release's own file names are not publicly documented -- if yours differ, pass "
                     "swarmpose.datasets.leewalk.LeeWalkLayout(...) with your patterns to open_leewalk; see "
                     "docs/datasets.md)")


def read_number_table(path: str | os.PathLike[str], columns: int, what: str,
                      names: Sequence[str] | None = None) -> np.ndarray:
    """Read a whitespace-separated table with ``columns`` numbers per non-empty line (``#`` comments).

    Raises
    ------
    DataError, FormatError
        Missing file; a line with the wrong count or a non-numeric value (named by line and column).
    """
    p, text = _read_text(path, what)
    rows = []
    for lineno, raw in enumerate(text.split("\n"), 1):
        line = raw.split("#", 1)[0]
        toks = line.split()
        if not toks:
            continue
        if len(toks) != columns:
            raise FormatError(f"{len(toks)} values, expected {columns} per line", path=p, line=lineno)
        rows.append([_number(t, p, lineno, names[j] if names else f"column {j + 1}") for j, t in enumerate(toks)])
    if not rows:
        raise FormatError(f"no data lines (expected {columns} numbers per line)", path=p)
    return np.array(rows, dtype=np.float64)


class _MaskFolder:
    """Numbered mask images (non-zero = foreground) read as (H, W) uint8 in {0, 1}."""

    def __init__(self, folder: Path):
        self.src = VideoSource(folder)
        self.n_frames, self.size, self.path = self.src.n_frames, self.src.size, folder

    def read(self, i: int) -> np.ndarray:
        rgb = self.src.read(i)
        return (rgb.max(axis=2) > 0).astype(np.uint8)

    def close(self) -> None:
        self.src.close()


class _LeeWalkFrames:
    """FrameReader over the Lee walk folders (grey images and/or precomputed silhouettes)."""

    def __init__(self, images: list[VideoSource] | None, silhouettes: list[_MaskFolder] | None, first: int):
        self.images, self.sils, self.first = images, silhouettes, first
        self.streams = tuple(s for s, v in (("image", images), ("silhouette", silhouettes)) if v is not None)

    def read(self, stream: str, k: int) -> np.ndarray:
        i = self.first + int(k)
        if stream == "image" and self.images is not None:
            return np.stack([cv2.cvtColor(s.read(i), cv2.COLOR_RGB2GRAY) for s in self.images])
        if stream == "silhouette" and self.sils is not None:
            return np.stack([s.read(i) for s in self.sils])
        raise ConfigError(f"unknown stream {stream!r}; this reader has {self.streams}")

    def close(self) -> None:
        for group in (self.images or []), (self.sils or []):
            for s in group:
                s.close()


def _checked_joints(gt: np.ndarray, path: Path) -> np.ndarray:
    """Ground-truth joints as the tracker scores them: a joint at exactly (0, 0, 0), how motion capture
    writes a lost marker, becomes NaN, so its frame is not scored; and the thighs must be a person's in mm
    (a file in metres or centimetres would be scored silently wrong)."""
    gt = np.array(gt, dtype=np.float64)
    gt[(gt == 0.0).all(axis=-1)] = np.nan
    l_hip, l_knee, r_hip, r_knee = (JOINT_INDEX[n] for n in ("l_hip", "l_knee", "r_hip", "r_knee"))
    thigh = np.linalg.norm(gt[:, [l_knee, r_knee]] - gt[:, [l_hip, r_hip]], axis=-1)
    if np.isfinite(thigh).any():
        median = float(np.nanmedian(thigh))
        if not 250.0 <= median <= 700.0:
            raise FormatError(f"the median thigh (hip to knee) is {median:.4g}, expected 250-700 mm: the joints must "
                              "be in millimetres, 15 x (x, y, z) per line in HumanEva's order (docs/datasets.md)",
                              path=path)
    return gt


class LeeWalkRelease:
    """The Lee walk files found under ``root`` with ``layout``.

    Attributes
    ----------
    root : pathlib.Path
    layout : LeeWalkLayout
    cameras : list of Camera
        Named ``cam1``..``cam4``.
    n_frames : int
        Frames common to every camera and stream.
    gt_params : numpy.ndarray of shape (T, 31), or None
    gt_joints : numpy.ndarray of shape (T, 15, 3), or None
    files : dict
        The paths used.

    Raises
    ------
    DataError
        A required file is missing (the message lists the candidates), or counts disagree.
    FormatError
        A malformed file (named with its line or field).
    """

    def __init__(self, root: str | os.PathLike[str], layout: LeeWalkLayout | None = None):
        self.root = Path(root)
        self.layout = layout or LeeWalkLayout()
        if not self.root.is_dir():
            raise DataError(f"{self.root}: no such Lee walk folder")
        lay, root_ = self.layout, self.root
        self.files: dict[str, Any] = {"calibration": {}, "images": {}, "silhouettes": {}, "backgrounds": {}}
        for cam in lay.cameras:
            cal = lay.find(root_, "calibration", cam)
            if cal is None:
                raise _missing(root_, lay, "calibration", "calibration file", cam)
            self.files["calibration"][cam] = cal
            img = lay.find(root_, "images", cam)
            sil = lay.find(root_, "silhouettes", cam)
            if img is None and sil is None:
                raise DataError(f"Lee walk release {root_}: no images and no background-subtracted images for camera "
                                f"{cam}; expected one of: {lay.expected(root_, 'images', cam)}; or: "
                                f"{lay.expected(root_, 'silhouettes', cam)} (adapt LeeWalkLayout if your copy "
                                "differs; see docs/datasets.md)")
            self.files["images"][cam] = img
            self.files["silhouettes"][cam] = sil
            self.files["backgrounds"][cam] = lay.find(root_, "backgrounds", cam)
        for kind in ("images", "silhouettes"):
            got = [c for c, p in self.files[kind].items() if p is not None]
            if got and len(got) != len(lay.cameras):
                lacking = [c for c in lay.cameras if c not in got]
                raise _missing(root_, lay, kind, kind, lacking[0])
        self.files["gt_params"] = lay.find(root_, "gt_params")
        self.files["gt_joints"] = lay.find(root_, "gt_joints")
        self.gt_params = None
        if self.files["gt_params"] is not None:
            self.gt_params = read_number_table(self.files["gt_params"], N_PARAMS, "ground-truth parameter file",
                                               [f"x{j + 1}" for j in range(N_PARAMS)])
        self.gt_joints = None
        if self.files["gt_joints"] is not None:
            names = [f"{j}.{a}" for j in range(15) for a in "xyz"]
            table = read_number_table(self.files["gt_joints"], 45, "ground-truth joint file", names)
            self.gt_joints = _checked_joints(table.reshape(-1, 15, 3), self.files["gt_joints"])
        self._calib = {cam: parse_calibration(p) for cam, p in self.files["calibration"].items()}
        self._counts: dict[str, int] = {}
        self._size: tuple[int, int] | None = None
        probe: list[Any] = []
        try:
            for kind, opener in (("images", VideoSource), ("silhouettes", _MaskFolder)):
                for cam, p in self.files[kind].items():
                    if p is None:
                        continue
                    src = opener(p)
                    probe.append(src)
                    self._counts[f"{kind}:{cam}"] = src.n_frames
                    if self._size is None:
                        self._size = src.size
                    elif src.size != self._size:
                        raise ShapeError(f"{p}: frames are {src.size[0]}x{src.size[1]}, other Lee walk views "
                                         f"{self._size[0]}x{self._size[1]}")
        finally:
            for s in probe:
                s.close()
        assert self._size is not None
        self.n_frames = min(self._counts.values())
        for what, arr in (("gt_params", self.gt_params), ("gt_joints", self.gt_joints)):
            if arr is not None and len(arr) < self.n_frames:
                raise FormatError(f"{len(arr)} frames of ground truth, the images have {self.n_frames}",
                                  path=self.files[what])
        self.cameras: list[Camera] = [self._calib[c].camera(f"cam{c}", *self._size) for c in self.layout.cameras]

    @property
    def size(self) -> tuple[int, int]:
        """Image ``(width, height)``."""
        assert self._size is not None
        return self._size

    def frame_counts(self) -> dict[str, int]:
        """Frames found per ``stream:camera``."""
        return dict(self._counts)

    def sequence(self, frames: tuple[int, int] | None = None) -> MultiViewSequence:
        """The release as a lazily read :class:`~swarmpose.io.sequence.MultiViewSequence`.

        Parameters
        ----------
        frames : (int, int), optional
            1-based inclusive frame range (e.g. ``(1, 450)``, the thesis's evaluation span).
        """
        first, last = (1, self.n_frames) if frames is None else (int(frames[0]), int(frames[1]))
        if not 1 <= first <= last <= self.n_frames:
            raise ConfigError(f"frames must satisfy 1 <= first <= last <= {self.n_frames}, got {first}-{last}")
        cams = self.layout.cameras
        images = sils = None
        try:
            if all(self.files["images"][c] is not None for c in cams):
                images = [VideoSource(self.files["images"][c]) for c in cams]
            if all(self.files["silhouettes"][c] is not None for c in cams):
                sils = [_MaskFolder(self.files["silhouettes"][c]) for c in cams]
            backgrounds = None
            if all(self.files["backgrounds"][c] is not None for c in cams):
                bg = []
                for c in cams:
                    p = self.files["backgrounds"][c]
                    img = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
                    if img is None:
                        raise FormatError("cannot decode the background image", path=p)
                    if (img.shape[1], img.shape[0]) != self.size:
                        raise FormatError(f"background is {img.shape[1]}x{img.shape[0]}, frames "
                                          f"{self.size[0]}x{self.size[1]}", path=p)
                    bg.append(img)
                backgrounds = np.stack(bg)
        except BaseException:
            for s in (images or []) + (sils or []):
                s.close()
            raise
        T = last - first + 1
        gt = None if self.gt_joints is None else self.gt_joints[first - 1:last]
        provenance = {"source": "leewalk", "root": str(self.root), "frames": [first, last],
                      "files": {k: ({c: (None if p is None else str(p)) for c, p in v.items()} if isinstance(v, dict)
                                    else (None if v is None else str(v))) for k, v in self.files.items()},
                      "gt_params": None if self.gt_params is None else self.gt_params[first - 1:last].tolist()}
        return MultiViewSequence(cameras=self.cameras, frame_rate=self.layout.frame_rate, n_frames=T,
                                 reader=_LeeWalkFrames(images, sils, first - 1), backgrounds=backgrounds,
                                 gt_joints=gt, provenance=provenance, path=self.root)


def open_leewalk(root: str | os.PathLike[str], layout: LeeWalkLayout | None = None) -> LeeWalkRelease:
    """Find and validate the Lee walk files under ``root``; see :class:`LeeWalkRelease`."""
    return LeeWalkRelease(root, layout)


def leewalk_sequence(spec: str | os.PathLike[str], layout: LeeWalkLayout | None = None) -> MultiViewSequence:
    """Open ``leewalk:<folder>[?frames=1-450]`` as a :class:`~swarmpose.io.sequence.MultiViewSequence`."""
    s = os.fspath(spec)
    if s.startswith("leewalk:"):
        s = s[len("leewalk:"):]
    path_part, _, query = s.partition("?")
    frames = None
    for k, v in parse_qsl(query, keep_blank_values=True):
        if k != "frames":
            raise ConfigError(f"unknown leewalk option {k!r}; known: frames")
        m = re.fullmatch(r"\s*(\d+)\s*[-:]\s*(\d+)\s*", v)
        if not m:
            raise ConfigError(f"frames must look like 1-450, got {v!r}")
        frames = (int(m.group(1)), int(m.group(2)))
    return open_leewalk(path_part, layout).sequence(frames)
