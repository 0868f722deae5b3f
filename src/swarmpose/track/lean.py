"""The trunk's lean searched again: the pelvis pitched against the spine (beyond the papers).

A trunk that leans forward by its spine (a crouch, a hop's landing) and one that leans by its pelvis, the spine
straightened and the hips bent to keep the legs, put the shoulders, the head and the arms in the same place; they
differ in the hips' positions and in the torso cone, which hangs on the pelvis. The tracker's searches seldom move
the three together (the APF draws every parameter alone, the pattern search moves one at a time), and on the default's
misses every run of the hop was found pitched 21-37 degrees further forward than the truth's IK pose, the spine
straightened by about as much, where the truth's basin scores higher (``docs/results.md``, members).

:class:`LeanSearch` tries, for each of ``degrees`` d, the frame's pose with the pelvis pitched by d (``pelvis_ry``),
the spine's flexion by -d and both hips' flexion by +d (:func:`lean_candidates`: the shoulders and the head do not
move, the spine turning about the pelvis's origin), clipped to the joint limits; the ``n_best`` best of them are
polished by a pattern search of ``budget`` evaluations, and the best is kept when it scores above the frame's pose.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.optim.refine import polish_best

__all__ = ["LeanResult", "LeanSearch", "lean_candidates", "require_lean_parameters", "LEAN_PARAMETERS"]

#: The parameters a lean moves, and by how much of it: the pelvis's pitch +d, the spine's flexion -d, both hips'
#: flexion +d.
LEAN_PARAMETERS: tuple[tuple[str, float], ...] = (("pelvis_ry", 1.0), ("spine_flex", -1.0), ("l_hip_flex", 1.0),
                                                  ("r_hip_flex", 1.0))


def require_lean_parameters(model: Any) -> None:
    """Raise ConfigError, naming them, where ``model`` lacks one of :data:`LEAN_PARAMETERS`."""
    names = set(model.param_names)
    missing = [n for n, _ in LEAN_PARAMETERS if n not in names]
    if missing:
        raise ConfigError(f"the lean search needs the parameters {', '.join(missing)}, which body model "
                          f"{model.name!r} has not")


def lean_candidates(model: Any, x: np.ndarray, degrees: tuple[float, ...]) -> np.ndarray:
    """``(len(degrees), D)``: pose ``x`` leaned by each of ``degrees`` (:data:`LEAN_PARAMETERS`), clipped to the
    joint limits. Raises ConfigError where the model lacks one of the parameters."""
    require_lean_parameters(model)
    x = np.asarray(x, dtype=np.float64)
    out = np.repeat(x[None], len(degrees), axis=0)
    d = np.radians(np.asarray(degrees, dtype=np.float64))
    for name, sign in LEAN_PARAMETERS:
        out[:, model.param_index(name)] += sign * d
    return np.clip(out, model.lower, model.upper)


@dataclass
class LeanResult:
    """What one frame's lean search did: the pose to go on from, its score, the evaluations, and the lean kept
    (degrees of the candidate it came from; 0: the frame's pose stayed)."""

    x: np.ndarray
    score: float = float("nan")
    evaluations: int = 0
    leaned: float = 0.0


@dataclass(frozen=True)
class LeanSearch:
    """The lean candidates ``degrees``, the ``n_best`` of them polished by ``budget`` pattern-search evaluations
    each (module docstring)."""

    degrees: tuple[float, ...]
    n_best: int
    budget: int

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any]) -> LeanSearch | None:
        """From an optimiser configuration's ``lean_search`` mapping (``None`` when it is empty)."""
        if not settings:
            return None
        unknown = set(settings) - {"degrees", "n_best", "budget"}
        if unknown:
            raise ConfigError(f"unknown lean search setting(s) {sorted(unknown)}")
        return cls(degrees=tuple(map(float, settings["degrees"])), n_best=int(settings["n_best"]),
                   budget=int(settings["budget"]))

    def __post_init__(self) -> None:
        if not self.degrees or not all(np.isfinite(self.degrees)) or 0.0 in self.degrees:
            raise ConfigError(f"lean search: degrees must be finite and not 0, got {self.degrees}")
        if not 1 <= self.n_best <= len(self.degrees) or self.budget < 1:
            raise ConfigError(f"lean search: n_best must be 1 to {len(self.degrees)} and budget >= 1, got "
                              f"{self.n_best}, {self.budget}")

    @property
    def evaluations(self) -> int:
        """At most, per frame: the pose, the candidates, the polishes."""
        return 1 + len(self.degrees) + self.n_best * self.budget

    def run(self, fitness: Any, model: Any, x: np.ndarray, constraint: Callable[[np.ndarray], np.ndarray] | None,
            sigma: np.ndarray, options: Mapping[str, Any] | None = None) -> LeanResult:
        """Search the leans of ``x`` (scored with ``options``; the polish steps half of ``sigma``); returns the pose
        to go on from."""
        x = np.array(x, dtype=np.float64)
        cands = lean_candidates(model, x, self.degrees)
        ok = np.ones(len(cands), bool) if constraint is None else np.asarray(constraint(cands), dtype=bool)
        scores = np.nan_to_num(np.asarray(fitness.evaluate(np.vstack([x[None], cands[ok]]), options), float),
                               nan=-np.inf)
        result = LeanResult(x=x, score=float(scores[0]), evaluations=1 + int(ok.sum()))
        idx = np.flatnonzero(ok)
        best_x, best_score, k, n = polish_best(lambda poses: fitness.evaluate(poses, options), cands[idx], scores[1:],
                                               self.n_best, 0.5 * np.asarray(sigma, dtype=np.float64), self.budget,
                                               model.lower, model.upper, constraint, above=result.score)
        result.evaluations += n
        if k >= 0:
            result.x, result.score, result.leaned = best_x, best_score, float(self.degrees[idx[k]])
        return result
