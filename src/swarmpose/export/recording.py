"""A sequence out as a recording: one video (or image folder) per camera plus a calibration file.

What :func:`swarmpose.datasets.recording.import_recording` reads back: the round trip checks the import
(same cameras, same images within the codec's tolerance), and a synthesised clip becomes test material
for other tools (Pose2Sim, EasyMocap, aniposelib read the calibration formats written here).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np

from swarmpose.errors import ConfigError, DataError
from swarmpose.io.calibration import WRITABLE, write_calibration
from swarmpose.io.sequence import MultiViewSequence

__all__ = ["export_recording", "CALIBRATION_FILES"]

#: The calibration file each writable format is written to.
CALIBRATION_FILES = {"toml": "calibration.toml", "opencv": "calibration.yml", "easymocap": "intri.yml"}


def export_recording(seq: MultiViewSequence, out: str | os.PathLike[str], *, calibration_format: str = "toml",
                     video: bool = True, frames: np.ndarray | None = None) -> dict[str, object]:
    """Write ``out/<camera>.mp4`` (or ``out/<camera>/000000.png ...`` with ``video=False``) and a calibration.

    Parameters
    ----------
    seq : MultiViewSequence
        A sequence with images.
    out : path
        A folder that must not exist yet (written under a temporary name, then moved into place).
    calibration_format : {"toml", "opencv", "easymocap"}
    video : bool
        MP4 (MPEG-4 Part 2 through OpenCV: lossy) or lossless PNG folders.
    frames : array of int, optional
        Which frames (default all).

    Returns
    -------
    dict
        ``{"sources": [paths], "calibration": path, "frames": n}``.
    """
    if calibration_format not in WRITABLE:
        raise ConfigError(f"calibration format {calibration_format!r}: expected one of {', '.join(WRITABLE)}")
    if "image" not in seq.streams:
        raise DataError(f"{seq.path or 'the sequence'}: has no images to export")
    out = Path(out)
    if out.exists():
        raise DataError(f"{out}: exists; export into a new folder")
    idx = np.arange(seq.n_frames) if frames is None else np.asarray(frames, dtype=np.int64)
    tmp = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    try:
        W, H = seq.image_size
        sources = []
        writers = []
        for cam in seq.cameras:
            if video:
                p = tmp / f"{cam.name}.mp4"
                w = cv2.VideoWriter(str(p), cv2.VideoWriter_fourcc(*"mp4v"), float(seq.frame_rate), (W, H), True)
                if not w.isOpened():
                    raise DataError(f"{p}: OpenCV cannot write MP4 video here; export with video=False")
                writers.append(w)
            else:
                p = tmp / cam.name
                p.mkdir()
            sources.append(out / p.name)
        for j, k in enumerate(idx):
            images = seq.images(int(k))
            for c, cam in enumerate(seq.cameras):
                bgr = cv2.cvtColor(images[c], cv2.COLOR_GRAY2BGR)
                if video:
                    writers[c].write(bgr)
                else:
                    cv2.imwrite(str(tmp / cam.name / f"{j:06d}.png"), images[c])
        for w in writers:
            w.release()
        calib = tmp / CALIBRATION_FILES[calibration_format]
        write_calibration(calib, list(seq.cameras), calibration_format)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"sources": [str(s) for s in sources], "calibration": str(out / calib.name), "frames": int(len(idx))}
