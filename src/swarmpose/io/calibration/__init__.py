"""Calibration files of other tools, read into swarmpose cameras (millimetres, z-up world) and written back.

Public API
----------
``read_calibration(path, *, extrinsics=None, fmt=None, units=None, up=None, sizes=None) -> Calibration``
    Any supported file; the format is told from the name and content.
``write_calibration(path, cameras, fmt, *, extrinsics_path=None, units="m") -> tuple[Path, ...]``
    ``"toml"``, ``"opencv"`` (one YAML/XML file) or ``"easymocap"`` (``intri.yml`` + ``extri.yml``).
``detect_format(path, extrinsics=None) -> str``

Formats (one module each): ``toml`` (Pose2Sim, aniposelib, FreeMoCap, Caliscope; metres), ``qualisys``
(``.qca.txt``; millimetres), ``opencv`` (EasyMocap's FileStorage layout, one file or the pair; the pair is
in metres, a single file states its unit or it is detected).

Every reader returns cameras in the file's own units and world; :func:`read_calibration` then converts to
millimetres and turns the world so that its up axis (stated with ``up=`` or detected from the cameras'
image-up directions) becomes +z, recording the rotation in ``Calibration.world_from_file``.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, FormatError
from swarmpose.io.calibration._common import (
    MM_PER_UNIT,
    Calibration,
    RawCalibration,
    camera_list,
    require_file,
)
from swarmpose.io.calibration._frame import check_up, detect_units, detect_up, to_world, world_from_up
from swarmpose.io.calibration.opencv import read_opencv, write_easymocap, write_opencv
from swarmpose.io.calibration.qualisys import read_qualisys
from swarmpose.io.calibration.toml import read_toml, write_toml

__all__ = ["Calibration", "read_calibration", "write_calibration", "detect_format", "FORMATS", "WRITABLE"]

#: Formats :func:`read_calibration` knows.
FORMATS = ("toml", "qualisys", "opencv", "easymocap")
#: Formats :func:`write_calibration` writes.
WRITABLE = ("toml", "opencv", "easymocap")
_YAML = (".yml", ".yaml")
_PAIR_STEMS = ("intri", "extri")


def _head(path: Path, n: int = 4096) -> str:
    with open(path, "rb") as fh:
        return fh.read(n).decode("utf-8", errors="replace")


def _sibling(path: Path, stem: str) -> Path | None:
    for suffix in (path.suffix, *_YAML):
        cand = path.with_name(stem + suffix)
        if cand.is_file():
            return cand
    return None


def _pair(path: Path, extrinsics: Path | None) -> tuple[Path, Path] | None:
    """``(intri, extri)`` when ``path`` is one of EasyMocap's pair (given, or found beside it)."""
    if extrinsics is not None:
        return path, extrinsics
    stem = path.name.split(".")[0].lower()
    if stem == "intri":
        other = _sibling(path, "extri")
        return (path, other) if other is not None else None
    if stem == "extri":
        other = _sibling(path, "intri")
        return (other, path) if other is not None else None
    return None


def detect_format(path: str | os.PathLike[str], extrinsics: str | os.PathLike[str] | None = None) -> str:
    """The calibration format of ``path``: one of :data:`FORMATS`.

    ``.toml``: toml. ``.qca.txt``, or XML with ``<calibration>`` and ``<cameras>``: qualisys.
    ``.yml``/``.yaml``/``.xml`` (OpenCV FileStorage): easymocap when ``extrinsics`` is given or the file is
    ``intri.yml`` with an ``extri.yml`` beside it (or the other way round), else opencv.

    Raises
    ------
    DataError
        The file does not exist.
    FormatError
        None of these (pass ``fmt=``).
    """
    p = require_file(path)
    name = p.name.lower()
    if name.endswith(".toml"):
        return "toml"
    if name.endswith(".qca.txt"):
        return "qualisys"
    head = _head(p)
    if "<calibration" in head and "<cameras" in head:
        return "qualisys"
    if p.suffix.lower() in (*_YAML, ".xml") or "<opencv_storage" in head or head.startswith("%YAML"):
        ext = Path(extrinsics) if extrinsics is not None else None
        return "easymocap" if _pair(p, ext) is not None else "opencv"
    raise FormatError("cannot tell the calibration format from the name or the content (expected .toml, "
                      ".qca.txt, or an OpenCV .yml/.yaml/.xml); pass fmt=", path=p)


def _read_raw(p: Path, fmt: str, extrinsics: Path | None, sizes: Mapping[str, Sequence[int]] | None
              ) -> RawCalibration:
    if fmt == "toml":
        return read_toml(p, sizes=sizes)
    if fmt == "qualisys":
        return read_qualisys(p, sizes=sizes)
    if fmt == "opencv":
        if extrinsics is not None:
            return read_opencv(p, extrinsics=extrinsics, sizes=sizes)
        return read_opencv(p, sizes=sizes)
    pair = _pair(p, extrinsics)
    if pair is None:
        raise FormatError("an EasyMocap calibration is a pair: pass extrinsics='extri.yml' (none found beside "
                          "this file)", path=p)
    intri, extri = pair
    raw = read_opencv(intri, extrinsics=extri, sizes=sizes)
    raw.notes.insert(0, f"EasyMocap pair: intrinsics from {intri.name}, extrinsics from {extri.name}")
    return raw


def read_calibration(
    path: str | os.PathLike[str],
    *,
    extrinsics: str | os.PathLike[str] | None = None,
    fmt: str | None = None,
    units: str | None = None,
    up: str | None = None,
    sizes: Mapping[str, Sequence[int]] | None = None,
) -> Calibration:
    """Read a calibration file into swarmpose cameras (mm, right-handed, z-up world).

    Parameters
    ----------
    path : path-like
        The calibration file (EasyMocap: ``intri.yml``).
    extrinsics : path-like, optional
        EasyMocap's ``extri.yml`` (found beside ``intri.yml`` when not given).
    fmt : {"toml", "qualisys", "opencv", "easymocap"}, optional
        Default: :func:`detect_format`.
    units : {"m", "cm", "mm"}, optional
        The file's length unit, overriding the format's or the detected one.
    up : {"+x", "-x", "+y", "-y", "+z", "-z"}, optional
        The file's up axis; default: detected from the cameras' image-up directions.
    sizes : mapping of camera name to (width, height), optional
        Image sizes for cameras whose file gives none (an OpenCV file without ``H_``/``W_``); where the
        file gives one, a different size here is noted and the file's is used.

    Returns
    -------
    Calibration

    Raises
    ------
    DataError
        A file does not exist.
    FormatError
        A file does not parse or lacks or mangles a field (the message names file, camera and field),
        a fisheye camera, distortion beyond k1 k2 p1 p2 k3, a 3x3 that is not a rotation.
    ConfigError
        A bad argument, or the units or up axis cannot be detected (pass ``units=``/``up=``).
    """
    if fmt is not None and fmt not in FORMATS:
        raise ConfigError(f"fmt must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if units is not None and units not in MM_PER_UNIT:
        raise ConfigError(f"units must be one of {', '.join(MM_PER_UNIT)}, got {units!r}")
    up_stated = check_up(up) if up is not None else None
    p = require_file(path)
    ext = require_file(extrinsics, "extrinsics file") if extrinsics is not None else None
    if ext is not None and fmt not in (None, "easymocap", "opencv"):
        raise ConfigError(f"extrinsics= is for the EasyMocap pair, not for fmt={fmt!r}")
    fmt = fmt or detect_format(p, ext)
    if ext is not None and fmt not in ("easymocap", "opencv"):
        raise ConfigError(f"extrinsics= is for the EasyMocap pair, but {p.name} is a {fmt} file")
    raw = _read_raw(p, fmt, ext, sizes)
    notes = list(raw.notes)
    if units is not None:
        units_used, units_source = units, "stated"
        if raw.units is not None and raw.units != units:
            notes.append(f"units={units!r} overrides the file's {raw.units!r}")
    elif raw.units is not None:
        units_used, units_source = raw.units, "format"
        if raw.format != "opencv":  # a single OpenCV file notes its own 'units' key
            notes.append(f"length unit {raw.units!r}, as the {raw.format} format defines it")
    else:
        units_used, note = detect_units(raw.cameras)
        units_source = "detected"
        notes.append(note)
    if up_stated is not None:
        up_used, up_source = up_stated, "stated"
    else:
        up_used, note = detect_up(raw.cameras)
        up_source = "detected"
        notes.append(note)
    A = world_from_up(up_used)
    if up_used != "+z":
        notes.append(f"world turned so that the file's {up_used} axis is +z (world_from_file)")
    scale = MM_PER_UNIT[units_used]
    world_from_file = np.eye(4)
    world_from_file[:3, :3] = A
    cameras = [to_world(c, A, scale) for c in raw.cameras]
    return Calibration(cameras=cameras, format=raw.format, paths=raw.paths, units=units_used,
                       units_source=units_source, up=up_used, up_source=up_source,
                       world_from_file=world_from_file, image_sizes=raw.image_sizes, notes=notes)


def write_calibration(
    path: str | os.PathLike[str],
    cameras: Iterable[Camera] | Calibration,
    fmt: str,
    *,
    extrinsics_path: str | os.PathLike[str] | None = None,
    units: str = "m",
) -> tuple[Path, ...]:
    """Write cameras (mm, swarmpose's world) in another tool's format; atomically, full precision.

    Parameters
    ----------
    path : path-like
        The file (EasyMocap: ``intri.yml``).
    cameras : iterable of Camera, or Calibration
        Unique names; for the OpenCV formats letters, digits, ``_`` and ``-`` only.
    fmt : {"toml", "opencv", "easymocap"}
    extrinsics_path : path-like, optional
        EasyMocap's ``extri.yml``; default ``extri.yml`` beside ``path``.
    units : {"m", "cm", "mm"}, default "m"
        Length unit of the translations. TOML and EasyMocap are metres by definition; an OpenCV file
        records the unit in its ``units`` key.

    Returns
    -------
    tuple of pathlib.Path
        The files written.
    """
    if fmt not in WRITABLE:
        raise ConfigError(f"fmt must be one of {', '.join(WRITABLE)} for writing, got {fmt!r}")
    if units not in MM_PER_UNIT:
        raise ConfigError(f"units must be one of {', '.join(MM_PER_UNIT)}, got {units!r}")
    if fmt in ("toml", "easymocap") and units != "m":
        raise ConfigError(f"the {fmt} format is in metres: units={units!r} cannot be written")
    if extrinsics_path is not None and fmt != "easymocap":
        raise ConfigError(f"extrinsics_path is for the EasyMocap pair, not for fmt={fmt!r}")
    cams = camera_list(cameras)
    if fmt == "toml":
        return (write_toml(path, cams),)
    if fmt == "opencv":
        return (write_opencv(path, cams, units=units),)
    p = Path(path)
    ext = Path(extrinsics_path) if extrinsics_path is not None else p.with_name("extri" + (p.suffix or ".yml"))
    return write_easymocap(p, ext, cams)
