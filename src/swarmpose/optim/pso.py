"""Constricted particle swarm optimisation with enforced constraints ([FL12] sec. 5.3.1-5.3.2, Algorithm 2).

:class:`ConstrictedPSO` is one stage of SPPSO; :class:`StagedPSO` chains stages (soft/hard partitions,
:mod:`~swarmpose.optim.staged`).

Algorithm 2, as implemented (one stage, ``N`` iterations):

1. start positions ``x_i ~ N(x_hat, diag(sigma^2))`` (eq. 5.10), start velocities ``v_i ~ U(-sigma, sigma)``;
2. evaluate; personal bests ``p_i`` and global best ``p_g`` (gbest topology);
3. for ``k = 2 .. N``: ``c1 = c2 = c(k)`` rising linearly ``2.05 -> 2.15``, ``chi(k)`` from eq. 5.9;
   ``v_i = chi (v_i + c1 e1 (p_i - x_i) + c2 e2 (p_g - x_i))`` (eq. 5.8); ``|v_id| <= 2 sigma_d``;
   ``x_i = x_i + v_i``; a move that violates the constraints is re-drawn (new ``e1, e2``) up to 10 times;
   evaluate; update ``p_i`` and ``p_g``.

Deviations, stated plainly:

* **Synchronous bests.** Algorithm 2 updates ``p_g`` after each particle, so particle ``i + 1`` already
  sees particle ``i``'s improvement within one iteration. A batched fitness evaluates the whole swarm at
  once, so ``p_g`` is updated once per iteration (the usual synchronous PSO).
* **After the last re-draw.** The thesis does not say what happens when all 10 re-draws violate the
  constraints. We keep the last move (Algorithm 2 read literally) and, when it left the joint-limit box,
  clip it into the box and test it again (``clip_invalid``): a clipped pose that passes every constraint
  is valid and may become a best, so estimates sit exactly on a joint limit on some frames (8 % of the
  frames of 100 walk runs at 20 fps; scoring the clipped poses as invalid instead changed D by 1.9 mm on
  36 searches, within their spread). A particle still invalid is scored and counted but not allowed to
  become a personal or global best, so the estimate always satisfies the constraints whenever any
  evaluated particle did. When none did, the stage reports its start centre ``x_hat`` (score ``-inf``)
  rather than an invalid particle.
* **Start positions** that violate the constraints are re-drawn from eq. 5.10 in the same way (Algorithm 2
  does not mention it; it keeps the initial swarm inside the hard priors).
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
    best_or_start,
    constricted_move,
    constriction,
    global_best,
    linear_coefficients,
    redraw_invalid,
    sample_normal,
    sample_uniform,
    tell_personal_best,
)
from .staged import StagedSwarm

__all__ = ["ConstrictedPSO", "StagedPSO"]


class ConstrictedPSO(Optimizer):
    """One stage of SPPSO: constricted gbest PSO with constraint re-draws ([FL12] Algorithm 2).

    Parameters
    ----------
    x0 : ndarray, shape (D,)
        Centre of the start distribution (the previous estimate ``x_hat``).
    sigma : ndarray, shape (D,)
        Per-parameter standard deviation of this stage (already frame-rate- and stage-scaled);
        0 holds a parameter fixed.
    n_particles, n_iterations : int
        The stage costs ``n_particles * n_iterations`` evaluations (iteration 1 = the start swarm).
    rng : numpy.random.Generator
    lower, upper : ndarray, shape (D,), optional
        Bounds (``±inf`` allowed); a move outside counts as a constraint violation.
    constraint : callable, optional
        ``constraint(poses (N, D)) -> (N,) bool``, True = valid.
    c_start, c_end : float
        c1 = c2 rise linearly from ``c_start`` to ``c_end`` over the velocity updates (default 2.05 -> 2.15).
    vmax_factor : float
        ``|v_d| <= vmax_factor * sigma_d`` (default 2).
    max_redraws : int
        Re-draws of a violating move (default 10).
    fitness_options : Mapping, optional
        Reported by :attr:`fitness_options`.
    init_positions : ndarray, shape (N, D), optional
        Explicit start positions instead of eq. 5.10 (used to give two optimisers the same start swarm in
        benchmarks); rows outside the bounds are clipped.

    Examples
    --------
    >>> import numpy as np
    >>> from swarmpose.optim import optimize
    >>> from swarmpose.optim.testfunctions import sphere
    >>> opt = ConstrictedPSO(np.ones(3), np.ones(3), 10, 20, np.random.default_rng(0))
    >>> optimize(opt, sphere).evaluations
    200
    """

    def __init__(
        self,
        x0: Any,
        sigma: Any,
        n_particles: int,
        n_iterations: int,
        rng: np.random.Generator,
        *,
        lower: Any = None,
        upper: Any = None,
        constraint: Constraint | None = None,
        c_start: float = 2.05,
        c_end: float = 2.15,
        vmax_factor: float = 2.0,
        max_redraws: int = 10,
        fitness_options: Mapping[str, Any] | None = None,
        init_positions: Any = None,
    ) -> None:
        super().__init__()
        self._x0 = np.array(x0, dtype=np.float64)
        if self._x0.ndim != 1:
            raise ShapeError(f"x0 must have shape (D,), got {self._x0.shape}")
        d = self._x0.shape[0]
        self._sigma = as_vector(sigma, d, "sigma")
        if not np.all(np.isfinite(self._sigma)) or np.any(self._sigma < 0):
            raise ConfigError("sigma must be finite and >= 0")
        if n_particles < 1 or n_iterations < 1:
            raise ConfigError(f"n_particles and n_iterations must be >= 1, got {n_particles}, {n_iterations}")
        if c_start + c_start <= 4.0 or c_end + c_end <= 4.0:
            raise ConfigError(f"c1 + c2 must exceed 4 (thesis eq. 5.9), got c = {c_start} .. {c_end}")
        if vmax_factor <= 0 or max_redraws < 0:
            raise ConfigError("vmax_factor must be > 0 and max_redraws >= 0")
        self._n = int(n_particles)
        self._iterations = int(n_iterations)
        self._rng = check_rng(rng)
        self._lower, self._upper = check_bounds(lower, upper, d)
        self._constraint = constraint
        self._coeffs = linear_coefficients(c_start, c_end, self._iterations - 1)
        self._vmax = vmax_factor * self._sigma
        self._max_redraws = int(max_redraws)
        self._options = frozen_options(fitness_options) if fitness_options else EMPTY_OPTIONS
        self._init = None
        if init_positions is not None:
            init = np.array(init_positions, dtype=np.float64)
            if init.shape != (self._n, d):
                raise ShapeError(f"init_positions must have shape ({self._n}, {d}), got {init.shape}")
            self._init = init
        self._k = 0  # iterations evaluated so far
        self._x = np.empty((0, d))
        self._v = np.empty((0, d))
        self._valid = np.empty(0, dtype=bool)
        self._pbest_x = np.empty((0, d))
        self._pbest_s = np.empty(0)
        self._g = 0

    # -- read-only state (for recorders and tests) ------------------------------------------------
    @property
    def positions(self) -> np.ndarray:
        """Positions of the last ask, shape (N, D)."""
        return self._x.copy()

    @property
    def velocities(self) -> np.ndarray:
        """Velocities that produced the last ask, shape (N, D)."""
        return self._v.copy()

    @property
    def valid(self) -> np.ndarray:
        """Constraint validity of the last ask, shape (N,)."""
        return self._valid.copy()

    @property
    def personal_best(self) -> tuple[np.ndarray, np.ndarray]:
        """``(p_i (N, D), scores (N,))``."""
        return self._pbest_x.copy(), self._pbest_s.copy()

    @property
    def iteration(self) -> int:
        """Iterations evaluated so far."""
        return self._k

    # -- protocol ----------------------------------------------------------------------------------
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

    def _finish_moves(self, x: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clip rows that are still outside the bounds after the re-draws; re-test them."""
        return clip_invalid(x, valid, self._lower, self._upper, self._is_valid)

    def _ask(self) -> np.ndarray:
        rng = self._rng
        if self._k == 0:
            if self._init is not None:
                x = np.clip(self._init, self._lower, self._upper)
                valid = self._is_valid(x)
            else:
                # x_i ~ N(x_hat, Sigma)  (eq. 5.10), violating rows re-drawn
                (x,), valid = redraw_invalid(
                    lambda rows: (sample_normal(self._x0, self._sigma, rows.size, rng),),
                    self._is_valid,
                    self._n,
                    self._max_redraws,
                )
            x, valid = self._finish_moves(x, valid)
            v = sample_uniform(self._sigma, self._n, rng)  # v_i ~ U(-sigma, sigma)
        else:
            c = float(self._coeffs[self._k - 1])
            chi = constriction(c, c)  # eq. 5.9, recomputed every iteration
            gbest = self._pbest_x[self._g]
            x_old, v_old, pbest = self._x, self._v, self._pbest_x

            fused = getattr(self._constraint, "constricted_moves", None)
            if fused is not None:  # the same moves, re-draws and clipping in one compiled call (optim.base)
                x, v, valid = fused(v_old, x_old, pbest, gbest, c, chi, self._vmax, self._lower, self._upper,
                                    self._max_redraws, rng)
            else:
                def propose(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
                    # v = chi (v + c1 e1 (p_i - x_i) + c2 e2 (p_g - x_i))  (eq. 5.8); |v| <= 2 sigma; x = x + v (eq. 5.7)
                    return constricted_move(v_old, x_old, pbest, gbest, rows, c, c, chi, self._vmax, rng)

                (x, v), valid = redraw_invalid(propose, self._is_valid, self._n, self._max_redraws)
                x, valid = self._finish_moves(x, valid)
        self._x, self._v, self._valid = x, v, valid
        return x

    def _tell(self, scores: np.ndarray) -> None:
        if self._k == 0:
            s = np.where(self._valid, scores, -np.inf)  # an invalid pose never becomes a best
            self._pbest_x, self._pbest_s = self._x.copy(), s
            self._g = global_best(self._pbest_s)
        else:  # update_personal_best and global_best in one compiled pass, in place
            self._g = tell_personal_best(self._valid, scores, self._x, self._pbest_x, self._pbest_s)
        self._k += 1


class StagedPSO(StagedSwarm):
    """Soft/hard-partitioned constricted PSO: one :class:`ConstrictedPSO` per :class:`Stage` ([FL12] 5.3.3).

    Stage ``j`` starts around stage ``j - 1``'s global best with ``sigma * stage.effective_scale``.

    Parameters
    ----------
    x0 : ndarray, shape (D,)
        Previous frame's estimate.
    sigma : ndarray, shape (D,)
        Frame-rate-scaled per-parameter sigma (``model.sigma * 60 / fps``).
    stages : sequence of Stage
    rng : numpy.random.Generator
    lower, upper, constraint, c_start, c_end, vmax_factor, max_redraws
        As in :class:`ConstrictedPSO`.
    """

    stage_optimizer = ConstrictedPSO
