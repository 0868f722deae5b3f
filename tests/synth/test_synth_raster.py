"""The z-buffer rasteriser against analytic spheres."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.camera import Camera
from swarmpose.errors import ShapeError
from swarmpose.synth.body import sphere_template
from swarmpose.synth.raster import project_vertices, rasterize

F = 500.0
W, H = 320, 240


@pytest.fixture(scope="module")
def cam() -> Camera:
    return Camera.look_at("c", eye=(0.0, -3000.0, 1000.0), target=(0.0, 0.0, 1000.0), f=F, width=W, height=H)


def sphere(centre, radius, rings=24, segments=48):
    v, f = sphere_template(rings, segments)
    return v * radius + np.asarray(centre, float), f


def test_sphere_disc_and_depth(cam):
    v, f = sphere((0.0, 0.0, 1000.0), 300.0)
    uv, z = project_vertices(v, [cam])
    r = rasterize(uv, z, np.full(len(v), 7.0), f, np.zeros(len(f)), H, W)
    assert r.depth.shape == (1, H, W) and r.part.dtype == np.int16 and r.shade.dtype == np.float32
    mask = r.masks[0].astype(bool)
    # analytic silhouette of a sphere at distance d: a disc of radius f * R / sqrt(d^2 - R^2)
    rad = F * 300.0 / np.sqrt(3000.0**2 - 300.0**2)
    yy, xx = np.mgrid[0:H, 0:W]
    disc = (xx - cam.cx) ** 2 + (yy - cam.cy) ** 2 <= rad**2
    iou = (mask & disc).sum() / (mask | disc).sum()
    assert iou > 0.985
    # the front surface is seen (back faces culled / hidden): depth at the centre = d - R
    cy, cx = int(round(cam.cy)), int(round(cam.cx))
    assert r.depth[0, cy, cx] == pytest.approx(2700.0, abs=3.0)
    assert np.all(np.isinf(r.depth[0][~mask])) and np.all(r.part[0][~mask] == -1)
    assert np.allclose(r.shade[0][mask], 7.0, atol=1e-4)


def test_nearer_surface_wins(cam):
    va, fa = sphere((0.0, 0.0, 1000.0), 300.0)
    vb, fb = sphere((0.0, -1000.0, 1000.0), 100.0)  # smaller, 1 m closer to the camera
    v = np.vstack([va, vb])
    f = np.vstack([fa, fb + len(va)])
    parts = np.r_[np.zeros(len(fa)), np.ones(len(fb))]
    uv, z = project_vertices(v, [cam, cam])
    r = rasterize(uv, z, np.zeros(len(v)), f, parts, H, W)
    cy, cx = int(round(cam.cy)), int(round(cam.cx))
    assert r.part[0, cy, cx] == 1 and r.part[1, cy, cx] == 1
    assert r.depth[0, cy, cx] == pytest.approx(1900.0, abs=3.0)
    # without back-face culling the result is the same for closed meshes
    r2 = rasterize(uv, z, np.zeros(len(v)), f, parts, H, W, cull_backfaces=False)
    np.testing.assert_array_equal(r2.part, r.part)
    np.testing.assert_allclose(r2.depth, r.depth, rtol=1e-5)


def test_behind_camera_is_skipped(cam):
    v, f = sphere((0.0, -4000.0, 1000.0), 300.0)  # behind the camera
    uv, z = project_vertices(v, [cam])
    r = rasterize(uv, z, np.zeros(len(v)), f, np.zeros(len(f)), H, W)
    assert r.masks.sum() == 0


def test_exceptions(cam):
    v, f = sphere((0.0, 0.0, 1000.0), 300.0, 4, 8)
    uv, z = project_vertices(v, [cam])
    with pytest.raises(ShapeError, match="z must have shape"):
        rasterize(uv, z[:, :-1], np.zeros(len(v)), f, np.zeros(len(f)), H, W)
    with pytest.raises(ShapeError, match="faces index"):
        rasterize(uv, z, np.zeros(len(v)), f + 1000, np.zeros(len(f)), H, W)
    with pytest.raises(ShapeError, match="vertices must have shape"):
        project_vertices(v[:, :2], [cam])
