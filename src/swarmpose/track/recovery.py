"""Loss detection and recovery of limbs (design.md sec. 7).

After a frame's search the tracker asks the fitness how well each cone is explained by the observation
(:meth:`~swarmpose.fitness.image.ImageFitness.part_agreement`: the cone's model-to-silhouette distance
term, averaged over the views; 0 when the cone lies inside every observed silhouette). A limb whose
worst cone is above ``threshold`` counts as *lost*: its parameters are searched again that frame over
their whole joint-limit box (:class:`~swarmpose.optim.refine.BoxSearch`, the rest of the body held),
then polished by a short pattern search of the same parameters. The new limb is kept only when the
frame's fitness prefers it. The optimisers know nothing of limbs: they get a mask and bounds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from swarmpose.errors import ConfigError
from swarmpose.optim.base import optimize
from swarmpose.optim.refine import BoxSearch, PatternSearch

__all__ = ["LIMBS", "Recovery", "RecoveryResult"]

#: Limb name -> (its cones, its parameter group) in the shipped body models.
LIMBS: dict[str, tuple[tuple[str, ...], str]] = {
    "left_arm": (("l_upper_arm", "l_lower_arm"), "left_arm"),
    "right_arm": (("r_upper_arm", "r_lower_arm"), "right_arm"),
    "left_leg": (("l_thigh", "l_calf"), "left_leg"),
    "right_leg": (("r_thigh", "r_calf"), "right_leg"),
}


@dataclass
class RecoveryResult:
    """What one frame's recovery did."""

    x: np.ndarray
    evaluations: int = 0
    lost: list[str] = field(default_factory=list)
    recovered: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class Recovery:
    """Per-limb loss detection and wide re-search.

    Attributes
    ----------
    threshold : float
        A limb is lost when one of its cones' disagreement (``[0, 1]``) is above this.
    n_samples, n_rounds : int
        The box search: ``1 + n_samples * n_rounds`` evaluations per lost limb.
    refine_budget : int
        Pattern-search evaluations on the limb's parameters after the box search.
    terms : str
        The fitness terms the search and the acceptance use: ``"distance"`` (default), the silhouette
        distance term, which still rises towards an arm 50-100 mm away where the overlap terms are flat;
        ``"fitness"``: the frame's own fitness as the run scores it.
    margin : float
        The searched-again limb is kept only when it scores more than this above the limb it replaces (0:
        any gain): a limb the fitness cannot tell from another place stays where the track had it.
    jump : float
        The searched-again limb is kept only when it scores more than ``margin + jump * d / 100`` above the limb it
        replaces, ``d`` the largest move in mm of a joint between the two (the rest of the body is held, so only the
        limb's joints move): a limb moves far from where the frame's search left it only on clear evidence (0: no
        such term).
    guard : str
        ``""``: the searched limb is kept on its score alone. ``"silhouette"``: it is kept only when the silhouette
        overlap term does not fall either (two more evaluations per searched limb), so that a limb the edges
        alone pull elsewhere (an arm folded over the head's outline) stays where the track had it.
    in_turn : int
        0: every lost limb is searched again on every frame. K >= 1: only K limbs per frame are looked at, in
        turn by the frame's position (``position * K``, ``position * K + 1``, ... modulo the number of limbs), and
        searched again when lost: with every limb counted as lost, each limb is searched every ``4 / K`` frames
        at ``K / 4`` of the cost.
    """

    threshold: float = 0.05
    n_samples: int = 100
    n_rounds: int = 5
    refine_budget: int = 100
    terms: str = "distance"
    margin: float = 0.0
    guard: str = ""
    in_turn: int = 0
    jump: float = 0.0

    @classmethod
    def from_settings(cls, settings: Mapping[str, Any]) -> Recovery | None:
        """From an optimiser configuration's ``recovery`` mapping (``None`` when it is empty)."""
        if not settings:
            return None
        unknown = set(settings) - {"threshold", "n_samples", "n_rounds", "refine_budget", "terms", "margin",
                                   "guard", "in_turn", "jump"}
        if unknown:
            raise ConfigError(f"unknown recovery setting(s) {sorted(unknown)}")
        return cls(**dict(settings))

    def limbs(self, model: Any) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Limb -> (cone indices, parameter indices) for the limbs ``model`` has."""
        names = model.cone_arrays.names
        out = {}
        for limb, (cones, group) in LIMBS.items():
            if all(c in names for c in cones) and group in model.groups:
                out[limb] = (np.array([names.index(c) for c in cones]), np.asarray(model.group(group)))
        return out

    def looked_at(self, model: Any, position: int, limbs: Mapping[str, Any] | None = None) -> list[str]:
        """The limbs looked at on the frame at ``position``: every limb, or ``in_turn`` of them in turn (``limbs``:
        :meth:`limbs` of ``model``, when already at hand)."""
        names = list(self.limbs(model) if limbs is None else limbs)
        if not self.in_turn or self.in_turn >= len(names):
            return names
        turn = {(position * self.in_turn + j) % len(names) for j in range(self.in_turn)}
        return [name for k, name in enumerate(names) if k in turn]

    def lost(self, fitness: Any, model: Any, x: np.ndarray, position: int = 0) -> list[str]:
        """The limbs of pose ``x`` (looked at on the frame at ``position``) whose worst cone disagrees with the
        observation by more than ``threshold``."""
        limbs = self.limbs(model)
        names = self.looked_at(model, position, limbs)
        if self.threshold < 0:  # every limb counts as lost: nothing to measure
            return names
        parts = fitness.part_agreement(np.asarray(x, np.float64)[None])[0]
        return [limb for limb in names if parts[limbs[limb][0]].max() > self.threshold]

    def jump_margin(self, model: Any, x: np.ndarray, cand: np.ndarray) -> float:
        """The score margin :attr:`jump` asks of pose ``cand`` to replace pose ``x``: ``jump`` per 100 mm of the
        largest move of one of the 15 joints between them (0 without ``jump``)."""
        if not self.jump:
            return 0.0
        joints = model.joints15(np.stack([x, cand]))
        return self.jump * float(np.linalg.norm(joints[1] - joints[0], axis=-1).max()) / 100.0

    def run(self, fitness: Any, model: Any, x: np.ndarray, rng: np.random.Generator,
            constraint: Callable[[np.ndarray], np.ndarray] | None, sigma: np.ndarray,
            options: Mapping[str, Any] | None = None, position: int = 0) -> RecoveryResult:
        """Detect the lost limbs of ``x`` and search each again; returns the (possibly) improved pose.

        ``sigma``: the search's per-parameter spread at this frame rate (the polishing step is half of it);
        ``position``: the frame's position in the sequence (which limbs are looked at, with ``in_turn``).
        """
        x = np.array(x, dtype=np.float64)
        result = RecoveryResult(x=x)
        # "fitness": the frame's own fitness (its terms as the run gives them); else the named terms
        options = dict(options or {}) if self.terms == "fitness" else {**dict(options or {}), "terms": self.terms}
        options = options or None
        limbs = self.limbs(model)
        for limb in self.lost(fitness, model, x, position):
            result.lost.append(limb)
            mask = np.zeros(x.size, bool)
            mask[limbs[limb][1]] = True
            search = BoxSearch(x, mask, model.lower, model.upper, rng, n_samples=self.n_samples,
                               n_rounds=self.n_rounds, constraint=constraint)
            first: list[float] = []  # the box search's first pose is the limb as tracked

            def score_of(poses: np.ndarray, first: list[float] = first) -> np.ndarray:
                s = fitness.evaluate(poses, options)
                if not first:
                    first.append(float(s[0]) if np.isfinite(s[0]) else -np.inf)
                return s

            found = optimize(search, score_of)
            result.evaluations += found.evaluations
            cand, score = found.x, found.score
            if self.refine_budget:
                step = np.where(mask, 0.5 * np.asarray(sigma), 0.0)
                ps = PatternSearch(cand, step, self.refine_budget, lower=model.lower, upper=model.upper,
                                   constraint=constraint)
                polished = optimize(ps, lambda poses: fitness.evaluate(poses, options))
                result.evaluations += polished.evaluations
                cand, score = polished.x, polished.score
            keep = score > first[0] + self.margin + self.jump_margin(model, x, cand)
            if keep and self.guard:
                sil = fitness.evaluate(np.stack([x, cand]), {**(options or {}), "terms": self.guard})
                result.evaluations += 2
                keep = bool(sil[1] >= sil[0])
            if keep:
                x = np.array(cand)
                result.recovered.append(limb)
        result.x = x
        return result
