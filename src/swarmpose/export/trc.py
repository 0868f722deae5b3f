"""Export tracked joints as an OpenSim marker file (TRC, "track row column").

The file holds one marker per joint (default: the 15 joints of :data:`swarmpose.joints.JOINTS15`),
tab-separated, in OpenSim's layout (that of its ``TRCFileAdapter``)::

    PathFileType<TAB>4<TAB>(X/Y/Z)<TAB>motion.trc
    DataRate<TAB>CameraRate<TAB>NumFrames<TAB>NumMarkers<TAB>Units<TAB>OrigDataRate<TAB>OrigDataStartFrame<TAB>OrigNumFrames
    20<TAB>20<TAB>6<TAB>15<TAB>mm<TAB>20<TAB>1<TAB>6
    Frame#<TAB>Time<TAB>thorax<TAB><TAB><TAB>pelvis<TAB><TAB><TAB>...
    <TAB><TAB>X1<TAB>Y1<TAB>Z1<TAB>X2<TAB>Y2<TAB>Z2<TAB>...
    (a blank line)
    1<TAB>0.000000<TAB>x<TAB>y<TAB>z<TAB>...

Frame numbers start at 1; the ``Time`` column holds the given frame times (seconds); every value is
followed by a tab, as OpenSim writes it. A marker that is missing in a frame (any coordinate not
finite) has three empty fields there, which OpenSim reads as NaN.

Axes
----
The swarmpose world is right-handed, millimetres, **Z up** (x forward, y to the subject's left in
the model's zero pose). OpenSim's ground frame is **Y up** (X forward, Z to the right in its models'
default pose, as Pose2Sim writes it), so every point is written as::

    trc = (x, z, -y)        (a rotation of -90 degrees about x; its inverse is world = (x, -z, y))

and the model's zero pose faces +X with its right side on +Z, as OpenSim's models stand.

the same mapping as the default BVH export (:func:`swarmpose.export.bvh_axes`). TRC has no comment
line, so the file itself does not state it. ``units="m"`` divides every coordinate by 1000 and
writes ``m`` in the ``Units`` field.

:func:`read_trc` is a plain parser of such files (and of other TRC files in OpenSim's layout): it
returns the marker names, the times, the points in the file's own units and axes, and the header.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from swarmpose.errors import ConfigError, FormatError, ShapeError
from swarmpose.export.bvh_export import bvh_axes
from swarmpose.joints import JOINTS15

__all__ = ["write_trc", "read_trc", "TrcData", "TRC_FROM_WORLD", "TRC_UNITS", "TRC_HEADER_KEYS", "frame_rate_of"]

#: ``trc = TRC_FROM_WORLD @ world``: (x, y, z) -> (x, z, -y), Z up to OpenSim's Y up.
TRC_FROM_WORLD: np.ndarray = bvh_axes(y_up=True)
#: Units :func:`write_trc` writes, with the file units per millimetre.
TRC_UNITS: dict[str, float] = {"mm": 1.0, "m": 0.001}
#: The fields of the second header line, in OpenSim's order.
TRC_HEADER_KEYS: tuple[str, ...] = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units", "OrigDataRate",
                                    "OrigDataStartFrame", "OrigNumFrames")
_INT_KEYS = ("NumFrames", "NumMarkers", "OrigDataStartFrame", "OrigNumFrames")
_FLOAT_KEYS = ("DataRate", "CameraRate", "OrigDataRate")


class TrcData(NamedTuple):
    """What :func:`read_trc` returns (a tuple: ``names, times, points, header = read_trc(path)``)."""

    names: list[str]
    """Marker names, in column order."""
    times: np.ndarray
    """``(T,)`` the ``Time`` column, seconds."""
    points: np.ndarray
    """``(T, M, 3)`` in the file's units and axes; NaN where a marker is missing."""
    header: dict[str, Any]
    """``PathFileType``, ``DataFormat``, ``FileName`` (first line) and the fields of :data:`TRC_HEADER_KEYS`
    (rates float, counts int, ``Units`` str)."""


def frame_rate_of(times: np.ndarray, frame_rate: float | None = None) -> float:
    """The frame rate to write: ``frame_rate`` when given, else ``1 / median interval`` of ``times``.

    Raises :class:`ConfigError` for a non-positive rate, or when ``times`` has fewer than two frames and no
    rate is given.
    """
    if frame_rate is not None:
        rate = float(frame_rate)
        if not (np.isfinite(rate) and rate > 0):
            raise ConfigError(f"frame_rate must be > 0, got {frame_rate!r}")
        return rate
    t = np.asarray(times, dtype=np.float64)
    if t.size < 2:
        raise ConfigError("one frame has no frame rate: give frame_rate")
    return float(1.0 / np.median(np.diff(t)))


def check_motion(joints, times, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """``joints`` as ``(T, M, 3)`` float64, ``times`` as ``(T,)`` (finite, increasing) and the names as a list."""
    P = np.asarray(joints, dtype=np.float64)
    names = [str(n) for n in names]
    if P.ndim != 3 or P.shape[2] != 3:
        raise ShapeError(f"joints must be (T, M, 3), got shape {P.shape}")
    if P.shape[0] < 1:
        raise ConfigError("joints has no frames to export")
    if P.shape[1] != len(names):
        raise ShapeError(f"joints has {P.shape[1]} markers but {len(names)} names were given")
    bad = [n for n in names if not n.strip() or any(c in n for c in "\t\r\n")]
    if bad or len(set(names)) != len(names):
        raise ConfigError(f"marker names must be distinct, non-empty and without tabs or line breaks: {names}")
    t = np.asarray(times, dtype=np.float64)
    if t.shape != (P.shape[0],):
        raise ShapeError(f"times must hold {P.shape[0]} times (one per frame), got shape {t.shape}")
    if not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise ConfigError("times must be finite and increasing (seconds)")
    return P, t, names


def atomic_target(path: str | os.PathLike[str], suffix: str) -> tuple[Path, Path]:
    """``(final path, temporary path beside it)``: write the temporary file, then :func:`os.replace` it."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return out, out.with_name(f".{out.name}.{os.getpid()}.tmp{suffix}")  # same folder: os.replace is atomic


def _number(x: float) -> str:
    """A rate or a count as short text: ``20``, ``29.97``."""
    return f"{x:.10g}"


def write_trc(
    path: str | os.PathLike[str],
    joints: np.ndarray,
    times: np.ndarray,
    *,
    names: Sequence[str] = JOINTS15,
    units: str = "mm",
    frame_rate: float | None = None,
) -> Path:
    """Write joints as an OpenSim TRC marker file (layout and axes: see the module docstring).

    Parameters
    ----------
    path : path-like
        The ``.trc`` file to write (parent folders are created; written to a temporary file beside it
        and moved into place, so a failed write leaves no partial file).
    joints : numpy.ndarray, shape (T, M, 3)
        Positions in the swarmpose world: millimetres, Z up. Non-finite coordinates mark a missing
        marker (written as empty fields).
    times : numpy.ndarray, shape (T,)
        Frame times in seconds, increasing: the ``Time`` column.
    names : sequence of str, default JOINTS15
        The M marker names.
    units : {"mm", "m"}, default "mm"
        Length unit of the file.
    frame_rate : float, optional
        ``DataRate``, ``CameraRate`` and ``OrigDataRate``; by default ``1 / median(diff(times))``.
        The rows keep ``times`` as given either way: put uneven frames on an even clock first with
        :func:`swarmpose.export.uniform_clock` if the rate must describe every interval.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ShapeError
        ``joints`` is not ``(T, M, 3)`` with one name per marker and one time per frame.
    ConfigError
        No frames, an unknown unit, times not increasing, a bad name or frame rate.
    """
    if units not in TRC_UNITS:
        raise ConfigError(f"TRC units must be one of {', '.join(TRC_UNITS)}, got {units!r}")
    P, t, names = check_motion(joints, times, names)
    rate = frame_rate_of(t, frame_rate)
    T, M = P.shape[:2]
    pts = np.einsum("ab,tmb->tma", TRC_FROM_WORLD, P) * TRC_UNITS[units] + 0.0  # + 0.0: no "-0.000000"
    decimals = 6 if units == "mm" else 9  # a micrometre either way
    out, tmp = atomic_target(path, ".trc")
    header = [
        "\t".join(("PathFileType", "4", "(X/Y/Z)", out.name)),
        "\t".join(TRC_HEADER_KEYS),
        "\t".join((_number(rate), _number(rate), str(T), str(M), units, _number(rate), "1", str(T))),
        "Frame#\tTime\t" + "".join(f"{n}\t\t\t" for n in names),
        "\t\t" + "".join(f"X{k}\tY{k}\tZ{k}\t" for k in range(1, M + 1)),
        "",
    ]
    missing = ~np.isfinite(pts).all(axis=2)  # (T, M)
    fmt = f"{{:.{decimals}f}}"
    try:
        with tmp.open("w", encoding="utf-8", newline="\n") as fh:
            fh.write("\n".join(header) + "\n")
            for k in range(T):
                fields = [str(k + 1), f"{t[k]:.6f}"]
                for m in range(M):
                    fields += ["", "", ""] if missing[k, m] else [fmt.format(v) for v in pts[k, m]]
                fh.write("\t".join(fields) + "\t\n")
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out


def _cells(line: str) -> list[str]:
    return line.rstrip("\r\n").split("\t")


def read_trc(path: str | os.PathLike[str]) -> TrcData:
    """Read a TRC marker file in OpenSim's layout (as :func:`write_trc` writes it).

    Parameters
    ----------
    path : path-like
        The ``.trc`` file.

    Returns
    -------
    TrcData
        ``(names, times, points, header)``: points ``(T, M, 3)`` in the file's units and axes (no
        conversion), NaN where a marker's fields are empty.

    Raises
    ------
    DataError
        The file cannot be read.
    FormatError
        The header is not OpenSim's, or a row has the wrong number of fields or a non-number.
    """
    from swarmpose.errors import DataError

    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise DataError(f"{p}: cannot read ({exc.strerror or exc})") from exc
    except UnicodeDecodeError as exc:
        raise FormatError("not a text file", path=p) from exc
    if len(lines) < 5:
        raise FormatError(f"{len(lines)} lines; a TRC file has 5 header lines", path=p)
    first = lines[0].split()
    if not first or first[0] != "PathFileType":
        raise FormatError("the first line does not start with PathFileType", path=p, line=1)
    header: dict[str, Any] = {"PathFileType": first[1] if len(first) > 1 else "",
                              "DataFormat": first[2] if len(first) > 2 else "",
                              "FileName": " ".join(first[3:])}
    keys = [c.strip() for c in _cells(lines[1]) if c.strip()]
    if tuple(keys) != TRC_HEADER_KEYS:
        raise FormatError(f"header fields {keys}, expected {list(TRC_HEADER_KEYS)}", path=p, line=2)
    values = [c.strip() for c in _cells(lines[2]) if c.strip()]
    if len(values) != len(keys):
        raise FormatError(f"{len(values)} header values for {len(keys)} fields", path=p, line=3)
    for key, value in zip(keys, values, strict=True):
        try:
            header[key] = int(value) if key in _INT_KEYS else float(value) if key in _FLOAT_KEYS else value
        except ValueError as exc:
            raise FormatError(f"{value!r} is not a number", path=p, line=3, field=key) from exc
    labels = [c.strip() for c in _cells(lines[3]) if c.strip()]
    if labels[:2] != ["Frame#", "Time"]:
        raise FormatError(f"the column labels start with {labels[:2]}, expected ['Frame#', 'Time']", path=p, line=4)
    names = labels[2:]
    M = len(names)
    if M != header["NumMarkers"]:
        raise FormatError(f"{M} marker names but NumMarkers is {header['NumMarkers']}", path=p, line=4)
    xyz = [c.strip() for c in _cells(lines[4]) if c.strip()]
    expected = [f"{a}{k}" for k in range(1, M + 1) for a in "XYZ"]
    if xyz != expected:
        raise FormatError("the coordinate labels are not X1 Y1 Z1 X2 ...", path=p, line=5)
    times: list[float] = []
    rows: list[np.ndarray] = []
    for i in range(5, len(lines)):
        cells = _cells(lines[i])
        if not any(c.strip() for c in cells):
            continue  # the blank line after the header (and any at the end)
        cells = [c.strip() for c in cells]
        while len(cells) > 2 + 3 * M and cells[-1] == "":  # the tab after the last value
            cells.pop()
        if len(cells) > 2 + 3 * M:
            raise FormatError(f"{len(cells)} fields, expected {2 + 3 * M}", path=p, line=i + 1)
        cells += [""] * (2 + 3 * M - len(cells))  # missing last markers written without their tabs
        try:
            times.append(float(cells[1]))
            rows.append(np.array([float(c) if c else np.nan for c in cells[2:]], dtype=np.float64))
        except ValueError as exc:
            raise FormatError(f"a field is not a number: {exc}", path=p, line=i + 1) from exc
    points = np.array(rows, dtype=np.float64).reshape(len(rows), M, 3)
    # a marker is there or not: one empty coordinate makes the point missing (as OpenSim reads it)
    points[~np.isfinite(points).all(axis=2)] = np.nan
    return TrcData(names=names, times=np.array(times, dtype=np.float64), points=points, header=header)
