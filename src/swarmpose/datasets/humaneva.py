"""HumanEva-I and HumanEva-II as distributed: calibration, sync offsets, mocap ground truth, video, backgrounds.

Everything here follows ``shared/reference/humaneva-facts.md`` (sections 1-6), which paraphrases the
HumanEva support code v1.1 (Sigal, Brown 2006-2007). MATLAB indices in that code are 1-based; the
synchronized frame numbers ``F`` used below (and in the official partitions) are 1-based too.

Layout (paths relative to the release root; ``<CAM>`` is ``C1..C3``/``BW1..BW4`` for HumanEva-I,
``C1..C4`` for HumanEva-II)::

    <S>/Calibration_Data/<CAM>.cal              22 numbers: fc(2) cc(2) alpha_c kc(5) R(9, row-major) T(3, mm)
    <S>/Sync_Data/<Action>_<Trial>_(<CAM>).ofs   3 numbers: im_st mc_st mc_sc
    <S>/Image_Data/<Action>_<Trial>_(<CAM>).avi  video (or a folder <Action>_<Trial>_(<CAM>)/ of numbered images)
    <S>/Mocap_Data/<Action>_<Trial>.c3d          Vicon C3D (the support code caches it as .mat beside it)
    <S>/Mocap_Data/Static.c3d                    static trial (torso radius for the pose modifiers)
    <S>/Mocap_Data/<S>.mp                        Vicon subject measurements ("$Name = value" lines)
    Background/Background_*_(<CAM>).avi          HumanEva-I background footage (release root)
    <S>/Background/Background_*_(<CAM>)/         HumanEva-II background footage (image folders)

Public API
----------
Parsers (each raises :class:`~swarmpose.errors.DataError` for a missing/unreadable file and
:class:`~swarmpose.errors.FormatError` naming the file and the line or field for a malformed one):
:func:`parse_calibration` / :func:`read_calibration` (``.cal`` -> :class:`~swarmpose.camera.Camera`),
:func:`read_offsets` (``.ofs``), :func:`read_mp` (``.mp``), :func:`read_mocap` (``.mat`` cache or
``.c3d``), :func:`read_background_mat` (the support code's ``Background_(<CAM>).mat``).

Synchronisation: :func:`synchronize` (the ``sync_stream`` rule, facts section 2).
Ground truth: :func:`humaneva_ground_truth` (the ``cur_frame`` rule, facts section 4.2) and
:func:`joints15_from_points20`. Background model: :func:`humaneva_background_model`,
:func:`humaneva_silhouette` (facts section 6). Video: :class:`VideoSource` (OpenCV's
``cv2.VideoCapture``, with ``imageio`` as fallback; or a folder of numbered images).
Sequences: :class:`HumanEvaTrial`, :func:`open_humaneva`, :func:`humaneva_sequence` (a lazily read
:class:`~swarmpose.io.sequence.MultiViewSequence`), :func:`parse_humaneva_spec`.

Choices where the sources are ambiguous or where the support code would crash (each is tested):

* **Double joints.** ``JOINTS15`` ground truth stores one point per joint. For thorax, elbows and
  knees HumanEva's ``error.m`` averages the *distances* of two points (torsoProximal/headProximal,
  upperArmDistal/lowerArmProximal, upperLegDistal/lowerLegProximal); we store the *midpoint* of the
  two (as VideoPose3D does). The two points differ by a few mm at the elbows (arm pose modifier)
  and thorax, so errors against the midpoint differ from ``error.m`` by at most half that gap. The
  full 20 points are kept in :attr:`GroundTruth.points20` for an exact ``error.m`` evaluation.
* **Invalid frames.** A frame is valid when the 39 Plug-in-Gait markers are non-zero in both
  bracketing mocap frames (as ``cur_frame``). Stricter than the support code, a frame is also
  invalid when a virtual marker it uses is (0, 0, 0) or its segment axes are not orthogonal to 1e-4
  (the support code substitutes an identity frame or stops with an error). Invalid frames are NaN
  rows in the ground truth and are skipped by HumanEva's evaluation.
* **Segment axes** come from the labels following each ``...O`` label: +1 = z point, +2 = x point,
  +3 = y point (index offsets, as the support code). Orientations are interpolated by slerp,
  positions linearly, between mocap frames ``floor(p)`` and ``floor(p) + 1``; at an integer ``p``
  only frame ``p`` is used (the support code would index past the end at the last frame).
* **Marker labels** are found by substring match (MATLAB ``findstr``), first match; ``LABELS``,
  ``LABELS2``, ... are concatenated (C3D convention for more than 255 markers).
* **Torso radius** for the pelvis tilt is computed from ``Static`` markers (as the support code,
  whose loader overwrites ``Markers`` with the static trial's); without a static trial, from the
  trial itself (recorded in the provenance).
* **.cal rotation**: the files are written with 6 decimals, so ``R`` is orthonormal only to ~1e-6;
  it is projected onto the nearest rotation (SVD) when within 1e-3, rejected otherwise. Exactly 22
  numbers are required (a 25-number file is the PARSEC bodytrack variant).
* **Images** of the sequence are grey ``(C, H, W)`` uint8 (``cv2`` RGB->grey); the colour frames are
  available through :meth:`HumanEvaFrames.colour` and feed the ``silhouette`` stream, which applies
  HumanEva's per-pixel Gaussian background mixture on colour values scaled to [0, 1].
* **Default partition**: ``split="auto"`` picks the official Validate frames for trial 1, Test for
  trial 2, Train for trial 3 (and HumanEva-II's test ranges); ``split="all"`` is every synchronized
  frame from 6 on (HumanEva-I, skipping the XVID duplicates) or from 1 (HumanEva-II).
* **Background footage** is summarised from at most ``background_frames`` evenly spaced frames per
  recording session (default 100; ``None`` = every frame, as the support code) and cached as
  ``.npz`` under ``cache_dir`` (default ``cache/humaneva``, relative to the working directory).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

import cv2
import numpy as np

from swarmpose.body.measurements import SubjectMeasurements, limb_table
from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, DataError, FormatError, ShapeError
from swarmpose.io.sequence import MultiViewSequence

__all__ = [
    "VIDEO_RATE",
    "MOCAP_RATE",
    "HEAD_LENGTH_MM",
    "HUMANEVA_I_CAMERAS",
    "HUMANEVA_II_CAMERAS",
    "BODY_POSE20",
    "VALIDITY_MARKERS",
    "FRAME_RANGES",
    "CalibrationValues",
    "StreamOffset",
    "SyncInfo",
    "MocapMarkers",
    "GroundTruth",
    "BackgroundModel",
    "VideoSource",
    "HumanEvaFrames",
    "HumanEvaTrial",
    "HumanEvaSpec",
    "parse_calibration",
    "read_calibration",
    "read_offsets",
    "read_mp",
    "mp_value",
    "read_mocap",
    "read_mocap_mat",
    "read_c3d",
    "synchronize",
    "matlab_round",
    "limb_lengths",
    "limb_parameters",
    "subject_measurements",
    "humaneva_ground_truth",
    "joints15_from_points20",
    "humaneva_background_model",
    "humaneva_silhouette",
    "read_background_mat",
    "load_background_model",
    "open_humaneva",
    "parse_humaneva_spec",
    "humaneva_sequence",
    "humaneva_frame_range",
    "detect_dataset",
    "trial_files",
]

VIDEO_RATE = 60.0
MOCAP_RATE = 120.0
#: First usable synchronized frame of HumanEva-I (XVID duplicates frames 1-5).
FIRST_FRAME_I = 6
HEAD_LENGTH_MM = 316.103
PELVIS_SHIFT_MM = -50.0
HUMANEVA_I_CAMERAS: tuple[str, ...] = ("C1", "C2", "C3", "BW1", "BW2", "BW3", "BW4")
HUMANEVA_II_CAMERAS: tuple[str, ...] = ("C1", "C2", "C3", "C4")
DATASET_CAMERAS = {"HumanEva-I": HUMANEVA_I_CAMERAS, "HumanEva-II": HUMANEVA_II_CAMERAS}
DEFAULT_CAMERAS = {"HumanEva-I": ("C1", "C2", "C3"), "HumanEva-II": HUMANEVA_II_CAMERAS}
#: Misclassification risk of the background model per camera (``BackgroundSubtraction.m`` defaults).
DEFAULT_RISK: dict[str, dict[str, float]] = {
    "HumanEva-I": dict.fromkeys(HUMANEVA_I_CAMERAS, 1.0),
    "HumanEva-II": {"C1": 1e80, "C2": 1e60, "C3": 1e30, "C4": 1e80},
}

CAL_FIELDS: tuple[str, ...] = (
    "fc[0]", "fc[1]", "cc[0]", "cc[1]", "alpha_c", "kc[0]", "kc[1]", "kc[2]", "kc[3]", "kc[4]",
    *(f"R[{i},{j}]" for i in range(3) for j in range(3)), "T[0]", "T[1]", "T[2]",
)
OFS_FIELDS: tuple[str, ...] = ("im_st", "mc_st", "mc_sc")
MP_NAMES: tuple[str, ...] = ("LKneeWidth", "RKneeWidth", "LAnkleWidth", "RAnkleWidth", "LElbowWidth",
                             "RElbowWidth", "LWristWidth", "RWristWidth", "LShoulderOffset", "RShoulderOffset",
                             "HeadOffset")

#: The 39 Plug-in-Gait markers that must be present for a valid frame (alternatives in a tuple).
VALIDITY_MARKERS: tuple[tuple[str, ...], ...] = tuple(
    (m,) if isinstance(m, str) else m for m in (
        "RASI", "LASI", "LPSI", "RELB", "STRN", "LTHI", "LWRA", "LELB", "T10", "RWRA", "RUPA", "RKNE",
        "RBAK", "LKNE", "CLAV", "RSHO", "LSHO", "C7", "RTIB", "LTIB", "LBHD", "RBHD", "RFHD", "LFHD",
        "LANK", "LHEE", "RANK", "LTOE", "RTOE", "RHEE", "LFIN", ("RFRM", "RFRA"), ("LFRM", "LFRA"),
        "RWRB", "RFIN", "LWRB", "RTHI", "LUPA", "RPSI"))

#: Virtual-marker groups whose ``...O`` label is followed by the z, x and y axis points.
SEGMENT_GROUPS: tuple[str, ...] = ("PELO", "TRXO", "HEDO", "LFEO", "LTIO", "RFEO", "RTIO", "LHUO", "LRAO",
                                   "RHUO", "RRAO")
#: Joint-centre labels used as positions.
JOINT_LABELS: tuple[str, ...] = ("PELO", "TRXO", "LFEP", "RFEP", "LFEO", "RFEO", "LTIO", "RTIO", "LCLO", "RCLO",
                                 "LHUO", "RHUO", "LRAO", "RRAO")

#: The 20 points of HumanEva's ``body_pose`` in the order used by :attr:`GroundTruth.points20`.
BODY_POSE20: tuple[str, ...] = (
    "torsoProximal", "torsoDistal",
    "upperLArmProximal", "upperLArmDistal", "lowerLArmProximal", "lowerLArmDistal",
    "upperRArmProximal", "upperRArmDistal", "lowerRArmProximal", "lowerRArmDistal",
    "upperLLegProximal", "upperLLegDistal", "lowerLLegProximal", "lowerLLegDistal",
    "upperRLegProximal", "upperRLegDistal", "lowerRLegProximal", "lowerRLegDistal",
    "headProximal", "headDistal",
)
_P20 = {n: i for i, n in enumerate(BODY_POSE20)}
#: JOINTS15 order -> the one or two body_pose points it is made of (midpoint of two).
JOINTS15_FROM_20: tuple[tuple[str, ...], ...] = (
    ("torsoProximal", "headProximal"), ("torsoDistal",),
    ("upperLArmProximal",), ("upperLArmDistal", "lowerLArmProximal"), ("lowerLArmDistal",),
    ("upperRArmProximal",), ("upperRArmDistal", "lowerRArmProximal"), ("lowerRArmDistal",),
    ("upperLLegProximal",), ("upperLLegDistal", "lowerLLegProximal"), ("lowerLLegDistal",),
    ("upperRLegProximal",), ("upperRLegDistal", "lowerRLegProximal"), ("lowerRLegDistal",),
    ("headDistal",),
)


def _ranges() -> dict[tuple[str, str, str], dict[int, dict[str, tuple[int, int]]]]:
    he1 = {
        "S1": {"Walking": ((6, 590), (591, 1203), (6, 1004), (1, 3238)), "Jog": ((6, 367), (368, 740), (6, 874), (1, 3175)),
               "ThrowCatch": ((6, 473), (474, 945), (6, 951), (1, 3453)),
               "Gestures": ((6, 395), (396, 801), (6, 1070), (1, 2127)), "Box": ((6, 385), (386, 789), (6, 606), (1, 1653)),
               "Combo": (None, None, (6, 2602), None)},
        "S2": {"Walking": ((6, 438), (439, 876), (6, 1093), (1, 1523)), "Jog": ((6, 398), (399, 795), (6, 727), (1, 1573)),
               "ThrowCatch": ((6, 550), (551, 1128), (6, 1399), (1, 3340)),
               "Gestures": ((6, 500), (501, 901), (6, 1062), (1, 3551)), "Box": ((6, 382), (383, 734), (6, 989), (1, 3108)),
               "Combo": (None, None, (6, 2054), None)},
        "S3": {"Walking": ((6, 448), (449, 939), (6, 805), (1, 2358)), "Jog": ((6, 401), (402, 842), (6, 864), (1, 1973)),
               "ThrowCatch": ((6, 493), (494, 1027), (6, 1000), (1, 2074)),
               "Gestures": ((6, 533), (534, 1102), (6, 553), (1, 1789)), "Box": ((6, 512), (513, 1021), (6, 753), (1, 1573)),
               "Combo": (None, None, (6, 1798), None)},
        "S4": {a: (None, None, r, None) for a, r in (("Walking", (6, 667)), ("Jog", (6, 590)), ("ThrowCatch", (6, 773)),
                                                       ("Gestures", (6, 459)), ("Box", (6, 574)), ("Combo", (6, 1102)))},
    }
    out: dict[tuple[str, str, str], dict[int, dict[str, tuple[int, int]]]] = {}
    for s, actions in he1.items():
        for a, (val, train, test, train3) in actions.items():
            d: dict[int, dict[str, tuple[int, int]]] = {}
            if val is not None:
                d[1] = {"validate": val, "train": train}
            d[2] = {"test": test}
            if train3 is not None:
                d[3] = {"train": train3}
            out[("HumanEva-I", s, a)] = d
    out[("HumanEva-II", "S2", "Combo")] = {1: {"test": (1, 1202)}}
    out[("HumanEva-II", "S4", "Combo")] = {4: {"test": (2, 1258)}}
    return out


#: Official partitions, synchronized frames (1-based, inclusive):
#: ``FRAME_RANGES[(dataset, subject, action)][trial][split] = (first, last)``.
FRAME_RANGES = _ranges()

#: 1-based video frame of C1, C2, C3 at synchronized frame 1, trial 1, *after* the critical OFS
#: update (hard-coded by VideoPose3D); used by ``datasets check`` as a sanity note.
OFS_UPDATE_SANITY: dict[tuple[str, str], tuple[int, int, int]] = {
    ("S1", "Walking"): (82, 81, 82), ("S1", "Jog"): (51, 51, 50), ("S1", "ThrowCatch"): (61, 61, 60),
    ("S1", "Gestures"): (45, 45, 44), ("S1", "Box"): (57, 57, 56),
    ("S2", "Walking"): (115, 115, 114), ("S2", "Jog"): (100, 100, 99), ("S2", "ThrowCatch"): (127, 127, 127),
    ("S2", "Gestures"): (122, 122, 121), ("S2", "Box"): (119, 119, 117),
    ("S3", "Walking"): (80, 80, 80), ("S3", "Jog"): (65, 65, 65), ("S3", "ThrowCatch"): (79, 79, 79),
    ("S3", "Gestures"): (83, 83, 82), ("S3", "Box"): (1, 1, 1),
}

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\Z")
IMAGE_EXTENSIONS = (".bmp", ".png", ".tif", ".tiff", ".pgm", ".ppm", ".jpg", ".jpeg")


# ---------------------------------------------------------------------- text parsing helpers
def _read_text(path: str | os.PathLike[str], what: str) -> tuple[Path, str]:
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: missing {what}")
    if not p.is_file():
        raise DataError(f"{p}: not a file ({what} expected)")
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise DataError(f"{p}: cannot read {what}: {exc}") from exc
    return p, data.decode("latin-1")  # never fails; non-numeric bytes are reported as bad tokens


def _tokens(text: str) -> list[tuple[int, str]]:
    out = []
    for lineno, line in enumerate(text.split("\n"), 1):
        out.extend((lineno, tok) for tok in line.split())
    return out


def _number(tok: str, path: Path, line: int, fld: str) -> float:
    if not _NUMBER.match(tok):
        shown = tok if len(tok) <= 40 else tok[:37] + "..."
        raise FormatError(f"not a number: {shown!r} (expected {fld})", path=path, line=line, field=fld)
    v = float(tok)
    if not math.isfinite(v):
        raise FormatError(f"{fld} is out of range: {tok!r}", path=path, line=line, field=fld)
    return v


def _fixed_numbers(path: Path, text: str, fields: Sequence[str], kind: str, extra_hint: str = "") -> list[float]:
    toks = _tokens(text)
    n = len(fields)
    if len(toks) > n:
        line, tok = toks[n]
        hint = extra_hint if extra_hint and len(toks) == 25 else ""
        raise FormatError(f"{len(toks)} values, a {kind} file holds exactly {n} ({', '.join(fields)}); first extra "
                          f"value {tok[:40]!r}{hint}", path=path, line=line)
    values = [_number(tok, path, line, fields[i]) for i, (line, tok) in enumerate(toks)]
    if len(values) < n:
        last_line = toks[-1][0] if toks else 1
        raise FormatError(f"truncated: {len(values)} of {n} numbers; {fields[len(values)]} and later are missing",
                          path=path, line=last_line, field=fields[len(values)])
    return values


# ---------------------------------------------------------------------- calibration (.cal)
@dataclass(frozen=True, eq=False)
class CalibrationValues:
    """The 22 numbers of a HumanEva ``.cal`` file (Bouguet's toolbox conventions).

    Attributes
    ----------
    fc : tuple of 2 float
        Focal lengths (pixels).
    cc : tuple of 2 float
        Principal point (pixels, (0, 0) = centre of the top-left pixel).
    alpha_c : float
        Skew coefficient.
    kc : tuple of 5 float
        Distortion ``(k1, k2, p1, p2, k3)``.
    R : numpy.ndarray, shape (3, 3)
        ``cam_from_world`` rotation (orthonormalised).
    T : numpy.ndarray, shape (3,)
        ``cam_from_world`` translation, mm.
    path : pathlib.Path or None
    rotation_residual : float
        ``max |R R^T - I|`` of the rotation as stored (before orthonormalisation).
    """

    fc: tuple[float, float]
    cc: tuple[float, float]
    alpha_c: float
    kc: tuple[float, float, float, float, float]
    R: np.ndarray
    T: np.ndarray
    path: Path | None = None
    rotation_residual: float = 0.0

    def camera(self, name: str, width: int, height: int) -> Camera:
        """A :class:`~swarmpose.camera.Camera` with these values and the given image size."""
        try:
            return Camera(name=name, width=width, height=height, fx=self.fc[0], fy=self.fc[1], cx=self.cc[0],
                          cy=self.cc[1], skew=self.alpha_c, dist=self.kc, R=self.R, t=self.T)
        except ConfigError as exc:
            raise FormatError(str(exc), path=self.path, field=getattr(exc, "field", None)) from None


def _nearest_rotation(R: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(R)
    return U @ Vt


def parse_calibration(path: str | os.PathLike[str]) -> CalibrationValues:
    """Read a HumanEva ``.cal`` file (``ReadSpicaCalib``): 22 whitespace-separated numbers.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    CalibrationValues

    Raises
    ------
    DataError
        Missing or unreadable file.
    FormatError
        Not exactly 22 numbers, a non-numeric or non-finite value (named by line and field, e.g.
        ``'kc[1]'``), focal lengths <= 0, or a rotation that is not orthonormal to 1e-3 with det +1.
    """
    p, text = _read_text(path, "calibration file (.cal)")
    v = _fixed_numbers(p, text, CAL_FIELDS, "HumanEva .cal",
                       extra_hint=" (25 numbers look like the PARSEC bodytrack variant with a trailing Rodrigues "
                                  "vector; HumanEva's own files hold 22)")
    fc = (v[0], v[1])
    for i in range(2):
        if fc[i] <= 0:
            raise FormatError(f"focal length {CAL_FIELDS[i]} must be > 0, got {fc[i]!r}", path=p, field=CAL_FIELDS[i])
    R = np.array(v[10:19], dtype=np.float64).reshape(3, 3)  # row-major (r11 r12 r13 r21 ...)
    residual = float(np.abs(R @ R.T - np.eye(3)).max())
    if residual > 1e-3:
        raise FormatError(f"R is not a rotation (max |R R^T - I| = {residual:.3g} > 1e-3)", path=p, field="R")
    if np.linalg.det(R) <= 0:
        raise FormatError("R has a negative determinant (a reflection, not a rotation)", path=p, field="R")
    return CalibrationValues(fc=fc, cc=(v[2], v[3]), alpha_c=v[4], kc=(v[5], v[6], v[7], v[8], v[9]),
                             R=_nearest_rotation(R), T=np.array(v[19:22], dtype=np.float64), path=p,
                             rotation_residual=residual)


def read_calibration(path: str | os.PathLike[str], *, width: int, height: int, name: str | None = None) -> Camera:
    """Read a HumanEva ``.cal`` file into a :class:`~swarmpose.camera.Camera`.

    The file holds no image size, so it is given (the loaders take it from the video). Units: world
    mm (Vicon frame, z up), ``x_cam = R x_world + T``, Bouguet distortion and pixel convention --
    the same as :class:`~swarmpose.camera.Camera`, so the values are used unchanged.

    Parameters
    ----------
    path : path-like
    width, height : int
        Image size in pixels.
    name : str, optional
        Camera name; default the file stem (``C1``, ``BW2``, ...).

    Returns
    -------
    Camera

    Raises
    ------
    DataError, FormatError
        See :func:`parse_calibration`.
    """
    values = parse_calibration(path)
    return values.camera(name or Path(path).stem, width, height)


# ---------------------------------------------------------------------- sync offsets (.ofs)
@dataclass(frozen=True)
class StreamOffset:
    """One ``.ofs`` file: ``mocap_index = mc_st + (image_index - im_st) * mc_sc`` (1-based)."""

    im_st: float
    mc_st: float
    mc_sc: float
    path: Path | None = None


def read_offsets(path: str | os.PathLike[str]) -> StreamOffset:
    """Read a HumanEva ``.ofs`` sync file: three numbers ``im_st mc_st mc_sc``.

    Raises
    ------
    DataError
        Missing or unreadable file.
    FormatError
        Not exactly 3 finite numbers, or ``mc_sc <= 0`` (the message names line and field).
    """
    p, text = _read_text(path, "sync file (.ofs)")
    im_st, mc_st, mc_sc = _fixed_numbers(p, text, OFS_FIELDS, "HumanEva .ofs")
    if mc_sc <= 0:
        raise FormatError(f"mc_sc (mocap frames per video frame) must be > 0, got {mc_sc!r}", path=p, field="mc_sc")
    return StreamOffset(im_st, mc_st, mc_sc, p)


def matlab_round(x: float) -> int:
    """MATLAB's ``round``: halves away from zero (``round(2.5) = 3``, ``round(-2.5) = -3``)."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


@dataclass(frozen=True)
class SyncInfo:
    """How synchronized frame ``F`` (1-based) maps to video and mocap (facts section 2).

    Attributes
    ----------
    mocap_start : float
        ``T0``: fractional 1-based mocap frame at ``F = 1``.
    mocap_scale : float
        ``s``: mean mocap frames per video frame over the cameras with an ``.ofs``.
    video_start : dict of str to int
        1-based video frame shown at ``F = 1``, per camera with an ``.ofs``.
    """

    mocap_start: float
    mocap_scale: float
    video_start: dict[str, int]

    def video_frame(self, camera: str, F: int | np.ndarray) -> Any:
        """1-based video frame of ``camera`` at synchronized frame ``F``: ``start + F - 1``."""
        return self.video_start[camera] + np.asarray(F) - 1

    def mocap_position(self, F: int | np.ndarray) -> Any:
        """Fractional 1-based mocap position at synchronized frame ``F``: ``T0 + (F - 1) s``."""
        return self.mocap_start + (np.asarray(F, dtype=np.float64) - 1.0) * self.mocap_scale

    def mocap_frames(self, n_mocap: int) -> int:
        """Number of synchronized frames with mocap, ``floor((n_mocap - T0) / s)`` (``n_frames.m``)."""
        return max(0, int(math.floor((n_mocap - self.mocap_start) / self.mocap_scale)))


def synchronize(offsets: Mapping[str, StreamOffset | None], order: Sequence[str] | None = None) -> SyncInfo:
    """Combine per-camera ``.ofs`` values into one synchronized frame index (``sync_stream``).

    Parameters
    ----------
    offsets : mapping of camera name to StreamOffset or None
        ``None`` for a camera whose ``.ofs`` is missing (it is skipped, as in the support code).
    order : sequence of str, optional
        Camera order; the first camera with an offset is the reference. Default: mapping order.
        Use every camera of the dataset (``HUMANEVA_I_CAMERAS``) to reproduce the official frame
        numbers, whichever views are loaded afterwards.

    Returns
    -------
    SyncInfo

    Raises
    ------
    DataError
        No camera has an offset.
    """
    names = list(order) if order is not None else list(offsets)
    starts: dict[str, float] = {}
    common_time = common_scale = 0.0
    n = 0
    for name in names:
        o = offsets.get(name)
        if o is None:
            continue
        if n == 0:
            common_time, common_scale = o.mc_st, o.mc_sc
            starts[name] = o.im_st
        else:
            starts[name] = o.im_st + (common_time - o.mc_st) / o.mc_sc
            common_scale += o.mc_sc
        n += 1
    if n == 0:
        raise DataError("no sync offsets (.ofs) for any camera: cannot synchronize video and mocap")
    s = common_scale / n
    first = min(starts.values())
    common_time -= s * (first - 1)
    starts = {k: v - first + 1 for k, v in starts.items()}
    if common_time < 1:
        starts = {k: v - (common_time - 1) / s for k, v in starts.items()}
        common_time = 1.0
    return SyncInfo(mocap_start=float(common_time), mocap_scale=float(s),
                    video_start={k: matlab_round(v) for k, v in starts.items()})


# ---------------------------------------------------------------------- subject file (.mp)
def read_mp(path: str | os.PathLike[str]) -> dict[str, float]:
    """Read a Vicon ``.mp`` subject file: lines ``$Name = value`` (blank lines allowed).

    Returns
    -------
    dict of str to float
        In file order.

    Raises
    ------
    DataError, FormatError
        Missing file; a line that is not ``[$]Name = number`` (named by line).
    """
    p, text = _read_text(path, "subject measurement file (.mp)")
    out: dict[str, float] = {}
    for lineno, raw in enumerate(text.split("\n"), 1):
        line = raw.strip()
        if not line:
            continue
        if "=" not in line:
            raise FormatError(f"expected '$Name = value', got {line[:40]!r}", path=p, line=lineno)
        name, _, value = line.partition("=")
        name = name.strip().lstrip("$").strip()
        if not name or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise FormatError(f"bad parameter name {name[:40]!r}", path=p, line=lineno)
        out[name] = _number(value.strip(), p, lineno, name)
    return out


def mp_value(mp: Mapping[str, float], name: str, path: object = None) -> float:
    """Value of the first ``.mp`` parameter whose name contains ``name`` (MATLAB ``readmp`` lookup)."""
    for k, v in mp.items():
        if name in k:
            return float(v)
    raise FormatError(f"missing parameter {name!r} (needed for the limb radii)", path=path, field=name)


# ---------------------------------------------------------------------- mocap (.mat / .c3d)
@dataclass(frozen=True, eq=False)
class MocapMarkers:
    """Marker trajectories of one C3D trial, as the support code sees them.

    Attributes
    ----------
    labels : tuple of str
        ``M`` marker labels (trailing blanks stripped).
    markers : numpy.ndarray, shape (T, M, 3)
        Positions in mm, frame-major; a lost marker is (0, 0, 0).
    frame_rate : float
        Mocap frames per second (120 for HumanEva).
    path : pathlib.Path or None
    """

    labels: tuple[str, ...]
    markers: np.ndarray
    frame_rate: float = MOCAP_RATE
    path: Path | None = None

    @property
    def n_frames(self) -> int:
        """``T``."""
        return int(self.markers.shape[0])

    def find(self, name: str) -> int | None:
        """0-based index of the first label containing ``name`` (MATLAB ``findstr``), or None."""
        for i, lab in enumerate(self.labels):
            if name in lab:
                return i
        return None

    def index(self, name: str) -> int:
        """Like :meth:`find`, raising :class:`FormatError` (naming the file) when absent."""
        i = self.find(name)
        if i is None:
            raise FormatError(f"no marker label contains {name!r}", path=self.path, field=name)
        return i

    def missing_labels(self) -> list[str]:
        """Labels the ground truth needs that this trial lacks (validity, virtual and joint markers)."""
        missing = [" or ".join(alt) for alt in VALIDITY_MARKERS if all(self.find(a) is None for a in alt)]
        missing += [n for n in (*SEGMENT_GROUPS, *JOINT_LABELS) if self.find(n) is None]
        for g in SEGMENT_GROUPS:
            i = self.find(g)
            if i is not None and i + 3 >= len(self.labels):
                missing.append(f"the 3 axis markers after {g}")
        return sorted(set(missing), key=missing.index)


def _mat_strings(obj: Any) -> list[str]:
    """Flatten a loadmat value (str, char/object arrays, nested cells) into a list of strings."""
    if isinstance(obj, str):
        return [obj]
    if isinstance(obj, bytes):
        return [obj.decode("latin-1")]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind == "U":
            return [str(x) for x in obj.ravel()]
        if obj.dtype == object:
            out: list[str] = []
            for x in obj.ravel():
                out.extend(_mat_strings(x))
            return out
    return []


def _mat_list(obj: Any) -> list[Any]:
    if isinstance(obj, np.ndarray) and obj.dtype == object:
        return list(obj.ravel())
    if obj is None or (isinstance(obj, np.ndarray) and obj.size == 0):
        return []
    return [obj]


def _point_labels(pg: Any, path: Path) -> list[str]:
    groups = _mat_list(pg)
    point = None
    for g in groups:
        name = "".join(_mat_strings(getattr(g, "name", None)))
        if "POINT" in name:
            point = g  # the support code keeps the last match
    if point is None:
        raise FormatError("ParameterGroup has no 'POINT' group (marker labels)", path=path, field="ParameterGroup")
    params = {}
    for prm in _mat_list(getattr(point, "Parameter", None)):
        pname = "".join(_mat_strings(getattr(prm, "name", None))).strip()
        if pname.startswith("LABELS"):
            params[pname] = prm
    if not params:
        raise FormatError("POINT group has no LABELS parameter", path=path, field="ParameterGroup.POINT.LABELS")

    def order(k: str) -> int:
        suffix = k[len("LABELS"):]
        return int(suffix) if suffix.isdigit() else (1 if suffix == "" else 10_000)

    labels: list[str] = []
    for k in sorted(params, key=order):
        labels.extend(s.strip() for s in _mat_strings(getattr(params[k], "data", None)))
    if not labels:
        raise FormatError("POINT:LABELS holds no strings", path=path, field="ParameterGroup.POINT.LABELS")
    return labels


def _markers_array(raw: Any, n_labels: int, path: Path) -> np.ndarray:
    try:
        m = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError("'Markers' must be a numeric array", path=path, field="Markers") from None
    if m.ndim == 2 and m.shape[1] == 3:  # a single marker squeezed away
        m = m[:, None, :]
    if m.ndim != 3 or m.shape[2] != 3:
        raise FormatError(f"'Markers' must have shape (frames, markers, 3), got {m.shape}", path=path, field="Markers")
    if m.shape[1] != n_labels and m.shape[0] == n_labels:
        m = m.transpose(1, 0, 2)  # markers x frames x 3, as the reader's comment claims
    if m.shape[0] < 1:
        raise FormatError("'Markers' has no frames", path=path, field="Markers")
    if not np.isfinite(m).all():
        raise FormatError("'Markers' holds non-finite values (lost markers must be 0, 0, 0)", path=path,
                          field="Markers")
    return np.ascontiguousarray(m)


def _fit_labels(labels: list[str], n: int) -> tuple[str, ...]:
    return tuple(labels[:n]) + ("",) * max(0, n - len(labels))


def _loadmat(p: Path, what: str, v73_hint: str = "") -> dict[str, Any]:
    """``scipy.io.loadmat`` (structs as objects, squeezed) with errors that name the file."""
    import io

    import scipy.io

    if not p.is_file():
        raise DataError(f"{p}: missing {what}")
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise DataError(f"{p}: cannot read {what}: {exc}") from exc
    try:
        return scipy.io.loadmat(io.BytesIO(raw), squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        raise FormatError(f"MATLAB v7.3 (HDF5) .mat files are not supported; re-save it with -v7{v73_hint}",
                          path=p) from None
    except Exception as exc:  # scipy raises many types on corrupt or truncated input; name the file
        raise FormatError(f"not a readable MATLAB .mat file ({type(exc).__name__}: {exc})", path=p) from None


def read_mocap_mat(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read the support code's ``.mat`` cache of a C3D trial (``scipy.io.loadmat``, no pickles).

    Needs ``Markers`` (frames x markers x 3, mm) and ``ParameterGroup`` with ``POINT``/``LABELS``;
    ``VideoFrameRate`` (the mocap rate) defaults to 120.

    Raises
    ------
    DataError
        Missing or unreadable file.
    FormatError
        Not a readable MATLAB v4-v7 file (v7.3/HDF5 is not supported), or missing/malformed fields.
    """

    p = Path(path)
    data = _loadmat(p, "mocap file (.mat)", " (or remove it so that the .c3d beside it is read)")
    for key in ("Markers", "ParameterGroup"):
        if key not in data:
            raise FormatError(f"missing variable {key!r}", path=p, field=key)
    labels = _point_labels(data["ParameterGroup"], p)
    markers = _markers_array(data["Markers"], len(labels), p)
    rate = MOCAP_RATE
    if "VideoFrameRate" in data:
        try:
            rate = float(np.asarray(data["VideoFrameRate"], dtype=np.float64).ravel()[0])
        except (TypeError, ValueError, IndexError):
            raise FormatError("'VideoFrameRate' must be a number", path=p, field="VideoFrameRate") from None
        if not (math.isfinite(rate) and rate > 0):
            raise FormatError(f"'VideoFrameRate' must be > 0, got {rate!r}", path=p, field="VideoFrameRate")
    return MocapMarkers(_fit_labels(labels, markers.shape[1]), markers, rate, p)


def read_c3d(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read a Vicon C3D trial with ``ezc3d`` or the ``c3d`` package; invalid points become (0, 0, 0).

    ``ezc3d`` is used when installed, else ``c3d`` (pure Python; what ``swarmpose[humaneva]``
    installs). Labels of ``POINT:LABELS`` (and ``LABELS2``...) are stripped of padding.

    Raises
    ------
    DataError
        Missing file, or neither reader is installed (install ``swarmpose[humaneva]``, or place the
        support code's ``.mat`` cache beside the ``.c3d``).
    FormatError
        The C3D file cannot be parsed.
    """
    p = Path(path)
    if not p.is_file():
        raise DataError(f"{p}: missing mocap file (.c3d)")
    try:
        import ezc3d  # type: ignore[import-not-found]
    except ImportError:
        ezc3d = None
    if ezc3d is not None:
        try:
            c = ezc3d.c3d(str(p))
            pts = np.asarray(c["data"]["points"], dtype=np.float64)  # (4, M, T)
            labels = [str(s).strip() for s in c["parameters"]["POINT"]["LABELS"]["value"]]
            for extra in ("LABELS2", "LABELS3"):
                if extra in c["parameters"]["POINT"]:
                    labels += [str(s).strip() for s in c["parameters"]["POINT"][extra]["value"]]
            rate = float(np.ravel(c["parameters"]["POINT"]["RATE"]["value"])[0])
        except Exception as exc:  # ezc3d raises RuntimeError/IndexError/KeyError on bad input
            raise FormatError(f"cannot parse C3D ({type(exc).__name__}: {exc})", path=p) from None
        xyz = np.transpose(pts[:3], (2, 1, 0))
        xyz = np.where(np.isfinite(xyz), xyz, 0.0)  # ezc3d marks invalid points NaN; HumanEva uses 0
        return MocapMarkers(_fit_labels(labels, xyz.shape[1]), np.ascontiguousarray(xyz), rate, p)
    try:
        import c3d as c3dpkg  # type: ignore[import-not-found]
    except ImportError:
        raise DataError(f"{p}: reading .c3d needs a C3D reader (the 'c3d' or 'ezc3d' package): pip install "
                        f"'swarmpose[humaneva]' (or put the HumanEva support code's cached "
                        f"{p.with_suffix('.mat').name} beside it)") from None
    try:
        with open(p, "rb") as fh:
            reader = c3dpkg.Reader(fh)
            labels = [str(s).strip() for s in reader.point_labels]
            rate = float(reader.point_rate)
            frames = []
            for _, points, _ in reader.read_frames():
                xyz = np.array(points[:, :3], dtype=np.float64)
                xyz[points[:, 3] < 0] = 0.0  # residual -1 = invalid point
                frames.append(xyz)
    except Exception as exc:
        raise FormatError(f"cannot parse C3D ({type(exc).__name__}: {exc})", path=p) from None
    if not frames:
        raise FormatError("C3D file holds no frames", path=p)
    m = np.stack(frames)
    return MocapMarkers(_fit_labels(labels, m.shape[1]), m, rate, p)


def read_mocap(path: str | os.PathLike[str]) -> MocapMarkers:
    """Read a trial from ``.mat`` (preferred when it sits beside the ``.c3d``) or ``.c3d``."""
    p = Path(path)
    if p.suffix.lower() == ".mat":
        return read_mocap_mat(p)
    mat = p.with_suffix(".mat")
    if mat.is_file():
        return read_mocap_mat(mat)
    return read_c3d(p)


# ---------------------------------------------------------------------- ground truth
def _zero(points: np.ndarray) -> np.ndarray:
    """True where a marker is (0, 0, 0) (lost)."""
    return np.all(points == 0.0, axis=-1)


def limb_lengths(mocap: MocapMarkers) -> np.ndarray:
    """The 18 limb lengths of ``ComputeLimbLengths`` (mm), mean over frames with both markers present.

    Slots (1-based as in the facts, section 5.1): 1 torso, 2 left asis, 3 L thigh, 4 L shank, 5 L foot
    (0), 6-9 right side, 10 L thorax-clavicle, 11 L upper arm, 12 L forearm, 13 L hand (0), 14-17
    right side, 18 head (316.103). NaN where a pair is never seen together.
    """
    pairs = [("TRXO", "PELO"), ("PELO", "LFEP"), ("LFEP", "LFEO"), ("LFEO", "LTIO"), None,
             ("PELO", "RFEP"), ("RFEP", "RFEO"), ("RFEO", "RTIO"), None,
             ("TRXO", "LCLO"), ("LCLO", "LHUO"), ("LHUO", "LRAO"), None,
             ("TRXO", "RCLO"), ("RCLO", "RHUO"), ("RHUO", "RRAO"), None]
    out = np.zeros(18)
    m = mocap.markers
    for k, pair in enumerate(pairs):
        if pair is None:
            continue
        a, b = m[:, mocap.index(pair[0])], m[:, mocap.index(pair[1])]
        ok = ~(_zero(a) | _zero(b))
        out[k] = float(np.linalg.norm(a[ok] - b[ok], axis=1).mean()) if ok.any() else np.nan
    out[17] = HEAD_LENGTH_MM
    return out


def subject_measurements(static: MocapMarkers, mp: Mapping[str, float], mp_path: object = None
                         ) -> SubjectMeasurements:
    """The subject's measurements: marker distances from ``static`` and the ``.mp`` widths and offsets.

    Marker distances are means over every frame of ``static`` (as the support code; a lost marker
    counts as 0).
    """
    m = static.markers

    def mean_dist(a: str, b: str) -> float:
        return float(np.linalg.norm(m[:, static.index(a)] - m[:, static.index(b)], axis=1).mean())

    def val(n: str) -> float:
        return mp_value(mp, n, mp_path)

    try:
        return SubjectMeasurements(
            shoulder_markers=mean_dist("LSHO", "RSHO"), sternum_t10=mean_dist("STRN", "T10"),
            l_knee_width=val("LKneeWidth"), r_knee_width=val("RKneeWidth"),
            l_ankle_width=val("LAnkleWidth"), r_ankle_width=val("RAnkleWidth"),
            l_elbow_width=val("LElbowWidth"), r_elbow_width=val("RElbowWidth"),
            l_wrist_width=val("LWristWidth"), r_wrist_width=val("RWristWidth"),
            l_shoulder_offset=val("LShoulderOffset"), r_shoulder_offset=val("RShoulderOffset"),
            head_diagonal=mean_dist("LBHD", "RFHD"), head_front=mean_dist("LFHD", "RFHD"),
            head_offset_deg=val("HeadOffset"),
            source=f"{static.path} (markers), {mp_path} (.mp)")
    except FormatError as exc:
        raise FormatError(f"{exc} (static trial {static.path}, subject file {mp_path})") from None


def limb_parameters(static: MocapMarkers, mp: Mapping[str, float], mp_path: object = None) -> np.ndarray:
    """The 10 x 5 cone parameters of ``ComputeLimbParameters`` (facts section 5.2).

    Rows: torso, L thigh, L calf, R thigh, R calf, L upper arm, L lower arm, R upper arm, R lower arm,
    head; columns: proximal radius, distal radius, x-scale, y-scale, (head only) head offset in rad.
    The rules are :func:`swarmpose.body.measurements.limb_table`.
    """
    return limb_table(subject_measurements(static, mp, mp_path))


def _yrot_t(theta: np.ndarray) -> np.ndarray:
    """The support code's ``yRotation(theta)``: the *transposed* rotation about y, shape (..., 3, 3)."""
    c, s = np.cos(theta), np.sin(theta)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1), np.stack([s, z, c], -1)], -2)


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """HumanEva ground truth at fractional mocap positions.

    Attributes
    ----------
    positions : numpy.ndarray, shape (F,)
        1-based fractional mocap positions.
    points20 : numpy.ndarray, shape (F, 20, 3)
        The :data:`BODY_POSE20` points, mm; NaN rows where invalid.
    joints15 : numpy.ndarray, shape (F, 15, 3)
        :data:`swarmpose.joints.JOINTS15`, mm (double joints = midpoints); NaN rows where invalid.
    valid : numpy.ndarray, shape (F,), bool
    """

    positions: np.ndarray
    points20: np.ndarray
    joints15: np.ndarray
    valid: np.ndarray


def joints15_from_points20(points20: np.ndarray) -> np.ndarray:
    """``(..., 20, 3)`` :data:`BODY_POSE20` points -> ``(..., 15, 3)`` JOINTS15 (double joints: midpoints)."""
    p = np.asarray(points20, dtype=np.float64)
    if p.shape[-2:] != (20, 3):
        raise ShapeError(f"points20 must have shape (..., 20, 3), got {p.shape}")
    return np.stack([np.mean([p[..., _P20[n], :] for n in names], axis=0) for names in JOINTS15_FROM_20], axis=-2)


def humaneva_ground_truth(mocap: MocapMarkers, positions: np.ndarray, *, torso_radius: float,
                          l_shoulder_offset: float, r_shoulder_offset: float) -> GroundTruth:
    """The ``cur_frame`` ground truth at fractional mocap positions (facts section 4.2).

    Parameters
    ----------
    mocap : MocapMarkers
        The trial (Plug-in-Gait virtual markers and the 39 validity markers).
    positions : array_like, shape (F,)
        1-based fractional mocap positions (:meth:`SyncInfo.mocap_position`), in ``[1, T]``.
    torso_radius : float
        ``Params(1, 1)`` of :func:`limb_parameters` (mm): tilts the torso by ``atan2(r/2, L_torso)``.
    l_shoulder_offset, r_shoulder_offset : float
        ``LShoulderOffset``/``RShoulderOffset`` from the ``.mp`` file (mm): tilt the upper arms.

    Returns
    -------
    GroundTruth

    Raises
    ------
    FormatError
        A needed marker label is missing from the trial.
    ConfigError
        A position outside ``[1, T]``.
    """
    from scipy.spatial.transform import Rotation

    missing = mocap.missing_labels()
    if missing:
        raise FormatError(f"missing marker labels {missing}", path=mocap.path, field="POINT:LABELS")
    p = np.asarray(positions, dtype=np.float64).reshape(-1)
    T = mocap.n_frames
    if p.size and (not np.isfinite(p).all() or p.min() < 1 or p.max() > T):
        raise ConfigError(f"mocap positions must lie in [1, {T}], got {p.min():.3f}..{p.max():.3f}")
    m = mocap.markers
    f0 = np.floor(p).astype(np.int64) - 1  # 0-based floor(p)
    alpha = p - np.floor(p)
    c0 = np.where(alpha > 0, f0 + 1, f0)  # floor(p) + 1 (only when it has weight)
    cl0 = np.ceil(p).astype(np.int64) - 1  # ceil(p), used for lengths and validity
    c0 = np.minimum(c0, T - 1)
    cl0 = np.minimum(cl0, T - 1)
    F = p.size
    if F == 0:
        return GroundTruth(positions=p, points20=np.zeros((0, 20, 3)), joints15=np.zeros((0, 15, 3)),
                           valid=np.zeros(0, dtype=bool))
    valid = np.ones(F, dtype=bool)

    for alt in VALIDITY_MARKERS:  # sum of coordinates == 0 counts as lost (support-code test)
        i = min(mocap.index(a) for a in alt if mocap.find(a) is not None)
        valid &= (m[f0, i].sum(-1) != 0) & (m[cl0, i].sum(-1) != 0)

    def pos(label: str) -> np.ndarray:
        i = mocap.index(label)
        a, b = m[f0, i], m[c0, i]
        valid[:] &= ~(_zero(a) | _zero(b))
        return (1.0 - alpha)[:, None] * a + alpha[:, None] * b

    def length(la: str, lb: str) -> np.ndarray:  # LimbLength over frames floor(p), ceil(p)
        ia, ib = mocap.index(la), mocap.index(lb)
        d, n = np.zeros(F), np.zeros(F)
        for fr in (f0, cl0):
            a, b = m[fr, ia], m[fr, ib]
            ok = ~(_zero(a) | _zero(b))
            d += np.where(ok, np.linalg.norm(a - b, axis=-1), 0.0)
            n += ok
        valid[:] &= n > 0
        return d / np.maximum(n, 1)

    def frame(group: str) -> np.ndarray:  # global_from_local rotations (F, 3, 3)
        i = mocap.index(group)
        mats = []
        for fr in (f0, c0):
            o, pz, px, py = m[fr, i], m[fr, i + 1], m[fr, i + 2], m[fr, i + 3]
            bad = _zero(o) | _zero(pz) | _zero(px) | _zero(py)
            axes = []
            for q in (px, py, pz):
                v = q - o
                n = np.linalg.norm(v, axis=-1, keepdims=True)
                bad |= n[:, 0] == 0
                axes.append(v / np.where(n == 0, 1.0, n))
            x, y, z = axes
            ortho = np.maximum.reduce([np.abs((x * y).sum(-1)), np.abs((x * z).sum(-1)), np.abs((y * z).sum(-1))])
            R = np.stack([x, y, z], axis=-1)  # columns = local axes in world
            bad |= (ortho > 1e-4) | ~(np.linalg.det(R) > 0)
            R[bad] = np.eye(3)
            valid[:] &= ~bad
            mats.append(R)
        Rf = Rotation.from_matrix(mats[0])
        Rc = Rotation.from_matrix(mats[1])
        rel = (Rf.inv() * Rc).as_rotvec()
        return (Rf * Rotation.from_rotvec(rel * alpha[:, None])).as_matrix()  # slerp(Rf, Rc, alpha)

    def apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.einsum("fij,fj->fi", R, v)

    zeros = np.zeros(F)

    def vec(x: Any, y: Any, z: Any) -> np.ndarray:
        return np.stack(np.broadcast_arrays(np.asarray(x, float) + zeros, np.asarray(y, float) + zeros,
                                            np.asarray(z, float) + zeros), axis=-1)

    L1 = length("TRXO", "PELO")
    L3, L4 = length("LFEP", "LFEO"), length("LFEO", "LTIO")
    L7, L8 = length("RFEP", "RFEO"), length("RFEO", "RTIO")
    L11, L12 = length("LCLO", "LHUO"), length("LHUO", "LRAO")
    L15, L16 = length("RCLO", "RHUO"), length("RHUO", "RRAO")

    pts = np.zeros((F, 20, 3))
    # torso: pelvis frame moved -50 mm along local x, tilted by yRotation(atan2(r_t / 2, L1))
    R_pel = frame("PELO")
    o_pel = pos("PELO") + apply(R_pel, vec(PELVIS_SHIFT_MM, 0, 0))
    R_tilt = R_pel @ _yrot_t(np.arctan2(torso_radius / 2.0, L1))
    pts[:, _P20["torsoDistal"]] = o_pel
    pts[:, _P20["torsoProximal"]] = o_pel + apply(R_tilt, vec(0, 0, L1))
    # head: thorax origin, head frame's +z for 316.103 mm
    trx = pos("TRXO")
    R_head = frame("HEDO")
    pts[:, _P20["headProximal"]] = trx
    pts[:, _P20["headDistal"]] = trx + apply(R_head, vec(0, 0, HEAD_LENGTH_MM))
    # legs: frames flipped 180 deg about y, so the distal points lie along -z of the PiG frames
    for side, La, Lb in (("L", L3, L4), ("R", L7, L8)):
        hip, knee = pos(f"{side}FEP"), pos(f"{side}FEO")
        R_fe, R_ti = frame(f"{side}FEO"), frame(f"{side}TIO")
        pts[:, _P20[f"upper{side}LegProximal"]] = hip
        pts[:, _P20[f"upper{side}LegDistal"]] = hip + apply(R_fe, vec(0, 0, -La))
        pts[:, _P20[f"lower{side}LegProximal"]] = knee
        pts[:, _P20[f"lower{side}LegDistal"]] = knee + apply(R_ti, vec(0, 0, -Lb))
    # arms: upper arm tilted by yRotation(-atan2(offset / 2, L)), forearm re-attached and tilted back
    for side, La, Lb, off in (("L", L11, L12, l_shoulder_offset), ("R", L15, L16, r_shoulder_offset)):
        sho, elb = pos(f"{side}CLO"), pos(f"{side}HUO")
        R_hu, R_ra = frame(f"{side}HUO"), frame(f"{side}RAO")
        theta = np.arctan2(off / 2.0, La)
        diff = elb - (sho + apply(R_hu, vec(0, 0, -La)))
        R_hu2 = R_hu @ _yrot_t(-theta)
        upper_distal = sho + apply(R_hu2, vec(0, 0, -La))
        elbow = upper_distal + diff
        R_ra2 = R_ra @ _yrot_t(theta)
        pts[:, _P20[f"upper{side}ArmProximal"]] = sho
        pts[:, _P20[f"upper{side}ArmDistal"]] = upper_distal
        pts[:, _P20[f"lower{side}ArmProximal"]] = elbow
        pts[:, _P20[f"lower{side}ArmDistal"]] = elbow + apply(R_ra2, vec(0, 0, -Lb))
    valid &= np.isfinite(pts).all(axis=(1, 2))
    pts[~valid] = np.nan
    return GroundTruth(positions=p, points20=pts, joints15=joints15_from_points20(pts), valid=valid)


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


# ---------------------------------------------------------------------- locating files
def _video_path(subject_dir: Path, action: str, trial: str, cam: str) -> Path | None:
    base = subject_dir / "Image_Data" / f"{action}_{trial}_({cam})"
    if base.is_dir():
        return base
    for ext in (".avi", ".AVI"):
        if base.with_name(base.name + ext).is_file():
            return base.with_name(base.name + ext)
    return None


def detect_dataset(subject_dir: str | os.PathLike[str], action: str | None = None,
                   trial: str | None = None) -> str:
    """``"HumanEva-I"`` or ``"HumanEva-II"`` from the camera names present for a subject (or trial).

    Greyscale cameras (``BW*``) mean HumanEva-I; a fourth colour camera (``C4``) HumanEva-II;
    otherwise HumanEva-I.
    """
    sd = Path(subject_dir)
    names: set[str] = set()
    pat = f"{action}_{trial}_(*).ofs" if action and trial else "*_(*).ofs"
    sync = sd / "Sync_Data"
    if sync.is_dir():
        names |= {m.group(1) for f in sync.glob(pat) if (m := re.search(r"_\(([^)]+)\)\.ofs$", f.name))}
    cal = sd / "Calibration_Data"
    if not names and cal.is_dir():
        names |= {f.stem for f in cal.glob("*.cal")}
    if any(n.startswith("BW") for n in names):
        return "HumanEva-I"
    if "C4" in names:
        return "HumanEva-II"
    return "HumanEva-I"


def _background_dirs(subject_dir: Path) -> list[Path]:
    return [d for d in (subject_dir / "Background", subject_dir.parent / "Background") if d.is_dir()]


def _background_sessions(subject_dir: Path, cam: str) -> tuple[Path | None, list[Path]]:
    """(precomputed Background_(CAM).mat or None, session footage paths) for a camera."""
    for d in _background_dirs(subject_dir):
        mat = d / f"Background_({cam}).mat"
        sessions = sorted(p for p in d.glob(f"Background_*_({cam})*")
                          if p.is_dir() or p.suffix.lower() == ".avi")
        if mat.is_file() or sessions:
            return (mat if mat.is_file() else None), sessions
    return None, []


def trial_files(subject_dir: str | os.PathLike[str], action: str, trial: str | int,
                dataset: str | None = None) -> dict[str, Any]:
    """Expected paths of one trial (existing or not), for the loader and ``datasets check``."""
    sd = Path(subject_dir)
    trial = str(trial)
    ds = dataset or detect_dataset(sd, action, trial)
    cams = DATASET_CAMERAS[ds]
    subject = sd.name
    mocap_c3d = sd / "Mocap_Data" / f"{action}_{trial}.c3d"
    return {
        "dataset": ds,
        "cameras": cams,
        "calibration": {c: sd / "Calibration_Data" / f"{c}.cal" for c in cams},
        "offsets": {c: sd / "Sync_Data" / f"{action}_{trial}_({c}).ofs" for c in cams},
        "video": {c: _video_path(sd, action, trial, c) or sd / "Image_Data" / f"{action}_{trial}_({c}).avi"
                  for c in cams},
        "mocap": mocap_c3d.with_suffix(".mat") if mocap_c3d.with_suffix(".mat").is_file() else mocap_c3d,
        "static": (sd / "Mocap_Data" / "Static.mat") if (sd / "Mocap_Data" / "Static.mat").is_file()
        else sd / "Mocap_Data" / "Static.c3d",
        "mp": sd / "Mocap_Data" / f"{subject}.mp",
    }


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


# ---------------------------------------------------------------------- trials and sequences
def _split_action_trial(name: str) -> tuple[str, str]:
    m = re.fullmatch(r"(.+)_(\d+)", name)
    if not m:
        raise ConfigError(f"expected <Action>_<Trial> (e.g. Walking_1), got {name!r}")
    return m.group(1), m.group(2)


def humaneva_frame_range(dataset: str, subject: str, action: str, trial: str | int,
                         split: str = "auto") -> tuple[int, int] | None:
    """Official synchronized-frame range of a partition, or None when the table has no entry.

    ``split``: ``"validate"``, ``"train"``, ``"test"`` or ``"auto"`` (trial 1 -> validate, trial 2 ->
    test, trial 3 -> train, HumanEva-II -> test).
    """
    trials = FRAME_RANGES.get((dataset, subject, action))
    if trials is None:
        return None
    splits = trials.get(int(trial))
    if not splits:
        return None
    if split == "auto":
        for s in ("validate", "test", "train"):
            if s in splits:
                return splits[s]
        return None
    return splits.get(split)


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
