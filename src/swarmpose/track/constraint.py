"""The tracker's constraint: the body model's hard priors, timed, with PSO's constrained moves compiled.

:class:`PriorsConstraint` is what the optimisers get as ``constraint``: called on poses it is
:meth:`swarmpose.body.priors.HardPriors.valid` (timed as the ``priors`` part). It also carries
``constricted_moves`` (the hook of :mod:`swarmpose.optim.base`): a constricted PSO iteration's move of every
particle ([FL12] eq. 5.7-5.8), the re-draws of the moves that leave the bounds or break the priors (Algorithm 2,
up to ``max_redraws`` times) and the clipping of the rows still outside the bounds, in one numba call. It draws
the same random numbers from the same generator, in the same order, as the plain path
(:func:`~swarmpose.optim.operators.redraw_invalid` with :func:`~swarmpose.optim.operators.constricted_move`,
:func:`~swarmpose.optim.base.feasibility`, :func:`~swarmpose.optim.base.clip_invalid`), and returns the same
arrays to the last bit (tested): only the Python between the rounds is gone. Its time counts as the optimiser's.
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np

from swarmpose.body.priors import HardPriors, pose_valid
from swarmpose.optim.operators import move_rows_kernel

__all__ = ["PriorsConstraint"]

#: Hash of the kernel sources this module's cached kernel calls (body/priors.py and what it calls,
#: optim/operators.py): numba's cache sees edits to this file only (tests/test_numba_cache.py gives the value).
INLINED_SOURCES_SHA1 = "7263e06c7c92fe02"


class PriorsConstraint:
    """``constraint(poses (N, D)) -> (N,) bool``: the hard priors, timed as ``"priors"`` by ``timer``
    (a :class:`~swarmpose.track.timing.PartTimer`, optional), plus the compiled ``constricted_moves``."""

    def __init__(self, priors: HardPriors, timer: Any = None) -> None:
        self.priors = priors
        self._valid = priors.valid if timer is None else timer.wrap("priors", priors.valid)
        self._tables = priors.kernel_tables()
        self._J = priors.model.kin.parents.shape[0]

    def __call__(self, poses: np.ndarray) -> np.ndarray:
        return self._valid(poses)

    def constricted_moves(self, v: np.ndarray, x: np.ndarray, pbest: np.ndarray, gbest: np.ndarray, c: float,
                          chi: float, vmax: np.ndarray, lower: np.ndarray, upper: np.ndarray, max_redraws: int,
                          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every particle moved (``c1 = c2 = c``), invalid moves re-drawn, rows still outside ``[lower, upper]``
        clipped into it and tested again; returns ``(x (N, D), v (N, D), valid (N,))`` (see the module)."""
        f64 = np.float64
        x = np.ascontiguousarray(x, dtype=f64)
        n, d = x.shape
        x_new = np.empty((n, d))
        v_new = np.empty((n, d))
        valid = np.empty(n, dtype=np.bool_)
        _constricted_moves(np.ascontiguousarray(v, dtype=f64), x, np.ascontiguousarray(pbest, dtype=f64),
                           np.ascontiguousarray(gbest, dtype=f64), float(c), float(chi),
                           np.ascontiguousarray(vmax, dtype=f64), np.ascontiguousarray(lower, dtype=f64),
                           np.ascontiguousarray(upper, dtype=f64), int(max_redraws), rng, self._J, self._tables,
                           x_new, v_new, valid)
        return x_new, v_new, valid


@nb.njit(cache=True, nogil=True, inline="always")
def _feasible(pose, lower, upper, T, tables):
    """:func:`swarmpose.optim.base.feasibility` of one pose: inside ``[lower, upper]`` (NaN: outside), then the
    priors."""
    for d in range(pose.shape[0]):
        if not (pose[d] >= lower[d] and pose[d] <= upper[d]):
            return False
    (plo, pup, check_limits, c_index, c_above, parents, offsets, rot_axis, rot_sign, rot_param, trans_param, joint,
     start, end, radii, scale, pairs, frac, keep) = tables
    return pose_valid(pose, T, plo, pup, check_limits, c_index, c_above, parents, offsets, rot_axis, rot_sign,
                      rot_param, trans_param, joint, start, end, radii, scale, pairs, frac, keep)


@nb.njit(cache=True, nogil=True)
def _constricted_moves(v, x, pbest, gbest, c, chi, vmax, lower, upper, max_redraws, rng, J, tables,
                       x_new, v_new, valid):
    """:meth:`PriorsConstraint.constricted_moves` into ``x_new``, ``v_new``, ``valid``."""
    n, d = x.shape
    T = np.empty((J, 3, 4))
    rows = np.arange(n)
    e = rng.random((2, n, d))  # the first draw: every row (redraw_invalid's propose(arange(n)))
    move_rows_kernel(v, x, pbest, gbest, rows, e, c, c, chi, vmax, x_new, v_new)
    for i in range(n):
        valid[i] = _feasible(x_new[i], lower, upper, T, tables)
    for _ in range(max_redraws):
        m = 0
        for i in range(n):
            if not valid[i]:
                rows[m] = i
                m += 1
        if m == 0:
            break
        e = rng.random((2, m, d))  # the invalid rows only, in row order
        xr = np.empty((m, d))
        vr = np.empty((m, d))
        move_rows_kernel(v, x, pbest, gbest, rows[:m], e, c, c, chi, vmax, xr, vr)
        for q in range(m):
            i = rows[q]
            x_new[i] = xr[q]
            v_new[i] = vr[q]
            valid[i] = _feasible(x_new[i], lower, upper, T, tables)
    for i in range(n):  # clip_invalid: the invalid rows outside the box, clipped and tested again
        if valid[i]:
            continue
        outside = False
        for k in range(d):
            if x_new[i, k] < lower[k] or x_new[i, k] > upper[k]:
                outside = True
                break
        if outside:
            for k in range(d):
                if x_new[i, k] < lower[k]:
                    x_new[i, k] = lower[k]
                elif x_new[i, k] > upper[k]:
                    x_new[i, k] = upper[k]
            valid[i] = _feasible(x_new[i], lower, upper, T, tables)
