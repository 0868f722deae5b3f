"""Which calibrated camera each video shows, how its frames fit the calibration, and which frames to take.

* :func:`match_cameras`: a video or image folder is matched to the calibration's camera of the same name
  (``cam01.mp4`` ↔ ``cam01``), else to the camera whose name holds the video's name as a word
  (``int_cam01_img``), else to the one camera with the same number (``cam1`` ↔ ``camera_01``). A calibration
  may hold more cameras than there are videos.
* :func:`fit_camera`: a video whose frames are the calibration's size keeps the camera; one at another
  scale of the same aspect gets the camera scaled to it; one a few pixels narrower or shorter (a codec
  that crops to a multiple of 8 or 16) is padded on the right and bottom to the calibration's size, which
  keeps every pixel where the calibration puts it. Any other size is an error.
* :func:`frame_plan`: the video frame of every camera for every imported frame, from a range, a step and
  per-camera offsets (camera ``c`` shows reference frame ``k`` in its own frame ``k + offset_c``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, DataError, FormatError

__all__ = ["match_cameras", "fit_camera", "frame_plan", "MAX_PAD_PX", "pad_to"]

#: The most a frame may be narrower or shorter than its calibration and still be padded (codec crops).
MAX_PAD_PX = 16


def _words(name: str) -> list[str]:
    return [w for w in re.split(r"[^0-9a-z]+", name.lower()) if w]


def _number(name: str) -> int | None:
    nums = re.findall(r"\d+", name)
    return int(nums[-1]) if len(nums) == 1 or (nums and len(set(map(int, nums))) == 1) else None


def match_cameras(camera_names: Sequence[str], source_names: Sequence[str], *, calibration: str | Path = "",
                  sources: Sequence[str | Path] = ()) -> list[int]:
    """Index into ``camera_names`` of each source (by exact name, then word, then number).

    Raises
    ------
    DataError
        A source matches no camera or several, or two sources match one camera; the message names the
        video and lists the calibration's cameras.
    """
    cams = list(camera_names)
    lower = [c.lower() for c in cams]
    out: list[int] = []
    for s, name in enumerate(source_names):
        label = str(sources[s]) if s < len(sources) else name
        key = name.lower()
        hits = [i for i, c in enumerate(lower) if c == key]
        if not hits:
            hits = [i for i, c in enumerate(lower) if key in _words(c) or key == "".join(_words(c))]
        if not hits:
            n = _number(name)
            hits = [] if n is None else [i for i, c in enumerate(cams) if _number(c) == n]
        where = f" in {calibration}" if calibration else ""
        if not hits:
            raise DataError(f"{label}: no camera named like {name!r}{where} (its cameras: {', '.join(cams)}); "
                            "rename the video after its camera")
        if len(hits) > 1:
            raise DataError(f"{label}: {name!r} matches several cameras{where}: "
                            f"{', '.join(cams[i] for i in hits)}; rename the video after one of them")
        if hits[0] in out:
            other = source_names[out.index(hits[0])]
            raise DataError(f"{label}: camera {cams[hits[0]]!r}{where} is matched by {other!r} already")
        out.append(hits[0])
    return out


def fit_camera(camera: Camera, size: tuple[int, int], *, source: str | Path = "",
               calibration: str | Path = "") -> tuple[Camera, str | None]:
    """The camera for frames of ``size`` = (width, height), and a note saying what was adapted (or None).

    Raises
    ------
    FormatError
        The size differs from the calibration's by more than a scale or a small codec crop.
    """
    w, h = int(size[0]), int(size[1])
    cw, ch = camera.width, camera.height
    if (w, h) == (cw, ch):
        return camera, None
    f = w / cw
    if abs(h - ch * f) <= 0.5 + 1e-9 and abs(w - math.floor(cw * f + 0.5)) == 0 and \
            math.floor(ch * f + 0.5) == h:
        scaled = camera.scaled(f)
        return scaled, (f"{source}: {w}x{h}, the calibration says {cw}x{ch}: the same view at {f:g} times the "
                        "size, so the camera was scaled to it")
    if 0 <= cw - w <= MAX_PAD_PX and 0 <= ch - h <= MAX_PAD_PX:
        return camera, (f"{source}: {w}x{h}, the calibration says {cw}x{ch}: frames padded by {cw - w} px on the "
                        f"right and {ch - h} px at the bottom (a codec's crop; pixel positions unchanged)")
    raise FormatError(f"frames are {w}x{h} but camera {camera.name!r} in {calibration} is {cw}x{ch}: not the same "
                      f"view at another scale, nor a crop of at most {MAX_PAD_PX} px; check that the video and the "
                      "calibration belong together", path=source)


def pad_to(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``image`` (H, W[, 3]) padded with zeros on the right and bottom to ``size`` = (width, height)."""
    w, h = size
    if image.shape[1] == w and image.shape[0] == h:
        return image
    out = np.zeros((h, w) + image.shape[2:], dtype=image.dtype)
    out[:image.shape[0], :image.shape[1]] = image
    return out


def with_size(camera: Camera, size: tuple[int, int]) -> Camera:
    """The same camera with a larger image (padding on the right and bottom moves no pixel)."""
    return dataclasses.replace(camera, width=int(size[0]), height=int(size[1]))


def frame_plan(n_frames: Sequence[int], offsets: Sequence[int], *, start: int = 0, stop: int | None = None,
               step: int = 1, common_range: bool = False, names: Sequence[str] = ()) -> tuple[np.ndarray, list[str]]:
    """Video frame of each camera for each imported frame, shape (T, C), and notes.

    Parameters
    ----------
    n_frames : sequence of C int
        Frames of each camera's video.
    offsets : sequence of C int
        Camera ``c`` shows reference frame ``k`` in its frame ``k + offsets[c]``.
    start, stop, step : int
        Reference frames ``start, start + step, ... < stop`` (stop None: as far as every camera has frames).
    common_range : bool
        Allow videos of different lengths (the frames all cameras have); without it, different lengths
        are an error that says by how much.
    names : sequence of str
        The videos' names, for the messages.
    """
    n = np.asarray(n_frames, dtype=np.int64)
    o = np.asarray(offsets, dtype=np.int64)
    labels = list(names) or [f"camera {c}" for c in range(len(n))]
    if step < 1:
        raise ConfigError(f"--step must be at least 1, got {step}")
    if start < 0:
        raise ConfigError(f"--start must be >= 0, got {start}")
    notes = []
    if len(set(n.tolist())) > 1 and not common_range:
        longest = int(np.argmax(n))
        diffs = "; ".join(f"{labels[c]} has {int(n[c])} ({int(n[longest] - n[c])} fewer than {labels[longest]})"
                          for c in range(len(n)) if n[c] != n[longest])
        raise DataError(f"the videos have different frame counts: {diffs}. Pass --common-range to import the frames "
                        "every camera has, or trim the videos")
    lo, hi = int(np.max(-o, initial=0)), int(np.min(n - o))
    if hi <= lo:
        raise ConfigError(f"with offsets {o.tolist()} the videos share no frame")
    first = max(start, lo)
    last = hi if stop is None else min(stop, hi)
    if first != start:
        notes.append(f"frames start at {first}, not {start}: with offsets {o.tolist()} earlier frames are missing in "
                     "some camera")
    if stop is not None and last != stop:
        notes.append(f"frames stop at {last}, not {stop}: the shortest video ends there")
    if last <= first:
        raise ConfigError(f"no frame in the range {start}..{stop} (the cameras share frames {lo}..{hi - 1})")
    k = np.arange(first, last, step, dtype=np.int64)
    return k[:, None] + o[None, :], notes
