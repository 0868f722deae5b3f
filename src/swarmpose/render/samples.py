"""Edge sample points (thesis sec. 5.2.1, Fig. 5.3) and named cone subsets for the edge fitness."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError
from swarmpose.render.project import DEFAULT_N_RIM, DEFAULT_NEAR_MM

__all__ = ["EDGE_CONE_SETS", "NO_EDGE_CONES", "TOP_EDGE_CONE", "DEFAULT_EDGE_SPACING_PX", "edge_cone_mask",
           "EdgeSamples", "edge_samples"]

#: Cones never sampled for edges (thesis sec. 5.2.1: the head is too crude a shape).
NO_EDGE_CONES = ("head",)
#: The cone whose end-cap arc is the "upper edge" sampled with ``edge_top`` (thesis sec. 5.2.1, 6.10).
TOP_EDGE_CONE = "torso"
#: Named cone subsets. ``"torso"``: SPPSO stage 1 (thesis Fig. 5.3(a)); ``"torso+upper"``: stage 2 of
#: the 3-partition SPPSO (thesis Table 6.3: torso, thighs and upper arms, the cones not moved by
#: x9, x10, x13, x14, x19, x20, x25, x26 alone); ``"all"``: every cone but the head (Fig. 5.3(b)).
EDGE_CONE_SETS: dict[str, tuple[str, ...] | None] = {
    "all": None,
    "torso": ("torso",),
    "torso+upper": ("torso", "l_thigh", "r_thigh", "l_upper_arm", "r_upper_arm"),
}
_ALIASES = {"torso+upper_limbs": "torso+upper"}
#: Default distance between edge samples, pixels of the bound frame's resolution.
DEFAULT_EDGE_SPACING_PX = 5.0


def edge_cone_mask(names: Sequence[str], cones: str | Sequence[str] = "all") -> np.ndarray:
    """``(K,)`` bool: which cones' silhouette lines are edge-sampled.

    Parameters
    ----------
    names : sequence of str
        The model's cone names (``ConeArrays.names``).
    cones : str or sequence of str
        ``"all"`` (every cone except :data:`NO_EDGE_CONES`), ``"torso"``, ``"torso+upper"`` (alias
        ``"torso+upper_limbs"``), or explicit cone names.

    Raises
    ------
    ConfigError
        Unknown set name or cone name (the message lists the known ones).
    """
    names = tuple(names)
    if isinstance(cones, str):
        key = _ALIASES.get(cones, cones)
        if key not in EDGE_CONE_SETS:
            raise ConfigError(f"unknown edge cone set {cones!r} (known: {', '.join(EDGE_CONE_SETS)}, "
                              f"{', '.join(_ALIASES)} or a list of cone names)")
        sel = EDGE_CONE_SETS[key]
        if sel is None:
            return np.array([n not in NO_EDGE_CONES for n in names])
    else:
        sel = tuple(cones)
    unknown = [c for c in sel if c not in names]
    if unknown:
        raise ConfigError(f"unknown cone(s) {unknown} for the edge fitness (model cones: {', '.join(names)})")
    return np.array([n in sel and n not in NO_EDGE_CONES for n in names])


@dataclass(frozen=True)
class EdgeSamples:
    """Edge sample points of ``N`` poses in ``C`` views, padded to ``S`` per (pose, view).

    Attributes
    ----------
    points : (N, C, S, 2) float64
        ``(u, v)`` pixels; NaN padding.
    depth : (N, C, S) float64
        Camera depth of the sample on its cone, mm.
    cone : (N, C, S) int64
        Cone index, ``-1`` for padding.
    visible : (N, C, S) bool
        False for padding and for samples hidden by a nearer cone.
    """

    points: np.ndarray
    depth: np.ndarray
    cone: np.ndarray
    visible: np.ndarray


def edge_samples(model, poses: np.ndarray, cameras: Sequence[Camera], *, cones: str | Sequence[str] = "all",
                 top_edge: bool = True, spacing: float = DEFAULT_EDGE_SPACING_PX, n_rim: int = DEFAULT_N_RIM,
                 near: float = DEFAULT_NEAR_MM) -> EdgeSamples:
    """Occlusion-aware edge sample points along the cones' sides (thesis sec. 5.2.1, Fig. 5.3).

    Each selected cone's two silhouette lines get ``max(1, floor(length / spacing + 1/2))`` evenly
    spaced points (at ``t = (i + 1/2) / n``); with ``top_edge`` the torso's end-cap outline arc (its
    upper edge) is sampled the same way along its polyline. A point is *hidden* when it lies in the
    footprint of another drawn cone whose axis is nearer to the camera there (see
    :mod:`swarmpose.render`). This is the plain reference implementation (for tests, figures and the
    ``"reference"`` fitness backend); the numba fitness kernel computes the same points on the fly.

    Parameters
    ----------
    model : BodyModel
    poses : (N, D) array_like
    cameras : sequence of Camera
    cones : str or sequence of str, default "all"
        See :func:`edge_cone_mask`.
    top_edge : bool, default True
    spacing : float, default 5.0
        Pixels between samples.
    n_rim, near : see :func:`swarmpose.render.project_cones`.

    Returns
    -------
    EdgeSamples
    """
    from swarmpose.render.reference import edge_samples_reference, reference_geometry

    if not spacing > 0:
        raise ConfigError(f"spacing must be > 0, got {spacing!r}")
    geom = reference_geometry(model, poses, cameras, n_rim=n_rim, near=near)
    names = model.cone_arrays.names
    mask = edge_cone_mask(names, cones)
    top = names.index(TOP_EDGE_CONE) if (top_edge and TOP_EDGE_CONE in names and mask[names.index(TOP_EDGE_CONE)]) else -1
    N, C = geom.cones.n_vertices.shape[:2]
    res = [[edge_samples_reference(geom, n, c, mask, top, spacing) for c in range(C)] for n in range(N)]
    S = max([len(r[0]) for row in res for r in row], default=0)
    pts = np.full((N, C, S, 2), np.nan)
    dep = np.full((N, C, S), np.nan)
    kk = np.full((N, C, S), -1, np.int64)
    vis = np.zeros((N, C, S), bool)
    for n in range(N):
        for c in range(C):
            xy, z, k, v = res[n][c]
            m = len(z)
            pts[n, c, :m], dep[n, c, :m], kk[n, c, :m], vis[n, c, :m] = xy, z, k, v
    return EdgeSamples(points=pts, depth=dep, cone=kk, visible=vis)
