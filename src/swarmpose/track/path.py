"""The offline pass's choice of pose per frame, made as one path over the frames.

With ``--backward`` every frame has two candidate poses: the forward pass's and the backward pass's (limbs of
both, :func:`swarmpose.track.step.mix_limbs`). Chosen frame by frame, the fitness alone decides, and now and
then it prefers a pose with a limb far off that no neighbouring frame has (the evidence of one frame is
ambiguous; the motion is not). Here the choice ``c_0 .. c_{T-1}`` maximises over all paths

    sum_t s[t, c_t]  -  w * sum_{t >= 1} (d(t, c_{t-1}, c_t) / 100 mm)^2,

``s`` the frame's fitness of each candidate, ``d`` the mean distance of the 15 joints between the poses chosen
at frames ``t - 1`` and ``t``: a first-order smoothness cost, the path found exactly by dynamic programming
(Viterbi 1967; Forney 1973, "The Viterbi algorithm", Proc. IEEE 61(3)), in ``O(T K^2)``. ``w = 0`` is the
frame-by-frame choice. :func:`best_path_reference` is the brute force over all ``K^T`` paths it is tested
against.
"""

from __future__ import annotations

import itertools

import numpy as np

from swarmpose.errors import ConfigError, ShapeError

__all__ = ["DEFAULT_PATH_WEIGHT", "JOINT_STEP_MM", "best_path", "best_path_reference", "check_weight", "path_cost"]

#: ``w``: the weight of the smoothness cost against the frame's fitness (the image fitness with keypoints
#: lies in about [0, 1.2]). Measured on the 8 shared clips and their mirror images with 3 members and the
#: backward pass, 3 runs each: 0.1, 0.3 and 1 all lower the worst frames; 0.3 alone both lowers D_mean on both
#: sets and holds every limit on all 8 mirrored clips (docs/results.md, "Offline: the two passes' poses as one
#: path").
DEFAULT_PATH_WEIGHT = 0.3
#: The unit of the joints' step between frames in the smoothness cost, mm.
JOINT_STEP_MM = 100.0


def check_weight(weight: float, name: str = "the path's weight") -> None:
    """Raise ConfigError, naming ``name``, unless ``weight`` is a number >= 0."""
    if (isinstance(weight, bool) or not isinstance(weight, int | float | np.number)
            or not (np.isfinite(weight) and weight >= 0.0)):
        raise ConfigError(f"{name} must be a weight >= 0 (0: each frame chooses alone), got {weight!r}")


def _check(scores: np.ndarray, joints: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray]:
    s = np.asarray(scores, dtype=np.float64)
    j = np.asarray(joints, dtype=np.float64)
    if s.ndim != 2 or s.shape[0] < 1 or s.shape[1] < 1:
        raise ShapeError(f"scores must be (T, K) with T, K >= 1, got {s.shape}")
    if j.ndim != 4 or j.shape[:2] != s.shape or j.shape[3] != 3:
        raise ShapeError(f"joints must be (T, K, J, 3) with (T, K) = {s.shape}, got {j.shape}")
    if not (np.isfinite(s).all() and np.isfinite(j).all()):
        raise ValueError("scores and joints must be finite")
    check_weight(weight)
    return s, j


def _steps(j: np.ndarray, t: int) -> np.ndarray:
    """``(K, K)``: the cost unit ``(d / JOINT_STEP_MM)^2`` from candidate ``a`` at ``t - 1`` to ``b`` at ``t``."""
    d = np.linalg.norm(j[t][None, :] - j[t - 1][:, None], axis=-1).mean(axis=-1) / JOINT_STEP_MM
    return d * d


def best_path(scores: np.ndarray, joints: np.ndarray, weight: float = DEFAULT_PATH_WEIGHT) -> np.ndarray:
    """``(T,)`` int: per frame the index of the chosen candidate (module docstring).

    ``scores (T, K)``: each candidate's fitness (higher is better); ``joints (T, K, J, 3)``: its joints, mm;
    ``weight >= 0``. Ties go to the lower candidate index (where a frame's candidates are the same pose, the
    first is taken).
    """
    s, j = _check(scores, joints, weight)
    T, K = s.shape
    acc = -s[0]  # the least cost of a path ending in each candidate
    back = np.zeros((T, K), dtype=np.int64)
    for t in range(1, T):
        tot = acc[:, None] + weight * _steps(j, t)  # (previous, current)
        back[t] = np.argmin(tot, axis=0)
        acc = tot[back[t], np.arange(K)] - s[t]
    path = np.empty(T, dtype=np.int64)
    path[-1] = int(np.argmin(acc))
    for t in range(T - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path


def path_cost(scores: np.ndarray, joints: np.ndarray, weight: float, path: np.ndarray) -> float:
    """The cost ``-(sum s) + w * sum (d / 100 mm)^2`` of one ``path (T,)`` (what :func:`best_path` minimises)."""
    s, j = _check(scores, joints, weight)
    p = np.asarray(path, dtype=np.int64)
    cost = -float(s[np.arange(len(p)), p].sum())
    for t in range(1, len(p)):
        cost += weight * float(_steps(j, t)[p[t - 1], p[t]])
    return cost


def best_path_reference(scores: np.ndarray, joints: np.ndarray, weight: float = DEFAULT_PATH_WEIGHT) -> np.ndarray:
    """:func:`best_path` by trying every one of the ``K^T`` paths (for tests: small ``T`` and ``K``)."""
    s, _ = _check(scores, joints, weight)
    T, K = s.shape
    best, best_cost = None, np.inf
    for p in itertools.product(range(K), repeat=T):
        c = path_cost(scores, joints, weight, np.array(p))
        if c < best_cost - 1e-12:
            best, best_cost = np.array(p, dtype=np.int64), c
    return best
