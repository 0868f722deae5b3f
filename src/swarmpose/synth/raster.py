"""A z-buffered triangle rasteriser (numba, CPU; no OpenGL context).

Triangles are filled at pixel centres (pixel ``(u, v)`` is ``image[v, u]``, ``(0, 0)`` the centre of
the top-left pixel, as everywhere in swarmpose). Vertices are projected by
:meth:`swarmpose.camera.Camera.project_with_depth`, i.e. *with* lens distortion; triangle edges
are straight between the distorted vertices, which is exact to a fraction of a pixel for the
small triangles of the observation body. Depth and the shading attribute are interpolated
perspective-correctly (linear in ``1/z``). Back faces (clockwise on screen for outward,
counter-clockwise meshes) are skipped when ``cull_backfaces`` is set, which is exact for closed
meshes.

Per view the rasteriser returns a depth buffer (mm along the optical axis, ``inf`` where empty), the
interpolated shading and the index of the frontmost part (``-1`` = background): the exact
foreground mask is ``part >= 0``.

Shape letters: ``C`` views, ``V`` vertices, ``F`` triangles, ``H, W`` pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ShapeError

__all__ = ["RasterResult", "rasterize", "project_vertices"]

_NEAR_MM = 10.0


@dataclass(frozen=True)
class RasterResult:
    """Output of :func:`rasterize` for ``C`` views.

    Attributes
    ----------
    depth : numpy.ndarray, shape (C, H, W), float32
        Depth of the frontmost surface along the optical axis, mm; ``inf`` on background.
    shade : numpy.ndarray, shape (C, H, W), float32
        Interpolated vertex attribute (the grey level) of the frontmost surface; 0 on background.
    part : numpy.ndarray, shape (C, H, W), int16
        Part index of the frontmost surface; -1 on background.
    """

    depth: np.ndarray
    shade: np.ndarray
    part: np.ndarray

    @property
    def masks(self) -> np.ndarray:
        """Exact foreground masks ``(C, H, W)`` uint8 in ``{0, 1}``."""
        return (self.part >= 0).astype(np.uint8)


@nb.njit(cache=True, nogil=True)
def _raster_view(uv, z, attr, faces, face_part, cull, depth, shade, part):  # pragma: no cover - numba
    H, W = depth.shape
    for f in range(faces.shape[0]):
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        z0, z1, z2 = z[i0], z[i1], z[i2]
        if z0 <= _NEAR_MM or z1 <= _NEAR_MM or z2 <= _NEAR_MM:
            continue
        x0, y0 = uv[i0, 0], uv[i0, 1]
        x1, y1 = uv[i1, 0], uv[i1, 1]
        x2, y2 = uv[i2, 0], uv[i2, 1]
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        if area == 0.0 or not np.isfinite(area):
            continue
        # outward CCW triangles facing the camera have area < 0 in (u right, v down) pixels
        if cull and area > 0.0:
            continue
        xmin = max(int(np.ceil(min(x0, min(x1, x2)))), 0)
        xmax = min(int(np.floor(max(x0, max(x1, x2)))), W - 1)
        ymin = max(int(np.ceil(min(y0, min(y1, y2)))), 0)
        ymax = min(int(np.floor(max(y0, max(y1, y2)))), H - 1)
        if xmin > xmax or ymin > ymax:
            continue
        inv_area = 1.0 / area
        iz0, iz1, iz2 = 1.0 / z0, 1.0 / z1, 1.0 / z2
        a0, a1, a2 = attr[i0] * iz0, attr[i1] * iz1, attr[i2] * iz2
        p = face_part[f]
        for y in range(ymin, ymax + 1):
            for x in range(xmin, xmax + 1):
                # barycentric weights from edge functions
                w0 = ((x1 - x) * (y2 - y) - (y1 - y) * (x2 - x)) * inv_area
                w1 = ((x2 - x) * (y0 - y) - (y2 - y) * (x0 - x)) * inv_area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                iz = w0 * iz0 + w1 * iz1 + w2 * iz2  # 1/z is linear in screen space
                d = 1.0 / iz
                if d < depth[y, x]:
                    depth[y, x] = d
                    shade[y, x] = (w0 * a0 + w1 * a1 + w2 * a2) * d
                    part[y, x] = p


@nb.njit(cache=True, parallel=True)
def _raster_views(uv, z, attr, faces, face_part, cull, depth, shade, part):  # pragma: no cover - numba
    for c in nb.prange(uv.shape[0]):
        _raster_view(uv[c], z[c], attr, faces, face_part, cull, depth[c], shade[c], part[c])


def project_vertices(vertices: np.ndarray, cameras: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray]:
    """Project mesh vertices into every camera.

    Parameters
    ----------
    vertices : numpy.ndarray, shape (V, 3)
        World mm.
    cameras : sequence of C Camera

    Returns
    -------
    uv : numpy.ndarray, shape (C, V, 2)
        Pixels (with distortion).
    z : numpy.ndarray, shape (C, V)
        Depth along each optical axis, mm.
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ShapeError(f"vertices must have shape (V, 3), got {v.shape}")
    uv = np.empty((len(cameras), v.shape[0], 2))
    z = np.empty((len(cameras), v.shape[0]))
    for c, cam in enumerate(cameras):
        uv[c], z[c] = cam.project_with_depth(v)
    return uv, z


def rasterize(
    uv: np.ndarray,
    z: np.ndarray,
    attr: np.ndarray,
    faces: np.ndarray,
    face_part: np.ndarray,
    height: int,
    width: int,
    *,
    cull_backfaces: bool = True,
) -> RasterResult:
    """Z-buffer rasterisation of one triangle mesh into ``C`` views (views run in parallel).

    Parameters
    ----------
    uv : numpy.ndarray, shape (C, V, 2)
        Projected vertices, pixels.
    z : numpy.ndarray, shape (C, V)
        Vertex depths, mm (> 10 mm in front of the camera, else the triangle is skipped).
    attr : numpy.ndarray, shape (V,)
        Per-vertex attribute to interpolate (e.g. grey level).
    faces : numpy.ndarray, shape (F, 3), int
        Vertex indices, counter-clockwise seen from outside.
    face_part : numpy.ndarray, shape (F,), int
        Part index written to ``part`` for each triangle (>= 0).
    height, width : int
        Image size.
    cull_backfaces : bool, default True
        Skip triangles facing away from the camera (exact for closed, outward meshes).

    Returns
    -------
    RasterResult
    """
    uv = np.ascontiguousarray(uv, dtype=np.float64)
    z = np.ascontiguousarray(z, dtype=np.float64)
    if uv.ndim != 3 or uv.shape[2] != 2:
        raise ShapeError(f"uv must have shape (C, V, 2), got {uv.shape}")
    C, V = uv.shape[:2]
    if z.shape != (C, V):
        raise ShapeError(f"z must have shape {(C, V)}, got {z.shape}")
    attr = np.ascontiguousarray(attr, dtype=np.float64)
    if attr.shape != (V,):
        raise ShapeError(f"attr must have shape {(V,)}, got {attr.shape}")
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ShapeError(f"faces must have shape (F, 3), got {faces.shape}")
    if faces.size and (faces.min() < 0 or faces.max() >= V):
        raise ShapeError(f"faces index vertices outside [0, {V})")
    face_part = np.ascontiguousarray(face_part, dtype=np.int16)
    if face_part.shape != (faces.shape[0],):
        raise ShapeError(f"face_part must have shape {(faces.shape[0],)}, got {face_part.shape}")
    depth = np.full((C, int(height), int(width)), np.inf, dtype=np.float32)
    shade = np.zeros((C, int(height), int(width)), dtype=np.float32)
    part = np.full((C, int(height), int(width)), -1, dtype=np.int16)
    _raster_views(uv, z, attr, faces, face_part, bool(cull_backfaces), depth, shade, part)
    return RasterResult(depth=depth, shade=shade, part=part)
