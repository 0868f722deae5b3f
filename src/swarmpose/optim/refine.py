"""Deterministic local refinement and wide re-search, as ask/tell optimisers; and their chaining.

* :class:`PatternSearch` -- a batched coordinate pattern search (Hooke & Jeeves 1961; Kolda, Lewis &
  Torczon 2003, "generating set search"): each step asks every move ``x +- h_d e_d`` of the active
  coordinates in one batch, then one batch of *combined* moves along the sum of the improving ones
  (a finite-difference ascent step that changes many parameters together); steps that find nothing
  better halve ``h``. Deterministic, bounded, constraint-aware, with a fixed evaluation budget.
* :class:`BoxSearch` -- a wide search of some coordinates over their whole box (uniform samples, then
  rounds of Gaussian samples around the best few, shrinking: a cross-entropy search), the others held.
  The tracker starts it for a limb it finds lost (:mod:`swarmpose.track.recovery`).
* :class:`Chain` -- runs optimisers one after another, each started from the previous one's estimate;
  it carries the first one's state to the next frame.

All see poses and scores only (:mod:`swarmpose.optim.base`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numba as nb
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
    feasibility,
    optimize,
)

__all__ = ["PatternSearch", "BoxSearch", "Chain", "line_moves_reference", "polish_best"]


class PatternSearch(Optimizer):
    """Batched coordinate pattern search with finite-difference line steps (maximises).

    Each step asks, in one batch, every poll move ``x +- h_d e_d`` of the active coordinates; from their
    scores it forms per coordinate the central difference ``g_d`` and curvature ``c_d``, and asks a second
    batch along two directions: the diagonal Newton step (``-g_d / c_d`` where ``c_d < 0``, clipped to
    ``2 h_d``) at ``newton`` multiples, and the gradient direction scaled so that its largest component
    is ``h_d`` at ``gradient`` multiples (this one follows ridges that no single coordinate climbs). The
    best point of both batches is kept; a step that finds nothing better halves ``h``.

    Parameters
    ----------
    x0 : (D,) start (evaluated first).
    step : (D,) initial step per coordinate (``h``); a coordinate with step 0 is held fixed.
    budget : int
        Evaluations; the last batch is cut to what is left.
    lower, upper : (D,) bounds; moves are clipped into them.
    constraint : callable, optional
        ``(N, D) -> (N,) bool``; invalid moves are not asked.
    min_step : float
        Stop when every ``h_d`` is below ``min_step * step_d``.
    newton, gradient : sequence of float
        Multiples of the two line directions asked after each poll.
    fitness_options : mapping
        Returned by :attr:`fitness_options` (e.g. ``{"terms": "distance"}``).
    """

    def __init__(self, x0: Any, step: Any, budget: int, *, lower: Any = None, upper: Any = None,
                 constraint: Constraint | None = None, min_step: float = 1e-3,
                 newton: Sequence[float] = (0.5, 1.0), gradient: Sequence[float] = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0),
                 fitness_options: Mapping[str, Any] = EMPTY_OPTIONS):
        super().__init__()
        x = np.array(x0, dtype=np.float64).reshape(-1)
        d = x.size
        self.step0 = as_vector(step, d, "step")
        if np.any(self.step0 < 0) or not np.all(np.isfinite(self.step0)):
            raise ConfigError("pattern search steps must be finite and >= 0")
        if isinstance(budget, bool) or int(budget) != budget or budget < 1:
            raise ConfigError(f"pattern search budget must be a whole number >= 1, got {budget!r}")
        self.budget = int(budget)
        self.lower, self.upper = check_bounds(lower, upper, d)
        self.constraint = constraint
        self.min_step = float(min_step)
        self.newton = tuple(float(c) for c in newton)
        self.gradient = tuple(float(c) for c in gradient)
        self._newton_mult = np.array(self.newton, dtype=np.float64)
        self._gradient_mult = np.array(self.gradient, dtype=np.float64)
        self._options = fitness_options
        self.h = self.step0.copy()
        self.x = np.clip(x, self.lower, self.upper)
        self.fx = -np.inf
        self._phase = "start"
        self._asked = np.zeros((0, d))
        self._poll: tuple[np.ndarray, np.ndarray] | None = None
        self._stalled = False

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._options

    @property
    def done(self) -> bool:
        return self.evaluations >= self.budget or self._stalled

    @property
    def best(self) -> Candidate:
        if self._phase == "start":
            raise RuntimeError("no evaluations yet")
        return Candidate(self.x.copy(), float(self.fx), self.evaluations)

    def _left(self) -> int:
        return self.budget - self.evaluations

    def _usable(self, cand: np.ndarray) -> np.ndarray:
        """Rows that are valid and differ from ``x`` (clipped into the box first)."""
        return feasibility(cand, self.lower, self.upper, self.constraint) & np.any(cand != self.x, axis=1)

    def _ask(self) -> np.ndarray:
        if self._phase == "start":
            self._asked = self.x[None]
            return self._asked
        while True:
            if self._phase == "poll":
                active = np.flatnonzero(self.h > 0)
                eye = np.eye(self.x.size)[active] * self.h[active, None]
                cand = np.clip(self.x + np.concatenate([eye, -eye]), self.lower, self.upper)
            else:
                cand = np.clip(self.x + self._line, self.lower, self.upper)
            cand = cand[self._usable(cand)][:self._left()]
            if len(cand):
                self._asked = cand
                return cand
            if self._phase == "line":
                self._phase = "poll"
                if not self._poll_improved:
                    self._shrink()
                if not self._stalled:
                    continue
                self._asked = self.x[None]
                return self._asked
            self._shrink()  # no usable poll move at this step size
            if self._stalled:
                self._asked = self.x[None]  # nothing left to try: keep the protocol, re-ask the estimate
                return self._asked

    def _shrink(self) -> None:
        self.h *= 0.5
        if np.all(self.h <= self.min_step * self.step0):
            self._stalled = True

    def _line_moves(self, asked: np.ndarray, scores: np.ndarray, fx: float, x: np.ndarray) -> np.ndarray:
        """Newton and gradient moves from the poll's scores around ``x`` (rows: ``len(newton) + len(gradient)``;
        compiled, :func:`line_moves_reference` is the plain version it is tested against)."""
        out = np.empty((len(self.newton) + len(self.gradient), x.size))
        _line_moves_kernel(np.ascontiguousarray(asked, dtype=np.float64), np.ascontiguousarray(scores, dtype=np.float64),
                           float(fx), x, self.h, self._newton_mult, self._gradient_mult, out)
        return out

    def _tell(self, scores: np.ndarray) -> None:
        if self._phase == "start":
            self.fx = float(scores[0])
            self._phase = "poll"
            return
        if self._stalled:
            return
        i = int(np.argmax(scores))
        improved = scores[i] > self.fx
        if self._phase == "poll":
            x0, f0 = self.x.copy(), self.fx
            self._line = self._line_moves(self._asked, scores, f0, x0)
            if improved:
                self._line = self._line + (x0 - self._asked[i])  # the line moves stay relative to x0
                self.x, self.fx = self._asked[i].copy(), float(scores[i])
            self._poll_improved = improved
            self._phase = "line" if self._left() > 0 else "poll"
            return
        if improved:
            self.x, self.fx = self._asked[i].copy(), float(scores[i])
        elif not self._poll_improved:
            self._shrink()
        self._phase = "poll"


def line_moves_reference(asked: np.ndarray, scores: np.ndarray, fx: float, x: np.ndarray, step: np.ndarray,
                         newton: Sequence[float], gradient: Sequence[float]) -> np.ndarray:
    """:meth:`PatternSearch._line_moves` in numpy: from the poll ``asked`` (each row ``x +- h_d e_d``) and its
    ``scores``, per coordinate the central difference ``g_d`` and curvature ``c_d`` (one-sided where one side is
    missing), then the Newton rows (``-g_d / c_d`` where ``c_d < 0``, clipped to ``2 h_d``, else ``sign(g_d) h_d``)
    at the ``newton`` multiples and the gradient rows (largest component ``h_d``) at the ``gradient`` multiples;
    coordinates with step 0 stay."""
    d = x.size
    fp = np.full(d, np.nan)
    fm = np.full(d, np.nan)
    delta = asked - x
    coord = np.argmax(np.abs(delta), axis=1)
    sign = np.sign(delta[np.arange(len(delta)), coord])
    ok = np.isfinite(scores)
    fp[coord[(sign > 0) & ok]] = scores[(sign > 0) & ok]
    fm[coord[(sign < 0) & ok]] = scores[(sign < 0) & ok]
    h = np.where(step > 0, step, 1.0)
    both = np.isfinite(fp) & np.isfinite(fm)
    g = np.zeros(d)
    g[both] = (fp[both] - fm[both]) / (2 * h[both])
    only_p = np.isfinite(fp) & ~both
    only_m = np.isfinite(fm) & ~both
    g[only_p] = (fp[only_p] - fx) / h[only_p]
    g[only_m] = (fx - fm[only_m]) / h[only_m]
    c = np.zeros(d)
    c[both] = (fp[both] - 2 * fx + fm[both]) / h[both] ** 2
    newton_move = np.where(c < 0, np.clip(-g / np.where(c < 0, c, -1.0), -2 * h, 2 * h), np.sign(g) * h)
    newton_move[step == 0] = 0.0
    gh = g * h
    scale = np.abs(gh).max()
    grad = np.zeros(d) if scale == 0 else h * gh / scale
    grad[step == 0] = 0.0
    return np.concatenate([np.multiply.outer(newton, newton_move), np.multiply.outer(gradient, grad)])


@nb.njit(cache=True, nogil=True)
def _line_moves_kernel(asked, scores, fx, x, step, newton, gradient, out):
    """:func:`line_moves_reference` into ``out``, the same operations in the same order per coordinate."""
    d = x.shape[0]
    fp = np.full(d, np.nan)
    fm = np.full(d, np.nan)
    for i in range(asked.shape[0]):
        coord = 0
        big = -1.0
        for j in range(d):
            a = abs(asked[i, j] - x[j])
            if a > big:  # the first largest, as argmax
                big = a
                coord = j
        dl = asked[i, coord] - x[coord]
        if not math.isfinite(scores[i]):
            continue
        if dl > 0.0:
            fp[coord] = scores[i]
        elif dl < 0.0:
            fm[coord] = scores[i]
    g = np.zeros(d)
    newton_move = np.zeros(d)
    grad = np.zeros(d)
    scale = 0.0
    for j in range(d):
        h = step[j] if step[j] > 0 else 1.0
        has_p = math.isfinite(fp[j])
        has_m = math.isfinite(fm[j])
        c = 0.0
        if has_p and has_m:
            g[j] = (fp[j] - fm[j]) / (2 * h)
            c = (fp[j] - 2 * fx + fm[j]) / (h * h)
        elif has_p:
            g[j] = (fp[j] - fx) / h
        elif has_m:
            g[j] = (fx - fm[j]) / h
        if c < 0:
            newton_move[j] = min(max(-g[j] / c, -2 * h), 2 * h)
        else:
            sg = 1.0 if g[j] > 0 else (-1.0 if g[j] < 0 else g[j])
            newton_move[j] = sg * h
        if step[j] == 0:
            newton_move[j] = 0.0
        scale = max(scale, abs(g[j] * h))
    for j in range(d):
        h = step[j] if step[j] > 0 else 1.0
        if scale != 0:
            grad[j] = h * (g[j] * h) / scale
        if step[j] == 0:
            grad[j] = 0.0
    for q in range(newton.shape[0]):
        for j in range(d):
            out[q, j] = newton[q] * newton_move[j]
    for q in range(gradient.shape[0]):
        for j in range(d):
            out[newton.shape[0] + q, j] = gradient[q] * grad[j]


class BoxSearch(Optimizer):
    """Wide search of the ``mask`` coordinates over ``[lower, upper]``, the others held at ``x0`` (maximises).

    Round 0 asks ``n_samples`` uniform samples of the box (plus ``x0`` itself); each later round asks
    ``n_samples`` Gaussian samples around the ``n_elite`` best so far with a spread that starts at a
    quarter of the box and halves per round (a cross-entropy search, Rubinstein 1999).

    Parameters
    ----------
    x0 : (D,) current estimate.
    mask : (D,) bool, the coordinates searched.
    lower, upper : (D,) finite bounds for the masked coordinates.
    rng : numpy.random.Generator
    n_samples, n_rounds, n_elite : int
    constraint : callable, optional
    fitness_options : mapping
    """

    def __init__(self, x0: Any, mask: Any, lower: Any, upper: Any, rng: np.random.Generator, *,
                 n_samples: int = 100, n_rounds: int = 3, n_elite: int = 5, constraint: Constraint | None = None,
                 fitness_options: Mapping[str, Any] = EMPTY_OPTIONS):
        super().__init__()
        x = np.array(x0, dtype=np.float64).reshape(-1)
        d = x.size
        self.mask = np.asarray(mask, bool).reshape(-1)
        if self.mask.shape != (d,):
            raise ShapeError(f"mask must have shape ({d},), got {self.mask.shape}")
        self.lower, self.upper = check_bounds(lower, upper, d)
        if not np.all(np.isfinite(self.lower[self.mask]) & np.isfinite(self.upper[self.mask])):
            raise ConfigError("a box search needs finite bounds on every searched coordinate")
        for name, v in (("n_samples", n_samples), ("n_rounds", n_rounds), ("n_elite", n_elite)):
            if isinstance(v, bool) or int(v) != v or v < 1:
                raise ConfigError(f"box search {name} must be a whole number >= 1, got {v!r}")
        self.rng = check_rng(rng)
        self.n_samples, self.n_rounds, self.n_elite = int(n_samples), int(n_rounds), int(n_elite)
        self.constraint = constraint
        self._options = fitness_options
        self.x0 = x
        self._round = 0
        self._asked = np.zeros((0, d))
        self._pool_x = np.zeros((0, d))
        self._pool_s = np.zeros(0)
        self._best: Candidate | None = None

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._options

    @property
    def budget(self) -> int:
        return 1 + self.n_samples * self.n_rounds

    @property
    def done(self) -> bool:
        return self._round >= self.n_rounds

    @property
    def best(self) -> Candidate:
        if self._best is None:
            raise RuntimeError("no evaluations yet")
        return self._best

    def _ask(self) -> np.ndarray:
        m = self.mask
        lo, hi = self.lower[m], self.upper[m]
        x = np.repeat(self.x0[None], self.n_samples, axis=0)
        if self._round == 0:
            x[:, m] = self.rng.uniform(lo, hi, (self.n_samples, m.sum()))
            x = np.concatenate([self.x0[None], x])
        else:
            spread = 0.25 * (hi - lo) * 0.5 ** (self._round - 1)
            elite = self._pool_x[np.argsort(-self._pool_s, kind="stable")[:self.n_elite]]
            pick = elite[self.rng.integers(0, len(elite), self.n_samples)]
            x[:, m] = np.clip(pick[:, m] + self.rng.normal(0.0, 1.0, (self.n_samples, m.sum())) * spread, lo, hi)
        self._asked = x
        return x

    def _tell(self, scores: np.ndarray) -> None:
        valid = feasibility(self._asked, self.lower, self.upper, self.constraint)
        s = np.where(valid, scores, -np.inf)
        if self._round == 0:
            s[0] = scores[0]  # the current estimate stands whatever the constraint says of it
        self._pool_x = np.concatenate([self._pool_x, self._asked])
        self._pool_s = np.concatenate([self._pool_s, s])
        i = int(np.argmax(self._pool_s))
        self._best = Candidate(self._pool_x[i].copy(), float(self._pool_s[i]), self.evaluations)
        self._round += 1


class Chain(Optimizer):
    """Optimisers run one after another, each started at the previous one's estimate.

    Parameters
    ----------
    first : Optimizer
        Started already; its :meth:`carry` is the chain's.
    then : sequence of callables
        ``make(x, score) -> Optimizer`` for each following member, given the previous estimate.
    """

    def __init__(self, first: Optimizer, then: Sequence[Callable[[np.ndarray, float], Optimizer]]):
        super().__init__()
        self._members = [first]
        self._then = list(then)
        self._current = first

    @property
    def members(self) -> list[Optimizer]:
        return list(self._members)

    @property
    def fitness_options(self) -> Mapping[str, Any]:
        return self._current.fitness_options

    @property
    def done(self) -> bool:
        return self._current.done and not self._then

    @property
    def best(self) -> Candidate:
        b = self._current.best
        return Candidate(b.x, b.score, self.evaluations)

    def carry(self) -> Any:
        return self._members[0].carry()

    def _advance(self) -> None:
        while self._current.done and self._then:
            b = self._current.best
            self._current = self._then.pop(0)(np.array(b.x), float(b.score))
            self._members.append(self._current)

    def _ask(self) -> np.ndarray:
        self._advance()
        return self._current.ask()

    def _tell(self, scores: np.ndarray) -> None:
        self._current._tell_checked(scores)  # checked once, by this search's tell
        self._advance()


def polish_best(score: Callable[[np.ndarray], np.ndarray], cands: np.ndarray, scores: np.ndarray, n_best: int,
                step: np.ndarray, budget: int, lower: np.ndarray, upper: np.ndarray,
                constraint: Constraint | None = None, above: float = -np.inf) -> tuple[np.ndarray | None, float, int, int]:
    """The best of ``cands (M, D)`` after a local search: the ``n_best`` highest of their ``scores (M,)`` (``-inf``:
    not tried), from the highest down until a non-finite one, each polished by a :class:`PatternSearch` of
    ``budget`` evaluations of ``score``. Returns ``(x, its score, its candidate's index, evaluations)`` of the best
    polished pose that scores above ``above``; ``(None, above, -1, evaluations)`` when none does."""
    best_x, best_score, best_k, evaluations = None, float(above), -1, 0
    for j in np.argsort(-np.asarray(scores, dtype=np.float64))[:n_best]:
        if not np.isfinite(scores[j]):
            break
        found = optimize(PatternSearch(cands[j], step, budget, lower=lower, upper=upper, constraint=constraint), score)
        evaluations += found.evaluations
        if found.score > best_score:
            best_x, best_score, best_k = np.array(found.x), float(found.score), int(j)
    return best_x, best_score, best_k, evaluations
