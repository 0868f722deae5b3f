"""Staged search as data: a :class:`Stage` says which parameters move, how far, with how many particles.

Soft partitioning ([FL12] sec. 5.3.3) is expressed entirely by the per-parameter ``sigma`` scaling of a
stage: a parameter with scale 0 is held at the previous stage's estimate (hard partition), a scale below
1 lets it vary a little (soft partition), scale 1 is a full search. The same :class:`StagedSearch` driver
runs the constricted-PSO schedules (``sppso``, ``sppso3``, ``hard2``, ``pso-global``, ``hpso12``) and the
adaptive annealed PSO's six stages ([SH17] sec. 3.4); only the per-stage optimiser differs.

Each stage is a complete optimisation initialised at the previous stage's estimate ([FL12] sec. 5.3.3:
"the estimated pose from the first stage is used as the initialisation for the second stage").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .base import Candidate, ConfigError, Optimizer, as_vector, check_bounds, check_rng, frozen_options

__all__ = ["Stage", "StagedSearch", "StagedSwarm"]


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Stage:
    """One stage of a staged search.

    Attributes
    ----------
    name : str
        Label (e.g. ``"global"``, ``"left_arm"``).
    active : ndarray of bool, shape (D,)
        Parameters searched in this stage; the others are held at the incoming estimate.
    sigma_scale : ndarray, shape (D,)
        Factor on the per-parameter sigma (e.g. 0.1 for the root position in SPPSO stage 2).
    n_particles, n_iterations : int
        Swarm size and iterations; the stage costs ``n_particles * n_iterations`` evaluations
        (the initial swarm counts as iteration 1, [FL12] Algorithm 2).
    fitness_options : Mapping
        Options for the fitness during this stage, read by the tracker through
        ``Optimizer.fitness_options`` (e.g. ``{"edge_cones": "torso", "edge_top": True}``).
    """

    name: str
    active: np.ndarray
    sigma_scale: np.ndarray
    n_particles: int
    n_iterations: int
    fitness_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        active = np.asarray(self.active, dtype=bool)
        if active.ndim != 1:
            raise ConfigError(f"stage {self.name!r}: active must be 1-D, got shape {active.shape}")
        scale = as_vector(self.sigma_scale, active.shape[0], f"stage {self.name!r} sigma_scale")
        if not np.all(np.isfinite(scale)) or np.any(scale < 0):
            raise ConfigError(f"stage {self.name!r}: sigma_scale must be finite and >= 0")
        if not active.any():
            raise ConfigError(f"stage {self.name!r}: no active parameter")
        for attr in ("n_particles", "n_iterations"):
            v = getattr(self, attr)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ConfigError(f"stage {self.name!r}: {attr} must be an int >= 1, got {v!r}")
            object.__setattr__(self, attr, int(v))
        object.__setattr__(self, "active", _readonly(active))
        object.__setattr__(self, "sigma_scale", _readonly(scale))
        object.__setattr__(self, "fitness_options", frozen_options(self.fitness_options))

    @classmethod
    def from_groups(
        cls,
        name: str,
        d: int,
        scales: Mapping[Any, float] | Sequence[tuple[Any, float]],
        n_particles: int,
        n_iterations: int,
        fitness_options: Mapping[str, Any] | None = None,
    ) -> Stage:
        """Build a stage from ``{indices: scale}`` pairs; indices not listed are inactive.

        Later pairs override earlier ones, so ``[(all, 1.0), (root_position, 0.1)]`` reads naturally.

        Parameters
        ----------
        name : str
        d : int
            Number of parameters.
        scales : mapping or sequence of (indices, scale)
            ``indices``: anything that indexes a ``(D,)`` array; a scale of 0 makes them inactive.
        n_particles, n_iterations : int
        fitness_options : Mapping, optional
        """
        scale = np.zeros(d)
        items = scales.items() if isinstance(scales, Mapping) else scales
        for idx, s in items:
            scale[np.asarray(idx, dtype=np.int64)] = float(s)
        return cls(name, scale > 0, scale, n_particles, n_iterations, fitness_options or {})

    @property
    def dimension(self) -> int:
        """Number of parameters ``D``."""
        return int(self.active.shape[0])

    @property
    def effective_scale(self) -> np.ndarray:
        """``sigma_scale`` where active, 0 elsewhere, shape (D,)."""
        return np.where(self.active, self.sigma_scale, 0.0)

    @property
    def evaluations(self) -> int:
        """``n_particles * n_iterations``."""
        return self.n_particles * self.n_iterations


StageFactory = Callable[[Stage, np.ndarray], Optimizer]
"""``make_stage(stage, x_hat) -> Optimizer`` builds one stage's optimiser around ``x_hat``."""


class StagedSearch(Optimizer):
    """Run a sequence of stages, each initialised at the previous stage's estimate.

    Parameters
    ----------
    x0 : ndarray, shape (D,)
        Start estimate (previous frame's pose).
    stages : sequence of Stage
    make_stage : callable
        ``make_stage(stage, x_hat) -> Optimizer``.

    Notes
    -----
    ``best`` is the estimate of the current (after ``done``: the last) stage. Scores of different stages are
    not compared with each other because stages may use different fitness options (SPPSO stage 1 uses the
    torso edges only, [FL12] Table 6.1).
    """

    def __init__(self, x0: np.ndarray, stages: Sequence[Stage], make_stage: StageFactory) -> None:
        super().__init__()
        if len(stages) == 0:
            raise ConfigError("a staged search needs at least one stage")
        self._x0 = np.array(x0, dtype=np.float64)
        d = self._x0.shape[0]
        for st in stages:
            if st.dimension != d:
                raise ConfigError(f"stage {st.name!r} has {st.dimension} parameters, x0 has {d}")
        self._stages = tuple(stages)
        self._make_stage = make_stage
        self._index = -1
        self._current: Optimizer | None = None
        self._previous_best: Candidate | None = None

    @property
    def stages(self) -> tuple[Stage, ...]:
        """The stage schedule."""
        return self._stages

    @property
    def stage_index(self) -> int:
        """Index of the stage of the last ask (``-1`` before the first ask)."""
        return self._index

    @property
    def current(self) -> Optimizer | None:
        """The optimiser of the current stage (``None`` before the first ask)."""
        return self._current

    @property
    def budget(self) -> int:
        """Total evaluations of the schedule."""
        return sum(st.evaluations for st in self._stages)

    @property
    def done(self) -> bool:
        return self._index == len(self._stages) - 1 and self._current is not None and self._current.done

    @property
    def best(self) -> Candidate:
        if self._current is None or self._current.evaluations == 0:
            if self._previous_best is None:
                raise RuntimeError("no scores told yet; ask() and tell() first")
            b = self._previous_best  # a new stage was asked but not told yet
        else:
            b = self._current.best
        return Candidate(b.x, b.score, self.evaluations)

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._stages[max(self._index, 0)].fitness_options

    def _ask(self) -> np.ndarray:
        if self._current is None or self._current.done:
            if self._current is not None:
                self._previous_best = self._current.best
            x_hat = self._x0 if self._previous_best is None else self._previous_best.x
            self._index += 1
            self._current = self._make_stage(self._stages[self._index], x_hat)
        return self._current.ask()

    def _tell(self, scores: np.ndarray) -> None:
        if self._current is None:  # pragma: no cover - Optimizer.tell guards the protocol
            raise RuntimeError("tell() before the first ask()")
        self._current._tell_checked(scores)  # checked once, by this search's tell


class StagedSwarm(StagedSearch):
    """A staged search with one swarm optimiser (``stage_optimizer``) per :class:`Stage`.

    Stage ``j`` starts around stage ``j - 1``'s estimate with ``sigma * stage.effective_scale``, its swarm size,
    iterations and fitness options; ``lower``, ``upper`` and every other keyword (``constraint``,
    ``max_redraws``, the optimiser's own coefficients) go to each stage's optimiser unchanged.
    """

    stage_optimizer: Callable[..., Optimizer]

    def __init__(self, x0: Any, sigma: Any, stages: Sequence[Stage], rng: np.random.Generator, *,
                 lower: Any = None, upper: Any = None, **options: Any) -> None:
        x0 = np.array(x0, dtype=np.float64)
        d = x0.shape[0]
        sigma = as_vector(sigma, d, "sigma")
        lower, upper = check_bounds(lower, upper, d)
        check_rng(rng)
        make = type(self).stage_optimizer

        def make_stage(stage: Stage, x_hat: np.ndarray) -> Optimizer:
            return make(x_hat, sigma * stage.effective_scale, stage.n_particles, stage.n_iterations, rng,
                        lower=lower, upper=upper, fitness_options=stage.fitness_options, **options)

        super().__init__(x0, stages, make_stage)
