"""Image features: background subtraction, edge maps, the pyramid (thesis sec. 5.2)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, ShapeError
from swarmpose.features import FrameFeatures, compute_features, edge_map, parse_feature_options, silhouette

H, W = 484, 644


def _scene(rng: np.random.Generator, noise: float, contrast: float = 40.0):
    """Textured background, a textured foreground differing by ``contrast`` everywhere, noise in both."""
    tex = cv2.GaussianBlur(rng.normal(0.0, 1.0, (H, W)).astype(np.float32), (0, 0), 3.0)
    bg = np.clip(128.0 + 45.0 * tex / tex.std(), 0, 255)
    mask = np.zeros((H, W), np.uint8)
    cv2.ellipse(mask, (320, 240), (60, 180), 0, 0, 360, 1, -1)
    cv2.rectangle(mask, (200, 150), (440, 175), 1, -1)
    fgtex = cv2.GaussianBlur(rng.normal(0.0, 12.0, (H, W)).astype(np.float32), (0, 0), 2.0)
    fg = np.clip(np.where(bg > 128, bg - contrast, bg + contrast) + fgtex, 0, 255)
    img = np.where(mask > 0, fg, bg)
    frame = np.clip(img + rng.normal(0.0, noise, (H, W)), 0, 255).astype(np.uint8)
    back = np.clip(bg + rng.normal(0.0, noise, (H, W)), 0, 255).astype(np.uint8)
    return frame, back, mask


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.logical_and(a, b).sum() / np.logical_or(a, b).sum())


@pytest.mark.parametrize(("noise", "contrast", "min_iou"), [(0.0, 40.0, 0.99), (8.0, 40.0, 0.99),
                                                           (15.0, 30.0, 0.95)])
def test_silhouette_robust_to_noise(noise, contrast, min_iou):
    frame, back, mask = _scene(np.random.default_rng(1), noise, contrast)
    sil = silhouette(frame, back)
    assert sil.dtype == np.uint8 and sil.shape == (H, W)
    assert set(np.unique(sil)) <= {0, 1}
    assert _iou(sil, mask) >= min_iou


def test_silhouette_colour_and_errors():
    frame, back, mask = _scene(np.random.default_rng(2), 5.0)
    col = silhouette(np.dstack([frame] * 3), np.dstack([back] * 3))
    np.testing.assert_array_equal(col, silhouette(frame, back))
    with pytest.raises(ShapeError):
        silhouette(frame, back[:-1])
    with pytest.raises(ShapeError):
        silhouette(frame.astype(np.float32), back)
    with pytest.raises(ConfigError):
        silhouette(frame, back, threshold=300)
    assert silhouette(back, back).sum() == 0  # identical images: nothing in front


def test_edge_map():
    rng = np.random.default_rng(3)
    _, back, mask = _scene(rng, 3.0)
    fg = 210.0 + cv2.GaussianBlur(rng.normal(0.0, 4.0, (H, W)).astype(np.float32), (0, 0), 2.0)
    frame = np.clip(np.where(mask > 0, fg, back) + rng.normal(0.0, 3.0, (H, W)), 0, 255).astype(np.uint8)
    sil = silhouette(frame, back)
    e = edge_map(frame, sil)
    assert e.dtype == np.float32 and e.shape == (H, W)
    assert e.min() >= 0.0 and e.max() == pytest.approx(1.0)
    # masked by the dilated silhouette: nothing far from the person (blur reaches ~3 sigma)
    far = cv2.dilate(mask, np.ones((41, 41), np.uint8)) == 0
    assert e[far].max() == 0.0
    # strongest along the outline
    outline = cv2.morphologyEx(mask, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    assert e[outline].mean() > 3 * e[(mask > 0) & ~outline].mean()
    assert edge_map(back, np.zeros((H, W), np.uint8)).max() == 0.0  # nothing to keep
    with pytest.raises(ShapeError):
        edge_map(frame, sil[:10])
    with pytest.raises(ConfigError):
        edge_map(frame, sil, sigma_px=0.0)


@pytest.mark.parametrize(("presmooth", "fires_above"), [(True, 40.0 * 4 / 3), (False, 40.0)])
def test_edge_threshold_in_grey_levels(presmooth, fires_above):
    """An ideal vertical step of height h: L1 Sobel magnitude 4h raw, 3h after the 3x3 pre-smoothing,
    against ``4 * threshold``; the default 40 keeps steps above 53 grey levels (40 raw)."""
    sil = np.ones((40, 40), np.uint8)
    for h, fires in ((int(np.floor(fires_above)) - 1, False), (int(np.floor(fires_above)) + 1, True)):
        img = np.full((40, 40), 100, np.uint8)
        img[:, 20:] += h
        assert bool(edge_map(img, sil, presmooth=presmooth).max() > 0) is fires, (h, presmooth)


def _cams(n: int = 2) -> list[Camera]:
    return [Camera.look_at(f"c{i}", eye=(4000.0 * np.cos(i), 4000.0 * np.sin(i), 1500.0), target=(0, 0, 900))
            for i in range(n)]


def test_frame_features_and_pyramid():
    rng = np.random.default_rng(4)
    pairs = [_scene(rng, 3.0) for _ in range(2)]
    imgs = np.stack([p[0] for p in pairs])
    bgs = np.stack([p[1] for p in pairs])
    cams = _cams(2)
    ff = compute_features(imgs, bgs, cams)
    assert ff.silhouettes.shape == (2, H, W) and ff.edges.dtype == np.float32 and ff.n_views == 2
    half = ff.downsample(2)
    assert half.size == (322, 242) and half.cameras[0].width == 322 and half.cameras[0].fx == 500.0
    quarter = compute_features(imgs, bgs, cams, downsample=4)
    assert quarter.size == (161, 121) and quarter.edges.max() <= 1.0
    assert ff.downsample(1) is ff
    # the downsampled silhouette is the box mean (plain numpy here), re-binarised at 1/2; the edge map the box
    # mean rescaled to a peak of 1
    for level, f in ((half, 2), (quarter, 4)):
        for v in range(2):
            box = ff.silhouettes[v].reshape(H // f, f, W // f, f).mean(axis=(1, 3))
            np.testing.assert_array_equal(level.silhouettes[v], box >= 0.5)
            e = ff.edges[v].astype(np.float64).reshape(H // f, f, W // f, f).mean(axis=(1, 3))
            np.testing.assert_allclose(level.edges[v], e / e.max(), atol=1e-6)
    with pytest.raises(ConfigError):
        ff.downsample(0)
    with pytest.raises(ShapeError):
        FrameFeatures(ff.silhouettes, ff.edges[:1], cams)
    with pytest.raises(ShapeError):
        FrameFeatures(ff.silhouettes, ff.edges, cams[:1])
    with pytest.raises(ShapeError):
        FrameFeatures(ff.silhouettes, ff.edges, [cams[0], cams[1].scaled(0.5)])
    with pytest.raises(ShapeError):
        compute_features(imgs, bgs[:1], cams)


def test_feature_options():
    sil, edge = parse_feature_options(" edge_threshold=8.5, silhouette_threshold=30,edge_dilate_px=9 ")
    assert sil == {"threshold": 30} and edge == {"threshold": 8.5, "dilate_px": 9}
    assert parse_feature_options("") == ({}, {})
    for bad, match in (("edge_treshold=8", "known: silhouette_threshold"), ("edge_threshold", "key=value"),
                       ("edge_sigma_px=wide", "number"), ("silhouette_open_px=2.5", "whole"),
                       ("edge_threshold=-5", ">= 0"), ("edge_sigma_px=nan", ">= 0")):
        with pytest.raises(ConfigError, match=match):
            parse_feature_options(bad)
    # the options reach the feature code: a low edge threshold keeps the faint inner edge of a
    # darker band across the person that the default (a 40 grey-level step) drops
    rng = np.random.default_rng(5)
    frame, back, mask = _scene(rng, 1.0)
    band = np.zeros_like(mask)
    band[300:320] = 1
    frame = np.where((band & mask) > 0, np.clip(frame.astype(int) - 15, 0, 255), frame).astype(np.uint8)
    cams = _cams(1)
    default = compute_features(frame[None], back[None], cams)
    low_sil, low_edge = parse_feature_options("edge_threshold=8")
    low = compute_features(frame[None], back[None], cams, silhouette_options=low_sil, edge_options=low_edge)
    inner = (np.abs(np.arange(H) - 300) <= 1)[:, None] & (cv2.erode(mask, np.ones((15, 15), np.uint8)) > 0)
    assert low.edges[0][inner].mean() > 0.3 > default.edges[0][inner].mean()


def test_colour_silhouette_uses_the_largest_channel_difference():
    """(features.py:136 max over channels -> min): the existing colour test uses three equal channels.
    A person who differs from the background in one channel only is still foreground."""
    from swarmpose.features import silhouette

    bg = np.full((60, 80, 3), 100, np.uint8)
    img = bg.copy()
    img[20:40, 30:50, 2] = 170  # only the red channel (BGR) differs, by 70 grey levels
    sil = silhouette(img, bg)
    assert sil[22:38, 32:48].all() and sil.sum() == pytest.approx(400, abs=40)


@pytest.mark.parametrize("sigma", [1.0, 2.0, 3.0])
def test_edge_blur_has_the_requested_sigma(sigma):
    """(features.py:237 GaussianBlur sigma -> sigma / 2): the existing edge tests only check that the blur
    stays within 20 px of the person. The profile across a one-pixel line is the Gaussian of sigma_px."""
    from swarmpose.features import blur_edges, edge_map

    edges = np.zeros((40, 60), np.uint8)
    edges[:, 30] = 1
    e = blur_edges(edges, sigma)
    d = np.array([1, 2, 3])
    np.testing.assert_allclose(e[20, 30 + d], np.exp(-d**2 / (2 * sigma**2)), rtol=0.03, atol=0.01)
    # the same through edge_map (a strong vertical step, raw Sobel: the edge is two pixels wide)
    img = np.full((40, 60), 50, np.uint8)
    img[:, 30:] = 200
    em = edge_map(img, np.ones_like(img), sigma_px=sigma, presmooth=False)
    assert em[20, 29] == pytest.approx(1.0) and em[20, 30] == pytest.approx(1.0)
    np.testing.assert_allclose(em[20, 30 + d], em[20, 29 - d], atol=1e-6)  # symmetric about the step
    expect = 0.5 * (np.exp(-(d**2) / (2 * sigma**2)) + np.exp(-((d + 1) ** 2) / (2 * sigma**2)))
    expect /= 0.5 * (1 + np.exp(-1 / (2 * sigma**2)))
    np.testing.assert_allclose(em[20, 30 + d], expect, rtol=0.05, atol=0.01)


def test_silhouette_threshold_is_strict():
    """(features.py:142 `d > threshold` -> `d >= threshold`): the documented rule is a difference *above*
    the threshold."""
    from swarmpose.features import silhouette

    bg = np.full((30, 30), 100, np.uint8)
    for diff, fg in ((25, 0), (26, 1)):
        img = bg.copy()
        img[10:20, 10:20] += diff
        sil = silhouette(img, bg, threshold=25, blur_px=0, open_px=0, close_px=0)
        assert sil[10:20, 10:20].min() == sil[10:20, 10:20].max() == fg, diff
        assert sil.sum() == 100 * fg


def _whole_image_edge_map(image, sil, threshold=40.0, dilate_px=7, sigma_px=2.0, presmooth=True):
    """The plain reference of ``edge_map``: every step on the whole image."""
    g = cv2.GaussianBlur(image, (3, 3), 0) if presmooth else image
    mag = cv2.add(cv2.convertScaleAbs(cv2.Sobel(g, cv2.CV_16S, 1, 0, ksize=3)),
                  cv2.convertScaleAbs(cv2.Sobel(g, cv2.CV_16S, 0, 1, ksize=3)))
    edges = cv2.threshold(mag, min(threshold * 4.0, 254.0), 1, cv2.THRESH_BINARY)[1]
    k = dilate_px if dilate_px % 2 else dilate_px + 1
    edges = cv2.bitwise_and(edges, cv2.dilate(sil, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))))
    kb = 2 * int(np.ceil(3.0 * sigma_px)) + 1
    e = cv2.GaussianBlur(edges.astype(np.float32), (kb, kb), sigma_px)
    return edges, (e * np.float32(1.0 / e.max()) if e.max() > 0 else e)


@pytest.mark.parametrize("seed", range(6))
def test_edges_filtered_in_the_silhouettes_box_equal_the_whole_images(seed):
    """``edge_pixels`` and ``blur_edges`` work in the bounding box of what they need only; the results are the
    whole image's to the last bit, with the person anywhere (also against a border) and any blur."""
    from swarmpose.features import blur_edges, edge_pixels

    rng = np.random.default_rng(seed)
    frame, back, _ = _scene(rng, noise=5.0)
    sil = np.zeros((H, W), np.uint8)
    cx, cy = int(rng.integers(0, W)), int(rng.integers(0, H))  # seeds 0-5: boxes inside and cut by borders
    if seed == 0:
        cx, cy = 3, H - 2
    cv2.ellipse(sil, (cx, cy), (int(rng.integers(5, 80)), int(rng.integers(5, 200))), float(rng.uniform(0, 180)),
                0, 360, 1, -1)
    sigma = float(rng.choice([1.0, 1.5, 2.0, 3.0]))
    presmooth = bool(seed % 2)
    want_pixels, want = _whole_image_edge_map(frame, sil, sigma_px=sigma, presmooth=presmooth)
    pixels = edge_pixels(frame, sil, presmooth=presmooth)
    np.testing.assert_array_equal(pixels, want_pixels)
    assert pixels.sum() > 20
    np.testing.assert_array_equal(blur_edges(pixels, sigma), want)
    np.testing.assert_array_equal(edge_map(frame, sil, sigma_px=sigma, presmooth=presmooth), want)
    assert not blur_edges(np.zeros((H, W), np.uint8)).any() and not edge_pixels(frame, 0 * sil).any()
