"""Annealed particle filter ([DR05] sec. 3, 3.1, 6.1, 6.2).

One frame = one annealing run over ``L`` layers of ``N`` particles (``L * N`` evaluations). Layer 1 is
DR05's broadest layer ``m = M``, layer ``L`` its final layer ``m = 0``.

For each layer:

1. evaluate the set; scores are read as log-weights, ``w = exp(score)``;
2. find ``beta_m`` by a 1-D search so that the survival rate ``D/N`` with ``D = 1 / sum(pi^2)``
   (eq. 11-12) equals the target ``alpha`` (sec. 3.1); ``pi ∝ w^beta_m`` (eq. 3, 6);
3. unless it is the last layer: draw ``N`` particles with replacement in proportion to ``pi`` (step 4),
   a fraction of them as two-point crossover children of two weighted draws (eq. 19), and add Gaussian
   diffusion: ``adaptive`` -- covariance ``c * Cov(set before noise)`` (eq. 18, sec. 6.1) after shrinking
   the set towards its mean by ``sqrt(1 - c)``, which keeps every parameter's variance (sec. 6.1), or
   ``fixed`` -- ``alpha^l * P_0`` after layer ``l`` (eq. 13 with ``alpha_M = ... = alpha_1 = alpha``);
4. after the last layer: estimate = weighted mean ``sum_i pi_i s_i`` (eq. 8).

The weighted final set is handed to the next frame by :meth:`AnnealedParticleFilter.carry`; the next run
resamples it by its weights and adds ``B_0 ~ N(0, P_0)`` (eq. 9; "the set S_{t+1,M} is produced from
S^pi_{t,0}"). Without a carried set, layer 1 is drawn from ``N(x0, P_0)``.

Constraints: a diffused particle that violates the bounds/constraint gets new noise (same parent) up to
``max_redraws`` times, like the PSO's move re-draw ([FL12] sec. 5.3.2); one still invalid after that is
clipped into the bounds and, if still invalid, evaluated but given weight 0 (HumanEva's "rejected"
particles, Sigal et al. 2010).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
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
    adaptive_diffusion,
    annealing_weights,
    crossover,
    find_beta,
    fixed_diffusion,
    kernel_bandwidth,
    redraw_invalid,
    resample_multinomial,
    resample_systematic,
    weighted_mean,
)

__all__ = ["AnnealedParticleFilter", "ParticleSet"]

_RESAMPLERS = {"multinomial": resample_multinomial, "systematic": resample_systematic}


@dataclass(frozen=True, eq=False)
class ParticleSet:
    """A weighted particle set ``S^pi_{t,0}`` carried to the next frame ([DR05] eq. 9).

    Attributes
    ----------
    particles : ndarray, shape (N, D)
    weights : ndarray, shape (N,)
        Normalised weights ``pi`` of the final layer.
    """

    particles: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        p = np.array(self.particles, dtype=np.float64)
        w = np.array(self.weights, dtype=np.float64)
        if p.ndim != 2 or w.shape != (p.shape[0],):
            raise ShapeError(f"particles (N, D) and weights (N,) expected, got {p.shape} and {w.shape}")
        if np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
            raise ValueError("weights must be finite, non-negative and not all zero")
        p.setflags(write=False)
        w = w / w.sum()
        w.setflags(write=False)
        object.__setattr__(self, "particles", p)
        object.__setattr__(self, "weights", w)

    def with_proposal(self, x: np.ndarray, share: float) -> ParticleSet:
        """The set with ``round(share * N)`` (at least one, at most ``N - 1``) of its lowest-weight particles
        replaced by ``x``, which together weigh ``share``; the others keep their proportions in the rest. A
        proposal from outside the filter (a detector's pose, say) that the next resampling draws in about
        ``share * N`` centres; ``share`` 0 returns the set as it is."""
        share = float(share)
        if not 0.0 <= share < 1.0:
            raise ConfigError(f"a proposal's share of the weight must lie in [0, 1), got {share}")
        if share == 0.0:
            return self
        x = np.asarray(x, dtype=np.float64)
        n = len(self.weights)
        if x.shape != (self.particles.shape[1],):
            raise ShapeError(f"a proposal of shape ({self.particles.shape[1]},) expected, got {x.shape}")
        if n < 2:
            raise ShapeError("a set of one particle has no room for a proposal beside it")
        k = min(n - 1, max(1, int(round(share * n))))
        low = np.argsort(self.weights, kind="stable")[:k]
        particles = np.array(self.particles)
        particles[low] = x
        weights = np.array(self.weights)
        weights[low] = 0.0  # the highest weight (> 0) is never among the k <= N - 1 lowest: the rest is > 0
        weights *= (1.0 - share) / weights.sum()
        weights[low] = share / k
        return ParticleSet(particles, weights)


class AnnealedParticleFilter(Optimizer):
    """Annealed particle filter over ``n_layers`` layers ([DR05] sec. 3 and 6).

    Parameters
    ----------
    particles : ndarray, shape (N, D)
        Centres of layer 1's particles (previous estimate repeated, or a resampled carried set).
    sigma0 : ndarray, shape (D,)
        ``sqrt(diag(P_0))`` (frame-rate scaled); the fixed schedule and the between-frame noise use it.
    n_layers : int
        Annealing layers ``L`` (``L * N`` evaluations).
    rng : numpy.random.Generator
    alpha : float
        Target survival rate ``D/N`` per layer (sec. 3.1; 0.5).
    diffusion : {"adaptive", "fixed"}
        eq. 18 or eq. 13.
    diffusion_scale : float or None
        Proportionality constant ``c`` of eq. 18 (adaptive only), in ``(0, 1)``. DR05 leaves it open.
        ``None`` (default) uses the optimal kernel bandwidth ``h^2`` of the regularised particle filter
        (:func:`~swarmpose.optim.operators.kernel_bandwidth`) for ``alpha * N`` effective particles in the
        number of parameters that still vary: noise that fills the gaps between repeatedly selected particles
        and shrinks automatically with the set (e.g. 0.29 for 4 parameters and 200 particles, 0.68 for 30).
        The resampled set is first shrunk towards its mean by ``sqrt(1 - c)``, so that the noise does not
        increase any parameter's variance (sec. 6.1; Liu & West 2001).
    crossover : float
        Fraction of the new particles made by the crossover operator (eq. 19), in ``[0, 1]``.
    diffuse_first : bool
        Add ``B_0 ~ N(0, P_0)`` to ``particles`` for layer 1 (eq. 9). ``False`` uses ``particles`` as given
        (e.g. a uniform initial set as in sec. 6.1).
    lower, upper, constraint, max_redraws
        Bounds and hard priors (see module notes).
    estimate : {"mean", "max"}
        ``best.x``: weighted mean (eq. 8) or the highest-scoring particle of the last layer.
    resampling : {"multinomial", "systematic"}
        Multinomial is DR05's step 4.
    fitness_options : Mapping, optional

    Notes
    -----
    ``best.score`` of the weighted-mean estimate is the ``pi``-weighted mean score of the last layer: the
    mean itself is never evaluated (that would cost an extra evaluation per frame). The mean of valid
    particles is not guaranteed to satisfy a non-convex constraint; use ``estimate="max"`` (the best
    particle, HumanEva's MAP estimate) where that matters.

    Examples
    --------
    >>> import numpy as np
    >>> from swarmpose.optim import optimize
    >>> from swarmpose.optim.testfunctions import sphere
    >>> rng = np.random.default_rng(0)
    >>> apf = AnnealedParticleFilter(np.zeros((100, 3)) + 1.0, np.ones(3), 5, rng)
    >>> optimize(apf, sphere).evaluations
    500
    """

    def __init__(
        self,
        particles: Any,
        sigma0: Any,
        n_layers: int,
        rng: np.random.Generator,
        *,
        alpha: float = 0.5,
        diffusion: str = "adaptive",
        diffusion_scale: float | None = None,
        crossover: float = 0.0,
        diffuse_first: bool = True,
        lower: Any = None,
        upper: Any = None,
        constraint: Constraint | None = None,
        max_redraws: int = 10,
        estimate: str = "mean",
        resampling: str = "multinomial",
        fitness_options: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__()
        centres = np.array(particles, dtype=np.float64)
        if centres.ndim != 2:
            raise ShapeError(f"particles must have shape (N, D), got {centres.shape}")
        n, d = centres.shape
        self._sigma0 = as_vector(sigma0, d, "sigma0")
        if not np.all(np.isfinite(self._sigma0)) or np.any(self._sigma0 < 0):
            raise ConfigError("sigma0 must be finite and >= 0")
        if n < 2 or n_layers < 1:
            raise ConfigError(f"need >= 2 particles and >= 1 layer, got {n} and {n_layers}")
        if not 0.0 < alpha < 1.0:
            raise ConfigError(f"alpha (target survival rate) must be in (0, 1), got {alpha}")
        if diffusion not in ("adaptive", "fixed"):
            raise ConfigError(f"diffusion must be 'adaptive' or 'fixed', got {diffusion!r}")
        if diffusion_scale is not None and not 0.0 < diffusion_scale < 1.0:
            raise ConfigError(f"diffusion_scale must be in (0, 1) or None, got {diffusion_scale}")
        if not 0.0 <= crossover <= 1.0:
            raise ConfigError(f"crossover fraction must be in [0, 1], got {crossover}")
        if estimate not in ("mean", "max"):
            raise ConfigError(f"estimate must be 'mean' or 'max', got {estimate!r}")
        if resampling not in _RESAMPLERS:
            raise ConfigError(f"resampling must be one of {sorted(_RESAMPLERS)}, got {resampling!r}")
        if max_redraws < 0:
            raise ConfigError("max_redraws must be >= 0")
        self._n, self._d = n, d
        self._layers = int(n_layers)
        self._rng = check_rng(rng)
        self._alpha = float(alpha)
        self._diffusion = diffusion
        self._scale = None if diffusion_scale is None else float(diffusion_scale)
        self._crossover = float(crossover)
        self._lower, self._upper = check_bounds(lower, upper, d)
        self._constraint = constraint
        self._max_redraws = int(max_redraws)
        self._estimate = estimate
        self._resample = _RESAMPLERS[resampling]
        self._options = frozen_options(fitness_options) if fitness_options else EMPTY_OPTIONS
        self._centres = centres
        self._diffuse_first = bool(diffuse_first)
        self._layer = 0  # layers evaluated so far
        self._x = np.empty((0, d))
        self._parents = np.empty((0, d))
        self._valid = np.empty(0, dtype=bool)
        self._scores = np.empty(0)
        self._weights = np.empty(0)
        self._betas: list[float] = []

    # -- construction helper -----------------------------------------------------------------------
    @classmethod
    def start(
        cls,
        x0: Any,
        sigma0: Any,
        n_particles: int,
        n_layers: int,
        rng: np.random.Generator,
        *,
        carry: ParticleSet | None = None,
        **kwargs: Any,
    ) -> AnnealedParticleFilter:
        """Start one frame's run: from a carried set (eq. 9) or around ``x0``.

        Parameters
        ----------
        x0 : ndarray, shape (D,)
            Previous estimate; used only when ``carry`` is None (all layer-1 particles ~ ``N(x0, P_0)``).
        sigma0 : ndarray, shape (D,)
        n_particles, n_layers : int
        rng : numpy.random.Generator
        carry : ParticleSet, optional
            The previous frame's final weighted set; it is resampled by its weights, then diffused by
            ``B_0`` in the first ask.
        **kwargs
            Passed to the constructor.
        """
        x0 = np.array(x0, dtype=np.float64)
        if carry is None:
            centres = np.tile(x0, (n_particles, 1))
        else:
            if not isinstance(carry, ParticleSet):
                raise TypeError(
                    f"carry must be a ParticleSet (from AnnealedParticleFilter.carry()), got {carry!r}"
                )
            if carry.particles.shape != (n_particles, x0.shape[0]):
                raise ShapeError(
                    f"carried set has shape {carry.particles.shape}, this run needs ({n_particles}, {x0.shape[0]})"
                )
            resample = _RESAMPLERS[kwargs.get("resampling", "multinomial")]
            centres = carry.particles[resample(carry.weights, n_particles, check_rng(rng))]
        return cls(centres, sigma0, n_layers, rng, diffuse_first=True, **kwargs)

    # -- read-only state ---------------------------------------------------------------------------
    @property
    def particles(self) -> np.ndarray:
        """Particles of the last ask, shape (N, D)."""
        return self._x.copy()

    @property
    def parents(self) -> np.ndarray:
        """The last ask's resampled/crossed set before shrinkage and diffusion noise, shape (N, D)."""
        return self._parents.copy()

    @property
    def weights(self) -> np.ndarray:
        """Normalised weights ``pi`` of the last told layer, shape (N,)."""
        return self._weights.copy()

    @property
    def betas(self) -> tuple[float, ...]:
        """``beta`` of each told layer."""
        return tuple(self._betas)

    @property
    def layer(self) -> int:
        """Layers evaluated so far."""
        return self._layer

    @property
    def n_layers(self) -> int:
        """Number of layers ``L``."""
        return self._layers

    # -- protocol ----------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self._layer >= self._layers

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._options

    @property
    def best(self) -> Candidate:
        if self._layer == 0:
            raise RuntimeError("no scores told yet; ask() and tell() first")
        finite = np.isfinite(self._scores)
        if self._estimate == "max" or not finite.any():
            i = int(np.argmax(self._scores))
            return Candidate(self._x[i].copy(), float(self._scores[i]), self.evaluations)
        x = weighted_mean(self._x, self._weights)  # eq. 8
        score = float(self._weights[finite] @ self._scores[finite])
        return Candidate(x, score, self.evaluations)

    @property
    def best_particle(self) -> Candidate:
        """Highest-scoring particle of the last told layer."""
        if self._layer == 0:
            raise RuntimeError("no scores told yet; ask() and tell() first")
        i = int(np.argmax(self._scores))
        return Candidate(self._x[i].copy(), float(self._scores[i]), self.evaluations)

    def carry(self) -> ParticleSet:
        """The final weighted set ``S^pi_{t,0}`` for the next frame (eq. 9); only when done."""
        if not self.done:
            raise RuntimeError("carry() is available after the last layer (done)")
        return ParticleSet(self._x, self._weights)

    # -- internals ---------------------------------------------------------------------------------
    def _is_valid(self, x: np.ndarray) -> np.ndarray:
        return feasibility(x, self._lower, self._upper, self._constraint)

    def _diffuse(self, parents: np.ndarray, noise: Any) -> tuple[np.ndarray, np.ndarray]:
        """``parents + noise(rows)`` with violating rows re-drawn, then clipped."""

        def propose(rows: np.ndarray) -> tuple[np.ndarray]:
            return (parents[rows] + noise(rows),)

        (x,), valid = redraw_invalid(propose, self._is_valid, self._n, self._max_redraws)
        return clip_invalid(x, valid, self._lower, self._upper, self._is_valid)

    def _ask(self) -> np.ndarray:
        rng = self._rng
        if self._layer == 0:
            parents = self._centres
            if self._diffuse_first:  # S_{t,M} = S_{t-1,0} + B_0  (eq. 9)
                x, valid = self._diffuse(parents, lambda rows: fixed_diffusion(self._sigma0, rows.size, rng))
            else:
                x = np.clip(parents, self._lower, self._upper)
                valid = self._is_valid(x)
        else:
            # step 4: draw N particles in proportion to pi; a fraction by crossover (eq. 19)
            n_cross = int(round(self._crossover * self._n))
            idx = self._resample(self._weights, self._n, rng)
            if n_cross > 0 and self._resample is resample_systematic:
                idx = rng.permutation(idx)  # its pointers come out sorted; the crossed rows must be any rows
            parents = self._x[idx]
            if n_cross > 0:
                mates = self._x[self._resample(self._weights, n_cross, rng)]
                parents[:n_cross] = crossover(parents[:n_cross], mates, rng)
            if self._diffusion == "adaptive":
                # B ~ N(0, c * Cov(S before noise))  (eq. 18); re-draws use the same covariance
                scale = self._scale
                if scale is None:
                    d_free = int(np.count_nonzero(np.ptp(parents, axis=0) > 0))
                    scale = kernel_bandwidth(d_free, self._alpha * self._n)
                # sec. 6.1 wants noise "enough to allow the thorough diffusion of the particles into the
                # spaces between repeatedly selected particles, but not enough to increase the variance of
                # any given parameter". N(0, c Cov) alone multiplies the variance of every parameter the
                # weights have not localised by (1 + c) per layer -- with c = 0.68 in 31-D, x 180 over 10
                # layers, and the set explodes from frame to frame. Shrinking the parents towards their mean
                # by sqrt(1 - c) first keeps the set's mean and covariance (Liu & West 2001's kernel shrinkage).
                mean = parents.mean(axis=0)
                base = mean + np.sqrt(1.0 - scale) * (parents - mean)

                def noise(rows: np.ndarray) -> np.ndarray:
                    return adaptive_diffusion(parents, scale, rng, rows.size)
            else:
                # P = alpha^l P_0 after layer l  (eq. 13)
                sigma = self._sigma0 * np.sqrt(self._alpha**self._layer)
                base = parents

                def noise(rows: np.ndarray) -> np.ndarray:
                    return fixed_diffusion(sigma, rows.size, rng)

            x, valid = self._diffuse(base, noise)
        self._parents = np.array(parents, copy=True)
        self._x, self._valid = x, valid
        return x

    def _tell(self, scores: np.ndarray) -> None:
        s = np.where(self._valid, scores, -np.inf)  # invalid particles get weight 0
        beta = find_beta(s, self._alpha)  # D(beta)/N = alpha  (eq. 11-12, sec. 3.1)
        self._scores = s
        self._weights = annealing_weights(s, beta)  # pi ∝ w^beta  (eq. 3, 6)
        self._betas.append(beta)
        self._layer += 1
