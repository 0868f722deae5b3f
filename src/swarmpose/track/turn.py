"""The body's heading searched again each frame: the pose turned about the vertical through the pelvis.

The pelvis and trunk cones are nearly round about the vertical, so the pelvis's heading is seen only through
where the hips and the spine attach to it. A track can then fall behind a turn with both hips and the spine
twisted to make up for it (``cmu_16_18_turn`` at 20 fps: the pelvis 45 degrees behind, both hips at their 45-degree
rotation limits, the truth scoring higher on most of those frames), or lose a fast spin altogether
(``cmu_131_03_hop``: 240 degrees in 18 frames, the track left facing 130 degrees off). The search's own
steps never make a turn of the pelvis that keeps the legs and the trunk in place, so it is asked for directly:

* the whole pose turned by each of :attr:`TurnSearch.whole` degrees (``pelvis_rz``, the root's first rotation,
  is a turn about the world's vertical through the pelvis);
* the pelvis alone turned by each of :attr:`TurnSearch.pelvis` degrees, the hips' and the spine's rotations
  about their own long axes turned back by as much (exact when the thighs hang and the trunk stands upright;
  the polish does the rest).

With ``keypoints`` (a sequence with a detector's keypoints), both are also tried by the turn that lays the model's
hip line onto the keypoints' triangulated hips, seen from above (:func:`keypoint_turn`).

The candidates are scored in one batch with the frame's fitness; the best :attr:`TurnSearch.n_best` are
polished by a pattern search of every parameter, and the best polished pose replaces the frame's pose when it
scores higher (and, with ``guard``, when the guard's terms do not fall either).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.joints import JOINT_INDEX
from swarmpose.optim.refine import polish_best

__all__ = ["TurnSearch", "TurnResult", "turn_candidates", "keypoint_turn"]

#: The parameters turned back when the pelvis alone turns: a joint's rotation about its own long axis (the
#: last elementary rotation of the root's children in the shipped models) and its axis sign.
_TWISTS = ("l_hip_rot", "r_hip_rot", "spine_twist")


def _twist_signs(model: Any) -> list[tuple[int, float]]:
    """(parameter index, sign) of the root's children's rotations about their ``z`` axis named in ``_TWISTS``:
    the pelvis turned by ``d`` is made up for by ``param -= sign * d`` (``sign`` -1 for a ``-z`` axis)."""
    root = next(j.name for j in model.spec.joints if j.parent is None)
    out = []
    for joint in model.spec.joints:
        if joint.parent != root:
            continue
        for axis, param in joint.rotation:
            if param in _TWISTS and axis in ("z", "-z"):
                out.append((model.param_index(param), -1.0 if axis == "-z" else 1.0))
    return out


def turn_candidates(model: Any, x: np.ndarray, whole: tuple[float, ...], pelvis: tuple[float, ...]) -> np.ndarray:
    """``(len(whole) + len(pelvis), D)``: ``x`` turned as a whole by each of ``whole`` degrees, then its pelvis
    alone by each of ``pelvis`` degrees (module docstring), clipped into the limits."""
    x = np.asarray(x, dtype=np.float64)
    rz = model.param_index("pelvis_rz")
    lower, upper = np.asarray(model.lower), np.asarray(model.upper)
    d = np.radians(np.concatenate([np.asarray(whole, float), np.asarray(pelvis, float)]))
    cands = np.repeat(x[None], d.size, axis=0)
    cands[:, rz] = x[rz] + d
    alone = np.arange(len(whole), d.size)
    for k, sign in _twist_signs(model):
        cands[alone, k] -= sign * d[alone]
    return np.clip(cands, lower, upper)


def _hip_heading(joints: np.ndarray) -> float:
    """The heading (radians, about the world's vertical z) of the line from the left hip to the right hip."""
    d = np.asarray(joints)[JOINT_INDEX["r_hip"]] - np.asarray(joints)[JOINT_INDEX["l_hip"]]
    return float(np.arctan2(d[1], d[0]))


def keypoint_turn(model: Any, x: np.ndarray, joints: np.ndarray, least: float = 5.0) -> float | None:
    """Degrees of ``pelvis_rz`` that turn pose ``x``'s hip line onto that of ``joints (15, 3)`` (the frame's
    triangulated keypoints) seen from above; None where a hip is missing or the turn is under ``least`` degrees."""
    j = np.asarray(joints, dtype=np.float64)
    if not np.isfinite(j[[JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]]]).all():
        return None
    own = model.joints15(np.asarray(x, dtype=np.float64)[None])[0]
    d = (_hip_heading(j) - _hip_heading(own) + np.pi) % (2 * np.pi) - np.pi
    if abs(np.degrees(d)) < least:
        return None
    rz = model.param_index("pelvis_rz")
    turned = np.array(x, dtype=np.float64)
    turned[rz] += d  # pelvis_rz's sign: the turn that brings the hips nearer is the one asked for
    after = _hip_heading(model.joints15(turned[None])[0])
    if abs((_hip_heading(j) - after + np.pi) % (2 * np.pi) - np.pi) > abs(d):
        d = -d
    return float(np.degrees(d))


@dataclass
class TurnResult:
    """What one frame's turn search did: the pose (turned or not), its score when turned, the evaluations and
    the degrees of the turn kept (0: none)."""

    x: np.ndarray
    score: float | None = None
    evaluations: int = 0
    turned: float = 0.0


@dataclass(frozen=True)
class TurnSearch:
    """The turn search (module docstring).

    Attributes
    ----------
    whole, pelvis : tuple of float
        The turns of the whole pose and of the pelvis alone tried (degrees).
    n_best : int
        Candidates polished.
    budget : int
        Pattern-search evaluations per polished candidate (its step half the search's spread).
    guard : str
        ``""`` or fitness terms (``"silhouette"``) that must not fall either for a turned pose to be kept (two
        evaluations).
    margin : float
        A turned pose is kept only when it scores more than this above the frame's pose.
    keypoints : bool
        Also try the turn that lays the hips onto the frame's triangulated keypoints (:func:`keypoint_turn`).
    """

    whole: tuple[float, ...]
    pelvis: tuple[float, ...]
    n_best: int
    budget: int
    guard: str = ""
    margin: float = 0.0
    keypoints: bool = False

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any]) -> TurnSearch | None:
        """From an optimiser configuration's ``turn_search`` mapping (``None`` when it is empty)."""
        if not settings:
            return None
        unknown = set(settings) - {"whole", "pelvis", "n_best", "budget", "guard", "margin", "keypoints"}
        if unknown:
            raise ConfigError(f"unknown turn search setting(s) {sorted(unknown)}")
        s = dict(settings)
        return cls(whole=tuple(map(float, s["whole"])), pelvis=tuple(map(float, s["pelvis"])),
                   n_best=int(s["n_best"]), budget=int(s["budget"]), guard=str(s.get("guard", "")),
                   margin=float(s.get("margin", 0.0)), keypoints=bool(s.get("keypoints", False)))

    def __post_init__(self) -> None:
        if self.n_best < 1 or self.budget < 1:
            raise ConfigError(f"turn search: n_best and budget must be >= 1, got {self.n_best}, {self.budget}")
        if not (np.isfinite(self.margin) and self.margin >= 0):
            raise ConfigError(f"turn search: margin must be a score >= 0, got {self.margin}")
        if self.n_best > len(self.whole) + len(self.pelvis):
            raise ConfigError(f"turn search: n_best {self.n_best} is more than the {len(self.whole) + len(self.pelvis)} "
                              "turns tried")

    def run(self, fitness: Any, model: Any, x: np.ndarray, constraint: Callable[[np.ndarray], np.ndarray] | None,
            sigma: np.ndarray, options: Mapping[str, Any] | None = None,
            extra: tuple[float, ...] = ()) -> TurnResult:
        """Search the turns of ``x`` (scored with ``options``), the whole pose and the pelvis alone also by each of
        ``extra`` degrees; returns the pose to go on from."""
        x = np.array(x, dtype=np.float64)
        whole, pelvis = (*self.whole, *extra), (*self.pelvis, *extra)
        cands = turn_candidates(model, x, whole, pelvis)
        ok = np.ones(len(cands), bool) if constraint is None else np.asarray(constraint(cands), dtype=bool)
        scores = np.nan_to_num(np.asarray(fitness.evaluate(np.vstack([x[None], cands[ok]]), options), float),
                               nan=-np.inf)
        result = TurnResult(x=x, evaluations=1 + int(ok.sum()))
        here, turned = scores[0], scores[1:]
        idx = np.flatnonzero(ok)
        best_x, best_score, k, n = polish_best(lambda poses: fitness.evaluate(poses, options), cands[idx], turned,
                                               self.n_best, 0.5 * np.asarray(sigma, dtype=np.float64), self.budget,
                                               model.lower, model.upper, constraint, above=here + self.margin)
        result.evaluations += n
        if k < 0:
            return result
        best_k = int(idx[k])
        if self.guard:
            g = fitness.evaluate(np.stack([x, best_x]), {**dict(options or {}), "terms": self.guard})
            result.evaluations += 2
            if not g[1] >= g[0]:
                return result
        degrees = (*whole, *pelvis)[best_k]
        return TurnResult(x=best_x, score=best_score, evaluations=result.evaluations, turned=float(degrees))
