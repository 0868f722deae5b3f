"""Objective functions for testing the optimisers without images. All return **scores** (higher is better).

This module is the one place where the sign flips: the classic benchmark functions are minimised in the
literature, so :func:`sphere`, :func:`rosenbrock` and :func:`rastrigin` return ``-f(X)``.

The toy articulated problems are planar linkages observed through a *silhouette-like* image: every link
is drawn as a row of Gaussian blobs, and the fitness is the negative sum of squared differences (SSD)
between the model image and the target image, computed in closed form from blob overlaps
(``∫ (M - T)^2``), normalised by ``∫ T^2``. This is the "SSD between a model template and a silhouette
image" of Deutscher & Reid (2005, sec. 6.1) without a pixel grid:

* :func:`planar_arm` -- DR05 Fig. 11: four links, swivel joints, rooted at O (adaptive diffusion test);
* :func:`two_arms` -- DR05 Fig. 15: two 3-link arms sharing the root O (crossover test);
* :func:`hierarchical_body` -- a planar "body": a root with position and orientation that moves
  everything (it dominates) and four 2-link limbs whose image positions depend on it (soft vs hard
  partitioning, thesis sec. 5.3.3 / 6.6). It comes with a duck-typed model (``param_names``, ``sigma``,
  ``lower``, ``upper``, ``group``) so the registry's named schedules run on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Linkage",
    "LinkageProblem",
    "ToyModel",
    "HierarchicalObjective",
    "hierarchical_body",
    "hierarchical_objective",
    "planar_arm",
    "rastrigin",
    "rosenbrock",
    "sphere",
    "two_arms",
]


# --------------------------------------------------------------------------------------------------
# Classic benchmarks (scores = -f)
# --------------------------------------------------------------------------------------------------
def sphere(x: np.ndarray) -> np.ndarray:
    """Score ``-sum(x^2)``; optimum 0 at ``x = 0``.

    Parameters
    ----------
    x : ndarray, shape (N, D)

    Returns
    -------
    ndarray, shape (N,)
    """
    x = np.asarray(x, dtype=np.float64)
    return -np.sum(x * x, axis=1)


def rosenbrock(x: np.ndarray) -> np.ndarray:
    """Score ``-sum(100 (x_{d+1} - x_d^2)^2 + (1 - x_d)^2)``; optimum 0 at ``x = 1``.

    Parameters
    ----------
    x : ndarray, shape (N, D), D >= 2

    Returns
    -------
    ndarray, shape (N,)
    """
    x = np.asarray(x, dtype=np.float64)
    return -np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=1)


def rastrigin(x: np.ndarray) -> np.ndarray:
    """Score ``-(10 D + sum(x^2 - 10 cos(2 pi x)))``; optimum 0 at ``x = 0``.

    Parameters
    ----------
    x : ndarray, shape (N, D)

    Returns
    -------
    ndarray, shape (N,)
    """
    x = np.asarray(x, dtype=np.float64)
    return -(10.0 * x.shape[1] + np.sum(x * x - 10.0 * np.cos(2.0 * np.pi * x), axis=1))


# --------------------------------------------------------------------------------------------------
# Planar linkages seen as silhouettes
# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Linkage:
    """A planar kinematic tree of straight links.

    Attributes
    ----------
    parents : tuple of int
        Parent link of each link (``-1``: attached to the root); ``parents[i] < i``.
    attach : ndarray, shape (L, 2)
        Attachment point in the parent's frame: ``(along, across)`` with ``along`` a fraction of the parent's
        length (1 = its tip) and ``across`` a perpendicular offset; for root links, in the root frame.
    lengths : ndarray, shape (L,)
    angle_index : tuple of int
        Parameter holding each link's angle relative to its parent (or to the root orientation);
        ``-1``: the link is rigidly fixed to its frame (relative angle 0).
    root_position_index : tuple of int, optional
        Two parameters for the root's ``(x, y)``; fixed at the origin when empty.
    root_angle_index : int, optional
        Parameter of the root orientation; 0 when None.
    samples : int
        Blobs per link.
    widths : ndarray, shape (L,), optional
        Blob standard deviation (thickness) per link; default: the problem's ``width`` for every link.
    """

    parents: tuple[int, ...]
    attach: np.ndarray
    lengths: np.ndarray
    angle_index: tuple[int, ...]
    root_position_index: tuple[int, ...] = ()
    root_angle_index: int | None = None
    samples: int = 6
    widths: np.ndarray | None = None

    @property
    def dimension(self) -> int:
        """Number of parameters."""
        idx = [i for i in self.angle_index if i >= 0] + list(self.root_position_index)
        if self.root_angle_index is not None:
            idx.append(self.root_angle_index)
        return max(idx) + 1

    def endpoints(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Start and end of every link, each ``(N, L, 2)``."""
        x = np.asarray(x, dtype=np.float64)
        n = x.shape[0]
        n_links = len(self.parents)
        base = np.zeros((n, 2)) if not self.root_position_index else x[:, list(self.root_position_index)]
        root_angle = np.zeros(n) if self.root_angle_index is None else x[:, self.root_angle_index]
        start = np.empty((n, n_links, 2))
        end = np.empty((n, n_links, 2))
        absolute = np.empty((n, n_links))
        for i, p in enumerate(self.parents):  # loop over links, batched over candidates
            if p < 0:
                frame_angle, origin, scale = root_angle, base, 1.0
            else:
                frame_angle, origin, scale = absolute[:, p], start[:, p], self.lengths[p]
            c, s = np.cos(frame_angle), np.sin(frame_angle)
            along, across = self.attach[i, 0] * scale, self.attach[i, 1]
            start[:, i, 0] = origin[:, 0] + c * along - s * across
            start[:, i, 1] = origin[:, 1] + s * along + c * across
            k = self.angle_index[i]
            absolute[:, i] = frame_angle + (x[:, k] if k >= 0 else 0.0)
            end[:, i, 0] = start[:, i, 0] + self.lengths[i] * np.cos(absolute[:, i])
            end[:, i, 1] = start[:, i, 1] + self.lengths[i] * np.sin(absolute[:, i])
        return start, end

    def points(self, x: np.ndarray) -> np.ndarray:
        """Blob centres along all links, ``(N, L * samples, 2)``."""
        start, end = self.endpoints(x)
        t = (np.arange(self.samples) + 0.5) / self.samples
        pts = start[:, :, None, :] + t[None, None, :, None] * (end - start)[:, :, None, :]
        return pts.reshape(x.shape[0], -1, 2)

    def point_widths(self, default: float) -> np.ndarray:
        """Blob width of every point of :meth:`points`, ``(L * samples,)``."""
        w = (
            np.full(len(self.parents), float(default))
            if self.widths is None
            else np.asarray(self.widths, float)
        )
        return np.repeat(w, self.samples)

    def joints(self, x: np.ndarray) -> np.ndarray:
        """Link starts and ends, ``(N, 2L, 2)`` (a "marker" set for error measures)."""
        start, end = self.endpoints(x)
        return np.concatenate([start, end], axis=1)


def _overlap(a: np.ndarray, wa: np.ndarray, b: np.ndarray, wb: np.ndarray) -> np.ndarray:
    """``∫ M_a M_b / (2 pi)`` for blob images; a (N, P, 2), b (N or 1, Q, 2), blob widths wa (P,), wb (Q,).

    Two blobs ``exp(-|p - a|^2 / (2 s_a^2))``, ``exp(-|p - b|^2 / (2 s_b^2))`` overlap by
    ``2 pi s_a^2 s_b^2 / (s_a^2 + s_b^2) * exp(-|a - b|^2 / (2 (s_a^2 + s_b^2)))``.
    """
    s2 = wa[:, None] ** 2 + wb[None, :] ** 2
    pref = (wa[:, None] ** 2 * wb[None, :] ** 2) / s2
    dx = a[:, :, None, 0] - b[:, None, :, 0]
    dy = a[:, :, None, 1] - b[:, None, :, 1]
    e = np.exp((dx * dx + dy * dy) * (-0.5 / s2))
    return np.einsum("npq,pq->n", e, pref)


@dataclass(eq=False)
class LinkageProblem:
    """A linkage fitted to the silhouette of a target pose (higher score = better fit).

    ``score(x) = -SSD(model image, target image) / ∫ T^2``: 0 for a perfect fit, about -2 for disjoint
    images. Images are sums of isotropic Gaussian blobs of standard deviation ``width``, so
    ``∫ (M - T)^2 = ∫ M^2 - 2 ∫ M T + ∫ T^2`` is a sum of pairwise blob overlaps.

    Attributes
    ----------
    linkage : Linkage
    target : ndarray, shape (D,)
        The true pose.
    width : float
        Blob standard deviation (silhouette thickness) of links without their own width.
    """

    linkage: Linkage
    target: np.ndarray
    width: float = 0.08
    _target_pts: np.ndarray = field(init=False, repr=False)
    _w: np.ndarray = field(init=False, repr=False)
    _tt: float = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.target = np.array(self.target, dtype=np.float64)
        self._target_pts = self.linkage.points(self.target[None])
        self._w = self.linkage.point_widths(self.width)
        self._tt = float(_overlap(self._target_pts, self._w, self._target_pts, self._w)[0])

    @property
    def dimension(self) -> int:
        """Number of parameters."""
        return self.target.shape[0]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Scores ``(N,)`` for poses ``(N, D)``."""
        pts = self.linkage.points(np.asarray(x, dtype=np.float64))
        mm = _overlap(pts, self._w, pts, self._w)
        mt = _overlap(pts, self._w, self._target_pts, self._w)
        return -(mm - 2.0 * mt + self._tt) / self._tt

    def ssd(self, x: np.ndarray) -> np.ndarray:
        """Normalised SSD ``(N,)`` (= ``-score``)."""
        return -self(x)

    def joint_error(self, x: np.ndarray) -> np.ndarray:
        """Mean distance of link starts/ends to the target's, ``(N,)`` (the toy "3D error")."""
        j = self.linkage.joints(np.asarray(x, dtype=np.float64))
        jt = self.linkage.joints(self.target[None])
        return np.linalg.norm(j - jt, axis=-1).mean(axis=1)

    def with_target(self, target: np.ndarray) -> LinkageProblem:
        """Same linkage, another target pose."""
        return LinkageProblem(self.linkage, target, self.width)


def planar_arm(
    target: Sequence[float] | np.ndarray, *, width: float = 0.08, samples: int = 6
) -> LinkageProblem:
    """DR05 Fig. 11: a planar arm of four links joined by swivel joints, rooted at O.

    ``x = (x1, x2, x3, x4)``: x1 is the root link's angle, each further angle is relative to the previous
    link, so x1 moves the whole arm and dominates the fitness. Link lengths 1.0, 0.8, 0.6, 0.5.

    Parameters
    ----------
    target : array_like, shape (4,)
        True angles (radians).
    width : float
        Silhouette blob width.
    samples : int
        Blobs per link.
    """
    link = Linkage(
        parents=(-1, 0, 1, 2),
        attach=np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 0.0]]),
        lengths=np.array([1.0, 0.8, 0.6, 0.5]),
        angle_index=(0, 1, 2, 3),
        samples=samples,
    )
    return LinkageProblem(link, np.asarray(target, dtype=np.float64), width)


def two_arms(
    target: Sequence[float] | np.ndarray, *, width: float = 0.08, samples: int = 6
) -> LinkageProblem:
    """DR05 Fig. 15: two planar 3-link arms rooted at the same point O.

    ``x = (x1, x2, x3, x4, x5, x6)``: (x1, x2, x3) the first arm (root angle, then relative angles),
    (x4, x5, x6) the second. Lengths 1.0, 0.8, 0.6 and 0.9, 0.7, 0.5 (different, so the arms are not
    interchangeable).
    """
    link = Linkage(
        parents=(-1, 0, 1, -1, 3, 4),
        attach=np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 0.0], [1.0, 0.0], [1.0, 0.0]]),
        lengths=np.array([1.0, 0.8, 0.6, 0.9, 0.7, 0.5]),
        angle_index=(0, 1, 2, 3, 4, 5),
        samples=samples,
    )
    return LinkageProblem(link, np.asarray(target, dtype=np.float64), width)


@dataclass(frozen=True, eq=False)
class ToyModel:
    """A duck-typed body model for the registry (``param_names``, ``sigma``, ``lower``, ``upper``, ``group``).

    Groups not in ``groups`` raise ``KeyError`` like the real model.
    """

    param_names: tuple[str, ...]
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    groups: dict[str, np.ndarray]

    def group(self, name: str) -> np.ndarray:
        """Indices of group ``name``."""
        try:
            return self.groups[name]
        except KeyError:
            raise KeyError(f"toy model has no group {name!r} (known: {sorted(self.groups)})") from None


def hierarchical_body(
    target: Sequence[float] | np.ndarray,
    *,
    torso_width: float = 0.2,
    limb_width: float = 0.05,
    samples: int = 5,
) -> tuple[LinkageProblem, ToyModel]:
    """A planar articulated "body" with a dominant root and dependent limbs (11 parameters).

    Parameters (0-based): ``x0, x1`` root position, ``x2`` root orientation (the torso's direction),
    then four 2-link limbs ``(upper, lower)`` angles: left arm ``x3, x4`` and right arm ``x5, x6``
    attached at the torso's top (±0.2 across), left leg ``x7, x8`` and right leg ``x9, x10`` at the
    root (±0.15 across). Torso length 1.0 drawn thick (``torso_width``), arm links 0.55/0.5, leg links
    0.7/0.65 drawn thin (``limb_width``).

    The root moves every limb and the torso is the biggest part of the silhouette, so the root dominates
    the fitness; but the best root for given limb angles depends on those angles (a misplaced limb pulls
    the root towards it), which is what makes hard partitioning accumulate errors ([FL12] sec. 5.3.3).

    Returns
    -------
    (LinkageProblem, ToyModel)
        The problem for ``target`` and a model with groups ``root_position``, ``root_orientation``,
        ``left_arm``, ``right_arm``, ``left_leg``, ``right_leg`` and per-parameter sigma (root position
        0.08, angles 0.12, read as "at 60 fps") for the registry's schedules.
    """
    link = Linkage(
        parents=(-1, -1, 1, -1, 3, -1, 5, -1, 7),
        # torso, left upper/lower arm, right upper/lower arm, left thigh/calf, right thigh/calf
        attach=np.array(
            [
                [0.0, 0.0],
                [1.0, 0.2],
                [1.0, 0.0],
                [1.0, -0.2],
                [1.0, 0.0],
                [0.0, 0.15],
                [1.0, 0.0],
                [0.0, -0.15],
                [1.0, 0.0],
            ]
        ),
        lengths=np.array([1.0, 0.55, 0.5, 0.55, 0.5, 0.7, 0.65, 0.7, 0.65]),
        angle_index=(-1, 3, 4, 5, 6, 7, 8, 9, 10),  # the torso is rigid on the root frame
        root_position_index=(0, 1),
        root_angle_index=2,
        samples=samples,
        widths=np.array([torso_width] + [limb_width] * 8),
    )
    problem = LinkageProblem(link, np.asarray(target, dtype=np.float64), limb_width)
    names = (
        "root_x",
        "root_y",
        "root_angle",
        "l_shoulder",
        "l_elbow",
        "r_shoulder",
        "r_elbow",
        "l_hip",
        "l_knee",
        "r_hip",
        "r_knee",
    )
    model = ToyModel(
        param_names=names,
        sigma=np.array([0.08, 0.08] + [0.12] * 9),
        lower=np.full(11, -np.inf),
        upper=np.full(11, np.inf),
        groups={
            "root_position": np.array([0, 1]),
            "root_orientation": np.array([2]),
            "left_arm": np.array([3, 4]),
            "right_arm": np.array([5, 6]),
            "left_leg": np.array([7, 8]),
            "right_leg": np.array([9, 10]),
        },
    )
    return problem, model


# --------------------------------------------------------------------------------------------------
# An analytic hierarchical objective (soft vs hard partitioning)
# --------------------------------------------------------------------------------------------------
def _bump(e: np.ndarray, width: float) -> np.ndarray:
    """Silhouette-like misfit ``1 - exp(-e^2 / (2 width^2))`` in [0, 1)."""
    return 1.0 - np.exp(-0.5 * (e / width) ** 2)


@dataclass(eq=False)
class HierarchicalObjective:
    """One dominant root parameter and ``K`` children whose observable features depend on it.

    ``x = (x_0, x_1 .. x_K)``. Child ``j`` is seen at the world coordinate ``u_j = x_j + b_j x_0``
    (a joint angle measured relative to its parent, observed in the world), the root at ``x_0``::

        score(x) = -[A * m(x_0 - t_0; w_root) + sum_j m(u_j - u_j*; w)] / (A + K)

    with ``m(e; w) = 1 - exp(-e^2 / (2 w^2))`` (a bounded, silhouette-like misfit). The root dominates:
    its own evidence is weighted ``A`` and broad (``w_root``, a big torso), and it moves every child's
    feature; the children are thin (``w``). Optimum ``0`` at ``x = t``.

    Attributes
    ----------
    target : ndarray, shape (K + 1,)
    coupling : ndarray, shape (K,)
        ``b_j``.
    dominance, width, root_width : float
    """

    target: np.ndarray
    coupling: np.ndarray
    dominance: float = 10.0
    width: float = 0.4
    root_width: float = 0.6

    def __post_init__(self) -> None:
        self.target = np.array(self.target, dtype=np.float64)
        self.coupling = np.array(self.coupling, dtype=np.float64)
        self._u = self.target[1:] + self.coupling * self.target[0]

    @property
    def dimension(self) -> int:
        """``K + 1``."""
        return self.target.shape[0]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Scores ``(N,)`` for ``(N, K + 1)``."""
        x = np.asarray(x, dtype=np.float64)
        u = x[:, 1:] + np.outer(x[:, 0], self.coupling)
        misfit = self.dominance * _bump(x[:, 0] - self.target[0], self.root_width)
        misfit = misfit + _bump(u - self._u, self.width).sum(axis=1)
        return -misfit / (self.dominance + self.coupling.shape[0])

    def error(self, x: np.ndarray) -> np.ndarray:
        """RMS parameter error ``(N,)`` to the target."""
        x = np.atleast_2d(np.asarray(x, dtype=np.float64))
        return np.sqrt(np.mean((x - self.target) ** 2, axis=1))


def hierarchical_objective(
    n_children: int = 29,
    *,
    rng: np.random.Generator,
    step: float = 3.0,
    stance: float = 0.6,
    dominance: float = 10.0,
    width: float = 0.4,
    root_width: float = 0.6,
) -> tuple[HierarchicalObjective, np.ndarray, ToyModel]:
    """One frame of a walking-like motion on :class:`HierarchicalObjective`: (problem, start pose, model).

    The previous pose ``p`` is uniform in ``[-1, 1]``. Between frames the root moves by
    ``U(-1, 1) * step * sigma_0``; a fraction ``stance`` of the children keep their *world* feature
    (like a stance foot: their relative value changes by ``-b_j * root move``), the others ("swing") change
    by ``U(-1, 1) * step * sigma_j``. The search starts at ``p``, the target is the new pose.

    This is the situation of [FL12] sec. 5.3.3: with the children at their previous values the stance
    children pull the root back to where it was, so a first stage over the root alone is biased, and a
    hard partition cannot undo that in stage 2.

    Parameters
    ----------
    n_children : int
        ``K`` (29: with the root, 30 free parameters like ``balan31``).
    rng : numpy.random.Generator
    step : float
        Inter-frame motion in units of sigma (3 = the thesis's 20 fps with 60-fps sigma).
    stance : float
        Fraction of stance children.
    dominance, width, root_width : float
        See :class:`HierarchicalObjective`.

    Returns
    -------
    (HierarchicalObjective, ndarray, ToyModel)
        The model has sigma 0.2 for the root and 0.1 for the children ("at 60 fps"); the root is the group
        ``root_position`` (so SPPSO divides its sigma by 10 in stage 2) and ``root_orientation`` is empty;
        children are split evenly over ``left_arm``, ``right_arm``, ``left_leg``, ``right_leg``, ``spine``
        and ``head``.
    """
    k = int(n_children)
    d = k + 1
    sigma = np.full(d, 0.1)
    sigma[0] = 0.2
    coupling = np.linspace(0.5, 1.5, k)
    prev = rng.uniform(-1.0, 1.0, d)
    target = prev.copy()
    move = rng.uniform(-1.0, 1.0) * step * sigma[0]
    target[0] += move
    n_stance = int(round(stance * k))
    target[1 : 1 + n_stance] -= coupling[:n_stance] * move
    target[1 + n_stance :] += rng.uniform(-1.0, 1.0, k - n_stance) * step * sigma[1 + n_stance :]
    problem = HierarchicalObjective(target, coupling, dominance, width, root_width)
    parts = np.array_split(np.arange(1, d), 6)
    groups = {"root_position": np.array([0]), "root_orientation": np.empty(0, dtype=np.int64)}
    for name, idx in zip(
        ("left_arm", "right_arm", "left_leg", "right_leg", "spine", "head"), parts, strict=True
    ):
        groups[name] = idx
    model = ToyModel(
        param_names=("root",) + tuple(f"child{j}" for j in range(1, d)),
        sigma=sigma,
        lower=np.full(d, -np.inf),
        upper=np.full(d, np.inf),
        groups=groups,
    )
    return problem, prev, model
