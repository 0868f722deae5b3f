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


def _raster_reference(uv, z, attr, faces, face_part, height, width, cull):
    """Plain numpy z-buffer of one view: pixel centres, barycentric weights from edge functions (w >= 0
    inside), 1/z interpolated linearly on screen, triangles in order, a nearer depth wins."""
    depth = np.full((height, width), np.inf, np.float32)
    shade = np.zeros((height, width), np.float32)
    part = np.full((height, width), -1, np.int16)
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float64)
    for f, (i0, i1, i2) in enumerate(faces):
        (x0, y0), (x1, y1), (x2, y2) = uv[i0], uv[i1], uv[i2]
        if min(z[i0], z[i1], z[i2]) <= 10.0:
            continue
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        if area == 0.0 or (cull and area > 0.0):
            continue
        w0 = ((x1 - xx) * (y2 - yy) - (y1 - yy) * (x2 - xx)) * (1.0 / area)
        w1 = ((x2 - xx) * (y0 - yy) - (y2 - yy) * (x0 - xx)) * (1.0 / area)
        w2 = 1.0 - w0 - w1
        iz = w0 / z[i0] + w1 / z[i1] + w2 / z[i2]
        with np.errstate(divide="ignore"):
            d = 1.0 / iz
        hit = (w0 >= 0) & (w1 >= 0) & (w2 >= 0) & (d < depth)
        depth[hit] = d[hit]
        shade[hit] = ((w0 * attr[i0] / z[i0] + w1 * attr[i1] / z[i1] + w2 * attr[i2] / z[i2]) * d)[hit]
        part[hit] = face_part[f]
    return depth, shade, part


@pytest.mark.parametrize("cull", [True, False])
def test_numba_rasteriser_matches_a_plain_one(cull):
    """Overlapping random triangles of random depths and both orientations, some with a vertex behind the near
    plane or off the image: the numba kernel gives the plain z-buffer's part indices, depths and shading."""
    rng = np.random.default_rng(11)
    h, w, n = 30, 40, 60
    uv = rng.uniform(-8.0, [w + 8.0, h + 8.0], (1, 3 * n, 2))
    z = rng.uniform(500.0, 3000.0, (1, 3 * n))
    z[0, rng.choice(3 * n, 4, replace=False)] = 5.0  # in front of the near plane: those triangles are skipped
    attr = rng.uniform(0.0, 255.0, 3 * n)
    faces = np.arange(3 * n).reshape(n, 3)
    parts = rng.integers(0, 12, n)
    got = rasterize(uv, z, attr, faces, parts, h, w, cull_backfaces=cull)
    depth, shade, part = _raster_reference(uv[0], z[0], attr, faces, parts, h, w, cull)
    assert (part >= 0).sum() > 0.5 * h * w and len(np.unique(part)) > 6  # a busy picture
    np.testing.assert_array_equal(got.part[0], part)
    np.testing.assert_array_equal(got.depth[0], depth)
    np.testing.assert_allclose(got.shade[0], shade, rtol=1e-5, atol=1e-3)


@pytest.mark.parametrize("supersample", [1, 2])
def test_background_kernel_matches_the_plain_room_shading(supersample):
    """render_background (numba: inverse distortion, rays, walls, floor, panels) against the numpy path:
    Camera.undistort_points, the ray R^T (a, b, 1) and Room.shade, box-averaged over the sub-pixel samples."""
    from swarmpose.synth.scene import Room, SceneSettings, render_background

    cam = Camera.look_at("c", eye=(3500.0, -2500.0, 1700.0), target=(0.0, 0.0, 900.0), f=400.0, width=48,
                         height=36, dist=(-0.2, 0.08, 0.001, -0.002, 0.0), skew=0.001)
    other = Camera.look_at("d", eye=(-3000.0, 2800.0, 1500.0), target=(0.0, 0.0, 900.0))
    room = Room(np.array([-1000.0, -1000.0, 0.0]), np.array([1000.0, 1000.0, 1800.0]), [cam, other],
                SceneSettings(), np.random.default_rng(4))
    got = render_background(cam, room, supersample=supersample)
    ss = supersample
    off = (np.arange(ss) + 0.5) / ss - 0.5
    acc = np.zeros((cam.height, cam.width))
    for dv in off:
        for du in off:
            vv, uu = np.mgrid[0:cam.height, 0:cam.width].astype(np.float64)
            ab = cam.undistort_points(np.stack([uu + du, vv + dv], axis=-1).reshape(-1, 2), output="normalized")
            dirs = np.column_stack([ab, np.ones(len(ab))]) @ cam.R  # rows of R^T (a, b, 1)
            acc += room.shade(cam.center, dirs).reshape(cam.height, cam.width)
    ref = acc / ss**2
    assert np.ptp(ref) > 20.0  # floor, walls and panels in view, not a flat grey
    np.testing.assert_allclose(got, ref, atol=1e-3)


def test_sensor_noise_has_the_set_sigma():
    """(scene.py:386 sensor noise never added): nothing measured the noise of a formed image."""
    from swarmpose.synth.scene import SceneSettings, form_image

    bg = np.full((200, 300), 120.0, np.float32)
    person = np.zeros_like(bg)
    mask = np.zeros(bg.shape, bool)
    for sigma in (2.5, 6.0):
        img = form_image(person, mask, bg, SceneSettings(noise_sigma=sigma), np.random.default_rng(0))
        assert img.astype(float).std() == pytest.approx(np.sqrt(sigma**2 + 1 / 12), rel=0.05)
    img = form_image(person, mask, bg, SceneSettings(noise_sigma=0.0), np.random.default_rng(0))
    assert np.all(img == 120)
