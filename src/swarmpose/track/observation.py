"""One frame's observation as the tracker's fitness consumes it: image features or 2D marker detections.

Image fitnesses get :class:`swarmpose.features.FrameFeatures`: the stored silhouettes when the sequence has
them (an imported recording's learned segmentation), else background subtraction; edge maps; and the
detector's keypoints where the sequence carries them. A feature store (:mod:`swarmpose.track.feature_store`)
keeps the binary maps between runs. Marker fitnesses get the frame's detections. Only the
tracked views (``track --views``) are included.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np

from swarmpose.errors import DataError

__all__ = ["frame_observation", "IMAGE_FITNESS", "MARKER_FITNESS", "Prefetcher"]

#: The fitness kinds that read images, and those that read 2D markers.
IMAGE_FITNESS = ("silhouette_edge", "deutscher_reid")
MARKER_FITNESS = ("markers", "reprojection")


def frame_observation(seq: Any, k: int, kind: str, downsample: int, backgrounds: Any,
                       feature_options: tuple[dict, dict] = ({}, {}), views: list[int] | None = None,
                       keypoints: tuple[np.ndarray, np.ndarray] | None = None, store: Any = None):
    """One frame's observation; ``feature_options`` = :func:`swarmpose.features.parse_feature_options`'s pair;
    ``views``: the cameras tracked with (default all); ``keypoints``: the whole sequence's labelled keypoints
    ``(T, C, 15, 2)`` and confidences ``(T, C, 15)`` when it has them (carried for the keypoint term);
    ``store``: a :class:`swarmpose.track.feature_store.FeatureStore` of this sequence, views and options, which
    gives the frame's binary features when it has them and keeps them when they are computed here."""
    v = list(range(seq.n_views)) if views is None else list(views)
    cams = [seq.cameras[c] for c in v]
    if kind in MARKER_FITNESS:
        from swarmpose.fitness import MarkerFrame

        markers = seq.markers(k)
        if markers is None:
            raise DataError(f"{getattr(seq, 'path', seq)}: frame {k} has no 2D marker detections (needed by the "
                            f"{kind} fitness)")
        return MarkerFrame([markers[c] for c in v], cams)
    from swarmpose.features import binary_features, features_from_binary

    sil_opts, edge_opts = feature_options
    kp = None if keypoints is None else (keypoints[0][k][v], keypoints[1][k][v])
    maps = None if store is None else store.get(k)
    if maps is None:
        images = seq.images(k)
        if images is None:
            raise DataError(f"{getattr(seq, 'path', seq)}: frame {k} has no images (needed by the {kind} fitness)")
        stored = seq.silhouettes(k)  # a learned segmentation imported with a recording, used as it is
        if stored is None and backgrounds is None:
            raise DataError(f"{getattr(seq, 'path', seq)}: has neither silhouettes nor background images (needed by "
                            f"the {kind} fitness); import the recording with --silhouettes learned or median")
        if len(v) != seq.n_views:
            images = images[v]
            stored = None if stored is None else stored[v]
            backgrounds = None if backgrounds is None else np.asarray(backgrounds)[v]
        maps = binary_features(images, backgrounds, silhouette_options=sil_opts, edge_options=edge_opts,
                               silhouettes=stored)
        if store is not None:
            store.put(k, *maps)
    return features_from_binary(*maps, cams, edge_options=edge_opts, downsample=downsample, keypoints=kp)


def _lower_priority() -> None:
    """Lowest priority (nice 19) for the calling thread, where the system allows it (Linux: per thread)."""
    import os
    import threading

    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 19)
    except (AttributeError, OSError):
        pass


class Prefetcher:
    """Frame ``i + 1``'s observation read and computed on a worker thread while frame ``i`` is tracked.

    ``load(i)`` makes position ``i``'s observation; :meth:`get` returns it (computed now unless it was already
    asked for) and starts position ``i + 1`` on the worker. Image decoding and OpenCV release the GIL, so the
    next frame's features overlap the optimiser's single-threaded Python work; the worker runs at the lowest
    scheduling priority (Linux), so that it takes the cores the fitness kernels leave idle. At most one load runs at a time,
    always on the worker thread once started, so the sequence is never read from two threads at once. A load's
    error is raised by the :meth:`get` that asks for that position. Use as a context manager (or call
    :meth:`close`) to stop the worker.
    """

    def __init__(self, load: Callable[[int], Any], n: int, *, enabled: bool = True):
        self._load = load
        self._n = int(n)
        self._pool = (ThreadPoolExecutor(max_workers=1, thread_name_prefix="swarmpose-prefetch", initializer=_lower_priority)
                      if enabled else None)
        self._pending: tuple[int, Future] | None = None

    def get(self, i: int) -> Any:
        """Position ``i``'s observation; starts position ``i + 1`` in the background."""
        if self._pool is None:
            return self._load(i)
        fut = None
        if self._pending is not None:
            j, f = self._pending
            self._pending = None
            if j == i:
                fut = f
            else:  # not the frame asked for: let it finish (one load at a time), then drop it
                f.exception()
        if fut is None:
            fut = self._pool.submit(self._load, i)
        obs = fut.result()
        if i + 1 < self._n:
            self._pending = (i + 1, self._pool.submit(self._load, i + 1))
        return obs

    def close(self) -> None:
        """Wait for the load in flight (its result or error is dropped) and stop the worker."""
        if self._pending is not None:
            self._pending[1].exception()
            self._pending = None
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def __enter__(self) -> Prefetcher:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
