"""Batched projection of the cone model: :func:`project_cones` and the numba camera/cone tables.

See :mod:`swarmpose.render` for the geometry (outline definition, pixel rule).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np

from swarmpose.body.kinematics import fk_pose_into
from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.render._kernels import cone_outline, rim_tables

#: Hash of the kernel sources this module's cached kernels inline (body/kinematics.py, render/_kernels.py).
#: numba's cache sees edits to this file only, so an edit there must change this line (or cached kernels keep
#: running the old code); tests/test_numba_cache.py says when and gives the new value.
INLINED_SOURCES_SHA1 = "0eb66cc3dceab8a8"

__all__ = ["ProjectedCones", "ConeTables", "cone_tables", "camera_tables", "project_cones",
           "DEFAULT_N_RIM", "DEFAULT_NEAR_MM"]

#: Grid angles per end-cap rim (the outline's arcs use these plus the tangent angles).
DEFAULT_N_RIM = 16
#: A cone is not drawn in a view when a cap centre is closer than this (plus the cap's radius) to the
#: camera plane.
DEFAULT_NEAR_MM = 100.0


@dataclass(frozen=True)
class ConeTables:
    """The model's cones as numba-ready arrays (``K`` cones).

    Attributes
    ----------
    joint : (K,) int64
        Joint frame of each cone.
    start, end : (K, 3) float64
        Axis end points in the joint frame, mm.
    semi_a, semi_b : (K,) float64
        Semi-axes of the start cap along the joint frame's x and y axes, mm.
    scale : (K,) float64
        End cap / start cap size ratio (the caps are similar ellipses).
    names : tuple of str
    """

    joint: np.ndarray
    start: np.ndarray
    end: np.ndarray
    semi_a: np.ndarray
    semi_b: np.ndarray
    scale: np.ndarray
    names: tuple[str, ...]

    def as_tuple(self) -> tuple[np.ndarray, ...]:
        """``(joint, start, end, semi_a, semi_b, scale)`` in kernel argument order."""
        return (self.joint, self.start, self.end, self.semi_a, self.semi_b, self.scale)


def cone_tables(model) -> ConeTables:
    """Compile ``model.cone_arrays`` into :class:`ConeTables`.

    Raises
    ------
    ConfigError
        A cone has a non-positive radius, end caps that are not similar ellipses (the closed-form
        silhouette lines of :func:`swarmpose.render._kernels.cone_outline` need ``semi_y / semi_x``
        equal at both ends), or an axis lying in its cap plane.
    """
    ca = model.cone_arrays
    semi_x = ca.radii * ca.scale[:, :1]  # (K, 2): at start, at end
    semi_y = ca.radii * ca.scale[:, 1:]
    if np.any(semi_x <= 0) or np.any(semi_y <= 0):
        raise ConfigError("every cone needs positive radii and scales")
    scale = semi_x[:, 1] / semi_x[:, 0]
    if not np.allclose(semi_y[:, 1] / semi_y[:, 0], scale, rtol=1e-9):
        bad = [ca.names[k] for k in np.flatnonzero(~np.isclose(semi_y[:, 1] / semi_y[:, 0], scale))]
        raise ConfigError(f"cones {bad} have end caps that are not similar ellipses")
    axis = ca.end - ca.start
    if np.any(np.abs(axis[:, 2]) < 1e-6 * np.linalg.norm(axis, axis=1)):
        raise ConfigError("a cone's axis lies in the plane of its caps (the joint frame's x-y plane)")
    t = ConeTables(joint=np.ascontiguousarray(ca.joint, np.int64), start=np.ascontiguousarray(ca.start, float),
                   end=np.ascontiguousarray(ca.end, float), semi_a=np.ascontiguousarray(semi_x[:, 0]),
                   semi_b=np.ascontiguousarray(semi_y[:, 0]), scale=np.ascontiguousarray(scale),
                   names=tuple(ca.names))
    return t


def _r2_max(cam: Camera) -> float:
    """Largest squared normalised radius (at most 4x the image corner's) up to which the radial
    distortion ``r (1 + k1 r^2 + k2 r^4 + k3 r^6)`` still increases with ``r``."""
    k1, k2, _, _, k3 = cam.dist
    corners = np.array([[0, 0], [cam.width - 1, 0], [0, cam.height - 1], [cam.width - 1, cam.height - 1]], float)
    a = (corners[:, 0] - cam.cx) / cam.fx
    b = (corners[:, 1] - cam.cy) / cam.fy
    limit = 4.0 * float(np.max(a * a + b * b))
    r = np.sqrt(np.linspace(0.0, limit, 2001))
    g = r * (1 + k1 * r**2 + k2 * r**4 + k3 * r**6)
    dec = np.flatnonzero(np.diff(g) <= 0)
    return float(r[dec[0]] ** 2) if dec.size else limit


def camera_tables(cameras: Sequence[Camera]) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Pack cameras for the kernels.

    Returns
    -------
    R : (C, 3, 3), t : (C, 3)
        ``cam_from_world``.
    cam : (C, 11)
        ``fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, r2_max``.
    width, height : int
        Common image size.

    Raises
    ------
    ShapeError
        No cameras, or cameras of different sizes.
    """
    cams = list(cameras)
    if not cams:
        raise ShapeError("expected at least one camera, got none")
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) != 1:
        raise ShapeError(f"all cameras must have the same image size, got {sorted(sizes)}")
    R = np.ascontiguousarray(np.stack([c.R for c in cams]))
    t = np.ascontiguousarray(np.stack([c.t for c in cams]))
    cam = np.array([[c.fx, c.fy, c.cx, c.cy, c.skew, *c.dist, _r2_max(c)] for c in cams], dtype=np.float64)
    w, h = sizes.pop()
    return R, t, cam, int(w), int(h)


@dataclass(frozen=True)
class ProjectedCones:
    """Cone outlines of ``N`` poses in ``C`` views (``K`` cones, at most ``P`` vertices each).

    Attributes
    ----------
    vertices : (N, C, K, P, 2) float64
        Outline polygon vertices ``(u, v)`` in pixels, in drawing order; NaN beyond ``n_vertices``.
    depth : (N, C, K, P) float64
        Camera depth (mm) of each vertex's 3D rim point.
    n_vertices : (N, C, K) int64
        0 where the cone is not drawn (too close to the camera plane).
    sides : (N, C, K, 2, 2, 2) float64
        The two silhouette lines (the sides parallel to the cone axis): ``[side, end, (u, v)]``, ``end``
        0 at the start cap and 1 at the end cap; NaN where the outline is a single rim (view along the
        axis).
    side_depth : (N, C, K, 2, 2) float64
    axis : (N, C, K, 2, 2) float64
        Projected centres of the start and end caps.
    axis_depth : (N, C, K, 2) float64
    end_arc : (N, C, K, 2) int64
        ``[first, stop)`` vertex indices of the end cap's outline arc (for the torso: its upper edge).
    end_arc_closed : (N, C, K) bool
        The end-cap arc is a whole rim (closed loop).
    """

    vertices: np.ndarray
    depth: np.ndarray
    n_vertices: np.ndarray
    sides: np.ndarray
    side_depth: np.ndarray
    axis: np.ndarray
    axis_depth: np.ndarray
    end_arc: np.ndarray
    end_arc_closed: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """``(N, C, K)`` bool: the cone is drawn."""
        return self.n_vertices > 0

    @property
    def has_sides(self) -> np.ndarray:
        """``(N, C, K)`` bool: the outline has two silhouette lines."""
        return ~np.isnan(self.sides[..., 0, 0, 0])


@nb.njit(cache=True, parallel=True, nogil=True)
def _project_kernel(poses, parents, offsets, rot_axis, rot_sign, rot_param, trans_param,
                    joint, start, end, semi_a, semi_b, scale, Rc, tc, cam, ctab, stab, near,
                    poly, sides, axis, info, nvs):
    N = poses.shape[0]
    C = Rc.shape[0]
    K = joint.shape[0]
    J = parents.shape[0]
    for n in nb.prange(N):
        T = np.empty((J, 3, 4))
        fk_pose_into(poses[n], parents, offsets, rot_axis, rot_sign, rot_param, trans_param, T)
        bbox = np.empty((K, 4))
        orient = np.empty(K)
        for c in range(C):
            for k in range(K):
                nvs[n, c, k] = cone_outline(T, joint, start, end, semi_a, semi_b, scale, Rc[c], tc[c], cam[c],
                                            ctab, stab, near, k, poly[n, c], sides[n, c], axis[n, c], info[n, c],
                                            bbox, orient)


def max_vertices(n_rim: int) -> int:
    """Upper bound on an outline's vertex count: two arcs of at most ``n_rim + 2`` vertices."""
    return 2 * n_rim + 4


def _check_n_rim(n_rim: int) -> int:
    if isinstance(n_rim, bool) or int(n_rim) != n_rim or n_rim < 4:
        raise ConfigError(f"n_rim must be an integer >= 4, got {n_rim!r}")
    return int(n_rim)


def project_cones(model, poses: np.ndarray, cameras: Sequence[Camera], *, n_rim: int = DEFAULT_N_RIM,
                  near: float = DEFAULT_NEAR_MM, backend: str = "numba") -> ProjectedCones:
    """Project every cone of every pose into every view (numba, parallel over poses).

    Parameters
    ----------
    model : BodyModel
    poses : (N, D) array_like
        Pose batch (a ``(D,)`` pose is a batch of one).
    cameras : sequence of Camera
        ``C`` cameras of one image size.
    n_rim : int, default 16
        Grid angles per cap rim (the outline's arcs are sampled at these plus the tangent angles).
    near : float, default 100.0
        Near-plane margin, mm.
    backend : {"numba", "reference"}
        ``"reference"``: the plain numpy implementation of :mod:`swarmpose.render.reference`.

    Returns
    -------
    ProjectedCones

    Raises
    ------
    ShapeError
        ``poses`` is not ``(N, D)``.
    ConfigError
        Unknown backend or bad ``n_rim``.
    """
    n_rim = _check_n_rim(n_rim)
    if backend == "reference":
        from swarmpose.render.reference import project_cones_reference

        return project_cones_reference(model, poses, cameras, n_rim=n_rim, near=near)
    if backend != "numba":
        raise ConfigError(f"unknown projection backend {backend!r} (known: 'numba', 'reference')")
    p = np.ascontiguousarray(model.check_poses(poses))
    ct = cone_tables(model)
    R, t, cam, _, _ = camera_tables(cameras)
    N, C, K, P = p.shape[0], R.shape[0], len(ct.names), max_vertices(n_rim)
    poly = np.full((N, C, K, P, 3), np.nan)
    sides = np.full((N, C, K, 2, 2, 3), np.nan)
    axis = np.full((N, C, K, 2, 3), np.nan)
    info = np.zeros((N, C, K, 4), np.int64)
    nvs = np.zeros((N, C, K), np.int64)
    ctab, stab = rim_tables(n_rim)
    _project_kernel(p, *model.kin.as_tuple(), *ct.as_tuple(), R, t, cam, ctab, stab, float(near),
                    poly, sides, axis, info, nvs)
    has = info[..., 0] == 1
    sides[~has] = np.nan
    # vertices beyond n_vertices are scratch: blank them
    pad = np.arange(P)[None, None, None, :] >= nvs[..., None]
    poly[pad] = np.nan
    return ProjectedCones(vertices=poly[..., :2], depth=poly[..., 2], n_vertices=nvs,
                          sides=sides[..., :2], side_depth=sides[..., 2], axis=axis[..., :2],
                          axis_depth=axis[..., 2], end_arc=info[..., 1:3].copy(),
                          end_arc_closed=info[..., 3] == 1)
