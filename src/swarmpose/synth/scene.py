"""The static scene and the camera's image formation: room background, shading, blur and noise.

* **Room**: an axis-aligned box around the capture volume (walls ``wall_margin_mm`` beyond the
  farthest camera, ceiling at ``ceiling_mm``) seen through each camera by ray casting, so all views
  show one consistent room. Floor: ``tile_mm`` tiles with darker grout, a random brightness per
  tile and two octaves of smooth value noise. Walls: a grey level per wall, smooth noise, a few
  random panels (doors, posters) and a dark skirting board. Everything is drawn from the seed.
  Rendered with 2x2 supersampling. Grey levels stay within about 85-215.
* **Person shading** (per vertex, interpolated by the rasteriser): ``255 * albedo * (ambient +
  sky * (1 + n.z) / 2 + key * max(0, n.L))`` with a key light from above and in front of the
  ``+x, -y`` side.
* **Optics and sensor**: the composite is blurred by a Gaussian point-spread function of
  ``psf_sigma_px`` (0.6 px), Gaussian sensor noise of ``noise_sigma`` grey levels (2.5) is added
  independently per pixel and frame, and the result is rounded and clipped to uint8. The stored
  *background* image is the noise-free empty scene through the same PSF (what averaging many
  background frames gives, humaneva-facts §6).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import cv2
import numba as nb
import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError

__all__ = ["SceneSettings", "Room", "render_background", "shade_vertices", "form_image"]


@dataclass(frozen=True)
class SceneSettings:
    """Scene, lighting and sensor settings (grey levels on the 0-255 scale).

    Parameters
    ----------
    noise_sigma : float, default 2.5
        Standard deviation of the Gaussian sensor noise, grey levels, per pixel and frame.
    psf_sigma_px : float, default 0.6
        Gaussian blur of the optics, pixels (0: none).
    tile_mm : float, default 500
        Floor tile size.
    wall_margin_mm : float, default 1500
        Distance of the walls beyond the farthest camera.
    ceiling_mm : float, default 3200
    ambient, sky, key : float, default 0.62, 0.18, 0.25
        Lighting terms of the person's shading (see the module docstring).
    light_dir : tuple of 3 float, default (0.45, -0.35, 0.82)
        Direction *towards* the key light (normalised internally).
    """

    noise_sigma: float = 2.5
    psf_sigma_px: float = 0.6
    tile_mm: float = 500.0
    wall_margin_mm: float = 1500.0
    ceiling_mm: float = 3200.0
    ambient: float = 0.62
    sky: float = 0.18
    key: float = 0.25
    light_dir: tuple[float, float, float] = (0.45, -0.35, 0.82)

    def __post_init__(self) -> None:
        for name in ("noise_sigma", "psf_sigma_px", "ambient", "sky", "key"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"SceneSettings.{name} must be finite and >= 0, got {v!r}")
        for name in ("tile_mm", "wall_margin_mm", "ceiling_mm"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"SceneSettings.{name} must be > 0, got {v!r}")
        if len(self.light_dir) != 3 or np.linalg.norm(self.light_dir) == 0:
            raise ConfigError(f"SceneSettings.light_dir must be a non-zero 3-vector, got {self.light_dir!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (for provenance)."""
        return asdict(self)


# ---------------------------------------------------------------------- textures
class _ValueNoise:
    """Smooth 2D value noise on a random lattice (bicubic-smoothstep interpolation)."""

    def __init__(self, rng: np.random.Generator, cell_mm: float, size: int = 64):
        self.grid = rng.uniform(-1.0, 1.0, (size, size))
        self.cell = float(cell_mm)
        self.size = size

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        gx, gy = x / self.cell, y / self.cell
        ix, iy = np.floor(gx).astype(np.int64), np.floor(gy).astype(np.int64)
        fx, fy = gx - ix, gy - iy
        sx, sy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
        n = self.size
        g = self.grid
        i0, i1 = ix % n, (ix + 1) % n
        j0, j1 = iy % n, (iy + 1) % n
        top = g[j0, i0] * (1 - sx) + g[j0, i1] * sx
        bot = g[j1, i0] * (1 - sx) + g[j1, i1] * sx
        return top * (1 - sy) + bot * sy


class Room:
    """The textured room around the capture volume (deterministic from ``rng``).

    Parameters
    ----------
    lo, hi : array_like, shape (3,)
        Capture volume (world mm); the room encloses it and every camera.
    cameras : list of Camera
    settings : SceneSettings
    rng : numpy.random.Generator
    """

    def __init__(self, lo: np.ndarray, hi: np.ndarray, cameras: list[Camera], settings: SceneSettings,
                 rng: np.random.Generator):
        s = settings
        pts = np.vstack([np.asarray(lo, float), np.asarray(hi, float)] + [c.center for c in cameras])
        self.xmin, self.ymin = pts[:, 0].min() - s.wall_margin_mm, pts[:, 1].min() - s.wall_margin_mm
        self.xmax, self.ymax = pts[:, 0].max() + s.wall_margin_mm, pts[:, 1].max() + s.wall_margin_mm
        self.zmax = max(s.ceiling_mm, pts[:, 2].max() + 500.0)
        self.settings = s
        self.floor_base = rng.uniform(112.0, 128.0)
        self.tile_jitter = rng.uniform(-8.0, 8.0, (97, 89))
        self.floor_noise = (_ValueNoise(rng, 900.0), _ValueNoise(rng, 170.0))
        self.wall_base = rng.uniform(128.0, 150.0, 4)
        self.wall_noise = (_ValueNoise(rng, 700.0), _ValueNoise(rng, 140.0))
        # panels: (wall, s0, s1, z0, z1, delta) with s along the wall
        panels = []
        for w in range(4):
            length = (self.xmax - self.xmin) if w in (0, 1) else (self.ymax - self.ymin)
            for _ in range(int(rng.integers(2, 5))):
                pw = rng.uniform(500.0, 1500.0)
                s0 = rng.uniform(0.0, max(length - pw, 1.0))
                z0 = rng.uniform(0.0, 1200.0) if rng.uniform() < 0.6 else 0.0
                ph = rng.uniform(500.0, 2100.0 - z0 + 1.0)
                delta = rng.choice([-1.0, 1.0]) * rng.uniform(12.0, 28.0)
                panels.append((w, s0, s0 + pw, z0, z0 + ph, delta))
        self.panels = panels
        self.panel_array = np.array(panels, dtype=np.float64).reshape(-1, 6)

    def shade(self, eye: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Grey level seen along rays ``eye + t * dirs`` (``dirs (N, 3)``) -> ``(N,)`` float64."""
        d = dirs
        with np.errstate(divide="ignore", invalid="ignore"):
            cands = np.stack([
                np.where(d[:, 2] < 0, (0.0 - eye[2]) / d[:, 2], np.inf),            # floor
                np.where(d[:, 2] > 0, (self.zmax - eye[2]) / d[:, 2], np.inf),      # ceiling
                np.where(d[:, 1] > 0, (self.ymax - eye[1]) / d[:, 1], np.inf),      # wall 0: y = ymax
                np.where(d[:, 1] < 0, (self.ymin - eye[1]) / d[:, 1], np.inf),      # wall 1: y = ymin
                np.where(d[:, 0] > 0, (self.xmax - eye[0]) / d[:, 0], np.inf),      # wall 2: x = xmax
                np.where(d[:, 0] < 0, (self.xmin - eye[0]) / d[:, 0], np.inf),      # wall 3: x = xmin
            ], axis=1)
        surf = np.argmin(cands, axis=1)
        t = cands[np.arange(len(d)), surf]
        p = eye + t[:, None] * d
        out = np.empty(len(d))
        # floor: tiles, grout, noise
        m = surf == 0
        if m.any():
            x, y = p[m, 0], p[m, 1]
            tile = self.settings.tile_mm
            ix, iy = np.floor(x / tile).astype(np.int64), np.floor(y / tile).astype(np.int64)
            g = self.floor_base + self.tile_jitter[iy % 97, ix % 89]
            g = g + 9.0 * self.floor_noise[0](x, y) + 4.0 * self.floor_noise[1](x, y)
            fx, fy = x / tile - ix, y / tile - iy
            grout = np.minimum(np.minimum(fx, 1 - fx), np.minimum(fy, 1 - fy)) * tile < 6.0
            out[m] = np.where(grout, g - 30.0, g)
        m = surf == 1
        out[m] = 175.0
        for w in range(4):
            m = surf == 2 + w
            if not m.any():
                continue
            s_along = p[m, 0] - self.xmin if w in (0, 1) else p[m, 1] - self.ymin
            z = p[m, 2]
            g = self.wall_base[w] + 12.0 * self.wall_noise[0](s_along, z) + 5.0 * self.wall_noise[1](s_along + 7e3 * w, z)
            for pw, s0, s1, z0, z1, delta in self.panels:
                if pw != w:
                    continue
                inside = (s_along >= s0) & (s_along <= s1) & (z >= z0) & (z <= z1)
                g = np.where(inside, g + delta, g)
            g = np.where(z < 110.0, 112.0 + 4.0 * self.wall_noise[1](s_along, z), g)  # skirting board
            out[m] = g
        return np.clip(out, 0.0, 255.0)


@nb.njit(cache=True, inline="always")
def _vnoise(grid, cell, x, y):  # pragma: no cover - numba; same formula as _ValueNoise.__call__
    gx = x / cell
    gy = y / cell
    ix = np.floor(gx)
    iy = np.floor(gy)
    fx = gx - ix
    fy = gy - iy
    sx = fx * fx * (3.0 - 2.0 * fx)
    sy = fy * fy * (3.0 - 2.0 * fy)
    n = grid.shape[0]
    i0 = int(ix) % n
    j0 = int(iy) % n
    i1 = (i0 + 1) % n
    j1 = (j0 + 1) % n
    top = grid[j0, i0] * (1.0 - sx) + grid[j0, i1] * sx
    bot = grid[j1, i0] * (1.0 - sx) + grid[j1, i1] * sx
    return top * (1.0 - sy) + bot * sy


@nb.njit(cache=True)
def _shade_ray(ex, ey, ez, dx, dy, dz, bounds, tile, floor_base, jitter, fn0, c0, fn1, c1, wall_base,
               wn0, w0, wn1, w1, panels):  # pragma: no cover - numba; mirrors Room.shade
    xmin, xmax, ymin, ymax, zmax = bounds[0], bounds[1], bounds[2], bounds[3], bounds[4]
    best = np.inf
    surf = -1
    if dz < 0.0:
        t = -ez / dz
        if t < best:
            best, surf = t, 0
    if dz > 0.0:
        t = (zmax - ez) / dz
        if t < best:
            best, surf = t, 1
    if dy > 0.0:
        t = (ymax - ey) / dy
        if t < best:
            best, surf = t, 2
    if dy < 0.0:
        t = (ymin - ey) / dy
        if t < best:
            best, surf = t, 3
    if dx > 0.0:
        t = (xmax - ex) / dx
        if t < best:
            best, surf = t, 4
    if dx < 0.0:
        t = (xmin - ex) / dx
        if t < best:
            best, surf = t, 5
    px, py, pz = ex + best * dx, ey + best * dy, ez + best * dz
    if surf == 0:
        ix = np.floor(px / tile)
        iy = np.floor(py / tile)
        g = floor_base + jitter[int(iy) % jitter.shape[0], int(ix) % jitter.shape[1]]
        g += 9.0 * _vnoise(fn0, c0, px, py) + 4.0 * _vnoise(fn1, c1, px, py)
        fx = px / tile - ix
        fy = py / tile - iy
        if min(min(fx, 1.0 - fx), min(fy, 1.0 - fy)) * tile < 6.0:
            g -= 30.0
    elif surf == 1:
        g = 175.0
    else:
        w = surf - 2
        s_along = px - xmin if w < 2 else py - ymin
        g = wall_base[w] + 12.0 * _vnoise(wn0, w0, s_along, pz) + 5.0 * _vnoise(wn1, w1, s_along + 7e3 * w, pz)
        for i in range(panels.shape[0]):
            if int(panels[i, 0]) == w and panels[i, 1] <= s_along <= panels[i, 2] and panels[i, 3] <= pz <= panels[i, 4]:
                g += panels[i, 5]
        if pz < 110.0:
            g = 112.0 + 4.0 * _vnoise(wn1, w1, s_along, pz)
    return min(max(g, 0.0), 255.0)


@nb.njit(cache=True, parallel=True)
def _background_kernel(H, W, ss, intr, dist, Rt, eye, bounds, tile, floor_base, jitter, fn0, c0, fn1, c1,
                       wall_base, wn0, w0, wn1, w1, panels, out):  # pragma: no cover - numba
    fx, fy, cx, cy, skew = intr[0], intr[1], intr[2], intr[3], intr[4]
    k1, k2, p1, p2, k3 = dist[0], dist[1], dist[2], dist[3], dist[4]
    for v in nb.prange(H):
        for u in range(W):
            acc = 0.0
            for sv in range(ss):
                for su in range(ss):
                    pu = u + (su + 0.5) / ss - 0.5
                    pv = v + (sv + 0.5) / ss - 0.5
                    yd = (pv - cy) / fy
                    xd = (pu - cx) / fx - skew * yd
                    a, b = xd, yd
                    for _ in range(40):  # Bouguet's inverse distortion by fixed-point iteration
                        r2 = a * a + b * b
                        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                        ddx = 2.0 * p1 * a * b + p2 * (r2 + 2.0 * a * a)
                        ddy = p1 * (r2 + 2.0 * b * b) + 2.0 * p2 * a * b
                        an = (xd - ddx) / radial
                        bn = (yd - ddy) / radial
                        step = max(abs(an - a), abs(bn - b))
                        a, b = an, bn
                        if step < 1e-12:
                            break
                    # world ray direction d = R^T (a, b, 1)
                    dx = Rt[0, 0] * a + Rt[0, 1] * b + Rt[0, 2]
                    dy = Rt[1, 0] * a + Rt[1, 1] * b + Rt[1, 2]
                    dz = Rt[2, 0] * a + Rt[2, 1] * b + Rt[2, 2]
                    acc += _shade_ray(eye[0], eye[1], eye[2], dx, dy, dz, bounds, tile, floor_base, jitter,
                                      fn0, c0, fn1, c1, wall_base, wn0, w0, wn1, w1, panels)
            out[v, u] = acc / (ss * ss)


def render_background(camera: Camera, room: Room, *, supersample: int = 2) -> np.ndarray:
    """The empty room seen by ``camera``, before blur and noise (numba, parallel over rows).

    Per sub-pixel sample: Bouguet's inverse distortion (fixed point, as
    :meth:`Camera.undistort_points`), the world ray ``R^T (a, b, 1)`` from the optical centre, the
    first wall/floor/ceiling it hits and that surface's texture (:meth:`Room.shade` is the plain
    numpy version of the same shading).

    Parameters
    ----------
    camera : Camera
    room : Room
    supersample : int, default 2
        Samples per pixel along each axis (box-averaged).

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Grey levels 0-255.
    """
    ss = int(supersample)
    if ss < 1:
        raise ConfigError(f"supersample must be >= 1, got {supersample!r}")
    out = np.empty((camera.height, camera.width), dtype=np.float64)
    intr = np.array([camera.fx, camera.fy, camera.cx, camera.cy, camera.skew])
    bounds = np.array([room.xmin, room.xmax, room.ymin, room.ymax, room.zmax])
    fn0, fn1 = room.floor_noise
    wn0, wn1 = room.wall_noise
    _background_kernel(camera.height, camera.width, ss, intr, np.array(camera.dist), np.ascontiguousarray(camera.R.T),
                       np.asarray(camera.center, dtype=np.float64), bounds, float(room.settings.tile_mm),
                       float(room.floor_base), room.tile_jitter, fn0.grid, fn0.cell, fn1.grid, fn1.cell,
                       room.wall_base, wn0.grid, wn0.cell, wn1.grid, wn1.cell, room.panel_array, out)
    return out.astype(np.float32)


def shade_vertices(normals: np.ndarray, albedo: np.ndarray, settings: SceneSettings) -> np.ndarray:
    """Grey level of each vertex from its normal and albedo.

    Parameters
    ----------
    normals : numpy.ndarray, shape (V, 3)
        Unit world normals.
    albedo : numpy.ndarray, shape (V,)
    settings : SceneSettings

    Returns
    -------
    numpy.ndarray, shape (V,)
        ``255 * albedo * (ambient + sky * (1 + n_z) / 2 + key * max(0, n . L))``.
    """
    s = settings
    L = np.asarray(s.light_dir, dtype=np.float64)
    L = L / np.linalg.norm(L)
    n = np.asarray(normals, dtype=np.float64)
    light = s.ambient + s.sky * 0.5 * (1.0 + n[:, 2]) + s.key * np.maximum(0.0, n @ L)
    return 255.0 * np.asarray(albedo, dtype=np.float64) * light


def blur(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian point-spread function (float32 in, float32 out); identity for ``sigma_px == 0``."""
    if sigma_px <= 0:
        return image
    k = 2 * int(math.ceil(3 * sigma_px)) + 1
    return cv2.GaussianBlur(image, (k, k), sigma_px, borderType=cv2.BORDER_REFLECT)


def form_image(person: np.ndarray, mask: np.ndarray, background: np.ndarray, settings: SceneSettings,
               rng: np.random.Generator) -> np.ndarray:
    """Composite one view: person over the *unblurred* background, PSF, sensor noise, uint8.

    Parameters
    ----------
    person : numpy.ndarray, shape (H, W), float32
        Shaded person (valid where ``mask``).
    mask : numpy.ndarray, shape (H, W), bool
    background : numpy.ndarray, shape (H, W), float32
        The empty scene before blur (:func:`render_background`).
    settings : SceneSettings
    rng : numpy.random.Generator

    Returns
    -------
    numpy.ndarray, shape (H, W), uint8
    """
    img = np.where(mask, person, background).astype(np.float32)
    img = blur(img, settings.psf_sigma_px)
    if settings.noise_sigma > 0:
        img += rng.standard_normal(img.shape, dtype=np.float32) * np.float32(settings.noise_sigma)
    np.clip(img, 0.0, 255.0, out=img)
    return np.rint(img).astype(np.uint8)
