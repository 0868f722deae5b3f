"""A 3D picture of a camera rig: every camera's viewing pyramid and name over a floor grid.

Drawn with matplotlib's Agg canvas directly (no ``pyplot``), so it works headless.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError
from swarmpose.report._style import count, rgb01

__all__ = ["plot_rig", "frustum_corners"]

# Okabe-Ito, as the error plots use
_COLOURS = [rgb01(c) for c in ((0, 114, 178), (213, 94, 0), (0, 158, 115), (204, 121, 167), (230, 159, 0),
                               (86, 180, 233), (120, 120, 120))]


def frustum_corners(cam: Camera, depth: float) -> np.ndarray:
    """World points (mm) of the image corners at ``depth`` mm along the optical axis, shape (4, 3).

    Order: top-left, top-right, bottom-right, bottom-left (pixel edges, distortion ignored).
    """
    u = np.array([-0.5, cam.width - 0.5, cam.width - 0.5, -0.5])
    v = np.array([-0.5, -0.5, cam.height - 0.5, cam.height - 0.5])
    b = (v - cam.cy) / cam.fy
    a = (u - cam.cx) / cam.fx - cam.skew * b
    xyz_cam = np.stack([a, b, np.ones(4)], axis=-1) * depth
    return cam.world_from_cam(xyz_cam)


def _grid_step(span_m: float) -> float:
    """A round grid spacing (m) giving about 4 to 10 cells over ``span_m``."""
    raw = max(span_m, 1e-3) / 8.0
    mag = 10.0 ** math.floor(math.log10(raw))
    for f in (1.0, 2.0, 5.0, 10.0):
        if raw <= f * mag:
            return f * mag
    return 10.0 * mag


def plot_rig(
    cameras: Iterable[Camera] | Any,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    floor_z: float = 0.0,
    depth: float | None = None,
    figsize: tuple[float, float] = (9.0, 6.5),
    dpi: float = 110,
) -> Path:
    """Draw the rig in 3D and save it as a PNG.

    Each camera is a pyramid from its optical centre to its image corners ``depth`` mm ahead, the image's
    top edge drawn thicker, with its name beside the centre, a dotted line down to the floor and its optical
    axis dashed to where it meets the floor; the floor is a grid at ``floor_z`` over a square around the
    cameras' ground projections. Axes in metres, equal aspect.

    Parameters
    ----------
    cameras : iterable of Camera, or a Calibration
        World mm, z up.
    path : path-like
        The PNG to write (folders are made).
    title : str, optional
        Default: the number of cameras.
    floor_z : float, default 0.0
        Height of the floor, mm.
    depth : float, optional
        Length of each pyramid, mm; default a tenth of the floor square's side, at least 400 mm.
    figsize, dpi :
        Inches and pixels per inch: the PNG is ``figsize * dpi`` pixels (990 x 715 by default).

    Returns
    -------
    pathlib.Path
        The PNG written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    cams = list(getattr(cameras, "cameras", cameras))
    if not cams:
        raise ConfigError("plot_rig needs at least one camera")
    if not all(isinstance(c, Camera) for c in cams):
        raise ConfigError("plot_rig expects Camera objects")
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    centres = np.stack([c.center for c in cams]) / 1000.0
    fz = floor_z / 1000.0
    # floor: a square around the ground projections, padded by a fifth of its size (at least 0.5 m)
    lo, hi = centres[:, :2].min(axis=0), centres[:, :2].max(axis=0)
    mid, half = (lo + hi) / 2.0, max(float((hi - lo).max()) / 2.0, 0.5)
    half = half + max(half / 5.0, 0.5)
    if depth is None:
        depth = max(400.0, 100.0 * round(2.0 * half))  # mm: about a tenth of the floor's side
    step = _grid_step(2 * half)
    g0 = np.floor((mid - half) / step) * step
    g1 = np.ceil((mid + half) / step) * step
    for x in np.arange(g0[0], g1[0] + step / 2, step):
        ax.plot([x, x], [g0[1], g1[1]], [fz, fz], color="0.65", lw=0.7)
    for y in np.arange(g0[1], g1[1] + step / 2, step):
        ax.plot([g0[0], g1[0]], [y, y], [fz, fz], color="0.65", lw=0.7)
    pts = [centres, np.array([[g0[0], g0[1], fz], [g1[0], g1[1], fz]])]
    for i, c in enumerate(cams):
        col = _COLOURS[i % len(_COLOURS)]
        o = centres[i]
        k = frustum_corners(c, depth) / 1000.0
        pts.append(k)
        for corner in k:
            ax.plot(*zip(o, corner, strict=True), color=col, lw=1.0)
        ring = np.vstack([k, k[:1]])
        ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=col, lw=1.0)
        ax.plot(k[:2, 0], k[:2, 1], k[:2, 2], color=col, lw=2.6)  # the image's top edge
        ax.plot([o[0], o[0]], [o[1], o[1]], [fz, o[2]], color=col, lw=0.6, ls=":")  # down to the floor
        d = np.asarray(c.R)[2]  # the optical axis, dashed down to where it meets the floor
        if d[2] < -1e-6:
            hit = o + d * (fz - o[2]) / d[2]
            if np.all(np.abs(hit[:2] - mid) <= 2 * half):
                ax.plot(*zip(o, hit, strict=True), color=col, lw=0.8, ls="--")
        ax.scatter([o[0]], [o[1]], [o[2]], color=col, s=14, depthshade=False)
        ax.text(o[0], o[1], o[2] + 0.15 * depth / 400.0, c.name, color=col, fontsize=9, ha="center",
                va="bottom")
    allp = np.vstack(pts)
    p0, p1 = allp.min(axis=0), allp.max(axis=0)
    p1 = np.maximum(p1, p0 + 0.1)
    ax.set_xlim(p0[0], p1[0])
    ax.set_ylim(p0[1], p1[1])
    ax.set_zlim(p0[2], p1[2])
    ax.set_box_aspect(tuple(p1 - p0), zoom=1.15)  # equal aspect: one metre is as long on every axis
    ax.zaxis.set_major_locator(MaxNLocator(3))
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.pane.set_alpha(0.0)
    ax.grid(False)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.view_init(elev=28.0, azim=-60.0)
    ax.set_title(title if title is not None else f"Camera rig: {count(len(cams), 'camera')} "
                 f"(pyramids {depth:g} mm deep, floor grid {step:g} m)", fontsize=11)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi, format="png")
    return out
