"""The TOML calibration layout of Pose2Sim, aniposelib, FreeMoCap and Caliscope.

One table per camera::

    [cam01]
    name = "cam01"
    size = [ 1088, 1920]                  # width, height in pixels
    matrix = [ [ fx, 0.0, cx], [ 0.0, fy, cy], [ 0.0, 0.0, 1.0]]
    distortions = [ k1, k2, p1, p2]       # 4 or 5 (k3) OpenCV coefficients
    rotation = [ rx, ry, rz]              # Rodrigues vector, world -> camera
    translation = [ tx, ty, tz]           # metres, world -> camera: x_cam = R x_world + t
    fisheye = false

and a ``[metadata]`` table (skipped). Other tables that hold no camera field are skipped with a note.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, FormatError
from swarmpose.io.calibration._common import (
    RawCalibration,
    as_array,
    cam_field,
    camera_list,
    distortion5,
    image_size,
    intrinsics,
    make_camera,
    pick_size,
    require_file,
    rodrigues,
    rotation_from_rodrigues,
    write_text_atomic,
)

__all__ = ["read_toml", "write_toml"]

_CAMERA_KEYS = ("name", "size", "matrix", "distortions", "rotation", "translation", "fisheye")
_SKIPPED_TABLES = ("metadata",)
_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def read_toml(path: str | os.PathLike[str], *, sizes: Mapping[str, Sequence[int]] | None = None) -> RawCalibration:
    """Read a Pose2Sim/aniposelib TOML calibration.

    Parameters
    ----------
    path : path-like
    sizes : mapping of name to (width, height), optional
        Image sizes for cameras whose table has no ``size`` (the file's ``size`` wins otherwise).

    Returns
    -------
    RawCalibration
        Cameras with ``t`` in metres (the format's unit), in the file's world frame.

    Raises
    ------
    DataError
        The file does not exist.
    FormatError
        Not TOML (the line is named), no camera, a missing or invalid field, or a fisheye camera.
    """
    p = require_file(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise FormatError("not a UTF-8 text file", path=p) from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"at line (\d+)", str(exc))
        line = int(m.group(1)) if m else (max(1, len(text.splitlines())) if "end of document" in str(exc) else None)
        raise FormatError(f"not valid TOML ({exc})", path=p, line=line) from None
    notes: list[str] = []
    cameras: list[Camera] = []
    stated_sizes: dict[str, tuple[int, int]] = {}
    for key, table in doc.items():
        if key in _SKIPPED_TABLES:
            continue
        if not isinstance(table, dict) or not any(k in table for k in _CAMERA_KEYS):
            notes.append(f"{key!r} is not a camera table (none of {', '.join(_CAMERA_KEYS)}): skipped")
            continue
        cam, size = _camera(p, key, table, sizes, notes)
        cameras.append(cam)
        if size is not None:
            stated_sizes[cam.name] = size
    if not cameras:
        raise FormatError("no camera table (a table with 'matrix', 'rotation', 'translation', ...)", path=p)
    names = [c.name for c in cameras]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(f"camera names must be unique, repeated: {dup}", path=p, field="name")
    return RawCalibration(cameras=cameras, format="toml", paths=(p,), units="m",
                          image_sizes=stated_sizes or None, notes=notes)


def _camera(p: Path, key: str, table: dict[str, Any], sizes: Mapping[str, Sequence[int]] | None,
            notes: list[str]) -> tuple[Camera, tuple[int, int] | None]:
    name = table.get("name", None)
    if name is None:
        name = key
        notes.append(f"table [{key}] has no 'name': the camera is called {key!r}")
    elif isinstance(name, bool) or not isinstance(name, (str, int)):
        raise cam_field(p, key, "name", f"must be a string, got {name!r}")
    name = str(name)
    for fld in ("matrix", "distortions", "rotation", "translation"):
        if fld not in table:
            raise cam_field(p, name, fld, f"missing field {fld!r} (table [{key}])")
    fisheye = table.get("fisheye", False)
    if fisheye is not False:
        if fisheye is True:
            raise cam_field(p, name, "fisheye", "fisheye cameras are not supported (swarmpose models pinhole "
                            "lenses with k1 k2 p1 p2 k3 distortion)")
        raise cam_field(p, name, "fisheye", f"must be true or false, got {fisheye!r}")
    stated = image_size(table["size"], p, name, "size") if "size" in table else None
    width, height = pick_size(name, stated, sizes, p, "size", notes)
    R = rotation_from_rodrigues(table["rotation"], p, name, "rotation")
    t = as_array(table["translation"], p, name, "translation", size=3)
    cam = make_camera(p, name, width=width, height=height, **intrinsics(table["matrix"], p, name, "matrix"),
                      dist=distortion5(table["distortions"], p, name, "distortions"), R=R, t=t)
    return cam, stated


# ---------------------------------------------------------------------- writing
def _float(x: float) -> str:
    """A TOML float with every digit (``repr``), never an integer literal."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write a non-finite number {x!r}")
    s = repr(x)
    return s if any(ch in s for ch in ".en") else s + ".0"


def _floats(values: Iterable[float]) -> str:
    return "[ " + ", ".join(_float(v) for v in values) + "]"


def _string(s: str) -> str:
    """A TOML basic string."""
    out = []
    for ch in s:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _key(s: str) -> str:
    return s if _BARE_KEY.match(s) else _string(s)


def toml_text(cameras: Iterable[Camera]) -> str:
    """The TOML text of ``cameras`` (translation in metres, full float precision)."""
    lines: list[str] = []
    for c in camera_list(cameras):
        if c.name in _SKIPPED_TABLES:
            raise ConfigError(f"a camera cannot be called {c.name!r} in TOML (that table is skipped on reading)")
        K = c.K
        lines += [
            f"[{_key(c.name)}]",
            f"name = {_string(c.name)}",
            f"size = [ {c.width}, {c.height}]",
            "matrix = [ " + ", ".join(_floats(row) for row in K) + "]",
            f"distortions = {_floats(c.dist)}",
            f"rotation = {_floats(rodrigues(c.R))}",
            f"translation = {_floats(c.t / 1000.0)}",
            "fisheye = false",
            "",
        ]
    lines += ["[metadata]", "adjusted = false", "error = 0.0", ""]
    return "\n".join(lines)


def write_toml(path: str | os.PathLike[str], cameras: Iterable[Camera]) -> Path:
    """Write cameras (mm) as a Pose2Sim/aniposelib TOML file (metres), atomically.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    return write_text_atomic(path, toml_text(cameras))
