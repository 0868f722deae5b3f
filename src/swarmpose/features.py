"""Image features for the fitness functions: silhouettes, edge maps and the image pyramid.

This module is the contract between the image side (synthesis, dataset loaders) and the fitness
side (:mod:`swarmpose.fitness`). Everything is OpenCV on ``uint8`` images, cheap enough to run
once per frame (about 2 ms per 644x484 view on one core).

Public API
----------
``silhouette(image, background, *, threshold=25, blur_px=2, open_px=3, close_px=5) -> (H, W) uint8``
    Background subtraction robust to sensor noise (thesis sec. 5.2.2 "observed silhouette"):
    ``|image - background|``, small Gaussian blur of that difference, threshold, morphological
    opening (removes noise speckles) then closing (fills pin holes). Values are ``{0, 1}``.
``edge_map(image, silhouette, *, threshold=40, dilate_px=7, sigma_px=2.0) -> (H, W) float32``
    Thesis sec. 5.2.1: Sobel -> threshold -> mask with the dilated silhouette -> Gaussian blur ->
    rescale to ``[0, 1]`` (divided by its maximum; all zeros when there is no edge).
``edge_pixels(image, silhouette, *, threshold=40, dilate_px=7) -> (H, W) uint8``
    The binary edges of ``edge_map`` before its blur (filtered in the dilated silhouette's box only).
``blur_edges(binary (H, W), sigma_px=2.0) -> (H, W) float32``
    The last two steps of ``edge_map`` for any binary edge image (e.g. a model's own outlines).
``FrameFeatures(silhouettes (C, H, W) uint8, edges (C, H, W) float32, cameras: list[Camera])``
    The observation of one frame in ``C`` views; :meth:`FrameFeatures.downsample` gives a pyramid
    level with the cameras rescaled by :meth:`swarmpose.camera.Camera.scaled`.
``compute_features(images (C, H, W) uint8, backgrounds (C, H, W) uint8, cameras, *, downsample=1)``
    Both features for every view, at full resolution, then optionally downsampled; in two halves,
    ``binary_features`` (silhouettes and edge pixels, what ``swarmpose.track.feature_store`` keeps
    between runs) and ``features_from_binary`` (the blur and the pyramid level).
``parse_feature_options("edge_threshold=8,...") -> (silhouette_options, edge_options)``
    The settings above from a ``key=value`` string (``swarmpose track --features``).

Pixel convention (``shared/design.md`` §2): ``(0, 0)`` is the centre of the top-left pixel; image
arrays are indexed ``[row, column] = [v, u]``.

Noise robustness (measured on 644x484 frames, a textured background and a textured foreground
whose grey level differs from the background by ``c`` everywhere, independent Gaussian noise of
standard deviation ``sigma`` in *both* the frame and the background; ``tests/test_features.py``
checks the first two): with the defaults, IoU against the exact mask is >= 0.99 for ``c = 40`` and
``sigma <= 10``, >= 0.97 for ``c = 40, sigma = 15``, >= 0.95 for ``c = 30, sigma <= 15``; it
collapses at ``sigma = 20`` (the mean of ``|noise difference|``, about 1.1 sigma, reaches the
threshold). For noisier cameras raise ``threshold`` to about 2 sigma + 5 (and keep ``c`` above it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from swarmpose.camera import Camera
from swarmpose.errors import ConfigError, ShapeError, option_items

__all__ = ["silhouette", "edge_map", "edge_pixels", "blur_edges", "FrameFeatures", "compute_features",
           "binary_features", "features_from_binary", "FEATURE_OPTIONS",
           "parse_feature_options"]

#: Keys of :func:`parse_feature_options`: ``(function, keyword)`` of :func:`silhouette` / :func:`edge_map`.
FEATURE_OPTIONS: dict[str, tuple[str, str]] = {
    "silhouette_threshold": ("silhouette", "threshold"),
    "silhouette_blur_px": ("silhouette", "blur_px"),
    "silhouette_open_px": ("silhouette", "open_px"),
    "silhouette_close_px": ("silhouette", "close_px"),
    "edge_threshold": ("edge", "threshold"),
    "edge_dilate_px": ("edge", "dilate_px"),
    "edge_sigma_px": ("edge", "sigma_px"),
}
_WHOLE_NUMBER_OPTIONS = frozenset({"silhouette_threshold", "silhouette_open_px", "silhouette_close_px",
                                   "edge_dilate_px"})


def _as_gray(image: np.ndarray, name: str) -> np.ndarray:
    """Return a ``(H, W)`` uint8 view of a grey or colour (``(H, W, 3)``, max over channels) image."""
    a = np.asarray(image)
    if a.dtype != np.uint8:
        raise ShapeError(f"{name} must be uint8, got dtype {a.dtype}")
    if a.ndim == 3 and a.shape[2] == 3:
        return a
    if a.ndim != 2:
        raise ShapeError(f"{name} must have shape (H, W) or (H, W, 3), got {a.shape}")
    return a


def _odd(px: float) -> int:
    """Smallest odd kernel size >= ``px`` (0 or less -> 0 meaning 'no operation')."""
    k = int(round(px))
    if k <= 0:
        return 0
    return k if k % 2 == 1 else k + 1


def silhouette(
    image: np.ndarray,
    background: np.ndarray,
    *,
    threshold: int = 25,
    blur_px: float = 2.0,
    open_px: int = 3,
    close_px: int = 5,
) -> np.ndarray:
    """Foreground mask by background subtraction (the *observed silhouette* of thesis sec. 5.2.2).

    Steps: ``d = |image - background|`` (max over colour channels), Gaussian blur of ``d`` with
    sigma ``blur_px / 2`` (shrinks the spread of the noise; blurring the *signed* difference instead
    would cancel textured foreground whose difference changes sign), ``d > threshold``,
    morphological opening with an elliptical ``open_px`` kernel (removes isolated noise pixels),
    closing with an elliptical ``close_px`` kernel (fills pin holes where the subject matches the
    background).

    Parameters
    ----------
    image, background : numpy.ndarray, shape (H, W) or (H, W, 3), uint8
        The frame and the empty-scene background of the same camera.
    threshold : int, default 25
        Grey-level difference above which a pixel is foreground (after the blur). Safe while the
        per-image noise sigma is below about ``(threshold - 5) / 2`` (see the module docstring).
    blur_px : float, default 2.0
        Pre-blur kernel size in pixels (sigma = ``blur_px / 2``); 0 disables it.
    open_px, close_px : int, default 3 and 5
        Kernel diameters of the opening and closing in pixels; 0 disables the step.

    Returns
    -------
    numpy.ndarray, shape (H, W), uint8
        1 for foreground, 0 for background.

    Raises
    ------
    ShapeError
        The images are not uint8, or their shapes differ.
    ConfigError
        ``threshold`` is outside ``[0, 255)``.
    """
    img = _as_gray(image, "image")
    bg = _as_gray(background, "background")
    if img.shape != bg.shape:
        raise ShapeError(f"image and background must have the same shape, got {img.shape} and {bg.shape}")
    if not 0 <= threshold < 255:
        raise ConfigError(f"threshold must be in [0, 255), got {threshold!r}")
    a = cv2.absdiff(img, bg)  # |I - B|
    if a.ndim == 3:
        a = cv2.max(cv2.max(a[..., 0], a[..., 1]), a[..., 2])  # (ndarray.max(axis=2) is ~20x slower)
    if blur_px > 0:
        # averaging |I - B| shrinks the noise's spread (not its mean, about 1.1 sigma_noise) while
        # keeping foreground whose signed difference changes sign (texture) above the threshold
        k = _odd(2 * blur_px + 1)
        a = cv2.GaussianBlur(a, (k, k), blur_px / 2.0)
    _, mask = cv2.threshold(a, int(threshold), 1, cv2.THRESH_BINARY)
    k = _odd(open_px)
    if k > 1:
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    k = _odd(close_px)
    if k > 1:
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    return mask


def edge_map(
    image: np.ndarray,
    silhouette: np.ndarray,
    *,
    threshold: float = 40.0,
    dilate_px: int = 7,
    sigma_px: float = 2.0,
    presmooth: bool = True,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Blurred, silhouette-masked edge map (thesis sec. 5.2.1, Fig. 5.3; Balan et al. 2005).

    Steps: (optional 3x3 Gaussian pre-smoothing against sensor noise) -> Sobel ``dx``, ``dy`` ->
    magnitude ``|dx| + |dy|`` (L1, on the 0..255 grey scale; the Sobel kernels' gain of 4 included)
    -> binary edges where the magnitude is ``> threshold * 4`` -> keep edges inside the silhouette
    dilated by ``dilate_px`` (removes background clutter) -> Gaussian blur with sigma ``sigma_px``
    (a cheap distance map) -> divide by the maximum, giving ``[0, 1]``.

    Parameters
    ----------
    image : numpy.ndarray, shape (H, W) or (H, W, 3), uint8
        The frame (a colour frame is converted to grey).
    silhouette : numpy.ndarray, shape (H, W), uint8 or bool
        The observed silhouette of the same frame (non-zero = foreground).
    threshold : float, default 40.0
        Edge threshold: an edge where the L1 Sobel magnitude exceeds ``4 * threshold``. An ideal step
        of height ``h`` grey levels has a magnitude of ``4 h`` on the raw image and ``3 h`` after the
        3x3 pre-smoothing (which spreads the step over two pixels), so the default keeps steps of more
        than 40 grey levels without pre-smoothing and more than 53 with it (``threshold * 4 / 3``).
    dilate_px : int, default 7
        Diameter of the dilation of the silhouette used as the mask; 0 or less: no masking.
    sigma_px : float, default 2.0
        Standard deviation of the Gaussian blur in pixels (> 0).
    presmooth : bool, default True
        3x3 Gaussian blur of the image before Sobel.
    out : numpy.ndarray, shape (H, W), float32, C-contiguous, optional
        Written in place and returned (saves a copy when filling a ``(C, H, W)`` stack).

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
        Values in ``[0, 1]``; 1 at the strongest edge response, all zeros when nothing passes the
        threshold inside the mask.

    Raises
    ------
    ShapeError
        Wrong dtype or mismatched shapes.
    ConfigError
        ``sigma_px <= 0``.
    """
    if not sigma_px > 0:
        raise ConfigError(f"sigma_px must be > 0, got {sigma_px!r}")
    pixels = edge_pixels(image, silhouette, threshold=threshold, dilate_px=dilate_px, presmooth=presmooth)
    if out is not None and (out.shape != pixels.shape or out.dtype != np.float32 or not out.flags.c_contiguous):
        raise ShapeError(f"out must be a C-contiguous float32 array of shape {pixels.shape}")
    return blur_edges(pixels, sigma_px, out=out)


def _box(mask: np.ndarray, margin: int) -> tuple[slice, slice] | None:
    """Rows and columns of the bounding box of ``mask``'s non-zero pixels grown by ``margin`` (clipped to the
    image); None when every pixel is zero."""
    x, y, w, h = cv2.boundingRect(mask)
    if w == 0 or h == 0:
        return None
    H, W = mask.shape
    return (slice(max(y - margin, 0), min(y + h + margin, H)), slice(max(x - margin, 0), min(x + w + margin, W)))


def edge_pixels(
    image: np.ndarray,
    silhouette: np.ndarray,
    *,
    threshold: float = 40.0,
    dilate_px: int = 7,
    presmooth: bool = True,
) -> np.ndarray:
    """The binary edges of :func:`edge_map` before its blur: ``(H, W)`` uint8, 1 where the (pre-smoothed) L1
    Sobel magnitude exceeds ``4 * threshold`` inside the silhouette dilated by ``dilate_px``.

    With a mask only the mask's bounding box is filtered, grown by the 3x3 filters' reach (two pixels with the
    pre-smoothing, one without): every kept pixel sees the same neighbours as on the whole image, so the
    result is the whole image's, exactly (tests/test_features.py).
    """
    img = _as_gray(image, "image")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    sil = np.asarray(silhouette)
    if sil.shape != img.shape:
        raise ShapeError(f"silhouette must have the image's shape {img.shape}, got {sil.shape}")
    if sil.dtype != np.uint8:
        sil = (sil != 0).astype(np.uint8)
    # an ideal step of height h: L1 magnitude 4h raw, 3h after the 3x3 pre-smoothing (test_features);
    # saturation at 255 only affects strong edges
    thr = min(float(threshold) * 4.0, 254.0)
    reach = 2 if presmooth else 1  # how far the 3x3 pre-smoothing and the 3x3 Sobel look

    def magnitude_edges(g: np.ndarray) -> np.ndarray:
        if presmooth:
            g = cv2.GaussianBlur(g, (3, 3), 0)
        gx = cv2.Sobel(g, cv2.CV_16S, 1, 0, ksize=3)
        gy = cv2.Sobel(g, cv2.CV_16S, 0, 1, ksize=3)
        mag = cv2.add(cv2.convertScaleAbs(gx), cv2.convertScaleAbs(gy))  # |dx| + |dy|, saturating uint8
        return cv2.threshold(mag, thr, 1, cv2.THRESH_BINARY)[1]

    k = _odd(dilate_px)
    if k <= 0:  # no mask: the whole image
        return magnitude_edges(img)
    out = np.zeros(img.shape, np.uint8)
    box = _box(sil, k // 2 + reach)  # the dilated silhouette and the filters' reach around it
    if box is None:
        return out
    s = sil[box]
    mask = cv2.dilate(s, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))) if k > 1 else s
    out[box] = cv2.bitwise_and(magnitude_edges(np.ascontiguousarray(img[box])), mask)
    return out


def blur_edges(edges: np.ndarray, sigma_px: float = 2.0, *, out: np.ndarray | None = None) -> np.ndarray:
    """The last step of :func:`edge_map`: Gaussian blur (sigma ``sigma_px``, kernel +-3 sigma) of a binary
    edge image, divided by its maximum (``[0, 1]``; all zeros stay zeros).

    Only the bounding box of the non-zero pixels grown by the kernel's radius is blurred (the rest stays
    exactly zero; the result is the whole image's, exactly); ``out`` (float32, the image's shape, C-contiguous) receives the result when given.
    """
    e = np.asarray(edges)
    if out is not None and (out.shape != e.shape or out.dtype != np.float32 or not out.flags.c_contiguous):
        raise ShapeError(f"out must be a C-contiguous float32 array of shape {e.shape}")
    if out is None:
        out = np.zeros(e.shape, np.float32)
    else:
        out[...] = 0.0
    if e.size == 0:
        return out
    kb = 2 * int(np.ceil(3.0 * sigma_px)) + 1  # +-3 sigma (OpenCV's float default, 4 sigma, is slower)
    # grown by the radius and one pixel: the blur reflects the box's border rows (OpenCV's default border), and
    # those it reflects into a window must be zeros, as outside the box
    box = _box(e if e.dtype == np.uint8 else (e != 0).view(np.uint8), kb // 2 + 1)
    if box is None:
        return out
    rows, cols = box
    W = e.shape[1]
    x0 = cols.start - cols.start % 16
    x1 = min(x0 + -(-(cols.stop - x0) // 16) * 16, W)
    box = (rows, slice(x0, x1))
    blurred = cv2.GaussianBlur(np.ascontiguousarray(e[box], dtype=np.float32), (kb, kb), float(sigma_px))
    peak = float(blurred.max())
    if peak > 0.0:
        blurred *= np.float32(1.0 / peak)
    out[box] = blurred
    return out


@dataclass(eq=False)
class FrameFeatures:
    """The observation of one frame in ``C`` views, as the image fitness functions consume it.

    Parameters
    ----------
    silhouettes : numpy.ndarray, shape (C, H, W), uint8
        Observed silhouettes, values ``{0, 1}``.
    edges : numpy.ndarray, shape (C, H, W), float32
        Edge maps in ``[0, 1]`` (:func:`edge_map`).
    cameras : list of Camera
        ``C`` cameras whose ``(width, height)`` equal ``(W, H)``.
    keypoints, keypoint_confidence : numpy.ndarray, shapes (C, J, 2) and (C, J), optional
        A detector's labelled body keypoints (px, NaN where absent) and their confidences.

    Raises
    ------
    ShapeError
        Shapes or dtypes disagree, or a camera's size is not ``(W, H)``.
    """

    silhouettes: np.ndarray
    edges: np.ndarray
    cameras: list[Camera]
    keypoints: np.ndarray | None = None
    keypoint_confidence: np.ndarray | None = None

    def __post_init__(self) -> None:
        s = np.asarray(self.silhouettes)
        e = np.asarray(self.edges)
        if s.ndim != 3:
            raise ShapeError(f"silhouettes must have shape (C, H, W), got {s.shape}")
        if s.dtype == np.bool_:
            s = s.astype(np.uint8)
        if s.dtype != np.uint8:
            raise ShapeError(f"silhouettes must be uint8 {{0, 1}}, got dtype {s.dtype}")
        if e.shape != s.shape:
            raise ShapeError(f"edges must have the silhouettes' shape {s.shape}, got {e.shape}")
        e = np.ascontiguousarray(e, dtype=np.float32)
        cams = list(self.cameras)
        if len(cams) != s.shape[0]:
            raise ShapeError(f"expected {s.shape[0]} cameras (one per view), got {len(cams)}")
        for c in cams:
            if not isinstance(c, Camera):
                raise ShapeError(f"cameras must be Camera objects, got {type(c).__name__}")
            if (c.width, c.height) != (s.shape[2], s.shape[1]):
                raise ShapeError(f"camera {c.name!r} is {c.width}x{c.height} but the images are "
                                 f"{s.shape[2]}x{s.shape[1]}")
        self.silhouettes = np.ascontiguousarray(s)
        self.edges = e
        self.cameras = cams
        if (self.keypoints is None) != (self.keypoint_confidence is None):
            raise ShapeError("keypoints and keypoint_confidence go together")
        if self.keypoints is not None:
            kp = np.asarray(self.keypoints, dtype=np.float64)
            kc = np.asarray(self.keypoint_confidence, dtype=np.float64)
            if kp.ndim != 3 or kp.shape[0] != len(cams) or kp.shape[2] != 2 or kc.shape != kp.shape[:2]:
                raise ShapeError(f"keypoints must be (C={len(cams)}, J, 2) with confidences (C, J), got {kp.shape} "
                                 f"and {kc.shape}")
            self.keypoints, self.keypoint_confidence = kp, kc

    @property
    def n_views(self) -> int:
        """Number of views ``C``."""
        return int(self.silhouettes.shape[0])

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` of the images in pixels."""
        return int(self.silhouettes.shape[2]), int(self.silhouettes.shape[1])

    def downsample(self, factor: int) -> FrameFeatures:
        """A coarser pyramid level: images shrunk by ``factor``, cameras rescaled to match.

        Silhouettes are box-averaged (``cv2.INTER_AREA``) and re-binarised at 1/2 (a pixel is
        foreground when at least half of its footprint was); edge maps are box-averaged and
        rescaled to a maximum of 1. Box averaging keeps pixel centres where
        :meth:`Camera.scaled` puts them (``u' = (u + 0.5) / factor - 0.5``); ``cv2.pyrDown`` would
        shift them by a quarter pixel. Output size is ``round(W / factor) x round(H / factor)``
        (the size :meth:`Camera.scaled` gives).

        Parameters
        ----------
        factor : int
            1 (returns ``self``), 2, 4, ...

        Returns
        -------
        FrameFeatures

        Raises
        ------
        ConfigError
            ``factor`` is not a positive integer.
        """
        if isinstance(factor, bool) or int(factor) != factor or factor < 1:
            raise ConfigError(f"downsample factor must be a positive integer, got {factor!r}")
        factor = int(factor)
        if factor == 1:
            return self
        cams = [c.scaled(1.0 / factor) for c in self.cameras]
        w, h = cams[0].width, cams[0].height
        sil = np.empty((self.n_views, h, w), np.uint8)
        edg = np.empty((self.n_views, h, w), np.float32)
        for v in range(self.n_views):
            s = cv2.resize(self.silhouettes[v] * np.uint8(255), (w, h), interpolation=cv2.INTER_AREA)
            sil[v] = s >= 128
            e = cv2.resize(self.edges[v], (w, h), interpolation=cv2.INTER_AREA)
            peak = float(e.max())
            edg[v] = e * np.float32(1.0 / peak) if peak > 0 else e
        kp = None if self.keypoints is None else (self.keypoints + 0.5) / factor - 0.5
        return FrameFeatures(sil, edg, cams, kp, self.keypoint_confidence)


def parse_feature_options(text: str) -> tuple[dict, dict]:
    """``"edge_threshold=8,silhouette_threshold=30"`` -> ``(silhouette_options, edge_options)``.

    The keys are :data:`FEATURE_OPTIONS`; values are numbers. The result feeds
    :func:`compute_features`. An empty string gives two empty dicts (the defaults).

    Raises
    ------
    ConfigError
        An item is not ``key=value``, the key is unknown (the message lists the known ones) or the
        value is not a number >= 0.
    """
    sil: dict = {}
    edge: dict = {}
    for key, value in option_items(text, "feature option"):
        if key not in FEATURE_OPTIONS:
            raise ConfigError(f"unknown feature option {key!r} (known: {', '.join(FEATURE_OPTIONS)})")
        target, kw = FEATURE_OPTIONS[key]
        try:
            v = float(value)
        except ValueError:
            raise ConfigError(f"feature option {key} needs a number, got {value!r}") from None
        if not (np.isfinite(v) and v >= 0):  # grey levels and pixel sizes
            raise ConfigError(f"feature option {key} needs a number >= 0, got {value!r}")
        if key in _WHOLE_NUMBER_OPTIONS:
            if v != int(v):
                raise ConfigError(f"feature option {key} needs a whole number, got {value!r}")
            v = int(v)
        (sil if target == "silhouette" else edge)[kw] = v
    return sil, edge


def compute_features(
    images: np.ndarray,
    backgrounds: np.ndarray,
    cameras: Sequence[Camera],
    *,
    downsample: int = 1,
    silhouette_options: dict | None = None,
    edge_options: dict | None = None,
    silhouettes: np.ndarray | None = None,
    keypoints: tuple[np.ndarray, np.ndarray] | None = None,
) -> FrameFeatures:
    """Silhouettes and edge maps of one multi-view frame (thesis sec. 5.2).

    Parameters
    ----------
    images, backgrounds : numpy.ndarray, shape (C, H, W) or (C, H, W, 3), uint8
        The frame and the background of every view (``backgrounds`` unused, may be None, when
        ``silhouettes`` are given).
    cameras : sequence of Camera
        ``C`` cameras of size ``(W, H)``.
    downsample : int, default 1
        Pyramid level: features are computed at full resolution, then
        :meth:`FrameFeatures.downsample` is applied.
    silhouette_options, edge_options : dict, optional
        Keyword arguments for :func:`silhouette` and :func:`edge_map`.
    silhouettes : numpy.ndarray, shape (C, H, W) uint8 in {0, 1}, optional
        Silhouettes found otherwise (a learned person segmentation stored with the sequence): used
        instead of background subtraction; the edge maps are masked with them as usual.
    keypoints : (numpy.ndarray (C, J, 2), numpy.ndarray (C, J)), optional
        A detector's body keypoints (px, NaN where absent) and confidences, carried with the features for
        the keypoint term of the image fitnesses (:mod:`swarmpose.fitness.keypoints`).

    Returns
    -------
    FrameFeatures

    Raises
    ------
    ShapeError
        Mismatched shapes, or not one camera per view.
    """
    sil, pix = binary_features(images, backgrounds, silhouette_options=silhouette_options,
                               edge_options=edge_options, silhouettes=silhouettes)
    return features_from_binary(sil, pix, cameras, edge_options=edge_options, downsample=downsample,
                                keypoints=keypoints)


def binary_features(images: np.ndarray, backgrounds: np.ndarray | None, *, silhouette_options: dict | None = None,
                    edge_options: dict | None = None,
                    silhouettes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The binary half of :func:`compute_features`: ``(silhouettes, edge pixels)``, each ``(C, H, W)`` uint8 in
    {0, 1} (:func:`silhouette` or the given ``silhouettes``; :func:`edge_pixels`). Shapes as checked there."""
    imgs = np.asarray(images)
    if imgs.ndim not in (3, 4):
        raise ShapeError(f"images must have shape (C, H, W) or (C, H, W, 3), got {imgs.shape}")
    given = None if silhouettes is None else np.asarray(silhouettes)
    if given is not None and given.shape != imgs.shape[:3]:
        raise ShapeError(f"silhouettes must have shape {imgs.shape[:3]}, got {given.shape}")
    bgs = None if given is not None else np.asarray(backgrounds)
    if bgs is not None and bgs.shape != imgs.shape:
        raise ShapeError(f"backgrounds must have the images' shape {imgs.shape}, got {bgs.shape}")
    so = dict(silhouette_options or {})
    eo = {k: v for k, v in (edge_options or {}).items() if k != "sigma_px"}  # the blur is the other half's
    C, H, W = imgs.shape[:3]
    sil = np.empty((C, H, W), np.uint8)
    pix = np.empty((C, H, W), np.uint8)
    for v in range(C):  # one view at a time: OpenCV calls, a handful per view
        sil[v] = (given[v] > 0) if given is not None else silhouette(imgs[v], bgs[v], **so)
        pix[v] = edge_pixels(imgs[v], sil[v], **eo)
    return sil, pix


def features_from_binary(silhouettes: np.ndarray, pixels: np.ndarray, cameras: Sequence[Camera], *,
                         edge_options: dict | None = None, downsample: int = 1,
                         keypoints: tuple[np.ndarray, np.ndarray] | None = None) -> FrameFeatures:
    """The other half of :func:`compute_features`: the edge pixels blurred into edge maps (:func:`blur_edges`,
    ``edge_options["sigma_px"]``), then the pyramid level ``downsample``."""
    sigma = float((edge_options or {}).get("sigma_px", 2.0))
    if not sigma > 0:
        raise ConfigError(f"sigma_px must be > 0, got {sigma!r}")
    sil = np.asarray(silhouettes)
    edg = np.empty(sil.shape, np.float32)
    for v in range(sil.shape[0]):
        blur_edges(pixels[v], sigma, out=edg[v])
    kp, kc = (None, None) if keypoints is None else keypoints
    return FrameFeatures(sil, edg, list(cameras), kp, kc).downsample(downsample)
