"""OpenCV FileStorage calibrations (YAML or XML) in EasyMocap's layout.

Keys, for every camera ``<name>`` listed in ``names`` (a sequence of strings):

* ``K_<name>``: 3x3 camera matrix; ``dist_<name>`` (or ``D_<name>``): 1x4, 1x5 or longer distortion
  (coefficients beyond k1 k2 p1 p2 k3 must be zero);
* ``H_<name>``, ``W_<name>``: image height and width (optional: else ``sizes=``);
* ``R_<name>`` (Rodrigues 3x1, or a 3x3 matrix) and/or ``Rot_<name>`` (3x3), and ``T_<name>`` (3x1):
  ``x_cam = R x_world + T``.

Either one file holds everything, or EasyMocap's pair splits it: ``intri.yml`` (names, K, dist, H, W) and
``extri.yml`` (names, R, Rot, T), T in metres. A single file's length unit is its optional ``units`` key
(written by :func:`write_opencv`), else detected by the caller.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, FormatError
from swarmpose.io.calibration._common import (
    MM_PER_UNIT,
    RawCalibration,
    as_rotation,
    atomic_path,
    cam_field,
    camera_list,
    distortion5,
    intrinsics,
    make_camera,
    pick_size,
    require_file,
    rodrigues,
    rotation_from_rodrigues,
)

__all__ = ["read_opencv", "write_opencv", "write_easymocap"]

_NAME_OK = re.compile(r"^[A-Za-z0-9_-]+$")  # what FileStorage accepts in a key, YAML and XML alike
_AGREE_TOL = 1e-5  # R_ (Rodrigues) and Rot_ of one camera must give the same matrix


def _cv2():
    import cv2

    return cv2


def _open(path: Path):
    """A FileStorage open for reading, or a FormatError naming the file (and the line cv2 gives)."""
    cv2 = _cv2()
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:  # OpenCV 5 wraps its cv2.error in a SystemError
        text = str(exc.__cause__ or exc).strip()
        m = re.search(r"\((\d+)\): (.*?)'?$", text)
        reason = m.group(2) if m else text.splitlines()[-1] if text else type(exc).__name__
        raise FormatError(f"not an OpenCV FileStorage file ({reason})", path=path,
                          line=int(m.group(1)) if m else None) from None
    if not fs.isOpened():
        raise FormatError("cannot be opened as an OpenCV FileStorage file", path=path)
    return fs


def _missing(node) -> bool:
    return node.empty() or node.isNone()


def _numbers(node, path: Path, camera: str, key: str) -> list[float]:
    if node.isSeq():
        out: list[float] = []
        for i in range(node.size()):
            out += _numbers(node.at(i), path, camera, key)
        return out
    if node.isInt() or node.isReal():
        return [float(node.real())]
    raise cam_field(path, camera, key, "must hold numbers")


def _array(fs, path: Path, camera: str, key: str, required: bool = True) -> np.ndarray | None:
    """The matrix or number sequence at ``key`` (None when absent and not required)."""
    node = fs.getNode(key)
    if _missing(node):
        if required:
            raise cam_field(path, camera, key, f"missing field {key!r}")
        return None
    if node.isMap():
        try:
            m = node.mat()
        except Exception:  # cv2.error on a map that is not an !!opencv-matrix
            m = None
        if m is None:
            raise cam_field(path, camera, key, "is a map but not an OpenCV matrix (rows, cols, dt, data)")
        return np.asarray(m, dtype=np.float64)
    return np.asarray(_numbers(node, path, camera, key), dtype=np.float64)


def _int(fs, path: Path, camera: str, key: str) -> int | None:
    a = _array(fs, path, camera, key, required=False)
    if a is None:
        return None
    if a.size != 1 or a.ravel()[0] != round(a.ravel()[0]):
        raise cam_field(path, camera, key, f"must be a whole number, got {a.ravel().tolist()}")
    v = int(a.ravel()[0])
    return None if v == -1 else v  # EasyMocap writes -1 for an unknown size


def _names(fs, path: Path) -> list[str]:
    node = fs.getNode("names")
    if _missing(node):
        raise FormatError("missing field 'names' (the sequence of camera names)", path=path, field="names")
    items = [node.at(i) for i in range(node.size())] if node.isSeq() else [node]
    names = []
    for it in items:
        if it.isString():
            names.append(it.string())
        elif it.isInt():
            names.append(str(int(it.real())))
        else:
            raise FormatError("'names' must be a sequence of strings", path=path, field="names")
    if not names or any(not n for n in names):
        raise FormatError("'names' must list at least one non-empty camera name", path=path, field="names")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise FormatError(f"camera names must be unique, repeated: {dup}", path=path, field="names")
    return names


def _rotation(fs, path: Path, camera: str, notes: list[str], pair: bool) -> np.ndarray:
    r_vec = _array(fs, path, camera, f"R_{camera}", required=False)
    r_mat = _array(fs, path, camera, f"Rot_{camera}", required=False)
    if r_vec is None and r_mat is None:
        hint = "" if pair else " (for EasyMocap's intri.yml, pass extrinsics='extri.yml')"
        raise cam_field(path, camera, f"R_{camera}", f"missing field 'R_{camera}' (or 'Rot_{camera}'){hint}")
    from_vec = None
    if r_vec is not None:
        if r_vec.size == 9:
            from_vec = as_rotation(r_vec, path, camera, f"R_{camera}", notes)
        elif r_vec.size == 3:
            from_vec = rotation_from_rodrigues(r_vec, path, camera, f"R_{camera}")
        else:
            raise cam_field(path, camera, f"R_{camera}", f"must be a Rodrigues 3x1 vector or a 3x3 matrix, "
                            f"got shape {r_vec.shape}")
    if r_mat is None:
        return from_vec
    R = as_rotation(r_mat, path, camera, f"Rot_{camera}", notes)
    if from_vec is not None:
        diff = float(np.abs(R - from_vec).max())
        if diff > _AGREE_TOL:
            raise cam_field(path, camera, f"Rot_{camera}", f"disagrees with R_{camera} (max difference "
                            f"{diff:.3g}): which rotation is meant is unclear")
    return R


def read_opencv(path: str | os.PathLike[str], *, extrinsics: str | os.PathLike[str] | None = None,
                sizes: Mapping[str, Sequence[int]] | None = None) -> RawCalibration:
    """Read an OpenCV FileStorage calibration: one file, or EasyMocap's ``intri.yml`` + ``extri.yml``.

    Parameters
    ----------
    path : path-like
        The file holding everything, or ``intri.yml``.
    extrinsics : path-like, optional
        ``extri.yml`` of an EasyMocap pair (then T is in metres).
    sizes : mapping of name to (width, height), optional
        Image sizes for cameras without ``H_``/``W_`` (the file's size wins otherwise).

    Returns
    -------
    RawCalibration
        ``units`` is ``"m"`` for the pair, the file's ``units`` key if any, else None (to detect).

    Raises
    ------
    DataError
        A file does not exist.
    FormatError
        A file does not parse, or a field is missing or invalid (the message names file, camera, field).
    """
    p = require_file(path)
    intri = _open(p)
    pair = extrinsics is not None
    ep = require_file(extrinsics, "extrinsics file") if pair else p
    extri = _open(ep) if pair else intri
    names = _names(intri, p)
    notes: list[str] = []
    units = None
    if pair:
        units = "m"
        extra = sorted(set(_names(extri, ep)) - set(names)) if not _missing(extri.getNode("names")) else []
        if extra:
            notes.append(f"{ep.name} also lists {extra}, which {p.name} does not: ignored")
    else:
        node = intri.getNode("units")
        if not _missing(node):
            if not node.isString() or node.string() not in MM_PER_UNIT:
                raise FormatError(f"'units' must be one of {sorted(MM_PER_UNIT)}", path=p, field="units")
            units = node.string()
            notes.append(f"length unit {units!r}, as the file's 'units' key states it")
    cameras: list[Camera] = []
    stated_sizes: dict[str, tuple[int, int]] = {}
    for name in names:
        K = _array(intri, p, name, f"K_{name}")
        dkey = f"dist_{name}" if not _missing(intri.getNode(f"dist_{name}")) else f"D_{name}"
        if _missing(intri.getNode(dkey)):
            dkey = f"dist_{name}"
        dist = distortion5(_array(intri, p, name, dkey), p, name, dkey)
        h, w = _int(intri, p, name, f"H_{name}"), _int(intri, p, name, f"W_{name}")
        if (h is None) != (w is None):
            key = f"W_{name}" if w is None else f"H_{name}"
            raise cam_field(p, name, key, f"missing field {key!r} (the file gives only one of H_ and W_)")
        stated = None
        if h is not None and w is not None:
            if h <= 0 or w <= 0:
                raise cam_field(p, name, f"W_{name}", f"image size must be positive, got {w}x{h}")
            stated = stated_sizes[name] = (w, h)
        width, height = pick_size(name, stated, sizes, p, f"W_{name}", notes)
        R = _rotation(extri, ep, name, notes, pair)
        T = _array(extri, ep, name, f"T_{name}")
        if T.size != 3:
            raise cam_field(ep, name, f"T_{name}", f"must hold 3 numbers, got shape {T.shape}")
        if not np.isfinite(T).all():
            raise cam_field(ep, name, f"T_{name}", "must be finite")
        cameras.append(make_camera(p, name, width=width, height=height, **intrinsics(K, p, name, f"K_{name}"),
                                   dist=dist, R=R, t=T.reshape(3)))
    return RawCalibration(cameras=cameras, format="easymocap" if pair else "opencv",
                          paths=(p, ep) if pair else (p,), units=units, image_sizes=stated_sizes or None,
                          notes=notes)


# ---------------------------------------------------------------------- writing
def _check_names(cams: list[Camera]) -> None:
    bad = [c.name for c in cams if not _NAME_OK.match(c.name)]
    if bad:
        raise ConfigError(f"camera names {bad} cannot be OpenCV FileStorage keys (letters, digits, '_' and '-' "
                          "only)")


def _write_names(fs, cams: list[Camera]) -> None:
    cv2 = _cv2()
    fs.startWriteStruct("names", cv2.FileNode_SEQ)
    for c in cams:
        fs.write("", c.name)
    fs.endWriteStruct()


def _write_intrinsics(fs, c: Camera) -> None:
    fs.write(f"K_{c.name}", c.K)
    fs.write(f"dist_{c.name}", np.asarray(c.dist, dtype=np.float64)[None, :])
    fs.write(f"H_{c.name}", int(c.height))
    fs.write(f"W_{c.name}", int(c.width))


def _write_extrinsics(fs, c: Camera, mm_per_unit: float) -> None:
    fs.write(f"R_{c.name}", rodrigues(c.R)[:, None])
    fs.write(f"Rot_{c.name}", np.asarray(c.R, dtype=np.float64))
    fs.write(f"T_{c.name}", (np.asarray(c.t, dtype=np.float64) / mm_per_unit)[:, None])


def _storage(path: Path):
    cv2 = _cv2()
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    if not fs.isOpened():
        raise OSError(f"cannot write {path}")
    return fs


def write_opencv(path: str | os.PathLike[str], cameras: Iterable[Camera], *, units: str = "m") -> Path:
    """Write cameras to one OpenCV FileStorage file (YAML, or XML for a ``.xml`` name), atomically.

    Parameters
    ----------
    path : path-like
    cameras : iterable of Camera (or a Calibration)
    units : {"m", "cm", "mm"}
        Length unit of ``T_``; written as the file's ``units`` key, which :func:`read_opencv` reads.

    Returns
    -------
    pathlib.Path
    """
    if units not in MM_PER_UNIT:
        raise ConfigError(f"units must be one of {sorted(MM_PER_UNIT)}, got {units!r}")
    cams = camera_list(cameras)
    _check_names(cams)
    with atomic_path(path) as tmp:
        fs = _storage(tmp)
        _write_names(fs, cams)
        fs.write("units", units)
        for c in cams:
            _write_intrinsics(fs, c)
            _write_extrinsics(fs, c, MM_PER_UNIT[units])
        fs.release()
    return Path(path)


def write_easymocap(intri_path: str | os.PathLike[str], extri_path: str | os.PathLike[str],
                    cameras: Iterable[Camera]) -> tuple[Path, Path]:
    """Write EasyMocap's pair: ``intri.yml`` (names, K, dist 1x5, H, W) and ``extri.yml`` (names, R, Rot, T in m).

    Returns
    -------
    (pathlib.Path, pathlib.Path)
        The two files written (each through a temporary file and ``os.replace``).
    """
    cams = camera_list(cameras)
    _check_names(cams)
    if Path(intri_path).resolve() == Path(extri_path).resolve():
        raise ConfigError(f"intrinsics and extrinsics must be two files, got {intri_path} twice")
    with atomic_path(intri_path) as ti, atomic_path(extri_path) as te:
        fi, fe = _storage(ti), _storage(te)
        _write_names(fi, cams)
        _write_names(fe, cams)
        for c in cams:
            _write_intrinsics(fi, c)
            _write_extrinsics(fe, c, 1000.0)
        fi.release()
        fe.release()
    return Path(intri_path), Path(extri_path)
