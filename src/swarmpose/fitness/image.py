"""Image fitness functions: silhouette + edge (thesis sec. 5.2) and the Deutscher-Reid weighting."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.features import FrameFeatures
from swarmpose.fitness.backends import Measurements, PreparedFrame, Request, make_backend
from swarmpose.fitness.base import (
    ImageOptions,
    deutscher_reid_log_weight,
    edge_score,
    parse_image_options,
    silhouette_score,
    thesis_fitness,
)
from swarmpose.fitness.distance import (
    DEFAULT_STRIDE_PX,
    DEFAULT_TAU_PX,
    FULL_WIDTH_PX,
    DistanceMaps,
    distance_terms,
    distance_terms_reference,
    part_distances,
    prepare_distance_maps,
)
from swarmpose.fitness.keypoints import joint_thresholds, joint_weights, keypoint_cost
from swarmpose.render.project import DEFAULT_N_RIM, DEFAULT_NEAR_MM
from swarmpose.render.samples import DEFAULT_EDGE_SPACING_PX, TOP_EDGE_CONE, edge_cone_mask

__all__ = ["ImageFitness", "SilhouetteEdgeFitness", "DeutscherReidFitness"]


def _finite_rows(p: np.ndarray, model) -> tuple[np.ndarray, np.ndarray | None]:
    """Replace non-finite pose rows by the zero pose (the kernels need finite input); return the mask."""
    if math.isfinite(p.sum()):  # every entry finite (a non-finite one makes the sum so; an overflow looks below)
        return p, None
    bad = ~np.isfinite(p).all(axis=1)
    if not bad.any():
        return p, None
    p = p.copy()
    p[bad] = model.zero_pose()
    return p, bad


class ImageFitness:
    """Common machinery: backend, bound frame, per-stage options.

    Parameters
    ----------
    model : BodyModel
    backend : str, default "numba"
        A name in :data:`swarmpose.fitness.backends.BACKENDS`.
    edge_cones, edge_top, terms :
        Defaults of the per-stage options (:class:`~swarmpose.fitness.base.ImageOptions`).
    edge_spacing : float, default 5.0
        Pixels between edge samples (at the bound frame's resolution).
    n_rim : int, default 16
        Rim grid angles of the cone outlines (:mod:`swarmpose.render`).
    near : float, default 100.0
        Near-plane margin, mm.
    backend_options : mapping, optional
        Extra keyword arguments of the backend (e.g. ``{"threads": "prange"}`` for
        :class:`~swarmpose.fitness.backends.NumbaBackend`).
    distance_tau, distance_stride : float, int
        Truncation and observed-point grid of the silhouette distance term, pixels at 644 pixels wide
        (scaled with the bound frame's width; :mod:`swarmpose.fitness.distance`).
    """

    kind = "image"

    def __init__(self, model, *, backend: str = "numba", edge_cones: str | tuple[str, ...] = "all",
                 edge_top: bool = True, terms: str = "silhouette+edge",
                 edge_spacing: float = DEFAULT_EDGE_SPACING_PX, n_rim: int = DEFAULT_N_RIM,
                 near: float = DEFAULT_NEAR_MM, backend_options: Mapping[str, Any] | None = None,
                 distance_tau: float = DEFAULT_TAU_PX, distance_stride: int = DEFAULT_STRIDE_PX):
        if not distance_tau > 0 or not distance_stride >= 1:
            raise ConfigError(f"distance_tau and distance_stride must be > 0 and >= 1 pixels, got "
                              f"{distance_tau!r} and {distance_stride!r}")
        self.distance_tau = float(distance_tau)
        self.distance_stride = float(distance_stride)
        if not edge_spacing > 0:
            raise ConfigError(f"edge_spacing must be > 0 pixels, got {edge_spacing!r}")
        self.model = model
        self.backend = make_backend(backend, model, n_rim=n_rim, near=near, **dict(backend_options or {}))
        self.edge_spacing = float(edge_spacing)
        self.default_options = ImageOptions(edge_cones=edge_cones, edge_top=edge_top, terms=terms)
        self._names = tuple(model.cone_arrays.names)
        self._requests: dict[ImageOptions, Request] = {}
        self._parsed: dict[tuple, ImageOptions] = {}  # per-stage option mappings seen, parsed once
        self._request(self.default_options)  # validates the defaults now
        self.prepared: PreparedFrame | None = None

    # ---------------------------------------------------------------- frame
    def prepare(self, frame: FrameFeatures) -> PreparedFrame:
        """Per-frame state (prefix sums, ``|O|`` per view, edge maps, camera tables); timed in
        ``PreparedFrame.prepare_ms``."""
        return self.backend.prepare(frame)

    def bind(self, frame: FrameFeatures | PreparedFrame) -> ImageFitness:
        """Install the observation of one frame (prepared once here). Returns ``self``."""
        self.prepared = frame if isinstance(frame, PreparedFrame) else self.prepare(frame)
        return self

    @property
    def prepare_ms(self) -> float:
        """Preparation time of the bound frame, ms."""
        return self._bound().prepare_ms

    def _bound(self) -> PreparedFrame:
        if self.prepared is None:
            raise RuntimeError("no frame bound: call fitness.bind(frame) first")
        return self.prepared

    # ---------------------------------------------------------------- options
    def _options(self, options: Mapping[str, Any] | None) -> ImageOptions:
        """:func:`parse_image_options` over the defaults, kept per mapping seen (the stages pass the same few)."""
        if not options:
            return self.default_options
        try:
            key = tuple(options.items())
            opts = self._parsed.get(key)
        except TypeError:  # an unhashable value: parsed (and refused) as it comes
            return parse_image_options(options, self.default_options)
        if opts is None:
            if len(self._parsed) >= 256:  # a caller that builds new options every time: keep the cache small
                self._parsed.clear()
            opts = self._parsed[key] = parse_image_options(options, self.default_options)
        return opts

    def _request(self, opts: ImageOptions) -> Request:
        req = self._requests.get(opts)
        if req is None:
            mask = edge_cone_mask(self._names, opts.edge_cones)
            top = -1
            if opts.edge_top and TOP_EDGE_CONE in self._names and mask[self._names.index(TOP_EDGE_CONE)]:
                top = self._names.index(TOP_EDGE_CONE)
            req = self._make_request(opts, mask, top)
            if opts.keypoints > 0:  # the keypoint term's joints from the backend's own kinematics, where it has them
                req = replace(req, joints=True)
            self._requests[opts] = req
        return req

    def _make_request(self, opts: ImageOptions, mask: np.ndarray, top: int) -> Request:
        raise NotImplementedError

    # ---------------------------------------------------------------- evaluation
    def __call__(self, poses: np.ndarray) -> np.ndarray:
        """Scores ``(N,)`` of ``poses (N, D)`` with the default options."""
        return self.evaluate(poses)

    def evaluate(self, poses: np.ndarray, options: Mapping[str, Any] | None = None) -> np.ndarray:
        """Scores ``(N,)`` of ``poses (N, D)``, higher is better; NaN for poses with non-finite values.

        Parameters
        ----------
        poses : (N, D) array_like
        options : mapping, optional
            Per-stage overrides of ``edge_cones``, ``edge_top``, ``terms``, ``distance``, ``keypoints``,
            ``keypoint_joints``, ``keypoint_elbow``, ``keypoint_swaps``, ``keypoint_scale``,
            ``keypoint_threshold``, ``keypoint_power``, ``keypoint_views``.

        Raises
        ------
        ShapeError
            ``poses`` is not ``(N, D)``.
        ConfigError
            Unknown option key or value.
        RuntimeError
            No frame bound.
        """
        prepared = self._bound()
        p = self.model.check_poses(poses)
        opts = self._options(options)
        req = self._request(opts)
        if p.shape[0] == 0:
            return np.zeros(0)
        p, bad = _finite_rows(p, self.model)
        m = None
        if opts.terms == "distance":
            scores = self.distance_score(p)
        else:
            m = self.backend.measure(prepared, p, req)
            scores = self._score(m, prepared, opts)
            if opts.distance > 0:
                scores += opts.distance * self.distance_score(p)
        if opts.keypoints > 0 and prepared.features.keypoints is not None:
            f = prepared.features
            a = joint_weights(opts.keypoint_joints) if opts.keypoint_joints else None
            threshold = opts.keypoint_threshold
            if isinstance(threshold, str):  # per joint
                threshold = joint_thresholds(threshold)
            joints = m.joints if m is not None and m.joints is not None else self.model.joints15(p)
            scores -= opts.keypoints * keypoint_cost(joints, prepared.cameras, f.keypoints,
                                                     f.keypoint_confidence, weights=a, elbow=opts.keypoint_elbow,
                                                     swaps=opts.keypoint_swaps, scale=opts.keypoint_scale,
                                                     threshold=threshold, power=opts.keypoint_power,
                                                     min_views=opts.keypoint_views,
                                                     tables=(prepared.R, prepared.t, prepared.cam))
        if bad is not None:
            scores[bad] = np.nan  # the optimisers' "invalid" (shared/design.md; optim.base score rule)
        return scores

    def measure(self, poses: np.ndarray, options: Mapping[str, Any] | None = None) -> Measurements:
        """The backend's raw per-(pose, view) measurements (for tests and diagnostics)."""
        prepared = self._bound()
        p, _ = _finite_rows(self.model.check_poses(poses), self.model)
        return self.backend.measure(prepared, p, self._request(parse_image_options(options, self.default_options)))

    def _score(self, m: Measurements, prepared: PreparedFrame, opts: ImageOptions) -> np.ndarray:
        raise NotImplementedError

    # ---------------------------------------------------------------- silhouette distance
    def distance_maps(self) -> DistanceMaps:
        """The bound frame's distance transforms and observed points (computed on first use, then kept)."""
        prepared = self._bound()
        maps = prepared.extra.get("distance_maps")
        if maps is None:
            s = prepared.width / FULL_WIDTH_PX
            maps = prepare_distance_maps(prepared.silhouettes, tau=self.distance_tau * s,
                                         stride=max(1, round(self.distance_stride * s)),
                                         scale=max(1, round(prepared.width / (FULL_WIDTH_PX / 2))))
            prepared.extra["distance_maps"] = maps
        return maps

    def distance_measure(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``A (N, C)``, ``B (N, C)``, per-cone ``A (N, C, K)`` of the silhouette distance term
        (:func:`swarmpose.fitness.distance.distance_terms`; the plain reference with the reference backend)."""
        prepared = self._bound()
        p = self.model.check_poses(poses)
        maps = self.distance_maps()
        if self.backend.name == "reference":
            return distance_terms_reference(self.model, p, prepared.cameras, maps, self.backend.near)
        return distance_terms(self.model, p, prepared.R, prepared.t, prepared.cam, maps, self.backend.near)

    def distance_score(self, poses: np.ndarray) -> np.ndarray:
        """The silhouette distance score ``-mean_c (A_c + B_c)`` of ``poses (N, D)``, in ``[-2, 0]``."""
        A, B, _ = self.distance_measure(poses)
        return -(A + B).mean(axis=1)

    def part_agreement(self, poses: np.ndarray) -> np.ndarray:
        """Per-cone disagreement ``(N, K)`` in ``[0, 1]``: each cone's model-to-silhouette distance term
        averaged over the views (0: the cone lies inside every observed silhouette). Loss detection reads it."""
        return part_distances(self.distance_measure(poses)[2])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(backend={self.backend.name!r}, options={self.default_options})"


class SilhouetteEdgeFitness(ImageFitness):
    """Thesis fitness ``f = f_s + f_e`` (sec. 5.2), each averaged over the views.

    ``f_s``: bidirectional silhouette overlap, eq. 5.2-5.5 with ``a = 0.5``, on the union of the
    projected cones (with their end caps) per view. ``f_e``: mean edge-map value at the visible
    sample points along the selected cones' sides (plus the torso's upper edge), eq. 5.1. Range
    ``[0, 2]``; ``terms`` selects ``f_s`` or ``f_e`` alone.

    Parameters
    ----------
    model, backend, edge_cones, edge_top, terms, edge_spacing, n_rim, near :
        See :class:`ImageFitness`.
    a : float, default 0.5
        Silhouette weight of eq. 5.5.

    Examples
    --------
    >>> import numpy as np
    >>> from swarmpose.body.model import load_model
    >>> from swarmpose.fitness import make_fitness
    >>> from swarmpose.fitness.scene import demo_cameras, demo_frame
    >>> model = load_model("balan31")
    >>> pose = model.zero_pose(); pose[5] = 1000.0
    >>> frame = demo_frame(model, pose, demo_cameras(width=322, height=242), clutter=0, inflate=1.0, noise=0)
    >>> fit = make_fitness("silhouette_edge", model).bind(frame)
    >>> fs = fit.evaluate(pose[None], {"terms": "silhouette"})
    >>> float(fs[0])
    1.0
    """

    kind = "silhouette_edge"

    def __init__(self, model, *, a: float = 0.5, **kwargs: Any):
        if not 0.0 <= a <= 1.0:
            raise ConfigError(f"silhouette weight a must be in [0, 1], got {a!r}")
        self.a = float(a)
        super().__init__(model, **kwargs)

    def _make_request(self, opts: ImageOptions, mask: np.ndarray, top: int) -> Request:
        return Request(edge_mask=mask, top_cone=top, silhouette=opts.terms != "edge",
                       edge=opts.terms != "silhouette", region=False, edge_spacing=self.edge_spacing)

    def _score(self, m: Measurements, prepared: PreparedFrame, opts: ImageOptions) -> np.ndarray:
        return thesis_fitness(m.overlap, m.projected, prepared.observed_area, m.edge_sum, m.edge_count, self.a,
                              silhouette=opts.terms != "edge", edge=opts.terms != "silhouette")

    def terms(self, poses: np.ndarray, options: Mapping[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(f_s, f_e)``, each ``(N, C)`` per view (for diagnostics and tests).

        Raises
        ------
        ShapeError
            ``poses`` is not ``(N, D)``.
        """
        prepared = self._bound()
        opts = parse_image_options(options, self.default_options)
        p, bad = _finite_rows(self.model.check_poses(poses), self.model)
        m = self.backend.measure(prepared, p, self._request(opts))
        fs = (silhouette_score(m.overlap, m.projected, prepared.observed_area, self.a)
              if opts.terms != "edge" else np.zeros(m.overlap.shape))
        fe = edge_score(m.edge_sum, m.edge_count)
        if bad is not None:
            fs[bad] = np.nan
            fe[bad] = np.nan
        return fs, fe


class DeutscherReidFitness(ImageFitness):
    """Deutscher & Reid (2005) weighting, eq. 14-17, as its log: ``log w = -sum_c (Sigma^e_c + Sigma^r_c)``.

    ``Sigma^e``: mean ``(1 - p)^2`` of the edge map at the visible contour samples (the same points as
    the thesis edge fitness, so ``edge_cones``/``edge_top`` apply); ``Sigma^r``: mean ``(1 - O)^2`` of
    the observed silhouette at interior grid points of every cone (Fig. 6(b); ``region_spacing``
    pixels apart). The annealed particle filter's alternative likelihood; in ``[-2 C, 0]`` for ``C``
    views (the weight ``w`` in ``(0, 1]``). ``terms``
    ``"edge"`` or ``"silhouette"`` keeps only ``Sigma^e`` or ``Sigma^r``.

    Parameters
    ----------
    region_spacing : float, default 8.0
        Pixels between interior grid points.
    **kwargs :
        See :class:`ImageFitness`.
    """

    kind = "deutscher_reid"

    def __init__(self, model, *, region_spacing: float = 8.0, **kwargs: Any):
        if not region_spacing > 0:
            raise ConfigError(f"region_spacing must be > 0 pixels, got {region_spacing!r}")
        self.region_spacing = float(region_spacing)
        super().__init__(model, **kwargs)

    def _make_request(self, opts: ImageOptions, mask: np.ndarray, top: int) -> Request:
        return Request(edge_mask=mask, top_cone=top, silhouette=False, edge=opts.terms != "silhouette",
                       region=opts.terms != "edge", edge_spacing=self.edge_spacing,
                       region_spacing=self.region_spacing)

    def _score(self, m: Measurements, prepared: PreparedFrame, opts: ImageOptions) -> np.ndarray:
        zero = np.zeros_like(m.edge_sq)
        one = np.ones_like(m.edge_sq)
        if opts.terms == "silhouette":  # drop Sigma^e: zero SSD with a unit count
            return deutscher_reid_log_weight(zero, one, m.region_sq, m.region_count)
        if opts.terms == "edge":
            return deutscher_reid_log_weight(m.edge_sq, m.edge_count, zero, one)
        return deutscher_reid_log_weight(m.edge_sq, m.edge_count, m.region_sq, m.region_count)

