"""What the calibration readers and writers share: the result types, field checks and atomic writes."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.camera import Camera, unique_cameras
from swarmpose.errors import ConfigError, DataError, FormatError

__all__ = ["Calibration", "RawCalibration", "MM_PER_UNIT"]

#: Millimetres in one file unit.
MM_PER_UNIT: dict[str, float] = {"m": 1000.0, "cm": 10.0, "mm": 1.0}

_ROTATION_TOL = 1e-6  # Camera's own tolerance
_NEAR_ROTATION_TOL = 1e-3  # a rotation written with few digits is projected back (with a note)

Size = tuple[int, int]


@dataclass
class Calibration:
    """Cameras read from a calibration file, in swarmpose's world (millimetres, right-handed, z up).

    Attributes
    ----------
    cameras : list of Camera
        In file order; ``t`` in mm, world rotated so that the file's up axis is +z.
    format : str
        ``"toml"``, ``"qualisys"``, ``"opencv"`` or ``"easymocap"``.
    paths : tuple of Path
        The file(s) read (the EasyMocap pair: ``intri.yml``, ``extri.yml``).
    units : str
        The file's length unit as read: ``"m"``, ``"cm"`` or ``"mm"``.
    units_source : str
        ``"format"`` (the format or the file states it), ``"stated"`` (``units=``) or ``"detected"``.
    up : str
        The file's up axis, ``"+x"`` ... ``"-z"``.
    up_source : str
        ``"stated"`` (``up=``) or ``"detected"`` (from the cameras' image-up directions).
    world_from_file : numpy.ndarray, shape (4, 4)
        The rotation applied to the file's world, acting on millimetres:
        ``x_world = world_from_file @ (x_file * mm_per_unit, 1)``. Its inverse maps results back.
    image_sizes : dict of str to (int, int), or None
        ``(width, height)`` per camera where the file states them.
    notes : list of str
        What was assumed or detected, in plain words.
    """

    cameras: list[Camera]
    format: str
    paths: tuple[Path, ...]
    units: str
    units_source: str
    up: str
    up_source: str
    world_from_file: np.ndarray
    image_sizes: dict[str, Size] | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def names(self) -> list[str]:
        """The camera names in file order."""
        return [c.name for c in self.cameras]

    @property
    def mm_per_unit(self) -> float:
        """Millimetres in one of the file's length units."""
        return MM_PER_UNIT[self.units]

    @property
    def file_from_world(self) -> np.ndarray:
        """Inverse of :attr:`world_from_file` (still millimetres), shape (4, 4)."""
        return np.linalg.inv(self.world_from_file)

    def camera(self, name: str) -> Camera:
        """The camera called ``name`` (``KeyError`` naming the known ones otherwise)."""
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(f"no camera {name!r} in {', '.join(map(str, self.paths))} (cameras: {self.names})")


@dataclass
class RawCalibration:
    """What a family reader returns: cameras in the file's own units (``t``) and world frame."""

    cameras: list[Camera]
    format: str
    paths: tuple[Path, ...]
    units: str | None  # stated by the format or the file; None: to detect
    image_sizes: dict[str, Size] | None
    notes: list[str]


def require_file(path: str | os.PathLike[str], what: str = "calibration file") -> Path:
    """``path`` as a Path, or a :class:`DataError` naming it when it is not a file."""
    p = Path(path)
    if not p.exists():
        raise DataError(f"{what} {p} does not exist")
    if not p.is_file():
        raise DataError(f"{what} {p} is not a file")
    return p


def cam_field(path: Path, camera: str, fld: str, message: str) -> FormatError:
    """A FormatError naming the file, the camera and the field."""
    return FormatError(f"camera {camera!r}: {message}", path=path, field=fld)


def as_array(value: Any, path: Path, camera: str, fld: str, size: int | None = None) -> np.ndarray:
    """``value`` as a finite float64 array (flattened to ``size`` elements when given)."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise cam_field(path, camera, fld, f"must be numbers, got {value!r}") from None
    if size is not None:
        if a.size != size:
            raise cam_field(path, camera, fld, f"must hold {size} numbers, got shape {a.shape}")
        a = a.reshape(size)
    if not np.isfinite(a).all():
        raise cam_field(path, camera, fld, "must be finite numbers")
    return a


def as_rotation(m: Any, path: Path, camera: str, fld: str, notes: list[str]) -> np.ndarray:
    """A 3x3 rotation from the file, checked: det +1 and orthonormal.

    Off by at most 1e-3 (a matrix written with few digits): projected onto the nearest rotation, with a
    note. Further off, or a reflection: a :class:`FormatError` naming the field.
    """
    R = as_array(m, path, camera, fld)
    if R.size != 9:
        raise cam_field(path, camera, fld, f"must be a 3x3 matrix, got shape {R.shape}")
    R = R.reshape(3, 3)
    ortho = float(np.abs(R @ R.T - np.eye(3)).max())
    det = float(np.linalg.det(R))
    if det <= 0 or ortho > _NEAR_ROTATION_TOL:
        raise cam_field(path, camera, fld, f"is not a rotation matrix (det {det:.6g}, max |R R^T - I| = "
                        f"{ortho:.3g})")
    if ortho > _ROTATION_TOL or abs(det - 1.0) > _ROTATION_TOL:
        u, _, vt = np.linalg.svd(R)
        R = u @ vt
        notes.append(f"camera {camera!r}: {fld} was not orthonormal to 1e-6 (max |R R^T - I| = {ortho:.2g}); "
                     "the nearest rotation is used")
    return R


def rotation_from_rodrigues(v: Any, path: Path, camera: str, fld: str) -> np.ndarray:
    """Rotation matrix of a Rodrigues vector (axis times angle in radians), shape (3,) -> (3, 3)."""
    from scipy.spatial.transform import Rotation

    rv = as_array(v, path, camera, fld, size=3)
    return Rotation.from_rotvec(rv).as_matrix()


def rodrigues(R: np.ndarray) -> np.ndarray:
    """Rodrigues vector of a rotation matrix (accurate near 180 degrees, unlike a trace formula)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, dtype=np.float64)).as_rotvec()


def distortion5(values: Any, path: Path, camera: str, fld: str) -> tuple[float, float, float, float, float]:
    """``(k1, k2, p1, p2, k3)`` from 4, 5 or more OpenCV coefficients; those beyond 5 must be zero."""
    d = as_array(values, path, camera, fld).ravel()
    if d.size < 4:
        raise cam_field(path, camera, fld, f"needs at least 4 coefficients (k1 k2 p1 p2), got {d.size}")
    if d.size > 5 and np.any(d[5:] != 0):
        raise cam_field(path, camera, fld, f"has {d.size} coefficients and those beyond k1 k2 p1 p2 k3 are not "
                        f"zero ({d[5:].tolist()}): only the 5-coefficient model is supported")
    d5 = np.zeros(5)
    d5[: min(5, d.size)] = d[:5]
    return (float(d5[0]), float(d5[1]), float(d5[2]), float(d5[3]), float(d5[4]))


def intrinsics(K: Any, path: Path, camera: str, fld: str) -> dict[str, float]:
    """``fx, fy, cx, cy, skew`` of a 3x3 camera matrix ``[[fx, s fx, cx], [0, fy, cy], [0, 0, 1]]``."""
    k = as_array(K, path, camera, fld)
    if k.size != 9:
        raise cam_field(path, camera, fld, f"must be a 3x3 matrix, got shape {k.shape}")
    k = k.reshape(3, 3)
    if k[1, 0] != 0 or k[2, 0] != 0 or k[2, 1] != 0 or k[2, 2] != 1:
        raise cam_field(path, camera, fld, f"is not a camera matrix (rows 2 and 3 must be [0 fy cy] and "
                        f"[0 0 1]), got {k.tolist()}")
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise cam_field(path, camera, fld, f"focal lengths must be > 0, got fx={k[0, 0]!r} fy={k[1, 1]!r}")
    return {"fx": float(k[0, 0]), "fy": float(k[1, 1]), "cx": float(k[0, 2]), "cy": float(k[1, 2]),
            "skew": float(k[0, 1] / k[0, 0])}


def image_size(value: Any, path: Path, camera: str, fld: str) -> Size:
    """``(width, height)`` from two positive whole numbers (``1088.0`` is fine)."""
    a = as_array(value, path, camera, fld, size=2)
    if np.any(a <= 0) or np.any(a != np.round(a)):
        raise cam_field(path, camera, fld, f"must be two positive whole numbers (width, height), got {a.tolist()}")
    return (int(a[0]), int(a[1]))


def pick_size(camera: str, stated: Size | None, sizes: Mapping[str, Sequence[int]] | None, path: Path,
              fld: str, notes: list[str]) -> Size:
    """The image size of a camera: the file's, else the caller's ``sizes``, else a FormatError."""
    given = None
    if sizes is not None and camera in sizes:
        g = sizes[camera]
        try:
            ok = len(g) == 2 and all(not isinstance(v, bool) and int(v) == v and v > 0 for v in g)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ConfigError(f"sizes[{camera!r}] must be (width, height) in pixels, got {g!r}")
        given = (int(g[0]), int(g[1]))
    if stated is not None:
        if given is not None and given != stated:
            notes.append(f"camera {camera!r}: the file gives the image size {stated[0]}x{stated[1]}, sizes= "
                         f"gives {given[0]}x{given[1]}; the file's size is used")
        return stated
    if given is not None:
        notes.append(f"camera {camera!r}: image size {given[0]}x{given[1]} from sizes= (the file has none)")
        return given
    raise cam_field(path, camera, fld, "the image size is missing (the file does not give it: pass "
                    "sizes={name: (width, height)}, e.g. from the videos)")


def make_camera(path: Path, camera: str, **kwargs: Any) -> Camera:
    """``Camera(name=camera, **kwargs)``, its ConfigError turned into a FormatError naming the file."""
    try:
        return Camera(name=camera, **kwargs)
    except ConfigError as exc:
        raise FormatError(str(exc), path=path, field=getattr(exc, "field", None)) from exc


def camera_list(cameras: Any) -> list[Camera]:
    """A writer's cameras: a Calibration or Camera objects with unique names."""
    cams = unique_cameras(cameras.cameras if isinstance(cameras, Calibration) else cameras, "a calibration writer")
    if not cams:
        raise ConfigError("no cameras to write")
    return cams


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) that replaces ``path`` when the block succeeds.

    On an error the temporary file is removed and ``path`` is left as it was.
    """
    dst = Path(path)
    dst.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=dst.parent, prefix=f".{dst.name}.", suffix=f".tmp{dst.suffix}")
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        os.chmod(tmp_path, dst.stat().st_mode & 0o777 if dst.exists() else 0o644)  # mkstemp makes it 0600
        yield tmp_path
        os.replace(tmp_path, dst)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` through a temporary file and ``os.replace``."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
