"""Offline smoothing of a track's poses over time (``track --smooth S``).

A frame-by-frame tracker answers each frame on its own, so its joints jitter from frame to frame by more than
the motion does. For a recording tracked offline, the pose parameters are smoothed over time with a
zero-phase Gaussian of standard deviation ``S`` seconds (``scipy.ndimage.gaussian_filter1d``; the sequence's
median frame interval turns it into frames), the unbounded rotations unwrapped first so that a heading crossing
+-pi is not averaged through zero, then kept inside the joint limits. Non-causal: frame ``t`` uses frames after it. The
collision priors are not checked again.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from swarmpose.errors import ConfigError

__all__ = ["smooth_params"]


def smooth_params(params: np.ndarray, times: np.ndarray, sigma_s: float, is_rotation: np.ndarray,
                  lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``params (T, D)`` smoothed over time (module docstring); ``times (T,)`` s; ``sigma_s`` 0: unchanged."""
    if not np.isfinite(sigma_s) or sigma_s < 0:
        raise ConfigError(f"smoothing must be a time in seconds >= 0, got {sigma_s!r}")
    p = np.array(params, dtype=np.float64)
    if sigma_s == 0 or len(p) < 2:
        return p
    dt = float(np.median(np.diff(np.asarray(times, dtype=np.float64))))
    if not dt > 0:
        raise ConfigError("smoothing needs increasing frame times")
    # unbounded rotations (the heading) are unwrapped; a bounded one cannot wrap, and unwrapping a genuine jump
    # of more than pi (a limb the tracker moved far) would shift the rest of its track by 2 pi
    free = np.asarray(is_rotation, dtype=bool) & ~(np.isfinite(lower) & np.isfinite(upper))
    p[:, free] = np.unwrap(p[:, free], axis=0)
    p = gaussian_filter1d(p, sigma_s / dt, axis=0, mode="nearest")
    return np.clip(p, lower, upper)
