"""Soft vs hard partitioning vs one global stage at equal budgets (thesis sec. 5.3.3, 6.6).

The objective is :func:`~swarmpose.optim.testfunctions.hierarchical_objective`: one dominant root
parameter and 29 children whose observed features depend on it (30 free parameters, like ``balan31``),
one frame of a walking-like motion (the root moves; stance children keep their world feature, swing children
move). The three searches are the registry's ``sppso`` (soft), ``hard2`` (hard) and ``pso-global``, 1000
evaluations each, started from the previous pose with the same seed per trial.

Measured while writing this test (300 trials each, seeds 7 / 2012 / 1, median RMS error):

=====  ======  ======  ==========  ==============================
fps    sppso   hard2   pso-global  one-sided Wilcoxon p (vs hard, vs global)
=====  ======  ======  ==========  ==============================
15     0.146   0.171   0.168       4e-4, 5e-4 (seed 7); 4e-3, 5e-3 (2012); 1e-3, 0.02 (1)
20     0.100   0.121   0.105       1.6e-14, 2e-3 (1000 trials, seed 7)
60     0.035   0.037   0.036       0.017, 0.02 (300 trials, seed 7)
=====  ======  ======  ==========  ==============================

So the thesis's ordering holds on this toy, with small margins at 60 and 20 fps (4-7 % of the median)
that grow at lower frame rates -- the direction the thesis reports (Fig. 6.11 vs 6.12). It is not a
property of every hierarchical toy: with fewer children (10-15) or with all children "stance", the
global search matched or beat the two-stage searches in exploratory runs.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import wilcoxon

from swarmpose.optim import get, optimize
from swarmpose.optim.testfunctions import hierarchical_objective


def _errors(fps: float, trials: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    names = ("sppso", "hard2", "pso-global")
    err: dict[str, list[float]] = {n: [] for n in names}
    for k in range(trials):
        problem, x0, model = hierarchical_objective(rng=rng, step=60.0 / fps)
        for n in names:
            cfg = get(n, model=model, fps=fps)
            assert cfg.evals_per_frame == 1000
            res = optimize(cfg.start(x0, np.random.default_rng([seed, k])), problem)
            err[n].append(float(problem.error(res.x)[0]))
    return {n: np.array(v) for n, v in err.items()}


@pytest.mark.slow
def test_soft_partitioning_beats_hard_and_global_at_equal_budget():
    err = _errors(fps=15.0, trials=300, seed=7)
    soft, hard, glob = err["sppso"], err["hard2"], err["pso-global"]
    assert np.median(soft) < 0.92 * np.median(hard), (np.median(soft), np.median(hard))
    assert np.median(soft) < 0.95 * np.median(glob), (np.median(soft), np.median(glob))
    assert wilcoxon(soft, hard, alternative="less").pvalue < 0.01
    assert wilcoxon(soft, glob, alternative="less").pvalue < 0.01
