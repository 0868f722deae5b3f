"""One frame's observation as the tracker's fitness consumes it: image features or 2D marker detections.

Image fitnesses get :class:`swarmpose.features.FrameFeatures`: the stored silhouettes when the sequence has
them (an imported recording's learned segmentation), else background subtraction; edge maps; and the
detector's keypoints where the sequence carries them. Marker fitnesses get the frame's detections. Only the
tracked views (``track --views``) are included.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from swarmpose.errors import DataError

__all__ = ["frame_observation", "IMAGE_FITNESS", "MARKER_FITNESS"]

#: The fitness kinds that read images, and those that read 2D markers.
IMAGE_FITNESS = ("silhouette_edge", "deutscher_reid")
MARKER_FITNESS = ("markers", "reprojection")


def frame_observation(seq: Any, k: int, kind: str, downsample: int, backgrounds: Any,
                       feature_options: tuple[dict, dict] = ({}, {}), views: list[int] | None = None,
                       keypoints: tuple[np.ndarray, np.ndarray] | None = None):
    """One frame's observation; ``feature_options`` = :func:`swarmpose.features.parse_feature_options`'s pair;
    ``views``: the cameras tracked with (default all); ``keypoints``: the whole sequence's labelled keypoints
    ``(T, C, 15, 2)`` and confidences ``(T, C, 15)`` when it has them (carried for the keypoint term)."""
    v = list(range(seq.n_views)) if views is None else list(views)
    cams = [seq.cameras[c] for c in v]
    if kind in MARKER_FITNESS:
        from swarmpose.fitness import MarkerFrame

        markers = seq.markers(k)
        if markers is None:
            raise DataError(f"{getattr(seq, 'path', seq)}: frame {k} has no 2D marker detections (needed by the "
                            f"{kind} fitness)")
        return MarkerFrame([markers[c] for c in v], cams)
    from swarmpose.features import compute_features

    images = seq.images(k)
    if images is None:
        raise DataError(f"{getattr(seq, 'path', seq)}: frame {k} has no images (needed by the {kind} fitness)")
    sil_opts, edge_opts = feature_options
    stored = seq.silhouettes(k)  # a learned segmentation imported with a recording, used as it is
    if stored is None and backgrounds is None:
        raise DataError(f"{getattr(seq, 'path', seq)}: has neither silhouettes nor background images (needed by the "
                        f"{kind} fitness); import the recording with --silhouettes learned or median")
    if len(v) != seq.n_views:
        images = images[v]
        stored = None if stored is None else stored[v]
        backgrounds = None if backgrounds is None else np.asarray(backgrounds)[v]
    kp = None if keypoints is None else (keypoints[0][k][v], keypoints[1][k][v])
    return compute_features(images, backgrounds, cams, downsample=downsample, silhouette_options=sil_opts,
                            edge_options=edge_opts, silhouettes=stored, keypoints=kp)
