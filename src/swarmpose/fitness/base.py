"""The fitness contract, per-stage options and the score formulas shared by every backend."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numba as nb
import numpy as np

from swarmpose.detection.joints import MIN_CONFIDENCE as KEYPOINT_THRESHOLD
from swarmpose.errors import ConfigError, ShapeError, option_items
from swarmpose.fitness._rowsum import row_sum
from swarmpose.fitness.keypoints import SCALE as KEYPOINT_SCALE
from swarmpose.fitness.keypoints import SWAPS, joint_thresholds, joint_weights

#: Hash of the kernel sources this module's cached kernels inline (fitness/_rowsum.py); tests/test_numba_cache.py
#: says when it must change.
INLINED_SOURCES_SHA1 = "7c39a6f7705c545b"

__all__ = ["Fitness", "ImageOptions", "parse_image_options", "TERMS", "silhouette_score", "edge_score",
           "thesis_fitness", "deutscher_reid_log_weight", "check_scores", "parse_fitness_options"]

#: Values of the ``"terms"`` option.
TERMS = ("silhouette+edge", "silhouette", "edge", "distance")
_OPTION_KEYS = ("edge_cones", "edge_top", "terms", "distance", "keypoints", "keypoint_joints", "keypoint_elbow",
                "keypoint_swaps", "keypoint_scale", "keypoint_threshold", "keypoint_power", "keypoint_views")


@runtime_checkable
class Fitness(Protocol):
    """A batched fitness for one frame (``shared/design.md`` §2): higher is better.

    Scores are log-weights, ``score = log w``: the fitnesses that define a weight (Deutscher & Reid
    eq. 17, Sharifi et al. eq. 12: ``w = exp(-...)``) return its logarithm, and the thesis's
    ``f = f_s + f_e`` is read as ``log w`` (the annealed particle filter weights by
    ``w^beta = exp(beta * score)``, DR05 eq. 3, 6). The swarm optimisers only rank scores, so for them
    the logarithm changes nothing.

    ``bind(frame)`` installs the observation (image fitness: a
    :class:`~swarmpose.features.FrameFeatures`; marker fitness: a
    :class:`~swarmpose.fitness.markers.MarkerFrame`) and prepares everything per-frame once; then
    ``fitness(poses (N, D)) -> (N,) float64`` and ``fitness.evaluate(poses, options) -> (N,)`` where
    ``options`` is the optimiser's per-stage mapping (``opt.fitness_options``).
    """

    def bind(self, frame: Any) -> Fitness: ...

    def __call__(self, poses: np.ndarray) -> np.ndarray: ...

    def evaluate(self, poses: np.ndarray, options: Mapping[str, Any] | None = None) -> np.ndarray: ...


@dataclass(frozen=True)
class ImageOptions:
    """Per-stage variant of an image fitness.

    Attributes
    ----------
    edge_cones : str or tuple of str
        ``"all"`` (every cone but the head), ``"torso"`` (SPPSO stage 1), ``"torso+upper"`` (torso,
        thighs, upper arms: stage 2 of the 3-partition SPPSO, thesis Table 6.3; alias
        ``"torso+upper_limbs"``) or explicit cone names.
    edge_top : bool
        Also sample the torso's upper edge (thesis sec. 5.2.1, 6.10; on in every SPPSO stage).
    terms : {"silhouette+edge", "silhouette", "edge", "distance"}
        Which terms of ``f = f_s + f_e`` are evaluated (the missing one counts as 0); ``"distance"``:
        the silhouette distance term alone (:mod:`swarmpose.fitness.distance`).
    distance : float
        Weight of the silhouette distance term added to the fitness (0: off, the papers' fitness).
    keypoints : float
        Weight of the keypoint term (:mod:`swarmpose.fitness.keypoints`) added where the bound frame carries
        a detector's keypoints (0: off, the papers' fitness).
    keypoint_joints : str
        The joints' weights inside the keypoint term, ``"elbow:0.25+hip:0.5"``
        (:func:`swarmpose.fitness.keypoints.joint_weights`; "" = all 1).
    keypoint_elbow : float
        Where the detector's elbow is taken to lie on the model's upper arm, as a fraction of it from the
        shoulder (:func:`swarmpose.fitness.keypoints.detector_elbows`; 1: at the model's elbow).
    keypoint_swaps : {"body", "limbs", "ends"}
        Which left/right exchanges of a view's labels the keypoint term tries
        (:data:`swarmpose.fitness.keypoints.SWAPS`): the whole body's; also the arms' and the legs' apart; or also
        the elbows with the wrists and the knees with the ankles apart.
    keypoint_scale : float
        The keypoint term's robust scale ``s`` as a fraction of the image diagonal
        (:data:`swarmpose.fitness.keypoints.SCALE`, 0.02): a detection farther off than ``s`` costs nearly the most.
    keypoint_threshold : float or str
        A detection counts in the keypoint term from confidence ``keypoint_threshold`` on (default
        :data:`swarmpose.detection.joints.MIN_CONFIDENCE`, 0.3); per joint as ``"wrist:0.1"`` or
        ``"0.2+wrist:0.1"`` (:func:`swarmpose.fitness.keypoints.joint_thresholds`; the joints not named at 0.3, or
        at the number that leads).
    keypoint_power : float
        A counted detection's weight is ``confidence ** keypoint_power`` (default 1; 0 weighs every counted
        detection alike).
    keypoint_views : int
        A view's detection of a joint counts only where at least this many views count a detection of that joint
        (default 1: every counted detection; 2: a joint that one view alone reports confidently is left to the
        images, as it cannot be triangulated).
    """

    edge_cones: str | tuple[str, ...] = "all"
    edge_top: bool = True
    terms: str = "silhouette+edge"
    distance: float = 0.0
    keypoints: float = 0.0
    keypoint_joints: str = ""
    keypoint_elbow: float = 1.0
    keypoint_swaps: str = "body"
    keypoint_scale: float = KEYPOINT_SCALE
    keypoint_threshold: float | str = KEYPOINT_THRESHOLD
    keypoint_power: float = 1.0
    keypoint_views: int = 1

    def __post_init__(self) -> None:
        if self.terms not in TERMS:
            raise ConfigError(f"unknown fitness terms {self.terms!r} (known: {', '.join(TERMS)})")
        if not isinstance(self.edge_top, (bool, np.bool_)):
            raise ConfigError(f"edge_top must be a bool, got {self.edge_top!r}")
        if not isinstance(self.edge_cones, str):
            object.__setattr__(self, "edge_cones", tuple(self.edge_cones))
        numbers = [(name, lambda f: np.isfinite(f) and f >= 0, "a weight >= 0") for name in ("distance", "keypoints")]
        numbers += [("keypoint_elbow", lambda f: 0 < f <= 1, "a fraction of the upper arm in (0, 1] (or auto, which a "
                                                            "track measures on its sequence)"),
                    ("keypoint_scale", lambda f: 0 < f <= 1, "a fraction of the image diagonal in (0, 1]"),
                    ("keypoint_power", lambda f: 0 <= f <= 4, "a number in [0, 4]")]
        for name, ok, expected in numbers:
            value = getattr(self, name)
            try:
                f = float(value)
            except (TypeError, ValueError):
                f = float("nan")
            if isinstance(value, bool) or not ok(f):
                raise ConfigError(f"{name} must be {expected}, got {value!r}")
            object.__setattr__(self, name, f)
        threshold = self.keypoint_threshold
        if isinstance(threshold, str) and (":" in threshold or "+" in threshold):  # per joint: checked here
            joint_thresholds(threshold.strip())
            object.__setattr__(self, "keypoint_threshold", threshold.strip())
        else:
            try:
                f = float(threshold)
            except (TypeError, ValueError):
                f = float("nan")
            if isinstance(threshold, bool) or not 0 <= f <= 1:
                raise ConfigError(f"keypoint_threshold must be a number in [0, 1] or per joint as 0.2+wrist:0.1, "
                                  f"got {threshold!r}")
            object.__setattr__(self, "keypoint_threshold", f)
        if self.keypoint_swaps not in SWAPS:
            raise ConfigError(f"keypoint_swaps must be one of {', '.join(SWAPS)}, got {self.keypoint_swaps!r}")
        views = self.keypoint_views
        try:
            n = int(views) if isinstance(views, (int, np.integer, str)) and not isinstance(views, bool) else 0
        except ValueError:
            n = 0
        if not 1 <= n <= 64:
            raise ConfigError(f"keypoint_views must be a whole number of views in 1-64, got {views!r}")
        object.__setattr__(self, "keypoint_views", n)
        object.__setattr__(self, "keypoint_joints", str(self.keypoint_joints))
        joint_weights(self.keypoint_joints)  # checks the text: a ConfigError names what is wrong


def parse_image_options(options: Mapping[str, Any] | None, default: ImageOptions) -> ImageOptions:
    """Overlay a per-stage ``options`` mapping on ``default``.

    Raises
    ------
    ConfigError
        An unknown key (the message lists the known ones) or a bad value.
    """
    if not options:
        return default
    unknown = [k for k in options if k not in _OPTION_KEYS]
    if unknown:
        raise ConfigError(f"unknown fitness option(s) {unknown} (known: {', '.join(_OPTION_KEYS)})")
    return ImageOptions(edge_cones=options.get("edge_cones", default.edge_cones),
                        edge_top=options.get("edge_top", default.edge_top),
                        terms=options.get("terms", default.terms),
                        distance=options.get("distance", default.distance),
                        keypoints=options.get("keypoints", default.keypoints),
                        keypoint_joints=options.get("keypoint_joints", default.keypoint_joints),
                        keypoint_elbow=options.get("keypoint_elbow", default.keypoint_elbow),
                        keypoint_swaps=options.get("keypoint_swaps", default.keypoint_swaps),
                        keypoint_scale=options.get("keypoint_scale", default.keypoint_scale),
                        keypoint_threshold=options.get("keypoint_threshold", default.keypoint_threshold),
                        keypoint_power=options.get("keypoint_power", default.keypoint_power),
                        keypoint_views=options.get("keypoint_views", default.keypoint_views))


def silhouette_score(Y: np.ndarray, P: np.ndarray, O: np.ndarray, a: float = 0.5) -> np.ndarray:
    """Bidirectional silhouette fitness, thesis eq. 5.2-5.5 (Sigal et al. 2010).

    ``f_s = (1 - a) Y / (B + Y) + a Y / (R + Y)`` with ``B + Y = P`` (projected area) and
    ``R + Y = O`` (observed area). A term whose denominator is 0 counts as 0 (nothing to overlap),
    except that both silhouettes empty is a perfect match (``f_s = 1``). Never NaN.

    Parameters
    ----------
    Y, P : (N, C) array_like
        Overlap ``|O & P|`` and projected area ``|P|`` per pose and view (pixels).
    O : (C,) array_like
        Observed area ``|O|`` per view.
    a : float, default 0.5
        Weight of the observed-coverage term.

    Returns
    -------
    (N, C) float64 in [0, 1]

    Raises
    ------
    ValueError
        ``Y`` exceeds ``P`` or ``O`` (inconsistent counts).
    """
    Y = np.asarray(Y, np.float64)
    P = np.asarray(P, np.float64)
    O = np.asarray(O, np.float64)
    if (Y > P).any() or (Y > O).any():
        raise ValueError("overlap Y cannot exceed the projected area P or the observed area O")
    # Y <= P and Y <= O, so Y / max(P, 1) is Y / P where P > 0 and 0 where P = 0 (likewise for O)
    f = (1.0 - a) * (Y / np.maximum(P, 1.0)) + a * (Y / np.maximum(O, 1.0))
    both_empty = (P == 0) & (O == 0)
    if both_empty.any():
        f = np.where(both_empty, 1.0, f)
    return f


def edge_score(edge_sum: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Edge fitness, thesis eq. 5.1: mean edge-map value over the visible sample points; 0 where no
    sample is visible. ``(N, C)`` -> ``(N, C)``."""
    edge_sum = np.asarray(edge_sum, np.float64)
    count = np.asarray(count, np.float64)
    return edge_sum / np.maximum(count, 1.0)  # the sum is 0 where the count is 0


def thesis_fitness(Y: np.ndarray, P: np.ndarray, O: np.ndarray, edge_sum: np.ndarray, count: np.ndarray,
                   a: float = 0.5, silhouette: bool = True, edge: bool = True) -> np.ndarray:
    """The thesis fitness ``f = f_s + f_e`` (sec. 5.2), each term averaged over the views: ``(N,)``.

    The same numbers, to the last bit, as ``silhouette_score(Y, P, O, a).mean(axis=1) + edge_score(edge_sum,
    count).mean(axis=1)`` (either term left out when ``silhouette`` or ``edge`` is False; tested), computed in one
    compiled pass instead of a dozen array operations: the fitness runs it on every batch. The view means add
    in numpy's order (its pairwise summation, up to 128 views; more views take the numpy path).

    Raises
    ------
    ValueError
        ``Y`` exceeds ``P`` or ``O`` (as :func:`silhouette_score`).
    """
    Y = np.asarray(Y)
    if Y.ndim != 2 or Y.shape[1] > 128:
        f = np.zeros(Y.shape[0])
        if silhouette:
            f += silhouette_score(Y, P, O, a).mean(axis=1)
        if edge:
            f += edge_score(edge_sum, count).mean(axis=1)
        return f
    f = np.empty(Y.shape[0])
    if not _thesis_kernel(Y, np.asarray(P), np.asarray(O, np.float64), np.asarray(edge_sum, np.float64),
                          np.asarray(count, np.float64), float(a), bool(silhouette), bool(edge), f):
        raise ValueError("overlap Y cannot exceed the projected area P or the observed area O")
    return f


@nb.njit(cache=True, nogil=True)
def _thesis_kernel(Y, P, O, edge_sum, count, a, silhouette, edge, out):
    """:func:`thesis_fitness` into ``out``; False when some ``Y`` exceeds ``P`` or ``O``."""
    N, C = Y.shape
    fs = np.empty(C)
    fe = np.empty(C)
    for n in range(N):
        for c in range(C):
            y = float(Y[n, c])
            p = float(P[n, c])
            if y > p or y > O[c]:
                return False
            if p == 0.0 and O[c] == 0.0:
                fs[c] = 1.0
            else:
                fs[c] = (1.0 - a) * (y / max(p, 1.0)) + a * (y / max(O[c], 1.0))
            fe[c] = edge_sum[n, c] / max(count[n, c], 1.0)
        f = 0.0
        if silhouette:
            f += row_sum(fs) / C
        if edge:
            f += row_sum(fe) / C
        out[n] = f
    return True


def deutscher_reid_log_weight(edge_sq: np.ndarray, edge_count: np.ndarray, region_sq: np.ndarray,
                              region_count: np.ndarray) -> np.ndarray:
    """Deutscher & Reid (2005) eq. 14-17 as a log-weight: ``log w = -sum_views (Sigma^e + Sigma^r)``.

    ``Sigma^e = mean (1 - p^e)^2`` over the visible edge samples (eq. 14), ``Sigma^r = mean (1 - p^r)^2``
    over the interior points (eq. 15); a view with no sample of a kind contributes 1 for it (no
    evidence: the largest SSD). Inputs ``(N, C)``; returns ``(N,)`` in ``[-2 C, 0]``.
    """
    se = np.where(edge_count > 0, edge_sq / np.maximum(edge_count, 1.0), 1.0)
    sr = np.where(region_count > 0, region_sq / np.maximum(region_count, 1.0), 1.0)
    return -(se + sr).sum(axis=1)


def check_scores(scores: np.ndarray, n: int) -> np.ndarray:
    """Return ``scores`` as a finite float64 ``(n,)`` array, or raise :class:`ShapeError`."""
    s = np.asarray(scores, np.float64)
    if s.shape != (n,):
        raise ShapeError(f"fitness must return shape ({n},), got {s.shape}")
    return s


_BOOLEAN_WORDS = {"true": True, "yes": True, "on": True, "false": False, "no": False, "off": False}


def parse_fitness_options(text: str) -> dict[str, Any]:
    """``"terms=silhouette,edge_top=false"`` → ``{"terms": "silhouette", "edge_top": False}``.

    true/yes/on and false/no/off (any case) become booleans; other values stay text, so that a
    boolean option given ``0`` or ``maybe`` is refused by the fitness instead of read as true.
    """
    return {k: _BOOLEAN_WORDS.get(v.lower(), v) for k, v in option_items(text, "fitness option")}
