"""Batched fitness functions: a batch of poses ``(N, D)`` against one bound frame -> scores ``(N,)``.

Contract (``shared/design.md`` §2)
---------------------------------
Every fitness follows :class:`Fitness`:

* ``fitness.bind(frame)`` installs one frame's observation and prepares it once (returns the
  fitness). Image fitness functions take a :class:`~swarmpose.features.FrameFeatures` (or an already
  prepared :class:`PreparedFrame`); marker fitness functions a :class:`MarkerFrame`.
* ``fitness(poses)`` -> ``(N,)`` float64, higher is better.
* ``fitness.evaluate(poses, options)`` -> ``(N,)`` with per-stage options, the mapping optimisers
  expose as ``opt.fitness_options``::

      {"edge_cones": "all" | "torso" | "torso+upper",   # "torso+upper_limbs" is an alias
       "edge_top": bool,                                 # the torso's upper edge
       "terms": "silhouette+edge" | "silhouette" | "edge"}

  Defaults: all cones but the head, top edge on, both terms. SPPSO stage 1 uses
  ``{"edge_cones": "torso"}`` (thesis sec. 5.2.1, Fig. 5.3(a)); its stage 2 the defaults (Fig. 5.3(b);
  the top edge is sampled in every stage, sec. 6.10); the 3-partition variant uses ``"torso"``,
  ``"torso+upper"`` (torso, thighs, upper arms) and ``"all"`` (Table 6.3). The silhouette term always
  covers the full body. Marker fitness functions ignore these options.

Factory
-------
``make_fitness(kind, model, *, backend="numba", **options)`` with kinds

* ``"silhouette_edge"`` -- :class:`SilhouetteEdgeFitness`, thesis ``f = f_s + f_e`` (eq. 5.1-5.5,
  ``a = 0.5``) averaged over the views;
* ``"deutscher_reid"`` -- :class:`DeutscherReidFitness`, Deutscher & Reid eq. 14-17 (``log w``);
* ``"markers"`` -- :class:`MarkerFitness`, Sharifi et al. eq. 7-12 (``rho = 5`` px, penalty 200,
  ``log w = -mean score``);
* ``"reprojection"`` -- :class:`ReprojectionFitness`, robust symmetric reprojection error (points to
  detections and detections to points; the tracker's default for the AAPSO family);

and, for the image kinds, backends ``"numba"`` (default: fused numba kernels on all cores),
``"torch"`` (:class:`~swarmpose.fitness.torch_backend.TorchBackend`, the GPU path: the same
measurements as batched PyTorch tensor code; needs ``pip install 'swarmpose[torch]'``) and ``"reference"`` (plain
numpy/OpenCV, slow, used by the tests). A backend is an entry in
:data:`swarmpose.fitness.backends.BACKENDS` implementing ``prepare``/``measure``.

Per-frame state
---------------
``fitness.prepare(frame)`` / ``bind`` build one :class:`PreparedFrame`: row prefix sums of the
silhouettes, ``|O|`` per view, the edge maps, camera tables; its ``prepare_ms`` is the time taken.
Pyramid levels come from :meth:`FrameFeatures.downsample` (cameras rescaled with them).
"""

from __future__ import annotations

from typing import Any

from swarmpose.errors import ConfigError
from swarmpose.fitness.backends import BACKENDS, Measurements, PreparedFrame, prepare_frame
from swarmpose.fitness.base import (
    Fitness,
    ImageOptions,
    deutscher_reid_log_weight,
    edge_score,
    silhouette_score,
)
from swarmpose.fitness.image import DeutscherReidFitness, ImageFitness, SilhouetteEdgeFitness
from swarmpose.fitness.markers import MarkerFitness, MarkerFrame, ReprojectionFitness
from swarmpose.fitness.torch_backend import TorchBackend, torch_available

BACKENDS["torch"] = TorchBackend  # imports torch only when constructed

__all__ = [
    "BACKENDS",
    "KINDS",
    "DeutscherReidFitness",
    "Fitness",
    "ImageFitness",
    "ImageOptions",
    "MarkerFitness",
    "MarkerFrame",
    "Measurements",
    "PreparedFrame",
    "ReprojectionFitness",
    "SilhouetteEdgeFitness",
    "deutscher_reid_log_weight",
    "edge_score",
    "make_fitness",
    "prepare_frame",
    "silhouette_score",
    "torch_available",
]

#: Fitness kinds known to :func:`make_fitness`.
KINDS: dict[str, type] = {
    "silhouette_edge": SilhouetteEdgeFitness,
    "deutscher_reid": DeutscherReidFitness,
    "markers": MarkerFitness,
    "reprojection": ReprojectionFitness,
}


def make_fitness(kind: str, model, *, backend: str = "numba", **options: Any) -> Fitness:
    """Build a fitness function by name.

    Parameters
    ----------
    kind : {"silhouette_edge", "deutscher_reid", "markers", "reprojection"}
    model : BodyModel
    backend : {"numba", "torch", "reference"}, default "numba"
        ``"torch"`` for the image kinds only; its settings (``device``, ``dtype``, ``max_elements``) go in
        ``backend_options``.
    **options :
        Keyword arguments of the class (e.g. ``edge_cones``, ``edge_spacing``, ``a``, ``rho``,
        ``penalty``, ``tau``).

    Returns
    -------
    Fitness
        Unbound; call ``bind(frame)`` before evaluating.

    Raises
    ------
    ConfigError
        Unknown kind or backend (the message lists the known ones), or a bad option.
    """
    try:
        cls = KINDS[kind]
    except (KeyError, TypeError):
        raise ConfigError(f"unknown fitness kind {kind!r} (known: {', '.join(KINDS)})") from None
    known_backends = ("numba", "reference") if cls in (MarkerFitness, ReprojectionFitness) else tuple(BACKENDS)
    if backend not in known_backends:
        raise ConfigError(f"unknown fitness backend {backend!r} for {kind!r} (known: {', '.join(known_backends)})")
    try:
        return cls(model, backend=backend, **options)
    except TypeError as e:  # unexpected keyword
        raise ConfigError(f"bad option for fitness {kind!r}: {e}") from None
