"""Camera calibration (``.cal``), sync offsets (``.ofs``) and the synchronisation rule, and the
subject's Vicon parameters (``.mp``)."""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.camera import Camera
from swarmpose.datasets.humaneva.files import _fixed_numbers, _number, _read_text
from swarmpose.errors import ConfigError, DataError, FormatError

CAL_FIELDS: tuple[str, ...] = (
    "fc[0]", "fc[1]", "cc[0]", "cc[1]", "alpha_c", "kc[0]", "kc[1]", "kc[2]", "kc[3]", "kc[4]",
    *(f"R[{i},{j}]" for i in range(3) for j in range(3)), "T[0]", "T[1]", "T[2]",
)
OFS_FIELDS: tuple[str, ...] = ("im_st", "mc_st", "mc_sc")
MP_NAMES: tuple[str, ...] = ("LKneeWidth", "RKneeWidth", "LAnkleWidth", "RAnkleWidth", "LElbowWidth",
                             "RElbowWidth", "LWristWidth", "RWristWidth", "LShoulderOffset", "RShoulderOffset",
                             "HeadOffset")


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
