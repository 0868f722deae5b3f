"""Pure array operators of the optimisers (PSO, annealed particle filter, adaptive annealed PSO).

Every function takes arrays (and an explicit ``numpy.random.Generator`` where it draws) and returns new
arrays; the stateful classes in :mod:`~swarmpose.optim.pso`, :mod:`~swarmpose.optim.apf` and
:mod:`~swarmpose.optim.aapso` only sequence them. Shapes use ``N`` candidates and ``D`` parameters.

References
----------
.. [FL12] P. Fleischmann, "Particle Swarm Optimization with Soft Search Space Partitioning for Video-Based
   Markerless 3D Human Pose Tracking", MSc thesis, Univ. of Stavanger, 2012 (sec. 5.3, Algorithm 2).
.. [DR05] J. Deutscher, I. Reid, "Articulated Body Motion Capture by Stochastic Search", IJCV 61(2), 2005
   (sec. 3, 3.1, 6.1, 6.2).
.. [SH17] A. Sharifi, A. Harati, A. Vahedian, "Marker-based human pose tracking using adaptive annealed
   particle swarm optimization with search space partitioning", Image and Vision Computing, 2017 (sec. 3.4).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numba as nb
import numpy as np
from scipy.optimize import brentq

__all__ = [
    "aapso_alpha",
    "aapso_velocity",
    "adaptive_diffusion",
    "annealing_weights",
    "best_or_start",
    "clamp_velocity",
    "constricted_move",
    "constricted_velocity",
    "constriction",
    "crossover",
    "find_beta",
    "fixed_diffusion",
    "global_best",
    "kernel_bandwidth",
    "linear_coefficients",
    "move_rows_kernel",
    "redraw_invalid",
    "resample_multinomial",
    "resample_systematic",
    "sample_normal",
    "sample_uniform",
    "survival_rate",
    "tell_personal_best",
    "update_personal_best",
    "weighted_mean",
]


# --------------------------------------------------------------------------------------------------
# Constricted PSO ([FL12] sec. 5.3.1-5.3.2, Algorithm 2)
# --------------------------------------------------------------------------------------------------
def constriction(c1: float, c2: float) -> float:
    """Clerc-Kennedy constriction factor ([FL12] eq. 5.9).

    ``chi = 2 / |2 - phi - sqrt(phi^2 - 4 phi)|`` with ``phi = c1 + c2``.

    Parameters
    ----------
    c1, c2 : float
        Cognitive and social coefficients; ``c1 + c2 > 4`` is required.

    Returns
    -------
    float

    Examples
    --------
    >>> round(constriction(2.05, 2.05), 5)
    0.72984
    """
    phi = float(c1) + float(c2)
    if not phi > 4.0:
        raise ValueError(f"constriction needs c1 + c2 > 4 (thesis eq. 5.9), got {phi}")
    return float(2.0 / abs(2.0 - phi - np.sqrt(phi * phi - 4.0 * phi)))


def linear_coefficients(start: float, end: float, n_updates: int) -> np.ndarray:
    """c1 = c2 for each velocity update, rising linearly from ``start`` to ``end`` ([FL12] sec. 5.3.2).

    Algorithm 2 evaluates the initial swarm at iteration 1 and updates velocities at iterations
    ``k = 2 .. N``; update ``j`` (0-based) uses ``start + (end - start) * j / (n_updates - 1)``,
    so the first update uses exactly ``start`` and the last exactly ``end``.

    Parameters
    ----------
    start, end : float
    n_updates : int
        Number of velocity updates (iterations - 1), ``>= 0``.

    Returns
    -------
    ndarray, shape (n_updates,)
    """
    if n_updates <= 0:
        return np.empty(0)
    if n_updates == 1:
        return np.array([float(start)])
    return np.linspace(float(start), float(end), n_updates)


def constricted_velocity(
    v: np.ndarray,
    x: np.ndarray,
    pbest: np.ndarray,
    gbest: np.ndarray,
    c1: float,
    c2: float,
    chi: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Constricted velocity update ([FL12] eq. 5.8, Algorithm 2).

    ``v <- chi * (v + c1 * e1 * (p_i - x_i) + c2 * e2 * (p_g - x_i))`` with ``e1, e2 ~ U[0, 1)`` drawn
    independently per particle and dimension.

    Parameters
    ----------
    v, x, pbest : ndarray, shape (N, D)
        Velocities, positions, personal bests.
    gbest : ndarray, shape (D,)
        Global best (gbest topology).
    c1, c2, chi : float
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (N, D)
    """
    e1 = rng.random(x.shape)
    e2 = rng.random(x.shape)
    return chi * (v + c1 * e1 * (pbest - x) + c2 * e2 * (gbest - x))


def constricted_move(
    v: np.ndarray,
    x: np.ndarray,
    pbest: np.ndarray,
    gbest: np.ndarray,
    rows: np.ndarray,
    c1: float,
    c2: float,
    chi: float,
    vmax: np.ndarray,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """One PSO move of the particles ``rows`` ([FL12] eq. 5.7-5.8, Algorithm 2), in one compiled pass.

    The same numbers as ``v' = clamp_velocity(constricted_velocity(v[rows], x[rows], pbest[rows], gbest, c1,
    c2, chi, rng), vmax)`` and ``x' = x[rows] + v'`` to the last bit, drawing the same random numbers from
    ``rng`` (``e1`` then ``e2``), without the dozen temporary arrays: the move is the optimiser's inner loop
    (tested against those plain operators).

    Parameters
    ----------
    v, x, pbest : ndarray, shape (N, D)
    gbest : ndarray, shape (D,)
    rows : ndarray of int, shape (R,)
    c1, c2, chi : float
    vmax : ndarray, shape (D,)
    rng : numpy.random.Generator

    Returns
    -------
    (ndarray, ndarray)
        New positions and velocities, each ``(R, D)``.
    """
    e = rng.random((2, rows.shape[0], x.shape[1]))  # e1 then e2: the stream constricted_velocity draws
    x_new = np.empty((rows.shape[0], x.shape[1]))
    v_new = np.empty_like(x_new)
    move_rows_kernel(v, x, pbest, gbest, rows, e, float(c1), float(c2), float(chi), vmax, x_new, v_new)
    return x_new, v_new


@nb.njit(cache=True, nogil=True)
def move_rows_kernel(v, x, pbest, gbest, rows, e, c1, c2, chi, vmax, x_new, v_new):
    """The compiled move of :func:`constricted_move`: row ``rows[r]`` moved with ``e[:, r]`` into ``x_new[r]``,
    ``v_new[r]`` (other compiled code that makes PSO moves calls it, so that the numbers stay the same)."""
    # the operations of constricted_velocity, clamp_velocity and x + v in numpy's order (no fused multiply-add)
    for r in range(rows.shape[0]):
        i = rows[r]
        for d in range(x.shape[1]):
            vv = chi * (v[i, d] + c1 * e[0, r, d] * (pbest[i, d] - x[i, d]) + c2 * e[1, r, d] * (gbest[d] - x[i, d]))
            if vv < -vmax[d]:  # np.clip: NaN stays NaN
                vv = -vmax[d]
            elif vv > vmax[d]:
                vv = vmax[d]
            v_new[r, d] = vv
            x_new[r, d] = x[i, d] + vv


def clamp_velocity(v: np.ndarray, vmax: np.ndarray) -> np.ndarray:
    """Limit ``|v_d| <= vmax_d`` component-wise ([FL12] sec. 5.3.2: ``vmax = 2 sigma``).

    Parameters
    ----------
    v : ndarray, shape (N, D)
    vmax : ndarray, shape (D,)

    Returns
    -------
    ndarray, shape (N, D)
    """
    return np.clip(v, -vmax, vmax)


def update_personal_best(
    pbest_x: np.ndarray,
    pbest_s: np.ndarray,
    x: np.ndarray,
    s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Personal-best update: a particle's best moves where its new score is strictly higher.

    Parameters
    ----------
    pbest_x : ndarray, shape (N, D)
    pbest_s : ndarray, shape (N,)
    x : ndarray, shape (N, D)
    s : ndarray, shape (N,)
        New scores (``-inf`` = invalid, never accepted).

    Returns
    -------
    (ndarray, ndarray)
        New ``pbest_x`` ``(N, D)`` and ``pbest_s`` ``(N,)``.
    """
    better = s > pbest_s
    return np.where(better[:, None], x, pbest_x), np.where(better, s, pbest_s)


@nb.njit(cache=True, nogil=True)
def tell_personal_best(valid, scores, x, pbest_x, pbest_s):
    """:func:`update_personal_best` of the valid rows' scores (an invalid row scores ``-inf``) in place, then
    :func:`global_best`: one compiled pass; returns the global best's index (the first on ties)."""
    n, d = x.shape
    g = 0
    for i in range(n):
        s = scores[i] if valid[i] else -np.inf
        if s > pbest_s[i]:
            pbest_s[i] = s
            for j in range(d):
                pbest_x[i, j] = x[i, j]
        if pbest_s[i] > pbest_s[g]:
            g = i
    return g


def global_best(pbest_s: np.ndarray) -> int:
    """Index of the global best (gbest topology; first index on ties)."""
    return int(np.argmax(pbest_s))


def best_or_start(pbest_x: np.ndarray, pbest_s: np.ndarray, g: int, start: np.ndarray) -> tuple[np.ndarray, float]:
    """The swarm's global best ``(x, score)``; the start centre ``start`` (score ``-inf``) while no valid
    particle has been scored, so that an invalid pose is never handed on as the estimate."""
    if np.isneginf(pbest_s[g]):
        return start.copy(), float("-inf")
    return pbest_x[g].copy(), float(pbest_s[g])


def sample_normal(mean: np.ndarray, sigma: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws from ``N(mean, diag(sigma^2))`` ([FL12] eq. 5.10; [SH17] eq. 6).

    Parameters
    ----------
    mean, sigma : ndarray, shape (D,)
    n : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (n, D)
    """
    return mean + sigma * rng.standard_normal((n, mean.shape[0]))


def sample_uniform(half_width: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws from ``U(-half_width, half_width)`` per dimension ([FL12] Algorithm 2, start velocities).

    Returns
    -------
    ndarray, shape (n, D)
    """
    return half_width * (2.0 * rng.random((n, half_width.shape[0])) - 1.0)


def redraw_invalid(
    propose: Callable[[np.ndarray], Sequence[np.ndarray]],
    is_valid: Callable[[np.ndarray], np.ndarray],
    n: int,
    max_redraws: int,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Draw ``n`` proposals, then re-draw only the invalid rows, at most ``max_redraws`` times.

    This is the constraint rule of [FL12] sec. 5.3.2 / Algorithm 2 ("repeat ... until x_i meets
    constraints", at most 10 attempts), vectorised: each round re-draws all still-invalid rows at once.

    Parameters
    ----------
    propose : callable
        ``propose(rows (R,) int) -> (positions (R, D), *other (R, ...))``; the first array is tested.
    is_valid : callable
        ``is_valid(positions (R, D)) -> (R,) bool``.
    n : int
        Number of rows.
    max_redraws : int
        Re-draws after the first draw (``0``: no re-draw).

    Returns
    -------
    (list of ndarray, ndarray of bool)
        The proposal arrays (rows replaced where re-drawn) and the final validity ``(n,)``.
    """
    out = [np.array(a, copy=True) for a in propose(np.arange(n))]
    valid = np.asarray(is_valid(out[0]), dtype=bool).copy()
    for _ in range(max_redraws):
        rows = np.flatnonzero(~valid)
        if rows.size == 0:
            break
        new = propose(rows)
        for arr, new_arr in zip(out, new, strict=True):
            arr[rows] = new_arr
        valid[rows] = is_valid(out[0][rows])
    return out, valid


# --------------------------------------------------------------------------------------------------
# Annealed particle filter ([DR05] sec. 3, 3.1, 6.1, 6.2)
# --------------------------------------------------------------------------------------------------
def _log_weights(scores: np.ndarray, beta: float) -> np.ndarray:
    """``beta * (score - max score)``; ``-inf`` for invalid scores (also at ``beta = 0``)."""
    finite = np.isfinite(scores)
    out = np.full(scores.shape, -np.inf)
    if finite.any():
        out[finite] = beta * (scores[finite] - scores[finite].max())
    return out


def annealing_weights(scores: np.ndarray, beta: float) -> np.ndarray:
    """Normalised weights ``pi ∝ w^beta`` ([DR05] eq. 3 and 6), with scores read as ``log w``.

    The optimisers' scores are log-weights: ``w = exp(score)`` (the :class:`~swarmpose.fitness.Fitness`
    contract; DR05's weighting function is itself an exponential of a negative sum of squared
    differences, eq. 14-17, and the fitnesses return its logarithm). Invalid scores (``-inf``) get
    weight 0; if every score is invalid the weights are uniform.

    Parameters
    ----------
    scores : ndarray, shape (N,)
    beta : float
        Annealing exponent ``beta_m >= 0`` (``inf`` allowed: the limit).

    Returns
    -------
    ndarray, shape (N,)
        Non-negative, summing to 1.
    """
    finite = np.isfinite(scores)
    if not finite.any():
        return np.full(scores.shape, 1.0 / scores.shape[0])
    if np.isinf(beta):  # the beta -> inf limit: equal mass on the particles tied at the best score
        top = finite & (scores == scores[finite].max())
        return top / top.sum()
    w = np.exp(_log_weights(scores, beta))
    return w / w.sum()


def survival_rate(scores: np.ndarray, beta: float) -> float:
    """Particle survival rate ``alpha = D / N`` with ``D = 1 / sum(pi^2)`` ([DR05] eq. 11-12).

    Parameters
    ----------
    scores : ndarray, shape (N,)
    beta : float

    Returns
    -------
    float
        In ``(0, 1]``.
    """
    pi = annealing_weights(scores, beta)
    return float(1.0 / np.sum(pi * pi) / scores.shape[0])


def find_beta(scores: np.ndarray, alpha: float, *, rtol: float = 1e-10) -> float:
    """Annealing exponent that makes the survival rate equal ``alpha`` ([DR05] sec. 3.1).

    ``D(beta)/N`` decreases monotonically from ``n_valid/N`` at ``beta = 0`` to ``n_top/N`` as
    ``beta -> inf`` (``n_top`` = number of particles tied at the best score), so the 1-D equation
    ``D(beta)/N = alpha`` has one root, found by bracket doubling and Brent's method. Because only
    score differences enter, ``beta * scale`` is invariant to a positive rescaling of the scores.

    Parameters
    ----------
    scores : ndarray, shape (N,)
        Log-weights (``-inf`` = invalid).
    alpha : float
        Target survival rate in ``(0, 1)``.
    rtol : float
        Relative tolerance on ``beta``.

    Returns
    -------
    float
        ``0`` when even uniform weights over the valid particles give ``D/N <= alpha``;
        ``inf`` when the target is below the ``beta -> inf`` limit (weights then put equal mass on the tied best
        particles, see :func:`annealing_weights`).
    """
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"target survival rate alpha must be in (0, 1), got {alpha}")
    finite = scores[np.isfinite(scores)]
    n = scores.shape[0]
    if finite.size == 0 or finite.size / n <= alpha:
        return 0.0
    spread = float(finite.max() - finite.min())
    if spread == 0.0:
        return 0.0
    n_top = int(np.sum(finite == finite.max()))
    if n_top / n >= alpha:
        return np.inf

    def gap(beta: float) -> float:
        return survival_rate(scores, beta) - alpha

    hi = 1.0 / spread
    while gap(hi) > 0.0:
        hi *= 2.0
        if hi > 1e300:  # pragma: no cover - guarded by the n_top test above
            return np.inf
    lo = hi / 2.0 if hi > 1.0 / spread else 0.0
    return float(brentq(gap, lo, hi, xtol=1e-300, rtol=max(rtol, 4 * np.finfo(float).eps)))


def resample_multinomial(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` indices drawn with replacement with probability ``weights`` ([DR05] sec. 3, step 4).

    Parameters
    ----------
    weights : ndarray, shape (N,)
        Non-negative, summing to 1.
    n : int
    rng : numpy.random.Generator

    Returns
    -------
    ndarray of int, shape (n,)
    """
    c = np.cumsum(weights)
    c /= c[-1]
    return np.minimum(np.searchsorted(c, rng.random(n), side="right"), weights.shape[0] - 1)


def resample_systematic(weights: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling: one uniform offset, ``n`` evenly spaced pointers (lower variance).

    Returns
    -------
    ndarray of int, shape (n,)
    """
    c = np.cumsum(weights)
    c /= c[-1]
    u = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(c, u, side="right"), weights.shape[0] - 1)


def crossover(a: np.ndarray, b: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Two-point crossover of parent pairs ([DR05] eq. 19).

    Child ``i`` is ``a_i`` with the block of parameters between two random cut points taken from ``b_i``:
    ``(x_1^a .. x_g^a, x_{g+1}^b .. x_e^b, x_{e+1}^a .. x_L^a)``. The cuts ``g < e`` are two distinct
    positions drawn uniformly from ``0 .. L`` (so the block is never empty and may start at ``x_1``).

    Parameters
    ----------
    a, b : ndarray, shape (N, D)
        Parents, drawn beforehand in proportion to their weights.
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (N, D)
    """
    n, d = a.shape
    g = rng.integers(0, d + 1, n)
    e = rng.integers(0, d, n)
    e = e + (e >= g)  # distinct from g, uniform over the other d positions
    lo, hi = np.minimum(g, e), np.maximum(g, e)
    j = np.arange(d)
    take_b = (j >= lo[:, None]) & (j < hi[:, None])
    return np.where(take_b, b, a)


def adaptive_diffusion(
    particles: np.ndarray,
    scale: float,
    rng: np.random.Generator,
    n: int | None = None,
) -> np.ndarray:
    """Gaussian noise with covariance ``scale * Cov(particles)`` ([DR05] eq. 18, adaptive diffusion).

    ``Cov = 1/N sum_i (s_i - s_av)(s_i - s_av)^T`` is the full covariance of the (resampled) set before
    noise. The noise is drawn as ``sqrt(scale/N) * Z @ (S - s_av)`` with ``Z ~ N(0, I)`` of shape
    ``(n, N)``, whose covariance is exactly ``scale * Cov`` and which needs no factorisation (a
    rank-deficient set, e.g. with parameters held fixed, is fine).

    Parameters
    ----------
    particles : ndarray, shape (N, D)
    scale : float
        Proportionality constant of eq. 18.
    rng : numpy.random.Generator
    n : int, optional
        Number of noise rows (default ``N``).

    Returns
    -------
    ndarray, shape (n, D)
    """
    n_particles = particles.shape[0]
    centred = particles - particles.mean(axis=0)
    z = rng.standard_normal((n_particles if n is None else n, n_particles))
    return np.sqrt(scale / n_particles) * (z @ centred)


def kernel_bandwidth(d: int, n_eff: float) -> float:
    """Squared optimal Gaussian-kernel bandwidth ``h^2`` for ``n_eff`` particles in ``d`` dimensions.

    ``h = (4 / ((d + 2) n_eff))^(1 / (d + 4))`` (Silverman's rule; the regularised particle filter of
    Musso, Oudjane & Le Gland 2001). Used as the default proportionality constant of [DR05] eq. 18, which
    leaves it open: resampling followed by noise ``~ N(0, h^2 Cov)`` is exactly kernel-smoothed
    (regularised) resampling.

    Examples
    --------
    >>> round(kernel_bandwidth(4, 100), 3)
    0.286
    """
    d = max(int(d), 1)
    return float((4.0 / ((d + 2.0) * max(n_eff, 1.0))) ** (2.0 / (d + 4.0)))


def fixed_diffusion(sigma: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Gaussian noise ``B ~ N(0, diag(sigma^2))`` ([DR05] eq. 7, 9, 13).

    Returns
    -------
    ndarray, shape (n, D)
    """
    return sigma * rng.standard_normal((n, sigma.shape[0]))


def weighted_mean(particles: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Weighted-mean estimate ``X_t = sum_i pi_i s_i`` ([DR05] eq. 8).

    Returns
    -------
    ndarray, shape (D,)
    """
    return weights @ particles


# --------------------------------------------------------------------------------------------------
# Adaptive annealed PSO ([SH17] sec. 3.4)
# --------------------------------------------------------------------------------------------------
def aapso_alpha(n: int, m: int) -> float:
    """Sampling factor ``alpha_n = 1 - 0.8 n / M`` ([SH17] eq. 17).

    Examples
    --------
    >>> aapso_alpha(5, 10)
    0.6
    """
    return -0.8 * (n / m) + 1.0


def aapso_velocity(
    x: np.ndarray,
    pbest: np.ndarray,
    gbest: np.ndarray,
    noise_var: np.ndarray,
    rng: np.random.Generator,
) -> np.ndarray:
    """Velocity of the adaptive annealed PSO ([SH17] eq. 15).

    ``v = b + phi1 * (p_i - x_i) + phi2 * (g - x_i)`` where the history term ``b ~ N(0, diag(P_n))``
    replaces the previous velocity and ``phi1, phi2 ~ U[0, 1)`` per particle and dimension.

    Parameters
    ----------
    x, pbest : ndarray, shape (N, D)
    gbest : ndarray, shape (D,)
    noise_var : ndarray, shape (D,)
        Diagonal of ``P_n`` (eq. 16: ``alpha_n * P_0``; eq. 18: ``alpha_n * Var(X)``).
    rng : numpy.random.Generator

    Returns
    -------
    ndarray, shape (N, D)
    """
    b = np.sqrt(noise_var) * rng.standard_normal(x.shape)
    phi1 = rng.random(x.shape)
    phi2 = rng.random(x.shape)
    return b + phi1 * (pbest - x) + phi2 * (gbest - x)
