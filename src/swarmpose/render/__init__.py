"""Projection of the truncated-cone body model into calibrated views (thesis sec. 5.1.2, 5.2).

Public API
----------
``project_cones(model, poses (N, D), cameras, *, n_rim=16, near=100.0, backend="numba") -> ProjectedCones``
    Outline polygon of every cone of every pose in every view, its two silhouette lines, the end
    cap's outline arc and depths (numba, parallel over poses; ``backend="reference"``: numpy).
``edge_samples(model, poses, cameras, *, cones="all", top_edge=True, spacing=5.0) -> EdgeSamples``
    Occlusion-aware edge sample points (thesis sec. 5.2.1, Fig. 5.3).
``render_silhouette(model, pose (D,), camera) -> (H, W) uint8``
    Mask of the union of the cones' footprints (pixel-centre rule), plain numpy.
``edge_cone_mask(names, cones)``, ``EDGE_CONE_SETS``
    Named cone subsets of the edge fitness.

Geometry (the one definition both the numba and the numpy code implement)
-------------------------------------------------------------------------
A cone ``k`` is the truncated cone between two similar elliptical caps: start cap centre ``S0``
with semi-axes ``a, b`` along the joint frame's x and y axes, end cap centre ``S1`` with ``s a, s b``
(the caps lie in planes parallel to the joint frame's x-y plane; the axis ``S1 - S0`` may be oblique,
as the torso's is). Its **outline** in a view is the projection of its occluding contour:

* the two **silhouette lines** -- the generators where the lateral surface's normal is orthogonal to
  the viewing ray, found in closed form (:func:`swarmpose.render.reference.reference_geometry`),
* joined by the **outline arcs** of the caps: the rim points where exactly one of (cap disc,
  lateral surface) faces the camera (a cap rim that is entirely on the outline when the view is along
  the axis).

Each arc is polygonised at the arc's two end (tangent) angles and the rim grid angles
``2 pi j / n_rim`` in between, every vertex projected with the full camera model (Bouguet
distortion). The **footprint** of the cone is the convex hull of that polygon: exactly the hull of
the projections of all ``2 n_rim`` rim grid points and the four tangent points for a pinhole
camera; with lens distortion the two differ by sub-pixel slivers at most. A cone is not drawn in a
view when a cap centre is less than ``near`` plus its radius in front of the camera plane.

Pixel rule
----------
``(0, 0)`` is the centre of the top-left pixel. A pixel belongs to a footprint when its **centre**
lies inside the outline polygon **or on its boundary** (closed set; ties on an edge count as
inside). The numba scanline evaluates this per image row ``y``: the polygon covers
``[x_min(y), x_max(y)]`` (the extreme crossings of the row's centre line with its edges), so
pixels ``ceil(x_min) .. floor(x_max)`` are in; the reference tests every pixel centre against
the hull's half-planes (``(b - a) x (p - a) >= 0`` for every counter-clockwise edge ``a -> b``).
Both give the same pixel set for convex outlines; exact ties are decided by floating-point
rounding in each (measure zero for real poses). The model silhouette in a view is the union of the
footprints. Images are sampled at sample points by the nearest pixel centre,
``img[floor(v + 1/2), floor(u + 1/2)]``, with value 0 outside the image.

Occlusion of edge samples
-------------------------
A sample point at depth ``z`` on cone ``k`` is hidden when it lies in the footprint of another
drawn cone ``j`` whose axis is nearer there: the depth of ``j``'s axis at the point's orthogonal
projection onto ``j``'s projected axis (clamped to the segment, depths interpolated linearly between
the cap centres) is ``< z``. Sample depths are interpolated linearly between the end points of
the silhouette line (or along the arc).
"""

from __future__ import annotations

import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ShapeError
from swarmpose.render.project import (
    DEFAULT_N_RIM,
    DEFAULT_NEAR_MM,
    ProjectedCones,
    camera_tables,
    cone_tables,
    project_cones,
)
from swarmpose.render.samples import (
    DEFAULT_EDGE_SPACING_PX,
    EDGE_CONE_SETS,
    EdgeSamples,
    edge_cone_mask,
    edge_samples,
)

__all__ = [
    "DEFAULT_EDGE_SPACING_PX",
    "DEFAULT_N_RIM",
    "DEFAULT_NEAR_MM",
    "EDGE_CONE_SETS",
    "EdgeSamples",
    "ProjectedCones",
    "camera_tables",
    "cone_tables",
    "edge_cone_mask",
    "edge_samples",
    "project_cones",
    "render_silhouette",
]


def render_silhouette(model, pose: np.ndarray, camera: Camera, *, n_rim: int = DEFAULT_N_RIM,
                      near: float = DEFAULT_NEAR_MM) -> np.ndarray:
    """The model's silhouette in one view: union of the cone footprints (pixel-centre rule).

    Plain numpy (:mod:`swarmpose.render.reference`); about 5 ms per view.

    Parameters
    ----------
    model : BodyModel
    pose : (D,) or (1, D) array_like
    camera : Camera
    n_rim, near : see :func:`project_cones`.

    Returns
    -------
    numpy.ndarray, shape (camera.height, camera.width), uint8
        1 inside the model silhouette, 0 elsewhere.

    Raises
    ------
    ShapeError
        More than one pose.

    Examples
    --------
    >>> from swarmpose.body.model import load_model
    >>> from swarmpose.camera import Camera
    >>> model = load_model("balan31")
    >>> pose = model.zero_pose(); pose[5] = 1000.0          # pelvis 1 m above the floor
    >>> cam = Camera.look_at("c", eye=(4000, 0, 1000), target=(0, 0, 1000))
    >>> mask = render_silhouette(model, pose, cam)
    >>> mask.shape, int(mask.max())
    ((484, 644), 1)
    """
    from swarmpose.render.reference import reference_geometry, union_mask

    p = model.check_poses(pose)
    if p.shape[0] != 1:
        raise ShapeError(f"render_silhouette takes one pose (D,) or (1, D), got {np.shape(pose)}")
    geom = reference_geometry(model, p, [camera], n_rim=n_rim, near=near)
    return union_mask(geom, 0, 0).astype(np.uint8)
