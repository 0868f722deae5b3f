"""The ask/tell contract shared by every optimiser, and the only optimisation loop.

Sign convention (``design.md`` sec. 2): **scores, higher is better**. Every optimiser maximises.
Benchmark functions that are conventionally minimised are flipped in exactly one place,
:mod:`swarmpose.optim.testfunctions`, which returns ``-f(X)``.

Protocol
--------
``poses = opt.ask()`` returns an ``(N, D)`` float64 batch; ``opt.tell(scores)`` takes the ``(N,)`` scores
of exactly that batch, in ask order. ``opt.best`` is a :class:`Candidate`, ``opt.evaluations`` the number
of scores told so far, ``opt.done`` whether the evaluation budget is used up, and
``opt.fitness_options`` the options of the stage/layer that the last ``ask()`` belongs to (the tracker
switches its fitness with it, e.g. edge cones of the torso only in SPPSO stage 1).

Score rule (non-finite values)
------------------------------
``NaN`` and ``-inf`` scores mean *invalid*: they are stored as ``-inf``, so such a candidate never becomes a
personal/global best and gets zero weight in the particle filter. ``+inf`` is rejected with ``ValueError``:
a fitness that returns ``+inf`` is broken, and accepting it would make every later comparison meaningless.

Bounds and constraints
----------------------
Every optimiser takes ``lower``/``upper`` ``(D,)`` bounds (``±inf`` allowed) and an optional
``constraint(poses (N, D)) -> (N,) bool`` (True = valid; the tracker passes the body model's hard priors).
A pose outside the bounds counts as a constraint violation and is re-drawn like one (thesis sec. 5.3.2:
up to 10 re-draws of the move); rows still outside after the last re-draw are clipped into the box, so
``ask()`` never returns a pose outside ``[lower, upper]``.

A constraint may also carry ``constricted_moves(v, x, pbest, gbest, c, chi, vmax, lower, upper, max_redraws,
rng) -> (x, v, valid)``: :class:`~swarmpose.optim.pso.ConstrictedPSO`'s move of every particle (eq. 5.7-5.8,
``c1 = c2 = c``), its re-draws and the final clipping, done in one compiled call that draws the same random
numbers and returns the same arrays as the plain path (:func:`~swarmpose.optim.operators.redraw_invalid`,
:func:`feasibility`, :func:`clip_invalid`). The tracker's hard priors carry one (``swarmpose.track.constraint``).
"""

from __future__ import annotations

import abc
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numba as nb
import numpy as np

from swarmpose.errors import ConfigError, ShapeError

__all__ = [
    "Candidate",
    "ConfigError",
    "Constraint",
    "Fitness",
    "OptimResult",
    "Optimizer",
    "ShapeError",
    "check_scores",
    "clip_invalid",
    "feasibility",
    "optimize",
]

Fitness = Callable[[np.ndarray], np.ndarray]
"""A batched fitness: poses ``(N, D)`` -> scores ``(N,)``, higher is better."""

Constraint = Callable[[np.ndarray], np.ndarray]
"""A batched validity test: poses ``(N, D)`` -> ``(N,)`` bool, True = valid."""

EMPTY_OPTIONS: Mapping[str, Any] = MappingProxyType({})


@dataclass(frozen=True, eq=False)
class Candidate:
    """One point of the search with its score.

    Attributes
    ----------
    x : ndarray, shape (D,)
        The pose (read-only copy).
    score : float
        Its score (higher is better). For the annealed particle filter's weighted-mean estimate
        (Deutscher & Reid 2005, eq. 8) ``x`` itself is never evaluated; ``score`` is then the
        weight-averaged score of the final layer (see :class:`~swarmpose.optim.apf.AnnealedParticleFilter`).
    evaluations : int
        Number of fitness evaluations spent when this candidate was reported.
    """

    x: np.ndarray
    score: float
    evaluations: int


@dataclass(frozen=True, eq=False)
class OptimResult:
    """What :func:`optimize` returns.

    Attributes
    ----------
    x : ndarray, shape (D,)
        Final estimate (``opt.best.x``).
    score : float
        Its score (``opt.best.score``).
    evaluations : int
        Fitness evaluations used (equals the configured budget when the optimiser ran to ``done``).
    iterations : int
        Number of ask/tell rounds.
    """

    x: np.ndarray
    score: float
    evaluations: int
    iterations: int


def check_scores(scores: Any, n: int) -> np.ndarray:
    """Validate the scores of one ask and apply the non-finite rule.

    Parameters
    ----------
    scores : array_like, shape (N,)
        Scores in ask order.
    n : int
        Number of candidates of the last ask.

    Returns
    -------
    ndarray, shape (N,)
        float64 copy with NaN replaced by ``-inf``.

    Raises
    ------
    ShapeError
        If the shape is not ``(n,)``.
    ValueError
        If any score is ``+inf``.
    """
    s = np.array(scores, dtype=np.float64, copy=True)
    if s.shape != (n,):
        raise ShapeError(f"scores must have shape ({n},) (one per asked candidate), got {s.shape}")
    if np.isfinite(s).all():  # the usual case: one pass
        return s
    if np.any(s == np.inf):
        raise ValueError("scores contain +inf; a fitness must return finite values (NaN/-inf = invalid)")
    s[np.isnan(s)] = -np.inf
    return s


def feasibility(
    poses: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    constraint: Constraint | None,
) -> np.ndarray:
    """Valid rows: inside ``[lower, upper]`` and accepted by ``constraint``.

    Parameters
    ----------
    poses : ndarray, shape (N, D)
    lower, upper : ndarray, shape (D,)
    constraint : callable or None
        ``constraint(poses) -> (N,) bool``; called only on the rows inside the bounds.

    Returns
    -------
    ndarray of bool, shape (N,)
    """
    p = np.ascontiguousarray(poses, dtype=np.float64)
    valid = np.empty(p.shape[0], dtype=bool)
    n_inside = _in_bounds(p, np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64), valid)
    if constraint is not None and n_inside:
        rows = None if n_inside == p.shape[0] else np.flatnonzero(valid)  # every row: no copy
        tested = p if rows is None else p[rows]
        ok = np.asarray(constraint(tested))
        if ok.shape != (tested.shape[0],):
            raise ShapeError(
                f"constraint must return shape ({tested.shape[0]},) for poses of shape {tested.shape}, got {ok.shape}"
            )
        if rows is None:
            valid[:] = ok
        else:
            valid[rows] = ok
    return valid


@nb.njit(cache=True, nogil=True)
def _in_bounds(poses, lower, upper, out):
    """``out = all(lower <= poses <= upper, axis=1)`` (NaN: outside); returns the number of rows inside."""
    n = 0
    for i in range(poses.shape[0]):
        ok = True
        for d in range(poses.shape[1]):
            if not (poses[i, d] >= lower[d] and poses[i, d] <= upper[d]):
                ok = False
                break
        out[i] = ok
        n += ok
    return n


def clip_invalid(
    x: np.ndarray,
    valid: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    is_valid: Callable[[np.ndarray], np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """Clip the invalid rows that lie outside ``[lower, upper]`` into the box and re-test only those.

    Used after the last constraint re-draw, so that ``ask()`` never leaves the bounds.

    Returns
    -------
    (ndarray, ndarray)
        ``x`` (modified in place) and the updated validity.
    """
    outside = ~valid & np.any((x < lower) | (x > upper), axis=1)
    rows = np.flatnonzero(outside)
    if rows.size:
        x[rows] = np.clip(x[rows], lower, upper)
        valid[rows] = is_valid(x[rows])
    return x, valid


class Optimizer(abc.ABC):
    """Base class of the ask/tell optimisers.

    Subclasses implement :meth:`_ask` and :meth:`_tell`; this class guards the protocol
    (``RuntimeError`` for a tell without an ask, a second tell, or an ask after ``done``; ``ShapeError``
    for scores of the wrong shape) and counts evaluations.
    """

    def __init__(self) -> None:
        self._pending: int | None = None
        self._evaluations = 0

    # -- protocol ---------------------------------------------------------------------------------
    def ask(self) -> np.ndarray:
        """Next batch of candidates.

        Returns
        -------
        ndarray, shape (N, D), float64

        Raises
        ------
        RuntimeError
            If the previous ask has not been told, or the optimiser is done.
        """
        if self._pending is not None:
            raise RuntimeError("ask() called twice without tell(); tell the scores of the last ask first")
        if self.done:
            raise RuntimeError("optimiser is done (evaluation budget used up); read .best")
        x = np.array(self._ask(), dtype=np.float64)
        self._pending = x.shape[0]
        return x

    def tell(self, scores: Any) -> None:
        """Scores of the last ask, in ask order (higher is better; NaN/-inf = invalid, +inf rejected).

        Raises
        ------
        RuntimeError
            Without a preceding ask (or when told twice).
        ShapeError
            If ``scores.shape != (N,)``.
        """
        if self._pending is None:
            raise RuntimeError("tell() without a preceding ask() (or told twice)")
        self._tell_checked(check_scores(scores, self._pending))

    def _tell_checked(self, scores: np.ndarray) -> None:
        """:meth:`tell` of scores already through :func:`check_scores` for this optimiser's last ask (a staged
        search hands its stage's optimiser the scores it checked, without checking them twice)."""
        if self._pending is None:
            raise RuntimeError("tell() without a preceding ask() (or told twice)")
        if self._pending != scores.shape[0]:
            raise RuntimeError(f"{self._pending} candidates asked, {scores.shape[0]} scores told")
        self._pending = None
        self._evaluations += scores.shape[0]
        self._tell(scores)

    @property
    def evaluations(self) -> int:
        """Number of scores told so far."""
        return self._evaluations

    @property
    @abc.abstractmethod
    def done(self) -> bool:
        """True when the evaluation budget is used up."""

    @property
    @abc.abstractmethod
    def best(self) -> Candidate:
        """Current estimate; ``RuntimeError`` before the first tell."""

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        """Fitness options of the stage/layer the last ``ask()`` belongs to (empty by default)."""
        return EMPTY_OPTIONS

    def carry(self) -> Any:
        """State handed to the next frame's search (``None``: nothing to carry)."""
        return None

    # -- for subclasses ---------------------------------------------------------------------------
    @abc.abstractmethod
    def _ask(self) -> np.ndarray: ...

    @abc.abstractmethod
    def _tell(self, scores: np.ndarray) -> None: ...


def optimize(
    opt: Optimizer,
    fitness: Fitness,
    callback: Callable[[Optimizer], None] | None = None,
) -> OptimResult:
    """Run ``opt`` to ``done`` on ``fitness``: the only optimisation loop.

    Parameters
    ----------
    opt : Optimizer
    fitness : callable
        ``fitness(poses (N, D)) -> scores (N,)``, higher is better.
    callback : callable, optional
        Called as ``callback(opt)`` after every tell (for recording; its return value is ignored).

    Returns
    -------
    OptimResult

    Examples
    --------
    >>> import numpy as np
    >>> from swarmpose.optim.testfunctions import sphere
    >>> from swarmpose.optim.pso import ConstrictedPSO
    >>> rng = np.random.default_rng(0)
    >>> opt = ConstrictedPSO(np.full(5, 2.0), np.ones(5), n_particles=10, n_iterations=30, rng=rng)
    >>> res = optimize(opt, sphere)
    >>> res.evaluations
    300
    >>> bool(res.score > -0.05)
    True
    """
    iterations = 0
    while not opt.done:
        x = opt.ask()
        opt.tell(fitness(x))
        iterations += 1
        if callback is not None:
            callback(opt)
    best = opt.best
    return OptimResult(x=best.x, score=best.score, evaluations=opt.evaluations, iterations=iterations)


def as_vector(a: Any, d: int, name: str) -> np.ndarray:
    """``a`` as a float64 ``(d,)`` array (scalars broadcast); ``ShapeError`` otherwise."""
    v = np.array(a, dtype=np.float64)
    if v.ndim == 0:
        v = np.full(d, float(v))
    if v.shape != (d,):
        raise ShapeError(f"{name} must have shape ({d},), got {v.shape}")
    return v


def check_bounds(lower: Any, upper: Any, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``(D,)`` bounds; ``None`` means unbounded."""
    lo = np.full(d, -np.inf) if lower is None else as_vector(lower, d, "lower")
    hi = np.full(d, np.inf) if upper is None else as_vector(upper, d, "upper")
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo > hi):
        raise ConfigError("bounds must satisfy lower <= upper (no NaN)")
    return lo, hi


def check_rng(rng: Any) -> np.random.Generator:
    """``rng`` if it is a ``numpy.random.Generator``; ``TypeError`` otherwise (no global RNG, ever)."""
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def frozen_options(options: Mapping[str, Any] | None) -> Mapping[str, Any]:
    """A read-only copy of ``options``."""
    return MappingProxyType(dict(options or {}))
