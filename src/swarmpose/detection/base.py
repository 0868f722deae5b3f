"""The person-detector interface: one person's 2D keypoints and segmentation mask in one image.

Public API
----------
``Detection(keypoints (K, 2), confidence (K,), mask (H, W) uint8 | None, found)``
    What a detector found in one image, in full-image pixels (NaN where absent).
``PersonDetector``
    The protocol every detector follows: ``name``, ``version``, ``keypoint_names``, ``settings``,
    ``detect(image, roi=None) -> Detection`` and ``reset()``.
``LandmarkDetector``
    A base class for detectors whose model gives landmarks normalised to the image ``[0, 1]``
    (MediaPipe's convention): it does the colour conversion, the region-of-interest crop and the
    mapping back to full-image pixels; a subclass writes :meth:`LandmarkDetector._infer` only.
``as_rgb(image) -> (H, W, 3) uint8``, ``clip_roi(roi, shape) -> (x0, y0, x1, y1)``
    The helpers it uses.

Pixel convention (``shared/design.md`` §2): ``(0, 0)`` is the centre of the top-left pixel. A
normalised landmark ``x`` in ``[0, 1]`` spans the image from its left edge to its right edge, so
``u = x * W - 0.5`` (and ``v = y * H - 0.5``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np

from swarmpose.errors import ConfigError, ShapeError

__all__ = ["Detection", "PersonDetector", "LandmarkDetector", "RawLandmarks", "as_rgb", "clip_roi"]


@dataclass
class Detection:
    """One person found (or not) in one image.

    Attributes
    ----------
    keypoints : (K, 2) float64
        ``(u, v)`` pixels in the full image; NaN where the keypoint is absent (all NaN when not found).
    confidence : (K,) float64
        In ``[0, 1]`` (MediaPipe's ``visibility``); 0 where absent.
    mask : (H, W) uint8 or None
        The person's segmentation, values ``{0, 1}``; None when the detector does not segment.
    found : bool
        Whether a person was found.
    """

    keypoints: np.ndarray
    confidence: np.ndarray
    mask: np.ndarray | None
    found: bool

    def __post_init__(self) -> None:
        self.keypoints = np.asarray(self.keypoints, dtype=np.float64)
        self.confidence = np.asarray(self.confidence, dtype=np.float64)
        k = self.keypoints.shape[0] if self.keypoints.ndim == 2 else -1
        if self.keypoints.ndim != 2 or self.keypoints.shape[1] != 2 or self.confidence.shape != (k,):
            raise ShapeError(f"keypoints must be (K, 2) and confidence (K,), got {self.keypoints.shape} "
                             f"and {self.confidence.shape}")
        if self.mask is not None and (self.mask.ndim != 2 or self.mask.dtype != np.uint8):
            raise ShapeError(f"mask must be (H, W) uint8, got {self.mask.shape} {self.mask.dtype}")
        self.found = bool(self.found)

    @classmethod
    def empty(cls, n_keypoints: int, shape: tuple[int, int] | None) -> Detection:
        """Nobody found: NaN keypoints, zero confidence, an all-zero mask of ``shape`` (None: no mask)."""
        mask = None if shape is None else np.zeros(shape, np.uint8)
        return cls(np.full((n_keypoints, 2), np.nan), np.zeros(n_keypoints), mask, False)


@runtime_checkable
class PersonDetector(Protocol):
    """A detector of one person's keypoints (and optionally mask) in one image.

    ``settings`` is a JSON-able dictionary of everything that changes the result (the detection
    cache is redone when it, ``name`` or ``version`` change).
    """

    name: str
    version: str
    keypoint_names: tuple[str, ...]

    @property
    def settings(self) -> dict[str, Any]: ...

    def detect(self, image_bgr_or_grey: np.ndarray, roi: tuple[int, int, int, int] | None = None) -> Detection:
        """The person in ``image`` (grey (H, W) or BGR (H, W, 3) uint8), inside ``roi = (x0, y0, x1, y1)``
        only when given (pixel columns ``x0 <= x < x1``, rows ``y0 <= y < y1``)."""
        ...

    def reset(self) -> None:
        """Forget the tracking state (call between views or videos)."""
        ...


def as_rgb(image: np.ndarray) -> np.ndarray:
    """A contiguous RGB ``(H, W, 3) uint8`` copy of a grey ``(H, W)``/``(H, W, 1)`` or BGR ``(H, W, 3)`` image.

    Raises
    ------
    ShapeError
        Another shape.
    ConfigError
        Not ``uint8``.
    """
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise ConfigError(f"a detector expects a uint8 image, got {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if image.ndim == 2:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_GRAY2RGB)
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_BGR2RGB)
    raise ShapeError(f"a detector expects a grey (H, W) or BGR (H, W, 3) image, got shape {image.shape}")


def clip_roi(roi: tuple[int, int, int, int], shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """``roi = (x0, y0, x1, y1)`` rounded to integers and clipped to an image of ``shape = (H, W, ...)``.

    Raises
    ------
    ConfigError
        Not four numbers, or nothing of it lies inside the image.
    """
    try:
        x0, y0, x1, y1 = (int(round(float(c))) for c in roi)
    except (TypeError, ValueError):
        raise ConfigError(f"roi must be four numbers (x0, y0, x1, y1), got {roi!r}") from None
    h, w = int(shape[0]), int(shape[1])
    x0, x1 = max(0, x0), min(w, x1)
    y0, y1 = max(0, y0), min(h, y1)
    if x1 <= x0 or y1 <= y0:
        raise ConfigError(f"roi {tuple(roi)} holds no pixel of the {w}x{h} image")
    return x0, y0, x1, y1


@dataclass
class RawLandmarks:
    """What a model gives for one image (or crop) of ``h x w`` pixels.

    ``xy (K, 2)`` normalised to ``[0, 1]`` of the width and the height; ``visibility (K,)``;
    ``mask_prob (h', w')`` float person probability (any size, resized to the image) or None.
    """

    xy: np.ndarray
    visibility: np.ndarray
    mask_prob: np.ndarray | None = None


class LandmarkDetector(ABC):
    """A detector whose model works on normalised landmarks; subclasses write :meth:`_infer`.

    Subclasses set ``name``, ``version``, ``keypoint_names``, ``segmentation`` (whether masks come) and
    ``mask_threshold``, and give ``settings``.
    """

    name: str = "landmarks"
    version: str = "0"
    keypoint_names: tuple[str, ...] = ()
    segmentation: bool = True
    mask_threshold: float = 0.5

    @property
    def settings(self) -> dict[str, Any]:
        return {"segmentation": self.segmentation, "mask_threshold": self.mask_threshold}

    @abstractmethod
    def _infer(self, rgb: np.ndarray, *, static: bool) -> RawLandmarks | None:
        """The model on one RGB uint8 image; None when nobody is found. ``static``: an unrelated
        image (a region of interest), which must not use or disturb the video tracking state."""

    def reset(self) -> None:
        """Forget the tracking state (nothing to forget here)."""
        return None

    def detect(self, image_bgr_or_grey: np.ndarray, roi: tuple[int, int, int, int] | None = None) -> Detection:
        """The person in a grey or BGR uint8 image, in full-image pixels (see :class:`PersonDetector`).

        With ``roi`` the model sees only that crop, as an unrelated still image; keypoints are shifted
        back by ``(x0, y0)`` and the crop's mask is pasted into an all-zero full-size mask.
        """
        rgb = as_rgb(image_bgr_or_grey)
        h_full, w_full = rgb.shape[:2]
        x0, y0, x1, y1 = (0, 0, w_full, h_full) if roi is None else clip_roi(roi, rgb.shape)
        crop = rgb if roi is None else np.ascontiguousarray(rgb[y0:y1, x0:x1])
        n = len(self.keypoint_names)
        raw = self._infer(crop, static=roi is not None)
        shape = (h_full, w_full) if self.segmentation else None
        if raw is None:
            return Detection.empty(n, shape)
        xy = np.asarray(raw.xy, dtype=np.float64).reshape(-1, 2)
        if xy.shape[0] != n:
            raise ShapeError(f"{self.name} gave {xy.shape[0]} landmarks, expected {n}")
        keypoints = np.empty((n, 2))
        keypoints[:, 0] = xy[:, 0] * (x1 - x0) - 0.5 + x0
        keypoints[:, 1] = xy[:, 1] * (y1 - y0) - 0.5 + y0
        confidence = np.clip(np.nan_to_num(np.asarray(raw.visibility, dtype=np.float64)), 0.0, 1.0)
        mask = None
        if shape is not None:
            mask = np.zeros(shape, np.uint8)
            if raw.mask_prob is not None:
                prob = np.asarray(raw.mask_prob, dtype=np.float32)
                if prob.shape != (y1 - y0, x1 - x0):
                    prob = cv2.resize(prob, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
                mask[y0:y1, x0:x1] = prob >= self.mask_threshold
        return Detection(keypoints, confidence, mask, True)
