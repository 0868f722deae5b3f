"""Synthetic 2D marker detections (Sharifi et al. 2017, sec. 4.1).

Per frame and view, starting from the noise-free projections of the marker points (the 15
HumanEva joints, optionally 4 more: toe tips and hand tips):

1. **Self-occlusion** (``occlusion=True``): a marker is visible in a view when it projects inside
   the image and the frontmost surface at its pixel (the rasteriser's z-buffer of the
   observation body) belongs to one of the marker's own body parts, or lies behind the marker, or
   is background. A joint inside its own limb is therefore seen, a wrist behind the torso is not.
   This replaces the paper's colour-coded depth-sorted cylinder meshes with an exact z-buffer.
2. **Drop-outs**: each visible marker is lost independently with probability ``dropout``.
3. **False detections**: ``Poisson(false_per_view)`` per frame and view, uniform in the
   projected body's bounding box grown by ``false_margin_px`` on each side (``false_region="body"``)
   or uniform over the image (``"image"``).
4. **Noise**: independent Gaussian pixel noise of standard deviation ``noise_px`` on both
   coordinates of every true detection (the paper adds noise "to some positions": set
   ``noise_fraction`` below 1 for that).

The detections of a view come in random order; their identities (``id = marker index``, ``-1``
for a false detection) are stored beside them for evaluation only -- the tracker sees positions.
All randomness comes from the ``numpy.random.Generator`` passed in.

Shape letters: ``C`` views, ``M`` markers, ``Q`` detections of one view.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError, ShapeError
from swarmpose.io.mocap import MocapClip
from swarmpose.joints import JOINTS15

__all__ = ["MarkerSettings", "MARKER_SETS", "MARKER_PARTS", "marker_points", "own_part_table",
           "marker_visibility", "detect_markers", "MarkerStats"]

#: Marker sets by name: the 15 HumanEva joints, or those plus toe and hand tips.
MARKER_SETS: dict[str, tuple[str, ...]] = {
    "joints15": JOINTS15,
    "extended": JOINTS15 + ("l_toe", "r_toe", "l_hand_tip", "r_hand_tip"),
}

#: Body parts (of :mod:`swarmpose.synth.body`) that a marker sits inside (cannot occlude it).
MARKER_PARTS: dict[str, tuple[str, ...]] = {
    "thorax": ("chest", "shoulders", "neck"),
    "pelvis": ("pelvis", "abdomen"),
    "head_top": ("head",),
    **{f"{x}_shoulder": ("shoulders", "chest", f"{x}_upper_arm") for x in "lr"},
    **{f"{x}_elbow": (f"{x}_upper_arm", f"{x}_forearm") for x in "lr"},
    **{f"{x}_wrist": (f"{x}_forearm", f"{x}_hand") for x in "lr"},
    **{f"{x}_hip": ("pelvis", f"{x}_thigh") for x in "lr"},
    **{f"{x}_knee": (f"{x}_thigh", f"{x}_calf") for x in "lr"},
    **{f"{x}_ankle": (f"{x}_calf", f"{x}_foot") for x in "lr"},
    **{f"{x}_toe": (f"{x}_foot",) for x in "lr"},
    **{f"{x}_hand_tip": (f"{x}_hand",) for x in "lr"},
}


@dataclass(frozen=True)
class MarkerSettings:
    """How 2D marker detections are synthesised (rates per frame and view).

    Parameters
    ----------
    markers : {"joints15", "extended", "none"}, default "joints15"
        Marker set (:data:`MARKER_SETS`); ``"none"`` writes no markers.
    occlusion : bool, default True
        Drop markers hidden by the body (z-buffer test).
    dropout : float, default 0.05
        Probability that a visible marker is not detected.
    false_per_view : float, default 0.5
        Mean number of false detections per frame and view (Poisson).
    noise_px : float, default 1.0
        Standard deviation of the Gaussian pixel noise on true detections.
    noise_fraction : float, default 1.0
        Fraction of true detections that get noise.
    false_region : {"body", "image"}, default "body"
        Where false detections fall (see the module docstring).
    false_margin_px : float, default 40.0
        Growth of the body's bounding box for ``false_region="body"``.
    """

    markers: str = "joints15"
    occlusion: bool = True
    dropout: float = 0.05
    false_per_view: float = 0.5
    noise_px: float = 1.0
    noise_fraction: float = 1.0
    false_region: str = "body"
    false_margin_px: float = 40.0

    def __post_init__(self) -> None:
        if self.markers not in MARKER_SETS and self.markers != "none":
            raise ConfigError(f"MarkerSettings.markers must be one of {sorted(MARKER_SETS) + ['none']}, "
                              f"got {self.markers!r}")
        for name in ("dropout", "noise_fraction"):
            v = getattr(self, name)
            if not (0.0 <= v <= 1.0):
                raise ConfigError(f"MarkerSettings.{name} must be in [0, 1], got {v!r}")
        for name in ("false_per_view", "noise_px", "false_margin_px"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f"MarkerSettings.{name} must be finite and >= 0, got {v!r}")
        if self.false_region not in ("body", "image"):
            raise ConfigError(f"MarkerSettings.false_region must be 'body' or 'image', got {self.false_region!r}")

    @property
    def names(self) -> tuple[str, ...]:
        """Marker names of the chosen set (empty for ``"none"``)."""
        return MARKER_SETS.get(self.markers, ())

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict (for provenance)."""
        return asdict(self)


def marker_points(clip: MocapClip, names: Sequence[str]) -> np.ndarray:
    """3D marker positions of every frame.

    Parameters
    ----------
    clip : MocapClip
    names : sequence of str
        From :data:`MARKER_SETS` (joint names of :data:`~swarmpose.joints.JOINTS15`, ``l_toe``,
        ``r_toe`` = toe end sites, ``l_hand_tip``, ``r_hand_tip`` = hand end sites).

    Returns
    -------
    numpy.ndarray, shape (T, M, 3)
        World mm.
    """
    sm = clip.skeleton_map
    out = np.empty((clip.frames, len(names), 3))
    for m, name in enumerate(names):
        if name in JOINTS15:
            out[:, m] = clip.joints[:, JOINTS15.index(name)]
        elif name in ("l_toe", "r_toe", "l_hand_tip", "r_hand_tip"):
            j = getattr(sm, name)
            p = clip.end_sites[:, j]
            out[:, m] = p if np.all(np.isfinite(p)) else clip.positions[:, j]
        else:
            raise ConfigError(f"unknown marker {name!r}")
    return out


def own_part_table(names: Sequence[str], part_names: Sequence[str]) -> np.ndarray:
    """``(M, P)`` bool: marker ``m`` sits inside part ``p`` (see :data:`MARKER_PARTS`)."""
    table = np.zeros((len(names), len(part_names)), dtype=bool)
    for m, name in enumerate(names):
        for p in MARKER_PARTS.get(name, ()):
            if p in part_names:
                table[m, list(part_names).index(p)] = True
    return table


def marker_visibility(uv: np.ndarray, z: np.ndarray, depth: np.ndarray, part: np.ndarray,
                      own: np.ndarray, *, occlusion: bool = True) -> np.ndarray:
    """Which markers each view sees.

    Parameters
    ----------
    uv : numpy.ndarray, shape (C, M, 2)
        Noise-free marker projections, pixels.
    z : numpy.ndarray, shape (C, M)
        Marker depths, mm.
    depth : numpy.ndarray, shape (C, H, W)
        Z-buffer of the body (``inf`` on background).
    part : numpy.ndarray, shape (C, H, W)
        Frontmost part index (``-1`` on background).
    own : numpy.ndarray, shape (M, P), bool
        :func:`own_part_table`.
    occlusion : bool, default True
        False: every marker inside the image (and in front of the camera) is visible.

    Returns
    -------
    numpy.ndarray, shape (C, M), bool
    """
    uv = np.asarray(uv, dtype=np.float64)
    C, M = uv.shape[:2]
    if z.shape != (C, M) or depth.shape[0] != C or part.shape != depth.shape or own.shape[0] != M:
        raise ShapeError(f"marker_visibility: inconsistent shapes uv {uv.shape}, z {z.shape}, "
                         f"depth {depth.shape}, part {part.shape}, own {own.shape}")
    H, W = depth.shape[1:]
    col = np.rint(uv[..., 0])
    row = np.rint(uv[..., 1])
    ok = np.isfinite(col) & np.isfinite(row)
    inside = ok & (z > 0) & (col >= 0) & (col <= W - 1) & (row >= 0) & (row <= H - 1)
    if not occlusion:
        return inside
    ci = np.clip(np.where(ok, col, 0), 0, W - 1).astype(np.int64)
    ri = np.clip(np.where(ok, row, 0), 0, H - 1).astype(np.int64)
    views = np.arange(C)[:, None]
    front = part[views, ri, ci].astype(np.int64)  # (C, M)
    front_depth = depth[views, ri, ci]
    mm = np.broadcast_to(np.arange(M)[None, :], (C, M))
    own_front = (front >= 0) & own[mm, np.maximum(front, 0)]
    unoccluded = (front < 0) | own_front | (front_depth >= z)
    return inside & unoccluded


@dataclass
class MarkerStats:
    """Counts over a clip for checking the realised rates against the settings."""

    visible: int = 0
    detected_true: int = 0
    false: int = 0
    view_frames: int = 0
    markers_total: int = 0

    @property
    def dropout_rate(self) -> float:
        """Lost fraction of the visible markers."""
        return 1.0 - self.detected_true / self.visible if self.visible else float("nan")

    @property
    def false_per_view(self) -> float:
        """Mean number of false detections per frame and view."""
        return self.false / self.view_frames if self.view_frames else float("nan")

    @property
    def visible_fraction(self) -> float:
        """Fraction of marker projections that are visible (inside the image and not occluded)."""
        return self.visible / self.markers_total if self.markers_total else float("nan")

    def to_dict(self) -> dict[str, Any]:
        """Counts and rates, JSON-safe."""
        return {"visible": self.visible, "detected_true": self.detected_true, "false": self.false,
                "view_frames": self.view_frames, "visible_fraction": self.visible_fraction,
                "dropout_rate": self.dropout_rate, "false_per_view": self.false_per_view}


def detect_markers(uv: np.ndarray, visible: np.ndarray, boxes: np.ndarray, image_size: tuple[int, int],
                   settings: MarkerSettings, rng: np.random.Generator,
                   stats: MarkerStats | None = None) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Turn visible marker projections into noisy detections with drop-outs and false positives.

    Parameters
    ----------
    uv : numpy.ndarray, shape (C, M, 2)
        Noise-free projections.
    visible : numpy.ndarray, shape (C, M), bool
        From :func:`marker_visibility`.
    boxes : numpy.ndarray, shape (C, 4)
        Per view ``(u_min, v_min, u_max, v_max)`` of the projected body (for ``false_region="body"``);
        NaN when the body is not in the view (false detections then fall anywhere in the image).
    image_size : (int, int)
        ``(width, height)``.
    settings : MarkerSettings
    rng : numpy.random.Generator
    stats : MarkerStats, optional
        Updated in place.

    Returns
    -------
    positions : list of C numpy.ndarray, shape (Q_c, 2), float64
    ids : list of C numpy.ndarray, shape (Q_c,), int16
        Marker index of each detection, ``-1`` for a false detection.
    """
    uv = np.asarray(uv, dtype=np.float64)
    C, M = uv.shape[:2]
    W, H = image_size
    positions, ids = [], []
    for c in range(C):
        vis = np.nonzero(visible[c])[0]
        keep = vis[rng.uniform(size=len(vis)) >= settings.dropout]
        pts = uv[c, keep].copy()
        if settings.noise_px > 0 and len(keep):
            noisy = rng.uniform(size=len(keep)) < settings.noise_fraction
            pts[noisy] += rng.normal(0.0, settings.noise_px, (int(noisy.sum()), 2))
        n_false = int(rng.poisson(settings.false_per_view))
        lo = np.array([0.0, 0.0])
        hi = np.array([W - 1.0, H - 1.0])
        if settings.false_region == "body" and np.all(np.isfinite(boxes[c])):
            lo = np.maximum(lo, boxes[c, :2] - settings.false_margin_px)
            hi = np.minimum(hi, boxes[c, 2:] + settings.false_margin_px)
        fake = lo + rng.uniform(size=(n_false, 2)) * (hi - lo)
        pts = np.clip(pts, 0.0, [W - 1.0, H - 1.0])  # a detector reports pixels inside the image
        all_pts = np.concatenate([pts, fake])
        all_ids = np.concatenate([keep, np.full(n_false, -1)]).astype(np.int16)
        order = rng.permutation(len(all_ids))
        positions.append(all_pts[order])
        ids.append(all_ids[order])
        if stats is not None:
            stats.visible += len(vis)
            stats.detected_true += len(keep)
            stats.false += n_false
            stats.view_frames += 1
            stats.markers_total += M
    return positions, ids
