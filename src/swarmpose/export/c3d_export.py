"""Export tracked joints as a C3D file, the biomechanics lab format (Vicon, Qualisys, Mokka, OpenSim).

The file is written with `ezc3d <https://github.com/pyomeca/ezc3d>`_ (the C3D library OpenSim itself
reads C3D with), an optional dependency: ``pip install 'swarmpose[export]'``.

Contents
--------
* one 3D point per joint, labelled with its name (default: :data:`swarmpose.joints.JOINTS15`),
  stored as 32-bit floats (``POINT:SCALE`` -1), one frame per tracked frame;
* ``POINT:RATE`` the frame rate, ``POINT:UNITS`` ``mm``; the first frame is frame 1. C3D has one
  rate and no time per frame, so frames are taken to be ``1 / rate`` apart: put uneven frames on an
  even clock first (:func:`swarmpose.export.uniform_clock`; ``swarmpose export`` does by default);
* a missing point (any coordinate not finite) has coordinates 0 and residual -1, C3D's mark of an
  invalid point; a present point has residual 0 (valid, no residual computed);
* no analog channels; ``MANUFACTURER:SOFTWARE`` names swarmpose.

Axes
----
The points stay in the swarmpose world: right-handed, millimetres, **Z up** (x forward, y to the
subject's left in the model's zero pose), the usual frame of a C3D lab. ``POINT:X_SCREEN`` ``+X``
and ``POINT:Y_SCREEN`` ``+Z`` tell viewers so (horizontal X, vertical Z).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.export.trc import atomic_target, check_motion, frame_rate_of
from swarmpose.joints import JOINTS15

__all__ = ["write_c3d", "C3D_INSTALL", "require_ezc3d"]

#: What to run when ezc3d is missing.
C3D_INSTALL = "pip install 'swarmpose[export]' (or pip install ezc3d)"


def require_ezc3d():
    """The ``ezc3d`` module; :class:`ConfigError` naming the install command when it is missing."""
    try:
        import ezc3d
    except ImportError as exc:
        raise ConfigError(f"writing C3D needs the ezc3d package: {C3D_INSTALL}") from exc
    return ezc3d


def write_c3d(
    path: str | os.PathLike[str],
    joints: np.ndarray,
    times: np.ndarray,
    *,
    names: Sequence[str] = JOINTS15,
    frame_rate: float | None = None,
) -> Path:
    """Write joints as a C3D file of labelled 3D points (contents and axes: see the module docstring).

    Parameters
    ----------
    path : path-like
        The ``.c3d`` file to write (parent folders are created; written to a temporary file beside it
        and moved into place, so a failed write leaves no partial file).
    joints : numpy.ndarray, shape (T, M, 3)
        Positions in the swarmpose world: millimetres, Z up. Non-finite coordinates mark a missing
        point (residual -1).
    times : numpy.ndarray, shape (T,)
        Frame times in seconds, increasing; used for the rate when ``frame_rate`` is not given.
    names : sequence of str, default JOINTS15
        The M point labels.
    frame_rate : float, optional
        ``POINT:RATE``; by default ``1 / median(diff(times))``.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ShapeError
        ``joints`` is not ``(T, M, 3)`` with one name per point and one time per frame.
    ConfigError
        ezc3d is not installed (the message says how to install it); no frames, times not increasing,
        a bad name or frame rate.
    """
    from swarmpose import __version__

    P, t, names = check_motion(joints, times, names)
    rate = frame_rate_of(t, frame_rate)
    ezc3d = require_ezc3d()
    T, M = P.shape[:2]
    valid = np.isfinite(P).all(axis=2)  # (T, M)
    points = np.ones((4, M, T), dtype=np.float64)
    points[:3] = np.where(valid[..., None], P, 0.0).transpose(2, 1, 0)
    c = ezc3d.c3d()
    point = c["parameters"]["POINT"]
    point["RATE"]["value"] = [rate]
    point["UNITS"]["value"] = ["mm"]
    point["LABELS"]["value"] = list(names)
    c.add_parameter("POINT", "X_SCREEN", ["+X"])
    c.add_parameter("POINT", "Y_SCREEN", ["+Z"])
    c.add_parameter("MANUFACTURER", "COMPANY", ["swarmpose"])
    c.add_parameter("MANUFACTURER", "SOFTWARE", ["swarmpose"])
    c.add_parameter("MANUFACTURER", "VERSION_LABEL", [str(__version__)])
    c["data"]["points"] = points
    c["data"]["meta_points"] = {"residuals": np.where(valid.T, 0.0, -1.0)[None]}
    out, tmp = atomic_target(path, ".c3d")  # ezc3d adds .c3d to a name without it
    try:
        c.write(str(tmp))
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    return out
