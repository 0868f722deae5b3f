"""Adaptive annealed PSO with soft search-space partitioning ([SH17] sec. 3.4, eq. 15-18).

One stage (``M`` iterations, the start swarm counting as iteration 1):

1. start positions ``x_i ~ N(x_hat, P_0)`` (eq. 6) with ``P_0 = diag(sigma^2)`` of this stage;
2. evaluate; personal bests ``p_i``, global best ``g``;
3. for ``n = 1 .. M - 1``: ``alpha_n = 1 - 0.8 n / M`` (eq. 17);
   ``P_n = alpha_n * Var(X)`` (eq. 18, ``adaptive=True``, :data:`aapso`) or ``alpha_n * P_0``
   (eq. 16, ``adaptive=False``, ``aapso-fixed``, the authors' earlier version);
   ``v_i = b_i + phi1 (p_i - x_i) + phi2 (g - x_i)`` with ``b_i ~ N(0, P_n)`` (eq. 15);
   ``x_i = x_i + v_i`` (eq. 14); evaluate; update bests.

Reading of the paper, stated plainly:

* ``P_n`` in eq. 15 is a covariance, so the history term is Gaussian noise with that covariance (the
  paper's "sampling covariance matrix is used to initialise the first part of the equation").
  ``Var`` is the per-parameter variance over the swarm (diagonal).
* Eq. 18 writes ``Var(X_{n-1})``, "the set of particles in iteration n-1", while eq. 15 indexes the
  positions being moved as ``x^{i,n}``; we use the variance of the swarm being moved (the most recent,
  evaluated set), which is what both readings share for the first update.
* The paper has no velocity limit and no constraint handling; constraints and bounds are enforced as in
  the thesis (re-draw the move up to 10 times, [FL12] sec. 5.3.2), so all optimisers honour the same
  hard priors. With no constraint and infinite bounds nothing changes.
* Bests are updated synchronously (the whole swarm is one fitness batch).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .base import (
    EMPTY_OPTIONS,
    Candidate,
    ConfigError,
    Constraint,
    Optimizer,
    ShapeError,
    as_vector,
    check_bounds,
    check_rng,
    clip_invalid,
    feasibility,
    frozen_options,
)
from .operators import (
    aapso_alpha,
    aapso_velocity,
    best_or_start,
    global_best,
    redraw_invalid,
    sample_normal,
    update_personal_best,
)
from .staged import StagedSwarm

__all__ = ["AdaptiveAnnealedPSO", "StagedAAPSO"]


class AdaptiveAnnealedPSO(Optimizer):
    """One stage of the adaptive annealed PSO ([SH17] eq. 15-18).

    Parameters
    ----------
    x0 : ndarray, shape (D,)
        Centre of the start distribution.
    sigma : ndarray, shape (D,)
        Square root of the diagonal of ``P_0`` for this stage; 0 holds a parameter fixed.
    n_particles, n_iterations : int
        The stage costs ``n_particles * n_iterations`` evaluations.
    rng : numpy.random.Generator
    adaptive : bool
        ``True``: ``P_n = alpha_n Var(X)`` (eq. 18); ``False``: ``P_n = alpha_n P_0`` (eq. 16).
    lower, upper, constraint, max_redraws
        As in :class:`~swarmpose.optim.pso.ConstrictedPSO`.
    fitness_options : Mapping, optional
    """

    def __init__(
        self,
        x0: Any,
        sigma: Any,
        n_particles: int,
        n_iterations: int,
        rng: np.random.Generator,
        *,
        adaptive: bool = True,
        lower: Any = None,
        upper: Any = None,
        constraint: Constraint | None = None,
        max_redraws: int = 10,
        fitness_options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__()
        self._x0 = np.array(x0, dtype=np.float64)
        if self._x0.ndim != 1:
            raise ShapeError(f"x0 must have shape (D,), got {self._x0.shape}")
        d = self._x0.shape[0]
        self._sigma = as_vector(sigma, d, "sigma")
        if not np.all(np.isfinite(self._sigma)) or np.any(self._sigma < 0):
            raise ConfigError("sigma must be finite and >= 0")
        if n_particles < 1 or n_iterations < 1 or max_redraws < 0:
            raise ConfigError("n_particles, n_iterations must be >= 1 and max_redraws >= 0")
        self._n = int(n_particles)
        self._iterations = int(n_iterations)
        self._rng = check_rng(rng)
        self._adaptive = bool(adaptive)
        self._lower, self._upper = check_bounds(lower, upper, d)
        self._constraint = constraint
        self._max_redraws = int(max_redraws)
        self._options = frozen_options(fitness_options) if fitness_options else EMPTY_OPTIONS
        self._k = 0
        self._x = np.empty((0, d))
        self._valid = np.empty(0, dtype=bool)
        self._pbest_x = np.empty((0, d))
        self._pbest_s = np.empty(0)
        self._g = 0
        self._noise_var = np.zeros(d)

    @property
    def positions(self) -> np.ndarray:
        """Positions of the last ask, shape (N, D)."""
        return self._x.copy()

    @property
    def noise_variance(self) -> np.ndarray:
        """Diagonal of ``P_n`` used for the last ask, shape (D,) (zeros for the start swarm)."""
        return self._noise_var.copy()

    @property
    def done(self) -> bool:
        return self._k >= self._iterations

    @property
    def best(self) -> Candidate:
        if self._k == 0:
            raise RuntimeError("no scores told yet; ask() and tell() first")
        x, score = best_or_start(self._pbest_x, self._pbest_s, self._g, self._x0)
        return Candidate(x, score, self.evaluations)

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._options

    def _is_valid(self, x: np.ndarray) -> np.ndarray:
        return feasibility(x, self._lower, self._upper, self._constraint)

    def _ask(self) -> np.ndarray:
        rng = self._rng
        if self._k == 0:
            # x_i ~ N(x_hat, P_0)  (eq. 6)
            (x,), valid = redraw_invalid(
                lambda rows: (sample_normal(self._x0, self._sigma, rows.size, rng),),
                self._is_valid,
                self._n,
                self._max_redraws,
            )
        else:
            n = self._k  # iterations done so far = index of the current swarm (1-based)
            alpha_n = aapso_alpha(n, self._iterations)  # eq. 17
            if self._adaptive:
                self._noise_var = alpha_n * self._x.var(axis=0)  # eq. 18
            else:
                self._noise_var = alpha_n * self._sigma**2  # eq. 16
            gbest = self._pbest_x[self._g]
            x_old, pbest, var = self._x, self._pbest_x, self._noise_var

            def propose(rows: np.ndarray) -> tuple[np.ndarray]:
                v = aapso_velocity(x_old[rows], pbest[rows], gbest, var, rng)  # eq. 15
                return (x_old[rows] + v,)  # eq. 14

            (x,), valid = redraw_invalid(propose, self._is_valid, self._n, self._max_redraws)
        x, valid = clip_invalid(x, valid, self._lower, self._upper, self._is_valid)
        self._x, self._valid = x, valid
        return x

    def _tell(self, scores: np.ndarray) -> None:
        s = np.where(self._valid, scores, -np.inf)
        if self._k == 0:
            self._pbest_x, self._pbest_s = self._x.copy(), s
        else:
            self._pbest_x, self._pbest_s = update_personal_best(self._pbest_x, self._pbest_s, self._x, s)
        self._g = global_best(self._pbest_s)
        self._k += 1


class StagedAAPSO(StagedSwarm):
    """Six soft stages of AAPSO ([SH17] sec. 3.4 and 4.2); one :class:`AdaptiveAnnealedPSO` per stage.

    Parameters
    ----------
    x0 : ndarray, shape (D,)
    sigma : ndarray, shape (D,)
        ``sqrt(diag(P_0))`` at the tracked frame rate.
    stages : sequence of Stage
    rng : numpy.random.Generator
    adaptive : bool
        eq. 18 (True) or eq. 16 (False).
    lower, upper, constraint, max_redraws
        As in :class:`AdaptiveAnnealedPSO`.
    """

    stage_optimizer = AdaptiveAnnealedPSO
