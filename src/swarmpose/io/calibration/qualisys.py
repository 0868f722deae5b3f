"""Qualisys Track Manager calibrations (``.qca.txt``, XML).

Per ``<camera serial="...">``:

* ``<fov_video left top right bottom>``: the video crop on the sensor; image size
  ``(right - left + 1, bottom - top + 1)``;
* ``<intrinsic>``: ``focalLengthU/V`` and ``centerPointU/V`` in sub-pixel sensor units (1/64 pixel); the
  principal point is then shifted by the crop (``- left``, ``- top``); ``radialDistortion1..3`` are k1 k2 k3
  and ``tangentalDistortion1, 2`` p1 p2, unscaled (they match a board calibration of the same lenses);
* ``<transform x y z r11 .. r33>``: the camera's position (mm) and orientation.

Qualisys's camera looks along its -z axis with y up in the image. Rows of ``M = [r_ij]`` are that frame's
axes in the world, so OpenCV's ``cam_from_world`` rotation is ``R = diag(1, -1, -1) @ M`` (a half turn about
the camera's x axis) and ``t = -R @ (x, y, z)``. This was checked on a rig calibrated both ways: the
relative rotations between cameras agree within 3.5 degrees and every optical axis points at the rig's
centre, while every other choice of transpose and axis flips puts some pair 99 degrees or more off.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import FormatError
from swarmpose.io.calibration._common import (
    RawCalibration,
    as_rotation,
    cam_field,
    make_camera,
    pick_size,
    require_file,
)

__all__ = ["read_qualisys", "QUALISYS_TO_OPENCV"]

#: Camera-frame change from Qualisys's (looks along -z, y up) to OpenCV's (looks along +z, y down).
QUALISYS_TO_OPENCV = np.diag([1.0, -1.0, -1.0])
_SUBPIXEL = 64.0  # sensor units per pixel of focalLength and centerPoint


def _attrs(cam: ET.Element, tag: str, keys: Sequence[str], path: Path, name: str) -> dict[str, float]:
    el = cam.find(tag)
    if el is None:
        raise cam_field(path, name, tag, f"missing element <{tag}>")
    out = {}
    for k in keys:
        v = el.get(k)
        if v is None:
            raise cam_field(path, name, f"{tag}.{k}", f"missing attribute {k!r} of <{tag}>")
        try:
            f = float(v)
        except ValueError:
            raise cam_field(path, name, f"{tag}.{k}", f"must be a number, got {v!r}") from None
        if not np.isfinite(f):
            raise cam_field(path, name, f"{tag}.{k}", f"must be finite, got {v!r}")
        out[k] = f
    return out


def _video_scale(cam: ET.Element, path: Path, name: str, notes: list[str]) -> float:
    """Miqus video cameras recording below 1080p: intrinsics scale by ``res / 1080`` (as Pose2Sim does)."""
    res = cam.get("video_resolution")
    if res in (None, "", "N/A"):
        return 1.0
    m = re.fullmatch(r"(\d+)p?", res.strip())
    if not m:
        raise cam_field(path, name, "video_resolution", f"expected e.g. '1080p', got {res!r}")
    scale = int(m.group(1)) / 1080.0
    if scale != 1.0:
        notes.append(f"camera {name!r}: video_resolution {res}: sizes and intrinsics scaled by {scale:g} "
                     "(the sensor calibration is for 1080p)")
    return scale


def _camera(cam: ET.Element, path: Path, index: int, sizes: Mapping[str, Sequence[int]] | None,
            notes: list[str]) -> tuple[Camera, tuple[int, int]]:
    name = cam.get("serial")
    if not name:
        raise FormatError(f"camera {index} has no 'serial' (its name)", path=path, field="serial")
    if cam.get("viewrotation", "0") not in ("0", ""):
        raise cam_field(path, name, "viewrotation", f"viewrotation={cam.get('viewrotation')!r} is not supported "
                        "(only unrotated views, 0)")
    if cam.get("active", "1") == "0":
        notes.append(f"camera {name!r} is marked inactive in the file; it is read all the same")
    scale = _video_scale(cam, path, name, notes)
    fov = _attrs(cam, "fov_video", ("left", "top", "right", "bottom"), path, name)
    w = (fov["right"] - fov["left"] + 1) * scale
    h = (fov["bottom"] - fov["top"] + 1) * scale
    if w <= 0 or h <= 0 or w != round(w) or h != round(h):
        raise cam_field(path, name, "fov_video", f"gives no whole positive image size ({w:g} x {h:g})")
    stated = (int(round(w)), int(round(h)))
    width, height = pick_size(name, stated, sizes, path, "fov_video", notes)
    ik = _attrs(cam, "intrinsic", ("focalLengthU", "focalLengthV", "centerPointU", "centerPointV",
                                   "radialDistortion1", "radialDistortion2", "radialDistortion3",
                                   "tangentalDistortion1", "tangentalDistortion2"), path, name)
    skew_attr = cam.find("intrinsic").get("skew", "0")  # type: ignore[union-attr]
    try:
        skew_units = float(skew_attr)
    except ValueError:
        raise cam_field(path, name, "intrinsic.skew", f"must be a number, got {skew_attr!r}") from None
    fx = ik["focalLengthU"] / _SUBPIXEL * scale
    fy = ik["focalLengthV"] / _SUBPIXEL * scale
    cx = (ik["centerPointU"] / _SUBPIXEL - fov["left"]) * scale
    cy = (ik["centerPointV"] / _SUBPIXEL - fov["top"]) * scale
    skew = 0.0
    if skew_units != 0.0:
        skew = skew_units / _SUBPIXEL * scale / fx
        notes.append(f"camera {name!r}: skew {skew_attr} read as K[0,1] in 1/64 pixel like the focal length "
                     "(an assumption: the files seen so far all have skew 0)")
    dist = (ik["radialDistortion1"], ik["radialDistortion2"], ik["tangentalDistortion1"],
            ik["tangentalDistortion2"], ik["radialDistortion3"])
    tr = _attrs(cam, "transform", ("x", "y", "z", *(f"r{i}{j}" for i in "123" for j in "123")), path, name)
    M = np.array([[tr[f"r{i}{j}"] for j in "123"] for i in "123"])
    M = as_rotation(M, path, name, "transform", notes)
    R = QUALISYS_TO_OPENCV @ M
    pos = np.array([tr["x"], tr["y"], tr["z"]])
    cam_obj = make_camera(path, name, width=width, height=height, fx=fx, fy=fy, cx=cx, cy=cy, skew=skew,
                          dist=dist, R=R, t=-R @ pos)
    return cam_obj, stated


def read_qualisys(path: str | os.PathLike[str], *,
                  sizes: Mapping[str, Sequence[int]] | None = None) -> RawCalibration:
    """Read a Qualisys ``.qca.txt`` calibration.

    Parameters
    ----------
    path : path-like
    sizes : mapping of name to (width, height), optional
        Compared with the file's ``fov_video`` sizes (a difference is noted; the file's size is used).

    Returns
    -------
    RawCalibration
        Cameras (named by ``serial``) with ``t`` in mm, in the file's world frame.

    Raises
    ------
    DataError
        The file does not exist.
    FormatError
        Not XML (the line is named), no ``<cameras>``, or a missing or invalid element or attribute.
    """
    p = require_file(path)
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        line = exc.position[0] if getattr(exc, "position", None) else None
        raise FormatError(f"not valid XML ({exc})", path=p, line=line) from None
    if root.tag != "calibration":
        raise FormatError(f"the root element is <{root.tag}>, not a Qualisys <calibration>", path=p)
    cams_el = root.findall("cameras/camera")
    if not cams_el:
        raise FormatError("no <cameras><camera> element", path=p, field="cameras")
    notes: list[str] = []
    cameras: list[Camera] = []
    stated: dict[str, tuple[int, int]] = {}
    for i, el in enumerate(cams_el):
        cam, size = _camera(el, p, i, sizes, notes)
        cameras.append(cam)
        stated[cam.name] = size
    names = [c.name for c in cameras]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(f"camera serials must be unique, repeated: {dup}", path=p, field="serial")
    return RawCalibration(cameras=cameras, format="qualisys", paths=(p,), units="mm", image_sizes=stated,
                          notes=notes)
