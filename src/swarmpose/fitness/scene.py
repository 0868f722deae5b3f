"""Small self-contained test scenes for the fitness functions and the ``bench`` command.

Not the project's observation synthesis (that is :mod:`swarmpose.synth`, with a detailed body that
is deliberately *not* the tracker's cone model). Here the observed person is the cone model itself,
optionally with inflated radii, drawn with a different grey level per cone over a textured
background with sensor noise and foreground clutter blobs -- enough to exercise and time the
fitness code, and to check ``f_s == 1`` on the model's own rendering.
"""

from __future__ import annotations

import copy
import dataclasses

import cv2
import numpy as np

from swarmpose.camera import Camera
from swarmpose.features import FrameFeatures, compute_features

__all__ = ["demo_cameras", "inflated_model", "demo_images", "demo_frame"]


def demo_cameras(n_views: int = 4, *, width: int = 644, height: int = 484, f: float = 1000.0,
                 distance: float = 4000.0, eye_height: float = 1500.0, target=(0.0, 0.0, 900.0),
                 k1: float = -0.12, k2: float = 0.05, azimuth0: float = 0.35) -> list[Camera]:
    """``n_views`` cameras on a circle around ``target`` (HumanEva-like: 644x484, f = 1000 px, mild
    radial distortion), azimuths ``azimuth0 + 2 pi i / n_views``. ``f`` scales with ``width / 644``."""
    s = width / 644.0
    cams = []
    for i in range(n_views):
        a = azimuth0 + 2 * np.pi * i / n_views
        eye = (target[0] + distance * np.cos(a), target[1] + distance * np.sin(a), eye_height)
        cams.append(Camera.look_at(f"view{i + 1}", eye=eye, target=target, f=f * s, width=width, height=height,
                                   dist=(k1, k2, 0.0, 0.0, 0.0)))
    return cams


def inflated_model(model, factor: float):
    """A copy of ``model`` whose cone radii are multiplied by ``factor`` (kinematics unchanged)."""
    m = copy.copy(model)
    ca = model.cone_arrays
    m.cone_arrays = dataclasses.replace(ca, radii=np.asarray(ca.radii) * float(factor))
    return m


def demo_images(model, pose: np.ndarray, cameras: list[Camera], *, rng: np.random.Generator | None = None,
                inflate: float = 1.08, clutter: int = 3, noise: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Render grey frames and backgrounds of the cone model at ``pose``.

    Parameters
    ----------
    model : BodyModel
    pose : (D,) array_like
    cameras : list of Camera (one image size)
    rng : numpy.random.Generator, optional
        ``None``: ``np.random.default_rng(0)``.
    inflate : float, default 1.08
        Radius factor of the observed body (1.0: the model itself).
    clutter : int, default 3
        Number of foreground clutter blobs per view (shadows, props).
    noise : float, default 3.0
        Sensor noise sigma (grey levels), independent in frame and background.

    Returns
    -------
    images, backgrounds : (C, H, W) uint8
    """
    from swarmpose.render.reference import rasterize_convex, reference_geometry

    rng = np.random.default_rng(0) if rng is None else rng
    body = inflated_model(model, inflate) if inflate != 1.0 else model
    geom = reference_geometry(body, np.asarray(pose, float)[None], cameras)
    C = len(cameras)
    W, H = geom.width, geom.height
    imgs = np.empty((C, H, W), np.uint8)
    bgs = np.empty((C, H, W), np.uint8)
    K = geom.cones.n_vertices.shape[2]
    shades = 140.0 + 90.0 * ((np.arange(K) * 0.37) % 1.0)  # bright body parts on a darker room
    for c in range(C):
        tex = cv2.GaussianBlur(rng.normal(0.0, 1.0, (H, W)).astype(np.float32), (0, 0), 4.0)
        bg = 75.0 + 18.0 * tex / max(float(tex.std()), 1e-6)
        img = bg.copy()
        depth = np.nanmean(geom.cones.axis_depth[0, c], axis=1)
        for k in np.argsort(-depth):  # painter's order: far to near
            hull = geom.hulls[0][c][k]
            if hull is not None:
                img[rasterize_convex(hull, W, H)] = shades[k]
        for _ in range(clutter):
            centre = (int(rng.integers(0, W)), int(rng.integers(0, H)))
            axes = (int(rng.integers(4, 15) * W / 644 + 1), int(rng.integers(4, 15) * W / 644 + 1))
            cv2.ellipse(img, centre, axes, 0.0, 0.0, 360.0, float(rng.uniform(140, 235)), -1)
        imgs[c] = np.clip(img + rng.normal(0.0, noise, (H, W)), 0, 255).astype(np.uint8)
        bgs[c] = np.clip(bg + rng.normal(0.0, noise, (H, W)), 0, 255).astype(np.uint8)
    return imgs, bgs


def demo_frame(model, pose: np.ndarray, cameras: list[Camera], *, rng: np.random.Generator | None = None,
               inflate: float = 1.08, clutter: int = 3, noise: float = 3.0, downsample: int = 1) -> FrameFeatures:
    """:func:`demo_images` run through :func:`swarmpose.features.compute_features`, except that with
    ``inflate == 1.0, clutter == 0, noise == 0`` the silhouettes are the exact model rendering."""
    imgs, bgs = demo_images(model, pose, cameras, rng=rng, inflate=inflate, clutter=clutter, noise=noise)
    frame = compute_features(imgs, bgs, cameras)
    if inflate == 1.0 and clutter == 0 and noise == 0:
        from swarmpose.render.reference import reference_geometry, union_mask

        geom = reference_geometry(model, np.asarray(pose, float)[None], cameras)
        sil = np.stack([union_mask(geom, 0, c) for c in range(len(cameras))]).astype(np.uint8)
        frame = FrameFeatures(sil, frame.edges, frame.cameras)
    return frame.downsample(downsample)
